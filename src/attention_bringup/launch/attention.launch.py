"""
Start the four nodes of the graph with the same YAML files as ``attention_train``.

For a full ROS 2 Jazzy install (after ``colcon build`` and ``source install/setup.bash``):

    ros2 launch attention_bringup attention.launch.py condition:=language
    ros2 launch attention_bringup attention.launch.py task:=doorkey

Every node gets ``config/graph.yaml`` (defaults), then ``config/tasks/<task>.yaml`` if the task
has one, then ``config/conditions/<condition>.yaml``,
then the optional ``params_file`` on top (later wins), as the launcher passes them. The launcher
also sets env_node ``max_steps`` and tamer_node ``run_dir``; here they are launch arguments.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

NODES = ('env_node', 'feedback_node', 'saliency_node', 'tamer_node')
CONDITIONS = (
    'vanilla', 'language', 'blind_obs', 'blind_saliency', 'language_every_step', 'hidden_agent',
    'language_input', 'text_film',
)
GRAPH_FILE = 'graph.yaml'
CONDITIONS_DIR = 'conditions'
TASKS_DIR = 'tasks'
DEFAULT_TASK = 'montezuma'
TRAINERS = ('teacher', 'thesis')
TEACHING_GREEDY_MARGIN = 0.1  # tamer_node greedy_margin with the teacher, as attention_train


def _nodes(context):
    condition = LaunchConfiguration('condition').perform(context)
    if condition not in CONDITIONS:
        raise RuntimeError(f'unknown condition {condition!r} (one of: {", ".join(CONDITIONS)})')
    config = os.path.join(get_package_share_directory('attention_bringup'), 'config')
    task = LaunchConfiguration('task').perform(context)
    task_file = os.path.join(config, TASKS_DIR, f'{task}.yaml')
    files = [os.path.join(config, GRAPH_FILE)]
    files += [task_file] if os.path.exists(task_file) else []
    files.append(os.path.join(config, CONDITIONS_DIR, f'{condition}.yaml'))
    user_file = LaunchConfiguration('params_file').perform(context)
    if user_file:
        files.append(user_file)
    trainer = LaunchConfiguration('trainer').perform(context)
    if trainer not in TRAINERS:
        raise RuntimeError(f'unknown trainer {trainer!r} (one of: {", ".join(TRAINERS)})')
    overrides = {
        'env_node': {'max_steps': int(LaunchConfiguration('max_steps').perform(context))},
        'saliency_node': {},
        'feedback_node': {'trainer': trainer},
        'tamer_node': {'run_dir': LaunchConfiguration('run_dir').perform(context),
                       **({'greedy_margin': TEACHING_GREEDY_MARGIN} if trainer == 'teacher'
                          else {})},
    }
    if task != DEFAULT_TASK:  # every node is told the task (each checks the name)
        for values in overrides.values():
            values['task'] = task
    return [Node(package=name, executable=name, name=name, output='screen',
                 parameters=files + [overrides.get(name, {})])
            for name in NODES]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('condition', default_value='language',
                              description='Study condition: ' + ', '.join(CONDITIONS)),
        DeclareLaunchArgument('task', default_value='montezuma',
                              description="The task: 'montezuma' (Room 1) or 'doorkey'"),
        DeclareLaunchArgument('trainer', default_value='teacher',
                              description="feedback_node's trainer: " + ', '.join(TRAINERS)),
        DeclareLaunchArgument('params_file', default_value='',
                              description='Your parameter file, applied last (optional)'),
        DeclareLaunchArgument('max_steps', default_value='0',
                              description='env_node budget of agent steps (0 = unlimited)'),
        DeclareLaunchArgument('run_dir', default_value='runs/launch',
                              description='tamer_node run folder (metrics, checkpoints)'),
        OpaqueFunction(function=_nodes),
    ])

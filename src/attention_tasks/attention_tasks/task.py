"""
The contract between a task and the nodes, and loading a task by name (no rclpy).

A task is a module ``attention_tasks.<name>.task`` with a ``TASK`` (a ``Task``): the nodes
read everything game-specific from it, the parameter ``task`` names it. Another task is one
new module (and its template manifest), no edits to the nodes.

The topic interface is the same for every task: an action travels as ``sensor_msgs/Joy`` of one
of ALE's 18 joystick actions (``attention_common.joy_actions``); ``Task.joy_actions`` says
which joystick action carries each of the task's own actions, so a gamepad, the console and
``ros2 topic pub`` work the same way in every task.
"""

from dataclasses import dataclass
import functools
import importlib
from pathlib import Path
import pkgutil
from typing import Any, Callable, Dict, Mapping, NamedTuple, Optional, Tuple

from attention_common.joy_actions import NUM_ACTIONS as NUM_JOY_ACTIONS

ROOM_1 = 'montezuma'
"""The thesis's task: Montezuma's Revenge, Room 1."""
DEFAULT_TASK = ROOM_1
NO_ACTION = -1
"""``Step.action`` of a step no agent action led to (a reset, the start after warm-up)."""


class Step(NamedTuple):
    """One environment step (or a reset) as env_node publishes it, in any task."""

    observation: Any
    """RGB frame, ``Task.frame_shape`` + (3,), uint8 (None from a world made not to render)."""
    state: Any
    """The task's state: a NamedTuple or frozen dataclass with ``status()`` (env_status)."""
    reward: float
    terminated: bool
    truncated: bool
    life_lost: bool
    episode: int
    episode_step: int
    agent_step: int
    """Steps the agent has taken in this trial (warm-up not counted)."""
    sim_time_ns: int
    """Simulation time since the trial began (strictly increasing)."""
    episode_return: float = 0.0
    action: int = NO_ACTION
    """The task action applied to reach this step (``NO_ACTION`` after a reset)."""

    @property
    def done(self) -> bool:
        """Tell whether the episode ended at this step (the caller resets)."""
        return self.terminated or self.truncated


@dataclass(frozen=True)
class Task:
    """What the nodes need to know of a task."""

    name: str
    env_id: str
    """Shown in logs and as env_status's hardware_id."""
    frame_shape: Tuple[int, int]
    """Rows and columns of the RGB frames env_node publishes."""
    joy_actions: Tuple[int, ...]
    """For each task action (index), the ALE joystick action that carries it over topics."""
    action_names: Tuple[str, ...]
    env_config: type
    """Dataclass of the world's settings: env_node declares one parameter per field."""
    make_env: Callable[[Any], Any]
    """``make_env(config)``: an object with ``warm_up()``, ``reset()``, ``step(action)`` (each a
    ``Step``) and ``close()``."""
    milestones: Tuple[str, ...]
    """The progress measure's steps, in order (critical positions, sub-goals)."""
    milestone_of: Callable[[Mapping[str, object], float], int]
    """``milestone_of(env_status values, radius)``: the milestone the step stands on, -1 none
    (radius: the feedback node's alpha, for tasks measured by distance)."""
    manifest: Optional[Path]
    """Template manifest of the saliency node; None: saliency_node's packaged Room 1 one."""
    realtime_hz: float
    """env_node ``rate_hz`` when a person watches (``attention_train --realtime``)."""
    encoder_file: str
    """File name of the pretrained encoder, in tamer_node's share folder."""
    collect_frames: Callable[..., Tuple[Any, str]]
    """``collect_frames(count, seed, stride=, detour_probability=, use_expert=, progress=)``:
    frames along the expert's routes with random detours, for pretraining the encoder."""
    solved: Callable[[Mapping[str, object]], bool] = lambda values: False
    """Whether the step's status ends an episode in success (the study counts these)."""
    heldout_layouts: bool = False
    """Whether the last part of a run is on layouts it never trained on (env_status
    ``heldout``): the summary then counts the held-out episodes and those solved."""
    standing_poses: frozenset = frozenset()
    """env_status ``pose`` values of an agent held by something (Room 1: ground, ladder, rope):
    the launcher counts a milestone as stood on only in one of them; empty: not measured."""

    @property
    def num_actions(self) -> int:
        return len(self.joy_actions)

    def joy_action(self, action: int) -> int:
        """Return the joystick action (0..17) that carries task ``action``."""
        if not 0 <= int(action) < self.num_actions:
            raise ValueError(f'{self.name} action {action} is out of range '
                             f'0..{self.num_actions - 1}')
        return self.joy_actions[int(action)]

    def action_of_joy(self, joy_action: int) -> Optional[int]:
        """Return the task action a joystick action carries; None if it carries none."""
        return self._from_joy.get(int(joy_action))

    @functools.cached_property
    def _from_joy(self) -> Dict[int, int]:
        return {joy: index for index, joy in enumerate(self.joy_actions)}

    def check(self) -> None:
        """Raise ValueError when the task's tables contradict each other."""
        if len(set(self.joy_actions)) != len(self.joy_actions) or not all(
                0 <= a < NUM_JOY_ACTIONS for a in self.joy_actions):
            raise ValueError(f'{self.name}: joy_actions must be distinct joystick actions')
        if len(self.action_names) != len(self.joy_actions):
            raise ValueError(f'{self.name}: one name per action')


class UnknownTask(ValueError):
    """No task module of that name."""


def task_names() -> Tuple[str, ...]:
    """Return the names of the tasks installed (sub-packages with a ``task`` module)."""
    import attention_tasks
    names = []
    for info in pkgutil.iter_modules(attention_tasks.__path__):
        if info.ispkg and importlib.util.find_spec(f'attention_tasks.{info.name}.task'):
            names.append(info.name)
    return tuple(sorted(names))


def load_task(name: str) -> Task:
    """Return the ``TASK`` of ``attention_tasks.<name>.task``; raise UnknownTask if none."""
    known = task_names()
    if name not in known:
        raise UnknownTask(f'unknown task {name!r}; installed tasks: {", ".join(known)}')
    task = importlib.import_module(f'attention_tasks.{name}.task').TASK
    task.check()
    return task

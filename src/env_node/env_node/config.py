"""env_node's parameters: ``task``, the task's world settings (its dataclass), the node's own."""

from dataclasses import dataclass

from attention_common.preview import PREVIEW_RATE_HZ
from attention_tasks.task import DEFAULT_TASK

RUNTIME_PARAMETERS = ('paused',)
"""Settable while the node runs; every other parameter is read once at start (read-only)."""


@dataclass
class EnvNodeConfig:
    """
    Each field is a ROS parameter of the same name; its docstring is the description.

    The world's parameters come from the task (``Task.env_config``: Room 1's frameskip,
    sticky_actions, seed, warmup_steps, end_on_room_exit, end_on_life_loss; DoorKey's size,
    distractors, ...), declared once ``task`` is read.
    """

    task: str = DEFAULT_TASK
    """The task to run: 'montezuma' (Room 1, the thesis's) or 'doorkey' (MiniGrid, a new layout
    every episode); any module attention_tasks.<task>.task."""
    rate_hz: float = 0.0
    """Steps per second on a steady timer with the latest action; 0 = lockstep (wait for the
    action stamped with the pending observation)."""
    action_timeout: float = 2.0
    """Lockstep: wall seconds without the answer before the pending observation is published
    again (same stamp) and a timeout counted."""
    max_steps: int = 0
    """Agent steps after which a last env_status with finished=true is published and stepping
    stops; 0 = unlimited."""
    wait_observation_subscribers: int = 1
    """Start-up: send the first step only once this many subscribers of observation have
    matched (graph.yaml: 2, saliency_node and tamer_node), so no node misses the first steps
    while DDS discovery runs."""
    wait_observation_nodes: str = ''
    """Start-up: comma-separated names of nodes that must subscribe to observation before the
    first step (the launcher: the learners and the recorder). The count above cannot tell a
    learner from a viewer: in real time the console's and the recorder's readers once made it
    while tamer_node was still loading, and the 60 steps went by unanswered. '' = the count
    only."""
    wait_position_subscribers: int = 0
    """Start-up: likewise for agent_position (graph.yaml: 1, the synthetic trainer)."""
    wait_status_subscribers: int = 0
    """Start-up: likewise for env_status (the teacher judges from it; 0 = do not wait)."""
    paused: bool = False
    """true: no steps are taken (real time: the timer skips; lockstep: the answer waits until
    resumed) and simulation time stands still. Settable at run time (the trainer console pauses
    with it)."""
    pause_each_episode: bool = False
    """true: every episode, the first included, starts paused (its first observation is out,
    env_status says 'paused'): a person looks at the new room and says the goal (Fetch), then
    resumes (the console's button, or ``paused`` set false)."""
    preview_rate_hz: float = PREVIEW_RATE_HZ
    """Most messages a wall second on observation/preview and env_status/preview, the copies
    a viewer reads (attention_common.preview: sent only while someone subscribes; real time's
    every step passes); 0 = no preview topics (viewers then read the full topics)."""

    def validate(self) -> None:
        """Raise ValueError saying which value is impossible (the world checks its own)."""
        if self.rate_hz < 0 or self.action_timeout <= 0 or self.max_steps < 0:
            raise ValueError('rate_hz must be >= 0, action_timeout > 0 and max_steps >= 0 '
                             f'(got {self.rate_hz}, {self.action_timeout}, {self.max_steps})')
        if not self.preview_rate_hz >= 0:
            raise ValueError(f'preview_rate_hz must be >= 0, got {self.preview_rate_hz}')

"""feedback_node's parameters in one dataclass, the two trainers' and the node's own."""

from dataclasses import dataclass, fields
from typing import Union

from attention_tasks.task import DEFAULT_TASK, load_task
from feedback_node.judging import TeacherConfig, TRAINERS
from feedback_node.task_teacher import load_knowledge, TaskTeacher
from feedback_node.trainer import SyntheticTrainer, TrainerConfig

RUNTIME_PARAMETERS = ('synthetic',)
"""Settable while the node runs; every other parameter is read once at start (read-only)."""


@dataclass
class FeedbackConfig(TrainerConfig):
    """
    Each field is a ROS parameter of the same name; its docstring is the description.

    The fields of ``TrainerConfig`` (h, the stuck rule, and the teacher's: utterances, the
    human-like knobs, seed), then the node's. The teacher uses only ``TeacherConfig``'s.
    """

    task: str = DEFAULT_TASK
    """The task taught: 'montezuma' (Room 1, both trainers) or 'doorkey' (MiniGrid, the teacher
    only); any attention_tasks.<task> with a task module (and a teaching module, to teach it)."""
    trainer: str = 'thesis'
    """'thesis': h from the position (equations 4.1/4.2, the study); 'teacher': +1 when the
    action does what the expert's would, -1 otherwise, nothing while no action can matter."""
    synthetic: bool = True
    """true: the synthetic trainer speaks and judges; false: a person does (ros2 topic pub),
    this node only logs what it hears. Settable at run time."""
    plain_copies: bool = False
    """true: publish every stamped feedback on the plain feedback topic too (the learner logs
    such a copy as a duplicate); false: only the late teacher, which has no stamp to give, uses
    the plain topic."""
    press_times: bool = False
    """true: the late teacher publishes each verdict on ``feedback_pressed`` with the moment it
    gave it (simulation time) instead of plain on ``feedback``, and the learner credits it from
    that moment (as a console that times a person's key press could; ``ros2 topic pub`` cannot).
    Still no stamp of the step judged."""
    wait_feedback_subscribers: int = 1
    """Judgements are held (in order, with their stamps) until the feedback topic has this many
    matched subscribers: a volatile topic gives a message only to readers matched when it is
    sent (attention_train sets 2: the learner and its monitor)."""
    wait_utterance_subscribers: int = 0
    """Utterances are held likewise (in order) until ``utterance`` and ``utterance_stamped``
    each have this many matched subscribers besides this node (0: not held; attention_train
    sets 2: the saliency node and the learner, the saliency node and the launcher; 3 when it
    records a bag), so the first words, said at the first step, reach every listener."""
    wait_feedback_nodes: str = ''
    """Comma-separated names of nodes that must be matched on the feedback topic in use before
    this node listens to the steps (so the env waits) and held judgements go out, besides the
    count above (attention_train: tamer_node, and the recorder when it records). A count cannot
    tell the learner from a viewer: a Foxglove client watching the feedback made it while
    tamer_node was still being discovered, and the learner missed the first 224 judgements.
    '' = the count only."""
    wait_utterance_nodes: str = ''
    """Likewise for utterances, on ``utterance`` (attention_train: saliency_node, tamer_node)."""
    wait_utterance_stamped_nodes: str = ''
    """Likewise on ``utterance_stamped`` (attention_train: saliency_node)."""
    summary_period: float = 30.0
    """Wall seconds between the log lines of counts (when they changed)."""

    def __post_init__(self):
        """Check the node's fields, then the chosen trainer's (the teacher's alone for it)."""
        if self.summary_period <= 0:
            raise ValueError(f'summary_period must be > 0, got {self.summary_period}')
        if self.wait_feedback_subscribers < 1:
            raise ValueError('wait_feedback_subscribers must be >= 1, got '
                             f'{self.wait_feedback_subscribers}')
        if self.wait_utterance_subscribers < 0:
            raise ValueError('wait_utterance_subscribers must be >= 0, got '
                             f'{self.wait_utterance_subscribers}')
        if self.trainer not in TRAINERS:
            raise ValueError(f'trainer must be one of {TRAINERS}, got {self.trainer!r}')
        load_task(self.task)  # UnknownTask (a ValueError) names the installed tasks
        if self.task != DEFAULT_TASK and self.trainer == 'thesis':
            raise ValueError(
                f"trainer 'thesis' measures Room 1's critical positions: it teaches only "
                f'task {DEFAULT_TASK}; task {self.task!r} needs trainer:=teacher')
        if self.trainer == 'teacher':
            load_knowledge(self.task)  # UnknownTeacher (a ValueError): no teaching module
        self.trainer_config()

    def trainer_config(self) -> Union[TeacherConfig, TrainerConfig]:
        """Build the chosen trainer's config from these fields (it checks them)."""
        cls = TeacherConfig if self.trainer == 'teacher' else TrainerConfig
        return cls(**{f.name: getattr(self, f.name) for f in fields(cls)})

    def make_trainer(self) -> Union[TaskTeacher, SyntheticTrainer]:
        """Build the chosen trainer: the thesis's, or the teacher with the task's knowledge."""
        config = self.trainer_config()
        if self.trainer == 'thesis':
            return SyntheticTrainer(config)
        return TaskTeacher(load_knowledge(self.task), load_task(self.task).num_actions, config)

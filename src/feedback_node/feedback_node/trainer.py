"""
The synthetic trainer: one ``agent_position`` in, the feedback and utterance it causes out.

Attribution: the action chosen at observation T moves the agent to the position of the next
step T'. So when the position of T' arrives, the trainer judges it (``RewardFunction``) and
stamps the feedback T, the step whose action it judges. A move longer than any the agent can
make in one step (a reset after a terminal step, a respawn after a life lost) was not caused by
an action, so that pair is not judged.

Utterances are about where the agent is now: the position of T' speaks at T'.

A more human-like trainer (all off by default, which is the thesis's trainer): feedback on only
some steps (``feedback_probability``), given late (a delay drawn uniformly between
``feedback_delay_min`` and ``feedback_delay_max`` seconds of simulation time after the
consequence is seen; the feedback keeps the stamp of the step it judges), and sometimes wrong
(``feedback_noise``: the probability that the sign of h is flipped). Seeded.
"""

from dataclasses import dataclass, fields
from typing import List, NamedTuple, Optional

from attention_tasks.montezuma.reward import RewardConfig, RewardFunction
from feedback_node.human_like import FeedbackScheduler
from feedback_node.judging import TeacherConfig
from feedback_node.utterances import Utterance, UtteranceGenerator


@dataclass
class TrainerConfig(TeacherConfig, RewardConfig):
    """The thesis's trainer: h's parameters, the teacher's, and the stuck rule's buffer."""

    stuck_buffer_steps: int = 10
    """Length of the position buffer of the stuck rule: no utterance while all its positions are
    equal."""

    def __post_init__(self):
        TeacherConfig.__post_init__(self)
        RewardConfig.__post_init__(self)

    def reward_config(self) -> RewardConfig:
        return RewardConfig(**{f.name: getattr(self, f.name) for f in fields(RewardConfig)})


class Feedback(NamedTuple):
    """Scalar feedback on the action taken at step ``stamp_ns``."""

    stamp_ns: int
    """The step judged: its action led to the position of ``seen_ns``."""
    h: float
    position: int
    """The critical position the action led to, -1 in between."""
    distance: float
    """d (equation 4.1) of that position."""
    seen_ns: int
    """The step whose position was judged (the next step)."""
    flipped: bool = False
    """The noise option flipped the sign."""
    pressed_ns: int = 0
    """When it is given (simulation ns): ``seen_ns`` plus the human-like delay."""
    marked: bool = False
    """Given with the step it judges (``feedback_marked``): published stamped, not plain."""


class TrainerOutput(NamedTuple):
    """What to publish after one position."""

    feedback: List[Feedback]
    """Feedback due now, oldest stamp first (more than one only with a delay)."""
    utterance: Optional[Utterance]


class SyntheticTrainer:
    """Turns the agent's positions into feedback and utterances; pure and deterministic."""

    def __init__(self, config: Optional[TrainerConfig] = None):
        self.config = config or TrainerConfig()
        self.reward = RewardFunction(self.config.reward_config())
        self.utterances = UtteranceGenerator(
            interval_s=self.config.utterance_interval,
            stuck_buffer_steps=self.config.stuck_buffer_steps,
            radius=self.config.alpha_threshold)
        self.scheduler = FeedbackScheduler(self.config, self.config.seed)
        self._counts = {'positions': 0, 'judged': 0, 'unjudged_jumps': 0, 'duplicates': 0,
                        'restarts': 0}
        self.reset()

    @property
    def counts(self) -> dict:
        return dict(self._counts, **self.scheduler.counts)

    def reset(self) -> None:
        """Forget the trial so far (pending delayed feedback too)."""
        self.reward.reset()
        self.utterances.reset()
        self._last_ns: Optional[int] = None
        self.scheduler.clear()

    def on_position(self, stamp_ns: int, x: float, y: float) -> TrainerOutput:
        """Take the agent's position at step ``stamp_ns``; return what to publish now."""
        if self._last_ns is not None and stamp_ns == self._last_ns:
            self._counts['duplicates'] += 1  # the same step again (a re-send): already judged
            return TrainerOutput(feedback=self.scheduler.release(stamp_ns), utterance=None)
        if self._last_ns is not None and stamp_ns < self._last_ns:
            self._counts['restarts'] += 1  # stamps went back: a new trial started
            self.reset()
        self._counts['positions'] += 1
        judgement = self.reward(x, y)
        if self._last_ns is not None:
            if judgement.teleported:
                self._counts['unjudged_jumps'] += 1
            else:
                self._counts['judged'] += 1
                self.scheduler.consider(Feedback(stamp_ns=self._last_ns, h=float(judgement.h),
                                        position=judgement.position,
                                        distance=judgement.distance, seen_ns=stamp_ns))
        self._last_ns = stamp_ns
        return TrainerOutput(feedback=self.scheduler.release(stamp_ns),
                             utterance=self.utterances.observe(x, y, stamp_ns))

    @property
    def pending(self) -> int:
        """Delayed feedback not given yet."""
        return self.scheduler.pending

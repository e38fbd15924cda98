"""
What makes a synthetic trainer human-like: feedback on some steps only, late, sometimes wrong.

Shared by every trainer (``trainer.SyntheticTrainer``, the teachers' ``judging.ActionTeacher``).
All off by default: feedback on every step, at once, always right. Seeded, so a trial is
reproducible.
"""

from dataclasses import dataclass
import heapq
from typing import Dict, List, Tuple, TypeVar

from attention_common.stamps import NS_PER_S
import numpy as np

F = TypeVar('F')  # a feedback NamedTuple: stamp_ns, h, seen_ns, flipped, pressed_ns, marked


@dataclass
class HumanLike:
    """The three knobs; the feedback node's parameters carry the same names."""

    feedback_probability: float = 1.0
    """Probability that a judged step gets feedback at all (1 = every step)."""
    feedback_delay_min: float = 0.0
    """Shortest delay of feedback, seconds of simulation time after the consequence is seen."""
    feedback_delay_max: float = 0.0
    """Longest delay; drawn uniformly between the two."""
    feedback_noise: float = 0.0
    """Probability that the sign of h is flipped (h = 0 stays 0)."""
    feedback_marked: float = 0.0
    """Probability that a late verdict is given with the step it judges, as a person who
    pauses to judge that moment in the trainer console: it goes out stamped (the learner
    credits that step), the rest plain. 0 = none (a person who never pauses)."""

    def __post_init__(self):
        for name in ('feedback_probability', 'feedback_noise', 'feedback_marked'):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f'{name} must be in [0, 1], got {value}')
        if not 0.0 <= self.feedback_delay_min <= self.feedback_delay_max:
            raise ValueError('need 0 <= feedback_delay_min <= feedback_delay_max, got '
                             f'{self.feedback_delay_min} and {self.feedback_delay_max}')

    @property
    def delayed(self) -> bool:
        """Whether feedback comes late (then a person could not stamp it either)."""
        return self.feedback_delay_max > 0.0


HUMAN_LIKE_SETTING = HumanLike(feedback_probability=0.33, feedback_delay_min=0.3,
                               feedback_delay_max=1.5, feedback_noise=0.1)
"""The named human-like setting (``attention_train --human-like``): one step in three on
average, 0.3 to 1.5 s late, 10 % of signs wrong."""


class FeedbackScheduler:
    """Decides which feedback is given, with which sign, and when it is due."""

    def __init__(self, knobs: HumanLike, seed: int = 0):
        self.knobs = knobs
        self._rng = np.random.default_rng(seed)
        self.counts: Dict[str, int] = {'given': 0, 'skipped': 0, 'flipped': 0, 'marked': 0}
        self.clear()

    def clear(self) -> None:
        """Forget feedback not given yet (a new trial)."""
        self._pending: List[Tuple[int, int, object]] = []
        self._sequence = 0

    @property
    def pending(self) -> int:
        return len(self._pending)

    def consider(self, feedback: F) -> None:
        """Draw whether, how and when ``feedback`` is given; queue it."""
        knobs = self.knobs
        if knobs.feedback_probability < 1.0 and self._rng.random() >= knobs.feedback_probability:
            self.counts['skipped'] += 1
            return
        if knobs.feedback_noise > 0.0 and self._rng.random() < knobs.feedback_noise:
            if feedback.h != 0.0:
                feedback = feedback._replace(h=-feedback.h, flipped=True)
                self.counts['flipped'] += 1
        delay_s = knobs.feedback_delay_min
        if knobs.feedback_delay_max > knobs.feedback_delay_min:
            delay_s = self._rng.uniform(knobs.feedback_delay_min, knobs.feedback_delay_max)
        due_ns = feedback.seen_ns + int(round(delay_s * NS_PER_S))
        feedback = feedback._replace(pressed_ns=due_ns)
        if knobs.feedback_marked > 0.0 and self._rng.random() < knobs.feedback_marked:
            feedback = feedback._replace(marked=True)  # (no draw at 0: old runs reproduce)
            self.counts['marked'] += 1
        heapq.heappush(self._pending, (due_ns, self._sequence, feedback))
        self._sequence += 1

    def release(self, now_ns: int) -> List[F]:
        """Feedback due at ``now_ns``, oldest judged step first."""
        due = []
        while self._pending and self._pending[0][0] <= now_ns:
            due.append(heapq.heappop(self._pending)[2])
        self.counts['given'] += len(due)
        return sorted(due, key=lambda feedback: feedback.stamp_ns)

"""
Questions: the learner asks for a verdict on the step it is least sure of.

A verdict given late and plain can be credited only to a window of steps, and in Room 1 at 15
Hz that teaches nothing (docs/teaching.md, the credit probe); one that names its step teaches,
but a person cannot name the step of every press. So the agent asks: when H barely tells its
best action from the next (their gap, read within the feedback range as the greedy policy reads
it, below ``margin``), it asks the trainer about that step, at most ``rate`` questions per acted
step on average (a token bucket: ``rate`` a step, at most ``burst`` saved). The trainer answers
about the step asked, stamped with it, so the answer is credited to that step alone.

Pure (no rclpy): ``ActingPath`` asks after it has chosen; the node publishes the question.
"""

from typing import Optional

from attention_common.feedback import FEEDBACK_RANGE
import torch


class Asker:
    """Decides, for each acted step, whether to ask the trainer about it."""

    def __init__(self, rate: float, margin: float, burst: float = 5.0, budget: int = 0):
        if not 0.0 < rate <= 1.0:
            raise ValueError(f'ask_rate must be in (0, 1], got {rate}')
        if margin <= 0.0 or burst < 1.0:
            raise ValueError(f'need ask_margin > 0 and ask_burst >= 1, got {margin}, {burst}')
        self.rate = float(rate)
        self.margin = float(margin)
        self.burst = float(burst)
        self.budget = int(budget)
        """Questions in all (0: no end): asked at ``rate`` until spent."""
        self.asked = 0
        self._tokens = 0.0

    @staticmethod
    def gap(values: torch.Tensor) -> float:
        """Return how far H's best action is ahead of the next (within the feedback range)."""
        clipped = values.clamp(-FEEDBACK_RANGE, FEEDBACK_RANGE)
        if clipped.numel() < 2:
            return float('inf')
        top = torch.topk(clipped, 2).values
        return float(top[0] - top[1])

    def consider(self, values: torch.Tensor) -> Optional[float]:
        """Return the gap when this step is to be asked about, else None (one step acted)."""
        if self.budget and self.asked >= self.budget:
            return None
        self._tokens = min(self._tokens + self.rate, self.burst)
        if self._tokens < 1.0 - 1e-9:  # (ten tenths add up to a hair below one)
            return None
        gap = self.gap(values)
        if gap >= self.margin:
            return None
        self._tokens -= 1.0
        self.asked += 1
        return gap

    def clear(self) -> None:
        self._tokens = 0.0

"""
Warnings a burst can bring by the thousand, said in full up to a budget, then summed up (pure).

A line of rclpy's log costs about 0.3 ms; 20,000 feedback that match no step (a burst with no
steps to credit) once held tamer_node's exit for 4 s, and over 15 s on a busy machine. A
``LogBudget`` says the first ``per_period`` warnings of each period whole; the rest of the
period become one line with their number and the last of them. Nothing is lost: what each
warning is about is in the node's files and counters; the summary says how many were folded.
"""

import time
from typing import Callable, Optional

Log = Callable[[str, str], None]


class LogBudget:
    """Pass warnings on to ``log`` whole up to ``per_period`` a period, then fold them."""

    def __init__(self, log: Log, per_period: int = 20, period_s: float = 1.0,
                 clock: Callable[[], float] = time.monotonic):
        if per_period < 1 or not period_s > 0.0:
            raise ValueError('a log budget needs per_period >= 1 and period_s > 0')
        self._log, self._clock = log, clock
        self.per_period, self.period_s = per_period, period_s
        self._period_start = -float('inf')
        self._said = 0
        self.folded = 0
        """Warnings of this period not said whole yet."""
        self._last: Optional[str] = None

    def warn(self, text: str) -> None:
        self.flush_due()
        if self._said < self.per_period:
            self._said += 1
            self._log('warn', text)
            return
        self.folded += 1
        self._last = text

    def flush_due(self) -> None:
        """Start a new period if this one is over (saying what it folded)."""
        now = self._clock()
        if now - self._period_start >= self.period_s:
            self.flush()
            self._period_start, self._said = now, 0

    def flush(self) -> None:
        """Say the folded warnings now, as one line."""
        if self.folded:
            self._log('warn', f'{self.folded} more warning(s) like those above in '
                              f'{self.period_s:g} s, not said one by one; the last: {self._last}')
            self.folded, self._last = 0, None

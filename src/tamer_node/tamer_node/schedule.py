"""When the learner owes a minibatch update: a fixed number per second of a clock it is given."""

import math
from typing import Optional


class UpdateSchedule:
    """
    Count the minibatch updates owed at ``rate_hz`` per second of a clock (pure; no threads).

    The caller reads its clock (simulation seconds from the observation stamps, or wall
    seconds) and calls ``advance(t)``; ``take()`` hands out one owed update at a time. Updates
    are owed from ``start(t)`` on (the learner starts it once the replay buffer has a sample),
    so the number of updates per second of that clock does not depend on how fast it runs, as
    long as the learner keeps up. At most ``max_backlog`` updates may be owed: beyond that the
    oldest owed ones are dropped and counted in ``skipped``. A clock that goes back (a new trial
    restarted its stamps) restarts the count there, owing nothing for the jump.
    """

    def __init__(self, rate_hz: float, max_backlog: float):
        if rate_hz < 0.0:
            raise ValueError(f'rate_hz must be >= 0, got {rate_hz}')
        self.rate_hz = float(rate_hz)
        self.max_backlog = max(1.0, float(max_backlog))
        self.owed = 0.0
        """Updates owed now (fractional: the next one's share accrues)."""
        self.taken = 0
        self.skipped = 0
        self._last: Optional[float] = None

    @property
    def started(self) -> bool:
        return self._last is not None

    @property
    def last_reading(self) -> Optional[float]:
        """Return the clock time of the last ``start``/``advance`` (None before)."""
        return self._last

    def start(self, t: float) -> None:
        """Begin owing updates from clock time ``t`` on."""
        if self._last is None:
            self._last = float(t)

    def advance(self, t: float) -> None:
        """Read the clock (``t``): add the updates owed since the last reading."""
        if self._last is None or self.rate_hz == 0.0:
            return
        if t < self._last:
            self._last = float(t)
            return
        self.owed += (t - self._last) * self.rate_hz
        self._last = float(t)
        if self.owed > self.max_backlog:
            dropped = math.floor(self.owed - self.max_backlog)
            self.skipped += dropped
            self.owed -= dropped

    def due(self) -> bool:
        """Tell whether an update is owed now."""
        return self.owed >= 1.0 - 1e-9

    def take(self) -> bool:
        """Return True (and count it) if an update is owed now."""
        if self.due():
            self.owed = max(0.0, self.owed - 1.0)
            self.taken += 1
            return True
        return False

    def due_at(self) -> float:
        """Clock time at which the next update will be owed (inf if never)."""
        if self._last is None or self.rate_hz == 0.0:
            return math.inf
        if self.due():
            return self._last
        return self._last + (1.0 - self.owed) / self.rate_hz

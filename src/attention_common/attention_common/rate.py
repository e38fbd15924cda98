"""A token bucket: at most ``rate_hz`` events a second on average, bursts of ``burst`` allowed."""

from typing import Optional


class TokenBucket:
    """Tokens come at ``rate_hz`` up to ``burst``; an event passes if it can take one."""

    def __init__(self, rate_hz: float, burst: float = 5.0):
        if not rate_hz > 0 or not burst >= 1:
            raise ValueError(f'rate_hz must be > 0 and burst >= 1, got {rate_hz}, {burst}')
        self.rate_hz, self.burst = float(rate_hz), float(burst)
        self._tokens = self.burst
        self._at: Optional[float] = None

    def allow(self, now_s: float) -> bool:
        """Tell whether an event at ``now_s`` (monotonic seconds) passes; take a token if so."""
        if self._at is not None:
            self._tokens = min(self.burst, self._tokens + (now_s - self._at) * self.rate_hz)
        self._at = now_s
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        return False

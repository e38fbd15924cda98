"""
What a trainer says, and when: an utterance, an interval, and the thesis's stuck rule.

- The thesis's trainer says Figure 5.1's sentence of where the agent is (Room 1's words:
  ``attention_tasks.montezuma.sentences``; in between, the nearest position's).
- One utterance per interval of simulation time (default 10 s, what the thesis settled on);
  0 speaks at every step (Figure 5.4), a negative interval never speaks.
- The stuck rule: a buffer of the agent's recent positions; while all of them are the same the
  agent has not moved and nothing is said (so no saliency maps are made) until it moves again.
  An utterance that falls due while the agent is stuck is said at the first step it moves.
"""

import collections
from typing import Deque, NamedTuple, Optional, Tuple

from attention_common.stamps import NS_PER_S
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS
from attention_tasks.montezuma.sentences import IN_BETWEEN_MODES, sentence_for


class Utterance(NamedTuple):
    """One thing the trainer says."""

    text: str
    position: int
    """The critical position the agent stands on, -1 in between."""
    sentence_of: int
    """Whose Figure 5.1 sentence was said (the nearest position when in between)."""
    stamp_ns: int
    """The step at which it is said."""


class IntervalSchedule:
    """When the next utterance is due, in simulation time."""

    def __init__(self, interval_s: float):
        self.interval_s = float(interval_s)
        self._last_ns: Optional[int] = None

    @property
    def enabled(self) -> bool:
        return self.interval_s >= 0.0

    def due(self, now_ns: int) -> bool:
        """Whether an utterance should be said at ``now_ns`` (the first one at once)."""
        if not self.enabled:
            return False
        if self._last_ns is None or self.interval_s == 0.0:
            return True
        return now_ns - self._last_ns >= round(self.interval_s * NS_PER_S)

    def spoken(self, now_ns: int) -> None:
        self._last_ns = now_ns

    def reset(self) -> None:
        self._last_ns = None


class StuckDetector:
    """The thesis's position buffer: stuck while the last ``size`` positions are all equal."""

    def __init__(self, size: int):
        if size < 2:
            raise ValueError(f'the position buffer needs at least 2 entries, got {size}')
        self._buffer: Deque[Tuple[float, float]] = collections.deque(maxlen=size)

    def add(self, x: float, y: float) -> bool:
        """Record this step's position; return whether the agent is stuck."""
        self._buffer.append((float(x), float(y)))
        return self.stuck

    @property
    def stuck(self) -> bool:
        buffer = self._buffer
        return len(buffer) == buffer.maxlen and buffer.count(buffer[0]) == len(buffer)

    def reset(self) -> None:
        self._buffer.clear()


class UtteranceGenerator:
    """Figure 5.1 sentences on an interval, withheld while the agent is stuck."""

    def __init__(self, interval_s: float = 10.0, stuck_buffer_steps: int = 10,
                 radius: float = DEFAULT_RADIUS, in_between: str = 'nearest'):
        if in_between not in IN_BETWEEN_MODES:
            raise ValueError(f'in_between must be one of {IN_BETWEEN_MODES}, got {in_between!r}')
        self.schedule = IntervalSchedule(interval_s)
        self.stuck = StuckDetector(stuck_buffer_steps)
        self.radius = radius
        self.in_between = in_between
        self.withheld = 0
        """Steps at which an utterance was due but withheld because the agent was stuck."""

    def reset(self) -> None:
        self.schedule.reset()
        self.stuck.reset()

    def observe(self, x: float, y: float, stamp_ns: int) -> Optional[Utterance]:
        """Take this step's position; return what to say at this step, if anything."""
        stuck = self.stuck.add(x, y)
        if not self.schedule.due(stamp_ns):
            return None
        if stuck:
            self.withheld += 1
            return None
        self.schedule.spoken(stamp_ns)
        position, sentence_of, text = sentence_for(x, y, self.radius, self.in_between)
        return Utterance(text=text, position=position, sentence_of=sentence_of,
                         stamp_ns=stamp_ns)

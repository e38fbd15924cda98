"""
The synthetic trainer's words: Figure 5.1 of the thesis, an interval, and the stuck rule.

- ``SENTENCES`` is Figure 5.1: one sentence per critical position 0..5, and the thesis's
  sentence for -1 (everywhere else).
- In between (-1) the thesis speaks "toward the nearest critical position" (section 5). The
  generator therefore says the sentence of the nearest position, so that what is said names the
  things near the agent (the template matcher looks for them). The literal -1 sentence ("Go back
  to the top of the ladder and jump onto the rope.") is kept in ``SENTENCES[-1]`` and is said
  with ``in_between='literal'``.
- One utterance per interval of simulation time (default 10 s, what the thesis settled on);
  0 speaks at every step (Figure 5.4), a negative interval never speaks.
- The stuck rule: a buffer of the agent's recent positions; while all of them are the same the
  agent has not moved and nothing is said (so no saliency maps are made) until it moves again.
  An utterance that falls due while the agent is stuck is said at the first step it moves.
"""

import collections
from typing import Deque, NamedTuple, Optional, Tuple

from attention_common.stamps import NS_PER_S
from attention_tasks.montezuma.critical_positions import (
    critical_position_at, DEFAULT_RADIUS, nearest_critical_position, OUTSIDE)

SENTENCES = {
    -1: 'Go back to the top of the ladder and jump onto the rope.',
    0: 'Jump right from the ladder onto the rope.',
    1: 'Jump right from the rope onto the lower platform.',
    2: 'Climb down the ladder onto the ground.',
    3: 'Move left and avoid the skull.',
    4: 'Climb up the ladder.',
    5: 'Jump up to get the key.',
}
"""Figure 5.1: the sentence for each current position (-1 = in between)."""

IN_BETWEEN_MODES = ('nearest', 'literal')


class Utterance(NamedTuple):
    """One thing the trainer says."""

    text: str
    position: int
    """The critical position the agent stands on, -1 in between."""
    sentence_of: int
    """Whose Figure 5.1 sentence was said (the nearest position when in between)."""
    stamp_ns: int
    """The step at which it is said."""


def sentence_for(x: float, y: float, radius: float = DEFAULT_RADIUS,
                 in_between: str = 'nearest') -> Tuple[int, int, str]:
    """Return ``(position, sentence_of, text)`` for an agent at (x, y)."""
    position = critical_position_at(x, y, radius)
    if position != OUTSIDE:
        return position, position, SENTENCES[position]
    if in_between == 'literal':
        return OUTSIDE, OUTSIDE, SENTENCES[OUTSIDE]
    nearest, _ = nearest_critical_position(x, y)
    return OUTSIDE, nearest, SENTENCES[nearest]


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

"""
What the learner made of the person: H on each step, and the steps each feedback was credited to.

Pure (no rclpy) and thread-safe: the node hands in the fields of ``action_values`` and
``feedback_credit`` (diagnostic_msgs/DiagnosticArray: status name, message, key-values) and, from
the receipts, the log ``seq`` of each of *our* presses; the web server asks ``view(stamp)`` for
the frame it just sent. The credit and the receipt of one feedback come on two topics, from two
threads of the learner, in either order: a credit waits among the others until a receipt says
its seq is ours. Stamps are integer ns (JSON gets them as strings: wall-clock ones exceed 2**53).
"""

import bisect
import collections
from dataclasses import dataclass
import math
import threading
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

from attention_common.stamps import MAX_STAMP_JUMP_S, NS_PER_S

STEPS_KEPT = 300
"""H of the last steps kept (20 s at 15 Hz): the frame on screen is among them."""
PRESSES_KEPT = 20
"""Credits of our last presses kept (the strip colours the ones still in it)."""
OTHERS_KEPT = 50
"""Credits not (yet) known to be ours: another publisher's, or ours before its receipt."""
STRIP_STEPS = 150
"""Steps in the strip under the frame (10 s at 15 Hz: a 4 s window stays in sight for 6 s)."""
Pairs = Sequence[Tuple[str, str]]


class Malformed(ValueError):
    """A message that breaks the topic's contract (counted, then ignored)."""


@dataclass(frozen=True)
class StepValues:
    """H of every action on one step, and the action the learner took there."""

    stamp: int
    action: int
    version: Optional[int]
    names: Tuple[str, ...]
    h: Tuple[Optional[float], ...]
    """In action order; None where H is not finite (JSON has no NaN)."""


@dataclass(frozen=True)
class Credit:
    """One feedback the learner learned from, and the steps its credit went to."""

    seq: int
    """Its number in the learner's feedback log (the receipt's ``seq``)."""
    h: float
    mode: str
    """'step' or 'window'."""
    steps: Tuple[Tuple[int, float], ...]
    """(stamp, weight), in time order."""

    @property
    def total(self) -> float:
        return sum(weight for _, weight in self.steps)


def _number(text: str, what: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        raise Malformed(f'{what} is not a number: {text!r}') from None


def _integer(text: str, what: str) -> int:
    try:
        return int(text)
    except (TypeError, ValueError):
        raise Malformed(f'{what} is not an integer: {text!r}') from None


def parse_values(stamp: int, name: str, message: str, pairs: Pairs) -> StepValues:
    """Read one ``action_values`` status; raise Malformed if it breaks the contract."""
    if name != 'action_values':
        raise Malformed(f'status {name!r} is not action_values')
    values = dict(pairs)
    action = _integer(values.get('action'), 'action')
    version = values.get('version')
    rest = [(key, value) for key, value in pairs if key not in ('action', 'version')]
    if not rest:
        raise Malformed('no action has an H')
    names = tuple(key for key, _ in rest)
    h = tuple(_number(value, f'H of {key}') for key, value in rest)
    if not 0 <= action < len(names) or names[action] != message:
        raise Malformed(f'action {action} ({message!r}) is not one of {len(names)} actions')
    return StepValues(int(stamp), action, _integer(version, 'version') if version else None,
                      names, tuple(x if math.isfinite(x) else None for x in h))


def parse_credit(name: str, message: str, pairs: Pairs) -> Credit:
    """Read one ``feedback_credit`` status; raise Malformed if it breaks the contract."""
    if name != 'feedback_credit':
        raise Malformed(f'status {name!r} is not feedback_credit')
    values = dict(pairs)
    seq, h = _integer(values.get('seq'), 'seq'), _number(values.get('h'), 'h')
    steps = []
    for key, value in pairs:
        if key not in ('seq', 'h'):
            weight = _number(value, f'weight of {key}')
            if not (math.isfinite(weight) and weight >= 0.0):
                raise Malformed(f'weight of {key} is {weight}')
            steps.append((_integer(key, 'a credited stamp'), weight))
    if not math.isfinite(h):
        raise Malformed(f'h is {h}')
    return Credit(seq, h, message, tuple(sorted(steps)))


class LearnerView:
    """H by step stamp and the credit of our last presses, bounded; ``view`` for the page."""

    def __init__(self, steps_kept: int = STEPS_KEPT, presses_kept: int = PRESSES_KEPT,
                 strip_steps: int = STRIP_STEPS, others_kept: int = OTHERS_KEPT):
        self.steps_kept, self.strip_steps = steps_kept, strip_steps
        self.presses_kept, self.others_kept = presses_kept, others_kept
        self._lock = threading.Lock()
        self._steps: List[StepValues] = []  # by stamp
        self._ours: Dict[int, Credit] = collections.OrderedDict()
        self._others: Dict[int, Credit] = collections.OrderedDict()
        self._our_seqs: collections.deque = collections.deque(maxlen=presses_kept)
        self.malformed = {'action_values': 0, 'feedback_credit': 0}

    # What the node hands in (rclpy's thread).
    def on_values(self, stamp: int, status: Optional[tuple]) -> Optional[str]:
        """Take ``(name, message, pairs)`` of an action_values; return why not, if not."""
        try:
            if status is None:
                raise Malformed('no status')
            step = parse_values(stamp, *status)
        except Malformed as error:
            return self._bad('action_values', error)
        with self._lock:
            steps = self._steps
            if steps and step.stamp < steps[-1].stamp - MAX_STAMP_JUMP_S * NS_PER_S:
                steps.clear()  # the stamps started over: a new env
            i = bisect.bisect_left(steps, step.stamp, key=_stamp)
            if i < len(steps) and steps[i].stamp == step.stamp:
                steps[i] = step
            else:
                steps.insert(i, step)
            if len(steps) > self.steps_kept:
                del steps[:-self.steps_kept]
        return None

    def on_credit(self, status: Optional[tuple]) -> Optional[str]:
        """Take ``(name, message, pairs)`` of a feedback_credit; return why not, if not."""
        try:
            if status is None:
                raise Malformed('no status')
            credit = parse_credit(*status)
        except Malformed as error:
            return self._bad('feedback_credit', error)
        with self._lock:
            if credit.seq in self._our_seqs:
                _put(self._ours, credit, self.presses_kept)
            else:
                _put(self._others, credit, self.others_kept)
        return None

    def ours(self, seq: int) -> None:
        """Note that the learner logged one of our presses as ``seq`` (its receipt)."""
        seq = int(seq)
        with self._lock:
            self._ours.pop(seq, None)  # a seq of an earlier run's log, if any
            self._our_seqs.append(seq)
            credit = self._others.pop(seq, None)  # its credit came first
            if credit is not None:
                _put(self._ours, credit, self.presses_kept)

    def _bad(self, topic: str, error: Malformed) -> str:
        with self._lock:
            self.malformed[topic] += 1
        return f'{topic} ignored: {error}'

    # What the page shows (the web server's thread).
    def view(self, frame: Optional[int] = None) -> dict:
        """Return H of the frame ``frame`` (or the newest step not newer) and the strip."""
        with self._lock:
            end = (len(self._steps) if frame is None
                   else bisect.bisect_right(self._steps, frame, key=_stamp))
            strip = self._steps[max(0, end - self.strip_steps):end]
            ours = sorted(self._ours.values(), key=lambda credit: credit.seq)
            waiting = [seq for seq in self._our_seqs if seq not in self._ours]
            others = list(self._others.values())
            malformed = dict(self.malformed)
        step = strip[-1] if strip else None
        cells = strip_cells([s.stamp for s in strip], ours)
        newest = ours[-1] if ours else None
        return {
            'frame': None if frame is None else str(frame),
            'values': None if step is None else {
                'stamp': str(step.stamp), 'exact': step.stamp == frame,
                'behind_ms': None if frame is None else round((frame - step.stamp) / 1e6, 1),
                'action': step.action, 'taken': step.names[step.action],
                'version': step.version, 'names': list(step.names), 'h': list(step.h)},
            'strip': {'size': self.strip_steps, 'steps': len(strip),
                      'first': str(strip[0].stamp) if strip else None,
                      'last': str(step.stamp) if step else None, 'cells': cells},
            'newest': None if newest is None else dict(
                _summary(newest), shown=sum(1 for cell in cells if cell[2] == newest.seq)),
            'waiting': [seq for seq in waiting if newest is None or seq > newest.seq],
            'others': {'count': len(others),
                       'newest': _summary(others[-1]) if others else None},
            'malformed': malformed,
        }


def strip_cells(stamps: Sequence[int], credits: Iterable[Credit]) -> List[list]:
    """
    Return ``[index, stamp, seq, sign, level]`` of each strip step a credit went to.

    ``stamps`` are the strip's steps in time order; ``credits`` oldest first: a newer press
    takes a cell an older one also credits. ``level`` is the weight over the press's largest
    weight (window weights are small: a 4 s window at 15 Hz gives each step about 1/57).
    """
    index = {stamp: i for i, stamp in enumerate(stamps)}
    cells = {}
    for credit in credits:
        top = max((weight for _, weight in credit.steps), default=0.0) or 1.0
        sign = (credit.h > 0) - (credit.h < 0)
        for stamp, weight in credit.steps:
            if stamp in index:
                cells[stamp] = [index[stamp], str(stamp), credit.seq, sign,
                                round(weight / top, 3)]
    return sorted(cells.values())


def _stamp(step: StepValues) -> int:
    return step.stamp


def _summary(credit: Credit) -> dict:
    return {'seq': credit.seq, 'h': credit.h, 'mode': credit.mode,
            'steps': len(credit.steps), 'sum': round(credit.total, 4)}


def _put(kept: Dict[int, Credit], credit: Credit, bound: int) -> None:
    kept.pop(credit.seq, None)
    kept[credit.seq] = credit
    while len(kept) > bound:
        kept.pop(next(iter(kept)))

"""
What the console knows and shows, without rclpy or the web server (pure, unit-tested).

The node feeds it what it hears (``on_*``) and what it sends (``sent``); the web server reads
``snapshot()``. A key press is *given* when published and *confirmed* only once the learner's
receipt on ``feedback_logged`` names it: the learner logged that message, not just some message.
A message is named by its publisher's sequence number (1, 2, 3, ... per publisher, from DDS)
and its source time, which both the console and the receipt know. The receipt of a press of
ours also gives its ``seq`` in the learner's log: what ``learner`` (H and credit) keys it by.
"""

import collections
from dataclasses import dataclass, field
import math
import threading
import time
from typing import Callable, Deque, Dict, List, Optional, Sequence

from trainer_console.learner_view import LearnerView

RECEIPT_WINDOW_NS = 10 * 1_000_000_000
"""A receipt names a press when the sequence number matches and the times are this close."""
HISTORY_POINTS = 600
"""Points of the progress plot (one per second: the last 10 minutes)."""
RECENT_PRESSES = 200


@dataclass
class Press:
    """One feedback or utterance the person gave."""

    kind: str
    """'feedback' or 'utterance' (the receipt's status name)."""
    value: object
    """h, or the utterance's text."""
    publication_seq: int
    sent_ns: int
    """Wall time of the publish, ns."""
    source: str = 'plain'
    """The topic it went on, as the learner's log names it: 'plain' (``feedback``,
    ``utterance``) or 'pressed' (``feedback_pressed``: with the moment it was given)."""
    confirmed: bool = False
    status: str = ''
    """The learner's status for it ('ok', 'invalid', 'empty', ...), once confirmed."""


@dataclass
class ConsoleState:
    """The console's whole view, thread-safe (rclpy callbacks write, the web loop reads)."""

    ground: Callable[[str], Sequence[str]] = lambda text: ()
    """Utterance -> names of the objects it names (the saliency node's grounding)."""
    position_of: Callable[[float, float], int] = lambda x, y: -1
    """(x, y) -> critical position index, -1 in between."""
    milestone_of: Optional[Callable[[dict], int]] = None
    """The task's measure on env_status values (``Task.milestone_of``); when set, it takes the
    place of ``position_of`` (DoorKey: the last sub-goal done)."""
    milestones: Sequence[str] = tuple(f'critical position {i}' for i in range(6))
    """Names of the task's milestones, in order (the page scales its curve by their number)."""
    presses: Deque[Press] = field(default_factory=lambda: collections.deque(
        maxlen=RECENT_PRESSES))
    given: Dict[str, int] = field(default_factory=lambda: {'feedback': 0, 'utterance': 0})
    confirmed: Dict[str, int] = field(default_factory=lambda: {'feedback': 0, 'utterance': 0})
    last_utterance: str = ''
    named: List[str] = field(default_factory=list)
    status: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    furthest: int = -1
    paused: bool = False
    judge_paused_frame: bool = True
    """While paused, a press judges the frame on screen (the page says so)."""
    paused_by_env: bool = False
    """The env paused itself (pause_each_episode): its next running step ends the pause here."""
    listeners: Dict[str, List[str]] = field(default_factory=dict)
    """kind -> the nodes that subscribe to its topic (from the ROS graph)."""
    history: Deque[tuple] = field(default_factory=lambda: collections.deque(
        maxlen=HISTORY_POINTS))
    learner: LearnerView = field(default_factory=LearnerView)
    """H of each step and the credit of our presses (the panels under the frame)."""
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _last_point: float = 0.0

    def sent(self, kind: str, value, publication_seq: int, sent_ns: int,
             source: str = 'plain') -> Press:
        """Note a message the console published (before its receipt can come)."""
        press = Press(kind, value, int(publication_seq), int(sent_ns), source)
        with self._lock:
            self.presses.append(press)
            self.given[kind] += 1
        return press

    def on_receipt(self, kind: str, publication_seq: Optional[int],
                   source_time_ns: Optional[int], status: str = 'ok',
                   source: Optional[str] = None) -> Optional[Press]:
        """
        Confirm the press the learner's receipt names; None if it names none of ours.

        ``source`` (the receipt's, when it has one) tells the publisher: the console's plain
        and pressed publishers each number their messages from 1.
        """
        if publication_seq is None or source_time_ns is None:
            return None
        with self._lock:
            for press in self.presses:
                if (not press.confirmed and press.kind == kind
                        and source in (None, press.source)
                        and press.publication_seq == int(publication_seq)
                        and abs(press.sent_ns - int(source_time_ns)) <= RECEIPT_WINDOW_NS):
                    press.confirmed, press.status = True, status
                    self.confirmed[kind] += 1
                    return press
        return None

    def on_receipt_message(self, msg) -> None:
        """Take a ``feedback_logged`` message (diagnostic_msgs/DiagnosticArray) of receipts."""
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            try:
                seq, source = int(values['publication_seq']), int(values['source_time_ns'])
            except (KeyError, ValueError):
                continue  # a receipt without a DDS identity names nobody's press
            press = self.on_receipt(status.name, seq, source, values.get('status', 'ok'),
                                    values.get('source'))
            if press is not None and press.kind == 'feedback' and press.status == 'ok':
                try:
                    self.learner.ours(int(values['seq']))  # its credit will name this seq
                except (KeyError, ValueError):
                    pass

    def on_utterance(self, text: str) -> None:
        """Take an utterance said by anyone: what it names is what the saliency image keeps."""
        named = list(self.ground(text))
        with self._lock:
            self.last_utterance, self.named = text, named

    def on_status(self, values: dict, now: Optional[float] = None, message: str = '') -> None:
        """Take one env_status (parsed key-values; ``message``: the env's 'paused', ...)."""
        if message == 'paused':
            self.paused = self.paused_by_env = True
        elif message == 'running' and self.paused_by_env:
            self.paused = self.paused_by_env = False
        position = -1
        if self.milestone_of is not None:
            position = self.milestone_of(values)
        elif values.get('room') == 1 and 'x' in values and 'y' in values:
            position = self.position_of(values['x'], values['y'])
        with self._lock:
            self.status = dict(values)
            self.furthest = max(self.furthest, position)
        self._point(now)

    def on_metrics(self, values: dict) -> None:
        """Take the learner's metrics; NaN and inf become None (JSON has neither)."""
        finite = {key: (value if math.isfinite(value) else None)
                  for key, value in values.items()}
        with self._lock:
            self.metrics = finite

    def _point(self, now: Optional[float]) -> None:
        now = time.monotonic() if now is None else now
        with self._lock:
            if now - self._last_point >= 1.0:
                self._last_point = now
                self.history.append((round(now, 2), self.status.get('agent_step', 0),
                                     self.furthest, self.confirmed['feedback']))

    def snapshot(self) -> dict:
        """Everything the page shows, as JSON-ready values."""
        with self._lock:
            metrics = self.metrics
            return {
                'given': dict(self.given), 'confirmed': dict(self.confirmed),
                'unconfirmed': [{'kind': p.kind, 'value': p.value, 'seq': p.publication_seq}
                                for p in self.presses if not p.confirmed][-20:],
                'last': [{'kind': p.kind, 'value': p.value, 'confirmed': p.confirmed,
                          'status': p.status} for p in list(self.presses)[-8:]],
                'utterance': self.last_utterance, 'named': list(self.named),
                'step': self.status.get('agent_step'), 'episode': self.status.get('episode'),
                'lives': self.status.get('lives'), 'has_key': self.status.get('has_key'),
                'furthest': self.furthest, 'milestones': list(self.milestones),
                'paused': self.paused,
                'judges_frame': self.paused and self.judge_paused_frame,
                'listeners': dict(self.listeners),
                'learner': {key: metrics.get(key) for key in (
                    'feedback/received', 'feedback/logged', 'feedback/count', 'train/loss',
                    'train/updates', 'model/version')},
                'history': list(self.history),
            }

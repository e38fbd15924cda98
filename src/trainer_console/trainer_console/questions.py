"""
The learner's questions at the console (pure: no rclpy, no web server; unit-tested).

tamer_node (``ask_rate``) asks about the steps it is least sure of: ``question`` carries the
step's stamp, the action taken and the gap of H's two best actions. The console shows one
question at a time: the env is paused, the asked frame is put on screen (from the recent frames
held here by stamp) with its H, and a press on it answers, stamped with that step. Questions
that come while one is open wait their turn (at most ``MAX_WAITING``); every question heard ends
in exactly one count: answered, skipped, lost (its frame never reached the console, or too many
waited) or not shown (``answer_questions`` false).
"""

import collections
from dataclasses import dataclass
import threading
from typing import Deque, Dict, Optional

FRAMES_HELD = 300
"""Recent frames kept by stamp (20 s at 15 Hz): a question names a step a few frames back."""
BYTES_HELD = 32 * 2 ** 20
"""At most this much of them (300 of Room 1's 210x160 RGB frames are 30 MB)."""
MAX_WAITING = 20
"""Questions waiting behind the one on screen; more are counted lost."""
FRAME_PATIENCE_S = 2.0
"""How long a question waits for its frame to reach the console before it is counted lost."""
OUTCOMES = ('answered', 'skipped', 'lost', 'not_shown')


@dataclass(frozen=True)
class Question:
    """One question of the learner: the step (its observation's stamp), the action, the gap."""

    stamp_ns: int
    action: int
    gap: float
    heard_at: float
    """Monotonic time it was heard (a missing frame is waited for ``FRAME_PATIENCE_S``)."""


class QuestionDesk:
    """The questions heard, the one on screen, and the recent frames they point at."""

    def __init__(self, show: bool = True, frames_held: int = FRAMES_HELD,
                 max_waiting: int = MAX_WAITING, bytes_held: int = BYTES_HELD):
        self.show = show
        self._frames: 'collections.OrderedDict[int, tuple]' = collections.OrderedDict()
        self._frames_held, self._bytes_held, self._bytes = frames_held, bytes_held, 0
        self._waiting: Deque[Question] = collections.deque()
        self._max_waiting = max_waiting
        self.current: Optional[Question] = None
        """The question on screen (its frame is held), or None."""
        self.counts: Dict[str, int] = dict.fromkeys(('heard',) + OUTCOMES, 0)
        self._lock = threading.Lock()

    def on_frame(self, stamp_ns: int, frame, size: int = 0) -> Optional[Question]:
        """Hold a frame (``size`` bytes); return a question that can now go on screen."""
        with self._lock:
            old = self._frames.pop(int(stamp_ns), None)
            self._bytes += int(size) - (old[1] if old else 0)
            self._frames[int(stamp_ns)] = (frame, int(size))
            while self._frames and (len(self._frames) > self._frames_held
                                    or self._bytes > self._bytes_held):
                self._bytes -= self._frames.popitem(last=False)[1][1]
            return self._next(now=None)

    def on_question(self, question: Question) -> Optional[Question]:
        """Take a question; return it when it goes on screen now (nothing else open)."""
        with self._lock:
            self.counts['heard'] += 1
            if not self.show:
                self.counts['not_shown'] += 1
                return None
            if len(self._waiting) >= self._max_waiting:
                self.counts['lost'] += 1
                return None
            self._waiting.append(question)
            return self._next(now=question.heard_at)

    def frame(self, stamp_ns: int):
        """Return the frame held for a stamp, or None."""
        with self._lock:
            held = self._frames.get(int(stamp_ns))
            return None if held is None else held[0]

    def close(self, outcome: str, stamp_ns: Optional[int] = None,
              now: Optional[float] = None) -> Optional[Question]:
        """
        End the question on screen as ``outcome`` ('answered' or 'skipped'); return the next.

        With ``stamp_ns``, only a question about that step is closed (an answer names the frame
        it was given on); otherwise None is returned and nothing changes.
        """
        if outcome not in OUTCOMES:
            raise ValueError(f'unknown outcome {outcome!r}')
        with self._lock:
            if self.current is None or (stamp_ns is not None
                                        and int(stamp_ns) != self.current.stamp_ns):
                return None
            self.counts[outcome] += 1
            self.current = None
            return self._next(now)

    def skip_all(self) -> int:
        """End every question (the person resumed the env themself); return how many."""
        with self._lock:
            ended = len(self._waiting) + (self.current is not None)
            self.counts['skipped'] += ended
            self._waiting.clear()
            self.current = None
            return ended

    def tick(self, now: float) -> Optional[Question]:
        """Count lost the questions whose frame did not come in time; return one now shown."""
        with self._lock:
            return self._next(now)

    def is_open(self) -> bool:
        """Tell whether a question is on screen or waiting."""
        with self._lock:
            return self.current is not None or bool(self._waiting)

    def snapshot(self, action_names=()) -> dict:
        """Return the page's view: the question on screen (stamp a string), waiting, counts."""
        with self._lock:
            shown = None
            if self.current is not None:
                q = self.current
                name = (action_names[q.action] if 0 <= q.action < len(action_names)
                        else str(q.action))
                shown = {'stamp': str(q.stamp_ns), 'action': q.action, 'taken': name,
                         'gap': round(q.gap, 4)}
            return {'question': shown, 'waiting': len(self._waiting),
                    'counts': dict(self.counts)}

    def _next(self, now: Optional[float]) -> Optional[Question]:
        """With nothing on screen, put up the oldest waiting question whose frame is held."""
        if self.current is not None:
            return None
        newest = next(reversed(self._frames)) if self._frames else None
        while self._waiting:
            question = self._waiting[0]
            if question.stamp_ns in self._frames:
                self.current = self._waiting.popleft()
                return self.current
            passed = newest is not None and newest > question.stamp_ns
            too_long = now is not None and now - question.heard_at > FRAME_PATIENCE_S
            if not (passed or too_long):
                return None  # its frame may still be on its way
            self._waiting.popleft()
            self.counts['lost'] += 1
        return None

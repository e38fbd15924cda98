"""The scale of a trainer's feedback, shared by the nodes that give, check and model it."""

import collections

FEEDBACK_RANGE = 1.0
"""A trainer's feedback h lies in [-FEEDBACK_RANGE, FEEDBACK_RANGE] ("good" +1, "bad" -1)."""

COPY_WINDOW_S = 3.0
"""Wall seconds within which a plain feedback may be a trainer's copy of a verdict."""


class PlainCopies:
    """
    Tell a synthetic trainer's plain copy of a verdict from a person's own plain feedback.

    A trainer with ``plain_copies`` sends each stamped (or pressed) verdict again as plain
    ``feedback``. A plain message is such a copy only when it pairs with a verdict of the same h
    that came at most ``window_s`` before it and is not paired yet: one copy per verdict, so a
    person's plain presses beside a stream of verdicts (``ros2 topic pub``, ``teach``, the
    console while paused) are all their own. Not thread-safe: one caller, or the caller's lock.
    """

    MAX_WAITING = 4096

    def __init__(self, window_s: float = COPY_WINDOW_S):
        self.window_s = window_s
        self._waiting = collections.deque()  # (arrival, h) of verdicts not paired yet

    def verdict(self, arrived: float, h: float) -> None:
        """Note a stamped or pressed verdict that arrived at ``arrived`` (monotonic s)."""
        self._waiting.append((arrived, h))
        if len(self._waiting) > self.MAX_WAITING:
            self._waiting.popleft()

    def is_copy(self, arrived: float, h: float) -> bool:
        """Pair a plain feedback with the oldest waiting verdict of the same h; tell if it did."""
        while self._waiting and arrived - self._waiting[0][0] >= self.window_s:
            self._waiting.popleft()
        for index, (_, waiting) in enumerate(self._waiting):
            if waiting == h:
                del self._waiting[index]
                return True
        return False

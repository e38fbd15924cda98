"""
Decide when an observation gets a saliency image, and under which utterance (no rclpy).

An utterance is valid from its stamp for ``ttl`` of simulation time. An observation stamped T
gets an image under the newest utterance stamped at or before T that is still valid at T. An
observation with no valid utterance is held (a bounded buffer, oldest dropped first) because
the synthetic trainer's stamped utterance for step T can arrive after observation T: when it
does, the held observations it covers are released. A held observation is released once.
With ``require_utterance`` false every observation is released at once, with the valid
utterance if there is one.
"""

import bisect
import collections
from typing import Any, List, NamedTuple, Optional, Tuple


class Utterance(NamedTuple):
    """Something said, valid from its stamp (None until a plain one is stamped)."""

    stamp_ns: Optional[int]
    text: str
    payload: Any = None
    """Whatever the caller wants back with it (the grounding)."""


class Release(NamedTuple):
    """An observation to render now."""

    stamp_ns: int
    item: Any
    utterance: Optional[Utterance]


class Timeline:
    """Pairs observations with the utterance valid at their stamp."""

    def __init__(self, ttl_ns: int, capacity: int = 64, require_utterance: bool = True,
                 history: int = 256):
        self.ttl_ns = int(ttl_ns)
        self.capacity = int(capacity)
        self.require_utterance = require_utterance
        self._utterances: List[Utterance] = []  # sorted by stamp
        self._stamps: List[int] = []  # their stamps, for bisect
        self._history = history
        self._held: 'collections.OrderedDict[int, Any]' = collections.OrderedDict()
        self._unstamped: List[Utterance] = []  # spoken before any observation
        self.now_ns: Optional[int] = None
        self.dropped = 0
        """Observations evicted from the buffer without ever having a valid utterance."""

    def valid_at(self, stamp_ns: int) -> Optional[Utterance]:
        """Return the newest utterance stamped at or before ``stamp_ns`` and valid then."""
        index = bisect.bisect_right(self._stamps, stamp_ns)
        if index == 0:
            return None
        utterance = self._utterances[index - 1]
        return utterance if stamp_ns < utterance.stamp_ns + self.ttl_ns else None

    @property
    def held(self) -> int:
        return len(self._held)

    def add_utterance(self, text: str, stamp_ns: Optional[int] = None,
                      payload: Any = None) -> Tuple[Utterance, List[Release]]:
        """
        Add an utterance (stamp None: stamped now).

        Returns it and the held observations it covers (before any observation, a plain
        utterance waits for the first one: its stamp is then None).
        """
        if stamp_ns is None:
            if self.now_ns is None:
                pending = Utterance(None, text, payload)
                self._unstamped.append(pending)
                return pending, []
            stamp_ns = self.now_ns
        utterance = Utterance(int(stamp_ns), text, payload)
        index = bisect.bisect_right(self._stamps, utterance.stamp_ns)
        self._stamps.insert(index, utterance.stamp_ns)
        self._utterances.insert(index, utterance)
        del self._stamps[:-self._history], self._utterances[:-self._history]
        released = []
        for stamp in [s for s in self._held if s >= utterance.stamp_ns]:
            valid = self.valid_at(stamp)
            if valid is not None:
                released.append(Release(stamp, self._held.pop(stamp), valid))
        return utterance, released

    def discard(self, utterance: Utterance) -> None:
        """Withdraw an utterance (a copy of another); observations it released stay released."""
        for index, pending in enumerate(self._unstamped):
            if pending is utterance:
                del self._unstamped[index]
                return
        for index in reversed(range(len(self._utterances))):
            known = self._utterances[index]
            if known is utterance or (utterance.stamp_ns is None  # stamped since it was said
                                      and known[1:] == utterance[1:]):
                del self._utterances[index], self._stamps[index]
                return

    def add_observation(self, stamp_ns: int, item: Any) -> List[Release]:
        """Add an observation; return it if it can be rendered now (else it is held)."""
        stamp_ns = int(stamp_ns)
        self.now_ns = stamp_ns if self.now_ns is None else max(self.now_ns, stamp_ns)
        early, self._unstamped = self._unstamped, []
        for pending in early:
            self.add_utterance(pending.text, stamp_ns, pending.payload)
        utterance = self.valid_at(stamp_ns)
        if utterance is not None or not self.require_utterance:
            self._held.pop(stamp_ns, None)
            return [Release(stamp_ns, item, utterance)]
        self._held[stamp_ns] = item
        self._held.move_to_end(stamp_ns)
        while len(self._held) > self.capacity:
            self._held.popitem(last=False)
            self.dropped += 1
        return []

    def clear_held(self) -> int:
        """Drop every held observation (e.g. when saliency is switched off); return how many."""
        count = len(self._held)
        self._held.clear()
        return count

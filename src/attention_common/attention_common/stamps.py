"""
Stamps as integer nanoseconds, and a bounded store that pairs messages by stamp.

Every stamped message of one environment step carries that step's stamp, so integer
nanoseconds are an exact key for pairing (floats are not).
"""

import collections
import threading
from typing import Generic, Optional, TypeVar

from builtin_interfaces.msg import Time

NS_PER_S = 1_000_000_000

V = TypeVar('V')


def stamp_to_ns(stamp) -> int:
    """Convert builtin_interfaces/Time (or anything with sec, nanosec) to int nanoseconds."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """Convert int nanoseconds to builtin_interfaces/Time."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return Time(sec=sec, nanosec=nanosec)


def frames_to_ns(frames: int, frame_rate_hz: float = 60.0) -> int:
    """Return the simulation time of ``frames`` emulator frames (the Atari runs at 60 Hz)."""
    return int(round(frames * NS_PER_S / frame_rate_hz))


class StampStore(Generic[V]):
    """
    A bounded, thread-safe map from stamp (ns) to a value, oldest evicted first.

    Used to pair messages of different topics that belong to the same step, whatever order
    they arrive in: put one side, ``pop`` it when the other side with the same stamp arrives.
    """

    def __init__(self, capacity: int):
        if capacity < 1:
            raise ValueError('capacity must be at least 1')
        self._capacity = capacity
        self._items: 'collections.OrderedDict[int, V]' = collections.OrderedDict()
        self._lock = threading.Lock()
        self.evicted = 0

    def put(self, stamp_ns: int, value: V) -> None:
        with self._lock:
            self._items[stamp_ns] = value
            self._items.move_to_end(stamp_ns)
            while len(self._items) > self._capacity:
                self._items.popitem(last=False)
                self.evicted += 1

    def get(self, stamp_ns: int) -> Optional[V]:
        with self._lock:
            return self._items.get(stamp_ns)

    def pop(self, stamp_ns: int) -> Optional[V]:
        with self._lock:
            return self._items.pop(stamp_ns, None)

    def pop_older_than(self, stamp_ns: int) -> list:
        """Remove and return ``[(stamp, value)]`` of every entry stamped before ``stamp_ns``."""
        with self._lock:
            old = [(s, v) for s, v in self._items.items() if s < stamp_ns]
            for s, _ in old:
                del self._items[s]
            return old

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)


MAX_STAMP_JUMP_S = 60.0
"""
Stamps of one stream further than this from the newest are implausible (900 agent steps of
sim time: the env never skips that many unpublished, and a paused env does not advance).
"""

RESTART_CONFIRMATIONS = 3
"""Consecutive, increasing off-timeline stamps that mean the stream restarted (a new env)."""


class StampGuard:
    """
    The newest stamp of one stream, and whether the next one belongs to it.

    ``check`` returns 'ok' for a stamp within ``max_jump_ns`` of the newest (a late re-send
    included), 'implausible' for one that jumps further ahead or behind (a stray message: it
    must not move "now"), and 'restart' when ``confirmations`` such stamps in a row form a
    timeline of their own (each at or after the one before, within ``max_jump_ns``; a lockstep
    env re-sends an unanswered step with its stamp): the publisher started over, and the guard
    follows it from that stamp on.
    """

    def __init__(self, max_jump_ns: int = int(MAX_STAMP_JUMP_S * NS_PER_S),
                 confirmations: int = RESTART_CONFIRMATIONS):
        if max_jump_ns <= 0 or confirmations < 1:
            raise ValueError('max_jump_ns must be > 0 and confirmations >= 1')
        self.max_jump_ns = int(max_jump_ns)
        self.confirmations = int(confirmations)
        self.newest: Optional[int] = None
        self._candidates: list = []
        self.rejected = 0
        self.restarts = 0

    def check(self, stamp_ns: int) -> str:
        stamp_ns = int(stamp_ns)
        if self.newest is None or abs(stamp_ns - self.newest) <= self.max_jump_ns:
            self._candidates.clear()
            self.newest = stamp_ns if self.newest is None else max(self.newest, stamp_ns)
            return 'ok'
        last = self._candidates[-1] if self._candidates else None
        if last is not None and not 0 <= stamp_ns - last <= self.max_jump_ns:
            self._candidates.clear()
        self._candidates.append(stamp_ns)
        if len(self._candidates) >= self.confirmations:
            self._candidates.clear()
            self.newest = stamp_ns
            self.restarts += 1
            return 'restart'
        self.rejected += 1
        return 'implausible'

    def plausible(self, stamp_ns: int) -> bool:
        """Tell whether ``stamp_ns`` is near the newest stamp (without changing anything)."""
        return self.newest is None or abs(int(stamp_ns) - self.newest) <= self.max_jump_ns

"""
Stamps as integer nanoseconds, and a guard that tells a stream's stamps from strays.

Every stamped message of one environment step carries that step's stamp, so integer
nanoseconds are an exact key for pairing (floats are not).
"""

from typing import Optional

from builtin_interfaces.msg import Time

NS_PER_S = 1_000_000_000


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

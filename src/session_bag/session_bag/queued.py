"""
A BagWriter on a thread of its own: the recorder's callbacks only queue. Pure (no node).

Taking a message from DDS must stay quick: the graph's frame writers keep 10 messages, so a
recorder that stops taking for 40 ms at 250 steps/s (compressing a chunk, say) would miss
frames. Here the executor's thread hands each message over and returns; this thread writes,
compresses, flushes every ``flush_period_s`` (so a SIGKILL loses at most that, as long as it
keeps up) and closes the bag once everything queued before ``close`` is written.
"""

import queue
import threading
import time
from typing import Callable, List, Optional

from session_bag.writer import BagWriter


class QueuedWriter:
    """Writes into ``writer`` on a thread; ``on_error(text)`` hears what could not be written."""

    def __init__(self, writer: BagWriter, flush_period_s: float,
                 on_error: Callable[[str], None]):
        self.writer = writer
        self.flush_period_s = flush_period_s
        self._on_error = on_error
        self._queue: 'queue.SimpleQueue' = queue.SimpleQueue()
        self._topics = set()
        self.errors = 0
        self._close_failed = False
        self._thread = threading.Thread(target=self._run, name='bag_writer', daemon=True)
        self._thread.start()

    def has_topic(self, name: str) -> bool:
        return name in self._topics

    def add_topic(self, name: str, type_name: str, qos_profiles: List[dict]) -> None:
        self._topics.add(name)
        self._queue.put(('topic', name, type_name, qos_profiles))

    def write(self, name: str, log_time_ns: int, data: bytes,
              publish_time_ns: Optional[int] = None, sequence: int = 0) -> None:
        self._queue.put(('message', name, log_time_ns, data, publish_time_ns, sequence))

    @property
    def backlog(self) -> int:
        """Items queued and not yet written."""
        return self._queue.qsize()

    def close(self, timeout_s: float = 30.0) -> bool:
        """Write what is queued, close the bag; False unless the bag is closed whole."""
        self._queue.put(('close',))
        self._thread.join(timeout_s)
        return not self._thread.is_alive() and self.writer.closed and not self._close_failed

    def _run(self) -> None:
        next_flush = time.monotonic() + self.flush_period_s
        while True:
            try:
                item = self._queue.get(timeout=max(0.0, next_flush - time.monotonic()))
            except queue.Empty:
                item = None
            if item is not None and item[0] == 'close':
                break
            if item is not None:
                self._apply(item)
            if time.monotonic() >= next_flush:
                self._safely(self.writer.flush, 'the bag could not be flushed')
                next_flush = time.monotonic() + self.flush_period_s
        if not self._safely(self.writer.close, 'the bag could not be closed'):
            self._close_failed = True

    def _apply(self, item: tuple) -> None:
        if item[0] == 'topic':
            if not self._safely(lambda: self.writer.add_topic(*item[1:]),
                                f'topic {item[1]} could not be added'):
                self._topics.discard(item[1])  # its next message asks again
        elif self.writer.has_topic(item[1]):
            self._safely(lambda: self.writer.write(*item[1:]),
                         f'{item[1]}: a message could not be written')
        else:
            self.errors += 1
            self._on_error(f'{item[1]}: a message could not be written (its channel could not '
                           f'be added; {self.errors} errors so far)')

    def _safely(self, action: Callable[[], None], what: str) -> bool:
        """Run ``action``; on any error say so, count it, go on (the thread must not die)."""
        try:
            action()
            return True
        except Exception as error:  # noqa: B902 - a full disk, a bad message: never the thread
            self.errors += 1
            self._on_error(f'{what} ({type(error).__name__}: {error}; {self.errors} errors '
                           'so far)')
            return False

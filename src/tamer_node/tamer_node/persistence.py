"""
Everything a run writes to <run_dir>, so that a crash loses nothing a person said.

- ``feedback_log.jsonl``: one JSON line per feedback (and utterance) received, written and
  flushed before the feedback is used (survives ``kill -9``), and made durable with
  ``fdatasync`` before its receipt goes out (``sync``: grouped by default, so a power cut
  loses no line a receipt was sent for).
- ``steps/segment-NNNNNN.bin``: a journal of the steps (preprocessed images, chosen actions),
  written a few records at a time. A step is known by its session and stamp: the env's stamps
  start over when it is started again (a resume), and each tamer_node start, or restart of the
  observation stamps, begins a new session of the run, so steps of two sessions never mix. It
  holds the buffer's images (so a checkpoint need not copy up to 170 MB of them every time,
  which would stall the process) and the steps that feedback
  logged after the last checkpoint refers to (replayed on resume). A new segment starts at every
  checkpoint; a segment is deleted once every step in it is older (session, then stamp) than
  anything the newest checkpoint still needs.
- ``checkpoints/checkpoint.pt``: model, optimizer, buffer (its columns; the images are found in
  the journal by stamp), counters; written to a temporary file and moved into place with
  ``os.replace`` (a reader sees the old or the new one, never half).
- Every feedback line of ``feedback_log.jsonl`` names its ``session`` with its ``stamp_ns``.
- ``metrics.csv``: one row per metrics period.
"""

import collections
import csv
import json
import math
import os
from pathlib import Path
import queue
import struct
import sys
import threading
import time
from typing import Callable, Dict, Iterator, List, Optional, Tuple
import zlib

from attention_common.run_files import CHECKPOINT_DIR, CHECKPOINT_FILE
import numpy as np
import torch

KIND_OBSERVATION, KIND_SALIENCY, KIND_ACTION = 1, 2, 3
KIND_TAKEN = 4
"""The action the world executed on a step (``action_taken``), when it was not the agent's."""
KIND_NAMES = {KIND_OBSERVATION: 'observation', KIND_SALIENCY: 'saliency'}
_MAGIC = b'TMJ3'  # /3: each record names its session
# magic, kind, session, stamp ns, action, rows, columns, payload bytes (the pixels, zlib level
# 1: Atari frames shrink ~13x, blurred saliency images ~6x, for ~40 us each on the disk thread).
_HEADER = struct.Struct('<4sBHqhHHI')
StepKey = Tuple[int, int]
"""(session, stamp ns): a step's identity in a run."""


def json_number(value: float):
    """Return a float for JSON; non-finite ones as strings ('nan', 'inf'): JSON has none."""
    return value if math.isfinite(value) else repr(float(value))


SYNC_GROUP_S = 0.1
"""``sync`` grouped: the longest a logged line waits for its fdatasync (and its receipt)."""


class FeedbackLog:
    """
    Append-only JSON lines, each flushed as it is written, synced before its receipt.

    ``append(entry, receipt)`` calls ``receipt()`` once the line is as durable as ``sync``
    says: at once ('off': in the OS's page cache), after an fdatasync of its own ('every'), or
    after the fdatasync that ``commit`` does for every line waiting ('grouped': the disk thread
    commits when it has nothing more queued, and ``append`` once the oldest waited
    ``SYNC_GROUP_S``). A failed fdatasync raises; the receipts of the lines it covered are not
    sent (the line is still in the file and with the learner).
    """

    def __init__(self, path: Path, sync: str = 'off'):
        self.path = Path(path)
        self.sync = sync
        self._file = open(self.path, 'a', encoding='utf-8')
        self._lock = threading.Lock()
        self._waiting: List[Callable[[], None]] = []  # receipts of lines not synced yet
        self._unsynced = False
        self._oldest = 0.0
        self.syncs = 0
        """fdatasync calls so far (the cost of durability, in metrics)."""

    def append(self, entry: dict, receipt: Optional[Callable[[], None]] = None) -> None:
        line = json.dumps(entry, allow_nan=False, ensure_ascii=True)
        with self._lock:
            self._file.write(line + '\n')
            self._file.flush()
            if not self._unsynced:
                self._oldest = time.monotonic()
            self._unsynced = True
            if receipt is not None:
                self._waiting.append(receipt)
            due = (self.sync != 'grouped'
                   or time.monotonic() - self._oldest >= SYNC_GROUP_S)
            ready = self._sync_locked() if due else []
        for callback in ready:
            callback()

    def commit(self) -> None:
        """Sync every line logged so far, then send their receipts (grouped)."""
        with self._lock:
            ready = self._sync_locked()
        for callback in ready:
            callback()

    def _sync_locked(self) -> List[Callable[[], None]]:
        ready, self._waiting = self._waiting, []
        unsynced, self._unsynced = self._unsynced, False
        if unsynced and self.sync != 'off':
            os.fdatasync(self._file.fileno())  # raises: the receipts above are not sent
            self.syncs += 1
        return ready

    def close(self) -> None:
        self.commit()
        with self._lock:
            self._file.close()

    @staticmethod
    def read(path: Path) -> Tuple[List[dict], int]:
        """Return (entries, number of unreadable lines); a missing file has none."""
        entries, bad = [], 0
        if not Path(path).exists():
            return entries, bad
        with open(path, encoding='utf-8', errors='replace') as file:
            for line in file:
                try:
                    entry = json.loads(line)
                except ValueError:  # a line cut short by a crash
                    bad += 1
                    continue
                if isinstance(entry, dict):
                    entries.append(entry)
                else:
                    bad += 1
        return entries, bad


class StepJournal:
    """Step records queued by the acting path (never blocks) and written by whoever drains."""

    def __init__(self, directory: Path, segment: int = 0, session: int = 1):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self._queue = collections.deque()  # append/popleft are atomic: no lock on the hot path
        self._lock = threading.Lock()      # serializes drains (file writes)
        self.segment = segment
        self.session = session
        """The session that records appended from now on belong to."""
        self._last_segment = segment
        self._newest: Dict[int, StepKey] = {}  # segment -> newest step in it
        self._file = open(self.segment_path(segment), 'ab')

    def segment_path(self, segment: int) -> Path:
        return self.directory / f'segment-{segment:06d}.bin'

    def append(self, kind: int, stamp: int, action: int = -1,
               image: Optional[torch.Tensor] = None) -> None:
        self._queue.append(('record', self.session, kind, stamp, action, image))

    def rotate(self) -> int:
        """Queue the switch to a new segment file (after what is queued now); return its index."""
        self._last_segment += 1
        self._queue.append(('rotate', self._last_segment))
        return self._last_segment

    def drain(self) -> int:
        """Write everything queued so far and flush; return the number of records written."""
        written = 0
        with self._lock:
            while self._queue:
                item = self._queue.popleft()
                if item[0] == 'rotate':
                    self._file.close()
                    if self.segment not in self._newest:  # nothing was written to it
                        self.segment_path(self.segment).unlink(missing_ok=True)
                    self.segment = item[1]
                    self._file = open(self.segment_path(self.segment), 'ab')
                    continue
                _, session, kind, stamp, action, image = item
                key = (session, stamp)
                self._newest[self.segment] = max(key, self._newest.get(self.segment, key))
                payload = b'' if image is None else zlib.compress(image.numpy().tobytes(), 1)
                rows, cols = (0, 0) if image is None else image.shape
                self._file.write(_HEADER.pack(_MAGIC, kind, session, stamp, action, rows, cols,
                                              len(payload)))
                self._file.write(payload)
                written += 1
            self._file.flush()
        return written

    def adopt(self, newest: Dict[int, StepKey]) -> None:
        """Take over the segments of an earlier process ({segment: newest step in it})."""
        with self._lock:
            for segment, stamp in newest.items():
                if segment != self.segment:
                    self._newest[segment] = stamp

    def delete_older_than(self, key: StepKey) -> int:
        """Delete the finished segments that hold only steps older than ``key``."""
        deleted = 0
        with self._lock:
            for segment, newest in list(self._newest.items()):
                if segment != self.segment and newest < tuple(key):
                    self.segment_path(segment).unlink(missing_ok=True)
                    del self._newest[segment]
                    deleted += 1
        return deleted

    def close(self) -> None:
        self.drain()
        with self._lock:
            self._file.close()

    @staticmethod
    def read(directory: Path, newest: Optional[Dict[int, StepKey]] = None
             ) -> Iterator[Tuple[int, int, int, int, object]]:
        """
        Yield (session, kind, stamp, action, image or None) from every segment, oldest first.

        A record cut short by a crash ends its segment's reading. ``newest``, if given, is
        filled with {segment: newest step in it}.
        """
        paths = sorted(Path(directory).glob('segment-*.bin'))
        for path in paths:
            segment = int(path.stem.split('-')[1])
            data = path.read_bytes()
            offset = 0
            while offset + _HEADER.size <= len(data):
                magic, kind, session, stamp, action, rows, cols, size = _HEADER.unpack_from(
                    data, offset)
                end = offset + _HEADER.size + size
                if magic != _MAGIC or end > len(data):
                    break
                image = None
                if rows:
                    try:
                        pixels = zlib.decompress(data[offset + _HEADER.size:end])
                    except zlib.error:
                        break
                    if len(pixels) != rows * cols:
                        break
                    image = torch.from_numpy(
                        np.frombuffer(pixels, np.uint8).reshape(rows, cols).copy())
                if newest is not None:
                    key = (session, stamp)
                    newest[segment] = max(key, newest.get(segment, key))
                yield session, kind, stamp, action, image
                offset = end

    @staticmethod
    def last_segment(directory: Path) -> int:
        segments = [int(p.stem.split('-')[1]) for p in Path(directory).glob('segment-*.bin')]
        return max(segments, default=-1)


def save_checkpoint(state: dict, run_dir: Path) -> Path:
    """Write ``state`` atomically to <run_dir>/checkpoints/checkpoint.pt."""
    directory = Path(run_dir) / CHECKPOINT_DIR
    directory.mkdir(parents=True, exist_ok=True)
    final = directory / CHECKPOINT_FILE
    temporary = directory / (CHECKPOINT_FILE + '.tmp')
    with open(temporary, 'wb') as file:
        torch.save(state, file)
        file.flush()
        os.fsync(file.fileno())
    os.replace(temporary, final)
    directory_fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(directory_fd)  # the rename itself is durable too
    finally:
        os.close(directory_fd)
    return final


def load_checkpoint(run_dir: Path) -> Optional[dict]:
    """Return the last checkpoint of a run, or None if it has none."""
    path = Path(run_dir) / CHECKPOINT_DIR / CHECKPOINT_FILE
    if not path.exists():
        return None
    return torch.load(path, map_location='cpu', weights_only=True)


class MetricsCsv:
    """metrics.csv: the columns of the first row written (or of the existing header)."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.columns: Optional[List[str]] = None
        if self.path.exists() and self.path.stat().st_size > 0:
            with open(self.path, newline='', encoding='utf-8') as file:
                self.columns = next(csv.reader(file), None)

    def write(self, row: Dict[str, object]) -> None:
        new_file = self.columns is None
        if new_file:
            self.columns = ['wall_time'] + sorted(k for k in row if k != 'wall_time')
        with open(self.path, 'a', newline='', encoding='utf-8') as file:
            writer = csv.writer(file)
            if new_file:
                writer.writerow(self.columns)
            writer.writerow([row.get(column, '') for column in self.columns])


class DiskWriter(threading.Thread):
    """The thread that does the run's slow disk work: journal drains, checkpoints, CSV rows."""

    def __init__(self, journal: StepJournal, on_error: Callable[[str], None],
                 drain_period_s: float = 0.2, name: str = 'tamer-disk',
                 when_idle: Optional[Callable[[], None]] = None):
        super().__init__(name=name, daemon=True)
        self._journal = journal
        self._when_idle = when_idle
        """Run whenever the queue is empty after a job (the feedback log's group commit)."""
        self._jobs: 'queue.Queue[Optional[Callable[[], None]]]' = queue.Queue()
        self._on_error = on_error
        self._period = drain_period_s
        self.errors = 0

    def submit(self, job: Callable[[], None]) -> None:
        self._jobs.put(job)

    def run(self) -> None:
        while True:
            try:
                job = self._jobs.get(timeout=self._period)
            except queue.Empty:
                job = self._drain
            if job is None:
                self._guard(self._drain)
                self._idle()
                return
            self._guard(job)
            if job is not self._drain:
                self._guard(self._drain)
            if self._jobs.empty():
                self._idle()

    def _idle(self) -> None:
        if self._when_idle is not None:
            self._guard(self._when_idle)

    def flush(self, timeout: float = 30.0) -> bool:
        """Wait until every job submitted so far is done (or the thread is not running)."""
        if not self.is_alive():
            return False
        done = threading.Event()
        self.submit(done.set)
        return done.wait(timeout)

    def stop(self, timeout: float = 30.0) -> None:
        self._jobs.put(None)
        self.join(timeout)

    def _drain(self) -> None:
        self._journal.drain()

    def _guard(self, job) -> None:
        try:
            job()
        except Exception as error:  # a full disk must not kill the node
            self.errors += 1
            try:
                self._on_error(f'disk write failed: {error!r}')
            except Exception as report_error:  # nor a failing logger this thread
                sys.stderr.write(f'disk write failed: {error!r} (and reporting it: '
                                 f'{report_error!r})\n')

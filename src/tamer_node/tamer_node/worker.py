"""
The learner thread, and how it shares the work with the acting path.

Concurrency contract
--------------------
Four kinds of thread touch the agent; each owns its objects and hands over through one point.

- Acting (the ``observation``/``saliency`` callbacks, or a benchmark loop): preprocesses the
  image, stores the step in the ``StepHistory``, picks the greedy action with its *own* copy of H
  (``ActingModel``, in eval mode for its whole life), queues journal records. With a frozen
  encoder it stores the image's features in the step's record (the learner trains on them).
  It takes only short locks (history, snapshot slot) and never waits for training, sampling or
  disk I/O.
- Feedback (the ``feedback*`` callbacks): numbers the feedback and queues it to the disk
  thread, which drains the step journal, appends the feedback to ``feedback_log.jsonl``
  (flushed) and only then puts it in the learner's inbox: what the learner uses is on disk, in
  arrival order.
- Learner (``LearnerWorker``): the only thread that uses the ``Learner`` (the model being
  trained and its optimizer) and that adds to the ``FeedbackBuffer``. It handles events strictly
  in arrival order; after every update it publishes a copy of the weights with a version number
  (the update count) in the ``SnapshotSlot``; the acting copy loads a newer version just before
  it acts. The trained model's train/eval mode is never flipped.
- Disk (``persistence.DiskWriter``): one FIFO of jobs: the feedback log, journal drains,
  metrics rows. Checkpoint files (small: the buffer's images are in the journal, but written
  with an fsync) go to a second DiskWriter, so a feedback line never waits behind one.
- Metrics (a timer callback): reads counters under the learner's small lock.

Pairing with saliency images: the steps a feedback credits may still wait for their saliency
image. The event stays at the head of the pending queue until every such image came, an image of
a later step came on that stream (so this one never will), or ``saliency_timeout_s`` of wall time
passed; then the steps without an image are used without the L2 term. Nothing waits forever, and
the events behind it wait no longer than that.

Minibatch schedule (``schedule.UpdateSchedule``): with ``update_clock: sim`` the learner owes
``update_rate_hz`` minibatch updates per second of *simulation* time, read from the observation
stamps the acting path passes to ``tick`` (which wakes the learner when the next one is due).
So every study condition gets the same number of minibatch updates per agent step however fast
its graph steps. The learner runs what it owes one update at a time, looking at its inbox in
between (immediate updates go first); it may lag behind the actor, which never waits for it. If
it owes more than ``update_backlog_s`` of sim time, the oldest owed updates are dropped and
counted (``train/skipped_updates``): then the study's conditions are not equal any more, and the
metrics say so. ``update_clock: wall`` is the old fixed rate per wall second (no catching up).

Checkpoints are taken by the learner between updates (consistent copies: every feedback up to
``applied_seq`` is in the buffer and the counters, none after it) and written by the disk thread:
after the first update, then ever less often up to ``checkpoint_period_s`` (``CheckpointClock``).
"""

import collections
import copy
from dataclasses import dataclass
import math
from pathlib import Path
import threading
import time
from typing import Callable, Dict, List, Optional

from attention_common.feedback import FEEDBACK_RANGE
import numpy as np
from tamer_node.buffer import collate, FeedbackBuffer, Sample
from tamer_node.config import TamerConfig
from tamer_node.credit import step_credit, window_credit
from tamer_node.history import other_kind, StepHistory
from tamer_node.learner import Learner
from tamer_node.model import HModel, to_input
from tamer_node.persistence import DiskWriter, KIND_NAMES, save_checkpoint, StepJournal
from tamer_node.schedule import UpdateSchedule
import torch

CHECKPOINT_FORMAT = 'tamer_node.checkpoint/3'  # /3: steps known by (session, stamp)

COUNTERS = (
    'feedback/count', 'feedback/duplicates', 'feedback/invalid', 'feedback/unmatched',
    'feedback/processed', 'samples/added', 'pairing/with_saliency', 'pairing/without_saliency',
    'train/updates', 'train/immediate_updates', 'train/minibatch_updates', 'train/l2_updates',
    'train/skipped_nonfinite', 'train/errors',
    'checkpoint/count', 'resume/replayed', 'resume/samples_without_images',
    'feedback/other_session',
)


@dataclass
class FeedbackEvent:
    """One feedback as the learner receives it (and as feedback_log.jsonl records it)."""

    seq: int
    """1, 2, 3, ... in order of arrival over the whole run."""
    h: float
    stamp: Optional[int]
    """The step it is attributed to: its header stamp, or the arrival stamp if unstamped."""
    now: Optional[int]
    """The newest observation stamp when it arrived (the window's t)."""
    status: str
    """'ok', 'duplicate' (the plain copy of a stamped one), 'invalid', 'no_observation'."""
    credit: str
    """Credit mode in force when it arrived."""
    arrived: float = 0.0
    """time.monotonic() at arrival (the saliency pairing deadline starts here)."""
    session: int = 1
    """The run's session its stamps belong to (see persistence.py)."""


class SnapshotSlot:
    """The newest weight snapshot and its version; the learner writes, the actor reads."""

    def __init__(self):
        self._lock = threading.Lock()
        self._version = 0
        self._state: Optional[Dict[str, torch.Tensor]] = None

    def publish(self, version: int, state: Dict[str, torch.Tensor]) -> None:
        with self._lock:
            self._version, self._state = version, state

    def newer_than(self, version: int):
        """(version, state) if a newer snapshot exists, else None."""
        with self._lock:
            if self._state is None or self._version <= version:
                return None
            return self._version, self._state


class ActingModel:
    """
    The actor's own copy of H: eval mode forever, refreshed from snapshots.

    ``greedy_margin`` 0 is the thesis's policy: argmax_a H(s, a), ties to the lowest index.
    Above 0, H is first clipped to the feedback range [-1, 1] and every action within the
    margin of the best counts as tied; a tie is broken at random (seeded). Without it an
    action the trainer never judged in a state, but punished in many others (UP, wrong almost
    everywhere on the floor), is extrapolated below -1 there and never tried, while every
    action tried sits at -1: an agent stood 3,000 steps at the foot of the left ladder trying
    every action but UP (graph trial, seed 1006).
    """

    def __init__(self, model: HModel, greedy_margin: float = 0.0, seed: int = 0):
        self.model = copy.deepcopy(model).eval()
        self.model.requires_grad_(False)
        self.version = 0
        self.greedy_margin = float(greedy_margin)
        self._rng = np.random.default_rng(seed)

    def refresh(self, slot: SnapshotSlot) -> None:
        newer = slot.newer_than(self.version)
        if newer is not None:
            self.version, state = newer
            self.model.load_state_dict(state)

    def predict(self, image: torch.Tensor) -> torch.Tensor:
        with torch.inference_mode():
            return self.model(to_input(image))[0]

    def choose(self, h: torch.Tensor) -> int:
        """Return the greedy action for one state's (18,) H values (see the class docstring)."""
        if self.greedy_margin <= 0.0:
            return int(torch.argmax(h))
        clipped = h.clamp(-FEEDBACK_RANGE, FEEDBACK_RANGE)  # beyond: extrapolation
        tied = torch.nonzero(clipped >= clipped.max() - self.greedy_margin).flatten()
        return int(tied[self._rng.integers(len(tied))])

    def greedy(self, image: torch.Tensor) -> int:
        """argmax_a H(s, a): the greedy policy (``choose``)."""
        return self.choose(self.predict(image))

    def features(self, image: torch.Tensor) -> torch.Tensor:
        """Return the (1120,) encoder features of a (105, 80) uint8 image (no_grad)."""
        with torch.no_grad():
            return self.model.features(to_input(image))[0]

    def greedy_on_features(self, features: torch.Tensor) -> int:
        """``greedy`` from the image's features (``features``): the same action."""
        with torch.no_grad():
            return self.choose(self.model.from_features(features.unsqueeze(0))[0])


class LearnerWorker(threading.Thread):
    """Turns feedback into samples and trains on them, in its own thread."""

    def __init__(self, config: TamerConfig, learner: Learner, buffer: FeedbackBuffer,
                 history: StepHistory, slot: SnapshotSlot, journal: StepJournal,
                 disk: DiskWriter, run_dir: Path, log: Callable[[str, str], None]):
        super().__init__(name='tamer-learner', daemon=True)
        self.config = config
        self.learner = learner
        self.buffer = buffer
        self.history = history
        self.slot = slot
        self.journal = journal
        self.disk = disk
        self.run_dir = Path(run_dir)
        self._log = log
        self._rng = np.random.default_rng(config.seed)
        self._inbox: 'collections.deque[FeedbackEvent]' = collections.deque()
        self._pending: 'collections.deque[FeedbackEvent]' = collections.deque()
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._lock = threading.Lock()  # guards counters and last losses for readers
        self.counters = collections.Counter(dict.fromkeys(COUNTERS, 0))
        self._period = _PeriodLosses()
        self.schedule = self._make_schedule(config)
        self._sim_now: Optional[float] = None  # newest observation stamp, simulation seconds
        self._wake_at = math.inf  # sim time at which tick() should wake the learner
        self.applied_seq = 0
        self.checkpoint_error: Optional[str] = None

    # Producers (any thread).
    def submit(self, event: FeedbackEvent) -> None:
        self._inbox.append(event)
        self._wake.set()

    def wake(self) -> None:
        """Something the pending events may wait for (a saliency image) arrived."""
        self._wake.set()

    def tick(self, stamp_ns: int) -> None:
        """Note that the acting path saw observation ``stamp_ns`` (sim time went on; cheap)."""
        self._sim_now = stamp_ns / 1e9
        if self._sim_now >= self._wake_at:
            self._wake.set()

    def stats(self) -> dict:
        with self._lock:
            stats = dict(self.counters)
        stats['train/skipped_updates'] = self.schedule.skipped
        stats['train/updates_owed'] = int(self.schedule.owed)
        stats['pairing/pending'] = len(self._pending) + len(self._inbox)
        stats['buffer/size'] = len(self.buffer)
        stats['buffer/with_saliency_fraction'] = self.buffer.companion_fraction()
        stats['model/version'] = self.learner.updates
        stats['feedback/applied_seq'] = self.applied_seq
        return stats

    def period_losses(self) -> dict:
        """
        Return the mean losses over the updates since the last call; start a new period.

        ``train/loss`` and ``train/mse`` average every update of the period, ``train/l2`` only
        those with an L2 term (rows with a saliency image and alpha > 0); NaN when there was
        none. ``train/period_updates`` and ``train/period_l2_updates`` say how many.
        """
        with self._lock:
            period, self._period = self._period, _PeriodLosses()
        return period.means()

    @staticmethod
    def _make_schedule(config: TamerConfig) -> UpdateSchedule:
        if config.update_clock == 'sim':
            return UpdateSchedule(config.update_rate_hz,
                                  config.update_rate_hz * config.update_backlog_s)
        return UpdateSchedule(config.update_rate_hz, 1.0)  # wall: as before, no catching up

    def _clock(self) -> Optional[float]:
        return self._sim_now if self.config.update_clock == 'sim' else time.monotonic()

    # The thread.
    def run(self) -> None:
        schedule = self.schedule
        checkpoints = CheckpointClock(self.config.checkpoint_period_s)
        next_checkpoint = math.inf
        while not self._stopping.is_set():
            self._wake.clear()
            now = time.monotonic()
            try:
                self._resolve(force=False)
                clock = self._clock()
                if clock is not None and len(self.buffer):
                    schedule.start(clock)  # if not started yet (a resumed buffer)
                    schedule.advance(clock)
                    if schedule.take():
                        batch = self.buffer.sample(self.config.batch_size, self._rng)
                        self._update(batch, immediate=False)
                progress = (self.learner.updates, self.applied_seq)
                next_checkpoint = checkpoints.next_at(progress)
                if now >= next_checkpoint:
                    self.checkpoint()
                    next_checkpoint = checkpoints.taken(progress, now)
            except Exception as error:  # the learner must outlive any one bad update
                with self._lock:
                    self.counters['train/errors'] += 1
                self._log('error', f'learner step failed: {error!r}')
            deadlines = [next_checkpoint, now + 0.1]
            self._wake_at = math.inf
            if schedule.started:
                if schedule.due():
                    deadlines.append(now)  # owed updates: go on at once (inbox first)
                elif self.config.update_clock == 'wall':
                    deadlines.append(schedule.due_at())
                else:
                    self._wake_at = schedule.due_at()  # tick() wakes the learner then
                    if (self._sim_now or 0.0) >= self._wake_at:
                        deadlines.append(now)
            if self._pending:
                deadlines.append(self._pending[0].arrived + self.config.saliency_timeout_s)
            self._wake.wait(max(0.0, min(deadlines) - time.monotonic()))
        self._resolve(force=True)  # nothing left half-done at exit
        self.checkpoint()

    def stop(self, timeout: float = 30.0) -> None:
        self._stopping.set()
        self._wake.set()
        self.join(timeout)

    # Feedback -> samples.
    def _resolve(self, force: bool) -> None:
        """Move inbox events to pending; use the pending ones whose pairing is settled."""
        while self._inbox:
            self._pending.append(self._inbox.popleft())
        fresh: List[Sample] = []
        now = time.monotonic()
        while self._pending:
            event = self._pending[0]
            timed_out = force or now - event.arrived >= self.config.saliency_timeout_s
            if not timed_out and not self._pairing_settled(event):
                break
            self._pending.popleft()
            samples = self.process(event, self.history)
            if samples and not self.schedule.started:
                # Minibatches are owed from the first sample's feedback on (its arrival).
                self.schedule.start(event.now / 1e9 if self.config.update_clock == 'sim'
                                    else event.arrived)
            fresh += samples
        if fresh and self.config.immediate_update:
            # Deep TAMER's immediate update on the new feedback's samples. Events that came
            # together (while an update ran, or waiting for saliency images) share one step:
            # one step each would let the learner fall behind the feedback without bound when
            # the graph steps fast (tried: 1,418 of 5,000 feedback used at 440 steps/s).
            self._update(collate(fresh), immediate=True)

    def _pairing_settled(self, event: FeedbackEvent) -> bool:
        if not self._wants_companion() or event.status != 'ok':
            return True
        companion = other_kind(self.config.input_image)
        return all(self.history.settled(stamp, companion)
                   for stamp in self._credit(event, self.history))

    def _wants_companion(self) -> bool:
        return self.learner.alpha > 0.0

    def _credit(self, event: FeedbackEvent, history: StepHistory) -> Dict[int, float]:
        if event.credit == 'window':
            if event.now is None:
                return {}
            return window_credit(history.acted_spans(event.now), event.now,
                                 self.config.window_min_s, self.config.window_max_s)
        record = history.get(event.stamp) if event.stamp is not None else None
        known = [event.stamp] if record is not None and record.action is not None else []
        return step_credit(event.stamp, known)

    def process(self, event: FeedbackEvent, history: StepHistory) -> List[Sample]:
        """Count the event and return its samples (already added to the buffer)."""
        samples: List[Sample] = []
        counts = collections.Counter({'feedback/processed': 1})
        if event.status == 'ok' and event.session != history.session:
            counts['feedback/other_session'] += 1
            self._log('warn', f'feedback #{event.seq} (h={event.h}) is on a step of session '
                      f'{event.session}, and the steps held are of session {history.session} '
                      '(the env started over): kept in the log, not learned from')
        elif event.status == 'ok':
            credit = self._credit(event, history)
            kind = self.config.input_image
            for stamp, weight in sorted(credit.items()):
                record = history.get(stamp)
                if record is None or record.image(kind) is None:
                    continue  # evicted meanwhile, or never had the image acted on
                state = self._item(record, kind, history)
                companion = self._item(record, other_kind(kind), history)
                counts['pairing/with_saliency' if companion is not None
                       else 'pairing/without_saliency'] += 1
                samples.append(Sample(state, companion, record.action, float(event.h),
                                      float(weight), stamp, event.seq, history.session))
            if samples:
                counts['feedback/count'] += 1
                counts['samples/added'] += len(samples)
            else:
                counts['feedback/unmatched'] += 1
                self._log('warn', f'feedback #{event.seq} (h={event.h}) matches no step the '
                          f'agent acted on (credit {event.credit}, stamp {event.stamp}); '
                          'kept in the log, not learned from')
        elif event.status == 'duplicate':
            counts['feedback/duplicates'] += 1
        elif event.status == 'invalid':
            counts['feedback/invalid'] += 1
        else:
            counts['feedback/unmatched'] += 1
        if not self._wants_companion():
            counts.pop('pairing/without_saliency', None)
        self.buffer.extend(samples)
        with self._lock:
            self.counters.update(counts)
        self.applied_seq = max(self.applied_seq, event.seq)
        return samples

    def _item(self, record, kind: str, history: StepHistory) -> Optional[torch.Tensor]:
        """
        Return what the buffer keeps of a step's ``kind`` image: the image, or its features.

        With a frozen encoder: the features the actor cached when it acted, else (the saliency
        companion, a resumed step) computed here once and cached in the history.
        """
        image = record.image(kind)
        if image is None or not self.learner.model.freeze_encoder:
            return image
        features = record.features(kind)
        if features is None:
            with torch.no_grad():
                features = self.learner.model.features(to_input(image))[0]
            history.put_features(kind, record.stamp, features)
        return features

    def _update(self, batch, immediate: bool) -> None:
        losses = self.learner.train_step(batch)
        if losses['skipped']:
            with self._lock:
                self.counters['train/skipped_nonfinite'] += 1
            self._log('warn', f'update skipped: the loss is not finite ({losses["loss"]})')
            return
        self.slot.publish(self.learner.updates, self.learner.snapshot())
        with self._lock:
            self._period.add(losses)
            self.counters['train/updates'] += 1
            self.counters['train/immediate_updates' if immediate
                          else 'train/minibatch_updates'] += 1
            if losses['l2_rows']:
                self.counters['train/l2_updates'] += 1

    # Checkpoints and resume.
    def checkpoint(self) -> int:
        """
        Copy the state now (learner thread, between updates); write it on the disk thread.

        The buffer goes in without its images: they are in the step journal, found again by
        session and stamp on resume. The journal keeps every step the buffer or the history
        still holds.
        """
        segment = self.journal.rotate()
        buffer_state = self.buffer.state_dict(images=False)
        needed = []
        sessions = buffer_state['columns']['sessions'].numpy()
        stamps = buffer_state['columns']['stamps'].numpy()
        if len(stamps):
            first = np.lexsort((stamps, sessions))[0]
            needed.append((int(sessions[first]), int(stamps[first])))
        if self.history.oldest() is not None:
            needed.append((self.history.session, self.history.oldest()))
        with self._lock:
            self.counters['checkpoint/count'] += 1
            counters = dict(self.counters)
        state = {
            'format': CHECKPOINT_FORMAT,
            'learner': copy.deepcopy(self.learner.state_dict()),
            'buffer': buffer_state,
            'input_image': self.config.input_image,
            'counters': counters,
            'applied_seq': self.applied_seq,
            'session': self.history.session,
            'saved_at': time.time(),
        }

        def write() -> None:
            self.journal.drain()  # every step the checkpoint refers to is on disk first
            save_checkpoint(state, self.run_dir)
            if needed:
                self.journal.delete_older_than(min(needed))

        self.disk.submit(write)
        return segment

    def restore(self, checkpoint: Optional[dict], events: List[FeedbackEvent],
                journal_records) -> int:
        """
        Load a checkpoint, replay the logged feedback after it; return how many replayed.

        Each feedback is paired with the steps of its own session only. The live history
        stays empty: this process is a new session, whose env stamps start over.
        """
        sessions: Dict[int, StepHistory] = {}
        for session, kind, stamp, action, image in journal_records:
            steps = sessions.get(session)
            if steps is None:
                steps = sessions[session] = StepHistory(capacity=1 << 30, session=session)
            if image is not None and kind in KIND_NAMES:
                steps.put_image(KIND_NAMES[kind], stamp, image)
            elif action >= 0:
                steps.set_action(stamp, action)
        if checkpoint is not None:
            if checkpoint.get('format') != CHECKPOINT_FORMAT:
                raise ValueError('the checkpoint was not written by this tamer_node version')
            self.learner.load_state_dict(checkpoint['learner'])
            buffer_state = checkpoint['buffer']
            if 'states' not in buffer_state:
                buffer_state = self._find_images(buffer_state, sessions,
                                                 checkpoint.get('input_image', 'observation'))
            self.buffer.load_state_dict(buffer_state)
            self.counters.update({k: int(v) for k, v in checkpoint['counters'].items()
                                  if k in COUNTERS})
            self.applied_seq = int(checkpoint['applied_seq'])
            self._rng = np.random.default_rng([self.config.seed, self.learner.updates])
        replayed = 0
        for event in events:
            if event.seq > self.applied_seq:
                self.process(event, sessions.get(event.session)
                             or StepHistory(1, session=event.session))
                replayed += 1
        with self._lock:
            self.counters['resume/replayed'] += replayed
        self.slot.publish(self.learner.updates, self.learner.snapshot())
        return replayed

    def _find_images(self, state: dict, sessions: Dict[int, StepHistory], kind: str) -> dict:
        """Put the journal's images back into a buffer state saved without them."""
        columns = {name: values.numpy() for name, values in state['columns'].items()}
        keep, states, companions = [], [], []
        for row, (session, stamp, has) in enumerate(zip(
                columns['sessions'], columns['stamps'], columns['has_companion'])):
            steps = sessions.get(int(session))
            record = steps.get(int(stamp)) if steps is not None else None
            image = record.image(kind) if record is not None else None
            companion = record.image(other_kind(kind)) if record is not None and has else None
            if image is None or (has and companion is None):
                continue
            keep.append(row)
            states.append(self._item(record, kind, steps))
            if has:
                companions.append(self._item(record, other_kind(kind), steps))
        missing = len(columns['stamps']) - len(keep)
        if missing:
            with self._lock:
                self.counters['resume/samples_without_images'] += missing
            self._log('warn', f'{missing} buffer sample(s) lost: their steps are not in the '
                      'journal any more')
        empty = torch.from_numpy(self.buffer.states[:0].copy())
        return {
            'capacity': state['capacity'], 'added': state['added'],
            'columns': {name: torch.from_numpy(values[keep]) for name, values in columns.items()},
            'states': torch.stack(states) if states else empty,
            'companions': torch.stack(companions) if companions else empty,
        }


class CheckpointClock:
    """
    Decide when the learner checkpoints.

    Once it has learned something (an update, or feedback used), then 1, 2, 4, ... s apart, at
    most ``period_s`` (0: only at exit), and only when it has learned more since the last one.

    So a kill -9 costs at most the minibatch updates of the last half of a short run, or of
    ``period_s`` in a long one; feedback never (it is logged first and replayed on resume).
    """

    FIRST_INTERVAL_S = 1.0

    def __init__(self, period_s: float):
        self.period_s = float(period_s)
        self._interval = min(self.FIRST_INTERVAL_S, self.period_s)
        self._progress = (0, 0)  # (updates, applied feedback) at the last checkpoint
        self._due = -math.inf

    def next_at(self, progress) -> float:
        """Return the monotonic time of the next checkpoint (inf: none due, nothing new)."""
        if not self.period_s or tuple(progress) == self._progress:
            return math.inf
        return self._due

    def taken(self, progress, now: float) -> float:
        self._progress = tuple(progress)
        self._due = now + self._interval
        self._interval = min(2 * self._interval, self.period_s)
        return self.next_at(progress)


class _PeriodLosses:
    """Sums of the loss terms over the updates of one metrics period."""

    def __init__(self):
        self.updates = self.l2_updates = 0
        self.loss = self.mse = self.l2 = 0.0

    def add(self, losses: dict) -> None:
        self.updates += 1
        self.loss += losses['loss']
        self.mse += losses['mse']
        if losses['l2_rows']:
            self.l2_updates += 1
            self.l2 += losses['l2']

    def means(self) -> dict:
        return {
            'train/loss': self.loss / self.updates if self.updates else math.nan,
            'train/mse': self.mse / self.updates if self.updates else math.nan,
            'train/l2': self.l2 / self.l2_updates if self.l2_updates else math.nan,
            'train/period_updates': self.updates,
            'train/period_l2_updates': self.l2_updates,
        }

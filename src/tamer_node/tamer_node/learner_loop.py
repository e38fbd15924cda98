"""
The learner thread: turns feedback into samples, trains, publishes weights, checkpoints.

``LearnerWorker`` is the only thread that uses the ``Learner`` (the model being trained and its
optimizer) and that adds to the ``FeedbackBuffer``. It handles events strictly in arrival order
(pairing.py says when an event's saliency images are settled); after every update it publishes
a copy of the weights with a version number (the update count) in the ``SnapshotSlot``. The
trained model's train/eval mode is never flipped. Readers (metrics) take its small lock.

Minibatch schedule (``schedule.UpdateSchedule``): with ``update_clock: sim`` the learner owes
``update_rate_hz`` minibatch updates per second of *simulation* time, read from the observation
stamps the acting path passes to ``tick`` (which wakes the learner when the next one is due).
So every study condition gets the same number of minibatch updates per agent step however fast
its graph steps. The learner runs what it owes one update at a time, looking at its inbox in
between (immediate updates go first); it may lag behind the actor, which never waits for it. If
it owes more than ``update_backlog_s`` of sim time, the oldest owed updates are dropped and
counted (``train/skipped_updates``): then the study's conditions are not equal any more, and the
metrics say so. ``update_clock: wall`` is the old fixed rate per wall second (no catching up).
"""

import collections
import math
from pathlib import Path
import threading
import time
from typing import Callable, List, Optional

from attention_common.log_budget import LogBudget
from attention_common.priority import lower_thread_priority as lower_thread
import numpy as np
from tamer_node.acting import SnapshotSlot
from tamer_node.buffer import collate, concatenate, FeedbackBuffer, Sample
from tamer_node.checkpointing import CheckpointClock, Checkpoints, journal_histories
from tamer_node.config import TamerConfig
from tamer_node.delay_fit import DelayFit
from tamer_node.events import FeedbackEvent, LEARNER_COUNTERS
from tamer_node.history import StepHistory
from tamer_node.learner import Learner
from tamer_node.memory import VerdictMemory
from tamer_node.pairing import pair, predict_judged, settled
from tamer_node.persistence import DiskWriter, StepJournal
from tamer_node.schedule import UpdateSchedule


class LearnerWorker(threading.Thread):
    """Turns feedback into samples and trains on them, in its own thread."""

    def __init__(self, config: TamerConfig, learner: Learner, buffer: FeedbackBuffer,
                 history: StepHistory, slot: SnapshotSlot, journal: StepJournal,
                 disk: DiskWriter, run_dir: Path, log: Callable[[str, str], None],
                 memory: Optional[VerdictMemory] = None,
                 kept: Optional[FeedbackBuffer] = None):
        super().__init__(name='tamer-learner', daemon=True)
        self.config = config
        self.kept = kept
        """Step-credited samples only, ``kept_per_batch`` rows of each minibatch (None: off)."""
        self.memory = memory
        """The acting path's verdict memory, told of every sample added (None: off)."""
        self.learner = learner
        self.buffer = buffer
        self.history = history
        self.slot = slot
        self.delays = (DelayFit(config.window_min_s, config.window_max_s,
                                config.credit_delay_bin_s, config.credit_delay_prior)
                       if config.credit_delay_fit else None)
        """The trainer's delay as fitted so far (``credit_delay_fit``), else None."""
        self.checkpoints = Checkpoints(config, learner, buffer, history, journal, disk,
                                       run_dir, log, self.delays)
        self._log = log
        self._warnings = LogBudget(log)  # a burst's thousands of unmatched feedback: folded
        self._rng = np.random.default_rng(config.seed)
        self._inbox: 'collections.deque[FeedbackEvent]' = collections.deque()
        self._pending: 'collections.deque[FeedbackEvent]' = collections.deque()
        self._first_feedback_at: Optional[float] = None  # see updates_behind
        self._wake = threading.Event()
        self._updated = threading.Event()  # set after every update (a paced actor waits on it)
        self._stopping = threading.Event()
        self._lock = threading.Lock()  # guards counters and last losses for readers
        self.counters = collections.Counter(dict.fromkeys(LEARNER_COUNTERS, 0))
        self._period = _PeriodLosses()
        self.schedule = self._make_schedule(config)
        self._sim_now: Optional[float] = None  # newest observation stamp, simulation seconds
        self._wake_at = math.inf  # sim time at which tick() should wake the learner
        self.applied_seq = 0
        self.on_credit: Optional[Callable[[FeedbackEvent, List[Sample]], None]] = None
        """Called on this thread with each feedback learned from and its samples (the steps
        its credit went to, with their weights), live only (not while resuming)."""

    # Producers (any thread).
    def expect(self, event: FeedbackEvent) -> None:
        """
        Note a feedback on its arrival (the intake's thread): updates are owed from then on.

        It may still wait for the disk thread to log it and ``submit`` it; meanwhile the actor
        is paced already (CI lost 29 owed updates to a busy disk thread before).
        """
        if self._first_feedback_at is None and event.status == 'ok' and event.now is not None:
            self._first_feedback_at = self._event_time(event)

    def submit(self, event: FeedbackEvent) -> None:
        self.expect(event)
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

    def updates_behind(self) -> float:
        """
        Return the minibatch updates owed up to the newest tick (what the actor paces on).

        Before the learner has started its schedule, what it will owe from the first usable
        feedback on (it starts there): at start-up the learner is slow and the actor, not
        held back yet, had run far enough ahead for the learner to drop owed updates.
        """
        schedule, now = self.schedule, self._clock()
        if now is None:
            return 0.0
        if not schedule.started:
            first = self._first_feedback_at
            return 0.0 if first is None else max(0.0, now - first) * schedule.rate_hz
        return schedule.owed + max(0.0, now - schedule.last_reading) * schedule.rate_hz

    def _event_time(self, event: FeedbackEvent) -> float:
        """Return the schedule's clock reading of an event's arrival (sim or wall seconds)."""
        return event.now / 1e9 if self.config.update_clock == 'sim' else event.arrived

    def wait_caught_up(self, limit: float, timeout_s: float) -> float:
        """
        Wait while the learner owes more than ``limit`` minibatch updates; return the wait (s).

        Called by the acting path before it acts (``pace_updates``): in lockstep the graph then
        never outruns its learner, which would drop owed updates. ``limit`` 0 never waits;
        ``timeout_s`` bounds one wait (a learner that stopped never stalls the actor).
        """
        if limit <= 0.0 or self.updates_behind() <= limit:
            return 0.0
        started = time.monotonic()
        deadline = started + timeout_s
        self._wake.set()
        while self.is_alive() and not self._stopping.is_set():
            left = deadline - time.monotonic()
            if left <= 0.0:
                break
            self._updated.clear()
            if self.updates_behind() <= limit:
                break
            self._updated.wait(min(left, 0.005))
        return time.monotonic() - started

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
        stats['credit/delay_mean_s'] = stats['credit/delay_sd_s'] = math.nan
        if self.delays is not None:  # (read unlocked: a torn read is one metrics row off)
            stats['credit/delay_mean_s'], stats['credit/delay_sd_s'] = self.delays.moments_s()
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
        lower_thread_priority(self.config.learner_nice, self._log)
        schedule = self.schedule
        checkpoints = CheckpointClock(self.config.checkpoint_period_s)
        next_checkpoint = math.inf
        while not self._stopping.is_set():
            self._wake.clear()
            now = time.monotonic()
            try:
                self._resolve(force=False)
                self._warnings.flush_due()
                clock = self._clock()
                if clock is not None and len(self.buffer):
                    schedule.start(clock)  # if not started yet (a resumed buffer)
                    schedule.advance(clock)
                    if schedule.take():
                        batch = self._minibatch()
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
        self._warnings.flush()
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
            if not timed_out and not settled(event, self.history, self.config,
                                             self._wants_companion()):
                break
            self._pending.popleft()
            samples = self.process(event, self.history)
            if samples and self.on_credit is not None:
                self.on_credit(event, samples)
            if samples and not self.schedule.started:
                # Minibatches are owed from the first sample's feedback on (its arrival).
                self.schedule.start(self._event_time(event))
            fresh += samples
        if fresh and self.config.immediate_update:
            # Deep TAMER's immediate update on the new feedback's samples. Events that came
            # together (while an update ran, or waiting for saliency images) share one step:
            # one step each would let the learner fall behind the feedback without bound when
            # the graph steps fast (tried: 1,418 of 5,000 feedback used at 440 steps/s).
            self._update(collate(fresh), immediate=True)

    def _minibatch(self):
        """``batch_size`` samples, or with the ``mixture`` loss ``batch_size`` whole feedbacks."""
        if self.config.credit_loss == 'mixture':
            return self.buffer.sample_feedback(self.config.batch_size, self._rng)
        if self.kept is None or not len(self.kept):
            return self.buffer.sample(self.config.batch_size, self._rng)
        kept = self.kept.sample(self.config.kept_per_batch, self._rng)
        rest = self.config.batch_size - len(kept.h)
        return concatenate(self.buffer.sample(rest, self._rng), kept)

    def _wants_companion(self) -> bool:
        """Wait for credited steps' saliency images: for the L2 term, or as part of H's input."""
        return self.learner.alpha > 0.0 or self.config.input_image == 'both'

    def process(self, event: FeedbackEvent, history: StepHistory) -> List[Sample]:
        """Count the event and return its samples (already added to the buffer)."""
        paired = pair(event, history, self.config, self.learner.model, self._wants_companion(),
                      self.delays)
        if paired.warning is not None:
            self._warnings.warn(paired.warning)
        if paired.delays:  # the M-step: where the verdict went
            total = sum(s.weight for s in paired.samples)
            if total > 0.0:
                self.delays.observe([paired.delays[s.stamp] for s in paired.samples],
                                    [s.weight / total for s in paired.samples])
        self.buffer.extend(paired.samples)
        if self.kept is not None and event.credit == 'step':
            self.kept.extend(paired.samples)
        if self.memory is not None:
            self.memory.add(paired.samples)
        with self._lock:
            self.counters.update(paired.counts)
        self.applied_seq = max(self.applied_seq, event.seq)
        return paired.samples

    def _update(self, batch, immediate: bool) -> None:
        losses = self.learner.train_step(batch)
        if losses['skipped']:
            with self._lock:
                self.counters['train/skipped_nonfinite'] += 1
            self._log('warn', f'update skipped: the loss is not finite ({losses["loss"]})')
            return
        self._refit_credit()
        self.slot.publish(self.learner.updates, self.learner.snapshot())
        self._updated.set()
        with self._lock:
            self._period.add(losses)
            self.counters['train/updates'] += 1
            self.counters['train/immediate_updates' if immediate
                          else 'train/minibatch_updates'] += 1
            if losses['l2_rows']:
                self.counters['train/l2_updates'] += 1

    def _refit_credit(self) -> None:
        """Credit by prediction: re-weigh the buffer with the new H every so many updates."""
        every = self.config.credit_refit_updates
        if not self.config.credit_posterior or every <= 0 or self.learner.updates % every:
            return
        model = self.learner.model
        self.buffer.refit_weights(lambda s, a: predict_judged(model, s, a),
                                  self.config.credit_noise)
        with self._lock:
            self.counters['credit/refits'] += 1

    # Checkpoints and resume (checkpointing.py).
    def checkpoint(self) -> int:
        """Copy the state now, between updates; the checkpoint thread writes it."""
        return self.checkpoints.take(self._count_checkpoint, self.applied_seq)

    def _count_checkpoint(self) -> dict:
        with self._lock:
            self.counters['checkpoint/count'] += 1
            return dict(self.counters)

    def restore(self, checkpoint: Optional[dict], events: List[FeedbackEvent],
                journal_records) -> int:
        """
        Load a checkpoint, replay the logged feedback after it; return how many replayed.

        Each feedback is paired with the steps of its own session only. The live history
        stays empty: this process is a new session, whose env stamps start over.
        """
        sessions = journal_histories(journal_records, self.config.decision_period_s)
        if checkpoint is not None:
            missing = self.checkpoints.load(checkpoint, sessions)
            if self.memory is not None:  # it summarises the buffer
                self.memory.add(self.buffer.samples())
            with self._lock:
                self.counters['resume/samples_without_images'] += missing
            self.counters.update({k: int(v) for k, v in checkpoint['counters'].items()
                                  if k in LEARNER_COUNTERS})
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


def lower_thread_priority(nice: int, log: Callable[[str, str], None]) -> None:
    """Add ``nice`` to the calling thread's niceness (Linux threads have their own)."""
    if nice <= 0:
        return
    try:
        lower_thread(threading.get_native_id(), nice)
    except (AttributeError, OSError) as error:  # not Linux, or not allowed: run as it is
        log('warn', f'learner thread priority left as it is ({error})')

"""
TamerAgent: everything tamer_node does, without ROS (the node converts messages and calls it).

Acting: ``on_observation`` (and ``on_saliency`` with ``input_image: saliency``) returns the
greedy action for that step at once. Learning runs on the learner thread (worker.py, which
states the concurrency contract). Everything a person gives is on disk before it is used
(persistence.py).
"""

import collections
import math
from pathlib import Path
import sys
import threading
import time
from typing import Callable, List, Optional, Tuple

from attention_common.feedback import FEEDBACK_RANGE
from attention_common.stamps import NS_PER_S, StampGuard
from attention_common.utterance import MAX_UTTERANCE_CHARS
import cv2
import numpy as np
from tamer_node.buffer import FeedbackBuffer
from tamer_node.config import TamerConfig
from tamer_node.history import StepHistory
from tamer_node.learner import Learner
from tamer_node.model import Encoder, FEATURE_SIZE, HModel, load_encoder, preprocess
from tamer_node.persistence import (
    CHECKPOINT_DIR, DiskWriter, FEEDBACK_LOG, FeedbackLog, json_number, KIND_ACTION,
    KIND_OBSERVATION, KIND_SALIENCY, load_checkpoint, METRICS_CSV, MetricsCsv, StepJournal,
    STEPS_DIR)
from tamer_node.worker import ActingModel, FeedbackEvent, LearnerWorker, SnapshotSlot
import torch

DEFAULT_ENCODER = Path(__file__).resolve().parent / 'weights' / 'encoder.pt'
HOW_TO_BUILD_ENCODER = ('build it with `tamer_pretrain` (writes tamer_node/weights/encoder.pt, '
                        'a few minutes on one core) or set encoder_path')


class BadInput(ValueError):
    """A message the agent cannot use; it was counted and dropped."""


def share_the_cpu(switch_interval_s: float = 0.0005) -> None:
    """
    Set this process up for a shared 2-core machine: one thread per torch op and OpenCV call.

    Python hands the GIL to a waiting thread only every ``sys.getswitchinterval()`` (5 ms by
    default); a shorter interval keeps the acting path from waiting that long behind the
    learner's Python code.
    """
    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    sys.setswitchinterval(switch_interval_s)


def default_run_dir() -> Path:
    """Return a new dated folder under ~/.ros/tamer_node/runs."""
    return Path.home() / '.ros' / 'tamer_node' / 'runs' / time.strftime('%Y%m%d-%H%M%S')


def resolve_encoder(path: str) -> Path:
    """Return the encoder file to load: ``path``, or the shipped one when empty."""
    return Path(path).expanduser() if path else DEFAULT_ENCODER


class TamerAgent:
    """Deep TAMER with the saliency L2 term: acts greedily, learns on its own thread."""

    def __init__(self, config: TamerConfig, run_dir: Path, encoder: Optional[Encoder] = None,
                 log: Optional[Callable[[str, str], None]] = None):
        config.validate()
        self.config = config
        self.run_dir = Path(run_dir)
        self._log = log or (lambda level, text: None)
        if encoder is None:
            encoder_file = resolve_encoder(config.encoder_path)
            if not encoder_file.exists():
                raise FileNotFoundError(
                    f'encoder weights {encoder_file} are missing: {HOW_TO_BUILD_ENCODER}')
            encoder = load_encoder(encoder_file)
        self._check_run_dir()
        torch.manual_seed(config.seed)
        model = HModel(config.head_hidden, freeze_encoder=not config.fine_tune_encoder,
                       encoder=encoder)
        self.learner = Learner(model, config.learning_rate, config.alpha, config.max_grad_norm)
        self.actor = ActingModel(model, config.greedy_margin, config.seed)
        self.slot = SnapshotSlot()
        # A frozen encoder: the buffer holds each image's features (computed once, by the
        # actor for the image it acts on), so an update runs the small head only.
        self.buffer = (FeedbackBuffer(config.buffer_capacity, (FEATURE_SIZE,), np.float32)
                       if model.freeze_encoder else FeedbackBuffer(config.buffer_capacity))
        self.history = StepHistory(config.history_steps)
        steps_dir = self.run_dir / STEPS_DIR
        self.journal = StepJournal(steps_dir, StepJournal.last_segment(steps_dir) + 1)
        self.feedback_log = FeedbackLog(self.run_dir / FEEDBACK_LOG)
        self.metrics_csv = MetricsCsv(self.run_dir / METRICS_CSV)
        self.disk = DiskWriter(self.journal, lambda text: self._log('error', text))
        # Checkpoints (torch.save + fsync, 50-150 ms) on a thread of their own: a person's
        # feedback is never written behind one (a key press waited 160 ms for it).
        self.checkpoint_disk = DiskWriter(self.journal, lambda text: self._log('error', text),
                                          name='tamer-checkpoint')
        self.worker = LearnerWorker(config, self.learner, self.buffer, self.history, self.slot,
                                    self.journal, self.checkpoint_disk, self.run_dir, self._log)
        # Every key exists from the start, so readers never see the dict change size.
        self.counters = collections.Counter(dict.fromkeys((
            'act/count', 'act/fallback_observation', 'drop/observation', 'drop/saliency',
            'drop/observation_stamp', 'drop/saliency_stamp', 'session/restarts',
            'utterance/count', 'utterance/empty', 'utterance/too_long', 'feedback/logged',
            'disk/feedback_log_errors'), 0))
        self._guard = StampGuard(int(round(config.max_stamp_jump_s * NS_PER_S)))
        self._feedback_lock = threading.Lock()  # seq order == log order == inbox order
        # input_image 'saliency': observations waiting for their saliency image (stamp ->
        # monotonic arrival time); answered on the observation after saliency_timeout_s.
        self._awaiting: 'collections.OrderedDict[int, float]' = (
            collections.OrderedDict())
        self._awaiting_lock = threading.Lock()
        self._seq = 0
        self._now: Optional[int] = None
        self._stamped_at = -math.inf
        self._act_seconds = collections.deque(maxlen=1000)
        self._last_rate = (time.monotonic(), 0)
        self._started = False
        self._updates_at_start = (0, 0)  # (all, minibatch) updates before this process
        self.on_logged: Optional[Callable[[dict], None]] = None
        """Called on the disk thread with each feedback_log.jsonl entry once it is written."""

    def _check_run_dir(self) -> None:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        used = [name for name in (FEEDBACK_LOG, CHECKPOINT_DIR)
                if (self.run_dir / name).exists()]
        if used and not self.config.resume:
            raise FileExistsError(
                f'run_dir {self.run_dir} already holds a run ({", ".join(used)}): pass '
                'resume:=true to continue it, or choose a new run_dir')

    # Life cycle.
    def start(self) -> int:
        """Resume if asked, then start the threads; return the number of feedback replayed."""
        replayed = 0
        if self.config.resume:
            replayed = self._resume()
        counters = self.worker.stats()
        self._updates_at_start = (counters['train/updates'], counters['train/minibatch_updates'])
        self.disk.start()
        self.checkpoint_disk.start()
        self.worker.start()
        self._started = True
        return replayed

    def close(self) -> None:
        """Finish pending work, write a last checkpoint, close the files."""
        if self._started:
            self.disk.flush()   # every feedback received is logged and with the learner,
            self.worker.stop()  # which uses it all and queues a last checkpoint,
            self.checkpoint_disk.stop()  # which is written before the files close
            self.disk.stop()
        self.journal.close()
        self.feedback_log.close()

    def _resume(self) -> int:
        try:
            checkpoint = load_checkpoint(self.run_dir)
        except Exception as error:  # torch.load raises many kinds
            raise RuntimeError(
                f'the checkpoint in {self.run_dir / CHECKPOINT_DIR} cannot be read ({error}); '
                'move it away to resume from the feedback log alone') from error
        entries, unreadable = FeedbackLog.read(self.run_dir / FEEDBACK_LOG)
        if unreadable:
            self._log('warn', f'{unreadable} unreadable line(s) in the feedback log skipped')
        events = [event_from_entry(e) for e in entries if e.get('kind') == 'feedback']
        self._seq = max((e.seq for e in events), default=0)
        self.counters['feedback/logged'] = len(events)
        segments = {}
        records = StepJournal.read(self.run_dir / STEPS_DIR, segments)
        replayed = self.worker.restore(checkpoint, events, records)
        self.journal.adopt(segments)
        # This process is a new session: the env's stamps start over, and its steps must never
        # be taken for an earlier session's steps with the same stamps.
        earlier = [session for session, _ in segments.values()]
        earlier += [e.session for e in events]
        earlier.append(int(checkpoint.get('session', 1)) if checkpoint else 0)
        self._set_session(max(earlier) + 1)
        self._log('info', f'resumed {self.run_dir}: checkpoint '
                  f'{"at feedback #%d" % checkpoint["applied_seq"] if checkpoint else "none"}, '
                  f'{replayed} logged feedback replayed, buffer {len(self.buffer)}, '
                  f'model version {self.learner.updates}; now session {self.session}')
        return replayed

    @property
    def session(self) -> int:
        """Return the run's session number (persistence.py): 1, then one more per resume."""
        return self.history.session

    def _set_session(self, session: int) -> None:
        self.history.start_session(session)
        self.journal.session = session
        with self._awaiting_lock:
            self._awaiting.clear()
        self._now = None

    # Acting path.
    def on_observation(self, stamp: int, rgb: np.ndarray) -> Optional[int]:
        """Store observation ``stamp``; return the greedy action if the agent acts on it."""
        started = time.perf_counter()
        image = self._preprocess('observation', rgb)
        verdict = self._guard.check(stamp)
        if verdict == 'implausible':
            self.counters['drop/observation_stamp'] += 1
            raise BadInput(f'observation dropped: its stamp {stamp / NS_PER_S:.3f}s is more '
                           f'than {self.config.max_stamp_jump_s:g} s from the newest '
                           f'({self._guard.newest / NS_PER_S:.3f}s)')
        if verdict == 'restart':
            self.counters['session/restarts'] += 1
            self._set_session(self.session + 1)
            self._log('warn', f'observation stamps started over at {stamp / NS_PER_S:.3f}s (a '
                      f'new env): session {self.session} begins; feedback on earlier steps is '
                      'kept in the log, not learned from')
        self._now = stamp if self._now is None else max(self._now, stamp)
        self.worker.tick(stamp)  # simulation time for the minibatch schedule
        record = self.history.put_image('observation', stamp, image)
        self.journal.append(KIND_OBSERVATION, stamp, image=image)
        if self.config.input_image == 'saliency':
            self.worker.wake()
            if record.action is None and record.saliency is None:
                with self._awaiting_lock:  # answered by on_saliency or act_overdue
                    self._awaiting.setdefault(stamp, time.monotonic())
                    while len(self._awaiting) > self.config.history_steps:
                        self._awaiting.popitem(last=False)
                return None
        return self._act(record, started)

    def on_saliency(self, stamp: int, rgb: np.ndarray) -> Optional[int]:
        """Store saliency image ``stamp``; return the action if the agent acts on saliency."""
        started = time.perf_counter()
        image = self._preprocess('saliency', rgb)
        if not self._guard.plausible(stamp):
            self.counters['drop/saliency_stamp'] += 1
            raise BadInput(f'saliency image dropped: its stamp {stamp / NS_PER_S:.3f}s is '
                           f'more than {self.config.max_stamp_jump_s:g} s from the newest '
                           'observation')
        record = self.history.put_image('saliency', stamp, image)
        self.journal.append(KIND_SALIENCY, stamp, image=image)
        self.worker.wake()
        if self.config.input_image != 'saliency':
            return None
        with self._awaiting_lock:
            self._awaiting.pop(stamp, None)
        if record.action is not None:
            return None  # answered already (fallback); a re-sent observation is re-answered
        if record.observation is None:
            return None  # its observation was dropped: the env will re-send the step
        return self._act(record, started)

    def act_overdue(self, now: Optional[float] = None) -> List[Tuple[int, int]]:
        """
        Answer the observations whose saliency image is ``saliency_timeout_s`` (wall) late.

        ``input_image: saliency`` only: such a step is answered by acting on its observation
        (counted in ``act/fallback_observation``; the step is not learned from, as the learner
        learns on saliency images only). Returns [(stamp, action)] to publish; the node calls
        it on a timer.
        """
        now = time.monotonic() if now is None else now
        due = []
        with self._awaiting_lock:
            while self._awaiting:
                stamp, arrived = next(iter(self._awaiting.items()))
                if now - arrived < self.config.saliency_timeout_s:
                    break
                self._awaiting.popitem(last=False)
                due.append(stamp)
        answers = []
        for stamp in due:
            record = self.history.get(stamp)
            if record is None or record.action is not None or record.observation is None:
                continue
            action = self._act(record, None, image=record.observation)
            self.counters['act/fallback_observation'] += 1
            self._log('warn', f'no saliency image for step {stamp} within '
                      f'{self.config.saliency_timeout_s} s: acted on its observation')
            answers.append((stamp, action))
        return answers

    def _preprocess(self, kind: str, rgb: np.ndarray) -> torch.Tensor:
        try:
            return torch.from_numpy(preprocess(rgb))
        except ValueError as error:
            self.counters[f'drop/{kind}'] += 1
            raise BadInput(f'{kind} dropped: {error}') from error

    def _act(self, record, started: Optional[float], image=None) -> int:
        if record.action is not None:
            return record.action  # the env re-sent this step: answer it the same way
        self.actor.refresh(self.slot)
        kind = self.config.input_image if image is None else 'observation'
        image = record.image(kind) if image is None else image
        if self.actor.model.freeze_encoder:
            features = self.actor.features(image)  # encoded once: acting and learning share it
            self.history.put_features(kind, record.stamp, features)
            action = self.actor.greedy_on_features(features)
        else:
            action = self.actor.greedy(image)
        self.history.set_action(record.stamp, action)
        self.journal.append(KIND_ACTION, record.stamp, action)
        if started is not None:
            self._act_seconds.append(time.perf_counter() - started)
        self.counters['act/count'] += 1
        return action

    # Feedback path.
    def on_feedback(self, h: float, source: str, stamp: Optional[int] = None,
                    extra: Optional[dict] = None) -> FeedbackEvent:
        """
        Queue a feedback: the disk thread logs it, then hands it to the learner.

        ``source`` is 'stamped' (``stamp`` = the step judged) or 'plain' (stamped on arrival
        with the newest observation stamp, and ignored as a copy while a stamped stream is
        active). Bad values are logged and counted, never raised. Returns at once.
        """
        arrived = time.monotonic()
        h = float(h)
        status = 'ok'
        if not math.isfinite(h) or abs(h) > FEEDBACK_RANGE:  # the one range of every node
            status = 'invalid'
        elif source == 'stamped':
            self._stamped_at = arrived
        elif arrived - self._stamped_at < self.config.stamped_active_s:
            status = 'duplicate'
        if source == 'plain':
            stamp = self._now
        if status == 'ok' and stamp is None:
            status = 'no_observation'
        with self._feedback_lock:
            self._seq += 1
            event = FeedbackEvent(self._seq, h, stamp, self._now, status, self.config.credit,
                                  arrived, self.session)
            entry = {'kind': 'feedback', 'seq': event.seq, 'wall_time': time.time(),
                     'source': source, 'h': json_number(h), 'stamp_ns': stamp,
                     'now_ns': event.now, 'session': event.session, 'status': status,
                     'credit': event.credit}
            entry.update(extra or {})
            # One FIFO queue: feedback reaches the log and then the learner in arrival order.
            self.disk.submit(lambda: self._log_then_learn(entry, event))
        if status == 'invalid':
            self._log('warn', f'feedback #{event.seq} h={h} is not a finite number within '
                      f'[-{FEEDBACK_RANGE:g}, {FEEDBACK_RANGE:g}]: logged, not learned from')
        elif status == 'no_observation':
            self._log('warn', f'feedback #{event.seq} came before any observation: logged, '
                      'not learned from')
        return event

    def _log_then_learn(self, entry: dict, event: FeedbackEvent) -> None:
        """On the disk thread: the feedback is on disk (flushed) before the learner sees it."""
        try:
            self.journal.drain()  # the steps it refers to reach the disk before it does
            self.feedback_log.append(entry)
            self.counters['feedback/logged'] += 1
        except (OSError, ValueError) as error:  # a full disk: say so loudly, still learn
            self.counters['disk/feedback_log_errors'] += 1
            self._log('error', f'feedback #{event.seq} could not be written to '
                      f'{self.feedback_log.path}: {error}')
        else:
            self._receipt(entry)
        self.worker.submit(event)

    def _receipt(self, entry: dict) -> None:
        if self.on_logged is not None:
            try:
                self.on_logged(entry)
            except Exception as error:  # a receipt must never cost the feedback
                self._log('error', f'receipt for a logged {entry["kind"]} failed: {error!r}')

    def _log_utterance(self, entry: dict) -> None:
        self.feedback_log.append(entry)
        self._receipt(entry)

    def on_utterance(self, text: str, extra: Optional[dict] = None) -> str:
        """
        Record an utterance in the feedback log (the saliency node turns it into images).

        Returns its status: 'ok', or 'empty' / 'too_long' (longer than MAX_UTTERANCE_CHARS),
        which are counted, warned about and logged with that status (a long one's first
        MAX_UTTERANCE_CHARS characters), as the saliency node drops them too.
        """
        self.counters['utterance/count'] += 1
        status = 'ok'
        if not text.strip():
            status = 'empty'
            self.counters['utterance/empty'] += 1
            self._log('warn', 'utterance dropped: empty or only whitespace (logged as such)')
        elif len(text) > MAX_UTTERANCE_CHARS:
            status = 'too_long'
            self.counters['utterance/too_long'] += 1
            self._log('warn', f'utterance dropped: {len(text)} characters, more than '
                      f'{MAX_UTTERANCE_CHARS} (its start is logged)')
        entry = {'kind': 'utterance', 'wall_time': time.time(), 'now_ns': self._now,
                 'session': self.session, 'status': status, 'chars': len(text),
                 'text': text[:MAX_UTTERANCE_CHARS]}
        entry.update(extra or {})
        self.disk.submit(lambda: self._log_utterance(entry))
        return status

    def set_alpha(self, alpha: float) -> None:
        if not (math.isfinite(alpha) and alpha >= 0.0):
            raise ValueError(f'alpha must be a finite number >= 0, got {alpha}')
        self.learner.alpha = float(alpha)
        self.config.alpha = float(alpha)

    # Metrics.
    def metrics(self) -> dict:
        """
        Namespaced key -> number, for the metrics topic and metrics.csv.

        The loss means cover the updates since the previous call (one metrics period).
        """
        values = self.worker.stats()
        values.update(self.worker.period_losses())
        values.update(self.counters)
        values['feedback/received'] = self._seq
        values['act/version'] = self.actor.version
        values['train/alpha'] = self.learner.alpha
        values['disk/errors'] = self.disk.errors + self.checkpoint_disk.errors
        now, updates = time.monotonic(), values['train/updates']
        last_time, last_updates = self._last_rate
        values['train/updates_per_s'] = (updates - last_updates) / max(now - last_time, 1e-9)
        self._last_rate = (now, updates)
        # Per agent step acted on by this process (a resumed run's earlier updates left out).
        acted = max(values['act/count'], 1)
        values['train/updates_per_step'] = (updates - self._updates_at_start[0]) / acted
        values['train/minibatch_updates_per_step'] = (
            values['train/minibatch_updates'] - self._updates_at_start[1]) / acted
        seconds = sorted(self._act_seconds)  # the last 1000 acts; NaN before the first
        values['act/latency_p50_ms'] = values['act/latency_p99_ms'] = math.nan
        if seconds:
            values['act/latency_p50_ms'] = 1e3 * seconds[len(seconds) // 2]
            values['act/latency_p99_ms'] = 1e3 * seconds[int(0.99 * (len(seconds) - 1))]
        return values

    def write_metrics_row(self, values: dict) -> None:
        """Queue a metrics.csv row (written on the disk thread)."""
        row = dict(values, wall_time=round(time.time(), 3))
        self.disk.submit(lambda: self.metrics_csv.write(row))


def event_from_entry(entry: dict) -> FeedbackEvent:
    """Rebuild a FeedbackEvent from its feedback_log.jsonl line (for replay on resume)."""
    h = entry.get('h')
    return FeedbackEvent(
        seq=int(entry['seq']), h=float(h) if h is not None else math.nan,
        stamp=entry.get('stamp_ns'), now=entry.get('now_ns'), status=entry.get('status', 'ok'),
        credit=entry.get('credit', 'step'), arrived=0.0, session=int(entry.get('session', 1)))

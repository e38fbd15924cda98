"""
TamerAgent: everything tamer_node does, without ROS (the node converts messages and calls it).

The composition root: it builds the parts, starts and stops their threads, and reads their
metrics. Concurrency contract: four kinds of thread touch the agent; each owns its objects and
hands over through one point.

- Acting (acting.py; the ``observation``/``saliency`` callbacks, or a benchmark loop): returns
  the greedy action for a step at once, with its own copy of H; takes only short locks (history,
  snapshot slot) and never waits for training, sampling or disk I/O.
- Feedback (intake.py; the ``feedback*`` and ``utterance`` callbacks): numbers the feedback and
  queues it to the disk thread, which logs it (flushed) and only then puts it in the learner's
  inbox: what the learner uses is on disk, in arrival order.
- Learner (learner_loop.py, with the pure pairing.py): the only user of the ``Learner`` and the
  only writer of the ``FeedbackBuffer``; it hands weights to the actor through the
  ``SnapshotSlot`` and takes checkpoints between updates (checkpointing.py).
- Disk (``persistence.DiskWriter``): one FIFO of jobs: the feedback log, journal drains,
  metrics rows. Checkpoint files (small: the buffer's images are in the journal, but written
  with an fsync) go to a second DiskWriter, so a feedback line never waits behind one.
- Metrics (a timer callback, ``metrics``): reads counters under the learner's small lock.
"""

import collections
import functools
import math
from pathlib import Path
import sys
import time
from typing import Callable, Optional

from attention_common.run_files import CHECKPOINT_DIR, FEEDBACK_LOG, METRICS_CSV, STEPS_DIR
from attention_tasks.task import DEFAULT_TASK, load_task
import cv2
import numpy as np
# BadInput is raised by the acting path; node.py imports it from here.
from tamer_node.acting import ActingModel, ActingPath, BadInput, SnapshotSlot  # noqa: F401
from tamer_node.buffer import FeedbackBuffer, KEPT_CAPACITY
from tamer_node.checkpointing import next_session, read_initial_model, read_run
from tamer_node.config import TamerConfig
from tamer_node.events import AGENT_COUNTERS
from tamer_node.history import StepHistory
from tamer_node.intake import FeedbackIntake
from tamer_node.learner import Learner
from tamer_node.learner_loop import LearnerWorker
from tamer_node.memory import VerdictMemory
from tamer_node.model import Encoder, FEATURE_SIZE, HModel, joystick_parts, load_encoder
from tamer_node.persistence import DiskWriter, FeedbackLog, MetricsCsv, StepJournal
import torch

WEIGHTS_DIR = Path(__file__).resolve().parent / 'weights'
DEFAULT_ENCODER = WEIGHTS_DIR / 'encoder.pt'
"""Room 1's (the default task's) shipped encoder."""


def encoder_for_task(task: str) -> Path:
    """Return the shipped encoder file of ``task`` (its ``encoder_file``)."""
    return WEIGHTS_DIR / load_task(task).encoder_file


def how_to_build_encoder(task: str) -> str:
    return (f'build it with `tamer_pretrain --task {task}` (writes {encoder_for_task(task)}, '
            'a few minutes on one core) or set encoder_path')


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


def resolve_encoder(path: str, task: str = DEFAULT_TASK) -> Path:
    """Return the encoder file to load: ``path``, or the task's shipped one when empty."""
    return Path(path).expanduser() if path else encoder_for_task(task)


class TamerAgent:
    """Deep TAMER with the saliency L2 term: acts greedily, learns on its own thread."""

    def __init__(self, config: TamerConfig, run_dir: Path, encoder: Optional[Encoder] = None,
                 log: Optional[Callable[[str, str], None]] = None):
        config.validate()
        self.config = config
        self.run_dir = Path(run_dir)
        self._log = log or (lambda level, text: None)
        if encoder is None:
            encoder_file = resolve_encoder(config.encoder_path, config.task)
            if not encoder_file.exists():
                raise FileNotFoundError(f'encoder weights {encoder_file} are missing: '
                                        f'{how_to_build_encoder(config.task)}')
            encoder = load_encoder(encoder_file)
        self._check_run_dir()
        torch.manual_seed(config.seed)
        self.task = load_task(config.task)
        model = HModel(config.head_hidden, freeze_encoder=not config.fine_tune_encoder,
                       encoder=encoder, num_actions=self.task.num_actions,
                       parts=(joystick_parts(self.task.joy_actions)
                              if config.share_action_parts else None),
                       streams=2 if config.input_image == 'both' else 1,
                       text_size=config.text_size if config.text_conditioning == 'film' else 0)
        if config.initial_model:
            self._start_from(model, read_initial_model(config.initial_model, config.input_image))
        self.learner = Learner(model, config.learning_rate, config.alpha, config.max_grad_norm,
                               config.credit_loss, config.positive_excludes)
        self.actor = ActingModel(model, config.greedy_margin, config.seed,
                                 config.keep_tied_action)
        self.slot = SnapshotSlot()
        # A frozen encoder: the buffer holds each image's features (computed once, by the
        # actor for the image it acts on), so an update runs the small head only.
        ring = (functools.partial(FeedbackBuffer, item_shape=(
            FEATURE_SIZE * model.streams + model.text_size,), dtype=np.float32)
            if model.freeze_encoder else FeedbackBuffer)
        self.buffer = ring(config.buffer_capacity)
        kept = ring(KEPT_CAPACITY) if config.kept_per_batch else None  # step credit's own
        self.history = StepHistory(config.history_steps)
        steps_dir = self.run_dir / STEPS_DIR
        self.journal = StepJournal(steps_dir, StepJournal.last_segment(steps_dir) + 1)
        self.feedback_log = FeedbackLog(self.run_dir / FEEDBACK_LOG, config.sync)
        self.metrics_csv = MetricsCsv(self.run_dir / METRICS_CSV)
        self.disk = DiskWriter(self.journal, lambda text: self._log('error', text),
                               when_idle=self.feedback_log.commit)
        # Checkpoints (torch.save + fsync, 50-150 ms) on a thread of their own: a person's
        # feedback is never written behind one (a key press waited 160 ms for it).
        self.checkpoint_disk = DiskWriter(self.journal, lambda text: self._log('error', text),
                                          name='tamer-checkpoint')
        memory = (VerdictMemory(config.verdict_memory, self.task.num_actions,
                                config.buffer_capacity) if config.verdict_memory > 0 else None)
        self.worker = LearnerWorker(config, self.learner, self.buffer, self.history, self.slot,
                                    self.journal, self.checkpoint_disk, self.run_dir, self._log,
                                    memory, kept)
        # Every key exists from the start, so readers never see the dict change size.
        self.counters = collections.Counter(dict.fromkeys(AGENT_COUNTERS, 0))
        self.acting = ActingPath(config, self.actor, self.slot, self.history, self.journal,
                                 self.worker, self.counters, self._log, memory)
        self.intake = FeedbackIntake(config, self.counters, self.acting, self.journal,
                                     self.feedback_log, self.disk, self.worker.submit, self._log,
                                     self.worker.expect)
        # What the node and the benchmarks call: acting.py and intake.py say what each does.
        self.on_observation = self.acting.on_observation
        self.on_saliency = self.acting.on_saliency
        self.on_action_taken = self.acting.on_action_taken
        self.act_overdue = self.acting.act_overdue
        self.on_feedback = self.intake.on_feedback
        self._last_rate = (time.monotonic(), 0)
        self._started = False
        self._updates_at_start = (0, 0)  # (all, minibatch) updates before this process

    def on_utterance(self, text: str, extra: Optional[dict] = None) -> str:
        """Log the utterance (intake.py); a text-conditioned learner also hears it from now on."""
        status = self.intake.on_utterance(text, extra)
        if status == 'ok':
            self.acting.hear(text)
        return status

    @property
    def on_logged(self) -> Optional[Callable[[dict], None]]:
        """Return the receipt hook: called on the disk thread with each logged entry."""
        return self.intake.on_logged

    @on_logged.setter
    def on_logged(self, receipt: Optional[Callable[[dict], None]]) -> None:
        self.intake.on_logged = receipt

    @property
    def session(self) -> int:
        """Return the run's session number (persistence.py): 1, then one more per resume."""
        return self.acting.session

    def _start_from(self, model: HModel, weights: dict) -> None:
        try:
            model.load_state_dict(weights)
        except RuntimeError as error:  # torch names every missing or misshapen tensor
            raise ValueError(f'initial_model {self.config.initial_model} does not fit this '
                             f'learner (task, text_conditioning, head_hidden, '
                             f'share_action_parts): {error}') from None
        self._log('info', f'H starts from the model of {self.config.initial_model}')

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
        checkpoint, events, records, segments = read_run(self.run_dir, self._log)
        self.intake.seq = max((e.seq for e in events), default=0)
        self.counters['feedback/logged'] = len(events)
        replayed = self.worker.restore(checkpoint, events, records)
        self.journal.adopt(segments)
        # This process is a new session: the env's stamps start over, and its steps must never
        # be taken for an earlier session's steps with the same stamps.
        self.acting.start_session(next_session(segments, events, checkpoint))
        self._log('info', f'resumed {self.run_dir}: checkpoint '
                  f'{"at feedback #%d" % checkpoint["applied_seq"] if checkpoint else "none"}, '
                  f'{replayed} logged feedback replayed, buffer {len(self.buffer)}, '
                  f'model version {self.learner.updates}; now session {self.session}')
        return replayed

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
        values['feedback/received'] = self.intake.seq
        values['act/version'] = self.actor.version
        values['train/alpha'] = self.learner.alpha
        values['disk/errors'] = self.disk.errors + self.checkpoint_disk.errors
        values['disk/feedback_syncs'] = self.feedback_log.syncs
        now, updates = time.monotonic(), values['train/updates']
        last_time, last_updates = self._last_rate
        values['train/updates_per_s'] = (updates - last_updates) / max(now - last_time, 1e-9)
        self._last_rate = (now, updates)
        # Per agent step acted on by this process (a resumed run's earlier updates left out).
        acted = max(values['act/count'], 1)
        values['train/updates_per_step'] = (updates - self._updates_at_start[0]) / acted
        values['train/minibatch_updates_per_step'] = (
            values['train/minibatch_updates'] - self._updates_at_start[1]) / acted
        seconds = sorted(self.acting.act_seconds)  # the last 1000 acts; NaN before the first
        values['act/latency_p50_ms'] = values['act/latency_p99_ms'] = math.nan
        if seconds:
            values['act/latency_p50_ms'] = 1e3 * seconds[len(seconds) // 2]
            values['act/latency_p99_ms'] = 1e3 * seconds[int(0.99 * (len(seconds) - 1))]
        return values

    def write_metrics_row(self, values: dict) -> None:
        """Queue a metrics.csv row (written on the disk thread)."""
        row = dict(values, wall_time=round(time.time(), 3))
        self.disk.submit(lambda: self.metrics_csv.write(row))

"""
Run a study's trials: each one ``attention_train`` subprocess, up to ``parallel`` at a time.

Trials are planned seed by seed across conditions (seed 0 of every condition first), so an
interrupted study is balanced. A trial whose result file exists is skipped; a crashed trial
keeps its result file (and is re-run only with ``retry_crashed``, its old file moved to
``trials/<condition>/retried/``). On Ctrl-C or SIGTERM every running launcher gets one SIGINT
(it stops its nodes cleanly); interrupted trials write no result file and run again next time.
"""

from dataclasses import dataclass
import datetime
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import threading
import time
from typing import Callable, List, Mapping, Optional, Sequence, Tuple

from attention_bringup.experiment.trials import (
    build_record, is_usable, read_json, trial_path, write_json)
from attention_bringup.plan import positive_int
from attention_common.isolation import isolated_environ
from attention_common.node_main import unblock_stop_signals
from attention_common.run_files import LAUNCHER_LOG, REPLAY_LOG

EXIT_INTERRUPTED = 130
"""A study command's exit code after Ctrl-C (finished trials are kept)."""
TRAIN, REPLAY = 'attention_train', 'attention_replay'
"""What a trial runs: a training run of the graph, or a recorded session replayed into a fresh
learner (``launcher_args`` then start with the bag)."""
PROGRAM_LOGS = {TRAIN: LAUNCHER_LOG, REPLAY: REPLAY_LOG}
STOP_GRACE_S = 90.0
"""After its SIGINT, how long a launcher may take to stop its nodes before SIGTERM."""


@dataclass(frozen=True)
class TrialJob:
    """One trial to run."""

    condition: str
    seed: int
    steps: int
    result_path: Path
    run_dir: Path
    launcher_args: Tuple[str, ...] = ()
    """More ``attention_train`` options (the trainer, the human-like setting)."""
    measure: Optional[Callable[[dict, Path], dict]] = None
    """A study's own measures, added to the record from the run folder where the trial ran
    (a module-level function: on Ray it runs on the worker, beside the run folder)."""
    arm: str = ''
    """The experiment's arm (its condition when an arm is a condition)."""
    program: str = TRAIN
    """``TRAIN`` or ``REPLAY`` (both stop their nodes on one SIGINT)."""


def auto_timeout_s(steps: int) -> float:
    """Backstop per trial (the launcher itself gives up after 2 min without a step)."""
    return 1800.0 + 1.0 * steps


def plan_trials(conditions: Sequence[str], trials: int, steps: int, out_dir: Path,
                runs_dir: Path, retry_crashed: bool = False,
                launcher_args: Sequence[str] = (), seeds: Optional[Sequence[int]] = None,
                measure: Optional[Callable[[dict, Path], dict]] = None, arm: str = '',
                program: str = TRAIN) -> Tuple[List[TrialJob], List[Path]]:
    """
    Return (trials to run, result files that exist and are kept).

    A result file of another budget raises ``ValueError`` (one budget per ``out_dir``); an
    unreadable one too (it is not silently overwritten).
    """
    pending, kept = [], []
    for seed in (range(trials) if seeds is None else seeds):
        for condition in conditions:
            path = trial_path(out_dir, condition, seed)
            run_dir = Path(runs_dir) / condition / f'seed{seed}'
            job = TrialJob(condition, seed, steps, path, run_dir, tuple(launcher_args), measure,
                           arm or condition, program)
            if not path.exists():
                pending.append(job)
                continue
            record = read_json(path)
            if record is None:
                raise ValueError(f'{path} exists but is not valid JSON; delete it to re-run')
            if record.get('budget') != steps:
                raise ValueError(f'{path} holds a trial of {record.get("budget")} steps, not '
                                 f'{steps}; use another --out for another budget')
            if retry_crashed and not is_usable(record):
                retire(path)
                pending.append(job)
            else:
                kept.append(path)
    return pending, kept


def retire(path: Path) -> Path:
    """Move a crashed trial's result file to ``retried/`` (kept for the report)."""
    folder = path.parent / 'retried'
    folder.mkdir(exist_ok=True)
    n = 1
    while (folder / f'{path.stem}-attempt{n}.json').exists():
        n += 1
    target = folder / f'{path.stem}-attempt{n}.json'
    path.replace(target)
    return target


def load_retired(out_dir: Path, conditions: Sequence[str]) -> List[dict]:
    records = []
    for condition in conditions:
        for path in sorted((Path(out_dir) / 'trials' / condition / 'retried').glob('*.json')):
            record = read_json(path)
            if record is not None:
                records.append(record)
    return records


def launcher_command(launcher: Path, job: TrialJob) -> List[str]:
    """Return the trial's command: ``launcher`` (``attention_train``) or the replay beside it."""
    own = ['--condition', job.condition, '--seed', str(job.seed), '--run-dir', str(job.run_dir),
           '--quiet']
    if job.program == REPLAY:  # it replays the whole bag: no budget to give
        return [str(Path(launcher).parent / REPLAY), *job.launcher_args, *own]
    return [str(launcher), '--steps', str(job.steps), *own, *job.launcher_args]


def _signal(process: subprocess.Popen, sig: signal.Signals) -> None:
    try:
        process.send_signal(sig)
    except ProcessLookupError:
        pass


def run_trial(job: TrialJob, launcher: Path, stop: threading.Event, timeout_s: float,
              parallel: int = 1, write: bool = True) -> Optional[dict]:
    """Run one trial to its end and (``write``) its result file; None if the study stopped."""
    if job.run_dir.exists():  # left by an interrupted attempt: its data is not a result
        shutil.rmtree(job.run_dir)
    job.run_dir.mkdir(parents=True)
    started_at = datetime.datetime.now().isoformat(timespec='seconds')
    started = time.monotonic()
    # The launcher reserves its own ROS domain; localhost discovery for anything it inherits.
    environ = isolated_environ(0)
    environ.pop('ROS_DOMAIN_ID')
    with open(job.run_dir / PROGRAM_LOGS[job.program], 'wb') as log:
        process = subprocess.Popen(launcher_command(launcher, job), stdin=subprocess.DEVNULL,
                                   stdout=log, stderr=subprocess.STDOUT, env=environ,
                                   start_new_session=True)
        interrupted_at, timed_out = None, False
        escalation = iter((signal.SIGTERM, signal.SIGKILL))
        while process.poll() is None:
            now = time.monotonic()
            if interrupted_at is None and (stop.is_set() or now - started > timeout_s):
                timed_out = not stop.is_set()
                interrupted_at = now
                _signal(process, signal.SIGINT)
            elif interrupted_at is not None and now - interrupted_at > STOP_GRACE_S:
                _signal(process, next(escalation, signal.SIGKILL))
                interrupted_at = now - STOP_GRACE_S + 10.0
            time.sleep(0.25)
    if stop.is_set() and not timed_out:
        return None
    record = build_record(job.condition, job.seed, job.steps, job.run_dir, process.returncode,
                          time.monotonic() - started, timed_out=timed_out,
                          started_at=started_at, parallel=parallel)
    if job.measure is not None:
        record = job.measure(record, job.run_dir)
    if write:
        write_json(job.result_path, record)
    return record


def run_trials(jobs: Sequence[TrialJob], launcher: Path, parallel: int, timeout_s: float,
               stop: threading.Event,
               report: Callable[[TrialJob, Optional[dict], int], None]) -> List[dict]:
    """Run ``jobs`` with ``parallel`` workers until done or ``stop`` is set."""
    queue = list(jobs)
    lock = threading.Lock()
    records: List[dict] = []

    def worker() -> None:
        while not stop.is_set():
            with lock:
                if not queue:
                    return
                job = queue.pop(0)
            record = run_trial(job, launcher, stop, timeout_s, parallel)
            with lock:
                if record is not None:
                    records.append(record)
                report(job, record, len(records))

    threads = [threading.Thread(target=worker, name=f'trial-worker-{i}', daemon=True)
               for i in range(max(1, parallel))]
    for thread in threads:
        thread.start()
    for thread in threads:
        while thread.is_alive():
            thread.join(timeout=0.5)
    return records


@dataclass(frozen=True)
class Backend:
    """Where a study's trials run (``--backend``, ``--address``, ``--parallel``)."""

    name: str = 'local'
    address: str = 'auto'
    parallel: int = 1


def add_backend_options(parser, parallel: Optional[int] = 1) -> None:
    """Add ``--parallel``, ``--backend`` and ``--address`` (every study command has them)."""
    default = "the spec's" if parallel is None else parallel
    parser.add_argument('--parallel', type=positive_int, default=parallel,
                        help=f'trials run side by side (default {default}; each is 4 node '
                             'processes)')
    parser.add_argument('--backend', choices=('local', 'ray'), default='local',
                        help="where trials run: 'local' (default, --parallel at a time) or "
                             "'ray' (each trial a task on the Ray cluster at --address, as "
                             "many at a time as its nodes' attention_graph resource allows; "
                             'docs/cluster.md)')
    parser.add_argument('--address', default='auto',
                        help="the Ray cluster with --backend ray (default 'auto': the one "
                             'started on this machine)')


def backend_of(options) -> Backend:
    return Backend(options.backend, options.address, options.parallel)


def launcher_path() -> Path:
    """Return this environment's ``attention_train``; FileNotFoundError if it is missing."""
    launcher = Path(sys.executable).parent / 'attention_train'
    if not os.access(launcher, os.X_OK):
        raise FileNotFoundError(f'{launcher} not found (run make setup)')
    return launcher


def run_pending(jobs: Sequence[TrialJob], backend: Backend, timeout_s: float,
                report: Callable[[TrialJob, Optional[dict], int], None],
                say: Callable[[str], None]) -> Tuple[List[dict], bool]:
    """
    Run ``jobs`` on ``backend`` until done, Ctrl-C or SIGTERM; return (records, interrupted).

    On a stop every running launcher gets one SIGINT and stops its own nodes; this returns only
    once they have (interrupted trials write no result file and run again next time).
    """
    launcher = launcher_path()
    unblock_stop_signals()  # Ctrl-C reaches the study, and the SIGINT it sends each launcher
    stop, done, box = threading.Event(), threading.Event(), {}

    def work() -> None:
        try:
            if backend.name == 'ray':
                from attention_bringup.experiment import ray_backend
                box['records'] = ray_backend.run_trials(jobs, backend.address, timeout_s, stop,
                                                        report)
            else:
                box['records'] = run_trials(jobs, launcher, backend.parallel, timeout_s, stop,
                                            report)
        except Exception as error:  # noqa: B902 - said, and the study ends with the rest
            box['error'] = error
        finally:
            done.set()

    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    threading.Thread(target=work, name='trials', daemon=True).start()
    # The main thread waits on an Event, not Thread.join: a join interrupted by Ctrl-C can leave
    # is_alive() False while the thread still runs (Python 3.11), and the trials would be lost.
    try:
        while not done.wait(timeout=0.5):
            pass
    except KeyboardInterrupt:
        say('interrupted: stopping the running trials (each launcher stops its nodes)...')
        stop.set()
        while not done.is_set():
            try:
                done.wait(timeout=0.5)
            except KeyboardInterrupt:
                say(f'still stopping; the launchers get SIGTERM after {STOP_GRACE_S:.0f} s')
    finally:
        signal.signal(signal.SIGTERM, previous)
    if 'error' in box:
        raise ValueError(f'the trials could not run: {box["error"]}')
    return box.get('records', []), stop.is_set()


def log_entry(backend: Backend, records: Sequence[Mapping], started_at: str, wall_s: float,
              interrupted: bool, **more) -> dict:
    """One invocation's entry in a study's log (the same fields for every study)."""
    return {'argv': sys.argv[1:], 'started_at': started_at, 'wall_time_s': round(wall_s, 1),
            'parallel': backend.parallel, 'backend': backend.name, **more,
            'cpus': os.cpu_count(), 'trials_run': len(records),
            'trials_crashed': sum(1 for r in records if not is_usable(r)),
            'interrupted': interrupted}

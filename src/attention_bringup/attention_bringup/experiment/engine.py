"""
The one engine every study runs on: plan a spec's trials, run them, keep the store, report.

The store is the spec's ``out`` folder: one result file per finished trial (the record: a trial
whose file exists is skipped, so the same command resumes), the log of every invocation
(``spec.log``), ``analysis.json``; the report goes to ``spec.report``. Trials run on a
``runner.Backend`` (local, ``parallel`` at a time, or a Ray cluster); Ctrl-C stops every
launcher it started. What a task measures, analyses and says is its plug-in's
(``experiment/plugins/``).
"""

import datetime
import importlib
from pathlib import Path
import sys
import time
from typing import Callable, Dict, List, Optional, Tuple

from attention_bringup.experiment import runner
from attention_bringup.experiment.spec import Arm, Spec, SpecError
from attention_bringup.experiment.trials import (
    load_records, read_json, refresh_records, trial_path, write_json)
from attention_common.run_files import ANALYSIS_FILE
import yaml

Say = Callable[[str], None]


def plugin_of(spec: Spec):
    """Import the spec's plug-in module (``experiment/plugins/<name>.py``)."""
    name = f'attention_bringup.experiment.plugins.{spec.plugin}'
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as error:
        if error.name != name:
            raise  # the plug-in is there; something it imports is not
        raise SpecError(f'{spec.source or spec.name}: no plug-in {spec.plugin!r}') from error


def arm_out(spec: Spec, arm: Arm) -> Path:
    """Where an arm's result files live (``trials/<condition>/`` below this)."""
    return Path(spec.out) / arm.name if spec.layout == 'by_arm' else Path(spec.out)


def arm_runs(spec: Spec, arm: Arm) -> Path:
    return Path(spec.runs_dir) / arm.name if spec.layout == 'by_arm' else Path(spec.runs_dir)


def result_path(spec: Spec, arm: Arm, seed: int) -> Path:
    return trial_path(arm_out(spec, arm), arm.condition, seed)


def trial_parameters(spec: Spec) -> Dict[str, dict]:
    """Return the node parameters every trial gets: the spec's and the plug-in's."""
    merged = {node: dict(values) for node, values in spec.parameters.items()}
    for node, values in getattr(plugin_of(spec), 'parameters', lambda spec: {})(spec).items():
        merged.setdefault(node, {}).update(values)
    return merged


def write_params(spec: Spec) -> Optional[Path]:
    """Write the parameters every trial gets into ``out``; None if there are none."""
    return _write_params(Path(spec.out) / spec.params_file, trial_parameters(spec),
                         f'# Written by the experiment engine ({spec.name!r}): every trial of '
                         'the study.')


def write_arm_params(spec: Spec, arm: Arm) -> Optional[Path]:
    """Write an arm's own parameters into ``<out>/<arm>_params.yaml``; None if it has none."""
    return _write_params(Path(spec.out) / f'{arm.name}_params.yaml', arm.parameters,
                         f'# Written by the experiment engine ({spec.name!r}): the trials of '
                         f'arm {arm.name!r}, on top of the parameters of every trial.')


def _write_params(path: Path, parameters, header: str) -> Optional[Path]:
    if not parameters:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    nodes = {node: {'ros__parameters': dict(values)} for node, values in parameters.items()}
    path.write_text(f'{header}\n{yaml.safe_dump(nodes, sort_keys=False)}')
    return path


def plan(spec: Spec, retry_crashed: bool = False, params: Optional[Path] = None
         ) -> Tuple[List[runner.TrialJob], List[Path]]:
    """Return (trials to run, result files kept), seed by seed across arms (balanced)."""
    measure = getattr(plugin_of(spec), 'measure', None)
    pending, kept = [], []
    arm_params = {arm.name: write_arm_params(spec, arm) for arm in spec.arms}
    for seed in spec.seeds:
        for arm in spec.arms:
            own = arm_params[arm.name]
            jobs, files = runner.plan_trials(
                [arm.condition], 0, spec.budget, arm_out(spec, arm),
                arm_runs(spec, arm).resolve(), retry_crashed,
                spec.trial_args(arm, params.resolve() if params else None,
                                own.resolve() if own else None), seeds=[seed],
                measure=measure, arm=arm.name, program=spec.program)
            pending += jobs
            kept += files
    return pending, kept


def read_log(spec: Spec) -> List[dict]:
    return read_json(Path(spec.out) / spec.log) or []


class _Progress:
    """One line per finished trial, with the plug-in's measures and the time left."""

    def __init__(self, spec: Spec, total: int, say: Say):
        self.text = getattr(plugin_of(spec), 'progress', lambda record: '')
        self.total, self.say = total, say
        self.started = time.monotonic()
        self.done = 0

    def __call__(self, job: runner.TrialJob, record: Optional[dict], finished: int) -> None:
        if record is None:
            self.say(f'{job.arm} seed {job.seed}: interrupted (no result file; runs again next '
                     'time)')
            return
        self.done += 1
        left = (self.total - self.done) * (time.monotonic() - self.started) / self.done
        measures = self.text(record)
        self.say(f'[{self.done}/{self.total}] {job.arm} seed {job.seed}: {record["outcome"]}, '
                 f'{record["steps"]} steps in {record["wall_time_s"]:.0f} s'
                 f'{", " + measures if measures else ""} (about {left / 60:.0f} min left)')


def run(spec: Spec, backend: runner.Backend, say: Say, retry_crashed: bool = False,
        timeout_s: float = 0.0) -> Optional[dict]:
    """Run the spec's pending trials; return the log entry (None if there was nothing to run)."""
    getattr(plugin_of(spec), 'check', lambda spec: None)(spec)  # SpecError: why it cannot run
    Path(spec.out).mkdir(parents=True, exist_ok=True)
    jobs, kept = plan(spec, retry_crashed, write_params(spec))
    if kept:
        say(f'{len(kept)} trial(s) already have results: skipped')
    if not jobs:
        return None
    say(f'running {len(jobs)} trial(s) of {spec.budget} steps on the {backend.name} backend'
        + (f', {backend.parallel} at a time' if backend.name == 'local' else '')
        + f'; run folders in {spec.runs_dir}')
    started_at = datetime.datetime.now().isoformat(timespec='seconds')
    started = time.monotonic()
    records, interrupted = runner.run_pending(
        jobs, backend, timeout_s or runner.auto_timeout_s(spec.budget),
        _Progress(spec, len(jobs), say), say)
    entry = runner.log_entry(backend, records, started_at, time.monotonic() - started,
                             interrupted, steps=spec.budget, trials_skipped=len(kept))
    write_json(Path(spec.out) / spec.log, read_log(spec) + [entry])
    return entry


def refresh(spec: Spec, say: Say) -> None:
    """Rebuild the result files from their run folders (relative ones under the cwd)."""
    done, skipped = 0, 0
    for arm in spec.arms:
        refreshed, missed = refresh_records(arm_out(spec, arm), [arm.condition], Path.cwd())
        for path, why in missed.items():
            say(f'{path}: not refreshed: {why}')
        done, skipped = done + len(refreshed), skipped + len(missed)
    say(f'{done} result file(s) refreshed from their run folders, {skipped} skipped')


def load(spec: Spec) -> Dict[str, List[dict]]:
    """
    Every result file of the spec's arms and seeds, by arm, sorted by seed.

    A record whose run folder is still here is measured again by the plug-in's ``measure``
    (and its file rewritten), so a measure added later reaches every trial.
    """
    measure = getattr(plugin_of(spec), 'measure', None)
    seeds = set(spec.seeds)
    by_arm = {}
    for arm in spec.arms:
        records = [r for r in load_records(arm_out(spec, arm), [arm.condition])[arm.condition]
                   if r['seed'] in seeds]
        for record in records:
            run_dir = Path(record.get('run_dir', ''))
            if measure is not None and record.get('run_dir') and run_dir.is_dir():
                measure(record, run_dir)
                write_json(result_path(spec, arm, record['seed']), record)
        by_arm[arm.name] = records
    return by_arm


def analyse_and_report(spec: Spec, context: Optional[dict] = None) -> dict:
    """Load the store, let the plug-in analyse it, write ``analysis.json`` and the report."""
    plugin = plugin_of(spec)
    by_arm = load(spec)
    log = read_log(spec)
    result = plugin.analyse(spec, by_arm, dict(context or {}, log=log))
    stored = getattr(plugin, 'stored', lambda result: result)(result)
    write_json(Path(spec.out) / ANALYSIS_FILE, stored)
    plugin.write_report(spec, result, by_arm, dict(context or {}, log=log))
    return result


def main_flow(spec: Spec, backend: runner.Backend, say: Say, run_trials: bool = True,
              refresh_first: bool = False, retry_crashed: bool = False,
              timeout_s: float = 0.0, context: Optional[dict] = None) -> Tuple[int, dict]:
    """Run (unless told not to), then analyse and report: (exit code, analysis)."""
    interrupted = False
    try:
        if refresh_first:
            refresh(spec, say)
        elif run_trials:
            entry = run(spec, backend, say, retry_crashed, timeout_s)
            interrupted = bool(entry and entry['interrupted'])
        result = analyse_and_report(spec, context)
    except (ValueError, FileNotFoundError) as error:
        say(str(error))
        return 2, {}
    return (runner.EXIT_INTERRUPTED if interrupted else 0), result


def sayer(prog: str) -> Say:
    def say(text: str) -> None:
        sys.stderr.write(f'{prog}: {text}\n')
        sys.stderr.flush()
    return say

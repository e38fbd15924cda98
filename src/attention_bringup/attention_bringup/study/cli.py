"""
``attention_study``: run the thesis's chapter 5 study and write its report.

Runs every condition's trials through ``attention_train`` (seed = trial index), keeps one small
result file per trial under ``<out>/trials/``, then draws the figures into ``<out>/`` and writes
the report. Trials whose result file exists are skipped, so the same command resumes. With
``--analyze-only`` it only redraws the figures and rewrites the report from the result files;
``--refresh-records`` first rebuilds the result files from the trials' run folders (for fields
added since they were written), then does the same.

Exit code: 0 when the report was written (crashed trials are in it); 2 for bad options or
result files; 130 when interrupted (finished trials are kept).
"""

import argparse
import datetime
import json
import os
from pathlib import Path
import shlex
import sys
import time
from typing import List, Optional, Sequence

from attention_bringup.graph import CONDITIONS
from attention_bringup.plan import positive_int
from attention_bringup.study import analysis as study_analysis
from attention_bringup.study import figures, report, runner
from attention_bringup.study.trials import load_records, refresh_records, write_json
from attention_common.run_files import ANALYSIS_FILE, STUDY_LOG
from feedback_node.teacher import TRAINERS

DEFAULT_TRIALS = 10
DEFAULT_STEPS = 10000
DEFAULT_OUT = 'docs/study'
DEFAULT_REPORT = 'docs/results.md'
DEFAULT_RUNS = 'runs/study'
EXIT_INTERRUPTED = runner.EXIT_INTERRUPTED


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='attention_study',
        description='Run the study of thesis chapter 5 (every condition, N seeded trials of the '
                    'real node graph), analyse it and write the report. Existing trial results '
                    'are skipped, so an interrupted study resumes with the same command.')
    parser.add_argument('--conditions', nargs='+', choices=CONDITIONS, default=list(CONDITIONS),
                        metavar='NAME', help=f'conditions (default all: {" ".join(CONDITIONS)})')
    parser.add_argument('--trials', type=positive_int, default=DEFAULT_TRIALS,
                        help=f'trials per condition, seeds 0..N-1 (default {DEFAULT_TRIALS})')
    parser.add_argument('--steps', type=positive_int, default=DEFAULT_STEPS,
                        help=f'agent steps per trial (default {DEFAULT_STEPS})')
    runner.add_backend_options(parser)
    parser.add_argument('--out', default=DEFAULT_OUT,
                        help=f'folder of trial results and figures (default {DEFAULT_OUT})')
    parser.add_argument('--report', default=DEFAULT_REPORT,
                        help=f'report file (default {DEFAULT_REPORT})')
    parser.add_argument('--runs-dir', default=None,
                        help=f"where the trials' full run folders go (large, not for "
                             f'committing; default {DEFAULT_RUNS} with the default --out, '
                             'else <out>/runs)')
    parser.add_argument('--analyze-only', action='store_true',
                        help='run no trials; redraw figures and rewrite the report')
    parser.add_argument('--refresh-records', action='store_true',
                        help='rebuild every result file (not retried/) from its run folder, '
                             'keeping its wall time, start and exit code, then analyse as '
                             '--analyze-only does (no trial runs). A run_dir stored as a '
                             'relative path is taken relative to the current directory: run '
                             'it from where the study ran (the repository root)')
    parser.add_argument('--retry-crashed', action='store_true',
                        help='re-run trials recorded as crashed or timed out (their old result '
                             'files move to trials/<condition>/retried/ and stay in the report)')
    parser.add_argument('--trainer', choices=TRAINERS, default='thesis',
                        help="the synthetic trainer of every trial (default 'thesis', the "
                             "study's; 'teacher' judges actions: docs/teaching.md)")
    parser.add_argument('--human-like', dest='human_like', action='store_true',
                        help='the human-like setting in every trial (attention_train '
                             '--human-like)')
    parser.add_argument('--trial-timeout', type=float, default=0.0, metavar='S',
                        help='wall seconds before a trial is stopped and recorded as timed out '
                             '(default 0: 1800 + 1 s per step)')
    return parser


def launcher_args(options: argparse.Namespace) -> List[str]:
    """Return the attention_train options every trial gets besides its condition and seed."""
    return ['--trainer', options.trainer] + (['--human-like'] if options.human_like else [])


def default_runs_dir(out: str) -> str:
    return DEFAULT_RUNS if out == DEFAULT_OUT else str(Path(out) / 'runs')


def regenerate_command(options: argparse.Namespace, parallel: int) -> str:
    words = ['.venv/bin/attention_study']
    if list(options.conditions) != list(CONDITIONS):
        words += ['--conditions', *options.conditions]
    words += ['--trials', str(options.trials), '--steps', str(options.steps),
              '--parallel', str(parallel), '--out', options.out, '--report', options.report]
    if options.runs_dir != default_runs_dir(options.out):
        words += ['--runs-dir', options.runs_dir]
    if options.trainer != 'thesis':
        words += ['--trainer', options.trainer]
    if options.human_like:
        words.append('--human-like')
    return ' '.join(shlex.quote(word) for word in words)


def read_log(out_dir: Path) -> List[dict]:
    try:
        return json.loads((out_dir / STUDY_LOG).read_text())
    except (OSError, ValueError):
        return []


def _say(text: str) -> None:
    sys.stderr.write(f'attention_study: {text}\n')
    sys.stderr.flush()


class _Progress:
    """Prints one line per finished trial, with an estimate of the time left."""

    def __init__(self, total: int, parallel: int):
        self.total, self.parallel = total, parallel
        self.started = time.monotonic()
        self.done = 0

    def __call__(self, job: runner.TrialJob, record: Optional[dict], finished: int) -> None:
        if record is None:
            _say(f'{job.condition} seed {job.seed}: interrupted (no result file; runs again '
                 'next time)')
            return
        self.done += 1
        elapsed = time.monotonic() - self.started
        left = (self.total - self.done) * elapsed / self.done
        _say(f'[{self.done}/{self.total}] {job.condition} seed {job.seed}: '
             f'{record["outcome"]}, {record["steps"]} steps in {record["wall_time_s"]:.0f} s, '
             f'furthest position {record["furthest_position"]}, key {record["key"]} '
             f'(about {left / 60:.0f} min left)')


def run_study(options: argparse.Namespace, out_dir: Path) -> Optional[dict]:
    """Run the pending trials; return the log entry (None if there was nothing to run)."""
    jobs, kept = runner.plan_trials(options.conditions, options.trials, options.steps, out_dir,
                                    Path(options.runs_dir).resolve(), options.retry_crashed,
                                    launcher_args(options))
    if kept:
        _say(f'{len(kept)} trial(s) already have results: skipped')
    if not jobs:
        return None
    timeout = options.trial_timeout or runner.auto_timeout_s(options.steps)
    _say(f'running {len(jobs)} trial(s) of {options.steps} steps, {options.parallel} at a '
         f'time; run folders in {options.runs_dir}')
    started_at = datetime.datetime.now().isoformat(timespec='seconds')
    started = time.monotonic()
    records, interrupted = runner.run_pending(
        jobs, runner.backend_of(options), timeout, _Progress(len(jobs), options.parallel), _say)
    entry = runner.log_entry(runner.backend_of(options), records, started_at,
                             time.monotonic() - started, interrupted, steps=options.steps,
                             trials_skipped=len(kept))
    log = read_log(out_dir) + [entry]
    write_json(out_dir / STUDY_LOG, log)
    return entry


def refresh(options: argparse.Namespace, out_dir: Path) -> None:
    """Rebuild the result files from their run folders (relative ones under the cwd)."""
    refreshed, skipped = refresh_records(out_dir, options.conditions, Path.cwd())
    for path, why in skipped.items():
        _say(f'{path}: not refreshed: {why}')
    _say(f'{len(refreshed)} result file(s) refreshed from their run folders, '
         f'{len(skipped)} skipped')


def analyse_and_report(options: argparse.Namespace, out_dir: Path) -> dict:
    """Load the result files, write analysis.json, the figures and the report."""
    found = load_records(out_dir, options.conditions)
    by_condition = {c: [r for r in found[c] if r['seed'] < options.trials]
                    for c in options.conditions}
    result = study_analysis.analyse(by_condition)
    if by_condition and any(by_condition.values()) and result['budget'] != options.steps:
        raise ValueError(f'the result files in {out_dir} are of {result["budget"]} steps; '
                         f'pass --steps {result["budget"]}')
    drawn = figures.draw_all(result, out_dir)
    compact = {key: value for key, value in result.items() if key != 'conditions'}
    compact['conditions'] = {
        c: {k: v for k, v in s.items() if k not in ('reach_curves', 'furthest_curve')}
        for c, s in result['conditions'].items()}
    write_json(out_dir / ANALYSIS_FILE, compact)
    log = [e for e in read_log(out_dir) if e.get('steps') == options.steps]
    ran = [e for e in log if e.get('trials_run')]
    parallel = ran[-1]['parallel'] if ran else options.parallel
    warmups = {r.get('parameters', {}).get('env_node.warmup_steps')
               for records in by_condition.values() for r in records}
    protocol = {'conditions': list(options.conditions), 'trials': options.trials,
                'steps': options.steps,
                'warmup_steps': sorted(w for w in warmups if w is not None)}
    report.write_report(Path(options.report), result, by_condition, protocol, drawn,
                        regenerate_command(options, parallel), log,
                        runner.load_retired(out_dir, options.conditions), os.cpu_count(),
                        f'{options.out.rstrip("/")}/trials')
    return result


def main(argv: Optional[Sequence[str]] = None) -> int:
    options = argument_parser().parse_args(argv)
    options.conditions = list(dict.fromkeys(options.conditions))
    if options.runs_dir is None:
        options.runs_dir = default_runs_dir(options.out)
    out_dir = Path(options.out).resolve()
    interrupted = False
    try:
        if options.refresh_records:
            refresh(options, out_dir)
        elif not options.analyze_only:
            entry = run_study(options, out_dir)
            interrupted = bool(entry and entry['interrupted'])
        result = analyse_and_report(options, out_dir)
    except (ValueError, FileNotFoundError) as error:
        _say(str(error))
        return 2
    usable = sum(s['usable'] for s in result['conditions'].values())
    problems = len(result['problems'])
    _say(f'report {options.report}: {usable} full trial(s), {problems} with problems; '
         f'figures in {options.out}')
    return EXIT_INTERRUPTED if interrupted else 0


if __name__ == '__main__':
    sys.exit(main())

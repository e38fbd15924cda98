"""
``attention_study_minigrid``: the six conditions on DoorKey, with the human-like teacher.

Every trial is one ``attention_train --task doorkey --trainer teacher --human-like`` run of the
real graph (seed = trial index, so the layouts of trial k are the same in every condition); for
the last ``--heldout-fraction`` of its budget every new episode has a held-out layout (seeds of
the level generator no trial trains on). One result file per trial under
``<out>/trials/<condition>/``: a trial whose file exists is skipped, so the same command resumes.
Then the analysis, the figures and the report (``report.py``). ``--analyze-only`` rewrites them
from the result files.
"""

import argparse
import datetime
import json
from pathlib import Path
import shlex
import sys
import time
from typing import List, Optional, Sequence

from attention_bringup.graph import CONDITIONS
from attention_bringup.minigrid_study import analysis, report
from attention_bringup.minigrid_study.measures import chance_levels, read_rows, trial_measures
from attention_bringup.plan import positive_int
from attention_bringup.study import runner
from attention_bringup.study.trials import load_records, read_json, trial_path, write_json
from attention_common.run_files import PROGRESS_FILE, STUDY_LOG

DEFAULT_TRIALS = 10
DEFAULT_STEPS = 4000
DEFAULT_HELDOUT_FRACTION = 0.25
DEFAULT_OUT = 'docs/study_minigrid'
DEFAULT_REPORT = 'docs/results_minigrid.md'
DEFAULT_RUNS = 'runs/study_minigrid'
PARAMS_FILE = 'doorkey_study.yaml'
"""Written into ``--out``: what every trial adds to the task's defaults (held-out layouts)."""


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='attention_study_minigrid',
        description='Run the six conditions on DoorKey (a new layout every episode) with the '
                    'human-like teacher, analyse them and write docs/results_minigrid.md. '
                    'Existing trial results are skipped: the same command resumes.')
    parser.add_argument('--conditions', nargs='+', choices=CONDITIONS, default=list(CONDITIONS),
                        metavar='NAME')
    parser.add_argument('--trials', type=positive_int, default=DEFAULT_TRIALS,
                        help=f'trials per condition, seeds 0..N-1 (default {DEFAULT_TRIALS})')
    parser.add_argument('--steps', type=positive_int, default=DEFAULT_STEPS,
                        help=f'agent steps per trial, fixed in advance (default {DEFAULT_STEPS})')
    parser.add_argument('--heldout-fraction', type=float, default=DEFAULT_HELDOUT_FRACTION,
                        help='last part of each trial on held-out layouts (default '
                             f'{DEFAULT_HELDOUT_FRACTION})')
    runner.add_backend_options(parser)
    parser.add_argument('--out', default=DEFAULT_OUT)
    parser.add_argument('--report', default=DEFAULT_REPORT)
    parser.add_argument('--runs-dir', default=None,
                        help=f'the run folders (large; default {DEFAULT_RUNS})')
    parser.add_argument('--analyze-only', action='store_true',
                        help='run no trials; rewrite the analysis, figures and report')
    parser.add_argument('--every-step-teacher', action='store_true',
                        help='the teacher judging every step, at once and always right, instead '
                             'of its human-like setting (a reference study: use another --out)')
    parser.add_argument('--reference', default=None, metavar='OUT',
                        help="another study's --out (e.g. the every-step teacher's) whose "
                             'analysis the report shows beside this one')
    return parser


def heldout_after(steps: int, fraction: float) -> int:
    """Agent steps after which new episodes have held-out layouts."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f'--heldout-fraction must be in (0, 1), got {fraction}')
    return int(round(steps * (1.0 - fraction)))


def write_params(out_dir: Path, steps: int, fraction: float) -> Path:
    path = out_dir / PARAMS_FILE
    path.write_text('# Written by attention_study_minigrid: every trial of the study.\n'
                    'env_node:\n  ros__parameters:\n'
                    f'    heldout_after: {heldout_after(steps, fraction)}\n')
    return path


def launcher_args(params: Path, human_like: bool = True) -> List[str]:
    human = ['--human-like'] if human_like else []
    return ['--task', 'doorkey', '--trainer', 'teacher', *human, '--params-file', str(params)]


def regenerate_command(options: argparse.Namespace) -> str:
    words = ['.venv/bin/attention_study_minigrid']
    if list(options.conditions) != list(CONDITIONS):
        words += ['--conditions', *options.conditions]
    words += ['--trials', str(options.trials), '--steps', str(options.steps),
              '--heldout-fraction', f'{options.heldout_fraction:g}', '--parallel',
              str(options.parallel), '--out', options.out, '--report', options.report]
    if options.every_step_teacher:
        words.append('--every-step-teacher')
    if options.reference:
        words += ['--reference', options.reference]
    return ' '.join(shlex.quote(word) for word in words)


def _say(text: str) -> None:
    sys.stderr.write(f'attention_study_minigrid: {text}\n')
    sys.stderr.flush()


def add_measures(record: dict, run_dir: Path) -> dict:
    """Add the DoorKey measures of the trial, from its run folder's progress.csv."""
    record['doorkey'] = trial_measures(read_rows(run_dir / PROGRESS_FILE), record['budget'])
    return record


def run_study(options: argparse.Namespace, out_dir: Path) -> bool:
    """Run the pending trials; return whether the study was interrupted."""
    params = write_params(out_dir, options.steps, options.heldout_fraction)
    jobs, kept = runner.plan_trials(options.conditions, options.trials, options.steps, out_dir,
                                    Path(options.runs_dir).resolve(),
                                    launcher_args=launcher_args(params.resolve(),
                                                                not options.every_step_teacher),
                                    measure=add_measures)
    if kept:
        _say(f'{len(kept)} trial(s) already have results: skipped')
    if not jobs:
        return False
    started, done = time.monotonic(), [0]

    def on_trial(job, record, finished) -> None:
        if record is None:
            _say(f'{job.condition} seed {job.seed}: interrupted (runs again next time)')
            return
        done[0] += 1
        measures = record['doorkey']
        left = (len(jobs) - done[0]) * (time.monotonic() - started) / done[0]
        _say(f'[{done[0]}/{len(jobs)}] {job.condition} seed {job.seed}: {record["outcome"]}, '
             f'{measures["solved"]}/{measures["episodes"]} episodes solved, held-out '
             f'{measures["heldout_solved"]}/{measures["heldout_episodes"]} '
             f'({record["wall_time_s"]:.0f} s; about {left / 60:.0f} min left)')

    _say(f'running {len(jobs)} trial(s) of {options.steps} steps, {options.parallel} at a time')
    started_at = datetime.datetime.now().isoformat(timespec='seconds')
    records, interrupted = runner.run_pending(jobs, runner.backend_of(options),
                                              runner.auto_timeout_s(options.steps), on_trial,
                                              _say)
    log_path = out_dir / STUDY_LOG
    log = read_json(log_path) or []
    log.append(runner.log_entry(runner.backend_of(options), records, started_at,
                                time.monotonic() - started, interrupted, steps=options.steps,
                                trials_skipped=len(kept)))
    write_json(log_path, log)
    return interrupted


def main(argv: Optional[Sequence[str]] = None) -> int:
    options = argument_parser().parse_args(argv)
    options.conditions = list(dict.fromkeys(options.conditions))
    options.runs_dir = options.runs_dir or (DEFAULT_RUNS if options.out == DEFAULT_OUT
                                            else str(Path(options.out) / 'runs'))
    out_dir = Path(options.out).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    try:
        heldout_after(options.steps, options.heldout_fraction)
        interrupted = False if options.analyze_only else run_study(options, out_dir)
        found = load_records(out_dir, options.conditions)
        for condition, condition_records in found.items():
            for record in condition_records:  # measured again while the run folder is here
                run_dir = Path(record.get('run_dir', ''))
                if (run_dir / PROGRESS_FILE).exists():
                    add_measures(record, run_dir)
                    write_json(trial_path(out_dir, condition, record['seed']), record)
        records = {c: [r for r in found[c] if r['seed'] < options.trials and 'doorkey' in r]
                   for c in options.conditions}  # (a trial without measures: interrupted)
        result = analysis.analyse(records, options.steps)
        result['chance'] = chance_levels()
        result['human_like'] = not options.every_step_teacher
        result['command'] = regenerate_command(options)
        result['wall_time_s'] = sum(e.get('wall_time_s', 0.0)
                                    for e in read_json(out_dir / STUDY_LOG) or [])
        write_json(out_dir / 'analysis.json', result)
        if options.reference:
            result['reference'] = read_json(Path(options.reference) / 'analysis.json')
        figures = report.draw_figures(result, out_dir)
        log = read_json(out_dir / STUDY_LOG) or []
        report.write_report(Path(options.report), result, options, figures,
                            regenerate_command(options), log)
    except (ValueError, FileNotFoundError) as error:
        _say(str(error))
        return 2
    _say(f'report {options.report}: '
         f'{sum(len(r) for r in records.values())} trial(s); figures in {options.out}')
    print(json.dumps({c: s['heldout_success_pooled'] for c, s in result['conditions'].items()}))
    return runner.EXIT_INTERRUPTED if interrupted else 0


if __name__ == '__main__':
    sys.exit(main())

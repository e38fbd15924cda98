"""
``attention_study``: run the thesis's chapter 5 study and write its report.

The ``thesis`` experiment (``config/experiments/thesis.yaml``) on the one engine: runs every
condition's trials through ``attention_train`` (seed = trial index), keeps one small result file
per trial under ``<out>/trials/``, then draws the figures into ``<out>/`` and writes
the report. Trials whose result file exists are skipped, so the same command resumes. With
``--analyze-only`` it only redraws the figures and rewrites the report from the result files;
``--refresh-records`` first rebuilds the result files from the trials' run folders (for fields
added since they were written), then does the same.

Exit code: 0 when the report was written (crashed trials are in it); 2 for bad options or
result files; 130 when interrupted (finished trials are kept).
"""

import argparse
from dataclasses import replace
from pathlib import Path
import shlex
import sys
from typing import List, Optional, Sequence

from attention_bringup.experiment import engine, runner, spec as specs
from attention_bringup.graph import CONDITIONS, THESIS_CONDITIONS
from attention_bringup.plan import positive_int
from feedback_node.judging import TRAINERS

SPEC = specs.load('thesis')


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='attention_study',
        description='Run the study of thesis chapter 5 (every condition, N seeded trials of the '
                    'real node graph), analyse it and write the report. Existing trial results '
                    'are skipped, so an interrupted study resumes with the same command.')
    parser.add_argument('--conditions', nargs='+', choices=CONDITIONS,
                        default=list(THESIS_CONDITIONS), metavar='NAME',
                        help=f"conditions (default the thesis's six: "
                             f'{" ".join(THESIS_CONDITIONS)})')
    parser.add_argument('--trials', type=positive_int, default=len(SPEC.seeds),
                        help=f'trials per condition, seeds 0..N-1 (default {len(SPEC.seeds)})')
    parser.add_argument('--steps', type=positive_int, default=SPEC.budget,
                        help=f'agent steps per trial (default {SPEC.budget})')
    runner.add_backend_options(parser)
    parser.add_argument('--out', default=SPEC.out,
                        help=f'folder of trial results and figures (default {SPEC.out})')
    parser.add_argument('--report', default=SPEC.report,
                        help=f'report file (default {SPEC.report})')
    parser.add_argument('--runs-dir', default=None,
                        help=f"where the trials' full run folders go (large, not for "
                             f'committing; default {SPEC.runs_dir} with the default --out, '
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
    return SPEC.runs_dir if out == SPEC.out else str(Path(out) / 'runs')


def regenerate_command(options: argparse.Namespace, parallel: int) -> str:
    words = ['.venv/bin/attention_study']
    if list(options.conditions) != list(THESIS_CONDITIONS):
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


def spec_of(options: argparse.Namespace) -> specs.Spec:
    """Return the experiment these options ask for (the ``thesis`` spec, narrowed or changed)."""
    arms = tuple(specs.Arm(condition, condition) for condition in options.conditions)
    return replace(SPEC, arms=arms, seeds=tuple(range(options.trials)), budget=options.steps,
                   out=options.out, report=options.report, runs_dir=options.runs_dir,
                   launcher_args=tuple(launcher_args(options)))


def main(argv: Optional[Sequence[str]] = None) -> int:
    options = argument_parser().parse_args(argv)
    options.conditions = list(dict.fromkeys(options.conditions))
    if options.runs_dir is None:
        options.runs_dir = default_runs_dir(options.out)
    say = engine.sayer('attention_study')
    code, result = engine.main_flow(
        spec_of(options), runner.backend_of(options), say,
        run_trials=not options.analyze_only, refresh_first=options.refresh_records,
        retry_crashed=options.retry_crashed, timeout_s=options.trial_timeout,
        context={'command': lambda parallel: regenerate_command(options, parallel)})
    if code == 2:
        return code
    usable = sum(s['usable'] for s in result['conditions'].values())
    problems = len(result['problems'])
    say(f'report {options.report}: {usable} full trial(s), {problems} with problems; '
        f'figures in {options.out}')
    return code


if __name__ == '__main__':
    sys.exit(main())

"""
``attention_study_minigrid``: the six conditions on DoorKey, with the human-like teacher.

The ``doorkey`` experiment (``config/experiments/doorkey.yaml``; with ``--every-step-teacher``
the ``doorkey_every_step`` reference) on the one engine: every trial is one ``attention_train
--task doorkey --trainer teacher --human-like`` run of the real graph (seed = trial index, so the
layouts of trial k are the same in every condition); for the last ``--heldout-fraction`` of its
budget every new episode has a held-out layout. A trial whose result file exists is skipped, so
the same command resumes; ``--analyze-only`` rewrites the analysis, figures and report.
"""

import argparse
from dataclasses import replace
import json
import shlex
import sys
from typing import Optional, Sequence

from attention_bringup.experiment import engine, runner, spec as specs
from attention_bringup.graph import CONDITIONS, THESIS_CONDITIONS
from attention_bringup.plan import positive_int

SPEC = specs.load('doorkey')
EVERY_STEP = specs.load('doorkey_every_step')


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='attention_study_minigrid',
        description='Run the six conditions on DoorKey (a new layout every episode) with the '
                    'human-like teacher, analyse them and write docs/results_minigrid.md. '
                    'Existing trial results are skipped: the same command resumes.')
    parser.add_argument('--conditions', nargs='+', choices=CONDITIONS,
                        default=list(THESIS_CONDITIONS), metavar='NAME')
    parser.add_argument('--trials', type=positive_int, default=len(SPEC.seeds),
                        help=f'trials per condition, seeds 0..N-1 (default {len(SPEC.seeds)})')
    parser.add_argument('--steps', type=positive_int, default=SPEC.budget,
                        help=f'agent steps per trial, fixed in advance (default {SPEC.budget})')
    fraction = SPEC.settings['heldout_fraction']
    parser.add_argument('--heldout-fraction', type=float, default=fraction,
                        help=f'last part of each trial on held-out layouts (default {fraction})')
    runner.add_backend_options(parser)
    parser.add_argument('--out', default=SPEC.out)
    parser.add_argument('--report', default=SPEC.report)
    parser.add_argument('--runs-dir', default=None,
                        help=f'the run folders (large; default {SPEC.runs_dir})')
    parser.add_argument('--analyze-only', action='store_true',
                        help='run no trials; rewrite the analysis, figures and report')
    parser.add_argument('--every-step-teacher', action='store_true',
                        help='the teacher judging every step, at once and always right, instead '
                             'of its human-like setting (a reference study: use another --out)')
    parser.add_argument('--reference', default=None, metavar='OUT',
                        help="another study's --out (e.g. the every-step teacher's) whose "
                             'analysis the report shows beside this one')
    return parser


def regenerate_command(options: argparse.Namespace) -> str:
    words = ['.venv/bin/attention_study_minigrid']
    if list(options.conditions) != list(THESIS_CONDITIONS):
        words += ['--conditions', *options.conditions]
    words += ['--trials', str(options.trials), '--steps', str(options.steps),
              '--heldout-fraction', f'{options.heldout_fraction:g}', '--parallel',
              str(options.parallel), '--out', options.out, '--report', options.report]
    if options.every_step_teacher:
        words.append('--every-step-teacher')
    if options.reference:
        words += ['--reference', options.reference]
    return ' '.join(shlex.quote(word) for word in words)


def spec_of(options: argparse.Namespace) -> specs.Spec:
    """Return the experiment these options ask for."""
    base = EVERY_STEP if options.every_step_teacher else SPEC
    runs_dir = options.runs_dir or (base.runs_dir if options.out == SPEC.out
                                    else f'{options.out}/runs')
    arms = [specs.Arm(condition, condition) for condition in dict.fromkeys(options.conditions)]
    return replace(base, arms=tuple(arms), seeds=tuple(range(options.trials)),
                   budget=options.steps, out=options.out, report=options.report,
                   runs_dir=runs_dir,
                   settings={**base.settings, 'heldout_fraction': options.heldout_fraction})


def main(argv: Optional[Sequence[str]] = None) -> int:
    options = argument_parser().parse_args(argv)
    options.conditions = list(dict.fromkeys(options.conditions))
    say = engine.sayer('attention_study_minigrid')
    spec = spec_of(options)
    code, result = engine.main_flow(
        spec, runner.backend_of(options), say, run_trials=not options.analyze_only,
        context={'command': regenerate_command(options), 'reference': options.reference})
    if code == 2:
        return code
    say(f'report {options.report}: {sum(s["trials"] for s in result["conditions"].values())} '
        f'trial(s); figures in {options.out}')
    print(json.dumps({c: s['heldout_success_pooled'] for c, s in result['conditions'].items()}))
    return code


if __name__ == '__main__':
    sys.exit(main())

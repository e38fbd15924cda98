"""
``attention_teaching``: does Deep TAMER learn Room 1 from the teacher? Run and report.

The ``teaching`` experiment (``config/experiments/teaching.yaml``: one arm per setting, seeds
1000-1009, none used for tuning) on the one engine (``attention_experiment teaching`` does the
same). Result files go to ``docs/teaching/<setting>/trials/<condition>/seed<k>.json`` as they
finish, so an interrupted evaluation resumes with the same command; then ``docs/teaching.md`` is
written from them (``--report-only`` skips running).
"""

import argparse
import sys
from typing import Optional, Sequence

from attention_bringup.experiment import engine, runner, spec as specs
from attention_bringup.plan import positive_int

SPEC = specs.load('teaching')


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='attention_teaching', description=__doc__.split('\n')[1])
    parser.add_argument('--settings', nargs='+', choices=SPEC.arm_names, default=SPEC.arm_names,
                        metavar='NAME', help=f'settings (default all: {" ".join(SPEC.arm_names)})')
    parser.add_argument('--seeds', type=int, nargs='+', default=list(SPEC.seeds),
                        help='trial seeds (default 1000..1009, never tuned on)')
    parser.add_argument('--steps', type=positive_int, default=SPEC.budget)
    runner.add_backend_options(parser, parallel=SPEC.parallel)
    parser.add_argument('--out', default=SPEC.out)
    parser.add_argument('--report', default=SPEC.report)
    parser.add_argument('--runs-dir', default=SPEC.runs_dir,
                        help='full run folders (large; not for committing)')
    parser.add_argument('--report-only', action='store_true', help='run no trials')
    parser.add_argument('--refresh-records', action='store_true',
                        help='rebuild the result files from their run folders (fields added '
                             'later), then report; run it from the repository root')
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    options = argument_parser().parse_args(argv)
    spec = SPEC.select(options.settings, options.seeds, options.steps, out=options.out,
                       report=options.report, runs_dir=options.runs_dir)
    command = ('.venv/bin/attention_teaching --parallel 2' if spec.arm_names == SPEC.arm_names
               else '.venv/bin/attention_teaching --settings ' + ' '.join(spec.arm_names))
    say = engine.sayer('attention_teaching')
    code, _ = engine.main_flow(spec, runner.backend_of(options), say,
                               run_trials=not options.report_only,
                               refresh_first=options.refresh_records,
                               context={'command': command})
    if code != 2:
        say(f'wrote {spec.report}')
    return code


if __name__ == '__main__':
    sys.exit(main())

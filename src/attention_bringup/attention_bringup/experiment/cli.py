"""
``attention_experiment SPEC``: run an experiment from its spec, resumably, and write its report.

SPEC is a YAML file or the name of a shipped one (``config/experiments/``: ``teaching``,
``doorkey``, ``doorkey_every_step``, ``thesis``). Every trial is one ``attention_train`` run of
the real graph; a trial whose result file exists is skipped, so the same command resumes;
Ctrl-C stops every launcher it started (exit code 130). ``--report-only`` rewrites the analysis
and the report from the result files.

    attention_experiment teaching --report-only
    attention_experiment doorkey --seeds 0 1 --steps 300 --out /tmp/doorkey --parallel 2
    attention_experiment my_study.yaml --backend ray --address auto
"""

import argparse
import sys
from typing import Optional, Sequence

from attention_bringup.experiment import engine, runner, spec as specs
from attention_bringup.plan import positive_int


def add_run_options(parser: argparse.ArgumentParser, parallel: Optional[int]) -> None:
    """Add the options every study command shares (``--backend``, ``--retry-crashed``, ...)."""
    runner.add_backend_options(parser, parallel)
    parser.add_argument('--retry-crashed', action='store_true',
                        help='re-run trials recorded as crashed or timed out (their old result '
                             'files move to trials/<condition>/retried/)')
    parser.add_argument('--trial-timeout', type=float, default=0.0, metavar='S',
                        help='wall seconds before a trial is stopped and recorded as timed out '
                             '(default 0: 1800 + 1 s per step)')
    parser.add_argument('--refresh-records', action='store_true',
                        help='rebuild every result file from its run folder (fields added '
                             'later), then report; run it from where the trials ran')


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='attention_experiment', formatter_class=argparse.RawDescriptionHelpFormatter,
        description='Run an experiment from its spec, resumably, and write its report.',
        epilog='\n'.join(__doc__.strip().split('\n')[2:]).replace('``', ''))
    parser.add_argument('spec', help='a spec file (YAML) or a shipped spec by name')
    parser.add_argument('--arms', nargs='+', metavar='NAME', help='only these arms')
    parser.add_argument('--seeds', type=int, nargs='+', help="only these seeds (the spec's)")
    parser.add_argument('--steps', type=positive_int, help="the budget (the spec's)")
    parser.add_argument('--out', help="result files, log and analysis (the spec's)")
    parser.add_argument('--report', help="the report file (the spec's)")
    parser.add_argument('--runs-dir', help="the trials' run folders (the spec's)")
    parser.add_argument('--report-only', action='store_true', help='run no trials')
    add_run_options(parser, parallel=None)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    options = argument_parser().parse_args(argv)
    say = engine.sayer('attention_experiment')
    try:
        spec = specs.load(options.spec)
        more = {name: getattr(options, name) for name in ('out', 'report', 'runs_dir')
                if getattr(options, name)}
        spec = spec.select(options.arms, options.seeds, options.steps, **more)
    except specs.SpecError as error:
        say(str(error))
        return 2
    options.parallel = options.parallel or spec.parallel
    code, _ = engine.main_flow(
        spec, runner.backend_of(options), say, run_trials=not options.report_only,
        refresh_first=options.refresh_records, retry_crashed=options.retry_crashed,
        timeout_s=options.trial_timeout)
    if code != 2:
        say(f'wrote {spec.report}')
    return code


if __name__ == '__main__':
    sys.exit(main())

"""
``attention_teaching``: does Deep TAMER learn Room 1 from the teacher? Run and report.

Every trial is the real four-process graph through ``attention_train`` (the study's runner),
one per setting (``settings.SETTINGS``) and seed (``settings.SEEDS``, none used for tuning).
Result files go to ``docs/teaching/<setting>/trials/<condition>/seed<k>.json`` as they finish,
so an interrupted evaluation resumes with the same command; then ``docs/teaching.md`` is
written from them (``--report-only`` skips running).
"""

import argparse
import datetime
import json
from pathlib import Path
import sys
import time
from typing import List, Optional, Sequence

from attention_bringup.plan import positive_int
from attention_bringup.study import runner
from attention_bringup.study.trials import load_records, refresh_records, write_json
from attention_bringup.teaching import analysis, report
from attention_bringup.teaching.settings import SEEDS, SETTINGS
from attention_common.run_files import ANALYSIS_FILE, TEACHING_LOG

DEFAULT_OUT = 'docs/teaching'
DEFAULT_REPORT = 'docs/teaching.md'
DEFAULT_RUNS = 'runs/teaching'
DEFAULT_STEPS = 10000


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='attention_teaching', description=__doc__.split('\n')[1])
    parser.add_argument('--settings', nargs='+', choices=list(SETTINGS), default=list(SETTINGS),
                        metavar='NAME', help=f'settings (default all: {" ".join(SETTINGS)})')
    parser.add_argument('--seeds', type=int, nargs='+', default=list(SEEDS),
                        help='trial seeds (default 1000..1009, never tuned on)')
    parser.add_argument('--steps', type=positive_int, default=DEFAULT_STEPS)
    runner.add_backend_options(parser, parallel=2)
    parser.add_argument('--out', default=DEFAULT_OUT)
    parser.add_argument('--report', default=DEFAULT_REPORT)
    parser.add_argument('--runs-dir', default=DEFAULT_RUNS,
                        help='full run folders (large; not for committing)')
    parser.add_argument('--report-only', action='store_true', help='run no trials')
    parser.add_argument('--refresh-records', action='store_true',
                        help='rebuild the result files from their run folders (fields added '
                             'later), then report; run it from the repository root')
    return parser


def _say(text: str) -> None:
    sys.stderr.write(f'attention_teaching: {text}\n')
    sys.stderr.flush()


def plan(options) -> List[runner.TrialJob]:
    jobs = []
    for seed in options.seeds:  # seed-major: an interrupted run has every setting so far
        for name in options.settings:
            setting = SETTINGS[name]
            pending, _ = runner.plan_trials(
                [setting.condition], 0, options.steps, Path(options.out) / name,
                Path(options.runs_dir) / name, launcher_args=setting.launcher_args,
                seeds=[seed])
            jobs += pending
    return jobs


def run(options) -> bool:
    """Run the pending trials; return whether the evaluation was interrupted."""
    jobs = plan(options)
    if not jobs:
        return False
    started = time.monotonic()

    def progress(job, record, finished) -> None:
        if record is None:
            _say(f'{job.run_dir.parent.parent.name} seed {job.seed}: interrupted (runs again '
                 'next time)')
            return
        elapsed = time.monotonic() - started
        _say(f'[{finished}/{len(jobs)}] {job.run_dir.parent.parent.name} seed {job.seed}: '
             f'{record["outcome"]}, key at {record.get("first_key_step")}, furthest stood '
             f'{record.get("furthest_position_stood")} '
             f'(about {(len(jobs) - finished) * elapsed / finished / 60:.0f} min left)')

    _say(f'running {len(jobs)} trial(s), {options.parallel} at a time')
    started_at = datetime.datetime.now().isoformat(timespec='seconds')
    backend = runner.backend_of(options)
    records, interrupted = runner.run_pending(jobs, backend,
                                              runner.auto_timeout_s(options.steps), progress,
                                              _say)
    log_path = Path(options.out) / TEACHING_LOG
    log = json.loads(log_path.read_text()) if log_path.exists() else []
    log.append(runner.log_entry(backend, records, started_at, time.monotonic() - started,
                                interrupted, steps=options.steps))
    write_json(log_path, log)
    return interrupted


def load(options) -> dict:
    by_setting = {}
    for name in options.settings:
        condition = SETTINGS[name].condition
        records = load_records(Path(options.out) / name, [condition])[condition]
        by_setting[name] = [r for r in records if r['seed'] in options.seeds
                            and r['outcome'] in ('completed', 'completed_unclean')]
    return by_setting


def main(argv: Optional[Sequence[str]] = None) -> int:
    options = argument_parser().parse_args(argv)
    if options.refresh_records:
        for name in options.settings:
            done, skipped = refresh_records(Path(options.out) / name,
                                            [SETTINGS[name].condition], Path.cwd())
            _say(f'{name}: {len(done)} result file(s) refreshed, {len(skipped)} skipped')
    interrupted = False
    if not (options.refresh_records or options.report_only):
        try:
            interrupted = run(options)
        except (ValueError, FileNotFoundError) as error:
            _say(str(error))
            return 2
    by_setting = load(options)
    result = analysis.analyse(by_setting, options.steps)
    write_json(Path(options.out) / ANALYSIS_FILE, result)
    report.write(Path(options.report), Path(options.out), result, by_setting, options)
    _say(f'wrote {options.report}')
    return runner.EXIT_INTERRUPTED if interrupted else 0


if __name__ == '__main__':
    sys.exit(main())

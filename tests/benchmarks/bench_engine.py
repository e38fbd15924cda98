"""
What the experiment engine costs per trial, beside the trial itself.

Runs a spec of ``--trials`` trials (2 arms, the teaching plug-in) whose launcher is a stand-in
that writes a run folder and sleeps ``--trial-s`` seconds, one at a time, through
``attention_experiment``'s own code (plan, run, record, log, analysis, report). The engine's
share is the wall time beyond the trials' own and the driver's CPU time; both are printed per
trial and as a share of a 10,000-step trial of the graph (about 220 s on 2 cores, two at a time:
the Room 1 study's 60 trials in 1 h 49 min).

    .venv/bin/python tests/benchmarks/bench_engine.py [--trials 20] [--trial-s 0.5]
"""

import argparse
from pathlib import Path
import resource
import sys
import tempfile
import textwrap
import time

from attention_bringup.experiment import cli, runner
import yaml

TRIAL_OF_THE_GRAPH_S = 220.0
STAND_IN = textwrap.dedent('''\
    #!{python}
    """Stand-in for attention_train: a run folder of a finished trial, after a wait."""
    import json, pathlib, sys, time
    args = dict(zip(sys.argv[1::2], sys.argv[2::2]))
    run = pathlib.Path(args['--run-dir'])
    steps = int(args['--steps'])
    time.sleep({trial_s})
    with open(run / 'progress.csv', 'w') as f:
        f.write('agent_step,position,furthest_position,episode,lives,has_key\\n')
        f.writelines(f'{{s}},-1,-1,0,5,0\\n' for s in range(steps + 1))
    (run / 'summary.json').write_text(json.dumps({{'status': 'completed'}}))
    ''')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--trials', type=int, default=20)
    parser.add_argument('--trial-s', type=float, default=0.5)
    parser.add_argument('--steps', type=int, default=10000, help='rows of each progress.csv')
    args = parser.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix='bench-engine-'))
    launcher = folder / 'attention_train'
    launcher.write_text(STAND_IN.format(python=sys.executable, trial_s=args.trial_s))
    launcher.chmod(0o755)
    runner.launcher_path = lambda: launcher
    spec = folder / 'spec.yaml'
    spec.write_text(yaml.safe_dump({
        'name': 'bench', 'plugin': 'teaching', 'budget': args.steps, 'layout': 'by_arm',
        'seeds': {'start': 0, 'count': args.trials // 2}, 'out': str(folder / 'out'),
        'report': str(folder / 'report.md'), 'runs_dir': str(folder / 'runs'),
        'arms': [{'name': 'a', 'condition': 'vanilla'}, {'name': 'b', 'condition': 'vanilla'}]}))
    cpu = resource.getrusage(resource.RUSAGE_SELF)
    started = time.monotonic()
    code = cli.main([str(spec), '--parallel', '1'])
    wall = time.monotonic() - started
    used = resource.getrusage(resource.RUSAGE_SELF)
    driver_cpu = used.ru_utime + used.ru_stime - cpu.ru_utime - cpu.ru_stime
    trials = 2 * (args.trials // 2)
    beyond = (wall - trials * args.trial_s) / trials
    print(f'exit code {code}; {trials} trials of {args.steps} steps, {args.trial_s:g} s each, '
          f'one at a time, in {wall:.1f} s')
    print(f'engine per trial: {1e3 * beyond:.0f} ms of wall time beyond the trial '
          f'({100 * beyond / TRIAL_OF_THE_GRAPH_S:.2f} % of a 10,000-step trial of the graph), '
          f"{1e3 * driver_cpu / trials:.0f} ms of the driver's CPU "
          f'({100 * driver_cpu / trials / TRIAL_OF_THE_GRAPH_S:.2f} %)')
    return code


if __name__ == '__main__':
    sys.exit(main())

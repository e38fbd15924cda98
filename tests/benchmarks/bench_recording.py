"""
Benchmark: what recording a session bag costs the graph, and how big the bag is.

For each task, ``attention_train --steps N`` runs ``--repeats`` times without a bag and as
many times with one (``--record``), interleaved (A B A B ...) so that a drift of the machine
hits both alike. Numbers come from each run's ``summary.json``: steps/s while training, the
recorder's CPU time, the bag's size. Prints a markdown table: steps/s with and without (median
and each run), the ratio of the medians (target >= 0.9), MB per 10,000 steps, and, from one bag,
each topic's share of the bytes before compression.
"""

import argparse
import json
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile

from machine_info import machine
from session_bag.reader import BagReader

BIN = Path(sys.executable).parent
RATIO_TARGET = 0.9


def run(task: str, steps: int, record: bool, run_dir: Path) -> dict:
    result = subprocess.run(
        [str(BIN / 'attention_train'), '--task', task, '--steps', str(steps), '--quiet',
         '--seed', '11', '--run-dir', str(run_dir), '--record' if record else '--no-record'],
        capture_output=True, text=True, timeout=3600)
    if result.returncode != 0:
        raise SystemExit(f'attention_train failed ({result.returncode}):\n{result.stderr}')
    return json.loads((run_dir / 'summary.json').read_text())


def topic_bytes(bag_dir: Path) -> dict:
    sizes = {}
    for message in BagReader(bag_dir).messages():
        sizes[message.topic] = sizes.get(message.topic, 0) + len(message.data)
    return sizes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--tasks', nargs='+', default=['montezuma', 'doorkey'])
    parser.add_argument('--steps', type=int, default=3000)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()
    print(f'# Recording a session bag ({machine()}); {args.steps} steps per run, '
          f'{args.repeats} runs each way, interleaved\n')
    print('| task | steps/s without (median; runs) | steps/s with | ratio of medians | '
          'recorder CPU s / 1k steps | MB / 10k steps | messages / step | frames in bag / '
          'steps (fewest) |')
    print('|---|---|---|---|---|---|---|---|')
    shares = {}
    worst = None
    with tempfile.TemporaryDirectory() as workdir:
        for task in args.tasks:
            speeds = {False: [], True: []}
            bags = []
            for repeat in range(args.repeats):
                for record in (False, True):
                    run_dir = Path(workdir) / f'{task}-{repeat}-{int(record)}'
                    summary = run(task, args.steps, record, run_dir)
                    speeds[record].append(summary['steps_per_s'])
                    if record:
                        bags.append((summary, run_dir))
            # Medians: one run of the graph can be 15 % off the others on 2 shared cores.
            without, with_ = (statistics.median(speeds[False]), statistics.median(speeds[True]))
            ratio = with_ / without
            worst = ratio if worst is None else min(worst, ratio)
            steps = [s['steps'] for s, _ in bags]
            megabytes = statistics.mean(s['bag']['bytes'] / 1e6 * 10000 / n
                                        for (s, _), n in zip(bags, steps))
            cpu = statistics.mean(s['cpu_s']['session_recorder'] / n * 1000
                                  for (s, _), n in zip(bags, steps))
            messages = statistics.mean(s['bag']['messages'] / n for (s, _), n in zip(bags, steps))
            frames = min(s['bag']['topics'].get('/observation', 0) / n
                         for (s, _), n in zip(bags, steps))
            runs = ', '.join(f'{v:.0f}' for v in speeds[False])
            runs_with = ', '.join(f'{v:.0f}' for v in speeds[True])
            print(f'| {task} | {without:.1f} ({runs}) | {with_:.1f} ({runs_with}) | '
                  f'{ratio:.3f} | {cpu:.2f} | {megabytes:.1f} | {messages:.1f} | {frames:.3f} |',
                  flush=True)
            shares[task] = topic_bytes(bags[0][1] / 'bag')
    print(f'\nTarget: ratio >= {RATIO_TARGET} (worst here {worst:.3f}: '
          f'{"met" if worst >= RATIO_TARGET else "NOT met"}).\n')
    for task, sizes in shares.items():
        total = sum(sizes.values())
        parts = ', '.join(f'{topic} {size / total:.1%}' for topic, size in
                          sorted(sizes.items(), key=lambda kv: -kv[1])[:5])
        print(f'{task}: {total / 1e6:.1f} MB of messages before compression; {parts}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

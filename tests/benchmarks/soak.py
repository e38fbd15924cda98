"""
Soak: a long run of the whole graph, printing each process's memory every 10,000 steps.

A benchmark, not a test (about 10 minutes for 100,000 steps on 2 cores). It starts
``attention_train`` (the teacher, ``language``) in a run folder of its own, reads the
resident memory (VmRSS) of the launcher and of each node from ``/proc`` whenever another
``--every`` agent steps are in ``progress.csv``, and prints one row per reading and, at the
end, the growth per 10,000 steps fitted over the second half of the run (after warm-up: the
learner's buffer fills for its first 10,000 samples).

    .venv/bin/python tests/benchmarks/soak.py [--steps 100000] [--every 10000]
"""

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from attention_bringup.processes import resident_memory_kb
import numpy as np

PROCESSES = ('attention_train', 'env_node', 'feedback_node', 'saliency_node', 'tamer_node')


def resident_mb(pid: int):
    kb = resident_memory_kb(pid).get('VmRSS')
    return None if kb is None else kb / 1024


def last_step(progress: Path) -> int:
    """Return the agent step of the last full row of progress.csv (read from its end)."""
    try:
        with open(progress, 'rb') as file:
            file.seek(0, os.SEEK_END)
            file.seek(max(0, file.tell() - 4096))
            lines = file.read().decode(errors='replace').splitlines()
    except OSError:
        return 0
    for line in reversed(lines[:-1] or lines):
        head = line.split(',', 1)[0]
        if head.isdigit():
            return int(head)
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--steps', type=int, default=100_000)
    parser.add_argument('--every', type=int, default=10_000)
    parser.add_argument('--run-dir', default=None, help='default: a new temporary folder')
    args = parser.parse_args()
    run_dir = Path(args.run_dir or tempfile.mkdtemp(prefix='soak-')) / 'run'
    launcher = subprocess.Popen(
        [str(Path(sys.executable).parent / 'attention_train'), '--steps', str(args.steps),
         '--run-dir', str(run_dir), '--quiet', '--seed', '11'],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    print(f'run folder {run_dir}')
    print('steps    wall_s  ' + '  '.join(f'{name:>15}' for name in PROCESSES) + '   (MB)')
    readings, started, next_at = [], time.monotonic(), 0
    while launcher.poll() is None:
        time.sleep(1.0)
        steps = last_step(run_dir / 'progress.csv')
        if steps < next_at or not (run_dir / 'pids.json').exists():
            continue
        try:
            pids = json.loads((run_dir / 'pids.json').read_text())
        except ValueError:  # being rewritten
            continue
        memory = [resident_mb(pids.get(name, -1)) for name in PROCESSES]
        readings.append((steps, memory))
        print(f'{steps:>7} {time.monotonic() - started:>7.0f}  '
              + '  '.join(f'{m:>15.1f}' if m is not None else f'{"-":>15}' for m in memory),
              flush=True)
        next_at = (steps // args.every + 1) * args.every
    stderr = launcher.stderr.read()
    summary = json.loads((run_dir / 'summary.json').read_text())
    print(f'exit code {launcher.returncode}, status {summary["status"]}, '
          f'{summary["steps"]} steps at {summary["steps_per_s"]} steps/s, feedback received by '
          f'the learner {summary["metrics"].get("feedback/received")}')
    half = [r for r in readings if r[0] >= args.steps / 2]
    if len(half) >= 2:
        steps = np.array([r[0] for r in half], float)
        for index, name in enumerate(PROCESSES):
            values = [r[1][index] for r in half]
            if all(v is not None for v in values):
                slope = np.polyfit(steps, np.array(values), 1)[0] * 10_000
                print(f'{name:>15}: {slope:+.2f} MB per 10,000 steps over the second half')
    if launcher.returncode != 0:
        sys.stderr.write(stderr[-3000:])
    return launcher.returncode


if __name__ == '__main__':
    sys.exit(main())

"""
Soak: a long run of the whole graph, printing each process's memory every 10,000 steps.

A benchmark, not a test (about 10 minutes for 100,000 steps on 2 cores). It starts
``attention_train`` (the teacher, ``language``) in a run folder of its own, reads the
resident memory (VmRSS) of the launcher and of each node from ``/proc`` whenever another
``--every`` agent steps are in ``progress.csv``, and prints one row per reading and, at the
end, the growth per 10,000 steps fitted over the second half of the run (after warm-up: the
learner's buffer fills for its first 10,000 samples).

    .venv/bin/python tests/benchmarks/soak.py [--steps 100000] [--every 10000]
    .venv/bin/python tests/benchmarks/soak.py --steps 1000000 --every 100000 \
        --run-dir runs/soak --out docs/robustness/soak_1m.csv   # an hour; run again to resume

With ``--out`` every reading is also a row of that CSV as it is taken, with the session it was
taken in; run the same command again after an interruption and the run resumes
(``attention_train --resume``: fresh processes, the learner from its checkpoint) and the rows
go on. Growth is fitted per session (a resumed process starts small again).
"""

import argparse
import csv
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


FIELDS = ['session', 'steps', 'wall_s'] + [f'{name}_mb' for name in PROCESSES]


def read_rows(path):
    if not path or not Path(path).exists():
        return []
    with open(path, newline='') as file:
        return list(csv.DictReader(file))


def append_row(path, row) -> None:
    new = not Path(path).exists()
    with open(path, 'a', newline='') as file:
        writer = csv.writer(file)
        if new:
            writer.writerow(FIELDS)
        writer.writerow(row)
        file.flush()
        os.fsync(file.fileno())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--steps', type=int, default=100_000)
    parser.add_argument('--every', type=int, default=10_000)
    parser.add_argument('--run-dir', default=None, help='default: a new temporary folder')
    parser.add_argument('--out', default=None, help='a CSV of the readings, appended to')
    args = parser.parse_args()
    run_dir = Path(args.run_dir or tempfile.mkdtemp(prefix='soak-')) / 'run'
    previous = read_rows(args.out)
    session = 1 + max((int(row['session']) for row in previous), default=0)
    done = (run_dir / 'summary.json').exists() and json.loads(
        (run_dir / 'summary.json').read_text()).get('status') == 'completed'
    if done:
        print(f'{run_dir} has run its budget already (its readings: {args.out})')
        return 0
    launcher_bin = str(Path(sys.executable).parent / 'attention_train')
    command = ([launcher_bin, '--resume', str(run_dir), '--quiet']
               if (run_dir / 'summary.json').exists() or (run_dir / 'progress.csv').exists()
               else [launcher_bin, '--steps', str(args.steps), '--run-dir', str(run_dir),
                     '--quiet', '--seed', '11'])
    launcher = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
    print(f'run folder {run_dir}, session {session}')
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
        if args.out:
            append_row(args.out, [session, steps, round(time.monotonic() - started)] + [
                '' if m is None else round(m, 1) for m in memory])
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

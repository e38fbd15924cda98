"""
Stress: start and stop the whole graph again and again, and count every node that hung.

A benchmark, not a test (about 12 s a cycle on 2 cores). Each cycle runs ``attention_train``
(the teacher, ``language``, with the bag recorder) in a fresh run folder and ends it one of two
ways, at random: a Ctrl-C after 5-300 steps, or a budget of 30-300 steps that the run finishes.
Every process of the graph thus starts and stops once a cycle, under load. A node *hung* when
its teardown watchdog fired (``attention_common/teardown_watchdog.py``: its stack is in its
log) or the launcher had to SIGTERM / SIGKILL it. One CSV row per cycle goes to ``--out``
(resumable: run again to add cycles); the table at the end counts cycles and hangs per node and
per executor (``ATTENTION_EXECUTOR``). With ``--gdb``, the native stacks of every node still
alive 2.5 s after a Ctrl-C are saved beside the CSV before the watchdog ends it.

    .venv/bin/python tests/benchmarks/stress_shutdown.py --cycles 100 [--executor events]
"""

import argparse
import csv
import json
import os
from pathlib import Path
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

from attention_bringup.processes import is_running

BIN = Path(sys.executable).parent
NODES = ('env_node', 'feedback_node', 'saliency_node', 'tamer_node', 'session_recorder')
FIELDS = ['cycle', 'executor', 'ending', 'status', 'seconds'] + [
    f'{node}_{what}' for node in NODES for what in ('exit', 'watchdog', 'escalated')]
GDB_AFTER_S = 2.5
"""After a Ctrl-C: a node still alive now is in its teardown's last second or stuck."""


def _progress_rows(run_dir: Path) -> int:
    try:
        with open(run_dir / 'progress.csv', 'rb') as progress:
            return max(0, sum(1 for _ in progress) - 1)
    except OSError:
        return 0


def _native_stacks(pids: dict, into: Path) -> None:
    for name, pid in pids.items():
        if name in NODES[:-1] and is_running(pid):  # (the recorder is stopped last, after them)
            stacks = subprocess.run(['gdb', '-p', str(pid), '-batch', '-ex',
                                     'thread apply all bt'], capture_output=True, text=True)
            into.mkdir(parents=True, exist_ok=True)
            (into / f'{name}.gdb.txt').write_text(stacks.stdout + stacks.stderr)


def one_cycle(cycle: int, executor: str, work: Path, gdb_dir: Path = None) -> dict:
    """Run one start/stop of the graph; return its CSV row."""
    rng = random.Random(cycle)
    ending = rng.choice(('ctrl_c', 'budget'))
    run_dir = work / f'cycle{cycle}'
    steps = rng.randint(30, 300) if ending == 'budget' else 100_000
    env = dict(os.environ, ATTENTION_EXECUTOR=executor)
    started = time.monotonic()
    launcher = subprocess.Popen(
        [str(BIN / 'attention_train'), '--steps', str(steps), '--run-dir', str(run_dir),
         '--quiet', '--record', '--seed', str(cycle)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    if ending == 'ctrl_c':
        wanted = rng.randint(5, 300)
        deadline = time.monotonic() + 180
        while (_progress_rows(run_dir) < wanted and launcher.poll() is None
               and time.monotonic() < deadline):
            time.sleep(0.05)
        launcher.send_signal(signal.SIGINT)
        if gdb_dir is not None:
            time.sleep(GDB_AFTER_S)
            try:
                pids = json.loads((run_dir / 'pids.json').read_text())
            except (OSError, ValueError):
                pids = {}
            _native_stacks(pids, gdb_dir / f'cycle{cycle}')
    try:
        launcher.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        launcher.kill()
        launcher.communicate()
    row = {'cycle': cycle, 'executor': executor, 'ending': ending,
           'seconds': round(time.monotonic() - started, 1)}
    try:
        summary = json.loads((run_dir / 'summary.json').read_text())
    except (OSError, ValueError):
        summary = {'status': 'no_summary', 'exit_codes': {}}
    row['status'] = summary['status']
    watched = set(summary.get('teardown_watchdog', ()))
    for node in NODES:
        row[f'{node}_exit'] = summary['exit_codes'].get(node)
        row[f'{node}_watchdog'] = int(node in watched)
        row[f'{node}_escalated'] = int(len(summary.get('signals_sent', {}).get(node, ())) > 1)
    if summary['status'] in ('completed', 'interrupted') and not watched:
        shutil.rmtree(run_dir, ignore_errors=True)  # keep only the runs worth reading
    return row


def table(rows) -> str:
    lines = ['| executor | node | cycles | clean | watchdog ended it | SIGTERM/SIGKILL needed |',
             '|---|---|---|---|---|---|']
    for executor in sorted({row['executor'] for row in rows}):
        mine = [row for row in rows if row['executor'] == executor]
        for node in NODES:
            ran = [row for row in mine if row[f'{node}_exit'] not in ('', 'None', None)]
            watchdog = sum(int(row[f'{node}_watchdog']) for row in ran)
            killed = sum(int(row[f'{node}_escalated']) for row in ran)
            clean = sum(int(row[f'{node}_exit']) == 0 and not int(row[f'{node}_watchdog'])
                        and not int(row[f'{node}_escalated']) for row in ran)
            lines.append(f'| {executor} | {node} | {len(ran)} | {clean} | {watchdog} | '
                         f'{killed} |')
    return '\n'.join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--cycles', type=int, default=100, help='cycles to add (default 100)')
    parser.add_argument('--executor', choices=('events', 'single'), default='events')
    parser.add_argument('--out', default='stress_shutdown.csv', help='the CSV, appended to')
    parser.add_argument('--gdb', action='store_true',
                        help='save the native stacks of nodes slow to exit (needs gdb)')
    args = parser.parse_args()
    out = Path(args.out)
    rows = list(csv.DictReader(open(out))) if out.exists() else []
    work = Path(tempfile.mkdtemp(prefix='stress-'))
    print(f'run folders of cycles with a hang are kept in {work}', flush=True)
    first = max((int(row['cycle']) for row in rows), default=-1) + 1
    with open(out, 'a', newline='') as file:
        writer = csv.DictWriter(file, FIELDS)
        if not rows:
            writer.writeheader()
        for cycle in range(first, first + args.cycles):
            row = one_cycle(cycle, args.executor, work,
                            out.parent / 'stress_gdb' if args.gdb else None)
            writer.writerow(row)
            file.flush()
            rows.append({key: str(value) for key, value in row.items()})
            hung = [n for n in NODES if row[f'{n}_watchdog'] or row[f'{n}_escalated']]
            print(f'cycle {cycle} {row["ending"]} {row["status"]} {row["seconds"]} s'
                  f'{" HUNG: " + ", ".join(hung) if hung else ""}', flush=True)
    print(table(rows))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

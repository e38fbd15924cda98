"""
What durability costs: feedback to receipt, with each ``sync`` setting of tamer_node.

In process (``TamerAgent``: the real disk and learner threads, on random frames): a person's
pace (one feedback every 100 ms) and a burst (the key held: 200 feedback as fast as they come),
timed from ``on_feedback`` to the receipt, which goes out once the line is as durable as
``sync`` says. Prints p50 / p99 / max in ms and the fdatasync calls, per setting.

    .venv/bin/python tests/benchmarks/bench_sync.py [--feedback 200]
"""

import argparse
from pathlib import Path
import sys
import tempfile
import threading
import time

import numpy as np
from tamer_node.agent import TamerAgent
from tamer_node.config import SYNC_MODES, TamerConfig
from tamer_node.model import Encoder

STEP_NS = 66_666_667


def measure(sync: str, count: int, period_s: float) -> dict:
    run_dir = Path(tempfile.mkdtemp(prefix=f'bench-sync-{sync}-')) / 'run'
    agent = TamerAgent(TamerConfig(sync=sync, checkpoint_period_s=0.0), run_dir,
                       encoder=Encoder(), log=lambda level, text: None)
    agent.start()
    frames = np.random.default_rng(0).integers(0, 256, (5, 210, 160, 3), np.uint8)
    for i in range(5):
        agent.on_observation((i + 1) * STEP_NS, frames[i])
    sent, latencies, done = {}, [], threading.Event()

    def receipt(entry):
        latencies.append(time.perf_counter() - sent[entry['seq']])
        if len(latencies) == count:
            done.set()

    agent.on_logged = receipt
    for i in range(count):
        sent[i + 1] = time.perf_counter()
        agent.on_feedback(1.0, 'stamped', (i % 5 + 1) * STEP_NS)
        if period_s:
            time.sleep(period_s)
    done.wait(30)
    syncs = agent.feedback_log.syncs
    agent.close()
    ms = sorted(1e3 * value for value in latencies)
    return {'n': len(ms), 'p50': ms[len(ms) // 2], 'p99': ms[int(0.99 * (len(ms) - 1))],
            'max': ms[-1], 'syncs': syncs}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--feedback', type=int, default=200)
    args = parser.parse_args()
    print('| sync | pace | receipts | p50 ms | p99 ms | max ms | fdatasync calls |')
    print('|---|---|---|---|---|---|---|')
    for pace, period in (('person, every 100 ms', 0.1), ('burst', 0.0)):
        for sync in SYNC_MODES:
            row = measure(sync, args.feedback, period)
            print(f'| {sync} | {pace} | {row["n"]} | {row["p50"]:.2f} | {row["p99"]:.2f} | '
                  f'{row["max"]:.2f} | {row["syncs"]} |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())

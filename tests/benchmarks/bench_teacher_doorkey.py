"""
Benchmark the DoorKey teacher: its cost per step (``see`` + ``on_step``), no ROS.

A real ``DoorKeyEnv`` is played by an agent that takes the expert's action with probability
``p`` and a random one otherwise (p 1: the expert; 0: at random), the teacher watching every
step from its env_status values; the expert memo starts empty for each p.

Run: ``.venv/bin/python tests/benchmarks/bench_teacher_doorkey.py [--steps N]``.
"""

import argparse
import time

from attention_tasks.doorkey import teaching
from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
from attention_tasks.doorkey.expert import next_action
from env_node.status import Counters, parse_status, status_values
from feedback_node.judging import TeacherConfig
from feedback_node.task_teacher import load_knowledge, TaskTeacher
import numpy as np


def measure(p_expert: float, steps: int, seed: int = 0) -> dict:
    """Return the teacher's cost per step (ms) and what it judged, for one agent."""
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed))
    rng = np.random.default_rng(seed)
    teacher = TaskTeacher(load_knowledge('doorkey'), 6, TeacherConfig())
    teaching.expert_action_of.cache_clear()
    spent = []

    def see(step):
        values = parse_status(status_values(step, Counters(), False))
        start = time.perf_counter()
        teacher.on_step(teacher.see(step.sim_time_ns, values))
        spent.append(time.perf_counter() - start)

    step = env.reset()
    for _ in range(steps):
        see(step)
        action = next_action(env.world)
        if action is None or rng.random() >= p_expert:
            action = int(rng.integers(6))
        step = env.step(action)
        if step.done:
            see(step)
            step = env.reset()
    env.close()
    ms = np.array(spent) * 1e3
    counts = teacher.counts
    return {'p_expert': p_expert, 'mean_ms': ms.mean(), 'median_ms': float(np.median(ms)),
            'p99_ms': float(np.percentile(ms, 99)), 'max_ms': ms.max(),
            'agreed': counts['agreed'] / max(counts['judged'], 1),
            'no_expert_action': counts['no_expert_action']}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[1])
    parser.add_argument('--steps', type=int, default=3000)
    args = parser.parse_args()
    for p_expert in (1.0, 0.8, 0.5, 0.0):
        r = measure(p_expert, args.steps)
        print(f"p_expert {r['p_expert']:.1f}: mean {r['mean_ms']:.3f} ms, median "
              f"{r['median_ms']:.3f}, p99 {r['p99_ms']:.2f}, max {r['max_ms']:.1f} ms per step; "
              f"{r['agreed']:.0%} judged good, {r['no_expert_action']} without an expert action")


if __name__ == '__main__':
    main()

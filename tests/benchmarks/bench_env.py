"""
Benchmark env_node: environment steps per second alone and with an action round trip.

1. In process, no ROS: ``MontezumaEnv.step`` alone, then with the rgb8 encoding the node does
   (best of three runs each).
2. Over topics: the real ``env_node`` executable in lockstep, answered by a probe node in this
   process acting as the learner (decode the frame, send the Joy stamped with it at once).
   Round-trip latency is from publishing the action to receiving the next observation.

Run: ``.venv/bin/python tests/benchmarks/bench_env.py [--steps N]``. It reserves a ROS domain of
its own and keeps DDS on loopback.
"""

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

from attention_common import qos, topics
from attention_common.image_codec import image_to_numpy, numpy_to_image
from attention_common.isolation import apply_to_this_process, isolated_environ, reserved_domain
from attention_common.joy_actions import action_to_joy, NUM_ACTIONS
from attention_common.stamps import stamp_to_ns
from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import Image, Joy

BIN = Path(sys.executable).parent


def bench_in_process(steps: int, encode: bool, repeats: int = 3) -> float:
    """Return the best of ``repeats`` runs (the machine is shared; the best is the least noisy)."""
    env = MontezumaEnv(EnvConfig())
    env.warm_up()
    rng = np.random.default_rng(0)
    actions = rng.integers(NUM_ACTIONS, size=steps)
    msg = Image()
    best = 0.0
    for _ in range(repeats):
        started = time.perf_counter()
        for action in actions:
            step = env.step(int(action))
            if encode:
                numpy_to_image(step.observation, 'rgb8', msg)
            if step.done:
                env.reset()
        best = max(best, steps / (time.perf_counter() - started))
    env.close()
    return best


class RoundTrip:
    """The learner's side: answer every new observation at once; time each round trip."""

    def __init__(self, node, steps: int, warmup: int):
        self.node = node
        self.target = steps + warmup
        self.warmup = warmup
        self.answered = 0
        self.latencies = []
        self.started = None
        self.finished = None
        self._sent_at = None
        self._last_ns = -1
        rng = np.random.default_rng(0)
        self._joys = [action_to_joy(int(a)) for a in rng.integers(NUM_ACTIONS, size=1000)]
        self.publisher = node.create_publisher(Joy, topics.ACTION, qos.ACTIONS)
        node.create_subscription(Image, topics.OBSERVATION, self.on_observation, qos.FRAMES)

    def on_observation(self, msg: Image) -> None:
        now = time.perf_counter()
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if stamp_ns <= self._last_ns:
            return  # a timeout's re-publication
        self._last_ns = stamp_ns
        if self._sent_at is not None and self.answered > self.warmup:
            self.latencies.append(now - self._sent_at)
        if self.answered == self.warmup:
            self.started = now
        if self.answered >= self.target:
            self.finished = now
            return
        image_to_numpy(msg)  # a learner decodes every frame
        axes, buttons = self._joys[self.answered % len(self._joys)]
        joy = Joy(axes=list(axes), buttons=list(buttons))
        joy.header.stamp = msg.header.stamp
        self._sent_at = time.perf_counter()
        self.publisher.publish(joy)
        self.answered += 1


def bench_round_trip(steps: int, warmup: int, log_path: Path) -> dict:
    with open(log_path, 'wb') as log:
        env_node = subprocess.Popen(
            [str(BIN / 'env_node'), '--ros-args', '-p', 'action_timeout:=1.0'],
            stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ))
    rclpy.init()
    node = rclpy.create_node('bench_learner')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    trip = RoundTrip(node, steps, warmup)
    deadline = time.monotonic() + 60 + steps / 20
    try:
        while trip.finished is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.5)
            if env_node.poll() is not None:
                raise RuntimeError(f'env_node exited with {env_node.returncode}; see {log_path}')
    finally:
        env_node.send_signal(signal.SIGINT)
        code = env_node.wait(timeout=20)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    if trip.finished is None:
        raise RuntimeError(f'only {trip.answered} round trips before the deadline')
    latencies_ms = np.array(trip.latencies) * 1e3
    return {
        'steps_per_s': (trip.answered - warmup) / (trip.finished - trip.started),
        'p50_ms': float(np.percentile(latencies_ms, 50)),
        'p99_ms': float(np.percentile(latencies_ms, 99)),
        'exit_code': code,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--steps', type=int, default=3000, help='measured steps per benchmark')
    args = parser.parse_args()

    alone = bench_in_process(args.steps, encode=False)
    encoded = bench_in_process(args.steps, encode=True)
    with reserved_domain() as domain:
        apply_to_this_process(domain)
        os.environ.update(isolated_environ(domain))
        log_path = Path(tempfile.mkdtemp(prefix='bench_env_')) / 'env_node.log'
        trip = bench_round_trip(args.steps, warmup=100, log_path=log_path)
    print(f'{"benchmark":52s} {"value":>10s}')
    print(f'{"env steps/s in process (MontezumaEnv.step)":52s} {alone:10.0f}')
    print(f'{"env steps/s in process, + rgb8 encoding":52s} {encoded:10.0f}')
    print(f'{"env steps/s, lockstep round trip over topics":52s} {trip["steps_per_s"]:10.0f}')
    print(f'{"round-trip latency p50 (ms)":52s} {trip["p50_ms"]:10.2f}')
    print(f'{"round-trip latency p99 (ms)":52s} {trip["p99_ms"]:10.2f}')
    print(f'(ROS_DOMAIN_ID {domain}, {args.steps} steps each, env_node exit code '
          f'{trip["exit_code"]})')
    return 0 if trip['exit_code'] == 0 else 1


if __name__ == '__main__':
    sys.exit(main())

"""
Benchmark tamer_node: acting while the learner trains, in process and over topics.

1. In process (``TamerAgent``, the real learner and disk threads), driven by the real game:
   each step the agent answers the frame, a saliency image of the frame arrives, and feedback
   judges the step (+1 when the agent's x grew, -1 otherwise, stamped with the step), so the
   learner does an immediate update per feedback plus its minibatches at ``update_rate_hz``
   per second of simulation time (``update_clock`` sim; 15 steps per sim second), with the L2
   term on every sample (alpha 1e-4), and writes its journal and checkpoints, as in
   a ``language_every_step`` run. Reports actions/s, act latency, updates/s and memory after
   ``--steps`` steps.
2. Over topics: the real ``tamer_node`` executable, fed by a probe in lockstep (observation and
   saliency image out, wait for the Joy with that stamp, feedback_stamped out). Reports steps/s
   and the observation -> action round trip.

Run: ``.venv/bin/python tests/benchmarks/bench_tamer.py [--steps 10000] [--topic-steps 1500]``.
It reserves a ROS domain of its own and keeps DDS on loopback.
"""

import argparse
import os
from pathlib import Path
import resource
import signal
import subprocess
import sys
import tempfile
import time

from attention_common import qos, topics
from attention_common.image_codec import numpy_to_image
from attention_common.isolation import apply_to_this_process, isolated_environ, reserved_domain
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
import numpy as np
from saliency_node.saliency import BLUR_RADIUS, gaussian_blur
from sensor_msgs.msg import Image, Joy
from tamer_node.agent import share_the_cpu, TamerAgent
from tamer_node.config import TamerConfig

BIN = Path(sys.executable).parent


def rss_mb() -> float:
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return float('nan')


def saliency_of(frame: np.ndarray) -> np.ndarray:
    return gaussian_blur(frame, BLUR_RADIUS)


def bench_in_process(steps: int, update_rate_hz: float, checkpoint_period_s: float,
                     alpha: float) -> dict:
    with tempfile.TemporaryDirectory(prefix='bench_tamer_') as tmp:
        run_dir = Path(tmp) / 'run'
        config = TamerConfig(alpha=alpha, update_rate_hz=update_rate_hz,
                             checkpoint_period_s=checkpoint_period_s)
        agent = TamerAgent(config, run_dir)
        agent.start()
        env = MontezumaEnv(EnvConfig(seed=0))
        step = env.warm_up()
        rss_start = rss_mb()
        act_seconds = []
        started = time.perf_counter()
        for _ in range(steps):
            stamp = step.sim_time_ns
            t0 = time.perf_counter()
            action = agent.on_observation(stamp, step.observation)
            act_seconds.append(time.perf_counter() - t0)
            agent.on_saliency(stamp, saliency_of(step.observation))
            x_before = step.state.x
            step = env.step(action)
            agent.on_feedback(1.0 if step.state.x > x_before else -1.0, 'stamped', stamp)
            if step.done:
                step = env.reset()
        elapsed = time.perf_counter() - started
        stats = agent.metrics()
        caught_up = time.perf_counter() - started
        rss_end = rss_mb()
        agent.close()
        env.close()
        checkpoint = run_dir / 'checkpoints' / 'checkpoint.pt'
        checkpoint_mb = checkpoint.stat().st_size / 2 ** 20 if checkpoint.exists() else 0.0
    act_ms = np.array(act_seconds) * 1e3
    return {
        'loop_steps_per_s': steps / elapsed,
        'actions_per_s': steps / act_ms.sum() * 1e3,
        'act_p50_ms': float(np.percentile(act_ms, 50)),
        'act_p99_ms': float(np.percentile(act_ms, 99)),
        'act_max_ms': float(act_ms.max()),
        'updates_per_s': stats['train/updates'] / elapsed,
        'updates': stats['train/updates'],
        'immediate': stats['train/immediate_updates'],
        'updates_per_step': stats['train/updates_per_step'],
        'minibatch_per_step': stats['train/minibatch_updates_per_step'],
        'skipped': stats['train/skipped_updates'],
        'elapsed_s': caught_up,
        'feedback': stats['feedback/count'],
        'buffer': stats['buffer/size'],
        'checkpoints': stats['checkpoint/count'],
        'checkpoint_mb': checkpoint_mb,
        'rss_start_mb': rss_start,
        'rss_end_mb': rss_end,
        'rss_peak_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def bench_topics(steps: int, frames: np.ndarray, log_path: Path) -> dict:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    run_dir = log_path.parent / 'topic_run'
    with open(log_path, 'wb') as log:
        process = subprocess.Popen(
            [str(BIN / 'tamer_node'), '--ros-args', '-p', f'run_dir:={run_dir}',
             '-p', 'metrics_period_s:=1.0'],
            stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ))
    rclpy.init()
    node = rclpy.create_node('bench_tamer_probe')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    answers = {}
    metrics = []
    node.create_subscription(Joy, topics.ACTION,
                             lambda m: answers.__setitem__(stamp_to_ns(m.header.stamp), m),
                             qos.ACTIONS)
    node.create_subscription(DiagnosticArray, topics.METRICS, metrics.append, qos.METRICS)
    observation_pub = node.create_publisher(Image, topics.OBSERVATION, qos.FRAMES)
    saliency_pub = node.create_publisher(Image, topics.SALIENCY, qos.FRAMES)
    feedback_pub = node.create_publisher(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    images = [numpy_to_image(f, 'rgb8', Image()) for f in frames]
    salient = [numpy_to_image(saliency_of(f), 'rgb8', Image()) for f in frames]
    round_trips = []
    try:
        deadline = time.monotonic() + 60
        while (observation_pub.get_subscription_count() < 1
               or feedback_pub.get_subscription_count() < 1):
            executor.spin_once(timeout_sec=0.1)
            if time.monotonic() > deadline or process.poll() is not None:
                raise RuntimeError(f'tamer_node did not come up; see {log_path}')
        started = time.perf_counter()
        for i in range(steps):
            stamp = (i + 1) * 66_666_667
            k = i % len(images)
            images[k].header.stamp = salient[k].header.stamp = ns_to_stamp(stamp)
            sent = time.perf_counter()
            observation_pub.publish(images[k])
            saliency_pub.publish(salient[k])
            deadline = time.monotonic() + 10
            while stamp not in answers:
                executor.spin_once(timeout_sec=0.05)
                if time.monotonic() > deadline:
                    raise RuntimeError(f'no action for step {i}; see {log_path}')
            round_trips.append(time.perf_counter() - sent)
            feedback = Vector3Stamped()
            feedback.header.stamp = ns_to_stamp(stamp)
            feedback.vector.x = 1.0 if i % 4 == 0 else -1.0
            feedback_pub.publish(feedback)
        elapsed = time.perf_counter() - started
        since = len(metrics)
        deadline = time.monotonic() + 10
        while len(metrics) <= since and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
    finally:
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=30)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    values = {kv.key: kv.value for kv in metrics[-1].status[0].values} if metrics else {}
    trips_ms = np.array(round_trips) * 1e3
    return {
        'steps_per_s': steps / elapsed,
        'trip_p50_ms': float(np.percentile(trips_ms, 50)),
        'trip_p99_ms': float(np.percentile(trips_ms, 99)),
        'node_act_p99_ms': values.get('act/latency_p99_ms', '?'),
        'node_updates_per_s': values.get('train/updates_per_s', '?'),
        'node_updates_per_step': values.get('train/updates_per_step', '?'),
        'node_minibatch_per_step': values.get('train/minibatch_updates_per_step', '?'),
        'node_skipped': values.get('train/skipped_updates', '?'),
        'exit_code': code,
    }


def bench_update_cost(repeats: int = 50) -> dict:
    """Milliseconds per Learner.train_step on 32 frames + 32 saliency images (alpha 1e-4)."""
    import torch
    from tamer_node.agent import DEFAULT_ENCODER
    from tamer_node.buffer import collate, Sample
    from tamer_node.learner import Learner
    from tamer_node.model import HModel, INPUT_SHAPE, load_encoder, to_input
    rng = np.random.default_rng(0)
    images = torch.from_numpy(rng.integers(0, 256, (64,) + INPUT_SHAPE, np.uint8))
    model = HModel(encoder=load_encoder(DEFAULT_ENCODER))
    learner = Learner(model, alpha=1e-4)
    with torch.no_grad():
        features = model.features(to_input(images))
    result = {}
    for name, items in (('images', images), ('features', features)):
        batch = collate([Sample(items[i], items[32 + i], i % 18, -1.0, 1.0, i, i)
                         for i in range(32)])
        learner.train_step(batch)
        started = time.perf_counter()
        for _ in range(repeats):
            learner.train_step(batch)
        result[name] = 1e3 * (time.perf_counter() - started) / repeats
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--steps', type=int, default=10_000, help='in-process steps')
    parser.add_argument('--topic-steps', type=int, default=1500, help='steps over topics')
    parser.add_argument('--update-rate-hz', type=float, default=TamerConfig.update_rate_hz,
                        help='minibatch updates per simulation second')
    parser.add_argument('--checkpoint-period-s', type=float, default=15.0)
    parser.add_argument('--alpha', type=float, default=1e-4)
    args = parser.parse_args()
    share_the_cpu()

    cost = bench_update_cost()
    print(f'one update, 32 samples + 32 saliency images: {cost["images"]:.2f} ms through the '
          f'encoder (fine_tune_encoder / before), {cost["features"]:.2f} ms on cached features')

    result = bench_in_process(args.steps, args.update_rate_hz, args.checkpoint_period_s,
                              args.alpha)
    print(f'in process, {args.steps} steps of the real game, feedback and saliency every step, '
          f'alpha {args.alpha}, update_rate_hz {args.update_rate_hz}, checkpoints every '
          f'{args.checkpoint_period_s} s')
    print(f'  steps/s, whole loop       {result["loop_steps_per_s"]:8.1f}  (emulator + agent)')
    print(f'  actions/s while training  {result["actions_per_s"]:8.1f}  (acting calls only)')
    print(f'  act latency p50 / p99     {result["act_p50_ms"]:6.2f} / {result["act_p99_ms"]:6.2f} '
          f'ms  (max {result["act_max_ms"]:.1f} ms)')
    print(f'  learner updates/s         {result["updates_per_s"]:8.1f}  ({result["updates"]} '
          f'updates, {result["immediate"]} of them immediate)')
    print(f'  updates per agent step    {result["updates_per_step"]:8.3f}  (minibatches '
          f'{result["minibatch_per_step"]:.3f}/step, {result["skipped"]} owed ones skipped: '
          'the learner could not keep up)')
    print(f'  feedback learned from     {result["feedback"]}, buffer {result["buffer"]}, '
          f'{result["checkpoints"]} checkpoints (last {result["checkpoint_mb"]:.0f} MB)')
    print(f'  resident memory           {result["rss_start_mb"]:.0f} MB at start, '
          f'{result["rss_end_mb"]:.0f} MB after {args.steps} steps (peak '
          f'{result["rss_peak_mb"]:.0f} MB)')

    if args.topic_steps > 0:
        collected, _ = _frames()
        with reserved_domain() as domain, tempfile.TemporaryDirectory() as tmp:
            apply_to_this_process(domain)
            os.environ.update(isolated_environ(domain))
            over = bench_topics(args.topic_steps, collected, Path(tmp) / 'tamer_node.log')
        print(f'over topics (real tamer_node process, lockstep probe), {args.topic_steps} steps')
        print(f'  steps/s                   {over["steps_per_s"]:8.1f}')
        print(f'  observation -> action     {over["trip_p50_ms"]:6.2f} / '
              f'{over["trip_p99_ms"]:6.2f} ms p50 / p99 (node-side act p99 '
              f'{over["node_act_p99_ms"]} ms)')
        print(f'  learner updates/s         {over["node_updates_per_s"]} (last metrics period)')
        print(f'  updates per agent step    {over["node_updates_per_step"]} (minibatches '
              f'{over["node_minibatch_per_step"]}/step, {over["node_skipped"]} skipped)')
        print(f'  exit code on SIGINT       {over["exit_code"]}')
    return 0


def _frames():
    from tamer_node.pretrain import collect_frames
    return collect_frames(64, seed=1, stride=3, use_expert=False)


if __name__ == '__main__':
    sys.exit(main())

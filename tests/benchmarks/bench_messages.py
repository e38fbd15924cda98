"""
Benchmark what one message costs in Python rclpy: CPU per publish() and per received message.

Every lockstep step moves an observation Image, an action Joy, an env_status DiagnosticArray and
a /clock through rclpy, and each costs CPU on both sides. Measured for four messages: a 210x160
rgb8 Image (100,800 bytes of pixels, an Atari frame), a Joy, a DiagnosticArray with one status
of 18 KeyValue pairs (like env_status) and a rosgraph_msgs/Clock.

1. Publisher (this process): once 1 or 3 subscribers are matched, it publishes a few warm-up
   messages, then ``--count`` (``--image-count`` for the Image) at a steady pace, one every
   ``--period-ms``, so nobody is flooded; QoS RELIABLE, KEEP_LAST 10 as the graph's frames
   (``--depth`` deepens both sides' history, for a loaded machine where subscribers lag).
   "publish()" sums ``time.process_time()`` around the ``publish()`` calls only; "pub. window"
   is the process's CPU over the whole sending window (adds DDS's own threads, e.g. reliability
   traffic, and the pacing loop), both per message.
2. Subscribers: separate processes (this file with ``--subscriber``), each spinning its own node
   in the executor ``--executor`` names (``events``, the graph's, or ``single``). Each reports
   its process CPU time from the last warm-up message to the last measured one, per message
   received in between: wait, take, deserialize into
   Python objects (or, with ``raw=True``, the serialized bytes only) and the callback. Each also
   reports its idle CPU (spinning with no traffic) as a baseline, not subtracted.

Process CPU time counts every thread of a process (Python and DDS). Messages carry their
sequence number in the stamp's seconds. Prints a markdown table.

Run: ``.venv/bin/python tests/benchmarks/bench_messages.py [--count N]``. It reserves a ROS domain
of its own and keeps DDS on loopback; the subscriber processes inherit both.
"""

import argparse
import importlib
import json
import os
from pathlib import Path
import subprocess
import sys
import time

from attention_common.executors import DEFAULT_EXECUTOR, EXECUTORS
from attention_common.isolation import apply_to_this_process, isolated_environ, reserved_domain
from machine_info import machine

# rclpy is imported lazily, in functions, so this holds before it is loaded in any process.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

WARMUP = 20
"""Messages published before the measured ones (discovery settles, caches warm)."""

IDLE_S = 0.5
"""How long each subscriber spins with no traffic to measure its idle CPU."""

KINDS = {
    'image': ('sensor_msgs.msg', 'Image'),
    'joy': ('sensor_msgs.msg', 'Joy'),
    'diagnostics': ('diagnostic_msgs.msg', 'DiagnosticArray'),
    'clock': ('rosgraph_msgs.msg', 'Clock'),
}
"""Message kind -> (module, class)."""

LABELS = {
    'image': 'Image 210x160 rgb8',
    'joy': 'Joy',
    'diagnostics': 'DiagnosticArray (18 KeyValue)',
    'clock': 'Clock',
}

RUNS = (
    ('image', 1, False), ('image', 3, False), ('image', 1, True),
    ('joy', 1, False), ('joy', 3, False),
    ('diagnostics', 1, False), ('diagnostics', 3, False),
    ('clock', 1, False), ('clock', 3, False),
)
"""(kind, subscribers, raw) of each run, one after the other."""

# The 18 keys of env_status (env_node.status.STATUS_KEYS; not imported, it pulls in ALE).
STATUS_VALUES = (
    ('agent_step', '1234'), ('episode', '3'), ('episode_step', '411'), ('lives', '5'),
    ('has_key', 'false'), ('reward', '0.0'), ('episode_return', '0.0'),
    ('terminated', 'false'), ('truncated', 'false'), ('life_lost', 'false'), ('room', '1'),
    ('x', '77'), ('y', '235'), ('timeouts', '0'), ('dropped_actions', '0'),
    ('bad_actions', '0'), ('finished', 'false'), ('action_latency_ms', '1.234'),
)


def message_class(kind: str):
    module, name = KINDS[kind]
    return getattr(importlib.import_module(module), name)


def stamp_of(msg):
    """Return the message's stamp (every message here starts with one)."""
    return msg.clock if hasattr(msg, 'clock') else msg.header.stamp


def seq_of_raw(data: bytes) -> int:
    """Return ``stamp.sec`` of a serialized message: CDR, the int32 after the 4-byte header."""
    return int.from_bytes(data[4:8], 'little' if data[1] & 1 else 'big', signed=True)


def frames_qos(depth: int):
    """Return the graph's frame QoS (RELIABLE, VOLATILE, KEEP_LAST 10) with ``depth``."""
    from attention_common import qos
    from rclpy.qos import QoSProfile
    frames = qos.FRAMES
    return QoSProfile(history=frames.history, depth=depth, reliability=frames.reliability,
                      durability=frames.durability)


def build_message(kind: str):
    """Return a message as the graph sends it."""
    msg = message_class(kind)()
    if kind == 'image':
        from attention_common.image_codec import numpy_to_image
        import numpy as np
        frame = np.random.default_rng(0).integers(0, 256, size=(210, 160, 3), dtype=np.uint8)
        numpy_to_image(frame, 'rgb8', msg)
    elif kind == 'joy':
        from attention_common.joy_actions import action_to_joy
        axes, buttons = action_to_joy(0)
        msg.axes, msg.buttons = list(axes), list(buttons)
    elif kind == 'diagnostics':
        from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
        msg.status = [DiagnosticStatus(
            level=DiagnosticStatus.OK, name='env_node', message='running',
            hardware_id='ALE/MontezumaRevenge-v5',
            values=[KeyValue(key=key, value=value) for key, value in STATUS_VALUES])]
    return msg


# --- subscriber process ---------------------------------------------------------------------

class Receiver:
    """Counts measured messages and takes process CPU time at the first and last of them."""

    def __init__(self, warmup: int, last: int):
        self.warmup = warmup
        self.last = last
        self.received = 0
        self.cpu_start = None
        self.cpu_end = None
        self.done = False

    def on_message(self, msg) -> None:
        self._count(stamp_of(msg).sec)

    def on_raw(self, data: bytes) -> None:
        self._count(seq_of_raw(data))

    def _count(self, seq: int) -> None:
        now = time.process_time()
        if seq < self.warmup or self.cpu_start is None:
            self.cpu_start = now  # the window opens after the last warm-up message seen
            return
        self.received += 1
        self.cpu_end = now
        self.done = seq >= self.last


def idle_cpu_us_per_s(executor, seconds: float) -> float:
    """Return the process's CPU while it waits with no traffic (long waits: few wake-ups)."""
    started_cpu, started = time.process_time(), time.monotonic()
    while (left := seconds - (time.monotonic() - started)) > 0:
        executor.spin_once(timeout_sec=left)
    return (time.process_time() - started_cpu) / (time.monotonic() - started) * 1e6


def run_subscriber(args) -> int:
    """Subscribe, say ``ready`` once the publisher is matched, print a JSON line at the end."""
    if 'ROS_DOMAIN_ID' not in os.environ:
        sys.exit('--subscriber runs only as a child of this benchmark (no ROS_DOMAIN_ID)')
    import rclpy

    from attention_common.executors import make_executor
    rclpy.init()
    node = rclpy.create_node(f'bench_messages_sub_{os.getpid()}')
    receiver = Receiver(WARMUP, WARMUP + args.expect - 1)
    subscription = node.create_subscription(
        message_class(args.subscriber), args.topic,
        receiver.on_raw if args.raw else receiver.on_message, frames_qos(args.depth),
        raw=args.raw)
    executor = make_executor(args.executor)
    executor.add_node(node)
    deadline = time.monotonic() + 30
    while subscription.get_publisher_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    print('ready', flush=True)
    deadline = time.monotonic() + args.timeout
    while not receiver.done and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    idle = idle_cpu_us_per_s(executor, IDLE_S)
    cpu = (receiver.cpu_end - receiver.cpu_start) if receiver.received else 0.0
    print(json.dumps({'received': receiver.received, 'cpu_s': cpu, 'idle_us_per_s': idle}),
          flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


# --- publisher (this process) ---------------------------------------------------------------

def start_subscribers(kind: str, topic: str, count: int, raw: bool, subscribers: int,
                      timeout: float, depth: int, executor: str) -> list:
    cmd = [sys.executable, str(Path(__file__).resolve()), '--subscriber', kind,
           '--topic', topic, '--expect', str(count), '--timeout', str(timeout),
           '--depth', str(depth)]
    cmd += ['--raw'] if raw else []
    cmd += ['--executor', executor]
    # os.environ holds the reserved domain and LOCALHOST (see main); children inherit it.
    return [subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=dict(os.environ))
            for _ in range(subscribers)]


def publish_paced(publisher, msg, count: int, period: float) -> dict:
    """Publish warm-up + ``count`` messages, one every ``period`` s; return CPU per message."""
    stamp = stamp_of(msg)
    in_publish = 0.0
    window_start = None
    next_at = time.perf_counter()
    for seq in range(WARMUP + count):
        stamp.sec = seq
        if seq == WARMUP:
            window_start = time.process_time()
        before = time.process_time()
        publisher.publish(msg)
        if seq >= WARMUP:
            in_publish += time.process_time() - before
        next_at += period
        delay = next_at - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    window = time.process_time() - window_start
    return {'publish_us': in_publish / count * 1e6, 'window_us': window / count * 1e6}


def wait_until(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise RuntimeError(f'timed out waiting for {what}')
        time.sleep(0.01)


def run_one(node, index: int, kind: str, subscribers: int, raw: bool, count: int,
            period: float, depth: int, executor: str) -> dict:
    """Publish ``count`` messages of ``kind`` to ``subscribers`` new subscriber processes."""
    topic = f'bench_messages/run{index}_{kind}'
    timeout = 30 + (WARMUP + count) * period * 5
    publisher = node.create_publisher(message_class(kind), topic, frames_qos(depth))
    children = start_subscribers(kind, topic, count, raw, subscribers, timeout, depth, executor)
    try:
        for child in children:
            if child.stdout.readline().strip() != 'ready':
                raise RuntimeError(f'a subscriber of {topic} exited early')
        wait_until(lambda: publisher.get_subscription_count() == subscribers, 30,
                   f'{subscribers} subscribers on {topic}')
        result = publish_paced(publisher, build_message(kind), count, period)
        reports = []
        for child in children:
            out, _ = child.communicate(timeout=timeout + 30)
            if child.returncode != 0:
                raise RuntimeError(f'a subscriber of {topic} exited with {child.returncode}')
            reports.append(json.loads(out.strip().splitlines()[-1]))
    finally:
        for child in children:
            if child.poll() is None:
                child.kill()
                child.wait()
        node.destroy_publisher(publisher)
    result.update(kind=kind, subscribers=subscribers, raw=raw, sent=count, reports=reports)
    return result


def timer_overhead_us(samples: int = 10000) -> float:
    started = time.perf_counter()
    for _ in range(samples):
        time.process_time()
    return (time.perf_counter() - started) / samples * 1e6


def serialized_sizes() -> dict:
    from rclpy.serialization import serialize_message
    return {kind: len(serialize_message(build_message(kind))) for kind in KINDS}


def run_benchmark(count: int, image_count: int, period: float, depth: int,
                  executor: str) -> dict:
    import rclpy
    from rclpy.utilities import get_rmw_implementation_identifier

    rclpy.init()
    node = rclpy.create_node('bench_messages_pub')
    try:
        runs = [run_one(node, index, kind, subscribers, raw,
                        image_count if kind == 'image' else count, period, depth, executor)
                for index, (kind, subscribers, raw) in enumerate(RUNS)]
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return {'runs': runs, 'sizes': serialized_sizes(),
            'rmw': get_rmw_implementation_identifier()}


# --- report ---------------------------------------------------------------------------------

def print_table(result: dict, period: float, depth: int, domain: int, executor: str) -> None:
    print('| message | serialized bytes | subscribers | received of sent | publish() µs '
          '| pub. window µs | receive µs (each subscriber) |')
    print('|---|---:|---:|---|---:|---:|---|')
    idle = []
    for run in result['runs']:
        reports = run['reports']
        idle += [r['idle_us_per_s'] for r in reports]
        label = LABELS[run['kind']] + (', raw=True' if run['raw'] else '')
        received = ' / '.join(str(r['received']) for r in reports)
        receive = ' / '.join(f'{r["cpu_s"] / r["received"] * 1e6:.0f}' if r['received'] else '-'
                             for r in reports)
        print(f'| {label} | {result["sizes"][run["kind"]]:,} | {run["subscribers"]} '
              f'| {received} of {run["sent"]} | {run["publish_us"]:.0f} '
              f'| {run["window_us"]:.0f} | {receive} |')
    print()
    print(f'CPU microseconds per message, subscribers on the {executor} executor. {machine()}; '
          f'{result["rmw"]}, ROS_DOMAIN_ID {domain}, '
          f'QoS depth {depth}, one message every {period * 1e3:g} ms after {WARMUP} warm-up '
          'ones.')
    print(f'Idle subscriber process: {sum(idle) / len(idle) * period:.1f} µs CPU per '
          f'{period * 1e3:g} ms period (included in "receive", not subtracted); one '
          f'process_time() reading costs {timer_overhead_us():.2f} µs.')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--count', type=int, default=2000,
                        help='measured messages per run for Joy, DiagnosticArray and Clock')
    parser.add_argument('--image-count', type=int, default=None,
                        help='measured messages per run for the Image (default: half --count)')
    parser.add_argument('--period-ms', type=float, default=2.0,
                        help='time between two published messages')
    parser.add_argument('--depth', type=int, default=10,
                        help='KEEP_LAST depth on both sides (the graph uses 10)')
    parser.add_argument('--executor', choices=EXECUTORS, default=DEFAULT_EXECUTOR,
                        help="the subscribers' rclpy executor (the graph's default: events)")
    parser.add_argument('--subscriber', choices=sorted(KINDS), help=argparse.SUPPRESS)
    parser.add_argument('--topic', help=argparse.SUPPRESS)
    parser.add_argument('--expect', type=int, help=argparse.SUPPRESS)
    parser.add_argument('--timeout', type=float, help=argparse.SUPPRESS)
    parser.add_argument('--raw', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.subscriber:
        return run_subscriber(args)

    image_count = args.image_count or max(1, args.count // 2)
    period = args.period_ms / 1e3
    with reserved_domain() as domain:
        apply_to_this_process(domain)
        os.environ.update(isolated_environ(domain))
        result = run_benchmark(args.count, image_count, period, args.depth, args.executor)
    print_table(result, period, args.depth, domain, args.executor)
    return 0


if __name__ == '__main__':
    sys.exit(main())

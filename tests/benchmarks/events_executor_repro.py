"""
A minimal reproduction: what rclpy's experimental EventsExecutor runs here (rclpy 7.1.6, PyPI).

Each case runs in a fresh process with a deadline (a hang is reported, not waited for): one
node, one timer or one subscription (its callback with or without rclpy's MessageInfo
argument, or with it through ``attention_common.executors.with_message_info``) fed from a
thread, spun by ``spin()`` or by ``spin_once`` in a loop, under
SingleThreadedExecutor and EventsExecutor, in the main thread. It prints how many callbacks ran
in 2 s, or how the process ended (a 10 Hz timer should give about 20; the subscription is sent
20 messages). The graph's way, from these results: ``spin_once`` in a loop, MessageInfo
callbacks through the adapter (``attention_common/executors.py``).

    .venv/bin/python tests/benchmarks/events_executor_repro.py
"""

import os
import subprocess
import sys

CASE = r"""
import os, sys, threading, time
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from std_msgs.msg import Float32
executor_name, entity, spin = sys.argv[1:4]
rclpy.init()
node = rclpy.create_node('repro')
fired = []
if entity == 'timer':
    node.create_timer(0.1, lambda: fired.append(1))
else:
    if entity == 'subscription':
        node.create_subscription(Float32, 'repro', lambda msg: fired.append(1), 10)
    elif entity == 'with_info':  # a callback that also takes rclpy's MessageInfo
        node.create_subscription(Float32, 'repro', lambda msg, info: fired.append(1), 10)
    else:  # the same through attention_common.executors.with_message_info (the graph's way)
        from attention_common.executors import with_message_info
        node.create_subscription(
            Float32, 'repro', with_message_info(lambda msg, info: fired.append(info)), 10)
    publisher = node.create_publisher(Float32, 'repro', 10)
    def publish():
        time.sleep(0.5)
        for i in range(20):
            publisher.publish(Float32(data=float(i)))
            time.sleep(0.02)
    threading.Thread(target=publish, daemon=True).start()
executor = EventsExecutor() if executor_name == 'events' else SingleThreadedExecutor()
executor.add_node(node)
def report():
    time.sleep(2.0)
    print(len(fired), flush=True)
    os._exit(0)
threading.Thread(target=report, daemon=True).start()
if spin == 'spin':
    executor.spin()
else:
    while True:
        executor.spin_once(timeout_sec=0.05)
"""


def main() -> int:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', '91'))
    print('executor   entity        spin       callbacks in 2 s')
    for executor in ('single', 'events'):
        for entity in ('timer', 'subscription', 'with_info', 'info_adapter'):
            for spin in ('spin', 'spin_once'):
                try:
                    result = subprocess.run([sys.executable, '-c', CASE, executor, entity, spin],
                                            capture_output=True, text=True, timeout=15, env=env)
                    error = (result.stderr.strip().splitlines() or [''])[-1][:60]
                    outcome = result.stdout.strip() or f'died (exit {result.returncode}): {error}'
                except subprocess.TimeoutExpired:
                    outcome = 'HANG (killed after 15 s; not even another thread ran)'
                print(f'{executor:10} {entity:13} {spin:10} {outcome}', flush=True)
    print('(with_info dies under the EventsExecutor because it calls the callback with one '
          'argument, the tuple (msg, info); info_adapter accepts that form.)')
    return 0


if __name__ == '__main__':
    sys.exit(main())

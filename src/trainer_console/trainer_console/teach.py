"""
``teach``: one judgement or one utterance from a shell, confirmed by the learner.

    teach good | bad | +1 | -1 | <h in [-1, 1]>
    teach say "climb down the ladder"

Publishes on ``feedback`` (std_msgs/Float32) or ``utterance`` (std_msgs/String), as
``ros2 topic pub`` would, but first waits until tamer_node subscribes, and then until the
learner's receipt on ``feedback_logged`` names this very message (see trainer_console.state).
Exit code 0 once the learner has logged it; 1 if it did not within ``--timeout`` seconds (the
message may still arrive: it is never sent twice); 2 for bad arguments.
"""

import argparse
import math
import sys
import time

from attention_common import qos, topics
from attention_common.dds_memory import use_freed_payloads
from attention_common.feedback import FEEDBACK_RANGE
from attention_common.utterance import MAX_UTTERANCE_CHARS
from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import Float32, String
from trainer_console.matching import subscriber_names, wait_for_all_matched
from trainer_console.state import ConsoleState

LEARNER = 'tamer_node'
WORDS = {'good': 1.0, '+': 1.0, 'bad': -1.0, '-': -1.0}


def parse(argv):
    parser = argparse.ArgumentParser(prog='teach', description=__doc__.split('\n\n')[0])
    parser.add_argument('what', help="good, bad, a number in [-1, 1], or 'say'")
    parser.add_argument('text', nargs='?', help='with say: the utterance')
    parser.add_argument('--timeout', type=float, default=10.0,
                        help='seconds to wait for the learner (default 10)')
    args = parser.parse_args(argv)
    if args.what == 'say':
        if not args.text or not args.text.strip() or len(args.text) > MAX_UTTERANCE_CHARS:
            parser.error(f'say needs an utterance of 1 to {MAX_UTTERANCE_CHARS} characters')
        return 'utterance', args.text, args.timeout
    try:
        h = WORDS.get(args.what)
        h = float(args.what) if h is None else h
    except ValueError:
        parser.error(f'{args.what!r} is neither good, bad, a number nor say')
    if not math.isfinite(h) or abs(h) > FEEDBACK_RANGE:
        parser.error(f'feedback must be in [-{FEEDBACK_RANGE:g}, {FEEDBACK_RANGE:g}], got {h}')
    return 'feedback', h, args.timeout


def learner_listens(node, topic: str) -> bool:
    return LEARNER in subscriber_names(node, topic)


def main(argv=None) -> int:
    kind, value, timeout = parse(sys.argv[1:] if argv is None else argv)
    use_freed_payloads()
    rclpy.init()
    node = rclpy.create_node('teach')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    state = ConsoleState()

    try:
        node.create_subscription(DiagnosticArray, topics.FEEDBACK_LOGGED,
                                 state.on_receipt_message, qos.HUMAN)
        topic = topics.FEEDBACK if kind == 'feedback' else topics.UTTERANCE
        publisher = node.create_publisher(Float32 if kind == 'feedback' else String, topic,
                                          qos.HUMAN)
        deadline = time.monotonic() + timeout

        def spin_until(done) -> bool:
            while not done():
                if time.monotonic() > deadline:
                    return False
                executor.spin_once(timeout_sec=0.05)
            return True

        # Matched both ways: the learner subscribes to our topic and we hear its receipts.
        if not spin_until(lambda: learner_listens(node, topic)
                          and node.count_publishers(topics.FEEDBACK_LOGGED) > 0):
            print(f'teach: no {LEARNER} on {node.resolve_topic_name(topic)} within {timeout:g} s'
                  ' (is the graph running, in this ROS_DOMAIN_ID?): nothing sent',
                  file=sys.stderr)
            return 1
        wait_for_all_matched(node, publisher, lambda s: executor.spin_once(timeout_sec=s))
        sent_ns = time.time_ns()
        publisher.publish(Float32(data=value) if kind == 'feedback' else String(data=value))
        press = state.sent(kind, value, 1, sent_ns)  # this publisher's first and only message
        if not spin_until(lambda: press.confirmed):
            print(f'teach: sent, but the learner has not logged it within {timeout:g} s',
                  file=sys.stderr)
            return 1
        print(f'{kind} {value!r} logged by the learner ({press.status})')
        return 0
    except KeyboardInterrupt:
        return 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())

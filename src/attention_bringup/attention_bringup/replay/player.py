"""
The replay's own node: sends the recorded items to the fresh nodes and hears their answers.

Publishes ``observation``, ``feedback``, ``feedback_stamped``, ``utterance``,
``utterance_stamped`` and ``action_taken`` as serialized bytes (the recorded messages unchanged),
with the graph's QoS; subscribes to the tamer's ``action`` answers and its ``feedback_logged``
receipts. ``send`` is called from the replay's main thread; the callbacks run on the executor's
thread and wake it.
"""

import threading
import time
from typing import Dict, Optional, Tuple

from attention_common import qos, topics
from attention_common.joy_actions import action_to_joy, joy_to_action, JoyActionError
from attention_common.stamps import ns_to_stamp
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Image, Joy
from std_msgs.msg import Float32, String

PUBLISHED = {
    topics.OBSERVATION: (Image, qos.FRAMES_WRITER),
    topics.FEEDBACK: (Float32, qos.HUMAN),
    topics.FEEDBACK_STAMPED: (Vector3Stamped, qos.HUMAN),
    topics.FEEDBACK_PRESSED: (Vector3Stamped, qos.HUMAN),
    topics.UTTERANCE: (String, qos.HUMAN),
    topics.UTTERANCE_STAMPED: (DiagnosticArray, qos.HUMAN),
    topics.ACTION_TAKEN: (Joy, qos.ACTIONS),
}


def task_action(joy: Joy, task) -> Optional[int]:
    """Return the task action a Joy message carries, or None if it carries none."""
    try:
        return task.action_of_joy(joy_to_action(joy.axes, joy.buttons))
    except JoyActionError:
        return None


def task_action_of_bytes(data: bytes, task) -> Optional[int]:
    return task_action(deserialize_message(data, Joy), task)


def feedback_receipt(status) -> Optional[Tuple[int, Optional[int]]]:
    """Return (seq, stamp the learner put it on) of a feedback's receipt, None for others."""
    values = {kv.key: kv.value for kv in status.values}
    if status.name != 'feedback' or 'seq' not in values:
        return None
    stamp = values.get('stamp_ns')
    return int(values['seq']), (int(stamp) if stamp not in (None, '', 'None') else None)


class ReplayPlayer(Node):
    """Sends recorded messages; collects the learner's answers and receipts."""

    def __init__(self, task, **kwargs):
        super().__init__('attention_replay', **kwargs)
        self.task = task
        self.publishers_by_topic = {topic: self.create_publisher(msg_type, topic, profile)
                                    for topic, (msg_type, profile) in PUBLISHED.items()}
        self._condition = threading.Condition()
        self.answers: Dict[int, Optional[int]] = {}
        """stamp -> the learner's answer (task action; None if not one of the task's)."""
        self.receipts = 0
        self.receipt_stamps: Dict[int, Optional[int]] = {}
        """Feedback receipts: the learner's seq -> the stamp it attached the feedback to."""
        self.metrics: Dict[str, str] = {}
        self._action_sub = self.create_subscription(Joy, topics.ACTION, self._on_action,
                                                    qos.ACTIONS)
        self._receipt_sub = self.create_subscription(DiagnosticArray, topics.FEEDBACK_LOGGED,
                                                     self._on_receipt, qos.WATCH_STEPS)
        self.create_subscription(DiagnosticArray, topics.METRICS, self._on_metrics, qos.METRICS)

    # -- what the nodes say ---------------------------------------------------------------
    def _on_action(self, msg: Joy) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with self._condition:
            self.answers[stamp] = task_action(msg, self.task)
            self._condition.notify_all()

    def _on_receipt(self, msg: DiagnosticArray) -> None:
        with self._condition:
            for status in msg.status:
                self.receipts += 1
                receipt = feedback_receipt(status)
                if receipt is not None:
                    self.receipt_stamps[receipt[0]] = receipt[1]
            self._condition.notify_all()

    def _on_metrics(self, msg: DiagnosticArray) -> None:
        with self._condition:
            for status in msg.status:
                self.metrics.update({kv.key: kv.value for kv in status.values})
            self._condition.notify_all()

    # -- the replay's thread --------------------------------------------------------------
    def nodes_listen(self) -> bool:
        """Whether saliency_node and tamer_node take observations and the tamer answers."""
        counts = {topic: self.publishers_by_topic[topic].get_subscription_count()
                  for topic in (topics.OBSERVATION, topics.UTTERANCE, topics.FEEDBACK,
                                topics.FEEDBACK_STAMPED, topics.FEEDBACK_PRESSED,
                                topics.ACTION_TAKEN)}
        return (counts[topics.OBSERVATION] >= 2 and counts[topics.UTTERANCE] >= 2
                and counts[topics.FEEDBACK] >= 1 and counts[topics.FEEDBACK_STAMPED] >= 1
                and counts[topics.FEEDBACK_PRESSED] >= 1
                and counts[topics.ACTION_TAKEN] >= 1
                and self._action_sub.get_publisher_count() >= 1
                and self._receipt_sub.get_publisher_count() >= 1)

    def send(self, topic: str, data: bytes) -> None:
        self.publishers_by_topic[topic].publish(data)

    def send_taken(self, stamp: int, action: int) -> None:
        """Say on ``action_taken`` that task action ``action`` was executed on step ``stamp``."""
        joy = Joy()
        joy.header.stamp = ns_to_stamp(stamp)
        axes, buttons = action_to_joy(self.task.joy_action(action))
        joy.axes = [float(a) for a in axes]
        joy.buttons = [int(b) for b in buttons]
        self.publishers_by_topic[topics.ACTION_TAKEN].publish(joy)

    def wait_answer(self, stamp: int, timeout_s: float) -> bool:
        """Wait until the learner answered ``stamp``; False after ``timeout_s``."""
        with self._condition:
            return self._condition.wait_for(lambda: stamp in self.answers, timeout_s)

    def wait_receipts(self, count: int, timeout_s: float) -> bool:
        """Wait until ``count`` receipts came; False after ``timeout_s``."""
        with self._condition:
            return self._condition.wait_for(lambda: self.receipts >= count, timeout_s)

    def wait_metrics(self, key: str, at_least: float, timeout_s: float) -> bool:
        """Wait until the learner's metrics say ``key`` >= ``at_least`` (they come each 1 s)."""
        def reached() -> bool:
            try:
                return float(self.metrics.get(key, 'nan')) >= at_least
            except ValueError:
                return False
        with self._condition:
            return self._condition.wait_for(reached, timeout_s)

    def answer(self, stamp: int) -> Optional[int]:
        with self._condition:
            return self.answers.get(stamp)


def sleep_until(deadline: float) -> None:
    """Sleep until ``time.monotonic()`` reaches ``deadline`` (no-op if it has)."""
    delay = deadline - time.monotonic()
    if delay > 0:
        time.sleep(delay)

"""
What the bridge serves as it comes: every topic a session bag holds, and the learner's H.

Each topic is one Foxglove channel named as the graph names it (absolute, as the bag keeps it),
encoded as the bag encodes it: the publisher's CDR bytes (``cdr``) under the message's ROS 2
definition (``ros2msg``), so one layout reads a live session and its bag alike. ``/clock`` is
left out: Foxglove keeps time by each message's receive time.
"""

from typing import Optional, Tuple

from attention_common import qos, topics
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSProfile
from session_bag.recorded import RECORDED, RecordedTopic, type_name
from session_bag.schema import definition

FORWARDED: Tuple[RecordedTopic, ...] = tuple(
    topic for topic in RECORDED if topic.name != topics.CLOCK) + (
    RecordedTopic(topics.ACTION_VALUES, DiagnosticArray, qos.ACTION_VALUES),)
"""The topics served raw. ``action_values`` is not in a bag: the learner publishes it only
while someone watches."""

ENCODING = 'cdr'
SCHEMA_ENCODING = 'ros2msg'


def is_image(topic: RecordedTopic) -> bool:
    return type_name(topic.msg_type) == 'sensor_msgs/msg/Image'


def schema_of(topic: RecordedTopic) -> Tuple[str, bytes]:
    """Return the channel's schema name ('sensor_msgs/msg/Image') and ros2msg definition."""
    name = type_name(topic.msg_type)
    return name, definition(name).text.encode()


def viewer_qos(topic: RecordedTopic) -> QoSProfile:
    """
    Return the bridge's QoS on ``topic``: a viewer never slows the graph.

    Images best effort (a lost frame is a frame not drawn; a reliable reader could hold a
    writer's history); a person's words and the learner's answers to them reliable and whole,
    as every reader of them is; step data and metrics reliable, as designed.
    """
    if is_image(topic):
        return qos.WATCH_IMAGES
    return topic.designed_qos


class RateLimit:
    """At most ``rate_hz`` messages a second: a message passes once a period has gone by."""

    def __init__(self, rate_hz: float):
        if not rate_hz > 0:
            raise ValueError(f'rate_hz must be > 0, got {rate_hz}')
        self.period_s = 1.0 / rate_hz
        self._last: Optional[float] = None

    def allow(self, now_s: float) -> bool:
        """Tell whether a message at ``now_s`` (monotonic seconds) goes; count it if it does."""
        if self._last is not None and now_s - self._last < self.period_s:
            return False
        self._last = now_s
        return True

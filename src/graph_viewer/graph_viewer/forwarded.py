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
from session_bag.recorded import RECORDED, RecordedTopic, type_name
from session_bag.schema import definition

FORWARDED: Tuple[RecordedTopic, ...] = tuple(
    topic for topic in RECORDED if topic.name != topics.CLOCK) + (
    RecordedTopic(topics.ACTION_VALUES, DiagnosticArray, qos.ACTION_VALUES),)
"""The topics served raw. ``action_values`` is not in a bag: the learner publishes it only
while someone watches."""

ENCODING = 'cdr'
SCHEMA_ENCODING = 'ros2msg'


PER_STEP = (topics.ACTION, topics.ACTION_TAKEN, topics.AGENT_POSITION, topics.ENV_STATUS,
            topics.ACTION_VALUES)
"""One message per agent step: a lockstep run sends 200 a second, more than a plot can show.
A person's words, the learner's receipts and credit, and metrics are never thinned."""


def is_image(topic: RecordedTopic) -> bool:
    return type_name(topic.msg_type) == 'sensor_msgs/msg/Image'


def is_per_step(topic: RecordedTopic) -> bool:
    return topic.name in PER_STEP


def schema_of(topic: RecordedTopic) -> Tuple[str, bytes]:
    """Return the channel's schema name ('sensor_msgs/msg/Image') and ros2msg definition."""
    name = type_name(topic.msg_type)
    return name, definition(name).text.encode()


def viewer_qos(topic: RecordedTopic):
    """
    Return the bridge's QoS on ``topic``: a viewer never slows the graph.

    Images and per-step topics: the newest only, best effort (a frame not drawn is no loss,
    and a reliable reader could hold a writer's history); a person's words, the learner's
    receipts and credit, and metrics reliable and whole, as their publishers offer them.
    """
    if is_image(topic) or is_per_step(topic):
        return qos.NEWEST
    return topic.designed_qos


class RateLimit:
    """At most ``rate_hz`` messages a second: a message passes once a period has gone by."""

    def __init__(self, rate_hz: float):
        if not rate_hz > 0:
            raise ValueError(f'rate_hz must be > 0, got {rate_hz}')
        self.period_s = 1.0 / rate_hz
        self._last: Optional[float] = None

    def due(self, now_s: float) -> bool:
        """Tell whether a message at ``now_s`` would go (without counting it)."""
        return self._last is None or now_s - self._last >= self.period_s

    def allow(self, now_s: float) -> bool:
        """Tell whether a message at ``now_s`` (monotonic seconds) goes; count it if it does."""
        if self._last is not None and now_s - self._last < self.period_s:
            return False
        self._last = now_s
        return True

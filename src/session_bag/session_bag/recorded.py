"""
What a session bag holds: every topic of the graph a viewer or a replay needs, with its type.

Pure (message classes only, no node). The QoS a topic is recorded with is its publishers' own,
asked from the graph when the first message comes (``node.py``); ``DESIGNED_QOS`` is the
graph's design (``attention_common.qos``), used when no publisher is known any more.
"""

from typing import Dict, NamedTuple

from attention_common import qos, topics
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, Vector3Stamped
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, Joy
from std_msgs.msg import Float32, String


class RecordedTopic(NamedTuple):
    """One topic of the bag."""

    name: str
    """As the graph names it (relative: a namespace moves it; the bag keeps the full name)."""
    msg_type: type
    designed_qos: QoSProfile
    """The publishers' QoS by design (``attention_common.qos``)."""


RECORDED = (
    RecordedTopic(topics.OBSERVATION, Image, qos.FRAMES_WRITER),
    RecordedTopic(topics.SALIENCY, Image, qos.FRAMES_WRITER),
    RecordedTopic(topics.SALIENCY_MASK, Image, qos.FRAMES_WRITER),
    RecordedTopic(topics.ACTION, Joy, qos.ACTIONS),
    RecordedTopic(topics.ACTION_TAKEN, Joy, qos.ACTIONS),
    RecordedTopic(topics.FEEDBACK, Float32, qos.HUMAN),
    RecordedTopic(topics.FEEDBACK_STAMPED, Vector3Stamped, qos.HUMAN),
    RecordedTopic(topics.FEEDBACK_PRESSED, Vector3Stamped, qos.HUMAN),
    RecordedTopic(topics.UTTERANCE, String, qos.HUMAN),
    RecordedTopic(topics.UTTERANCE_STAMPED, DiagnosticArray, qos.HUMAN),
    RecordedTopic(topics.FEEDBACK_LOGGED, DiagnosticArray, qos.HUMAN),
    RecordedTopic(topics.FEEDBACK_CREDIT, DiagnosticArray, qos.HUMAN),
    RecordedTopic(topics.QUESTION, Vector3Stamped, qos.HUMAN),
    RecordedTopic(topics.AGENT_POSITION, PointStamped, qos.STEP_DATA),
    RecordedTopic(topics.ENV_STATUS, DiagnosticArray, qos.STEP_DATA),
    RecordedTopic(topics.METRICS, DiagnosticArray, qos.METRICS),
    RecordedTopic(topics.CLOCK, Clock, qos.CLOCK),
)
"""Every topic the recorder subscribes to, in the bag's channel order."""

BY_NAME: Dict[str, RecordedTopic] = {t.name: t for t in RECORDED}


def type_name(msg_type: type) -> str:
    """Return the ROS 2 name of a message class: Image -> 'sensor_msgs/msg/Image'."""
    package = msg_type.__module__.split('.')[0]
    return f'{package}/msg/{msg_type.__name__}'

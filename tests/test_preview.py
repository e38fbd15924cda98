"""attention_common.preview on a real rclpy node: only for a reader, at most its rate."""

from attention_common.preview import Preview, preview_topic
from harness import TopicProbe, wait_until
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

TOPIC = 'preview_test'
READER = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)


class Clock:
    """Wall seconds that move only when the test says."""

    def __init__(self):
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def node():
    with TopicProbe('preview_publisher') as probe:
        yield probe


def test_nothing_is_made_or_sent_while_nobody_reads(node):
    clock = Clock()
    preview = Preview(node.node, String, TOPIC, 30.0, clock=clock)
    made = []
    assert not preview.publish(lambda: made.append(1) or String(data='x'))
    assert preview.published == 0 and not made  # not even built


def test_a_reader_gets_at_most_the_rate_and_a_burst(node):
    clock = Clock()
    preview = Preview(node.node, String, TOPIC, 30.0, clock=clock)
    with TopicProbe('preview_reader') as reader:
        log = reader.subscribe(String, preview_topic(TOPIC), READER)
        assert wait_until(lambda: preview.publisher.get_subscription_count() == 1, 10.0)
        assert reader.wait_matched(log)  # both sides: best effort sends nothing twice
        sent = 0
        for step in range(400):  # 400 steps over 2 wall seconds: a lockstep run's 200/s
            clock.now += 0.005
            sent += preview.publish(String(data=str(step)))
        assert 60 <= sent <= 5 + 60 + 1, sent  # 30 a second, bursts of 5
        assert preview.published == sent
        assert log.wait_count(sent, 10.0), len(log.snapshot())
        numbers = [int(msg.data) for msg in log.snapshot()]
        assert numbers == sorted(numbers)  # the steps' own messages, in order


def test_rate_zero_makes_no_preview_topic(node):
    preview = Preview(node.node, String, TOPIC, 0.0)
    assert preview.publisher is None and not preview.publish(String(data='x'))
    assert node.node.count_publishers(preview_topic(TOPIC)) == 0
    with pytest.raises(ValueError, match='preview_rate_hz must be >= 0'):
        Preview(node.node, String, TOPIC, -1.0)

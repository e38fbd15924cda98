"""The start-up gate that holds a node's outputs until the session recorder hears them."""

import time

from attention_common import qos
from attention_common.recorder_gate import RecorderGate
from harness import TopicProbe, wait_until
import pytest
from std_msgs.msg import String

TOPIC = 'gate_test'


def _strings(log):
    return [m.data for m in log.snapshot()]


def _say(text: str) -> String:
    return String(data=text)


@pytest.fixture
def sender():
    with TopicProbe('gated_sender') as probe:
        yield probe


def test_held_until_the_recorder_matches_then_sent_in_order(sender):
    publisher = sender.publisher(String, TOPIC, qos.HUMAN)
    gate = RecorderGate(sender.node, 'session_recorder', [publisher], timeout_s=60.0)
    with TopicProbe('some_viewer') as viewer:
        seen = viewer.subscribe(String, TOPIC, qos.HUMAN)
        assert sender.wait_for_subscribers(publisher, 1)
        for k in range(5):
            gate.publish(publisher, _say(f'm{k}'))
        time.sleep(0.5)  # another reader is matched, but not the recorder: all held
        assert not gate.is_open and _strings(seen) == []
        with TopicProbe('session_recorder') as recorder:
            heard = recorder.subscribe(String, TOPIC, qos.HUMAN)
            assert heard.wait_count(5, 10.0), _strings(heard)
            assert gate.is_open and gate.held_total == 5
            gate.publish(publisher, _say('m5'))
            assert heard.wait_count(6, 10.0)
            assert _strings(heard) == [f'm{k}' for k in range(6)]
        assert seen.wait_count(6, 10.0) and _strings(seen) == _strings(heard)


def test_opens_after_the_wait_without_a_recorder_and_loses_nothing(sender):
    publisher = sender.publisher(String, TOPIC, qos.HUMAN)
    with TopicProbe('some_viewer') as viewer:
        seen = viewer.subscribe(String, TOPIC, qos.HUMAN)
        assert sender.wait_for_subscribers(publisher, 1)
        gate = RecorderGate(sender.node, 'session_recorder', [publisher], timeout_s=0.5)
        gate.publish(publisher, _say('early'))
        assert not gate.is_open
        assert wait_until(lambda: gate.is_open, 10.0)
        gate.publish(publisher, _say('late'))
        assert seen.wait_count(2, 10.0) and _strings(seen) == ['early', 'late']


def test_no_recorder_named_publishes_at_once(sender):
    publisher = sender.publisher(String, TOPIC, qos.HUMAN)
    gate = RecorderGate(sender.node, '', [publisher], timeout_s=60.0)
    assert gate.is_open
    with TopicProbe('some_viewer') as viewer:
        seen = viewer.subscribe(String, TOPIC, qos.HUMAN)
        assert sender.wait_for_subscribers(publisher, 1)
        gate.publish(publisher, _say('now'))
        assert seen.wait_count(1, 10.0) and gate.held_total == 0

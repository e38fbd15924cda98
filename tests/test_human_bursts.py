"""
Bursts on the human topics: every message of a burst reaches the node (the README's limit).

``qos.HUMAN`` keeps all: 10,000 messages published at once on each of ``feedback``,
``feedback_stamped``, ``utterance`` and ``utterance_stamped`` all arrive (with a depth of 100,
a burst of 10,000 feedback gave the learner 466).
"""

import re
import signal

from attention_common import qos, topics
from attention_common.stamps import NS_PER_S, ns_to_stamp
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped
from harness import wait_until
import pytest
from std_msgs.msg import Float32, String

pytestmark = pytest.mark.topics
BURST = 10_000
STARTUP_S = 60.0
DRAIN_S = 120.0


def metrics_of(msg):
    return {kv.key: float(kv.value) for kv in msg.status[0].values}


def test_bursts_of_feedback_and_utterances_all_reach_the_learner(probe, start_node, tmp_path):
    run = tmp_path / 'run'
    tamer = start_node('tamer_node', {'run_dir': str(run), 'metrics_period_s': 0.5})
    feedback = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
    stamped = probe.publisher(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
    metrics = probe.subscribe(DiagnosticArray, topics.METRICS, qos.METRICS)
    for publisher in (feedback, stamped, utterance):
        assert probe.wait_for_subscribers(publisher, timeout=STARTUP_S), tamer.log_text()[-2000:]
    # A running learner (its metrics heard): discovery has matched both ways by then. (Right
    # after the publisher first sees the subscription, the reader may not know the writer yet;
    # a burst then fills the publisher's own history, 5,000 by default, and publish fails.)
    assert metrics.wait_count(1, STARTUP_S)
    for i in range(BURST):
        feedback.publish(Float32(data=1.0 if i % 2 else -1.0))
    for i in range(BURST):
        msg = Vector3Stamped()
        msg.header.stamp = ns_to_stamp((i + 1) * NS_PER_S // 15)
        msg.vector.x = 1.0
        stamped.publish(msg)
    for i in range(BURST):
        utterance.publish(String(data=f'utterance {i}'))

    def all_in(ms):
        return bool(ms) and (metrics_of(ms[-1])['feedback/received'] == 2 * BURST
                             and metrics_of(ms[-1])['utterance/count'] == BURST)
    assert metrics.wait_for(all_in, DRAIN_S), metrics_of(metrics.snapshot()[-1])
    assert tamer.stop(signal.SIGINT) == 0
    lines = (run / 'feedback_log.jsonl').read_text().splitlines()
    assert len(lines) == 3 * BURST  # on disk, every one
    # No stamped one had a step to learn on; each is in the log above, and the node's log says
    # so for each, one line each up to its budget and the rest folded into counted lines (10,000
    # lines of their own held its exit for 4 s here, and over 15 s on a busy machine).
    log = tamer.log_text()
    whole = log.count('matches no step the agent acted on')
    folded = sum(int(n) for n in re.findall(r'(\d+) more warning\(s\) like those above', log))
    assert whole + folded - len(re.findall('more warning', log)) == BURST
    assert whole < BURST // 10


def test_bursts_of_utterances_all_reach_the_saliency_node(probe, start_node):
    node = start_node('saliency_node', {'status_period': 0.5})
    utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
    stamped = probe.publisher(DiagnosticArray, topics.UTTERANCE_STAMPED, qos.HUMAN)
    for publisher in (utterance, stamped):
        assert probe.wait_for_subscribers(publisher, timeout=STARTUP_S), node.log_text()[-2000:]
    # Running and matched both ways: one utterance on each topic is heard first.
    stamped.publish(DiagnosticArray(status=[DiagnosticStatus(name='utterance', message='go')]))
    utterance.publish(String(data='go on'))
    assert node.wait_for_log("utterance at now: 'go on'", STARTUP_S), node.log_text()[-2000:]
    assert node.wait_for_log("utterance_stamped at 0.000s: 'go'", STARTUP_S)
    for i in range(BURST):
        msg = DiagnosticArray(status=[DiagnosticStatus(name='utterance',
                                                       message=f'get the key {i}')])
        msg.header.stamp = ns_to_stamp((i + 1) * NS_PER_S // 15)
        stamped.publish(msg)
    for i in range(BURST):
        utterance.publish(String(data=f'climb the ladder {i}'))  # other texts: all heard
    total = 2 * BURST + 2
    assert wait_until(lambda: f'utterances {total};' in node.log_text()
                      or f'utterances {total},' in node.log_text(), DRAIN_S), (
        node.log_text()[-1500:])
    assert node.log_text().count('utterance_stamped at ') == BURST + 1
    assert node.log_text().count('utterance at ') == BURST + 1
    assert node.stop(signal.SIGINT) == 0


def test_feedback_sent_just_before_ctrl_c_is_logged(probe, start_node, tmp_path):
    """The node takes what it was sent before the signal (rclpy alone had logged 0 of 50)."""
    run = tmp_path / 'run'
    tamer = start_node('tamer_node', {'run_dir': str(run), 'metrics_period_s': 0.5})
    feedback = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
    metrics = probe.subscribe(DiagnosticArray, topics.METRICS, qos.METRICS)
    assert probe.wait_for_subscribers(feedback, timeout=STARTUP_S), tamer.log_text()[-2000:]
    assert metrics.wait_count(1, STARTUP_S)  # matched both ways (see the burst test)
    for i in range(50):
        feedback.publish(Float32(data=1.0 if i % 2 else -1.0))
    assert tamer.stop(signal.SIGINT) == 0
    lines = (run / 'feedback_log.jsonl').read_text().splitlines()
    assert len(lines) == 50, tamer.log_text()[-2000:]

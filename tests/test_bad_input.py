"""
Bad input on every input topic of every node, over real topics to the real executables.

For each topic at least six kinds of bad message: the node keeps running, logs one clear line
per message, counts it, and then still does its job on good input. (env_node's ``action`` has
its matrix in test_env_topics: wrong stamps, NaN and out-of-range axes, missing fields.)
"""

import math
import re
import signal

from attention_bringup.processes import resident_memory_kb
from attention_common import qos, topics
from attention_common.image_codec import numpy_to_image
from attention_common.joy_actions import action_to_joy
from attention_common.stamps import NS_PER_S, ns_to_stamp, stamp_to_ns
from attention_common.utterance import MAX_UTTERANCE_CHARS
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from env_node.status import STATUS_NAME
from geometry_msgs.msg import PointStamped, Vector3Stamped
from harness import wait_until
import numpy as np
import pytest
from sensor_msgs.msg import Image, Joy
from std_msgs.msg import Float32, String

pytestmark = pytest.mark.topics
STARTUP_S = 60.0
REPLY_S = 15.0
FAR = 2**31 * NS_PER_S  # a stamp far in the future
T0 = 7 * NS_PER_S


def image(array, stamp_ns, encoding='rgb8'):
    msg = numpy_to_image(array, encoding, Image())
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def bad_images(frame, stamp_ns):
    """(message, what the node's log line says) for seven kinds of bad image."""
    truncated = image(frame, stamp_ns)
    truncated.data = truncated.data[:5000]
    short_step = image(frame, stamp_ns)
    short_step.step = 10
    bgr = image(frame, stamp_ns)
    bgr.encoding = 'bgr8'
    return [
        (image(frame[:, :, 0].copy(), stamp_ns, 'mono8'), "encoding 'mono8'"),
        (bgr, "encoding 'bgr8'"),
        (image(np.zeros((100, 100, 3), np.uint8), stamp_ns), 'size 100x100, 160x210 expected'),
        (image(np.zeros((4000, 4000, 3), np.uint8), stamp_ns), 'size 4000x4000'),
        (truncated, 'data has 5000 bytes'),
        (short_step, 'step 10 is shorter than a row'),
        (image(frame, FAR), 'more than 60 s from the newest'),
    ]


def frame(seed=0):
    return np.random.default_rng(seed).integers(0, 256, (210, 160, 3), np.uint8)


def values(msg):
    return {kv.key: float(kv.value) for kv in msg.status[0].values}


def wait_metrics(log, predicate, timeout=REPLY_S):
    return log.wait_for(lambda ms: bool(ms) and predicate(values(ms[-1])), timeout)


def counts_line(node, pattern):
    """Return the node's newest status line that matches ``pattern`` (a regex)."""
    found = re.findall(pattern, node.log_text())
    return found[-1] if found else None


def test_tamer_node_survives_bad_input_on_all_five_topics(probe, start_node, tmp_path):
    tamer = start_node('tamer_node', {'run_dir': str(tmp_path / 'run'), 'metrics_period_s': 0.2})
    observation = probe.publisher(Image, topics.OBSERVATION, qos.FRAMES)
    saliency = probe.publisher(Image, topics.SALIENCY, qos.FRAMES)
    feedback = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
    stamped = probe.publisher(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
    actions = probe.subscribe(Joy, topics.ACTION, qos.ACTIONS)
    metrics = probe.subscribe(DiagnosticArray, topics.METRICS, qos.METRICS)
    for publisher in (observation, saliency, feedback, stamped, utterance):
        assert probe.wait_for_subscribers(publisher, timeout=STARTUP_S), tamer.log_text()[-2000:]

    def answered(stamp_ns):
        return actions.wait_for(
            lambda ms: any(stamp_to_ns(m.header.stamp) == stamp_ns for m in ms), REPLY_S)

    observation.publish(image(frame(), T0))
    assert answered(T0), tamer.log_text()[-2000:]
    for kind, publisher in (('observation', observation), ('saliency', saliency)):
        for msg, line in bad_images(frame(1), T0 + NS_PER_S):
            publisher.publish(msg)
            assert tamer.wait_for_log(line, REPLY_S), (kind, line, tamer.log_text()[-2000:])
    for value in (math.nan, math.inf, -math.inf, 1e9, 5.0, -50.0):  # one range: [-1, 1]
        feedback.publish(Float32(data=value))
    for h, stamp_ns in ((math.nan, T0), (math.inf, T0), (1e9, T0),
                        (1.0, FAR), (1.0, 0), (1.0, T0 + 5 * NS_PER_S)):
        msg = Vector3Stamped()
        msg.header.stamp = ns_to_stamp(stamp_ns)
        msg.vector.x = h
        stamped.publish(msg)
    for text in ('', '   ', '\t\n', ' ' * 5000, 'x' * (MAX_UTTERANCE_CHARS + 1), 'y' * 1_000_000):
        utterance.publish(String(data=text))
    expected = {'drop/observation': 6, 'drop/observation_stamp': 1, 'drop/saliency': 6,
                'drop/saliency_stamp': 1, 'feedback/invalid': 9, 'feedback/unmatched': 3,
                'utterance/empty': 4, 'utterance/too_long': 2}
    assert wait_metrics(metrics, lambda v: all(v[k] == n for k, n in expected.items())), (
        {k: values(metrics.snapshot()[-1])[k] for k in expected})
    log = tamer.log_text()
    assert log.count('is not a finite number within [-1, 1]') == 9
    assert log.count('matches no step the agent acted on') == 3
    assert log.count('utterance dropped: empty') == 4 and log.count('more than 2000') == 2
    # And then it does its job: acts, learns from good feedback, logs good words.
    t1 = T0 + NS_PER_S // 15
    observation.publish(image(frame(2), t1))
    assert answered(t1)
    good = Vector3Stamped()
    good.header.stamp = ns_to_stamp(t1)
    good.vector.x = 1.0
    stamped.publish(good)
    utterance.publish(String(data='Climb down the ladder.'))
    assert wait_metrics(metrics, lambda v: v['feedback/count'] == 1 and v['samples/added'] == 1)
    assert tamer.wait_for_log("utterance: 'Climb down the ladder.'", REPLY_S)
    assert tamer.alive() and tamer.stop(signal.SIGINT) == 0


def stamped_utterance(text, stamp_ns, name='utterance'):
    msg = DiagnosticArray(status=[DiagnosticStatus(name=name, message=text)])
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def test_saliency_node_survives_bad_input_on_all_three_topics(probe, start_node):
    node = start_node('saliency_node', {'status_period': 0.5})
    observation = probe.publisher(Image, topics.OBSERVATION, qos.FRAMES)
    utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
    stamped = probe.publisher(DiagnosticArray, topics.UTTERANCE_STAMPED, qos.HUMAN)
    saliency = probe.subscribe(Image, topics.SALIENCY, qos.FRAMES)
    for publisher in (observation, utterance, stamped):
        assert probe.wait_for_subscribers(publisher, timeout=STARTUP_S), node.log_text()[-2000:]
    observation.publish(image(frame(), T0))
    assert node.wait_for_log('no utterance valid', REPLY_S)
    for msg, line in bad_images(frame(1), T0 + NS_PER_S):
        observation.publish(msg)
        assert node.wait_for_log(line, REPLY_S), (line, node.log_text()[-2000:])
    plain = [('', 'empty or only whitespace'), (' \t\n ', 'empty or only whitespace'),
             ('x' * 100_000, '100000 characters'), ('x' * 2001, '2001 characters'),
             ('\U0001F642\U0001F642', 'no ASCII words'), ('\u4e2d\u6587', 'no ASCII words')]
    for text, line in plain:
        utterance.publish(String(data=text))
    stamped_bad = [(DiagnosticArray(), 'status[0].name must be "utterance"'),
                   (stamped_utterance('Get the key', T0, name='speech'), "(got ['speech'])"),
                   (stamped_utterance('   ', T0), 'empty or only whitespace'),
                   (stamped_utterance('k' * 3000, T0), '3000 characters'),
                   (stamped_utterance('\U0001F511', T0), 'no ASCII words'),
                   (stamped_utterance('Get the key', FAR),
                    "utterance_stamped 'Get the key' dropped: its stamp")]
    for msg, _ in stamped_bad:
        stamped.publish(msg)
    for _, line in plain + stamped_bad:
        assert node.wait_for_log(line, REPLY_S), (line, node.log_text()[-2000:])
    expected = {'observations_malformed': 6, 'observations_implausible_stamp': 1,
                'utterances_empty': 3, 'utterances_too_long': 3, 'utterances_non_ascii': 3,
                'utterances_malformed': 2, 'utterances_implausible_stamp': 1}

    def counted():
        line = counts_line(node, r'(callback_errors.*|observations.*); held')
        return line is not None and all(f'{k} {n}' in line for k, n in expected.items())

    assert wait_until(counted, REPLY_S), node.log_text()[-2000:]
    assert 'callback_errors' not in node.log_text()
    # And then it does its job.
    stamped.publish(stamped_utterance('Climb down the ladder.', T0))
    assert saliency.wait_for(lambda ms: any(stamp_to_ns(m.header.stamp) == T0 for m in ms),
                             REPLY_S), node.log_text()[-2000:]
    assert node.alive() and node.stop(signal.SIGINT) == 0


def test_feedback_node_survives_bad_positions_and_a_persons_bad_input(probe, start_node):
    trainer = start_node('feedback_node', {'summary_period': 0.5, 'utterance_interval': -1.0})
    positions = probe.publisher(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    feedback = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
    utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
    judged = probe.subscribe(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    for publisher in (positions, feedback, utterance):
        assert probe.wait_for_subscribers(publisher, timeout=STARTUP_S)

    def position(x, y, step):
        msg = PointStamped()
        msg.header.stamp = ns_to_stamp(T0 + step * NS_PER_S // 15)
        msg.point.x, msg.point.y, msg.point.z = x, y, 1.0
        return msg

    bad = [(math.nan, 235.0), (77.0, math.inf), (1e30, 235.0), (300.0, 235.0),
           (77.0, -5.0), (-1e308, 0.0)]
    for step, (x, y) in enumerate(bad):
        positions.publish(position(x, y, step))
    assert wait_until(lambda: trainer.log_text().count('agent_position dropped') == 6, REPLY_S)
    for step in range(6, 10):  # good positions after: judged
        positions.publish(position(77.0, 235.0, step))
    assert judged.wait_count(3, REPLY_S), trainer.log_text()[-2000:]
    assert wait_until(lambda: 'bad_positions 6' in (
        counts_line(trainer, r'counts: (.*)') or ''), REPLY_S)

    from test_feedback_topics import set_parameter
    set_parameter(probe, 'synthetic', False)
    assert trainer.wait_for_log('a person trains', REPLY_S)
    for value in (math.nan, math.inf, -math.inf, 5.0, -2.0, 1e30):
        feedback.publish(Float32(data=value))
    for text in ('', '   ', 'caf\u00e9', 'x' * 100_000, 'bell\x07',
                 'x' * (MAX_UTTERANCE_CHARS + 1)):
        utterance.publish(String(data=text))
    feedback.publish(Float32(data=1.0))
    utterance.publish(String(data='Move left.'))
    assert trainer.wait_for_log("a person said 'Move left.'", REPLY_S)
    assert trainer.wait_for_log('a person gave feedback +1', REPLY_S)
    log = trainer.log_text()
    assert log.count('bad feedback ignored') == 6 and log.count('bad utterance ignored') == 6
    assert wait_until(lambda: all(f'{k} 6' in (counts_line(trainer, r'counts: (.*)') or '')
                                  for k in ('bad_feedback', 'bad_utterances')), REPLY_S)
    assert trainer.alive() and trainer.stop(signal.SIGINT) == 0


def status_msg(stamp_ns, pairs, name=STATUS_NAME):
    msg = DiagnosticArray(status=[DiagnosticStatus(
        name=name, values=[KeyValue(key=k, value=v) for k, v in pairs])])
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def test_the_teacher_survives_bad_env_status_among_a_real_envs(probe, start_node):
    statuses = probe.subscribe(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
    observations = probe.subscribe(Image, topics.OBSERVATION, qos.FRAMES)
    actions = probe.publisher(Joy, topics.ACTION, qos.ACTIONS)
    injected = probe.publisher(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
    judged = probe.subscribe(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    trainer = start_node('feedback_node', {'trainer': 'teacher', 'summary_period': 0.5,
                                           'utterance_interval': -1.0})
    # env_node steps only once the teacher and the probe hear its env_status (a DDS match is per
    # writer: under load the teacher once heard the probe's statuses but none of the env's).
    env = start_node('env_node', {'warmup_steps': 0, 'action_timeout': 30.0,
                                  'wait_status_subscribers': 2})
    # The probe hears env_status itself: wait for the teacher too (2), or the bad statuses may
    # go out before the teacher has matched.
    assert probe.wait_for_subscribers(injected, count=2, timeout=STARTUP_S)
    assert probe.wait_for_subscribers(actions, timeout=STARTUP_S)
    assert probe.wait_matched(judged, timeout=STARTUP_S)  # volatile: judgements before it are lost

    def play(steps):
        for _ in range(steps):
            assert observations.wait_count(1, STARTUP_S)
            last = observations.snapshot()[-1]
            count = len(observations.snapshot())
            joy = Joy()
            joy.header = last.header
            axes, buttons = action_to_joy(0)
            joy.axes, joy.buttons = [float(a) for a in axes], [int(b) for b in buttons]
            actions.publish(joy)
            assert observations.wait_count(count + 1, REPLY_S), env.log_text()[-2000:]

    play(3)
    real = statuses.snapshot()[-1]
    pairs = [(kv.key, kv.value) for kv in real.status[0].values]
    stamp_ns = stamp_to_ns(real.header.stamp)

    def changed(key, value):
        return [(k, value if k == key else v) for k, v in pairs]

    bad = [status_msg(stamp_ns, []),
           status_msg(stamp_ns, pairs, name='other_node'),
           status_msg(stamp_ns, [(k, v) for k, v in pairs if k != 'pose']),
           status_msg(stamp_ns, changed('x', 'left')),
           status_msg(stamp_ns, changed('x', '300')),
           status_msg(stamp_ns, changed('y', '-7'))]
    before = len(judged.snapshot())
    for msg in bad:
        injected.publish(msg)
    assert wait_until(lambda: trainer.log_text().count('env_status dropped') == 6, REPLY_S), (
        trainer.log_text()[-2000:])
    assert wait_until(lambda: 'bad_status 6' in (counts_line(trainer, r'counts: (.*)') or ''),
                      REPLY_S)
    play(3)  # the real steps after them are judged
    assert judged.wait_count(before + 2, REPLY_S), trainer.log_text()[-2000:]
    assert trainer.alive() and env.alive()
    assert trainer.stop(signal.SIGINT) == 0 and env.stop(signal.SIGINT) == 0


FRAME_MB = 4000 * 4000 * 3 / 2 ** 20
"""The 4000x4000 rgb8 frame's pixels (45.8 MB)."""


def resident_mb(pid):
    return resident_memory_kb(pid)['VmRSS'] / 1024


@pytest.mark.parametrize('node_name', ['saliency_node', 'tamer_node'])
def test_a_huge_frame_leaves_no_lasting_memory(probe, start_node, tmp_path, node_name):
    """A 48 MB frame is dropped, and the node does not stay 46 MB larger (dds_memory)."""
    tamer = node_name == 'tamer_node'
    params = ({'run_dir': str(tmp_path / 'run'), 'metrics_period_s': 0.2} if tamer
              else {'status_period': 0.2})
    node = start_node(node_name, params)
    observation = probe.publisher(Image, topics.OBSERVATION, qos.FRAMES)
    metrics = probe.subscribe(DiagnosticArray, topics.METRICS, qos.METRICS)
    assert probe.wait_for_subscribers(observation, timeout=STARTUP_S)
    assert node.wait_for_log('ready', STARTUP_S)
    # A good one first, handled whole before memory is read (the learner's first forward pass
    # allocates tens of MB: measured after it, or the test measures torch, not the frame).
    observation.publish(image(frame(), T0))
    if tamer:  # metrics come periodically: no message is missed while DDS matches
        assert metrics.wait_for(lambda ms: bool(ms) and any(
            kv.key == 'act/count' and float(kv.value) >= 1
            for kv in ms[-1].status[0].values), REPLY_S), node.log_text()[-2000:]
    else:
        assert node.wait_for_log('observations 1', REPLY_S), node.log_text()[-2000:]
    before = resident_mb(node.process.pid)
    for i in range(2):
        observation.publish(image(np.zeros((4000, 4000, 3), np.uint8), T0 + i + 1))
    assert wait_until(lambda: node.log_text().count('size 4000x4000') == 2, REPLY_S)

    def grown():
        return resident_mb(node.process.pid) - before

    # A frame kept costs 46 MB, two 92; the node's own first seconds (torch, the learner
    # thread) have added up to 30 MB on a loaded CI machine, so the line is one frame. Lasting:
    # a frame still on its way out when the drop is logged (46.2 MB once, on a CI machine) is
    # given a few seconds to be freed; one kept for good never is.
    assert wait_until(lambda: grown() < FRAME_MB, 5.0), f'{node_name} grew {grown():.1f} MB'
    assert 'XMLPARSER' not in node.log_text()  # the profile loaded whole
    assert node.stop(signal.SIGINT) == 0

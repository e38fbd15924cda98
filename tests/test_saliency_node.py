"""The real saliency_node executable, talked to over topics only."""

import shutil

from attention_common import qos, topics
from attention_common.image_codec import image_to_numpy, numpy_to_image
from attention_common.stamps import NS_PER_S, ns_to_stamp, stamp_to_ns
from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from harness import wait_until
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from saliency_node.manifest import load_manifest
from sensor_msgs.msg import Image
from std_msgs.msg import String

pytestmark = pytest.mark.topics
AGENT_COLOURS = [(200, 72, 72), (210, 182, 86), (228, 111, 111)]


@pytest.fixture(scope='module')
def frames():
    env = MontezumaEnv(EnvConfig(warmup_steps=0))
    step = env.reset()
    shots = [step.observation]
    for action in (0, 0, 5, 5, 5, 5, 5, 5):  # wait, then climb down the middle ladder
        step = env.step(action)
        shots.append(step.observation)
    env.close()
    return shots


def image_msg(array, stamp_ns, encoding='rgb8'):
    msg = numpy_to_image(array, encoding, Image())
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = 'atari'
    return msg


def stamped_utterance(text, stamp_ns):
    msg = DiagnosticArray()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.status = [DiagnosticStatus(name='utterance', message=text,
                                   hardware_id='synthetic_trainer')]
    return msg


class Wiring:
    """Publishers into the node and logs of what it publishes."""

    def __init__(self, probe):
        self.observation = probe.publisher(Image, topics.OBSERVATION, qos.FRAMES)
        self.utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
        self.stamped = probe.publisher(DiagnosticArray, topics.UTTERANCE_STAMPED, qos.HUMAN)
        self.saliency = probe.subscribe(Image, topics.SALIENCY, qos.FRAMES)
        self.mask = probe.subscribe(Image, topics.SALIENCY_MASK, qos.FRAMES)
        for publisher in (self.observation, self.utterance, self.stamped):
            assert probe.wait_for_subscribers(publisher, timeout=20.0)
        assert probe.wait_for_publishers(topics.SALIENCY, timeout=20.0)

    def say(self, text):
        self.utterance.publish(String(data=text))

    def stamps(self, log):
        return [stamp_to_ns(m.header.stamp) for m in log.snapshot()]

    def wait_stamp(self, log, stamp_ns, timeout=15.0):
        return log.wait_for(lambda ms: any(stamp_to_ns(m.header.stamp) == stamp_ns for m in ms),
                            timeout)


def set_parameter(probe, name, value):
    client = AsyncParameterClient(probe.node, 'saliency_node')
    assert client.wait_for_services(timeout_sec=10.0)
    future = client.set_parameters([Parameter(name, value=value)])
    assert wait_until(future.done, 10.0)
    return future.result().results[0]


def test_observation_and_utterance_in_saliency_out_bad_input_survived(start_node, probe,
                                                                      frames):
    node = start_node('saliency_node', {'utterance_ttl': 10.0},
                      ros_args=['--log-level', 'saliency_node:=debug'])
    wire = Wiring(probe)
    t1 = 7 * NS_PER_S

    # An observation before any utterance is held; a person's utterance is stamped with it.
    wire.observation.publish(image_msg(frames[4], t1))
    assert node.wait_for_log('no utterance valid', 15.0), node.log_text()[-2000:]
    wire.say('Climb down the ladder and avoid the skull')
    assert wire.wait_stamp(wire.saliency, t1), node.log_text()[-2000:]
    [saliency] = [m for m in wire.saliency.snapshot() if stamp_to_ns(m.header.stamp) == t1]
    assert saliency.encoding == 'rgb8' and (saliency.height, saliency.width) == (210, 160)
    assert saliency.header.frame_id == 'atari'
    image = image_to_numpy(saliency)
    agent = np.zeros((210, 160), bool)
    for colour in AGENT_COLOURS:
        agent |= np.all(frames[4] == colour, axis=2)
    agent[:44] = False
    assert agent.sum() > 50 and np.array_equal(image[agent], frames[4][agent])
    assert (image != frames[4]).any(axis=2).sum() > 1000  # the rest is blurred
    assert wire.wait_stamp(wire.mask, t1)
    mask = [m for m in wire.mask.snapshot() if stamp_to_ns(m.header.stamp) == t1][0]
    assert mask.encoding == 'mono8' and set(np.unique(image_to_numpy(mask))) == {0, 255}

    # A stamped utterance that arrives after its observation still gets it a saliency image.
    t2 = t1 + 30 * NS_PER_S  # the person's utterance has expired by then
    wire.observation.publish(image_msg(frames[5], t2))
    assert node.wait_for_log('no utterance valid at 37.000s', 15.0)
    wire.stamped.publish(stamped_utterance('Jump up to get the key.', t2))
    assert wire.wait_stamp(wire.saliency, t2), node.log_text()[-2000:]

    # Bad input: logged, dropped, counted; the node keeps running.
    wire.observation.publish(image_msg(frames[5][:, :, 0].copy(), t2 + 1, 'mono8'))
    wire.observation.publish(image_msg(np.zeros((100, 100, 3), np.uint8), t2 + 2))
    truncated = image_msg(frames[5], t2 + 3)
    truncated.data = truncated.data[:5000]
    wire.observation.publish(truncated)
    wire.say('x' * 100_000)
    wire.say('')
    wire.say(' \t\n ')
    wire.say('\U0001F642\U0001F642')
    wire.stamped.publish(stamped_utterance('Cl\u00edmb the l\u00e4dder', t2 + 4))
    wire.stamped.publish(DiagnosticArray())
    for expected in ("encoding 'mono8', rgb8 expected", 'size 100x100, 160x210 expected',
                     'data has 5000 bytes', '100000 characters',
                     'empty or only whitespace', 'no ASCII words',
                     "non-ASCII characters; using 'Climb the ladder'",
                     'status[0].name must be "utterance"'):
        assert node.wait_for_log(expected, 10.0), f'{expected!r} not logged'
    assert node.alive()
    t3 = t2 + NS_PER_S
    wire.observation.publish(image_msg(frames[6], t3))
    assert wire.wait_stamp(wire.saliency, t3), node.log_text()[-2000:]
    assert not {t2 + 1, t2 + 2, t2 + 3} & set(wire.stamps(wire.saliency))

    # Modes switch at run time; `ros2 param set ... mode off` arrives as a boolean false.
    assert not set_parameter(probe, 'mode', 'loud').successful
    assert set_parameter(probe, 'mode', False).successful
    t4, t5 = t3 + NS_PER_S, t3 + 2 * NS_PER_S
    wire.observation.publish(image_msg(frames[7], t4))
    assert set_parameter(probe, 'mode', 'blind_agent').successful
    wire.observation.publish(image_msg(frames[8], t5))
    assert wire.wait_stamp(wire.saliency, t5), node.log_text()[-2000:]
    assert t4 not in wire.stamps(wire.saliency)  # off: nothing published
    assert node.stop() == 0


def test_the_trainers_plain_copy_is_not_used_twice(start_node, probe, frames):
    node = start_node('saliency_node', ros_args=['--log-level', 'saliency_node:=debug'])
    wire = Wiring(probe)
    t1 = 3 * NS_PER_S
    wire.observation.publish(image_msg(frames[0], t1))
    assert node.wait_for_log('no utterance valid', 15.0)
    text = 'Move left and avoid the skull.'
    wire.say(text)  # the copy can arrive first...
    assert node.wait_for_log(f"utterance at now: '{text}'", 10.0)
    wire.stamped.publish(stamped_utterance(text, t1))  # ...then the original
    assert node.wait_for_log('stamped one: withdrawn', 10.0), node.log_text()[-2000:]
    wire.say(text)  # a copy after the original
    assert node.wait_for_log('is the copy of the stamped one just heard', 10.0)
    assert wire.wait_stamp(wire.saliency, t1)
    # A person's other words while the trainer's stream is active are heard, not muted.
    wire.say('Jump over the skull')
    assert node.wait_for_log("utterance at now: 'Jump over the skull'", 10.0), (
        node.log_text()[-2000:])
    assert node.log_text().count('used once') == 1
    assert node.stop() == 0


def test_mode_off_from_the_command_line_and_sigint(start_node):
    node = start_node('saliency_node', ros_args=['-p', 'mode:=off'])  # YAML: boolean false
    assert node.wait_for_log('ready: mode off', 20.0), node.log_text()[-2000:]
    assert node.stop() == 0


def test_a_missing_template_file_stops_start_up_with_its_name(start_node, tmp_path):
    folder = tmp_path / 'templates'
    shutil.copytree(load_manifest().folder, folder)
    (folder / 'ladder.png').unlink()
    node = start_node('saliency_node', {'templates_manifest': str(folder / 'manifest.yaml')})
    assert wait_until(lambda: not node.alive(), 20.0)
    assert node.process.returncode == 1
    assert 'ladder.png' in node.log_text()

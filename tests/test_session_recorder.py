"""session_recorder as a process, over topics: what it records, and a SIGKILL's cost."""

import json
import signal
import time

from attention_common import qos
from harness import wait_until
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader as RosbagsReader
from sensor_msgs.msg import Image
from session_bag import metadata
from session_bag.reader import BagReader
from session_bag.repair import repair
from std_msgs.msg import Float32, String

FLUSH_PERIOD_S = 0.5


def _image(i: int) -> Image:
    pixels = np.full((210, 160, 3), i % 256, np.uint8)
    return Image(height=210, width=160, encoding='rgb8', step=480, data=pixels.tobytes())


def _start(start_node, bag_dir, **params):
    recorder = start_node('session_recorder', {'bag_dir': str(bag_dir), **params})
    assert recorder.wait_for_log('recording', 30.0), recorder.log_text()
    return recorder


@pytest.mark.topics
def test_the_recorder_keeps_every_message_with_its_type_qos_and_the_run(
        start_node, probe, tmp_path):
    run_dir = tmp_path / 'run'
    run_dir.mkdir()
    (run_dir / 'launch_options.json').write_text(json.dumps({'condition': 'vanilla'}))
    (run_dir / 'params.yaml').write_text('tamer_node:\n  ros__parameters:\n    alpha: 0.0\n')
    recorder = _start(start_node, run_dir / 'bag', run_dir=str(run_dir))
    # The graph's frame writers keep 100 frames for a reader that fell behind (qos.FRAMES_WRITER;
    # with 10, a recorder under the full test suite's load once kept 48 of 100 frames at 200 Hz).
    images = probe.publisher(Image, 'observation', qos.FRAMES_WRITER)
    words = probe.publisher(String, 'utterance', qos.HUMAN)
    feedback = probe.publisher(Float32, 'feedback', qos.HUMAN)
    for publisher in (images, words, feedback):
        assert probe.wait_for_subscribers(publisher, 1, 10.0)
    # Each end of a match is made on its own: a volatile reader that matches after our writer
    # did starts after what was already sent (under the suite's load it once missed the first
    # 2 of 10 words). The recorder's end cannot be seen from here; give it a moment.
    time.sleep(1.0)
    for i in range(100):
        feedback.publish(Float32(data=1.0 if i % 2 else -1.0))  # a burst, as a person's keys
    for i in range(100):  # frames at 200 Hz, the lockstep graph's pace (their writers keep 10)
        images.publish(_image(i))
        if i % 10 == 0:
            words.publish(String(data=f'climb down the ladder {i}'))
        time.sleep(0.005)
    time.sleep(1.0)
    assert recorder.stop(signal.SIGINT) == 0
    bag = run_dir / 'bag'
    with RosbagsReader(bag) as reader:
        found = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        qos_of = {c.topic: c.ext.offered_qos_profiles[0] for c in reader.connections}
        texts = [deserialize_message(raw, String).data for c, _, raw in reader.messages()
                 if c.topic == '/utterance']
    assert found == {'/observation': ('sensor_msgs/msg/Image', 100),
                     '/utterance': ('std_msgs/msg/String', 10),
                     '/feedback': ('std_msgs/msg/Float32', 100)}
    assert texts == [f'climb down the ladder {i}' for i in range(0, 100, 10)]
    assert {q.reliability.name for q in qos_of.values()} == {'RELIABLE'}  # the publishers'
    custom = metadata.read(bag)['custom_data']
    assert json.loads(custom['attention.launch_options']) == {'condition': 'vanilla'}
    assert 'alpha: 0.0' in custom['attention.params']
    assert 'bag closed: 210 messages' in recorder.log_text()


@pytest.mark.topics
def test_a_recorder_killed_with_sigkill_loses_at_most_the_last_second(
        start_node, probe, tmp_path):
    bag = tmp_path / 'bag'
    recorder = _start(start_node, bag, flush_period_s=FLUSH_PERIOD_S)
    images = probe.publisher(Image, 'observation', qos.FRAMES)
    assert probe.wait_for_subscribers(images, 1, 10.0)
    sent_at = []
    start = time.monotonic()
    while time.monotonic() - start < 3.0:  # 3 s at 50 Hz, killed in the middle of it
        images.publish(_image(len(sent_at)))
        sent_at.append(time.time_ns())
        time.sleep(0.02)
        if time.monotonic() - start > 2.0 and recorder.alive():
            killed_at = time.time_ns()
            recorder.process.send_signal(signal.SIGKILL)
    assert recorder.stop(signal.SIGKILL) == -signal.SIGKILL
    reader = BagReader(bag)
    times = [m.log_time for m in reader.messages()]
    assert reader.complete is False  # no footer: it was killed
    assert times == sorted(times) and len(times) >= 50
    assert killed_at - times[-1] <= 1e9, 'more than the last second was lost'
    before = sum(t <= killed_at - 1e9 for t in sent_at)
    assert len(times) >= before  # everything sent over a second before the kill is there
    # metadata.yaml was there all along (at most one flush behind), and the repair makes the
    # bag whole for every rosbag2 reader.
    assert 0 < metadata.read(bag)['message_count'] <= len(times)
    assert repair(bag).messages == len(times)
    with RosbagsReader(bag) as whole:
        assert whole.message_count == len(times)
        last = max(t for _, t, _ in whole.messages())
    assert last == times[-1]


@pytest.mark.topics
def test_a_bad_setting_or_a_used_folder_is_refused_with_a_clear_error(start_node, tmp_path):
    bad = start_node('session_recorder', {'bag_dir': str(tmp_path / 'a'),
                                          'compression': 'gzip'}, name='bad')
    assert wait_until(lambda: not bad.alive(), 30.0)
    assert bad.process.returncode == 1 and 'compression must be one of' in bad.log_text()
    used = tmp_path / 'used'
    used.mkdir()
    (used / 'x.mcap').write_bytes(b'')
    refused = start_node('session_recorder', {'bag_dir': str(used)}, name='used')
    assert wait_until(lambda: not refused.alive(), 30.0)
    assert refused.process.returncode == 1 and 'never overwritten' in refused.log_text()

"""The session bag's pure parts: writing, reading (whole or cut short), repair, replay items."""

import json
from pathlib import Path
import shutil
import sys
import time

from attention_bringup.replay.cli import send_until_answered
from attention_bringup.replay.plan import build_plan, ReplayOptions
from attention_bringup.replay.session import (
    Agreement, header_stamp_ns, LOOKAHEAD_OBSERVATIONS, replay_items)
from attention_common import qos
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mcap.reader import make_reader
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.rosbag2 import Reader as RosbagsReader
from sensor_msgs.msg import Image, Joy
from session_bag import metadata
from session_bag.reader import BagMessage, BagReader
from session_bag.recorded import RECORDED, type_name
from session_bag.repair import repair
from session_bag.schema import definition
from session_bag.writer import BagWriter
from std_msgs.msg import String
import yaml

VENV_SHARE = Path(sys.prefix) / 'share'


def _image(stamp_ns: int) -> Image:
    image = Image(height=2, width=2, encoding='rgb8', step=6, data=bytes(range(12)))
    image.header.stamp.sec, image.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    return image


def _joy(stamp_ns: int, fire: int = 1) -> Joy:
    joy = Joy(axes=[0.0, 0.0], buttons=[fire])
    joy.header.stamp.sec, joy.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    return joy


def _writer(bag_dir: Path, custom=None) -> BagWriter:
    writer = BagWriter(bag_dir, custom_data=custom)
    writer.add_topic('/observation', 'sensor_msgs/msg/Image', [metadata.qos_dict(qos.FRAMES)])
    writer.add_topic('/utterance', 'std_msgs/msg/String', [metadata.qos_dict(qos.HUMAN)])
    return writer


def test_a_written_bag_reads_back_with_rosbags_as_rosbag2_does(tmp_path):
    bag = tmp_path / 'bag'
    writer = _writer(bag, {'attention.launch_options': '{"condition": "vanilla"}'})
    for i in range(50):
        writer.write('/observation', 1_000 + i, serialize_message(_image(i * 10**8)))
        if i % 10 == 0:
            writer.write('/utterance', 1_000 + i, serialize_message(String(data=f'key {i}')))
    writer.close()
    assert sorted(p.name for p in bag.iterdir()) == ['bag_0.mcap', 'metadata.yaml']
    # An independent rosbag2 implementation reads metadata.yaml and the MCAP file.
    with RosbagsReader(bag) as reader:
        assert {c.topic: (c.msgtype, c.msgcount) for c in reader.connections} == {
            '/observation': ('sensor_msgs/msg/Image', 50),
            '/utterance': ('std_msgs/msg/String', 5)}
        qos_of = {c.topic: c.ext.offered_qos_profiles[0] for c in reader.connections}
        assert qos_of['/utterance'].history.name == 'KEEP_ALL'
        assert qos_of['/observation'].reliability.name == 'RELIABLE'
        assert reader.ros_distro == 'jazzy'
        texts = [deserialize_message(raw, String).data for c, _, raw in reader.messages()
                 if c.topic == '/utterance']
    assert texts == [f'key {i}' for i in range(0, 50, 10)]
    info = metadata.read(bag)
    assert info['custom_data'] == {'attention.launch_options': '{"condition": "vanilla"}'}
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['message_count'] == 55 and info['relative_file_paths'] == ['bag_0.mcap']
    # What Foxglove and rosbag2's MCAP plugin look for.
    with open(bag / 'bag_0.mcap', 'rb') as stream:
        mcap = make_reader(stream)
        assert mcap.get_header().profile == 'ros2'
        summary = mcap.get_summary()
    assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}
    channels = list(summary.channels.values())
    assert {c.message_encoding for c in channels} == {'cdr'}
    assert all(c.metadata['topic_type_hash'].startswith('RIHS01_') for c in channels)
    assert all(yaml.safe_load(c.metadata['offered_qos_profiles']) for c in channels)


@pytest.mark.parametrize('topic', RECORDED, ids=lambda t: t.name)
def test_every_recorded_type_has_the_definition_and_hash_of_the_installed_ros(topic):
    name = type_name(topic.msg_type)
    package, _, short = name.split('/')
    described = json.loads((VENV_SHARE / package / 'msg' / f'{short}.json').read_text())
    installed = {h['type_name']: h['hash_string'] for h in described['type_hashes']}
    found = definition(name)
    assert found.type_hash == installed[name]
    assert found.text.startswith((VENV_SHARE / package / 'msg' / f'{short}.msg').read_text()
                                 .strip().splitlines()[0].split('#')[0].strip() or '')


def test_a_bag_is_never_overwritten(tmp_path):
    bag = tmp_path / 'bag'
    _writer(bag).close()
    with pytest.raises(FileExistsError):
        BagWriter(bag)


def test_a_bag_cut_short_after_a_flush_keeps_everything_flushed_and_is_repaired(tmp_path):
    bag = tmp_path / 'bag'
    writer = _writer(bag, {'k': 'v'})
    for i in range(30):
        writer.write('/observation', 10**9 + i, serialize_message(_image(i)))
    writer.flush()  # what a SIGKILL right now leaves on disk: the flushed chunks, no footer
    cut = tmp_path / 'cut'
    shutil.copytree(bag, cut)
    for i in range(30, 40):  # written after the flush: in memory only
        writer.write('/observation', 10**9 + i, serialize_message(_image(i)))
    writer.close()

    reader = BagReader(cut)
    stamps = [header_stamp_ns(m.data) for m in reader.messages()]
    assert stamps == list(range(30)) and reader.complete is False
    assert metadata.topic_counts(metadata.read(cut))['/observation'] == 30
    with pytest.raises(Exception):  # a reader that needs the footer refuses it as it is
        with RosbagsReader(cut) as whole:
            list(whole.messages())
    result = repair(cut)
    assert (result.was_complete, result.messages) == (False, 30)
    with RosbagsReader(cut) as whole:
        assert whole.message_count == 30
    assert metadata.read(cut)['custom_data'] == {'k': 'v'}
    with RosbagsReader(cut) as whole:
        assert [header_stamp_ns(raw) for _, _, raw in whole.messages()] == list(range(30))
    assert repair(cut).was_complete is True  # repairing twice changes nothing
    reader = BagReader(bag)
    assert len(list(reader.messages())) == 40 and reader.complete is True


def test_a_torn_last_chunk_is_dropped_not_misread(tmp_path):
    bag = tmp_path / 'bag'
    writer = _writer(bag)
    sizes = []
    for i in range(20):
        writer.write('/observation', 10**9 + i, serialize_message(_image(i)))
        if i in (9, 19):
            writer.flush()
            sizes.append((bag / 'bag_0.mcap').stat().st_size)
    data = (bag / 'bag_0.mcap').read_bytes()[:sum(sizes) // 2]  # the second chunk half on disk
    (bag / 'bag_0.mcap').write_bytes(data)
    reader = BagReader(bag)
    assert [header_stamp_ns(m.data) for m in reader.messages()] == list(range(10))
    assert reader.complete is False and reader.problem


def test_a_file_cut_anywhere_reads_up_to_the_cut_and_never_raises(tmp_path):
    bag = tmp_path / 'bag'
    writer = _writer(bag)
    for i in range(12):
        writer.write('/observation', 10**9 + i, serialize_message(_image(i)))
        if i % 4 == 3:
            writer.flush()
    writer.close()
    whole = (bag / 'bag_0.mcap').read_bytes()
    for cut in range(0, len(whole), 3):
        (bag / 'bag_0.mcap').write_bytes(whole[:cut])
        reader = BagReader(bag)
        stamps = [header_stamp_ns(m.data) for m in reader.messages()]
        assert stamps == list(range(len(stamps))), cut  # a prefix, in order
        # (cut within the last bytes, after the footer: every message is there)
        assert (reader.complete is False and reader.problem) or len(stamps) == 12, cut


def test_header_stamps_are_read_from_the_cdr_bytes():
    assert header_stamp_ns(serialize_message(_image(12_345_678_901))) == 12_345_678_901
    assert header_stamp_ns(serialize_message(_joy(7))) == 7
    with pytest.raises(ValueError):
        header_stamp_ns(b'\x00\x01')  # (attention_bringup.gallery's, shared)


def _message(topic, t, msg):
    return BagMessage(topic, '', t, t, serialize_message(msg))


def _status(stamp_ns: int, action: int) -> DiagnosticArray:
    """env_node's env_status of step ``stamp_ns``, reached with task action ``action``."""
    status = DiagnosticStatus(name='env_node', values=[
        KeyValue(key='agent_step', value='1'), KeyValue(key='action', value=str(action))])
    array = DiagnosticArray(status=[status])
    array.header.stamp.sec, array.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    return array


def test_each_observation_carries_what_was_executed_on_it_and_the_order_is_kept():
    messages = [
        _message('/env_status', 0, _status(100, -1)),  # the first step: no action led here
        _message('/observation', 1, _image(100)),
        _message('/feedback', 2, String(data='x')),  # (the type does not matter here)
        _message('/action', 3, _joy(100)),
        _message('/observation', 4, _image(200)),
        _message('/env_status', 5, _status(200, 1)),  # executed on step 100: FIRE
        _message('/utterance', 6, String(data='get the key')),
        _message('/observation', 7, _image(300)),
        _message('/action', 8, _joy(200)),
        # Real time: the answer to 200 came late; the env executed the newest one it had (0).
        _message('/env_status', 9, _status(300, 0)),
        _message('/action', 10, _joy(300, fire=0)),
    ]
    items = list(replay_items(messages))
    assert [(i.topic, i.log_time) for i in items] == [
        ('observation', 1), ('feedback', 2), ('observation', 4), ('utterance', 6),
        ('observation', 7)]
    steps = [i for i in items if i.topic == 'observation']
    assert [i.stamp for i in steps] == [100, 200, 300]
    assert [i.executed for i in steps] == [1, 0, None]  # the last step's is not known yet
    answers = [deserialize_message(i.answered, Joy).buttons[0] for i in steps]
    assert answers == [1, 1, 0]


def test_steps_a_loaded_recorder_logged_late_still_carry_their_actions():
    # Measured in a recorded run under load: observations logged in a burst after their
    # answers and the next steps' env_status (each topic in order, not across topics).
    messages = [_message('/env_status', 0, _status(100, -1))]
    for k, stamp in enumerate((200, 300, 400)):  # executed on 100, 200, 300: 2, 0, 1
        messages += [_message('/action', 1 + 2 * k, _joy(stamp - 100, fire=k % 2)),
                     _message('/env_status', 2 + 2 * k, _status(stamp, (2, 0, 1)[k]))]
    messages += [_message('/observation', 10 + k, _image(stamp))
                 for k, stamp in enumerate((100, 200, 300, 400))]
    messages += [_message('/action', 20, _joy(400)), _message('/env_status', 21, _status(500, 2))]
    steps = list(replay_items(messages))
    assert [i.stamp for i in steps] == [100, 200, 300, 400]
    assert [i.executed for i in steps] == [2, 0, 1, 2]
    answers = [deserialize_message(i.answered, Joy).buttons[0] for i in steps]
    assert answers == [0, 1, 0, 1]


def test_a_step_whose_next_status_never_comes_is_sent_all_the_same():
    messages = [_message('/observation', 0, _image(0))]  # an episode's last step, say
    for k in range(1, 12):
        messages += [_message('/observation', k, _image(k * 10)),
                     _message('/env_status', k, _status(k * 10 + 1, k % 3))]
    items = list(replay_items(messages))
    assert [i.stamp for i in items] == [0] + [k * 10 for k in range(1, 12)]
    # Each status names the newest step before it (11 -> step 10, ...): step 0 has none, and
    # goes once LOOKAHEAD_OBSERVATIONS more steps came.
    assert [i.executed for i in items] == [None] + [k % 3 for k in range(1, 12)]
    assert LOOKAHEAD_OBSERVATIONS < 11


def test_agreement_counts_only_steps_both_acted_on():
    agreement = Agreement()
    for session, replayed in [(1, 1), (2, 3), (None, 1), (4, None), (5, 5), (6, 6), (7, 0),
                              (8, 8)]:
        agreement.add(0, session, replayed)
    summary = agreement.summary()
    assert summary['compared'] == 6 and summary['agreement'] == round(4 / 6, 4)
    assert summary['unanswered'] == 1 and summary['without_session_action'] == 1
    assert summary['agreement_last_quarter'] == 0.5  # steps 7, 8: (7, 0), (8, 8)
    # Windows of two steps; the second compares nothing, so it has no point.
    assert [p['step'] for p in agreement.curve(windows=4)] == [2, 6, 8]


def test_a_replay_takes_the_sessions_parameters_and_the_chosen_condition(tmp_path):
    session_params = ('tamer_node:\n  ros__parameters:\n    credit: window\n'
                      '    window_max_s: 1.6\n    alpha: 0.0001\n'
                      '    run_dir: /elsewhere\n    seed: 7\n    explore: 0.1\n'
                      '    wait_for_recorder: session_recorder\n'
                      'saliency_node:\n  ros__parameters:\n    mode: language\n'
                      '    wait_for_recorder: session_recorder\n')
    writer = _writer(tmp_path / 'run' / 'bag', {
        'attention.launch_options': json.dumps({'condition': 'language', 'task': 'montezuma'}),
        'attention.params': session_params})
    writer.close()
    plan = build_plan(ReplayOptions(bag=str(tmp_path / 'run'), condition='blind_obs'),
                      tmp_path / 'bin', tmp_path)
    tamer, saliency = plan.params['tamer_node'], plan.params['saliency_node']
    assert plan.bag_dir == tmp_path / 'run' / 'bag' and plan.condition == 'blind_obs'
    assert (tamer['credit'], tamer['window_max_s'], tamer['seed']) == ('window', 1.6, 7)
    assert (tamer['alpha'], tamer['input_image'], saliency['mode']) == (
        0.0, 'saliency', 'blind_agent')  # the condition's file wins over the session's
    assert tamer['run_dir'] == str(plan.run_dir) and tamer['resume'] is False
    # Nothing records a replay, and its answers are greedy (compared with the session's).
    assert tamer.get('wait_for_recorder', '') == saliency.get('wait_for_recorder', '') == ''
    assert tamer['explore'] == 0.0
    assert '-replay-blind_obs-seed7' in plan.run_dir.name
    same = build_plan(ReplayOptions(bag=str(tmp_path / 'run'), run_dir='r'), tmp_path / 'b',
                      tmp_path)
    assert same.condition == 'language' and same.params['tamer_node']['alpha'] == 0.0001
    with pytest.raises(ValueError, match='neither a bag folder'):
        build_plan(ReplayOptions(bag=str(tmp_path)), tmp_path / 'bin', tmp_path)


def test_a_synced_flush_puts_the_flushed_bag_on_disk_first(tmp_path, monkeypatch):
    import os
    durable = []
    real = os.fdatasync

    def fdatasync(fd):
        real(fd)
        durable.append(os.fstat(fd).st_size)

    monkeypatch.setattr(os, 'fdatasync', fdatasync)
    writer = BagWriter(tmp_path / 'bag', sync=True)
    writer.add_topic('/utterance', 'std_msgs/msg/String', [metadata.qos_dict(qos.HUMAN)])
    writer.write('/utterance', 1_000, serialize_message(String(data='climb down')))
    writer.flush()
    assert writer.syncs == 1 and durable == [(tmp_path / 'bag' / 'bag_0.mcap').stat().st_size]
    unsynced = BagWriter(tmp_path / 'other')
    unsynced.flush()
    assert unsynced.syncs == 0 and len(durable) == 1
    writer.close()
    unsynced.close()


def test_a_step_the_learner_did_not_answer_is_sent_again_until_it_does():
    # CI: a replay's first observation went before the learner's reader had matched its
    # writer, so it never came and the step counted unanswered after 10 s.
    sent, waits = [], []

    def wait(seconds):
        waits.append(seconds)
        return len(sent) >= 3  # the third copy is answered
    assert send_until_answered(lambda: sent.append(1), wait, timeout_s=10.0, resend_s=0.01) == 3
    assert waits == [0.01, 0.01, 0.01]
    # An answer to the first copy: sent once. None at all: it stops at the timeout.
    assert send_until_answered(lambda: None, lambda s: True, 10.0, 0.01) == 1
    assert 3 <= send_until_answered(lambda: None, lambda s: time.sleep(s), 0.05, 0.01) <= 6

"""A recorded training run, its bag read back, and the session replayed into a fresh learner."""

import bisect
import csv
import json
from pathlib import Path
import subprocess
import sys

import pytest
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader as RosbagsReader
from sensor_msgs.msg import Image
import yaml

BIN = Path(sys.executable).parent
STEPS = 300
TYPES = {
    '/observation': 'sensor_msgs/msg/Image', '/saliency': 'sensor_msgs/msg/Image',
    '/saliency_mask': 'sensor_msgs/msg/Image', '/action': 'sensor_msgs/msg/Joy',
    '/feedback_stamped': 'geometry_msgs/msg/Vector3Stamped',
    '/utterance': 'std_msgs/msg/String',
    '/utterance_stamped': 'diagnostic_msgs/msg/DiagnosticArray',
    '/feedback_logged': 'diagnostic_msgs/msg/DiagnosticArray',
    '/feedback_credit': 'diagnostic_msgs/msg/DiagnosticArray',
    '/agent_position': 'geometry_msgs/msg/PointStamped',
    '/env_status': 'diagnostic_msgs/msg/DiagnosticArray',
    '/metrics': 'diagnostic_msgs/msg/DiagnosticArray', '/clock': 'rosgraph_msgs/msg/Clock',
}
"""Every topic a run with the synthetic trainer publishes (a person's plain feedback and
action_taken have no publisher here)."""


def _json(path: Path) -> dict:
    return json.loads(path.read_text())


@pytest.fixture(scope='module')
def recorded_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp('recorded') / 'run'
    result = subprocess.run([str(BIN / 'attention_train'), '--steps', str(STEPS), '--record',
                             '--seed', '4', '--run-dir', str(run_dir)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-4000:]
    return run_dir, result


@pytest.mark.topics
def test_a_recorded_run_leaves_a_bag_that_rosbag2_readers_open(recorded_run):
    run_dir, result = recorded_run
    summary = _json(run_dir / 'summary.json')
    assert summary['exit_codes']['session_recorder'] == 0
    assert summary['bag']['dir'] == 'bag' and summary['bag']['repaired'] is False
    assert 'bag: ' in result.stdout.splitlines()[-1]
    with RosbagsReader(run_dir / 'bag') as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        counts = {c.topic: c.msgcount for c in reader.connections}
        frame = next(raw for c, _, raw in reader.messages() if c.topic == '/observation')
        reliability = {c.topic: c.ext.offered_qos_profiles[0].reliability.name
                       for c in reader.connections}
    assert types == TYPES
    assert counts == summary['bag']['topics']
    # The bag heard every judgement and every word the learner logged (the trainer waits for
    # the recorder as for the learner), every step and its answer, and never less than the
    # launcher's monitor heard (which may miss a topic's first messages under load).
    logged = summary['learner_log']
    assert counts['/feedback_stamped'] == logged['feedback'] == summary['feedback_count']
    assert counts['/utterance'] == logged['utterances'] == counts['/utterance_stamped'] >= 1
    assert counts['/feedback_logged'] == logged['feedback'] + logged['utterances']
    assert 1 <= counts['/feedback_credit'] <= logged['feedback']  # one per feedback learned from
    assert counts['/observation'] >= STEPS and counts['/action'] == counts['/observation']
    assert counts['/env_status'] > summary['steps']  # one per step, and at each episode's start
    for topic, heard in summary['message_counts'].items():
        if topic != 'metrics':  # (the learner's metrics timer runs from its start, unwaited)
            assert counts.get(f'/{topic}', 0) >= heard, topic
    assert set(reliability.values()) == {'RELIABLE'}
    image = deserialize_message(frame, Image)
    assert (image.height, image.width, image.encoding) == (210, 160, 'rgb8')
    custom = yaml.safe_load((run_dir / 'bag' / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']['custom_data']
    assert json.loads(custom['attention.launch_options'])['seed'] == 4


def _executed_actions(bag_dir: Path) -> dict:
    """
    Return step stamp -> the action the world executed on it.

    An env_status names the action that led to its step: that of the newest observation before.
    """
    from attention_bringup.gallery import cdr_header_stamp_ns
    from attention_bringup.replay.session import executed_action
    from session_bag.reader import BagReader
    observations, statuses = set(), []
    for message in BagReader(bag_dir).messages():
        if message.topic == '/observation':
            observations.add(cdr_header_stamp_ns(message.data))
        elif message.topic == '/env_status':
            found = executed_action(message.data)
            if found is not None and found[1] is not None:
                statuses.append(found)
    steps = sorted(observations)
    executed = {}
    for stamp, action in statuses:
        earlier = bisect.bisect_left(steps, stamp)
        if earlier:
            executed[steps[earlier - 1]] = action
    return executed


def _replay(run_dir: Path, out: Path, *options: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / 'attention_replay'), str(run_dir), '--run-dir', str(out),
                           '--quiet', *options], capture_output=True, text=True, timeout=300)


@pytest.mark.topics
def test_the_session_replays_into_a_fresh_learner_that_then_acts(recorded_run, tmp_path):
    run_dir, _ = recorded_run
    session = _json(run_dir / 'summary.json')
    result = _replay(run_dir, tmp_path / 'replay', '--fast')
    assert result.returncode == 0, result.stderr[-4000:]
    summary = _json(tmp_path / 'replay' / 'summary.json')
    bag = session['bag']['topics']
    assert summary['status'] == 'completed' and summary['condition'] == 'language'
    assert summary['exit_codes'] == {'saliency_node': 0, 'tamer_node': 0}
    # Every observation was answered by the new learner; every feedback and utterance logged,
    # each feedback on the very step the session's learner put it on.
    assert summary['steps'] == bag['/observation'] and summary['unanswered'] == 0
    # (under load the world may publish a step or two past the budget before it stops: the
    # session's agent never acted on those, so they cannot be compared)
    missing = summary['without_session_action']
    assert missing <= bag['/observation'] - session['steps']
    assert summary['compared'] == summary['steps'] - missing
    assert summary['receipts'] == bag['/feedback_stamped'] + bag['/utterance']
    same = summary['feedback_same_step']
    assert same['compared'] == bag['/feedback_stamped'] and same['same'] == same['compared']
    assert 0.0 <= summary['agreement'] <= 1.0 and summary['curve']
    assert int(summary['metrics']['act/taken']) == summary['steps'] - missing
    assert int(summary['metrics']['feedback/count']) > 0  # it learned from them
    with open(tmp_path / 'replay' / 'replay_steps.csv') as steps:
        rows = list(csv.DictReader(steps))
    assert len(rows) == summary['steps'] and all(r['replayed_action'] != '' for r in rows)
    # It learned every feedback on the action the session's agent executed on that step: the
    # world says it in the next step's env_status (read here by stamp, whatever the bag's order).
    from tamer_node.persistence import load_checkpoint
    executed = _executed_actions(run_dir / 'bag')
    buffer = load_checkpoint(tmp_path / 'replay')['buffer']
    count = min(int(buffer['added']), int(buffer['capacity']))
    learned = list(zip(buffer['columns']['stamps'][:count].tolist(),
                       buffer['columns']['actions'][:count].tolist()))
    assert len(learned) >= 0.5 * bag['/feedback_stamped']
    wrong = [(stamp, action, executed.get(stamp)) for stamp, action in learned
             if executed.get(stamp) != action]
    assert not wrong, f'{len(wrong)} of {len(learned)} (stamp, learned, executed): {wrong[:5]}'
    disagreed = sum(r['agree'] == '0' for r in rows)
    # (counted only once it happens: a learner that agreed on every step has no such counter)
    assert int(summary['metrics'].get('act/taken_differs', 0)) == disagreed
    assert (tmp_path / 'replay' / 'learning_curve.png').read_bytes()[:4] == b'\x89PNG'
    assert 'greedy actions agree' in result.stdout


@pytest.mark.topics
def test_another_condition_learns_from_the_same_recorded_feedback_in_a_replay_study(
        recorded_run, tmp_path):
    run_dir, _ = recorded_run
    out = tmp_path / 'study'
    command = [str(BIN / 'attention_replay'), str(run_dir), '--fast', '--conditions',
               'blind_obs', '--out', str(out)]
    result = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-4000:]
    blind = out / 'blind_obs' / 'seed4'  # (the session's seed)
    summary = _json(blind / 'summary.json')
    params = yaml.safe_load((blind / 'replay_params.yaml').read_text())
    assert params['tamer_node']['ros__parameters']['input_image'] == 'saliency'
    assert params['saliency_node']['ros__parameters']['mode'] == 'blind_agent'
    # The session waited for its recorder; a replay has none, so its nodes must not wait.
    assert all(params[node]['ros__parameters'].get('wait_for_recorder', '') == ''
               for node in ('saliency_node', 'tamer_node'))
    assert (summary['condition'], summary['session_condition']) == ('blind_obs', 'language')
    assert summary['unanswered'] == 0 and summary['feedback_same_step']['same'] > 0
    # The study ran on the experiment engine: a result file, the table, the report.
    record = _json(out / 'trials' / 'blind_obs' / 'seed4.json')
    assert record['outcome'] == 'completed' and record['steps'] == summary['steps']
    assert record['replay']['agreement'] == summary['agreement']
    assert [row['condition'] for row in _json(out / 'replay_study.json')] == ['blind_obs']
    assert '| blind_obs |' in result.stdout and '| blind_obs | 1 |' in (
        out / 'replay_study.md').read_text()
    again = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert again.returncode == 0 and 'already have results' in again.stderr
    assert _json(out / 'replay_study.json')[0]['agreement'] == summary['agreement']


@pytest.mark.topics
def test_a_killed_recorder_stops_the_run_and_its_bag_is_repaired(tmp_path):
    import os
    import signal
    import time

    from harness import thread_niceness, wait_until
    from session_bag.config import RecorderConfig
    run_dir = tmp_path / 'run'
    launcher = subprocess.Popen([str(BIN / 'attention_train'), '--steps', '100000', '--record',
                                 '--run-dir', str(run_dir), '--quiet'],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_until(lambda: (run_dir / 'bag' / 'metadata.yaml').exists() and yaml.safe_load(
            (run_dir / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information'][
                'message_count'] > 200 or launcher.poll() is not None, 150, interval=0.2)
        assert launcher.poll() is None, launcher.communicate()[1][-4000:]
        time.sleep(0.3)
        recorder = _json(run_dir / 'pids.json')['session_recorder']
        # Every thread of the recorder yields the cores to the graph, DDS's too.
        niceness = thread_niceness(recorder)
        assert len(niceness) > 1 and min(niceness.values()) >= RecorderConfig.nice, niceness
        os.kill(recorder, signal.SIGKILL)
        _, stderr = launcher.communicate(timeout=90)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert launcher.returncode == 1
    assert 'session_recorder died (killed by SIGKILL)' in stderr
    assert 'the bag was repaired' in stderr
    summary = _json(run_dir / 'summary.json')
    assert summary['failed_node'] == 'session_recorder' and summary['bag']['repaired'] is True
    with RosbagsReader(run_dir / 'bag') as reader:  # whole again, for every rosbag2 reader
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts == summary['bag']['topics'] and counts['/observation'] > 10

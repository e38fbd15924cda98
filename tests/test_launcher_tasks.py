"""
The launcher on the other tasks (DoorKey, Fetch) and their conditions, with the real graph.

Split from ``test_launcher.py`` so that the two files run on two test workers. Each test runs
``.venv/bin/attention_train`` as a process and judges it by its exit code, its terminal output
and the run folder it leaves.
"""

import csv
import json
from pathlib import Path
import subprocess
import sys

from harness import progress_rows, read_json, wait_until
import pytest
import yaml

BIN = Path(sys.executable).parent
LAUNCHER = str(BIN / 'attention_train')
NODES = ('env_node', 'feedback_node', 'saliency_node', 'tamer_node')
STEPS = 300


@pytest.mark.topics
def test_doorkey_trains_through_the_real_graph(tmp_path):
    """attention_train --task doorkey: every node on the new task, the teacher and saliency."""
    run_dir = tmp_path / 'run'
    result = subprocess.run(
        [LAUNCHER, '--task', 'doorkey', '--condition', 'language_every_step', '--steps',
         str(STEPS), '--seed', '3', '--run-dir', str(run_dir), '--human-like'],
        capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stderr[-4000:]
    summary = read_json(run_dir / 'summary.json')
    assert summary['status'] == 'completed' and summary['steps'] == STEPS
    assert summary['task'] == 'doorkey' and summary['milestones'] == ['key', 'door', 'goal']
    assert summary['exit_codes'] == dict.fromkeys(NODES, 0)
    # DoorKey's own terms, none of Room 1's (held-out layouts come only later in a run).
    assert set(summary['milestone_steps']) == {'key', 'door', 'goal'}
    assert summary['heldout_episodes'] == summary['heldout_episodes_solved'] == 0
    assert 'first_key_step' not in summary and 'furthest_position' not in summary
    params = yaml.safe_load((run_dir / 'params.yaml').read_text())
    for node in NODES:
        assert params[node]['ros__parameters']['task'] == 'doorkey', node
    assert params['env_node']['ros__parameters']['distractors'] == 4
    counts = summary['message_counts']
    # The human-like teacher judged about a third of the steps, late (plain feedback), and
    # said the next sub-goal every step; the saliency node grounded it in DoorKey's templates.
    assert 0.1 * STEPS <= summary['learner_log']['feedback'] <= 0.6 * STEPS
    assert counts['utterance_stamped'] >= 0.8 * STEPS
    # The learner's samples had their saliency images (the launcher only samples the images,
    # best effort: under load it heard 156 of 300 once while the learner paired 290 of 290).
    # A saliency image later than saliency_timeout_s leaves its sample without one: 182 of 290
    # had theirs once in a full suite run, 290 of 290 alone.
    metrics = summary['metrics']
    paired = metrics['pairing/with_saliency'] + metrics['pairing/without_saliency']
    assert counts['saliency'] >= 1 and metrics['pairing/with_saliency'] >= 0.5 * paired > 0
    assert summary['metrics']['act/count'] >= 0.8 * STEPS
    assert summary['episodes'] >= STEPS // 100  # episodes of at most 100 steps
    with open(run_dir / 'progress.csv') as progress:
        rows = list(csv.DictReader(progress))
    assert {row['heldout'] for row in rows} == {'0'}  # no held-out layouts unless asked
    assert {row['room'] for row in rows} == {'0'}
    logged = [json.loads(line) for line in
              (run_dir / 'feedback_log.jsonl').read_text().splitlines()]
    said = {entry['text'] for entry in logged if entry['kind'] == 'utterance'}
    assert any(text.startswith('pick up the ') and text.endswith(' key') for text in said)


@pytest.mark.topics
def test_fetch_runs_on_every_node_by_name_and_says_each_mission(tmp_path):
    """attention_train --task fetch: a task added as one sub-package, no node edited."""
    # 300 steps: a reader matches a writer on its own side after the writer did, and a busy
    # machine's first words once reached the saliency node after a 120-step run had ended.
    run_dir, steps = tmp_path / 'run', 300
    result = subprocess.run(
        [LAUNCHER, '--task', 'fetch', '--steps', str(steps), '--seed', '4', '--run-dir',
         str(run_dir), '--quiet'], capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stderr[-4000:]
    summary = read_json(run_dir / 'summary.json')
    assert summary['status'] == 'completed' and summary['steps'] == steps
    assert summary['task'] == 'fetch' and summary['milestones'] == ['reached', 'fetched']
    assert summary['exit_codes'] == dict.fromkeys(NODES, 0)
    # Episodes end at a pick-up or after 50 steps: each has its target, said at its start.
    logged = [json.loads(line) for line in
              (run_dir / 'feedback_log.jsonl').read_text().splitlines()]
    said = [entry['text'] for entry in logged if entry['kind'] == 'utterance']
    assert summary['episodes'] >= steps // 50
    assert len(said) >= summary['episodes'] and all(
        text.startswith('pick up the ') for text in said)
    # The teacher judged the steps (all but an episode's last), and the learner logged every
    # judgement it gave before the nodes were stopped.
    teacher = summary['trainer_counts']
    assert teacher['judged'] >= 0.8 * steps and teacher['unjudged_gaps'] == 0, teacher
    assert summary['learner_log']['feedback'] == teacher['given_feedback'] == teacher['judged']
    metrics = summary['metrics']
    assert metrics['pairing/with_saliency'] > 0  # the words grounded in the room's objects


def _task_run(run_dir: Path, condition: str, steps: int, task: str = 'fetch') -> dict:
    """Run ``task`` in ``condition`` to its budget (seed 5); return its summary."""
    result = subprocess.run(
        [LAUNCHER, '--task', task, '--condition', condition, '--steps', str(steps),
         '--seed', '5', '--run-dir', str(run_dir), '--quiet'],
        capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stderr[-4000:]
    summary = read_json(run_dir / 'summary.json')
    assert summary['status'] == 'completed' and summary['steps'] == steps
    return summary


@pytest.mark.topics
@pytest.mark.parametrize('task', ['fetch', 'doorkey'])
def test_language_input_acts_on_each_steps_saliency_image(tmp_path, task):
    """
    --condition language_input (issue 25): H reads the frame and its saliency image.

    In Fetch the mask is the mission's object; in DoorKey the sub-goal's the teacher names.
    """
    run_dir, steps = tmp_path / 'run', 120
    summary = _task_run(run_dir, 'language_input', steps, task)
    params = yaml.safe_load((run_dir / 'params.yaml').read_text())
    assert params['tamer_node']['ros__parameters']['input_image'] == 'both'
    assert params['saliency_node']['ros__parameters']['mode'] == 'mask'
    assert 'input_image both' in (run_dir / 'logs' / 'tamer_node.log').read_text()
    metrics = summary['metrics']
    # Each step was answered once its saliency image came (lockstep waits for it); a step
    # answered on its observation alone would be counted here.
    assert metrics['act/count'] >= 0.95 * steps
    assert metrics['act/fallback_observation'] <= 0.05 * steps
    # The samples learned from carry both images (no L2 term: alpha 0).
    paired = metrics['pairing/with_saliency'] + metrics['pairing/without_saliency']
    assert metrics['pairing/with_saliency'] >= 0.9 * paired > 0
    assert metrics['train/l2_updates'] == 0


@pytest.mark.topics
def test_the_text_conditioned_peer_reads_each_mission(tmp_path):
    """--condition text_film (issue 25's peer): H reads the words, no saliency image made."""
    run_dir = tmp_path / 'run'
    summary = _task_run(run_dir, 'text_film', 120)
    assert 'text film' in (run_dir / 'logs' / 'tamer_node.log').read_text()
    assert summary['message_counts'].get('saliency', 0) == 0  # words, not images
    logged = [json.loads(line) for line in
              (run_dir / 'feedback_log.jsonl').read_text().splitlines()]
    said = [entry['text'] for entry in logged if entry['kind'] == 'utterance']
    assert len(said) >= summary['episodes'] >= 2  # every mission reached the learner
    assert summary['metrics']['samples/added'] > 0


@pytest.mark.topics
def test_a_person_teaches_doorkey_over_topics(tmp_path, probe):
    """--no-synthetic --realtime: what a person sends with ros2 topic pub reaches the log."""
    from attention_common import qos, topics
    from std_msgs.msg import Float32, String
    run_dir = tmp_path / 'run'
    launcher = subprocess.Popen(
        [LAUNCHER, '--task', 'doorkey', '--realtime', '--no-synthetic', '--steps', '12',
         '--run-dir', str(run_dir), '--quiet'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        feedback = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
        utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
        assert wait_until(lambda: progress_rows(run_dir) >= 2, 120), 'no steps'
        assert probe.wait_for_subscribers(feedback, 2, timeout=30)  # tamer and feedback_node
        assert probe.wait_for_subscribers(utterance, 2, timeout=30)  # tamer and saliency
        utterance.publish(String(data='pick up the yellow key'))
        for h in (1.0, -1.0, 1.0):
            feedback.publish(Float32(data=h))
        stdout, stderr = launcher.communicate(timeout=120)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert launcher.returncode == 0, stderr[-4000:]
    params = yaml.safe_load((run_dir / 'params.yaml').read_text())
    assert params['env_node']['ros__parameters']['rate_hz'] == 1.0  # DoorKey's real time
    logged = [json.loads(line) for line in
              (run_dir / 'feedback_log.jsonl').read_text().splitlines()]
    assert [e['h'] for e in logged if e['kind'] == 'feedback'] == [1.0, -1.0, 1.0]
    assert [e['text'] for e in logged if e['kind'] == 'utterance'] == ['pick up the yellow key']
    feedback_log = (run_dir / 'logs' / 'feedback_node.log').read_text()
    assert "a person said 'pick up the yellow key'" in feedback_log

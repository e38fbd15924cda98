"""tamer_node as a real process, spoken to over topics only."""

import json
import math
import signal
import time

from attention_common import qos, topics
from attention_common.executors import EXECUTOR_ENV, EXECUTORS
from attention_common.image_codec import numpy_to_image
from attention_common.joy_actions import joy_to_action
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from harness import wait_until
import numpy as np
import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from saliency_node.saliency import BLUR_RADIUS, gaussian_blur
from sensor_msgs.msg import Image, Joy
from std_msgs.msg import Float32, String
from tamer_node.pretrain import collect_frames

pytestmark = pytest.mark.topics
STEP_NS = 1_000_000_000 // 15
RIGHT = 3


@pytest.fixture(scope='module')
def frames():
    """Return real Room 1 frames, from a seeded random walk through the real emulator."""
    collected, _ = collect_frames(30, seed=5, stride=3, use_expert=False)
    return collected


class Graph:
    """The probe's publishers and subscriptions towards one tamer_node."""

    def __init__(self, probe):
        self.probe = probe
        self.observation = probe.publisher(Image, topics.OBSERVATION, qos.FRAMES)
        self.saliency = probe.publisher(Image, topics.SALIENCY, qos.FRAMES)
        self.feedback_stamped = probe.publisher(Vector3Stamped, topics.FEEDBACK_STAMPED,
                                                qos.HUMAN)
        self.feedback = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
        self.utterance = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
        self.actions = probe.subscribe(Joy, topics.ACTION, qos.ACTIONS)
        self.metrics = probe.subscribe(DiagnosticArray, topics.METRICS, qos.METRICS)

    def wait_connected(self, node, timeout=60.0):
        connected = wait_until(lambda: all(
            p.get_subscription_count() >= 1
            for p in (self.observation, self.saliency, self.feedback_stamped, self.feedback,
                      self.utterance)), timeout)
        assert connected, 'tamer_node did not subscribe in time\n' + node.log_text()[-3000:]
        assert self.probe.wait_for_publishers(topics.METRICS, timeout=timeout)

    def image(self, array, stamp, encoding='rgb8'):
        msg = numpy_to_image(array, encoding, Image())
        msg.header.stamp = ns_to_stamp(stamp)
        msg.header.frame_id = 'atari'
        return msg

    def step(self, frame, stamp, saliency=None, timeout=10.0):
        """Publish an observation (and its saliency image); return the action that answers it."""
        self.observation.publish(self.image(frame, stamp))
        if saliency is not None:
            self.saliency.publish(self.image(saliency, stamp))
        answered = self.actions.wait_for(
            lambda msgs: any(stamp_to_ns(m.header.stamp) == stamp for m in msgs), timeout)
        assert answered, f'no action for stamp {stamp}'
        joy = next(m for m in self.actions.snapshot() if stamp_to_ns(m.header.stamp) == stamp)
        return joy_to_action(joy.axes, joy.buttons)

    def judge(self, stamp, h):
        msg = Vector3Stamped()
        msg.header.stamp = ns_to_stamp(stamp)
        msg.vector.x, msg.vector.y, msg.vector.z = float(h), -1.0, 30.0
        self.feedback_stamped.publish(msg)

    def wait_metrics(self, predicate, timeout=20.0, since=0):
        """Wait for a metrics message (after index ``since``) whose values satisfy predicate."""
        def check(messages):
            return any(predicate(values(m)) for m in messages[since:])
        return self.metrics.wait_for(check, timeout)

    def latest_metrics(self):
        messages = self.metrics.snapshot()
        return values(messages[-1]) if messages else {}


def values(msg):
    return {kv.key: float(kv.value) for kv in msg.status[0].values}


def blurred(frame):
    return gaussian_blur(frame, BLUR_RADIUS)


def feedback_lines(run_dir):
    path = run_dir / 'feedback_log.jsonl'
    return [json.loads(line) for line in path.read_text().splitlines()
            if json.loads(line)['kind'] == 'feedback']


def set_parameter(probe, name, value: float):
    client = probe.node.create_client(SetParameters, '/tamer_node/set_parameters')
    assert client.wait_for_service(timeout_sec=10.0)
    request = SetParameters.Request(parameters=[ParameterMsg(
        name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                        double_value=value))])
    future = client.call_async(request)
    assert wait_until(future.done, 10.0)
    return future.result().results[0]


def test_answers_every_observation_while_it_trains(probe, start_node, tmp_path, frames):
    run_dir = tmp_path / 'run'
    node = start_node('tamer_node', {'run_dir': str(run_dir), 'update_rate_hz': 30.0,
                                     'metrics_period_s': 0.2, 'saliency_timeout_s': 0.3})
    graph = Graph(probe)
    graph.wait_connected(node)
    steps = 60
    for i in range(steps):
        stamp = (i + 1) * STEP_NS
        frame = frames[i % len(frames)]
        action = graph.step(frame, stamp, saliency=blurred(frame) if i % 2 else None)
        graph.judge(stamp, 1.0 if action == RIGHT else -1.0)
    stamps = [stamp_to_ns(m.header.stamp) for m in graph.actions.snapshot()]
    assert sorted(stamps) == [(i + 1) * STEP_NS for i in range(steps)]  # each once, no other
    assert graph.wait_metrics(lambda v: v['feedback/count'] == steps
                              and v['buffer/size'] == steps and v['model/version'] > steps
                              and v['pairing/with_saliency'] == steps // 2
                              and v['train/updates_per_s'] > 0), str(graph.latest_metrics())
    metrics = graph.latest_metrics()
    assert metrics['act/version'] > 0
    # Half the steps had a saliency image: half the buffer rows, and the L2 term is non-zero
    # (a mean over the period's updates that had one, not the last update's value).
    assert metrics['buffer/with_saliency_fraction'] == 0.5
    assert metrics['train/l2_updates'] > 0
    rows = [values(m) for m in graph.metrics.snapshot()]
    with_l2 = [v for v in rows if v['train/period_l2_updates'] > 0]
    assert with_l2 and all(v['train/l2'] > 0.0 for v in with_l2)
    assert all(math.isfinite(v['train/loss']) for v in rows if v['train/period_updates'] > 0)
    # 30 minibatch updates per simulation second: 2 per 15 Hz step (from the first feedback
    # on), plus the immediate ones; the learner may lag behind, then catches up.
    assert graph.wait_metrics(lambda v: v['train/updates_owed'] == 0
                              and v['train/minibatch_updates_per_step'] > 1.9), \
        str(graph.latest_metrics())
    metrics = graph.latest_metrics()
    assert metrics['train/minibatch_updates_per_step'] <= 2.0
    assert metrics['train/updates_per_step'] > 2.0 and metrics['train/skipped_updates'] == 0

    # alpha changes at run time; other parameters are start-up only.
    assert set_parameter(probe, 'alpha', 0.0).successful
    assert graph.wait_metrics(lambda v: v['train/alpha'] == 0.0, since=len(graph.metrics.messages))
    assert not set_parameter(probe, 'learning_rate', 0.5).successful

    assert node.stop(signal.SIGINT) == 0
    assert len(feedback_lines(run_dir)) == steps
    assert (run_dir / 'checkpoints' / 'checkpoint.pt').exists()
    header = (run_dir / 'metrics.csv').read_text().splitlines()[0].split(',')
    assert {'train/loss', 'train/mse', 'train/l2', 'feedback/count', 'buffer/size',
            'train/updates_per_s', 'model/version', 'drop/observation', 'train/l2_updates',
            'train/updates_per_step', 'buffer/with_saliency_fraction'} <= set(header)


def test_saliency_input_answers_a_step_whose_saliency_image_never_comes(
        probe, start_node, tmp_path, frames):
    """input_image:=saliency acts on the saliency image; without one, on the observation."""
    node = start_node('tamer_node', {'run_dir': str(tmp_path / 'run'), 'input_image': 'saliency',
                                     'alpha': 0.0, 'saliency_timeout_s': 0.3,
                                     'metrics_period_s': 0.2})
    graph = Graph(probe)
    graph.wait_connected(node)
    graph.step(frames[0], STEP_NS, saliency=blurred(frames[0]))
    lonely = graph.step(frames[1], 2 * STEP_NS, timeout=5.0)  # no saliency image: fallback
    assert graph.wait_metrics(lambda v: v['act/fallback_observation'] == 1
                              and v['act/count'] == 2), graph.latest_metrics()
    graph.saliency.publish(graph.image(blurred(frames[1]), 2 * STEP_NS))  # too late
    assert graph.step(frames[1], 2 * STEP_NS) == lonely  # the env re-sends: the same answer
    graph.step(frames[2], 3 * STEP_NS, saliency=blurred(frames[2]))
    graph.judge(3 * STEP_NS, 1.0)
    assert graph.wait_metrics(lambda v: v['feedback/count'] == 1 and v['act/count'] == 3
                              and v['act/fallback_observation'] == 1), graph.latest_metrics()
    answers = [stamp_to_ns(m.header.stamp) for m in graph.actions.snapshot()]
    assert answers.count(STEP_NS) == 1 and answers.count(3 * STEP_NS) == 1
    assert answers.count(2 * STEP_NS) == 2  # the fallback and the re-send, not the late image
    assert 'acted on its observation' in node.log_text()
    assert node.stop(signal.SIGINT) == 0


def test_kill_9_then_resume_loses_no_logged_feedback(probe, start_node, tmp_path, frames):
    run_dir = tmp_path / 'run'
    params = {'run_dir': str(run_dir), 'metrics_period_s': 0.2, 'checkpoint_period_s': 0.0,
              'alpha': 0.0}
    graph = Graph(probe)

    def play(first, count):
        for i in range(first, first + count):
            stamp = (i + 1) * STEP_NS
            graph.step(frames[i % len(frames)], stamp)
            graph.judge(stamp, 1.0 if i % 3 else -1.0)

    # Run 1 ends cleanly with a checkpoint of 15 feedback.
    first = start_node('tamer_node', params, name='tamer_run1')
    graph.wait_connected(first)
    play(0, 15)
    assert graph.wait_metrics(lambda v: v['feedback/count'] == 15)
    assert first.stop(signal.SIGINT) == 0

    # Run 2 resumes, gets 12 more (logged, no checkpoint after them), and is killed.
    since = len(graph.metrics.messages)
    second = start_node('tamer_node', dict(params, resume=True), name='tamer_run2')
    graph.wait_connected(second)
    assert graph.wait_metrics(lambda v: v['feedback/count'] == 15 and v['buffer/size'] == 15,
                              since=since)
    play(15, 12)
    assert graph.wait_metrics(lambda v: v['feedback/logged'] == 27, since=since)
    second.stop(signal.SIGKILL)
    logged = feedback_lines(run_dir)
    assert [e['seq'] for e in logged] == list(range(1, 28))

    # Run 3 restores the checkpoint and replays the 12 from the log and the step journal.
    since = len(graph.metrics.messages)
    third = start_node('tamer_node', dict(params, resume=True), name='tamer_run3')
    graph.wait_connected(third)
    assert graph.wait_metrics(
        lambda v: v['resume/replayed'] == 12 and v['feedback/count'] == 27
        and v['buffer/size'] == 27 and v['feedback/logged'] == 27, since=since), \
        graph.latest_metrics()
    play(27, 3)  # and carries on
    assert graph.wait_metrics(lambda v: v['feedback/count'] == 30, since=since)
    assert third.stop(signal.SIGINT) == 0
    assert [e['seq'] for e in feedback_lines(run_dir)] == list(range(1, 31))


def test_bad_input_is_dropped_and_counted(probe, start_node, tmp_path, frames):
    run_dir = tmp_path / 'run'
    node = start_node('tamer_node', {'run_dir': str(run_dir), 'metrics_period_s': 0.2})
    graph = Graph(probe)
    graph.wait_connected(node)
    frame = frames[0]
    graph.observation.publish(graph.image(frame[:, :, 0], STEP_NS, 'mono8'))
    bgr = graph.image(frame, 2 * STEP_NS)
    bgr.encoding = 'bgr8'
    graph.observation.publish(bgr)
    cut = graph.image(frame, 3 * STEP_NS)
    cut.data = cut.data[:1000]
    graph.observation.publish(cut)
    graph.saliency.publish(graph.image(np.zeros((100, 100, 3), np.uint8), 4 * STEP_NS))
    graph.feedback.publish(Float32(data=float('nan')))
    nan_stamped = Vector3Stamped()
    nan_stamped.vector.x = float('inf')
    graph.feedback_stamped.publish(nan_stamped)
    for text in ('', 'x' * 100_000, 'Klettere die Leiter hinunter, bitte! \u00fc\u00df'):
        graph.utterance.publish(String(data=text))
    assert graph.wait_metrics(lambda v: v['drop/observation'] == 3 and v['drop/saliency'] == 1
                              and v['feedback/invalid'] == 2 and v['utterance/count'] == 3)
    assert node.alive()
    graph.step(frame, 5 * STEP_NS)  # still acting
    assert 'observation dropped' in node.log_text()
    assert node.stop(signal.SIGINT) == 0
    statuses = [e['status'] for e in feedback_lines(run_dir)]
    assert statuses == ['invalid', 'invalid']


def test_start_up_errors_say_what_to_do(start_node, tmp_path):
    missing = start_node('tamer_node', {'run_dir': str(tmp_path / 'a'),
                                        'encoder_path': str(tmp_path / 'nope.pt')},
                         name='tamer_missing')
    wrong = start_node('tamer_node', {'run_dir': str(tmp_path / 'b'), 'credit': 'sometimes'},
                       name='tamer_wrong')
    assert missing.process.wait(timeout=60) == 1
    assert 'tamer_pretrain' in missing.log_text()
    assert wrong.process.wait(timeout=60) == 1
    assert 'credit' in wrong.log_text()


@pytest.mark.parametrize('executor', EXECUTORS)
def test_every_logged_feedback_and_utterance_gets_a_receipt(probe, start_node, tmp_path, frames,
                                                            monkeypatch, executor):
    # Under either executor: the receipts need rclpy's MessageInfo, which rclpy 7.1.6's
    # EventsExecutor hands over in another form (attention_common.executors).
    monkeypatch.setenv(EXECUTOR_ENV, executor)
    run_dir = tmp_path / 'run'
    node = start_node('tamer_node', {'run_dir': str(run_dir), 'metrics_period_s': 0.2})
    graph = Graph(probe)
    receipts = probe.subscribe(DiagnosticArray, topics.FEEDBACK_LOGGED, qos.HUMAN)
    graph.wait_connected(node)
    assert probe.wait_for_publishers(topics.FEEDBACK_LOGGED, timeout=30.0)
    graph.step(frames[0], STEP_NS)
    for h in (1.0, -1.0, 7.0):
        graph.feedback.publish(Float32(data=h))
    graph.utterance.publish(String(data='Climb down the ladder.'))
    assert receipts.wait_count(4, 20.0), node.log_text()[-2000:]
    got = [(m.status[0].name, {kv.key: kv.value for kv in m.status[0].values}, m.status[0].message)
           for m in receipts.snapshot()]
    feedback = [values for name, values, _ in got if name == 'feedback']
    # The probe's publisher numbers its messages 1, 2, 3: the receipts name them.
    assert [v['publication_seq'] for v in feedback] == ['1', '2', '3']
    assert [v['status'] for v in feedback] == ['ok', 'ok', 'invalid']
    assert [v['seq'] for v in feedback] == ['1', '2', '3'] and float(feedback[0]['h']) == 1.0
    [(_, said, text)] = [g for g in got if g[0] == 'utterance']
    assert text == 'Climb down the ladder.' and said['publication_seq'] == '1'
    lines = [json.loads(line)
             for line in (run_dir / 'feedback_log.jsonl').read_text().splitlines()]
    assert [line['publication_seq'] for line in lines if line['kind'] == 'feedback'] == [1, 2, 3]
    assert all(line['source_time_ns'] > 0 for line in lines)
    assert node.stop() == 0


def test_a_pressed_verdict_is_credited_from_the_moment_it_was_given(
        probe, start_node, tmp_path, frames):
    # Grid steps of 1 s at 1..6 s; the verdict on the step at 3 s (result shown at 4 s) was
    # given at 5.1 s. From the press, a 0.2-1.6 s delay after a result credits the step at
    # 3 s; from the newest observation (6 s) it would credit the step at 4 s.
    run_dir = tmp_path / 'run'
    node = start_node('tamer_node', {'run_dir': str(run_dir), 'credit': 'window',
                                     'credit_anchor': 'effect', 'window_min_s': 0.2,
                                     'window_max_s': 1.6, 'update_rate_hz': 0.0})
    graph = Graph(probe)
    pressed = probe.publisher(Vector3Stamped, topics.FEEDBACK_PRESSED, qos.HUMAN)
    credit = probe.subscribe(DiagnosticArray, topics.FEEDBACK_CREDIT, qos.HUMAN)
    graph.wait_connected(node)
    assert wait_until(lambda: pressed.get_subscription_count() >= 1, 30.0)
    assert probe.wait_for_publishers(topics.FEEDBACK_CREDIT, timeout=30.0)
    for i in range(6):
        graph.step(frames[i % len(frames)], (i + 1) * 1_000_000_000)
    msg = Vector3Stamped()
    msg.header.stamp = ns_to_stamp(5_100_000_000)
    msg.vector.x = 1.0
    pressed.publish(msg)
    assert credit.wait_count(1, 20.0), node.log_text()[-2000:]
    [line] = [json.loads(line) for line in (run_dir / 'feedback_log.jsonl').read_text()
              .splitlines() if json.loads(line)['kind'] == 'feedback']
    assert (line['source'], line['now_ns'], line['stamp_ns']) == (
        'pressed', 5_100_000_000, 6_000_000_000)
    values = {kv.key: kv.value for kv in credit.snapshot()[0].status[0].values}
    assert [key for key in values if key.isdigit()] == ['3000000000'], values
    assert node.stop() == 0


def test_it_says_what_it_made_of_each_step_and_each_feedback(
        probe, start_node, tmp_path, frames):
    """action_values: H of every action and the action taken; feedback_credit: the steps."""
    node = start_node('tamer_node', {'run_dir': str(tmp_path / 'run'), 'credit': 'window',
                                     'window_min_s': 0.2, 'window_max_s': 1.6,
                                     'decision_period_s': 0.2,
                                     'values_rate_hz': 0.0})  # every step, however fast
    graph = Graph(probe)
    seen = probe.subscribe(DiagnosticArray, topics.ACTION_VALUES, qos.ACTION_VALUES)
    credited = probe.subscribe(DiagnosticArray, topics.FEEDBACK_CREDIT, qos.HUMAN)
    graph.wait_connected(node)
    assert wait_until(lambda: probe.node.count_publishers(topics.FEEDBACK_CREDIT) >= 1, 30.0)
    stamps = [(i + 1) * STEP_NS for i in range(45)]
    actions = {stamp: graph.step(frames[i % len(frames)], stamp)
               for i, stamp in enumerate(stamps)}
    assert seen.wait_for(lambda msgs: len(msgs) >= len(stamps), 10.0)
    by_stamp = {stamp_to_ns(m.header.stamp): m.status[0] for m in seen.snapshot()}
    assert set(by_stamp) == set(stamps)
    status = by_stamp[stamps[-1]]
    named = {kv.key: kv.value for kv in status.values}
    assert int(named['action']) == actions[stamps[-1]]  # the action it published
    assert len(status.values) == 2 + 18 and status.message == list(named)[2 + int(named['action'])]
    graph.feedback.publish(Float32(data=1.0))  # a person's plain, late feedback
    assert credited.wait_for(lambda msgs: len(msgs) >= 1, 10.0), node.log_text()[-2000:]
    credit = {int(kv.key): float(kv.value) for kv in credited.snapshot()[0].status[0].values
              if kv.key not in ('seq', 'h')}
    assert sum(credit.values()) == pytest.approx(1.0, abs=1e-3)
    assert set(credit) <= set(stamps[::3])  # decisions of 3: the steps that chose
    assert min(credit) >= stamps[-1] - 2 * 1_000_000_000 and len(credit) >= 5
    assert node.stop(signal.SIGINT) == 0


@pytest.mark.topics
def test_h_goes_out_at_most_at_its_rate_when_the_steps_come_faster(
        probe, start_node, tmp_path, frames):
    """values_rate_hz thins a lockstep run's action_values where they are made; newest last."""
    node = start_node('tamer_node', {'run_dir': str(tmp_path / 'run'), 'values_rate_hz': 5.0})
    graph = Graph(probe)
    seen = probe.subscribe(DiagnosticArray, topics.ACTION_VALUES, qos.ACTION_VALUES)
    graph.wait_connected(node)
    started = time.monotonic()
    stamps = [(i + 1) * STEP_NS for i in range(60)]
    for i, stamp in enumerate(stamps):
        graph.step(frames[i % len(frames)], stamp)
    elapsed = time.monotonic() - started
    assert seen.wait_for(lambda msgs: len(msgs) >= 1, 10.0)
    time.sleep(0.5)  # any straggler in DDS
    sent = [stamp_to_ns(m.header.stamp) for m in seen.snapshot()]
    assert 1 <= len(sent) <= 5 + 5.0 * elapsed + 1, (len(sent), elapsed)  # burst, then rate
    assert len(sent) < len(stamps) and set(sent) <= set(stamps) and sent == sorted(sent)
    assert node.stop(signal.SIGINT) == 0


@pytest.mark.topics
def test_it_asks_about_the_steps_it_is_unsure_of_after_answering_them(
        probe, start_node, tmp_path, frames):
    """ask_rate: a question per step it is unsure of, at most the rate, naming step and action."""
    node = start_node('tamer_node', {'run_dir': str(tmp_path / 'run'), 'ask_rate': 0.5,
                                     'ask_margin': 2.5})  # unsure everywhere: the rate decides
    graph = Graph(probe)
    questions = probe.subscribe(Vector3Stamped, topics.QUESTION, qos.HUMAN)
    graph.wait_connected(node)
    assert probe.wait_for_publishers(topics.QUESTION, timeout=30.0)
    stamps = [(i + 1) * STEP_NS for i in range(40)]
    actions = {stamp: graph.step(frames[i % len(frames)], stamp)
               for i, stamp in enumerate(stamps)}
    assert questions.wait_for(lambda msgs: len(msgs) >= 20, 10.0), node.log_text()[-2000:]
    asked = {stamp_to_ns(m.header.stamp): m.vector for m in questions.snapshot()}
    assert sorted(asked) == stamps[1::2]  # a token every other step, spent at once
    assert all(int(v.x) == actions[stamp] and 0.0 <= v.y < 2.5 for stamp, v in asked.items())
    assert node.stop(signal.SIGINT) == 0

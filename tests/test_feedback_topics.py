"""
The real env_node and feedback_node executables, driven over topics by a probe.

The probe acts as the learner: it answers every observation with the scripted expert's action,
so the agent walks the route to the key, and it records every message by stamp. Attribution is
checked by stamp, whatever order messages of different topics arrive in.
"""

import math
import signal
import time

from attention_common import qos, topics
from attention_common.image_codec import image_to_numpy
from attention_common.joy_actions import action_to_joy
from attention_common.stamps import frames_to_ns, NS_PER_S, ns_to_stamp, stamp_to_ns
from attention_tasks.montezuma.critical_positions import critical_position_at
from attention_tasks.montezuma.env import RamState
from attention_tasks.montezuma.expert import RoomOneExpert, skull_x_from_frame
from attention_tasks.montezuma.reward import RewardFunction
from diagnostic_msgs.msg import DiagnosticArray
from feedback_node.utterances import UtteranceGenerator
from geometry_msgs.msg import PointStamped, Vector3Stamped
from harness import TopicProbe, wait_until
import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from sensor_msgs.msg import Image, Joy
from std_msgs.msg import Float32, String

pytestmark = pytest.mark.topics

STARTUP_S = 30.0
REPLY_S = 10.0
ROUTE_S = 60.0  # wall time for the whole route (about 90 steps)


class TrainerListener:
    """Everything the feedback node says, as the learner and the saliency node hear it."""

    def __init__(self, probe):
        self.feedback_stamped = probe.subscribe(Vector3Stamped, topics.FEEDBACK_STAMPED,
                                                qos.HUMAN)
        self.feedback = probe.subscribe(Float32, topics.FEEDBACK, qos.HUMAN)
        self.utterance_stamped = probe.subscribe(DiagnosticArray, topics.UTTERANCE_STAMPED,
                                                 qos.HUMAN)
        self.utterance = probe.subscribe(String, topics.UTTERANCE, qos.HUMAN)


class ExpertLearner:
    """Answers each observation with the expert's action; records positions by stamp."""

    def __init__(self, probe):
        # The env sends the first step when an observation subscriber appears; subscribing
        # to the step data first makes it likely that they hear that step too.
        self.positions = probe.subscribe(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
        self.statuses = probe.subscribe(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
        self.observations = probe.subscribe(Image, topics.OBSERVATION, qos.FRAMES)
        self.actions = probe.publisher(Joy, topics.ACTION, qos.ACTIONS)
        self.answered = []
        self._probe = probe

    def _by_stamp(self, log, stamp_ns, timeout=REPLY_S):
        def found(messages):
            return any(stamp_to_ns(m.header.stamp) == stamp_ns for m in messages)
        assert log.wait_for(found, timeout), f'nothing stamped {stamp_ns} within {timeout} s'
        return next(m for m in log.snapshot() if stamp_to_ns(m.header.stamp) == stamp_ns)

    def _heard(self, stamp_ns, timeout=2.0) -> bool:
        def found(messages):
            return any(stamp_to_ns(m.header.stamp) == stamp_ns for m in messages)
        return self.positions.wait_for(found, timeout) and self.statuses.wait_for(found, timeout)

    def _has_key(self, stamp_ns) -> bool:
        status = self._by_stamp(self.statuses, stamp_ns)
        return {kv.key: kv.value for kv in status.status[0].values}['has_key'] == 'true'

    def play_to_key(self, trainer_ready, deadline_s=ROUTE_S) -> int:
        """
        Play until the agent has the key; return the stamp of that step.

        Until ``trainer_ready()`` (the env's positions reach the trainer: DDS discovery between
        two other processes can take seconds) the agent waits at the start with NOOPs.
        """
        assert self.observations.wait_count(1, STARTUP_S), 'no observation from env_node'
        assert self._probe.wait_for_subscribers(self.actions, timeout=STARTUP_S)
        expert = RoomOneExpert()
        expert.reset()
        last = -1
        deadline = time.monotonic() + deadline_s
        while time.monotonic() < deadline:
            def newer(messages):
                return any(stamp_to_ns(m.header.stamp) > last for m in messages)
            assert self.observations.wait_for(newer, REPLY_S), f'no observation after {last}'
            observation = min((m for m in self.observations.snapshot()
                               if stamp_to_ns(m.header.stamp) > last),
                              key=lambda m: stamp_to_ns(m.header.stamp))
            stamp_ns = stamp_to_ns(observation.header.stamp)
            if not trainer_ready():
                action = 0
                time.sleep(0.05)  # pace the wait: a few steps per second of discovery
            elif self.answered or self._heard(stamp_ns):
                point = self._by_stamp(self.positions, stamp_ns).point
                has_key = self._has_key(stamp_ns)
                if has_key:
                    return stamp_ns
                state = RamState(x=int(point.x), y=int(point.y), room=int(point.z), lives=5,
                                 has_key=has_key)
                skull = skull_x_from_frame(image_to_numpy(observation))
                action = expert.act(state, skull)
            else:
                action = 0  # the first step's data went out before we matched
            axes, buttons = action_to_joy(action)
            joy = Joy(axes=list(axes), buttons=list(buttons))
            joy.header.stamp = ns_to_stamp(stamp_ns)
            self.actions.publish(joy)
            self.answered.append(stamp_ns)
            last = stamp_ns
        raise AssertionError(f'no key within {deadline_s} s; phase {expert.phase}')

    def positions_until(self, stamp_ns):
        """``[(stamp, x, y)]`` of every agent_position up to ``stamp_ns``, in stamp order."""
        points = {stamp_to_ns(m.header.stamp): (m.point.x, m.point.y)
                  for m in self.positions.snapshot()}
        return [(s, *points[s]) for s in sorted(points) if s <= stamp_ns]


def stamped_h(msgs):
    return {stamp_to_ns(m.header.stamp): m.vector for m in msgs}


def test_trainer_follows_the_expert_position_by_position(probe, start_node):
    listener = TrainerListener(probe)
    learner = ExpertLearner(probe)
    trainer = start_node('feedback_node', {'utterance_interval': 0.0, 'plain_copies': True})
    # The trainer listens before the env starts (agent_position is not kept for late joiners).
    assert wait_until(lambda: probe.node.count_subscribers(topics.AGENT_POSITION) >= 2,
                      STARTUP_S)
    start_node('env_node', {'warmup_steps': 0, 'sticky_actions': 0.0, 'seed': 0})

    key_stamp = learner.play_to_key(
        trainer_ready=lambda: bool(listener.utterance_stamped.snapshot()))
    route = learner.positions_until(key_stamp)
    stamps = [s for s, _, _ in route]
    assert len(route) >= 60
    assert stamps[:-1] == learner.answered[-len(stamps) + 1:]  # one position per answer
    # The trainer starts hearing positions when DDS has matched it with the env. With
    # utterances at every step the first one shows the first position it heard; check from
    # there on (the probe has heard every position since its first answer).
    assert listener.utterance_stamped.wait_count(1, REPLY_S), (
        f'no utterance_stamped; heard {len(listener.feedback_stamped.snapshot())} '
        f'feedback_stamped, {len(listener.utterance.snapshot())} utterance\n'
        + trainer.log_text()[-3000:])
    first_heard = min(stamp_to_ns(m.header.stamp) for m in listener.utterance_stamped.snapshot())
    start = max(first_heard, stamps[0])
    assert start in stamps[:len(stamps) - 60]
    route = route[stamps.index(start):]
    stamps = [s for s, _, _ in route]

    # Every step but the last is judged once, by the position it led to.
    judged = set(stamps[:-1])
    assert listener.feedback_stamped.wait_for(
        lambda msgs: judged <= set(stamped_h(msgs)), REPLY_S), 'feedback missing'
    received = stamped_h(listener.feedback_stamped.snapshot())
    assert len(listener.feedback_stamped.snapshot()) == len(received)  # no stamp twice
    reward = RewardFunction()
    reward(*route[0][1:])
    for (stamp, _, _), (_, x, y) in zip(route, route[1:]):
        expected = reward(x, y)
        vector = received[stamp]
        assert vector.x == expected.h, f'step {stamp}: h {vector.x} != {expected.h}'
        assert vector.y == critical_position_at(x, y)
        assert vector.z == pytest.approx(expected.distance, abs=1e-6)
    assert {v.x for s, v in received.items() if s in judged} == {-1.0, 0.0, 1.0}

    # Utterances: one per step (interval 0) but while stuck, the sentence of where it stands.
    generator = UtteranceGenerator(interval_s=0.0)
    expected_said = [u for u in (generator.observe(x, y, s) for s, x, y in route) if u]
    expected_stamps = {u.stamp_ns for u in expected_said}
    assert listener.utterance_stamped.wait_for(
        lambda msgs: expected_stamps <= {stamp_to_ns(m.header.stamp) for m in msgs}, REPLY_S)
    said = sorted(listener.utterance_stamped.snapshot(), key=lambda m: stamp_to_ns(m.header.stamp))
    said = [m for m in said if start <= stamp_to_ns(m.header.stamp) <= key_stamp]
    assert [(stamp_to_ns(m.header.stamp), m.status[0].message) for m in said] == [
        (u.stamp_ns, u.text) for u in expected_said]
    for m, u in zip(said, expected_said):
        status = m.status[0]
        assert (status.name, status.hardware_id) == ('utterance', 'synthetic_trainer')
        assert status.values[0].key == 'position' and int(status.values[0].value) == u.position
    on_positions = [int(m.status[0].values[0].value) for m in said]
    visited = [p for i, p in enumerate(on_positions)
               if p >= 0 and p not in on_positions[:i]]
    assert visited == [0, 1, 2, 3, 4, 5]

    # plain_copies: each stamped message has its plain companion, with the same value.
    all_h = sorted(m.vector.x for m in listener.feedback_stamped.snapshot())
    all_text = sorted(m.status[0].message for m in listener.utterance_stamped.snapshot())
    assert listener.feedback.wait_count(len(all_h), REPLY_S)
    assert listener.utterance.wait_count(len(all_text), REPLY_S)
    assert sorted(m.data for m in listener.feedback.snapshot()) == all_h
    assert sorted(m.data for m in listener.utterance.snapshot()) == all_text
    assert trainer.alive()
    assert trainer.stop(signal.SIGINT) == 0


def set_parameter(probe, name, value: bool):
    client = probe.node.create_client(SetParameters, '/feedback_node/set_parameters')
    assert client.wait_for_service(timeout_sec=STARTUP_S)
    request = SetParameters.Request(parameters=[ParameterMsg(
        name=name, value=ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value))])
    future = client.call_async(request)
    assert wait_until(future.done, REPLY_S)
    assert future.result().results[0].successful


def publish_positions(publisher, steps, x0=40.0):
    for step in steps:
        msg = PointStamped()
        msg.header.stamp = ns_to_stamp(frames_to_ns(4 * step))
        msg.point.x, msg.point.y, msg.point.z = x0 + 2 * (step % 3), 235.0, 1.0
        publisher.publish(msg)


def say_until_heard(publisher, trainer, text, step):
    """Say ``text`` until the trainer logs it heard at ``step``'s time (all positions in)."""
    line = f'a person said {text!r} at {frames_to_ns(4 * step) / NS_PER_S:.2f} s'
    deadline = time.monotonic() + REPLY_S
    while time.monotonic() < deadline:
        publisher.publish(String(data=text))
        if trainer.wait_for_log(line, 0.5):
            return
    raise AssertionError(f'never logged {line!r}\n' + trainer.log_text()[-2000:])


def test_a_person_takes_over_and_bad_input_is_logged(probe, start_node):
    listener = TrainerListener(probe)
    positions = probe.publisher(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    person_says = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
    person_rates = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
    trainer = start_node('feedback_node', {'utterance_interval': 0.0})
    assert probe.wait_for_subscribers(positions, timeout=STARTUP_S)
    assert probe.wait_for_subscribers(person_says, timeout=STARTUP_S)
    assert probe.wait_for_subscribers(person_rates, timeout=STARTUP_S)

    publish_positions(positions, range(0, 10))
    assert listener.feedback_stamped.wait_count(9, REPLY_S)
    broken = PointStamped()
    broken.header.stamp = ns_to_stamp(frames_to_ns(4 * 10))
    broken.point.x = math.nan
    positions.publish(broken)
    assert trainer.wait_for_log('agent_position dropped: x=nan', REPLY_S)
    for step, (x, y) in enumerate(((1e30, 235.0), (300.0, 235.0), (40.0, -5.0)), start=11):
        far = PointStamped()
        far.header.stamp = ns_to_stamp(frames_to_ns(4 * step))
        far.point.x, far.point.y, far.point.z = x, y, 1.0
        positions.publish(far)
    assert trainer.wait_for_log("x=300, y=235 is outside the game's range 0..255", REPLY_S)
    assert trainer.wait_for_log('x=1e+30, y=235 is outside', REPLY_S)
    assert trainer.wait_for_log('x=40, y=-5 is outside', REPLY_S)
    publish_positions(positions, range(14, 18))  # good input after: judged again
    assert listener.feedback_stamped.wait_count(12, REPLY_S), trainer.log_text()[-2000:]
    set_parameter(probe, 'synthetic', False)
    assert trainer.wait_for_log('a person trains', REPLY_S)
    before = (len(listener.feedback_stamped.snapshot()),
              len(listener.utterance_stamped.snapshot()))

    publish_positions(positions, range(10, 40))
    # Each bad message gets its own error line; the valid one after them is heard.
    bad = ['', '   \t ', 'Climb up the ladder \u00e9\u00e9', 'x' * 100_000]
    for text in bad:
        person_says.publish(String(data=text))
    for value in (math.nan, math.inf, -math.inf):
        person_rates.publish(Float32(data=value))
    person_rates.publish(Float32(data=1.0))
    say_until_heard(person_says, trainer, 'Move left and avoid the skull.', step=39)
    assert trainer.wait_for_log('a person gave feedback +1', REPLY_S), trainer.log_text()[-2000:]
    # The console's timed press (feedback_pressed) is a person's feedback too.
    console = probe.publisher(Vector3Stamped, topics.FEEDBACK_PRESSED, qos.HUMAN)
    assert probe.wait_for_subscribers(console, timeout=STARTUP_S)
    timed = Vector3Stamped()
    timed.header.stamp = ns_to_stamp(frames_to_ns(4 * 39))
    timed.vector.x = -0.5
    console.publish(timed)
    assert trainer.wait_for_log('a person gave feedback -0.5', REPLY_S), trainer.log_text()[-2000:]
    log = trainer.log_text()
    for reason in ('empty utterance', 'whitespace-only utterance', 'non-ASCII characters',
                   'utterance of 100000 characters'):
        assert f'bad utterance ignored ({reason}' in log, reason
    assert log.count('bad feedback ignored: feedback') == 3
    assert 'feedback nan is not a finite number' in log and 'feedback -inf is not a' in log
    # The person's messages are the only ones on the topics: the trainer said nothing more.
    assert (len(listener.feedback_stamped.snapshot()),
            len(listener.utterance_stamped.snapshot())) == (before[0], before[1])
    assert trainer.alive()
    assert trainer.stop(signal.SIGINT) == 0


def test_synthetic_false_publishes_nothing(probe, start_node):
    listener = TrainerListener(probe)
    positions = probe.publisher(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    person_says = probe.publisher(String, topics.UTTERANCE, qos.HUMAN)
    trainer = start_node('feedback_node', {'synthetic': False, 'utterance_interval': 0.0})
    assert probe.wait_for_subscribers(positions, timeout=STARTUP_S)
    assert probe.wait_for_subscribers(person_says, timeout=STARTUP_S)
    publish_positions(positions, range(0, 20))
    say_until_heard(person_says, trainer, 'Climb up the ladder.', step=19)
    assert listener.feedback_stamped.snapshot() == []
    assert listener.utterance_stamped.snapshot() == []
    assert listener.feedback.snapshot() == []
    assert {m.data for m in listener.utterance.snapshot()} == {'Climb up the ladder.'}
    assert trainer.stop(signal.SIGINT) == 0


def test_stamped_feedback_has_no_plain_copy_unless_asked(probe, start_node):
    """The learner needs one message per judgement: the plain twin is off by default."""
    listener = TrainerListener(probe)
    positions = probe.publisher(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    trainer = start_node('feedback_node', {'utterance_interval': 0.0})
    assert probe.wait_for_subscribers(positions, timeout=STARTUP_S)
    assert wait_until(lambda: probe.node.count_publishers(topics.FEEDBACK) >= 1, STARTUP_S)
    # Both utterance topics matched before the first step, so each hears every sentence.
    for log in (listener.utterance, listener.utterance_stamped):
        assert probe.wait_matched(log, timeout=STARTUP_S)
    publish_positions(positions, range(0, 20))
    assert listener.feedback_stamped.wait_count(19, REPLY_S), trainer.log_text()[-2000:]
    # The plain utterances are published after the feedback of the same step.
    assert listener.utterance.wait_count(len(listener.utterance_stamped.snapshot()), REPLY_S)
    assert listener.utterance.snapshot()
    assert listener.feedback.snapshot() == []
    assert trainer.stop(signal.SIGINT) == 0


def test_judgements_wait_until_every_expected_reader_is_matched(probe, start_node):
    """wait_feedback_subscribers 2: one reader matched is not enough; then both get them all."""
    first = TrainerListener(probe)
    positions = probe.publisher(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    trainer = start_node('feedback_node', {'utterance_interval': 0.0,
                                           'wait_feedback_subscribers': 2})
    assert probe.wait_for_subscribers(positions, timeout=STARTUP_S)
    assert wait_until(lambda: probe.node.count_publishers(topics.FEEDBACK_STAMPED) >= 1,
                      STARTUP_S)
    publish_positions(positions, range(0, 20))
    # Utterances are not held: once they are in, the judgements were made (and held).
    assert first.utterance_stamped.wait_count(1, REPLY_S), trainer.log_text()[-2000:]
    assert first.feedback_stamped.snapshot() == []
    second = probe.subscribe(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    assert first.feedback_stamped.wait_count(19, REPLY_S), trainer.log_text()[-2000:]
    assert second.wait_count(19, REPLY_S)
    assert (sorted(stamp_to_ns(m.header.stamp) for m in second.snapshot())
            == sorted(stamp_to_ns(m.header.stamp) for m in first.feedback_stamped.snapshot()))
    assert trainer.stop(signal.SIGINT) == 0


def test_utterances_wait_until_every_expected_listener_is_matched(probe, start_node):
    """wait_utterance_subscribers 2: the first words, said at the first step, reach both."""
    first = TrainerListener(probe)
    positions = probe.publisher(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    trainer = start_node('feedback_node', {'utterance_interval': 0.0,
                                           'wait_utterance_subscribers': 2})
    assert probe.wait_for_subscribers(positions, timeout=STARTUP_S)
    assert wait_until(lambda: probe.node.count_publishers(topics.UTTERANCE) >= 1, STARTUP_S)
    publish_positions(positions, range(0, 20))
    assert first.feedback_stamped.wait_count(19, REPLY_S), trainer.log_text()[-2000:]
    assert first.utterance.snapshot() == [] and first.utterance_stamped.snapshot() == []
    second = probe.subscribe(String, topics.UTTERANCE, qos.HUMAN)
    also = probe.subscribe(DiagnosticArray, topics.UTTERANCE_STAMPED, qos.HUMAN)
    assert second.wait_count(1, REPLY_S), trainer.log_text()[-2000:]
    assert wait_until(lambda: len(first.utterance.snapshot()) == len(second.snapshot())
                      == len(first.utterance_stamped.snapshot()) >= 19, REPLY_S)
    assert [m.data for m in first.utterance.snapshot()] == [m.data for m in second.snapshot()]
    assert also.wait_count(len(second.snapshot()), REPLY_S)
    assert trainer.stop(signal.SIGINT) == 0


def test_the_trainer_listens_to_the_steps_only_once_the_named_readers_are_matched(
        probe, start_node):
    """
    A viewer's reader makes a count, not a learner: the trainer waits for its readers by name.

    It subscribes to the steps (and so lets the env take its first) only once the learner and
    the saliency node are matched. Before, a Foxglove client watching the feedback counted as
    the learner, and tamer_node, still being discovered, missed the first 224 judgements of a
    run; and in a short run the first words reached the saliency node 66 steps late.
    """
    viewer = TrainerListener(probe)  # the probe: a reader of everything, not the learner
    positions = probe.publisher(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    trainer = start_node('feedback_node', {
        'utterance_interval': 0.0, 'wait_feedback_subscribers': 1,
        'wait_utterance_subscribers': 1, 'wait_feedback_nodes': 'the_learner',
        'wait_utterance_nodes': 'the_learner', 'wait_utterance_stamped_nodes': 'the_grounder'})
    assert wait_until(lambda: probe.node.count_publishers(topics.FEEDBACK_STAMPED) >= 1,
                      STARTUP_S)
    assert not probe.wait_for_subscribers(positions, timeout=2.0)  # no learner: not listening
    with TopicProbe('the_learner') as learner_probe:
        learner = TrainerListener(learner_probe)
        assert not probe.wait_for_subscribers(positions, timeout=2.0)  # nor without grounder
        with TopicProbe('the_grounder') as grounder_probe:
            grounder = TrainerListener(grounder_probe)
            assert probe.wait_for_subscribers(positions, timeout=STARTUP_S)
            publish_positions(positions, range(0, 20))
            assert learner.feedback_stamped.wait_count(19, REPLY_S), trainer.log_text()[-2000:]
            assert grounder.utterance_stamped.wait_count(1, REPLY_S)
            assert wait_until(lambda: [m.data for m in learner.utterance.snapshot()]
                              == [m.data for m in viewer.utterance.snapshot()]
                              != [], REPLY_S)  # the first words too, to both
            first = min(stamp_to_ns(m.header.stamp) for m in learner.feedback_stamped.snapshot())
            assert first == min(stamp_to_ns(m.header.stamp)
                                for m in viewer.feedback_stamped.snapshot())
    assert trainer.stop(signal.SIGINT) == 0

"""
The teacher over topics: the real env_node and feedback_node (``trainer:=teacher``) executables.

A probe plays the learner: it answers each observation with the scripted expert's action (from
the step's ``env_status``, as the teacher sees it) except on every fourth step, where it does
something that is not the same. The teacher must judge exactly the action the env applied for
each step, stamped with that step, +1 for the expert's and -1 for the others; with a delay it
must publish only the plain ``feedback``, as a person's ``ros2 topic pub`` would.
"""

import signal
import time

from attention_common import qos, topics
from attention_common.joy_actions import action_to_joy, NUM_ACTIONS
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from attention_tasks.montezuma.action_effects import EffectTable, place_of, Situation
from attention_tasks.montezuma.expert import FIRE_ACTIONS, RoomOneExpert
from attention_tasks.montezuma.teaching import SeenStep
from diagnostic_msgs.msg import DiagnosticArray
from env_node.status import parse_status
from geometry_msgs.msg import Vector3Stamped
from harness import wait_until
import pytest
from sensor_msgs.msg import Image, Joy
from std_msgs.msg import Float32, String

pytestmark = pytest.mark.topics

STARTUP_S = 30.0
REPLY_S = 10.0


def status_values(msg):
    return parse_status((kv.key, kv.value) for kv in msg.status[0].values)


class Player:
    """The probe's learner: mostly the expert, every fourth step a different action."""

    def __init__(self, probe):
        self.statuses = probe.subscribe(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
        self.observations = probe.subscribe(Image, topics.OBSERVATION, qos.FRAMES)
        self.actions = probe.publisher(Joy, topics.ACTION, qos.ACTIONS)
        self.table = EffectTable.load()
        self.expert = RoomOneExpert()
        self.expert.reset()
        self.played = {}   # stamp -> (action, expert action, deliberately wrong)
        self._probe = probe

    def _status(self, stamp_ns):
        def found(msgs):
            return any(stamp_to_ns(m.header.stamp) == stamp_ns for m in msgs)
        assert self.statuses.wait_for(found, REPLY_S), f'no env_status stamped {stamp_ns}'
        msg = next(m for m in self.statuses.snapshot() if stamp_to_ns(m.header.stamp) == stamp_ns)
        return status_values(msg)

    def play(self, steps: int, ask_every: int = 0) -> None:
        """Play ``steps`` steps; with ``ask_every``, ask the teacher about every such step."""
        questions = self._probe.publisher(Vector3Stamped, topics.QUESTION, qos.HUMAN)
        self.asked = []
        assert self.observations.wait_count(1, STARTUP_S), 'no observation from env_node'
        assert self._probe.wait_for_subscribers(self.actions, timeout=STARTUP_S)
        last = -1
        for index in range(steps):
            def newer(msgs):
                return any(stamp_to_ns(m.header.stamp) > last for m in msgs)
            assert self.observations.wait_for(newer, REPLY_S), f'no observation after {last}'
            stamp_ns = min(stamp_to_ns(m.header.stamp) for m in self.observations.snapshot()
                           if stamp_to_ns(m.header.stamp) > last)
            v = self._status(stamp_ns)
            seen = SeenStep(v['x'], v['y'], v['has_key'], v['pose'], v['skull_x'], v['action'])
            previous = v['action'] if v['action'] >= 0 else None
            expert_action = self.expert.act(seen, seen.skull_x, previous_action=previous)
            action, wrong = expert_action, False
            if index % 4 == 3:
                situation = Situation(self.expert.phase.name, place_of(seen.x, seen.y),
                                      seen.pose, v['action'] in FIRE_ACTIONS)
                action = next(a for a in range(NUM_ACTIONS)
                              if not self.table.equivalent(situation, a, expert_action))
                wrong = True
            axes, buttons = action_to_joy(action)
            joy = Joy(axes=list(axes), buttons=list(buttons))
            joy.header.stamp = ns_to_stamp(stamp_ns)
            self.actions.publish(joy)
            self.played[stamp_ns] = (action, expert_action, wrong)
            if ask_every and index % ask_every == 2:  # after the action, as tamer_node asks
                question = Vector3Stamped()
                question.header.stamp = joy.header.stamp
                question.vector.x, question.vector.y = float(action), 0.1
                questions.publish(question)
                self.asked.append(stamp_ns)
            last = stamp_ns


def start_graph(probe, start_node, teacher_params):
    feedback_stamped = probe.subscribe(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    feedback = probe.subscribe(Float32, topics.FEEDBACK, qos.HUMAN)
    utterances = probe.subscribe(String, topics.UTTERANCE, qos.HUMAN)
    player = Player(probe)
    teacher = start_node('feedback_node', dict({'trainer': 'teacher'}, **teacher_params))
    assert teacher.wait_for_log('teacher: judges each action', STARTUP_S), teacher.log_text()
    assert wait_until(lambda: probe.node.count_subscribers(topics.ENV_STATUS) >= 2, STARTUP_S)
    # env_node steps once the teacher (and the probe) hear its env_status: lockstep plays 120
    # steps in about a second, faster than a late DDS match.
    start_node('env_node', {'warmup_steps': 0, 'sticky_actions': 0.0, 'seed': 0,
                            'wait_status_subscribers': 2})
    return player, teacher, feedback_stamped, feedback, utterances


def test_the_teacher_judges_the_applied_action_of_each_step(probe, start_node):
    player, teacher, stamped, plain, utterances = start_graph(
        probe, start_node, {'utterance_interval': 2.0})
    player.play(120)
    wrong = {s for s, (_, _, w) in player.played.items() if w}
    assert stamped.wait_for(lambda msgs: len(msgs) >= 40, REPLY_S), teacher.log_text()[-3000:]
    time.sleep(0.5)  # the last judgements in flight
    received = {stamp_to_ns(m.header.stamp): m.vector for m in stamped.snapshot()}
    assert len(received) == len(stamped.snapshot())  # no step judged twice
    assert set(received) <= set(player.played)
    for stamp, vector in received.items():
        action, expert_action, was_wrong = player.played[stamp]
        assert int(vector.z) == action, f'step {stamp}: judged {vector.z}, played {action}'
        assert int(vector.y) == expert_action
        assert vector.x == (-1.0 if was_wrong else 1.0), f'step {stamp}: h {vector.x}'
    assert {s for s in received if received[s].x < 0} == wrong & set(received)
    assert len(wrong & set(received)) >= 8
    # The stage sentences are spoken; a stamped judgement has no plain copy (plain_copies).
    assert utterances.wait_count(2, REPLY_S)
    assert plain.snapshot() == []
    assert teacher.alive() and teacher.stop(signal.SIGINT) == 0


def test_late_feedback_is_plain_only(probe, start_node):
    player, teacher, stamped, plain, _ = start_graph(
        probe, start_node, {'utterance_interval': -1.0, 'feedback_delay_min': 0.3,
                            'feedback_delay_max': 0.6})
    player.play(80)
    assert plain.wait_count(30, REPLY_S), teacher.log_text()[-3000:]
    assert stamped.snapshot() == []
    assert {m.data for m in plain.snapshot()} == {-1.0, 1.0}
    assert teacher.wait_for_log('plain feedback only', 1.0)
    assert teacher.stop(signal.SIGINT) == 0


def test_late_feedback_with_press_times_carries_the_moment_it_was_given(probe, start_node):
    pressed = probe.subscribe(Vector3Stamped, topics.FEEDBACK_PRESSED, qos.HUMAN)
    player, teacher, stamped, plain, _ = start_graph(
        probe, start_node, {'utterance_interval': -1.0, 'feedback_delay_min': 0.3,
                            'feedback_delay_max': 0.6, 'press_times': True})
    player.play(80)
    assert pressed.wait_count(30, REPLY_S), teacher.log_text()[-3000:]
    assert stamped.snapshot() == [] and plain.snapshot() == []  # no stamp, no plain copy
    steps = sorted(player.played)
    for msg in pressed.snapshot():
        moment = stamp_to_ns(msg.header.stamp)
        assert moment not in player.played  # a moment between steps, not a step's stamp
        # Some step T, seen done at the next step T', was judged 0.3-0.6 s after T': its
        # action is the one the verdict names, with the sign the player's choice deserves.
        judged = [(t, player.played[t]) for t, seen in zip(steps, steps[1:])
                  if 0.3e9 - 1 <= moment - seen <= 0.6e9 + 1]
        assert any(int(msg.vector.z) == action and int(msg.vector.y) == expert
                   and msg.vector.x == (-1.0 if wrong else 1.0)
                   for _, (action, expert, wrong) in judged), (moment, msg.vector)
    assert teacher.wait_for_log('feedback_pressed with the moment given', 1.0)
    assert teacher.stop(signal.SIGINT) == 0


def test_a_marking_teacher_gives_some_late_verdicts_with_their_step(probe, start_node):
    # feedback_marked 0.5: as a person who pauses to judge every other verdict. Those go out
    # on feedback_stamped with the step they judge; the others plain; none twice.
    player, teacher, stamped, plain, _ = start_graph(
        probe, start_node, {'utterance_interval': -1.0, 'feedback_delay_min': 0.3,
                            'feedback_delay_max': 0.6, 'feedback_marked': 0.5})
    player.play(100)
    assert plain.wait_count(20, REPLY_S) and stamped.wait_count(20, REPLY_S), (
        teacher.log_text()[-3000:])
    time.sleep(0.5)  # the last judgements in flight
    for msg in stamped.snapshot():
        action, expert_action, wrong = player.played[stamp_to_ns(msg.header.stamp)]
        assert (int(msg.vector.z), int(msg.vector.y)) == (action, expert_action)
        assert msg.vector.x == (-1.0 if wrong else 1.0)  # (no noise set: every sign right)
    marked, given = len(stamped.snapshot()), len(stamped.snapshot()) + len(plain.snapshot())
    assert 0.3 <= marked / given <= 0.7, (marked, given)
    assert teacher.wait_for_log('marked 0.5', 1.0)
    assert teacher.stop(signal.SIGINT) == 0


def test_the_teacher_answers_a_question_about_a_step_stamped_with_it(probe, start_node):
    # The learner asks about a step (topic question, after its action): the human-like
    # teacher, late and plain otherwise, answers on feedback_stamped with that step's stamp,
    # judging the action the env applied there; a step asked about is not also judged late.
    player, teacher, stamped, plain, _ = start_graph(
        probe, start_node, {'utterance_interval': -1.0, 'feedback_delay_min': 0.3,
                            'feedback_delay_max': 0.6, 'feedback_probability': 1.0})
    player.play(100, ask_every=5)
    assert stamped.wait_count(15, REPLY_S), teacher.log_text()[-3000:]
    time.sleep(1.0)  # the last late verdicts in flight
    answers = [stamp_to_ns(m.header.stamp) for m in stamped.snapshot()]
    assert len(set(answers)) == len(answers) and set(answers) <= set(player.asked)
    for msg in stamped.snapshot():
        action, expert_action, wrong = player.played[stamp_to_ns(msg.header.stamp)]
        assert (int(msg.vector.z), int(msg.vector.y)) == (action, expert_action)
        assert msg.vector.x == (-1.0 if wrong else 1.0)
    # Every step judged once at most: late and plain, or as an answer (the steps in the air
    # are not judged, nor those whose delay outlasts the play).
    assert 50 <= len(plain.snapshot()) and len(plain.snapshot()) + len(answers) <= 99
    assert teacher.stop(signal.SIGINT) == 0

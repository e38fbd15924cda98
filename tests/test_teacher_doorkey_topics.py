"""
The DoorKey teacher over topics: the real feedback_node executable with ``task:=doorkey``.

The probe plays env_node: it publishes the env_status of a real ``DoorKeyEnv`` on which the
expert plays, every fifth step an action that changes nothing instead (a step lost), with a few
unreadable statuses in between. The node must judge each step's action, stamped with that step,
+1 for the expert's and -1 for the lost ones, say the next sub-goal's sentence, drop and count
the bad statuses and keep going; with ``trainer:=thesis`` (or an unknown task) it must not start.
"""

import copy
import signal
import time

from attention_common import qos, topics
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
from attention_tasks.doorkey.expert import next_action
from attention_tasks.doorkey.world import progress
from attention_tasks.doorkey.world import state_of
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from env_node.status import Counters, STATUS_NAME, status_values
from geometry_msgs.msg import Vector3Stamped
from harness import wait_until
import pytest
from std_msgs.msg import Float32

pytestmark = pytest.mark.topics

STARTUP_S = 30.0
REPLY_S = 10.0
PUBLISH_GAP_S = 0.005


def status_msg(stamp_ns, pairs, name=STATUS_NAME):
    msg = DiagnosticArray(status=[DiagnosticStatus(
        name=name, values=[KeyValue(key=k, value=v) for k, v in pairs])])
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def lost_step(world):
    """Return an action that changes nothing in ``world``'s state (None if none does)."""
    before = state_of(world)
    for action in (3, 4, 5, 2):  # pickup, drop, toggle, forward
        trial = copy.deepcopy(world)
        trial.step(action)
        if state_of(trial) == before:
            return action
    return None


def play(steps=70, seed=0):
    """
    Play a real level: the expert, every fifth step a lost step.

    Return the steps to publish and ``{stamp: (action, expert action, h)}`` of each step whose
    action is judged.
    """
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed))
    published, expected = [], {}
    step = env.reset()
    try:
        for index in range(steps):
            published.append(step)
            expert_action = next_action(env.world)
            lost = lost_step(env.world) if index % 5 == 4 else None
            action = expert_action if lost is None else lost
            expected[step.sim_time_ns] = (action, expert_action, 1.0 if lost is None else -1.0)
            step = env.step(action)
            if step.done:
                published.append(step)
                step = env.reset()
        published.append(step)
    finally:
        env.close()
    return published, expected


def bad_statuses(step):
    """Unreadable statuses stamped like ``step``: no grid, a bad grid, off the grid, not ours."""
    pairs = status_values(step, Counters(), False)

    def changed(key, value):
        return [(k, value if k == key else v) for k, v in pairs if value is not None or k != key]
    return [status_msg(step.sim_time_ns, changed('grid', None)),
            status_msg(step.sim_time_ns, changed('grid', 'not hex')),
            status_msg(step.sim_time_ns, changed('grid', dict(pairs)['grid'][:-6])),
            status_msg(step.sim_time_ns, changed('x', '12')),
            status_msg(step.sim_time_ns, changed('action', '9')),
            status_msg(step.sim_time_ns, pairs, name='other_node')]


def test_the_doorkey_teacher_judges_each_action_and_names_the_sub_goals(probe, start_node):
    stamped = probe.subscribe(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    plain = probe.subscribe(Float32, topics.FEEDBACK, qos.HUMAN)
    utterances = probe.subscribe(DiagnosticArray, topics.UTTERANCE_STAMPED, qos.HUMAN)
    statuses = probe.publisher(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
    teacher = start_node('feedback_node', {'task': 'doorkey', 'trainer': 'teacher',
                                           'utterance_interval': 2.0, 'summary_period': 0.5})
    assert teacher.wait_for_log('teacher of task doorkey: judges each action', STARTUP_S), (
        teacher.log_text())
    assert probe.wait_for_subscribers(statuses, timeout=STARTUP_S)
    published, expected = play()
    by_stamp = {step.sim_time_ns: step for step in published}
    bad = 0
    for index, step in enumerate(published):
        statuses.publish(status_msg(step.sim_time_ns, status_values(step, Counters(), False)))
        if index in (10, 40):
            for msg in bad_statuses(step):
                statuses.publish(msg)
                bad += 1
        time.sleep(PUBLISH_GAP_S)
    assert stamped.wait_for(lambda msgs: len(msgs) >= len(expected), REPLY_S), (
        teacher.log_text()[-3000:])
    # Every step whose next step was seen in the same episode, once, with its own stamp.
    received = {stamp_to_ns(m.header.stamp): m.vector for m in stamped.snapshot()}
    assert len(received) == len(stamped.snapshot())
    assert set(received) == set(expected)
    for stamp, vector in received.items():
        action, expert_action, h = expected[stamp]
        assert (vector.x, int(vector.y), int(vector.z)) == (h, expert_action, action), stamp
    assert sum(v.x < 0 for v in received.values()) >= 10
    assert plain.snapshot() == []  # stamped only (no delay, no plain_copies)
    # The next sub-goal's sentence, at the interval and at each new layout's first step.
    assert utterances.wait_count(5, REPLY_S)
    episode_starts = {s.sim_time_ns for s in published if s.episode_step == 0}
    said = {stamp_to_ns(m.header.stamp): m.status[0] for m in utterances.snapshot()}
    assert episode_starts <= set(said)
    for stamp, status in said.items():
        state = by_stamp[stamp].state
        values = {kv.key: kv.value for kv in status.values}
        assert values == {'position': '-1', 'sentence_of': str(progress(state))}
        assert (state.door_color if progress(state) < 2 else 'green') in status.message
    # The bad statuses were dropped, said and counted; the node kept going.
    assert wait_until(lambda: teacher.log_text().count('env_status dropped') == bad, REPLY_S)
    assert teacher.wait_for_log(f'bad_status {bad}', REPLY_S), teacher.log_text()[-2000:]
    assert teacher.alive() and teacher.stop(signal.SIGINT) == 0


@pytest.mark.parametrize('params, message', [
    ({'task': 'doorkey', 'trainer': 'thesis'}, "trainer 'thesis' measures Room 1's critical"),
    ({'task': 'sokoban', 'trainer': 'teacher'}, 'installed tasks: doorkey, fetch, montezuma'),
])
def test_the_node_refuses_a_trainer_the_task_cannot_have(start_node, params, message):
    node = start_node('feedback_node', params)
    assert node.process.wait(timeout=STARTUP_S) == 1
    assert '[startup error]' in node.log_text() and message in node.log_text()

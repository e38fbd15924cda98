"""The real env_node executable, driven only over topics by a probe node acting as the learner."""

import math
import signal
import time

from attention_common import qos, topics
from attention_common.image_codec import image_to_numpy
from attention_common.joy_actions import action_to_joy
from attention_common.preview import preview_topic
from attention_common.stamps import frames_to_ns, stamp_to_ns
from diagnostic_msgs.msg import DiagnosticArray
from env_node.status import NO_LATENCY, parse_status
from geometry_msgs.msg import PointStamped
from harness import TopicProbe, wait_until
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, Joy
from std_srvs.srv import Trigger

pytestmark = pytest.mark.topics

NOOP, UP, RIGHT, LEFT, DOWN = 0, 2, 3, 4, 5
STARTUP_S = 30.0  # importing, making the emulator and the warm-up, on a busy machine
REPLY_S = 10.0
FRAMESKIP = 4
PREVIEW_READER = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
"""Keeps every preview that comes (the previews are best effort)."""


class Learner:
    """The probe's side of the contract: observe, answer by stamp, read positions and status."""

    def __init__(self, probe):
        self.observations = probe.subscribe(Image, topics.OBSERVATION, qos.FRAMES)
        self.positions = probe.subscribe(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
        self.statuses = probe.subscribe(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
        self.clock = probe.subscribe(Clock, topics.CLOCK, qos.CLOCK)
        self.actions = probe.publisher(Joy, topics.ACTION, qos.ACTIONS)
        self._probe = probe

    def connect(self, timeout=STARTUP_S):
        """Wait for the env's first observation and for it to hear our actions."""
        assert self.observations.wait_count(1, timeout), 'no observation from env_node'
        assert self._probe.wait_for_subscribers(self.actions, timeout=timeout)
        return self.observations.snapshot()[0]

    def send(self, stamp_ns, action=NOOP, axes=None, buttons=None):
        default_axes, default_buttons = action_to_joy(action)
        msg = Joy(axes=list(default_axes if axes is None else axes),
                  buttons=list(default_buttons if buttons is None else buttons))
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        self.actions.publish(msg)

    def next_observation(self, after_ns, timeout=REPLY_S):
        """Wait for an observation stamped later than ``after_ns`` and return it."""
        def newer(messages):
            return any(stamp_to_ns(m.header.stamp) > after_ns for m in messages)
        assert self.observations.wait_for(newer, timeout), f'no observation after {after_ns}'
        return next(m for m in self.observations.snapshot()
                    if stamp_to_ns(m.header.stamp) > after_ns)

    def step(self, observation, action=NOOP):
        """Answer ``observation`` and return the next one."""
        stamp = stamp_to_ns(observation.header.stamp)
        self.send(stamp, action)
        return self.next_observation(stamp)

    def status_at(self, stamp_ns, timeout=REPLY_S):
        def found(messages):
            return any(stamp_to_ns(m.header.stamp) == stamp_ns for m in messages)
        assert self.statuses.wait_for(found, timeout), f'no env_status stamped {stamp_ns}'
        msg = next(m for m in self.statuses.snapshot() if stamp_to_ns(m.header.stamp) == stamp_ns)
        return parse_status((kv.key, kv.value) for kv in msg.status[0].values)

    def position_at(self, stamp_ns, timeout=REPLY_S):
        def found(messages):
            return any(stamp_to_ns(m.header.stamp) == stamp_ns for m in messages)
        assert self.positions.wait_for(found, timeout), f'no agent_position stamped {stamp_ns}'
        return next(m.point for m in self.positions.snapshot()
                    if stamp_to_ns(m.header.stamp) == stamp_ns)


def stamps(messages):
    return [stamp_to_ns(m.header.stamp) for m in messages]


def test_lockstep_frames_stamps_and_motion(start_node, probe):
    learner = Learner(probe)
    env = start_node('env_node', {'action_timeout': 30.0})  # default warm-up of 100 steps
    observation = learner.connect()
    first_ns = stamp_to_ns(observation.header.stamp)
    assert first_ns == frames_to_ns((100 + 1) * FRAMESKIP)  # the warm-up steps went unpublished
    learner.position_at(first_ns)
    assert min(stamps(learner.positions.snapshot())) == first_ns
    for action in [RIGHT, RIGHT, LEFT, LEFT, DOWN, DOWN, UP, UP] * 2:
        observation = learner.step(observation, action)
    received = learner.observations.snapshot()
    for msg in received:
        assert (msg.encoding, msg.height, msg.width, msg.step) == ('rgb8', 210, 160, 480)
        assert image_to_numpy(msg).shape == (210, 160, 3)
    observed = sorted(set(stamps(received)))  # start-up may send the first one again
    assert stamps(received) == sorted(stamps(received))  # never older than one already sent
    assert len(observed) == 17
    # Every observed step has its position (published right after its observation).
    assert learner.positions.wait_for(lambda m: set(observed) <= set(stamps(m)), REPLY_S)
    assert learner.clock.wait_for(
        lambda m: stamp_to_ns(m[-1].clock) == observed[-1], REPLY_S)  # /clock follows the steps
    points = {(learner.position_at(s).x, learner.position_at(s).y) for s in observed}
    assert len(points) > 1  # the agent moved
    last = learner.status_at(observed[-1])
    assert last['agent_step'] == 16 and last['room'] == 1 and not last['finished']
    # The env times its closed loop: the first step answered nothing, later ones one action each.
    assert learner.status_at(first_ns)['action_latency_ms'] == NO_LATENCY
    assert 0.0 < last['action_latency_ms'] < 1000.0 * REPLY_S
    assert env.stop(signal.SIGINT) == 0


def test_the_previews_are_the_steps_own_messages_thinned_to_their_rate(start_node, probe):
    """A viewer reads observation/preview and env_status/preview: the same steps, fewer."""
    learner = Learner(probe)
    previews = {topic: probe.subscribe(msg_type, preview_topic(topic), PREVIEW_READER)
                for topic, msg_type in ((topics.OBSERVATION, Image),
                                        (topics.ENV_STATUS, DiagnosticArray))}
    env = start_node('env_node', {'warmup_steps': 0, 'action_timeout': 30.0,
                                  'preview_rate_hz': 10.0})
    observation = learner.connect()
    for log in previews.values():
        assert probe.wait_matched(log, timeout=STARTUP_S)
    started = time.monotonic()
    for _ in range(150):  # lockstep, as fast as this probe answers
        observation = learner.step(observation, RIGHT)
    elapsed = time.monotonic() - started
    learner.status_at(stamp_to_ns(observation.header.stamp))  # the last step's status is here
    full = {topics.OBSERVATION: set(stamps(learner.observations.snapshot())),
            topics.ENV_STATUS: set(stamps(learner.statuses.snapshot()))}
    for topic, log in previews.items():
        thinned = stamps(log.snapshot())
        assert thinned, f'nothing on {preview_topic(topic)}'
        assert set(thinned) <= full[topic]  # the steps' own messages, nothing made up
        # At most 10 a second, bursts of 5: far fewer than the 150 steps sent.
        assert len(thinned) <= 5 + 10.0 * elapsed + 1, (topic, len(thinned), elapsed)
    assert env.stop(signal.SIGINT) == 0


def test_wrong_stamps_and_bad_actions_are_dropped_and_counted(start_node, probe):
    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'action_timeout': 30.0})
    observation = learner.connect()
    pending = stamp_to_ns(observation.header.stamp)
    one_step = frames_to_ns(2 * FRAMESKIP) - frames_to_ns(FRAMESKIP)
    learner.send(pending - one_step, RIGHT)   # late: an earlier frame's stamp
    learner.send(pending + one_step, RIGHT)   # from the future
    learner.send(0, RIGHT)                    # a gamepad's own stamp
    learner.send(pending, axes=[math.nan, 0.0], buttons=[0])
    learner.send(pending, axes=[2.0, 0.0], buttons=[0])
    learner.send(pending, axes=[0.0], buttons=[0])
    learner.send(pending, axes=[0.0, 0.0], buttons=[])
    learner.send(pending, NOOP)               # the answer
    observation = learner.next_observation(pending)
    assert stamp_to_ns(observation.header.stamp) == pending + one_step  # exactly one step
    status = learner.status_at(pending + one_step)
    assert status['agent_step'] == 1
    assert status['dropped_actions'] == 7 and status['bad_actions'] == 4
    assert learner.position_at(pending + one_step).x == learner.position_at(pending).x  # NOOP
    assert env.alive()

    learner.send(pending, RIGHT)  # a late duplicate of the answer already applied
    observation = learner.step(observation, NOOP)
    status = learner.status_at(stamp_to_ns(observation.header.stamp))
    assert status['agent_step'] == 2 and status['dropped_actions'] == 8
    assert 'dropped' in env.log_text() and 'bad action' in env.log_text()
    assert env.stop(signal.SIGINT) == 0


def test_timeout_publishes_the_pending_observation_again(start_node, probe):
    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'action_timeout': 0.5})
    observation = learner.step(learner.connect(), RIGHT)  # past start-up: now timeouts count
    pending = stamp_to_ns(observation.header.stamp)
    assert learner.status_at(pending)['timeouts'] == 0
    assert learner.observations.wait_for(lambda m: stamps(m).count(pending) >= 2, REPLY_S)
    again = [m for m in learner.observations.snapshot() if stamp_to_ns(m.header.stamp) == pending]
    assert again[1].data == again[0].data  # the same observation, the same stamp
    observation = learner.step(again[1], RIGHT)
    status = learner.status_at(stamp_to_ns(observation.header.stamp))
    assert status['timeouts'] >= 1 and status['agent_step'] == 2
    assert 'no action stamped' in env.log_text()
    assert env.stop(signal.SIGTERM) == 0


def test_terminal_step_reset_and_max_steps(start_node, probe):
    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'action_timeout': 30.0, 'max_steps': 25,
                                  'end_on_life_loss': True})
    observation = learner.connect()
    terminal = None
    for _ in range(24):  # walking right off the middle platform kills the agent
        stamp = stamp_to_ns(observation.header.stamp)
        observation = learner.step(observation, RIGHT)
        after = stamp_to_ns(observation.header.stamp)
        if learner.status_at(after)['episode'] == 1:
            terminal = [s for s in stamps(learner.statuses.snapshot()) if stamp < s < after]
            break
    assert terminal, 'the episode never ended'
    # The terminal step: its position and status went out (the last action gets judged), ...
    assert len(terminal) == 1 and learner.status_at(terminal[0])['terminated']
    assert learner.status_at(terminal[0])['life_lost']
    learner.position_at(terminal[0])
    # ... no observation; the reset step is the next pending observation.
    assert terminal[0] not in stamps(learner.observations.snapshot())
    assert learner.status_at(after)['episode_step'] == 0

    while learner.status_at(stamp_to_ns(observation.header.stamp))['agent_step'] < 24:
        observation = learner.step(observation, NOOP)
    pending = stamp_to_ns(observation.header.stamp)
    learner.send(pending, NOOP)  # step 25, the last one
    assert learner.statuses.wait_for(
        lambda m: parse_status((kv.key, kv.value) for kv in m[-1].status[0].values)['finished'],
        REPLY_S)
    final = stamp_to_ns(learner.statuses.snapshot()[-1].header.stamp)
    assert learner.status_at(final)['agent_step'] == 25
    assert final not in stamps(learner.observations.snapshot())
    learner.send(pending, NOOP)  # nothing is pending any more
    learner.send(final, NOOP)
    assert env.wait_for_log('no observation is pending', REPLY_S) and env.alive()
    assert env.stop(signal.SIGINT) == 0


def test_real_time_steps_with_the_latest_action(start_node, probe):
    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'rate_hz': 30})  # an integer works too
    assert learner.observations.wait_count(3, STARTUP_S)  # it steps without being answered
    assert learner.positions.wait_count(3, REPLY_S)
    assert probe.wait_for_subscribers(learner.actions, timeout=STARTUP_S)
    start_x = learner.positions.snapshot()[0].point.x
    assert all(m.point.x == start_x for m in learner.positions.snapshot())  # NOOP so far
    learner.send(0, RIGHT)  # any stamp: a gamepad's
    assert learner.positions.wait_for(lambda m: m[-1].point.x > start_x, REPLY_S)
    observed = stamps(learner.observations.snapshot())
    assert all(b > a for a, b in zip(observed, observed[1:]))
    learner.send(0, axes=[math.inf, 0.0], buttons=[0])
    assert env.wait_for_log('bad action', REPLY_S) and env.alive()
    count = len(learner.observations.snapshot())
    assert learner.observations.wait_count(count + 2, REPLY_S)  # still stepping
    assert env.stop(signal.SIGINT) == 0


def set_paused(probe, value):
    client = AsyncParameterClient(probe.node, 'env_node')
    assert client.wait_for_services(timeout_sec=10.0)
    future = client.set_parameters([Parameter('paused', value=value)])
    assert wait_until(future.done, 10.0)
    return future.result().results[0]


def test_pause_and_resume_in_real_time_and_lockstep(start_node, probe):
    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'rate_hz': 30})
    assert learner.observations.wait_count(3, STARTUP_S)
    assert set_paused(probe, True).successful
    assert env.wait_for_log('paused', REPLY_S)
    count = len(learner.observations.snapshot())
    assert not learner.observations.wait_count(count + 2, 1.0)  # at most one in flight
    paused_at = len(learner.observations.snapshot())
    assert not set_paused(probe, 'yes').successful  # only a boolean
    assert set_paused(probe, False).successful
    assert learner.observations.wait_count(paused_at + 3, REPLY_S)  # stepping again
    assert env.stop(signal.SIGINT) == 0

    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'action_timeout': 30.0},
                     name='env_lockstep')
    observation = learner.step(learner.connect(), RIGHT)
    assert set_paused(probe, True).successful
    pending = stamp_to_ns(observation.header.stamp)
    learner.send(pending, RIGHT)  # the answer comes while paused: it waits
    assert not learner.observations.wait_for(
        lambda ms: stamp_to_ns(ms[-1].header.stamp) > pending, 1.0)
    assert set_paused(probe, False).successful
    following = learner.next_observation(pending)  # applied on resume, once
    status = learner.status_at(stamp_to_ns(following.header.stamp))
    assert status['agent_step'] == 2 and status['dropped_actions'] == 0
    assert env.stop(signal.SIGINT) == 0


def step_once(probe):
    """Call env_node's ~/step (std_srvs/Trigger); return its response."""
    client = probe.node.create_client(Trigger, '/env_node/step')
    try:
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(Trigger.Request())
        assert wait_until(future.done, 10.0)
        return future.result()
    finally:
        probe.node.destroy_client(client)


def test_while_paused_a_person_steps_one_step_at_a_time(start_node, probe):
    # Real time: each ~/step takes one step with the agent's latest action, and stays paused.
    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'rate_hz': 30})
    assert learner.observations.wait_count(3, STARTUP_S)
    refused = step_once(probe)
    assert not refused.success and 'not paused' in refused.message  # it steps on its own
    assert set_paused(probe, True).successful
    time.sleep(0.3)  # a step in flight
    for _ in range(2):
        count = len(learner.observations.snapshot())
        assert step_once(probe).success
        assert learner.observations.wait_count(count + 1, REPLY_S)
        assert not learner.observations.wait_count(count + 2, 0.5)  # one, and paused again
    assert env.wait_for_log('one step taken while paused', REPLY_S)
    assert env.stop(signal.SIGINT) == 0

    # Lockstep: the step applies the agent's answer to the observation on screen, once.
    learner = Learner(probe)
    env = start_node('env_node', {'warmup_steps': 0, 'action_timeout': 30.0, 'paused': True},
                     name='env_lockstep')
    pending = stamp_to_ns(learner.connect().header.stamp)
    refused = step_once(probe)
    assert not refused.success and 'not answered' in refused.message
    learner.send(pending, RIGHT)  # the answer comes while paused: it waits for the person
    assert not learner.observations.wait_for(
        lambda ms: stamp_to_ns(ms[-1].header.stamp) > pending, 1.0)
    assert wait_until(lambda: step_once(probe).success, REPLY_S)  # once the answer is in
    following = learner.next_observation(pending)
    status = learner.status_at(stamp_to_ns(following.header.stamp))
    assert status['agent_step'] == 1 and status['dropped_actions'] == 0
    assert not learner.observations.wait_for(
        lambda ms: stamp_to_ns(ms[-1].header.stamp) > stamp_to_ns(following.header.stamp), 1.0)
    assert env.stop(signal.SIGINT) == 0


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['sigint', 'sigterm'])
def test_a_signal_during_start_up_exits_cleanly(start_node, sig):
    env = start_node('env_node', {'warmup_steps': 5000})  # seconds of warm-up to land in
    assert env.wait_for_log('starting', STARTUP_S)
    assert env.stop(sig) == 0
    log = env.log_path.read_text()  # the process has ended and its log is closed
    assert 'ready' not in log and 'Traceback' not in log


@pytest.mark.parametrize('params, message', [
    ({'frameskip': 0}, 'frameskip'),
    ({'action_timeout': 0.0}, 'action_timeout'),
    ({'rate_hz': 'fast'}, 'rate_hz'),
    ({'preview_rate_hz': -1.0}, 'preview_rate_hz must be >= 0'),
    ({'task': 'pong'}, "unknown task 'pong'; installed tasks: doorkey, fetch, montezuma"),
    ({'task': 'doorkey', 'distractors': 99}, 'distractors must be in 0..12'),
], ids=['frameskip', 'action_timeout', 'rate_hz', 'preview_rate_hz', 'task',
        'doorkey_distractors'])
def test_bad_parameters_stop_it_with_a_clear_message(start_node, params, message):
    env = start_node('env_node', params)
    assert env.process.wait(timeout=STARTUP_S) == 1
    assert '[startup error]' in env.log_text() and message in env.log_text()


def test_first_step_waits_for_the_expected_subscribers(probe, start_node):
    """With wait_position_subscribers 1, no step goes out until agent_position is subscribed."""
    env = start_node('env_node', {'warmup_steps': 0, 'wait_observation_subscribers': 1,
                                  'wait_position_subscribers': 1})
    observations = probe.subscribe(Image, topics.OBSERVATION, qos.FRAMES)
    assert env.wait_for_log('waiting for subscribers before the first step', STARTUP_S), \
        env.log_text()[-2000:]
    assert not observations.messages, 'a step went out before agent_position was subscribed'
    positions = probe.subscribe(PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
    assert observations.wait_count(1, REPLY_S)
    assert positions.wait_for(
        lambda m: stamps(m)[:1] == stamps(observations.snapshot())[:1], REPLY_S)
    assert env.stop() == 0


def test_real_time_waits_for_the_named_learner_not_any_reader(probe, start_node):
    """
    wait_observation_nodes: a viewer's reader does not make the count in a learner's stead.

    In CI the console's and the recorder's readers made the count while tamer_node was still
    loading torch, and a real-time run's 60 steps went by with no learner to answer them.
    """
    env = start_node('env_node', {'warmup_steps': 0, 'rate_hz': 15.0, 'max_steps': 30,
                                  'wait_observation_subscribers': 1,
                                  'wait_observation_nodes': 'late_learner'})
    viewer = probe.subscribe(Image, topics.OBSERVATION, qos.FRAMES)  # the count is made
    assert env.wait_for_log('not yet matched with late_learner', STARTUP_S), \
        env.log_text()[-2000:]
    assert not viewer.messages, 'a step went out before the named node subscribed'
    with TopicProbe('late_learner') as learner:
        heard = learner.subscribe(Image, topics.OBSERVATION, qos.FRAMES)
        assert heard.wait_count(1, REPLY_S) and viewer.wait_count(1, REPLY_S), \
            env.log_text()[-2000:]
    assert env.stop() == 0


def test_doorkey_over_the_same_topics(start_node, probe):
    """task:=doorkey: 112x112 frames (the agent's view), MiniGrid's actions as joystick ones."""
    from attention_tasks.gridworld import STEP_S
    from attention_tasks.task import load_task
    task = load_task('doorkey')
    learner = Learner(probe)
    env = start_node('env_node', {'task': 'doorkey', 'seed': 3, 'action_timeout': 30.0})
    observation = learner.connect()
    assert (observation.height, observation.width) == task.frame_shape == (112, 112)
    first_ns = stamp_to_ns(observation.header.stamp)
    status = learner.status_at(first_ns)
    assert status['subgoals'] == 0 and status['heldout'] is False and len(status['grid']) == 384
    point = learner.position_at(first_ns)
    assert (point.x, point.y) == (status['x'], status['y'])
    turned = learner.step(observation, task.joy_action(1))  # MiniGrid right: joystick RIGHT
    status = learner.status_at(stamp_to_ns(turned.header.stamp))
    assert status['action'] == 1 and status['direction'] == (
        learner.status_at(first_ns)['direction'] + 1) % 4
    assert stamp_to_ns(turned.header.stamp) - first_ns == round(STEP_S * 1e9)
    learner.send(stamp_to_ns(turned.header.stamp), 6)  # UPRIGHT carries no DoorKey action
    assert env.wait_for_log('is no action of task doorkey', REPLY_S) and env.alive()
    learner.send(stamp_to_ns(turned.header.stamp), task.joy_action(2))  # forward: still pending
    after = learner.next_observation(stamp_to_ns(turned.header.stamp))
    status = learner.status_at(stamp_to_ns(after.header.stamp))
    assert status['action'] == 2 and status['bad_actions'] == 1 and status['agent_step'] == 2
    assert env.stop(signal.SIGINT) == 0


def test_each_episode_starts_paused_until_resumed(start_node, probe):
    """pause_each_episode: a person sees each new room first (Fetch: then says the goal)."""
    learner = Learner(probe)
    env = start_node('env_node', {'task': 'fetch', 'max_episode_steps': 2,
                                  'pause_each_episode': True, 'action_timeout': 30.0})

    def message_at(stamp_ns):
        learner.status_at(stamp_ns)
        return next(m.status[0].message for m in learner.statuses.snapshot()
                    if stamp_to_ns(m.header.stamp) == stamp_ns)

    observation = learner.connect()
    for episode in range(2):
        pending = stamp_to_ns(observation.header.stamp)
        assert message_at(pending) == 'paused'
        assert learner.status_at(pending)['episode'] == episode
        learner.send(pending, LEFT)  # answered while paused: it waits
        assert not learner.observations.wait_for(
            lambda ms: stamp_to_ns(ms[-1].header.stamp) > pending, 1.0)
        assert set_paused(probe, False).successful  # the person resumes
        following = learner.next_observation(pending)
        assert message_at(stamp_to_ns(following.header.stamp)) == 'running'
        observation = learner.step(following, LEFT)  # the second step ends the episode
    assert env.wait_for_log('paused: episode 1 starts', REPLY_S)
    assert env.stop(signal.SIGINT) == 0

"""
env_node: the task's world over topics, in lockstep with the learner or in real time.

The world comes from the task named by ``task`` (``attention_tasks``: Montezuma's Revenge Room 1
by default, or DoorKey); the node itself knows no game.

Lockstep (``rate_hz`` 0): publish observation T, wait for the Joy stamped T, step, publish the
next. An action with another stamp is dropped and counted, so a late or duplicate action is never
applied to a later frame (stamps strictly increase, the pending stamp is consumed before the
step). Without an answer for ``action_timeout`` wall seconds, observation T goes out again with
the same stamp. Until the first answer arrives (start-up), the first observation goes out as
soon as a subscriber appears and again every ``START_RESEND_S``, not counted as timeouts, so a
learner still being discovered, or started later, gets it at once. Real time (``rate_hz`` > 0):
once the same start-up subscribers have matched, a steady timer steps with the latest valid
action.
"""

import threading
import time

from attention_common import qos, topics
from attention_common.image_codec import numpy_to_image
from attention_common.joy_actions import ACTION_MEANINGS, joy_to_action, JoyActionError
from attention_common.node_main import Closing, run_node, StartupError
from attention_common.parameters import declare_dataclass
from attention_common.preview import Preview
from attention_common.recorder_gate import node_names, nodes_unmatched
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from attention_tasks.task import load_task, Step, UnknownTask
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from env_node.config import EnvNodeConfig, RUNTIME_PARAMETERS
from env_node.status import Counters, NO_LATENCY, STATUS_NAME, status_values
from geometry_msgs.msg import PointStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import Image, Joy
from std_srvs.srv import Trigger

SCREEN_FRAME = 'atari_screen'
RAM_FRAME = 'atari_ram'
START_POLL_S = 0.02
"""Until the first answer: how often the node looks for a subscriber to send observations to."""
START_RESEND_S = 0.5
"""Until the first answer, the first observation is sent again this often (not counted as a
timeout): DDS discovery takes seconds, and a message sent before a new subscriber has matched
this publisher on its side is lost."""
LOG_THROTTLE_S = 5.0
STEP_SERVICE = '~/step'
"""std_srvs/Trigger: while paused, one step with the agent's answer (a person judging each)."""


class EnvNode(Closing, Node):
    """Publishes each step of the game; applies the Joy actions that answer it."""

    OBS, POSITION, STATUS = topics.OBSERVATION, topics.AGENT_POSITION, topics.ENV_STATUS

    def __init__(self, **kwargs):
        super().__init__('env_node', **kwargs)
        config = declare_dataclass(self, EnvNodeConfig, runtime=RUNTIME_PARAMETERS)
        try:
            config.validate()
            self._task = task = load_task(config.task)
        except (ValueError, UnknownTask) as error:
            raise StartupError(str(error)) from None
        world = declare_dataclass(self, task.env_config)
        self._paused = config.paused or config.pause_each_episode
        self._pause_each_episode = config.pause_each_episode
        self._deferred = None  # lockstep, paused: the answer to apply on resume
        self._rate_hz = config.rate_hz
        self._action_timeout = config.action_timeout
        self._max_steps = config.max_steps
        self._wait_subscribers = ((self.OBS, config.wait_observation_subscribers),
                                  (self.POSITION, config.wait_position_subscribers),
                                  (self.STATUS, config.wait_status_subscribers))
        self._wait_observation_nodes = node_names(config.wait_observation_nodes)
        self.get_logger().info(f'starting {task.env_id} (task {task.name}), '
                               f'{world.warmup_steps} warm-up steps')
        try:
            self._env = task.make_env(world)
        except ValueError as error:
            raise StartupError(str(error)) from None

        # Messages are built once and refilled every step.
        self._obs_msg = Image()
        self._obs_msg.header.frame_id = SCREEN_FRAME
        self._position_msg = PointStamped()
        self._position_msg.header.frame_id = RAM_FRAME
        self._key_values = []  # one per status key, made at the first step, refilled after
        self._status = DiagnosticStatus(name=STATUS_NAME, hardware_id=task.env_id,
                                        level=DiagnosticStatus.OK, values=self._key_values)
        self._status_msg = DiagnosticArray(status=[self._status])
        self._clock_msg = ClockMsg()

        self._obs_pub = self.create_publisher(Image, topics.OBSERVATION, qos.FRAMES_WRITER)
        self._position_pub = self.create_publisher(
            PointStamped, topics.AGENT_POSITION, qos.STEP_DATA)
        self._status_pub = self.create_publisher(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
        self._clock_pub = self.create_publisher(ClockMsg, topics.CLOCK, qos.CLOCK)
        self._obs_preview = Preview(self, Image, topics.OBSERVATION, config.preview_rate_hz)
        self._status_preview = Preview(self, DiagnosticArray, topics.ENV_STATUS,
                                       config.preview_rate_hz)
        self.create_subscription(Joy, topics.ACTION, self._on_action, qos.ACTIONS)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.create_service(Trigger, STEP_SERVICE, self._on_step_request)

        # Callbacks run one at a time (single-threaded executor, one callback group); the lock
        # keeps the pending stamp and the step atomic even under a multi-threaded executor.
        self._lock = threading.Lock()
        self._counters = Counters()
        self._finished = False
        self._pending_ns = None  # lockstep: stamp of the observation awaiting its action
        self._answered = False  # lockstep: an action has been applied (start-up is over)
        self._started_at = self._sent_at = time.monotonic()
        self._latency_ms = NO_LATENCY  # lockstep: observation published -> its action received
        self._latest_action = 0  # real time: NOOP until a valid action arrives
        self._current = self._env.warm_up()

        # Wall-clock timers: a steady clock, whatever use_sim_time says.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timeout_timer = None
        self._start_timer = None
        self._steady = steady
        self._tick_timer = None
        if self._rate_hz > 0:
            # Real time also waits for the graph's subscribers, then steps on its timer.
            self._start_timer = self.create_timer(START_POLL_S, self._on_realtime_start,
                                                  clock=steady)
        else:
            self._timeout_timer = self.create_timer(
                self._action_timeout, self._on_timeout, clock=steady, autostart=False)
            self._start_timer = self.create_timer(START_POLL_S, self._on_start_poll, clock=steady)
        mode = f'real time at {self._rate_hz} Hz' if self._rate_hz > 0 else 'lockstep'
        self.get_logger().info(
            f'{task.env_id} ready ({mode}, {task.num_actions} actions, seed {world.seed}, '
            f'{world.warmup_steps} warm-up steps done, first stamp '
            f'{self._current.sim_time_ns} ns)')

    # -- publishing -------------------------------------------------------------------------

    def _publish_step_data(self, step: Step, finished: bool = False) -> None:
        """Publish /clock, agent_position and env_status of a step (not its observation)."""
        stamp = ns_to_stamp(step.sim_time_ns)
        self._clock_msg.clock = stamp
        self._clock_pub.publish(self._clock_msg)
        self._position_msg.header.stamp = stamp
        point = self._position_msg.point
        point.x, point.y, point.z = step.state.position()
        self._position_pub.publish(self._position_msg)
        values = status_values(step, self._counters, finished, self._latency_ms)
        if len(values) != len(self._key_values):  # the first step: the task's keys
            self._key_values = [KeyValue(key=key) for key, _ in values]
            self._status.values = self._key_values
        for key_value, (_, value) in zip(self._key_values, values):
            key_value.value = value
        self._status.message = ('finished' if finished else 'episode over' if step.done else
                                'paused' if self._paused else 'running')
        self._status_msg.header.stamp = stamp
        self._status_pub.publish(self._status_msg)
        self._status_preview.publish(self._status_msg)
        self._latency_ms = NO_LATENCY  # an answer is timed once (not again after a reset)

    def _publish_step(self, step: Step) -> None:
        """Publish a step the agent acts on; in lockstep it becomes the pending observation."""
        self._current = step
        numpy_to_image(step.observation, 'rgb8', self._obs_msg)  # encoded once per step
        self._obs_msg.header.stamp = ns_to_stamp(step.sim_time_ns)
        if self._timeout_timer is not None:
            self._pending_ns = step.sim_time_ns
            self._sent_at = time.monotonic()
            if self._answered:  # start-up has its own re-sends, see _on_start_poll
                self._timeout_timer.reset()  # (re)starts the wait for this answer
        # The observation first: the learner acts on it while the step's data goes out.
        self._obs_pub.publish(self._obs_msg)
        self._obs_preview.publish(self._obs_msg)
        self._publish_step_data(step)

    def _advance(self, action: int) -> None:
        step = self._env.step(action)
        finished = 0 < self._max_steps <= step.agent_step
        if step.done or finished:
            # The last action still gets judged: its position and status go out, no observation.
            self._publish_step_data(step, finished)
            if finished:
                self._finish(step)
                return
            step = self._env.reset()
            if self._pause_each_episode and not self._paused:
                self._paused = True
                self.get_logger().info(f'paused: episode {step.episode} starts '
                                       '(pause_each_episode); set paused false to go on')
        self._publish_step(step)

    def _finish(self, step: Step) -> None:
        self._finished = True
        self._pending_ns = None
        for timer in (self._timeout_timer, self._start_timer, self._tick_timer):
            if timer is not None:
                timer.cancel()
        self.get_logger().info(
            f'finished: {step.agent_step} agent steps (max_steps), {step.episode + 1} episodes, '
            f'{self._counters.timeouts} timeouts, {self._counters.dropped_actions} dropped '
            'actions; no more steps')

    # -- callbacks --------------------------------------------------------------------------

    def _on_start_poll(self) -> None:
        """Before the first answer: send the first step once the graph's subscribers match."""
        with self._lock:
            if self._answered or self._finished:
                return
            now = time.monotonic()
            if self._pending_ns is None:
                missing = self._missing_subscribers()
                if not missing:
                    self._publish_step(self._current)
                elif now - self._started_at >= self._action_timeout:
                    self.get_logger().info(
                        f'waiting for subscribers before the first step: {missing}',
                        throttle_duration_sec=LOG_THROTTLE_S)
            elif now - self._sent_at >= START_RESEND_S:
                # The whole step again (same stamp): a subscriber matched late still gets it.
                self._sent_at = now
                self._publish_step_data(self._current)
                self._obs_pub.publish(self._obs_msg)
                if now - self._started_at >= self._action_timeout:
                    self.get_logger().info(
                        f'waiting for the first action (stamped {self._pending_ns} ns) on '
                        f'{self.resolve_topic_name(topics.ACTION)}',
                        throttle_duration_sec=10 * LOG_THROTTLE_S)

    def _missing_subscribers(self) -> str:
        """Describe the start-up subscribers not yet matched ('' when all are)."""
        counts = {self.OBS: self._obs_pub.get_subscription_count(),
                  self.POSITION: self._position_pub.get_subscription_count(),
                  self.STATUS: self._status_pub.get_subscription_count()}
        missing = [f'{topic} has {counts[topic]} of {wanted}'
                   for topic, wanted in self._wait_subscribers if counts[topic] < wanted]
        nodes = nodes_unmatched(self, self._obs_pub, self._wait_observation_nodes)
        if nodes:
            missing.append(f'{self.OBS} not yet matched with {", ".join(nodes)}')
        return ', '.join(missing)

    def _on_timeout(self) -> None:
        with self._lock:
            if self._finished or self._pending_ns is None:
                return
            self._counters = self._counters._replace(timeouts=self._counters.timeouts + 1)
            self.get_logger().warning(
                f'no action stamped {self._pending_ns} ns within {self._action_timeout} s; '
                f'observation published again ({self._counters.timeouts} timeouts so far)',
                throttle_duration_sec=LOG_THROTTLE_S)
            self._obs_pub.publish(self._obs_msg)

    def _on_realtime_start(self) -> None:
        """Real time: start stepping once the graph's subscribers have matched."""
        with self._lock:
            if self._tick_timer is not None or self._finished:
                return
            missing = self._missing_subscribers()
            if missing:
                if time.monotonic() - self._started_at >= self._action_timeout:
                    self.get_logger().info(
                        f'waiting for subscribers before the first step: {missing}',
                        throttle_duration_sec=LOG_THROTTLE_S)
                return
            self._start_timer.cancel()
            self._publish_step(self._current)
            self._tick_timer = self.create_timer(1.0 / self._rate_hz, self._on_tick,
                                                 clock=self._steady)

    def _on_tick(self) -> None:
        with self._lock:
            if not self._finished and not self._paused:
                self._advance(self._latest_action)

    def _on_set_parameters(self, parameters) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name != 'paused' or not isinstance(parameter.value, bool):
                return SetParametersResult(
                    successful=False, reason='only paused (true/false) is settable at run time')
        for parameter in parameters:
            with self._lock:
                changed = parameter.value != self._paused
                self._paused = parameter.value
                if not self._paused and self._deferred is not None:
                    action, self._deferred = self._deferred, None
                    if not self._finished:
                        self._advance(action)  # the answer that came while paused
            if changed:
                self.get_logger().info('paused' if parameter.value else 'resumed')
        return SetParametersResult(successful=True)

    def _on_step_request(self, request, response):
        """Take one step while paused, with the agent's answer to the step on screen."""
        with self._lock:
            why = self._why_no_step()
            if not why:
                action = self._latest_action if self._rate_hz > 0 else self._deferred
                self._deferred = None
                self._advance(action)
        response.success, response.message = not why, why or 'one step taken; still paused'
        if not why:
            self.get_logger().info('one step taken while paused')
        return response

    def _why_no_step(self) -> str:
        """Return why ``~/step`` cannot step now ('' when it can); called with the lock held."""
        if not self._paused:
            return 'not paused: the env steps on its own'
        if self._finished:
            return 'finished: no more steps'
        if self._rate_hz > 0 and self._tick_timer is None:
            return 'not started yet'
        if self._rate_hz <= 0 and self._deferred is None:
            return 'the agent has not answered the step on screen yet'
        return ''

    def _drop(self, bad: bool = False) -> int:
        counters = self._counters
        self._counters = counters._replace(dropped_actions=counters.dropped_actions + 1,
                                           bad_actions=counters.bad_actions + int(bad))
        return self._counters.dropped_actions

    def _on_action(self, msg: Joy) -> None:
        try:
            action = self._task_action(joy_to_action(msg.axes, msg.buttons))
        except JoyActionError as error:
            with self._lock:
                dropped = self._drop(bad=True)
            self.get_logger().error(f'bad action dropped ({dropped} dropped so far): {error}',
                                    throttle_duration_sec=LOG_THROTTLE_S)
            return
        if self._rate_hz > 0:
            self._latest_action = action
            return
        stamp_ns = stamp_to_ns(msg.header.stamp)
        with self._lock:
            pending = self._pending_ns
            if pending is None or stamp_ns != pending:
                dropped = self._drop()
            else:
                self._latency_ms = 1000.0 * (time.monotonic() - self._sent_at)
                self._pending_ns = None  # consumed before stepping: a duplicate cannot match
                if not self._answered:
                    self._answered = True
                    self._start_timer.cancel()
                if self._paused:
                    self._deferred = action  # applied when resumed
                else:
                    self._advance(action)
                return
        if pending is None:
            self.get_logger().warning(
                f'action stamped {stamp_ns} ns dropped: no observation is pending '
                f'({"finished" if self._finished else "not started"}; {dropped} dropped so far)',
                throttle_duration_sec=LOG_THROTTLE_S)
        else:
            age = 'late or duplicate' if stamp_ns < pending else 'from the future'
            self.get_logger().warning(
                f'action stamped {stamp_ns} ns dropped ({age}): the pending observation is '
                f'stamped {pending} ns ({dropped} dropped so far)',
                throttle_duration_sec=LOG_THROTTLE_S)

    def _task_action(self, joy_action: int) -> int:
        """Return the task action a joystick action carries; JoyActionError if none."""
        action = self._task.action_of_joy(joy_action)
        if action is None:
            carried = ', '.join(f'{ACTION_MEANINGS[j]} = {name}' for j, name in
                                zip(self._task.joy_actions, self._task.action_names))
            raise JoyActionError(f'joystick {ACTION_MEANINGS[joy_action]} is no action of '
                                 f'task {self._task.name} ({carried})')
        return action

    def on_close(self) -> None:
        """Release the emulator."""
        self._env.close()


def main(args=None):
    """Run env_node until Ctrl-C / SIGTERM (exit code 0)."""
    return run_node(EnvNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

"""
tamer_node: Deep TAMER with the saliency L2 term over ROS topics (a thin shell on TamerAgent).

Subscribes ``observation``, ``saliency``, ``feedback``, ``feedback_stamped``,
``feedback_pressed`` (h and the moment it was given: credited from then), ``utterance`` and
``action_taken`` (the action executed on a step when it was not the agent's: attention_replay);
publishes ``action`` (sensor_msgs/Joy with the answered image's header), ``metrics``,
``feedback_logged``: one receipt per feedback or utterance line written to the log,
``action_values`` (while anyone listens, at most ``values_rate_hz`` a second: H of every action
on each step acted on, and the action taken), ``feedback_credit`` (the steps each feedback
learned from was credited to) and ``question`` (with ``ask_rate``: the steps the agent asks
the trainer about, answered on ``feedback_stamped``).
Every TamerConfig field is a parameter of the same name; ``alpha`` may be changed at run time.

Executor: one thread (``attention_common.executors``: the EventsExecutor) on purpose. Every
callback only converts and hands over (acting itself is a ~1 ms forward pass); training runs on
the learner thread and all disk I/O, the feedback log included, on the disk thread (agent.py
states the contract). rclpy's MultiThreadedExecutor measured 2-3x fewer lockstep steps per
second here on 2 shared cores, for nothing a callback would gain from running in parallel.
"""

import dataclasses
import math
import time

from attention_common import qos, topics
from attention_common.executors import with_message_info
from attention_common.image_codec import image_to_numpy, ImageFormatError
from attention_common.joy_actions import action_to_joy, joy_to_action, JoyActionError
from attention_common.node_main import Closing, run_node, StartupError
from attention_common.parameters import declare_parameters
from attention_common.rate import TokenBucket
from attention_common.recorder_gate import RecorderGate
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import Image, Joy
from std_msgs.msg import Float32, Header, String
from tamer_node.agent import BadInput, default_run_dir, share_the_cpu, TamerAgent
from tamer_node.config import field_docs, TamerConfig, WAITS_FOR_SALIENCY
from tamer_node.persistence import json_number

RUNTIME_PARAMETERS = ('alpha',)
LOG_THROTTLE_S = 5.0
DROPS_LOGGED_IN_FULL = 20
"""The first drops of images each get a line (each kind of bad input is seen); then throttled."""


class TamerNode(Closing, Node):
    """Acts greedily on each observation and learns from feedback on a thread of its own."""

    def __init__(self, **kwargs):
        super().__init__('tamer_node', **kwargs)
        share_the_cpu()
        self.config = self._declare_config()
        if self.config.resume and not self.config.run_dir:
            raise StartupError('tamer_node: resume:=true needs the run_dir of the run to resume')
        if not self.config.run_dir:
            self.config.run_dir = str(default_run_dir())
        try:
            self.agent = TamerAgent(self.config, self.config.run_dir, log=self._log)
            replayed = self.agent.start()
        except Exception as error:  # whatever stops the start, say it in one line
            raise StartupError(f'tamer_node: {error}') from error
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.action_pub = self.create_publisher(Joy, topics.ACTION, qos.ACTIONS)
        self.metrics_pub = self.create_publisher(DiagnosticArray, topics.METRICS, qos.METRICS)
        self.logged_pub = self.create_publisher(DiagnosticArray, topics.FEEDBACK_LOGGED,
                                                qos.HUMAN)
        self.agent.on_logged = self._publish_receipt
        self.values_pub = self.create_publisher(DiagnosticArray, topics.ACTION_VALUES,
                                                qos.ACTION_VALUES)
        self._values_budget = (TokenBucket(self.config.values_rate_hz)
                               if self.config.values_rate_hz > 0 else None)
        self.credit_pub = self.create_publisher(DiagnosticArray, topics.FEEDBACK_CREDIT,
                                                qos.HUMAN)
        self.agent.worker.on_credit = self._publish_credit
        self.question_pub = self.create_publisher(Vector3Stamped, topics.QUESTION, qos.HUMAN)
        self._gate = RecorderGate(
            self, self.config.wait_for_recorder,
            (self.action_pub, self.metrics_pub, self.logged_pub, self.credit_pub,
             self.question_pub),
            self.config.wait_for_recorder_s)
        self.create_subscription(Image, topics.OBSERVATION, self._on_observation, qos.FRAMES)
        self.create_subscription(Image, topics.SALIENCY, self._on_saliency, qos.FRAMES)
        self.create_subscription(Joy, topics.ACTION_TAKEN, self._on_action_taken, qos.ACTIONS)
        self.create_subscription(Vector3Stamped, topics.FEEDBACK_STAMPED,
                                 with_message_info(self._on_feedback_stamped), qos.HUMAN)
        self.create_subscription(Vector3Stamped, topics.FEEDBACK_PRESSED,
                                 with_message_info(self._on_feedback_pressed), qos.HUMAN)
        self.create_subscription(Float32, topics.FEEDBACK, with_message_info(self._on_feedback),
                                 qos.HUMAN)
        self.create_subscription(String, topics.UTTERANCE, with_message_info(self._on_utterance),
                                 qos.HUMAN)
        steady = Clock(clock_type=ClockType.STEADY_TIME)  # wall time, whatever use_sim_time says
        self.create_timer(self.config.metrics_period_s, self._publish_metrics, clock=steady)
        self._frame_id = ''
        self._drops = 0
        if self.config.input_image in WAITS_FOR_SALIENCY:
            # A step whose saliency image does not come is answered on its observation.
            period = min(0.05, max(0.005, self.config.saliency_timeout_s / 5))
            self.create_timer(period, self._answer_overdue, clock=steady)
        self.get_logger().info(
            f'ready: run_dir {self.config.run_dir}, alpha {self.config.alpha}, credit '
            f'{self.config.credit}, input_image {self.config.input_image}, text '
            f'{self.config.text_conditioning}, model version '
            f'{self.agent.learner.updates}, buffer {len(self.agent.buffer)}'
            + (f', {replayed} logged feedback replayed' if self.config.resume else ''))

    # Parameters.
    def _declare_config(self) -> TamerConfig:
        docs = field_docs()
        specs = {field.name: (field.default, docs[field.name])
                 for field in dataclasses.fields(TamerConfig)}
        # Floats accept integers too (alpha:=0 must work from the command line).
        values = declare_parameters(self, specs, runtime=RUNTIME_PARAMETERS)
        config = TamerConfig(**values)
        try:
            config.validate()
        except ValueError as error:
            raise StartupError(f'tamer_node: {error}') from error
        return config

    def _on_set_parameters(self, parameters) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name not in RUNTIME_PARAMETERS:
                return SetParametersResult(
                    successful=False,
                    reason=f'{parameter.name} is read at start-up only; restart the node')
            try:
                alpha = float(parameter.value)
                if not (math.isfinite(alpha) and alpha >= 0.0):
                    raise ValueError
            except (TypeError, ValueError):
                return SetParametersResult(successful=False,
                                           reason='alpha must be a finite number >= 0')
        for parameter in parameters:
            self.agent.set_alpha(float(parameter.value))
            self.get_logger().info(f'alpha is now {self.agent.learner.alpha}')
        return SetParametersResult(successful=True)

    # Acting path.
    def _on_observation(self, msg: Image) -> None:
        self._handle_image(msg, 'observation', self.agent.on_observation)

    def _on_saliency(self, msg: Image) -> None:
        self._handle_image(msg, 'saliency', self.agent.on_saliency)

    def _handle_image(self, msg: Image, kind: str, handler) -> None:
        try:
            if msg.encoding != 'rgb8':
                raise ImageFormatError(f'encoding {msg.encoding!r}, rgb8 expected')
            rgb = image_to_numpy(msg, self.agent.task.frame_shape)  # a wrong size: not copied
            action = handler(stamp_to_ns(msg.header.stamp), rgb)
            self._frame_id = msg.header.frame_id
        except (ImageFormatError, BadInput) as error:
            if isinstance(error, ImageFormatError):
                self.agent.counters[f'drop/{kind}'] += 1
            self._drops += 1
            text = f'{kind} dropped ({error}; {self._drops} images dropped so far)'
            if self._drops <= DROPS_LOGGED_IN_FULL:
                self.get_logger().warning(text)
            else:
                self.get_logger().warning(text, throttle_duration_sec=LOG_THROTTLE_S)
            return
        if action is not None:
            self._publish_action(msg.header, action)
            self._publish_values()
            self._publish_questions()

    def _on_action_taken(self, msg: Joy) -> None:
        try:
            action = self.agent.task.action_of_joy(joy_to_action(msg.axes, msg.buttons))
            if action is None:
                self.agent.counters['drop/action_taken'] += 1
                raise BadInput('action_taken dropped: a joystick action this task does not use')
            self.agent.on_action_taken(stamp_to_ns(msg.header.stamp), action)
        except JoyActionError as error:
            self.agent.counters['drop/action_taken'] += 1
            self.get_logger().warning(f'action_taken dropped: {error}',
                                      throttle_duration_sec=LOG_THROTTLE_S)
        except BadInput as error:
            self.get_logger().warning(str(error), throttle_duration_sec=LOG_THROTTLE_S)

    def _answer_overdue(self) -> None:
        for stamp, action in self.agent.act_overdue():
            header = Header(stamp=ns_to_stamp(stamp), frame_id=self._frame_id)
            self._publish_action(header, action)
        self._publish_values()
        self._publish_questions()

    def _publish_action(self, header: Header, action: int) -> None:
        joy = Joy()
        joy.header = header
        axes, buttons = action_to_joy(self.agent.task.joy_action(action))
        joy.axes = [float(a) for a in axes]
        joy.buttons = [int(b) for b in buttons]
        self._gate.publish(self.action_pub, joy)

    # Feedback path. Each message's DDS identity (the publisher's sequence number and its
    # source time) is logged with it, so a publisher (the trainer console) can tell from the
    # receipt on feedback_logged that *its* message reached the log.
    def _on_feedback_stamped(self, msg: Vector3Stamped, info) -> None:
        extra = {'critical_position': json_number(msg.vector.y),
                 'distance': json_number(msg.vector.z), **_identity(info)}
        self.agent.on_feedback(msg.vector.x, 'stamped', stamp_to_ns(msg.header.stamp), extra)

    def _on_feedback_pressed(self, msg: Vector3Stamped, info) -> None:
        self.agent.on_feedback(msg.vector.x, 'pressed', stamp_to_ns(msg.header.stamp),
                               _identity(info))

    def _on_feedback(self, msg: Float32, info) -> None:
        self.agent.on_feedback(msg.data, 'plain', extra=_identity(info))

    def _on_utterance(self, msg: String, info) -> None:
        if self.agent.on_utterance(msg.data, _identity(info)) == 'ok':
            text = msg.data
            shown = text if len(text) <= 200 else text[:200] + f'... ({len(text)} characters)'
            self.get_logger().info(f'utterance: {shown!r}')

    def _publish_receipt(self, entry: dict) -> None:
        """On the disk thread: say on feedback_logged what was just written to the log."""
        if not self.context.ok():
            return  # shutting down (the line is on disk; nobody could hear the receipt now)
        keys = ('seq', 'h', 'source', 'status', 'stamp_ns', 'session', 'publication_seq',
                'source_time_ns', 'chars')
        status = DiagnosticStatus(level=DiagnosticStatus.OK, name=entry['kind'],
                                  hardware_id='tamer_node',
                                  message=entry.get('text', '')[:RECEIPT_TEXT_CHARS])
        status.values = [KeyValue(key=key, value=_format(entry[key]))
                         for key in keys if entry.get(key) is not None]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._gate.publish(self.logged_pub, array)

    def _publish_values(self) -> None:
        """After an action went out: H of every action and the one taken, while anyone listens."""
        acted = self.agent.acting.acted
        if not self.values_pub.get_subscription_count():
            acted.clear()  # a lockstep run without a viewer pays nothing for it
            return
        while acted:
            entry = acted.popleft()
            if self._values_budget is None or self._values_budget.allow(time.monotonic()):
                self._publish_step_values(*entry)

    def _publish_questions(self) -> None:
        """After an action went out: the steps the agent asks the trainer about (ask_rate)."""
        for stamp, action, gap in self.agent.acting.take_questions():
            msg = Vector3Stamped()
            msg.header = Header(stamp=ns_to_stamp(stamp), frame_id=self._frame_id)
            msg.vector.x, msg.vector.y = float(action), float(gap)
            self._gate.publish(self.question_pub, msg)

    def _publish_step_values(self, stamp: int, action: int, values) -> None:
        names = self.agent.task.action_names
        status = DiagnosticStatus(level=DiagnosticStatus.OK, name='action_values',
                                  hardware_id='tamer_node', message=names[action])
        status.values = [KeyValue(key='action', value=str(action)),
                         KeyValue(key='version', value=str(self.agent.actor.version))]
        status.values += [KeyValue(key=name, value=f'{float(h):.4f}')
                          for name, h in zip(names, values.tolist())]
        array = DiagnosticArray(status=[status])
        array.header = Header(stamp=ns_to_stamp(stamp), frame_id=self._frame_id)
        self.values_pub.publish(array)

    def _publish_credit(self, event, samples) -> None:
        """On the learner thread: the steps a feedback's credit went to, and their weights."""
        if not self.context.ok():
            return
        status = DiagnosticStatus(level=DiagnosticStatus.OK, name='feedback_credit',
                                  hardware_id='tamer_node', message=event.credit)
        status.values = [KeyValue(key='seq', value=str(event.seq)),
                         KeyValue(key='h', value=_format(float(event.h)))]
        status.values += [KeyValue(key=str(sample.stamp), value=f'{sample.weight:.5f}')
                          for sample in samples]
        array = DiagnosticArray(status=[status])
        array.header.stamp = ns_to_stamp(event.now if event.now is not None else event.stamp)
        self._gate.publish(self.credit_pub, array)

    def _log(self, level: str, text: str) -> None:
        # One call site per severity: rclpy's logger refuses another severity from the same
        # line ("Logger severity cannot be changed between calls"), and the ValueError had
        # killed the disk thread, losing the feedback still queued to the log.
        logger = self.get_logger()
        if level == 'error':
            logger.error(text)
        elif level == 'warn':
            logger.warning(text)
        else:
            logger.info(text)

    # Metrics.
    def _publish_metrics(self) -> None:
        values = self.agent.metrics()
        status = DiagnosticStatus(level=DiagnosticStatus.OK, name='tamer_node',
                                  hardware_id='tamer_node', message='learner metrics')
        status.values = [KeyValue(key=key, value=_format(value))
                         for key, value in sorted(values.items())]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._gate.publish(self.metrics_pub, array)
        self.agent.write_metrics_row(values)

    def on_close(self) -> None:
        """Finish pending feedback, write the last checkpoint, close the files."""
        agent = getattr(self, 'agent', None)
        if agent is not None:
            agent.close()


RECEIPT_TEXT_CHARS = 200


def _identity(info) -> dict:
    """Return the DDS identity of a received message (rclpy's MessageInfo), for the log."""
    return {'publication_seq': info.get('publication_sequence_number'),
            'source_time_ns': info.get('source_timestamp')}


def _format(value) -> str:
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value)


def main(args=None) -> int:
    return run_node(TamerNode, args)  # one thread: see the module docstring


if __name__ == '__main__':
    raise SystemExit(main())

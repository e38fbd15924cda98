"""
trainer_console: a person teaches from the browser (a thin rclpy shell on ConsoleState).

Subscribes ``observation`` and ``saliency`` (shown live, as JPEG over a websocket),
``env_status``, ``metrics``, ``utterance``, ``utterance_stamped``, ``feedback_logged`` (the
learner's receipts), ``action_values`` and ``feedback_credit`` (what the learner made of the
person: ``learner_view.py``); publishes each key press on ``feedback_pressed``
(geometry_msgs/Vector3Stamped: h and the moment it was given, ``press_time.py``; plain
``feedback``, std_msgs/Float32, with ``press_times`` false), or while the env is paused on
``feedback_stamped`` (Vector3Stamped: h and the frame on screen, the step judged), and words on
``utterance`` (std_msgs/String), the very topic ``ros2 topic pub`` uses, sets env_node's
``paused`` and, while paused, steps it once at a time (its ``~/step`` service). The learner's
``question``s (tamer_node ``ask_rate``) are shown one at a time: the env paused, the asked frame
on screen, a press on it answers on ``feedback_stamped`` (``questions.py``).
The web server runs on its own thread (``web.ConsoleServer``); rclpy spins in the main one.
"""

import math
import secrets
import threading
import time

from attention_common import qos, topics
from attention_common.feedback import FEEDBACK_RANGE
from attention_common.image_codec import image_to_numpy, ImageFormatError
from attention_common.node_main import Closing, run_node, StartupError
from attention_common.parameters import declare_dataclass
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from attention_common.utterance import MAX_UTTERANCE_CHARS
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS
from attention_tasks.task import load_task, UnknownTask
import cv2
from diagnostic_msgs.msg import DiagnosticArray
from env_node.status import parse_status
from geometry_msgs.msg import Vector3Stamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from saliency_node.grounding import Grounder
from saliency_node.manifest import load_manifest
from sensor_msgs.msg import Image
from std_msgs.msg import Float32, String
from std_srvs.srv import Trigger
from trainer_console.config import ConsoleConfig
from trainer_console.matching import subscriber_names, wait_for_all_matched
from trainer_console.press_time import frame_stamp, press_moment
from trainer_console.questions import Question, QuestionDesk
from trainer_console.state import ConsoleState
from trainer_console.web import ConsoleServer, Frames

SOURCES = {topics.FEEDBACK: 'plain', topics.FEEDBACK_PRESSED: 'pressed',
           topics.FEEDBACK_STAMPED: 'stamped', topics.UTTERANCE: 'plain'}
"""The console's topics, and the source the learner logs a message of each under."""
MAX_PIXELS = 1024 * 1024
"""Larger images are not shown (and never decoded)."""


class ConsoleNode(Closing, Node):
    """The trainer's console: serves the page, publishes what the person gives."""

    def __init__(self, **kwargs):
        super().__init__('trainer_console', **kwargs)
        self.config = declare_dataclass(self, ConsoleConfig)
        try:
            self.config.validate()
            task = load_task(self.config.task)
        except (ValueError, UnknownTask) as error:
            raise StartupError(f'trainer_console: {error}') from None
        grounder = Grounder.from_manifest(load_manifest(task.manifest))
        self.state = ConsoleState(
            ground=lambda text: grounder.ground(text).objects,
            milestone_of=lambda values: task.milestone_of(values, DEFAULT_RADIUS),
            milestones=task.milestones, judge_paused_frame=self.config.judge_paused_frame)
        self.frames = Frames()
        self.action_names = tuple(task.action_names)
        self.questions = QuestionDesk(show=self.config.answer_questions)
        self._question_paused = False  # the console paused the env for a question
        self._person_paused = False  # the person paused it (the button)
        self._pause_lock = threading.Lock()  # (questions settle on rclpy's and the web's threads)
        self._encoded_at = {'frame': 0.0, 'saliency': 0.0}
        self._publish_lock = threading.Lock()  # publish and its sequence number together
        self._published = dict.fromkeys(SOURCES, 0)
        self._person_pubs = {
            topic: self.create_publisher(kind, topic, qos.HUMAN) for topic, kind in (
                (topics.FEEDBACK, Float32), (topics.FEEDBACK_PRESSED, Vector3Stamped),
                (topics.FEEDBACK_STAMPED, Vector3Stamped), (topics.UTTERANCE, String))}
        self.counts = {'timed_presses': 0, 'plain_presses': 0, 'frame_presses': 0,
                       'unreadable_timings': 0, 'bad_questions': 0}
        self.create_subscription(Image, topics.OBSERVATION,
                                 lambda msg: self._on_image('frame', msg), qos.FRAMES)
        self.create_subscription(Image, topics.SALIENCY,
                                 lambda msg: self._on_image('saliency', msg), qos.FRAMES)
        self.create_subscription(DiagnosticArray, topics.ENV_STATUS, self._on_status,
                                 qos.STEP_DATA)
        self.create_subscription(DiagnosticArray, topics.METRICS, self._on_metrics, qos.METRICS)
        self.create_subscription(String, topics.UTTERANCE,
                                 lambda msg: self.state.on_utterance(msg.data), qos.HUMAN)
        self.create_subscription(DiagnosticArray, topics.UTTERANCE_STAMPED,
                                 self._on_utterance_stamped, qos.HUMAN)
        self.create_subscription(DiagnosticArray, topics.FEEDBACK_LOGGED,
                                 self.state.on_receipt_message, qos.HUMAN)
        self.create_subscription(DiagnosticArray, topics.ACTION_VALUES, self._on_values,
                                 qos.ACTION_VALUES)
        self.create_subscription(DiagnosticArray, topics.FEEDBACK_CREDIT, self._on_credit,
                                 qos.HUMAN)
        self.create_subscription(Vector3Stamped, topics.QUESTION, self._on_question, qos.HUMAN)
        self._env_parameters = AsyncParameterClient(self, self.config.env_node)
        self._env_step = self.create_client(Trigger, f'{self.config.env_node}/step')
        self.create_timer(1.0, self._look_for_listeners)
        token = None
        if not self.config.loopback:
            token = self.config.token or secrets.token_urlsafe(16)
        self.server = ConsoleServer(self.config.host, self.config.port, self.frames,
                                    self.snapshot, self.on_command,
                                    self.config.frame_rate_hz, token,
                                    log=self.get_logger().warning,
                                    view=self.state.learner.view)
        try:
            port = self.server.start()
        except OSError as error:
            raise StartupError(f'trainer_console: cannot serve on {self.config.host}:'
                               f'{self.config.port} ({error})') from None
        self.url = f'http://{self.config.host}:{port}/' + (f'?token={token}' if token else '')
        self.get_logger().info(f'trainer console at {self.url}')

    # What the console hears.
    def _on_image(self, kind: str, msg: Image) -> None:
        if msg.encoding != 'rgb8' or msg.height * msg.width > MAX_PIXELS:
            self.get_logger().warning(f'{kind} not shown: {msg.encoding} {msg.width}x'
                                      f'{msg.height}', throttle_duration_sec=10.0)
            return
        stamp = stamp_to_ns(msg.header.stamp)
        if kind == 'frame' and self.questions.show:  # held: a question may ask about it
            self._settle(self.questions.on_frame(stamp, msg, len(msg.data)))
            if self.questions.current is not None:
                return  # the asked frame stands on screen
        now = time.monotonic()
        if now - self._encoded_at[kind] < 0.5 / self.config.frame_rate_hz:
            return  # (half the period: a frame a little early is still shown at the env's rate)
        self._encoded_at[kind] = now
        self._show_image(kind, msg, stamp)

    def _show_image(self, kind: str, msg: Image, stamp: int) -> None:
        try:
            rgb = image_to_numpy(msg)
        except ImageFormatError as error:
            self.get_logger().warning(f'{kind} not shown: {error}', throttle_duration_sec=10.0)
            return
        ok, jpeg = cv2.imencode('.jpg', cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                                [cv2.IMWRITE_JPEG_QUALITY, self.config.jpeg_quality])
        if ok:
            self.frames.put(kind, jpeg.tobytes(), stamp)

    # The learner's questions: one on screen at a time, the env paused meanwhile.
    def _on_question(self, msg: Vector3Stamped) -> None:
        action, gap = msg.vector.x, msg.vector.y
        if not (math.isfinite(action) and action == int(action)
                and 0 <= action < len(self.action_names) and math.isfinite(gap)):
            self.counts['bad_questions'] += 1
            self.get_logger().error(f'question ignored: action {action!r} is not one of the '
                                    f"task's {len(self.action_names)} or gap {gap!r} is not "
                                    f'finite ({self.counts["bad_questions"]} so far)')
            return
        self._settle(self.questions.on_question(Question(
            stamp_to_ns(msg.header.stamp), int(action), float(gap), time.monotonic())))

    def _settle(self, shown) -> None:
        """Show a question that went on screen; pause while any is open, resume after."""
        frame = None if shown is None else self.questions.frame(shown.stamp_ns)
        if frame is not None:
            self._show_image('frame', frame, shown.stamp_ns)
            self.get_logger().info(f'the learner asks about step {shown.stamp_ns} (it took '
                                   f'{self.action_names[shown.action]}, gap {shown.gap:.3f})')
        with self._pause_lock:
            is_open = self.questions.is_open()
            held = self._person_paused or self.state.paused_by_env  # not ours to end
            if is_open and not held and not self._question_paused:
                self._question_paused = True
                self._set_paused_soon(True)
            elif not is_open and self._question_paused:
                self._question_paused = False
                self._set_paused_soon(False)

    def _set_paused_soon(self, paused: bool) -> None:
        """Set env_node's ``paused`` without waiting (rclpy completes it on the main thread)."""
        if not self._env_parameters.services_are_ready():
            self.get_logger().warning(f'{self.config.env_node} does not answer: the question is'
                                      f' shown, the env not {"paused" if paused else "resumed"}',
                                      throttle_duration_sec=10.0)
            return

        def done(future) -> None:
            result = future.result()
            if result is not None and result.results[0].successful:
                self.state.paused = paused
            else:
                self.get_logger().warning('the env did not take paused := '
                                          f'{str(paused).lower()} for a question')
        self._env_parameters.set_parameters(
            [Parameter('paused', value=paused)]).add_done_callback(done)

    def _on_status(self, msg: DiagnosticArray) -> None:
        try:
            values = parse_status((kv.key, kv.value) for kv in msg.status[0].values)
        except (IndexError, ValueError):
            return
        self.state.on_status(values, message=msg.status[0].message)

    def _on_metrics(self, msg: DiagnosticArray) -> None:
        values = {}
        for kv in msg.status[0].values if msg.status else ():
            try:
                values[kv.key] = float(kv.value)
            except ValueError:
                pass
        self.state.on_metrics(values)

    def _on_values(self, msg: DiagnosticArray) -> None:
        self._warn(self.state.learner.on_values(stamp_to_ns(msg.header.stamp), _first(msg)))

    def _on_credit(self, msg: DiagnosticArray) -> None:
        self._warn(self.state.learner.on_credit(_first(msg)))

    def _warn(self, problem) -> None:
        if problem:
            self.get_logger().warning(problem, throttle_duration_sec=10.0)

    def _on_utterance_stamped(self, msg: DiagnosticArray) -> None:
        if msg.status:
            self.state.on_utterance(msg.status[0].message)

    def _look_for_listeners(self) -> None:
        self.state.listeners = {kind: self.listeners(kind) for kind in ('feedback', 'utterance')}
        self._settle(self.questions.tick(time.monotonic()))  # (a frame that never came)

    def snapshot(self) -> dict:
        """Return the page's state: the console's, and the learner's question on screen."""
        return dict(self.state.snapshot(), questions=self.questions.snapshot(self.action_names))

    # What the person gives (called on the web server's worker threads).
    def on_command(self, command: dict) -> dict:
        kind = command.get('type')
        if kind == 'feedback':
            h = command.get('h')
            if (isinstance(h, bool) or not isinstance(h, (int, float)) or not math.isfinite(h)
                    or abs(h) > FEEDBACK_RANGE):
                return {'ok': False, 'error': f'feedback must be in [-{FEEDBACK_RANGE:g}, '
                                              f'{FEEDBACK_RANGE:g}], got {h!r}'}
            return self._give_feedback(float(h), command)
        if kind == 'utterance':
            text = command.get('text')
            if not isinstance(text, str) or not text.strip():
                return {'ok': False, 'error': 'an utterance needs words'}
            if len(text) > MAX_UTTERANCE_CHARS:
                return {'ok': False, 'error': f'at most {MAX_UTTERANCE_CHARS} characters'}
            return self._give('utterance', text, String(data=text), topics.UTTERANCE)
        if kind in ('pause', 'resume'):
            return self._pause(kind == 'pause')
        if kind == 'step':
            return self._step()
        if kind == 'skip':
            if self.questions.current is None:
                return {'ok': False, 'error': 'no question on screen'}
            self._settle(self.questions.close('skipped', now=time.monotonic()))
            return {'ok': True}
        return {'ok': False, 'error': f'unknown command {kind!r}'}

    def listeners(self, kind: str) -> list:
        """Return the nodes the graph knows to subscribe to ``kind``'s topic (not this one)."""
        if kind == 'utterance':
            return subscriber_names(self, topics.UTTERANCE)
        return subscriber_names(self, topics.FEEDBACK_PRESSED if self.config.press_times
                                else topics.FEEDBACK)

    def _give_feedback(self, h: float, command: dict) -> dict:
        """Publish a key press: an answer, on the paused frame, or with its moment."""
        question = self.questions.current
        if question is not None and frame_stamp(command.get('frame'))[0] == question.stamp_ns:
            reply = self._give('feedback', h, _verdict(h, question.stamp_ns),
                               topics.FEEDBACK_STAMPED)  # the answer: that step's verdict
            if reply['ok']:
                self._settle(self.questions.close('answered', question.stamp_ns,
                                                  time.monotonic()))
            return reply
        pressed_ns, why = None, 'press_times is false'
        if self.config.judge_paused_frame and self.state.paused:
            frame_ns, why = frame_stamp(command.get('frame'))
            if frame_ns is not None:  # what the person judges: the step on screen
                self.counts['frame_presses'] += 1
                return self._give('feedback', h, _verdict(h, frame_ns), topics.FEEDBACK_STAMPED)
        elif self.config.press_times:
            pressed_ns, why = press_moment(command.get('frame'), command.get('after_ms'),
                                           self.state.paused)
        if pressed_ns is None:
            self.counts['plain_presses'] += 1
            if why.startswith('unreadable'):  # not our page's: said, counted, still sent
                self.counts['unreadable_timings'] += 1
                self.get_logger().error(f'key press sent plain on {topics.FEEDBACK}: {why} '
                                        f'({self.counts["unreadable_timings"]} so far)')
            elif self.config.press_times:
                self.get_logger().info(f'key press sent plain on {topics.FEEDBACK}: {why}')
            return self._give('feedback', h, Float32(data=h), topics.FEEDBACK)
        self.counts['timed_presses'] += 1
        return self._give('feedback', h, _verdict(h, pressed_ns), topics.FEEDBACK_PRESSED)

    def _give(self, kind: str, value, msg, topic: str) -> dict:
        publisher = self._person_pubs[topic]
        wait_for_all_matched(self, publisher, time.sleep)
        if not publisher.get_subscription_count():
            self.get_logger().warning(f'{kind} {value!r} not sent: nobody subscribes to it yet '
                                      '(is tamer_node running?)')
            return {'ok': False, 'error': f'nobody listens to {kind} yet (is the learner '
                                          'running?): not sent'}
        source = SOURCES[topic]  # as the learner logs it
        with self._publish_lock:
            sent_ns = time.time_ns()
            publisher.publish(msg)
            self._published[topic] += 1
            seq = self._published[topic]  # DDS numbers this publisher's messages 1, 2, 3, ...
            self.state.sent(kind, value, seq, sent_ns, source)
        listeners = subscriber_names(self, topic)
        self.get_logger().info(f'the person gave {kind} {value!r} (#{seq} on {topic}) to '
                               f'{", ".join(listeners) or "nobody"}')
        return {'ok': True, 'seq': seq, 'listeners': listeners}

    def _pause(self, paused: bool) -> dict:
        if not self._env_parameters.services_are_ready():
            return {'ok': False, 'error': f'{self.config.env_node} does not answer'}
        result = _answer(self._env_parameters.set_parameters([Parameter('paused', value=paused)]))
        if result is None or not result.results[0].successful:
            return {'ok': False, 'error': 'the env did not take it'}
        self.state.paused, self.state.paused_by_env = paused, False
        with self._pause_lock:
            self._person_paused = paused
            if self._question_paused:  # the person holds the pause now, or resumed for good
                self._question_paused = False
                if not paused:
                    self.questions.skip_all()
        self.get_logger().info('paused the env' if paused else 'resumed the env')
        return {'ok': True}

    def _step(self) -> dict:
        """While paused: env_node takes one step (its ``~/step``), and stays paused."""
        if not self._env_step.service_is_ready():
            return {'ok': False, 'error': f'{self.config.env_node} does not answer'}
        result = _answer(self._env_step.call_async(Trigger.Request()))
        if result is None:
            return {'ok': False, 'error': 'the env did not answer'}
        if not result.success:
            return {'ok': False, 'error': f'no step: {result.message}'}
        self.get_logger().info('stepped the env once')
        return {'ok': True}

    def on_close(self) -> None:
        """Stop the web server."""
        server = getattr(self, 'server', None)
        if server is not None:
            server.stop()


def _answer(future, timeout_s: float = 5.0):
    """Wait for env_node's answer (rclpy completes it on the main thread); None if none came."""
    deadline = time.monotonic() + timeout_s
    while not future.done() and time.monotonic() < deadline:
        time.sleep(0.01)
    return future.result() if future.done() else None


def _verdict(h: float, stamp_ns: int) -> Vector3Stamped:
    """Return a key press as a Vector3Stamped: x = h, stamped with ``stamp_ns``."""
    msg = Vector3Stamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.vector.x = h
    return msg


def _first(msg: DiagnosticArray):
    """Return (name, message, [(key, value)]) of the first status, or None."""
    if not msg.status:
        return None
    status = msg.status[0]
    return status.name, status.message, [(kv.key, kv.value) for kv in status.values]


def main(args=None) -> int:
    return run_node(ConsoleNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

"""
feedback_node: a synthetic trainer over topics, or a listener when a person trains.

``trainer`` chooses which: ``thesis`` (equations 4.1/4.2 on the agent's position, every study
condition; Room 1 only) or ``teacher`` (judges each action against the expert's, from
``env_status``: ``feedback_node.task_teacher`` with ``attention_tasks.<task>.teaching``, for every
task).

Subscribes ``agent_position``. With ``synthetic`` true, for every position (step T') it
publishes the feedback judging the action of the previous step T (``feedback_stamped``, stamp
T; the plain ``feedback`` only with ``plain_copies`` or when the teacher is late, or with
``press_times`` a late verdict on ``feedback_pressed``, stamped with the moment given) and,
when one is due, the utterance said at T' (``utterance_stamped``, stamp T', then the plain
``utterance``). The teacher answers the learner's questions (``question``: a step it asks
about) on ``feedback_stamped``, stamped with that step. With ``synthetic`` false it
publishes nothing and logs what a person says on ``utterance``, ``feedback`` and
``feedback_pressed`` (the console's timed presses); bad input gets
a clear error line and is counted. ``synthetic`` can be switched at run time
(``ros2 param set /feedback_node synthetic false``). ``trainer_status`` (latched) says how far
the synthetic trainer got: the launcher ends a run only once it judged the last step.
"""


import collections
import time

from attention_common import qos, topics
from attention_common.node_main import run_node, StartupError
from attention_common.parameters import declare_dataclass
from attention_common.recorder_gate import node_names, nodes_unmatched
from attention_common.stamps import NS_PER_S, ns_to_stamp, stamp_to_ns
from attention_tasks.montezuma.sentences import position_problem
from attention_tasks.task import DEFAULT_TASK
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from env_node.status import parse_status, STATUS_NAME
from feedback_node.config import FeedbackConfig, RUNTIME_PARAMETERS
from feedback_node.human_input import excerpt, feedback_problem, utterance_problem
from feedback_node.utterances import Utterance
from geometry_msgs.msg import PointStamped, Vector3Stamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Float32, String

HARDWARE_ID = 'synthetic_trainer'
HELD_FEEDBACK = 100_000
"""Judgements held while nobody subscribes to the feedback yet (start-up), at most."""
HELD_CHECK_S = 0.05
LISTEN_WAIT_S = 30.0
"""Longest wait at start for the nodes named in ``wait_*_nodes``; then listen anyway, warned."""
TRAINER_STATUS_PERIOD_S = 0.1
"""How often ``trainer_status`` is published when it changed (steady seconds)."""


class FeedbackNode(Node):
    """The synthetic trainer (section 4.1, Figure 5.1) as a node."""

    def __init__(self, **kwargs):
        super().__init__('feedback_node', **kwargs)
        try:
            config = declare_dataclass(self, FeedbackConfig, runtime=RUNTIME_PARAMETERS)
            self._kind = config.trainer
            self._task = config.task
            self._config = config.trainer_config()
            self._trainer = config.make_trainer()
        except (ValueError, OSError) as error:
            raise StartupError(str(error)) from None
        self._synthetic = config.synthetic
        self._plain_copies = config.plain_copies
        self._press_times = config.press_times
        self._wait_subscribers = config.wait_feedback_subscribers
        self._wait_listeners = config.wait_utterance_subscribers
        self._wait_names = {}  # publisher -> the nodes it waits for, until all are matched
        self._now_ns = None  # the newest step stamp heard: this node's "now"
        self._restarts_logged = 0
        self._counts = {'bad_positions': 0, 'bad_status': 0, 'heard_utterances': 0,
                        'heard_feedback': 0, 'bad_utterances': 0, 'bad_feedback': 0,
                        'utterances': 0, 'unanswerable_questions': 0}
        self._asked = False  # a learner asked: it reads feedback_stamped (the answers)

        self._feedback_stamped_pub = self.create_publisher(
            Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
        self._feedback_pub = self.create_publisher(Float32, topics.FEEDBACK, qos.HUMAN)
        self._feedback_pressed_pub = self.create_publisher(
            Vector3Stamped, topics.FEEDBACK_PRESSED, qos.HUMAN)
        self._utterance_stamped_pub = self.create_publisher(
            DiagnosticArray, topics.UTTERANCE_STAMPED, qos.HUMAN)
        self._utterance_pub = self.create_publisher(String, topics.UTTERANCE, qos.HUMAN)
        self._trainer_status_pub = self.create_publisher(
            DiagnosticArray, topics.TRAINER_STATUS, qos.LATCHED)
        for publishers, names in (
                ((self._feedback_stamped_pub, self._feedback_pub, self._feedback_pressed_pub),
                 config.wait_feedback_nodes),
                ((self._utterance_pub,), config.wait_utterance_nodes),
                ((self._utterance_stamped_pub,), config.wait_utterance_stamped_nodes)):
            for publisher in publishers:
                self._wait_names[publisher] = node_names(names)
        self._named = any(self._wait_names.values())
        """Readers are named: listen to the steps only once they and the counts are matched."""
        self._handled_ns = -1  # the newest step the synthetic trainer has judged from
        self._given = {'given_feedback': 0, 'given_utterances': 0}  # published to the graph
        self._last_trainer_status = None
        self._listening = False  # to the steps: only once the named readers are matched
        self._listen_by = time.monotonic() + LISTEN_WAIT_S
        self.create_subscription(String, topics.UTTERANCE, self._on_heard_utterance, qos.HUMAN)
        self.create_subscription(Float32, topics.FEEDBACK,
                                 lambda msg: self._on_heard_feedback(msg.data), qos.HUMAN)
        self.create_subscription(Vector3Stamped, topics.FEEDBACK_PRESSED,  # the console's
                                 lambda msg: self._on_heard_feedback(msg.vector.x), qos.HUMAN)
        self.create_subscription(Vector3Stamped, topics.QUESTION, self._on_question, qos.HUMAN)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(config.summary_period, self._log_summary, clock=steady)
        self._unsent = collections.deque(maxlen=HELD_FEEDBACK)  # until the learner is matched
        self._unsaid = collections.deque(maxlen=HELD_FEEDBACK)  # utterances, likewise
        self._listen()
        self.create_timer(HELD_CHECK_S, self._send_held, clock=steady)
        self.create_timer(TRAINER_STATUS_PERIOD_S, self._publish_trainer_status, clock=steady)
        self._last_summary = None
        self.get_logger().info(f'feedback_node ready: {self._mode_text()}')

    def _mode_text(self) -> str:
        if not self._synthetic:
            return 'a person trains (synthetic:=false): publishing nothing, logging what it hears'
        c = self._config
        interval = ('off' if c.utterance_interval < 0 else 'every step'
                    if c.utterance_interval == 0 else f'every {c.utterance_interval:g} s')
        human = (f'feedback probability {c.feedback_probability:g}, '
                 f'delay {c.feedback_delay_min:g}-{c.feedback_delay_max:g} s, '
                 f'noise {c.feedback_noise:g}'
                 + (f', marked {c.feedback_marked:g}' if c.feedback_marked else ''))
        if self._kind == 'teacher':
            plain = ((' (on feedback_pressed with the moment given: it comes late)'
                      if self._press_times else ' (plain feedback only: it comes late)')
                     if c.delayed else '')
            task = '' if self._task == DEFAULT_TASK else f' of task {self._task}'
            return (f"teacher{task}: judges each action against the expert's, utterances "
                    f'{interval}, {human}{plain}')
        return (f'synthetic trainer, reward {c.reward_variant} (alpha {c.alpha_threshold:g}, '
                f'beta {c.beta_threshold:g}, stationary {c.stationary_steps} steps), '
                f'utterances {interval}, feedback probability {c.feedback_probability:g}, '
                f'delay {c.feedback_delay_min:g}-{c.feedback_delay_max:g} s, '
                f'noise {c.feedback_noise:g}')

    def _on_set_parameters(self, parameters) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name == 'synthetic':
                if not isinstance(parameter.value, bool):
                    return SetParametersResult(successful=False, reason='synthetic is a bool')
                if parameter.value and not self._synthetic:
                    self._trainer.reset()  # do not judge across the time a person trained
                self._synthetic = parameter.value
                self.get_logger().info(f'now: {self._mode_text()}')
        return SetParametersResult(successful=True)

    # -- the synthetic trainer --------------------------------------------------------------

    def _on_position(self, msg: PointStamped) -> None:
        stamp_ns = stamp_to_ns(msg.header.stamp)
        x, y = msg.point.x, msg.point.y
        problem = position_problem(x, y)
        if problem is not None:
            self._counts['bad_positions'] += 1
            self.get_logger().error(f'agent_position dropped: {problem}')
            return
        self._now_ns = stamp_ns
        if not self._synthetic or self._kind != 'thesis':
            return
        out = self._trainer.on_position(stamp_ns, x, y)
        self._handled_ns = max(self._handled_ns, stamp_ns)
        if self._trainer.counts['restarts'] > self._restarts_logged:
            self._restarts_logged = self._trainer.counts['restarts']
            self.get_logger().warning(
                f'agent_position stamps went back (now {stamp_ns} ns): a new trial, '
                'starting the trainer over')
        for feedback in out.feedback:
            self._publish_feedback(feedback.stamp_ns, feedback.h, feedback.position,
                                   feedback.distance, feedback.pressed_ns, feedback.marked)
        if out.utterance is not None:
            self._publish_utterance(out.utterance)

    def _publish_feedback(self, stamp_ns: int, h: float, y: float, z: float,
                          pressed_ns: int, marked: bool = False) -> None:
        """
        feedback_stamped, or plain feedback (or pressed) when it comes late as a person's.

        ``marked``: a late verdict given with the step it judges goes out stamped all the same.
        """
        self._unsent.append((stamp_ns, h, y, z, pressed_ns, marked))
        self._send_held()

    def _readers(self, publisher) -> int:
        """Return the readers matched with ``publisher``, this node's own not counted."""
        own = publisher in (self._utterance_pub, self._feedback_pub)  # it hears both topics
        return publisher.get_subscription_count() - int(own)

    def _send_held(self) -> None:
        """
        Publish what is held once enough readers are matched.

        Feedback once ``wait_feedback_subscribers`` readers are matched, utterances (stamped
        and plain, together) once each topic has ``wait_utterance_subscribers`` (this node's
        own reader not counted); and each once the nodes it waits for by name
        (``wait_feedback_nodes``, ...) are among them.

        The topics are volatile: a message published before a reader matched never reaches it
        (a 300-step run can end before discovery is done: once the learner, once the launcher's
        monitor heard none of 300), so judgements wait here instead.
        """
        if not self._listening:
            self._listen()
        listeners = min(self._readers(self._utterance_pub),
                        self._readers(self._utterance_stamped_pub))
        if (self._unsaid and listeners >= self._wait_listeners
                and self._named_matched(self._utterance_pub)
                and self._named_matched(self._utterance_stamped_pub)):
            while self._unsaid:
                stamped_utterance, plain = self._unsaid.popleft()
                self._utterance_stamped_pub.publish(stamped_utterance)
                self._utterance_pub.publish(plain)
                self._given['given_utterances'] += 1
        publisher = self._feedback_publisher()
        stamped = publisher is self._feedback_stamped_pub
        pressed = publisher is self._feedback_pressed_pub
        if not self._unsent or any(
                p.get_subscription_count() < self._wait_subscribers or not self._named_matched(p)
                for p in self._feedback_publishers()):
            return
        while self._unsent:
            stamp_ns, h, y, z, pressed_ns, marked = self._unsent.popleft()
            if stamped or pressed or marked:  # the step judged, or the moment given
                msg_out = Vector3Stamped()
                msg_out.header.stamp = ns_to_stamp(pressed_ns if pressed and not marked
                                                   else stamp_ns)
                msg_out.vector.x, msg_out.vector.y, msg_out.vector.z = (
                    float(h), float(y), float(z))
                (self._feedback_stamped_pub if marked else publisher).publish(msg_out)
            if not (stamped or pressed or marked) or self._plain_copies:
                self._feedback_pub.publish(Float32(data=float(h)))
            self._given['given_feedback'] += 1

    def _listen(self) -> None:
        """
        Subscribe to the steps once the nodes named for the judgements and words are matched.

        The env takes its first step only once this node listens (``wait_position_subscribers``,
        ``wait_status_subscribers``), so what the trainer says at the first steps goes to the
        learner and the saliency node, not to a viewer in their place.
        """
        waiting = self._waiting_for()
        if waiting and time.monotonic() < self._listen_by:
            return
        if waiting:
            self.get_logger().warning(
                f'listening to the steps after {LISTEN_WAIT_S:g} s although {waiting}')
        self._listening = True
        self.create_subscription(PointStamped, topics.AGENT_POSITION, self._on_position,
                                 qos.STEP_DATA)
        if self._kind == 'teacher':
            self.create_subscription(DiagnosticArray, topics.ENV_STATUS, self._on_status,
                                     qos.STEP_DATA)

    def _waiting_for(self) -> str:
        """
        Say what the trainer waits for before it listens to the steps ('' when nothing).

        Nothing when no reader is named (``ros2 run`` alone: it listens at once and holds what
        it says until the counts are matched, as ever). With names, the counts too: words held
        for a late reader are held for all.
        """
        if not self._named:
            return ''
        publishers = (*self._feedback_publishers(), self._utterance_pub,
                      self._utterance_stamped_pub)
        unmatched = [publisher.topic_name for publisher in publishers
                     if not self._named_matched(publisher)]
        if unmatched:
            return f'the nodes named for {", ".join(unmatched)} are not matched'
        for feedback in self._feedback_publishers():
            if feedback.get_subscription_count() < self._wait_subscribers:
                return f'{feedback.topic_name} has fewer than {self._wait_subscribers} readers'
        if min(self._readers(self._utterance_pub),
               self._readers(self._utterance_stamped_pub)) < self._wait_listeners:
            return f'the utterance topics have fewer than {self._wait_listeners} readers'
        return ''

    def _feedback_publisher(self):
        """Return the publisher judgements go out on: stamped, pressed, or plain (late)."""
        if not (self._kind == 'teacher' and self._config.delayed):
            return self._feedback_stamped_pub
        return self._feedback_pressed_pub if self._press_times else self._feedback_pub

    def _feedback_publishers(self) -> tuple:
        """Return the publishers judgements go out on: with marks or answers, stamped too."""
        publisher = self._feedback_publisher()
        if ((self._config.feedback_marked > 0.0 or self._asked)
                and publisher is not self._feedback_stamped_pub):
            return publisher, self._feedback_stamped_pub
        return (publisher,)

    def _named_matched(self, publisher) -> bool:
        """Tell whether the nodes ``publisher`` waits for by name are matched (then remembered)."""
        if self._wait_names.get(publisher):
            if nodes_unmatched(self, publisher, self._wait_names[publisher]):
                return False
            self._wait_names[publisher] = ()  # matched once: the graph's learners stay
        return True

    def _publish_trainer_status(self) -> None:
        """
        Say on ``trainer_status`` (latched) how far the synthetic trainer got, when it changed.

        ``handled_ns``: the newest step judged from (-1: none); ``given_*``: what went out;
        ``held``: what waits for its readers; the trainer's counts besides. The launcher waits
        for it at a run's end: every step judged, and everything given logged by the learner.
        """
        values = {'handled_ns': self._handled_ns, **self._given,
                  'held': len(self._unsent) + len(self._unsaid),
                  **self._counts, **self._trainer.counts}
        if values == self._last_trainer_status:
            return
        self._last_trainer_status = values
        status = DiagnosticStatus(level=DiagnosticStatus.OK, name='trainer',
                                  hardware_id=HARDWARE_ID, message=self._kind,
                                  values=[KeyValue(key=key, value=str(value))
                                          for key, value in values.items()])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._trainer_status_pub.publish(msg)

    # -- the teacher --------------------------------------------------------------------------

    def _on_status(self, msg: DiagnosticArray) -> None:
        try:
            status = next(s for s in msg.status if s.name == STATUS_NAME)
            values = parse_status((kv.key, kv.value) for kv in status.values)
            seen = self._trainer.see(stamp_to_ns(msg.header.stamp), values)
        except StopIteration:
            self._drop_status(f'no {STATUS_NAME} status in it')
            return
        except (KeyError, ValueError, TypeError) as error:
            self._drop_status(f'not a status the teacher can read ({error!r})')
            return
        self._now_ns = seen.stamp_ns
        if not self._synthetic:
            return
        out = self._trainer.on_step(seen)
        self._handled_ns = max(self._handled_ns, seen.stamp_ns)
        if self._trainer.counts['restarts'] > self._restarts_logged:
            self._restarts_logged = self._trainer.counts['restarts']
            self.get_logger().warning(f'env_status stamps went back (now {seen.stamp_ns} ns): '
                                      'a new trial, starting the teacher over')
        for judgement in out.feedback:
            self._publish_feedback(judgement.stamp_ns, judgement.h, judgement.expert_action,
                                   judgement.action, judgement.pressed_ns, judgement.marked)
        if out.utterance is not None:
            self._publish_utterance(out.utterance)

    def _on_question(self, msg: Vector3Stamped) -> None:
        """Answer the learner's question about a step, stamped (``ActionTeacher.ask``)."""
        if not self._synthetic or self._kind != 'teacher':
            self._counts['unanswerable_questions'] += 1  # a person, or the thesis's trainer
            return
        self._asked = True
        for answer in self._trainer.ask(stamp_to_ns(msg.header.stamp)):
            self._publish_feedback(answer.stamp_ns, answer.h, answer.expert_action,
                                   answer.action, answer.pressed_ns, answer.marked)

    def _drop_status(self, problem: str) -> None:
        self._counts['bad_status'] += 1
        self.get_logger().error(f'env_status dropped: {problem}')

    def _publish_utterance(self, utterance: Utterance) -> None:
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK, name='utterance', message=utterance.text,
            hardware_id=HARDWARE_ID,
            values=[KeyValue(key='position', value=str(utterance.position)),
                    KeyValue(key='sentence_of', value=str(utterance.sentence_of))])
        stamped = DiagnosticArray(status=[status])
        stamped.header.stamp = ns_to_stamp(utterance.stamp_ns)
        self._unsaid.append((stamped, String(data=utterance.text)))
        self._send_held()
        self._counts['utterances'] += 1
        self.get_logger().debug(f'said at {utterance.stamp_ns / NS_PER_S:.2f} s: '
                                f'{utterance.text!r}')

    # -- a person -----------------------------------------------------------------------------

    def _now_text(self) -> str:
        return 'before the first step' if self._now_ns is None else (
            f'at {self._now_ns / NS_PER_S:.2f} s of simulation time')

    def _on_heard_utterance(self, msg: String) -> None:
        if self._synthetic:
            return  # our own copies
        problem = utterance_problem(msg.data)
        if problem is not None:
            self._counts['bad_utterances'] += 1
            self.get_logger().error(f'bad utterance ignored ({problem}): {excerpt(msg.data)}')
            return
        self._counts['heard_utterances'] += 1
        self.get_logger().info(f'a person said {msg.data!r} {self._now_text()}')

    def _on_heard_feedback(self, h: float) -> None:
        if self._synthetic:
            return
        problem = feedback_problem(h)
        if problem is not None:
            self._counts['bad_feedback'] += 1
            self.get_logger().error(f'bad feedback ignored: {problem}')
            return
        self._counts['heard_feedback'] += 1
        self.get_logger().info(f'a person gave feedback {h:+g} {self._now_text()}')

    def _log_summary(self) -> None:
        summary = dict(self._counts, **self._trainer.counts)
        if self._kind == 'thesis':
            summary['withheld_utterances'] = self._trainer.utterances.withheld
        if summary != self._last_summary:
            self._last_summary = summary
            self.get_logger().info(
                'counts: ' + ', '.join(f'{key} {value}' for key, value in summary.items()))


def main(args=None):
    return run_node(FeedbackNode, args=args)


if __name__ == '__main__':
    raise SystemExit(main())

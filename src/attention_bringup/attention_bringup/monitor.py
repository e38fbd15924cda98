"""
The launcher's own node: watches the graph's topics and asks the nodes for their parameters.

Callbacks only update counters, the progress tracker and the gallery collector under one lock;
the launcher's main thread reads them. Watching must not slow the graph (each message costs the
launcher's executor a few hundred microseconds, an image more): per step the launcher takes
``env_status`` (which carries the position and env_node's own closed-loop latency) and the
stamped feedback, and ``saliency`` raw and best-effort to count it (a lost one only costs a
count). ``observation`` and ``saliency_mask`` only while the gallery takes a sample; the plain
``feedback`` / ``utterance`` only when a person trains (the synthetic trainer's stamped
companions carry the same).

Subscriptions change only on the executor's own thread (a timer), never from the launcher's main
thread: destroying a subscription while another thread spins the executor can hang that
executor for good (seen as a "stall" at the gallery's first sample).
"""

import functools
import threading
import time
import traceback
from typing import Dict, Optional

from attention_bringup.gallery import (
    cdr_header_stamp_ns, GalleryCollector, MASK, OBSERVATION, SALIENCY)
from attention_bringup.progress import parse_key_values, ProgressTracker
from attention_common import qos, topics
from attention_common.stamps import stamp_to_ns
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from sensor_msgs.msg import Image
from std_msgs.msg import Float32, String

SUBSCRIPTION_PERIOD_S = 0.1
"""How often the monitor's timer adds or removes the image subscriptions."""

COUNTED_TOPICS = (
    topics.ENV_STATUS, topics.UTTERANCE, topics.UTTERANCE_STAMPED, topics.FEEDBACK,
    topics.FEEDBACK_STAMPED, topics.FEEDBACK_PRESSED, topics.SALIENCY, topics.METRICS,
)
"""Topics the launcher hears whole and counts (the gallery's images come and go)."""
PLAIN_TOPICS = (topics.FEEDBACK, topics.UTTERANCE)


def key_values(msg: DiagnosticArray) -> Dict[str, object]:
    pairs = [(kv.key, kv.value) for status in msg.status for kv in status.values]
    return parse_key_values(pairs)


class GraphMonitor(Node):
    """Subscribes to every topic of the graph; keeps what the launcher shows and writes."""

    def __init__(self, tracker: ProgressTracker, gallery: GalleryCollector,
                 watch_plain: bool = True, **kwargs):
        super().__init__('attention_train', **kwargs)
        self.lock = threading.Lock()
        self.env_message = ''
        """The newest env_status's message: 'running', 'paused', 'episode over', 'finished'."""
        self.tracker = tracker
        self.gallery = gallery
        self.counts = dict.fromkeys(
            (t for t in COUNTED_TOPICS if watch_plain or t not in PLAIN_TOPICS), 0)
        self.first_message_wall: Dict[str, float] = {}
        self.metrics: Dict[str, object] = {}
        self.trainer_status: Optional[Dict[str, object]] = None
        """The newest ``trainer_status`` values of feedback_node (None: none heard)."""
        self.receipts: Dict[str, int] = {'feedback': 0, 'utterance': 0}
        """The learner's receipts on ``feedback_logged``, by kind."""
        self._started = time.monotonic()
        sub = self.create_subscription
        self._status_subscription = sub(
            DiagnosticArray, topics.ENV_STATUS, self._on_env_status, qos.WATCH_STEPS)
        for verdicts in (topics.FEEDBACK_STAMPED, topics.FEEDBACK_PRESSED):  # a trainer's
            sub(Vector3Stamped, verdicts, functools.partial(self._on_verdict, verdicts),
                qos.WATCH_STEPS)
        sub(DiagnosticArray, topics.UTTERANCE_STAMPED, self._on_utterance_stamped, qos.WATCH_STEPS)
        if watch_plain:
            sub(Float32, topics.FEEDBACK, self._on_feedback, qos.WATCH_STEPS)
            sub(String, topics.UTTERANCE, self._on_utterance, qos.WATCH_STEPS)
        sub(DiagnosticArray, topics.METRICS, self._on_metrics, qos.METRICS)
        sub(DiagnosticArray, topics.TRAINER_STATUS, self._on_trainer_status, qos.LATCHED)
        sub(DiagnosticArray, topics.FEEDBACK_LOGGED, self._on_receipt, qos.HUMAN)
        self._images_wanted = threading.Event()
        self._watching_images = False
        self._gallery_subscriptions = ()
        self.create_timer(SUBSCRIPTION_PERIOD_S, self._manage_subscriptions)

    def watch_images(self) -> None:
        """Ask for the image subscriptions (call once env_node is heard; any thread)."""
        self._images_wanted.set()

    def _manage_subscriptions(self) -> None:
        """
        Add or remove image subscriptions (a timer, so on the executor's thread).

        ``saliency`` once asked for; ``observation`` and ``saliency_mask`` only while the
        gallery waits for a sample (saliency_node renders masks only while someone subscribes).
        """
        if self._images_wanted.is_set() and not self._watching_images:
            self._watching_images = True
            self.create_subscription(Image, topics.SALIENCY,
                                     self._image_callback(topics.SALIENCY, SALIENCY),
                                     qos.WATCH_IMAGES, raw=True)
        with self.lock:
            waiting = self.gallery.waiting and not self.gallery.full
        if waiting and self._watching_images and not self._gallery_subscriptions:
            self._gallery_subscriptions = tuple(
                self.create_subscription(Image, topic, self._image_callback(topic, kind),
                                         qos.WATCH_IMAGES, raw=True)
                for topic, kind in ((topics.OBSERVATION, OBSERVATION),
                                    (topics.SALIENCY_MASK, MASK)))
        elif not waiting and self._gallery_subscriptions:
            for subscription in self._gallery_subscriptions:
                self.destroy_subscription(subscription)
            self._gallery_subscriptions = ()

    def learners_listen(self, recorders: int = 0) -> bool:
        """Return whether saliency, tamer, feedback (and the ``recorders``) listen."""
        return (self.count_subscribers(topics.OBSERVATION) >= 2 + recorders
                and self.count_subscribers(topics.AGENT_POSITION) >= 1 + recorders)

    def node_subscribes(self, node_name: str, topic: str) -> bool:
        """Return whether the node ``node_name`` subscribes to ``topic`` (in the graph)."""
        name = self.resolve_topic_name(topic)
        return any(info.node_name == node_name
                   for info in self.get_subscriptions_info_by_topic(name))

    def hears_env(self) -> bool:
        """Return whether env_node's ``env_status`` is matched (so no step goes unseen)."""
        return self._status_subscription.get_publisher_count() > 0

    def elapsed(self) -> float:
        return time.monotonic() - self._started

    def _count(self, topic: str) -> None:
        if topic in self.counts:
            self.counts[topic] += 1
            self.first_message_wall.setdefault(topic, self.elapsed())

    def _on_env_status(self, msg: DiagnosticArray) -> None:
        values = key_values(msg)
        with self.lock:
            self._count(topics.ENV_STATUS)
            self.env_message = msg.status[0].message if msg.status else ''
            self.tracker.on_status(stamp_to_ns(msg.header.stamp), values, self.elapsed())

    def _on_verdict(self, topic: str, msg: Vector3Stamped) -> None:
        """Count a verdict, stamped or pressed (x = h): a trainer's or the console's."""
        with self.lock:
            self._count(topic)
            self.tracker.counters.feedback += 1
            self.tracker.counters.feedback_sum += float(msg.vector.x)

    def _on_feedback(self, msg: Float32) -> None:
        with self.lock:
            self._count(topics.FEEDBACK)
            # Heard only while a person trains (watch_plain): no trainer sends copies then, so
            # every plain feedback is the person's own, even beside their stamped presses.
            self.tracker.counters.feedback += 1
            self.tracker.counters.feedback_sum += float(msg.data)

    def _on_utterance_stamped(self, msg: DiagnosticArray) -> None:
        stamp = stamp_to_ns(msg.header.stamp)
        with self.lock:
            self._count(topics.UTTERANCE_STAMPED)
            for status in msg.status:
                self.tracker.counters.utterances += 1
                self.gallery.on_utterance(stamp, status.message)

    def _on_utterance(self, msg: String) -> None:
        with self.lock:
            self._count(topics.UTTERANCE)
            if self.counts[topics.UTTERANCE_STAMPED] == 0:  # a person: stamp it with "now"
                self.tracker.counters.utterances += 1
                rows = self.tracker.rows
                now = int(rows[-1]['sim_time_s'] * 1e9) if rows else 0
                self.gallery.on_utterance(now, msg.data)

    def _on_metrics(self, msg: DiagnosticArray) -> None:
        values = key_values(msg)
        with self.lock:
            self._count(topics.METRICS)
            self.metrics.update(values)

    def _on_trainer_status(self, msg: DiagnosticArray) -> None:
        values = key_values(msg)
        with self.lock:
            self.trainer_status = values

    def _on_receipt(self, msg: DiagnosticArray) -> None:
        with self.lock:
            for status in msg.status:
                self.receipts[status.name] = self.receipts.get(status.name, 0) + 1

    def _image_callback(self, topic: str, kind: str):
        def callback(raw: bytes) -> None:
            try:
                stamp = cdr_header_stamp_ns(raw)
            except ValueError as error:
                self.get_logger().warning(f'{topic}: {error}')
                return
            with self.lock:
                self._count(topic)
                if kind == SALIENCY:
                    self.tracker.counters.saliency += 1
                self.gallery.on_image(kind, stamp, raw)
        return callback

    def query_parameters(self, node_names, timeout_s: float = 10.0) -> Dict[str, Optional[dict]]:
        """
        Ask every node for all its parameters, all at once; None for a node that does not answer.

        Call from a thread other than the one spinning this node.
        """
        deadline = time.monotonic() + timeout_s
        clients = {name: (self.create_client(ListParameters, f'/{name}/list_parameters'),
                          self.create_client(GetParameters, f'/{name}/get_parameters'))
                   for name in node_names}
        result: Dict[str, Optional[dict]] = dict.fromkeys(node_names)
        try:
            listing = {}
            for name, (lister, getter) in clients.items():
                ready = (lister.wait_for_service(timeout_sec=self._left(deadline))
                         and getter.wait_for_service(timeout_sec=self._left(deadline)))
                if ready:
                    listing[name] = lister.call_async(ListParameters.Request())
            getting = {}
            for name, future in listing.items():
                listed = self._wait(future, deadline)
                if listed is not None:
                    names = sorted(listed.result.names)
                    getting[name] = (names, clients[name][1].call_async(
                        GetParameters.Request(names=names)))
            for name, (names, future) in getting.items():
                got = self._wait(future, deadline)
                if got is not None:
                    result[name] = {n: parameter_value_to_python(v)
                                    for n, v in zip(names, got.values)}
        finally:
            for lister, getter in clients.values():
                self.destroy_client(lister)
                self.destroy_client(getter)
        return result

    @staticmethod
    def _left(deadline: float) -> float:
        return max(0.0, deadline - time.monotonic())

    @staticmethod
    def _wait(future, deadline: float):
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        return future.result() if future.done() else None


def spin_until_shutdown(executor, context, err, stop=None) -> int:
    """
    Spin ``executor`` until ``context`` shuts down or ``stop`` is set; return how many raised.

    A callback that raises is reported on ``err`` with its traceback and the spinning goes on:
    a silent death of this thread would look like a stalled graph.
    """
    from rclpy.executors import ExternalShutdownException, ShutdownException
    errors = 0
    while context.ok() and not (stop is not None and stop.is_set()):
        try:
            executor.spin_once(timeout_sec=0.2)
        except (ExternalShutdownException, ShutdownException):
            break
        except Exception:  # noqa: B902 - any callback error is reported, then spinning goes on
            if not context.ok():
                break
            errors += 1
            err.write('attention_train: a callback of its monitor failed (the run goes on):\n'
                      + traceback.format_exc())
            err.flush()
    return errors

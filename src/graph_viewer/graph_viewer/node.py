"""
graph_viewer: the running graph, live in Foxglove (a thin rclpy shell on foxglove-sdk's server).

Serves the Foxglove WebSocket protocol on 127.0.0.1:8765: every topic a session bag holds, and
``action_values``, as the publisher's CDR bytes under the message's ROS 2 definition
(``forwarded.py``), with DDS's receive time as the message's time, as the bag has it; and the
DiagnosticArrays as plottable JSON (``plots.py``). Read-only: a client cannot publish, call or
set anything.

A viewer must not slow the graph it shows (a callback per message cost a lockstep run 25 % of
its speed, even with nobody watching). So a topic is subscribed only while a client watches it
(its raw or its plot channel), on a node of its own that no executor spins, and a timer takes
what came (``poll_hz``): per-step topics and images through a depth-1 reader, at most
``max_step_rate_hz`` / ``max_image_rate_hz`` (the newest), so DDS drops the rest and Python
never sees them. The frames and env_status are read from the copies their sources thin to 30
a second (``<topic>/preview``, attention_common.preview), so DDS does not even bring the
rest. A person's words, receipts, credit and metrics come whole, in order. Every thread
of it runs ``nice`` lower than the graph's (``attention_common.priority``): on busy cores the
graph steps first and the viewer takes what is left.
"""

import threading
import time
from typing import Dict, Optional
from urllib.parse import quote

from attention_common.node_main import Closing, run_node, StartupError
from attention_common.parameters import declare_dataclass
from attention_common.preview import preview_topic, PREVIEWED
from attention_common.priority import lower_process_priority
from attention_common.stamps import stamp_to_ns
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS
from attention_tasks.task import load_task, UnknownTask
from diagnostic_msgs.msg import DiagnosticArray
import foxglove
from graph_viewer.config import ViewerConfig
from graph_viewer.forwarded import (ENCODING, FORWARDED, is_image, is_per_step, RateLimit,
                                    SCHEMA_ENCODING, schema_of, viewer_qos)
from graph_viewer.plots import encode, plot_topic, PLOTTED, record_of, SCHEMAS
from graph_viewer.subprotocol import Relay
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.serialization import deserialize_message

LOG_THROTTLE_S = 10.0
MAX_TAKES_PER_POLL = 1000
"""A whole topic's backlog is taken each poll, up to this (the rest at the next)."""
SOURCE_CHECK_S = 1.0
"""How often a watched topic's source is looked at again: its preview once one is published
(a source started after the client subscribed), else the full topic."""


class Watchers:
    """The channels clients subscribe to (a ``foxglove.ServerListener``; called on its thread)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._count: Dict[int, int] = {}

    def on_subscribe(self, client, channel) -> None:
        with self._lock:
            self._count[channel.id] = self._count.get(channel.id, 0) + 1

    def on_unsubscribe(self, client, channel) -> None:
        with self._lock:
            self._count[channel.id] = max(self._count.get(channel.id, 0) - 1, 0)

    def watched(self, channel_id: int) -> bool:
        return self._count.get(channel_id, 0) > 0


class Forward:
    """One graph topic: its channels, its reader while watched, and its rate limit."""

    def __init__(self, topic, name: str, context, limit: Optional[RateLimit]):
        self.topic, self.name, self.limit = topic, name, limit
        self.kind = topic.name if topic.name in PLOTTED else None
        schema_name, definition = schema_of(topic)
        self.raw = foxglove.Channel(
            name, message_encoding=ENCODING, context=context,
            schema=foxglove.Schema(name=schema_name, encoding=SCHEMA_ENCODING, data=definition))
        self.plot = None
        if self.kind is not None:
            self.plot = foxglove.Channel(plot_topic(name), schema=SCHEMAS[self.kind],
                                         context=context)
        self.reader = None
        """The subscription on the viewer's reading node while a client watches."""
        self.preview = preview_topic(name) if topic.name in PREVIEWED else None
        """The source's thinned copy of the topic (attention_common.preview), if it makes one."""
        self.reading: Optional[str] = None
        """The topic the reader reads: ``name`` or its preview."""
        self.checked_at = 0.0
        """When the source was last looked at (monotonic s; only while ``reading`` is set)."""


class GraphViewerNode(Closing, Node):
    """Serves the graph to Foxglove."""

    def __init__(self, **kwargs):
        super().__init__('graph_viewer', **kwargs)
        self.config = declare_dataclass(self, ViewerConfig)
        try:
            self.config.validate()
            task = load_task(self.config.task)
        except (ValueError, UnknownTask) as error:
            raise StartupError(f'graph_viewer: {error}') from None
        self._milestone_of = lambda values: task.milestone_of(values, DEFAULT_RADIUS)
        # DDS's threads now; the server's and the relay's, started below, inherit it.
        for failed in lower_process_priority(self.config.nice):
            self.get_logger().warning(f'priority left as it is: {failed}')
        self.errors = 0
        self.foxglove = foxglove.Context()
        self.watchers = Watchers()
        self.forwards = []
        for topic in FORWARDED:
            rate_hz = (self.config.max_image_rate_hz if is_image(topic) else
                       self.config.max_step_rate_hz if is_per_step(topic) else 0.0)
            limit = RateLimit(rate_hz) if rate_hz > 0 else None
            self.forwards.append(Forward(topic, self.resolve_topic_name(topic.name),
                                         self.foxglove, limit))
        # Never spun: its readers wake nobody; the poll timer takes what they hold.
        self.readers = rclpy.create_node(
            self.get_name() + '_readers', namespace=self.get_namespace(), context=self.context,
            use_global_arguments=False, start_parameter_services=False, enable_rosout=False)
        self.create_timer(1.0 / self.config.poll_hz, self._poll,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        legacy = self.config.legacy_subprotocol
        self.relay = None
        try:
            self.server = foxglove.start_server(
                name='attention graph', context=self.foxglove, server_listener=self.watchers,
                message_backlog_size=self.config.message_backlog,
                host='127.0.0.1' if legacy else self.config.host,
                port=0 if legacy else self.config.port)
            port = self.server.port
            if legacy:
                self.relay = Relay(self.config.host, self.config.port, self.server.port)
                port = self.relay.start()
        except Exception as error:  # noqa: B902 - the SDK's error for a port in use, say
            raise StartupError(f'graph_viewer: cannot serve on {self.config.host}:'
                               f'{self.config.port} ({error})') from None
        self.url = f'ws://{self.config.host}:{port}'
        self.get_logger().info(
            f'Foxglove bridge at {self.url} ({len(self.forwards)} topics; in Foxglove: Open '
            f'connection, Foxglove WebSocket, this URL; or https://app.foxglove.dev/?ds='
            f'foxglove-websocket&ds.url={quote(self.url, safe="")})')

    def _poll(self) -> None:
        now = time.monotonic()
        for forward in self.forwards:
            watched = self.watchers.watched(forward.raw.id()) or (
                forward.plot is not None and self.watchers.watched(forward.plot.id()))
            source = self._source(forward, now) if watched else None
            if forward.reader is not None and forward.reading != source:
                self.readers.destroy_subscription(forward.reader)
                forward.reader = forward.reading = None
            if source is not None and forward.reader is None:
                forward.reader = self.readers.create_subscription(
                    forward.topic.msg_type, source, _never_called, viewer_qos(forward.topic),
                    raw=True)
                forward.reading = source
            if forward.reader is None:
                continue
            if forward.limit is not None:  # a depth-1 reader: its newest, if it is time
                if forward.limit.due(now):
                    taken = _take(forward.reader)
                    if taken is not None:
                        forward.limit.allow(now)
                        self._forward(forward, *taken)
                continue
            for _ in range(MAX_TAKES_PER_POLL):
                taken = _take(forward.reader)
                if taken is None:
                    break
                self._forward(forward, *taken)

    def _source(self, forward: Forward, now: float) -> str:
        """Return the topic to read for ``forward``: its preview while a source publishes one."""
        if forward.preview is None:
            return forward.name
        if forward.reading is not None and now - forward.checked_at < SOURCE_CHECK_S:
            return forward.reading
        forward.checked_at = now
        if (self.readers.count_publishers(forward.preview) > 0
                or self.readers.count_publishers(forward.name) == 0):
            return forward.preview
        return forward.name  # a source that makes no preview (preview_rate_hz 0)

    def _forward(self, forward: Forward, data: bytes, info: dict) -> None:
        log_time = info.get('received_timestamp') or time.time_ns()
        if self.watchers.watched(forward.raw.id()):
            forward.raw.log(data, log_time=log_time)
        if forward.plot is not None and self.watchers.watched(forward.plot.id()):
            try:
                msg = deserialize_message(data, DiagnosticArray)
                record = record_of(forward.kind, stamp_to_ns(msg.header.stamp), msg.status,
                                   self._milestone_of)
            except Exception as error:  # noqa: B902 - a malformed message: never the node
                self.errors += 1
                self.get_logger().error(
                    f'{forward.name}: not plotted ({type(error).__name__}: {error}; '
                    f'{self.errors} so far)', throttle_duration_sec=LOG_THROTTLE_S)
                return
            forward.plot.log(encode(record), log_time=log_time)

    def on_close(self) -> None:
        """Stop serving (clients see the connection close)."""
        if getattr(self, 'relay', None) is not None:
            self.relay.stop()
        if getattr(self, 'server', None) is not None:
            self.server.stop()
        if getattr(self, 'readers', None) is not None:
            self.readers.destroy_node()


def _never_called(msg) -> None:
    """Do nothing: the readers' node is never spun; the poll takes their messages."""


def _take(reader):
    """Return (CDR bytes, info) of the reader's oldest message, or None."""
    with reader.handle:
        return reader.handle.take_message(reader.msg_type, True)


def main(args=None) -> int:
    return run_node(GraphViewerNode, args)

"""
graph_viewer: the running graph, live in Foxglove (a thin rclpy shell on foxglove-sdk's server).

Serves the Foxglove WebSocket protocol (``foxglove.websocket.v1``) on 127.0.0.1:8765: every
topic a session bag holds, and ``action_values``, as the publisher's CDR bytes under the
message's ROS 2 definition (``forwarded.py``), with DDS's receive time as the message's time,
as the bag has it; and the DiagnosticArrays as plottable JSON (``plots.py``). Subscriptions
are raw: a message is never decoded unless a client watches its plot channel, and nothing is
sent on a channel nobody watches. Read-only: a client cannot publish, call or set anything.
"""

import functools
import threading
import time
from typing import Dict, Optional
from urllib.parse import quote

from attention_common.executors import with_message_info
from attention_common.node_main import Closing, run_node, StartupError
from attention_common.parameters import declare_dataclass
from attention_common.stamps import stamp_to_ns
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS
from attention_tasks.task import load_task, UnknownTask
from diagnostic_msgs.msg import DiagnosticArray
import foxglove
from graph_viewer.config import ViewerConfig
from graph_viewer.forwarded import (ENCODING, FORWARDED, is_image, RateLimit, SCHEMA_ENCODING,
                                    schema_of, viewer_qos)
from graph_viewer.plots import encode, plot_topic, PLOTTED, record_of, SCHEMAS
from graph_viewer.subprotocol import Relay
from rclpy.node import Node
from rclpy.serialization import deserialize_message

LOG_THROTTLE_S = 10.0


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
    """One graph topic: its raw channel, its plot channel if it has one, its rate limit."""

    def __init__(self, topic, name: str, context, limit: Optional[RateLimit]):
        self.kind = topic.name if topic.name in PLOTTED else None
        schema_name, definition = schema_of(topic)
        self.raw = foxglove.Channel(
            name, message_encoding=ENCODING, context=context,
            schema=foxglove.Schema(name=schema_name, encoding=SCHEMA_ENCODING, data=definition))
        self.plot = None
        if self.kind is not None:
            self.plot = foxglove.Channel(plot_topic(name), schema=SCHEMAS[self.kind],
                                         context=context)
        self.limit = limit


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
        self.errors = 0
        self.foxglove = foxglove.Context()
        self.watchers = Watchers()
        self.forwards = []
        for topic in FORWARDED:
            holder = []
            subscription = self.create_subscription(
                topic.msg_type, topic.name,
                with_message_info(functools.partial(self._on_message, holder)),
                viewer_qos(topic), raw=True)
            limit = None
            if is_image(topic) and self.config.max_image_rate_hz > 0:
                limit = RateLimit(self.config.max_image_rate_hz)
            holder.append(Forward(topic, subscription.topic_name, self.foxglove, limit))
            self.forwards.append(holder[0])
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

    def _on_message(self, holder: list, data: bytes, info: dict) -> None:
        forward: Forward = holder[0]
        log_time = info.get('received_timestamp') or time.time_ns()
        if forward.limit is not None and not forward.limit.allow(time.monotonic()):
            return
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
                    f'{forward.raw.topic()}: not plotted ({type(error).__name__}: {error}; '
                    f'{self.errors} so far)', throttle_duration_sec=LOG_THROTTLE_S)
                return
            forward.plot.log(encode(record), log_time=log_time)

    def on_close(self) -> None:
        """Stop serving (clients see the connection close)."""
        if getattr(self, 'relay', None) is not None:
            self.relay.stop()
        if getattr(self, 'server', None) is not None:
            self.server.stop()


def main(args=None) -> int:
    return run_node(GraphViewerNode, args)

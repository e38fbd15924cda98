"""
session_recorder: every topic of the graph into a rosbag2 bag (MCAP storage), as it comes.

Subscriptions are raw (``raw=True``): each message is written as the CDR bytes its publisher
sent, never deserialized, with DDS's receive time (the bag's log time) and source time (its
publish time), like ``ros2 bag record``. A topic's channel is added on its first message, with
the QoS its publishers offer (asked from the graph then). Every ``flush_period_s`` the chunk
is closed and handed to the OS and metadata.yaml rewritten, so a SIGKILL loses at most that.
Writing runs in the callbacks: a writer thread measured slower (0.86 of the graph's speed
against 0.92, the GIL shared by two threads), and the frame writers keep 100 frames for a
recorder that falls behind for a moment (``qos.FRAMES_WRITER``). A message that cannot be
written (a full disk) is logged and counted; the node keeps going.
"""

import datetime
import functools
import json
from pathlib import Path

from attention_common.executors import with_message_info
from attention_common.node_main import Closing, run_node, StartupError
from attention_common.parameters import declare_dataclass
from attention_common.priority import lower_process_priority
from attention_common.run_files import OPTIONS_FILE, PARAMS_FILE
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from session_bag.config import RecorderConfig
from session_bag.metadata import qos_dict
from session_bag.recorded import BY_NAME, RecordedTopic, type_name
from session_bag.schema import definition
from session_bag.writer import BagWriter

IMAGE_DEPTH = 100
"""Images waiting to be written, per topic (a reliable publisher of depth 10 waits for us)."""
SMALL_DEPTH = 1000
LOG_THROTTLE_S = 5.0


def subscriber_qos(topic: RecordedTopic) -> QoSProfile:
    """
    Return the recorder's QoS on ``topic``: reliable, volatile, deep.

    Reliable, so a reliable publisher waits for the recorder; KEEP_ALL for a person's words,
    as their other readers have.
    """
    designed = topic.designed_qos
    if designed.history == HistoryPolicy.KEEP_ALL:
        return QoSProfile(history=HistoryPolicy.KEEP_ALL,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    depth = IMAGE_DEPTH if type_name(topic.msg_type) == 'sensor_msgs/msg/Image' else SMALL_DEPTH
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def run_custom_data(run_dir: str) -> dict:
    """Return the run folder's launch options and parameters, for the bag's custom_data."""
    if not run_dir:
        return {}
    data = {'attention.run_dir': str(run_dir)}
    for key, name in (('attention.launch_options', OPTIONS_FILE),
                      ('attention.params', PARAMS_FILE)):
        path = Path(run_dir) / name
        if path.is_file():
            data[key] = path.read_text()
    return data


class RecorderNode(Closing, Node):
    """Writes what the graph publishes into one bag."""

    def __init__(self, **kwargs):
        super().__init__('session_recorder', **kwargs)
        self.config = declare_dataclass(self, RecorderConfig)
        try:
            self.config.validate()
            bag_dir = self.config.bag_path(Path.cwd(), datetime.datetime.now())
            writer = BagWriter(bag_dir, self.config.compression,
                               run_custom_data(self.config.run_dir),
                               sync=self.config.sync == 'grouped')
        except (ValueError, OSError) as error:
            raise StartupError(f'session_recorder: {error}') from error
        self.writer = writer
        self.errors = 0
        # Every thread (os.nice lowers the calling one only): DDS's, and those started later.
        for failed in lower_process_priority(self.config.nice):
            self.get_logger().warning(f'priority left as it is: {failed}')
        self._names = {}
        chosen = [BY_NAME[name] for name in self.config.topic_names()]
        for topic in chosen:  # rosbags' type store loads in 0.2-1 s: now, not at a first frame
            definition(type_name(topic.msg_type))
        for topic in chosen:
            subscription = self.create_subscription(
                topic.msg_type, topic.name,
                with_message_info(functools.partial(self._on_message, topic)),
                subscriber_qos(topic), raw=True)
            self._names[topic.name] = subscription.topic_name  # absolute, as the bag keeps it
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(self.config.flush_period_s, self._flush, clock=steady)
        self.get_logger().info(f'recording {len(self._names)} topics to {bag_dir} '
                               f'({self.config.compression}, flushed every '
                               f'{self.config.flush_period_s:g} s)')

    def _on_message(self, topic: RecordedTopic, data: bytes, info: dict) -> None:
        name = self._names[topic.name]
        try:
            if not self.writer.has_topic(name):  # (a failed add is tried again next time)
                self.writer.add_topic(name, type_name(topic.msg_type), self._offered_qos(topic))
            self.writer.write(name, info.get('received_timestamp') or self._now_ns(), data,
                              info.get('source_timestamp'),
                              info.get('publication_sequence_number') or 0)
        except Exception as error:  # noqa: B902 - a full disk, a bad message: never the node
            self._error(f'{name}: a message could not be written', error)

    def _flush(self) -> None:
        try:
            self.writer.flush()
        except Exception as error:  # noqa: B902
            self._error('the bag could not be flushed', error)

    def _error(self, what: str, error: Exception) -> None:
        self.errors += 1
        self.get_logger().error(f'{what} ({type(error).__name__}: {error}; {self.errors} '
                                'errors so far)', throttle_duration_sec=LOG_THROTTLE_S)

    def _offered_qos(self, topic: RecordedTopic) -> list:
        """Return the QoS of the topic's publishers now (the designed one if none is known)."""
        name = self._names[topic.name]
        profiles = [qos_dict(info.qos_profile)
                    for info in self.get_publishers_info_by_topic(name)]
        return profiles or [qos_dict(topic.designed_qos)]

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def on_close(self) -> None:
        """Close the bag: its last chunk, its index and its metadata."""
        writer = getattr(self, 'writer', None)
        if writer is not None and not writer.closed:
            try:
                writer.close()
                self.get_logger().info(f'bag closed: {writer.message_count} messages in '
                                       f'{writer.bag_dir} {json.dumps(writer.counts)}')
            except Exception as error:  # noqa: B902
                self._error('the bag was not closed whole (attention_bag repair makes it '
                            'readable by every rosbag2 reader)', error)


def main(args=None) -> int:
    return run_node(RecorderNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

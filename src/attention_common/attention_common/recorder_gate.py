"""
Hold a node's first outputs until the session recorder hears them.

A reliable writer sends only to the readers it has matched, and DDS discovery matches each pair
of endpoints on its own: the recorder may already hear the env and the trainer while the
learner's ``feedback_logged`` writer has not found it yet, and the bag then lacks the first
receipts (seen in CI: 7 of 229). So until the recorder node is matched on every gated topic,
a node's messages wait here, in order, and go out together once it is. A topic counts as
matched when the graph lists the recorder's subscription on it and the writer has matched at
least as many readers as the graph lists (discovery reports the two separately).

The gate never hangs the graph: after ``timeout_s`` it opens anyway and says which topics the
recorder had not matched. Thread-safe: any thread may publish through it.
"""

import threading
from typing import Iterable, List, Sequence

from rclpy.clock import Clock, ClockType

CHECK_PERIOD_S = 0.01
RECORDER_WAIT_S = 10.0
"""The nodes' default longest start-up wait for the recorder (wall seconds)."""


def node_names(text: str) -> List[str]:
    """Return the node names of a comma-separated parameter ('a, b' -> ['a', 'b']; '' -> [])."""
    return [name.strip() for name in text.split(',') if name.strip()]


def nodes_unmatched(node, publisher, names: Iterable[str]) -> List[str]:
    """
    Return those of the nodes ``names`` not yet matched with ``publisher`` ([]: all are).

    The graph lists a node's subscription and the writer matches its reader separately, so all
    count as matched only once the writer has matched as many readers as the graph lists.
    """
    readers = node.get_subscriptions_info_by_topic(publisher.topic_name)
    listed = {info.node_name for info in readers}
    missing = [name for name in names if name not in listed]
    if not missing and publisher.get_subscription_count() < len(readers):
        return list(names)
    return missing


def recorder_matched(node, publisher, recorder: str) -> bool:
    """Return whether node ``recorder`` is matched with ``publisher`` (graph and match count)."""
    return not nodes_unmatched(node, publisher, (recorder,))


class RecorderGate:
    """Publishes through ``publish``; holds all until ``recorder`` matches ``publishers``."""

    def __init__(self, node, recorder: str, publishers: Sequence, timeout_s: float):
        self._node = node
        self._recorder = recorder
        self._publishers = list(publishers)
        self._held: List = []
        self._lock = threading.Lock()
        self.is_open = not recorder
        self.held_total = 0
        if self.is_open:
            return
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._deadline = steady.now().nanoseconds + int(timeout_s * 1e9)
        self._steady = steady
        self._timer = node.create_timer(CHECK_PERIOD_S, self._check, clock=steady)

    def publish(self, publisher, msg) -> None:
        """Publish ``msg`` now, or hold it (in order) while the recorder is not matched."""
        if not self.is_open:
            with self._lock:
                if not self.is_open:
                    self._held.append((publisher, msg))
                    self.held_total += 1
                    return
        publisher.publish(msg)

    def _check(self) -> None:
        missing = [p.topic_name for p in self._publishers
                   if not recorder_matched(self._node, p, self._recorder)]
        late = self._steady.now().nanoseconds >= self._deadline
        if missing and not late:
            return
        with self._lock:
            for publisher, msg in self._held:
                publisher.publish(msg)
            held, self._held = len(self._held), []
            self.is_open = True
        self._timer.cancel()
        if missing:
            self._node.get_logger().warning(
                f'{self._recorder} is not matched on {", ".join(missing)} after the start-up '
                f'wait; publishing anyway ({held} held messages sent): the bag may miss some')
        elif held:
            self._node.get_logger().info(
                f'{self._recorder} matched; sent what start-up held: {held} messages')

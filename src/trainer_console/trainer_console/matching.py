"""Before a person's message goes out: every subscriber the ROS graph knows of is matched."""

import time
from typing import Callable, List

MATCH_WAIT_S = 3.0
"""Longest wait, before publishing, for every known subscriber to be matched."""


def subscriber_names(node, topic: str) -> List[str]:
    """Return the nodes the graph knows to subscribe to ``topic`` (``node`` itself left out)."""
    resolved = node.resolve_topic_name(topic)
    return sorted(info.node_name for info in node.get_subscriptions_info_by_topic(resolved)
                  if info.node_name != node.get_name())


def wait_for_all_matched(node, publisher, idle: Callable[[float], None],
                         timeout_s: float = MATCH_WAIT_S) -> bool:
    """
    Wait until ``publisher`` is matched with every subscriber known of (at least one).

    A volatile topic gives a message only to the readers matched when it is published: the
    saliency node, which sends no receipt, would miss it unseen. ``idle(seconds)`` passes the
    time (a sleep, or spinning the caller's executor). Returns whether all were matched.
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        known = len(subscriber_names(node, publisher.topic_name))
        if publisher.get_subscription_count() >= max(1, known):
            return True
        idle(0.01)
    return False

"""
Thinned copies of the busiest topics, for viewers: ``<topic>/preview``, made at the source.

A lockstep run steps at 150-250 steps a second; a viewer draws 30. A viewer that reads the
full topic, even through a depth-1 reader it seldom takes, still has DDS bring it every
message: a wake-up and a copy in its process, one more send in the publisher's (about a third
of the Foxglove bridge's cost, README). The preview carries the same messages, published only
while someone subscribes to it, at most ``rate_hz`` a second (bursts of a few), best effort,
depth 1: real time's 15 steps a second pass whole. Bags and learners read the full topics.
"""

import time
from typing import Callable, Union

from attention_common import qos, topics
from attention_common.rate import TokenBucket

PREVIEW_RATE_HZ = 30.0
"""The sources' default ``preview_rate_hz``: a viewer shows no more."""

PREVIEWED = (topics.OBSERVATION, topics.ENV_STATUS, topics.SALIENCY, topics.SALIENCY_MASK)
"""The topics whose sources publish a preview (one message per step each)."""


def preview_topic(name: str) -> str:
    """Return the preview's name of topic ``name`` ('observation' -> 'observation/preview')."""
    return f'{name}/preview'


class Preview:
    """The preview of one topic on one node: ``publish`` each message of the full topic too."""

    def __init__(self, node, msg_type, topic: str, rate_hz: float = PREVIEW_RATE_HZ,
                 clock: Callable[[], float] = time.monotonic):
        """``rate_hz`` 0: no preview topic at all (viewers then read the full topic)."""
        if not rate_hz >= 0:
            raise ValueError(f'preview_rate_hz must be >= 0, got {rate_hz}')
        self._clock = clock
        self._budget = TokenBucket(rate_hz) if rate_hz > 0 else None
        self.publisher = (node.create_publisher(msg_type, preview_topic(topic), qos.NEWEST)
                          if rate_hz > 0 else None)
        self.published = 0

    def publish(self, msg: Union[object, Callable[[], object]]) -> bool:
        """
        Publish ``msg`` if someone reads the preview and the rate allows; tell whether it went.

        ``msg`` may be a function that makes the message: it is called only when one goes.
        """
        if self.publisher is None or not self.publisher.get_subscription_count():
            return False
        if not self._budget.allow(self._clock()):
            return False
        self.publisher.publish(msg() if callable(msg) else msg)
        self.published += 1
        return True

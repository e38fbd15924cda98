"""
A recorded session as the items a replay sends, and how its learner agrees with it. Pure.

What a replay sends is what the learner and the saliency node heard in the session: the
observations, and a person's (or the trainer's) feedback and utterances, in recorded order.
Each observation carries the action the session's agent answered it with (its ``action``
message, found a few messages later in the bag): the replay sends it on ``action_taken`` just
before the observation, so the new learner credits the feedback to the action it judged.
"""

import collections
from typing import Dict, Iterable, Iterator, List, NamedTuple, Optional

from attention_bringup.gallery import cdr_header_stamp_ns as header_stamp_ns
from attention_common import topics

REPLAYED = (topics.OBSERVATION, topics.FEEDBACK, topics.FEEDBACK_STAMPED, topics.UTTERANCE,
            topics.UTTERANCE_STAMPED)
"""Topics sent to the fresh nodes (relative names)."""
RECEIPTED = (topics.FEEDBACK, topics.FEEDBACK_STAMPED, topics.UTTERANCE)
"""Topics the tamer logs one line for, with a receipt on ``feedback_logged``."""
LOOKAHEAD_OBSERVATIONS = 8
"""How many later observations may come before an observation's action (real time: a few)."""


def relative(topic: str) -> str:
    """'/observation' or '/trial3/observation' -> 'observation'; '/clock' stays."""
    return topic if topic == topics.CLOCK else topic.rsplit('/', 1)[-1]


class Item(NamedTuple):
    topic: str
    """Relative topic name (``REPLAYED``)."""
    log_time: int
    """When the session's recorder received it (ns)."""
    data: bytes
    stamp: Optional[int] = None
    """An observation's header stamp."""
    taken: Optional[bytes] = None
    """An observation's: the session's ``action`` message answering it (None: none found)."""


def replay_items(messages: Iterable) -> Iterator[Item]:
    """
    Yield the items to replay from a bag's messages (``session_bag.reader.BagMessage``).

    An observation is held back until its action comes (or ``LOOKAHEAD_OBSERVATIONS`` more
    observations came); what follows it waits behind it, so the order is kept.
    """
    pending: collections.deque = collections.deque()  # [Item] lists, oldest first
    waiting: Dict[int, list] = {}  # stamp -> the pending observation still without its action
    observations = 0  # in pending

    def release(final: bool = False) -> Iterator[Item]:
        nonlocal observations
        while pending:
            item = pending[0][0]
            if item.topic == topics.OBSERVATION:
                if (not final and waiting.get(item.stamp) is pending[0]
                        and observations <= LOOKAHEAD_OBSERVATIONS):
                    return
                observations -= 1
                if waiting.get(item.stamp) is pending[0]:
                    del waiting[item.stamp]
            yield pending.popleft()[0]

    for message in messages:
        topic = relative(message.topic)
        if topic == topics.ACTION:
            holder = waiting.pop(header_stamp_ns(message.data), None)
            if holder is not None:
                holder[0] = holder[0]._replace(taken=message.data)
        elif topic in REPLAYED:
            stamp = header_stamp_ns(message.data) if topic == topics.OBSERVATION else None
            holder = [Item(topic, message.log_time, message.data, stamp)]
            pending.append(holder)
            if stamp is not None:
                observations += 1
                waiting.setdefault(stamp, holder)  # a re-sent step: its first copy gets it
        yield from release()
    yield from release(final=True)


class Agreement:
    """How the replayed learner's greedy actions agree with the session's, step by step."""

    def __init__(self):
        self.rows: List[dict] = []

    def add(self, stamp: int, session: Optional[int], replayed: Optional[int]) -> None:
        agree = None if session is None or replayed is None else int(session == replayed)
        self.rows.append({'step': len(self.rows) + 1, 'stamp_ns': stamp,
                          'session_action': session, 'replayed_action': replayed,
                          'agree': agree})

    def compared(self, rows: Optional[List[dict]] = None) -> List[dict]:
        return [r for r in (self.rows if rows is None else rows) if r['agree'] is not None]

    def fraction(self, rows: Optional[List[dict]] = None) -> Optional[float]:
        compared = self.compared(rows)
        return sum(r['agree'] for r in compared) / len(compared) if compared else None

    def curve(self, windows: int = 20) -> List[dict]:
        """Agreement in ``windows`` consecutive windows of steps: [{'step', 'agreement'}]."""
        size = max(1, -(-len(self.rows) // windows))
        curve = []
        for start in range(0, len(self.rows), size):
            part = self.rows[start:start + size]
            value = self.fraction(part)
            if value is not None:
                curve.append({'step': part[-1]['step'], 'agreement': round(value, 4)})
        return curve

    def summary(self) -> dict:
        quarter = self.rows[len(self.rows) * 3 // 4:]
        fraction, last = self.fraction(), self.fraction(quarter)
        return {
            'steps': len(self.rows),
            'compared': len(self.compared()),
            'unanswered': sum(r['replayed_action'] is None for r in self.rows),
            'without_session_action': sum(r['session_action'] is None for r in self.rows),
            'agreement': None if fraction is None else round(fraction, 4),
            'agreement_last_quarter': None if last is None else round(last, 4),
            'curve': self.curve(),
        }

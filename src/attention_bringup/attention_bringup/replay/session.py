"""
A recorded session as the items a replay sends, and how its learner agrees with it. Pure.

What a replay sends is what the learner and the saliency node heard in the session: the
observations, and a person's (or the trainer's) feedback and utterances, in recorded order.
Each observation carries the action the world executed on it (the next step's ``env_status``,
found a few messages later in the bag; else the session learner's ``action`` answer): the
replay sends it on ``action_taken`` just before the observation, so the new learner credits
the feedback to the action the person saw and judged.
"""

import collections
from typing import Dict, Iterable, Iterator, List, NamedTuple, Optional, Tuple

from attention_bringup.gallery import cdr_header_stamp_ns as header_stamp_ns
from attention_common import topics
from attention_common.stamps import stamp_to_ns
from attention_tasks.task import NO_ACTION
from diagnostic_msgs.msg import DiagnosticArray
from env_node.status import STATUS_NAME as ENV_STATUS_NAME
from rclpy.serialization import deserialize_message

REPLAYED = (topics.OBSERVATION, topics.FEEDBACK, topics.FEEDBACK_STAMPED,
            topics.FEEDBACK_PRESSED, topics.UTTERANCE, topics.UTTERANCE_STAMPED)
"""Topics sent to the fresh nodes (relative names)."""
RECEIPTED = (topics.FEEDBACK, topics.FEEDBACK_STAMPED, topics.FEEDBACK_PRESSED,
             topics.UTTERANCE)
"""Topics the tamer logs one line for, with a receipt on ``feedback_logged``."""
LOOKAHEAD_OBSERVATIONS = 8
"""How many later observations may come before an observation's executed action is known (one
in lockstep and in real time; more only where a step has none: an episode's last)."""


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
    executed: Optional[int] = None
    """An observation's: the task action the world executed on that step (the next step's
    ``env_status`` says which; in real time it is the answer that was newest at the tick)."""
    answered: Optional[bytes] = None
    """An observation's: the session learner's ``action`` message answering it."""


def executed_action(data: bytes) -> Optional[Tuple[int, Optional[int]]]:
    """
    Return (stamp, task action applied to reach that step) of an env_status, or None.

    The action is None at a reset or the start (no agent action led to that step).
    """
    message = deserialize_message(data, DiagnosticArray)
    for status in message.status:
        if status.name == ENV_STATUS_NAME:
            value = next((kv.value for kv in status.values if kv.key == 'action'), None)
            try:
                action = int(value)
            except (TypeError, ValueError):
                return None
            return stamp_to_ns(message.header.stamp), None if action == NO_ACTION else action
    return None


def _with_early(item: Item, early_status: Dict[int, Optional[int]],
                early_answer: Dict[int, bytes]) -> Tuple[Item, bool]:
    """
    Attach to a step what was logged before it; return (item, whether its action is known).

    The step's executed action is the first env_status after it (the next step's); what is
    older than the step can no longer be anyone's, and is dropped.
    """
    later = [s for s in early_status if s > item.stamp]
    closed = bool(later)
    if closed:
        item = item._replace(executed=early_status.pop(min(later)))
    item = item._replace(answered=early_answer.pop(item.stamp, None))
    for stale in [s for s in early_status if s <= item.stamp]:
        del early_status[stale]
    for stale in [s for s in early_answer if s < item.stamp]:
        del early_answer[stale]
    return item, closed


def replay_items(messages: Iterable) -> Iterator[Item]:
    """
    Yield the items to replay from a bag's messages (``session_bag.reader.BagMessage``).

    An observation is held back until the next step's ``env_status`` says which action was
    executed on it (or ``LOOKAHEAD_OBSERVATIONS`` more observations came: the last step of an
    episode has none); what follows it waits behind it, so the order is kept. Its ``action``
    answer is attached on the way.

    A loaded recorder may log a step's observation after its answer and the next step's
    env_status (each topic keeps its own order, not the others'): those are kept until their
    observation comes.
    """
    pending: collections.deque = collections.deque()  # [Item] lists, oldest first
    open_steps: Dict[int, list] = {}  # stamp -> pending observation without its executed action
    by_stamp: Dict[int, list] = {}  # stamp -> pending observation (the first copy of a step)
    observations = 0  # in pending
    early_status: Dict[int, Optional[int]] = {}  # status stamp -> action, before its step came
    early_answer: Dict[int, bytes] = {}  # stamp -> answer heard before its observation

    def release(final: bool = False) -> Iterator[Item]:
        nonlocal observations
        while pending:
            holder = pending[0]
            item = holder[0]
            if item.topic == topics.OBSERVATION:
                if (not final and open_steps.get(item.stamp) is holder
                        and observations <= LOOKAHEAD_OBSERVATIONS):
                    return
                observations -= 1
                for index in (open_steps, by_stamp):
                    if index.get(item.stamp) is holder:
                        del index[item.stamp]
            yield pending.popleft()[0]

    for message in messages:
        topic = relative(message.topic)
        if topic == topics.ENV_STATUS:
            found = executed_action(message.data)
            earlier = [s for s in open_steps if found and s < found[0]]
            if earlier:  # the step this one was reached from: the newest before it
                holder = open_steps.pop(max(earlier))
                holder[0] = holder[0]._replace(executed=found[1])
            elif found:
                early_status[found[0]] = found[1]
        elif topic == topics.ACTION:
            stamp = header_stamp_ns(message.data)
            holder = by_stamp.get(stamp)
            if holder is None:
                early_answer.setdefault(stamp, message.data)
            elif holder[0].answered is None:
                holder[0] = holder[0]._replace(answered=message.data)
        elif topic in REPLAYED:
            stamp = header_stamp_ns(message.data) if topic == topics.OBSERVATION else None
            item = Item(topic, message.log_time, message.data, stamp)
            if stamp is not None and stamp not in by_stamp:
                item, closed = _with_early(item, early_status, early_answer)
            holder = [item]
            pending.append(holder)
            if stamp is not None:
                observations += 1
                if stamp not in by_stamp:  # a re-sent step: its first copy is the step
                    by_stamp[stamp] = holder
                    if not closed:
                        open_steps[stamp] = holder
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

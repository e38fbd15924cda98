"""What the agent's threads hand each other: the feedback event and the counters' names."""

from dataclasses import dataclass
import math
from typing import Optional

from tamer_node.persistence import json_number

LEARNER_COUNTERS = (
    'feedback/count', 'feedback/duplicates', 'feedback/invalid', 'feedback/unmatched',
    'feedback/processed', 'samples/added', 'pairing/with_saliency', 'pairing/without_saliency',
    'train/updates', 'train/immediate_updates', 'train/minibatch_updates', 'train/l2_updates',
    'train/skipped_nonfinite', 'train/errors',
    'checkpoint/count', 'resume/replayed', 'resume/samples_without_images',
    'feedback/other_session', 'credit/refits',
)
"""Counted by the learner thread, read under its lock (and saved in each checkpoint)."""

AGENT_COUNTERS = (
    'act/count', 'act/fallback_observation', 'drop/observation', 'drop/saliency',
    'drop/observation_stamp', 'drop/saliency_stamp', 'session/restarts',
    'utterance/count', 'utterance/empty', 'utterance/too_long', 'feedback/logged',
    'disk/feedback_log_errors', 'act/paced', 'act/paced_ms', 'act/held',
    'act/switched', 'act/revisits', 'ask/asked',
    'log/feedback_lines', 'log/utterance_lines',
)
"""Counted by the acting path, the intake and the node (``TamerAgent.counters``). ``log/...``:
the lines this process wrote to feedback_log.jsonl (a resumed run's earlier lines not counted),
by which the launcher knows the learner logged all a trainer gave even if it heard no receipt."""


@dataclass
class FeedbackEvent:
    """One feedback as the learner receives it (and as feedback_log.jsonl records it)."""

    seq: int
    """1, 2, 3, ... in order of arrival over the whole run."""
    h: float
    stamp: Optional[int]
    """The step it is attributed to: its header stamp, or the arrival stamp if unstamped."""
    now: Optional[int]
    """The window's t: the newest observation stamp when it arrived, or the moment a 'pressed'
    feedback was given."""
    status: str
    """'ok', 'duplicate' (the plain copy of a stamped one), 'invalid', 'no_observation'."""
    credit: str
    """Credit mode in force when it arrived."""
    arrived: float = 0.0
    """time.monotonic() at arrival (the saliency pairing deadline starts here)."""
    session: int = 1
    """The run's session its stamps belong to (see persistence.py)."""


def entry_from_event(event: FeedbackEvent, source: str, wall_time: float) -> dict:
    """Return the feedback_log.jsonl line of ``event`` (``event_from_entry`` reads it back)."""
    return {'kind': 'feedback', 'seq': event.seq, 'wall_time': wall_time, 'source': source,
            'h': json_number(event.h), 'stamp_ns': event.stamp, 'now_ns': event.now,
            'session': event.session, 'status': event.status, 'credit': event.credit}


def event_from_entry(entry: dict) -> FeedbackEvent:
    """Rebuild a FeedbackEvent from its feedback_log.jsonl line (for replay on resume)."""
    h = entry.get('h')
    return FeedbackEvent(
        seq=int(entry['seq']), h=float(h) if h is not None else math.nan,
        stamp=entry.get('stamp_ns'), now=entry.get('now_ns'), status=entry.get('status', 'ok'),
        credit=entry.get('credit', 'step'), arrived=0.0, session=int(entry.get('session', 1)))

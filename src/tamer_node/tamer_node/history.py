"""
Recent steps by stamp: the images of each step and the action chosen for it.

Observation T, saliency T and the feedback on T arrive on different topics in any order; this
is where they meet. Bounded (oldest step evicted first) and thread-safe: the acting path writes,
the learner thread reads.
"""

import collections
import dataclasses
from dataclasses import dataclass
import threading
from typing import Callable, Dict, List, Optional

from tamer_node.credit import NS_PER_S, Span, spans_from_stamps
import torch

IMAGE_KINDS = ('observation', 'saliency')
DECISION_SLACK_NS = 1_000_000
"""Stamps are rounded to the nanosecond: 3 steps of 1/15 s are a 0.2 s decision."""


def holds(decision: Optional[int], stamp: int, period_s: float) -> bool:
    """Tell whether the decision made at stamp ``decision`` still holds at ``stamp``."""
    if decision is None or period_s <= 0.0 or stamp < decision:
        return False
    return stamp - decision < int(round(period_s * NS_PER_S)) - DECISION_SLACK_NS


@dataclass
class StepRecord:
    """What is known about one step."""

    stamp: int
    observation: Optional[torch.Tensor] = None
    """Preprocessed (105, 80) uint8 observation."""
    saliency: Optional[torch.Tensor] = None
    """Preprocessed (105, 80) uint8 saliency image, if one came."""
    action: Optional[int] = None
    """The action the agent answered this step with."""
    taken: Optional[int] = None
    """The action the world executed on this step when the agent's answer was not it
    (``action_taken``: a replayed session's action); learned from instead of ``action``."""
    decision: Optional[int] = None
    """The stamp of the step whose choice this step's action holds (``decision_period_s``): the
    step itself when it chose, else the first step of its decision."""
    observation_features: Optional[torch.Tensor] = None
    """(1120,) float32 frozen-encoder features of the observation, once computed."""
    saliency_features: Optional[torch.Tensor] = None
    """(1120,) float32 frozen-encoder features of the saliency image, once computed."""
    text: Optional[torch.Tensor] = None
    """The bag of words of the utterance in force when the agent acted (text conditioning)."""

    def image(self, kind: str) -> Optional[torch.Tensor]:
        return getattr(self, kind)

    def features(self, kind: str) -> Optional[torch.Tensor]:
        return getattr(self, f'{kind}_features')

    @property
    def learned_action(self) -> Optional[int]:
        """Return the action feedback on this step is about: the one taken, else the agent's."""
        return self.action if self.taken is None else self.taken


def other_kind(kind: str) -> str:
    """'observation' <-> 'saliency'."""
    return IMAGE_KINDS[1 - IMAGE_KINDS.index(kind)]


class StepHistory:
    """The newest ``capacity`` steps of one session of the run (stamps are unique in it)."""

    def __init__(self, capacity: int, session: int = 1):
        if capacity < 1:
            raise ValueError('capacity must be at least 1')
        self.capacity = capacity
        self.session = session
        self._records: 'collections.OrderedDict[int, StepRecord]' = collections.OrderedDict()
        self._newest: Dict[str, int] = {}
        self._lock = threading.Lock()

    def put_image(self, kind: str, stamp: int, image: torch.Tensor) -> StepRecord:
        """Store an image of a step; return a copy of the step's record."""
        if kind not in IMAGE_KINDS:
            raise ValueError(f'unknown image kind {kind!r}')
        with self._lock:
            record = self._record(stamp)
            setattr(record, kind, image)
            setattr(record, f'{kind}_features', None)  # (a re-sent image: computed again)
            self._newest[kind] = max(stamp, self._newest.get(kind, stamp))
            return dataclasses.replace(record)

    def put_features(self, kind: str, stamp: int, features: torch.Tensor) -> None:
        """Cache the frozen encoder's features of a step's image (if the step is still held)."""
        if kind not in IMAGE_KINDS:
            raise ValueError(f'unknown image kind {kind!r}')
        with self._lock:
            record = self._records.get(stamp)
            if record is not None and record.image(kind) is not None:
                setattr(record, f'{kind}_features', features)

    def put_text(self, stamp: int, text: torch.Tensor) -> None:
        """Keep the words the agent read when it acted on step ``stamp`` (if still held)."""
        with self._lock:
            record = self._records.get(stamp)
            if record is not None:
                record.text = text

    def set_action(self, stamp: int, action: int, decision: Optional[int] = None) -> None:
        with self._lock:
            record = self._record(stamp)
            record.action = int(action)
            record.decision = decision

    def mark_decisions(self, holds: Callable[[Optional[int], int], bool]) -> None:
        """Group the acted steps, in stamp order, into decisions as the actor did (a resume)."""
        with self._lock:
            decision = None
            for stamp in sorted(s for s, r in self._records.items() if r.action is not None):
                if not holds(decision, stamp):
                    decision = stamp
                self._records[stamp].decision = decision

    def set_taken(self, stamp: int, action: int) -> Optional[int]:
        """Record the action the world executed on ``stamp``; return the agent's answer."""
        with self._lock:
            record = self._record(stamp)
            record.taken = int(action)
            return record.action

    def get(self, stamp: int) -> Optional[StepRecord]:
        """Return a copy of the record (images are shared, never modified), or None."""
        with self._lock:
            record = self._records.get(stamp)
            return None if record is None else dataclasses.replace(record)

    def settled(self, stamp: int, kind: str) -> bool:
        """
        Tell whether step ``stamp`` has its ``kind`` image or never will get it.

        Each image stream comes from one publisher in stamp order, so once an image of a later
        step has arrived, this step's will not come any more.
        """
        with self._lock:
            record = self._records.get(stamp)
            if record is not None and record.image(kind) is not None:
                return True
            return self._newest.get(kind, stamp) > stamp

    def acted_spans(self, now: int) -> List[Span]:
        """Return the time spans of the steps that were answered with an action."""
        with self._lock:
            stamps = [s for s, r in self._records.items() if r.learned_action is not None]
        return spans_from_stamps(stamps, now)

    def oldest(self) -> Optional[int]:
        """Return the oldest stamp held, or None."""
        with self._lock:
            return min(self._records, default=None)

    def records(self) -> List[StepRecord]:
        """Return copies of all records, oldest first."""
        with self._lock:
            return [dataclasses.replace(r) for r in self._records.values()]

    def start_session(self, session: int) -> None:
        """Forget every step: the stamps start over (a new env) in ``session``."""
        with self._lock:
            self._records.clear()
            self._newest.clear()
            self.session = session

    def __len__(self) -> int:
        with self._lock:
            return len(self._records)

    def _record(self, stamp: int) -> StepRecord:
        record = self._records.get(stamp)
        if record is None:
            record = self._records[stamp] = StepRecord(stamp)
            while len(self._records) > self.capacity:
                self._records.popitem(last=False)
        return record

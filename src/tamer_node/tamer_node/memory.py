"""
Verdict memory: what the trainer said about each action of a state seen before, exactly.

H generalises, and so it forgets: after a -1 on an action, H of that state moves only a little,
and a greedy agent takes the same action again and again where nothing changes (turning on the
spot, walking into a wall). The memory keeps, for each exact state the learner trained on (its
stored item: the image's features, or the image, and the words), every verdict's credit weight
and value per action. Acting blends them into H as pseudo-counts:

    H'(s, a) = (H(s, a) + m * w * v) / (1 + m * w)

with ``w`` the credit mass on (s, a), ``v`` its credit-weighted mean verdict and ``m`` the
``verdict_memory`` weight. So an action judged bad in this very state drops below the untried
ones, and the agent tries those instead of the least-bad one it knows; one judged good is
repeated. A late feedback spread over a window weighs on each step only its share of the
credit. It is rebuilt from the buffer on resume (the buffer is what it summarises).
"""

import collections
import hashlib
import threading
from typing import Iterable, Optional

import torch


def state_key(state: torch.Tensor) -> bytes:
    """Return the key of one stored item: a digest of its bytes."""
    array = state.detach().contiguous().cpu().numpy()
    return hashlib.blake2b(array.tobytes(), digest_size=16).digest()


class VerdictMemory:
    """Per exact state: credit mass and weighted verdict sum of each action (thread-safe)."""

    def __init__(self, weight: float, num_actions: int, capacity: int):
        self.weight = float(weight)
        self.num_actions = int(num_actions)
        self.capacity = int(capacity)
        self._lock = threading.Lock()
        self._states: 'collections.OrderedDict[bytes, torch.Tensor]' = (
            collections.OrderedDict())
        """key -> (2, actions): credit mass, then credit-weighted sum of verdicts."""

    def __len__(self) -> int:
        with self._lock:
            return len(self._states)

    def add(self, samples: Iterable) -> None:
        """Remember the verdicts of ``samples`` (buffer.Sample: state, action, h, weight)."""
        with self._lock:
            for sample in samples:
                key = state_key(sample.state)
                sums = self._states.pop(key, None)
                if sums is None:
                    sums = torch.zeros(2, self.num_actions)
                sums[0, sample.action] += sample.weight
                sums[1, sample.action] += sample.weight * sample.h
                self._states[key] = sums  # the newest last; the oldest forgotten first
            while len(self._states) > self.capacity:
                self._states.popitem(last=False)

    def blend(self, key: bytes, values: torch.Tensor) -> torch.Tensor:
        """Return H(s, .) blended with the verdicts remembered for the state of ``key``."""
        with self._lock:
            sums = self._states.get(key)
            if sums is None:
                return values
            return (values + self.weight * sums[1]) / (1.0 + self.weight * sums[0])

    def lookup(self, state: torch.Tensor) -> Optional[torch.Tensor]:
        """Return a copy of the (2, actions) sums remembered for ``state``, or None."""
        with self._lock:
            sums = self._states.get(state_key(state))
            return None if sums is None else sums.clone()

"""
Revisits: try what was not tried here lately, instead of repeating the least-bad action.

A greedy agent whose H is flat or wrong in a state repeats one action there for as long as no
verdict corrects it: with a trainer who judges a third of the steps, late, that is long enough
to spend a whole episode turning on the spot. ``Revisits`` counts, over the last ``steps``
acted steps, how often each action was taken in each exact state (the state acted on: the
frame's features and the words, ``memory.state_key``), and acting lowers each action's H
(clipped to the feedback's range) by ``penalty`` per time it was taken there. So an agent back
in a state it just left takes another action, and a loop opens. States that never come back
(Room 1's rolling skull makes most frames new) are unaffected.
"""

import collections
from typing import Deque, Tuple

import torch


class Revisits:
    """Per exact state, how often each action was taken in the last ``steps`` acted steps."""

    def __init__(self, penalty: float, steps: int, num_actions: int):
        self.penalty = float(penalty)
        self.num_actions = int(num_actions)
        self._recent: Deque[Tuple[bytes, int]] = collections.deque(maxlen=int(steps))
        self._counts: 'collections.Counter[Tuple[bytes, int]]' = collections.Counter()

    def penalties(self, key: bytes) -> torch.Tensor:
        """Return the (actions,) amounts to lower H by in the state of ``key`` (``state_key``)."""
        taken = torch.tensor([self._counts.get((key, action), 0)
                              for action in range(self.num_actions)], dtype=torch.float32)
        return self.penalty * taken

    def took(self, key: bytes, action: int) -> None:
        """Count ``action`` taken in the state of ``key``; forget the oldest beyond the window."""
        if len(self._recent) == self._recent.maxlen:
            old = self._recent[0]
            self._counts[old] -= 1
            if self._counts[old] <= 0:
                del self._counts[old]
        self._recent.append((key, action))
        self._counts[(key, action)] += 1

    def clear(self) -> None:
        self._recent.clear()
        self._counts.clear()

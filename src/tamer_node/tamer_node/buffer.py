"""The feedback replay buffer: bounded, lock-protected, sampled into a NamedTuple of tensors."""

import threading
from typing import Callable, Iterable, List, NamedTuple, Optional, Tuple

import numpy as np
from tamer_node.model import INPUT_SHAPE
from tamer_node.posterior import feedback_likelihood, posterior_weights
import torch


class Sample(NamedTuple):
    """
    One labelled (state, action) pair, as the learner makes it from a feedback.

    ``state`` and ``companion`` are (105, 80) uint8 images, or, with a frozen encoder, their
    (1120,) float32 features (computed once per image; the head trains on them directly).
    """

    state: torch.Tensor
    companion: Optional[torch.Tensor]
    """The step's other image for the L2 term (its saliency image), or None."""
    action: int
    h: float
    weight: float
    """Credit weight (1 for ``step`` credit, the window's probability mass otherwise)."""
    stamp: int
    """The step's stamp, ns."""
    seq: int
    """Sequence number of the feedback that made it (its line in feedback_log.jsonl)."""
    session: int = 1
    """The run's session the step belongs to (stamps restart with each env): with ``stamp``,
    the step's identity in the run."""
    prior: Optional[float] = None
    """The credit window's weight before credit by prediction (None: ``weight`` is it)."""


class Batch(NamedTuple):
    """A minibatch: B samples as tensors."""

    states: torch.Tensor
    """(B, 105, 80) uint8."""
    companions: torch.Tensor
    """(B, 105, 80) uint8; zeros where ``has_companion`` is false."""
    has_companion: torch.Tensor
    """(B,) bool."""
    actions: torch.Tensor
    """(B,) int64."""
    h: torch.Tensor
    """(B,) float32 feedback values."""
    weights: torch.Tensor
    """(B,) float32 credit weights."""
    groups: Optional[torch.Tensor] = None
    """(B,) int64: which feedback of the batch each row came from, numbered 0..G-1 (for the
    ``mixture`` credit loss); None: rows are independent."""


def group_ids(seqs) -> torch.Tensor:
    """Return each row's feedback as 0..G-1 (the distinct sequence numbers, in order)."""
    return torch.from_numpy(np.unique(np.asarray(seqs), return_inverse=True)[1].astype(np.int64))


def collate(samples: List[Sample]) -> Batch:
    """Stack samples into a Batch (``groups``: by the feedback each came from)."""
    if not samples:
        raise ValueError('cannot collate an empty list of samples')
    blank = torch.zeros_like(samples[0].state)
    return Batch(
        groups=group_ids([s.seq for s in samples]),
        states=torch.stack([s.state for s in samples]),
        companions=torch.stack([blank if s.companion is None else s.companion
                                for s in samples]),
        has_companion=torch.tensor([s.companion is not None for s in samples]),
        actions=torch.tensor([s.action for s in samples], dtype=torch.int64),
        h=torch.tensor([s.h for s in samples], dtype=torch.float32),
        weights=torch.tensor([s.weight for s in samples], dtype=torch.float32),
    )


def concatenate(first: Batch, second: Batch) -> Batch:
    """Return the rows of two batches as one (``groups`` dropped: rows independent)."""
    return Batch(*(torch.cat([a, b]) for a, b in zip(first[:-1], second[:-1])), groups=None)


KEPT_CAPACITY = 5000
"""Step-credited samples kept in a ring of their own (``kept_per_batch``): more answers than a
person gives in a session (the teacher's 0.25 questions a step: about 1,600 in 10,000 steps)."""

# Per-sample columns of the ring (besides the two images).
_COLUMNS = {'has_companion': np.bool_, 'actions': np.int64, 'h': np.float32,
            'weights': np.float32, 'stamps': np.int64, 'seqs': np.int64,
            'sessions': np.int64, 'priors': np.float32}


class FeedbackBuffer:
    """
    The newest ``capacity`` samples, in preallocated arrays (as SB3's buffers); thread-safe.

    Each sample's images (or features) are copied in, so the memory is fixed (2 x 8.4 kB per
    sample for images, 2 x 4.5 kB for features) and a long run does not fragment the heap with
    small blocks. Every page of the ring is taken at construction (written once), so the
    process is its full size from the start: memory stays flat however slowly the ring fills
    (a million-step soak), and no write into the ring waits on a page fault.
    """

    def __init__(self, capacity: int, item_shape: Tuple[int, ...] = INPUT_SHAPE,
                 dtype=np.uint8):
        """``item_shape``/``dtype``: images by default; (1120,) float32 for cached features."""
        if capacity < 1:
            raise ValueError('capacity must be at least 1')
        self.capacity = capacity
        self.item_shape = tuple(item_shape)
        self.states = np.empty((capacity,) + self.item_shape, dtype)
        self.companions = np.empty((capacity,) + self.item_shape, dtype)
        self.columns = {name: np.empty(capacity, dtype) for name, dtype in _COLUMNS.items()}
        for array in (self.states, self.companions, *self.columns.values()):
            array.fill(0)  # takes every page now (np.zeros would take them as the ring fills)
        self._size = 0
        self._next = 0  # ring position of the next write
        self._lock = threading.Lock()
        self.added = 0

    def add(self, sample: Sample) -> None:
        self.extend([sample])

    def extend(self, samples: Iterable[Sample]) -> None:
        with self._lock:
            for sample in samples:
                i = self._next
                self.states[i] = sample.state.numpy()
                has_companion = sample.companion is not None
                if has_companion:
                    self.companions[i] = sample.companion.numpy()
                for name, value in (('has_companion', has_companion),
                                    ('actions', sample.action), ('h', sample.h),
                                    ('weights', sample.weight), ('stamps', sample.stamp),
                                    ('seqs', sample.seq), ('sessions', sample.session),
                                    ('priors', sample.weight if sample.prior is None
                                     else sample.prior)):
                    self.columns[name][i] = value
                self._next = (i + 1) % self.capacity
                self._size = min(self._size + 1, self.capacity)
                self.added += 1

    def sample(self, batch_size: int, rng: np.random.Generator) -> Batch:
        """``min(batch_size, len)`` distinct samples, uniformly at random."""
        with self._lock:
            if not self._size:
                raise ValueError('cannot sample from an empty buffer')
            rows = rng.choice(self._size, min(batch_size, self._size), replace=False)
            return self._batch(rows)

    def sample_feedback(self, count: int, rng: np.random.Generator) -> Batch:
        """
        Every sample of ``min(count, feedbacks held)`` distinct feedbacks, drawn uniformly.

        A feedback's samples are the steps its credit spread over; the ``mixture`` credit loss
        needs them together. A feedback whose oldest samples the ring already overwrote keeps
        the rest.
        """
        with self._lock:
            if not self._size:
                raise ValueError('cannot sample from an empty buffer')
            seqs = self.columns['seqs'][:self._size]
            distinct, inverse = np.unique(seqs, return_inverse=True)
            chosen = rng.choice(len(distinct), min(count, len(distinct)), replace=False)
            rows = np.flatnonzero(np.isin(inverse, chosen))
            return self._batch(rows, groups=True)

    def _batch(self, rows: np.ndarray, groups: bool = False) -> Batch:
        columns = {name: torch.from_numpy(values[rows]) for name, values in self.columns.items()}
        return Batch(states=torch.from_numpy(self.states[rows]),
                     companions=torch.from_numpy(self.companions[rows]),
                     has_companion=columns['has_companion'], actions=columns['actions'],
                     h=columns['h'], weights=columns['weights'],
                     groups=group_ids(columns['seqs'].numpy()) if groups else None)

    def _order(self) -> np.ndarray:
        """Return the row indices, oldest sample first."""
        if self._size < self.capacity:
            return np.arange(self._size)
        return (np.arange(self.capacity) + self._next) % self.capacity

    def samples(self) -> List[Sample]:
        """Return copies of all samples, oldest first."""
        with self._lock:
            out = []
            for i in self._order():
                has = bool(self.columns['has_companion'][i])
                out.append(Sample(
                    torch.from_numpy(self.states[i].copy()),
                    torch.from_numpy(self.companions[i].copy()) if has else None,
                    int(self.columns['actions'][i]), float(self.columns['h'][i]),
                    float(self.columns['weights'][i]), int(self.columns['stamps'][i]),
                    int(self.columns['seqs'][i]), int(self.columns['sessions'][i]),
                    float(self.columns['priors'][i])))
            return out

    def __len__(self) -> int:
        with self._lock:
            return self._size

    def refit_weights(self, predict: Callable[[torch.Tensor, torch.Tensor], np.ndarray],
                      noise: float, chunk: int = 2048) -> int:
        """
        Re-weigh every sample by credit by prediction (posterior.py) with the current H.

        ``predict(states, actions)`` returns H(s, a) of a chunk of rows. Call it from the one
        thread that adds samples (the learner's): the rows cannot change meanwhile, so H is
        computed without the lock and only the new weights are written under it.
        """
        size = len(self)
        if not size:
            return 0
        predicted = np.concatenate([
            predict(torch.from_numpy(self.states[i:min(i + chunk, size)]),
                    torch.from_numpy(self.columns['actions'][i:min(i + chunk, size)]))
            for i in range(0, size, chunk)])
        columns = self.columns
        likelihood = feedback_likelihood(columns['h'][:size], predicted, noise)
        weights = posterior_weights(columns['priors'][:size], likelihood, columns['seqs'][:size])
        with self._lock:
            columns['weights'][:size] = weights
        return size

    def companion_fraction(self) -> float:
        """Fraction of the samples held that have a companion (saliency) image; 0 if empty."""
        with self._lock:
            if not self._size:
                return 0.0
            return float(self.columns['has_companion'][:self._size].mean())

    def state_dict(self, images: bool = True) -> dict:
        """
        Return a consistent copy, oldest first, for ``torch.load(weights_only=True)``.

        ``images=False`` leaves the images out (the caller finds them again by session and
        stamp): a few hundred kB instead of up to 170 MB.
        """
        with self._lock:
            order = self._order()
            state = {
                'capacity': self.capacity,
                'added': self.added,
                'columns': {name: torch.from_numpy(values[order])
                            for name, values in self.columns.items()},
            }
            if images:
                has = self.columns['has_companion'][order]
                state['states'] = torch.from_numpy(self.states[order])
                state['companions'] = torch.from_numpy(self.companions[order[has]])
            return state

    def load_state_dict(self, state: dict) -> None:
        """Load a ``state_dict(images=True)``; ``companions`` holds the rows that have one."""
        states = state['states'].numpy()[-self.capacity:]
        columns = {name: values.numpy()[-self.capacity:]
                   for name, values in state['columns'].items()}
        columns.setdefault('priors', columns['weights'])  # a checkpoint from before priors
        has = columns['has_companion']
        companions = np.zeros_like(states)
        companions[has] = state['companions'].numpy()[-int(has.sum()):] if has.any() else 0
        with self._lock:
            size = len(states)
            self.states[:size] = states
            self.companions[:size] = companions
            for name in _COLUMNS:
                self.columns[name][:size] = columns[name]
            self._size = size
            self._next = size % self.capacity
            self.added = int(state['added'])

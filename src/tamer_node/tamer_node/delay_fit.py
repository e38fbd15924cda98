"""
The trainer's delay, fitted online (``credit_delay_fit``): the credit window's prior learned.

Deep TAMER's window takes every delay in [min, max] as equally likely. A person's is not (Knox
and Stone measured a gamma, mean 0.56 s), and neither is a graph's: a verdict is stamped with
the newest observation the learner saw, so on 1 s grid steps the delay it shows is a whole
number of steps. A window wide enough for any trainer therefore puts most of each verdict's
credit on steps it was not about.

Here the window's prior is a histogram over the delay (bins of ``bin_s`` on [min, max]),
fitted by EM as feedback comes: credit by prediction (posterior.py) says how likely each
candidate step was the one judged (the E-step); each step's share is added to the bins of its
delay (the M-step, online). The histogram starts at ``prior_count`` pseudo-verdicts spread
evenly, so at first it is the plain window, and a few verdicts cannot sharpen it much. Steps
are candidates at their delay as ``credit_anchor`` measures it: the moment their result was
shown ('effect', one delay each), or any moment of their span ('span', an interval).

Pure numpy; the learner thread owns it (learner_loop.py) and checkpoints it.
"""

import math
from typing import Dict, Sequence, Tuple

import numpy as np
from tamer_node.credit import NS_PER_S, Span

Interval = Tuple[int, int]
"""(lo, hi) delays of one candidate step, ns; lo == hi: one delay (the 'effect' anchor)."""


class DelayFit:
    """A histogram of the trainer's delay on [min_s, max_s], fitted by online EM."""

    def __init__(self, min_s: float, max_s: float, bin_s: float = 0.1,
                 prior_count: float = 20.0):
        if not 0.0 <= min_s < max_s:
            raise ValueError(f'the delay fit needs 0 <= min_s < max_s, got {min_s}, {max_s}')
        if bin_s <= 0.0 or prior_count <= 0.0:
            raise ValueError('the delay fit needs bin_s > 0 and prior_count > 0')
        bins = max(1, math.ceil((max_s - min_s) / bin_s - 1e-9))
        self.edges = np.linspace(min_s * NS_PER_S, max_s * NS_PER_S, bins + 1)
        self.counts = np.full(bins, prior_count / bins)
        self.observed = 0.0
        """Verdicts' worth of responsibility added so far (the prior not counted)."""

    @property
    def probabilities(self) -> np.ndarray:
        """Each bin's probability."""
        return self.counts / self.counts.sum()

    def mass(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Return the fitted probability of a delay in each [lo, hi] (ns); 0 outside the fit."""
        cdf = np.concatenate([[0.0], np.cumsum(self.probabilities)])
        return np.interp(hi, self.edges, cdf) - np.interp(lo, self.edges, cdf)

    def density(self, delay: np.ndarray) -> np.ndarray:
        """Return the fitted density at each delay (per ns); 0 outside [min, max]."""
        delay = np.asarray(delay, np.float64)
        index = np.clip(np.searchsorted(self.edges, delay, side='right') - 1, 0,
                        len(self.counts) - 1)
        inside = (delay >= self.edges[0]) & (delay <= self.edges[-1])
        widths = np.diff(self.edges)
        return np.where(inside, self.probabilities[index] / widths[index], 0.0)

    def observe(self, intervals: Sequence[Interval], responsibilities: Sequence[float]) -> None:
        """Add each candidate's responsibility to the bins of its delay (the online M-step)."""
        probabilities, widths = self.probabilities, np.diff(self.edges)
        for (lo, hi), share in zip(intervals, responsibilities):
            if share <= 0.0:
                continue
            if hi <= lo:  # one delay: its bin
                if self.edges[0] <= lo <= self.edges[-1]:
                    index = min(np.searchsorted(self.edges, lo, side='right') - 1,
                                len(self.counts) - 1)
                    self.counts[index] += share
                    self.observed += share
                continue
            overlap = np.clip(np.minimum(hi, self.edges[1:]) - np.maximum(lo, self.edges[:-1]),
                              0.0, None)
            spread = probabilities * overlap / widths  # the density on the interval
            if spread.sum() > 0.0:
                self.counts += share * spread / spread.sum()
                self.observed += share

    def moments_s(self) -> Tuple[float, float]:
        """Return the fitted delay's mean and standard deviation, in seconds."""
        centres = 0.5 * (self.edges[1:] + self.edges[:-1]) / NS_PER_S
        p = self.probabilities
        mean = float(p @ centres)
        return mean, float(np.sqrt(max(p @ (centres - mean) ** 2, 0.0)))

    def state(self) -> dict:
        """Plain lists and floats (a checkpoint is read with torch.load(weights_only=True))."""
        return {'edges': self.edges.tolist(), 'counts': self.counts.tolist(),
                'observed': float(self.observed)}

    def load(self, state: dict) -> None:
        """Take a saved fit back; one of other bins (another window) is refused."""
        edges = np.asarray(state['edges'], np.float64)
        if edges.shape != self.edges.shape or not np.allclose(edges, self.edges):
            raise ValueError('the saved delay fit has other bins (another credit window)')
        self.counts = np.asarray(state['counts'], np.float64).copy()
        self.observed = float(state['observed'])


def candidate_intervals(spans: Sequence[Span], now: int, anchor: str) -> Dict[int, Interval]:
    """{stamp: its delay interval} of the acted steps before ``now`` (``credit_anchor``)."""
    if anchor == 'effect':  # the newest step, on screen, has shown no result yet
        return {stamp: (now - t_end, now - t_end) for stamp, _, t_end in spans if t_end < now}
    return {stamp: (now - t_end, now - t_start) for stamp, t_start, t_end in spans
            if t_end > t_start}


def fitted_credit(intervals: Dict[int, Interval], fit: DelayFit) -> Dict[int, float]:
    """
    {stamp: weight} under the fitted delay; zero weights left out.

    A span's weight is the fit's probability of its interval (as the window's, which it is
    while the fit is flat); one-delay candidates share 1 in proportion to the density at theirs.
    """
    if not intervals:
        return {}
    stamps = list(intervals)
    lo = np.array([intervals[s][0] for s in stamps], np.float64)
    hi = np.array([intervals[s][1] for s in stamps], np.float64)
    points = hi <= lo
    weights = np.where(points, fit.density(lo), fit.mass(lo, hi))
    if points.any():
        total = weights[points].sum()
        weights[points] = weights[points] / total if total > 0 else 0.0
    return {stamp: float(w) for stamp, w in zip(stamps, weights) if w > 0.0}

"""
Statistics for small samples, the distributions and tests from scipy.stats.

Welch's unpaired t-test, t-based confidence intervals of a mean, Wilson score intervals of a
proportion, Cohen's d / Hedges' g and Holm's adjustment, as plain floats and dataclasses. What
an analysis stores has one shape: ``estimate`` (a mean) and ``proportion`` (a rate).
"""

from dataclasses import asdict, dataclass
import math
import statistics
from typing import Iterable, List, Mapping, Optional, Sequence, Tuple
import warnings

from scipy import stats as scipy_stats


def t_quantile(q: float, df: float) -> float:
    """Return t with P(T <= t) = q for Student's t with ``df`` degrees of freedom."""
    if not 0.0 < q < 1.0:
        raise ValueError(f'q must be in (0, 1), got {q}')
    return float(scipy_stats.t.ppf(q, df))


def mean(values: Sequence[float]) -> float:
    return statistics.fmean(values)


def mean_of(values: Iterable[Optional[float]]) -> Optional[float]:
    """Return sum / count of the values that are not None (None if there are none)."""
    found = [value for value in values if value is not None]
    return sum(found) / len(found) if found else None


def sample_sd(values: Sequence[float]) -> float:
    """Return the standard deviation with Bessel's correction (n - 1); 0 for one value."""
    return statistics.stdev(values) if len(values) >= 2 else 0.0


@dataclass(frozen=True)
class Estimate:
    """A mean with its 95 % t interval (low/high None for fewer than two values)."""

    n: int
    mean: Optional[float]
    sd: Optional[float]
    low: Optional[float]
    high: Optional[float]


def mean_ci(values: Sequence[float], level: float = 0.95) -> Estimate:
    """Return the mean and its t-based confidence interval (mean +- t * sd / sqrt(n))."""
    values = [float(v) for v in values]
    n = len(values)
    if n == 0:
        return Estimate(0, None, None, None, None)
    centre = mean(values)
    if n == 1:
        return Estimate(1, centre, None, None, None)
    sd = sample_sd(values)
    half = t_quantile(0.5 + level / 2.0, n - 1) * sd / math.sqrt(n)
    return Estimate(n, centre, sd, centre - half, centre + half)


@dataclass(frozen=True)
class MedianInterval:
    n: int
    median: Optional[float]
    low: Optional[float]
    high: Optional[float]
    """The bounds are order statistics (None when n is too small for the level)."""


def median_ci(values: Sequence[float], level: float = 0.95) -> MedianInterval:
    """
    Return the median and its distribution-free confidence interval (sign test's order stats).

    For measurements with outliers a t interval of the mean does not suit: one wild value widens
    it for all (for n = 10, the 95 % interval is the 2nd to the 9th smallest value).
    """
    values = sorted(float(v) for v in values)
    if not values:
        return MedianInterval(0, None, None, None)
    interval = scipy_stats.quantile_test(values, q=0.0).confidence_interval(level)  # any q
    low, high = (float(b) if math.isfinite(b) else None for b in (interval.low, interval.high))
    return MedianInterval(len(values), statistics.median(values), low, high)


def wilson_interval(successes: int, n: int, level: float = 0.95) -> Tuple[float, float]:
    """Return the Wilson score interval of a proportion (95 % by default); (0, 1) for n = 0."""
    if n == 0:
        return 0.0, 1.0
    if not 0 <= successes <= n:
        raise ValueError(f'successes must be in [0, {n}], got {successes}')
    interval = scipy_stats.binomtest(successes, n).proportion_ci(level, method='wilson')
    return float(interval.low), float(interval.high)


@dataclass(frozen=True)
class WelchResult:
    """Welch's unpaired t-test of a against b (difference = mean(a) - mean(b))."""

    n_a: int
    n_b: int
    mean_a: float
    mean_b: float
    difference: float
    t: Optional[float]
    df: Optional[float]
    p: Optional[float]
    hedges_g: Optional[float]
    cohens_d: Optional[float]
    note: str = ''
    """Why t or p is missing (too few values, no variance)."""


def cohens_d(a: Sequence[float], b: Sequence[float]) -> Optional[float]:
    """Return (mean(a) - mean(b)) / pooled sd; None when undefined (no variance, n < 2)."""
    n_a, n_b = len(a), len(b)
    if n_a < 2 or n_b < 2:
        return None
    pooled = math.sqrt(((n_a - 1) * sample_sd(a) ** 2 + (n_b - 1) * sample_sd(b) ** 2)
                       / (n_a + n_b - 2))
    if pooled == 0:
        return None
    return (mean(a) - mean(b)) / pooled


def hedges_g(a: Sequence[float], b: Sequence[float]) -> Optional[float]:
    """Return Cohen's d with the small-sample correction 1 - 3 / (4 (n_a + n_b) - 9)."""
    d = cohens_d(a, b)
    if d is None:
        return None
    return d * (1.0 - 3.0 / (4.0 * (len(a) + len(b)) - 9.0))


def welch_t_test(a: Sequence[float], b: Sequence[float]) -> WelchResult:
    """
    Return Welch's two-sided unpaired t-test of a against b.

    scipy's ``ttest_ind(equal_var=False)``: degrees of freedom by the Welch-Satterthwaite
    equation. When both samples have no variance the test is undefined: p is None (and
    ``note`` says so), whether or not the means differ.
    """
    a = [float(v) for v in a]
    b = [float(v) for v in b]
    n_a, n_b = len(a), len(b)
    if n_a < 2 or n_b < 2:
        centre_a = mean(a) if a else float('nan')
        centre_b = mean(b) if b else float('nan')
        return WelchResult(n_a, n_b, centre_a, centre_b, centre_a - centre_b, None, None, None,
                           None, None, 'fewer than two values')
    mean_a, mean_b = mean(a), mean(b)
    difference = mean_a - mean_b
    g, d = hedges_g(a, b), cohens_d(a, b)
    constant = sample_sd(a) == 0, sample_sd(b) == 0
    if all(constant):
        note = 'identical constant samples' if difference == 0 else 'constant samples'
        return WelchResult(n_a, n_b, mean_a, mean_b, difference, None, None, None, g, d, note)
    with warnings.catch_warnings():
        if any(constant):  # exact (all trials censored, say), yet scipy warns of cancellation
            warnings.simplefilter('ignore', RuntimeWarning)
        test = scipy_stats.ttest_ind(a, b, equal_var=False)
    return WelchResult(n_a, n_b, mean_a, mean_b, difference, float(test.statistic),
                       float(test.df), float(test.pvalue), g, d)


def detectable_effect(n_per_group: int, power: float = 0.8, alpha: float = 0.05) -> float:
    """
    Return the |d| a two-sided two-sample t-test detects with ``power`` (n per group).

    Uses (t_{1-alpha/2, df} + t_{power, df}) * sqrt(2 / n), df = 2n - 2, which is within about
    1 % of the exact noncentral-t value for n >= 5 (n = 10: 1.32).
    """
    if n_per_group < 2:
        return math.inf
    df = 2 * n_per_group - 2
    return ((t_quantile(1 - alpha / 2, df) + t_quantile(power, df))
            * math.sqrt(2.0 / n_per_group))


def holm_adjust(p_values: Sequence[Optional[float]]) -> List[Optional[float]]:
    """Return Holm-Bonferroni adjusted p-values (None entries stay None and are not counted)."""
    indexed = sorted((p, i) for i, p in enumerate(p_values) if p is not None)
    m = len(indexed)
    adjusted: List[Optional[float]] = [None] * len(p_values)
    running = 0.0
    for rank, (p, i) in enumerate(indexed):
        running = max(running, min(1.0, (m - rank) * p))
        adjusted[i] = running
    return adjusted


def welch_rows(pairs: Iterable[Tuple[Mapping, Sequence[float], Sequence[float]]]) -> List[dict]:
    """Return ``{**key, Welch's test of a against b}`` for each (key, a, b), Holm-adjusted."""
    rows = [{**key, **asdict(welch_t_test(a, b))} for key, a, b in pairs]
    for row, adjusted in zip(rows, holm_adjust([row['p'] for row in rows])):
        row['p_holm'] = adjusted
    return rows


def estimate(values: Sequence[float]) -> dict:
    """Return a mean and its 95 % t interval as stored: {n, mean, sd, low, high} (one shape)."""
    return asdict(mean_ci(values))


def proportion(successes: int, n: int) -> dict:
    """Return a proportion and its Wilson 95 % interval as stored: {k, n, rate, low, high}."""
    low, high = wilson_interval(successes, n)
    return {'k': successes, 'n': n, 'rate': successes / n if n else None, 'low': low,
            'high': high}


def median(values: Sequence[float]) -> Optional[float]:
    """Return the middle value (the mean of the middle two for an even count); None if empty."""
    return float(statistics.median(values)) if values else None


def reach_curve(firsts: Sequence[Optional[int]], steps: Iterable[int]) -> dict:
    """Fraction of trials whose first step (None: never) is by each step, with Wilson bands."""
    n = len(firsts)
    curve = {'steps': list(steps), 'fraction': [], 'low': [], 'high': []}
    for step in curve['steps']:
        k = sum(1 for first in firsts if first is not None and first <= step)
        low, high = wilson_interval(k, n)
        curve['fraction'].append(k / n if n else None)
        curve['low'].append(low)
        curve['high'].append(high)
    return curve

"""
Statistics for small samples, in plain Python (no scipy).

Student's t distribution through the regularized incomplete beta function (a continued fraction
evaluated with the modified Lentz method), Welch's unpaired t-test, t-based confidence intervals
of a mean, Wilson score intervals of a proportion, Cohen's d / Hedges' g and Holm's adjustment.
"""

from dataclasses import dataclass
import functools
import math
from typing import List, Optional, Sequence, Tuple

Z_975 = 1.959963984540054
"""The 97.5 % quantile of the standard normal distribution (two-sided 95 %)."""

_TINY = 1e-300
_EPS = 1e-15


def _beta_fraction(a: float, b: float, x: float) -> float:
    """Continued fraction of I_x(a, b): 1 / (1 + d1 / (1 + d2 / (1 + ...)))."""
    value = _TINY
    c, d = value, 0.0
    for j in range(1, 2000):
        if j == 1:
            numerator = 1.0
        else:
            k = j - 1  # d_k
            m = k // 2
            if k % 2:
                numerator = -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))
            else:
                numerator = m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m))
        d = 1.0 + numerator * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + numerator / c
        c = c if abs(c) > _TINY else _TINY
        delta = c * d
        value *= delta
        if abs(delta - 1.0) < _EPS:
            break
    return value


def regularized_beta(x: float, a: float, b: float) -> float:
    """Return I_x(a, b), the regularized incomplete beta function, for 0 <= x <= 1."""
    if not 0.0 <= x <= 1.0:
        raise ValueError(f'x must be in [0, 1], got {x}')
    if x in (0.0, 1.0):
        return x
    log_front = (a * math.log(x) + b * math.log1p(-x)
                 - (math.lgamma(a) + math.lgamma(b) - math.lgamma(a + b)))
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(log_front) * _beta_fraction(a, b, x) / a
    return 1.0 - math.exp(log_front) * _beta_fraction(b, a, 1.0 - x) / b


def t_two_sided_p(t: float, df: float) -> float:
    """Return P(|T| >= |t|) for Student's t with ``df`` (> 0, not necessarily whole) degrees."""
    if df <= 0:
        raise ValueError(f'degrees of freedom must be positive, got {df}')
    if math.isinf(t):
        return 0.0
    return regularized_beta(df / (df + t * t), df / 2.0, 0.5)


def t_cdf(t: float, df: float) -> float:
    """Return P(T <= t) for Student's t with ``df`` degrees of freedom."""
    tail = t_two_sided_p(t, df) / 2.0
    return 1.0 - tail if t > 0 else tail


@functools.lru_cache(maxsize=256)
def t_quantile(q: float, df: float) -> float:
    """Return t with P(T <= t) = q (bisection on ``t_cdf``; |error| < 1e-10)."""
    if not 0.0 < q < 1.0:
        raise ValueError(f'q must be in (0, 1), got {q}')
    if q < 0.5:
        return -t_quantile(1.0 - q, df)
    low, high = 0.0, 1.0
    while t_cdf(high, df) < q:
        low, high = high, high * 2.0
    while high - low > 1e-10 * max(1.0, high):
        middle = (low + high) / 2.0
        if t_cdf(middle, df) < q:
            low = middle
        else:
            high = middle
    return (low + high) / 2.0


def mean(values: Sequence[float]) -> float:
    return math.fsum(values) / len(values)


def sample_sd(values: Sequence[float]) -> float:
    """Return the standard deviation with Bessel's correction (n - 1); 0 for one value."""
    if len(values) < 2:
        return 0.0
    centre = mean(values)
    return math.sqrt(math.fsum((v - centre) ** 2 for v in values) / (len(values) - 1))


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


def wilson_interval(successes: int, n: int, z: float = Z_975) -> Tuple[float, float]:
    """Return the Wilson score interval of a proportion (95 % by default); (0, 1) for n = 0."""
    if n == 0:
        return 0.0, 1.0
    if not 0 <= successes <= n:
        raise ValueError(f'successes must be in [0, {n}], got {successes}')
    p = successes / n
    z2 = z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return max(0.0, centre - half), min(1.0, centre + half)


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

    t = (mean_a - mean_b) / sqrt(s_a^2 / n_a + s_b^2 / n_b), degrees of freedom by the
    Welch-Satterthwaite equation. When both samples have no variance the test is undefined:
    p is None (and ``note`` says so), whether or not the means differ.
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
    var_a, var_b = sample_sd(a) ** 2 / n_a, sample_sd(b) ** 2 / n_b
    difference = mean_a - mean_b
    g, d = hedges_g(a, b), cohens_d(a, b)
    if var_a + var_b == 0:
        note = 'identical constant samples' if difference == 0 else 'constant samples'
        return WelchResult(n_a, n_b, mean_a, mean_b, difference, None, None, None, g, d, note)
    t = difference / math.sqrt(var_a + var_b)
    df = (var_a + var_b) ** 2 / (var_a ** 2 / (n_a - 1) + var_b ** 2 / (n_b - 1))
    return WelchResult(n_a, n_b, mean_a, mean_b, difference, t, df, t_two_sided_p(t, df), g, d)


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

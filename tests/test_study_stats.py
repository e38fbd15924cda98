"""The study's statistics against closed forms, hand computations and a textbook example."""

import math

from attention_bringup.study import stats
import numpy as np
import pytest


def _t_pdf(x: float, df: float) -> float:
    log_c = math.lgamma((df + 1) / 2) - math.lgamma(df / 2) - 0.5 * math.log(df * math.pi)
    return math.exp(log_c - (df + 1) / 2 * math.log1p(x * x / df))


def _integrated_two_sided_p(t: float, df: float, pieces: int = 20000) -> float:
    """1 - 2 * integral of the t density from 0 to |t| (composite Simpson's rule)."""
    h = abs(t) / pieces
    total = _t_pdf(0.0, df) + _t_pdf(abs(t), df)
    total += sum((4 if i % 2 else 2) * _t_pdf(i * h, df) for i in range(1, pieces))
    return 1.0 - 2.0 * total * h / 3.0


@pytest.mark.parametrize('t', [-3.0, -0.5, 0.0, 0.7, 2.0, 12.0])
def test_t_cdf_matches_the_closed_forms_for_one_and_two_degrees(t):
    cauchy = 0.5 + math.atan(t) / math.pi
    assert stats.t_cdf(t, 1) == pytest.approx(cauchy, abs=1e-12)
    two = 0.5 + t / (2.0 * math.sqrt(2.0 + t * t))
    assert stats.t_cdf(t, 2) == pytest.approx(two, abs=1e-12)


@pytest.mark.parametrize('t, df', [(2.5, 3.3), (1.1, 9.0), (4.0, 17.6), (0.3, 0.8),
                                   (2.9, 48.2)])
def test_two_sided_p_matches_numerical_integration_for_fractional_df(t, df):
    assert stats.t_two_sided_p(t, df) == pytest.approx(_integrated_two_sided_p(t, df),
                                                       abs=1e-8)


@pytest.mark.parametrize('df, quantile', [(1, 12.706204736), (9, 2.262157163),
                                          (10, 2.228138852), (30, 2.042272456)])
def test_t_quantile_975_matches_the_printed_tables(df, quantile):
    assert stats.t_quantile(0.975, df) == pytest.approx(quantile, abs=1e-8)
    assert stats.t_quantile(0.025, df) == pytest.approx(-quantile, abs=1e-8)


def test_welch_by_hand():
    # a: mean 2, variance 1; b: mean 6, variance 4. se^2 = 1/3 + 4/3 = 5/3,
    # t = -4 / sqrt(5/3), df = (5/3)^2 / ((1/3)^2 / 2 + (4/3)^2 / 2) = 50/17.
    result = stats.welch_t_test([1, 2, 3], [4, 6, 8])
    assert result.t == pytest.approx(-4 / math.sqrt(5 / 3), rel=1e-12)
    assert result.df == pytest.approx(50 / 17, rel=1e-12)
    assert result.p == pytest.approx(_integrated_two_sided_p(result.t, result.df), abs=1e-8)
    # Pooled sd sqrt((2 * 1 + 2 * 4) / 4); Hedges' factor 1 - 3 / (4 * 6 - 9) = 0.8.
    assert result.cohens_d == pytest.approx(-4 / math.sqrt(2.5), rel=1e-12)
    assert result.hedges_g == pytest.approx(0.8 * -4 / math.sqrt(2.5), rel=1e-12)


def test_welch_textbook_example():
    # The first example of the Wikipedia article "Welch's t-test" (reported there as
    # t = -2.46, df = 24.99, p = 0.021).
    a = [27.5, 21.0, 19.0, 23.6, 17.0, 17.9, 16.9, 20.1, 21.9, 22.6, 23.1, 19.6, 19.0, 21.7,
         21.4]
    b = [27.1, 22.0, 20.8, 23.4, 23.4, 23.5, 25.8, 22.0, 24.8, 20.2, 21.9, 22.1, 22.9, 20.5,
         24.4]
    result = stats.welch_t_test(a, b)
    assert round(result.t, 2) == -2.46
    assert round(result.df, 2) == 24.99
    assert round(result.p, 3) == 0.021


def test_welch_is_symmetric_and_undefined_without_variance():
    forward = stats.welch_t_test([1, 4, 2, 8], [3, 3, 5, 9, 7])
    backward = stats.welch_t_test([3, 3, 5, 9, 7], [1, 4, 2, 8])
    assert forward.t == pytest.approx(-backward.t)
    assert forward.p == pytest.approx(backward.p)
    constant = stats.welch_t_test([5, 5, 5], [7, 7, 7])
    assert constant.p is None and constant.note == 'constant samples'
    assert stats.welch_t_test([5, 5], [5, 5]).note == 'identical constant samples'
    assert stats.welch_t_test([1], [2, 3]).p is None


def test_wilson_by_hand():
    # 0 of n: the upper bound is z^2 / (n + z^2).
    z2 = stats.Z_975 ** 2
    assert stats.wilson_interval(0, 10) == pytest.approx((0.0, z2 / (10 + z2)))
    low, high = stats.wilson_interval(5, 10)
    assert low == pytest.approx(1 - high) and low < 0.5 < high
    assert stats.wilson_interval(0, 0) == (0.0, 1.0)
    with pytest.raises(ValueError):
        stats.wilson_interval(11, 10)


def test_wilson_exact_coverage_is_near_95_percent_for_ten_trials():
    n = 10
    intervals = [stats.wilson_interval(k, n) for k in range(n + 1)]
    coverages = []
    for p in np.linspace(0.02, 0.98, 49):
        coverages.append(sum(math.comb(n, k) * p ** k * (1 - p) ** (n - k)
                             for k, (low, high) in enumerate(intervals) if low <= p <= high))
    assert 0.93 <= float(np.mean(coverages)) <= 0.97
    assert min(coverages) > 0.8


def test_t_interval_covers_the_true_mean_95_percent_of_the_time():
    rng = np.random.default_rng(7)
    trials = 4000
    covered = 0
    for sample in rng.normal(3.0, 2.0, size=(trials, 10)):
        estimate = stats.mean_ci(sample.tolist())
        covered += estimate.low <= 3.0 <= estimate.high
    # Binomial sd of the rate is 0.0034: the bounds are over 4 sd away.
    assert 0.935 <= covered / trials <= 0.965


def test_mean_ci_of_small_samples():
    assert stats.mean_ci([]).mean is None
    one = stats.mean_ci([4.0])
    assert one.mean == 4.0 and one.low is None
    two = stats.mean_ci([1.0, 3.0])
    assert two.mean == 2.0 and two.high - 2.0 == pytest.approx(12.706204736 * 1.0, rel=1e-9)


def test_holm_by_hand():
    # Sorted 0.01, 0.03, 0.04 (m = 3): 3 * 0.01, max(0.03, 2 * 0.03), max(0.06, 0.04).
    assert stats.holm_adjust([0.04, 0.01, None, 0.03]) == pytest.approx(
        [0.06, 0.03, None, 0.06])
    assert stats.holm_adjust([0.9, 0.8]) == [1.0, 1.0]


def test_detectable_effect_matches_power_tables():
    # Two-sided alpha 0.05, power 0.8 (G*Power, exact noncentral t): n = 10 -> d = 1.32,
    # n = 20 -> 0.91.
    assert stats.detectable_effect(10) == pytest.approx(1.32, abs=0.01)
    assert stats.detectable_effect(20) == pytest.approx(0.91, abs=0.01)
    assert stats.detectable_effect(1) == math.inf

"""The study's statistics against published values (tables, R, Newcombe 1998) and by hand."""

import math
import warnings

from attention_bringup.experiment import stats
import numpy as np
import pytest


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
    # Pooled sd sqrt((2 * 1 + 2 * 4) / 4); Hedges' factor 1 - 3 / (4 * 6 - 9) = 0.8.
    assert result.cohens_d == pytest.approx(-4 / math.sqrt(2.5), rel=1e-12)
    assert result.hedges_g == pytest.approx(0.8 * -4 / math.sqrt(2.5), rel=1e-12)


# R's sleep data (Cushny and Peebles): extra hours of sleep under two drugs.
SLEEP_1 = [0.7, -1.6, -0.2, -1.2, -0.1, 3.4, 3.7, 0.8, 0.0, 2.0]
SLEEP_2 = [1.9, 0.8, 1.1, 0.1, -0.1, 4.4, 5.5, 1.6, 4.6, 3.4]


def test_welch_matches_r_on_the_sleep_data():
    # R: t.test(extra ~ group, data = sleep) -> t = -1.8608, df = 17.776, p-value = 0.07939.
    result = stats.welch_t_test(SLEEP_1, SLEEP_2)
    assert result.t == pytest.approx(-1.8608, abs=1e-4)
    assert result.df == pytest.approx(17.776, abs=1e-3)
    assert result.p == pytest.approx(0.07939, abs=1e-5)


def test_mean_ci_matches_r_on_the_sleep_data():
    # R: t.test(sleep$extra[1:10]) -> mean 0.75, 95 % CI -0.5297804 2.0297804.
    estimate = stats.mean_ci(SLEEP_1)
    assert estimate.mean == pytest.approx(0.75)
    assert estimate.low == pytest.approx(-0.5297804, abs=1e-7)
    assert estimate.high == pytest.approx(2.0297804, abs=1e-7)


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


def test_welch_against_a_constant_sample_is_a_one_sample_test_without_warnings():
    # Every trial censored at the budget: b's variance alone counts, so df = n_b - 1.
    budget, steps = [1001.0] * 10, [300.0 + 14 * i for i in range(10)]
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        result = stats.welch_t_test(budget, steps)
    assert result.df == pytest.approx(9.0)
    sd = stats.sample_sd(steps)
    assert result.t == pytest.approx((1001.0 - stats.mean(steps)) / (sd / math.sqrt(10)))


def test_welch_is_symmetric_and_undefined_without_variance():
    forward = stats.welch_t_test([1, 4, 2, 8], [3, 3, 5, 9, 7])
    backward = stats.welch_t_test([3, 3, 5, 9, 7], [1, 4, 2, 8])
    assert forward.t == pytest.approx(-backward.t)
    assert forward.p == pytest.approx(backward.p)
    constant = stats.welch_t_test([5, 5, 5], [7, 7, 7])
    assert constant.p is None and constant.note == 'constant samples'
    assert stats.welch_t_test([5, 5], [5, 5]).note == 'identical constant samples'
    assert stats.welch_t_test([1], [2, 3]).p is None


@pytest.mark.parametrize('successes, n, low, high', [
    (81, 263, 0.2553, 0.3662), (15, 148, 0.0624, 0.1605), (0, 20, 0.0, 0.1611),
    (1, 29, 0.0061, 0.1718)])
def test_wilson_matches_newcombe_1998(successes, n, low, high):
    # Newcombe, Statistics in Medicine 17 (1998) 857-872: method 3 (score, no correction).
    assert stats.wilson_interval(successes, n) == pytest.approx((low, high), abs=5e-5)


def test_wilson_by_hand():
    # 0 of n: the upper bound is z^2 / (n + z^2), z = 1.959964 (two-sided 95 %).
    z2 = 1.959963984540054 ** 2
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


def test_median_ci_is_the_order_statistics_of_the_sign_test():
    # n = 10: P(X < 2 or X > 8) for X ~ Bin(10, 1/2) is 0.021, so (x(2), x(9)) is the smallest
    # symmetric interval with at least 95 %; an outlier moves neither bound.
    interval = stats.median_ci([5, 1, 9, 3, 7, 2, 10, 4, 8, 6])
    assert (interval.n, interval.median, interval.low, interval.high) == (10, 5.5, 2.0, 9.0)
    assert stats.median_ci([5, 1, 9, 3, 7, 2, -500, 4, 8, 6]).low == 1.0
    assert stats.median_ci([1.0, 2.0, 3.0]).low is None  # too few for 95 %
    assert stats.median_ci([]).median is None


def test_median_interval_covers_the_true_median_95_percent_of_the_time():
    rng = np.random.default_rng(3)
    covered = 0
    for _ in range(2000):
        interval = stats.median_ci(rng.standard_cauchy(12) + 4.0)  # heavy tails, median 4
        covered += interval.low <= 4.0 <= interval.high
    assert covered / 2000 >= 0.95


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


def test_the_small_helpers_the_analyses_share():
    assert stats.median([3, 1, 2]) == 2.0 and isinstance(stats.median([3, 1, 2]), float)
    assert stats.median([4, 1, 2, 3]) == 2.5 and stats.median([]) is None
    assert stats.mean_of([1, None, 2]) == 1.5 and stats.mean_of([None]) is None
    assert stats.mean_of(x > 1 for x in (1, 2, 3, 4)) == 0.75
    curve = stats.reach_curve([5, None, 20], [0, 10, 20])
    assert curve['steps'] == [0, 10, 20] and curve['fraction'] == [0.0, 1 / 3, 2 / 3]
    assert (curve['low'][0], curve['high'][0]) == stats.wilson_interval(0, 3)
    assert stats.reach_curve([], [0])['fraction'] == [None]


def test_welch_rows_are_holm_adjusted_together():
    rows = stats.welch_rows([({'arm': 'a'}, [1.0, 2.0, 3.0], [4.0, 5.0, 6.0]),
                             ({'arm': 'b'}, [1.0, 2.0, 3.0], [1.5, 2.5, 3.5])])
    assert [row['arm'] for row in rows] == ['a', 'b']
    assert rows[0]['p'] == stats.welch_t_test([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]).p
    assert [row['p_holm'] for row in rows] == stats.holm_adjust([row['p'] for row in rows])

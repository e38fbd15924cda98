"""TokenBucket: the average rate holds, a short burst passes, a steady slower stream is whole."""

from attention_common.rate import TokenBucket
import pytest


def test_a_fast_stream_is_thinned_to_the_rate_after_its_burst():
    bucket = TokenBucket(30.0, burst=5)
    passed = sum(bucket.allow(step / 200.0) for step in range(2000))  # 10 s at 200 a second
    assert 300 <= passed <= 300 + 5


def test_a_stream_slower_than_the_rate_passes_whole_even_with_jitter():
    bucket = TokenBucket(30.0, burst=5)
    times = [step / 15.0 + (0.03 if step % 7 == 3 else 0.0) for step in range(300)]  # late ones
    assert all(bucket.allow(t) for t in times)


def test_impossible_rates_are_refused():
    with pytest.raises(ValueError):
        TokenBucket(0.0)
    with pytest.raises(ValueError):
        TokenBucket(10.0, burst=0.5)

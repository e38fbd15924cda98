"""Stamps as integer nanoseconds and the StampStore (attention_common.stamps)."""

import threading

from attention_common.stamps import (frames_to_ns, NS_PER_S, ns_to_stamp, stamp_to_ns,
                                     StampGuard, StampStore)
from builtin_interfaces.msg import Time
import pytest


@pytest.mark.parametrize('ns, sec, nanosec', [
    (0, 0, 0),
    (1, 0, 1),
    (NS_PER_S - 1, 0, NS_PER_S - 1),
    (NS_PER_S, 1, 0),
    (6_733_333_333, 6, 733_333_333),
    (2**31 * NS_PER_S - 1, 2**31 - 1, NS_PER_S - 1),
])
def test_ns_and_stamp_convert_exactly(ns, sec, nanosec):
    stamp = ns_to_stamp(ns)
    assert isinstance(stamp, Time) and (stamp.sec, stamp.nanosec) == (sec, nanosec)
    assert stamp_to_ns(stamp) == ns
    assert stamp_to_ns(Time(sec=sec, nanosec=nanosec)) == ns


@pytest.mark.parametrize('frames, ns', [(0, 0), (1, 16_666_667), (4, 66_666_667),
                                        (60, NS_PER_S), (404, 6_733_333_333)])
def test_frames_to_ns_at_60_hz(frames, ns):
    assert frames_to_ns(frames) == ns


def test_frame_stamps_strictly_increase_and_survive_the_round_trip():
    stamps = [frames_to_ns(frames) for frames in range(0, 100_000, 4)]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert all(stamp_to_ns(ns_to_stamp(ns)) == ns for ns in stamps)


def test_store_pairs_by_stamp():
    store = StampStore(4)
    store.put(10, 'a')
    store.put(20, 'b')
    assert store.get(10) == 'a' and store.get(15) is None
    assert store.pop(10) == 'a' and store.pop(10) is None
    assert len(store) == 1


@pytest.mark.parametrize('capacity', [1, 3, 8])
def test_store_is_bounded_and_evicts_the_oldest(capacity):
    store = StampStore(capacity)
    for stamp in range(capacity + 5):
        store.put(stamp, stamp)
    assert len(store) == capacity and store.evicted == 5
    assert store.get(4) is None and store.get(capacity + 4) == capacity + 4


def test_store_put_again_refreshes_an_entry():
    store = StampStore(2)
    store.put(1, 'old')
    store.put(2, 'two')
    store.put(1, 'new')  # now the most recent, so 2 goes first
    store.put(3, 'three')
    assert store.get(1) == 'new' and store.get(2) is None and store.evicted == 1


@pytest.mark.parametrize('cut, expected_old, expected_left', [
    (0, [], [5, 10, 15]),
    (10, [5], [10, 15]),
    (11, [5, 10], [15]),
    (100, [5, 10, 15], []),
])
def test_pop_older_than(cut, expected_old, expected_left):
    store = StampStore(10)
    for stamp in (10, 5, 15):  # arrival order differs from stamp order
        store.put(stamp, f'v{stamp}')
    old = store.pop_older_than(cut)
    assert sorted(old) == [(s, f'v{s}') for s in expected_old]
    assert sorted(s for s in (5, 10, 15) if store.get(s) is not None) == expected_left


@pytest.mark.parametrize('capacity', [0, -1])
def test_store_needs_room(capacity):
    with pytest.raises(ValueError):
        StampStore(capacity)


def test_store_stays_bounded_under_concurrent_writers():
    store = StampStore(50)

    def writer(offset):
        for i in range(2000):
            store.put(offset * 10_000 + i, i)
            store.pop(offset * 10_000 + i - 7)

    threads = [threading.Thread(target=writer, args=(n,)) for n in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=30)
    assert not any(thread.is_alive() for thread in threads)
    assert len(store) <= 50


# StampGuard: implausible jumps and restarts of a stream's stamps.
JUMP = 60 * NS_PER_S


def test_stamps_near_the_newest_are_accepted_late_ones_too():
    guard = StampGuard(JUMP)
    assert [guard.check(s * NS_PER_S) for s in (7, 8, 9, 8, 69)] == ['ok'] * 5
    assert guard.newest == 69 * NS_PER_S and guard.rejected == 0


@pytest.mark.parametrize('stray', [2**31 * NS_PER_S, 0, 200 * NS_PER_S])
def test_one_stray_stamp_far_ahead_or_behind_is_rejected_and_moves_nothing(stray):
    guard = StampGuard(JUMP)
    for s in (100, 101):
        guard.check(s * NS_PER_S)
    assert guard.check(stray) == 'implausible'
    assert guard.newest == 101 * NS_PER_S
    assert guard.check(102 * NS_PER_S) == 'ok'
    assert not guard.plausible(stray) and guard.plausible(102 * NS_PER_S)
    assert guard.rejected == 1 and guard.restarts == 0


def test_a_stream_that_starts_over_is_followed_after_three_stamps():
    guard = StampGuard(JUMP)
    for s in range(500, 510):
        guard.check(s * NS_PER_S)
    # A new env: 6.7 s, re-sent once (lockstep, unanswered), then on.
    verdicts = [guard.check(s) for s in (6_700_000_000, 6_700_000_000, 6_766_666_667)]
    assert verdicts == ['implausible', 'implausible', 'restart']
    assert guard.newest == 6_766_666_667 and guard.restarts == 1
    assert guard.check(6_833_333_333) == 'ok'


def test_stray_stamps_that_do_not_continue_each_other_never_restart():
    guard = StampGuard(JUMP)
    guard.check(500 * NS_PER_S)
    for stray in (0, 2**31 * NS_PER_S, 5 * NS_PER_S, 10**6 * NS_PER_S, 1 * NS_PER_S):
        assert guard.check(stray) == 'implausible'
    assert guard.newest == 500 * NS_PER_S and guard.restarts == 0


def test_the_dds_profile_is_chosen_unless_the_user_configures_fast_dds():
    from attention_common.dds_memory import PROFILE, use_freed_payloads
    environ = {}
    assert use_freed_payloads(environ) and PROFILE.exists()
    assert environ == {'FASTRTPS_DEFAULT_PROFILES_FILE': str(PROFILE),
                       'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'}
    for own in ({'FASTRTPS_DEFAULT_PROFILES_FILE': '/mine.xml'},
                {'RMW_FASTRTPS_USE_QOS_FROM_XML': '0'}):
        untouched = dict(own)
        assert not use_freed_payloads(untouched) and untouched == own

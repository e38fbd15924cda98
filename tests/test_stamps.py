"""Stamps as integer nanoseconds and the StampGuard (attention_common.stamps)."""

from attention_common.stamps import (frames_to_ns, NS_PER_S, ns_to_stamp, stamp_to_ns,
                                     StampGuard)
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

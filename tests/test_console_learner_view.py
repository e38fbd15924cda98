"""The console's view of the learner (trainer_console.learner_view): pure, no rclpy."""

import json

import pytest
from trainer_console.learner_view import LearnerView, parse_credit, parse_values, strip_cells
from trainer_console.state import ConsoleState

NAMES = ('NOOP', 'FIRE', 'UP')
MS = 1_000_000
T0 = 1_700_000_000_000_000_000  # beyond 2**53: only strings carry it to the page


def values(action=2, h=(0.1, -0.2, 0.5), names=NAMES, version='7'):
    pairs = [('action', str(action)), ('version', version)]
    pairs += [(name, f'{x:.4f}') for name, x in zip(names, h)]
    return 'action_values', names[action] if 0 <= action < len(names) else 'X', pairs


def credit(seq, h=1.0, steps=(), mode='window'):
    pairs = [('seq', str(seq)), ('h', f'{h:.6g}')]
    pairs += [(str(stamp), f'{weight:.5f}') for stamp, weight in steps]
    return 'feedback_credit', mode, pairs


def steps_every(view, count, period_ms=66, start=T0):
    stamps = [start + i * period_ms * MS for i in range(count)]
    for stamp in stamps:
        assert view.on_values(stamp, values()) is None
    return stamps


@pytest.mark.parametrize('frame, shown, exact', [
    (2, 2, True),      # the frame's own step
    (3, 2, False),     # its H has not come yet: the newest step not newer
    (0, 0, True),
    (None, 4, False),  # no frame yet: the newest step
])
def test_the_h_shown_is_the_frames_or_the_newest_not_newer(frame, shown, exact):
    view = LearnerView()
    stamps = [T0 + i * 100 * MS for i in (0, 1, 2, 4)]
    for i, stamp in zip((0, 1, 2, 4), stamps):
        view.on_values(stamp, values(action=i % 3, h=(i, -i, 0.5)))
    frame_ns = None if frame is None else T0 + frame * 100 * MS
    got = view.view(frame_ns)['values']
    assert got['stamp'] == str(T0 + shown * 100 * MS) and got['exact'] is exact
    assert got['h'][0] == shown and got['taken'] == NAMES[shown % 3]
    assert got['names'] == list(NAMES) and got['version'] == 7


def test_a_frame_older_than_every_step_has_no_h_and_an_empty_strip():
    view = LearnerView()
    steps_every(view, 3)
    shown = view.view(T0 - 1)
    assert shown['values'] is None and shown['strip']['steps'] == 0


def test_credit_goes_to_our_press_by_seq_whichever_comes_first():
    view = LearnerView()
    stamps = steps_every(view, 10)
    view.ours(5)  # receipt first, then its credit
    view.on_credit(credit(5, 1.0, [(stamps[2], 0.25), (stamps[3], 0.75)]))
    view.on_credit(credit(6, -1.0, [(stamps[4], 1.0)]))  # not (yet) ours
    shown = view.view(stamps[-1])
    assert shown['newest']['seq'] == 5 and shown['newest']['h'] == 1.0
    assert shown['newest']['steps'] == 2 and shown['newest']['sum'] == 1.0
    assert shown['strip']['cells'] == [[2, str(stamps[2]), 5, 1, 0.333],
                                       [3, str(stamps[3]), 5, 1, 1.0]]
    assert shown['others']['count'] == 1 and shown['others']['newest']['seq'] == 6
    view.ours(6)  # its receipt came after its credit
    shown = view.view(stamps[-1])
    assert shown['newest']['seq'] == 6 and shown['newest']['h'] == -1.0
    assert shown['others']['count'] == 0 and shown['newest']['shown'] == 1
    assert [cell[2] for cell in shown['strip']['cells']] == [5, 5, 6]
    assert shown['strip']['cells'][-1][3] == -1  # red


def test_a_newer_press_takes_the_cells_an_older_one_also_credits():
    cells = strip_cells([10, 20, 30], [parse_credit(*credit(1, 1.0, [(10, 0.5), (20, 0.5)])),
                                       parse_credit(*credit(2, -1.0, [(20, 0.2), (99, 0.8)]))])
    assert cells == [[0, '10', 1, 1, 1.0], [1, '20', 2, -1, 0.25]]  # 99 is not in the strip


def test_our_press_waiting_for_its_credit_is_named():
    view = LearnerView()
    stamps = steps_every(view, 3)
    view.ours(1)
    view.on_credit(credit(1, 1.0, [(stamps[0], 1.0)], mode='step'))
    view.ours(2)
    shown = view.view()
    assert shown['newest']['seq'] == 1 and shown['waiting'] == [2]


def test_the_receipt_of_our_press_hands_its_log_seq_to_the_view():
    state = ConsoleState()
    t = 1_800_000_000_000_000_000
    state.sent('feedback', 1.0, 1, t)
    state.learner.on_credit(credit(41, 1.0, [(T0, 1.0)], mode='step'))
    state.learner.on_credit(credit(42, -1.0, [(T0, 1.0)], mode='step'))
    state.learner.on_values(T0, values())

    class KV:
        def __init__(self, key, value):
            self.key, self.value = key, value

    class Status:
        name = 'feedback'
        values = [KV('seq', '42'), KV('publication_seq', '1'),
                  KV('source_time_ns', str(t)), KV('status', 'ok')]

    class Receipt:
        status = [Status()]

    state.on_receipt_message(Receipt())
    shown = state.learner.view()
    assert shown['newest']['seq'] == 42 and shown['newest']['h'] == -1.0
    assert shown['others']['count'] == 1  # 41 is someone else's


def test_everything_is_bounded():
    view = LearnerView(steps_kept=50, presses_kept=3, strip_steps=20, others_kept=4)
    stamps = steps_every(view, 120)
    for seq in range(1, 11):
        view.ours(seq)
        view.on_credit(credit(seq, 1.0, [(stamps[-seq], 1.0)]))
    for seq in range(100, 110):
        view.on_credit(credit(seq, 1.0, [(stamps[-1], 1.0)]))
    shown = view.view()
    assert shown['strip']['steps'] == 20 and shown['strip']['first'] == str(stamps[-20])
    assert view.view(stamps[60])['values'] is None  # older than the last 50 kept
    assert shown['newest']['seq'] == 10 and shown['others']['count'] == 4
    assert sorted({cell[2] for cell in shown['strip']['cells']}) == [8, 9, 10]
    assert len(json.dumps(shown, allow_nan=False)) < 4000  # cheap at 15 a second


def test_stamps_that_start_over_clear_the_steps():
    view = LearnerView()
    steps_every(view, 5)
    view.on_values(10 * MS, values())  # a new env: its stamps start near zero
    assert view.view()['values']['stamp'] == str(10 * MS) and view.view()['strip']['steps'] == 1


@pytest.mark.parametrize('status', [
    None,
    ('metrics', 'UP', [('action', '2'), ('UP', '0.1')]),
    ('action_values', 'UP', [('version', '1'), ('NOOP', '0.1')]),                 # no action
    ('action_values', 'UP', [('action', 'two'), ('NOOP', '0.1')]),
    ('action_values', 'UP', [('action', '5'), ('version', '1'), ('NOOP', '0.1')]),
    ('action_values', 'FIRE', [('action', '0'), ('version', '1'), ('NOOP', '0.1')]),
    ('action_values', 'NOOP', [('action', '0'), ('version', '1'), ('NOOP', 'high')]),
    ('action_values', 'NOOP', [('action', '0'), ('version', '1')]),               # no H
])
def test_a_malformed_action_values_is_counted_and_ignored(status):
    view = LearnerView()
    assert view.on_values(T0, status)
    assert view.malformed['action_values'] == 1 and view.view()['values'] is None
    assert view.on_values(T0, values()) is None and view.view()['values'] is not None


@pytest.mark.parametrize('status', [
    None,
    ('feedback_logged', 'window', [('seq', '1'), ('h', '1')]),
    ('feedback_credit', 'window', [('h', '1'), ('5', '1.0')]),                    # no seq
    ('feedback_credit', 'window', [('seq', '1'), ('h', 'nan'), ('5', '1.0')]),
    ('feedback_credit', 'window', [('seq', '1'), ('h', '1'), ('later', '1.0')]),
    ('feedback_credit', 'window', [('seq', '1'), ('h', '1'), ('5', '-0.5')]),
    ('feedback_credit', 'window', [('seq', '1'), ('h', '1'), ('5', 'inf')]),
])
def test_a_malformed_credit_is_counted_and_ignored(status):
    view = LearnerView()
    view.ours(1)
    assert view.on_credit(status)
    shown = view.view()
    assert view.malformed['feedback_credit'] == 1 and shown['newest'] is None
    assert shown['malformed']['feedback_credit'] == 1


def test_a_non_finite_h_is_shown_as_none_not_nan():
    step = parse_values(T0, 'action_values', 'NOOP',
                        [('action', '0'), ('version', '3'), ('NOOP', 'nan'), ('UP', '0.5')])
    assert step.h == (None, 0.5)


def test_a_frame_goes_to_the_page_with_its_stamp():
    from trainer_console.web import Frames, STAMP
    frames, seen = Frames(), {}
    frames.put('frame', b'jpeg', T0)
    [(kind, stamp, jpeg)] = frames.newer(seen)
    assert (kind, jpeg) == ('frame', b'jpeg') and STAMP.unpack(STAMP.pack(stamp)) == (T0,)
    assert frames.newer(seen) == []

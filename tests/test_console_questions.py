"""The console's desk of the learner's questions (pure: trainer_console/questions.py)."""

from trainer_console.questions import FRAME_PATIENCE_S, OUTCOMES, Question, QuestionDesk


def ask(stamp, action=3, gap=0.1, at=0.0):
    return Question(stamp, action, gap, at)


def ended(desk):
    return sum(desk.counts[outcome] for outcome in OUTCOMES)


def test_a_question_goes_on_screen_with_its_own_frame_and_only_its_answer_closes_it():
    desk = QuestionDesk()
    for stamp in (10, 20, 30):
        assert desk.on_frame(stamp, f'frame {stamp}', 100) is None  # nothing asked yet
    first = desk.on_question(ask(20))
    assert first == desk.current == ask(20) and desk.frame(20) == 'frame 20'
    assert desk.on_question(ask(30, action=5)) is None  # waits behind the one on screen
    assert desk.snapshot(action_names=[f'a{i}' for i in range(6)]) == {
        'question': {'stamp': '20', 'action': 3, 'taken': 'a3', 'gap': 0.1}, 'waiting': 1,
        'counts': {'heard': 2, 'answered': 0, 'skipped': 0, 'lost': 0, 'not_shown': 0}}
    assert desk.close('answered', stamp_ns=30) is None  # a press on another frame: no answer
    assert desk.current == ask(20)
    second = desk.close('answered', stamp_ns=20)
    assert second == desk.current == ask(30, action=5)
    assert desk.close('skipped') is None and desk.current is None and not desk.is_open()
    assert (desk.counts['answered'], desk.counts['skipped'], ended(desk)) == (1, 1, 2)


def test_a_question_waits_for_its_frame_and_is_lost_when_it_cannot_come():
    desk = QuestionDesk()
    desk.on_frame(10, 'f10', 1)
    assert desk.on_question(ask(20, at=5.0)) is None  # its frame is on its way
    assert desk.is_open() and desk.current is None
    assert desk.on_frame(20, 'f20', 1) == ask(20, at=5.0)  # it came: on screen
    desk.close('answered', 20)
    # A frame after the asked one came first: the asked one was lost on the way.
    assert desk.on_question(ask(25)) is None
    assert desk.on_frame(30, 'f30', 1) is None and desk.counts['lost'] == 1
    # No frame comes at all (the env is paused): lost after the patience.
    desk.on_question(ask(40, at=100.0))
    assert desk.tick(100.0 + FRAME_PATIENCE_S / 2) is None and desk.is_open()
    assert desk.tick(100.0 + FRAME_PATIENCE_S + 0.1) is None and not desk.is_open()
    assert (desk.counts['heard'], desk.counts['lost'], ended(desk)) == (3, 2, 3)


def test_every_question_heard_is_counted_once_whatever_becomes_of_it():
    desk = QuestionDesk(max_waiting=2)
    for stamp in range(1, 6):
        desk.on_frame(stamp, stamp, 1)
    for stamp in range(1, 6):
        desk.on_question(ask(stamp))
    # One on screen, two waiting, two more than the desk keeps: lost (counted, not silent).
    assert desk.current.stamp_ns == 1 and desk.snapshot()['waiting'] == 2
    assert desk.counts['lost'] == 2
    assert desk.skip_all() == 3 and not desk.is_open()  # the person resumed the env
    assert ended(desk) == desk.counts['heard'] == 5
    hidden = QuestionDesk(show=False)
    assert hidden.on_question(ask(1)) is None and not hidden.is_open()
    assert hidden.counts['not_shown'] == hidden.counts['heard'] == 1


def test_the_frames_held_are_bounded_by_number_and_bytes():
    desk = QuestionDesk(frames_held=3, bytes_held=250)
    for stamp in range(1, 5):
        desk.on_frame(stamp, stamp, 100)
    assert [desk.frame(s) for s in range(1, 5)] == [None, None, 3, 4]  # 250 bytes: two
    desk = QuestionDesk(frames_held=3, bytes_held=10**6)
    for stamp in range(1, 6):
        desk.on_frame(stamp, stamp, 100)
    assert [desk.frame(s) for s in range(1, 6)] == [None, None, 3, 4, 5]
    desk.on_question(ask(1))  # older than any frame held: lost at once
    assert desk.counts['lost'] == 1 and not desk.is_open()

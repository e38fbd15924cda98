"""Figure 5.1 utterances: each position, in between, the interval and the stuck rule."""

from attention_common.stamps import frames_to_ns
from attention_tasks.montezuma.critical_positions import CRITICAL_POSITIONS
from attention_tasks.montezuma.sentences import sentence_for, SENTENCES
from feedback_node.utterances import IntervalSchedule, StuckDetector, UtteranceGenerator
import pytest

FIGURE_5_1 = [
    (0, 'Jump right from the ladder onto the rope.'),
    (1, 'Jump right from the rope onto the lower platform.'),
    (2, 'Climb down the ladder onto the ground.'),
    (3, 'Move left and avoid the skull.'),
    (4, 'Climb up the ladder.'),
    (5, 'Jump up to get the key.'),
]


def stamp(step: int) -> int:
    """Return the stamp of agent step ``step`` (frameskip 4 at 60 Hz)."""
    return frames_to_ns(4 * step)


@pytest.mark.parametrize('position, text', FIGURE_5_1)
def test_each_critical_position_says_its_figure_5_1_sentence(position, text):
    x, y = CRITICAL_POSITIONS[position]
    assert sentence_for(x + 3, y - 3) == (position, position, text)


@pytest.mark.parametrize('x, y, nearest', [
    (95, 195, 0),    # on the conveyor, short of the rope jump
    (100, 205, 1),   # in the air toward the rope
    (133, 172, 2),   # on the right ladder, nearer the top
    (133, 165, 3),   # on the right ladder, nearer the bottom
    (55, 148, 4),    # on the floor, nearer the left ladder
    (77, 148, 0),    # on the floor right below the conveyor: position 0 is nearest
    (21, 172, 5),    # climbing the left ladder
])
def test_in_between_speaks_toward_the_nearest_position(x, y, nearest):
    position, sentence_of, text = sentence_for(x, y)
    assert position == -1 and sentence_of == nearest
    assert text == SENTENCES[nearest]


def test_in_between_literal_says_the_figure_5_1_minus_one_sentence():
    assert sentence_for(70, 148, in_between='literal') == (
        -1, -1, 'Go back to the top of the ladder and jump onto the rope.')


@pytest.mark.parametrize('interval, expected_steps', [
    (10.0, [0, 150, 300]),  # 150 steps of 4 frames = 10 s
    (2.5, [0, 38, 76, 114, 152, 190, 228, 266, 304]),  # 37.5 steps: the next whole step
    (0.0, list(range(320))),
    (-1.0, []),
])
def test_interval_in_simulation_seconds(interval, expected_steps):
    schedule = IntervalSchedule(interval)
    spoken = []
    for step in range(320):
        if schedule.due(stamp(step)):
            schedule.spoken(stamp(step))
            spoken.append(step)
    assert spoken == expected_steps


def test_stuck_detector_is_a_buffer_of_equal_positions():
    detector = StuckDetector(4)
    assert [detector.add(5, 5) for _ in range(5)] == [False, False, False, True, True]
    assert detector.add(6, 5) is False
    assert [detector.add(6, 5) for _ in range(3)] == [False, False, True]


def test_stuck_agent_gets_no_utterance_until_it_moves():
    generator = UtteranceGenerator(interval_s=0.0, stuck_buffer_steps=10)
    x, y = CRITICAL_POSITIONS[0]
    said = [generator.observe(x, y, stamp(step)) for step in range(14)]
    assert all(u is not None for u in said[:9])
    assert said[9:] == [None] * 5  # ten equal positions in the buffer: stuck
    moved = generator.observe(x + 2, y, stamp(14))
    assert moved is not None and moved.text == SENTENCES[0] and moved.stamp_ns == stamp(14)
    assert generator.withheld == 5


def test_utterance_due_while_stuck_is_said_when_the_agent_moves():
    generator = UtteranceGenerator(interval_s=10.0, stuck_buffer_steps=10)
    x, y = CRITICAL_POSITIONS[3]
    first = generator.observe(x, y, stamp(0))
    assert first is not None and first.text == SENTENCES[3]
    said = [generator.observe(x, y, stamp(step)) for step in range(1, 200)]
    assert said == [None] * 199  # due at step 150, but stuck since step 9
    late = generator.observe(x - 4, y, stamp(200))
    assert late is not None and late.position == 3 and late.stamp_ns == stamp(200)
    assert generator.observe(x - 8, y, stamp(201)) is None  # the interval restarts from 200


def test_generator_follows_a_walk_position_by_position():
    generator = UtteranceGenerator(interval_s=0.0)
    # Along the floor from the right ladder to the left ladder.
    spoken = [generator.observe(x, 148, stamp(i)) for i, x in enumerate(range(133, 20, -4))]
    positions = [u.position for u in spoken]
    assert positions[0] == 3 and positions[-1] == 4 and -1 in positions
    # Euclidean "nearest" (the thesis's rule) passes under position 0 in the middle.
    said = [u.sentence_of for u in spoken]
    assert [s for i, s in enumerate(said) if i == 0 or said[i - 1] != s] == [3, 0, 4]

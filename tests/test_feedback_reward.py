"""Equations 4.1 and 4.2, the stationary rule and the progress variant, table-driven."""

import math

from attention_tasks.montezuma.critical_positions import (
    critical_position_at, CRITICAL_POSITIONS, DEFAULT_RADIUS, nearest_critical_position)
from attention_tasks.montezuma.reward import RewardConfig, RewardFunction, threshold_reward
from feedback_node.trainer import TrainerConfig
import pytest

RIGHT_LADDER_BOTTOM = CRITICAL_POSITIONS[3]


def walk(*points, step=4.0):
    """Positions from point to point, at most ``step`` apart (no teleports)."""
    path = [tuple(map(float, points[0]))]
    for (x0, y0), (x1, y1) in zip(points, points[1:]):
        count = max(1, math.ceil(math.hypot(x1 - x0, y1 - y0) / step))
        path += [(x0 + (x1 - x0) * k / count, y0 + (y1 - y0) * k / count)
                 for k in range(1, count + 1)]
    return path


@pytest.mark.parametrize('d, expected', [
    (0.0, 1), (7.0, 1), (7.99, 1),        # d < alpha
    (8.0, 0), (8.01, 0), (19.99, 0),      # alpha <= d < beta
    (20.0, -1), (20.01, -1), (300.0, -1),  # d >= beta
])
def test_threshold_reward_at_and_around_both_thresholds(d, expected):
    assert threshold_reward(d, alpha=8.0, beta=20.0) == expected


@pytest.mark.parametrize('dx, dy, expected', [
    (0, 0, 1), (-7, 0, 1), (-7.9, 0, 1), (-8, 0, 0), (-8.1, 0, 0),
    (-6, 6, 0),  # diagonal: d = 8.49
    (-19.9, 0, 0), (-20, 0, -1), (-20.1, 0, -1),
    (-12, 16, -1),  # d = 20 exactly, diagonally
])
def test_h_from_a_position_near_a_critical_position(dx, dy, expected):
    x, y = RIGHT_LADDER_BOTTOM[0] + dx, RIGHT_LADDER_BOTTOM[1] + dy
    judgement = RewardFunction()(x, y)
    assert judgement.target == 3
    assert judgement.distance == pytest.approx(math.hypot(dx, dy))
    assert judgement.h == expected
    assert judgement.position == (3 if math.hypot(dx, dy) < DEFAULT_RADIUS else -1)


def test_alpha_is_the_thesis_8_px_everywhere_by_default():
    assert DEFAULT_RADIUS == 8.0
    assert RewardConfig().alpha_threshold == TrainerConfig().alpha_threshold == DEFAULT_RADIUS


@pytest.mark.parametrize('alpha, beta, d, expected', [
    (4.0, 10.0, 5.0, 0), (4.0, 10.0, 3.9, 1), (4.0, 10.0, 10.0, -1), (12.0, 30.0, 25.0, 0),
])
def test_thresholds_are_parameters(alpha, beta, d, expected):
    reward = RewardFunction(RewardConfig(alpha_threshold=alpha, beta_threshold=beta))
    judgement = reward(RIGHT_LADDER_BOTTOM[0] - d, RIGHT_LADDER_BOTTOM[1])
    assert judgement.h == expected


@pytest.mark.parametrize('stationary_steps', [1, 3, 10])
def test_standing_still_more_than_stationary_steps_gives_minus_one(stationary_steps):
    reward = RewardFunction(RewardConfig(stationary_steps=stationary_steps))
    x, y = CRITICAL_POSITIONS[1]  # on the rope: h = 1 while moving
    hs = [reward(x, y).h for _ in range(stationary_steps + 4)]
    # Call k has stood still for k steps: fine up to stationary_steps, -1 after.
    assert hs[:stationary_steps + 1] == [1] * (stationary_steps + 1)
    assert hs[stationary_steps + 1:] == [-1] * 3
    assert reward(x + 1, y).h == 1  # moving again lifts it at once


def test_a_small_move_resets_the_stationary_count():
    reward = RewardFunction()
    x, y = CRITICAL_POSITIONS[0]
    hs = []
    for step in range(30):
        hs.append(reward(x + (step // 8) % 2, y).h)  # moves one pixel every 8 steps
    assert hs == [1] * 30


def test_progress_variant_does_not_reward_going_back():
    nearest = RewardFunction()
    progress = RewardFunction(RewardConfig(reward_variant='progress'))
    for x, y in walk(*CRITICAL_POSITIONS[:3]):
        nearest(x, y)
        judgement = progress(x, y)
    assert progress.furthest == 2 and judgement.h == 1
    # Back on the rope (position 1): nearest rewards it, progress does not.
    for x, y in walk(CRITICAL_POSITIONS[2], CRITICAL_POSITIONS[1]):
        back_nearest, back_progress = nearest(x, y), progress(x, y)
    assert back_nearest.h == 1
    assert back_progress.h == -1 and back_progress.target == 2


def test_progress_variant_targets_the_next_position_and_resets_on_a_teleport():
    progress = RewardFunction(RewardConfig(reward_variant='progress'))
    start = (77, 235)
    assert progress(*start).target == 0
    for x, y in walk(start, CRITICAL_POSITIONS[0]):
        judgement = progress(x, y)
    assert judgement.h == 1 and progress.furthest == 0
    for x, y in walk(CRITICAL_POSITIONS[0], (101, 200)):
        judgement = progress(x, y)
    assert judgement.target == 1  # nearer to the rope than back to the ladder
    assert progress(*start).target == 0  # a respawn at the start: progress starts over
    assert progress.furthest == -1


def test_reward_config_rejects_nonsense():
    with pytest.raises(ValueError):
        RewardConfig(alpha_threshold=20.0, beta_threshold=8.0)
    with pytest.raises(ValueError):
        RewardConfig(reward_variant='furthest')
    with pytest.raises(ValueError):
        RewardConfig(stationary_steps=0)


@pytest.mark.parametrize('index', range(6))
def test_critical_position_lookup(index):
    x, y = CRITICAL_POSITIONS[index]
    assert nearest_critical_position(x, y) == (index, 0.0)
    assert critical_position_at(x + 7.9, y) == index
    assert critical_position_at(x, y - 8.0) in (-1, index) and critical_position_at(
        x, y - 8.0, radius=8.01) == index


def test_between_positions_is_minus_one():
    assert critical_position_at(50, 170) == -1
    index, d = nearest_critical_position(50, 170)
    assert d >= 8.0 and 0 <= index < 6

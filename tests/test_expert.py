"""
The scripted expert plays Room 1 to the key through the real emulator.

Also checks the critical positions against its route: it must pass within alpha (8) of
positions 0..5, in that order.
"""

from attention_tasks.montezuma.critical_positions import (
    critical_position_at, CRITICAL_POSITIONS, DEFAULT_RADIUS, distance)
from attention_tasks.montezuma.env import EnvConfig, KEY_BIT, MontezumaEnv, RAM_INVENTORY
from attention_tasks.montezuma.expert import (
    Phase, RoomOneExpert, SKULL_RAM, skull_x_from_frame, skull_x_from_ram, SkullTracker)
import numpy as np
import pytest

MAX_STEPS = 600  # the route takes ~90 steps; waiting out the skull adds at most ~100


def play(config: EnvConfig, skull_source: str = 'none', max_steps: int = MAX_STEPS):
    """Run the expert until it has the key; return the trajectory and the rewards."""
    env = MontezumaEnv(config)
    try:
        step = env.warm_up() if config.warmup_steps else env.reset()
        expert = RoomOneExpert()
        expert.reset()
        positions, rewards, phases = [(step.state.x, step.state.y)], [], []
        for _ in range(max_steps):
            skull = None
            if skull_source == 'ram':
                skull = skull_x_from_ram(env.ale.getRAM())
            elif skull_source == 'frame':
                skull = skull_x_from_frame(step.observation)
            action = expert.act(step.state, skull)
            phases.append(expert.phase)
            step = env.step(action)
            positions.append((step.state.x, step.state.y))
            rewards.append(step.reward)
            assert not step.truncated, f'left Room 1 at {positions[-1]}'
            if step.state.has_key or step.terminated:
                break
        return {'positions': positions, 'rewards': rewards, 'phases': phases,
                'state': step.state, 'ram': env.ale.getRAM().copy()}
    finally:
        env.close()


def first_visits(positions):
    """Step index at which each critical position is first within alpha (None if never)."""
    visits = []
    for point in CRITICAL_POSITIONS:
        hits = [i for i, (x, y) in enumerate(positions) if distance(x, y, point) < DEFAULT_RADIUS]
        visits.append(hits[0] if hits else None)
    return visits


def assert_route_to_key(run):
    visits = first_visits(run['positions'])
    assert None not in visits, f'critical positions never reached: {visits}'
    assert visits == sorted(visits) and len(set(visits)) == len(visits), visits
    assert run['state'].has_key, f'no key; ended at {run["positions"][-1]}'
    assert run['ram'][RAM_INVENTORY] & KEY_BIT
    assert 100.0 in run['rewards']


def test_fresh_game_reaches_key_through_positions_in_order():
    # Blind to the skull: the tracker predicts it from the start of a fresh game.
    run = play(EnvConfig(warmup_steps=0, sticky_actions=0.0))
    assert_route_to_key(run)
    assert sum(run['rewards']) == 100.0
    assert run['state'].lives == 5, 'the expert lost a life on a fresh game'
    phases = [p for p in dict.fromkeys(run['phases']) if p is not Phase.AIRBORNE]
    assert phases == [Phase.TO_MIDDLE_LADDER, Phase.DOWN_MIDDLE_LADDER, Phase.TO_ROPE,
                      Phase.ON_ROPE, Phase.TO_RIGHT_LADDER, Phase.DOWN_RIGHT_LADDER,
                      Phase.ACROSS_FLOOR, Phase.UP_LEFT_LADDER, Phase.TO_KEY]


def test_fresh_game_is_deterministic_and_labels_every_position():
    first = play(EnvConfig(warmup_steps=0, sticky_actions=0.0))
    second = play(EnvConfig(warmup_steps=0, sticky_actions=0.0, seed=7))
    assert first['positions'] == second['positions']
    labels = [critical_position_at(x, y) for x, y in first['positions']]
    spoken = [label for i, label in enumerate(labels)
              if label >= 0 and (i == 0 or labels[i - 1] != label)]
    assert spoken == sorted(spoken) and set(spoken) == set(range(len(CRITICAL_POSITIONS)))


@pytest.mark.parametrize('seed', range(6))
def test_reaches_key_after_random_warm_up(seed):
    # 100 random warm-up steps (as every trial starts) leave the agent and the skull anywhere.
    run = play(EnvConfig(warmup_steps=100, sticky_actions=0.0, seed=seed), skull_source='ram')
    assert run['state'].has_key, f'seed {seed}: ended at {run["positions"][-1]}'
    assert 100.0 in run['rewards']


@pytest.mark.parametrize('seed', [3, 11])
def test_reaches_key_seeing_the_skull_only_in_frames(seed):
    run = play(EnvConfig(warmup_steps=100, sticky_actions=0.0, seed=seed), skull_source='frame')
    assert run['state'].has_key, f'seed {seed}: ended at {run["positions"][-1]}'


def test_skull_tracker_and_frame_reader_follow_the_skull():
    env = MontezumaEnv(EnvConfig(warmup_steps=0, sticky_actions=0.0))
    try:
        step = env.reset()
        predicted = SkullTracker()
        corrected = SkullTracker()
        corrected.reset(position=30, velocity=1)  # deliberately wrong
        frame_errors, late_errors = [], []
        rng = np.random.default_rng(0)
        for t in range(250):
            skull = int(env.ale.getRAM()[SKULL_RAM])
            seen = skull_x_from_frame(step.observation)
            assert seen is not None
            frame_errors.append(abs(seen - skull))
            assert predicted.update() == skull, f'step {t}'
            estimate = corrected.update(seen)
            if t >= 3:
                late_errors.append(abs(estimate - skull))
            # NOOP and UP keep the agent safe on the top floor while the skull rolls.
            step = env.step(int(rng.choice([0, 2])))
        assert max(frame_errors) <= 0.5
        assert max(late_errors) <= 1
    finally:
        env.close()


def test_skull_reader_sees_no_skull_in_a_black_frame():
    assert skull_x_from_frame(np.zeros((210, 160, 3), np.uint8)) is None

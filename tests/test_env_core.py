"""env_node's pure core on the real ALE: RAM addresses checked against the frames, flags, time."""

from dataclasses import fields

from attention_common.parameters import field_docs
from attention_common.stamps import frames_to_ns
from attention_tasks.montezuma.env import (
    EnvConfig, FRAME_HEIGHT, FRAME_WIDTH, MontezumaEnv, NO_ACTION, RAM_INVENTORY, RAM_X, RamState,
    read_ram_state, STANDING_POSES)
from env_node.config import EnvNodeConfig
from env_node.status import Counters, NO_LATENCY, parse_status, STATUS_KEYS, status_values
import numpy as np
import pytest

NOOP, UP, RIGHT, LEFT, DOWN = 0, 2, 3, 4, 5

# What the frame shows, found by colour (independent of the RAM decoding under test).
SPRITE_COLOURS = np.array([[200, 72, 72], [210, 182, 86], [228, 111, 111]], np.uint8)
HAT_COLOUR = np.array([210, 182, 86], np.uint8)   # lives are drawn as hats in the HUD
KEY_COLOUR = np.array([232, 204, 99], np.uint8)   # the key, in the room or in the inventory
PLAY_TOP = 47                                     # rows above are the HUD
LIVES_ROWS = slice(10, 24)
INVENTORY_ROWS = slice(25, PLAY_TOP)


def _packed(pixels):
    pixels = pixels.astype(np.uint32)
    return (pixels[..., 0] << 16) | (pixels[..., 1] << 8) | pixels[..., 2]


def colour_mask(pixels, colours):
    return np.isin(_packed(pixels), _packed(np.atleast_2d(colours)))


def sprite_bbox(frame):
    """Return (top, bottom, left, right) inclusive of the agent's pixels in the play area."""
    rows, cols = np.nonzero(colour_mask(frame[PLAY_TOP:], SPRITE_COLOURS))
    if len(rows) == 0:
        return None
    return rows.min() + PLAY_TOP, rows.max() + PLAY_TOP, cols.min(), cols.max()


def hats_in_hud(frame):
    """Count the hat icons (one per life left) in the HUD."""
    columns = np.any(colour_mask(frame[LIVES_ROWS], HAT_COLOUR), axis=0)
    return int(columns[0]) + int(np.sum(columns[1:] & ~columns[:-1]))


def room_one_likeness(frame, reference):
    """Fraction of play-area pixels equal to a Room 1 frame."""
    return float(np.mean(np.all(frame[PLAY_TOP:] == reference[PLAY_TOP:], axis=2)))


def make_env(**overrides):
    config = EnvConfig(**{'warmup_steps': 0, **overrides})
    return MontezumaEnv(config)


@pytest.fixture
def env():
    environment = make_env()
    yield environment
    environment.close()


# -- the RAM -> pixel mapping ------------------------------------------------------------------

def standing_sprite(x, y):
    """``(top, bottom, left, right)``, inclusive, of the standing sprite at RAM ``(x, y)``."""
    return 308 - y, 327 - y, x - 1, x + 6  # as measured; the env README's table


def test_standing_sprite_is_where_the_ram_position_says_at_the_start(env):
    step = env.reset()
    assert sprite_bbox(step.observation) == standing_sprite(step.state.x, step.state.y)


@pytest.mark.parametrize('action', [RIGHT, LEFT], ids=['right', 'left'])
def test_walking_moves_sprite_columns_with_ram_x(env, action):
    previous = env.reset()  # x = 77 on the middle platform, which spans x = 63 .. 87
    for _ in range(3):
        step = env.step(action)
        before, after = sprite_bbox(previous.observation), sprite_bbox(step.observation)
        dx = step.state.x - previous.state.x
        assert np.sign(dx) == (1 if action == RIGHT else -1)
        assert abs((after[2] - before[2]) - dx) <= 2  # walking frames shift by a pixel or two
        assert step.state.y == previous.state.y and abs(after[1] - before[1]) <= 1
        previous = step


def test_climbing_down_moves_sprite_rows_against_ram_y(env):
    env.reset()  # the agent starts on top of the middle ladder
    first = env.step(DOWN)  # from the standing to the climbing pose
    previous = first.state, sprite_bbox(first.observation)
    for _ in range(5):
        step = env.step(DOWN)
        bbox = sprite_bbox(step.observation)
        dy = step.state.y - previous[0].y
        assert dy < 0 and step.state.x == previous[0].x
        assert bbox[1] - previous[1][1] == -dy  # one RAM unit of y is one row, downwards
        previous = step.state, bbox


def test_ram_position_predicts_sprite_over_random_play():
    env = make_env(seed=3)
    rng = np.random.default_rng(1)
    step = env.reset()
    errors, inside = [], []
    for _ in range(1000):
        step = env.step(int(rng.integers(18)))
        if step.done:
            step = env.reset()
            continue
        bbox = sprite_bbox(step.observation)
        if step.life_lost or bbox is None:
            continue
        top, bottom, left, right = standing_sprite(step.state.x, step.state.y)
        errors.append(((bbox[2] + bbox[3] - left - right) / 2,
                       (bbox[0] + bbox[1] - top - bottom) / 2))
        # Walking, jumping, climbing and dying frames stay within 3 pixels of it.
        inside.append(top - 3 <= bbox[0] and bbox[1] <= bottom + 3
                      and left - 3 <= bbox[2] and bbox[3] <= right + 3)
    env.close()
    errors = np.array(errors)
    assert len(errors) > 600
    assert np.all(np.abs(errors.mean(axis=0)) < 1.0)  # no offset left in the mapping
    assert np.mean(np.all(np.abs(errors) <= 3.0, axis=1)) > 0.95  # jumps lift it 2 or 3 rows
    assert np.mean(inside) > 0.95


# -- lives, game over, room, key ---------------------------------------------------------------

def test_lives_drop_on_a_fall_as_the_hud_shows_until_game_over(env):
    step = env.reset()
    assert step.state.lives == hats_in_hud(step.observation) == 5
    losses = []
    for _ in range(400):  # walking right off the middle platform is a deadly fall, every life
        previous_lives = step.state.lives
        step = env.step(RIGHT)
        assert hats_in_hud(step.observation) == step.state.lives
        if step.life_lost:
            losses.append(previous_lives - step.state.lives)
            assert step.state.y < 235  # it fell from the platform (y = 235) before dying
        if step.done:
            break
    assert step.terminated and not step.truncated and step.life_lost
    assert losses == [1, 1, 1, 1, 1, 0]  # the last death ends the game with lives at 0
    assert step.state.lives == 0
    with pytest.raises(RuntimeError):
        env.step(NOOP)
    assert env.reset().state.lives == 5


def test_end_on_life_loss_terminates_at_the_first_death():
    env = make_env(end_on_life_loss=True)
    env.reset()
    for _ in range(100):
        step = env.step(RIGHT)
        if step.done:
            break
    env.close()
    assert step.terminated and step.life_lost and step.state.lives == 4


def walk_out_through_the_left_door(env):
    """Give the agent the key on the upper-left floor and walk left; return the steps."""
    env.reset()
    env.step(NOOP)
    env.ale.setRAM(RAM_X, 20)
    env.ale.setRAM(RAM_INVENTORY, int(env.ale.getRAM()[RAM_INVENTORY]) | 0x02)
    steps = [env.step(NOOP)]
    while not steps[-1].done and len(steps) < 30:
        steps.append(env.step(LEFT))
    return steps


def test_room_changes_when_the_frame_shows_another_room(env):
    reference = env.reset().observation
    steps = walk_out_through_the_left_door(env)
    in_room_one = [s for s in steps if s.state.room == 1]
    assert in_room_one and all(room_one_likeness(s.observation, reference) > 0.95
                               for s in in_room_one)
    last = steps[-1]
    assert last.state.room != 1 and room_one_likeness(last.observation, reference) < 0.8
    assert last.truncated and not last.terminated
    assert steps[-2].state.room == 1  # the room changes at the very step the screen does


def test_key_bit_is_the_key_in_the_hud_and_the_door_takes_it(env):
    steps = walk_out_through_the_left_door(env)
    carrying = [s for s in steps if s.state.has_key]
    assert carrying and all(np.any(colour_mask(s.observation[INVENTORY_ROWS], KEY_COLOUR))
                            for s in carrying)
    assert not steps[-1].state.has_key  # the door used it up ...
    assert not np.any(colour_mask(steps[-1].observation[INVENTORY_ROWS], KEY_COLOUR))
    assert steps[-1].episode_return == sum(s.reward for s in steps) > 0  # ... for 300 points


def test_room_exit_can_be_allowed():
    env = make_env(end_on_room_exit=False)
    steps = walk_out_through_the_left_door(env)
    env.close()
    assert steps[-1].state.room != 1 and not steps[-1].done


def test_steps_carry_the_action_applied_and_resets_none():
    env = make_env()
    first = env.reset()
    step = env.step(5)
    assert (first.action, step.action) == (NO_ACTION, 5)
    env.close()


def test_the_pose_shows_the_agent_climbing_the_ladder_and_walking():
    # A fresh game: the agent stands on the top floor; DOWN at the ladder takes it onto the
    # ladder (climbing pose), RIGHT on the platform below walks.
    env = make_env(warmup_steps=0)
    step = env.reset()
    assert step.state.pose in STANDING_POSES
    poses = [env.step(5).state.pose for _ in range(4)]
    assert poses[-1] == 10 and all(p in STANDING_POSES for p in poses)
    env.close()


def test_read_ram_state_decodes_the_addresses():
    ram = np.zeros(128, np.uint8)
    ram[[42, 43, 3, 58, 65, 53, 47]] = [77, 235, 1, 5, 0x02 | 0x40, 10, 36]
    assert read_ram_state(ram) == RamState(x=77, y=235, room=1, lives=5, has_key=True,
                                           pose=10, skull_x=36)
    ram[65] = 0xFD
    assert not read_ram_state(ram).has_key


# -- determinism, warm-up, time ----------------------------------------------------------------

def rollout(seed, warmup_steps=20, steps=30):
    env = make_env(seed=seed, warmup_steps=warmup_steps)
    start = env.warm_up()
    rng = np.random.default_rng(7)
    trace = [env.step(int(rng.integers(18))) for _ in range(steps)]
    env.close()
    return start, trace


def test_same_seed_same_warm_up_and_steps():
    (start_a, trace_a), (start_b, trace_b) = rollout(0), rollout(0)
    assert start_a.state == start_b.state
    np.testing.assert_array_equal(start_a.observation, start_b.observation)
    assert [s.state for s in trace_a] == [s.state for s in trace_b]
    assert all(np.array_equal(a.observation, b.observation) for a, b in zip(trace_a, trace_b))


def test_warm_up_is_random_per_seed_and_not_counted_as_agent_steps():
    starts = [rollout(seed, warmup_steps=100, steps=0)[0] for seed in (0, 1, 2)]
    assert len({s.state for s in starts}) > 1  # different random warm-ups
    for start in starts:
        assert start.agent_step == 0
        assert start.sim_time_ns == frames_to_ns((100 + 1) * 4)  # reset + 100 steps of 4 frames


def test_sim_time_strictly_increases_across_steps_and_resets():
    env = make_env(frameskip=2)
    step = env.reset()
    stamps, episodes = [step.sim_time_ns], {step.episode}
    while len(episodes) < 2 and len(stamps) < 1000:  # walk off the platform until game over
        step = env.reset() if step.done else env.step(RIGHT)
        stamps.append(step.sim_time_ns)
        episodes.add(step.episode)
    for _ in range(5):
        stamps.append(env.step(NOOP).sim_time_ns)
    env.close()
    assert len(episodes) == 2  # a game over and a reset happened on the way
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert stamps[1] - stamps[0] == frames_to_ns(4) - frames_to_ns(2)  # 2 frames at 60 Hz


def test_observations_are_fresh_rgb_frames(env):
    first = env.reset().observation
    second = env.step(NOOP).observation
    assert first.shape == (FRAME_HEIGHT, FRAME_WIDTH, 3) and first.dtype == np.uint8
    assert not np.shares_memory(first, second)


@pytest.mark.parametrize('config, error', [
    ({'frameskip': 0}, ValueError), ({'sticky_actions': 1.5}, ValueError),
    ({'sticky_actions': -0.1}, ValueError), ({'warmup_steps': -1}, ValueError)])
def test_bad_config_is_refused(config, error):
    with pytest.raises(error):
        make_env(**config)


@pytest.mark.parametrize('action', [-1, 18, 99])
def test_out_of_range_action_is_refused(env, action):
    env.reset()
    with pytest.raises(ValueError):
        env.step(action)


def test_step_before_reset_is_refused(env):
    with pytest.raises(RuntimeError):
        env.step(NOOP)


# -- env_status key-values ---------------------------------------------------------------------

def test_status_values_round_trip(env):
    step = env.reset()
    values = status_values(step, Counters(timeouts=2, dropped_actions=3, bad_actions=1), True)
    assert [key for key, _ in values] == list(STATUS_KEYS)
    parsed = parse_status(values)
    assert parsed['lives'] == 5 and parsed['room'] == 1 and parsed['has_key'] is False
    assert parsed['timeouts'] == 2 and parsed['dropped_actions'] == 3
    assert parsed['bad_actions'] == 1
    assert parsed['finished'] is True and parsed['terminated'] is False
    assert parsed['reward'] == 0.0 and parsed['agent_step'] == step.agent_step
    assert parsed['action_latency_ms'] == NO_LATENCY  # no answer led to this step
    timed = parse_status(status_values(step, Counters(), False, action_latency_ms=4.56789))
    assert timed['action_latency_ms'] == 4.568 and timed['finished'] is False
    assert parse_status([('extra', 'text')]) == {'extra': 'text'}


# -- the node's parameters -----------------------------------------------------------------

def test_node_config_is_the_task_and_the_nodes_each_documented():
    names = [f.name for f in fields(EnvNodeConfig)]
    assert names[0] == 'task' and EnvNodeConfig().task == 'montezuma'
    assert not set(names) & {f.name for f in fields(EnvConfig)}  # the world's: from the task
    assert 'env_id' not in names and 'start_room' not in names  # fixed, not parameters
    for cls in (EnvNodeConfig, EnvConfig):
        docs = field_docs(cls)
        assert all(docs.get(f.name) for f in fields(cls))


@pytest.mark.parametrize('values, message', [
    ({'rate_hz': -1.0}, 'rate_hz must be >= 0'), ({'action_timeout': 0.0}, 'action_timeout > 0'),
    ({'max_steps': -1}, 'max_steps >= 0'),
])
def test_node_config_says_which_value_is_wrong(values, message):
    with pytest.raises(ValueError, match=message):
        EnvNodeConfig(**values).validate()

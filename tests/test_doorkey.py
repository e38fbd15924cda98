"""The DoorKey task's pure core on the real MiniGrid level: layouts, expert, progress, words."""

from attention_tasks.doorkey.expert import DROP, next_action, PICKUP, TOGGLE
from attention_tasks.doorkey.language import sentence
from attention_tasks.doorkey.world import (
    DistractorDoorKeyEnv, DoorKeyConfig, progress, state_of)
from attention_tasks.gridworld import observe
import numpy as np
import pytest

SEEDS = range(40)


def play_expert(env, limit=400):
    """Play the expert to the goal; return the sub-goal count after each step."""
    seen = []
    for _ in range(limit):
        action = next_action(env)
        assert action is not None, 'the expert found no way'
        _, reward, terminated, truncated, _ = env.step(action)
        seen.append(progress(state_of(env)))
        if terminated:
            assert reward > 0
            return seen
        assert not truncated
    raise AssertionError('the expert did not reach the goal')


def test_the_layout_changes_every_episode():
    env = DistractorDoorKeyEnv()
    layouts = set()
    for seed in SEEDS:
        env.reset(seed=seed)
        layouts.add((env.door.color, tuple(env.door.cur_pos), env.goal_pos,
                     tuple(env.key.cur_pos), tuple(env.agent_pos)))
    assert len(layouts) == len(SEEDS)
    colors = {layout[0] for layout in layouts}
    assert len(colors) >= 5  # the door's colour too: which pixels matter changes


def test_distractors_are_of_the_other_colours_and_frames_are_large_enough():
    env = DistractorDoorKeyEnv(DoorKeyConfig(distractors=4), render_mode='rgb_array')
    env.reset(seed=3)
    objects = [c for c in env.grid.grid if c is not None and c.type in ('key', 'ball', 'box')]
    assert len(objects) == 5  # the door's key and four distractors
    assert [o for o in objects if o.color == env.door.color] == [env.key]
    frame = env.render()
    assert frame.shape == (8 * 16, 8 * 16, 3) and frame.dtype == np.uint8
    view = observe(env)  # the agent's own: 7 x 7 cells of 16 px, the agent at the bottom centre
    assert view.shape == (7 * 16, 7 * 16, 3) and view.dtype == np.uint8
    agent_tile = view[6 * 16:, 3 * 16:4 * 16]
    assert (agent_tile[..., 0] > 200).sum() > 30 and (agent_tile[..., 1] > 150).sum() == 0  # red


def test_the_agents_view_turns_with_it():
    env = DistractorDoorKeyEnv()
    env.reset(seed=5)
    before = observe(env)
    env.step(0)  # left: the world turns right in the agent's view, the agent stays put
    after = observe(env)
    assert not np.array_equal(before, after)
    assert np.array_equal(before[6 * 16:, 3 * 16:4 * 16], after[6 * 16:, 3 * 16:4 * 16])


@pytest.mark.parametrize('seed', SEEDS)
def test_the_expert_takes_the_key_opens_the_door_and_reaches_the_goal(seed):
    env = DistractorDoorKeyEnv()
    env.reset(seed=seed)
    assert progress(state_of(env)) == 0
    seen = play_expert(env)
    assert seen[-1] == 3
    assert seen == sorted(seen)  # sub-goals in order, none undone
    assert {1, 2} <= set(seen)


def test_the_expert_recovers_from_any_state():
    """Random play first (distractors picked up, the key dropped elsewhere), then the expert."""
    rng = np.random.default_rng(0)
    for seed in range(15):
        env = DistractorDoorKeyEnv()
        env.reset(seed=100 + seed)
        terminated = False
        for _ in range(60):
            _, _, terminated, _, _ = env.step(int(rng.integers(0, 6)))
            if terminated:
                break
        if not terminated:
            assert play_expert(env)[-1] == 3


def test_the_expert_drops_a_distractor_before_it_takes_the_key():
    env = DistractorDoorKeyEnv(DoorKeyConfig(distractors=8))
    for seed in range(200):  # find a start that faces a distractor
        env.reset(seed=seed)
        ahead = env.grid.get(*env.front_pos)
        if ahead is not None and ahead.type in ('ball', 'key') and ahead is not env.key:
            break
    else:
        pytest.skip('no start facing a distractor in 200 layouts')
    env.step(PICKUP)
    assert state_of(env).carrying and not state_of(env).has_key
    assert sentence(state_of(env)).startswith('drop the ')
    actions = []
    while state_of(env).carrying and not state_of(env).has_key:
        actions.append(next_action(env))
        env.step(actions[-1])
        assert len(actions) < 20
    assert actions[-1] == DROP


def test_sentences_name_the_next_subgoal_with_its_colour():
    env = DistractorDoorKeyEnv()
    env.reset(seed=7)
    color = env.door.color
    said = [sentence(state_of(env))]
    while True:
        action = next_action(env)
        _, _, terminated, _, _ = env.step(action)
        if terminated:
            break
        said.append(sentence(state_of(env)))
        if action == TOGGLE:
            assert state_of(env).door_open
    order = list(dict.fromkeys(said))
    assert order == [f'pick up the {color} key', f'open the {color} door',
                     'go to the green square']


@pytest.mark.parametrize('config, message', [
    (DoorKeyConfig(size=6), 'size'), (DoorKeyConfig(distractors=99), 'distractors'),
    (DoorKeyConfig(max_episode_steps=-1), 'max_episode_steps')])
def test_bad_configs_say_what_is_wrong(config, message):
    with pytest.raises(ValueError, match=message):
        DistractorDoorKeyEnv(config)


def test_a_world_made_not_to_render_plays_the_same_without_frames():
    """Tools that only measure play (the study's chance levels) skip rendering, not the game."""
    from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
    seen = DoorKeyEnv(DoorKeyEnvConfig(seed=3))
    blind = DoorKeyEnv(DoorKeyEnvConfig(seed=3), render=False)
    rng = np.random.default_rng(0)
    steps = [(seen.reset(), blind.reset())]
    for _ in range(60):
        action = int(rng.integers(6))
        pair = tuple(env.reset() if step.done else env.step(action)
                     for env, step in zip((seen, blind), steps[-1]))
        steps.append(pair)
    assert all(a.state == b.state and a.reward == b.reward and a.done == b.done
               for a, b in steps)
    assert steps[-1][0].observation.shape == (112, 112, 3)
    assert all(b.observation is None for _, b in steps)
    seen.close()
    blind.close()

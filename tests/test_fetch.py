"""Fetch, where only words say the goal: the room, held-out targets, the expert, the teacher."""

from attention_tasks.fetch.env import FetchEnv, FetchEnvConfig
from attention_tasks.fetch.expert import moves_after, next_action, plan_length
from attention_tasks.fetch.task import TASK
from attention_tasks.fetch.world import (
    HELDOUT_TARGETS, KINDS, PAIRS, phrase, state_of, TRAINING_PAIRS)
from attention_tasks.gridworld import FORWARD, LEFT, observe, PICKUP, RIGHT
from attention_tasks.task import load_task
from feedback_node.config import FeedbackConfig
from minigrid.core.constants import COLOR_NAMES
import numpy as np
import pytest
from saliency_node.grounding import Grounder
from saliency_node.manifest import load_manifest


def room(env):
    """Return the colour-kind pairs of the objects in the room."""
    grid = env.world.grid
    return {(obj.color, obj.type) for obj in grid.grid if obj is not None and obj.type in KINDS}


def test_held_out_targets_never_show_in_training_and_are_the_targets_after():
    assert len(HELDOUT_TARGETS) == 6 and len(TRAINING_PAIRS) == 12
    assert sorted(c for c, _ in HELDOUT_TARGETS) == sorted(COLOR_NAMES)
    env = FetchEnv(FetchEnvConfig(seed=3, heldout_after=40))
    try:
        targets = {False: set(), True: set()}
        for _ in range(60):
            step = env.reset()
            for _ in range(5):
                step = env.step(LEFT)
            state = step.state
            targets[state.heldout].add(state.target)
            assert len(room(env)) == env.config.objects
            assert tuple(state.target.split()) in room(env)
            if not state.heldout:
                assert not room(env) & set(HELDOUT_TARGETS)  # not even as a distractor
    finally:
        env.close()
    assert targets[False] and targets[True]
    assert targets[True] <= {phrase(*pair) for pair in HELDOUT_TARGETS}
    assert not targets[False] & targets[True]


def test_nothing_in_the_frame_says_which_object_is_the_target():
    env = FetchEnv(FetchEnvConfig(seed=5))
    try:
        env.reset()
        before = observe(env.world)
        others = sorted(room(env) - {env.world.target})
        env.world.target = others[0]  # the same room, another object named
        assert np.array_equal(observe(env.world), before)
        assert state_of(env.world).target == phrase(*others[0])
    finally:
        env.close()


@pytest.mark.parametrize('seed', [0, 1])
def test_the_expert_fetches_the_target_from_every_layout(seed):
    env = FetchEnv(FetchEnvConfig(seed=seed, heldout_after=100))
    try:
        for _ in range(40):
            step = env.reset()
            planned = plan_length(step.state)
            for taken in range(1, 100):
                step = env.step(next_action(step.state))
                if step.done:
                    break
            assert step.terminated and step.state.fetched and step.reward > 0
            assert taken == planned  # the plan's length is the expert's own count
    finally:
        env.close()


def teacher_and_step(seed=2):
    env = FetchEnv(FetchEnvConfig(seed=seed))
    teacher = FeedbackConfig(task='fetch', trainer='teacher',
                             utterance_interval=-1.0).make_trainer()
    return env, teacher


def see(teacher, step):
    values = dict(step.state.status(), action=step.action, episode=step.episode,
                  agent_step=step.agent_step)
    return teacher.on_step(teacher.see(step.sim_time_ns, values))


def test_the_teacher_calls_the_expert_good_and_a_wrong_pickup_bad():
    env, teacher = teacher_and_step()
    try:
        step = env.reset()
        see(teacher, step)
        verdicts = []
        while True:  # the expert's own actions, to the target
            step = env.step(next_action(step.state))
            verdicts += [f.h for f in see(teacher, step).feedback]
            if step.done:
                break
        assert verdicts and set(verdicts) == {1.0}
        wrong_pickups = 0
        for _ in range(200):  # layouts that start the agent facing another object
            step = env.reset()
            see(teacher, step)
            obj = env.world.grid.get(*env.world.front_pos)
            if obj is None or obj.type not in KINDS or step.state.fetched:
                continue
            if phrase(obj.color, obj.type) == step.state.target:
                continue
            step = env.step(PICKUP)
            assert step.done and not step.state.fetched and step.reward == 0.0
            assert [f.h for f in see(teacher, step).feedback] == [-1.0]
            wrong_pickups += 1
        assert wrong_pickups >= 3
    finally:
        env.close()


def test_a_move_away_from_the_target_is_bad_and_an_equal_way_is_good():
    knowledge = FeedbackConfig(task='fetch', trainer='teacher').make_trainer().knowledge
    env = FetchEnv(FetchEnvConfig(seed=9))
    try:
        judged = {True: 0, False: 0}
        for _ in range(30):
            state = env.reset().state
            expert = next_action(state)
            if expert == PICKUP:
                continue
            for action in (LEFT, RIGHT, FORWARD, PICKUP):
                good = knowledge.as_good(state, action, expert)
                judged[good] += 1
                if action != expert and action != PICKUP:
                    assert good == (moves_after(state, [action])
                                    <= moves_after(state, [expert]))
                if action == PICKUP:
                    assert not good  # nothing, or the wrong thing, in front
    finally:
        env.close()
    assert judged[True] and judged[False]


def test_the_mission_is_said_at_the_first_step_of_every_episode():
    env = FetchEnv(FetchEnvConfig(seed=4))
    teacher = FeedbackConfig(task='fetch', trainer='teacher',
                             utterance_interval=1000.0).make_trainer()
    try:
        for _ in range(3):
            step = env.reset()
            said = see(teacher, step).utterance
            assert said.text == f'pick up the {step.state.target}'
            assert see(teacher, env.step(LEFT)).utterance is None  # the interval is long
    finally:
        env.close()


@pytest.mark.parametrize('color, kind', PAIRS)
def test_every_colour_kind_phrase_grounds_to_its_object_alone(color, kind):
    grounder = Grounder.from_manifest(load_manifest(TASK.manifest))
    grounding = grounder.ground(f'pick up the {color} {kind}')
    assert grounding.named == (f'{color} {kind}',)


def test_the_task_loads_by_name_with_the_shared_minigrid_parts():
    task = load_task('fetch')
    assert task.num_actions == 6 and task.frame_shape == (112, 112)
    assert task.heldout_layouts and task.milestones == ('reached', 'fetched')
    assert task.solved({'fetched': True}) and not task.solved({'fetched': False})


def test_a_step_gives_every_node_what_it_reads():
    env = FetchEnv(FetchEnvConfig(seed=1))
    try:
        step = env.reset()
        x, y, z = step.state.position()  # agent_position
        assert (x, y, z) == (step.state.x, step.state.y, 0.0)
        status = step.state.status()
        assert {'x', 'y', 'direction', 'carrying', 'target', 'fetched', 'grid', 'layout',
                'heldout'} <= set(status)
        assert step.observation.shape == TASK.frame_shape + (3,)
    finally:
        env.close()


def test_every_held_out_target_is_grounded_to_its_object_in_the_frames():
    """
    The mission's mask hits the target, and only it, in 99 % of the frames showing it.

    Issue 25's grounding target: held-out pairs, the expert with random moves.
    """
    from saliency_node.manifest import load_backdrops, load_template_images
    from saliency_node.matching import build_objects
    from saliency_node.saliency import SaliencyConfig, SaliencyMaker
    from test_saliency_doorkey import TILE, truth
    manifest = load_manifest(TASK.manifest)
    maker = SaliencyMaker(build_objects(manifest, load_template_images(manifest),
                                        load_backdrops(manifest)),
                          manifest.search_region, manifest.background)
    grounder = Grounder.from_manifest(manifest)
    env = FetchEnv(FetchEnvConfig(seed=31, heldout_after=1, max_episode_steps=40))
    rng = np.random.default_rng(31)
    env.reset()
    env.step(LEFT)  # past heldout_after: every episode from here has a held-out target
    shown, hit, targets = 0, 0, set()
    try:
        for _ in range(18):
            step = env.reset()
            target = step.state.target
            named = grounder.ground(f'pick up the {target}').objects
            while not step.done:
                where = truth(env.world)
                scene = maker.observe(step.observation)
                image, mask = maker.render(step.observation, scene, named,
                                           SaliencyConfig(mode='mask'))
                if target in where:
                    shown += 1
                    targets.add(target)
                    cells = {name: [mask[y:y + TILE, x:x + TILE].any() for x, y in places]
                             for name, places in where.items() if name != 'agent'}
                    hit += all(cells[target]) and not any(
                        any(found) for name, found in cells.items() if name != target)
                action = next_action(step.state)
                if action is None or action == PICKUP or rng.random() < 0.3:
                    action = int(rng.choice([LEFT, RIGHT, FORWARD]))
                step = env.step(action)
    finally:
        env.close()
    assert targets == {phrase(*pair) for pair in HELDOUT_TARGETS}
    assert shown >= 200 and hit >= 0.99 * shown, (hit, shown)

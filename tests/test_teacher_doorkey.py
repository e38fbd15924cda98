"""
The DoorKey teacher (feedback_node.task_teacher with attention_tasks.doorkey.teaching).

On the real level (``DoorKeyEnv``, as env_node steps it, its statuses as env_node publishes
them): the expert's own actions are all good, wasted ones bad, the other turn as good when it is
as short (checked against the expert played to the goal on copies of the level), stamps, gaps,
the human-like knobs, the sentences, bad statuses, and the node's choice of trainer by task.
"""

import copy
import itertools

from attention_tasks.doorkey import teaching
from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
from attention_tasks.doorkey.expert import (
    DROP, FORWARD, LEFT, next_action, PICKUP, RIGHT, TOGGLE)
from attention_tasks.doorkey.world import DistractorDoorKeyEnv, DoorKeyConfig, progress, state_of
from attention_tasks.gridworld import STEP_S
from attention_tasks.montezuma.teaching import RoomOneKnowledge
from attention_tasks.task import Step
from env_node.status import Counters, parse_status, status_values
from feedback_node.config import FeedbackConfig
from feedback_node.human_like import HUMAN_LIKE_SETTING
from feedback_node.judging import TeacherConfig
from feedback_node.task_teacher import load_knowledge, TaskTeacher, UnknownTeacher
from feedback_node.trainer import SyntheticTrainer
import numpy as np
import pytest

STEP_NS = int(round(STEP_S * 1e9))
QUIET = TeacherConfig(utterance_interval=-1.0)


def values_of(step: Step) -> dict:
    return parse_status(status_values(step, Counters(), False))


def make_teacher(config: TeacherConfig = QUIET) -> TaskTeacher:
    return TaskTeacher(load_knowledge('doorkey'), 6, config)


def play(teacher, steps, seed=0, wrong=lambda world, rng: None, skip=lambda step: False):
    """
    Play ``steps`` of the level: the expert, or ``wrong(world, rng)`` when that gives an action.

    The teacher sees every step but those ``skip`` drops. Return the feedback it gave, the
    ``(utterance, step)`` it said, ``{stamp: (action, expert action, deliberately wrong, agent
    step)}`` of the steps acted on, and the goals reached.
    """
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed))
    rng = np.random.default_rng(seed)
    feedback, utterances, played, goals = [], [], {}, 0
    step = env.reset()

    def see(step):
        if not skip(step):
            out = teacher.on_step(teacher.see(step.sim_time_ns, values_of(step)))
            feedback.extend(out.feedback)
            utterances.extend([(out.utterance, step)] if out.utterance else [])

    try:
        for _ in range(steps):
            see(step)
            expert_action = next_action(env.world)
            action = wrong(env.world, rng)
            assert expert_action is not None or action is not None, 'the expert has no action'
            played[step.sim_time_ns] = (expert_action if action is None else action,
                                        expert_action, action is not None, step.agent_step)
            step = env.step(played[step.sim_time_ns][0])
            if step.done:
                goals += int(step.terminated)
                see(step)
                step = env.reset()
        see(step)
    finally:
        env.close()
    return feedback, utterances, played, goals


def wasted(world, rng):
    """Every fourth step or so an action that changes nothing (the teacher must say -1)."""
    if rng.random() > 0.25:
        return None
    before = state_of(world)
    for action in rng.permutation(6):
        trial = copy.deepcopy(world)
        trial.step(int(action))
        if state_of(trial) == before:
            return int(action)
    return None


@pytest.mark.parametrize('seed', [0, 1])
def test_the_expert_s_own_actions_are_all_judged_good(seed):
    teacher = make_teacher()
    feedback, _, played, goals = play(teacher, 500, seed)
    counts = teacher.counts
    assert goals >= 15  # a new layout every episode
    assert counts['judged'] > 450 and counts['agreed'] == counts['judged']
    assert {f.h for f in feedback} == {1.0}
    assert counts['no_expert_action'] == 0 and counts['unjudged_resets'] == goals


def judge(world, action):
    """Return the teacher's judgements of ``action`` taken in ``world``'s state."""
    teacher = make_teacher()
    before, after = state_of(world), copy.deepcopy(world)
    after.step(action)
    steps = [Step(None, state, 0.0, False, False, False, 0, t, t, t * STEP_NS, action=a)
             for t, state, a in ((1, before, FORWARD), (2, state_of(after), action))]
    teacher.on_step(teacher.see(steps[0].sim_time_ns, values_of(steps[0])))
    return teacher.on_step(teacher.see(steps[1].sim_time_ns, values_of(steps[1]))).feedback


def states(predicate, seeds=range(60), distractors=6):
    """Yield the expert's play on real levels where ``predicate(world, expert action)``."""
    for seed in seeds:
        world = DistractorDoorKeyEnv(DoorKeyConfig(distractors=distractors))
        world.reset(seed=seed)
        for _ in range(40):
            expert_action = next_action(world)
            if expert_action is None:
                break
            if predicate(world, expert_action):
                yield world, expert_action
            _, _, terminated, _, _ = world.step(expert_action)
            if terminated:
                break


def ahead(world):
    return world.grid.get(*world.front_pos)


WASTED = {
    'pickup facing a wall': (PICKUP, lambda w, e: getattr(ahead(w), 'type', '') == 'wall'),
    'forward into a wall': (FORWARD, lambda w, e: getattr(ahead(w), 'type', '') == 'wall'),
    'toggle facing nothing': (TOGGLE, lambda w, e: ahead(w) is None),
    'drop holding nothing': (DROP, lambda w, e: w.carrying is None),
}
"""Actions that change nothing where they are taken: a step lost."""


@pytest.mark.parametrize('kind', sorted(WASTED))
def test_a_wasted_action_is_bad(kind):
    action, where = WASTED[kind]
    found = [judge(world, action) for world, _ in itertools.islice(states(where), 80)]
    assert len(found) >= 20, f'only {len(found)} states for {kind}'
    assert all([(f.h, f.action) for f in judged] == [(-1.0, action)] for judged in found)


def test_picking_up_a_distractor_is_bad_unless_it_clears_a_shorter_way():
    def facing_a_distractor(world, expert_action):
        front = ahead(world)
        return (expert_action != PICKUP and world.carrying is None and front is not world.key
                and getattr(front, 'type', '') in ('key', 'ball', 'box'))
    verdicts = []
    for world, expert_action in states(facing_a_distractor):
        [judgement] = judge(world, PICKUP)
        mine, theirs = copy.deepcopy(world), copy.deepcopy(world)
        mine.step(PICKUP)
        theirs.step(expert_action)
        verdicts.append((judgement.h, plan_length(mine) <= plan_length(theirs)))
    assert len(verdicts) >= 10
    assert all((h > 0) == shorter for h, shorter in verdicts)
    assert sum(h < 0 for h, _ in verdicts) >= 0.8 * len(verdicts)  # mostly a detour


def test_the_other_turn_is_as_good_when_the_target_is_behind():
    """The expert turns left twice (ties go to the lowest action): right, right is as short."""
    def behind(world, expert_action):
        if expert_action != LEFT:
            return False
        trial = copy.deepcopy(world)
        trial.step(LEFT)
        return next_action(trial) == LEFT
    found = [judge(world, RIGHT) for world, _ in states(behind)]
    assert len(found) >= 10
    assert all([(f.h, f.action, f.expert_action) for f in judged] == [(1.0, RIGHT, LEFT)]
               for judged in found)


def plan_length(world, limit=300):
    """Return the steps the expert takes to the goal on a copy of ``world``; inf: never."""
    world, seen = copy.deepcopy(world), set()
    for steps in range(limit):
        state = state_of(world)
        if state.at_goal:
            return steps
        if state in seen or next_action(world) is None:
            return float('inf')
        seen.add(state)
        world.step(next_action(world))
    return float('inf')


def test_as_good_is_a_plan_no_longer_than_the_expert_s_played_to_the_goal():
    """From states random play reached, every other action, against the expert to the goal."""
    rng = np.random.default_rng(5)
    verdicts = []
    for seed in range(25):
        world = DistractorDoorKeyEnv(DoorKeyConfig(distractors=int(rng.integers(0, 7))))
        world.reset(seed=1000 + seed)
        for _ in range(int(rng.integers(0, 40))):
            expert_action = next_action(world)
            random_play = expert_action is None or rng.random() < 0.4
            if world.step(int(rng.integers(6)) if random_play else expert_action)[2]:
                world.reset(seed=2000 + seed)
        world.step_count = 0
        state, expert_action = state_of(world), next_action(world)
        theirs = copy.deepcopy(world)
        theirs.step(expert_action)
        for action in set(range(6)) - {expert_action}:
            mine = copy.deepcopy(world)
            mine.step(action)
            shorter = plan_length(mine) <= plan_length(theirs) < float('inf')
            verdicts.append((teaching.KNOWLEDGE.as_good(state, action, expert_action), shorter))
    assert len(verdicts) >= 100
    assert all(got == want for got, want in verdicts)
    assert any(got for got, _ in verdicts)  # some other actions are as good


def test_after_is_minigrid_s_step_on_the_encoded_grid():
    rng = np.random.default_rng(2)
    checked = 0
    for seed in range(12):
        world = DistractorDoorKeyEnv(DoorKeyConfig(distractors=int(rng.integers(0, 9))))
        world.reset(seed=seed)
        for _ in range(40):
            state = state_of(world)
            for action in range(6):
                trial = copy.deepcopy(world)
                trial.step(action)
                assert teaching.after(state, action) == state_of(trial), (seed, action)
                checked += 1
            if world.step(int(rng.integers(6)))[2]:
                break
    assert checked > 1500


def test_the_judgement_of_t_carries_t_s_stamp_and_a_missed_step_is_not_judged():
    missed = {10, 25, 26, 60}  # agent steps whose status never arrives
    teacher = make_teacher()
    feedback, _, played, _ = play(teacher, 120, seed=3, wrong=wasted,
                                  skip=lambda step: step.agent_step in missed)
    by_stamp = {f.stamp_ns: f for f in feedback}
    assert len(by_stamp) == len(feedback)  # no step judged twice
    for stamp, judgement in by_stamp.items():
        action, expert_action, was_wrong, _ = played[stamp]
        assert judgement.seen_ns == stamp + STEP_NS  # seen at the next step, stamped this one
        assert (judgement.action, judgement.expert_action) == (action, expert_action)
        assert judgement.h == (-1.0 if was_wrong else 1.0)
    assert sum(p[2] for p in played.values()) >= 15
    # Missing step k: neither the action of k - 1 (reported at k) nor that of k is judged.
    assert teacher.counts['unjudged_gaps'] == 3  # 25 and 26 are one gap
    unjudged = {p[3] for stamp, p in played.items() if stamp not in by_stamp}
    assert unjudged == {9, 10, 24, 25, 26, 59, 60}


def test_the_human_like_setting_gives_a_third_late_and_some_wrong():
    teacher = make_teacher(TeacherConfig(utterance_interval=-1.0, seed=3,
                                         **vars(HUMAN_LIKE_SETTING)))
    feedback, _, played, _ = play(teacher, 2000, seed=4, wrong=wasted)
    judged = teacher.counts['judged']
    assert judged > 1800
    assert 0.28 < (len(feedback) + teacher.pending) / judged < 0.38
    flipped = [f for f in feedback if (f.h < 0) != played[f.stamp_ns][2]]
    assert flipped and all(f.flipped for f in flipped)
    assert 0.05 < len(flipped) / len(feedback) < 0.15
    assert all(f.seen_ns == f.stamp_ns + STEP_NS for f in feedback)


def test_sentences_follow_the_sub_goals_and_name_the_door_colour():
    teacher = make_teacher(TeacherConfig(utterance_interval=0.0))
    _, said, _, goals = play(teacher, 200, seed=5)
    assert goals >= 5
    for utterance, step in said:
        state = step.state
        assert utterance.position == -1 and utterance.sentence_of == progress(state)
        expected = {0: f'{state.door_color} key', 1: f'open the {state.door_color} door',
                    2: 'go to the green square'}[utterance.sentence_of]
        assert expected in utterance.text
    assert {u.sentence_of for u, _ in said} == {0, 1, 2}
    # Every step speaks (interval 0) but the goal's: the episode is over.
    assert not any(step.state.at_goal for _, step in said)
    assert len(said) == teacher.counts['steps'] - goals


def test_each_new_layout_is_named_at_its_first_step():
    teacher = make_teacher(TeacherConfig(utterance_interval=1000.0))
    _, said, _, goals = play(teacher, 150, seed=6)
    assert len(said) == goals + 1  # one per episode, the last one unfinished
    assert [(step.episode, step.episode_step) for _, step in said] == [
        (episode, 0) for episode in range(goals + 1)]
    assert all(u.text == f'pick up the {step.state.door_color} key' for u, step in said)


def test_the_expert_has_an_action_in_every_state_a_mostly_expert_agent_reaches():
    """The door's key lying in the way once the door is open used to leave it with none."""
    teacher = make_teacher()
    rng = np.random.default_rng(0)
    play(teacher, 1500, seed=0, wrong=lambda world, r: int(rng.integers(6)) if (
        rng.random() < 0.2) else None)
    assert teacher.counts['judged'] > 1400 and teacher.counts['no_expert_action'] == 0


def first_status():
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=0))
    try:
        return values_of(env.reset())
    finally:
        env.close()


GOOD = first_status()
BAD = {
    'no grid': {'grid': None}, 'no direction': {'direction': None},
    'no action': {'action': None}, 'no episode': {'episode': None},
    'grid not hex': {'grid': 'zz'}, 'grid too small': {'grid': '0102'},
    'grid not square': {'grid': GOOD['grid'][:-6]}, 'x on the wall': {'x': 0},
    'y off the grid': {'y': 9}, 'direction 4': {'direction': 4}, 'action 6': {'action': 6},
    'carrying a colour': {'carrying': 'purple'}, 'carrying lava': {'carrying': 'red lava'},
    'door pink': {'door_color': 'pink'},
}


@pytest.mark.parametrize('kind', sorted(BAD))
def test_a_bad_status_is_refused_with_a_key_or_value_error(kind):
    values = {k: v for k, v in dict(GOOD, **BAD[kind]).items() if v is not None}
    with pytest.raises((KeyError, ValueError)):
        make_teacher().see(0, values)


def test_a_grid_without_a_door_or_walls_is_refused():
    values = dict(GOOD)
    cells = bytearray.fromhex(values['grid'])
    no_door = bytes(cells).replace(bytes((4, cells[cells.index(4) + 1], 2)), bytes((2, 5, 0)))
    holed = bytearray(cells)
    holed[0:3] = bytes((1, 0, 0))
    for grid in (no_door.hex(), holed.hex()):
        with pytest.raises(ValueError):
            make_teacher().see(0, dict(values, grid=grid))
    assert make_teacher().see(0, values).state.grid == values['grid']


def test_the_task_chooses_the_trainer():
    assert isinstance(FeedbackConfig().make_trainer(), SyntheticTrainer)
    room_one = FeedbackConfig(trainer='teacher').make_trainer()
    assert isinstance(room_one, TaskTeacher) and isinstance(room_one.knowledge, RoomOneKnowledge)
    assert room_one.knowledge is not FeedbackConfig(trainer='teacher').make_trainer().knowledge
    assert room_one.SILENT == ('cannot_matter', 'after_key')  # an expert each, counted apart
    doorkey = FeedbackConfig(task='doorkey', trainer='teacher').make_trainer()
    assert isinstance(doorkey, TaskTeacher) and doorkey.knowledge is teaching.KNOWLEDGE
    assert doorkey.num_actions == 6
    with pytest.raises(ValueError, match="trainer 'thesis' measures Room 1"):
        FeedbackConfig(task='doorkey')
    with pytest.raises(ValueError, match='installed tasks: doorkey, fetch, montezuma'):
        FeedbackConfig(task='sokoban', trainer='teacher')
    with pytest.raises(UnknownTeacher, match='attention_tasks.sokoban.teaching'):
        load_knowledge('sokoban')

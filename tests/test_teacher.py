"""
Room 1's teacher: judges actions against the expert's, on real game states.

The one teacher (feedback_node.task_teacher) with Room 1's knowledge
(attention_tasks.montezuma.teaching).

The judging is checked twice: with hand-made steps (attribution, silence, the human-like knobs,
the utterances), and with the real emulator, where an agent that plays the expert is always
right and one that plays at random is mostly wrong.
"""

import ast
from pathlib import Path

from attention_common.joy_actions import ACTION_MEANINGS, NUM_ACTIONS
from attention_tasks.montezuma.action_effects import EffectTable, place_of, Situation
from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
from attention_tasks.montezuma.expert import Phase, RoomOneExpert
from attention_tasks.montezuma.sentences import SENTENCES
from attention_tasks.montezuma.teaching import RoomOneKnowledge, SeenStep, STAGE_SENTENCE
from attention_tasks.task import task_names
from feedback_node import task_teacher
from feedback_node.config import FeedbackConfig
from feedback_node.human_like import HUMAN_LIKE_SETTING
from feedback_node.judging import TeacherConfig
from feedback_node.task_teacher import TaskStep, TaskTeacher
import numpy as np
import pytest

A = {name: index for index, name in enumerate(ACTION_MEANINGS)}
NS = 66_666_667  # one agent step of simulation time (4 frames at 60 Hz)


def room_one_teacher(config=None, table=None) -> TaskTeacher:
    """Return the one teacher with Room 1's knowledge (the table: the shipped one)."""
    return TaskTeacher(RoomOneKnowledge(table), NUM_ACTIONS, config)


def seen(t, x, y, action, pose=8, episode=0, has_key=False, skull_x=40):
    return TaskStep(t * NS, action, episode, -1, SeenStep(x, y, has_key, pose, skull_x, action))


def game_step(step) -> TaskStep:
    """Return a step of the real game as the teacher sees it."""
    s = step.state
    return TaskStep(step.sim_time_ns, step.action, step.episode, -1,
                    SeenStep(s.x, s.y, s.has_key, s.pose, s.skull_x, step.action))


def test_judges_the_action_taken_at_t_when_t_plus_1_is_seen():
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0))
    # At the top of the middle ladder (77, 235) the expert climbs down.
    assert teacher.on_step(seen(0, 77, 235, action=-1)).feedback == []
    out = teacher.on_step(seen(1, 77, 231, action=A['DOWN'], pose=10))
    assert [(f.stamp_ns, f.h, f.action, f.expert_action, f.seen_ns) for f in out.feedback] == [
        (0, 1.0, A['DOWN'], A['DOWN'], NS)]
    # On the ladder, LEFT does not climb: -1, stamped with the step it was taken at.
    out = teacher.on_step(seen(2, 77, 231, action=A['LEFT'], pose=10))
    assert [(f.stamp_ns, f.h) for f in out.feedback] == [(NS, -1.0)]
    assert teacher.counts['judged'] == 2 and teacher.counts['agreed'] == 1


def test_equivalent_actions_count_as_the_expert_s_on_the_floor_not_on_a_ladder():
    table = EffectTable.load()
    floor = Situation(Phase.ACROSS_FLOOR.name, place_of(100, 148), 18, False)
    ladder = Situation(Phase.DOWN_MIDDLE_LADDER.name, place_of(77, 213), 10, False)
    assert table.equivalent(floor, A['LEFT'], A['UPLEFT'])
    assert table.equivalent(floor, A['LEFT'], A['DOWNLEFT'])
    assert not table.equivalent(floor, A['LEFT'], A['RIGHT'])
    assert not table.equivalent(floor, A['UPLEFT'], A['NOOP'])
    # On a ladder a diagonal does not climb: UPLEFT is NOOP there, not UP, not LEFT's walk.
    assert not table.equivalent(ladder, A['UP'], A['UPLEFT'])
    assert table.equivalent(ladder, A['UPLEFT'], A['NOOP'])
    assert table.equivalent(ladder, A['LEFT'], A['NOOP'])


def test_silent_while_dying_in_the_air_after_the_key_and_across_a_reset():
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0))
    teacher.on_step(seen(0, 100, 148, action=-1, pose=22))     # dying on the floor
    # Then in the air with the button held (it jumped): nothing it does changes the jump.
    assert teacher.on_step(seen(1, 97, 165, action=A['RIGHTFIRE'], pose=6)).feedback == []
    assert teacher.on_step(seen(2, 95, 160, action=A['LEFT'], pose=6)).feedback == []
    assert teacher.counts['cannot_matter'] == 2
    teacher.on_step(seen(3, 13, 192, action=A['LEFT'], has_key=True))
    assert teacher.on_step(seen(4, 17, 192, action=A['RIGHT'], has_key=True)).feedback == []
    assert teacher.counts['after_key'] == 1
    # A new episode: nothing caused the jump back to the start, so nothing is judged.
    assert teacher.on_step(seen(5, 77, 235, action=-1, episode=1)).feedback == []
    assert teacher.counts['unjudged_resets'] == 1


def test_a_missed_step_is_not_judged_with_the_wrong_action():
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0))
    teacher.on_step(seen(0, 77, 235, action=-1)._replace(agent_step=0))
    # Step 1's status never arrived: step 2 carries the action taken at 1, not at 0.
    out = teacher.on_step(seen(2, 77, 227, action=A['LEFT'], pose=10)._replace(agent_step=2))
    assert out.feedback == [] and teacher.counts['unjudged_gaps'] == 1
    out = teacher.on_step(seen(3, 77, 223, action=A['DOWN'], pose=10)._replace(agent_step=3))
    assert [(f.stamp_ns, f.h) for f in out.feedback] == [(2 * NS, 1.0)]


def test_stamps_that_go_back_start_the_teacher_over_and_re_sends_are_not_judged_twice():
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0))
    teacher.on_step(seen(5, 77, 235, action=-1))
    assert len(teacher.on_step(seen(6, 77, 231, action=A['DOWN'], pose=10)).feedback) == 1
    assert teacher.on_step(seen(6, 77, 231, action=A['DOWN'], pose=10)).feedback == []
    assert teacher.counts['duplicates'] == 1
    assert teacher.on_step(seen(1, 77, 235, action=-1)).feedback == []
    assert teacher.counts['restarts'] == 1


def walk(teacher, steps, seed=0):
    """Judge ``steps`` alternating right/wrong actions on the ladder; return every feedback."""
    rng = np.random.default_rng(seed)
    released = []
    teacher.on_step(seen(0, 77, 235, action=-1))
    for t in range(1, steps + 1):
        action = A['DOWN'] if rng.random() < 0.5 else A['LEFT']
        out = teacher.on_step(seen(t, 77, 231, action=action, pose=10))
        released += [(f, f.action) for f in out.feedback]
    return released


def test_the_human_like_setting_gives_a_third_late_and_some_wrong():
    knobs = vars(HUMAN_LIKE_SETTING)
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0, seed=3, **knobs))
    assert teacher.config.delayed
    released = walk(teacher, 3000)
    judged = teacher.counts['judged']
    assert 0.28 < (len(released) + teacher.pending) / judged < 0.38
    delays = [f.seen_ns - f.stamp_ns for f, _ in released]
    assert all(d == NS for d in delays)  # seen one step after the step judged
    wrong = [f for f, action in released if (f.h > 0) != (action == A['DOWN'])]
    assert wrong and all(f.flipped for f in wrong)
    assert 0.05 < len(wrong) / len(released) < 0.15


def test_a_marking_teacher_marks_its_share_and_otherwise_gives_the_same_verdicts():
    # feedback_marked: a person who pauses to judge; about the share asked is marked, none at
    # 0 (where it draws nothing, so the named setting's runs stay as they were).
    knobs = vars(HUMAN_LIKE_SETTING)
    runs = {}
    for marked in (0.0, 0.5):
        teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0, seed=3,
                                                 **dict(knobs, feedback_marked=marked)))
        runs[marked] = walk(teacher, 3000)
    plain, marking = runs[0.0], runs[0.5]
    assert not any(f.marked for f, _ in plain)
    share = sum(f.marked for f, _ in marking) / len(marking)
    assert 0.4 < share < 0.6, share
    with pytest.raises(ValueError, match='feedback_marked'):
        TeacherConfig(feedback_marked=1.5)


def test_delayed_feedback_is_released_between_0_3_and_1_5_s_after_it_was_seen():
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0, feedback_delay_min=0.3,
                                             feedback_delay_max=1.5))
    teacher.on_step(seen(0, 77, 235, action=-1))
    lags, presses = [], []
    for t in range(1, 400):
        out = teacher.on_step(seen(t, 77, 231, action=A['DOWN'], pose=10))
        lags += [t * NS - f.seen_ns for f in out.feedback]
        presses += [(f.pressed_ns - f.seen_ns, t * NS - f.pressed_ns) for f in out.feedback]
    assert lags and min(lags) >= 0.3e9 and max(lags) < 1.5e9 + NS
    # Each carries the moment it was given: its own delay after the step seen, before release.
    delays = [delay for delay, _ in presses]
    assert min(delays) >= 0.3e9 and max(delays) <= 1.5e9 and len(set(delays)) > 10
    assert all(0 <= waited < NS for _, waited in presses)


def test_speaks_the_sentence_of_the_stage_it_is_in_at_the_interval():
    teacher = room_one_teacher(TeacherConfig(utterance_interval=1.0))
    first = teacher.on_step(seen(0, 109, 205, action=-1, pose=4)).utterance  # on the rope
    assert first.text == SENTENCES[STAGE_SENTENCE[Phase.ON_ROPE]] == SENTENCES[1]
    quiet = [teacher.on_step(seen(t, 109, 205, action=0, pose=4)).utterance
             for t in range(1, 15)]
    assert quiet == [None] * 14  # 14 steps < 1 s
    # In the air after the rope the stage is still the rope's; then the right ladder's.
    assert teacher.on_step(seen(15, 120, 215, action=0, pose=6)).utterance.text == SENTENCES[1]
    for t in range(16, 30):
        teacher.on_step(seen(t, 133, 180, action=A['DOWN'], pose=10))
    assert teacher.on_step(seen(30, 133, 176, action=A['DOWN'], pose=10)).utterance.text == (
        SENTENCES[2])


def play(policy, seed, steps, teacher):
    """Play ``steps`` of the real game with ``policy(step, expert_action)``; teacher watches."""
    env = MontezumaEnv(EnvConfig(seed=seed))
    expert = RoomOneExpert()
    try:
        step = env.warm_up()
        expert.reset()
        for _ in range(steps):
            s = step.state
            teacher.on_step(game_step(step))
            action = policy(expert.act(s, s.skull_x))
            step = env.step(action)
            if step.done:
                teacher.on_step(game_step(step))
                step = env.reset()
                expert.reset()
    finally:
        env.close()


@pytest.mark.parametrize('seed', [31, 32])
def test_an_agent_that_plays_the_expert_is_always_right(seed):
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0))
    play(lambda expert_action: expert_action, seed, 300, teacher)
    counts = teacher.counts
    assert counts['after_key'] > 0  # the route was played to the key
    assert counts['judged'] > 40 and counts['agreed'] == counts['judged']


def test_an_agent_that_plays_at_random_is_mostly_wrong():
    rng = np.random.default_rng(5)
    teacher = room_one_teacher(TeacherConfig(utterance_interval=-1.0))
    play(lambda expert_action: int(rng.integers(NUM_ACTIONS)), 33, 400, teacher)
    counts = teacher.counts
    assert counts['judged'] > 100
    assert counts['agreed'] / counts['judged'] < 0.35


@pytest.mark.parametrize('task', task_names())
def test_every_task_is_taught_by_the_one_teacher_from_its_own_knowledge(task):
    teacher = FeedbackConfig(task=task, trainer='teacher').make_trainer()
    assert isinstance(teacher, TaskTeacher)
    assert type(teacher.knowledge).__module__ == f'attention_tasks.{task}.teaching'


def test_the_teacher_names_no_task():
    """feedback_node's teacher imports no task's module: a new task needs no edit of it."""
    package = Path(task_teacher.__file__).parent
    for name in ('task_teacher.py', 'judging.py', 'config.py', 'human_like.py'):
        tree = ast.parse((package / name).read_text())
        imported = [node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
        imported += [alias.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                     for alias in node.names]
        tasks = [m for m in imported if m.startswith('attention_tasks.')
                 and m != 'attention_tasks.task']
        assert tasks == [], (name, tasks)

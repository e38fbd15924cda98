"""
Questions (issue 23): the learner asks about the steps it is least sure of, the teacher answers.

The asking rule (tamer_node.questions), the agent that asks (no rclpy), and the teacher's answer
(feedback_node.judging): stamped with the step asked, about the action taken there, in either
order of question and judgement, never for a step the teacher is silent on, and not also given
late.
"""

from attention_common.joy_actions import ACTION_MEANINGS, NUM_ACTIONS
from attention_tasks.montezuma.teaching import RoomOneKnowledge, SeenStep
from feedback_node.human_like import HUMAN_LIKE_SETTING
from feedback_node.judging import TeacherConfig
from feedback_node.task_teacher import TaskStep, TaskTeacher
import numpy as np
import pytest
from tamer_node.agent import TamerAgent
from tamer_node.config import TamerConfig
from tamer_node.model import Encoder
from tamer_node.questions import Asker
import torch

A = {name: index for index, name in enumerate(ACTION_MEANINGS)}
NS = 66_666_667


def values(*top):
    """H of 18 actions: the given ones first, every other action at -1."""
    h = torch.full((18,), -1.0)
    h[:len(top)] = torch.tensor(top)
    return h


def test_it_asks_only_where_the_two_best_actions_are_close():
    asker = Asker(rate=1.0, margin=0.5)
    assert asker.consider(values(0.9, 0.1)) is None            # sure: a gap of 0.8
    assert asker.consider(values(0.3, 0.1)) == pytest.approx(0.2)
    # Beyond the feedback range H is extrapolation: 3.0 and 1.2 both read as 1, a tie.
    assert asker.consider(values(3.0, 1.2)) == pytest.approx(0.0)


def test_it_asks_at_most_its_rate_and_saves_only_a_burst():
    asker = Asker(rate=0.1, margin=0.5, burst=3.0)
    unsure = values(0.0, 0.0)
    asked = [asker.consider(unsure) is not None for _ in range(1000)]
    assert sum(asked) == 100 and not any(asked[:9])
    for _ in range(200):          # sure for 200 steps: 20 questions' worth, 3 kept
        assert asker.consider(values(1.0, -1.0)) is None
    burst = [asker.consider(unsure) is not None for _ in range(10)]
    assert burst[:3] == [True] * 3 and sum(burst) == 3
    for rate, margin, burst in ((0.0, 0.5, 5), (1.5, 0.5, 5), (0.1, 0.0, 5), (0.1, 0.5, 0.5)):
        with pytest.raises(ValueError):
            Asker(rate, margin, burst)


def test_a_budget_of_questions_is_spent_at_the_rate_from_the_start_then_it_asks_no_more():
    asker = Asker(rate=0.25, margin=0.5, burst=1.0, budget=30)
    unsure = values(0.0, 0.0)
    asked = [asker.consider(unsure) is not None for _ in range(1000)]
    assert sum(asked) == 30 and sum(asked[:120]) == 30  # the first 120 steps: 30 at 0.25
    assert not any(asked[120:]) and asker.asked == 30
    endless = Asker(rate=0.25, margin=0.5, burst=1.0)
    assert sum(endless.consider(unsure) is not None for _ in range(1000)) == 250
    with pytest.raises(ValueError, match='ask_budget'):
        TamerConfig(ask_rate=0.25, ask_budget=-1).validate()


def test_an_agent_that_asks_names_the_steps_it_acted_on(tmp_path):
    config = TamerConfig(ask_rate=0.5, ask_margin=2.5, update_rate_hz=0.0,
                         checkpoint_period_s=0.0, pace_updates=0.0)  # always unsure: the rate
    agent = TamerAgent(config, tmp_path / 'run', encoder=Encoder())
    agent.start()
    try:
        frames = np.random.default_rng(0).integers(0, 256, (20, 210, 160, 3), np.uint8)
        acted = {(i + 1) * NS: agent.on_observation((i + 1) * NS, frame)
                 for i, frame in enumerate(frames)}
        questions = agent.acting.take_questions()
        assert agent.acting.take_questions() == []  # taken once
    finally:
        agent.close()
    assert len(questions) == 10
    assert [stamp for stamp, _, _ in questions] == sorted(acted)[1::2]
    assert all(acted[stamp] == action for stamp, action, _ in questions)
    assert agent.metrics()['ask/asked'] == 10
    with pytest.raises(ValueError, match='ask_rate'):
        TamerConfig(ask_rate=1.5).validate()


def room_one(**knobs):
    return TaskTeacher(RoomOneKnowledge(None), NUM_ACTIONS, TeacherConfig(
        utterance_interval=-1.0, seed=5, **knobs))


def on_ladder(t, action):
    """Step t on the middle ladder (the expert climbs DOWN), reached by ``action``."""
    return TaskStep(t * NS, action, 0, t, SeenStep(77, 231, False, 10, 40, action))


def test_the_teacher_answers_the_step_asked_stamped_whichever_comes_first():
    # Late and sparse otherwise (the named human-like setting, no wrong signs): the answers
    # still come at once, stamped with the step asked, about the action taken there.
    teacher = room_one(**dict(vars(HUMAN_LIKE_SETTING), feedback_noise=0.0))
    teacher.on_step(on_ladder(0, -1))
    assert teacher.ask(1 * NS) == []                 # asked before step 1 is judged
    teacher.on_step(on_ladder(1, A['DOWN']))
    out = teacher.on_step(on_ladder(2, A['LEFT']))   # judges step 1's LEFT: wrong
    answers = [f for f in out.feedback if f.marked]
    assert [(f.stamp_ns, f.h, f.action, f.pressed_ns) for f in answers] == [
        (1 * NS, -1.0, A['LEFT'], 2 * NS)]
    teacher.on_step(on_ladder(3, A['DOWN']))         # judges step 2's DOWN: right
    [late] = teacher.ask(2 * NS)                     # asked after: answered at once
    assert (late.stamp_ns, late.h, late.marked) == (2 * NS, 1.0, True)
    later = []
    for t in range(4, 100):
        later += teacher.on_step(on_ladder(t, A['DOWN'])).feedback
    assert 1 * NS not in [f.stamp_ns for f in later]  # asked first: not judged late as well
    assert teacher.counts['questions'] == 2 and teacher.counts['answered'] == 2


def test_a_step_the_teacher_is_silent_on_gets_no_answer():
    teacher = room_one()
    dying = TaskStep(0, -1, 0, 0, SeenStep(100, 148, False, 22, 40, -1))  # on the floor
    teacher.on_step(dying)
    assert teacher.ask(0) == []  # nothing it does while dying changes anything
    in_the_air = SeenStep(97, 165, False, 6, 40, A['LEFT'])
    out = teacher.on_step(TaskStep(NS, A['LEFT'], 0, 1, in_the_air))
    assert out.feedback == [] and teacher.counts['cannot_matter'] == 1
    assert teacher.counts['answered'] == 0


def test_answers_carry_the_share_of_wrong_signs_a_person_gives():
    teacher = room_one(feedback_noise=0.1)
    teacher.on_step(on_ladder(0, -1))
    answers = []
    for t in range(1, 3001):
        teacher.ask((t - 1) * NS)  # asked about step t - 1, judged when step t is seen
        answers += [f for f in teacher.on_step(on_ladder(t, A['DOWN'])).feedback if f.marked]
    assert len(answers) == 3000
    wrong = [f for f in answers if f.h < 0]
    assert all(f.flipped for f in wrong) and 0.08 < len(wrong) / 3000 < 0.12

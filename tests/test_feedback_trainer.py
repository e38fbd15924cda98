"""The synthetic trainer: attribution by stamp, utterances, and the human-like options."""

from dataclasses import fields

from attention_common.parameters import field_docs
from attention_common.stamps import frames_to_ns, NS_PER_S
from attention_tasks.montezuma.critical_positions import CRITICAL_POSITIONS
from attention_tasks.montezuma.reward import RewardConfig, RewardFunction
from feedback_node.config import FeedbackConfig
from feedback_node.judging import TeacherConfig
from feedback_node.trainer import SyntheticTrainer, TrainerConfig
import pytest


def stamp(step: int) -> int:
    return frames_to_ns(4 * step)


def route():
    """Return a walk in steps of at most 4 pixels: down the ladder, the conveyor, the rope."""
    x0, y0 = CRITICAL_POSITIONS[0]
    path = [(x0, 235 - 4 * k) for k in range(11)] + [(x0, y0)]
    path += [(x0 + 2 * k, y0) for k in range(1, 12)]
    path += [(99 + k, 192 + 2 * k) for k in range(1, 9)] + [CRITICAL_POSITIONS[1]] * 14
    return path


def run(trainer, positions, start=0):
    outputs = []
    for step, (x, y) in enumerate(positions, start=start):
        outputs.append(trainer.on_position(stamp(step), x, y))
    return outputs


def test_feedback_judges_the_previous_step_by_the_next_position():
    positions = route()
    outputs = run(SyntheticTrainer(), positions)
    expected = RewardFunction()
    expected_h = [expected(x, y).h for x, y in positions]
    assert outputs[0].feedback == []
    for step in range(1, len(positions)):
        (feedback,) = outputs[step].feedback
        assert feedback.stamp_ns == stamp(step - 1)
        assert feedback.seen_ns == stamp(step)
        assert feedback.h == expected_h[step]
    hs = [out.feedback[0].h for out in outputs[1:]]
    assert {1.0, 0.0, -1.0} <= set(hs)  # the route covers all three values
    assert hs[-1] == -1.0  # hanging still on the rope for too long


def test_utterances_are_stamped_where_they_are_said():
    trainer = SyntheticTrainer(TrainerConfig(utterance_interval=0.0))
    outputs = run(trainer, route())
    said = [(i, out.utterance) for i, out in enumerate(outputs) if out.utterance]
    assert all(u.stamp_ns == stamp(i) for i, u in said)
    texts = [u.sentence_of for _, u in said]
    assert 0 in texts and texts[-1] == 1  # (the start itself is nearer the rope than 0)
    assert len(said) < len(outputs)  # the stuck rule silenced the end on the rope


def test_default_interval_speaks_once_per_ten_seconds_of_simulation():
    trainer = SyntheticTrainer()
    positions = [(40 + (k % 2), 235) for k in range(400)]  # pacing on the top floor
    said = [i for i, out in enumerate(run(trainer, positions)) if out.utterance]
    assert said == [0, 150, 300]


def test_a_teleport_is_not_judged():
    trainer = SyntheticTrainer()
    run(trainer, [(21, 148), (21, 152)])
    out = trainer.on_position(stamp(2), 77, 235)  # reset or respawn at the start
    assert out.feedback == [] and trainer.counts['unjudged_jumps'] == 1
    out = trainer.on_position(stamp(3), 77, 231)
    assert [f.stamp_ns for f in out.feedback] == [stamp(2)]


def test_stamps_going_back_restart_the_trial():
    trainer = SyntheticTrainer()
    run(trainer, route()[:5], start=100)
    out = trainer.on_position(stamp(0), 77, 235)
    assert out.feedback == [] and trainer.counts['restarts'] == 1
    assert [f.stamp_ns for f in trainer.on_position(stamp(1), 77, 231).feedback] == [stamp(0)]


def test_a_repeated_stamp_is_ignored():
    trainer = SyntheticTrainer(TrainerConfig(utterance_interval=0.0))
    run(trainer, [(21, 148), (21, 152)])
    out = trainer.on_position(stamp(1), 21, 152)
    assert out == ([], None) and trainer.counts['duplicates'] == 1
    assert [f.stamp_ns for f in trainer.on_position(stamp(2), 21, 156).feedback] == [stamp(1)]


def test_probability_zero_gives_no_feedback_but_still_speaks():
    trainer = SyntheticTrainer(TrainerConfig(feedback_probability=0.0, utterance_interval=0.0))
    outputs = run(trainer, route())
    assert all(out.feedback == [] for out in outputs)
    assert trainer.counts['skipped'] == len(outputs) - 1
    assert outputs[0].utterance is not None


def test_probability_gives_a_seeded_fraction():
    positions = [(40 + (k % 2), 235) for k in range(2001)]
    counts = []
    for seed in (1, 1, 2):
        trainer = SyntheticTrainer(TrainerConfig(feedback_probability=0.3, seed=seed))
        counts.append(sum(len(out.feedback) for out in run(trainer, positions)))
    assert counts[0] == counts[1]  # same seed, same draws
    assert 500 < counts[0] < 700 and 500 < counts[2] < 700


def test_noise_flips_the_sign_and_leaves_zero_alone():
    positions = route()
    clean = [f for out in run(SyntheticTrainer(), positions) for f in out.feedback]
    noisy = [f for out in run(SyntheticTrainer(TrainerConfig(feedback_noise=1.0)), positions)
             for f in out.feedback]
    assert [f.h for f in noisy] == [-f.h + 0.0 for f in clean]
    assert all(f.flipped == (f.h != 0.0) for f in noisy)


@pytest.mark.parametrize('delay_min, delay_max', [(1.0, 1.0), (0.5, 2.0)])
def test_delay_gives_feedback_later_with_the_stamp_of_the_step_judged(delay_min, delay_max):
    positions = [(40 + (k % 2), 235) for k in range(120)]
    trainer = SyntheticTrainer(TrainerConfig(feedback_delay_min=delay_min,
                                             feedback_delay_max=delay_max))
    released = []
    for step, out in enumerate(run(trainer, positions)):
        released += [(step, f) for f in out.feedback]
    step_of = {stamp(k): k for k in range(len(positions))}
    judged = [step_of[f.stamp_ns] for _, f in released]
    assert len(set(judged)) == len(judged)
    for step, feedback in released:
        assert step_of[feedback.seen_ns] == step_of[feedback.stamp_ns] + 1
        waited = (stamp(step) - feedback.seen_ns) / NS_PER_S
        assert delay_min - 0.07 <= waited <= delay_max + 0.07
    assert trainer.pending > 0 and len(released) + trainer.pending == len(positions) - 1


def test_config_rejects_nonsense():
    with pytest.raises(ValueError):
        TrainerConfig(feedback_probability=1.5)
    with pytest.raises(ValueError):
        TrainerConfig(feedback_delay_min=2.0, feedback_delay_max=1.0)


def test_node_config_documents_every_parameter_and_builds_the_chosen_trainers():
    docs = field_docs(FeedbackConfig)
    assert all(docs.get(f.name) for f in fields(FeedbackConfig))
    thesis = FeedbackConfig(utterance_interval=0.0).trainer_config()
    assert thesis == TrainerConfig(utterance_interval=0.0)
    assert thesis.reward_config() == RewardConfig()
    # The teacher has no h: its config holds only its own fields, and h's are not checked.
    teacher = FeedbackConfig(trainer='teacher', seed=3, beta_threshold=1.0).trainer_config()
    assert teacher == TeacherConfig(seed=3)


@pytest.mark.parametrize('values, message', [
    ({'summary_period': 0.0}, 'summary_period must be > 0'),
    ({'trainer': 'oracle'}, 'trainer must be one of'),
    ({'feedback_noise': 2.0}, 'feedback_noise'),
    ({'reward_variant': 'furthest'}, 'reward_variant'),
])
def test_node_config_says_which_value_is_wrong(values, message):
    with pytest.raises(ValueError, match=message):
        FeedbackConfig(**values)

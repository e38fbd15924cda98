"""Late feedback's credit (no rclpy): credit by prediction, the mixture loss, held decisions."""

from pathlib import Path
import time

from attention_common.joy_actions import ACTION_MEANINGS, NUM_ACTIONS
import numpy as np
import pytest
from tamer_node.acting import ActingModel
from tamer_node.agent import TamerAgent
from tamer_node.buffer import collate, FeedbackBuffer, Sample
from tamer_node.config import TamerConfig
from tamer_node.credit import effect_credit, NS_PER_S, spans_from_stamps, window_credit
from tamer_node.history import holds, StepHistory
from tamer_node.learner import excluded_mse, Learner, mixture_mse
from tamer_node.memory import state_key, VerdictMemory
from tamer_node.model import Encoder, FEATURE_SIZE, HModel, joystick_parts, PartsHead
from tamer_node.pairing import by_prediction, to_decisions
from tamer_node.posterior import feedback_likelihood, posterior_weights
from tamer_node.revisits import Revisits
import torch

torch.set_num_threads(1)
GOOD, BAD = 3, 7


def constant_h(good=GOOD, value=0.9):
    """Return an HModel whose H is +value for ``good`` and -value for every other action."""
    model = HModel(freeze_encoder=True, encoder=Encoder())
    with torch.no_grad():
        model.head[2].weight.zero_()
        model.head[2].bias.fill_(-value)
        model.head[2].bias[good] = value
    return model


def sample(action, h, weight, seq, stamp=0, state=None):
    state = torch.zeros(FEATURE_SIZE) if state is None else state
    return Sample(state, None, action, h, weight, stamp, seq)


# Credit by prediction (posterior.py).
def test_a_learner_that_knows_nothing_gives_the_plain_window():
    priors = np.array([0.2, 0.3, 0.5])
    weights = posterior_weights(priors, feedback_likelihood(np.ones(3), np.zeros(3), 0.1),
                                np.zeros(3))
    assert weights == pytest.approx(priors)


def test_a_good_verdict_goes_to_the_step_h_believes_good_and_keeps_its_mass():
    priors = np.full(4, 0.25)
    predicted = np.array([-0.9, 0.9, -0.9, -0.9])
    good = posterior_weights(priors, feedback_likelihood(np.ones(4), predicted, 0.1),
                             np.zeros(4))
    bad = posterior_weights(priors, feedback_likelihood(-np.ones(4), predicted, 0.1),
                            np.zeros(4))
    assert good.sum() == pytest.approx(1.0) and bad.sum() == pytest.approx(1.0)
    assert good.argmax() == 1 and good[1] > 0.6
    assert bad[1] == bad.min() and bad[1] < 0.1


def test_noise_bounds_how_far_one_prediction_moves_credit():
    likelihood = feedback_likelihood(np.ones(2), np.array([5.0, -5.0]), 0.1)  # beyond [-1, 1]
    assert likelihood[0] / likelihood[1] == pytest.approx(9.0)
    with pytest.raises(ValueError):
        feedback_likelihood(np.ones(1), np.zeros(1), 0.5)


def test_each_feedback_is_normalised_on_its_own():
    priors = np.array([0.5, 0.5, 1.0])
    weights = posterior_weights(priors, np.array([0.9, 0.1, 0.3]), np.array([7, 7, 8]))
    assert weights[:2].sum() == pytest.approx(1.0) and weights[2] == pytest.approx(1.0)
    assert weights[0] == pytest.approx(0.9)


def test_pairing_puts_a_late_good_on_the_decision_h_believes_good():
    # A window of six steps, two actions; the learner believes GOOD is good here.
    window = [sample(GOOD if i % 3 == 0 else BAD, 1.0, 1 / 6, seq=1, stamp=i) for i in range(6)]
    credited = by_prediction(window, constant_h(), noise=0.1)
    on_good = sum(s.weight for s in credited if s.action == GOOD)
    good, bad = 0.1 + 0.8 * 0.95, 0.1 + 0.8 * 0.05  # P(+1 | H = 0.9), P(+1 | H = -0.9)
    assert on_good == pytest.approx(2 * good / (2 * good + 4 * bad))  # plain window: 1/3
    assert sum(s.weight for s in credited) == pytest.approx(1.0)
    assert all(s.prior == pytest.approx(1 / 6) for s in credited)


def test_the_buffer_is_reweighed_with_the_current_h():
    buffer = FeedbackBuffer(100, (FEATURE_SIZE,), np.float32)
    buffer.extend([sample(GOOD if i == 1 else BAD, 1.0, 0.25, seq=1, stamp=i) for i in range(4)])
    buffer.extend([sample(GOOD, -1.0, 1.0, seq=2, stamp=9)])  # step credit: one step
    model = constant_h()

    def predict(states, actions):
        with torch.no_grad():
            return model.from_features(states).gather(1, actions.unsqueeze(1)).squeeze(1).numpy()

    assert buffer.refit_weights(predict, 0.1) == 5
    weights = buffer.columns['weights'][:5]
    assert weights[1] == weights[:4].max() and weights[:4].sum() == pytest.approx(1.0)
    assert weights[4] == pytest.approx(1.0)  # a single step keeps its whole weight
    assert buffer.columns['priors'][:4] == pytest.approx([0.25] * 4)


# The mixture loss (learner.mixture_mse).
def fit_per_action(loss_name, steps=400, seed=0):
    """Fit one H value per action to late feedback from windows that mix actions."""
    rng = np.random.default_rng(seed)
    verdict = np.array([1.0, -1.0, -1.0])  # action 0 is right, 1 and 2 are wrong
    rows, seqs, h = [], [], []
    for seq in range(400):
        actions = rng.choice(3, size=10, p=rng.dirichlet([1, 1, 1]))
        judged = actions[rng.integers(10)]
        rows.append(actions)
        seqs.append(np.full(10, seq))
        h.append(np.full(10, verdict[judged] * (-1 if rng.random() < 0.1 else 1)))
    actions = torch.from_numpy(np.concatenate(rows))
    groups = torch.from_numpy(np.concatenate(seqs))
    targets = torch.from_numpy(np.concatenate(h)).float()
    weights = torch.full_like(targets, 0.1)
    values = torch.zeros(3, requires_grad=True)
    optimizer = torch.optim.Adam([values], lr=0.05)
    for _ in range(steps):
        judged = values[actions]
        if loss_name == 'mixture':
            loss = mixture_mse(judged, targets, weights, groups)
        else:
            loss = (weights * (judged - targets) ** 2).sum() / weights.sum()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return values.detach().numpy()


def test_the_mixture_loss_recovers_the_verdicts_that_per_step_regression_blurs():
    each = fit_per_action('each')
    mixture = fit_per_action('mixture')
    # 10 % of signs flipped: the truth a fit can reach is 0.8 and -0.8 (400 feedbacks).
    assert mixture[0] > 0.3 and max(mixture[1:]) < -0.55
    assert mixture[0] - max(mixture[1:]) > 1.0
    # Deep TAMER's: the good action takes its neighbours' verdicts, and hardly stands out.
    assert each[0] < 0.2 and each[0] - max(each[1:]) < 0.6


# A positive verdict as a label on the policy (learner.excluded_mse, positive_excludes).
def fit_one_good_verdict(positive_excludes, steps=300):
    """Train on one +1 verdict for GOOD in one state; return H(s, .) after."""
    torch.manual_seed(0)
    model = HModel(freeze_encoder=True, encoder=Encoder(), num_actions=6)
    learner = Learner(model, learning_rate=1e-2, alpha=0.0,
                      positive_excludes=positive_excludes)
    state = torch.randn(FEATURE_SIZE)
    batch = collate([sample(GOOD % 6, 1.0, 1.0, 1, state=state)])
    for _ in range(steps):
        learner.train_step(batch)
    with torch.no_grad():
        return model.from_features(state.unsqueeze(0))[0].numpy()


def test_a_good_verdict_also_teaches_that_the_other_actions_were_not_wanted():
    others = [a for a in range(6) if a != GOOD % 6]
    plain = fit_one_good_verdict(0.0)
    implied = fit_one_good_verdict(1.0)
    assert plain[GOOD % 6] == pytest.approx(1.0, abs=0.05)
    assert implied[GOOD % 6] == pytest.approx(1.0, abs=0.05)
    assert max(implied[others]) < -0.9  # each other action learned -1 from the one verdict
    assert max(plain[others]) > -0.5  # without: an untried action keeps whatever H it had


def test_a_bad_verdict_implies_nothing_about_the_other_actions():
    batch = collate([sample(1, -1.0, 1.0, 1), sample(2, -1.0, 0.5, 2)])
    assert excluded_mse(torch.zeros(2, 6), batch).item() == 0.0
    batch = collate([sample(1, 1.0, 1.0, 1), sample(2, -1.0, 1.0, 2)])
    # Only the positive row counts: its 5 other actions at 0 are each 1 from -1.
    assert excluded_mse(torch.zeros(2, 6), batch).item() == pytest.approx(1.0)


def test_a_feedback_with_one_step_is_the_plain_squared_error():
    judged, h = torch.tensor([0.5, -0.2]), torch.tensor([1.0, -1.0])
    assert mixture_mse(judged, h, torch.ones(2), torch.tensor([0, 1])).item() == pytest.approx(
        ((0.5 - 1.0) ** 2 + (-0.2 + 1.0) ** 2) / 2)


def test_the_mixture_learner_trains_on_whole_feedbacks():
    buffer = FeedbackBuffer(1000, (FEATURE_SIZE,), np.float32)
    for seq in range(1, 21):
        buffer.extend([sample(i, 1.0, 0.25, seq=seq, stamp=i) for i in range(4)])
    batch = buffer.sample_feedback(5, np.random.default_rng(0))
    assert len(batch.actions) == 20 and int(batch.groups.max()) == 4
    assert torch.bincount(batch.groups).tolist() == [4] * 5
    learner = Learner(HModel(freeze_encoder=True, encoder=Encoder()), credit_loss='mixture')
    loss, mse, _ = learner.loss(batch)
    predicted = learner.predict(batch.states).gather(1, batch.actions.unsqueeze(1)).squeeze(1)
    expected = mixture_mse(predicted, batch.h, batch.weights, batch.groups)
    assert mse.item() == pytest.approx(expected.item())
    assert collate([sample(0, 1.0, 1.0, seq=5), sample(1, 1.0, 1.0, seq=9)]).groups.tolist() \
        == [0, 1]


def wait_for_samples(agent, seconds=10.0):
    """Wait until the learner has turned a feedback into samples (or ``seconds`` passed)."""
    deadline = time.monotonic() + seconds
    while not len(agent.buffer) and time.monotonic() < deadline:
        time.sleep(0.01)


# Decisions held, ties kept.
def play_actions(tmp_path: Path, **changes):
    frames = np.random.default_rng(0).integers(0, 256, (12, 210, 160, 3), np.uint8)
    config = TamerConfig(run_dir=str(tmp_path), greedy_margin=2.0, pace_updates=0.0,
                         checkpoint_period_s=0.0, **changes)  # margin 2: every action tied
    agent = TamerAgent(config, tmp_path, encoder=Encoder())
    agent.start()
    try:
        actions = [agent.on_observation((i + 1) * 66_666_667, frames[i]) for i in range(12)]
        return actions, agent.counters['act/held']
    finally:
        agent.close()


def test_a_decision_is_held_for_decision_period_s(tmp_path):
    actions, held = play_actions(tmp_path / 'held', decision_period_s=0.2)  # 3 steps of 15 Hz
    decisions = [actions[i:i + 3] for i in range(0, 12, 3)]
    assert all(len(set(d)) == 1 for d in decisions) and held == 8
    free, _ = play_actions(tmp_path / 'free')  # every step its own (random) choice
    assert any(len(set(free[i:i + 3])) > 1 for i in range(0, 12, 3))


def test_a_held_decision_ends_early_only_when_another_action_is_clearly_better(tmp_path):
    frames = np.random.default_rng(2).integers(0, 256, (3, 210, 160, 3), np.uint8)

    def second_action(margin):
        config = TamerConfig(run_dir=str(tmp_path / str(margin)), greedy_margin=0.1,
                             pace_updates=0.0, checkpoint_period_s=0.0, update_rate_hz=0.0,
                             decision_period_s=1.0, decision_switch_margin=margin)
        agent = TamerAgent(config, tmp_path / str(margin), encoder=Encoder())
        agent.start()
        try:
            last = agent.actor.model.head[-1]
            with torch.no_grad():  # every action at -1: the first decision is any of them
                last.weight.zero_()
                last.bias.fill_(-1.0)
            first = agent.on_observation(66_666_667, frames[0])
            better = (first + 1) % NUM_ACTIONS
            with torch.no_grad():  # a step later H has learned another action is good
                last.bias[better] = 0.5
            return first, better, agent.on_observation(133_333_334, frames[1]), dict(
                agent.counters)
        finally:
            agent.close()

    first, better, second, counters = second_action(0.0)
    assert second == first and counters['act/held'] == 1  # held its whole second
    first, better, second, counters = second_action(2.0)
    assert second == first and counters['act/switched'] == 0  # 0.5 - (-1) is not above 2
    first, better, second, counters = second_action(0.5)
    assert second == better and counters['act/switched'] == 1 and counters['act/held'] == 0


def test_a_tie_that_includes_the_previous_action_keeps_it():
    actor = ActingModel(HModel(), greedy_margin=0.1, seed=0, keep_tied=True)
    tied = torch.full((NUM_ACTIONS,), -1.0)
    first = actor.choose(tied)
    assert {actor.choose(tied) for _ in range(50)} == {first}
    better = tied.clone()
    better[(first + 1) % NUM_ACTIONS] = 0.5
    assert actor.choose(better) == (first + 1) % NUM_ACTIONS  # a clear best still wins
    loose = ActingModel(HModel(), greedy_margin=0.1, seed=0)
    assert len({loose.choose(tied) for _ in range(50)}) > 1


def test_with_held_decisions_late_credit_lands_on_the_steps_that_chose(tmp_path):
    config = TamerConfig(run_dir=str(tmp_path), credit='window', window_min_s=0.2,
                         window_max_s=1.6, decision_period_s=0.2, pace_updates=0.0,
                         checkpoint_period_s=0.0, update_rate_hz=0.0)
    agent = TamerAgent(config, tmp_path, encoder=Encoder())
    agent.start()
    frames = np.random.default_rng(1).integers(0, 256, (4, 210, 160, 3), np.uint8)
    stamps = [(i + 1) * 66_666_667 for i in range(60)]
    try:
        for i, stamp in enumerate(stamps):
            agent.on_observation(stamp, frames[i % 4])
        agent.on_feedback(1.0, 'plain')
        wait_for_samples(agent)
        credited = agent.buffer.samples()
    finally:
        agent.close()
    chose = set(stamps[::3])  # the first step of every decision
    assert credited and {s.stamp for s in credited} <= chose
    assert sum(s.weight for s in credited) == pytest.approx(1.0, abs=1e-5)
    assert 6 <= len(credited) <= 9  # 1.4 s of 15 Hz steps in decisions of 3, not 21 steps


# Credit anchored at the step's effect (credit_anchor 'effect').
def grid_spans(steps, now_s):
    """Spans of steps 1 s long, starting at 1, 2, ... s (MiniGrid's clock)."""
    return spans_from_stamps([(i + 1) * NS_PER_S for i in range(steps)], int(now_s * NS_PER_S))


def test_a_verdict_on_a_grid_step_falls_on_the_steps_whose_effect_it_followed():
    # A verdict at 12 s, 0.2-2.5 s late: the steps whose result showed at 9.5-11.8 s, that is
    # at 10 s and 11 s, are the ones started at 9 s and 10 s; the span model adds 11 s too.
    spans = grid_spans(12, 12.0)
    effect = effect_credit(spans, 12 * NS_PER_S, 0.2, 2.5)
    assert effect == {9 * NS_PER_S: 0.5, 10 * NS_PER_S: 0.5}
    span = window_credit(spans, 12 * NS_PER_S, 0.2, 2.5)
    assert set(span) == {9 * NS_PER_S, 10 * NS_PER_S, 11 * NS_PER_S}
    assert max(span.values()) < 0.5


def test_the_step_on_screen_has_shown_no_effect_yet():
    spans = grid_spans(3, 3.0)  # step 3 s is on screen; step 2 s's result shows right now
    assert effect_credit(spans, 3 * NS_PER_S, 0.0, 2.5) == {1 * NS_PER_S: 1.0}
    assert effect_credit(spans, 3 * NS_PER_S, 3.0, 4.0) == {}
    with pytest.raises(ValueError):
        effect_credit(spans, 3 * NS_PER_S, 1.0, 1.0)


def credit_one_verdict(run: Path, steps: int, source: str, press_s=None, **changes):
    """Return {step (s): weight} of one +1 given after ``steps`` 1 s grid steps."""
    frames = np.random.default_rng(2).integers(0, 256, (steps, 210, 160, 3), np.uint8)
    config = TamerConfig(run_dir=str(run), credit='window', pace_updates=0.0,
                         checkpoint_period_s=0.0, update_rate_hz=0.0, **changes)
    agent = TamerAgent(config, run, encoder=Encoder())
    agent.start()
    try:
        for i in range(steps):
            agent.on_observation((i + 1) * NS_PER_S, frames[i])
        event = agent.on_feedback(1.0, source, None if press_s is None
                                  else int(press_s * NS_PER_S))
        assert event.stamp == steps * NS_PER_S  # attributed on arrival: the newest step
        wait_for_samples(agent)
        return {s.stamp // NS_PER_S: s.weight for s in agent.buffer.samples()}
    finally:
        agent.close()


def test_the_agent_credits_a_plain_verdict_by_the_anchor_it_is_set_to(tmp_path):
    credited = {anchor: credit_one_verdict(tmp_path / anchor, 12, 'plain', credit_anchor=anchor,
                                           window_min_s=0.2, window_max_s=2.5)
                for anchor in ('span', 'effect')}  # at 12 s, the newest observation's stamp
    assert credited['effect'] == pytest.approx({9: 0.5, 10: 0.5})
    assert set(credited['span']) == {9, 10, 11}
    with pytest.raises(ValueError, match='credit_anchor'):
        TamerConfig(credit_anchor='press').validate()


def test_a_verdict_that_carries_its_press_time_lands_on_the_step_it_judged(tmp_path):
    # Steps of 1 s at 1..6 s. The trainer judged the step at 3 s, whose result showed at 4 s,
    # and pressed 1.1 s later, at 5.1 s; the learner hears it once the step at 6 s is shown.
    # From the newest observation (6 s) a 0.2-1.6 s delay after a result points at the step
    # at 4 s (result at 5 s): wrong. From the press (5.1 s) it points at 3 s alone.
    credited = {source: credit_one_verdict(tmp_path / source, 6, source, 5.1,
                                           credit_anchor='effect', window_min_s=0.2,
                                           window_max_s=1.6)
                for source in ('plain', 'pressed')}
    assert credited == {'plain': {4: 1.0}, 'pressed': {3: 1.0}}


def test_a_resume_finds_the_decisions_the_acting_path_made():
    history = StepHistory(100)
    step = 66_666_667
    for i in range(7):
        history.set_action((i + 1) * step, i % 2)
    history.mark_decisions(lambda decision, stamp: holds(decision, stamp, 0.2))
    assert [r.decision // step for r in history.records()] == [1, 1, 1, 4, 4, 4, 7]
    assert not holds(None, step, 0.2) and not holds(step, 2 * step, 0.0)
    assert holds(step, 3 * step, 0.2) and not holds(step, 4 * step, 0.2)


def test_a_step_the_world_did_otherwise_keeps_its_own_credit():
    history = StepHistory(100)
    for stamp in (1, 2, 3):
        history.set_action(stamp, GOOD, decision=1)
    history.set_taken(3, BAD)  # a replay: the session's world executed another action
    assert to_decisions({1: 0.2, 2: 0.3, 3: 0.5}, history) == {1: 0.5, 3: 0.5}


def moved_by_a_verdict_on_upright(head):
    """Return the last layer's change on RIGHT and DOWNLEFTFIRE after 'UPRIGHT is bad'."""
    torch.manual_seed(0)
    x = torch.randn(1, 64)
    optimizer = torch.optim.SGD(head.parameters(), lr=0.002)
    before = head(x).detach()[0]
    upright = ACTION_MEANINGS.index('UPRIGHT')
    for _ in range(10):
        loss = (head(x)[0, upright] + 1.0) ** 2
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    change = head(x).detach()[0] - before
    return (float(change[ACTION_MEANINGS.index('RIGHT')]),
            float(change[ACTION_MEANINGS.index('DOWNLEFTFIRE')]))


def test_shared_joystick_parts_carry_a_verdict_to_the_actions_that_share_them():
    torch.manual_seed(1)
    right, unrelated = moved_by_a_verdict_on_upright(
        PartsHead(64, joystick_parts(range(NUM_ACTIONS))))
    assert right < -0.1 and unrelated == pytest.approx(0.0, abs=1e-6)  # shares no part
    alone = moved_by_a_verdict_on_upright(torch.nn.Linear(64, NUM_ACTIONS))  # the thesis's
    assert alone == pytest.approx((0.0, 0.0), abs=1e-6)
    model = HModel(parts=joystick_parts(range(NUM_ACTIONS)))
    assert isinstance(model.head[2], PartsHead) and model.from_features(
        torch.zeros(2, FEATURE_SIZE)).shape == (2, NUM_ACTIONS)


# Verdicts remembered on exact states (memory.py).
def test_the_memory_blends_remembered_verdicts_into_h_as_pseudo_counts():
    memory = VerdictMemory(1.0, 6, capacity=2)
    here, there = torch.zeros(FEATURE_SIZE), torch.ones(FEATURE_SIZE)
    memory.add([sample(2, -1.0, 1.0, 1, state=here), sample(4, 1.0, 0.5, 2, state=here)])
    blended = memory.blend(state_key(here.clone()), torch.zeros(6))
    assert blended[2] == pytest.approx(-0.5)  # one verdict of -1 against H = 0: half way
    assert blended[4] == pytest.approx(0.5 / 1.5)  # half a verdict (a window's share)
    assert blended[[0, 1, 3, 5]].tolist() == [0.0] * 4  # untried: H alone
    elsewhere = memory.blend(state_key(there), torch.zeros(6))
    assert torch.equal(elsewhere, torch.zeros(6))  # another state
    memory.add([sample(0, 1.0, 1.0, 3, state=there), sample(0, 1.0, 1.0, 4, state=2 * there)])
    assert len(memory) == 2 and memory.lookup(here) is None  # the oldest state forgotten


def act_again_after_a_bad_verdict(tmp_path: Path, **changes):
    """Act on one frame, hear -1 on that step, act on the same frame again: both actions."""
    frame = np.random.default_rng(3).integers(0, 256, (210, 160, 3), np.uint8)
    config = TamerConfig(run_dir=str(tmp_path), pace_updates=0.0, checkpoint_period_s=0.0,
                         update_rate_hz=0.0, immediate_update=False, **changes)
    agent = TamerAgent(config, tmp_path, encoder=Encoder())  # H fixed: no update is taken
    agent.start()
    try:
        first = agent.on_observation(66_666_667, frame)
        agent.on_feedback(-1.0, 'stamped', 66_666_667)
        wait_for_samples(agent)
        assert agent.learner.updates == 0
        return first, agent.on_observation(133_333_334, frame)
    finally:
        agent.close()


def test_an_action_judged_bad_in_this_very_state_is_not_taken_again(tmp_path):
    first, second = act_again_after_a_bad_verdict(tmp_path / 'plain')
    assert second == first  # H alone has not moved: the same greedy action
    first, second = act_again_after_a_bad_verdict(tmp_path / 'memory', verdict_memory=1.0)
    assert second != first


def test_revisits_count_each_action_per_state_over_the_last_steps_only():
    revisits = Revisits(penalty=0.5, steps=3, num_actions=4)
    here, there = torch.zeros(8), torch.ones(8)
    key = state_key(here)
    assert revisits.penalties(key).tolist() == [0.0] * 4
    revisits.took(key, 2)
    revisits.took(key, 2)
    other = state_key(there)
    revisits.took(other, 1)
    assert revisits.penalties(key).tolist() == [0.0, 0.0, 1.0, 0.0]
    assert revisits.penalties(other).tolist() == [0.0, 0.5, 0.0, 0.0]
    revisits.took(other, 1)  # the window holds 3: the first visit here is forgotten
    assert revisits.penalties(key).tolist() == [0.0, 0.0, 0.5, 0.0]
    assert revisits.penalties(other).tolist() == [0.0, 1.0, 0.0, 0.0]


def act_on_one_frame_again_and_again(tmp_path: Path, times: int, **changes) -> list:
    """Return the actions of an agent whose H never moves, shown one frame ``times`` times."""
    frame = np.random.default_rng(5).integers(0, 256, (210, 160, 3), np.uint8)
    config = TamerConfig(run_dir=str(tmp_path), pace_updates=0.0, checkpoint_period_s=0.0,
                         update_rate_hz=0.0, immediate_update=False, greedy_margin=0.0,
                         **changes)
    agent = TamerAgent(config, tmp_path, encoder=Encoder())
    agent.start()
    try:
        return [agent.on_observation((1 + k) * 66_666_667, frame) for k in range(times)]
    finally:
        agent.close()


def test_back_in_a_state_it_just_left_the_agent_tries_another_action(tmp_path):
    # Without a verdict, greedy H repeats one action in a state forever (DoorKey's agent turned
    # on the spot on 89-93 % of its steps); counted against it, the actions taken there vary.
    alone = act_on_one_frame_again_and_again(tmp_path / 'plain', 6)
    assert len(set(alone)) == 1
    revisiting = act_on_one_frame_again_and_again(tmp_path / 'revisits', 6,
                                                  revisit_penalty=0.5)
    assert len(set(revisiting)) >= 3
    assert revisiting[1] != revisiting[0]


def test_the_ring_takes_all_its_memory_when_made_so_a_long_run_stays_flat():
    # A million-step soak grew tamer_node by 36 MB as a slowly filling ring took its pages.
    def resident_kb() -> int:
        with open('/proc/self/status') as status:
            return next(int(line.split()[1]) for line in status if line.startswith('VmRSS:'))

    before = resident_kb()
    ring = FeedbackBuffer(5000, (FEATURE_SIZE,), np.float32)
    taken_kb = resident_kb() - before
    size_kb = (ring.states.nbytes + ring.companions.nbytes) / 1024
    assert taken_kb >= 0.9 * size_kb, (taken_kb, size_kb)
    assert not ring.states.any() and len(ring) == 0


# Answers kept: step-credited samples in a ring of their own (kept_per_batch).
def batches_after_a_flood(run: Path, **changes):
    """One stamped +1, then plain window verdicts that fill the main ring many times over."""
    frames = np.random.default_rng(3).integers(0, 256, (30, 210, 160, 3), np.uint8)
    config = TamerConfig(run_dir=str(run), credit='window', pace_updates=0.0,
                         checkpoint_period_s=0.0, update_rate_hz=0.0, buffer_capacity=40,
                         batch_size=16, window_min_s=0.2, window_max_s=4.0, **changes)
    agent = TamerAgent(config, run, encoder=Encoder())
    agent.start()
    try:
        for i in range(30):
            agent.on_observation((i + 1) * NS_PER_S // 15, frames[i])
        for step in range(10, 15):  # answers about steps 10-14
            agent.on_feedback(1.0, 'stamped', step * NS_PER_S // 15)
        for _ in range(20):  # each credited to the whole 2 s of steps: the ring holds 1-2
            agent.on_feedback(-1.0, 'plain')
        deadline = time.monotonic() + 10.0
        while agent.worker.applied_seq < 25 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert agent.worker.applied_seq == 25
        batches = [agent.worker._minibatch() for _ in range(50)]
        return batches, agent.buffer.samples()
    finally:
        agent.close()


def test_an_answer_is_rehearsed_in_every_minibatch_after_the_window_floods_the_ring(tmp_path):
    batches, ring = batches_after_a_flood(tmp_path / 'kept', kept_per_batch=4)
    assert not any(s.h > 0 for s in ring)  # pushed out of the main ring...
    for batch in batches:  # ...yet 4 of each 16 rows are answers kept (+1, full weight)
        assert len(batch.h) == 16 and (batch.h > 0).sum() == 4
        assert batch.weights[batch.h > 0].tolist() == [1.0] * 4
    assert len({row.tolist() for batch in batches  # every one of the five drawn in turn
                for row in batch.states[batch.h > 0].sum(1)}) == 5
    batches, ring = batches_after_a_flood(tmp_path / 'one_ring')
    assert not any((batch.h > 0).any() for batch in batches)  # one ring: it is gone
    with pytest.raises(ValueError, match='kept_per_batch'):
        TamerConfig(kept_per_batch=4, credit_loss='mixture').validate()

"""The trainer's delay fitted online (credit_delay_fit, delay_fit.py): no rclpy."""

import time

import numpy as np
import pytest
from tamer_node.agent import TamerAgent
from tamer_node.config import TamerConfig
from tamer_node.credit import effect_credit, NS_PER_S, spans_from_stamps, window_credit
from tamer_node.delay_fit import candidate_intervals, DelayFit, fitted_credit
from tamer_node.model import Encoder
import torch

torch.set_num_threads(1)
GOOD, BAD = 3, 7


def test_a_flat_fit_is_the_plain_window_on_either_anchor():
    rng = np.random.default_rng(0)
    stamps = list(np.cumsum(rng.integers(50_000_000, 1_200_000_000, 40)))
    now = int(stamps[-1] + 300_000_000)
    spans = spans_from_stamps(stamps, now)
    fit = DelayFit(0.2, 2.5)
    span = fitted_credit(candidate_intervals(spans, now, 'span'), fit)
    assert span == pytest.approx(window_credit(spans, now, 0.2, 2.5))
    effect = fitted_credit(candidate_intervals(spans, now, 'effect'), fit)
    assert effect == pytest.approx(effect_credit(spans, now, 0.2, 2.5))
    assert effect and sum(effect.values()) == pytest.approx(1.0)


def test_responsibility_moves_the_fit_and_the_credit_follows():
    fit = DelayFit(0.2, 4.0, prior_count=10.0)
    one, three = (NS_PER_S, NS_PER_S), (3 * NS_PER_S, 3 * NS_PER_S)
    for _ in range(40):
        fit.observe([one, three], [0.9, 0.1])
    credit = fitted_credit({1: one, 3: three}, fit)
    assert credit[1] > 0.85 and credit[1] + credit[3] == pytest.approx(1.0)
    mean, sd = fit.moments_s()
    assert 1.0 < mean < 1.6 and sd < 0.9
    assert fit.observed == pytest.approx(40.0)
    fit.observe([(5 * NS_PER_S, 5 * NS_PER_S)], [1.0])  # outside the window: nothing learned
    assert fit.observed == pytest.approx(40.0)


def test_an_interval_spreads_its_share_over_the_bins_it_covers():
    fit = DelayFit(0.0, 1.0, bin_s=0.25, prior_count=4.0)
    fit.observe([(0, NS_PER_S // 2)], [2.0])
    assert fit.counts == pytest.approx([2.0, 2.0, 1.0, 1.0])


def test_a_saved_fit_comes_back_and_another_window_is_refused():
    fit = DelayFit(0.2, 2.5)
    fit.observe([(NS_PER_S, NS_PER_S)], [1.0])
    again = DelayFit(0.2, 2.5)
    again.load(fit.state())
    assert again.counts == pytest.approx(fit.counts) and again.observed == 1.0
    with pytest.raises(ValueError, match='other bins'):
        DelayFit(0.2, 4.0).load(fit.state())


def test_the_fit_needs_credit_by_prediction_and_single_steps():
    with pytest.raises(ValueError, match='credit_posterior'):
        TamerConfig(credit_delay_fit=True).validate()
    with pytest.raises(ValueError, match='decision_period_s'):
        TamerConfig(credit_delay_fit=True, credit_posterior=True,
                    decision_period_s=0.2).validate()
    with pytest.raises(ValueError, match='credit_delay_bin_s'):
        TamerConfig(credit_delay_bin_s=0.0).validate()


def fitting_config(run_dir, fit: bool, **extra) -> TamerConfig:
    return TamerConfig(run_dir=str(run_dir), credit='window', credit_anchor='effect',
                       window_min_s=0.2, window_max_s=4.0, credit_posterior=True,
                       credit_delay_fit=fit, immediate_update=False, update_rate_hz=0.0,
                       pace_updates=0.0, checkpoint_period_s=0.0, credit_refit_updates=0,
                       **extra)


def credit_on_the_judged_step(tmp_path, fit: bool, verdicts: int = 160) -> tuple:
    """
    Return the mean credit on the judged step of the last 40 verdicts, and the fitted delay.

    The learner's H already tells GOOD from BAD; Deep TAMER's wide window (0.2-4 s) on 1 s
    steps; each verdict exactly 1 s after its step's result showed.
    """
    agent = TamerAgent(fitting_config(tmp_path, fit), tmp_path, encoder=Encoder())
    with torch.no_grad():  # H = +0.9 for GOOD, -0.9 otherwise, in every state; never trained
        head = agent.learner.model.head[2]
        head.weight.zero_()
        head.bias.fill_(-0.9)
        head.bias[GOOD] = 0.9
    agent.start()
    rng = np.random.default_rng(3)
    frames = rng.integers(0, 256, (4, 210, 160, 3), np.uint8)
    actions = {}
    try:
        for i in range(verdicts + 2):
            stamp = (i + 1) * NS_PER_S
            agent.on_observation(stamp, frames[i % 4])
            actions[stamp] = GOOD if rng.random() < 0.3 else BAD
            agent.on_action_taken(stamp, actions[stamp])
            if i >= 2:  # the step before last: its result showed 1 s ago
                judged = stamp - 2 * NS_PER_S
                agent.on_feedback(1.0 if actions[judged] == GOOD else -1.0, 'plain')
        deadline = time.monotonic() + 30
        while agent.worker.applied_seq < verdicts and time.monotonic() < deadline:
            time.sleep(0.01)
        samples = agent.buffer.samples()
        delays = agent.worker.delays
    finally:
        agent.close()
    on_judged = [sum(s.weight for s in samples if s.seq == seq and s.stamp == seq *
                     NS_PER_S) / sum(s.weight for s in samples if s.seq == seq)
                 for seq in range(verdicts - 39, verdicts + 1)]
    return float(np.mean(on_judged)), delays


def test_with_a_known_delay_the_credit_lands_on_the_judged_step(tmp_path):
    fitted, delays = credit_on_the_judged_step(tmp_path / 'fit', fit=True)
    plain, none = credit_on_the_judged_step(tmp_path / 'plain', fit=False)
    assert none is None
    mode = delays.probabilities.argmax()  # the true delay, from the window's flat 0.2-4 s
    assert delays.edges[mode] <= NS_PER_S < delays.edges[mode + 1]
    assert delays.probabilities[mode] > 0.5
    assert fitted > 0.8 and plain < 0.55, (fitted, plain)


def test_a_resumed_run_keeps_its_fitted_delay(tmp_path):
    _, fitted = credit_on_the_judged_step(tmp_path, fit=True, verdicts=60)
    resumed = TamerAgent(fitting_config(tmp_path, True, resume=True), tmp_path,
                         encoder=Encoder())
    resumed.start()
    try:
        assert resumed.worker.delays.observed == pytest.approx(fitted.observed)
        assert resumed.worker.delays.counts == pytest.approx(fitted.counts)
        assert resumed.metrics()['credit/delay_mean_s'] == pytest.approx(fitted.moments_s()[0])
    finally:
        resumed.close()

"""The acting policy: the thesis's argmax, and greedy with a margin on H clipped to [-1, 1]."""

from tamer_node.acting import ActingModel
from tamer_node.model import HModel
import torch


def actor(margin, seed=0):
    return ActingModel(HModel(), greedy_margin=margin, seed=seed)


def h_values(best=None, below=None):
    h = torch.full((18,), -1.0)
    h += torch.linspace(0.0, 0.05, 18)  # judged actions near -1, not exactly equal
    if below is not None:
        h[below] = -1.8    # extrapolated beyond the feedback range
    if best is not None:
        h[best] = 0.9
    return h


def test_margin_zero_is_the_thesis_argmax():
    a = actor(0.0)
    assert a.choose(h_values(below=2)) == 17  # the largest, never the extrapolated one
    assert a.choose(torch.zeros(18)) == 0     # ties: the lowest index


def test_a_clear_best_action_is_always_taken():
    a = actor(0.1)
    assert {a.choose(h_values(best=11, below=2)) for _ in range(200)} == {11}


def test_an_action_extrapolated_below_minus_one_is_tried_with_the_margin():
    a = actor(0.1, seed=3)
    chosen = [a.choose(h_values(below=2)) for _ in range(2000)]
    assert 2 in chosen                       # clipped to -1: tied with the judged ones
    assert len(set(chosen)) == 18            # a tie is broken at random
    again = actor(0.1, seed=3)
    assert [again.choose(h_values(below=2)) for _ in range(2000)] == chosen  # seeded

"""LogBudget: warnings said whole up to a budget a period, the rest folded and counted."""

from attention_common.log_budget import LogBudget
import pytest


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_a_burst_is_said_up_to_the_budget_then_folded_with_its_count_and_last():
    said, clock = [], Clock()
    budget = LogBudget(lambda level, text: said.append((level, text)), per_period=3,
                       period_s=1.0, clock=clock)
    for i in range(10):
        budget.warn(f'feedback #{i} matches no step')
    assert [text for _, text in said] == [f'feedback #{i} matches no step' for i in range(3)]
    clock.now += 1.0
    budget.flush_due()  # the period is over: its folded warnings are said, counted
    assert said[-1] == ('warn', '7 more warning(s) like those above in 1 s, not said one by '
                                'one; the last: feedback #9 matches no step')
    budget.warn('feedback #10 matches no step')  # a new period: said whole again
    assert said[-1][1] == 'feedback #10 matches no step' and budget.folded == 0


def test_flush_says_what_is_folded_at_once_and_nothing_when_nothing_is():
    said = []
    budget = LogBudget(lambda level, text: said.append(text), per_period=1, clock=Clock())
    budget.flush()
    assert said == []
    budget.warn('a')
    budget.warn('b')
    budget.warn('c')
    budget.flush()
    assert said == ['a', '2 more warning(s) like those above in 1 s, not said one by one; '
                         'the last: c']


@pytest.mark.parametrize('per_period, period_s', [(0, 1.0), (5, 0.0)])
def test_an_impossible_budget_is_refused(per_period, period_s):
    with pytest.raises(ValueError):
        LogBudget(lambda *_: None, per_period=per_period, period_s=period_s)

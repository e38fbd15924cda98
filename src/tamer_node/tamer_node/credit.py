"""
Credit assignment: which (state, action) pairs a feedback labels, and with what weight.

Times are integer nanoseconds of simulation time. A step T "spans" [t_start, t_end): from the
moment its observation was shown (its stamp) until the next observation replaced it.

- ``step``: feedback stamped T labels exactly (s_T, a_T), weight 1 (the thesis's simple TAMER;
  the synthetic trainer stamps each feedback with the step it judges).
- ``window`` (Deep TAMER): a person's feedback arriving at time t was caused by something they
  saw between t - 4 s and t - 0.2 s, every delay in that range equally likely (a uniform delay
  density). A step's weight is the probability that the delay lands in its span: the overlap of
  [t_start, t_end) with [t - max, t - min] divided by (max - min). Weights of all steps sum to at
  most 1; a pair with zero weight gets no sample at all.
- ``window`` anchored at the ``effect`` (``credit_anchor``): in a world that changes in discrete
  steps (MiniGrid: 1 s a step) a person judges an action when its result is shown, the next
  observation, not at a moment spread over the step's span. Step T's delay is then
  t - t_end(T); every acted step whose delay lies in [min, max] is equally likely, its weight
  1 / (their number). The span model spreads one verdict over about (max - min + step) / step
  steps; this one over (max - min) / step.
"""

from typing import Dict, Iterable, List, Sequence, Tuple

NS_PER_S = 1_000_000_000

Span = Tuple[int, int, int]
"""(stamp, t_start, t_end) of one step, nanoseconds."""


def step_credit(judged_stamp: int, known_stamps: Iterable[int]) -> Dict[int, float]:
    """{judged_stamp: 1.0} if that step is known, else {} (nothing to label)."""
    return {judged_stamp: 1.0} if judged_stamp in set(known_stamps) else {}


def window_ns(min_delay_s: float, max_delay_s: float) -> Tuple[int, int]:
    """Return the credit window's (min, max) delay in ns; refuse an empty window."""
    min_delay = int(round(min_delay_s * NS_PER_S))
    max_delay = int(round(max_delay_s * NS_PER_S))
    if max_delay <= min_delay:
        raise ValueError('the credit window needs min_delay_s < max_delay_s')
    return min_delay, max_delay


def window_weight(t_start: int, t_end: int, feedback_time: int,
                  min_delay_s: float = 0.2, max_delay_s: float = 4.0) -> float:
    """Probability mass of the uniform delay density that falls on [t_start, t_end)."""
    min_delay, max_delay = window_ns(min_delay_s, max_delay_s)
    lo, hi = feedback_time - max_delay, feedback_time - min_delay
    overlap = min(t_end, hi) - max(t_start, lo)
    return overlap / (max_delay - min_delay) if overlap > 0 else 0.0


def window_credit(spans: Sequence[Span], feedback_time: int,
                  min_delay_s: float = 0.2, max_delay_s: float = 4.0) -> Dict[int, float]:
    """{stamp: weight} for every step whose span overlaps the window; zero weights left out."""
    credit = {}
    for stamp, t_start, t_end in spans:
        weight = window_weight(t_start, t_end, feedback_time, min_delay_s, max_delay_s)
        if weight > 0.0:
            credit[stamp] = weight
    return credit


def effect_credit(spans: Sequence[Span], feedback_time: int,
                  min_delay_s: float = 0.2, max_delay_s: float = 4.0) -> Dict[int, float]:
    """
    Return {stamp: 1/n} for the n steps whose result showed ``min``-``max`` s before feedback.

    A step's result is shown when its span ends (the next observation); the newest step, whose
    span runs to ``feedback_time``, has shown none yet.
    """
    min_delay, max_delay = window_ns(min_delay_s, max_delay_s)
    shown = [stamp for stamp, _, t_end in spans
             if t_end < feedback_time and min_delay <= feedback_time - t_end <= max_delay]
    return {stamp: 1.0 / len(shown) for stamp in shown}


def spans_from_stamps(stamps: Sequence[int], now: int) -> List[Span]:
    """Spans of consecutive steps: each lasts until the next stamp, the newest until ``now``."""
    ordered = sorted(stamps)
    ends = ordered[1:] + [max(now, ordered[-1])] if ordered else []
    return [(stamp, stamp, end) for stamp, end in zip(ordered, ends)]

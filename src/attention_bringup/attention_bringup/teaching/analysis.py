"""
The teaching evaluation's numbers, from the trials' result files (pure).

Per setting: key rate with its Wilson interval, steps to the first key (median of the trials
that took it; a trial without the key counts as the budget in the Welch test, so the test
compares "time to key, censored at 10,000"), the furthest critical position passed (within
alpha, the old study's measure) and stood on (on the ground, a ladder or the rope, alive a
second later), lives lost, feedback given, the learner's updates per step.
"""

from typing import Dict, List, Mapping, Optional, Sequence

from attention_bringup.study import stats
from attention_bringup.teaching.settings import COMPARISONS, SETTINGS, TARGETS
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS

MEASURES = {
    'steps_to_key': 'steps to the first key (no key: the budget)',
    'furthest_stood': 'furthest critical position stood on',
    'furthest_passed': f'furthest critical position passed (within {DEFAULT_RADIUS:g} px)',
    'lives_lost': 'lives lost',
}


def value(record: Mapping, measure: str) -> Optional[float]:
    """One trial's value of a measure (None when the record lacks it)."""
    if measure == 'steps_to_key':
        key = record.get('first_key_step')
        return float(record['budget'] if key is None else key)
    if measure == 'furthest_stood':
        stood = record.get('furthest_position_stood')
        return None if stood is None else float(stood)
    if measure == 'furthest_passed':
        return float(record['furthest_position'])
    if measure == 'feedback':  # the learner's count; the launcher hears no plain feedback
        count = record.get('feedback_received', record.get('feedback_count'))
        return None if count is None else float(count)
    return float(record[measure]) if record.get(measure) is not None else None


def values(records: Sequence[Mapping], measure: str) -> List[float]:
    return [v for v in (value(r, measure) for r in records) if v is not None]


def median(numbers: Sequence[float]) -> Optional[float]:
    ordered = sorted(numbers)
    if not ordered:
        return None
    middle = len(ordered) // 2
    if len(ordered) % 2:
        return float(ordered[middle])
    return (ordered[middle - 1] + ordered[middle]) / 2.0


def summarize(records: Sequence[Mapping]) -> dict:
    n = len(records)
    keyed = sorted(r['first_key_step'] for r in records if r.get('first_key_step') is not None)
    low, high = stats.wilson_interval(len(keyed), n)
    summary = {
        'n': n, 'keys': len(keyed), 'key_rate': len(keyed) / n if n else None,
        'key_ci': [low, high], 'first_key_steps': keyed,
        'median_steps_to_key': median(keyed),
        'median_steps_to_key_censored': median(values(records, 'steps_to_key')),
        'wall_time_s': sum(r.get('wall_time_s', 0.0) for r in records),
    }
    for measure in ('furthest_stood', 'furthest_passed', 'lives_lost', 'feedback',
                    'updates_per_step', 'training_steps_per_s'):
        estimate = stats.mean_ci(values(records, measure))
        summary[measure] = {'mean': estimate.mean, 'low': estimate.low, 'high': estimate.high}
    return summary


def key_curve(records: Sequence[Mapping], budget: int, every: int = 100) -> dict:
    """Fraction of trials holding a key by each step, with Wilson bands."""
    steps = list(range(0, budget + 1, every))
    fraction, low, high = [], [], []
    for step in steps:
        hits = sum(1 for r in records
                   if r.get('first_key_step') is not None and r['first_key_step'] <= step)
        lo, hi = stats.wilson_interval(hits, len(records))
        fraction.append(hits / len(records) if records else 0.0)
        low.append(lo)
        high.append(hi)
    return {'steps': steps, 'fraction': fraction, 'low': low, 'high': high}


def compare(test: Sequence[Mapping], baseline: Sequence[Mapping]) -> Dict[str, dict]:
    """Welch tests of every measure, test minus baseline."""
    out = {}
    for measure in MEASURES:
        result = stats.welch_t_test(values(test, measure), values(baseline, measure))
        out[measure] = {'mean_test': result.mean_a, 'mean_baseline': result.mean_b,
                        'difference': result.difference, 't': result.t, 'df': result.df,
                        'p': result.p, 'hedges_g': result.hedges_g, 'note': result.note}
    return out


def targets(summaries: Mapping[str, dict]) -> Dict[str, dict]:
    """Whether each issue target is met."""
    out = {}
    for name, (min_keys, max_median) in TARGETS.items():
        summary = summaries.get(name)
        if not summary:
            continue
        met = summary['keys'] >= min_keys and summary['n'] >= 10
        if max_median is not None:
            median_steps = summary['median_steps_to_key']
            met = met and median_steps is not None and median_steps <= max_median
        out[name] = {'min_keys': min_keys, 'max_median': max_median, 'met': met}
    return out


def analyse(by_setting: Mapping[str, Sequence[Mapping]], budget: int) -> dict:
    summaries = {name: summarize(records) for name, records in by_setting.items() if records}
    comparisons = {f'{a} vs {b}': compare(by_setting[a], by_setting[b])
                   for a, b in COMPARISONS if by_setting.get(a) and by_setting.get(b)}
    return {'budget': budget, 'settings': summaries, 'comparisons': comparisons,
            'curves': {name: key_curve(records, budget)
                       for name, records in by_setting.items() if records},
            'targets': targets(summaries), 'order': [n for n in SETTINGS if n in summaries]}

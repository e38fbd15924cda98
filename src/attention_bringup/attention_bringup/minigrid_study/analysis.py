"""
The DoorKey study's numbers: per condition and against vanilla (pure; result files in).

Per trial the measures of ``measures.trial_measures``; per condition their means with t
intervals, the pooled held-out success with its Wilson interval, and Welch's test of each
condition against vanilla (Hedges' g, Holm's adjustment over the five comparisons of a measure).
"""

from typing import Dict, List, Mapping, Sequence

from attention_bringup.experiment.stats import estimate, median, welch_rows, wilson_interval
from attention_bringup.minigrid_study.measures import CURVE_BINS, SUBGOALS

BASELINE = 'vanilla'
COMPARED = ('heldout_success', 'heldout_progress', 'solved', 'training_progress')
"""Per-trial measures tested against vanilla."""


def _values(records: Sequence[Mapping], name: str) -> List[float]:
    return [float(r['doorkey'][name]) for r in records if r['doorkey'].get(name) is not None]


def condition_summary(records: Sequence[Mapping]) -> dict:
    """Means, intervals and pooled rates of one condition's trials."""
    summary = {'trials': len(records),
               'completed': sum(r.get('outcome') == 'completed' for r in records)}
    for name in ('episodes', 'solved', 'training_success', 'heldout_success',
                 'heldout_episodes', 'training_progress', 'heldout_progress',
                 'heldout_key_rate'):
        summary[name] = estimate(_values(records, name))
    solved = sum(r['doorkey']['heldout_solved'] for r in records)
    episodes = sum(r['doorkey']['heldout_episodes'] for r in records)
    low, high = wilson_interval(solved, episodes)
    summary['heldout_success_pooled'] = {'solved': solved, 'episodes': episodes,
                                         'rate': solved / episodes if episodes else None,
                                         'low': low, 'high': high}
    summary['trials_solving_heldout'] = sum(r['doorkey']['heldout_solved'] > 0 for r in records)
    summary['first_step'] = {}
    for name in SUBGOALS:
        steps = [r['doorkey']['first_step'][name] for r in records
                 if r['doorkey']['first_step'][name] is not None]
        summary['first_step'][name] = {'trials': len(steps), 'median': median(steps)}
    summary['mean_steps_to'] = {
        name: estimate([r['doorkey']['mean_steps_to'][name] for r in records
                        if r['doorkey']['mean_steps_to'][name] is not None])
        for name in SUBGOALS}
    curves = [r['doorkey']['success_curve'] for r in records]
    summary['success_curve'] = [
        estimate([c[i] for c in curves if c[i] is not None]) for i in range(CURVE_BINS)]
    summary['updates_per_step'] = estimate(
        [float(r['updates_per_step']) for r in records if r.get('updates_per_step') is not None])
    summary['wall_time_s'] = estimate([float(r['wall_time_s']) for r in records])
    summary['action_shares'] = {
        kind: estimate([r['doorkey']['action_shares'][kind] for r in records
                        if 'action_shares' in r['doorkey']])
        for kind in ('turn', 'forward', 'other')}
    return summary


def comparisons(by_condition: Mapping[str, Sequence[Mapping]]) -> Dict[str, List[dict]]:
    """Welch's test of every condition against vanilla, per measure, Holm-adjusted."""
    if BASELINE not in by_condition:
        return {}
    others = [c for c in by_condition if c != BASELINE]
    return {name: welch_rows(({'condition': c}, _values(by_condition[c], name),
                              _values(by_condition[BASELINE], name)) for c in others)
            for name in COMPARED}


def analyse(by_condition: Mapping[str, Sequence[Mapping]], budget: int) -> dict:
    """Everything the report shows."""
    return {'budget': budget,
            'conditions': {c: condition_summary(r) for c, r in by_condition.items() if r},
            'comparisons': comparisons({c: r for c, r in by_condition.items() if r})}

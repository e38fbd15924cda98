"""
From trial result files to what the report states (pure: dicts and numbers in, dicts out).

Progress to position p means the furthest critical position so far is p or beyond: the first
step at which the agent stood on p or any later position. Reaching a later position counts for
the earlier ones too (a jump can carry the agent past a position's radius in one step).

Censoring: a trial that never reaches p within its budget has no step count for p. Tables give
the reach rate (with a Wilson 95 % interval) and the mean steps over the trials that reached p;
the t-tests on steps to p count an unreached trial as budget + 1 steps (a lower bound of its
true value, so differences in steps are if anything understated).

Where the agent spends its steps: the fraction of a trial's recorded steps within alpha
(``attention_tasks.montezuma.critical_positions.DEFAULT_RADIUS``) of each critical position (-1: of
none), averaged over trials, with the trainer's mean h. Result files written before these fields
existed count as unknown (left out), not as zero.
"""

from collections import Counter
from typing import Dict, List, Mapping, Optional, Sequence

from attention_bringup.experiment import stats
from attention_bringup.experiment.trials import is_usable, PLACES, POSITIONS

BASELINE = 'vanilla'
TESTED_POSITIONS = (1, 2, 3)
"""Positions whose steps-to-reach are t-tested (the thesis's figures show 1 to 3)."""
MEASURES = ('furthest_position',) + tuple(f'steps_to_{p}' for p in TESTED_POSITIONS)
SETTLED_SHARE = 0.5
"""A trial settled near a position if more than this share of its steps was spent there."""


def progress_step(record: Mapping, position: int) -> Optional[int]:
    """Return the first step at which the agent stood on ``position`` or a later one."""
    steps = [step for p, step in record['first_step_at_position'].items()
             if int(p) >= position and step is not None]
    return min(steps) if steps else None


def censored_steps(record: Mapping, position: int) -> int:
    """Return steps to reach ``position``, or budget + 1 when it was never reached."""
    step = progress_step(record, position)
    return record['budget'] + 1 if step is None else step


def step_grid(budget: int, points: int = 101) -> List[int]:
    """Return ``points`` evenly spaced steps from 0 to budget."""
    return sorted({round(budget * i / (points - 1)) for i in range(points)})


def reach_curve(records: Sequence[Mapping], position: int, grid: Sequence[int]) -> dict:
    """Fraction of trials with progress to ``position`` by each step, with Wilson 95 % bands."""
    firsts = [progress_step(record, position) for record in records]
    return dict(stats.reach_curve(firsts, grid), n=len(records))


def furthest_curve(records: Sequence[Mapping]) -> dict:
    """Mean furthest position over steps, with t-based 95 % bands."""
    if not records:
        return {'steps': [], 'mean': [], 'low': [], 'high': [], 'n': 0}
    every = records[0]['curve_every']
    length = min(len(record['furthest_curve']) for record in records)
    budget = records[0]['budget']
    steps = [min(i * every, budget) for i in range(length)]
    means, lows, highs = [], [], []
    for i in range(length):
        estimate = stats.mean_ci([record['furthest_curve'][i] for record in records])
        means.append(estimate.mean)
        lows.append(estimate.low if estimate.low is not None else estimate.mean)
        highs.append(estimate.high if estimate.high is not None else estimate.mean)
    return {'steps': steps, 'mean': means, 'low': lows, 'high': highs, 'n': len(records)}


def position_shares(record: Mapping) -> Optional[Dict[str, float]]:
    """Return the share of the trial's recorded steps at each place (None: not recorded)."""
    counts = record.get('steps_at_position')
    total = sum(counts.values()) if counts else 0
    if not total:
        return None
    return {str(p): counts.get(str(p), 0) / total for p in PLACES}


def where_steps_go(records: Sequence[Mapping]) -> dict:
    """Mean step shares per place, trials settled near one position, and mean h."""
    usable = [record for record in records if is_usable(record)]
    shares = [s for s in (position_shares(r) for r in usable) if s is not None]
    settled = dict.fromkeys((str(p) for p in POSITIONS), 0)
    for share in shares:
        top = max(POSITIONS, key=lambda p: share[str(p)])
        if share[str(top)] > SETTLED_SHARE:
            settled[str(top)] += 1
    mean_share = {str(p): stats.mean_of([s[str(p)] for s in shares]) for p in PLACES}
    return {
        'n': len(shares),
        'share': mean_share,
        'settled': settled,
        'feedback_mean': stats.estimate([r['feedback_mean'] for r in usable
                                         if r.get('feedback_mean') is not None]),
    }


def reward_variants(records: Sequence[Mapping]) -> List[str]:
    """Return the feedback_node reward variants the trials recorded (sorted, distinct)."""
    found = {record.get('parameters', {}).get('feedback_node.reward_variant')
             for record in records}
    return sorted(str(variant) for variant in found if variant is not None)


def summarize_condition(condition: str, records: Sequence[Mapping]) -> dict:
    """Aggregate one condition's trials (only those whose whole budget was recorded)."""
    usable = [record for record in records if is_usable(record)]
    outcomes = dict(Counter(record['outcome'] for record in records))
    n = len(usable)
    steps_to = {}
    for position in POSITIONS:
        reached = [progress_step(r, position) for r in usable
                   if progress_step(r, position) is not None]
        steps_to[str(position)] = {
            'reach': stats.proportion(len(reached), n),
            'reachers': stats.estimate(reached),
            'median_reachers': stats.median(reached),
            'censored': stats.estimate([censored_steps(r, position) for r in usable]),
        }
    return {
        'condition': condition,
        'trials': len(records),
        'usable': n,
        'seeds': [record['seed'] for record in usable],
        'outcomes': outcomes,
        'furthest_position': stats.estimate([r['furthest_position'] for r in usable]),
        'furthest_counts': {str(p): sum(1 for r in usable if r['furthest_position'] == p)
                            for p in PLACES},
        'steps_to': steps_to,
        'key': stats.proportion(sum(1 for r in usable if r['key']), n),
        'episodes': stats.estimate([r['episodes'] for r in usable]),
        'lives_lost': stats.estimate([r['lives_lost'] for r in usable]),
        'wall_time_s': stats.estimate([r['wall_time_s'] for r in usable]),
        'updates_per_step': stats.estimate([r['learner_updates'] / r['steps'] for r in usable
                                            if r.get('learner_updates') is not None
                                            and r['steps']]),
        'where': where_steps_go(usable),
    }


def measure_values(records: Sequence[Mapping], measure: str) -> List[float]:
    usable = [record for record in records if is_usable(record)]
    if measure == 'furthest_position':
        return [record['furthest_position'] for record in usable]
    position = int(measure.rsplit('_', 1)[1])
    return [censored_steps(record, position) for record in usable]


def compare_to_baseline(by_condition: Mapping[str, Sequence[Mapping]],
                        baseline: str = BASELINE) -> List[dict]:
    """Welch t-tests of every other condition against the baseline, Holm-adjusted together."""
    base = by_condition.get(baseline, [])
    return stats.welch_rows(
        ({'condition': condition, 'measure': measure}, measure_values(records, measure),
         measure_values(base, measure))
        for condition, records in by_condition.items() if condition != baseline
        for measure in MEASURES)


def analyse(by_condition: Mapping[str, Sequence[Mapping]]) -> dict:
    """Everything the figures and the report use, for the given conditions' result files."""
    budgets = {record['budget'] for records in by_condition.values() for record in records}
    if len(budgets) > 1:
        raise ValueError(f'trial files with different budgets ({sorted(budgets)}) in one study; '
                         'keep each budget in its own --out folder')
    budget = budgets.pop() if budgets else 0
    grid = step_grid(budget) if budget else []
    conditions = {}
    for condition, records in by_condition.items():
        usable = [record for record in records if is_usable(record)]
        summary = summarize_condition(condition, records)
        summary['reach_curves'] = {str(p): reach_curve(usable, p, grid) for p in POSITIONS}
        summary['furthest_curve'] = furthest_curve(usable)
        conditions[condition] = summary
    every = [record for records in by_condition.values() for record in records]
    return {
        'budget': budget,
        'conditions': conditions,
        'where': where_steps_go(every),
        'reward_variants': reward_variants(every),
        'tests': compare_to_baseline(by_condition) if BASELINE in by_condition else [],
        'problems': [
            {key: record.get(key) for key in ('condition', 'seed', 'outcome', 'exit_code',
                                              'steps', 'launcher_status', 'problem')}
            for records in by_condition.values() for record in records
            if record['outcome'] != 'completed'],
    }

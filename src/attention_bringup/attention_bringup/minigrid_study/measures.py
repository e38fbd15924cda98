"""
What a DoorKey trial measures, from its ``progress.csv`` (pure: rows in, numbers out).

Per episode: whether it was solved (the goal reached), on a held-out layout or not, its length,
and the episode step at which each sub-goal (key, door, goal) was first done. Per trial: the
episodes solved, the success rate on held-out layouts (the last part of the run, layouts the
learner never saw), the agent step at which each sub-goal was first done, and the success rate
over training (for the curves).
"""

import csv
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

SUBGOALS = ('key', 'door', 'goal')
CURVE_BINS = 10
"""Training success curve: episodes ended in each tenth of the budget."""


def _int(text, default: int = -1) -> int:
    try:
        return int(float(text))
    except (TypeError, ValueError):
        return default


def read_rows(path: Path) -> List[Dict[str, int]]:
    """The columns the measures need, as ints ([] without a file)."""
    columns = ('agent_step', 'episode', 'episode_step', 'position', 'heldout', 'session')
    try:
        with open(path, newline='') as handle:
            return [{name: _int(row.get(name)) for name in columns}
                    for row in csv.DictReader(handle)]
    except OSError:
        return []


def episodes_of(rows: Sequence[Mapping[str, int]]) -> List[dict]:
    """
    Return one dict per episode, in order: its first and last agent step, length, held-out,
    solved, and the episode step of each sub-goal (None: not done). The last episode, cut by
    the budget, has ``ended`` False.
    """
    episodes: List[dict] = []
    current: Optional[dict] = None
    for row in rows:
        key = (row['session'], row['episode'])
        if current is None or current['key'] != key:
            current = {'key': key, 'first_step': row['agent_step'], 'last_step': row['agent_step'],
                       'heldout': bool(row['heldout'] == 1), 'length': 0, 'ended': False,
                       **{f'{name}_at': None for name in SUBGOALS}}
            episodes.append(current)
        current['last_step'] = row['agent_step']
        current['length'] = max(current['length'], row['episode_step'])
        for index, name in enumerate(SUBGOALS):
            if row['position'] >= index and current[f'{name}_at'] is None:
                current[f'{name}_at'] = row['episode_step']
    for episode, following in zip(episodes, episodes[1:]):
        episode['ended'] = True
    if episodes and episodes[-1]['goal_at'] is not None:
        episodes[-1]['ended'] = True
    for episode in episodes:
        episode['solved'] = episode['goal_at'] is not None
        del episode['key']
    return episodes


def first_steps(rows: Sequence[Mapping[str, int]]) -> Dict[str, Optional[int]]:
    """Return the agent step at which each sub-goal was first done in the trial."""
    first: Dict[str, Optional[int]] = dict.fromkeys(SUBGOALS)
    for row in rows:
        for index, name in enumerate(SUBGOALS):
            if row['position'] >= index and first[name] is None:
                first[name] = row['agent_step']
    return first


def success_curve(episodes: Sequence[Mapping], budget: int, bins: int = CURVE_BINS
                  ) -> List[Optional[float]]:
    """Fraction of the episodes ended in each of ``bins`` parts of the budget that were solved."""
    ended = [[0, 0] for _ in range(bins)]
    for episode in episodes:
        if not episode['ended']:
            continue
        part = min(bins - 1, max(0, (episode['last_step'] - 1) * bins // max(1, budget)))
        ended[part][0] += int(episode['solved'])
        ended[part][1] += 1
    return [solved / total if total else None for solved, total in ended]


def trial_measures(rows: Sequence[Mapping[str, int]], budget: int) -> dict:
    """Everything the report needs of one trial."""
    episodes = episodes_of(rows)
    ended = [e for e in episodes if e['ended']]
    training = [e for e in ended if not e['heldout']]
    heldout = [e for e in ended if e['heldout']]
    solved = [e for e in ended if e['solved']]

    def rate(group):
        return sum(e['solved'] for e in group) / len(group) if group else None

    def progress(group):  # sub-goals done per episode, 0..3
        done = [sum(e[f'{name}_at'] is not None for name in SUBGOALS) for e in group]
        return sum(done) / len(done) if done else None

    def mean_of(values):
        values = [v for v in values if v is not None]
        return sum(values) / len(values) if values else None

    return {
        'episodes': len(ended),
        'solved': len(solved),
        'training_episodes': len(training),
        'training_solved': sum(e['solved'] for e in training),
        'training_success': rate(training),
        'heldout_episodes': len(heldout),
        'heldout_solved': sum(e['solved'] for e in heldout),
        'heldout_success': rate(heldout),
        'training_progress': progress(training),
        'heldout_progress': progress(heldout),
        'heldout_key_rate': (sum(e['key_at'] is not None for e in heldout) / len(heldout)
                             if heldout else None),
        'first_step': first_steps(rows),
        'mean_steps_to': {name: mean_of([e[f'{name}_at'] for e in solved])
                          for name in SUBGOALS},
        'subgoal_episodes': {name: sum(e[f'{name}_at'] is not None for e in ended)
                             for name in SUBGOALS},
        'success_curve': success_curve(episodes, budget),
    }

"""
What a DoorKey trial measures, from its ``progress.csv`` (pure: rows in, numbers out).

Per episode: whether it was solved (the goal reached), on a held-out layout or not, its length,
and the episode step at which each sub-goal (key, door, goal) was first done. Per trial: the
episodes solved, the success rate on held-out layouts (the last part of the run, layouts the
learner never saw), the agent step at which each sub-goal was first done, and the success rate
over training (for the curves).
"""

from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

from attention_bringup.experiment.stats import mean_of
from attention_bringup.experiment.trials import read_progress

SUBGOALS = ('key', 'door', 'goal')
CURVE_BINS = 10
"""Training success curve: episodes ended in each tenth of the budget."""


def read_rows(path: Path) -> List[Dict[str, int]]:
    """Return the columns the measures need, as ints ([] without a file)."""
    return read_progress(path, ('agent_step', 'episode', 'episode_step', 'position', 'heldout',
                                'session', 'action'))


def episodes_of(rows: Sequence[Mapping[str, int]]) -> List[dict]:
    """
    Return one dict per episode, in order.

    Each has its first and last agent step, length, held-out, solved, and the episode step of
    each sub-goal (None: not done). The last episode, cut by the budget, has ``ended`` False.
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
    for episode in episodes[:-1]:  # a later one began: this one ended
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
        return mean_of(e['solved'] for e in group)

    def progress(group):  # sub-goals done per episode, 0..3
        return mean_of(sum(e[f'{name}_at'] is not None for name in SUBGOALS) for e in group)

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
        'heldout_key_rate': mean_of(e['key_at'] is not None for e in heldout),
        'first_step': first_steps(rows),
        'mean_steps_to': {name: mean_of([e[f'{name}_at'] for e in solved])
                          for name in SUBGOALS},
        'subgoal_episodes': {name: sum(e[f'{name}_at'] is not None for e in ended)
                             for name in SUBGOALS},
        'success_curve': success_curve(episodes, budget),
        'action_shares': action_shares(rows[-len(rows) // 4:] if rows else []),
    }


def action_shares(rows: Sequence[Mapping[str, int]]) -> Dict[str, float]:
    """Return the share of turns, forward moves and the rest (pick up, drop, toggle)."""
    actions = [row['action'] for row in rows if row.get('action', -1) >= 0]
    if not actions:
        return {'turn': 0.0, 'forward': 0.0, 'other': 0.0}
    n = len(actions)
    turns = sum(a in (0, 1) for a in actions)
    forward = sum(a == 2 for a in actions)
    return {'turn': turns / n, 'forward': forward / n, 'other': (n - turns - forward) / n}


def chance_levels(episodes: int = 200, seed: int = 0, max_episode_steps: int = 100) -> dict:
    """
    Return what uniformly random actions achieve on held-out layouts (the study's level).

    The floor every condition is to be compared with: the fraction of episodes solved and the
    sub-goals done per episode by a policy that learned nothing.
    """
    import numpy as np
    from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
    from attention_tasks.gridworld import NUM_ACTIONS
    from attention_tasks.doorkey.expert import next_action
    rng = np.random.default_rng(seed)
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed, heldout_after=1,
                                      max_episode_steps=max_episode_steps), render=False)
    done = []
    step = env.reset()
    step = env.step(int(rng.integers(NUM_ACTIONS)))  # past heldout_after: held-out layouts next
    while not step.done:
        step = env.step(int(rng.integers(NUM_ACTIONS)))
    for _ in range(episodes):
        step, best = env.reset(), 0
        while not step.done:
            step = env.step(int(rng.integers(NUM_ACTIONS)))
            best = max(best, step.state.status()['subgoals'])
        done.append(best)
    expert_actions, expert_solved = [], 0
    for _ in range(episodes // 4):  # the expert on held-out layouts: the ceiling, its actions
        step = env.reset()
        while not step.done:
            action = next_action(env.world)
            step = env.step(int(rng.integers(NUM_ACTIONS)) if action is None else action)
            expert_actions.append({'action': step.action})
        expert_solved += int(step.state.at_goal)
    env.close()
    judged = judged_good_by_kind(seed)
    return {'episodes': episodes, 'solved': sum(d == 3 for d in done) / episodes,
            'judged_good': judged,
            'progress': sum(done) / episodes,
            'key': sum(d >= 1 for d in done) / episodes,
            'expert_solved': expert_solved / (episodes // 4),
            'expert_action_shares': action_shares(expert_actions)}


def _kind(action: int) -> str:
    return {0: 'turn', 1: 'turn', 2: 'forward'}.get(int(action), 'other')


def judged_good_by_kind(seed: int = 0, steps: int = 3000) -> Dict[str, float]:
    """
    Return how often the teacher judges a random action "as good as the expert's", by kind.

    Under random play (what a learner does before it has learned): turns, forward moves, and
    the rest (pick up, drop, toggle), each the fraction judged +1 where the expert has a plan.
    """
    import numpy as np
    from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
    from attention_tasks.gridworld import NUM_ACTIONS
    from attention_tasks.doorkey.teaching import KNOWLEDGE
    from env_node.status import Counters, parse_status, status_values
    rng = np.random.default_rng(seed)
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed, max_episode_steps=100), render=False)
    good = {'turn': 0, 'forward': 0, 'other': 0}
    total = dict(good)
    step = env.reset()
    for _ in range(steps):
        state = KNOWLEDGE.observe(parse_status(status_values(step, Counters(), False)))
        expert = KNOWLEDGE.expert_action(state)
        action = int(rng.integers(NUM_ACTIONS))
        if expert is not None:
            total[_kind(action)] += 1
            good[_kind(action)] += int(KNOWLEDGE.as_good(state, action, expert))
        step = env.step(action)
        if step.done:
            step = env.reset()
    env.close()
    return {kind: good[kind] / total[kind] if total[kind] else None for kind in good}

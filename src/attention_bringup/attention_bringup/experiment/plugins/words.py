"""
Fetch, where only the words say the goal (``docs/results_words.md``, issue 25): the plug-in.

Every episode draws a room and a target among its four objects, said only in words. From
``heldout_after`` on (the last ``heldout_fraction`` of the budget; ``parameters`` are the doorkey
plug-in's), every episode has a held-out layout and one of the six held-out colour-kind pairs
as its target. A trial's measures come from
its ``progress.csv`` (``position`` is 1 once the target is in hand): the success of the episodes
that ended in the last quarter of the training part (new rooms, trained pairs), and of the
held-out ones. Each arm's trials give one rate each; arms are compared on the held-out rate with
Welch's t-test and Hedges' g (``experiment.stats``), as the other reports are.
"""

from pathlib import Path
from typing import Dict, List, Mapping

from attention_bringup.experiment import markdown, stats
from attention_bringup.experiment.plugins.doorkey import heldout_after, parameters  # noqa: F401
from attention_bringup.experiment.spec import Spec
from attention_bringup.experiment.trials import read_progress
from attention_bringup.params import load_params_file, node_params, ParamsFileError
from attention_common.run_files import PARAMS_FILE, PROGRESS_FILE

OBJECTS = 4
CHANCE = 1.0 / OBJECTS
"""A learner that picks up one of the room's four objects at random, every episode."""


def episodes_of(path: Path) -> List[dict]:
    """Return the trial's episodes: first step, held-out, solved, ended (a later one began)."""
    episodes: Dict[tuple, dict] = {}
    columns = ('agent_step', 'session', 'episode', 'episode_step', 'heldout', 'position')
    for row in read_progress(path, columns):
        episode = episodes.setdefault((row['session'], row['episode']), {
            'first_step': row['agent_step'], 'heldout': row['heldout'] == 1, 'solved': False,
            'length': 0})
        episode['length'] = max(episode['length'], row['episode_step'])
        episode['solved'] = episode['solved'] or row['position'] >= 1
    found = list(episodes.values())
    for episode in found[:-1]:
        episode['ended'] = True
    if found:
        found[-1]['ended'] = found[-1]['solved']
    return found


def trial_measures(episodes: List[dict], after: int, step_limit: int = 0) -> dict:
    """
    Return the trial's counts and rates (None for a part with no ended episode).

    ``step_limit``: the env's ``max_episode_steps``; an episode that ended before it ended with
    a pick-up (of the target or not), one that reached it, with none.
    """
    late = [e for e in episodes if e['ended'] and not e['heldout']
            and e['first_step'] >= after * 0.75]
    held = [e for e in episodes if e['ended'] and e['heldout']]

    def rate(part):
        return sum(e['solved'] for e in part) / len(part) if part else None

    def picked(part):
        return sum(1 for e in part if step_limit and e['length'] < step_limit - 1)

    return {'episodes': sum(e['ended'] for e in episodes),
            'late_training_picked': picked(late), 'heldout_picked': picked(held),
            'late_training_episodes': len(late),
            'late_training_solved': sum(e['solved'] for e in late),
            'late_training_success': rate(late),
            'heldout_episodes': len(held), 'heldout_solved': sum(e['solved'] for e in held),
            'heldout_success': rate(held)}


def measure(record: dict, run_dir: Path) -> dict:
    try:  # when the trial's held-out episodes began: its own parameters say
        env = node_params(load_params_file(run_dir / PARAMS_FILE), 'env_node')
    except ParamsFileError:
        env = {}
    after = int(env.get('heldout_after') or record['budget'])
    record['words'] = trial_measures(episodes_of(run_dir / PROGRESS_FILE), after,
                                     int(env.get('max_episode_steps') or 0))
    return record


def progress(record: Mapping) -> str:
    found = record['words']
    return (f'held-out {found["heldout_solved"]}/{found["heldout_episodes"]} solved, late '
            f'training {found["late_training_solved"]}/{found["late_training_episodes"]}')


MEASURES = ('heldout_success', 'late_training_success')


def analyse(spec: Spec, by_arm: Mapping, context: Mapping) -> dict:
    arms = {}
    for arm in spec.arms:
        records = [r for r in by_arm[arm.name] if 'words' in r]
        arm_result = {'condition': arm.condition, 'text': arm.text,
                      'launcher_args': list(arm.launcher_args), 'trials': len(records),
                      'seeds': [r['seed'] for r in records]}
        for name in MEASURES:
            values = [r['words'][name] for r in records if r['words'][name] is not None]
            arm_result[name] = stats.estimate(values)
            arm_result[name + '_per_trial'] = values
        solved = sum(r['words']['heldout_solved'] for r in records)
        episodes = sum(r['words']['heldout_episodes'] for r in records)
        picked = sum(r['words'].get('heldout_picked', 0) for r in records)
        arm_result['heldout_pooled'] = stats.proportion(solved, episodes)
        arm_result['heldout_picked'] = stats.proportion(picked, episodes)
        arm_result['target_among_picked'] = stats.proportion(solved, picked)
        arms[arm.name] = arm_result
    comparisons = []
    for comparison in spec.comparisons:
        a = arms[comparison.arm]['heldout_success_per_trial']
        b = arms[comparison.baseline]['heldout_success_per_trial']
        welch = stats.welch_t_test(a, b) if len(a) >= 2 and len(b) >= 2 else None
        comparisons.append({
            'arm': comparison.arm, 'baseline': comparison.baseline,
            'difference': (stats.mean(a) - stats.mean(b)) if a and b else None,
            'hedges_g': stats.hedges_g(a, b) if len(a) >= 2 and len(b) >= 2 else None,
            'p': welch.p if welch is not None else None})
    return {'budget': spec.budget, 'heldout_fraction': spec.settings['heldout_fraction'],
            'chance': CHANCE, 'arms': arms, 'comparisons': comparisons,
            'seeds': list(spec.seeds),
            'command': context.get('command', f'.venv/bin/attention_experiment {spec.name}'),
            'wall_time_s': sum(e.get('wall_time_s', 0.0) for e in context['log'])}


def write_report(spec: Spec, result: dict, by_arm: Mapping, context: Mapping) -> None:
    arms = result['arms']
    rows = [[f'`{name}`', found['text'] or found['condition'], found['trials'],
             markdown.mean_interval(found['heldout_success']),
             f'{found["heldout_pooled"]["k"]}/{found["heldout_pooled"]["n"]}',
             f'{found["heldout_picked"]["k"]}/{found["heldout_picked"]["n"]}',
             markdown.num(found['target_among_picked']['rate']),
             markdown.mean_interval(found['late_training_success'])]
            for name, found in arms.items()]
    compared = [[f'`{c["arm"]}` vs `{c["baseline"]}`', markdown.num(c['difference']),
                 markdown.num(c['hedges_g']), markdown.p_value(c['p'])]
                for c in result['comparisons']]
    after = heldout_after(result['budget'], result['heldout_fraction'])
    lines = [
        '# Words that say the goal: Fetch (issue 25)', '',
        f'Written by `{result["command"]}` from the result files in `{spec.out}` (one per '
        'trial; the command resumes). Do not edit by hand.', '',
        f'Each trial: {result["budget"]} agent steps of `attention_train --task fetch` through '
        f'the real graph, seeds {", ".join(map(str, result["seeds"]))} (never tuned on; '
        '"trials" says how many have run so far), from '
        f'step {after} on every episode with a held-out layout and a held-out colour-kind pair '
        f'as its target. Chance, for a learner that picks up one of the four objects at random: '
        f'{result["chance"]:.2f}. Success is a mean over trials of each trial\'s rate, with '
        'its 95 % t interval; "pooled" counts every held-out episode of the arm.', '',
        *markdown.table(['arm', 'what', 'trials', 'held-out success', 'held-out pooled',
                         'held-out episodes ended by a pick-up', 'the target, of those',
                         'late-training success'], rows), '',
        *(['## Comparisons (held-out success)', '',
           *markdown.table(['comparison', 'difference', 'Hedges g', 'Welch p'], compared), '']
          if compared else []),  # (a spec of one arm compares nothing)
        f'Wall time of the trials: {markdown.minutes(result["wall_time_s"])}.', '']
    report = Path(spec.report)
    discussion = report.with_name(f'{report.stem}_discussion.md')
    if discussion.exists():
        lines += [discussion.read_text().rstrip(), '']
    markdown.write(report, '\n'.join(lines))

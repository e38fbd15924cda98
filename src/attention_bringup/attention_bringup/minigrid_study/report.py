"""
``docs/results_minigrid.md``: the DoorKey study's report, written from the analysis (pure text
and matplotlib figures). Every number comes from the trial result files.
"""

import os
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

from attention_bringup.minigrid_study.analysis import BASELINE
from attention_bringup.minigrid_study.measures import CURVE_BINS, SUBGOALS
from attention_bringup.study.figures import COLOURS
from attention_bringup.study.report import CONDITION_TEXT

FIGURES = ('success_curves', 'heldout_success')


def _pyplot():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def draw_figures(result: Mapping, out_dir: Path) -> Dict[str, Path]:
    """Training success over the budget per condition; held-out success with Wilson bars."""
    conditions = list(result['conditions'])
    if not conditions:
        return {}
    plt = _pyplot()
    drawn = {}
    budget = result['budget']
    figure, axis = plt.subplots(figsize=(7.5, 4.2))
    centres = [(i + 0.5) * budget / CURVE_BINS for i in range(CURVE_BINS)]
    for condition in conditions:
        curve = result['conditions'][condition]['success_curve']
        points = [(x, c['mean']) for x, c in zip(centres, curve) if c['mean'] is not None]
        if points:
            axis.plot(*zip(*points), marker='o', label=condition,
                      color=COLOURS.get(condition))
    axis.set_xlabel('agent step (episodes ended in each tenth of the budget)')
    axis.set_ylabel('episodes solved (mean over trials)')
    axis.set_ylim(-0.02, 1.02)
    axis.set_xlim(0, budget)
    axis.grid(alpha=0.3)
    axis.legend(fontsize='small')
    axis.set_title('DoorKey: success over the run (the last part on held-out layouts)')
    drawn['success_curves'] = out_dir / 'success_curves.png'
    figure.tight_layout()
    figure.savefig(drawn['success_curves'], dpi=110)
    plt.close(figure)

    figure, axis = plt.subplots(figsize=(7.5, 3.8))
    for i, condition in enumerate(conditions):
        pooled = result['conditions'][condition]['heldout_success_pooled']
        if pooled['rate'] is None:
            continue
        axis.bar(i, pooled['rate'], color=COLOURS.get(condition))
        axis.errorbar(i, pooled['rate'], yerr=[[pooled['rate'] - pooled['low']],
                                               [pooled['high'] - pooled['rate']]],
                      color='black', capsize=4)
    axis.set_xticks(range(len(conditions)), conditions, rotation=20, fontsize='small')
    axis.set_ylabel('held-out episodes solved')
    axis.set_ylim(0, 1)
    axis.grid(alpha=0.3, axis='y')
    axis.set_title('Held-out layouts: episodes solved, pooled over trials (Wilson 95 %)')
    drawn['heldout_success'] = out_dir / 'heldout_success.png'
    figure.tight_layout()
    figure.savefig(drawn['heldout_success'], dpi=110)
    plt.close(figure)
    return drawn


def _num(value: Optional[float], digits: int = 2) -> str:
    return 'n/a' if value is None else f'{value:.{digits}f}'


def _ci(estimate: Mapping, digits: int = 2) -> str:
    if estimate['mean'] is None:
        return 'n/a'
    if estimate['low'] is None:
        return _num(estimate['mean'], digits)
    return (f'{estimate["mean"]:.{digits}f} [{estimate["low"]:.{digits}f}, '
            f'{estimate["high"]:.{digits}f}]')


def _p(value: Optional[float]) -> str:
    if value is None:
        return 'n/a'
    return '< 0.001' if value < 0.001 else f'{value:.3f}'


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> List[str]:
    return (['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
            + ['| ' + ' | '.join(str(cell) for cell in row) + ' |' for row in rows])


def _duration(seconds: float) -> str:
    minutes = int(round(seconds / 60))
    return f'{minutes // 60} h {minutes % 60:02d} min' if minutes >= 60 else f'{minutes} min'


def discussion(result: Mapping) -> List[str]:
    """The honest reading of the numbers, sentence by sentence from them."""
    conditions = result['conditions']
    tests = {row['condition']: row for row in result['comparisons'].get('heldout_success', [])}
    lines = []
    if BASELINE not in conditions:
        return ['Vanilla has no trials yet: nothing to compare with.']
    base = conditions[BASELINE]['heldout_success_pooled']
    lines.append(
        f'**Does vanilla learn the task?** On held-out layouts vanilla solved '
        f'{base["solved"]} of {base["episodes"]} episodes ({_num(base["rate"])}; Wilson 95 % '
        f'{_num(base["low"])}-{_num(base["high"])}), and '
        f'{conditions[BASELINE]["trials_solving_heldout"]} of {conditions[BASELINE]["trials"]} '
        'trials solved at least one: the budget was fixed so that the baseline succeeds '
        'sometimes but not always, which is what a comparison needs.')
    significant = [c for c, row in tests.items() if row['p_holm'] is not None
                   and row['p_holm'] < 0.05]
    for condition in ('language', 'language_every_step', 'blind_saliency', 'blind_obs',
                      'hidden_agent'):
        if condition not in tests:
            continue
        row = tests[condition]
        pooled = conditions[condition]['heldout_success_pooled']
        direction = 'above' if row['difference'] > 0 else 'below'
        verdict = ('significant after Holm' if condition in significant else
                   'not significant after Holm')
        lines.append(
            f'- **{condition}**: held-out success {_num(pooled["rate"])} (pooled '
            f'{pooled["solved"]}/{pooled["episodes"]}); per trial '
            f'{_num(row["mean_a"])} against vanilla {_num(row["mean_b"])}, '
            f'{abs(row["difference"]):.2f} {direction}, Hedges g {_num(row["hedges_g"])}, '
            f'Welch p {_p(row["p"])}, Holm {_p(row["p_holm"])}: {verdict}.')
    language = tests.get('language')
    if language is not None:
        helped = language['difference'] > 0 and 'language' in significant
        lines.append('')
        lines.append(
            '**Does language as supervised attention help when the world changes?** ' + (
                f'Yes here: the language condition solved {language["difference"]:.2f} more of '
                'its held-out episodes per trial than vanilla, and the difference survives '
                "Holm's adjustment." if helped else
                f'Not measurably in this study: the language condition differs from vanilla '
                f'by {language["difference"]:+.2f} in held-out success per trial (Hedges g '
                f'{_num(language["hedges_g"])}), within what 10 trials per condition cannot '
                'tell from chance.'))
    return lines


def write_report(path: Path, result: Mapping, options, figures: Mapping[str, Path],
                 command: str, log: Sequence[Mapping]) -> None:
    """Write the Markdown report."""
    path.parent.mkdir(parents=True, exist_ok=True)
    conditions = result['conditions']
    budget = result['budget']
    heldout_from = int(round(budget * (1 - options.heldout_fraction)))
    wall = sum(entry.get('wall_time_s', 0.0) for entry in log)
    parallel = log[-1]['parallel'] if log else options.parallel
    lines = [
        '# Results: language as supervised attention in a world that changes every episode',
        '',
        f'Generated by `{command}` from the trial result files in `{options.out}/trials/` '
        f'(wall time of the runs: {_duration(wall)} on {os.cpu_count()} CPU cores, '
        f'{parallel} trials at a time; the same command resumes and rewrites this file).',
        '',
        '## Protocol',
        '',
        '- **Task**: `attention_train --task doorkey`: MiniGrid DoorKey, 8 x 8 cells (6 x 6 '
        'inside), a locked door of a random colour in a wall at a random column, its key on '
        "the agent's side, the green goal square behind the door, 4 distractors (keys, balls "
        'and boxes of the other colours) on both sides; every episode a new layout, start and '
        'goal. 128 x 128 frames (16 px tiles); 6 actions; an episode ends at the goal or '
        'after 100 steps.',
        '- **Teacher**: the synthetic teacher judges each action against the planner '
        '(`attention_tasks.doorkey.expert`) in its human-like setting: feedback on a third of '
        'the steps, 0.3-1.5 s of simulation time late (0.25 s per step), 10 % of signs wrong; '
        'the learner credits it with its window (0.2-1.6 s). It says the next sub-goal ("pick '
        'up the yellow key", "open the yellow door", "go to the green square") every 10 s of '
        'simulation time (40 steps) in the language condition, every step in '
        'language_every_step.',
        f'- **Budget**: {budget} agent steps per trial, fixed before the study; from agent '
        f'step {heldout_from} on (the last {options.heldout_fraction:.0%}) every new episode '
        "has a held-out layout: seeds of the level generator that no trial's training draws "
        'and that the encoder was not pretrained on.',
        f'- **Trials**: {options.trials} per condition, seed = trial index (the same layouts '
        'in every condition for a seed).',
        '- **Encoder**: pretrained by `tamer_pretrain --task doorkey` on 2,400 DoorKey frames '
        "along the expert's routes with random detours (layouts of their own), frozen.",
        '- **Statistics**: per-trial measures; Welch tests of each condition against '
        "vanilla, Hedges' g, Holm's adjustment over the five comparisons of a measure; pooled "
        'held-out success with Wilson 95 % intervals.',
        '',
        '## Conditions',
        '',
    ]
    lines += [f'- **{c}**: {CONDITION_TEXT.get(c, "")}' for c in conditions]
    lines += ['', '## Results', '']
    rows = []
    for condition, s in conditions.items():
        pooled = s['heldout_success_pooled']
        rows.append([
            condition, f'{s["completed"]}/{s["trials"]}', _ci(s['episodes'], 1),
            _ci(s['solved'], 1), _ci(s['training_success']), _ci(s['heldout_success']),
            f'{pooled["solved"]}/{pooled["episodes"]} = {_num(pooled["rate"])} '
            f'[{_num(pooled["low"])}, {_num(pooled["high"])}]',
            f'{s["trials_solving_heldout"]}/{s["trials"]}'])
    lines += _table(['condition', 'completed', 'episodes', 'episodes solved',
                     'training success', 'held-out success (per trial)',
                     'held-out pooled [Wilson]', 'trials solving a held-out layout'], rows)
    lines += ['', 'Means with t-based 95 % intervals over trials. Success: the fraction of '
              'ended episodes that reached the goal.', '',
              '### Steps to each sub-goal', '']
    rows = []
    for condition, s in conditions.items():
        cells = [condition]
        for name in SUBGOALS:
            first = s['first_step'][name]
            cells.append(f'{first["trials"]}/{s["trials"]} trials, median step '
                         f'{_num(first["median"], 0)}')
        cells += [_ci(s['mean_steps_to'][name], 1) for name in SUBGOALS]
        rows.append(cells)
    lines += _table(['condition'] + [f'first {n} (agent step)' for n in SUBGOALS]
                    + [f'episode steps to {n} (solved episodes)' for n in SUBGOALS], rows)
    lines += ['', '### Against vanilla', '']
    for measure, tests in result['comparisons'].items():
        lines += [f'**{measure}**', '']
        lines += _table(['condition', 'mean', 'vanilla', 'difference', "Hedges' g", 'Welch p',
                         'Holm p'],
                        [[t['condition'], _num(t['mean_a']), _num(t['mean_b']),
                          f'{t["difference"]:+.2f}', _num(t['hedges_g']), _p(t['p']),
                          _p(t['p_holm'])] for t in tests])
        lines.append('')
    for name in FIGURES:
        if name in figures:
            relative = os.path.relpath(figures[name], path.parent)
            lines += [f'![{name}]({relative})', '']
    lines += ['## Discussion', ''] + discussion(result) + ['']
    path.write_text('\n'.join(lines) + '\n')

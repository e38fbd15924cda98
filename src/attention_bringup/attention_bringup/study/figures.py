"""
The study's figures (matplotlib, Agg): progress to critical positions over agent steps.

Like the thesis's Figures 5.3 and 5.4: for positions 1 to 3, the fraction of trials whose
furthest position had reached the position by each step, with Wilson 95 % bands over trials.
"""

from pathlib import Path
from typing import Dict, List, Mapping, Sequence

from attention_bringup.experiment.figures import pyplot, save

# Colours as in the thesis where it names them: vanilla blue, blind_obs red, language orange,
# blind-agent saliency green.
COLOURS = {
    'vanilla': 'tab:blue', 'blind_obs': 'tab:red', 'language_every_step': 'tab:orange',
    'blind_saliency': 'tab:green', 'language': 'tab:purple', 'hidden_agent': 'tab:gray',
}

FIGURES = {
    'figure_5_3': (('vanilla', 'blind_obs'), (1, 2, 3),
                   'vanilla vs blind_obs (thesis Figure 5.3)'),
    'figure_5_4': (('vanilla', 'language_every_step', 'blind_saliency'), (1, 2, 3),
                   'vanilla vs language_every_step vs blind_saliency (thesis Figure 5.4)'),
    'all_conditions': (('vanilla', 'language', 'blind_obs', 'blind_saliency',
                        'language_every_step', 'hidden_agent'), (0, 1, 2, 3, 4, 5),
                       'all conditions'),
}
"""File stem -> (conditions, positions, title)."""


def _present(analysis: Mapping, conditions: Sequence[str]) -> List[str]:
    """Return the conditions that have at least one usable trial, in the given order."""
    return [c for c in conditions if c in analysis['conditions']
            and analysis['conditions'][c]['usable'] > 0]


def _panel_grid(panels: int):
    """Return (figure, axes) of a grid of up to three columns with room for ``panels``."""
    columns = min(3, panels)
    rows = (panels + columns - 1) // columns
    return pyplot().subplots(rows, columns, figsize=(4.2 * columns, 3.3 * rows),
                             sharey=True, squeeze=False)


def _style_panel(axis, title: str, budget: int) -> None:
    """Title, x label, limits and grid of one reach panel."""
    axis.set_title(title, fontsize='medium')
    axis.set_xlabel('agent step')
    axis.set_ylim(-0.02, 1.02)
    axis.set_xlim(0, budget)
    axis.grid(alpha=0.3)


def plot_reach(analysis: Mapping, conditions: Sequence[str], positions: Sequence[int],
               title: str, path: Path) -> bool:
    """One panel per position: fraction of trials that progressed to it by step t."""
    present = _present(analysis, conditions)
    if not present:
        return False
    figure, axes = _panel_grid(len(positions))
    bands = len(present) <= 3  # more overlapping bands hide the curves (see plot_by_condition)
    for axis, position in zip(axes.flat, positions):
        for condition in present:
            summary = analysis['conditions'][condition]
            curve = summary['reach_curves'][str(position)]
            colour = COLOURS.get(condition)
            axis.step(curve['steps'], curve['fraction'], where='post', color=colour,
                      label=f'{condition} (n={curve["n"]})')
            if bands:
                axis.fill_between(curve['steps'], curve['low'], curve['high'],
                                  step='post', color=colour, alpha=0.25, linewidth=0)
        _style_panel(axis, f'critical position {position}', analysis['budget'])
    note = ('shaded: Wilson 95 % interval over trials' if bands else
            'intervals per condition in reach_by_condition.png')
    _finish_panels(figure, axes, len(positions),
                   f'Progress to critical positions: {title}\n({note})', path)
    return True


def plot_by_condition(analysis: Mapping, conditions: Sequence[str], path: Path) -> bool:
    """One panel per condition: progress to every position 0..5, with Wilson 95 % bands."""
    present = _present(analysis, conditions)
    if not present:
        return False
    figure, axes = _panel_grid(len(present))
    colours = pyplot().get_cmap('viridis')
    for axis, condition in zip(axes.flat, present):
        curves = analysis['conditions'][condition]['reach_curves']
        for position in range(6):
            curve = curves[str(position)]
            colour = colours(position / 5.0)
            axis.step(curve['steps'], curve['fraction'], where='post', color=colour,
                      label=f'position {position}')
            axis.fill_between(curve['steps'], curve['low'], curve['high'], step='post',
                              color=colour, alpha=0.12, linewidth=0)
        _style_panel(axis, f'{condition} (n={curves["0"]["n"]})', analysis['budget'])
    _finish_panels(figure, axes, len(present),
                   'Progress to each critical position, per condition '
                   '(shaded: Wilson 95 % interval over trials)', path)
    return True


def _finish_panels(figure, axes, used: int, title: str, path: Path) -> None:
    """Label a grid of reach panels, hide the unused ones, and save and close the figure."""
    for axis in axes[:, 0]:
        axis.set_ylabel('fraction of trials reached')
    for axis in list(axes.flat)[used:]:
        axis.set_visible(False)
    axes.flat[0].legend(loc='upper left', fontsize='small')
    figure.suptitle(title, fontsize='medium')
    save(figure, path)


def plot_furthest(analysis: Mapping, conditions: Sequence[str], path: Path) -> bool:
    """Mean furthest critical position over steps, with t-based 95 % bands."""
    present = _present(analysis, conditions)
    if not present:
        return False
    figure, axis = pyplot().subplots(figsize=(7.5, 4.2))
    for condition in present:
        curve = analysis['conditions'][condition]['furthest_curve']
        colour = COLOURS.get(condition)
        axis.plot(curve['steps'], curve['mean'], color=colour,
                  label=f'{condition} (n={curve["n"]})')
        axis.fill_between(curve['steps'], curve['low'], curve['high'], color=colour,
                          alpha=0.1, linewidth=0)
    axis.set_xlabel('agent step')
    axis.set_ylabel('furthest critical position so far')
    axis.set_yticks(range(-1, 6))
    axis.set_ylim(-1.2, 5.2)
    axis.set_xlim(0, analysis['budget'])
    axis.grid(alpha=0.3)
    axis.legend(loc='upper left', fontsize='small')
    axis.set_title('Mean furthest critical position (-1: none yet); shaded: t 95 % interval',
                   fontsize='medium')
    save(figure, path)
    return True


def draw_all(analysis: Mapping, out_dir: Path) -> Dict[str, Path]:
    """Draw every figure into ``out_dir``; return name -> path of those drawn."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    drawn = {}
    for stem, (conditions, positions, title) in FIGURES.items():
        path = out_dir / f'{stem}.png'
        if plot_reach(analysis, conditions, positions, title, path):
            drawn[stem] = path
    path = out_dir / 'reach_by_condition.png'
    if plot_by_condition(analysis, FIGURES['all_conditions'][0], path):
        drawn['reach_by_condition'] = path
    path = out_dir / 'furthest_position.png'
    if plot_furthest(analysis, FIGURES['all_conditions'][0], path):
        drawn['furthest_position'] = path
    return drawn

"""
DoorKey with a new layout every episode (``docs/results_minigrid.md``): the plug-in.

Each trial's DoorKey measures come from its ``progress.csv`` (``minigrid_study.measures``); for
the last ``heldout_fraction`` of the budget every new episode has a held-out layout (the
``heldout_after`` parameter every trial gets). The analysis and the report are
``minigrid_study.analysis`` and ``minigrid_study.report``. The spec's ``settings``:
``heldout_fraction``; optionally ``budget_note`` (the protocol's reason for the budget) and
``follow_ups`` (later studies of the level, ``{spec, text}`` each, summed up at the end).
"""

from pathlib import Path
from typing import Mapping

from attention_bringup.experiment.spec import Spec
from attention_bringup.experiment.trials import read_json
from attention_bringup.minigrid_study import analysis, report
from attention_bringup.minigrid_study.measures import chance_levels, read_rows, trial_measures
from attention_common.run_files import ANALYSIS_FILE, PROGRESS_FILE


def heldout_after(steps: int, fraction: float) -> int:
    """Agent steps after which new episodes have held-out layouts."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f'--heldout-fraction must be in (0, 1), got {fraction}')
    return int(round(steps * (1.0 - fraction)))


def parameters(spec: Spec) -> dict:
    return {'env_node': {'heldout_after': heldout_after(spec.budget,
                                                        spec.settings['heldout_fraction'])}}


def measure(record: dict, run_dir: Path) -> dict:
    """Add the DoorKey measures of the trial, from its run folder's progress.csv."""
    record['doorkey'] = trial_measures(read_rows(run_dir / PROGRESS_FILE), record['budget'])
    return record


def progress(record: Mapping) -> str:
    found = record['doorkey']
    return (f'{found["solved"]}/{found["episodes"]} episodes solved, held-out '
            f'{found["heldout_solved"]}/{found["heldout_episodes"]}')


def human_like(spec: Spec) -> bool:
    return '--human-like' in spec.launcher_args


def ask_rate(spec: Spec) -> float:
    """Return the questions a step the learner may ask (``--ask RATE``; 0: it never asks)."""
    args = list(spec.launcher_args)
    return float(args[args.index('--ask') + 1]) if '--ask' in args else 0.0


def analyse(spec: Spec, by_arm: Mapping, context: Mapping) -> dict:
    # A trial without measures was interrupted.
    records = {arm.condition: [r for r in by_arm[arm.name] if 'doorkey' in r]
               for arm in spec.arms}
    result = analysis.analyse(records, spec.budget)
    result['chance'] = chance_levels()
    result['human_like'] = human_like(spec)
    rate = ask_rate(spec)
    if rate:  # absent without questions: the earlier reports stay byte-identical
        result['ask_rate'] = rate
    result['command'] = context.get('command', f'.venv/bin/attention_experiment {spec.name}')
    result['wall_time_s'] = sum(e.get('wall_time_s', 0.0) for e in context['log'])
    return result


def write_report(spec: Spec, result: dict, by_arm: Mapping, context: Mapping) -> None:
    if context.get('reference'):
        result['reference'] = read_json(Path(context['reference']) / ANALYSIS_FILE)
    figures = report.draw_figures(result, Path(spec.out).resolve())
    report.write_report(Path(spec.report), result, spec, figures, result['command'],
                        context['log'])

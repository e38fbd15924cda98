"""
``docs/teaching.md``: the teaching evaluation's report, written from its numbers.

Every number comes from the trials' result files (``analysis.analyse``) or from the in-process
ablation files in ``<out>/ablation/`` (``tests/benchmarks/teach_inprocess.py --out``). The
figure is drawn here with matplotlib.
"""

import json
import os
from pathlib import Path
from typing import List, Mapping, Optional, Sequence

from attention_bringup.progress import ALIVE_STEPS
from attention_bringup.teaching.analysis import MEASURES
from attention_bringup.teaching.settings import SETTINGS
from attention_common.run_files import TEACHING_LOG
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS

FIGURE = 'key_by_step.png'


def _num(value, digits: int = 1) -> str:
    if value is None:
        return '-'
    if isinstance(value, int):
        return str(value)
    return f'{value:.{digits}f}'


def _p(value: Optional[float]) -> str:
    if value is None:
        return '-'
    return '< 0.001' if value < 0.001 else f'{value:.3f}'


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> List[str]:
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    return lines + ['| ' + ' | '.join(row) + ' |' for row in rows]


def draw(result: Mapping, path: Path) -> bool:
    if not result['curves']:
        return False
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(8, 4.5))
    for index, name in enumerate(result['order']):
        curve = result['curves'][name]
        axis.plot(curve['steps'], curve['fraction'], color=f'C{index}', label=name)
        axis.fill_between(curve['steps'], curve['low'], curve['high'], color=f'C{index}',
                          alpha=0.12)
    axis.set_xlabel('agent step')
    axis.set_ylabel('fraction of trials that have taken the key')
    axis.set_ylim(-0.02, 1.02)
    axis.legend(loc='lower right', fontsize='small')
    axis.set_title('The key, by step (Wilson 95 % bands)')
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return True


def settings_table(result: Mapping) -> List[str]:
    rows = []
    for name in result['order']:
        s = result['settings'][name]
        low, high = s['key_ci']
        rows.append([
            f'`{name}`', str(s['n']), f'{s["keys"]} ({low:.2f}-{high:.2f})',
            _num(s['median_steps_to_key'], 0), ', '.join(map(str, s['first_key_steps'])) or '-',
            _num(s['furthest_stood']['mean']), _num(s['furthest_passed']['mean']),
            _num(s['lives_lost']['mean']), _num(s['feedback']['mean'], 0),
            _num(s['updates_per_step']['mean'], 2), _num(s['training_steps_per_s']['mean'], 0)])
    return _table(['setting', 'trials', 'key (Wilson 95 %)', 'median steps to key',
                   'first key steps', 'furthest stood', 'furthest passed', 'lives lost',
                   'feedback', 'updates / step', 'steps/s'], rows)


def comparison_table(result: Mapping) -> List[str]:
    rows = []
    for pair, tests in result['comparisons'].items():
        for measure, test in tests.items():
            rows.append([pair, MEASURES[measure], _num(test['mean_test']),
                         _num(test['mean_baseline']), _num(test['difference']),
                         _num(test['hedges_g'], 2), _p(test['p']), test['note'] or ''])
    return _table(['comparison', 'measure', 'language', 'vanilla', 'difference', 'Hedges g',
                   'Welch p', 'note'], rows)


def ablation_rows(out_dir: Path) -> List[List[str]]:
    """One row per ``<out>/ablation/*.json`` (``teach_inprocess.py --out``), and its command."""
    rows = []
    for path in sorted((out_dir / 'ablation').glob('*.json')):
        data = json.loads(path.read_text())
        results = data['results']
        keyed = sorted(r['first_key_step'] for r in results if r['first_key_step'])
        lives = sum(r['lives_lost'] for r in results) / len(results)
        argv = list(data.get('argv', []))
        for flag in ('--what', '--out'):  # the row says what; the file is the row
            if flag in argv:
                del argv[argv.index(flag):argv.index(flag) + 2]
        command = 'teach_inprocess.py ' + ' '.join(argv)
        rows.append([f'`{path.stem}`', data.get('what', ''), str(len(results)),
                     f'{len(keyed)}', ', '.join(map(str, keyed)) or '-',
                     _num(sum(r['agreement'] for r in results) / len(results), 2),
                     _num(lives), _mean_of(results, 'furthest_stage', 1),
                     _mean_of(results, 'learned_purity', 2), f'`{command}`'])
    return rows


def _mean_of(results, key: str, digits: int) -> str:
    """Return the mean of a per-trial field of later teach_inprocess.py runs ('-' if none)."""
    values = [r[key] for r in results if r.get(key) is not None]
    return _num(sum(values) / len(values), digits) if values else '-'


def target_lines(result: Mapping) -> List[str]:
    lines = []
    for name, target in result['targets'].items():
        s = result['settings'][name]
        want = f'key in at least {target["min_keys"]} of 10'
        if target['max_median'] is not None:
            want += f', median steps to key at most {target["max_median"]:,}'
        verdict = 'met' if target['met'] else 'missed'
        lines.append(f'- `{name}`: {want}. Measured: {s["keys"]} of {s["n"]}, median '
                     f'{_num(s["median_steps_to_key"], 0)}: **{verdict}**.')
    return lines


def write(path: Path, out_dir: Path, result: Mapping, by_setting: Mapping, options) -> None:
    drawn = draw(result, out_dir / FIGURE)
    figure = os.path.relpath(out_dir / FIGURE, path.parent)
    log_path = out_dir / TEACHING_LOG
    log = json.loads(log_path.read_text()) if log_path.exists() else []
    elapsed = sum(entry.get('wall_time_s', 0.0) for entry in log)
    command = ('.venv/bin/attention_teaching --parallel 2' if options.settings == list(SETTINGS)
               else '.venv/bin/attention_teaching --settings ' + ' '.join(options.settings))
    text = [
        '# Teaching Room 1: the teacher and Deep TAMER',
        '',
        f'Generated by `{command}` from the result files in `{options.out}/`; '
        f'{sum(s["n"] for s in result["settings"].values())} trials of '
        f'{result["budget"]:,} agent steps; running them took {elapsed / 60:.0f} min of wall '
        f'time over {len(log)} invocation(s), two trials side by side on 2 cores '
        f'(`{out_dir.name}/{TEACHING_LOG}`). The command is resumable (finished trials are '
        'skipped); `--report-only` rewrites this file without running anything.',
        '',
        'Every trial is the real graph (env_node, feedback_node with `trainer:=teacher`, '
        'saliency_node, tamer_node as four processes over Fast DDS) started by `attention_train`'
        f', seeds {min(options.seeds)}-{max(options.seeds)}: none of them was used to tune '
        'anything (the teacher and the learner were tuned in one process on seeds 100-105).',
        '',
        '## Settings',
        '',
    ]
    text += [f'- `{name}`: {setting.text} (`attention_train --condition {setting.condition} '
             f'{" ".join(setting.launcher_args)}`)' for name, setting in SETTINGS.items()
             if name in result['order']]
    text += ['', '## Targets', ''] + target_lines(result)
    text += ['', '## Results', ''] + settings_table(result)
    text += ['', '*Furthest stood*: the furthest critical position the agent stood on (within '
             f'{DEFAULT_RADIUS:g} px, on the ground, a ladder or the rope, alive {ALIVE_STEPS} '
             f'steps later). *Furthest passed*: within {DEFAULT_RADIUS:g} px at any moment, in '
             'mid-air or dying too; this is the measure '
             'the Room 1 study (`docs/results.md`) used. *Feedback*: what the learner '
             'received (`feedback/received` of its metrics). *Updates / step*: learner updates '
             '(immediate and minibatch) per agent '
             'step.', '']
    if drawn:
        text += [f'![the key by step]({figure})', '']
    text += ['## Language against vanilla', '']
    text += comparison_table(result) if result['comparisons'] else ['(not run yet)']
    text += ['', 'Steps to key count a trial without the key as the budget (10,000), so the '
             'test compares censored times; with 10 trials per arm a Welch test detects only '
             'large effects (about 1.3 standard deviations at 80 % power).', '']
    rows = ablation_rows(out_dir)
    if rows:
        text += ['## What each change bought (in one process, tuning seeds)', '']
        text += _table(['variant', 'what', 'trials', 'key', 'first key steps',
                        'agreement', 'lives lost', 'furthest stage', 'label purity',
                        'command'], rows)
        text += ['', 'Each row: `tests/benchmarks/teach_inprocess.py` with the real game, the '
                 'teacher and TamerAgent in one process, 10,000 steps per trial, seeds 100-107 '
                 '(tuning seeds). *Agreement*: the share of judged actions the teacher '
                 "counted as the expert's. *Furthest stage*: the furthest stage of the "
                 "expert's route the agent's position was in (0 walk to the middle ladder ... "
                 '6 the floor, 7 up the left ladder, 8 to the key, 9 the key), mean of the '
                 'trials; at any moment, in mid-air or dying too (a fall to the floor counts), '
                 "so like 'furthest passed' it overstates progress. *Label purity*: of each "
                 "late feedback's weight in the learner's buffer at the end "
                 '(after any credit by prediction), the share on steps that did the judged '
                 'action. Both are recorded by runs from issue 23 on.', '']
    discussion = out_dir / 'discussion.md'
    if discussion.exists():
        text += ['## Discussion', '', discussion.read_text().strip(), '']
    path.write_text('\n'.join(text) + '\n')

"""
Room 1 taught by the teacher (``docs/teaching.md``): its measures, analysis and report.

Per arm: the key rate with its Wilson interval, steps to the first key (median of the trials that
took it; a trial without the key counts as the budget in the Welch test, so the test compares
"time to key, censored at the budget"), the furthest critical position passed (within alpha, the
old study's measure) and stood on (on the ground, a ladder or the rope, alive a second later),
lives lost, feedback given, the learner's updates per step. The in-process ablation's files in
``<out>/ablation/`` (``tests/benchmarks/teach_inprocess.py --out``) get a table of their own.
"""

import json
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

from attention_bringup.experiment import stats
from attention_bringup.experiment.figures import pyplot, save
from attention_bringup.experiment.markdown import image, num, p_value, table, write
from attention_bringup.experiment.spec import Spec
from attention_bringup.experiment.trials import is_usable
from attention_bringup.progress import ALIVE_STEPS
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS

FIGURE = 'key_by_step.png'
MEASURES = {
    'steps_to_key': 'steps to the first key (no key: the budget)',
    'furthest_stood': 'furthest critical position stood on',
    'furthest_passed': f'furthest critical position passed (within {DEFAULT_RADIUS:g} px)',
    'lives_lost': 'lives lost',
}


def progress(record: Mapping) -> str:
    return (f'key at {record.get("first_key_step")}, furthest stood '
            f'{record.get("furthest_position_stood")}')


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


def summarize(records: Sequence[Mapping]) -> dict:
    n = len(records)
    keyed = sorted(r['first_key_step'] for r in records if r.get('first_key_step') is not None)
    low, high = stats.wilson_interval(len(keyed), n)
    summary = {
        'n': n, 'keys': len(keyed), 'key_rate': len(keyed) / n if n else None,
        'key_ci': [low, high], 'first_key_steps': keyed,
        'median_steps_to_key': stats.median(keyed),
        'median_steps_to_key_censored': stats.median(values(records, 'steps_to_key')),
        'wall_time_s': sum(r.get('wall_time_s', 0.0) for r in records),
    }
    for measure in ('furthest_stood', 'furthest_passed', 'lives_lost', 'feedback',
                    'updates_per_step', 'training_steps_per_s'):
        summary[measure] = stats.estimate(values(records, measure))
    return summary


def key_curve(records: Sequence[Mapping], budget: int, every: int = 100) -> dict:
    """Fraction of trials holding a key by each step, with Wilson bands."""
    return stats.reach_curve([r.get('first_key_step') for r in records],
                             range(0, budget + 1, every))


def compare(test: Sequence[Mapping], baseline: Sequence[Mapping],
            measures: Sequence[str]) -> Dict[str, dict]:
    """Welch tests of every measure, test minus baseline."""
    out = {}
    for measure in measures:
        result = stats.welch_t_test(values(test, measure), values(baseline, measure))
        out[measure] = {'mean_test': result.mean_a, 'mean_baseline': result.mean_b,
                        'difference': result.difference, 't': result.t, 'df': result.df,
                        'p': result.p, 'hedges_g': result.hedges_g, 'note': result.note}
    return out


def targets(spec: Spec, summaries: Mapping[str, dict]) -> Dict[str, dict]:
    """Whether each issue target is met."""
    out = {}
    for name, target in spec.targets.items():
        summary = summaries.get(name)
        if not summary:
            continue
        min_keys, max_median = target['min_keys'], target.get('max_median')
        met = summary['keys'] >= min_keys and summary['n'] >= 10
        if max_median is not None:
            median_steps = summary['median_steps_to_key']
            met = met and median_steps is not None and median_steps <= max_median
        out[name] = {'min_keys': min_keys, 'max_median': max_median, 'met': met}
    return out


def analyse(spec: Spec, by_arm: Mapping[str, Sequence[Mapping]], context: Mapping) -> dict:
    by_arm = {name: [r for r in records if is_usable(r)] for name, records in by_arm.items()}
    summaries = {name: summarize(records) for name, records in by_arm.items() if records}
    comparisons = {f'{c.arm} vs {c.baseline}': compare(by_arm[c.arm], by_arm[c.baseline],
                                                       spec.measures)
                   for c in spec.comparisons if by_arm.get(c.arm) and by_arm.get(c.baseline)}
    return {'budget': spec.budget, 'settings': summaries, 'comparisons': comparisons,
            'curves': {name: key_curve(records, spec.budget)
                       for name, records in by_arm.items() if records},
            'targets': targets(spec, summaries),
            'order': [n for n in spec.arm_names if n in summaries]}


def draw(result: Mapping, path: Path) -> bool:
    if not result['curves']:
        return False
    figure, axis = pyplot().subplots(figsize=(8, 4.5))
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
    save(figure, path)
    return True


def _num(value, digits: int = 1) -> str:
    return num(value, digits, missing='-', whole_ints=True)


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
    return table(['setting', 'trials', 'key (Wilson 95 %)', 'median steps to key',
                  'first key steps', 'furthest stood', 'furthest passed', 'lives lost',
                  'feedback', 'updates / step', 'steps/s'], rows)


def comparison_table(result: Mapping) -> List[str]:
    rows = []
    for pair, tests in result['comparisons'].items():
        for measure, test in tests.items():
            rows.append([pair, MEASURES[measure], _num(test['mean_test']),
                         _num(test['mean_baseline']), _num(test['difference']),
                         _num(test['hedges_g'], 2), p_value(test['p'], '-'), test['note'] or ''])
    return table(['comparison', 'measure', 'language', 'vanilla', 'difference', 'Hedges g',
                  'Welch p', 'note'], rows)


def ablation_rows(out_dir: Path) -> List[List[str]]:
    """One row per ``<out>/ablation/*.json`` (``teach_inprocess.py --out``), and its command."""
    rows = []
    for path in sorted((out_dir / 'ablation').glob('*.json')):
        data = json.loads(path.read_text())
        results = data['results']
        keyed = sorted(r['first_key_step'] for r in results if r['first_key_step'])
        argv = list(data.get('argv', []))
        for flag in ('--what', '--out'):  # the row says what; the file is the row
            if flag in argv:
                del argv[argv.index(flag):argv.index(flag) + 2]
        command = 'teach_inprocess.py ' + ' '.join(argv)
        rows.append([f'`{path.stem}`', data.get('what', ''), str(len(results)),
                     f'{len(keyed)}', ', '.join(map(str, keyed)) or '-',
                     *(_num(stats.mean_of(r.get(key) for r in results), digits) for key, digits
                       in (('agreement', 2), ('lives_lost', 1), ('furthest_stage', 1),
                           ('learned_purity', 2))),
                     f'`{command}`'])
    return rows


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


def write_report(spec: Spec, result: Mapping, by_arm: Mapping, context: Mapping) -> None:
    path, out_dir = Path(spec.report), Path(spec.out)
    drawn = draw(result, out_dir / FIGURE)
    log = context['log']
    elapsed = sum(entry.get('wall_time_s', 0.0) for entry in log)
    command = context.get('command', f'.venv/bin/attention_experiment {spec.name}')
    text = [
        '# Teaching Room 1: the teacher and Deep TAMER',
        '',
        f'Generated by `{command}` from the result files in `{spec.out}/`; '
        f'{sum(s["n"] for s in result["settings"].values())} trials of '
        f'{result["budget"]:,} agent steps; running them took {elapsed / 60:.0f} min of wall '
        f'time over {len(log)} invocation(s), two trials side by side on 2 cores '
        f'(`{out_dir.name}/{spec.log}`). The command is resumable (finished trials are '
        'skipped); `--report-only` rewrites this file without running anything.',
        '',
        'Every trial is the real graph (env_node, feedback_node with `trainer:=teacher`, '
        'saliency_node, tamer_node as four processes over Fast DDS) started by `attention_train`'
        f', seeds {min(spec.seeds)}-{max(spec.seeds)}: none of them was used to tune '
        'anything (the teacher and the learner were tuned in one process on seeds 100-105).',
        '',
        '## Settings',
        '',
    ]
    text += [f'- `{arm.name}`: {arm.text} (`attention_train --condition {arm.condition} '
             f'{" ".join(arm.launcher_args)}`)' for arm in spec.arms
             if arm.name in result['order']]
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
        text += [image('the key by step', out_dir / FIGURE, path), '']
    text += ['## Language against vanilla', '']
    text += comparison_table(result) if result['comparisons'] else ['(not run yet)']
    text += ['', 'Steps to key count a trial without the key as the budget (10,000), so the '
             'test compares censored times; with 10 trials per arm a Welch test detects only '
             'large effects (about 1.3 standard deviations at 80 % power).', '']
    rows = ablation_rows(out_dir)
    if rows:
        text += ['## What each change bought (in one process, tuning seeds)', '']
        text += table(['variant', 'what', 'trials', 'key', 'first key steps',
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
    write(path, '\n'.join(text) + '\n')

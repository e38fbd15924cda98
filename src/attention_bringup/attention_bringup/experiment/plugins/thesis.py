"""
The thesis's chapter 5 study of Room 1 (``docs/results.md``): the plug-in.

The analysis, figures, report and discussion are ``study.analysis``, ``study.figures``,
``study.report`` and ``study.discussion``; crashed trials that were retried stay in the report.
"""

import os
from pathlib import Path
from typing import Mapping

from attention_bringup.experiment import runner
from attention_bringup.experiment.spec import Spec
from attention_bringup.study import analysis, figures, report


def progress(record: Mapping) -> str:
    return f'furthest position {record["furthest_position"]}, key {record["key"]}'


def _by_condition(spec: Spec, by_arm: Mapping) -> dict:
    return {arm.condition: by_arm[arm.name] for arm in spec.arms}


def analyse(spec: Spec, by_arm: Mapping, context: Mapping) -> dict:
    by_condition = _by_condition(spec, by_arm)
    result = analysis.analyse(by_condition)
    if any(by_condition.values()) and result['budget'] != spec.budget:
        raise ValueError(f'the result files in {spec.out} are of {result["budget"]} steps; '
                         f'pass --steps {result["budget"]}')
    return result


def stored(result: Mapping) -> dict:
    """analysis.json: everything but the curves (the figures show them)."""
    compact = {key: value for key, value in result.items() if key != 'conditions'}
    compact['conditions'] = {
        c: {k: v for k, v in s.items() if k not in ('reach_curves', 'furthest_curve')}
        for c, s in result['conditions'].items()}
    return compact


def write_report(spec: Spec, result: Mapping, by_arm: Mapping, context: Mapping) -> None:
    out_dir = Path(spec.out).resolve()
    by_condition = _by_condition(spec, by_arm)
    drawn = figures.draw_all(result, out_dir)
    log = [e for e in context['log'] if e.get('steps') == spec.budget]
    ran = [e for e in log if e.get('trials_run')]
    parallel = ran[-1]['parallel'] if ran else spec.parallel
    warmups = {r.get('parameters', {}).get('env_node.warmup_steps')
               for records in by_condition.values() for r in records}
    protocol = {'conditions': list(by_condition), 'trials': len(spec.seeds),
                'steps': spec.budget,
                'warmup_steps': sorted(w for w in warmups if w is not None)}
    command = context.get('command', lambda parallel: f'.venv/bin/attention_experiment '
                                                      f'{spec.name}')
    report.write_report(Path(spec.report), result, by_condition, protocol, drawn,
                        command(parallel), log, runner.load_retired(out_dir, list(by_condition)),
                        os.cpu_count(), f'{spec.out.rstrip("/")}/trials')

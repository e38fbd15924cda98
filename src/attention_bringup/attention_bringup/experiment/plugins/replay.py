"""
One recorded session replayed into a fresh learner per arm (``docs/results_replay.md``).

Each trial is ``attention_replay BAG`` (the spec's ``program``): the learner changes, the
person's teaching does not. A trial's measures are its replay's ``summary.json``; the analysis
gives each arm's agreement with the session's greedy actions (a mean over seeds, with its
interval), and the report is the table ``attention_replay --all-conditions`` prints.
"""

from pathlib import Path
from typing import List, Mapping

from attention_bringup.experiment import stats
from attention_bringup.experiment.markdown import mean_interval, table_text, write
from attention_bringup.experiment.runner import REPLAY
from attention_bringup.experiment.spec import Spec, SpecError
from attention_bringup.experiment.trials import read_json
from attention_bringup.replay.output import study_table
from attention_bringup.replay.plan import bag_folder
from attention_common import topics
from attention_common.run_files import SUMMARY_FILE
from session_bag import metadata


def bag_steps(bag: Path) -> int:
    """Return the steps a bag holds: its observations (ValueError if it is no bag)."""
    counts = metadata.topic_counts(metadata.read(bag_folder(bag)))
    return counts.get(f'/{topics.OBSERVATION}', 0)


def check(spec: Spec) -> None:
    """Refuse a replay spec without a bag, or whose budget is not the bag's steps."""
    where = spec.source or spec.name
    if spec.program != REPLAY or not spec.launcher_args:
        raise SpecError(f'{where}: the replay plug-in needs program: {REPLAY} and the bag as '
                        'the first of launcher_args')
    try:
        steps = bag_steps(Path(spec.launcher_args[0]))
    except ValueError as error:
        raise SpecError(f'{where}: {error}') from None
    if steps != spec.budget:
        raise SpecError(f'{where}: the bag {spec.launcher_args[0]} holds {steps} steps; set '
                        f'budget: {steps}')


def measure(record: dict, run_dir: Path) -> dict:
    """Add the replay's own summary (agreement, receipts, the learner's metrics)."""
    record['replay'] = read_json(Path(run_dir) / SUMMARY_FILE) or {}
    return record


def progress(record: Mapping) -> str:
    agreement = record.get('replay', {}).get('agreement')
    return '' if agreement is None else f'agreement {agreement:.3f}'


def summaries(spec: Spec, by_arm: Mapping) -> List[dict]:
    """Every trial's replay summary, arm by arm (the rows of ``replay_study.json``)."""
    return [dict(record['replay'], arm=arm.name) for arm in spec.arms
            for record in by_arm[arm.name] if record.get('replay')]


def analyse(spec: Spec, by_arm: Mapping, context: Mapping) -> dict:
    arms = {}
    for arm in spec.arms:
        done = [r['replay'] for r in by_arm[arm.name] if r.get('replay', {}).get('agreement')
                is not None]
        arms[arm.name] = {
            'condition': arm.condition, 'trials': len(done),
            'agreement': stats.estimate([s['agreement'] for s in done]),
            'agreement_last_quarter': stats.estimate(
                [s['agreement_last_quarter'] for s in done
                 if s.get('agreement_last_quarter') is not None]),
        }
    return {'bag': spec.launcher_args[0], 'steps': spec.budget, 'arms': arms,
            'summaries': summaries(spec, by_arm)}


def stored(result: Mapping) -> dict:
    return {key: value for key, value in result.items() if key != 'summaries'}


def write_report(spec: Spec, result: dict, by_arm: Mapping, context: Mapping) -> None:
    rows = [[name, arm['trials'], mean_interval(arm['agreement'], 3),
             mean_interval(arm['agreement_last_quarter'], 3)]
            for name, arm in result['arms'].items()]
    lines = [f'# {spec.name}: {result["bag"]} replayed into a fresh learner per arm', '',
             f'{result["steps"]} steps; agreement is the share of steps on which the new '
             "learner's greedy action is the session's (mean over seeds [95 % interval]).", '',
             table_text(['arm', 'trials', 'agreement', 'last quarter'], rows), '',
             '## Every replay', '', study_table(result['summaries']), '']
    write(spec.report, '\n'.join(lines))

"""
An experiment as data: the task, the arms, the seeds, the budget, the comparisons (pure).

A spec is a YAML file; the shipped ones are in ``config/experiments/`` and are named by their
file stem (``attention_experiment teaching``). Its fields:

- ``name``, ``plugin`` (a module of ``experiment/plugins/``: the task's measures, analysis and
  report), ``task`` (``attention_train --task``), ``budget`` (agent steps per trial), ``seeds``
  (a list, or ``{start: S, count: N}``), ``parallel`` (default trials side by side);
- ``out`` (result files, the log, the analysis), ``report`` (the markdown file), ``runs_dir``
  (the trials' run folders), ``log`` (the log's file name in ``out``);
- ``layout``: ``by_condition`` (``<out>/trials/<condition>/seed<k>.json``: an arm is a
  condition) or ``by_arm`` (``<out>/<arm>/trials/<condition>/seed<k>.json``);
- ``launcher_args`` (every trial's ``attention_train`` options), ``parameters`` (node
  parameters every trial gets, written to ``<out>/<params_file>`` and passed as
  ``--params-file``);
- ``arms``: each ``{name, condition, launcher_args, parameters, text}`` (an arm's
  ``parameters`` go on top of the spec's, in ``<out>/<arm>_params.yaml``);
- ``comparisons``: each ``{arm, baseline}``; ``measures``: what they compare;
  ``targets``: ``{arm: {...}}`` (read by the plug-in); ``settings``: anything else the plug-in
  reads;
- ``program``: what a trial runs, ``attention_train`` (default) or ``attention_replay`` (a
  recorded session replayed into each arm's fresh learner: ``launcher_args`` start with the bag,
  ``budget`` is the number of steps it holds);
- ``extends``: another spec (a shipped name, or a file beside this one) whose fields this one
  starts from (``load``).
"""

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, List, Mapping, Optional, Sequence, Tuple

from attention_bringup.experiment.runner import REPLAY, TRAIN
from attention_bringup.graph import CONDITIONS
import yaml

SPEC_DIR = Path(__file__).resolve().parent.parent / 'config' / 'experiments'
"""The shipped specs (``attention_experiment NAME``)."""
LAYOUTS = ('by_condition', 'by_arm')


class SpecError(ValueError):
    """A spec that cannot be run: the message names the file and the field."""


@dataclass(frozen=True)
class Arm:
    """One arm: a condition of the graph and the launcher options that make it this arm."""

    name: str
    condition: str
    launcher_args: Tuple[str, ...] = ()
    text: str = ''
    parameters: Mapping[str, Mapping[str, Any]] = field(default_factory=dict, hash=False)
    """Node parameters of this arm's trials only (on top of the spec's ``parameters``)."""


@dataclass(frozen=True)
class Comparison:
    """``arm`` tested against ``baseline`` on every measure of the spec."""

    arm: str
    baseline: str


@dataclass(frozen=True)
class Spec:
    """One experiment (see the module docstring for each field)."""

    name: str
    plugin: str
    arms: Tuple[Arm, ...]
    seeds: Tuple[int, ...]
    budget: int
    out: str
    report: str
    runs_dir: str
    task: str = ''
    parallel: int = 1
    layout: str = 'by_condition'
    log: str = 'study_log.json'
    launcher_args: Tuple[str, ...] = ()
    parameters: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    params_file: str = 'experiment_params.yaml'
    comparisons: Tuple[Comparison, ...] = ()
    measures: Tuple[str, ...] = ()
    targets: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    settings: Mapping[str, Any] = field(default_factory=dict)
    program: str = TRAIN
    source: str = ''
    """Where the spec was read from (for messages)."""

    def arm(self, name: str) -> Arm:
        for arm in self.arms:
            if arm.name == name:
                return arm
        raise SpecError(f'{self.source or self.name}: no arm {name!r} (arms: '
                        f'{", ".join(self.arm_names)})')

    @property
    def arm_names(self) -> List[str]:
        return [arm.name for arm in self.arms]

    def select(self, arms: Optional[Sequence[str]] = None,
               seeds: Optional[Sequence[int]] = None, budget: Optional[int] = None,
               **more) -> 'Spec':
        """Return the spec narrowed to ``arms`` (in its order), ``seeds``, their comparisons."""
        chosen = self.arms if arms is None else tuple(
            self.arm(name) for name in dict.fromkeys(arms))
        names = {arm.name for arm in chosen}
        comparisons = tuple(c for c in self.comparisons if {c.arm, c.baseline} <= names)
        return replace(self, arms=chosen, comparisons=comparisons,
                       seeds=self.seeds if seeds is None else tuple(int(s) for s in seeds),
                       budget=self.budget if budget is None else int(budget), **more)

    def trial_args(self, arm: Arm, params_path: Optional[Path],
                   arm_params_path: Optional[Path] = None) -> Tuple[str, ...]:
        """Every ``attention_train`` option of a trial of ``arm`` but condition, seed, budget."""
        task = ('--task', self.task) if self.task else ()
        params = tuple(word for path in (params_path, arm_params_path) if path is not None
                       for word in ('--params-file', str(path)))
        return task + tuple(self.launcher_args) + tuple(arm.launcher_args) + params


def _seeds(value, where: str) -> Tuple[int, ...]:
    if isinstance(value, Mapping):
        start, count = value.get('start', 0), value.get('count')
        if not isinstance(start, int) or not isinstance(count, int) or count < 1:
            raise SpecError(f'{where}: seeds as a mapping needs integers start and count >= 1')
        return tuple(range(start, start + count))
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise SpecError(f'{where}: seeds must be a list of integers or {{start, count}}')
    if len(set(value)) != len(value):
        raise SpecError(f'{where}: seeds repeat')
    return tuple(value)


def _strings(value, where: str, name: str) -> Tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, (str, int, float)) for v in value):
        raise SpecError(f'{where}: {name} must be a list of words')
    return tuple(str(v) for v in value)


def _arm(entry, where: str) -> Arm:
    if not isinstance(entry, Mapping) or 'name' not in entry:
        raise SpecError(f'{where}: every arm needs a name')
    unknown = set(entry) - {'name', 'condition', 'launcher_args', 'parameters', 'text'}
    if unknown:
        raise SpecError(f'{where}: arm {entry["name"]}: unknown field(s) {sorted(unknown)}')
    condition = entry.get('condition', entry['name'])
    if condition not in CONDITIONS:
        raise SpecError(f'{where}: arm {entry["name"]}: condition {condition!r} is not one of '
                        f'{", ".join(CONDITIONS)}')
    return Arm(str(entry['name']), condition,
               _strings(entry.get('launcher_args'), where, 'launcher_args'),
               str(entry.get('text', '')),
               _parameters(entry.get('parameters'), f'{where}: arm {entry["name"]}'))


def _parameters(value, where: str) -> Mapping[str, Mapping[str, Any]]:
    value = value or {}
    if not isinstance(value, Mapping) or not all(isinstance(v, Mapping) for v in value.values()):
        raise SpecError(f'{where}: parameters must map node names to their parameters')
    return {str(k): dict(v) for k, v in value.items()}


REQUIRED = ('name', 'plugin', 'arms', 'seeds', 'budget', 'out', 'report', 'runs_dir')
OPTIONAL = ('task', 'parallel', 'layout', 'log', 'launcher_args', 'parameters', 'params_file',
            'comparisons', 'measures', 'targets', 'settings', 'program')


def from_dict(data: Mapping, source: str = '') -> Spec:
    """Build and check a spec from its parsed YAML; ``SpecError`` names what is wrong."""
    where = source or str(data.get('name', 'the spec'))
    if not isinstance(data, Mapping):
        raise SpecError(f'{where}: a spec is a mapping of fields')
    missing = [name for name in REQUIRED if name not in data]
    if missing:
        raise SpecError(f'{where}: missing field(s) {", ".join(missing)}')
    unknown = set(data) - set(REQUIRED) - set(OPTIONAL)
    if unknown:
        raise SpecError(f'{where}: unknown field(s) {", ".join(sorted(unknown))}')
    if not isinstance(data['arms'], list) or not data['arms']:
        raise SpecError(f'{where}: arms must be a non-empty list')
    arms = tuple(_arm(entry, where) for entry in data['arms'])
    names = [arm.name for arm in arms]
    if len(set(names)) != len(names):
        raise SpecError(f'{where}: arm names repeat')
    layout = data.get('layout', 'by_condition')
    if layout not in LAYOUTS:
        raise SpecError(f'{where}: layout must be one of {", ".join(LAYOUTS)}')
    if layout == 'by_condition' and len({arm.condition for arm in arms}) != len(arms):
        raise SpecError(f'{where}: two arms of one condition need layout: by_arm')
    budget = data['budget']
    if not isinstance(budget, int) or isinstance(budget, bool) or budget < 1:
        raise SpecError(f'{where}: budget must be a positive number of agent steps')
    comparisons = []
    for entry in data.get('comparisons') or ():
        if not isinstance(entry, Mapping) or not {'arm', 'baseline'} <= set(entry):
            raise SpecError(f'{where}: each comparison needs an arm and a baseline')
        for name in (entry['arm'], entry['baseline']):
            if name not in names:
                raise SpecError(f'{where}: comparison names an unknown arm {name!r}')
        comparisons.append(Comparison(str(entry['arm']), str(entry['baseline'])))
    parameters = _parameters(data.get('parameters'), where)
    parallel = data.get('parallel', 1)
    if not isinstance(parallel, int) or parallel < 1:
        raise SpecError(f'{where}: parallel must be a positive integer')
    program = data.get('program', TRAIN)
    if program not in (TRAIN, REPLAY):
        raise SpecError(f'{where}: program must be {TRAIN} or {REPLAY}')
    return Spec(
        name=str(data['name']), plugin=str(data['plugin']), arms=arms,
        seeds=_seeds(data['seeds'], where), budget=budget, out=str(data['out']),
        report=str(data['report']), runs_dir=str(data['runs_dir']),
        task=str(data.get('task') or ''), parallel=parallel, layout=layout,
        log=str(data.get('log', 'study_log.json')),
        launcher_args=_strings(data.get('launcher_args'), where, 'launcher_args'),
        parameters=parameters,
        params_file=str(data.get('params_file', 'experiment_params.yaml')),
        comparisons=tuple(comparisons),
        measures=_strings(data.get('measures'), where, 'measures'),
        targets=dict(data.get('targets') or {}), settings=dict(data.get('settings') or {}),
        program=program, source=source)


def spec_path(name_or_path: str) -> Path:
    """Return the file of a shipped spec's name (``teaching``) or of a path to a YAML file."""
    path = Path(name_or_path)
    if path.suffix in ('.yaml', '.yml') or path.exists():
        return path
    shipped = SPEC_DIR / f'{name_or_path}.yaml'
    if not shipped.exists():
        names = ', '.join(sorted(p.stem for p in SPEC_DIR.glob('*.yaml')))
        raise SpecError(f'no spec {name_or_path!r}: give a YAML file or one of: {names}')
    return shipped


def _read(path: Path) -> dict:
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as error:
        raise SpecError(f'{path}: cannot read it: {error}') from error
    except yaml.YAMLError as error:
        raise SpecError(f'{path}: not valid YAML: {error}') from error
    if data is not None and not isinstance(data, Mapping):
        raise SpecError(f'{path}: a spec is a mapping of fields')
    return dict(data or {})


def _extended(path: Path, chain: Tuple[Path, ...] = ()) -> dict:
    """
    Return the fields of the spec in ``path`` with those of the spec it ``extends``.

    ``extends`` names a shipped spec or a file (relative to this one). This spec's fields
    replace the base's, but ``parameters``, merged node by node, and ``settings``, merged name
    by name (this spec's values win).
    """
    if path.resolve() in chain:
        raise SpecError(f'{path}: extends itself (through {", ".join(map(str, chain))})')
    data = _read(path)
    base_name = data.pop('extends', None)
    if base_name is None:
        return data
    if not isinstance(base_name, str) or not base_name:
        raise SpecError(f'{path}: extends must name a spec')
    beside = path.parent / base_name
    base = _extended(beside if beside.is_file() else spec_path(base_name),
                     chain + (path.resolve(),))
    merged = {**base, **data}
    below, above = base.get('parameters'), data.get('parameters')
    if isinstance(below, Mapping) and isinstance(above, Mapping):  # else from_dict says why
        merged['parameters'] = dict(below)
        for node, values in above.items():
            under = below.get(node)
            both = isinstance(under, Mapping) and isinstance(values, Mapping)
            merged['parameters'][node] = {**under, **values} if both else values
    below, above = base.get('settings'), data.get('settings')
    if isinstance(below, Mapping) and isinstance(above, Mapping):
        merged['settings'] = {**below, **above}
    return merged


def load(name_or_path: str) -> Spec:
    """Read and check a spec (``spec_path``), with the spec it ``extends`` if any."""
    path = spec_path(name_or_path)
    return from_dict(_extended(path), str(path))

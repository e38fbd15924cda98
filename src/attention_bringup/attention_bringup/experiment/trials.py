"""
One trial's compact result file, built from the run folder ``attention_train`` left (pure).

A result file (``<out>/trials/<condition>/seed<k>.json``, a few kB) keeps what the analysis
needs: the outcome, the first step at which each critical position was visited, the furthest
position every ``CURVE_EVERY`` steps, key pick-ups, episodes, lives lost, wall time, the
parameters that define the condition, and for a trial that did not finish cleanly the tail of
its logs. Steps are agent steps after the warm-up (``agent_step`` of ``env_status``: 0 is the
first step the agent chooses).

``steps_at_position`` and ``feedback_mean`` came later: a file without them still loads (the
analysis treats them as unknown), and ``refresh_records`` rebuilds such files from their run
folders.
"""

import csv
import json
import os
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

from attention_bringup.params import load_params_file, node_params, ParamsFileError
from attention_common.run_files import (
    LAUNCHER_LOG, node_log, PARAMS_FILE, PROGRESS_FILE, REPLAY_LOG, SUMMARY_FILE)

FORMAT = 1
"""Version of the result file layout."""
POSITIONS = tuple(range(6))
"""The critical positions 0..5."""
PLACES = (-1,) + POSITIONS
"""Position indices of ``steps_at_position``: -1 (near none) and the critical positions."""
CURVE_EVERY = 100
"""Agent steps between two points of the stored furthest-position curve."""
RECORD_COLUMNS = ('agent_step', 'position', 'furthest_position', 'episode', 'lives', 'has_key')
"""The columns of ``progress.csv`` a result file is built from."""
TAIL_CHARS = 2500
"""Longest log tail kept in a result file."""

COMPLETED = 'completed'
COMPLETED_UNCLEAN = 'completed_unclean'
CRASHED = 'crashed'
TIMEOUT = 'timeout'
USABLE_OUTCOMES = (COMPLETED, COMPLETED_UNCLEAN)
"""Outcomes whose full budget of steps was recorded (the analysis uses these)."""

# (node, parameter) pairs copied into the result file: what defines a condition and a trial.
RECORDED_PARAMETERS = (
    ('env_node', 'seed'), ('env_node', 'warmup_steps'), ('env_node', 'max_steps'),
    ('env_node', 'frameskip'), ('env_node', 'sticky_actions'),
    ('feedback_node', 'utterance_interval'), ('feedback_node', 'reward_variant'),
    ('feedback_node', 'trainer'), ('feedback_node', 'feedback_probability'),
    ('feedback_node', 'feedback_delay_min'), ('feedback_node', 'feedback_delay_max'),
    ('feedback_node', 'feedback_noise'), ('tamer_node', 'window_min_s'),
    ('tamer_node', 'window_max_s'), ('tamer_node', 'greedy_margin'), ('tamer_node', 'explore'),
    ('saliency_node', 'mode'), ('saliency_node', 'require_utterance'),
    ('tamer_node', 'alpha'), ('tamer_node', 'input_image'), ('tamer_node', 'credit'),
    ('tamer_node', 'seed'),
)


def trial_path(out_dir: Path, condition: str, seed: int) -> Path:
    return Path(out_dir) / 'trials' / condition / f'seed{seed}.json'


def read_json(path: Path) -> Optional[dict]:
    """Return the parsed file, or None when it is missing or not valid JSON."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def write_json(path: Path, data: Mapping) -> None:
    """Write atomically (a study killed mid-write leaves no half file to be skipped later)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + '.tmp')
    tmp.write_text(json.dumps(data, indent=1) + '\n')
    tmp.replace(path)


def _as_int(text: str, default: int = -1) -> int:
    try:
        return int(float(text))
    except (TypeError, ValueError):
        return default


def read_progress(path: Path, columns: Sequence[str] = RECORD_COLUMNS
                  ) -> List[Dict[str, int]]:
    """Read ``columns`` of ``progress.csv`` as ints (-1 if blank); [] if there is no file."""
    try:
        with open(path, newline='') as handle:
            return [{name: _as_int(row.get(name)) for name in columns}
                    for row in csv.DictReader(handle)]
    except OSError:
        return []


def first_visits(rows: Sequence[Mapping[str, int]]) -> Dict[int, Optional[int]]:
    """Return the first agent step at which each critical position was stood on (None: never)."""
    first: Dict[int, Optional[int]] = dict.fromkeys(POSITIONS)
    for row in rows:
        position = row['position']
        if position in first and first[position] is None:
            first[position] = row['agent_step']
    return first


def steps_at_position(rows: Sequence[Mapping[str, int]]) -> Dict[str, int]:
    """Count the recorded steps at each position index (-1: near none of them)."""
    counts = dict.fromkeys(PLACES, 0)
    for row in rows:
        position = row['position'] if row['position'] in counts else -1
        counts[position] += 1
    return {str(position): n for position, n in counts.items()}


def furthest_curve(rows: Sequence[Mapping[str, int]], budget: int,
                   every: int = CURVE_EVERY) -> List[Optional[int]]:
    """Furthest position so far at steps 0, every, 2 every, ..., budget (None after the data)."""
    points = list(range(0, budget + 1, every))
    if points[-1] != budget:
        points.append(budget)
    curve: List[Optional[int]] = []
    index, furthest = 0, -1
    last_step = rows[-1]['agent_step'] if rows else -1
    for step in points:
        while index < len(rows) and rows[index]['agent_step'] <= step:
            furthest = max(furthest, rows[index]['furthest_position'], rows[index]['position'])
            index += 1
        curve.append(furthest if step <= last_step else None)
    return curve


def lives_lost_in(rows: Sequence[Mapping[str, int]]) -> int:
    """Count drops of ``lives`` between consecutive steps of the same episode."""
    lost = 0
    for before, after in zip(rows, rows[1:]):
        if (before['episode'] == after['episode'] and before['lives'] >= 0
                and 0 <= after['lives'] < before['lives']):
            lost += before['lives'] - after['lives']
    return lost


def key_pickups_in(rows: Sequence[Mapping[str, int]]) -> int:
    """Count steps at which ``has_key`` turned on."""
    pickups, had = 0, False
    for row in rows:
        has = row['has_key'] == 1
        pickups += int(has and not had)
        had = has
    return pickups


def recorded_parameters(params_path: Path) -> Dict[str, object]:
    """Return the condition-defining parameters from a run's ``params.yaml`` ({} if unreadable)."""
    try:
        graph = load_params_file(params_path)
    except ParamsFileError:
        return {}
    values = {}
    for node, name in RECORDED_PARAMETERS:
        value = node_params(graph, node).get(name)
        if value is not None:
            values[f'{node}.{name}'] = value
    return values


def display_path(path: Path) -> str:
    """Return ``path`` relative to the working directory when it lies inside it."""
    relative = os.path.relpath(Path(path).resolve(), Path.cwd())
    return str(Path(path).resolve()) if relative.startswith('..') else relative


def tail(text: str, chars: int = TAIL_CHARS) -> str:
    return text if len(text) <= chars else '...' + text[-chars:]


def read_tail(path: Path, chars: int = TAIL_CHARS) -> str:
    try:
        with open(path, 'rb') as handle:
            handle.seek(0, 2)
            handle.seek(max(0, handle.tell() - 4 * chars))
            return tail(handle.read().decode(errors='replace'), chars)
    except OSError:
        return ''


def outcome_of(summary: Optional[Mapping], steps: int, budget: int, exit_code: Optional[int],
               timed_out: bool) -> str:
    """Classify a trial: completed, completed_unclean (budget done, unclean exit), crashed..."""
    if timed_out:
        return TIMEOUT
    if summary is None or steps < budget:
        return CRASHED
    if exit_code == 0 and summary.get('status') == 'completed':
        return COMPLETED
    return COMPLETED_UNCLEAN


def build_record(condition: str, seed: int, budget: int, run_dir: Path,
                 exit_code: Optional[int], wall_time_s: float, timed_out: bool = False,
                 started_at: str = '', parallel: int = 1) -> dict:
    """Summarize one finished (or failed) trial's run folder as a result-file dict."""
    run_dir = Path(run_dir)
    launcher_log = REPLAY_LOG if (run_dir / REPLAY_LOG).exists() else LAUNCHER_LOG
    summary = read_json(run_dir / SUMMARY_FILE)
    rows = read_progress(run_dir / PROGRESS_FILE)
    steps = rows[-1]['agent_step'] if rows else 0
    if summary is not None and summary.get('kind') == 'replay':  # (no progress.csv)
        steps = summary.get('steps', 0)
    outcome = outcome_of(summary, steps, budget, exit_code, timed_out)
    first = first_visits(rows)
    visited = [position for position, step in first.items() if step is not None]
    keys = key_pickups_in(rows)
    summary = summary or {}
    record = {
        'format': FORMAT,
        'condition': condition,
        'seed': seed,
        'budget': budget,
        'outcome': outcome,
        'exit_code': exit_code,
        'launcher_status': summary.get('status'),
        'steps': steps,
        'wall_time_s': round(wall_time_s, 1),
        'training_steps_per_s': summary.get('steps_per_s'),
        'started_at': started_at,
        'parallel': parallel,
        'furthest_position': max(visited) if visited else -1,
        'first_step_at_position': {str(p): step for p, step in first.items()},
        'steps_at_position': steps_at_position(rows),
        'key_pickups': keys,
        'key': keys > 0,
        'episodes': summary.get('episodes', len({row['episode'] for row in rows})),
        'lives_lost': summary.get('lives_lost', lives_lost_in(rows)),
        'feedback_count': summary.get('feedback_count'),
        'feedback_mean': summary.get('feedback_mean'),
        'utterance_count': summary.get('utterance_count'),
        'saliency_count': summary.get('message_counts', {}).get('saliency'),
        'learner_updates': summary.get('metrics', {}).get('train/updates'),
        'feedback_received': summary.get('metrics', {}).get('feedback/received'),
        'questions_asked': summary.get('metrics', {}).get('ask/asked'),
        'updates_per_step': summary.get('metrics', {}).get('train/updates_per_step'),
        'first_key_step': summary.get('first_key_step', first_key_step(rows)),
        'furthest_position_stood': summary.get('furthest_position_stood'),
        'first_step_stood_at_position': summary.get('first_step_stood_at_position'),
        'trainer': summary.get('trainer', 'thesis'),
        'human_like': summary.get('human_like', False),
        'parameters': recorded_parameters(run_dir / PARAMS_FILE),
        'curve_every': CURVE_EVERY,
        'furthest_curve': furthest_curve(rows, budget),
        'run_dir': display_path(run_dir),
        'problem': None,
    }
    if outcome != COMPLETED:
        failed = summary.get('failed_node')
        record['problem'] = {
            'exit_text': summary.get('exit_text'),
            'failed_node': failed,
            'launcher_output_tail': read_tail(run_dir / launcher_log),
            'node_log_tail': read_tail(run_dir / node_log(failed)) if failed else '',
        }
    return record


def first_key_step(rows: Sequence[Mapping[str, int]]) -> Optional[int]:
    """Return the agent step at which the key was first held (None: never)."""
    return next((row['agent_step'] for row in rows if row['has_key'] == 1), None)


def is_usable(record: Mapping) -> bool:
    return record.get('outcome') in USABLE_OUTCOMES


def result_files(out_dir: Path, condition: str) -> List[Path]:
    """Return ``<out>/trials/<condition>/seed*.json`` (not ``retried/``), sorted."""
    return sorted((Path(out_dir) / 'trials' / condition).glob('seed*.json'))


def load_records(out_dir: Path, conditions: Sequence[str]) -> Dict[str, List[dict]]:
    """Return every result file under ``<out>/trials/<condition>/``, sorted by seed."""
    found: Dict[str, List[dict]] = {}
    for condition in conditions:
        records = []
        for path in result_files(out_dir, condition):
            record = read_json(path)
            if record is None or record.get('format') != FORMAT:
                raise ValueError(f'{path}: not a trial result file of format {FORMAT}')
            records.append(record)
        found[condition] = sorted(records, key=lambda r: r['seed'])
    return found


def stored_run_dir(record: Mapping, base_dir: Path) -> Path:
    """Return a record's run folder: ``run_dir`` as stored, if relative then under ``base_dir``."""
    return Path(base_dir) / record['run_dir']  # an absolute run_dir replaces base_dir


def rebuild_record(record: Mapping, run_dir: Path) -> dict:
    """Build ``record`` again from ``run_dir``, keeping what only the runner knew."""
    fresh = build_record(record['condition'], record['seed'], record['budget'], run_dir,
                         record.get('exit_code'), record.get('wall_time_s') or 0.0,
                         timed_out=record.get('outcome') == TIMEOUT,
                         started_at=record.get('started_at', ''),
                         parallel=record.get('parallel', 1))
    fresh['run_dir'] = record['run_dir']
    return fresh


SAME_TRIAL_FIELDS = ('outcome', 'steps', 'first_step_at_position')
"""A rebuilt record must agree on these, or its run folder holds another run by now."""


def refresh_records(out_dir: Path, conditions: Sequence[str], base_dir: Path
                    ) -> Tuple[List[Path], Dict[Path, str]]:
    """
    Rebuild every ``trials/<condition>/seed*.json`` from its run folder, in place.

    ``retried/`` files are left alone. A file is skipped (and kept as it was) when it is not
    readable, its run folder is gone, or the rebuilt record disagrees on ``SAME_TRIAL_FIELDS``.
    Returns (refreshed files, {skipped file: why}).
    """
    refreshed: List[Path] = []
    skipped: Dict[Path, str] = {}
    for condition in conditions:
        for path in result_files(out_dir, condition):
            record = read_json(path)
            if record is None or record.get('format') != FORMAT or not record.get('run_dir'):
                skipped[path] = f'not a trial result file of format {FORMAT}'
                continue
            run_dir = stored_run_dir(record, base_dir)
            if not run_dir.is_dir():
                skipped[path] = f'run folder {run_dir} not found'
                continue
            fresh = rebuild_record(record, run_dir)
            changed = [f for f in SAME_TRIAL_FIELDS if fresh.get(f) != record.get(f)]
            if changed:
                skipped[path] = f'run folder {run_dir} differs now ({", ".join(changed)})'
                continue
            write_json(path, fresh)
            refreshed.append(path)
    return refreshed, skipped

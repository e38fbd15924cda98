"""
The bridge's plottable channels: the graph's DiagnosticArrays as JSON with numbers.

A DiagnosticArray's values are all strings; a plot needs numbers.

Pure: from a message's stamp and key-values, no node. The live bridge and ``graph_viewer_plots``
(a finished bag) use the same functions, so a plot reads the same in both.

- ``/plot/metrics``: the learner's metrics nested by their '/' (``train/loss`` is
  ``.train.loss``), one message per metrics period, the values of that period's metrics.csv row;
- ``/plot/action_values``: for each step the learner acted on, the action taken, H of every
  action (``.h.UP``), H of the action taken and the best H;
- ``/plot/env_status``: each step's status typed (step, episode, lives, ...) and the milestone
  it stands on (-1: none).

Every message carries ``stamp`` ({sec, nsec}: the step's or metrics' header stamp), so a plot
can be drawn on the graph's time as well as on the time it came.
"""

import json
import math
from typing import Callable, Dict, Iterable, Mapping, Optional, Tuple

from attention_common import topics
from env_node.status import parse_status

PLOT_ROOT = '/plot'

PLOTTED = (topics.METRICS, topics.ACTION_VALUES, topics.ENV_STATUS)
"""The graph topics (relative names) that have a plottable channel."""

STAMP_SCHEMA = {'type': 'object',
                'properties': {'sec': {'type': 'integer'}, 'nsec': {'type': 'integer'}}}

SCHEMAS = {
    'metrics': {
        'title': 'graph_viewer.Metrics', 'type': 'object',
        'description': "tamer_node's metrics, nested by '/' (train/loss: .train.loss)",
        'properties': {'stamp': STAMP_SCHEMA}},
    'action_values': {
        'title': 'graph_viewer.ActionValues', 'type': 'object',
        'properties': {'stamp': STAMP_SCHEMA, 'action': {'type': 'string'},
                       'action_index': {'type': 'integer'}, 'version': {'type': 'integer'},
                       'h': {'type': 'object', 'additionalProperties': {'type': 'number'}},
                       'h_taken': {'type': 'number'}, 'h_best': {'type': 'number'}}},
    'env_status': {
        'title': 'graph_viewer.EnvStatus', 'type': 'object',
        'properties': {'stamp': STAMP_SCHEMA, 'agent_step': {'type': 'integer'},
                       'episode': {'type': 'integer'}, 'lives': {'type': 'integer'},
                       'milestone': {'type': 'integer'}}},
}
"""Each plottable channel's JSON schema, by the graph topic it comes from."""

Pairs = Iterable[Tuple[str, str]]


def plot_topic(graph_topic: str) -> str:
    """Return the plottable channel of an absolute graph topic: /metrics -> /plot/metrics."""
    return PLOT_ROOT + graph_topic


def stamp(ns: int) -> dict:
    sec, nsec = divmod(int(ns), 1_000_000_000)
    return {'sec': sec, 'nsec': nsec}


def number(text: str) -> Optional[float]:
    """Return the number a value says (an int if whole), None for NaN, infinities or words."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _value(text: str):
    """Return a number, None for a NaN or an infinity (JSON has none), else the words."""
    value = number(text)
    if value is not None:
        return value
    try:
        float(text)
    except ValueError:
        return text
    return None


def metrics_record(stamp_ns: int, pairs: Pairs) -> dict:
    """Return a metrics message's values as numbers nested by '/' (a word stays a string)."""
    record: Dict[str, object] = {'stamp': stamp(stamp_ns)}
    for key, text in pairs:
        value = _value(text)
        parts = key.split('/')
        node = record
        for part in parts[:-1]:
            child = node.get(part)
            if not isinstance(child, dict):  # ('a' and 'a/b': a's own value is a.value)
                child = node[part] = {'value': child} if part in node else {}
            node = child
        leaf = parts[-1]
        if isinstance(node.get(leaf), dict):
            node[leaf]['value'] = value
        else:
            node[leaf] = value
    return record


def action_values_record(stamp_ns: int, action_name: str, pairs: Pairs) -> dict:
    """
    Return one step's H for each action, as the learner published it.

    ``pairs``: 'action' (its index), 'version' (the model that acted), then one pair per action
    name with its H. Raises ValueError for a message without them.
    """
    values = list(pairs)
    head = dict(values[:2])
    if 'action' not in head or 'version' not in head:
        raise ValueError('an action_values message starts with action and version')
    h = {name: number(text) for name, text in values[2:]}
    if action_name not in h:
        raise ValueError(f'the action taken, {action_name!r}, has no H')
    known = [value for value in h.values() if value is not None]
    return {'stamp': stamp(stamp_ns), 'action': action_name,
            'action_index': int(head['action']), 'version': int(head['version']), 'h': h,
            'h_taken': h[action_name], 'h_best': max(known) if known else None}


def env_status_record(stamp_ns: int, pairs: Pairs,
                      milestone_of: Callable[[Mapping[str, object]], int]) -> dict:
    """Return a step's status typed, with the milestone it stands on (ValueError if malformed)."""
    values = parse_status(pairs)
    record = {'stamp': stamp(stamp_ns)}
    for key, value in values.items():
        if isinstance(value, float) and not math.isfinite(value):
            value = None
        record[key] = value
    record['milestone'] = int(milestone_of(values))
    return record


def record_of(kind: str, stamp_ns: int, statuses,
              milestone_of: Callable[[Mapping[str, object]], int]) -> dict:
    """
    Return the plottable record of a DiagnosticArray of topic ``kind`` (one of ``PLOTTED``).

    ``statuses``: the message's ``status`` (its first one is read). ValueError if malformed.
    """
    if not statuses:
        raise ValueError('a message without a status')
    status = statuses[0]
    pairs = [(kv.key, kv.value) for kv in status.values]
    if kind == topics.METRICS:
        return metrics_record(stamp_ns, pairs)
    if kind == topics.ACTION_VALUES:
        return action_values_record(stamp_ns, status.message, pairs)
    if kind == topics.ENV_STATUS:
        return env_status_record(stamp_ns, pairs, milestone_of)
    raise ValueError(f'{kind!r} has no plot channel')


def encode(record: dict) -> bytes:
    """Serialize a record as strict JSON (a NaN would be refused, never sent)."""
    return json.dumps(record, allow_nan=False, separators=(',', ':')).encode()

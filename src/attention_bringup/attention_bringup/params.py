"""
ROS 2 parameter files: read, merge in order (later wins) and write, without rclpy.

The same rules as ``--ros-args --params-file a.yaml --params-file b.yaml``: a file maps node
names (``env_node``, ``/env_node`` or the wildcard ``/**``) to ``ros__parameters``; nested
mappings are parameter namespaces (``train: {lr: 0.1}`` is ``train.lr``); a later file
overrides the same parameter of an earlier one.
"""

from pathlib import Path
from typing import Dict, Iterable, Mapping, Union

import yaml

ROS_PARAMETERS = 'ros__parameters'
WILDCARD = '/**'

NodeParams = Dict[str, object]
"""Flat parameter name (dotted for namespaces) -> value, for one node."""

GraphParams = Dict[str, NodeParams]
"""Node name (or ``/**``) -> its parameters."""


class ParamsFileError(ValueError):
    """A parameter file that ``--params-file`` would reject."""


def _flatten(values: Mapping, prefix: str, where: str) -> NodeParams:
    flat: NodeParams = {}
    for key, value in values.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            flat.update(_flatten(value, f'{name}.', where))
        elif value is None:
            raise ParamsFileError(f'{where}: parameter {name!r} has no value')
        else:
            flat[name] = value
    return flat


def _node_key(key: str) -> str:
    """``/env_node`` and ``env_node`` name the same node; ``/**`` stays as it is."""
    return key if key == WILDCARD else key.lstrip('/')


def parse_params(text: str, where: str = '<text>') -> GraphParams:
    """Parse the text of one parameter file."""
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ParamsFileError(f'{where}: not valid YAML ({error})') from None
    if document is None:
        return {}
    if not isinstance(document, Mapping):
        raise ParamsFileError(f'{where}: the top level must map node names to parameters')
    graph: GraphParams = {}
    for key, section in document.items():
        if not isinstance(section, Mapping) or ROS_PARAMETERS not in section:
            raise ParamsFileError(f'{where}: {key!r} has no {ROS_PARAMETERS!r} section')
        values = section[ROS_PARAMETERS] or {}
        if not isinstance(values, Mapping):
            raise ParamsFileError(f'{where}: {key}.{ROS_PARAMETERS} must be a mapping')
        graph.setdefault(_node_key(str(key)), {}).update(_flatten(values, '', where))
    return graph


def load_params_file(path: Union[str, Path]) -> GraphParams:
    """Read one parameter file; a missing or malformed file raises ``ParamsFileError``."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise ParamsFileError(f'cannot read parameter file {path}: {error.strerror}') from None
    return parse_params(text, str(path))


def merge_params(layers: Iterable[GraphParams]) -> GraphParams:
    """Merge parameter layers in order; a later layer's value wins."""
    merged: GraphParams = {}
    for layer in layers:
        for node, values in layer.items():
            merged.setdefault(node, {}).update(values)
    return merged


def node_params(graph: GraphParams, node: str) -> NodeParams:
    """
    Return what ``node`` receives from merged layers: the wildcard, its own section on top.

    (rcl gives a node's own section priority over ``/**`` within one file; across files the
    later file wins. Layers here are merged first, which matches whenever, as in this project,
    the wildcard is not used to override a node's own section from a later file.)
    """
    values = dict(graph.get(WILDCARD, {}))
    values.update(graph.get(node, {}))
    return values


def _nest(values: NodeParams) -> dict:
    nested: dict = {}
    for name, value in sorted(values.items()):
        *namespaces, leaf = name.split('.')
        target = nested
        for namespace in namespaces:
            target = target.setdefault(namespace, {})
        target[leaf] = value
    return nested


def dump_params(graph: Mapping[str, NodeParams], header: str = '') -> str:
    """Write parameters as a file ``--params-file`` accepts (nodes in the given order)."""
    document = {node: {ROS_PARAMETERS: _nest(values)} for node, values in graph.items()}
    comment = ''.join(f'# {line}\n' for line in header.splitlines())
    return comment + yaml.safe_dump(document, sort_keys=False, default_flow_style=False)

"""Declare a node's parameters from one table (or one dataclass), types checked at start-up."""

import ast
import dataclasses
import inspect
from typing import Dict, Iterable, Mapping, Tuple

from attention_common.node_main import StartupError
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException


def declare_parameters(node, specs: Mapping[str, Tuple[object, str]],
                       runtime: Iterable[str] = ()) -> Dict[str, object]:
    """
    Declare ``specs`` ({name: (default, description)}) on ``node``; return {name: value}.

    A float parameter also accepts an integer (``rate_hz:=15``). Parameters not named in
    ``runtime`` are read-only. A value of the wrong type raises ``StartupError`` naming it.
    """
    runtime = set(runtime)
    values = {}
    for name, (default, description) in specs.items():
        is_float = isinstance(default, float)
        descriptor = ParameterDescriptor(description=description,
                                         read_only=name not in runtime,
                                         dynamic_typing=is_float)
        try:
            value = node.declare_parameter(name, default, descriptor).value
        except InvalidParameterTypeException as error:
            raise StartupError(f'parameter {name}: {error}') from None
        if is_float:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise StartupError(f'parameter {name} must be a number, got {value!r}')
            value = float(value)
        values[name] = value
    return values


def field_docs(cls) -> Dict[str, str]:
    """Return {field name: the docstring written under it} of a dataclass and its bases."""
    docs = {}
    for klass in reversed(cls.__mro__):  # a subclass's docstring wins
        if dataclasses.is_dataclass(klass):
            docs.update(_own_field_docs(klass))
    return docs


def _own_field_docs(cls) -> Dict[str, str]:
    tree = ast.parse(inspect.getsource(cls))
    body = tree.body[0].body
    docs = {}
    for node, following in zip(body, body[1:]):
        if (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                and isinstance(following, ast.Expr)
                and isinstance(following.value, ast.Constant)
                and isinstance(following.value.value, str)):
            docs[node.target.id] = ' '.join(following.value.value.split())
    return docs


def dataclass_specs(cls) -> Dict[str, Tuple[object, str]]:
    """{field name: (default, docstring)} of the dataclass ``cls``, in declaration order."""
    docs = field_docs(cls)
    return {field.name: (field.default, docs.get(field.name, ''))
            for field in dataclasses.fields(cls)}


def declare_dataclass(node, cls, runtime: Iterable[str] = ()):
    """Declare one parameter per field of the dataclass ``cls`` (its docstring, its default)."""
    return cls(**declare_parameters(node, dataclass_specs(cls), runtime=runtime))

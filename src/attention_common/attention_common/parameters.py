"""Declare a node's parameters from one table, with types checked at start-up."""

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

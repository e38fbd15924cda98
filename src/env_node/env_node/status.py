"""
The key-values of ``env_status`` (one DiagnosticArray per step), without rclpy.

Values are strings, as DiagnosticStatus wants: integers in decimal, floats as Python writes them,
booleans as ``true`` / ``false``. ``parse_status`` turns them back into typed values.
"""

from typing import Dict, Iterable, List, NamedTuple, Tuple, Union

from attention_tasks.montezuma.env import Step

STATUS_NAME = 'env_node'
"""``DiagnosticStatus.name`` of every env_status message."""

INT_KEYS = ('agent_step', 'episode', 'episode_step', 'lives', 'room', 'x', 'y', 'timeouts',
            'dropped_actions', 'bad_actions', 'action', 'pose', 'skull_x')
FLOAT_KEYS = ('reward', 'episode_return', 'action_latency_ms')
BOOL_KEYS = ('has_key', 'terminated', 'truncated', 'life_lost', 'finished')
TEXT_KEYS = ('carrying', 'door_color', 'grid')
"""Keys of other tasks whose values stay strings; other unknown keys are read as what they
look like (true/false, an integer, a float, else a string)."""

STATUS_KEYS = ('agent_step', 'episode', 'episode_step', 'lives', 'has_key', 'reward',
               'episode_return', 'terminated', 'truncated', 'life_lost', 'room', 'x', 'y',
               'timeouts', 'dropped_actions', 'bad_actions', 'finished', 'action_latency_ms',
               'action', 'pose', 'skull_x')
"""Every key of Room 1, in the order the node publishes them; another task's state keys that
are not among them follow, in the order its ``status()`` gives them."""

NO_LATENCY = -1.0
"""``action_latency_ms`` of a step no lockstep answer led to (the first one, real time)."""


class Counters(NamedTuple):
    """What the node counts besides the game."""

    timeouts: int = 0
    """Times no answer came within ``action_timeout`` (the observation was published again)."""
    dropped_actions: int = 0
    """Actions not applied, for any reason (wrong stamp, none pending, malformed, finished)."""
    bad_actions: int = 0
    """The malformed part of ``dropped_actions`` (axes out of range, NaN, missing fields)."""


def _text(value: Union[bool, int, float]) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    return str(value)


def status_values(step: Step, counters: Counters, finished: bool,
                  action_latency_ms: float = NO_LATENCY) -> List[Tuple[str, str]]:
    """
    Return ``[(key, value)]`` of one step, in ``STATUS_KEYS`` order.

    ``action_latency_ms``: wall time from publishing the observation this step answered to
    receiving its action (the closed loop as env_node sees it).
    """
    values = {
        'agent_step': step.agent_step, 'episode': step.episode,
        'episode_step': step.episode_step, 'reward': step.reward,
        'episode_return': step.episode_return, 'terminated': step.terminated,
        'truncated': step.truncated, 'life_lost': step.life_lost,
        'timeouts': counters.timeouts, 'dropped_actions': counters.dropped_actions,
        'bad_actions': counters.bad_actions, 'finished': finished,
        'action_latency_ms': round(action_latency_ms, 3), 'action': step.action,
    }
    state = step.state.status()
    values.update(state)
    keys = [key for key in STATUS_KEYS if key in values]
    keys += [key for key in state if key not in STATUS_KEYS]
    return [(key, _text(values[key])) for key in keys]


def _guess(value: str) -> Union[bool, int, float, str]:
    if value in ('true', 'false'):
        return value == 'true'
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            pass
    return value


def parse_status(pairs: Iterable[Tuple[str, str]]) -> Dict[str, Union[bool, int, float, str]]:
    """Return typed values of ``(key, value)`` pairs (see ``TEXT_KEYS`` for unknown keys)."""
    parsed: Dict[str, Union[bool, int, float, str]] = {}
    for key, value in pairs:
        if key in INT_KEYS:
            parsed[key] = int(value)
        elif key in FLOAT_KEYS:
            parsed[key] = float(value)
        elif key in BOOL_KEYS:
            parsed[key] = value == 'true'
        elif key in TEXT_KEYS:
            parsed[key] = value
        else:
            parsed[key] = _guess(value)
    return parsed

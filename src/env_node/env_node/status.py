"""
The key-values of ``env_status`` (one DiagnosticArray per step), without rclpy.

Values are strings, as DiagnosticStatus wants: integers in decimal, floats as Python writes them,
booleans as ``true`` / ``false``. ``parse_status`` turns them back into typed values.
"""

from typing import Dict, Iterable, List, NamedTuple, Tuple, Union

from env_node.core import Step

STATUS_NAME = 'env_node'
"""``DiagnosticStatus.name`` of every env_status message."""

INT_KEYS = ('agent_step', 'episode', 'episode_step', 'lives', 'room', 'x', 'y', 'timeouts',
            'dropped_actions', 'bad_actions', 'action', 'pose', 'skull_x')
FLOAT_KEYS = ('reward', 'episode_return', 'action_latency_ms')
BOOL_KEYS = ('has_key', 'terminated', 'truncated', 'life_lost', 'finished')

STATUS_KEYS = ('agent_step', 'episode', 'episode_step', 'lives', 'has_key', 'reward',
               'episode_return', 'terminated', 'truncated', 'life_lost', 'room', 'x', 'y',
               'timeouts', 'dropped_actions', 'bad_actions', 'finished', 'action_latency_ms',
               'action', 'pose', 'skull_x')
"""Every key, in the order the node publishes them."""

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
    state = step.state
    values = {
        'agent_step': step.agent_step, 'episode': step.episode,
        'episode_step': step.episode_step, 'lives': state.lives, 'has_key': state.has_key,
        'reward': step.reward, 'episode_return': step.episode_return,
        'terminated': step.terminated, 'truncated': step.truncated,
        'life_lost': step.life_lost, 'room': state.room, 'x': state.x, 'y': state.y,
        'timeouts': counters.timeouts, 'dropped_actions': counters.dropped_actions,
        'bad_actions': counters.bad_actions, 'finished': finished,
        'action_latency_ms': round(action_latency_ms, 3),
        'action': step.action, 'pose': state.pose, 'skull_x': state.skull_x,
    }
    return [(key, _text(values[key])) for key in STATUS_KEYS]


def parse_status(pairs: Iterable[Tuple[str, str]]) -> Dict[str, Union[bool, int, float, str]]:
    """Return typed values of ``(key, value)`` pairs; unknown keys stay strings."""
    parsed: Dict[str, Union[bool, int, float, str]] = {}
    for key, value in pairs:
        if key in INT_KEYS:
            parsed[key] = int(value)
        elif key in FLOAT_KEYS:
            parsed[key] = float(value)
        elif key in BOOL_KEYS:
            parsed[key] = value == 'true'
        else:
            parsed[key] = value
    return parsed

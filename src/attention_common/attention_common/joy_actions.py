"""
ALE's 18 joystick actions <-> sensor_msgs/Joy, by the ROS joystick convention.

``axes[0]`` is horizontal (+1 left, -1 right), ``axes[1]`` vertical (+1 up, -1 down) and
``buttons[0]`` is fire, so a gamepad through the standard ``joy`` driver can play.
"""

import math
from typing import Sequence, Tuple

# ALE's full action set, in ALE's order (gymnasium ``get_action_meanings()``).
ACTION_MEANINGS = (
    'NOOP', 'FIRE', 'UP', 'RIGHT', 'LEFT', 'DOWN', 'UPRIGHT', 'UPLEFT', 'DOWNRIGHT', 'DOWNLEFT',
    'UPFIRE', 'RIGHTFIRE', 'LEFTFIRE', 'DOWNFIRE', 'UPRIGHTFIRE', 'UPLEFTFIRE', 'DOWNRIGHTFIRE',
    'DOWNLEFTFIRE',
)
NUM_ACTIONS = len(ACTION_MEANINGS)

# Axis values beyond this magnitude count as pressed (a gamepad stick is analogue).
DEADZONE = 0.5


class JoyActionError(ValueError):
    """A Joy message that does not describe an ALE action."""


def _components(meaning: str) -> Tuple[float, float, int]:
    horizontal = 1.0 if 'LEFT' in meaning else (-1.0 if 'RIGHT' in meaning else 0.0)
    vertical = 1.0 if 'UP' in meaning else (-1.0 if 'DOWN' in meaning else 0.0)
    return horizontal, vertical, int('FIRE' in meaning)


_TO_JOY = tuple(_components(m) for m in ACTION_MEANINGS)
_FROM_JOY = {joy: index for index, joy in enumerate(_TO_JOY)}


def action_to_joy(action: int) -> Tuple[Tuple[float, float], Tuple[int]]:
    """Return ``(axes, buttons)`` for an ALE action index."""
    if not 0 <= int(action) < NUM_ACTIONS:
        raise JoyActionError(f'action {action} is out of range 0..{NUM_ACTIONS - 1}')
    horizontal, vertical, fire = _TO_JOY[int(action)]
    return (horizontal, vertical), (fire,)


def joy_to_action(axes: Sequence[float], buttons: Sequence[int]) -> int:
    """Return the ALE action index a Joy state means; raise ``JoyActionError`` if none."""
    if len(axes) < 2:
        raise JoyActionError(f'Joy needs axes[0] and axes[1], got {len(axes)} axes')
    if len(buttons) < 1:
        raise JoyActionError('Joy needs buttons[0] (fire), got no buttons')
    horizontal, vertical = float(axes[0]), float(axes[1])
    for name, value in (('axes[0]', horizontal), ('axes[1]', vertical)):
        if not math.isfinite(value) or abs(value) > 1.0:
            raise JoyActionError(f'{name} = {value} is outside [-1, 1]')
    if buttons[0] not in (0, 1):
        raise JoyActionError(f'buttons[0] = {buttons[0]} is neither 0 nor 1')

    def pressed(value: float) -> float:
        return 0.0 if abs(value) < DEADZONE else math.copysign(1.0, value)

    return _FROM_JOY[(pressed(horizontal), pressed(vertical), int(buttons[0]))]

"""
Room 1's words: Figure 5.1 of the thesis, one sentence per critical position (pure).

``SENTENCES[-1]`` is the thesis's sentence for everywhere else ("in between"). In between, the
thesis speaks "toward the nearest critical position" (section 5): ``sentence_for`` says the
sentence of the nearest position by default, so that what is said names the things near the
agent (the template matcher looks for them); ``in_between='literal'`` says the -1 sentence.
"""

import math
from typing import Optional, Tuple

from attention_tasks.montezuma.critical_positions import (
    critical_position_at, DEFAULT_RADIUS, nearest_critical_position, OUTSIDE)

SENTENCES = {
    -1: 'Go back to the top of the ladder and jump onto the rope.',
    0: 'Jump right from the ladder onto the rope.',
    1: 'Jump right from the rope onto the lower platform.',
    2: 'Climb down the ladder onto the ground.',
    3: 'Move left and avoid the skull.',
    4: 'Climb up the ladder.',
    5: 'Jump up to get the key.',
}
"""Figure 5.1: the sentence for each current position (-1 = in between)."""

IN_BETWEEN_MODES = ('nearest', 'literal')
RAM_COORDINATE_MAX = 255
"""x and y of a position are RAM bytes: 0..255 is the game's whole range."""


def sentence_for(x: float, y: float, radius: float = DEFAULT_RADIUS,
                 in_between: str = 'nearest') -> Tuple[int, int, str]:
    """Return ``(position, sentence_of, text)`` for an agent at (x, y)."""
    position = critical_position_at(x, y, radius)
    if position != OUTSIDE:
        return position, position, SENTENCES[position]
    if in_between == 'literal':
        return OUTSIDE, OUTSIDE, SENTENCES[OUTSIDE]
    nearest, _ = nearest_critical_position(x, y)
    return OUTSIDE, nearest, SENTENCES[nearest]


def position_problem(x: float, y: float) -> Optional[str]:
    """Why (x, y) is not a position the game can report, or None."""
    if not (math.isfinite(x) and math.isfinite(y)):
        return f'x={x}, y={y} is not finite'
    if not (0.0 <= x <= RAM_COORDINATE_MAX and 0.0 <= y <= RAM_COORDINATE_MAX):
        return f"x={x:g}, y={y:g} is outside the game's range 0..{RAM_COORDINATE_MAX}"
    return None

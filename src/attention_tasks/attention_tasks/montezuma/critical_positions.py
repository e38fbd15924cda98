"""
The thesis's six critical positions along the optimal route through Room 1.

Coordinates are RAM coordinates, as the env publishes them on ``agent_position``: x = ram[42]
grows to the right, y = ram[43] grows upward (the top floor is y 235, the platforms below it
y 192, the bottom floor y 148).

How they were found: the scripted expert (``attention_tasks.montezuma.expert``) was run through the
real emulator (no warm-up, no sticky actions) and each position is where the expert stands when the
thesis's corresponding stage begins: where it lands at the bottom of the middle ladder, where it
catches the rope, the lower right platform above the right ladder, where it steps off the right
ladder, where it reaches the left ladder, and where it stands at the top of the left ladder below
the key. ``tests/test_expert.py`` checks that the expert passes within ``DEFAULT_RADIUS`` (the
alpha threshold) of each, in order, on its way to the key.
"""

import math
from typing import Sequence, Tuple

CRITICAL_POSITIONS: Tuple[Tuple[int, int], ...] = (
    (77, 192),   # 0: bottom of the middle ladder, on the conveyor: jump right to the rope
    (109, 209),  # 1: hanging on the rope
    (133, 192),  # 2: the lower right platform, at the top of the right ladder
    (133, 148),  # 3: bottom of the right ladder, on the floor
    (21, 148),   # 4: bottom of the left ladder, on the floor
    (21, 192),   # 5: top of the left ladder, below the key
)
"""(x, y) of positions 0..5, in route order."""

OUTSIDE = -1
"""The position label of everywhere in between."""

DEFAULT_RADIUS = 8.0
"""The thesis's alpha in pixels: an agent closer than this stands on a critical position. The
one place of this value: the feedback node's ``alpha_threshold`` default, the launcher's
progress and the reports' texts all take it from here."""


def distance(x: float, y: float, point: Sequence[float]) -> float:
    """Euclidean distance from (x, y) to ``point`` (equation 4.1)."""
    return math.hypot(float(x) - point[0], float(y) - point[1])


def nearest_critical_position(x: float, y: float) -> Tuple[int, float]:
    """Return ``(index, distance)`` of the critical position nearest to (x, y)."""
    distances = [distance(x, y, point) for point in CRITICAL_POSITIONS]
    index = min(range(len(distances)), key=distances.__getitem__)
    return index, distances[index]


def critical_position_at(x: float, y: float, radius: float = DEFAULT_RADIUS) -> int:
    """Return the index of the critical position within ``radius`` of (x, y), else -1."""
    index, dist = nearest_critical_position(x, y)
    return index if dist < radius else OUTSIDE

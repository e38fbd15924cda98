"""
The thesis's scalar feedback h (equations 4.1 and 4.2), as a pure function of positions.

d is the Euclidean distance from the agent to a critical position; h = 1 if d < alpha,
0 if alpha <= d < beta, -1 if d >= beta. An agent that has stood still for more than
``stationary_steps`` steps gets -1 whatever d is (the thesis's guard against hiding).

Two variants of "a critical position":

- ``nearest`` (the thesis, used by every study condition): the nearest of the six.
- ``progress``: only the furthest position reached so far in this life and the next one on the
  route count, so going back to an earlier position is not rewarded. A life lost or a new
  episode shows as a teleport of the agent back to the start; it resets the progress.
"""

from dataclasses import dataclass
from typing import NamedTuple, Optional, Tuple

from attention_tasks.montezuma.critical_positions import (
    CRITICAL_POSITIONS, DEFAULT_RADIUS, distance, nearest_critical_position, OUTSIDE)

VARIANTS = ('nearest', 'progress')

TELEPORT_DISTANCE = 24.0
"""A move longer than this in one step is a respawn or a reset, not the agent's own doing
(walking is 4 pixels per step, jumping at most ~10, falling and climbing 8)."""


@dataclass
class RewardConfig:
    """Parameters of h; the feedback node's ROS parameters carry the same names."""

    alpha_threshold: float = DEFAULT_RADIUS
    """h = +1 when the agent is closer than this to a critical position (equation 4.2); also
    the radius of standing on one."""
    beta_threshold: float = 20.0
    """h = -1 when the agent is this far or further; 0 in between."""
    stationary_steps: int = 10
    """h = -1 once the agent has stood still for more than this many steps."""
    reward_variant: str = 'nearest'
    """'nearest' (the thesis: nearest critical position) or 'progress' (the furthest reached
    so far and the next)."""

    def __post_init__(self):
        if not 0.0 < self.alpha_threshold <= self.beta_threshold:
            raise ValueError('need 0 < alpha_threshold <= beta_threshold, got '
                             f'{self.alpha_threshold} and {self.beta_threshold}')
        if self.stationary_steps < 1:
            raise ValueError(f'stationary_steps must be >= 1, got {self.stationary_steps}')
        if self.reward_variant not in VARIANTS:
            raise ValueError(f'reward_variant must be one of {VARIANTS}, '
                             f'got {self.reward_variant!r}')


def threshold_reward(d: float, alpha: float, beta: float) -> int:
    """Equation 4.2: 1 if d < alpha, 0 if alpha <= d < beta, -1 otherwise."""
    if d < alpha:
        return 1
    if d < beta:
        return 0
    return -1


class Judgement(NamedTuple):
    """h for one position, and what it was measured against."""

    h: int
    position: int
    """The critical position the agent stands on (within alpha), -1 in between."""
    target: int
    """The critical position d was measured to."""
    distance: float
    stationary: bool
    """True when h is -1 because the agent stood still too long."""
    teleported: bool = False
    """The agent moved further than ``TELEPORT_DISTANCE`` since the last step (a respawn)."""


class RewardFunction:
    """h for a stream of positions, one per step (it remembers stillness and progress)."""

    def __init__(self, config: Optional[RewardConfig] = None):
        self.config = config or RewardConfig()
        self.reset()

    def reset(self) -> None:
        """Forget the past (a new trial)."""
        self._last: Optional[Tuple[float, float]] = None
        self._still_steps = 0
        self.furthest = -1

    def __call__(self, x: float, y: float) -> Judgement:
        """Judge the agent standing at (x, y) this step."""
        config = self.config
        here = (float(x), float(y))
        teleported = (self._last is not None
                      and distance(*here, self._last) > TELEPORT_DISTANCE)
        if teleported:
            self.furthest = -1
        self._still_steps = self._still_steps + 1 if here == self._last else 0
        self._last = here
        nearest, nearest_d = nearest_critical_position(*here)
        position = nearest if nearest_d < config.alpha_threshold else OUTSIDE
        if config.reward_variant == 'progress':
            target, d = self._progress_target(*here)
        else:
            target, d = nearest, nearest_d
        stationary = self._still_steps > config.stationary_steps
        h = (-1 if stationary
             else threshold_reward(d, config.alpha_threshold, config.beta_threshold))
        return Judgement(h=h, position=position, target=target, distance=d,
                         stationary=stationary, teleported=teleported)

    def _progress_target(self, x: float, y: float) -> Tuple[int, float]:
        candidates = [i for i in (self.furthest, self.furthest + 1)
                      if 0 <= i < len(CRITICAL_POSITIONS)]
        distances = {i: distance(x, y, CRITICAL_POSITIONS[i]) for i in candidates}
        target = min(distances, key=lambda i: (distances[i], -i))
        if target > self.furthest and distances[target] < self.config.alpha_threshold:
            self.furthest = target
        return target, distances[target]

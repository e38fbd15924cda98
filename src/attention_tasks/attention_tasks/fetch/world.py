"""
Fetch: a room of objects where only the words say which one to pick up (issue 25).

A room of ``objects`` keys, balls and boxes, each a different colour-kind pair; every episode
draws the pairs, their places, the agent's, and the target among them. The mission ("pick up
the purple ball") is said, never shown: the frame shows several objects and nothing marks the
target, so a learner that does not listen can do no better than chance (1 in ``objects``).
Picking up an object ends the episode: solved when it is the target.

Held out: layouts (seeds no trial trains on, ``gridworld.layout_seed``) and target
combinations. ``HELDOUT_TARGETS`` are six colour-kind pairs (each colour once, each kind
twice) that never appear in a training episode, as target or in the room; a held-out episode
names one of them as its target (its other objects may be any pair).
"""

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Mapping, Optional, Tuple

from attention_tasks.gridworld import AGENT_VIEW, PICKUP, TILE_SIZE
from minigrid.core.constants import COLOR_NAMES
from minigrid.core.grid import Grid
from minigrid.core.mission import MissionSpace
from minigrid.core.world_object import Ball, Box, Key
from minigrid.minigrid_env import MiniGridEnv
import numpy as np


class SealedBox(Box):
    """
    A box that stays shut.

    MiniGrid's toggle empties a box into what it holds (nothing here): a target that vanished
    could not be fetched.
    """

    def toggle(self, env, pos) -> bool:
        return False


KINDS = {'key': Key, 'ball': Ball, 'box': SealedBox}
PAIRS = tuple((color, kind) for color in COLOR_NAMES for kind in KINDS)
"""Every colour-kind pair: 6 colours x 3 kinds."""
HELDOUT_TARGETS = (('red', 'ball'), ('green', 'box'), ('blue', 'key'), ('purple', 'ball'),
                   ('yellow', 'box'), ('grey', 'key'))
"""Pairs no training episode shows (each colour once, each kind twice)."""
TRAINING_PAIRS = tuple(pair for pair in PAIRS if pair not in HELDOUT_TARGETS)
MILESTONES = ('reached', 'fetched')
"""Progress: facing the target (one pick-up away), the target in hand."""


def phrase(color: str, kind: str) -> str:
    return f'{color} {kind}'


def mission(color: str, kind: str) -> str:
    """Return what the teacher says: the episode's goal, in words only."""
    return f'pick up the {phrase(color, kind)}'


@dataclass
class FetchConfig:
    """The room's size and clutter."""

    size: int = 8
    """Grid cells per side, outer walls included (8: a 6 x 6 interior)."""
    objects: int = 4
    """Objects in the room, the target one of them (chance: 1 in this many)."""
    max_episode_steps: int = 0
    """Steps before the episode is truncated; 0: 5 x size^2 (320 for size 8)."""

    def validate(self) -> None:
        if self.size < 5:
            raise ValueError(f'size must be >= 5, got {self.size}')
        if not 1 <= self.objects <= min(len(HELDOUT_TARGETS), (self.size - 2) ** 2 // 3):
            raise ValueError(f'objects must be in 1..{len(HELDOUT_TARGETS)} and fit the room, '
                             f'got {self.objects}')
        if self.max_episode_steps < 0:
            raise ValueError(f'max_episode_steps must be >= 0, got {self.max_episode_steps}')


class FetchLevel(MiniGridEnv):
    """The room (see the module docstring); ``target`` is the episode's (colour, kind)."""

    def __init__(self, config: Optional[FetchConfig] = None, **kwargs):
        self.config = config or FetchConfig()
        self.config.validate()
        self.heldout = False
        """Set before a reset: the next episode's target is a held-out pair."""
        self.target: Tuple[str, str] = ('', '')
        size = self.config.size
        super().__init__(
            mission_space=MissionSpace(mission_func=mission, ordered_placeholders=[
                list(COLOR_NAMES), list(KINDS)]),
            grid_size=size, max_steps=self.config.max_episode_steps or 5 * size * size,
            tile_size=TILE_SIZE, agent_view_size=AGENT_VIEW, **kwargs)

    def _gen_grid(self, width: int, height: int) -> None:
        self.grid = Grid(width, height)
        self.grid.wall_rect(0, 0, width, height)
        targets = HELDOUT_TARGETS if self.heldout else TRAINING_PAIRS
        others = PAIRS if self.heldout else TRAINING_PAIRS
        self.target = targets[self._rand_int(0, len(targets))]
        room = [self.target]
        while len(room) < self.config.objects:
            pair = others[self._rand_int(0, len(others))]
            if pair not in room:
                room.append(pair)
        for color, kind in room:
            self.place_obj(KINDS[kind](color))
        self.place_agent()
        self.mission = mission(*self.target)

    def step(self, action: int):
        """Step as MiniGrid does; a pick-up ends the episode, rewarded when it is the target."""
        observation, reward, terminated, truncated, info = super().step(action)
        if action == PICKUP and self.carrying is not None:
            terminated = True
            right = (self.carrying.color, self.carrying.type) == self.target
            reward = self._reward() if right else 0.0
        return observation, reward, terminated, truncated, info


@dataclass(frozen=True)
class FetchState:
    """What the other nodes need of a step."""

    x: int
    y: int
    direction: int
    """0 right, 1 down, 2 left, 3 up (MiniGrid's)."""
    carrying: str
    """'' or '<colour> <kind>'."""
    target: str
    """The episode's target, '<colour> <kind>' (what the teacher says; never in the frame)."""
    grid: str = ''
    """The whole grid, MiniGrid's ``Grid.encode()`` in hex: the teacher plans on it."""
    layout: int = -1
    heldout: bool = False

    @property
    def fetched(self) -> bool:
        return bool(self.carrying) and self.carrying == self.target

    def status(self) -> dict:
        """Return the env_status values of the state (``env_node.status``)."""
        return {'lives': 1, 'has_key': False, 'room': 0, 'x': self.x, 'y': self.y,
                'direction': self.direction, 'carrying': self.carrying,
                'target': self.target, 'fetched': self.fetched, 'layout': self.layout,
                'heldout': self.heldout, 'grid': self.grid}

    def position(self) -> Tuple[float, float, float]:
        """Return agent_position's (x, y, z): the agent's cell (z 0: one room)."""
        return float(self.x), float(self.y), 0.0


def state_of(env: FetchLevel, layout: int = -1, heldout: bool = False) -> FetchState:
    """Read the state of ``env`` (after a reset or a step)."""
    carrying = env.carrying
    return FetchState(
        x=int(env.agent_pos[0]), y=int(env.agent_pos[1]), direction=int(env.agent_dir),
        carrying=f'{carrying.color} {carrying.type}' if carrying is not None else '',
        target=phrase(*env.target), grid=env.grid.encode().tobytes().hex(), layout=layout,
        heldout=heldout)


def state_from_status(values: Mapping[str, object]) -> FetchState:
    """Return the state env_status ``values`` (parsed) describe; KeyError, ValueError if not."""
    return FetchState(
        x=int(values['x']), y=int(values['y']), direction=int(values['direction']),
        carrying=str(values['carrying']), target=str(values['target']),
        grid=str(values['grid']), layout=int(values.get('layout', -1)),
        heldout=bool(values.get('heldout', False)))


def decode_grid(state: FetchState) -> SimpleNamespace:
    """Return the state's grid as MiniGrid's ``Grid`` and its size; ValueError if malformed."""
    cells = np.frombuffer(bytes.fromhex(state.grid), np.uint8)
    size = int(round((cells.size // 3) ** 0.5))
    if size * size * 3 != cells.size or size < 3:
        raise ValueError(f'grid of {cells.size} values is not size x size x 3')
    grid, _ = Grid.decode(cells.reshape(size, size, 3).copy())
    return SimpleNamespace(grid=grid, size=size)

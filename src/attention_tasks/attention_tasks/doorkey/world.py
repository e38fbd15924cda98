"""
DoorKey with distractors: a MiniGrid level whose layout changes every episode.

A room split by a wall with one locked door of a random colour; the key of that colour lies on
the agent's side, the green goal square on the other; keys, balls and boxes of other colours
distract on both sides. Every episode draws the wall's column, the door's row and colour, the
goal's, key's, distractors' and agent's places: which pixels matter changes with the layout,
which is where language should help (thesis chapters 5 to 7). Chosen over MiniGrid's own
DoorKey (one colour, no distractors: one route to memorise, as in Room 1) and over
ObstructedMaze (long, hard for a learner to make any progress with in a study's budget).

Frames: ``render()`` gives ``size * tile_size`` pixels square (16 px tiles: 128 x 128 for size
8), large enough for template matching. A layout the expert cannot solve (a distractor walling
off the key or the door) is drawn again.
"""

from dataclasses import dataclass
from typing import Optional, Tuple

from attention_tasks.doorkey.expert import solvable
from minigrid.core.constants import COLOR_NAMES
from minigrid.core.grid import Grid
from minigrid.core.mission import MissionSpace
from minigrid.core.world_object import Ball, Box, Door, Goal, Key
from minigrid.minigrid_env import MiniGridEnv

DISTRACTOR_KINDS = (Key, Ball, Box)
MAX_LAYOUT_TRIES = 100


@dataclass
class DoorKeyConfig:
    """The level's size and clutter, and how it is drawn."""

    size: int = 8
    """Grid cells per side, outer walls included (8: a 6 x 6 interior)."""
    distractors: int = 4
    """Keys, balls and boxes of the other colours, on both sides of the wall."""
    tile_size: int = 16
    """Pixels per cell of the rendered frame."""
    max_steps: int = 0
    """Steps before the episode is truncated; 0: 10 x size^2 (640 for size 8)."""

    def validate(self) -> None:
        if self.size < 7:
            raise ValueError('size must be >= 7 (two sides of at least 2 columns), '
                             f'got {self.size}')
        if not 0 <= self.distractors <= 2 * (self.size - 2):
            raise ValueError(f'distractors must be in 0..{2 * (self.size - 2)}, '
                             f'got {self.distractors}')
        if self.tile_size < 8 or self.max_steps < 0:
            raise ValueError('tile_size must be >= 8 and max_steps >= 0')


class DistractorDoorKeyEnv(MiniGridEnv):
    """The level (see the module docstring); ``door``, ``key`` and ``goal_pos`` name its parts."""

    def __init__(self, config: Optional[DoorKeyConfig] = None, **kwargs):
        self.config = config or DoorKeyConfig()
        self.config.validate()
        self.door: Optional[Door] = None
        self.key: Optional[Key] = None
        self.goal_pos: Tuple[int, int] = (0, 0)
        size = self.config.size
        super().__init__(
            mission_space=MissionSpace(mission_func=self._mission, ordered_placeholders=[
                list(COLOR_NAMES)]),
            grid_size=size, max_steps=self.config.max_steps or 10 * size * size,
            tile_size=self.config.tile_size, **kwargs)

    @staticmethod
    def _mission(color: str) -> str:
        return f'open the {color} door and go to the green square'

    def _gen_grid(self, width: int, height: int) -> None:
        for _ in range(MAX_LAYOUT_TRIES):
            self._draw_layout(width, height)
            if solvable(self):
                return
        raise RuntimeError(f'no solvable layout in {MAX_LAYOUT_TRIES} draws: fewer distractors')

    def _draw_layout(self, width: int, height: int) -> None:
        self.carrying = None
        self.grid = Grid(width, height)
        self.grid.wall_rect(0, 0, width, height)
        split = self._rand_int(3, width - 3)  # both sides at least 2 columns wide
        self.grid.vert_wall(split, 0)
        color = self._rand_elem(COLOR_NAMES)
        self.door = Door(color, is_locked=True)
        self.put_obj(self.door, split, self._rand_int(1, height - 1))
        left, right = ((0, 0), (split, height)), ((split + 1, 0), (width - split - 1, height))
        self.goal_pos = tuple(self.place_obj(Goal(), *right))
        self.key = Key(color)
        self.place_obj(self.key, *left)
        others = [c for c in COLOR_NAMES if c != color]
        for _ in range(self.config.distractors):
            kind = self._rand_elem(DISTRACTOR_KINDS)
            self.place_obj(kind(self._rand_elem(others)), *self._rand_elem((left, right)))
        self.place_agent(*left)
        self.mission = self._mission(color)


@dataclass(frozen=True)
class DoorKeyState:
    """What the other nodes need of a step (the task's counterpart of Room 1's RAM state)."""

    x: int
    y: int
    direction: int
    """0 right, 1 down, 2 left, 3 up (MiniGrid's)."""
    carrying: str
    """'' or '<colour> <kind>', e.g. 'yellow key'."""
    door_color: str
    door_open: bool
    at_goal: bool

    @property
    def has_key(self) -> bool:
        return self.carrying == f'{self.door_color} key'


def state_of(env: DistractorDoorKeyEnv) -> DoorKeyState:
    """Read the state of ``env`` (after a reset or a step)."""
    x, y = (int(v) for v in env.agent_pos)
    carrying = env.carrying
    return DoorKeyState(
        x=x, y=y, direction=int(env.agent_dir),
        carrying=f'{carrying.color} {carrying.type}' if carrying is not None else '',
        door_color=env.door.color, door_open=bool(env.door.is_open),
        at_goal=(x, y) == tuple(env.goal_pos))

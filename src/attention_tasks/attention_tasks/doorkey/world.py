"""
DoorKey with distractors: a MiniGrid level whose layout changes every episode.

A room split by a wall with one locked door of a random colour; the key of that colour lies on
the agent's side, the green goal square on the other; keys, balls and boxes of other colours
distract on both sides. Every episode draws the wall's column, the door's row and colour, the
goal's, key's, distractors' and agent's places: which pixels matter changes with the layout,
which is where language should help (thesis chapters 5 to 7). Chosen over MiniGrid's own
DoorKey (one colour, no distractors: one route to memorise, as in Room 1) and over
ObstructedMaze (long, hard for a learner to make any progress with in a study's budget).

Frames: what the agent sees, MiniGrid's egocentric view of 7 x 7 cells (the agent at the bottom
centre, facing up; walls hide what is behind them), rendered in 16 px tiles: 112 x 112 RGB,
large enough for template matching (``observe``). The whole level (``render()``, 128 x 128 for
size 8) is for tools and people. Why the agent's view: from 10,000 frames labelled with the
expert's action, a head on a frozen encoder predicted the expert on new layouts for 71 % of the
egocentric frames and 45-49 % of the whole-level ones (always "forward" scores 45 %; an encoder
trained end to end did no better on the whole level): turning is relative to the agent, and the
egocentric frame shows it directly. A layout the expert cannot solve (a distractor walling
off the key or the door) is drawn again.
"""

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Mapping, Optional, Tuple

from attention_tasks.doorkey.expert import solvable
from attention_tasks.gridworld import AGENT_VIEW, TILE_SIZE
from minigrid.core.constants import COLOR_NAMES
from minigrid.core.grid import Grid
from minigrid.core.mission import MissionSpace
from minigrid.core.world_object import Ball, Box, Door, Goal, Key
from minigrid.minigrid_env import MiniGridEnv
import numpy as np

DISTRACTOR_KINDS = (Key, Ball, Box)
MAX_LAYOUT_TRIES = 100


@dataclass
class DoorKeyConfig:
    """The level's size and clutter, and how it is drawn."""

    size: int = 8
    """Grid cells per side, outer walls included (8: a 6 x 6 interior)."""
    distractors: int = 4
    """Keys, balls and boxes of the other colours, on both sides of the wall."""
    max_episode_steps: int = 0
    """Steps before the episode is truncated; 0: 10 x size^2 (640 for size 8)."""

    def validate(self) -> None:
        if self.size < 7:
            raise ValueError('size must be >= 7 (two sides of at least 2 columns), '
                             f'got {self.size}')
        if not 0 <= self.distractors <= 2 * (self.size - 2):
            raise ValueError(f'distractors must be in 0..{2 * (self.size - 2)}, '
                             f'got {self.distractors}')
        if self.max_episode_steps < 0:
            raise ValueError(f'max_episode_steps must be >= 0, got {self.max_episode_steps}')

    @property
    def tile_size(self) -> int:
        """Pixels per cell of a rendered frame (fixed: the templates are cut at this size)."""
        return TILE_SIZE


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
            grid_size=size, max_steps=self.config.max_episode_steps or 10 * size * size,
            tile_size=TILE_SIZE, agent_view_size=AGENT_VIEW, **kwargs)

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
    grid: str = ''
    """The whole grid, MiniGrid's ``Grid.encode()`` (type, colour, state per cell) in hex: the
    teacher plans on it (``planner_view``)."""
    layout: int = -1
    """The seed the episode's layout was drawn from."""
    heldout: bool = False
    """The layout comes from the held-out seeds (never trained on)."""

    @property
    def has_key(self) -> bool:
        return self.carrying == f'{self.door_color} key'

    def status(self) -> dict:
        """Return the env_status values of the state (``env_node.status``)."""
        return {'lives': 1, 'has_key': self.has_key, 'room': 0, 'x': self.x, 'y': self.y,
                'direction': self.direction, 'carrying': self.carrying,
                'door_color': self.door_color, 'door_open': self.door_open,
                'at_goal': self.at_goal, 'subgoals': progress(self), 'layout': self.layout,
                'heldout': self.heldout, 'grid': self.grid}

    def position(self):
        """Return agent_position's (x, y, z): the agent's cell (z 0: one room)."""
        return float(self.x), float(self.y), 0.0


SUBGOALS = ('key', 'door', 'goal')
"""The level's sub-goals in order: they take the place of Room 1's critical positions."""


def progress(state: DoorKeyState) -> int:
    """Return how many sub-goals are done (0..3); an open door counts the key as taken."""
    if state.at_goal:
        return 3
    if state.door_open:
        return 2
    return 1 if state.has_key else 0


def state_of(env: DistractorDoorKeyEnv, layout: int = -1, heldout: bool = False
             ) -> DoorKeyState:
    """Read the state of ``env`` (after a reset or a step)."""
    x, y = (int(v) for v in env.agent_pos)
    carrying = env.carrying
    return DoorKeyState(
        x=x, y=y, direction=int(env.agent_dir),
        carrying=f'{carrying.color} {carrying.type}' if carrying is not None else '',
        door_color=env.door.color, door_open=bool(env.door.is_open),
        at_goal=(x, y) == tuple(env.goal_pos), grid=env.grid.encode().tobytes().hex(),
        layout=layout, heldout=heldout)


def state_from_status(values: Mapping[str, object]) -> DoorKeyState:
    """Return the state env_status ``values`` (parsed) describe; KeyError, ValueError if not."""
    return DoorKeyState(
        x=int(values['x']), y=int(values['y']), direction=int(values['direction']),
        carrying=str(values['carrying']), door_color=str(values['door_color']),
        door_open=bool(values['door_open']), at_goal=bool(values['at_goal']),
        grid=str(values['grid']), layout=int(values.get('layout', -1)),
        heldout=bool(values.get('heldout', False)))


def planner_view(state: DoorKeyState) -> SimpleNamespace:
    """
    Rebuild what ``expert.next_action`` reads (grid, agent, what it holds, door, key, goal).

    From the state alone, as the teacher in another process sees it: the grid is decoded from
    ``state.grid``; what the agent carries from ``state.carrying``.
    """
    cells = np.frombuffer(bytes.fromhex(state.grid), np.uint8)
    size = int(round((cells.size // 3) ** 0.5))
    if size * size * 3 != cells.size or size < 3:
        raise ValueError(f'grid of {cells.size} values is not size x size x 3')
    grid, _ = Grid.decode(cells.reshape(size, size, 3).copy())
    door = key = goal = None
    for i in range(size):
        for j in range(size):
            obj = grid.get(i, j)
            if obj is None:
                continue
            obj.cur_pos = (i, j)
            if obj.type == 'door':
                door = obj
            elif obj.type == 'goal':
                goal = (i, j)
            elif obj.type == 'key' and obj.color == state.door_color:
                key = obj
    if door is None or goal is None:
        raise ValueError('the grid has no door or no goal')
    carrying = None
    if state.carrying:
        color, kind = state.carrying.split(' ', 1)
        carrying = {'key': Key, 'ball': Ball, 'box': Box}[kind](color)
        if carrying.color == state.door_color and kind == 'key':
            key = carrying
    return SimpleNamespace(grid=grid, agent_pos=(state.x, state.y), agent_dir=state.direction,
                           carrying=carrying, door=door, key=key, goal_pos=goal, width=size,
                           height=size)

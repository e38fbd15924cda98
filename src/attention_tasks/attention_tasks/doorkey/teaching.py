"""
What the DoorKey teacher knows: the expert's action, which actions are as good, what to say.

feedback_node's task teacher loads ``KNOWLEDGE`` from ``attention_tasks.<task>.teaching`` (the
convention for every task but Room 1, whose teacher is feedback_node's own) and reads all of a
step from its env_status values, as a person watching the screen would:

- ``observe(values)``: the step's ``DoorKeyState`` (``world.state_from_status``), checked (a bad
  grid, a pose off the grid: ValueError or KeyError); the expert's action is worked out here,
  once per state (``expert.next_action`` on ``world.planner_view``, memoised).
- ``expert_action(state)``: that action; None at the goal or where no way exists (not judged).
- ``as_good(state, action, expert_action)``: the same action, or one after which the expert's
  plan is no longer than after its own. Measured, not guessed: ``after`` applies MiniGrid's
  rules to the encoded grid, then the expert plays on from both states until the two plays
  meet (the state reached sooner or at the same step decides), end, or loop. Turning left or
  right when the target is behind meets after one step; a wasted action (pickup facing a wall,
  forward into one: the state does not change) is known without playing; a distractor picked
  up is mostly dropped back at once (a step later than the expert's own play: not as good),
  unless taking it away opens a way shorter by more.
- ``sentence(state)``: ``(sub-goal index 0..2, language.sentence)``; None at the goal (the
  episode is over).
"""

from dataclasses import replace
import functools
import math
from typing import Mapping, Optional, Tuple

from attention_tasks.doorkey.expert import (
    DIRECTIONS, DROP, FORWARD, LEFT, next_action, PICKUP, RIGHT, TOGGLE)
from attention_tasks.doorkey.language import sentence
from attention_tasks.doorkey.world import (
    DoorKeyState, planner_view, progress, state_from_status, SUBGOALS)
from minigrid.core.constants import (
    COLOR_NAMES, COLOR_TO_IDX, IDX_TO_COLOR, OBJECT_TO_IDX, STATE_TO_IDX)

MEMO_STATES = 4096
"""Expert actions remembered, by state (the plays of ``as_good`` revisit the steps to come)."""
MAX_PLAY_STEPS = 128
"""Steps of expert play from each side after which ``as_good`` gives up (says not as good)."""

_EMPTY, _WALL, _DOOR, _GOAL = (OBJECT_TO_IDX[k] for k in ('empty', 'wall', 'door', 'goal'))
_PASSABLE = (_EMPTY, _GOAL, OBJECT_TO_IDX['floor'])
_CARRIED = {OBJECT_TO_IDX[k]: k for k in ('key', 'ball', 'box')}
"""What can be picked up (MiniGrid's ``can_pickup``), by type index."""
_OPEN, _CLOSED, _LOCKED = (STATE_TO_IDX[k] for k in ('open', 'closed', 'locked'))


def after(state: DoorKeyState, action: int) -> DoorKeyState:
    """Return the state ``action`` leads to from ``state`` (MiniGrid's ``step``, on the grid)."""
    x, y, d = state.x, state.y, state.direction
    if action in (LEFT, RIGHT):
        return replace(state, direction=(d + (1 if action == RIGHT else -1)) % 4)
    cells = bytearray.fromhex(state.grid)
    size = _size(len(cells))
    fx, fy = x + DIRECTIONS[d][0], y + DIRECTIONS[d][1]
    at = (fx * size + fy) * 3
    kind, color, door = cells[at:at + 3]
    if action == FORWARD:
        if kind in _PASSABLE or (kind == _DOOR and door == _OPEN):
            return replace(state, x=fx, y=fy, at_goal=kind == _GOAL)
        return state
    if action == PICKUP:
        if kind not in _CARRIED or state.carrying:
            return state
        cells[at:at + 3] = bytes((_EMPTY, 0, 0))
        return _changed(state, cells, f'{IDX_TO_COLOR[color]} {_CARRIED[kind]}')
    if action == DROP:
        if kind != _EMPTY or not state.carrying:
            return state
        held_color, held_kind = state.carrying.split(' ', 1)
        cells[at:at + 3] = bytes((OBJECT_TO_IDX[held_kind], COLOR_TO_IDX[held_color], 0))
        return _changed(state, cells, '')
    if action == TOGGLE:
        if kind == _DOOR:
            if door == _LOCKED:
                if state.carrying != f'{IDX_TO_COLOR[color]} key':
                    return state
                door = _OPEN
            else:
                door = _CLOSED if door == _OPEN else _OPEN
            cells[at + 2] = door
        elif kind == OBJECT_TO_IDX['box']:  # a box opens into what it holds: nothing here
            cells[at:at + 3] = bytes((_EMPTY, 0, 0))
        else:
            return state
        return _changed(state, cells, state.carrying)
    raise ValueError(f'action {action} is not a DoorKey action (0..5)')


def _size(values: int) -> int:
    size = int(round((values // 3) ** 0.5))
    if size * size * 3 != values:
        raise ValueError(f'grid of {values} values is not size x size x 3')
    return size


def _changed(state: DoorKeyState, cells: bytearray, carrying: str) -> DoorKeyState:
    door_open = any(cells[i] == _DOOR and cells[i + 2] == _OPEN for i in range(0, len(cells), 3))
    return replace(state, carrying=carrying, door_open=door_open, grid=cells.hex())


@functools.lru_cache(maxsize=MEMO_STATES)
def expert_action_of(state: DoorKeyState) -> Optional[int]:
    """Return the expert's action in ``state`` (None: at the goal, or no way to it)."""
    if state.at_goal:
        return None
    return next_action(planner_view(state))


def plan_no_longer(mine: DoorKeyState, theirs: DoorKeyState,
                   limit: int = MAX_PLAY_STEPS) -> bool:
    """
    Tell whether the expert's plan from ``mine`` is no longer than from ``theirs``.

    Both are played on, a step each in turn; a state both plays pass decides (``mine`` got there
    no later: True), else the goal reached no later. A play that finds no way or comes back to
    a state of its own (a loop) never ends; ``limit`` steps without a decision: False.
    """
    paths = ({mine: 0}, {theirs: 0})  # state -> steps after the action judged
    heads = [mine, theirs]
    ends = [0 if mine.at_goal else None, 0 if theirs.at_goal else None]  # None: still playing
    for step in range(1, limit + 1):
        decided = _by_the_ends(*ends)
        if decided is not None:
            return decided
        for side in (1, 0):  # theirs first: a state ``mine`` reaches at the same step counts
            if ends[side] is not None:
                continue
            action = expert_action_of(heads[side])
            head = None if action is None else after(heads[side], action)
            if head is None or head in paths[side]:
                ends[side] = math.inf
                continue
            met = paths[1 - side].get(head)
            if met is not None:
                return met <= step if side == 1 else step <= met
            paths[side][head], heads[side] = step, head
            if head.at_goal:
                ends[side] = step
    return bool(_by_the_ends(*ends))


def _by_the_ends(mine: Optional[float], theirs: Optional[float]) -> Optional[bool]:
    """Decide by the steps each play took to the goal (inf: never), None: not yet."""
    if mine == math.inf:
        return False
    if theirs is not None and theirs < math.inf:
        return mine is not None and mine <= theirs
    return True if mine is not None else None


class DoorKeyKnowledge:
    """The teacher's knowledge of DoorKey (``feedback_node.task_teacher.TeacherKnowledge``)."""

    SILENT = ('no_expert_action',)
    SPEAKS_AT_NEW_EPISODE = True
    """A new episode is a new layout: name its objects at once."""

    def observe(self, values: Mapping[str, object]) -> DoorKeyState:
        """Return the state ``values`` describe; KeyError, ValueError when they do not."""
        state = state_from_status(values)
        cells = bytes.fromhex(state.grid)
        size = _size(len(cells))
        border = [(i, j) for i in range(size) for j in (0, size - 1)]
        if any(cells[(i * size + j) * 3] != _WALL or cells[(j * size + i) * 3] != _WALL
               for i, j in border):
            raise ValueError('the grid is not walled in')
        if not (0 < state.x < size - 1 and 0 < state.y < size - 1
                and 0 <= state.direction < 4):
            raise ValueError(f'pose ({state.x}, {state.y}, {state.direction}) is not on the '
                             f'{size} x {size} grid')
        if state.door_color not in COLOR_NAMES:
            raise ValueError(f'door_color {state.door_color!r} is not a MiniGrid colour')
        if state.carrying:
            color, _, kind = state.carrying.partition(' ')
            if color not in COLOR_NAMES or kind not in _CARRIED.values():
                raise ValueError(f'carrying {state.carrying!r} is not "<colour> key|ball|box"')
        expert_action_of(state)  # a grid without a door or a goal: ValueError
        return state

    def expert_action(self, state: DoorKeyState) -> Optional[int]:
        return expert_action_of(state)

    def silent(self, state: DoorKeyState, expert_action: Optional[int]) -> Optional[str]:
        """Return 'no_expert_action' where there is none (at the goal, no way), else None."""
        return 'no_expert_action' if expert_action is None else None

    def as_good(self, state: DoorKeyState, action: int, expert_action: int) -> bool:
        """Tell whether ``action`` leaves the expert's plan as short as ``expert_action``."""
        if action == expert_action:
            return True
        mine = after(state, action)
        if mine == state:  # nothing happened: a step lost
            return False
        return plan_no_longer(mine, after(state, expert_action))

    def sentence(self, state: DoorKeyState) -> Optional[Tuple[int, str]]:
        """Return ``(sub-goal index, sentence)`` of the next sub-goal; None after the goal."""
        done = progress(state)
        return (done, sentence(state)) if done < len(SUBGOALS) else None


KNOWLEDGE = DoorKeyKnowledge()

"""
The expert of the DoorKey level: a planner on the true grid, from any state.

It is the teacher's knowledge, as the scripted expert is in Room 1. The next sub-goal decides
the target: the door's key (face it, pick it up), then the door (face it, open it), then the
goal square (step onto it). Paths are breadth-first over poses (cell, direction) with left,
right and forward, through empty cells, the goal and an open door; ties go to the lowest
action, so a plan is deterministic.

From any state: carrying anything but the door's key, it first drops it on a free cell off the
way to the target. When objects wall the target off (a learner dropped a ball in a corridor),
it plans through movable objects and clears the first one in the way: it puts down what it
holds (the key too) off that way, picks the blocker up, and drops it off the way in turn.
Measured from 299 states reached by 10-150 random actions (4 and 8 distractors): 292 solved;
the other 7 are rearrangement puzzles in a crowded room that this greedy clearing loops on (8
distractors in 6 x 6 cells for 6 of them). ``next_action`` returns None only when no way exists
at all (the teacher then stays silent, as in Room 1 when no action can matter).
"""

from collections import deque
import copy
from typing import Callable, List, Optional, Set, Tuple

LEFT, RIGHT, FORWARD, PICKUP, DROP, TOGGLE = 0, 1, 2, 3, 4, 5
DIRECTIONS = ((1, 0), (0, 1), (-1, 0), (0, -1))
"""MiniGrid's: 0 right, 1 down, 2 left, 3 up."""
MOVABLE = ('key', 'ball', 'box')

Pose = Tuple[int, int, int]
Cell = Tuple[int, int]


def _front(pose: Pose) -> Cell:
    x, y, d = pose
    return x + DIRECTIONS[d][0], y + DIRECTIONS[d][1]


def _free(env, cell: Cell) -> bool:
    obj = env.grid.get(*cell)
    return obj is None or obj.type == 'goal' or (obj.type == 'door' and obj.is_open)


def _free_or_movable(env, cell: Cell) -> bool:
    obj = env.grid.get(*cell)
    return _free(env, cell) or obj.type in MOVABLE


def _path(env, start: Pose, done: Callable[[Pose], bool],
          passable: Callable[[object, Cell], bool] = _free) -> Optional[List[Pose]]:
    """Return the poses of a shortest path from ``start`` to one where ``done``; None: none."""
    came = {start: None}
    queue = deque([start])
    while queue:
        pose = queue.popleft()
        if done(pose):
            path = [pose]
            while came[path[-1]] is not None:
                path.append(came[path[-1]])
            return path[::-1]
        x, y, d = pose
        moves = [(x, y, (d - 1) % 4), (x, y, (d + 1) % 4)]
        if passable(env, _front(pose)):
            moves.append((*_front(pose), d))
        for nxt in moves:
            if nxt not in came:
                came[nxt] = pose
                queue.append(nxt)
    return None


def _step(path: List[Pose], arrived: int) -> int:
    """Return the first action along ``path``, or ``arrived`` when it is already there."""
    if len(path) == 1:
        return arrived
    (x, y, d), (nx, ny, nd) = path[0], path[1]
    if (nx, ny) != (x, y):
        return FORWARD
    return LEFT if nd == (d - 1) % 4 else RIGHT


def _cells(path: Optional[List[Pose]]) -> List[Cell]:
    """Return the cells a path passes, in order, and the one it faces at the end."""
    if not path:
        return []
    cells = list(dict.fromkeys((x, y) for x, y, _ in path))
    return cells + [_front(path[-1])]


def _facing(cell: Cell) -> Callable[[Pose], bool]:
    return lambda p: _front(p) == cell


def _way(env, pose: Pose, done: Callable[[Pose], bool]) -> Optional[List[Pose]]:
    """Return a shortest free path, else one through movable objects (to clear)."""
    return _path(env, pose, done) or _path(env, pose, done, _free_or_movable)


def _main_way(env, pose: Pose) -> Optional[List[Pose]]:
    """Return the way to the door (closed) or the goal (open)."""
    if env.door.is_open:
        goal = tuple(env.goal_pos)
        return _way(env, pose, lambda p: (p[0], p[1]) == goal)
    return _way(env, pose, _facing(tuple(int(v) for v in env.door.cur_pos)))


def _key_way(env, pose: Pose) -> Optional[List[Pose]]:
    return _way(env, pose, _facing(_key_cell(env)))


def _key_cell(env) -> Optional[Cell]:
    return None if env.carrying is env.key else tuple(int(v) for v in env.key.cur_pos)


def _blockers(env, way: Optional[List[Pose]]) -> List[Cell]:
    """Return the cells along ``way`` holding objects (the key too once the door is open)."""
    key = None if env.door.is_open else _key_cell(env)
    return [c for c in _cells(way)[:-1] if not _free(env, c) and c != key]


def _needed_cells(env, x: int, y: int) -> Set[Cell]:
    """
    Return the cells the ways to the next sub-goals pass, from every direction at (x, y).

    From every direction, so that turning to a drop cell does not change which cells are
    needed (the choice would swing back and forth).
    """
    needed: Set[Cell] = set()
    for d in range(4):
        needed |= set(_cells(_main_way(env, (x, y, d))))
        if not env.door.is_open and env.carrying is not env.key:
            needed |= set(_cells(_key_way(env, (x, y, d))))
    return needed


def _drop_off(env, pose: Pose, keep_clear: Set[Cell]) -> Optional[int]:
    """Return the way to put down what is held: on a free cell no way needs, else any free."""
    for keep in (keep_clear, set()):
        path = _path(env, pose, lambda p: env.grid.get(*_front(p)) is None
                     and _front(p) not in keep)
        if path is not None:
            return _step(path, DROP)
    return None


def _pick_up(env, pose: Pose, cell: Cell) -> Optional[int]:
    path = _path(env, pose, _facing(cell))
    return None if path is None else _step(path, PICKUP)


def next_action(env) -> Optional[int]:
    """Return the expert's action in ``env``'s state; None when the goal cannot be reached."""
    x, y = (int(v) for v in env.agent_pos)
    pose = (x, y, int(env.agent_dir))
    held = env.carrying
    if held is not None and held is not env.key:  # put it down off every way it needs
        env.carrying = None
        keep = _needed_cells(env, x, y)
        env.carrying = held
        return _drop_off(env, pose, keep)
    way = _main_way(env, pose)
    if way is None:
        return None
    blockers = _blockers(env, way)
    if blockers:  # objects wall the way off: move the first one
        if held is not None:
            return _drop_off(env, pose, _needed_cells(env, x, y))
        return _pick_up(env, pose, blockers[0])
    if env.door.is_open:
        return _step(way, FORWARD) if len(way) > 1 else None
    if held is env.key or not env.door.is_locked:  # a closed door once unlocked opens as it is
        return _step(way, TOGGLE)
    key_way = _key_way(env, pose)
    if key_way is None:
        return None
    blockers = _blockers(env, key_way)
    return _pick_up(env, pose, blockers[0] if blockers else _key_cell(env))


def solvable(env) -> bool:
    """Tell whether the expert reaches the goal from ``env``'s state (a copy is played)."""
    trial = copy.deepcopy(env)
    trial.render_mode, trial.step_count = None, 0  # (mid-reset: not counted yet)
    for _ in range(8 * trial.width * trial.height):
        action = next_action(trial)
        if action is None:
            return False
        _, _, terminated, _, _ = trial.step(action)
        if terminated:
            return True
    return False

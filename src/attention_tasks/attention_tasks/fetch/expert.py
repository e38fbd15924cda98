"""
The expert of Fetch: the shortest way to face the target and pick it up, from any state (pure).

Breadth-first over poses (cell, direction) with left, right and forward through empty cells
(objects are in the way, as in MiniGrid); ties go to the lowest action, so a plan is
deterministic. It plans on the grid a step's status carries, so the teacher in another process
plans on what env_node saw.
"""

from collections import deque
from typing import Dict, List, Optional, Tuple

from attention_tasks.fetch.world import decode_grid, FetchState
from attention_tasks.gridworld import FORWARD, LEFT, PICKUP, RIGHT

DIRECTIONS = ((1, 0), (0, 1), (-1, 0), (0, -1))
"""MiniGrid's: 0 right, 1 down, 2 left, 3 up."""
Pose = Tuple[int, int, int]


def after(pose: Pose, action: int, free) -> Pose:
    """Return the pose an action leads to (turns; forward onto a free cell; else the same)."""
    x, y, d = pose
    if action == LEFT:
        return x, y, (d - 1) % 4
    if action == RIGHT:
        return x, y, (d + 1) % 4
    if action == FORWARD:
        ahead = x + DIRECTIONS[d][0], y + DIRECTIONS[d][1]
        return (ahead[0], ahead[1], d) if free(ahead) else pose
    return pose


def _target_cell(level, target: str) -> Optional[Tuple[int, int]]:
    for i in range(level.size):
        for j in range(level.size):
            obj = level.grid.get(i, j)
            if obj is not None and f'{obj.color} {obj.type}' == target:
                return i, j
    return None


def _free(level):
    """Return whether a cell of ``level`` can be walked onto (in the room, nothing on it)."""
    return lambda c: 0 <= c[0] < level.size and 0 <= c[1] < level.size and (
        level.grid.get(*c) is None)


def distances(state: FetchState, level=None) -> Dict[Pose, int]:
    """Return every pose's number of moves to face the target (unreachable poses absent)."""
    level = level or decode_grid(state)
    cell = _target_cell(level, state.target)
    if cell is None:
        return {}
    free = _free(level)

    # Backwards from every pose that faces the target: the moves that lead into a pose.
    goals = [(cell[0] - dx, cell[1] - dy, d) for d, (dx, dy) in enumerate(DIRECTIONS)]
    found = {pose: 0 for pose in goals if free(pose[:2])}
    queue = deque(found)
    while queue:
        pose = queue.popleft()
        x, y, d = pose
        dx, dy = DIRECTIONS[d]
        before = [(x, y, (d + 1) % 4), (x, y, (d - 1) % 4)]  # a left, a right turn into it
        if free((x - dx, y - dy)):
            before.append((x - dx, y - dy, d))                 # forward into it
        for prior in before:
            if prior not in found:
                found[prior] = found[pose] + 1
                queue.append(prior)
    return found


def plan_length(state: FetchState, pose: Optional[Pose] = None,
                level=None) -> Optional[int]:
    """Return the actions left to fetch the target from ``pose`` (the state's); None: no way."""
    if state.carrying:
        return 0 if state.fetched else None
    pose = pose or (state.x, state.y, state.direction)
    moves = distances(state, level).get(pose)
    return None if moves is None else moves + 1


def next_action(state: FetchState) -> Optional[int]:
    """Return the expert's action; None when there is none (something in hand, no way)."""
    if state.carrying:
        return None
    level = decode_grid(state)
    found = distances(state, level)
    pose = (state.x, state.y, state.direction)
    if pose not in found:
        return None
    if found[pose] == 0:
        return PICKUP
    for action in (LEFT, RIGHT, FORWARD):
        if found.get(after(pose, action, _free(level)), -1) == found[pose] - 1:
            return action
    return None


def moves_after(state: FetchState, actions: List[int]) -> Optional[int]:
    """Return the plan length after ``actions`` from the state's pose (turns and forwards)."""
    level = decode_grid(state)
    pose = (state.x, state.y, state.direction)
    for action in actions:
        pose = after(pose, action, _free(level))
    return plan_length(state, pose, level)

"""
A scripted expert for Room 1: a closed-loop controller on the agent's RAM position.

The route (the thesis's optimal trajectory): down the middle ladder, right along the conveyor,
jump onto the rope, jump off it onto the lower right platform, down the right ladder, left
along the floor jumping over the rolling skull, up the left ladder, jump up to the key.

Each step the expert reads where the agent stands, names the phase of the route that position
belongs to and picks the action for it, so it recovers from wherever it finds itself (after
random warm-up steps, say). The skull is not in the agent's position: ``act`` takes its x
(``skull_x_from_ram`` or ``skull_x_from_frame``) when the caller can see it; otherwise a
``SkullTracker`` predicts it from the skull's motion since the start of a fresh game (the
skull rolls back and forth at one pixel per step, see ``SkullTracker``).

All coordinates and constants below were measured with the real emulator (frameskip 4, no
sticky actions); ``tests/test_expert.py`` runs the route through it.
"""

import enum
import math
from typing import Optional

from attention_common.joy_actions import ACTION_MEANINGS
import numpy as np

A = {name: index for index, name in enumerate(ACTION_MEANINGS)}
NOOP, FIRE, UP, RIGHT, LEFT, DOWN = A['NOOP'], A['FIRE'], A['UP'], A['RIGHT'], A['LEFT'], A['DOWN']
RIGHTFIRE, LEFTFIRE = A['RIGHTFIRE'], A['LEFTFIRE']
FIRE_ACTIONS = frozenset(a for a, name in enumerate(ACTION_MEANINGS) if 'FIRE' in name)
"""Every action that presses the button (fire acts on a press, not while held)."""

# Floors (RAM y grows upward).
TOP_Y, PLATFORM_Y, FLOOR_Y = 235, 192, 148
# Ladders (x where the agent climbs; it snaps onto a ladder within a few pixels).
MIDDLE_LADDER_X, RIGHT_LADDER_X, LEFT_LADDER_X = 77, 133, 21
LADDER_SNAP = 3
# The top floor is three pieces: the middle one (x 65..89, the ladder) is reached from the
# others by jumping over the gaps; jumps from these x land on it.
TOP_LEFT_MAX_X, TOP_LEFT_JUMP_X = 58, 51
TOP_RIGHT_MIN_X, TOP_RIGHT_JUMP_X = 96, 104
# Conveyor under the middle ladder (it carries a standing agent left): jump from here to the rope.
CONVEYOR_MIN_X, CONVEYOR_MAX_X, ROPE_JUMP_X = 50, 104, 94
ROPE_MIN_X, ROPE_MAX_X = 105, 113
ROPE_JUMP_MIN_Y = 198  # climb at least this high on the rope before jumping to the platform
RIGHT_PLATFORM_MIN_X = 118
LEFT_PLATFORM_MAX_X = 40
KEY_JUMP_X = 13  # jumping straight up at or left of this reaches the key

# The skull: ram[47] rolls between SKULL_LOW and SKULL_HIGH, one pixel per step, pausing one
# step at each end; a fresh game starts it at SKULL_START rolling left.
SKULL_RAM = 47
SKULL_LOW, SKULL_HIGH, SKULL_START = 22, 72, 58
# Agent x minus skull ram is the gap d. Measured over every skull phase: jumping left from a
# standstill at d == 47 clears an approaching skull; d <= 60 is close enough to wait there.
SKULL_JUMP_GAP = 47
SKULL_WAIT_GAP = 60
SKULL_PASSED_GAP = 20  # below this the agent is already past the skull
SKULL_JUMP_MAX = 65    # a skull beyond this turns around mid-jump: wait for its next pass
SKULL_GONE_STEPS = 3   # a skull x seen unchanged this many steps in a row: it has vanished
# skull_x_from_frame: the skull is the only pure-grey sprite on the floor rows of a frame.
_SKULL_ROWS = slice(160, 186)
_SKULL_COLOUR = (236, 236, 236)
_SKULL_FRAME_OFFSET = 35.5  # centre column of the sprite minus ram[47]


class Phase(enum.Enum):
    """The stage of the route the agent's position belongs to."""

    TO_MIDDLE_LADDER = 'walk to the middle ladder'
    DOWN_MIDDLE_LADDER = 'climb down the middle ladder'
    TO_ROPE = 'walk right along the conveyor and jump to the rope'
    ON_ROPE = 'jump right off the rope'
    TO_RIGHT_LADDER = 'walk to the right ladder'
    DOWN_RIGHT_LADDER = 'climb down the right ladder'
    ACROSS_FLOOR = 'walk left along the floor, jumping the skull'
    UP_LEFT_LADDER = 'climb up the left ladder'
    TO_KEY = 'walk left and jump up to the key'
    AIRBORNE = 'in the air: wait for the landing'
    DONE = 'has the key'


def skull_x_from_ram(ram) -> int:
    """Return the skull's x as the expert uses it (ram[47])."""
    return int(ram[SKULL_RAM])


def skull_x_from_frame(frame: np.ndarray) -> Optional[float]:
    """Estimate ram[47] from an RGB frame (within half a pixel); None if no skull is seen."""
    rows = frame[_SKULL_ROWS]
    mask = np.all(rows == np.asarray(_SKULL_COLOUR, dtype=rows.dtype), axis=2)
    columns = np.flatnonzero(mask.any(axis=0))
    if columns.size == 0:
        return None
    return (columns[0] + columns[-1]) / 2.0 - _SKULL_FRAME_OFFSET


def _advance_skull(position: int, velocity: int):
    """One step of the skull's motion: a pause of one step at each end, then it turns."""
    if velocity < 0 and position <= SKULL_LOW:
        return SKULL_LOW, 1
    if velocity > 0 and position >= SKULL_HIGH:
        return SKULL_HIGH, -1
    return position + velocity, velocity


class SkullTracker:
    """Where the skull is and which way it rolls: predicted each step, corrected when seen."""

    RESYNC = 1.25
    """A measurement further than this from the prediction replaces it."""

    def __init__(self):
        self.reset()

    def reset(self, position: int = SKULL_START, velocity: int = -1) -> None:
        """Assume a fresh game (or the given skull state) at the next ``update``."""
        self.position, self.velocity = position, velocity
        self._first = True

    def update(self, measured: Optional[float] = None) -> int:
        """Advance one step (none at the first call) and return the skull's x."""
        previous = self.position
        if not self._first:
            self.position, self.velocity = _advance_skull(self.position, self.velocity)
        if measured is not None and abs(measured - self.position) > self.RESYNC:
            seen = min(max(int(math.floor(measured + 0.5)), SKULL_LOW), SKULL_HIGH)
            if not self._first and seen != previous:
                self.velocity = 1 if seen > previous else -1
            elif seen in (SKULL_LOW, SKULL_HIGH):
                self.velocity = 1 if seen == SKULL_LOW else -1
            self.position = seen
        self._first = False
        return self.position


class RoomOneExpert:
    """Plays Room 1 from wherever the agent is to the key; ``act`` once per env step."""

    def __init__(self):
        self.skull = SkullTracker()
        self.reset()

    def reset(self) -> None:
        """Call at the start of every episode (a fresh game, before its first ``act``)."""
        self.skull.reset()
        self._seen_skull: Optional[float] = None
        self._skull_still = 0
        self.phase: Optional[Phase] = None
        self._last_action = NOOP

    def act(self, state, skull_x: Optional[float] = None,
            previous_action: Optional[int] = None) -> int:
        """
        Return the ALE action for ``state`` (a RamState: x, y, has_key).

        ``skull_x`` is the skull's ram[47] if the caller sees it; without it the tracker
        predicts it (exact for a fresh game played without losing a life).
        ``previous_action``: the action actually taken at the step before, when someone else
        plays (the teacher judging a learner); fire acts on a press, so it matters.
        """
        if previous_action is not None:
            self._last_action = int(previous_action)
        skull = self.skull.update(skull_x)
        if skull_x is not None:
            self._skull_still = self._skull_still + 1 if skull_x == self._seen_skull else 0
            self._seen_skull = skull_x
        self.phase = phase_of(state)
        action = self._action(self.phase, int(state.x), int(state.y), skull)
        if self._last_action in FIRE_ACTIONS and action in FIRE_ACTIONS:
            action = NOOP  # fire acts on a press: let go for one step first
        self._last_action = action
        return action

    def _action(self, phase: Phase, x: int, y: int, skull: int) -> int:
        if phase is Phase.TO_MIDDLE_LADDER:
            return _to_middle_ladder(x)
        if phase in (Phase.DOWN_MIDDLE_LADDER, Phase.DOWN_RIGHT_LADDER):
            return DOWN
        if phase is Phase.TO_ROPE:
            return RIGHTFIRE if x >= ROPE_JUMP_X else RIGHT
        if phase is Phase.ON_ROPE:
            return RIGHTFIRE if y >= ROPE_JUMP_MIN_Y else UP
        if phase is Phase.TO_RIGHT_LADDER:
            return _walk_toward(x, RIGHT_LADDER_X, then=DOWN, snap=LADDER_SNAP)
        if phase is Phase.ACROSS_FLOOR:
            return self._cross_floor(x, skull)
        if phase is Phase.UP_LEFT_LADDER:
            return UP
        if phase is Phase.TO_KEY:
            return FIRE if x <= KEY_JUMP_X else LEFT
        return NOOP

    @property
    def skull_gone(self) -> bool:
        """
        Tell whether the skull seen has not moved for ``SKULL_GONE_STEPS`` steps: it is gone.

        A rolling skull moves every step but one at each end of its path; once it has killed
        the agent it vanishes from the room and its RAM x stays where it was.
        """
        return self._skull_still >= SKULL_GONE_STEPS

    def _cross_floor(self, x: int, skull: int) -> int:
        if x <= LEFT_LADDER_X + 1:
            return UP
        if self.skull_gone:
            return LEFT
        gap = x - skull
        if gap <= SKULL_PASSED_GAP:
            return LEFT
        approaching = self.skull.velocity > 0
        if approaching and gap <= SKULL_JUMP_GAP and skull <= SKULL_JUMP_MAX:
            return LEFTFIRE
        if gap <= SKULL_WAIT_GAP:
            return NOOP  # let the skull come to the jump gap (or roll away and come back)
        return LEFT


def _to_middle_ladder(x: int) -> int:
    if x <= TOP_LEFT_MAX_X:
        return RIGHTFIRE if x >= TOP_LEFT_JUMP_X else RIGHT
    if x >= TOP_RIGHT_MIN_X:
        return LEFTFIRE if x <= TOP_RIGHT_JUMP_X else LEFT
    return _walk_toward(x, MIDDLE_LADDER_X, then=DOWN, snap=4)


def _walk_toward(x: int, target: int, then: int, snap: int) -> int:
    if abs(x - target) <= snap:
        return then
    return RIGHT if x < target else LEFT


def phase_of(state) -> Phase:
    """Name the stage of the route that the agent's position belongs to."""
    x, y = int(state.x), int(state.y)
    if state.has_key:
        return Phase.DONE
    if y == TOP_Y:
        return Phase.TO_MIDDLE_LADDER
    if FLOOR_Y < y < TOP_Y and ROPE_MIN_X <= x <= ROPE_MAX_X:
        return Phase.ON_ROPE
    if y == PLATFORM_Y:
        if CONVEYOR_MIN_X <= x <= CONVEYOR_MAX_X:
            return Phase.TO_ROPE
        if x >= RIGHT_PLATFORM_MIN_X:
            return Phase.TO_RIGHT_LADDER
        if x <= LEFT_PLATFORM_MAX_X:
            return Phase.TO_KEY
        return Phase.AIRBORNE
    if y == FLOOR_Y:
        return Phase.ACROSS_FLOOR
    if PLATFORM_Y < y < TOP_Y and x == MIDDLE_LADDER_X:
        return Phase.DOWN_MIDDLE_LADDER
    if FLOOR_Y < y < PLATFORM_Y:
        if x == RIGHT_LADDER_X:
            return Phase.DOWN_RIGHT_LADDER
        if x == LEFT_LADDER_X:
            return Phase.UP_LEFT_LADDER
    return Phase.AIRBORNE

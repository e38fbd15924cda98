"""
What Fetch's teacher knows: the episode's target, the expert's action, and the mission to say.

feedback_node's one teacher asks ``KNOWLEDGE`` about each step (``TeacherKnowledge``). An
action is as good as the expert's when it is the expert's, or when it leaves the way to the
target no longer (a turn either way at a fork); picking up anything but the target, and moves
that change nothing, are bad. The mission ("pick up the purple ball") is said at the first step
of every episode and every ``utterance_interval`` after: it is the only place the goal is.
"""

from typing import Mapping, Optional, Tuple

from attention_tasks.fetch.expert import moves_after, next_action
from attention_tasks.fetch.world import (
    decode_grid, FetchState, KINDS, mission, PAIRS, phrase, state_from_status)
from attention_tasks.gridworld import FORWARD, LEFT, NUM_ACTIONS, RIGHT
from minigrid.core.constants import COLOR_NAMES

SENTENCE_OF = {phrase(color, kind): index for index, (color, kind) in enumerate(PAIRS)}
"""``Utterance.sentence_of`` of each target: its index among the colour-kind pairs."""


class FetchKnowledge:
    """The teacher's knowledge of Fetch (``feedback_node.task_teacher.TeacherKnowledge``)."""

    SILENT = ('no_expert_action',)
    SPEAKS_AT_NEW_EPISODE = True
    """A new episode has a new target: say it at once."""

    def observe(self, values: Mapping[str, object]) -> FetchState:
        """Return the state ``values`` describe; KeyError, ValueError when they do not."""
        state = state_from_status(values)
        level = decode_grid(state)
        if not (0 < state.x < level.size - 1 and 0 < state.y < level.size - 1
                and 0 <= state.direction < 4):
            raise ValueError(f'pose ({state.x}, {state.y}, {state.direction}) is not in the '
                             f'{level.size} x {level.size} room')
        color, _, kind = state.target.partition(' ')
        if color not in COLOR_NAMES or kind not in KINDS:
            raise ValueError(f'target {state.target!r} is not "<colour> key|ball|box"')
        return state

    def expert_action(self, state: FetchState) -> Optional[int]:
        return next_action(state)

    def silent(self, state: FetchState, expert_action: Optional[int]) -> Optional[str]:
        """Return 'no_expert_action' where there is none (the episode's end, no way)."""
        return 'no_expert_action' if expert_action is None else None

    def as_good(self, state: FetchState, action: int, expert_action: int) -> bool:
        """Tell whether ``action`` leaves the way to the target as short as the expert's."""
        if action == expert_action:
            return True
        if action not in (LEFT, RIGHT, FORWARD) or not 0 <= action < NUM_ACTIONS:
            return False  # a pick-up of the wrong thing, or of nothing; drop, toggle: no use
        mine, theirs = moves_after(state, [action]), moves_after(state, [expert_action])
        return mine is not None and theirs is not None and mine <= theirs

    def sentence(self, state: FetchState) -> Optional[Tuple[int, str]]:
        """Return ``(the target's index, the mission)``; None once something is in hand."""
        if state.carrying:
            return None
        color, _, kind = state.target.partition(' ')
        return SENTENCE_OF[state.target], mission(color, kind)


KNOWLEDGE = FetchKnowledge()

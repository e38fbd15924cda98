"""
What Room 1's teacher knows: the expert's action, which actions do the same, what to say.

feedback_node's one teacher (``task_teacher.TaskTeacher``) asks a task's ``KNOWLEDGE`` about each
step, as a person who knows the route would: for the step T the agent acted on, the expert
(``expert.RoomOneExpert``) says what it would do from T's state (position, key, the skull it can
see, the agent's previous action), and the agent's action counts as good when it does the same
there (``action_effects``, measured with the emulator). Where every action does the same (in
the air, dying, respawning) the teacher says nothing; after the key the lesson is over.

It speaks the Figure 5.1 sentence of the stage of the route the agent is in (the expert knows
the stage); in the air the stage is the one the jump began in. Unlike DoorKey, a new episode is
the same room: the interval of utterances goes on.

The expert remembers the route so far, so every teacher gets a knowledge of its own
(``fresh``). Pure (no rclpy, no feedback_node).
"""

from dataclasses import dataclass
from typing import Dict, Mapping, Optional, Tuple

from attention_common.joy_actions import NUM_ACTIONS
from attention_tasks.montezuma.action_effects import EffectTable, place_of, Situation
from attention_tasks.montezuma.critical_positions import critical_position_at
from attention_tasks.montezuma.expert import FIRE_ACTIONS, Phase, RoomOneExpert
from attention_tasks.montezuma.sentences import position_problem, SENTENCES

STAGE_SENTENCE: Dict[Phase, int] = {
    Phase.TO_MIDDLE_LADDER: 0,    # the route's first sentence: down to the rope
    Phase.DOWN_MIDDLE_LADDER: 0,
    Phase.TO_ROPE: 0,
    Phase.ON_ROPE: 1,
    Phase.TO_RIGHT_LADDER: 2,
    Phase.DOWN_RIGHT_LADDER: 2,
    Phase.ACROSS_FLOOR: 3,
    Phase.UP_LEFT_LADDER: 4,
    Phase.TO_KEY: 5,
}
"""Which Figure 5.1 sentence (by critical position) names what matters in each stage."""


@dataclass
class SeenStep:
    """One step as ``env_status`` reports it, and what the expert made of it."""

    x: int
    y: int
    has_key: bool
    pose: int
    """The agent's sprite (``attention_tasks.montezuma.env.RAM_POSE``)."""
    skull_x: int
    action: int
    """The action the env applied to reach this step; -1 after a reset."""
    phase: Optional[Phase] = None
    """The stage of the route, once the expert has seen the step (``expert_action``)."""
    situation: Optional[Situation] = None
    """What a person sees of the state (``action_effects``), likewise."""


class RoomOneKnowledge:
    """The teacher's knowledge of Room 1 (``task_teacher.TeacherKnowledge``)."""

    SILENT = ('cannot_matter', 'after_key')
    SPEAKS_AT_NEW_EPISODE = False

    def __init__(self, table: Optional[EffectTable] = None):
        self.table = table
        self.expert = RoomOneExpert()
        self._stage: Optional[Phase] = None

    def fresh(self) -> 'RoomOneKnowledge':
        """Return a knowledge with an expert of its own (one per teacher), the same table."""
        if self.table is None:
            self.table = EffectTable.load()
        return RoomOneKnowledge(self.table)

    def reset(self) -> None:
        """Forget the trial: the route so far and the stage last named."""
        self.expert.reset()
        self._stage = None

    def new_episode(self) -> None:
        self.expert.reset()

    def observe(self, values: Mapping[str, object]) -> SeenStep:
        """Read a step's env_status values; KeyError, ValueError when they are bad."""
        seen = SeenStep(x=values['x'], y=values['y'], has_key=values['has_key'],
                        pose=values['pose'], skull_x=values['skull_x'], action=values['action'])
        problem = position_problem(seen.x, seen.y)
        if problem is not None:
            raise ValueError(problem)
        return seen

    def expert_action(self, state: SeenStep) -> int:
        """Return the expert's action from ``state``; its stage and situation go on the state."""
        previous = state.action if 0 <= state.action < NUM_ACTIONS else None
        expert_action = self.expert.act(state, state.skull_x, previous_action=previous)
        state.phase = self.expert.phase
        state.situation = Situation(state.phase.name, place_of(state.x, state.y), state.pose,
                                    state.action in FIRE_ACTIONS)
        return expert_action

    def silent(self, state: SeenStep, expert_action: Optional[int]) -> Optional[str]:
        """Return why the action taken in ``state`` is not judged (``SILENT``), or None."""
        if state.phase is Phase.DONE:
            return 'after_key'
        if self.table.cannot_matter(state.situation):
            return 'cannot_matter'
        return None

    def as_good(self, state: SeenStep, action: int, expert_action: int) -> bool:
        """Tell whether ``action`` does in ``state`` what the expert's does."""
        return self.table.equivalent(state.situation, action, expert_action)

    def sentence(self, state: SeenStep) -> Optional[Tuple[int, str]]:
        """Return the stage's ``(sentence_of, text)``: the stage a jump began in while in it."""
        if state.phase in STAGE_SENTENCE:
            self._stage = state.phase
        if self._stage is None or state.phase is Phase.DONE:
            return None
        sentence_of = STAGE_SENTENCE[self._stage]
        return sentence_of, SENTENCES[sentence_of]

    def position(self, state: SeenStep) -> int:
        """Return the critical position the agent stands on (-1: none), for the utterance."""
        return critical_position_at(state.x, state.y)


KNOWLEDGE = RoomOneKnowledge()
"""Room 1's knowledge; a teacher takes ``KNOWLEDGE.fresh()`` (the table loaded once)."""

"""
The teacher: a synthetic trainer that judges the agent's *actions*, as TAMER models a person.

A person who knows the route watches the agent and says "good" when it does what they would do
and "bad" when it does something else. Here the person's knowledge is the scripted expert
(``expert.RoomOneExpert``): for the step T the agent acted on, the teacher asks the expert what
it would do from T's state (position, key, the skull it can see, the agent's previous action)
and compares with the action the env applied for T (``env_status`` of the next step T' carries
it). Actions that do the same there count as the same (``action_effects``, measured with the
emulator); where every action does the same (in the air, dying, respawning) the teacher says
nothing. After the key the lesson is over: nothing is judged.

- h = +1: the agent's action does what the expert's would; -1: it does something else.
- Attribution as the thesis's trainer: the judgement of T is made when T' is seen, stamped T.
  What is judged and when (re-sends, restarts, resets, missed steps, the human-like knobs) is
  the frame every task's teacher shares (``judging.ActionTeacher``).
- It speaks the Figure 5.1 sentence of the stage of the route the agent is in (the expert knows
  the stage), every ``utterance_interval`` seconds of simulation time. In the air the stage is
  the one the jump began in.

Pure and deterministic (no rclpy): ``on_step`` takes one step as the env reported it.
"""

from typing import Dict, Mapping, NamedTuple, Optional

from attention_common.joy_actions import NUM_ACTIONS
from attention_tasks.montezuma.critical_positions import critical_position_at
from attention_tasks.montezuma.expert import FIRE_ACTIONS, Phase, RoomOneExpert
from feedback_node.action_effects import EffectTable, place_of, Situation
from feedback_node.human_input import position_problem
from feedback_node.judging import ActionTeacher, TeacherConfig
from feedback_node.utterances import SENTENCES, Utterance

TRAINERS = ('teacher', 'thesis')
"""feedback_node ``trainer``: this teacher, or the thesis's trainer (``trainer.py``)."""

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


class SeenStep(NamedTuple):
    """One step as ``env_status`` reports it: what the teacher sees."""

    stamp_ns: int
    x: int
    y: int
    has_key: bool
    pose: int
    """The agent's sprite (``attention_tasks.montezuma.env.RAM_POSE``)."""
    skull_x: int
    action: int
    """The action the env applied to reach this step; -1 after a reset."""
    episode: int
    agent_step: int = -1
    """``env_status`` ``agent_step`` (-1: unknown); a step missed in between is not judged."""


class _Decided(NamedTuple):
    """What the teacher thought of step T when it saw it."""

    phase: Phase
    situation: Situation
    expert_action: int


class Teacher(ActionTeacher):
    """Judges each action the agent took against the expert's; speaks the stage's sentence."""

    SILENT = ('cannot_matter', 'after_key')

    def __init__(self, config: Optional[TeacherConfig] = None,
                 table: Optional[EffectTable] = None):
        self.table = table if table is not None else EffectTable.load()
        self.expert = RoomOneExpert()
        super().__init__(config)

    def reset(self) -> None:
        """Forget the trial so far (pending delayed feedback too)."""
        super().reset()
        self.expert.reset()
        self._stage: Optional[Phase] = None

    def see(self, stamp_ns: int, values: Mapping[str, object]) -> SeenStep:
        """Read step ``values`` (parsed env_status); KeyError, ValueError when they are bad."""
        seen = SeenStep(stamp_ns=stamp_ns, x=values['x'], y=values['y'],
                        has_key=values['has_key'], pose=values['pose'],
                        skull_x=values['skull_x'], action=values['action'],
                        episode=values['episode'], agent_step=values['agent_step'])
        problem = position_problem(seen.x, seen.y)
        if problem is not None:
            raise ValueError(problem)
        return seen

    def _decide(self, seen: SeenStep, new_episode: bool) -> _Decided:
        if new_episode:
            self.expert.reset()
        previous = seen.action if 0 <= seen.action < NUM_ACTIONS else None
        expert_action = self.expert.act(seen, seen.skull_x, previous_action=previous)
        phase = self.expert.phase
        situation = Situation(phase.name, place_of(seen.x, seen.y), seen.pose,
                              seen.action in FIRE_ACTIONS)
        return _Decided(phase, situation, expert_action)

    def _judge(self, last: SeenStep, decided: _Decided, seen: SeenStep) -> None:
        if decided.phase is Phase.DONE:
            self._counts['after_key'] += 1
            return
        if self.table.cannot_matter(decided.situation):
            self._counts['cannot_matter'] += 1
            return
        same = self.table.equivalent(decided.situation, seen.action, decided.expert_action)
        self._give(last, seen, decided.expert_action, same)

    def _speak(self, seen: SeenStep, decided: _Decided) -> Optional[Utterance]:
        phase = decided.phase
        if phase in STAGE_SENTENCE:
            self._stage = phase
        if self._stage is None or phase is Phase.DONE or not self.schedule.due(seen.stamp_ns):
            return None
        self.schedule.spoken(seen.stamp_ns)
        sentence_of = STAGE_SENTENCE[self._stage]
        return Utterance(text=SENTENCES[sentence_of],
                         position=critical_position_at(seen.x, seen.y),
                         sentence_of=sentence_of, stamp_ns=seen.stamp_ns)

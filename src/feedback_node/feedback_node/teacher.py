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
- The human-like knobs (``human_like.HumanLike``) apply: probability, delay, noise.
- It speaks the Figure 5.1 sentence of the stage of the route the agent is in (the expert knows
  the stage), every ``utterance_interval`` seconds of simulation time. In the air the stage is
  the one the jump began in.

Pure and deterministic (no rclpy): ``on_step`` takes one step as the env reported it.
"""

from dataclasses import dataclass
from typing import Dict, List, NamedTuple, Optional

from attention_common.joy_actions import NUM_ACTIONS
from attention_tasks.montezuma.critical_positions import critical_position_at
from attention_tasks.montezuma.expert import FIRE_ACTIONS, Phase, RoomOneExpert
from feedback_node.action_effects import EffectTable, place_of, Situation
from feedback_node.human_like import FeedbackScheduler, HumanLike
from feedback_node.utterances import IntervalSchedule, SENTENCES, Utterance

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


@dataclass
class TeacherConfig(HumanLike):
    """Parameters of the teacher; the feedback node's ROS parameters carry the same names."""

    utterance_interval: float = 10.0
    """Seconds of simulation time between utterances; 0 = every step; negative = no
    utterances."""
    seed: int = 0
    """Seeds the human-like draws (probability, delay, noise)."""


class SeenStep(NamedTuple):
    """One step as ``env_status`` reports it: what the teacher sees."""

    stamp_ns: int
    x: int
    y: int
    has_key: bool
    pose: int
    """The agent's sprite (``env_node.core.RAM_POSE``)."""
    skull_x: int
    action: int
    """The action the env applied to reach this step; -1 after a reset."""
    episode: int
    agent_step: int = -1
    """``env_status`` ``agent_step`` (-1: unknown); a step missed in between is not judged."""


class Judgement(NamedTuple):
    """The teacher's feedback on the action taken at ``stamp_ns``."""

    stamp_ns: int
    h: float
    expert_action: int
    action: int
    seen_ns: int
    """The step at which the action was seen done (the next step)."""
    flipped: bool = False


class TeacherOutput(NamedTuple):
    feedback: List[Judgement]
    """Feedback due now, oldest judged step first (more than one only with a delay)."""
    utterance: Optional[Utterance]


class _Decided(NamedTuple):
    """What the teacher thought of step T when it saw it."""

    stamp_ns: int
    episode: int
    agent_step: int
    phase: Phase
    situation: Situation
    expert_action: int


class Teacher:
    """Judges each action the agent took against the expert's; speaks the stage's sentence."""

    def __init__(self, config: Optional[TeacherConfig] = None,
                 table: Optional[EffectTable] = None):
        self.config = config or TeacherConfig()
        self.table = table if table is not None else EffectTable.load()
        self.expert = RoomOneExpert()
        self.scheduler = FeedbackScheduler(self.config, self.config.seed)
        self.schedule = IntervalSchedule(self.config.utterance_interval)
        self._counts = {'steps': 0, 'judged': 0, 'agreed': 0, 'cannot_matter': 0,
                        'after_key': 0, 'unjudged_resets': 0, 'unjudged_gaps': 0,
                        'duplicates': 0, 'restarts': 0}
        self.reset()

    @property
    def counts(self) -> dict:
        return dict(self._counts, **self.scheduler.counts)

    @property
    def pending(self) -> int:
        return self.scheduler.pending

    def reset(self) -> None:
        """Forget the trial so far (pending delayed feedback too)."""
        self.expert.reset()
        self.scheduler.clear()
        self.schedule.reset()
        self._last: Optional[_Decided] = None
        self._stage: Optional[Phase] = None

    def on_step(self, seen: SeenStep) -> TeacherOutput:
        """Take step T' as the env reported it; return what to publish now."""
        last = self._last
        if last is not None and seen.stamp_ns == last.stamp_ns:
            self._counts['duplicates'] += 1
            return TeacherOutput(self.scheduler.release(seen.stamp_ns), None)
        if last is not None and seen.stamp_ns < last.stamp_ns:
            self._counts['restarts'] += 1
            self.reset()
            last = None
        self._counts['steps'] += 1
        new_episode = last is None or seen.episode != last.episode or seen.action < 0
        if last is not None:
            if new_episode:
                self._counts['unjudged_resets'] += 1
            elif min(seen.agent_step, last.agent_step) >= 0 and (
                    seen.agent_step != last.agent_step + 1):
                # A step's status was missed: the action seen is not the one taken at T.
                self._counts['unjudged_gaps'] += 1
            else:
                self._judge(last, seen)
        if new_episode:
            self.expert.reset()
        previous = seen.action if 0 <= seen.action < NUM_ACTIONS else None
        expert_action = self.expert.act(seen, seen.skull_x, previous_action=previous)
        phase = self.expert.phase
        situation = Situation(phase.name, place_of(seen.x, seen.y), seen.pose,
                              seen.action in FIRE_ACTIONS)
        self._last = _Decided(seen.stamp_ns, seen.episode, seen.agent_step, phase, situation,
                              expert_action)
        return TeacherOutput(self.scheduler.release(seen.stamp_ns), self._speak(seen, phase))

    def _judge(self, last: _Decided, seen: SeenStep) -> None:
        if last.phase is Phase.DONE:
            self._counts['after_key'] += 1
            return
        if self.table.cannot_matter(last.situation):
            self._counts['cannot_matter'] += 1
            return
        self._counts['judged'] += 1
        same = self.table.equivalent(last.situation, seen.action, last.expert_action)
        self._counts['agreed'] += int(same)
        self.scheduler.consider(Judgement(
            stamp_ns=last.stamp_ns, h=1.0 if same else -1.0, expert_action=last.expert_action,
            action=seen.action, seen_ns=seen.stamp_ns))

    def _speak(self, seen: SeenStep, phase: Phase) -> Optional[Utterance]:
        if phase in STAGE_SENTENCE:
            self._stage = phase
        if self._stage is None or phase is Phase.DONE or not self.schedule.due(seen.stamp_ns):
            return None
        self.schedule.spoken(seen.stamp_ns)
        sentence_of = STAGE_SENTENCE[self._stage]
        return Utterance(text=SENTENCES[sentence_of],
                         position=critical_position_at(seen.x, seen.y),
                         sentence_of=sentence_of, stamp_ns=seen.stamp_ns)

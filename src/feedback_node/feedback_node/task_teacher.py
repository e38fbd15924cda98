"""
The teacher of any task but Room 1: the shared frame, with the task's knowledge plugged in.

A task teaches by one module, ``attention_tasks.<task>.teaching``, whose ``KNOWLEDGE`` answers
the four questions of ``TeacherKnowledge`` from a step's ``env_status`` values; this teacher
asks them (no task name, no game keys here). For step T it keeps the expert's action; when T'
(the next agent step, same episode) shows the action taken, it gives +1 if that action is as
good as the expert's and -1 otherwise, stamped T; nothing where the expert has no action (at
the goal, no way). Re-sends, restarts, resets, missed steps and the human-like knobs are
``judging.ActionTeacher``'s, as for Room 1.

Every ``utterance_interval`` seconds of simulation time it says the knowledge's sentence
(``position`` -1, ``sentence_of`` its index). A new episode is a new layout: its first step
speaks at once; where the knowledge has nothing to say (after the goal) it is silent.
"""

import importlib
from typing import Any, Hashable, Mapping, NamedTuple, Optional, Protocol, Tuple

from attention_tasks.task import NO_ACTION
from feedback_node.judging import ActionTeacher, TeacherConfig
from feedback_node.utterances import Utterance

NO_POSITION = -1
"""``Utterance.position`` of every task but Room 1 (critical positions are Room 1's)."""


class TeacherKnowledge(Protocol):
    """What a task's teacher knows, asked of each step (``attention_tasks.<task>.teaching``)."""

    def observe(self, values: Mapping[str, object]) -> Hashable:
        """Return the task's state of a step's parsed env_status; KeyError, ValueError: bad."""

    def expert_action(self, state: Any) -> Optional[int]:
        """Return the expert's task action in ``state``; None: nothing to judge there."""

    def as_good(self, state: Any, action: int, expert_action: int) -> bool:
        """Tell whether ``action`` taken in ``state`` is as good as ``expert_action``."""

    def sentence(self, state: Any) -> Optional[Tuple[int, str]]:
        """Return ``(sentence_of, text)`` to say in ``state``; None: nothing to say."""


class UnknownTeacher(ValueError):
    """The task has no teaching module."""


def load_knowledge(task: str) -> TeacherKnowledge:
    """Return ``KNOWLEDGE`` of ``attention_tasks.<task>.teaching``; UnknownTeacher if none."""
    name = f'attention_tasks.{task}.teaching'
    try:
        return importlib.import_module(name).KNOWLEDGE
    except ModuleNotFoundError as error:
        if error.name not in (name, f'attention_tasks.{task}'):
            raise
    except AttributeError:
        pass
    raise UnknownTeacher(f'task {task!r} has no teacher: {name} with a KNOWLEDGE is missing')


class TaskStep(NamedTuple):
    """One step as the teacher sees it: the frame's fields and the task's state."""

    stamp_ns: int
    action: int
    """The task action applied to reach this step; -1 after a reset."""
    episode: int
    agent_step: int
    state: Any
    """``TeacherKnowledge.observe`` of the step's values."""


class TaskTeacher(ActionTeacher):
    """Judges each action by the task's knowledge; says the task's sentences."""

    SILENT = ('no_expert_action',)

    def __init__(self, knowledge: TeacherKnowledge, num_actions: int,
                 config: Optional[TeacherConfig] = None):
        self.knowledge = knowledge
        self.num_actions = num_actions
        super().__init__(config)

    def see(self, stamp_ns: int, values: Mapping[str, object]) -> TaskStep:
        """Read step ``values`` (parsed env_status); KeyError, ValueError when they are bad."""
        action = int(values['action'])
        if not NO_ACTION <= action < self.num_actions:
            raise ValueError(f'action {action} is not in {NO_ACTION}..{self.num_actions - 1}')
        return TaskStep(stamp_ns, action, int(values['episode']), int(values['agent_step']),
                        self.knowledge.observe(values))

    def _decide(self, seen: TaskStep, new_episode: bool) -> Optional[int]:
        if new_episode:
            self.schedule.reset()  # a new layout: name its objects at once
        return self.knowledge.expert_action(seen.state)

    def _judge(self, last: TaskStep, expert_action: Optional[int], seen: TaskStep) -> None:
        if expert_action is None:
            self._counts['no_expert_action'] += 1
            return
        same = self.knowledge.as_good(last.state, seen.action, expert_action)
        self._give(last, seen, expert_action, same)

    def _speak(self, seen: TaskStep, expert_action: Optional[int]) -> Optional[Utterance]:
        said = self.knowledge.sentence(seen.state)
        if said is None or not self.schedule.due(seen.stamp_ns):
            return None
        self.schedule.spoken(seen.stamp_ns)
        sentence_of, text = said
        return Utterance(text=text, position=NO_POSITION, sentence_of=sentence_of,
                         stamp_ns=seen.stamp_ns)

"""
The teacher of every task: the shared frame, with the task's knowledge plugged in.

A task teaches by one module, ``attention_tasks.<task>.teaching``, whose ``KNOWLEDGE`` answers
the questions of ``TeacherKnowledge`` from a step's ``env_status`` values; this teacher asks
them (no task name, no game keys here), so a new task needs no edit of this node. For step T it
keeps the expert's action; when T' (the next agent step, same episode) shows the action taken,
it gives +1 if that action is as good as the expert's and -1 otherwise, stamped T; nothing
where the knowledge says it is silent (no expert action: at the goal, no way; in Room 1 also
an action that cannot matter, or after the key). Re-sends, restarts, resets, missed steps and
the human-like knobs are ``judging.ActionTeacher``'s.

Every ``utterance_interval`` seconds of simulation time it says the knowledge's sentence (its
``position``, -1 where the task has none, and ``sentence_of`` its index); where the knowledge
has nothing to say it is silent. A task whose new episode is a new layout
(``SPEAKS_AT_NEW_EPISODE``) speaks at its first step at once.
"""

import importlib
from typing import Any, Mapping, NamedTuple, Optional, Protocol, Tuple

from attention_tasks.task import NO_ACTION
from feedback_node.judging import ActionTeacher, TeacherConfig
from feedback_node.utterances import Utterance

NO_POSITION = -1
"""``Utterance.position`` of every task but Room 1 (critical positions are Room 1's)."""


class TeacherKnowledge(Protocol):
    """
    What a task's teacher knows, asked of each step (``attention_tasks.<task>.teaching``).

    Besides the methods below a knowledge has ``SILENT`` (the reasons ``silent`` gives, counted)
    and ``SPEAKS_AT_NEW_EPISODE``; it may have ``fresh()`` (a knowledge with state of its own
    for one teacher), ``reset()`` (a new trial), ``new_episode()`` and ``position(state)``
    (the utterance's ``position``; -1 without it).
    """

    def observe(self, values: Mapping[str, object]) -> Any:
        """Return the task's state of a step's parsed env_status; KeyError, ValueError: bad."""

    def expert_action(self, state: Any) -> Optional[int]:
        """Return the expert's task action in ``state``; None: nothing to judge there."""

    def silent(self, state: Any, expert_action: Optional[int]) -> Optional[str]:
        """Return why the action taken in ``state`` is not judged (one of ``SILENT``), or None."""

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

    def __init__(self, knowledge: TeacherKnowledge, num_actions: int,
                 config: Optional[TeacherConfig] = None):
        self.knowledge = knowledge.fresh() if hasattr(knowledge, 'fresh') else knowledge
        self.num_actions = num_actions
        self.SILENT = tuple(knowledge.SILENT)
        super().__init__(config)

    def reset(self) -> None:
        """Forget the trial so far (pending delayed feedback and the knowledge's too)."""
        super().reset()
        if hasattr(self.knowledge, 'reset'):
            self.knowledge.reset()

    def see(self, stamp_ns: int, values: Mapping[str, object]) -> TaskStep:
        """Read step ``values`` (parsed env_status); KeyError, ValueError when they are bad."""
        action = int(values['action'])
        if not NO_ACTION <= action < self.num_actions:
            raise ValueError(f'action {action} is not in {NO_ACTION}..{self.num_actions - 1}')
        return TaskStep(stamp_ns, action, int(values['episode']), int(values['agent_step']),
                        self.knowledge.observe(values))

    def _decide(self, seen: TaskStep, new_episode: bool) -> Optional[int]:
        if new_episode:
            if hasattr(self.knowledge, 'new_episode'):
                self.knowledge.new_episode()
            if self.knowledge.SPEAKS_AT_NEW_EPISODE:
                self.schedule.reset()  # a new layout: name its objects at once
        return self.knowledge.expert_action(seen.state)

    def _judge(self, last: TaskStep, expert_action: Optional[int], seen: TaskStep) -> None:
        reason = self.knowledge.silent(last.state, expert_action)
        if reason is not None:
            self._counts[reason] += 1
            return
        same = self.knowledge.as_good(last.state, seen.action, expert_action)
        self._give(last, seen, expert_action, same)

    def _speak(self, seen: TaskStep, expert_action: Optional[int]) -> Optional[Utterance]:
        said = self.knowledge.sentence(seen.state)
        if said is None or not self.schedule.due(seen.stamp_ns):
            return None
        self.schedule.spoken(seen.stamp_ns)
        sentence_of, text = said
        position = getattr(self.knowledge, 'position', lambda state: NO_POSITION)(seen.state)
        return Utterance(text=text, position=position, sentence_of=sentence_of,
                         stamp_ns=seen.stamp_ns)

"""
What every teacher that judges actions shares: which steps are judged, and how feedback goes out.

A teacher sees one step T' at a time (from ``env_status``) and judges the action taken at the
step T before it, which T' reports (``action``); the judgement is stamped T. The frame is the
same in every task, so it lives here once (``ActionTeacher``):

- a step seen again (the same stamp, a re-send) is not judged twice; stamps that go back (a new
  trial) start the teacher over;
- nothing caused a jump to a new episode (or a step with ``action`` -1), and a step whose status
  was missed leaves the action of T unknown: neither is judged;
- judgements pass the human-like knobs (``human_like.FeedbackScheduler``); utterances come on
  an interval of simulation time (``utterances.IntervalSchedule``).

What a teacher thinks of a step, whether and how it judges, and what it says are its own
(``_decide``, ``_judge``, ``_speak``): ``task_teacher.TaskTeacher`` asks the task's knowledge.
Pure (no rclpy).
"""

import collections
from dataclasses import dataclass
from typing import Any, List, NamedTuple, Optional, Tuple

from feedback_node.human_like import FeedbackScheduler, HumanLike
from feedback_node.utterances import IntervalSchedule, Utterance
import numpy as np


QUESTIONS_HELD = 1000
"""Questions waiting for their step to be judged, and judged steps a question may still ask
about, at most each (the oldest forgotten first)."""
ANSWER_STREAM = 7
"""Seeds the answers' wrong signs apart from the human-like draws."""

TRAINERS = ('teacher', 'thesis')
"""feedback_node ``trainer``: the teacher (``task_teacher``), or the thesis's (``trainer.py``)."""


@dataclass
class TeacherConfig(HumanLike):
    """Parameters of the teacher; the feedback node's ROS parameters carry the same names."""

    utterance_interval: float = 10.0
    """Seconds of simulation time between utterances; 0 = every step; negative = no
    utterances."""
    seed: int = 0
    """Seeds the human-like draws (probability, delay, noise)."""


class Judgement(NamedTuple):
    """The teacher's feedback on the action taken at ``stamp_ns``."""

    stamp_ns: int
    h: float
    expert_action: int
    action: int
    seen_ns: int
    """The step at which the action was seen done (the next step)."""
    flipped: bool = False
    pressed_ns: int = 0
    """When it is given (simulation ns): ``seen_ns`` plus the human-like delay."""
    marked: bool = False
    """Given with the step it judges (``feedback_marked``): published stamped, not plain."""


class TeacherOutput(NamedTuple):
    feedback: List[Judgement]
    """Feedback due now, oldest judged step first (more than one only with a delay)."""
    utterance: Optional[Utterance]


class ActionTeacher:
    """
    The shared frame; a subclass says what it thinks of a step and what it says.

    A seen step has ``stamp_ns``, ``action`` (applied to reach it; -1 after a reset),
    ``episode`` and ``agent_step`` (-1: unknown).
    """

    SILENT: Tuple[str, ...] = ()
    """Counts of the steps the subclass does not judge, by reason."""

    def __init__(self, config: Optional[TeacherConfig] = None):
        self.config = config or TeacherConfig()
        self.scheduler = FeedbackScheduler(self.config, self.config.seed)
        self.schedule = IntervalSchedule(self.config.utterance_interval)
        self._counts = dict.fromkeys(('steps', 'judged', 'agreed') + self.SILENT + (
            'unjudged_resets', 'unjudged_gaps', 'duplicates', 'restarts', 'questions',
            'answered'), 0)
        self._answer_rng = np.random.default_rng([self.config.seed, ANSWER_STREAM])
        self.reset()

    @property
    def counts(self) -> dict:
        return dict(self._counts, **self.scheduler.counts)

    @property
    def pending(self) -> int:
        return self.scheduler.pending

    def reset(self) -> None:
        """Forget the trial so far (pending delayed feedback too)."""
        self.scheduler.clear()
        self.schedule.reset()
        self._asked: 'collections.OrderedDict[int, None]' = collections.OrderedDict()
        self._judged: 'collections.OrderedDict[int, Judgement]' = collections.OrderedDict()
        self._answers: List[Judgement] = []
        self._last = None  # the step T seen before, and what the teacher decided of it
        self._decided: Any = None

    def on_step(self, seen) -> TeacherOutput:
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
                self._judge(last, self._decided, seen)
        self._last = seen
        self._decided = self._decide(seen, new_episode)
        return TeacherOutput(self._take_answers() + self.scheduler.release(seen.stamp_ns),
                             self._speak(seen, self._decided))

    def ask(self, stamp_ns: int) -> List[Judgement]:
        """
        Answer the learner's question about the step of ``stamp_ns`` once it is judged.

        Return the answer now if the step was judged already; else it comes with the output of
        the step that judges it. A step the teacher is silent on gets no answer. The answer is
        the teacher's verdict on that step, given with it (``marked``: published stamped), with
        the human-like share of wrong signs but neither a delay nor a skip: a person asked about
        a paused frame answers about that frame. A step asked about before it is judged is not
        also judged late.
        """
        self._counts['questions'] += 1
        judged = self._judged.pop(stamp_ns, None)
        if judged is not None:
            return [self._answer(judged)]
        _hold(self._asked, stamp_ns, None)
        return []

    def _answer(self, judgement: Judgement) -> Judgement:
        self._counts['answered'] += 1
        noise = self.config.feedback_noise
        if noise > 0.0 and judgement.h != 0.0 and self._answer_rng.random() < noise:
            judgement = judgement._replace(h=-judgement.h, flipped=True)
        return judgement._replace(pressed_ns=judgement.seen_ns, marked=True)

    def _take_answers(self) -> List[Judgement]:
        answers, self._answers = self._answers, []
        return answers

    def _give(self, last, seen, expert_action: int, same: bool) -> None:
        """Judge the action of ``last`` (seen done at ``seen``): +1 as good as the expert's."""
        self._counts['judged'] += 1
        self._counts['agreed'] += int(same)
        judgement = Judgement(stamp_ns=last.stamp_ns, h=1.0 if same else -1.0,
                              expert_action=expert_action, action=seen.action,
                              seen_ns=seen.stamp_ns)
        if last.stamp_ns in self._asked:  # asked about: answered now, not judged late
            del self._asked[last.stamp_ns]
            self._answers.append(self._answer(judgement))
            return
        self.scheduler.consider(judgement)
        _hold(self._judged, last.stamp_ns, judgement)

    def _decide(self, seen, new_episode: bool) -> Any:
        """Return what the teacher thinks of step ``seen`` (kept until the next step)."""
        raise NotImplementedError

    def _judge(self, last, decided: Any, seen) -> None:
        """Judge the action taken at ``last`` (``_give``), or count why not (``SILENT``)."""
        raise NotImplementedError

    def _speak(self, seen, decided: Any) -> Optional[Utterance]:
        """Return the utterance said at ``seen``, if one is due (``self.schedule``)."""
        raise NotImplementedError


def _hold(held: 'collections.OrderedDict', key, value) -> None:
    """Put ``key`` in ``held``, forgetting the oldest beyond ``QUESTIONS_HELD``."""
    held[key] = value
    while len(held) > QUESTIONS_HELD:
        held.popitem(last=False)

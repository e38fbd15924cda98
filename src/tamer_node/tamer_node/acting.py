"""
The acting path: the greedy action for each step at once, on the actor's own copy of H.

Owned by the acting thread (the ``observation``/``saliency`` callbacks, or a benchmark loop):
it preprocesses the image, stores the step in the ``StepHistory``, picks the greedy action with
its *own* copy of H (``ActingModel``, in eval mode for its whole life), queues journal records.
With a frozen encoder it stores the image's features in the step's record (the learner trains on
them). It takes only short locks (history, snapshot slot, the steps awaiting their saliency
image) and never waits for training, sampling or disk I/O. The learner hands it weights through
the ``SnapshotSlot``: the acting copy loads a newer version just before it acts.
"""

import collections
import copy
import threading
import time
from typing import Callable, Dict, List, Optional, Tuple

from attention_common.feedback import FEEDBACK_RANGE
from attention_common.stamps import NS_PER_S, StampGuard
from attention_tasks.task import load_task
import numpy as np
from tamer_node.config import TamerConfig, WAITS_FOR_SALIENCY
from tamer_node.history import holds, StepHistory
from tamer_node.memory import state_key, VerdictMemory
from tamer_node.model import HModel, preprocess, to_input
from tamer_node.pairing import both_item
from tamer_node.persistence import (
    KIND_ACTION, KIND_OBSERVATION, KIND_SALIENCY, KIND_TAKEN, StepJournal)
from tamer_node.questions import Asker
from tamer_node.revisits import Revisits
from tamer_node.words import bag_of_words
import torch

EXPLORE_STREAM = 0x5EED
"""The exploring draws' own random stream (beside the seed): ties draw from another."""


class BadInput(ValueError):
    """A message the agent cannot use; it was counted and dropped."""


class SnapshotSlot:
    """The newest weight snapshot and its version; the learner writes, the actor reads."""

    def __init__(self):
        self._lock = threading.Lock()
        self._version = 0
        self._state: Optional[Dict[str, torch.Tensor]] = None

    def publish(self, version: int, state: Dict[str, torch.Tensor]) -> None:
        with self._lock:
            self._version, self._state = version, state

    def newer_than(self, version: int):
        """(version, state) if a newer snapshot exists, else None."""
        with self._lock:
            if self._state is None or self._version <= version:
                return None
            return self._version, self._state


def clearly_better(values: torch.Tensor, held: int, margin: float) -> bool:
    """
    Tell whether another action's H beats the held one's by more than ``margin`` (> 0).

    H is read within the feedback range, as the greedy policy reads it.
    """
    if margin <= 0.0:
        return False
    clipped = values.clamp(-FEEDBACK_RANGE, FEEDBACK_RANGE)
    return bool(clipped.max() - clipped[held] > margin)


class ActingModel:
    """
    The actor's own copy of H: eval mode forever, refreshed from snapshots.

    ``greedy_margin`` 0 is the thesis's policy: argmax_a H(s, a), ties to the lowest index.
    Above 0, H is first clipped to the feedback range [-1, 1] and every action within the
    margin of the best counts as tied; a tie is broken at random (seeded). Without it an
    action the trainer never judged in a state, but punished in many others (UP, wrong almost
    everywhere on the floor), is extrapolated below -1 there and never tried, while every
    action tried sits at -1: an agent stood 3,000 steps at the foot of the left ladder trying
    every action but UP (graph trial, seed 1006).
    """

    def __init__(self, model: HModel, greedy_margin: float = 0.0, seed: int = 0,
                 keep_tied: bool = False):
        self.model = copy.deepcopy(model).eval()
        self.model.requires_grad_(False)
        self.version = 0
        self.greedy_margin = float(greedy_margin)
        self.keep_tied = keep_tied
        """A tie that includes the previous action keeps it (with ``greedy_margin`` > 0)."""
        self.previous: Optional[int] = None
        self._rng = np.random.default_rng(seed)

    def refresh(self, slot: SnapshotSlot) -> None:
        newer = slot.newer_than(self.version)
        if newer is not None:
            self.version, state = newer
            # A frozen encoder's snapshot is the head only (Learner.snapshot).
            unexpected = self.model.load_state_dict(state, strict=False).unexpected_keys
            if unexpected:
                raise KeyError(f'a weight snapshot with unknown tensors: {unexpected}')

    def predict(self, image: torch.Tensor) -> torch.Tensor:
        with torch.inference_mode():
            return self.model(to_input(image))[0]

    def choose(self, h: torch.Tensor, penalty: Optional[torch.Tensor] = None) -> int:
        """
        Return the greedy action for one state's (18,) H values (see the class docstring).

        ``penalty``: amounts to lower each action by after clipping (revisits.py).
        """
        if self.greedy_margin <= 0.0:
            return int(torch.argmax(h if penalty is None else h - penalty))
        clipped = h.clamp(-FEEDBACK_RANGE, FEEDBACK_RANGE)  # beyond: extrapolation
        if penalty is not None:
            clipped = clipped - penalty
        tied = torch.nonzero(clipped >= clipped.max() - self.greedy_margin).flatten()
        if self.keep_tied and self.previous is not None and bool((tied == self.previous).any()):
            return self.previous
        self.previous = int(tied[self._rng.integers(len(tied))])
        return self.previous

    def greedy(self, image: torch.Tensor) -> int:
        """argmax_a H(s, a): the greedy policy (``choose``)."""
        return self.choose(self.predict(image))

    def features(self, image: torch.Tensor) -> torch.Tensor:
        """Return the (1120,) encoder features of a (105, 80) uint8 image (no_grad)."""
        with torch.no_grad():
            return self.model.features(to_input(image))[0]

    def greedy_on_features(self, features: torch.Tensor) -> int:
        """``greedy`` from the image's features (``features``): the same action."""
        return self.choose(self.values_on_features(features))

    def values_on_features(self, features: torch.Tensor) -> torch.Tensor:
        """H(s, .) from the image's features: (actions,) float32."""
        with torch.no_grad():
            return self.model.from_features(features.unsqueeze(0))[0]


class ActingPath:
    """Observations and saliency images in, actions out; the newest stamp and the session."""

    def __init__(self, config: TamerConfig, actor: ActingModel, slot: SnapshotSlot,
                 history: StepHistory, journal: StepJournal, worker,
                 counters: collections.Counter, log: Callable[[str, str], None],
                 memory: Optional[VerdictMemory] = None):
        """``worker``: told of each observation stamp (``tick``) and image (``wake``)."""
        self.config = config
        self.memory = memory
        """Verdicts on exact states, blended into H before choosing (None: H alone)."""
        self.actor = actor
        self.slot = slot
        self.history = history
        self.journal = journal
        self.worker = worker
        self.counters = counters
        self._log = log
        self._guard = StampGuard(int(round(config.max_stamp_jump_s * NS_PER_S)))
        task = load_task(config.task)
        self._frame_shape = task.frame_shape
        self._num_actions = task.num_actions
        self.revisits = (Revisits(config.revisit_penalty, config.revisit_steps, task.num_actions)
                         if config.revisit_penalty > 0.0 else None)
        """Actions taken lately in each exact state, counted against them (None: off)."""
        self.asker = (Asker(config.ask_rate, config.ask_margin, config.ask_burst,
                            config.ask_budget)
                      if config.ask_rate > 0.0 else None)
        self.questions: 'collections.deque[Tuple[int, int, float]]' = collections.deque(
            maxlen=64)
        """(stamp, action, gap) of the steps asked about, oldest first; the node takes them
        after it has published the action (``take_questions``)."""
        # input_image 'saliency': observations waiting for their saliency image (stamp ->
        # monotonic arrival time); answered on the observation after saliency_timeout_s.
        self._awaiting: 'collections.OrderedDict[int, float]' = (
            collections.OrderedDict())
        self._awaiting_lock = threading.Lock()
        self.now: Optional[int] = None
        """The newest observation stamp (what a plain feedback is stamped with)."""
        self.act_seconds = collections.deque(maxlen=1000)
        """The last 1000 acts' latencies."""
        self.acted: 'collections.deque[Tuple[int, int, torch.Tensor]]' = collections.deque(
            maxlen=16)
        """(stamp, action, H of every action) of the newest acts, for a viewer; the node takes
        them after it has published the action (``action_values``), so they never delay it."""
        self.text: Optional[torch.Tensor] = None
        """The bag of words of the newest utterance (text_conditioning film; zeros before)."""
        if config.text_conditioning == 'film':
            self.text = torch.zeros(config.text_size)
        self._held: Optional[int] = None  # the decision being held (decision_period_s)
        self._decision: Optional[int] = None  # the stamp of the step that chose it
        self._explore_rng = np.random.default_rng([config.seed, EXPLORE_STREAM])

    @property
    def session(self) -> int:
        """Return the run's session number (persistence.py): 1, then one more per resume."""
        return self.history.session

    def start_session(self, session: int) -> None:
        self.history.start_session(session)
        self.journal.session = session
        with self._awaiting_lock:
            self._awaiting.clear()
        self.now = None
        self._held, self._decision = None, None
        if self.revisits is not None:
            self.revisits.clear()
        if self.asker is not None:
            self.asker.clear()
        self.questions.clear()

    def on_observation(self, stamp: int, rgb: np.ndarray) -> Optional[int]:
        """Store observation ``stamp``; return the greedy action if the agent acts on it."""
        started = time.perf_counter()
        image = self._preprocess('observation', rgb)
        verdict = self._guard.check(stamp)
        if verdict == 'implausible':
            self.counters['drop/observation_stamp'] += 1
            raise BadInput(f'observation dropped: its stamp {stamp / NS_PER_S:.3f}s is more '
                           f'than {self.config.max_stamp_jump_s:g} s from the newest '
                           f'({self._guard.newest / NS_PER_S:.3f}s)')
        if verdict == 'restart':
            self.counters['session/restarts'] += 1
            self.start_session(self.session + 1)
            self._log('warn', f'observation stamps started over at {stamp / NS_PER_S:.3f}s (a '
                      f'new env): session {self.session} begins; feedback on earlier steps is '
                      'kept in the log, not learned from')
        self.now = stamp if self.now is None else max(self.now, stamp)
        self.worker.tick(stamp)  # simulation time for the minibatch schedule
        record = self.history.put_image('observation', stamp, image)
        self.journal.append(KIND_OBSERVATION, stamp, image=image)
        if self.config.input_image in WAITS_FOR_SALIENCY:
            self.worker.wake()
            if record.action is None and record.saliency is None:
                with self._awaiting_lock:  # answered by on_saliency or act_overdue
                    self._awaiting.setdefault(stamp, time.monotonic())
                    while len(self._awaiting) > self.config.history_steps:
                        self._awaiting.popitem(last=False)
                return None
        return self._act(record, started)

    def on_saliency(self, stamp: int, rgb: np.ndarray) -> Optional[int]:
        """Store saliency image ``stamp``; return the action if the agent acts on saliency."""
        started = time.perf_counter()
        image = self._preprocess('saliency', rgb)
        if not self._guard.plausible(stamp):
            self.counters['drop/saliency_stamp'] += 1
            raise BadInput(f'saliency image dropped: its stamp {stamp / NS_PER_S:.3f}s is '
                           f'more than {self.config.max_stamp_jump_s:g} s from the newest '
                           'observation')
        record = self.history.put_image('saliency', stamp, image)
        self.journal.append(KIND_SALIENCY, stamp, image=image)
        self.worker.wake()
        if self.config.input_image not in WAITS_FOR_SALIENCY:
            return None
        with self._awaiting_lock:
            self._awaiting.pop(stamp, None)
        if record.action is not None:
            return None  # answered already (fallback); a re-sent observation is re-answered
        if record.observation is None:
            return None  # its observation was dropped: the env will re-send the step
        return self._act(record, started)

    def on_action_taken(self, stamp: int, action: int) -> None:
        """
        Record the action the world executed on step ``stamp`` (not chosen by this agent).

        Feedback on that step is then learned on this action: attention_replay tells a fresh
        learner what the agent of the recorded session did. Counted in ``act/taken`` and, when
        this agent had answered otherwise, ``act/taken_differs``.
        """
        if not 0 <= int(action) < self._num_actions:
            self.counters['drop/action_taken'] += 1
            raise BadInput(f'action_taken dropped: action {action} is not one of the '
                           f'{self._num_actions} actions of the task')
        answer = self.history.set_taken(stamp, action)
        self.journal.append(KIND_TAKEN, stamp, int(action))
        self.counters['act/taken'] += 1
        if answer is not None and answer != int(action):
            self.counters['act/taken_differs'] += 1

    def act_overdue(self, now: Optional[float] = None) -> List[Tuple[int, int]]:
        """
        Answer the observations whose saliency image is ``saliency_timeout_s`` (wall) late.

        ``input_image`` saliency or both: such a step is answered by acting on its observation
        (counted in ``act/fallback_observation``; with ``saliency`` the step is not learned from,
        as the learner learns on saliency images only; with ``both`` the observation stands in
        for its saliency image, in acting and in learning). Returns [(stamp, action)] to
        publish; the node calls it on a timer.
        """
        now = time.monotonic() if now is None else now
        due = []
        with self._awaiting_lock:
            while self._awaiting:
                stamp, arrived = next(iter(self._awaiting.items()))
                if now - arrived < self.config.saliency_timeout_s:
                    break
                self._awaiting.popitem(last=False)
                due.append(stamp)
        answers = []
        for stamp in due:
            record = self.history.get(stamp)
            if record is None or record.action is not None or record.observation is None:
                continue
            action = self._act(record, None, image=record.observation)
            self.counters['act/fallback_observation'] += 1
            self._log('warn', f'no saliency image for step {stamp} within '
                      f'{self.config.saliency_timeout_s} s: acted on its observation')
            answers.append((stamp, action))
        return answers

    def hear(self, text: str) -> None:
        """Take an utterance heard: a text-conditioned agent reads it from its next step on."""
        if self.text is not None:
            self.text = bag_of_words(text, self.config.text_size)

    def _with_text(self, record, features: torch.Tensor) -> torch.Tensor:
        """Return ``features`` with the words in force appended (text conditioning), kept."""
        if self.text is None:
            return features
        self.history.put_text(record.stamp, self.text)
        return torch.cat([features, self.text])

    def _preprocess(self, kind: str, rgb: np.ndarray) -> torch.Tensor:
        try:
            return torch.from_numpy(preprocess(rgb, self._frame_shape))
        except ValueError as error:
            self.counters[f'drop/{kind}'] += 1
            raise BadInput(f'{kind} dropped: {error}') from error

    def _decide(self, values: torch.Tensor, penalty: Optional[torch.Tensor]) -> int:
        """Return a new decision: at random on a share ``explore`` of them, else H's choice."""
        if self.config.explore > 0.0 and self._explore_rng.random() < self.config.explore:
            self.counters['act/explored'] += 1
            return int(self._explore_rng.integers(self._num_actions))
        return self.actor.choose(values, penalty)

    def _act(self, record, started: Optional[float], image=None) -> int:
        if record.action is not None:
            return record.action  # the env re-sent this step: answer it the same way
        waited = self.worker.wait_caught_up(self.config.pace_updates, self.config.pace_max_s)
        if waited > 0.0:  # the learner's turn first: the same learning per step however fast
            self.counters['act/paced'] += 1
            self.counters['act/paced_ms'] += round(1e3 * waited, 3)
            if started is not None:
                started += waited  # act latency is the agent's own time
        self.actor.refresh(self.slot)
        kind = self.config.input_image if image is None else 'observation'
        held = self._held if holds(self._decision, record.stamp,
                                   self.config.decision_period_s) else None
        if self.config.input_image == 'both':  # the frame's features, then its saliency's
            state = self._with_text(  # each image encoded once, as learned
                record, both_item(record, self.history, self.actor.model))
            values = self.actor.values_on_features(state)
        elif self.actor.model.freeze_encoder:
            image = record.image(kind) if image is None else image
            features = self.actor.features(image)  # encoded once: acting and learning share it
            self.history.put_features(kind, record.stamp, features)
            state = self._with_text(record, features)
            values = self.actor.values_on_features(state)
        else:
            state = record.image(kind) if image is None else image
            values = self.actor.predict(state)
        hashed = self.memory is not None or self.revisits is not None
        key = state_key(state) if hashed else None  # one digest for the memory and the revisits
        if self.memory is not None:  # the verdicts on this very state (memory.py)
            values = self.memory.blend(key, values)
        if held is not None and clearly_better(values, held, self.config.decision_switch_margin):
            self.counters['act/switched'] += 1
            held = None  # what H learned overrides the rest of the decision
        penalty = None if self.revisits is None else self.revisits.penalties(key)
        action = held if held is not None else self._decide(values, penalty)
        if penalty is not None:
            if float(penalty.sum()) > 0.0:  # back in a state acted in lately
                self.counters['act/revisits'] += 1
            self.revisits.took(key, action)
        if held is not None:
            self.counters['act/held'] += 1
        else:  # a new decision, held until decision_period_s has passed
            self._held, self._decision = action, record.stamp
        self.history.set_action(record.stamp, action,
                                self._decision if self.config.decision_period_s > 0 else None)
        self.journal.append(KIND_ACTION, record.stamp, action)
        if record.taken is not None and record.taken != action:  # told before it answered
            self.counters['act/taken_differs'] += 1
        if started is not None:
            self.act_seconds.append(time.perf_counter() - started)
        self.counters['act/count'] += 1
        self.acted.append((record.stamp, action, values))
        if self.asker is not None:
            gap = self.asker.consider(values)
            if gap is not None:
                self.counters['ask/asked'] += 1
                self.questions.append((record.stamp, action, gap))
        return action

    def take_questions(self) -> List[Tuple[int, int, float]]:
        """Return and forget the questions not yet taken (stamp, action, gap), oldest first."""
        taken = list(self.questions)
        self.questions.clear()
        return taken

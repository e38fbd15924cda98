"""
The learner's checkpoints: when, what goes in, and how a run is read back on resume.

Checkpoints are taken by the learner between updates (consistent copies: every feedback up to
``applied_seq`` is in the buffer and the counters, none after it) and written by the checkpoint
disk thread: after the first update, then ever less often up to ``checkpoint_period_s``
(``CheckpointClock``). The buffer goes in without its images: they are in the step journal,
found again by session and stamp on resume (``Checkpoints.load``).
"""

import copy
import math
from pathlib import Path
import time
from typing import Callable, Dict, Iterable, List, Optional, Tuple

from attention_common.run_files import (
    CHECKPOINT_DIR, CHECKPOINT_FILE, FEEDBACK_LOG, STEPS_DIR)
import numpy as np
from tamer_node.buffer import FeedbackBuffer
from tamer_node.config import TamerConfig
from tamer_node.delay_fit import DelayFit
from tamer_node.events import event_from_entry, FeedbackEvent
from tamer_node.history import holds, other_kind, StepHistory
from tamer_node.learner import Learner
from tamer_node.pairing import stored_item
from tamer_node.persistence import (
    DiskWriter, FeedbackLog, KIND_NAMES, KIND_TAKEN, load_checkpoint, save_checkpoint,
    StepJournal)
import torch

CHECKPOINT_FORMAT = 'tamer_node.checkpoint/3'  # /3: steps known by (session, stamp)


class CheckpointClock:
    """
    Decide when the learner checkpoints.

    Once it has learned something (an update, or feedback used), then 1, 2, 4, ... s apart, at
    most ``period_s`` (0: only at exit), and only when it has learned more since the last one.

    So a kill -9 costs at most the minibatch updates of the last half of a short run, or of
    ``period_s`` in a long one; feedback never (it is logged first and replayed on resume).
    """

    FIRST_INTERVAL_S = 1.0

    def __init__(self, period_s: float):
        self.period_s = float(period_s)
        self._interval = min(self.FIRST_INTERVAL_S, self.period_s)
        self._progress = (0, 0)  # (updates, applied feedback) at the last checkpoint
        self._due = -math.inf

    def next_at(self, progress) -> float:
        """Return the monotonic time of the next checkpoint (inf: none due, nothing new)."""
        if not self.period_s or tuple(progress) == self._progress:
            return math.inf
        return self._due

    def taken(self, progress, now: float) -> float:
        self._progress = tuple(progress)
        self._due = now + self._interval
        self._interval = min(2 * self._interval, self.period_s)
        return self.next_at(progress)


class Checkpoints:
    """Copies the learner's state into a checkpoint, and loads one back."""

    def __init__(self, config: TamerConfig, learner: Learner, buffer: FeedbackBuffer,
                 history: StepHistory, journal: StepJournal, disk: DiskWriter, run_dir: Path,
                 log: Callable[[str, str], None], delays: Optional[DelayFit] = None):
        self.config = config
        self.delays = delays
        self.learner = learner
        self.buffer = buffer
        self.history = history
        self.journal = journal
        self.disk = disk
        self.run_dir = Path(run_dir)
        self._log = log

    def take(self, count: Callable[[], dict], applied_seq: int) -> int:
        """
        Copy the state now (learner thread, between updates); write it on the disk thread.

        ``count`` counts the checkpoint and returns the counters to save. The journal keeps
        every step the buffer or the history still holds. Returns the new journal segment.
        """
        segment = self.journal.rotate()
        buffer_state = self.buffer.state_dict(images=False)
        needed = []
        sessions = buffer_state['columns']['sessions'].numpy()
        stamps = buffer_state['columns']['stamps'].numpy()
        if len(stamps):
            first = np.lexsort((stamps, sessions))[0]
            needed.append((int(sessions[first]), int(stamps[first])))
        if self.history.oldest() is not None:
            needed.append((self.history.session, self.history.oldest()))
        counters = count()
        state = {
            'format': CHECKPOINT_FORMAT,
            'learner': copy.deepcopy(self.learner.state_dict()),
            'buffer': buffer_state,
            'input_image': self.config.input_image,
            'counters': counters,
            'applied_seq': applied_seq,
            'session': self.history.session,
            'saved_at': time.time(),
        }
        if self.delays is not None:
            state['delay_fit'] = self.delays.state()

        def write() -> None:
            self.journal.drain()  # every step the checkpoint refers to is on disk first
            save_checkpoint(state, self.run_dir)
            if needed:
                self.journal.delete_older_than(min(needed))

        self.disk.submit(write)
        return segment

    def load(self, checkpoint: dict, sessions: Dict[int, StepHistory]) -> int:
        """Load the learner and the buffer (images from the journal); return samples lost."""
        if checkpoint.get('format') != CHECKPOINT_FORMAT:
            raise ValueError('the checkpoint was not written by this tamer_node version')
        self.learner.load_state_dict(checkpoint['learner'])
        if self.delays is not None and 'delay_fit' in checkpoint:
            self.delays.load(checkpoint['delay_fit'])
        buffer_state, missing = checkpoint['buffer'], 0
        if 'states' not in buffer_state:
            buffer_state, missing = self._find_images(
                buffer_state, sessions, checkpoint.get('input_image', 'observation'))
        self.buffer.load_state_dict(buffer_state)
        return missing

    def _find_images(self, state: dict, sessions: Dict[int, StepHistory],
                     kind: str) -> Tuple[dict, int]:
        """Put the journal's images back into a buffer state saved without them."""
        model = self.learner.model
        columns = {name: values.numpy() for name, values in state['columns'].items()}
        keep, states, companions = [], [], []
        for row, (session, stamp, has) in enumerate(zip(
                columns['sessions'], columns['stamps'], columns['has_companion'])):
            steps = sessions.get(int(session))
            record = steps.get(int(stamp)) if steps is not None else None
            image = record.image(kind) if record is not None else None
            companion = record.image(other_kind(kind)) if record is not None and has else None
            if image is None or (has and companion is None):
                continue
            keep.append(row)
            states.append(stored_item(record, kind, steps, model))
            if has:
                companions.append(stored_item(record, other_kind(kind), steps, model))
        missing = len(columns['stamps']) - len(keep)
        if missing:
            self._log('warn', f'{missing} buffer sample(s) lost: their steps are not in the '
                      'journal any more')
        empty = torch.from_numpy(self.buffer.states[:0].copy())
        return {
            'capacity': state['capacity'], 'added': state['added'],
            'columns': {name: torch.from_numpy(values[keep]) for name, values in columns.items()},
            'states': torch.stack(states) if states else empty,
            'companions': torch.stack(companions) if companions else empty,
        }, missing


def read_initial_model(path: str, input_image: str) -> Dict[str, torch.Tensor]:
    """
    Return H's weights from a trained run's checkpoint (a file, or a run folder's).

    ``ValueError`` says why they cannot be used: missing, unreadable, another version, or
    trained on another ``input_image``.
    """
    file = Path(path).expanduser()
    if file.is_dir():
        file = file / CHECKPOINT_DIR / CHECKPOINT_FILE
    if not file.is_file():
        raise ValueError(f'initial_model: no checkpoint at {file}')
    try:
        state = torch.load(file, map_location='cpu', weights_only=True)
    except Exception as error:  # torch.load raises many kinds
        raise ValueError(f'initial_model: {file} cannot be read ({error})') from error
    if not isinstance(state, dict) or state.get('format') != CHECKPOINT_FORMAT:
        raise ValueError(f'initial_model: {file} is not a checkpoint of this tamer_node version')
    trained_on = state.get('input_image', 'observation')
    if trained_on != input_image:
        raise ValueError(f'initial_model: {file} was trained with input_image {trained_on!r}, '
                         f'this learner has {input_image!r}')
    return state['learner']['model']


def read_run(run_dir: Path, log: Callable[[str, str], None]):
    """
    Return what a resume reads of ``run_dir``.

    (checkpoint or None, the logged feedback events, the journal's records, {segment: newest
    step}): the records are read lazily, and the dict fills as they are.
    """
    try:
        checkpoint = load_checkpoint(run_dir)
    except Exception as error:  # torch.load raises many kinds
        raise RuntimeError(
            f'the checkpoint in {run_dir / CHECKPOINT_DIR} cannot be read ({error}); '
            'move it away to resume from the feedback log alone') from error
    entries, unreadable = FeedbackLog.read(run_dir / FEEDBACK_LOG)
    if unreadable:
        log('warn', f'{unreadable} unreadable line(s) in the feedback log skipped')
    events = [event_from_entry(e) for e in entries if e.get('kind') == 'feedback']
    segments = {}
    records = StepJournal.read(run_dir / STEPS_DIR, segments)
    return checkpoint, events, records, segments


def journal_histories(records: Iterable,
                      decision_period_s: float = 0.0) -> Dict[int, StepHistory]:
    """
    Return the journal's steps as one unbounded StepHistory per session.

    With ``decision_period_s`` > 0 the acted steps of each session are grouped into decisions
    as the acting path made them (``history.holds``).
    """
    sessions: Dict[int, StepHistory] = {}
    for session, kind, stamp, action, image in records:
        steps = sessions.get(session)
        if steps is None:
            steps = sessions[session] = StepHistory(capacity=1 << 30, session=session)
        if image is not None and kind in KIND_NAMES:
            steps.put_image(KIND_NAMES[kind], stamp, image)
        elif kind == KIND_TAKEN:
            steps.set_taken(stamp, action)
        elif action >= 0:
            steps.set_action(stamp, action)
    if decision_period_s > 0.0:
        for steps in sessions.values():
            steps.mark_decisions(lambda decision, stamp: holds(decision, stamp,
                                                               decision_period_s))
    return sessions


def next_session(segments: dict, events: List[FeedbackEvent],
                 checkpoint: Optional[dict]) -> int:
    """Return the session a resumed process begins: one after every session of the run."""
    earlier = [session for session, _ in segments.values()]
    earlier += [e.session for e in events]
    earlier.append(int(checkpoint.get('session', 1)) if checkpoint else 0)
    return max(earlier) + 1

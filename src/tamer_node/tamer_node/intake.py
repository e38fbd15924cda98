"""
Feedback and utterance intake: what a person (or the synthetic trainer) says, on disk first.

Owned by the ``feedback*``/``utterance`` callbacks: it numbers each feedback, checks it and
queues it to the disk thread, which drains the step journal, appends the feedback to
``feedback_log.jsonl`` (flushed) and only then puts it in the learner's inbox: what the learner
uses is on disk, in arrival order. Its receipt goes out once its line is synced
(``sync``). Utterances are checked and logged the same way (the saliency
node turns them into images).
"""

import collections
import math
import threading
import time
from typing import Callable, Optional

from attention_common.feedback import FEEDBACK_RANGE, PlainCopies
from attention_common.utterance import MAX_UTTERANCE_CHARS
from tamer_node.config import TamerConfig
from tamer_node.events import entry_from_event, FeedbackEvent
from tamer_node.persistence import DiskWriter, FeedbackLog, StepJournal


class FeedbackIntake:
    """Numbers, checks and logs each feedback, then hands it to ``learn`` (the disk thread)."""

    def __init__(self, config: TamerConfig, counters: collections.Counter, steps,
                 journal: StepJournal, feedback_log: FeedbackLog, disk: DiskWriter,
                 learn: Callable[[FeedbackEvent], None], log: Callable[[str, str], None],
                 expect: Callable[[FeedbackEvent], None] = lambda event: None):
        self.config = config
        self.counters = counters
        self._steps = steps  # the acting path: the newest observation stamp and the session
        self.journal = journal
        self.feedback_log = feedback_log
        self.disk = disk
        self._learn = learn
        self._expect = expect  # told at once: the actor is paced from the arrival on
        self._log = log
        self._lock = threading.Lock()  # seq order == log order == inbox order
        self.seq = 0
        """Feedback received over the whole run (the last one's ``seq``)."""
        self._copies = PlainCopies(config.stamped_active_s)  # a trainer's plain_copies
        self.on_logged: Optional[Callable[[dict], None]] = None
        """Called on the disk thread with each feedback_log.jsonl entry once it is written."""

    def on_feedback(self, h: float, source: str, stamp: Optional[int] = None,
                    extra: Optional[dict] = None) -> FeedbackEvent:
        """
        Queue a feedback: the disk thread logs it, then hands it to the learner.

        ``source`` is 'stamped' (``stamp`` = the step judged: credited to that step whatever
        ``credit`` says, since it names it), 'plain' (stamped on arrival
        with the newest observation stamp; with ``plain_copies``, a copy, logged as
        'duplicate', when it pairs with a stamped or pressed verdict of the same h that came at
        most ``stamped_active_s`` before it) or 'pressed' (as plain, but ``stamp`` is the
        moment the trainer gave it, in simulation time: the credit window is measured from it
        instead of from the newest observation). Bad values are logged and counted, never
        raised. Returns at once.
        """
        arrived = time.monotonic()
        h = float(h)
        status = 'ok'
        if not math.isfinite(h) or abs(h) > FEEDBACK_RANGE:  # the one range of every node
            status = 'invalid'
        else:
            with self._lock:  # (without plain_copies every plain feedback is its own)
                if self.config.plain_copies and source in ('stamped', 'pressed'):
                    self._copies.verdict(arrived, h)
                elif self.config.plain_copies and self._copies.is_copy(arrived, h):
                    status = 'duplicate'
        now = self._steps.now
        if source == 'pressed':  # the window's t: the press, not the newest observation
            now = stamp if now is not None else None
        if source in ('plain', 'pressed'):
            stamp = self._steps.now
        if status == 'ok' and stamp is None:
            status = 'no_observation'
        with self._lock:
            self.seq += 1
            credit = 'step' if source == 'stamped' else self.config.credit
            event = FeedbackEvent(self.seq, h, stamp, now, status, credit, arrived,
                                  self._steps.session)
            entry = entry_from_event(event, source, time.time())
            entry.update(extra or {})
            # One FIFO queue: feedback reaches the log and then the learner in arrival order.
            self._expect(event)
            self.disk.submit(lambda: self._log_then_learn(entry, event))
        if status == 'invalid':
            self._log('warn', f'feedback #{event.seq} h={h} is not a finite number within '
                      f'[-{FEEDBACK_RANGE:g}, {FEEDBACK_RANGE:g}]: logged, not learned from')
        elif status == 'no_observation':
            self._log('warn', f'feedback #{event.seq} came before any observation: logged, '
                      'not learned from')
        return event

    def _log_then_learn(self, entry: dict, event: FeedbackEvent) -> None:
        """On the disk thread: the feedback is on disk (flushed) before the learner sees it."""
        try:
            self.journal.drain()  # the steps it refers to reach the disk before it does
            # The receipt goes out once the line is durable (TamerConfig.sync).
            self.feedback_log.append(entry, lambda: self._receipt(entry))
            self.counters['feedback/logged'] += 1
            self.counters['log/feedback_lines'] += 1
        except (OSError, ValueError) as error:  # a full disk: say so loudly, still learn
            self.counters['disk/feedback_log_errors'] += 1
            self._log('error', f'feedback #{event.seq} could not be written to '
                      f'{self.feedback_log.path}: {error}')
        self._learn(event)

    def _receipt(self, entry: dict) -> None:
        if self.on_logged is not None:
            try:
                self.on_logged(entry)
            except Exception as error:  # a receipt must never cost the feedback
                self._log('error', f'receipt for a logged {entry["kind"]} failed: {error!r}')

    def _log_utterance(self, entry: dict) -> None:
        self.feedback_log.append(entry, lambda: self._receipt(entry))
        self.counters['log/utterance_lines'] += 1

    def on_utterance(self, text: str, extra: Optional[dict] = None) -> str:
        """
        Record an utterance in the feedback log (the saliency node turns it into images).

        Returns its status: 'ok', or 'empty' / 'too_long' (longer than MAX_UTTERANCE_CHARS),
        which are counted, warned about and logged with that status (a long one's first
        MAX_UTTERANCE_CHARS characters), as the saliency node drops them too.
        """
        self.counters['utterance/count'] += 1
        status = 'ok'
        if not text.strip():
            status = 'empty'
            self.counters['utterance/empty'] += 1
            self._log('warn', 'utterance dropped: empty or only whitespace (logged as such)')
        elif len(text) > MAX_UTTERANCE_CHARS:
            status = 'too_long'
            self.counters['utterance/too_long'] += 1
            self._log('warn', f'utterance dropped: {len(text)} characters, more than '
                      f'{MAX_UTTERANCE_CHARS} (its start is logged)')
        entry = {'kind': 'utterance', 'wall_time': time.time(), 'now_ns': self._steps.now,
                 'session': self._steps.session, 'status': status, 'chars': len(text),
                 'text': text[:MAX_UTTERANCE_CHARS]}
        entry.update(extra or {})
        self.disk.submit(lambda: self._log_utterance(entry))
        return status

"""
A run's end: the synthetic trainer judged every step, and the learner logged it all.

In lockstep the env waits for the learner only, so on a busy machine the trainer can be dozens
of steps behind when the last step is taken; stopping the nodes then would lose its last
judgements. The trainer says how far it got on ``trainer_status``; the learner gives a receipt on
``feedback_logged`` for every line it logs, and counts the lines in its metrics
(``log/feedback_lines``, ``log/utterance_lines``): receipts sent before the launcher's reader
matched the learner's writer never reach it (a short run on a busy machine missed 262 of 296),
the periodic count does. The launcher stops the nodes once both caught up.
"""

from typing import Dict, Mapping, Optional

LINES_METRICS = {'feedback': 'log/feedback_lines', 'utterance': 'log/utterance_lines'}
"""The learner's metric counting the lines of each kind this process logged."""

TRAINER_DRAIN_S = 60.0
"""At most this long (wall seconds) for the trainer and the learner to catch up at the end."""


def logged_lines(metrics: Mapping[str, object]) -> Dict[str, int]:
    """Return the lines the learner says it logged, by kind, from its newest metrics."""
    return {kind: int(float(metrics.get(key, 0) or 0)) for kind, key in LINES_METRICS.items()}


def behind(trainer: Optional[Mapping[str, object]], last_step_ns: int,
           receipts: Mapping[str, int],
           lines: Optional[Mapping[str, int]] = None) -> Optional[str]:
    """
    Return what is not done yet at a run's end, or None when nothing is.

    ``trainer``: the newest ``trainer_status`` values (None: none heard); ``last_step_ns``: the
    stamp of the env's last step; ``receipts``: the learner's receipts counted by kind
    ('feedback', 'utterance'); ``lines``: the lines it says it logged (``logged_lines``).
    """
    if trainer is None:
        return 'no trainer_status heard from feedback_node'
    handled = int(trainer.get('handled_ns', -1))
    if handled < last_step_ns:
        return f'the trainer judged up to {handled} ns of {last_step_ns} ns'
    if int(trainer.get('held', 0)) > 0:
        return f'the trainer holds {trainer["held"]} messages for readers not matched'
    for kind, given in (('feedback', 'given_feedback'), ('utterance', 'given_utterances')):
        logged = max(receipts.get(kind, 0), (lines or {}).get(kind, 0))
        if logged < int(trainer.get(given, 0)):
            return (f'the learner logged {logged} of the {trainer[given]} '
                    f'{kind} messages the trainer gave')
    return None

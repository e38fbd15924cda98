"""
A run's end: the synthetic trainer judged every step, and the learner logged it all.

In lockstep the env waits for the learner only, so on a busy machine the trainer can be dozens
of steps behind when the last step is taken; stopping the nodes then would lose its last
judgements. The trainer says how far it got on ``trainer_status``; the learner gives a receipt on
``feedback_logged`` for every line it logs. The launcher stops the nodes once both caught up.
"""

from typing import Mapping, Optional

TRAINER_DRAIN_S = 60.0
"""At most this long (wall seconds) for the trainer and the learner to catch up at the end."""


def behind(trainer: Optional[Mapping[str, object]], last_step_ns: int,
           receipts: Mapping[str, int]) -> Optional[str]:
    """
    Return what is not done yet at a run's end, or None when nothing is.

    ``trainer``: the newest ``trainer_status`` values (None: none heard); ``last_step_ns``: the
    stamp of the env's last step; ``receipts``: the learner's receipts counted by kind
    ('feedback', 'utterance').
    """
    if trainer is None:
        return 'no trainer_status heard from feedback_node'
    handled = int(trainer.get('handled_ns', -1))
    if handled < last_step_ns:
        return f'the trainer judged up to {handled} ns of {last_step_ns} ns'
    if int(trainer.get('held', 0)) > 0:
        return f'the trainer holds {trainer["held"]} messages for readers not matched'
    for kind, given in (('feedback', 'given_feedback'), ('utterance', 'given_utterances')):
        if receipts.get(kind, 0) < int(trainer.get(given, 0)):
            return (f'the learner logged {receipts.get(kind, 0)} of the {trainer[given]} '
                    f'{kind} messages the trainer gave')
    return None

"""
The four settings of the teaching evaluation.

Every-step or human-like teacher, with or without language: each is a study condition plus the
``attention_train`` options that set the trainer.
"""

from typing import Dict, NamedTuple, Tuple


class Setting(NamedTuple):
    """One arm of the evaluation."""

    condition: str
    """The study condition (``config/conditions/<name>.yaml``)."""
    launcher_args: Tuple[str, ...]
    text: str


SETTINGS: Dict[str, Setting] = {
    'every_step_vanilla': Setting(
        'vanilla', ('--trainer', 'teacher'),
        'Teacher on every step, no delay, no noise (stamped: step credit); Deep TAMER alone.'),
    'every_step_language': Setting(
        'language', ('--trainer', 'teacher'),
        'The same teacher; it also speaks its stage sentence every 10 s (language saliency, '
        'alpha 1e-4).'),
    'human_like_vanilla': Setting(
        'vanilla', ('--trainer', 'teacher', '--human-like'),
        'Teacher on a third of the steps, 0.3-1.5 s late, 10 % of signs wrong, plain feedback '
        'credited by the window (0.2-1.6 s); Deep TAMER alone.'),
    'human_like_language': Setting(
        'language', ('--trainer', 'teacher', '--human-like'),
        'The same human-like teacher, speaking every 10 s (language saliency, alpha 1e-4).'),
    'human_like_vanilla_late_learner': Setting(
        'vanilla', ('--trainer', 'teacher', '--human-like', '--late-learner'),
        'The human-like teacher; the learner for late feedback (issue 23): decisions of 0.2 s '
        "credited on the step that chose, the mixture loss (the window's credit-weighted mean "
        'of H fitted to h), ties kept; Deep TAMER alone.'),
    'human_like_language_late_learner': Setting(
        'language', ('--trainer', 'teacher', '--human-like', '--late-learner'),
        'As human_like_vanilla_late_learner, the teacher speaking every 10 s (language saliency, '
        'alpha 1e-4).'),
}
"""The arms, in report order."""

THESIS_LEARNER = {
    f'{name}_thesis_learner': Setting(
        SETTINGS[name].condition, SETTINGS[name].launcher_args + ('--thesis-learner',),
        f"As {name}, with the thesis's greedy policy (argmax, ties to the lowest action; no "
        'greedy_margin).')
    for name in ('every_step_vanilla', 'every_step_language')}
"""Arms that show what the learner's change bought (run, not tuned on, by ``--settings``)."""
SETTINGS.update(THESIS_LEARNER)

COMPARISONS = (('every_step_language', 'every_step_vanilla'),
               ('human_like_language', 'human_like_vanilla'),
               ('human_like_language_late_learner', 'human_like_vanilla_late_learner'))
"""(language, its vanilla baseline) pairs tested against each other."""

SEEDS = tuple(range(1000, 1010))
"""Seeds of the reported trials: none of them was used to tune anything (the learner and the
teacher were tuned in one process on seeds 100-105: ``tests/benchmarks/teach_inprocess.py``)."""

TARGETS = {'every_step_vanilla': (9, 3000), 'human_like_vanilla': (7, None),
           'human_like_vanilla_late_learner': (8, 5000)}
"""Issue targets: (keys in at least this many of 10 trials, median steps to the key at most)."""

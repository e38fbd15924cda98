"""
The study of issue 7: run every condition's trials, analyse them, draw figures, write a report.

``stats`` (pure statistics), ``trials`` (one trial's compact result file), ``analysis`` (per
condition aggregates and tests), ``figures``, ``report`` (``docs/results.md``), ``runner``
(trials as ``attention_train`` subprocesses) and ``cli`` (the ``attention_study`` command).
"""

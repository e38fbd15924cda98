"""
The study of issue 7 (the ``thesis`` experiment): analyse the trials, draw figures, write a report.

``analysis`` (per condition aggregates and tests), ``figures``, ``report`` (``docs/results.md``),
``discussion`` and ``cli`` (the ``attention_study`` command).
"""

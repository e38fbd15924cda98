"""The teaching evaluation (``attention_teaching``): the teacher's four settings, 10 seeds each."""

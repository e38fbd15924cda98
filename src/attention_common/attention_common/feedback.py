"""The scale of a trainer's feedback, shared by the nodes that give, check and model it."""

FEEDBACK_RANGE = 1.0
"""A trainer's feedback h lies in [-FEEDBACK_RANGE, FEEDBACK_RANGE] ("good" +1, "bad" -1)."""

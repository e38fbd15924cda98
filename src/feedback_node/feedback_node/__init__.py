"""
The thesis's synthetic trainer.

Scalar feedback and Figure 5.1 utterances from the agent's position; off when a person trains.
"""

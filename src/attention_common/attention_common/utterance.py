"""What an utterance may be, shared by every node that reads one."""

MAX_UTTERANCE_CHARS = 2000
"""Longer utterances are logged, counted and dropped (Figure 5.1's longest sentence has 57)."""

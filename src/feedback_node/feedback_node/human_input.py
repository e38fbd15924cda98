"""
Checks of what a person sends on ``utterance`` and ``feedback`` (pure; no rclpy).

Each check returns None for good input, or a short reason fit for a log line. The feedback node
logs what it hears when a person trains (``synthetic:=false``), for the record.
"""

import math
from typing import Optional

from attention_common.feedback import FEEDBACK_RANGE
from attention_common.utterance import MAX_UTTERANCE_CHARS

EXCERPT_CHARS = 60


def excerpt(text: str) -> str:
    """Quote ``text`` shortly and printably for a log line."""
    quoted = repr(text[:EXCERPT_CHARS])
    return quoted + (f'... ({len(text)} characters)' if len(text) > EXCERPT_CHARS else '')


def utterance_problem(text: str) -> Optional[str]:
    """Why ``text`` is not a usable utterance, or None."""
    if not text:
        return 'empty utterance'
    if not text.strip():
        return 'whitespace-only utterance'
    if len(text) > MAX_UTTERANCE_CHARS:
        return f'utterance of {len(text)} characters (limit {MAX_UTTERANCE_CHARS})'
    if not text.isascii():
        odd = sorted({c for c in text if not c.isascii()})[:5]
        return f'non-ASCII characters in utterance: {", ".join(map(repr, odd))}'
    if any(not (c.isprintable() or c in '\t\n') for c in text):
        return 'control characters in utterance'
    return None


def feedback_problem(value: float) -> Optional[str]:
    """Why ``value`` is not a usable feedback h, or None (h is expected in [-1, 1])."""
    if not math.isfinite(value):
        return f'feedback {value} is not a finite number'
    if abs(value) > FEEDBACK_RANGE:
        return f'feedback {value} is outside [-1, 1]'
    return None

"""What a person may send: the checks behind the feedback node's log lines."""

import math

from attention_tasks.montezuma.sentences import position_problem
from feedback_node.human_input import (
    excerpt, feedback_problem, MAX_UTTERANCE_CHARS, utterance_problem)
import pytest


@pytest.mark.parametrize('text, reason', [
    ('', 'empty utterance'),
    ('  \t\n ', 'whitespace-only utterance'),
    ('Climb up the ladder \u00e9', 'non-ASCII characters'),
    ('\u68af\u5b50', 'non-ASCII characters'),
    ('x' * 100_000, 'utterance of 100000 characters'),
    ('Jump\x00 up', 'control characters'),
])
def test_bad_utterances_are_named(text, reason):
    assert reason in utterance_problem(text)


@pytest.mark.parametrize('text', [
    'Jump up to get the key.', 'Move left\tand avoid the skull.\n', 'x' * MAX_UTTERANCE_CHARS])
def test_good_utterances_pass(text):
    assert utterance_problem(text) is None


@pytest.mark.parametrize('value, ok', [
    (1.0, True), (-1.0, True), (0.0, True), (0.5, True),
    (math.nan, False), (math.inf, False), (-math.inf, False), (1.5, False), (-2.0, False),
])
def test_feedback_values(value, ok):
    assert (feedback_problem(value) is None) == ok


def test_excerpt_of_a_huge_utterance_is_short():
    quoted = excerpt('x' * 100_000)
    assert len(quoted) < 120 and '100000 characters' in quoted
    assert excerpt('ok') == "'ok'"


@pytest.mark.parametrize('x, y, reason', [
    (float('nan'), 235.0, 'not finite'), (40.0, float('inf'), 'not finite'),
    (1e30, 235.0, 'outside'), (300.0, 235.0, 'outside'), (40.0, -5.0, 'outside'),
    (-0.5, 148.0, 'outside')])
def test_positions_the_game_cannot_report_are_refused(x, y, reason):
    assert reason in position_problem(x, y)


@pytest.mark.parametrize('x, y', [(0.0, 0.0), (77.0, 235.0), (255.0, 255.0), (21.0, 148.0)])
def test_positions_in_the_ram_range_are_accepted(x, y):
    assert position_problem(x, y) is None

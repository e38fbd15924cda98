"""The executor choice and the MessageInfo callback adapter (attention_common.executors)."""

import inspect

from attention_common import executors
import pytest


def test_the_events_executor_is_the_default_and_single_can_be_chosen(monkeypatch):
    monkeypatch.delenv(executors.EXECUTOR_ENV, raising=False)
    assert executors.executor_name() == 'events'
    monkeypatch.setenv(executors.EXECUTOR_ENV, ' Single ')
    assert executors.executor_name() == 'single'
    monkeypatch.setenv(executors.EXECUTOR_ENV, 'multi')
    with pytest.raises(ValueError, match='events, single'):
        executors.executor_name()


def test_a_message_info_callback_takes_both_calling_forms():
    got = []
    callback = executors.with_message_info(lambda msg, info: got.append((msg, info)))
    callback('msg', {'publication_sequence_number': 3})  # SingleThreadedExecutor
    callback(('msg', {'publication_sequence_number': 4}))  # EventsExecutor (rclpy 7.1.6)
    assert got == [('msg', {'publication_sequence_number': 3}),
                   ('msg', {'publication_sequence_number': 4})]
    # rclpy hands over the MessageInfo only to a callback that cannot bind one argument.
    signature = inspect.signature(callback)
    with pytest.raises(TypeError):
        signature.bind(object())
    signature.bind(object(), object())

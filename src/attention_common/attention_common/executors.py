"""
Which rclpy executor runs the graph's nodes, and how it is spun.

Receiving one message costs a Python subscriber 320-480 µs of CPU with rclpy's
SingleThreadedExecutor and about a third of that with its C++ ``EventsExecutor``
(``rclpy.experimental``; ``tests/benchmarks/bench_messages.py --executor``). Every node of the
graph uses the EventsExecutor unless ``ATTENTION_EXECUTOR=single`` is set. Two defects of the
EventsExecutor in Jazzy's rclpy 7.1.6 are worked around here (reproduced by
``tests/benchmarks/events_executor_repro.py``):

- ``spin()`` never fires timers and can hang holding the GIL; ``spin_once()`` in a loop works,
  so ``spin_until_shutdown`` spins that way, in the main thread.
- A subscription callback that takes rclpy's MessageInfo is called with *one* argument, the
  tuple ``(msg, info)``, instead of two (the SingleThreadedExecutor passes two): a plain
  ``def callback(msg, info)`` raises inside C++ and the process dies with ``SystemError``.
  ``with_message_info`` makes a callback that accepts either form.
"""

import inspect
import os
import threading
import time
from typing import Callable, Optional

EXECUTOR_ENV = 'ATTENTION_EXECUTOR'
EXECUTORS = ('events', 'single')
DEFAULT_EXECUTOR = 'events'
SPIN_TIMEOUT_S = 0.1
"""Longest a spin_once waits, so a shutdown is seen within this time at worst."""
SHUTDOWN_TIMEOUT_S = 2.0
DRAIN_S = 0.5
"""After a stop signal, how long a node still takes and handles what it was sent before."""


def executor_name() -> str:
    """Return the executor chosen by ``ATTENTION_EXECUTOR`` (``events`` unless set)."""
    name = os.environ.get(EXECUTOR_ENV, '').strip().lower() or DEFAULT_EXECUTOR
    if name not in EXECUTORS:
        raise ValueError(f'{EXECUTOR_ENV}={name!r}: use one of {", ".join(EXECUTORS)}')
    return name


def make_executor(name: str = None, context=None):
    """Return a new executor: rclpy's EventsExecutor, or its SingleThreadedExecutor."""
    name = name or executor_name()
    if name == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    from rclpy.executors import SingleThreadedExecutor
    return SingleThreadedExecutor(context=context)


def spin_until_shutdown(executor, context=None, stop: Optional[threading.Event] = None) -> None:
    """
    Spin ``executor`` with ``spin_once`` until the context shuts down or ``stop`` is set.

    After ``stop`` (a signal, see ``node_main``) it spins ``DRAIN_S`` more: what was sent to the
    node before the signal (a person's last key press) is taken and handled, not left unread
    in DDS when the process ends.
    """
    import rclpy
    while rclpy.ok(context=context) and not (stop is not None and stop.is_set()):
        executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
    deadline = time.monotonic() + DRAIN_S
    while stop is not None and rclpy.ok(context=context):
        left = deadline - time.monotonic()
        if left <= 0.0:
            break
        executor.spin_once(timeout_sec=min(left, SPIN_TIMEOUT_S))


def release(executor, node) -> None:
    """Take ``node`` out of ``executor`` and shut the executor down (before destroying node)."""
    try:
        if node is not None:
            executor.remove_node(node)
        executor.shutdown(timeout_sec=SHUTDOWN_TIMEOUT_S)
    except Exception:  # noqa: B902 - a context already shut down: nothing left to release
        pass


class _MessageInfoCallback:
    """A two-argument subscription callback that also accepts one ``(msg, info)`` tuple."""

    __signature__ = inspect.Signature([
        inspect.Parameter('msg', inspect.Parameter.POSITIONAL_ONLY),
        inspect.Parameter('info', inspect.Parameter.POSITIONAL_ONLY)])
    """What rclpy inspects to hand over the MessageInfo (it binds two arguments)."""

    def __init__(self, callback: Callable[[object, dict], None]):
        self._callback = callback

    def __call__(self, *args) -> None:
        if len(args) == 1:  # the EventsExecutor's (msg, info) tuple
            args = tuple(args[0])
        msg, info = args
        self._callback(msg, info)


def with_message_info(callback: Callable[[object, dict], None]) -> _MessageInfoCallback:
    """Wrap ``callback(msg, info)`` so that either executor can call it (see above)."""
    return _MessageInfoCallback(callback)

"""
The Jazzy ``main()`` every node of the graph shares.

``rclpy.init``, build the node, spin it in the main thread (``executors.py``: rclpy's
EventsExecutor unless ``ATTENTION_EXECUTOR=single``), and on Ctrl-C / SIGINT / SIGTERM handle
what was already sent to the node (``StopRequest``), destroy it and shut down cleanly with exit
code 0. A node's own last work (``close()``, see ``Closing``) comes first; leaving DDS after it
runs under a watchdog (``teardown_watchdog``) that ends a hung teardown with exit code 0. A node
that cannot start (a missing template file, say) raises ``StartupError`` from
its constructor: the message is printed once, plainly, and the exit code is 1.
"""

import signal
import sys
import threading
import time
from typing import Callable, Optional

from attention_common.dds_memory import use_freed_payloads
from attention_common.executors import make_executor, release, spin_until_shutdown
from attention_common.teardown_watchdog import TeardownWatchdog
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions


SHUTDOWN_GRACE_S = 0.5
"""How long an error is given to turn out to be a shutdown in progress (the context ends)."""


def _still_running() -> bool:
    """Tell whether the context is still up a moment after an error (not a shutdown)."""
    deadline = time.monotonic() + SHUTDOWN_GRACE_S
    while rclpy.ok() and time.monotonic() < deadline:
        time.sleep(0.01)
    return rclpy.ok()


class StartupError(RuntimeError):
    """A node cannot start; the message says why and what to do."""


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def unblock_stop_signals() -> None:
    """
    Let SIGINT and SIGTERM reach this process, whatever its parent blocked or ignored.

    A signal mask is inherited across fork and exec: a Ray worker's threads block SIGINT, so a
    launcher started from a Ray task, and its nodes, never got the SIGINT that stops them
    cleanly (each needed SIGTERM, 10 s later). An ignored signal stays ignored across exec too:
    a study started in the background by a shell without job control (``cmd &`` in a script)
    ignores SIGINT, and so did every launcher it started, which then ran on until SIGTERM
    30 s later when the study was stopped. Call from the main thread.
    """
    if hasattr(signal, 'pthread_sigmask'):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


class Closing:
    """
    Mixin for a node with work of its own to finish (a last checkpoint, a bag's last chunk).

    The node puts that work in ``on_close()``; ``close()`` runs it once. ``run_node`` calls
    ``close()`` before leaving DDS (which is watched for hangs, the node's work is not), and
    ``destroy_node()`` calls it too, for whoever builds the node in their own process.
    """

    _closed = False

    def on_close(self) -> None:
        """Finish the node's own work (override)."""

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.on_close()

    def destroy_node(self) -> None:
        self.close()
        super().destroy_node()


class StopRequest:
    """
    SIGINT / SIGTERM handler: ask the node to stop, once it has handled what it was sent.

    rclpy's own handler shuts the context down at once, and a message already delivered to the
    node but not yet taken (feedback given just before Ctrl-C) was then never read. Before the
    node spins (a long start-up) and at a second signal it stops at once (KeyboardInterrupt).
    """

    def __init__(self):
        self.event = threading.Event()
        self.spinning = False

    def install(self) -> None:
        for sig in STOP_SIGNALS:
            signal.signal(sig, self)
        unblock_stop_signals()

    def __call__(self, signum, frame) -> None:
        if not self.spinning or self.event.is_set():
            raise KeyboardInterrupt
        self.event.set()


def run_node(node_factory: Callable[[], object], args=None,
             executor_factory: Optional[Callable[[], object]] = None) -> int:
    """Run one node until shutdown; return the process exit code."""
    use_freed_payloads()  # before rclpy.init: Fast DDS reads its profile then
    stop = StopRequest()
    stop.install()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    try:
        node = node_factory()
        executor = (executor_factory or make_executor)()
        executor.add_node(node)
        stop.spinning = True
        spin_until_shutdown(executor, stop=stop.event)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except StartupError as error:
        sys.stderr.write(f'[startup error] {error}\n')
        return 1
    except Exception:
        if _still_running():
            raise
        # The context was shut down meanwhile (rclpy.shutdown from elsewhere while the node was
        # being built or a message taken): creating a publisher or taking from a subscription
        # then fails. That is stopping, not an error.
    finally:
        try:
            if isinstance(node, Closing):
                node.close()
        finally:
            with TeardownWatchdog():
                _leave_dds(executor, node)
    return 0


def _leave_dds(executor, node) -> None:
    """Let go of the executor, the node and the context (rclpy and the middleware)."""
    if executor is not None:
        # Let go of the node's entities first: the EventsExecutor holds them "in use", and a
        # node destroyed under it left saliency_node spinning in rclpy's EventHandler __exit__
        # after the end of a run, never exiting.
        release(executor, node)
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()

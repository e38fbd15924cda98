"""
The ROS side of a process that drives a graph (``attention_train``, ``attention_replay``).

One node of its own (the launcher's monitor, the replay's player) on a context of its own in
the run's domain, spun with ``spin_once`` on a thread (``monitor.spin_until_shutdown``), and
left under the teardown watchdog, as every node of the graph leaves (``node_main``): by then
the run folder is written, and a teardown that hangs ends with the run's own exit code.
"""

import threading
from typing import Callable, TextIO

from attention_common.dds_memory import use_freed_payloads
from attention_common.executors import make_executor, release
from attention_common.isolation import apply_to_this_process
from attention_common.teardown_watchdog import TeardownWatchdog

SPINNER_JOIN_S = 2.0
"""How long the spinning thread is given to end once the context is down (under the
watchdog's deadline)."""


class Driver:
    """``with Driver(domain, make_node, err) as driver:`` ... ``driver.exit_code = code``."""

    def __init__(self, domain_id: int, make_node: Callable[[object], object], err: TextIO):
        self._domain_id = domain_id
        self._make_node = make_node
        self._err = err
        self.node = None
        self.exit_code = 1
        """What the process exits with if its teardown hangs: set it to the run's result."""

    def __enter__(self) -> 'Driver':
        import rclpy
        from rclpy.context import Context
        from rclpy.signals import SignalHandlerOptions

        from attention_bringup.monitor import spin_until_shutdown

        apply_to_this_process(self._domain_id)
        use_freed_payloads()  # the graph's Fast DDS profile, as every node of it has
        self._context = Context()
        rclpy.init(context=self._context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = self._make_node(self._context)
        self._executor = make_executor(context=self._context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._spinner = threading.Thread(
            target=spin_until_shutdown,
            args=(self._executor, self._context, self._err, self._stop), daemon=True)
        self._spinner.start()
        return self

    def __exit__(self, *exc) -> None:
        import rclpy
        with TeardownWatchdog(exit_code=self.exit_code):
            # The spinning thread ends first: shutting the EventsExecutor down while another
            # thread spins it raised "Attempt to remove nonexistent callback" and then aborted
            # the process (std::terminate) after a whole run had completed (seen once in 30
            # study trials).
            self._stop.set()
            self._spinner.join(timeout=SPINNER_JOIN_S)
            release(self._executor, self.node)
            self.node.destroy_node()
            rclpy.try_shutdown(context=self._context)

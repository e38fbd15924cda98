"""
A watchdog for the last part of a node's life: leaving DDS.

A node's own work ends with ``close()`` (the tamer's last checkpoint, the bag's last chunk);
what follows is rclpy and the middleware letting go of the node's entities. That part hung,
rarely: env_node spun in rcl's node teardown (``Node.destroy_node``) holding the GIL, and
saliency_node in rclpy's ``EventHandler.__exit__``, each until the launcher's SIGKILL. A
Python thread cannot help while native code holds the GIL, so the watchdog is native:

- at ``deadline_s`` the stdlib's ``faulthandler`` (a C thread) writes every thread's Python
  stack to stderr (the node's log), starting with ``Timeout (0:00:0N)!``;
- ``EXIT_GRACE_S`` later a POSIX timer (``timer_create`` with ``SIGEV_THREAD``, calling libc's
  ``_exit``) ends the process with the exit code it was about to return (a node's is 0):
  nothing of the node's is lost by then.

Where POSIX timers are missing (not Linux), faulthandler itself exits, with code 1.
"""

import ctypes
import faulthandler
import sys
from typing import Optional

TEARDOWN_DEADLINE_S = 3.0
"""How long leaving DDS may take before the stacks are dumped (it takes well under 0.1 s)."""
EXIT_GRACE_S = 0.2
"""From the dump to the exit: time to write the stacks."""
DUMP_HEADER = 'Timeout ('
"""How faulthandler's dump begins in the log: how the launcher counts a hung teardown."""

_SIGEV_THREAD = 2
_CLOCK_MONOTONIC = 1


class _SigVal(ctypes.Union):
    _fields_ = [('sival_int', ctypes.c_int), ('sival_ptr', ctypes.c_void_p)]


class _SigEvent(ctypes.Structure):
    # glibc's struct sigevent: value, signo, notify, then a union (function, attributes) padded
    # to 64 bytes in all.
    _fields_ = [('sigev_value', _SigVal), ('sigev_signo', ctypes.c_int),
                ('sigev_notify', ctypes.c_int), ('sigev_notify_function', ctypes.c_void_p),
                ('sigev_notify_attributes', ctypes.c_void_p), ('_pad', ctypes.c_byte * 32)]


class _TimeSpec(ctypes.Structure):
    _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]


class _ITimerSpec(ctypes.Structure):
    _fields_ = [('it_interval', _TimeSpec), ('it_value', _TimeSpec)]


def _native_exit_timer(after_s: float, code: int) -> Optional[ctypes.c_void_p]:
    """Start a POSIX timer that calls ``_exit(code)`` after ``after_s``; None if impossible."""
    if not sys.platform.startswith('linux'):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        event = _SigEvent()
        event.sigev_notify = _SIGEV_THREAD
        event.sigev_value.sival_int = code
        event.sigev_notify_function = ctypes.cast(libc._exit, ctypes.c_void_p).value
        timer = ctypes.c_void_p()
        if libc.timer_create(_CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)):
            return None
        seconds = int(after_s)
        spec = _ITimerSpec(_TimeSpec(0, 0),
                           _TimeSpec(seconds, int((after_s - seconds) * 1e9)))
        if libc.timer_settime(timer, 0, ctypes.byref(spec), None):
            libc.timer_delete(timer)
            return None
        return timer
    except (AttributeError, OSError):
        return None


class TeardownWatchdog:
    """Dump the stacks, then exit cleanly, if the teardown outlives its deadline."""

    def __init__(self, deadline_s: float = TEARDOWN_DEADLINE_S, exit_code: int = 0):
        self.deadline_s = deadline_s
        self.exit_code = exit_code
        """What a hung teardown exits with: the process's own result (a node's is 0)."""
        self._timer = None
        self._armed = False

    def arm(self) -> None:
        sys.stdout.flush()
        sys.stderr.flush()
        self._timer = _native_exit_timer(self.deadline_s + EXIT_GRACE_S, self.exit_code)
        for stream in (sys.stderr, sys.__stderr__):  # (a captured stderr may have no fd)
            try:
                faulthandler.dump_traceback_later(self.deadline_s, exit=self._timer is None,
                                                  file=stream)
                break
            except (AttributeError, ValueError, OSError):
                continue
        self._armed = True

    def disarm(self) -> None:
        if not self._armed:
            return
        faulthandler.cancel_dump_traceback_later()
        if self._timer is not None:
            ctypes.CDLL(None).timer_delete(self._timer)
            self._timer = None
        self._armed = False

    def __enter__(self) -> 'TeardownWatchdog':
        self.arm()
        return self

    def __exit__(self, *exc) -> None:
        self.disarm()

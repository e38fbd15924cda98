"""The teardown watchdog ends a teardown that hangs in native code holding the GIL."""

import signal
import subprocess
import sys
import time

from attention_common.teardown_watchdog import DUMP_HEADER

# A hang no Python thread can break: the regex engine backtracks for hours holding the GIL.
_HANG = "import re; re.match(r'(a+)+$', 'a' * 40 + 'b')"


def _run(body: str, timeout: float = 30.0) -> subprocess.CompletedProcess:
    script = ('import sys\n'
              'from attention_common.teardown_watchdog import TeardownWatchdog\n' + body)
    return subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                          timeout=timeout)


def test_a_teardown_hung_holding_the_gil_ends_with_exit_code_0_and_its_stack():
    start = time.monotonic()
    result = _run('def leave_dds():\n'
                  f'    {_HANG}\n'
                  'with TeardownWatchdog(deadline_s=0.5):\n'
                  '    leave_dds()\n'
                  'sys.exit(5)  # never reached\n')
    took = time.monotonic() - start
    assert result.returncode == 0, result.stderr
    assert took < 20.0
    assert result.stderr.startswith(DUMP_HEADER)
    assert 'leave_dds' in result.stderr  # the stack says where it hung


def test_a_teardown_that_finishes_disarms_the_watchdog():
    result = _run('with TeardownWatchdog(deadline_s=0.5):\n'
                  '    pass\n'
                  'import time; time.sleep(1.5)  # past the deadline: nothing fires\n'
                  'sys.exit(5)\n')
    assert result.returncode == 5
    assert DUMP_HEADER not in result.stderr


def test_the_launcher_names_a_node_whose_teardown_the_watchdog_ended(tmp_path):
    from attention_bringup.plan import NodeCommand
    from attention_bringup.processes import NodeGroup
    hangs = ('import signal, sys, time\n'
             'from attention_common.teardown_watchdog import TeardownWatchdog\n'
             'signal.signal(signal.SIGINT, lambda *_: sys.exit(0))\n'
             'print("ready", flush=True)\n'
             'try:\n'
             '    time.sleep(60)\n'
             'finally:\n'
             '    with TeardownWatchdog(deadline_s=0.5):\n'
             f'        {_HANG}\n')
    quits = 'import time; time.sleep(60)\n'  # SIGINT's KeyboardInterrupt: exit code 1
    group = NodeGroup({})
    for name, body in (('hung_node', hangs), ('plain_node', quits)):
        group.start(NodeCommand(name, [sys.executable, '-c', body], tmp_path / f'{name}.log'))
    deadline = time.monotonic() + 20
    while 'ready' not in (tmp_path / 'hung_node.log').read_text():
        assert time.monotonic() < deadline
        time.sleep(0.05)
    codes = group.stop(sigint_timeout=15.0)
    assert codes['hung_node'] == 0
    assert group.teardown_hangs() == ['hung_node']


CHILD = """
import os, signal
from attention_common.node_main import unblock_stop_signals
ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
unblock_stop_signals()
try:
    os.kill(os.getpid(), signal.SIGINT)  # (a handler runs as soon as kill returns)
    print('ignored' if ignored else 'not ignored', 'ran on')
except KeyboardInterrupt:
    print('ignored' if ignored else 'not ignored', 'stopped')
"""


def test_a_process_started_with_sigint_ignored_hears_it_again():
    """A study started with ``&`` from a script inherits SIGINT ignored; its stop must work."""
    result = subprocess.run([sys.executable, '-c', CHILD], capture_output=True, text=True,
                            timeout=60, preexec_fn=lambda: signal.signal(signal.SIGINT,
                                                                         signal.SIG_IGN))
    assert result.stdout.strip() == 'ignored stopped', result.stdout + result.stderr

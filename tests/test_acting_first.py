"""``--acting-first``: the processes off the acting path really run in Linux's idle class."""

import os
import subprocess
import sys
import textwrap

from attention_bringup.plan import NodeCommand
from attention_bringup.processes import NodeGroup
import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith('linux'),
                                reason='SCHED_IDLE is Linux only')

# Prints the scheduling class of every thread of the process, one started after the choice.
POLICIES = textwrap.dedent("""
    import os, sys, threading
    {before}
    done = threading.Event()
    worker = threading.Thread(target=done.wait)
    worker.start()
    print(sorted({{os.sched_getscheduler(int(tid)) for tid in os.listdir('/proc/self/task')}}))
    done.set()
""")


def policies_of_node(tmp_path, idle: bool):
    log = tmp_path / f'node-{idle}.log'
    group = NodeGroup(os.environ)
    node = group.start(NodeCommand('probe', [sys.executable, '-c', POLICIES.format(before='')],
                                   log, idle=idle))
    assert node.process.wait(30) == 0
    return log.read_text().strip()


def test_a_node_started_idle_runs_every_thread_in_the_idle_class(tmp_path):
    assert policies_of_node(tmp_path, idle=True) == str([os.SCHED_IDLE])
    assert policies_of_node(tmp_path, idle=False) == str([os.SCHED_OTHER])


def test_the_launcher_idles_its_own_threads_those_started_before_too():
    before = ('threading.Thread(target=threading.Event().wait, daemon=True).start()\n'
              'from attention_bringup.processes import idle_this_process\n'
              'idle_this_process()')
    out = subprocess.run([sys.executable, '-c', POLICIES.format(before=before)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str([os.SCHED_IDLE])

"""lower_process_priority: every thread of the process yields, not only the caller (no ROS)."""

import json
import subprocess
import sys

from graph_viewer.config import ViewerConfig
import pytest

PROBE = r"""
import json, os, threading
from attention_common.priority import lower_process_priority
release, ready = threading.Event(), threading.Event()
def wait():
    ready.set()
    release.wait()
before = threading.Thread(target=wait)  # as DDS's threads: started before
before.start()
ready.wait()
nice = lambda tid: os.getpriority(os.PRIO_PROCESS, tid)
start = nice(threading.get_native_id())
failed = lower_process_priority(int(os.environ['NICE']))
after = {}
later = threading.Thread(target=lambda: after.update(tid=nice(threading.get_native_id())))
later.start()
later.join()
seen = {'start': start, 'caller': nice(threading.get_native_id()),
        'before': nice(before.native_id), 'later': after['tid'], 'failed': failed}
release.set()
before.join()
print(json.dumps(seen))
"""


def _probe(nice: int) -> dict:
    result = subprocess.run([sys.executable, '-c', PROBE], capture_output=True, text=True,
                            timeout=60, env={'NICE': str(nice), 'PATH': ''})
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_a_thread_started_before_is_lowered_too_and_new_ones_inherit():
    seen = _probe(7)
    assert seen['failed'] == []
    assert seen['caller'] == seen['start'] + 7
    assert seen['before'] == seen['start'] + 7  # os.nice would have left it where it was
    assert seen['later'] == seen['start'] + 7


def test_zero_leaves_every_thread_as_it_is():
    seen = _probe(0)
    assert seen['caller'] == seen['before'] == seen['start']


def test_the_viewers_niceness_is_checked():
    with pytest.raises(ValueError, match='nice'):
        ViewerConfig(nice=20).validate()
    ViewerConfig(nice=0).validate()

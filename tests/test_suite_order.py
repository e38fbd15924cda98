"""The suite's own scheduling: the files it runs first are files it has."""

import os
from pathlib import Path
import subprocess
import sys

from conftest import LONGEST_FIRST
import pytest


def test_every_file_scheduled_first_exists_and_is_named_once():
    here = Path(__file__).resolve().parent
    assert [name for name in LONGEST_FIRST if not (here / name).is_file()] == []
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)


def test_under_ci_the_suite_runs_on_every_cpu_it_may_use():
    """
    .ci/run widens a pinned CPU affinity: the tests then have every CPU the machine allows.

    On the CI machines here the init process is pinned to one of two CPUs, and the whole suite
    inherited it. A child tries to take every CPU; if it may, the suite should have had them.
    """
    if not os.environ.get('CI'):
        pytest.skip('checks the CI set-up (.ci/run); set CI=1 to run it')
    mine = os.sched_getaffinity(0)
    probe = subprocess.run(
        [sys.executable, '-c', 'import os\n'
         'try:\n    os.sched_setaffinity(0, range(os.cpu_count()))\n'
         'except OSError:\n    pass\nprint(len(os.sched_getaffinity(0)))'],
        capture_output=True, text=True, check=True)
    assert len(mine) >= int(probe.stdout), (
        f'the suite runs on CPUs {sorted(mine)} of {os.cpu_count()}, but may use '
        f'{probe.stdout.strip()}: run it through .ci/run')

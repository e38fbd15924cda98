"""Lower a whole process's CPU priority, every thread of it (Linux threads have their own)."""

import os
from pathlib import Path
from typing import List

TASKS = Path('/proc/self/task')


def lower_thread_priority(tid: int, nice: int) -> None:
    """Add ``nice`` to thread ``tid``'s niceness, up to 19 (OSError, AttributeError: not so)."""
    os.setpriority(os.PRIO_PROCESS, tid, min(os.getpriority(os.PRIO_PROCESS, tid) + nice, 19))


def lower_process_priority(nice: int) -> List[str]:
    """
    Add ``nice`` to the niceness of every thread this process has now; return what failed.

    ``os.nice`` changes the calling thread only, so DDS's and a library's threads started
    before it would keep competing at full priority; threads started after this inherit it from
    the thread that starts them. Not Linux, or not allowed: left as it is, and said.
    """
    if nice <= 0:
        return []
    failed = []
    try:
        tids = [int(entry.name) for entry in TASKS.iterdir()]
    except OSError as error:
        return [f'threads not listed ({error})']
    for tid in tids:
        try:
            lower_thread_priority(tid, nice)
        except (AttributeError, OSError) as error:  # gone meanwhile, or not allowed
            if (TASKS / str(tid)).exists():
                failed.append(f'thread {tid}: {error}')
    return failed

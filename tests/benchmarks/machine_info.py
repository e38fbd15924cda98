"""The one line every benchmark prints about the machine it ran on."""

import os
import platform


def machine() -> str:
    """Return CPU model, usable cores, Python version and OS, e.g. for a table's caption."""
    model = 'unknown CPU'
    try:
        with open('/proc/cpuinfo') as cpuinfo:
            for line in cpuinfo:
                if line.startswith('model name'):
                    model = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()
    return f'{model}, {cores} cores, Python {platform.python_version()}, {platform.system()}'

"""
Run every benchmark script in this folder (``make bench``), one after the other.

Each ``bench_*.py`` runs as its own process with this Python and prints its own table; this
script prints which one runs, its wall time, and exits non-zero if any of them failed.
Arguments, if any, pick scripts by name: ``run_all.py graph saliency``.
"""

from pathlib import Path
import subprocess
import sys
import time


def main() -> int:
    here = Path(__file__).resolve().parent
    scripts = sorted(here.glob('bench_*.py'))
    wanted = sys.argv[1:]
    if wanted:
        scripts = [s for s in scripts if any(name in s.stem for name in wanted)]
    if not scripts:
        print(f'no bench_*.py in {here}')
        return 1
    failed = []
    for script in scripts:
        print(f'=== {script.name}', flush=True)
        started = time.monotonic()
        code = subprocess.call([sys.executable, str(script)], cwd=here.parents[1])
        print(f'=== {script.name}: exit code {code}, {time.monotonic() - started:.0f} s\n',
              flush=True)
        if code != 0:
            failed.append(script.name)
    if failed:
        print(f'failed: {", ".join(failed)}')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())

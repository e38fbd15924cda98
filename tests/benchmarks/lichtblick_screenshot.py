r"""
A screenshot of a live session in Lichtblick (Foxglove Studio's open-source fork), with our layout.

Not a benchmark: the script that made the README's picture. It starts a real-time Room 1 run
with the Foxglove bridge (``attention_train --realtime --foxglove``), serves a static web build
of Lichtblick and the session layout (``layouts/attention_graph_lichtblick.json``) on
127.0.0.1, opens it in the system's Chromium with the connection and the layout in the URL
(Lichtblick's ``ds=foxglove-websocket``, ``ds.url`` and ``layoutUrl``), waits, and saves the page.

The run is recorded; ``--bag RUN`` then shows that run's bag instead, in the same layout:
the bag and its plot channels (``graph_viewer_plots``, made if missing) served with HTTP range
requests as Lichtblick's ``ds=remote-file`` reads them, the player at ``--at`` seconds in.

Lichtblick is not on PyPI: build its web app once from its repository
(``yarn web:build:prod``; ``web/.webpack`` is the folder to pass).

    .venv/bin/python tests/benchmarks/lichtblick_screenshot.py --out docs/foxglove/session.png \
        --lichtblick PATH/web/.webpack   # prints the run folder; then, for its bag:
    .venv/bin/python tests/benchmarks/lichtblick_screenshot.py --out docs/foxglove/bag.png \
        --lichtblick PATH/web/.webpack --bag RUN
"""

import argparse
import asyncio
import base64
import datetime
import functools
import http.server
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from cdp import Browser  # noqa: E402,I100 (tests/cdp.py: Chromium over the DevTools protocol)
from graph_viewer.bag_plots import PLOTS_FILE  # noqa: E402,I100
from graph_viewer.layout import LICHTBLICK_FILE  # noqa: E402,I100
from harness import free_port  # noqa: E402,I100
from mcap.reader import make_reader  # noqa: E402,I100

BIN = Path(sys.executable).parent
LAYOUT_PATH = '/' + LICHTBLICK_FILE.name


class _Handler(http.server.SimpleHTTPRequestHandler):
    """Lichtblick's files, and ``extra`` files by path (the layout, a bag), with ranges."""

    extra: dict = {}  # '/name' -> a file to serve there

    def send_head(self):
        """Serve an extra file whole or, for ``Range: bytes=A-B``, that slice (206)."""
        path = self.path.split('?')[0]
        if path not in self.extra:
            return super().send_head()
        file = open(self.extra[path], 'rb')
        size = Path(self.extra[path]).stat().st_size
        found = re.fullmatch(r'bytes=(\d+)-(\d*)', self.headers.get('Range', ''))
        start, end = (0, size - 1) if not found else (
            int(found.group(1)), min(int(found.group(2) or size - 1), size - 1))
        file.seek(start)
        self.send_response(206 if found else 200)
        self.send_header('Content-Type', self.guess_type(self.extra[path]))
        self.send_header('Accept-Ranges', 'bytes')
        if found:
            self.send_header('Content-Range', f'bytes {start}-{end}/{size}')
        self.send_header('Content-Length', str(end - start + 1))
        self.end_headers()
        return _Slice(file, end - start + 1)

    def copyfile(self, source, outputfile):
        if isinstance(source, _Slice):
            outputfile.write(source.read())
        else:
            super().copyfile(source, outputfile)

    def log_message(self, *args):
        pass


class _Slice:
    """``length`` bytes of an open file from where it stands."""

    def __init__(self, file, length: int):
        self.file, self.length = file, length

    def read(self) -> bytes:
        return self.file.read(self.length)

    def close(self) -> None:
        self.file.close()


def _serve(directory: Path, extra: dict) -> http.server.ThreadingHTTPServer:
    """Serve ``directory`` and ``extra`` (filled in later) on 127.0.0.1, on a thread."""
    handler = functools.partial(type('Handler', (_Handler,), {'extra': extra}),
                                directory=str(directory))
    server = http.server.ThreadingHTTPServer(('127.0.0.1', 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def _start_session(steps: int, run_dir: Path) -> tuple:
    """Start the run; return (process, the bridge's URL)."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    process = subprocess.Popen(
        [str(BIN / 'attention_train'), '--realtime', '--foxglove', '--record',
         '--foxglove-port', str(free_port()),
         '--steps', str(steps), '--run-dir', str(run_dir)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    for line in process.stderr:
        found = re.search(r'Foxglove: (ws://\S+)', line)
        if found:
            threading.Thread(target=process.stderr.read, daemon=True).start()  # keep draining
            return process, found.group(1)
    raise RuntimeError(f'attention_train ended before its bridge started ({process.wait()})')


async def _shoot(url: str, profile: Path, out: Path, wait_s: float, size: tuple) -> None:
    async with Browser('about:blank', profile) as browser:
        await browser.call('Emulation.setDeviceMetricsOverride', width=size[0], height=size[1],
                           deviceScaleFactor=1, mobile=False)
        await browser.call('Page.navigate', url=url)
        await asyncio.sleep(wait_s)
        shot = await browser.call('Page.captureScreenshot', format='png')
        out.write_bytes(base64.b64decode(shot['data']))


def _bag_sources(run: Path, page: str, at_s: float) -> tuple:
    """Return ({path: file}, the ds.url values and time= of the run's bag and plot channels)."""
    bag = next((run / 'bag').glob('*.mcap'))
    plots = run / PLOTS_FILE
    if not plots.exists():
        subprocess.run([str(BIN / 'graph_viewer_plots'), str(run / 'bag')], check=True)
    with open(bag, 'rb') as file:
        statistics = make_reader(file).get_summary().statistics
    at_ns = statistics.message_start_time + int(at_s * 1e9)
    at = datetime.datetime.fromtimestamp(at_ns / 1e9, datetime.timezone.utc)
    extra = {'/' + bag.name: bag, '/' + plots.name: plots}
    query = ''.join(f'&ds.url={page}{name}' for name in extra)
    return extra, f'ds=remote-file{query}&time={at.isoformat().replace("+00:00", "Z")}'


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--lichtblick', required=True, type=Path,
                        help='a static web build of Lichtblick (its web/.webpack)')
    parser.add_argument('--out', type=Path, default=Path('lichtblick_session.png'))
    parser.add_argument('--steps', type=int, default=3000, help='the run (15 steps a second)')
    parser.add_argument('--wait', type=float, default=40.0,
                        help='seconds the page watches before the picture')
    parser.add_argument('--size', default='1600x1000', help='the window, WIDTHxHEIGHT')
    parser.add_argument('--bag', type=Path, default=None,
                        help="a recorded run's folder: show its bag instead of a live session")
    parser.add_argument('--at', type=float, default=30.0,
                        help='with --bag: where the player stands, seconds into the bag')
    args = parser.parse_args()
    if not (args.lichtblick / 'index.html').exists():
        parser.error(f'{args.lichtblick} has no index.html: pass the web build (web/.webpack)')
    size = tuple(int(v) for v in args.size.split('x'))
    work = Path(tempfile.mkdtemp(prefix='lichtblick-shot-'))
    extra = {LAYOUT_PATH: LICHTBLICK_FILE}
    server = _serve(args.lichtblick, extra)
    page = f'http://127.0.0.1:{server.server_address[1]}'
    process = None
    try:
        if args.bag:
            files, source = _bag_sources(args.bag, page, args.at)
            extra.update(files)
        else:
            process, ws_url = _start_session(args.steps, work / 'run')
            source = f'ds=foxglove-websocket&ds.url={ws_url}'
        url = f'{page}/?{source}&layoutUrl={page}{LAYOUT_PATH}'
        print(f'run {args.bag or work / "run"}, page {url}', file=sys.stderr)
        started = time.monotonic()
        asyncio.run(_shoot(url, work / 'chromium', args.out, args.wait, size))
        print(f'{args.out} after {time.monotonic() - started:.0f} s of watching', file=sys.stderr)
    finally:
        if process is not None:
            process.send_signal(signal.SIGINT)
            process.wait(timeout=60)
        server.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

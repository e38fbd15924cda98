r"""
A screenshot of a live session in Lichtblick (Foxglove Studio's open-source fork), with our layout.

Not a benchmark: the script that made the README's picture. It starts a real-time Room 1 run
with the Foxglove bridge (``attention_train --realtime --foxglove``), serves a static web build
of Lichtblick and the session layout (``layouts/attention_graph_lichtblick.json``) on
127.0.0.1, opens it in the system's Chromium with the connection and the layout in the URL
(Lichtblick's ``ds=foxglove-websocket``, ``ds.url`` and ``layoutUrl``), waits, and saves the page.

Lichtblick is not on PyPI: build its web app once from its repository
(``yarn web:build:prod``; ``web/.webpack`` is the folder to pass).

    .venv/bin/python tests/benchmarks/lichtblick_screenshot.py --out docs/foxglove/session.png \
        --lichtblick PATH/web/.webpack
"""

import argparse
import asyncio
import base64
import functools
import http.server
import os
from pathlib import Path
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from cdp import Browser  # noqa: E402,I100 (tests/cdp.py: Chromium over the DevTools protocol)
from graph_viewer.layout import LICHTBLICK_FILE  # noqa: E402,I100

BIN = Path(sys.executable).parent
LAYOUT_PATH = '/' + LICHTBLICK_FILE.name


class _Handler(http.server.SimpleHTTPRequestHandler):
    """Lichtblick's files, and the session layout at LAYOUT_PATH."""

    def translate_path(self, path):
        if path.split('?')[0] == LAYOUT_PATH:
            return str(LICHTBLICK_FILE)
        return super().translate_path(path)

    def log_message(self, *args):
        pass


def _serve(directory: Path) -> http.server.ThreadingHTTPServer:
    handler = functools.partial(_Handler, directory=str(directory))
    server = http.server.ThreadingHTTPServer(('127.0.0.1', 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def _start_session(steps: int, run_dir: Path) -> tuple:
    """Start the run; return (process, the bridge's URL)."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    process = subprocess.Popen(
        [str(BIN / 'attention_train'), '--realtime', '--foxglove',
         '--foxglove-port', str(_free_port()),
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--lichtblick', required=True, type=Path,
                        help='a static web build of Lichtblick (its web/.webpack)')
    parser.add_argument('--out', type=Path, default=Path('lichtblick_session.png'))
    parser.add_argument('--steps', type=int, default=3000, help='the run (15 steps a second)')
    parser.add_argument('--wait', type=float, default=40.0,
                        help='seconds the page watches before the picture')
    parser.add_argument('--size', default='1600x1000', help='the window, WIDTHxHEIGHT')
    args = parser.parse_args()
    if not (args.lichtblick / 'index.html').exists():
        parser.error(f'{args.lichtblick} has no index.html: pass the web build (web/.webpack)')
    size = tuple(int(v) for v in args.size.split('x'))
    work = Path(tempfile.mkdtemp(prefix='lichtblick-shot-'))
    server = _serve(args.lichtblick)
    page = f'http://127.0.0.1:{server.server_address[1]}'
    process, ws_url = _start_session(args.steps, work / 'run')
    try:
        url = (f'{page}/?ds=foxglove-websocket&ds.url={ws_url}'
               f'&layoutUrl={page}{LAYOUT_PATH}')
        print(f'session {work / "run"}, bridge {ws_url}, page {url}', file=sys.stderr)
        started = time.monotonic()
        asyncio.run(_shoot(url, work / 'chromium', args.out, args.wait, size))
        print(f'{args.out} after {time.monotonic() - started:.0f} s of watching', file=sys.stderr)
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(timeout=60)
        server.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""
A real headless Chromium driven over the DevTools protocol (CDP), for the console's tests.

No browser download: the system's ``chromium`` (Debian's package; ``.ci/run`` installs it).
Started with everything that would reach beyond this machine switched off.
"""

import asyncio
import itertools
import json
from pathlib import Path
import shutil
import subprocess
import time
from typing import Optional

import aiohttp

CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser')
QUIET = ('--headless=new', '--no-sandbox', '--disable-gpu', '--no-first-run',
         '--disable-background-networking', '--disable-component-update', '--disable-sync',
         '--disable-default-apps', '--disable-extensions', '--metrics-recording-only',
         '--remote-debugging-address=127.0.0.1', '--remote-debugging-port=0')
KEYS = {'ArrowUp': 38, 'ArrowDown': 40, 'Enter': 13}


class Browser:
    """One Chromium process with one page; ``async with Browser(url, profile_dir)``."""

    def __init__(self, url: str, profile_dir: Path):
        self.url = url
        self.profile_dir = Path(profile_dir)
        self.process: Optional[subprocess.Popen] = None
        self._ids = itertools.count(1)
        self._session = self._socket = None

    async def __aenter__(self) -> 'Browser':
        self.profile_dir.mkdir(parents=True, exist_ok=True)
        (self.profile_dir / 'DevToolsActivePort').unlink(missing_ok=True)  # an earlier one's
        self.process = subprocess.Popen(
            [CHROMIUM, *QUIET, f'--user-data-dir={self.profile_dir}', self.url],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = self.profile_dir / 'DevToolsActivePort'
        deadline = time.monotonic() + 30
        while not port_file.exists() or not port_file.read_text().strip():
            if time.monotonic() > deadline or self.process.poll() is not None:
                raise RuntimeError('chromium did not open its DevTools port')
            await asyncio.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        self._session = aiohttp.ClientSession()
        page = None
        while page is None and time.monotonic() < deadline:
            async with self._session.get(f'http://127.0.0.1:{port}/json/list') as response:
                targets = await response.json()
            page = next((t for t in targets if t.get('type') == 'page'), None)
            await asyncio.sleep(0.1)
        self._socket = await self._session.ws_connect(page['webSocketDebuggerUrl'],
                                                      max_msg_size=0)
        return self

    async def __aexit__(self, *exc) -> None:
        if self._socket is not None:
            await self._socket.close()
        if self._session is not None:
            await self._session.close()
        if self.process is not None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()

    async def call(self, method: str, **params) -> dict:
        ident = next(self._ids)
        await self._socket.send_str(json.dumps({'id': ident, 'method': method,
                                                'params': params}))
        while True:
            message = await self._socket.receive_json(timeout=30)
            if message.get('id') == ident:
                if 'error' in message:
                    raise RuntimeError(f'{method}: {message["error"]}')
                return message.get('result', {})

    async def evaluate(self, expression: str):
        result = await self.call('Runtime.evaluate', expression=expression, returnByValue=True)
        return result.get('result', {}).get('value')

    async def wait_for(self, expression: str, timeout: float = 20.0) -> bool:
        """Wait until ``expression`` is truthy in the page."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if await self.evaluate(expression):
                return True
            await asyncio.sleep(0.1)
        return False

    async def press(self, key: str) -> None:
        """Press and release one key as a person would (keydown with its text, keyup)."""
        code = KEYS.get(key, 0)
        text = {'Enter': '\r'}.get(key, key if len(key) == 1 else '')
        down = {'type': 'keyDown', 'key': key, 'windowsVirtualKeyCode': code or ord(key[0])}
        if text:
            down['text'] = text
        await self.call('Input.dispatchKeyEvent', **down)
        await self.call('Input.dispatchKeyEvent', type='keyUp', key=key,
                        windowsVirtualKeyCode=down['windowsVirtualKeyCode'])

    async def type_text(self, text: str) -> None:
        await self.call('Input.insertText', text=text)

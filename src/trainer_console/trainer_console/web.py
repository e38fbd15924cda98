"""
The console's web server (aiohttp, on a thread of its own with its own asyncio loop).

``GET /`` is the page, ``/static/*`` its script, ``GET /ws`` a websocket: the server sends
frames as binary messages (one byte, ``F`` frame or ``S`` saliency image, then the JPEG) as
they come, at most 2 x ``frame_rate_hz``, and the state as JSON text 4 times a second; the page
sends JSON commands (``feedback``, ``utterance``, ``pause``, ``resume``), handed to
``on_command``. With a token, every request must carry ``?token=...``.
"""

import asyncio
import hmac
import json
from pathlib import Path
import threading
from typing import Callable, Optional

from aiohttp import web, WSMsgType

STATIC = Path(__file__).resolve().parent / 'static'
STATE_PERIOD_S = 0.25
KIND_BYTES = {'frame': b'F', 'saliency': b'S'}


class Frames:
    """The newest JPEG of each kind, with a version number (written by rclpy callbacks)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._latest = {kind: (0, b'') for kind in KIND_BYTES}

    def put(self, kind: str, jpeg: bytes) -> None:
        with self._lock:
            version = self._latest[kind][0] + 1
            self._latest[kind] = (version, jpeg)

    def newer(self, seen: dict) -> list:
        """Return [(kind, jpeg)] newer than ``seen`` ({kind: version}), updating ``seen``."""
        out = []
        with self._lock:
            for kind, (version, jpeg) in self._latest.items():
                if version > seen.get(kind, 0):
                    seen[kind] = version
                    out.append((kind, jpeg))
        return out


class ConsoleServer:
    """Serves the page and its websockets until ``stop``."""

    def __init__(self, host: str, port: int, frames: Frames, snapshot: Callable[[], dict],
                 on_command: Callable[[dict], dict], frame_rate_hz: float,
                 token: Optional[str] = None, log: Callable[[str], None] = print):
        self.host, self.port = host, port
        self.frames, self.snapshot, self.on_command = frames, snapshot, on_command
        self.poll_period = 0.5 / frame_rate_hz  # new frames go out within half a period
        self.token = token
        self._log = log
        self._loop = asyncio.new_event_loop()
        self._runner: Optional[web.AppRunner] = None
        self._thread = threading.Thread(target=self._loop.run_forever, name='console-web',
                                        daemon=True)
        self.clients = 0

    def start(self) -> int:
        """Bind and serve; return the port (the actual one when 0 was asked)."""
        self._thread.start()
        return asyncio.run_coroutine_threadsafe(self._start(), self._loop).result(timeout=30)

    async def _start(self) -> int:
        app = web.Application()
        app.add_routes([web.get('/', self._page), web.get('/ws', self._socket),
                        web.static('/static', STATIC)])
        app.middlewares.append(self._check_token)
        self._runner = web.AppRunner(app, access_log=None)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        await site.start()
        return self._runner.addresses[0][1]

    def stop(self) -> None:
        if self._runner is not None:
            asyncio.run_coroutine_threadsafe(self._runner.cleanup(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10)

    @web.middleware
    async def _check_token(self, request, handler):
        if self.token is not None:
            given = request.query.get('token', '')
            if not hmac.compare_digest(given.encode(), self.token.encode()):
                return web.Response(status=403, text='a token is required: ?token=...')
        return await handler(request)

    async def _page(self, request) -> web.StreamResponse:
        return web.FileResponse(STATIC / 'index.html')

    async def _socket(self, request) -> web.WebSocketResponse:
        socket = web.WebSocketResponse(heartbeat=10.0, max_msg_size=64 * 1024)
        await socket.prepare(request)
        self.clients += 1
        sender = asyncio.ensure_future(self._send(socket))
        try:
            async for message in socket:
                if message.type != WSMsgType.TEXT:
                    continue
                try:
                    command = json.loads(message.data)
                    if not isinstance(command, dict):
                        raise ValueError('a command is a JSON object')
                except ValueError as error:
                    await socket.send_json({'type': 'error', 'error': f'bad command: {error}'})
                    continue
                reply = await self._loop.run_in_executor(None, self.on_command, command)
                await socket.send_json(dict(reply, type='reply', id=command.get('id')))
        finally:
            sender.cancel()
            self.clients -= 1
        return socket

    async def _send(self, socket) -> None:
        seen, last_state = {}, 0.0
        try:
            while not socket.closed:
                for kind, jpeg in self.frames.newer(seen):
                    await socket.send_bytes(KIND_BYTES[kind] + jpeg)
                now = self._loop.time()
                if now - last_state >= STATE_PERIOD_S:
                    last_state = now
                    await socket.send_str(json.dumps(dict(self.snapshot(), type='state'),
                                                     allow_nan=False))
                await asyncio.sleep(self.poll_period)
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        except Exception as error:  # a broken client must not stop the others
            self._log(f'a browser connection failed: {error!r}')

"""
The console's web server (aiohttp, on a thread of its own with its own asyncio loop).

``GET /`` is the page, ``/static/*`` its script, ``GET /ws`` a websocket: the server sends
frames as binary messages (one byte, ``F`` frame or ``S`` saliency image, the image's stamp in
ns as 8 bytes big-endian, then the JPEG) as they come, at most 2 x ``frame_rate_hz``; the state
as JSON text 4 times a second; and the learner's view of the frame just sent (``view(stamp)``:
its H, the credit strip) as JSON text ``{"type": "view", ...}`` after a new frame, at most
``frame_rate_hz``, and 4 times a second (an H that came after its frame replaces an older one).
The page sends JSON commands (``feedback``, ``utterance``, ``pause``, ``resume``, ``step``,
``skip``), handed to ``on_command``. With a token, every request must carry ``?token=...``.
"""

import asyncio
import hmac
import json
from pathlib import Path
import struct
import threading
from typing import Callable, Optional
import weakref

from aiohttp import web, WSCloseCode, WSMsgType

STATIC = Path(__file__).resolve().parent / 'static'
STATE_PERIOD_S = 0.25
KIND_BYTES = {'frame': b'F', 'saliency': b'S'}
STAMP = struct.Struct('>Q')
"""The image's stamp (ns) after the kind byte: the page pairs the frame with its step's H."""


class Frames:
    """The newest JPEG of each kind, with its stamp and a version (written by rclpy callbacks)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._latest = {kind: (0, 0, b'') for kind in KIND_BYTES}

    def put(self, kind: str, jpeg: bytes, stamp_ns: int = 0) -> None:
        with self._lock:
            version = self._latest[kind][0] + 1
            self._latest[kind] = (version, min(max(int(stamp_ns), 0), 2**64 - 1), jpeg)

    def newer(self, seen: dict) -> list:
        """Return [(kind, stamp, jpeg)] newer than ``seen`` ({kind: version}), updating it."""
        out = []
        with self._lock:
            for kind, (version, stamp, jpeg) in self._latest.items():
                if version > seen.get(kind, 0):
                    seen[kind] = version
                    out.append((kind, stamp, jpeg))
        return out


class ConsoleServer:
    """Serves the page and its websockets until ``stop``."""

    def __init__(self, host: str, port: int, frames: Frames, snapshot: Callable[[], dict],
                 on_command: Callable[[dict], dict], frame_rate_hz: float,
                 token: Optional[str] = None, log: Callable[[str], None] = print,
                 view: Optional[Callable[[Optional[int]], dict]] = None):
        self.host, self.port = host, port
        self.frames, self.snapshot, self.on_command = frames, snapshot, on_command
        self.view = view
        self.poll_period = 0.5 / frame_rate_hz  # new frames go out within half a period
        self.view_period = 1.0 / frame_rate_hz
        self.token = token
        self._log = log
        self._loop = asyncio.new_event_loop()
        self._runner: Optional[web.AppRunner] = None
        self._thread = threading.Thread(target=self._loop.run_forever, name='console-web',
                                        daemon=True)
        self.clients = 0
        self._sockets: 'weakref.WeakSet[web.WebSocketResponse]' = weakref.WeakSet()

    def start(self) -> int:
        """Bind and serve; return the port (the actual one when 0 was asked)."""
        self._thread.start()
        return asyncio.run_coroutine_threadsafe(self._start(), self._loop).result(timeout=30)

    async def _start(self) -> int:
        app = web.Application()
        app.add_routes([web.get('/', self._page), web.get('/ws', self._socket),
                        web.static('/static', STATIC)])
        app.middlewares.append(self._check_token)
        app.on_shutdown.append(self._close_sockets)  # else cleanup waits for every open tab
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

    async def _close_sockets(self, app) -> None:
        for socket in list(self._sockets):
            await socket.close(code=WSCloseCode.GOING_AWAY, message=b'the console stops')

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
        self._sockets.add(socket)
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
        seen, last_state, last_view = {}, 0.0, 0.0
        shown, view_due = None, True  # the stamp of the frame this page shows
        try:
            while not socket.closed:
                for kind, stamp, jpeg in self.frames.newer(seen):
                    await socket.send_bytes(KIND_BYTES[kind] + STAMP.pack(stamp) + jpeg)
                    if kind == 'frame':
                        shown, view_due = stamp, True
                now = self._loop.time()
                if self.view is not None and (
                        view_due and now - last_view >= self.view_period
                        or now - last_view >= STATE_PERIOD_S):
                    last_view, view_due = now, False
                    await socket.send_str(json.dumps(dict(self.view(shown), type='view'),
                                                     allow_nan=False))
                if now - last_state >= STATE_PERIOD_S:
                    last_state = now
                    await socket.send_str(json.dumps(dict(self.snapshot(), type='state'),
                                                     allow_nan=False))
                await asyncio.sleep(self.poll_period)
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        except Exception as error:  # a broken client must not stop the others
            self._log(f'a browser connection failed: {error!r}')

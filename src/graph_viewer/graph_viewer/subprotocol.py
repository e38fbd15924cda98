"""
Both names of the Foxglove WebSocket protocol on one port.

foxglove-sdk serves the protocol as ``foxglove.sdk.v1`` only; Lichtblick before 1.22 and other
clients written for it offer only ``foxglove.websocket.v1``, the same protocol under its first
name (Foxglove's own statement), and the SDK answers them 400. ``Relay`` listens on the public
port, renames the one header in the client's handshake for the SDK (on a private loopback
port) and back in the SDK's answer, then copies bytes both ways untouched. A client that offers
``foxglove.sdk.v1`` gets exactly what the SDK says. The rewrite is pure and tested
(``rewrite_request``, ``rewrite_response``).
"""

import asyncio
import re
import threading
from typing import Optional, Tuple

SDK = 'foxglove.sdk.v1'
LEGACY = 'foxglove.websocket.v1'
MAX_HEADER_BYTES = 16 * 1024
_PROTOCOL = re.compile(rb'^(sec-websocket-protocol:[ \t]*)([^\r\n]*)\r\n', re.I | re.M)


def rewrite_request(head: bytes) -> Tuple[bytes, bool]:
    """
    Return the client's handshake as the SDK accepts it, and whether it was renamed.

    Only a request that offers ``foxglove.websocket.v1`` and not ``foxglove.sdk.v1`` changes:
    that offer becomes ``foxglove.sdk.v1``.
    """
    found = _PROTOCOL.search(head)
    if found is None:
        return head, False
    offered = [name.strip() for name in found.group(2).decode('latin-1').split(',')]
    if SDK in offered or LEGACY not in offered:
        return head, False
    renamed = ', '.join(SDK if name == LEGACY else name for name in offered).encode()
    return head[:found.start(2)] + renamed + head[found.end(2):], True


def rewrite_response(head: bytes) -> bytes:
    """Return the SDK's handshake answer naming ``foxglove.websocket.v1`` instead."""
    return _PROTOCOL.sub(lambda m: m.group(1) + LEGACY.encode() + b'\r\n', head, count=1)


async def _read_head(reader: asyncio.StreamReader) -> bytes:
    return await reader.readuntil(b'\r\n\r\n')


async def _pump(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    try:
        while data := await reader.read(256 * 1024):
            writer.write(data)
            await writer.drain()
    except (ConnectionError, asyncio.CancelledError):
        pass
    finally:
        writer.close()


class Relay:
    """The public port: every connection relayed to the SDK's private one (its own thread)."""

    def __init__(self, host: str, port: int, target_port: int):
        self.host, self.port, self.target_port = host, port, target_port
        self.errors = 0
        self._loop = asyncio.new_event_loop()
        self._server: Optional[asyncio.base_events.Server] = None
        self._thread = threading.Thread(target=self._loop.run_forever, name='foxglove-relay',
                                        daemon=True)

    def start(self) -> int:
        """Listen (OSError if the port is taken); return the port."""
        self._thread.start()
        self._server = asyncio.run_coroutine_threadsafe(
            asyncio.start_server(self._serve, self.host, self.port, limit=MAX_HEADER_BYTES),
            self._loop).result(10.0)
        self.port = self._server.sockets[0].getsockname()[1]
        return self.port

    def stop(self) -> None:
        if self._server is not None:
            self._loop.call_soon_threadsafe(self._server.close)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(2.0)

    async def _serve(self, client_reader, client_writer) -> None:
        try:
            head, legacy = rewrite_request(await _read_head(client_reader))
            sdk_reader, sdk_writer = await asyncio.open_connection('127.0.0.1', self.target_port)
            sdk_writer.write(head)
            answer = await _read_head(sdk_reader)
            client_writer.write(rewrite_response(answer) if legacy else answer)
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
            self.errors += 1
            client_writer.close()
            return
        await asyncio.gather(_pump(client_reader, sdk_writer), _pump(sdk_reader, client_writer))

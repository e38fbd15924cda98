"""
A client of the Foxglove WebSocket protocol (``foxglove.websocket.v1``), for the tests.

It speaks as the Foxglove app does: the server's ``serverInfo`` and ``advertise`` (JSON text),
the client's ``subscribe``, then binary message data (opcode 1, subscription id u32, log time
u64, payload; little-endian). Written here from the protocol's published description.
"""

import asyncio
import json
import struct
import time
from typing import Dict, List, NamedTuple

import aiohttp

SUBPROTOCOL = 'foxglove.websocket.v1'
SDK_SUBPROTOCOL = 'foxglove.sdk.v1'
"""The same protocol under the name foxglove-sdk gives it (the Foxglove app offers both)."""
MESSAGE_DATA = 0x01


class Received(NamedTuple):
    topic: str
    log_time: int
    payload: bytes
    arrived: float
    """time.monotonic() when the client read it."""


class FoxgloveClient:
    """One connection: ``channels`` by topic once advertised; ``received`` as subscribed."""

    def __init__(self, url: str, protocols=(SUBPROTOCOL,)):
        self.url = url
        self.protocols = tuple(protocols)
        self.server_info: dict = {}
        self.channels: Dict[str, dict] = {}
        self.received: List[Received] = []
        self.protocol = None
        self._subscriptions: Dict[int, str] = {}

    async def __aenter__(self):
        self._session = aiohttp.ClientSession()
        try:
            self._ws = await self._session.ws_connect(self.url, protocols=self.protocols)
        except BaseException:
            await self._session.close()
            raise
        self.protocol = self._ws.protocol
        return self

    async def __aexit__(self, *exc):
        await self._ws.close()
        await self._session.close()

    async def wait_for_channels(self, topics, timeout: float) -> bool:
        """Read the server's text messages until every topic in ``topics`` is advertised."""
        deadline = time.monotonic() + timeout
        while not set(topics) <= set(self.channels):
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            try:
                await self._read_one(left)
            except asyncio.TimeoutError:
                return False
        return True

    async def subscribe(self, topics) -> None:
        subscriptions = []
        for topic in topics:
            sub_id = len(self._subscriptions) + 1
            self._subscriptions[sub_id] = topic
            subscriptions.append({'id': sub_id, 'channelId': self.channels[topic]['id']})
        await self._ws.send_str(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))

    async def read_for(self, seconds: float) -> None:
        """Read whatever comes for ``seconds``."""
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            try:
                await self._read_one(left)
            except asyncio.TimeoutError:
                return

    def of(self, topic: str) -> List[Received]:
        return [message for message in self.received if message.topic == topic]

    async def _read_one(self, timeout: float) -> None:
        message = await self._ws.receive(timeout=timeout)
        if message.type == aiohttp.WSMsgType.TEXT:
            data = json.loads(message.data)
            if data.get('op') == 'serverInfo':
                self.server_info = data
            elif data.get('op') == 'advertise':
                for channel in data['channels']:
                    self.channels[channel['topic']] = channel
            elif data.get('op') == 'unadvertise':
                gone = set(data['channelIds'])
                self.channels = {topic: channel for topic, channel in self.channels.items()
                                 if channel['id'] not in gone}
        elif message.type == aiohttp.WSMsgType.BINARY:
            data = message.data
            if data[0] == MESSAGE_DATA:
                sub_id, log_time = struct.unpack_from('<IQ', data, 1)
                self.received.append(Received(self._subscriptions[sub_id], log_time,
                                              bytes(data[13:]), time.monotonic()))
        elif message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED,
                              aiohttp.WSMsgType.ERROR):
            raise ConnectionError(f'the server closed the connection ({message.type})')

"""The viewer's parameters, in one dataclass (each field is a ROS parameter of that name)."""

from dataclasses import dataclass

from attention_common.isolation import is_loopback_host

DEFAULT_PORT = 8765
"""Foxglove's own default for a WebSocket data source (``ws://127.0.0.1:8765``)."""


@dataclass
class ViewerConfig:
    """Where the Foxglove bridge serves, and how much it sends."""

    host: str = '127.0.0.1'
    """Address the WebSocket server binds to; anything but loopback also needs
    allow_remote:=true."""
    port: int = DEFAULT_PORT
    """TCP port (0: any free one, printed at start-up)."""
    allow_remote: bool = False
    """Serve a non-loopback host. The bridge is read-only (clients cannot publish or call), but
    anyone who reaches the port sees the session: prefer an SSH tunnel (README)."""
    max_image_rate_hz: float = 30.0
    """Most frames per second forwarded per image topic (a lockstep run steps at 200/s; 0: all).
    Real time (15 Hz) is below it: every frame goes."""
    max_step_rate_hz: float = 30.0
    """Most per-step messages a second forwarded per topic (status, action, H: forwarded.PER_STEP;
    0: all). Feedback, utterances, receipts, credit and metrics always go whole."""
    poll_hz: float = 60.0
    """How often the watched topics are read (a frame waits at most 1/poll_hz to be sent)."""
    task: str = 'montezuma'
    """The task taught: its milestones (Room 1's critical positions, DoorKey's sub-goals) in
    the env status channel."""
    legacy_subprotocol: bool = True
    """Also serve clients that offer only the protocol's first name, foxglove.websocket.v1
    (Lichtblick before 1.22): foxglove-sdk names it foxglove.sdk.v1 only, so a small relay in
    front renames the one header (subprotocol.py). false: the SDK serves the port itself."""
    nice: int = 10
    """Niceness added to every thread of the viewer (0-19): on busy cores the graph's own
    processes get the CPU first and the viewer what they leave (0: equal). The frames it sends
    come late under load; feedback and words are still taken whole, in order."""
    message_backlog: int = 256
    """Messages buffered per client; a slow client loses the oldest, never the graph's time."""

    def validate(self) -> None:
        """Raise ValueError naming the first impossible value."""
        if not 0 <= self.port <= 65535:
            raise ValueError(f'port must be 0..65535, got {self.port}')
        for name in ('max_image_rate_hz', 'max_step_rate_hz'):
            if not getattr(self, name) >= 0:
                raise ValueError(f'{name} must be >= 0, got {getattr(self, name)}')
        if not 0 <= self.nice <= 19:
            raise ValueError(f'nice must be within 0..19, got {self.nice}')
        if not self.poll_hz > 0:
            raise ValueError(f'poll_hz must be > 0, got {self.poll_hz}')
        if self.message_backlog < 1:
            raise ValueError(f'message_backlog must be at least 1, got {self.message_backlog}')
        if not self.loopback and not self.allow_remote:
            raise ValueError(f'host {self.host!r} is not loopback: the session would be open to '
                             'your network; pass allow_remote:=true to mean it (or keep '
                             '127.0.0.1 and tunnel: ssh -L 8765:127.0.0.1:8765 HOST)')

    @property
    def loopback(self) -> bool:
        """Tell whether ``host`` only ever reaches this machine."""
        return is_loopback_host(self.host)

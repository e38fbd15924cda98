"""The console's parameters, in one dataclass (each field is a ROS parameter of that name)."""

from dataclasses import dataclass

from attention_common.isolation import is_loopback_host

DEFAULT_PORT = 8080


@dataclass
class ConsoleConfig:
    """Where the console serves its page, and what it shows."""

    host: str = '127.0.0.1'
    """Address the web server binds to; anything but loopback also needs allow_remote:=true."""
    port: int = DEFAULT_PORT
    """TCP port of the page (0: any free one, printed at start-up)."""
    allow_remote: bool = False
    """Serve a non-loopback host; then every request needs the token printed at start-up."""
    token: str = ''
    """The token remote browsers must send (?token=...); '' = a new random one per start."""
    frame_rate_hz: float = 15.0
    """Most frames per second sent to each browser (the env's real-time rate)."""
    jpeg_quality: int = 85
    """JPEG quality of the frames sent (1-100)."""
    env_node: str = 'env_node'
    """Name of the env node whose ``paused`` parameter the pause button sets."""
    press_times: bool = True
    """true: each key press goes on ``feedback_pressed`` with the moment it was given (the
    frame on screen plus the time since it appeared, ``press_time.py``), and the learner
    credits it from then. false: plain on ``feedback``. Either way a press while the env is
    paused follows ``judge_paused_frame``."""
    judge_paused_frame: bool = True
    """true: while the env is paused a key press judges the frame on screen, the step whose H
    and action the page shows: it goes on ``feedback_stamped`` stamped with that frame, and
    the learner credits exactly that step. false: plain on ``feedback`` (the learner's window
    then falls on the steps 0.2 s and more before the paused frame, never on it)."""
    answer_questions: bool = True
    """true: the learner's questions (tamer_node ``ask_rate``, topic ``question``) are shown one
    at a time: the env is paused, the asked frame is put on screen with its H, and a press
    answers it on ``feedback_stamped``, stamped with that step (``0`` or Escape skips it); the
    env resumes after the last. false: questions are counted, not shown."""
    task: str = 'montezuma'
    """The task taught: what utterances can name (its template manifest) and its milestones
    (Room 1's critical positions, DoorKey's sub-goals)."""

    def validate(self) -> None:
        """Raise ValueError naming the first impossible value."""
        if not 0 <= self.port <= 65535:
            raise ValueError(f'port must be 0..65535, got {self.port}')
        if not self.frame_rate_hz > 0:
            raise ValueError(f'frame_rate_hz must be > 0, got {self.frame_rate_hz}')
        if not 1 <= self.jpeg_quality <= 100:
            raise ValueError(f'jpeg_quality must be 1..100, got {self.jpeg_quality}')
        if not self.loopback and not self.allow_remote:
            raise ValueError(f'host {self.host!r} is not loopback: the console would be open to '
                             'your network; pass allow_remote:=true to mean it (a token is '
                             'then required)')

    @property
    def loopback(self) -> bool:
        """Tell whether ``host`` only ever reaches this machine."""
        return is_loopback_host(self.host)

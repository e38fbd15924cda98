"""
The node's parameters in one dataclass: names, defaults, descriptions, and their checking.

Numbers accept an integer or a float (``-p utterance_ttl:=5`` and ``:=5.0`` both work), and
``mode`` accepts the boolean false that YAML makes of ``off``. No rclpy.
"""

from dataclasses import dataclass, fields
import functools
from pathlib import Path
from typing import Mapping

from attention_common.preview import PREVIEW_RATE_HZ
from attention_common.recorder_gate import RECORDER_WAIT_S
from attention_common.stamps import MAX_STAMP_JUMP_S, NS_PER_S
from attention_common.utterance import MAX_UTTERANCE_CHARS
from attention_tasks.task import DEFAULT_TASK, load_task, Task

from saliency_node.manifest import DEFAULT_MANIFEST
from saliency_node.matching import method_from_name
from saliency_node.saliency import SaliencyConfig

START_ONLY = ('task', 'templates_manifest', 'status_period', 'wait_for_recorder',
              'wait_for_recorder_s', 'preview_rate_hz')
"""Read at start only; every other parameter is settable at run time."""


def _number(name: str, value, low: float, integer: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f'{name} must be a number, got {value!r}')
    if integer and int(value) != value:
        raise ValueError(f'{name} must be a whole number, got {value!r}')
    if value < low:
        raise ValueError(f'{name} must be at least {low}, got {value!r}')
    return int(value) if integer else float(value)


def _flag(name: str, value) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f'{name} must be true or false, got {value!r}')
    return value


@dataclass
class Settings(SaliencyConfig):
    """
    Each field is a ROS parameter of the same name; its docstring is the description.

    The saliency image's (``SaliencyConfig``), then the node's. Checked on construction.
    """

    utterance_ttl: float = 10.0
    """Simulation seconds an utterance stays valid from its stamp (the synthetic trainer speaks
    every 10 s)."""
    require_utterance: bool = True
    """false: every observation gets a saliency image, the agent alone when no utterance is
    valid (blind_agent and hidden_agent conditions)."""
    match_method: str = 'TM_CCORR_NORMED'
    """cv2.matchTemplate method: TM_CCORR_NORMED (equation 3.1), TM_CCOEFF_NORMED or
    TM_SQDIFF_NORMED."""
    task: str = DEFAULT_TASK
    """The task (attention_tasks.<task>): its frame size, and its template manifest unless
    templates_manifest names one. Read at start only."""
    templates_manifest: str = ''
    """Template manifest YAML; empty: the task's (montezuma: the packaged one, Room 1). Read
    at start only."""
    observation_buffer: int = 64
    """Observations held while waiting for a late stamped utterance."""
    max_utterance_chars: int = MAX_UTTERANCE_CHARS
    """Longer utterances are logged and dropped."""
    stamped_stream_timeout: float = 5.0
    """Wall seconds after a stamped utterance during which a plain utterance of the same text
    is taken as its copy and not used twice."""
    max_stamp_jump: float = MAX_STAMP_JUMP_S
    """Simulation seconds: an observation or stamped utterance stamped further than this from
    the newest observation is dropped with a warning (3 such observations in a row that
    continue each other: the env started over)."""
    publish_mask: bool = True
    """Also publish the mask (mono8, 0 or 255) on saliency_mask."""
    preview_rate_hz: float = PREVIEW_RATE_HZ
    """Most images a wall second on saliency/preview and saliency_mask/preview, the copies a
    viewer reads (attention_common.preview: sent only while someone subscribes; real time's
    every step passes); 0 = no preview topics. Read at start only."""
    status_period: float = 30.0
    """Wall seconds between the log lines of counts. Read at start only."""
    wait_for_recorder: str = ''
    """Start-up: the node name of a session recorder (the launcher's session_recorder when it
    records; '' = none). No saliency image or mask goes out until that node is matched on
    both topics, so the bag misses none; they wait, in order. Read at start only."""
    wait_for_recorder_s: float = RECORDER_WAIT_S
    """Longest start-up wait for that recorder, in wall seconds; then publish anyway, with a
    warning. Read at start only."""

    def __post_init__(self):
        """Check every value, numbers made int or float; ``ValueError`` says which and why."""
        self.utterance_ttl = _number('utterance_ttl', self.utterance_ttl, 0.0)
        if self.utterance_ttl <= 0.0:
            raise ValueError(f'utterance_ttl must be positive, got {self.utterance_ttl}')
        if not isinstance(self.templates_manifest, str):
            raise ValueError('templates_manifest must be a path')
        if not isinstance(self.task, str):
            raise ValueError(f'task must be a task name, got {self.task!r}')
        self.task_spec: Task = load_task(self.task)
        """The ``Task`` that ``task`` names; UnknownTask (a ValueError) names the installed."""
        self.blur_radius = _number('blur_radius', self.blur_radius, 0, True)
        self.blur_sigma = _number('blur_sigma', self.blur_sigma, 0.0)
        self.fade = _number('fade', self.fade, 0.0)
        super().__post_init__()  # the mode, and the ranges of the blur and the fade
        method_from_name(self.match_method)
        _flag('require_utterance', self.require_utterance)
        self.observation_buffer = _number('observation_buffer', self.observation_buffer, 1, True)
        self.max_utterance_chars = _number('max_utterance_chars', self.max_utterance_chars, 1,
                                           True)
        self.stamped_stream_timeout = _number('stamped_stream_timeout',
                                              self.stamped_stream_timeout, 0.0)
        self.max_stamp_jump = _number('max_stamp_jump', self.max_stamp_jump, 1e-3)
        _flag('publish_mask', self.publish_mask)
        self.preview_rate_hz = _number('preview_rate_hz', self.preview_rate_hz, 0.0)
        self.status_period = _number('status_period', self.status_period, 0.001)
        if not isinstance(self.wait_for_recorder, str):
            raise ValueError(
                f'wait_for_recorder must be a node name, got {self.wait_for_recorder!r}')
        self.wait_for_recorder_s = _number('wait_for_recorder_s', self.wait_for_recorder_s, 0.0)

    @classmethod
    def from_values(cls, values: Mapping) -> 'Settings':
        """Check ``values``: missing names keep their defaults, others (use_sim_time) skipped."""
        return cls(**{f.name: values[f.name] for f in fields(cls) if f.name in values})

    @property
    def manifest_path(self) -> Path:
        """Return the manifest to read: templates_manifest, the task's, or the packaged one."""
        if self.templates_manifest:
            return Path(self.templates_manifest)
        return self.task_spec.manifest or DEFAULT_MANIFEST

    @functools.cached_property
    def saliency(self) -> SaliencyConfig:
        """Return the saliency image's part, as ``SaliencyMaker.render`` takes it."""
        return SaliencyConfig(**{f.name: getattr(self, f.name) for f in fields(SaliencyConfig)})

    @property
    def method(self) -> int:
        """Return the cv2 constant of ``match_method``."""
        return method_from_name(self.match_method)

    @property
    def ttl_ns(self) -> int:
        return int(round(self.utterance_ttl * NS_PER_S))

    @property
    def max_stamp_jump_ns(self) -> int:
        return int(round(self.max_stamp_jump * NS_PER_S))

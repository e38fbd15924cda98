"""
The node's parameters: names, defaults, descriptions, and their checking (no rclpy).

Numbers accept an integer or a float (``-p utterance_ttl:=5`` and ``:=5.0`` both work), and
``mode`` accepts the boolean false that YAML makes of ``off``.
"""

from dataclasses import dataclass
from typing import Mapping

from attention_common.stamps import MAX_STAMP_JUMP_S
from attention_common.utterance import MAX_UTTERANCE_CHARS

from saliency_node.matching import method_from_name
from saliency_node.saliency import MODES, SaliencyConfig

PARAMETERS = (
    ('mode', 'language', f'One of {", ".join(MODES)}; settable at run time (`-p mode:=off` '
     'arrives as a boolean false and means off).'),
    ('blur_radius', 3, 'Gaussian blur radius r in pixels (kernel 2r+1); run-time settable.'),
    ('blur_sigma', 0.0, 'Blur standard deviation; 0 means blur_radius / 2.'),
    ('fade', 0.3, 'Brightness kept outside the mask in faded mode.'),
    ('utterance_ttl', 10.0, 'Simulation seconds an utterance stays valid from its stamp '
     '(the synthetic trainer speaks every 10 s).'),
    ('require_utterance', True, 'false: every observation gets a saliency image, the agent '
     'alone when no utterance is valid (blind_agent and hidden_agent conditions).'),
    ('match_method', 'TM_CCORR_NORMED', 'cv2.matchTemplate method: TM_CCORR_NORMED '
     '(equation 3.1), TM_CCOEFF_NORMED or TM_SQDIFF_NORMED.'),
    ('templates_manifest', '', "Template manifest YAML; empty: the packaged one (Montezuma's "
     'Revenge, Room 1). Read at start only.'),
    ('observation_buffer', 64, 'Observations held while waiting for a late stamped utterance.'),
    ('max_utterance_chars', MAX_UTTERANCE_CHARS, 'Longer utterances are logged and dropped.'),
    ('stamped_stream_timeout', 5.0, 'Wall seconds after a stamped utterance during which a plain '
     'utterance of the same text is taken as its copy and not used twice.'),
    ('max_stamp_jump', MAX_STAMP_JUMP_S, 'Simulation seconds: an observation or stamped '
     'utterance stamped further than this from the newest observation is dropped with a warning '
     '(3 such observations in a row that continue each other: the env started over).'),
    ('publish_mask', True, 'Also publish the mask (mono8, 0 or 255) on saliency_mask.'),
    ('status_period', 30.0, 'Wall seconds between the log lines of counts. Read at start only.'),
)
DEFAULTS = {name: default for name, default, _ in PARAMETERS}


def _number(values: Mapping, name: str, low: float, integer: bool = False) -> float:
    value = values[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f'{name} must be a number, got {value!r}')
    if integer and int(value) != value:
        raise ValueError(f'{name} must be a whole number, got {value!r}')
    if value < low:
        raise ValueError(f'{name} must be at least {low}, got {value!r}')
    return int(value) if integer else float(value)


def _flag(values: Mapping, name: str) -> bool:
    if not isinstance(values[name], bool):
        raise ValueError(f'{name} must be true or false, got {values[name]!r}')
    return values[name]


@dataclass(frozen=True)
class Settings:
    """Checked parameter values."""

    saliency: SaliencyConfig
    method: int
    ttl_ns: int
    require_utterance: bool
    observation_buffer: int
    max_utterance_chars: int
    stamped_stream_timeout: float
    max_stamp_jump_ns: int
    publish_mask: bool
    templates_manifest: str
    status_period: float

    @classmethod
    def from_values(cls, values: Mapping) -> 'Settings':
        """Check every parameter; ``ValueError`` says which one is wrong and why."""
        values = {**DEFAULTS, **values}
        ttl = _number(values, 'utterance_ttl', 0.0)
        if ttl <= 0.0:
            raise ValueError(f'utterance_ttl must be positive, got {ttl}')
        if not isinstance(values['templates_manifest'], str):
            raise ValueError('templates_manifest must be a path')
        return cls(
            saliency=SaliencyConfig(
                mode=values['mode'], blur_radius=_number(values, 'blur_radius', 0, True),
                blur_sigma=_number(values, 'blur_sigma', 0.0), fade=_number(values, 'fade', 0.0)),
            method=method_from_name(values['match_method']),
            ttl_ns=int(round(ttl * 1e9)),
            require_utterance=_flag(values, 'require_utterance'),
            observation_buffer=_number(values, 'observation_buffer', 1, True),
            max_utterance_chars=_number(values, 'max_utterance_chars', 1, True),
            stamped_stream_timeout=_number(values, 'stamped_stream_timeout', 0.0),
            max_stamp_jump_ns=int(round(_number(values, 'max_stamp_jump', 1e-3) * 1e9)),
            publish_mask=_flag(values, 'publish_mask'),
            templates_manifest=values['templates_manifest'],
            status_period=_number(values, 'status_period', 0.001))

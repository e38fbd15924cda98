"""
Saliency images: keep the named objects and the agent sharp, blur the rest (no rclpy).

    saliency = mask * frame + (1 - mask) * GaussianBlur(frame)

The mask is 1 on the pixels of every matched template that is not background (a ladder's rails
and rungs, the skull's own pixels, the agent's sprite) and 0 elsewhere. The blur has radius ``r``
(kernel ``2r + 1``; ``BLUR_RADIUS``, the thesis's 3, by default) and standard deviation
``r / 2`` unless set: the kernel then reaches two standard deviations, so the blur is strong
without being a box filter.

Modes (section 3 and chapter 5 of the thesis):

- ``language``: the objects the utterance names, and the agent.
- ``blind_agent``: the agent only, whatever was said (Figure 5.2).
- ``hidden_agent``: everything but the agent. The agent's pixels are replaced by the background
  seen there before it came (the background colour where never seen) before blurring, so the
  blur leaves no agent-shaped smudge behind.
- ``faded``: the ``language`` mask without blur, the rest dimmed (the variant of Figure 3.3 that
  the thesis rejected).
- ``mask``: the ``language`` mask itself as the image, white on black (not the thesis's: for a
  learner that reads the saliency image as an input, ``language_input``; through the frozen
  grey encoder a radius-3 blur hardly tells the named object from the others,
  tests/benchmarks/fetch_capacity.py).
- ``off``: no saliency images.
"""

from dataclasses import dataclass
import functools
from typing import Dict, Iterable, Optional, Sequence, Tuple

import cv2
import numpy as np

from saliency_node.matching import ObjectModel, Scene, SceneMatcher

MODES = ('language', 'blind_agent', 'hidden_agent', 'faded', 'mask', 'off')
BLUR_RADIUS = 3
"""The thesis's Gaussian blur radius in pixels: the one place of the default."""


def parse_mode(value) -> str:
    """Return the mode a parameter value names; ``False`` is ``off`` (YAML reads off as false)."""
    if value is False:
        return 'off'
    if isinstance(value, str) and value.strip().lower() in MODES:
        return value.strip().lower()
    raise ValueError(f'mode {value!r} is not one of {", ".join(MODES)}')


@dataclass
class SaliencyConfig:
    """How saliency images are made; each field is a ROS parameter of saliency_node too."""

    mode: str = 'language'
    """One of language, blind_agent, hidden_agent, faded, off (MODES); false means off (YAML
    reads `-p mode:=off` as false)."""
    blur_radius: int = BLUR_RADIUS
    """Gaussian blur radius r in pixels (kernel 2r + 1); 0 disables the blur."""
    blur_sigma: float = 0.0
    """Standard deviation of the blur; 0 means blur_radius / 2."""
    fade: float = 0.3
    """Brightness kept outside the mask in faded mode."""

    def __post_init__(self):
        self.mode = parse_mode(self.mode)
        if int(self.blur_radius) != self.blur_radius or not 0 <= self.blur_radius <= 50:
            raise ValueError(f'blur_radius must be an integer in 0..50, got {self.blur_radius}')
        if not 0.0 <= self.blur_sigma <= 50.0:
            raise ValueError(f'blur_sigma must be in [0, 50], got {self.blur_sigma}')
        if not 0.0 <= self.fade <= 1.0:
            raise ValueError(f'fade must be in [0, 1], got {self.fade}')
        self.blur_radius = int(self.blur_radius)

    @property
    def sigma(self) -> float:
        return self.blur_sigma if self.blur_sigma > 0 else self.blur_radius / 2.0


@functools.lru_cache(maxsize=16)
def gaussian_kernel(radius: int, sigma: float) -> np.ndarray:
    """1-D Gaussian of ``2 * radius + 1`` taps (sigma 0 means ``radius / 2``), summing to 1."""
    return cv2.getGaussianKernel(2 * radius + 1, sigma if sigma > 0 else radius / 2.0)


def gaussian_blur(frame: np.ndarray, radius: int, sigma: float = 0.0) -> np.ndarray:
    """
    Gaussian blur with kernel ``2 * radius + 1``, borders reflected as cv2.GaussianBlur does.

    The same separable filter as ``cv2.GaussianBlur``, applied with ``cv2.sepFilter2D``, which is
    about 3x faster on uint8 frames; values differ from ``cv2.GaussianBlur``'s fixed-point
    rounding by at most 2 levels.
    """
    if radius <= 0:
        return frame.copy()
    kernel = gaussian_kernel(int(radius), float(sigma))
    return cv2.sepFilter2D(frame, -1, kernel, kernel)


def object_mask(shape: Tuple[int, int], scene: Scene, names: Iterable[str],
                models: Dict[str, ObjectModel], region) -> np.ndarray:
    """uint8 mask (1 = keep) of the non-background pixels of every match of ``names``."""
    mask = np.zeros(shape, np.uint8)
    rx, ry = region[:2] if region else (0, 0)  # region None: the whole frame
    for name in names:
        model = models[name]
        pixels = scene.sprite_pixels.get(name)
        for m in scene.matches.get(name, ()):
            box = mask[m.y:m.y + m.h, m.x:m.x + m.w]
            cv2.bitwise_or(box, model.templates[m.template].foreground, dst=box)
            if pixels is not None:  # a sprite's own colours count even in an unseen pose
                own = pixels[m.y - ry:m.y - ry + m.h, m.x - rx:m.x - rx + m.w]
                cv2.bitwise_or(box, own // 255, dst=box)
    return mask


def compose(frame: np.ndarray, mask: np.ndarray, outside: np.ndarray) -> np.ndarray:
    """``mask * frame + (1 - mask) * outside`` for a 0/1 uint8 mask."""
    out = outside.copy()
    cv2.copyTo(frame, mask, out)
    return out


def hide_sprites(frame: np.ndarray, scene: Scene, name: str, mask: np.ndarray) -> np.ndarray:
    """``frame`` with the pixels of ``mask`` inside ``name``'s matches taken from the backdrop."""
    out = frame.copy()
    for m, backdrop in scene.backdrop.get(name, ()):
        box = out[m.y:m.y + m.h, m.x:m.x + m.w]
        cv2.copyTo(backdrop, mask[m.y:m.y + m.h, m.x:m.x + m.w], box)
    return out


class SaliencyMaker:
    """Matches frames as they come and renders saliency images for selected objects."""

    def __init__(self, objects: Sequence[ObjectModel], region=None, background=(0, 0, 0),
                 method: int = cv2.TM_CCORR_NORMED):
        """``region``: ``(x, y, width, height)`` searched; None: the whole incoming frame."""
        self.models = {o.name: o for o in objects}
        self.agent = next(o.name for o in objects if o.agent)
        self.matcher = SceneMatcher(objects, region, background, method)
        self.region = self.matcher.region

    def observe(self, frame: np.ndarray) -> Scene:
        """Match a frame (frames must come in time order)."""
        return self.matcher.update(frame)

    def mask(self, frame_shape, scene: Scene, names: Iterable[str]) -> np.ndarray:
        return object_mask(frame_shape[:2], scene, names, self.models, self.region)

    def render(self, frame: np.ndarray, scene: Scene, named: Iterable[str],
               config: SaliencyConfig) -> Tuple[Optional[np.ndarray], Optional[np.ndarray]]:
        """Return ``(saliency RGB, mask 0/1)`` in ``config.mode``; ``(None, None)`` if off."""
        mode = config.mode
        if mode == 'off':
            return None, None
        if mode == 'hidden_agent':
            agent = self.mask(frame.shape, scene, [self.agent])
            hidden = hide_sprites(frame, scene, self.agent, agent)
            keep = 1 - agent
            return compose(frame, keep, gaussian_blur(hidden, config.blur_radius,
                                                      config.sigma)), keep
        names = [self.agent] if mode == 'blind_agent' else set(named) | {self.agent}
        keep = self.mask(frame.shape, scene, names)
        if mode == 'faded':
            dimmed = cv2.convertScaleAbs(frame, alpha=config.fade)
            return compose(frame, keep, dimmed), keep
        if mode == 'mask':
            return np.repeat(keep[:, :, None] * np.uint8(255), 3, axis=2), keep
        return compose(frame, keep, gaussian_blur(frame, config.blur_radius, config.sigma)), keep

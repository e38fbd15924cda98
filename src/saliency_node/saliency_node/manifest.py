"""
The template manifest: what an utterance can name, and where each template comes from.

The manifest (YAML) is the only place that knows the game. It lists the objects (name, words
that refer to it, match threshold, whether it moves, whether it is the agent) and, for each of
their template images, how ``saliency_make_templates`` cuts it from a frame the emulator renders
(the frame after ``step`` actions of the manifest's ``route``). Another game means another
manifest, not new code.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Optional, Sequence, Tuple

import cv2
import numpy as np
import yaml

DEFAULT_MANIFEST = Path(__file__).resolve().parent / 'templates' / 'manifest.yaml'


class ManifestError(ValueError):
    """The manifest cannot be read or does not describe templates."""


class TemplateFileError(FileNotFoundError):
    """A template image named by the manifest is missing or unreadable."""


@dataclass(frozen=True)
class TemplateSpec:
    """One template image of an object."""

    file: str
    """PNG file name, relative to the manifest's folder."""
    step: int
    """The template is cut from the frame after this many actions of the route."""
    box: Optional[Tuple[int, int, int, int]]
    """``(x, y, width, height)`` to cut; for a moving object, where to look for its colours."""


@dataclass(frozen=True)
class ObjectSpec:
    """An object an utterance can name, with the templates that find it."""

    name: str
    words: Tuple[str, ...]
    """Words that refer to it (the name included); grounding stems them."""
    threshold: float
    """A match counts when its score (equation 3.1) reaches this."""
    moves: bool
    """Moving sprites are searched where their own colours are; static ones are cached."""
    agent: bool
    """The agent is always part of the mask (and the only part in ``blind_agent`` mode)."""
    colors: Tuple[Tuple[int, int, int], ...]
    """RGB colours of a moving sprite: cutting keeps only these pixels."""
    templates: Tuple[TemplateSpec, ...]


@dataclass(frozen=True)
class Manifest:
    """Everything game-specific the saliency node uses."""

    folder: Path
    env_id: str
    frameskip: int
    seed: int
    route: Tuple[str, ...]
    """ALE action names, one per step, played from reset to reach the template frames."""
    search_region: Tuple[int, int, int, int]
    """``(x, y, width, height)`` of the frame where objects are searched (the playfield)."""
    frame_shape: Tuple[int, int]
    """``(height, width)`` of the frames the templates belong to."""
    background: Tuple[int, int, int]
    """RGB colour of empty space: template pixels of this colour are not part of a mask."""
    objects: Tuple[ObjectSpec, ...]

    @property
    def agent(self) -> ObjectSpec:
        return next(spec for spec in self.objects if spec.agent)


def parse_route(text: str) -> Tuple[str, ...]:
    """``'NOOP*5 DOWN*2 FIRE'`` -> ``('NOOP',) * 5 + ('DOWN',) * 2 + ('FIRE',)``."""
    actions = []
    for item in text.split():
        name, _, count = item.partition('*')
        if count and not count.isdigit():
            raise ManifestError(f'route item {item!r} is not NAME or NAME*COUNT')
        actions.extend([name.upper()] * (int(count) if count else 1))
    return tuple(actions)


def _box(value, where: str) -> Optional[Tuple[int, int, int, int]]:
    if value is None:
        return None
    if len(value) != 4 or any(int(v) != v for v in value) or value[2] < 1 or value[3] < 1:
        raise ManifestError(f'{where}: box must be [x, y, width, height], got {value!r}')
    return tuple(int(v) for v in value)


def _color(value, where: str) -> Tuple[int, int, int]:
    if len(value) != 3 or not all(0 <= int(v) <= 255 for v in value):
        raise ManifestError(f'{where}: colour must be [r, g, b] in 0..255, got {value!r}')
    return tuple(int(v) for v in value)


def _object(name: str, raw: dict) -> ObjectSpec:
    where = f'object {name!r}'
    templates = raw.get('templates') or []
    if not templates:
        raise ManifestError(f'{where} has no templates')
    threshold = float(raw.get('threshold', 0.9))
    if not 0.0 < threshold <= 1.0:
        raise ManifestError(f'{where}: threshold {threshold} is outside (0, 1]')
    specs = tuple(TemplateSpec(file=str(t['file']), step=int(t.get('step', 0)),
                               box=_box(t.get('box'), f'{where} {t.get("file")}'))
                  for t in templates)
    words = tuple(dict.fromkeys([name] + [str(w).lower() for w in raw.get('words', [])]))
    return ObjectSpec(name=name, words=words, threshold=threshold,
                      moves=bool(raw.get('moves', False)), agent=bool(raw.get('agent', False)),
                      colors=tuple(_color(c, where) for c in raw.get('colors', [])),
                      templates=specs)


def load_manifest(path=None) -> Manifest:
    """Read and check a manifest (default: the one shipped with this package)."""
    path = Path(path) if path else DEFAULT_MANIFEST
    try:
        raw = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise TemplateFileError(f'template manifest not found: {path}') from None
    except yaml.YAMLError as error:
        raise ManifestError(f'{path} is not valid YAML: {error}') from None
    try:
        emulator = raw['emulator']
        objects = tuple(_object(name, spec) for name, spec in raw['objects'].items())
        manifest = Manifest(
            folder=path.parent, env_id=str(emulator['env_id']),
            frameskip=int(emulator.get('frameskip', 4)), seed=int(emulator.get('seed', 0)),
            route=parse_route(str(raw.get('route', ''))),
            search_region=_box(raw['search_region'], 'search_region'),
            frame_shape=(int(raw['frame_shape'][0]), int(raw['frame_shape'][1])),
            background=_color(raw.get('background', [0, 0, 0]), 'background'),
            objects=objects)
    except (KeyError, TypeError) as error:
        raise ManifestError(f'{path}: missing or malformed entry {error}') from None
    if sum(spec.agent for spec in objects) != 1:
        raise ManifestError(f'{path}: exactly one object must be the agent')
    return manifest


def template_paths(manifest: Manifest) -> Dict[str, Sequence[Path]]:
    """Template file paths of every object, in manifest order."""
    return {spec.name: [manifest.folder / t.file for t in spec.templates]
            for spec in manifest.objects}


def load_template_images(manifest: Manifest) -> Dict[str, Sequence[np.ndarray]]:
    """RGB uint8 images of every template; ``TemplateFileError`` names a missing file."""
    images = {}
    for name, paths in template_paths(manifest).items():
        images[name] = []
        for path in paths:
            bgr = cv2.imread(str(path), cv2.IMREAD_COLOR) if path.is_file() else None
            if bgr is None:
                raise TemplateFileError(
                    f'template file missing or unreadable: {path} (object {name!r}); '
                    'regenerate with saliency_make_templates')
            images[name].append(np.ascontiguousarray(bgr[:, :, ::-1]))
    return images

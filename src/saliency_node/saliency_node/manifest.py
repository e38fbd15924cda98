"""
The template manifest: what an utterance can name, and where each template comes from.

The manifest (YAML) is the only place that knows the game. It lists the objects (name, words
that refer to it, match threshold, whether it moves, whether it is the agent, whether it is
matched in colour) and, for each of their template images, how its ``source`` makes it:
``ale`` (the default), cut by ``saliency_make_templates`` from a frame the emulator renders
(the frame after ``step`` actions of the manifest's ``route``); ``minigrid``, one cell drawn
by MiniGrid's renderer (``cell``, ``agent_dir``; ``doorkey_make_templates``). Another game
means another manifest, not new code.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

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
    backdrop: Optional[str] = None
    """PNG of the same place without the object (the object's ``backdrop`` if the template
    names none): the mask is where the two differ, not the background colour; ``hidden_agent``
    paints the agent's over the agent."""
    cell: str = ''
    """Source minigrid: what the cell holds ('yellow key', 'blue door open', 'goal', 'floor')."""
    agent_dir: Optional[str] = None
    """Source minigrid: the agent drawn on the cell, facing right, down, left or up."""


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
    color_match: bool = False
    """Matched in colour (3-channel ``cv2.matchTemplate``), not on luma: a yellow key then
    does not match a blue one. Static objects only."""
    grid: int = 0
    """Pitch in pixels of the grid the object lies on (a tile renderer's cells), from the
    search region's corner: matches off it are dropped. 0: anywhere."""


@dataclass(frozen=True)
class Manifest:
    """Everything game-specific the saliency node uses."""

    folder: Path
    objects: Tuple[ObjectSpec, ...]
    source: str = 'ale'
    """What makes the templates: ``ale`` (an emulator playing ``route``), ``minigrid``..."""
    env_id: str = ''
    """Source ale: the emulator's game (``emulator.env_id``), with its frameskip and seed."""
    frameskip: int = 4
    seed: int = 0
    route: Tuple[str, ...] = ()
    """Source ale: action names, one per step, played from reset to reach the template frames."""
    search_region: Optional[Tuple[int, int, int, int]] = None
    """``(x, y, width, height)`` of the frame where objects are searched (the playfield);
    None: the whole frame."""
    frame_shape: Optional[Tuple[int, int]] = None
    """``(height, width)`` of the frames the templates belong to; None: the task's."""
    background: Tuple[int, int, int] = (0, 0, 0)
    """RGB colour of empty space: template pixels of this colour are not part of a mask."""
    maker: str = 'saliency_make_templates'
    """The command that makes the template PNGs (named when one is missing)."""

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


def _template(raw: dict, where: str, backdrop: Optional[str]) -> TemplateSpec:
    agent_dir = raw.get('agent_dir')
    backdrop = raw.get('backdrop', backdrop)
    return TemplateSpec(file=str(raw['file']), step=int(raw.get('step', 0)),
                        box=_box(raw.get('box'), f'{where} {raw.get("file")}'),
                        backdrop=str(backdrop) if backdrop else None,
                        cell=str(raw.get('cell', '')),
                        agent_dir=None if agent_dir is None else str(agent_dir))


def _object(name: str, raw: dict) -> ObjectSpec:
    where = f'object {name!r}'
    templates = raw.get('templates') or []
    if not templates:
        raise ManifestError(f'{where} has no templates')
    threshold = float(raw.get('threshold', 0.9))
    if not 0.0 < threshold <= 1.0:
        raise ManifestError(f'{where}: threshold {threshold} is outside (0, 1]')
    moves, color_match = bool(raw.get('moves', False)), bool(raw.get('color_match', False))
    grid = int(raw.get('grid', 0))
    if grid < 0:
        raise ManifestError(f'{where}: grid must be a pitch in pixels or 0, got {grid}')
    if moves and color_match:
        raise ManifestError(f'{where}: color_match is for static objects (a moving sprite is '
                            'keyed by its colours on luma)')
    words = tuple(dict.fromkeys([name] + [str(w).lower() for w in raw.get('words', [])]))
    return ObjectSpec(name=name, words=words, threshold=threshold, moves=moves,
                      agent=bool(raw.get('agent', False)),
                      colors=tuple(_color(c, where) for c in raw.get('colors', [])),
                      templates=tuple(_template(t, where, raw.get('backdrop'))
                                      for t in templates),
                      color_match=color_match, grid=grid)


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
        source = str(raw.get('source', 'ale'))
        defaults = dict(raw.get('defaults') or {})
        objects = tuple(_object(name, {**defaults, **spec})
                        for name, spec in raw['objects'].items())
        emulator = raw['emulator'] if source == 'ale' else {'env_id': ''}
        shape = raw.get('frame_shape')
        manifest = Manifest(
            folder=path.parent, objects=objects, source=source,
            env_id=str(emulator['env_id']),
            frameskip=int(emulator.get('frameskip', 4)), seed=int(emulator.get('seed', 0)),
            route=parse_route(str(raw.get('route', ''))),
            search_region=_box(raw.get('search_region'), 'search_region'),
            frame_shape=(int(shape[0]), int(shape[1])) if shape is not None else None,
            background=_color(raw.get('background', [0, 0, 0]), 'background'),
            maker=str(raw.get('maker', Manifest.maker)))
    except (KeyError, TypeError) as error:
        raise ManifestError(f'{path}: missing or malformed entry {error}') from None
    if sum(spec.agent for spec in objects) != 1:
        raise ManifestError(f'{path}: exactly one object must be the agent')
    return manifest


def frame_shape_for(manifest: Manifest, task_shape: Tuple[int, int]) -> Tuple[int, int]:
    """Return the observations' ``(height, width)``: the manifest's, else the task's frames."""
    shape = tuple(manifest.frame_shape or task_shape)
    if shape != tuple(task_shape):
        raise ManifestError(f'the manifest in {manifest.folder} is for {list(shape)} frames, '
                            f'the task has {list(task_shape)}')
    return shape


def template_paths(manifest: Manifest) -> Dict[str, Sequence[Path]]:
    """Template file paths of every object, in manifest order."""
    return {spec.name: [manifest.folder / t.file for t in spec.templates]
            for spec in manifest.objects}


def _read_rgb(path: Path, name: str, manifest: Manifest) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR) if path.is_file() else None
    if bgr is None:
        raise TemplateFileError(f'template file missing or unreadable: {path} (object {name!r}); '
                                f'regenerate with {manifest.maker}')
    return np.ascontiguousarray(bgr[:, :, ::-1])


def load_template_images(manifest: Manifest) -> Dict[str, Sequence[np.ndarray]]:
    """RGB uint8 images of every template; ``TemplateFileError`` names a missing file."""
    return {name: [_read_rgb(path, name, manifest) for path in paths]
            for name, paths in template_paths(manifest).items()}


def load_backdrops(manifest: Manifest) -> Dict[str, List[Optional[np.ndarray]]]:
    """RGB uint8 backdrop of every template (None where the manifest names none)."""
    return {spec.name: [_read_rgb(manifest.folder / t.backdrop, spec.name, manifest)
                        if t.backdrop else None for t in spec.templates]
            for spec in manifest.objects}

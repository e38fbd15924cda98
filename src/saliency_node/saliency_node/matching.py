"""
Template matching: every instance of every object in a frame (no rclpy).

The score is ``cv2.matchTemplate`` with ``TM_CCORR_NORMED`` by default, which is equation 3.1 of
the thesis (normalized cross-correlation); the method is a parameter. All positions whose score
reaches the object's threshold count, and non-maximum suppression keeps the best of overlapping
ones. Matching runs on luma images (one channel: about ten times faster than three), or on
RGB for objects the manifest marks ``color_match`` (a yellow key is not a blue key).

``SceneMatcher`` gives the same instances as ``match_scene`` (which searches every template over
the whole search region), fast enough to run on every frame:

- Static objects (ladders, doors...) are searched once in a background image: the frame with the
  moving sprites left out (their pixels keep what was seen there before; the background colour
  where never seen). Each frame, pixels of the background that changed are found with one
  ``absdiff`` (on RGB when an object is matched in colour); a change inside a cached match
  re-verifies that object in place (the conveyor's animation); any other change (the key taken
  or back, a new room) searches every static object around the change, and only there.
  Matching the background also means that the agent in front of a ladder does not lower the
  ladder's score. Templates whose score bound (``score_bounds``) cannot reach their threshold
  in the searched area are skipped (colour objects: DoorKey has 74 templates of one size).
- Moving sprites (the agent, the skull) are searched where their own colours are: the frame's
  pixels of those colours (a lookup table on luma), everything else zeroed, so the background
  behind a sprite does not count. A template of exactly the size of that pixel group which
  matches exactly is taken at once; otherwise every template is searched around the group.

The search region is the manifest's, or the whole incoming frame when it names none.

Known limit: a moving sprite's colours are told apart by luma, so a background colour with the
luma of a sprite colour would count as the sprite's (no such pair in Room 1); an agent that
shares its colours with other objects (DoorKey's red triangle and red keys) is a static object
matched in colour instead, with a template for each thing it can stand over.
"""

from dataclasses import dataclass, field
import functools
from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

import cv2
import numpy as np

METHODS = {
    'TM_CCORR_NORMED': cv2.TM_CCORR_NORMED,
    'TM_CCOEFF_NORMED': cv2.TM_CCOEFF_NORMED,
    'TM_SQDIFF_NORMED': cv2.TM_SQDIFF_NORMED,
}
"""Normalized methods (scores in [0, 1], thresholds comparable); the first is equation 3.1."""

EXACT_SCORE = 0.9995
"""A score this high means the sprite's pixels equal the template's (the fast path takes it)."""

CHANGE_MARGIN = 2
"""Pixels around a sprite's box left out of the background (sprites may overhang a template)."""

BOUND_BLOCKS = 8
"""Blocks per side of a template in the score bound that skips templates (colour objects)."""
BOUND_SLACK = 1e-3
"""A template is skipped only when its bound is this far below the threshold (float error)."""


def method_problem(objects: Sequence['ObjectModel'], method: int) -> str:
    """
    Say why ``method`` cannot match ``objects`` ('' if it can).

    ``TM_CCOEFF_NORMED`` subtracts the template's mean: of a template of one colour (DoorKey's
    goal) nothing is left, and it scores 1 on any flat area.
    """
    if method != cv2.TM_CCOEFF_NORMED:
        return ''
    flat = [obj.name for obj in objects
            if any((t.image == t.image.reshape(-1, *t.image.shape[2:])[0]).all()
                   for t in obj.templates)]
    return (f'TM_CCOEFF_NORMED cannot match {", ".join(flat)}: a template of one flat colour '
            'scores 1 on any flat area') if flat else ''


def method_from_name(name: str) -> int:
    """``'TM_CCORR_NORMED'`` -> ``cv2.TM_CCORR_NORMED``; ``ValueError`` names the choices."""
    try:
        return METHODS[str(name).upper()]
    except KeyError:
        raise ValueError(
            f'unknown match method {name!r} (choose from {", ".join(METHODS)})') from None


class Match(NamedTuple):
    """One instance of an object: box in frame pixels, the template that matched, its score."""

    name: str
    template: int
    x: int
    y: int
    w: int
    h: int
    score: float

    def shifted(self, dx: int, dy: int) -> 'Match':
        return self._replace(x=self.x + dx, y=self.y + dy)


def iou(a: Match, b: Match) -> float:
    """Intersection over union of two boxes."""
    w = min(a.x + a.w, b.x + b.w) - max(a.x, b.x)
    h = min(a.y + a.h, b.y + b.h) - max(a.y, b.y)
    if w <= 0 or h <= 0:
        return 0.0
    inter = w * h
    return inter / float(a.w * a.h + b.w * b.h - inter)


def non_max_suppression(matches: Sequence[Match], overlap: float = 0.0) -> List[Match]:
    """
    Keep the best first (the larger on a tie), drop any whose IoU with a kept one > overlap.

    The default 0 drops any overlap: two instances of one object never overlap in a frame,
    while a repetitive object (a ladder's rungs) also matches, less well, shifted by a period.
    Scores are compared to 4 decimals, so float noise does not decide between exact matches.
    """
    kept: List[Match] = []
    for match in sorted(matches, key=lambda m: (-round(m.score, 4), -m.w * m.h)):
        if all(iou(match, other) <= overlap for other in kept):
            kept.append(match)
    return kept


def score_map(image: np.ndarray, template: np.ndarray, method: int) -> np.ndarray:
    """
    ``cv2.matchTemplate`` scores, higher is better (``TM_SQDIFF_NORMED`` is flipped).

    Colour images are matched as one plane with the channels side by side (``h x 3w``): every
    third column then holds the 3-channel score, the same sums, in half the time.
    ``TM_CCOEFF_NORMED`` subtracts each channel's own mean, so it keeps the 3 channels.
    """
    if image.ndim == 3 and method != cv2.TM_CCOEFF_NORMED:
        channels = image.shape[2]
        scores = cv2.matchTemplate(
            np.ascontiguousarray(image).reshape(image.shape[0], -1),
            np.ascontiguousarray(template).reshape(template.shape[0], -1), method)[:, ::channels]
    else:
        scores = cv2.matchTemplate(image, template, method)
    if method == cv2.TM_SQDIFF_NORMED:
        scores = 1.0 - scores
    return scores


def exact_score(patch: np.ndarray, template: np.ndarray, method: int) -> float:
    """Score of ``template`` on a ``patch`` of its size; an identical patch scores 1 at once."""
    if patch.shape == template.shape and not cv2.norm(patch, template, cv2.NORM_INF):
        return 1.0  # every normalized method gives an exact copy 1: skip the call
    return float(score_map(patch, template, method)[0, 0])


@functools.lru_cache(maxsize=64)
def _bands(n: int) -> Tuple[Tuple[int, int], ...]:
    """``(start, length)`` of the ``BOUND_BLOCKS`` bands (fewer if ``n`` is smaller) of ``n``."""
    edges = np.linspace(0, n, min(BOUND_BLOCKS, n) + 1).round().astype(int)
    return tuple((int(a), int(b - a)) for a, b in zip(edges[:-1], edges[1:]))


def block_energies(image: np.ndarray, size: Tuple[int, int], grid: int = 0,
                   origin: Tuple[int, int] = (0, 0)) -> np.ndarray:
    """
    Sum of squares of each block and channel of every ``size`` window of ``image``.

    The window (``(width, height)``) is cut into ``BOUND_BLOCKS`` x ``BOUND_BLOCKS`` blocks;
    returns ``(positions, blocks * channels)`` in float32: one unnormalized box filter of the
    squared image per block shape, read at each block's offset. With a ``grid`` pitch, only
    the windows on it (``image`` starting at ``origin``, ``(x, y)``).
    """
    w, h = size
    rows, cols = image.shape[0] - h + 1, image.shape[1] - w + 1
    step = grid or 1
    y0, x0 = (-origin[1]) % step, (-origin[0]) % step
    channels = image.shape[2] if image.ndim == 3 else 1
    squares = np.square(image, dtype=np.float32)
    sums = {}
    blocks = []
    for y, bh in _bands(h):
        for x, bw in _bands(w):
            if (bh, bw) not in sums:
                sums[bh, bw] = cv2.boxFilter(squares, -1, (bw, bh), anchor=(0, 0),
                                             normalize=False, borderType=cv2.BORDER_CONSTANT)
            windows = sums[bh, bw][y + y0:y + rows:step, x + x0:x + cols:step]
            blocks.append(windows.reshape(-1, channels))
    # The box filter's running float sums may dip a hair below zero.
    return np.maximum(np.concatenate(blocks, axis=1), 0.0)


def bound_vector(template: np.ndarray) -> np.ndarray:
    """Return the unit vector of the roots of a template's block energies (``score_bounds``)."""
    roots = np.sqrt(block_energies(template, (template.shape[1], template.shape[0]))[0])
    norm = float(np.linalg.norm(roots))
    return roots / norm if norm > 0 else roots


def window_positions(image: np.ndarray, size: Tuple[int, int], grid: int = 0,
                     origin: Tuple[int, int] = (0, 0)) -> Tuple[np.ndarray, np.ndarray]:
    """Return ``(xs, ys)`` of the windows ``block_energies`` gives, in its order."""
    w, h = size
    step = grid or 1
    ys = np.arange((-origin[1]) % step, image.shape[0] - h + 1, step)
    xs = np.arange((-origin[0]) % step, image.shape[1] - w + 1, step)
    grid_x, grid_y = np.meshgrid(xs, ys)
    return grid_x.ravel(), grid_y.ravel()


def score_bounds(image: np.ndarray, templates: Sequence['Template'], grid: int = 0,
                 origin: Tuple[int, int] = (0, 0)
                 ) -> List[Tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """
    Bound each template's ``TM_CCORR_NORMED`` score in every window of ``image`` from above.

    Cauchy-Schwarz block by block and channel by channel: a window's score is at most the dot
    product of the unit vectors of block-energy roots of the window and of the template; one
    matrix product (``cv2.gemm``: no BLAS thread pool) for all windows and templates of a size.
    Windows anywhere, or on the ``grid`` (``block_energies``). Per template ``(xs, ys,
    bounds)``: the windows' top-left corners and their bounds (empty where none fits).
    """
    empty = np.zeros(0)
    result = [(empty, empty, empty)] * len(templates)
    by_size: Dict[Tuple[int, int], List[int]] = {}
    for index, template in enumerate(templates):
        by_size.setdefault(template.size, []).append(index)
    for (w, h), indices in by_size.items():
        if image.shape[0] < h or image.shape[1] < w:
            continue
        energies = block_energies(image, (w, h), grid, origin)
        if not len(energies):
            continue
        xs, ys = window_positions(image, (w, h), grid, origin)
        norms = np.sqrt(cv2.reduce(energies, 1, cv2.REDUCE_SUM))
        windows = np.sqrt(energies) / np.where(norms > 0, norms, np.inf)  # unit rows (or 0)
        vectors = np.stack([templates[i].bound_vector for i in indices])
        dots = cv2.gemm(vectors, windows, 1.0, None, 0.0, flags=cv2.GEMM_2_T)
        for row, index in enumerate(indices):
            result[index] = (xs, ys, dots[row])
    return result


def least_bound(threshold: float, method: int) -> float:
    """Return the lowest ``TM_CCORR_NORMED`` bound of a window that may score ``threshold``."""
    if method == cv2.TM_CCORR_NORMED:
        return threshold - BOUND_SLACK
    if method == cv2.TM_SQDIFF_NORMED:  # 1 - sqdiff_normed <= 2 ccorr_normed - 1
        return (threshold - BOUND_SLACK + 1.0) / 2.0
    return -np.inf  # TM_CCOEFF_NORMED: no bound


def find_matches(image: np.ndarray, template: np.ndarray, threshold: float, method: int,
                 name: str = '', index: int = 0, dx: int = 0, dy: int = 0,
                 grid: int = 0) -> List[Match]:
    """
    Every position of ``template`` in ``image`` scoring at least ``threshold``.

    ``image`` starts at ``(dx, dy)``; with a ``grid`` pitch, only positions on it count (a
    flat template, MiniGrid's goal, also matches a pixel off beside a cell of its colour).
    """
    h, w = template.shape[:2]
    if image.shape[0] < h or image.shape[1] < w:
        return []
    scores = score_map(image, template, method)
    hit = scores >= threshold
    if grid:
        on_grid = np.zeros_like(hit)
        on_grid[(-dy) % grid::grid, (-dx) % grid::grid] = True
        hit &= on_grid
    ys, xs = np.nonzero(hit)
    return [Match(name, index, int(x) + dx, int(y) + dy, w, h, float(scores[y, x]))
            for y, x in zip(ys, xs)]


@dataclass
class Template:
    """One template image of an object, prepared for matching."""

    rgb: np.ndarray
    gray: np.ndarray = field(init=False)
    foreground: np.ndarray = field(init=False)
    """uint8 1 where the template differs from its backdrop, else from the background colour:
    its mask pixels."""
    background: Tuple[int, int, int] = (0, 0, 0)
    backdrop: Optional[np.ndarray] = None
    """RGB of the same place without the object (an agent's: what it stands over)."""
    color: bool = False
    """Matched on RGB (``image`` is ``rgb``), else on luma (``image`` is ``gray``)."""
    image: np.ndarray = field(init=False)
    """What ``cv2.matchTemplate`` gets."""
    bound_vector: np.ndarray = field(init=False)
    """Unit vector of the roots of its block energies (``score_bounds``)."""

    def __post_init__(self):
        self.rgb = np.ascontiguousarray(self.rgb, dtype=np.uint8)
        self.gray = cv2.cvtColor(self.rgb, cv2.COLOR_RGB2GRAY)
        behind = (np.array(self.background, np.uint8) if self.backdrop is None
                  else np.asarray(self.backdrop, np.uint8))
        if behind.ndim == 3 and behind.shape != self.rgb.shape:
            raise ValueError(f'backdrop {behind.shape} and template {self.rgb.shape} differ')
        self.foreground = np.any(self.rgb != behind, axis=2).astype(np.uint8)
        self.image = self.rgb if self.color else self.gray
        self.bound_vector = bound_vector(self.image)

    @property
    def size(self) -> Tuple[int, int]:
        return self.gray.shape[1], self.gray.shape[0]


@dataclass
class ObjectModel:
    """An object's templates and matching settings (from the manifest)."""

    name: str
    templates: List[Template]
    threshold: float
    moves: bool = False
    agent: bool = False
    color_match: bool = False
    """Matched on RGB (its templates' ``color``): static objects only."""
    grid: int = 0
    """Pitch in pixels of the grid it lies on, from the search region's corner; 0: anywhere."""
    key_lut: np.ndarray = field(init=False)
    """256-entry table: 255 for luma values of the object's own pixels (moving objects)."""

    def __post_init__(self):
        lut = np.zeros(256, np.uint8)
        for template in self.templates:
            lut[template.gray[template.foreground > 0]] = 255
        self.key_lut = lut
        self.by_size: Dict[Tuple[int, int], List[int]] = {}
        for index, template in enumerate(self.templates):
            self.by_size.setdefault(template.size, []).append(index)
        self.max_size = (max(t.size[0] for t in self.templates),
                         max(t.size[1] for t in self.templates))


def build_objects(manifest, images, backdrops=None) -> List[ObjectModel]:
    """
    Build an ``ObjectModel`` per manifest object from ``manifest.load_template_images``.

    ``backdrops`` (``manifest.load_backdrops``) are required when the manifest names some.
    """
    if backdrops is None:
        if any(t.backdrop for spec in manifest.objects for t in spec.templates):
            raise ValueError('the manifest names backdrops: pass load_backdrops(manifest)')
        backdrops = {spec.name: [None] * len(spec.templates) for spec in manifest.objects}
    return [ObjectModel(name=spec.name, threshold=spec.threshold, moves=spec.moves,
                        agent=spec.agent, color_match=spec.color_match, grid=spec.grid,
                        templates=[Template(rgb, background=manifest.background, backdrop=behind,
                                            color=spec.color_match)
                                   for rgb, behind in zip(images[spec.name],
                                                          backdrops[spec.name])])
            for spec in manifest.objects]


class Scene(NamedTuple):
    """What a frame contains: matches per object (frame coordinates) and sprite pixels."""

    matches: Dict[str, List[Match]]
    sprite_pixels: Dict[str, np.ndarray]
    """Per moving object, uint8 255 on its colours, the size of the search region."""
    backdrop: Dict[str, List[Tuple[Match, np.ndarray]]]
    """For the agent, per match, what is behind it in its box (RGB): the template's backdrop,
    else what the background showed there (the background colour where never seen) - used to
    hide the agent."""


Windows = Dict[int, Tuple[int, int, int, int]]
"""Per template index, ``(x0, y0, x1, y1)``: the top-left corners of the windows to search."""


def _search_object(image: np.ndarray, obj: ObjectModel, method: int, overlap: float,
                   dx: int = 0, dy: int = 0, windows: Optional[Windows] = None
                   ) -> List[Match]:
    """Search ``obj``'s templates in ``image`` (only ``windows``, if given)."""
    found = []
    for index, template in enumerate(obj.templates):
        part, x0, y0 = image, 0, 0
        if windows is not None:
            if index not in windows:
                continue
            x0, y0, x1, y1 = windows[index]
            w, h = template.size
            part = image[y0:y1 + h, x0:x1 + w]
        found += find_matches(part, template.image, obj.threshold, method, obj.name, index,
                              dx + x0, dy + y0, obj.grid)
    return non_max_suppression(found, overlap)


def candidate_windows(image: np.ndarray, objects: Sequence[ObjectModel], method: int,
                      origin: Tuple[int, int] = (0, 0)) -> Dict[str, Optional[Windows]]:
    """
    Per object, the windows of ``image`` where each template may reach its threshold.

    For colour objects (many templates of one size: every look of every colour) the score
    bound (``score_bounds``, on each object's grid; ``image`` starts at ``origin``) rules most
    templates and windows out at a fraction of a search's cost; the rest: None, everywhere.
    """
    colour = [obj for obj in objects if obj.color_match]
    candidates: Dict[str, Optional[Windows]] = {obj.name: None for obj in objects}
    for grid in sorted({obj.grid for obj in colour}):
        group = [obj for obj in colour if obj.grid == grid]
        bounds = iter(score_bounds(image, [t for obj in group for t in obj.templates], grid,
                                   origin))
        for obj in group:
            least = least_bound(obj.threshold, method)
            candidates[obj.name] = {}
            for index in range(len(obj.templates)):
                xs, ys, bound = next(bounds)
                near = bound >= least
                if near.any():
                    candidates[obj.name][index] = (int(xs[near].min()), int(ys[near].min()),
                                                   int(xs[near].max()), int(ys[near].max()))
    return candidates


def keyed_image(gray: np.ndarray, obj: ObjectModel) -> Tuple[np.ndarray, np.ndarray]:
    """``(image, pixels)``: luma of the object's own colours only, and where they are."""
    pixels = cv2.LUT(gray, obj.key_lut)
    return cv2.bitwise_and(gray, pixels), pixels


def match_scene(frame: np.ndarray, objects: Sequence[ObjectModel], region,
                method: int = cv2.TM_CCORR_NORMED, overlap: float = 0.0) -> Dict[str, List[Match]]:
    """Search every template over the whole search region, without caches (the reference)."""
    x, y, w, h = region or (0, 0, frame.shape[1], frame.shape[0])
    rgb = np.ascontiguousarray(frame[y:y + h, x:x + w])
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    result = {}
    for obj in objects:
        image = keyed_image(gray, obj)[0] if obj.moves else (rgb if obj.color_match else gray)
        result[obj.name] = [m.shifted(x, y) for m in _search_object(image, obj, method, overlap)]
    return result


def _channel_max(image: np.ndarray) -> np.ndarray:
    """Return the largest channel of each pixel (``cv2.max``: numpy's reduce on 3 is slow)."""
    planes = cv2.split(image)
    out = planes[0]
    for plane in planes[1:]:
        out = cv2.max(out, plane)
    return out


class SceneMatcher:
    """Finds every object in a stream of frames; frames must arrive in time order."""

    def __init__(self, objects: Sequence[ObjectModel], region=None, background=(0, 0, 0),
                 method: int = cv2.TM_CCORR_NORMED, overlap: float = 0.0):
        self.objects = list(objects)
        self.static = [o for o in self.objects if not o.moves]
        self.moving = [o for o in self.objects if o.moves]
        self.region = tuple(int(v) for v in region) if region else None
        """``(x, y, width, height)`` searched; None: the whole frame."""
        self._color = any(o.color_match for o in self.static)
        self._agents = [o for o in self.static if o.agent]
        self._others = [o for o in self.static if not o.agent]
        self.background_color = np.array(background, np.uint8)
        self.method = method
        self.overlap = overlap
        self.stats = {'frames': 0, 'full_searches': 0, 'local_searches': 0, 'reverified': 0,
                      'sprite_searches': 0}
        self.reset()

    def reset(self) -> None:
        """Forget the background and the cached matches (a new room, a new run)."""
        self._bg_gray: Optional[np.ndarray] = None
        self._bg_rgb: Optional[np.ndarray] = None
        self._static: Dict[str, List[Match]] = {}  # search-region coordinates
        self._static_in_frame: Optional[Dict[str, List[Match]]] = None  # frame coordinates
        self._last_template: Dict[str, int] = {}

    def set_method(self, method: int) -> None:
        self.method = method
        self.reset()

    def update(self, frame: np.ndarray) -> Scene:
        """Match one RGB frame (full size); returns its ``Scene``."""
        x0, y0, w, h = self.region or (0, 0, frame.shape[1], frame.shape[0])
        rgb = frame[y0:y0 + h, x0:x0 + w]
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        if self._bg_gray is not None and self._bg_gray.shape != gray.shape:
            self.reset()  # frames of another size: what was seen no longer applies
        self.stats['frames'] += 1
        matches, pixels, boxes = {}, {}, []
        for obj in self.moving:
            found, pixels[obj.name] = self._find_sprites(gray, obj)
            matches[obj.name] = [m.shifted(x0, y0) for m in found]
            boxes += found
        self._update_background(rgb, gray, boxes, list(pixels.values()))
        if self._static_in_frame is None:
            self._static_in_frame = {name: [m.shifted(x0, y0) for m in found]
                                     for name, found in self._static.items()}
        matches.update(self._static_in_frame)
        backdrop = {obj.name: [(m, self._backdrop(obj, m, x0, y0)) for m in matches[obj.name]]
                    for obj in self.objects if obj.agent}
        return Scene(matches, pixels, backdrop)

    # Moving sprites -------------------------------------------------------------------------

    def _find_sprites(self, gray: np.ndarray, obj: ObjectModel):
        keyed, pixels = keyed_image(gray, obj)
        bx, by, bw, bh = cv2.boundingRect(pixels)
        if bw == 0:
            return [], pixels
        same_size = obj.by_size.get((bw, bh), ())
        if same_size:
            last = self._last_template.get(obj.name)
            order = sorted(same_size, key=lambda i: i != last)
            patch = keyed[by:by + bh, bx:bx + bw]
            for index in order:
                score = exact_score(patch, obj.templates[index].gray, self.method)
                if score >= EXACT_SCORE:
                    self._last_template[obj.name] = index
                    return [Match(obj.name, index, bx, by, bw, bh, score)], pixels
        self.stats['sprite_searches'] += 1
        mw, mh = obj.max_size
        rx, ry = max(bx - mw + 1, 0), max(by - mh + 1, 0)
        rx1 = min(bx + bw + mw - 1, gray.shape[1])
        ry1 = min(by + bh + mh - 1, gray.shape[0])
        found = _search_object(keyed[ry:ry1, rx:rx1], obj, self.method, self.overlap, rx, ry)
        if found:
            self._last_template[obj.name] = found[0].template
        return found, pixels

    def _backdrop(self, obj: ObjectModel, match: Match, x0: int, y0: int) -> np.ndarray:
        behind = obj.templates[match.template].backdrop
        if behind is not None:
            return behind
        x, y = match.x - x0, match.y - y0
        return self._bg_rgb[y:y + match.h, x:x + match.w].copy()

    # Static objects on the background ------------------------------------------------------

    def _view(self, obj: ObjectModel) -> np.ndarray:
        """Return the background image ``obj`` is matched on: RGB or luma."""
        return self._bg_rgb if obj.color_match else self._bg_gray

    def _update_background(self, rgb, gray, boxes, sprite_pixels) -> None:
        if self._bg_gray is None:
            # Where a sprite is, the background is unknown: the background colour stands in.
            sprites = np.zeros(gray.shape, np.uint8)
            for pixels in sprite_pixels:
                cv2.bitwise_or(sprites, pixels, dst=sprites)
            self._bg_rgb = rgb.copy()
            self._bg_rgb[sprites > 0] = self.background_color
            self._bg_gray = cv2.cvtColor(self._bg_rgb, cv2.COLOR_RGB2GRAY)
            self._search_all()
            return
        # What changed in the background: not where a sprite is (its box plus a margin, or a
        # pixel of a sprite's colour). A stand-in that differs from what is now seen changed.
        changed = (_channel_max(cv2.absdiff(rgb, self._bg_rgb)) if self._color
                   else cv2.absdiff(gray, self._bg_gray))
        m, (h, w) = CHANGE_MARGIN, gray.shape
        for b in boxes:
            changed[max(b.y - m, 0):min(b.y + b.h + m, h),
                    max(b.x - m, 0):min(b.x + b.w + m, w)] = 0
        for pixels in sprite_pixels:
            cv2.subtract(changed, pixels, dst=changed)
        if not cv2.countNonZero(changed):
            return
        cv2.copyTo(gray, changed, self._bg_gray)
        cv2.copyTo(rgb, changed, self._bg_rgb)
        self._on_background_change(changed)

    def _on_background_change(self, changed: np.ndarray) -> None:
        """
        Re-verify cached matches whose boxes changed; search again around other changes.

        A static agent (matched in colour: it shares its colours with other objects) overlaps
        other objects' places (what it carries), where their re-verifying explains the change:
        it is searched again around every change instead.
        """
        rect = cv2.boundingRect(changed)
        x, y, w, h = rect
        m, (rows, cols) = CHANGE_MARGIN, changed.shape
        for obj in self._others:
            for i, match in enumerate(self._static[obj.name]):
                x0, y0 = max(match.x - m, 0), max(match.y - m, 0)
                x1, y1 = min(match.x + match.w + m, cols), min(match.y + match.h + m, rows)
                if (x < x1 and x0 < x + w and y < y1 and y0 < y + h
                        and cv2.countNonZero(changed[y0:y1, x0:x1]) and self._reverify(obj, i)):
                    changed[y0:y1, x0:x1] = 0  # explained: the object is still there
        if cv2.countNonZero(changed):  # an object went, came or moved
            self._search_around(rect if self._agents else cv2.boundingRect(changed),
                                self.static)
        elif self._agents:
            self._search_around(rect, self._agents)

    def _reverify(self, obj: ObjectModel, i: int) -> bool:
        """Search ``obj`` again around its ``i``-th cached match; True if still there."""
        self.stats['reverified'] += 1
        old = self._static[obj.name][i]
        view = self._view(obj)
        for index, template in enumerate(obj.templates):  # an exact match in place (animation)
            tw, th = template.size
            patch = view[old.y:old.y + th, old.x:old.x + tw]
            if patch.shape == template.image.shape:
                score = exact_score(patch, template.image, self.method)
                if score >= EXACT_SCORE:
                    self._replace_static(obj, i, Match(obj.name, index, old.x, old.y, tw, th,
                                                       score))
                    return True
        m = CHANGE_MARGIN
        rx, ry = max(old.x - m, 0), max(old.y - m, 0)
        roi = view[ry:old.y + old.h + m, rx:old.x + old.w + m]
        found = _search_object(roi, obj, self.method, self.overlap, rx, ry)
        if not found:
            return False
        self._replace_static(obj, i, found[0])
        return True

    def _replace_static(self, obj: ObjectModel, i: int, match: Match) -> None:
        old = self._static[obj.name][i]
        if (old.template, old.x, old.y) != (match.template, match.x, match.y):
            self._static[obj.name][i] = match
            self._static_in_frame = None

    def _search_around(self, rect, objects: Sequence[ObjectModel]) -> None:
        """
        Search ``objects`` (static) wherever they could overlap ``rect`` (plus the margin).

        Cached matches clear of ``rect`` are unaffected by the change and kept; the rest are
        replaced by what the search finds. A change over the whole region is a full search.
        """
        self.stats['local_searches'] += 1
        m, (rows, cols) = CHANGE_MARGIN, self._bg_gray.shape
        x, y = rect[0] - m, rect[1] - m
        x1, y1 = rect[0] + rect[2] + m, rect[1] + rect[3] + m

        def clear(match: Match) -> bool:
            return (match.x + match.w <= x or x1 <= match.x
                    or match.y + match.h <= y or y1 <= match.y)

        def roi(image, mw, mh):
            rx, ry = max(x - mw + 1, 0), max(y - mh + 1, 0)
            return image[ry:min(y1 + mh - 1, rows), rx:min(x1 + mw - 1, cols)], rx, ry

        # Every object's region lies inside the one of the largest templates.
        largest = (max(o.max_size[0] for o in objects), max(o.max_size[1] for o in objects))
        image, ux, uy = roi(self._bg_rgb, *largest)
        candidates = candidate_windows(image, objects, self.method, (ux, uy))
        for obj in objects:
            windows = candidates[obj.name]
            if windows is None:
                image, rx, ry = roi(self._view(obj), *obj.max_size)
            else:  # colour objects: the windows, in the region of the largest templates
                image, rx, ry = roi(self._bg_rgb, *largest)
            found = [f for f in _search_object(image, obj, self.method, self.overlap, rx, ry,
                                               windows)
                     if not clear(f)]
            kept = [c for c in self._static[obj.name] if clear(c)]
            self._static[obj.name] = non_max_suppression(kept + found, self.overlap)
        self._static_in_frame = None

    def _search_all(self) -> None:
        self.stats['full_searches'] += 1
        candidates = candidate_windows(self._bg_rgb, self.static, self.method)
        self._static = {obj.name: _search_object(self._view(obj), obj, self.method,
                                                 self.overlap, windows=candidates[obj.name])
                        for obj in self.static}
        self._static_in_frame = None

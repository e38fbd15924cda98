"""
Template matching: every instance of every object in a frame (no rclpy).

The score is ``cv2.matchTemplate`` with ``TM_CCORR_NORMED`` by default, which is equation 3.1 of
the thesis (normalized cross-correlation); the method is a parameter. All positions whose score
reaches the object's threshold count, and non-maximum suppression keeps the best of overlapping
ones. Matching runs on luma images (one channel: about ten times faster than three).

``SceneMatcher`` gives the same instances as ``match_scene`` (which searches every template over
the whole search region), fast enough to run on every frame:

- Static objects (ladders, doors...) are searched once in a background image: the frame with the
  moving sprites left out (their pixels keep what was seen there before; the background colour
  where never seen). Each frame, pixels of the background that changed are found with one
  ``absdiff``; a change inside a cached match re-verifies that object in place (the conveyor's
  animation); any other change (the key taken or back, a new room) searches every static object
  around the change, and only there. Matching the background also means that the agent in
  front of a ladder does not lower the ladder's score.
- Moving sprites (the agent, the skull) are searched where their own colours are: the frame's
  pixels of those colours (a lookup table on luma), everything else zeroed, so the background
  behind a sprite does not count. A template of exactly the size of that pixel group which
  matches exactly is taken at once; otherwise every template is searched around the group.

Known limit: colours are told apart by luma, so a background colour with the luma of a sprite
colour would count as the sprite's (no such pair in Room 1).
"""

from dataclasses import dataclass, field
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
    """``cv2.matchTemplate`` scores, higher is better (``TM_SQDIFF_NORMED`` is flipped)."""
    scores = cv2.matchTemplate(image, template, method)
    if method == cv2.TM_SQDIFF_NORMED:
        scores = 1.0 - scores
    return scores


def exact_score(patch: np.ndarray, template: np.ndarray, method: int) -> float:
    """Score of ``template`` on a ``patch`` of its size; an identical patch scores 1 at once."""
    if patch.shape == template.shape and not cv2.norm(patch, template, cv2.NORM_INF):
        return 1.0  # every normalized method gives an exact copy 1: skip the call
    return float(score_map(patch, template, method)[0, 0])


def find_matches(image: np.ndarray, template: np.ndarray, threshold: float, method: int,
                 name: str = '', index: int = 0, dx: int = 0, dy: int = 0) -> List[Match]:
    """Every position of ``template`` in ``image`` scoring at least ``threshold``."""
    h, w = template.shape[:2]
    if image.shape[0] < h or image.shape[1] < w:
        return []
    scores = score_map(image, template, method)
    ys, xs = np.nonzero(scores >= threshold)
    return [Match(name, index, int(x) + dx, int(y) + dy, w, h, float(scores[y, x]))
            for y, x in zip(ys, xs)]


@dataclass
class Template:
    """One template image of an object, prepared for matching."""

    rgb: np.ndarray
    gray: np.ndarray = field(init=False)
    foreground: np.ndarray = field(init=False)
    """uint8 1 where the template differs from the background colour: its mask pixels."""
    background: Tuple[int, int, int] = (0, 0, 0)

    def __post_init__(self):
        self.rgb = np.ascontiguousarray(self.rgb, dtype=np.uint8)
        self.gray = cv2.cvtColor(self.rgb, cv2.COLOR_RGB2GRAY)
        self.foreground = np.any(self.rgb != np.array(self.background, np.uint8),
                                 axis=2).astype(np.uint8)

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


def build_objects(manifest, images) -> List[ObjectModel]:
    """``ObjectModel`` per manifest object, from ``manifest.load_template_images`` output."""
    return [ObjectModel(name=spec.name, threshold=spec.threshold, moves=spec.moves,
                        agent=spec.agent,
                        templates=[Template(rgb, background=manifest.background)
                                   for rgb in images[spec.name]])
            for spec in manifest.objects]


class Scene(NamedTuple):
    """What a frame contains: matches per object (frame coordinates) and sprite pixels."""

    matches: Dict[str, List[Match]]
    sprite_pixels: Dict[str, np.ndarray]
    """Per moving object, uint8 255 on its colours, the size of the search region."""
    backdrop: Dict[str, List[Tuple[Match, np.ndarray]]]
    """For the agent, per match, what the background shows in its box (RGB; the background
    colour where never seen) - used to hide the agent."""


def _search_object(image: np.ndarray, obj: ObjectModel, method: int, overlap: float,
                   dx: int = 0, dy: int = 0) -> List[Match]:
    found = []
    for index, template in enumerate(obj.templates):
        found += find_matches(image, template.gray, obj.threshold, method, obj.name, index,
                              dx, dy)
    return non_max_suppression(found, overlap)


def keyed_image(gray: np.ndarray, obj: ObjectModel) -> Tuple[np.ndarray, np.ndarray]:
    """``(image, pixels)``: luma of the object's own colours only, and where they are."""
    pixels = cv2.LUT(gray, obj.key_lut)
    return cv2.bitwise_and(gray, pixels), pixels


def match_scene(frame: np.ndarray, objects: Sequence[ObjectModel], region,
                method: int = cv2.TM_CCORR_NORMED, overlap: float = 0.0) -> Dict[str, List[Match]]:
    """Search every template over the whole search region, without caches (the reference)."""
    x, y, w, h = region
    gray = cv2.cvtColor(np.ascontiguousarray(frame[y:y + h, x:x + w]), cv2.COLOR_RGB2GRAY)
    result = {}
    for obj in objects:
        image = keyed_image(gray, obj)[0] if obj.moves else gray
        result[obj.name] = _search_object(image, obj, method, overlap, x, y)
    return result


class SceneMatcher:
    """Finds every object in a stream of frames; frames must arrive in time order."""

    def __init__(self, objects: Sequence[ObjectModel], region, background=(0, 0, 0),
                 method: int = cv2.TM_CCORR_NORMED, overlap: float = 0.0):
        self.objects = list(objects)
        self.static = [o for o in self.objects if not o.moves]
        self.moving = [o for o in self.objects if o.moves]
        self.region = tuple(int(v) for v in region)
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
        x0, y0, w, h = self.region
        rgb = frame[y0:y0 + h, x0:x0 + w]
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        self.stats['frames'] += 1
        matches, pixels, boxes = {}, {}, []
        for obj in self.moving:
            found, pixels[obj.name] = self._find_sprites(gray, obj)
            matches[obj.name] = [m.shifted(x0, y0) for m in found]
            boxes += found
        self._update_background(rgb, gray, boxes, list(pixels.values()))
        backdrop = {obj.name: [(m, self._backdrop(m, x0, y0)) for m in matches[obj.name]]
                    for obj in self.moving if obj.agent}
        if self._static_in_frame is None:
            self._static_in_frame = {name: [m.shifted(x0, y0) for m in found]
                                     for name, found in self._static.items()}
        matches.update(self._static_in_frame)
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

    def _backdrop(self, match: Match, x0: int, y0: int) -> np.ndarray:
        x, y = match.x - x0, match.y - y0
        return self._bg_rgb[y:y + match.h, x:x + match.w].copy()

    # Static objects on the background ------------------------------------------------------

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
        changed = cv2.absdiff(gray, self._bg_gray)
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
        """Re-verify cached matches whose boxes changed; search again around other changes."""
        x, y, w, h = cv2.boundingRect(changed)
        m, (rows, cols) = CHANGE_MARGIN, changed.shape
        for obj in self.static:
            for i, match in enumerate(self._static[obj.name]):
                x0, y0 = max(match.x - m, 0), max(match.y - m, 0)
                x1, y1 = min(match.x + match.w + m, cols), min(match.y + match.h + m, rows)
                if (x < x1 and x0 < x + w and y < y1 and y0 < y + h
                        and cv2.countNonZero(changed[y0:y1, x0:x1]) and self._reverify(obj, i)):
                    changed[y0:y1, x0:x1] = 0  # explained: the object is still there
        if cv2.countNonZero(changed):  # an object went, came or moved
            self._search_around(cv2.boundingRect(changed))

    def _reverify(self, obj: ObjectModel, i: int) -> bool:
        """Search ``obj`` again around its ``i``-th cached match; True if still there."""
        self.stats['reverified'] += 1
        old = self._static[obj.name][i]
        for index, template in enumerate(obj.templates):  # an exact match in place (animation)
            tw, th = template.size
            patch = self._bg_gray[old.y:old.y + th, old.x:old.x + tw]
            if patch.shape == template.gray.shape:
                score = exact_score(patch, template.gray, self.method)
                if score >= EXACT_SCORE:
                    self._replace_static(obj, i, Match(obj.name, index, old.x, old.y, tw, th,
                                                       score))
                    return True
        m = CHANGE_MARGIN
        rx, ry = max(old.x - m, 0), max(old.y - m, 0)
        roi = self._bg_gray[ry:old.y + old.h + m, rx:old.x + old.w + m]
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

    def _search_around(self, rect) -> None:
        """
        Search every static object wherever it could overlap ``rect`` (plus the margin).

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

        for obj in self.static:
            mw, mh = obj.max_size
            rx, ry = max(x - mw + 1, 0), max(y - mh + 1, 0)
            roi = self._bg_gray[ry:min(y1 + mh - 1, rows), rx:min(x1 + mw - 1, cols)]
            found = [f for f in _search_object(roi, obj, self.method, self.overlap, rx, ry)
                     if not clear(f)]
            kept = [c for c in self._static[obj.name] if clear(c)]
            self._static[obj.name] = non_max_suppression(kept + found, self.overlap)
        self._static_in_frame = None

    def _search_all(self) -> None:
        self.stats['full_searches'] += 1
        self._static = {obj.name: _search_object(self._bg_gray, obj, self.method, self.overlap)
                        for obj in self.static}
        self._static_in_frame = None

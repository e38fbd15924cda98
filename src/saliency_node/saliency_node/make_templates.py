"""
Regenerate the template PNGs from frames the real emulator renders.

Plays the manifest's ``route`` from a seeded reset (no sticky actions, so every run renders the
same frames) and cuts each template from the frame after its ``step``: a static object's ``box``
as it is; a moving object's sprite as the bounding box of its ``colors`` (inside ``box`` if
given, else inside the search region), every other pixel set to the background colour.

    saliency_make_templates                  # rewrite the PNGs next to the manifest
    saliency_make_templates --check          # exit 1 if a shipped PNG differs from a fresh cut
    saliency_make_templates --list-sprites   # every distinct moving sprite along the route
"""

import argparse
from pathlib import Path
import sys
from typing import Dict, Iterator, List, Tuple

from attention_common.joy_actions import ACTION_MEANINGS
import cv2
import numpy as np
from saliency_node.manifest import load_manifest, Manifest, ManifestError, ObjectSpec


def render_route(manifest: Manifest) -> Iterator[np.ndarray]:
    """Yield the RGB frame after reset and after every action of the route."""
    if manifest.source != 'ale':
        raise ManifestError(f'the manifest has source {manifest.source!r}, not ale: its '
                            f'templates are made by {manifest.maker}')
    import ale_py
    import gymnasium as gym
    gym.register_envs(ale_py)
    unknown = sorted(set(manifest.route) - set(ACTION_MEANINGS))
    if unknown:
        raise ManifestError(f'route has unknown ALE actions: {", ".join(unknown)}')
    env = gym.make(manifest.env_id, frameskip=manifest.frameskip,
                   repeat_action_probability=0.0, full_action_space=True)
    try:
        frame, _ = env.reset(seed=manifest.seed)
        yield frame
        for name in manifest.route:
            frame, _, terminated, truncated, _ = env.step(ACTION_MEANINGS.index(name))
            yield frame
            if terminated or truncated:
                return
    finally:
        env.close()


def color_pixels(patch: np.ndarray, colors) -> np.ndarray:
    """Boolean mask of the pixels of ``patch`` that have one of ``colors``."""
    keep = np.zeros(patch.shape[:2], dtype=bool)
    for color in colors:
        keep |= np.all(patch == color, axis=2)
    return keep


def sprite_box(frame: np.ndarray, colors, area) -> Tuple[int, int, int, int]:
    """Bounding box ``(x, y, w, h)`` of the pixels of ``colors`` inside ``area`` (None: all)."""
    x, y, w, h = area or (0, 0, frame.shape[1], frame.shape[0])
    ys, xs = np.nonzero(color_pixels(frame[y:y + h, x:x + w], colors))
    if len(ys) == 0:
        return (0, 0, 0, 0)
    return (x + int(xs.min()), y + int(ys.min()),
            int(xs.max() - xs.min()) + 1, int(ys.max() - ys.min()) + 1)


def cut_template(frame: np.ndarray, spec: ObjectSpec, box, manifest: Manifest) -> np.ndarray:
    """Cut one template (RGB) from ``frame``."""
    if not spec.moves:
        x, y, w, h = box
        if x < 0 or y < 0 or x + w > frame.shape[1] or y + h > frame.shape[0]:
            raise ManifestError(f'{spec.name}: box {box} leaves the frame')
        return frame[y:y + h, x:x + w].copy()
    x, y, w, h = sprite_box(frame, spec.colors, box or manifest.search_region)
    if w == 0:
        raise ManifestError(f'{spec.name}: none of its colours inside {box or "the region"}')
    patch = frame[y:y + h, x:x + w].copy()
    patch[~color_pixels(patch, spec.colors)] = manifest.background
    return patch


def cut_all(manifest: Manifest) -> Dict[str, np.ndarray]:
    """Every template of the manifest, by file name."""
    wanted: Dict[int, List[Tuple[ObjectSpec, object]]] = {}
    for spec in manifest.objects:
        for template in spec.templates:
            wanted.setdefault(template.step, []).append((spec, template))
    cut = {}
    for step, frame in enumerate(render_route(manifest)):
        for spec, template in wanted.pop(step, []):
            cut[template.file] = cut_template(frame, spec, template.box, manifest)
        if not wanted:
            break
    if wanted:
        raise ManifestError(f'route ends before steps {sorted(wanted)}')
    return cut


def list_sprites(manifest: Manifest) -> None:
    """Print the first step at which each distinct sprite of each moving object appears."""
    moving = [spec for spec in manifest.objects if spec.moves]
    seen = {spec.name: {} for spec in moving}
    for step, frame in enumerate(render_route(manifest)):
        for spec in moving:
            box = sprite_box(frame, spec.colors, manifest.search_region)
            if box[2]:
                key = cut_template(frame, spec, None, manifest).tobytes() + bytes(box[2:])
                seen[spec.name].setdefault(key, (step, box))
    for name, sprites in seen.items():
        print(f'{name}: {len(sprites)} distinct sprites')
        for step, box in sprites.values():
            print(f'  step {step:4d}  box {list(box)}')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--manifest', help='manifest YAML (default: the packaged one)')
    parser.add_argument('--out', help='folder for the PNGs (default: the manifest folder)')
    parser.add_argument('--check', action='store_true',
                        help='compare with the existing PNGs instead of writing')
    parser.add_argument('--list-sprites', action='store_true',
                        help='list distinct sprites of moving objects along the route')
    args = parser.parse_args(argv)
    manifest = load_manifest(args.manifest)
    if args.list_sprites:
        list_sprites(manifest)
        return 0
    out = Path(args.out) if args.out else manifest.folder
    out.mkdir(parents=True, exist_ok=True)
    differing = []
    for file, rgb in cut_all(manifest).items():
        path = out / file
        if args.check:
            existing = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if existing is None or not np.array_equal(existing[:, :, ::-1], rgb):
                differing.append(file)
        else:
            cv2.imwrite(str(path), np.ascontiguousarray(rgb[:, :, ::-1]))
            print(f'{path}  {rgb.shape[1]}x{rgb.shape[0]}')
    if differing:
        print(f'differ from a fresh cut: {", ".join(differing)}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())

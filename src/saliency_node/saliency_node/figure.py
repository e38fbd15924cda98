"""
Draw a picture like the thesis's Figure 3.3: frame, mask and saliency for three utterances.

    saliency_figure                                   # docs/saliency_figure.png
    saliency_figure --out fig.png --step 88 --utterance 'Jump up to get the key' ...

The frame is the one after ``--step`` actions of the manifest's route, rendered by the real
emulator; the matcher sees every frame of the route up to it, as the node would.
"""

import argparse
from pathlib import Path
import sys

import cv2

from saliency_node.grounding import Grounder
from saliency_node.make_templates import render_route
from saliency_node.manifest import load_manifest, load_template_images
from saliency_node.matching import build_objects
from saliency_node.saliency import BLUR_RADIUS, SaliencyConfig, SaliencyMaker

UTTERANCES = (
    'Climb downs the ladder and avoid the skull',
    'Jump up to get the key.',
    'Go back to the top of the ladder and jump onto the rope.',
)


def make_figure(out: Path, step: int, utterances, manifest_path=None) -> Path:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    cv2.setNumThreads(1)
    manifest = load_manifest(manifest_path)
    maker = SaliencyMaker(build_objects(manifest, load_template_images(manifest)),
                          manifest.search_region, manifest.background)
    grounder = Grounder.from_manifest(manifest)
    for index, frame in enumerate(render_route(manifest)):
        scene = maker.observe(frame)
        if index == step:
            break
    else:
        raise ValueError(f'the route has fewer than {step} steps')
    columns = ('observation', 'mask', f'saliency (blur r={BLUR_RADIUS})',
               'faded (rejected variant)')
    fig, axes = plt.subplots(len(utterances), len(columns),
                             figsize=(2.3 * len(columns), 3.3 * len(utterances)))
    for row, text in enumerate(utterances):
        named = grounder.ground(text).objects
        image, mask = maker.render(frame, scene, named, SaliencyConfig(mode='language'))
        faded, _ = maker.render(frame, scene, named, SaliencyConfig(mode='faded'))
        for col, (picture, title) in enumerate(zip((frame, mask * 255, image, faded), columns)):
            axis = axes[row, col]
            axis.imshow(picture, cmap='gray' if picture.ndim == 2 else None,
                        interpolation='nearest', vmin=0, vmax=255)
            axis.set_xticks([])
            axis.set_yticks([])
            if row == 0:
                axis.set_title(title, fontsize=9)
        axes[row, 0].set_ylabel(f'"{text}"\n-> {", ".join(named)}', fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--out', default='docs/saliency_figure.png', help='PNG to write')
    parser.add_argument('--step', type=int, default=12, help='route step of the frame')
    parser.add_argument('--utterance', action='append',
                        help='an utterance (give three; default: the thesis examples)')
    parser.add_argument('--manifest', help='manifest YAML (default: the packaged one)')
    args = parser.parse_args(argv)
    out = make_figure(Path(args.out), args.step, args.utterance or UTTERANCES, args.manifest)
    print(out)
    return 0


if __name__ == '__main__':
    sys.exit(main())

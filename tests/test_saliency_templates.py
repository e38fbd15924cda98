"""The shipped template PNGs are what the real emulator renders, cut deterministically."""

from pathlib import Path
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest

from saliency_node import make_templates
from saliency_node.manifest import load_manifest

BIN = Path(sys.executable).parent


@pytest.mark.slow
def test_the_console_script_regenerates_exactly_the_shipped_templates():
    result = subprocess.run([str(BIN / 'saliency_make_templates'), '--check'],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.slow
def test_check_names_a_template_that_differs_and_a_rewrite_restores_it(tmp_path):
    folder = tmp_path / 'templates'
    shutil.copytree(load_manifest().folder, folder)
    manifest = str(folder / 'manifest.yaml')
    skull = cv2.imread(str(folder / 'skull_03.png'))
    cv2.imwrite(str(folder / 'skull_03.png'), 255 - skull)
    assert make_templates.main(['--manifest', manifest, '--check']) == 1
    assert make_templates.main(['--manifest', manifest]) == 0
    assert np.array_equal(cv2.imread(str(folder / 'skull_03.png')), skull)
    assert make_templates.main(['--manifest', manifest, '--check']) == 0


def test_templates_are_tight_and_moving_sprites_keep_only_their_colours():
    manifest = load_manifest()
    for spec in manifest.objects:
        for template in spec.templates:
            rgb = cv2.imread(str(manifest.folder / template.file))[:, :, ::-1]
            content = np.any(rgb != manifest.background, axis=2)
            if spec.moves:  # cropped to the sprite: every border row and column has a pixel
                assert content[0].any() and content[-1].any(), template.file
                assert content[:, 0].any() and content[:, -1].any(), template.file
                colours = {tuple(c) for c in rgb[content]}
                assert colours <= set(spec.colors), template.file
            else:
                assert (rgb.shape[1], rgb.shape[0]) == template.box[2:], template.file

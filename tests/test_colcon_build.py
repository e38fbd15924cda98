"""colcon builds every package of src/ into an install tree that ``ros2 run`` can use."""

import os
from pathlib import Path
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

import pytest

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / 'src'
COLCON = Path(sys.executable).parent / 'colcon'
NODES = ('env_node', 'feedback_node', 'saliency_node', 'tamer_node', 'trainer_console')
EXECUTABLES = tuple((node, node) for node in NODES) + (
    ('session_bag', 'session_recorder'), ('session_bag', 'attention_bag'),
    ('graph_viewer', 'graph_viewer'))
"""(package, executable): what ``ros2 run <package> <executable>`` starts."""


def package_names():
    """Names declared by every package.xml under src/."""
    return sorted(ElementTree.parse(path).getroot().findtext('name')
                  for path in SRC.glob('*/package.xml'))


@pytest.fixture(scope='module')
def install_base(tmp_path_factory):
    base = tmp_path_factory.mktemp('colcon')
    command = [str(COLCON), '--log-base', str(base / 'log'), 'build',
               '--base-paths', str(SRC), '--build-base', str(base / 'build'),
               '--install-base', str(base / 'install'), '--executor', 'sequential']
    env = dict(os.environ, COLCON_HOME=str(base / 'colcon_home'))
    result = subprocess.run(command, cwd=base, env=env, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, (
        f'colcon build failed ({result.returncode}):\n{result.stdout[-4000:]}\n'
        f'{result.stderr[-4000:]}')
    return base / 'install'


@pytest.mark.slow
def test_every_node_package_is_in_src():
    assert set(NODES) <= set(package_names())


@pytest.mark.slow
@pytest.mark.parametrize('package, name', EXECUTABLES)
def test_executable_is_installed_where_ros2_run_looks(install_base, package, name):
    executable = install_base / package / 'lib' / package / name
    assert executable.is_file(), f'{executable} missing'
    assert os.access(executable, os.X_OK), f'{executable} is not executable'
    assert executable.read_text().startswith('#!')


@pytest.mark.slow
def test_every_package_is_indexed_with_its_manifest(install_base):
    for package in package_names():
        manifest = install_base / package / 'share' / package / 'package.xml'
        assert manifest.is_file(), f'{manifest} missing'
        assert ElementTree.parse(manifest).getroot().findtext('name') == package
        marker = (install_base / package / 'share' / 'ament_index' / 'resource_index' /
                  'packages' / package)
        assert marker.is_file(), f'ament index marker {marker} missing'


@pytest.mark.slow
def test_the_foxglove_layout_is_installed_with_its_package(install_base):
    layouts = list((install_base / 'graph_viewer').rglob('layouts/attention_graph.json'))
    assert layouts, 'the layout file is not in the install tree'

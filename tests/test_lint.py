"""The ament linters a ROS 2 package is held to: ament_flake8 and ament_pep257."""

from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent


@pytest.mark.parametrize('linter', ['ament_flake8', 'ament_pep257'])
def test_code_is_clean_under(linter):
    result = subprocess.run([str(BIN / linter), 'src', 'tests'], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    report = (result.stdout + result.stderr)[-6000:]
    assert result.returncode == 0, f'{linter} found problems:\n{report}'

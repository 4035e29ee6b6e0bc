"""Lint the package's Python sources with ament_flake8 (ROS 2 flake8 rules)."""

import os
from pathlib import Path
import subprocess
import sys

import pytest

PACKAGE_ROOT = Path(__file__).resolve().parent.parent

# Only the package's own sources: never .venv/, build/, install/ or log/.
LINTED_PATHS = ['rigid_body_sim', 'test', 'benchmarks', 'launch', 'setup.py']


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8_finds_no_style_errors_in_package_sources():
    """
    The package and its tests follow the ament flake8 configuration.

    In a process of its own: flake8 forks a pool of workers, and a fork of a test worker
    that ran DDS tests (rclpy's threads) can crash in the child and leave the pool waiting.
    """
    paths = [p for p in LINTED_PATHS if os.path.exists(PACKAGE_ROOT / p)]
    result = subprocess.run([sys.executable, '-m', 'ament_flake8.main', *paths],
                            cwd=PACKAGE_ROOT, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, \
        f'code style errors / warnings:\n{result.stdout}\n{result.stderr}'

"""Lint the package's Python sources with ament_flake8 (ROS 2 flake8 rules)."""

import os
from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

PACKAGE_ROOT = Path(__file__).resolve().parent.parent

# Only the package's own sources: never .venv/, build/, install/ or log/.
LINTED_PATHS = ['rigid_body_sim', 'test', 'benchmarks', 'launch', 'setup.py']


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8_finds_no_style_errors_in_package_sources(monkeypatch):
    """The package and its tests follow the ament flake8 configuration."""
    monkeypatch.chdir(PACKAGE_ROOT)
    paths = [p for p in LINTED_PATHS if os.path.exists(p)]
    rc, errors = main_with_errors(argv=paths)
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + \
        '\n'.join(errors)

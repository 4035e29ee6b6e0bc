"""Check the package's docstrings with ament_pep257 (ROS 2 docstring rules)."""

import os
from pathlib import Path

from ament_pep257.main import main
import pytest

PACKAGE_ROOT = Path(__file__).resolve().parent.parent

# Only the package's own sources: never .venv/, build/, install/ or log/.
LINTED_PATHS = ['rigid_body_sim', 'test', 'benchmarks', 'launch', 'setup.py']


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257_finds_no_docstring_errors_in_package_sources(monkeypatch):
    """The package and its tests follow the ament pep257 convention."""
    monkeypatch.chdir(PACKAGE_ROOT)
    paths = [p for p in LINTED_PATHS if os.path.exists(p)]
    rc = main(argv=paths)
    assert rc == 0, 'Found code style errors / warnings'

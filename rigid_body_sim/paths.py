"""
Locate the installed configuration of rigid_body_sim.

The configuration (``config/*.yaml`` and ``config/scenes/*.yaml``, and the RViz config
``rviz/rigid_body_sim.rviz``) is found in the first of these places that exists:

1. the package's share directory from the ament index, as in a colcon
   install whose prefix is on ``AMENT_PREFIX_PATH`` (``source install/setup.bash``);
2. the ``config/`` directory of the source tree next to this package, as in
   an editable (``pip install -e .``) or in-tree development set-up;
3. ``<sys.prefix>/share/rigid_body_sim``, as in a plain ``pip install`` of the
   package into a virtual environment.
"""

from __future__ import annotations

from pathlib import Path
import sys

PACKAGE_NAME = 'rigid_body_sim'


def _ament_share_dir() -> Path | None:
    """
    Return the share directory the ament index knows for this package.

    :returns: the share directory, or None when ament_index_python is not
        importable, ``AMENT_PREFIX_PATH`` is unset, or no prefix on it holds
        this package's marker.
    """
    try:
        from ament_index_python.packages import get_package_share_directory
    except ImportError:
        return None
    try:
        share = Path(get_package_share_directory(PACKAGE_NAME))
    except (LookupError, OSError, ValueError):
        return None
    return share if share.is_dir() else None


def _source_share_dir() -> Path | None:
    """
    Return the source tree's root when it holds a ``config/`` directory.

    :returns: the directory above this package, which plays the role of the
        share directory in an editable install, or None when there is no
        ``config/`` beside the package (a non-editable install).
    """
    root = Path(__file__).resolve().parent.parent
    if (root / 'config').is_dir() and (root / 'package.xml').is_file():
        return root
    return None


def share_dir() -> Path:
    """
    Return the directory that holds this package's ``config/`` directory.

    :returns: the ament share directory, else the source tree root, else
        ``<sys.prefix>/share/rigid_body_sim`` (which may not exist).
    """
    for candidate in (_ament_share_dir(), _source_share_dir()):
        if candidate is not None:
            return candidate
    return Path(sys.prefix) / 'share' / PACKAGE_NAME


def config_dir() -> Path:
    """
    Return the directory of the package's configuration files.

    :returns: ``share_dir() / 'config'``, holding ``rigid_body_sim.yaml``.
    """
    return share_dir() / 'config'


def scenes_dir() -> Path:
    """
    Return the directory of the scene files.

    :returns: ``config_dir() / 'scenes'``, holding ``*.yaml`` scenes.
    """
    return config_dir() / 'scenes'


def rviz_config() -> Path:
    """
    Return the package's RViz config, for ``rviz2 -d`` (sim.launch.py starts RViz with it).

    :returns: ``share_dir() / 'rviz' / 'rigid_body_sim.rviz'``.
    """
    return share_dir() / 'rviz' / 'rigid_body_sim.rviz'

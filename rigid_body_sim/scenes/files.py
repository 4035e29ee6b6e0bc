"""
Scene files: the built-in ones by name (``config/scenes``), any other by path.

:func:`load_scene` finds the file (:func:`find_scene`), reads its YAML strictly
(:mod:`.strict_yaml`) and validates it (:func:`.schema.parse_scene`); :func:`default_body`
and :func:`default_state` are those of the node's default scene, for callers that want the
body or the state alone.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
import re
import stat

from .schema import parse_scene
from .schema import Scene
from .strict_yaml import read_scene_yaml
from ..paths import scenes_dir
from ..physics import RigidBody
from ..physics import State
from ..text import one_line_errors

__all__ = ['DEFAULT_SCENE', 'default_body', 'default_state', 'find_scene', 'load_scene',
           'scene_names']

DEFAULT_SCENE = 'default'
"""The node's default scene: the T-handle with external_wrench, so a newcomer can push it."""


# A built-in scene of several bodies: its `bodies:` key at the top level of the file.
_BODIES_KEY = re.compile(r'^bodies\s*:', re.MULTILINE)


def scene_names(several_bodies: bool | None = None) -> list[str]:
    """
    Return the names of the built-in scenes (``config/scenes/*.yaml``), sorted.

    several_bodies: None for all of them; True for the scenes of a ``bodies:`` list only,
    False for the one-body scenes only (what the work-precision benchmark and the
    one-body tests take).
    """
    paths = sorted(Path(scenes_dir()).glob('*.yaml'))
    if several_bodies is not None:
        paths = [path for path in paths
                 if bool(_BODIES_KEY.search(path.read_text())) == several_bodies]
    return [path.stem for path in paths]


@one_line_errors
def find_scene(name_or_path: str | os.PathLike[str]) -> Path:
    """
    Return the file of a scene given by built-in name or by path.

    A value with a path separator or a ``.yaml``/``.yml`` ending is a path; anything else
    is a built-in name.  ValueError if there is no such file (listing the built-ins).
    """
    text = str(name_or_path)
    if not text:
        raise ValueError(f'scene: empty name; built-in scenes: {", ".join(scene_names())}')
    given_path = '/' in text or text.endswith(('.yaml', '.yml'))
    path = Path(text).expanduser() if given_path else Path(scenes_dir()) / f'{text}.yaml'
    kind = _file_kind(path, text)
    if given_path:
        if kind == 'directory':
            raise ValueError(f'scene {text!r} is a directory; give the path of a .yaml file '
                             'in it')
        if kind is None:
            raise ValueError(f'scene file {text!r} does not exist')
        if kind != 'file':
            raise ValueError(f'scene {text!r} is {kind}, not a regular file; give the path '
                             'of a .yaml file')
        return path
    if kind != 'file':
        raise ValueError(f'unknown scene {text!r}; built-in scenes: {", ".join(scene_names())}'
                         ' (or give a path to a .yaml file)')
    return path


# What a path that is not a regular file is, in a message (S_IS* test, words).
_FILE_KINDS = ((stat.S_ISFIFO, 'a FIFO (named pipe)'), (stat.S_ISCHR, 'a character device'),
               (stat.S_ISBLK, 'a block device'), (stat.S_ISSOCK, 'a socket'))


def _file_kind(path: Path, text: str) -> str | None:
    """
    Return 'file', 'directory', None (nothing there) or what else the path is, in words.

    Only stat: a FIFO is never opened (opening one blocks until a writer comes), a device
    never read (/dev/zero has no end).
    """
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return 'a broken symlink' if path.is_symlink() else None
    except OSError as error:
        if error.errno == errno.ELOOP:
            return 'a symlink loop'
        if error.errno == errno.ENOTDIR:
            return None
        raise ValueError(f'scene {text!r}: {error.strerror or error}') from None
    except ValueError as error:  # a null character
        raise ValueError(f'scene {text!r}: {error}') from None
    if stat.S_ISREG(mode):
        return 'file'
    if stat.S_ISDIR(mode):
        return 'directory'
    return next((words for test, words in _FILE_KINDS if test(mode)), 'not a regular file')


@one_line_errors
def load_scene(name_or_path: str | os.PathLike[str] = DEFAULT_SCENE) -> Scene:
    """
    Read, validate and return a scene, by built-in name or by path.

    Raises
    ------
    ValueError
        If the file is missing or is not valid YAML, or for any problem of the scene; the
        message names the file, the key path and what is wrong.

    """
    path = find_scene(name_or_path)
    builtin = path.parent.resolve() == Path(scenes_dir()).resolve()
    source = f'scenes/{path.name}' if builtin else str(name_or_path)
    try:
        with open(path, encoding='utf-8') as stream:
            data = read_scene_yaml(stream, source)
    except OSError as error:
        raise ValueError(f'{source}: cannot read: {error.strerror}') from None
    except UnicodeDecodeError as error:
        raise ValueError(f'{source}: not UTF-8 text: byte {error.object[error.start]:#04x} at '
                         f'offset {error.start}') from None
    return parse_scene(data, source, path.parent)


def default_body() -> RigidBody:
    """Return the default scene's RigidBody (the T-handle: mass 1 kg, I = diag(1, 2, 3) kg m^2)."""
    return load_scene(DEFAULT_SCENE).body


def default_state() -> State:
    """Return the default scene's initial State: at the origin, at rest, spinning near axis 2."""
    return load_scene(DEFAULT_SCENE).state

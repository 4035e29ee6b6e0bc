"""
Scene files: the built-in ones by name (``config/scenes``), any other by path.

:func:`load_scene` finds the file (:func:`find_scene`), reads its YAML strictly
(:mod:`.strict_yaml`) and validates it (:func:`.schema.parse_scene`); :func:`default_body`
and :func:`default_state` are those of the node's default scene, for callers that want the
body or the state alone.
"""

from pathlib import Path

from .schema import parse_scene
from .strict_yaml import read_scene_yaml
from ..paths import scenes_dir
from ..text import one_line_errors

__all__ = ['DEFAULT_SCENE', 'default_body', 'default_state', 'find_scene', 'load_scene',
           'scene_names']

DEFAULT_SCENE = 'default'
"""The node's default scene: the T-handle with external_wrench, so a newcomer can push it."""


def scene_names():
    """Return the names of the built-in scenes (``config/scenes/*.yaml``), sorted."""
    return sorted(path.stem for path in Path(scenes_dir()).glob('*.yaml'))


@one_line_errors
def find_scene(name_or_path):
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
    try:
        is_dir, is_file = path.is_dir(), path.is_file()
    except (OSError, ValueError) as error:  # a name too long, a null character
        raise ValueError(f'scene {text!r}: {getattr(error, "strerror", None) or error}') \
            from None
    if given_path:
        if is_dir:
            raise ValueError(f'scene {text!r} is a directory; give the path of a .yaml file '
                             'in it')
        if not is_file:
            raise ValueError(f'scene file {text!r} does not exist')
        return path
    if not is_file:
        raise ValueError(f'unknown scene {text!r}; built-in scenes: {", ".join(scene_names())}'
                         ' (or give a path to a .yaml file)')
    return path


@one_line_errors
def load_scene(name_or_path=DEFAULT_SCENE):
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


def default_body():
    """Return the default scene's RigidBody (the T-handle: mass 1 kg, I = diag(1, 2, 3) kg m^2)."""
    return load_scene(DEFAULT_SCENE).body


def default_state():
    """Return the default scene's initial State: at the origin, at rest, spinning near axis 2."""
    return load_scene(DEFAULT_SCENE).state

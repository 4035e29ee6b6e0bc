"""
Scenes: a body, its initial state, the effects on it, how to run it and how to draw it.

The package's modules, from the bottom: :mod:`.limits` (the ranges and bounds),
:mod:`.strict_yaml` (a scene file's YAML, read strictly), :mod:`.schema` (what a scene is
and its validation), :mod:`.files` (the built-in scenes and loading by name or path).  Every
public name is here too: ``from rigid_body_sim.scenes import load_scene``.

A scene is a YAML file (schema: the comment block of ``config/scenes/default.yaml`` and the
docs/scenes.md; units SI).  :func:`load_scene` reads a built-in scene by name
(``config/scenes/<name>.yaml``, found with :func:`rigid_body_sim.paths.scenes_dir`) or any
file by path, validates it strictly and returns a :class:`Scene` value: unknown keys, wrong
types, missing values and non-physical bodies are ValueErrors whose message names the file,
the key path and what is wrong, e.g.
``scenes/heavy_top.yaml: effects[0].pivot.point: expected 3 numbers, got 2``.

The YAML is read more strictly than ``yaml.safe_load`` (:func:`read_scene_yaml`): a key given
twice in one mapping is an error (``body.size: duplicate key (lines 5 and 9)``), and numbers
are YAML 1.2's, so ``damping: 1e-3`` is a float.  A section key with nothing after it
(``initial:``, ``draw:``, ``body:``, ``effects:``, an effect's ``- pivot:``) is an error, as its
lines were likely lost: leave a section out for its defaults, ``effects: []`` means none.

For the node: ``scene = load_scene(name_or_path)``, then
``scene = scene.with_overrides(...)`` with the body and initial-state parameters the user
set (they win over the scene's values, and are validated the same way), then
``simulator = scene.simulator()``.  Subscribe to the torque and wrench topics only if
``scene.accepts_external_wrench``, and pass the input through
``scene.external_wrench.limit(force, torque)`` before ``simulator.set_wrench``.
"""

from .files import default_body
from .files import DEFAULT_SCENE
from .files import default_state
from .files import find_scene
from .files import load_scene
from .files import scene_names
from .limits import MAX_SCENE_DEPTH
from .limits import MAX_SCENE_SIZE
from .limits import MAX_SCENE_VALUES
from .limits import RATE_RANGE
from .limits import SUBSTEPS_RANGE
from .limits import TOLERANCE_RANGE
from .schema import DEFAULT_TOLERANCE
from .schema import Drawing
from .schema import parse_scene
from .schema import Scene
from .schema import SHAPES
from .strict_yaml import read_scene_yaml

__all__ = [
    'DEFAULT_SCENE',
    'DEFAULT_TOLERANCE',
    'Drawing',
    'MAX_SCENE_DEPTH',
    'MAX_SCENE_SIZE',
    'MAX_SCENE_VALUES',
    'RATE_RANGE',
    'Scene',
    'SHAPES',
    'SUBSTEPS_RANGE',
    'TOLERANCE_RANGE',
    'default_body',
    'default_state',
    'find_scene',
    'load_scene',
    'parse_scene',
    'read_scene_yaml',
    'scene_names',
]

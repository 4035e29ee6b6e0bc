"""
What a scene is: its values and the validation of its mapping.

:func:`parse_scene` validates a scene's mapping (as YAML gives it) into a :class:`Scene`,
which holds a :class:`Drawing`.  The schema is the comment block of
``config/scenes/default.yaml`` and docs/scenes.md (units SI).  Unknown keys, wrong types,
missing values and non-physical bodies are ValueErrors whose message names the source, the
key path and what is wrong, e.g.
``scenes/heavy_top.yaml: effects[0].pivot.point: expected 3 numbers, got 2``.  A section key
with nothing after it (``initial:``, ``draw:``, ``body:``, ``effects:``, an effect's
``- pivot:``) is an error, as its lines were likely lost: leave a section out for its
defaults, ``effects: []`` means none.
"""

from __future__ import annotations

from collections.abc import Iterable
from collections.abc import Mapping
import copy
from dataclasses import dataclass
from dataclasses import field
from dataclasses import replace
from pathlib import Path
import re
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from .limits import MAX_BODIES
from .limits import MAX_BODY_NAME_LENGTH
from .limits import MAX_DESCRIPTION_LENGTH
from .limits import MAX_NAME_LENGTH
from .limits import RATE_RANGE
from .limits import TOLERANCE_RANGE
from .strict_yaml import is_yaml_number
from ..physics import INTEGRATORS
from ..physics import RigidBody
from ..physics import Simulator
from ..physics import State
from ..physics import World
from ..physics.effects import create_effect
from ..physics.effects import EFFECTS
from ..physics.effects import ExternalWrench
from ..physics.effects import load_effect_file
from ..physics.effects import ParameterError
from ..physics.effects import Pivot
from ..physics.effects import PluginError
from ..physics.effects.registry import check_number
from ..physics.effects.registry import check_vector
from ..physics.effects.registry import describe_value
from ..physics.effects.registry import Effect
from ..physics.effects.registry import unknown_effect
from ..physics.imu import Imu
from ..physics.imu import ImuModel
from ..physics.rotations import quaternion_from_matrix
from ..text import one_line_errors

__all__ = ['DEFAULT_TOLERANCE', 'Drawing', 'SHAPES', 'Scene', 'parse_scene']

DEFAULT_INTEGRATOR = 'buss'
DEFAULT_RATE = 100.0
DEFAULT_TOLERANCE = 1e-7
"""Error control (rad per simulated s) of a scene file without ``tolerance:``: the largest
that keeps every built-in scene within 1e-3 rad over 60 s (the T-handle and the tennis racket
need it); the built-in scenes set their own, the largest each allows (docs/scenes.md)."""
DEFAULT_COLOR = (0.8, 0.5, 0.2, 1.0)
SHAPES = ('box', 'cylinder', 'sphere', 'ellipsoid')
"""Body shapes with a closed-form inertia (``body.shape``) and the shapes a scene draws."""

# The keys each part of a scene may have; anything else is an error.
_TOP_KEYS = ('name', 'description', 'plugins', 'body', 'initial', 'effects', 'integrator',
             'rate', 'tolerance', 'imu', 'draw', 'bodies')
# What each entry of `bodies:` may give; the same keys at the top are every body's default.
_BODY_KEYS = ('name', 'body', 'initial', 'effects', 'imu', 'draw')
_BODY_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*')
_IMU_KEYS = ('position', 'orientation') + ImuModel.NOISE_KEYS + ('seed',)
_IMU_UNITS = {'gyro_noise_density': 'rad/s/sqrt(Hz)', 'gyro_random_walk': 'rad/s^2/sqrt(Hz)',
              'gyro_bias_sigma': 'rad/s', 'accel_noise_density': 'm/s^2/sqrt(Hz)',
              'accel_random_walk': 'm/s^3/sqrt(Hz)', 'accel_bias_sigma': 'm/s^2'}
_SHAPE_KEYS = {
    'box': ('size',),
    'cylinder': ('radius', 'height'),
    'sphere': ('radius',),
    'ellipsoid': ('semi_axes',),
}
_INITIAL_KEYS = ('orientation', 'angular_velocity_body', 'angular_velocity_world', 'position',
                 'velocity')
_DRAW_KEYS = ('shape', 'size', 'color')
# A flat body (I1 + I2 = I3) has an equivalent box of zero thickness: draw it this thin
# relative to its largest extent instead, so that it stays visible.
_THINNEST_DRAWING = 0.01
# How far a scene's orientation quaternion may be from unit norm before it is an error.
_QUATERNION_NORM_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Drawing:
    """
    How to draw the body: a shape in the body frame, sized like visualization_msgs/Marker.

    Attributes
    ----------
    shape : str
        'box', 'cylinder' (axis along the drawing's z), 'sphere' or 'ellipsoid'.
    size : tuple of 3 floats
        Extents in m along the drawing's x, y, z: box edges; cylinder (2 r, 2 r, height);
        sphere and ellipsoid the diameters.  This is a Marker's ``scale``.
    color : tuple of 4 floats
        (r, g, b, a), each 0..1.
    orientation : tuple of 4 floats
        Quaternion (x, y, z, w) of the drawing's axes in the body frame: identity, except
        for a box drawn from a non-diagonal inertia, which lies along the principal axes.
    derived : bool
        True if the drawing was derived from the body (no ``draw.size`` in the scene), so
        it follows a body override.

    """

    shape: str
    size: tuple
    color: tuple = DEFAULT_COLOR
    orientation: tuple = (0.0, 0.0, 0.0, 1.0)
    derived: bool = True


@dataclass(frozen=True)
class Scene:
    """
    A validated scene: everything needed to simulate and show one experiment.

    Attributes
    ----------
    name : str
        The scene's name (for a built-in scene, its file name without ``.yaml``).
    description : str
        One line saying what the scene shows.
    body : RigidBody
        Mass (kg) and inertia about the COM (kg m^2, body frame).
    state : State
        Initial state, world frame; in a pivot scene already on the constraint (the COM
        position and velocity derived from the pivot).
    effects : tuple
        The effect instances, in the scene's order.
    integrator : str
        Name of the default integrator (a key of INTEGRATORS).
    rate : float
        Default step rate in Hz: the node's tick and the step dt = 1 / rate.
    tolerance : float or None
        Error control in rad per simulated s (Simulator's tolerance): each tick is split
        into as many substeps as keep the orientation error added per second below it;
        None: off (``tolerance: 0``), one step per tick.
    drawing : Drawing
        How to draw the body.
    source : str
        Where the scene came from (the file, for messages).
    data : dict
        The scene's validated mapping, as in the file (used by :meth:`with_overrides`),
        but its plugins' paths made absolute.
    plugins : tuple of str
        The absolute paths of the effect plugin files the scene loaded (``plugins:``).
    bodies : tuple of Scene
        A scene of several bodies (``bodies:``): each body as a one-body scene named after
        it (its body, state, effects, IMU and drawing; the scene's integrator, rate and
        tolerance); the attributes above that describe one body are then the first one's.
        Empty for a one-body scene.  :attr:`members` gives the bodies of either kind.

    """

    name: str
    description: str
    body: RigidBody
    state: State
    effects: tuple
    integrator: str
    rate: float
    drawing: Drawing
    tolerance: float | None = DEFAULT_TOLERANCE
    imu: ImuModel = ImuModel()
    source: str = '<scene>'
    data: dict = field(default_factory=dict, repr=False, compare=False)
    plugins: tuple[str, ...] = ()
    bodies: tuple[Scene, ...] = ()

    @property
    def members(self) -> tuple[Scene, ...]:
        """Return the bodies, each a one-body scene: the scene itself if it has one body."""
        return self.bodies or (self,)

    @property
    def has_named_bodies(self) -> bool:
        """Return True for a scene of ``bodies:`` (topics and frames under the bodies' names)."""
        return bool(self.bodies)

    def world(self, integrator: str | None = None, tolerance: float | None = None) -> World:
        """
        Return a World of the scene's bodies, each with its effects, at their initial states.

        integrator, tolerance (rad/s; 0: off): replace the scene's, as in :meth:`simulator`.
        """
        tolerance = self.tolerance if tolerance is None else tolerance
        return World(((member.name, member.simulator()) for member in self.members),
                     integrator=self.integrator if integrator is None else integrator,
                     tolerance=tolerance or None)

    @property
    def dt(self) -> float:
        """Return the default step in s: 1 / rate."""
        return 1.0 / self.rate

    @property
    def external_wrench(self) -> ExternalWrench | None:
        """Return the scene's external_wrench effect, or None if it takes no outside input."""
        return self._effect('external_wrench')

    @property
    def accepts_external_wrench(self) -> bool:
        """Return True if the scene takes a wrench from outside (the node's topics)."""
        return any(getattr(e, 'accepts_external_wrench', False) for e in self.effects)

    @property
    def pivot(self) -> Pivot | None:
        """Return the scene's pivot effect, or None if the body is free."""
        return self._effect('pivot')

    @property
    def gravity(self) -> NDArray[np.float64]:
        """Return the gravitational field in m/s^2, world frame (zeros without gravity)."""
        gravity = self._effect('gravity')
        return np.zeros(3) if gravity is None else np.array(gravity.acceleration)

    def imu_sensor(self, model: ImuModel | None = None) -> Imu:
        """Return the IMU of `model` (default: the scene's) on the body, gravity and pivot."""
        pivot = self.pivot
        return Imu(self.imu if model is None else model, self.body, self.gravity,
                   None if pivot is None else -np.asarray(pivot.point, dtype=float))

    def effect_names(self) -> list[str]:
        """Return the names of the scene's effects, in order."""
        return [getattr(effect, 'effect_name', type(effect).__name__) for effect in self.effects]

    def simulator(self, body: RigidBody | None = None, state: State | None = None,
                  integrator: str | None = None, tolerance: float | None = None) -> Simulator:
        """
        Return a Simulator of this scene, with its effects.

        A scene of several bodies has none (ValueError): see :meth:`world`.

        Parameters
        ----------
        body : RigidBody, optional
            Replaces the scene's body (prefer :meth:`with_overrides`, which also rebuilds
            the state for it).
        state : State, optional
            Replaces the initial state (projected onto a pivot, if the scene has one).
        integrator : str, optional
            Replaces the scene's integrator.
        tolerance : float, optional
            Replaces the scene's tolerance (rad/s; 0: off).

        """
        if self.bodies:
            raise ValueError(f'{self.source}: a scene of {len(self.bodies)} bodies (bodies:); '
                             'this takes a scene of one body: its bodies are simulated together '
                             'by Scene.world()')
        return Simulator(self.body if body is None else body,
                         self.state if state is None else state,
                         integrator=self.integrator if integrator is None else integrator,
                         effects=self.effects,
                         tolerance=self.tolerance if tolerance is None else tolerance)

    def with_overrides(self, mass: float | None = None, inertia: ArrayLike | None = None,
                       orientation: ArrayLike | None = None,
                       angular_velocity_body: ArrayLike | None = None,
                       angular_velocity_world: ArrayLike | None = None,
                       position: ArrayLike | None = None, velocity: ArrayLike | None = None,
                       integrator: str | None = None, rate: float | None = None,
                       body: Mapping[str, Any] | None = None,
                       tolerance: float | None = None) -> Scene:
        """
        Return the scene with some body, initial-state or run values replaced.

        What is None keeps the scene's value.  The new values are validated like the file
        (messages name ``<source> (overrides): <key path>``), and the scene is rebuilt:

        - body: a mapping in the scene's body schema (e.g. ``{'shape': 'cylinder',
          'radius': 0.1, 'height': 0.05}``) replacing the body section; its mass defaults
          to the scene's.  mass and inertia below apply on top of it.
        - mass: a body given by shape keeps its shape (its inertia scales with the mass); a
          body given by inertia keeps it.
        - inertia (3 diagonal entries, 9 row-major entries or 3x3; kg m^2): replaces the
          shape; a drawing derived from the body follows it.  An inertia equal to the
          body's own is no override (so a node may pass back the values it showed).
        - orientation (quaternion x, y, z, w), angular_velocity_body or
          angular_velocity_world (rad/s; one replaces the other), position (m), velocity
          (m/s): the initial state is rebuilt from these velocities, so a new body keeps the
          scene's angular velocity, not its angular momentum.  In a pivot scene position and
          velocity follow from the pivot and may not be given.
        - integrator (name), rate (Hz), tolerance (rad/s, 0: off).

        """
        if self.bodies and any(value is not None for value in (
                mass, inertia, orientation, angular_velocity_body, angular_velocity_world,
                position, velocity, body)):
            raise ValueError(f'{self.source}: the body and initial overrides are for a scene '
                             f'of one body; this one has {len(self.bodies)} (bodies:): change '
                             'them in its file')
        data = copy.deepcopy(self.data)
        if body is not None:
            replaced = _plain(dict(body)) if isinstance(body, dict) else body
            if isinstance(replaced, dict):
                replaced.setdefault('mass', data['body'].get('mass'))
            data['body'] = replaced
        elif inertia is not None and _same_tensor(inertia, self.body.inertia):
            inertia = None
        section = data.get('body')
        if inertia is not None and isinstance(section, dict):
            section = data['body'] = {'mass': section.get('mass'), 'inertia': _plain(inertia)}
        if mass is not None and isinstance(section, dict):
            section['mass'] = _plain(mass)
        initial = data.get('initial') or {}
        for key, value in (('orientation', orientation), ('position', position),
                           ('velocity', velocity)):
            if value is not None:
                initial[key] = _plain(value)
        for key, value, other in (
                ('angular_velocity_body', angular_velocity_body, 'angular_velocity_world'),
                ('angular_velocity_world', angular_velocity_world, 'angular_velocity_body')):
            if value is not None:
                initial.pop(other, None)
                initial[key] = _plain(value)
        if initial:
            data['initial'] = initial
        if integrator is not None:
            data['integrator'] = integrator
        if rate is not None:
            data['rate'] = _plain(rate)
        if tolerance is not None:
            data['tolerance'] = _plain(tolerance)
        return parse_scene(data, f'{self.source} (overrides)')

    def _effect(self, name: str) -> Any:
        for effect in self.effects:
            if getattr(effect, 'effect_name', None) == name:
                return effect
        return None


@one_line_errors
def parse_scene(data: Any, source: str = '<scene>',
                folder: str | Path | None = None) -> Scene:
    """
    Validate a scene's mapping (as from YAML) and return the :class:`Scene`.

    `source` names the scene in error messages; `folder` is the folder the paths of its
    ``plugins:`` are relative to (None: they must be absolute).  The schema: see the module
    docstring.
    """
    # Overflows (a 1e308 in a quaternion's norm, a mass times a size squared) give inf or
    # nan, which the reader's finiteness checks then refuse naming the key: numpy's
    # RuntimeWarnings on the way would only add lines without the key.
    with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
        return _SceneReader(source, folder).read(data)


class _SceneReader:
    """Validates one scene mapping; every error names the source and the key path."""

    def __init__(self, source: str, folder: str | Path | None = None) -> None:
        self.source = source
        self.folder = folder

    def error(self, path: str, problem: str) -> ValueError:
        # Escaped and cut to one line by parse_scene (one_line_errors).
        prefix = f'{self.source}: {path}: ' if path else f'{self.source}: '
        return ValueError(prefix + problem)

    def read(self, data: Any) -> Scene:
        mapping = self.mapping(data, '', _TOP_KEYS)
        self.reject_empty_sections(mapping)
        if 'bodies' in mapping:
            return self.read_bodies(mapping)
        for key in ('name', 'description', 'body'):
            if key not in mapping or mapping[key] is None:
                raise self.error(key, 'missing; the scene requires it')
        name = self.text(mapping['name'], 'name', MAX_NAME_LENGTH)
        description = self.text(mapping['description'], 'description', MAX_DESCRIPTION_LENGTH)
        body, body_shape = self.body(mapping['body'])
        plugins = self.plugins(mapping['plugins']) if 'plugins' in mapping else ()
        effects = self.effects(mapping.get('effects', []))
        pivot = next((e for e in effects if getattr(e, 'effect_name', None) == 'pivot'), None)
        self.pivot_path = next((f'effects[{index}].pivot' for index, e in enumerate(effects)
                                if e is pivot), 'effects')
        state = self.initial(mapping.get('initial', {}), body, pivot)
        integrator = mapping.get('integrator', DEFAULT_INTEGRATOR)
        if not isinstance(integrator, str) or integrator not in INTEGRATORS:
            valid = ', '.join(sorted(INTEGRATORS))
            raise self.error('integrator', f'unknown integrator {integrator!r}; valid: {valid}')
        rate = self.number(mapping.get('rate', DEFAULT_RATE), 'rate', 'Hz', positive=True)
        # The node's range for its rate parameter (node/parameters.py): beyond it a tick is
        # too short for the clock (and 1 / rate underflows long before 1e308 Hz).
        if not RATE_RANGE[0] <= rate <= RATE_RANGE[1]:
            raise self.error('rate', f'must be {RATE_RANGE[0]:g} to {RATE_RANGE[1]:g} Hz, got '
                                     f'{rate:g}')
        tolerance = self.number(mapping.get('tolerance', DEFAULT_TOLERANCE), 'tolerance',
                                'rad/s')
        if not TOLERANCE_RANGE[0] <= tolerance <= TOLERANCE_RANGE[1]:
            raise self.error('tolerance', f'must be {TOLERANCE_RANGE[0]:g} (off) to '
                                          f'{TOLERANCE_RANGE[1]:g} rad/s, got {tolerance:g}')
        drawing = self.drawing(mapping.get('draw', {}), body, body_shape, mapping['body'])
        imu = self.imu(mapping.get('imu', {}))
        data = copy.deepcopy(mapping)
        if plugins:
            data['plugins'] = list(plugins)
        return Scene(name=name, description=description, body=body, state=state,
                     effects=tuple(effects), integrator=integrator, rate=rate,
                     drawing=drawing, source=self.source, data=data,
                     tolerance=tolerance or None, imu=imu, plugins=plugins)

    def read_bodies(self, mapping: dict[str, Any]) -> Scene:
        """
        Return the Scene of a ``bodies:`` list, each body read as a one-body scene.

        An entry's ``body``, ``initial``, ``effects``, ``imu`` and ``draw`` replace the
        scene-wide ones given at the top (each section whole, not merged key by key).
        """
        for key in ('name', 'description'):
            if key not in mapping or mapping[key] is None:
                raise self.error(key, 'missing; the scene requires it')
        name = self.text(mapping['name'], 'name', MAX_NAME_LENGTH)
        description = self.text(mapping['description'], 'description', MAX_DESCRIPTION_LENGTH)
        entries = mapping['bodies']
        if not isinstance(entries, list) or not entries:
            raise self.error('bodies', 'expected a list of bodies, each a mapping with a name, '
                                       f'got {describe_value(entries)}')
        if len(entries) > MAX_BODIES:
            raise self.error('bodies', f'{len(entries)} bodies; a scene takes at most '
                                       f'{MAX_BODIES}')
        shared = {key: mapping[key] for key in _TOP_KEYS
                  if key in mapping and key not in ('name', 'bodies')}
        named: dict[str, int] = {}
        members = []
        for index, entry in enumerate(entries):
            path = f'bodies[{index}]'
            entry = self.mapping(entry, path, _BODY_KEYS, required=('name',))
            body_name = self.body_name(entry['name'], f'{path}.name')
            if body_name in named:
                raise self.error(f'{path}.name', f'{body_name!r} is the name of '
                                                 f'bodies[{named[body_name]}] too; each body '
                                                 'needs a name of its own')
            named[body_name] = index
            single = dict(shared, **entry)
            if single.get('body') is None:
                raise self.error(f'{path}.body', 'missing; give the body here or a scene-wide '
                                                 'body: for every body')
            members.append(_SceneReader(f'{self.source}: {path}', self.folder).read(single))
        first = members[0]
        return replace(first, name=name, description=description, source=self.source,
                       data=copy.deepcopy(mapping), bodies=tuple(members))

    def body_name(self, value: Any, path: str) -> str:
        """Return a body's name: a ROS name token (its topics' and frame's namespace)."""
        if not isinstance(value, str) or not _BODY_NAME.fullmatch(value):
            raise self.error(path, f'expected a name of letters, digits and _ starting with a '
                                   "letter (it names the body's topics and frame), got "
                                   f'{describe_value(value)}')
        if len(value) > MAX_BODY_NAME_LENGTH:
            raise self.error(path, f'{len(value)} characters; give at most '
                                   f'{MAX_BODY_NAME_LENGTH}')
        return value

    def reject_empty_sections(self, mapping: dict[str, Any]) -> None:
        """
        Raise for a section key with nothing after it (``initial:`` alone).

        YAML reads it as null, which could be taken for "the defaults", but more likely the
        lines below it were lost or mis-indented.  Leaving a section out is the documented
        way to get its defaults; ``effects: []`` says "no effects".
        """
        for key in ('body', 'initial', 'imu', 'draw', 'plugins', 'bodies'):
            if key in mapping and mapping[key] is None:
                remedy = ('the scene requires it' if key == 'body' else
                          'give its keys, or leave the line out for the defaults')
                raise self.error(key, f'empty; {remedy}')
        if 'effects' in mapping and mapping['effects'] is None:
            raise self.error('effects', 'empty; list the effects, or write effects: [] '
                                        'for none')

    # -- generic checks

    def mapping(self, value: Any, path: str, keys: Iterable[str],
                required: Iterable[str] = ()) -> dict[str, Any]:
        where = path or 'the scene'
        if not isinstance(value, dict):
            raise self.error(path, f'expected a mapping of keys, got {describe_value(value)}')
        for key in value:
            if key not in keys:
                raise self.error(_join(path, str(key)),
                                 f'unknown key; {where} takes: {", ".join(keys)}')
        for key in required:
            if key not in value or value[key] is None:
                raise self.error(_join(path, key), f'missing; {where} requires it')
        return value

    def text(self, value: Any, path: str, limit: int) -> str:
        """Return one line of printable text of at most `limit` characters (no control ones)."""
        if not isinstance(value, str) or not value.strip():
            raise self.error(path, f'expected a non-empty string, got {describe_value(value)}')
        value = value.strip()
        if '\n' in value:
            raise self.error(path, 'expected one line')
        if len(value) > limit:
            raise self.error(path, f'{len(value)} characters; give at most {limit} characters')
        # A name and a description reach terminals and logs: an escape sequence in them
        # (written "\e[31m" in YAML) would act there.
        for index, character in enumerate(value):
            if not character.isprintable():
                shown = f'{repr(character)[1:-1]} (U+{ord(character):04X})'
                raise self.error(path, f'contains {shown} at character {index + 1}, which is not '
                                       'printable; give one line of printable text')
        return value

    def number(self, value: Any, path: str, unit: str = '', positive: bool = False) -> float:
        try:
            return check_number(value, 'value', unit, positive=positive)
        except ParameterError as error:
            raise self.error(path, error.problem + _quoted_number_hint(value)) from None

    def vector(self, value: Any, path: str, unit: str = '') -> NDArray[np.float64]:
        try:
            return check_vector(value, 'value', unit)
        except ParameterError as error:
            raise self.error(path, error.problem + _quoted_number_hint(value)) from None

    # -- sections

    def body(self, value: Any) -> tuple[RigidBody, str | None]:
        """Return (RigidBody, shape or None) of the body section."""
        shape = value.get('shape') if isinstance(value, dict) else None
        # A shape of the wrong YAML type (a list, a mapping) is not hashable: it gets the
        # shape error below, not a TypeError here.
        shape_keys = _SHAPE_KEYS.get(shape, ()) if isinstance(shape, str) else ()
        keys = ('mass', 'shape', 'inertia') + tuple(k for s in SHAPES for k in _SHAPE_KEYS[s])
        body = self.mapping(value, 'body', keys, required=('mass',))
        mass = self.number(body['mass'], 'body.mass', 'kg', positive=True)
        if 'shape' in body and 'inertia' in body:
            raise self.error('body', 'give shape (with its sizes) or inertia, not both')
        if 'inertia' in body:
            for key in body:
                if key not in ('mass', 'inertia'):
                    raise self.error(f'body.{key}', 'is a shape size; a body given by inertia '
                                                    'takes only mass and inertia')
            return self.inertia_body(mass, body['inertia']), None
        if 'shape' not in body:
            raise self.error('body', f'missing shape ({", ".join(SHAPES)}) or inertia')
        if shape not in SHAPES:
            raise self.error('body.shape', f'expected one of {", ".join(SHAPES)}, got '
                                           f'{describe_value(shape)}')
        for key in body:
            if key not in ('mass', 'shape') + shape_keys:
                raise self.error(f'body.{key}', f'not a size of shape {shape}; it takes: '
                                                f'{", ".join(shape_keys)}')
        for key in shape_keys:
            if key not in body:
                raise self.error(f'body.{key}', f'missing; shape {shape} requires it')
        sizes: dict[str, Any] = {}
        for key in shape_keys:
            path = f'body.{key}'
            if key in ('size', 'semi_axes'):
                sizes[key] = self.vector(body[key], path, 'm')
                if np.any(sizes[key] <= 0.0):
                    raise self.error(path, f'must be > 0 m, got {sizes[key].tolist()}')
            else:
                sizes[key] = self.number(body[key], path, 'm', positive=True)
        # Huge masses or sizes overflow the inertia to inf: said here, naming the keys,
        # without numpy's RuntimeWarnings on the way.
        with np.errstate(over='ignore', invalid='ignore'):
            try:
                if shape == 'box':
                    return RigidBody.box(mass, sizes['size']), shape
                if shape == 'ellipsoid':
                    return RigidBody.ellipsoid(mass, sizes['semi_axes']), shape
                if shape == 'sphere':
                    return RigidBody.sphere(mass, sizes['radius']), shape
                return RigidBody.cylinder(mass, sizes['radius'], sizes['height']), shape
            except ValueError as error:
                given = ', '.join(f'{key} {np.asarray(size).tolist()} m'
                                  for key, size in sizes.items())
                raise self.error('body.mass', f'{mass:g} kg with {given} gives no valid '
                                              f'inertia ({error})') from None

    def inertia_body(self, mass: float, value: Any) -> RigidBody:
        path = 'body.inertia'
        if isinstance(value, np.ndarray):
            value = value.tolist()
        if not isinstance(value, (list, tuple)):
            raise self.error(path, f'expected 3 numbers (the diagonal) or 3 rows of 3, got '
                                   f'{describe_value(value)}')
        if len(value) == 3 and all(isinstance(row, (list, tuple)) for row in value):
            tensor = np.array([self.vector(row, f'{path}[{i}]', 'kg m^2')
                               for i, row in enumerate(value)])
        elif len(value) == 9:
            tensor = np.array([self.number(x, f'{path}[{i}]', 'kg m^2')
                               for i, x in enumerate(value)]).reshape(3, 3)
        else:
            tensor = np.diag(self.vector(value, path, 'kg m^2'))
        try:
            return RigidBody(mass, tensor)
        except ValueError as error:
            raise self.error(path, str(error)) from None

    def effects(self, value: Any) -> list[Effect]:
        if not isinstance(value, list):
            raise self.error('effects', f'expected a list of effects, got {describe_value(value)}')
        effects, seen = [], set()
        parameters: Any
        for index, item in enumerate(value):
            path = f'effects[{index}]'
            if isinstance(item, str):
                name, parameters = item, {}
            elif isinstance(item, dict) and len(item) == 1:
                (name, parameters), = item.items()
            else:
                raise self.error(path, 'expected an effect name or {name: {parameters}}, got '
                                       f'{describe_value(item)}')
            if name not in EFFECTS:
                raise self.error(path, unknown_effect(name))
            if name in seen:
                raise self.error(path, f'effect {name!r} is named twice')
            seen.add(name)
            if parameters is None:
                # "- pivot:" with nothing below: the parameters' lines were likely lost.
                raise self.error(f'{path}.{name}', 'no parameters after the colon; give them, '
                                                   f'or write "- {name}" for the defaults')
            if not isinstance(parameters, dict):
                raise self.error(f'{path}.{name}', 'expected a mapping of parameters, got '
                                                   f'{describe_value(parameters)}')
            try:
                effects.append(create_effect(name, parameters))
            except ParameterError as error:
                hint = _quoted_number_hint(parameters.get(error.key))
                raise self.error(f'{path}.{name}.{error.key}', error.problem + hint) from None
            except ValueError as error:
                raise self.error(f'{path}.{name}', str(error)) from None
        return effects

    def plugins(self, value: Any) -> tuple[str, ...]:
        """
        Load the effect plugin files the scene names; return their absolute paths.

        Each is a ``.py`` file, its path relative to the scene file's folder (or absolute),
        imported once per process; a plugin that fails is an error naming it.
        """
        if not isinstance(value, list) or not value:
            raise self.error('plugins', 'expected a list of effect plugin files (.py, paths '
                                        f'relative to the scene file), got '
                                        f'{describe_value(value)}')
        loaded: list[str] = []
        for index, item in enumerate(value):
            path = f'plugins[{index}]'
            if not isinstance(item, str) or not item.strip():
                raise self.error(path, 'expected the path of a .py file, got '
                                       f'{describe_value(item)}')
            file = Path(item).expanduser()
            if not file.is_absolute():
                if self.folder is None:
                    raise self.error(path, 'a relative path, but this scene is not read from '
                                           'a file; give an absolute path')
                file = Path(self.folder) / file
            try:
                load_effect_file(file, shown=item)
            except PluginError as error:
                raise self.error(path, str(error)) from None
            loaded.append(str(file.resolve()))
        return tuple(loaded)

    def initial(self, value: Any, body: RigidBody, pivot: Effect | None) -> State:
        initial = self.mapping(value, 'initial', _INITIAL_KEYS)
        if 'angular_velocity_body' in initial and 'angular_velocity_world' in initial:
            raise self.error('initial', 'give angular_velocity_body or angular_velocity_world, '
                                        'not both')
        if pivot is not None:
            for key in ('position', 'velocity'):
                if key in initial:
                    raise self.error(f'initial.{key}', 'not allowed with a pivot: the COM '
                                                       'follows from the pivot; remove it')
        vectors = {key: self.vector(initial[key], f'initial.{key}', unit)
                   for key, unit in (('angular_velocity_body', 'rad/s'),
                                     ('angular_velocity_world', 'rad/s'),
                                     ('position', 'm'), ('velocity', 'm/s'))
                   if key in initial}
        rotation = None
        if 'orientation' in initial:
            rotation = self.orientation(initial['orientation'])
        # A finite but huge velocity can overflow p = m v or the energy |p|^2 / 2m, and an
        # angular velocity L = R I omega or 1/2 omega . L: refused naming the key, without
        # numpy's warnings.  The velocity first, so that its overflow is not blamed on the
        # angular velocity.
        if 'velocity' in vectors:
            with np.errstate(over='ignore', invalid='ignore'):
                momentum = body.mass * vectors['velocity']
                energy: Any = 0.5 * (momentum @ momentum) / body.mass
            if not (np.isfinite(energy) and np.all(np.isfinite(momentum))):
                raise self.error('initial.velocity', f'gives a linear momentum of '
                                                     f'{momentum.tolist()} kg m/s and a kinetic '
                                                     f'energy of {energy:g} J: not finite')
        given = next((f'initial.{key}' for key in ('angular_velocity_body',
                                                   'angular_velocity_world') if key in vectors),
                     'initial')
        with np.errstate(over='ignore', invalid='ignore'):
            try:
                state = State.from_velocity(body, rotation=rotation, **vectors)
            except ValueError as error:
                raise self.error(given, f'gives a state that is not finite ({error})') from None
            if pivot is not None:
                try:
                    state = pivot.constrain(body).project(state)
                except ValueError as error:
                    raise self.error(self.pivot_path, f'no valid body about this pivot '
                                                      f'({error})') from None
            energy = state.kinetic_energy(body)
        if not (np.isfinite(energy) and np.all(np.isfinite(state.angular_momentum))):
            raise self.error(given, f'gives a kinetic energy of {energy:g} J and an angular '
                                    f'momentum of {np.asarray(state.angular_momentum).tolist()}'
                                    ' kg m^2/s: not finite')
        return state

    def orientation(self, value: Any, path: str = 'initial.orientation') -> NDArray[np.float64]:
        if isinstance(value, (list, tuple)) and len(value) != 4:
            raise self.error(path, f'expected 4 numbers (quaternion x, y, z, w), got '
                                   f'{len(value)}')
        try:
            quaternion = check_vector(value, 'value', size=4)
        except ParameterError as error:
            raise self.error(path, error.problem + ' (quaternion x, y, z, w)'
                             + _quoted_number_hint(value)) from None
        norm = float(np.linalg.norm(quaternion))
        if abs(norm - 1.0) > _QUATERNION_NORM_TOLERANCE:
            raise self.error(path, f'expected a unit quaternion (x, y, z, w), got norm '
                                   f'{norm:.9g}')
        return quaternion / norm

    def imu(self, value: Any) -> ImuModel:
        """Read the imu section: mount pose and Kalibr noise terms (all optional)."""
        self.mapping(value, 'imu', _IMU_KEYS)
        values: dict[str, Any] = {}
        if 'position' in value:
            values['position'] = tuple(float(v) for v in self.vector(
                value['position'], 'imu.position', 'm'))
        if 'orientation' in value:
            values['orientation'] = tuple(float(v) for v in self.orientation(
                value['orientation'], 'imu.orientation'))
        for key in ImuModel.NOISE_KEYS:
            if key in value:
                number = self.number(value[key], f'imu.{key}', _IMU_UNITS[key])
                if number < 0.0:
                    raise self.error(f'imu.{key}', f'must be >= 0 {_IMU_UNITS[key]} (0: off), '
                                                   f'got {number:g}')
                values[key] = float(number)
        if 'seed' in value:
            seed = value['seed']
            if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 63:
                raise self.error('imu.seed', f'expected a whole number 0 to 2^63 - 1, got '
                                             f'{describe_value(seed)}')
            values['seed'] = seed
        return ImuModel(**values)

    def drawing(self, value: Any, body: RigidBody, body_shape: str | None,
                body_data: Any) -> Drawing:
        draw = self.mapping(value, 'draw', _DRAW_KEYS)
        shape = draw.get('shape', body_shape or 'box')
        if shape not in SHAPES:
            raise self.error('draw.shape', f'expected one of {", ".join(SHAPES)}, got '
                                           f'{describe_value(shape)}')
        color: tuple[float, ...] = DEFAULT_COLOR
        if 'color' in draw:
            color = self.color(draw['color'])
        if 'size' in draw:
            size: Any = self.vector(draw['size'], 'draw.size', 'm')
            if np.any(size <= 0.0):
                raise self.error('draw.size', f'must be > 0 m, got {size.tolist()}')
            return Drawing(shape, tuple(size.tolist()), color, derived=False)
        if shape == body_shape:
            size = _shape_extents(body_data, shape)
            return Drawing(shape, size, color)
        if shape not in ('box', 'ellipsoid'):
            raise self.error('draw.size', f'missing: a {shape} cannot be derived from this '
                                          'body; give draw.size (m)')
        size, orientation = _equivalent_extents(body, shape)
        return Drawing(shape, size, color, orientation)

    def color(self, value: Any) -> tuple[float, ...]:
        path = 'draw.color'
        if isinstance(value, (list, tuple)) and len(value) == 3:
            value = list(value) + [1.0]
        if isinstance(value, (list, tuple)) and len(value) != 4:
            raise self.error(path, f'expected 3 or 4 numbers (r, g, b[, a]), got {len(value)}')
        try:
            color = check_vector(value, 'value', size=4)
        except ParameterError as error:
            raise self.error(path, error.problem + ' (r, g, b[, a])'
                             + _quoted_number_hint(value)) from None
        if np.any(color < 0.0) or np.any(color > 1.0):
            raise self.error(path, f'each of r, g, b, a must be in 0..1, got {color.tolist()}')
        return tuple(color.tolist())


def _shape_extents(body_data: Mapping[str, Any], shape: str) -> tuple[float, ...]:
    """Return the Marker scale (m) of a body's own shape from its sizes."""
    if shape == 'box':
        return tuple(float(x) for x in body_data['size'])
    if shape == 'ellipsoid':
        return tuple(2.0 * float(x) for x in body_data['semi_axes'])
    diameter = 2.0 * float(body_data['radius'])
    if shape == 'sphere':
        return (diameter, diameter, diameter)
    return (diameter, diameter, float(body_data['height']))


def _equivalent_extents(body: RigidBody,
                        shape: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """
    Return the extents and orientation of the box or ellipsoid with the body's inertia.

    A solid box of edges (a, b, c) has I1 = m/12 (b^2 + c^2) and cyclic, so
    a^2 = 6 (I2 + I3 - I1) / m; a solid ellipsoid of semi-axes (a, b, c) has
    I1 = m/5 (b^2 + c^2), so its diameter (2a)^2 = 10 (I2 + I3 - I1) / m.  The triangle
    inequality makes these real; a flat body gets a small thickness.
    """
    inertia = body.inertia
    orientation: tuple[float, ...]
    if np.count_nonzero(inertia - np.diag(np.diag(inertia))) == 0:
        moments, orientation = np.diag(inertia), (0.0, 0.0, 0.0, 1.0)
    else:
        moments = body.principal_moments
        orientation = tuple(float(x) for x in quaternion_from_matrix(body.principal_axes))
    factor = 6.0 if shape == 'box' else 10.0
    total = float(np.sum(moments))
    squared = factor * (total - 2.0 * np.asarray(moments)) / body.mass
    extents = np.sqrt(np.clip(squared, 0.0, None))
    extents = np.maximum(extents, _THINNEST_DRAWING * float(np.max(extents)))
    return tuple(float(x) for x in extents), orientation


def _quoted_number_hint(value: object) -> str:
    """Return a hint if `value` (or an item of it) is a number in quotes, else ''."""
    items = value if isinstance(value, (list, tuple)) else (value,)
    for item in items:
        if isinstance(item, str) and is_yaml_number(item):
            return '; write it without quotes to make it a number'
    return ''


def _join(path: str, key: str) -> str:
    return f'{path}.{key}' if path else key


def _same_tensor(value: ArrayLike, tensor: NDArray[np.float64]) -> bool:
    """Return True if `value` (3, 9 or 3x3 numbers) is exactly the 3x3 `tensor`."""
    try:
        array = np.array(_plain(value), dtype=float)
    except (TypeError, ValueError):
        return False
    if array.shape == (3,):
        array = np.diag(array)
    elif array.shape == (9,):
        array = array.reshape(3, 3)
    return array.shape == (3, 3) and np.array_equal(array, tensor)


def _plain(value: Any) -> Any:
    """Return an override as plain Python data (lists and floats), like YAML gives."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value

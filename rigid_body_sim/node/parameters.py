"""
The node's parameters, each declared once, and what they make: the scene to simulate.

The node simulates a scene (:mod:`rigid_body_sim.scenes`): the read-only parameter
``scene`` names a built-in scene or a scene file, which gives the body, its initial state,
the effects on it, how to draw it, and the default integrator and rate.  The parameters come
in three kinds, told apart by the ``default`` of their :class:`ParameterSpec`:

- a value: the node's own settings (frames, inputs, sim time), the same for every scene;
- :data:`NAMESPACE_VALUE`: ``frame_prefix`` is declared with the node's namespace as a
  frame prefix (``sat1/`` in ``/sat1``), so that nodes in two namespaces name distinct frames;
- :data:`SCENE_VALUE`: ``integrator``, ``rate`` and ``tolerance`` are declared with the
  scene's values as their defaults, so ``ros2 param get`` shows what runs; a value the user
  gives replaces it;
- :data:`NOT_SET`: the body and initial-state parameters (``body.*``, ``initial.*``) are
  declared with their type and no value, so that the values the user gives can be told
  from the scene's; once the scene is built, :func:`show_effective_values` gives every one
  that is not set the value the simulation runs with (the scene's, or what follows from the
  overrides: a new mass scales a shape's inertia).  Every parameter then has a value:
  ``ros2 param dump`` and every tool that lists and gets parameters see the simulation
  (rclpy answers a GetParameters request with nothing at all if one name in it has no
  value), and a dump loaded back with ``--params-file`` gives the same simulation:
  :func:`scene_from_parameters` takes a value equal to the scene's, or one that follows from
  the others (the inertia of the given shape, the world angular velocity of the given body
  one, a pivot body's position), as no override.

:func:`declare_scene_parameter` and :func:`declare_parameters` declare them with a
ParameterDescriptor each; :func:`scene_from_parameters` applies the values that are set to
the scene, the one place that knows how the body and state parameters combine.

What the user gave (``-p name:=value``, ``--params-file``) is read once, by
:func:`given_overrides`, so that an unknown name (a typo in a params file) can be reported
and a refused override quoted.
"""

import dataclasses
from dataclasses import dataclass
import math

import numpy as np
from rcl_interfaces.msg import FloatingPointRange
from rcl_interfaces.msg import IntegerRange
from rcl_interfaces.msg import ParameterDescriptor
from rcl_interfaces.msg import ParameterType
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.exceptions import InvalidParameterValueException
from rclpy.exceptions import ParameterUninitializedException
from rclpy.parameter import Parameter

from ..messages.frames import default_frame_prefix
from ..messages.frames import frame_ids
from ..messages.frames import MAX_FRAME_ID_LENGTH
from ..physics import get_integrator
from ..physics import INTEGRATORS
from ..physics.imu import ImuModel
from ..scenes import DEFAULT_SCENE
from ..scenes import RATE_RANGE
from ..scenes import SHAPES
from ..scenes import SUBSTEPS_RANGE
from ..scenes import TOLERANCE_RANGE
from ..text import one_line_errors

__all__ = [
    'PARAMETERS',
    'DEFAULTS',
    'NOT_SET',
    'SCENE_VALUE',
    'NAMESPACE_VALUE',
    'ParameterSpec',
    'declare_scene_parameter',
    'declare_parameters',
    'given_overrides',
    'parameter_descriptor',
    'scene_from_parameters',
    'effective_values',
    'show_effective_values',
    'imu_model_from_parameters',
    'check_integrator',
    'frame_ids_from_parameters',
    'ONE_BODY_PARAMETERS',
    'WORLD_PARAMETERS',
]


class _Placeholder:
    """A default that is not a value: see the module docstring."""

    def __init__(self, text):
        self._text = text

    def __repr__(self):
        return self._text


NOT_SET = _Placeholder('NOT_SET')
"""Default of a parameter declared without a value: when set, it overrides the scene."""

SCENE_VALUE = _Placeholder('SCENE_VALUE')
"""Default of a parameter declared with the scene's value as its default."""

NAMESPACE_VALUE = _Placeholder('NAMESPACE_VALUE')
"""Default of ``frame_prefix``: the node's namespace as a frame prefix (``/sat1``: ``sat1/``)."""


@dataclass(frozen=True)
class ParameterSpec:
    """
    One parameter of the node.

    Attributes
    ----------
    name : str
    kind : type
        Its Python type: float, int, str, bool or list (a list of doubles).
    default
        A value, :data:`SCENE_VALUE` or :data:`NOT_SET`.
    description : str
    read_only : bool
    value_range : (from, to) or None
        Inclusive.
    constraints : str
        What the value must be, in words.

    """

    name: str
    kind: type
    default: object
    description: str
    read_only: bool
    value_range: tuple
    constraints: str


# A unit quaternion given to 4 decimals is off by up to ~1e-4 in norm; such a slightly
# unnormalised value is normalised, anything further from 1 is a mistake and is refused.
_QUATERNION_NORM_TOLERANCE = 1e-3
_FRAME_CONSTRAINTS = (
    f'the three different as tf2 reads them (one leading / dropped), non-empty, without '
    f'whitespace or control characters, at most {MAX_FRAME_ID_LENGTH} characters with the '
    'prefix')
_FROM_SCENE = (" Default: the scene's value (the one the simulation runs with); a value equal to "
               'it, or following from the others, overrides nothing.')


def _spec(name, kind, default, description, read_only=True, value_range=None,
          constraints=''):
    return ParameterSpec(name, kind, default, description, read_only, value_range,
                         constraints)


PARAMETERS = (
    _spec('scene', str, DEFAULT_SCENE,
          'The scene to simulate: a built-in name (config/scenes/<name>.yaml; list them with '
          '`rigid-body-sim scenes`) or the path of a scene file.  It gives the body, the '
          'initial state, the effects, the drawing and the default integrator and rate; '
          'the body.* and initial.* parameters that are set override its values.'),
    _spec('integrator', str, SCENE_VALUE,
          "Integration method; default: the scene's.  May change at run time; the state "
          'stays continuous.',
          read_only=False, constraints='one of: ' + ', '.join(sorted(INTEGRATORS))),
    _spec('rate', float, SCENE_VALUE,
          "Tick rate in Hz; default: the scene's.  Each tick advances the simulation by "
          '1/rate s of simulated time and publishes the state once.',
          value_range=RATE_RANGE),
    _spec('substeps', int, 1,
          'Integrator steps per tick (step = 1 / (rate * substeps) s); with a tolerance, the '
          'least number of substeps.',
          read_only=False, value_range=SUBSTEPS_RANGE),
    _spec('tolerance', float, SCENE_VALUE,
          "Error control in rad per simulated second; default: the scene's.  Each tick is "
          'split into as many equal substeps (at least substeps) as keep the orientation '
          'error the integrator adds per simulated second at or below it (a step-doubling '
          "estimate with the integrator's order); 0: off, substeps fixed steps per tick.  May "
          'change at run time; the state stays continuous.',
          read_only=False, value_range=TOLERANCE_RANGE),
    _spec('real_time_factor', float, 1.0,
          'Simulated seconds per wall-clock second: the ticks come every '
          '(1/rate)/real_time_factor s of wall-clock time, each still advancing the '
          'simulation by 1/rate s.  May change at run time.',
          read_only=False, value_range=(0.001, 1000.0)),
    _spec('publish_clock', bool, False,
          'Publish the simulated time on /clock (rosgraph_msgs/Clock, best effort, keep '
          'last 1) at every tick, and stamp every message with it: simulated time from 0 '
          'at start-up, frozen while paused, never going back (a reset restarts the body, '
          'not the clock).  Sim-time consumers (use_sim_time:=true, ros2 bag record '
          '--use-sim-time) then follow the simulation.  False: stamps come from the '
          "node's clock."),
    _spec('frame_prefix', str, NAMESPACE_VALUE,
          'Put in front of every frame id the node publishes (world_frame, body_frame, '
          "imu_frame), verbatim as robot_state_publisher's frame_prefix: 'sat1/' makes "
          "'sat1/world' and 'sat1/body'.  Default: the node's namespace ('sat1/' in /sat1, "
          "none at the root), so that nodes in two namespaces publish distinct frames; '' "
          'for none.'),
    _spec('world_frame', str, 'world',
          'Frame id of the inertial world frame (z up), after frame_prefix (REP 105: odom).',
          constraints=_FRAME_CONSTRAINTS),
    _spec('body_frame', str, 'body',
          'Frame id of the body frame (origin at the centre of mass), after frame_prefix '
          '(REP 105: base_link).', constraints=_FRAME_CONSTRAINTS),
    _spec('input_timeout', float, 0.5,
          'A torque or wrench input holds until replaced or until this many seconds of the '
          "node's clock pass without a new one on its topic; 0 holds forever.",
          read_only=False, value_range=(0.0, 86400.0)),
    _spec('max_wrench', float, 1000.0,
          'Largest accepted force magnitude (N) and torque magnitude (N m) of an input; '
          'larger inputs are rejected (inputs within it are then scaled down to the '
          "scene's external_wrench limits, if it has any).",
          read_only=False, value_range=(0.0, 1.0e12)),
    _spec('imu_frame', str, 'imu',
          "Frame id of the simulated IMU (the imu topic's header), after frame_prefix: fixed "
          'in the body at imu.position with orientation imu.orientation.',
          constraints=_FRAME_CONSTRAINTS),
    _spec('imu.position', list, SCENE_VALUE,
          "Where the IMU sits: m from the centre of mass, body frame; default: the scene's "
          '(its imu section), else the COM.'),
    _spec('imu.orientation', list, SCENE_VALUE,
          'The IMU frame in the body frame, a unit quaternion (x, y, z, w); default: the '
          "scene's, else aligned with the body."),
    *(_spec(f'imu.{key}', float, SCENE_VALUE,
            f"IMU noise (Kalibr's model): {meaning} in {unit}; default: the scene's, else 0 "
            '(off).', value_range=(0.0, 1.0e6))
      for key, meaning, unit in (
          ('gyro_noise_density', 'gyroscope white noise density', 'rad/s/sqrt(Hz)'),
          ('gyro_random_walk', 'gyroscope bias random walk', 'rad/s^2/sqrt(Hz)'),
          ('gyro_bias_sigma', 'gyroscope turn-on bias sigma', 'rad/s'),
          ('accel_noise_density', 'accelerometer white noise density', 'm/s^2/sqrt(Hz)'),
          ('accel_random_walk', 'accelerometer bias random walk', 'm/s^3/sqrt(Hz)'),
          ('accel_bias_sigma', 'accelerometer turn-on bias sigma', 'm/s^2'))),
    _spec('imu.seed', int, SCENE_VALUE,
          'Seed of the IMU noise (the same seed, the same noise sequence); default: the '
          "scene's, else 0.", value_range=(0, 2 ** 63 - 1)),
    _spec('body.mass', float, NOT_SET,
          'Mass of the body in kg (> 0).  A body given by shape keeps its shape (its '
          'inertia scales with the mass); one given by inertia keeps its inertia.'
          + _FROM_SCENE),
    _spec('body.inertia', list, NOT_SET,
          'Inertia tensor about the centre of mass in the body frame, kg m^2: 9 numbers '
          "(row-major 3x3) or 3 (the diagonal).  Replaces the scene's body (with "
          "body.shape only if it is that shape's inertia)." + _FROM_SCENE,
          constraints='symmetric, positive definite, principal moments satisfy '
                      'I1 + I2 >= I3'),
    _spec('body.shape', str, NOT_SET,
          'Solid body of uniform density whose inertia follows from its mass and '
          "body.size (needed unless the scene's body has this shape).  Empty: a body "
          "given by its inertia.  Default: the scene's.",
          constraints='one of: ' + ', '.join(SHAPES)),
    _spec('body.size', list, NOT_SET,
          "Dimensions in m of body.shape (or of the scene's shape): box (a, b, c) edges; "
          'cylinder (radius, height) along body z; sphere (radius); ellipsoid (a, b, c) '
          'semi-axes.' + _FROM_SCENE),
    _spec('initial.orientation', list, NOT_SET,
          'Initial orientation, body to world, as a unit quaternion (x, y, z, w).'
          + _FROM_SCENE),
    _spec('initial.position', list, NOT_SET,
          'Initial position of the centre of mass in m, world frame (in a scene with a '
          'pivot only the one that follows from the pivot).' + _FROM_SCENE),
    _spec('initial.velocity', list, NOT_SET,
          'Initial velocity of the centre of mass in m/s, world frame (with a pivot only '
          'the one that follows).' + _FROM_SCENE),
    _spec('initial.angular_velocity_body', list, NOT_SET,
          "Initial angular velocity in rad/s, body frame; replaces the scene's angular "
          'velocity in either frame (with initial.angular_velocity_world only if they '
          'agree).' + _FROM_SCENE),
    _spec('initial.angular_velocity_world', list, NOT_SET,
          "Initial angular velocity in rad/s, world frame; replaces the scene's angular "
          'velocity in either frame (with initial.angular_velocity_body only if they '
          'agree).' + _FROM_SCENE),
)
"""Every parameter of the node, in declaration order."""

ONE_BODY_PARAMETERS = tuple(
    spec.name for spec in PARAMETERS
    if spec.name in ('body_frame', 'imu_frame') or spec.name.split('.')[0] in (
        'body', 'initial', 'imu'))
"""The parameters of one body (its frames, body, initial state and IMU): a scene of
``bodies:`` gives each body's in its file, and its node has none of them."""

WORLD_PARAMETERS = tuple(spec.name for spec in PARAMETERS
                         if spec.name not in ONE_BODY_PARAMETERS)
"""The parameters of a node that simulates a scene of ``bodies:`` (every body alike)."""

DEFAULTS = {spec.name: spec.default for spec in PARAMETERS
            if not isinstance(spec.default, _Placeholder)}
"""Parameter name -> default value, for the parameters whose default is a value."""

_SPECS = {spec.name: spec for spec in PARAMETERS}

_PARAMETER_TYPES = {
    bool: (ParameterType.PARAMETER_BOOL, Parameter.Type.BOOL),
    int: (ParameterType.PARAMETER_INTEGER, Parameter.Type.INTEGER),
    float: (ParameterType.PARAMETER_DOUBLE, Parameter.Type.DOUBLE),
    str: (ParameterType.PARAMETER_STRING, Parameter.Type.STRING),
    list: (ParameterType.PARAMETER_DOUBLE_ARRAY, Parameter.Type.DOUBLE_ARRAY),
}
_TYPE_NAMES = {float: 'a double', int: 'an integer', str: 'a string', bool: 'a boolean',
               list: 'a list of doubles'}
_EXAMPLES = {float: '100.0 for a double, not 100', int: '10', str: "'5' (quoted) for a string",
             bool: 'true or false', list: '[1.0, 2.0, 3.0] for a list of doubles'}


def parameter_descriptor(spec):
    """Return the rcl_interfaces/ParameterDescriptor of a :class:`ParameterSpec`."""
    descriptor = ParameterDescriptor(
        name=spec.name, type=_PARAMETER_TYPES[spec.kind][0], description=spec.description,
        additional_constraints=spec.constraints, read_only=spec.read_only)
    if spec.value_range is not None:
        low, high = spec.value_range
        if spec.kind is int:
            descriptor.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
        else:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    return descriptor


def given_overrides(node):
    """
    Return {name: value} of the parameter overrides `node` was started with.

    rclpy (7.1 here, 8.0 too) has no public accessor for them: Node keeps them in a private
    dict, the attribute read below and nowhere else (if a later rclpy renames it, this
    returns {}: unknown names then go unreported and refused overrides unquoted, nothing
    else changes).  The one public route,
    ``automatically_declare_parameters_from_overrides=True`` (rclpy declares every override,
    ``list_parameters`` then shows them), makes rclpy's Node.__init__ raise ValueError
    ("Cannot declare a statically typed parameter with default value of type
    PARAMETER_NOT_SET") for an override without a type: an empty list, as ``-p name:=[]``
    or ``size: []`` in a params file, which ``ros2 param dump`` writes for an empty array
    (this node's dump of the default scene holds one), so the node could not start from
    its own dump.  Parsing ``--ros-args`` here would duplicate rcl's parser (params files,
    node-name keys and wildcards, namespaces).
    """
    overrides = getattr(node, '_parameter_overrides', {})
    return {name: parameter.value for name, parameter in overrides.items()}


# A -p value can be a megabyte string or list: echoed cut, on one line.
@one_line_errors
def declare_scene_parameter(node, overrides=None):
    """
    Declare the parameter ``scene`` on `node` and return its value.

    `overrides` ({name: value}, :func:`given_overrides`) quotes a refused override.

    Raises
    ------
    ValueError
        If its override is not a string.

    """
    _declare(node, _SPECS['scene'], DEFAULT_SCENE, overrides)
    return node.get_parameter('scene').value


@one_line_errors
def declare_parameters(node, scene, overrides=None, names=None):
    """
    Declare every parameter of :data:`PARAMETERS` (or of `names`) not yet declared on `node`.

    Overrides (``-p name:=value``, ``--params-file``) are applied by the declaration.

    Parameters
    ----------
    node : rclpy.node.Node
        The node to declare them on.
    scene : Scene
        The scene the node simulates: its integrator, rate and tolerance are the defaults
        of the parameters of the same names.
    overrides : dict, optional
        What :func:`given_overrides` returned: a refused override is quoted from it.
    names : collection of str, optional
        Only these parameters (:data:`WORLD_PARAMETERS` for a scene of bodies).

    Returns
    -------
    dict
        Parameter name -> value, None for a parameter that is not set.

    Raises
    ------
    ValueError
        If an override has the wrong type or is out of its range; the message names the
        parameter and what it expects.

    """
    scene_values = {'integrator': scene.integrator, 'rate': float(scene.rate),
                    'tolerance': float(scene.tolerance or 0.0),
                    'imu.position': [float(v) for v in scene.imu.position],
                    'imu.orientation': [float(v) for v in scene.imu.orientation],
                    'imu.seed': int(scene.imu.seed)}
    scene_values.update({f'imu.{key}': float(getattr(scene.imu, key))
                         for key in ImuModel.NOISE_KEYS})
    values = {}
    for spec in PARAMETERS:
        if names is not None and spec.name not in names:
            continue
        if not node.has_parameter(spec.name):
            default = spec.default
            if default is SCENE_VALUE:
                default = scene_values[spec.name]
            elif default is NAMESPACE_VALUE:
                default = default_frame_prefix(node.get_namespace())
            _declare(node, spec, default, overrides)
        try:
            values[spec.name] = node.get_parameter(spec.name).value
        except ParameterUninitializedException:
            values[spec.name] = None
    return values


def _declare(node, spec, default, overrides):
    if default is NOT_SET:
        default = _PARAMETER_TYPES[spec.kind][1]  # declared typed, without a value
        # Writable until show_effective_values has given it the value that runs.
        spec = dataclasses.replace(spec, read_only=False)
    try:
        node.declare_parameter(spec.name, default, parameter_descriptor(spec))
    except InvalidParameterTypeException:
        raise ValueError(
            f'parameter {spec.name!r} must be {_TYPE_NAMES[spec.kind]}; got '
            f'{(overrides or {}).get(spec.name)!r} (ROS parameters are typed: write e.g. '
            f'{_EXAMPLES[spec.kind]})') from None
    except InvalidParameterValueException:
        low, high = spec.value_range
        override = (overrides or {}).get(spec.name)
        if override is None:  # the scene's value is outside the node's range
            raise ValueError(
                f"parameter {spec.name!r} must be in [{low}, {high}]; the scene's "
                f'{spec.name} is {default!r}: set {spec.name}') from None
        raise ValueError(
            f'parameter {spec.name!r} must be in [{low}, {high}]; got {override!r}') from None


@one_line_errors
def frame_ids_from_parameters(values):
    """
    Return {world_frame, body_frame, imu_frame: frame id}: prefixed, as tf2 reads them.

    Raises
    ------
    ValueError
        If one is not a usable frame id or two are one frame, naming the parameter
        (:func:`rigid_body_sim.messages.frames.frame_ids`).

    """
    return frame_ids(values['frame_prefix'], {name: values[name] for name in (
        'world_frame', 'body_frame', 'imu_frame')})


def check_integrator(name):
    """Return None if `name` is a registered integrator, else the reason it is not."""
    try:
        get_integrator(name)
    except ValueError as error:
        return str(error)
    return None


# Shape -> its size keys in a scene's body section with their number of values, in the order
# of body.size.
_SIZE_KEYS = {
    'box': (('size', 3),),
    'cylinder': (('radius', 1), ('height', 1)),
    'sphere': (('radius', 1),),
    'ellipsoid': (('semi_axes', 3),),
}
_SIZE_MEANINGS = {'box': 'edges a, b, c', 'cylinder': 'radius, height',
                  'sphere': 'radius', 'ellipsoid': 'semi-axes a, b, c'}


def _body_section(scene, shape, size, mass):
    """Return the body section that body.shape and body.size describe, or None."""
    scene_body = scene.data.get('body', {})
    scene_shape = None if 'inertia' in scene_body else scene_body.get('shape')
    if shape is None and size is None:
        return None
    if shape is None:
        if scene_shape is None:
            raise ValueError("parameter 'body.size' needs body.shape: the scene's body is "
                             'given by its inertia')
        shape = scene_shape
    if shape not in _SIZE_KEYS:
        raise ValueError(f"parameter 'body.shape' must be one of {', '.join(SHAPES)}; got "
                         f'{shape!r}')
    counts = _SIZE_KEYS[shape]
    needed = sum(count for _, count in counts)
    if size is None:
        if shape == scene_shape:
            return None  # the scene's own shape and sizes
        raise ValueError(f"parameter 'body.shape' is {shape!r}: set body.size too, "
                         f'{needed} value(s) in m ({_SIZE_MEANINGS[shape]})')
    size = [float(s) for s in size]
    if len(size) != needed:
        raise ValueError(f"parameter 'body.size' of a {shape} must have {needed} value(s) "
                         f'in m ({_SIZE_MEANINGS[shape]}); got {len(size)}: {size}')
    section = {'shape': shape, 'mass': mass}
    start = 0
    for key, count in counts:
        section[key] = size[start] if count == 1 else size[start:start + count]
        start += count
    return section


def _inertia(values):
    inertia = [float(i) for i in values]
    if len(inertia) not in (3, 9):
        raise ValueError(f"parameter 'body.inertia' must have 9 values (row-major 3x3) or 3 "
                         f'(the diagonal) in kg m^2; got {len(inertia)}: {inertia}')
    return inertia


def _orientation(values):
    quaternion = np.array(values, dtype=float).reshape(-1)
    if quaternion.size != 4 or not np.all(np.isfinite(quaternion)):
        raise ValueError(f"parameter 'initial.orientation' must be 4 finite numbers, a "
                         f'quaternion (x, y, z, w); got {quaternion.tolist()}')
    norm = math.sqrt(quaternion @ quaternion)
    if abs(norm - 1.0) > _QUATERNION_NORM_TOLERANCE:
        raise ValueError(f"parameter 'initial.orientation' must be a unit quaternion "
                         f'(x, y, z, w); got {quaternion.tolist()} of norm {norm:.6g}')
    return (quaternion / norm).tolist()


@one_line_errors
def scene_from_parameters(scene, values):
    """
    Return `scene` with the parameter values that are set applied to it.

    Parameters
    ----------
    scene : Scene
        The scene the ``scene`` parameter names.
    values : mapping
        Parameter name -> value; a missing name or None is a parameter that is not set,
        which keeps the scene's value.  ``integrator`` and ``rate`` replace the scene's;
        ``body.mass``, ``body.inertia``, ``body.shape`` with ``body.size``, and the
        ``initial.*`` orientation (quaternion x, y, z, w, body to world), COM position (m)
        and velocity (m/s), world frame, and angular velocity (rad/s, body or world frame)
        replace the scene's body and initial state (see :meth:`Scene.with_overrides`).

    Raises
    ------
    ValueError
        If the values describe no valid scene; the message names the parameter or, for
        the scene's own checks, ``<scene file> (overrides): <key path>``.

    """
    value = _overriding(scene, values).get
    integrator = value('integrator')
    if integrator is not None:
        reason = check_integrator(integrator)
        if reason is not None:
            raise ValueError(f"parameter 'integrator': {reason}")
        if integrator == scene.integrator:
            integrator = None
    rate = value('rate')
    if rate is not None and float(rate) == scene.rate:
        rate = None
    shape = value('body.shape') or None  # empty: not set
    inertia = value('body.inertia')
    if shape is not None and inertia is not None:
        raise ValueError('body.inertia is not the inertia of body.shape and body.size: set '
                         'body.shape (with body.size) or body.inertia, not both')
    overrides = {'integrator': integrator, 'rate': rate, 'mass': value('body.mass')}
    mass = overrides['mass'] if overrides['mass'] is not None else scene.body.mass
    overrides['body'] = _body_section(scene, shape, value('body.size'), mass)
    if inertia is not None:
        overrides['inertia'] = _inertia(inertia)
    if value('initial.orientation') is not None:
        overrides['orientation'] = _orientation(value('initial.orientation'))
    if value('initial.angular_velocity_body') is not None and \
            value('initial.angular_velocity_world') is not None:
        raise ValueError('initial.angular_velocity_body and initial.angular_velocity_world '
                         'disagree (omega_world != R omega_body): set one of them')
    for name in ('position', 'velocity', 'angular_velocity_body', 'angular_velocity_world'):
        overrides[name] = value(f'initial.{name}')
    if all(override is None for override in overrides.values()):
        return scene
    return scene.with_overrides(**overrides)


_SCENE_PARAMETERS = tuple(spec.name for spec in PARAMETERS if spec.default is NOT_SET)


def effective_values(scene):
    """
    Return the body.* and initial.* parameter values that describe `scene`.

    body.mass (kg), body.inertia (kg m^2, 9 row-major values, body frame), body.shape and
    body.size (the shape's sizes in m; '' and [] for a body given by its inertia), and the
    initial orientation (quaternion x, y, z, w, body to world), COM position (m) and
    velocity (m/s) in the world frame, angular velocity (rad/s) in the body and in the
    world frame: the one the scene file gives as it gives it, the others read from the
    scene's body and built state.
    """
    body, state = scene.body, scene.state
    initial = scene.data.get('initial') or {}
    section = scene.data.get('body', {})
    shape = '' if 'inertia' in section else section.get('shape', '')
    size = []
    for key, count in _SIZE_KEYS.get(shape, ()):
        size += [float(section[key])] if count == 1 else [float(v) for v in section[key]]
    # The angular velocity the scene gives, as it gives it: recomputed from L it would
    # round differently for another orientation, and then seem an override.
    angular_velocity = {
        frame: [float(v) for v in initial[f'angular_velocity_{frame}']]
        if f'angular_velocity_{frame}' in initial else [float(v) for v in computed]
        for frame, computed in (('body', state.angular_velocity_body(body)),
                                ('world', state.angular_velocity(body)))}
    return {
        'body.mass': float(body.mass),
        'body.inertia': [float(v) for v in np.asarray(body.inertia).reshape(-1)],
        'body.shape': shape,
        'body.size': size,
        'initial.orientation': [float(v) for v in state.quaternion],
        'initial.position': [float(v) for v in state.position],
        'initial.velocity': [float(v) for v in state.velocity(body)],
        'initial.angular_velocity_body': angular_velocity['body'],
        'initial.angular_velocity_world': angular_velocity['world'],
    }


def _same(given, effective):
    if isinstance(effective, str):
        return given == effective
    if isinstance(effective, float):
        return float(given) == effective
    return [float(v) for v in given] == effective


def _follows(given, effective):
    # Recomputed from the same inputs by the same code, a derived value comes out bit for bit
    # equal; 1e-12 relative only forgives a value written with fewer digits.
    try:
        given = np.asarray(given, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        return False
    effective = np.asarray(effective, dtype=float)
    return given.shape == effective.shape and bool(np.all(
        np.abs(given - effective) <= 1e-12 * (np.abs(effective).max(initial=0.0) + 1e-300)))


def _overriding(scene, values):
    """
    Return `values` without the body and initial values that change nothing.

    A value equal to the scene's is no override; neither is one that follows from the other
    values given (checked on the scene they make): the inertia of the body they describe,
    in a pivot scene the COM position and velocity, and of two angular velocities the one
    recomputed from the other (the node shows both).  An empty body.shape or body.size (a
    body given by its inertia) is no value.  What is left are the user's overrides.
    """
    values = {name: value for name, value in dict(values).items()
              if value is not None and not (name in ('body.shape', 'body.size')
                                            and len(value) == 0)}
    given = [name for name in _SCENE_PARAMETERS if name in values]
    if not given:
        return values
    derived = ['body.inertia']
    if scene.pivot is not None:
        derived += ['initial.position', 'initial.velocity']
    # The scene's own frame first: a hand-written pair is then read as the scene reads it.
    pair = ['initial.angular_velocity_body', 'initial.angular_velocity_world']
    if 'angular_velocity_world' in (scene.data.get('initial') or {}):
        pair.reverse()
    both = all(name in values for name in pair)
    scene_values = effective_values(scene)
    for name in given:
        if name not in derived and not (both and name in pair) and \
                _same(values[name], scene_values[name]):
            del values[name]

    def made_without(*names):
        return effective_values(scene_from_parameters(scene, {
            name: value for name, value in values.items()
            if name not in derived and name not in names}))

    if both:
        # The one the node built its state from reproduces the other bit for bit (the node
        # computed it so); applying the other instead would round the momentum differently.
        for primary, secondary in (pair, pair[::-1]):
            if made_without(secondary)[secondary] == [float(v) for v in values[secondary]]:
                break
        else:
            primary, secondary = pair
            if not _follows(values[secondary], made_without(secondary)[secondary]):
                secondary = None  # they disagree: scene_from_parameters says so
        if secondary is not None:
            del values[secondary]
            if _same(values[primary], scene_values[primary]):
                del values[primary]
    # The body before the motion: a pivot body's COM velocity follows from its inertia too.
    for level in (['body.inertia'], ['initial.position', 'initial.velocity']):
        derived = [name for name in derived if name not in level]
        level = [name for name in level if name in values]
        if level:
            made_values = made_without(*level)
            for name in level:
                if _follows(values[name], made_values[name]):
                    del values[name]
    return values


def show_effective_values(node, scene, values, effective_scene):
    """
    Give each body.* and initial.* parameter that is not set the value the simulation has.

    Then make them read-only (they were declared writable for this); return the report
    of which values override the scene, for the start-up log.

    Parameters
    ----------
    node : rclpy.node.Node
        The node, its parameters declared by :func:`declare_parameters`.
    scene : Scene
        The scene the ``scene`` parameter names.
    values : mapping
        What :func:`declare_parameters` returned (None: not set).
    effective_scene : Scene
        `scene` with `values` applied (:func:`scene_from_parameters`): what runs.

    """
    shown = effective_values(effective_scene)
    for name in _SCENE_PARAMETERS:
        spec = _SPECS[name]
        if values.get(name) is None:
            node.set_parameters([Parameter(name, _PARAMETER_TYPES[spec.kind][1],
                                           shown[name])])
        node.set_descriptor(name, parameter_descriptor(spec))
    overriding = [name for name in _overriding(scene, values) if name in _SCENE_PARAMETERS]
    return (f'body and initial parameters overriding the scene {scene.name!r}: '
            f'{", ".join(overriding) or "none"}; the others hold its values (or what '
            'follows from the overrides)')


@one_line_errors
def imu_model_from_parameters(values):
    """
    Return the :class:`ImuModel` the imu.* parameter values describe.

    Raises
    ------
    ValueError
        For a position that is not 3 finite numbers (m) or an orientation that is not a unit
        quaternion; the message names the parameter.

    """
    position = np.array(values['imu.position'], dtype=float).reshape(-1)
    if position.size != 3 or not np.all(np.isfinite(position)):
        raise ValueError(f"parameter 'imu.position' must be 3 finite numbers in m (body "
                         f'frame, from the COM); got {position.tolist()}')
    orientation = np.array(values['imu.orientation'], dtype=float).reshape(-1)
    norm = math.sqrt(orientation @ orientation) if orientation.size == 4 else math.nan
    if not abs(norm - 1.0) <= _QUATERNION_NORM_TOLERANCE:
        raise ValueError(f"parameter 'imu.orientation' must be a unit quaternion (x, y, z, "
                         f'w), IMU to body; got {orientation.tolist()}')
    return ImuModel(position=tuple(position.tolist()),
                    orientation=tuple((orientation / norm).tolist()),
                    seed=int(values['imu.seed']),
                    **{key: float(values[f'imu.{key}']) for key in ImuModel.NOISE_KEYS})

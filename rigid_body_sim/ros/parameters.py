"""
The node's parameters, each declared once, and what they make: a body and its state.

:data:`PARAMETERS` lists every parameter with its default, description, range and whether
it may change at run time; :func:`declare_parameters` declares them all on a node with a
ParameterDescriptor each.  :func:`body_and_state_from_parameters` turns the values into the
RigidBody and initial State: the one place that knows how the body parameters combine.

Defaults are :mod:`rigid_body_sim.defaults`: the T-handle I = (1, 2, 3) kg m^2 spun near
its unstable middle axis, which flips within the first minute.
"""

import collections
import math

import numpy as np
from rcl_interfaces.msg import FloatingPointRange
from rcl_interfaces.msg import IntegerRange
from rcl_interfaces.msg import ParameterDescriptor
from rcl_interfaces.msg import ParameterType
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.exceptions import InvalidParameterValueException

from .conversions import marker_geometry
from .conversions import SHAPES
from ..defaults import DEFAULT_ANGULAR_VELOCITY_BODY
from ..defaults import DEFAULT_INERTIA
from ..defaults import DEFAULT_INTEGRATOR
from ..defaults import DEFAULT_MASS
from ..physics import get_integrator
from ..physics import INTEGRATORS
from ..physics import RigidBody
from ..physics import State

__all__ = [
    'PARAMETERS',
    'DEFAULTS',
    'ParameterSpec',
    'declare_parameters',
    'parameter_descriptor',
    'body_and_state_from_parameters',
    'marker_geometry_from_parameters',
    'check_integrator',
]

ParameterSpec = collections.namedtuple(
    'ParameterSpec', 'name default description read_only value_range constraints')
ParameterSpec.__doc__ = """One parameter: name, default (its type is the parameter's type),
description, read_only, value_range ((from, to) inclusive, or None) and constraints (text)."""

# A unit quaternion given to 4 decimals is off by up to ~1e-4 in norm; such a slightly
# unnormalised value is normalised, anything further from 1 is a mistake and is refused.
_QUATERNION_NORM_TOLERANCE = 1e-3


def _spec(name, default, description, read_only=True, value_range=None, constraints=''):
    return ParameterSpec(name, default, description, read_only, value_range, constraints)


PARAMETERS = (
    _spec('integrator', DEFAULT_INTEGRATOR,
          'Integration method; may change at run time, the state stays continuous.',
          read_only=False,
          constraints='one of: ' + ', '.join(sorted(INTEGRATORS))),
    _spec('rate', 100.0, 'Timer rate in Hz: each tick advances the simulation by 1/rate s '
          'of simulated time and publishes the state once.', value_range=(0.1, 10000.0)),
    _spec('substeps', 1, 'Integrator steps per tick (step = 1 / (rate * substeps) s).',
          read_only=False, value_range=(1, 100000)),
    _spec('world_frame', 'world', 'Frame id of the inertial world frame (z up).'),
    _spec('body_frame', 'body', 'Frame id of the body frame (origin at the centre of mass).'),
    _spec('input_timeout', 0.5, 'A torque or wrench input holds until replaced or until this '
          'many seconds pass without a new one on its topic; 0 holds forever.',
          read_only=False, value_range=(0.0, 86400.0)),
    _spec('max_wrench', 1000.0, 'Largest accepted force magnitude (N) and torque magnitude '
          '(N m) of an input; larger inputs are rejected.',
          read_only=False, value_range=(0.0, 1.0e12)),
    _spec('body.mass', DEFAULT_MASS, 'Mass of the body in kg (> 0).'),
    _spec('body.inertia', [float(i) for i in DEFAULT_INERTIA],
          'Inertia tensor about the centre of mass in the body frame, kg m^2: 9 numbers '
          '(row-major 3x3) or 3 (the diagonal).  Used when body.shape is empty.',
          constraints='symmetric, positive definite, principal moments satisfy '
                      'I1 + I2 >= I3'),
    _spec('body.shape', '', 'Solid body of uniform density whose inertia follows from '
          'body.mass and body.size; empty: use body.inertia (drawn as the box with the same '
          'principal moments).', constraints='one of: ' + ', '.join(SHAPES) + ', or empty'),
    _spec('body.size', [1.0, 1.0, 1.0], 'Dimensions of body.shape in m: box (a, b, c) edges; '
          'cylinder (radius, height) along body z; sphere (radius); ellipsoid (a, b, c) '
          'semi-axes.  Ignored when body.shape is empty.'),
    _spec('initial.orientation', [0.0, 0.0, 0.0, 1.0],
          'Initial orientation, body to world, as a unit quaternion (x, y, z, w).'),
    _spec('initial.position', [0.0, 0.0, 0.0],
          'Initial position of the centre of mass in m, world frame.'),
    _spec('initial.velocity', [0.0, 0.0, 0.0],
          'Initial velocity of the centre of mass in m/s, world frame.'),
    _spec('initial.angular_velocity_body', [float(w) for w in DEFAULT_ANGULAR_VELOCITY_BODY],
          'Initial angular velocity in rad/s, body frame.'),
)
"""Every parameter of the node, in declaration order."""

DEFAULTS = {spec.name: spec.default for spec in PARAMETERS}
"""Parameter name -> default value."""


def _parameter_type(default):
    if isinstance(default, bool):
        return ParameterType.PARAMETER_BOOL
    if isinstance(default, int):
        return ParameterType.PARAMETER_INTEGER
    if isinstance(default, float):
        return ParameterType.PARAMETER_DOUBLE
    if isinstance(default, str):
        return ParameterType.PARAMETER_STRING
    return ParameterType.PARAMETER_DOUBLE_ARRAY


def parameter_descriptor(spec):
    """Return the rcl_interfaces/ParameterDescriptor of a :class:`ParameterSpec`."""
    descriptor = ParameterDescriptor(
        name=spec.name, type=_parameter_type(spec.default), description=spec.description,
        additional_constraints=spec.constraints, read_only=spec.read_only)
    if spec.value_range is not None:
        low, high = spec.value_range
        if isinstance(spec.default, int):
            descriptor.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
        else:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    return descriptor


def declare_parameters(node):
    """
    Declare every parameter of :data:`PARAMETERS` on `node`; return {name: value}.

    Overrides (``-p name:=value``, ``--params-file``) are applied by the declaration.

    Raises
    ------
    ValueError
        If an override has the wrong type or is out of its range; the message names the
        parameter and what it expects.

    """
    for spec in PARAMETERS:
        try:
            node.declare_parameter(spec.name, spec.default, parameter_descriptor(spec))
        except InvalidParameterTypeException:
            raise ValueError(
                f'parameter {spec.name!r} must be {_TYPE_NAMES[type(spec.default)]}; got '
                f'{_override(node, spec.name)!r} (ROS parameters are typed: write e.g. '
                f'{_example(spec.default)})') from None
        except InvalidParameterValueException:
            low, high = spec.value_range
            raise ValueError(
                f'parameter {spec.name!r} must be in [{low}, {high}]; got '
                f'{_override(node, spec.name)!r}') from None
    return {spec.name: node.get_parameter(spec.name).value for spec in PARAMETERS}


_TYPE_NAMES = {float: 'a double', int: 'an integer', str: 'a string',
               list: 'a list of doubles'}


def _override(node, name):
    # The offending value: rclpy keeps the overrides in a private dict (Jazzy).
    override = getattr(node, '_parameter_overrides', {}).get(name)
    return None if override is None else override.value


def _example(default):
    if isinstance(default, float):
        return f'{default!r} for a double, not {int(default)}'
    if isinstance(default, list):
        return f'{default!r} for a list of doubles'
    return repr(default)


def check_integrator(name):
    """Return None if `name` is a registered integrator, else the reason it is not."""
    try:
        get_integrator(name)
    except ValueError as error:
        return str(error)
    return None


def _vector(values, name, count, unit):
    array = np.array(values, dtype=float).reshape(-1)
    if array.size != count:
        raise ValueError(f'parameter {name!r} must have {count} values ({unit}); got '
                         f'{array.size}: {list(values)}')
    if not np.all(np.isfinite(array)):
        raise ValueError(f'parameter {name!r} must be finite; got {array.tolist()}')
    return array


def _orientation(values):
    quaternion = _vector(values, 'initial.orientation', 4, 'quaternion x, y, z, w')
    norm = math.sqrt(quaternion @ quaternion)
    if abs(norm - 1.0) > _QUATERNION_NORM_TOLERANCE:
        raise ValueError(f"parameter 'initial.orientation' must be a unit quaternion "
                         f'(x, y, z, w); got {quaternion.tolist()} of norm {norm:.6g}')
    return quaternion / norm


def _body(values):
    mass = values['body.mass']
    shape = values['body.shape']
    try:
        if shape == '':
            inertia = np.array(values['body.inertia'], dtype=float)
            if inertia.size == 9:
                inertia = inertia.reshape(3, 3)
            elif inertia.size != 3:
                raise ValueError(f'body.inertia must have 9 values (row-major 3x3) or 3 (the '
                                 f'diagonal) in kg m^2; got {inertia.size}')
            return RigidBody(mass, inertia)
        size = list(values['body.size'])
        marker_geometry(RigidBody(1.0, np.ones(3)), shape, size)  # checks shape and count
        if shape == 'box':
            return RigidBody.box(mass, size)
        if shape == 'cylinder':
            return RigidBody.cylinder(mass, size[0], size[1])
        if shape == 'sphere':
            return RigidBody.sphere(mass, size[0])
        return RigidBody.ellipsoid(mass, size)
    except ValueError as error:
        raise ValueError(f'body parameters: {error}') from None


def body_and_state_from_parameters(values):
    """
    Return the (RigidBody, initial State) that parameter values describe.

    Parameters
    ----------
    values : mapping
        Parameter name -> value for the names of :data:`PARAMETERS` (missing names take
        their defaults).  The body is body.shape with body.size and body.mass when the shape
        is set, else body.mass with body.inertia.  The initial state (world frame) has
        orientation initial.orientation, COM position initial.position, COM velocity
        initial.velocity and body-frame angular velocity initial.angular_velocity_body.

    Raises
    ------
    ValueError
        If the values describe no real body or state; the message names the parameter.

    """
    values = {**DEFAULTS, **dict(values)}
    body = _body(values)
    orientation = _orientation(values['initial.orientation'])
    position = _vector(values['initial.position'], 'initial.position', 3, 'm')
    velocity = _vector(values['initial.velocity'], 'initial.velocity', 3, 'm/s')
    angular_velocity = _vector(values['initial.angular_velocity_body'],
                               'initial.angular_velocity_body', 3, 'rad/s')
    state = State.from_velocity(body, rotation=orientation, position=position,
                                velocity=velocity, angular_velocity_body=angular_velocity)
    return body, state


def marker_geometry_from_parameters(body, values):
    """Return the MarkerGeometry drawing `body` as the parameters describe it."""
    values = {**DEFAULTS, **dict(values)}
    shape = values['body.shape']
    return marker_geometry(body, shape, values['body.size'] if shape else ())

"""
The core as ROS 2's standard simulation interfaces: ``simulation_interfaces`` messages.

The ros-simulation organisation's ``simulation_interfaces`` package (jazzy 1.5.x) is the
standard set of services a simulator serves (spawn, delete, get and set entity states,
reset, pause, step); Gazebo serves it through ros_gz_sim.  This module converts between
the physics core and its messages, with no node: the node's services call it.

- :func:`entity_state_message`: a :class:`~rigid_body_sim.physics.state.State` as an
  ``EntityState``; :func:`state_from_entity_state` the way back, refusing (ValueError, one
  line) what is not a state: a non-finite value, a quaternion off unit norm, a twist whose
  momenta overflow, a frame other than the world frame.
- :func:`result`: a ``Result`` (code, one-line reason) for every reply.
- :func:`features_message`: the ``SimulatorFeatures`` that lists what is served.

Frames (REP 103/105): the world frame is the inertial frame; an entity's frame is the
body's, with its origin at the centre of mass (COM).  ``EntityState`` gives the pose and
the twist "observed in the frame specified by header.frame_id" (ros2/common_interfaces
pull request 240's convention): here the world frame, so pose = COM position (m) and
orientation (body to world), twist = COM velocity (m/s) and angular velocity (rad/s), both
world-frame vectors.  Units: SI.

simulation_interfaces has no wheel: ``make venv`` builds it into the venv
(``interfaces/build_interfaces.sh``), a ROS installation may have it.  Where it cannot be
imported, :func:`unavailable_reason` says why and the functions here raise ImportError.
"""

from __future__ import annotations

from collections.abc import Iterable
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .frames import as_tf2_reads
from ..physics.body import RigidBody
from ..physics.state import State
from ..text import one_line
from ..text import one_line_errors
from ..text import shortened

try:
    from simulation_interfaces.msg import EntityState
    from simulation_interfaces.msg import Result
    from simulation_interfaces.msg import SimulatorFeatures
except ImportError as error:  # the package is built by the set-up where it can be
    _IMPORT_ERROR: str | None = one_line(
        f'simulation_interfaces cannot be imported ({error}); `make venv` builds it where '
        'cmake and a C/C++ compiler exist (see the README), a ROS installation may have it')
else:
    _IMPORT_ERROR = None

__all__ = ['QUATERNION_TOLERANCE', 'entity_state_message', 'features_message', 'result',
           'state_from_entity_state', 'unavailable_reason']

QUATERNION_TOLERANCE = 1e-6
"""How far from 1 the norm of a pose's quaternion may be; within it, it is normalised (as a
scene file's orientation is)."""


def unavailable_reason() -> str | None:
    """Return None where simulation_interfaces imports, else one line saying why (and how)."""
    return _IMPORT_ERROR


def _require() -> None:
    if _IMPORT_ERROR is not None:
        raise ImportError(_IMPORT_ERROR)


def _stamp(header: Any, stamp_nanoseconds: int) -> None:
    header.stamp.sec, header.stamp.nanosec = divmod(int(stamp_nanoseconds), 1_000_000_000)


def _set_vector(target: Any, values: Iterable[float]) -> None:
    target.x, target.y, target.z = (float(value) for value in values)


def entity_state_message(body: RigidBody, state: State, stamp_nanoseconds: int,
                         frame_id: str = 'world', force: ArrayLike | None = None,
                         torque: ArrayLike | None = None) -> EntityState:
    """
    Return `state` of `body` as a simulation_interfaces/EntityState.

    Parameters
    ----------
    body : RigidBody
        The body (mass and inertia turn the state's momenta into velocities).
    state : State
        World-frame state: rotation body to world, COM position, momenta.
    stamp_nanoseconds : int
        Header stamp in ns: the time the node's other messages carry (simulated time when
        it publishes /clock).
    frame_id : str
        The world frame's id: the header's frame, in which pose and twist are given.
    force, torque : array_like, shape (3,), optional
        The net external force (N) and torque about the COM (N m) on the body at `state`,
        world frame; None: zero (a free body).  Only the acceleration depends on them.

    Returns
    -------
    EntityState
        ``pose``: COM position (m) and orientation (quaternion, body to world).
        ``twist``: COM velocity v = p / m (m/s) and angular velocity omega = I_w^-1 L
        (rad/s), world frame.
        ``acceleration``: a = F / m (m/s^2) and the angular acceleration
        I_w^-1 (tau + L x omega) (rad/s^2), world frame: Euler's equations in world axes,
        exact for the given wrench (the gyroscopic part L x omega is there for a free
        body too).

    """
    _require()
    message = EntityState()
    message.header.frame_id = frame_id
    _stamp(message.header, stamp_nanoseconds)
    pose = message.pose
    _set_vector(pose.position, state.position)
    orientation = pose.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = (
        float(value) for value in state.quaternion)
    angular_momentum = state.angular_momentum
    omega = state.angular_velocity(body)
    _set_vector(message.twist.linear, state.velocity(body))
    _set_vector(message.twist.angular, omega)
    net_force = np.zeros(3) if force is None else np.asarray(force, dtype=float)
    net_torque = np.zeros(3) if torque is None else np.asarray(torque, dtype=float)
    # I_w^-1 = R I_b^-1 R^T: no inverse of the world-frame inertia.
    rotation = state.rotation
    angular_acceleration = rotation @ (body.inertia_inverse @ (
        rotation.T @ (net_torque + np.cross(angular_momentum, omega))))
    _set_vector(message.acceleration.linear, net_force / body.mass)
    _set_vector(message.acceleration.angular, angular_acceleration)
    return message


def _values(vector: Any) -> list[float]:
    return [vector.x, vector.y, vector.z]


def _check_finite(values: list[float], field: str, unit: str) -> None:
    if not all(math.isfinite(value) for value in values):
        raise ValueError(f'{field} must be finite ({unit}); got {values}')


@one_line_errors
def state_from_entity_state(message: EntityState, body: RigidBody,
                            world_frame: str = 'world') -> State:
    """
    Return the State of `body` that a simulation_interfaces/EntityState gives, or raise.

    The message's pose and twist are in its header's frame, which must be `world_frame`
    as tf2 reads it (one leading ``/`` dropped; empty means the world frame, as the message
    defines): pose = COM position (m) and
    orientation (body to world), twist = COM velocity (m/s) and angular velocity (rad/s),
    world frame.  The momenta are p = m v and L = I_w omega.  The stamp and the
    acceleration are not part of a state and are not read.  A body held by a pivot gets
    the state as given: projecting it onto the pivot is the caller's (the scene's) job.

    Raises
    ------
    ValueError
        One line saying why: a frame other than the world frame; a non-finite position,
        orientation or twist; a quaternion whose norm is off 1 by more than
        :data:`QUATERNION_TOLERANCE` (the zero quaternion among them); a twist so large
        that its momentum overflows float64.

    """
    _require()
    frame = message.header.frame_id
    if frame != '' and as_tf2_reads(frame) != world_frame:
        raise ValueError(f"header.frame_id is '{shortened(frame, 80)}': states are set in the "
                         f"world frame '{world_frame}' (or an empty frame_id, which means it)")
    position = _values(message.pose.position)
    _check_finite(position, 'pose.position', 'm')
    orientation = message.pose.orientation
    quaternion = [orientation.x, orientation.y, orientation.z, orientation.w]
    _check_finite(quaternion, 'pose.orientation', 'quaternion x, y, z, w')
    # math.hypot does not overflow for components near the largest double.
    norm = math.hypot(*quaternion)
    if not abs(norm - 1.0) <= QUATERNION_TOLERANCE:
        raise ValueError(f'pose.orientation (x, y, z, w) must be a unit quaternion (norm 1 '
                         f'to {QUATERNION_TOLERANCE:g}); got norm {norm:.9g}')
    velocity = _values(message.twist.linear)
    _check_finite(velocity, 'twist.linear', 'm/s')
    omega = _values(message.twist.angular)
    _check_finite(omega, 'twist.angular', 'rad/s')
    # State normalises the quaternion; R of that one turns omega into L.
    oriented = State(quaternion, position)
    matrix = oriented.rotation
    with np.errstate(over='ignore', invalid='ignore'):
        linear_momentum = body.mass * np.array(velocity)
        angular_momentum = matrix @ (body.inertia @ (matrix.T @ np.array(omega)))
    if not (np.all(np.isfinite(linear_momentum)) and np.all(np.isfinite(angular_momentum))):
        raise ValueError(f'twist too large: its momentum overflows float64 (linear '
                         f'{velocity} m/s, angular {omega} rad/s)')
    return State(oriented.quaternion, oriented.position, linear_momentum, angular_momentum)


def result(code: int, message: object = '') -> Result:
    """
    Return a simulation_interfaces/Result: `code` and `message` as one printable line.

    code : one of Result's RESULT_* constants, or a service's own (above 100).
    message : the reason, made one line of at most :data:`~rigid_body_sim.text.MESSAGE_LIMIT`
        printable characters (:func:`~rigid_body_sim.text.one_line`): it may quote what a
        peer sent.
    """
    _require()
    return Result(result=int(code), error_message=one_line(message))


def features_message(served: Iterable[int], spawn_formats: Iterable[str] = (),
                     custom_info: str = '') -> SimulatorFeatures:
    """
    Return the simulation_interfaces/SimulatorFeatures listing `served`, sorted, once each.

    served : SimulatorFeatures constants (SPAWNING, ENTITY_STATE_GETTING, ...).
    spawn_formats : the formats SpawnEntity reads beyond the standard ones.
    custom_info : a line for the caller (documentation, version).

    Raises ValueError for a number that is none of SimulatorFeatures' constants.
    """
    _require()
    defined = {getattr(SimulatorFeatures, name) for name in dir(SimulatorFeatures)
               if name.isupper() and isinstance(getattr(SimulatorFeatures, name), int)}
    features = sorted({int(feature) for feature in served})
    unknown = [feature for feature in features if feature not in defined]
    if unknown:
        raise ValueError(f'not simulation_interfaces/SimulatorFeatures constants: {unknown}')
    return SimulatorFeatures(features=features, spawn_formats=list(spawn_formats),
                             custom_info=one_line(custom_info))

"""
The state of a rigid body, in the world frame: an immutable value.

State variables (all world frame, SI): the rotation R (body to world, x_world = R x_body +
x_com), the COM position x (m), the linear momentum p = m v (kg m/s) and the angular
momentum about the COM L (kg m^2/s).  Momenta, not velocities, are the state because the
torque-free motion conserves world L exactly, and the integrators keep it so.

Velocities are derived with the body's mass properties:
I_w = R I_b R^T, omega = I_w^{-1} L (world), Omega = R^T omega (body), v = p / m.
"""

from __future__ import annotations

import math
from typing import Any
from typing import NoReturn

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from .body import RigidBody
from .rotations import check_quaternion
from .rotations import check_rotation_matrix
from .rotations import matrix_from_quaternion
from .rotations import quaternion_from_matrix

__all__ = ['State']

# |q|^2 of a unit quaternion, summed in floating point, is within a few ulps of 1.
_UNIT_TOLERANCE = 4.0 * 2.0 ** -52


def _vector(value: Any, name: str, unit: str) -> NDArray[np.float64]:
    array = np.array(value, dtype=float).reshape(-1) if value is not None else np.zeros(3)
    if array.shape != (3,):
        raise ValueError(f'{name} must be a 3-vector in {unit}; got {np.shape(value)}')
    if not np.all(np.isfinite(array)):
        raise ValueError(f'{name} must be finite; got {array.tolist()}')
    array.flags.writeable = False
    return array


def _frozen(array: NDArray[np.float64]) -> NDArray[np.float64]:
    array.flags.writeable = False
    return array


class State:
    """
    Rigid-body state in the world frame (immutable).

    Parameters
    ----------
    rotation : array_like, shape (3, 3) or (4,)
        Orientation, body to world: a rotation matrix, or a unit quaternion (x, y, z, w).
        Default: identity.
    position : array_like, shape (3,)
        COM position in m, world frame.  Default: origin.
    linear_momentum : array_like, shape (3,)
        p = m v in kg m/s, world frame.  Default: zero.
    angular_momentum : array_like, shape (3,)
        L about the COM in kg m^2/s, world frame.  Default: zero.

    Raises
    ------
    ValueError
        For non-finite entries, wrong shapes, or a rotation that is not orthonormal with
        det = +1 (to 1e-6), or a quaternion whose norm is not 1 (to 1e-6).

    """

    __slots__ = ('_rotation', '_quaternion', '_position', '_linear_momentum',
                 '_angular_momentum')
    # The slots' types (read-only arrays; R is made on first use).
    _rotation: NDArray[np.float64] | None
    _quaternion: NDArray[np.float64]
    _position: NDArray[np.float64]
    _linear_momentum: NDArray[np.float64]
    _angular_momentum: NDArray[np.float64]

    def __init__(self, rotation: ArrayLike | None = None, position: ArrayLike | None = None,
                 linear_momentum: ArrayLike | None = None,
                 angular_momentum: ArrayLike | None = None) -> None:
        if rotation is None:
            quaternion = np.array([0.0, 0.0, 0.0, 1.0])
            matrix = np.eye(3)
        elif np.shape(rotation) == (4,):
            quaternion = check_quaternion(rotation, 'rotation quaternion')
            matrix = matrix_from_quaternion(quaternion)
        else:
            matrix = check_rotation_matrix(rotation, 'rotation')
            quaternion = quaternion_from_matrix(matrix)
            # Re-derive R from its quaternion so the stored pair agree and R is orthonormal to
            # round-off even if the input was only orthonormal to the tolerance.
            matrix = matrix_from_quaternion(quaternion)
        self._set(_frozen(quaternion), _frozen(matrix), _vector(position, 'position', 'm'),
                  _vector(linear_momentum, 'linear_momentum', 'kg m/s'),
                  _vector(angular_momentum, 'angular_momentum', 'kg m^2/s'))

    def _set(self, quaternion: NDArray[np.float64], matrix: NDArray[np.float64] | None,
             position: NDArray[np.float64], linear_momentum: NDArray[np.float64],
             angular_momentum: NDArray[np.float64]) -> None:
        # The arrays come read-only: every field of a State is frozen.
        _set_quaternion(self, quaternion)
        _set_rotation(self, matrix)
        _set_position(self, position)
        _set_linear_momentum(self, linear_momentum)
        _set_angular_momentum(self, angular_momentum)

    @classmethod
    def _from_arrays(cls, quaternion: NDArray[np.float64], position: NDArray[np.float64],
                     linear_momentum: NDArray[np.float64],
                     angular_momentum: NDArray[np.float64]) -> State:
        """
        Build a state from trusted float arrays (integrator output): no validation.

        The quaternion is normalised here, so R is orthonormal to round-off.  Callers own the
        arrays they pass; they are frozen, not copied.  R is built on first use: a node tick
        or a kernel run makes one state and often publishes only the quaternion.
        """
        state = object.__new__(cls)
        x, y, z, w = quaternion.tolist()
        norm_squared = x * x + y * y + z * z + w * w
        # A quaternion already unit to round-off is kept: rescaling it by 1 +- 2^-52 would
        # add an ulp of noise to every step of an integrator that normalises itself.
        q = quaternion if abs(norm_squared - 1.0) <= _UNIT_TOLERANCE \
            else quaternion * (1.0 / math.sqrt(norm_squared))
        state._set(_frozen(q), None, _frozen(position), _frozen(linear_momentum),
                   _frozen(angular_momentum))
        return state

    @classmethod
    def _from_values(cls, values: NDArray[np.float64]) -> State:
        """
        Build a state from a packed array [q (4), x, p, L] (a compiled kernel's state).

        The values are copied into one read-only buffer whose four views are the fields, so
        the caller may go on changing its array.  Trusted: no validation, and the quaternion
        is taken as it is (the kernels normalise it after every turn), so a state read back
        into a kernel continues the run bit for bit.
        """
        frozen = np.frombuffer(values.tobytes())
        state = object.__new__(cls)
        state._set(frozen[0:4], None, frozen[4:7], frozen[7:10], frozen[10:13])
        return state

    def __setattr__(self, name: str, value: object) -> NoReturn:
        """Refuse assignment: a State is an immutable value."""
        raise AttributeError('State is immutable; use State.replace(...) for a changed copy')

    @classmethod
    def from_velocity(cls, body: RigidBody, rotation: ArrayLike | None = None,
                      position: ArrayLike | None = None, velocity: ArrayLike | None = None,
                      angular_velocity_body: ArrayLike | None = None,
                      angular_velocity_world: ArrayLike | None = None) -> State:
        """
        Return the state of `body` moving with the given velocities.

        Parameters
        ----------
        body : RigidBody
            The body whose inertia turns angular velocity into angular momentum.
        rotation : array_like, shape (3, 3) or (4,), optional
            Body to world rotation matrix, or quaternion (x, y, z, w).  Default identity.
        position : array_like, optional
            COM position in m (world).
        velocity : array_like, optional
            COM velocity in m/s (world).
        angular_velocity_body, angular_velocity_world : array_like, optional
            Angular velocity in rad/s, in the body frame (Omega) or the world frame (omega);
            give at most one.  L = R I_b Omega = I_w omega.

        """
        if angular_velocity_body is not None and angular_velocity_world is not None:
            raise ValueError('give angular_velocity_body or angular_velocity_world, not both')
        oriented = cls(rotation)
        matrix = oriented.rotation
        v = _vector(velocity, 'velocity', 'm/s')
        if angular_velocity_world is not None:
            omega_body = matrix.T @ _vector(angular_velocity_world, 'angular_velocity_world',
                                            'rad/s')
        else:
            omega_body = _vector(angular_velocity_body, 'angular_velocity_body', 'rad/s')
        angular_momentum = matrix @ (body.inertia @ omega_body)
        return cls(oriented.quaternion, position, body.mass * v, angular_momentum)

    def replace(self, rotation: ArrayLike | None = None, position: ArrayLike | None = None,
                linear_momentum: ArrayLike | None = None,
                angular_momentum: ArrayLike | None = None) -> State:
        """Return a copy with the given fields changed (validated like the constructor)."""
        return State(self._quaternion if rotation is None else rotation,
                     self._position if position is None else position,
                     self._linear_momentum if linear_momentum is None else linear_momentum,
                     self._angular_momentum if angular_momentum is None else angular_momentum)

    # -- state variables

    @property
    def rotation(self) -> NDArray[np.float64]:
        """Rotation matrix R, body to world (3x3, read-only)."""
        if self._rotation is None:
            _set_rotation(self, _frozen(matrix_from_quaternion(self._quaternion)))
        return self._rotation  # type: ignore[return-value]  # set just above

    @property
    def quaternion(self) -> NDArray[np.float64]:
        """Get the orientation, body to world, as a unit quaternion [x, y, z, w] (read-only)."""
        return self._quaternion

    @property
    def position(self) -> NDArray[np.float64]:
        """COM position in m, world frame (read-only)."""
        return self._position

    @property
    def linear_momentum(self) -> NDArray[np.float64]:
        """Linear momentum p = m v in kg m/s, world frame (read-only)."""
        return self._linear_momentum

    @property
    def angular_momentum(self) -> NDArray[np.float64]:
        """Angular momentum about the COM in kg m^2/s, world frame (read-only)."""
        return self._angular_momentum

    # -- derived quantities, which need the body's mass properties

    def inertia_world(self, body: RigidBody) -> NDArray[np.float64]:
        """Return I_w = R I_b R^T, the inertia about the COM in world axes (kg m^2)."""
        return self.rotation @ body.inertia @ self.rotation.T

    def velocity(self, body: RigidBody) -> NDArray[np.float64]:
        """Return the COM velocity v = p / m in m/s, world frame."""
        return self._linear_momentum / body.mass

    def angular_velocity_body(self, body: RigidBody) -> NDArray[np.float64]:
        """Return Omega = I_b^{-1} R^T L in rad/s, body frame."""
        return body.inertia_inverse @ (self.rotation.T @ self._angular_momentum)

    def angular_velocity(self, body: RigidBody) -> NDArray[np.float64]:
        """Return omega = R Omega = I_w^{-1} L in rad/s, world frame."""
        return self.rotation @ self.angular_velocity_body(body)

    def kinetic_energy(self, body: RigidBody) -> float:
        """Return T = |p|^2 / (2 m) + omega . L / 2 in J."""
        p = self._linear_momentum
        return 0.5 * (p @ p) / body.mass + 0.5 * (  # type: ignore[return-value]
            self.angular_velocity(body) @ self._angular_momentum)

    def __eq__(self, other: object) -> bool:
        """Return True if all state variables are bit-identical."""
        if not isinstance(other, State):
            return NotImplemented
        return all(np.array_equal(a, b) for a, b in zip(self._fields(), other._fields()))

    __hash__ = None  # type: ignore[assignment]

    def _fields(self) -> tuple[NDArray[np.float64], ...]:
        return (self._quaternion, self._position, self._linear_momentum,
                self._angular_momentum)

    def __repr__(self) -> str:
        """Return the state variables, quaternion (x, y, z, w) for the rotation."""
        def fmt(a: NDArray[np.float64]) -> str:
            return np.array2string(a, precision=6, separator=', ')
        return (f'State(quaternion={fmt(self._quaternion)}, position={fmt(self._position)}, '
                f'linear_momentum={fmt(self._linear_momentum)}, '
                f'angular_momentum={fmt(self._angular_momentum)})')


# Slot setters, bypassing State.__setattr__ (which refuses every assignment): a State is
# built once and never changed.
# (mypy sees the slots' declared types, not their descriptors.)
_set_quaternion = State._quaternion.__set__  # type: ignore[misc, attr-defined]
_set_rotation = State._rotation.__set__  # type: ignore[misc, union-attr]
_set_position = State._position.__set__  # type: ignore[misc, attr-defined]
_set_linear_momentum = State._linear_momentum.__set__  # type: ignore[misc, attr-defined]
_set_angular_momentum = State._angular_momentum.__set__  # type: ignore[misc, attr-defined]

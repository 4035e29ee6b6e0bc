"""
pivot: a point of the body fixed in the world (heavy top, gyroscope, a wheel held by its axle).

Formulation.  Let d be the COM's offset from the pivot in the body frame and r = R d its
world image.  About a fixed point a rigid body obeys the same equations as about its COM
(dR/dt = [omega]x R, dL_pivot/dt = tau_pivot) with the inertia moved to the pivot by the
parallel-axis theorem, I_pivot = I_com + m (|d|^2 E - d d^T).  So the Simulator integrates
the *pivot system*: the body RigidBody(m, I_pivot), a state whose position is the pivot's
anchor, whose linear momentum is zero and whose angular momentum is L_pivot, under the
torque about the pivot tau_pivot = tau_com + r x F.  The reaction at the pivot passes
through it, so it has no torque about it and never needs computing.  After the steps the
COM follows from the constraint:

    x_com = anchor + r,   p = m omega x r,   L_com = L_pivot - r x p.

The State the Simulator shows is this physical state, as everywhere: State.angular_momentum
is about the COM.  :meth:`PivotConstraint.angular_momentum_about_pivot` gives
L_pivot = L_com + r x p.  Energy needs no special case: |p|^2/(2m) + omega . L_com / 2 equals
omega . L_pivot / 2 (Koenig), and gravity adds m g z_com.
"""

import numba
import numpy as np

from .registry import check_vector
from .registry import Effect
from .registry import register_effect
from ..body import RigidBody
from ..rotations import cross
from ..state import State


@register_effect('pivot')
class Pivot(Effect):
    """
    Fix the body point `point` at the world point `anchor`; the body turns about it.

    A pivot is a constraint: the Simulator advances the body about it (see the module
    docstring) and projects every state it is given onto it (rotation and angular velocity
    kept, the COM position and velocity derived).

    Parameters
    ----------
    point : array_like, shape (3,)
        The pivot in the body frame, m from the COM (so the COM is at d = -point from the
        pivot).
    anchor : array_like, shape (3,)
        Where the pivot is held, m, world frame (default the origin).

    """

    def __init__(self, point, anchor=(0.0, 0.0, 0.0)):
        self.point = check_vector(point, 'point', 'm')
        self.anchor = check_vector(anchor, 'anchor', 'm')

    def constrain(self, body):
        """Return the :class:`PivotConstraint` of this pivot on `body`."""
        return PivotConstraint(body, self.point, self.anchor)

    def angular_momentum_about_pivot(self, body, state):
        """Return L_pivot = L_com + r x p in kg m^2/s, world frame (r = R d)."""
        return self.constrain(body).angular_momentum_about_pivot(state)


class PivotConstraint:
    """
    A pivot bound to a body: the maps between the physical state and the pivot system.

    Attributes
    ----------
    body : RigidBody
        The pivot system's body: mass m, inertia about the pivot I_pivot (body frame).
    offset_body : ndarray, shape (3,)
        d, the COM's offset from the pivot in m, body frame.
    anchor : ndarray, shape (3,)
        The pivot's world position in m.

    """

    def __init__(self, body, point, anchor):
        d = -np.array(point, dtype=float)
        # Parallel-axis theorem: the inertia about the pivot, body frame.
        inertia = body.inertia + body.mass * ((d @ d) * np.eye(3) - np.outer(d, d))
        self.body = RigidBody(body.mass, inertia)
        self.offset_body = d
        self.anchor = np.array(anchor, dtype=float)
        self._physical_body = body
        self._mass = body.mass
        # What the compiled expansion needs, in one array (one argument to pass per call):
        # I_pivot^{-1} row-major (9), d (3), anchor (3), m.
        self._expansion = np.concatenate([self.body.inertia_inverse.reshape(9), d,
                                          self.anchor, [self._mass]])

    def project(self, state):
        """
        Return `state` moved onto the constraint: R and omega kept, x and p derived.

        omega = I_w^{-1} L_com; x = anchor + R d; p = m omega x R d; L_com unchanged.
        """
        omega = state.angular_velocity(self._physical_body)
        r = state.rotation @ self.offset_body
        return State._from_arrays(np.array(state.quaternion), self.anchor + r,
                                  self._mass * cross(omega, r),
                                  np.array(state.angular_momentum))

    def reduce(self, state):
        """
        Return the pivot-system state of a physical state on the constraint.

        Position: the anchor; linear momentum: zero; angular momentum: L_pivot.
        """
        return State._from_arrays(np.array(state.quaternion), self.anchor.copy(), np.zeros(3),
                                  self.angular_momentum_about_pivot(state))

    def expand(self, pivot_state):
        """Return the physical state (COM position and momenta) of a pivot-system state."""
        rotation = pivot_state.rotation
        omega = rotation @ (self.body.inertia_inverse
                            @ (rotation.T @ pivot_state.angular_momentum))
        r = rotation @ self.offset_body
        linear_momentum = self._mass * cross(omega, r)
        return State._from_arrays(np.array(pivot_state.quaternion), self.anchor + r,
                                  linear_momentum,
                                  pivot_state.angular_momentum - cross(r, linear_momentum))

    def expand_values(self, pivot_values):
        """
        Return the physical state of a packed pivot-system state, packed (compiled).

        The same map as :meth:`expand` (tested to round-off) on the packed arrays of
        integrators/fast.py [q, x, p, L]: the Simulator reads its state through it.
        """
        return _expanded_values(pivot_values, self._expansion)

    def angular_momentum_about_pivot(self, state):
        """Return L_pivot = L_com + r x p of a physical state, kg m^2/s, world frame."""
        r = state.rotation @ self.offset_body
        return state.angular_momentum + cross(r, state.linear_momentum)

    def wrench(self, wrench):
        """
        Return the pivot system's wrench: (0, tau + r x F) from the physical one.

        `wrench(state, time)` acts on physical states (force through the COM, torque about
        it).  A wrench marked ``rotation_only`` (held and constant parts only) is evaluated
        on the pivot state directly, which has the same rotation, saving the expansion.
        """
        if wrench is None:
            return None
        offset_body = self.offset_body
        expand = None if getattr(wrench, 'rotation_only', False) else self.expand
        no_force = np.zeros(3)
        no_force.flags.writeable = False

        def pivot_wrench(state, time):
            force, torque = wrench(state if expand is None else expand(state), time)
            r = state.rotation @ offset_body
            return no_force, torque + cross(r, force)

        pivot_wrench.momentum_dependent = getattr(wrench, 'momentum_dependent', False)
        return pivot_wrench


@numba.njit(cache=True, nogil=True)
def _expanded_values(values, expansion):
    """Compiled :meth:`PivotConstraint.expand` on packed [q, x, p, L] arrays (SI, world)."""
    pivot_inertia_inverse = expansion[0:9].reshape((3, 3))
    offset_body, anchor, mass = expansion[9:12], expansion[12:15], expansion[15]
    x, y, z, w = values[0], values[1], values[2], values[3]
    rotation = np.empty((3, 3))
    rotation[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    rotation[0, 1] = 2.0 * (x * y - z * w)
    rotation[0, 2] = 2.0 * (x * z + y * w)
    rotation[1, 0] = 2.0 * (x * y + z * w)
    rotation[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    rotation[1, 2] = 2.0 * (y * z - x * w)
    rotation[2, 0] = 2.0 * (x * z - y * w)
    rotation[2, 1] = 2.0 * (y * z + x * w)
    rotation[2, 2] = 1.0 - 2.0 * (x * x + y * y)
    angular_momentum = values[10:13]
    # omega = R I_pivot^{-1} R^T L_pivot; r = R d; p = m omega x r; L_com = L_pivot - r x p.
    momentum_body = np.zeros(3)
    for i in range(3):
        for j in range(3):
            momentum_body[i] += rotation[j, i] * angular_momentum[j]
    omega_body = np.zeros(3)
    for i in range(3):
        for j in range(3):
            omega_body[i] += pivot_inertia_inverse[i, j] * momentum_body[j]
    omega, r = np.zeros(3), np.zeros(3)
    for i in range(3):
        for j in range(3):
            omega[i] += rotation[i, j] * omega_body[j]
            r[i] += rotation[i, j] * offset_body[j]
    linear_momentum = mass * np.array([omega[1] * r[2] - omega[2] * r[1],
                                       omega[2] * r[0] - omega[0] * r[2],
                                       omega[0] * r[1] - omega[1] * r[0]])
    physical = np.empty(13)
    physical[0:4] = values[0:4]
    physical[4:7] = anchor + r
    physical[7:10] = linear_momentum
    physical[10] = angular_momentum[0] - (r[1] * linear_momentum[2] - r[2] * linear_momentum[1])
    physical[11] = angular_momentum[1] - (r[2] * linear_momentum[0] - r[0] * linear_momentum[2])
    physical[12] = angular_momentum[2] - (r[0] * linear_momentum[1] - r[1] * linear_momentum[0])
    return physical

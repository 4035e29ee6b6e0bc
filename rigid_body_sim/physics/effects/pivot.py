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

In the kernels (kernels/model.py) the pivot is a constraint of two compiled functions:
:func:`expand` (the physical state of the pivot system's, for effects that read it) and
:func:`transmit` (a wrench at the COM as the pivot system takes it: no force, the torque
tau + r x F).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .registry import check_vector
from .registry import Effect
from .registry import register_effect
from ..body import RigidBody
from ..kernels.algebra import cross
from ..kernels.algebra import rotate
from ..kernels.layout import inverse_inertia_times
from ..kernels.model import Array
from ..kernels.model import expand_function
from ..kernels.model import transmit_function
from ..kernels.model import Wrench
from ..rotations import cross as cross_product
from ..state import State


MAX_DISTANCE = 1.0e6
"""The farthest a pivot may be from the COM or the anchor from the origin, m."""


@expand_function
def expand(integrated: Array, parameters: Array, physical: Array) -> None:
    """
    Write the physical state of a packed pivot-system state into `physical` (SI, world).

    parameters: I_pivot^-1 (9, row-major), d (3, the COM from the pivot, body frame),
    anchor (3), m.  omega = R I_pivot^-1 R^T L_pivot; r = R d; p = m omega x r;
    x = anchor + r; L_com = L_pivot - r x p.
    """
    q = (integrated[0], integrated[1], integrated[2], integrated[3])
    angular_momentum = (integrated[10], integrated[11], integrated[12])
    conjugated = (-q[0], -q[1], -q[2], q[3])
    omega = rotate(q, inverse_inertia_times(parameters[0:9],
                                            rotate(conjugated, angular_momentum)))
    r = rotate(q, (parameters[9], parameters[10], parameters[11]))
    mass = parameters[15]
    turning = cross(omega, r)
    linear_momentum = (mass * turning[0], mass * turning[1], mass * turning[2])
    moment = cross(r, linear_momentum)
    for i in range(4):
        physical[i] = integrated[i]
    for i in range(3):
        physical[4 + i] = parameters[12 + i] + r[i]
        physical[7 + i] = linear_momentum[i]
        physical[10 + i] = angular_momentum[i] - moment[i]


@transmit_function
def transmit(state: Array, wrench: Wrench, parameters: Array) -> Wrench:
    """
    Return the wrench about the pivot of one at the COM: (0, tau + r x F), r = R d (world).

    The reaction at the pivot takes the force; its moment about the pivot stays.
    """
    q = (state[0], state[1], state[2], state[3])
    r = rotate(q, (parameters[9], parameters[10], parameters[11]))
    moment = cross(r, (wrench[0], wrench[1], wrench[2]))
    return 0.0, 0.0, 0.0, wrench[3] + moment[0], wrench[4] + moment[1], wrench[5] + moment[2]


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

    units = {'point': 'm from the COM, body frame', 'anchor': 'm, world frame'}
    example = {'point': [0.02, -0.01, -0.05], 'anchor': [0.0, 0.0, 1.0]}

    def __init__(self, point: ArrayLike, anchor: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        self.point = check_vector(point, 'point', 'm', largest=MAX_DISTANCE)
        self.anchor = check_vector(anchor, 'anchor', 'm', largest=MAX_DISTANCE)

    def constrain(self, body: RigidBody) -> PivotConstraint:
        """Return the :class:`PivotConstraint` of this pivot on `body`."""
        return PivotConstraint(body, self.point, self.anchor)

    def angular_momentum_about_pivot(self, body: RigidBody, state: State) -> Array:
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

    def __init__(self, body: RigidBody, point: ArrayLike, anchor: ArrayLike) -> None:
        d = -np.array(point, dtype=float)
        # Parallel-axis theorem: the inertia about the pivot, body frame.
        inertia = body.inertia + body.mass * ((d @ d) * np.eye(3) - np.outer(d, d))
        self.body = RigidBody(body.mass, inertia)
        self.offset_body = d
        self.anchor = np.array(anchor, dtype=float)
        self._physical_body = body
        self._mass = body.mass
        # The parameters of the compiled expand and transmit: I_pivot^-1 row-major (9),
        # d (3), anchor (3), m.
        self.parameters = np.concatenate([self.body.inertia_inverse.reshape(9), d,
                                          self.anchor, [self._mass]])
        self.expand_function = expand
        self.transmit_function = transmit

    def project(self, state: State) -> State:
        """
        Return `state` moved onto the constraint: R and omega kept, x and p derived.

        omega = I_w^{-1} L_com; x = anchor + R d; p = m omega x R d; L_com unchanged.
        """
        omega = state.angular_velocity(self._physical_body)
        r = state.rotation @ self.offset_body
        return State._from_arrays(np.array(state.quaternion), self.anchor + r,
                                  self._mass * cross_product(omega, r),
                                  np.array(state.angular_momentum))

    def reduce(self, state: State) -> State:
        """
        Return the pivot-system state of a physical state on the constraint.

        Position: the anchor; linear momentum: zero; angular momentum: L_pivot.
        """
        return State._from_arrays(np.array(state.quaternion), self.anchor.copy(), np.zeros(3),
                                  self.angular_momentum_about_pivot(state))

    def expand(self, pivot_state: State) -> State:
        """Return the physical state (COM position and momenta) of a pivot-system state."""
        return State._from_values(self.expand_values(np.concatenate(pivot_state._fields())))

    def expand_values(self, pivot_values: Array) -> Array:
        """Return the physical state of a packed pivot-system state, packed (compiled)."""
        physical = np.empty(13)
        expand(pivot_values, self.parameters, physical)
        return physical

    def angular_momentum_about_pivot(self, state: State) -> Array:
        """Return L_pivot = L_com + r x p of a physical state, kg m^2/s, world frame."""
        r = state.rotation @ self.offset_body
        return state.angular_momentum + cross_product(r, state.linear_momentum)

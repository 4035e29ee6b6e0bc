"""
dissipation: a flexing body loses kinetic energy at constant angular momentum (flat spin).

Model.  Internal forces cannot change the world angular momentum L, but internal friction
drains energy, so the spin migrates to the axis of largest inertia, where the energy
|L|^2 / (2 I3) is least for the given |L| (Explorer 1, 1958).  In the body frame,
m = R^T L and Omega = I_b^{-1} m; torque-free, dm/dt = m x Omega.  Add the term

    dm/dt = m x Omega + eps m x (m x Omega),   eps = damping / |m|.

It keeps |m|:  d|m|^2/dt = 2 eps m . (m x (m x Omega)) = 0, and it drains energy:
E = m . I_b^{-1} m / 2, so dE/dt = Omega . dm/dt = eps Omega . (m x (m x Omega))
= -eps |m x Omega|^2 <= 0, zero only when Omega is parallel to m (a pure principal spin).
The stable end is the spin about the largest axis; every other one is left.

Realisation.  A body-frame rotation rate u turns R as dR/dt = R [u]x, which changes
m = R^T L, L fixed, as dm/dt = m x u.  So the extra term is the extra rotation
u = eps m x Omega of the orientation, with L untouched: world L is exactly constant, not
just |L|.  The effect is therefore a flow of R, composed with the integrator's step
symmetrically (flow(dt/2), step(dt), flow(dt/2): Strang, second order), and not a torque.
Each flow step is the explicit midpoint rule on SO(3) (second order):
R_half = R exp(h/2 u(R)), R_new = R exp(h u(R_half)).

The parameter `damping` (dimensionless) is the ratio of the dissipative turning of m to the
gyroscopic one, |eps m x (m x Omega)| / |m x Omega| = damping; 0.01 to 0.1 gives a
migration over tens to hundreds of spin periods.
"""

import numpy as np

from ._vector import cross
from .registry import check_number
from .registry import Effect
from .registry import register_effect
from ..rotations import matrix_from_quaternion
from ..rotations import quaternion_from_rotation_vector
from ..rotations import quaternion_multiply
from ..state import State


@register_effect('dissipation')
class Dissipation(Effect):
    """
    Internal energy loss at constant world angular momentum: the spin goes to the major axis.

    Parameters
    ----------
    damping : float
        Dimensionless rate (> 0): eps = damping / |L| in the body-frame law
        dm/dt = m x Omega + eps m x (m x Omega) (see the module docstring).

    """

    def __init__(self, damping):
        self.damping = check_number(damping, 'damping', positive=True)

    def flow(self, body, state, dt):
        """Return the state after dt s of dissipation alone: R turned, x, p and L unchanged."""
        momentum_norm = np.sqrt(state.angular_momentum @ state.angular_momentum)
        if momentum_norm == 0.0:
            return state
        eps = self.damping / momentum_norm
        quaternion = state.quaternion
        rate = self._turn_rate(body, state.rotation, state.angular_momentum, eps)
        half = _turned(quaternion, 0.5 * dt * rate)
        rate = self._turn_rate(body, matrix_from_quaternion(half), state.angular_momentum, eps)
        return State._from_arrays(_turned(quaternion, dt * rate), state.position,
                                  state.linear_momentum, state.angular_momentum)

    @staticmethod
    def _turn_rate(body, rotation, angular_momentum, eps):
        # u = eps m x Omega in the body frame (rad/s), m = R^T L, Omega = I_b^{-1} m.
        momentum_body = rotation.T @ angular_momentum
        return eps * cross(momentum_body, body.inertia_inverse @ momentum_body)

    def energy_rate(self, body, state):
        """Return dE/dt = -eps |m x Omega|^2 in W (<= 0) of the dissipation law."""
        momentum_norm = np.sqrt(state.angular_momentum @ state.angular_momentum)
        if momentum_norm == 0.0:
            return 0.0
        momentum_body = state.rotation.T @ state.angular_momentum
        turning = cross(momentum_body, body.inertia_inverse @ momentum_body)
        return -self.damping / momentum_norm * float(turning @ turning)


def _turned(quaternion, rotation_vector_body):
    # R exp([v]x): a body-frame turn multiplies on the right.
    q = quaternion_multiply(quaternion, quaternion_from_rotation_vector(rotation_vector_body))
    return q / np.sqrt(q @ q)

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

import math

import numba
import numpy as np

from .registry import check_number
from .registry import Effect
from .registry import ParameterError
from .registry import register_effect
from ..rotations import cross
from ..state import State


MAX_DAMPING = 1.0e6
"""The largest damping accepted (dimensionless)."""


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
        # Above 1 the body already relaxes within a turn; the flow stays finite up to 1e6
        # and beyond (measured on flat_spin), but products with it overflow near 1e308: far from
        # physics and far from overflow.
        if self.damping > MAX_DAMPING:
            raise ParameterError('damping', f'must be at most {MAX_DAMPING:g} (a ratio of '
                                            f'turning rates), got {self.damping:g}')

    def flow(self, body, state, dt):
        """Return the state after dt s of dissipation alone: R turned, x, p and L unchanged."""
        quaternion = dissipated_quaternion(state.quaternion, state.angular_momentum,
                                           body.inertia_inverse, self.damping, dt)
        return State._from_arrays(quaternion, state.position, state.linear_momentum,
                                  state.angular_momentum)

    def energy_rate(self, body, state):
        """Return dE/dt = -eps |m x Omega|^2 in W (<= 0) of the dissipation law."""
        momentum_norm = math.sqrt(state.angular_momentum @ state.angular_momentum)
        if momentum_norm == 0.0:
            return 0.0
        momentum_body = state.rotation.T @ state.angular_momentum
        turning = cross(momentum_body, body.inertia_inverse @ momentum_body)
        return -self.damping / momentum_norm * float(turning @ turning)


@numba.njit(cache=True, nogil=True)
def _turn_rate(q, angular_momentum, inertia_inverse, eps):
    """Return u = eps m x Omega (rad/s, body frame): m = R^T L, Omega = I_b^{-1} m."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    lx, ly, lz = angular_momentum[0], angular_momentum[1], angular_momentum[2]
    # m = R^T L with R the matrix of q (columns: the body axes in the world).
    m0 = ((1.0 - 2.0 * (y * y + z * z)) * lx + 2.0 * (x * y + z * w) * ly
          + 2.0 * (x * z - y * w) * lz)
    m1 = (2.0 * (x * y - z * w) * lx + (1.0 - 2.0 * (x * x + z * z)) * ly
          + 2.0 * (y * z + x * w) * lz)
    m2 = (2.0 * (x * z + y * w) * lx + 2.0 * (y * z - x * w) * ly
          + (1.0 - 2.0 * (x * x + y * y)) * lz)
    o0 = inertia_inverse[0, 0] * m0 + inertia_inverse[0, 1] * m1 + inertia_inverse[0, 2] * m2
    o1 = inertia_inverse[1, 0] * m0 + inertia_inverse[1, 1] * m1 + inertia_inverse[1, 2] * m2
    o2 = inertia_inverse[2, 0] * m0 + inertia_inverse[2, 1] * m1 + inertia_inverse[2, 2] * m2
    return eps * (m1 * o2 - m2 * o1), eps * (m2 * o0 - m0 * o2), eps * (m0 * o1 - m1 * o0)


@numba.njit(cache=True, nogil=True)
def _turned(q, vx, vy, vz):
    """Return q * exp(v): R turned by the body-frame rotation vector v (rad), normalised."""
    angle = math.sqrt(vx * vx + vy * vy + vz * vz)
    # sin(t/2)/t by its series below 1e-4 rad (next term ~t^4/3840, below round-off).
    s = 0.5 - angle * angle / 48.0 if angle < 1e-4 else math.sin(0.5 * angle) / angle
    bx, by, bz, bw = s * vx, s * vy, s * vz, math.cos(0.5 * angle)
    ax, ay, az, aw = q[0], q[1], q[2], q[3]
    out = np.empty(4)
    out[0] = aw * bx + ax * bw + ay * bz - az * by
    out[1] = aw * by - ax * bz + ay * bw + az * bx
    out[2] = aw * bz + ax * by - ay * bx + az * bw
    out[3] = aw * bw - ax * bx - ay * by - az * bz
    return out / math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)


@numba.njit(cache=True, nogil=True)
def dissipated_quaternion(q, angular_momentum, inertia_inverse, damping, dt):
    """
    Return the quaternion after dt s of the dissipation flow (explicit midpoint on SO(3)).

    The one definition of the flow: :meth:`Dissipation.flow` calls it, and the compiled
    integrators (integrators/fast.py) fuse it into their steps.
    """
    momentum_norm = math.sqrt(angular_momentum[0] ** 2 + angular_momentum[1] ** 2
                              + angular_momentum[2] ** 2)
    if momentum_norm == 0.0:
        return q.copy()
    eps = damping / momentum_norm
    ux, uy, uz = _turn_rate(q, angular_momentum, inertia_inverse, eps)
    half = _turned(q, 0.5 * dt * ux, 0.5 * dt * uy, 0.5 * dt * uz)
    ux, uy, uz = _turn_rate(half, angular_momentum, inertia_inverse, eps)
    return _turned(q, dt * ux, dt * uy, dt * uz)

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
Each flow step is the explicit midpoint rule (second order), its midpoint predicted in m
and its one turn exact on SO(3): m_half = m + (h/2) m x u(m), R_new = R exp(h u(m_half)).

The parameter `damping` (dimensionless) is the ratio of the dissipative turning of m to the
gyroscopic one, |eps m x (m x Omega)| / |m x Omega| = damping; 0.01 to 0.1 gives a
migration over tens to hundreds of spin periods.
"""

from __future__ import annotations

import math

import numpy as np

from .registry import check_number
from .registry import Effect
from .registry import ParameterError
from .registry import register_effect
from ..body import RigidBody
from ..kernels.algebra import cross
from ..kernels.algebra import exp_map
from ..kernels.algebra import quaternion_product
from ..kernels.algebra import rotate_back
from ..kernels.layout import inverse_inertia_times
from ..kernels.model import Array
from ..kernels.model import flow_function
from ..rotations import cross as cross_product
from ..state import State


MAX_DAMPING = 1.0e6
"""The largest damping accepted (dimensionless)."""


@flow_function
def relax(state: Array, parameters: Array, duration: float) -> None:
    """
    Turn the packed state's orientation by `duration` s of the dissipation flow, in place.

    parameters: damping, I_b^-1 (9, row-major).  u(m) = eps m x Omega (body frame, eps =
    damping / |L|, m = R^T L, Omega = I_b^-1 m) is the extra turning rate, and
    dm/dt = m x u as R turns.  Explicit midpoint, second order: the midpoint's m is predicted
    by m + (h/2) m x u(m), and R <- R exp(h u(m_half)) turns on SO(3) exactly (R stays a
    rotation to round-off, L is not touched).  One turn per flow: the flow costs about what a
    Buss step does (two turns, the midpoint's as a rotation too, would cost more for nothing
    the order needs).
    """
    lx, ly, lz = state[10], state[11], state[12]
    momentum_norm = math.sqrt(lx * lx + ly * ly + lz * lz)
    if momentum_norm == 0.0:
        return
    eps = parameters[0] / momentum_norm
    inverse = parameters[1:10]
    q = (state[0], state[1], state[2], state[3])
    m = rotate_back(q, (lx, ly, lz))
    # The rates scaled by eps first: m x (m x Omega) alone can overflow for a huge body.
    turning = cross(m, inverse_inertia_times(inverse, m))
    u = (eps * turning[0], eps * turning[1], eps * turning[2])
    drift = cross(m, u)
    half = 0.5 * duration
    middle = (m[0] + half * drift[0], m[1] + half * drift[1], m[2] + half * drift[2])
    ux, uy, uz = cross(middle, inverse_inertia_times(inverse, middle))
    whole = duration * eps
    # Not normalised: a product of unit quaternions is unit to round-off, and the step that
    # follows each flow normalises its own turn, so |q| never drifts; the normalisation's
    # square root and divisions were a quarter of the flow's time, on the step's critical
    # path (benchmarks/effect_cost.py).
    state[0], state[1], state[2], state[3] = quaternion_product(
        q, exp_map((whole * ux, whole * uy, whole * uz)))


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

    compiled_flow = staticmethod(relax)
    # Internal friction: no external torque, so |L| stays while T_rot drains.
    conserves = ('angular_momentum',)
    units = {'damping': '1 (dimensionless)'}
    example = {'damping': 0.1}

    def __init__(self, damping: float) -> None:
        self.damping = check_number(damping, 'damping', positive=True)
        # Above 1 the body already relaxes within a turn; the flow stays finite up to 1e6
        # and beyond (measured on flat_spin), but products with it overflow near 1e308: far from
        # physics and far from overflow.
        if self.damping > MAX_DAMPING:
            raise ParameterError('damping', f'must be at most {MAX_DAMPING:g} (a ratio of '
                                            f'turning rates), got {self.damping:g}')

    def flow_parameters(self, body: RigidBody) -> Array:
        """Return the damping and I_b^-1 (row-major) of the integrated body."""
        return np.concatenate([[self.damping], body.inertia_inverse.reshape(9)])

    def energy_rate(self, body: RigidBody, state: State) -> float:
        """Return dE/dt = -eps |m x Omega|^2 in W (<= 0) of the dissipation law."""
        momentum_norm = math.sqrt(state.angular_momentum @ state.angular_momentum)
        if momentum_norm == 0.0:
            return 0.0
        momentum_body = state.rotation.T @ state.angular_momentum
        turning = cross_product(momentum_body, body.inertia_inverse @ momentum_body)
        return -self.damping / momentum_norm * float(turning @ turning)

"""
The seed's integrators: the simple first-order method and Buss's second-order methods.

Both start from the world angular velocity omega = I_w^{-1} L and end with
R <- exp(h [w]x) R, I_w = R I_b R^T (seed 000, "Numerical Methods for Rigid Body
Simulation"); they differ in the effective angular velocity w.  World L is not touched by
the rotation update, so torque-free motion conserves it exactly.
"""

import numpy as np

from .common import free_translation
from .common import kick_drift_kick
from .common import rotate_by_world_vector
from .common import world_inertia_inverse
from .fast import buss_kernel
from .fast import first_order_kernel
from .registry import register_integrator
from ..rotations import cross
from ..state import State


@register_integrator('first_order', order=1, fast_kernel=first_order_kernel)
def first_order(body, state, time, dt, wrench):
    """
    Seed's simple first-order method: w = omega = I_w^{-1} L, then R <- exp(h [w]x) R.

    The wrench is read once at the start of the step and held over it: L <- L + h tau,
    p <- p + h F, and x <- x + h p/m + h^2 F/(2m) (the exact motion under the held force, so
    a constant force gives the exact parabola and a constant torque the exact L(t)).
    """
    omega = world_inertia_inverse(body, state.rotation) @ state.angular_momentum
    quaternion = rotate_by_world_vector(state.quaternion, dt * omega)
    position = free_translation(state, dt, body.mass)
    if wrench is None:
        return State._from_arrays(quaternion, position, state.linear_momentum,
                                  state.angular_momentum)
    force, torque = wrench(state, time)
    linear_momentum = state.linear_momentum
    if np.any(force):
        # Only a force moves the COM from rest (a torque alone leaves it where it is).
        position = position + 0.5 * dt * dt * force / body.mass
        linear_momentum = linear_momentum + dt * force
    return State._from_arrays(quaternion, position, linear_momentum,
                              state.angular_momentum + dt * torque)


def buss_free_step(body, state, dt, augmented=True):
    """
    Return Buss's torque-free step (the drift); world L and p are unchanged.

    alpha = I_w^{-1} (tau - omega x L) with tau = 0 inside the drift (torques enter as
    kicks around it), and the effective angular velocity

        w = omega + (h/2) alpha + (h^2/12) (alpha x omega).

    The h^2/12 term is the first Magnus-expansion (BCH/Dynkin) correction: it accounts for
    rotations about omega and alpha not commuting.  augmented=False drops it (plain).
    """
    inertia_inverse_world = world_inertia_inverse(body, state.rotation)
    angular_momentum = state.angular_momentum
    omega = inertia_inverse_world @ angular_momentum
    alpha = inertia_inverse_world @ (-cross(omega, angular_momentum))
    effective = omega + (0.5 * dt) * alpha
    if augmented:
        effective = effective + (dt * dt / 12.0) * cross(alpha, omega)
    quaternion = rotate_by_world_vector(state.quaternion, dt * effective)
    return State._from_arrays(quaternion, free_translation(state, dt, body.mass),
                              state.linear_momentum, angular_momentum)


def _buss_plain_free_step(body, state, dt):
    return buss_free_step(body, state, dt, augmented=False)


@register_integrator('buss', order=2, fast_kernel=buss_kernel(augmented=True))
def buss(body, state, time, dt, wrench):
    """
    Buss's augmented second-order method (J. Comput. Phys. 164:377, 2000).

    Torque-free it is exactly Buss's step (see :func:`buss_free_step`); a wrench enters as
    half kicks of the momenta around it (Strang splitting), which keeps second order.
    """
    return kick_drift_kick(body, state, time, dt, wrench, buss_free_step)


@register_integrator('buss_plain', order=2, fast_kernel=buss_kernel(augmented=False))
def buss_plain(body, state, time, dt, wrench):
    """Buss's plain second-order method: :func:`buss` without the h^2/12 term."""
    return kick_drift_kick(body, state, time, dt, wrench, _buss_plain_free_step)

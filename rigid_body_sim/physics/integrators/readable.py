"""
Building blocks of the readable steps (State in, State out, a Python wrench callable).

Frames: everything here is world frame unless a name ends in ``_body``.  Units SI.
"""

import numpy as np

from ..rotations import quaternion_from_rotation_vector
from ..rotations import quaternion_multiply
from ..state import State


def rotate_by_world_vector(quaternion, rotation_vector):
    """
    Return R' = exp([v]x) R as a unit quaternion: turn by v (rad, world frame).

    The quaternion form of the seed's update R <- exp(h [w]x) R; it is exact for any angle
    and renormalised, so R stays orthonormal to round-off however many steps are taken.
    """
    q = quaternion_multiply(quaternion_from_rotation_vector(rotation_vector), quaternion)
    return q / np.sqrt(q @ q)


def world_inertia_inverse(body, rotation):
    """Return I_w^{-1} = R I_b^{-1} R^T (world frame)."""
    return rotation @ body.inertia_inverse @ rotation.T


def kick(state, time, half_step, wrench, estimate=None):
    """
    Return (the state after the momenta take the wrench for `half_step` s, an estimate).

    The kick flow changes p and L with the configuration (R, x) fixed:
    p <- p + h F, L <- L + h tau.  For a wrench that depends only on configuration and time
    this is exact.  A momentum-dependent wrench (drag) is integrated by the explicit
    midpoint rule instead, which keeps the kick second order, so the Strang composition
    kick-drift-kick stays second order too: its first half takes `estimate` (force,
    torque) if given, else the wrench at the state.  The estimate returned, the wrench
    extrapolated to the kick's end along the momenta (2 W_mid - W_0), is the closing kick's
    (kernels/model.py's impulse says why it keeps the order; None without momentum
    dependence).
    """
    if not getattr(wrench, 'momentum_dependent', False):
        force, torque = wrench(state, time)
        next_estimate = None
    else:
        first_force, first_torque = wrench(state, time) if estimate is None else estimate
        midpoint = State._from_arrays(state.quaternion, state.position,
                                      state.linear_momentum + 0.5 * half_step * first_force,
                                      state.angular_momentum + 0.5 * half_step * first_torque)
        force, torque = wrench(midpoint, time)
        next_estimate = (2.0 * force - first_force, 2.0 * torque - first_torque)
    return State._from_arrays(state.quaternion, state.position,
                              state.linear_momentum + half_step * force,
                              state.angular_momentum + half_step * torque), next_estimate


def kick_drift_kick(body, state, time, dt, wrench, drift):
    """
    Return the Strang composition kick(dt/2) drift(dt) kick(dt/2).

    `drift(body, state, dt)` is a torque-free, force-free step (the free flow), of order >= 2.
    Splitting the wrench off this way keeps a second-order drift second order with any
    wrench, and makes a constant torque give L(t) = L0 + tau t and a constant force give the
    exact parabola of the COM.  The closing kick starts from the opening one's estimate.
    """
    if wrench is None:
        return drift(body, state, dt)
    half = 0.5 * dt
    state, estimate = kick(state, time, half, wrench)
    state = drift(body, state, dt)
    return kick(state, time + dt, half, wrench, estimate)[0]


def free_translation(state, dt, mass):
    """
    Return the COM position after dt s of force-free motion: x + dt p / m (exact).

    At rest (p = 0) nothing moves the COM: the position array itself is returned, not
    recomputed, so translation costs nothing when nothing pushes it.
    """
    if not state.linear_momentum.any():
        return state.position
    return state.position + dt * state.linear_momentum / mass

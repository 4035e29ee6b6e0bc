"""
Classical fourth-order Runge-Kutta on (quaternion, position, momenta), re-normalised.

A baseline, not a geometric method: it conserves neither the energy nor |q| by construction
(|q| is restored after each step), but it is fourth order.  World L is exact torque-free only
because its rate, the torque, is then zero.
"""

import numpy as np

from .fast import rk4_kernel
from .registry import register_integrator
from ..rotations import matrix_from_quaternion
from ..state import State


def _derivative(body, quaternion, position, linear_momentum, angular_momentum, time, wrench):
    """Return d/dt of (q, x, p, L): (1/2 (omega, 0) * q, p / m, F, tau), world frame."""
    unit = quaternion / np.sqrt(quaternion @ quaternion)
    rotation = matrix_from_quaternion(unit)
    omega = rotation @ body.inertia_inverse @ rotation.T @ angular_momentum
    x, y, z, w = quaternion
    # (omega, 0) * q: the world angular velocity acts on the left.
    quaternion_rate = 0.5 * np.array([
        omega[0] * w + omega[1] * z - omega[2] * y,
        -omega[0] * z + omega[1] * w + omega[2] * x,
        omega[0] * y - omega[1] * x + omega[2] * w,
        -omega[0] * x - omega[1] * y - omega[2] * z,
    ])
    if wrench is None:
        force = torque = np.zeros(3)
    else:
        force, torque = wrench(
            State._from_arrays(unit, position, linear_momentum, angular_momentum), time)
    return quaternion_rate, linear_momentum / body.mass, force, torque


@register_integrator('rk4', order=4, fast_kernel=rk4_kernel)
def rk4(body, state, time, dt, wrench):
    """Classical RK4 step of (q, x, p, L); the wrench is sampled at each of the 4 stages."""
    y0 = (state.quaternion, state.position, state.linear_momentum, state.angular_momentum)

    def f(y, t):
        return _derivative(body, *y, t, wrench)

    def add(y, k, h):
        return tuple(a + h * b for a, b in zip(y, k))

    k1 = f(y0, time)
    k2 = f(add(y0, k1, 0.5 * dt), time + 0.5 * dt)
    k3 = f(add(y0, k2, 0.5 * dt), time + 0.5 * dt)
    k4 = f(add(y0, k3, dt), time + dt)
    y1 = tuple(a + dt / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
               for a, b1, b2, b3, b4 in zip(y0, k1, k2, k3, k4))
    return State._from_arrays(*y1)

"""
Compiled fast paths (numba) of the integrators, for runs under a held wrench.

Each kernel advances (quaternion, position, linear_momentum, angular_momentum) in place over
`steps` steps.  The wrench is held constant in the world frame (force_world, torque_world)
and in the body frame (force_body, torque_body, which turn with the body); that covers
torque-free motion, the node's torque/wrench topics and uniform gravity.

They compute the same thing as the readable step functions beside them (tested to
round-off), in the cheapest frame: turning by w in the world frame, exp(h [w]x) R, equals
R exp(h [R^T w]x), so Buss's update is formed from body-frame vectors and applied on the
right, q <- q * exp(h w_body), which avoids building I_w = R I_b R^T at all.
"""

import functools
import math

import numba
import numpy as np

_jit = functools.partial(numba.njit, cache=True, nogil=True)


@_jit
def _matrix(q):
    x, y, z, w = q[0], q[1], q[2], q[3]
    m = np.empty((3, 3))
    m[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    m[0, 1] = 2.0 * (x * y - z * w)
    m[0, 2] = 2.0 * (x * z + y * w)
    m[1, 0] = 2.0 * (x * y + z * w)
    m[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    m[1, 2] = 2.0 * (y * z - x * w)
    m[2, 0] = 2.0 * (x * z - y * w)
    m[2, 1] = 2.0 * (y * z + x * w)
    m[2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return m


@_jit
def _mul(m, v):
    return np.array([m[0, 0] * v[0] + m[0, 1] * v[1] + m[0, 2] * v[2],
                     m[1, 0] * v[0] + m[1, 1] * v[1] + m[1, 2] * v[2],
                     m[2, 0] * v[0] + m[2, 1] * v[1] + m[2, 2] * v[2]])


@_jit
def _mul_transposed(m, v):
    return np.array([m[0, 0] * v[0] + m[1, 0] * v[1] + m[2, 0] * v[2],
                     m[0, 1] * v[0] + m[1, 1] * v[1] + m[2, 1] * v[2],
                     m[0, 2] * v[0] + m[1, 2] * v[1] + m[2, 2] * v[2]])


@_jit
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1],
                     a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


@_jit
def _turn_right(q, v):
    """Set q <- q * exp(v) in place: turn by the body-frame rotation vector v (rad)."""
    angle = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if angle < 1e-4:
        s = 0.5 - angle * angle / 48.0
    else:
        s = math.sin(0.5 * angle) / angle
    bx, by, bz, bw = s * v[0], s * v[1], s * v[2], math.cos(0.5 * angle)
    ax, ay, az, aw = q[0], q[1], q[2], q[3]
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    w = aw * bw - ax * bx - ay * by - az * bz
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    q[0], q[1], q[2], q[3] = x / norm, y / norm, z / norm, w / norm


@_jit
def _held_wrench(q, force_world, torque_world, force_body, torque_body):
    m = _matrix(q)
    return force_world + _mul(m, force_body), torque_world + _mul(m, torque_body)


@_jit
def _has_wrench(force_world, torque_world, force_body, torque_body):
    for i in range(3):
        if (force_world[i] != 0.0 or torque_world[i] != 0.0 or force_body[i] != 0.0
                or torque_body[i] != 0.0):
            return True
    return False


@_jit
def _first_order_steps(quaternion, position, linear_momentum, angular_momentum,
                       inertia_body, inertia_body_inverse, mass, dt, steps,
                       force_world, torque_world, force_body, torque_body):
    pushed = _has_wrench(force_world, torque_world, force_body, torque_body)
    for _ in range(steps):
        m = _matrix(quaternion)
        omega_body = _mul(inertia_body_inverse, _mul_transposed(m, angular_momentum))
        if pushed:
            force, torque = _held_wrench(quaternion, force_world, torque_world, force_body,
                                         torque_body)
            position += dt * linear_momentum / mass + (0.5 * dt * dt / mass) * force
            linear_momentum += dt * force
            angular_momentum += dt * torque
        else:
            position += dt * linear_momentum / mass
        _turn_right(quaternion, dt * omega_body)


@_jit
def _buss_steps(quaternion, position, linear_momentum, angular_momentum,
                inertia_body, inertia_body_inverse, mass, dt, steps,
                force_world, torque_world, force_body, torque_body, augmentation):
    pushed = _has_wrench(force_world, torque_world, force_body, torque_body)
    half = 0.5 * dt
    twelfth = dt * dt / 12.0 * augmentation
    for _ in range(steps):
        if pushed:
            force, torque = _held_wrench(quaternion, force_world, torque_world, force_body,
                                         torque_body)
            linear_momentum += half * force
            angular_momentum += half * torque
        m = _matrix(quaternion)
        momentum_body = _mul_transposed(m, angular_momentum)
        omega_body = _mul(inertia_body_inverse, momentum_body)
        alpha_body = _mul(inertia_body_inverse, -_cross(omega_body, momentum_body))
        effective = omega_body + half * alpha_body + twelfth * _cross(alpha_body, omega_body)
        _turn_right(quaternion, dt * effective)
        position += dt * linear_momentum / mass
        if pushed:
            force, torque = _held_wrench(quaternion, force_world, torque_world, force_body,
                                         torque_body)
            linear_momentum += half * force
            angular_momentum += half * torque


def buss_kernel(augmented):
    """Return the compiled Buss kernel, with (True) or without (False) the h^2/12 term."""
    return functools.partial(_buss_steps, augmentation=1.0 if augmented else 0.0)


first_order_kernel = _first_order_steps


@_jit
def _rk4_derivative(q, linear_momentum, angular_momentum, inertia_body_inverse, mass,
                    force_world, torque_world, force_body, torque_body):
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    unit = q / norm
    m = _matrix(unit)
    omega = _mul(m, _mul(inertia_body_inverse, _mul_transposed(m, angular_momentum)))
    # dq/dt = 1/2 (omega, 0) * q, omega in the world frame (left product).
    dq = np.empty(4)
    dq[0] = 0.5 * (omega[0] * q[3] + omega[1] * q[2] - omega[2] * q[1])
    dq[1] = 0.5 * (-omega[0] * q[2] + omega[1] * q[3] + omega[2] * q[0])
    dq[2] = 0.5 * (omega[0] * q[1] - omega[1] * q[0] + omega[2] * q[3])
    dq[3] = 0.5 * (-omega[0] * q[0] - omega[1] * q[1] - omega[2] * q[2])
    force, torque = _held_wrench(unit, force_world, torque_world, force_body, torque_body)
    return dq, linear_momentum / mass, force, torque


@_jit
def _rk4_steps(quaternion, position, linear_momentum, angular_momentum,
               inertia_body, inertia_body_inverse, mass, dt, steps,
               force_world, torque_world, force_body, torque_body):
    args = (inertia_body_inverse, mass, force_world, torque_world, force_body, torque_body)
    for _ in range(steps):
        q0, x0, p0, l0 = quaternion.copy(), position.copy(), linear_momentum.copy(), \
            angular_momentum.copy()
        dq1, dx1, dp1, dl1 = _rk4_derivative(q0, p0, l0, *args)
        h = 0.5 * dt
        dq2, dx2, dp2, dl2 = _rk4_derivative(q0 + h * dq1, p0 + h * dp1, l0 + h * dl1, *args)
        dq3, dx3, dp3, dl3 = _rk4_derivative(q0 + h * dq2, p0 + h * dp2, l0 + h * dl2, *args)
        dq4, dx4, dp4, dl4 = _rk4_derivative(q0 + dt * dq3, p0 + dt * dp3, l0 + dt * dl3,
                                             *args)
        s = dt / 6.0
        q = q0 + s * (dq1 + 2.0 * dq2 + 2.0 * dq3 + dq4)
        quaternion[:] = q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        position[:] = x0 + s * (dx1 + 2.0 * dx2 + 2.0 * dx3 + dx4)
        linear_momentum[:] = p0 + s * (dp1 + 2.0 * dp2 + 2.0 * dp3 + dp4)
        angular_momentum[:] = l0 + s * (dl1 + 2.0 * dl2 + 2.0 * dl3 + dl4)


rk4_kernel = _rk4_steps

"""
Compiled fast path (numba) of the `exact` integrator.

The same construction as the readable :mod:`.exact` (see its docstring for the derivation),
line for line, with scalars instead of small arrays and the compiled elliptic functions of
:mod:`rigid_body_sim.physics.elliptic`; the tests prove both equal to round-off.  Under a
held wrench each step is kick(dt/2), exact free flow(dt), kick(dt/2), as in the readable
step.
"""

import functools
import math

import numba

from .principal import ASYMMETRIC
from .principal import OBLATE
from .principal import principal_frame
from .principal import PROLATE
from ..elliptic import carlson_rf_compiled
from ..elliptic import carlson_rj_compiled
from ..elliptic import jacobi_elliptic_compiled

__all__ = ['exact_kernel']

_jit = functools.partial(numba.njit, cache=True, nogil=True)

_HALF_SQRT2 = math.sqrt(0.5)


@_jit
def _multiply(a, b):
    """Hamilton product of quaternions (x, y, z, w) given as tuples."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


@_jit
def _conjugate(q):
    return (-q[0], -q[1], -q[2], q[3])


@_jit
def _normalised(q):
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)


@_jit
def _from_rotation_vector(vx, vy, vz):
    angle = math.sqrt(vx * vx + vy * vy + vz * vz)
    if angle < 1e-4:
        s = 0.5 - angle * angle / 48.0
    else:
        s = math.sin(0.5 * angle) / angle
    return (s * vx, s * vy, s * vz, math.cos(0.5 * angle))


@_jit
def _rotate_inverse(q, vx, vy, vz):
    """Return R(q)^T v: world vector v in the body frame."""
    x, y, z, w = q
    return ((1.0 - 2.0 * (y * y + z * z)) * vx + 2.0 * (x * y + z * w) * vy
            + 2.0 * (x * z - y * w) * vz,
            2.0 * (x * y - z * w) * vx + (1.0 - 2.0 * (x * x + z * z)) * vy
            + 2.0 * (y * z + x * w) * vz,
            2.0 * (x * z + y * w) * vx + 2.0 * (y * z - x * w) * vy
            + (1.0 - 2.0 * (x * x + y * y)) * vz)


@_jit
def _rotate(q, vx, vy, vz):
    """Return R(q) v."""
    return _rotate_inverse(_conjugate(q), vx, vy, vz)


@_jit
def _turn_about_momentum(q, lx, ly, lz, angle):
    norm = math.sqrt(lx * lx + ly * ly + lz * lz)
    f = angle / norm
    return _normalised(_multiply(_from_rotation_vector(f * lx, f * ly, f * lz), q))


@_jit
def _to_pole(nx, ny, nz):
    """Smallest rotation taking the unit vector n (n_z >= 0) to +e_z."""
    return _normalised((ny, -nx, 0.0, 1.0 + nz))


@_jit
def _symmetric_rotation(q, lx, ly, lz, moments, axes, kind, duration):
    if kind == PROLATE:
        column, axial, transverse = 2, moments[2], moments[0]
    elif kind == OBLATE:
        column, axial, transverse = 0, moments[0], moments[1]
    else:
        column, axial, transverse = 2, moments[2], moments[2]
    ax, ay, az = axes[0, column], axes[1, column], axes[2, column]
    mx, my, mz = _rotate_inverse(q, lx, ly, lz)
    spin = duration * (ax * mx + ay * my + az * mz) * (1.0 / axial - 1.0 / transverse)
    spun = _multiply(q, _from_rotation_vector(spin * ax, spin * ay, spin * az))
    norm = math.sqrt(lx * lx + ly * ly + lz * lz)
    return _turn_about_momentum(spun, lx, ly, lz, duration * norm / transverse)


@_jit
def _precession_integral(u, sn, cn, dn, turns, c_over_a, l_over_a_alpha, third_coefficient,
                         alpha, characteristic, complete_rj):
    theta = turns * math.pi + math.atan2(alpha * sn, max(cn, 0.0))
    periodic = 0.0
    if characteristic != 0.0:
        periodic = sn ** 3 * carlson_rj_compiled(cn * cn, dn * dn, 1.0,
                                                 1.0 - characteristic * sn * sn)
        if turns != 0:
            periodic += 2.0 * turns * complete_rj
    return -c_over_a * u + l_over_a_alpha * theta + third_coefficient * periodic


@_jit
def _asymmetric_rotation(q, lx, ly, lz, moments, axes, axes_quaternion, duration):
    bx, by, bz = _rotate_inverse(q, lx, ly, lz)
    # Principal coordinates: axes^T m_body.
    p1 = axes[0, 0] * bx + axes[1, 0] * by + axes[2, 0] * bz
    p2 = axes[0, 1] * bx + axes[1, 1] * by + axes[2, 1] * bz
    p3 = axes[0, 2] * bx + axes[1, 2] * by + axes[2, 2] * bz
    i1, i2, i3 = moments[0], moments[1], moments[2]
    separatrix = p1 * p1 * (i1 - i2) / i1 + p3 * p3 * (i3 - i2) / i3
    frame = axes_quaternion
    if separatrix >= 0.0:
        j1, j2, j3 = i1, i2, i3
        m1, m2, m3 = p1, p2, p3
    else:
        # New axes (e3, -e2, e1): a half turn about (e1 + e3) / sqrt(2).
        j1, j2, j3 = i3, i2, i1
        m1, m2, m3 = p3, -p2, p1
        frame = _multiply(frame, (_HALF_SQRT2, 0.0, _HALF_SQRT2, 0.0))
    if m3 < 0.0:
        m2, m3 = -m2, -m3
        frame = _multiply(frame, (1.0, 0.0, 0.0, 0.0))
    if m1 < 0.0:
        m1, m2 = -m1, -m2
        frame = _multiply(frame, (0.0, 0.0, 1.0, 0.0))
    momentum_norm = math.sqrt(lx * lx + ly * ly + lz * lz)
    twice_energy = m1 * m1 / j1 + m2 * m2 / j2 + m3 * m3 / j3
    a = m1 * m1 + m2 * m2 * j1 * (j3 - j2) / (j2 * (j3 - j1))
    if a == 0.0 or (m1 == 0.0 and m3 == 0.0):
        return _turn_about_momentum(q, lx, ly, lz, duration * twice_energy / momentum_norm)
    b_squared = m2 * m2 + m1 * m1 * j2 * (j3 - j1) / (j1 * (j3 - j2))
    c_squared = m3 * m3 + m2 * m2 * j3 * (j2 - j1) / (j2 * (j3 - j1))
    amplitude_a, amplitude_b = math.sqrt(a), math.sqrt(b_squared)
    amplitude_c = math.sqrt(c_squared)
    g = m2 * m2 * (j2 - j1) / j2 + m3 * m3 * (j3 - j1) / j3
    h = m1 * m1 * (j3 - j1) / j1 + m2 * m2 * (j3 - j2) / j2
    parameter = (j2 - j1) * h / ((j3 - j2) * g)
    complement = (j3 - j1) * separatrix / ((j3 - j2) * g)
    rate = math.copysign(math.sqrt((j3 - j2) * g / (j1 * j2 * j3)), j3 - j2)
    c0, s0 = m1 / amplitude_a, m2 / amplitude_b
    norm = math.hypot(c0, s0)
    c0, s0 = c0 / norm, s0 / norm
    d0 = math.sqrt(c0 * c0 + complement * s0 * s0)
    u0 = s0 * carlson_rf_compiled(c0 * c0, d0 * d0, 1.0)
    u1 = u0 + rate * duration
    turns, reduced = 0, u1
    if complement > 0.0:
        half_period = 2.0 * carlson_rf_compiled(0.0, complement, 1.0)
        turns = int(round(u1 / half_period))
        reduced = u1 - half_period * turns
    s1, c1, d1 = jacobi_elliptic_compiled(reduced, parameter, complement)
    sign = -1.0 if turns % 2 != 0 else 1.0
    n1 = amplitude_a * c1 * sign
    n2 = amplitude_b * s1 * sign
    n3 = amplitude_c * d1
    b_term = c_squared * parameter
    characteristic = -b_term / a
    alpha = math.sqrt(1.0 + b_term / a)
    complete_rj = 0.0
    if turns != 0 and characteristic != 0.0:
        complete_rj = carlson_rj_compiled(0.0, complement, 1.0, 1.0 - characteristic)
    c_over_a = amplitude_c / a
    l_over_a_alpha = momentum_norm / (a * alpha)
    third = momentum_norm * momentum_norm * amplitude_c * parameter / (3.0 * a * a)
    integral = (_precession_integral(u1, s1, c1, d1, turns, c_over_a, l_over_a_alpha, third,
                                     alpha, characteristic, complete_rj)
                - _precession_integral(u0, s0, c0, d0, 0, c_over_a, l_over_a_alpha, third,
                                       alpha, characteristic, complete_rj))
    precession = (duration * twice_energy / momentum_norm
                  - amplitude_a * amplitude_b / momentum_norm * integral)
    new_norm = math.sqrt(n1 * n1 + n2 * n2 + n3 * n3)
    body_turn = _multiply(
        _conjugate(_to_pole(m1 / momentum_norm, m2 / momentum_norm, m3 / momentum_norm)),
        _to_pole(n1 / new_norm, n2 / new_norm, n3 / new_norm))
    body_turn = _multiply(_multiply(frame, body_turn), _conjugate(frame))
    return _turn_about_momentum(_multiply(q, body_turn), lx, ly, lz, precession)


@_jit
def _free_rotation(q, lx, ly, lz, moments, axes, axes_quaternion, kind, duration):
    if (lx == 0.0 and ly == 0.0 and lz == 0.0) or duration == 0.0:
        return q
    if kind == ASYMMETRIC:
        return _asymmetric_rotation(q, lx, ly, lz, moments, axes, axes_quaternion, duration)
    return _symmetric_rotation(q, lx, ly, lz, moments, axes, kind, duration)


@_jit
def _exact_steps(quaternion, position, linear_momentum, angular_momentum, moments, axes,
                 axes_quaternion, kind, mass, dt, steps, force_world, torque_world,
                 force_body, torque_body):
    pushed = False
    for i in range(3):
        if (force_world[i] != 0.0 or torque_world[i] != 0.0 or force_body[i] != 0.0
                or torque_body[i] != 0.0):
            pushed = True
    frame_q = (axes_quaternion[0], axes_quaternion[1], axes_quaternion[2], axes_quaternion[3])
    q = _normalised((quaternion[0], quaternion[1], quaternion[2], quaternion[3]))
    half = 0.5 * dt
    for _ in range(steps):
        if pushed:
            _kick(q, linear_momentum, angular_momentum, half, force_world, torque_world,
                  force_body, torque_body)
        q = _free_rotation(q, angular_momentum[0], angular_momentum[1], angular_momentum[2],
                           moments, axes, frame_q, kind, dt)
        for i in range(3):
            position[i] += dt * linear_momentum[i] / mass
        if pushed:
            _kick(q, linear_momentum, angular_momentum, half, force_world, torque_world,
                  force_body, torque_body)
    quaternion[0], quaternion[1], quaternion[2], quaternion[3] = q


@_jit
def _kick(q, linear_momentum, angular_momentum, half, force_world, torque_world, force_body,
          torque_body):
    """Kick the momenta in place: p += h F, L += h tau, F = F_w + R F_b, tau = tau_w + R tau_b."""
    fx, fy, fz = _rotate(q, force_body[0], force_body[1], force_body[2])
    tx, ty, tz = _rotate(q, torque_body[0], torque_body[1], torque_body[2])
    linear_momentum[0] += half * (force_world[0] + fx)
    linear_momentum[1] += half * (force_world[1] + fy)
    linear_momentum[2] += half * (force_world[2] + fz)
    angular_momentum[0] += half * (torque_world[0] + tx)
    angular_momentum[1] += half * (torque_world[1] + ty)
    angular_momentum[2] += half * (torque_world[2] + tz)


def exact_kernel(quaternion, position, linear_momentum, angular_momentum, inertia_body,
                 inertia_body_inverse, mass, dt, steps, force_world, torque_world, force_body,
                 torque_body):
    """
    Advance the arrays in place by `steps` exact steps under a held wrench.

    The kernel signature of :mod:`.registry`; the principal frame of `inertia_body` is
    looked up once per call (cached), then the compiled loop runs.
    """
    frame = principal_frame(inertia_body)
    _exact_steps(quaternion, position, linear_momentum, angular_momentum, frame.moments,
                 frame.axes, frame.quaternion, frame.kind, mass, dt, steps, force_world,
                 torque_world, force_body, torque_body)

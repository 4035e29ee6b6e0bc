"""
Compiled fast paths (numba) of the `splitting` and `splitting4` integrators.

The same flows as the readable :mod:`.splitting`, in the same order and with the same
arithmetic (a sin/cos pair of the half angle per flow), on scalars; the tests prove both
equal to round-off.  Each stage is kick(c h/2), free flow(c h), kick(c h/2) under the held
wrench, as in the readable steps.  Packed arrays and the run signature: see :mod:`.fast`.
"""

import functools
import math

import numba

from .fast import BODY_FRAME
from .fast import BODY_MASS
from .fast import BODY_MOMENTS
from .fast import CompiledIntegrator
from .fast import dissipate
from .fast import FORCE_BODY
from .fast import FORCE_WORLD
from .fast import LEVER_ARM
from .fast import LEVER_FORCE
from .fast import nonzero_momentum
from .fast import pushes
from .fast import TORQUE_BODY
from .fast import TORQUE_WORLD
from ..error_control import controlled_ticks

__all__ = ['splitting_kernel_for']

_jit = functools.partial(numba.njit, cache=True, nogil=True)


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
def _rotate_inverse(q, vx, vy, vz):
    """Return R(q)^T v (q normalised here, as matrix_from_quaternion does)."""
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    x, y, z, w = q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm
    return ((1.0 - 2.0 * (y * y + z * z)) * vx + 2.0 * (x * y + z * w) * vy
            + 2.0 * (x * z - y * w) * vz,
            2.0 * (x * y - z * w) * vx + (1.0 - 2.0 * (x * x + z * z)) * vy
            + 2.0 * (y * z + x * w) * vz,
            2.0 * (x * z + y * w) * vx + 2.0 * (y * z - x * w) * vy
            + (1.0 - 2.0 * (x * x + y * y)) * vz)


@_jit
def _impulse(q, half, wrench):
    """
    Return the impulses (h F, h tau) of the held wrench taken at q, as 6 numbers.

    F = F_w + R F_b, tau = tau_w + R tau_b + (R r) x F_lever (packed rows: see fast.py).
    """
    conjugate = (-q[0], -q[1], -q[2], q[3])
    force_body, torque_body = wrench[FORCE_BODY], wrench[TORQUE_BODY]
    fx, fy, fz = _rotate_inverse(conjugate, force_body[0], force_body[1], force_body[2])
    tx, ty, tz = _rotate_inverse(conjugate, torque_body[0], torque_body[1], torque_body[2])
    lever = wrench[LEVER_FORCE]
    if lever[0] != 0.0 or lever[1] != 0.0 or lever[2] != 0.0:
        # The moment (R r) x F of a world force at the body point r.
        arm = wrench[LEVER_ARM]
        rx, ry, rz = _rotate_inverse(conjugate, arm[0], arm[1], arm[2])
        tx += ry * lever[2] - rz * lever[1]
        ty += rz * lever[0] - rx * lever[2]
        tz += rx * lever[1] - ry * lever[0]
    force_world, torque_world = wrench[FORCE_WORLD], wrench[TORQUE_WORLD]
    return (half * (force_world[0] + fx), half * (force_world[1] + fy),
            half * (force_world[2] + fz), half * (torque_world[0] + tx),
            half * (torque_world[1] + ty), half * (torque_world[2] + tz))


@_jit
def _free_flow(q, lx, ly, lz, moments, frame, axes, dt):
    """Return q after the Strang step with (outer, inner, central) = axes, as the readable."""
    qp = _multiply(q, frame)
    m0, m1, m2 = _rotate_inverse(qp, lx, ly, lz)
    x, y, z, w = qp
    for flow in range(5):
        if flow == 2:
            axis, duration = axes[2], dt
        elif flow == 1 or flow == 3:
            axis, duration = axes[1], 0.5 * dt
        else:
            axis, duration = axes[0], 0.5 * dt
        # The flow of m_i^2 / (2 I_i): qp <- qp * (half_sine e_i, half_cosine), and the
        # other two components of m turn back by the angle.
        if axis == 0:
            angle = duration * m0 / moments[0]
        elif axis == 1:
            angle = duration * m1 / moments[1]
        else:
            angle = duration * m2 / moments[2]
        half_sine, half_cosine = math.sin(0.5 * angle), math.cos(0.5 * angle)
        cosine = 1.0 - 2.0 * half_sine * half_sine
        sine = 2.0 * half_sine * half_cosine
        if axis == 0:
            m1, m2 = cosine * m1 + sine * m2, -sine * m1 + cosine * m2
            x, y, z, w = (w * half_sine + x * half_cosine, y * half_cosine + z * half_sine,
                          z * half_cosine - y * half_sine, w * half_cosine - x * half_sine)
        elif axis == 1:
            m2, m0 = cosine * m2 + sine * m0, -sine * m2 + cosine * m0
            x, y, z, w = (x * half_cosine - z * half_sine, w * half_sine + y * half_cosine,
                          z * half_cosine + x * half_sine, w * half_cosine - y * half_sine)
        else:
            m0, m1 = cosine * m0 + sine * m1, -sine * m0 + cosine * m1
            x, y, z, w = (x * half_cosine + y * half_sine, y * half_cosine - x * half_sine,
                          w * half_sine + z * half_cosine, w * half_cosine - z * half_sine)
    q = _multiply((x, y, z, w), (-frame[0], -frame[1], -frame[2], frame[3]))
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)


@_jit
def _splitting_run(state, wrench, body, method, damping, dt, steps):
    """Run the splitting (signature: fast.py); method = (outer, inner, central axis, c...)."""
    mass = body[BODY_MASS]
    moments = body[BODY_MOMENTS:BODY_MOMENTS + 3]
    frame = (body[BODY_FRAME], body[BODY_FRAME + 1], body[BODY_FRAME + 2], body[BODY_FRAME + 3])
    axes = (int(method[0]), int(method[1]), int(method[2]))
    coefficients = method[3:]
    pushed, forced = pushes(wrench)
    translates = forced or nonzero_momentum(state)
    moved = 0
    # Round-off: a step's kicks (two per stage, five stages for splitting4, one of them
    # negative) and the COM's displacement are summed apart, small, and each added to its
    # momentum or position once per step, compensated (Kahan) across the steps of the run.
    # Added stage by stage, each add rounded at |p| or |x| and a held force made the COM
    # drift in proportion to the step count (splitting4: 3.2e-7 m after 2e5 steps of 1 N
    # on 1 kg, 9x rk4's).  Within a step the momenta are p0 + (kicks so far), one rounding.
    # Kahan's lost low bits of p, L and x, carried across the steps.
    cpx = cpy = cpz = clx = cly = clz = cxx = cxy = cxz = 0.0
    for _ in range(steps):
        if damping > 0.0:
            dissipate(state, body, damping, 0.5 * dt)
        q = (state[0], state[1], state[2], state[3])
        # This step's start and sums (kicks to p and L, displacement); the momenta within
        # the step are start + sum.
        px0, py0, pz0 = state[7], state[8], state[9]
        lx0, ly0, lz0 = state[10], state[11], state[12]
        spx = spy = spz = slx = sly = slz = dxx = dxy = dxz = 0.0
        px, py, pz, lx, ly, lz = px0, py0, pz0, lx0, ly0, lz0
        for coefficient in coefficients:
            stage = coefficient * dt
            if pushed:
                ipx, ipy, ipz, ilx, ily, ilz = _impulse(q, 0.5 * stage, wrench)
                spx += ipx
                spy += ipy
                spz += ipz
                slx += ilx
                sly += ily
                slz += ilz
                px, py, pz = px0 + spx, py0 + spy, pz0 + spz
                lx, ly, lz = lx0 + slx, ly0 + sly, lz0 + slz
            q = _free_flow(q, lx, ly, lz, moments, frame, axes, stage)
            if translates:
                dxx += stage * px / mass
                dxy += stage * py / mass
                dxz += stage * pz / mass
            if pushed:
                ipx, ipy, ipz, ilx, ily, ilz = _impulse(q, 0.5 * stage, wrench)
                spx += ipx
                spy += ipy
                spz += ipz
                slx += ilx
                sly += ily
                slz += ilz
                px, py, pz = px0 + spx, py0 + spy, pz0 + spz
                lx, ly, lz = lx0 + slx, ly0 + sly, lz0 + slz
        if pushed:
            state[7], cpx = _compensated_add(px0, spx, cpx)
            state[8], cpy = _compensated_add(py0, spy, cpy)
            state[9], cpz = _compensated_add(pz0, spz, cpz)
            state[10], clx = _compensated_add(lx0, slx, clx)
            state[11], cly = _compensated_add(ly0, sly, cly)
            state[12], clz = _compensated_add(lz0, slz, clz)
        if translates:
            moved += 1
            state[4], cxx = _compensated_add(state[4], dxx, cxx)
            state[5], cxy = _compensated_add(state[5], dxy, cxy)
            state[6], cxz = _compensated_add(state[6], dxz, cxz)
        state[0], state[1], state[2], state[3] = q
        if damping > 0.0:
            dissipate(state, body, damping, 0.5 * dt)
    return moved


@_jit
def _compensated_add(total, addend, compensation):
    """Return (total + addend, new compensation): one step of Kahan summation."""
    corrected = addend - compensation
    result = total + corrected
    return result, (result - total) - corrected


@_jit
def _splitting_controlled(state, wrench, body, method, damping, tick, ticks, control, clock):
    return controlled_ticks(_splitting_run, state, wrench, body, method, damping, tick, ticks,
                            control, clock)


def splitting_kernel_for(axes, coefficients):
    """
    Return the compiled integrator of a composition of Strang splitting steps.

    axes: principal axes (0, 1, 2 by ascending moment) of the outer, inner and central
    flows; coefficients: the stage lengths as fractions of dt ((1.0,) for Strang itself).
    Callable with the registry's kernel signature, see :class:`.fast.CompiledIntegrator`.
    """
    return CompiledIntegrator(_splitting_run, tuple(axes) + tuple(coefficients),
                              _splitting_controlled)

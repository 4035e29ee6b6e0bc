"""
Compiled fast paths (numba) of the integrators, on packed arrays.

Each compiled integrator is a function

    run(state, wrench, body, method, damping, dt, steps) -> moved

that advances `state` in place over `steps` steps of dt s and returns the number of steps in
which the position changed (zero when nothing pushes the origin and it is at rest: the
translation is then skipped, not computed as x + 0).  The arrays are packed once by the
caller (the Simulator keeps its state in this layout between calls), so a call passes seven
arguments, not fourteen:

state : (13,)  q (x, y, z, w, body to world) | x (m) | p (kg m/s) | L (kg m^2/s); world
    frame, x, p and L of the body's origin (the COM of a free body, the pivot of a pivoted
    one, see effects/pivot.py).
wrench : (6, 3)  the held wrench, constant over the steps:
    FORCE_WORLD   force through the origin, world frame (N)
    TORQUE_WORLD  torque, world frame (N m)
    FORCE_BODY    force through the origin fixed in the body, body frame (N); turns with it
    TORQUE_BODY   torque fixed in the body, body frame (N m)
    LEVER_FORCE   a world-fixed force (N) acting at the body point LEVER_ARM (m, body frame,
    LEVER_ARM     from the origin); it enters by its moment (R r) x F about the origin only,
                  as under a pivot, whose reaction takes the force itself (gravity on a top)
body : (27,)  I_b^{-1} row-major (9, kg^-1 m^-2) | m (kg) | principal moments (3, kg m^2)
    | principal frame quaternion (4) | principal axes as columns, row-major (9) | kind of
    body (ASYMMETRIC ... OBLATE of principal.py, as a float); see :func:`body_values`.
method : (n,)  the integrator's constants (Buss's augmentation; the splitting's axes and
    stage coefficients).
damping : float  the dissipation flow fused into every step as flow(dt/2), step(dt),
    flow(dt/2), exactly as the Simulator composes effects.dissipation's flow; 0: none.

They compute the same thing as the readable step functions beside them (tested to
round-off), with every part of the wrench evaluated at the same kick points, so each keeps
its order.  They work in the cheapest frame: turning by w in the world frame,
exp(h [w]x) R, equals R exp(h [R^T w]x), so Buss's update is formed from body-frame vectors
and applied on the right, q <- q * exp(h w_body), which avoids building I_w = R I_b R^T.

:class:`CompiledIntegrator` holds a run function with its method constants and is also
callable with the registry's kernel signature (integrators/registry.py).
"""

import functools
import math

import numba
import numpy as np

from .principal import principal_frame
from ..effects.dissipation import dissipated_quaternion
from ..error_control import controlled_ticks

__all__ = ['CompiledIntegrator', 'body_values', 'packed_wrench', 'FORCE_WORLD',
           'TORQUE_WORLD', 'FORCE_BODY', 'TORQUE_BODY', 'LEVER_FORCE', 'LEVER_ARM',
           'STATE_SIZE', 'BODY_SIZE', 'BODY_MASS', 'BODY_MOMENTS', 'BODY_FRAME', 'BODY_AXES',
           'BODY_KIND']

_jit = functools.partial(numba.njit, cache=True, nogil=True)

# Rows of the packed wrench.
FORCE_WORLD, TORQUE_WORLD, FORCE_BODY, TORQUE_BODY, LEVER_FORCE, LEVER_ARM = range(6)
STATE_SIZE = 13
BODY_SIZE = 27
# Offsets in the packed body: mass, principal moments, principal frame quaternion, principal
# axes (the exact integrator solves in the very matrix the readable step uses), kind.
BODY_MASS, BODY_MOMENTS, BODY_FRAME, BODY_AXES, BODY_KIND = 9, 10, 13, 17, 26


def body_values(inertia_body, inertia_body_inverse, mass):
    """
    Return the packed body (27,) of a body's mass properties (body frame, SI).

    The principal frame comes from :func:`.principal.principal_frame`, the same function the
    readable splitting and exact steps use, so both split in the very same frame.
    """
    frame = principal_frame(inertia_body)
    return np.concatenate([np.asarray(inertia_body_inverse, dtype=float).reshape(9),
                           [float(mass)], frame.moments, frame.quaternion,
                           frame.axes.reshape(9), [float(frame.kind)]])


def packed_wrench(force_world=None, torque_world=None, force_body=None, torque_body=None,
                  lever_force=None, lever_arm=None):
    """Return the packed (6, 3) wrench; parts not given are zero (units: see module doc)."""
    wrench = np.zeros((6, 3))
    for row, part in ((FORCE_WORLD, force_world), (TORQUE_WORLD, torque_world),
                      (FORCE_BODY, force_body), (TORQUE_BODY, torque_body),
                      (LEVER_FORCE, lever_force), (LEVER_ARM, lever_arm)):
        if part is not None:
            wrench[row] = part
    return wrench


class CompiledIntegrator:
    """
    A compiled integrator: ``run`` on packed arrays and its ``method`` constants.

    Calling it with the registry's kernel signature (quaternion, position, linear_momentum,
    angular_momentum, inertia_body, inertia_body_inverse, mass, dt, steps, force_world,
    torque_world, force_body, torque_body) packs the arrays, runs, and writes them back: the
    form the tests and benchmarks call directly.  The Simulator calls ``run``.

    ``controlled``, if given, is ``run`` under error control: the compiled
    :func:`~rigid_body_sim.physics.error_control.controlled_ticks` with this run built in,

        controlled(state, wrench, body, method, damping, tick, ticks, control, clock)

    (a module-level wrapper beside the run: numba caches those, not closures).  Without it
    the Simulator runs the same controller in Python around ``run``.
    """

    def __init__(self, run, method=(), controlled=None):
        self.run = run
        self.method = np.array(method, dtype=float)
        self.controlled = controlled

    def __call__(self, quaternion, position, linear_momentum, angular_momentum, inertia_body,
                 inertia_body_inverse, mass, dt, steps, force_world, torque_world, force_body,
                 torque_body):
        """Advance the four arrays in place by `steps` steps of dt s under a held wrench."""
        state = np.concatenate([quaternion, position, linear_momentum, angular_momentum])
        self.run(state, packed_wrench(force_world, torque_world, force_body, torque_body),
                 body_values(inertia_body, inertia_body_inverse, mass), self.method, 0.0,
                 float(dt), int(steps))
        quaternion[:] = state[0:4]
        position[:] = state[4:7]
        linear_momentum[:] = state[7:10]
        angular_momentum[:] = state[10:13]


# -- small compiled helpers


@_jit
def _rotated_back(q, v):
    """Return R^T v as a 3-tuple, R the matrix of the unit quaternion q (a tuple or an array)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    return ((1.0 - 2.0 * (y * y + z * z)) * v[0] + 2.0 * (x * y + z * w) * v[1]
            + 2.0 * (x * z - y * w) * v[2],
            2.0 * (x * y - z * w) * v[0] + (1.0 - 2.0 * (x * x + z * z)) * v[1]
            + 2.0 * (y * z + x * w) * v[2],
            2.0 * (x * z + y * w) * v[0] + 2.0 * (y * z - x * w) * v[1]
            + (1.0 - 2.0 * (x * x + y * y)) * v[2])


@_jit
def _inverse_inertia_times(body, v):
    """Return I_b^-1 v as a 3-tuple, I_b^-1 row-major in the packed body's first nine."""
    return (body[0] * v[0] + body[1] * v[1] + body[2] * v[2],
            body[3] * v[0] + body[4] * v[1] + body[5] * v[2],
            body[6] * v[0] + body[7] * v[1] + body[8] * v[2])


@_jit
def _crossed(a, b):
    """Return a x b as a 3-tuple."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@_jit
def _turn_right_by(q, vx, vy, vz):
    """Set q <- q * exp(v) in place, v = (vx, vy, vz) a body-frame rotation vector (rad)."""
    square = vx * vx + vy * vy + vz * vz
    if square < 1e-4:
        # |v| < 0.01 rad (a substep of a split tick): the Taylor series of sin(|v|/2) / |v|
        # and cos(|v|/2) in place of sqrt, sin and cos; the first terms left out,
        # |v|^6 / 322560 and |v|^8 / 10321920, are below 1e-17 and 1e-23 there, under half
        # an ulp of 0.5 and 1.
        s = 0.5 + square * (-1.0 / 48.0 + square / 3840.0)
        c = 1.0 + square * (-0.125 + square * (1.0 / 384.0 - square / 46080.0))
    else:
        angle = math.sqrt(square)
        s = math.sin(0.5 * angle) / angle
        c = math.cos(0.5 * angle)
    bx, by, bz, bw = s * vx, s * vy, s * vz, c
    ax, ay, az, aw = q[0], q[1], q[2], q[3]
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    w = aw * bw - ax * bx - ay * by - az * bz
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    q[0], q[1], q[2], q[3] = x / norm, y / norm, z / norm, w / norm


@_jit
def _is_nonzero(v):
    return v[0] != 0.0 or v[1] != 0.0 or v[2] != 0.0


@_jit
def _row_size(array, row):
    """Return |a_r0| + |a_r1| + |a_r2| of one row of a 2-D array (0 only for a zero row)."""
    return abs(array[row, 0]) + abs(array[row, 1]) + abs(array[row, 2])


@_jit
def pushes(wrench):
    """
    Return (pushed, forced) of a packed wrench.

    pushed: some part is non-zero, so the momenta take kicks; forced: a force acts on the
    origin (FORCE_WORLD or FORCE_BODY), so p changes and the position must be advanced even
    from rest.  A lever force only turns the body.  Straight-line sums, no branch per
    entry: every run call asks this, and at a few steps per call it weighed like a step.
    """
    forced = _row_size(wrench, FORCE_WORLD) + _row_size(wrench, FORCE_BODY) != 0.0
    lever = (_row_size(wrench, LEVER_FORCE) != 0.0) & (_row_size(wrench, LEVER_ARM) != 0.0)
    turned = (_row_size(wrench, TORQUE_WORLD) + _row_size(wrench, TORQUE_BODY) != 0.0) | lever
    return forced | turned, forced


@_jit
def _rotated(q, v):
    """Return R v as a 3-tuple, R the rotation matrix of the unit quaternion q."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    return ((1.0 - 2.0 * (y * y + z * z)) * v[0] + 2.0 * (x * y - z * w) * v[1]
            + 2.0 * (x * z + y * w) * v[2],
            2.0 * (x * y + z * w) * v[0] + (1.0 - 2.0 * (x * x + z * z)) * v[1]
            + 2.0 * (y * z - x * w) * v[2],
            2.0 * (x * z - y * w) * v[0] + 2.0 * (y * z + x * w) * v[1]
            + (1.0 - 2.0 * (x * x + y * y)) * v[2])


@_jit
def wrench_at(q, wrench):
    """
    Return (F, tau), 3-tuples, of the held wrench with the body at the unit quaternion q.

    F = F_w + R F_b through the origin; tau = tau_w + R tau_b + (R r) x F_lever about it
    (world frame).  Scalars only: a kick allocates nothing.
    """
    force_world, torque_world = wrench[FORCE_WORLD], wrench[TORQUE_WORLD]
    fx, fy, fz = _rotated(q, wrench[FORCE_BODY])
    tx, ty, tz = _rotated(q, wrench[TORQUE_BODY])
    lever = wrench[LEVER_FORCE]
    if _is_nonzero(lever):
        rx, ry, rz = _rotated(q, wrench[LEVER_ARM])
        tx += ry * lever[2] - rz * lever[1]
        ty += rz * lever[0] - rx * lever[2]
        tz += rx * lever[1] - ry * lever[0]
    return ((force_world[0] + fx, force_world[1] + fy, force_world[2] + fz),
            (torque_world[0] + tx, torque_world[1] + ty, torque_world[2] + tz))


@_jit
def kick(q, linear_momentum, angular_momentum, wrench, duration):
    """
    Kick the momenta in place: p += h F, L += h tau, the held wrench taken at q.

    q is the unit quaternion as an array or a 4-tuple (fast_exact.py keeps it in a tuple).
    """
    force, torque = wrench_at(q, wrench)
    for i in range(3):
        linear_momentum[i] += duration * force[i]
        angular_momentum[i] += duration * torque[i]


@_jit
def dissipate(state, body, damping, duration):
    """
    Apply the dissipation flow of effects.dissipation for `duration` s to q (in place).

    Its one definition is compiled into these kernels: numba's cache does not see edits to
    a function in another file, so after changing dissipated_quaternion delete the cached
    kernels (integrators/__pycache__/*.nbi, *.nbc); the fused == composed test catches it.
    """
    state[0:4] = dissipated_quaternion(state[0:4], state[10:13],
                                       body[0:9].reshape((3, 3)), damping, duration)


@_jit
def nonzero_momentum(state):
    """Return True if the linear momentum of the packed state is not exactly zero."""
    return state[7] != 0.0 or state[8] != 0.0 or state[9] != 0.0


# -- the seed's integrators (readable definitions: seed.py)


@_jit
def _first_order_run(state, wrench, body, method, damping, dt, steps):
    quaternion, position = state[0:4], state[4:7]
    linear_momentum, angular_momentum = state[7:10], state[10:13]
    mass = body[BODY_MASS]
    pushed, forced = pushes(wrench)
    # Unforced, p is constant: a body at rest stays where it is without any arithmetic.
    translates = forced or nonzero_momentum(state)
    moved = 0
    for _ in range(steps):
        if damping > 0.0:
            dissipate(state, body, damping, 0.5 * dt)
        omega_body = _inverse_inertia_times(body, _rotated_back(quaternion, angular_momentum))
        if pushed:
            # The wrench at the start of the step, held over it (seed.first_order).
            force, torque = wrench_at(quaternion, wrench)
            if translates:
                for i in range(3):
                    position[i] += (dt * linear_momentum[i] / mass
                                    + (0.5 * dt * dt / mass) * force[i])
                moved += 1
            for i in range(3):
                linear_momentum[i] += dt * force[i]
                angular_momentum[i] += dt * torque[i]
        elif translates:
            position += dt * linear_momentum / mass
            moved += 1
        _turn_right_by(quaternion, dt * omega_body[0], dt * omega_body[1], dt * omega_body[2])
        if damping > 0.0:
            dissipate(state, body, damping, 0.5 * dt)
    return moved


@_jit
def _buss_run(state, wrench, body, method, damping, dt, steps):
    # Scalars and tuples only in the loop: numba keeps them in registers, where the small
    # arrays of the array form were heap-allocated every step (a torque-free step went from
    # 0.17 to 0.06 us, and to 0.05 with the series in _turn_right_by: benchmarks/
    # step_cost.py; the same operations in the same order, so the same bits).
    quaternion, position = state[0:4], state[4:7]
    linear_momentum, angular_momentum = state[7:10], state[10:13]
    mass = body[BODY_MASS]
    pushed, forced = pushes(wrench)
    translates = forced or nonzero_momentum(state)
    half = 0.5 * dt
    twelfth = dt * dt / 12.0 * method[0]
    moved = 0
    for _ in range(steps):
        if damping > 0.0:
            dissipate(state, body, damping, half)
        if pushed:
            kick(quaternion, linear_momentum, angular_momentum, wrench, half)
        momentum_body = _rotated_back(quaternion, angular_momentum)
        omega_body = _inverse_inertia_times(body, momentum_body)
        gyroscopic = _crossed(omega_body, momentum_body)
        alpha_body = _inverse_inertia_times(body, (-gyroscopic[0], -gyroscopic[1], -gyroscopic[2]))
        coupling = _crossed(alpha_body, omega_body)
        _turn_right_by(quaternion,
                       dt * (omega_body[0] + half * alpha_body[0] + twelfth * coupling[0]),
                       dt * (omega_body[1] + half * alpha_body[1] + twelfth * coupling[1]),
                       dt * (omega_body[2] + half * alpha_body[2] + twelfth * coupling[2]))
        if translates:
            for i in range(3):
                position[i] += dt * linear_momentum[i] / mass
            moved += 1
        if pushed:
            kick(quaternion, linear_momentum, angular_momentum, wrench, half)
        if damping > 0.0:
            dissipate(state, body, damping, half)
    return moved


@_jit
def _buss_controlled(state, wrench, body, method, damping, tick, ticks, control, clock):
    return controlled_ticks(_buss_run, state, wrench, body, method, damping, tick, ticks,
                            control, clock)


@_jit
def _first_order_controlled(state, wrench, body, method, damping, tick, ticks, control, clock):
    return controlled_ticks(_first_order_run, state, wrench, body, method, damping, tick,
                            ticks, control, clock)


def buss_kernel(augmented):
    """Return the compiled Buss integrator, with (True) or without (False) the h^2/12 term."""
    return CompiledIntegrator(_buss_run, (1.0 if augmented else 0.0,), _buss_controlled)


first_order_kernel = CompiledIntegrator(_first_order_run, controlled=_first_order_controlled)


# -- classical RK4 (readable definition: rk4.py)


@_jit
def _rk4_derivative(q, momentum_body, linear_momentum, inertia_body_inverse, wrench, pushed):
    """
    Return (dq, dm, F) of rk4.py's stage at the (unnormalised) stage quaternion q (4-tuple).

    dq = 1/2 q * (Omega, 0), dm = m x Omega + R^T tau (body frame), F (world), with
    Omega = I_b^{-1} m and the held wrench taken at the normalised q, as rk4.py samples it.
    Scalars and tuples only: a stage allocates nothing.
    """
    x, y, z, w = q
    m0, m1, m2 = momentum_body
    a = inertia_body_inverse
    o0 = a[0, 0] * m0 + a[0, 1] * m1 + a[0, 2] * m2
    o1 = a[1, 0] * m0 + a[1, 1] * m1 + a[1, 2] * m2
    o2 = a[2, 0] * m0 + a[2, 1] * m1 + a[2, 2] * m2
    dq = (0.5 * (w * o0 + y * o2 - z * o1), 0.5 * (w * o1 + z * o0 - x * o2),
          0.5 * (w * o2 + x * o1 - y * o0), -0.5 * (x * o0 + y * o1 + z * o2))
    d0, d1, d2 = m1 * o2 - m2 * o1, m2 * o0 - m0 * o2, m0 * o1 - m1 * o0
    force = (0.0, 0.0, 0.0)
    if pushed:
        norm = math.sqrt(x * x + y * y + z * z + w * w)
        unit = (x / norm, y / norm, z / norm, w / norm)
        force, torque = wrench_at(unit, wrench)
        # R^T tau: the torque in the body frame at this stage's orientation.
        t0, t1, t2 = _rotated_back(unit, torque)
        d0, d1, d2 = d0 + t0, d1 + t1, d2 + t2
    return dq, (d0, d1, d2), force


@_jit
def _stage4(y, k, h):
    """Return the 4-tuple y + h k."""
    return (y[0] + h * k[0], y[1] + h * k[1], y[2] + h * k[2], y[3] + h * k[3])


@_jit
def _stage3(y, k, h):
    """Return the 3-tuple y + h k."""
    return (y[0] + h * k[0], y[1] + h * k[1], y[2] + h * k[2])


@_jit
def _world_momentum_change(q, dq, m, dm):
    """Return R(d) m1 - m0 of rk4.world_momentum_change (tuples; see there)."""
    x, y, z, w = q
    a, b, c, e = dq
    vx, vy, vz = w * a - x * e - y * c + z * b, w * b - y * e - z * a + x * c, \
        w * c - z * e - x * b + y * a
    scalar = 1.0 + (w * e + x * a + y * b + z * c)
    tx, ty, tz = vy * m[2] - vz * m[1], vz * m[0] - vx * m[2], vx * m[1] - vy * m[0]
    ux, uy, uz = vy * tz - vz * ty, vz * tx - vx * tz, vx * ty - vy * tx
    scale = 2.0 / (vx * vx + vy * vy + vz * vz + scalar * scalar)
    return (dm[0] + scale * (scalar * tx + ux), dm[1] + scale * (scalar * ty + uy),
            dm[2] + scale * (scalar * tz + uz))


@_jit
def _rk4_run(state, wrench, body, method, damping, dt, steps):
    quaternion, position = state[0:4], state[4:7]
    linear_momentum, angular_momentum = state[7:10], state[10:13]
    inertia_body_inverse = body[0:9].reshape((3, 3))
    mass = body[BODY_MASS]
    pushed, forced = pushes(wrench)
    translates = forced or nonzero_momentum(state)
    half, sixth = 0.5 * dt, dt / 6.0
    moved = 0
    for _ in range(steps):
        if damping > 0.0:
            dissipate(state, body, damping, half)
        q0 = (quaternion[0], quaternion[1], quaternion[2], quaternion[3])
        m0 = _rotated_back(q0, angular_momentum)
        p0 = (linear_momentum[0], linear_momentum[1], linear_momentum[2])
        dq1, dm1, f1 = _rk4_derivative(q0, m0, p0, inertia_body_inverse, wrench, pushed)
        p1 = _stage3(p0, f1, half)
        dq2, dm2, f2 = _rk4_derivative(_stage4(q0, dq1, half), _stage3(m0, dm1, half), p1,
                                       inertia_body_inverse, wrench, pushed)
        p2 = _stage3(p0, f2, half)
        dq3, dm3, f3 = _rk4_derivative(_stage4(q0, dq2, half), _stage3(m0, dm2, half), p2,
                                       inertia_body_inverse, wrench, pushed)
        p3 = _stage3(p0, f3, dt)
        dq4, dm4, f4 = _rk4_derivative(_stage4(q0, dq3, dt), _stage3(m0, dm3, dt), p3,
                                       inertia_body_inverse, wrench, pushed)
        dq = (sixth * (dq1[0] + 2.0 * dq2[0] + 2.0 * dq3[0] + dq4[0]),
              sixth * (dq1[1] + 2.0 * dq2[1] + 2.0 * dq3[1] + dq4[1]),
              sixth * (dq1[2] + 2.0 * dq2[2] + 2.0 * dq3[2] + dq4[2]),
              sixth * (dq1[3] + 2.0 * dq2[3] + 2.0 * dq3[3] + dq4[3]))
        dm = (sixth * (dm1[0] + 2.0 * dm2[0] + 2.0 * dm3[0] + dm4[0]),
              sixth * (dm1[1] + 2.0 * dm2[1] + 2.0 * dm3[1] + dm4[1]),
              sixth * (dm1[2] + 2.0 * dm2[2] + 2.0 * dm3[2] + dm4[2]))
        q = _stage4(q0, dq, 1.0)
        norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        quaternion[0], quaternion[1] = q[0] / norm, q[1] / norm
        quaternion[2], quaternion[3] = q[2] / norm, q[3] / norm
        # L1 = L0 + R0 (dm + (R(d) - 1) m1) from increments (rk4.world_momentum_change).
        change = _world_momentum_change(q0, dq, _stage3(m0, dm, 1.0), dm)
        lx, ly, lz = _rotated(q0, change)
        angular_momentum[0] += lx
        angular_momentum[1] += ly
        angular_momentum[2] += lz
        if translates:
            # dx/dt = p / m at the stages' momenta p0, p1, p2, p3.
            for i in range(3):
                position[i] += sixth * (p0[i] / mass + 2.0 * (p1[i] / mass)
                                        + 2.0 * (p2[i] / mass) + p3[i] / mass)
            moved += 1
        if pushed:
            for i in range(3):
                linear_momentum[i] = p0[i] + sixth * (f1[i] + 2.0 * f2[i] + 2.0 * f3[i] + f4[i])
        if damping > 0.0:
            dissipate(state, body, damping, half)
    return moved


@_jit
def _rk4_controlled(state, wrench, body, method, damping, tick, ticks, control, clock):
    return controlled_ticks(_rk4_run, state, wrench, body, method, damping, tick, ticks,
                            control, clock)


rk4_kernel = CompiledIntegrator(_rk4_run, controlled=_rk4_controlled)

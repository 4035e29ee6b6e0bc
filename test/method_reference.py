"""
Independent references of the integrators and the effects, written from their equations.

The kernels (rigid_body_sim/physics) are the only implementation of each method in the
package; this module writes each method again from its definition, with numpy and scipy and
in another formulation where the method allows one, and calls no kernel and no package
arithmetic (the package's RigidBody, State and effects are read as data: mass, inertia, the
state's arrays, an effect's parameters and declared flags).  A test that runs a kernel and
the reference of its method from the same state therefore compares two implementations: they
agree to round-off when both are right, whatever the method's own error.

The references (all world frame but where a name says body or principal; SI units):

- first_order and Buss's methods in the world frame with rotation matrices, as the seed and
  the paper write them: omega = I_w^{-1} L, alpha = I_w^{-1} (tau - omega x L),
  w = omega (+ (h/2) alpha (+ (h^2/12) alpha x omega)), R <- exp(h [w]x) R by Rodrigues'
  formula (the kernels turn a quaternion in the body frame);
- rk4: the textbook classical RK4 on y = (q, x, p, m = R^T L) with numpy arrays, q
  normalised after the step (the kernels write it out in scalars and form L from
  increments);
- the splittings: the principal frame from numpy's eigh, each flow of m_i^2 / (2 I_i) a
  matrix exponential (scipy.linalg.expm) of the rotation about principal axis i, composed
  Strang 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2) (axes by ascending moment), Suzuki's base step
  1 3 2 3 1, and Suzuki's coefficients p = 1 / (4 - 4^(1/3)) (Phys. Lett. A 146:319, 1990);
- exact: the torque-free equations dm/dt = m x Omega, dq/dt = 1/2 q (Omega, 0) (body frame)
  solved by scipy's DOP853 at rtol 1e-13 over each step (the kernel: Jacobi elliptic
  functions);
- the kicks: p += h F, L += h tau at fixed configuration; for a momentum-dependent wrench
  the explicit midpoint rule, the closing kick of a stage started from the opening one's
  extrapolated estimate 2 W_mid - W_0 (kernels/model.py's impulse defines the method so);
- the effects: gravity, drag, the sinusoidal torque, the dissipation flow (explicit
  midpoint in the body frame, one exact turn) and the pivot (the pivot system about the
  fixed point by the parallel-axis theorem, the moment r x F of a force at the COM).

The splitting references need distinct principal moments: with two equal, the split depends
on the choice of axes in their plane, which the package and numpy make differently.
"""

from dataclasses import dataclass
from dataclasses import replace
import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm

__all__ = ['Motion', 'REFERENCE_STEPS', 'REFERENCE_EFFECTS', 'STRANG', 'SUZUKI',
           'reference_run', 'rotation_of_quaternion', 'rotation_angle', 'motion_error',
           'kick', 'buss_drift', 'held_wrench', 'pivot_system', 'exact_drift',
           'dop853_solution']

EPS = np.finfo(float).eps
# The exact drift's DOP853 solve: over a step of |Omega| h < 1 rad it reaches round-off.
EXACT_RTOL = 1e-13
EXACT_ATOL = 1e-16


@dataclass(frozen=True)
class Motion:
    """A state as the references carry it: R (body to world), x, p, L (world), numpy."""

    rotation: np.ndarray
    position: np.ndarray
    linear_momentum: np.ndarray
    angular_momentum: np.ndarray

    @classmethod
    def of(cls, state):
        """Return the Motion of a package State (its quaternion turned into R here)."""
        return cls(rotation_of_quaternion(state.quaternion), np.array(state.position),
                   np.array(state.linear_momentum), np.array(state.angular_momentum))


def rotation_of_quaternion(q):
    """Return R of the quaternion q = (x, y, z, w) (normalised here), body to world."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _quaternion_of_rotation(rotation):
    """Return a unit quaternion (x, y, z, w) of the rotation matrix (Shepperd's method)."""
    r = rotation
    trace = np.trace(r)
    candidates = [trace, r[0, 0], r[1, 1], r[2, 2]]
    largest = int(np.argmax(candidates))
    if largest == 0:
        w = 0.5 * math.sqrt(1.0 + trace)
        q = [(r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w),
             (r[1, 0] - r[0, 1]) / (4 * w), w]
    else:
        i = largest - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        v = [0.0, 0.0, 0.0]
        v[i] = 0.5 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        v[j] = (r[j, i] + r[i, j]) / (4 * v[i])
        v[k] = (r[k, i] + r[i, k]) / (4 * v[i])
        q = v + [(r[k, j] - r[j, k]) / (4 * v[i])]
    return np.array(q) / np.linalg.norm(q)


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rodrigues(v):
    """Return exp([v]x) = E + sin(t)/t [v]x + (1 - cos t)/t^2 [v]x^2, t = |v| (Rodrigues)."""
    t = float(np.linalg.norm(v))
    k = _skew(v)
    if t < 1e-4:
        # sin(t)/t and (1 - cos t)/t^2 by their series to t^4 (error < t^6 / 5040 < 1e-26).
        a, b = 1.0 - t * t / 6.0 + t ** 4 / 120.0, 0.5 - t * t / 24.0 + t ** 4 / 720.0
    else:
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / (t * t)
    return np.eye(3) + a * k + b * (k @ k)


def _hamilton(a, b):
    """Return the Hamilton product a b of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def rotation_angle(a, b):
    """Return the angle (rad) of the rotation a^T b between two rotation matrices."""
    relative = a.T @ b
    sine = 0.5 * np.linalg.norm([relative[2, 1] - relative[1, 2],
                                 relative[0, 2] - relative[2, 0],
                                 relative[1, 0] - relative[0, 1]])
    return math.atan2(sine, 0.5 * (np.trace(relative) - 1.0))


def motion_error(state, motion):
    """
    Return (angle, the largest relative error of x, p and L) of a package State.

    The angle (rad) is that between R(q) of the State and the reference's R; each vector's
    error is relative to max(1, its reference magnitude) in SI units.
    """
    angle = rotation_angle(rotation_of_quaternion(state.quaternion), motion.rotation)
    worst = 0.0
    for got, expected in ((state.position, motion.position),
                          (state.linear_momentum, motion.linear_momentum),
                          (state.angular_momentum, motion.angular_momentum)):
        worst = max(worst, float(np.linalg.norm(np.asarray(got) - expected))
                    / max(1.0, float(np.linalg.norm(expected))))
    return angle, worst


@dataclass(frozen=True)
class _Body:
    """Mass properties as the references use them: m, I_b and its inverse (body frame)."""

    mass: float
    inertia: np.ndarray

    @property
    def inertia_inverse(self):
        return np.linalg.inv(self.inertia)


def _body(body):
    return _Body(float(body.mass), np.array(body.inertia, dtype=float))


# -- the kicks and the steps ---------------------------------------------------------------


def kick(motion, time, duration, wrench, estimate=None):
    """
    Return (the motion after a kick of `duration` s, the estimate for a closing kick).

    p += h F, L += h tau with (R, x) fixed.  A momentum-dependent wrench (its attribute
    ``momentum_dependent``) takes the explicit midpoint rule from a first estimate W_0 (the
    given `estimate`, else the wrench at the motion) and returns 2 W_mid - W_0.
    """
    if not getattr(wrench, 'momentum_dependent', False):
        force, torque = wrench(motion, time)
        following = None
    else:
        first = wrench(motion, time) if estimate is None else estimate
        half = 0.5 * duration
        middle = replace(motion, linear_momentum=motion.linear_momentum + half * first[0],
                         angular_momentum=motion.angular_momentum + half * first[1])
        force, torque = wrench(middle, time)
        following = (2.0 * force - first[0], 2.0 * torque - first[1])
    return replace(motion, linear_momentum=motion.linear_momentum + duration * force,
                   angular_momentum=motion.angular_momentum + duration * torque), following


def _translated(motion, body, duration):
    return replace(motion, position=motion.position
                   + duration * motion.linear_momentum / body.mass)


def buss_drift(body, motion, h, augmented=True):
    """Return Buss's torque-free step (world frame, rotation matrices, as the paper)."""
    rotation, momentum = motion.rotation, motion.angular_momentum
    inverse_world = rotation @ body.inertia_inverse @ rotation.T
    omega = inverse_world @ momentum
    alpha = inverse_world @ -np.cross(omega, momentum)
    effective = omega + 0.5 * h * alpha
    if augmented:
        effective = effective + h * h / 12.0 * np.cross(alpha, omega)
    return _translated(replace(motion, rotation=_rodrigues(h * effective) @ rotation), body, h)


def _principal(body):
    """Return (moments ascending, axes as columns, right-handed) of I_b by numpy's eigh."""
    moments, axes = np.linalg.eigh(body.inertia)
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


def _splitting_drift(axes_order):
    """Return the Strang free flow of the given (outer, inner, central) principal axes."""
    outer, inner, central = axes_order

    def drift(body, motion, h):
        moments, axes = _principal(body)
        principal = motion.rotation @ axes
        m = principal.T @ motion.angular_momentum
        for axis, duration in ((outer, 0.5 * h), (inner, 0.5 * h), (central, h),
                               (inner, 0.5 * h), (outer, 0.5 * h)):
            # The flow of m_i^2 / (2 I_i): a turn about e_i at the rate m_i / I_i.
            unit = np.zeros(3)
            unit[axis] = 1.0
            generator = _skew(unit) * (duration * m[axis] / moments[axis])
            principal = principal @ expm(generator)
            m = expm(-generator) @ m
        return _translated(replace(motion, rotation=principal @ axes.T), body, h)

    return drift


def exact_drift(body, motion, h):
    """Return the torque-free motion after h s, by DOP853 on the body-frame equations."""
    inverse = body.inertia_inverse
    q0 = _quaternion_of_rotation(motion.rotation)
    m0 = motion.rotation.T @ motion.angular_momentum

    def rate(time, y):
        q, m = y[:4], y[4:]
        omega = inverse @ m
        return np.concatenate([0.5 * _hamilton(q, np.append(omega, 0.0)), np.cross(m, omega)])

    solution = solve_ivp(rate, (0.0, h), np.concatenate([q0, m0]), method='DOP853',
                         rtol=EXACT_RTOL, atol=EXACT_ATOL * max(1.0, np.linalg.norm(m0)))
    assert solution.success, solution.message
    # World L is the flow's invariant: kept as it is; R from the solved quaternion.
    return _translated(replace(motion, rotation=rotation_of_quaternion(solution.y[:4, -1])),
                       body, h)


def dop853_solution(body, motion, duration, wrench=None, start_time=0.0, rtol=1e-13):
    """
    Return the Motion after `duration` s of the equations of motion, by DOP853 at `rtol`.

    World frame: dq/dt = 1/2 (omega, 0) q, omega = R I_b^{-1} R^T L, dx/dt = p / m,
    dp/dt = F, dL/dt = tau, with a reference `wrench(motion, time)` (or none).
    """
    inverse = body.inertia_inverse
    scale = max(1.0, float(np.linalg.norm(motion.angular_momentum)),
                float(np.linalg.norm(motion.linear_momentum)))

    def rate(time, y):
        q, x, p, momentum = y[:4], y[4:7], y[7:10], y[10:]
        rotation = rotation_of_quaternion(q)
        omega = rotation @ inverse @ rotation.T @ momentum
        force = torque = np.zeros(3)
        if wrench is not None:
            force, torque = wrench(Motion(rotation, x, p, momentum), time)
        return np.concatenate([0.5 * _hamilton(np.append(omega, 0.0), q), p / body.mass,
                               force, torque])

    y0 = np.concatenate([_quaternion_of_rotation(motion.rotation), motion.position,
                         motion.linear_momentum, motion.angular_momentum])
    solution = solve_ivp(rate, (start_time, start_time + duration), y0, method='DOP853',
                         rtol=rtol, atol=1e-15 * scale)
    assert solution.success, solution.message
    y = solution.y[:, -1]
    return Motion(rotation_of_quaternion(y[:4]), y[4:7], y[7:10], y[10:])


def _kicked(drift, stages):
    """Return the step of kick-drift-kick stages c_i around `drift` (the time runs along)."""
    def step(body, motion, time, dt, wrench):
        for c in stages:
            h = c * dt
            estimate = None
            if wrench is not None:
                motion, estimate = kick(motion, time, 0.5 * h, wrench)
            motion = drift(body, motion, h)
            if wrench is not None:
                motion = kick(motion, time + h, 0.5 * h, wrench, estimate)[0]
            time += h
        return motion
    return step


def _first_order(body, motion, time, dt, wrench):
    """Take the seed's step: turn by h omega, the wrench held over the step from its start."""
    rotation = motion.rotation
    omega = rotation @ body.inertia_inverse @ rotation.T @ motion.angular_momentum
    force = torque = np.zeros(3)
    if wrench is not None:
        force, torque = wrench(motion, time)
    return Motion(_rodrigues(dt * omega) @ rotation,
                  motion.position + dt * motion.linear_momentum / body.mass
                  + 0.5 * dt * dt * force / body.mass,
                  motion.linear_momentum + dt * force, motion.angular_momentum + dt * torque)


def _rk4(body, motion, time, dt, wrench):
    """Classical RK4 on y = (q, x, p, m = R^T L); the wrench at every stage's state."""
    inverse = body.inertia_inverse
    q0 = _quaternion_of_rotation(motion.rotation)
    y0 = np.concatenate([q0, motion.position, motion.linear_momentum,
                         motion.rotation.T @ motion.angular_momentum])

    def f(y, t):
        q, x, p, m = y[:4], y[4:7], y[7:10], y[10:]
        omega = inverse @ m
        dm = np.cross(m, omega)
        force = np.zeros(3)
        if wrench is not None:
            rotation = rotation_of_quaternion(q)
            force, torque = wrench(Motion(rotation, x, p, rotation @ m), t)
            dm = dm + rotation.T @ torque
        return np.concatenate([0.5 * _hamilton(q, np.append(omega, 0.0)), p / body.mass,
                               force, dm])

    k1 = f(y0, time)
    k2 = f(y0 + 0.5 * dt * k1, time + 0.5 * dt)
    k3 = f(y0 + 0.5 * dt * k2, time + 0.5 * dt)
    k4 = f(y0 + dt * k3, time + dt)
    y = y0 + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    rotation = rotation_of_quaternion(y[:4])
    return Motion(rotation, y[4:7], y[7:10], rotation @ y[10:])


STRANG = (1.0,)
"""The Strang step as one kick-drift-kick stage."""
_SUZUKI_P = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))
SUZUKI = (_SUZUKI_P, _SUZUKI_P, 1.0 - 4.0 * _SUZUKI_P, _SUZUKI_P, _SUZUKI_P)
"""Suzuki's fractal composition S(p h) S(p h) S((1 - 4p) h) S(p h) S(p h)."""

REFERENCE_STEPS = {
    'first_order': _first_order,
    'buss': _kicked(buss_drift, STRANG),
    'buss_plain': _kicked(lambda body, motion, h: buss_drift(body, motion, h, False), STRANG),
    'rk4': _rk4,
    'splitting': _kicked(_splitting_drift((0, 1, 2)), STRANG),
    'splitting4': _kicked(_splitting_drift((0, 2, 1)), SUZUKI),
    'exact': _kicked(exact_drift, STRANG),
}
"""Integrator name -> its reference step(body, motion, time, dt, wrench) -> Motion: one
entry per registered method (test_fast_paths checks that every one has its reference)."""


# -- the effects --------------------------------------------------------------------------


def held_wrench(force_world=None, torque_world=None, force_body=None, torque_body=None):
    """Return the held wrench F_w + R F_b, tau_w + R tau_b as a reference wrench (or None)."""
    parts = [np.zeros(3) if v is None else np.asarray(v, dtype=float)
             for v in (force_world, torque_world, force_body, torque_body)]
    if not any(np.any(part) for part in parts):
        return None

    def wrench(motion, time):
        rotation = motion.rotation
        return parts[0] + rotation @ parts[2], parts[1] + rotation @ parts[3]

    return wrench


def _gravity(effect, body):
    weight = body.mass * np.asarray(effect.acceleration, dtype=float)
    return lambda motion, time: (weight, np.zeros(3))


def _drag(effect, body):
    def wrench(motion, time):
        velocity = motion.linear_momentum / body.mass
        rotation = motion.rotation
        omega = rotation @ body.inertia_inverse @ rotation.T @ motion.angular_momentum
        return (-(effect.linear + effect.quadratic * np.linalg.norm(velocity)) * velocity,
                -(effect.rotational_linear + effect.rotational_quadratic
                  * np.linalg.norm(omega)) * omega)
    return wrench


def _sinusoidal_torque(effect, body):
    amplitude = np.asarray(effect.amplitude, dtype=float)
    return lambda motion, time: (
        np.zeros(3),
        amplitude * math.sin(2.0 * math.pi * effect.frequency * time + effect.phase))


def _dissipation(effect, body):
    """Return the flow(body, motion, h) of the dissipation law (explicit midpoint, body)."""
    def flow(integrated_body, motion, h):
        momentum = motion.angular_momentum
        norm = np.linalg.norm(momentum)
        if norm == 0.0:
            return motion
        eps = effect.damping / norm
        inverse = integrated_body.inertia_inverse

        def turning_rate(m):
            # u = eps m x Omega: the extra body-frame turning; it moves m by m x u.
            return eps * np.cross(m, inverse @ m)

        m = motion.rotation.T @ momentum
        middle = m + 0.5 * h * np.cross(m, turning_rate(m))
        return replace(motion, rotation=motion.rotation @ _rodrigues(h * turning_rate(middle)))
    return flow


@dataclass(frozen=True)
class _Pivot:
    """A pivot on a body: the pivot system and the maps between it and the physical state."""

    body: _Body  # the pivot system: m and the inertia about the pivot
    physical: _Body
    offset: np.ndarray  # d, the COM from the pivot, body frame
    anchor: np.ndarray

    def project(self, motion):
        """R and omega kept, x = anchor + R d, p = m omega x R d, L unchanged."""
        rotation = motion.rotation
        omega = rotation @ self.physical.inertia_inverse @ rotation.T @ motion.angular_momentum
        r = rotation @ self.offset
        return replace(motion, position=self.anchor + r,
                       linear_momentum=self.physical.mass * np.cross(omega, r))

    def reduce(self, motion):
        """Return the pivot system's motion: at the anchor, p = 0, L_pivot = L + r x p."""
        r = motion.rotation @ self.offset
        return Motion(motion.rotation, self.anchor.copy(), np.zeros(3),
                      motion.angular_momentum + np.cross(r, motion.linear_momentum))

    def expand(self, motion):
        """Return the physical motion of a pivot-system one."""
        rotation = motion.rotation
        omega = rotation @ self.body.inertia_inverse @ rotation.T @ motion.angular_momentum
        r = rotation @ self.offset
        p = self.body.mass * np.cross(omega, r)
        return Motion(rotation, self.anchor + r, p, motion.angular_momentum - np.cross(r, p))

    def transmit(self, wrench):
        """Return the pivot system's wrench (0, tau + r x F) of a physical one."""
        def transmitted(motion, time):
            force, torque = wrench(self.expand(motion), time)
            return np.zeros(3), torque + np.cross(motion.rotation @ self.offset, force)
        transmitted.momentum_dependent = getattr(wrench, 'momentum_dependent', False)
        return transmitted


def pivot_system(effect, body):
    """Return the :class:`_Pivot` of a pivot effect (its point and anchor) on `body`."""
    body = _body(body)
    d = -np.asarray(effect.point, dtype=float)
    inertia = body.inertia + body.mass * ((d @ d) * np.eye(3) - np.outer(d, d))
    return _Pivot(_Body(body.mass, inertia), body, d, np.asarray(effect.anchor, dtype=float))


REFERENCE_EFFECTS = {
    'gravity': ('wrench', _gravity),
    'drag': ('wrench', _drag),
    'sinusoidal_torque': ('wrench', _sinusoidal_torque),
    'dissipation': ('flow', _dissipation),
    'pivot': ('constraint', pivot_system),
    'external_wrench': ('nothing', None),
}
"""Effect name -> (what it is, its reference maker (effect, body)): one entry per registered
effect (test_fast_paths checks that every one has its reference)."""


def _summed(parts, momentum_dependent):
    """Return the reference wrench that sums `parts` (each ``(motion, time) -> (F, tau)``)."""
    def wrench(motion, time):
        force, torque = np.zeros(3), np.zeros(3)
        for part in parts:
            f, t = part(motion, time)
            force, torque = force + f, torque + t
        return force, torque
    wrench.momentum_dependent = momentum_dependent
    return wrench


def reference_run(name, body, state, dt, steps, effects=(), held=None, wrenches=(),
                  start_time=0.0):
    """
    Return the Motion after `steps` reference steps of integrator `name` from `state`.

    body : RigidBody; state : State at `start_time` (s); dt : s; effects : the package's
    effect objects, each taken by its reference (REFERENCE_EFFECTS, by ``effect_name``);
    held : the held wrench as a dict of held_wrench's keyword arguments; wrenches : further
    reference wrenches ``wrench(motion, time) -> (F, tau)`` on the physical motion (a
    test's own compiled terms written again), with ``momentum_dependent`` if they are.
    Each step is flow(dt/2), step(dt), flow(dt/2) with the flows, as the kernels compose them.
    Returns the physical motion.
    """
    physical = _body(body)
    parts = [] if held is None else [held_wrench(**held)]
    parts = [part for part in parts if part is not None] + list(wrenches)
    flows, constraint, momentum_dependent = [], None, any(
        getattr(w, 'momentum_dependent', False) for w in wrenches)
    for effect in effects:
        kind, make = REFERENCE_EFFECTS[effect.effect_name]
        if kind == 'wrench':
            parts.append(make(effect, physical))
            momentum_dependent = momentum_dependent or effect.momentum_dependent
        elif kind == 'flow':
            flows.append(make(effect, physical))
        elif kind == 'constraint':
            constraint = make(effect, physical)
    wrench = _summed(parts, momentum_dependent) if parts else None
    motion = Motion.of(state)
    integrated = physical
    if constraint is not None:
        motion = constraint.reduce(constraint.project(motion))
        integrated = constraint.body
        if wrench is not None:
            wrench = constraint.transmit(wrench)
    step = REFERENCE_STEPS[name]
    half = 0.5 * dt
    for k in range(steps):
        for flow in flows:
            motion = flow(integrated, motion, half)
        motion = step(integrated, motion, start_time + k * dt, dt, wrench)
        for flow in reversed(flows):
            motion = flow(integrated, motion, half)
    return motion if constraint is None else constraint.expand(motion)

"""
Tight reference solutions and error measures shared by the physics tests.

The reference integrates the equations of motion of /work/shared/physics.md written for the
unit quaternion q (x, y, z, w), body to world, with scipy's DOP853 at rtol 1e-13:

    dq/dt = 1/2 (omega, 0) * q,  omega = R I_b^{-1} R^T L   (world frame, left product)
    dx/dt = p / m,  dp/dt = F,  dL/dt = tau

It shares no code with the integrators under test (only the State container, so that the
same wrench callables drive both, and the registry's declarations), and its error (~1e-12)
is far below the errors the convergence tests measure.  Everything is world frame and SI.
"""

import math

import numpy as np
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import State
from scipy.integrate import solve_ivp
from scipy.special import ellipk

__all__ = [
    'body_rates_symmetric_top',
    'first_order_energy_gain_rate',
    'random_rotation',
    'rotation_angle_between',
    'reference_solution',
    'state_error',
    'torque_free_momentum_drift',
    'torque_free_omega_period',
]

REFERENCE_RTOL = 1e-13
REFERENCE_ATOL = 1e-15


def random_rotation(rng):
    """Return a uniformly random rotation matrix (det +1) drawn from `rng`."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _rotation_from_quaternion(q):
    """Return R of the (possibly unnormalised) quaternion (x, y, z, w)."""
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _derivative(body, wrench):
    inertia_inverse = body.inertia_inverse
    mass = body.mass

    def rate(time, y):
        q, x, p, angular_momentum = y[:4], y[4:7], y[7:10], y[10:13]
        rotation = _rotation_from_quaternion(q)
        omega = rotation @ (inertia_inverse @ (rotation.T @ angular_momentum))
        # (omega, 0) * q for quaternions stored (x, y, z, w).
        qx, qy, qz, qw = q
        dq = 0.5 * np.array([
            omega[0] * qw + omega[1] * qz - omega[2] * qy,
            -omega[0] * qz + omega[1] * qw + omega[2] * qx,
            omega[0] * qy - omega[1] * qx + omega[2] * qw,
            -omega[0] * qx - omega[1] * qy - omega[2] * qz,
        ])
        if wrench is None:
            force = torque = np.zeros(3)
        else:
            state = State._from_arrays(q.copy(), x.copy(), p.copy(), angular_momentum.copy())
            force, torque = wrench(state, time)
        return np.concatenate([dq, p / mass, force, torque])

    return rate


def reference_solution(body, state, duration, wrench=None, start_time=0.0):
    """
    Return the State after `duration` s from `state`, integrated to ~1e-12.

    Parameters
    ----------
    body : RigidBody
        Mass properties (body frame, about the COM).
    state : State
        Initial state (world frame) at `start_time` (s).
    duration : float
        Time span in s.
    wrench : callable or None
        ``wrench(state, time) -> (force_world, torque_world)`` in N and N m, as given to the
        integrators.
    start_time : float
        Time of `state` in s, passed on to the wrench.

    """
    y0 = np.concatenate([state.quaternion, state.position, state.linear_momentum,
                         state.angular_momentum])
    solution = solve_ivp(_derivative(body, wrench), (start_time, start_time + duration), y0,
                         method='DOP853', rtol=REFERENCE_RTOL, atol=REFERENCE_ATOL)
    if not solution.success:
        raise RuntimeError(f'reference integration failed: {solution.message}')
    y = solution.y[:, -1]
    return State._from_arrays(y[:4].copy(), y[4:7].copy(), y[7:10].copy(), y[10:13].copy())


def rotation_angle_between(rotation_a, rotation_b):
    """Return the angle (rad) of the rotation R_a^T R_b, accurate also for tiny angles."""
    relative = rotation_a.T @ rotation_b
    # sin from the skew part and cos from the trace: atan2 keeps full precision near 0.
    sine = 0.5 * np.linalg.norm([relative[2, 1] - relative[1, 2],
                                 relative[0, 2] - relative[2, 0],
                                 relative[1, 0] - relative[0, 1]])
    cosine = 0.5 * (np.trace(relative) - 1.0)
    return math.atan2(sine, cosine)


def state_error(state, reference, scale_length=1.0, scale_momentum=1.0):
    """
    Return a dict of the errors of `state` against `reference` and their sum 'total'.

    'angle': rotation angle of R^T R_ref (rad); 'angular_momentum': |L - L_ref| / |L_ref|
    (absolute when L_ref = 0); 'position': |x - x_ref| / scale_length; 'linear_momentum':
    |p - p_ref| / scale_momentum.  Each is dimensionless, so the sum measures the whole state.
    """
    reference_norm = np.linalg.norm(reference.angular_momentum)
    errors = {
        'angle': rotation_angle_between(state.rotation, reference.rotation),
        'angular_momentum': np.linalg.norm(state.angular_momentum - reference.angular_momentum)
        / (reference_norm if reference_norm > 0.0 else 1.0),
        'position': np.linalg.norm(state.position - reference.position) / scale_length,
        'linear_momentum': np.linalg.norm(state.linear_momentum - reference.linear_momentum)
        / scale_momentum,
    }
    errors['total'] = sum(errors.values())
    return errors


def torque_free_omega_period(moments, angular_velocity_body):
    """
    Return the period (s) of the body angular velocity of a torque-free asymmetric top.

    Landau & Lifshitz, Mechanics, section 37: with I1 < I2 < I3, energy E and |L| = L,
    for L^2 > 2 E I2 the body rates are Omega1 ~ cn, Omega2 ~ sn, Omega3 ~ dn of
    tau = t sqrt((I3 - I2)(L^2 - 2 E I1) / (I1 I2 I3)) with modulus
    k^2 = (I2 - I1)(2 E I3 - L^2) / ((I3 - I2)(L^2 - 2 E I1)); the period is 4 K(k^2) in
    tau.  For L^2 < 2 E I2 the indices 1 and 3 swap.  Omega2 ~ sn changes sign twice per
    period.
    """
    i1, i2, i3 = (float(v) for v in moments)
    if not i1 < i2 < i3:
        raise ValueError('need I1 < I2 < I3')
    omega = np.asarray(angular_velocity_body, dtype=float)
    inertia = np.array([i1, i2, i3])
    energy = 0.5 * np.sum(inertia * omega ** 2)
    momentum_squared = np.sum((inertia * omega) ** 2)
    if momentum_squared < 2.0 * energy * i2:
        i1, i3 = i3, i1
    rate = math.sqrt((i3 - i2) * (momentum_squared - 2.0 * energy * i1) / (i1 * i2 * i3))
    modulus = ((i2 - i1) * (2.0 * energy * i3 - momentum_squared)
               / ((i3 - i2) * (momentum_squared - 2.0 * energy * i1)))
    return 4.0 * ellipk(modulus) / rate


def body_rates_symmetric_top(moments, axis, angular_velocity_body, time):
    """
    Return the exact body angular velocity (rad/s) of a torque-free symmetric top.

    `axis` (0, 1 or 2) is the symmetry axis a; the other two moments are equal (I_perp).
    Euler's equations give dOmega_b/dt = n Omega_c, dOmega_c/dt = -n Omega_b for the cyclic
    (a, b, c), with n = (I_perp - I_a) / I_perp Omega_a constant: (Omega_b, Omega_c) turns
    by the angle -n t.
    """
    a = axis
    b, c = (a + 1) % 3, (a + 2) % 3
    perpendicular = moments[b]
    omega = np.array(angular_velocity_body, dtype=float)
    rate = (perpendicular - moments[a]) / perpendicular * omega[a]
    angle = -rate * time
    result = omega.copy()
    result[b] = math.cos(angle) * omega[b] - math.sin(angle) * omega[c]
    result[c] = math.sin(angle) * omega[b] + math.cos(angle) * omega[c]
    return result


def first_order_energy_gain_rate(body, state, dt):
    """
    Return the rate (J/s) at which the seed's first-order method gains kinetic energy.

    Torque-free, one step of R <- exp(h [omega]x) R misses the exact increment
    exp(h omega + h^2/2 alpha + O(h^3)) by the world rotation -h^2/2 alpha, alpha =
    I_w^{-1} (-omega x L).  Turning R by a small world rotation d changes
    T = 1/2 L . I_w^{-1} L by d . (omega x L) (L held), so each step gains

        dT = h^2/2 (omega x L)^T I_w^{-1} (omega x L) >= 0,

    i.e. dT/dt = h/2 (omega x L)^T I_w^{-1} (omega x L) to leading order: never negative,
    proportional to dt, zero only for a steady spin about a principal axis.  `state` is
    world frame, `dt` in s.
    """
    rotation = state.rotation
    omega = state.angular_velocity(body)
    gyroscopic = np.cross(omega, state.angular_momentum)
    inverse_world = rotation @ body.inertia_inverse @ rotation.T
    return 0.5 * dt * float(gyroscopic @ inverse_world @ gyroscopic)


# rk4 integrates the body momentum m = R^T L (integrators/rk4.py): its world L = R m carries
# the method's global error, K (|Omega| dt)^4 |Omega| t relative, and the rounding of each
# step's increment, <= 1 ulp of |L| (an increment below half an ulp leaves L bit-identical).
# Measured over the torque-free runs of test_hard_cases and test_conservation: K at most
# 3.5e-5; with test_core_speed_paths' dissipation, which sweeps the body across its polhodes,
# 3.8e-4.  Allowed 2e-3, for every method that writes L torque-free.
MOMENTUM_WRITING_K = 2e-3


def torque_free_momentum_drift(name, body, state, dt, steps):
    """
    Return how far (kg m^2/s) torque-free world L may move in `steps` steps of dt s.

    0 for the methods registered as conserving world L (they never write L without a wrench:
    it stays bit-identical); for the others their order bound plus round-off (see
    MOMENTUM_WRITING_K).
    """
    integrator = INTEGRATORS[name]
    if 'angular_momentum' in integrator.conserves:
        return 0.0
    omega = np.linalg.norm(state.angular_velocity_body(body))
    magnitude = np.linalg.norm(state.angular_momentum)
    return magnitude * (MOMENTUM_WRITING_K * (omega * dt) ** integrator.order * omega * steps
                        * dt + steps * np.finfo(float).eps)

"""
Reference orientations of the torque-free benchmark bodies.

The reference is the extended-precision Taylor solve of :mod:`.extended_reference` (decimal
arithmetic, 34 and 42 digits, independent of every integrator it scores), taken at exactly
N x dt s for each run of N steps of dt.  Its uncertainty is the gap between its two solves,
and never below :data:`MEASUREMENT_FLOOR`, what an angle between two double rotation matrices
resolves.  Two double-precision solutions are compared with it and reported:

- :func:`ode_reference`: Euler's equations for the body angular momentum M = I_b Omega and
  the quaternion q (x, y, z, w), body to world, integrated by scipy's DOP853 at rtol 1e-13,
  atol 1e-16:

      dM/dt = M x Omega,   dq/dt = 1/2 q * (Omega, 0),   Omega = I_b^{-1} M.

  It shares no code with the integrators.  The solve is restarted at every requested time
  so each value is a step end point, never a dense-output interpolant (DOP853's interpolant
  is only 7th order and would add its own error).
- :func:`exact_reference`: the project's exact torque-free flow, the ``exact`` integrator,
  taken in one step from t = 0 to each requested time (it is exact for any step).

Both are cross-checks only: the exact flow scored against itself would hide its own errors,
and DOP853 at rtol 1e-13 resolves only ~1e-12 rad on the fast bodies.
"""

from dataclasses import dataclass
import decimal
from decimal import Decimal

import numpy as np
from scipy.integrate import solve_ivp

from .extended_reference import DIGITS
from .extended_reference import exact_time
from .extended_reference import reference_quaternions
from .extended_reference import rotation_matrix_decimal
from ..physics import INTEGRATORS
from ..physics import matrix_from_quaternion
from ..physics import Simulator

__all__ = ['Reference', 'ode_reference', 'exact_reference', 'reference_rotations',
           'rotation_angle', 'MEASUREMENT_FLOOR']

ODE_RTOL = 1e-13
ODE_ATOL = 1e-16
# The least error (rad) ever claimed resolvable: the angle between two double rotation
# matrices, each entry rounded (<= 0.5 ulp) and multiplied in double, is good to a few eps.
MEASUREMENT_FLOOR = 1e-15


def rotation_angle(rotation_a, rotation_b):
    """
    Return the angle (rad, in [0, pi]) of the rotation between two rotation matrices.

    The angle theta of Q = R_a^T R_b from sin(theta) = |vee(Q - Q^T)| / 2 and
    cos(theta) = (tr Q - 1) / 2 with atan2: unlike acos of the trace alone, this keeps full
    precision both for tiny angles (down to ~1e-16 rad) and near pi.
    """
    relative = np.asarray(rotation_a, dtype=float).T @ np.asarray(rotation_b, dtype=float)
    sine = 0.5 * np.sqrt((relative[2, 1] - relative[1, 2]) ** 2
                         + (relative[0, 2] - relative[2, 0]) ** 2
                         + (relative[1, 0] - relative[0, 1]) ** 2)
    cosine = 0.5 * (relative[0, 0] + relative[1, 1] + relative[2, 2] - 1.0)
    return float(np.arctan2(sine, cosine))


def _euler_rate(inertia_inverse):
    (a11, a12, a13), (a21, a22, a23), (a31, a32, a33) = inertia_inverse.tolist()

    def rate(time, y):
        # Plain float arithmetic: this runs ~10^5 times per solve, where numpy's per-call
        # overhead on 3-vectors would dominate.
        qx, qy, qz, qw, mx, my, mz = y.tolist()
        wx = a11 * mx + a12 * my + a13 * mz
        wy = a21 * mx + a22 * my + a23 * mz
        wz = a31 * mx + a32 * my + a33 * mz
        # q * (Omega, 0), Hamilton product with quaternions stored (x, y, z, w): the body
        # angular velocity acts on the right.  dM/dt = M x Omega.
        return np.array([
            0.5 * (qw * wx + qy * wz - qz * wy),
            0.5 * (qw * wy + qz * wx - qx * wz),
            0.5 * (qw * wz + qx * wy - qy * wx),
            -0.5 * (qx * wx + qy * wy + qz * wz),
            my * wz - mz * wy,
            mz * wx - mx * wz,
            mx * wy - my * wx,
        ])
    return rate


def ode_reference(body, state, times, rtol=ODE_RTOL):
    """
    Return {time: R(time)} by the DOP853 solve of Euler's equations (see module doc).

    Parameters
    ----------
    body : RigidBody
        Mass properties (the inertia tensor in the body frame, kg m^2).
    state : State
        Torque-free initial state (world frame) at t = 0.
    times : iterable of float
        Times in s, > 0.
    rtol : float
        Relative tolerance of DOP853 (absolute tolerance: 1e-16).

    """
    rate = _euler_rate(np.array(body.inertia_inverse))
    y = np.concatenate([state.quaternion, state.rotation.T @ state.angular_momentum])
    rotations = {}
    now = 0.0
    for time in sorted({float(t) for t in times}):
        if time > now:
            solution = solve_ivp(rate, (now, time), y, method='DOP853', rtol=rtol,
                                 atol=ODE_ATOL)
            if not solution.success:
                raise RuntimeError(f'reference ODE solve failed: {solution.message}')
            y = solution.y[:, -1]
            now = time
        rotations[time] = matrix_from_quaternion(y[:4])
    return rotations


def exact_reference(body, state, times):
    """Return {time: R(time)} from the ``exact`` integrator in one step from t = 0 (s)."""
    return {float(t): np.array(Simulator(body, state, integrator='exact').step(float(t))
                               .rotation) for t in times}


def _double_rotation(quaternion):
    """Return R (double, each entry correctly rounded) of a quaternion of decimal strings."""
    with decimal.localcontext() as context:
        context.prec = DIGITS + 8
        rows = rotation_matrix_decimal([Decimal(c) for c in quaternion])
        return np.array([[float(value) for value in row] for row in rows])


@dataclass
class Reference:
    """
    Reference orientations of one case, at N steps of dt (keys (N, dt)).

    Attributes
    ----------
    rotations : dict
        (N, dt) -> R (3x3, body to world) at exactly N x dt s.
    uncertainty : dict
        (N, dt) -> estimated error (rad) of the reference: the gap between its two solves,
        at least :data:`MEASUREMENT_FLOOR`.  Errors below it are not resolved.
    drift : float
        Largest relative drift of the conserved |M| and 2T in the extended solves.
    origin : str
        Where the values came from: 'committed', 'cached' and/or 'computed now'.
    exact_gap : dict or None
        (N, dt) -> angle (rad) between the exact flow (one step from 0) and the reference;
        None when no exact flow is registered.
    ode_gap : dict
        (N, dt) -> angle (rad) between the DOP853 solve and the reference.

    """

    rotations: dict
    uncertainty: dict
    drift: float
    origin: str
    exact_gap: dict
    ode_gap: dict

    def angle_error(self, steps, dt, rotation):
        """Return the angle (rad) between `rotation` and the reference after N steps of dt."""
        return rotation_angle(rotation, self.rotations[(int(steps), float(dt))])


def reference_rotations(body, state, keys, use_cache=True):
    """
    Return the Reference of a torque-free case after N steps of dt, for each (N, dt) in keys.

    The extended-precision solve is the reference (module docstring); the exact flow (when
    registered) and the DOP853 solve are compared with it at every key.
    """
    keys = sorted({(int(n), float(dt)) for n, dt in keys})
    values, drift, origin = reference_quaternions(body, state, keys, use_cache=use_cache)
    rotations = {key: _double_rotation(values[key][0]) for key in keys}
    uncertainty = {key: max(values[key][1], MEASUREMENT_FLOOR) for key in keys}
    # The double-precision solutions take the double nearest the exact time N x dt.
    times = {key: float(exact_time(*key)) for key in keys}
    ode = ode_reference(body, state, times.values())
    ode_gap = {key: rotation_angle(ode[times[key]], rotations[key]) for key in keys}
    exact_gap = None
    if 'exact' in INTEGRATORS:
        exact = exact_reference(body, state, times.values())
        exact_gap = {key: rotation_angle(exact[times[key]], rotations[key]) for key in keys}
    return Reference(rotations, uncertainty, drift, origin, exact_gap, ode_gap)

"""
Reference orientations of the torque-free benchmark bodies.

Two independent references:

- :func:`ode_reference`: Euler's equations for the body angular momentum M = I_b Omega and
  the quaternion q (x, y, z, w), body to world, integrated by scipy's DOP853 at rtol 1e-13,
  atol 1e-16:

      dM/dt = M x Omega,   dq/dt = 1/2 q * (Omega, 0),   Omega = I_b^{-1} M.

  It shares no code with the integrators.  The solve is restarted at every requested time
  so each value is a step end point, never a dense-output interpolant (DOP853's interpolant
  is only 7th order and would add its own error).
- :func:`exact_reference`: the project's exact torque-free flow, ``INTEGRATORS['exact']``,
  taken in one step from t = 0 to each requested time (it is exact for any step).

:func:`reference_rotations` uses the exact flow when it is registered and cross-checks it
against the ODE solve; otherwise the ODE solve alone.
"""

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from ..physics import INTEGRATORS
from ..physics import matrix_from_quaternion
from ..physics import State

__all__ = ['Reference', 'ode_reference', 'exact_reference', 'exact_resolution',
           'reference_rotations', 'rotation_angle']

ODE_RTOL = 1e-13
ODE_ATOL = 1e-16
# The exact flow is trusted when it is this close (rad) to the ODE solve, or closer than 3x
# the ODE's own estimated error; a larger gap is a defect in one of them and the case falls
# back to the ODE reference (reported).
CROSS_CHECK_FLOOR = 1e-11
# The least error (rad) ever claimed resolvable: a few ulp of an angle.
EXACT_FLOOR = 1e-15


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
    """Return {time: R(time)} from ``INTEGRATORS['exact']`` in one step from t = 0."""
    exact = INTEGRATORS['exact']
    return {float(t): np.array(exact(body, state, 0.0, float(t), None).rotation)
            for t in times}


def exact_resolution(body, state, time):
    """
    Return how far (rad) the exact flow's R(time) can be trusted: its round-off level.

    The largest of: the gap between one step to `time` and 2 or 10 equal steps (the flow's
    group property, which an exact flow keeps up to round-off), and the change of R(time)
    when L(0) is perturbed by one ulp of |L| in three fixed directions (the problem's own
    conditioning: no double-precision method can resolve less).  Never below 1e-15 rad.
    """
    exact = INTEGRATORS['exact']
    one_step = exact(body, state, 0.0, time, None).rotation
    gaps = [EXACT_FLOOR]
    for pieces in (2, 10):
        piecewise = state
        for k in range(pieces):
            piecewise = exact(body, piecewise, k * time / pieces, time / pieces, None)
        gaps.append(rotation_angle(one_step, piecewise.rotation))
    magnitude = np.linalg.norm(state.angular_momentum)
    ulp = np.spacing(magnitude)
    for direction in np.eye(3):
        perturbed = State._from_arrays(
            np.array(state.quaternion), np.array(state.position),
            np.array(state.linear_momentum), state.angular_momentum + ulp * direction)
        gaps.append(rotation_angle(one_step, exact(body, perturbed, 0.0, time, None).rotation))
    return max(gaps)


@dataclass
class Reference:
    """
    Reference orientations of one case.

    Attributes
    ----------
    rotations : dict
        time (s) -> R (3x3, body to world).
    source : str
        'exact' (the exact flow) or 'ode' (the DOP853 solve).
    uncertainty : dict
        time (s) -> estimated error of the reference (rad); errors below it are not
        resolved.  For the ODE: the gap between the solves at rtol 1e-12 and 1e-13 (the
        error of the looser one, an upper estimate of the tighter one's).  For the exact
        flow, which agreed with the ODE within that: :func:`exact_resolution`.
    cross_check : float or None
        Max angle (rad) between the exact flow and the DOP853 solve over all the times,
        when the exact flow is registered.
    gaps : dict or None
        time (s) -> angle (rad) between the exact flow and the DOP853 solve.
    ode_uncertainty : float
        Max over the times of the ODE's estimated error (rad).
    note : str
        Why the source was chosen, for the report.

    """

    rotations: dict
    source: str
    uncertainty: dict
    cross_check: float = None
    ode_uncertainty: float = None
    note: str = ''
    gaps: dict = None

    def angle_error(self, time, rotation):
        """Return the rotation angle (rad) between `rotation` and the reference at `time`."""
        return rotation_angle(rotation, self.rotations[float(time)])


def reference_rotations(body, state, times):
    """
    Return the Reference of a torque-free case at `times` (see the module docstring).

    With ``INTEGRATORS['exact']`` registered, the exact flow is the reference when it agrees
    with the DOP853 solve at every time within max(3 x the ODE's estimated error, 1e-11 rad);
    otherwise (or without an exact flow) the DOP853 solve is, and the note says why.
    """
    times = sorted({float(t) for t in times})
    ode = ode_reference(body, state, times)
    looser = ode_reference(body, state, times, rtol=10.0 * ODE_RTOL)
    ode_uncertainty = {t: max(rotation_angle(ode[t], looser[t]), EXACT_FLOOR)
                       for t in times}
    worst = max(ode_uncertainty.values())
    if 'exact' not in INTEGRATORS:
        return Reference(ode, 'ode', ode_uncertainty, None, worst,
                         'DOP853 solve (no "exact" integrator registered yet)')
    exact = exact_reference(body, state, times)
    gaps = {t: rotation_angle(exact[t], ode[t]) for t in times}
    gap = max(gaps.values())
    agree = all(gaps[t] <= max(3.0 * ode_uncertainty[t], CROSS_CHECK_FLOOR) for t in times)
    if not agree:
        return Reference(ode, 'ode', ode_uncertainty, gap, worst,
                         f'the exact flow DISAGREES with the DOP853 solve by up to {gap:.1e} '
                         f'rad (its estimated error: {worst:.1e} rad): DOP853 used', gaps)
    resolution = {t: exact_resolution(body, state, t) for t in times}
    return Reference(exact, 'exact', resolution, gap, worst,
                     f'exact flow; DOP853 agrees within {gap:.1e} rad (its estimated '
                     f'error: {worst:.1e} rad)', gaps)

"""
The exact torque-free flow of a rigid body, and the `exact` integrator built on it.

Torque-free, world L is constant; in the principal frame the body angular momentum m moves on
the intersection of the sphere |m| = |L| with the energy ellipsoid sum m_i^2 / I_i = 2T
(Euler's equations), and the orientation follows from m and one angle about L.

Construction (after van Zon & Schofield, J. Comput. Phys. 225:145, 2007, and Celledoni,
Fasso, Safstrom & Zanna, SIAM J. Sci. Comput. 30:2084, 2008), with L = |L|, E2 = 2T:

1. Pick a proper frame of principal axes with moments (J1, J2, J3) in which m circulates
   around axis 3 with m1 >= 0 and m3 >= 0: J = (I1, I2, I3) when L^2 >= E2 I2 (rotation
   about the axis of largest inertia), else J = (I3, I2, I1) with the axes (e3, -e2, e1);
   then turns by pi about e1 or e3 fix the signs.  In it (A&S 16; Landau-Lifshitz s. 37)

       m(t) = (A cn u, B sn u, C dn u),  u = u0 + nu t,  parameter k^2,

   with A^2, B^2, C^2, k^2, k'^2 = 1 - k^2 and nu = sign(J3 - J2) sqrt((J3 - J2)(L^2 - J1 E2)
   / (J1 J2 J3)) each formed from sums of terms of one sign (so from m itself, not from
   differences of L^2 and E2 J_i) except for the separatrix distance L^2 - J2 E2.
2. Let B(m) be the smallest rotation taking m/L to e_z (no singularity, as m3 >= 0).  Then
   Q R F = Rz(psi) B(m) for a fixed Q taking L to L e_z, so that

       R(t) F = exp(dpsi [L/L]x) R(0) F B(m(0))^T B(m(t)),

   and psi' = omega . L/L - beta_z = E2/L - (m1 m2' - m2 m1') / (L (L + m3)), where beta is
   B's angular velocity.  With m1 m2' - m2 m1' = A B nu dn and a = A^2 = L^2 - C^2,
   b = C^2 k^2, n = -b/a, alpha^2 = 1 + b/a, the integral of dn / (L + C dn) du is

       I(u) = -(C/a) u + L/(a alpha) Theta(u) + L^2 C k^2/(3 a^2) P(u),
       Theta(u) = atan2(alpha sn u, cn u) (continued),  (1/alpha) Theta' = dn/(1 + b/a sn^2),
       Pi(n; am u | k^2) = u + (n/3) P(u),  P = s^3 R_J(c^2, d^2, 1, 1 - n s^2) + periods,

   using F(am u) = s R_F(c^2, d^2, 1) = u (s, c, d = sn, cn, dn) in Carlson's form of the
   elliptic integral of the third kind.  So

       dpsi = E2 dt / L - (A B / L) (I(u1) - I(u0)),

   free of 1/C (small for nearly symmetric tops spun about a transverse axis) and of
   divergences at a = 0 (steady spin about axis 3), where the terms cancel analytically.
3. Arguments are reduced to |u| <= K with the quasi-periodicity of sn, cn, dn, Theta and Pi;
   the Jacobi functions come from k^2 and k'^2 separately (descending Landen), so nothing is
   lost near the separatrix (k'^2 -> 0); on it (k'^2 = 0) sn, cn, dn are tanh, sech, sech.
   The terms of I grow like K ~ ln(4/k') near the unstable axis and cancel to O(1), so a
   step carries a round-off of ~eps K: about 1e-15 at k'^2 = 1e-8, 1e-14 for a state within
   1e-16 of the unstable axis (K ~ 38).

Symmetric and spherical tops (two or three principal moments exactly equal) use the closed
form R(t) = exp(t [L]x / I_t) R(0) exp(t nu_a [a]x), nu_a = m_a (1/I_a - 1/I_t): a steady
precession about L and a steady spin about the symmetry axis a.  Steady spins about a
principal axis are rotations about L at the rate E2 / L.

Everything is world frame except m (principal frame); SI units.
"""

import math

import numpy as np

from .common import free_translation
from .common import kick_drift_kick
from .fast_exact import exact_kernel
from .principal import ASYMMETRIC
from .principal import OBLATE
from .principal import principal_frame
from .principal import PROLATE
from .registry import register_integrator
from ..elliptic import carlson_rf
from ..elliptic import carlson_rj
from ..elliptic import jacobi_elliptic
from ..rotations import matrix_from_quaternion
from ..rotations import quaternion_from_matrix
from ..rotations import quaternion_from_rotation_vector
from ..rotations import quaternion_multiply
from ..state import State

__all__ = ['exact_free_flow', 'exact_free_rotation', 'exact']

# Proper frame changes of the principal coordinates (columns: new axes in old coordinates).
# Circulation about axis 1: new axes (e3, -e2, e1), moments (I3, I2, I1).
_ABOUT_AXIS_1 = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
# Half turns about e1 (negates m2, m3) and about e3 (negates m1, m2).
_HALF_TURN_1 = np.diag([1.0, -1.0, -1.0])
_HALF_TURN_3 = np.diag([-1.0, -1.0, 1.0])


def _conjugate(q):
    return np.array([-q[0], -q[1], -q[2], q[3]])


def _to_pole(direction):
    """
    Return the quaternion of the smallest rotation taking the unit vector to +e_z.

    q = (n x e_z, 1 + n . e_z), normalised; regular wherever n_z > -1 (here n_z >= 0).
    """
    q = np.array([direction[1], -direction[0], 0.0, 1.0 + direction[2]])
    return q / math.sqrt(q @ q)


def _turn_about_momentum(quaternion, angular_momentum, angle):
    """Return exp(angle [L/|L|]x) R as a quaternion: a turn about world L."""
    axis = angular_momentum / math.sqrt(angular_momentum @ angular_momentum)
    q = quaternion_multiply(quaternion_from_rotation_vector(angle * axis), quaternion)
    return q / math.sqrt(q @ q)


def _symmetric_top_rotation(frame, quaternion, angular_momentum, duration):
    """Return the closed-form orientation for I1 == I2 or I2 == I3 (spherical: nu_a = 0)."""
    moments, axes = frame.moments, frame.axes
    if frame.kind == PROLATE:
        axis, axial, transverse = axes[:, 2], moments[2], moments[0]
    elif frame.kind == OBLATE:
        axis, axial, transverse = axes[:, 0], moments[0], moments[1]
    else:
        axis, axial, transverse = axes[:, 2], moments[2], moments[2]
    momentum_body = matrix_from_quaternion(quaternion).T @ angular_momentum
    spin_rate = (axis @ momentum_body) * (1.0 / axial - 1.0 / transverse)
    # Right factor: spin about the body-fixed symmetry axis; left: precession about L.
    spun = quaternion_multiply(quaternion, quaternion_from_rotation_vector(
        duration * spin_rate * axis))
    return _turn_about_momentum(spun, angular_momentum,
                                duration * math.sqrt(angular_momentum @ angular_momentum)
                                / transverse)


def _circulation_frame(frame, momentum_principal):
    """
    Return (frame change T, moments J, m in the new frame) for the asymmetric solution.

    In the new principal frame m circulates about axis 3, m1 >= 0 and m3 >= 0.
    """
    i1, i2, i3 = frame.moments
    m1, _, m3 = momentum_principal
    # L^2 - I2 E2 (the separatrix distance): >= 0 when m circulates about the axis of
    # largest inertia.
    separatrix = m1 * m1 * (i1 - i2) / i1 + m3 * m3 * (i3 - i2) / i3
    if separatrix >= 0.0:
        change, moments = np.eye(3), np.array([i1, i2, i3])
    else:
        change, moments = _ABOUT_AXIS_1, np.array([i3, i2, i1])
    momentum = change.T @ momentum_principal
    if momentum[2] < 0.0:
        change = change @ _HALF_TURN_1
        momentum = _HALF_TURN_1 @ momentum
    if momentum[0] < 0.0:
        change = change @ _HALF_TURN_3
        momentum = _HALF_TURN_3 @ momentum
    return change, moments, momentum, separatrix


def _precession_integral(u, sn, cn, dn, turns, c_over_a, l_over_a_alpha, third_coefficient,
                         alpha, characteristic, complete_rj):
    """
    Return I(u) = int_0^u dn / (L + C dn) du' for u = 2 K turns + r, |r| <= K.

    sn, cn, dn are those of the reduced argument r (so cn >= 0); complete_rj is
    R_J(0, k'^2, 1, 1 - n), needed only when turns != 0.
    """
    theta = turns * math.pi + math.atan2(alpha * sn, max(cn, 0.0))
    periodic = 0.0
    if characteristic != 0.0:
        periodic = sn ** 3 * carlson_rj(cn * cn, dn * dn, 1.0, 1.0 - characteristic * sn * sn)
        if turns:
            periodic += 2.0 * turns * complete_rj
    return -c_over_a * u + l_over_a_alpha * theta + third_coefficient * periodic


def _asymmetric_top_rotation(frame, quaternion, angular_momentum, duration):
    rotation = matrix_from_quaternion(quaternion)
    momentum_principal = frame.axes.T @ (rotation.T @ angular_momentum)
    change, moments, momentum, separatrix = _circulation_frame(frame, momentum_principal)
    # Python floats: scalar arithmetic on numpy scalars is several times slower.
    j1, j2, j3 = (float(v) for v in moments)
    m1, m2, m3 = (float(v) for v in momentum)
    separatrix = float(separatrix)
    momentum_norm = math.sqrt(angular_momentum @ angular_momentum)
    twice_energy = m1 * m1 / j1 + m2 * m2 / j2 + m3 * m3 / j3
    # Squared amplitudes of (cn, sn, dn): sums of terms of one sign.
    a = m1 * m1 + m2 * m2 * j1 * (j3 - j2) / (j2 * (j3 - j1))
    if a == 0.0 or (m1 == 0.0 and m3 == 0.0):
        # m along a principal axis: a steady spin, omega = (E2 / L^2) L.
        return _turn_about_momentum(quaternion, angular_momentum,
                                    duration * twice_energy / momentum_norm)
    b_squared = m2 * m2 + m1 * m1 * j2 * (j3 - j1) / (j1 * (j3 - j2))
    c_squared = m3 * m3 + m2 * m2 * j3 * (j2 - j1) / (j2 * (j3 - j1))
    amplitude_a, amplitude_b, amplitude_c = math.sqrt(a), math.sqrt(b_squared), \
        math.sqrt(c_squared)
    # L^2 - J1 E2 and J3 E2 - L^2, and from them k^2 and k'^2.
    g = m2 * m2 * (j2 - j1) / j2 + m3 * m3 * (j3 - j1) / j3
    h = m1 * m1 * (j3 - j1) / j1 + m2 * m2 * (j3 - j2) / j2
    parameter = (j2 - j1) * h / ((j3 - j2) * g)
    complement = (j3 - j1) * separatrix / ((j3 - j2) * g)
    rate = math.copysign(math.sqrt((j3 - j2) * g / (j1 * j2 * j3)), j3 - j2)
    # Phase u0 from (cn, sn) = (m1 / A, m2 / B), renormalised against round-off.
    c0, s0 = m1 / amplitude_a, m2 / amplitude_b
    norm = math.hypot(c0, s0)
    c0, s0 = c0 / norm, s0 / norm
    d0 = math.sqrt(c0 * c0 + complement * s0 * s0)
    u0 = s0 * carlson_rf(c0 * c0, d0 * d0, 1.0)
    u1 = u0 + rate * duration
    # Reduce u1 = 2 K turns + r, |r| <= K (K infinite on the separatrix).
    turns, reduced = 0, u1
    if complement > 0.0:
        half_period = 2.0 * carlson_rf(0.0, complement, 1.0)
        turns = round(u1 / half_period)
        reduced = u1 - half_period * turns
    s1, c1, d1 = jacobi_elliptic(reduced, parameter, complement)
    sign = -1.0 if turns % 2 else 1.0
    momentum_new = np.array([amplitude_a * c1 * sign, amplitude_b * s1 * sign,
                             amplitude_c * d1])
    # The precession angle.
    b_term = c_squared * parameter
    characteristic = -b_term / a
    alpha = math.sqrt(1.0 + b_term / a)
    complete_rj = 0.0
    if turns and characteristic != 0.0:
        complete_rj = carlson_rj(0.0, complement, 1.0, 1.0 - characteristic)
    coefficients = (amplitude_c / a, momentum_norm / (a * alpha),
                    momentum_norm ** 2 * amplitude_c * parameter / (3.0 * a * a), alpha,
                    characteristic, complete_rj)
    # Both ends are evaluated at the arguments actually used (u1 as rounded), so that the
    # O(K) terms of I cancel consistently: the rounding of u1 then enters only through
    # I'(u1) = dn / (L + C dn), small where K is large (near the unstable axis).
    integral = (_precession_integral(u1, s1, c1, d1, turns, *coefficients)
                - _precession_integral(u0, s0, c0, d0, 0, *coefficients))
    precession = (duration * twice_energy / momentum_norm
                  - amplitude_a * amplitude_b / momentum_norm * integral)
    # R(t) F = exp(dpsi [L]) R(0) F B(m0)^T B(m1), F = axes @ change.
    frame_quaternion = quaternion_from_matrix(frame.axes @ change)
    body_turn = quaternion_multiply(_conjugate(_to_pole(momentum / momentum_norm)),
                                    _to_pole(momentum_new / np.linalg.norm(momentum_new)))
    body_turn = quaternion_multiply(quaternion_multiply(frame_quaternion, body_turn),
                                    _conjugate(frame_quaternion))
    return _turn_about_momentum(quaternion_multiply(quaternion, body_turn), angular_momentum,
                                precession)


def exact_free_rotation(body, quaternion, angular_momentum, duration):
    """
    Return the orientation after `duration` s of torque-free rotation, exactly.

    Parameters
    ----------
    body : RigidBody
        Mass properties (any inertia tensor; solved in its principal frame).
    quaternion : array_like, shape (4,)
        Initial orientation (x, y, z, w), body to world.
    angular_momentum : array_like, shape (3,)
        World angular momentum about the COM (kg m^2/s), constant in the motion.
    duration : float
        Time span in s (any sign, any size).

    Returns
    -------
    numpy.ndarray, shape (4,)
        The unit quaternion (x, y, z, w) at the end: exact up to round-off, for every body
        (asymmetric, symmetric, spherical) and every state (near the separatrix and on it,
        steady spins).  See the module docstring for the construction.

    """
    quaternion = np.asarray(quaternion, dtype=float)
    angular_momentum = np.asarray(angular_momentum, dtype=float)
    quaternion = quaternion / math.sqrt(quaternion @ quaternion)
    if not np.any(angular_momentum) or duration == 0.0:
        return quaternion
    frame = principal_frame(body.inertia)
    if frame.kind == ASYMMETRIC:
        return _asymmetric_top_rotation(frame, quaternion, angular_momentum, duration)
    return _symmetric_top_rotation(frame, quaternion, angular_momentum, duration)


def exact_free_flow(body, state, duration):
    """
    Return the State after `duration` s of force- and torque-free motion, exactly.

    World L and p are constant, the COM moves uniformly and the orientation is
    :func:`exact_free_rotation`.  Usable as a reference solution at any time.
    """
    quaternion = exact_free_rotation(body, state.quaternion, state.angular_momentum, duration)
    return State._from_arrays(quaternion, free_translation(state, duration, body.mass),
                              state.linear_momentum, state.angular_momentum)


@register_integrator('exact', order=2, fast_kernel=exact_kernel)
def exact(body, state, time, dt, wrench):
    """
    Exact torque-free flow; a wrench enters as half kicks around it (Strang splitting).

    Torque-free the step is exact at any dt (error: round-off only).  With a wrench it is
    second order in dt, with error constants set by the wrench alone: the registered order.
    """
    return kick_drift_kick(body, state, time, dt, wrench, exact_free_flow)

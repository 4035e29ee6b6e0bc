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
2. Let B(n) be the smallest rotation taking the unit vector n to e_z.  Then, with
   n = m / L and F the frame of step 1 (body coordinates = F circulation coordinates),

       R(t) = R(0) F D F^T,  D = B(n(0))^T Rz(psi) B(n(t)),

   psi' = E2/L - (m1 m2' - m2 m1') / (L (L + m3)).  The step is computed as this body-frame
   increment D - 1, never from u0 itself: over a step h = nu t the addition theorems give
   n(t) - n(0) and psi from sn, cn, dn of h and of the start alone, each as a sum of terms
   that vanish with h, so that a short step carries round-off relative to its own size (the
   values at u0 and u0 + h, of size up to K ~ ln(4/k') near the unstable axis, are never
   formed and subtracted):

       sn(u0 + h), cn(..), dn(..)  (A&S 16.17.1-3), written as increments;
       psi = E2 t / L - (A B / L) (-(C/a) h + L/(a alpha) dTheta + L^2 C k^2/(3 a^2) dP),

   a = A^2, b = C^2 k^2, n = -b/a, alpha^2 = 1 + b/a, Theta(u) = atan2(alpha sn u, cn u)
   (continued; its increment is one atan2 of the two ends), and dP = P(u0 + h) - P(u0) for
   Pi(n; am u | k^2) = u + (n/3) P(u): by the addition theorem of the third kind (written
   here for n <= 0; checked against 40-digit quadrature),

       dP = P(h) + 3 atan(rho S / Q) / rho,  S = sn u0 sn h sn(u0 + h),
       Q = 1 + (b/a)(1 - cn u0 cn h cn(u0 + h)) >= 1,  rho^2 = alpha^2 (k^2 + b/a) b/a,

   P(h) = s^3 R_J(c^2, d^2, 1, 1 - n s^2) (Carlson) at the reduced h, plus 2 R_J(0, k'^2,
   1, 1 - n) per half period 2K, and dTheta gains pi per half period.  The addition
   theorems divide by cn^2 u0 + sn^2 u0 dn^2 h, small only when k'^2 is small and u0 and h
   are both near a quarter period (a long step); there the round-off of cn h and dn h
   (absolute, relative to values ~k') would be amplified, and the values at both ends are
   subtracted instead, at a round-off ~eps K that a long step can afford.
   D itself: D = R_n0(psi + chi) S(n(t) -> n(0)), chi the signed area of the spherical
   triangle (e_z, n(0), n(t)) and S(v -> u) the smallest rotation taking v to u, both formed
   from n(t) - n(0): the turn is about the momentum itself, so a body spinning about a
   principal axis keeps its small components accurate relative to their size.  When n(t)
   is more than a quarter turn from n(0) (long steps; S is singular at n(t) = -n(0)) the
   e_z form is used: with the unit bisectors a_i = (e_z + n_i)/|e_z + n_i| as pure
   quaternions D = -a0 Rz(psi) a1, regular as n_z >= 0.
3. h is reduced by multiples of the half period 2K only when |h| > pi/2 (K >= pi/2); the
   Jacobi functions come from k^2 and k'^2 separately (descending Landen), so nothing is
   lost near the separatrix (k'^2 -> 0); on it (k'^2 = 0) sn, cn, dn are tanh, sech, sech.

Symmetric and spherical tops (two or three principal moments exactly equal) use the closed
form R(t) = R(0) exp(t L [m/L]x / I_t) exp(t nu_a [a]x), nu_a = m_a (1/I_a - 1/I_t): a steady
precession about L and a steady spin about the symmetry axis a.  Steady spins about a
principal axis are rotations about L at the rate E2 / L.

The last rounding.  The step returns q(t) = q(0) + q(0) (D - 1), the increment q(0) (D - 1)
small for a short step.  Before the one rounding to double, that sum, held exactly, is
normalised to first order in |q|^2 - 1 and turned about the body axis m x omega by the
angle that gives it the kinetic energy of q(0) exactly (the flow conserves it).  The
readable definition here holds it in integers over a power of two (every double is such a
dyadic rational: exact, and without the gcd of fractions.Fraction at every operation, which
made the step cost ~1 ms); the compiled path in double-double arithmetic (~1e-32), which
rounds to the same double but in the rarest ties (tested: the same bits).  That turn
removes round-off, ~0.01-4 ulp; it is skipped above 16 ulp (not round-off: a long step's
error, or an energy rounded into k'^2 next to the unstable axis, where m x omega -> 0).  So
a short step rounds the state once, like an ideal stepper that evaluates the exact flow in
extended precision and stores (q, L) in double, and the energy error is that rounding's
random walk, not a drift.  What remains above that ideal: the constants of the motion (nu,
k^2, A, B, C) are rounded each step from the rounded state, the same way each step, a phase
bias of ~0.04 ulp of L per step at dt = 0.01 s on van Zon & Schofield's body.

Measured against an independent 30-digit Taylor integration (test/taylor_reference.py) at
10 s, median over eight starts 1 ulp apart (benchmarks/exact_roundoff_floor.py, which also
runs that ideal stepper, the floor): van Zon & Schofield's body 2.0e-13 / 2.4e-12 / 9.1e-12
rad at dt = 0.1 / 0.01 / 0.001 s, floor 3.0e-13 / 2.3e-12 / 6.5e-12 (before this
construction: 7.1e-12 / 4.3e-11 / 4.0e-10); the T-handle 1.5e-14 / 1.1e-14 / 2.2e-14, floor
4e-16 / 2e-15 / 1.2e-14 (its start spins about a world axis, whose rounding turns it about L
alone: a floor no computed step reaches).

Everything is world frame except m (principal or circulation frame); SI units.
"""

import functools
import math

import numpy as np

from .common import free_translation
from .common import kick_drift_kick
from .fast_exact import exact_kernel
from .principal import ASYMMETRIC
from .principal import OBLATE
from .principal import principal_frame
from .principal import PROLATE
from .principal import SPHERICAL
from .registry import register_integrator
from ..elliptic import carlson_rf
from ..elliptic import carlson_rj
from ..elliptic import jacobi_elliptic
from ..rotations import cross
from ..state import State

__all__ = ['exact_free_flow', 'exact_free_rotation', 'exact']

# Proper frame changes of the principal coordinates (columns: new axes in old coordinates).
# Circulation about axis 1: new axes (e3, -e2, e1), moments (I3, I2, I1).
_ABOUT_AXIS_1 = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
# Half turns about e1 (negates m2, m3) and about e3 (negates m1, m2).
_HALF_TURN_1 = np.diag([1.0, -1.0, -1.0])
_HALF_TURN_3 = np.diag([-1.0, -1.0, 1.0])
_E_Z = np.array([0.0, 0.0, 1.0])
# K(m) >= pi/2 for every parameter: a step |h| <= pi/2 needs no reduction by periods.
_QUARTER_PERIOD_FLOOR = 0.5 * math.pi
# Below this |sn h| the addition theorem's denominator 1 - k^2 sn^2 u0 sn^2 h is >= 0.43 and
# is formed directly, with the O(h) parts of the numerators explicit; above, it is formed as
# cn^2 u0 + sn^2 u0 dn^2 h (no cancellation where both sn are near 1 and k'^2 is small).
_SHORT_STEP_SN = 0.75
# The addition theorem is used where its denominator is at least this (round-off amplified
# at most 4x); below, the functions at both ends are subtracted.
_WELL_CONDITIONED = 0.25
# Largest energy correction applied (rad): 16 ulp.  It removes the round-off of a step, a
# turn of ~0.01-4 ulp (measured on the benchmark bodies at dt = 0.01-0.1).  A larger one is
# not round-off: next to the unstable axis m x omega -> 0 and an energy error of a
# parameter rounded from m (k'^2, to ~eps/k'^2) would take a large turn, which the motion
# there amplifies (~1e7 per ulp over 16 s at k'^2 = 2e-9); and a long step's error (~eps
# per radian turned) is not the rounding of the state.  Those are left alone.
_LARGEST_CORRECTION = 16.0 * np.finfo(float).eps


def _momentum_body(quaternion, angular_momentum):
    """Return m = R(q)^T L (body frame, a 3-tuple) for a unit quaternion q (x, y, z, w)."""
    x, y, z, w = (float(c) for c in quaternion)
    lx, ly, lz = (float(c) for c in angular_momentum)
    return ((1.0 - 2.0 * (y * y + z * z)) * lx + 2.0 * (x * y + z * w) * ly
            + 2.0 * (x * z - y * w) * lz,
            2.0 * (x * y - z * w) * lx + (1.0 - 2.0 * (x * x + z * z)) * ly
            + 2.0 * (y * z + x * w) * lz,
            2.0 * (x * z + y * w) * lx + 2.0 * (y * z - x * w) * ly
            + (1.0 - 2.0 * (x * x + y * y)) * lz)


# 3-vectors in the step's hot path are tuples of Python floats: numpy's cost per call on
# one 3-vector exceeds the arithmetic several times over.


def _dot(a, b):
    """Return a . b of two 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    """Return a x b of two 3-vectors, as a tuple."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _half_turn_increment(axis, angle):
    """Return exp(angle/2 axis) - 1 as (vector, scalar): (sin(angle/2) axis, cos(angle/2) - 1)."""
    quarter, sine = math.sin(0.25 * angle), math.sin(0.5 * angle)
    return tuple(sine * c for c in axis), -2.0 * quarter * quarter


def _compose_increments(first, second):
    """Return (1 + x)(1 + y) - 1 = x + y + x y for quaternion increments (vector, scalar)."""
    xv, xw = first
    yv, yw = second
    product = _cross(xv, yv)
    return (tuple(xv[i] + yv[i] + xw * yv[i] + yw * xv[i] + product[i] for i in range(3)),
            xw + yw + xw * yw - _dot(xv, yv))


def _symmetric_top_increment(frame, momentum_body, momentum_norm, duration):
    """Return D - 1 (body frame) for I1 == I2 or I2 == I3 (spherical: nu_a = 0)."""
    moments, axes = frame.moments, frame.axes
    if frame.kind == PROLATE:
        axis, axial, transverse = axes[:, 2], moments[2], moments[0]
    elif frame.kind == OBLATE:
        axis, axial, transverse = axes[:, 0], moments[0], moments[1]
    else:
        axis, axial, transverse = axes[:, 2], moments[2], moments[2]
    spin_rate = _dot(axis, momentum_body) * (1.0 / axial - 1.0 / transverse)
    # Precession about L, seen in the body at its start (R0^T L / L), then the spin.
    precession = _half_turn_increment(tuple(c / momentum_norm for c in momentum_body),
                                      duration * momentum_norm / transverse)
    return _compose_increments(precession, _half_turn_increment(axis, duration * spin_rate))


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


def _third_kind_part(sn, cn, dn, b_over_a):
    """Return P(u) = sn^3 R_J(cn^2, dn^2, 1, 1 + (b/a) sn^2) for |u| <= K (cn >= 0)."""
    return sn ** 3 * carlson_rj(cn * cn, dn * dn, 1.0, 1.0 + b_over_a * sn * sn)


def _increments_by_addition(start, step_functions, parameter, b_over_a):
    """
    Return the increments over u0 -> u0 + r by the addition theorems, or None.

    `start` is (sn, cn, dn)(u0), `step_functions` (sn, cn, dn)(r), |r| <= K.  Returned:
    (sn, cn, dn)(u0 + r) - (sn, cn, dn)(u0), Theta(u0 + r) - Theta(u0) and P(u0 + r) - P(u0).
    A&S 16.17.1-3 have the denominator 1 - k^2 sn^2 u0 sn^2 r = cn^2 u0 + sn^2 u0 dn^2 r; where
    it is small (k'^2 small, u0 and r both near a quarter period) the sum would amplify the
    round-off of cn r and dn r (absolute, ~eps, but relative to values ~k') by its inverse:
    then None, and the ends are used instead.  For a short step (|sn r| <= 0.75, denominator
    >= 0.43) the numerators are written with cn r - 1 = -sn^2 r / (1 + cn r) and dn r - 1 =
    -k^2 sn^2 r / (1 + dn r), so that every term of every increment is O(r).
    """
    s0, c0, d0 = start
    sh, ch, dh = step_functions
    sum_form = c0 * c0 + s0 * s0 * dh * dh
    if sum_form < _WELL_CONDITIONED:
        return None
    sh2 = sh * sh
    dh_minus_1 = -parameter * sh2 / (1.0 + dh)
    ch_minus_1 = -sh2 / (1.0 + ch) if ch >= 0.0 else ch - 1.0
    if abs(sh) <= _SHORT_STEP_SN:
        shrink = parameter * s0 * s0 * sh2
        denominator = 1.0 - shrink
        d_sn = (s0 * (ch_minus_1 * dh + dh_minus_1) + sh * c0 * d0 + shrink * s0) / denominator
        d_cn = (c0 * ch_minus_1 - s0 * d0 * sh * dh + shrink * c0) / denominator
        d_dn = (d0 * dh_minus_1 - parameter * s0 * c0 * sh * ch + shrink * d0) / denominator
    else:
        denominator = sum_form
        d_sn = (s0 * ch * dh + sh * c0 * d0) / denominator - s0
        d_cn = (c0 * ch - s0 * d0 * sh * dh) / denominator - c0
        d_dn = (d0 * dh - parameter * s0 * c0 * sh * ch) / denominator - d0
    s1, c1 = s0 + d_sn, c0 + d_cn
    # Theta(u0 + r) - Theta(u0) = atan2(alpha (s1 c0 - c1 s0), c1 c0 + alpha^2 s1 s0), which
    # lies in (0, pi) for r > 0 (in (-pi, 0) for r < 0): put on that side of the cut.
    alpha_squared = 1.0 + b_over_a
    sine_difference = (s0 * c0 * ch * dh_minus_1 + sh * d0 * (c0 * c0 + s0 * s0 * dh)) \
        / denominator
    theta = math.atan2(math.sqrt(alpha_squared) * sine_difference,
                       c1 * c0 + alpha_squared * s1 * s0)
    if sh > 0.0 and theta < 0.0:
        theta += 2.0 * math.pi
    elif sh < 0.0 and theta > 0.0:
        theta -= 2.0 * math.pi
    third = 0.0
    if b_over_a != 0.0:
        # P(u0 + r) - P(u0) = P(r) + 3 atan(rho S / Q) / rho (module docstring), with
        # atan(x)/rho = (atan(x)/x) S/Q finite as rho -> 0.
        rho = math.sqrt(alpha_squared * (parameter + b_over_a) * b_over_a)
        product = s0 * sh * s1
        quotient = 1.0 + b_over_a * (1.0 - c0 * ch * c1)
        x = rho * product / quotient
        ratio = math.atan(x) / x if x != 0.0 else 1.0
        third = (_third_kind_part(sh, ch, dh, b_over_a)
                 + 3.0 * ratio * product / quotient)
    return d_sn, d_cn, d_dn, theta, third


def _increments_from_the_ends(start, reduced, parameter, complement, b_over_a):
    """
    Return what :func:`_increments_by_addition` does, from the values at both ends.

    u0 = F(am u0) = sn u0 R_F(cn^2 u0, dn^2 u0, 1) (|u0| <= K as cn u0 >= 0), u0 + r is
    reduced to |u| <= K again, and the functions, Theta and P are evaluated at both ends and
    subtracted: for the long steps that need this the increments are O(1), and the ends,
    of size up to K, cost a round-off of ~eps K.
    """
    s0, c0, d0 = start
    u0 = s0 * carlson_rf(c0 * c0, d0 * d0, 1.0)
    end = u0 + reduced
    turns = 0
    if complement > 0.0:
        half_period = 2.0 * carlson_rf(0.0, complement, 1.0)
        turns = round(end / half_period)
        end -= half_period * turns
    s1, c1, d1 = jacobi_elliptic(end, parameter, complement)
    theta = (turns * math.pi + math.atan2(math.sqrt(1.0 + b_over_a) * s1, c1)
             - math.atan2(math.sqrt(1.0 + b_over_a) * s0, c0))
    third = 0.0
    if b_over_a != 0.0:
        third = (_third_kind_part(s1, c1, d1, b_over_a)
                 - _third_kind_part(s0, c0, d0, b_over_a))
        if turns:
            third += 2.0 * turns * carlson_rj(0.0, complement, 1.0, 1.0 + b_over_a)
    if turns % 2:
        s1, c1 = -s1, -c1
    return s1 - s0, c1 - c0, d1 - d0, theta, third


def _spherical_excess(direction, direction_change):
    """
    Return the signed area chi of the spherical triangle (e_z, n0, n1), n1 = n0 + dn.

    tan(chi/2) = e_z . (n0 x n1) / (1 + e_z . n0 + n0 . n1 + n1 . e_z) (Eriksson's formula);
    e_z . (n0 x n1) = e_z . (n0 x dn), so chi is formed from dn, O(dn) for a short step.
    """
    n0, dn = direction, direction_change
    n1 = (n0[0] + dn[0], n0[1] + dn[1], n0[2] + dn[2])
    return 2.0 * math.atan2(n0[0] * dn[1] - n0[1] * dn[0], 1.0 + n0[2] + n1[2] + _dot(n0, n1))


def _turn_about_momentum_increment(direction, direction_change, angle):
    """
    Return D - 1 as (vector, scalar) for D = R_n0(angle) S(n0 + dn -> n0) (any one frame).

    S(v -> u) is the smallest rotation taking v to u, the quaternion (v x u, 1 + v . u)
    normalised; with v x u = dn x n0 and its scalar part minus 1 written as -|v x u|^2 /
    (N (1 + v . u + N)), both parts vanish with dn.  The pole-e_z factorisation D =
    B(n0)^T Rz(psi) B(n1) equals R_n0(psi + chi) S(n1 -> n0), chi the area of the triangle
    (e_z, n0, n1) (:func:`_spherical_excess`): the round-off of this form follows the
    momentum itself (a turn about n0 and a small tilt), so components that are small (a body
    spinning about a principal axis) stay accurate relative to their size.
    """
    n0, dn = direction, direction_change
    tilt = _cross(dn, n0)
    tilt_squared = _dot(tilt, tilt)
    alignment = 1.0 + _dot(n0, n0) + _dot(n0, dn)
    norm = math.sqrt(tilt_squared + alignment * alignment)
    return _compose_increments(_half_turn_increment(n0, angle),
                               (tuple(c / norm for c in tilt),
                                -tilt_squared / (norm * (alignment + norm))))


def _pole_turn_increment(direction, direction_change, precession):
    """
    Return D - 1 as (vector, scalar) for D = B(n0)^T Rz(psi) B(n0 + dn) (circulation frame).

    With B(n) = -e_z (e_z + n)/|e_z + n| (quaternion products of pure quaternions), D =
    -a0 r a1 for the unit bisectors a_i = (e_z + n_i)/|e_z + n_i| and r = cos(psi/2) +
    sin(psi/2) e_z.  Written with e = a1 - a0 (formed from dn, small for a short step),
    a0 . e = -|e|^2/2 and cos(psi/2) - 1 = -2 sin^2(psi/4), every part of D - 1 vanishes with
    the step.  n_z >= 0 here (m3 >= 0), so |e_z + n| >= 1.
    """
    lifted = direction + _E_Z
    start_squared = lifted @ lifted
    start_length = math.sqrt(start_squared)
    a0 = lifted / start_length
    growth = 2.0 * (lifted @ direction_change) + direction_change @ direction_change
    end_length = math.sqrt(start_squared + growth)
    e = (direction_change - a0 * (growth / (start_length + end_length))) / end_length
    a1 = a0 + e
    sine = math.sin(0.5 * precession)
    quarter = math.sin(0.25 * precession)
    cosine_minus_1 = -2.0 * quarter * quarter
    cosine = 1.0 + cosine_minus_1
    e_cross_a0 = cross(e, a0)
    e_squared = e @ e
    vector = cosine * e_cross_a0 - sine * ((1.0 - 0.5 * e_squared) * _E_Z - a0[2] * a1
                                           - a1[2] * a0)
    scalar = cosine_minus_1 - 0.5 * cosine * e_squared + sine * e_cross_a0[2]
    return vector, scalar


def _asymmetric_top_increment(frame, momentum_body, momentum_norm, duration):
    """Return D - 1 (body frame, as (vector, scalar)) of the asymmetric top's step."""
    change, moments, momentum, separatrix = _circulation_frame(
        frame, frame.axes.T @ momentum_body)
    # Python floats: scalar arithmetic on numpy scalars is several times slower.
    j1, j2, j3 = (float(v) for v in moments)
    m1, m2, m3 = (float(v) for v in momentum)
    twice_energy = m1 * m1 / j1 + m2 * m2 / j2 + m3 * m3 / j3
    # Squared amplitudes of (cn, sn, dn): sums of terms of one sign.
    a = m1 * m1 + m2 * m2 * j1 * (j3 - j2) / (j2 * (j3 - j1))
    if a == 0.0 or (m1 == 0.0 and m3 == 0.0):
        # m along a principal axis: a steady spin, omega = (E2 / L^2) L.
        return _half_turn_increment(tuple(c / momentum_norm for c in momentum_body),
                                    duration * twice_energy / momentum_norm)
    b_squared = m2 * m2 + m1 * m1 * j2 * (j3 - j1) / (j1 * (j3 - j2))
    c_squared = m3 * m3 + m2 * m2 * j3 * (j2 - j1) / (j2 * (j3 - j1))
    amplitude_a, amplitude_b = math.sqrt(a), math.sqrt(b_squared)
    amplitude_c = math.sqrt(c_squared)
    # L^2 - J1 E2 and J3 E2 - L^2, and from them k^2 and k'^2.
    g = m2 * m2 * (j2 - j1) / j2 + m3 * m3 * (j3 - j1) / j3
    h = m1 * m1 * (j3 - j1) / j1 + m2 * m2 * (j3 - j2) / j2
    parameter = (j2 - j1) * h / ((j3 - j2) * g)
    complement = (j3 - j1) * float(separatrix) / ((j3 - j2) * g)
    rate = math.copysign(math.sqrt((j3 - j2) * g / (j1 * j2 * j3)), j3 - j2)
    # The start (sn, cn, dn)(u0) = (m2/B, m1/A, m3/C): u0 itself is never needed.
    start = (m2 / amplitude_b, m1 / amplitude_a, m3 / amplitude_c)
    # The step h = 2 K turns + r, |r| <= K (K infinite on the separatrix).
    step = rate * duration
    turns, reduced = 0, step
    if complement > 0.0 and abs(step) > _QUARTER_PERIOD_FLOOR:
        half_period = 2.0 * carlson_rf(0.0, complement, 1.0)
        turns = round(step / half_period)
        reduced = step - half_period * turns
    b_over_a = c_squared * parameter / a
    increments = _increments_by_addition(
        start, jacobi_elliptic(reduced, parameter, complement), parameter, b_over_a)
    if increments is None:
        increments = _increments_from_the_ends(start, reduced, parameter, complement,
                                               b_over_a)
    d_sn, d_cn, d_dn, theta, third_kind = increments
    # The precession angle psi; each half period adds pi to Theta and 2 R_J(0, k'^2, 1,
    # 1 - n) to P.
    theta += turns * math.pi
    if turns and b_over_a != 0.0:
        third_kind += 2.0 * turns * carlson_rj(0.0, complement, 1.0, 1.0 + b_over_a)
    third_kind *= momentum_norm ** 2 * amplitude_c * parameter / (3.0 * a * a)
    alpha = math.sqrt(1.0 + b_over_a)
    integral = (-amplitude_c / a * step + momentum_norm / (a * alpha) * theta + third_kind)
    precession = (duration * twice_energy / momentum_norm
                  - amplitude_a * amplitude_b / momentum_norm * integral)
    # n(u0 + h) - n(u0); an odd number of half periods flips the signs of cn and sn.
    if turns % 2:
        direction_change = (-(2.0 * m1 + amplitude_a * d_cn), -(2.0 * m2 + amplitude_b * d_sn),
                            amplitude_c * d_dn)
    else:
        direction_change = (amplitude_a * d_cn, amplitude_b * d_sn, amplitude_c * d_dn)
    direction = (m1 / momentum_norm, m2 / momentum_norm, m3 / momentum_norm)
    direction_change = tuple(c / momentum_norm for c in direction_change)
    to_body = (frame.axes @ change).tolist()
    if _dot(direction, tuple(n + d for n, d in zip(direction, direction_change))) >= 0.0:
        return _turn_about_momentum_increment(
            tuple(c / momentum_norm for c in momentum_body),
            tuple(_dot(row, direction_change) for row in to_body),
            precession + _spherical_excess(direction, direction_change))
    vector, scalar = _pole_turn_increment(np.array(direction), np.array(direction_change),
                                          precession)
    return tuple(_dot(row, vector) for row in to_body), scalar


def _dyadic(values):
    """
    Return (integers n_i, shift s) with values[i] = n_i / 2^s exactly, for doubles.

    Every double is a dyadic rational n / 2^j (float.as_integer_ratio); over the common
    power of two the arithmetic below is plain integer arithmetic: exact, and, unlike
    fractions.Fraction, with no gcd to take after every operation.
    """
    ratios = [value.as_integer_ratio() for value in values]
    common = max([denominator for _, denominator in ratios])
    return ([numerator * (common // denominator) for numerator, denominator in ratios],
            common.bit_length() - 1)


@functools.lru_cache(maxsize=256)
def _frame_integers(axes, moments):
    """Return ((integers, shift) of the flattened principal axes, the moments' (n, d))."""
    return _dyadic(axes), [moment.as_integer_ratio() for moment in moments]


def _twice_energy_exactly(quaternion, momentum, axes, moments):
    """
    Return (N, Q): 2T = N / (C Q^2) of the orientation q/|q| exactly, |q|^2 = Q / 4^s.

    `quaternion` holds the integers of q over 2^s (:func:`_dyadic`), `momentum` those of
    world L over 2^sl, `axes` those of the principal axes (columns, body frame) row by row
    over 2^sa, `moments` the integer ratios (n_k, d_k) of I_k.  2T = sum_k (axes^T R^T L)_k^2
    / I_k with R = R(q/|q|), written with the homogeneous R_h(q) = |q|^2 R(q/|q|), quadratic
    in q, as 2T_h / |q|^4 (no square root); in integers, with p = a^T R_h(q)^T l,

        2T = sum_k p_k^2 d_k prod_{j != k} n_j / (C Q^2),  C = n_1 n_2 n_3 4^(sl + sa),

    the scale 2^s cancelling: C is the same for every q (not returned).
    """
    x, y, z, w = quaternion
    l, a = momentum, axes
    xx, yy, zz, ww = x * x, y * y, z * z, w * w
    xy, xz, yz, xw, yw, zw = x * y, x * z, y * z, x * w, y * w, z * w
    rotation = ((ww + xx - yy - zz, 2 * (xy - zw), 2 * (xz + yw)),
                (2 * (xy + zw), ww - xx + yy - zz, 2 * (yz - xw)),
                (2 * (xz - yw), 2 * (yz + xw), ww - xx - yy + zz))
    body = [rotation[0][j] * l[0] + rotation[1][j] * l[1] + rotation[2][j] * l[2]
            for j in range(3)]
    p = [a[k] * body[0] + a[3 + k] * body[1] + a[6 + k] * body[2] for k in range(3)]
    (n1, d1), (n2, d2), (n3, d3) = moments
    return (p[0] * p[0] * d1 * n2 * n3 + p[1] * p[1] * d2 * n1 * n3
            + p[2] * p[2] * d3 * n1 * n2), xx + yy + zz + ww


def _rounded_step(frame, quaternion, increment, angular_momentum):
    """
    Return q + q (D - 1), normalised, its energy set to that of q, rounded once to double.

    The sum is held exactly (integers over a power of two, :func:`_dyadic`).  Normalised to
    first order in eta = |q'|^2 - 1 (~1e-16: the error is ~eta^2).  A body-frame turn
    theta = lambda (m x omega) changes 2T by -2 lambda |m x omega|^2 (m -> m - theta x m), so
    lambda is set to remove the excess of 2T over that of q (both exact, the difference
    rounded once); the turn is computed in double, being ~1e-16 rad.  Python floats and
    integers throughout: numpy's cost per call on 3-vectors exceeds the arithmetic.
    """
    x, y, z, w = (float(c) for c in quaternion)
    vector, s = increment
    vx, vy, vz, s = (float(c) for c in (*vector, s))
    # q (D - 1) = (w v + s q_v + q_v x v, w s - q_v . v)
    change = (w * vx + s * x + (y * vz - z * vy), w * vy + s * y + (z * vx - x * vz),
              w * vz + s * z + (x * vy - y * vx), w * s - (x * vx + y * vy + z * vz))
    # q and q' = q + q (D - 1), exactly: integers over 2^shift.
    parts, shift = _dyadic((x, y, z, w) + change)
    start, end = parts[:4], [parts[i] + parts[4 + i] for i in range(4)]
    # 2T of q and of q' exactly (:func:`_twice_energy_exactly`), L and the frame in integers.
    momentum = [float(c) for c in angular_momentum]
    axes, moments = tuple(frame.axes.ravel().tolist()), tuple(frame.moments.tolist())
    (l, momentum_shift), ((a, axes_shift), ratios) = (_dyadic(momentum),
                                                      _frame_integers(axes, moments))
    target, start_norm = _twice_energy_exactly(start, l, a, ratios)
    reached, norm_squared = _twice_energy_exactly(end, l, a, ratios)
    # q' rounded to double: the base of the energy turn, computed in double.
    hx, hy, hz, hw = (c / (1 << shift) for c in end)
    correction = (0.0, 0.0, 0.0, 0.0)
    # A spherical top's energy does not depend on its orientation (and m x omega is round-off).
    if frame.kind != SPHERICAL:
        # The turn axis m x omega, formed in the principal frame, returned to the body frame.
        m = _momentum_body((hx, hy, hz, hw), momentum)
        p = [axes[k] * m[0] + axes[3 + k] * m[1] + axes[6 + k] * m[2] for k in range(3)]
        o = [p[k] / moments[k] for k in range(3)]
        k1, k2, k3 = (p[1] * o[2] - p[2] * o[1], p[2] * o[0] - p[0] * o[2],
                      p[0] * o[1] - p[1] * o[0])
        kx, ky, kz = (axes[3 * i] * k1 + axes[3 * i + 1] * k2 + axes[3 * i + 2] * k3
                      for i in range(3))
        axis_squared = kx * kx + ky * ky + kz * kz
        if axis_squared > 0.0:
            # 2T(q') - 2T(q) = (N' Q^2 - N Q'^2) / (C Q^2 Q'^2), rounded once.
            common = (ratios[0][0] * ratios[1][0] * ratios[2][0]
                      << 2 * (momentum_shift + axes_shift))
            excess = ((reached * start_norm ** 2 - target * norm_squared ** 2)
                      / (common * start_norm ** 2 * norm_squared ** 2))
            f = excess / (4.0 * axis_squared)
            tx, ty, tz = f * kx, f * ky, f * kz
            if tx * tx + ty * ty + tz * tz <= (0.5 * _LARGEST_CORRECTION) ** 2:
                # q (x) (theta/2, 0)
                correction = (hw * tx + (hy * tz - hz * ty), hw * ty + (hz * tx - hx * tz),
                              hw * tz + (hx * ty - hy * tx), -(hx * tx + hy * ty + hz * tz))
    # c (1 - eta/2) + correction, eta = Q / 4^s - 1: exactly, over 2^(3s + 1 + sc), rounded.
    corrections, correction_shift = _dyadic(correction)
    unit, scale = 1 << 2 * shift, 1 << 3 * shift + 1 + correction_shift
    return np.array([((c * (3 * unit - norm_squared) << correction_shift)
                      + (d << 3 * shift + 1)) / scale for c, d in zip(end, corrections)])


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
        steady spins), rounded once; its kinetic energy is that of the start before that
        rounding.  See the module docstring for the construction.

    """
    quaternion = tuple(float(c) for c in quaternion)
    angular_momentum = tuple(float(c) for c in angular_momentum)
    norm_squared = sum(c * c for c in quaternion)
    if abs(norm_squared - 1.0) > 1e-12:
        # The last rounding normalises to first order: start from a unit quaternion.
        norm = math.sqrt(norm_squared)
        quaternion = tuple(c / norm for c in quaternion)
    if not any(angular_momentum) or duration == 0.0:
        return np.array(quaternion)
    frame = principal_frame(body.inertia)
    momentum_body = _momentum_body(quaternion, angular_momentum)
    momentum_norm = math.sqrt(_dot(angular_momentum, angular_momentum))
    if frame.kind == ASYMMETRIC:
        increment = _asymmetric_top_increment(frame, momentum_body, momentum_norm, duration)
    else:
        increment = _symmetric_top_increment(frame, momentum_body, momentum_norm, duration)
    return _rounded_step(frame, quaternion, increment, angular_momentum)


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

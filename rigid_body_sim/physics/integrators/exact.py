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
small for a short step.  Before the one rounding to double, that sum, held in double-double
arithmetic (Dekker's exact products and Knuth's exact sums, relative error ~1e-32), is
normalised to first order in |q|^2 - 1 and turned about the body axis m x omega by the angle
that gives it the kinetic energy of q(0) exactly (the flow conserves it).  An exact version
of this rounding (integers over a power of two: every double is a dyadic rational) is the
test suite's oracle (test/exact_rounding_reference.py): the same bits but in the rarest
ties.  That turn removes round-off, a few ulp; it is skipped above 16 ulp (not round-off:
a long step's error, or an energy rounded into k'^2 next to the unstable axis, where
m x omega -> 0).  So a short step rounds the state once, like an ideal stepper that
evaluates the exact flow in extended precision and stores (q, L) in double, and the energy
error is that rounding's random walk, not a drift.  What remains above that ideal: the
constants of the motion (nu, k^2, A, B, C) are rounded each step from the rounded state, the
same way each step: a small phase bias of L per step.

Measured against an independent 30-digit Taylor integration (test/taylor_reference.py),
over eight starts 1 ulp apart, the error stays close to that ideal stepper's, the floor
(benchmarks/exact_roundoff_floor.py runs both; the figures, and those of the construction
before this one, are in docs/physics_api.md): on the T-handle above it, as its start spins
about a world axis, whose rounding turns it about L alone, a floor no computed step reaches.

Everything is world frame except m (principal or circulation frame); SI units.  One
construction, compiled (scalars): :func:`free_rotation`, composed with the kicks by
:func:`step`.
"""

from __future__ import annotations

import math
from typing import Any

from .registry import KICK_STAGE
from .registry import register_integrator
from ..elliptic import carlson_rf
from ..elliptic import carlson_rj
from ..elliptic import jacobi_elliptic
from ..kernels import helper
from ..kernels import inline
from ..kernels import outlined
from ..kernels.algebra import cross
from ..kernels.algebra import normalised
from ..kernels.algebra import Quaternion
from ..kernels.algebra import quaternion_product
from ..kernels.algebra import rotate_back
from ..kernels.algebra import Vector
from ..kernels.layout import BODY_AXES
from ..kernels.layout import BODY_KIND
from ..kernels.layout import BODY_MASS
from ..kernels.layout import BODY_MOMENTS
from ..kernels.loop import MethodConstants
from ..kernels.loop import run_kernel
from ..kernels.loop import run_steps
from ..kernels.model import Array
from ..kernels.model import kick
from ..kernels.model import Model
from ..kernels.model import NO_ESTIMATE
from ..principal_frame import ASYMMETRIC
from ..principal_frame import OBLATE
from ..principal_frame import PROLATE
from ..principal_frame import SPHERICAL

__all__ = ['free_rotation', 'exact']

_QUARTER_PERIOD_FLOOR = 0.5 * math.pi
_SHORT_STEP_SN = 0.75
_WELL_CONDITIONED = 0.25
_LARGEST_CORRECTION = 16.0 * 2.0 ** -52
# Dekker's splitting constant 2^27 + 1: a = hi + lo with 26-bit halves, so hi * hi is exact.
_SPLITTER = 134217729.0
DoubleDouble = tuple[float, float]
"""The annotations' type of a double-double: (hi, lo), the value hi + lo."""


# -- double-double arithmetic (a value is a pair hi + lo, |lo| <= ulp(hi)/2) -------------


@helper
def _two_sum(a: float, b: float) -> DoubleDouble:
    """Return (s, e) with s = fl(a + b) and s + e = a + b exactly (Knuth)."""
    s = a + b
    v = s - a
    return s, (a - (s - v)) + (b - v)


@helper
def _fast_two_sum(a: float, b: float) -> DoubleDouble:
    """Return (s, e), s + e = a + b exactly, for |a| >= |b| (Dekker)."""
    s = a + b
    return s, b - (s - a)


@helper
def _two_product(a: float, b: float) -> DoubleDouble:
    """Return (p, e) with p = fl(a b) and p + e = a b exactly (Dekker, Veltkamp split)."""
    p = a * b
    t = _SPLITTER * a
    ah = t - (t - a)
    al = a - ah
    t = _SPLITTER * b
    bh = t - (t - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


@helper
def _dd_add(a: DoubleDouble, b: DoubleDouble) -> DoubleDouble:
    s, e = _two_sum(a[0], b[0])
    return _fast_two_sum(s, e + (a[1] + b[1]))


@helper
def _dd_sub(a: DoubleDouble, b: DoubleDouble) -> DoubleDouble:
    return _dd_add(a, (-b[0], -b[1]))


@helper
def _dd_mul(a: DoubleDouble, b: DoubleDouble) -> DoubleDouble:
    p, e = _two_product(a[0], b[0])
    return _fast_two_sum(p, e + (a[0] * b[1] + a[1] * b[0]))


@helper
def _dd_scale(a: DoubleDouble, b: float) -> DoubleDouble:
    """Return a b for a double-double a and a double b."""
    p, e = _two_product(a[0], b)
    return _fast_two_sum(p, e + a[1] * b)


@helper
def _dd_div(a: DoubleDouble, b: DoubleDouble) -> DoubleDouble:
    q1 = a[0] / b[0]
    r = _dd_sub(a, _dd_scale(b, q1))
    return _fast_two_sum(q1, (r[0] + r[1]) / b[0])


@helper
def _twice_energy(qx: DoubleDouble, qy: DoubleDouble, qz: DoubleDouble, qw: DoubleDouble,
                  lx: float, ly: float, lz: float, axes: Array,
                  moments: Array) -> tuple[DoubleDouble, DoubleDouble]:
    """
    Return (2T, |q|^2) as double-doubles for the orientation q/|q|, q given as double-doubles.

    2T = 2T_h(q) / |q|^4 with the homogeneous R_h(q), quadratic in q (the test suite's
    test/exact_rounding_reference.py forms the same value exactly).
    """
    xx, yy, zz, ww = _dd_mul(qx, qx), _dd_mul(qy, qy), _dd_mul(qz, qz), _dd_mul(qw, qw)
    xy, xz, yz = _dd_mul(qx, qy), _dd_mul(qx, qz), _dd_mul(qy, qz)
    xw, yw, zw = _dd_mul(qx, qw), _dd_mul(qy, qw), _dd_mul(qz, qw)
    norm_squared = _dd_add(_dd_add(xx, yy), _dd_add(zz, ww))
    r00 = _dd_sub(_dd_add(ww, xx), _dd_add(yy, zz))
    r11 = _dd_sub(_dd_add(ww, yy), _dd_add(xx, zz))
    r22 = _dd_sub(_dd_add(ww, zz), _dd_add(xx, yy))
    r01 = _dd_scale(_dd_sub(xy, zw), 2.0)
    r10 = _dd_scale(_dd_add(xy, zw), 2.0)
    r02 = _dd_scale(_dd_add(xz, yw), 2.0)
    r20 = _dd_scale(_dd_sub(xz, yw), 2.0)
    r12 = _dd_scale(_dd_sub(yz, xw), 2.0)
    r21 = _dd_scale(_dd_add(yz, xw), 2.0)
    # m_j = sum_i R_ij L_i (body frame, times |q|^2)
    b0 = _dd_add(_dd_add(_dd_scale(r00, lx), _dd_scale(r10, ly)), _dd_scale(r20, lz))
    b1 = _dd_add(_dd_add(_dd_scale(r01, lx), _dd_scale(r11, ly)), _dd_scale(r21, lz))
    b2 = _dd_add(_dd_add(_dd_scale(r02, lx), _dd_scale(r12, ly)), _dd_scale(r22, lz))
    total = (0.0, 0.0)
    for k in range(3):
        p = _dd_add(_dd_add(_dd_scale(b0, axes[0, k]), _dd_scale(b1, axes[1, k])),
                    _dd_scale(b2, axes[2, k]))
        total = _dd_add(total, _dd_div(_dd_mul(p, p), (moments[k], 0.0)))
    return _dd_div(total, _dd_mul(norm_squared, norm_squared)), norm_squared


# -- quaternions and the increment --------------------------------------------------------


@helper
def _half_turn_increment(ax: float, ay: float, az: float, angle: float) -> Quaternion:
    quarter = math.sin(0.25 * angle)
    s = math.sin(0.5 * angle)
    return s * ax, s * ay, s * az, -2.0 * quarter * quarter


@helper
def _compose_increments(x: Quaternion, y: Quaternion) -> Quaternion:
    xx, xy, xz, xw = x
    yx, yy, yz, yw = y
    return (xx + yx + xw * yx + yw * xx + (xy * yz - xz * yy),
            xy + yy + xw * yy + yw * xy + (xz * yx - xx * yz),
            xz + yz + xw * yz + yw * xz + (xx * yy - xy * yx),
            xw + yw + xw * yw - (xx * yx + xy * yy + xz * yz))


@helper
def _symmetric_increment(mx: float, my: float, mz: float, momentum_norm: float, moments: Array,
                         axes: Array, kind: float, duration: float) -> Quaternion:
    if kind == PROLATE:
        column, axial, transverse = 2, moments[2], moments[0]
    elif kind == OBLATE:
        column, axial, transverse = 0, moments[0], moments[1]
    else:
        column, axial, transverse = 2, moments[2], moments[2]
    ax, ay, az = axes[0, column], axes[1, column], axes[2, column]
    spin = duration * (ax * mx + ay * my + az * mz) * (1.0 / axial - 1.0 / transverse)
    precession = _half_turn_increment(mx / momentum_norm, my / momentum_norm,
                                      mz / momentum_norm, duration * momentum_norm / transverse)
    return _compose_increments(precession, _half_turn_increment(ax, ay, az, spin))


@helper
def _third_kind_part(sn: float, cn: float, dn: float, b_over_a: float) -> float:
    return sn ** 3 * carlson_rj(cn * cn, dn * dn, 1.0, 1.0 + b_over_a * sn * sn)


@helper
def _increments_by_addition(s0: float, c0: float, d0: float, sh: float, ch: float, dh: float,
                            parameter: float, b_over_a: float
                            ) -> tuple[bool, float, float, float, float, float]:
    """
    Return (ok, dsn, dcn, ddn, dTheta, dP) over a step of h from u0, by addition theorems.

    s0, c0, d0: sn, cn, dn at u0; sh, ch, dh: at the (reduced) h (the module docstring,
    step 2).  ok is False where the addition theorems are ill-conditioned (a long step next
    to a quarter period), and the values at both ends are subtracted instead.
    """
    sum_form = c0 * c0 + s0 * s0 * dh * dh
    if sum_form < _WELL_CONDITIONED:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0
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
        rho = math.sqrt(alpha_squared * (parameter + b_over_a) * b_over_a)
        product = s0 * sh * s1
        quotient = 1.0 + b_over_a * (1.0 - c0 * ch * c1)
        x = rho * product / quotient
        ratio = math.atan(x) / x if x != 0.0 else 1.0
        third = _third_kind_part(sh, ch, dh, b_over_a) + 3.0 * ratio * product / quotient
    return True, d_sn, d_cn, d_dn, theta, third


@helper
def _increments_from_the_ends(s0: float, c0: float, d0: float, reduced: float,
                              parameter: float, complement: float, b_over_a: float
                              ) -> tuple[float, float, float, float, float]:
    """Return (dsn, dcn, ddn, dTheta, dP) from the values at both ends of the step (u0, u0 + h)."""
    u0 = s0 * carlson_rf(c0 * c0, d0 * d0, 1.0)
    end = u0 + reduced
    turns = 0
    if complement > 0.0:
        half_period = 2.0 * carlson_rf(0.0, complement, 1.0)
        turns = int(round(end / half_period))
        end -= half_period * turns
    s1, c1, d1 = jacobi_elliptic(end, parameter, complement)
    theta = (turns * math.pi + math.atan2(math.sqrt(1.0 + b_over_a) * s1, c1)
             - math.atan2(math.sqrt(1.0 + b_over_a) * s0, c0))
    third = 0.0
    if b_over_a != 0.0:
        third = _third_kind_part(s1, c1, d1, b_over_a) - _third_kind_part(s0, c0, d0, b_over_a)
        if turns != 0:
            third += 2.0 * turns * carlson_rj(0.0, complement, 1.0, 1.0 + b_over_a)
    if turns % 2 != 0:
        s1, c1 = -s1, -c1
    return s1 - s0, c1 - c0, d1 - d0, theta, third


@helper
def _turn_about_momentum_increment(nx: float, ny: float, nz: float, dx: float, dy: float,
                                   dz: float, angle: float) -> Quaternion:
    """Return D - 1 = R_n(angle) S(n + d -> n) - 1 as a quaternion increment (body frame)."""
    tx, ty, tz = dy * nz - dz * ny, dz * nx - dx * nz, dx * ny - dy * nx
    tilt_squared = tx * tx + ty * ty + tz * tz
    alignment = 1.0 + (nx * nx + ny * ny + nz * nz) + (nx * dx + ny * dy + nz * dz)
    norm = math.sqrt(tilt_squared + alignment * alignment)
    return _compose_increments(_half_turn_increment(nx, ny, nz, angle),
                               (tx / norm, ty / norm, tz / norm,
                                -tilt_squared / (norm * (alignment + norm))))


@helper
def _pole_turn_increment(nx: float, ny: float, nz: float, dx: float, dy: float, dz: float,
                         precession: float) -> Quaternion:
    lz = nz + 1.0
    start_squared = nx * nx + ny * ny + lz * lz
    start_length = math.sqrt(start_squared)
    ax, ay, az = nx / start_length, ny / start_length, lz / start_length
    growth = 2.0 * (nx * dx + ny * dy + lz * dz) + (dx * dx + dy * dy + dz * dz)
    end_length = math.sqrt(start_squared + growth)
    f = growth / (start_length + end_length)
    ex, ey, ez = (dx - ax * f) / end_length, (dy - ay * f) / end_length, \
        (dz - az * f) / end_length
    bx, by, bz = ax + ex, ay + ey, az + ez
    sine = math.sin(0.5 * precession)
    quarter = math.sin(0.25 * precession)
    cosine_minus_1 = -2.0 * quarter * quarter
    cosine = 1.0 + cosine_minus_1
    cx, cy, cz = ey * az - ez * ay, ez * ax - ex * az, ex * ay - ey * ax
    e_squared = ex * ex + ey * ey + ez * ez
    return (cosine * cx - sine * (-az * bx - bz * ax),
            cosine * cy - sine * (-az * by - bz * ay),
            cosine * cz - sine * ((1.0 - 0.5 * e_squared) - az * bz - bz * az),
            cosine_minus_1 - 0.5 * cosine * e_squared + sine * cz)


@helper
def _asymmetric_increment(bx: float, by: float, bz: float, momentum_norm: float,
                          moments: Array, axes: Array, duration: float) -> Quaternion:
    # Principal coordinates: axes^T m_body.
    p1 = axes[0, 0] * bx + axes[1, 0] * by + axes[2, 0] * bz
    p2 = axes[0, 1] * bx + axes[1, 1] * by + axes[2, 1] * bz
    p3 = axes[0, 2] * bx + axes[1, 2] * by + axes[2, 2] * bz
    i1, i2, i3 = moments[0], moments[1], moments[2]
    separatrix = p1 * p1 * (i1 - i2) / i1 + p3 * p3 * (i3 - i2) / i3
    # The circulation frame F = axes @ change, as principal-axis columns with signs.
    if separatrix >= 0.0:
        j1, j2, j3 = i1, i2, i3
        m1, m2, m3 = p1, p2, p3
        column1, column2, column3 = 0, 1, 2
        f1, f2, f3 = 1.0, 1.0, 1.0
    else:
        # New axes (e3, -e2, e1).
        j1, j2, j3 = i3, i2, i1
        m1, m2, m3 = p3, -p2, p1
        column1, column2, column3 = 2, 1, 0
        f1, f2, f3 = 1.0, -1.0, 1.0
    if m3 < 0.0:
        m2, m3 = -m2, -m3
        f2, f3 = -f2, -f3
    if m1 < 0.0:
        m1, m2 = -m1, -m2
        f1, f2 = -f1, -f2
    twice_energy = m1 * m1 / j1 + m2 * m2 / j2 + m3 * m3 / j3
    a = m1 * m1 + m2 * m2 * j1 * (j3 - j2) / (j2 * (j3 - j1))
    if a == 0.0 or (m1 == 0.0 and m3 == 0.0):
        return _half_turn_increment(bx / momentum_norm, by / momentum_norm,
                                    bz / momentum_norm, duration * twice_energy / momentum_norm)
    b_squared = m2 * m2 + m1 * m1 * j2 * (j3 - j1) / (j1 * (j3 - j2))
    c_squared = m3 * m3 + m2 * m2 * j3 * (j2 - j1) / (j2 * (j3 - j1))
    amplitude_a, amplitude_b = math.sqrt(a), math.sqrt(b_squared)
    amplitude_c = math.sqrt(c_squared)
    g = m2 * m2 * (j2 - j1) / j2 + m3 * m3 * (j3 - j1) / j3
    h = m1 * m1 * (j3 - j1) / j1 + m2 * m2 * (j3 - j2) / j2
    parameter = (j2 - j1) * h / ((j3 - j2) * g)
    complement = (j3 - j1) * separatrix / ((j3 - j2) * g)
    rate = math.copysign(math.sqrt((j3 - j2) * g / (j1 * j2 * j3)), j3 - j2)
    s0, c0, d0 = m2 / amplitude_b, m1 / amplitude_a, m3 / amplitude_c
    step = rate * duration
    turns, reduced = 0, step
    if complement > 0.0 and abs(step) > _QUARTER_PERIOD_FLOOR:
        half_period = 2.0 * carlson_rf(0.0, complement, 1.0)
        turns = int(round(step / half_period))
        reduced = step - half_period * turns
    b_over_a = c_squared * parameter / a
    sh, ch, dh = jacobi_elliptic(reduced, parameter, complement)
    ok, d_sn, d_cn, d_dn, theta, third_kind = _increments_by_addition(
        s0, c0, d0, sh, ch, dh, parameter, b_over_a)
    if not ok:
        d_sn, d_cn, d_dn, theta, third_kind = _increments_from_the_ends(
            s0, c0, d0, reduced, parameter, complement, b_over_a)
    theta += turns * math.pi
    if turns != 0 and b_over_a != 0.0:
        third_kind += 2.0 * turns * carlson_rj(0.0, complement, 1.0, 1.0 + b_over_a)
    third_kind *= momentum_norm * momentum_norm * amplitude_c * parameter / (3.0 * a * a)
    alpha = math.sqrt(1.0 + b_over_a)
    integral = -amplitude_c / a * step + momentum_norm / (a * alpha) * theta + third_kind
    precession = (duration * twice_energy / momentum_norm
                  - amplitude_a * amplitude_b / momentum_norm * integral)
    if turns % 2 != 0:
        dx, dy = -(2.0 * m1 + amplitude_a * d_cn), -(2.0 * m2 + amplitude_b * d_sn)
    else:
        dx, dy = amplitude_a * d_cn, amplitude_b * d_sn
    dz = amplitude_c * d_dn
    nx, ny, nz = m1 / momentum_norm, m2 / momentum_norm, m3 / momentum_norm
    dx, dy, dz = dx / momentum_norm, dy / momentum_norm, dz / momentum_norm
    if nx * (nx + dx) + ny * (ny + dy) + nz * (nz + dz) >= 0.0:
        excess = 2.0 * math.atan2(nx * dy - ny * dx, 1.0 + nz + (nz + dz)
                                  + (nx * (nx + dx) + ny * (ny + dy) + nz * (nz + dz)))
        ex, ey, ez = _to_body(dx, dy, dz, f1, f2, f3, column1, column2, column3, axes)
        return _turn_about_momentum_increment(bx / momentum_norm, by / momentum_norm,
                                              bz / momentum_norm, ex, ey, ez,
                                              precession + excess)
    vx, vy, vz, w = _pole_turn_increment(nx, ny, nz, dx, dy, dz, precession)
    ux, uy, uz = _to_body(vx, vy, vz, f1, f2, f3, column1, column2, column3, axes)
    return ux, uy, uz, w


@helper
def _to_body(vx: float, vy: float, vz: float, f1: float, f2: float, f3: float, column1: int,
             column2: int, column3: int, axes: Array) -> Vector:
    """Return F v = sum_k f_k v_k axes[:, column_k] (circulation frame to body frame)."""
    ux, uy, uz = f1 * vx, f2 * vy, f3 * vz
    return (ux * axes[0, column1] + uy * axes[0, column2] + uz * axes[0, column3],
            ux * axes[1, column1] + uy * axes[1, column2] + uz * axes[1, column3],
            ux * axes[2, column1] + uy * axes[2, column2] + uz * axes[2, column3])


@helper
def _rounded_step(q: Quaternion, increment: Quaternion, lx: float, ly: float, lz: float,
                  moments: Array, axes: Array, kind: float) -> Quaternion:
    """Round q + q (D - 1) once, normalised, with the energy of q (the module docstring)."""
    x, y, z, w = q
    vx, vy, vz, s = increment
    # q (D - 1)
    change = quaternion_product(q, (vx, vy, vz, s))
    hx, ex = _two_sum(x, change[0])
    hy, ey = _two_sum(y, change[1])
    hz, ez = _two_sum(z, change[2])
    hw, ew = _two_sum(w, change[3])
    target, _ = _twice_energy((x, 0.0), (y, 0.0), (z, 0.0), (w, 0.0), lx, ly, lz, axes,
                              moments)
    reached, norm_squared = _twice_energy((hx, ex), (hy, ey), (hz, ez), (hw, ew), lx, ly, lz,
                                          axes, moments)
    excess = (reached[0] - target[0]) + (reached[1] - target[1])
    mx, my, mz = rotate_back((hx, hy, hz, hw), (lx, ly, lz))
    p1 = axes[0, 0] * mx + axes[1, 0] * my + axes[2, 0] * mz
    p2 = axes[0, 1] * mx + axes[1, 1] * my + axes[2, 1] * mz
    p3 = axes[0, 2] * mx + axes[1, 2] * my + axes[2, 2] * mz
    o1, o2, o3 = p1 / moments[0], p2 / moments[1], p3 / moments[2]
    k1, k2, k3 = cross((p1, p2, p3), (o1, o2, o3))
    kx = axes[0, 0] * k1 + axes[0, 1] * k2 + axes[0, 2] * k3
    ky = axes[1, 0] * k1 + axes[1, 1] * k2 + axes[1, 2] * k3
    kz = axes[2, 0] * k1 + axes[2, 1] * k2 + axes[2, 2] * k3
    axis_squared = kx * kx + ky * ky + kz * kz
    cx = cy = cz = cw = 0.0
    if axis_squared > 0.0 and kind != SPHERICAL:
        f = excess / (4.0 * axis_squared)
        tx, ty, tz = f * kx, f * ky, f * kz
        if tx * tx + ty * ty + tz * tz <= (0.5 * _LARGEST_CORRECTION) ** 2:
            # q (theta/2, 0)
            cx, cy, cz, cw = quaternion_product((hx, hy, hz, hw), (tx, ty, tz, 0.0))
    half_excess = 0.5 * ((norm_squared[0] - 1.0) + norm_squared[1])
    return (hx + ((ex - hx * half_excess) + cx), hy + ((ey - hy * half_excess) + cy),
            hz + ((ez - hz * half_excess) + cz), hw + ((ew - hw * half_excess) + cw))


@outlined
def free_rotation(q: Quaternion, lx: float, ly: float, lz: float, moments: Array, axes: Array,
                  kind: float, duration: float) -> Quaternion:
    """
    Return the unit quaternion after `duration` s of torque-free rotation, exactly.

    q: the orientation (x, y, z, w), body to world, a unit 4-tuple; L = (lx, ly, lz): the
    world angular momentum about the COM (kg m^2/s), constant in the motion; moments, axes,
    kind: the body's principal frame (principal_frame.py); duration: any sign, any size.
    Exact up to round-off for every body (asymmetric, symmetric, spherical) and every state
    (near the separatrix and on it, steady spins), rounded once; its kinetic energy is that
    of q before that rounding (see the module docstring for the construction).
    """
    if (lx == 0.0 and ly == 0.0 and lz == 0.0) or duration == 0.0:
        return q
    largest = max(abs(lx), abs(ly), abs(lz))
    if not 1e-40 < largest < 1e40:
        # The flow is homogeneous (m(t) for s m0 is s m(s t)): L scaled by a power of two,
        # exactly, and the time the other way keep the products of up to four components
        # of L (the last rounding's energy turn) from under- or overflowing (a spin that
        # drag brought to 1e-63 kg m^2/s gave 0/0).
        exponent = math.frexp(largest)[1]
        lx, ly, lz = math.ldexp(lx, -exponent), math.ldexp(ly, -exponent), \
            math.ldexp(lz, -exponent)
        duration = math.ldexp(duration, exponent)
    mx, my, mz = rotate_back(q, (lx, ly, lz))
    momentum_norm = math.sqrt(lx * lx + ly * ly + lz * lz)
    if kind == ASYMMETRIC:
        increment = _asymmetric_increment(mx, my, mz, momentum_norm, moments, axes, duration)
    else:
        increment = _symmetric_increment(mx, my, mz, momentum_norm, moments, axes, kind,
                                         duration)
    return _rounded_step(q, increment, lx, ly, lz, moments, axes, kind)


# -- the integrator


@inline
def step(state: Array, forcing: Any, method: MethodConstants, dt: float, time: float,
         pushed: bool, translates: bool) -> None:
    """Take kick(dt/2), exact free flow(dt), kick(dt/2) on a packed state in place."""
    body = forcing.body
    mass = body[BODY_MASS]
    moments = body[BODY_MOMENTS:BODY_MOMENTS + 3]
    axes = body[BODY_AXES:BODY_AXES + 9].reshape((3, 3))
    kind = int(body[BODY_KIND])
    half = 0.5 * dt
    q = (state[0], state[1], state[2], state[3])
    if abs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0) > 1e-12:
        # The last rounding normalises to first order: start from a unit quaternion.
        state[0], state[1], state[2], state[3] = normalised(q)
    estimate = NO_ESTIMATE
    if pushed:
        estimate = kick(state, time, half, forcing, estimate, False)
    state[0], state[1], state[2], state[3] = free_rotation(
        (state[0], state[1], state[2], state[3]), state[10], state[11], state[12], moments,
        axes, kind, dt)
    if translates:
        for i in range(3):
            state[4 + i] += dt * state[7 + i] / mass
    if pushed:
        # The closing kick starts from the opening one's estimate (model.impulse).
        kick(state, time + dt, half, forcing, estimate, True)


@run_kernel(compile_seconds=25.0)
def run(state: Array, model: Model, method: MethodConstants, dt: float, steps: int,
        time: float) -> int:
    """Take `steps` exact steps of dt s from `time` (kernels/loop.py)."""
    return run_steps(step, state, model, method, dt, steps, time)


# Torque-free the step is exact at any dt (error: round-off only); with a wrench it is second
# order in dt, with error constants set by the wrench alone: the registered order.
exact = register_integrator(
    'exact', order=2, run=run, kicks=KICK_STAGE,
    conserves=('angular_momentum', 'rotational_energy'), exact_torque_free=True,
    summary='the torque-free flow in Jacobi elliptic functions (round-off at any step), '
            'kicked by a wrench')

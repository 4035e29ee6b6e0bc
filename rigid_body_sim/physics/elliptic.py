"""
Jacobi elliptic functions and Carlson's symmetric elliptic integrals.

Compiled (numba) for the exact integrator's kernels: Carlson's duplication algorithms
(B. C. Carlson, "Numerical computation of real or complex elliptic integrals", Numer.
Algorithms 10:13-26, 1995) and the descending Landen transformation (Abramowitz & Stegun
16.12) for sn, cn, dn.  The tests hold them to scipy.special (test/elliptic_reference.py).

Parameter convention: m = k^2 (A&S), and the complementary parameter m1 = 1 - m = k'^2 is
passed alongside m.  Near m = 1 the motion of a rigid body close to its separatrix is governed
by m1, and 1 - m computed from a rounded m has a relative error eps / m1 (1e-8 at
m1 = 1e-8): both are given so neither is formed by subtraction.
"""

from __future__ import annotations

import math

import numpy as np

from .kernels import outlined as _jit

__all__ = ['jacobi_elliptic', 'carlson_rf', 'carlson_rj']

# Below this parameter the first-order expansion in m (A&S 16.13) is exact to ~m^2 < 1e-18
# relative, so the compiled Landen descent stops there.
_SMALL_PARAMETER = 1e-9
# Carlson's relative error bound r of the duplication algorithms: the truncated series is
# accurate to ~r, at double round-off.
_CARLSON_TOLERANCE = 1e-16
# (3 r)^(-1/6) for R_F and (r / 4)^(-1/6) for R_J, Carlson (1995) eqs. (2.2) and (2.13).
_RF_SCALE = (3.0 * _CARLSON_TOLERANCE) ** (-1.0 / 6.0)
_RJ_SCALE = (0.25 * _CARLSON_TOLERANCE) ** (-1.0 / 6.0)


# Landen levels the compiled descent can hold: each level roughly squares m1 (for m1 near 0)
# or m (for m near 0), so even m1 = 1e-300 takes 15 levels from m1 to m < 1e-9.
_MAX_LANDEN_LEVELS = 40


@_jit
def jacobi_elliptic(u: float, parameter: float,
                    complement: float) -> tuple[float, float, float]:
    """
    Return the Jacobi elliptic functions (sn, cn, dn) of (u | m).

    u: the argument (for accuracy, reduce it to |u| <= K(m) first); parameter, complement:
    m = k^2 in [0, 1] and m1 = 1 - m, each to full relative precision.  Descending Landen
    transformations, computed from m1 without forming 1 - m, down to m < 1e-9, then
    A&S 16.13; m = 1 gives the hyperbolic limit sn = tanh u, cn = dn = sech u.
    """
    if complement == 0.0:
        secant = 1.0 / math.cosh(u)
        return math.tanh(u), secant, secant
    roots = np.empty(_MAX_LANDEN_LEVELS)
    one_minus_roots = np.empty(_MAX_LANDEN_LEVELS)
    levels = 0
    m, m1, v = parameter, complement, u
    while m >= _SMALL_PARAMETER and levels < _MAX_LANDEN_LEVELS:
        modulus_complement = math.sqrt(m1)
        root = m / (1.0 + modulus_complement) ** 2
        roots[levels] = root
        one_minus_roots[levels] = 2.0 * modulus_complement / (1.0 + modulus_complement)
        levels += 1
        m, m1 = root * root, 4.0 * modulus_complement / (1.0 + modulus_complement) ** 2
        v = v / (1.0 + root)
    sine, cosine = math.sin(v), math.cos(v)
    # A&S 16.13.1-3, first order in the tiny parameter left.
    correction = 0.25 * m * (v - sine * cosine)
    sn = sine - correction * cosine
    cn = cosine + correction * sine
    dn = 1.0 - 0.5 * m * sine * sine
    for level in range(levels - 1, -1, -1):
        root = roots[level]
        denominator = 1.0 + root * sn * sn
        sn, cn, dn = ((1.0 + root) * sn / denominator, cn * dn / denominator,
                      (one_minus_roots[level] + root * cn * cn) / denominator)
    return sn, cn, dn


@_jit
def carlson_rf(x: float, y: float, z: float) -> float:
    """Return R_F(x, y, z) = 1/2 int_0^inf dt / sqrt((t+x)(t+y)(t+z)), at most one zero."""
    mean0 = (x + y + z) / 3.0
    spread = _RF_SCALE * max(abs(mean0 - x), abs(mean0 - y), abs(mean0 - z))
    x0, y0 = x, y
    mean = mean0
    scale = 1.0
    while scale * spread >= abs(mean):
        sx, sy, sz = math.sqrt(x), math.sqrt(y), math.sqrt(z)
        lam = sx * sy + sx * sz + sy * sz
        x, y, z = 0.25 * (x + lam), 0.25 * (y + lam), 0.25 * (z + lam)
        mean = 0.25 * (mean + lam)
        scale *= 0.25
    big_x = scale * (mean0 - x0) / mean
    big_y = scale * (mean0 - y0) / mean
    big_z = -(big_x + big_y)
    e2 = big_x * big_y - big_z * big_z
    e3 = big_x * big_y * big_z
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / math.sqrt(mean)


@_jit
def _carlson_rc_one(e: float) -> float:
    """Return R_C(1, 1 + e) for e > -1: atan(sqrt e)/sqrt e, or atanh(sqrt(-e))/sqrt(-e)."""
    if e > 0.0:
        root = math.sqrt(e)
        return math.atan(root) / root
    if e < 0.0:
        root = math.sqrt(-e)
        return math.atanh(root) / root
    return 1.0


@_jit
def carlson_rj(x: float, y: float, z: float, p: float) -> float:
    """Return R_J(x, y, z, p) = 3/2 int_0^inf dt / ((t+p) sqrt((t+x)(t+y)(t+z))), p > 0."""
    mean0 = (x + y + z + 2.0 * p) / 5.0
    delta = (p - x) * (p - y) * (p - z)
    spread = _RJ_SCALE * max(abs(mean0 - x), abs(mean0 - y), abs(mean0 - z), abs(mean0 - p))
    x0, y0, z0 = x, y, z
    mean = mean0
    scale = 1.0
    total = 0.0
    while scale * spread >= abs(mean):
        sx, sy, sz, sp = math.sqrt(x), math.sqrt(y), math.sqrt(z), math.sqrt(p)
        lam = sx * sy + sx * sz + sy * sz
        d = (sp + sx) * (sp + sy) * (sp + sz)
        e = scale * scale * scale * delta / (d * d)
        total += scale / d * _carlson_rc_one(e)
        x, y, z, p = 0.25 * (x + lam), 0.25 * (y + lam), 0.25 * (z + lam), 0.25 * (p + lam)
        mean = 0.25 * (mean + lam)
        scale *= 0.25
    big_x = scale * (mean0 - x0) / mean
    big_y = scale * (mean0 - y0) / mean
    big_z = scale * (mean0 - z0) / mean
    big_p = -0.5 * (big_x + big_y + big_z)
    e2 = big_x * big_y + big_x * big_z + big_y * big_z - 3.0 * big_p * big_p
    e3 = big_x * big_y * big_z + 2.0 * e2 * big_p + 4.0 * big_p ** 3
    e4 = (2.0 * big_x * big_y * big_z + e2 * big_p + 3.0 * big_p ** 3) * big_p
    e5 = big_x * big_y * big_z * big_p * big_p
    series = (1.0 - 3.0 * e2 / 14.0 + e3 / 6.0 + 9.0 * e2 * e2 / 88.0 - 3.0 * e4 / 22.0
              - 9.0 * e2 * e3 / 52.0 + 3.0 * e5 / 26.0)
    return scale * series / (mean * math.sqrt(mean)) + 6.0 * total

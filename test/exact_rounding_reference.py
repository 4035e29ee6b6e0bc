"""
The exact flow's last rounding done exactly: the oracle of the compiled double-double one.

The exact integrator (rigid_body_sim/physics/integrators/exact.py) ends each step with
q' = q + q (D - 1), normalised to first order in |q'|^2 - 1 and turned about m x omega so that
it keeps the kinetic energy of q, then rounded once; it holds the sum in double-double
arithmetic (~1e-32).  This module holds it exactly instead, in integers over a power of two
(every double is a dyadic rational n / 2^j; over the common power plain integer arithmetic
is exact, without the gcd of fractions.Fraction at every operation), with the same float
operations where the compiled step computes in double (the increment's product, the turn's
axis and angle): the two must round to the same bits but in ties of probability ~1e-16.
"""

import functools

import numpy as np
from rigid_body_sim.physics.kernels.algebra import cross
from rigid_body_sim.physics.kernels.algebra import quaternion_product
from rigid_body_sim.physics.kernels.algebra import rotate_back
from rigid_body_sim.physics.principal_frame import SPHERICAL

# Largest energy correction applied (rad): 16 ulp, as the compiled step.
LARGEST_CORRECTION = 16.0 * np.finfo(float).eps


def dyadic(values):
    """Return (integers n_i, shift s) with values[i] = n_i / 2^s exactly, for doubles."""
    ratios = [value.as_integer_ratio() for value in values]
    common = max([denominator for _, denominator in ratios])
    return ([numerator * (common // denominator) for numerator, denominator in ratios],
            common.bit_length() - 1)


@functools.lru_cache(maxsize=256)
def frame_integers(axes, moments):
    """Return ((integers, shift) of the flattened principal axes, the moments' (n, d))."""
    return dyadic(axes), [moment.as_integer_ratio() for moment in moments]


def twice_energy_exactly(quaternion, momentum, axes, moments):
    """
    Return (N, Q): 2T = N / (C Q^2) of the orientation q/|q| exactly, |q|^2 = Q / 4^s.

    `quaternion` holds the integers of q over 2^s (:func:`dyadic`), `momentum` those of world
    L over 2^sl, `axes` those of the principal axes (columns, body frame) row by row over
    2^sa, `moments` the integer ratios (n_k, d_k) of I_k.  2T = sum_k (axes^T R^T L)_k^2 / I_k
    with R = R(q/|q|), written with the homogeneous R_h(q) = |q|^2 R(q/|q|), quadratic in q,
    as 2T_h / |q|^4; in integers, with p = a^T R_h(q)^T l,

        2T = sum_k p_k^2 d_k prod_{j != k} n_j / (C Q^2),  C = n_1 n_2 n_3 4^(sl + sa).
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


def rounded_step(frame, quaternion, increment, angular_momentum):
    """
    Return q + q (D - 1), normalised, its energy set to that of q, rounded once to double.

    frame: a principal_frame.PrincipalFrame; quaternion: q (4 floats); increment: D - 1 as
    4 floats (vector, scalar); angular_momentum: world L (3 floats).
    """
    q = tuple(float(c) for c in quaternion)
    change = quaternion_product(q, tuple(float(c) for c in increment))
    parts, shift = dyadic(q + tuple(change))
    start, end = parts[:4], [parts[i] + parts[4 + i] for i in range(4)]
    momentum = [float(c) for c in angular_momentum]
    axes, moments = tuple(frame.axes.ravel().tolist()), tuple(frame.moments.tolist())
    (l, momentum_shift), ((a, axes_shift), ratios) = (dyadic(momentum),
                                                      frame_integers(axes, moments))
    target, start_norm = twice_energy_exactly(start, l, a, ratios)
    reached, norm_squared = twice_energy_exactly(end, l, a, ratios)
    # q' rounded to double: the base of the energy turn, computed in double.
    rounded = tuple(c / (1 << shift) for c in end)
    correction = (0.0, 0.0, 0.0, 0.0)
    if frame.kind != SPHERICAL:
        m = rotate_back(rounded, tuple(momentum))
        p = [axes[k] * m[0] + axes[3 + k] * m[1] + axes[6 + k] * m[2] for k in range(3)]
        o = [p[k] / moments[k] for k in range(3)]
        k1, k2, k3 = cross(tuple(p), tuple(o))
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
            if tx * tx + ty * ty + tz * tz <= (0.5 * LARGEST_CORRECTION) ** 2:
                correction = quaternion_product(rounded, (tx, ty, tz, 0.0))
    # c (1 - eta/2) + correction, eta = Q / 4^s - 1: exactly, over 2^(3s + 1 + sc), rounded.
    corrections, correction_shift = dyadic(correction)
    unit, scale = 1 << 2 * shift, 1 << 3 * shift + 1 + correction_shift
    return np.array([((c * (3 * unit - norm_squared) << correction_shift)
                      + (d << 3 * shift + 1)) / scale for c, d in zip(end, corrections)])

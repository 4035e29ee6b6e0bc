"""
Rigid-body algebra on scalars and tuples, compiled: each operation written once.

Quaternions are 4-tuples (x, y, z, w) composed by the Hamilton product, so that
R(a * b) = R(a) R(b); R(q) maps body to world coordinates.  Vectors are 3-tuples.  Scalars and
tuples only: numba keeps them in registers, where small arrays would be allocated per call.
Every function here is also callable from Python (with tuples or arrays), at numba's
dispatch cost; :mod:`rigid_body_sim.physics.rotations` gives them numpy faces.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from . import helper

__all__ = ['quaternion_product', 'conjugate', 'normalised', 'rotation_matrix', 'rotate',
           'rotate_unnormalised', 'rotate_back', 'cross', 'dot', 'exp_map', 'turned',
           'SERIES_SQUARE', 'Quaternion', 'Vector', 'Matrix', 'QuaternionLike', 'VectorLike']

# The types of the annotations: what compiled code holds, and what a Python caller may pass.
Quaternion = tuple[float, float, float, float]
"""A quaternion (x, y, z, w) as a 4-tuple."""
Vector = tuple[float, float, float]
"""A 3-vector as a 3-tuple."""
Matrix = tuple[float, float, float, float, float, float, float, float, float]
"""A 3x3 matrix as a row-major 9-tuple."""
QuaternionLike = Quaternion | NDArray[np.float64]
"""A quaternion as a 4-tuple or a (4,) array, which the helpers index alike."""
VectorLike = Vector | NDArray[np.float64]
"""A 3-vector as a 3-tuple or a (3,) array."""

SERIES_SQUARE = 1e-4
"""Below this |v|^2 (|v| < 0.01 rad) :func:`exp_map` takes the Taylor series of sin(|v|/2)/|v|
and cos(|v|/2): the first terms left out, |v|^6 / 322560 and |v|^8 / 10321920, are below
3.1e-18 and 1e-23 there, under half an ulp of 0.5 and of 1, so the series is exact to
round-off; it replaces a sqrt, a sin and a cos in the small turns of split ticks."""


@helper
def quaternion_product(a: QuaternionLike, b: QuaternionLike) -> Quaternion:
    """Return the Hamilton product of two quaternions (x, y, z, w): first times second."""
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


@helper
def conjugate(q: QuaternionLike) -> Quaternion:
    """Return the inverse rotation of a unit quaternion, (-x, -y, -z, w)."""
    return (-q[0], -q[1], -q[2], q[3])


@helper
def normalised(q: QuaternionLike) -> Quaternion:
    """Return q / |q| as a 4-tuple."""
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)


@helper
def rotation_matrix(q: QuaternionLike) -> Matrix:
    """Return R(q) of a unit quaternion as a row-major 9-tuple (body to world)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w),
            2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w),
            2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y))


@helper
def rotate(q: QuaternionLike, v: VectorLike) -> Vector:
    """Return R(q) v (body to world) as a 3-tuple, q a unit quaternion."""
    r = rotation_matrix(q)
    return (r[0] * v[0] + r[1] * v[1] + r[2] * v[2],
            r[3] * v[0] + r[4] * v[1] + r[5] * v[2],
            r[6] * v[0] + r[7] * v[1] + r[8] * v[2])


@helper
def rotate_unnormalised(q: QuaternionLike, v: VectorLike) -> Vector:
    """
    Return R(q / |q|) v (body to world) as a 3-tuple, for any non-zero quaternion q.

    R's homogeneous form (quadratic in q) over |q|^2: no square root, so the product need
    not wait for q's normalisation (rk4's stage quaternions are not unit; its stages' L
    then comes sooner in a step under drag: benchmarks/effect_cost.py times it).  Equal to
    rotate(normalised(q), v) to a few ulps.
    """
    x, y, z, w = q[0], q[1], q[2], q[3]
    xx, yy, zz, ww = x * x, y * y, z * z, w * w
    scale = 1.0 / (xx + yy + zz + ww)
    return (scale * ((ww + xx - yy - zz) * v[0] + 2.0 * (x * y - z * w) * v[1]
                     + 2.0 * (x * z + y * w) * v[2]),
            scale * (2.0 * (x * y + z * w) * v[0] + (ww - xx + yy - zz) * v[1]
                     + 2.0 * (y * z - x * w) * v[2]),
            scale * (2.0 * (x * z - y * w) * v[0] + 2.0 * (y * z + x * w) * v[1]
                     + (ww - xx - yy + zz) * v[2]))


@helper
def rotate_back(q: QuaternionLike, v: VectorLike) -> Vector:
    """Return R(q)^T v (world to body) as a 3-tuple, q a unit quaternion."""
    r = rotation_matrix(q)
    return (r[0] * v[0] + r[3] * v[1] + r[6] * v[2],
            r[1] * v[0] + r[4] * v[1] + r[7] * v[2],
            r[2] * v[0] + r[5] * v[1] + r[8] * v[2])


@helper
def cross(a: VectorLike, b: VectorLike) -> Vector:
    """Return a x b as a 3-tuple."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@helper
def dot(a: VectorLike, b: VectorLike) -> float:
    """Return a . b of 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@helper
def exp_map(v: VectorLike) -> Quaternion:
    """
    Return the unit quaternion of the rotation vector v (rad): exp([v]x) = R(q).

    q = (sin(|v|/2) v / |v|, cos(|v|/2)), exact for any angle, several turns included;
    below |v| = 0.01 rad by the series of :data:`SERIES_SQUARE`.
    """
    vx, vy, vz = v[0], v[1], v[2]
    square = vx * vx + vy * vy + vz * vz
    if square < SERIES_SQUARE:
        s = 0.5 + square * (-1.0 / 48.0 + square / 3840.0)
        c = 1.0 + square * (-0.125 + square * (1.0 / 384.0 - square / 46080.0))
    else:
        angle = math.sqrt(square)
        s = math.sin(0.5 * angle) / angle
        c = math.cos(0.5 * angle)
    return (s * vx, s * vy, s * vz, c)


@helper
def turned(q: QuaternionLike, v: VectorLike) -> Quaternion:
    """
    Return q * exp(v), normalised: R turned by the body-frame rotation vector v (rad).

    Turning by w in the world frame, exp([w]x) R, is R exp([R^T w]x): the integrators form
    their turns from body-frame vectors and apply them on the right.  The normalisation keeps
    R orthonormal to round-off however many turns are taken.
    """
    return normalised(quaternion_product(q, exp_map(v)))

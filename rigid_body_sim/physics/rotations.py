"""
Rotations on numpy arrays: skew matrices, the exponential map, quaternions and matrices.

Conventions (see README): a rotation matrix R maps body coordinates to world coordinates,
x_world = R x_body.  Quaternions are stored (x, y, z, w) as in geometry_msgs and compose
with the Hamilton product, so that matrix_from_quaternion(a * b) = R(a) R(b).

The algebra itself is written once, compiled, in :mod:`.kernels.algebra`; the functions
here are its numpy faces (arrays in, arrays out) plus the checks and conversions that only
Python code needs.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from .kernels import algebra
from .kernels.algebra import VectorLike


__all__ = [
    'cross',
    'skew',
    'rotation_matrix_from_rotation_vector',
    'quaternion_from_rotation_vector',
    'quaternion_multiply',
    'matrix_from_quaternion',
    'quaternion_from_matrix',
    'check_rotation_matrix',
    'check_quaternion',
]


def cross(a: VectorLike, b: VectorLike) -> NDArray[np.float64]:
    """Return the cross product a x b of two 3-vectors (an array)."""
    return np.array(algebra.cross(a, b))


def skew(vector: VectorLike | Sequence[float]) -> NDArray[np.float64]:
    """Return the 3x3 cross-product matrix [v]x of v, which maps u to v x u."""
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_matrix_from_rotation_vector(rotation_vector: ArrayLike) -> NDArray[np.float64]:
    """Return exp([v]x), v the rotation axis times the angle (rad)."""
    return matrix_from_quaternion(quaternion_from_rotation_vector(rotation_vector))


def quaternion_from_rotation_vector(rotation_vector: ArrayLike) -> NDArray[np.float64]:
    """
    Return the unit quaternion (x, y, z, w) of the rotation exp([v]x).

    q = (sin(t/2) v/t, cos(t/2)), t = |v|; any angle, including several turns, is exact
    (:func:`.kernels.algebra.exp_map`).
    """
    return np.array(algebra.exp_map(np.asarray(rotation_vector, dtype=float)))


def quaternion_multiply(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Return the Hamilton product a * b of quaternions stored (x, y, z, w)."""
    return np.array(algebra.quaternion_product(np.asarray(a, dtype=float),
                                               np.asarray(b, dtype=float)))


def matrix_from_quaternion(quaternion: ArrayLike) -> NDArray[np.float64]:
    """Return the rotation matrix of a quaternion (x, y, z, w); it is normalised first."""
    unit = algebra.normalised(np.asarray(quaternion, dtype=float))
    return np.array(algebra.rotation_matrix(unit)).reshape(3, 3)


def quaternion_from_matrix(rotation: ArrayLike) -> NDArray[np.float64]:
    """
    Return the unit quaternion (x, y, z, w), w >= 0, of a rotation matrix.

    Shepperd's method: take the largest of the four squared components first, so no
    division by a small number loses precision.
    """
    m = np.asarray(rotation, dtype=float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    candidates = (trace, m[0, 0], m[1, 1], m[2, 2])
    k = int(np.argmax(candidates))
    q: Any
    if k == 0:
        w = 0.5 * np.sqrt(1.0 + trace)
        f = 0.25 / w
        q = [(m[2, 1] - m[1, 2]) * f, (m[0, 2] - m[2, 0]) * f, (m[1, 0] - m[0, 1]) * f, w]
    elif k == 1:
        x = 0.5 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        f = 0.25 / x
        q = [x, (m[0, 1] + m[1, 0]) * f, (m[0, 2] + m[2, 0]) * f, (m[2, 1] - m[1, 2]) * f]
    elif k == 2:
        y = 0.5 * np.sqrt(1.0 - m[0, 0] + m[1, 1] - m[2, 2])
        f = 0.25 / y
        q = [(m[0, 1] + m[1, 0]) * f, y, (m[1, 2] + m[2, 1]) * f, (m[0, 2] - m[2, 0]) * f]
    else:
        z = 0.5 * np.sqrt(1.0 - m[0, 0] - m[1, 1] + m[2, 2])
        f = 0.25 / z
        q = [(m[0, 2] + m[2, 0]) * f, (m[1, 2] + m[2, 1]) * f, z, (m[1, 0] - m[0, 1]) * f]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0.0 else q


def check_rotation_matrix(rotation: ArrayLike, name: str = 'rotation',
                          tolerance: float = 1e-6) -> NDArray[np.float64]:
    """
    Return `rotation` as a float 3x3 array, or raise ValueError if it is not a rotation.

    A rotation is finite, orthonormal (|R^T R - E| <= tolerance) and proper (det R = +1).
    """
    matrix = np.array(rotation, dtype=float)
    if matrix.shape != (3, 3):
        raise ValueError(f'{name} must be a 3x3 rotation matrix; got shape {matrix.shape}')
    if not np.all(np.isfinite(matrix)):
        raise ValueError(f'{name} must be finite; got {matrix.tolist()}')
    error = np.max(np.abs(matrix.T @ matrix - np.eye(3)))
    if error > tolerance:
        raise ValueError(
            f'{name} must be orthonormal (max |R^T R - E| <= {tolerance:g}); got {error:.3g}')
    determinant = np.linalg.det(matrix)
    if determinant < 0.0:
        raise ValueError(f'{name} must be a proper rotation (det R = +1); got det R = '
                         f'{determinant:.6g} (a reflection)')
    return matrix


def check_quaternion(quaternion: ArrayLike, name: str = 'quaternion',
                     tolerance: float = 1e-6) -> NDArray[np.float64]:
    """
    Return a unit quaternion (x, y, z, w), or raise ValueError.

    The input must be finite with norm within `tolerance` of 1; it is then normalised exactly.
    """
    q = np.array(quaternion, dtype=float)
    if q.shape != (4,):
        raise ValueError(f'{name} must have 4 components (x, y, z, w); got shape {q.shape}')
    if not np.all(np.isfinite(q)):
        raise ValueError(f'{name} must be finite; got {q.tolist()}')
    norm = np.linalg.norm(q)
    if abs(norm - 1.0) > tolerance:
        raise ValueError(f'{name} (x, y, z, w) must have unit norm; got |q| = {norm:.9g}')
    return q / norm

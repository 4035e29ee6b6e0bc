"""
Rotations: skew matrices, the exponential map, quaternions (x, y, z, w) and matrices.

Conventions (see README): a rotation matrix R maps body coordinates to world coordinates,
x_world = R x_body.  Quaternions are stored (x, y, z, w) as in geometry_msgs and compose
with the Hamilton product, so that matrix_from_quaternion(a * b) = R(a) R(b).
"""

import math

import numpy as np

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

# Below this angle (rad) the Taylor series of sin(t)/t and (1 - cos t)/t^2 are used: at
# t = 1e-4 the first omitted terms are ~t^4/120 ~ 1e-18, below double round-off.
_SERIES_ANGLE = 1e-4


def cross(a, b):
    """
    Return the cross product a x b of two 3-vectors.

    Written out because numpy's general np.cross, which handles stacks and broadcasting,
    costs ~10x more for one pair of 3-vectors, and the readable steps call it every step.
    """
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def skew(vector):
    """Return the 3x3 cross-product matrix [v]x of v, which maps u to v x u."""
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_matrix_from_rotation_vector(rotation_vector):
    """
    Return exp([v]x) by Rodrigues' formula; v is the rotation axis times the angle (rad).

    exp([v]x) = E + sin(t)/t [v]x + (1 - cos t)/t^2 [v]x^2 with t = |v|.
    """
    v = np.asarray(rotation_vector, dtype=float)
    angle = np.sqrt(v @ v)
    if angle < _SERIES_ANGLE:
        a = 1.0 - angle * angle / 6.0
        b = 0.5 - angle * angle / 24.0
    else:
        a = np.sin(angle) / angle
        b = (1.0 - np.cos(angle)) / (angle * angle)
    k = skew(v)
    return np.eye(3) + a * k + b * (k @ k)


def quaternion_from_rotation_vector(rotation_vector):
    """
    Return the unit quaternion (x, y, z, w) of the rotation exp([v]x).

    q = (sin(t/2) v/t, cos(t/2)), t = |v|; any angle, including several turns, is exact.
    """
    v = np.asarray(rotation_vector, dtype=float)
    angle = np.sqrt(v @ v)
    half = 0.5 * angle
    if angle < _SERIES_ANGLE:
        # sin(t/2)/t = 1/2 - t^2/48 + ...
        s = 0.5 - angle * angle / 48.0
    else:
        s = np.sin(half) / angle
    return np.array([s * v[0], s * v[1], s * v[2], np.cos(half)])


def quaternion_multiply(a, b):
    """Return the Hamilton product a * b of quaternions stored (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ])


def matrix_from_quaternion(quaternion):
    """Return the rotation matrix of a quaternion (x, y, z, w); it is normalised first."""
    # Python floats: for one 3x3 matrix, scalar arithmetic beats numpy's per-call overhead.
    x, y, z, w = (float(c) for c in quaternion)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array([
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ])


def quaternion_from_matrix(rotation):
    """
    Return the unit quaternion (x, y, z, w), w >= 0, of a rotation matrix.

    Shepperd's method: take the largest of the four squared components first, so no
    division by a small number loses precision.
    """
    m = np.asarray(rotation, dtype=float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    candidates = (trace, m[0, 0], m[1, 1], m[2, 2])
    k = int(np.argmax(candidates))
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


def check_rotation_matrix(rotation, name='rotation', tolerance=1e-6):
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


def check_quaternion(quaternion, name='quaternion', tolerance=1e-6):
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

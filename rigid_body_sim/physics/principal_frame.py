"""
Principal frames of inertia tensors, shared by the splitting and exact integrators.

The principal frame is derived from the inertia tensor here, once per tensor (cached), and
packed with the body (kernels/layout.py): every kernel splits and solves in the very same
frame, which matters when two moments are equal and the principal axes are not unique.
"""

from __future__ import annotations

import collections

import numpy as np
from numpy.typing import ArrayLike

from .rotations import quaternion_from_matrix

__all__ = ['PrincipalFrame', 'principal_frame', 'ASYMMETRIC', 'SPHERICAL', 'PROLATE',
           'OBLATE']

# Kinds of body, by exact equality of principal moments I1 <= I2 <= I3.  Bodies whose
# moments are merely close are ASYMMETRIC: the general solutions stay accurate for them.
ASYMMETRIC = 0
SPHERICAL = 1  # I1 == I2 == I3
PROLATE = 2  # I1 == I2 < I3: symmetry axis 3
OBLATE = 3  # I1 < I2 == I3: symmetry axis 1

PrincipalFrame = collections.namedtuple('PrincipalFrame', 'moments axes quaternion kind')
PrincipalFrame.__doc__ = """Principal moments and axes of an inertia tensor.

moments : (3,) I1 <= I2 <= I3 in kg m^2; axes : (3, 3) right-handed principal axes in the
body frame as columns (body coords = axes @ principal coords); quaternion : the unit
quaternion (x, y, z, w) of `axes`; kind : ASYMMETRIC, SPHERICAL, PROLATE or OBLATE.
"""

_CACHE: dict[bytes, PrincipalFrame] = {}
_CACHE_SIZE = 256


def principal_frame(inertia: ArrayLike) -> PrincipalFrame:
    """
    Return the :class:`PrincipalFrame` of a symmetric positive definite 3x3 tensor.

    Computed as RigidBody does (eigh, last axis flipped if needed for det = +1), cached by
    the tensor's bytes so that a kernel call costs a dictionary look-up, not an eigensolve.
    """
    tensor = np.ascontiguousarray(inertia, dtype=float)
    key = tensor.tobytes()
    frame = _CACHE.get(key)
    if frame is None:
        moments, axes = np.linalg.eigh(tensor)
        if np.linalg.det(axes) < 0.0:
            axes[:, 2] = -axes[:, 2]
        i1, i2, i3 = moments
        if i1 == i3:
            kind = SPHERICAL
        elif i1 == i2:
            kind = PROLATE
        elif i2 == i3:
            kind = OBLATE
        else:
            kind = ASYMMETRIC
        for array in (moments, axes):
            array.flags.writeable = False
        frame = PrincipalFrame(moments, axes, quaternion_from_matrix(axes), kind)
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.clear()
        _CACHE[key] = frame
    return frame

"""
The packed arrays the kernels work on: the state (13) and the body (27).

state : (13,)  q (x, y, z, w; body to world) | x (m) | p (kg m/s) | L (kg m^2/s), world
    frame: the COM of a free body, the pivot of a pivoted one (its position fixed, its
    linear momentum zero, its angular momentum about the pivot: effects/pivot.py).
body : (27,)  I_b^-1 row-major (9, kg^-1 m^-2) | m (kg) | principal moments I1 <= I2 <= I3
    (3, kg m^2) | principal frame quaternion (4) | principal axes as columns, row-major (9)
    | kind of body (ASYMMETRIC ... OBLATE of principal_frame.py, as a float).

The principal frame is :func:`~rigid_body_sim.physics.principal_frame.principal_frame`'s,
so every method that solves in it (the splittings, the exact flow) uses the very same axes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from . import helper
from .algebra import Quaternion
from .algebra import Vector
from .algebra import VectorLike
from ..principal_frame import principal_frame

__all__ = ['STATE_SIZE', 'QUATERNION', 'POSITION', 'LINEAR_MOMENTUM', 'ANGULAR_MOMENTUM',
           'BODY_SIZE', 'BODY_MASS', 'BODY_MOMENTS', 'BODY_FRAME', 'BODY_AXES', 'BODY_KIND',
           'body_values', 'inverse_inertia_times', 'quaternion_of', 'angular_momentum_of']

STATE_SIZE = 13
# Offsets of the parts of the packed state.
QUATERNION, POSITION, LINEAR_MOMENTUM, ANGULAR_MOMENTUM = 0, 4, 7, 10
BODY_SIZE = 27
# Offsets in the packed body: mass, principal moments, principal frame quaternion, principal
# axes, kind.
BODY_MASS, BODY_MOMENTS, BODY_FRAME, BODY_AXES, BODY_KIND = 9, 10, 13, 17, 26


def body_values(inertia_body: ArrayLike, inertia_body_inverse: ArrayLike,
                mass: float) -> NDArray[np.float64]:
    """Return the packed body (27,) of a body's mass properties (body frame, SI)."""
    frame = principal_frame(inertia_body)
    return np.concatenate([np.asarray(inertia_body_inverse, dtype=float).reshape(9),
                           [float(mass)], frame.moments, frame.quaternion,
                           frame.axes.reshape(9), [float(frame.kind)]])


@helper
def inverse_inertia_times(body: NDArray[np.float64], v: VectorLike) -> Vector:
    """Return I_b^-1 v (body frame) as a 3-tuple; I_b^-1 row-major in the packed body."""
    return (body[0] * v[0] + body[1] * v[1] + body[2] * v[2],
            body[3] * v[0] + body[4] * v[1] + body[5] * v[2],
            body[6] * v[0] + body[7] * v[1] + body[8] * v[2])


@helper
def quaternion_of(state: NDArray[np.float64]) -> Quaternion:
    """Return the orientation of a packed state as a 4-tuple (x, y, z, w)."""
    return (state[0], state[1], state[2], state[3])


@helper
def angular_momentum_of(state: NDArray[np.float64]) -> Vector:
    """Return L of a packed state as a 3-tuple (world frame)."""
    return (state[10], state[11], state[12])

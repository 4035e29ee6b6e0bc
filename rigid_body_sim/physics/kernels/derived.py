"""
What the state messages carry besides the state: velocities in both frames, a turned marker.

One compiled computation for the node, which publishes one state a tick, and for the offline
writer, which serialises thousands at once (ros/conversions.py, recording/state_batch.py):
they compute the same numbers the same way, so a bag written offline and a live one agree to
the bit.  Frames and units as everywhere: world frame unless named body, SI.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from . import kernel
from .algebra import normalised
from .algebra import quaternion_product
from .algebra import rotate
from .algebra import rotate_back
from .layout import inverse_inertia_times

__all__ = ['derived_quantities', 'COLUMNS']

COLUMNS = {'velocity': slice(0, 3), 'angular_velocity': slice(3, 6),
           'velocity_body': slice(6, 9), 'angular_velocity_body': slice(9, 12),
           'marker_orientation': slice(12, 16)}
"""Columns of :func:`derived_quantities`' rows: v (m/s) and omega (rad/s) in the world, the
same in the body frame, and the marker's orientation (x, y, z, w)."""


@kernel
def derived_quantities(rows: NDArray[np.float64], inverse_inertia: NDArray[np.float64],
                       mass: float, marker_axes: NDArray[np.float64]) -> NDArray[np.float64]:
    """
    Return (n, 16) rows of COLUMNS for n packed states (rows (n, 13): q, x, p, L).

    inverse_inertia: I_b^-1 row-major (9,), kg^-1 m^-2; mass: kg; marker_axes: the marker's
    orientation in the body (4,), (x, y, z, w).  v = p / m, Omega = I_b^-1 R^T L,
    omega = R Omega, v_body = R^T v, with R the matrix of the normalised quaternion; the
    marker turned as q * marker_axes.
    """
    derived = np.empty((rows.shape[0], 16))
    axes = (marker_axes[0], marker_axes[1], marker_axes[2], marker_axes[3])
    for k in range(rows.shape[0]):
        raw = (rows[k, 0], rows[k, 1], rows[k, 2], rows[k, 3])
        q = normalised(raw)
        velocity = (rows[k, 7] / mass, rows[k, 8] / mass, rows[k, 9] / mass)
        omega_body = inverse_inertia_times(inverse_inertia, rotate_back(
            q, (rows[k, 10], rows[k, 11], rows[k, 12])))
        derived[k, 0], derived[k, 1], derived[k, 2] = velocity
        derived[k, 3], derived[k, 4], derived[k, 5] = rotate(q, omega_body)
        derived[k, 6], derived[k, 7], derived[k, 8] = rotate_back(q, velocity)
        derived[k, 9], derived[k, 10], derived[k, 11] = omega_body
        derived[k, 12], derived[k, 13], derived[k, 14], derived[k, 15] = quaternion_product(
            raw, axes)
    return derived

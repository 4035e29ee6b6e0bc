"""gravity: a uniform gravitational field, a constant force m g through the COM."""

import numpy as np

from .registry import check_vector
from .registry import Effect
from .registry import register_effect

STANDARD_ACCELERATION = (0.0, 0.0, -9.81)
"""Default field in m/s^2, world frame: 9.81 m/s^2 along -z (REP 103: z up)."""


@register_effect('gravity')
class Gravity(Effect):
    """
    Uniform gravity: force m g through the COM, no torque about it; potential -m g . x.

    The force is constant in the world and in time, so the Simulator folds it into the held
    wrench (:meth:`constant_force`) and the compiled fast path still runs, on a pivot too
    (there its moment (R d) x m g about the pivot is the kernels' lever torque);
    :meth:`wrench` is the same force for callers that sum effects themselves.

    Parameters
    ----------
    acceleration : array_like, shape (3,)
        The field g in m/s^2, world frame (default (0, 0, -9.81)).

    """

    def __init__(self, acceleration=STANDARD_ACCELERATION):
        self.acceleration = check_vector(acceleration, 'acceleration', 'm/s^2')

    def constant_force(self, body):
        """Return the weight m g in N (world frame), constant in time."""
        return body.mass * self.acceleration

    def wrench(self, body, state, time):
        """Return (m g, 0): the weight acts at the COM, so it has no torque about it."""
        return body.mass * self.acceleration, np.zeros(3)

    def potential_energy(self, body, state):
        """Return -m g . x_com in J (m g z for the default field), zero at the origin."""
        return -body.mass * float(self.acceleration @ state.position)

"""gravity: a uniform gravitational field, a constant force m g through the COM."""

from __future__ import annotations

from numpy.typing import ArrayLike

from .registry import check_vector
from .registry import Effect
from .registry import register_effect
from ..body import RigidBody
from ..kernels.model import Array
from ..kernels.model import Wrench
from ..kernels.model import wrench_term
from ..state import State

MAX_ACCELERATION = 1.0e6
"""The largest field accepted, m/s^2 (1e5 g: far beyond a planet's)."""
STANDARD_ACCELERATION = (0.0, 0.0, -9.81)
"""Default field in m/s^2, world frame: 9.81 m/s^2 along -z (REP 103: z up)."""


@wrench_term
def weight(state: Array, time: float, parameters: Array) -> Wrench:
    """Return (m g, 0): the weight acts at the COM, so it has no torque about it."""
    return parameters[0], parameters[1], parameters[2], 0.0, 0.0, 0.0


@register_effect('gravity')
class Gravity(Effect):
    """
    Uniform gravity: force m g through the COM, no torque about it; potential -m g . x.

    On a pivot its moment (R d) x m g about the pivot makes a top precess (the pivot's
    transmission of effects/pivot.py).

    Parameters
    ----------
    acceleration : array_like, shape (3,)
        The field g in m/s^2, world frame (default (0, 0, -9.81)).

    """

    exerts_torque = False
    # It acts at the COM: T_rot and L about the COM; about a pivot, E with its potential.
    conserves = ('angular_momentum', 'rotational_energy')
    keeps_pivot_invariants = True
    compiled_wrench = staticmethod(weight)
    units = {'acceleration': 'm/s^2, world frame'}
    example = {}

    def __init__(self, acceleration: ArrayLike = STANDARD_ACCELERATION) -> None:
        self.acceleration = check_vector(acceleration, 'acceleration', 'm/s^2',
                                         largest=MAX_ACCELERATION)

    def wrench_parameters(self, body: RigidBody) -> Array:
        """Return the weight m g in N (world frame)."""
        return body.mass * self.acceleration

    def potential_energy(self, body: RigidBody, state: State) -> float:
        """Return -m g . x_com in J (m g z for the default field), zero at the origin."""
        return -body.mass * float(self.acceleration @ state.position)

"""sinusoidal_torque: a world-frame torque oscillating in time, A sin(2 pi f t + phi)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .registry import check_number
from .registry import check_vector
from .registry import Effect
from .registry import register_effect
from ..body import RigidBody
from ..kernels.model import Array
from ..kernels.model import Wrench
from ..kernels.model import wrench_term


MAX_AMPLITUDE = 1.0e9
"""The largest torque amplitude accepted, N m (a ship's engine is ~1e7)."""
MAX_FREQUENCY = 1.0e6
"""The largest frequency accepted, Hz (beyond any tick rate it is an aliased blur)."""


@wrench_term
def oscillating_torque(state: Array, time: float, parameters: Array) -> Wrench:
    """Return (0, A sin(omega t + phi)); parameters: A (3, N m), omega (rad/s), phi (rad)."""
    s = math.sin(parameters[3] * time + parameters[4])
    return 0.0, 0.0, 0.0, parameters[0] * s, parameters[1] * s, parameters[2] * s


@register_effect('sinusoidal_torque')
class SinusoidalTorque(Effect):
    """
    A torque about the COM, fixed in direction in the world, oscillating in time.

    tau(t) = amplitude sin(2 pi frequency t + phase), world frame; no force.  It depends on
    time, not on the state: every integrator samples it at its own kick or stage times, so
    each keeps its order.

    Parameters
    ----------
    amplitude : array_like, shape (3,)
        N m, world frame.
    frequency : float
        Hz (> 0).
    phase : float
        rad (default 0).

    """

    compiled_wrench = staticmethod(oscillating_torque)
    units = {'amplitude': 'N m, world frame', 'frequency': 'Hz', 'phase': 'rad'}
    example = {'amplitude': [0.1, -0.2, 0.3], 'frequency': 0.5, 'phase': 0.2}

    def __init__(self, amplitude: ArrayLike, frequency: float, phase: float = 0.0) -> None:
        self.amplitude = check_vector(amplitude, 'amplitude', 'N m', largest=MAX_AMPLITUDE)
        self.frequency = check_number(frequency, 'frequency', 'Hz', positive=True,
                                      maximum=MAX_FREQUENCY)
        self.phase = check_number(phase, 'phase', 'rad', minimum=-1e6, maximum=1e6)

    def wrench_parameters(self, body: RigidBody | None) -> Array:
        """Return (A_x, A_y, A_z, 2 pi f, phase)."""
        return np.array([*self.amplitude, 2.0 * math.pi * self.frequency, self.phase])

    def torque(self, time: float) -> Array:
        """Return tau(t) in N m, world frame."""
        values = oscillating_torque(np.zeros(13), float(time), self.wrench_parameters(None))
        return np.array(values[3:])

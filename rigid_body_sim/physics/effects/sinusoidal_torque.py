"""sinusoidal_torque: a world-frame torque oscillating in time, A sin(2 pi f t + phi)."""

import math

import numpy as np

from .registry import check_number
from .registry import check_vector
from .registry import Effect
from .registry import register_effect


@register_effect('sinusoidal_torque')
class SinusoidalTorque(Effect):
    """
    A torque about the COM, fixed in direction in the world, oscillating in time.

    tau(t) = amplitude sin(2 pi frequency t + phase), world frame; no force.  It depends on
    time, not on the state, so the steps sample it where they kick (a time-varying wrench
    runs the integrators' readable path).

    Parameters
    ----------
    amplitude : array_like, shape (3,)
        N m, world frame.
    frequency : float
        Hz (> 0).
    phase : float
        rad (default 0).

    """

    def __init__(self, amplitude, frequency, phase=0.0):
        self.amplitude = check_vector(amplitude, 'amplitude', 'N m')
        self.frequency = check_number(frequency, 'frequency', 'Hz', positive=True)
        self.phase = check_number(phase, 'phase', 'rad')
        self._no_force = np.zeros(3)
        self._no_force.flags.writeable = False

    def torque(self, time):
        """Return tau(t) in N m, world frame."""
        return self.amplitude * math.sin(2.0 * math.pi * self.frequency * time + self.phase)

    def wrench(self, body, state, time):
        """Return (0, tau(t)): a pure torque about the COM."""
        return self._no_force, self.torque(time)

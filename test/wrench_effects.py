"""
Wrenches for the convergence tests: compiled terms for the kernels, numpy twins for references.

Each is an Effect whose compiled wrench term the Simulator's kernels take (so every integrator
runs it compiled, as it runs the package's effects), with the same law written in numpy as
``reference(state, time) -> (force, torque)`` for the DOP853 references and the methods'
references (it reads only ``state.rotation``: a package State or a reference Motion).  World
frame, SI units.
"""

import math

import numpy as np
from rigid_body_sim.physics.effects.registry import Effect
from rigid_body_sim.physics.kernels.algebra import rotate
from rigid_body_sim.physics.kernels.model import wrench_term

__all__ = ['OrientationDependent', 'TimeDependent']


@wrench_term
def _restoring(state, time, parameters):
    """Return (k_f R e1, k_t (R e3) x e_z); parameters: k_f (N), k_t (N m)."""
    q = (state[0], state[1], state[2], state[3])
    fx, fy, fz = rotate(q, (1.0, 0.0, 0.0))
    ax, ay, az = rotate(q, (0.0, 0.0, 1.0))
    force, torque = parameters[0], parameters[1]
    return force * fx, force * fy, force * fz, torque * ay, -torque * ax, 0.0


class OrientationDependent(Effect):
    """
    A restoring torque k_t (R e3) x e_z, like gravity on an offset COM, and a body-x force.

    force: k_f in N, along the body x axis; torque: k_t in N m.
    """

    compiled_wrench = staticmethod(_restoring)

    def __init__(self, force, torque):
        self.force, self.torque = float(force), float(torque)

    def wrench_parameters(self, body):
        """Return (k_f, k_t)."""
        return np.array([self.force, self.torque])

    def reference(self, state, time):
        """Return the same wrench in numpy."""
        rotation = state.rotation
        return (self.force * rotation[:, 0],
                self.torque * np.cross(rotation[:, 2], np.array([0.0, 0.0, 1.0])))


@wrench_term
def _oscillating(state, time, parameters):
    """Return (F0 sin(w t), tau0 cos(w t)); parameters: F0 (3), tau0 (3), w (rad/s)."""
    s, c = math.sin(parameters[6] * time), math.cos(parameters[6] * time)
    return (parameters[0] * s, parameters[1] * s, parameters[2] * s, parameters[3] * c,
            parameters[4] * c, parameters[5] * c)


class TimeDependent(Effect):
    """A world force F0 sin(2 pi t / T) and torque tau0 cos(2 pi t / T) (N, N m, s)."""

    compiled_wrench = staticmethod(_oscillating)

    def __init__(self, force, torque, period):
        self.force = np.array(force, dtype=float)
        self.torque = np.array(torque, dtype=float)
        self.period = float(period)

    def wrench_parameters(self, body):
        """Return (F0, tau0, 2 pi / T)."""
        return np.array([*self.force, *self.torque, 2.0 * math.pi / self.period])

    def reference(self, state, time):
        """Return the same wrench in numpy."""
        phase = 2.0 * math.pi * time / self.period
        return self.force * math.sin(phase), self.torque * math.cos(phase)

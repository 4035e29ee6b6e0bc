"""
The seed's simple first-order method: w = omega = I_w^{-1} L, then R <- exp(h [w]x) R.

Seed 000, "Numerical Methods for Rigid Body Simulation".  The wrench is read once at the
start of the step and held over it: L <- L + h tau, p <- p + h F, and
x <- x + h p/m + h^2 F/(2m) (the exact motion under the held force, so a constant force
gives the exact parabola and a constant torque the exact L(t)).  World L is not touched by
the turn, so torque-free motion conserves it exactly.

The step forms the turn in the body frame and applies it on the right:
exp(h [omega]x) R = R exp(h [Omega]x), Omega = R^T omega = I_b^{-1} R^T L, never building
I_w = R I_b R^T.
"""

from __future__ import annotations

from typing import Any

from .registry import register_integrator
from ..kernels import inline
from ..kernels.algebra import rotate_back
from ..kernels.algebra import turned
from ..kernels.layout import angular_momentum_of
from ..kernels.layout import BODY_MASS
from ..kernels.layout import inverse_inertia_times
from ..kernels.layout import quaternion_of
from ..kernels.loop import MethodConstants
from ..kernels.loop import run_kernel
from ..kernels.loop import run_steps_specialised
from ..kernels.model import Array
from ..kernels.model import integrated_wrench
from ..kernels.model import Model

__all__ = ['first_order']


@inline
def step(state: Array, forcing: Any, method: MethodConstants, dt: float, time: float,
         pushed: bool, translates: bool) -> None:
    """Take the first-order step on a packed state in place (no method constants)."""
    mass = forcing.body[BODY_MASS]
    omega_body = inverse_inertia_times(
        forcing.body, rotate_back(quaternion_of(state), angular_momentum_of(state)))
    if pushed:
        wrench = integrated_wrench(state, time, forcing)
        if translates:
            for i in range(3):
                state[4 + i] += dt * state[7 + i] / mass + (0.5 * dt * dt / mass) * wrench[i]
        for i in range(3):
            state[7 + i] += dt * wrench[i]
            state[10 + i] += dt * wrench[3 + i]
    elif translates:
        for i in range(3):
            state[4 + i] += dt * state[7 + i] / mass
    state[0], state[1], state[2], state[3] = turned(quaternion_of(state), (
        dt * omega_body[0], dt * omega_body[1], dt * omega_body[2]))


@run_kernel(compile_seconds=3.5)
def run(state: Array, model: Model, method: MethodConstants, dt: float, steps: int,
        time: float) -> int:
    """Take `steps` first-order steps of dt s from `time` (kernels/loop.py)."""
    return run_steps_specialised(step, state, model, method, dt, steps, time)


first_order = register_integrator(
    'first_order', order=1, run=run, summary="the seed's simple first-order method",
    wrench_samples=((0.0, 1.0),), conserves=('angular_momentum',))

"""
Buss's second-order methods: the augmented step (``buss``) and the plain one (``buss_plain``).

S. R. Buss, "Accurate and efficient simulation of rigid body rotations", J. Comput. Phys.
164:377-406, 2000 (the seed cites it as "Accurate and Efficient Simulation of Rigid Body
Dynamics", 2001).  From the world angular velocity omega = I_w^{-1} L and the angular
acceleration alpha = I_w^{-1} (tau - omega x L) (tau = 0 inside the drift: torques enter as
kicks around it), the body turns by R <- exp(h [w]x) R with the effective angular velocity

    w = omega + (h/2) alpha + (h^2/12) (alpha x omega).

The h^2/12 term is the first Magnus-expansion (BCH/Dynkin) correction: it accounts for
rotations about omega and alpha not commuting; ``buss_plain`` drops it.  World L is not
touched by the turn, so torque-free motion conserves it exactly.  A wrench enters as half
kicks of the momenta around the turn (Strang splitting), which keeps second order.

The step forms the paper's world-frame turn from body-frame vectors and applies it on the
right (exp(h [w]x) R = R exp(h [R^T w]x)), never building I_w = R I_b R^T.
"""

from __future__ import annotations

from typing import Any

from .registry import KICK_STAGE
from .registry import register_integrator
from ..kernels import inline
from ..kernels.algebra import cross
from ..kernels.algebra import rotate_back
from ..kernels.algebra import turned
from ..kernels.layout import angular_momentum_of
from ..kernels.layout import BODY_MASS
from ..kernels.layout import inverse_inertia_times
from ..kernels.layout import quaternion_of
from ..kernels.loop import MethodConstants
from ..kernels.loop import run_kernel
from ..kernels.loop import run_steps
from ..kernels.model import Array
from ..kernels.model import kick
from ..kernels.model import Model
from ..kernels.model import NO_ESTIMATE

__all__ = ['buss', 'buss_plain']


@inline
def step(state: Array, forcing: Any, method: MethodConstants, dt: float, time: float,
         pushed: bool, translates: bool) -> None:
    """
    Take Buss's step on a packed state in place (method[0]: 1 augmented, 0 plain).

    Scalars and tuples only between the kicks: numba keeps them in registers (the cost per
    step: benchmarks/step_cost.py).
    """
    half = 0.5 * dt
    estimate = NO_ESTIMATE
    if pushed:
        estimate = kick(state, time, half, forcing, estimate, False)
    body = forcing.body
    momentum_body = rotate_back(quaternion_of(state), angular_momentum_of(state))
    omega_body = inverse_inertia_times(body, momentum_body)
    gyroscopic = cross(omega_body, momentum_body)
    alpha_body = inverse_inertia_times(body, (-gyroscopic[0], -gyroscopic[1], -gyroscopic[2]))
    coupling = cross(alpha_body, omega_body)
    twelfth = dt * dt / 12.0 * method[0]
    state[0], state[1], state[2], state[3] = turned(quaternion_of(state), (
        dt * (omega_body[0] + half * alpha_body[0] + twelfth * coupling[0]),
        dt * (omega_body[1] + half * alpha_body[1] + twelfth * coupling[1]),
        dt * (omega_body[2] + half * alpha_body[2] + twelfth * coupling[2])))
    if translates:
        mass = body[BODY_MASS]
        for i in range(3):
            state[4 + i] += dt * state[7 + i] / mass
    if pushed:
        # The closing kick starts from the opening one's estimate (model.impulse).
        kick(state, time + dt, half, forcing, estimate, True)


@run_kernel(compile_seconds=10.0)
def run(state: Array, model: Model, method: MethodConstants, dt: float, steps: int,
        time: float) -> int:
    """Take `steps` Buss steps of dt s from `time` (kernels/loop.py)."""
    return run_steps(step, state, model, method, dt, steps, time)


buss = register_integrator(
    'buss', order=2, run=run, method=(1.0,), kicks=KICK_STAGE,
    conserves=('angular_momentum',),
    summary="Buss's augmented second-order method (the default)")
buss_plain = register_integrator(
    'buss_plain', order=2, run=run, method=(0.0,), kicks=KICK_STAGE,
    conserves=('angular_momentum',),
    summary="Buss's plain second-order method: buss without the h^2/12 term")

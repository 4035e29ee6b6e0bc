"""
Classical fourth-order Runge-Kutta on Euler's equations and the quaternion kinematics.

RK4 as textbooks and MuJoCo use it for a free body: one set of four stages advances, together,

    dq/dt = 1/2 q * (Omega, 0)       the quaternion kinematics (x, y, z, w), body to world,
    dm/dt = m x Omega + R^T tau      Euler's equations for the body angular momentum
                                     m = R^T L (Omega = I_b^{-1} m, body frame),
    dx/dt = p / m_body,  dp/dt = F   the translation (world frame),

with the wrench (F, tau: world frame) evaluated at each stage's state and time, and the
torque taken into the body frame at that stage's orientation (R of the normalised stage
quaternion).  After the step q is normalised and the world angular momentum is L = R(q) m.

Why the body frame: in it the fast part of the motion, the spin, is only the linear
kinematics of q, and Euler's equations carry the slow tumble of m.  The former formulation
(world L and q, with omega = R I_b^{-1} R^T L recomputed at each stage) differentiated the
rotation matrix inside the stages and was orders of magnitude less accurate near the
separatrix than this form and than MuJoCo's RK4 (docs/benchmark.md, "rk4 as users know it",
has the figures: benchmarks/rk4_before_after.py).

A baseline, not a geometric method: it conserves neither |q| (restored after each step)
nor the energy, nor, torque-free, the world angular momentum (L = R m drifts at the
method's order, ~h^4); it is fourth order.
"""

from __future__ import annotations

from typing import Any

from .registry import register_integrator
from ..kernels import helper
from ..kernels import inline
from ..kernels.algebra import conjugate
from ..kernels.algebra import cross
from ..kernels.algebra import normalised
from ..kernels.algebra import Quaternion
from ..kernels.algebra import quaternion_product
from ..kernels.algebra import rotate
from ..kernels.algebra import rotate_back
from ..kernels.algebra import rotate_unnormalised
from ..kernels.algebra import Vector
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

__all__ = ['rk4', 'world_momentum_change']


@helper
def world_momentum_change(quaternion: Quaternion, quaternion_change: Quaternion,
                          momentum_body: Vector, momentum_change: Vector) -> Vector:
    """
    Return R0^T (L1 - L0) = R(d) m1 - m0 (body frame at the start), from increments alone.

    The step ends at L1 = R(q1) m1 with q1 = (q0 + dq) / |q0 + dq| and m1 = m0 + dm.  Formed
    as R(q1) m1 in double, L1 would carry the rounding of the round trip m0 = R0^T L0, ~1 ulp
    of |L| per step; that random walk of L is amplified near the separatrix (on the T-handle
    at small steps it left rk4 far behind MuJoCo's RK4 over 100 s).  Written as
    L1 = L0 + R0 (dm + (R(d) - 1) m1), d = q0^* q1 ~ (q0^* dq) + (0, 0, 0, 1), every term
    is an increment known to its relative precision, so L changes only by the step's own
    change (torque-free, ~h^5: below half an ulp, L then stays bit-identical).

    quaternion : q0 (unit); quaternion_change : dq; momentum_body : m1 = m0 + dm;
    momentum_change : dm (tuples).  (R(d) - 1) m = 2 (w v x m + v x (v x m)) / (|v|^2 + w^2)
    for the unnormalised d = (v, w).
    """
    vx, vy, vz, scalar = quaternion_product(conjugate(quaternion), quaternion_change)
    scalar = 1.0 + scalar
    turned = cross((vx, vy, vz), momentum_body)
    twice = cross((vx, vy, vz), turned)
    scale = 2.0 / (vx * vx + vy * vy + vz * vz + scalar * scalar)
    return (momentum_change[0] + scale * (scalar * turned[0] + twice[0]),
            momentum_change[1] + scale * (scalar * turned[1] + twice[1]),
            momentum_change[2] + scale * (scalar * turned[2] + twice[2]))


@helper
def _stage4(y: Quaternion, k: Quaternion, h: float) -> Quaternion:
    """Return the 4-tuple y + h k."""
    return (y[0] + h * k[0], y[1] + h * k[1], y[2] + h * k[2], y[3] + h * k[3])


@helper
def _stage3(y: Vector, k: Vector, h: float) -> Vector:
    """Return the 3-tuple y + h k."""
    return (y[0] + h * k[0], y[1] + h * k[1], y[2] + h * k[2])


@inline
def _derivatives(q: Quaternion, momentum_body: Vector, position: Vector,
                 linear_momentum: Vector, time: float, forcing: Any,
                 pushed: bool) -> tuple[Quaternion, Vector, Vector]:
    """
    Return (dq, dm, F) of the stage at the (unnormalised) stage quaternion q (a 4-tuple).

    dq = 1/2 q * (Omega, 0), dm = m x Omega + R^T tau (body frame), F (world), with
    Omega = I_b^{-1} m and the wrench taken at the stage's state (the normalised q, the
    stage's position and momenta) and time.
    """
    omega = inverse_inertia_times(forcing.body, momentum_body)
    product = quaternion_product(q, (omega[0], omega[1], omega[2], 0.0))
    dq = (0.5 * product[0], 0.5 * product[1], 0.5 * product[2], 0.5 * product[3])
    dm = cross(momentum_body, omega)
    force = (0.0, 0.0, 0.0)
    if pushed:
        unit = normalised(q)
        stage = forcing.stage
        stage[0], stage[1], stage[2], stage[3] = unit
        if forcing.reads_state:
            # The effects read all of the stage's state, not just its orientation.
            stage[4], stage[5], stage[6] = position
            stage[7], stage[8], stage[9] = linear_momentum
            # L = R m from the stage's own q, beside its normalisation rather than after it.
            stage[10], stage[11], stage[12] = rotate_unnormalised(q, momentum_body)
        wrench = integrated_wrench(stage, time, forcing)
        force = (wrench[0], wrench[1], wrench[2])
        # R^T tau: the torque in the body frame at this stage's orientation.
        torque = rotate_back(unit, (wrench[3], wrench[4], wrench[5]))
        dm = (dm[0] + torque[0], dm[1] + torque[1], dm[2] + torque[2])
    return dq, dm, force


@inline
def step(state: Array, forcing: Any, method: MethodConstants, dt: float, time: float,
         pushed: bool, translates: bool) -> None:
    """Take the classical RK4 step on a packed state in place (no method constants)."""
    mass = forcing.body[BODY_MASS]
    half, sixth = 0.5 * dt, dt / 6.0
    q0 = quaternion_of(state)
    m0 = rotate_back(q0, angular_momentum_of(state))
    x0 = (state[4], state[5], state[6])
    p0 = (state[7], state[8], state[9])
    dq1, dm1, f1 = _derivatives(q0, m0, x0, p0, time, forcing, pushed)
    p1 = _stage3(p0, f1, half)
    dq2, dm2, f2 = _derivatives(_stage4(q0, dq1, half), _stage3(m0, dm1, half),
                                _stage3(x0, p0, half / mass), p1, time + half, forcing, pushed)
    p2 = _stage3(p0, f2, half)
    dq3, dm3, f3 = _derivatives(_stage4(q0, dq2, half), _stage3(m0, dm2, half),
                                _stage3(x0, p1, half / mass), p2, time + half, forcing, pushed)
    p3 = _stage3(p0, f3, dt)
    dq4, dm4, f4 = _derivatives(_stage4(q0, dq3, dt), _stage3(m0, dm3, dt),
                                _stage3(x0, p2, dt / mass), p3, time + dt, forcing, pushed)
    dq = (sixth * (dq1[0] + 2.0 * dq2[0] + 2.0 * dq3[0] + dq4[0]),
          sixth * (dq1[1] + 2.0 * dq2[1] + 2.0 * dq3[1] + dq4[1]),
          sixth * (dq1[2] + 2.0 * dq2[2] + 2.0 * dq3[2] + dq4[2]),
          sixth * (dq1[3] + 2.0 * dq2[3] + 2.0 * dq3[3] + dq4[3]))
    dm = (sixth * (dm1[0] + 2.0 * dm2[0] + 2.0 * dm3[0] + dm4[0]),
          sixth * (dm1[1] + 2.0 * dm2[1] + 2.0 * dm3[1] + dm4[1]),
          sixth * (dm1[2] + 2.0 * dm2[2] + 2.0 * dm3[2] + dm4[2]))
    state[0], state[1], state[2], state[3] = normalised(_stage4(q0, dq, 1.0))
    # L1 = L0 + R0 (dm + (R(d) - 1) m1) from increments (world_momentum_change).
    change = rotate(q0, world_momentum_change(q0, dq, _stage3(m0, dm, 1.0), dm))
    for i in range(3):
        state[10 + i] += change[i]
    if translates:
        # dx/dt = p / m at the stages' momenta p0, p1, p2, p3.
        for i in range(3):
            state[4 + i] += sixth * (p0[i] / mass + 2.0 * (p1[i] / mass)
                                     + 2.0 * (p2[i] / mass) + p3[i] / mass)
    if pushed:
        for i in range(3):
            state[7 + i] = p0[i] + sixth * (f1[i] + 2.0 * f2[i] + 2.0 * f3[i] + f4[i])


@run_kernel(compile_seconds=22.0)
def run(state: Array, model: Model, method: MethodConstants, dt: float, steps: int,
        time: float) -> int:
    """Take `steps` RK4 steps of dt s from `time` (kernels/loop.py)."""
    return run_steps_specialised(step, state, model, method, dt, steps, time)


rk4 = register_integrator(
    'rk4', order=4, run=run,
    summary='classical Runge-Kutta on the body-frame Euler equations and the quaternion',
    wrench_samples=((0.0, 1.0 / 6.0), (0.5, 1.0 / 3.0), (0.5, 1.0 / 3.0), (1.0, 1.0 / 6.0)))

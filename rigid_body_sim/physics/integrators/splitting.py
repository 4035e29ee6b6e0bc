"""
Symplectic Lie-Poisson splitting of the free rigid body: `splitting` (2nd order), `splitting4`.

In the principal frame the kinetic energy is T = sum_i m_i^2 / (2 I_i), m the body angular
momentum in principal coordinates (McLachlan 1993; Touma & Wisdom 1994; Dullweber,
Leimkuhler & McLachlan, J. Chem. Phys. 107:5840, 1997).  The flow of each term alone is an
exact rotation about principal axis i at the constant rate m_i / I_i:

    R_p <- R_p exp(h m_i / I_i [e_i]x),   m <- exp(-h m_i / I_i [e_i]x) m,

with R_p = R P the principal-to-world rotation (P: principal axes in the body frame).  World
L = R_p m is untouched by construction, so every composition of these flows conserves world
L and |L| exactly (to round-off), and, being symplectic, keeps the energy error bounded.

`splitting` is the Strang composition 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2), axes numbered by
ascending moment: the largest moment in the middle, the smallest outside.  Of the six
orderings this one had the smallest orientation error on the benchmark bodies and on random
bodies (the axis of middle moment outside was the worst).

`splitting4` is Suzuki's five-stage fractal composition (Phys. Lett. A 146:319, 1990):
S(p h) S(p h) S((1 - 4p) h) S(p h) S(p h), p = 1 / (4 - 4^(1/3)), of the symmetric
second-order step S.  Yoshida's three-stage triple jump costs 3 instead of 5 stages, but its
large negative middle stage (-1.70 h) gives error constants far larger at equal step, so
at equal cost (equal number of stages) Suzuki's is still the more accurate on each of the
five benchmark bodies (test/test_splitting.py holds it to that).  Its base step puts the
middle moment in the middle, 1(h/2) 3(h/2) 2(h) 3(h/2) 1(h/2): the ordering that was best for
the composition (the `splitting` ordering was worse there).

Wrenches enter as kicks: kick(h/2) free flow(h) kick(h/2), so `splitting` is second order
with any wrench; `splitting4` composes that whole symmetric step and is fourth order for
wrenches that depend on the configuration and time.  For a momentum-dependent wrench the
kicks take the explicit midpoint rule, second order and not symmetric: the composition still
cancels the stage's h^3 term (its coefficients' cubes sum to zero), not the h^4 one, so
`splitting4` is then third order.

One free flow (:func:`free_flow`), composed with the kicks by :func:`step`.
"""

from __future__ import annotations

from collections.abc import Iterable
from collections.abc import Sequence
import math
from typing import Any

from .registry import KICK_STAGE
from .registry import register_integrator
from ..kernels import helper
from ..kernels import inline
from ..kernels import outlined
from ..kernels.algebra import conjugate
from ..kernels.algebra import normalised
from ..kernels.algebra import Quaternion
from ..kernels.algebra import quaternion_product
from ..kernels.algebra import rotate_back
from ..kernels.layout import BODY_FRAME
from ..kernels.layout import BODY_MASS
from ..kernels.layout import BODY_MOMENTS
from ..kernels.loop import MethodConstants
from ..kernels.loop import run_kernel
from ..kernels.loop import run_steps_specialised
from ..kernels.model import Array
from ..kernels.model import impulse
from ..kernels.model import Model
from ..kernels.model import NO_ESTIMATE

__all__ = ['STRANG_AXES', 'SUZUKI_AXES', 'SUZUKI_COEFFICIENTS', 'free_flow', 'splitting',
           'splitting4']

# Principal axes (0, 1, 2 by ascending moment) of the Strang step's outer, inner and central
# flows.
STRANG_AXES = (0, 1, 2)
SUZUKI_AXES = (0, 2, 1)
_SUZUKI_P = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))
SUZUKI_COEFFICIENTS = (_SUZUKI_P, _SUZUKI_P, 1.0 - 4.0 * _SUZUKI_P, _SUZUKI_P, _SUZUKI_P)
# The length of the method constants: three axes, a count, up to six stages.
_METHOD_SIZE = 10


@outlined
def free_flow(q: Quaternion, lx: float, ly: float, lz: float, moments: Array,
              frame: Quaternion, axes: MethodConstants, dt: float) -> Quaternion:
    """
    Return q after the torque-free Strang step of dt s (world L unchanged), as a 4-tuple.

    q: the orientation (body to world); L = (lx, ly, lz) world; moments: I1 <= I2 <= I3;
    frame: the principal frame's quaternion (4-tuple); axes: the principal axes (0, 1, 2 by
    ascending moment) of the outer, inner and central flows.  Each flow of m_i^2 / (2 I_i)
    turns q_p = q * frame about principal axis i by angle = duration m_i / I_i, and the
    other two components of m = R_p^T L back by the same angle, with one sin/cos pair of
    the half angle.  The turn about a coordinate axis is the Hamilton product with the
    sparse (half_sine e_i, half_cosine), written out per axis: half the products of the
    general one, in the one method that takes fifteen of them a step.
    """
    qp = quaternion_product(q, frame)
    m0, m1, m2 = rotate_back(normalised(qp), (lx, ly, lz))
    x, y, z, w = qp
    for flow in range(5):
        if flow == 2:
            axis, duration = axes[2], dt
        elif flow == 1 or flow == 3:
            axis, duration = axes[1], 0.5 * dt
        else:
            axis, duration = axes[0], 0.5 * dt
        if axis == 0:
            angle = duration * m0 / moments[0]
        elif axis == 1:
            angle = duration * m1 / moments[1]
        else:
            angle = duration * m2 / moments[2]
        half_sine, half_cosine = math.sin(0.5 * angle), math.cos(0.5 * angle)
        cosine = 1.0 - 2.0 * half_sine * half_sine
        sine = 2.0 * half_sine * half_cosine
        if axis == 0:
            m1, m2 = cosine * m1 + sine * m2, -sine * m1 + cosine * m2
            x, y, z, w = (w * half_sine + x * half_cosine, y * half_cosine + z * half_sine,
                          z * half_cosine - y * half_sine, w * half_cosine - x * half_sine)
        elif axis == 1:
            m2, m0 = cosine * m2 + sine * m0, -sine * m2 + cosine * m0
            x, y, z, w = (x * half_cosine - z * half_sine, w * half_sine + y * half_cosine,
                          z * half_cosine + x * half_sine, w * half_cosine - y * half_sine)
        else:
            m0, m1 = cosine * m0 + sine * m1, -sine * m0 + cosine * m1
            x, y, z, w = (x * half_cosine + y * half_sine, y * half_cosine - x * half_sine,
                          w * half_sine + z * half_cosine, w * half_cosine - z * half_sine)
    return normalised(quaternion_product((x, y, z, w), conjugate(frame)))


@helper
def _compensated_add(total: float, addend: float, compensation: float) -> tuple[float, float]:
    """Return (total + addend, new compensation): one step of Kahan summation."""
    corrected = addend - compensation
    result = total + corrected
    return result, (result - total) - corrected


@inline
def step(state: Array, forcing: Any, method: MethodConstants, dt: float, time: float,
         pushed: bool, translates: bool) -> None:
    """
    Take the splitting step on a packed state in place.

    method = (outer, inner, central axis, number of stages n, c_1 .. c_n, zeros up to
    :data:`_METHOD_SIZE`): one length for both methods, so one compiled kernel.

    Each stage c is kick(c h/2), free flow(c h), kick(c h/2).  Round-off: a step's kicks
    (two per stage, five stages for splitting4, one of them negative) and the COM's
    displacement are summed apart, small, and each added to its momentum or position once
    per step, with Kahan's compensation carried across the steps of a run (forcing.carry).
    Added stage by stage, each add rounded at |p| or |x| and a held force made the COM
    drift in proportion to the step count, beyond rk4's (docs/benchmark.md, "Round-off under
    a held force", has the figures: benchmarks/splitting4_round_off.py).
    """
    body = forcing.body
    mass = body[BODY_MASS]
    moments = body[BODY_MOMENTS:BODY_MOMENTS + 3]
    frame = (body[BODY_FRAME], body[BODY_FRAME + 1], body[BODY_FRAME + 2],
             body[BODY_FRAME + 3])
    axes = (int(method[0]), int(method[1]), int(method[2]))
    stages = int(method[3])
    q = (state[0], state[1], state[2], state[3])
    x0 = (state[4], state[5], state[6])
    p0 = (state[7], state[8], state[9])
    l0 = (state[10], state[11], state[12])
    sp = (0.0, 0.0, 0.0)
    sl = (0.0, 0.0, 0.0)
    dx = (0.0, 0.0, 0.0)
    p, angular = p0, l0
    stage_start = time
    stage_state = forcing.stage
    estimate = NO_ESTIMATE
    for index in range(4, 4 + stages):
        stage = method[index] * dt
        for kick_number in range(2):
            if kick_number == 1:
                q = free_flow(q, angular[0], angular[1], angular[2], moments, frame, axes,
                              stage)
                if translates:
                    dx = (dx[0] + stage * p[0] / mass, dx[1] + stage * p[1] / mass,
                          dx[2] + stage * p[2] / mass)
            if pushed:
                stage_state[0], stage_state[1], stage_state[2], stage_state[3] = q
                if forcing.reads_state:
                    # The effects read the stage's whole state.
                    for i in range(3):
                        stage_state[4 + i] = x0[i] + dx[i]
                        stage_state[7 + i] = p[i]
                        stage_state[10 + i] = angular[i]
                # A stage's closing kick starts from its opening one's estimate.
                change, estimate = impulse(stage_state, stage_start + kick_number * stage,
                                           0.5 * stage, forcing, estimate, kick_number == 1)
                sp = (sp[0] + change[0], sp[1] + change[1], sp[2] + change[2])
                sl = (sl[0] + change[3], sl[1] + change[4], sl[2] + change[5])
                p = (p0[0] + sp[0], p0[1] + sp[1], p0[2] + sp[2])
                angular = (l0[0] + sl[0], l0[1] + sl[1], l0[2] + sl[2])
        stage_start += stage
    carry = forcing.carry
    if pushed:
        for i in range(3):
            state[7 + i], carry[i] = _compensated_add(p0[i], sp[i], carry[i])
            state[10 + i], carry[3 + i] = _compensated_add(l0[i], sl[i], carry[3 + i])
    if translates:
        for i in range(3):
            state[4 + i], carry[6 + i] = _compensated_add(x0[i], dx[i], carry[6 + i])
    state[0], state[1], state[2], state[3] = q


@run_kernel(compile_seconds=8.0)
def run(state: Array, model: Model, method: MethodConstants, dt: float, steps: int,
        time: float) -> int:
    """Take `steps` splitting steps of dt s from `time` (kernels/loop.py)."""
    return run_steps_specialised(step, state, model, method, dt, steps, time)


def _method(axes: Iterable[float], coefficients: Sequence[float]) -> MethodConstants:
    """Return the method constants of a composition of Strang steps (see :func:`step`)."""
    constants = tuple(axes) + (len(coefficients),) + tuple(coefficients)
    return tuple(float(value) for value in constants) + (0.0,) * (_METHOD_SIZE - len(constants))


splitting = register_integrator(
    'splitting', order=2, run=run, method=_method(STRANG_AXES, KICK_STAGE), kicks=KICK_STAGE,
    conserves=('angular_momentum',),
    summary='symplectic Strang splitting of the free body into exact rotations about the '
            'principal axes, 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2)')
splitting4 = register_integrator(
    'splitting4', order=4, run=run, method=_method(SUZUKI_AXES, SUZUKI_COEFFICIENTS),
    kicks=SUZUKI_COEFFICIENTS, conserves=('angular_momentum',), momentum_dependent_order=3,
    summary="Suzuki's fourth-order five-stage composition of the kicked Strang step")

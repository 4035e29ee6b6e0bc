"""
The one run loop of every integrator's kernel: flows around each step, the step's time.

Each integrator writes one compiled step,

    step(state, forcing, method, dt, time, pushed, translates)

that advances the packed state in place by dt s from `time` (s) under the forcing (the
model's fields, unpacked once per call: :class:`.model.Forcing`); `method` holds the
integrator's constants; `pushed` says that a wrench may act (some term, or a held wrench
that is not zero), `translates` that the position moves (pushed, or p is not zero);
``forcing.carry`` holds what a step hands to the next (zero at the start of each call).
The step and everything it calls on the forcing are inlined (kernels.inline): one function,
in which the compiler keeps the forcing in registers.  Its kernel is then two lines (see
integrators/buss.py):

    run(state, model, method, dt, steps, time)          = run_steps(step, ...)
    controlled(state, model, method, tick, ticks, time, control)
                                                        = controlled_ticks(run, ...)

numba compiles each once, for the one type of a Model, and caches it.
"""

import math

from . import inline
from .borrow import borrowed
from .layout import STATE_SIZE
from .model import apply_flows
from .model import unpacked

__all__ = ['run_steps']


@inline
def run_steps(step, state, model, method, dt, steps, time):
    """
    Take `steps` steps of dt s from `time` (s) on the packed state, in place.

    Each is flow(dt/2), step(dt), flow(dt/2) with the model's flows (Strang: second order,
    world L untouched by a dissipation flow); without flows, the steps alone.  The k-th step
    starts at time + k dt (a product, not a running sum: no drift over long runs).  Returns
    the number of integrator steps taken, or -1 if the state ended with a value that is not
    finite (the Simulator then keeps the last finite state and says so; tested here, the
    check costs a few ns, where one in Python cost a tenth of a step() call).
    """
    forcing = unpacked(model)
    state = borrowed(state)
    pushed = forcing.term_count > 0 or forcing.holding
    translates = pushed or state[7] != 0.0 or state[8] != 0.0 or state[9] != 0.0
    # The low bits a step hands the next (splitting's Kahan sums): each call starts afresh.
    forcing.carry[:] = 0.0
    # Two copies of the loop, in which `pushed` is a constant: the torque-free one carries no
    # kick code at all (its registers are the step's alone: 2 ns of Buss's 47 ns step).
    if pushed:
        _steps(step, state, forcing, method, dt, steps, time, True, translates)
    else:
        _steps(step, state, forcing, method, dt, steps, time, False, translates)
    for i in range(STATE_SIZE):
        if not math.isfinite(state[i]):
            return -1
    return steps


@inline
def _steps(step, state, forcing, method, dt, steps, time, pushed, translates):
    """Take the steps of :func:`run_steps` with `pushed` a constant (see there)."""
    flowing = forcing.flow_count > 0
    half = 0.5 * dt
    for k in range(steps):
        if flowing:
            apply_flows(state, forcing, half, False)
        step(state, forcing, method, dt, time + k * dt, pushed, translates)
        if flowing:
            apply_flows(state, forcing, half, True)

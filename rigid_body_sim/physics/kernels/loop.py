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
integrators/buss.py), declared with the CPU seconds it takes to compile:

    @run_kernel(compile_seconds=10.0)
    def run(state, model, method, dt, steps, time):
        return run_steps(step, ...)

Every run kernel has the one signature :data:`RUN_SIGNATURE` (`method` padded to
:data:`METHOD_SIZE` constants), so that the error controller, compiled once, takes any of
them as a first-class function (error_control.controlled).  numba compiles each on first
use and caches it.
"""

from __future__ import annotations

from collections.abc import Callable
from collections.abc import Iterable
import math
from typing import Any

from numba import types
import numpy as np
from numpy.typing import NDArray

from . import inline
from . import LazyKernel
from .borrow import borrowed
from .layout import STATE_SIZE
from .model import apply_flows
from .model import Model
from .model import MODEL_TYPE
from .model import unpacked

__all__ = ['run_steps', 'run_steps_specialised', 'run_kernel', 'method_constants',
           'METHOD_SIZE', 'METHOD_TYPE', 'RUN_SIGNATURE']

METHOD_SIZE = 10
"""Constants of a method a run kernel takes (zeros past the method's own): the largest is
the fourth-order splitting's (3 axes, its stage count and 5 coefficients)."""
METHOD_TYPE = types.UniTuple(types.float64, METHOD_SIZE)
"""numba's type of the method constants: a tuple, passed by value, so that the compiler knows
them constant over the loop and hoists what it computes from them (an array it must read
again after each store to the state)."""
MethodConstants = tuple[float, ...]
"""The annotations' type of a method's constants: METHOD_SIZE floats."""
RUN_SIGNATURE = types.int64(types.float64[::1], MODEL_TYPE, METHOD_TYPE, types.float64,
                            types.int64, types.float64)
"""run(state, model, method, dt, steps, time) -> steps taken, or -1 (see run_steps)."""


def run_kernel(compile_seconds: float) -> Callable[[Callable[..., int]], LazyKernel]:
    """
    Declare an integrator's run kernel: compiled for :data:`RUN_SIGNATURE` on first use.

    compile_seconds: the CPU seconds it takes to compile on the 2-core development machine
    (``rigid-body-sim compile`` prints each job's figure), the estimate where this machine
    has not compiled it yet (physics/warm_up.py).
    """
    def declare(function: Callable[..., int]) -> LazyKernel:
        return LazyKernel(RUN_SIGNATURE, function, compile_seconds=compile_seconds)
    return declare


def method_constants(values: Iterable[float] = ()) -> MethodConstants:
    """Return a method's constants as the run kernels take them (padded with zeros)."""
    values = tuple(float(value) for value in values)
    if len(values) > METHOD_SIZE:
        raise ValueError(f'a method has at most {METHOD_SIZE} constants; got {len(values)}')
    return values + (0.0,) * (METHOD_SIZE - len(values))


@inline
def run_steps(step: Callable[..., None], state: NDArray[np.float64], model: Model,
              method: MethodConstants, dt: float, steps: int, time: float) -> int:
    """
    Take `steps` steps of dt s from `time` (s) on the packed state, in place.

    Each is flow(dt/2), step(dt), flow(dt/2) with the model's flows (Strang: second order,
    world L untouched by a dissipation flow); without flows, the steps alone.  The k-th step
    starts at time + k dt (a product, not a running sum: no drift over long runs).  Returns
    the number of integrator steps taken, or -1 if the state ended with a value that is not
    finite (the Simulator then keeps the last finite state and says so; tested here, the
    check costs a few ns, where one in Python cost a tenth of a step() call).

    One loop, `pushed` a value tested in it: LLVM keeps the torque-free path as fast as a
    loop of its own for the kick-drift-kick methods (buss, exact, the splittings), and numba
    compiles the step once (see :func:`run_steps_specialised` for the others).
    """
    forcing, state, pushed, translates = _start(state, model)
    _steps(step, state, forcing, method, dt, steps, time, pushed, translates)
    return _finish(state, steps)


@inline
def run_steps_specialised(step: Callable[..., None], state: NDArray[np.float64], model: Model,
                          method: MethodConstants, dt: float, steps: int, time: float) -> int:
    """
    Take the steps of :func:`run_steps` in two copies of the loop, `pushed` a constant in each.

    numba compiles the step twice (it does not drop the torque-free copy's kick code before
    LLVM does), for the methods whose torque-free step LLVM does not separate from the
    wrench in one loop (first_order, rk4: slower torque-free in one loop).
    """
    forcing, state, pushed, translates = _start(state, model)
    if pushed:
        _steps(step, state, forcing, method, dt, steps, time, True, translates)
    else:
        _steps(step, state, forcing, method, dt, steps, time, False, translates)
    return _finish(state, steps)


@inline
def _start(state: NDArray[np.float64],
           model: Model) -> tuple[Any, NDArray[np.float64], bool, bool]:
    """Return (forcing, the state borrowed, pushed, translates) at the start of a run."""
    forcing = unpacked(model)
    state = borrowed(state)
    pushed = forcing.term_count > 0 or forcing.holding
    translates = pushed or state[7] != 0.0 or state[8] != 0.0 or state[9] != 0.0
    # The low bits a step hands the next (splitting's Kahan sums): each call starts afresh.
    forcing.carry[:] = 0.0
    return forcing, state, pushed, translates


@inline
def _finish(state: NDArray[np.float64], steps: int) -> int:
    """Return `steps`, or -1 if the state holds a value that is not finite."""
    for i in range(STATE_SIZE):
        if not math.isfinite(state[i]):
            return -1
    return steps


@inline
def _steps(step: Callable[..., None], state: NDArray[np.float64], forcing: Any,
           method: MethodConstants, dt: float, steps: int, time: float, pushed: bool,
           translates: bool) -> None:
    """Take the steps of :func:`run_steps` (`pushed` a value, or a constant in each copy)."""
    flowing = forcing.flow_count > 0
    half = 0.5 * dt
    for k in range(steps):
        if flowing:
            apply_flows(state, forcing, half, False)
        step(state, forcing, method, dt, time + k * dt, pushed, translates)
        if flowing:
            apply_flows(state, forcing, half, True)

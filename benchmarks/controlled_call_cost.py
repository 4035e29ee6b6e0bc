#!/usr/bin/env python3
"""
What one call of the compiled error controller costs the node's tick, against a fixed step.

The node calls ``Simulator.step`` once a tick.  Under error control that is one call of the
compiled controller (``physics/error_control.py``'s ``controlled``), which reaches the
integrator's run kernel through a ``Controller`` built once per integrator; with a fixed
step, one call of the run kernel.  This script times, in CPU time (``time.process_time``,
the median of three timings), side by side in one process, on the default scene at a 1 kHz
tick:

- ``Simulator.step`` under the scene's error control and with one fixed step, and their
  ratio (error control / fixed);
- the physics of a controlled tick alone: the controller taking 1000 ticks in one call, per
  tick;
- the per-call overhead: the controller called with 0 ticks (its call alone), given the
  Controller (as the Simulator calls it), and given the run kernel as a first-class
  function argument, the way it took it before the Controller (a kernel compiled here,
  calling the same controller): numba unboxes such an argument, typing it and resolving
  its compiled address, on every call; beside them the run kernel called for 0 steps (the
  fixed step's call alone);
- whether 200 ticks taken either way leave the same bits.

It reads the Simulator's private attributes (the kernels it calls): a measurement of the
code at one commit, not an API.  The results are in docs/node.md ("The node against a bare
rclpy loop").

Usage: ``.venv/bin/python benchmarks/controlled_call_cost.py [--calls 20000]``
"""

import argparse
from pathlib import Path
import sys
import time

import numba
from numba.core import types
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rigid_body_sim.physics import error_control  # noqa: E402
from rigid_body_sim.physics.error_control import CONTROLLED_SIGNATURE  # noqa: E402
from rigid_body_sim.physics.error_control import Controller  # noqa: E402
from rigid_body_sim.physics.kernels.loop import RUN_SIGNATURE  # noqa: E402
from rigid_body_sim.physics.warm_up import load_kernels  # noqa: E402
from rigid_body_sim.scenes import load_scene  # noqa: E402

TICK = 1e-3  # s: the node at 1 kHz


def run_as_argument():
    """Return the controller as it was called before: the run a first-class argument."""
    controlled = error_control.controlled.dispatcher
    signature = types.int64(types.FunctionType(RUN_SIGNATURE), *CONTROLLED_SIGNATURE.args[1:])

    @numba.njit(signature)
    def controlled_run(run, state, model, method, tick, ticks, time, control):
        return controlled(Controller(run), state, model, method, tick, ticks, time, control)
    return controlled_run


def microseconds(call, arguments, calls):
    """Return the CPU time of one call in us, the median of three timings of `calls`."""
    call(*arguments)
    timings = []
    for _ in range(3):
        started = time.process_time()
        for _ in range(calls):
            call(*arguments)
        timings.append(1e6 * (time.process_time() - started) / calls)
    return sorted(timings)[1]


def main(argv=None):
    """Print the costs listed in the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--calls', type=int, default=20000, help='calls per timing')
    calls = parser.parse_args(argv).calls
    scene = load_scene('default')
    load_kernels(scene.integrator)
    controlled = scene.simulator()
    fixed = scene.simulator(tolerance=0.0)
    controlled.step(TICK)  # the kernels fetched
    fixed.step(TICK)
    print(f'default scene: {scene.integrator}, error control at {controlled.tolerance:g} '
          f'rad/s, a tick of {1e3 * TICK:g} ms; CPU time per call (us), median of 3')
    kernel, controller = controlled._controlled_kernel, controlled._controller
    run = controlled._run
    old_way = run_as_argument()

    def arguments(handle, ticks):
        return (handle, controlled._values, controlled._model, controlled._integrator.method,
                TICK, ticks, controlled.time, controlled._control)
    step_controlled = microseconds(controlled.step, (TICK,), calls)
    step_fixed = microseconds(fixed.step, (TICK,), calls)
    rows = [
        ('Simulator.step, error control', step_controlled),
        ('Simulator.step, one fixed step', step_fixed),
        ('controller, 0 ticks, given the Controller',
         microseconds(kernel, arguments(controller, 0), calls)),
        ('controller, 0 ticks, given the run as an argument',
         microseconds(old_way, arguments(run, 0), calls)),
        ('run kernel, 0 steps', microseconds(
            run, (fixed._values, fixed._model, fixed._integrator.method, TICK, 0, fixed.time),
            calls)),
    ]
    for label, cost in rows:
        print(f'{label:52s} {cost:8.2f}')
    per_call = microseconds(kernel, arguments(controller, 1000), max(1, calls // 400))
    print(f'{"the physics of one tick (1000 ticks in one call)":52s} {per_call / 1000:8.2f}')
    print(f'{"ratio Simulator.step, error control / fixed":52s} '
          f'{step_controlled / step_fixed:8.2f}')
    states = [controlled._values.copy(), controlled._values.copy()]
    controls = [controlled._control.copy(), controlled._control.copy()]
    for tick in range(200):
        for index, (call, handle) in enumerate(((kernel, controller), (old_way, run))):
            call(handle, states[index], controlled._model, controlled._integrator.method,
                 TICK, 1, tick * TICK, controls[index])
    same = np.array_equal(*states) and np.array_equal(*controls)
    print(f'200 ticks either way: the same bits: {same}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

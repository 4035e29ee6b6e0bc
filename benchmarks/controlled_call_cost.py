#!/usr/bin/env python3
"""
What one call of the compiled error controller costs the node's tick, and where it goes.

The node calls ``Simulator.step`` once a tick.  Under error control that is one call of the
compiled controller (``physics/error_control.py``'s ``controlled``), which takes the
integrator's run kernel as a first-class function argument.  This script times, in CPU time
(``time.process_time``), on the default scene at a 1 kHz tick:

- ``Simulator.step`` under the scene's error control, and with one fixed step;
- the physics of a tick alone: the controller taking 1000 ticks in one call, per tick;
- the controller called with 0 ticks (its call alone): through its dispatcher, through its
  compiled entry point (no typing of the arguments), and numba's resolution of the run
  kernel's address (``_get_wrapper_address``) by itself;
- the same call with the run kernel passed as an object that keeps its address (numba's
  ``WrapperAddressProtocol``), and whether 200 ticks so taken leave the same bits.

It reads the Simulator's private attributes (the kernels it calls): a measurement of the
code at one commit, not an API.  The results are in docs/node.md ("The node against a bare
rclpy loop").

Usage: ``.venv/bin/python benchmarks/controlled_call_cost.py [--calls 20000]``
"""

import argparse
from pathlib import Path
import sys
import time

from numba.core import types
from numba.experimental.function_type import _get_wrapper_address
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rigid_body_sim.physics.kernels.loop import RUN_SIGNATURE  # noqa: E402
from rigid_body_sim.physics.warm_up import load_kernels  # noqa: E402
from rigid_body_sim.scenes import load_scene  # noqa: E402

TICK = 1e-3  # s: the node at 1 kHz


class RunAddress(types.WrapperAddressProtocol):
    """A run kernel as numba's first-class function protocol, its address resolved once."""

    def __init__(self, dispatcher):
        self._address = _get_wrapper_address(dispatcher, RUN_SIGNATURE)

    def __wrapper_address__(self):
        """Return the compiled run's address (resolved at construction)."""
        return self._address

    def signature(self):
        """Return the run kernel's signature."""
        return RUN_SIGNATURE


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
    print(f'default scene: {scene.integrator}, error control at {controlled.tolerance:g} '
          f'rad/s, a tick of {1e3 * TICK:g} ms; CPU time per call (us)')
    controller, run = controlled._controller, controlled._controlled_run

    def arguments(run, ticks):
        return (run, controlled._values, controlled._model, controlled._integrator.method,
                TICK, ticks, controlled.time, controlled._control)
    address = RunAddress(run)
    rows = [
        ('Simulator.step, error control', controlled.step, (TICK,)),
        ('Simulator.step, one fixed step', fixed.step, (TICK,)),
        ('controller, 0 ticks, through its dispatcher', controller, arguments(run, 0)),
        ('controller, 0 ticks, its entry point (no typing)',
         controller.overloads[controller.signatures[0]].entry_point, arguments(run, 0)),
        ("numba's _get_wrapper_address(run) alone", _get_wrapper_address,
         (run, RUN_SIGNATURE)),
        ('controller, 0 ticks, the run by its kept address', controller,
         arguments(address, 0)),
    ]
    for label, call, passed in rows:
        print(f'{label:50s} {microseconds(call, passed, calls):8.2f}')
    per_call = microseconds(controller, arguments(run, 1000), max(1, calls // 400))
    print(f'{"the physics of one tick (1000 ticks in one call)":50s} {per_call / 1000:8.2f}')
    states = [controlled._values.copy(), controlled._values.copy()]
    controls = [controlled._control.copy(), controlled._control.copy()]
    for tick in range(200):
        for index, passed in enumerate((run, address)):
            controller(passed, states[index], controlled._model, controlled._integrator.method,
                       TICK, 1, tick * TICK, controls[index])
    same = np.array_equal(*states) and np.array_equal(*controls)
    print(f'200 ticks through either: the same bits: {same}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

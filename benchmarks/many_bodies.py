#!/usr/bin/env python3
"""
What a body-step costs in a World of N bodies, against the single body's kernel.

A World (physics/world.py) advances all its bodies in one compiled call a tick, each by
the kernels its own Simulator calls.  This script times, in CPU time
(``time.process_time``), side by side in one process, the median of three rounds in which
each contender is timed in turn:

- world: ``World.step(dt)`` of the first N bodies of the constellation scene (1,000
  cubesats tumbling torque-free at 100 Hz), per body-step: the CPU of the tick / N;
- kernel: the single body's kernel taking many ticks in one call (its loop, no call per
  tick), per tick, for a sample of the same bodies: what a tick costs at the least;
- tick call: the same kernel called once a tick, from a compiled loop, the state copied
  first as Simulator.step copies it (to restore, should it turn non-finite): a single
  body's tick as Simulator.step takes it without the Python around it, the call's set-up
  included (reading the model's fields, checking the state it leaves);
- Simulator.step: each body's own Simulator stepped from Python once a tick, per
  body-step: what N one-body simulations cost;

at N = 1, 10, 100, 1,000, with one fixed step a tick (the scene's) and under error
control (--tolerance, each body its own substeps; the kernel there is the controller).
The goal (issue 29): the world's body-step at most 1.2x the single body's kernel step at
N = 1,000; both readings of "the kernel's step" are printed.
It also checks that 200 ticks of the world leave every body with the bits of the same body
simulated alone (Simulator.step).

Usage: ``.venv/bin/python benchmarks/many_bodies.py [--integrator buss] [--json FILE]``
"""

import argparse
import json
from pathlib import Path
import sys
import time

import numba
from numba import types
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rigid_body_sim.physics import get_integrator  # noqa: E402
from rigid_body_sim.physics import World  # noqa: E402
from rigid_body_sim.physics.error_control import CONTROLLED_SIGNATURE  # noqa: E402
from rigid_body_sim.physics.kernels.loop import RUN_SIGNATURE  # noqa: E402
from rigid_body_sim.physics.warm_up import load_kernels  # noqa: E402
from rigid_body_sim.scenes import load_scene  # noqa: E402

COUNTS = (1, 10, 100, 1000)
BODY_STEPS = 200_000  # per timing of the world
SAMPLE = 20  # bodies whose kernel is timed alone
REFERENCE_TICKS = 20_000  # ticks per timing of one body's kernel (its set-up amortised)


@numba.njit(types.int64(types.FunctionType(RUN_SIGNATURE), *RUN_SIGNATURE.args[:4],
                        types.int64))
def _run_tick_by_tick(run, state, model, method, tick, ticks):
    checkpoint = np.empty_like(state)
    taken = 0
    for index in range(ticks):
        checkpoint[:] = state
        taken += run(state, model, method, tick, 1, index * tick)
    return taken


@numba.njit(types.int64(types.FunctionType(CONTROLLED_SIGNATURE), *CONTROLLED_SIGNATURE.args[:5],
                        types.int64, CONTROLLED_SIGNATURE.args[7]))
def _controlled_tick_by_tick(controlled, controller, state, model, method, tick, ticks, control):
    checkpoint = np.empty_like(state)
    taken = 0
    for index in range(ticks):
        checkpoint[:] = state
        taken += controlled(controller, state, model, method, tick, 1, index * tick, control)
    return taken


def _cpu(call, repeats):
    started = time.process_time()
    for _ in range(repeats):
        call()
    return time.process_time() - started


def measure(scene, integrator, tolerance, rounds=3):
    """Return {N: {world, kernel, simulator} ns per body-step} (medians of `rounds`)."""
    members = scene.members
    dt = scene.dt
    results = {}
    for count in COUNTS:
        chosen = members[:count]
        world = World(((m.name, m.simulator()) for m in chosen), integrator=integrator,
                      tolerance=tolerance)
        simulators = [m.simulator(integrator=integrator, tolerance=tolerance or 0.0)
                      for m in chosen]
        world.step(dt)
        for simulator in simulators:
            simulator.step(dt)
        ticks = max(20, BODY_STEPS // count)
        sample = chosen[:SAMPLE]
        # The kernel alone: one call takes `ticks` ticks of one body.
        alone = [m.simulator(integrator=integrator, tolerance=tolerance or 0.0)
                 for m in sample]
        kernel_calls, tick_calls = [], []
        for simulator in alone:
            simulator.step(dt)
            values, model, control = simulator.kernel_arguments()
            controller, run, controlled = simulator.stepping_kernels()
            method = get_integrator(integrator).method
            if tolerance:
                kernel_calls.append(lambda c=controlled, k=controller, v=values, m=model,
                                    n=control: c(k, v, m, method, dt, REFERENCE_TICKS, 1.0, n))
                tick_calls.append(lambda c=controlled, k=controller, v=values, m=model,
                                  n=control: _controlled_tick_by_tick(c, k, v, m, method, dt,
                                                                      REFERENCE_TICKS, n))
            else:
                kernel_calls.append(lambda r=run, v=values, m=model: r(
                    v, m, method, dt, REFERENCE_TICKS, 1.0))
                tick_calls.append(lambda r=run, v=values, m=model: _run_tick_by_tick(
                    r, v, m, method, dt, REFERENCE_TICKS))
        rounds_world, rounds_kernel, rounds_tick, rounds_simulator = [], [], [], []
        simulator_ticks = max(5, ticks // 20)
        for _ in range(rounds):
            rounds_world.append(_cpu(lambda: world.step(dt), ticks) / (ticks * count))
            kernel = sum(_cpu(call, 1) for call in kernel_calls)
            rounds_kernel.append(kernel / (REFERENCE_TICKS * len(kernel_calls)))
            by_tick = sum(_cpu(call, 1) for call in tick_calls)
            rounds_tick.append(by_tick / (REFERENCE_TICKS * len(tick_calls)))

            def step_each():
                for simulator in simulators:
                    simulator.step(dt)
            rounds_simulator.append(_cpu(step_each, simulator_ticks)
                                    / (simulator_ticks * count))
        results[count] = {'world': 1e9 * float(np.median(rounds_world)),
                          'kernel': 1e9 * float(np.median(rounds_kernel)),
                          'tick_call': 1e9 * float(np.median(rounds_tick)),
                          'simulator': 1e9 * float(np.median(rounds_simulator))}
    return results


def same_bits(scene, integrator, tolerance, count=100, ticks=200):
    """Return True if `ticks` ticks of a World leave each body as it is alone."""
    chosen = scene.members[:count]
    world = World(((m.name, m.simulator()) for m in chosen), integrator=integrator,
                  tolerance=tolerance)
    alone = [m.simulator(integrator=integrator, tolerance=tolerance or 0.0) for m in chosen]
    for _ in range(ticks):
        world.step(scene.dt)
        for simulator in alone:
            simulator.step(scene.dt)
    return all(np.array_equal(world.simulator(m.name).kernel_arguments()[0],
                              simulator.kernel_arguments()[0])
               for m, simulator in zip(chosen, alone))


def main(argv=None):
    """Print the table; --json writes the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--integrator', default='buss', help='integrator (default buss)')
    parser.add_argument('--tolerance', type=float, default=1e-6,
                        help='error control of the second table, rad/s (default 1e-6)')
    parser.add_argument('--json', type=Path, help='also write the figures to this file')
    arguments = parser.parse_args(argv)
    scene = load_scene('constellation')
    load_kernels(arguments.integrator)
    figures = {'integrator': arguments.integrator, 'scene': scene.name, 'rate': scene.rate}
    for label, tolerance in (('fixed step', None), ('error control', arguments.tolerance)):
        results = measure(scene, arguments.integrator, tolerance)
        same = same_bits(scene, arguments.integrator, tolerance)
        print(f'{scene.name}: {arguments.integrator}, {label}'
              + (f' at {tolerance:g} rad/s' if tolerance else ', one step a tick')
              + '; CPU ns per body-step, median of 3')
        print(f'{"N":>6} {"world":>8} {"kernel":>8} {"tick call":>10} {"world/kernel":>13} '
              f'{"world/tick call":>16} {"Simulator.step":>15} {"its/world":>10}')
        for count, row in results.items():
            print(f'{count:6d} {row["world"]:8.1f} {row["kernel"]:8.1f} '
                  f'{row["tick_call"]:10.1f} {row["world"] / row["kernel"]:13.2f} '
                  f'{row["world"] / row["tick_call"]:16.2f} {row["simulator"]:15.1f} '
                  f'{row["simulator"] / row["world"]:10.1f}')
        print(f'200 ticks of 100 bodies in a World, each the bits of it alone: {same}')
        figures[label] = {'tolerance': tolerance, 'same_bits': same,
                          'per_body_step_ns': {str(k): v for k, v in results.items()}}
    if arguments.json:
        arguments.json.write_text(json.dumps(figures, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""
Print the CPU time per step of each integrator: in one Simulator.run and per step() call.

Usage: .venv/bin/python benchmarks/step_cost.py [--steps N] [--repeats K] [NAME ...]

Each integrator runs the default T-handle body torque-free, and again under a held
body-frame torque, after a warm-up run (so numba compilation is not counted).  Times are
CPU time of this process (time.process_time, not wall-clock: the machine may be loaded),
the median over K repeats, in microseconds per step:

- run: N steps in one Simulator.run call (the offline tools, the benchmark);
- step(): one Simulator.step call per step, as the node ticks (N / 10 calls).

NAME ... limits the table to those integrators (default: all).
"""

import argparse
import statistics
import time

from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import Simulator
from rigid_body_sim.scenes import load_scene

DT = 1e-3


def _simulator(name, torque):
    scene = load_scene('default')
    simulator = Simulator(scene.body, scene.state, integrator=name)
    if torque:
        simulator.set_wrench(torque=[0.01, 0.0, 0.02], frame='body')
    return simulator


def microseconds_per_step(name, steps, repeats, torque, per_call):
    """Return the median CPU us/step of `name` over `repeats` timed runs of `steps` steps."""
    simulator = _simulator(name, torque)
    simulator.run(min(steps, 1000) * DT, DT)
    samples = []
    for _ in range(repeats):
        started = time.process_time()
        if per_call:
            for _ in range(steps):
                simulator.step(DT)
        else:
            simulator.run(steps * DT, DT)
        samples.append((time.process_time() - started) / steps * 1e6)
    return statistics.median(samples)


def main():
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=200000)
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('names', nargs='*', metavar='NAME',
                        help='integrators to time (default: all)')
    args = parser.parse_args()
    unknown = sorted(set(args.names) - set(INTEGRATORS))
    if unknown:
        parser.error(f'unknown integrator(s) {", ".join(unknown)}; valid: '
                     f'{", ".join(sorted(INTEGRATORS))}')
    columns = (('run', False), ('step()', True))
    header = ''.join(f'{f"{label}, {kind}":>17}' for label, _ in columns
                     for kind in ('free', 'torque'))
    print(f'{"integrator":<12}{header}   (CPU us/step, median of {args.repeats})')
    for name in args.names or sorted(INTEGRATORS):
        row = []
        for _, per_call in columns:
            steps = max(args.steps // 10, 1000) if per_call else args.steps
            for torque in (False, True):
                cost = microseconds_per_step(name, steps, args.repeats, torque, per_call)
                row.append(f'{cost:.3f}')
        print(f'{name:<12}' + ''.join(f'{cell:>17}' for cell in row))


if __name__ == '__main__':
    main()

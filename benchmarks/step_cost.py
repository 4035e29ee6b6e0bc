#!/usr/bin/env python3
"""
Print the time per step of each integrator inside Simulator.run (median of repeats).

Usage: .venv/bin/python benchmarks/step_cost.py [--steps N] [--repeats K]

Each integrator runs the default T-handle body torque-free, and again under a held
body-frame torque, for N steps per repeat after a warm-up run (so numba compilation is not
counted); the median over K repeats is printed in microseconds per step, for the fast
(compiled) path and for the readable reference definitions.
"""

import argparse
import statistics
import time

from rigid_body_sim.physics import FAST_KERNELS
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import Simulator
from rigid_body_sim.scenes import load_scene


def microseconds_per_step(name, steps, repeats, fast, torque):
    """Return the median us/step of `name` over `repeats` runs of `steps` steps."""
    scene = load_scene('default')
    simulator = Simulator(scene.body, scene.state, integrator=name, fast=fast)
    if torque:
        simulator.set_wrench(torque=[0.01, 0.0, 0.02], frame='body')
    dt = 1e-3
    simulator.run(min(steps, 1000) * dt, dt)
    samples = []
    for _ in range(repeats):
        started = time.perf_counter()
        simulator.run(steps * dt, dt)
        samples.append((time.perf_counter() - started) / steps * 1e6)
    return statistics.median(samples)


def main():
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=200000)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()
    print(f'{"integrator":<12} {"fast, free":>11} {"fast, torque":>13} '
          f'{"readable, free":>15} {"readable, torque":>17}   (us/step, median of '
          f'{args.repeats})')
    for name in sorted(INTEGRATORS):
        row = []
        for fast in (True, False):
            steps = args.steps if fast else max(args.steps // 100, 200)
            for torque in (False, True):
                if fast and name not in FAST_KERNELS:
                    row.append('n/a')
                    continue
                row.append(f'{microseconds_per_step(name, steps, args.repeats, fast, torque):.3f}')
        print(f'{name:<12} {row[0]:>11} {row[1]:>13} {row[2]:>15} {row[3]:>17}')


if __name__ == '__main__':
    main()

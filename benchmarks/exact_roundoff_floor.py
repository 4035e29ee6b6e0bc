#!/usr/bin/env python3
"""
Measure the round-off floor of the exact integrator: what no double-precision stepper can beat.

For a benchmark body and each step dt, over 10 s (N = 10/dt steps), against the torque-free
motion integrated in 30-digit decimals (test/taylor_reference.py, independent of the package):

- floor: the ideal stepper, the exact flow in decimals with the quaternion rounded to double
  after every step (L is constant and exact): any stepper that stores (q, L) in double
  rounds at least this much;
- exact: the package's ``exact`` integrator in Simulator.run (the fast path the benchmark,
  node and tools use);
- sensitivity: how far R(10 s) moves when q0 is changed by one ulp (of 0.5) per component.

Start 0 is the benchmark's; starts 1.. change q0 by -1, 0 or +1 ulp (of its size, at least
0.5) per component: other rounding sequences of the same motion, each with its own
reference.  Prints the error (rad) at start 0, and the median and largest over the starts.

Usage: ``.venv/bin/python benchmarks/exact_roundoff_floor.py [--body van_zon] [--dts 0.1 0.01]
[--starts 8]``.  The ideal stepper's decimal arithmetic takes most of the time, in proportion
to the starts times the steps: a run with ``--starts 1`` at the coarsest dt shows what the
finer ones will take.
"""

import argparse
from decimal import Decimal
from pathlib import Path
import statistics
import sys

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'test'))

from rigid_body_sim.physics import Simulator  # noqa: E402
from rigid_body_sim.physics import State  # noqa: E402
from rigid_body_sim.work_precision.bodies import benchmark_cases  # noqa: E402
from taylor_reference import angle_to_reference  # noqa: E402
from taylor_reference import reference_orientations  # noqa: E402
from taylor_reference import rounded_flow_steps  # noqa: E402

DURATION = 10.0


def starts(state, count, rng):
    """Return `count` initial quaternions: the state's, then 1-ulp changes of it."""
    quaternions = [np.array(state.quaternion, dtype=float)]
    for _ in range(count - 1):
        q = quaternions[0].copy()
        for i in range(4):
            q[i] += rng.integers(-1, 2) * np.spacing(max(abs(q[i]), 0.5))
        quaternions.append(q)
    return quaternions


def summary(errors):
    """Format errors as 'start 0, median, largest'."""
    return (f'{errors[0]:.2e} (median {statistics.median(errors):.2e}, '
            f'largest {max(errors):.2e})')


def main():
    """Print the floor and the errors of exact for each step."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--body', default='van_zon', help='benchmark body (default van_zon)')
    parser.add_argument('--dts', type=float, nargs='+', default=[0.1, 0.01, 0.001])
    parser.add_argument('--starts', type=int, default=8)
    args = parser.parse_args()
    case = benchmark_cases((args.body,))[0]
    body, momentum = case.body, np.array(case.state.angular_momentum)
    quaternions = starts(case.state, args.starts, np.random.default_rng(7))
    print(f'{args.body}: errors (rad) at {DURATION:g} s, start 0 and over {args.starts} starts')
    end = reference_orientations(body, case.state, [Decimal(DURATION)])[0]
    moved = [angle_to_reference(reference_orientations(
        body, State(q, angular_momentum=momentum), [Decimal(DURATION)])[0], end)
        for q in quaternions[1:]]
    if moved:
        print(f'  sensitivity to 1 ulp of q0: median {statistics.median(moved):.2e}, '
              f'largest {max(moved):.2e}')
    for dt in args.dts:
        steps = int(round(DURATION / dt))
        floor, exact = [], []
        for q in quaternions:
            state = State(q, angular_momentum=momentum)
            expected = reference_orientations(body, state, [Decimal(dt) * steps])[0]
            floor.append(angle_to_reference(rounded_flow_steps(body, state, dt, steps),
                                            expected))
            simulator = Simulator(body, state, integrator='exact')
            simulator.run(steps * dt, dt)
            exact.append(angle_to_reference(simulator.state.quaternion, expected))
        print(f'  dt = {dt:g} s: floor {summary(floor)}; exact {summary(exact)}', flush=True)


if __name__ == '__main__':
    main()

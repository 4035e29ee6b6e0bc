"""
Simulate the default tumbling body offline and print a readable summary.

The body and its initial state are the node's default scene (config/scenes/default.yaml):
the T-handle I = (1, 2, 3) kg m^2 spun at 2 rad/s about its middle (unstable) axis with a
small nudge.  Watch the body angular velocity's y component reverse (the Dzhanibekov flip:
first after ~7.2 s, then every ~14.4 s) while energy and |L| stay put.  Columns: simulated
time (s), the orientation quaternion (x, y, z, w), the body angular velocity (rad/s), and
the relative drift of kinetic energy and |L| since t = 0.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from .compile import ensure_compiled
from .run_limits import check_duration
from .run_limits import check_every
from .run_limits import check_step
from .run_limits import check_tolerance
from ..physics import INTEGRATORS
from ..physics import Simulator
from ..scenes import DEFAULT_SCENE
from ..scenes import load_scene


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim run``."""
    parser.add_argument('--integrator', default=None,
                        help=f'one of: {", ".join(sorted(INTEGRATORS))} '
                             f"(default: the {DEFAULT_SCENE} scene's)")
    parser.add_argument('--duration', type=float, default=30.0,
                        help='simulated time in s, at most 2^31 (default: 30)')
    parser.add_argument('--dt', type=float, default=None,
                        help="time step in s, 0.0001 to 10 as the periods of the node's rates "
                             f"(default: 1 / the {DEFAULT_SCENE} scene's rate); with a "
                             'tolerance, the tick that error control splits')
    parser.add_argument('--tolerance', type=float, default=None,
                        help='error control in rad per simulated s: each step of dt is split '
                             'into as many substeps as keep the orientation error added per '
                             f'second below it; 0: off, one step per dt; at most 1 (default: the '
                             f"{DEFAULT_SCENE} scene's)")
    parser.add_argument('--every', type=float, default=1.0,
                        help='print a line every this many simulated s, at least --dt '
                             '(default: 1)')


def main(args: argparse.Namespace) -> int:
    """Run the simulation and print the summary table; return 0."""
    scene = load_scene(DEFAULT_SCENE)
    body = scene.body
    duration = check_duration(args.duration)
    dt = check_step(scene.dt if args.dt is None else args.dt)
    every = check_every(args.every, dt)
    tolerance = scene.tolerance if args.tolerance is None else check_tolerance(args.tolerance)
    ensure_compiled('run', [args.integrator or scene.integrator])
    # The body and state alone: the scene's only effect, external_wrench, has no input here.
    simulator = Simulator(body, scene.state, integrator=args.integrator or scene.integrator,
                          tolerance=tolerance)
    energy0 = simulator.energy()
    momentum0 = np.linalg.norm(simulator.state.angular_momentum)
    control = ('off' if simulator.tolerance is None
               else f'{simulator.tolerance:g} rad/s (error control)')
    print(f'body: mass {body.mass:g} kg, principal moments '
          f'{np.array2string(body.principal_moments, precision=4)} kg m^2; '
          f'integrator {simulator.integrator}, dt {dt:g} s, tolerance {control}')
    header = (f'{"t [s]":>8}  {"quaternion (x, y, z, w)":^35}  '
              f'{"body angular velocity [rad/s]":^32}  {"dE/E":>9}  {"d|L|/|L|":>9}')
    print(header)
    print('-' * len(header))

    def line() -> None:
        state = simulator.state
        omega = state.angular_velocity_body(body)
        energy_drift = (simulator.energy() - energy0) / energy0
        momentum_drift = (np.linalg.norm(state.angular_momentum) - momentum0) / momentum0
        q = ' '.join(f'{c:+8.5f}' for c in state.quaternion)
        w = ' '.join(f'{c:+9.5f}' for c in omega)
        print(f'{simulator.time:8.2f}  {q:>35}  {w:>32}  {energy_drift:+9.2e}  '
              f'{momentum_drift:+9.2e}')

    line()
    started = time.perf_counter()
    steps = 0
    # A row at each multiple of `every` and one at the end, counted rather than waited for
    # on the simulated clock: Simulator.run advances nothing for a rest below 1e-9 dt, so a
    # loop until the clock reaches the duration would not end on such a rest.
    rows = max(1, math.ceil(duration / every - 1e-9))
    for row in range(1, rows + 1):
        chunk = max(0.0, (duration if row == rows else row * every) - simulator.time)
        simulator.run(chunk, dt)
        steps += int(round(chunk / dt))
        line()
    elapsed = time.perf_counter() - started
    if simulator.tolerance is not None:
        figures = simulator.substep_statistics()
        print(f'{steps} ticks, {figures["substeps_min"]}-{figures["substeps_max"]} substeps '
              f'each ({figures["steps"]} integrator steps, the estimates\' included) in '
              f'{elapsed:.3f} s wall-clock ({duration / max(elapsed, 1e-12):.0f}x real '
              'time)')
        return 0
    print(f'{steps} steps in {elapsed:.3f} s wall-clock '
          f'({duration / max(elapsed, 1e-12):.0f}x real time)')
    return 0

#!/usr/bin/env python3
"""
Print what each built-in effect adds to a step, per integrator, as a ratio to the free step.

Usage: .venv/bin/python benchmarks/effect_cost.py [--steps N] [--repeats K] [--json PATH]
       [--integrators NAME ...] [--effects NAME ...]

For each integrator, a box (1 kg, 0.4 x 0.2 x 0.1 m, spun at 2 rad/s about its long axis with
a small tilt) is run torque-free, then under each built-in effect alone (a pivot always with
gravity, as a top is), through ``Simulator.run`` with a fixed step of 1 ms: N steps per timed
run, the median of K runs after a warm-up run (compilation is not counted).  Times are CPU
time of this process (``time.process_time``: the machine may be loaded) in microseconds per
step; the ratio to the torque-free step of the same integrator, timed in the same loop, is
the figure that carries from one machine to another (issue 20's goal: at most 3 under rk4
and buss).  ``--json`` also writes the table as JSON.

Only the public API is used (Simulator, the effects' classes), so the same script times an
older checkout: ``PYTHONPATH=<checkout> .venv/bin/python benchmarks/effect_cost.py``.
"""

import argparse
import json
import statistics
import time

import numpy as np

from rigid_body_sim.physics import effects
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State

DT = 1e-3


def _effects(name):
    """Return (effects, held wrench kwargs for set_wrench or None) of one benchmark case."""
    if name == 'free':
        return (), None
    if name == 'external_wrench':
        return (effects.ExternalWrench(),), {'force': (0.1, 0.0, 0.0),
                                             'torque': (0.0, 0.01, 0.02), 'frame': 'body'}
    if name == 'gravity':
        return (effects.Gravity(),), None
    if name == 'pivot':
        return (effects.Pivot(point=(-0.2, 0.0, 0.0)), effects.Gravity()), None
    if name == 'drag':
        return (effects.Drag(linear=0.1, quadratic=0.01, rotational_linear=1e-4,
                             rotational_quadratic=1e-5),), None
    if name == 'dissipation':
        return (effects.Dissipation(damping=0.05),), None
    if name == 'sinusoidal_torque':
        return (effects.SinusoidalTorque(amplitude=(0.0, 0.01, 0.02), frequency=0.5),), None
    raise ValueError(f'unknown case {name!r}')


CASES = ('free', 'external_wrench', 'gravity', 'pivot', 'drag', 'dissipation',
         'sinusoidal_torque')


def simulator(integrator, case):
    """Return a fresh Simulator of the benchmark box under `case`."""
    body = RigidBody.box(1.0, (0.4, 0.2, 0.1))
    state = State.from_velocity(body, angular_velocity_body=(2.0, 0.05, 0.02),
                                velocity=(0.1, 0.0, 0.0))
    scene_effects, held = _effects(case)
    sim = Simulator(body, state, integrator=integrator, effects=scene_effects)
    if held is not None:
        sim.set_wrench(**held)
    return sim


def microseconds_per_step(integrator, case, steps, repeats):
    """Return the median CPU us/step over `repeats` runs of `steps` steps, warmed up."""
    sim = simulator(integrator, case)
    sim.run(min(steps, 1000) * DT, DT)
    samples = []
    for _ in range(repeats):
        started = time.process_time()
        sim.run(steps * DT, DT)
        samples.append((time.process_time() - started) / steps * 1e6)
    if not np.all(np.isfinite(sim.state.quaternion)):
        raise RuntimeError(f'{integrator} under {case}: the state went non-finite')
    return statistics.median(samples)


def main():
    """Print the table (and write it as JSON with --json)."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=100000, help='steps per timed run')
    parser.add_argument('--repeats', type=int, default=5, help='timed runs per cell')
    parser.add_argument('--integrators', nargs='*', default=None, metavar='NAME',
                        help='integrators to time (default: all registered)')
    parser.add_argument('--effects', nargs='*', default=None, metavar='NAME',
                        help=f'cases to time besides free (default: all of '
                             f'{", ".join(CASES[1:])})')
    parser.add_argument('--json', default=None, metavar='PATH', help='also write JSON here')
    args = parser.parse_args()
    integrators = args.integrators or sorted(INTEGRATORS)
    unknown = sorted(set(integrators) - set(INTEGRATORS))
    if unknown:
        parser.error(f'unknown integrator(s) {", ".join(unknown)}; valid: '
                     f'{", ".join(sorted(INTEGRATORS))}')
    cases = ('free',) + tuple(args.effects if args.effects is not None else CASES[1:])
    bad = sorted(set(cases) - set(CASES))
    if bad:
        parser.error(f'unknown case(s) {", ".join(bad)}; valid: {", ".join(CASES)}')
    print(f'{"integrator":<12}' + ''.join(f'{case:>19}' for case in cases)
          + f'   (CPU us/step, median of {args.repeats}; x = ratio to free)', flush=True)
    table = {}
    for integrator in integrators:
        row = {case: microseconds_per_step(integrator, case, args.steps, args.repeats)
               for case in cases}
        table[integrator] = row
        free = row['free']
        cells = [f'{row[case]:.3f}' if case == 'free'
                 else f'{row[case]:.3f} ({row[case] / free:.2f}x)' for case in cases]
        print(f'{integrator:<12}' + ''.join(f'{cell:>19}' for cell in cells), flush=True)
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'dt': DT, 'steps': args.steps, 'repeats': args.repeats,
                       'us_per_step': table}, stream, indent=1)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

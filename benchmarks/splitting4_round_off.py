"""
Round-off of the COM under a held force: splitting4 beside rk4, splitting and buss.

A box (1 kg) thrown at v0 = (0.3, -0.1, 2) m/s, spinning, under a held world force
F = (1, 0.5, -0.3) N and torque; 2e5 steps of 1 ms.  The translation is then exactly
x0 + v0 t + F t^2 / (2 m) and p0 + F t whatever the rotation; the reference is computed in
rationals.  Two ways to step: one run of 2e5 steps (Simulator.run: one compiled call, as
simulate and bench do), and tick by tick (Simulator.step per step, as the node does).

Before the fix (rigid_body_sim e7bc82a..7c19d5d), splitting4 kicked the momenta and moved the
COM stage by stage (five stages, one negative), each add rounded.  Since: each step's kicks
and displacement are summed apart and added once (one rounding per step, as rk4),
compensated (Kahan) across the steps of one run.  The figures, before and after, are in
docs/benchmark.md ("Round-off under a held force").

Usage: .venv/bin/python benchmarks/splitting4_round_off.py [--steps N]
"""

import argparse
from fractions import Fraction

import numpy as np
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State

FORCE = np.array([1.0, 0.5, -0.3])
TORQUE = np.array([0.01, -0.02, 0.005])
VELOCITY = np.array([0.3, -0.1, 2.0])
BODY = RigidBody.box(1.0, (0.3, 0.2, 0.1))


def errors(integrator, steps, dt=1e-3, tick_by_tick=False):
    """Return (position error m, momentum error kg m/s, |x| m) after `steps` steps."""
    state = State.from_velocity(BODY, velocity=VELOCITY, angular_velocity_body=(0.1, 2.0, 0.1))
    simulator = Simulator(BODY, state, integrator=integrator)
    simulator.set_wrench(force=FORCE, torque=TORQUE, frame='world')
    if tick_by_tick:
        for _ in range(steps):
            simulator.step(dt)
    else:
        simulator.run(steps * dt, dt)
    t = Fraction(dt) * steps
    mass = Fraction(BODY.mass)
    position = np.array([float(Fraction(v) * t + Fraction(f) * t * t / (2 * mass))
                         for v, f in zip(VELOCITY, FORCE)])
    momentum = np.array([float(mass * Fraction(v) + Fraction(f) * t)
                         for v, f in zip(VELOCITY, FORCE)])
    final = simulator.state
    return (float(np.max(np.abs(final.position - position))),
            float(np.max(np.abs(final.linear_momentum - momentum))),
            float(np.max(np.abs(position))))


def main():
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--steps', type=int, default=200_000)
    args = parser.parse_args()
    print(f'{"integrator":11s} {"stepping":13s} {"position error m":>17s} '
          f'{"momentum error":>15s} {"ulp(|x|)":>9s}')
    for integrator in ('splitting4', 'rk4', 'splitting', 'buss'):
        for tick_by_tick in (False, True):
            position, momentum, size = errors(integrator, args.steps,
                                              tick_by_tick=tick_by_tick)
            print(f'{integrator:11s} {"tick by tick" if tick_by_tick else "one run":13s} '
                  f'{position:17.3g} {momentum:15.3g} {np.spacing(size):9.2g}')


if __name__ == '__main__':
    main()

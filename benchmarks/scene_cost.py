#!/usr/bin/env python3
"""
Print the cost per step of each built-in scene with its effects, and of its body torque-free.

Usage: .venv/bin/python benchmarks/scene_cost.py [--seconds S] [--repeats K]

For each scene, the scene's simulator (its integrator, step and effects) and a Simulator of
the same body, state, integrator and step with no effects are timed: in one run() call
(bulk, as the offline tools do) and one step() call per tick (as the node does).  Each
timing is CPU time of this process (time.process_time: the machine may be loaded), the
median over K repeats of about S CPU seconds of work, after a warm-up run (so numba
compilation is not counted), in microseconds per step.  The ratio of the two bulk columns
is the price of the scene's effects (every effect runs compiled: 'path' says so).
"""

import argparse
import statistics
import time

from rigid_body_sim.physics import Simulator
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import scene_names


def microseconds_per_step(make_simulator, dt, seconds, repeats, per_tick):
    """Return the median us/step of fresh simulators over `repeats` timed runs."""
    def timed(steps):
        simulator = make_simulator()
        started = time.process_time()
        if per_tick:
            for _ in range(steps):
                simulator.step(dt)
        else:
            simulator.run(steps * dt, dt)
        return (time.process_time() - started) / steps

    # Warm up (compilation, caches) and size the runs to about `seconds` each.
    estimate = max(min(timed(1000), timed(1000)), 1e-8)
    steps = max(200, int(seconds / estimate))
    return statistics.median(timed(steps) for _ in range(repeats)) * 1e6


def main():
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=0.3,
                        help='CPU work per timed run in s (default 0.3)')
    parser.add_argument('--repeats', type=int, default=5, help='timed runs (default 5)')
    args = parser.parse_args()
    print(f'{"scene":<14} {"integrator":<10} {"Hz":>5} {"effects":<26} {"path":<13}'
          f'{"with":>9} {"free":>8} {"ratio":>6}   {"tick with":>9} {"tick free":>9}')
    print(f'{"":<14} {"":<10} {"":>5} {"":<26} {"":<13}{"us/step (run)":>17} {"":>6}   '
          f'{"us/step (step)":>19}')
    for name in scene_names(several_bodies=False):
        scene = load_scene(name)

        def with_effects():
            return scene.simulator()

        def torque_free():
            return Simulator(scene.body, scene.state, integrator=scene.integrator)

        timings = [microseconds_per_step(make, scene.dt, args.seconds, args.repeats, tick)
                   for tick in (False, True) for make in (with_effects, torque_free)]
        # _path is private; read here only to label the table.
        path = scene.simulator().path
        effects = ', '.join(scene.effect_names()) or '-'
        print(f'{name:<14} {scene.integrator:<10} {scene.rate:>5g} {effects:<26} {path:<13}'
              f'{timings[0]:>9.2f} {timings[1]:>8.2f} {timings[0] / timings[1]:>6.1f}   '
              f'{timings[2]:>9.2f} {timings[3]:>9.2f}')


if __name__ == '__main__':
    main()

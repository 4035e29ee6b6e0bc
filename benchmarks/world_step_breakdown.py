#!/usr/bin/env python3
"""
Where a World's body-step goes beyond the single body's kernel tick: variants side by side.

benchmarks/many_bodies.py finds a World's fixed-step body-step at N = 1,000 some 1.2-1.3x
the single body's kernel called once a tick.  This script times, in CPU time, in one
process, the median of seven rounds each timing every variant in turn, 200 ticks of the
1,000 constellation bodies (buss, one fixed step a tick) stepped by:

- world: the World's own kernel (world.step_bodies): per body the activity check, the
  copy of the state kept to restore it, the run kernel through the Stepper;
- no copy: the same loop without the activity check and the copy (not safe: a body
  turning non-finite could not be put back; timed to see what the copy costs);
- one model: as "no copy", every body stepped with the first body's model (its arrays and
  fields hot in the cache; wrong physics for the others, timed only): what reading 1,000
  models' fields from memory costs;
- shared arrays: the World's kernel on a World whose models all point at the first
  model's arrays (the structs themselves still one per body): what the arrays' data
  costs against the structs' fields;
- one block: the World's kernel on a World whose models' arrays were copied into one
  block, body after body in the World's order (same numbers: the same bits, checked), the
  layout a rewrite of the model could give them; the structs stay one per body.

Usage: ``.venv/bin/python benchmarks/world_step_breakdown.py``
"""

import argparse
from pathlib import Path
import sys
import time

import numba
from numba import types
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rigid_body_sim.physics import world as world_module  # noqa: E402
from rigid_body_sim.physics.kernels.borrow import borrowed  # noqa: E402
from rigid_body_sim.physics.kernels.model import MODEL_TYPE  # noqa: E402
from rigid_body_sim.physics.warm_up import load_kernels  # noqa: E402
from rigid_body_sim.scenes import load_scene  # noqa: E402

TICKS = 200
ROUNDS = 7


def _no_copy(stepper, states, models, controls, checkpoints, method, tick, substeps, time,
             active, taken):
    run = stepper.controller.run
    for index in range(states.shape[0]):
        taken[index] = run(borrowed(states[index]), models[index], method, tick / substeps,
                           substeps, time)
    return 0


def _one_model(stepper, states, models, controls, checkpoints, method, tick, substeps, time,
               active, taken):
    run = stepper.controller.run
    model = models[0]
    for index in range(states.shape[0]):
        taken[index] = run(borrowed(states[index]), model, method, tick / substeps,
                           substeps, time)
    return 0


@numba.njit(types.void(MODEL_TYPE, MODEL_TYPE))
def _share_arrays(model, other):
    model.body = other.body
    model.held = other.held
    model.term_parameters = other.term_parameters
    model.term_offsets = other.term_offsets
    model.flow_parameters = other.flow_parameters
    model.flow_offsets = other.flow_offsets
    model.constraint_parameters = other.constraint_parameters
    model.physical = other.physical
    model.stage = other.stage
    model.carry = other.carry


@numba.njit(types.void(MODEL_TYPE, types.float64[::1], types.float64[:, ::1],
                       types.float64[::1], types.int64[::1], types.float64[::1],
                       types.int64[::1], types.float64[::1], types.float64[::1],
                       types.float64[::1], types.float64[::1]))
def _set_arrays(model, body, held, term_parameters, term_offsets, flow_parameters,
                flow_offsets, constraint_parameters, physical, stage, carry):
    model.body = body
    model.held = held
    model.term_parameters = term_parameters
    model.term_offsets = term_offsets
    model.flow_parameters = flow_parameters
    model.flow_offsets = flow_offsets
    model.constraint_parameters = constraint_parameters
    model.physical = physical
    model.stage = stage
    model.carry = carry


@numba.njit
def _arrays_of(model):
    return (model.body, model.held, model.term_parameters, model.term_offsets,
            model.flow_parameters, model.flow_offsets, model.constraint_parameters,
            model.physical, model.stage, model.carry)


_OFFSETS = (3, 5)  # the int64 arrays among _arrays_of's


def _into_one_block(models):
    """Copy every model's arrays into two blocks (floats, offsets), body after body."""
    arrays = [_arrays_of(model) for model in models]
    width = max(sum(a.size for i, a in enumerate(each) if i not in _OFFSETS)
                for each in arrays)
    width = (width + 7) // 8 * 8  # each body's floats start on a 64-byte line
    floats = np.zeros(len(arrays) * width)
    offsets_width = max(sum(each[i].size for i in _OFFSETS) for each in arrays)
    offsets = np.zeros(len(arrays) * offsets_width, dtype=np.int64)
    for index, (model, each) in enumerate(zip(models, arrays)):
        at, at_offsets, views = index * width, index * offsets_width, []
        for position, array in enumerate(each):
            if position in _OFFSETS:
                view = offsets[at_offsets:at_offsets + array.size]
                at_offsets += array.size
            else:
                view = floats[at:at + array.size]
                at += array.size
            view = view.reshape(array.shape)
            view[...] = array
            views.append(view)
        _set_arrays(model, *views)


def main(argv=None):
    """Print the CPU ns per body-step of each variant."""
    argparse.ArgumentParser(description=__doc__.split('\n\n')[1],
                            formatter_class=argparse.RawDescriptionHelpFormatter
                            ).parse_args(argv)
    scene = load_scene('constellation')
    load_kernels('buss')
    dt = scene.dt

    def new_world():
        world = scene.world(integrator='buss', tolerance=0.0)
        world.step(dt)
        return world

    world, shared, blocked = new_world(), new_world(), new_world()
    first = world_module_models(shared)[0]
    for model in world_module_models(shared):
        _share_arrays(model, first)
    _into_one_block(world_module_models(blocked))
    alike = new_world()
    for _ in range(50):
        blocked.step(dt)
        alike.step(dt)
    same = all(np.array_equal(blocked.simulator(name).kernel_arguments()[0],
                              alike.simulator(name).kernel_arguments()[0])
               for name in alike.names)
    signature = world_module.STEP_BODIES_SIGNATURE
    variants = {
        'world': (world, world_module.step_bodies.dispatcher),
        'no copy': (world, numba.njit(signature)(_no_copy)),
        'one model': (world, numba.njit(signature)(_one_model)),
        'shared arrays': (shared, world_module.step_bodies.dispatcher),
        'one block': (blocked, world_module.step_bodies.dispatcher),
    }
    count = len(world)
    timings = {name: [] for name in variants}
    for _ in range(ROUNDS):
        for name, (stepped, kernel) in variants.items():
            arguments = kernel_arguments(stepped, dt)
            started = time.process_time()
            for _ in range(TICKS):
                kernel(*arguments)
            timings[name].append(1e9 * (time.process_time() - started) / (TICKS * count))
    print(f'constellation, {count} bodies, buss, one fixed step a tick; CPU ns per body-step, '
          f'median of {ROUNDS} rounds of {TICKS} ticks')
    reference = float(np.median(timings['world']))
    for name, values in timings.items():
        median = float(np.median(values))
        print(f'{name:14s} {median:7.1f}  ({median - reference:+6.1f} vs world)')
    print(f'one block: 50 ticks leave every body with the bits of a World as built: {same}')


def world_module_models(world):
    """Return the World's compiled models, in the bodies' order (its kernel's argument)."""
    return kernel_arguments(world, 0.0)[2]


def kernel_arguments(world, dt):
    """Return the arguments World.step gives its kernel (fixed step: substeps as set)."""
    # The World keeps them private: this script times its kernel as World.step calls it.
    return (world._stepper, world._states, world._models, world._controls,
            world._checkpoints, world._method, dt, world.substeps, world.time,
            world._active, world._taken)


if __name__ == '__main__':
    main()

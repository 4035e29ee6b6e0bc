#!/usr/bin/env python3
"""
Where a World's body-step goes beyond the single body's kernel tick: variants side by side.

benchmarks/many_bodies.py compares a World's fixed-step body-step at N = 1,000 with the
single body's kernel called once a tick.  This script times, in CPU time, in one process,
the median of seven rounds each timing every variant in turn, 200 ticks of the 1,000
constellation bodies (buss, one fixed step a tick) stepped by:

- world: the World's own kernel (world.step_bodies): per body the activity check, the
  copy of the state kept to restore it, the model read from the World's table (and the
  model after next prefetched), the run kernel through the Stepper; the models' arrays in
  one block (kernels/model_table.py);
- no copy: the same loop without the activity check and the copy (not safe: a body
  turning non-finite could not be put back; timed to see what the copy costs);
- one model: as "no copy", every body stepped with the first body's model (its arrays and
  fields hot in the cache; wrong physics for the others, timed only): what reading 1,000
  models' fields from memory costs;
- shared arrays: the World's kernel on a World whose models all point at the first
  model's arrays (the structs themselves still one per body): what the arrays' data
  costs against the structs' fields;
- scattered: the World's loop before kernels/model_table.py, kept to show what it saves:
  the models read from a numba typed list (a reference counted each), none prefetched,
  each model's arrays allocated apart (copied out of the block: the same values, the
  same bits, checked).

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
from rigid_body_sim.physics.kernels.model_table import model_at  # noqa: E402
from rigid_body_sim.physics.kernels.model_table import prefetch_model  # noqa: E402
from rigid_body_sim.physics.warm_up import load_kernels  # noqa: E402
from rigid_body_sim.scenes import load_scene  # noqa: E402

TICKS = 200
ROUNDS = 7


def _no_copy(stepper, states, models, controls, checkpoints, method, tick, substeps, time,
             active, taken):
    run = stepper.controller.run
    for index in range(states.shape[0]):
        prefetch_model(models, index + 2)
        taken[index] = run(borrowed(states[index]), model_at(models, index), method,
                           tick / substeps, substeps, time)
    return 0


def _one_model(stepper, states, models, controls, checkpoints, method, tick, substeps, time,
               active, taken):
    run = stepper.controller.run
    model = model_at(models, 0)
    for index in range(states.shape[0]):
        taken[index] = run(borrowed(states[index]), model, method, tick / substeps,
                           substeps, time)
    return 0


def _from_list(stepper, states, models, controls, checkpoints, method, tick, substeps, time,
               active, taken):
    # world.step_all before the table: the fixed-step path, the model from a typed list.
    run = stepper.controller.run
    for index in range(states.shape[0]):
        if active[index] == 0:
            taken[index] = 0
            continue
        state = borrowed(states[index])
        checkpoint = borrowed(checkpoints[index])
        checkpoint[:] = state
        steps = run(state, models[index], method, tick / substeps, substeps, time)
        if steps < 0:
            state[:] = checkpoint
        taken[index] = steps
    return 0


_ARRAYS = types.Tuple((types.float64[::1], types.float64[:, ::1], types.float64[::1],
                       types.int64[::1], types.float64[::1], types.int64[::1],
                       types.float64[::1], types.float64[::1], types.float64[::1],
                       types.float64[::1]))


@numba.njit(types.void(MODEL_TYPE, _ARRAYS))
def _set_arrays(model, arrays):
    (model.body, model.held, model.term_parameters, model.term_offsets, model.flow_parameters,
     model.flow_offsets, model.constraint_parameters, model.physical, model.stage,
     model.carry) = arrays


@numba.njit(_ARRAYS(MODEL_TYPE))
def _arrays_of(model):
    return (model.body, model.held, model.term_parameters, model.term_offsets,
            model.flow_parameters, model.flow_offsets, model.constraint_parameters,
            model.physical, model.stage, model.carry)


_from_list_kernel = numba.njit(types.int64(
    *world_module.STEP_BODIES_SIGNATURE.args[:2], types.ListType(MODEL_TYPE),
    *world_module.STEP_BODIES_SIGNATURE.args[3:]))(_from_list)


def _scatter(models):
    """Give every model copies of its arrays, each allocated apart (timing only)."""
    for model in models:
        _set_arrays(model, tuple(array.copy() for array in _arrays_of(model)))


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

    world, shared, scattered = new_world(), new_world(), new_world()
    first = _arrays_of(world_module_models(shared)[0])
    for model in world_module_models(shared):
        _set_arrays(model, first)
    _scatter(world_module_models(scattered))
    alike = new_world()
    for _ in range(50):
        _from_list_kernel(*kernel_arguments(scattered, dt, listed=True))
        world_module.step_bodies.dispatcher(*kernel_arguments(alike, dt))
    same = all(np.array_equal(scattered.simulator(name).kernel_arguments()[0],
                              alike.simulator(name).kernel_arguments()[0])
               for name in alike.names)
    signature = world_module.STEP_BODIES_SIGNATURE
    variants = {
        'world': (kernel_arguments(world, dt), world_module.step_bodies.dispatcher),
        'no copy': (kernel_arguments(world, dt), numba.njit(signature)(_no_copy)),
        'one model': (kernel_arguments(world, dt), numba.njit(signature)(_one_model)),
        'shared arrays': (kernel_arguments(shared, dt), world_module.step_bodies.dispatcher),
        'scattered': (kernel_arguments(scattered, dt, listed=True), _from_list_kernel),
    }
    count = len(world)
    timings = {name: [] for name in variants}
    for _ in range(ROUNDS):
        for name, (arguments, kernel) in variants.items():
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
    print(f'scattered: 50 ticks leave every body with the bits of the World: {same}')


def world_module_models(world):
    """Return the World's compiled models (a typed list), in the bodies' order."""
    return world._models


def kernel_arguments(world, dt, listed=False):
    """
    Return the arguments World.step gives its kernel (fixed step: substeps as set).

    listed: the models as a typed list (the scattered variant's), not the World's table.
    """
    # The World keeps them private: this script times its kernel as World.step calls it.
    return (world._stepper, world._states, world._models if listed else world._model_table,
            world._controls, world._checkpoints, world._method, dt, world.substeps,
            world.time, world._active, world._taken)


if __name__ == '__main__':
    main()

"""
A World of many bodies: one compiled call a tick, each body as it moves alone.

The World calls, per body, the very kernels the body's own Simulator.step calls (the
integrator's run kernel, or the error controller), on the same arrays: so on one machine a
body in a World ends with the bits it has alone, step for step, whatever the others do.
"""

import math

import numpy as np
import pytest

from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics import World
from rigid_body_sim.physics.effects import create_effect

DT = 0.01


def mixed_bodies():
    """Return [(name, body, state, effects)]: free, falling, dragged, driven, pivoted."""
    box = RigidBody.box(0.5, (0.3, 0.2, 0.1))
    cylinder = RigidBody.cylinder(1.0, 0.05, 0.4)
    ellipsoid = RigidBody.ellipsoid(2.0, (0.3, 0.2, 0.05))
    return [
        ('tumbler', box, State.from_velocity(box, angular_velocity_body=(0.1, 6.0, 0.2)), []),
        ('falling', cylinder, State.from_velocity(
            cylinder, angular_velocity_body=(3.0, 0.5, 1.0), velocity=(0.5, 0.0, 4.0)),
         [create_effect('gravity', {})]),
        ('dragged', ellipsoid, State.from_velocity(
            ellipsoid, angular_velocity_body=(1.0, 2.0, 3.0), velocity=(1.0, 0.0, 0.0)),
         [create_effect('drag', {'linear': 0.1, 'rotational_linear': 0.001})]),
        ('driven', box, State.from_velocity(box, angular_velocity_body=(0.0, 0.0, 1.0)),
         [create_effect('sinusoidal_torque', {'amplitude': [0.01, 0.0, 0.02],
                                              'frequency': 1.5})]),
        ('top', cylinder, State.from_velocity(cylinder, angular_velocity_body=(0.0, 0.0, 40.0)),
         [create_effect('gravity', {}), create_effect('pivot', {'point': [0.0, 0.0, -0.2]})]),
    ]


def world_and_alone(integrator='buss', tolerance=None):
    """Return (World of mixed_bodies, {name: the same body's own Simulator})."""
    bodies = mixed_bodies()
    world = World(((name, Simulator(body, state, effects=effects))
                   for name, body, state, effects in bodies),
                  integrator=integrator, tolerance=tolerance)
    alone = {name: Simulator(body, state, integrator=integrator, effects=effects,
                             tolerance=tolerance)
             for name, body, state, effects in bodies}
    return world, alone


def step_together(world, alone, ticks):
    """Step the World and each body's own Simulator `ticks` ticks of DT."""
    for _ in range(ticks):
        world.step(DT)
        for simulator in alone.values():
            simulator.step(DT)


def assert_as_alone(world, alone, names=None):
    """Assert each named body (default: all of `alone`) has in the World its bits alone."""
    for name in alone if names is None else names:
        np.testing.assert_array_equal(packed(world.simulator(name)), packed(alone[name]))


def packed(simulator):
    """Return a copy of a simulator's packed state (13 values)."""
    return simulator.kernel_arguments()[0].copy()


@pytest.mark.parametrize('integrator', sorted(INTEGRATORS))
@pytest.mark.parametrize('tolerance', [None, 1e-6])
def test_each_body_in_a_world_ends_with_the_bits_it_has_alone(integrator, tolerance):
    world, alone = world_and_alone(integrator, tolerance)
    for _ in range(150):
        assert world.step(DT) == {}
        for simulator in alone.values():
            simulator.step(DT)
    assert_as_alone(world, alone)
    for name, simulator in alone.items():
        assert world.state(name).position.tolist() == simulator.state.position.tolist()
    # The clock is the one a body has alone (the same sum, to the bit).
    assert world.time == alone['tumbler'].time
    assert world.simulator('top').time == world.time


def test_under_error_control_each_body_takes_the_substeps_it_takes_alone():
    slow_body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
    fast_body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
    slow = State.from_velocity(slow_body, angular_velocity_body=(0.01, 0.5, 0.01))
    fast = State.from_velocity(fast_body, angular_velocity_body=(1.0, 60.0, 1.0))
    world = World([('slow', Simulator(slow_body, slow)), ('fast', Simulator(fast_body, fast))],
                  tolerance=1e-7)
    slow_alone = Simulator(slow_body, slow, tolerance=1e-7)
    for _ in range(50):
        world.step(DT)
        slow_alone.step(DT)
    slow_steps, fast_steps = world.steps_taken
    # The fast tumbler needs many more substeps; the slow body takes what it takes alone.
    assert world.simulator('fast').substep_statistics()['substeps'] > \
        4 * world.simulator('slow').substep_statistics()['substeps']
    assert world.simulator('slow').substep_statistics() == slow_alone.substep_statistics()
    assert fast_steps > slow_steps > 0


def test_a_body_turning_non_finite_stops_alone_at_its_last_finite_state():
    world, alone = world_and_alone()
    world.simulator('driven').hold_wrench(torque_world=(1e308, 1e308, 1e308))
    before = None
    stopped = {}
    for _ in range(20):
        before = packed(world.simulator('driven'))
        stopped = world.step(DT)
        if stopped:
            break
        for simulator in alone.values():
            simulator.step(DT)
    assert list(stopped) == ['driven'], stopped
    assert 'non-finite' in stopped['driven'] and world.diverged == stopped
    # Put back to the state before the tick that broke it; the others moved on.
    np.testing.assert_array_equal(packed(world.simulator('driven')), before)
    for simulator in alone.values():
        simulator.step(DT)
    assert_as_alone(world, alone, ('tumbler', 'falling', 'top'))
    # Stopped: the next ticks leave it where it is, until its state is set.
    world.step(DT)
    np.testing.assert_array_equal(packed(world.simulator('driven')), before)
    assert world.steps_taken[world.names.index('driven')] == 0
    world.simulator('driven').hold_wrench()
    world.set_state('driven', alone['driven'].state)
    assert world.diverged == {}
    world.step(DT)
    assert world.steps_taken[world.names.index('driven')] == 1


def test_bodies_added_and_removed_leave_the_others_as_they_are_alone():
    world, alone = world_and_alone()
    step_together(world, alone, 30)
    removed = world.remove('falling')
    assert 'falling' not in world and len(world) == 4 and isinstance(removed, Simulator)
    newcomer = RigidBody.sphere(1.0, 0.1)
    newcomer_state = State.from_velocity(newcomer, angular_velocity_body=(0.0, 0.0, 2.0))
    world.add('newcomer', Simulator(newcomer, newcomer_state))
    assert world.names == ('tumbler', 'dragged', 'driven', 'top', 'newcomer')
    assert world.simulator('newcomer').time == world.time
    step_together(world, alone, 30)
    assert_as_alone(world, alone, ('tumbler', 'dragged', 'driven', 'top'))
    # A sphere spins about a fixed axis at a constant rate: 30 ticks turn it 0.6 rad.
    quaternion = world.state('newcomer').quaternion
    assert math.isclose(2.0 * math.atan2(quaternion[2], quaternion[3]), 0.6, rel_tol=1e-12)
    with pytest.raises(ValueError, match="'top' exists already"):
        world.add('top', Simulator(newcomer, newcomer_state))
    with pytest.raises(KeyError, match="no body called 'falling'"):
        world.state('falling')


def test_switching_the_integrator_switches_every_body_as_alone():
    world, alone = world_and_alone('buss', 1e-6)
    for tick in range(60):
        if tick == 30:
            world.integrator = 'rk4'
            for simulator in alone.values():
                simulator.integrator = 'rk4'
        world.step(DT)
        for simulator in alone.values():
            simulator.step(DT)
    for name, simulator in alone.items():
        assert world.simulator(name).integrator == 'rk4'
        np.testing.assert_array_equal(packed(world.simulator(name)), packed(simulator))


def test_a_step_a_stiff_effect_refuses_names_the_body():
    body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
    stiff = create_effect('drag', {'rotational_linear': 100.0})
    world = World([('calm', Simulator(body, State.from_velocity(body))),
                   ('stiff', Simulator(body, State.from_velocity(body), effects=[stiff]))])
    with pytest.raises(ValueError, match="body 'stiff': "):
        world.step(0.1)


def test_a_reset_puts_every_body_and_the_clock_back():
    world, alone = world_and_alone()
    initial = {name: simulator.state for name, simulator in alone.items()}
    for _ in range(10):
        world.step(DT)
    world.reset(initial, time=0.0)
    assert world.time == 0.0
    step_together(world, alone, 10)
    assert_as_alone(world, alone)
    with pytest.raises(ValueError, match='no state for top'):
        world.reset({name: state for name, state in initial.items() if name != 'top'})


@pytest.mark.parametrize('dt, words', [(0.0, '> 0'), (-0.01, '> 0'), (math.inf, 'finite'),
                                       (math.nan, 'finite'), ('fast', 'number of seconds'),
                                       (None, 'number of seconds')])
def test_a_tick_that_is_not_a_positive_number_of_seconds_is_refused_naming_dt(dt, words):
    world, _ = world_and_alone()
    before = {name: packed(world.simulator(name)) for name in world.names}
    with pytest.raises(ValueError, match='dt must be') as refused:
        world.step(dt)
    assert words in str(refused.value)
    for name in world.names:
        np.testing.assert_array_equal(packed(world.simulator(name)), before[name])
    assert world.time == 0.0


def test_a_whole_number_of_seconds_steps_as_its_float_as_a_simulator_takes_it():
    by_int, _ = world_and_alone()
    by_float, _ = world_and_alone()
    by_int.step(1)
    by_float.step(1.0)
    for name in by_int.names:
        np.testing.assert_array_equal(packed(by_int.simulator(name)),
                                      packed(by_float.simulator(name)))
    assert by_int.time == 1.0


def test_a_held_wrench_acts_on_a_body_in_a_world_as_alone_when_bodies_come_and_go():
    # The World moves each model's arrays into its blocks (kernels/model_table.py), the held
    # wrench with them: the Simulator must go on writing the array its model reads.
    world, alone = world_and_alone()
    for simulator in (world.simulator('tumbler'), alone['tumbler']):
        simulator.hold_wrench(torque_world=(0.01, 0.0, 0.02), force_body=(0.5, 0.0, 0.0))
    step_together(world, alone, 20)
    sphere = RigidBody.sphere(1.0, 0.1)
    world.add('newcomer', Simulator(sphere, State.from_velocity(sphere)))
    for simulator in (world.simulator('tumbler'), alone['tumbler']):
        simulator.hold_wrench(torque_body=(0.0, 0.03, 0.0))
    step_together(world, alone, 20)
    assert_as_alone(world, alone, ('tumbler', 'driven', 'top'))
    # A body taken out of the world steps alone, its held wrench its own.
    removed = world.remove('tumbler')
    for simulator in (removed, alone['tumbler']):
        simulator.hold_wrench(force_world=(0.0, 0.0, -1.0))
        for _ in range(10):
            simulator.step(DT)
    np.testing.assert_array_equal(packed(removed), packed(alone['tumbler']))


def test_the_models_moved_into_the_worlds_blocks_are_every_array_a_model_holds():
    from numba import types
    from rigid_body_sim.physics.kernels.model import MODEL_TYPE
    from rigid_body_sim.physics.kernels.model_table import MOVED_ARRAYS
    arrays = {name for name, kind in MODEL_TYPE.field_dict.items()
              if isinstance(kind, types.Array)}
    assert set(MOVED_ARRAYS) == arrays, 'kernels/model_table.py must move every array'


def test_a_world_run_as_python_steps_each_body_as_it_steps_alone_as_python():
    # The kernels' source run as Python (a node's first ticks while they compile): a
    # table is the list of models there, and nothing is moved or prefetched.
    world, alone = world_and_alone()
    world.interpreted = True
    for simulator in alone.values():
        simulator.interpreted = True
    step_together(world, alone, 3)
    assert_as_alone(world, alone)
    world.interpreted = False
    for simulator in alone.values():
        simulator.interpreted = False
    step_together(world, alone, 3)
    assert_as_alone(world, alone)

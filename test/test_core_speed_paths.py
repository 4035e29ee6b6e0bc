"""
The Simulator's compiled paths: everything runs compiled, equal to the readable path, no more.

That a pivot with gravity and dissipation run compiled under every integrator, equal the
readable path and keep each method's order, and that the model holds only what the scene
calls for.

Frames world, units SI.  Round-off bounds: the compiled and readable paths evaluate the same
formulas in a different order, each step adding a few ulp that then grow about linearly over
a non-chaotic run; 10 eps per stage evaluation (steps x stages of the method) bounds that with
a margin of about ten (measured: 1e-14 to 6e-13 over 500 steps).
"""

import math

import numpy as np
import pytest
from reference import random_rotation
from reference import reference_solution
from reference import rotation_angle_between
from reference import state_error
from reference import torque_free_momentum_drift
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects import Dissipation
from rigid_body_sim.physics.effects import Gravity
from rigid_body_sim.physics.effects import Pivot
from rigid_body_sim.physics.effects.registry import Effect
from rigid_body_sim.physics.kernels.model import wrench_term
from rigid_body_sim.physics.rotations import cross
from rigid_body_sim.physics.simulator import COMPILED
from rigid_body_sim.physics.simulator import READABLE
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import scene_names

EPS = np.finfo(float).eps
COMPILED_NAMES = sorted(INTEGRATORS)
GRAVITY = np.array([0.0, 0.0, -9.81])
# The held wrench of the pivot problems: every part, so each reaches the kernel.
HELD = {'force_world': (0.1, 0.0, 0.0), 'torque_world': (0.0, 0.01, 0.0),
        'force_body': (0.05, 0.0, 0.1), 'torque_body': (0.0, 0.0, 0.002)}


@wrench_term
def _counted_nothing(state, time, parameters):
    parameters[0] += 1.0
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


class _Counting(Effect):
    compiled_wrench = staticmethod(_counted_nothing)

    def wrench_parameters(self, body):
        return np.zeros(1)


def _stages(name):
    """Return the wrench evaluations per step of integrator `name`, counted by a spy term."""
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    simulator = Simulator(body, State(), integrator=name, effects=[_Counting()])
    simulator.run(0.1, 0.01)
    return int(simulator._model.term_parameters[0]) // 10


STAGES = {name: _stages(name) for name in COMPILED_NAMES}


def test_the_stage_counts_are_the_methods():
    # Kicks at both ends for the split methods (five stages for splitting4), rk4's four
    # derivatives, first_order's one sample.
    names = ('first_order', 'buss', 'rk4', 'splitting', 'splitting4', 'exact')
    assert {name: STAGES[name] for name in names} == {
        'first_order': 1, 'buss': 2, 'rk4': 4, 'splitting': 2, 'splitting4': 10, 'exact': 2}


@pytest.mark.parametrize('scene_name', ['heavy_top', 'bike_wheel', 'flat_spin'])
@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_pivot_and_dissipation_scenes_run_compiled_with_every_integrator(scene_name, name):
    simulator = load_scene(scene_name).simulator(integrator=name)
    assert simulator.path == COMPILED


def _round_off(name, steps):
    return 10.0 * EPS * steps * STAGES[name]


def _top():
    """Return a box pivoted off every principal axis, spinning and tilted (body, state, pivot)."""
    rng = np.random.default_rng(7)
    body = RigidBody.box(0.5, (0.08, 0.05, 0.02))
    state = State.from_velocity(body, rotation=random_rotation(rng),
                                angular_velocity_body=(2.0, -3.0, 25.0))
    return body, state, Pivot(point=(0.01, -0.02, -0.06), anchor=(0.1, 0.0, 0.2))


def _pivot_simulator(name, fast_path, held=True):
    body, state, pivot = _top()
    simulator = Simulator(body, state, integrator=name, effects=[pivot, Gravity()],
                          fast=fast_path)
    if held:
        simulator.hold_wrench(**HELD)
    return simulator


def _assert_states_agree(state, other, tolerance):
    assert rotation_angle_between(state.rotation, other.rotation) <= tolerance
    for a, b in ((state.position, other.position),
                 (state.linear_momentum, other.linear_momentum),
                 (state.angular_momentum, other.angular_momentum)):
        assert np.linalg.norm(a - b) <= tolerance * max(1.0, np.linalg.norm(b)), (a, b)


# -- 1. a constant force under a pivot: compiled, equal to the readable path, orders kept


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_pivot_with_gravity_runs_compiled_and_equals_the_readable_path(name):
    compiled, readable = _pivot_simulator(name, True), _pivot_simulator(name, False)
    assert compiled.path == COMPILED
    assert readable.path == READABLE
    steps = 500
    compiled.run(steps * 1e-3, 1e-3)
    readable.run(steps * 1e-3, 1e-3)
    # The body turned well away from the start: a dropped lever torque could not hide.
    assert rotation_angle_between(compiled.state.rotation, _top()[1].rotation) > 1.0
    _assert_states_agree(compiled.state, readable.state, _round_off(name, steps))
    assert compiled.time == readable.time


def _pivot_reference(duration):
    """Return the physical state after `duration` s, from DOP853 on the pivot system."""
    body, state, pivot = _top()
    constraint = pivot.constrain(body)
    torque_world = np.array(HELD['torque_world'])
    torque_body = np.array(HELD['torque_body'])
    force_world = np.array(HELD['force_world']) + body.mass * GRAVITY
    force_body = np.array(HELD['force_body'])

    def wrench(pivot_state, time):
        # About the pivot: the torques, and the moment of every force at the COM, r = R d.
        rotation = pivot_state.rotation
        r = rotation @ constraint.offset_body
        force = force_world + rotation @ force_body
        return np.zeros(3), torque_world + rotation @ torque_body + cross(r, force)

    start = constraint.reduce(constraint.project(state))
    return constraint.expand(reference_solution(constraint.body, start, duration, wrench))


# Coarse steps over 0.5 s by the method's order: the coarse error well below 0.05, the fine
# one far above the reference's ~1e-12 (both asserted).
COARSE_STEPS = {1: 80000, 2: 400, 4: 100}


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_compiled_pivot_with_gravity_keeps_the_method_order(name):
    order = INTEGRATORS[name].order
    steps = COARSE_STEPS[order]
    duration = 0.5
    reference = _pivot_reference(duration)
    body = _top()[0]
    errors = []
    for count in (steps, 2 * steps):
        simulator = _pivot_simulator(name, True)
        assert simulator.path == COMPILED
        errors.append(state_error(simulator.run(duration, duration / count), reference,
                                  0.1, body.mass)['total'])
    coarse, fine = errors
    assert coarse < 0.05 and fine > 1e-10, errors
    observed = math.log2(coarse / fine)
    # As test_integrator_convergence: within 0.3 of the nominal order (4th: >= 3.7).
    if order == 4:
        assert observed >= order - 0.3, observed
    else:
        assert abs(observed - order) <= 0.3, observed


def test_compiled_pivot_expansion_equals_the_readable_one():
    rng = np.random.default_rng(11)
    body, _, pivot = _top()
    constraint = pivot.constrain(body)
    # omega = I_pivot^{-1} R^T L, then two rotations and two cross products: a few eps each,
    # amplified by the conditioning of the inertia about the pivot (~7 here).
    tolerance = 32 * EPS * np.linalg.cond(constraint.body.inertia)
    for _ in range(20):
        pivot_state = State(random_rotation(rng), pivot.anchor, np.zeros(3),
                            rng.normal(size=3))
        readable = constraint.expand(pivot_state)
        compiled = State._from_values(constraint.expand_values(
            np.concatenate(pivot_state._fields())))
        _assert_states_agree(compiled, readable, tolerance)


# -- 2. the dissipation flow fused into the compiled loop


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_dissipation_is_fused_into_the_compiled_run_and_equals_the_composition(name):
    rng = np.random.default_rng(12)
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    state = State.from_velocity(body, rotation=random_rotation(rng),
                                angular_velocity_body=(0.4, 3.0, 0.3))
    fused = Simulator(body, state, integrator=name, effects=[Dissipation(0.05)])
    composed = Simulator(body, state, integrator=name, effects=[Dissipation(0.05)], fast=False)
    assert fused.path == COMPILED
    steps = 500
    fused.run(steps * 0.01, 0.01)
    composed.run(steps * 0.01, 0.01)
    # The spin left the middle axis: the flow did act.
    assert abs(fused.state.angular_velocity_body(body)[1]) < 2.5
    _assert_states_agree(fused.state, composed.state, _round_off(name, steps))
    # Neither the flow nor a torque-free step touches world L (rk4 moves it by its error).
    drift = torque_free_momentum_drift(name, body, state, 0.01, steps)
    assert np.linalg.norm(fused.state.angular_momentum - state.angular_momentum) <= drift


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_a_com_at_rest_stays_exactly_where_it_is_under_a_torque_and_a_force_moves_it(name):
    body = RigidBody(2.0, (1.0, 1.6, 2.2))
    start = State.from_velocity(body, position=(1.0, -2.0, 0.5),
                                angular_velocity_body=(0.8, -0.5, 1.1))
    steps, dt = 100, 0.01
    turned = Simulator(body, start, integrator=name)
    turned.set_wrench(torque=(0.1, 0.2, 0.0))
    final = turned.run(steps * dt, dt)
    np.testing.assert_array_equal(final.position, start.position)
    np.testing.assert_array_equal(final.linear_momentum, start.linear_momentum)
    assert not np.array_equal(final.angular_momentum, start.angular_momentum)
    # From rest under a force, the COM falls the parabola.
    pushed = Simulator(body, start, integrator=name)
    pushed.set_wrench(force=(0.0, 0.0, -1.0))
    final = pushed.run(steps * dt, dt)
    np.testing.assert_allclose(final.position, start.position + 0.5 * (-1.0 / body.mass)
                               * (steps * dt) ** 2 * np.array([0.0, 0.0, 1.0]), atol=1e-14)


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_unforced_com_moves_uniformly_on_the_compiled_path(name):
    body = RigidBody(2.0, (1.0, 1.6, 2.2))
    start = State.from_velocity(body, position=(1.0, -2.0, 0.5), velocity=(0.3, -0.2, 0.6),
                                angular_velocity_body=(0.8, -0.5, 1.1))
    steps, dt = 1000, 0.01
    simulator = Simulator(body, start, integrator=name)
    simulator.set_wrench(torque=(0.0, 0.1, 0.0), frame='body')
    final = simulator.run(steps * dt, dt)
    np.testing.assert_array_equal(final.linear_momentum, start.linear_momentum)
    expected = start.position + steps * dt * start.velocity(body)
    # x + dt v added 1000 times (1000 rounded additions of ~|x| eps each).
    np.testing.assert_allclose(final.position, expected, rtol=0,
                               atol=steps * EPS * np.max(np.abs(expected)))


@pytest.mark.parametrize('name', ['first_order', 'buss', 'buss_plain', 'splitting',
                                  'splitting4', 'exact'])
def test_readable_steps_do_not_recompute_a_com_at_rest(name):
    # The position array itself comes back: nothing was computed for it (rk4's readable
    # step integrates x like every other variable).
    body = RigidBody(2.0, (1.0, 1.6, 2.2))
    start = State.from_velocity(body, position=(1.0, -2.0, 0.5),
                                angular_velocity_body=(0.8, -0.5, 1.1))

    def torque_only(state, time):
        return np.zeros(3), np.array([0.1, 0.2, 0.0])

    for wrench in (None, torque_only):
        state = start
        for _ in range(3):
            state = INTEGRATORS[name](body, state, 0.0, 0.01, wrench)
        assert state.position is start.position


def _torque_free_scenes():
    return [name for name in scene_names()
            if all(effect.effect_name == 'external_wrench' for effect in load_scene(name).effects)]


def test_the_models_of_the_scenes_hold_only_what_they_name():
    names = _torque_free_scenes()
    assert {'default', 't_handle', 'van_zon'} <= set(names)
    for name in names:
        simulator = load_scene(name).simulator()
        model = simulator._model
        # No term, no flow, nothing held: the kernel takes no kick.
        assert (model.term_count, model.flow_count, model.constrained) == (0, 0, False), name
        assert simulator.wrench_function() is None
    for name in ('heavy_top', 'bike_wheel'):
        model = load_scene(name).simulator()._model
        # Gravity's one term, transmitted about the pivot.
        assert (model.term_count, model.flow_count, model.constrained) == (1, 0, True)
    model = load_scene('thrown_box').simulator()._model
    assert (model.term_count, model.flow_count, model.constrained) == (1, 0, False)
    model = load_scene('flat_spin').simulator()._model
    assert (model.term_count, model.flow_count, model.constrained) == (0, 1, False)


@pytest.mark.parametrize('name', ['heavy_top', 'bike_wheel'])
def test_pivot_scenes_never_translate(name):
    scene = load_scene(name)
    simulator = scene.simulator(tolerance=0.0)
    start = simulator._integrated_state()
    simulator.run(100 * scene.dt, scene.dt)
    integrated = simulator._integrated_state()
    # The pivot system's origin is the anchor and its linear momentum zero, exactly.
    np.testing.assert_array_equal(integrated.position, start.position)
    np.testing.assert_array_equal(integrated.linear_momentum, np.zeros(3))


# -- 4. one fast path for the node (step per tick) and the offline tools (run)


@pytest.mark.parametrize('name', ['default', 'heavy_top', 'flat_spin', 'thrown_box'])
def test_single_steps_and_one_run_give_the_same_trajectory_bit_for_bit(name):
    scene = load_scene(name)
    ticked, bulk = scene.simulator(), scene.simulator()
    for k in range(200):
        ticked.step(scene.dt)
        if k % 7 == 0:
            # Reading the state (as the node does to publish) must not disturb the run.
            assert ticked.state.rotation.shape == (3, 3)
    bulk.run(200 * scene.dt, scene.dt)
    assert ticked.state == bulk.state
    assert ticked.time == bulk.time


def test_a_returned_state_is_an_immutable_snapshot():
    scene = load_scene('heavy_top')
    simulator = scene.simulator()
    first = simulator.step(scene.dt)
    copy = [np.array(a) for a in first._fields()]
    simulator.step(scene.dt)
    simulator.run(0.1, scene.dt)
    for kept, now in zip(copy, first._fields()):
        np.testing.assert_array_equal(now, kept)
    with pytest.raises(ValueError):
        first.quaternion[0] = 0.0
    assert simulator.state is simulator.state
    assert simulator.state != first


def test_setting_the_state_restarts_from_it_exactly():
    scene = load_scene('t_handle')
    simulator = scene.simulator()
    simulator.run(1.0, scene.dt)
    simulator.state = scene.state
    assert simulator.state is scene.state
    again = scene.simulator()
    assert simulator.run(1.0, scene.dt) == again.run(1.0, scene.dt)

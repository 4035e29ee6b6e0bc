"""
The Simulator's compiled paths: everything runs compiled, equal to the references, no more.

That a pivot with gravity and dissipation run compiled under every integrator, equal the
independent references of their methods (test/method_reference.py) and keep each method's
order, that each step evaluates the wrench as often as its registration says, and that the
model holds only what the scene calls for.

Frames world, units SI.  Round-off bounds: a kernel and its method's reference evaluate the
same formulas in another form and order, each step adding a few eps that then add up over a
non-chaotic run; 10 eps per wrench evaluation per step (steps x stages of the method, and
two turns a step for a flow) bounds that.
"""

import math

from method_reference import dop853_solution
from method_reference import Motion
from method_reference import motion_error
from method_reference import pivot_system
from method_reference import reference_run
import numpy as np
import pytest
from reference import random_rotation
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
from rigid_body_sim.physics.simulator import COMPILED
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import scene_names
from spy_effects import CountingWrench
from spy_effects import evaluations

EPS = np.finfo(float).eps
COMPILED_NAMES = sorted(INTEGRATORS)
ROUNDINGS = 10
# The held wrench of the pivot problems: every part, so each reaches the kernel.
HELD = {'force_world': (0.1, 0.0, 0.0), 'torque_world': (0.0, 0.01, 0.0),
        'force_body': (0.05, 0.0, 0.1), 'torque_body': (0.0, 0.0, 0.002)}


class _MomentumDependentCount(CountingWrench):
    momentum_dependent = True


def _evaluations_per_step(name, effect):
    """Return the wrench evaluations per step of integrator `name`, counted by a spy term."""
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    simulator = Simulator(body, State(), integrator=name, effects=[effect])
    simulator.run(0.1, 0.01)
    return evaluations(simulator) / 10


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_each_step_evaluates_the_wrench_as_often_as_its_registration_says(name):
    # One evaluation per wrench sample (a kick, an RK stage); a momentum-dependent wrench
    # adds one per kick-drift-kick stage: the opening kick's midpoint rule (the closing kick
    # starts from its estimate, kernels/model.py's impulse).
    integrator = INTEGRATORS[name]
    assert _evaluations_per_step(name, CountingWrench()) == integrator.stages
    assert _evaluations_per_step(name, _MomentumDependentCount()) == (
        integrator.stages + len(integrator.kicks))


@pytest.mark.parametrize('scene_name', ['heavy_top', 'bike_wheel', 'flat_spin'])
@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_pivot_and_dissipation_scenes_run_compiled_with_every_integrator(scene_name, name):
    simulator = load_scene(scene_name).simulator(integrator=name)
    assert simulator.path == COMPILED


def _round_off(name, steps, flows=0):
    return ROUNDINGS * EPS * steps * (INTEGRATORS[name].stages + 2 * flows)


def _top():
    """Return a box pivoted off every principal axis, spinning and tilted (body, state, pivot)."""
    rng = np.random.default_rng(7)
    body = RigidBody.box(0.5, (0.08, 0.05, 0.02))
    state = State.from_velocity(body, rotation=random_rotation(rng),
                                angular_velocity_body=(2.0, -3.0, 25.0))
    return body, state, Pivot(point=(0.01, -0.02, -0.06), anchor=(0.1, 0.0, 0.2))


def _pivot_simulator(name, held=True):
    body, state, pivot = _top()
    simulator = Simulator(body, state, integrator=name, effects=[pivot, Gravity()])
    if held:
        simulator.hold_wrench(**HELD)
    return simulator


# -- 1. a constant force under a pivot: compiled, equal to the reference, orders kept


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_pivot_with_gravity_runs_compiled_and_equals_its_reference(name):
    compiled = _pivot_simulator(name)
    assert compiled.path == COMPILED
    steps = 500
    compiled.run(steps * 1e-3, 1e-3)
    body, state, pivot = _top()
    reference = reference_run(name, body, state, 1e-3, steps, effects=[pivot, Gravity()],
                              held=HELD)
    # The body turned well away from the start: a dropped lever torque could not hide.
    assert rotation_angle_between(compiled.state.rotation, state.rotation) > 1.0
    angle, vectors = motion_error(compiled.state, reference)
    assert max(angle, vectors) <= _round_off(name, steps), (angle, vectors)
    assert compiled.time == pytest.approx(steps * 1e-3, rel=4 * EPS)


def _pivot_reference(duration):
    """Return the physical state after `duration` s, from DOP853 on the pivot system."""
    body, state, pivot = _top()
    system = pivot_system(pivot, body)
    weight = body.mass * np.array(Gravity().acceleration)

    def wrench(physical, time):
        # The held wrench and the weight at the COM (world frame).
        rotation = physical.rotation
        return (np.array(HELD['force_world']) + weight + rotation @ HELD['force_body'],
                np.array(HELD['torque_world']) + rotation @ HELD['torque_body'])

    start = system.reduce(system.project(Motion.of(state)))
    final = system.expand(dop853_solution(system.body, start, duration,
                                          system.transmit(wrench)))
    return State(final.rotation, final.position, final.linear_momentum,
                 final.angular_momentum)


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
        simulator = _pivot_simulator(name)
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


def test_compiled_pivot_expansion_equals_its_reference():
    rng = np.random.default_rng(11)
    body, _, pivot = _top()
    constraint = pivot.constrain(body)
    system = pivot_system(pivot, body)
    # omega = I_pivot^{-1} R^T L, then two rotations and two cross products: a few eps each,
    # amplified by the conditioning of the inertia about the pivot.
    tolerance = 32 * EPS * np.linalg.cond(constraint.body.inertia)
    for _ in range(20):
        pivot_state = State(random_rotation(rng), pivot.anchor, np.zeros(3),
                            rng.normal(size=3))
        expected = system.expand(Motion.of(pivot_state))
        compiled = State._from_values(constraint.expand_values(
            np.concatenate(pivot_state._fields())))
        angle, vectors = motion_error(compiled, expected)
        assert max(angle, vectors) <= tolerance, (angle, vectors)


# -- 2. the dissipation flow fused into the compiled loop


@pytest.mark.parametrize('name', COMPILED_NAMES)
def test_dissipation_is_fused_into_the_compiled_run_and_equals_its_reference(name):
    rng = np.random.default_rng(12)
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    state = State.from_velocity(body, rotation=random_rotation(rng),
                                angular_velocity_body=(0.4, 3.0, 0.3))
    fused = Simulator(body, state, integrator=name, effects=[Dissipation(0.05)])
    assert fused.path == COMPILED
    steps = 500
    fused.run(steps * 0.01, 0.01)
    reference = reference_run(name, body, state, 0.01, steps, effects=[Dissipation(0.05)])
    # The spin left the middle axis: the flow did act.
    assert abs(fused.state.angular_velocity_body(body)[1]) < 2.5
    angle, vectors = motion_error(fused.state, reference)
    assert max(angle, vectors) <= _round_off(name, steps, flows=1), (angle, vectors)
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


def _torque_free_scenes():
    return [name for name in scene_names(several_bodies=False)
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

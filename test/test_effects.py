"""
Effects: the registry, what the Simulator evaluates, and each effect against its law.

Frames world, units SI.  Accuracy bounds follow the method order: the scenes' default
integrator (buss) is second order, so halving the step must divide an error by ~4.
"""

import math
from pathlib import Path

from method_reference import buss_drift
from method_reference import kick
from method_reference import Motion
from method_reference import motion_error
from method_reference import REFERENCE_EFFECTS
from method_reference import reference_run
import numpy as np
import pytest
from reference import random_rotation
from reference import rotation_angle_between
from rigid_body_sim.physics import effects as effects_package
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects import create_effect
from rigid_body_sim.physics.effects import Dissipation
from rigid_body_sim.physics.effects import Drag
from rigid_body_sim.physics.effects import effect_parameters
from rigid_body_sim.physics.effects import EFFECTS
from rigid_body_sim.physics.effects import ExternalWrench
from rigid_body_sim.physics.effects import Gravity
from rigid_body_sim.physics.effects import ParameterError
from rigid_body_sim.physics.effects import Pivot
from rigid_body_sim.physics.effects import register_effect
from rigid_body_sim.physics.effects import SinusoidalTorque
from rigid_body_sim.physics.rotations import quaternion_multiply
from scipy.integrate import solve_ivp

# Second order: halving the step divides the error by 4; allow 3.4..4.6 for the next
# order's share at these steps (checked: the ratios measured are within 1 % of 4).
SECOND_ORDER_RATIO = (3.4, 4.6)


def _asymmetric_body(mass=2.0):
    return RigidBody.box(mass, (0.3, 0.2, 0.1))


def _random_state(body, rng, speed=1.0, spin=3.0):
    return State.from_velocity(body, rotation=random_rotation(rng),
                               position=rng.normal(size=3),
                               velocity=speed * rng.normal(size=3),
                               angular_velocity_body=spin * rng.normal(size=3))


# -- registry


def test_registry_holds_the_effect_of_each_module_by_name():
    # Each module of physics/effects/ but the registry and the plugin loader registers one
    # effect, named as the module (another registered from outside the package would be an
    # addition).
    folder = Path(effects_package.__file__).parent
    modules = {path.stem for path in folder.glob('*.py')} - {'__init__', 'registry',
                                                             'plugins'}
    assert modules <= set(EFFECTS)
    for name in modules:
        assert EFFECTS[name].__module__.rsplit('.', 1)[-1] == name
    for name, cls in EFFECTS.items():
        assert cls.effect_name == name
        assert (cls.__doc__ or '').strip(), f'effect {name} has no docstring'


def test_create_effect_reads_parameters_from_the_signature():
    assert effect_parameters('pivot')['anchor'] == (0.0, 0.0, 0.0)
    pivot = create_effect('pivot', {'point': [0, 0, -1]})
    assert isinstance(pivot, Pivot)
    np.testing.assert_array_equal(pivot.point, [0.0, 0.0, -1.0])
    assert isinstance(create_effect('gravity'), Gravity)


@pytest.mark.parametrize('name, parameters, key, words', [
    ('pivot', {}, 'point', 'missing'),
    ('pivot', {'point': [1, 2]}, 'point', 'expected 3 numbers, got 2'),
    ('pivot', {'point': [1, 2, 'x']}, 'point', 'item 2'),
    ('gravity', {'g': 9.81}, 'g', 'unknown parameter'),
    ('drag', {'linear': -1.0}, 'linear', 'must be >= 0'),
    ('drag', {'linear': True}, 'linear', 'boolean'),
    ('drag', {'quadratic': '0.1'}, 'quadratic', 'string'),
    ('dissipation', {'damping': 0.0}, 'damping', 'must be > 0'),
    ('external_wrench', {'max_torque': float('inf')}, 'max_torque', 'finite'),
])
def test_bad_effect_parameters_are_errors_naming_the_parameter(name, parameters, key, words):
    with pytest.raises(ParameterError) as caught:
        create_effect(name, parameters)
    assert caught.value.key == key
    assert words in caught.value.problem


def test_unknown_effect_is_an_error_listing_the_valid_ones():
    valid = ', '.join(sorted(EFFECTS))
    with pytest.raises(ValueError) as caught:
        create_effect('magnetism')
    assert str(caught.value) == f"unknown effect 'magnetism'; valid effects: {valid}"
    assert set(valid.split(', ')) == set(EFFECTS)


def test_registering_a_name_twice_is_an_error():
    with pytest.raises(ValueError, match='registered twice'):
        register_effect('gravity')(type('Other', (), {}))


def test_drag_without_any_coefficient_is_an_error():
    with pytest.raises(ValueError, match='every coefficient is zero'):
        Drag()


# -- only what a scene names is computed


def test_a_scenes_model_holds_exactly_the_terms_flows_and_constraint_it_names():
    body = _asymmetric_body()
    state = State.from_velocity(body, angular_velocity_body=(1, 2, 3))
    cases = (([], 0, 0, False), ([ExternalWrench()], 0, 0, False), ([Gravity()], 1, 0, False),
             ([Pivot(point=(0, 0, -0.1)), Gravity()], 1, 0, True),
             ([Drag(linear=0.1), SinusoidalTorque((0, 0, 1), 1.0)], 2, 0, False),
             ([Dissipation(0.1)], 0, 1, False))
    for effects, terms, flows, constrained in cases:
        model = Simulator(body, state, effects=effects)._model
        assert (model.term_count, model.flow_count, model.constrained) == (
            terms, flows, constrained), effects


def test_an_unused_external_wrench_costs_nothing_and_a_held_one_pushes():
    # external_wrench only marks that the body may be pushed: the same bits as without it.
    body = _asymmetric_body()
    state = State.from_velocity(body, angular_velocity_body=(1, 2, 3))
    marked = Simulator(body, state, effects=[ExternalWrench()])
    assert marked.wrench_function() is None
    assert marked.run(0.1, 0.01) == Simulator(body, state).run(0.1, 0.01)
    marked.set_wrench(torque=(0.0, 0.0, 1.0))
    assert not np.array_equal(marked.step(0.01).angular_momentum, state.angular_momentum)


def test_gravity_gives_the_exact_parabola_of_the_com():
    body = _asymmetric_body()
    state = _random_state(body, np.random.default_rng(1))
    simulator = Simulator(body, state, effects=[Gravity()])
    simulator.run(1.0, 0.01)
    # Leapfrog is exact for a constant force.
    g = np.array([0.0, 0.0, -9.81])
    expected = state.position + state.velocity(body) + 0.5 * g
    np.testing.assert_allclose(simulator.state.position, expected, rtol=0, atol=1e-13)
    np.testing.assert_allclose(simulator.state.linear_momentum,
                               state.linear_momentum + body.mass * g, rtol=0, atol=1e-13)


def test_rotational_drag_leaves_the_translation_untouched():
    body = _asymmetric_body()
    state = _random_state(body, np.random.default_rng(2))
    simulator = Simulator(body, state, effects=[Drag(rotational_linear=0.01)])
    final = simulator.run(1.0, 0.01)
    np.testing.assert_array_equal(final.linear_momentum, state.linear_momentum)
    np.testing.assert_allclose(final.position, state.position + state.velocity(body),
                               rtol=0, atol=1e-14)
    assert np.linalg.norm(final.angular_momentum) < np.linalg.norm(state.angular_momentum)


def test_an_effect_with_a_python_wrench_only_is_refused_naming_what_to_write():
    body = _asymmetric_body()
    state = State.from_velocity(body)

    class Push:

        def wrench(self, body, state, time):
            return np.array([1.0, 0.0, 0.0]), np.zeros(3)

    with pytest.raises(ValueError, match='compiled_wrench') as caught:
        Simulator(body, state, effects=[Push()])
    assert 'wrench_term' in str(caught.value) and '\n' not in str(caught.value)


# -- external_wrench


def test_external_wrench_limit_scales_down_and_keeps_direction():
    effect = ExternalWrench(max_force=2.0, max_torque=0.5)
    force, torque = effect.limit([3.0, 4.0, 0.0], [0.0, 0.1, 0.0])
    np.testing.assert_allclose(force, [1.2, 1.6, 0.0])
    np.testing.assert_array_equal(torque, [0.0, 0.1, 0.0])
    force, torque = ExternalWrench().limit([3.0, 4.0, 0.0], [0.0, 9.0, 0.0])
    np.testing.assert_array_equal(force, [3.0, 4.0, 0.0])
    assert ExternalWrench.accepts_external_wrench


# -- gravity


def test_gravity_energy_is_conserved_along_the_flight():
    body = _asymmetric_body()
    state = _random_state(body, np.random.default_rng(3))
    simulator = Simulator(body, state, effects=[Gravity()])
    energy = simulator.energy()
    assert energy == pytest.approx(
        state.kinetic_energy(body) + body.mass * 9.81 * state.position[2], rel=1e-15)
    simulator.run(2.0, 0.01)
    # Translation exact, rotation torque-free: only the free step's own energy error,
    # bounded by (|omega| dt)^2 relative for buss.
    omega = np.linalg.norm(state.angular_velocity(body))
    assert simulator.energy() == pytest.approx(energy, rel=(omega * 0.01) ** 2)


def test_gravity_potential_follows_any_field_direction():
    body = _asymmetric_body()
    state = State(position=(1.0, 2.0, 3.0))
    gravity = Gravity(acceleration=(1.0, 0.0, 0.0))
    assert gravity.potential_energy(body, state) == -body.mass * 1.0
    force, torque = gravity.wrench(body, state, 0.0)
    np.testing.assert_array_equal(force, [body.mass, 0.0, 0.0])
    np.testing.assert_array_equal(torque, [0.0, 0.0, 0.0])


# -- drag


def _drag_error(effect, body, state, exact, duration, dt):
    final = Simulator(body, state, effects=[effect]).run(duration, dt)
    return exact(final)


@pytest.mark.parametrize('case', ['linear', 'quadratic', 'rotational_linear',
                                  'rotational_quadratic'])
def test_drag_follows_its_closed_form_to_second_order(case):
    mass, duration = 2.0, 2.0
    body = RigidBody.sphere(mass, 0.5)  # I = 0.2 kg m^2 about every axis
    moment = body.inertia[0, 0]
    v0 = np.array([1.0, -2.0, 0.5])
    w0 = np.array([3.0, 1.0, -2.0])
    state = State.from_velocity(body, velocity=v0, angular_velocity_world=w0)
    c = 0.4
    effect = Drag(**{case: c})
    if case == 'linear':       # m dv/dt = -c v
        expected = v0 * math.exp(-c * duration / mass)
    elif case == 'quadratic':  # m dv/dt = -c |v| v
        expected = v0 / (1.0 + c * np.linalg.norm(v0) * duration / mass)
    elif case == 'rotational_linear':  # I dw/dt = -c w (a sphere: omega stays parallel to L)
        expected = w0 * math.exp(-c * duration / moment)
    else:
        expected = w0 / (1.0 + c * np.linalg.norm(w0) * duration / moment)

    def error(final):
        got = (final.velocity(body) if case in ('linear', 'quadratic')
               else final.angular_velocity(body))
        return np.linalg.norm(got - expected) / np.linalg.norm(expected)

    coarse = _drag_error(effect, body, state, error, duration, 0.02)
    fine = _drag_error(effect, body, state, error, duration, 0.01)
    assert SECOND_ORDER_RATIO[0] < coarse / fine < SECOND_ORDER_RATIO[1]
    assert coarse < 1e-3


def test_a_closing_kick_started_from_the_estimate_keeps_the_error_of_two_evaluations():
    # A Buss step evaluates drag three times (kernels/model.py's impulse: the closing kick's
    # midpoint starts from the opening kick's extrapolated estimate).  Against the same step
    # whose kicks each evaluate it twice (test/method_reference.py's kick without an
    # estimate around its Buss drift), strong drag on a tumbling box: the same error at
    # second order, within 5 %.
    body = RigidBody.box(1.0, (0.4, 0.2, 0.1))
    state = State.from_velocity(body, angular_velocity_body=(2.0, 3.0, 0.5),
                                velocity=(1.0, 0.5, 0.0))
    drag = Drag(linear=0.5, quadratic=0.3, rotational_linear=2e-3, rotational_quadratic=1e-3)
    duration = 2.0
    reference = Simulator(body, state, integrator='rk4', effects=[drag]).run(duration, 1e-4)
    wrench = REFERENCE_EFFECTS['drag'][1](drag, body)
    wrench.momentum_dependent = True

    def error(final):
        return (np.linalg.norm(final.angular_momentum - reference.angular_momentum)
                + np.linalg.norm(final.linear_momentum - reference.linear_momentum))

    def four_evaluations(dt):
        current, half = Motion.of(state), 0.5 * dt
        for k in range(round(duration / dt)):
            current = kick(current, k * dt, half, wrench)[0]
            current = buss_drift(body, current, dt)
            current = kick(current, (k + 1) * dt, half, wrench)[0]
        return current

    errors = {}
    for dt in (0.02, 0.01):
        three = error(Simulator(body, state, effects=[drag]).run(duration, dt))
        four = error(four_evaluations(dt))
        assert 0.95 < three / four < 1.05, (dt, three, four)
        errors[dt] = three
    assert SECOND_ORDER_RATIO[0] < errors[0.02] / errors[0.01] < SECOND_ORDER_RATIO[1]


# -- pivot


def test_pivot_inertia_is_the_inertia_about_the_pivot_of_the_mass_points():
    rng = np.random.default_rng(4)
    masses = rng.uniform(0.5, 2.0, size=6)
    positions = rng.normal(size=(6, 3))
    body = RigidBody.from_point_masses(masses, positions)
    pivot_world = rng.normal(size=3)
    # The pivot in the body frame, measured from the COM.
    point = pivot_world - body.center_of_mass
    relative = positions - pivot_world
    about_pivot = (np.eye(3) * np.sum(masses * np.einsum('ij,ij->i', relative, relative))
                   - np.einsum('i,ij,ik->jk', masses, relative, relative))
    constraint = Pivot(point=point).constrain(body)
    np.testing.assert_allclose(constraint.body.inertia, about_pivot, rtol=1e-12)
    np.testing.assert_allclose(constraint.offset_body, -point)


def _top(point=(0.0, 0.0, -0.04), spin=150.0, tilt=0.5):
    body = RigidBody.cylinder(0.3, 0.04, 0.01)
    rotation = [math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)]
    state = State.from_velocity(body, rotation=rotation,
                                angular_velocity_body=(0.3, -0.2, spin))
    return body, state, Pivot(point=point, anchor=(0.1, -0.2, 0.3))


def test_pivot_holds_the_body_point_at_the_anchor_and_the_com_follows():
    body, state, pivot = _top()
    simulator = Simulator(body, state, effects=[pivot, Gravity()])
    for _ in range(50):
        current = simulator.run(0.01, 0.001)
        np.testing.assert_allclose(current.position + current.rotation @ pivot.point,
                                   pivot.anchor, rtol=0, atol=1e-15)
        # The COM velocity is that of a point of a body turning about the pivot.
        r = current.rotation @ -pivot.point
        np.testing.assert_allclose(current.velocity(body),
                                   np.cross(current.angular_velocity(body), r),
                                   rtol=0, atol=1e-13)


def test_pivot_state_maps_round_trip_and_convert_the_angular_momentum():
    body, state, pivot = _top()
    constraint = pivot.constrain(body)
    physical = constraint.project(state)
    reduced = constraint.reduce(physical)
    r = physical.rotation @ constraint.offset_body
    # L_pivot = L_com + r x p, and L_pivot = I_pivot_world omega.
    np.testing.assert_allclose(reduced.angular_momentum,
                               physical.angular_momentum + np.cross(r, physical.linear_momentum),
                               rtol=1e-14)
    np.testing.assert_allclose(
        reduced.angular_momentum,
        physical.rotation @ constraint.body.inertia @ physical.angular_velocity_body(body),
        rtol=1e-13)
    back = constraint.expand(reduced)
    for got, want in zip(back._fields(), physical._fields()):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-16)
    # Projection keeps the rotation and the angular velocity of the given state.
    np.testing.assert_allclose(physical.angular_velocity(body), state.angular_velocity(body),
                               rtol=1e-14)


def test_pivot_energy_is_the_rotational_energy_about_the_pivot_plus_m_g_z():
    body, state, pivot = _top()
    simulator = Simulator(body, state, effects=[pivot, Gravity()])
    simulator.run(0.05, 0.001)
    current = simulator.state
    constraint = pivot.constrain(body)
    omega = current.angular_velocity(body)
    expected = (0.5 * omega @ constraint.angular_momentum_about_pivot(current)
                + body.mass * 9.81 * current.position[2])
    assert simulator.energy() == pytest.approx(expected, rel=1e-13)


def test_pivot_at_the_com_turns_like_the_free_body():
    body, state, _ = _top()
    pivoted = Simulator(body, state, effects=[Pivot(point=(0.0, 0.0, 0.0))]).run(1.0, 0.001)
    free = Simulator(body, state).run(1.0, 0.001)
    assert rotation_angle_between(pivoted.rotation, free.rotation) < 1e-12
    np.testing.assert_allclose(pivoted.angular_momentum, free.angular_momentum, rtol=1e-13)
    np.testing.assert_array_equal(pivoted.position, [0.0, 0.0, 0.0])


def test_pivot_with_a_held_torque_takes_the_kernel_and_equals_its_reference():
    body, state, pivot = _top()
    torque = (0.0, 0.01, 0.02)
    fast = Simulator(body, state, effects=[pivot])
    fast.set_wrench(torque=torque)
    fast.run(0.5, 0.001)
    reference = reference_run(fast.integrator, body, state, 0.001, 500, effects=[pivot],
                              held={'torque_world': torque})
    # Round-off (test_fast_paths): 10 eps per wrench evaluation per step.
    bound = 10 * np.finfo(float).eps * 500 * 2
    assert max(motion_error(fast.state, reference)) <= bound
    # A world torque about the pivot: L_pivot(t) = L_pivot(0) + tau t exactly.
    constraint = pivot.constrain(body)
    np.testing.assert_allclose(
        constraint.angular_momentum_about_pivot(fast.state),
        constraint.angular_momentum_about_pivot(constraint.project(state))
        + 0.5 * np.array(torque), rtol=1e-12)


def test_a_body_with_two_pivots_is_rejected():
    body, state, pivot = _top()
    with pytest.raises(ValueError, match='at most one constraint'):
        Simulator(body, state, effects=[pivot, Pivot(point=(0.0, 0.0, 0.04))])


# -- dissipation


def _rotational_energy(body, state):
    return 0.5 * state.angular_velocity(body) @ state.angular_momentum


def test_dissipation_flow_keeps_world_angular_momentum_exactly_and_drains_energy():
    rng = np.random.default_rng(5)
    body = _asymmetric_body()
    effect = Dissipation(damping=0.3)
    for _ in range(5):
        state = _random_state(body, rng)
        energies = [_rotational_energy(body, state)]
        current = state
        for _ in range(100):
            current = effect.flow(body, current, 0.01)
            energies.append(_rotational_energy(body, current))
        np.testing.assert_array_equal(current.angular_momentum, state.angular_momentum)
        np.testing.assert_array_equal(current.position, state.position)
        np.testing.assert_array_equal(current.linear_momentum, state.linear_momentum)
        assert np.all(np.diff(energies) < 0.0)


def test_dissipation_energy_rate_is_minus_eps_times_the_turning_squared():
    rng = np.random.default_rng(6)
    body = _asymmetric_body()
    effect = Dissipation(damping=0.2)
    h = 1e-4
    for _ in range(5):
        state = _random_state(body, rng)
        # Central difference: error O(h^2) relative, ~1e-8 here.
        rate = (_rotational_energy(body, effect.flow(body, state, h))
                - _rotational_energy(body, effect.flow(body, state, -h))) / (2.0 * h)
        assert rate == pytest.approx(effect.energy_rate(body, state), rel=1e-6)
        assert effect.energy_rate(body, state) < 0.0


def test_principal_spin_is_a_fixed_point_of_dissipation():
    body = _asymmetric_body()
    effect = Dissipation(damping=0.5)
    for axis in range(3):
        omega = np.zeros(3)
        omega[axis] = 4.0
        state = State.from_velocity(body, angular_velocity_body=omega)
        assert effect.energy_rate(body, state) == 0.0
        np.testing.assert_array_equal(effect.flow(body, state, 0.1).quaternion,
                                      state.quaternion)


def _dissipative_reference(body, state, damping, duration):
    """Return the rotation after `duration` s of dR/dt = R [Omega + eps m x Omega]x, L fixed."""
    angular_momentum = state.angular_momentum
    eps = damping / np.linalg.norm(angular_momentum)

    def rate(time, q):
        q = q / np.linalg.norm(q)
        rotation = State(q).rotation
        momentum_body = rotation.T @ angular_momentum
        omega_body = body.inertia_inverse @ momentum_body
        turn = omega_body + eps * np.cross(momentum_body, omega_body)
        # dq/dt = 1/2 q * (turn, 0): a body-frame rate acts on the right.
        return 0.5 * quaternion_multiply(q, np.append(turn, 0.0))

    solution = solve_ivp(rate, (0.0, duration), state.quaternion, method='DOP853',
                         rtol=1e-13, atol=1e-15)
    q = solution.y[:, -1]
    return State(q / np.linalg.norm(q)).rotation


def test_dissipation_composed_with_buss_is_second_order():
    body = _asymmetric_body()
    state = State.from_velocity(body, rotation=random_rotation(np.random.default_rng(7)),
                                angular_velocity_body=(0.4, 0.3, 3.0))
    damping, duration = 0.2, 2.0
    expected = _dissipative_reference(body, state, damping, duration)

    def error(dt):
        final = Simulator(body, state, effects=[Dissipation(damping)]).run(duration, dt)
        return rotation_angle_between(final.rotation, expected)

    coarse, fine = error(0.01), error(0.005)
    assert SECOND_ORDER_RATIO[0] < coarse / fine < SECOND_ORDER_RATIO[1]


def test_dissipation_flow_on_the_kernel_equals_its_reference_and_keeps_world_l():
    body = _asymmetric_body()
    state = State.from_velocity(body, angular_velocity_body=(0.4, 0.3, 3.0))
    simulator = Simulator(body, state, effects=[Dissipation(0.2)])
    final = simulator.run(1.0, 0.01)
    reference = reference_run(simulator.integrator, body, state, 0.01, 100,
                              effects=[Dissipation(0.2)])
    # Round-off (test_fast_paths): 10 eps per evaluation per step, the flow's two turns too.
    assert max(motion_error(final, reference)) <= 10 * np.finfo(float).eps * 100 * 4
    np.testing.assert_array_equal(final.angular_momentum, state.angular_momentum)

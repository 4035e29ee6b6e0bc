"""
The compiled kernels equal the readable step functions, and runs are deterministic.

Every integrator's kernel advances (q, x, p, L) in place under a wrench held in the world
and body frames and under every effect; it must compute what the readable step computes with
the same wrench given as a callable, to round-off (they differ only in the order of
floating-point operations and in the frame the turn is formed in).  Over 500 steps of a
generic motion round-off grows about linearly, so 1e-12 relative to each quantity's scale is
the bound.  The tables derive from the registries: a new integrator or effect is covered.
"""

import numpy as np
import pytest
from reference import random_rotation
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects import create_effect
from rigid_body_sim.physics.effects import EFFECTS

STEPS = 500
DT = 2e-2
ROUND_OFF = 1e-12

# (force_world, torque_world, force_body, torque_body): N and N m.
ZERO = np.zeros(3)
HELD_WRENCHES = {
    'torque_free': (ZERO, ZERO, ZERO, ZERO),
    'world': (np.array([0.4, -0.3, -9.81]), np.array([0.2, 0.5, -0.1]), ZERO, ZERO),
    'body': (ZERO, ZERO, np.array([1.0, 0.2, -0.5]), np.array([-0.3, 0.1, 0.4])),
    'world_and_body': (np.array([0.0, 0.0, -9.81]), np.array([0.1, 0.0, 0.0]),
                       np.array([0.5, 0.0, 0.0]), np.array([0.0, 0.0, 0.3])),
}


def _problem():
    rng = np.random.default_rng(606)
    axes = random_rotation(rng)
    body = RigidBody(2.0, axes @ np.diag([1.0, 1.6, 2.2]) @ axes.T)
    state = State.from_velocity(body, rotation=random_rotation(rng), position=(1.0, 2.0, -0.5),
                                velocity=(0.3, -0.2, 0.6), angular_velocity_body=(0.8, -0.5, 1.1))
    return body, state


def _wrench_function(held):
    force_world, torque_world, force_body, torque_body = held
    if not any(np.any(part) for part in held):
        return None

    def wrench(state, time):
        rotation = state.rotation
        return force_world + rotation @ force_body, torque_world + rotation @ torque_body

    return wrench


def _assert_states_agree(state, other, tolerance=ROUND_OFF):
    """Assert two states agree to `tolerance` relative (quaternion up to sign)."""
    q, r = state.quaternion, other.quaternion
    assert min(np.linalg.norm(q - r), np.linalg.norm(q + r)) <= tolerance
    for a, b in ((state.position, other.position),
                 (state.linear_momentum, other.linear_momentum),
                 (state.angular_momentum, other.angular_momentum)):
        scale = max(1.0, np.linalg.norm(a))
        assert np.linalg.norm(a - b) <= tolerance * scale, (a, b)


@pytest.mark.parametrize('held', sorted(HELD_WRENCHES))
@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_kernel_equals_the_readable_step_function(name, held):
    body, state = _problem()
    wrench = _wrench_function(HELD_WRENCHES[held])
    readable = state
    for k in range(STEPS):
        readable = INTEGRATORS[name](body, readable, k * DT, DT, wrench)
    compiled = _held_simulator(body, state, name, True, held).run(STEPS * DT, DT)
    # The motion is non-trivial: the body turned and moved.
    assert np.linalg.norm(compiled.quaternion - state.quaternion) > 0.1
    _assert_states_agree(compiled, readable)


def _held_simulator(body, state, name, fast, held):
    simulator = Simulator(body, state, integrator=name, fast=fast)
    force_world, torque_world, force_body, torque_body = HELD_WRENCHES[held]
    simulator.hold_wrench(force_world=force_world, torque_world=torque_world,
                          force_body=force_body, torque_body=torque_body)
    return simulator


@pytest.mark.parametrize('held', sorted(HELD_WRENCHES))
@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_simulator_fast_and_readable_paths_agree(name, held):
    body, state = _problem()
    fast = _held_simulator(body, state, name, True, held)
    slow = _held_simulator(body, state, name, False, held)
    fast.run(STEPS * DT, DT)
    slow.run(STEPS * DT, DT)
    _assert_states_agree(fast.state, slow.state)
    assert fast.time == slow.time


@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_set_wrench_frames_match_the_held_wrench_parts(name):
    body, state = _problem()
    force, torque = np.array([0.5, -1.0, 2.0]), np.array([0.3, 0.0, -0.2])
    for frame, parts in (('world', {'force_world': force, 'torque_world': torque}),
                         ('body', {'force_body': force, 'torque_body': torque})):
        by_frame = Simulator(body, state, integrator=name)
        by_frame.set_wrench(force=force, torque=torque, frame=frame)
        by_parts = Simulator(body, state, integrator=name)
        by_parts.hold_wrench(**parts)
        assert by_frame.run(100 * DT, DT) == by_parts.run(100 * DT, DT)


@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_simulator_readable_path_is_the_step_function_applied_in_order(name):
    body, state = _problem()
    simulator = _held_simulator(body, state, name, False, 'world_and_body')
    simulator.run(200 * DT, DT)
    wrench = simulator.wrench_function()
    expected = state
    for k in range(200):
        expected = INTEGRATORS[name](body, expected, k * DT, DT, wrench)
    assert simulator.state == expected


@pytest.mark.parametrize('fast', [True, False], ids=['fast', 'readable'])
@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_same_run_twice_is_bit_identical(name, fast):
    body, state = _problem()
    finals = []
    for _ in range(2):
        simulator = _held_simulator(body, state, name, fast, 'world_and_body')
        simulator.run(STEPS * DT / 2, DT)
        # Steps of varying size and a last partial step exercise the same paths again.
        for dt in (DT, DT / 3, 2 * DT):
            simulator.step(dt)
        simulator.run(0.105, 0.01)
        finals.append((simulator.state, simulator.time))
    assert finals[0][0] == finals[1][0]
    assert finals[0][1] == finals[1][1]


def _example(name):
    """Return the example instance of the effect `name` (its class's `example` parameters)."""
    return create_effect(name, EFFECTS[name].example)


def test_every_effect_gives_an_example_of_itself():
    # The tables below take them: an effect without one would be left out silently.
    for name, cls in EFFECTS.items():
        assert isinstance(getattr(cls, 'example', None), dict), name
        _example(name)


@pytest.mark.parametrize('effect', sorted(EFFECTS))
@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_every_effect_runs_compiled_under_every_integrator_as_the_readable_steps(name, effect):
    body, state = _problem()
    effects = [_example(effect)]
    compiled = Simulator(body, state, integrator=name, effects=effects)
    readable = Simulator(body, state, integrator=name, effects=effects, fast=False)
    for simulator in (compiled, readable):
        simulator.set_wrench(torque=(0.05, -0.02, 0.03), frame='body')
        simulator.run(100 * DT, DT)
    assert compiled.path == 'compiled' and readable.path == 'readable'
    _assert_states_agree(compiled.state, readable.state, 1e-11)
    assert np.all(np.isfinite(compiled.state.quaternion))

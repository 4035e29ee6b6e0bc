"""
The kernels equal the independent references of their methods, and runs are deterministic.

Every integrator's kernel advances (q, x, p, L) in place under a wrench held in the world and
body frames and under every effect.  test/method_reference.py writes each method again from its
equations, in another formulation (rotation matrices in the world frame for the seed's and
Buss's methods, the textbook RK4 on numpy arrays, matrix exponentials for the splittings,
DOP853 for the exact flow), and each effect from its law, calling no kernel: the two differ by
round-off only where both are right.

Round-off bound: each step rounds every quantity it forms to a few eps of its scale, and the
two implementations form them differently, so their results differ by up to ~10 eps per
wrench evaluation of the step (each evaluation brings a kick or a stage of arithmetic);
over a generic motion away from a separatrix such differences add up about linearly, so
ROUNDINGS eps x steps x stages, relative to each quantity's scale, is the bound.  The tables
derive from the registries: a new integrator or effect is covered, and fails here until its
reference is written.
"""

from method_reference import Motion
from method_reference import motion_error
from method_reference import REFERENCE_EFFECTS
from method_reference import reference_run
from method_reference import REFERENCE_STEPS
import numpy as np
import pytest
from reference import random_rotation
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects import create_effect
from rigid_body_sim.physics.effects import EFFECTS

EPS = np.finfo(float).eps
STEPS = 500
DT = 2e-2
ROUNDINGS = 10

# The held wrench (keyword arguments of Simulator.hold_wrench): N and N m.
HELD_WRENCHES = {
    'torque_free': {},
    'world': {'force_world': (0.4, -0.3, -9.81), 'torque_world': (0.2, 0.5, -0.1)},
    'body': {'force_body': (1.0, 0.2, -0.5), 'torque_body': (-0.3, 0.1, 0.4)},
    'world_and_body': {'force_world': (0.0, 0.0, -9.81), 'torque_world': (0.1, 0.0, 0.0),
                       'force_body': (0.5, 0.0, 0.0), 'torque_body': (0.0, 0.0, 0.3)},
}


def _problem():
    rng = np.random.default_rng(606)
    axes = random_rotation(rng)
    body = RigidBody(2.0, axes @ np.diag([1.0, 1.6, 2.2]) @ axes.T)
    state = State.from_velocity(body, rotation=random_rotation(rng), position=(1.0, 2.0, -0.5),
                                velocity=(0.3, -0.2, 0.6), angular_velocity_body=(0.8, -0.5, 1.1))
    return body, state


def _round_off(name, steps):
    return ROUNDINGS * EPS * steps * INTEGRATORS[name].stages


def _held_simulator(body, state, name, held):
    simulator = Simulator(body, state, integrator=name)
    simulator.hold_wrench(**HELD_WRENCHES[held])
    return simulator


def test_every_integrator_and_every_effect_has_an_independent_reference():
    assert set(REFERENCE_STEPS) == set(INTEGRATORS)
    # The package's own effects: the registry also holds the plugins that other tests of
    # this process loaded (test_effect_plugins' files), which are theirs to test.
    own = {name for name, effect in EFFECTS.items()
           if effect.__module__.startswith('rigid_body_sim.physics.effects.')}
    assert set(REFERENCE_EFFECTS) == own


@pytest.mark.parametrize('held', sorted(HELD_WRENCHES))
@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_kernel_equals_the_independent_reference_of_its_method(name, held):
    body, state = _problem()
    compiled = _held_simulator(body, state, name, held).run(STEPS * DT, DT)
    reference = reference_run(name, body, state, DT, STEPS, held=HELD_WRENCHES[held])
    # The motion is non-trivial: the body turned and moved.
    assert np.linalg.norm(compiled.quaternion - state.quaternion) > 0.1
    angle, vectors = motion_error(compiled, reference)
    assert max(angle, vectors) <= _round_off(name, STEPS), (angle, vectors)


def test_a_wrong_step_is_far_outside_the_round_off_bound():
    # The comparison can fail: buss against the reference of buss_plain (one term of h^2/12
    # apart) differs by the method's own error, orders of magnitude above round-off.
    body, state = _problem()
    compiled = Simulator(body, state, integrator='buss').run(STEPS * DT, DT)
    angle, _ = motion_error(compiled, reference_run('buss_plain', body, state, DT, STEPS))
    assert angle > 1e6 * _round_off('buss', STEPS)


# The interpreted kernels are the compiled ones' source: the same operations in the same
# order, so a step differs only where a library function (sqrt, sin, atan2) or numba's and
# Python's float formatting of a constant round differently: a few ulp per evaluation.
INTERPRETED_STEPS = 60
INTERPRETED_ROUNDINGS = 4


@pytest.mark.parametrize('held', sorted(HELD_WRENCHES))
@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_the_interpreted_kernels_take_the_compiled_steps(name, held):
    # A test of the compilation (kernels/interpreted.py runs the same source): what the node
    # integrates while its kernels compile must be what they compute once compiled.
    body, state = _problem()
    compiled = _held_simulator(body, state, name, held)
    interpreted = _held_simulator(body, state, name, held)
    interpreted.interpreted = True
    for simulator in (compiled, interpreted):
        simulator.run(INTERPRETED_STEPS * DT, DT)
    assert compiled.path == 'compiled' and interpreted.path == 'interpreted'
    bound = INTERPRETED_ROUNDINGS * EPS * INTERPRETED_STEPS * INTEGRATORS[name].stages
    angle, vectors = motion_error(compiled.state, Motion.of(interpreted.state))
    assert max(angle, vectors) <= bound, (angle, vectors)
    assert compiled.time == interpreted.time


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
def test_same_run_twice_is_bit_identical(name):
    body, state = _problem()
    finals = []
    for _ in range(2):
        simulator = _held_simulator(body, state, name, 'world_and_body')
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


EFFECT_STEPS = 100


@pytest.mark.parametrize('effect', sorted(EFFECTS))
@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_every_effect_runs_compiled_under_every_integrator_as_its_reference(name, effect):
    body, state = _problem()
    effects = [_example(effect)]
    held = {'torque_body': (0.05, -0.02, 0.03)}
    simulator = Simulator(body, state, integrator=name, effects=effects)
    simulator.hold_wrench(**held)
    final = simulator.run(EFFECT_STEPS * DT, DT)
    assert simulator.path == 'compiled'
    reference = reference_run(name, body, state, DT, EFFECT_STEPS, effects=effects, held=held)
    angle, vectors = motion_error(final, reference)
    # A flow adds its own turns, two a step, each like an evaluation's.
    evaluations = INTEGRATORS[name].stages + 2 * (effects[0].compiled_flow is not None)
    assert max(angle, vectors) <= ROUNDINGS * EPS * EFFECT_STEPS * evaluations, (angle, vectors)

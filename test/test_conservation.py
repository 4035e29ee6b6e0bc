"""
Conservation laws and exact solutions that the integrators must reproduce to round-off.

Torque-free, world L and p are constant (physics.md): the state holds world-frame momenta and
the seed's methods never touch them without a wrench, so they must stay bit-identical.  Under a
constant world torque L(t) = L0 + tau t and under a constant force the COM follows the
parabola x0 + v0 t + F t^2 / (2 m): their kicks integrate these exactly, so only round-off
(at most ~1 ulp per step and component) may separate them.  rk4 is the classical method on
the body momentum m = R^T L (integrators/rk4.py): its world L = R m is held to its order
(the error falls 16x when dt halves), its p and parabola exactly as the others'.  The
kinetic energy is not conserved exactly by any of these methods; its error must shrink at
the method's order and, for the second- and fourth-order methods, stay within
(|omega| dt)^order over long runs.
first_order gains energy at a rate derived in reference.first_order_energy_gain_rate,
dT/dt = dt/2 (omega x L)^T I_w^{-1} (omega x L) >= 0: its error grows with time, in
proportion to dt, and must follow that rate.
"""

import math

import numpy as np
import pytest
from reference import first_order_energy_gain_rate
from reference import random_rotation
from reference import torque_free_momentum_drift
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State

EPS = np.finfo(float).eps
# The methods whose torque-free step leaves world L untouched (registered as conserving it),
# and the others.
WORLD_MOMENTUM_METHODS = sorted(name for name, integrator in INTEGRATORS.items()
                                if 'angular_momentum' in integrator.conserves)
MOMENTUM_WRITING_METHODS = sorted(set(INTEGRATORS) - set(WORLD_MOMENTUM_METHODS))
# The methods whose energy is not conserved exactly (registered as not conserving it).
ENERGY_ERROR_METHODS = sorted(name for name, integrator in INTEGRATORS.items()
                              if 'rotational_energy' not in integrator.conserves)
# Halving dt must divide a fourth-order error by 16 within this factor.
CONVERGENCE_FACTOR = 1.3
LONG_RUN = 100_000


def _t_handle():
    rng = np.random.default_rng(501)
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    state = State.from_velocity(body, rotation=random_rotation(rng), position=(0.5, -1.0, 2.0),
                                velocity=(0.1, 0.2, -0.3), angular_velocity_body=(0.4, 1.0, 0.6))
    return body, state


def _tilted_tensor():
    rng = np.random.default_rng(502)
    axes = random_rotation(rng)
    body = RigidBody(2.5, axes @ np.diag([2.0, 3.0, 4.5]) @ axes.T)
    state = State.from_velocity(body, rotation=random_rotation(rng), position=(1.0, 2.0, 3.0),
                                velocity=(0.3, 0.0, 0.1), angular_velocity_body=(0.7, -0.9, 0.5))
    return body, state


BODIES = {'t_handle': _t_handle, 'tilted_tensor': _tilted_tensor}


@pytest.mark.parametrize('name', WORLD_MOMENTUM_METHODS)
def test_torque_free_world_momenta_are_bit_identical(name):
    # World-frame momenta as state make this exact: with no wrench, L and p are never
    # written.
    body, state = _t_handle()
    simulator = Simulator(body, state, integrator=name)
    steps = LONG_RUN
    dt = 1e-2
    final = simulator.run(steps * dt, dt)
    np.testing.assert_array_equal(final.angular_momentum, state.angular_momentum)
    np.testing.assert_array_equal(final.linear_momentum, state.linear_momentum)
    # x = x0 + v t, summed step by step: each step rounds x once (~1 ulp of |x|).
    expected = state.position + state.velocity(body) * (steps * dt)
    bound = steps * EPS * np.max(np.abs(expected)) * 2
    np.testing.assert_allclose(final.position, expected, rtol=0, atol=bound)


def _largest_momentum_error(name, body, state, dt, steps, torque=None):
    """Return max |L(t) - L0 - tau t| / |L0 + tau t| of `name` over 100 samples of the run."""
    simulator = Simulator(body, state, integrator=name)
    if torque is not None:
        simulator.set_wrench(torque=torque)
    worst = 0.0
    for _ in range(100):
        current = simulator.run(steps // 100 * dt, dt)
        expected = state.angular_momentum + (0.0 if torque is None else torque * simulator.time)
        worst = max(worst, np.linalg.norm(current.angular_momentum - expected)
                    / np.linalg.norm(expected))
    return worst, current


@pytest.mark.parametrize('name', MOMENTUM_WRITING_METHODS)
def test_torque_free_world_momentum_of_the_others_moves_only_at_their_order(name):
    """
    rk4 integrates m = R^T L, so world L = R m moves by the method's error, at its order.

    The T-handle, 1e4 steps of 0.02 s and 2e4 of 0.01 s: the largest relative error of L
    must fall 2^order within CONVERGENCE_FACTOR and stay within the bound of
    reference.torque_free_momentum_drift; p is never written.
    """
    body, state = _t_handle()
    dt, steps = 0.02, 10_000
    order = INTEGRATORS[name].order
    coarse, final = _largest_momentum_error(name, body, state, dt, steps)
    fine, _ = _largest_momentum_error(name, body, state, dt / 2, 2 * steps)
    assert (2.0 ** order / CONVERGENCE_FACTOR <= coarse / fine
            <= 2.0 ** order * CONVERGENCE_FACTOR)
    assert coarse * np.linalg.norm(state.angular_momentum) <= torque_free_momentum_drift(
        name, body, state, dt, steps)
    np.testing.assert_array_equal(final.linear_momentum, state.linear_momentum)


@pytest.mark.parametrize('name', MOMENTUM_WRITING_METHODS)
def test_constant_world_torque_gives_linear_angular_momentum_at_the_order_of_the_others(name):
    # rk4: the torque enters Euler's equations in the body frame at each stage, so L0 + tau t
    # is not integrated exactly but at the method's order (over 50 s the torque makes |L|
    # ~8x its start and the body spin up).
    body, state = _t_handle()
    torque = np.array([0.3, -0.7, 0.2])
    order = INTEGRATORS[name].order
    coarse, _ = _largest_momentum_error(name, body, state, 5e-3, 10_000, torque)
    fine, _ = _largest_momentum_error(name, body, state, 2.5e-3, 20_000, torque)
    assert (2.0 ** order / CONVERGENCE_FACTOR <= coarse / fine
            <= 2.0 ** order * CONVERGENCE_FACTOR)


@pytest.mark.parametrize('name', WORLD_MOMENTUM_METHODS)
def test_constant_world_torque_gives_linear_angular_momentum(name):
    body, state = _t_handle()
    torque = np.array([0.3, -0.7, 0.2])
    simulator = Simulator(body, state, integrator=name)
    simulator.set_wrench(torque=torque)
    steps = 20_000
    dt = 1e-3
    final = simulator.run(steps * dt, dt)
    expected = state.angular_momentum + torque * (steps * dt)
    # Each step adds dt tau to L in at most a few roundings: ~2 ulp of |L| per step.
    bound = 2 * steps * EPS * max(np.linalg.norm(expected), np.linalg.norm(state.angular_momentum))
    assert np.linalg.norm(final.angular_momentum - expected) <= bound
    np.testing.assert_array_equal(final.linear_momentum, state.linear_momentum)


@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_constant_force_moves_the_com_on_the_exact_parabola(name):
    body, state = _t_handle()
    force = np.array([0.0, 1.5, -9.81]) * body.mass
    simulator = Simulator(body, state, integrator=name)
    simulator.set_wrench(force=force)
    steps = 20_000
    dt = 1e-3
    duration = steps * dt
    final = simulator.run(duration, dt)
    velocity = state.velocity(body)
    expected_position = (state.position + velocity * duration
                         + force * duration ** 2 / (2.0 * body.mass))
    expected_momentum = state.linear_momentum + force * duration
    # Round-off: ~2 ulp of the largest magnitude per step, for x and for p.
    bound_position = 2 * steps * EPS * np.max(np.abs(expected_position))
    bound_momentum = 2 * steps * EPS * np.max(np.abs(expected_momentum))
    np.testing.assert_allclose(final.position, expected_position, rtol=0, atol=bound_position)
    np.testing.assert_allclose(final.linear_momentum, expected_momentum, rtol=0,
                               atol=bound_momentum)
    # A force through the COM exerts no torque: L is as torque-free.
    drift = torque_free_momentum_drift(name, body, state, dt, steps)
    if drift == 0.0:
        np.testing.assert_array_equal(final.angular_momentum, state.angular_momentum)
    else:
        assert np.linalg.norm(final.angular_momentum - state.angular_momentum) <= drift


def _max_energy_error(body, state, name, dt, duration, sample):
    """Return max |E(t) - E0| / E0 over samples every `sample` s (a multiple of dt)."""
    simulator = Simulator(body, state, integrator=name)
    initial = simulator.energy()
    worst = 0.0
    for _ in range(int(round(duration / sample))):
        simulator.run(sample, dt)
        worst = max(worst, abs(simulator.energy() - initial) / initial)
    return worst


# dt by the method's order, in the asymptotic range: a fourth-order energy error at 0.01 s is
# near round-off.
ENERGY_STEPS = {1: 1e-2, 2: 1e-2, 4: 4e-2}


@pytest.mark.parametrize('body_name', sorted(BODIES))
@pytest.mark.parametrize('name', ENERGY_ERROR_METHODS)
def test_energy_error_shrinks_at_least_at_the_method_order(name, body_name):
    body, state = BODIES[body_name]()
    order = INTEGRATORS[name].order
    dt = ENERGY_STEPS[order]
    coarse = _max_energy_error(body, state, name, dt, 20.0, 0.2)
    fine = _max_energy_error(body, state, name, dt / 2, 20.0, 0.2)
    observed = math.log2(coarse / fine)
    # The energy error may converge faster than the state (it is a conserved quantity of
    # the exact flow), never slower.
    assert observed >= order - 0.3, (coarse, fine)
    assert fine > 1e3 * EPS


# dt of the long runs by the method's order.
LONG_RUN_STEPS = {2: 2.5e-3, 4: 1e-2}


@pytest.mark.parametrize('body_name', sorted(BODIES))
@pytest.mark.parametrize('name', sorted(name for name in ENERGY_ERROR_METHODS
                                        if INTEGRATORS[name].order >= 2))
def test_energy_error_stays_within_the_order_bound_over_a_long_run(name, body_name):
    # The error band of an order-p method is ~ (|omega| dt)^p; Buss's methods also drift,
    # but at O(dt^3 t), which must not leave the band within 1e5 steps.  (A first-order
    # method's energy drifts at O(dt t) and leaves any fixed band: the next test follows
    # first_order's drift.)
    body, state = BODIES[body_name]()
    order = INTEGRATORS[name].order
    dt = LONG_RUN_STEPS[order]
    omega = np.linalg.norm(state.angular_velocity(body))
    worst = _max_energy_error(body, state, name, dt, LONG_RUN * dt, 100 * dt)
    assert worst <= (omega * dt) ** order


def _first_order_energy_gain(body, state, dt, duration, sample_steps):
    """
    Return first_order's energy gain E(t) - E0 and its derived value, both in J.

    The derived value integrates reference.first_order_energy_gain_rate along the run by
    the trapezoid rule over samples `sample_steps` steps apart (its integrand is smooth and
    quasi-periodic: the quadrature error is far below the ones compared).
    """
    simulator = Simulator(body, state, integrator='first_order')
    initial = simulator.energy()
    rate = first_order_energy_gain_rate(body, state, dt)
    predicted = 0.0
    for _ in range(int(round(duration / (sample_steps * dt)))):
        current = simulator.run(sample_steps * dt, dt)
        following = first_order_energy_gain_rate(body, current, dt)
        predicted += 0.5 * (rate + following) * sample_steps * dt
        rate = following
    return simulator.energy() - initial, predicted


@pytest.mark.parametrize('body_name', sorted(BODIES))
def test_first_order_energy_gain_follows_its_derived_rate_and_halves_with_dt(body_name):
    """
    first_order's energy error is a gain of dt/2 integral (omega x L)^T I_w^{-1} (omega x L).

    Over 1e5 steps the measured gain must equal that leading-order value up to the next
    order: the relative difference is O((|omega| dt)^2) (measured 0.48 (|omega| dt)^2 on the
    T-handle, 0.15 on the tilted tensor at dt = 1e-3, ~4x smaller at dt / 2), so
    2 (|omega| dt)^2 is allowed.  A method that lost its first order (a gain O(1) per unit
    time, or of the other sign) fails this by orders of magnitude.  Halving dt halves the
    gain: the ratio differs from 2 only because the trajectory moves with the energy it
    gains, which changes the rate by O(gain / E) (measured ratios 2.016 and 1.995 with
    gains of 2.7 % and 1.1 %), so 2 is required within 2 gain / E.
    """
    body, state = BODIES[body_name]()
    dt = 1e-3
    duration = LONG_RUN * dt
    omega = np.linalg.norm(state.angular_velocity(body))
    energy = state.kinetic_energy(body)
    gain, predicted = _first_order_energy_gain(body, state, dt, duration, 10)
    gain_half, predicted_half = _first_order_energy_gain(body, state, dt / 2, duration, 20)
    assert gain > 0.0 and gain_half > 0.0
    assert gain == pytest.approx(predicted, rel=2.0 * (omega * dt) ** 2)
    assert gain_half == pytest.approx(predicted_half, rel=2.0 * (omega * dt / 2) ** 2)
    assert gain / gain_half == pytest.approx(2.0, rel=2.0 * gain / energy)

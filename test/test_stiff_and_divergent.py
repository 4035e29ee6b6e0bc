"""
Stiff effects and diverging states: refused before the first step, or stopped finite.

An explicit step of a linear decay y' = -lambda y grows without bound beyond a limit of
lambda h fixed by the method (physics/stability.py measures it on each kernel); a state that
turns non-finite anyway (an effect's own blow-up) is not stepped further: the Simulator keeps
the last finite state and raises DivergedError naming when and under what.
"""

import math

import numpy as np
import pytest
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects import create_effect
from rigid_body_sim.physics.effects import Drag
from rigid_body_sim.physics.effects import EFFECTS
from rigid_body_sim.physics.effects import ParameterError
from rigid_body_sim.physics.effects.registry import Effect
from rigid_body_sim.physics.kernels.model import wrench_term
from rigid_body_sim.physics.simulator import DivergedError
from rigid_body_sim.physics.stability import decay_limit

SCAN_STEP = 0.02
# The scan of physics/stability.py: lambda h from SCAN_STEP on, the first whose step grows.
SCAN = np.arange(SCAN_STEP, 20.0, SCAN_STEP)


def _amplification(name, z):
    """
    Return the amplification factor g(z) of `name` for y' = -lambda y, z = lambda h.

    From its registration.  A kicking method: each kick-drift-kick stage of c h takes an
    explicit midpoint kick of c h/2, 1 - cz/2 + (cz)^2/8, and a closing one started from its
    extrapolated estimate (kernels/model.py's impulse), together
    g(cz) = (1 - cz/2)(1 - cz/2 + (cz)^2/4) (for one stage -1 at z = 2u,
    u^3 - 2u^2 + 2u - 2 = 0: 3.0874), a composition the product over its stages.  Otherwise
    an explicit method of p <= 4 stages and order p: the truncated exponential
    sum_{k <= p} (-z)^k / k! (Euler 1 - z, limit 2; classical RK4, limit 2.785).
    """
    integrator = INTEGRATORS[name]
    if integrator.kicks:
        g = 1.0
        for c in integrator.kicks:
            w = c * z
            g *= (1.0 - w / 2.0) * (1.0 - w / 2.0 + w * w / 4.0)
        return g
    assert integrator.stages == integrator.order <= 4, name
    return sum((-z) ** k / math.factorial(k) for k in range(integrator.order + 1))


def _theoretical_limit(name):
    """Return the last lambda h of the scan before |g| first exceeds 1."""
    previous = 0.0
    for z in SCAN:
        if abs(_amplification(name, z)) > 1.0:
            return previous
        previous = z
    return previous


@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_each_methods_measured_decay_limit_is_its_theoretical_one(name):
    assert decay_limit(name) == pytest.approx(_theoretical_limit(name), abs=SCAN_STEP)


def test_the_theory_gives_euler_rk4_and_a_strang_kick_pair_their_known_limits():
    # The formulas above at their textbook values: Euler 2, classical RK4 2.7853, the kicked
    # Strang step 3.0874 (a check of this file's theory, by what each registration declares).
    for name, integrator in INTEGRATORS.items():
        expected = ({1: 2.0, 4: 2.7853}[integrator.order] if not integrator.kicks
                    else 3.0874 if integrator.kicks == (1.0,) else None)
        if expected is not None:
            assert _theoretical_limit(name) == pytest.approx(expected, abs=SCAN_STEP), name


def test_every_integrator_has_a_positive_decay_limit():
    for name in INTEGRATORS:
        assert decay_limit(name) > 1.0, name


def _issue_box():
    # Issue 22's case: a 0.4 x 0.2 x 0.1 m box (1 kg) under rotational_linear 10 N m s.
    body = RigidBody.box(1.0, (0.4, 0.2, 0.1))
    return body, State.from_velocity(body, angular_velocity_body=(1.0, 2.0, 3.0))


@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_a_fixed_step_too_long_for_stiff_drag_is_refused_in_one_line(name):
    body, state = _issue_box()
    simulator = Simulator(body, state, integrator=name, effects=[Drag(rotational_linear=10.0)])
    with pytest.raises(ValueError) as caught:
        simulator.run(1.0, 0.01)
    message = str(caught.value)
    assert '\n' not in message and message.startswith('drag damps the motion at 2400 /s')
    assert 'raise rate to at least' in message and 'substeps to' in message
    # Nothing was stepped.
    assert simulator.time == 0.0 and simulator.state == state


@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_the_substeps_the_refusal_names_carry_the_stiff_drag_finite_and_decaying(name):
    body, state = _issue_box()
    simulator = Simulator(body, state, integrator=name, effects=[Drag(rotational_linear=10.0)])
    with pytest.raises(ValueError) as caught:
        simulator.step(0.01)
    substeps = int(str(caught.value).split('substeps to ')[1].split(',')[0])
    simulator.substeps = substeps
    final = simulator.run(1.0, 0.01)
    assert np.all(np.isfinite(final.angular_momentum))
    # 2400 /s of decay about the least axis, at least k1 / I3 = 480 /s about any: after 1 s
    # nothing is left of the spin.
    assert np.linalg.norm(final.angular_momentum) < 1e-100


def test_under_error_control_the_stiff_drag_runs_finite_with_at_least_the_stable_count():
    body, state = _issue_box()
    simulator = Simulator(body, state, effects=[Drag(rotational_linear=10.0)], tolerance=1e-7)
    final = simulator.run(0.5, 0.01)
    assert np.all(np.isfinite(final.quaternion)) and np.all(np.isfinite(final.angular_momentum))
    needed = math.ceil(2400.0 * 0.01 / (0.9 * decay_limit('buss')))
    assert simulator.substep_statistics()['substeps_min'] >= needed


@wrench_term
def _blow_up(state, time, parameters):
    """Return a finite torque until parameters[0] s, then an infinite one."""
    torque = math.inf if time >= parameters[0] else 0.1
    return 0.0, 0.0, 0.0, torque, 0.0, 0.0


class _BlowUp(Effect):
    compiled_wrench = staticmethod(_blow_up)

    def __init__(self, at):
        self.at = at

    def wrench_parameters(self, body):
        return np.array([self.at])


@pytest.mark.parametrize('name', sorted(INTEGRATORS))
def test_a_state_turning_non_finite_stops_at_the_last_finite_one_naming_when(name):
    body, state = _issue_box()
    simulator = Simulator(body, state, integrator=name, effects=[_BlowUp(0.105)])
    for _ in range(10):
        simulator.step(0.01)
    kept = simulator.state
    with pytest.raises(DivergedError) as caught:
        for _ in range(10):
            simulator.step(0.01)
    message = str(caught.value)
    assert '\n' not in message
    # The first step that samples the torque at t >= 0.105 s: its end (the kicks), its middle
    # (rk4), or, for first_order, which samples the start alone, the next one.
    start = 0.11 if name == 'first_order' else 0.1
    assert caught.value.time == pytest.approx(start)
    assert f'between t = {start:g} s and {start + 0.01:g} s' in message and name in message
    assert '_BlowUp' in message
    # The last finite state is kept, and the clock did not move past it.
    assert simulator.time == pytest.approx(start)
    if name != 'first_order':
        assert simulator.state == kept
    assert np.all(np.isfinite(simulator.state.angular_momentum))


@pytest.mark.parametrize('interpreted', [False, True], ids=['compiled', 'interpreted'])
def test_under_error_control_a_state_turning_non_finite_stops_at_the_last_finite_one(
        interpreted):
    # The controller tests the state it leaves (error_control.controlled_ticks), compiled and
    # as its interpreted source: the Simulator restores the last finite state from it alone.
    body, state = _issue_box()
    simulator = Simulator(body, state, effects=[_BlowUp(0.105)], tolerance=1e-3)
    simulator.interpreted = interpreted
    for _ in range(10):
        simulator.step(0.01)
    kept = simulator.state
    with pytest.raises(DivergedError) as caught:
        for _ in range(10):
            simulator.step(0.01)
    assert caught.value.time == pytest.approx(0.1)
    assert 'error control at 0.001 rad/s' in str(caught.value)
    assert simulator.time == pytest.approx(0.1)
    assert simulator.state == kept


# Values past each bound: the effects refuse them at load, naming the unit.
BEYOND = [('drag', {'rotational_linear': 1e300}, 'rotational_linear', 'N m s'),
          ('drag', {'linear': 2e6}, 'linear', 'N s/m'),
          ('sinusoidal_torque', {'amplitude': [1e300, 0, 0], 'frequency': 1.0}, 'amplitude',
           'N m'),
          ('sinusoidal_torque', {'amplitude': [1, 0, 0], 'frequency': 1e9}, 'frequency', 'Hz'),
          ('gravity', {'acceleration': [0, 0, -1e300]}, 'acceleration', 'm/s^2'),
          ('pivot', {'point': [1e300, 0, 0]}, 'point', 'm'),
          ('dissipation', {'damping': 1e300}, 'damping', '')]


@pytest.mark.parametrize('name, parameters, key, unit', BEYOND)
def test_effect_parameters_beyond_their_bound_are_refused_naming_the_unit(
        name, parameters, key, unit):
    with pytest.raises(ParameterError) as caught:
        create_effect(name, parameters)
    assert caught.value.key == key and 'at most' in caught.value.problem
    assert unit in caught.value.problem


def test_every_effects_example_is_within_its_bounds():
    for name, cls in EFFECTS.items():
        create_effect(name, cls.example)


@pytest.mark.parametrize('mass', [5e-324, 1e-12, 1e20])
def test_a_body_mass_beyond_a_microgram_to_a_mountain_is_refused(mass):
    with pytest.raises(ValueError, match='mass must be within 1e-09 .. 1e\\+15 kg'):
        RigidBody(mass, (1.0, 1.0, 1.0))


def test_the_command_line_says_a_divergence_in_one_line_and_exits_1(monkeypatch, capsys):
    from rigid_body_sim import cli

    def diverge(self, duration, dt, progress=None):
        raise DivergedError('the state turned non-finite between t = 1 s and 1.01 s', 1.0)

    monkeypatch.setattr(Simulator, 'run', diverge)
    assert cli.main(['run', '--duration', '2']) == 1
    err = capsys.readouterr().err.strip()
    assert err == ('rigid-body-sim run: error: the state turned non-finite between t = 1 s '
                   'and 1.01 s')

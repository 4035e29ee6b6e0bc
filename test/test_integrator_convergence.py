"""
Observed order of convergence of every integrator against a tight reference solution.

The reference is scipy's DOP853 at rtol 1e-13 (test/reference.py), ~1e-12 accurate.  Each
registered method's kernel (Simulator.run) is run at dt and dt/2 over the same span, and the
observed order is log2(error(dt) / error(dt/2)).  The wrenches are held ones, the drag effect
and compiled test terms (test/wrench_effects.py), whose numpy twins drive the reference.  The
step counts put every error in the asymptotic range: far above the reference's error and far
below O(1) (both asserted, so a change that leaves the range fails loudly instead of
producing a meaningless order).

The expected order is the registered one: `order`, and `momentum_dependent_order` under drag
(a kicking method takes a momentum-dependent wrench by the kicks' explicit midpoint rule,
kernels/model.py's impulse, second order).  Torque-free, an exact flow has no error to
measure.

Errors (dimensionless, summed): the rotation angle of R^T R_ref (rad), |L - L_ref| / |L_ref|,
and the position and linear momentum errors scaled by the run's lengths and momenta.
"""

import functools
import math

import numpy as np
import pytest
from reference import random_rotation
from reference import reference_solution
from reference import state_error
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects import Drag
from wrench_effects import OrientationDependent
from wrench_effects import TimeDependent

# The coarse run's wrench evaluations by the method's order, the same for every body (each
# run turns the body by about 1.5 rad): the methods of one order compared at equal work, a
# method of more stages taking longer steps.  Small enough steps that the leading error term
# dominates (rk4's L error still carries a visible fifth-order part at 10 steps), large
# enough that the fine error (twice the steps) stays far above the reference's.
COARSE_EVALUATIONS = {1: 200, 2: 80, 4: 120}
METHODS = {name: (integrator.order,
                  COARSE_EVALUATIONS[integrator.order] // integrator.stages)
           for name, integrator in INTEGRATORS.items()}
"""Name -> (registered order, coarse step count), for every registered integrator."""
# Observed order within +-0.3 of the nominal one (fourth order: >= 3.7, higher is harmless).
ORDER_TOLERANCE = 0.3
# The reference is good to ~1e-13 (checked below): an error must exceed it 1000-fold.
MEASURABLE_ERROR = 1e-10
# The coarse error must be well below O(1) to be in the asymptotic range.
ASYMPTOTIC_ERROR = 0.05


def _t_handle():
    rng = np.random.default_rng(101)
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    state = State.from_velocity(body, rotation=random_rotation(rng), position=(0.5, 0.0, 1.0),
                                velocity=(0.1, 0.2, -0.3), angular_velocity_body=(0.4, 1.0, 0.6))
    return body, state, 1.0


def _tilted_tensor():
    # Non-diagonal inertia (principal axes not the body axes) and a non-identity rotation.
    rng = np.random.default_rng(202)
    axes = random_rotation(rng)
    body = RigidBody(2.5, axes @ np.diag([2.0, 3.0, 4.5]) @ axes.T)
    state = State.from_velocity(body, rotation=random_rotation(rng), position=(1.0, -2.0, 0.5),
                                velocity=(0.3, 0.0, 0.1), angular_velocity_body=(0.7, -0.9, 0.5))
    return body, state, 1.0


def _van_zon_schofield():
    # The standard test body of van Zon & Schofield (2007): I = (10, 20, 26), Omega0 =
    # (1, 15, 1) rad/s, over 0.1 s (about 1.5 rad of turn, like the others).
    rng = np.random.default_rng(303)
    body = RigidBody(3.0, (10.0, 20.0, 26.0))
    state = State.from_velocity(body, rotation=random_rotation(rng), velocity=(2.0, -1.0, 0.0),
                                angular_velocity_body=(1.0, 15.0, 1.0))
    return body, state, 0.1


BODIES = {
    't_handle': _t_handle,
    'tilted_tensor': _tilted_tensor,
    'van_zon_schofield': _van_zon_schofield,
}


class _Wrench:
    """A wrench of the tests: the effects and held parts the kernels take, its numpy twin."""

    def __init__(self, effects=(), held=None, reference=None):
        self.effects, self.held, self.reference = tuple(effects), held or {}, reference
        self.momentum_dependent = any(e.momentum_dependent for e in self.effects)


def _wrench(kind, body, state, duration):
    """
    Return a wrench of the given kind, scaled to the body and the run.

    Torques are scaled so that they change L by about |L0| over the run, forces so that they
    change the velocity by ~1 m/s: big enough that a wrong kick shows in the error.
    """
    torque_scale = np.linalg.norm(state.angular_momentum) / duration
    force_scale = body.mass / duration
    constant_force = force_scale * np.array([0.3, -0.2, 0.5])
    constant_torque = torque_scale * np.array([0.2, 0.1, -0.3])
    body_force = force_scale * np.array([0.1, 0.2, 0.0])
    body_torque = torque_scale * np.array([0.3, -0.2, 0.25])
    if kind == 'torque_free':
        return _Wrench()
    if kind == 'constant':
        return _Wrench(held={'force_world': constant_force, 'torque_world': constant_torque},
                       reference=lambda state, time: (constant_force, constant_torque))
    if kind == 'orientation_dependent':
        # A restoring torque like gravity on an offset COM, a force along the body x axis.
        effect = OrientationDependent(0.5 * force_scale, torque_scale)
        return _Wrench([effect], reference=effect.reference)
    if kind == 'body_fixed':
        def fixed(state, time):
            return state.rotation @ body_force, state.rotation @ body_torque
        return _Wrench(held={'force_body': body_force, 'torque_body': body_torque},
                       reference=fixed)
    if kind == 'time_dependent':
        effect = TimeDependent(constant_force, constant_torque, duration)
        return _Wrench([effect], reference=effect.reference)
    # Linear drag on both motions: F = -c v, tau = -c' omega (momentum-dependent).
    linear, rotational = 0.3 * body.mass / duration, 0.5 / duration * np.trace(body.inertia) / 3

    def drag(state, time):
        rotation = state.rotation
        omega = rotation @ body.inertia_inverse @ rotation.T @ state.angular_momentum
        return -linear / body.mass * state.linear_momentum, -rotational * omega

    return _Wrench([Drag(linear=linear, rotational_linear=rotational)], reference=drag)


WRENCHES = ('torque_free', 'constant', 'orientation_dependent', 'body_fixed',
            'time_dependent', 'momentum_dependent_drag')


@functools.lru_cache(maxsize=None)
def _problem(body_name, wrench_kind):
    body, state, duration = BODIES[body_name]()
    wrench = _wrench(wrench_kind, body, state, duration)
    reference = reference_solution(body, state, duration, wrench.reference)
    return body, state, duration, wrench, reference


def _run(name, body, state, duration, steps, wrench):
    simulator = Simulator(body, state, integrator=name, effects=wrench.effects)
    simulator.hold_wrench(**wrench.held)
    return simulator.run(duration, duration / steps)


def _errors(name, body_name, wrench_kind, steps, wrench=None):
    body, state, duration, default_wrench, reference = _problem(body_name, wrench_kind)
    wrench = default_wrench if wrench is None else wrench
    scale_length = duration * max(1.0, np.linalg.norm(state.velocity(body)))
    scale_momentum = body.mass * max(1.0, np.linalg.norm(state.velocity(body)))
    result = []
    for count in (steps, 2 * steps):
        final = _run(name, body, state, duration, count, wrench)
        result.append(state_error(final, reference, scale_length, scale_momentum))
    return result


def _order(coarse, fine):
    return math.log2(coarse / fine)


def _expected_order(name, wrench_kind):
    integrator = INTEGRATORS[name]
    if wrench_kind == 'momentum_dependent_drag':
        return integrator.momentum_dependent_order
    return integrator.order


CASES = [(name, body_name, wrench_kind) for name in sorted(INTEGRATORS)
         for body_name in sorted(BODIES) for wrench_kind in WRENCHES
         if not (INTEGRATORS[name].exact_torque_free and wrench_kind == 'torque_free')]


@pytest.mark.parametrize('name, body_name, wrench_kind', CASES)
def test_observed_order_matches_nominal_order(name, body_name, wrench_kind):
    order = _expected_order(name, wrench_kind)
    coarse, fine = _errors(name, body_name, wrench_kind, METHODS[name][1])
    assert coarse['total'] < ASYMPTOTIC_ERROR, coarse
    assert fine['total'] > MEASURABLE_ERROR, fine
    observed = _order(coarse['total'], fine['total'])
    if order == 4:
        assert observed >= order - ORDER_TOLERANCE, (observed, coarse, fine)
    else:
        assert abs(observed - order) <= ORDER_TOLERANCE, (observed, coarse, fine)
    # Every part of the state that carries a measurable error converges at least at the
    # nominal order: the wrench enters L and p, and through them R and x, without loss.
    for part in ('angle', 'angular_momentum', 'position', 'linear_momentum'):
        if fine[part] > MEASURABLE_ERROR:
            assert _order(coarse[part], fine[part]) >= order - ORDER_TOLERANCE, (part, coarse,
                                                                                 fine)


class _UnflaggedDrag(Drag):
    """Drag that does not declare its momentum dependence."""

    momentum_dependent = False


@pytest.mark.parametrize('name', sorted(name for name, integrator in INTEGRATORS.items()
                                        if integrator.kicks))
def test_unflagged_drag_costs_a_kicking_method_its_second_order(name):
    """
    The momentum_dependent flag is what keeps a kicking method second order under drag.

    Without it the kicks are explicit Euler steps of a momentum-dependent torque, first
    order: this shows the order measurement above can see a first-order defect.
    """
    drag = _problem('t_handle', 'momentum_dependent_drag')[3]
    flagged = drag.effects[0]
    unflagged = _Wrench([_UnflaggedDrag(linear=flagged.linear,
                                        rotational_linear=flagged.rotational_linear)])
    coarse, fine = _errors(name, 't_handle', 'momentum_dependent_drag', METHODS[name][1],
                           wrench=unflagged)
    assert abs(_order(coarse['total'], fine['total']) - 1.0) <= ORDER_TOLERANCE


def test_reference_is_exact_for_a_spherical_top_and_conserves_the_free_invariants():
    # Spherical top: omega = L / I is constant and R(t) = exp(t [omega]) R0 exactly.
    rng = np.random.default_rng(404)
    body = RigidBody.sphere(2.0, 0.5)
    rotation = random_rotation(rng)
    omega = np.array([0.3, -1.2, 0.8])
    state = State.from_velocity(body, rotation=rotation, angular_velocity_world=omega)
    duration = 2.0
    reference = reference_solution(body, state, duration)
    angle = np.linalg.norm(omega) * duration
    axis = omega / np.linalg.norm(omega)
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                      [-axis[1], axis[0], 0.0]])
    turn = np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * cross @ cross
    exact = State(turn @ rotation, angular_momentum=state.angular_momentum)
    assert state_error(reference, exact)['total'] < 1e-12
    # Asymmetric body, torque-free: world L is constant and so is the kinetic energy.
    body, state, duration = _tilted_tensor()
    reference = reference_solution(body, state, duration)
    assert state_error(reference, State(reference.rotation, reference.position,
                                        reference.linear_momentum,
                                        state.angular_momentum))['total'] < 1e-12
    assert reference.kinetic_energy(body) == pytest.approx(state.kinetic_energy(body),
                                                           rel=1e-12)

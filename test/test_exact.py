"""
The exact torque-free flow (integrator 'exact') and the elliptic functions it is built on.

References: a Taylor-series integration of the torque-free equations in 30-digit decimal
arithmetic (here, sharing no code with the package; its own error is ~1e-26 rad over 10 s,
tested), scipy.special for the elliptic functions (test/elliptic_reference.py), and
test/reference.py's DOP853 solve and test/method_reference.py's exact step (kicks around a
DOP853 solve of the free motion) for the motion under a torque.  Errors are rotation angles
(rad) between the double quaternion and the decimal one, computed in decimals.

What sets the tolerances:
- round-off: each exact step rounds the state once, like an ideal stepper that evaluates the
  flow in extended precision and stores the quaternion in double (measured by one, the
  "floor": benchmarks/exact_roundoff_floor.py), plus a few ulp per radian turned in the
  precession angle and the Jacobi functions;
- the conditioning of the motion: an error of 1 ulp in the state grows by the factor A(t)
  (up to ~1e3-1e4 over 10 s near the separatrix, where the period depends on the energy
  logarithmically), for any stepper that stores its state in double.
"""

import decimal
from fractions import Fraction
import math

from elliptic_reference import carlson_rf
from elliptic_reference import carlson_rj
from elliptic_reference import jacobi_elliptic
import exact_rounding_reference as oracle
from method_reference import motion_error
from method_reference import reference_run
import numpy as np
import pytest
from reference import random_rotation
from reference import reference_solution
from reference import rotation_angle_between
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects.registry import Effect
from rigid_body_sim.physics.elliptic import carlson_rf as carlson_rf_compiled
from rigid_body_sim.physics.elliptic import carlson_rj as carlson_rj_compiled
from rigid_body_sim.physics.elliptic import jacobi_elliptic as jacobi_elliptic_compiled
from rigid_body_sim.physics.integrators import exact as exact_module
from rigid_body_sim.physics.kernels.algebra import rotate
from rigid_body_sim.physics.kernels.algebra import rotate_back
from rigid_body_sim.physics.kernels.layout import body_values
from rigid_body_sim.physics.kernels.model import new_model
from rigid_body_sim.physics.kernels.model import wrench_term
from rigid_body_sim.physics.principal_frame import ASYMMETRIC
from rigid_body_sim.physics.principal_frame import principal_frame
from rigid_body_sim.physics.principal_frame import SPHERICAL
from rigid_body_sim.physics.rotations import quaternion_from_rotation_vector
from rigid_body_sim.physics.rotations import quaternion_multiply
from rigid_body_sim.work_precision.bodies import benchmark_cases
from scipy.special import ellipj
import taylor_reference
from taylor_reference import angle_to_reference
from taylor_reference import reference_orientations
from taylor_reference import TaylorReference

EPS = np.finfo(float).eps


def _stepped(body, state, dt, steps):
    """Return the state after `steps` exact steps of dt s (the kernel, Simulator.run)."""
    return Simulator(body, state, integrator='exact').run(steps * dt, dt)


def _flow(body, state, duration):
    """
    Return the state after `duration` s (any sign) of the kernel's exact free flow.

    exact.free_rotation, the compiled function each exact step calls, in the body's principal
    frame (physics/principal_frame.py), called from Python; the COM moves uniformly and the
    momenta are constant.
    """
    frame = principal_frame(body.inertia)
    quaternion = exact_module.free_rotation(
        tuple(float(c) for c in state.quaternion), *(float(c) for c in state.angular_momentum),
        frame.moments, frame.axes, frame.kind, float(duration))
    return State._from_arrays(np.array(quaternion), state.position + duration
                              * state.linear_momentum / body.mass, state.linear_momentum,
                              state.angular_momentum)


# -- the elliptic functions -------------------------------------------------------------


def test_compiled_carlson_integrals_equal_scipy_on_the_arguments_the_flow_uses():
    # The flow calls R_F(c^2, d^2, 1) and R_J(c^2, d^2, 1, 1 - n s^2) with c^2 in [0, 1],
    # d^2 = c^2 + k'^2 s^2, n <= 0; and the complete R_F(0, k'^2, 1), R_J(0, k'^2, 1, 1 - n).
    rng = np.random.default_rng(11)
    worst_rf = worst_rj = 0.0
    for _ in range(3000):
        c2 = rng.uniform(0.0, 1.0) if rng.uniform() < 0.8 else 0.0
        complement = 10.0 ** rng.uniform(-16.0, 0.0)
        d2 = c2 + complement * (1.0 - c2)
        p = 1.0 + 10.0 ** rng.uniform(-8.0, 4.0) * (1.0 - c2)
        worst_rf = max(worst_rf, abs(carlson_rf_compiled(c2, d2, 1.0) / carlson_rf(c2, d2, 1.0)
                                     - 1.0))
        worst_rj = max(worst_rj, abs(carlson_rj_compiled(c2, d2, 1.0, p)
                                     / carlson_rj(c2, d2, 1.0, p) - 1.0))
    # Carlson's truncation bound is 1e-16; a few ulps of round-off on top.
    assert worst_rf < 8 * EPS
    assert worst_rj < 16 * EPS


def test_jacobi_functions_equal_scipy_where_its_parameter_is_exact():
    # Away from m = 1 scipy's ellipj (which forms 1 - m itself) is accurate: both versions
    # must match it, including the Landen descent used above m = 1/2.  scipy's own error
    # reaches ~8 ulp here (measured against an 80-bit evaluation), ours ~4-8 ulp.
    rng = np.random.default_rng(12)
    worst = 0.0
    for _ in range(3000):
        m = rng.uniform(0.0, 0.99)
        quarter = carlson_rf(0.0, 1.0 - m, 1.0)
        u = rng.uniform(-quarter, quarter)
        expected = np.array(ellipj(u, m)[:3])
        for function in (jacobi_elliptic, jacobi_elliptic_compiled):
            worst = max(worst, np.max(np.abs(np.array(function(u, m, 1.0 - m)) - expected)))
    assert worst < 16 * EPS


def test_jacobi_functions_keep_full_accuracy_next_to_m_equal_1():
    # A&S 16.5: sn(K/2) = 1/sqrt(1 + k'), cn(K/2) = sqrt(k'/(1 + k')), dn(K/2) = sqrt(k'),
    # and dn(K) = k'.  These hinge on m1 = k'^2 itself: with 1 - m formed from a rounded m
    # the relative error of m1 is eps/m1 (1e-6 at m1 = 1e-10), of dn(K) half that.  Allowed:
    # the rounding of the argument u ~ K (absolute eps K, relative to dn ~ 1 here) and a few
    # ulp per Landen level.
    for m1 in (1e-4, 1e-8, 1e-10, 1e-14, 1e-20, 1e-40):
        quarter = carlson_rf(0.0, m1, 1.0)
        k = math.sqrt(m1)
        half_values = (1.0 / math.sqrt(1.0 + k), math.sqrt(k / (1.0 + k)), math.sqrt(k))
        for function in (jacobi_elliptic, jacobi_elliptic_compiled):
            got = function(0.5 * quarter, 1.0 - m1, m1)
            for value, expected in zip(got, half_values):
                assert value == pytest.approx(expected, rel=16 * EPS * (1.0 + quarter))
            assert function(quarter, 1.0 - m1, m1)[2] == pytest.approx(
                k, rel=16 * EPS * (1.0 + quarter))


def test_compiled_jacobi_functions_equal_the_scipy_landen_reference_for_every_parameter():
    # Both round the argument on its way down the Landen levels and back up, an absolute
    # error of (a few ulp per level) x |u|; against an 80-bit evaluation both stay within
    # ~100 ulp per unit of |u| for m1 >= 1e-32 (where scipy's ellipj, forming 1 - m, is off
    # by up to 6e5 ulp).  Below m1 = 1e-32 (a state within round-off of the separatrix,
    # K up to 350) more levels are taken and the allowance is 8x larger.
    rng = np.random.default_rng(13)
    for lowest, allowed in ((-32.0, 128 * EPS), (-300.0, 1024 * EPS)):
        worst = 0.0
        for _ in range(2000):
            m1 = 10.0 ** rng.uniform(lowest, 0.0) if rng.uniform() < 0.7 else rng.uniform()
            quarter = carlson_rf(0.0, m1, 1.0)
            u = rng.uniform(-quarter, quarter)
            expected = np.array(jacobi_elliptic(u, 1.0 - m1, m1))
            compiled = np.array(jacobi_elliptic_compiled(u, 1.0 - m1, m1))
            worst = max(worst, np.max(np.abs(expected - compiled)) / (1.0 + abs(u)))
        assert worst < allowed


# -- the Taylor reference ----------------------------------------------------------------


def test_the_taylor_reference_is_converged():
    # 30 against 40 digits on substeps 2.5x shorter, for the fastest tumble (van Zon &
    # Schofield, 150 rad in 10 s): the references' own error is far below any tolerance here.
    case = benchmark_cases(('van_zon',))[0]
    coarse = TaylorReference(case.body, case.state).advance_to(10.0)
    fine = TaylorReference(case.body, case.state, digits=40, substep_scale=0.3).advance_to(10.0)
    with decimal.localcontext(decimal.Context(prec=40)):
        gap = sum((a - b) ** 2 for a, b in zip(coarse, fine)).sqrt()
    assert 2.0 * float(gap) < 1e-24


# -- random bodies and states for the property tests -------------------------------------


def _oblique_body(rng, moments):
    """Return a body with the given principal moments along random axes (non-diagonal)."""
    axes = random_rotation(rng)
    return RigidBody(rng.uniform(0.5, 2.0), axes @ np.diag(moments) @ axes.T)


def _state_with_principal_momentum(rng, body, momentum_principal):
    """Return a random-orientation state whose principal-frame angular momentum is given."""
    rotation = random_rotation(rng)
    frame = principal_frame(body.inertia)
    angular_momentum = rotation @ (frame.axes @ np.asarray(momentum_principal))
    return State(rotation, rng.normal(size=3), rng.normal(size=3), angular_momentum)


def _random_moments(rng):
    while True:
        moments = np.sort(rng.uniform(0.5, 3.0, 3))
        if moments[0] + moments[1] >= moments[2]:
            return moments


def _near_separatrix_momentum(rng, moments, complement):
    """Return m with |m| ~ 1..3 whose elliptic parameter is 1 - complement (either side)."""
    i1, i2, i3 = moments
    m2 = rng.uniform(-1.0, 1.0)
    m3 = rng.uniform(0.5, 2.0) * rng.choice([-1.0, 1.0])
    # On the separatrix m1^2 (I2 - I1)/I1 = m3^2 (I3 - I2)/I3; k'^2 = (I3 - I1) D /
    # ((I3 - I2) G), D = L^2 - I2 E2 = m3^2 (I3 - I2)/I3 - m1^2 (I2 - I1)/I1, G = L^2 - I1 E2.
    g = m2 * m2 * (i2 - i1) / i2 + m3 * m3 * (i3 - i1) / i3
    distance = rng.choice([-1.0, 1.0]) * complement * (i3 - i2) * g / (i3 - i1)
    m1_squared = (m3 * m3 * (i3 - i2) / i3 - distance) * i1 / (i2 - i1)
    return np.array([math.sqrt(m1_squared) * rng.choice([-1.0, 1.0]), m2, m3])


# Half turns about the body axes: rotation matrices with entries 0 and +-1, so R^T L is exact.
_HALF_TURNS = ((1.0, 1.0, 1.0), (1.0, -1.0, -1.0), (-1.0, 1.0, -1.0), (-1.0, -1.0, 1.0))


def _separatrix_state(rng):
    """
    Return (body, state) exactly on the separatrix, in exact arithmetic.

    I = s (1.5, 3, 4) (s a power of two) has (I2 - I1)/I1 = -1 and (I3 - I2)/I3 = 1/4
    exactly, so with m = (a, m2, +-2a), a a power of two, L^2 - I2 E2 = -a^2 + 4 a^2/4 = 0
    exactly; a half turn about a body axis as the orientation keeps R^T L exact.
    """
    body = RigidBody(rng.uniform(0.5, 2.0), np.diag([1.5, 3.0, 4.0]) * 2.0 ** rng.integers(-2, 3))
    a = 2.0 ** rng.integers(-2, 2)
    momentum = np.array([a * rng.choice([-1.0, 1.0]), rng.uniform(-2.0, 2.0) * a,
                         2.0 * a * rng.choice([-1.0, 1.0])])
    turn = np.diag(_HALF_TURNS[rng.integers(4)])
    return body, State(turn, rng.normal(size=3), rng.normal(size=3), turn @ momentum)


def _case(rng, kind):
    """Return (body, state) of the given kind, inertia tensor oblique in the body frame."""
    if kind == 'asymmetric':
        body = _oblique_body(rng, _random_moments(rng))
        return body, State(random_rotation(rng), rng.normal(size=3), rng.normal(size=3),
                           rng.normal(size=3) * rng.uniform(0.3, 3.0))
    if kind in ('near_separatrix', 'closer_to_separatrix'):
        # 1 - m = k'^2 in [1e-9, 1e-8], or down to 1e-15 (where the rounding of R^T L at an
        # oblique orientation moves it by ~eps: either side of the separatrix).
        lowest, highest = (-9.0, -8.0) if kind == 'near_separatrix' else (-15.0, -9.0)
        moments = _random_moments(rng)
        body = _oblique_body(rng, moments)
        momentum = _near_separatrix_momentum(rng, moments,
                                             10.0 ** rng.uniform(lowest, highest))
        return body, _state_with_principal_momentum(rng, body, momentum)
    if kind == 'on_separatrix':
        return _separatrix_state(rng)
    base = rng.uniform(1.0, 2.0)
    moments = {
        'prolate': (base, base, base * rng.uniform(1.1, 2.0)),
        'oblate': (base * rng.uniform(0.55, 0.9), base, base),
        'spherical': (base, base, base),
        'prolate_1e-12': (base, base * (1 + 1e-12), base * rng.uniform(1.1, 2.0)),
        'oblate_1e-12': (base * rng.uniform(0.55, 0.9), base, base * (1 + 1e-12)),
        'spherical_1e-12': (base, base * (1 + 1e-12), base * (1 + 2e-12)),
        'prolate_1e-14': (base, base * (1 + 1e-14), base * rng.uniform(1.1, 2.0)),
        'oblate_1e-14': (base * rng.uniform(0.55, 0.9), base, base * (1 + 1e-14)),
    }[kind]
    if kind in ('prolate', 'oblate', 'spherical'):
        # Exactly equal moments need exact arithmetic: principal axes = body axes (a
        # rotated tensor's eigenvalues differ in the last bits and make it nearly symmetric).
        body = RigidBody(rng.uniform(0.5, 2.0), np.diag(moments))
    else:
        body = _oblique_body(rng, moments)
    return body, State(random_rotation(rng), rng.normal(size=3), rng.normal(size=3),
                       rng.normal(size=3) * rng.uniform(0.3, 3.0))


# New kinds go last: each kind's seed is its index here.
KINDS = ('asymmetric', 'near_separatrix', 'prolate', 'oblate', 'spherical', 'prolate_1e-12',
         'oblate_1e-12', 'spherical_1e-12', 'closer_to_separatrix', 'on_separatrix',
         'prolate_1e-14', 'oblate_1e-14')
# Where 1 ulp of the state can change the motion qualitatively over long times (which side
# of the separatrix), comparisons over long spans measure the conditioning, not the method.
SEPARATRIX_KINDS = ('closer_to_separatrix', 'on_separatrix')


def _separatrix(frame, momentum):
    """Return L^2 - I2 E2 as the step forms it: m1^2 (I1 - I2)/I1 + m3^2 (I3 - I2)/I3."""
    i1, i2, i3 = frame.moments
    m1, _, m3 = momentum
    return m1 * m1 * (i1 - i2) / i1 + m3 * m3 * (i3 - i2) / i3


def test_the_cases_are_of_the_kinds_they_claim():
    # The property tests below are only as good as their cases: the symmetric ones take the
    # closed form, the nearly symmetric ones (1e-12, 1e-14 apart) the elliptic solution, the
    # near-separatrix ones have 1 - m within 1e-8 of 0 (down to ~1e-15 for the closer ones),
    # and those on the separatrix have L^2 - I2 E2 = 0 exactly in the step's own arithmetic.
    rng = np.random.default_rng(21)
    kinds = {}
    for kind in KINDS:
        for _ in range(10):
            body, state = _case(rng, kind)
            frame = principal_frame(body.inertia)
            kinds[kind] = frame.kind
            if kind == 'near_separatrix':
                assert 1e-10 < _elliptic_complement(body, state)[0] < 1e-8 * 1.01
            if kind == 'closer_to_separatrix':
                assert abs(_elliptic_complement(body, state)[0]) < 1e-9 * 1.01
            if kind == 'on_separatrix':
                momentum = frame.axes.T @ (state.rotation.T @ state.angular_momentum)
                assert _separatrix(frame, momentum) == 0.0
    assert kinds == {'asymmetric': 0, 'near_separatrix': 0, 'prolate': 2, 'oblate': 3,
                     'spherical': 1, 'prolate_1e-12': 0, 'oblate_1e-12': 0,
                     'spherical_1e-12': 0, 'closer_to_separatrix': 0, 'on_separatrix': 0,
                     'prolate_1e-14': 0, 'oblate_1e-14': 0}


# -- accuracy against the Taylor reference -----------------------------------------------


def _issue_bodies():
    """Bodies of issue 5 (t_handle ... non_diagonal) at random orientations."""
    rng = np.random.default_rng(31)
    tilted = ((2.0, -0.3, 0.2), (-0.3, 3.0, 0.4), (0.2, 0.4, 4.0))
    cases = {
        't_handle': (RigidBody(1.0, (1.0, 2.0, 3.0)), (0.001, 2.0, 0.001)),
        'fast_spin': (RigidBody(1.0, (1.0, 2.0, 3.0)), (0.3, 0.2, 5.0)),
        'near_symmetric': (RigidBody(1.0, (1.0, 1.0 + 1e-6, 2.0)), (1.0, 0.5, 3.0)),
        'non_diagonal': (RigidBody(1.0, tilted), (1.5, -1.0, 2.0)),
    }
    return {name: (body, State.from_velocity(body, rotation=random_rotation(rng),
                                             angular_velocity_body=omega))
            for name, (body, omega) in cases.items()}


@pytest.mark.parametrize('name', ['t_handle', 'fast_spin', 'near_symmetric', 'non_diagonal'])
def test_exact_orientation_error_is_below_1e_12_rad_at_dt_0_1_over_10_s(name):
    # The issue's bound, at each of the 100 steps of the kernel (Simulator.step).  (scipy's
    # DOP853 at its tightest rtol, 2.5e-14, is itself 3.8e-12 off for the T-handle: no
    # reference for this bound.)
    body, state = _issue_bodies()[name]
    times = [decimal.Decimal(0.1) * k for k in range(1, 101)]
    simulator = Simulator(body, state, integrator='exact')
    worst = 0.0
    for expected in reference_orientations(body, state, times):
        simulator.step(0.1)
        worst = max(worst, angle_to_reference(simulator.state.quaternion, expected))
    assert worst <= 1e-12


def test_van_zon_schofield_at_dt_0_1_over_10_s_is_within_1e_12_rad():
    """
    Hold the benchmark's van Zon & Schofield tumble (Simulator.run, dt = 0.1 s) to 1e-12 rad.

    I = (10, 20, 26), Omega0 = (1, 15, 1), R0 = E: 150 rad in 10 s next to the separatrix
    (k'^2 = 3.3e-3).  Measured: 1.9e-13 rad.  What any double-precision stepper can reach
    here (benchmarks/exact_roundoff_floor.py: the exact flow in 30-digit decimals, the
    quaternion rounded to double after every step, from this start and seven starts 1 ulp
    away): 6.4e-13 rad at 10 s from this start, median 3.0e-13 and largest 6.4e-13 over the
    eight; a 1-ulp change of q0 alone moves R(10 s) by 2.2e-13 (median; largest 2.5e-13).
    So 1e-12 holds here with a factor 5, but near what the conditioning allows: over the
    eight starts exact measures median 2.0e-13, largest 1.9e-12.  Before the round-off work
    (commit 908d2a6): 5.8e-12.
    """
    case = benchmark_cases(('van_zon',))[0]
    expected = reference_orientations(case.body, case.state, [decimal.Decimal(0.1) * 100])[0]
    simulator = Simulator(case.body, case.state, integrator='exact')
    simulator.run(10.0, 0.1)
    assert angle_to_reference(simulator.state.quaternion, expected) <= 1e-12


PROPERTY_CASES_PER_KIND = 6
PROPERTY_DURATION = 3.0


@pytest.mark.parametrize('kind', KINDS)
def test_exact_flow_matches_the_taylor_reference_on_random_bodies_and_states(kind):
    # Random bodies (inertia tensors oblique in the body frame unless exactly symmetric),
    # random orientations and momenta, one 3 s step and thirty 0.1 s steps, against the
    # 30-digit reference.  Round-off: a few ulp per radian turned (the precession angle and
    # the Jacobi functions are rounded relative to their size) plus one rounding of the state
    # per step; measured worst 2.4e-15 per (1 + rad turned) over all kinds (closer to the
    # separatrix, k'^2 down to ~1e-16); allowed 1e-14 per (1 + rad).
    rng = np.random.default_rng(100 + KINDS.index(kind))
    duration = decimal.Decimal(0.1) * 30
    for _ in range(PROPERTY_CASES_PER_KIND):
        body, state = _case(rng, kind)
        turned = np.linalg.norm(state.angular_velocity(body)) * PROPERTY_DURATION
        expected = reference_orientations(body, state, [duration])[0]
        tolerance = 1e-14 * (1.0 + turned)
        one_step = Simulator(body, state, integrator='exact').step(float(duration))
        stepped = _stepped(body, state, 0.1, 30)
        assert angle_to_reference(one_step.quaternion, expected) < tolerance
        assert angle_to_reference(stepped.quaternion, expected) < tolerance
        # Force-free translation and constant momenta come along exactly.
        assert np.array_equal(one_step.angular_momentum, state.angular_momentum)
        assert np.allclose(one_step.position, state.position + float(duration)
                           * state.linear_momentum / body.mass, rtol=1e-15, atol=1e-15)


def _separatrix_cases():
    """
    Return (body, state) pairs exactly on the separatrix, in exact arithmetic.

    I = s (1.5, 3, 4) has (I2 - I1)/I1 = 1 and (I3 - I2)/I3 = 1/4 exactly, so with R = E and
    m = (a, m2, +-2a) (powers of two) L^2 - I2 E2 = -a^2 + 4 a^2 / 4 = 0 exactly.
    """
    rng = np.random.default_rng(33)
    cases = []
    for scale in (0.5, 1.0, 4.0):
        body = RigidBody(1.0, np.diag([1.5, 3.0, 4.0]) * scale)
        for a in (0.25, 1.0, 2.0):
            for signs in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                momentum = (signs[0] * a, rng.uniform(-2.0, 2.0) * a, signs[1] * 2.0 * a)
                cases.append((body, State(angular_momentum=momentum)))
    return cases


def test_exact_flow_on_the_separatrix_uses_the_hyperbolic_closed_form_and_is_exact():
    # k'^2 = 0 exactly: sn, cn, dn are tanh, sech, sech and K is infinite.  Measured worst
    # 1.4e-15 per (1 + rad turned) against the 30-digit reference; allowed 1e-14.
    worst = 0.0
    duration = decimal.Decimal(0.1) * 30
    for body, state in _separatrix_cases():
        frame = principal_frame(body.inertia)
        momentum = frame.axes.T @ state.angular_momentum
        assert _separatrix(frame, momentum) == 0.0
        turned = np.linalg.norm(state.angular_velocity(body)) * 3.0
        expected = reference_orientations(body, state, [duration])[0]
        for final in (Simulator(body, state, integrator='exact').step(float(duration)),
                      _stepped(body, state, 0.1, 30)):
            worst = max(worst, angle_to_reference(final.quaternion, expected) / (1.0 + turned))
    assert worst < 1e-14


def test_steady_spins_about_principal_axes_are_uniform_rotations_about_l():
    # m along a principal axis: omega = L / I_i, R(t) = exp(t [L]x / I_i) R0.  Exactly along
    # it (R0 = E, diagonal tensor) the steady branch is taken and only the turn is rounded.
    # At an oblique R0 the rounding of R0^T L leaves m ~1e-16 off the axis: the stable axes
    # stay steady to round-off, and on the unstable one the elliptic solution with
    # k'^2 ~ 1e-32 (K ~ 38, the largest in double precision) carries ~eps K of round-off per
    # Carlson term (a long step subtracts the values at its two ends): allow 64 eps K.
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    duration = 2.5
    for axis in range(3):
        momentum = np.zeros(3)
        momentum[axis] = 1.7
        turned = duration * 1.7 / body.principal_moments[axis]
        for rotation in (np.eye(3), random_rotation(np.random.default_rng(axis))):
            state = State(rotation, angular_momentum=rotation @ momentum)
            final = _flow(body, state, duration)
            turn = quaternion_from_rotation_vector(duration * state.angular_momentum
                                                   / body.principal_moments[axis])
            expected = State(quaternion_multiply(turn, state.quaternion)).rotation
            error = rotation_angle_between(final.rotation, expected)
            if axis == 1 and not np.array_equal(rotation, np.eye(3)):
                assert error < 64 * EPS * 38.0
            else:
                assert error < 8 * EPS * (1.0 + turned)


# -- structure: the group property, invariants, frames -------------------------------------


@pytest.mark.parametrize('kind', KINDS)
def test_exact_flow_has_the_group_property_and_keeps_the_energy(kind):
    # Phi(t1 + t2) = Phi(t2) o Phi(t1) and Phi(-t) o Phi(t) = identity, for any t (here up to
    # many periods), to round-off; the kinetic energy 1/2 L . I_w^{-1} L is invariant.  No
    # reference needed, so many cases: 40 per kind.
    #
    # Near the separatrix the rounding of the intermediate state is amplified: it changes k'^2
    # by ~eps absolute, eps/k'^2 relative, hence K ~ 1/2 ln(16/k'^2) by eps/(2 k'^2), and the
    # motion's phase by that fraction dK/K of the angle turned.  Allowed: 1e-14 per rad
    # (a few ulp per Carlson term) plus eps/(2 k'^2 K) per rad.  Closer than k'^2 ~ 1e-9, and
    # on the separatrix, that rounding decides within ~20 s on which side of the separatrix
    # the motion goes on (measured: 1e-4 rad per rad turned for |t| <= 20 s on it): there the
    # spans are |t| <= 3 s, short of the unstable axis, and the allowance 1e-14 per rad
    # (measured 3.9e-15).
    rng = np.random.default_rng(200 + KINDS.index(kind))
    span = 3.0 if kind in SEPARATRIX_KINDS else 20.0
    worst_group = worst_energy = 0.0
    for _ in range(40):
        body, state = _case(rng, kind)
        t1, t2 = rng.uniform(-span, span, 2)
        turned = np.linalg.norm(state.angular_velocity(body)) * (abs(t1) + abs(t2))
        direct = _flow(body, state, t1 + t2)
        composed = _flow(body, _flow(body, state, t1), t2)
        back = _flow(body, _flow(body, state, t1), -t1)
        per_rad = 1e-14
        if kind == 'near_separatrix':
            complement, quarter_period = _elliptic_complement(body, state)
            per_rad += EPS / (2.0 * complement * quarter_period)
        worst_group = max(worst_group,
                          rotation_angle_between(direct.rotation, composed.rotation)
                          / ((1.0 + turned) * per_rad),
                          rotation_angle_between(back.rotation, state.rotation)
                          / ((1.0 + turned) * per_rad))
        energy = state.kinetic_energy(body)
        worst_energy = max(worst_energy, abs(direct.kinetic_energy(body) / energy - 1.0))
    assert worst_group < 1.0
    assert worst_energy < 64 * EPS


def _kinetic_energy_exactly(body, state):
    """Return 1/2 m . I_b^{-1} m, m = R(q)^T L, exactly in the stored floats (rationals)."""
    x, y, z, w = (Fraction(float(c)) for c in state.quaternion)
    norm_squared = x * x + y * y + z * z + w * w
    # R(q/|q|) = R_h(q) / |q|^2 with the homogeneous R_h.
    rotation = ((w * w + x * x - y * y - z * z, 2 * (x * y - z * w), 2 * (x * z + y * w)),
                (2 * (x * y + z * w), w * w - x * x + y * y - z * z, 2 * (y * z - x * w)),
                (2 * (x * z - y * w), 2 * (y * z + x * w), w * w - x * x - y * y + z * z))
    momentum = [Fraction(float(c)) for c in state.angular_momentum]
    body_momentum = [sum(rotation[i][j] * momentum[i] for i in range(3)) / norm_squared
                     for j in range(3)]
    tensor = [[Fraction(float(body.inertia[i, j])) for j in range(3)] for i in range(3)]
    inverse = taylor_reference._rational_inverse(tensor)
    return sum(body_momentum[i] * inverse[i][j] * body_momentum[j]
               for i in range(3) for j in range(3)) / 2


@pytest.mark.parametrize('name, dt', [('t_handle', 1e-3), ('van_zon', 1e-2)])
def test_energy_error_is_a_random_walk_not_a_drift_over_2e5_steps(name, dt):
    """
    Keep the kinetic energy of 2e5 exact steps (Simulator.run) to round-off, without drift.

    Each step rounds the stored quaternion once; that rounding alone changes the energy by
    ~0.05 eps rms per step (measured on an ideal stepper, the decimal flow rounded each step),
    a random walk of ~0.05 sqrt(N) eps after N steps.  Checked every 1000 steps, exactly in
    the stored floats: the largest relative error and the drift fitted through all of them
    must stay below 0.25 sqrt(N) eps (112 eps at N = 2e5).  Measured: largest 25 and 18 eps,
    fitted drift -9 and -7 eps (t_handle at 1 ms, van_zon at 10 ms).  Before the round-off
    work (commit 908d2a6) the energy drifted one way: -3400 and -8400 eps.
    """
    case = benchmark_cases((name,))[0]
    simulator = Simulator(case.body, case.state, integrator='exact')
    start = _kinetic_energy_exactly(case.body, case.state)
    steps, checkpoints = 200_000, 200
    errors = []
    for _ in range(checkpoints):
        simulator.run(steps // checkpoints * dt, dt)
        errors.append(float(_kinetic_energy_exactly(case.body, simulator.state) / start - 1)
                      / EPS)
    bound = 0.25 * math.sqrt(steps)
    drift = np.polyfit(np.arange(1, checkpoints + 1), errors, 1)[0] * checkpoints
    assert max(abs(e) for e in errors) < bound
    assert abs(drift) < bound


def _elliptic_complement(body, state):
    """Return (k'^2, K) of the torque-free motion from `state` (Landau-Lifshitz s. 37)."""
    frame = principal_frame(body.inertia)
    m = frame.axes.T @ (state.rotation.T @ state.angular_momentum)
    i1, i2, i3 = frame.moments
    distance = m[0] ** 2 * (i1 - i2) / i1 + m[2] ** 2 * (i3 - i2) / i3
    g = m[1] ** 2 * (i2 - i1) / i2 + m[2] ** 2 * (i3 - i1) / i3
    if distance < 0.0:
        i1, i3 = i3, i1
        g = m[1] ** 2 * (i2 - i1) / i2 + m[0] ** 2 * (i3 - i1) / i3
    complement = (i3 - i1) * distance / ((i3 - i2) * g)
    return complement, carlson_rf(0.0, complement, 1.0)


def test_exact_flow_does_not_depend_on_the_body_frame():
    # A body with inertia P D P^T in state R moves like the body D in state R P.
    rng = np.random.default_rng(34)
    for _ in range(20):
        moments = _random_moments(rng)
        axes = random_rotation(rng)
        oblique = RigidBody(1.0, axes @ np.diag(moments) @ axes.T)
        diagonal = RigidBody(1.0, np.diag(moments))
        rotation = random_rotation(rng)
        momentum = rng.normal(size=3)
        a = _flow(oblique, State(rotation, angular_momentum=momentum), 4.0)
        b = _flow(diagonal, State(rotation @ axes, angular_momentum=momentum), 4.0)
        turned = 4.0 * np.linalg.norm(momentum) / moments[0]
        assert rotation_angle_between(a.rotation @ axes, b.rotation) < 1e-14 * (1.0 + turned)


# -- the run kernel's step against the references -----------------------------------------


KERNEL_STEP_CASES_PER_KIND = 3


@pytest.mark.parametrize('kind', KINDS)
def test_one_kernel_step_of_any_length_and_sign_matches_the_taylor_reference(kind):
    # The run kernel itself (its step: start normalised, free flow, COM moved uniformly,
    # momenta kept), one step of up to 10 s either way, against the 30-digit reference;
    # round-off as in the property test above: 1e-14 per (1 + rad turned).
    rng = np.random.default_rng(300 + KINDS.index(kind))
    exact = INTEGRATORS['exact']
    for _ in range(KERNEL_STEP_CASES_PER_KIND):
        body, state = _case(rng, kind)
        dt = rng.uniform(-10.0, 10.0)
        model = new_model(body_values(body.inertia, body.inertia_inverse, body.mass),
                          np.zeros((4, 3)))
        values = np.concatenate(state._fields())
        exact.run(values, model, exact.method, dt, 1, 0.0)
        final = State._from_values(values)
        expected = reference_orientations(body, state, [dt])[0]
        turned = np.linalg.norm(state.angular_velocity(body)) * abs(dt)
        assert angle_to_reference(final.quaternion, expected) < 1e-14 * (1.0 + turned)
        assert np.array_equal(final.angular_momentum, state.angular_momentum)
        assert np.array_equal(final.linear_momentum, state.linear_momentum)
        # x + dt p / m: one rounding of the product, one of the sum.
        np.testing.assert_allclose(final.position, state.position + dt * state.velocity(body),
                                   rtol=0.0, atol=2 * EPS * np.max(np.abs(final.position)))


def test_the_kernel_under_a_held_wrench_equals_the_reference_of_the_method():
    # Simulator.run takes the kernel; test/method_reference.py's exact step is the same
    # method written again: kicks of the held wrench (world- and body-fixed parts) around a
    # DOP853 solve of the free motion.  20 steps of each kind; round-off (test_fast_paths):
    # 10 eps per wrench evaluation per step.
    rng = np.random.default_rng(35)
    for kind in KINDS:
        body, state = _case(rng, kind)
        simulator = Simulator(body, state, integrator='exact')
        assert simulator.path == 'compiled'
        held = {part: rng.normal(size=3) for part in
                ('force_world', 'torque_world', 'force_body', 'torque_body')}
        simulator.hold_wrench(**held)
        simulator.run(1.0, 0.05)
        reference = reference_run('exact', body, state, 0.05, 20, held=held)
        angle, vectors = motion_error(simulator.state, reference)
        assert max(angle, vectors) < 10 * EPS * 20 * INTEGRATORS['exact'].stages, (
            kind, angle, vectors)


# -- with a torque: second order, exact without -------------------------------------------


@wrench_term
def _lever_torque(state, time, parameters):
    """Return (0, 2 (R e3) x e_z): the moment of 2 e_z at the body point e3."""
    rx, ry, rz = rotate((state[0], state[1], state[2], state[3]), (0.0, 0.0, 1.0))
    return 0.0, 0.0, 0.0, 2.0 * ry, -2.0 * rx, 0.0


class _LeverTorque(Effect):
    compiled_wrench = staticmethod(_lever_torque)

    def wrench_parameters(self, body):
        return np.zeros(0)


def test_exact_with_a_torque_is_second_order_and_exact_without_it():
    # tau = k (R e3) x e_z (a restoring torque, like gravity on an offset COM) plus a force
    # along body x: the kicks are exact for a configuration-dependent wrench, so the error is
    # the O(h^2) of the splitting alone; the observed order must be 2 +- 0.3.  The compiled
    # kernel takes the wrench packed (the torque is the moment of the lever force 2 e_z at
    # the body point e3, the force a body-fixed one) and must keep the order and equal the
    # method's reference (test/method_reference.py, taking the wrench as written here) to
    # round-off: 10 eps per wrench evaluation per step (test_fast_paths).
    rng = np.random.default_rng(36)
    axes = random_rotation(rng)
    body = RigidBody(2.0, axes @ np.diag([1.0, 2.0, 2.5]) @ axes.T)
    state = State.from_velocity(body, rotation=random_rotation(rng), velocity=(0.3, 0.1, 0.0),
                                angular_velocity_body=(0.4, 1.0, 0.6))

    def wrench(state, time):
        # A State (the DOP853 solution) or a reference Motion: both hold the rotation R.
        rotation = state.rotation
        return 0.5 * rotation[:, 0], 2.0 * np.cross(rotation[:, 2], (0.0, 0.0, 1.0))

    # The compiled side: the torque is the moment of a lever force 2 e_z at the body point e3,
    # as a pivot at -e3 (the COM e3 from it) transmits gravity; a body force through the COM.
    lever = _LeverTorque()
    duration = 1.0
    expected = reference_solution(body, state, duration, wrench)
    errors = []
    for steps in (20, 40):
        simulator = Simulator(body, state, integrator='exact', effects=[lever])
        simulator.set_wrench(force=(0.5, 0.0, 0.0), frame='body')
        compiled = simulator.run(duration, duration / steps)
        errors.append(rotation_angle_between(compiled.rotation, expected.rotation)
                      + np.linalg.norm(compiled.angular_momentum - expected.angular_momentum))
        method = reference_run('exact', body, state, duration / steps, steps,
                               wrenches=[wrench])
        angle, vectors = motion_error(compiled, method)
        assert max(angle, vectors) < 10 * EPS * steps * INTEGRATORS['exact'].stages
    assert 1e-9 < errors[1] < errors[0] < 0.05
    assert abs(math.log2(errors[0] / errors[1]) - 2.0) < 0.3
    assert INTEGRATORS['exact'].order == 2


# -- the last rounding: the same bits as done exactly (exact_rounding_reference) ---------


def _sandwich_twice_energy(body_frame, quaternion, angular_momentum):
    """Return 2T = m . J m, m = q* L q / |q|^2, J = A diag(1/I) A^T, in Fractions."""
    x, y, z, w = quaternion
    lx, ly, lz = (Fraction(float(c)) for c in angular_momentum)
    # t = L q (L a pure quaternion), then m = q* t (vector part), over |q|^2.
    tx, ty, tz = lx * w + ly * z - lz * y, ly * w + lz * x - lx * z, lz * w + lx * y - ly * x
    tw = -(lx * x + ly * y + lz * z)
    m = (w * tx - x * tw - (y * tz - z * ty), w * ty - y * tw - (z * tx - x * tz),
         w * tz - z * tw - (x * ty - y * tx))
    norm_squared = x * x + y * y + z * z + w * w
    axes = [[Fraction(float(c)) for c in row] for row in body_frame.axes]
    moments = [Fraction(float(c)) for c in body_frame.moments]
    principal = [sum(axes[j][k] * m[j] for j in range(3)) / norm_squared for k in range(3)]
    return sum(principal[k] ** 2 / moments[k] for k in range(3))


def test_the_oracles_energy_is_exact_in_the_stored_floats():
    # The oracle (exact_rounding_reference) holds q' = q + q (D - 1) and its energy in
    # integers over powers of two: they must equal the rational value of the same floats
    # exactly, here against an independent formula (the quaternion sandwich q* L q instead
    # of the matrix R_h).
    rng = np.random.default_rng(37)
    for kind in KINDS:
        for _ in range(4):
            body, state = _case(rng, kind)
            frame = principal_frame(body.inertia)
            # A quaternion that is the exact sum of two doubles per component, not unit.
            values = tuple(state.quaternion) + tuple(rng.normal(size=4) * 1e-3)
            parts, _ = oracle.dyadic(values)
            integers = [parts[i] + parts[4 + i] for i in range(4)]
            momentum = [float(c) for c in state.angular_momentum]
            (l, momentum_shift) = oracle.dyadic(momentum)
            (a, axes_shift), ratios = oracle.frame_integers(
                tuple(frame.axes.ravel().tolist()), tuple(frame.moments.tolist()))
            numerator, norm = oracle.twice_energy_exactly(integers, l, a, ratios)
            common = (ratios[0][0] * ratios[1][0] * ratios[2][0]
                      << 2 * (momentum_shift + axes_shift))
            quaternion = [Fraction(values[i]) + Fraction(values[4 + i]) for i in range(4)]
            assert Fraction(numerator, common * norm ** 2) == _sandwich_twice_energy(
                frame, quaternion, state.angular_momentum)


@pytest.mark.parametrize('kind', KINDS)
def test_the_compiled_last_rounding_gives_the_oracles_bits(kind):
    # Given the same increment D - 1, the compiled rounding (double-double, ~1e-32) and the
    # oracle's (exact, in integers) round to the same double but in ties of probability
    # ~1e-16: every case must give the same bits, with and without the energy turn.
    rng = np.random.default_rng(400 + KINDS.index(kind))
    turned = 0
    for _ in range(40):
        body, state = _case(rng, kind)
        frame = principal_frame(body.inertia)
        quaternion = tuple(float(c) for c in state.quaternion)
        momentum = tuple(float(c) for c in state.angular_momentum)
        mx, my, mz = rotate_back(quaternion, momentum)
        norm = math.sqrt(sum(c * c for c in momentum))
        duration = rng.uniform(-1.0, 1.0)
        if frame.kind == ASYMMETRIC:
            increment = exact_module._asymmetric_increment(mx, my, mz, norm, frame.moments,
                                                           frame.axes, duration)
        else:
            increment = exact_module._symmetric_increment(mx, my, mz, norm, frame.moments,
                                                          frame.axes, frame.kind, duration)
        exact = oracle.rounded_step(frame, quaternion, increment, momentum)
        compiled = exact_module._rounded_step(quaternion, increment, *momentum, frame.moments,
                                              frame.axes, frame.kind)
        assert np.array_equal(exact, np.array(compiled)), (exact, compiled)
        plain = exact_module._rounded_step(quaternion, increment, *momentum, frame.moments,
                                           frame.axes, SPHERICAL)
        turned += not np.array_equal(exact, np.array(plain))
    # The energy turn changed the result in some cases (it is not vacuous here) unless
    # the body's energy does not depend on its orientation.
    assert turned > 0 or kind == 'spherical'

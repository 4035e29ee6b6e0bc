"""
Every built-in scene against theory, at the scene's own integrator and default step.

Frames world, units SI.  Tolerances come from the theory or from the method order: the
scenes' integrators are second order, so an error scales as (omega dt)^2 with omega the
fastest rate that matters (the nutation rate for a top), and halving the step divides it
by ~4.
"""

import hashlib
import math

import numpy as np
import pytest
from reference import torque_free_omega_period
from rigid_body_sim.physics import Simulator
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import scene_names
from scipy.integrate import quad

G = 9.81
EPS = np.finfo(float).eps
# Halving the step must divide a second-order error by 4; >= 3.4 allows the next order.
SECOND_ORDER = 3.4


# -- torque-free scenes: the intermediate-axis theorem and the elliptic period


def _flip_times(simulator, body, duration, dt):
    """Return the times (s) at which the body rate Omega2 changes sign (interpolated)."""
    times = []
    previous = simulator.state.angular_velocity_body(body)[1]
    for _ in range(int(round(duration / dt))):
        current = simulator.step(dt).angular_velocity_body(body)[1]
        if (current > 0.0) != (previous > 0.0):
            times.append(simulator.time - dt * current / (current - previous))
        previous = current
    return np.array(times)


def _elliptic_period(scene):
    return torque_free_omega_period(np.diag(scene.body.inertia),
                                    scene.state.angular_velocity_body(scene.body))


def _flip_period(name, periods):
    """
    Return (measured, elliptic, flips): the period (s) of Omega2 over `periods` periods.

    The measured period is twice the mean time between sign changes of Omega2 (nan with
    fewer than two); `flips` are those times (s); `elliptic` is the closed form 4 K / rate.
    """
    scene = load_scene(name)
    expected = _elliptic_period(scene)
    flips = _flip_times(scene.simulator(), scene.body, periods * expected, scene.dt)
    measured = 2.0 * float(np.mean(np.diff(flips))) if len(flips) >= 2 else math.nan
    return measured, expected, flips


@pytest.mark.parametrize('name, periods', [('t_handle', 3), ('default', 3),
                                           ('tennis_racket', 4), ('van_zon', 4)])
def test_middle_axis_flip_period_matches_the_elliptic_closed_form(name, periods):
    # Landau-Lifshitz section 37: Omega2 ~ sn(tau | k^2) changes sign twice per period
    # T = 4 K(k^2) / rate; the issue asks for 0.5 % at the scene's default step.
    measured, expected, flips = _flip_period(name, periods)
    assert len(flips) >= 2 * periods - 1
    assert measured == pytest.approx(expected, rel=0.005)


def _first_flip(scene, integrator):
    """Return (first sign change of Omega2, T / 4) in s and the tolerance 2 (|Omega| dt)^2."""
    expected = _elliptic_period(scene) / 4.0
    omega = np.linalg.norm(scene.state.angular_velocity_body(scene.body))
    simulator = scene.simulator(integrator=integrator)
    flips = _flip_times(simulator, scene.body, 1.2 * expected, scene.dt)
    return flips[0], expected, 2.0 * (omega * scene.dt) ** 2


@pytest.mark.parametrize('name', ['t_handle', 'tennis_racket', 'thrown_box'])
def test_first_flip_comes_after_a_quarter_period_even_with_buss(name):
    # At t = 0 Omega3 = 0: the rates start at the extremum of sn, so the first flip is at
    # T / 4.  The seed's buss gets this right at the default step; its energy drift shows
    # only in later flips (see t_handle.yaml).  The thrown box's flip is torque-free too:
    # gravity acts at the COM.  Both methods are second order: 2 (|Omega| dt)^2.
    scene = load_scene(name)
    for integrator in (scene.integrator, 'buss'):
        first, expected, tolerance = _first_flip(scene, integrator)
        assert first == pytest.approx(expected, rel=tolerance), integrator


def _widest_cone(scene, axis, duration):
    """Return max |Omega_perp| (rad/s): the body rate away from `axis` over the run."""
    simulator, body = scene.simulator(), scene.body
    widest = 0.0
    for _ in range(int(round(duration / scene.dt))):
        omega = simulator.step(scene.dt).angular_velocity_body(body)
        widest = max(widest, float(np.linalg.norm(np.delete(omega, axis))))
    return widest


def _linear_cone(moments, axis, omega_body):
    """
    Return the largest |Omega_perp| of linear theory for spin about a stable `axis`.

    Linearised Euler equations about a spin n along axis a, with (b, c) the other axes:
    I_b (I_a - I_b) Omega_b^2 + I_c (I_a - I_c) Omega_c^2 is constant.  For the largest or
    smallest axis both weights have one sign, so it is an ellipse; its widest point from
    the start (Omega_b0, Omega_c0) is returned.
    """
    b, c = [k for k in range(3) if k != axis]
    weight_b = abs(moments[b] * (moments[axis] - moments[b]))
    weight_c = abs(moments[c] * (moments[axis] - moments[c]))
    invariant = weight_b * omega_body[b] ** 2 + weight_c * omega_body[c] ** 2
    return math.sqrt(invariant / min(weight_b, weight_c))


def _stable_cone(name, omega_body, axis):
    """
    Return (widest, bound, limit) in rad/s for a spin about the stable `axis` over 20 turns.

    `widest` is the simulated max |Omega_perp|, `bound` linear theory's, and `limit` the
    bound widened by (Omega_perp / n)^2 (linear theory) and (n dt)^2 (the method).
    """
    scene = load_scene(name)
    if omega_body is not None:
        scene = scene.with_overrides(angular_velocity_body=omega_body)
    omega = scene.state.angular_velocity_body(scene.body)
    bound = _linear_cone(np.diag(scene.body.inertia), axis, omega)
    spin = abs(omega[axis])
    # Linear theory up to (Omega_perp / n)^2 ~ 1e-5 and the method's (n dt)^2.
    widest = _widest_cone(scene, axis, 20.0 * 2.0 * math.pi / spin)
    return widest, bound, bound * (1.0 + (spin * scene.dt) ** 2 + (bound / spin) ** 2)


@pytest.mark.parametrize('name, omega_body, axis', [
    ('stable_spin', None, 2),
    ('stable_spin', (2.0, 0.002, 0.0), 0),
    ('tennis_racket', (12.0, 0.05, 0.0), 0),
    ('tennis_racket', (0.0, 0.05, 12.0), 2),
])
def test_spin_about_the_largest_and_smallest_axes_stays_in_its_cone(name, omega_body, axis):
    widest, _, limit = _stable_cone(name, omega_body, axis)
    assert widest <= limit


def _middle_axis_flip(name):
    """
    Return (lowest, flipped, tolerance): min Omega2 (rad/s) over 0.6 period, -Omega2(0).

    The relative tolerance is the method's (Omega2 dt)^2 plus 1e-4.
    """
    scene = load_scene(name)
    omega = scene.state.angular_velocity_body(scene.body)
    simulator = scene.simulator()
    lowest = omega[1]
    for _ in range(int(round(0.6 * _elliptic_period(scene) / scene.dt))):
        lowest = min(lowest, simulator.step(scene.dt).angular_velocity_body(scene.body)[1])
    return lowest, -omega[1], (abs(omega[1]) * scene.dt) ** 2 + 1e-4


@pytest.mark.parametrize('name', ['t_handle', 'tennis_racket'])
def test_spin_about_the_middle_axis_flips_over(name):
    lowest, flipped, tolerance = _middle_axis_flip(name)
    # Half a period later the exact solution has Omega2 = -Omega2(0): a complete flip,
    # where the same nudge about the other axes stays ~1e-3 of the spin (above).
    assert lowest == pytest.approx(flipped, rel=tolerance)


def _van_zon_run():
    """
    Return the van Zon body's start and 20 s later, and the energy tolerance.

    (L0, L, E0, E, rel): world angular momentum (kg m^2/s) and energy (J) at both ends,
    and the relative energy tolerance (|omega| dt)^2 of a second-order method.
    """
    scene = load_scene('van_zon')
    simulator = scene.simulator()
    energy = simulator.energy()
    final = simulator.run(20.0, scene.dt)
    omega = np.linalg.norm(scene.state.angular_velocity(scene.body))
    return (scene.state.angular_momentum, final.angular_momentum, energy, simulator.energy(),
            (omega * scene.dt) ** 2)


def test_van_zon_body_keeps_its_angular_momentum_exactly_and_its_energy():
    start_momentum, momentum, start_energy, energy, tolerance = _van_zon_run()
    np.testing.assert_allclose(momentum, start_momentum, rtol=1e-13)
    assert energy == pytest.approx(start_energy, rel=tolerance)


# -- the heavy symmetric top and the bicycle wheel: pivot + gravity


class SymmetricTop:
    """
    The exact motion of a heavy symmetric top, from its constants (Goldstein 5.7).

    With u = cos(theta) (tilt of the symmetry axis e3 from the vertical), the pivot's
    inertia I1' = I1 + m d^2, a = I3 omega3 / I1', b = L_z / I1', beta = 2 m g d / I1',
    alpha = 2 (E - I3 omega3^2 / 2) / I1', energy and momentum conservation give
    du/dt^2 = f(u) = (alpha - beta u)(1 - u^2) - (b - a u)^2, a cubic whose two roots in
    [-1, 1] are the turning points of the nutation; the precession rate is
    dphi/dt = (b - a u) / (1 - u^2).  f = beta (u - u1)(u - u2)(u - u3), so with
    u = u1 + (u2 - u1)(1 - cos s)/2 the time element is dt = ds / sqrt(beta (u3 - u)):
    smooth quadratures for the nutation period and the mean precession rate.
    """

    def __init__(self, scene):
        body, pivot, state = scene.body, scene.pivot, scene.state
        self.mass = body.mass
        self.distance = float(np.linalg.norm(pivot.point))
        self.i1 = body.inertia[0, 0] + self.mass * self.distance ** 2
        self.i3 = body.inertia[2, 2]
        self.omega3 = state.angular_velocity_body(body)[2]
        energy = scene.simulator().energy()
        vertical = pivot.angular_momentum_about_pivot(body, state)[2]
        self.a = self.i3 * self.omega3 / self.i1
        self.b = vertical / self.i1
        self.beta = 2.0 * self.mass * G * self.distance / self.i1
        alpha = 2.0 * (energy - 0.5 * self.i3 * self.omega3 ** 2) / self.i1
        cubic = [self.beta, -(alpha + self.a ** 2), 2.0 * self.a * self.b - self.beta,
                 alpha - self.b ** 2]
        self.roots = np.sort(np.roots(cubic).real)
        self.u0 = state.rotation[2, 2]

    def _u(self, s):
        u1, u2 = self.roots[0], self.roots[1]
        return u1 + (u2 - u1) * 0.5 * (1.0 - math.cos(s))

    def _time_weight(self, s):
        return 1.0 / math.sqrt(self.beta * (self.roots[2] - self._u(s)))

    def nutation_period(self):
        """Return the period (s) of u(t) between the turning points."""
        return 2.0 * quad(self._time_weight, 0.0, math.pi, epsabs=0.0, epsrel=1e-13)[0]

    def mean_precession_rate(self):
        """Return the time average of dphi/dt over a nutation period (rad/s)."""
        def rate(s):
            u = self._u(s)
            return (self.b - self.a * u) / (1.0 - u * u) * self._time_weight(s)
        return 2.0 * quad(rate, 0.0, math.pi, epsabs=0.0, epsrel=1e-13)[0] / (
            self.nutation_period())

    def fast_top_rate(self):
        """Return the fast-top approximation m g d / (I3 omega3) (rad/s)."""
        return self.mass * G * self.distance / (self.i3 * self.omega3)

    def smallness(self):
        """Return eps = m g d I1' / (I3 omega3)^2, the fast-top expansion parameter."""
        return self.mass * G * self.distance * self.i1 / (self.i3 * self.omega3) ** 2

    def exchanged_energy(self):
        """Return m g d (u2 - u1) (J): the energy the nutation trades, potential for kinetic."""
        return self.mass * G * self.distance * (self.roots[1] - self.roots[0])


class TopRun:
    """A run of a pivot scene over whole nutation periods, sampled every step."""

    def __init__(self, scene, dt, periods):
        self.theory = SymmetricTop(scene)
        body, pivot = scene.body, scene.pivot
        simulator = scene.simulator()
        duration = periods * self.theory.nutation_period()
        start = simulator.state
        axis = start.rotation[:, 2]
        energy = simulator.energy()
        momentum = pivot.angular_momentum_about_pivot(body, start)
        self.heights, azimuths = [axis[2]], [math.atan2(axis[1], axis[0])]
        self.energy_error = self.vertical_error = self.spin_error = 0.0
        spin = momentum @ axis
        for _ in range(int(math.floor(duration / dt))):
            state = simulator.step(dt)
            axis = state.rotation[:, 2]
            current = pivot.angular_momentum_about_pivot(body, state)
            self.heights.append(axis[2])
            azimuths.append(math.atan2(axis[1], axis[0]))
            self.energy_error = max(self.energy_error, abs(simulator.energy() - energy))
            self.vertical_error = max(self.vertical_error, abs(current[2] - momentum[2]))
            self.spin_error = max(self.spin_error, abs(current @ axis - spin))
        # End exactly after the whole periods, so the mean rate is the period average.
        state = simulator.run(duration - simulator.time, dt)
        azimuths.append(math.atan2(state.rotation[1, 2], state.rotation[0, 2]))
        self.precession_rate = (np.unwrap(azimuths)[-1] - azimuths[0]) / simulator.time
        self.momentum = float(np.linalg.norm(momentum))
        self.spin = spin
        # The mean step: the tick over the mean substeps (error control's, or 1).
        self.step = dt / simulator.substep_statistics()['substeps_mean']
        # The method's error scale: the fastest slow motion, nutation, times the step.
        self.phase_error = (self.theory.a * dt) ** 2


def _top_runs():
    """
    Return the pivot scenes' TopRuns at their tick and tolerance, and at half the step.

    Half the step: under error control a quarter of the tolerance, since a second-order
    method's error rate goes as h^2 (r ~ C h^2: the substeps double); without it, half the
    tick.
    """
    runs = {}
    for name, periods in (('heavy_top', 6), ('bike_wheel', 4)):
        scene = load_scene(name)
        runs[name] = TopRun(scene, scene.dt, periods)
        if scene.tolerance is None:
            runs[name, 'half step'] = TopRun(scene, 0.5 * scene.dt, periods)
        else:
            runs[name, 'half step'] = TopRun(
                scene.with_overrides(tolerance=0.25 * scene.tolerance), scene.dt, periods)
    return runs


@pytest.fixture(scope='module')
def top_runs():
    return _top_runs()


@pytest.mark.parametrize('name', ['heavy_top', 'bike_wheel'])
def test_precession_rate_matches_the_exact_gyroscopic_precession(top_runs, name):
    run = top_runs[name]
    assert run.precession_rate == pytest.approx(run.theory.mean_precession_rate(),
                                                rel=run.phase_error)


@pytest.mark.parametrize('name', ['heavy_top', 'bike_wheel'])
def test_precession_rate_is_m_g_d_over_i3_omega3_to_the_fast_top_order(top_runs, name):
    # Averaged over a nutation, the precession of a top released without precession is
    # m g d / (I3 omega3) (1 + eps cos(theta0) + O(eps^2)), eps = m g d I1' / (I3 omega3)^2
    # (expanding the quadrature to first order in eps).  The second-order coefficient is
    # O(1): +1 for the 30 degree top, -2 for the horizontal axle (from the quadrature).
    run = top_runs[name]
    theory = run.theory
    eps = theory.smallness()
    relative = run.precession_rate / theory.fast_top_rate() - 1.0
    assert abs(relative) <= 2.0 * eps
    assert abs(relative - eps * theory.u0) <= 3.0 * eps ** 2 + run.phase_error
    # Counterclockwise seen from above, like the spin, for a spin along +e3.
    assert run.precession_rate > 0.0


@pytest.mark.parametrize('name', ['heavy_top', 'bike_wheel'])
def test_nutation_stays_between_the_turning_points_of_the_cubic(top_runs, name):
    run = top_runs[name]
    lower, upper = run.theory.roots[0], run.theory.roots[1]
    swing = upper - lower
    assert swing > 0.0 and abs(run.theory.u0 - upper) < 1e-12 * swing + 1e-15
    tolerance = run.phase_error * swing
    assert min(run.heights) == pytest.approx(lower, abs=tolerance)
    assert max(run.heights) == pytest.approx(upper, abs=tolerance)


@pytest.mark.parametrize('name', ['heavy_top', 'bike_wheel'])
def test_top_keeps_energy_vertical_momentum_and_spin(top_runs, name):
    run, finer = top_runs[name], top_runs[name, 'half step']
    theory = run.theory
    # The gravity torque about the pivot is horizontal and the free drift keeps L_pivot:
    # L_z is conserved to round-off.
    assert run.vertical_error <= 1e-14 * run.momentum
    # Energy and the spin component L . e3 are conserved by the motion, and by a
    # second-order method up to O(dt^2): the error shrinks >= 4x per halved step (by
    # (step ratio)^2: error control's whole substeps halve the step only nearly), and the
    # energy error is (a dt)^2 of the energy exchanged by the nutation, m g d (u2 - u1).
    shrink = SECOND_ORDER / 4.0 * (run.step / finer.step) ** 2
    assert run.energy_error <= run.phase_error * theory.exchanged_energy()
    assert run.energy_error >= shrink * finer.energy_error
    assert run.spin_error >= shrink * finer.spin_error
    assert run.spin_error <= run.phase_error * abs(run.spin)


# -- thrown_box: the COM parabola is exact, the rotation torque-free


def _thrown_box_flight(scene):
    """
    Yield, every 0.1 s for 1 s, the thrown box's state, its free twin's and the parabola.

    (state, free_state, position, velocity, steps): the scene's state, the same body and
    start without gravity (same integrator and tolerance, so the same substeps), the exact
    COM position (m) and velocity (m/s), world frame, and the integrator steps so far.
    """
    body, start = scene.body, scene.state
    thrown = scene.simulator()
    free = Simulator(body, start, integrator=scene.integrator, tolerance=scene.tolerance)
    g = np.array([0.0, 0.0, -G])
    for _ in range(10):
        state = thrown.run(0.1, scene.dt)
        free.run(0.1, scene.dt)
        t = thrown.time
        yield (state, free.state, start.position + start.velocity(body) * t + 0.5 * g * t * t,
               start.velocity(body) + g * t, thrown.substep_statistics()['steps'])


def test_thrown_box_flies_the_exact_parabola_and_tumbles_torque_free():
    scene = load_scene('thrown_box')
    body, start = scene.body, scene.state
    for state, free_state, position, velocity, steps in _thrown_box_flight(scene):
        # Kick-drift-kick is exact for a constant force: round-off only, each step rounding
        # x and p once (<= 1 ulp of the largest component, summed over the steps, the
        # estimates' extra steps counted too).
        for value, exact in ((state.position, position), (state.velocity(body), velocity)):
            np.testing.assert_allclose(value, exact, rtol=0,
                                       atol=2.0 * steps * EPS * np.max(np.abs(exact)))
        # Gravity has no torque about the COM: world L is constant and the rotation is
        # bit for bit that of the same body without gravity.
        np.testing.assert_array_equal(state.angular_momentum, start.angular_momentum)
        np.testing.assert_array_equal(state.quaternion, free_state.quaternion)


# -- flat_spin: dissipation at constant L


def _flat_spin_run(scene):
    """
    Run the flat_spin scene 80 s and the same body without dissipation beside it.

    Return (energies, free_energies, momenta, state): the energies (J) of both every
    0.5 s from t = 0, the world L (kg m^2/s) of the dissipating body every 0.5 s from
    t = 0.5 s, and its final state.
    """
    body, start = scene.body, scene.state
    simulator = scene.simulator()
    free = Simulator(body, start, integrator=scene.integrator)
    energies, free_energies, momenta = [simulator.energy()], [free.energy()], []
    for _ in range(160):
        state = simulator.run(0.5, scene.dt)
        energies.append(simulator.energy())
        momenta.append(state.angular_momentum)
        free.run(0.5, scene.dt)
        free_energies.append(free.energy())
    return energies, free_energies, momenta, state


def test_flat_spin_keeps_l_drains_energy_and_ends_about_the_largest_axis():
    scene = load_scene('flat_spin')
    body, start = scene.body, scene.state
    momentum = start.angular_momentum
    flat_energy = (momentum @ momentum) / (2.0 * body.principal_moments[2])
    energies, free_energies, momenta, state = _flat_spin_run(scene)
    for current in momenta:
        # Dissipation turns R only: world L is untouched, so |L| is constant (to 1e-9
        # asked; exactly here).
        np.testing.assert_array_equal(current, momentum)
    # Energy never rises, beyond the free integrator's own energy wobble.
    wobble = max(free_energies) - min(free_energies)
    assert np.all(np.diff(energies) <= wobble)
    assert energies[0] > 8.0 * flat_energy
    # After 80 s the spin is flat: energy |L|^2 / (2 I3) and spin along the largest axis.
    assert energies[-1] == pytest.approx(flat_energy, rel=1e-4)
    axis = body.principal_axes[:, 2]
    omega = state.angular_velocity_body(body)
    assert abs(omega @ axis) / np.linalg.norm(omega) > 1.0 - 1e-4


# -- driven and default: torque-free until pushed from outside


def _held_push(scene, simulator):
    """
    Run the scene's simulator 1 s unpushed, then 2 s under a held world force and torque.

    Return (unpushed, before, after, force, torque): the state after the unpushed second,
    the states at the start and end of the push, and the force (N) and torque (N m): the
    request (0, 0.4, 0) N and (0, 0, 0.3) N m as the scene's limits pass it.
    """
    simulator.run(1.0, scene.dt)
    unpushed = simulator.state
    force, torque = scene.external_wrench.limit([0.0, 0.4, 0.0], [0.0, 0.0, 0.3])
    simulator.set_wrench(force=force, torque=torque)
    before = simulator.state
    after = simulator.run(2.0, scene.dt)
    return unpushed, before, after, force, torque


@pytest.mark.parametrize('name', ['driven', 'default'])
def test_outside_push_changes_the_momenta_exactly_as_held(name):
    scene = load_scene(name)
    simulator = scene.simulator()
    assert scene.accepts_external_wrench and simulator.wrench_function() is None
    unpushed, before, after, force, torque = _held_push(scene, simulator)
    np.testing.assert_array_equal(unpushed.angular_momentum, scene.state.angular_momentum)
    # A held world torque: L(t) = L0 + tau t; a held force: the parabola.  Round-off only:
    # two kicks and a drift per step, each rounding once (<= 1 ulp of the largest value),
    # over the steps of the run (error control may take many per tick).
    steps = simulator.substep_statistics()['steps']
    for value, exact in ((after.angular_momentum, before.angular_momentum + 2.0 * torque),
                         (after.linear_momentum, before.linear_momentum + 2.0 * force),
                         (after.position, before.position + 0.5 * force / scene.body.mass * 4.0)):
        np.testing.assert_allclose(value, exact, rtol=0, atol=max(
            1e-13, 2.0 * steps * EPS * np.max(np.abs(exact))))


# -- translation is skipped when nothing pushes the COM; determinism


def _one_second_later(scene):
    """Return the scene's state after 1 s at its own integrator and step."""
    return scene.simulator().run(1.0, scene.dt)


@pytest.mark.parametrize('name', ['t_handle', 'stable_spin', 'tennis_racket', 'van_zon',
                                  'flat_spin', 'driven'])
def test_unpushed_com_stays_exactly_where_it_was(name):
    scene = load_scene(name)
    final = _one_second_later(scene)
    np.testing.assert_array_equal(final.position, scene.state.position)
    np.testing.assert_array_equal(final.linear_momentum, scene.state.linear_momentum)


def _state_hash(state):
    digest = hashlib.sha256()
    for array in state._fields():
        digest.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
    return digest.hexdigest()


def _final_hash(scene, steps, dt, one_at_a_time):
    simulator = scene.simulator()
    if scene.accepts_external_wrench:
        simulator.set_wrench(torque=(0.0, 0.0, 0.01))
    if one_at_a_time:
        for _ in range(steps):
            simulator.step(dt)
    else:
        simulator.run(steps * dt, dt)
    return _state_hash(simulator.state)


@pytest.mark.parametrize('name', scene_names(several_bodies=False))
def test_same_scene_integrator_and_step_give_a_bit_identical_trajectory(name):
    # Twice the same calls give the same bits, both for one run() and for tick-by-tick
    # step() as the node does.  (The two differ in the last bits where a compiled kernel
    # takes the steps: each call re-normalises the quaternion it returns.)
    scene = load_scene(name)
    for one_at_a_time in (False, True):
        first = _final_hash(scene, 300, scene.dt, one_at_a_time)
        assert _final_hash(scene, 300, scene.dt, one_at_a_time) == first
    # The hash does see the trajectory: another step gives another state.  (Under error
    # control half the tick may mean the very same substeps, hence a fixed step here.)
    assert _final_hash(scene.with_overrides(tolerance=0.0), 600, 0.5 * scene.dt,
                       False) != first

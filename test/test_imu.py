"""
Tests of the IMU core: the specific force at the mount point and Kalibr's noise model.

The compiled reading is held to test/imu_reference.py, the kinematics written in numpy.
"""

import math

from imu_reference import accelerations
from imu_reference import specific_force_body
import numpy as np
import pytest
from rigid_body_sim.physics.imu import ImuModel
from rigid_body_sim.physics.imu import KalibrNoise
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import parse_scene

EPS = np.finfo(float).eps
GRAVITY = np.array([0.0, 0.0, -9.81])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def test_free_fall_reads_zero_specific_force():
    reading = specific_force_body(GRAVITY, np.zeros(3), np.zeros(3), IDENTITY,
                                  np.zeros(3), GRAVITY)
    assert np.array_equal(reading, np.zeros(3))


def test_body_at_rest_reads_gravity_up():
    reading = specific_force_body(np.zeros(3), np.zeros(3), np.zeros(3), IDENTITY,
                                  np.array([0.1, 0.0, 0.0]), GRAVITY)
    assert np.array_equal(reading, np.array([0.0, 0.0, 9.81]))


def test_spin_off_the_mount_point_reads_centripetal_omega_squared_r():
    omega, r = 3.0, 0.2
    reading = specific_force_body(np.zeros(3), np.zeros(3), np.array([0.0, 0.0, omega]),
                                  IDENTITY, np.array([r, 0.0, 0.0]), np.zeros(3))
    # Toward the axis: -omega^2 r along x; round-off of two cross products only.
    np.testing.assert_allclose(reading, [-omega ** 2 * r, 0.0, 0.0], rtol=1e-15, atol=0)


def test_same_seed_gives_the_same_noise_sequence():
    first, second = KalibrNoise(1e-3, 1e-4, 1e-2, seed=7), KalibrNoise(1e-3, 1e-4, 1e-2, seed=7)
    for _ in range(100):
        assert np.array_equal(first.corrupt(np.zeros(3), 0.01), second.corrupt(np.zeros(3), 0.01))


def test_noise_off_equals_the_truth():
    noise = KalibrNoise(0.0, 0.0, 0.0, seed=1)
    truth = np.array([0.1, -0.2, 9.81])
    assert np.array_equal(noise.corrupt(truth, 0.01), truth)


def _overlapping_allan_deviation(samples, dt, m):
    # Overlapping estimator (IEEE 1139): sigma^2(m dt) = <(theta[k+2m] - 2 theta[k+m]
    # + theta[k])^2> / (2 (m dt)^2), theta the integral of the rate.
    theta = np.concatenate([[0.0], np.cumsum(samples) * dt])
    second = theta[2 * m:] - 2.0 * theta[m:-m] + theta[:-2 * m]
    return np.sqrt(np.mean(second ** 2) / (2.0 * (m * dt) ** 2))


def test_allan_deviation_recovers_white_noise_density_and_random_walk():
    # N = 1e-2, K = 1e-3: white noise dominates at tau = 1 s (K^2/3 adds 0.2 % to the
    # variance), the bias walk at tau = 100 s (N^2/tau adds 3 %); each is compared with the
    # model sigma^2(tau) = N^2 / tau + K^2 tau / 3, so neither region's leak counts as error.
    # The record (2e4 s) holds 200 spans of 100 s: an estimate's scatter is a few %.
    density, walk, dt, count = 1e-2, 1e-3, 0.1, 200_000
    noise = KalibrNoise(density, walk, 0.0, seed=3)
    record = np.array([noise.corrupt(np.zeros(3), dt) for _ in range(count)])
    for axis in range(3):
        for tau in (1.0, 100.0):  # white noise region (slope -1/2), random walk (+1/2)
            model = np.sqrt(density ** 2 / tau + walk ** 2 * tau / 3.0)
            estimate = _overlapping_allan_deviation(record[:, axis], dt, round(tau / dt))
            assert abs(estimate / model - 1.0) < 0.10


# -- the IMU on a simulated scene: accelerations from the wrench, the pivot, the mount


def _reading_after(scene, ticks, model=None):
    """Run `scene` for `ticks` ticks; return its IMU's noiseless reading then."""
    simulator = scene.simulator()
    for _ in range(ticks):
        simulator.step(scene.dt)
    wrench = simulator.wrench_function()
    force, torque = (np.zeros(3), np.zeros(3)) if wrench is None else wrench(
        simulator.state, simulator.time)
    return scene.imu_sensor(model).truth(simulator.state, force, torque), simulator


def test_a_thrown_box_in_free_fall_reads_zero_specific_force():
    scene = load_scene('thrown_box')
    (_, omega, specific_force), simulator = _reading_after(scene, 50)
    # a_COM = F / m = g exactly, so a - g is 0 up to the rotation's round-off.
    np.testing.assert_allclose(specific_force, 0.0, rtol=0, atol=1e-15 * 9.81)
    # The gyro's Omega = I^-1 R^T L, compiled, against State's numpy form of it: two ways to
    # the same number (numpy's R^T L and I^-1 v are BLAS calls, whose kernel, and so the
    # order of the sums and whether they fuse, is chosen per CPU: they differ by an ulp on an
    # AVX-512 machine).  Each forms R from q (entries <= 1, <= 4 roundings each; the numpy
    # side normalises q once more: <= 4 more), then R^T L and I^-1 (R^T L) as sums of three
    # products (<= 3 roundings each, in any order, fused or not): per component <= 14
    # roundings of u = eps / 2 of terms at most sum_j |I^-1_ij| |L|_1 in size; twice that
    # between the two.
    state = simulator.state
    scale = np.abs(scene.body.inertia_inverse).sum(axis=1) * np.abs(state.angular_momentum).sum()
    expected = state.angular_velocity_body(scene.body)
    tolerance = 2 * 14 * (EPS / 2) * scale
    assert np.all(np.abs(omega - expected) <= tolerance), (omega, expected, tolerance)


HANGING = {'name': 'hanging', 'description': 'a box hanging at rest below its pivot',
           'body': {'mass': 2.0, 'shape': 'box', 'size': [0.1, 0.2, 0.3]},
           'effects': [{'pivot': {'point': [0.0, 0.0, 0.5]}}, 'gravity']}


def test_a_body_hanging_at_rest_on_its_pivot_reads_g_up():
    scene = parse_scene(HANGING, 'hanging.yaml')
    # The IMU 0.1 m off the COM: at rest nothing but the support shows.
    model = ImuModel(position=(0.1, 0.0, 0.0))
    (orientation, omega, specific_force), _ = _reading_after(scene, 100, model)
    np.testing.assert_array_equal(omega, 0.0)
    np.testing.assert_array_equal(specific_force, [0.0, 0.0, 9.81])
    np.testing.assert_array_equal(orientation, [0.0, 0.0, 0.0, 1.0])


def test_a_hanging_imu_turned_on_its_mount_reads_g_along_its_own_up_axis():
    scene = parse_scene(HANGING, 'hanging.yaml')
    # The IMU turned +90 deg about body x: its y axis points down the body's z.
    half = math.sqrt(0.5)
    model = ImuModel(orientation=(half, 0.0, 0.0, half))
    (orientation, _, specific_force), _ = _reading_after(scene, 10, model)
    # The mount's rotation matrix from sqrt(1/2) entries: a few eps of |g| (2.2e-15 each).
    np.testing.assert_allclose(specific_force, [0.0, 9.81, 0.0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(orientation, [half, 0.0, 0.0, half], rtol=0, atol=1e-16)


SPIN = {'name': 'spin', 'description': 'a cylinder spinning about its axis',
        'body': {'mass': 1.0, 'shape': 'cylinder', 'radius': 0.1, 'height': 0.05},
        'initial': {'angular_velocity_body': [0.0, 0.0, 7.0]}}


def test_a_spin_about_an_axis_off_the_mount_reads_omega_squared_r_toward_it():
    scene = parse_scene(SPIN, 'spin.yaml')
    r = 0.04
    (_, omega, specific_force), _ = _reading_after(scene, 37, ImuModel(position=(r, 0, 0)))
    # Torque-free about a principal axis: alpha = I^-1 (-omega x L) = 0 exactly.
    np.testing.assert_allclose(omega, [0.0, 0.0, 7.0], rtol=1e-15, atol=0)
    np.testing.assert_allclose(specific_force, [-49.0 * r, 0.0, 0.0], rtol=1e-14, atol=1e-15)


def test_the_heavy_tops_imu_reads_the_pivot_kinematics_of_a_finite_difference():
    # Independent check of the pivot system's accelerations: the COM velocity and the
    # angular velocity differenced over +-h around a state (central, error O(h^2)).
    scene = load_scene('heavy_top')
    simulator = scene.simulator(tolerance=0.0)
    simulator.substeps = 1
    h = 1e-5
    for _ in range(30):
        simulator.step(scene.dt)
    states = []
    for _ in range(3):
        states.append(simulator.state)
        simulator.step(h)
    before, middle, after = states
    body = scene.body
    acceleration, alpha = accelerations(
        body, middle, body.mass * scene.gravity, np.zeros(3),
        -np.asarray(scene.pivot.point, dtype=float))
    difference_a = (after.velocity(body) - before.velocity(body)) / (2 * h)
    difference_alpha = (after.angular_velocity(body) - before.angular_velocity(body)) / (2 * h)
    # omega ~ 150 rad/s: the central difference's error ~ h^2 |d^3 v| ~ 1e-10 omega^3 r;
    # the Buss step's own error over h ~ (omega h)^3 / 12 relative: both below 1e-5 relative.
    scale_a = np.linalg.norm(acceleration)
    np.testing.assert_allclose(difference_a, acceleration, rtol=0, atol=1e-5 * scale_a)
    np.testing.assert_allclose(difference_alpha, alpha, rtol=0,
                               atol=1e-5 * np.linalg.norm(alpha))


def test_noise_off_reads_the_truth_exactly_and_noise_on_follows_its_seed():
    scene = load_scene('thrown_box')
    quiet = scene.imu_sensor(ImuModel())
    noisy = [scene.imu_sensor(ImuModel(gyro_noise_density=1e-3, accel_random_walk=1e-2,
                                       accel_bias_sigma=0.1, seed=11)) for _ in range(2)]
    state = scene.state
    force = scene.body.mass * scene.gravity
    for _ in range(20):
        quiet.advance(0.01)
        truth = quiet.truth(state, force, np.zeros(3))
        assert all(np.array_equal(a, b) for a, b in zip(
            quiet.reading(state, force, np.zeros(3)), truth))
        readings = []
        for imu in noisy:
            imu.advance(0.01)
            readings.append(imu.reading(state, force, np.zeros(3)))
        assert all(np.array_equal(a, b) for a, b in zip(*readings))
        assert not np.array_equal(readings[0][1], truth[1])


def test_the_compiled_reading_equals_the_numpy_reference_to_round_off():
    scene = load_scene('heavy_top')
    simulator = scene.simulator()
    for _ in range(40):
        simulator.step(scene.dt)
    state, body = simulator.state, scene.body
    model = ImuModel(position=(0.01, -0.02, 0.03),
                     orientation=(0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)))
    force, torque = body.mass * scene.gravity, np.array([0.01, 0.0, -0.02])
    orientation, omega, specific_force = scene.imu_sensor(model).truth(state, force, torque)
    acceleration, alpha = accelerations(body, state, force, torque,
                                        -np.asarray(scene.pivot.point, dtype=float))
    expected = specific_force_body(acceleration, state.rotation.T @ alpha,
                                   state.angular_velocity_body(body), state.quaternion,
                                   model.position, scene.gravity)
    mount = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # IMU to body
    scale = np.linalg.norm(expected)
    np.testing.assert_allclose(specific_force, mount.T @ expected, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(omega, mount.T @ state.angular_velocity_body(body), rtol=0,
                               atol=1e-13 * 150.0)
    assert np.linalg.norm(orientation) == pytest.approx(1.0, abs=1e-15)

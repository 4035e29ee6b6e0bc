"""Tests of the IMU core: the specific force at the mount point and Kalibr's noise model."""

import numpy as np

from rigid_body_sim.physics.imu import KalibrNoise
from rigid_body_sim.physics.imu import specific_force_body

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

"""
What a body-mounted IMU measures: kinematics at the mount point and Kalibr's noise model.

An IMU fixed in the body at r (from the COM, body frame) with orientation q_bi (IMU to
body) reads, in its own frame:

- the angular velocity omega (a gyro sees the body's rotation wherever it sits);
- the specific force a_point - g, with a_point = a_COM + alpha x r + omega x (omega x r):
  0 in free fall, g up at rest, omega^2 r toward the axis on a spinning body.

a_COM and alpha are the instantaneous accelerations of the simulated motion: from the total
wrench of the held inputs and the effects (gravity, drag, ...) by Newton and Euler, and for
a body on a pivot from the pivot system (Euler's equation about the fixed point with the
parallel-axis inertia, then a_COM = alpha x r_c + omega x (omega x r_c)), so the pivot's
reaction, which is never computed, is in it all the same.  Not in it: the internal torque
of the `dissipation` effect, which changes omega at constant L through the integrator only
(its alpha is of the order of damping x omega^2).

Noise (off by default): :class:`KalibrNoise` per sensor, the white noise and bias random
walk of Kalibr's IMU model (units as Kalibr defines them), a turn-on bias, a seed.
Core only: numpy, no ROS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from .body import RigidBody
from .kernels import kernel
from .kernels.algebra import cross
from .kernels.algebra import quaternion_product
from .kernels.algebra import rotate
from .kernels.algebra import rotate_back
from .kernels.layout import inverse_inertia_times
from .state import State


class KalibrNoise:
    """
    White noise plus a random-walk bias on a 3-axis signal, discretised as Kalibr does.

    Per sample of period dt: sigma_d = sigma / sqrt(dt) for the white noise, and the bias
    steps by N(0, (sigma_b sqrt(dt))^2).  Units (Kalibr): noise density in unit/sqrt(Hz),
    bias random walk in unit/s/sqrt(Hz), turn-on bias sigma in unit.  A numpy Generator
    seeded with `seed` makes the sequence reproducible.
    """

    def __init__(self, noise_density: float, random_walk: float,
                 turn_on_bias_sigma: float = 0.0,
                 seed: int | np.random.SeedSequence = 0) -> None:
        """Draw the turn-on bias from N(0, turn_on_bias_sigma^2) per axis."""
        self.noise_density = float(noise_density)
        self.random_walk = float(random_walk)
        self._rng = np.random.default_rng(seed)
        self.bias = self._rng.normal(0.0, float(turn_on_bias_sigma), 3)

    def error(self, dt: float) -> NDArray[np.float64]:
        """Advance by one sample of period dt s; return its error: bias plus white noise."""
        self.bias = self.bias + self._rng.normal(0.0, self.random_walk * np.sqrt(dt), 3)
        return self.bias + self._rng.normal(0.0, self.noise_density / np.sqrt(dt), 3)

    def corrupt(self, truth: ArrayLike, dt: float) -> NDArray[np.float64]:
        """Return `truth` (shape (3,)) plus bias and white noise for a sample of period dt."""
        return np.asarray(truth, dtype=float) + self.error(dt)

    def white_variance(self, dt: float) -> float:
        """Return the white noise's variance per sample of period dt: (sigma / sqrt(dt))^2."""
        return self.noise_density ** 2 / dt


@dataclass(frozen=True)
class ImuModel:
    """
    Where an IMU sits on the body and how noisy it is (a scene's ``imu:`` section).

    position : (3,) m from the COM, body frame.  orientation : unit quaternion (x, y, z, w),
    IMU frame to body frame.  gyro_* in rad/s/sqrt(Hz) (noise density), rad/s^2/sqrt(Hz)
    (random walk), rad/s (turn-on bias sigma); accel_* in m/s^2/sqrt(Hz), m/s^3/sqrt(Hz),
    m/s^2.  seed : int, the noise sequence's (the same seed, the same sequence).
    """

    position: tuple = (0.0, 0.0, 0.0)
    orientation: tuple = (0.0, 0.0, 0.0, 1.0)
    gyro_noise_density: float = 0.0
    gyro_random_walk: float = 0.0
    gyro_bias_sigma: float = 0.0
    accel_noise_density: float = 0.0
    accel_random_walk: float = 0.0
    accel_bias_sigma: float = 0.0
    seed: int = 0

    NOISE_KEYS = ('gyro_noise_density', 'gyro_random_walk', 'gyro_bias_sigma',
                  'accel_noise_density', 'accel_random_walk', 'accel_bias_sigma')

    @property
    def noisy(self) -> bool:
        """Return True if any noise term is not zero."""
        return any(getattr(self, key) != 0.0 for key in self.NOISE_KEYS)


class Imu:
    """
    A simulated IMU on a body: truth at its mount, plus noise advanced once per sample.

    Parameters
    ----------
    model : ImuModel
    body : RigidBody
    gravity : array_like, shape (3,)
        The gravitational field, m/s^2, world frame (zeros without gravity).
    pivot_offset : array_like, shape (3,), optional
        The COM's offset from a pivot, body frame, m (the accelerations are then those of
        the pivot system: see the module docstring).

    """

    def __init__(self, model: ImuModel, body: RigidBody, gravity: ArrayLike = (0.0, 0.0, 0.0),
                 pivot_offset: ArrayLike | None = None) -> None:
        self.model = model
        self._body = body
        self._gravity = np.asarray(gravity, dtype=float)
        self._pivot_offset = None if pivot_offset is None else np.asarray(pivot_offset, float)
        self._position = np.asarray(model.position, dtype=float)
        # IMU to body, a unit quaternion.
        self._orientation = np.asarray(model.orientation, dtype=float)
        self._orientation = self._orientation / np.linalg.norm(self._orientation)
        seeds = np.random.SeedSequence(model.seed).spawn(2)
        self.gyro_noise = KalibrNoise(model.gyro_noise_density, model.gyro_random_walk,
                                      model.gyro_bias_sigma, seeds[0])
        self.accel_noise = KalibrNoise(model.accel_noise_density, model.accel_random_walk,
                                       model.accel_bias_sigma, seeds[1])
        self._gyro_error = np.zeros(3)
        self._accel_error = np.zeros(3)
        inverse = body.inertia_inverse
        if self._pivot_offset is None:
            pivot_inverse, offset, pivoted = inverse, np.zeros(3), 0.0
        else:
            offset = self._pivot_offset
            pivot_inverse = np.linalg.inv(body.inertia + body.mass * (  # type: ignore[assignment]
                offset @ offset * np.eye(3) - np.outer(offset, offset)))
            pivoted = 1.0
        # Packed for the compiled kernel: I^-1, I_pivot^-1 (body), m, pivoted, d, r, q_bi
        # (IMU to body), g.
        self._constants = np.concatenate([
            np.asarray(inverse).reshape(-1), pivot_inverse.reshape(-1),
            [body.mass, pivoted], offset, self._position, self._orientation, self._gravity])

    def advance(self, dt: float) -> None:
        """Draw the noise of the next sample, dt s after the last (once per sample)."""
        if self.model.noisy:
            self._gyro_error = self.gyro_noise.error(dt)
            self._accel_error = self.accel_noise.error(dt)

    def truth(self, state: State, force: ArrayLike,
              torque: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                          NDArray[np.float64]]:
        """
        Return (orientation, angular_velocity, specific_force) without noise.

        orientation: the IMU frame in the world, quaternion (x, y, z, w); angular velocity
        (rad/s) and specific force (m/s^2) in the IMU frame, in one compiled call (simulate
        computes it every tick); test/imu_reference.py writes the same kinematics in numpy.
        """
        values = _imu_truth(state.quaternion, state.angular_momentum, state.linear_momentum,
                            np.asarray(force, dtype=float), np.asarray(torque, dtype=float),
                            self._constants)
        return values[0:4], values[4:7], values[7:10]

    def reading(self, state: State, force: ArrayLike,
                torque: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                            NDArray[np.float64]]:
        """Return (orientation, angular_velocity, specific_force) with this sample's noise."""
        orientation, omega, specific_force = self.truth(state, force, torque)
        return orientation, omega + self._gyro_error, specific_force + self._accel_error


@kernel
def _imu_truth(quaternion: NDArray[np.float64], angular_momentum: NDArray[np.float64],
               linear_momentum: NDArray[np.float64], force: NDArray[np.float64],
               torque: NDArray[np.float64], constants: NDArray[np.float64]
               ) -> NDArray[np.float64]:
    """Compiled :meth:`Imu.truth`: [q_world_imu (4), omega_imu (3), specific force (3)]."""
    q = (quaternion[0], quaternion[1], quaternion[2], quaternion[3])
    inverse, pivot_inverse = constants[0:9], constants[9:18]
    mass, pivoted = constants[18], constants[19]
    offset = (constants[20], constants[21], constants[22])
    position = (constants[23], constants[24], constants[25])
    mount = (constants[26], constants[27], constants[28], constants[29])
    gravity = (constants[30], constants[31], constants[32])
    momentum = (angular_momentum[0], angular_momentum[1], angular_momentum[2])
    applied_force = (force[0], force[1], force[2])
    applied_torque = (torque[0], torque[1], torque[2])
    # Omega = I^-1 R^T L (body), omega = R Omega.
    omega_body = inverse_inertia_times(inverse, rotate_back(q, momentum))
    omega = rotate(q, omega_body)
    if pivoted == 0.0:
        # alpha = R I^-1 R^T (tau - omega x L), a = F / m.
        gyroscopic = cross(omega, momentum)
        alpha_body = inverse_inertia_times(inverse, rotate_back(q, (
            applied_torque[0] - gyroscopic[0], applied_torque[1] - gyroscopic[1],
            applied_torque[2] - gyroscopic[2])))
        acceleration = (applied_force[0] / mass, applied_force[1] / mass,
                        applied_force[2] / mass)
    else:
        # About the pivot: tau_p = tau + r x F, L_p = L + r x p; the COM on its sphere.
        r = rotate(q, offset)
        lever = cross(r, (linear_momentum[0], linear_momentum[1], linear_momentum[2]))
        momentum_pivot = (momentum[0] + lever[0], momentum[1] + lever[1],
                          momentum[2] + lever[2])
        moment = cross(r, applied_force)
        gyroscopic = cross(omega, momentum_pivot)
        alpha_body = inverse_inertia_times(pivot_inverse, rotate_back(q, (
            applied_torque[0] + moment[0] - gyroscopic[0],
            applied_torque[1] + moment[1] - gyroscopic[1],
            applied_torque[2] + moment[2] - gyroscopic[2])))
        alpha = rotate(q, alpha_body)
        tangential, centripetal = cross(alpha, r), cross(omega, cross(omega, r))
        acceleration = (tangential[0] + centripetal[0], tangential[1] + centripetal[1],
                        tangential[2] + centripetal[2])
    translational = rotate_back(q, (acceleration[0] - gravity[0], acceleration[1] - gravity[1],
                                    acceleration[2] - gravity[2]))
    tangential = cross(alpha_body, position)
    centripetal = cross(omega_body, cross(omega_body, position))
    specific_force = (translational[0] + tangential[0] + centripetal[0],
                      translational[1] + tangential[1] + centripetal[1],
                      translational[2] + tangential[2] + centripetal[2])
    out = np.empty(10)
    out[0], out[1], out[2], out[3] = quaternion_product(q, mount)
    # IMU frame = mount^T body frame.
    out[4], out[5], out[6] = rotate_back(mount, omega_body)
    out[7], out[8], out[9] = rotate_back(mount, specific_force)
    return out

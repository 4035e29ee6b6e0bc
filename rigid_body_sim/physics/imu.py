"""
What a body-mounted IMU measures: kinematics at the mount point and Kalibr's noise model.

Core only (numpy, no ROS).  Not yet wired to the simulator or the node (issue 13, part 2):
the caller supplies the COM acceleration and angular acceleration the effects produce.
"""

import numpy as np

from .rotations import matrix_from_quaternion


def specific_force_body(acceleration_com_world, angular_acceleration_body,
                        angular_velocity_body, orientation, mount_position_body, gravity_world):
    """
    Return the specific force (m/s^2) at the mount point, in the body frame.

    a_point = a_COM + alpha x r + omega x (omega x r) (rigid-body kinematics, r fixed in
    the body, every vector in the body frame), and an accelerometer reads a_point - g.

    Parameters
    ----------
    acceleration_com_world : array_like, shape (3,)
        COM acceleration in the world frame, m/s^2.
    angular_acceleration_body, angular_velocity_body : array_like, shape (3,)
        Body frame, rad/s^2 and rad/s.
    orientation : array_like, shape (4,)
        Quaternion (x, y, z, w), body to world.
    mount_position_body : array_like, shape (3,)
        Mount point from the COM, body frame, m.
    gravity_world : array_like, shape (3,)
        World frame, m/s^2 (e.g. (0, 0, -9.81)).

    """
    rotation = matrix_from_quaternion(np.asarray(orientation, dtype=float))
    r = np.asarray(mount_position_body, dtype=float)
    omega = np.asarray(angular_velocity_body, dtype=float)
    alpha = np.asarray(angular_acceleration_body, dtype=float)
    # R^T (a_COM - g): the translational part seen in the body frame.
    translational = rotation.T @ (np.asarray(acceleration_com_world, dtype=float)
                                  - np.asarray(gravity_world, dtype=float))
    return translational + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))


class KalibrNoise:
    """
    White noise plus a random-walk bias on a 3-axis signal, discretised as Kalibr does.

    Per sample of period dt: sigma_d = sigma / sqrt(dt) for the white noise, and the bias
    steps by N(0, (sigma_b sqrt(dt))^2).  Units (Kalibr): noise density in unit/sqrt(Hz),
    bias random walk in unit/s/sqrt(Hz), turn-on bias sigma in unit.  A numpy Generator
    seeded with `seed` makes the sequence reproducible.
    """

    def __init__(self, noise_density, random_walk, turn_on_bias_sigma=0.0, seed=0):
        """Draw the turn-on bias from N(0, turn_on_bias_sigma^2) per axis."""
        self.noise_density = float(noise_density)
        self.random_walk = float(random_walk)
        self._rng = np.random.default_rng(seed)
        self.bias = self._rng.normal(0.0, float(turn_on_bias_sigma), 3)

    def corrupt(self, truth, dt):
        """Return `truth` (shape (3,)) plus bias and white noise for a sample of period dt."""
        self.bias = self.bias + self._rng.normal(0.0, self.random_walk * np.sqrt(dt), 3)
        white = self._rng.normal(0.0, self.noise_density / np.sqrt(dt), 3)
        return np.asarray(truth, dtype=float) + self.bias + white

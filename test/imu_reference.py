"""
The IMU's kinematics in numpy, the reference physics/imu.py's compiled reading is held to.

Written from the rigid-body kinematics, calling no kernel (the package's RigidBody and State
read as data): the instantaneous accelerations of a free body (Newton and Euler) or of a body
on a pivot (Euler about the fixed point, the parallel-axis inertia), and the specific force an
accelerometer at a body point reads.  World frame unless a name says body; SI units.
"""

from method_reference import rotation_of_quaternion
import numpy as np

__all__ = ['accelerations', 'specific_force_body']


def specific_force_body(acceleration_com_world, angular_acceleration_body,
                        angular_velocity_body, orientation, mount_position_body, gravity_world):
    """
    Return the specific force (m/s^2) at the mount point, in the body frame.

    a_point = a_COM + alpha x r + omega x (omega x r) (rigid-body kinematics, r fixed in the
    body, every vector in the body frame), and an accelerometer reads a_point - g.
    orientation: the quaternion (x, y, z, w), body to world; mount_position_body: r, m.
    """
    rotation = rotation_of_quaternion(orientation)
    r = np.asarray(mount_position_body, dtype=float)
    omega = np.asarray(angular_velocity_body, dtype=float)
    alpha = np.asarray(angular_acceleration_body, dtype=float)
    # R^T (a_COM - g): the translational part seen in the body frame.
    translational = rotation.T @ (np.asarray(acceleration_com_world, dtype=float)
                                  - np.asarray(gravity_world, dtype=float))
    return translational + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))


def accelerations(body, state, force, torque, pivot_offset=None):
    """
    Return (a_COM, alpha): the instantaneous COM and angular accelerations, world frame.

    Free body: a = F / m; dL/dt = tau with L = I_w omega gives
    alpha = I_w^{-1} (tau - omega x L).  On a pivot, the same about the fixed point:
    tau_p = tau + r_c x F, L_p = L + r_c x p, I_p the parallel-axis inertia, and the COM
    moves on a sphere about it: a = alpha x r_c + omega x (omega x r_c).  force, torque: the
    total applied force through the COM (N) and torque about it (N m), a constraint's
    reaction excluded; pivot_offset: the COM's offset from the pivot, body frame (m).
    """
    rotation = rotation_of_quaternion(state.quaternion)
    inertia = np.array(body.inertia, dtype=float)
    momentum = np.array(state.angular_momentum, dtype=float)
    omega = rotation @ np.linalg.solve(inertia, rotation.T @ momentum)
    force = np.asarray(force, dtype=float)
    torque = np.asarray(torque, dtype=float)
    if pivot_offset is None:
        inertia_world = rotation @ inertia @ rotation.T
        alpha = np.linalg.solve(inertia_world, torque - np.cross(omega, momentum))
        return force / body.mass, alpha
    offset = np.asarray(pivot_offset, dtype=float)
    r = rotation @ offset
    pivot_inertia = inertia + body.mass * (offset @ offset * np.eye(3) - np.outer(offset, offset))
    inertia_world = rotation @ pivot_inertia @ rotation.T
    momentum_pivot = momentum + np.cross(r, np.asarray(state.linear_momentum, dtype=float))
    alpha = np.linalg.solve(inertia_world, torque + np.cross(r, force)
                            - np.cross(omega, momentum_pivot))
    return np.cross(alpha, r) + np.cross(omega, np.cross(omega, r)), alpha

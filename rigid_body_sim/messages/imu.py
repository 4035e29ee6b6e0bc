"""
The ``imu`` topic's sensor_msgs/Imu: made once with its covariances, filled each tick.

The node and ``simulate`` publish the scene's IMU (:class:`rigid_body_sim.physics.imu.Imu`)
through these two functions, so a bag written offline holds the node's messages.  Frames
and units: the IMU's frame, SI.
"""

from sensor_msgs.msg import Imu

__all__ = ['fill_imu_message', 'imu_message']


def imu_message(frame_id, imu, dt):
    """
    Return a sensor_msgs/Imu to fill each tick: frame id and covariances set.

    The covariances follow the IMU's noise for samples dt s apart: the diagonal of the
    angular velocity and linear acceleration holds the white noise's variance per sample,
    (density / sqrt(dt))^2, plus the turn-on bias's sigma^2 (the bias walk's growth over
    the run is left out).  Without noise they stay zeros, which sensor_msgs reads as
    "unknown"; so does the orientation's, which is the simulation's truth.
    """
    message = Imu()
    message.header.frame_id = frame_id
    if imu.model.noisy:
        model = imu.model
        for field, noise, bias_sigma in (
                ('angular_velocity_covariance', imu.gyro_noise, model.gyro_bias_sigma),
                ('linear_acceleration_covariance', imu.accel_noise, model.accel_bias_sigma)):
            variance = noise.white_variance(dt) + bias_sigma ** 2
            setattr(message, field, [variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0, 0.0,
                                     variance])
    return message


def fill_imu_message(message, stamp_nanoseconds, orientation, angular_velocity,
                     linear_acceleration):
    """Set a sensor_msgs/Imu's stamp (ns) and reading (IMU frame; SI); return it."""
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(
        int(stamp_nanoseconds), 1_000_000_000)
    quaternion = message.orientation
    quaternion.x, quaternion.y, quaternion.z, quaternion.w = (float(v) for v in orientation)
    vector = message.angular_velocity
    vector.x, vector.y, vector.z = (float(v) for v in angular_velocity)
    vector = message.linear_acceleration
    vector.x, vector.y, vector.z = (float(v) for v in linear_acceleration)
    return message

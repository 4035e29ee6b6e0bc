"""
The node's simulated IMU over DDS.

Published only to subscribers, in its frame, the truth without noise, the covariances of
its noise with noise.

The physics of the reading (free fall, hanging, spinning, the pivot's kinematics, the
Allan deviation of the noise) is tested on the core in test_imu.py.
"""

import math

from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import unique_namespace
import numpy as np
import pytest
from rigid_body_sim.messages.qos import STATE_QOS
from rigid_body_sim.scenes import load_scene
from sensor_msgs.msg import Imu

IMU_TOPIC = {'imu': (Imu, STATE_QOS)}


@pytest.fixture(autouse=True, scope='module')
def ros_environment():
    """Give this test process a ROS domain of its own."""
    isolate_ros_environment()


def _stamp(message):
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def _run(tmp_path, parameters, count=50):
    node = NodeProcess(tmp_path / 'node.log', namespace=unique_namespace(),
                       parameters=parameters)
    client = Client(node.namespace, extra_topics=IMU_TOPIC)
    try:
        client.wait_until_connected(inputs=False)
        client.wait_for_messages('imu', count)
        client.wait_for_messages('pose', count)
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    return client, node


def test_a_noiseless_imu_at_the_com_reads_the_bodys_rotation_and_no_force(tmp_path):
    """The default scene: torque-free, no gravity; the IMU at the COM, aligned with the body."""
    client, _ = _run(tmp_path, {'publish_clock': 'true'})
    poses = {_stamp(m): m.pose.orientation for m in client.messages('pose')}
    scene = load_scene('default')
    # Torque-free: |omega|-weighted L fixed; here the reading's own consistency: the
    # angular velocity's body-frame L = I Omega has the magnitude of the initial |L|.
    momentum = np.linalg.norm(scene.state.angular_momentum)
    matched = 0
    for message in client.messages('imu'):
        assert message.header.frame_id == client.frame('imu')
        acceleration = message.linear_acceleration
        assert (acceleration.x, acceleration.y, acceleration.z) == (0.0, 0.0, 0.0)
        omega = np.array([message.angular_velocity.x, message.angular_velocity.y,
                          message.angular_velocity.z])
        assert np.linalg.norm(scene.body.inertia @ omega) == pytest.approx(momentum, rel=1e-9)
        pose = poses.get(_stamp(message))
        if pose is not None:
            matched += 1
            q = message.orientation
            assert (q.x, q.y, q.z, q.w) == (pose.x, pose.y, pose.z, pose.w)
        assert not any(message.angular_velocity_covariance)  # noise off: "unknown"
    assert matched >= 10


def test_a_hanging_imu_with_noise_reads_g_up_with_its_covariances(tmp_path):
    """heavy_top's pivot, no spin, hanging: the IMU reads +g along the body z, noisily."""
    density = 0.02  # m/s^2/sqrt(Hz)
    client, node = _run(tmp_path, {
        'scene': 'heavy_top', 'initial.orientation': '[1.0, 0.0, 0.0, 0.0]',
        'initial.angular_velocity_body': '[0.0, 0.0, 0.0]',
        'imu.accel_noise_density': str(density), 'imu.seed': '5', 'imu_frame': 'top_imu'},
        count=200)
    rate = load_scene('heavy_top').rate
    messages = client.messages('imu')
    readings = np.array([[m.linear_acceleration.x, m.linear_acceleration.y,
                          m.linear_acceleration.z] for m in messages])
    # Upside down (180 deg about x) below its pivot: the body z points down, so +g up
    # reads -9.81 along body z.  White noise sigma = density sqrt(rate) per sample.
    sigma = density * math.sqrt(rate)
    assert abs(readings[:, 2].mean() + 9.81) < 5 * sigma / math.sqrt(len(readings))
    assert np.std(readings[:, 0]) == pytest.approx(sigma, rel=0.25)
    assert messages[0].header.frame_id == client.frame('top_imu')
    covariance = messages[0].linear_acceleration_covariance
    assert covariance[0] == covariance[4] == covariance[8] == pytest.approx(sigma ** 2)
    assert not any(messages[0].angular_velocity_covariance)  # the gyro has no noise
    assert f"imu in frame '{client.frame('top_imu')}' (noise seed 5)" in node.output()

"""
The node's and simulate's serialised messages pad with zeros: the same state, the same bytes.

rclpy's serializer skips CDR's alignment padding without writing it, so those bytes held
whatever its buffer held.  The oracle here is rosbags' serializer, which writes zeros
there: a message's bytes must equal its own re-serialisation by rosbags.  Frame names of
every length modulo 8 move the padding about.
"""

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from diagnostic_msgs.msg import KeyValue
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from rigid_body_sim.messages.cdr import serialize_zeroed
from rigid_body_sim.messages.imu import fill_imu_message
from rigid_body_sim.messages.imu import imu_message
from rigid_body_sim.messages.state import STATE_TYPES
from rigid_body_sim.messages.state import StateSerializer
from rigid_body_sim.messages.tf import static_transforms
from rigid_body_sim.messages.tf import transform_message_class
from rigid_body_sim.messages.tf import TransformSerializer
from rigid_body_sim.physics import State
from rigid_body_sim.recording.bag_writer import typestore
from rigid_body_sim.scenes import load_scene

FRAMES = ['w', 'wo', 'wor', 'worl', 'world', 'world_', 'world_f', 'world_fr']


def _type_name(message_class):
    return f"{message_class.__module__.split('.')[0]}/msg/{message_class.__name__}"


def _padding_is_zero(data, message_class):
    """Return True if rosbags, which pads with zeros, serialises the message to `data`."""
    store = typestore()
    name = _type_name(message_class)
    return bytes(store.serialize_cdr(store.deserialize_cdr(bytes(data), name), name)) == \
        bytes(data)


def _diagnostics(frame):
    values = [KeyValue(key=frame * k, value='v' * (7 - k)) for k in range(4)]
    return DiagnosticArray(status=[
        DiagnosticStatus(level=bytes([k]), name=frame[:k + 1], message='é' * k,
                         hardware_id='/' + frame, values=values[:k]) for k in range(3)])


@pytest.mark.parametrize('frame', FRAMES)
def test_serialize_zeroed_is_rclpys_bytes_with_zero_padding(frame):
    """The bytes deserialise to the message (rclpy) and pad with zeros (rosbags)."""
    scene = load_scene('default')
    messages = [_diagnostics(frame), fill_imu_message(imu_message(frame, scene.imu_sensor(),
                                                                  0.01),
                                                      123_456_789_012, (0.1, 0.2, 0.3, 0.9),
                                                      (1.0, 2.0, 3.0), (4.0, 5.0, 6.0))]
    message_class, _ = transform_message_class()
    messages.append(static_transforms(message_class, frame, frame + '_imu', scene.imu,
                                      5_000_000_001))
    for message in messages:
        data = serialize_zeroed(message)
        assert deserialize_message(data, type(message)) == message
        assert _padding_is_zero(data, type(message)), type(message).__name__


@pytest.mark.parametrize('frame', FRAMES)
def test_the_nodes_state_and_tf_serializers_pad_with_zeros(frame):
    """The node's serializers of its state topics (StateSerializer) and /tf pad with zeros."""
    scene = load_scene('tennis_racket')
    rng = np.random.default_rng(len(frame))
    quaternion = rng.normal(size=4)
    state = State(quaternion / np.linalg.norm(quaternion), position=rng.normal(size=3),
                  linear_momentum=rng.normal(size=3), angular_momentum=rng.normal(size=3))
    serializer = StateSerializer(scene.body, frame, frame + '_body')
    for topic, data in serializer.serialize(state, 1_234_567_890_123).items():
        assert _padding_is_zero(data, STATE_TYPES[topic]), topic
    message_class, _ = transform_message_class()
    transforms = TransformSerializer(message_class, frame, frame[:-1] + 'b')
    data = transforms.serialize(42_000_000_007, (1.0, 2.0, 3.0, 0.0, 0.0, 0.6, 0.8))
    assert _padding_is_zero(data, message_class)

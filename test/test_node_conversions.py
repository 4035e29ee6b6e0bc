"""
The node's pure conversions: state -> messages, serialised messages, inputs -> wrench.

No DDS here: these are the functions the node and an offline bag writer share.
"""

import math

from geometry_msgs.msg import Vector3Stamped
from geometry_msgs.msg import WrenchStamped
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from rclpy.serialization import serialize_message
from rigid_body_sim.messages.marker import inertia_equivalent_box
from rigid_body_sim.messages.marker import marker_geometry
from rigid_body_sim.messages.marker import marker_geometry_from_drawing
from rigid_body_sim.messages.marker import MarkerGeometry
from rigid_body_sim.messages.state import state_messages
from rigid_body_sim.messages.state import STATE_TOPICS
from rigid_body_sim.messages.state import StateSerializer
from rigid_body_sim.messages.wrench import RejectedInput
from rigid_body_sim.messages.wrench import wrench_input_from_message
from rigid_body_sim.physics import matrix_from_quaternion
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import State
from rigid_body_sim.scenes import Drawing
from rigid_body_sim.scenes import load_scene
from visualization_msgs.msg import Marker


def random_rotation(rng):
    """Return a uniformly random unit quaternion (x, y, z, w)."""
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def random_body(rng):
    """Return a body with a random, non-diagonal inertia tensor (a real one)."""
    moments = rng.uniform(1.0, 2.0, size=3)  # any three in [1, 2] satisfy I1 + I2 >= I3
    axes = matrix_from_quaternion(random_rotation(rng))
    return RigidBody(rng.uniform(0.5, 5.0), axes @ np.diag(moments) @ axes.T)


def random_state(rng):
    """Return a random state (world frame)."""
    return State(random_rotation(rng), rng.normal(size=3), rng.normal(size=3),
                 rng.normal(size=3))


def box_moments(mass, edges):
    """Return the principal moments of a solid box: m/12 (b^2 + c^2, ...)."""
    a, b, c = np.square(edges)
    return mass / 12.0 * np.array([b + c, a + c, a + b])


def test_inertia_equivalent_box_has_the_bodys_principal_moments():
    """Edges a_i = sqrt(6 (I_j + I_k - I_i) / m) give back I1, I2, I3."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        body = random_body(rng)
        edges, axes = inertia_equivalent_box(body)
        np.testing.assert_allclose(box_moments(body.mass, edges), body.principal_moments,
                                   rtol=1e-12)
        np.testing.assert_allclose(axes, body.principal_axes)


def test_marker_of_a_lamina_keeps_a_visible_thickness():
    """The default T-handle (I1 + I2 = I3) has a zero edge; the marker is drawn thin."""
    geometry = marker_geometry(RigidBody(1.0, [1.0, 2.0, 3.0]))
    assert geometry.marker_type == Marker.CUBE
    longest = max(geometry.scale)
    assert min(geometry.scale) == pytest.approx(0.02 * longest)
    assert geometry.axes is None  # diagonal inertia: the box is aligned with the body


@pytest.mark.parametrize('shape, size, marker_type, scale', [
    ('box', [1.0, 2.0, 3.0], Marker.CUBE, (1.0, 2.0, 3.0)),
    ('cylinder', [0.5, 2.0], Marker.CYLINDER, (1.0, 1.0, 2.0)),
    ('sphere', [0.5], Marker.SPHERE, (1.0, 1.0, 1.0)),
    ('ellipsoid', [1.0, 2.0, 3.0], Marker.SPHERE, (2.0, 4.0, 6.0)),
])
def test_marker_of_a_shape_is_that_shape(shape, size, marker_type, scale):
    """Shapes are drawn as themselves, full extents along the body axes."""
    geometry = marker_geometry(RigidBody(1.0, [1.0, 1.0, 1.0]), shape, size)
    assert geometry == MarkerGeometry(marker_type, scale, None, None)  # body axes, default colour


def test_marker_of_a_shape_needs_its_number_of_sizes():
    """A cylinder needs radius and height; the error says so."""
    with pytest.raises(ValueError, match='a cylinder needs 2 size value'):
        marker_geometry(RigidBody(1.0, [1.0, 1.0, 1.0]), 'cylinder', [1.0])


def test_state_messages_carry_the_state_in_their_frames():
    """Pose and L in the world frame, twist world, odom twist in the body frame."""
    rng = np.random.default_rng(5)
    body = random_body(rng)
    state = random_state(rng)
    messages = state_messages(body, state, 1_234_567_890_123, 'map', 'base')
    assert sorted(messages) == sorted(STATE_TOPICS)
    rotation = state.rotation

    pose = messages['pose']
    assert pose.header.frame_id == 'map'
    assert (pose.header.stamp.sec, pose.header.stamp.nanosec) == (1234, 567_890_123)
    position = pose.pose.position
    np.testing.assert_array_equal([position.x, position.y, position.z], state.position)
    q = pose.pose.orientation
    np.testing.assert_array_equal([q.x, q.y, q.z, q.w], state.quaternion)

    twist = messages['twist']
    velocity = state.linear_momentum / body.mass
    omega = state.angular_velocity(body)
    np.testing.assert_allclose([twist.linear.x, twist.linear.y, twist.linear.z], velocity,
                               rtol=1e-14)
    np.testing.assert_allclose([twist.angular.x, twist.angular.y, twist.angular.z], omega,
                               rtol=1e-12, atol=1e-14)

    momentum = messages['angular_momentum']
    assert momentum.header.frame_id == 'map'
    np.testing.assert_array_equal(
        [momentum.vector.x, momentum.vector.y, momentum.vector.z], state.angular_momentum)

    odom = messages['odom']
    assert (odom.header.frame_id, odom.child_frame_id) == ('map', 'base')
    assert odom.pose.pose == pose.pose
    linear = odom.twist.twist.linear
    angular = odom.twist.twist.angular
    np.testing.assert_allclose([linear.x, linear.y, linear.z], rotation.T @ velocity,
                               rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose([angular.x, angular.y, angular.z],
                               state.angular_velocity_body(body), rtol=1e-12, atol=1e-14)

    marker = messages['marker']
    assert marker.header.frame_id == 'map'
    assert marker.pose.position == pose.pose.position
    # The marker's box lies along the principal axes: R_marker = R P.
    m = marker.pose.orientation
    np.testing.assert_allclose(matrix_from_quaternion([m.x, m.y, m.z, m.w]),
                               rotation @ body.principal_axes, atol=1e-12)


def test_state_messages_refill_in_place():
    """Passing the earlier dict back reuses its messages and gives the new state."""
    rng = np.random.default_rng(7)
    body = random_body(rng)
    first = state_messages(body, random_state(rng), 1)
    pose = first['pose']
    state = random_state(rng)
    again = state_messages(body, state, 2, messages=first)
    assert again is first and again['pose'] is pose
    assert again['odom'].header.stamp.nanosec == 2
    assert again['pose'].pose.position.x == state.position[0]


@pytest.mark.parametrize('shape, size', [('', ()), ('box', [1.0, 0.5, 0.2]),
                                         ('cylinder', [0.3, 1.0])])
def test_serialized_messages_equal_state_messages(shape, size):
    """The node's fast serialiser publishes exactly what state_messages describes."""
    rng = np.random.default_rng(11)
    body = random_body(rng)
    geometry = marker_geometry(body, shape, size)
    serializer = StateSerializer(body, 'world', 'body', geometry)
    messages = None
    for _ in range(10):
        state = random_state(rng)
        stamp = int(rng.integers(0, 2**31)) * 1_000_000_000 + int(rng.integers(0, 10**9))
        messages = state_messages(body, state, stamp, 'world', 'body', geometry, messages)
        serialized = serializer.serialize(state, stamp)
        for topic in STATE_TOPICS:
            message = messages[topic]
            assert deserialize_message(serialized[topic], type(message)) == message, topic


@pytest.mark.parametrize('scene_name, marker_type', [
    ('driven', Marker.CUBE), ('heavy_top', Marker.CYLINDER), ('default', Marker.CUBE)])
def test_marker_of_a_scene_drawing_has_its_shape_size_and_colour(scene_name, marker_type):
    """The drawing's size is the marker's scale; its colour survives serialisation."""
    drawing = load_scene(scene_name).drawing
    geometry = marker_geometry_from_drawing(drawing)
    assert geometry.marker_type == marker_type
    assert geometry.scale == drawing.size
    assert geometry.axes is None
    np.testing.assert_allclose(geometry.color, drawing.color, rtol=0, atol=2.0 ** -24)
    body = load_scene(scene_name).body
    state = load_scene(scene_name).state
    marker = state_messages(body, state, 5, geometry=geometry)['marker']
    assert deserialize_message(serialize_message(marker), Marker) == marker
    serialized = StateSerializer(body, geometry=geometry).serialize(state, 5, ('marker',))
    assert deserialize_message(serialized['marker'], Marker) == marker


def test_marker_of_a_drawing_along_principal_axes_turns_with_them():
    """A box drawn from a non-diagonal inertia lies along the principal axes."""
    quaternion = (0.0, 0.0, math.sin(0.3), math.cos(0.3))
    drawing = Drawing('box', (1.0, 2.0, 3.0), orientation=quaternion)
    geometry = marker_geometry_from_drawing(drawing)
    assert geometry.axes == quaternion
    assert geometry.color == marker_geometry_from_drawing(Drawing('box', (1.0,) * 3)).color


def torque_message(vector, frame_id=''):
    """Return a Vector3Stamped torque message."""
    message = Vector3Stamped()
    message.header.frame_id = frame_id
    message.vector.x, message.vector.y, message.vector.z = vector
    return message


def wrench_message(force, torque, frame_id=''):
    """Return a WrenchStamped message."""
    message = WrenchStamped()
    message.header.frame_id = frame_id
    message.wrench.force.x, message.wrench.force.y, message.wrench.force.z = force
    message.wrench.torque.x, message.wrench.torque.y, message.wrench.torque.z = torque
    return message


@pytest.mark.parametrize('frame_id, frame', [('', 'world'), ('world', 'world'),
                                             ('body', 'body')])
def test_input_frame_follows_the_header(frame_id, frame):
    """Empty or world_frame: world-fixed; body_frame: body-fixed."""
    wrench = wrench_input_from_message(wrench_message((1.0, 2.0, 3.0), (4.0, 5.0, 6.0),
                                                      frame_id), 'world', 'body', 100.0)
    assert wrench.frame == frame
    np.testing.assert_array_equal(wrench.force, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(wrench.torque, [4.0, 5.0, 6.0])
    torque = wrench_input_from_message(torque_message((1.0, 0.0, 0.0), frame_id), 'world',
                                       'body', 100.0)
    assert torque.frame == frame
    np.testing.assert_array_equal(torque.force, 0.0)


@pytest.mark.parametrize('frame_id, frame', [
    ('', 'world'), ('sat1/odom', 'world'), ('/sat1/odom', 'world'),
    ('sat1/base_link', 'body'), ('/sat1/base_link', 'body'), ('base_link', None),
    ('odom', None), ('//sat1/base_link', None)])
def test_input_frames_are_read_as_tf2_reads_them(frame_id, frame):
    """The node's prefixed frames, with or without the leading '/' tf2 drops; no other."""
    message = torque_message((1.0, 0.0, 0.0), frame_id)
    if frame is None:
        with pytest.raises(RejectedInput, match="accepted frame ids: 'sat1/odom' or empty"):
            wrench_input_from_message(message, 'sat1/odom', 'sat1/base_link', 100.0)
    else:
        assert wrench_input_from_message(message, 'sat1/odom', 'sat1/base_link',
                                         100.0).frame == frame


@pytest.mark.parametrize('message, kind, words', [
    (torque_message((math.nan, 0.0, 0.0)), 'non-finite', 'non-finite torque'),
    (wrench_message((0.0, -math.inf, 0.0), (0.0, 0.0, 0.0)), 'non-finite', 'non-finite force'),
    (torque_message((0.0, 60.0, 80.0)), 'magnitude', 'torque magnitude 100 N m is above'),
    (wrench_message((0.0, 0.0, 101.0), (0.0, 0.0, 0.0)), 'magnitude', 'force magnitude 101 N'),
    (torque_message((1.0, 0.0, 0.0), 'map'), 'frame',
     "accepted frame ids: 'world' or empty (world-fixed), 'body' (body-fixed)"),
])
def test_bad_inputs_are_rejected_with_the_reason(message, kind, words):
    """Non-finite, above max_wrench (99.9 here) or in an unknown frame: refused."""
    with pytest.raises(RejectedInput, match=words.replace('(', r'\(').replace(')', r'\)')) \
            as caught:
        wrench_input_from_message(message, 'world', 'body', 99.9)
    assert caught.value.kind == kind


def test_a_rejected_frame_id_is_quoted_cut_and_escaped():
    """A 1 MB frame id, control characters in it: the reason stays one short line."""
    frame_id = '\x1b[2J' + 'x' * 1_000_000 + '\n'
    with pytest.raises(RejectedInput) as caught:
        wrench_input_from_message(torque_message((1.0, 0.0, 0.0), frame_id), 'world', 'body',
                                  99.9)
    reason = str(caught.value)
    assert len(reason) < 500, len(reason)
    assert reason.isprintable(), reason
    assert "unknown frame_id '\\x1b[2Jxxx" in reason
    assert '... (999805 more characters)' in reason


def test_input_at_max_wrench_is_accepted():
    """The limit itself is allowed (|torque| = 100 N m = max_wrench)."""
    wrench = wrench_input_from_message(torque_message((0.0, 60.0, 80.0)), 'world', 'body',
                                       100.0)
    assert np.linalg.norm(wrench.torque) == 100.0

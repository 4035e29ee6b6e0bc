"""
Pure conversions between ROS messages and the physics core's objects.

Outgoing: :func:`state_messages` turns a State of a RigidBody into every message the node
publishes, keyed by topic name.  The node and any offline writer (a bag of a simulated run)
call the same function, so a bag written offline holds exactly what the node publishes.

Incoming: :func:`wrench_input_from_message` turns a ``torque`` (Vector3Stamped) or
``wrench`` (WrenchStamped) message into a validated :class:`WrenchInput`, or raises
:class:`RejectedInput` saying why.

Frames (REP 103/105): ``world_frame`` is the inertial frame; ``body_frame`` is attached to
the body with its origin at the centre of mass (COM).  Units: SI.
"""

import collections
import math
import struct

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu
from visualization_msgs.msg import Marker

from ..physics.kernels.derived import derived_quantities
from ..physics.rotations import quaternion_from_matrix
from ..text import shortened

__all__ = [
    'STATE_TOPICS',
    'STATE_TYPES',
    'SHAPES',
    'MarkerGeometry',
    'WrenchInput',
    'RejectedInput',
    'frame_from_frame_id',
    'imu_message',
    'fill_imu_message',
    'inertia_equivalent_box',
    'marker_geometry',
    'marker_geometry_from_drawing',
    'state_messages',
    'StateSerializer',
    'wrench_input_from_message',
]

STATE_TOPICS = ('pose', 'twist', 'angular_momentum', 'odom', 'marker')
"""Topic names (relative) of the messages :func:`state_messages` returns, in that order."""

STATE_TYPES = {'pose': PoseStamped, 'twist': Twist, 'angular_momentum': Vector3Stamped,
               'odom': Odometry, 'marker': Marker}
"""Topic name (relative) -> message class of :func:`state_messages`, known without a scene."""

SHAPES = ('box', 'cylinder', 'sphere', 'ellipsoid')
"""Body shapes with a closed-form inertia and a matching RViz marker."""

_SIZE_COUNTS = {'box': 3, 'cylinder': 2, 'sphere': 1, 'ellipsoid': 3}
# An inertia-equivalent box thinner than this fraction of its longest edge is drawn this
# thick: a lamina (I1 + I2 = I3, such as the default T-handle I = (1, 2, 3)) has a zero edge,
# which RViz would not draw at all.
_MIN_EDGE_FRACTION = 0.02
# RGBA of the marker: an orange, visible on RViz's grey grid, nearly opaque.  The values are
# exact in float32 (ColorRGBA's type), so a message survives serialisation unchanged.
_MARKER_COLOR = (0.875, 0.4375, 0.125, 0.875)
_MARKER_NAMESPACE = 'rigid_body'

MarkerGeometry = collections.namedtuple('MarkerGeometry', 'marker_type scale axes color',
                                        defaults=(None,))
MarkerGeometry.__doc__ = """How the body is drawn: an RViz marker type, its extent and colour.

marker_type : int, a visualization_msgs/Marker type (CUBE, CYLINDER or SPHERE).
scale : tuple of 3 floats, the marker's full extent along its own x, y, z (m).
axes : quaternion (x, y, z, w) of the marker's axes in the body frame, or None when they
    are the body axes.
color : (r, g, b, a), each 0..1, or None (default) for the package's orange.
"""

WrenchInput = collections.namedtuple('WrenchInput', 'force torque frame')
WrenchInput.__doc__ = """A validated external wrench from a message.

force : ndarray (3,), through the COM, N.  torque : ndarray (3,), about the COM, N m.
frame : 'world' (fixed in the world frame) or 'body' (fixed in the body, turning with it),
    in the terms of :meth:`rigid_body_sim.physics.Simulator.set_wrench`.
"""


class RejectedInput(ValueError):
    """
    An input message the node refuses; the message says why.

    ``kind`` names the rule it broke: 'non-finite', 'magnitude' or 'frame'.
    """

    def __init__(self, message, kind):
        super().__init__(message)
        self.kind = kind


# -- outgoing: state -> messages


def inertia_equivalent_box(body):
    """
    Return the solid box with the body's mass and principal moments.

    For principal moments I1, I2, I3 and mass m, the box with edges
    a_i = sqrt(6 (I_j + I_k - I_i) / m) along principal axis i has the same moments, since a
    box's moment about axis i is m (a_j^2 + a_k^2) / 12.  The triangle inequality of real
    bodies makes every radicand >= 0.

    Returns
    -------
    edges : ndarray (3,)
        Edge lengths in m along the principal axes, in the order of
        ``body.principal_moments`` (ascending moments, so descending edges).
    axes : ndarray (3, 3)
        The principal axes in the body frame as columns (right-handed).

    """
    moments = body.principal_moments
    total = moments.sum()
    # I_j + I_k - I_i = total - 2 I_i; clipped at 0 against round-off for a lamina.
    radicands = np.clip(6.0 * (total - 2.0 * moments) / body.mass, 0.0, None)
    return np.sqrt(radicands), body.principal_axes


def marker_geometry(body, shape='', size=()):
    """
    Return the :class:`MarkerGeometry` that draws `body`.

    Parameters
    ----------
    body : RigidBody
        The body; its principal moments and axes size the inertia-equivalent box.
    shape : str
        One of :data:`SHAPES`, or '' for the inertia-equivalent box
        (:func:`inertia_equivalent_box`), which is what RViz shows for a body given by its
        inertia alone.
    size : sequence of float
        The shape's dimensions in m: box (a, b, c) edges; cylinder (radius, height) along
        body z; sphere (radius,); ellipsoid (a, b, c) semi-axes.

    """
    if shape == '':
        edges, axes = inertia_equivalent_box(body)
        edges = np.maximum(edges, _MIN_EDGE_FRACTION * edges.max())
        is_identity = np.allclose(axes, np.eye(3), rtol=0.0, atol=1e-12)
        axes = None if is_identity else tuple(quaternion_from_matrix(axes).tolist())
        return MarkerGeometry(Marker.CUBE, tuple(float(e) for e in edges), axes)
    if shape not in _SIZE_COUNTS:
        raise ValueError(f'shape must be one of {", ".join(SHAPES)} or empty; got {shape!r}')
    size = tuple(float(s) for s in size)
    if len(size) != _SIZE_COUNTS[shape]:
        raise ValueError(f'a {shape} needs {_SIZE_COUNTS[shape]} size value(s) in m; got '
                         f'{len(size)}')
    if shape == 'box':
        scale = size
        marker_type = Marker.CUBE
    elif shape == 'cylinder':
        radius, height = size
        scale = (2.0 * radius, 2.0 * radius, height)
        marker_type = Marker.CYLINDER
    elif shape == 'sphere':
        scale = (2.0 * size[0],) * 3
        marker_type = Marker.SPHERE
    else:
        scale = tuple(2.0 * s for s in size)
        marker_type = Marker.SPHERE
    return MarkerGeometry(marker_type, scale, None)


_DRAWING_MARKER_TYPES = {'box': Marker.CUBE, 'cylinder': Marker.CYLINDER,
                         'sphere': Marker.SPHERE, 'ellipsoid': Marker.SPHERE}


def marker_geometry_from_drawing(drawing):
    """
    Return the :class:`MarkerGeometry` of a scene's :class:`~rigid_body_sim.scenes.Drawing`.

    The drawing's size is already a Marker scale (m).  The colour is rounded to float32,
    ColorRGBA's type, so that a message survives serialisation unchanged.
    """
    identity = tuple(float(q) for q in drawing.orientation) == (0.0, 0.0, 0.0, 1.0)
    axes = None if identity else tuple(float(q) for q in drawing.orientation)
    color = tuple(float(np.float32(c)) for c in drawing.color)
    return MarkerGeometry(_DRAWING_MARKER_TYPES[drawing.shape],
                          tuple(float(s) for s in drawing.size), axes, color)


_POSE_FIELDS = ('position.x', 'position.y', 'position.z',
                'orientation.x', 'orientation.y', 'orientation.z', 'orientation.w')
_TWIST_FIELDS = ('linear.x', 'linear.y', 'linear.z', 'angular.x', 'angular.y', 'angular.z')
# The state-dependent fields of each message, in the order of _state_values().  Everything
# else in a message (frame ids, marker shape and colour, zero covariances) is fixed.
_STATE_FIELDS = {
    'pose': tuple('pose.' + field for field in _POSE_FIELDS),
    'twist': _TWIST_FIELDS,
    'angular_momentum': ('vector.x', 'vector.y', 'vector.z'),
    'odom': tuple('pose.pose.' + field for field in _POSE_FIELDS)
    + tuple('twist.twist.' + field for field in _TWIST_FIELDS),
    'marker': tuple('pose.' + field for field in _POSE_FIELDS),
}
_STAMPED = ('pose', 'angular_momentum', 'odom', 'marker')


def state_field_columns(body, rows, marker_axes):
    """
    Return topic -> the value columns of its _STATE_FIELDS for n packed states, SI.

    rows : (n, 13) q, x, p, L (world frame).  The velocities and the marker's orientation
    come from :func:`~rigid_body_sim.physics.kernels.derived.derived_quantities`, the one
    computation the node (one state a tick) and the offline writer (thousands at once,
    recording/state_batch.py) share, so their messages agree to the bit.
    """
    rows = np.ascontiguousarray(rows, dtype=float)
    axes = _NO_TURN if marker_axes is None else np.asarray(marker_axes, dtype=float)
    inverse = np.ascontiguousarray(body.inertia_inverse, dtype=float).reshape(9)
    derived = derived_quantities(rows, inverse, body.mass, axes)
    columns = list(rows.T)
    velocity, omega = list(derived[:, 0:3].T), list(derived[:, 3:6].T)
    velocity_body, omega_body = list(derived[:, 6:9].T), list(derived[:, 9:12].T)
    position, quaternion = columns[4:7], columns[0:4]
    pose = position + quaternion
    # The marker's axes are the principal axes: its orientation is R composed with them.
    marker = pose if marker_axes is None else position + list(derived[:, 12:16].T)
    return {
        'pose': pose,
        'twist': velocity + omega,
        'angular_momentum': columns[10:13],
        'odom': pose + velocity_body + omega_body,
        'marker': marker,
    }


def _state_values(body, state, marker_axes):
    """Return topic -> the values of its _STATE_FIELDS (floats, SI) for `state`."""
    # One state a tick: the columns of state_field_columns as Python floats, without the
    # column arrays (3 us a tick instead of 10).
    axes = _NO_TURN if marker_axes is None else np.asarray(marker_axes, dtype=float)
    inverse = np.ascontiguousarray(body.inertia_inverse, dtype=float).reshape(9)
    derived = derived_quantities(np.concatenate(state._fields())[None, :], inverse, body.mass,
                                 axes)[0].tolist()
    position, quaternion = state.position.tolist(), state.quaternion.tolist()
    pose = position + quaternion
    return {
        'pose': pose,
        'twist': derived[0:6],
        'angular_momentum': state.angular_momentum.tolist(),
        'odom': pose + derived[6:12],
        'marker': pose if marker_axes is None else position + derived[12:16],
    }


_NO_TURN = np.array([0.0, 0.0, 0.0, 1.0])


def _new_state_messages(world_frame, body_frame, geometry):
    pose = PoseStamped()
    angular_momentum = Vector3Stamped()
    odom = Odometry()
    odom.child_frame_id = body_frame
    marker = Marker()
    marker.ns = _MARKER_NAMESPACE
    marker.id = 0
    marker.type = geometry.marker_type
    marker.action = Marker.ADD
    marker.scale.x, marker.scale.y, marker.scale.z = (float(s) for s in geometry.scale)
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = (
        _MARKER_COLOR if geometry.color is None else geometry.color)
    messages = _StateMessages(pose=pose, twist=Twist(), angular_momentum=angular_momentum,
                              odom=odom, marker=marker)
    # One Time object is shared by every header: stamping it once stamps all the messages.
    stamp = Time()
    for topic in _STAMPED:
        messages[topic].header.frame_id = world_frame
        messages[topic].header.stamp = stamp
    messages.stamp = stamp
    messages.marker_axes = geometry.axes
    # (parent message, attribute) of every state field, resolved once.
    messages.targets = {topic: [_target(messages[topic], path) for path in paths]
                        for topic, paths in _STATE_FIELDS.items()}
    return messages


def _target(message, path):
    *parents, attribute = path.split('.')
    for parent in parents:
        message = getattr(message, parent)
    return message, attribute


class _StateMessages(dict):
    """Topic name -> message, with what refilling them in place needs."""

    __slots__ = ('stamp', 'marker_axes', 'targets')


def state_messages(body, state, stamp_nanoseconds, world_frame='world', body_frame='body',
                   geometry=None, messages=None):
    """
    Return every message that describes `state`, keyed by topic name.

    Parameters
    ----------
    body : RigidBody
        The simulated body (mass and inertia turn momenta into velocities).
    state : State
        World-frame state (rotation body to world, COM position, momenta).
    stamp_nanoseconds : int
        Header stamp in ns (ROS time of the node's clock, or simulated time offline).
    world_frame, body_frame : str
        Frame ids of the inertial frame and of the body (origin at its COM).
    geometry : MarkerGeometry, optional
        How to draw the body; default: its inertia-equivalent box.
    messages : dict, optional
        The dict returned by an earlier call with the same body, frames and geometry: its
        messages are refilled in place and returned (no allocation).  The messages share
        their stamp; publish or serialise them before the next call.

    Returns
    -------
    dict
        ``pose`` PoseStamped (frame world_frame): COM position and orientation.
        ``twist`` Twist: COM velocity and angular velocity, both in the world frame.
        ``angular_momentum`` Vector3Stamped (world_frame): L about the COM.
        ``odom`` Odometry: pose in world_frame, twist in body_frame (child_frame_id), as
        nav_msgs prescribes.  Covariances are zero: the simulated state is exact.
        ``marker`` Marker (world_frame): the body's shape at its pose.

    """
    if messages is None:
        if geometry is None:
            geometry = marker_geometry(body)
        messages = _new_state_messages(world_frame, body_frame, geometry)
    stamp = messages.stamp
    stamp.sec, stamp.nanosec = divmod(int(stamp_nanoseconds), 1_000_000_000)
    values = _state_values(body, state, messages.marker_axes)
    for topic, targets in messages.targets.items():
        for (parent, attribute), value in zip(targets, values[topic]):
            setattr(parent, attribute, value)
    return messages


class StateSerializer:
    """
    The serialised (CDR) messages of :func:`state_messages`, made fast for the node.

    rclpy converts a message to C field by field, which for the five state messages costs
    more than the physics step; publishing ready bytes costs a few microseconds.  Each
    message is serialised once as a template, the byte offsets of its stamp and state fields
    are found by serialising sentinel values, and every call patches only those bytes.
    ``serialize(...)[topic]`` deserialises to a message equal, field for field, to
    ``state_messages(...)[topic]`` (tested; only CDR's alignment padding, whose content is
    unspecified, may differ from ``serialize_message``'s output).

    Parameters
    ----------
    body, world_frame, body_frame, geometry
        As for :func:`state_messages`.

    """

    def __init__(self, body, world_frame='world', body_frame='body', geometry=None):
        if geometry is None:
            geometry = marker_geometry(body)
        self._body = body
        self._marker_axes = geometry.axes
        messages = _new_state_messages(world_frame, body_frame, geometry)
        self._layouts = {topic: _layout(messages, topic) for topic in STATE_TOPICS}

    def serialize(self, state, stamp_nanoseconds, topics=STATE_TOPICS):
        """
        Return topic -> serialised message (bytes) of `state`, stamped (ns).

        Only the given `topics` (a subset of :data:`STATE_TOPICS`) are serialised.
        """
        seconds, nanoseconds = divmod(int(stamp_nanoseconds), 1_000_000_000)
        values = _state_values(self._body, state, self._marker_axes)
        serialized = {}
        layouts = self._layouts
        for topic in topics:
            buffer, stamp_packer, stamp_offset, runs = layouts[topic]
            if stamp_packer is not None:
                stamp_packer.pack_into(buffer, stamp_offset, seconds, nanoseconds)
            topic_values = values[topic]
            for packer, offset, first, last in runs:
                packer.pack_into(buffer, offset, *topic_values[first:last])
            serialized[topic] = bytes(buffer)
        return serialized


def _layout(messages, topic):
    """
    Return (template, stamp packer, stamp offset, runs) of one topic's message.

    runs: (packer, byte offset, first, last) for each stretch of consecutive state fields
    that are contiguous doubles in the serialised message.
    """
    message = messages[topic]
    targets = messages.targets[topic]
    # Sentinels: distinct values whose bytes occur nowhere else in the template.
    sentinels = [-8.765432109876e17 - 1.0e6 * k for k in range(len(targets))]
    for (parent, attribute), value in zip(targets, sentinels):
        setattr(parent, attribute, value)
    stamp_sentinel = (1987654321, 987654321)
    if topic in _STAMPED:
        messages.stamp.sec, messages.stamp.nanosec = stamp_sentinel
    template = bytearray(serialize_message(message))
    # The CDR encapsulation header's second byte is 1 for little-endian data.
    order = '<' if template[1] == 1 else '>'

    def offset_of(packed, what):
        offset = template.find(packed)
        if offset < 0 or template.find(packed, offset + 1) >= 0:
            raise RuntimeError(f'cannot locate {what} in the serialised {topic} message')
        return offset

    offsets = [offset_of(struct.pack(order + 'd', value), f'field {path}')
               for value, path in zip(sentinels, _STATE_FIELDS[topic])]
    runs = []
    first = 0
    for k in range(1, len(offsets) + 1):
        if k == len(offsets) or offsets[k] != offsets[k - 1] + 8:
            runs.append((struct.Struct(f'{order}{k - first}d'), offsets[first], first, k))
            first = k
    stamp_packer = stamp_offset = None
    if topic in _STAMPED:
        stamp_packer = struct.Struct(order + 'iI')
        stamp_offset = offset_of(stamp_packer.pack(*stamp_sentinel), 'the stamp')
    return template, stamp_packer, stamp_offset, runs


# -- incoming: messages -> validated wrench


def _vector_from_message(vector_message):
    return np.array((vector_message.x, vector_message.y, vector_message.z))


def frame_from_frame_id(frame_id, world_frame, body_frame):
    """
    Return 'world' or 'body' for a header frame id; RejectedInput for any other id.

    An empty frame id means the world frame (what ``ros2 topic pub`` sends by default).
    """
    if frame_id in ('', world_frame):
        return 'world'
    if frame_id == body_frame:
        return 'body'
    # A peer's frame id can be megabytes long or hold control characters: quoted cut and
    # escaped, so the warning (and /rosout) stays one short line.
    raise RejectedInput(
        f"unknown frame_id '{shortened(frame_id)}'; accepted frame ids: {world_frame!r} or "
        f'empty (world-fixed), {body_frame!r} (body-fixed)', 'frame')


def wrench_input_from_message(message, world_frame, body_frame, max_wrench):
    """
    Return the :class:`WrenchInput` of a torque or wrench message, validated.

    Parameters
    ----------
    message : geometry_msgs/Vector3Stamped (a torque, N m) or geometry_msgs/WrenchStamped
        (a force through the COM, N, and a torque about it, N m).  header.frame_id selects
        the frame the vectors are given and held in (see :func:`frame_from_frame_id`).
    world_frame : str
        Frame id of the world frame: vectors fixed in the world.
    body_frame : str
        Frame id of the body frame: vectors fixed in the body, turning with it.
    max_wrench : float
        Largest accepted magnitude of the force (N) and of the torque (N m).

    Raises
    ------
    RejectedInput
        For a non-finite component, a magnitude above max_wrench, or an unknown frame id;
        the message says which and why.

    """
    if hasattr(message, 'wrench'):
        force = _vector_from_message(message.wrench.force)
        torque = _vector_from_message(message.wrench.torque)
    else:
        force = np.zeros(3)
        torque = _vector_from_message(message.vector)
    for name, vector, unit in (('force', force, 'N'), ('torque', torque, 'N m')):
        if not np.all(np.isfinite(vector)):
            raise RejectedInput(f'non-finite {name} {vector.tolist()}: every component must '
                                'be a finite number', 'non-finite')
        magnitude = math.hypot(*vector)  # no overflow for components near 1e154
        if magnitude > max_wrench:
            raise RejectedInput(f'{name} magnitude {magnitude:.6g} {unit} is above '
                                f'max_wrench = {max_wrench:g}', 'magnitude')
    frame = frame_from_frame_id(message.header.frame_id, world_frame, body_frame)
    return WrenchInput(force, torque, frame)


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

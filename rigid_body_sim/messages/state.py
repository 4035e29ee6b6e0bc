"""
The node's state messages: a State of a RigidBody as every message it publishes.

:func:`state_messages` turns a State into the messages of :data:`STATE_TOPICS`, keyed by
topic name, and :class:`StateSerializer` into their serialised (CDR) bytes for the node's
ticks.  The node and any offline writer (a bag of a simulated run,
:mod:`rigid_body_sim.recording.state_batch`) call the same code, so a bag written offline
holds exactly what the node publishes.

Frames (REP 103/105): ``world_frame`` is the inertial frame; ``body_frame`` is attached to
the body with its origin at the centre of mass (COM).  Units: SI.
"""

import struct

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
import numpy as np
from visualization_msgs.msg import Marker

from .cdr import byte_order
from .cdr import field_target
from .cdr import offset_of
from .cdr import sentinels
from .cdr import serialize_zeroed
from .cdr import STAMP_SENTINEL
from .marker import marker_geometry
from .marker import new_marker
from ..physics.kernels.derived import derived_quantities

__all__ = [
    'STATE_FIELDS',
    'STATE_TOPICS',
    'STATE_TYPES',
    'state_field_columns',
    'state_messages',
    'StateSerializer',
]

STATE_TOPICS = ('pose', 'twist', 'angular_momentum', 'odom', 'marker')
"""Topic names (relative) of the messages :func:`state_messages` returns, in that order."""

STATE_TYPES = {'pose': PoseStamped, 'twist': Twist, 'angular_momentum': Vector3Stamped,
               'odom': Odometry, 'marker': Marker}
"""Topic name (relative) -> message class of :func:`state_messages`, known without a scene."""


_POSE_FIELDS = ('position.x', 'position.y', 'position.z',
                'orientation.x', 'orientation.y', 'orientation.z', 'orientation.w')
_TWIST_FIELDS = ('linear.x', 'linear.y', 'linear.z', 'angular.x', 'angular.y', 'angular.z')
STATE_FIELDS = {
    'pose': tuple('pose.' + field for field in _POSE_FIELDS),
    'twist': _TWIST_FIELDS,
    'angular_momentum': ('vector.x', 'vector.y', 'vector.z'),
    'odom': tuple('pose.pose.' + field for field in _POSE_FIELDS)
    + tuple('twist.twist.' + field for field in _TWIST_FIELDS),
    'marker': tuple('pose.' + field for field in _POSE_FIELDS),
}
"""Topic -> the paths of its message's state-dependent fields, in the order of the values
:func:`state_field_columns` returns.  Everything else in a message (frame ids, the marker's
shape and colour, zero covariances) is fixed."""
_STAMPED = ('pose', 'angular_momentum', 'odom', 'marker')


def state_field_columns(body, rows, marker_axes):
    """
    Return topic -> the value columns of its :data:`STATE_FIELDS` for n packed states, SI.

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
    """Return topic -> the values of its STATE_FIELDS (floats, SI) for `state`."""
    # One state a tick: the columns of state_field_columns as Python floats, without the
    # column arrays, whose numpy calls cost more than the arithmetic for one state.
    axes = _NO_TURN if marker_axes is None else np.asarray(marker_axes, dtype=float)
    inverse = np.ascontiguousarray(body.inertia_inverse, dtype=float).reshape(9)
    row = np.concatenate((state.quaternion, state.position, state.linear_momentum,
                          state.angular_momentum))
    derived = derived_quantities(row[None, :], inverse, body.mass, axes)[0].tolist()
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
    marker = new_marker(geometry, world_frame)
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
    messages.targets = {topic: [field_target(messages[topic], path) for path in paths]
                        for topic, paths in STATE_FIELDS.items()}
    return messages


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
    ``state_messages(...)[topic]`` (tested), with CDR's alignment padding zeroed
    (:func:`~rigid_body_sim.messages.cdr.serialize_zeroed`): the same state gives the same
    bytes in every run.

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
    values = sentinels(len(targets))
    for (parent, attribute), value in zip(targets, values):
        setattr(parent, attribute, value)
    if topic in _STAMPED:
        messages.stamp.sec, messages.stamp.nanosec = STAMP_SENTINEL
    template = bytearray(serialize_zeroed(message))
    order = byte_order(template)
    offsets = [offset_of(template, struct.pack(order + 'd', value), f'{topic} field {path}')
               for value, path in zip(values, STATE_FIELDS[topic])]
    runs = []
    first = 0
    for k in range(1, len(offsets) + 1):
        if k == len(offsets) or offsets[k] != offsets[k - 1] + 8:
            runs.append((struct.Struct(f'{order}{k - first}d'), offsets[first], first, k))
            first = k
    stamp_packer = stamp_offset = None
    if topic in _STAMPED:
        stamp_packer = struct.Struct(order + 'iI')
        stamp_offset = offset_of(template, stamp_packer.pack(*STAMP_SENTINEL),
                                 f'the {topic} stamp')
    return template, stamp_packer, stamp_offset, runs

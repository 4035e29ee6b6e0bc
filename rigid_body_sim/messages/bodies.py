"""
The messages of a scene of several bodies, all bodies' at once: one call a tick.

A node that simulates many bodies publishes, for each, what the one-body node publishes
(:mod:`.state`: ``pose``, ``twist``, ``angular_momentum``, ``odom``; :mod:`.imu`), each
under the body's name, and for all of them one ``/tf`` message (every body's transform
``world_frame -> <name>``) and one ``visualization_msgs/MarkerArray`` (each body's marker,
``ns`` its name).  :class:`BodiesSerializer` writes them from the bodies' packed states
(an (N, 13) array: q, x, p, L, world frame, SI) in a few numpy operations, whatever N:
every message of one kind is serialised once as a template (:mod:`.cdr`), all of them lie
in one byte buffer, and a tick writes every state field and stamp into it with one indexed
assignment each; the velocities come from the one-body messages' own computation
(:func:`~rigid_body_sim.physics.kernels.derived.derived_quantities`, one call per group of
alike bodies), so a body's messages here equal, bit for bit, those of the one-body node in
that state (tested).

Frames: ``world_frame`` is the inertial frame, ``<name>`` each body's (origin at its COM),
``<name>/imu`` its IMU's; the caller gives them as tf2 reads them (:mod:`.frames`).
"""

from dataclasses import dataclass
import struct

from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import TransformStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
import numpy as np
from visualization_msgs.msg import Marker
from visualization_msgs.msg import MarkerArray

from .cdr import field_target
from .cdr import sentinels
from .cdr import serialize_zeroed
from .cdr import STAMP_SENTINEL
from .imu import imu_message
from .marker import new_marker
from .state import STATE_FIELDS
from ..physics.kernels.derived import derived_quantities

__all__ = ['BODY_TOPICS', 'IMU_FIELDS', 'MARKERS_TOPIC', 'BodyMessages', 'BodiesSerializer',
           'BodyRows', 'PatchedMessages', 'deleted_markers']

BODY_TOPICS = ('pose', 'twist', 'angular_momentum', 'odom')
"""The state topics each body has under its name (besides ``imu``), as the one-body node's."""
MARKERS_TOPIC = 'markers'
"""The MarkerArray of every body, relative to the node's namespace."""
IMU_FIELDS = ('orientation.x', 'orientation.y', 'orientation.z', 'orientation.w',
              'angular_velocity.x', 'angular_velocity.y', 'angular_velocity.z',
              'linear_acceleration.x', 'linear_acceleration.y', 'linear_acceleration.z')
"""The Imu message's reading fields, in the order of the values its batch is written with."""
_TRANSFORM_FIELDS = ('transform.translation.x', 'transform.translation.y',
                     'transform.translation.z', 'transform.rotation.x',
                     'transform.rotation.y', 'transform.rotation.z', 'transform.rotation.w')
_POSE = [4, 5, 6, 0, 1, 2, 3]  # packed state columns of position, then quaternion (x, y, z, w)
_NO_TURN = np.array([0.0, 0.0, 0.0, 1.0])


@dataclass(frozen=True)
class BodyMessages:
    """
    What one body's messages name and show.

    name : str, its ``ns`` in the MarkerArray; body : RigidBody (mass, inertia);
    body_frame, imu_frame : its frame ids as tf2 reads them; geometry : MarkerGeometry;
    imu : Imu (its covariances), or None for no imu topic; marker_id : int, unique.
    """

    name: str
    body: object
    body_frame: str
    imu_frame: str
    geometry: object
    imu: object
    marker_id: int


class PatchedMessages:
    """
    Serialised messages in one buffer, their state fields and stamps patched in place.

    :meth:`write` takes (groups, F) values and a stamp; :meth:`message` returns a message's
    bytes.  Little-endian CDR only (what rclpy writes on every platform here).

    Parameters
    ----------
    messages : list of ROS messages
        Each serialised once (padding zeroed), after its fields were set to sentinels.
    fields : list of list of list of (parent, attribute)
        For each message, its groups of F double fields (F the same everywhere), in the
        order they are serialised: a one-body message has one group, a TFMessage one per
        transform.
    stamps : list of list of builtin_interfaces/Time
        For each message, the stamps it holds (a Time object shared by several headers
        counts once), in the order they are serialised.

    """

    def __init__(self, messages, fields, stamps):
        width = len(fields[0][0]) if fields and fields[0] else 0
        marks = sentinels(width)
        packed = [struct.pack('<d', mark) for mark in marks]
        stamp_bytes = struct.pack('<iI', *STAMP_SENTINEL)
        buffers, double_positions, stamp_positions, bounds = [], [], [], []
        start = 0
        for message, groups, message_stamps in zip(messages, fields, stamps):
            for group in groups:
                for (parent, attribute), mark in zip(group, marks):
                    setattr(parent, attribute, mark)
            for stamp in message_stamps:
                stamp.sec, stamp.nanosec = STAMP_SENTINEL
            template = serialize_zeroed(message)
            if template[1] != 1:
                raise RuntimeError('rclpy serialised big-endian CDR; the batches are written '
                                   'little-endian')
            # Groups and stamps in serialised order: each found after the one before.
            offset = 0
            for _group in groups:
                for mark in packed:
                    offset = template.index(mark, offset)
                    double_positions.append(start + offset)
                    offset += 8
            offset = 0
            for _stamp in message_stamps:
                offset = template.index(stamp_bytes, offset)
                stamp_positions.append(start + offset)
                offset += 8
            buffers.append(template)
            bounds.append((start, start + len(template)))
            start += len(template)
        self._buffer = np.frombuffer(b''.join(buffers), dtype=np.uint8).copy()
        self._doubles = (np.asarray(double_positions, dtype=np.int64)[:, None]
                         + np.arange(8)).reshape(-1)
        self._stamps = (np.asarray(stamp_positions, dtype=np.int64)[:, None]
                        + np.arange(8)).reshape(-1)
        self._stamp_count = len(stamp_positions)
        self._bounds = bounds

    def __len__(self):
        """Return the number of messages."""
        return len(self._bounds)

    def write(self, values, stamp_nanoseconds):
        """Write (groups, F) values (SI) and the stamp (ns) into every message."""
        if self._doubles.size:
            self._buffer[self._doubles] = np.ascontiguousarray(
                values, dtype='<f8').view(np.uint8).reshape(-1)
        if self._stamp_count:
            stamp = np.frombuffer(struct.pack(
                '<iI', *divmod(int(stamp_nanoseconds), 1_000_000_000)), dtype=np.uint8)
            self._buffer[self._stamps] = np.tile(stamp, self._stamp_count)

    def message(self, index):
        """Return the serialised bytes of message `index` as last written."""
        start, end = self._bounds[index]
        return self._buffer[start:end].tobytes()


def _state_message(topic, world_frame, body_frame):
    """Return (message, its state fields' targets, its stamps) of a one-body state topic."""
    message = {'pose': PoseStamped, 'twist': Twist, 'angular_momentum': Vector3Stamped,
               'odom': Odometry}[topic]()
    stamps = []
    if topic != 'twist':
        message.header.frame_id = world_frame
        stamps.append(message.header.stamp)
    if topic == 'odom':
        message.child_frame_id = body_frame
    return message, [field_target(message, path) for path in STATE_FIELDS[topic]], stamps


class BodiesSerializer:
    """
    Every body's state topics, one /tf message and one MarkerArray, written at once.

    After :meth:`write`, ``batches[topic].message(i)`` is body i's message on a topic of
    :data:`BODY_TOPICS` or ``imu``, ``batches['/tf'].message(0)`` and
    ``batches['markers'].message(0)`` the one of all bodies.

    Parameters
    ----------
    world_frame : str
        The inertial frame's id (as tf2 reads it): every header's frame, every
        transform's parent.
    bodies : sequence of BodyMessages
        The bodies, in the order of the rows given to :meth:`write`.
    transform_class : type or None
        tf2_msgs/TFMessage (None: no /tf; see
        :func:`~rigid_body_sim.messages.tf.transform_message_class`).
    imu_period : float
        The IMU's sample period in s (its covariances).

    """

    def __init__(self, world_frame, bodies, transform_class=None, imu_period=0.01):
        self.bodies = tuple(bodies)
        count = len(self.bodies)
        self.batches = {}
        for topic in BODY_TOPICS:
            made = [_state_message(topic, world_frame, body.body_frame) for body in self.bodies]
            self.batches[topic] = PatchedMessages(
                [message for message, _, _ in made], [[targets] for _, targets, _ in made],
                [stamps for _, _, stamps in made])
        imus = [imu_message(body.imu_frame, body.imu, imu_period) for body in self.bodies
                if body.imu is not None]
        if imus:
            self.batches['imu'] = PatchedMessages(
                imus, [[[field_target(message, path) for path in IMU_FIELDS]]
                       for message in imus], [[message.header.stamp] for message in imus])
        if transform_class is not None and count:
            transforms = []
            for body in self.bodies:
                transform = TransformStamped()
                transform.header.frame_id = world_frame
                transform.child_frame_id = body.body_frame
                transforms.append(transform)
            self.batches['/tf'] = PatchedMessages(
                [transform_class(transforms=transforms)],
                [[[field_target(transform, path) for path in _TRANSFORM_FIELDS]
                  for transform in transforms]],
                [[transform.header.stamp for transform in transforms]])
        if count:
            markers = [new_marker(body.geometry, world_frame, body.name, body.marker_id)
                       for body in self.bodies]
            self.batches[MARKERS_TOPIC] = PatchedMessages(
                [MarkerArray(markers=markers)],
                [[[field_target(marker, 'pose.' + path) for path in (
                    'position.x', 'position.y', 'position.z', 'orientation.x',
                    'orientation.y', 'orientation.z', 'orientation.w')]
                  for marker in markers]],
                [[marker.header.stamp for marker in markers]])
        # Alike bodies (mass, inertia, marker axes) share one call of the velocities' kernel.
        groups = {}
        for index, body in enumerate(self.bodies):
            inverse = np.ascontiguousarray(body.body.inertia_inverse, dtype=float).reshape(9)
            axes = body.geometry.axes
            key = (float(body.body.mass), inverse.tobytes(), axes)
            groups.setdefault(key, (inverse, []))[1].append(index)
        self._groups = [(np.asarray(indices), inverse, mass,
                         _NO_TURN if axes is None else np.asarray(axes, dtype=float))
                        for (mass, _, axes), (inverse, indices) in groups.items()]
        self._turned = np.array([body.geometry.axes is not None for body in self.bodies],
                                dtype=bool)

    def write(self, rows, stamp_nanoseconds, topics):
        """
        Write the messages of `topics` for the packed states `rows` (N, 13), stamped (ns).

        topics: names among :data:`BODY_TOPICS`, ``/tf`` and ``markers`` (those absent from
        :attr:`batches` are skipped).  Returns :attr:`batches`.
        """
        rows = np.ascontiguousarray(rows, dtype=float)
        pose = rows[:, _POSE]
        derived = None
        velocities = any(topic in ('twist', 'odom') for topic in topics)
        if velocities or (MARKERS_TOPIC in topics and self._turned.any()):
            # The markers alone need it only for bodies drawn turned in their frame.
            derived = np.empty((rows.shape[0], 16))
            for indices, inverse, mass, axes in self._groups:
                if velocities or self._turned[indices[0]]:
                    derived[indices] = derived_quantities(rows[indices], inverse, mass, axes)
        for topic in topics:
            batch = self.batches.get(topic)
            if batch is None:
                continue
            if topic == 'pose' or topic == '/tf':
                values = pose
            elif topic == 'twist':
                values = derived[:, 0:6]
            elif topic == 'angular_momentum':
                values = rows[:, 10:13]
            elif topic == 'odom':
                values = np.concatenate((pose, derived[:, 6:12]), axis=1)
            elif topic == MARKERS_TOPIC:
                values = pose
                if derived is not None:
                    values = pose.copy()
                    values[self._turned, 3:7] = derived[self._turned, 12:16]
            else:
                raise ValueError(f'no batch of {topic!r}: its values come from write_imu')
            batch.write(values, stamp_nanoseconds)
        return self.batches

    def write_imu(self, readings, stamp_nanoseconds):
        """Write (M, 10) IMU readings (orientation x, y, z, w, omega, acceleration; SI)."""
        self.batches['imu'].write(readings, stamp_nanoseconds)
        return self.batches['imu']


class BodyRows:
    """
    The packed states (N, 13) of a World's bodies, read where the World keeps them.

    Each row is q (x, y, z, w), x, p, L (world frame, SI) of the body's centre of mass, in
    the order of `names`.  A free body's row is a view of its Simulator's packed state (no
    copy per body per tick); a pivoted body integrates about its pivot, so its COM state is
    asked of the World.

    Parameters
    ----------
    world : rigid_body_sim.physics.World
    names : sequence of str
        The bodies, in the order of the rows.
    pivoted : sequence of bool
        For each, whether it hangs from a pivot (its scene's ``pivot`` effect).

    """

    def __init__(self, world, names, pivoted):
        self._world = world
        self._names = list(names)
        self._packed = [world.simulator(name).kernel_arguments()[0] for name in self._names]
        self._pivoted = [index for index, flag in enumerate(pivoted) if flag]

    def rows(self):
        """Return the bodies' packed states now, (N, 13), a new array."""
        rows = np.array(self._packed) if self._packed else np.zeros((0, 13))
        for index in self._pivoted:
            state = self._world.state(self._names[index])
            rows[index] = np.concatenate((state.quaternion, state.position,
                                          state.linear_momentum, state.angular_momentum))
        return rows


def deleted_markers(markers):
    """Return a MarkerArray deleting the markers (namespace, id) of `markers`."""
    array = MarkerArray()
    for namespace, marker_id in markers:
        marker = Marker()
        marker.ns = namespace
        marker.id = marker_id
        marker.action = Marker.DELETE
        array.markers.append(marker)
    return array

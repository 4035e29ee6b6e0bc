"""
TF (REP 105): the body's frame on ``/tf`` and the IMU's mount on ``/tf_static``.

Every tick the node publishes one ``tf2_msgs/TFMessage`` on ``/tf`` holding the transform
``world_frame -> body_frame``: translation = the COM position, rotation = the orientation
quaternion, the very doubles of the ``pose`` message of that tick and its stamp, so a TF
listener and a pose subscriber see the same motion bit for bit.  ``/tf_static`` (reliable,
transient local, keep last 1: what tf2's static broadcaster offers) holds
``body_frame -> imu_frame`` from the IMU mount.  ``simulate`` writes both into its bags.

tf2_msgs is not among the ROS 2 PyPI wheels: ``make venv`` builds it into the venv
(``interfaces/``), and a ROS installation has its own.  Where neither is there,
:func:`transform_message_class` says why, and the node runs without TF.
"""

import struct

from geometry_msgs.msg import TransformStamped
import numpy as np

from .cdr import byte_order
from .cdr import column
from .cdr import offset_of
from .cdr import rows_of
from .cdr import sentinels
from .cdr import serialize_zeroed
from .cdr import STAMP_SENTINEL
from .cdr import write_stamps

__all__ = ['TF_TOPIC', 'TF_STATIC_TOPIC', 'TransformSerializer', 'static_transforms',
           'transform_message_class']

TF_TOPIC = '/tf'
TF_STATIC_TOPIC = '/tf_static'
# The transform's 7 doubles, told apart in the template.
_SENTINELS = sentinels(7)


def transform_message_class():
    """Return (tf2_msgs/TFMessage class, None), or (None, why it cannot be imported)."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError as error:
        return None, (f'tf2_msgs cannot be imported ({error}); `make venv` builds it where '
                      'cmake and a C/C++ compiler exist (see the README), a ROS installation '
                      'has it')
    return TFMessage, None


def _transform(parent_frame, child_frame, stamp_nanoseconds, translation, rotation):
    transform = TransformStamped()
    transform.header.frame_id = parent_frame
    transform.header.stamp.sec, transform.header.stamp.nanosec = divmod(
        int(stamp_nanoseconds), 1_000_000_000)
    transform.child_frame_id = child_frame
    vector = transform.transform.translation
    vector.x, vector.y, vector.z = (float(v) for v in translation)
    quaternion = transform.transform.rotation
    quaternion.x, quaternion.y, quaternion.z, quaternion.w = (float(v) for v in rotation)
    return transform


def static_transforms(message_class, body_frame, imu_frame, imu_model, stamp_nanoseconds):
    """
    Return the /tf_static message: ``body_frame -> imu_frame`` from the IMU mount.

    The mount's position (m, body frame, from the COM) and orientation (quaternion x, y, z,
    w, IMU to body) of an :class:`~rigid_body_sim.physics.imu.ImuModel`.
    """
    return message_class(transforms=[_transform(body_frame, imu_frame, stamp_nanoseconds,
                                                imu_model.position, imu_model.orientation)])


class TransformSerializer:
    """
    The serialised /tf message of one transform, patched in place for each state.

    ``serialize(stamp, pose)`` (one tick, the node) and ``serialize_rows(stamps, columns)``
    (many ticks, ``simulate``) write the stamp and the 7 doubles of the pose (position x,
    y, z, quaternion x, y, z, w) into a template serialised once by rclpy, as
    :class:`~rigid_body_sim.messages.state.StateSerializer` does for the state topics (its
    padding zeroed: :func:`~rigid_body_sim.messages.cdr.serialize_zeroed`).
    """

    def __init__(self, message_class, parent_frame, child_frame):
        message = message_class(transforms=[_transform(
            parent_frame, child_frame, 0, _SENTINELS[:3], _SENTINELS[3:])])
        message.transforms[0].header.stamp.sec, message.transforms[0].header.stamp.nanosec = \
            STAMP_SENTINEL
        template = bytearray(serialize_zeroed(message))
        order = byte_order(template)
        self._pose_offset = offset_of(template, struct.pack(order + '7d', *_SENTINELS),
                                      'the transform')
        self._stamp_offset = offset_of(template, struct.pack(order + 'iI', *STAMP_SENTINEL),
                                       'the transform stamp')
        self._little_endian = order == '<'
        self._pose_packer = struct.Struct(order + '7d')
        self._stamp_packer = struct.Struct(order + 'iI')
        self._template = template

    def serialize(self, stamp_nanoseconds, pose):
        """Return the bytes of the message for a stamp (ns) and pose (7 floats)."""
        buffer = self._template
        self._stamp_packer.pack_into(buffer, self._stamp_offset,
                                     *divmod(int(stamp_nanoseconds), 1_000_000_000))
        self._pose_packer.pack_into(buffer, self._pose_offset, *pose)
        return bytes(buffer)

    def serialize_rows(self, stamps, pose_columns):
        """Return (n, size) uint8: the message of each stamp (ns) and pose (7 columns)."""
        if not self._little_endian:
            raise RuntimeError('rclpy serialised big-endian CDR; rows are written '
                               'little-endian')
        stamps = np.asarray(stamps, dtype=np.int64)
        rows = rows_of(self._template, stamps.size)
        write_stamps(rows, self._stamp_offset, stamps)
        for index, values in enumerate(pose_columns):
            column(rows, self._pose_offset + 8 * index, '<f8')[:] = values
        return rows

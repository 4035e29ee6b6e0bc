"""
The node's state messages for many ticks at once, serialised with numpy.

An offline run writes the same five state messages every tick.  Serialising them one
state at a time (:class:`rigid_body_sim.messages.state.StateSerializer`, what the node
does) costs more than the physics step; here a batch of states becomes, per topic, a
(ticks, bytes) array: the message's CDR template from rclpy's serializer repeated, with the
stamp and the state fields written into it column-wise.

The messages are those of ``StateSerializer.serialize`` field for field (tested for every
topic over random states): the fields are the ones
:func:`~rigid_body_sim.messages.state.state_messages` documents, each computed with the
same floating-point operations in the same order (numpy's element-wise operations round
like Python's), so each value is bit for bit the node's.

Padding.  rclpy's serializer skips CDR's alignment padding without writing it, so those
bytes of its output are whatever its buffer held (they differ from run to run and may be
leftover memory).  The templates here have them zeroed
(:func:`~rigid_body_sim.messages.cdr.serialize_zeroed`), so a run
serialises the same states into the same bytes every time (tested: two identical
``simulate`` runs write byte-identical messages).
"""

import struct

import numpy as np

from ..messages.cdr import byte_order
from ..messages.cdr import column
from ..messages.cdr import field_target
from ..messages.cdr import offset_of
from ..messages.cdr import rows_of
from ..messages.cdr import sentinels
from ..messages.cdr import serialize_zeroed
from ..messages.cdr import STAMP_SENTINEL
from ..messages.cdr import write_stamps
from ..messages.marker import marker_geometry
from ..messages.state import state_field_columns
from ..messages.state import STATE_FIELDS
from ..messages.state import state_messages
from ..messages.state import STATE_TOPICS
from ..physics import State

__all__ = ['StateBatch', 'BatchSerializer', 'STATE_COLUMNS']

STATE_COLUMNS = 13
"""Columns of a state row: quaternion (x, y, z, w), position, linear and angular momentum."""


class StateBatch:
    """
    Up to `capacity` states, one row each (see :data:`STATE_COLUMNS`), filled by append.

    Appending copies four small arrays (a microsecond or two), the whole per-tick cost of
    collecting a run for :class:`BatchSerializer`.
    """

    def __init__(self, capacity):
        self.rows = np.empty((int(capacity), STATE_COLUMNS))
        self.count = 0

    def append(self, state):
        """Add a State (world frame) as the next row."""
        row = self.rows[self.count]
        row[0:4] = state.quaternion
        row[4:7] = state.position
        row[7:10] = state.linear_momentum
        row[10:13] = state.angular_momentum
        self.count += 1

    def clear(self):
        """Forget the rows (keep the memory)."""
        self.count = 0

    @property
    def full(self):
        """Whether no row is left."""
        return self.count == len(self.rows)

    def filled(self):
        """Return the filled rows, (count, 13)."""
        return self.rows[:self.count]


class BatchSerializer:
    """
    Serialise batches of states into the node's state messages (CDR bytes).

    Parameters
    ----------
    body : RigidBody
    world_frame, body_frame : str
    geometry : MarkerGeometry, optional
        As for :func:`~rigid_body_sim.messages.state.state_messages`.
    topics : sequence of str
        Which of :data:`~rigid_body_sim.messages.state.STATE_TOPICS` to serialise.

    Raises
    ------
    RuntimeError
        If rclpy serialises big-endian data (no supported platform does).

    """

    def __init__(self, body, world_frame='world', body_frame='body', geometry=None,
                 topics=STATE_TOPICS):
        if geometry is None:
            geometry = marker_geometry(body)
        self._body = body
        self._marker_axes = geometry.axes
        self.topics = tuple(topics)
        reference = State()
        self._layouts = {}
        for topic in self.topics:
            messages = state_messages(body, reference, 0, world_frame, body_frame, geometry)
            self._layouts[topic] = _layout(messages, topic)

    def sizes(self):
        """Return topic -> size in bytes of its serialised message (fixed for a body)."""
        return {topic: layout[0].size for topic, layout in self._layouts.items()}

    def serialize(self, rows, stamps):
        """
        Return topic -> (n, size) uint8 array: the serialised message of each state.

        Parameters
        ----------
        rows : ndarray (n, 13)
            States as :class:`StateBatch` rows.
        stamps : ndarray (n,) of int
            Header stamps in ns.

        """
        rows = np.asarray(rows, dtype=float)
        stamps = np.asarray(stamps, dtype=np.int64)
        values = self._values(rows)
        serialized = {}
        for topic in self.topics:
            template, stamp_offset, offsets = self._layouts[topic]
            data = rows_of(template, len(rows))  # every byte, padding (zero) included
            if stamp_offset is not None:
                write_stamps(data, stamp_offset, stamps)
            for offset, value in zip(offsets, values[topic]):
                column(data, offset, '<f8')[:] = value
            serialized[topic] = data
        return serialized

    def _values(self, rows):
        """Return topic -> list of value columns, as the node's messages carry them."""
        return state_field_columns(self._body, rows, self._marker_axes)


def _layout(messages, topic):
    """Return (template uint8 array, stamp offset or None, field offsets) of a topic."""
    message = messages[topic]
    paths = STATE_FIELDS[topic]
    values = sentinels(len(paths))
    for path, value in zip(paths, values):
        parent, attribute = field_target(message, path)
        setattr(parent, attribute, value)
    header = getattr(message, 'header', None)
    if header is not None:
        header.stamp.sec, header.stamp.nanosec = STAMP_SENTINEL
    # Padding zeroed: the same states give the same bytes in every run.
    template = serialize_zeroed(message)
    if byte_order(template) != '<':
        raise RuntimeError('rclpy serialised big-endian CDR; the batch serializer writes '
                           'little-endian fields')
    offsets = [offset_of(template, struct.pack('<d', value), f'{topic} field {path}')
               for value, path in zip(values, paths)]
    stamp_offset = None
    if header is not None:
        stamp_offset = offset_of(template, struct.pack('<iI', *STAMP_SENTINEL),
                                 f'the {topic} stamp')
    buffer = bytearray(template)
    # The template's own values do not matter (every state field and the stamp are
    # overwritten), but zeros keep a mistake visible.
    for offset in offsets:
        buffer[offset:offset + 8] = bytes(8)
    if stamp_offset is not None:
        buffer[stamp_offset:stamp_offset + 8] = bytes(8)
    return np.frombuffer(bytes(buffer), dtype=np.uint8), stamp_offset, offsets

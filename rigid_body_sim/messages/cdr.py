"""
Serialised messages patched in place: where a message's fields sit in its CDR bytes.

rclpy converts a message to C field by field, which for the state messages costs more than
the physics step.  So the serialisers of the node and of ``simulate`` serialise each message
once, as a template holding sentinel values, find every field's byte offset from them, and
then write only those bytes: for one tick (``struct.pack_into``) or for many ticks at once
(numpy columns of a (ticks, bytes) array).  The stamp (builtin_interfaces/Time: int32
seconds, uint32 nanoseconds) is found the same way.
"""

import numpy as np

__all__ = ['STAMP_SENTINEL', 'byte_order', 'column', 'field_target', 'offset_of', 'rows_of',
           'sentinels', 'write_stamps']

STAMP_SENTINEL = (1987654321, 987654321)
"""A stamp (s, ns) no real message has, to find a header's stamp in a template."""


def sentinels(count):
    """Return `count` distinct doubles whose bytes occur nowhere else in a message."""
    return [-8.765432109876e17 - 1.0e6 * k for k in range(count)]


def byte_order(template):
    """Return the struct byte order ('<' or '>') of serialised CDR bytes."""
    # The CDR encapsulation header's second byte is 1 for little-endian data.
    return '<' if template[1] == 1 else '>'


def offset_of(template, packed, what):
    """Return where the bytes `packed` stand in `template`; RuntimeError unless once."""
    offset = template.find(packed)
    if offset < 0 or template.find(packed, offset + 1) >= 0:
        raise RuntimeError(f'cannot locate {what} in its serialised message')
    return offset


def field_target(message, path):
    """Return (parent message, attribute name) of a field path such as 'pose.position.x'."""
    *parents, attribute = path.split('.')
    for parent in parents:
        message = getattr(message, parent)
    return message, attribute


def rows_of(template, count):
    """Return (count, size) uint8: the template's bytes (bytes or uint8 array) in each row."""
    template = np.frombuffer(bytes(template), dtype=np.uint8)
    rows = np.empty((int(count), template.size), dtype=np.uint8)
    rows[:] = template
    return rows


def column(rows, offset, dtype):
    """Return a view of one field (at byte `offset`) of every row of `rows` (n, size)."""
    dtype = np.dtype(dtype)
    return np.ndarray((rows.shape[0],), dtype=dtype, buffer=rows, offset=offset,
                      strides=(rows.shape[1],))


def write_stamps(rows, offset, stamps):
    """Write stamps (ns, int) into the little-endian Time at byte `offset` of every row."""
    seconds, nanoseconds = np.divmod(np.asarray(stamps, dtype=np.int64), 1_000_000_000)
    column(rows, offset, '<i4')[:] = seconds
    column(rows, offset + 4, '<u4')[:] = nanoseconds

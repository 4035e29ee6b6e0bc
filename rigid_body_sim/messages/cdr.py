"""
Serialised messages patched in place: where a message's fields sit in its CDR bytes.

rclpy converts a message to C field by field, which for the state messages costs more than
the physics step.  So the serialisers of the node and of ``simulate`` serialise each message
once, as a template holding sentinel values, find every field's byte offset from them, and
then write only those bytes: for one tick (``struct.pack_into``) or for many ticks at once
(numpy columns of a (ticks, bytes) array).  The stamp (builtin_interfaces/Time: int32
seconds, uint32 nanoseconds) is found the same way.

Padding.  CDR aligns each primitive to its size, counted from the end of the 4-byte
encapsulation header; rclpy's serializer skips the bytes in between without writing them,
so they hold whatever its buffer held, and two runs serialise one message into different
bytes.  :func:`serialize_zeroed` writes those bytes as zeros: every template here comes from
it, so the same states give the same bytes (a bag, a topic's messages) every time.
"""

import numpy as np
from rclpy.serialization import deserialize_message
from rclpy.serialization import serialize_message
from rosidl_parser.definition import AbstractSequence
from rosidl_parser.definition import AbstractString
from rosidl_parser.definition import Array
from rosidl_parser.definition import BasicType
from rosidl_parser.definition import NamespacedType

__all__ = ['STAMP_SENTINEL', 'byte_order', 'column', 'field_target', 'offset_of', 'rows_of',
           'sentinels', 'serialize_zeroed', 'write_stamps']

# Bytes of each primitive in CDR, which is also its alignment.
_PRIMITIVE_SIZES = {'boolean': 1, 'octet': 1, 'char': 1, 'int8': 1, 'uint8': 1, 'int16': 2,
                    'uint16': 2, 'int32': 4, 'uint32': 4, 'float': 4, 'int64': 8,
                    'uint64': 8, 'double': 8}
_HEADER = 4  # the encapsulation: alignment counts from its end

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


def serialize_zeroed(message):
    """
    Return the CDR bytes of a ROS message (rclpy's), its alignment padding written as zeros.

    The message's fields are walked in their CDR order (its type's introspection) to mark
    the bytes that hold them; the others are padding.  Checked: the walk ends where the
    bytes do, and the result deserialises to `message`, so only padding changes.

    Raises
    ------
    RuntimeError
        If the walk does not account for the serialised bytes (a type it does not know:
        wide strings).

    """
    data = bytearray(serialize_message(message))
    fields = bytearray(len(data))  # 1 where a field's byte is
    end = _mark_message(message, _HEADER, fields)
    if end != len(data):
        raise RuntimeError(f'cannot find the padding of {type(message).__name__}: its fields '
                           f'end at byte {end} of {len(data)}')
    for index in range(_HEADER, len(data)):
        if not fields[index]:
            data[index] = 0
    zeroed = bytes(data)
    if deserialize_message(zeroed, type(message)) != message:
        raise RuntimeError(f'zeroing the padding of {type(message).__name__} changed it')
    return zeroed


def _mark(fields, position, size, count=1):
    """Mark `count` primitives of `size` bytes from `position` (aligned first); return end."""
    start = position + (-(position - _HEADER)) % size
    end = start + size * count
    if end > len(fields):
        raise RuntimeError("the message's fields run past its serialised bytes")
    fields[start:end] = b'\x01' * (end - start)
    return end


def _mark_message(message, position, fields):
    names = type(message).get_fields_and_field_types()
    for name, kind in zip(names, type(message).SLOT_TYPES):
        position = _mark_value(getattr(message, name), kind, position, fields)
    return position


def _mark_value(value, kind, position, fields):
    if isinstance(kind, BasicType):
        return _mark(fields, position, _PRIMITIVE_SIZES[kind.typename])
    if isinstance(kind, AbstractString):
        if not isinstance(value, str):
            raise RuntimeError(f'a wide or unknown string type: {kind}')
        # uint32 length (with the terminating null), the UTF-8 bytes, the null.
        position = _mark(fields, position, 4)
        return _mark(fields, position, 1, len(value.encode('utf-8')) + 1)
    if isinstance(kind, (Array, AbstractSequence)):
        if isinstance(kind, AbstractSequence):
            position = _mark(fields, position, 4)  # uint32 element count
        item = kind.value_type
        if isinstance(item, BasicType):
            return _mark(fields, position, _PRIMITIVE_SIZES[item.typename], len(value))
        for element in value:
            position = _mark_value(element, item, position, fields)
        return position
    if isinstance(kind, NamespacedType):
        return _mark_message(value, position, fields)
    raise RuntimeError(f'a field type the padding walk does not know: {kind}')

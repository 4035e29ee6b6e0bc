"""
The bodies' markers in a bag of several bodies: shapes, colours and poses to draw.

The node of bodies (and ``simulate`` of a scene of ``bodies:``) publishes one
visualization_msgs/MarkerArray ``<ns>/markers`` a tick, each body's marker with ``ns`` its
name: its shape (CUBE, CYLINDER, SPHERE), ``scale`` (m), colour, and its pose in the world
frame (position the COM, orientation the drawing's axes: the body's, turned by the
drawing's orientation in the body frame).  ``plot`` reads the first array (the bodies'
shapes and colours); ``animate`` the arrays of the ticks its frames show.
"""

from dataclasses import dataclass
import math
from pathlib import Path
import struct

import numpy as np
from rosbags.rosbag2 import Reader

from .bag_writer import typestore

__all__ = ['MarkerFrames', 'first_markers', 'marker_frames']

_MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'
# A tick is kept when a frame's time may fall within this fraction of the frame interval of
# it: a small superset of the ticks the plan picks, whatever the rounding of the times.
_SLACK = 1e-3


def _connection(reader, namespace):
    """Return the bag's ``<namespace>/markers`` MarkerArray connection, or None."""
    wanted = f'{(namespace or "").rstrip("/")}/markers'
    for connection in reader.connections:
        if connection.topic == wanted and connection.msgtype == _MARKER_ARRAY:
            return connection
    return None


def _stamp(message):
    """Return the header stamp (ns) of a deserialised message's first marker."""
    stamp = message.markers[0].header.stamp
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def first_markers(bag, namespace=''):
    """
    Return (stamp ns, {body name: Marker}) of the bag's first marker array, or None.

    None when the bag has no ``<namespace>/markers`` array (a bag without it, or of one
    body, whose marker is ``marker``).
    """
    store = typestore()
    with Reader(Path(bag)) as reader:
        connection = _connection(reader, namespace)
        if connection is None:
            return None
        for _, _, raw in reader.messages(connections=[connection]):
            message = store.deserialize_cdr(raw, _MARKER_ARRAY)
            if message.markers:
                return _stamp(message), {marker.ns: marker for marker in message.markers}
    return None


@dataclass(eq=False)
class MarkerFrames:
    """
    The marker arrays of the ticks an animation shows.

    Attributes
    ----------
    stamps : ndarray (n,) of int64
        The header stamps (ns) of every tick's array.
    arrays : dict
        Tick index -> {body name: Marker} of the ticks kept (those the frames show).

    """

    stamps: np.ndarray
    arrays: dict


def _raw_stamp(raw):
    """
    Return the first marker's header stamp (ns) of a serialised MarkerArray, or None.

    CDR: the 4-byte encapsulation header (its second byte 1 for little-endian), the
    sequence's length (uint32), then the first marker's header stamp (int32 sec, uint32
    nanosec): read without deserialising the array, which at 1,000 markers takes long.
    """
    if len(raw) < 16:
        return None
    order = '<' if raw[1] == 1 else '>'
    count, sec, nanosec = struct.unpack_from(order + 'Iii', raw, 4)
    if count == 0:
        return None
    return sec * 1_000_000_000 + (nanosec & 0xFFFFFFFF)


def marker_frames(bag, namespace, interval):
    """
    Read the marker arrays of a bag of bodies that frames every `interval` s would show.

    Every tick's stamp is read from the serialised array; an array is deserialised only
    for a tick a frame at t0 + k `interval` may show (the latest tick at or before it), so
    the cost is the frames', not the ticks'.

    Raises
    ------
    ValueError
        If the bag has no ``<namespace>/markers`` array, or none with a marker.

    """
    store = typestore()
    stamps = []
    arrays = {}
    with Reader(Path(bag)) as reader:
        connection = _connection(reader, namespace)
        if connection is None:
            elsewhere = [c.topic for c in reader.connections if c.msgtype == _MARKER_ARRAY]
            hint = (f'its marker array is {elsewhere[0]}: --namespace '
                    f'{elsewhere[0][:-len("/markers")] or "/"}?' if elsewhere else
                    'record the markers of the node too')
            raise ValueError(f'{bag}: no {(namespace or "").rstrip("/")}/markers topic '
                             f'({_MARKER_ARRAY}) to draw the bodies from: {hint}; or '
                             'animate one body with --body NAME')
        previous = None  # (tick index, raw) of the tick before
        for _, _, raw in reader.messages(connections=[connection]):
            stamp = _raw_stamp(raw)
            if stamp is None:
                continue
            if previous is not None and _frame_between(stamps[0], stamps[-1], stamp,
                                                       interval):
                arrays[previous[0]] = previous[1]
            previous = (len(stamps), bytes(raw))
            stamps.append(stamp)
        if previous is None:
            raise ValueError(f'{bag}: its markers topic holds no marker')
        arrays[previous[0]] = previous[1]
    decoded = {}
    for index, raw in arrays.items():
        message = store.deserialize_cdr(raw, _MARKER_ARRAY)
        decoded[index] = {marker.ns: marker for marker in message.markers}
    return MarkerFrames(np.asarray(stamps, dtype=np.int64), decoded)


def _frame_between(first, last, following, interval):
    """
    Return whether a frame time t0 + k interval may lie in [last, following) (stamps ns).

    With a slack of a thousandth of the interval either side: the tick `last` is kept when
    it may be the latest at or before a frame.
    """
    start = (last - first) / 1e9 / interval
    end = (following - first) / 1e9 / interval
    return math.floor(end + _SLACK) >= math.ceil(start - _SLACK)

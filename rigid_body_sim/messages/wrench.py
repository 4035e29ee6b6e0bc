"""
The torque and wrench the node takes: a message validated into a :class:`WrenchInput`.

:func:`wrench_input_from_message` turns a ``torque`` (Vector3Stamped) or ``wrench``
(WrenchStamped) message into a validated :class:`WrenchInput`, or raises
:class:`RejectedInput` saying why.  Frames (REP 103/105): ``world_frame`` is the inertial
frame; ``body_frame`` is attached to the body with its origin at the COM.  Units: SI.
"""

from dataclasses import dataclass
import math

import numpy as np

from .frames import as_tf2_reads
from ..text import shortened

__all__ = ['RejectedInput', 'WrenchInput', 'frame_from_frame_id', 'wrench_input_from_message']


@dataclass(frozen=True, eq=False)
class WrenchInput:
    """
    A validated external wrench from a message.

    Attributes
    ----------
    force : ndarray (3,)
        Through the COM, N.
    torque : ndarray (3,)
        About the COM, N m.
    frame : str
        'world' (fixed in the world frame) or 'body' (fixed in the body, turning with it),
        in the terms of :meth:`rigid_body_sim.physics.Simulator.set_wrench`.

    """

    force: np.ndarray
    torque: np.ndarray
    frame: str


class RejectedInput(ValueError):
    """
    An input message the node refuses; the message says why.

    ``kind`` names the rule it broke: 'non-finite', 'magnitude' or 'frame'.
    """

    def __init__(self, message, kind):
        super().__init__(message)
        self.kind = kind


def _vector_from_message(vector_message):
    return np.array((vector_message.x, vector_message.y, vector_message.z))


def frame_from_frame_id(frame_id, world_frame, body_frame):
    """
    Return 'world' or 'body' for a header frame id; RejectedInput for any other id.

    An empty frame id means the world frame (what ``ros2 topic pub`` sends by default).  The
    ids are compared as tf2 reads them (:func:`~rigid_body_sim.messages.frames.as_tf2_reads`:
    ``/sat1/body`` is ``sat1/body``).
    """
    if frame_id == '' or as_tf2_reads(frame_id) == world_frame:
        return 'world'
    if as_tf2_reads(frame_id) == body_frame:
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

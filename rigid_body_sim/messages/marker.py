"""
How the body is drawn: the RViz marker of the ``marker`` topic, from a body or a scene.

:class:`MarkerGeometry` is what a ``visualization_msgs/Marker`` needs besides the pose: its
type, its extent and the turn of its axes in the body frame.  A scene's drawing gives it
(:func:`marker_geometry_from_drawing`, what the node and ``simulate`` publish); a body alone
gives its inertia-equivalent box (:func:`inertia_equivalent_box`), which is what a body
given by its inertia looks like.  Lengths in m, frames as in :mod:`.state`.
"""

from dataclasses import dataclass

import numpy as np
from visualization_msgs.msg import Marker

from ..physics.rotations import quaternion_from_matrix
from ..scenes import SHAPES

__all__ = [
    'MARKER_COLOR',
    'MARKER_NAMESPACE',
    'MarkerGeometry',
    'inertia_equivalent_box',
    'marker_geometry',
    'marker_geometry_from_drawing',
    'new_marker',
    'visible_equivalent_box',
]

MARKER_COLOR = (0.875, 0.4375, 0.125, 0.875)
"""RGBA of a marker without a colour of its own: an orange, visible on RViz's grey grid,
nearly opaque.  The values are exact in float32 (ColorRGBA's type), so a message survives
serialisation unchanged."""
MARKER_NAMESPACE = 'rigid_body'
"""The marker's ``ns`` (its id is 0)."""

_SIZE_COUNTS = {'box': 3, 'cylinder': 2, 'sphere': 1, 'ellipsoid': 3}
# An inertia-equivalent box thinner than this fraction of its longest edge is drawn this
# thick: a lamina (I1 + I2 = I3, such as the default T-handle I = (1, 2, 3)) has a zero edge,
# which RViz would not draw at all.
_MIN_EDGE_FRACTION = 0.02


@dataclass(frozen=True)
class MarkerGeometry:
    """
    How the body is drawn: an RViz marker type, its extent and colour.

    Attributes
    ----------
    marker_type : int
        A visualization_msgs/Marker type (CUBE, CYLINDER or SPHERE).
    scale : tuple of 3 floats
        The marker's full extent along its own x, y, z (m).
    axes : tuple of 4 floats or None
        Quaternion (x, y, z, w) of the marker's axes in the body frame, or None when they
        are the body axes.
    color : tuple of 4 floats or None
        (r, g, b, a), each 0..1, or None (default) for :data:`MARKER_COLOR`.

    """

    marker_type: int
    scale: tuple
    axes: tuple = None
    color: tuple = None


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


def visible_equivalent_box(body):
    """
    Return :func:`inertia_equivalent_box` as it is drawn: (edges in m, axes).

    A lamina's zero edge is drawn as a thin slab: no edge is shorter than a fiftieth of the
    longest.
    """
    edges, axes = inertia_equivalent_box(body)
    return np.maximum(edges, _MIN_EDGE_FRACTION * edges.max()), axes


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
        edges, axes = visible_equivalent_box(body)
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


def new_marker(geometry, frame_id, namespace=MARKER_NAMESPACE, marker_id=0):
    """
    Return a Marker (action ADD) drawing `geometry` in frame `frame_id`, its pose to fill.

    Its type, scale (m) and colour (:data:`MARKER_COLOR` if the geometry has none) set, its
    ``ns`` and ``id`` as given.
    """
    marker = Marker()
    marker.header.frame_id = frame_id
    marker.ns = namespace
    marker.id = marker_id
    marker.type = geometry.marker_type
    marker.action = Marker.ADD
    marker.scale.x, marker.scale.y, marker.scale.z = (float(s) for s in geometry.scale)
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = (
        MARKER_COLOR if geometry.color is None else geometry.color)
    return marker

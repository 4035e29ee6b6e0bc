"""
The body drawn in 3D: its shape, its axes, the direction of L and a trail, from its messages.

``rigid-body-sim animate`` draws each frame of a bag with :class:`BodyView`, and
``rigid-body-sim watch`` its live window: one drawing, whether the motion comes from a bag or
from the running node.  The shape is the node's ``marker`` (:func:`shape_from_marker`), or
for a body known by its mass and inertia alone its inertia-equivalent box
(:func:`equivalent_box_shape`).  Frames: the shape in the body frame, the view in the world
frame from the COM; lengths in m.  matplotlib is imported by :class:`BodyView` only.
"""

from dataclasses import dataclass
import math

import numpy as np
from visualization_msgs.msg import Marker

from .messages.marker import inertia_equivalent_box
from .messages.marker import visible_equivalent_box
from .physics import matrix_from_quaternion
from .physics import RigidBody
from .physics.principal_frame import principal_frame

__all__ = ['AXIS_COLOURS', 'BodyShape', 'BodyView', 'TrailAxis', 'axis_endpoints',
           'equivalent_box_shape', 'is_equivalent_box', 'middle_axis', 'shape_from_marker',
           'trail_axis', 'trail_points']

AXIS_COLOURS = ('tab:red', 'tab:green', 'tab:blue')
"""The colours of the body axes x, y, z (and of what is drawn per axis) in every figure."""
# The marker types a shape is drawn for, and the shape each stands for.
_SHAPE_NAMES = {Marker.CUBE: 'box', Marker.SPHERE: 'ellipsoid', Marker.CYLINDER: 'cylinder'}
# Frames of trail behind the current one, and its alpha at the head.
_TRAIL_FRAMES = 45
# The trail's points: none closer than the first (rad on the unit sphere: a 1 kHz bag draws
# no more points than the eye resolves), none farther apart than the second (a fast spin
# sampled at 100 Hz turns 7 degrees a tick, which drew as corners: stars and squares).
_TRAIL_FINEST = 0.005
_TRAIL_COARSEST = 0.02
# A unit direction within this of a body axis is that axis (its colour, its name).
_ALIGNED = 1e-9
# The colour of a trail along no body axis (a principal axis of a non-diagonal inertia).
_OFF_AXIS_COLOUR = 'tab:purple'


@dataclass(eq=False)
class BodyShape:
    """
    The drawn shape in the body frame.

    Attributes
    ----------
    kind : str
        'box', 'cylinder' (axis along the drawing's z) or 'ellipsoid'.
    scale : ndarray (3,)
        Marker scale in m: box edges, cylinder (2 r, 2 r, h), ellipsoid diameters.
    orientation : ndarray (3, 3)
        The drawing's axes in the body frame (columns).
    colour : tuple of 4 floats
        (r, g, b, a).
    origin : str
        Where the shape came from: 'marker', 'marker: inertia-equivalent box' (the node's
        marker of a body given by its inertia alone) or 'inertia-equivalent box' (no marker).

    """

    kind: str
    scale: np.ndarray
    orientation: np.ndarray
    colour: tuple
    origin: str

    def __post_init__(self):
        """Hold the sizes and axes as float arrays, the colour as a tuple."""
        self.scale = np.asarray(self.scale, dtype=float)
        self.orientation = np.asarray(self.orientation, dtype=float)
        self.colour = tuple(self.colour)

    def faces(self, coarse=False):
        """
        Return the surface as a list of polygons (k, 3) in the body frame, m.

        `coarse`: fewer facets of a curved surface (a cylinder of 12 sides, an ellipsoid
        of 60 facets), for a scene of many bodies drawn small.
        """
        half = 0.5 * self.scale
        if self.kind == 'box':
            polygons = _box_faces(half)
        elif self.kind == 'cylinder':
            polygons = _cylinder_faces(half[0], half[1], half[2], sides=12 if coarse else 24)
        elif coarse:
            polygons = _ellipsoid_faces(half, rings=6, sides=10)
        else:
            polygons = _ellipsoid_faces(half)
        return [polygon @ self.orientation.T for polygon in polygons]

    @property
    def equivalent(self):
        """Return True if this is a stand-in with the body's moments, not its shape."""
        return 'inertia-equivalent' in self.origin

    @property
    def label(self):
        """Return what the drawing is, for a legend: its shape and size, or a stand-in."""
        size = ' x '.join(f'{value:.3g}' for value in self.scale)
        if self.equivalent:
            return f"inertia-equivalent {self.kind} {size} m\n(the body's moments, not its shape)"
        return f'body: {self.kind} {size} m'

    @property
    def extent(self):
        """Return the largest distance (m) of the shape's surface from the COM."""
        return float(0.5 * np.linalg.norm(self.scale)) if self.kind == 'box' else \
            float(0.5 * np.max(self.scale) * (math.sqrt(2.0) if self.kind == 'cylinder'
                                              else 1.0))


def _box_faces(half):
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                       dtype=float) * half
    # Corner index = 4 ix + 2 iy + iz; each face is the four corners sharing one sign.
    faces = ((0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4),
             (1, 3, 7, 5))
    return [corners[list(face)] for face in faces]


def _cylinder_faces(radius_x, radius_y, half_height, sides=24):
    angles = np.linspace(0.0, 2.0 * math.pi, sides + 1)
    ring = np.stack([radius_x * np.cos(angles), radius_y * np.sin(angles)], axis=1)
    faces = []
    for k in range(sides):
        a, b = ring[k], ring[k + 1]
        faces.append(np.array([[*a, -half_height], [*b, -half_height], [*b, half_height],
                               [*a, half_height]]))
    for z in (-half_height, half_height):
        faces.append(np.column_stack([ring[:-1], np.full(sides, z)]))
    return faces


def _ellipsoid_faces(half, rings=10, sides=20):
    polar = np.linspace(0.0, math.pi, rings + 1)
    azimuth = np.linspace(0.0, 2.0 * math.pi, sides + 1)

    def point(theta, phi):
        return half * np.array([math.sin(theta) * math.cos(phi),
                                math.sin(theta) * math.sin(phi), math.cos(theta)])
    return [np.array([point(polar[i], azimuth[j]), point(polar[i], azimuth[j + 1]),
                      point(polar[i + 1], azimuth[j + 1]), point(polar[i + 1], azimuth[j])])
            for i in range(rings) for j in range(sides)]


def shape_from_marker(marker, body_quaternion, equivalent=False):
    """
    Return the :class:`BodyShape` a visualization_msgs/Marker draws.

    `body_quaternion` (x, y, z, w) is the body's orientation at the marker's stamp: the
    drawing's axes in the body frame are R_body^T R_marker.  `equivalent` says that the
    marker is the inertia-equivalent box of a body given by its inertia alone.

    Raises
    ------
    ValueError
        If the marker is not a CUBE, SPHERE or CYLINDER.

    """
    if marker.type not in _SHAPE_NAMES:
        raise ValueError(f'the marker is of type {marker.type}; only CUBE, SPHERE and '
                         'CYLINDER markers are drawn')
    orientation = marker.pose.orientation
    marker_rotation = matrix_from_quaternion(
        (orientation.x, orientation.y, orientation.z, orientation.w))
    body_rotation = matrix_from_quaternion(body_quaternion)
    colour = (marker.color.r, marker.color.g, marker.color.b, marker.color.a or 1.0)
    return BodyShape(_SHAPE_NAMES[marker.type],
                     (marker.scale.x, marker.scale.y, marker.scale.z),
                     body_rotation.T @ marker_rotation, colour,
                     'marker: inertia-equivalent box' if equivalent else 'marker')


def is_equivalent_box(shape, mass, inertia):
    """Return True if a box shape has the edges of the inertia-equivalent box of the body."""
    if shape.kind != 'box' or mass is None or inertia is None:
        return False
    edges, _ = inertia_equivalent_box(RigidBody(mass, inertia))
    # The two longest edges decide: a lamina's zero edge is drawn as a thin slab.
    drawn = np.sort(shape.scale)[1:]
    return bool(np.allclose(drawn, np.sort(edges)[1:], rtol=1e-6, atol=0.0))


def equivalent_box_shape(mass, inertia):
    """Return the :class:`BodyShape` of the inertia-equivalent box of mass (kg), inertia."""
    # A lamina's zero edge would not show: a thin slab, as the node's marker draws it.
    edges, axes = visible_equivalent_box(RigidBody(mass, inertia))
    return BodyShape('box', edges, axes, (0.55, 0.6, 0.75, 1.0), 'inertia-equivalent box')


def axis_endpoints(quaternion, length):
    """Return the tips (3, 3) of the body axes x, y, z (rows) of length m, world frame."""
    return length * matrix_from_quaternion(quaternion).T


def trail_axis(quaternions):
    """
    Return the body axis (0, 1, 2) whose world direction varies most over the motion.

    For a motion whose inertia is not known (:func:`middle_axis` is the axis that flips).
    """
    rotations = np.array([matrix_from_quaternion(q) for q in quaternions[::max(1, len(
        quaternions) // 400)]])
    # Column i of R is body axis i in the world; its spread is 1 - |mean direction|.
    return int(np.argmax(1.0 - np.linalg.norm(rotations.mean(axis=0), axis=0)))


@dataclass(frozen=True)
class TrailAxis:
    """
    The body direction whose tip leaves the trail, and what it is, for the caption.

    Attributes
    ----------
    direction : ndarray (3,)
        Unit vector in the body frame.
    name : str
        What it is, e.g. 'body y: the middle principal axis, which flips' (a legend's
        lines).
    flips : bool
        Whether it is the middle axis of three distinct moments: the one that flips.

    """

    direction: np.ndarray
    name: str
    flips: bool = False

    @property
    def body_axis(self):
        """Return the body axis (0, 1, 2) the direction lies along, or None."""
        direction = np.asarray(self.direction, dtype=float)
        index = int(np.argmax(np.abs(direction)))
        return index if abs(direction[index]) >= 1.0 - _ALIGNED else None

    @property
    def colour(self):
        """Return the colour of its trail: its body axis's, else one of its own."""
        index = self.body_axis
        return _OFF_AXIS_COLOUR if index is None else AXIS_COLOURS[index]


def middle_axis(inertia):
    """
    Return the :class:`TrailAxis` of the middle principal axis of an inertia (3, 3), kg m^2.

    The spin about the middle axis is the unstable one: it is the axis that flips over (a
    T-handle, a tennis racket), as ``watch`` counts and traces it.  Body frame.  For a body
    with two equal moments no axis flips, and the caption says the axis is one of two.
    """
    frame = principal_frame(np.asarray(inertia, dtype=float))
    direction = np.array(frame.axes[:, 1])
    index = int(np.argmax(np.abs(direction)))
    if abs(direction[index]) >= 1.0 - _ALIGNED:
        direction = np.eye(3)[index]
        where = f'body {"xyz"[index]}'
    else:
        where = 'body (' + ', '.join(f'{value:.2f}' for value in direction) + ')'
    low, middle, high = frame.moments
    if middle - low <= 1e-9 * high or high - middle <= 1e-9 * high:
        return TrailAxis(direction, f'{where}: a middle principal\naxis (two moments equal)')
    return TrailAxis(direction, f'{where}: the middle\nprincipal axis, which flips', True)


def trail_points(rotations, direction):
    """
    Return the tips (m, 3) of a body direction in the world frame along a motion, unit length.

    `rotations` (n, 3, 3): R, body to world, of every sample in time order; `direction`:
    unit vector, body frame.  Every sample's tip is taken, thinned where samples lie closer
    than the eye resolves, and between two samples farther apart than a hundredth of a turn
    points are added along the rotation that takes the one to the other at a constant rate
    (the motion between two samples at a constant angular velocity): a fast spin draws as a
    smooth curve, not as the polygon of its samples.
    """
    rotations = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    direction = np.asarray(direction, dtype=float)
    tips = rotations @ direction
    if len(tips) < 2:
        return tips
    # R_k^T R_k+1: the turn from one sample to the next, in sample k's body frame.
    turns = np.einsum('nji,njk->nik', rotations[:-1], rotations[1:])
    cosine = np.clip(0.5 * (np.trace(turns, axis1=1, axis2=2) - 1.0), -1.0, 1.0)
    angles = np.arccos(cosine)
    pieces = np.maximum(1, np.ceil(angles / _TRAIL_COARSEST)).astype(int)
    if np.any(pieces > 1):
        axes = np.stack([turns[:, 2, 1] - turns[:, 1, 2], turns[:, 0, 2] - turns[:, 2, 0],
                         turns[:, 1, 0] - turns[:, 0, 1]], axis=1)
        norms = np.linalg.norm(axes, axis=1, keepdims=True)
        axes = np.divide(axes, norms, out=np.zeros_like(axes), where=norms > 0.0)
        # Each interval k gives its start and pieces[k] - 1 points inside.
        interval = np.repeat(np.arange(len(turns)), pieces)
        fraction = (np.arange(len(interval)) - np.repeat(np.cumsum(pieces) - pieces, pieces)) \
            / pieces[interval]
        angle = fraction * angles[interval]
        axis = axes[interval]
        # Rodrigues' formula: the direction turned by `angle` about `axis` (body frame).
        along = np.sum(axis * direction, axis=1, keepdims=True)
        turned = (direction * np.cos(angle)[:, None]
                  + np.cross(axis, direction) * np.sin(angle)[:, None]
                  + axis * along * (1.0 - np.cos(angle))[:, None])
        tips = np.vstack([np.einsum('nij,nj->ni', rotations[interval], turned), tips[-1:]])
    travelled = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(tips, axis=0),
                                                                axis=1))])
    keep = np.ones(len(tips), dtype=bool)
    keep[1:] = np.diff(np.floor(travelled / _TRAIL_FINEST)) > 0
    keep[-1] = True
    return tips[keep]


class BodyView:
    """
    The body drawn in a 3D matplotlib axes, viewed from its COM, updated in place.

    Draws the shape, the body axes x, y, z (red, green, blue) reaching past the shape, the
    direction of the world angular momentum L (dashed black) and a fading trail of the tip
    of one body direction over the last frames.  ``rigid-body-sim animate`` draws each
    frame with it, and ``rigid-body-sim watch`` its live window.

    Parameters
    ----------
    axes : mpl_toolkits.mplot3d.Axes3D
        Where to draw; its limits, projection and view are set here.
    shape : BodyShape
        The shape, in the body frame.
    trail_axis : int or TrailAxis
        The body axis (0, 1, 2), or the body direction, whose tip leaves the trail.  A
        :class:`TrailAxis` is named in the legend.
    font_size : float
        Points, of the tick and legend labels.

    """

    def __init__(self, axes, shape, trail_axis, font_size=7.0):
        import matplotlib.ticker
        from mpl_toolkits.mplot3d.art3d import Line3DCollection
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        self.axes = axes
        self.shape = shape
        self.body_faces = shape.faces()
        self.axis_length = 1.25 * max(shape.extent, 1e-9)
        axes.set_proj_type('ortho')
        limit = 1.1 * self.axis_length
        for setter in (axes.set_xlim, axes.set_ylim, axes.set_zlim):
            setter(-limit, limit)
        axes.set_box_aspect((1.0, 1.0, 1.0))
        axes.view_init(elev=22.0, azim=-55.0)
        axes.set_xlabel('world x (m)', fontsize=font_size)
        axes.set_ylabel('world y (m)', fontsize=font_size)
        axes.set_zlabel('world z (m)', fontsize=font_size)
        axes.tick_params(labelsize=font_size - 1.0)
        # Plain white panes without a grid: fewer colours and edges that change between
        # frames, so a GIF compresses several times better.
        axes.grid(False)
        for axis in (axes.xaxis, axes.yaxis, axes.zaxis):
            axis.set_pane_color((1.0, 1.0, 1.0, 0.0))
            axis.set_major_locator(matplotlib.ticker.MaxNLocator(3))
        self.polygons = Poly3DCollection(self.body_faces, facecolor=shape.colour[:3],
                                         edgecolor='0.25', linewidth=0.3,
                                         alpha=0.55 * shape.colour[3])
        axes.add_collection3d(self.polygons, autolim=False)
        # A legend entry for the body that says what is drawn (its shape, or a stand-in).
        axes.plot([], [], marker='s', linestyle='none', markersize=6,
                  color=shape.colour[:3], alpha=0.7, label=shape.label)
        self.axis_lines = [axes.plot([0, 0], [0, 0], [0, 0], color=colour, linewidth=2.0,
                                     label=f'body {name}')[0]
                           for colour, name in zip(AXIS_COLOURS, 'xyz')]
        self.momentum_line = axes.plot([0, 0], [0, 0], [0, 0], color='black',
                                       linewidth=1.5, linestyle='--',
                                       label='L (world)')[0]
        if not isinstance(trail_axis, TrailAxis):
            trail_axis = TrailAxis(np.eye(3)[trail_axis], f'body {"xyz"[trail_axis]}')
        else:
            # Named in the legend, which says which axis the trail is.
            axes.plot([], [], [], color=trail_axis.colour, linewidth=1.2,
                      label=f'trail: tip of {trail_axis.name}')
        self.trail_axis = trail_axis
        self.trail = Line3DCollection([np.zeros((2, 3))], colors=trail_axis.colour,
                                      linewidths=1.2)
        axes.add_collection3d(self.trail, autolim=False)
        # The trail's points (unit vectors, world frame) of each of the last frames.
        self.trail_points = []

    def show(self, quaternion, angular_momentum, trail=None):
        """
        Draw the body at `quaternion` (x, y, z, w) with L (world frame); extend the trail.

        `trail` (k, 3): the trail's points since the last frame up to this one
        (:func:`trail_points` of every sample between them: unit vectors, world frame);
        without it, this frame's tip alone.
        """
        rotation = matrix_from_quaternion(quaternion)
        self.polygons.set_verts([face @ rotation.T for face in self.body_faces])
        tips = axis_endpoints(quaternion, self.axis_length)
        for line, tip in zip(self.axis_lines, tips):
            line.set_data_3d([0.0, tip[0]], [0.0, tip[1]], [0.0, tip[2]])
        momentum = np.asarray(angular_momentum, dtype=float)
        size = np.linalg.norm(momentum)
        direction = momentum / size * self.axis_length if size > 0.0 else np.zeros(3)
        self.momentum_line.set_data_3d([0.0, direction[0]], [0.0, direction[1]],
                                       [0.0, direction[2]])
        if trail is None:
            trail = (rotation @ np.asarray(self.trail_axis.direction, dtype=float))[None, :]
        self.trail_points.append(np.asarray(trail, dtype=float).reshape(-1, 3))
        del self.trail_points[:-_TRAIL_FRAMES]
        points = self.axis_length * np.vstack(self.trail_points)
        if len(points) > 1:
            segments = np.stack([points[:-1], points[1:]], axis=1)
            self.trail.set_segments(segments)
            alphas = np.linspace(0.05, 0.9, len(segments))
            base = np.array(self.trail.get_edgecolor()[0][:3])
            self.trail.set_color([(*base, alpha) for alpha in alphas])
        return size

    def clear_trail(self):
        """Forget the trail (after a reset: the body jumps back to its start)."""
        self.trail_points.clear()
        self.trail.set_segments([np.zeros((2, 3))])

    def set_trail(self, quaternions):
        """
        Draw the trail through the tip of the trail axis at each orientation, oldest first.

        `quaternions` (k, 4) are (x, y, z, w), body to world: the trail then follows the
        motion as sampled by whoever calls (every pose received, say), not the frames drawn;
        it fades towards the oldest as :meth:`show`'s does.
        """
        direction = np.asarray(self.trail_axis.direction, dtype=float)
        units = np.array([matrix_from_quaternion(quaternion) @ direction
                          for quaternion in np.asarray(quaternions, dtype=float)]).reshape(-1, 3)
        # show() keeps unit directions in trail_points and scales them when it draws.
        self.trail_points = [units[-_TRAIL_FRAMES:]]
        tips = self.axis_length * units
        if len(tips) < 2:
            self.trail.set_segments([np.zeros((2, 3))])
            return
        self.trail.set_segments(np.stack([tips[:-1], tips[1:]], axis=1))
        base = np.array(self.trail.get_edgecolor()[0][:3])
        self.trail.set_color([(*base, alpha) for alpha in np.linspace(0.05, 0.9,
                                                                      len(tips) - 1)])

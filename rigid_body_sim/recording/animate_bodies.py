"""
Animate all the bodies of a bag of several bodies in one 3-D scene.

Everything drawn comes from the bag's marker array ``<ns>/markers`` (one a tick, each
body's marker with ``ns`` its name: :mod:`.marker_arrays`): each body's shape (CUBE,
CYLINDER, SPHERE) of the marker's ``scale`` and colour at the marker's pose (its COM and
the drawing's axes, world frame), and a fading trail of each COM over the last
:data:`TRAIL_FRAMES` frames.  The axes are fitted to every body over the run (equal scales,
m).  Only the arrays of the ticks the frames show are deserialised, so the cost follows the
frames, not the ticks or the bodies' topics.

Up to :data:`NAMED_BODIES` bodies are named in a legend.  More than :data:`MOST_SHAPES`
bodies (a 1,000-body constellation) are drawn as points of their markers' colours: their
shapes would be specks at this size and cost seconds a frame; ``--body NAME`` animates one.

Frames, writers and the size budget are :mod:`.animate`'s.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .frame_plan import figure_image
from .frame_plan import plan_frames
from .marker_arrays import marker_frames
from .motion import read_custom_data
from .motion import time_of_stamps

__all__ = ['BodiesAnimation', 'MOST_SHAPES', 'NAMED_BODIES', 'TRAIL_FRAMES',
           'prepare_bodies_animation']

NAMED_BODIES = 10
"""Up to this many bodies are named in the legend."""
MOST_SHAPES = 200
"""Up to this many bodies are drawn as their shapes; more as points."""
TRAIL_FRAMES = 10
"""Frames of each COM's trail."""
# Bodies drawn with coarse facets above this many (a field of debris).
_FINE_BODIES = 10


@dataclass(eq=False)
class BodiesAnimation:
    """
    An animation of a bag of bodies checked and ready to render (nothing written yet).

    Attributes
    ----------
    out : Path
        The GIF or MP4 to write.
    plan : AnimationPlan
        Which tick each frame shows.
    max_bytes : int
        Size budget of a GIF.
    arrays : dict
        Tick index -> {body name: Marker} of every tick a frame shows.
    title : str
        The scene's title.

    """

    out: Path
    plan: object
    max_bytes: int
    arrays: dict
    title: str

    def scene(self, pixels):
        """Return the figure that draws the frames (:class:`_BodiesScene`)."""
        return _BodiesScene(self, pixels)


def prepare_bodies_animation(bag, out, fps, speed, namespace, max_bytes):
    """
    Read the marker arrays the frames of a bag of bodies show; return a BodiesAnimation.

    Raises
    ------
    ValueError
        Bad fps or speed; a bag without the marker array.

    """
    plan_frames(np.zeros(1), fps, speed)  # the options' checks, before the bag is read
    frames = marker_frames(bag, namespace, speed / fps)
    custom = read_custom_data(bag)
    time, _ = time_of_stamps(frames.stamps, custom)
    plan = plan_frames(time, fps, speed)
    missing = sorted({int(index) for index in plan.indices} - set(frames.arrays))
    if missing:
        # marker_frames keeps every tick a frame may show: a gap is a bug, said plainly.
        raise ValueError(f'{bag}: the marker arrays of ticks {missing[:5]} were not kept')
    shown = [frames.arrays[int(index)] for index in plan.indices]
    count = max(len(array) for array in shown)
    scene = custom.get('rigid_body_sim.scene')
    title = (f'scene {scene}' if scene else Path(bag).name) + f', {count} bodies'
    if count > MOST_SHAPES:
        title += ' as points (--body NAME: one body)'
    return BodiesAnimation(out, plan, max_bytes,
                           {int(index): frames.arrays[int(index)] for index in plan.indices},
                           title)


def _pose(marker):
    """Return (position (3,), R (3, 3)) of a marker's pose, world frame."""
    from ..physics import matrix_from_quaternion

    pose = marker.pose
    orientation = pose.orientation
    return (np.array([pose.position.x, pose.position.y, pose.position.z]),
            matrix_from_quaternion((orientation.x, orientation.y, orientation.z,
                                    orientation.w)))


class _BodiesScene:
    """The matplotlib figure of the bodies' frames, updated in place from frame to frame."""

    def __init__(self, animation, pixels):
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        import matplotlib.ticker
        from mpl_toolkits.mplot3d.art3d import Line3DCollection
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        from ..drawing import shape_from_marker

        self.animation = animation
        first = animation.arrays[int(animation.plan.indices[0])]
        self.names = list(first)
        dpi = 100
        self.figure = plt.figure(figsize=(pixels / dpi, pixels / dpi), dpi=dpi)
        self.axes = axes = self.figure.add_subplot(projection='3d')
        self.as_points = len(self.names) > MOST_SHAPES
        coarse = len(self.names) > _FINE_BODIES
        self.faces = {}
        self.colours = {}
        extent = 0.0
        for name, marker in first.items():
            colour = (marker.color.r, marker.color.g, marker.color.b)
            self.colours[name] = colour
            if self.as_points:
                continue
            try:
                # The shape in the drawing's own frame: the marker's pose turns it.
                shape = shape_from_marker(marker, (marker.pose.orientation.x,
                                                   marker.pose.orientation.y,
                                                   marker.pose.orientation.z,
                                                   marker.pose.orientation.w))
            except ValueError as error:
                raise ValueError(f'body {name}: {error}') from None
            shape.orientation = np.eye(3)
            self.faces[name] = shape.faces(coarse=coarse)
            extent = max(extent, shape.extent)
        positions = np.array([[_pose(array[name])[0] for name in self.names if name in array]
                              for array in animation.arrays.values()]).reshape(-1, 3)
        low = positions.min(axis=0) - extent
        high = positions.max(axis=0) + extent
        centre = 0.5 * (low + high)
        half = 0.55 * max(float((high - low).max()), 1e-9)
        axes.set_proj_type('ortho')
        for setter, middle in zip((axes.set_xlim, axes.set_ylim, axes.set_zlim), centre):
            setter(middle - half, middle + half)
        axes.set_box_aspect((1.0, 1.0, 1.0))
        axes.view_init(elev=22.0, azim=-55.0)
        for label, setter in zip('xyz', (axes.set_xlabel, axes.set_ylabel, axes.set_zlabel)):
            setter(f'world {label} (m)', fontsize=7)
        axes.tick_params(labelsize=6)
        # White panes without a grid, as the one-body animation: a GIF compresses better.
        axes.grid(False)
        for axis in (axes.xaxis, axes.yaxis, axes.zaxis):
            axis.set_pane_color((1.0, 1.0, 1.0, 0.0))
            axis.set_major_locator(matplotlib.ticker.MaxNLocator(3))
        self.polygons = None
        self.polygons_world = []
        self.points = None
        if not self.as_points:
            facecolors = [self.colours[name] for name in self.names
                          for _ in self.faces[name]]
            self.polygons = Poly3DCollection(
                [face for name in self.names for face in self.faces[name]],
                facecolors=facecolors, edgecolor='0.3',
                linewidth=0.2 if coarse else 0.3, alpha=0.8)
            axes.add_collection3d(self.polygons, autolim=False)
        self.trail = Line3DCollection([np.zeros((2, 3))], linewidths=0.8)
        axes.add_collection3d(self.trail, autolim=False)
        self.history = []  # each frame's COM positions (bodies, 3)
        if len(self.names) <= NAMED_BODIES:
            for name in self.names:
                axes.plot([], [], marker='s', linestyle='none', markersize=6,
                          color=self.colours[name], label=name)
            axes.legend(loc='upper left', fontsize=6, frameon=False)
        axes.set_title(animation.title, fontsize=8)
        self.text = self.figure.text(0.02, 0.02, '', fontsize=7)

    def draw(self, index, time):
        """Show tick `index` (every body at its marker's pose) at simulated `time` s."""
        array = self.animation.arrays[int(index)]
        names = [name for name in self.names if name in array]
        poses = {name: _pose(array[name]) for name in names}
        positions = np.array([poses[name][0] for name in names])
        if self.as_points:
            if self.points is not None:
                self.points.remove()
            self.points = self.axes.scatter(*positions.T, s=2,
                                            c=[self.colours[name] for name in names],
                                            depthshade=False)
        else:
            # The faces in the world frame, body after body in the order of self.names.
            self.polygons_world = [face @ poses[name][1].T + poses[name][0]
                                   for name in names for face in self.faces[name]]
            self.polygons.set_verts(self.polygons_world)
            self.polygons.set_facecolor([self.colours[name] for name in names
                                         for _ in self.faces[name]])
        self.history.append(dict(zip(names, positions)))
        del self.history[:-TRAIL_FRAMES]
        self._draw_trail(names)
        self.text.set_text(f't = {time:6.2f} s')

    def _draw_trail(self, names):
        """Draw each COM's path over the last frames, fading toward the oldest."""
        segments, colours = [], []
        steps = len(self.history) - 1
        for step in range(steps):
            older, newer = self.history[step], self.history[step + 1]
            alpha = 0.15 + 0.75 * (step + 1) / steps
            for name in names:
                if name in older and name in newer and np.any(older[name] != newer[name]):
                    segments.append(np.vstack((older[name], newer[name])))
                    colours.append((*self.colours[name], alpha))
        self.trail.set_segments(segments or [np.zeros((2, 3))])
        self.trail.set_color(colours or [(0.0, 0.0, 0.0, 0.0)])

    def image(self):
        """Return the rendered frame as an RGB picture (Pillow)."""
        return figure_image(self.figure)

    def close(self):
        """Release the figure."""
        import matplotlib.pyplot as plt
        plt.close(self.figure)

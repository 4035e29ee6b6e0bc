"""
Animate the body recorded in a bag: its shape turning, its axes, L, and a trail.

What is drawn comes from the node's topics alone, so any bag of the node works:

- ``odom``: the orientation R (body to world) of each tick; ``angular_momentum``: L about
  the COM, world frame (read with :func:`.plot.read_motion`, paired by stamp);
- ``marker`` (visualization_msgs/Marker, its first message): the shape (CUBE, CYLINDER,
  SPHERE), its ``scale`` (m) and its colour; its orientation relative to the body's at the
  same stamp is the drawing's orientation in the body frame (a box drawn along the
  principal axes of a non-diagonal inertia).  A bag without ``marker`` draws the
  inertia-equivalent box (the solid box with the body's mass and principal moments, as
  RViz would show the body) from the mass and inertia an offline bag names in its custom
  data; a live bag without either is refused with a clear error.

The view is from the COM (the body turns about it; a translation of the COM is not
drawn): the shape, the body axes x, y, z (red, green, blue) of a length that reaches past
the shape, the direction of the world angular momentum L (black, fixed for a torque-free
body), and a fading trail of the tip of the body axis that moves most over the bag (the one
that flips, for a T-handle).

Frames are taken at simulated times t0, t0 + speed / fps, ... up to the bag's end: a frame
shows the latest tick at or before its time.  Writers: Pillow for GIF (a palette per frame,
each frame shown 1 / fps s), matplotlib's ffmpeg writer for MP4 when ffmpeg is installed.
A GIF above the size budget is scaled down (whole frames, to within the budget) rather than
written too large.
"""

import io
import math
from pathlib import Path

import numpy as np

# The bag reading (rosbags) is imported where it is used: the command line builds this
# tool's options from the defaults below at every start.

__all__ = ['Animation', 'AnimationPlan', 'animate_bag', 'prepare_animation',
           'render_animation', 'plan_frames', 'BodyShape', 'BodyView', 'read_shape',
           'shape_from_marker', 'trail_axis', 'axis_endpoints', 'DEFAULT_FPS',
           'DEFAULT_SPEED', 'DEFAULT_MAX_BYTES']

DEFAULT_FPS = 10.0
DEFAULT_SPEED = 1.0
DEFAULT_MAX_BYTES = 4 * 1024 * 1024
FORMATS = ('.gif', '.mp4')
_MARKER = 'visualization_msgs/msg/Marker'
# visualization_msgs/Marker's type constants.
_CUBE, _SPHERE, _CYLINDER = 1, 2, 3
_SHAPE_NAMES = {_CUBE: 'box', _SPHERE: 'ellipsoid', _CYLINDER: 'cylinder'}
_AXIS_COLOURS = ('tab:red', 'tab:green', 'tab:blue')
# Frames of trail behind the current one, and its alpha at the head.
_TRAIL_FRAMES = 45


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

    def __init__(self, kind, scale, orientation, colour, origin):
        self.kind = kind
        self.scale = np.asarray(scale, dtype=float)
        self.orientation = np.asarray(orientation, dtype=float)
        self.colour = tuple(colour)
        self.origin = origin

    def faces(self):
        """Return the surface as a list of polygons (k, 3) in the body frame, m."""
        half = 0.5 * self.scale
        if self.kind == 'box':
            polygons = _box_faces(half)
        elif self.kind == 'cylinder':
            polygons = _cylinder_faces(half[0], half[1], half[2])
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


def _quaternion_matrix(quaternion):
    x, y, z, w = quaternion / np.linalg.norm(quaternion)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _first_marker(bag, namespace):
    """Return (stamp ns, Marker message) of the bag's first marker, or None if it has none."""
    from rosbags.rosbag2 import Reader

    from .bag_writer import typestore
    store = typestore()
    wanted = f'{namespace}/marker'
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.msgtype == _MARKER and (
            c.topic == wanted or c.topic.endswith('/marker'))]
        if not connections:
            return None
        for connection, _, raw in reader.messages(connections=connections[:1]):
            message = store.deserialize_cdr(raw, connection.msgtype)
            stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
            return stamp, message
    return None


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
    marker_rotation = _quaternion_matrix(np.array(
        [orientation.x, orientation.y, orientation.z, orientation.w]))
    body_rotation = _quaternion_matrix(np.asarray(body_quaternion, dtype=float))
    colour = (marker.color.r, marker.color.g, marker.color.b, marker.color.a or 1.0)
    return BodyShape(_SHAPE_NAMES[marker.type],
                     (marker.scale.x, marker.scale.y, marker.scale.z),
                     body_rotation.T @ marker_rotation, colour,
                     'marker: inertia-equivalent box' if equivalent else 'marker')


def _is_equivalent_box(shape, mass, inertia):
    """Return True if a box marker has the edges of the body's inertia-equivalent box."""
    if shape.kind != 'box' or mass is None or inertia is None:
        return False
    from ..messages.marker import inertia_equivalent_box
    from ..physics import RigidBody
    edges, _ = inertia_equivalent_box(RigidBody(mass, inertia))
    # The two longest edges decide: a lamina's zero edge is drawn as a thin slab.
    drawn = np.sort(shape.scale)[1:]
    return bool(np.allclose(drawn, np.sort(edges)[1:], rtol=1e-6, atol=0.0))


def read_shape(bag, motion, namespace=''):
    """
    Return the :class:`BodyShape` to draw for a bag: its marker's, or the inertia box.

    A box marker with the edges of the inertia-equivalent box of the mass and inertia an
    offline bag names is labelled as that stand-in (the node draws a body given by its
    inertia alone so).

    Raises
    ------
    ValueError
        If the bag has no marker and does not name the body's mass and inertia.

    """
    first = _first_marker(Path(bag), (namespace or '').rstrip('/'))
    if first is not None:
        stamp, marker = first
        index = int(np.searchsorted(motion.stamps, stamp))
        index = min(index, len(motion.stamps) - 1)
        try:
            shape = shape_from_marker(marker, motion.quaternion[index])
        except ValueError as error:
            raise ValueError(f'{bag}: {error}') from None
        if _is_equivalent_box(shape, motion.mass, motion.inertia):
            shape.origin = 'marker: inertia-equivalent box'
        return shape
    mass, inertia = motion.mass, motion.inertia
    if mass is None or inertia is None:
        raise ValueError(f'{bag}: no marker topic, and the bag does not name the mass and '
                         'inertia of the body (a live recording): record the marker topic '
                         'of the node too, or use a bag of rigid-body-sim simulate')
    from ..messages.marker import inertia_equivalent_box
    from ..physics import RigidBody
    edges, axes = inertia_equivalent_box(RigidBody(mass, inertia))
    # A lamina's zero edge would not show: keep it a thin slab, as the node's marker does.
    edges = np.maximum(edges, 0.02 * edges.max())
    return BodyShape('box', edges, axes, (0.55, 0.6, 0.75, 1.0), 'inertia-equivalent box')


class AnimationPlan:
    """
    Which tick each frame shows.

    Attributes
    ----------
    indices : ndarray (frames,) of int
        Index into the motion's ticks of each frame: the latest tick at or before the
        frame's time.
    times : ndarray (frames,)
        Simulated time of each frame, s.
    fps : float
        Frames per second of the output.
    speed : float
        Simulated seconds per second of the output.

    """

    def __init__(self, indices, times, fps, speed):
        self.indices = indices
        self.times = times
        self.fps = fps
        self.speed = speed

    @property
    def frames(self):
        """Get the number of frames."""
        return len(self.indices)

    @property
    def duration(self):
        """Get the playing time in s (frames / fps)."""
        return self.frames / self.fps


def plan_frames(time, fps=DEFAULT_FPS, speed=DEFAULT_SPEED):
    """
    Return the :class:`AnimationPlan` for ticks at simulated `time` (s, ascending).

    Frame k is at t0 + k speed / fps, for every such time up to the last tick (a tolerance
    of a microsecond absorbs the rounding of the times).
    """
    if not (math.isfinite(fps) and fps > 0.0):
        raise ValueError(f'--fps must be a number > 0; got {fps:g}')
    if not (math.isfinite(speed) and speed > 0.0):
        raise ValueError(f'--speed must be a number > 0; got {speed:g}')
    time = np.asarray(time, dtype=float)
    interval = speed / fps
    count = int(math.floor((time[-1] - time[0]) / interval + 1e-6)) + 1
    times = time[0] + interval * np.arange(count)
    indices = np.searchsorted(time, times + 1e-6, side='right') - 1
    return AnimationPlan(np.clip(indices, 0, len(time) - 1), times, float(fps), float(speed))


def axis_endpoints(quaternion, length):
    """Return the tips (3, 3) of the body axes x, y, z (rows) of length m, world frame."""
    return length * _quaternion_matrix(np.asarray(quaternion, dtype=float)).T


def trail_axis(quaternions):
    """Return the body axis (0, 1, 2) whose world direction varies most over the motion."""
    rotations = np.array([_quaternion_matrix(q) for q in quaternions[::max(1, len(
        quaternions) // 400)]])
    # Column i of R is body axis i in the world; its spread is 1 - |mean direction|.
    return int(np.argmax(1.0 - np.linalg.norm(rotations.mean(axis=0), axis=0)))


class BodyView:
    """
    The body drawn in a 3D matplotlib axes, viewed from its COM, updated in place.

    Draws the shape, the body axes x, y, z (red, green, blue) reaching past the shape, the
    direction of the world angular momentum L (dashed black) and a fading trail of the tip
    of one body axis.  ``rigid-body-sim animate`` draws each frame with it, and
    ``rigid-body-sim watch`` its live window.

    Parameters
    ----------
    axes : mpl_toolkits.mplot3d.Axes3D
        Where to draw; its limits, projection and view are set here.
    shape : BodyShape
        The shape, in the body frame.
    trail_axis : int
        The body axis (0, 1, 2) whose tip leaves the trail.
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
                           for colour, name in zip(_AXIS_COLOURS, 'xyz')]
        self.momentum_line = axes.plot([0, 0], [0, 0], [0, 0], color='black',
                                       linewidth=1.5, linestyle='--',
                                       label='L (world)')[0]
        self.trail_axis = trail_axis
        self.trail = Line3DCollection([np.zeros((2, 3))], colors=_AXIS_COLOURS[trail_axis],
                                      linewidths=1.2)
        axes.add_collection3d(self.trail, autolim=False)
        self.trail_points = []

    def show(self, quaternion, angular_momentum):
        """Draw the body at `quaternion` (x, y, z, w) with L (world frame); extend the trail."""
        rotation = _quaternion_matrix(np.asarray(quaternion, dtype=float))
        self.polygons.set_verts([face @ rotation.T for face in self.body_faces])
        tips = axis_endpoints(quaternion, self.axis_length)
        for line, tip in zip(self.axis_lines, tips):
            line.set_data_3d([0.0, tip[0]], [0.0, tip[1]], [0.0, tip[2]])
        momentum = np.asarray(angular_momentum, dtype=float)
        size = np.linalg.norm(momentum)
        direction = momentum / size * self.axis_length if size > 0.0 else np.zeros(3)
        self.momentum_line.set_data_3d([0.0, direction[0]], [0.0, direction[1]],
                                       [0.0, direction[2]])
        self.trail_points.append(tips[self.trail_axis])
        del self.trail_points[:-_TRAIL_FRAMES]
        points = np.array(self.trail_points)
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


class _Scene3D:
    """The matplotlib figure of one animation frame, updated in place from frame to frame."""

    def __init__(self, shape, motion, title, pixels):
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt

        self.motion = motion
        dpi = 100
        self.figure = plt.figure(figsize=(pixels / dpi, pixels / dpi), dpi=dpi)
        self.axes = self.figure.add_subplot(projection='3d')
        self.view = BodyView(self.axes, shape, trail_axis(motion.quaternion))
        self.axis_lines = self.view.axis_lines
        self.axis_length = self.view.axis_length
        self.axes.legend(loc='upper left', fontsize=6, frameon=False)
        self.title = title
        self.text = self.figure.text(0.02, 0.02, '', fontsize=7)

    def draw(self, index, time):
        """Show tick `index` (its orientation and L) at simulated `time` s."""
        size = self.view.show(self.motion.quaternion[index],
                              self.motion.angular_momentum[index])
        self.axes.set_title(self.title, fontsize=8)
        self.text.set_text(f't = {time:6.2f} s   |L| = {size:.4g} kg m²/s')

    def image(self):
        """Return the rendered frame as an RGB picture (Pillow)."""
        from PIL import Image
        self.figure.canvas.draw()
        return Image.frombuffer('RGBA', self.figure.canvas.get_width_height(),
                                self.figure.canvas.buffer_rgba()).convert('RGB')

    def close(self):
        """Release the figure."""
        import matplotlib.pyplot as plt
        plt.close(self.figure)


def _title(motion, shape):
    scene = motion.custom('scene')
    integrator = motion.custom('integrator')
    parts = [f'scene {scene}' if scene else motion.name]
    if integrator:
        parts.append(integrator)
    # What the body is drawn as is in the legend (its shape, or a stand-in).
    return ', '.join(parts) + ', viewed from the COM'


def _gif_bytes(images, fps):
    buffer = io.BytesIO()
    # GIF delays are in hundredths of a second: Pillow rounds 1000 / fps ms to that.
    images[0].save(buffer, format='GIF', save_all=True, append_images=images[1:],
                   duration=1000.0 / fps, loop=0, optimize=False, disposal=1)
    return buffer.getvalue()


def _palette(image):
    from PIL import Image
    # Octree keeps the few saturated colours (the axes) that median cut merges away.
    return image.quantize(colors=64, method=Image.Quantize.FASTOCTREE,
                          dither=Image.Dither.NONE)


class Animation:
    """An animation checked and ready to render: output, motion, frames, shape, budget."""

    def __init__(self, out, motion, plan, shape, max_bytes):
        self.out = out
        self.motion = motion
        self.plan = plan
        self.shape = shape
        self.max_bytes = max_bytes


def prepare_animation(bag, out=None, fps=DEFAULT_FPS, speed=DEFAULT_SPEED, namespace='',
                      max_bytes=DEFAULT_MAX_BYTES):
    """
    Check the options and read the bag; return an :class:`Animation` (nothing written yet).

    Parameters
    ----------
    bag : str or Path
        Bag directory with the node's odom and angular_momentum topics (and marker).
    out : str or Path, optional
        Output file, .gif or .mp4 (default: <bag>.gif beside the bag).
    fps, speed : float
        Frames per second of the output; simulated seconds per second of the output.
    namespace : str
        The node's namespace in the bag.
    max_bytes : int
        Size budget of a GIF: frames are scaled down until it fits.

    Raises
    ------
    ValueError
        Bad options, an unreadable bag or one without the topics, MP4 without ffmpeg.

    """
    from .plot import read_motion

    bag = Path(bag)
    out = Path(out) if out is not None else bag.with_name(bag.name + '.gif')
    suffix = out.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f'--out must end in .gif or .mp4; got {out.name!r}')
    if not (isinstance(max_bytes, int) and max_bytes >= 16 * 1024):
        raise ValueError(f'the size budget must be at least 16 KiB; got {max_bytes} bytes')
    if suffix == '.mp4':
        from matplotlib.animation import FFMpegWriter
        if not FFMpegWriter.isAvailable():
            raise ValueError('MP4 needs ffmpeg, which is not installed (apt install ffmpeg); '
                             'write a GIF instead: --out FILE.gif')
    motion = read_motion(bag, namespace)
    plan = plan_frames(motion.time, fps, speed)
    shape = read_shape(bag, motion, namespace)
    return Animation(out, motion, plan, shape, max_bytes)


def render_animation(animation, pixels=400, progress=None):
    """
    Render a prepared :class:`Animation` into its file; return the bytes written.

    progress(frames_done) is called after each rendered frame.
    """
    out, plan, motion, shape = animation.out, animation.plan, animation.motion, animation.shape
    scene = _Scene3D(shape, motion, _title(motion, shape), pixels)
    try:
        if out.suffix.lower() == '.mp4':
            from matplotlib.animation import FFMpegWriter
            writer = FFMpegWriter(fps=plan.fps)
            with writer.saving(scene.figure, str(out), dpi=100):
                for done, (index, time) in enumerate(zip(plan.indices, plan.times), 1):
                    scene.draw(index, time)
                    writer.grab_frame()
                    if progress is not None:
                        progress(done)
            return out.stat().st_size
        images = []
        for done, (index, time) in enumerate(zip(plan.indices, plan.times), 1):
            scene.draw(index, time)
            images.append(_palette(scene.image()))
            if progress is not None:
                progress(done)
    finally:
        scene.close()
    data = _gif_bytes(images, plan.fps)
    while len(data) > animation.max_bytes:
        # The size goes with the pixel count: shrink both sides by the square root of the
        # excess, and a little more so one round usually suffices.
        factor = 0.95 * math.sqrt(animation.max_bytes / len(data))
        width, height = images[0].size
        size = (max(64, int(width * factor)), max(64, int(height * factor)))
        if size == images[0].size:
            raise ValueError(f'the animation does not fit in {animation.max_bytes} bytes '
                             f'even at {size[0]} pixels: lower --fps, raise --speed or the '
                             'budget')
        images = [_palette(image.convert('RGB').resize(size)) for image in images]
        data = _gif_bytes(images, plan.fps)
    out.write_bytes(data)
    return len(data)


def animate_bag(bag, out=None, fps=DEFAULT_FPS, speed=DEFAULT_SPEED, namespace='',
                max_bytes=DEFAULT_MAX_BYTES, pixels=400, progress=None):
    """
    Render the bag's body into a GIF or MP4; return (path, AnimationPlan, bytes written).

    See :func:`prepare_animation` for the arguments and errors, :func:`render_animation`
    for `pixels` and `progress`.
    """
    animation = prepare_animation(bag, out, fps, speed, namespace, max_bytes)
    size = render_animation(animation, pixels, progress)
    return animation.out, animation.plan, size

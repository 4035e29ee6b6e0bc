"""
Animate the body recorded in a bag: its shape turning, its axes, L, and a trail.

What is drawn comes from the node's topics alone, so any bag of the node works:

- ``odom``: the orientation R (body to world) of each tick; ``angular_momentum``: L about
  the COM, world frame (read with :func:`.motion.read_motion`, paired by stamp);
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
body), and a fading trail of the tip of the middle principal axis, the one that flips (of
the inertia an offline bag names, or that a live bag's motion shows: L = I Omega), drawn
through every tick between frames so a fast spin stays a smooth curve; the legend names it.

Frames are taken at simulated times t0, t0 + speed / fps, ... up to the bag's end: a frame
shows the latest tick at or before its time.  Writers: Pillow for GIF (a palette per frame,
each frame shown 1 / fps s), matplotlib's ffmpeg writer for MP4 when ffmpeg is installed.
A GIF above the size budget is scaled down (whole frames, to within the budget) rather than
written too large.

A bag of several bodies is drawn in one scene by :mod:`.animate_bodies`, or one of its
bodies (``body``) as here, its shape from its marker in the array ``markers``.
"""

from dataclasses import dataclass
import io
import math
from pathlib import Path

import numpy as np

from .frame_plan import AnimationPlan
from .frame_plan import DEFAULT_FPS
from .frame_plan import DEFAULT_SPEED
from .frame_plan import figure_image
from .frame_plan import plan_frames

# The bag reading (rosbags) and the drawing (message types) are imported where they are
# used: the command line builds this tool's options from the defaults below at every start.

__all__ = ['Animation', 'AnimationPlan', 'animate_bag', 'prepare_animation',
           'render_animation', 'plan_frames', 'read_shape', 'read_trail_axis', 'DEFAULT_FPS',
           'DEFAULT_SPEED', 'DEFAULT_MAX_BYTES']

DEFAULT_MAX_BYTES = 4 * 1024 * 1024
FORMATS = ('.gif', '.mp4')
_MARKER = 'visualization_msgs/msg/Marker'


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


def read_shape(bag, motion, namespace=''):
    """
    Return the BodyShape to draw for a bag: its marker's, or the inertia box.

    The marker of one body of a bag of bodies (`motion.body`) is its marker in the array
    ``markers`` (``ns`` its name).

    A box marker with the edges of the inertia-equivalent box of the mass and inertia an
    offline bag names is labelled as that stand-in (the node draws a body given by its
    inertia alone so), unless the bag says the scene gave the body a shape (a box body is
    its own equivalent box).

    Raises
    ------
    ValueError
        If the bag has no marker and does not name the body's mass and inertia.

    """
    from ..drawing import equivalent_box_shape
    from ..drawing import is_equivalent_box
    from ..drawing import shape_from_marker

    if motion.body is not None:
        from .marker_arrays import first_markers
        found = first_markers(Path(bag), namespace)
        marker = None if found is None else found[1].get(motion.body)
        first = None if marker is None else (found[0], marker)
    else:
        first = _first_marker(Path(bag), (namespace or '').rstrip('/'))
    if first is not None:
        stamp, marker = first
        index = int(np.searchsorted(motion.stamps, stamp))
        index = min(index, len(motion.stamps) - 1)
        try:
            shape = shape_from_marker(marker, motion.quaternion[index])
        except ValueError as error:
            raise ValueError(f'{bag}: {error}') from None
        # A box body's own box has the moments of its equivalent box too: the bag's word on
        # the body's shape decides (an older offline bag says nothing: the edges do).
        given_by_inertia = motion.body_shape in ('', None)
        if given_by_inertia and is_equivalent_box(shape, motion.mass, motion.inertia):
            shape.origin = 'marker: inertia-equivalent box'
        return shape
    mass, inertia = motion.mass, motion.inertia
    if mass is None or inertia is None:
        raise ValueError(f'{bag}: no marker topic, and the bag does not name the mass and '
                         'inertia of the body (a live recording): record the marker topic '
                         'of the node too, or use a bag of rigid-body-sim simulate')
    return equivalent_box_shape(mass, inertia)


class _Scene3D:
    """The matplotlib figure of one animation frame, updated in place from frame to frame."""

    def __init__(self, shape, motion, title, pixels):
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt

        from ..drawing import BodyView

        self.motion = motion
        dpi = 100
        self.figure = plt.figure(figsize=(pixels / dpi, pixels / dpi), dpi=dpi)
        self.axes = self.figure.add_subplot(projection='3d')
        self.view = BodyView(self.axes, shape, read_trail_axis(motion))
        self.shown = 0  # the tick of the last frame drawn: the trail runs on from it
        self.axis_lines = self.view.axis_lines
        self.axis_length = self.view.axis_length
        self.axes.legend(loc='upper left', fontsize=6, frameon=False)
        self.title = title
        self.text = self.figure.text(0.02, 0.02, '', fontsize=7)

    def draw(self, index, time):
        """Show tick `index` (its orientation and L) at simulated `time` s."""
        from ..drawing import trail_points

        # Every tick since the last frame, its last point included, so the trail is joined.
        start = min(self.shown, index)
        trail = trail_points(self.motion.rotation[start:index + 1],
                             self.view.trail_axis.direction)
        self.shown = index
        size = self.view.show(self.motion.quaternion[index],
                              self.motion.angular_momentum[index], trail)
        self.axes.set_title(self.title, fontsize=8)
        self.text.set_text(f't = {time:6.2f} s   |L| = {size:.4g} kg m²/s')

    def image(self):
        """Return the rendered frame as an RGB picture (Pillow)."""
        return figure_image(self.figure)

    def close(self):
        """Release the figure."""
        import matplotlib.pyplot as plt
        plt.close(self.figure)


def _title(motion, shape):
    scene = motion.custom('scene')
    integrator = motion.custom('integrator')
    parts = [f'scene {scene}' if scene else motion.name]
    if motion.body:
        parts.append(f'body {motion.body}')
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


def read_trail_axis(motion):
    """
    Return the :class:`~rigid_body_sim.drawing.TrailAxis` whose tip the animation trails.

    The middle principal axis, the one that flips (as ``watch`` traces it), of the inertia
    the bag names or its motion shows (:meth:`.motion.BagMotion.inertia_seen`); else the
    body axis whose direction varies most, and the caption says so.
    """
    from ..drawing import middle_axis
    from ..drawing import trail_axis
    from ..drawing import TrailAxis

    inertia = motion.inertia_seen()
    if inertia is not None:
        return middle_axis(inertia)
    index = trail_axis(motion.quaternion)
    return TrailAxis(np.eye(3)[index], f'body {"xyz"[index]}: the axis that moves\nmost '
                                       '(the bag shows no inertia)')


def _palette(image):
    from PIL import Image
    # Octree keeps the few saturated colours (the axes) that median cut merges away.
    return image.quantize(colors=64, method=Image.Quantize.FASTOCTREE,
                          dither=Image.Dither.NONE)


@dataclass(eq=False)
class Animation:
    """An animation checked and ready to render: output, motion, frames, shape, budget."""

    out: Path
    motion: object
    plan: AnimationPlan
    shape: object
    max_bytes: int

    def scene(self, pixels):
        """Return the figure that draws the frames (viewed from the body's COM)."""
        return _Scene3D(self.shape, self.motion, _title(self.motion, self.shape), pixels)


def prepare_animation(bag, out=None, fps=DEFAULT_FPS, speed=DEFAULT_SPEED, namespace='',
                      max_bytes=DEFAULT_MAX_BYTES, body=None):
    """
    Check the options and read the bag; return an :class:`Animation` (nothing written yet).

    A bag of several bodies gives a :class:`.animate_bodies.BodiesAnimation` of all of
    them in one scene, or with `body` an :class:`Animation` of that body alone.

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
    body : str, optional
        In a bag of several bodies, the one to animate (default: all of them).

    Raises
    ------
    ValueError
        Bad options, an unreadable bag or one without the topics, MP4 without ffmpeg, a
        `body` the bag does not hold (or given for a bag of one body).

    """
    from .motion import bag_bodies
    from .motion import read_motion

    bag = Path(bag)
    bodies = bag_bodies(bag, namespace)
    if body is not None:
        bodies.check(bag, body)
    out = Path(out) if out is not None else \
        bag.with_name(bag.name + (f'_{body}' if body else '') + '.gif')
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
    if body is None and bodies.names:
        from .animate_bodies import prepare_bodies_animation
        return prepare_bodies_animation(bag, out, fps, speed, namespace, max_bytes)
    motion = read_motion(bag, namespace, body)
    plan = plan_frames(motion.time, fps, speed)
    shape = read_shape(bag, motion, namespace)
    return Animation(out, motion, plan, shape, max_bytes)


def render_animation(animation, pixels=400, progress=None):
    """
    Render a prepared :class:`Animation` (or BodiesAnimation) into its file; return bytes.

    progress(frames_done) is called after each rendered frame.
    """
    out, plan = animation.out, animation.plan
    scene = animation.scene(pixels)
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
                max_bytes=DEFAULT_MAX_BYTES, pixels=400, progress=None, body=None):
    """
    Render the bag's body into a GIF or MP4; return (path, AnimationPlan, bytes written).

    See :func:`prepare_animation` for the arguments and errors, :func:`render_animation`
    for `pixels` and `progress`.
    """
    animation = prepare_animation(bag, out, fps, speed, namespace, max_bytes, body)
    size = render_animation(animation, pixels, progress)
    return animation.out, animation.plan, size

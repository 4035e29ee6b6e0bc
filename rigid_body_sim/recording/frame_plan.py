"""
The frames of an animation: which tick of a bag each frame shows (``animate``).

Frames are taken at simulated times t0, t0 + speed / fps, ... up to the bag's last tick, each
showing the latest tick at or before its time; :mod:`.animate` (one body) and
:mod:`.animate_bodies` (several) draw them.
"""

from dataclasses import dataclass
import math

import numpy as np

__all__ = ['AnimationPlan', 'DEFAULT_FPS', 'DEFAULT_SPEED', 'figure_image', 'plan_frames']

DEFAULT_FPS = 10.0
DEFAULT_SPEED = 1.0


@dataclass(eq=False)
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

    indices: np.ndarray
    times: np.ndarray
    fps: float
    speed: float

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


def figure_image(figure):
    """Return a matplotlib figure rendered as an RGB picture (Pillow)."""
    from PIL import Image
    figure.canvas.draw()
    return Image.frombuffer('RGBA', figure.canvas.get_width_height(),
                            figure.canvas.buffer_rgba()).convert('RGB')

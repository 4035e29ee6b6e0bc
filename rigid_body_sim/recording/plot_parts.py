"""
Parts of the figures of ``plot``, of one body (:mod:`.plot`) and of several (:mod:`.plot_bodies`).

The time axis's label, titles wrapped, 3-D axes with equal scales and few ticks, the
coordinate plane a path lies in, and a thrown body's apex.
"""

import numpy as np

__all__ = ['apex_index', 'equal_3d', 'matplotlib_ticker', 'plane_of_motion', 'tidy_3d',
           'time_axis_label', 'wrapped_title']


def time_axis_label(motion):
    """Return the time axis's label: simulated time, and how it was told, or wall time."""
    if motion.timed_by_reports:
        return "simulated time [s] (live bag: timed by the node's /diagnostics reports)"
    if motion.time_is_simulated:
        return 'simulated time [s]'
    spacing = motion.stamp_spacing
    irregular = '' if spacing is None else \
        f': stamps {1e3 * spacing[0]:.2g}-{1e3 * spacing[1]:.2g} ms apart, as received'
    return f'wall-clock time since the first message [s]{irregular}'


def matplotlib_ticker():
    """Return matplotlib.ticker (imported with matplotlib, after the Agg backend is set)."""
    from matplotlib import ticker
    return ticker


def wrapped_title(title, width=70):
    """Break a title over two lines at a space near `width` characters (mathtext kept)."""
    if len(title) <= width:
        return title
    cut = title.rfind(' ', 0, width)
    while cut > 0 and title[:cut].count('$') % 2:
        cut = title.rfind(' ', 0, cut)
    return title if cut <= 0 else title[:cut] + '\n' + title[cut + 1:]


def tidy_3d(axes, ticks=4):
    """Few ticks, small labels, no offset text: 3D tick labels otherwise collide."""
    ticker = matplotlib_ticker()
    for axis in (axes.xaxis, axes.yaxis, axes.zaxis):
        axis.set_major_locator(ticker.MaxNLocator(ticks))
        formatter = ticker.ScalarFormatter(useOffset=False)
        axis.set_major_formatter(formatter)
    axes.tick_params(labelsize='small', pad=0)


def plane_of_motion(position):
    """
    Return (first, second, normal) axis indices of the coordinate plane the COM moves in.

    The plane normal to the axis along which the path spans least: x-z for a throw along x,
    x-y for a top's COM circling above its pivot.  `position` is (n, 3), world frame.
    """
    normal = int(np.argmin(np.ptp(position, axis=0)))
    first, second = [k for k in range(3) if k != normal]
    return first, second, normal


def apex_index(motion):
    """
    Return the tick of a thrown body's apex (its highest COM, world z), or None.

    None when the highest point is the first or last tick (no apex inside the bag) or the
    body is held by a pivot (its COM bobs up and down, with no single apex).
    """
    height = motion.position[:, 2]
    apex = int(np.argmax(height))
    held = any(effect['effect'] == 'pivot' for effect in (motion.effects or []))
    return apex if 0 < apex < len(height) - 1 and not held else None


def equal_3d(axes, points):
    """Give the 3D axes equal scales around the points' bounding box."""
    low, high = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (low + high)
    half = 0.5 * max(float((high - low).max()), 1e-12)
    axes.set_xlim(centre[0] - half, centre[0] + half)
    axes.set_ylim(centre[1] - half, centre[1] + half)
    axes.set_zlim(centre[2] - half, centre[2] + half)
    axes.set_box_aspect((1.0, 1.0, 1.0))

"""
Plot the motion recorded in a bag, and the quantities the physics conserves in it.

The motion, its time axis and what its scene conserves come from :mod:`.motion`.

The figure (matplotlib, Agg backend) has four panels: Omega's components against time (one
spinning many times faster than the others on an axis of its own; a component oscillating
too fast for the pixels as its envelope); the drift of the conserved quantities; the
orientation as the paths the tips of the body axes trace on the unit sphere (until the
busiest has gone round four times; an axis spinning many times faster than the others,
such as a top's, shows only its ends); and when the COM moves its path in the plane it
moves in (with equal scales) and its height z(t) with the apex, else the polhode (the path
of Omega in the body frame).
"""

from pathlib import Path

import numpy as np

from .motion import bag_bodies
from .motion import conserved_quantities
from .motion import read_motion
from .plot_parts import apex_index
from .plot_parts import equal_3d
from .plot_parts import matplotlib_ticker
from .plot_parts import plane_of_motion
from .plot_parts import tidy_3d
from .plot_parts import time_axis_label
from .plot_parts import wrapped_title
from ..drawing import AXIS_COLOURS
from ..drawing import middle_axis

__all__ = [
    'apex_index',
    'com_moves',
    'oscillations',
    'plane_of_motion',
    'plot_bag',
    'plot_motion',
]

# The COM "moves" when its path spans more than this (m): below, it is at rest up to
# round-off and its panel shows the polhode instead.
_MOTION_THRESHOLD = 1e-9
# An axis whose tip travels more than this many turns, and 20 times as far as the slowest
# axis, spins: its path would cover the sphere.
_FAST_TURNS = 10
# Turns of the busiest drawn axis shown on the sphere.
_DRAWN_TURNS = 4
# Points per 3D path: more only slow the drawing down, the lines look the same.
_PATH_POINTS = 6000
# A time series with more oscillations than this over the panel's ~600 pixel columns
# fills its band nearly solid (a cycle in fewer than ~15 columns, two lines each): it is
# drawn as its envelope.
_ENVELOPE_CYCLES = 40
# Above this many oscillations a line is drawn thin, so neighbouring cycles stay apart.
_THIN_CYCLES = 10
# Points of an envelope: about the panel's width in pixels.
_ENVELOPE_BINS = 500


def oscillations(values):
    """
    Return how many times `values` swings across the middle of its range, halved (cycles).

    A swing counts when the series goes from below 30% of its range to above 70% or back
    (a Schmitt trigger), so round-off and small ripples do not count; a series constant to
    1e-9 of its size has none.
    """
    values = np.asarray(values, dtype=float)
    low, high = float(values.min()), float(values.max())
    if high - low <= 1e-9 * max(abs(low), abs(high), 1e-300):
        return 0.0
    level = (values - low) / (high - low)
    state = np.full(values.shape, np.nan)
    state[level < 0.3] = 0.0
    state[level > 0.7] = 1.0
    known = state[~np.isnan(state)]
    return float(np.count_nonzero(np.diff(known))) / 2.0


def _draw_series(axes, time, values, color, label, linestyle='-'):
    """
    Draw a time series: a line, thin when it oscillates fast, an envelope when faster.

    The envelope (light fill between the running extremes) gets its running mean as a
    line, so the slow motion under a fast oscillation reads at a glance.
    """
    cycles = max(oscillations(values), oscillations(_detrended(time, values)))
    if cycles <= _ENVELOPE_CYCLES:
        width = 0.6 if cycles > _THIN_CYCLES else 1.5
        return axes.plot(time, values, color=color, linewidth=width, label=label,
                         linestyle=linestyle)[0]
    # The envelope: the running minimum and maximum over three mean periods, so every
    # window holds whole cycles' extremes (and a beat of two frequencies does not make the
    # edges flicker); then one point per pixel column.
    window = int(np.ceil(3.0 * len(values) / cycles))
    # Reflected at the ends: a series starting at an extreme keeps its mean honest there.
    upper = _running_extreme(values, window, np.maximum)
    lower = _running_extreme(values, window, np.minimum)
    mean = _running_mean(values, window)
    stride = max(1, len(values) // _ENVELOPE_BINS)
    picked = np.r_[np.arange(0, len(values), stride), len(values) - 1]
    period = (time[-1] - time[0]) / cycles
    # Light fill and thin edges: two overlapping envelopes stay apart; the mean is the line.
    for edge in (lower, upper):
        axes.plot(time[picked], edge[picked], color=color, linewidth=0.6, alpha=0.7)
    axes.fill_between(time[picked], lower[picked], upper[picked], color=color, alpha=0.12,
                      linewidth=0.0)
    # The mean only where its window is whole: at the ends it would lean to one side.
    half = window // 2
    picked = picked[(picked >= half) & (picked < len(values) - half)]
    return axes.plot(time[picked], mean[picked], color=color, linewidth=1.5,
                     linestyle=linestyle,
                     label=f'{label}\n({cycles:.0f} cycles of {period:.2g} s: mean; '
                           'envelope shaded)')[0]


def _reflected(values, window):
    """
    Return `values` extended by window - 1 samples for a centred running window.

    window // 2 before and the rest after, mirrored about the ends (d c b a | a b c d |
    d c b a, repeated for a window longer than the series): scipy.ndimage's 'reflect'.
    """
    before = window // 2
    return np.pad(np.asarray(values, dtype=float), (before, window - 1 - before),
                  mode='symmetric')


def _running_extreme(values, window, ufunc):
    """
    Return the running maximum (`ufunc` np.maximum) or minimum (np.minimum) over `window`.

    Centred as scipy.ndimage's maximum_filter1d and minimum_filter1d with mode='reflect'
    (equal to them: test/test_plot_filters.py), in O(n) whatever the window (van Herk,
    Gil and Werman): the extended series cut into blocks of `window`, each window is the
    end of one block (its running extreme from the right) and the start of the next (from
    the left).
    """
    count = len(values)
    padded = _reflected(values, window)
    blocks = -(-len(padded) // window)
    grid = np.full(blocks * window, -np.inf if ufunc is np.maximum else np.inf)
    grid[:len(padded)] = padded
    grid = grid.reshape(blocks, window)
    from_left = ufunc.accumulate(grid, axis=1).ravel()
    from_right = ufunc.accumulate(grid[:, ::-1], axis=1)[:, ::-1].ravel()
    return ufunc(from_right[:count], from_left[window - 1:window - 1 + count])


def _running_mean(values, window):
    """
    Return the running mean over `window`, centred and reflected at the ends.

    scipy.ndimage's uniform_filter1d with mode='reflect', and its arithmetic (the first
    window's sum, then each next sum by adding the sample that enters and subtracting the
    one that leaves, divided by the window): the same doubles, in O(n).
    """
    padded = _reflected(values, window)
    first = np.cumsum(padded[:window])[-1]
    return np.cumsum(np.r_[first, padded[window:] - padded[:-window]]) / window


def _detrended(time, values):
    """
    Return `values` less their straight-line fit, clipped to its 1st..99th percentiles.

    A drift's oscillation around its trend, without the few outliers (a drift starts at
    exactly 0 and jumps to its oscillation's mean at the first step) whose range would hide
    the oscillation from :func:`oscillations`.
    """
    if len(values) < 3 or np.ptp(time) == 0.0:
        return values
    slope, intercept = np.polyfit(time - time[0], values, 1)
    rest = values - (intercept + slope * (time - time[0]))
    return np.clip(rest, *np.percentile(rest, (1.0, 99.0)))


def _legend_above_data(axes, handles=None, row_height=0.065):
    """
    Put the legend in headroom above the data: the y range grows so no curve lies under it.

    Each legend row takes about `row_height` of the axes' height (small font on a panel a
    few hundred pixels tall).
    """
    if handles is None:
        handles = axes.get_legend_handles_labels()[0]
    rows = sum(handle.get_label().count('\n') + 1 for handle in handles)
    fraction = min(0.6, row_height * rows + 0.03)
    low, high = axes.get_ylim()
    axes.set_ylim(low, high + (high - low) * fraction / (1.0 - fraction))
    return axes.legend(handles=handles, loc='upper left', fontsize='small', framealpha=0.9)


def _reference_value(values):
    """
    Return a round value to subtract from a series that varies in its far decimals, or 0.

    150.00000010 .. 150.00000055 reads as 150 + (1.0 .. 5.5) x 10^-7, not as eight-decimal
    tick labels: the reference keeps the digits the whole series shares.
    """
    values = np.asarray(values, dtype=float)
    middle, spread = float(np.mean(values)), float(np.ptp(values))
    if middle == 0.0 or spread >= 1e-3 * abs(middle):
        return 0.0
    # The digits common to the series: its middle rounded to the spread's decade, times 10.
    decade = 10.0 ** np.floor(np.log10(max(spread, 1e-300) * 10.0))
    return float(np.round(middle / decade) * decade)


def _power_of_ten(values):
    """Return k such that values / 10^k reads with a few digits (0 for ordinary sizes)."""
    largest = float(np.max(np.abs(values))) if np.size(values) else 0.0
    if largest == 0.0 or not np.isfinite(largest):
        return 0
    k = int(np.floor(np.log10(largest)))
    return 0 if -2 <= k <= 2 else k


def plot_motion(motion, out):
    """Draw the four panels of `motion` (a :class:`BagMotion`) into the PNG `out`."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot

    figure = pyplot.figure(figsize=(14.0, 11.0), layout='constrained')
    grid = figure.add_gridspec(2, 2)
    time_label = time_axis_label(motion)
    _angular_velocity_panel(figure, grid[0, 0], motion, time_label)
    _conserved_panel(figure.add_subplot(grid[0, 1]), motion, time_label)
    _orientation_panel(figure.add_subplot(grid[1, 0], projection='3d'), motion)
    if com_moves(motion):
        _com_panel(figure, grid[1, 1], motion, time_label)
    else:
        _polhode_panel(figure.add_subplot(grid[1, 1], projection='3d'), motion)
    figure.suptitle(_title(motion))
    out = Path(out)
    figure.savefig(out, dpi=100)
    pyplot.close(figure)
    return out


def _angular_velocity_panel(figure, cell, motion, time_label):
    time = motion.time
    omega = motion.angular_velocity_body
    peaks = np.abs(omega).max(axis=0)
    order = np.argsort(peaks)
    # A fast spin about one axis would flatten the other two components to a line: it
    # gets an axes of its own below, with its own scale.
    dominant = order[2] if peaks[order[2]] > 10.0 * max(peaks[order[1]], 1e-300) else None
    fast = [k for k in range(3) if k != dominant
            and oscillations(omega[:, k]) > _ENVELOPE_CYCLES]
    # Panels: the components (shared time), the dominant spin on its own scale, and a zoom
    # of the first cycles of components too fast for the pixels.
    ratios = (3,) + ((1,) if dominant is not None else ()) + ((1.4,) if fast else ())
    cells = cell.subgridspec(len(ratios), 1, height_ratios=ratios)
    axes = figure.add_subplot(cells[0])
    lower = None if dominant is None else figure.add_subplot(cells[1], sharex=axes)
    zoom = figure.add_subplot(cells[len(ratios) - 1]) if fast else None
    handles = []
    fast = []
    for k, (name, color) in enumerate(zip('xyz', AXIS_COLOURS)):
        label = f'$\\Omega_{name}$'
        if k == dominant:
            # Its own scale; a spin constant to many digits is drawn as its change from a
            # round value named in the label (150 + 1e-7 x ...), not as 150.00000024.
            reference = _reference_value(omega[:, k])
            shown = omega[:, k] - reference
            name_shown = f'$\\Omega_{name}$' + (f' $-$ {reference:g}' if reference else '')
            lower.plot(time, shown, color=color, label=name_shown)
            lower.set_ylabel(f'{name_shown} [rad/s]')
            lower.ticklabel_format(axis='y', style='sci', scilimits=(-2, 3), useOffset=False)
            lower.yaxis.set_major_locator(matplotlib_ticker().MaxNLocator(4))
            lower.set_xlabel(time_label)
            lower.grid(True, alpha=0.3)
            continue
        if oscillations(omega[:, k]) > _ENVELOPE_CYCLES:
            fast.append(k)
            continue
        handles.append(_draw_series(axes, time, omega[:, k], color, label))
    if len(fast) == 2:
        # Two components turning with a fast spin (a top's Omega_x, Omega_y): each alone is
        # a band between +-its amplitude; their magnitude, the rate about a transverse
        # axis, is what changes (nutation), drawn as a series of its own.
        a, b = fast
        names = 'xyz'[a] + 'xyz'[b]
        handles.append(_draw_series(
            axes, time, np.hypot(omega[:, a], omega[:, b]), 'black',
            f'$|\\Omega_{{{names}}}| = \\sqrt{{\\Omega_{names[0]}^2 + '
            f'\\Omega_{names[1]}^2}}$'))
    else:
        for k in fast:
            handles.append(_draw_series(axes, time, omega[:, k], AXIS_COLOURS[k],
                                        f'$\\Omega_{"xyz"[k]}$'))
    title = 'Angular velocity in the body frame'
    if dominant is not None:
        title += f' ($\\Omega_{"xyz"[dominant]}$ below, on its own scale)'
        axes.tick_params(labelbottom=False)
    else:
        axes.set_xlabel(time_label)
    axes.set(title=title, ylabel='$\\Omega$ [rad/s]')
    _legend_above_data(axes, handles)
    axes.grid(True, alpha=0.3)
    if fast:
        _zoom_panel(figure, zoom, time, omega, fast, time_label)


def _zoom_panel(figure, axes, time, omega, fast, time_label):
    """Draw the first few cycles of the fast components as lines: their true shape."""
    cycles = max(oscillations(omega[:, k]) for k in fast)
    span = 4.0 * (time[-1] - time[0]) / cycles
    shown = time <= time[0] + span
    for k in fast:
        axes.plot(time[shown], omega[shown, k], color=AXIS_COLOURS[k], linewidth=1.0,
                  label=f'$\\Omega_{"xyz"[k]}$')
    axes.set(title=f'The first {span:.2g} s of the fast components, every tick',
             xlabel=time_label, ylabel='$\\Omega$ [rad/s]')
    axes.title.set_fontsize('medium')
    axes.grid(True, alpha=0.3)
    axes.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0,
                fontsize='small')


def _conserved_panel(axes, motion, time_label):
    title, quantities = conserved_quantities(motion)
    drifts = [quantity.drift for quantity in quantities]
    k = _power_of_ten(np.concatenate(drifts))
    styles = ('-', '--', '-.')
    colors = ('tab:orange', 'tab:purple', 'tab:cyan')
    for quantity, drift, style, color in zip(quantities, drifts, styles, colors):
        first = quantity.values[0]
        if abs(first) <= 1e-12 * abs(quantity.scale):
            first = 0.0  # round-off of a zero component
        label = (f'{quantity.label}: first {first:.6g} {quantity.unit}; '
                 f'drift / {quantity.scale_label}')
        if not quantity.conserved:
            label += ' (not conserved)'
        _draw_series(axes, motion.time, drift / 10.0**k, color, label, linestyle=style)
    scale = f' [$\\times 10^{{{k}}}$]' if k else ''
    axes.set(title=wrapped_title(title), xlabel=time_label,
             ylabel=f'(X(t) $-$ X(first)) / scale{scale}')
    axes.ticklabel_format(axis='y', style='plain', useOffset=False)
    _legend_above_data(axes)
    axes.grid(True, alpha=0.3)


def _orientation_panel(axes, motion):
    time = motion.time
    _unit_sphere(axes)
    rotation = motion.rotation
    # Distance each axis tip has travelled on the sphere up to each message (rad).
    travelled = np.vstack([np.concatenate(([0.0], np.cumsum(np.linalg.norm(
        np.diff(rotation[:, :, k], axis=0), axis=1)))) for k in range(3)])
    lengths = travelled[:, -1]
    spinning = [lengths[k] > _FAST_TURNS * 2.0 * np.pi and lengths[k] > 20.0 * lengths.min()
                for k in range(3)]
    # The other axes are drawn until one of them has gone round _DRAWN_TURNS times: more
    # loops would only tangle.
    drawn = [k for k in range(3) if not spinning[k]]
    end = len(time)
    if drawn:
        beyond = np.flatnonzero(travelled[drawn].max(axis=0) > _DRAWN_TURNS * 2.0 * np.pi)
        if beyond.size:
            end = int(beyond[0]) + 1
    window_stride = max(1, -(-end // _PATH_POINTS))
    # The axis that flips, named as animate and watch trace it (its inertia named by the
    # bag, or shown by its motion).
    inertia = motion.inertia_seen()
    middle = None if inertia is None else middle_axis(inertia)
    flipping = middle.body_axis if middle is not None and middle.flips else None
    for k, (label, color) in enumerate(zip('xyz', AXIS_COLOURS)):
        tips = rotation[:, :, k]
        if spinning[k]:
            # A fast-spinning axis would paint the whole sphere: only its ends are shown.
            label = f'body {label} axis (spins: {lengths[k] / (2 * np.pi):.0f} turns, ends only)'
            last = tips[-1]
        else:
            path = np.vstack((tips[:end:window_stride], tips[end - 1:end]))
            axes.plot(path[:, 0], path[:, 1], path[:, 2], color=color, linewidth=0.7,
                      alpha=0.85)
            label = f'body {label} axis' + (
                ' (the middle principal axis: it flips)' if k == flipping else '')
            last = tips[end - 1]
        axes.plot([], [], color=color, label=label)
        axes.scatter(*tips[0], color=color, marker='o', s=25)
        axes.scatter(*last, color=color, marker='s', s=25)
    shown = 'o start, \u25a1 end' if end == len(time) else \
        f'o start, \u25a1 at {time[end - 1]:.3g} s: the first {_DRAWN_TURNS} turns'
    axes.set(title=f'Orientation: body axes on the unit sphere\n({shown})',
             xlabel='world x', ylabel='world y', zlabel='world z')
    equal_3d(axes, np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]))
    for set_ticks in (axes.set_xticks, axes.set_yticks, axes.set_zticks):
        set_ticks([-1.0, 0.0, 1.0])
    axes.tick_params(labelsize='small', pad=0)
    axes.legend(loc='upper left', fontsize='small')


def _polhode_panel(axes, motion):
    omega = motion.angular_velocity_body
    stride = max(1, -(-len(omega) // _PATH_POINTS))
    path = np.vstack((omega[::stride], omega[-1:]))
    axes.plot(path[:, 0], path[:, 1], path[:, 2], color='tab:blue', linewidth=0.8)
    axes.scatter(*omega[0], color='tab:green', marker='o', s=30, label='start')
    axes.scatter(*omega[-1], color='tab:red', marker='s', s=30, label='end')
    at = ', '.join(f'{c:.3g}' for c in motion.position[0])
    axes.set(title=f'Polhode: $\\Omega$ in the body frame\n(COM at rest at ({at}) m)',
             xlabel='$\\Omega_x$ [rad/s]', ylabel='$\\Omega_y$ [rad/s]',
             zlabel='$\\Omega_z$ [rad/s]')
    equal_3d(axes, omega)
    tidy_3d(axes)
    axes.legend(loc='upper left', fontsize='small')


def _com_panel(figure, cell, motion, time_label):
    """Draw the COM's path in the plane it moves in (equal scales) and its height z(t)."""
    position = motion.position
    time = motion.time
    cells = cell.subgridspec(1, 2, width_ratios=(1.0, 1.0))
    first, second, normal = plane_of_motion(position)
    names = 'xyz'
    stride = max(1, -(-len(time) // _PATH_POINTS))
    path = np.vstack((position[::stride], position[-1:]))
    axes = figure.add_subplot(cells[0])
    axes.plot(path[:, first], path[:, second], color='tab:blue', linewidth=1.0)
    axes.scatter(position[0, first], position[0, second], color='tab:green', marker='o',
                 s=30, label='start', zorder=3)
    axes.scatter(position[-1, first], position[-1, second], color='tab:red', marker='s',
                 s=30, label='end', zorder=3)
    axes.set_aspect('equal', adjustable='datalim')
    spread = np.ptp(position[:, normal])
    axes.set(title=f'COM path in the {names[first]}-{names[second]} plane\n'
                   f'({names[normal]} spans {spread:.3g} m)',
             xlabel=f'{names[first]} [m]', ylabel=f'{names[second]} [m]')
    axes.legend(loc='upper left', bbox_to_anchor=(0.0, -0.12), ncols=2, borderaxespad=0.0,
                fontsize='small', frameon=False)
    axes.grid(True, alpha=0.3)

    axes = figure.add_subplot(cells[1])
    height = position[:, 2]
    _draw_series(axes, time, height, 'tab:blue', 'z')
    apex = apex_index(motion)
    if apex is not None:
        # A throw's apex: where the vertical velocity changes sign.
        axes.plot(time[apex], height[apex], marker='^', color='tab:red')
        # The label inside the arch, off the curve, with an arrow to the apex.
        axes.annotate(f'apex z = {height[apex]:.4g} m\nat t = {time[apex]:.3g} s',
                      (time[apex], height[apex]), xytext=(0.5, 0.4),
                      textcoords='axes fraction', ha='center', va='center', fontsize='small',
                      arrowprops={'arrowstyle': '->', 'color': '0.4'})
    axes.set(title='COM height', xlabel=time_label, ylabel='z [m]')
    if oscillations(height) > _ENVELOPE_CYCLES:
        _legend_above_data(axes)
    axes.ticklabel_format(axis='y', style='plain', useOffset=False)
    axes.grid(True, alpha=0.3)


def com_moves(motion):
    """Return True if the COM path spans more than round-off (1e-9 m) in the bag."""
    return bool(np.ptp(motion.position, axis=0).max() > _MOTION_THRESHOLD)


def _title(motion):
    custom = {key: motion.custom(key) for key in ('scene', 'integrator', 'rate', 'effects')
              if motion.custom(key) is not None}
    span = f'{len(motion.time)} ticks to {motion.time[-1]:g} s' if motion.time_is_simulated \
        else f'{len(motion.time)} ticks over {motion.time[-1]:g} s'
    parts = [f'bag {motion.name}'] + ([f'body {motion.body}'] if motion.body else []) + [span]
    if 'scene' in custom:
        parts.append(f'scene {custom["scene"]}')
    if 'integrator' in custom:
        rate = custom.get('rate')
        parts.append(f'{custom["integrator"]}' + (f' at {float(rate):g} Hz' if rate else ''))
    if 'effects' in custom:
        parts.append(f'effects: {custom["effects"]}')
    return ' \u2014 '.join(parts)


def _unit_sphere(axes):
    u = np.linspace(0.0, 2.0 * np.pi, 37)
    v = np.linspace(0.0, np.pi, 19)
    axes.plot_wireframe(np.outer(np.cos(u), np.sin(v)), np.outer(np.sin(u), np.sin(v)),
                        np.outer(np.ones_like(u), np.cos(v)), color='0.88', linewidth=0.3)


def plot_bag(bag, out=None, namespace='', body=None):
    """
    Read a bag and plot it; return the PNG path (default ``<bag>.png`` beside it).

    A bag of several bodies is drawn as :mod:`.plot_bodies` draws them, or, with `body`,
    that body as a bag of one body is (default PNG ``<bag>_<body>.png``).

    Raises
    ------
    ValueError
        As :func:`.motion.read_motion`: an unreadable bag, one without the topics, a
        `body` the bag does not hold (or given for a bag of one body).

    """
    bag = Path(bag)
    bodies = bag_bodies(bag, namespace)
    if body is not None:
        bodies.check(bag, body)
    if out is None:
        out = bag.with_name(bag.name + (f'_{body}' if body else '') + '.png')
    if body is None and bodies.names:
        from .plot_bodies import plot_bodies
        return plot_bodies(bag, out, namespace)
    return plot_motion(read_motion(bag, namespace, body), out)

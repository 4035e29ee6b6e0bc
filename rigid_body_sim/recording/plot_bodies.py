"""
Plot the bodies of a bag of several bodies in one figure; one of them with ``--body``.

A scene of ``bodies:`` (``juggling_clubs``, ``debris_field``, ``constellation``) gives
each body its topics under its name and the bag's custom data each body's mass, inertia
and effects (:mod:`.motion`).  ``plot --body NAME`` draws that body as a bag of one body
is drawn (:mod:`.plot`), with what it conserves from its own effects.  Without it the
figure has four panels over all the bodies drawn:

- the COM paths in 3-D (world frame, m, equal scales), each from its start (o); for a few
  bodies with markers, each body's longest drawn axis every tenth of the run (a
  stroboscope of its tumbling); when no COM moves, the bodies' positions;
- the drift of what each body conserves (:func:`.motion.conserved_quantities`), as its
  largest size so far, |X(t') - X(first)| / scale over t' <= t, on a log scale: a hundred
  bodies' drifts stay apart over decades, and a drift exactly zero (buss keeps a
  torque-free body's L to the bit) is said in the legend instead of drawn;
- |Omega| (rad/s) of each body against time;
- each body's largest drift over the run: by name for a few bodies, against |Omega(0)|
  for many (a faster tumbler takes larger rotations per step), the worst named.

Up to :data:`NAMED_BODIES` bodies are coloured as their markers (or a colour cycle) and
named in a legend; more are coloured by |Omega(0)| on one colour bar.  At most
:data:`MOST_BODIES` are read and drawn (every k-th in the scene's order, so a scene laid
out in groups shows each), and the title says how many of how many.
"""

from pathlib import Path

import numpy as np

from .marker_arrays import first_markers
from .motion import bag_bodies
from .motion import conserved_quantities
from .motion import read_body_motions
from .plot_parts import apex_index
from .plot_parts import equal_3d
from .plot_parts import plane_of_motion
from .plot_parts import tidy_3d
from .plot_parts import time_axis_label
from .plot_parts import wrapped_title

__all__ = ['MOST_BODIES', 'NAMED_BODIES', 'drawn_bodies', 'plot_bodies', 'plot_body_motions']

NAMED_BODIES = 10
"""Up to this many bodies are named in a legend; more are coloured by |Omega(0)|."""
MOST_BODIES = 100
"""At most this many bodies are read and drawn (every k-th in the scene's order)."""
# Points per body's path and series: a hundred bodies of 6000 points each would only slow
# the drawing; a path of 600 looks the same at the panel's size.
_POINTS_PER_BODY = 600
# Instants of the stroboscope of each body's longest axis.
_STROBE_INSTANTS = 11
# Two marker colours closer than this (RGB distance) would not tell bodies apart.
_DISTINCT_COLOURS = 0.25
# The COM "moves" when a path spans more than this (m), as in .plot.
_MOTION_THRESHOLD = 1e-9
# Paths spanning less than this fraction of their largest span across a coordinate plane are
# drawn in that plane.
_FLAT = 0.05
_QUANTITY_STYLES = ('-', '--', ':')
_QUANTITY_MARKERS = ('o', 's', '^')


def plot_bodies(bag, out, namespace='', most=MOST_BODIES):
    """
    Read the bodies of a bag of bodies (the first `most`) and plot them into the PNG `out`.

    Returns the PNG's path.
    """
    bodies = bag_bodies(bag, namespace)
    names, every = drawn_bodies(bodies.names, most)
    motions = read_body_motions(bag, namespace, names)
    # The markers give a few bodies their colours and longest axes; more bodies are coloured
    # by their spin, and opening a bag of thousands of topics again costs seconds.
    markers = first_markers(bag, namespace) if len(names) <= NAMED_BODIES else None
    return plot_body_motions(motions, out, len(bodies.names), markers, every)


def drawn_bodies(names, most=MOST_BODIES):
    """
    Return (the names drawn, k): every k-th of `names`, at most `most` of them.

    Every k-th rather than the first, so a scene laid out in groups (a constellation's
    rings) shows each group.
    """
    every = max(1, -(-len(names) // most))
    return list(names[::every]), every


def plot_body_motions(motions, out, total=None, markers=None, every=1):
    """
    Draw the four panels of several bodies' motions (:class:`.motion.BagMotion`) into `out`.

    `total`: how many bodies the bag holds (default: those given); `markers`: (stamp ns,
    {name: Marker}) of the bag's first marker array (:func:`.marker_arrays.first_markers`)
    for the bodies' colours and longest axes, or None; `every`: the motions are every
    that many-th body of the bag's.
    """
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot

    total = len(motions) if total is None else total
    named = len(motions) <= NAMED_BODIES
    spins = np.array([np.linalg.norm(motion.angular_velocity_body[0]) for motion in motions])
    colours, mappable = _colours(motions, markers, spins, named, pyplot)
    figure = pyplot.figure(figsize=(14.0, 11.0), layout='constrained')
    grid = figure.add_gridspec(2, 2)
    _com_panel(figure, grid[0, 0], motions, colours, markers, named)
    drifts = _drift_panel(figure.add_subplot(grid[0, 1]), motions, colours, named)
    _spin_panel(figure.add_subplot(grid[1, 0]), motions, colours, named)
    _worst_panel(figure.add_subplot(grid[1, 1]), motions, drifts, colours, spins, named)
    if mappable is not None:
        figure.colorbar(mappable, ax=figure.axes, shrink=0.5, pad=0.01,
                        label='$|\\Omega(0)|$ of the body [rad/s]')
    figure.suptitle(_title(motions, total, every))
    out = Path(out)
    figure.savefig(out, dpi=100)
    pyplot.close(figure)
    return out


def _colours(motions, markers, spins, named, pyplot):
    """Return (a colour per body, the colour bar's mappable or None)."""
    if not named:
        from matplotlib import cm
        from matplotlib import colors
        low, high = float(spins.min()), float(spins.max())
        norm = colors.Normalize(low, high if high > low else low + 1.0)
        mappable = cm.ScalarMappable(norm=norm, cmap='viridis')
        return [mappable.to_rgba(spin) for spin in spins], mappable
    cycle = pyplot.rcParams['axes.prop_cycle'].by_key()['color']
    fallback = [cycle[k % len(cycle)] for k in range(len(motions))]
    if markers is None:
        return fallback, None
    found = [markers[1].get(motion.body) for motion in motions]
    if any(marker is None for marker in found):
        return fallback, None
    rgb = np.array([(m.color.r, m.color.g, m.color.b) for m in found])
    apart = [np.linalg.norm(rgb[i] - rgb[j]) for i in range(len(rgb))
             for j in range(i + 1, len(rgb))]
    # Light colours vanish on white, alike ones merge: then the cycle's.
    if (apart and min(apart) < _DISTINCT_COLOURS) or np.any(rgb.sum(axis=1) > 2.4):
        return fallback, None
    return [tuple(colour) for colour in rgb], None


def _stride(count):
    return max(1, -(-count // _POINTS_PER_BODY))


def _com_panel(figure, cell, motions, colours, markers, named):
    """
    Draw the COM paths, with a stroboscope of each body's longest axis (few bodies).

    In the coordinate plane the bodies move in when their paths span less than a twentieth
    as much across it (three clubs thrown straight up: x-z), beside their heights z(t),
    else in 3-D; equal scales.
    """
    points = np.vstack([motion.position for motion in motions])
    moving = any(np.ptp(motion.position, axis=0).max() > _MOTION_THRESHOLD
                 for motion in motions)
    spans = np.ptp(points, axis=0)
    flat = moving and spans.min() <= _FLAT * spans.max()
    first, second, normal = plane_of_motion(points)
    plane = (first, second) if flat else (0, 1, 2)
    if flat:
        cells = cell.subgridspec(1, 2)
        axes = figure.add_subplot(cells[0])
        _height_panel(figure.add_subplot(cells[1]), motions, colours, named)
    else:
        axes = figure.add_subplot(cell, projection='3d')
    for motion, colour in zip(motions, colours):
        position = motion.position
        if moving:
            path = np.vstack((position[::_stride(len(position))], position[-1:]))
            axes.plot(*path[:, plane].T, color=colour, linewidth=1.0,
                      label=motion.body if named else None)
        axes.scatter(*position[0, plane], color=colour, marker='o', s=18 if named else 8,
                     label=motion.body if named and not moving else None, zorder=3)
    extent = 0.0
    if named and markers is not None and not flat:
        extent = _strobe(axes, motions, colours, markers, plane)
    names = 'xyz'
    if flat:
        axes.set_aspect('equal', adjustable='datalim')
        axes.set(xlabel=f'world {names[first]} [m]', ylabel=f'world {names[second]} [m]')
        axes.grid(True, alpha=0.3)
        what = (f'COM paths in the {names[first]}-{names[second]} plane\n(o: start; '
                f'{names[normal]} spans {spans[normal]:.2g} m)')
    else:
        low, high = points.min(axis=0) - extent, points.max(axis=0) + extent
        equal_3d(axes, np.vstack((low, high)))
        # A little smaller than the panel: the z label stays off the next panel's.
        axes.set_box_aspect((1.0, 1.0, 1.0), zoom=0.9)
        tidy_3d(axes)
        axes.set(xlabel='world x [m]', ylabel='world y [m]', zlabel='world z [m]')
        what = 'COM paths (o: start)' if moving else \
            'COM positions (every body at rest: it only turns)'
    if extent:
        what += (f"\neach body's longest axis every {_strobe_spacing(motions):.2g} s, "
                 'fainter earlier')
    axes.set_title(what)
    if named:
        axes.legend(loc='upper left', fontsize='small')


def _height_panel(axes, motions, colours, named):
    """Draw each body's COM height z(t), its apex marked (a thrown body's highest point)."""
    for motion, colour in zip(motions, colours):
        height = motion.position[:, 2]
        stride = _stride(len(height))
        axes.plot(motion.time[::stride], height[::stride], color=colour,
                  linewidth=1.2 if named else 0.6)
        apex = apex_index(motion)
        if apex is not None and named:
            axes.plot(motion.time[apex], height[apex], marker='^', color=colour,
                      linestyle='none')
    apexes = [apex_index(motion) for motion in motions]
    title = 'COM height'
    if named and any(apex is not None for apex in apexes):
        highest = max((motion.position[apex, 2], motion.time[apex])
                      for motion, apex in zip(motions, apexes) if apex is not None)
        title += f'\n(\u25b2 apex; highest z = {highest[0]:.3g} m at t = {highest[1]:.3g} s)'
    axes.set(title=title, xlabel=time_axis_label(motions[0]), ylabel='z [m]')
    axes.grid(True, alpha=0.3)


def _strobe_spacing(motions):
    time = motions[0].time
    return (time[-1] - time[0]) / (_STROBE_INSTANTS - 1)


def _strobe(axes, motions, colours, markers, plane):
    """
    Draw each body's longest drawn axis at a few instants; return its half-length (m).

    `plane`: the world coordinates drawn (two for a plane, three in 3-D).
    """
    from ..drawing import shape_from_marker

    stamp, by_name = markers
    longest = 0.0
    for motion, colour in zip(motions, colours):
        marker = by_name.get(motion.body)
        if marker is None:
            continue
        index = min(int(np.searchsorted(motion.stamps, stamp)), len(motion.stamps) - 1)
        try:
            shape = shape_from_marker(marker, motion.quaternion[index])
        except ValueError:
            continue
        axis = int(np.argmax(shape.scale))
        half = 0.5 * float(shape.scale[axis])
        longest = max(longest, half)
        # The drawing's longest axis in the body frame.
        along = shape.orientation[:, axis]
        instants = np.unique(np.linspace(0, len(motion.time) - 1, _STROBE_INSTANTS).astype(int))
        for k in instants:
            direction = motion.rotation[k] @ along * half
            ends = np.vstack((motion.position[k] - direction, motion.position[k] + direction))
            axes.plot(*ends[:, plane].T, color=colour, linewidth=2.5,
                      alpha=0.35 + 0.6 * k / max(1, len(motion.time) - 1),
                      solid_capstyle='round')
    return longest


def _largest_so_far(drift):
    """Return max |drift| over the ticks up to each, with exact zeros as NaN (log axes)."""
    largest = np.maximum.accumulate(np.abs(drift))
    return np.where(largest > 0.0, largest, np.nan)


def _drift_panel(axes, motions, colours, named):
    """
    Draw each body's largest drift so far of each conserved quantity; return them.

    Returns {quantity label: [(body index, ConservedQuantity)]}.
    """
    from matplotlib.lines import Line2D

    titles = set()
    by_label = {}
    for index, motion in enumerate(motions):
        title, quantities = conserved_quantities(motion)
        titles.add(title)
        for quantity in quantities:
            by_label.setdefault(quantity.label, []).append((index, quantity))
    handles = []
    for style, (label, entries) in zip(_QUANTITY_STYLES, by_label.items()):
        zero = 0
        for index, quantity in entries:
            motion = motions[index]
            drift = quantity.drift
            if not np.any(drift):
                zero += 1
                continue
            stride = _stride(len(drift))
            # The largest so far, sampled: the running maximum first, so no peak is lost.
            largest = _largest_so_far(drift)
            axes.plot(motion.time[::stride], largest[::stride], color=colours[index],
                      linestyle=style, linewidth=1.2 if named else 0.6,
                      alpha=1.0 if named else 0.7)
        conserved = all(quantity.conserved for _, quantity in entries)
        text = f'{label} / {entries[0][1].scale_label}'
        if not conserved:
            text += ' (not conserved)'
        if zero == len(entries):
            text += ': exactly 0 in every body'
        elif zero:
            text += f': exactly 0 in {zero} of {len(entries)} bodies'
        handles.append(Line2D([], [], color='0.2', linestyle=style, label=text))
    if named:
        handles += [Line2D([], [], color=colour, linewidth=3.0, label=motion.body)
                    for motion, colour in zip(motions, colours)]
    axes.set_yscale('log')
    title = titles.pop() if len(titles) == 1 else \
        'What each body conserves (their effects differ): largest drift so far'
    axes.set(title=wrapped_title(title), xlabel=time_axis_label(motions[0]),
             ylabel='largest |X(t) $-$ X(first)| / scale so far')
    axes.grid(True, which='major', alpha=0.3)
    axes.legend(handles=handles, loc='lower right', fontsize='small', framealpha=0.9)
    return by_label


def _spin_panel(axes, motions, colours, named):
    """Draw |Omega| of each body against time."""
    for motion, colour in zip(motions, colours):
        spin = np.linalg.norm(motion.angular_velocity_body, axis=1)
        stride = _stride(len(spin))
        axes.plot(motion.time[::stride], spin[::stride], color=colour,
                  linewidth=1.2 if named else 0.6, label=motion.body if named else None)
    axes.set(title='Angular speed $|\\Omega|$ of each body', xlabel=time_axis_label(motions[0]),
             ylabel='$|\\Omega|$ [rad/s]')
    axes.grid(True, alpha=0.3)
    if named:
        axes.legend(loc='best', fontsize='small')


def _worst_panel(axes, motions, drifts, colours, spins, named):
    """Draw each body's largest drift over the run: by name, or against |Omega(0)|."""
    worst_value, worst_name = 0.0, None
    positions = np.arange(len(motions)) if named else spins
    for (label, entries), marker in zip(drifts.items(), _QUANTITY_MARKERS):
        indices = np.array([index for index, _ in entries])
        largest = np.array([np.abs(quantity.drift).max() for _, quantity in entries])
        shown = largest > 0.0
        if not shown.any():
            continue
        axes.scatter(positions[indices[shown]], largest[shown], marker=marker,
                     c=[colours[i] for i in indices[shown]], s=40 if named else 14,
                     edgecolors='0.2', linewidths=0.4, label=label)
        top = int(np.argmax(largest))
        if largest[top] > worst_value:
            worst_value, worst_name = float(largest[top]), motions[indices[top]].body
    axes.set_yscale('log')
    if named:
        axes.set_xticks(positions, [motion.body for motion in motions],
                        rotation=30 if len(motions) > 4 else 0)
        axes.set_xlim(-0.6, len(motions) - 0.4)
        axes.set_xlabel('body')
    else:
        axes.set_xlabel('$|\\Omega(0)|$ of the body [rad/s]')
    title = 'Largest drift of each body over the run'
    if worst_name is not None:
        title += f'\n(worst: {worst_name}, {worst_value:.2g}: plot --body {worst_name})'
    axes.set(title=title, ylabel='max |X(t) $-$ X(first)| / scale')
    axes.grid(True, which='major', alpha=0.3)
    if axes.get_legend_handles_labels()[0]:
        axes.legend(loc='best', fontsize='small')


def _title(motions, total, every):
    """Return the figure's title: bag, bodies drawn, ticks, scene, integrator."""
    first = motions[0]
    drawn = f'{total} bodies' if len(motions) == total else \
        f'1 in {every} of {total} bodies: {len(motions)} drawn (plot --body NAME: any one)'
    span = f'{len(first.time)} ticks to {first.time[-1]:g} s' if first.time_is_simulated \
        else f'{len(first.time)} ticks over {first.time[-1]:g} s'
    parts = [f'bag {first.name}', drawn, span]
    scene = first.custom('scene')
    if scene:
        parts.append(f'scene {scene}')
    integrator = first.custom('integrator')
    if integrator:
        rate = first.custom('rate')
        parts.append(integrator + (f' at {float(rate):g} Hz' if rate else ''))
    return ' \u2014 '.join(parts)

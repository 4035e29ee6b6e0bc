"""
The terminal view of ``rigid-body-sim watch``: a few lines refreshed in place.

On a terminal the block is rewritten where it stands (ANSI cursor movement); piped into a
file or another program, each changed block is printed after the last, so a log reads
top to bottom.  Every number of the node is printed as its message has it: the state's
with :func:`.live.format_number`, the report's strings as they came (cut and escaped by
:class:`.live.LiveState`); a number that is not finite or absurd is said to be so.

Of a node of bodies, the view of one body (``--body``) has the lines of a one-body node's,
the drift of what the body's effects conserve computed here from its state (the node
reports no body's energy); without ``--body``, :func:`table_lines` is a table of the bodies,
one line each.
"""

import shutil

from .live import format_number

__all__ = ['flips_text', 'refused_lines', 'render_lines', 'table_lines', 'TABLE_MARGIN',
           'TerminalView', 'waiting_lines']

TABLE_MARGIN = 5
"""The lines of the table's view besides its rows: its header, the column names, the time
and cost line, the line of more bodies, and the prompt's."""


def waiting_lines(listener, waited):
    """Return the lines that say no node is watched yet, and why, after `waited` s."""
    domain = listener.domain_id
    others = ', '.join(candidate.fully_qualified_name for candidate in listener.candidates)
    asked = ''
    if listener.wanted_node or listener.wanted_namespace:
        asked = ' named ' + ' in namespace '.join(
            part for part in (listener.wanted_node, listener.wanted_namespace) if part)
    if others and not asked:
        # Seen in the graph, not yet chosen: the first report of its topics is on its way
        # (seconds on a busy machine, where discovery is slow).
        return [f'rigid-body-sim watch: found {others} on ROS domain {domain}; connecting '
                f'to its topics ({waited:.0f} s, Ctrl-C stops).']
    lines = [f'rigid-body-sim watch: no rigid_body_sim node{asked} found on ROS domain '
             f'{domain} for {waited:.0f} s; still looking (Ctrl-C stops).']
    if others:
        lines.append(f'  nodes that publish its topics: {others} (choose one with --node)')
    else:
        lines.append('  start one: make run, or .venv/bin/rigid_body_node (same ROS_DOMAIN_ID '
                     'and ROS_AUTOMATIC_DISCOVERY_RANGE as here)')
    return lines


def render_lines(snapshot):
    """Return the view's lines for a :class:`.live.Snapshot` of a watched node."""
    shown = snapshot.shown
    status = shown('status') if snapshot.diagnostics else \
        'waiting for its first report (/diagnostics, once a second)'
    lines = [f'rigid-body-sim watch: {snapshot.watched}: {status}']
    lines.extend(f'  warning       {text}' for text in snapshot.warnings.values())
    if snapshot.diagnostics:
        whose = '' if snapshot.body is None else \
            f'{shown("bodies")} bodies; effects on {snapshot.body}'
        lines.append(f'  scene         {shown("scene")} ({whose or "effects"}: '
                     f'{shown("effects")}), integrator {shown("integrator")} at '
                     f'{shown("rate")} Hz')
    latest = snapshot.latest
    if latest is None:
        lines.append('  waiting for its state (odom, angular_momentum)')
        lines.extend(refused_lines(snapshot))
        return lines
    time = latest.time
    lines.append('  time          ' + (
        '(known at the first report)' if time is None else f'{time:.6f} s simulated'))
    lines.append('  omega body    ' + '  '.join(
        format_number(component) for component in latest.angular_velocity_body) + ' rad/s')
    magnitude = format_number(latest.momentum_magnitude, signed=False)
    lines.append(f'  |L|           {magnitude} kg m^2/s')
    if snapshot.body is not None:
        lines.extend(_body_drift_lines(snapshot))
    elif snapshot.diagnostics:
        lines.append(f'  energy drift  {shown("energy_drift")} (total energy, since the last '
                     "input; the node's report)")
    lines.append(f'  flips         {flips_text(snapshot)}')
    if snapshot.diagnostics:
        tolerance = snapshot.value('tolerance')
        control = 'fixed' if tolerance == 'off' else f'tolerance {shown("tolerance")} rad/s'
        lines.append(f'  substeps      {shown("substeps")} per tick ({control})')
        lines.append(f'  ticks/s       {shown("achieved_rate")} (requested {shown("rate")} x '
                     f'real-time factor {shown("real_time_factor")}); tick p50 '
                     f'{shown("tick_p50")} ms, p99 {shown("tick_p99")} ms'
                     + _publishing_text(snapshot))
    changes = [_event_text(event) for event in snapshot.events[-3:]]
    if changes:
        lines.append('  changes       ' + '; '.join(changes))
    lines.extend(refused_lines(snapshot))
    return lines


def _body_drift_lines(snapshot):
    """Return the lines of a body's energy and drifts, computed from its state here."""
    latest = snapshot.latest
    energy = format_number(latest.rotational_energy, signed=False)
    lines = [f'  energy        T_rot {energy} J (rotational, 1/2 Omega . R^T L)']
    if not snapshot.torque_free:
        effects = snapshot.shown('effects')
        lines.append(f'  drift         not charted: T_rot and |L| are not conserved under its '
                     f'effects ({effects})')
        return lines
    _, energy_drift, momentum_drift = snapshot.drifts()
    if not len(energy_drift):
        lines.append('  drift         (from the first tick timed by a report)')
        return lines
    since = 'since the reset' if snapshot.resets_seen else 'since watch started'
    lines.append(f'  drift         T_rot {format_number(energy_drift[-1], 3)}, |L| '
                 f'{format_number(momentum_drift[-1], 3)} (relative, {since}; its effects '
                 'conserve both)')
    return lines


def _publishing_text(snapshot):
    """Return what a node of bodies says of its rate: kept, published every k ticks."""
    every = snapshot.value('publish_every')
    if every is None:
        return ''
    return (f'; rate kept {snapshot.shown("rate_kept")}, state published every '
            f'{snapshot.shown("publish_every")} tick(s)')


def table_lines(snapshot, rows, table_bodies):
    """
    Return the view of a node's bodies: one line each of those shown, sorted by name.

    `rows` is :meth:`.live.BodyTable.rows`, `table_bodies` the bodies shown (the first
    ones of ``snapshot.bodies``, as many as the terminal has lines for).
    """
    shown = snapshot.shown
    status = shown('status') if snapshot.diagnostics else \
        'waiting for its first report (/diagnostics, once a second)'
    count = len(snapshot.bodies)
    lines = [f'rigid-body-sim watch: {snapshot.node}: {status}; {count} bodies'
             + (f' (scene {shown("scene")})' if snapshot.diagnostics else '')
             + ': --body NAME watches one']
    lines.extend(f'  warning       {text}' for text in snapshot.warnings.values())
    lines.append(f'  {"body":<20} {"|omega| rad/s":>14} {"|L| kg m^2/s":>14} '
                 f'{"x m":>11} {"y m":>11} {"z m":>11} {"speed m/s":>11}')
    for name in table_bodies:
        row = rows.get(name, {})
        label = name if len(name) <= 20 else name[:17] + '...'
        if 'refused' in row:
            lines.append(f'  {label:<20} refused: {row["refused"]} (not shown)')
            continue
        if 'omega' not in row:
            lines.append(f'  {label:<20} {"waiting for its state":>14}')
            continue
        momentum = row.get('momentum')
        position = row['position']
        lines.append(
            f'  {label:<20} {format_number(row["omega"], 6, signed=False):>14} '
            + (f'{format_number(momentum, 6, signed=False):>14} ' if momentum is not None
               else f'{"waiting":>14} ')
            + ' '.join(f'{format_number(value, 6):>11}' for value in position)
            + f' {format_number(row["speed"], 5, signed=False):>11}')
    if count > len(table_bodies):
        lines.append(f'  ... and {count - len(table_bodies)} more (--body NAME to watch one)')
    if snapshot.diagnostics:
        lines.append(f'  time {shown("simulated_time")} s simulated; integrator '
                     f'{shown("integrator")} at {shown("rate")} Hz; {shown("achieved_rate")} '
                     'ticks/s' + _publishing_text(snapshot))
    return lines


def flips_text(snapshot, brief=False):
    """Return the flips as the views say them: how many, of what, since when."""
    if snapshot.middle_axis is None:
        return ('not counted: the body has no middle principal axis' if snapshot.marker
                else 'not counted until the marker tells the principal axes')
    if brief:
        return f'{snapshot.flips} {snapshot.flips_since} (about the middle axis, while free)'
    axis = ' '.join(f'{component:+.2f}' for component in snapshot.middle_axis)
    return (f'{snapshot.flips} {snapshot.flips_since} (sign changes of Omega along the middle '
            f'principal axis [{axis}] while no input acts)')


def refused_lines(snapshot):
    """Return a line per topic of which messages were not taken, and why."""
    return [f'  refused       {topic}: {count} ({why}; not shown, not charted)'
            for topic, (why, count) in sorted(snapshot.refused.items())]


def _event_text(event):
    time, name, value = event
    when = '' if time is None else f' at {time:.2f} s'
    if name == 'reset':
        return 'reset (time 0)'
    if value is None:
        return f'{name}{when}'
    return f'{name} {value}{when}'


class TerminalView:
    """
    Writes the lines to a stream: in place on a terminal, appended otherwise.

    Parameters
    ----------
    stream : file
        Where to write (stdout).
    in_place : bool
        Rewrite the block where it stands (a terminal) rather than append it.

    """

    def __init__(self, stream, in_place):
        self.stream = stream
        self.in_place = in_place
        self._shown = 0
        self._last = None

    def show(self, lines):
        """Show the block `lines` (the same block twice is written once)."""
        if lines == self._last:
            return
        self._last = list(lines)
        if self.in_place:
            # A line wider than the terminal would wrap, and the block's lines would no
            # longer be the rows to go back up: each is cut to the width.
            width = max(20, shutil.get_terminal_size().columns - 1)
            lines = [line if len(line) <= width else line[:width - 3] + '...'
                     for line in lines]
            # Up to the block's first line, rewrite each line, clear what is left below.
            text = (f'\x1b[{self._shown}F' if self._shown else '') + ''.join(
                f'\x1b[2K{line}\n' for line in lines) + '\x1b[J'
            self._shown = len(lines)
        else:
            text = '\n'.join(lines) + '\n\n'
        self.stream.write(text)
        self.stream.flush()

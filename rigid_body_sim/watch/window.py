"""
The window of ``rigid-body-sim watch``: the body turning, strip charts, the node's cost.

matplotlib with its TkAgg backend (Tk comes with CPython; see docs/dependencies.md): the
body as ``rigid-body-sim animate`` draws it (:class:`rigid_body_sim.drawing.BodyView`: its
shape, the body axes, the direction of L, a trail), a strip chart of the body angular
velocity, one of the drift of what the scene conserves, and the node's live cost and state
from /diagnostics as text.  A timer redraws it a few times a second from a
:class:`.live.Snapshot`; the ROS side runs in the listener's thread.

What a peer sends (a scene name, a status, a parameter value) is drawn as plain text
(``parse_math=False``): a ``$`` is a dollar sign, never mathtext to parse.  Each redraw is
drawn at once and timed: the window says it shows the node only after a draw that
succeeded, and the refresh slows down so that redrawing takes at most
:data:`CPU_SHARE` of a core, and more when the machine is busy (load above its cores).

Of a node of bodies, the window shows one body (``--body``, else the first by name); the
keys n and p show the next and the previous (the listener subscribes to that body's topics
instead), and the title says "body NAME (i of N)".
"""

import math
import os
import sys
import time

import numpy as np

from .live import bodies_text
from .live import format_number
from .terminal import flips_text
from .terminal import refused_lines
from .terminal import waiting_lines
from ..drawing import AXIS_COLOURS
from ..drawing import BodyView
from ..drawing import shape_from_marker

__all__ = ['CPU_SHARE', 'display_problem', 'WatchWindow']

# The default and the longest time between redraws (ms): the 3D body costs tens of ms a
# frame on a loaded 2-core machine.
_REDRAW_PERIOD_MS = 200
_SLOWEST_PERIOD_MS = 2000
# How often the window checks whether the watch must end (ms).
_STOP_CHECK_MS = 100
CPU_SHARE = 0.2
"""The share of a core the redraws may take: the period grows to draw time / CPU_SHARE."""
# Simulated seconds in the charts before the window counts as showing the node.
_SHOWN_SPAN = 2.0
# Points per strip-chart line: about the chart's width in pixels.
_CHART_POINTS = 800
# The share of the charts' span kept on the left when they scroll on.
_SCROLL_KEEP = 0.5
# Event labels closer than this fraction of the chart's span are stacked.
_LABEL_SPAN = 0.15
# The keys that show the next and the previous body of a node of bodies.
_BODY_KEYS = {'n': 1, 'p': -1}


def display_problem():
    """Return why no window can open here (a sentence), or None if one can."""
    import os
    if not (os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')):
        return 'no display (DISPLAY is not set)'
    try:
        import tkinter
    except ImportError:
        return ('this Python has no tkinter, which the window needs (Debian: apt install '
                'python3-tk; pyenv: build Python with tk-dev installed)')
    try:
        root = tkinter.Tk()
    except tkinter.TclError as error:
        return f'Tk cannot open the display: {error}'
    root.destroy()
    return None


def _drawing_is_equivalent_box(scene_name, body=None):
    """
    Return True if the scene draws a body given by its inertia as its equivalent box.

    `body`: the body's name in a scene of bodies (its entry's drawing).
    """
    from ..scenes import load_scene
    try:
        scene = load_scene(scene_name)
    except (ValueError, OSError):
        return False
    if body is not None:
        scene = next((member for member in scene.members if member.name == body), None)
        if scene is None:
            return False
    return 'shape' not in scene.data.get('body', {}) and scene.drawing.derived


class WatchWindow:
    """
    The figure and its timer.

    Parameters
    ----------
    state : LiveState
        What to draw (its snapshots).
    listener : Listener
        Who feeds it (for the waiting message).
    history : float
        Simulated seconds shown by the strip charts.
    should_stop : callable
        Returns True when the watch must end (a signal, a timeout): the window closes.
    on_drawn : callable, optional
        Called once, with the snapshot, after the first redraw that showed the body and
        2 simulated seconds of data in both charts.
    refresh : float, optional
        Seconds between redraws, kept as given; by default 0.2 s, lengthened while a redraw
        takes more than :data:`CPU_SHARE` of a core or the machine is busy.

    """

    def __init__(self, state, listener, history, should_stop, on_drawn=None, refresh=None):
        import warnings

        import matplotlib
        matplotlib.use('TkAgg')
        import matplotlib.pyplot as plt

        # n and p choose the body of a node of bodies: p is not matplotlib's pan here.
        matplotlib.rcParams['keymap.pan'] = [key for key in matplotlib.rcParams['keymap.pan']
                                             if key not in _BODY_KEYS]

        # Before Tk has sized the window, its first draw is too small to lay out.
        warnings.filterwarnings('ignore', message='constrained_layout not applied')

        self.state = state
        self.listener = listener
        self.history = history
        self.should_stop = should_stop
        self.on_drawn = on_drawn
        self.plt = plt
        self.figure = plt.figure(figsize=(13.0, 6.4), layout='constrained')
        self.figure.canvas.manager.set_window_title('rigid-body-sim watch')
        grid = self.figure.add_gridspec(2, 2, width_ratios=(1.0, 1.25))
        self.body_axes = self.figure.add_subplot(grid[0:2, 0], projection='3d')
        self.omega_axes = self.figure.add_subplot(grid[0, 1])
        self.drift_axes = self.figure.add_subplot(grid[1, 1], sharex=self.omega_axes)
        self.text = _TextPanel(self.figure.canvas)
        self.title = self.figure.suptitle('rigid-body-sim watch', parse_math=False)
        self.body_view = None
        self.resets_seen = 0
        self.omega_lines = [self.omega_axes.plot([], [], color=colour, linewidth=1.2,
                                                 label=f'$\\Omega_{name}$')[0]
                            for colour, name in zip(AXIS_COLOURS, 'xyz')]
        self.omega_axes.set(title='Body angular velocity', ylabel='$\\Omega$ [rad/s]')
        # Legends in one row in headroom above the data (see _autoscale_y): never on a curve.
        self.omega_axes.legend(loc='upper left', ncols=3, fontsize='small')
        self.omega_axes.tick_params(labelbottom=False)
        self.energy_line, = self.drift_axes.plot([], [], color='tab:orange', linewidth=1.2,
                                                 label='$T_{rot}$ drift')
        self.momentum_line, = self.drift_axes.plot([], [], color='tab:purple',
                                                   linestyle='--', linewidth=1.2,
                                                   label='$|L|$ drift')
        self.report_line, = self.drift_axes.plot([], [], color='black', marker='o',
                                                 linestyle='none', markersize=4,
                                                 label='energy,\nnode report')
        self.drift_axes.set(xlabel='simulated time [s]', ylabel='relative drift')
        self.legend_torque_free = None
        self.reports = []
        for axes in (self.omega_axes, self.drift_axes):
            axes.grid(True, alpha=0.3)
            axes.ticklabel_format(axis='y', style='sci', scilimits=(-3, 4), useOffset=True)
        for artist in self._animated():
            artist.set_animated(True)
        # A draw of the whole figure leaves the moving artists out (Tk draws it when the
        # window is mapped, exposed or resized): they are drawn over it at once.
        self.figure.canvas.mpl_connect('draw_event', self._on_full_draw)
        self.event_artists = []
        self.drawn_once = False
        self.draw_error = None
        self.background = self.background_key = None
        self.events_key = None
        self.chart_span = None
        self.redraws, self.redraw_seconds, self.full_draws = 0, 0.0, 0
        self.adaptive = refresh is None
        self.default_period_ms = _REDRAW_PERIOD_MS if refresh is None else max(
            1, int(round(1000.0 * refresh)))
        self.period_ms = self.default_period_ms
        self.timer = self.figure.canvas.new_timer(interval=self.period_ms)
        self.timer.add_callback(self._redraw)
        # Apart from the redraws, which may come seconds apart: Ctrl-C is answered at once.
        self.stop_timer = self.figure.canvas.new_timer(interval=_STOP_CHECK_MS)
        self.stop_timer.add_callback(self._check_stop)
        self.figure.canvas.mpl_connect('key_press_event', self._on_key)
        self.shown = None  # (node, body) drawn now

    def run(self):
        """Show the window until it is closed or the watch must stop."""
        self.timer.start()
        self.stop_timer.start()
        started = time.monotonic()
        self._redraw()
        self.plt.show()
        elapsed = time.monotonic() - started
        if self.redraws:
            # For benchmarks/watch_window_cpu.py, and anyone who wonders why it lagged.
            print(f'rigid-body-sim watch: {self.redraws} redraws in {elapsed:.1f} s '
                  f'({self.full_draws} of the whole figure), '
                  f'{1000.0 * self.redraw_seconds / self.redraws:.1f} ms of CPU each; redraw '
                  f'period {self.default_period_ms} ms'
                  + (f', {self.period_ms} ms at the end' if self.adaptive else ' (kept)'),
                  file=sys.stderr)

    def close(self):
        """Close the window (ends :meth:`run`)."""
        self.timer.stop()
        self.stop_timer.stop()
        self.plt.close(self.figure)

    def _on_key(self, event):
        step = _BODY_KEYS.get(event.key)
        if step is not None:
            self.listener.select_body(step)

    def _forget_body(self):
        """Start the drawing and the charts afresh: another body (or node) is shown."""
        self.body_axes.cla()
        self.body_view = None
        self.reports = []
        self.chart_span = None
        self.events_key = None
        self.background_key = None
        self.drawn_once = False
        for artist in self.event_artists:
            artist.remove()
        self.event_artists = []
        for line in (*self.omega_lines, self.energy_line, self.momentum_line,
                     self.report_line):
            line.set_data([], [])

    def _check_stop(self):
        if self.should_stop():
            self.close()

    # -- drawing

    def _redraw(self):
        if self.should_stop():
            self.close()
            return
        started = time.thread_time()
        try:
            charted = self._update()
            self._draw()
        except Exception as error:  # noqa: B902 (say it in the window, keep running)
            self.background_key = None
            self._show_draw_error(error)
            return
        self.draw_error = None
        self.redraws += 1
        self.redraw_seconds += time.thread_time() - started
        self._adapt_period(time.thread_time() - started)
        if charted and self.body_view is not None and not self.drawn_once:
            self.drawn_once = True
            self.figure.canvas.flush_events()
            if self.on_drawn is not None:
                self.on_drawn(self.state.snapshot())

    def _draw(self):
        """
        Draw what changed: the moving artists over a saved background, or everything.

        The background (axes, ticks, titles, legends, event marks; laid out anew) is drawn
        again only when it changes: the charts scroll in steps and their y ranges stick
        while the data fit.
        """
        canvas = self.figure.canvas
        axes3d = self.body_axes
        texts = (canvas.get_width_height(), self.drift_axes.get_title(),
                 self.title.get_text(), self.legend_torque_free, self.body_view is None,
                 axes3d.get_title())
        key = (texts, self.omega_axes.get_xlim(), self.omega_axes.get_ylim(),
               self.drift_axes.get_ylim(), self.events_key, axes3d.elev, axes3d.azim,
               axes3d.roll)
        if key != self.background_key:
            if self.background_key is None or texts != self.background_key[0]:
                # The constrained layout settles in two passes when titles or legends
                # changed (the first places them, the second makes room for them): one
                # here, one in the draw.
                self.figure.get_layout_engine().execute(self.figure)
            canvas.draw()  # the animated artists left out; then _on_full_draw
            self.full_draws += 1
            self.background_key = key
            return
        canvas.restore_region(self.background)
        self._draw_moving()

    def _on_full_draw(self, event):
        """After any draw of the whole figure (a redraw's, Tk's): keep it, add what moves."""
        canvas = self.figure.canvas
        self.background = canvas.copy_from_bbox(self.figure.bbox)
        try:
            self._draw_moving()
        except Exception as error:  # noqa: B902 (say it in the window, keep running)
            self.background_key = None
            self._show_draw_error(error)

    def _draw_moving(self):
        canvas = self.figure.canvas
        for artist in self._animated():
            if hasattr(artist, 'do_3d_projection'):
                artist.do_3d_projection()
            self.figure.draw_artist(artist)
        # Only the three axes go to the screen: less to copy than the whole figure.
        for axes in (self.body_axes, self.omega_axes, self.drift_axes):
            canvas.blit(axes.bbox)

    def _animated(self):
        """Return the artists drawn at every redraw (the rest is the background)."""
        artists = [*self.omega_lines, self.energy_line, self.momentum_line, self.report_line]
        view = self.body_view
        if view is not None:
            artists += [view.polygons, *view.axis_lines, view.momentum_line, view.trail]
        return artists

    def _show_draw_error(self, error):
        # What failed is not known: the window falls back to the text alone, which draws.
        message = f'rigid-body-sim watch: the window could not be drawn: {error!r}'[:300]
        if message != self.draw_error:
            self.draw_error = message
            print(message, flush=True)
        self.text.set_text(message)

    def _adapt_period(self, seconds):
        """Set the next redraw's delay from this one's CPU time and the machine's load."""
        if not self.adaptive:
            return
        busy = max(1.0, os.getloadavg()[0] / (os.cpu_count() or 1))
        period = max(_REDRAW_PERIOD_MS, 1000.0 * seconds / CPU_SHARE) * busy
        period = int(min(_SLOWEST_PERIOD_MS, period))
        if abs(period - self.period_ms) > 0.1 * self.period_ms:
            self.period_ms = period
            self.timer.interval = period

    def _update(self):
        """Update the artists from a snapshot; return True if both charts show data."""
        snapshot = self.state.snapshot()
        if snapshot.node is None:
            self.title.set_text('rigid-body-sim watch: no node')
            waited = time.monotonic() - self.listener.searching_since
            self.text.set_text('\n'.join(waiting_lines(self.listener, waited)))
            return False
        status = snapshot.shown('status') if snapshot.diagnostics else \
            'waiting for its first report'
        # (The keys n / p are said in the text: the node's status can fill the title.)
        self.title.set_text(f'rigid-body-sim watch: {snapshot.watched} \u2014 {status}')
        if (snapshot.node, snapshot.body) != self.shown:
            if self.shown is not None:
                self._forget_body()
            self.shown = (snapshot.node, snapshot.body)
        if self.body_view is None:
            self._make_body_view(snapshot)
        if snapshot.resets_seen != self.resets_seen:
            self.resets_seen = snapshot.resets_seen
            self.reports = []
            if self.body_view is not None:
                self.body_view.clear_trail()
        charted = self._draw_charts(snapshot)
        if self.body_view is not None and snapshot.latest is not None:
            self.body_view.show(snapshot.latest.quaternion, snapshot.latest.angular_momentum)
            # The trail from every pose received (one per 2 degrees turned), not per redraw.
            self.body_view.set_trail(snapshot.trail)
        self.text.set_text(self._text(snapshot))
        return charted

    def _make_body_view(self, snapshot):
        if snapshot.marker is None or len(snapshot.time) < 2:
            self.body_axes.set_title('the body: waiting for its marker', fontsize=9)
            return
        marker, quaternion = snapshot.marker
        scene = snapshot.value('scene')
        try:
            shape = shape_from_marker(marker, quaternion, scene is not None
                                      and _drawing_is_equivalent_box(scene, snapshot.body))
        except ValueError as error:
            self.body_axes.set_title(f'the body: {error}', fontsize=9, parse_math=False)
            return
        # The trail follows the body axis nearest the middle principal axis: it flips over
        # (a T-handle), while the axes spinning about it would only paint a ring.
        middle = snapshot.middle_axis
        self.body_view = BodyView(self.body_axes, shape,
                                  2 if middle is None else int(np.argmax(np.abs(middle))))
        self.body_axes.set_title(
            'The body, viewed from its COM' if snapshot.body is None else
            f'{snapshot.body}, viewed from its COM', fontsize=10, parse_math=False)
        self.body_axes.legend(loc='upper left', fontsize=7, frameon=False)
        for artist in self._animated():
            artist.set_animated(True)

    def _draw_charts(self, snapshot):
        """Update the strip charts; return True if both show data."""
        times = snapshot.time
        if len(times) < 2:
            return False
        end = times[-1]
        stride = max(1, len(times) // _CHART_POINTS)
        picked = np.r_[np.arange(0, len(times), stride), len(times) - 1]
        for k, line in enumerate(self.omega_lines):
            line.set_data(times[picked], snapshot.angular_velocity_body[picked, k])
        start, _ = self._scroll(times[0], end)
        _autoscale_y(self.omega_axes, snapshot.angular_velocity_body)

        drift_time, energy, momentum = snapshot.drifts()
        torque_free = snapshot.torque_free
        report, reported_at = snapshot.number('energy_drift'), snapshot.number('simulated_time')
        if report is not None and reported_at is not None and (
                not self.reports or self.reports[-1][0] != reported_at):
            self.reports.append((reported_at, report))
        self.reports = [(t, value) for t, value in self.reports if start <= t <= end]
        if torque_free and len(drift_time):
            every = max(1, len(drift_time) // _CHART_POINTS)
            self.energy_line.set_data(drift_time[::every], energy[::every])
            self.momentum_line.set_data(drift_time[::every], momentum[::every])
            title = ('Drift of what the scene conserves (torque-free about the COM)'
                     if snapshot.body is None else f'Drift of what the effects on '
                     f'{snapshot.body} conserve (torque-free about the COM)')
        elif snapshot.body is not None:
            # A node of bodies reports no body's energy: nothing conserved to chart.
            self.energy_line.set_data([], [])
            self.momentum_line.set_data([], [])
            title = (f'No drift charted: the effects on {snapshot.body}\n'
                     f'({snapshot.shown("effects")}) do not conserve T_rot, |L|')
        else:
            self.energy_line.set_data([], [])
            self.momentum_line.set_data([], [])
            title = ("Drift of the total energy, from the node's reports\n(effects "
                     f'{snapshot.shown("effects")}: T_rot, |L| not conserved)')
        if self.legend_torque_free != torque_free:
            # The legend names what is drawn: the drifts computed here, or the reports.
            self.legend_torque_free = torque_free
            handles = [self.energy_line, self.momentum_line] if torque_free else \
                [self.report_line]
            self.drift_axes.legend(handles=handles, loc='upper left', fontsize='small',
                                   ncols=len(handles))
        if self.reports and not torque_free:
            # Only where no drift is computed here: the report counts from the node's last
            # input, not from the chart's start, and the two would disagree by an offset.
            self.report_line.set_data(*zip(*self.reports))
        else:
            self.report_line.set_data([], [])
        if snapshot.value('wrench_active') == 'True':
            title += '\nan outside input acts: drifts count from its end'
        if title != self.drift_axes.get_title():
            self.drift_axes.set_title(title, fontsize=10, parse_math=False)
        shown = [values for values in (energy, momentum) if torque_free and len(values)]
        if not torque_free:
            shown.append(np.array([value for _, value in self.reports]))
        _autoscale_y(self.drift_axes, np.concatenate([np.ravel(v) for v in shown]))
        self._draw_events(snapshot, start)
        # "Shown" once the charts hold a stretch worth looking at, not their first points.
        return end - times[0] >= _SHOWN_SPAN and bool(
            len(drift_time) if torque_free else self.reports or snapshot.body is not None)

    def _scroll(self, first, end):
        """
        Return the charts' time span: it changes in steps, so the background stands.

        While the charts hold less than their history, the span doubles (8, 16, ... s)
        from the first tick; then it moves on by half the history at a time.
        """
        if self.chart_span is None or not self.chart_span[0] <= end <= self.chart_span[1]:
            held = end - first
            if held < _SCROLL_KEEP * self.history:
                length = min(self.history, 2.0 ** math.ceil(math.log2(max(held, 4.0) * 1.25)))
                low = first
            else:
                length = self.history
                low = end - _SCROLL_KEEP * self.history
            self.chart_span = (low, low + length)
            self.omega_axes.set_xlim(*self.chart_span)
        return self.chart_span

    def _draw_events(self, snapshot, start):
        shown = [event for event in snapshot.events
                 if event[0] is not None and event[0] >= start and event[1] != 'reset']
        if shown == self.events_key:
            return
        self.events_key = shown
        for artist in self.event_artists:
            artist.remove()
        self.event_artists = []
        low, high = self.omega_axes.get_xlim()
        row, previous = 0, None
        for moment, name, value in shown:
            label = name if value is None else f'{name} {value}'
            for axes in (self.omega_axes, self.drift_axes):
                self.event_artists.append(axes.axvline(moment, color='0.4', linestyle=':',
                                                       linewidth=1.0))
            # Labels of events close in time go one under the other, never over each other.
            row = row + 1 if previous is not None and \
                moment - previous < _LABEL_SPAN * (high - low) else 0
            previous = moment
            self.event_artists.append(self.omega_axes.annotate(
                label, (moment, 1.0), xycoords=('data', 'axes fraction'),
                xytext=(2, -2 - 10 * (row % 4)), textcoords='offset points', va='top',
                fontsize=8, color='0.3', parse_math=False,
                bbox={'facecolor': 'white', 'edgecolor': 'none', 'alpha': 0.8, 'pad': 0.5}))

    def _text(self, snapshot):
        shown = snapshot.shown
        latest = snapshot.latest
        lines = list(snapshot.warnings.values())
        if latest is not None:
            now = 'not yet known' if latest.time is None else f'{latest.time:.3f} s'
            omega = ' '.join(format_number(w, 6) for w in latest.angular_velocity_body)
            magnitude = format_number(latest.momentum_magnitude, signed=False)
            lines.append(f'simulated time {now}   omega body [{omega}] rad/s   '
                         f'|L| {magnitude} kg m^2/s   flips {flips_text(snapshot, brief=True)}')
        if snapshot.bodies:
            lines.append(f'{len(snapshot.bodies)} bodies: {bodies_text(snapshot.bodies)}  '
                         '(n / p: next / previous; --body NAME)')
        if snapshot.diagnostics:
            tolerance = snapshot.value('tolerance')
            control = 'fixed step' if tolerance == 'off' else \
                f'tolerance {shown("tolerance")} rad/s'
            whose = 'effects' if snapshot.body is None else f'effects on {snapshot.body}'
            lines.append(f'scene {shown("scene")} ({whose}: {shown("effects")})   integrator '
                         f'{shown("integrator")}   {control}   substeps {shown("substeps")} '
                         f'({shown("substeps_min")}-{shown("substeps_max")} over the last '
                         'report)')
            lines.append(f'cost: {shown("achieved_rate")} ticks/s of {shown("rate")} Hz x '
                         f'{shown("real_time_factor")}; tick p50 {shown("tick_p50")} ms, p99 '
                         f'{shown("tick_p99")} ms; step p50 {shown("step_p50")} ms; '
                         f'integration CPU per simulated s {shown("cpu_per_simulated_second")}'
                         f' s; missed ticks {shown("missed_ticks")}')
            if snapshot.body is not None and latest is not None:
                energy = format_number(latest.rotational_energy, 6, signed=False)
                lines.append(f'T_rot {energy} J (computed here: the node reports none per '
                             f'body); rate kept {shown("rate_kept")}, state published every '
                             f'{shown("publish_every")} tick(s); node report of t = '
                             f'{shown("simulated_time")} s')
            elif snapshot.body is None:
                lines.append(f'energy {shown("energy")} J (drift since the last input '
                             f'{shown("energy_drift")}); |L| {shown("momentum")} (drift '
                             f'{shown("momentum_drift")}); node report of t = '
                             f'{shown("simulated_time")} s')
        else:
            lines.append("waiting for the node's first /diagnostics report (once a second)")
        lines.extend(line.strip() for line in refused_lines(snapshot))
        return '\n'.join(lines)


class _TextPanel:
    """
    The text below the figure: a Tk label, not matplotlib text.

    Agg renders every glyph at every redraw (most of a redraw's time for a few lines of
    numbers); Tk draws its label's text as text, and takes it literally (no markup).
    """

    def __init__(self, canvas):
        import tkinter
        import tkinter.font
        widget = canvas.get_tk_widget()
        self.font = tkinter.font.nametofont('TkFixedFont')
        # width=1: the label takes the window's width, never widens it for a long line.
        self.label = tkinter.Label(widget.master, text='', justify='left', anchor='nw',
                                   font=self.font, background='white', padx=8, pady=4,
                                   height=6, width=1)
        self.label.pack(side=tkinter.BOTTOM, fill=tkinter.X, before=widget)
        self.shown = None

    def set_text(self, text):
        """Show `text` (a few lines), each cut to the label's width."""
        width = self.label.master.winfo_width()
        if width > 100:  # (1 until the window is mapped: nothing to cut to yet)
            columns = width // max(1, self.font.measure('0')) - 3
            text = '\n'.join(line if len(line) <= columns else line[:columns - 3] + '...'
                             for line in text.split('\n'))
        if text != self.shown:
            self.shown = text
            self.label.configure(text=text)

    def get_text(self):
        """Return the text shown."""
        return self.shown or ''


def _autoscale_y(axes, values):
    """
    Fit the y range to the values, with a fifth of the height free on top for the legend.

    The range sticks while the values fit below the legend's room and fill a third of it:
    a new range draws the chart's background again.
    """
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if not values.size:
        return
    low, high = float(values.min()), float(values.max())
    bottom, top = axes.get_ylim()
    room = (top - bottom) / 1.25
    if bottom <= low and high <= bottom + room and high - low >= room / 3.0:
        return
    span = high - low
    # Room to grow (a drift that climbs): the range need not change at the next redraw.
    margin = 0.15 * span if span > 0.0 else max(abs(high) * 0.1, 1e-12)
    low, high = low - margin, high + margin
    axes.set_ylim(low, high + 0.25 * (high - low))

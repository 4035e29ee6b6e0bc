"""
What ``rigid-body-sim watch`` knows of a running node: its ticks, its reports, its changes.

Plain numbers in, no rclpy here (the listener converts the messages): each tick's state
from ``odom`` and ``angular_momentum`` (paired by their header stamp), each /diagnostics
report of the node, and each parameter change the node announces.

Simulated time.  The state messages are stamped with the node's clock (the wall clock
unless it publishes /clock), so their stamps are not simulated time; /diagnostics says the
simulated time once a second, in the same tick as that tick's state.  A report is paired
with the latest state whose stamp is at or before the report's (the node publishes a tick's
state, then its report), and every later tick whose state moved adds one period 1/rate
(a paused tick publishes the same state and adds nothing).  A report whose time is behind
the count by more than half a tick is a ``reset`` (time restarts at 0); the ticks since the
reset are re-timed from the report, and everything before it is forgotten.  Ticks that
come before the first report wait for it (at most a second).

What a peer sends is not believed blindly.  A state whose numbers are not finite or absurd
(beyond :data:`ABSURD`, or a quaternion that is not a rotation) is refused: it never enters
the history, and the views say 'not finite' or 'absurd'.  A report's strings are cut and
escaped (:func:`rigid_body_sim.text.shortened`) before they are kept, and its numbers are
used only if they are finite and in range.

Flips.  A Dzhanibekov flip is a sign change of the body angular velocity's component along
the body's middle principal axis, counted while the body is free (no outside input acts).
The principal axes come from the node's marker: a box or an ellipsoid of uniform density
(the node draws a body given by its inertia as its inertia-equivalent box) has its middle
moment about its middle edge; an axisymmetric body has no middle axis and no flips.
"""

from collections import deque
from dataclasses import dataclass
from dataclasses import field
import math
import threading

import numpy as np

from ..drawing import shape_from_marker
from ..physics import matrix_from_quaternion
from ..physics.effects import EFFECTS
from ..scenes.limits import RATE_RANGE
from ..text import shortened

__all__ = ['ABSURD', 'bodies_text', 'BodyTable', 'LiveState', 'Tick', 'DIAGNOSTICS_KEYS',
           'format_number', 'number_verdict']

# The /diagnostics keys the view reads (the node's own names, docs/node.md).
DIAGNOSTICS_KEYS = {
    'scene': 'scene',
    'effects': 'effects',
    'integrator': 'integrator',
    'rate': 'requested rate [Hz]',
    'real_time_factor': 'real-time factor',
    'achieved_rate': 'achieved rate [Hz]',
    'achieved_real_time_factor': 'achieved real-time factor',
    'missed_ticks': 'missed ticks',
    'tolerance': 'tolerance [rad/s]',
    'substeps': 'substeps',
    'substeps_min': 'substeps min',
    'substeps_max': 'substeps max',
    'step_p50': 'step time p50 [ms]',
    'tick_p50': 'tick duration p50 [ms]',
    'tick_p99': 'tick duration p99 [ms]',
    'cpu_per_simulated_second': 'integration CPU per simulated s [s]',
    'simulated_time': 'simulated time [s]',
    'paused': 'paused',
    'wrench_active': 'external wrench active',
    'energy': 'energy [J]',
    'energy_drift': 'energy drift since last input',
    'momentum': '|L| [kg m^2/s]',
    'momentum_drift': '|L| drift since last input',
    # A node of bodies (node/world_node.py) reports these instead of a body's energy.
    'bodies': 'bodies',
    'rate_kept': 'rate kept',
    'publish_every': 'state published every k-th tick',
    # Not a key of the node's: the status's message ('running', 'paused', 'falling behind').
    'status': '(status message)',
}
ABSURD = 1e12
"""The largest magnitude of a number the view charts or computes with (a state's component
in SI units, a simulated time in s): beyond it a peer's number is 'absurd'."""
# What an effect must conserve (its class's ``conserves``, physics/effects/registry.py) for
# the view to chart the drift of the rotational energy 1/2 Omega . R^T L and of |L|.
_TORQUE_FREE = {'angular_momentum', 'rotational_energy'}
# Ticks kept while the first report is awaited (a second at 10 kHz).
_PENDING_TICKS = 10000
# The most ticks kept at all, whatever a report says of the rate: memory stays bounded.
_MAX_TICKS = 50000
# A flip is counted when the middle-axis component of Omega swings from below
# -_FLIP_LEVEL |Omega| to above +_FLIP_LEVEL |Omega| or back (a Schmitt trigger: no count
# for ripples around zero).
_FLIP_LEVEL = 0.3
# The trail keeps an orientation each time the body has turned this far (rad) since the
# last one kept: a smooth curve at any spin rate, from every pose received.
_TRAIL_STEP = math.radians(2.0)
_TRAIL_POINTS = 600
# The most (key, value) pairs of a report kept, and characters of a key.
_MAX_REPORT_VALUES = 64
_MAX_KEY = 80
# Names a one-line list of bodies shows before '... and N more'.
_NAMES_SHOWN = 5
# A quaternion whose norm is this far from 1 is not a rotation.
_QUATERNION_NORM_TOLERANCE = 1e-3


def number_verdict(value, limit=ABSURD):
    """Return 'not finite' or 'absurd' for a number the view must not show as one, else None."""
    if not math.isfinite(value):
        return 'not finite'
    if abs(value) > limit:
        return 'absurd'
    return None


def format_number(value, digits=9, signed=True):
    """
    Return `value` as the view prints it: `digits` significant digits, trailing zeros kept.

    None is 'not reported'; a number that is not finite or absurd (:data:`ABSURD`) is said
    to be so.  The terminal view and its test format a message's numbers with this function.
    """
    if value is None:
        return 'not reported'
    verdict = number_verdict(value)
    if verdict is not None:
        return verdict
    return f'{value:{"+" if signed else ""}#.{digits}g}'


def _state_verdict(quaternion, *vectors):
    """Return why a tick's numbers cannot be charted ('not finite', 'absurd'), or None."""
    values = np.concatenate([np.asarray(quaternion, dtype=float).ravel()]
                            + [np.asarray(v, dtype=float).ravel() for v in vectors])
    if not np.all(np.isfinite(values)):
        return 'not finite'
    if np.any(np.abs(values) > ABSURD) or abs(
            np.linalg.norm(quaternion) - 1.0) > _QUATERNION_NORM_TOLERANCE:
        return 'absurd'
    return None


@dataclass(eq=False, slots=True)
class Tick:
    """
    One tick of the node as its messages tell it.

    Attributes
    ----------
    stamp : int
        Header stamp in ns (the node's clock).
    quaternion : ndarray (4,)
        Orientation (x, y, z, w), body to world (odom's pose).
    position : ndarray (3,)
        COM position in m, world frame.
    angular_velocity_body : ndarray (3,)
        Omega in rad/s, body frame (odom's twist).
    angular_momentum : ndarray (3,)
        L about the COM in kg m^2/s, world frame.
    moved : bool
        Whether the state differs from the tick before (False while paused).
    time : float or None
        Simulated time in s, once a report has told it.
    rotational_energy : float
        T_rot = 1/2 Omega . (R^T L) in J (needs no inertia).
    momentum_magnitude : float
        |L| in kg m^2/s.

    """

    stamp: int
    quaternion: np.ndarray
    position: np.ndarray
    angular_velocity_body: np.ndarray
    angular_momentum: np.ndarray
    moved: bool = field(default=True, init=False)
    time: float = field(default=None, init=False)
    rotational_energy: float = field(default=0.0, init=False)
    momentum_magnitude: float = field(default=0.0, init=False)

    def __post_init__(self):
        """Hold the stamp as an int and the vectors as float arrays; compute T_rot, |L|."""
        self.stamp = int(self.stamp)
        self.quaternion = np.asarray(self.quaternion, dtype=float)
        self.position = np.asarray(self.position, dtype=float)
        self.angular_velocity_body = np.asarray(self.angular_velocity_body, dtype=float)
        self.angular_momentum = np.asarray(self.angular_momentum, dtype=float)
        # Once per tick, not per redraw: a snapshot reads them for every tick it holds.
        rotation = matrix_from_quaternion(self.quaternion / np.linalg.norm(self.quaternion))
        self.rotational_energy = 0.5 * float(
            self.angular_velocity_body @ (rotation.T @ self.angular_momentum))
        self.momentum_magnitude = float(np.linalg.norm(self.angular_momentum))


def middle_principal_axis(marker, body_quaternion):
    """
    Return the body's middle principal axis (unit, body frame) from its marker, or None.

    A box's or an ellipsoid's moment about an axis grows with the other two edges squared,
    so the middle moment is about the middle edge; None when two moments are equal (a
    cylinder, a square box: no flip) or the marker is not a shape.
    """
    try:
        shape = shape_from_marker(marker, body_quaternion)
    except ValueError:
        return None
    if shape.kind == 'cylinder' or not np.all(np.isfinite(shape.scale)):
        return None
    squares = np.asarray(shape.scale, dtype=float) ** 2
    moments = squares.sum() - squares
    order = np.argsort(moments)
    low, middle, high = moments[order]
    if not high > 0.0 or min(middle - low, high - middle) <= 1e-9 * high:
        return None
    axis = shape.orientation[:, order[1]]
    return axis / np.linalg.norm(axis)


class LiveState:
    """
    The node's recent motion and reports, fed from the listener's thread, read by a view.

    Every method takes the lock; the views read a consistent :meth:`snapshot`.

    Parameters
    ----------
    history : float
        Simulated seconds of ticks kept for the strip charts.

    """

    def __init__(self, history=20.0):
        self.history = float(history)
        self._lock = threading.Lock()
        self._odometry = {}
        self._momentum = {}
        self._ticks = deque()
        self._trail = deque(maxlen=_TRAIL_POINTS)
        self._pending_report = None
        self.node = None
        self.body = None
        self.bodies = ()
        self._publish_every = 1
        self._previous_report = None
        self.diagnostics = {}
        self.events = deque(maxlen=50)
        self.ticks_received = 0
        self.resets_seen = 0
        self.refused = {}
        self.warnings = {}
        self._announced = {}
        self._rate = None
        self._marker = None
        self.marker = None
        self.middle_axis = None
        self._input_active = False
        self._reset_motion()

    def _reset_motion(self):
        self._ticks.clear()
        self._trail.clear()
        self._reference = None
        self._reference_after = -math.inf
        self._flip_sign = 0
        self.flips = 0

    # -- input (the listener's thread)

    def set_node(self, name, body=None, bodies=()):
        """
        Say which node is watched (its fully qualified name), or None while none is.

        Of a node of bodies, `body` is the body watched (None: the table of them, or not
        chosen yet) and `bodies` the names of all, sorted.
        """
        with self._lock:
            self.bodies = tuple(bodies)
            if name != self.node or body != self.body:
                self._odometry.clear()
                self._momentum.clear()
                self._pending_report = None
                self.diagnostics = {}
                self._marker = self.marker = self.middle_axis = None
                self._rate = None
                self._publish_every = 1
                self._previous_report = None
                self._announced.clear()
                self.refused.clear()
                self.warnings.clear()
                self._reset_motion()
            self.node = name
            self.body = body

    def set_warning(self, topic, text):
        """Say (or with None stop saying) why a topic's messages are not taken now."""
        with self._lock:
            if text is None:
                self.warnings.pop(topic, None)
            else:
                self.warnings[topic] = shortened(text, 400)

    def refuse(self, topic, verdict):
        """Count a message of `topic` not taken, and why ('not finite', 'too large', ...)."""
        with self._lock:
            self._refuse(topic, verdict)

    def _refuse(self, topic, verdict):
        _, count = self.refused.get(topic, (None, 0))
        self.refused[topic] = (verdict, count + 1)

    def add_marker(self, stamp, marker):
        """Take a marker message (stamp ns): the drawing, paired with its tick's orientation."""
        with self._lock:
            if self.marker is None:
                self._marker = (int(stamp), marker)
                self._match_marker()

    @property
    def wants_marker(self):
        """Return True until a marker has been paired with its tick."""
        return self.marker is None

    def _match_marker(self):
        if self._marker is None:
            return
        stamp, marker = self._marker
        for tick in reversed(self._ticks):
            if tick.stamp == stamp:
                # (marker, the body's orientation at the marker's stamp)
                self.marker = (marker, tick.quaternion)
                self.middle_axis = middle_principal_axis(marker, tick.quaternion)
                self._marker = None
                return

    def add_odometry(self, stamp, quaternion, position, angular_velocity_body):
        """Take one odom message (stamp ns; pose in the world, Omega in the body frame)."""
        with self._lock:
            verdict = _state_verdict(quaternion, position, angular_velocity_body)
            if verdict is not None:
                self._refuse('odom', verdict)
                return
            self._odometry[int(stamp)] = (quaternion, position, angular_velocity_body)
            self._pair(int(stamp))

    def add_angular_momentum(self, stamp, angular_momentum):
        """Take one angular_momentum message (stamp ns, L in kg m^2/s, world frame)."""
        with self._lock:
            verdict = _state_verdict((0.0, 0.0, 0.0, 1.0), angular_momentum)
            if verdict is not None:
                self._refuse('angular_momentum', verdict)
                return
            self._momentum[int(stamp)] = angular_momentum
            self._pair(int(stamp))

    def add_diagnostics(self, stamp, values):
        """Take the node's /diagnostics status: its stamp (ns) and {key: value} (strings)."""
        # A peer's strings, cut and escaped once here: every view shows them as they are.
        values = {shortened(key, _MAX_KEY): shortened(value)
                  for key, value in list(values.items())[:_MAX_REPORT_VALUES]}
        with self._lock:
            previous = self.diagnostics
            self.diagnostics = values
            integrator = values.get('integrator')
            if previous.get('integrator') not in (None, integrator):
                # The node announces a switch on /parameter_events at once: one event.
                if self._announced.pop('integrator', None) != integrator:
                    self._note_change('integrator', integrator)
            if previous.get(DIAGNOSTICS_KEYS['paused']) != values.get(
                    DIAGNOSTICS_KEYS['paused']) and previous:
                paused = values.get(DIAGNOSTICS_KEYS['paused']) == 'True'
                self._note_change('paused' if paused else 'running', None)
            active = DIAGNOSTICS_KEYS['wrench_active']
            self._input_active = values.get(active) == 'True'
            if previous.get(active) == 'True' and values.get(active) == 'False':
                # The input ended: the conserved quantities hold again from here.
                self._reference = None
                last = self._ticks[-1] if self._ticks else None
                if last is not None and last.time is not None:
                    self._reference_after = last.time
            rate = self._float('rate', RATE_RANGE)
            if rate is not None:
                self._rate = rate
            every = self._float('publish_every', (1.0, RATE_RANGE[1]))
            # A node of bodies that publishes every k-th tick: each state k ticks apart.
            self._publish_every = 1 if every is None else int(every)
            self._pending_report = (int(stamp), self._float('simulated_time', (0.0, ABSURD)),
                                    rate)
            self._resolve_report()

    def add_parameter_change(self, name, value):
        """Take a parameter the node announces it changed (/parameter_events)."""
        with self._lock:
            if name in ('integrator', 'tolerance', 'substeps', 'real_time_factor'):
                if isinstance(value, float) and number_verdict(value) is not None:
                    value = number_verdict(value)
                value = shortened(value, 60)
                self._announced[name] = value
                self._note_change(name, value)

    def _note_change(self, name, value):
        last = self._ticks[-1] if self._ticks else None
        time = None if last is None else last.time
        self.events.append((time, name, value))

    def _float(self, key, bounds):
        """Return the report's number under `key` if it is one within `bounds`, else None."""
        try:
            value = float(self.diagnostics[DIAGNOSTICS_KEYS[key]])
        except (KeyError, ValueError, OverflowError):
            return None
        low, high = bounds
        return value if low <= value <= high else None

    def _pair(self, stamp):
        if stamp not in self._odometry or stamp not in self._momentum:
            # The two topics of a tick arrive apart: keep the unpaired ones a while.
            if len(self._odometry) > 64 or len(self._momentum) > 64:
                oldest = sorted(set(self._odometry) | set(self._momentum))[:-32]
                for key in oldest:
                    self._odometry.pop(key, None)
                    self._momentum.pop(key, None)
            return
        quaternion, position, omega = self._odometry.pop(stamp)
        tick = Tick(stamp, quaternion, position, omega, self._momentum.pop(stamp))
        self.ticks_received += 1
        last = self._ticks[-1] if self._ticks else None
        if last is not None:
            tick.moved = not (np.array_equal(tick.quaternion, last.quaternion)
                              and np.array_equal(tick.angular_velocity_body,
                                                 last.angular_velocity_body)
                              and np.array_equal(tick.position, last.position))
            if last.time is not None and self._rate is not None:
                tick.time = last.time + (
                    self._publish_every / self._rate if tick.moved else 0.0)
        self._ticks.append(tick)
        self._extend_trail(tick)
        self._count_flip(tick)
        self._match_marker()
        self._resolve_report()
        self._forget_old()

    def _extend_trail(self, tick):
        if self._trail:
            # The angle between two orientations: 2 acos |q1 . q2|.
            dot = min(1.0, abs(float(self._trail[-1] @ tick.quaternion)))
            if 2.0 * math.acos(dot) < _TRAIL_STEP:
                return
        self._trail.append(tick.quaternion)

    def _resolve_report(self):
        """Pair the waiting report with its tick, once a later tick shows which that is."""
        if self._pending_report is None or not self._ticks:
            return
        stamp, simulated, rate = self._pending_report
        if simulated is None or rate is None:
            self._pending_report = None
            return
        if self._ticks[-1].stamp <= stamp:
            return  # the report's own tick, or a later one, may still come
        self._pending_report = None
        previous, self._previous_report = self._previous_report, simulated
        ticks = self._ticks
        index = len(ticks) - 1
        while index > 0 and ticks[index].stamp > stamp:
            index -= 1
        if ticks[index].stamp > stamp:
            return  # the report's tick came before the first one kept
        expected = ticks[index].time
        period = 1.0 / rate
        if expected is not None and abs(expected - simulated) <= 0.5 * period:
            return
        reset = expected is not None and simulated < expected - 0.5 * period
        if self.bodies:
            # A node of bodies publishes every k-th tick, k chosen anew at each report: the
            # ticks counted since the last report may be a few off, and are re-timed here.
            # Time going back from the last report is a reset; a count that ran ahead is not.
            reset = previous is not None and simulated < previous - 0.5 * period
        # Re-time from the report: backwards to the first tick, forwards to the last (the
        # states k ticks apart where the node publishes every k-th tick).
        spacing = self._publish_every * period
        ticks[index].time = simulated
        for k in range(index - 1, -1, -1):
            ticks[k].time = ticks[k + 1].time - (spacing if ticks[k + 1].moved else 0.0)
        for k in range(index + 1, len(ticks)):
            ticks[k].time = ticks[k - 1].time + (spacing if ticks[k].moved else 0.0)
        if reset:
            self.resets_seen += 1
            # The ticks before the reset come out at or before time 0: forget them and all
            # that was counted on them.  A running node steps in the tick that resets, so
            # its first state after a reset is at one period and the one at 0 is the last
            # before it; a paused one publishes the initial state itself, at 0, and the
            # ticks after it did not move.
            kept = [tick for k, tick in enumerate(ticks) if tick.time > 0.5 * period or (
                tick.time > -0.5 * period and tick.moved
                and (k + 1 == len(ticks) or not ticks[k + 1].moved))]
            self._reset_motion()
            self._ticks.extend(kept)
            for tick in kept:
                self._extend_trail(tick)
                self._count_flip(tick)
            self.events.append((0.0, 'reset', None))

    def _forget_old(self):
        last = self._ticks[-1]
        limit = _PENDING_TICKS if last.time is None else _MAX_TICKS
        while len(self._ticks) > limit:
            self._ticks.popleft()
        if last.time is None:
            return
        while self._ticks and (self._ticks[0].time is None
                               or self._ticks[0].time < last.time - self.history):
            self._ticks.popleft()

    def _count_flip(self, tick):
        if self.middle_axis is None:
            return
        if self._input_active:
            # Pushed, the body may turn any way: count again once it is free.
            self._flip_sign = 0
            return
        omega = tick.angular_velocity_body
        value = float(omega @ self.middle_axis)
        level = _FLIP_LEVEL * float(np.linalg.norm(omega))
        if level <= 0.0:
            return
        if self._flip_sign == 0:
            if abs(value) > level:
                self._flip_sign = 1 if value > 0.0 else -1
        elif self._flip_sign > 0 and value < -level:
            self._flip_sign, self.flips = -1, self.flips + 1
        elif self._flip_sign < 0 and value > level:
            self._flip_sign, self.flips = 1, self.flips + 1

    # -- output (a view's thread)

    def snapshot(self):
        """Return a :class:`Snapshot` of what is known now (copies, safe to read)."""
        with self._lock:
            timed = [tick for tick in self._ticks if tick.time is not None]
            latest = self._ticks[-1] if self._ticks else None
            if self._reference is None:
                first = next((tick for tick in timed if tick.time >= self._reference_after),
                             None)
                if first is not None:
                    self._reference = (first.rotational_energy, first.momentum_magnitude,
                                       first.time)
            return Snapshot(
                node=self.node, body=self.body, bodies=self.bodies, latest=latest,
                timed=timed, diagnostics=dict(self.diagnostics),
                flips=self.flips, middle_axis=self.middle_axis, events=list(self.events),
                reference=self._reference, ticks_received=self.ticks_received,
                marker=self.marker, resets_seen=self.resets_seen,
                trail=np.array(self._trail).reshape(-1, 4), refused=dict(self.refused),
                warnings=dict(self.warnings))


class Snapshot:
    """
    What a view draws: the latest tick, the timed ticks of the chart window, the reports.

    Attributes
    ----------
    node : str or None
        The watched node's fully qualified name.
    body : str or None
        Of a node of bodies, the body watched (None: a one-body node, or the table).
    bodies : tuple of str
        Of a node of bodies, the names of its bodies, sorted (empty for a one-body node).
    latest : Tick or None
        The newest tick.
    time, angular_velocity_body, momentum_magnitude : arrays (n,), (n, 3), (n,)
        The timed ticks (simulated s; rad/s, body frame; kg m^2/s).
    rotational_energy : ndarray (n,)
        T_rot = 1/2 Omega . R^T L in J.
    diagnostics : dict
        The node's last /diagnostics report, {key: value}, its strings cut and escaped.
    flips : int
        Flips seen since the watch started (or the node's last reset): sign changes of
        Omega's component along the middle principal axis while the body was free.
    middle_axis : ndarray (3,) or None
        The middle principal axis in the body frame (None: not known, or none).
    events : list of (time or None, name, value)
        Resets, pauses, integrator and tolerance switches, in order, one per change.
    reference : (T_rot, |L|, time) or None
        The values the drifts are counted from: the first timed tick after the start, a
        reset or the end of an outside input.
    ticks_received : int
        Ticks received since the watch started.
    marker : (Marker, ndarray (4,)) or None
        The node's marker message and the body's orientation at its stamp.
    resets_seen : int
        Resets seen since the watch started.
    trail : ndarray (k, 4)
        Recent orientations (x, y, z, w), one each time the body turned 2 degrees.
    refused : dict
        {topic: (why, how many)} of the messages not taken (not finite, absurd, too large,
        from another publisher).
    warnings : dict
        {topic: sentence} of what the listener says of a topic now (another publisher).

    """

    def __init__(self, node, latest, timed, diagnostics, flips, middle_axis, events,
                 reference, ticks_received, marker=None, resets_seen=0, trail=None,
                 refused=None, warnings=None, body=None, bodies=()):
        self.node = node
        self.body = body
        self.bodies = tuple(bodies)
        self.marker = marker
        self.resets_seen = resets_seen
        self.latest = latest
        self.time = np.array([tick.time for tick in timed])
        self.angular_velocity_body = np.array(
            [tick.angular_velocity_body for tick in timed]).reshape(-1, 3)
        self.momentum_magnitude = np.array([tick.momentum_magnitude for tick in timed])
        self.rotational_energy = np.array([tick.rotational_energy for tick in timed])
        self.diagnostics = diagnostics
        self.flips = flips
        self.middle_axis = middle_axis
        self.events = events
        self.reference = reference
        self.ticks_received = ticks_received
        self.trail = np.zeros((0, 4)) if trail is None else trail
        self.refused = refused or {}
        self.warnings = warnings or {}

    def value(self, key):
        """Return the report's value of a :data:`DIAGNOSTICS_KEYS` key, or None."""
        return self.diagnostics.get(DIAGNOSTICS_KEYS[key])

    def shown(self, key):
        """
        Return the report's value of a key as the views print it.

        'not reported' if missing; a number that is not finite or absurd said to be so;
        any other text as it came (already cut and escaped).
        """
        text = self.value(key)
        if text is None:
            return 'not reported'
        try:
            number = float(text)
        except (ValueError, OverflowError):
            return text
        return number_verdict(number) or text

    def number(self, key):
        """Return the report's value of a key as a float, or None (also if not finite)."""
        try:
            value = float(self.value(key))
        except (TypeError, ValueError, OverflowError):
            return None
        return value if number_verdict(value) is None else None

    @property
    def watched(self):
        """Return what is watched as the views name it: the node, and its body if one."""
        if self.body is None:
            return self.node
        if self.body not in self.bodies:
            return f'{self.node} body {self.body}'
        return (f'{self.node} body {self.body} ({self.bodies.index(self.body) + 1} of '
                f'{len(self.bodies)})')

    @property
    def current_time(self):
        """Return the simulated time of the newest tick (s), or None before a report."""
        return None if self.latest is None else self.latest.time

    @property
    def flips_since(self):
        """Return since when the flips are counted, as the views say it."""
        return 'since the reset' if self.resets_seen else 'since watch started'

    @property
    def torque_free(self):
        """
        Return True if the scene's effects leave T_rot and |L| conserved (no input).

        Each effect's class declares what it conserves; an effect this version does not
        know conserves nothing.
        """
        effects = self.value('effects')
        if effects is None:
            return False
        names = {name.strip() for name in effects.split(',')} - {'none', ''}
        return all(name in EFFECTS and _TORQUE_FREE <= set(EFFECTS[name].conserves)
                   for name in names)

    def drifts(self):
        """
        Return (time, T_rot drift, |L| drift) since the reference, relative, of the window.

        Only the ticks at or after the reference; empty arrays before a report.
        """
        if self.reference is None or not len(self.time):
            empty = np.zeros(0)
            return empty, empty, empty
        energy0, momentum0, start = self.reference
        after = self.time >= start
        energy = (self.rotational_energy[after] - energy0) / (abs(energy0) or 1.0)
        momentum = (self.momentum_magnitude[after] - momentum0) / (momentum0 or 1.0)
        return self.time[after], energy, momentum


def bodies_text(names):
    """Return a list of body names as one line: the first few, and how many more."""
    names = [shortened(name, 80) for name in names]
    shown = ', '.join(names[:_NAMES_SHOWN])
    if len(names) > _NAMES_SHOWN:
        shown += f' ... and {len(names) - _NAMES_SHOWN} more'
    return shown


class BodyTable:
    """
    The latest state of each body a table of a node's bodies shows, fed by the listener.

    Only the numbers a row prints are kept, each body's from its own topics (odom: the
    position in m, world frame, |Omega| in rad/s and the COM speed in m/s; angular_momentum:
    |L| in kg m^2/s); a state whose numbers are not finite or absurd is refused as
    :class:`LiveState` refuses it, and the row says so.
    """

    def __init__(self):
        self._lock = threading.Lock()
        self._rows = {}

    def clear(self):
        """Forget every row (another node, or other bodies shown)."""
        with self._lock:
            self._rows.clear()

    def keep_only(self, names):
        """Forget the rows of the bodies not in `names` (no longer shown)."""
        with self._lock:
            for name in set(self._rows) - set(names):
                del self._rows[name]

    def add_odometry(self, name, quaternion, position, angular_velocity_body, velocity):
        """Take body `name`'s odom: pose in the world, Omega and the COM velocity (any frame)."""
        verdict = _state_verdict(quaternion, position, angular_velocity_body, velocity)
        with self._lock:
            row = self._rows.setdefault(name, {})
            if verdict is not None:
                row['refused'] = verdict
                return
            row.pop('refused', None)
            row['position'] = tuple(float(value) for value in position)
            row['omega'] = float(np.linalg.norm(angular_velocity_body))
            row['speed'] = float(np.linalg.norm(velocity))

    def add_angular_momentum(self, name, angular_momentum):
        """Take body `name`'s L (kg m^2/s, world frame)."""
        verdict = _state_verdict((0.0, 0.0, 0.0, 1.0), angular_momentum)
        with self._lock:
            row = self._rows.setdefault(name, {})
            if verdict is not None:
                row['refused'] = verdict
                return
            row['momentum'] = float(np.linalg.norm(angular_momentum))

    def rows(self):
        """Return {name: {'position', 'omega', 'speed', 'momentum', 'refused'}} (copies)."""
        with self._lock:
            return {name: dict(row) for name, row in self._rows.items()}

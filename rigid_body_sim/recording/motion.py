"""
The motion recorded in a bag, and the quantities the physics conserves in it.

:func:`read_motion` reads a bag into a :class:`BagMotion` (arrays over its ticks), and
:func:`conserved_quantities` says what its scene conserves; ``rigid-body-sim plot`` draws
them (:mod:`.plot`) and ``rigid-body-sim animate`` turns the body with them (:mod:`.animate`).

The motion comes from two of the node's topics, so any bag of the node works (recorded
live, by ``ros2 bag record``, or written offline):

- ``odom`` (nav_msgs/Odometry): the orientation q and COM position x in the world frame,
  and in the body frame the COM velocity and the angular velocity Omega (the node gives
  odom's twist in the body frame);
- ``angular_momentum`` (geometry_msgs/Vector3Stamped): L about the COM, world frame.

Messages of the two topics are paired by their header stamp (each tick stamps all alike).

Several bodies.  A bag of a scene of ``bodies:`` has each body's topics under its name
(``<ns>/<name>/odom``, ...) and, offline, a custom data list of the bodies with each one's
mass, inertia, shape and effects (``rigid_body_sim.bodies``): :func:`bag_bodies` finds
them (in a live bag, by their topics), ``read_motion(bag, body=NAME)`` reads one as a bag
of one body is read, with its own mass, inertia and effects as a one-body bag names them
(:func:`body_custom_data`), and :func:`read_body_motions` reads several in one pass.

Time.  The time axis is simulated time from the scene's start: an offline bag names the
stamp of simulated time 0 in its custom data, and the node's stamps with ``publish_clock``
are simulated time already; so a 5 s run at 100 Hz shows ticks at 0.01 .. 5 s.  A live bag
stamped with the wall clock has its ticks arrive as the machine schedules them (under load
far from evenly): when it holds the node's /diagnostics, whose reports say the
simulated time and rate once a second in the tick of a state, each tick is timed from the
last report before it plus one period per tick whose state moved (a paused tick adds none;
a reset restarts at its report's time).  Without reports the wall-clock time from the first
message is shown, and the panel titles say how irregular the stamps are.

Conserved quantities.  What is conserved depends on the scene's effects.  An offline bag
names them, their parameters and the body's mass and inertia in its custom data (keys
``rigid_body_sim.*``); a live bag carries none of it and is treated as torque-free, which
the panel says.

- Torque-free about the COM (no effect, or uniform gravity, which acts at the COM):
  the rotational energy T_rot = 1/2 Omega . (R^T L), which needs no inertia, and |L|.
- Internal dissipation: |L| (internal friction exerts no external torque), while T_rot
  drains toward the spin about the major axis.
- A pivot (a body point held fixed), with or without gravity: the total energy
  E = T_rot + 1/2 m |v|^2 - m g . x (the pivot's reaction does no work: its point does not
  move); the angular momentum about the pivot, L_p = L + m (x - a) x v (a the anchor),
  along gravity (the weight's torque about the pivot is horizontal), all of it without
  gravity; and for a body symmetric about an axis e3 through the pivot (a Lagrange top,
  a wheel on its axle) L . e3 = I3 omega3, as the torque r x m g is normal to e3.
- Drag, a torque oscillating in time: none.

Each effect's class declares what it conserves (``conserves``, ``keeps_pivot_invariants``:
physics/effects/registry.py), so a new effect needs no case here.

Each drift is relative to a physical scale: the energy's to the initial kinetic energy
(the potential's zero is arbitrary), a momentum's to the initial |L| (a component may start
at zero).
"""

from dataclasses import dataclass
import json
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.rosbag2 import ReaderError
import yaml

from .bag_writer import CUSTOM_DATA_PREFIX
from .bag_writer import typestore
from ..physics import matrix_from_quaternion
from ..physics.effects import EFFECTS
from ..physics.effects import load_effect_file
from ..physics.principal_frame import principal_frame

__all__ = [
    'BagMotion',
    'BagBodies',
    'ConservedQuantity',
    'bag_bodies',
    'body_custom_data',
    'conserved_quantities',
    'not_a_bag',
    'read_body_motions',
    'read_custom_data',
    'read_motion',
    'simulated_time_from_reports',
    'symmetry_axis',
    'time_of_stamps',
]

_ODOMETRY = 'nav_msgs/msg/Odometry'
_MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'
# The file endings of rosbag2's storage files (MCAP, sqlite3).
_STORAGE_SUFFIXES = ('.mcap', '.db3')
_DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
_VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
# Stamps before this (one year after the epoch, ns) are simulated time, not the wall clock.
_SIMULATED_STAMPS_BEFORE = 365 * 86400 * 10**9
# libyaml's loader where PyYAML has it: a bag of 100 bodies has a metadata.yaml of 500 topics,
# which a pure-Python parser reads in seconds.
_YAML_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
# Two principal moments closer than this (relative to the largest) are equal: the body is
# symmetric about the third axis.
_SYMMETRY_TOLERANCE = 1e-9
# The inertia a live bag's motion shows is taken when the motion spans all six of its
# components (the least singular value of the fit at least this fraction of the largest) and
# L = I Omega holds to this fraction of |L| over the ticks.
_FIT_CONDITION = 1e-6
_FIT_RESIDUAL = 1e-6


class BagMotion:
    """
    The motion in a bag, as arrays over the paired ticks (n of them).

    Attributes
    ----------
    time : ndarray (n,)
        Simulated time in s from the scene's start (see the module docstring), or, for a
        bag stamped with the wall clock, s from the first message.
    time_is_simulated : bool
        Whether `time` is simulated time from the start.
    stamps : ndarray (n,) of int64
        The header stamps, ns.
    quaternion : ndarray (n, 4)
        Orientation (x, y, z, w), body to world.
    position : ndarray (n, 3)
        COM position in m, world frame.
    velocity_body : ndarray (n, 3)
        COM velocity in m/s, body frame (odom's twist.linear).
    angular_velocity_body : ndarray (n, 3)
        Omega in rad/s, body frame.
    angular_momentum : ndarray (n, 3)
        L about the COM in kg m^2/s, world frame.
    custom_data : dict
        The bag's custom data (scene, integrator, mass, effects, ... of an offline run); of
        one body of a bag of bodies, with that body's mass, inertia and effects
        (:func:`body_custom_data`).
    body : str or None
        The body's name in a bag of several bodies, None in a bag of one.

    """

    def __init__(self, stamps, quaternion, position, angular_velocity_body, angular_momentum,
                 custom_data, name, velocity_body=None, reports=(), body=None):
        self.stamps = np.asarray(stamps, dtype=np.int64)
        self.custom_data = dict(custom_data or {})
        origin, self.time_is_simulated = _time_origin(self.stamps, self.custom_data)
        # Division, not * 1e-9: correctly rounded, so tick 500 at 100 Hz reads 5.0 exactly.
        self.time = (self.stamps - origin) / 1e9
        self.timed_by_reports = False
        self.quaternion = np.asarray(quaternion, dtype=float)
        self.position = np.asarray(position, dtype=float)
        self.angular_velocity_body = np.asarray(angular_velocity_body, dtype=float)
        self.angular_momentum = np.asarray(angular_momentum, dtype=float)
        self.velocity_body = (np.zeros_like(self.position) if velocity_body is None
                              else np.asarray(velocity_body, dtype=float))
        self.name = name
        self.body = body
        self._rotation = None
        if not self.time_is_simulated and len(reports):
            timed = simulated_time_from_reports(self.stamps, self._moved(), reports)
            if timed is not None:
                self.time, self.time_is_simulated, self.timed_by_reports = timed, True, True

    def _moved(self):
        """Return whether each tick's state differs from the one before (n,) bool."""
        state = np.hstack((self.quaternion, self.angular_velocity_body, self.position))
        moved = np.ones(len(state), dtype=bool)
        moved[1:] = np.any(state[1:] != state[:-1], axis=1)
        return moved

    @property
    def stamp_spacing(self):
        """Return (least, largest) spacing of the header stamps in s, or None for one tick."""
        if len(self.stamps) < 2:
            return None
        spacing = np.diff(self.stamps) / 1e9
        return float(spacing.min()), float(spacing.max())

    @property
    def rotation(self):
        """Return R (n, 3, 3), body to world, of the quaternions (computed once)."""
        if self._rotation is None:
            self._rotation = np.array([matrix_from_quaternion(q) for q in self.quaternion])
        return self._rotation

    @property
    def velocity(self):
        """Return the COM velocity v = R v_body in m/s, world frame, (n, 3)."""
        return np.einsum('nij,nj->ni', self.rotation, self.velocity_body)

    @property
    def rotational_energy(self):
        """Return T_rot = 1/2 Omega . (R^T L) in J, (n,)."""
        momentum_body = np.einsum('nji,nj->ni', self.rotation, self.angular_momentum)
        return 0.5 * np.einsum('ni,ni->n', self.angular_velocity_body, momentum_body)

    @property
    def momentum_magnitude(self):
        """Return |L| in kg m^2/s, (n,)."""
        return np.linalg.norm(self.angular_momentum, axis=1)

    def custom(self, key, default=None):
        """Return the custom data value ``rigid_body_sim.<key>`` (a string), or `default`."""
        return self.custom_data.get(CUSTOM_DATA_PREFIX + key, default)

    @property
    def mass(self):
        """Return the body's mass in kg from the custom data, or None if the bag lacks it."""
        value = self.custom('mass')
        return None if value is None else float(value)

    @property
    def inertia(self):
        """Return the inertia about the COM (3, 3) in kg m^2, body frame, or None."""
        value = self.custom('inertia')
        return None if value is None else np.array(value.split(), dtype=float).reshape(3, 3)

    @property
    def effects(self):
        """
        Return the scene's effects as a list of {'effect': name, parameter: value}, or None.

        None when the bag does not name them (a live recording); an offline bag of an
        older version names them without parameters.
        """
        parameters = self.custom('effect_parameters')
        if parameters is not None:
            return json.loads(parameters)
        names = self.custom('effects')
        if names is None:
            return None
        return [{'effect': name.strip()} for name in names.split(',')
                if name.strip() and name.strip() != 'none']

    @property
    def body_shape(self):
        """
        Return the shape the scene gave the body ('box', ...), '' if given by inertia, or None.

        None when the bag does not say (a live recording, or an offline bag of an older
        version).
        """
        return self.custom('body_shape')

    def inertia_seen(self):
        """
        Return the inertia (3, 3) in kg m^2, body frame: the one the bag names, or the motion's.

        A live bag names none; its motion shows it where L = I Omega (in the body frame, R^T
        L) pins down all six components: the least-squares fit over the ticks.  None when
        the motion does not (a steady spin about one axis shows one column of I).
        """
        named = self.inertia
        if named is not None:
            return named
        step = max(1, len(self.stamps) // 2000)
        omega = self.angular_velocity_body[::step]
        momentum = np.einsum('nji,nj->ni', self.rotation[::step], self.angular_momentum[::step])
        if len(omega) < 2 or not (np.all(np.isfinite(omega)) and np.all(np.isfinite(momentum))):
            return None
        # Unknowns (Ixx, Iyy, Izz, Ixy, Ixz, Iyz); three equations per tick.
        x, y, z = omega.T
        zero = np.zeros_like(x)
        design = np.concatenate([np.stack([x, zero, zero, y, z, zero], axis=1),
                                 np.stack([zero, y, zero, x, zero, z], axis=1),
                                 np.stack([zero, zero, z, zero, x, y], axis=1)])
        target = np.concatenate(momentum.T)
        values, _, rank, singular = np.linalg.lstsq(design, target, rcond=None)
        if rank < 6 or singular[-1] < _FIT_CONDITION * singular[0]:
            return None
        xx, yy, zz, xy, xz, yz = values
        inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        fitted = design @ values
        if np.linalg.norm(fitted - target) > _FIT_RESIDUAL * np.linalg.norm(target) or \
                np.any(np.linalg.eigvalsh(inertia) <= 0.0):
            return None
        return inertia

    def total_energy(self, gravity):
        """Return E = T_rot + 1/2 m |v|^2 - m g . x in J, (n,); `gravity` in m/s^2 or None."""
        mass = self.mass
        velocity = self.velocity
        energy = self.rotational_energy + 0.5 * mass * np.einsum('ni,ni->n', velocity, velocity)
        if gravity is not None:
            energy -= mass * (self.position @ np.asarray(gravity, dtype=float))
        return energy

    def angular_momentum_about(self, point):
        """Return L_p = L + m (x - p) x v in kg m^2/s about the world point `point`, (n, 3)."""
        arm = self.position - np.asarray(point, dtype=float)
        return self.angular_momentum + self.mass * np.cross(arm, self.velocity)


def simulated_time_from_reports(stamps, moved, reports):
    """
    Return the simulated time (s) of live ticks from the node's reports, or None.

    `stamps` (n,) are the ticks' header stamps (ns) and `moved` (n,) whether each tick's
    state differs from the one before; `reports` are (stamp ns, simulated time s, rate Hz)
    of the node's /diagnostics.  A report belongs to the latest tick stamped at or before it
    (the node publishes a tick's state, then its report); a tick is timed from the last
    report at or before it, plus one period per moving tick since; ticks before the first
    report count back from it.  None if no report falls among the ticks.
    """
    reports = sorted(reports)
    anchors = []  # (tick index, simulated time, rate)
    for stamp, simulated, rate in reports:
        index = int(np.searchsorted(stamps, stamp, side='right')) - 1
        if 0 <= index < len(stamps) and rate > 0.0:
            anchors.append((index, simulated, rate))
    if not anchors:
        return None
    steps = np.cumsum(moved.astype(float))  # moving ticks up to and including each
    time = np.empty(len(stamps))
    first, first_time, first_rate = anchors[0]
    time[:first] = first_time - (steps[first] - steps[:first]) / first_rate
    bounds = [anchor[0] for anchor in anchors[1:]] + [len(stamps)]
    for (index, simulated, rate), end in zip(anchors, bounds):
        time[index:end] = simulated + (steps[index:end] - steps[index]) / rate
    return time


def time_of_stamps(stamps, custom_data):
    """
    Return (time s, whether it is simulated time) of header stamps (ns) of a bag.

    Simulated time from the scene's start where the bag says when that was or its stamps
    are simulated time; else s from the first stamp (see the module docstring).
    """
    stamps = np.asarray(stamps, dtype=np.int64)
    origin, simulated = _time_origin(stamps, dict(custom_data or {}))
    return (stamps - origin) / 1e9, simulated


def _time_origin(stamps, custom_data):
    """Return (stamp of time 0 in ns, whether the time is simulated time)."""
    start = custom_data.get(CUSTOM_DATA_PREFIX + 'start_time')
    if start is not None:
        return int(start), True
    if stamps[0] < _SIMULATED_STAMPS_BEFORE:
        return 0, True
    return int(stamps[0]), False


@dataclass(eq=False)
class ConservedQuantity:
    """
    A quantity the physics of the scene conserves (or, with `conserved` False, shown anyway).

    Attributes
    ----------
    label : str
        Its name in mathtext, e.g. '$E = T + V$'.
    values : ndarray (n,)
        Its value at each tick.
    unit : str
        Its unit.
    scale, scale_label : float, str
        The physical scale its drift is divided by, and that scale's name.
    conserved : bool
        Whether the physics conserves it here.

    """

    label: str
    values: np.ndarray
    unit: str
    scale: float
    scale_label: str
    conserved: bool = True

    def __post_init__(self):
        """Hold the values as a float array and the scale as a float."""
        self.values = np.asarray(self.values, dtype=float)
        self.scale = float(self.scale)

    @property
    def drift(self):
        """Return (X(t) - X(first)) / scale (absolute if the scale is 0)."""
        change = self.values - self.values[0]
        return change / self.scale if self.scale != 0.0 else change


def _effect(effects, name):
    for effect in effects:
        if effect.get('effect') == name:
            return effect
    return None


def symmetry_axis(inertia):
    """
    Return the unit axis (body frame) a body is symmetric about, or None.

    A body is symmetric about the principal axis of its odd moment when the other two are
    equal (to 1e-9 of the largest); `inertia` is (3, 3) in kg m^2 about the COM.
    """
    frame = principal_frame(inertia)
    moments, axes = frame.moments, frame.axes
    tolerance = _SYMMETRY_TOLERANCE * moments[-1]
    if abs(moments[1] - moments[0]) <= tolerance and abs(moments[2] - moments[1]) > tolerance:
        return axes[:, 2]
    if abs(moments[2] - moments[1]) <= tolerance and abs(moments[1] - moments[0]) > tolerance:
        return axes[:, 0]
    return None


def conserved_quantities(motion):
    """
    Return (title, [ConservedQuantity]) of what the scene of `motion` conserves.

    See the module docstring for the physics; the title says what is conserved and why.
    """
    rotational = ConservedQuantity(
        '$T_{rot} = \\frac{1}{2}\\,\\Omega \\cdot R^T L$', motion.rotational_energy, 'J',
        motion.rotational_energy[0], '$T_{rot}(0)$')
    magnitude = ConservedQuantity('$|L|$', motion.momentum_magnitude, 'kg m$^2$/s',
                                  motion.momentum_magnitude[0], '$|L(0)|$')
    effects = motion.effects
    if effects is None:
        return ('Drift of $T_{rot}$ and $|L|$ (conserved if torque-free about the COM; the '
                'bag does not name the effects)', [rotational, magnitude])
    names = {effect['effect'] for effect in effects}
    # What each effect conserves, as its class declares it (physics/effects/registry.py); an
    # effect this version does not know conserves nothing.
    classes = effect_classes(motion, names)
    if 'pivot' in names:
        pivot = _effect(effects, 'pivot')
        kept = all(cls is not None and cls.keeps_pivot_invariants
                   for name, cls in classes.items() if name != 'pivot')
        if kept and motion.mass is not None and 'anchor' in pivot:
            return _pivot_quantities(motion, pivot, _effect(effects, 'gravity'))
        for quantity in (rotational, magnitude):
            quantity.conserved = False
        reason = (', '.join(sorted(names)) if not kept
                  else 'the pivot torques the body; the bag lacks its parameters')
        return (f'$T_{{rot}}$ and $|L|$: not conserved here ({reason})',
                [rotational, magnitude])
    conserved = {'angular_momentum', 'rotational_energy'}
    for cls in classes.values():
        conserved &= set(() if cls is None else cls.conserves)
    rotational.conserved = 'rotational_energy' in conserved
    magnitude.conserved = 'angular_momentum' in conserved
    if rotational.conserved and magnitude.conserved:
        return 'Conserved without torque about the COM: drift of $T_{rot}$ and $|L|$', \
            [rotational, magnitude]
    if magnitude.conserved:
        changing = sorted(name for name, cls in classes.items()
                          if cls is None or 'rotational_energy' not in cls.conserves)
        return (f'$|L|$ is conserved; {", ".join(changing)} changes $T_{{rot}}$',
                [magnitude, rotational])
    return (f'$T_{{rot}}$ and $|L|$: not conserved here ({", ".join(sorted(names))})',
            [rotational, magnitude])


def effect_classes(motion, names):
    """
    Return {effect name: its class, or None if unknown here} of the bag's effects `names`.

    An installed plugin's effect is found by its entry point; a plugin file that the bag's
    scene named (``plugins:``, recorded by ``simulate`` as ``effect_plugins``) is loaded
    first if it is still there (one that no longer loads leaves its effects unknown).
    """
    try:
        files = json.loads(motion.custom('effect_plugins') or '[]')
    except ValueError:
        files = []
    for path in files if isinstance(files, list) else []:
        try:
            load_effect_file(str(path))
        except ValueError:
            continue
    return {name: EFFECTS.get(name) for name in names}


def _pivot_quantities(motion, pivot, gravity):
    """Return the conserved quantities of a body turning about a fixed point (see above)."""
    acceleration = None if gravity is None else np.asarray(gravity['acceleration'], float)
    velocity = motion.velocity
    kinetic = motion.rotational_energy[0] + 0.5 * motion.mass * float(velocity[0] @ velocity[0])
    quantities = [ConservedQuantity(
        '$E = T + V$' if acceleration is not None else '$E = T$',
        motion.total_energy(acceleration), 'J', kinetic, '$T(0)$')]
    about_pivot = motion.angular_momentum_about(pivot['anchor'])
    scale = float(np.linalg.norm(about_pivot[0]))
    if acceleration is not None and np.any(acceleration):
        up = -acceleration / np.linalg.norm(acceleration)
        if np.allclose(up, (0.0, 0.0, 1.0)):
            label = '$L_{p,z}$ (world z, about the pivot)'
        else:
            label = '$L_p \\cdot \\hat{u}$ (up, about the pivot)'
        quantities.append(ConservedQuantity(label, about_pivot @ up, 'kg m$^2$/s', scale,
                                            '$|L_p(0)|$'))
    else:
        quantities.append(ConservedQuantity('$|L_p|$ (about the pivot)',
                                            np.linalg.norm(about_pivot, axis=1), 'kg m$^2$/s',
                                            scale, '$|L_p(0)|$'))
    inertia = motion.inertia
    axis = None if inertia is None else symmetry_axis(inertia)
    point = np.asarray(pivot.get('point', (0.0, 0.0, 0.0)), dtype=float)
    if axis is not None and np.linalg.norm(np.cross(point, axis)) <= \
            _SYMMETRY_TOLERANCE * max(np.linalg.norm(point), 1e-300):
        # The symmetry axis in the world frame at each tick; its sign as given.
        axis_world = np.einsum('nij,j->ni', motion.rotation, axis)
        along = np.einsum('ni,ni->n', motion.angular_momentum, axis_world)
        name = {0: 'x', 1: 'y', 2: 'z'}.get(int(np.argmax(np.abs(axis))), '3')
        quantities.append(ConservedQuantity(
            f'$L \\cdot e_3$ (body {name} axis: symmetry axis through the pivot)', along,
            'kg m$^2$/s', scale, '$|L_p(0)|$'))
    title = 'Conserved about the pivot: energy, ' + (
        'vertical $L_p$' if len(quantities) > 1 and acceleration is not None else '$|L_p|$')
    if len(quantities) == 3:
        title += ', spin $L \\cdot e_3$'
    return title, quantities


def _find_topic(connections, suffix, message_type, namespace):
    wanted = f'{namespace}/{suffix}'
    candidates = [c for c in connections if c.msgtype == message_type]
    for connection in candidates:
        if connection.topic == wanted:
            return connection
    matching = [c for c in candidates if c.topic.endswith('/' + suffix)]
    if len(matching) == 1:
        return matching[0]
    found = ', '.join(f'{c.topic} ({c.msgtype})' for c in connections) or 'none'
    raise ValueError(f'the bag has no single {message_type} topic named {wanted!r} (or '
                     f'ending in /{suffix}); its topics: {found}')


@dataclass(eq=False)
class BagBodies:
    """
    The bodies of a bag of several (``simulate`` or ``record`` of a scene of ``bodies:``).

    Attributes
    ----------
    names : list of str
        The bodies' names, in the scene's order (an offline bag's custom data) or sorted
        (a live bag's topics); empty for a bag of one body.
    entries : dict
        Name -> the body's entry in the custom data ``rigid_body_sim.bodies`` (name, mass,
        inertia, shape, effects, effect_parameters); empty for a live bag.

    """

    names: list
    entries: dict

    def described(self, most=5):
        """Return the bodies for a message: the first `most` names and how many there are."""
        shown = ', '.join(self.names[:most])
        more = f', ... ({len(self.names)} bodies)' if len(self.names) > most else ''
        return shown + more

    def check(self, bag, body):
        """
        Raise ValueError with one line unless `body` is one of the bag's bodies.

        A bag of one body has no names: --body is refused, as it names nothing there.
        """
        if not self.names:
            raise ValueError(f'{bag} holds one body (its topics odom, angular_momentum, '
                             f'...): --body {body} is for a bag of several bodies; drop it')
        if body not in self.names:
            raise ValueError(f'{bag} has no body {body!r}; its bodies: {self.described()}')


def bag_bodies(bag, namespace=''):
    """
    Return the :class:`BagBodies` of a bag: those its custom data or its topics name.

    An offline bag of bodies lists them in its custom data (``rigid_body_sim.bodies``, with
    each body's mass, inertia and effects); a live one has each body's ``<ns>/<name>/odom``
    and ``<ns>/<name>/angular_momentum`` and the ``<ns>/markers`` array.  A bag with
    ``<ns>/odom`` is a bag of one body, as is one with a single ``<ns>/<name>/odom`` and no
    marker array (the one body of a node in a namespace the caller did not give).

    Raises
    ------
    ValueError
        If the bag cannot be read.

    """
    bag = Path(bag)
    problem = not_a_bag(bag)
    if problem is not None:
        raise ValueError(problem)
    custom = _custom_data(bag)
    if CUSTOM_DATA_PREFIX + 'mass' in custom:
        return BagBodies([], {})  # an offline bag of one body names its mass
    listed = custom.get(CUSTOM_DATA_PREFIX + 'bodies')
    if listed is not None:
        try:
            entries = {entry['name']: entry for entry in json.loads(listed)}
        except (ValueError, TypeError, KeyError) as error:
            raise ValueError(f'{bag}: its custom data rigid_body_sim.bodies is not a list of '
                             f'bodies: {error}') from None
        return BagBodies(list(entries), entries)
    namespace = (namespace or '').rstrip('/')
    try:
        with Reader(bag) as reader:
            topics = {connection.topic: connection.msgtype
                      for connection in reader.connections}
    except ReaderError as error:
        raise ValueError(f'cannot read the bag {bag}: {error}') from None
    if topics.get(f'{namespace}/odom') == _ODOMETRY:
        return BagBodies([], {})
    prefix = f'{namespace}/'
    names = sorted(
        topic[len(prefix):-len('/odom')] for topic, msgtype in topics.items()
        if msgtype == _ODOMETRY and topic.startswith(prefix) and topic.endswith('/odom')
        and '/' not in topic[len(prefix):-len('/odom')]
        and topics.get(topic[:-len('odom')] + 'angular_momentum') == _VECTOR3_STAMPED)
    if len(names) < 2 and topics.get(f'{namespace}/markers') != _MARKER_ARRAY:
        return BagBodies([], {})
    return BagBodies(names, {})


def body_custom_data(custom_data, entry):
    """
    Return the custom data of one body of a bag of bodies, as a one-body bag names them.

    The bag's (scene, integrator, rate, start_time, ...) with the body's ``mass``,
    ``inertia``, ``body_shape``, ``effects`` and ``effect_parameters`` from its `entry` in
    ``rigid_body_sim.bodies``, in the one-body bag's text forms; without an entry (a live
    bag), the bag's alone.
    """
    custom = {key: value for key, value in custom_data.items()
              if key != CUSTOM_DATA_PREFIX + 'bodies'}
    if entry:
        values = {
            'mass': f'{float(entry["mass"]):.17g}',
            'inertia': ' '.join(f'{float(value):.17g}' for value in entry['inertia']),
            'body_shape': entry.get('shape', ''),
            'effects': ', '.join(entry.get('effects') or ()) or 'none',
            'effect_parameters': json.dumps(entry.get('effect_parameters') or []),
        }
        custom.update({CUSTOM_DATA_PREFIX + key: value for key, value in values.items()})
    return custom


def read_motion(bag, namespace='', body=None):
    """
    Read the node's odom and angular_momentum topics of a bag; return a :class:`BagMotion`.

    `body` names one body of a bag of several: its topics ``<namespace>/<body>/...`` and its
    mass, inertia and effects from the bag's list of bodies.

    Raises
    ------
    ValueError
        If the bag cannot be read or lacks the topics, or no stamp is in both; if `body`
        is not one of the bag's bodies (or the bag holds one body).

    """
    if body is None:
        return _read_motions(bag, namespace, [None], BagBodies([], {}))[0]
    bodies = bag_bodies(bag, namespace)
    bodies.check(bag, body)
    return _read_motions(bag, namespace, [body], bodies)[0]


def read_body_motions(bag, namespace='', names=None):
    """
    Read several bodies of a bag of bodies in one pass; return their :class:`BagMotion` list.

    `names`: the bodies to read (default all), in the order returned.

    Raises
    ------
    ValueError
        As :func:`read_motion`; also for a bag of one body.

    """
    bodies = bag_bodies(bag, namespace)
    if not bodies.names:
        raise ValueError(f'{bag} holds one body: read it with read_motion')
    names = bodies.names if names is None else list(names)
    for name in names:
        bodies.check(bag, name)
    return _read_motions(bag, namespace, names, bodies)


def _body_topic(connections, namespace, body, suffix, message_type):
    """Return the connection of `body`'s topic (None: the one body's, found as before)."""
    if body is None:
        return _find_topic(connections, suffix, message_type, namespace)
    wanted = f'{namespace}/{body}/{suffix}'
    for connection in connections:
        if connection.topic == wanted and connection.msgtype == message_type:
            return connection
    tail = f'/{body}/{suffix}'
    elsewhere = [c.topic for c in connections if c.topic.endswith(tail)]
    hint = f' (it has {elsewhere[0]}: --namespace {elsewhere[0][:-len(tail)]}?)' \
        if elsewhere else ''
    raise ValueError(f'the bag has no {message_type} topic {wanted!r} of body {body!r}{hint}')


def _read_motions(bag, namespace, names, bodies):
    """Read the odom and angular_momentum of `names` (None: the one body) in one pass."""
    bag = Path(bag)
    problem = not_a_bag(bag)
    if problem is not None:
        raise ValueError(problem)
    namespace = (namespace or '').rstrip('/')
    store = typestore()
    # Per body: stamp -> odom's values, stamp -> L.
    odometry = [{} for _ in names]
    momentum = [{} for _ in names]
    reports = []
    try:
        with Reader(bag) as reader:
            connections = reader.connections
            wanted = {}
            for index, name in enumerate(names):
                wanted[_body_topic(connections, namespace, name, 'odom', _ODOMETRY).id] = \
                    (index, True)
                wanted[_body_topic(connections, namespace, name, 'angular_momentum',
                                   _VECTOR3_STAMPED).id] = (index, False)
            diagnostics = [c for c in connections if c.msgtype == _DIAGNOSTIC_ARRAY]
            node = f'{namespace}/'
            chosen = [c for c in connections if c.id in wanted] + diagnostics
            for connection, _, raw in reader.messages(connections=chosen):
                message = store.deserialize_cdr(raw, connection.msgtype)
                stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
                if connection.msgtype == _DIAGNOSTIC_ARRAY:
                    reports.extend(_report(stamp, message, node))
                    continue
                index, is_odometry = wanted[connection.id]
                if is_odometry:
                    pose, twist = message.pose.pose, message.twist.twist
                    odometry[index][stamp] = (
                        (pose.orientation.x, pose.orientation.y, pose.orientation.z,
                         pose.orientation.w),
                        (pose.position.x, pose.position.y, pose.position.z),
                        (twist.angular.x, twist.angular.y, twist.angular.z),
                        (twist.linear.x, twist.linear.y, twist.linear.z))
                else:
                    vector = message.vector
                    momentum[index][stamp] = (vector.x, vector.y, vector.z)
            custom = _custom_data(bag)
    except FileNotFoundError:
        raise ValueError(f'no bag at {bag}') from None
    except ReaderError as error:
        # A bag by its metadata (not_a_bag), which rosbags cannot read: a killed writer's.
        raise ValueError(f'cannot read the bag {bag}: {error} (if a recorder was killed, '
                         f'try: rigid-body-sim record --recover {bag})') from None
    motions = []
    for name, odometry_of, momentum_of in zip(names, odometry, momentum):
        stamps = sorted(set(odometry_of) & set(momentum_of))
        if not stamps:
            whose = '' if name is None else f' of body {name!r}'
            raise ValueError(f'{bag}: no stamp has both an odom and an angular_momentum '
                             f'message{whose}')
        rows = [odometry_of[stamp] for stamp in stamps]
        own = custom if name is None else body_custom_data(custom, bodies.entries.get(name))
        motions.append(BagMotion(
            stamps, [row[0] for row in rows], [row[1] for row in rows],
            [row[2] for row in rows], [momentum_of[stamp] for stamp in stamps], own, bag.name,
            velocity_body=[row[3] for row in rows], reports=reports, body=name))
    return motions


def not_a_bag(path):
    """
    Return one line saying why `path` is not a rosbag2 bag, or None if it may be one.

    A bag is a folder whose ``metadata.yaml`` holds ``rosbag2_bagfile_information``, or a
    lone .mcap or .db3 file.  A folder with storage files and no metadata.yaml is a killed
    recorder's bag, which ``record --recover`` completes; any other folder or file is not a
    bag, and nothing suggests recovering it.
    """
    path = Path(path)
    if not path.exists():
        return f'no bag at {path}: nothing is there'
    if not path.is_dir():
        if path.suffix in _STORAGE_SUFFIXES:
            return None
        return (f'{path} is not a bag: a file that is not a storage file of one (.mcap, '
                '.db3); a bag is a folder with its metadata.yaml')
    metadata = path / 'metadata.yaml'
    storage = [child.name for child in path.iterdir() if child.suffix in _STORAGE_SUFFIXES]
    if not metadata.is_file():
        if storage:
            return (f'{path} has storage files ({", ".join(sorted(storage)[:3])}) but no '
                    'metadata.yaml: a recorder killed before it wrote it? try: rigid-body-sim '
                    f'record --recover {path}')
        return (f'{path} is not a bag: a folder with no metadata.yaml and no .mcap or .db3 '
                'file')
    try:
        document = _load_yaml(metadata)
    except Exception:  # noqa: B902 (any YAML or decoding error: not rosbag2's metadata)
        document = None
    if not isinstance(document, dict) or not isinstance(
            document.get('rosbag2_bagfile_information'), dict):
        return (f'{path} is not a bag: its metadata.yaml is not a rosbag2 one (no '
                'rosbag2_bagfile_information)')
    return None


def read_custom_data(bag):
    """Return the custom data of a bag ({} if it has none); see :func:`_custom_data`."""
    return _custom_data(Path(bag))


def _custom_data(bag):
    """
    Return the custom data of a bag directory's ``metadata.yaml`` ({} if it has none).

    rosbag2 keeps it there (``custom_data``, since metadata version 6), where
    :meth:`~rigid_body_sim.recording.bag_writer.BagWriter.set_custom_data` puts it; rosbags'
    Reader has no public accessor for it.  A lone storage file has no metadata.yaml: {}.
    """
    metadata = bag / 'metadata.yaml'
    if not bag.is_dir() or not metadata.is_file():
        return {}
    try:
        document = _load_yaml(metadata)
        return dict(document['rosbag2_bagfile_information'].get('custom_data') or {})
    except Exception as error:  # noqa: B902 (rosbags has just read it: damaged meanwhile)
        raise ValueError(f'cannot read the custom data of {metadata}: {error}') from None


def _load_yaml(path):
    """Return the YAML document of the file `path` (YAML's safe subset)."""
    return yaml.load(path.read_text(encoding='utf-8'), Loader=_YAML_LOADER)  # noqa: S506


def _report(stamp, message, node):
    """Yield (stamp, simulated time, rate) of the node's status in a /diagnostics message."""
    for status in message.status:
        # The node's hardware_id is its fully qualified name: in the namespace asked for.
        if not status.hardware_id.startswith(node) or '/' in status.hardware_id[len(node):]:
            continue
        values = {pair.key: pair.value for pair in status.values}
        try:
            yield (stamp, float(values['simulated time [s]']),
                   float(values['requested rate [Hz]']))
        except (KeyError, ValueError):
            continue

"""
Simulate a scene faster than real time, straight into a rosbag2 bag, without DDS.

The bag holds what the node (:mod:`rigid_body_sim.node.rigid_body_node`) publishes while it
simulates the same body at the same rate: the topics ``pose``, ``twist``, ``angular_momentum``,
``odom``, ``marker`` (relative names, under ``namespace``), with their types, frame ids and
QoS, serialised by the node's own :class:`~rigid_body_sim.messages.state.StateSerializer`;
``/diagnostics`` once per simulated second with the node's status keys; ``/tf`` at every
tick and ``/tf_static`` once, as the node publishes them (:mod:`rigid_body_sim.messages.tf`;
left out, with a note on stderr, where tf2_msgs is not installed); and, on request,
``/clock`` (rosgraph_msgs/Clock) at every tick, for ``ros2 bag play --clock``-free sim-time
playback.

Time.  As in the node, tick k (k = 1 .. duration x rate) advances the simulation by the
nominal period 1/rate and then publishes the state, so the first message is the state
after one period.  Its stamp, which is also its bag (log) time, is
``start_time + round(k * 1e9 / rate)`` ns: simulated time counted from ``start_time``.
The default start is 0, so that stamps read as simulated time (the bag starts at
1970-01-01T00:00:00 in tools that show dates); give the wall clock (``--start-time now``)
for a bag that looks like a live recording.  Successive stamps are exactly 1e9/rate ns
apart when that is a whole number of ns, else within 1 ns of it.
"""

from dataclasses import dataclass
import json
import math
import struct
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu

from .bag_writer import BagWriter
from .bag_writer import CUSTOM_DATA_PREFIX
from .bag_writer import offered_qos
from .state_batch import BatchSerializer
from .state_batch import StateBatch
from ..messages import qos
from ..messages.cdr import column
from ..messages.cdr import offset_of
from ..messages.cdr import rows_of
from ..messages.cdr import sentinels
from ..messages.cdr import serialize_zeroed
from ..messages.cdr import STAMP_SENTINEL
from ..messages.cdr import write_stamps
from ..messages.diagnostics import diagnostic_array
from ..messages.diagnostics import NODE_NAME
from ..messages.diagnostics import status_name
from ..messages.diagnostics import status_values
from ..messages.diagnostics import TickFigures
from ..messages.frames import default_frame_prefix
from ..messages.frames import frame_ids
from ..messages.imu import fill_imu_message
from ..messages.imu import imu_message
from ..messages.marker import marker_geometry_from_drawing
from ..messages.state import STATE_TOPICS
from ..messages.state import STATE_TYPES
from ..messages.tf import static_transforms
from ..messages.tf import TF_STATIC_TOPIC
from ..messages.tf import TF_TOPIC
from ..messages.tf import transform_message_class
from ..messages.tf import TransformSerializer

__all__ = [
    'CLOCK_TOPIC',
    'DIAGNOSTICS_TOPIC',
    'SimulationSummary',
    'absolute_namespace',
    'clock_rows',
    'effect_parameters_json',
    'message_type_name',
    'progress_bar',
    'run_plan',
    'set_custom_data',
    'simulate_to_bag',
    'stamp_nanoseconds',
    'topic_names',
]

DIAGNOSTICS_TOPIC = '/diagnostics'
CLOCK_TOPIC = '/clock'
IMU_TOPIC = 'imu'


# Ticks serialised and written at once (at most; a batch also ends with each simulated
# second): a few hundred rows amortise numpy's per-call cost, and 1024 ticks of all
# topics are about a megabyte.
_BATCH_TICKS = 1024
FLUSH_PERIOD = 1.0
"""Default wall-clock s between flushes of simulate's bag (record flushes every 0.25 s;
a simulation writes far more per second, so less often keeps a flush's cost small beside
the writing)."""
# The first stamp builtin_interfaces/Time (int32 seconds) cannot hold.
_LAST_STAMP = 2**31 * 10**9


@dataclass
class SimulationSummary:
    """
    What :func:`simulate_to_bag` did: ticks, messages per topic, wall time, speed.

    `ticks` and `duration` are what was simulated and written, less than asked for when
    the run was stopped early (`stopped`).
    """

    bag: object
    ticks: int
    duration: float
    message_counts: dict
    wall_time: float
    stopped: bool = False

    @property
    def speed(self):
        """Return simulated seconds per wall-clock second (the multiple of real time)."""
        return self.duration / self.wall_time if self.wall_time > 0.0 else math.inf

    def __str__(self):
        total = sum(self.message_counts.values())
        return (f'{self.bag}: {self.duration:g} s simulated in {self.wall_time:.2f} s '
                f'({self.speed:.1f}x real time), {self.ticks} ticks, {total} messages on '
                f'{len(self.message_counts)} topics'
                + (' (stopped early)' if self.stopped else ''))


def message_type_name(message_class):
    """Return the ROS 2 type name of a message class, e.g. 'geometry_msgs/msg/PoseStamped'."""
    package = message_class.__module__.split('.')[0]
    return f'{package}/msg/{message_class.__name__}'


def topic_names(namespace=''):
    """Return relative state topic -> absolute name under `namespace` ('' or '/ns')."""
    namespace = absolute_namespace(namespace)
    return {topic: f'{namespace}/{topic}' for topic in STATE_TOPICS}


def absolute_namespace(namespace):
    """Return a namespace as a topic name's prefix: '' or '/name' (no trailing '/')."""
    namespace = (namespace or '').rstrip('/')
    if namespace and not namespace.startswith('/'):
        namespace = '/' + namespace
    return namespace


def stamp_nanoseconds(start_nanoseconds, tick, rate):
    """
    Return the stamp (ns) of tick `tick` (an int or an integer array): start + tick/rate.

    tick * 1e9 / rate is rounded to the nearest ns; for a whole number of Hz in exact
    integer arithmetic, so no rounding error accumulates however long the run.
    """
    if float(rate).is_integer():
        whole = int(rate)
        return start_nanoseconds + (tick * 1_000_000_000 + whole // 2) // whole
    nanoseconds = np.rint(np.asarray(tick) * 1e9 / rate).astype(np.int64)
    return start_nanoseconds + (nanoseconds if nanoseconds.ndim else int(nanoseconds))


def _tick_count(duration, rate):
    try:
        duration = float(duration)
    except (TypeError, ValueError):
        raise ValueError(f'duration must be a number of seconds; got {duration!r}') from None
    if not math.isfinite(duration) or duration <= 0.0:
        raise ValueError(f'duration must be > 0 s; got {duration:g}')
    ticks = round(duration * rate)
    if ticks < 1 or abs(ticks - duration * rate) > 1e-6 * max(1.0, ticks):
        raise ValueError(f'duration {duration:g} s is not a whole number of ticks at '
                         f'{rate:g} Hz (period {1.0 / rate:g} s)')
    return ticks


def run_plan(scene, duration, rate, substeps, start_time):
    """
    Return (rate Hz, ticks, substeps, start_time ns) of an offline run, checked.

    rate None: the scene's.  Raises ValueError for a rate, duration, substeps or start
    time the bag cannot hold (a header stamp's seconds are an int32).
    """
    rate = float(scene.rate if rate is None else rate)
    if not math.isfinite(rate) or rate <= 0.0:
        raise ValueError(f'rate must be > 0 Hz; got {rate:g}')
    ticks = _tick_count(duration, rate)
    if int(substeps) != substeps or substeps < 1:
        raise ValueError(f'substeps must be a whole number >= 1; got {substeps!r}')
    substeps = int(substeps)
    start_time = int(start_time)
    last_stamp = stamp_nanoseconds(start_time, ticks, rate)
    if start_time < 0 or last_stamp >= _LAST_STAMP:
        raise ValueError(f'stamps must lie between 0 and {_LAST_STAMP // 10**9} s since the '
                         f'epoch; the start time {start_time * 1e-9:g} s and duration '
                         f'{ticks / rate:g} s do not fit')
    return rate, ticks, substeps, start_time


def simulate_to_bag(scene, bag, duration, rate=None, integrator=None, substeps=1,
                    tolerance=None, storage='mcap', start_time=0, clock=False, namespace='',
                    world_frame='world', body_frame='body', progress=False, stop=None,
                    flush_period=FLUSH_PERIOD, imu_frame='imu', frame_prefix=None):
    """
    Simulate `scene` for `duration` s and write what the node would publish into a bag.

    Parameters
    ----------
    scene : rigid_body_sim.scenes.Scene
        What to simulate: body, initial state, effects, default integrator and rate.
    bag : str or Path
        New bag directory.
    duration : float
        Simulated time in s; a whole number of ticks at `rate`.
    rate : float, optional
        Tick rate in Hz (default: the scene's): one state per topic per tick.
    integrator : str, optional
        Default: the scene's.
    substeps : int
        Integrator steps per tick, as the node's ``substeps`` parameter (with a tolerance,
        the least number).
    tolerance : float, optional
        Error control in rad per simulated s, as the node's ``tolerance`` parameter
        (default: the scene's; 0: off).
    storage : str
        'mcap' or 'sqlite3'.
    start_time : int
        Stamp of simulated time 0, in ns since the epoch (see the module docstring).
    clock : bool
        Also write /clock at every tick.
    namespace : str
        Namespace of the state topics ('' or '/name'), as the node's ``__ns``.
    world_frame, body_frame, imu_frame : str
        Frame names, as the node's parameters, after `frame_prefix` (unless one starts with
        ``/``), checked and read as tf2 reads them (:mod:`rigid_body_sim.messages.frames`).
        The ``imu`` topic (sensor_msgs/Imu) holds
        the scene's IMU (its ``imu:`` section: mount, noise and seed) as the node publishes
        it: the same readings, the same noise for the same seed.
    frame_prefix : str, optional
        Put before every frame name, as the node's parameter; default (None): the
        namespace's, as the node's (``sat1/`` for ``/sat1``).
    progress : bool
        Show a tqdm progress bar (on stderr).
    stop : threading.Event, optional
        Stop when set, after the batch of ticks being simulated (at most a simulated
        second): the bag then holds every tick up to there and is complete; the summary's
        `ticks` and `stopped` say how far the run got.
    flush_period : float
        Wall-clock s between flushes of the bag (:meth:`BagWriter.flush`, without fsync):
        killed at any moment (even by SIGKILL), the bag reads as it is up to the last flush,
        ``metadata.yaml`` included; 0: only at the end.

    Returns
    -------
    SimulationSummary

    Raises
    ------
    ValueError
        For a bad duration, rate, substeps, storage, start time or frame, or an existing
        bag.

    """
    rate, ticks, substeps, start_time = run_plan(scene, duration, rate, substeps, start_time)
    if frame_prefix is None:
        frame_prefix = default_frame_prefix(absolute_namespace(namespace))
    frames = frame_ids(frame_prefix, {'world_frame': world_frame, 'body_frame': body_frame,
                                      'imu_frame': imu_frame})
    world_frame, body_frame, imu_frame = (frames[name] for name in (
        'world_frame', 'body_frame', 'imu_frame'))
    names = topic_names(namespace)
    simulator = scene.simulator(integrator=integrator, tolerance=tolerance)
    simulator.substeps = substeps
    body = simulator.body
    geometry = marker_geometry_from_drawing(scene.drawing)
    serializer = BatchSerializer(body, world_frame, body_frame, geometry)
    types = {topic: message_type_name(STATE_TYPES[topic]) for topic in STATE_TOPICS}
    transform_class, no_tf = transform_message_class()
    if no_tf is not None:
        print(f'simulate: no /tf or /tf_static in the bag: {no_tf}', file=sys.stderr)
    imu = scene.imu_sensor()
    imu_rows = _ImuRows(imu, simulator, imu_frame, 1.0 / rate)
    diagnostics = _OfflineDiagnostics(scene, simulator, rate, substeps,
                                      absolute_namespace(namespace), clock)
    period = 1.0 / rate

    started = time.perf_counter()
    with BagWriter(bag, storage) as writer:
        _set_custom_data(writer, scene, simulator, rate, substeps, start_time)
        clock_connection = None
        if clock:
            clock_connection = writer.add_topic(CLOCK_TOPIC, message_type_name(Clock),
                                                [offered_qos(qos.CLOCK_QOS)])
        state_offer = [offered_qos(qos.STATE_QOS)]
        connections = [(topic, writer.add_topic(names[topic], types[topic], state_offer))
                       for topic in STATE_TOPICS]
        connections.append((IMU_TOPIC, writer.add_topic(
            f'{absolute_namespace(namespace)}/{IMU_TOPIC}', message_type_name(Imu),
            state_offer)))
        diagnostics_connection = writer.add_topic(
            DIAGNOSTICS_TOPIC, message_type_name(DiagnosticArray),
            [offered_qos(qos.DIAGNOSTICS_QOS)])
        tf_serializer = None
        if transform_class is not None:
            tf_serializer = TransformSerializer(transform_class, world_frame, body_frame)
            static_connection = writer.add_topic(
                TF_STATIC_TOPIC, message_type_name(transform_class),
                [offered_qos(qos.TF_STATIC_QOS)])
            writer.write(static_connection, start_time, serialize_zeroed(static_transforms(
                transform_class, body_frame, imu_frame, imu.model, start_time)))
            connections.append((TF_TOPIC, writer.add_topic(
                TF_TOPIC, message_type_name(transform_class), [offered_qos(qos.TF_QOS)])))
        if clock_connection is not None:
            connections.insert(0, (CLOCK_TOPIC, clock_connection))
        row_connections = [connection for _, connection in connections]
        bar = progress_bar(duration) if progress else None
        batch = StateBatch(_BATCH_TICKS)
        perf_counter = time.perf_counter
        last_flush = perf_counter()
        last_second = 0
        tick = 1
        try:
            while tick <= ticks and not (stop is not None and stop.is_set()):
                # The batch ends at the last tick, when full, or at the first tick of a new
                # simulated second, after which /diagnostics is written (time order).
                count = min(_BATCH_TICKS, ticks - tick + 1)
                stamps = stamp_nanoseconds(start_time, np.arange(tick, tick + count), rate)
                seconds = (stamps - start_time) // 1_000_000_000
                new_second = np.flatnonzero(seconds > last_second)
                if new_second.size:
                    count = int(new_second[0]) + 1
                    stamps = stamps[:count]
                batch.clear()
                step_durations = np.empty(count)
                batch_started = perf_counter()
                for index in range(count):
                    step_started = perf_counter()
                    simulator.step(period)
                    step_durations[index] = perf_counter() - step_started
                    batch.append(simulator.state)
                    imu_rows.append(stamps[index])
                serialized = serializer.serialize(batch.filled(), stamps)
                serialized[IMU_TOPIC] = imu_rows.take()
                if tf_serializer is not None:
                    # The pose's own doubles: position, then the quaternion (x, y, z, w).
                    rows = batch.filled()
                    serialized[TF_TOPIC] = tf_serializer.serialize_rows(
                        stamps, [rows[:, column] for column in (4, 5, 6, 0, 1, 2, 3)])
                if clock_connection is not None:
                    serialized[CLOCK_TOPIC] = clock_rows(stamps)
                writer.write_rows(row_connections,
                                  [serialized[topic] for topic, _ in connections], stamps)
                diagnostics.record(step_durations, perf_counter() - batch_started)
                if new_second.size:
                    last_second = int(seconds[count - 1])
                    stamp = int(stamps[-1])
                    writer.write(diagnostics_connection, stamp, diagnostics.serialized(stamp))
                tick += count
                if flush_period and perf_counter() - last_flush >= flush_period:
                    # As record does: a kill -9 from now on leaves a bag that reads as it
                    # is up to here (valid MCAP end, metadata.yaml with the counts).
                    writer.flush(sync=False)
                    last_flush = perf_counter()
                if bar is not None:
                    bar.update(count * period)
        finally:
            if bar is not None:
                bar.close()
        counts = writer.message_counts
    written = tick - 1
    return SimulationSummary(writer.path, written, written * period, counts,
                             time.perf_counter() - started, stopped=written < ticks)


class _ImuRows:
    """The serialised imu messages of a batch of ticks, as the node publishes them."""

    def __init__(self, imu, simulator, frame_id, period):
        self._imu = imu
        self._simulator = simulator
        self._period = period
        self._values = []
        self._stamps = []
        # The message's byte layout (messages/cdr.py): sentinel values serialised once,
        # then located.
        message = imu_message(frame_id, imu, period)
        values = sentinels(10)
        seconds, nanoseconds = STAMP_SENTINEL
        fill_imu_message(message, seconds * 1_000_000_000 + nanoseconds, values[0:4],
                         values[4:7], values[7:10])
        template = bytes(serialize_zeroed(message))
        self._offsets = [offset_of(template, struct.pack('<d', value), 'an imu field')
                         for value in values]
        self._stamp_offset = offset_of(template, struct.pack('<iI', *STAMP_SENTINEL),
                                       'the imu stamp')
        self._template = template

    def append(self, stamp):
        """Add the reading of the simulator's state, stamped `stamp` (ns)."""
        imu = self._imu
        imu.advance(self._period)
        simulator = self._simulator
        # The wrench on the state now (offline: the effects only), in one compiled call.
        force, torque = simulator.applied_wrench()
        self._values.append(np.concatenate(imu.reading(simulator.state, force, torque)))
        self._stamps.append(stamp)

    def take(self):
        """Return the rows added since the last take, (ticks, size) uint8."""
        values, stamps = np.array(self._values), np.array(self._stamps, dtype=np.int64)
        self._values, self._stamps = [], []
        data = rows_of(self._template, len(values))
        write_stamps(data, self._stamp_offset, stamps)
        for index, offset in enumerate(self._offsets):
            column(data, offset, '<f8')[:] = values[:, index]
        return data


def clock_rows(stamps):
    """Return the serialised rosgraph_msgs/Clock of each stamp, (n, size) uint8."""
    rows = rows_of(serialize_zeroed(Clock()), len(stamps))
    # CDR: the 4-byte encapsulation header, then clock.sec (int32), clock.nanosec (uint32).
    write_stamps(rows, 4, stamps)
    return rows


def progress_bar(duration):
    """Return a tqdm bar (stderr) counting simulated s up to `duration`."""
    from tqdm import tqdm
    return tqdm(total=float(duration), unit='s', desc='simulated', leave=True,
                bar_format='{desc}: {percentage:3.0f}%|{bar}| {n:.3g}/{total:.3g} s '
                           '[{elapsed}<{remaining}, {rate_fmt}]')


def effect_parameters_json(scene):
    """
    Return the scene's effects and their parameters as JSON, for the bag's custom data.

    A list, in the scene's order, of {"effect": name, parameter: value, ...} with the
    effects' public attributes (SI units, world or body frame as each effect defines them;
    vectors as lists, floats exactly: JSON writes the shortest repr that reads back
    equal).  The plot reads the pivot's point and anchor and gravity's acceleration.
    """
    effects = []
    for name, effect in zip(scene.effect_names(), scene.effects):
        parameters = {'effect': name}
        for key, value in vars(effect).items():
            if not key.startswith('_'):
                parameters[key] = value.tolist() if isinstance(value, np.ndarray) else value
        effects.append(parameters)
    return json.dumps(effects)


def set_custom_data(writer, scene, stepper, rate, substeps, start_time, **more):
    """
    Write what a reader of the bag may want to know about the run into its custom data.

    The scene, its source, the integrator and tolerance of `stepper` (a Simulator or a
    World), rate, substeps and start time, then `more` (key: text), then the plugins'
    paths (the plot finds what a plugin's effect conserves by loading it again) and the
    writer.  The node's messages carry none of it.
    """
    tolerance = stepper.tolerance
    values = {
        'scene': scene.name,
        'scene_source': scene.source,
        'integrator': stepper.integrator,
        'rate': f'{rate:.17g}',
        'substeps': str(substeps),
        'tolerance': 'off' if tolerance is None else f'{tolerance:.17g}',
        'start_time': str(start_time),
        **more,
        'writer': 'rigid-body-sim simulate',
    }
    if scene.plugins:
        values['effect_plugins'] = json.dumps(list(scene.plugins))
    for key, value in values.items():
        writer.set_custom_data(CUSTOM_DATA_PREFIX + key, value)


def _set_custom_data(writer, scene, simulator, rate, substeps, start_time):
    body = simulator.body
    set_custom_data(
        writer, scene, simulator, rate, substeps, start_time,
        mass=f'{body.mass:.17g}',
        inertia=' '.join(f'{value:.17g}' for value in body.inertia.ravel()),
        # The scene's own shape of the body ('' for a body given by its inertia): a box
        # marker of a box body is that box, not a stand-in with its moments.
        body_shape=scene.data.get('body', {}).get('shape', ''),
        effects=', '.join(scene.effect_names()) or 'none',
        effect_parameters=effect_parameters_json(scene))


class _OfflineDiagnostics:
    """The node's /diagnostics status (same keys, same order), for a run off the wall clock."""

    def __init__(self, scene, simulator, rate, substeps, namespace, clock):
        self._scene = scene
        self._simulator = simulator
        self._rate = rate
        self._substeps = substeps
        self._clock = clock
        self._name = status_name(NODE_NAME)
        self._hardware_id = f'{namespace}/{NODE_NAME}'
        self._reference_energy = simulator.energy()
        self._reference_momentum = float(np.linalg.norm(simulator.state.angular_momentum))
        self._steps = []
        self._ticks = []
        self._simulated = simulator.time

    def record(self, step_durations, batch_duration):
        """
        Note a batch of ticks: each tick's step duration and the whole batch's (s, wall).

        A tick's duration is its step plus an equal share of the batch's serialising and
        writing, which are done for the batch at once.
        """
        step_durations = np.asarray(step_durations)
        share = (batch_duration - step_durations.sum()) / max(1, step_durations.size)
        self._steps.append(step_durations)
        self._ticks.append(step_durations + share)

    def serialized(self, stamp):
        """Return the serialised DiagnosticArray for the ticks since the last one."""
        simulator = self._simulator
        steps = np.concatenate(self._steps) if self._steps else np.empty(0)
        ticks = np.concatenate(self._ticks) if self._ticks else np.empty(0)
        self._steps, self._ticks = [], []
        simulated, self._simulated = simulator.time - self._simulated, simulator.time
        # Ticks per wall-clock second, as the node reports them: here as fast as it goes.
        wall = float(ticks.sum())
        achieved = ticks.size / wall if wall > 0.0 else math.inf
        values = status_values(
            self._scene, simulator, self._rate, 'offline: as fast as possible',
            TickFigures(achieved, 0, steps, ticks, simulated),
            clock_seconds=1e-9 * stamp if self._clock else None,
            reference_energy=self._reference_energy,
            reference_momentum=self._reference_momentum)
        return serialize_zeroed(diagnostic_array(
            self._name, self._hardware_id, DiagnosticStatus.OK, 'running', values, stamp))

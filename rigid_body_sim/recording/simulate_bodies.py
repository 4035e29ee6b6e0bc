"""
Simulate a scene of several bodies into a rosbag2 bag: what the node of bodies publishes.

The bag holds, for a scene of ``bodies:``, the topics the node of bodies
(:mod:`rigid_body_sim.node.world_node`) publishes while it simulates the scene at the same
rate: each body's ``<name>/pose``, ``<name>/twist``, ``<name>/angular_momentum``,
``<name>/odom`` and ``<name>/imu`` (under ``namespace``), one ``/tf`` message a tick with
every body's transform ``world -> <name>``, ``/tf_static`` once with every ``<name> ->
<name>/imu``, one ``visualization_msgs/MarkerArray`` ``markers`` a tick, ``/diagnostics``
once per simulated second and, on request, ``/clock``.  The messages are the node's, from
the same serialiser (:class:`~rigid_body_sim.messages.bodies.BodiesSerializer`); all
bodies advance together in one :class:`~rigid_body_sim.physics.World`, each exactly as it
would alone.

Time as in :mod:`.simulate`: tick k advances every body by 1/rate and is stamped
``start_time + round(k * 1e9 / rate)`` ns (stamps and bag times in simulated time from
``start_time``).

The bag's custom data say what was simulated: the scene, integrator, rate, tolerance and
``bodies``, a JSON list with each body's name, mass (kg), inertia (kg m^2, body frame,
row-major), shape, effects and their parameters (what ``plot`` and ``animate`` read).
"""

import json
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from visualization_msgs.msg import MarkerArray

from .bag_writer import BagWriter
from .bag_writer import offered_qos
from .simulate import absolute_namespace
from .simulate import clock_rows
from .simulate import CLOCK_TOPIC
from .simulate import DIAGNOSTICS_TOPIC
from .simulate import effect_parameters_json
from .simulate import FLUSH_PERIOD
from .simulate import message_type_name
from .simulate import progress_bar
from .simulate import run_plan
from .simulate import set_custom_data
from .simulate import SimulationSummary
from .simulate import stamp_nanoseconds
from ..messages import qos
from ..messages.bodies import BodiesSerializer
from ..messages.bodies import BODY_TOPICS
from ..messages.bodies import BodyMessages
from ..messages.bodies import BodyRows
from ..messages.bodies import MARKERS_TOPIC
from ..messages.cdr import serialize_zeroed
from ..messages.diagnostics import diagnostic_array
from ..messages.diagnostics import NODE_NAME
from ..messages.diagnostics import status_name
from ..messages.frames import default_frame_prefix
from ..messages.frames import frame_ids
from ..messages.marker import marker_geometry_from_drawing
from ..messages.state import STATE_TYPES
from ..messages.tf import static_transforms
from ..messages.tf import TF_STATIC_TOPIC
from ..messages.tf import TF_TOPIC
from ..messages.tf import transform_message_class

__all__ = ['BODIES_KEY', 'body_entries', 'simulate_bodies_to_bag']

BODIES_KEY = 'bodies'
"""The custom-data key (after the package's prefix) of the bodies' JSON list."""


def body_entries(scene):
    """
    Return the bodies of `scene` as JSON-ready dicts: what a reader of the bag needs.

    Each: name, mass (kg), inertia (kg m^2, body frame, 9 values row-major), shape (the
    scene's ``body.shape``, '' for a body given by its inertia), effects (names) and
    effect_parameters (as :func:`~.simulate.effect_parameters_json`).
    """
    entries = []
    for member in scene.members:
        entries.append({
            'name': member.name,
            'mass': float(member.body.mass),
            'inertia': [float(value) for value in np.asarray(member.body.inertia).ravel()],
            'shape': member.data.get('body', {}).get('shape', ''),
            'effects': member.effect_names(),
            'effect_parameters': json.loads(effect_parameters_json(member)),
        })
    return entries


def simulate_bodies_to_bag(scene, bag, duration, rate=None, integrator=None, substeps=1,
                           tolerance=None, storage='mcap', start_time=0, clock=False,
                           namespace='', world_frame='world', progress=False, stop=None,
                           flush_period=FLUSH_PERIOD, frame_prefix=None):
    """
    Simulate the bodies of `scene` for `duration` s; write what the node would publish.

    Parameters as :func:`~.simulate.simulate_to_bag` (a body's frames are its name and
    ``<name>/imu``, after `frame_prefix`, so there is no body_frame or imu_frame); `scene`
    a scene of ``bodies:``.

    Returns
    -------
    SimulationSummary

    Raises
    ------
    ValueError
        For a scene of one body, a bad duration, rate, substeps, storage, start time or
        frame, or an existing bag.

    """
    if not scene.has_named_bodies:
        raise ValueError(f'scene {scene.name!r} has one body: simulate_to_bag writes it')
    rate, ticks, substeps, start_time = run_plan(scene, duration, rate, substeps, start_time)
    namespace = absolute_namespace(namespace)
    if frame_prefix is None:
        frame_prefix = default_frame_prefix(namespace)
    members = scene.members
    names = [member.name for member in members]
    frames = frame_ids(frame_prefix, {'world_frame': world_frame,
                                      **{name: name for name in names},
                                      **{f'{name}/imu': f'{name}/imu' for name in names}})
    world_frame = frames['world_frame']
    world = scene.world(integrator=integrator, tolerance=tolerance)
    world.substeps = substeps
    period = 1.0 / rate
    imus = [member.imu_sensor() for member in members]
    transform_class, no_tf = transform_message_class()
    if no_tf is not None:
        print(f'simulate: no /tf or /tf_static in the bag: {no_tf}', file=sys.stderr)
    serializer = BodiesSerializer(
        world_frame,
        [BodyMessages(member.name, member.body, frames[member.name],
                      frames[f'{member.name}/imu'],
                      marker_geometry_from_drawing(member.drawing), imu, index)
         for index, (member, imu) in enumerate(zip(members, imus))],
        transform_class, period)
    body_rows = BodyRows(world, names, [member.pivot is not None for member in members])
    simulators = [world.simulator(name) for name in names]
    topics = list(BODY_TOPICS) + ([TF_TOPIC] if transform_class is not None else []) \
        + [MARKERS_TOPIC]
    diagnostics = _OfflineDiagnostics(scene, world, rate, namespace)

    started = time.perf_counter()
    with BagWriter(bag, storage) as writer:
        set_custom_data(writer, scene, world, rate, substeps, start_time,
                        **{BODIES_KEY: json.dumps(body_entries(scene))})
        state_offer = [offered_qos(qos.STATE_QOS)]
        clock_connection = None
        if clock:
            clock_connection = writer.add_topic(CLOCK_TOPIC, message_type_name(Clock),
                                                [offered_qos(qos.CLOCK_QOS)])
        body_connections = {
            topic: [writer.add_topic(f'{namespace}/{name}/{topic}',
                                     message_type_name(STATE_TYPES[topic]), state_offer)
                    for name in names]
            for topic in BODY_TOPICS}
        body_connections['imu'] = [writer.add_topic(f'{namespace}/{name}/imu',
                                                    message_type_name(Imu), state_offer)
                                   for name in names]
        shared_connections = {MARKERS_TOPIC: writer.add_topic(
            f'{namespace}/{MARKERS_TOPIC}', message_type_name(MarkerArray), state_offer)}
        diagnostics_connection = writer.add_topic(
            DIAGNOSTICS_TOPIC, message_type_name(DiagnosticArray),
            [offered_qos(qos.DIAGNOSTICS_QOS)])
        if transform_class is not None:
            static_connection = writer.add_topic(
                TF_STATIC_TOPIC, message_type_name(transform_class),
                [offered_qos(qos.TF_STATIC_QOS)])
            transforms = [static_transforms(transform_class, frames[name],
                                            frames[f'{name}/imu'], imu.model,
                                            start_time).transforms[0]
                          for name, imu in zip(names, imus)]
            writer.write(static_connection, start_time,
                         serialize_zeroed(transform_class(transforms=transforms)))
            shared_connections[TF_TOPIC] = writer.add_topic(
                TF_TOPIC, message_type_name(transform_class), [offered_qos(qos.TF_QOS)])
        bar = progress_bar(duration) if progress else None
        perf_counter = time.perf_counter
        last_flush = perf_counter()
        readings = np.empty((len(names), 10))
        bar_ticks = max(1, int(round(rate / 10)))
        tick = 1
        try:
            while tick <= ticks and not (stop is not None and stop.is_set()):
                stamp = stamp_nanoseconds(start_time, tick, rate)
                step_started = perf_counter()
                stopped = world.step(period)
                step_seconds = perf_counter() - step_started
                diagnostics.note_stopped(stopped)
                for imu in imus:
                    imu.advance(period)
                for index, (imu, simulator) in enumerate(zip(imus, simulators)):
                    # The wrench on the state now (offline: the effects only).
                    force, torque = simulator.applied_wrench()
                    readings[index] = np.concatenate(
                        imu.reading(simulator.state, force, torque))
                if clock_connection is not None:
                    clock_row = clock_rows(np.array([stamp]))[0]
                    writer.write(clock_connection, stamp, clock_row.tobytes())
                batches = serializer.write(body_rows.rows(), stamp, topics)
                serializer.write_imu(readings, stamp)
                for topic in (*BODY_TOPICS, 'imu'):
                    batch = batches[topic]
                    for index, connection in enumerate(body_connections[topic]):
                        writer.write(connection, stamp, batch.message(index))
                for topic, connection in shared_connections.items():
                    writer.write(connection, stamp, batches[topic].message(0))
                diagnostics.record(step_seconds, perf_counter() - step_started)
                if diagnostics.second_ended(stamp - start_time):
                    writer.write(diagnostics_connection, stamp, diagnostics.serialized(stamp))
                if flush_period and perf_counter() - last_flush >= flush_period:
                    writer.flush(sync=False)
                    last_flush = perf_counter()
                if bar is not None and (tick % bar_ticks == 0 or tick == ticks):
                    # Simulated s so far, the last exactly the duration (no rounding past it).
                    bar.update((float(duration) if tick == ticks else tick * period) - bar.n)
                tick += 1
        finally:
            if bar is not None:
                bar.close()
        counts = writer.message_counts
    written = tick - 1
    return SimulationSummary(writer.path, written, written * period, counts,
                             time.perf_counter() - started, stopped=written < ticks)


class _OfflineDiagnostics:
    """The node of bodies' /diagnostics status, once per simulated second, off the clock."""

    def __init__(self, scene, world, rate, namespace):
        self._scene = scene
        self._world = world
        self._rate = rate
        self._name = status_name(NODE_NAME)
        self._hardware_id = f'{namespace}/{NODE_NAME}'
        self._steps = []
        self._ticks = []
        self._stopped = {}
        self._second = 0

    def note_stopped(self, stopped):
        """Keep the bodies that stopped (name -> why) for the reports from now on."""
        self._stopped.update(stopped)

    def record(self, step_seconds, tick_seconds):
        """Note a tick: its step's and its whole duration (s, wall)."""
        self._steps.append(step_seconds)
        self._ticks.append(tick_seconds)

    def second_ended(self, elapsed_nanoseconds):
        """Return whether this tick is the first of a new simulated second."""
        second = int(elapsed_nanoseconds // 1_000_000_000)
        if second > self._second:
            self._second = second
            return True
        return False

    def serialized(self, stamp):
        """Return the serialised DiagnosticArray for the ticks since the last one."""
        steps, ticks = np.asarray(self._steps), np.asarray(self._ticks)
        self._steps, self._ticks = [], []
        wall = float(ticks.sum())
        world = self._world
        values = [
            ('scene', self._scene.name),
            ('bodies', str(len(world))),
            ('integrator', world.integrator),
            ('tolerance [rad/s]', 'off' if world.tolerance is None
             else f'{world.tolerance:g}'),
            ('rate [Hz]', f'{self._rate:g}'),
            ('mode', 'offline: as fast as possible'),
            ('ticks per second', f'{ticks.size / wall:.1f}' if wall > 0.0 else 'n/a'),
            ('step mean [ms]', f'{1e3 * steps.mean():.4f}' if steps.size else 'n/a'),
            ('simulated time [s]', f'{world.time:.6f}'),
            ('bodies stopped', ', '.join(sorted(self._stopped)) or 'none'),
        ]
        level = DiagnosticStatus.WARN if self._stopped else DiagnosticStatus.OK
        message = (f'{len(self._stopped)} bodies stopped (not finite)' if self._stopped
                   else 'running')
        return serialize_zeroed(diagnostic_array(
            self._name, self._hardware_id, level, message, values, stamp))

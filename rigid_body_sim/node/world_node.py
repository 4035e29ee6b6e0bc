"""
The node of a scene of several bodies (``bodies:``): one World, every body's topics and frames.

The node is :class:`~.rigid_body_node.RigidBodyNode` with a
:class:`~rigid_body_sim.physics.World` where that one has a Simulator: the same ticks on the
steady clock (one ``World.step`` call a tick for every body, at the scene's rate), the same
parameters that apply to every body (``integrator``, ``tolerance`` and ``substeps`` switchable
at run time, ``rate``, ``real_time_factor``, ``publish_clock``, ``frame_prefix``,
``world_frame``, ``input_timeout``, ``max_wrench``; the one-body parameters ``body.*``,
``initial.*``, ``imu.*``, ``body_frame`` and ``imu_frame`` are refused: each body's are in
the scene file), the same ``reset`` and ``pause`` services (for every body), kernels compiled
beside it, /clock and stamps.

Topics, relative to the node's namespace, for each body ``<name>``: ``<name>/pose``,
``<name>/twist``, ``<name>/angular_momentum``, ``<name>/odom``, ``<name>/imu`` (the one-body
node's messages, QoS and contents), and ``<name>/torque``, ``<name>/wrench`` subscribed only
for a body whose effects include external_wrench (the one-body node's semantics, limits and
expiry).  For all bodies: one ``/tf`` message a tick holding every body's transform
``world_frame -> <name>``, ``/tf_static`` holding every ``<name> -> <name>/imu``, and one
``markers`` (visualization_msgs/MarkerArray) a tick, each body's marker with ``ns`` its
name.  Frame ids get ``frame_prefix`` as the one-body node's do
(:mod:`rigid_body_sim.messages.frames`).
Only what has subscribers is written and published (:mod:`rigid_body_sim.messages.bodies`).

Rate.  When a tick costs more than its period allows, the node publishes less often rather
than fall behind: every k-th tick (the integration still every tick), k chosen at each
/diagnostics report from the measured cost of a tick's integration and of a tick's
publishing (:func:`publish_every`); /diagnostics says k, the tick cost and whether the
rate is kept, the log says each change of k once.  If the integration alone cannot keep
the rate, the status is "falling behind" as the one-body node's.

The public methods (:meth:`WorldNode.spawn_body`, :meth:`WorldNode.delete_body`, ...) are
what :mod:`rigid_body_sim.node.simulation_services` serves as simulation_interfaces.
"""

import math
import re
import time

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped
from geometry_msgs.msg import WrenchStamped
import numpy as np
from sensor_msgs.msg import Imu as ImuMessage
from std_srvs.srv import SetBool
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from .parameters import declare_parameters
from .parameters import declare_scene_parameter
from .parameters import given_overrides
from .parameters import ONE_BODY_PARAMETERS
from .parameters import scene_from_parameters
from .parameters import WORLD_PARAMETERS
from .rigid_body_node import NODE_NAME
from .rigid_body_node import RigidBodyNode
from .simulation_services import SimulationServices
from ..messages.bodies import BodiesSerializer
from ..messages.bodies import BODY_TOPICS
from ..messages.bodies import BodyMessages
from ..messages.bodies import BodyRows
from ..messages.bodies import deleted_markers
from ..messages.bodies import MARKERS_TOPIC
from ..messages.frames import frame_ids
from ..messages.marker import marker_geometry_from_drawing
from ..messages.qos import DIAGNOSTICS_QOS
from ..messages.qos import INPUT_QOS
from ..messages.qos import SERVICE_QOS
from ..messages.qos import STATE_QOS
from ..messages.qos import TF_QOS
from ..messages.qos import TF_STATIC_QOS
from ..messages.simulation import unavailable_reason
from ..messages.state import STATE_TYPES
from ..messages.tf import static_transforms
from ..messages.tf import TF_STATIC_TOPIC
from ..messages.tf import TF_TOPIC
from ..messages.tf import transform_message_class
from ..physics import World
from ..physics.state import State
from ..scenes import DEFAULT_SCENE
from ..scenes import load_scene
from ..scenes.limits import MAX_BODIES
from ..scenes.limits import MAX_BODY_NAME_LENGTH
from ..text import shortened

__all__ = ['WorldNode', 'node_for_scene', 'publish_every', 'BUSY_FRACTION']

# The scene schema's rule for a body's name: a ROS name token (its topics' namespace).
_BODY_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*')
_INPUT_TYPES = {'torque': Vector3Stamped, 'wrench': WrenchStamped}
BUSY_FRACTION = 0.7
"""Share of a tick's wall-clock period the node's thread may spend in ticks; the rest is
the executor's, the services' and the reports'."""
# Publishers whose subscribers are looked for at one check (every 0.1 s): a scene of
# thousands of bodies spreads its look over several checks.
_CHECKS_PER_CALL = 500
# After ticks were missed, k is not lowered for this long (s); then one step every _STEP_DOWN s.
_MISSED_MEMORY = 30.0
_STEP_DOWN = 5.0


def node_for_scene(context):
    """
    Return the node the ``scene`` parameter asks for: a WorldNode for a scene of bodies.

    The parameter is read from the context's arguments (``-p scene:=``, params files) by
    a node that lives only for that, named as the simulation node will be; a scene that
    does not load is left to RigidBodyNode, which reports why.
    """
    import rclpy

    probe = rclpy.create_node(NODE_NAME, context=context, start_parameter_services=False,
                              enable_rosout=False)
    try:
        name = given_overrides(probe).get('scene', DEFAULT_SCENE)
    finally:
        probe.destroy_node()
    scene = None
    if isinstance(name, str):
        try:
            scene = load_scene(name)
        except (OSError, ValueError):
            scene = None
    if scene is not None and scene.has_named_bodies:
        return WorldNode(context=context, scene=scene)
    return RigidBodyNode(context=context)


def publish_every(step_seconds, publish_seconds, other_seconds, wall_period, most):
    """
    Return k: publish every k-th tick so that ticks fit BUSY_FRACTION of `wall_period`.

    step_seconds: a tick's integration; publish_seconds: a publishing tick's writing and
    publishing; other_seconds: the rest of a tick (inputs); all s, measured.  The mean tick
    then costs step + other + publish / k.  k is at most `most` (when the integration alone
    leaves no room: the rate is then not kept whatever k).
    """
    room = BUSY_FRACTION * wall_period - step_seconds - other_seconds
    if publish_seconds <= room:
        return 1
    if room <= 0.0:
        return most
    return min(most, math.ceil(publish_seconds / room))


class _Body:
    """One body of the node: its Simulator, frames, publishers and inputs."""

    def __init__(self, name, member, simulator, frames, marker_id):
        self.name = name
        self.member = member
        self.simulator = simulator
        self.initial_state = member.state
        self.frame = frames['body']
        self.imu_frame = frames['imu']
        self.imu = member.imu_sensor()
        self.marker_id = marker_id
        self.pivoted = member.pivot is not None
        external_wrench = member.external_wrench
        self.external_wrench = external_wrench
        self.limit = None if external_wrench is None or (
            external_wrench.max_force is None and external_wrench.max_torque is None) \
            else external_wrench.limit
        self.publishers = {}
        self.subscriptions = []
        self.input_keys = ()


class WorldNode(RigidBodyNode):
    """
    Simulate the bodies of a scene of ``bodies:`` in one World; see the module docstring.

    Raises ConfigurationError as :class:`RigidBodyNode` does (a scene of one body too: that
    is RigidBodyNode's).  `scene`: the Scene the ``scene`` parameter names, if the caller
    loaded it already (:func:`node_for_scene`), so that it is not read twice.
    """

    def __init__(self, node_name=NODE_NAME, scene=None, **kwargs):
        self._given_scene = scene
        super().__init__(node_name, **kwargs)

    # -- set-up

    def _configure(self):
        name = declare_scene_parameter(self, self._overrides)
        scene = self._given_scene
        if scene is None:
            scene = load_scene(name)
        if not scene.has_named_bodies:
            raise ValueError(f'scene {scene.name!r} has one body: the one-body node runs it')
        values = declare_parameters(self, scene, self._overrides, WORLD_PARAMETERS)
        refused = [name for name in ONE_BODY_PARAMETERS if name in self._overrides]
        if refused:
            raise ValueError(
                f'parameter(s) {", ".join(refused)} describe one body; scene {scene.name!r} '
                f'has {len(scene.bodies)} (bodies:): give each body its own in the scene file')
        self._warn_unknown_overrides()
        scene = scene_from_parameters(scene, {name: values[name]
                                              for name in ('integrator', 'rate')})
        self._scene = scene
        self._rate = scene.rate
        self._period = 1.0 / self._rate
        self._real_time_factor = values['real_time_factor']
        self._wall_period = self._period / self._real_time_factor
        self._substeps = values['substeps']
        self._input_timeout_ns = int(values['input_timeout'] * 1e9)
        self._max_wrench = values['max_wrench']
        self._frame_prefix = values['frame_prefix']
        self._world_frame = frame_ids(self._frame_prefix,
                                      {'world_frame': values['world_frame']})['world_frame']
        self._body_frame = None
        frames = {member.name: self._frames_of(member.name) for member in scene.members}
        self._world = self._simulator = World(
            ((member.name, member.simulator()) for member in scene.members),
            integrator=scene.integrator, tolerance=values['tolerance'] or None,
            substeps=self._substeps)
        kernels_ready = self._prepare_kernels(scene.integrator, values)
        self._start_clock(values)
        self._transform_class, tf_reason = transform_message_class()
        self._tf_publisher = self._tf_static_publisher = None
        if self._transform_class is not None:
            self._tf_publisher = self.create_publisher(self._transform_class, TF_TOPIC, TF_QOS)
            self._tf_static_publisher = self.create_publisher(
                self._transform_class, TF_STATIC_TOPIC, TF_STATIC_QOS)
        else:
            self.get_logger().warning(f'TF is off (no /tf, /tf_static): {tf_reason}')
        self._markers_publisher = self.create_publisher(MarkerArray, MARKERS_TOPIC, STATE_QOS)
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
        self._inputs = {}
        self._input_types = {}
        self._received = {}
        self._inputs_changed = False
        self._last_held = {}
        self._paused = False
        self._diverged = None
        self._last_warning = {}
        self._rejected = 0
        self._limited = 0
        self._bodies = {}
        self._marker_ids = 0
        for member in scene.members:
            self._add_body(member.name, member, self._world.simulator(member.name),
                           frames[member.name])
        self._imu_noisy = False
        self._rebuild_messages()
        self._publish_every = 1
        self._publish_phase = 0
        self._publish_seconds = 0.0
        self._publishes = 0
        # CPU s of this thread (not wall: a busy machine's preemption is no cost of ours):
        # publishing, a publishing tick's mean at the last report; the integration, summed
        # over the report's window.
        self._last_publish_cost = 0.0
        self._step_cpu = 0.0
        self._steps_counted = 0
        self._missed_with = (0, -math.inf)  # (k, when on the steady clock) ticks were missed
        self._k_changed = -math.inf
        self._check_cursor = 0
        self._body_subscribers = {topic: {} for topic in (*BODY_TOPICS, 'imu')}
        self._markers_subscribed = False
        self._tf_subscribed = False
        self.create_service(Trigger, 'reset', self._reset_callback, qos_profile=SERVICE_QOS)
        self.create_service(SetBool, 'pause', self._pause_callback, qos_profile=SERVICE_QOS)
        self.add_on_set_parameters_callback(self._validate_parameters_callback)
        self.add_post_set_parameters_callback(self._parameters_set_callback)
        self._set_drift_reference()
        self._log_world_start(values)
        # ROS 2's standard simulation services (simulation_interfaces), where it is built.
        self._simulation_services = None
        missing = unavailable_reason()
        if missing is None:
            self._simulation_services = SimulationServices(self)
        else:
            self.get_logger().warning(f'the standard simulation services are not served: '
                                      f'{missing}')
        self._start_running(kernels_ready, scene.integrator)

    def _frames_of(self, name):
        """Return {'body', 'imu'}: the frame ids of body `name` (ValueError if unusable)."""
        ids = frame_ids(self._frame_prefix, {'world_frame': self._world_frame, name: name,
                                             f'{name}/imu': f'{name}/imu'})
        return {'body': ids[name], 'imu': ids[f'{name}/imu']}

    def _add_body(self, name, member, simulator, frames):
        body = _Body(name, member, simulator, frames, self._marker_ids)
        self._marker_ids += 1
        for topic in BODY_TOPICS:
            body.publishers[topic] = self.create_publisher(
                STATE_TYPES[topic], f'{name}/{topic}', STATE_QOS)
        body.publishers['imu'] = self.create_publisher(ImuMessage, f'{name}/imu', STATE_QOS)
        if member.accepts_external_wrench:
            keys = []
            for topic, message_type in _INPUT_TYPES.items():
                key = f'{name}/{topic}'
                keys.append(key)
                self._input_types[key] = message_type
                self._inputs[key] = None
                body.subscriptions.append(self.create_subscription(
                    message_type, key, lambda data, key=key: self._input_callback(key, data),
                    INPUT_QOS, raw=True))
            body.input_keys = tuple(keys)
        self._bodies[name] = body

    def _rebuild_messages(self):
        """Make the serialiser, the packed states read each tick and /tf_static anew."""
        bodies = list(self._bodies.values())
        self._serializer = BodiesSerializer(
            self._world_frame,
            [BodyMessages(body.name, body.member.body, body.frame, body.imu_frame,
                          marker_geometry_from_drawing(body.member.drawing), body.imu,
                          body.marker_id) for body in bodies],
            self._transform_class, self._period)
        self._body_rows = BodyRows(self._world, [body.name for body in bodies],
                                   [body.pivoted for body in bodies])
        self._noisy_imus = [body.imu for body in bodies if body.imu.model.noisy]
        self._body_list = bodies
        self._index = {body.name: index for index, body in enumerate(bodies)}
        self._check_cursor = 0
        if self._tf_static_publisher is not None:
            stamp = 0 if self._publish_clock else self.get_clock().now().nanoseconds
            transforms = [static_transforms(self._transform_class, body.frame, body.imu_frame,
                                            body.imu.model, stamp).transforms[0]
                          for body in bodies]
            self._tf_static_publisher.publish(self._transform_class(transforms=transforms))

    def _log_world_start(self, values):
        scene = self._scene
        inputs = sum(1 for body in self._bodies.values() if body.input_keys)
        tolerance = self._world.tolerance
        control = (f'error control {tolerance:g} rad/s, at least {self._substeps} substep(s)'
                   if tolerance else f'{self._substeps} substep(s)')
        self.get_logger().info(
            f'simulating scene {scene.name!r}: {len(self._bodies)} bodies in one world; '
            f'{self._world.integrator} at {self._rate:g} Hz, {control}'
            + (f', {self._real_time_factor:g}x real time' if self._real_time_factor != 1.0
               else '')
            + ('; publishing /clock (stamps in simulated time)' if self._publish_clock
               else '')
            + f'; each body <name>: pose, twist, angular_momentum, odom, imu, frames <name> '
            f'and <name>/imu under {self._world_frame!r}; /tf and {MARKERS_TOPIC} for all; '
            f'{inputs} bodies take torque and wrench')

    # -- the interface of the simulation services (simulation_interfaces)

    @property
    def world(self):
        """Get the :class:`~rigid_body_sim.physics.World` of the bodies (world frame, SI)."""
        return self._world

    @property
    def scene(self):
        """Get the Scene the node started from (its ``bodies:`` as one-body members)."""
        return self._scene

    @property
    def world_frame(self):
        """Get the world frame's id as published (frame_prefix applied, as tf2 reads it)."""
        return self._world_frame

    @property
    def simulated_time(self):
        """Get the simulated time in s (0 at start-up and after a reset)."""
        return self._world.time

    @property
    def playing(self):
        """Get whether the simulation advances each tick (False while paused)."""
        return not self._paused

    def stamp_nanoseconds(self):
        """
        Return the stamp (ns) the state messages carry now.

        The simulated time since start-up (ticks x 1/rate, on through resets) with
        publish_clock, else the node clock's now (ROS time).
        """
        if self._publish_clock:
            return self._simulated_nanoseconds()
        return self.get_clock().now().nanoseconds

    def spawn_body(self, name, member):
        """
        Add body `name` simulated as the one-body Scene `member` says, from its state.

        The body joins the world at the world's time, with its effects and drawing; its
        topics, input subscriptions (with external_wrench), frames ``<name>`` and
        ``<name>/imu`` (on /tf_static) and marker appear from the next tick.  Its initial
        state (what a reset returns it to) is the member's.  ValueError (one line) for a
        name that is taken, not a name token (letters, digits, _ from a letter; at most
        the scene schema's length), a member that is not a one-body Scene, a frame tf2
        cannot use, or a body whose fixed step its stiff effect refuses.
        """
        if not isinstance(name, str) or not _BODY_NAME.fullmatch(name) or \
                len(name) > MAX_BODY_NAME_LENGTH:
            raise ValueError(f'a body name is letters, digits and _ from a letter, at most '
                             f'{MAX_BODY_NAME_LENGTH} characters; got {shortened(repr(name))}')
        if name in self._bodies:
            raise ValueError(f'a body called {name!r} exists already')
        if len(self._bodies) >= MAX_BODIES:
            raise ValueError(f'the node holds {len(self._bodies)} bodies, the most a scene '
                             'takes')
        if getattr(member, 'has_named_bodies', True):
            raise ValueError('expected a scene of one body (no bodies: list)')
        frames = self._frames_of(name)
        simulator = member.simulator()
        problem = self._body_step_problem(simulator, self._world.integrator, self._substeps,
                                          self._world.tolerance or 0.0)
        if problem is not None:
            raise ValueError(f'body {name!r}: {problem}')
        self._world.add(name, simulator)
        self._add_body(name, member, self._world.simulator(name), frames)
        self._rebuild_messages()
        self._check_subscribers(every_body=True)
        self.get_logger().info(f'spawned body {name!r} ({len(self._bodies)} bodies)')

    def delete_body(self, name):
        """
        Remove body `name`: its topics, inputs, frames and marker go with it.

        Its marker is deleted once (a MarkerArray with its marker's action DELETE on
        ``markers``), its static transform dropped from /tf_static.  KeyError if no body
        has that name.
        """
        if name not in self._bodies:
            raise KeyError(f'no body called {shortened(repr(name))}')
        body = self._bodies.pop(name)
        self._world.remove(name)
        for publisher in body.publishers.values():
            self.destroy_publisher(publisher)
        for subscription in body.subscriptions:
            self.destroy_subscription(subscription)
        for key in body.input_keys:
            self._inputs.pop(key, None)
            self._input_types.pop(key, None)
            self._received.pop(key, None)
            self._last_held.pop(key, None)
        self._rebuild_messages()
        self._check_subscribers(every_body=True)
        self._markers_publisher.publish(deleted_markers([(name, body.marker_id)]))
        self.get_logger().info(f'deleted body {name!r} ({len(self._bodies)} bodies)')

    def set_body_state(self, name, state):
        """
        Set the State (world frame, SI) of body `name`; a stopped body goes on from it.

        Projected onto the body's pivot if it has one.  Publishes nothing by itself: the
        next tick does.  KeyError for an unknown body, ValueError for what is no State.
        """
        if name not in self._bodies:
            raise KeyError(f'no body called {shortened(repr(name))}')
        if not isinstance(state, State):
            raise ValueError(f'expected a State; got {type(state).__name__}')
        self._world.set_state(name, state)

    def reset_simulation(self):
        """Put every body back to its initial state at simulated time 0 (as ~/reset)."""
        self._reset()

    def set_playing(self, playing):
        """Play (True) or pause (False) the simulation, as ~/pause does."""
        self._paused = not bool(playing)

    def step_while_paused(self, ticks):
        """
        Advance exactly `ticks` ticks of 1/rate s now, publishing each tick's messages.

        Only while paused: ValueError while playing, or for a negative or non-integer
        count.
        """
        if not self._paused:
            raise ValueError('the simulation is playing: pause it before stepping it')
        if isinstance(ticks, bool) or not isinstance(ticks, (int, np.integer)) or ticks < 0:
            raise ValueError(f'ticks must be a whole number >= 0; got {ticks!r}')
        for _ in range(int(ticks)):
            self._advance()
            self._publish_state(self.get_clock().now().nanoseconds, every_tick=True)

    # -- the ticks

    def _reset(self):
        self._world.reset({name: body.initial_state for name, body in self._bodies.items()},
                          0.0)
        self._diverged = None
        self._restart_after_reset()

    def _advance(self):
        started = time.thread_time()
        stopped = self._world.step(self._period)
        self._step_cpu += time.thread_time() - started
        self._steps_counted += 1
        for name, why in stopped.items():
            self.get_logger().error(f'body {name!r} stopped: {why}; its topics show its last '
                                    'finite state until it is set or the world reset')
        self._clock_ticks += 1
        for imu in self._noisy_imus:
            imu.advance(self._period)
        return True

    def _rows(self):
        """Return the bodies' packed states (N, 13): q, x, p, L (world frame, SI)."""
        return self._body_rows.rows()

    def _publish_state(self, now, every_tick=False):
        stamp = self._publish_clock_stamp(now)
        self._publish_phase += 1
        if not every_tick and self._publish_phase < self._publish_every:
            return
        self._publish_phase = 0
        started = time.thread_time()
        subscribers = self._body_subscribers
        topics = [topic for topic in BODY_TOPICS if subscribers[topic]]
        if self._tf_subscribed:
            topics.append(TF_TOPIC)
        if self._markers_subscribed:
            topics.append(MARKERS_TOPIC)
        if topics or subscribers['imu']:
            rows = self._rows()
            batches = self._serializer.write(rows, stamp, topics)
            for topic in BODY_TOPICS:
                batch = batches[topic]
                for index, publisher in subscribers[topic].items():
                    publisher.publish(batch.message(index))
            if self._tf_subscribed:
                self._tf_publisher.publish(batches[TF_TOPIC].message(0))
            if self._markers_subscribed:
                self._markers_publisher.publish(batches[MARKERS_TOPIC].message(0))
            if subscribers['imu']:
                self._publish_imus(subscribers['imu'], stamp)
        self._last_stamp = stamp
        self._publish_seconds += time.thread_time() - started
        self._publishes += 1

    def _publish_imus(self, subscribed, stamp):
        readings = np.zeros((len(self._body_list), 10))
        for index in subscribed:
            body = self._body_list[index]
            simulator = self._world.simulator(body.name)
            force, torque = simulator.applied_wrench()
            readings[index] = np.concatenate(body.imu.reading(simulator.state, force, torque))
        batch = self._serializer.write_imu(readings, stamp)
        for index, publisher in subscribed.items():
            publisher.publish(batch.message(index))

    def _check_subscribers(self, every_body=False):
        # Every publisher of a few hundred bodies each check; the whole node in turn (and
        # at once after bodies came or went: the bodies' indices changed).
        bodies = self._body_list
        count = len(bodies)
        per_call = max(1, _CHECKS_PER_CALL // (len(BODY_TOPICS) + 1))
        if every_body:
            per_call = max(per_call, count)
        if count <= per_call:
            indices = range(count)
        else:
            start = self._check_cursor
            indices = [(start + k) % count for k in range(per_call)]
            self._check_cursor = (start + per_call) % count
        subscribers = self._body_subscribers
        if count <= per_call:
            for table in subscribers.values():
                table.clear()
        for index in indices:
            for topic, publisher in bodies[index].publishers.items():
                if publisher.get_subscription_count() > 0:
                    subscribers[topic][index] = publisher
                else:
                    subscribers[topic].pop(index, None)
        self._tf_subscribed = self._tf_publisher is not None and \
            self._tf_publisher.get_subscription_count() > 0
        self._markers_subscribed = self._markers_publisher.get_subscription_count() > 0
        self._check_clock()

    # -- inputs

    def _input_target(self, topic):
        body = self._bodies[topic.rsplit('/', 1)[0]]
        return body.frame, body.limit, body.external_wrench

    def _hold_inputs(self, now):
        # Only the bodies whose held inputs changed (came, or expired) are held anew.
        for body in self._bodies.values():
            keys = body.input_keys
            if keys and any(self._inputs[key] is not self._last_held.get(key)
                            for key in keys):
                self._hold_sum(body.simulator, keys, now)
                for key in keys:
                    self._last_held[key] = self._inputs[key]
        self._inputs_changed = False

    def _restart_after_reset(self):
        # Every body's held inputs are cleared: each is held anew (with none).
        self._last_held = {}
        super()._restart_after_reset()

    def _set_drift_reference(self):
        # Energy and momentum are each body's: the status reports the world, not them.
        self._reference_energy = self._reference_momentum = 0.0

    # -- parameters

    def _step_refusal(self, integrator, substeps, tolerance):
        for name in self._world.names:
            problem = self._body_step_problem(self._world.simulator(name), integrator,
                                              substeps, tolerance)
            if problem is not None:
                return f'body {name!r}: {problem}'
        return None

    # -- diagnostics

    def _status_values(self, figures):
        self._choose_publish_every(figures)
        step, tick = figures.step_durations, figures.tick_durations
        taken = self._world.steps_taken
        active = taken[taken > 0]
        count = max(1, len(self._bodies))
        tolerance = self._world.tolerance
        stopped = sorted(self._world.diverged)
        keeps = self._keeps_rate(figures)
        simulated = figures.simulated if figures.simulated > 0.0 else step.size * self._period
        return [
            ('scene', self._scene.name),
            ('bodies', str(len(self._bodies))),
            ('bodies stopped', ', '.join(stopped[:10]) + (' ...' if len(stopped) > 10 else '')
             if stopped else 'none'),
            ('integrator', self._world.integrator),
            ('kernels', 'interpreted' if self._world.interpreted else 'compiled'),
            ('requested rate [Hz]', f'{self._rate:g}'),
            ('real-time factor', f'{self._real_time_factor:g}'),
            ('achieved rate [Hz]', f'{figures.achieved:.2f}'),
            ('achieved real-time factor', f'{figures.achieved / self._rate:.3f}'),
            ('missed ticks', str(figures.missed)),
            ('rate kept', 'yes' if keeps else 'no'),
            ('state published every k-th tick', str(self._publish_every)),
            ('tolerance [rad/s]', f'{tolerance:g}' if tolerance else 'off'),
            ('substeps', str(self._substeps)),
            ('substeps min', str(int(active.min())) if active.size else 'n/a'),
            ('substeps max', str(int(active.max())) if active.size else 'n/a'),
            ('step time p50 [ms]', _milliseconds(step, 50)),
            ('step time max [ms]', _milliseconds(step, 100)),
            ('tick duration p50 [ms]', _milliseconds(tick, 50)),
            ('tick duration p99 [ms]', _milliseconds(tick, 99)),
            ('integration per body-tick [us]',
             f'{1e6 * float(np.mean(step)) / count:.3f}' if step.size else 'n/a'),
            # All bodies' steps (wall, one thread) per simulated s, as the one-body node's.
            ('integration CPU per simulated s [s]',
             f'{float(np.sum(step)) / simulated:.3e}' if step.size and simulated > 0.0
             else 'n/a'),
            ('publishing CPU per publishing tick [ms]',
             f'{1e3 * self._last_publish_cost:.4f}'),
            ('simulated time [s]', f'{self._world.time:.6f}'),
            ('clock [s]', f'{1e-9 * self._simulated_nanoseconds():.6f}' if self._publish_clock
             else 'not published'),
            ('paused', str(self._paused)),
            ('external wrench active', str(any(held is not None
                                               for held in self._inputs.values()))),
            ('inputs rejected', str(self._rejected)),
            ('inputs scaled down to the scene limits', str(self._limited)),
        ]

    def _keeps_rate(self, figures):
        """Return whether the last window kept the rate (no tick missed, none owed)."""
        return figures.missed == 0 and not self._falling_behind

    def _choose_publish_every(self, figures):
        """Choose k from the window's measured costs; log a change once."""
        publishes, self._publishes = self._publishes, 0
        spent, self._publish_seconds = self._publish_seconds, 0.0
        if publishes:
            self._last_publish_cost = spent / publishes
        steps, self._steps_counted = self._steps_counted, 0
        step_cpu, self._step_cpu = self._step_cpu, 0.0
        if steps == 0 or publishes == 0:
            return
        step = step_cpu / steps
        other = 0.0  # inputs and expiry: within the share of the period left to the rest
        most = max(1, int(self._rate / self._real_time_factor))
        current = self._publish_every
        wanted = publish_every(step, self._last_publish_cost, other, self._wall_period, most)
        now = time.monotonic()
        if figures.missed > 0 or self._behind_schedule(0, 0.0):
            # Ticks missed with k: the machine gives the node less than its CPU costs say
            # (other processes' load): k doubles until the ticks keep their schedule, and
            # stays above the k that missed for a while.
            wanted = max(wanted, min(most, 2 * current))
            self._missed_with = (current, now)
        elif wanted < current:
            # Back to publishing more often, with a margin, one step every _STEP_DOWN s and
            # none for _MISSED_MEMORY s after ticks were missed: so that k does not flap.
            _, missed_at = self._missed_with
            if now - missed_at < _MISSED_MEMORY or now - self._k_changed < _STEP_DOWN:
                wanted = current
            else:
                wanted = max(wanted, current - 1, publish_every(
                    step, 1.25 * self._last_publish_cost, other, self._wall_period, most))
        if wanted != current:
            self._publish_every = wanted
            self._k_changed = now
            self.get_logger().info(
                f'publishing the state topics, /tf and {MARKERS_TOPIC} every {wanted} '
                f'tick(s) (a tick integrates in {1e3 * step:.3g} ms, publishes in '
                f'{1e3 * self._last_publish_cost:.3g} ms of CPU, its period is '
                f'{1e3 * self._wall_period:.3g} ms); the integration keeps every tick')

    def _amend_status(self, level, message):
        if self._publish_every > 1:
            message += (f'; publishing every {self._publish_every} ticks to keep the rate '
                        '(the integration runs every tick)')
            if level == DiagnosticStatus.OK:
                level = DiagnosticStatus.WARN
        stopped = self._world.diverged
        if stopped:
            message += f'; {len(stopped)} bodies stopped (non-finite): set or reset them'
            if level == DiagnosticStatus.OK:
                level = DiagnosticStatus.WARN
        return level, message


def _milliseconds(durations, percentile):
    if durations.size == 0:
        return 'n/a'
    return f'{1e3 * float(np.percentile(durations, percentile)):.4f}'

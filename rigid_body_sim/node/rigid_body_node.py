"""
The rigid_body_sim ROS 2 node: a timer-driven simulation of one rigid body in a scene.

The parameter ``scene`` (:mod:`rigid_body_sim.scenes`) gives the body, its initial state,
the effects on it (gravity, a pivot, drag, ...), how to draw it, and the default integrator
and rate; the body and initial-state parameters that are set override it (see
:mod:`rigid_body_sim.node.parameters`).

The tick runs on a ``create_timer`` of the node, on the steady clock (so ``use_sim_time``
never stops it, even when only its own ticks publish /clock), every (1/rate) /
real_time_factor s of wall-clock time.  Each tick expires inputs older than
``input_timeout``, holds the inputs that came since the last one, advances the simulation
by the nominal period 1/rate in ``substeps`` equal steps (or, with a ``tolerance``, in as
many as error control chooses), then publishes the state.  Ticks keep deadlines on the
steady clock: a late tick is followed at once by the ticks it held up (simulated time keeps
pace), one later than :data:`MAX_LAG` is dropped and counted as missed; one timer callback
works at most :data:`WORK_PER_CALLBACK` s before it lets the executor serve services,
inputs and signals, and catches up in the next.  Stamps: the node's clock, or with
``publish_clock`` the simulated time, which is then also published on ``/clock``.

Everything runs in the executor's one thread (:func:`rigid_body_sim.node.process.spin`):
inputs, service requests and parameter changes are applied as they come, between two
ticks, in the order they came; none waits for a deadline.  ``reset`` and ``pause`` reply
once applied, saying from which stamp on the published messages show the new state.

Integrator kernels that are not compiled are compiled in a process of their own
(:mod:`rigid_body_sim.node.background_compile`), never in the node's: a switch to such an
integrator is accepted at once, the simulation goes on with the old one until they are
compiled (a log line, and /diagnostics, say so), then switches; if the compilation fails,
one error line says so, the old integrator stays, and so does the parameter.  At start-up,
the services, parameters and /diagnostics come first and the ticks start once the scene's
integrator is compiled.

Topics (relative names, so ``--ros-args -r __ns:=/sat1`` namespaces them; the frame ids
follow the namespace too: ``frame_prefix``, by default ``sat1/`` there, comes before
``world_frame``, ``body_frame`` and ``imu_frame``, see :mod:`rigid_body_sim.messages.frames`):

- published: ``pose``, ``twist``, ``angular_momentum``, ``odom``, ``marker`` (see
  :func:`rigid_body_sim.messages.state.state_messages`; the marker is the scene's
  drawing), ``imu``, ``/tf`` and ``/tf_static`` (:mod:`rigid_body_sim.messages.tf`),
  ``/diagnostics`` at 1 Hz (:mod:`rigid_body_sim.messages.diagnostics`), and with
  ``publish_clock`` ``/clock`` at every tick;
- subscribed, only if the scene has the effect ``external_wrench``: ``torque``
  (Vector3Stamped) and ``wrench`` (WrenchStamped).  The header's frame_id chooses
  world-fixed (``world_frame`` or empty) or body-fixed (``body_frame``).  Each topic holds
  its latest input until replaced or timed out; the two topics' inputs add up.

Services: ``reset`` (std_srvs/Trigger), ``pause`` (std_srvs/SetBool) and the parameter
services (:mod:`rigid_body_sim.node.parameter_services`).  The model is the scene's
:class:`rigid_body_sim.physics.Simulator`; this module only converts between it and ROS.
"""

import math
import struct
import time

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rclpy.serialization import serialize_message
from rclpy.time import Time
from rosgraph_msgs.msg import Clock as ClockMessage
from sensor_msgs.msg import Imu as ImuMessage
from std_srvs.srv import SetBool
from std_srvs.srv import Trigger

from .background_compile import BackgroundCompilation
from .background_compile import compile_seconds
from .background_compile import kernels_compiled
from .clock_guard import ClockGuard
from .parameter_services import ParameterServices
from .parameters import check_integrator
from .parameters import declare_parameters
from .parameters import declare_scene_parameter
from .parameters import frame_ids_from_parameters
from .parameters import given_overrides
from .parameters import imu_model_from_parameters
from .parameters import PARAMETERS
from .parameters import scene_from_parameters
from .parameters import show_effective_values
from ..messages.diagnostics import diagnostic_array
from ..messages.diagnostics import NODE_NAME
from ..messages.diagnostics import status_name
from ..messages.diagnostics import status_values
from ..messages.diagnostics import substep_cap_reached
from ..messages.diagnostics import TickFigures
from ..messages.imu import fill_imu_message
from ..messages.imu import imu_message
from ..messages.marker import marker_geometry_from_drawing
from ..messages.qos import CLOCK_QOS
from ..messages.qos import DIAGNOSTICS_QOS
from ..messages.qos import INPUT_QOS
from ..messages.qos import SERVICE_QOS
from ..messages.qos import STATE_QOS
from ..messages.qos import TF_QOS
from ..messages.qos import TF_STATIC_QOS
from ..messages.state import STATE_TOPICS
from ..messages.state import STATE_TYPES
from ..messages.state import StateSerializer
from ..messages.tf import static_transforms
from ..messages.tf import TF_STATIC_TOPIC
from ..messages.tf import TF_TOPIC
from ..messages.tf import transform_message_class
from ..messages.tf import TransformSerializer
from ..messages.wrench import RejectedInput
from ..messages.wrench import wrench_input_from_message
from ..messages.wrench import WrenchInput
from ..physics import unresolved_rotation
from ..physics.error_control import MAX_SUBSTEPS
from ..physics.kernels import set_interpreted
from ..physics.simulator import DivergedError
from ..physics.stability import step_problem
from ..physics.warm_up import load_kernels
from ..scenes import load_scene
from ..text import shortened

__all__ = ['RigidBodyNode', 'ConfigurationError', 'NODE_NAME', 'MAX_LAG',
           'WORK_PER_CALLBACK']

_INPUT_TOPICS = ('torque', 'wrench')
_CLOCK_TOPIC = '/clock'
_DIAGNOSTICS_PERIOD = 1.0  # s
_WARNING_PERIOD = 1.0  # s between two warnings of the same kind
# Ring of the latest tick durations: 65536 ticks is over a minute at 1 kHz, enough for the
# percentiles in the shutdown summary, and bounded memory for a node that runs for days.
_HISTORY = 1 << 16
# Once falling behind, the node keeps up again when a report finds no tick missed and the
# schedule at most this many seconds behind (a timer callback's usual delay, not a backlog).
_CAUGHT_UP_LAG = 0.05
MAX_LAG = 0.5
"""Ticks held up by longer than this (s) are dropped rather than caught up with."""
WORK_PER_CALLBACK = 0.05
"""Most wall-clock s one timer callback spends catching up before the executor serves the
rest (services, inputs, signals); the ticks still due follow in the next callback."""
# How often (s) the node looks for the topics that have subscribers.
_SUBSCRIBER_CHECK_PERIOD = 0.1
# How often (s) the node looks whether a background compilation ended.
_COMPILATION_POLL_PERIOD = 0.2


class ConfigurationError(ValueError):
    """
    The node's configuration describes no valid simulation (already logged).

    ``node`` is the node that failed to configure: the caller destroys it (its process
    bounds the middleware's shutdown first: see :mod:`.process`).
    """

    def __init__(self, message, node):
        super().__init__(message)
        self.node = node


class RigidBodyNode(Node):
    """
    Simulate one rigid body and publish its state; see the module docstring.

    The timers start with the node; :func:`rigid_body_sim.node.process.spin` runs them.

    Raises
    ------
    ConfigurationError
        If the parameters are invalid: one clear error is logged first; the caller destroys
        the node, the error's ``node``.

    """

    tick_error = None
    """The exception that stopped the ticks, if one did."""

    def __init__(self, node_name=NODE_NAME, **kwargs):
        # rclpy's parameter services let a malformed request stop the node: ours answer it.
        parameter_services = kwargs.pop('start_parameter_services', True)
        super().__init__(node_name, start_parameter_services=False, **kwargs)
        self._overrides = given_overrides(self)
        if parameter_services:
            ParameterServices(self, note=self._parameter_note)
        self._ticks = 0
        self._timer = None
        self._compilation = None  # the integrator's kernels compiling in the background
        self._compilation_timer = None
        try:
            self._configure()
        except ValueError as error:
            self.get_logger().error(f'invalid configuration: {error}')
            raise ConfigurationError(str(error), self) from None

    # -- set-up

    def _configure(self):
        # The scene first: its integrator and rate are the defaults of those parameters.
        scene = load_scene(declare_scene_parameter(self, self._overrides))
        values = declare_parameters(self, scene, self._overrides)
        self._warn_unknown_overrides()
        named_scene, scene = scene, scene_from_parameters(scene, values)
        parameter_sources = show_effective_values(self, named_scene, values, scene)
        self._scene = scene
        body = scene.body
        self._initial_state = scene.state
        self._simulator = scene.simulator(tolerance=values['tolerance'])
        self._simulator.substeps = values['substeps']
        self._rate = scene.rate
        self._period = 1.0 / self._rate
        self._real_time_factor = values['real_time_factor']
        self._wall_period = self._period / self._real_time_factor
        kernels_ready = self._prepare_kernels(scene.integrator, values)
        self._substeps = values['substeps']
        self._input_timeout_ns = int(values['input_timeout'] * 1e9)
        self._max_wrench = values['max_wrench']
        # Prefixed (frame_prefix, by default the namespace) and as tf2 reads them.
        frames = frame_ids_from_parameters(values)
        self._world_frame = frames['world_frame']
        self._body_frame = frames['body_frame']
        imu_frame = self._imu_frame = frames['imu_frame']

        self._serializer = StateSerializer(
            body, self._world_frame, self._body_frame,
            geometry=marker_geometry_from_drawing(scene.drawing))
        self._state_publishers = [
            (topic, self.create_publisher(STATE_TYPES[topic], topic, STATE_QOS))
            for topic in STATE_TOPICS]
        # The simulated IMU: computed only while someone listens; its noise (if any) drawn
        # every tick, so a seed gives the same sequence whenever a subscriber comes.
        self._imu = scene.imu_sensor(imu_model_from_parameters(values))
        self._imu_publisher = self.create_publisher(ImuMessage, 'imu', STATE_QOS)
        self._imu_message = imu_message(imu_frame, self._imu, self._period)
        self._imu_subscribed = False
        self._imu_noisy = self._imu.model.noisy
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
        self._start_clock(values)
        tf_status = self._start_tf(imu_frame)

        self._inputs = dict.fromkeys(_INPUT_TOPICS)  # topic -> (WrenchInput, held from ns)
        self._inputs_changed = False
        # topic -> the latest message received since the last tick, serialised: the tick
        # reads it (one per topic and tick), so a flood of inputs costs the callbacks only
        # a store each, and cannot take the tick's time.
        self._received = {}
        self._input_types = {}
        self._paused = False
        # Why the simulation stopped (a state that turned non-finite), until a reset.
        self._diverged = None
        self._last_warning = {}
        self._rejected = 0
        self._limited = 0
        external_wrench = scene.external_wrench
        self._limit = None if external_wrench is None or (
            external_wrench.max_force is None and external_wrench.max_torque is None) \
            else external_wrench.limit
        # Only a scene that takes outside input listens for it.
        if scene.accepts_external_wrench:
            from geometry_msgs.msg import Vector3Stamped
            from geometry_msgs.msg import WrenchStamped
            for topic, message_type in (('torque', Vector3Stamped),
                                        ('wrench', WrenchStamped)):
                self._input_types[topic] = message_type
                self.create_subscription(
                    message_type, topic,
                    lambda data, topic=topic: self._input_callback(topic, data),
                    INPUT_QOS, raw=True)
        self.create_service(Trigger, 'reset', self._reset_callback, qos_profile=SERVICE_QOS)
        self.create_service(SetBool, 'pause', self._pause_callback, qos_profile=SERVICE_QOS)
        self.add_on_set_parameters_callback(self._validate_parameters_callback)
        self.add_post_set_parameters_callback(self._parameters_set_callback)

        self._set_drift_reference()
        self._log_start(scene, values, parameter_sources, tf_status)
        self._start_running(kernels_ready, scene.integrator)

    def _prepare_kernels(self, integrator, values):
        """
        Load the integrator's kernels, or run their source until compiled; check the step.

        Returns whether the kernels were compiled on this machine.  ValueError (what to
        change) for a scene whose fixed step cannot carry its stiff effect.
        """
        kernels_ready = kernels_compiled(integrator)
        if kernels_ready:
            # The integrator's compiled kernels loaded now, so that loading them from the cache
            # does not make the first tick late.
            load_kernels(integrator)
        else:
            # Not compiled on this machine: the kernels' source runs interpreted, nothing
            # compiled in this process, until a compile beside the node has them ready.
            set_interpreted(True)
            self._simulator.interpreted = True
        # Interpreted, the check runs the same steps.
        reason = self._step_refusal(integrator, values['substeps'], values['tolerance'])
        if reason is not None:
            raise ValueError(reason)
        return kernels_ready

    def _start_clock(self, values):
        """Set up simulated time, /clock (with publish_clock) and the ROS clock's guard."""
        # Simulated time: _clock_ticks whole periods since start-up, counted on through
        # resets and not while paused, so /clock never goes back.
        self._publish_clock = values['publish_clock']
        self._clock_ticks = 0
        self._clock_subscribed = False
        self._clock_publisher = None
        if self._publish_clock:
            self._clock_publisher = self.create_publisher(ClockMessage, _CLOCK_TOPIC,
                                                          CLOCK_QOS)
            # Clock is a lone Time: its CDR bytes are a 4-byte header, then sec and nanosec.
            self._clock_message = bytearray(serialize_message(ClockMessage()))
            self._clock_packer = struct.Struct(('<' if self._clock_message[1] == 1 else '>')
                                               + 'iI')
        self._system_time = False
        self._last_stamp = 0  # ns: the stamp of the last state published
        self._clock_guard = self._guard_ros_clock()

    def _start_running(self, kernels_ready, integrator):
        """Start the statistics, the timers and the ticks (once the kernels are compiled)."""
        self._missed_ticks = 0
        self._subscribed = {}
        self._tick_durations = np.zeros(_HISTORY)
        self._step_durations = np.zeros(_HISTORY)
        # Start, ticks, missed ticks and simulated time then.
        self._window = (time.monotonic(), 0, 0, 0.0)
        self._falling_behind = False
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._check_subscribers()
        self.create_timer(_SUBSCRIBER_CHECK_PERIOD, self._check_subscribers,
                          clock=self._steady_clock)
        self.create_timer(_DIAGNOSTICS_PERIOD, self._publish_diagnostics,
                          clock=self._steady_clock)
        self._start_ticking(time.monotonic())
        if not kernels_ready:
            self._compile_in_background(integrator)

    def _start_tf(self, imu_frame):
        """Create the /tf publishers and publish /tf_static; return the log's TF words."""
        message_class, reason = transform_message_class()
        self._tf_publisher = None
        if message_class is None:
            self.get_logger().warning(f'TF is off (no /tf, /tf_static): {reason}')
            return 'TF off'
        self._tf_serializer = TransformSerializer(message_class, self._world_frame,
                                                  self._body_frame)
        self._tf_publisher = self.create_publisher(message_class, TF_TOPIC, TF_QOS)
        self._tf_static_publisher = self.create_publisher(message_class, TF_STATIC_TOPIC,
                                                          TF_STATIC_QOS)
        stamp = 0 if self._publish_clock else self.get_clock().now().nanoseconds
        self._tf_static_publisher.publish(static_transforms(
            message_class, self._body_frame, imu_frame, self._imu.model, stamp))
        return (f'TF {self._world_frame!r} -> {self._body_frame!r} on /tf, '
                f'{self._body_frame!r} -> {imu_frame!r} on /tf_static')

    def _log_start(self, scene, values, parameter_sources, tf_status):
        body = scene.body
        moments = ', '.join(f'{m:.4g}' for m in body.principal_moments)
        effects = ', '.join(scene.effect_names()) or 'none (torque-free)'
        inputs = 'torque and wrench' if scene.accepts_external_wrench else 'no inputs'
        imu_noise = f'noise seed {self._imu.model.seed}' if self._imu_noisy else 'no noise'
        timing = ''
        tolerance = self._simulator.tolerance
        if tolerance is not None:
            timing += f' at least, error control {tolerance:g} rad/s'
        if self._real_time_factor != 1.0:
            timing += f', {self._real_time_factor:g}x real time'
        if self._publish_clock:
            timing += ', publishing /clock (stamps in simulated time)'
        self.get_logger().info(
            f'simulating scene {scene.name!r}: a body of {body.mass:g} kg, principal moments '
            f'({moments}) kg m^2, effects: {effects}; {self._simulator.integrator} at '
            f'{self._rate:g} Hz x {self._substeps} substep(s){timing}; publishing pose, '
            f'twist, angular_momentum, odom, marker in frame {self._world_frame!r}, imu in '
            f'frame {self._imu_frame!r} ({imu_noise}), {tf_status}; subscribed to '
            f'{inputs}')
        self.get_logger().info(parameter_sources)
        warning = unresolved_rotation(body, self._simulator.state, self._period,
                                      self._substeps, tolerance)
        if warning is not None:
            self.get_logger().warning(warning)

    def _warn_unknown_overrides(self):
        # rclpy ignores overrides of undeclared parameters: a typo in a params file would
        # silently leave the default in place.
        # rclpy's own parameters, which a dumped parameter file holds too.
        known = {spec.name for spec in PARAMETERS} | {'use_sim_time',
                                                      'start_type_description_service'}
        unknown = sorted(set(self._overrides) - known)
        if unknown:
            self.get_logger().warning(
                f'ignoring unknown parameter(s): {", ".join(map(shortened, unknown))}; known '
                f'parameters: {", ".join(spec.name for spec in PARAMETERS)}')

    # -- the ticks

    def _start_ticking(self, last_tick):
        """(Re)start the tick timer at the current pace, the next tick one period after."""
        if self._timer is not None:
            self.destroy_timer(self._timer)
        self._restart_schedule(last_tick)
        self._timer = self.create_timer(self._wall_period, self._timer_callback,
                                        clock=self._steady_clock)

    def _restart_schedule(self, last_tick):
        # The next tick is due one period after last_tick; the timer keeps its phase (a
        # callback half a period early or more waits for the next), so the ticks follow
        # the new deadlines one per period.
        self._last_tick = last_tick
        self._next_due = last_tick + self._wall_period

    def _timer_callback(self):
        # Deadlines on the steady clock at whole periods: the rate is exact on average
        # whatever the timer's jitter; the ticks a late callback held up follow at once.
        now = time.monotonic()
        period = self._wall_period
        lag = now - self._next_due
        if lag < -0.5 * period:
            return  # early (a timer restarted at a new pace): the deadline decides
        max_lag = max(MAX_LAG, 2.0 * period)
        if lag > max_lag:
            missed = int(lag / period)
            self._missed_ticks += missed
            self._next_due += missed * period
        end = now + WORK_PER_CALLBACK
        try:
            while True:
                self._tick()
                self._last_tick = self._next_due
                self._next_due += period
                now = time.monotonic()
                if now < self._next_due - 0.5 * period or now >= end:
                    return
        except Exception as error:  # noqa: B902 (a failed tick must not be silent)
            if not self.context.ok():
                return  # shut down (SIGTERM) while publishing: nothing to report
            self.get_logger().fatal(f'the simulation tick failed: {error!r}')
            self.tick_error = error
            self.context.try_shutdown()

    def _tick(self):
        started = time.perf_counter()
        # The node's clock; while it runs on system time (no /clock), time.time_ns() reads
        # the same clock for a tenth of the cost of Clock.now().
        now = time.time_ns() if self._system_time else self.get_clock().now().nanoseconds
        # Inputs expire on the steady clock: a ROS clock that stands still or runs back
        # (use_sim_time) must not hold an input forever.
        steady = time.monotonic_ns()
        if self._received:
            self._take_received_inputs()
        if self._input_timeout_ns > 0 and self._expire_inputs(steady):
            self._inputs_changed = True
        if self._inputs_changed:
            self._hold_inputs(steady)
        stepped = time.perf_counter()
        if self._diverged is not None:
            return  # stopped at the last finite state until a reset: nothing to publish
        if not self._paused and not self._advance():
            return
        step_duration = time.perf_counter() - stepped
        self._publish_state(now)
        index = self._ticks % _HISTORY
        self._step_durations[index] = step_duration
        self._tick_durations[index] = time.perf_counter() - started
        self._ticks += 1

    def _advance(self):
        """Advance the simulation by one tick; return False if it stopped (diverged)."""
        # substeps steps, or under error control as many as it chooses.
        try:
            self._simulator.step(self._period)
        except DivergedError as error:
            self._stop_diverged(error)
            return False
        self._clock_ticks += 1
        if self._imu_noisy:
            self._imu.advance(self._period)
        return True

    def _stop_diverged(self, error):
        # The state topics stop rather than carry NaN; the simulator holds the last finite
        # state, which /diagnostics (ERROR, naming the cause) and a reset go on from.
        self._diverged = str(error)
        self.get_logger().error(
            f'the simulation stopped: {self._diverged}; the state topics are silent until '
            'a reset (~/reset)')
        self._publish_diagnostics()

    def _publish_clock_stamp(self, now):
        """Publish /clock (with publish_clock); return the stamp of this tick's messages (ns)."""
        if not self._publish_clock:
            return now
        # /clock first: a sim-time consumer's clock reaches a stamp before the message.
        stamp = self._simulated_nanoseconds()
        if self._clock_subscribed:
            self._clock_packer.pack_into(self._clock_message, 4, *divmod(stamp, 1_000_000_000))
            self._clock_publisher.publish(bytes(self._clock_message))
        return stamp

    def _publish_state(self, now):
        stamp = self._publish_clock_stamp(now)
        state = self._simulator.state
        if self._subscribed:
            serialized = self._serializer.serialize(state, stamp, self._subscribed)
            for topic, publisher in self._subscribed.items():
                publisher.publish(serialized[topic])
        if self._tf_subscribed:
            # The pose message's own doubles: position, then the quaternion (x, y, z, w).
            self._tf_publisher.publish(self._tf_serializer.serialize(
                stamp, state.position.tolist() + state.quaternion.tolist()))
        if self._imu_subscribed:
            self._publish_imu(stamp)
        self._last_stamp = stamp

    def _publish_imu(self, stamp):
        # The accelerations at the published state, from the wrench acting on it now (held
        # inputs and effects, in one compiled call).
        simulator = self._simulator
        force, torque = simulator.applied_wrench()
        reading = self._imu.reading(simulator.state, force, torque)
        self._imu_publisher.publish(fill_imu_message(self._imu_message, stamp, *reading))

    def _simulated_nanoseconds(self):
        # k periods of 1/rate s in ns, rounded; in integer arithmetic for a whole number of
        # Hz, so the spacing is exact (1e9/rate ns when that is whole) however long the run.
        rate = self._rate
        if rate.is_integer():
            whole = int(rate)
            return (self._clock_ticks * 1_000_000_000 + whole // 2) // whole
        return round(self._clock_ticks * 1e9 / rate)

    def _check_subscribers(self):
        # A topic nobody subscribes to is neither serialised nor published: the tick then
        # costs what the listeners need; so is whether the node's clock follows /clock
        # (use_sim_time) or the system clock.
        self._subscribed = {topic: publisher for topic, publisher in self._state_publishers
                            if publisher.get_subscription_count() > 0}
        self._imu_subscribed = self._imu_publisher.get_subscription_count() > 0
        self._tf_subscribed = self._tf_publisher is not None and \
            self._tf_publisher.get_subscription_count() > 0
        self._check_clock()

    def _check_clock(self):
        """Look whether /clock has subscribers and the node's clock is the system's."""
        self._clock_subscribed = self._publish_clock and \
            self._clock_publisher.get_subscription_count() > 0
        clock = self.get_clock()
        self._system_time = clock.clock_type == ClockType.SYSTEM_TIME or (
            clock.clock_type == ClockType.ROS_TIME and not clock.ros_time_is_active)

    def _guard_ros_clock(self):
        """
        Follow /clock here rather than through rclpy's TimeSource (ros/clock_guard.py).

        Returns the ClockGuard, or None when the node runs on the system clock.  rclpy
        subscribed to /clock when use_sim_time was given at start; that subscription is
        replaced by one whose callback refuses what is not a time instead of raising.
        """
        if not self.get_parameter('use_sim_time').value:
            return None
        clock_topic = self.resolve_topic_name(_CLOCK_TOPIC)  # as remapped, if it is
        for subscription in list(self.subscriptions):
            if subscription.topic_name == clock_topic:
                self.destroy_subscription(subscription)
        self.create_subscription(ClockMessage, _CLOCK_TOPIC, self._clock_callback,
                                 CLOCK_QOS)
        return ClockGuard()

    def _clock_callback(self, message):
        stamp = self._clock_guard.receive(message.clock.sec, message.clock.nanosec)
        if stamp is None:
            self._warn_throttled('clock', f'refused a /clock message '
                                 f'({self._clock_guard.last_rejected}); the ROS clock stays '
                                 'where it was')
            return
        self.get_clock().set_ros_time_override(
            Time(nanoseconds=stamp, clock_type=ClockType.ROS_TIME))

    def _expire_inputs(self, now):
        expired = False
        for topic, held in self._inputs.items():
            if held is not None and held[1] is not None and \
                    now - held[1] > self._input_timeout_ns:
                self._inputs[topic] = None
                expired = True
        return expired

    def _hold_inputs(self, now):
        # Inputs from both topics add up; body-fixed parts are held as such so that they
        # turn with the body during the substeps.  An input holds from the tick that
        # applies it: input_timeout counts from there.
        self._hold_sum(self._simulator, list(self._inputs), now)
        self._set_drift_reference()
        self._inputs_changed = False

    def _hold_sum(self, simulator, keys, now=None):
        """Hold on `simulator` the sum of the inputs of `keys` (topics), held from `now`."""
        parts = {'world': [np.zeros(3), np.zeros(3)], 'body': [np.zeros(3), np.zeros(3)]}
        for key in keys:
            held = self._inputs[key]
            if held is not None:
                wrench, held_from = held
                if held_from is None:
                    self._inputs[key] = (wrench, now)
                part = parts[wrench.frame]
                part[0] = part[0] + wrench.force
                part[1] = part[1] + wrench.torque
        simulator.hold_wrench(force_world=parts['world'][0], torque_world=parts['world'][1],
                              force_body=parts['body'][0], torque_body=parts['body'][1])

    def _set_drift_reference(self):
        self._reference_energy = self._simulator.energy()
        self._reference_momentum = float(np.linalg.norm(
            self._simulator.state.angular_momentum))

    # -- callbacks: inputs, services and parameters, applied as they come (between ticks)

    def _input_callback(self, topic, data):
        # Kept, not read: the next tick takes the latest (see _received).
        self._received[topic] = data

    def _take_received_inputs(self):
        """Read the latest input of each topic received since the last tick, and hold it."""
        received, self._received = self._received, {}
        for topic, data in received.items():
            try:
                message = deserialize_message(data, self._input_types[topic])
            except Exception as error:  # noqa: B902 (a peer's bytes: any failure is a refusal)
                self._rejected += 1
                self._warn_throttled((topic, 'bytes'), f'rejected a {topic} input that does '
                                     f'not deserialise ({shortened(str(error))}), state '
                                     'unchanged')
                continue
            wrench = self._accepted_input(topic, message)
            if wrench is not None:
                self._inputs[topic] = (wrench, None)  # held from the tick that applies it
                self._inputs_changed = True

    def _input_target(self, topic):
        """
        Return (body frame id, limit function or None, external_wrench) of an input topic.

        What an input on `topic` acts on: the frame its body-fixed inputs name, and the
        scene's limits (:mod:`rigid_body_sim.physics.effects.external_wrench`).
        """
        return self._body_frame, self._limit, self._scene.external_wrench

    def _accepted_input(self, topic, message):
        """Return the WrenchInput of a torque or wrench message, or None if rejected."""
        body_frame, limit, limits = self._input_target(topic)
        try:
            wrench = wrench_input_from_message(message, self._world_frame, body_frame,
                                               self._max_wrench)
        except RejectedInput as error:
            self._rejected += 1
            self._warn_throttled((topic, error.kind),
                                 f'rejected a {topic} input, state unchanged: {error}')
            return None
        if limit is not None:
            force, torque = limit(wrench.force, wrench.torque)
            if np.any(force != wrench.force) or np.any(torque != wrench.torque):
                self._limited += 1
                self._warn_throttled((topic, 'limit'), (
                    f"scaled a {topic} input down to the scene's limits (max_force "
                    f'{limits.max_force} N, max_torque {limits.max_torque} N m)'))
                wrench = WrenchInput(force, torque, wrench.frame)
        return wrench

    def _from_stamp(self):
        seconds, nanoseconds = divmod(self._last_stamp, 1_000_000_000)
        guard = self._clock_guard
        if not self._publish_clock and guard is not None and not guard.stamps_ordered():
            # Stamped with a /clock that stands still or never came: a stamp cannot tell
            # the messages before this from those after it.
            return (f'the stamps follow /clock, which stands at {seconds}.{nanoseconds:09d} s: '
                    'they do not tell messages before this from those after it')
        return f'every message stamped after {seconds}.{nanoseconds:09d} s shows it'

    def _reset_callback(self, request, response):
        self._reset()
        response.success = True
        response.message = (
            f'reset to the initial state at simulated time 0 ({self._from_stamp()}'
            + ('; /clock counts on)' if self._publish_clock else ')'))
        return response

    def _reset(self):
        """Put the body back to its initial state at simulated time 0, its inputs cleared."""
        self._simulator.reset(self._initial_state, time=0.0)
        self._diverged = None
        self._restart_after_reset()

    def _restart_after_reset(self):
        if self._timer is not None:
            # Simulated time 0 is now: ticks still due from before the reset (a late
            # node's backlog) belonged to the run it ended, and are not run after it.
            self._restart_schedule(time.monotonic())
        self._inputs = dict.fromkeys(self._inputs)
        self._received = {}
        self._hold_inputs(None)

    def _pause_callback(self, request, response):
        self._paused = bool(request.data)
        response.success = True
        state = 'paused' if self._paused else 'running'
        response.message = (f'{state} at simulated time {self._simulator.time:.9f} s '
                            f'({self._from_stamp()})')
        return response

    def _validate_parameters_callback(self, parameters):
        # Types, ranges and read-only flags are checked by rclpy from the descriptors.
        simulator = self._simulator
        proposed = {'integrator': simulator.integrator, 'substeps': self._substeps,
                    'tolerance': simulator.tolerance or 0.0}
        for parameter in parameters:
            if parameter.name == 'use_sim_time':
                # rclpy would follow /clock again through its own subscription, which a
                # peer's malformed /clock message turns into an exception (clock_guard.py).
                return SetParametersResult(
                    successful=False, reason='use_sim_time is set at start-up only '
                    '(--ros-args -p use_sim_time:=true); restart the node to change it')
            if parameter.name == 'integrator':
                reason = check_integrator(shortened(parameter.value))
                if reason is not None:
                    return SetParametersResult(successful=False, reason=reason)
            if parameter.name in proposed:
                proposed[parameter.name] = parameter.value
        # A fixed step too long for a stiff effect would turn the state non-finite: refused
        # here, with what to change.  (An integrator still to compile is checked when it is,
        # unless the node runs interpreted: then it is checked interpreted.)
        if self._simulator.interpreted or kernels_compiled(proposed['integrator']):
            reason = self._step_refusal(**proposed)
            if reason is not None:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _parameter_note(self, parameters):
        """Return what a successful set of `parameters` will do beyond setting them ('')."""
        for parameter in parameters:
            # (An unknown name is refused by the validation: no note.)
            if parameter.name == 'integrator' and isinstance(parameter.value, str) and \
                    check_integrator(parameter.value) is None:
                return self._switch_note(parameter.value)
        return ''

    def _switch_note(self, name):
        """
        Return when a switch to integrator `name` acts, if not at once ('' if it does).

        Read before the switch (see :meth:`_switch_integrator`, whose cases these are).
        """
        current = self._simulator.integrator
        pending = self._compilation
        if pending is not None and pending.name == name:
            return (f'{name} compiling in the background already (about '
                    f'{pending.estimate:.0f} s, {pending.elapsed():.0f} s so far); {current} '
                    'runs until then')
        if self._simulator.interpreted and not kernels_compiled(name):
            return (f'{name} runs at once from its source, interpreted (the same steps, '
                    f'slower), while its kernels compile in the background (about '
                    f"{compile_seconds(name):.0f} s from the registry's compile estimate); "
                    'then compiled')
        if name != current and not kernels_compiled(name):
            return (f'{name} compiling in the background (about {compile_seconds(name):.0f} s '
                    f"from the registry's compile estimate); {current} runs until then, then "
                    f'{name} takes over with the state kept')
        if pending is not None:
            return (f'{name} runs at once; the pending switch to {pending.name} (its kernels '
                    'compiling) is abandoned')
        return ''

    def _step_refusal(self, integrator, substeps, tolerance):
        """Return why the steps of this configuration cannot carry a stiff effect, or None."""
        return self._body_step_problem(self._simulator, integrator, substeps, tolerance)

    def _body_step_problem(self, simulator, integrator, substeps, tolerance):
        """Return why `simulator`'s body and effects refuse these steps a tick, or None."""
        problem = step_problem(simulator.body, simulator.effects, integrator,
                               1 if tolerance > 0.0 else substeps, self._period)
        if problem is not None and (tolerance == 0.0 or math.isinf(problem[0])):
            return problem[1]
        return None

    def _parameters_set_callback(self, parameters):
        for parameter in parameters:
            self._apply_parameter(parameter.name, parameter.value)

    def _apply_parameter(self, name, value):
        if name == 'integrator':
            self._switch_integrator(value)
        elif name == 'substeps':
            self._substeps = value
            self._simulator.substeps = value
        elif name == 'tolerance':
            # The state is kept; the next tick estimates anew.
            self._simulator.tolerance = value
            self.get_logger().info('error control is now ' + (
                f'{value:g} rad/s' if value > 0.0 else f'off ({self._substeps} substep(s))'))
        elif name == 'input_timeout':
            self._input_timeout_ns = int(value * 1e9)
        elif name == 'max_wrench':
            self._max_wrench = value
        elif name == 'real_time_factor':
            self._real_time_factor = value
            self._wall_period = self._period / value
            if self._timer is not None:
                # The next tick one new period after the last one (at once if that is
                # past), never at the deadline set at the old pace.
                self._start_ticking(min(self._last_tick, time.monotonic()))
            self.get_logger().info(f'real_time_factor is now {value:g}')

    # -- integrator switches, and their kernels compiled in the background

    def _switch_integrator(self, name):
        pending = self._compilation
        if pending is not None and pending.name == name:
            return  # on its way
        if self._simulator.interpreted and not kernels_compiled(name):
            # Nothing compiled runs yet: the new method runs interpreted at once, and the
            # compile beside the node is for it now.
            self._simulator.integrator = name
            self.get_logger().info(f'integrator is now {name} (interpreted until compiled)')
            self._compile_in_background(name)
            return
        running = self._timer is not None and name == self._simulator.integrator
        if not running and not kernels_compiled(name):
            self._compile_in_background(name)
            return
        if pending is not None:
            self._end_compilation()
            self.get_logger().info(f'compiling the kernels of {pending.name} abandoned')
        self._use_integrator(name)

    def _use_integrator(self, name, how=''):
        # Kernels loaded from the cache (tens of ms), then the simulator keeps its state:
        # the switch is continuous (from interpreted too: the same steps, compiled).
        load_kernels(name)
        if self._simulator.interpreted:
            set_interpreted(False)
            self._simulator.interpreted = False
        reason = self._step_refusal(name, self._substeps, self._simulator.tolerance or 0.0)
        if reason is not None:
            self._refuse_integrator(name, reason)
            return
        self._simulator.integrator = name
        self.get_logger().info(f'integrator is now {name}{how}')
        if self._timer is None:
            self.get_logger().info(f'simulating with {name}')
            self._window = (time.monotonic(), self._ticks, self._missed_ticks,
                            self._simulator.time)
            self._start_ticking(time.monotonic())

    def _compile_in_background(self, name):
        """Compile the kernels of integrator `name` beside the node; switch when done."""
        if self._compilation is not None:
            self._end_compilation()
        self._compilation = BackgroundCompilation(name)
        self._compilation_timer = self.create_timer(
            _COMPILATION_POLL_PERIOD, self._poll_compilation, clock=self._steady_clock)
        until = (f'integrating with {self._simulator.integrator} until then'
                 if not self._simulator.interpreted else
                 f'integrating with the source of {name} interpreted until then (the same '
                 'steps, slower)')
        self.get_logger().info(
            f'the kernels of {name} are not compiled: compiling them in the background '
            f'(about {self._compilation.estimate:.0f} s; `rigid-body-sim compile` after an '
            f'install avoids it); {until}')

    def _end_compilation(self):
        self._compilation.stop()
        self._compilation = None
        self.destroy_timer(self._compilation_timer)
        self._compilation_timer = None

    def _poll_compilation(self):
        compilation = self._compilation
        result = None if compilation is None else compilation.poll()
        if result is None:
            return
        self._end_compilation()
        succeeded, what = result
        if succeeded:
            self._use_integrator(compilation.name, f' (its kernels {what} in the background)')
        elif self._simulator.interpreted and compilation.name == self._simulator.integrator:
            self.get_logger().error(
                f'compiling the kernels of {compilation.name} failed ({what}; '
                f'`rigid-body-sim compile {compilation.name}` shows why): integrating on with '
                'its source interpreted (the same steps, slower)')
        else:
            self._refuse_integrator(
                compilation.name, f'compiling the kernels of {compilation.name} failed ({what}; '
                f'`rigid-body-sim compile {compilation.name}` shows why)')

    def _refuse_integrator(self, name, reason):
        """Say why integrator `name` cannot run; stop at start-up, else keep the current one."""
        if self._timer is None:
            # At start-up: nothing to simulate with.
            self.get_logger().fatal(f'cannot simulate with {name}: {reason}')
            self.tick_error = RuntimeError(f'{name}: {reason}')
            self.context.try_shutdown()
            return
        current = self._simulator.integrator
        self.get_logger().error(f'not switching to {name}: {reason}; integrating on with '
                                f'{current}')
        # The parameter says what runs.
        self.set_parameters([Parameter('integrator', value=current)])

    def _compilation_status(self):
        """Return the diagnostics' words about a background compilation ('' if none)."""
        compilation = self._compilation
        if compilation is None:
            return ''
        return (f'compiling the kernels of {compilation.name} in the background (about '
                f'{compilation.estimate:.0f} s, {compilation.elapsed():.0f} s so far)')

    def destroy_node(self):
        """Stop a background compilation, then destroy the node."""
        if self._compilation is not None:
            self._end_compilation()
        return super().destroy_node()

    def _warn_throttled(self, key, text):
        now = time.monotonic()
        if now - self._last_warning.get(key, -math.inf) >= _WARNING_PERIOD:
            self._last_warning[key] = now
            self.get_logger().warning(text)

    # -- diagnostics and statistics

    def _recent(self, durations, count):
        count = min(count, _HISTORY, self._ticks)
        end = self._ticks % _HISTORY
        if count <= end:
            return durations[end - count:end]
        return np.concatenate((durations[end - count:], durations[:end]))

    def _publish_diagnostics(self):
        now = time.monotonic()
        window_start, window_ticks, window_missed, window_simulated = self._window
        ticks = self._ticks - window_ticks
        self._window = (now, self._ticks, self._missed_ticks, self._simulator.time)
        achieved = ticks / (now - window_start) if now > window_start else 0.0
        missed = self._missed_ticks - window_missed
        figures = TickFigures(achieved, missed,
                              self._recent(self._step_durations, ticks),
                              self._recent(self._tick_durations, ticks),
                              self._simulator.time - window_simulated)
        values = self._status_values(figures)
        level, message = DiagnosticStatus.OK, 'running'
        compiling = self._compilation_status()
        if self._diverged is not None:
            level = DiagnosticStatus.ERROR
            message = f'stopped: {self._diverged}; reset to start again'
        elif self._timer is None:
            message = f'waiting: {compiling}; the simulation starts when they are'
        elif self._paused:
            message = 'paused'
        else:
            behind = self._behind_schedule(missed, now - window_start)
            if behind:
                level = DiagnosticStatus.WARN
                message = f'falling behind: {behind}'
                if substep_cap_reached(dict(values), MAX_SUBSTEPS):
                    message += f' (error control at its cap of {MAX_SUBSTEPS} substeps a tick)'
        self._report_falling_behind(message.startswith('falling behind'), message)
        if compiling and level == DiagnosticStatus.OK:
            # Not what was asked for: the integrator set runs interpreted, or another one
            # runs in its place, until its kernels are compiled.
            level = DiagnosticStatus.WARN
        if compiling and self._timer is not None:
            running = self._simulator.integrator
            if self._compilation.name != running:
                message += f'; the switch to {self._compilation.name} is pending'
            message += f'; {compiling}, {running} ' + (
                'interpreted until then' if self._simulator.interpreted else 'until then')
        elif self._simulator.interpreted:
            message += '; interpreted: the kernels are not compiled'
        if self._clock_guard is not None:
            problems, clock_values = self._clock_guard.status()
            values = list(values) + clock_values
            # What the stamps mean matters only where they come from /clock.
            problems = [(text, kind) for text, kind in problems
                        if kind == 'peer' or not self._publish_clock]
            if problems:
                if level == DiagnosticStatus.OK:
                    level = DiagnosticStatus.WARN
                message += '; ROS clock (use_sim_time): ' + '; '.join(
                    text for text, _ in problems)
        level, message = self._amend_status(level, message)
        stamp = self._simulated_nanoseconds() if self._publish_clock \
            else self.get_clock().now().nanoseconds
        self._diagnostics_publisher.publish(diagnostic_array(
            status_name(self.get_name()), self.get_fully_qualified_name(), level, message,
            values, stamp))

    def _status_values(self, figures):
        """Return the status's (key, value) pairs for a report's window (TickFigures)."""
        return status_values(
            self._scene, self._simulator, self._rate, self._real_time_factor, figures,
            clock_seconds=(1e-9 * self._simulated_nanoseconds() if self._publish_clock
                           else None),
            paused=self._paused,
            wrench_active=any(held is not None for held in self._inputs.values()),
            reference_energy=self._reference_energy,
            reference_momentum=self._reference_momentum, rejected=self._rejected,
            limited=self._limited)

    def _amend_status(self, level, message):
        """Return the status's (level, message) as a report publishes them (here unchanged)."""
        return level, message

    def _behind_schedule(self, missed, window):
        """
        Return what says the ticks fall behind their schedule ('' if they keep it).

        Only ticks actually missed count: dropped in the report's window of `window` s
        (`missed`), and once falling behind, ticks still owed (the schedule's lag) until it
        has caught up.  The achieved rate does not: its window spans a change of
        real_time_factor (ticks at the old pace, then at the new) and the start-up before the
        first tick, and such a window's average is below the new rate with nothing missed.
        """
        lag = max(0.0, time.monotonic() - self._next_due)  # s the next tick is overdue
        if missed > 0:
            return f'{missed} ticks missed in the last {window:.1f} s'
        if self._falling_behind and lag > max(_CAUGHT_UP_LAG, 2.0 * self._wall_period):
            return f'the ticks run {lag:.2f} s behind their schedule'
        return ''

    def _report_falling_behind(self, behind, message):
        # One log line when the node starts falling behind, one when it keeps up again.
        if behind and not self._falling_behind:
            self.get_logger().warning(
                f'{message}: each tick takes longer than its period '
                f'({1e3 * self._wall_period:.3g} ms); lower the rate, the real_time_factor, '
                'the substeps or raise the tolerance')
        elif self._falling_behind and not behind:
            self.get_logger().info('keeping up again')
        self._falling_behind = behind

    def statistics(self):
        """Return a one-line summary: ticks, missed ticks, tick duration percentiles."""
        if self._ticks == 0:
            return 'no ticks'
        tick = self._recent(self._tick_durations, self._ticks)
        return (f'{self._ticks} ticks, {self._missed_ticks} missed; tick duration over the '
                f'last {tick.size}: p50 {_milliseconds(tick, 50)} ms, p99 '
                f'{_milliseconds(tick, 99)} ms, max {_milliseconds(tick, 100)} ms')


def _milliseconds(durations, percentile):
    return f'{1e3 * float(np.percentile(durations, percentile)):.4f}'

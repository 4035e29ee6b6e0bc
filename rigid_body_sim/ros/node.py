"""
The rigid_body_sim ROS 2 node: a timer-driven simulation of one rigid body in a scene.

The parameter ``scene`` (:mod:`rigid_body_sim.scenes`) gives the body, its initial state,
the effects on it (gravity, a pivot, drag, ...), how to draw it, and the default integrator
and rate; the body and initial-state parameters that are set override it (see
:mod:`rigid_body_sim.ros.parameters`).

Each tick applies the queued inputs, service requests and parameter changes in the order
they came, expires inputs older than ``input_timeout``, advances the simulation by the
nominal period 1/rate in ``substeps`` equal steps, or with a ``tolerance`` in as many as
error control chooses (simulated time follows the nominal period, not wall-clock jitter),
then publishes the state.  Ticks come every
(1/rate)/real_time_factor s of wall-clock time.  Stamps: the node's clock, or with
``publish_clock`` the simulated time, which is then also published on ``/clock``.

The timer is a thread of its own on the steady clock, not an rclpy timer: rclpy's executor
costs ~0.4 ms of CPU per timer callback on the reference machine, which alone would take 40%
of a core at 1 kHz; and a timer on the node's clock would never fire under
``use_sim_time:=true`` until a /clock arrived, which with ``publish_clock`` only its own
ticks would publish.  The executor thread only runs the service and parameter callbacks,
and they only queue work, so the simulation is touched by the tick thread alone.

The torque and wrench subscriptions are not run by the executor either: each tick takes
the messages waiting in them itself, right before it steps.  An input then acts at the
first tick after it arrives (at most one period later) instead of waiting for the
executor's turn (~0.4 ms of CPU per callback, plus a thread switch) and then for the
next tick, and ticks without input cost two empty takes.

Topics (relative names, so ``--ros-args -r __ns:=/sat1`` namespaces them):

- published: ``pose``, ``twist``, ``angular_momentum``, ``odom``, ``marker`` (see
  :func:`rigid_body_sim.ros.conversions.state_messages`; the marker is the scene's
  drawing), ``/diagnostics`` at 1 Hz, and with ``publish_clock`` ``/clock`` at every tick;
- subscribed, only if the scene has the effect ``external_wrench``: ``torque``
  (Vector3Stamped) and ``wrench`` (WrenchStamped).  The header's frame_id chooses
  world-fixed (``world_frame`` or empty) or body-fixed (``body_frame``).  Each topic holds
  its latest input until replaced or timed out; the two topics' inputs add up.

Services: ``reset`` (std_srvs/Trigger) and ``pause`` (std_srvs/SetBool).  The model is the
scene's :class:`rigid_body_sim.physics.Simulator`; this module only converts between it and
ROS.
"""

import collections
import heapq
import math
import struct
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from diagnostic_msgs.msg import KeyValue
from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import Vector3Stamped
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.callback_groups import CallbackGroup
from rclpy.clock import ClockType
from rclpy.exceptions import NotInitializedException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu as ImuMessage
from std_srvs.srv import SetBool
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker

from .conversions import fill_imu_message
from .conversions import imu_message
from .conversions import marker_geometry_from_drawing
from .conversions import RejectedInput
from .conversions import STATE_TOPICS
from .conversions import StateSerializer
from .conversions import wrench_input_from_message
from .conversions import WrenchInput
from .parameter_services import ParameterServices
from .parameters import check_integrator
from .parameters import declare_parameters
from .parameters import declare_scene_parameter
from .parameters import imu_model_from_parameters
from .parameters import PARAMETERS
from .parameters import scene_from_parameters
from .parameters import show_effective_values
from .qos import CLOCK_QOS
from .qos import DIAGNOSTICS_QOS
from .qos import INPUT_QOS
from .qos import STATE_QOS
from .start_up import only_note_signals
from .start_up import signalled
from .start_up import signals_deferred
from .start_up import start_up_phase
from .text import shortened
from ..physics import unresolved_rotation
from ..scenes import load_scene

__all__ = ['RigidBodyNode', 'ConfigurationError', 'main', 'NODE_NAME', 'substep_diagnostics']

NODE_NAME = 'rigid_body_sim'
"""Default node name."""

_MESSAGE_TYPES = {'pose': PoseStamped, 'twist': Twist, 'angular_momentum': Vector3Stamped,
                  'odom': Odometry, 'marker': Marker}
_INPUT_TOPICS = {'torque': Vector3Stamped, 'wrench': WrenchStamped}
_NO_VECTOR = np.zeros(3)
_NO_VECTOR.flags.writeable = False
_CLOCK_TOPIC = '/clock'
_DIAGNOSTICS_PERIOD = 1.0  # s
_WARNING_PERIOD = 1.0  # s between two warnings of the same kind
# Ring of the latest tick durations: 65536 ticks is over a minute at 1 kHz, enough for the
# percentiles in the shutdown summary, and bounded memory for a node that runs for days.
_HISTORY = 1 << 16
# Below this fraction of the requested rate the diagnostics report a warning.
_RATE_WARNING_FRACTION = 0.9
# Ticks held up by longer than this (s) are dropped rather than caught up with.
_MAX_LAG = 0.5
# How often (s) the tick looks for the topics that have subscribers.
_SUBSCRIBER_CHECK_PERIOD = 0.1
# Longest sleep (s) of the tick thread between looks at its stop flag.
_STOP_LATENCY = 0.1


class ConfigurationError(ValueError):
    """The node's configuration describes no valid simulation (already logged)."""


class _TakenByTheTick(CallbackGroup):
    """
    A callback group no executor runs: the tick thread takes its messages itself.

    An executor waits only on the entities whose group can execute them, so these
    subscriptions never wake it.
    """

    def can_execute(self, entity):
        return False

    def beginning_execution(self, entity):
        return False

    def ending_execution(self, entity):
        pass


class RigidBodyNode(Node):
    """
    Simulate one rigid body and publish its state; see the module docstring.

    The tick thread starts with :meth:`start` and ends with :meth:`stop`; :func:`main` does
    both around spinning the node.

    Raises
    ------
    ConfigurationError
        If the parameters are invalid: one clear error is logged first, and the node is
        destroyed.

    """

    def __init__(self, node_name=NODE_NAME, **kwargs):
        # rclpy's parameter services let a malformed request stop the node: ours answer it.
        super().__init__(node_name, start_parameter_services=False, **kwargs)
        ParameterServices(self)
        self._ticker = None
        self._ticks = 0
        try:
            self._configure()
        except ValueError as error:
            self.get_logger().error(f'invalid configuration: {error}')
            self.destroy_node()
            raise ConfigurationError(str(error)) from None

    # -- set-up

    def _configure(self):
        # The scene first: its integrator and rate are the defaults of those parameters.
        scene = load_scene(declare_scene_parameter(self))
        values = declare_parameters(self, scene)
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
        # One throwaway step loads the integrator's compiled kernels (~0.5 s) now rather
        # than in the first tick.
        _load_kernels(scene, scene.integrator, self._period)
        self._substeps = values['substeps']
        self._input_timeout_ns = int(values['input_timeout'] * 1e9)
        self._max_wrench = values['max_wrench']
        self._world_frame = values['world_frame']
        self._body_frame = values['body_frame']
        if self._world_frame == self._body_frame:
            raise ValueError(f'world_frame and body_frame must differ; both are '
                             f'{self._world_frame!r}')

        self._serializer = StateSerializer(
            body, self._world_frame, self._body_frame,
            geometry=marker_geometry_from_drawing(scene.drawing))
        self._state_publishers = [
            (topic, self.create_publisher(_MESSAGE_TYPES[topic], topic, STATE_QOS))
            for topic in STATE_TOPICS]
        # The simulated IMU: computed only while someone listens; its noise (if any) drawn
        # every tick, so a seed gives the same sequence whenever a subscriber comes.
        self._imu = scene.imu_sensor(imu_model_from_parameters(values))
        self._imu_publisher = self.create_publisher(ImuMessage, 'imu', STATE_QOS)
        self._imu_message = imu_message(values['imu_frame'], self._imu, self._period)
        self._imu_subscribed = False
        self._imu_noisy = self._imu.model.noisy
        self._wrench = self._simulator.wrench_function()
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
        # Simulated time: _clock_ticks whole periods since start-up, counted on through
        # resets and not while paused, so /clock never goes back.
        self._publish_clock = values['publish_clock']
        self._clock_ticks = 0
        self._clock_subscribed = False
        self._clock_publisher = None
        if self._publish_clock:
            self._clock_publisher = self.create_publisher(Clock, _CLOCK_TOPIC, CLOCK_QOS)
            # Clock is a lone Time: its CDR bytes are a 4-byte header, then sec and nanosec.
            self._clock_message = bytearray(serialize_message(Clock()))
            self._clock_packer = struct.Struct(('<' if self._clock_message[1] == 1 else '>')
                                               + 'iI')

        # Work queued by the callbacks (executor thread), done in order by the tick thread;
        # deque.append and popleft are atomic, so no lock is needed.
        self._queue = collections.deque()
        self._inputs = dict.fromkeys(_INPUT_TOPICS)  # topic -> (WrenchInput, received ns)
        self._paused = False
        self._last_warning = {}
        self._rejected = 0
        self._limited = 0
        external_wrench = scene.external_wrench
        self._limit = None if external_wrench is None or (
            external_wrench.max_force is None and external_wrench.max_torque is None) \
            else external_wrench.limit
        # Only a scene that takes outside input listens for it; the tick takes the
        # messages (see the module docstring), so the callback is never called.
        self._input_subscriptions = []
        if scene.accepts_external_wrench:
            taken_by_the_tick = _TakenByTheTick()
            for topic, message_type in _INPUT_TOPICS.items():
                subscription = self.create_subscription(
                    message_type, topic, _never_called, INPUT_QOS,
                    callback_group=taken_by_the_tick)
                self._input_subscriptions.append((topic, subscription.handle, message_type))
        self.create_service(Trigger, 'reset', self._reset_callback)
        self.create_service(SetBool, 'pause', self._pause_callback)
        self.add_on_set_parameters_callback(self._validate_parameters_callback)
        self.add_post_set_parameters_callback(self._parameters_set_callback)

        self._missed_ticks = 0
        self._subscribed = {}
        self._next_subscriber_check = 0
        self._system_time = False
        self._tick_durations = np.zeros(_HISTORY)
        self._step_durations = np.zeros(_HISTORY)
        # Start, ticks, missed ticks and simulated time then.
        self._window = (time.monotonic(), 0, 0, 0.0)
        self._next_diagnostics = time.monotonic() + _DIAGNOSTICS_PERIOD
        self._set_drift_reference()
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
            f'frame {values["imu_frame"]!r} ({imu_noise}); subscribed to {inputs}')
        self.get_logger().info(parameter_sources)
        warning = unresolved_rotation(body, self._simulator.state, self._period,
                                      self._substeps, tolerance)
        if warning is not None:
            self.get_logger().warning(warning)

    def _warn_unknown_overrides(self):
        # rclpy ignores overrides of undeclared parameters: a typo in a params file would
        # silently leave the default in place.  (No public accessor exists in Jazzy.)
        overrides = getattr(self, '_parameter_overrides', {})
        # rclpy's own parameters, which a dumped parameter file holds too.
        known = {spec.name for spec in PARAMETERS} | {'use_sim_time',
                                                      'start_type_description_service'}
        unknown = sorted(set(overrides) - known)
        if unknown:
            self.get_logger().warning(
                f'ignoring unknown parameter(s): {", ".join(unknown)}; known parameters: '
                f'{", ".join(spec.name for spec in PARAMETERS)}')

    # -- the tick thread

    def start(self):
        """Start ticking at `rate` Hz in a thread of its own."""
        if self._ticker is None:
            self._stop = threading.Event()
            self._wake = threading.Event()
            self._ticker = threading.Thread(target=self._tick_loop, name='tick', daemon=True)
            self._ticker.start()

    def stop(self):
        """Stop ticking; return after the tick in progress, if any, has finished."""
        if self._ticker is not None:
            self._stop.set()
            self._wake.set()
            self._ticker.join()
            self._ticker = None

    def _tick_loop(self):
        # Deadlines on the steady clock at whole multiples of the period: the rate is exact
        # on average whatever each tick's jitter.  A tick that comes late (the process was
        # not scheduled) is followed at once by the ticks it held up, so simulated time keeps
        # pace with the clock; beyond _MAX_LAG the missed ticks are dropped instead.  Work
        # queued between ticks (services, parameters) wakes the loop and is applied at once;
        # a new pace (real_time_factor) counts from the last tick, never from the deadline
        # of the old one.
        period = self._wall_period
        last_deadline = time.monotonic()
        deadline = last_deadline + period
        stop = self._stop
        wake = self._wake
        while not stop.is_set():
            delay = deadline - time.monotonic()
            if delay > 0.0:
                # stop() is seen within _STOP_LATENCY even at slow rates.
                if wake.wait(min(delay, _STOP_LATENCY)):
                    wake.clear()
                    if self._queue and self._apply_queue():
                        self._hold_inputs()
                    if self._wall_period != period:
                        period = self._wall_period
                        deadline = last_deadline + period
                continue
            max_lag = max(_MAX_LAG, 2.0 * period)
            if delay < -max_lag:
                missed = int(-delay / period)
                self._missed_ticks += missed
                deadline += missed * period
            try:
                self._tick()
            except Exception as error:  # noqa: B902 (a dying tick thread must not be silent)
                if not self.context.ok():
                    return  # shut down (SIGTERM) while publishing: nothing to report
                self.get_logger().fatal(f'the simulation tick failed: {error!r}')
                self.tick_error = error
                self.context.try_shutdown()
                return
            last_deadline = deadline
            deadline += period

    def _tick(self):
        started = time.perf_counter()
        # The node's clock; while it runs on system time (no /clock), time.time_ns() reads
        # the same clock for a tenth of the cost of Clock.now().
        now = time.time_ns() if self._system_time else self.get_clock().now().nanoseconds
        inputs = self._take_inputs(now) if self._input_subscriptions else None
        inputs_changed = self._apply_queue(inputs) if self._queue or inputs else False
        if self._input_timeout_ns > 0 and self._expire_inputs(now):
            inputs_changed = True
        if inputs_changed:
            self._hold_inputs()
        simulator = self._simulator
        stepped = time.perf_counter()
        if not self._paused:
            # substeps steps, or under error control as many as it chooses.
            simulator.step(self._period)
            self._clock_ticks += 1
            if self._imu_noisy:
                self._imu.advance(self._period)
        step_duration = time.perf_counter() - stepped
        if self._ticks >= self._next_subscriber_check:
            self._check_subscribers()
        stamp = now
        if self._publish_clock:
            # /clock first: a sim-time consumer's clock reaches a stamp before the message.
            stamp = self._simulated_nanoseconds()
            if self._clock_subscribed:
                self._clock_packer.pack_into(self._clock_message, 4,
                                             *divmod(stamp, 1_000_000_000))
                self._clock_publisher.publish(bytes(self._clock_message))
        if self._subscribed:
            serialized = self._serializer.serialize(simulator.state, stamp, self._subscribed)
            for topic, publisher in self._subscribed.items():
                publisher.publish(serialized[topic])
        if self._imu_subscribed:
            self._publish_imu(stamp)
        index = self._ticks % _HISTORY
        self._step_durations[index] = step_duration
        self._tick_durations[index] = time.perf_counter() - started
        self._ticks += 1
        steady = time.monotonic()
        if steady >= self._next_diagnostics:
            # At 1 Hz on average; a late one does not make the next one early.
            self._next_diagnostics = max(self._next_diagnostics + _DIAGNOSTICS_PERIOD,
                                         steady + 0.5 * _DIAGNOSTICS_PERIOD)
            self._publish_diagnostics()

    tick_error = None
    """The exception that stopped the tick thread, if one did."""

    def _publish_imu(self, stamp):
        # The accelerations at the published state, from the wrench acting on it now.
        simulator = self._simulator
        state = simulator.state
        if self._wrench is None:
            force = torque = _NO_VECTOR
        else:
            force, torque = self._wrench(state, simulator.time)
        reading = self._imu.reading(state, force, torque)
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
        # costs what the listeners need.  Checked every _SUBSCRIBER_CHECK_PERIOD s, so a
        # new subscriber waits at most that long (discovery takes longer anyway); so is
        # whether the node's clock follows /clock (use_sim_time) or the system clock.
        self._subscribed = {topic: publisher for topic, publisher in self._state_publishers
                            if publisher.get_subscription_count() > 0}
        self._imu_subscribed = self._imu_publisher.get_subscription_count() > 0
        self._clock_subscribed = self._publish_clock and \
            self._clock_publisher.get_subscription_count() > 0
        clock = self.get_clock()
        self._system_time = clock.clock_type == ClockType.SYSTEM_TIME or (
            clock.clock_type == ClockType.ROS_TIME and not clock.ros_time_is_active)
        self._next_subscriber_check = self._ticks + max(
            1, int(_SUBSCRIBER_CHECK_PERIOD * self._rate))

    def _take_inputs(self, now):
        """
        Take every torque and wrench message waiting; return [(received ns, item)].

        `received` is the DDS reception time (system clock), which orders the inputs
        among the service requests queued meanwhile; the input itself holds from `now`
        (the node's clock), so input_timeout counts from the tick that applies it.
        """
        taken = []
        # The handles are used without their `with` guard (which halves the cost of an
        # empty take): the tick thread is stopped before the node is destroyed.
        for topic, handle, message_type in self._input_subscriptions:
            while True:
                message_and_info = handle.take_message(message_type, False)
                if message_and_info is None:
                    break
                message, info = message_and_info
                wrench = self._accepted_input(topic, message)
                if wrench is not None:
                    received = info.get('received_timestamp') or time.time_ns()
                    taken.append((received, ('input', topic, wrench, now)))
        taken.sort(key=lambda timed: timed[0])
        return taken

    def _apply_queue(self, inputs=None):
        # Service requests and parameter changes (queued by the executor thread) and the
        # inputs just taken, in the order they came.
        items = (item for _, item in heapq.merge(self._drain_queue(), inputs or (),
                                                 key=lambda timed: timed[0]))
        inputs_changed = False
        for item in items:
            kind = item[0]
            if kind == 'input':
                _, topic, wrench, held_from = item
                self._inputs[topic] = (wrench, held_from)
                inputs_changed = True
            elif kind == 'reset':
                self._simulator.reset(self._initial_state, time=0.0)
                self._inputs = dict.fromkeys(_INPUT_TOPICS)
                inputs_changed = True
            elif kind == 'pause':
                self._paused = item[1]
            elif kind == 'parameter':
                self._apply_parameter(item[1], item[2])
        return inputs_changed

    def _drain_queue(self):
        queue = self._queue
        while queue:
            yield queue.popleft()

    def _apply_parameter(self, name, value):
        if name == 'integrator':
            # The simulator keeps its state: the switch is continuous.
            self._simulator.integrator = value
            self.get_logger().info(f'integrator is now {value}')
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
        elif name == 'real_time_factor':
            self._real_time_factor = value
            self._wall_period = self._period / value
            self.get_logger().info(f'real_time_factor is now {value:g}')

    def _expire_inputs(self, now):
        expired = False
        for topic, held in self._inputs.items():
            if held is not None and now - held[1] > self._input_timeout_ns:
                self._inputs[topic] = None
                expired = True
        return expired

    def _hold_inputs(self):
        # Inputs from both topics add up; body-fixed parts are held as such so that they
        # turn with the body during the substeps.
        parts = {'world': [np.zeros(3), np.zeros(3)], 'body': [np.zeros(3), np.zeros(3)]}
        for held in self._inputs.values():
            if held is not None:
                wrench = held[0]
                part = parts[wrench.frame]
                part[0] = part[0] + wrench.force
                part[1] = part[1] + wrench.torque
        self._simulator.hold_wrench(force_world=parts['world'][0],
                                    torque_world=parts['world'][1],
                                    force_body=parts['body'][0],
                                    torque_body=parts['body'][1])
        self._wrench = self._simulator.wrench_function()
        self._set_drift_reference()

    def _set_drift_reference(self):
        self._reference_energy = self._simulator.energy()
        self._reference_momentum = float(np.linalg.norm(
            self._simulator.state.angular_momentum))

    def _accepted_input(self, topic, message):
        """Return the WrenchInput of a torque or wrench message, or None if rejected."""
        try:
            wrench = wrench_input_from_message(message, self._world_frame, self._body_frame,
                                               self._max_wrench)
        except RejectedInput as error:
            self._rejected += 1
            self._warn_throttled((topic, error.kind),
                                 f'rejected a {topic} input, state unchanged: {error}')
            return None
        if self._limit is not None:
            force, torque = self._limit(wrench.force, wrench.torque)
            if np.any(force != wrench.force) or np.any(torque != wrench.torque):
                self._limited += 1
                limits = self._scene.external_wrench
                self._warn_throttled((topic, 'limit'), (
                    f"scaled a {topic} input down to the scene's limits (max_force "
                    f'{limits.max_force} N, max_torque {limits.max_torque} N m)'))
                wrench = WrenchInput(force, torque, wrench.frame)
        return wrench

    # -- callbacks (executor thread): they only queue work for the tick, stamped with the
    # system time (the clock of the inputs' DDS reception stamps) to keep them in order.

    def _queue_work(self, item):
        self._queue.append((time.time_ns(), item))
        if self._ticker is not None:
            self._wake.set()  # applied now, not at the next tick

    def _reset_callback(self, request, response):
        self._queue_work(('reset',))
        response.success = True
        response.message = 'reset to the initial state and time 0 at the next tick' + (
            ' (/clock counts on)' if self._publish_clock else '')
        return response

    def _pause_callback(self, request, response):
        self._queue_work(('pause', bool(request.data)))
        response.success = True
        response.message = 'paused' if request.data else 'running'
        return response

    def _validate_parameters_callback(self, parameters):
        # Types, ranges and read-only flags are checked by rclpy from the descriptors.
        for parameter in parameters:
            if parameter.name == 'integrator':
                reason = check_integrator(shortened(parameter.value))
                if reason is not None:
                    return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _parameters_set_callback(self, parameters):
        for parameter in parameters:
            if parameter.name == 'max_wrench':
                self._max_wrench = parameter.value  # read by the input callbacks
            else:
                if parameter.name == 'integrator':
                    # Load the integrator's compiled kernels here (~0.1 s the first time),
                    # not in the tick thread, which would miss ticks meanwhile.
                    _load_kernels(self._scene, parameter.value, self._period)
                self._queue_work(('parameter', parameter.name, parameter.value))

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
        requested = self._rate * self._real_time_factor  # ticks per wall-clock second
        tick = self._recent(self._tick_durations, ticks)
        step = self._recent(self._step_durations, ticks)
        simulator = self._simulator
        energy = simulator.energy()
        momentum = float(np.linalg.norm(simulator.state.angular_momentum))
        wrench_active = any(held is not None for held in self._inputs.values())
        # The steps of the window over the simulated time they advanced (a reset restarts
        # the clock: then over the window's ticks).
        simulated = simulator.time - window_simulated
        if simulated <= 0.0:
            simulated = ticks * self._period

        status = DiagnosticStatus()
        status.name = f'{self.get_name()}: simulation'
        status.hardware_id = self.get_fully_qualified_name()
        if self._paused:
            status.level, status.message = DiagnosticStatus.OK, 'paused'
        elif achieved < _RATE_WARNING_FRACTION * requested:
            status.level = DiagnosticStatus.WARN
            status.message = f'falling behind: {achieved:.1f} of {requested:g} ticks/s'
        else:
            status.level, status.message = DiagnosticStatus.OK, 'running'
        values = [
            ('scene', self._scene.name),
            ('effects', ', '.join(self._scene.effect_names()) or 'none'),
            ('integrator', simulator.integrator),
            ('requested rate [Hz]', f'{self._rate:g}'),
            ('real-time factor', f'{self._real_time_factor:g}'),
            # Ticks per wall-clock second: rate x real-time factor when the node keeps up.
            ('achieved rate [Hz]', f'{achieved:.2f}'),
            ('achieved real-time factor', f'{achieved / self._rate:.3f}'),
            ('missed ticks', str(self._missed_ticks - window_missed)),
            *substep_diagnostics(simulator, self._period, float(step.sum()), simulated),
            ('step time p50 [ms]', _milliseconds(step, 50)),
            ('step time max [ms]', _milliseconds(step, 100)),
            ('tick duration p50 [ms]', _milliseconds(tick, 50)),
            ('tick duration p99 [ms]', _milliseconds(tick, 99)),
            ('simulated time [s]', f'{simulator.time:.6f}'),
            ('clock [s]', f'{1e-9 * self._simulated_nanoseconds():.6f}'
             if self._publish_clock else 'not published'),
            ('paused', str(self._paused)),
            ('external wrench active', str(wrench_active)),
            # Kinetic plus the effects' potential energy (gravity): what is conserved.
            ('energy [J]', f'{energy:.12g}'),
            ('energy drift since last input', _relative(energy, self._reference_energy)),
            ('|L| [kg m^2/s]', f'{momentum:.12g}'),
            ('|L| drift since last input', _relative(momentum, self._reference_momentum)),
            ('inputs rejected', str(self._rejected)),
            ('inputs scaled down to the scene limits', str(self._limited)),
        ]
        status.values = [KeyValue(key=key, value=value) for key, value in values]
        array = DiagnosticArray()
        if self._publish_clock:
            array.header.stamp.sec, array.header.stamp.nanosec = divmod(
                self._simulated_nanoseconds(), 1_000_000_000)
        else:
            array.header.stamp = self.get_clock().now().to_msg()
        array.status = [status]
        self._diagnostics_publisher.publish(array)

    def statistics(self):
        """Return a one-line summary: ticks, missed ticks, tick duration percentiles."""
        if self._ticks == 0:
            return 'no ticks'
        tick = self._recent(self._tick_durations, self._ticks)
        return (f'{self._ticks} ticks, {self._missed_ticks} missed; tick duration over the '
                f'last {tick.size}: p50 {_milliseconds(tick, 50)} ms, p99 '
                f'{_milliseconds(tick, 99)} ms, max {_milliseconds(tick, 100)} ms')


def substep_diagnostics(simulator, period, step_seconds, simulated_seconds):
    """
    Return the diagnostics (key, value) pairs of the substeps and error control.

    The simulator's figures since the last call (it starts a new period): tolerance (or
    'off'), substeps in use (the last tick's, and the least and most of the period), the
    step, the error rate estimated last and the largest of the period (rad/s, 'n/a' off),
    and the integration's CPU per simulated second: `step_seconds` (the wall time of the
    steps, pure computation in one thread: their CPU time unless it was preempted) over
    `simulated_seconds`.  The node and ``rigid-body-sim simulate`` report the same keys.
    """
    figures = simulator.substep_statistics(reset=True)
    controlled = figures['tolerance'] is not None

    def rate(value):
        return f'{value:.3e}' if controlled and math.isfinite(value) else 'n/a'
    return [
        ('tolerance [rad/s]', f'{figures["tolerance"]:g}' if controlled else 'off'),
        ('substeps', str(figures['substeps'])),
        ('substeps min', str(figures['substeps_min'])),
        ('substeps max', str(figures['substeps_max'])),
        ('step [s]', f'{period / figures["substeps"]:.6g}'),
        ('estimated error rate [rad/s]', rate(figures['error_rate'])),
        ('estimated error rate max [rad/s]', rate(figures['error_rate_max'])),
        ('integration CPU per simulated s [s]',
         f'{step_seconds / simulated_seconds:.3e}' if simulated_seconds > 0.0 else 'n/a'),
    ]


def _load_kernels(scene, integrator, period):
    """Load (from numba's cache, or compile) the kernels an integrator runs with, both ways."""
    simulator = scene.simulator(integrator=integrator)
    simulator.step(period)
    simulator.tolerance = 0.0 if simulator.tolerance is not None else 1e-6
    simulator.step(period)


def _never_called(message):
    raise AssertionError('the tick takes the input messages; no executor runs this')


def _milliseconds(durations, percentile):
    if durations.size == 0:
        return 'n/a'
    return f'{1e3 * float(np.percentile(durations, percentile)):.4f}'


def _relative(value, reference):
    if reference == 0.0:
        return f'{value - reference:+.3e} (absolute)'
    return f'{(value - reference) / abs(reference):+.3e}'


# Attributes that rclpy's constructors set only once the context proved valid, and whose
# __del__ reads them: Executor._sigint_gc, and GuardCondition's handle (the executor's
# SignalHandlerGuardCondition).
_SET_ONCE_BUILT = ('_sigint_gc', '_GuardCondition__gc')


def _quiet_half_built_executor(unraisable):
    # An executor whose construction met a context that a signal had just shut down (the
    # signal during the executor's set-up, between its guard conditions) prints "Exception
    # ignored ... AttributeError" from a half-built object's __del__ when it is collected.
    # Those messages, and no other, are dropped.
    error = unraisable.exc_value
    if isinstance(error, AttributeError) and any(name in str(error) for name in _SET_ONCE_BUILT):
        return
    _PREVIOUS_UNRAISABLE_HOOK(unraisable)


_PREVIOUS_UNRAISABLE_HOOK = sys.unraisablehook


def _spin_until_signalled(node):
    """
    Serve the node's services and inputs until the context shuts down or a signal comes.

    rclpy.spin would wait without a timeout (the ticks run in a thread of their own, so the
    wait set has no timer): a SIGINT then relies on rclpy's guard condition alone to wake
    the wait, and once in a few hundred stops (a benchmark saw it) the node stayed blocked
    in rcl_wait with the signal noted but never acted on.  Waiting at most _STOP_LATENCY
    lets Python run its signal handler within that time in every case.
    """
    # As rclpy.spin does it, with a timeout.
    try:
        with signals_deferred():
            executor = rclpy.get_global_executor()
            executor.add_node(node)
    except RuntimeError:
        # rclpy's own handler shut the context down (a signal just now): the executor
        # could not be built on it; a clean stop.
        if node.context.ok():
            raise
        return
    try:
        # signalled() too: a signal's KeyboardInterrupt can be raised where rclpy or a
        # finaliser swallows it, and the loop would then spin on (a node stayed up 60 s
        # after SIGINT, once in ~20 stops of benchmarks/node_tolerance_cost.py).
        while executor.context.ok() and not signalled():
            executor.spin_once(timeout_sec=_STOP_LATENCY)
    finally:
        executor.remove_node(node)


def _only_note_signals():
    # From here a signal is only noted: rclpy acts on one in its own thread (the spin loop
    # ends), and Python may run our handler later, inside the shutdown below, where its
    # KeyboardInterrupt would cut the stop, the summary and rclpy's shutdown short.  The
    # handler can still run as this call begins: then it is caught, and the call repeated.
    while True:
        try:
            only_note_signals()
            return
        except KeyboardInterrupt:
            continue


def main(args=None):
    """
    Run the node until SIGINT or SIGTERM; return the exit code.

    0 after a clean shutdown; 1 if the configuration is invalid (one error is logged) or the
    simulation failed; 2 if the ROS arguments cannot be parsed.
    """
    start_up_phase('rclpy.init')
    sys.unraisablehook = _quiet_half_built_executor
    try:
        rclpy.init(args=args)
    except KeyboardInterrupt:
        return 0
    except (RuntimeError, ValueError) as error:
        print(f'rigid_body_node: error: {error}'.replace('\n', ' '), file=sys.stderr)
        return 2
    node = None
    code = 0
    try:
        start_up_phase('node')
        node = RigidBodyNode()
        node.start()
        start_up_phase('spin')
        _spin_until_signalled(node)
    except ConfigurationError:
        # One that the context's shutdown under a half-built node caused is a stop.
        code = 1 if rclpy.ok() else 0
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (RuntimeError, NotInitializedException):
        # A signal during start-up shuts the context down under the node being built
        # (rclpy's RCLError "context is invalid", or NotInitializedException "cannot create
        # node" from Node.__init__): a clean stop, not a failure.  rclpy shuts the context
        # down from its own signal thread, which can come before Python runs our handler,
        # so the context says it, not signalled() (1 fresh-clone run in 8 saw that).
        if rclpy.ok():
            raise
    finally:
        _only_note_signals()
        if node is not None:
            node.stop()
            if node.tick_error is not None:
                code = 1
            summary = node.statistics()
            logger = node.get_logger()
            # Destroyed first: after a SIGTERM the context is gone and logging through the
            # node would also try its /rosout publisher and fail.
            node.destroy_node()
            logger.info(summary)
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())

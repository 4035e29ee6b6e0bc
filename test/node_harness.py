"""
Run the rigid_body_sim node as a subprocess and talk to it over real DDS.

Each test process gets a ROS domain of its own (:func:`isolate_ros_environment`) and every
node a namespace of its own, so concurrent test runs on one machine never hear each other.
:class:`NodeProcess` starts and stops the node; :class:`Client` is an rclpy node in the test
process that records what the node publishes and calls its services.
"""

import itertools
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import Vector3Stamped
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import SetParameters
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rigid_body_sim.messages.frames import as_tf2_reads
from rigid_body_sim.messages.frames import default_frame_prefix
from rigid_body_sim.messages.qos import STATE_QOS
from std_srvs.srv import SetBool
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker
import yaml

PACKAGE_ROOT = Path(__file__).resolve().parent.parent
NODE_NAME = 'rigid_body_sim'
STATE_TYPES = {'pose': PoseStamped, 'twist': Twist, 'angular_momentum': Vector3Stamped,
               'odom': Odometry, 'marker': Marker}
# Discovery on the loopback takes well under a second; under load (6 on 2 cores, a fresh-clone
# run) more than 20 s. A failure detector, not a wait: nothing waits for it to pass.
DISCOVERY_TIMEOUT = 120.0
_namespaces = itertools.count()


def isolate_ros_environment():
    """
    Give this process a ROS domain of its own and keep discovery on the loopback.

    The domain id (1..100) is derived from the pytest-xdist worker and the process id, so
    the workers of one run differ; namespaces (:func:`unique_namespace`) keep even two runs
    that happen to share a domain apart.

    :returns: the domain id, also set in ``os.environ`` for this process and its children.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    index = int(''.join(c for c in worker if c.isdigit()) or 0)
    domain = 1 + (os.getpid() + 37 * index) % 100
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return domain


def unique_namespace():
    """Return a namespace no other node of this or another test process uses."""
    return f'/test_{os.getpid()}_{next(_namespaces)}'


def start_node_in_process(node_class, scene):
    """Return a node of `node_class` simulating `scene`, in a context of its own, not spun."""
    isolate_ros_environment()
    context = rclpy.Context()
    rclpy.init(context=context)
    return node_class(context=context, start_parameter_services=False,
                      parameter_overrides=[Parameter('scene', value=scene)])


def stop_node_in_process(node):
    """Destroy a node of :func:`start_node_in_process` and shut its context down."""
    context = node.context
    node.destroy_node()
    rclpy.try_shutdown(context=context)


class NodeProcess:
    """
    The node running as a subprocess, its output captured in a file.

    :param namespace: the node's namespace (``-r __ns:=``), or None for the root.
    :param parameters: ``{name: value}`` passed as ``-p name:=value`` (values as ROS
        writes them: ``'100.0'``, ``'[1.0, 2.0, 3.0]'``).
    :param extra_arguments: more ``--ros-args`` arguments (``--params-file``, ...).
    :param command: the command that starts the node, default
        ``python -m rigid_body_sim.node.entry_point`` (what ``rigid_body_node`` runs).
    :param log_path: the file for its stdout and stderr.
    :param cwd: its working directory (default: the package root).
    :param environment: variables to set in its environment, beside this process's.
    """

    def __init__(self, log_path, namespace=None, parameters=None, extra_arguments=(),
                 command=None, cwd=PACKAGE_ROOT, environment=None):
        arguments = ['--ros-args']
        if namespace is not None:
            arguments += ['-r', f'__ns:={namespace}']
        for name, value in (parameters or {}).items():
            arguments += ['-p', f'{name}:={value}']
        arguments += list(extra_arguments)
        command = command or [sys.executable, '-m', 'rigid_body_sim.node.entry_point']
        self.log_path = Path(log_path)
        self.namespace = namespace
        self._log = open(self.log_path, 'w')
        variables = dict(os.environ)
        variables['PYTHONUNBUFFERED'] = '1'
        variables['RCUTILS_LOGGING_BUFFERED_STREAM'] = '0'
        variables.update(environment or {})
        self.process = subprocess.Popen(
            list(command) + arguments, stdout=self._log, stderr=subprocess.STDOUT,
            cwd=cwd, env=variables)

    @property
    def pid(self):
        """Return the process id."""
        return self.process.pid

    def alive(self):
        """Return True while the process runs."""
        return self.process.poll() is None

    def output(self):
        """Return everything the node printed so far."""
        return self.log_path.read_text()

    def wait(self, timeout=20.0):
        """Wait for the process to exit and return its exit code (None on timeout)."""
        try:
            return self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return None

    def send_signal(self, signal_number):
        """Send a signal to the node."""
        self.process.send_signal(signal_number)

    def stop(self):
        """Stop the node (SIGINT, then SIGKILL if it hangs); return its exit code."""
        if self.alive():
            self.process.send_signal(signal.SIGINT)
            if self.wait(10.0) is None:
                self.process.kill()
                self.wait(10.0)
        self._log.close()
        return self.process.returncode


def nanoseconds(stamp):
    """Return a builtin_interfaces/Time in ns."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def applied_from(response):
    """
    Return the stamp (ns) after which a reset or pause reply's new state is published.

    The node replies once it has applied the request, with '... every message stamped after
    <s>.<ns> s shows it ...'.
    """
    match = re.search(r'stamped after (\d+)\.(\d{9}) s', response.message)
    assert match, response.message
    return int(match.group(1)) * 1_000_000_000 + int(match.group(2))


class SpunNode:
    """
    An rclpy node of a test, in a context of its own, spun in a background thread.

    A subclass makes its subscriptions and clients on :attr:`node`, then calls
    :meth:`start_spinning`; :meth:`close` stops the thread and releases the context.
    """

    def __init__(self, node_name, namespace):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(node_name, namespace=namespace, context=self.context)
        self._executor = None

    def start_spinning(self):
        """Spin the node in a background thread until :meth:`close`."""
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        # spin_once in a loop, not spin(): close() stops the loop and joins this thread
        # before anything is destroyed, so no wait set is ever built on a dead context.
        while not self._stopping.is_set():
            self._executor.spin_once(timeout_sec=0.05)

    def close(self):
        """Stop spinning and release the context."""
        if self._executor is not None:
            self._stopping.set()
            self._thread.join(5.0)
            self._executor.shutdown(timeout_sec=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


class Client(SpunNode):
    """
    An rclpy node in the test process that records the simulator node's topics.

    It uses a context of its own and spins in a background thread.  Received messages are
    kept per topic with their arrival time (``time.monotonic()``).

    :param namespace: the simulator node's namespace.
    :param extra_topics: more topics to record, ``{topic: (message type, QoS)}``.
    """

    def __init__(self, namespace, extra_topics=None):
        super().__init__('test_client', namespace)
        self.namespace = namespace
        self._lock = threading.Lock()
        extra_topics = dict(extra_topics or {})
        self._received = {topic: []
                          for topic in list(STATE_TYPES) + ['/diagnostics'] + list(extra_topics)}
        topics = {topic: (message_type, STATE_QOS) for topic, message_type in STATE_TYPES.items()}
        topics.update(extra_topics)
        for topic, (message_type, qos) in topics.items():
            self.node.create_subscription(
                message_type, topic,
                lambda message, topic=topic: self._record(topic, message), qos)
        self.node.create_subscription(
            DiagnosticArray, '/diagnostics', self._diagnostics_callback, STATE_QOS)
        self.torque_publisher = self.node.create_publisher(Vector3Stamped, 'torque', STATE_QOS)
        self.wrench_publisher = self.node.create_publisher(WrenchStamped, 'wrench', STATE_QOS)
        self.reset_client = self.node.create_client(Trigger, 'reset')
        self.pause_client = self.node.create_client(SetBool, 'pause')
        self.parameters_client = self.node.create_client(
            SetParameters, f'{NODE_NAME}/set_parameters')
        self.start_spinning()

    def _record(self, topic, message):
        with self._lock:
            self._received[topic].append((time.monotonic(), message))

    def _diagnostics_callback(self, message):
        # /diagnostics is shared by every node of the domain: keep only our node's status.
        if any(status.hardware_id == f'{self.namespace}/{NODE_NAME}'
               for status in message.status):
            self._record('/diagnostics', message)

    def frame(self, name):
        """
        Return the frame id the node publishes for frame `name` (``world``, ``body``, ``imu``).

        The node's default frame_prefix is its namespace: ``body`` of a node in ``/test_1_0``
        is ``test_1_0/body``.
        """
        return as_tf2_reads(default_frame_prefix(self.namespace or '/') + name)

    # -- received messages

    def received(self, topic):
        """Return a copy of [(arrival time, message)] received on `topic` so far."""
        with self._lock:
            return list(self._received[topic])

    def messages(self, topic, since=None):
        """Return the messages received on `topic`, those arrived after `since` if given."""
        return [message for arrived, message in self.received(topic)
                if since is None or arrived > since]

    def wait_for(self, condition, timeout, what):
        """Poll `condition()` until it is true; fail with `what` after `timeout` s."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f'timed out after {timeout:g} s waiting for {what}')
            time.sleep(0.01)  # waits-for: poll interval of wait_for(condition)

    def wait_for_messages(self, topic, count, since=None, timeout=DISCOVERY_TIMEOUT):
        """Wait until `count` messages arrived on `topic` (after `since`); return them."""
        self.wait_for(lambda: len(self.messages(topic, since)) >= count, timeout,
                      f'{count} messages on {topic}')
        return self.messages(topic, since)

    def diagnostics_values(self, message):
        """Return {key: value} of our node's status in a /diagnostics message."""
        status = next(s for s in message.status
                      if s.hardware_id == f'{self.namespace}/{NODE_NAME}')
        return {kv.key: kv.value for kv in status.values}

    def scheduled_rate(self, since, windows=6):
        """
        Return (ticks taken + ticks missed) per wall-clock second over `windows` reports.

        The node's tick keeps deadlines (a late tick caught up at once, one later than
        0.5 s dropped and counted as missed), so this is rate x real_time_factor however
        starved the machine is; how many ticks it manages to take is the machine's.  Each
        /diagnostics report covers the ~1 s since the one before: ticks = achieved rate x
        its window, the windows measured by the reports' arrivals here.  The first report
        after `since` is the window's start (its own window began before `since`).
        """
        self.wait_for_messages('/diagnostics', windows + 1, since=since)
        reports = [(arrival, message) for arrival, message in self.received('/diagnostics')
                   if arrival > since][:windows + 1]
        ticks = 0.0
        for (before, _), (after, message) in zip(reports, reports[1:]):
            values = self.diagnostics_values(message)
            ticks += float(values['achieved rate [Hz]']) * (after - before) + int(
                values['missed ticks'])
        return ticks / (reports[-1][0] - reports[0][0])

    def wait_until_connected(self, timeout=DISCOVERY_TIMEOUT, inputs=True):
        """
        Wait until the node publishes to us and its inputs and services are matched.

        :param inputs: whether to wait for its torque and wrench subscriptions too (a scene
            without external_wrench has none).
        """
        self.wait_for(
            lambda: all(self.received(topic) for topic in STATE_TYPES)
            and (not inputs or self.torque_publisher.get_subscription_count() > 0)
            and (not inputs or self.wrench_publisher.get_subscription_count() > 0)
            and self.reset_client.service_is_ready()
            and self.pause_client.service_is_ready()
            and self.parameters_client.service_is_ready(),
            timeout, 'the node to connect')

    def stamped_after(self, topic, stamp, count=1, timeout=DISCOVERY_TIMEOUT):
        """
        Wait for `count` messages on `topic` stamped after `stamp` (ns); return them.

        With the stamp a reset or pause reply gives (:func:`applied_from`), these are the
        messages that show its new state.
        """
        def after():
            return [message for message in self.messages(topic)
                    if nanoseconds(message.header.stamp) > stamp]
        self.wait_for(lambda: len(after()) >= count, timeout,
                      f'{count} messages on {topic} stamped after {stamp} ns')
        return after()

    def arrival_of_first_after(self, topic, stamp, timeout=DISCOVERY_TIMEOUT):
        """Return the arrival time of the first message on `topic` stamped after `stamp`."""
        first = self.stamped_after(topic, stamp, 1, timeout)[0]
        return next(arrived for arrived, message in self.received(topic) if message is first)

    # -- inputs and services

    def publish_torque(self, torque, frame_id=''):
        """Publish a torque (N m) on ``torque`` with the given header frame id."""
        message = Vector3Stamped()
        message.header.frame_id = frame_id
        message.vector.x, message.vector.y, message.vector.z = (float(t) for t in torque)
        self.torque_publisher.publish(message)

    def publish_wrench(self, force, torque, frame_id=''):
        """Publish a wrench (N, N m) on ``wrench`` with the given header frame id."""
        message = WrenchStamped()
        message.header.frame_id = frame_id
        wrench = message.wrench
        wrench.force.x, wrench.force.y, wrench.force.z = (float(f) for f in force)
        wrench.torque.x, wrench.torque.y, wrench.torque.z = (float(t) for t in torque)
        self.wrench_publisher.publish(message)

    def call(self, client, request, timeout=10.0, attempts=3):
        """
        Call a service and return its response; the request is sent again if none comes.

        A response can be lost before the node's DDS participant has discovered this
        client's response reader: rmw_fastrtps then drops it after a short wait ("failed to
        send response (timeout): client will not receive response", seen once on a loaded
        machine, where discovery lags), and no public API tells a client when the server
        has matched it.  The requests these tests send (parameters, reset, pause) may be
        sent twice; each attempt waits `timeout` s for its response.
        """
        for attempt in range(attempts):
            future = client.call_async(request)
            try:
                self.wait_for(future.done, timeout, f'a response from {client.srv_name}')
                return future.result()
            except AssertionError:
                client.remove_pending_request(future)
                if attempt == attempts - 1:
                    raise

    def await_matched(self, clients):
        """
        Call each service client once with its request type's defaults, until answered.

        A response received proves that the node's DDS has matched that client's response
        reader; a burst or a property-based series sent before then can lose its first
        answers (see :meth:`call`).  The default requests are harmless here: empty
        parameter lists, a reset, pause(false).
        """
        for client in clients:
            self.call(client, client.srv_type.Request())

    def reset(self):
        """Call ``reset``; return the response."""
        return self.call(self.reset_client, Trigger.Request())

    def pause(self, paused):
        """Call ``pause`` with data = `paused`; return the response."""
        return self.call(self.pause_client, SetBool.Request(data=paused))

    def set_parameter(self, name, value):
        """Set one parameter of the node; return the rcl_interfaces SetParametersResult."""
        request = SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])
        return self.call(self.parameters_client, request).results[0]


class RecorderProcess:
    """``rigid-body-sim record`` as a subprocess, its output in a file."""

    def __init__(self, log_path, bag, *arguments):
        self.log_path = Path(log_path)
        self._log = open(self.log_path, 'w')
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.cli', 'record', '--bag', str(bag),
             *arguments], stdout=self._log, stderr=subprocess.STDOUT, cwd=PACKAGE_ROOT)

    def output(self):
        """Return what it printed."""
        return self.log_path.read_text()

    def wait_until_recording(self, bag, timeout=30.0):
        """Wait for the first flush (metadata.yaml) with the node's topics in it."""
        deadline = time.monotonic() + timeout
        metadata = Path(bag) / 'metadata.yaml'
        while not (metadata.exists() and '/pose' in metadata.read_text()):
            assert self.process.poll() is None, self.output()
            assert time.monotonic() < deadline, 'the recorder recorded nothing:\n' + \
                self.output()
            time.sleep(0.05)  # waits-for: poll interval of the loop waiting for the first flush

    def flushed_counts(self, bag):
        """Return topic -> messages the flushed metadata.yaml counts (None: none readable)."""
        metadata = Path(bag) / 'metadata.yaml'
        if not metadata.exists():
            return None
        try:
            info = yaml.safe_load(metadata.read_text())['rosbag2_bagfile_information']
        except (yaml.YAMLError, KeyError, TypeError):
            return None  # caught between the writer's truncate and write: look again
        return {entry['topic_metadata']['name']: entry['message_count']
                for entry in info.get('topics_with_message_count') or []}

    def has_counts(self, bag, least):
        """Return whether the flushed metadata.yaml counts least[topic] of each topic."""
        counts = self.flushed_counts(bag)
        return counts is not None and all(counts.get(topic, 0) >= count
                                          for topic, count in least.items())

    def wait_for_counts(self, bag, least, timeout=120.0):
        """Wait until the flushed metadata.yaml counts at least least[topic] of each topic."""
        deadline = time.monotonic() + timeout
        while not self.has_counts(bag, least):
            assert self.process.poll() is None, self.output()
            assert time.monotonic() < deadline, f'not {least} recorded:\n{self.output()}'
            time.sleep(0.05)  # waits-for: poll interval of the loop waiting for the counts

    def finish(self, timeout=60.0):
        """Wait for the exit; return the exit code."""
        try:
            return self.process.wait(timeout=timeout)
        finally:
            if self.process.poll() is None:
                self.process.kill()
                self.process.wait()
            self._log.close()

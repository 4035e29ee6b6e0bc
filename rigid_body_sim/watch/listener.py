"""
Find a running rigid_body_node over DDS and feed its messages to a :class:`LiveState`.

A node is recognised by what it publishes, whatever its name or namespace: a
nav_msgs/Odometry topic and a geometry_msgs/Vector3Stamped topic named
``angular_momentum`` (the actual topic names are read from the graph, so a remapped or
namespaced node is found too).  The listener subscribes to those two, to the marker until
its first message, to /diagnostics (keeping the watched node's status) and to
/parameter_events (the node's own changes: an integrator switch shows at once, not at the
next report).  It spins a SingleThreadedExecutor in a thread of its own, in a context of
its own, so the views keep the main thread (Tk needs it).  (rclpy 7.1.6's experimental
EventsExecutor, cheaper per message, never ran a timer spun from a second thread here, and
its shutdown hung.)
"""

from dataclasses import dataclass
import os
import threading
import time

from .live import DIAGNOSTICS_KEYS
from .live import LiveState

__all__ = ['Listener', 'NodeCandidate', 'find_nodes']

_ODOMETRY = 'nav_msgs/msg/Odometry'
_VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
_MARKER = 'visualization_msgs/msg/Marker'
# How often the graph is searched while no node is watched, and checked while one is (s).
_DISCOVERY_PERIOD = 0.5
# A watched node absent from the graph this long is gone (the graph lags a little).
_GONE_AFTER = 3.0


@dataclass
class NodeCandidate:
    """A node that publishes the rigid_body_sim state topics: its name and topic names."""

    name: str
    namespace: str
    odom: str
    angular_momentum: str
    marker: str

    @property
    def fully_qualified_name(self):
        """Return /namespace/name."""
        return f'{self.namespace.rstrip("/")}/{self.name}'

    def matches(self, node=None, namespace=None):
        """Return True if it is the node asked for (a name or /ns/name) in the namespace."""
        if namespace is not None and self.namespace.rstrip('/') != \
                ('/' + namespace.strip('/')).rstrip('/'):
            return False
        if node is None:
            return True
        return node in (self.name, self.fully_qualified_name)


def find_nodes(ros_node, exclude=()):
    """Return the :class:`NodeCandidate` s in the graph, sorted by fully qualified name."""
    found = []
    for name, namespace in ros_node.get_node_names_and_namespaces():
        if (name, namespace) in exclude:
            continue
        try:
            topics = ros_node.get_publisher_names_and_types_by_node(name, namespace)
        except Exception:  # noqa: B902 (the node left the graph between the two calls)
            continue
        odom = momentum = marker = None
        for topic, types in topics:
            last = topic.rsplit('/', 1)[-1]
            if _ODOMETRY in types and (odom is None or last == 'odom'):
                odom = topic
            elif _VECTOR3_STAMPED in types and last == 'angular_momentum':
                momentum = topic
            elif _MARKER in types and (marker is None or last == 'marker'):
                marker = topic
        if odom is not None and momentum is not None:
            found.append(NodeCandidate(name, namespace, odom, momentum, marker))
    return sorted(found, key=lambda candidate: candidate.fully_qualified_name)


class Listener:
    """
    The watch's own ROS node: discovery, subscriptions, and the thread that spins them.

    Parameters
    ----------
    state : LiveState
        Where the messages go.
    node : str, optional
        The node to watch: its name or fully qualified name (default: the first found).
    namespace : str, optional
        Only nodes in this namespace.

    Attributes
    ----------
    candidates : list of NodeCandidate
        The nodes found at the last search.
    watched : NodeCandidate or None
        The node watched now.
    searching_since : float
        time.monotonic() when the search for a node began (the last one gone).

    """

    def __init__(self, state, node=None, namespace=None):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.state = state
        self.wanted_node = node
        self.wanted_namespace = namespace
        self.candidates = []
        self.watched = None
        self.searching_since = time.monotonic()
        self._subscriptions = []
        self._marker_subscription = None
        self._last_seen = time.monotonic()
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=_no_signal_handlers())
        self.node = rclpy.create_node(f'rigid_body_sim_watch_{os.getpid()}',
                                      context=self.context,
                                      start_parameter_services=False)
        self._own = (self.node.get_name(), self.node.get_namespace())
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.node.create_timer(_DISCOVERY_PERIOD, self._discover)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._spin, name='watch-ros', daemon=True)

    @property
    def domain_id(self):
        """Return the ROS domain searched."""
        return self.context.get_domain_id()

    def start(self):
        """Start spinning (discovery, then the messages) in the background."""
        self._thread.start()

    def _spin(self):
        # spin_once in a loop, not spin(): close() stops the loop and joins this thread
        # before anything is destroyed, so no wait set is built on a dead context.
        while not self._stopping.is_set():
            self.executor.spin_once(timeout_sec=0.1)

    def close(self):
        """Stop spinning and release the node and its context."""
        import rclpy
        self._stopping.set()
        if self._thread.is_alive():
            self._thread.join(5.0)
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    # -- discovery (the executor's thread)

    def _discover(self):
        self.candidates = find_nodes(self.node, exclude=(self._own,))
        wanted = [candidate for candidate in self.candidates
                  if candidate.matches(self.wanted_node, self.wanted_namespace)]
        if self.watched is not None:
            same = [candidate for candidate in wanted if candidate.fully_qualified_name
                    == self.watched.fully_qualified_name]
            if same:
                self._last_seen = time.monotonic()
                return
            if time.monotonic() - self._last_seen < _GONE_AFTER:
                return
            self._unsubscribe()
            self.watched = None
            self.searching_since = time.monotonic()
            self.state.set_node(None)
        if wanted:
            self._subscribe(wanted[0])

    def _subscribe(self, candidate):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import Vector3Stamped
        from nav_msgs.msg import Odometry
        from rcl_interfaces.msg import ParameterEvent
        from rclpy.qos import qos_profile_parameter_events

        from ..messages.qos import DIAGNOSTICS_QOS
        from ..messages.qos import STATE_QOS

        self.watched = candidate
        self._last_seen = time.monotonic()
        self.state.set_node(candidate.fully_qualified_name)
        node = self.node
        self._subscriptions = [
            node.create_subscription(Odometry, candidate.odom, self._odometry_callback,
                                     STATE_QOS),
            node.create_subscription(Vector3Stamped, candidate.angular_momentum,
                                     self._angular_momentum_callback, STATE_QOS),
            node.create_subscription(DiagnosticArray, '/diagnostics',
                                     self._diagnostics_callback, DIAGNOSTICS_QOS),
            node.create_subscription(ParameterEvent, '/parameter_events',
                                     self._parameter_event_callback,
                                     qos_profile_parameter_events),
        ]
        if candidate.marker is not None:
            from visualization_msgs.msg import Marker
            self._marker_subscription = node.create_subscription(
                Marker, candidate.marker, self._marker_callback, STATE_QOS)

    def _unsubscribe(self):
        for subscription in self._subscriptions:
            self.node.destroy_subscription(subscription)
        self._subscriptions = []
        self._drop_marker_subscription()

    def _drop_marker_subscription(self):
        # One marker is all the drawing needs: the node stops publishing it (at its rate)
        # once nobody subscribes.
        if self._marker_subscription is not None:
            self.node.destroy_subscription(self._marker_subscription)
            self._marker_subscription = None

    # -- messages (the executor's thread)

    def _odometry_callback(self, message):
        pose, twist = message.pose.pose, message.twist.twist
        orientation, position, angular = pose.orientation, pose.position, twist.angular
        self.state.add_odometry(
            _nanoseconds(message.header.stamp),
            (orientation.x, orientation.y, orientation.z, orientation.w),
            (position.x, position.y, position.z), (angular.x, angular.y, angular.z))

    def _angular_momentum_callback(self, message):
        vector = message.vector
        self.state.add_angular_momentum(_nanoseconds(message.header.stamp),
                                        (vector.x, vector.y, vector.z))

    def _marker_callback(self, message):
        self.state.add_marker(_nanoseconds(message.header.stamp), message)
        if not self.state.wants_marker:
            self._drop_marker_subscription()

    def _diagnostics_callback(self, message):
        watched = self.watched
        if watched is None:
            return
        for status in message.status:
            if status.hardware_id == watched.fully_qualified_name:
                values = {pair.key: pair.value for pair in status.values}
                values[DIAGNOSTICS_KEYS['status']] = status.message
                self.state.add_diagnostics(_nanoseconds(message.header.stamp), values)

    def _parameter_event_callback(self, event):
        from rclpy.parameter import parameter_value_to_python
        watched = self.watched
        if watched is None or event.node != watched.fully_qualified_name:
            return
        for parameter in event.changed_parameters:
            self.state.add_parameter_change(parameter.name,
                                            parameter_value_to_python(parameter.value))


def _nanoseconds(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _no_signal_handlers():
    # The watch handles SIGINT itself (a window must close cleanly); rclpy's handler would
    # shut the context down under the views' feet.
    from rclpy.signals import SignalHandlerOptions
    return SignalHandlerOptions.NO


def new_state_and_listener(history, node=None, namespace=None):
    """Return a (LiveState, Listener) pair, the listener not yet started."""
    state = LiveState(history)
    return state, Listener(state, node=node, namespace=namespace)

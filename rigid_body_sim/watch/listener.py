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

Only the watched node is believed.  Its publishers are known by their GIDs (the graph's
endpoint GIDs; the first 12 bytes of a GID are its DDS participant's, one per process).
rclpy 7.1.6 does not say which publisher sent a message (its message info has no publisher
GID), so each message is checked against who can send it: on the node's own topics
(odom, angular_momentum, marker) a message is taken only while every publisher matched is
the node's; on the shared /diagnostics and /parameter_events, while other publishers are
matched, a message that claims the node is taken only if it continues the node's stream
(its publication sequence number follows the last one taken).  A second node of the same
name (another participant) is another publisher: the view says so.  Every subscription is
raw: a message larger than its topic's bound is counted and dropped unread, so a peer's
megabytes cost a copy, never a deserialisation or the memory to hold them.
"""

from dataclasses import dataclass
from dataclasses import field
import os
import threading
import time

from .live import DIAGNOSTICS_KEYS
from .live import LiveState
from ..text import shortened

__all__ = ['Listener', 'NodeCandidate', 'find_nodes']

_ODOMETRY = 'nav_msgs/msg/Odometry'
_VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
_MARKER = 'visualization_msgs/msg/Marker'
# How often the graph is searched while no node is watched, and checked while one is (s).
_DISCOVERY_PERIOD = 0.5
# A watched node absent from the graph this long is gone (the graph lags a little).
_GONE_AFTER = 3.0
# The largest serialised message (bytes) taken per topic: the node's are far smaller (a
# report holds some forty short values); a larger one is a peer's, dropped unread.
_STATE_BYTES = 16 * 1024
_REPORT_BYTES = 64 * 1024
# Keep-last depth of the shared topics' subscriptions: the node's report comes once a second,
# so a short queue loses nothing and bounds what a peer's large messages can hold.
_SHARED_DEPTH = 4
# A claim on a shared topic continues the node's stream if its sequence number is at most
# this far past the last one taken (a few lost messages are forgiven).
_SEQUENCE_SLACK = 8
# The bytes of a GID that name its DDS participant (an RTPS GUID prefix).
_PARTICIPANT_BYTES = 12


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
    seen = set()
    for name, namespace in ros_node.get_node_names_and_namespaces():
        if (name, namespace) in exclude or (name, namespace) in seen:
            continue  # (two nodes of one name are listed twice; the listener tells them)
        seen.add((name, namespace))
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


@dataclass
class _Topic:
    """One subscription of the watch: its bound, and whose messages it takes now."""

    name: str
    message_type: type
    shared: bool  # /diagnostics, /parameter_events: other nodes publish there too
    limit: int  # bytes
    label: str
    subscription: object = None
    own: int = 0  # the watched node's publishers on it, and the watch's own (graph)
    foreign: list = field(default_factory=list)  # the others, described (graph)
    last_sequence: int = None  # of the last message taken in the node's name


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
    participant : bytes or None
        The DDS participant of the watched node's publishers (a GID's first 12 bytes).
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
        self.participant = None
        self.searching_since = time.monotonic()
        self._topics = {}
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
        # The DDS participant goes now, not in the interpreter's exit.
        self.context.destroy()

    # -- discovery (the executor's thread)

    def _discover(self):
        if self.watched is not None:
            # Watching, only the watched node's topics are looked at: the whole graph is
            # searched again once it is gone.
            if self._check_publishers():
                self._last_seen = time.monotonic()
                return
            if time.monotonic() - self._last_seen < _GONE_AFTER:
                return
            self._unsubscribe()
            self.watched = None
            self.participant = None
            self.searching_since = time.monotonic()
            self.state.set_node(None)
        self.candidates = find_nodes(self.node, exclude=(self._own,))
        wanted = [candidate for candidate in self.candidates
                  if candidate.matches(self.wanted_node, self.wanted_namespace)]
        if wanted:
            self._subscribe(wanted[0])

    def _publishers(self, topic):
        """Return the (GID bytes, fully qualified node name) of the topic's publishers."""
        try:
            infos = self.node.get_publishers_info_by_topic(topic)
        except Exception:  # noqa: B902 (a topic name the graph no longer resolves)
            return []
        return [(bytes(info.endpoint_gid), f'{info.node_namespace.rstrip("/")}/'
                 f'{info.node_name}') for info in infos]

    def _check_publishers(self):
        """
        Sort each topic's publishers into the node's own and others; say what changed.

        Returns True while the watched node's own odom publisher is in the graph.
        """
        name = self.watched.fully_qualified_name
        odom = [(gid, node) for gid, node in self._publishers(self.watched.odom)
                if node == name]
        participants = {gid[:_PARTICIPANT_BYTES] for gid, _ in odom}
        if self.participant is None and len(participants) == 1:
            self.participant = participants.pop()
        # (Two of that name from the start: none is chosen, and both are present.)
        present = bool(odom) if self.participant is None else any(
            gid[:_PARTICIPANT_BYTES] == self.participant for gid, _ in odom)
        for topic in self._topics.values():
            own, foreign = 0, []
            for gid, node in self._publishers(topic.name):
                if node == name and self.participant is not None and \
                        gid[:_PARTICIPANT_BYTES] == self.participant:
                    own += 1
                elif node == name:
                    foreign.append(f'a second node named {shortened(name)} (publisher GID '
                                   f'{gid.hex()})')
                elif (node.rsplit('/', 1)[-1], node.rsplit('/', 1)[0] or '/') == self._own:
                    own += 1  # the watch's own (its parameter events)
                else:
                    foreign.append(f'{shortened(node)} (GID {gid.hex()})')
            topic.own, topic.foreign = own, foreign
            self._say(topic)
        if self.participant is None and len(odom) > 1:
            self.state.set_warning('node', f'{len(odom)} nodes named {shortened(name)} publish '
                                   'its state: which message is whose cannot be told (rclpy '
                                   'gives no sender per message); nothing is taken until one '
                                   'is left')
        else:
            self.state.set_warning('node', next((
                f'{shortened(name)}: ' + ', '.join(topic.foreign[:2])
                + ' appeared; the state is taken only while no other publisher is matched'
                for topic in self._topics.values() if not topic.shared and any(
                    'a second node' in text for text in topic.foreign)), None))
        return present

    def _say(self, topic):
        # Other nodes publish on the shared topics as a matter of course: a claim there that
        # is not the node's is counted as refused, not warned about in advance.
        if not topic.foreign or topic.shared:
            self.state.set_warning(topic.label, None)
            return
        others = ', '.join(topic.foreign[:3]) + (
            f' and {len(topic.foreign) - 3} more' if len(topic.foreign) > 3 else '')
        text = (f'other publishers on {topic.name}: {others}; its messages are not taken '
                'while they are matched')
        self.state.set_warning(topic.label, text)

    def _subscribe(self, candidate):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import Vector3Stamped
        from nav_msgs.msg import Odometry
        from rcl_interfaces.msg import ParameterEvent
        from rclpy.qos import HistoryPolicy
        from rclpy.qos import QoSProfile

        from ..messages.qos import DIAGNOSTICS_QOS
        from ..messages.qos import STATE_QOS

        self.watched = candidate
        self._last_seen = time.monotonic()
        self.state.set_node(candidate.fully_qualified_name)
        shared_qos = QoSProfile(reliability=DIAGNOSTICS_QOS.reliability,
                                durability=DIAGNOSTICS_QOS.durability,
                                history=HistoryPolicy.KEEP_LAST, depth=_SHARED_DEPTH)
        topics = [
            (_Topic(candidate.odom, Odometry, False, _STATE_BYTES, 'odom'),
             self._odometry_callback, STATE_QOS),
            (_Topic(candidate.angular_momentum, Vector3Stamped, False, _STATE_BYTES,
                    'angular_momentum'), self._angular_momentum_callback, STATE_QOS),
            (_Topic('/diagnostics', DiagnosticArray, True, _REPORT_BYTES, 'diagnostics'),
             self._diagnostics_callback, shared_qos),
            (_Topic('/parameter_events', ParameterEvent, True, _REPORT_BYTES,
                    'parameter_events'), self._parameter_event_callback, shared_qos),
        ]
        if candidate.marker is not None:
            from visualization_msgs.msg import Marker
            topics.append((_Topic(candidate.marker, Marker, False, _REPORT_BYTES, 'marker'),
                           self._marker_callback, STATE_QOS))
        for topic, callback, qos in topics:
            topic.subscription = self.node.create_subscription(
                topic.message_type, topic.name,
                lambda data, info, topic=topic, callback=callback: self._take(
                    topic, data, info, callback), qos, raw=True)
            self._topics[topic.label] = topic
        self._check_publishers()

    def _unsubscribe(self):
        for label in list(self._topics):
            self._drop(label)

    def _drop(self, label):
        topic = self._topics.pop(label, None)
        if topic is not None:
            self.node.destroy_subscription(topic.subscription)
            self.state.set_warning(label, None)

    # -- messages (the executor's thread)

    def _take(self, topic, data, info, callback):
        """Deserialise a message the node can have sent, within its bound; else count it."""
        from rclpy.serialization import deserialize_message
        if len(data) > topic.limit:
            self.state.refuse(topic.label, f'larger than {topic.limit // 1024} kB')
            return
        clean = topic.subscription.get_publisher_count() <= topic.own
        if not topic.shared and not clean:
            self.state.refuse(topic.label, 'sent while another publisher was matched')
            return
        try:
            message = deserialize_message(data, topic.message_type)
        except Exception:  # noqa: B902 (a peer's bytes that are no such message)
            self.state.refuse(topic.label, 'not a message of its type')
            return
        if topic.shared:
            callback(message, lambda: self._in_stream(topic, clean, info))
        else:
            callback(message)

    def _in_stream(self, topic, clean, info):
        """Return True if a message claiming the node on a shared topic is the node's own."""
        sequence = info.get('publication_sequence_number')
        last = topic.last_sequence
        if not clean and last is not None and sequence is not None and not (
                last < sequence <= last + _SEQUENCE_SLACK):
            self.state.refuse(topic.label, 'claimed the node, not from its publisher')
            return False
        topic.last_sequence = sequence
        return True

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
            # One marker is all the drawing needs: the node stops publishing it (at its
            # rate) once nobody subscribes.
            self._drop('marker')

    def _diagnostics_callback(self, message, from_the_node):
        watched = self.watched
        if watched is None:
            return
        for status in message.status:
            if status.hardware_id == watched.fully_qualified_name:
                if not from_the_node():
                    return
                values = {pair.key: pair.value for pair in status.values}
                values[DIAGNOSTICS_KEYS['status']] = status.message
                self.state.add_diagnostics(_nanoseconds(message.header.stamp), values)
                return

    def _parameter_event_callback(self, event, from_the_node):
        from rclpy.parameter import parameter_value_to_python
        watched = self.watched
        if watched is None or event.node != watched.fully_qualified_name:
            return
        if not from_the_node():
            return
        for parameter in event.changed_parameters:
            try:
                value = parameter_value_to_python(parameter.value)
            except Exception:  # noqa: B902 (a peer's parameter of no known type)
                continue
            self.state.add_parameter_change(parameter.name, value)


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

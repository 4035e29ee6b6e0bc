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

A node of bodies (node/world_node.py) is recognised by its ``markers`` MarkerArray and its
bodies' ``<name>/odom`` and ``<name>/angular_momentum``; the bodies are the names under
which both are published.  The listener watches one body (``--body``, or the one the
window's keys choose): its two state topics, ``markers`` until the message that holds its
marker (``ns`` its name), the node's reports; the effects that act on it come from the
scene's body entry (the scene the node's report names, if it is a built-in one).  Or it
keeps a table of the bodies shown (:class:`.live.BodyTable`): the state topics of those rows
only, as the node publishes a body's topics only while they have subscribers.  The body
topics are believed as the node's own topics are (only while every publisher matched is
the node's).
"""

from dataclasses import dataclass
from dataclasses import field
import os
import threading
import time

from .live import bodies_text
from .live import BodyTable
from .live import DIAGNOSTICS_KEYS
from .live import LiveState
from ..text import shortened

__all__ = ['Listener', 'NodeCandidate', 'find_nodes', 'node_candidate']

_ODOMETRY = 'nav_msgs/msg/Odometry'
_VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
_MARKER = 'visualization_msgs/msg/Marker'
_MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'
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
# The bound of a MarkerArray per body it holds (the node's marker is a few hundred bytes).
_MARKER_BYTES_PER_BODY = 1024
# How often (s) the requests of the views (another body, more table rows) are applied.
_REQUEST_PERIOD = 0.1
# A node of bodies' topics are read again every this many searches (they change only when
# a body is spawned or deleted; reading thousands of names costs).
_RESCAN_EVERY = 4
# A --body not among the node's bodies is unknown once the node's report counts as many
# bodies as the graph shows, or once the bodies seen have not changed for this long (s).
_SETTLE = 10.0


@dataclass
class NodeCandidate:
    """
    A node that publishes the rigid_body_sim state topics: its name and topic names.

    Of a node of bodies, `bodies` is {body name: (its odom topic, its angular_momentum
    topic)} and `markers` its MarkerArray topic (odom, angular_momentum: the first body's);
    of a one-body node, `bodies` is empty.
    """

    name: str
    namespace: str
    odom: str
    angular_momentum: str
    marker: str
    bodies: dict = field(default_factory=dict)
    markers: str = None

    @property
    def body_names(self):
        """Return the names of the bodies, sorted (empty for a one-body node)."""
        return sorted(self.bodies)

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
        candidate = node_candidate(ros_node, name, namespace)
        if candidate is not None:
            found.append(candidate)
    return sorted(found, key=lambda candidate: candidate.fully_qualified_name)


def node_candidate(ros_node, name, namespace):
    """Return the :class:`NodeCandidate` of node `name` in `namespace` from its topics, or None."""
    try:
        topics = ros_node.get_publisher_names_and_types_by_node(name, namespace)
    except Exception:  # noqa: B902 (the node left the graph)
        return None
    odom = momentum = marker = markers = None
    odoms, momenta = {}, {}
    for topic, types in topics:
        parent, _, last = topic.rpartition('/')
        if _ODOMETRY in types and (odom is None or last == 'odom'):
            odom = topic
        elif _VECTOR3_STAMPED in types and last == 'angular_momentum':
            momentum = topic
        elif _MARKER in types and (marker is None or last == 'marker'):
            marker = topic
        if _ODOMETRY in types and last == 'odom':
            odoms[parent] = topic
        elif _VECTOR3_STAMPED in types and last == 'angular_momentum':
            momenta[parent] = topic
        elif _MARKER_ARRAY in types and last == 'markers':
            markers = topic
    bodies = {}
    if markers is not None:
        for parent in odoms.keys() & momenta.keys():
            body = _body_name(parent, namespace)
            if body:
                bodies[body] = (odoms[parent], momenta[parent])
    if bodies:
        first = bodies[min(bodies)]
        return NodeCandidate(name, namespace, first[0], first[1], None, bodies, markers)
    if odom is not None and momentum is not None:
        return NodeCandidate(name, namespace, odom, momentum, marker)
    return None


def _body_name(parent, namespace):
    """Return the body a topic under `parent` belongs to (relative to the node's namespace)."""
    prefix = namespace.rstrip('/') + '/'
    if parent.startswith(prefix):
        return parent[len(prefix):]
    return parent.rsplit('/', 1)[-1]


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
    # A table row's topic: its newest message taken is kept as bytes, read at a refresh.
    lazy: bool = False
    latest: bytes = None
    read: bytes = None


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
    body : str, optional
        Of a node of bodies, the body to watch (``--body``).  Without it: the first body,
        another at :meth:`select_body` (chooser 'switch'), or the table of the bodies
        (chooser 'table', :attr:`table`).
    chooser : {'switch', 'table'}
        What a node of bodies shows without `body`.
    table_rows : int
        The rows of the table (the bodies subscribed to), until :meth:`set_table_rows`.

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
    body : str or None
        The body watched now (of a node of bodies).
    table : BodyTable
        The rows of the table of a node's bodies (chooser 'table').
    table_bodies : tuple of str
        The bodies whose rows the table shows now (their topics subscribed to).
    problem : str or None
        A sentence saying why the watch cannot go on as asked (a --body the node does not
        have; --body on a one-body node): the command says it and exits.

    """

    def __init__(self, state, node=None, namespace=None, body=None, chooser='switch',
                 table_rows=20):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.state = state
        self.wanted_node = node
        self.wanted_namespace = namespace
        self.wanted_body = body
        self.chooser = chooser
        self.body = None
        self.table = BodyTable()
        self.table_bodies = ()
        self.problem = None
        self._table_rows = max(1, int(table_rows))
        self._requested = None
        self._bodies_seen = (frozenset(), time.monotonic())
        self._searches = 0
        self._effects = {}
        self._built_in = None
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
        self.node.create_timer(_REQUEST_PERIOD, self._apply_requests)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._spin, name='watch-ros', daemon=True)

    @property
    def domain_id(self):
        """Return the ROS domain searched."""
        return self.context.get_domain_id()

    def start(self):
        """Start spinning (discovery, then the messages) in the background."""
        self._thread.start()

    def select_body(self, step):
        """Watch the body `step` places on in the sorted names (-1: the one before); any thread."""
        watched = self.watched
        if watched is None or not watched.bodies:
            return
        names = watched.body_names
        current = self._requested or self.body
        index = names.index(current) if current in names else 0
        self._requested = names[(index + step) % len(names)]

    def set_table_rows(self, rows):
        """Show (subscribe to) this many bodies in the table from now on; any thread."""
        self._table_rows = max(1, int(rows))

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
                if self.watched.bodies:
                    self._follow_bodies()
                return
            if time.monotonic() - self._last_seen < _GONE_AFTER:
                return
            self._unsubscribe()
            self.watched = None
            self.participant = None
            self.body = None
            self.table_bodies = ()
            self.table.clear()
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
        # The node's presence: its markers of all bodies, or its one body's odom.
        odom = [(gid, node) for gid, node in self._publishers(
            self.watched.markers or self.watched.odom) if node == name]
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
        from rcl_interfaces.msg import ParameterEvent
        from rclpy.qos import HistoryPolicy
        from rclpy.qos import QoSProfile

        from ..messages.qos import DIAGNOSTICS_QOS

        self.watched = candidate
        self._last_seen = time.monotonic()
        self._bodies_seen = (frozenset(candidate.bodies), time.monotonic())
        shared_qos = QoSProfile(reliability=DIAGNOSTICS_QOS.reliability,
                                durability=DIAGNOSTICS_QOS.durability,
                                history=HistoryPolicy.KEEP_LAST, depth=_SHARED_DEPTH)
        name = candidate.fully_qualified_name
        if not candidate.bodies:
            if self.wanted_body is not None:
                self.problem = (f'{shortened(name)} simulates one body (its topics odom, '
                                'angular_momentum, marker): watch it without --body')
            self.state.set_node(name)
            self._subscribe_state(candidate.odom, candidate.angular_momentum)
            if candidate.marker is not None:
                from visualization_msgs.msg import Marker
                self._add_topic(_Topic(candidate.marker, Marker, False, _REPORT_BYTES,
                                       'marker'), self._marker_callback)
        else:
            self._choose_body()
        self._add_topic(_Topic('/diagnostics', DiagnosticArray, True, _REPORT_BYTES,
                               'diagnostics'), self._diagnostics_callback, shared_qos)
        self._add_topic(_Topic('/parameter_events', ParameterEvent, True, _REPORT_BYTES,
                               'parameter_events'), self._parameter_event_callback, shared_qos)
        self._check_publishers()

    def _add_topic(self, topic, callback, qos=None):
        from ..messages.qos import STATE_QOS
        topic.subscription = self.node.create_subscription(
            topic.message_type, topic.name,
            lambda data, info, topic=topic, callback=callback: self._take(
                topic, data, info, callback), qos or STATE_QOS, raw=True)
        self._topics[topic.label] = topic

    def _subscribe_state(self, odom, angular_momentum):
        """Subscribe the LiveState to one body's odom and angular_momentum."""
        from geometry_msgs.msg import Vector3Stamped
        from nav_msgs.msg import Odometry
        self._add_topic(_Topic(odom, Odometry, False, _STATE_BYTES, 'odom'),
                        self._odometry_callback)
        self._add_topic(_Topic(angular_momentum, Vector3Stamped, False, _STATE_BYTES,
                               'angular_momentum'), self._angular_momentum_callback)

    # -- a node of bodies (the executor's thread)

    def _choose_body(self):
        """Watch the body asked for, the table, or the first body, as the options say."""
        names = self.watched.body_names
        if self.wanted_body is not None:
            # Not (yet) in the graph: the node's report and the graph settle it
            # (_follow_bodies); meanwhile the view says which body it waits for.
            self._watch_body(self.wanted_body)
        elif self.chooser == 'table' and len(names) > 1:
            self._show_table()
        else:
            self._watch_body(self.body if self.body in names else names[0])

    def _watch_body(self, name):
        """Subscribe to body `name`'s state, and to markers until its marker came."""
        from visualization_msgs.msg import MarkerArray
        for label in ('odom', 'angular_momentum', 'markers'):
            self._drop(label)
        watched = self.watched
        self.body = name
        self.state.set_node(watched.fully_qualified_name, name, watched.body_names)
        if name not in watched.bodies:
            return
        self._subscribe_state(*watched.bodies[name])
        self._add_topic(_Topic(watched.markers, MarkerArray, False, max(
            _REPORT_BYTES, _MARKER_BYTES_PER_BODY * len(watched.bodies)), 'markers'),
            self._markers_callback)
        # Whose publishers the new subscriptions match, before their first message.
        self._check_publishers()

    def _show_table(self):
        """Subscribe to the state of the bodies the table shows (its first rows), only."""
        from geometry_msgs.msg import Vector3Stamped
        from nav_msgs.msg import Odometry
        watched = self.watched
        # (The same node and no body: the state goes on, with the bodies as they are now.)
        self.state.set_node(watched.fully_qualified_name, None, watched.body_names)
        self.body = None
        shown = tuple(watched.body_names[:self._table_rows])
        if shown == self.table_bodies:
            return
        for name in set(self.table_bodies) - set(shown):
            self._drop(f'{name}/odom')
            self._drop(f'{name}/angular_momentum')
        for name in set(shown) - set(self.table_bodies):
            odom, momentum = watched.bodies[name]
            self._add_topic(_Topic(odom, Odometry, False, _STATE_BYTES, f'{name}/odom',
                                   lazy=True), None)
            self._add_topic(_Topic(momentum, Vector3Stamped, False, _STATE_BYTES,
                                   f'{name}/angular_momentum', lazy=True), None)
        self.table.keep_only(shown)
        self.table_bodies = shown
        self._check_publishers()

    def _apply_requests(self):
        """Apply what a view asked for: another body, another number of table rows."""
        watched = self.watched
        if watched is None or not watched.bodies or self.problem is not None:
            return
        requested, self._requested = self._requested, None
        if requested is not None and requested != self.body and requested in watched.bodies:
            self._watch_body(requested)
        if self.table_bodies or (self.body is None and self.chooser == 'table'):
            self._show_table()

    def _follow_bodies(self):
        """Read a node of bodies' topics again now and then; settle an absent --body."""
        self._searches += 1
        absent = self.wanted_body is not None and self.wanted_body not in self.watched.bodies
        if not absent and self._searches % _RESCAN_EVERY:
            return
        watched = self.watched
        fresh = node_candidate(self.node, watched.name, watched.namespace)
        if fresh is None or not fresh.bodies:
            return
        now = time.monotonic()
        if set(fresh.bodies) != self._bodies_seen[0]:
            self._bodies_seen = (frozenset(fresh.bodies), now)
            watched.bodies, watched.markers = fresh.bodies, fresh.markers
            watched.odom, watched.angular_momentum = fresh.odom, fresh.angular_momentum
            if self.body is not None and self.wanted_body is None and \
                    self.body not in watched.bodies:
                self._watch_body(watched.body_names[0])  # (the body watched was deleted)
            elif self.body in watched.bodies and 'odom' not in self._topics:
                self._watch_body(self.body)  # (the body asked for came)
            elif self.body is None:
                self._show_table()
            else:
                self.state.set_node(watched.fully_qualified_name, self.body,
                                    watched.body_names)
        if self.wanted_body is None or self.wanted_body in watched.bodies:
            self.state.set_warning('body', None)
            return
        reported = self.state.snapshot().number('bodies')
        if reported == len(watched.bodies) or now - self._bodies_seen[1] >= _SETTLE:
            self.problem = (f'{shortened(watched.fully_qualified_name)} has no body named '
                            f'{shortened(repr(self.wanted_body), 80)}; its '
                            f'{len(watched.bodies)} bodies: {bodies_text(watched.body_names)}')
        else:
            self.state.set_warning('body', f'no body {self.wanted_body} among the '
                                   f'{len(watched.bodies)} found so far; still looking')

    def _effects_of(self, scene_name, body):
        """Return the effects on `body` (their names, ', '-joined) from the built-in scene."""
        from ..scenes import load_scene
        from ..scenes import scene_names
        if self._built_in is None:
            self._built_in = set(scene_names(several_bodies=True))
        # Only a built-in scene, by name: a peer's text never names a file to read.
        if scene_name not in self._built_in:
            return 'not known here (the scene is not a built-in one)'
        if scene_name not in self._effects:
            try:
                scene = load_scene(scene_name)
            except (OSError, ValueError):
                scene = None
            self._effects[scene_name] = None if scene is None else {
                member.name: ', '.join(member.effect_names()) or 'none'
                for member in scene.members}
        effects = self._effects[scene_name]
        if effects is None:
            return 'not known here (the scene is not a built-in one)'
        return effects.get(body, 'not known here (a body spawned into the scene)')

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
        if topic.lazy:
            # The table shows a state a refresh: the newest, deserialised then (a message
            # costs the executor a fraction of what deserialising it would).
            topic.latest = data
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

    def _markers_callback(self, message):
        body = self.body
        for marker in message.markers:
            if marker.ns == body:
                self.state.add_marker(_nanoseconds(marker.header.stamp), marker)
                break
        if not self.state.wants_marker:
            self._drop('markers')  # (as the marker: one is all the drawing needs)

    def table_rows(self):
        """
        Return the table's rows (:meth:`.live.BodyTable.rows`), from the newest messages.

        Any thread: the messages taken since the last call are deserialised here.
        """
        from rclpy.serialization import deserialize_message
        for name in self.table_bodies:
            for kind, take in (('odom', self._table_odometry),
                               ('angular_momentum', self._table_momentum)):
                topic = self._topics.get(f'{name}/{kind}')
                data = None if topic is None else topic.latest
                if data is None or data is topic.read:
                    continue
                topic.read = data
                try:
                    message = deserialize_message(data, topic.message_type)
                except Exception:  # noqa: B902 (a peer's bytes that are no such message)
                    self.state.refuse(topic.label, 'not a message of its type')
                    continue
                take(name, message)
        return self.table.rows()

    def _table_odometry(self, name, message):
        pose, twist = message.pose.pose, message.twist.twist
        orientation, position = pose.orientation, pose.position
        angular, linear = twist.angular, twist.linear
        self.table.add_odometry(
            name, (orientation.x, orientation.y, orientation.z, orientation.w),
            (position.x, position.y, position.z), (angular.x, angular.y, angular.z),
            (linear.x, linear.y, linear.z))

    def _table_momentum(self, name, message):
        vector = message.vector
        self.table.add_angular_momentum(name, (vector.x, vector.y, vector.z))

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
                if self.body is not None and DIAGNOSTICS_KEYS['effects'] not in values:
                    # A node of bodies reports none: the body's own, from its scene.
                    values[DIAGNOSTICS_KEYS['effects']] = self._effects_of(
                        values.get(DIAGNOSTICS_KEYS['scene']), self.body)
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


def new_state_and_listener(history, node=None, namespace=None, body=None, chooser='switch',
                           table_rows=20):
    """Return a (LiveState, Listener) pair, the listener not yet started."""
    state = LiveState(history)
    return state, Listener(state, node=node, namespace=namespace, body=body, chooser=chooser,
                           table_rows=table_rows)

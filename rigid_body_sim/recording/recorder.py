"""
A live recorder of ROS 2 topics into a rosbag2 bag, for machines without rosbag2.

:func:`record` subscribes to the topics (default: everything the node publishes: its state
topics, /diagnostics and /clock; a topic nobody publishes simply stays out of the bag),
writes every message as it was received, and on SIGINT (Ctrl-C) or SIGTERM finishes the bag.

Matching QoS.  A subscription must be compatible with the publisher and keep up with it.
Reliability and durability follow the publishers, as ``ros2 bag record`` adapts them:
the node's topics are subscribed at once with the policies of
:mod:`rigid_body_sim.messages.qos` (best effort for /clock, whose publishers are best effort),
other topics when discovery shows their type and offers (reliable if every publisher is,
transient local if every publisher is).  History is keep-last with a deep queue (`depth`,
default 30,000: thirty seconds at 1 kHz; Fast DDS allocates a sample only when it is
queued, so a deep queue costs nothing until the recorder falls behind), so a recorder that
falls behind while the DDS threads keep receiving (a slow flush, the interpreter busy)
loses nothing.  A flush was seen to block for seconds on a loaded machine (most likely its
write into the page of the bag's end that the fsync thread had under writeback), which
overflowed the former, shallower queue.  A stall of the whole process, DDS threads
included, is another matter: Fast DDS's shared-memory port queue holds 512 samples (under a
tenth of a second of the node's six topics at 1 kHz), and a reliable publisher resends only
what its history still holds: the node's state publishers their last 1000 samples
(1 s at 1 kHz, :mod:`rigid_body_sim.messages.qos`), /diagnostics and other publishers often 10,
best-effort /clock nothing.  A longer stall loses the rest (measured in
``benchmarks/recording_benchmark.py --stalls``; the summary says so when it happens).

Subscriptions on rclpy's EventsExecutor.  Each topic is an ordinary subscription, raw (CDR
bytes, never deserialised), whose callback takes the message info with it (reception and
source timestamps, publication sequence number); rclpy's EventsExecutor
(``rclpy.experimental``) dispatches them from C++, where the SingleThreadedExecutor's
Python wait loop costs tens of microseconds a message, much of a core for the node's
topics at 1 kHz.  The main thread spins it in slices of :data:`_SLICE` s and between two
slices writes what came, flushes, looks for topics and for a stop.

What is written.  Each message's bag (log) time is its receive time: the DDS reception
timestamp (system clock), or with ``use_sim_time`` the latest /clock received (messages
received before the first /clock get its time; 0 if none ever comes).  Messages are written
in the order of their log times (an MCAP file without index, a killed recorder's, must be in
time order for rosbags to read it): held back :data:`_ORDER_MARGIN` after their reception
stamp, so that one received earlier on another topic and dispatched later still comes
before them; one dispatched later than that is written at the last time written.  MCAP also
keeps the publisher's source timestamp (publish time) and its publication sequence number
(sequence), so a reader can count what was lost: the summary does, per topic, as gaps in
the sequence numbers (meaningful for one publisher per topic).
The offered QoS profiles stored per topic are those discovery reports, as ``ros2 bag
record`` stores them.

Killed.  Every `flush_period` (default 0.25 s) the bag is flushed (see
:meth:`BagWriter.flush`): after SIGKILL the bag reads as it is, up to the last flush;
``rigid-body-sim record --recover BAG`` rewrites it into a complete bag.
"""

from dataclasses import dataclass
from dataclasses import field
import importlib
import inspect
import math
import re
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from rosgraph_msgs.msg import Clock

from .bag_writer import BagWriter
from .bag_writer import CUSTOM_DATA_PREFIX
from .bag_writer import fsync_file
from .bag_writer import offered_qos
from .bag_writer import qos_from_profile
from .signals import StopOnSignals
from .simulate import absolute_namespace
from .simulate import CLOCK_TOPIC
from .simulate import DIAGNOSTICS_TOPIC
from .simulate import message_type_name
from .simulate import topic_names
from ..messages import qos
from ..messages.bodies import BODY_TOPICS
from ..messages.bodies import MARKERS_TOPIC
from ..messages.state import STATE_TYPES

__all__ = ['NODE_NAME', 'RecordingSummary', 'default_topics', 'record']

NODE_NAME = 'rigid_body_recorder'
"""Name of the recorder's node."""

_SLICE = 0.05
"""Seconds the executor dispatches messages before the recorder writes, flushes, looks for
topics and for a stop."""
_ORDER_MARGIN = 20_000_000
"""How long (ns) after its DDS reception stamp a message's callback has surely run (the
messages received before are written then, in time order)."""
# What a node of bodies publishes under its namespace: each body's topics and the markers,
# by type name (a topic of the right name and another type is not the node's).
_BODY_TOPIC_TYPES = {**{topic: message_type_name(STATE_TYPES[topic]) for topic in BODY_TOPICS},
                     'imu': 'sensor_msgs/msg/Imu'}
_BODY_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*')
# How often topics of yet unknown type are looked up in the ROS graph.
_DISCOVERY_PERIOD = 0.5  # s


def default_topics(namespace=''):
    """
    Return absolute topic -> (message class, publisher QoS) of what the node publishes.

    The state topics under `namespace`, /diagnostics and /clock.
    """
    topics = {name: (STATE_TYPES[topic], qos.STATE_QOS)
              for topic, name in topic_names(namespace).items()}
    topics[DIAGNOSTICS_TOPIC] = (DiagnosticArray, qos.DIAGNOSTICS_QOS)
    topics[CLOCK_TOPIC] = (Clock, qos.CLOCK_QOS)
    return topics


@dataclass
class RecordingSummary:
    """
    Messages recorded per topic, losses seen in sequence numbers, time and CPU used.

    `longest_pause` is the longest time (s) between two slices of the executor's
    dispatching, `longest_flush` the longest flush.
    """

    bag: object
    counts: dict
    lost: dict
    wall_time: float
    cpu_time: float
    longest_pause: float = 0.0
    longest_flush: float = 0.0
    missing: list = field(default_factory=list)

    def __post_init__(self):
        """Hold the missing topics as a list."""
        self.missing = list(self.missing)

    @property
    def cpu_fraction(self):
        """Return the recorder's CPU time per wall-clock second (1.0 = one core)."""
        return self.cpu_time / self.wall_time if self.wall_time > 0.0 else 0.0

    def __str__(self):
        lines = [f'{self.bag}: {sum(self.counts.values())} messages on {len(self.counts)} '
                 f'topics in {self.wall_time:.1f} s, CPU {100.0 * self.cpu_fraction:.1f}% '
                 f'of a core; longest pause in dispatching {1e3 * self.longest_pause:.0f} '
                 f'ms, longest flush {1e3 * self.longest_flush:.0f} ms']
        for topic, count in self.counts.items():
            lost = self.lost.get(topic)
            seen = 'lost: n/a' if lost is None else f'lost (sequence gaps): {lost}'
            lines.append(f'  {topic}: {count} ({seen})')
        if any(self.lost.values()):
            lines.append('  messages lost: a pause in dispatching (the longest above) longer '
                         "than the subscriptions' queue holds (--depth messages a topic), or a "
                         "stall of this process longer than the publishers' history covers "
                         "(Fast DDS's shared-memory queue holds 512 samples, ~85 ms at 1 kHz; "
                         "the node's state publishers resend their last 1000, 1 s at 1 kHz); "
                         'see the README')
        if self.missing:
            lines.append(f'  no message received (not in the bag): {", ".join(self.missing)}')
        return '\n'.join(lines)


@dataclass(eq=False)
class _Topic:
    """One recorded topic: its subscription, bag connection and loss count."""

    name: str
    type_name: str
    message_class: type
    publisher_qos: list
    recorded: bool = True
    subscription: object = field(default=None, init=False)
    connection: object = field(default=None, init=False)
    last_sequence: int = field(default=None, init=False)
    lost: int = field(default=0, init=False)
    count: int = field(default=0, init=False)


def _log_time(item):
    return item[0]


def _message_class(type_name):
    """Return the message class of a type name such as 'geometry_msgs/msg/PoseStamped'."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


def _subscription_qos(reliability, durability, depth):
    return QoSProfile(reliability=reliability, durability=durability,
                      history=HistoryPolicy.KEEP_LAST, depth=depth)


# What rclpy reads from a callback's signature to pass the message info with the message.
_MESSAGE_AND_INFO = inspect.Signature([
    inspect.Parameter(name, inspect.Parameter.POSITIONAL_ONLY) for name in ('message', 'info')])


def _receiver(keep, topic):
    """
    Return a subscription callback that calls ``keep(topic, data, info)`` for each message.

    Its signature takes (message, info), which tells rclpy to pass the message info;
    rclpy's EventsExecutor (7.1.x) then calls it with one (message, info) tuple instead of
    two arguments (the SingleThreadedExecutor passes two): both are taken.
    """
    def receive(*received):
        if len(received) == 1:
            received = received[0]
        keep(topic, *received)
    receive.__signature__ = _MESSAGE_AND_INFO
    return receive


class _Recorder:
    """The subscriptions and what they received, written in time order; see :func:`record`."""

    def __init__(self, node, writer, topics, namespace, depth, flush_period, sync,
                 use_sim_time, log, bodies=False):
        self.node = node
        self.bodies = bodies
        self.body_topics = set()  # the topics found as a node of bodies' (logged together)
        self.namespace = absolute_namespace(namespace)
        self.writer = writer
        self.depth = depth
        self.flush_period = flush_period
        self.sync = sync
        self.use_sim_time = use_sim_time
        self.log = log
        self.topics = {}
        self.pending = []  # topic names whose type is not known yet
        # Received, not yet written: (log time, connection, data, publish time, sequence),
        # written once no earlier one can still come, in the order of their times.
        self.buffer = []
        self.written_until = -math.inf  # ns: the latest log time written
        self.sim_time = None  # ns, from /clock (use_sim_time): None before the first one
        self.first_sim_time = None  # ns, the first /clock's: the time of earlier messages
        self.refused_clocks = 0  # /clock messages that were not a time
        # The node's topics (in its namespace) are subscribed at once, with known types.
        known = default_topics(namespace)
        for name in topics:
            if name in known:
                message_class, publisher_qos = known[name]
                self._add(name, message_type_name(message_class), message_class,
                          publisher_qos)
            else:
                self.pending.append(name)
        if use_sim_time and CLOCK_TOPIC not in self.topics:
            # Read for the time, not recorded.
            self._add(CLOCK_TOPIC, message_type_name(Clock), Clock,
                      known[CLOCK_TOPIC][1], recorded=False)

    def _add(self, name, type_name, message_class, publisher_qos, recorded=True):
        topic = _Topic(name, type_name, message_class, publisher_qos, recorded)
        profile = _subscription_qos(publisher_qos.reliability, publisher_qos.durability,
                                    self.depth)
        topic.subscription = self.node.create_subscription(
            message_class, name, _receiver(self._keep, topic), profile, raw=True)
        self.topics[name] = topic

    def discover(self):
        """Subscribe to the pending topics whose type and publishers the graph now shows."""
        types = None
        if self.bodies:
            types = dict(self.node.get_topic_names_and_types())
            self._find_bodies(types)
        if not self.pending:
            return
        if types is None:
            types = dict(self.node.get_topic_names_and_types())
        bodies_added = []
        for name in list(self.pending):
            if name not in types:
                continue
            type_name = types[name][0]
            offers = self.node.get_publishers_info_by_topic(name)
            if not offers:
                continue
            reliable = all(info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                           for info in offers)
            transient = all(info.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                            for info in offers)
            publisher_qos = QoSProfile(
                reliability=(ReliabilityPolicy.RELIABLE if reliable
                             else ReliabilityPolicy.BEST_EFFORT),
                durability=(DurabilityPolicy.TRANSIENT_LOCAL if transient
                            else DurabilityPolicy.VOLATILE),
                history=HistoryPolicy.KEEP_LAST, depth=1)
            try:
                message_class = _message_class(type_name)
            except (ImportError, AttributeError, ValueError):
                self.log(f'cannot record {name}: message type {type_name} is not installed')
                self.pending.remove(name)
                continue
            self._add(name, type_name, message_class, publisher_qos)
            self.pending.remove(name)
            if name in self.body_topics:
                bodies_added.append(name)
            else:
                self.log(f'recording {name} ({type_name})')
        if bodies_added:
            # A node of a thousand bodies: one line, not five thousand.
            shown = ', '.join(bodies_added[:3]) + (', ...' if len(bodies_added) > 3 else '')
            self.log(f'recording {len(bodies_added)} topics of a node of bodies ({shown})')

    def _find_bodies(self, types):
        """Add to the pending topics those of a node of bodies in the namespace, as they come."""
        prefix = self.namespace + '/'
        for name, type_names in types.items():
            if name in self.topics or name in self.pending or not name.startswith(prefix):
                continue
            relative = name[len(prefix):]
            if relative == MARKERS_TOPIC:
                wanted = 'visualization_msgs/msg/MarkerArray'
            else:
                body, _, topic = relative.partition('/')
                wanted = _BODY_TOPIC_TYPES.get(topic) if _BODY_NAME.fullmatch(body) else None
            if wanted is not None and type_names == [wanted]:
                self.pending.append(name)
                self.body_topics.add(name)

    def write_received(self):
        """Write what was received, as far as no earlier message can still come."""
        if not self.use_sim_time:
            # A message received before now - margin has had its callback.
            self.write_buffered(time.time_ns() - _ORDER_MARGIN)
        elif self.sim_time is not None:
            self.write_buffered()

    def write_buffered(self, before=math.inf):
        """Write the messages received before `before` (ns), in time order."""
        buffer = self.buffer
        if not buffer:
            return
        if self.use_sim_time and buffer[0][0] < 0:
            # Received before the first /clock: they get its time (0 if none came), so the
            # bag stays in time order; the node publishes /clock only once it has seen a
            # subscriber, which under load can be seconds after the state topics matched.
            first = self.first_sim_time
            early = sum(1 for item in buffer if item[0] < 0)
            if first is None:
                self.log(f'no /clock received: the {early} message(s) received have bag time '
                         '0')
                first = 0
            else:
                self.log(f'{early} message(s) received before the first /clock are logged '
                         f'at its time, {first} ns')
            buffer[:] = [(first if item[0] < 0 else item[0],) + item[1:] for item in buffer]
        buffer.sort(key=_log_time)
        count = len(buffer)
        if buffer[-1][0] >= before:
            count = next(k for k, item in enumerate(buffer) if item[0] >= before)
        write = self.writer.write
        written_until = self.written_until
        for log_time, connection, data, publish_time, sequence in buffer[:count]:
            # One dispatched later than the margin: at the last time written, in order.
            written_until = max(written_until, log_time)
            write(connection, written_until, data, publish_time, sequence)
        self.written_until = written_until
        del buffer[:count]

    def _keep(self, topic, data, info):
        if topic.name == CLOCK_TOPIC and self.use_sim_time:
            # rosgraph_msgs/Clock in CDR: 4-byte encapsulation (its second byte 1: little
            # endian), int32 sec, uint32 nanosec.
            order = 'little' if len(data) > 1 and data[1] == 1 else 'big'
            seconds = int.from_bytes(data[4:8], order, signed=True)
            nanoseconds = int.from_bytes(data[8:12], order)
            if len(data) < 12 or seconds < 0 or nanoseconds >= 1_000_000_000:
                # Not a time (a peer's negative /clock): the bag time stays where it was,
                # and no message is taken for one received before the first /clock.
                self.refused_clocks += 1
                if self.refused_clocks == 1:
                    self.log(f'refused a /clock message that is not a time (sec {seconds}, '
                             f'nanosec {nanoseconds}): bag times stay at the last valid one; '
                             'the end says how many were refused')
            else:
                self.sim_time = seconds * 1_000_000_000 + nanoseconds
                if self.first_sim_time is None:
                    self.first_sim_time = self.sim_time
        if not topic.recorded:
            return
        if self.use_sim_time:
            log_time = self.sim_time
            if log_time is None:
                # Kept until the first /clock gives the time (see write_buffered).
                log_time = -1
        else:
            log_time = info.get('received_timestamp') or time.time_ns()
        if topic.connection is None:
            topic.connection = self.writer.add_topic(topic.name, topic.type_name,
                                                     self._offers(topic))
        sequence = info.get('publication_sequence_number')
        if sequence is not None:
            if topic.last_sequence is not None and sequence > topic.last_sequence + 1:
                topic.lost += sequence - topic.last_sequence - 1
            topic.last_sequence = sequence
        topic.count += 1
        self.buffer.append((log_time, topic.connection, data,
                            info.get('source_timestamp') or log_time, sequence or 0))

    def _offers(self, topic):
        # What discovery reports now, as ros2 bag record stores it; if the publisher is not
        # in the graph yet, what it reports for a publisher with this QoS.
        offers = [qos_from_profile(info.qos_profile)
                  for info in self.node.get_publishers_info_by_topic(topic.name)]
        return offers or [offered_qos(topic.publisher_qos)]

    def summary_counts(self):
        """Return (counts, lost) per recorded topic, in the order they were first seen."""
        recorded = [t for t in self.topics.values() if t.recorded and t.connection is not None]
        recorded.sort(key=lambda t: t.connection.id)
        counts = {t.name: t.count for t in recorded}
        lost = {}
        for t in recorded:
            publishers = len(self.node.get_publishers_info_by_topic(t.name))
            lost[t.name] = t.lost if t.last_sequence is not None and publishers <= 1 else None
        return counts, lost


def record(bag, topics=None, storage='mcap', namespace='', depth=30000, flush_period=0.25,
           sync=True, use_sim_time=False, duration=None, stop=None, log=None, ros_args=None,
           bodies=False):
    """
    Record topics into a new bag until stopped; return a :class:`RecordingSummary`.

    Parameters
    ----------
    bag : str or Path
        New bag directory.
    topics : sequence of str, optional
        Topic names; relative names are taken under `namespace`.  Default: the node's
        topics (:func:`default_topics`).
    storage : str
        'mcap' (default) or 'sqlite3'.
    namespace : str
        Namespace of the node whose topics are recorded ('' or '/name').
    depth : int
        Keep-last depth of each subscription's queue, in messages.
    flush_period : float
        Seconds between flushes; a killed recorder loses at most the last period.
    sync : bool
        fsync at each flush (against power loss; SIGKILL needs no fsync).
    use_sim_time : bool
        Bag times from /clock instead of the reception time.
    duration : float, optional
        Stop after this many seconds.
    stop : threading.Event, optional
        Stop when set.  In the main thread, SIGINT and SIGTERM also stop the recording.
    log : callable, optional
        Called with progress messages (default: print).
    ros_args : list of str, optional
        Arguments for rclpy.init (e.g. ['--ros-args', '-r', '__ns:=/rec']).
    bodies : bool
        Also record, as they appear (a body spawned later too), the topics of a node of
        bodies in `namespace`: every ``<namespace>/<name>/pose``, ``twist``,
        ``angular_momentum``, ``odom`` and ``imu`` of its type, and ``<namespace>/markers``.

    Raises
    ------
    ValueError
        For an existing bag, a bad storage, depth or flush period.

    """
    if depth < 1:
        raise ValueError(f'depth must be >= 1; got {depth}')
    if not flush_period > 0.0:
        raise ValueError(f'flush period must be > 0 s; got {flush_period}')
    if duration is not None and not duration > 0.0:
        raise ValueError(f'duration must be > 0 s; got {duration}')
    log = log or print
    stop = stop or threading.Event()
    names = _absolute_topics(topics, namespace)
    writer = BagWriter(bag, storage)
    context = rclpy.Context()
    rclpy.init(args=ros_args, context=context,
               signal_handler_options=SignalHandlerOptions.NO)
    signals = StopOnSignals(stop)
    signals.install()
    node = None
    executor = None
    syncer = None
    started = time.monotonic()
    cpu_started = time.process_time()
    try:
        executor = EventsExecutor(context=context)
        # The executor catches SIGINT and SIGTERM itself (asio's signal set, which shuts the
        # context down): ours are put back in front of it.
        signals.restore()
        signals.install()
        node = Node(NODE_NAME, context=context, start_parameter_services=False)
        writer.create()
        writer.set_custom_data(CUSTOM_DATA_PREFIX + 'writer', 'rigid-body-sim record')
        recorder = _Recorder(node, writer, names, namespace, depth, flush_period, sync,
                             use_sim_time, log, bodies=bodies)
        executor.add_node(node)
        log(f'recording {", ".join(names)} into {writer.path} ({storage}); Ctrl-C to stop')
        next_flush = started + flush_period
        next_discovery = started
        end = math.inf if duration is None else started + duration
        # Longest time between two slices of dispatching (writing, flushing, discovery), and
        # longest flush: a queue of `depth` messages at rate r overflows after depth / r s
        # without dispatching.
        longest_pause = longest_flush = 0.0
        syncer = _Syncer(writer) if sync and storage == 'mcap' else None
        dispatched = time.monotonic()
        while not stop.is_set() and context.ok():
            now = time.monotonic()
            longest_pause = max(longest_pause, now - dispatched)
            if now >= end:
                break
            _dispatch(executor, min(_SLICE, end - now))
            dispatched = time.monotonic()
            if dispatched >= next_discovery:
                recorder.discover()
                next_discovery = dispatched + _DISCOVERY_PERIOD
            recorder.write_received()
            if time.monotonic() >= next_flush:
                flush_started = time.monotonic()
                # To the OS here (enough against SIGKILL); the fsync against power loss runs
                # in a thread of its own, as it can take a slow disk tens of milliseconds.
                writer.flush(sync=False)
                if syncer is not None:
                    syncer.request()
                next_flush = time.monotonic() + flush_period
                longest_flush = max(longest_flush, next_flush - flush_period - flush_started)
        # What arrived up to the stop is recorded too: its callbacks have run within the
        # order margin.
        if context.ok():
            _dispatch(executor, 1e-9 * _ORDER_MARGIN)
        recorder.write_buffered()
        if recorder.refused_clocks:
            recorder.log(f'{recorder.refused_clocks} /clock message(s) refused in all: not a '
                         'time (bag times did not follow them)')
        counts, lost = recorder.summary_counts()
        missing = [name for name in names if name not in counts]
    finally:
        if executor is not None:
            # The executor lets go of the node's callbacks before the node is destroyed.
            if node is not None:
                executor.remove_node(node)
            executor.shutdown()
        signals.restore()
        if syncer is not None:
            syncer.stop()
        writer.close()
        if sync:
            fsync_file(writer.storage_file)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    return RecordingSummary(writer.path, counts, lost, time.monotonic() - started,
                            time.process_time() - cpu_started, longest_pause, longest_flush,
                            missing)


def _dispatch(executor, seconds):
    """Let `executor` dispatch callbacks for `seconds` s."""
    # (The EventsExecutor of rclpy 7.1 spins for a time only until a future completes: one
    # that never does.)
    executor.spin_until_future_complete(Future(), timeout_sec=seconds)


class _Syncer:
    """A thread that fsyncs the bag's storage file whenever asked."""

    def __init__(self, writer):
        self._writer = writer
        self._wanted = threading.Event()
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name='fsync', daemon=True)
        self._thread.start()

    def request(self):
        """Ask for an fsync (one pending request covers any number)."""
        self._wanted.set()

    def stop(self):
        """Finish the pending fsync, if any, and end the thread."""
        self._stopping = True
        self._wanted.set()
        self._thread.join()

    def _run(self):
        while True:
            self._wanted.wait()
            self._wanted.clear()
            if self._stopping:
                return
            self._writer.sync_to_disk()


def _absolute_topics(topics, namespace):
    if not topics:
        return list(default_topics(namespace))
    namespace = absolute_namespace(namespace)
    names = []
    for topic in topics:
        name = topic if topic.startswith('/') else f'{namespace}/{topic}'
        if name not in names:
            names.append(name)
    return names

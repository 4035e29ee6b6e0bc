"""
The live recorder against the running node: nothing lost, clean finish, survives SIGKILL.

The node and the recorder run as subprocesses (``python -m rigid_body_sim.node.entry_point``
and ``python -m rigid_body_sim.cli record``) in a ROS domain of this test process's own, on the
loopback.  What the node published is known from the messages themselves: its publisher
numbers every message (the publication sequence number the recorder stores in each MCAP
message), and with ``publish_clock`` it stamps tick k with k / rate exactly; so between the
first and the last message recorded on a topic, received == published exactly when the
sequence numbers and the stamps have no gap.
"""

import inspect
import math
import re
import signal
import time
import types
import warnings

from geometry_msgs.msg import PoseStamped

from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.records import Message
from mcap.stream_reader import breakup_chunk
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import RecorderProcess
from node_harness import unique_namespace
import numpy as np
import pytest
import rclpy
from rclpy.qos import DurabilityPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rigid_body_sim.recording.bag_writer import storage_file
from rigid_body_sim.recording.recorder import _receiver
from rigid_body_sim.recording.recorder import _Recorder
from rigid_body_sim.recording.recovery import bag_is_complete
from rigid_body_sim.recording.recovery import recover_bag
from rigid_body_sim.recording.simulate import simulate_to_bag
from rigid_body_sim.scenes import load_scene
from rosbags.interfaces import QosDurability
from rosbags.interfaces import QosReliability
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.errors import ReaderError
from std_msgs.msg import String

pytestmark = pytest.mark.xdist_group('node')

STATE_TOPICS = ('pose', 'twist', 'angular_momentum', 'odom', 'marker')
STAMPED = ('pose', 'angular_momentum', 'odom', 'marker')


def mcap_messages(path):
    """Return topic -> list of mcap Message records, in file order."""
    messages = {}
    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            messages.setdefault(channel.topic, []).append(message)
    return messages


def stamp_of(data):
    """Return the header stamp (ns) of a serialised stamped message (CDR, little-endian)."""
    seconds = int.from_bytes(data[4:8], 'little', signed=True)
    return seconds * 1_000_000_000 + int.from_bytes(data[8:12], 'little')


def assert_nothing_lost(messages, namespace, rate):
    """Per state topic: sequence numbers and (sim-time) stamps without a gap."""
    period = round(1e9 / rate)
    for topic in STATE_TOPICS:
        records = messages[f'{namespace}/{topic}']
        sequences = np.array([m.sequence for m in records])
        assert np.all(np.diff(sequences) == 1), \
            f'{topic}: {int(np.sum(np.diff(sequences) - 1))} lost of {np.ptp(sequences) + 1}'
        if topic in STAMPED:
            stamps = np.array([stamp_of(m.data) for m in records])
            assert np.all(np.diff(stamps) == period), f'{topic}: stamps with gaps'
        log_times = np.array([m.log_time for m in records])
        assert np.all(np.diff(log_times) >= 0)


def assert_logged_at_the_receive_time(messages, latched=()):
    """
    Each message's bag time is when it was received: after it was published, and soon.

    The publish time the recorder stores is the publisher's DDS source timestamp, the log
    time the reader's reception timestamp, both from the system clock of this one machine:
    so publish <= log exactly.  Over the loopback a sample arrives within a fraction of a
    millisecond (measured: median 0.1-0.4 ms, longest 8 ms, at 100 Hz), so the median delay
    is below one tick at the node's 100 Hz (10 ms);
    the longest is bounded by the recorder's order margin (20 ms), the longest a sample
    may take from its reception stamp to its reader's queue, plus what a loaded two-core
    machine takes to schedule the receive thread: 0.5 s, the longest stall the node itself
    catches up.  A log time taken when the message was written (every 2 ms at least, after
    the 20 ms margin) would lie 20 ms or more after the publish time: above the median bound.

    The `latched` topics (transient local, as /tf_static) are the exception: the node
    published their sample when it started, before the recorder, and DDS hands it over when
    the recorder subscribes, once its discovery (every 0.5 s) finds the topic: 0.5-1.2 s
    later, measured.  Logged when received, its log time lies strictly after its publish
    time (at it, were the publish time taken for the log time); how much after says how long
    discovery took, not the recorder's clock, so no upper bound.
    """
    for topic, records in messages.items():
        publish = np.array([m.publish_time for m in records], dtype=np.int64)
        log = np.array([m.log_time for m in records], dtype=np.int64)
        delay = log - publish
        assert np.all(delay >= 0), (topic, delay.min())
        if topic in latched:
            assert np.all(delay > 0), (topic, delay.min())
            continue
        assert np.all(delay < 500_000_000), (topic, delay.max())
        if len(records) >= 100:
            # A median over many (the 100 Hz topics; /diagnostics has a few, at 1 Hz).
            assert np.median(delay) < 10_000_000, (topic, np.median(delay))


def wait_until_ticking(node, timeout=120.0):
    """
    Wait until the node logged its start (recordings then wait for the counts they need).

    On a fresh clone the first node compiles the numba kernels, which on a busy machine
    takes longer than a short recording: a fixed sleep is not enough.
    """
    deadline = time.monotonic() + timeout
    while 'simulating scene' not in node.output():
        assert node.alive(), node.output()
        assert time.monotonic() < deadline, f'the node did not start:\n{node.output()}'
        time.sleep(0.1)  # waits-for: poll interval of the loop waiting for the start line


@pytest.fixture
def environment():
    """Isolate ROS discovery for this test process; return a fresh namespace."""
    isolate_ros_environment()
    return unique_namespace()


def recorded_counts(output):
    """Return topic -> (recorded, lost) as the recorder's summary printed them."""
    counts = {}
    for line in output.splitlines():
        match = re.fullmatch(r'  (\S+): (\d+) \(lost \(sequence gaps\): (\d+)\)', line)
        if match:
            counts[match[1]] = (int(match[2]), int(match[3]))
    return counts


@pytest.mark.slow
def test_recorder_loses_no_message_at_1_khz_over_30_s(tmp_path, environment):
    """
    The long one (about 35 s): five topics at 1 kHz, counted by the node's own numbers.

    Over the recording window of each reliable topic (its first to its last message in the
    bag) the node published last - first + 1 messages by its publisher's sequence numbers;
    the bag holds exactly that many, and for the stamped topics as many ticks as the
    simulated-time stamps span.  /clock is best effort (as every ROS clock): its losses
    are reported (a warning), not required to be none.
    """
    namespace = environment
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'rate': 1000.0, 'publish_clock': 'true'})
    bag = tmp_path / 'live'
    try:
        wait_until_ticking(node)
        recorder = RecorderProcess(tmp_path / 'recorder.log', bag, '--namespace', namespace,
                                   '--duration', '32')
        assert recorder.finish(timeout=120.0) == 0, recorder.output()
    finally:
        node.stop()
    messages = mcap_messages(storage_file(bag, 'mcap'))
    assert_nothing_lost(messages, namespace, 1000.0)
    printed = recorded_counts(recorder.output())
    with Reader(bag) as reader:
        in_metadata = {c.topic: c.msgcount for c in reader.connections}
    for topic in [f'{namespace}/{topic}' for topic in STATE_TOPICS] + ['/diagnostics']:
        records = messages[topic]
        sequences = np.array([m.sequence for m in records])
        published = int(sequences[-1] - sequences[0] + 1)
        assert len(records) == published == in_metadata[topic], (topic, recorder.output())
        assert printed[topic] == (published, 0), (topic, recorder.output())
        if topic.rsplit('/', 1)[1] in STAMPED:
            stamps = [stamp_of(records[0].data), stamp_of(records[-1].data)]
            assert (stamps[1] - stamps[0]) // 1_000_000 + 1 == published, topic
        if topic != '/diagnostics':
            # 32 s less discovery: about 30,000 messages at 1 kHz where the node keeps its
            # rate; on a loaded machine it misses ticks (21,616 of them published with both
            # cores taken by others, its log says so).  What this proves is that none of those
            # published is lost, over a recording of 10,000 at least.
            assert published >= 10000, (topic, recorder.output())
    assert len(messages['/diagnostics']) >= 28
    clock = np.array([m.sequence for m in messages['/clock']])
    assert np.all(np.diff(clock) > 0)
    clock_lost = int(clock[-1] - clock[0] + 1) - len(clock)
    assert printed['/clock'] == (len(clock), clock_lost)
    print(f'/clock (best effort): {len(clock)} recorded, {clock_lost} lost')
    if clock_lost:
        warnings.warn(f'/clock (best effort) lost {clock_lost} of {clock[-1] - clock[0] + 1} '
                      'at 1 kHz (allowed: best effort)')
    assert bag_is_complete(bag)


@pytest.fixture(scope='module')
def node_100_hz(tmp_path_factory):
    """Run a node at 100 Hz with /clock for the shorter tests; yield its namespace."""
    isolate_ros_environment()
    namespace = unique_namespace()
    node = NodeProcess(tmp_path_factory.mktemp('node') / 'node.log', namespace=namespace,
                       parameters={'rate': 100.0, 'publish_clock': 'true'})
    wait_until_ticking(node)
    yield namespace
    node.stop()


@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_finish_a_complete_bag(tmp_path, node_100_hz, signal_number):
    namespace = node_100_hz
    bag = tmp_path / 'stopped'
    recorder = RecorderProcess(tmp_path / 'recorder.log', bag, '--namespace', namespace)
    recorder.wait_until_recording(bag)
    recorder.wait_for_counts(bag, {f'{namespace}/pose': 100})
    recorder.process.send_signal(signal_number)
    assert recorder.finish() == 0, recorder.output()
    assert bag_is_complete(bag)
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        read = {}
        for connection, _, _ in reader.messages():
            read[connection.topic] = read.get(connection.topic, 0) + 1
        offers = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    assert counts == read
    assert counts[f'{namespace}/pose'] >= 100
    (offer,) = offers[f'{namespace}/pose']
    assert (offer.reliability, offer.durability) == (QosReliability.RELIABLE,
                                                     QosDurability.VOLATILE)
    (clock_offer,) = offers['/clock']
    assert clock_offer.reliability == QosReliability.BEST_EFFORT
    messages = mcap_messages(storage_file(bag, 'mcap'))
    assert_nothing_lost(messages, namespace, 100.0)
    latched = [topic for topic, (offer, *_) in offers.items()
               if offer.durability == QosDurability.TRANSIENT_LOCAL]
    assert latched == ['/tf_static'], offers
    assert_logged_at_the_receive_time(messages, latched)
    assert f'{namespace}/pose: {counts[f"{namespace}/pose"]} (lost' in recorder.output()
    # The node's topics in its namespace are subscribed at once, not found by discovery.
    assert f'recording {namespace}/pose (' not in recorder.output()


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_recorder_killed_with_sigkill_leaves_a_readable_bag_that_recovers(
        tmp_path, node_100_hz, storage):
    namespace = node_100_hz
    bag = tmp_path / 'killed'
    recorder = RecorderProcess(tmp_path / 'recorder.log', bag, '--namespace', namespace,
                               '--storage', storage, '--flush-period', '0.2')
    recorder.wait_until_recording(bag)
    recorder.wait_for_counts(bag, {f'{namespace}/pose': 150})
    recorder.process.kill()
    recorder.finish()
    assert not bag_is_complete(bag)
    # Readable as it is, up to the last flush (0.2 s at most before the kill).
    with Reader(bag) as reader:
        before = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    poses = [item for item in before if item[0] == f'{namespace}/pose']
    assert len(poses) >= 150
    if storage == 'mcap':
        by_mcap = mcap_messages(storage_file(bag, 'mcap'))
        assert sum(len(m) for m in by_mcap.values()) == len(before)
        assert_nothing_lost(by_mcap, namespace, 100.0)
    summary = recover_bag(bag)
    assert bag_is_complete(bag) and (tmp_path / 'killed.orig').is_dir()
    with Reader(bag) as reader:
        after = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
        assert reader.message_count == len(after) == sum(summary.counts.values())
    assert sorted(after) == sorted(before)


def test_use_sim_time_logs_messages_at_the_simulated_time(tmp_path, node_100_hz):
    namespace = node_100_hz
    bag = tmp_path / 'sim_time'
    recorder = RecorderProcess(tmp_path / 'recorder.log', bag, '--namespace', namespace,
                               '--use-sim-time')
    # Until the flushed metadata counts 2 s of /clock and of poses: an event, however long
    # discovery takes on a loaded machine (a fixed --duration missed the poses there).
    recorder.wait_for_counts(bag, {'/clock': 200, f'{namespace}/pose': 200})
    recorder.process.send_signal(signal.SIGINT)
    assert recorder.finish() == 0, recorder.output()
    messages = mcap_messages(storage_file(bag, 'mcap'))
    clock = messages['/clock']
    clock_times = np.array([stamp_of(m.data) for m in clock])
    # /clock is logged at its own value.
    np.testing.assert_array_equal([m.log_time for m in clock], clock_times)
    poses = messages[f'{namespace}/pose']
    stamps = np.array([stamp_of(m.data) for m in poses])
    log_times = np.array([m.log_time for m in poses])
    # Every message is logged at a /clock value: the latest taken before it, or the first
    # one for those taken before any /clock came (the node publishes /clock only once it
    # has seen the recorder's subscription, which under load can be seconds after the
    # state topics matched); the recorder says how many those were.
    assert set(log_times) <= set(clock_times)
    assert np.all(np.diff(log_times) >= 0)
    early = stamps < clock_times[0]
    said = re.search(r'(\d+) message\(s\) received before the first /clock are logged at its '
                     r'time, (\d+) ns', recorder.output())
    if said is not None:
        assert int(said.group(2)) == clock_times[0], recorder.output()
    # After the first /clock, a pose is logged at its own tick's /clock (the node publishes
    # /clock first), or at an earlier one when it was dispatched before its tick's /clock
    # (the two topics' callbacks come in the order their readers signalled them): by at
    # most the longest pause in dispatching (which the recorder reports) and a tick; later
    # when it waited in the queue, by at most the queue's depth (5000 ticks: a keep-last
    # queue drops anything older) - on a loaded machine the recorder can fall a second or
    # more behind, so no tighter bound holds.
    pause = int(re.search(r'longest pause in dispatching (\d+) ms', recorder.output()).group(1))
    lag = (log_times - stamps)[~early]
    # (+1 ms: the report rounds to whole ms.)
    assert lag.size and np.all(lag >= -(pause + 11) * 1_000_000), (lag.min(), pause)
    assert np.all(lag <= 5000 * 10_000_000), lag.max()


class TopicPublisher:
    """
    Publishers in this test process (a context of their own): std_msgs/String messages.

    Each message's data is its number (0, 1, 2, ...) on its topic, so what was received
    can be compared with what was published, message by message.
    """

    def __init__(self, topics):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('test_publisher', context=self.context)
        self.publishers = {topic: self.node.create_publisher(String, topic, profile)
                           for topic, profile in topics.items()}
        self.published = dict.fromkeys(topics, 0)

    def publish(self, topic):
        """Publish the next number on `topic`."""
        self.publishers[topic].publish(String(data=str(self.published[topic])))
        self.published[topic] += 1

    def close(self):
        """Destroy the node and release the context."""
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def test_topics_the_node_does_not_publish_are_found_by_discovery_with_their_qos(
        tmp_path, environment):
    """
    Record only foreign topics, found by discovery with the publishers' QoS.

    The recorder starts with nothing to subscribe (no wait on an empty wait set), finds the
    topics by discovery and matches their QoS: a best-effort one, and a transient-local one
    whose message was published before the recorder started (only a transient-local
    subscription receives it).
    """
    namespace = environment
    best_effort, latched = f'{namespace}/best_effort_count', f'{namespace}/latched_count'
    publisher = TopicPublisher({
        best_effort: QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT),
        latched: QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)})
    bag = tmp_path / 'foreign'
    try:
        publisher.publish(latched)
        recorder = RecorderProcess(tmp_path / 'recorder.log', bag, best_effort, latched,
                                   f'{namespace}/nobody_publishes')
        # Until the flushed metadata counts both topics: an event, however long discovery
        # takes (a fixed --duration 6 missed the latched topic once in a full run).
        deadline = time.monotonic() + 120.0
        while not recorder.has_counts(bag, {best_effort: 100, latched: 1}):
            assert recorder.process.poll() is None, recorder.output()
            assert time.monotonic() < deadline, \
                f'flushed counts {recorder.flushed_counts(bag)}\n{recorder.output()}'
            publisher.publish(best_effort)
            time.sleep(0.01)  # waits-for: pace of the publisher while the recorder runs
        recorder.process.send_signal(signal.SIGINT)
        assert recorder.finish() == 0, recorder.output()
    finally:
        publisher.close()
    assert bag_is_complete(bag)
    with Reader(bag) as reader:
        offers = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
        received = {}
        for connection, _, raw in reader.messages():
            message = deserialize_message(bytes(raw), String)
            received.setdefault(connection.topic, []).append(int(message.data))
    assert set(offers) == {best_effort, latched}
    (offer,) = offers[best_effort]
    assert offer.reliability == QosReliability.BEST_EFFORT
    (offer,) = offers[latched]
    assert (offer.reliability, offer.durability) == (QosReliability.RELIABLE,
                                                     QosDurability.TRANSIENT_LOCAL)
    assert received[latched] == [0]
    # Best effort may drop some, never reorders or invents: increasing numbers, all
    # published; the recorder ran until the flushed bag held 100 of them.
    numbers = received[best_effort]
    assert len(numbers) >= 100 and np.all(np.diff(numbers) > 0)
    assert numbers[-1] < publisher.published[best_effort]
    assert f'recording {best_effort} (std_msgs/msg/String)' in recorder.output()
    assert f'no message received (not in the bag): {namespace}/nobody_publishes' in \
        recorder.output()


def _messages_in_complete_chunks(path, cut):
    """Return the Message records of the chunks that end before byte `cut`, in file order."""
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
        messages = []
        for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            if index.chunk_start_offset + index.chunk_length > cut:
                break
            # Past the record's opcode (1 byte) and length (8 bytes).
            stream.seek(index.chunk_start_offset + 1 + 8)
            chunk = Chunk.read(ReadDataStream(stream))
            messages += [r for r in breakup_chunk(chunk) if isinstance(r, Message)]
    return messages


def test_an_mcap_cut_anywhere_is_recovered_up_to_its_last_complete_chunk(tmp_path):
    source = tmp_path / 'source'
    simulate_to_bag(load_scene('default'), source, 6.0, rate=1000.0, clock=True)
    data = storage_file(source, 'mcap').read_bytes()
    rng = np.random.default_rng(11)
    cuts = sorted(rng.integers(100, len(data) - 1, size=6)) + [len(data) - 20, 60]
    for number, cut in enumerate(cuts):
        bag = tmp_path / f'cut{number}'
        bag.mkdir()
        storage_file(bag, 'mcap').write_bytes(data[:cut])
        (bag / 'metadata.yaml').write_bytes((source / 'metadata.yaml').read_bytes())
        # As documented: rosbags cannot open a cut file (no footer).
        with pytest.raises(ReaderError):
            with Reader(bag) as reader:
                list(reader.messages())
        expected = _messages_in_complete_chunks(storage_file(source, 'mcap'), cut)
        summary = recover_bag(bag)
        assert summary.truncated
        assert bag_is_complete(bag)
        recovered = [m for ms in mcap_messages(storage_file(bag, 'mcap')).values() for m in ms]
        order = lambda message: (message.log_time, message.channel_id)  # noqa: E731
        assert len(recovered) == len(expected), cut
        for got, want in zip(sorted(recovered, key=order), sorted(expected, key=order)):
            assert (got.log_time, got.data) == (want.log_time, want.data)


def test_recover_refuses_a_complete_bag_and_a_missing_one(tmp_path):
    bag = tmp_path / 'complete'
    simulate_to_bag(load_scene('default'), bag, 0.5)
    with pytest.raises(ValueError, match='complete bag already'):
        recover_bag(bag)
    with pytest.raises(ValueError, match='not a bag directory'):
        recover_bag(tmp_path / 'nothing')
    assert recover_bag(bag, force=True).counts['/pose'] == 50


def test_a_message_info_callback_takes_both_calls_rclpy_executors_make():
    """
    (message, info) as two arguments (SingleThreadedExecutor) or one tuple (EventsExecutor).

    rclpy reads the signature to decide whether to pass the info: it must ask for it.
    """
    kept = []
    receive = _receiver(lambda topic, data, info: kept.append((topic, data, info)), 'topic')
    assert list(inspect.signature(receive).parameters) == ['message', 'info']
    receive(b'data', {'received_timestamp': 1})
    receive((b'data', {'received_timestamp': 1}))
    assert kept == [('topic', b'data', {'received_timestamp': 1})] * 2


class _ListWriter:

    def __init__(self):
        self.written = []

    def write(self, connection, log_time, data, publish_time, sequence):
        self.written.append((log_time, data))


def test_a_message_dispatched_after_later_ones_were_written_keeps_the_bag_in_time_order():
    """One received before the last written but dispatched after it: at that last time."""
    recorder = _Recorder.__new__(_Recorder)
    recorder.writer = _ListWriter()
    recorder.use_sim_time = False
    recorder.written_until = -math.inf
    recorder.buffer = [(30, None, b'b', 30, 2), (10, None, b'a', 10, 1)]
    recorder.write_buffered(before=40)
    recorder.buffer = [(20, None, b'late', 20, 3), (50, None, b'c', 50, 4)]
    recorder.write_buffered()
    assert recorder.writer.written == [(10, b'a'), (30, b'b'), (30, b'late'), (50, b'c')]


def _clock_bytes(seconds, nanoseconds):
    """Return a rosgraph_msgs/Clock in CDR, little endian (what the recorder receives)."""
    return (b'\x00\x01\x00\x00' + seconds.to_bytes(4, 'little', signed=True)
            + nanoseconds.to_bytes(4, 'little'))


def test_a_clock_that_is_not_a_time_moves_no_bag_time_under_use_sim_time():
    """
    A /clock that is not a time is refused, said once, and counted.

    A peer's /clock {sec: -5} once set a negative bag time: the messages after it were
    logged as received before the first /clock.
    """
    recorder = _Recorder.__new__(_Recorder)
    recorder.use_sim_time = True
    recorder.sim_time = recorder.first_sim_time = None
    recorder.refused_clocks = 0
    said = []
    recorder.log = said.append
    clock = types.SimpleNamespace(name='/clock', recorded=False)
    recorder._keep(clock, _clock_bytes(-5, 0), {})
    assert recorder.sim_time is None and recorder.refused_clocks == 1
    recorder._keep(clock, _clock_bytes(12, 500), {})
    assert recorder.sim_time == recorder.first_sim_time == 12_000_000_500
    recorder._keep(clock, _clock_bytes(3, 1_000_000_000), {})
    recorder._keep(clock, _clock_bytes(-1, 0), {})
    assert recorder.sim_time == 12_000_000_500 and recorder.refused_clocks == 3
    assert len(said) == 1 and 'refused a /clock message' in said[0], said


def test_messages_after_a_refused_clock_keep_the_last_valid_time_not_the_first_clocks():
    """
    Under use_sim_time a negative /clock leaves the messages after it at the valid time.

    It once made their bag time negative, which marks a message received before the first
    /clock: the six received after /clock 10 s were logged "before the first /clock".  Only
    the one message received before any valid /clock is, at the first /clock's time.
    """
    recorder = _Recorder.__new__(_Recorder)
    recorder.use_sim_time = True
    recorder.sim_time = recorder.first_sim_time = None
    recorder.refused_clocks = 0
    recorder.buffer = []
    recorder.written_until = -math.inf
    recorder.writer = _ListWriter()
    said = []
    recorder.log = said.append
    clock = types.SimpleNamespace(name='/clock', recorded=False)
    pose = types.SimpleNamespace(name='/pose', recorded=True, connection='pose',
                                 last_sequence=None, lost=0, count=0)
    recorder._keep(clock, _clock_bytes(-5, 0), {})
    recorder._keep(pose, b'early', {})
    recorder._keep(clock, _clock_bytes(10, 0), {})
    for k in range(6):
        recorder._keep(pose, b'after %d' % k, {})
    recorder._keep(clock, _clock_bytes(-1, 0), {})
    recorder._keep(pose, b'after the second refused', {})
    recorder.write_received()
    ten = 10_000_000_000
    assert recorder.writer.written == [(ten, b'early')] + [
        (ten, b'after %d' % k) for k in range(6)] + [(ten, b'after the second refused')]
    early = [line for line in said if 'before the first /clock' in line]
    assert early == [f'1 message(s) received before the first /clock are logged at its '
                     f'time, {ten} ns'], said


def test_record_takes_every_body_topic_of_a_node_of_bodies_without_losing_any(
        tmp_path, environment):
    """
    By default, record finds and records each body's topics of a node of bodies.

    The juggler's clubs in a namespace: every club's pose, twist, angular_momentum, odom
    and imu, the MarkerArray and /tf, found by discovery (no topic named on the command
    line); with publish_clock each pose is stamped k / rate, so consecutive stamps one tick
    apart on every club's pose prove none was lost between the first and last recorded.
    """
    namespace = environment
    clubs = [member.name for member in load_scene('juggling_clubs').members]
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'scene': 'juggling_clubs', 'publish_clock': True})
    bag = tmp_path / 'clubs'
    try:
        wait_until_ticking(node)
        recorder = RecorderProcess(tmp_path / 'recorder.log', bag, '--namespace', namespace)
        wanted = {f'{namespace}/{club}/{topic}': 100 for club in clubs
                  for topic in ('pose', 'twist', 'angular_momentum', 'odom', 'imu')}
        wanted[f'{namespace}/markers'] = 100
        wanted['/tf'] = 100
        recorder.wait_for_counts(bag, wanted)
        recorder.process.send_signal(signal.SIGINT)
        assert recorder.finish() == 0, recorder.output()
    finally:
        node.stop()
    assert bag_is_complete(bag)
    with Reader(bag) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        poses = {}
        for connection, _, raw in reader.messages():
            if connection.topic.endswith('/pose'):
                message = deserialize_message(bytes(raw), PoseStamped)
                stamp = message.header.stamp.sec * 10**9 + message.header.stamp.nanosec
                poses.setdefault(connection.topic, []).append(stamp)
    assert set(wanted) <= set(topics)
    assert topics[f'{namespace}/markers'] == 'visualization_msgs/msg/MarkerArray'
    assert topics[f'{namespace}/{clubs[0]}/imu'] == 'sensor_msgs/msg/Imu'
    for club in clubs:
        stamps = np.array(poses[f'{namespace}/{club}/pose'])
        assert len(stamps) >= 100
        assert np.all(np.diff(stamps) == 10_000_000), club  # 100 Hz, none lost
    assert 'topics of a node of bodies' in recorder.output()

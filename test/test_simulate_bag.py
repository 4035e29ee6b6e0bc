"""
Offline simulation into rosbag2 bags: what is in them, read back by two independent readers.

The bags are read with rosbags (its Reader and typestore) and, independently, with the
``mcap`` library and mcap-ros2-support's decoder.  Expectations follow from the node's
contract: one state message per topic per tick, stamped start + k / rate; and from the
physics: without torque about the COM, the integrators leave L untouched (L <- L + h tau
with tau = 0), so every angular_momentum message equals L(0) exactly.
"""

import contextlib
import json
import math
from pathlib import Path
import signal
import sqlite3
import subprocess
import sys
import time

from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import Vector3Stamped
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from nav_msgs.msg import Odometry
from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import PACKAGE_ROOT
from node_harness import unique_namespace
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from rigid_body_sim.cli import main as cli_main
from rigid_body_sim.messages import qos
from rigid_body_sim.messages.diagnostics import NODE_NAME
from rigid_body_sim.messages.marker import marker_geometry
from rigid_body_sim.messages.marker import marker_geometry_from_drawing
from rigid_body_sim.messages.state import STATE_TOPICS
from rigid_body_sim.messages.state import StateSerializer
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import State
from rigid_body_sim.physics.effects import EFFECTS
from rigid_body_sim.recording.bag_writer import INFINITE_DURATION
from rigid_body_sim.recording.bag_writer import offered_qos
from rigid_body_sim.recording.bag_writer import qos_from_profile
from rigid_body_sim.recording.bag_writer import typestore
from rigid_body_sim.recording.recovery import bag_is_complete
from rigid_body_sim.recording.simulate import simulate_to_bag
from rigid_body_sim.recording.simulate import stamp_nanoseconds
from rigid_body_sim.recording.state_batch import BatchSerializer
from rigid_body_sim.recording.state_batch import StateBatch
from rigid_body_sim.scenes import load_scene
from rosbags.interfaces import QosDurability
from rosbags.interfaces import QosHistory
from rosbags.interfaces import QosReliability
from rosbags.rosbag2 import Reader
from rosbags.rosbag2 import ReaderError
from visualization_msgs.msg import Marker
import yaml

STATE_TYPES = {'pose': PoseStamped, 'twist': Twist, 'angular_momentum': Vector3Stamped,
               'odom': Odometry, 'marker': Marker}
TYPE_NAMES = {'/pose': 'geometry_msgs/msg/PoseStamped', '/twist': 'geometry_msgs/msg/Twist',
              '/angular_momentum': 'geometry_msgs/msg/Vector3Stamped',
              '/odom': 'nav_msgs/msg/Odometry', '/marker': 'visualization_msgs/msg/Marker',
              '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
              '/clock': 'rosgraph_msgs/msg/Clock', '/imu': 'sensor_msgs/msg/Imu',
              '/tf': 'tf2_msgs/msg/TFMessage', '/tf_static': 'tf2_msgs/msg/TFMessage'}
STAMPED = ('/pose', '/angular_momentum', '/odom', '/marker')
# The installed interfaces' share folder: the venv's (the wheels install there).
SHARE = Path(sys.prefix) / 'share'


def stamp_of(message):
    """Return a header stamp in ns."""
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def custom_data(bag):
    """Return the custom_data of a bag's metadata.yaml (rosbags' Reader has no accessor)."""
    information = yaml.safe_load((bag / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    return information.get('custom_data') or {}


def read_rosbags(bag):
    """Return (reader facts, topic -> [(log time, message)]) read with rosbags."""
    store = typestore()
    messages = {}
    with Reader(bag) as reader:
        facts = {'connections': {c.topic: c for c in reader.connections},
                 'message_count': reader.message_count,
                 'custom': custom_data(bag)}
        for connection, log_time, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (log_time, store.deserialize_cdr(raw, connection.msgtype)))
    return facts, messages


def _flushed_poses(metadata):
    """Return the /pose count of a provisional metadata.yaml (0 if caught mid-write)."""
    try:
        info = yaml.safe_load(metadata.read_text())['rosbag2_bagfile_information']
        return next(entry['message_count'] for entry in info['topics_with_message_count']
                    if entry['topic_metadata']['name'] == '/pose')
    except (yaml.YAMLError, KeyError, TypeError, StopIteration):
        return 0


def read_mcap(path):
    """Return (channels by topic, topic -> [(log time, decoded message)]) read with mcap."""
    messages = {}
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        schemas = summary.schemas
        for _, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            messages.setdefault(channel.topic, []).append((message.log_time, decoded))
    return channels, schemas, messages


@pytest.fixture(scope='module')
def van_zon_bag(tmp_path_factory):
    """Van Zon & Schofield's torque-free body, 3.5 s at 1 kHz, from t = 12.5 s."""
    bag = tmp_path_factory.mktemp('bags') / 'van_zon'
    scene = load_scene('van_zon')
    summary = simulate_to_bag(scene, bag, 3.5, rate=1000.0, start_time=12_500_000_000,
                              clock=True)
    return bag, scene, summary


def test_counts_are_duration_times_rate_for_every_state_topic(van_zon_bag):
    bag, _, summary = van_zon_bag
    facts, messages = read_rosbags(bag)
    ticks = 3500
    for topic in ('/pose', '/twist', '/angular_momentum', '/odom', '/marker', '/imu',
                  '/clock', '/tf'):
        assert len(messages[topic]) == ticks, topic
        assert facts['connections'][topic].msgcount == ticks
    # /diagnostics once per simulated second: at 1, 2 and 3 s.
    assert len(messages['/diagnostics']) == 3
    # /tf_static once.
    assert len(messages['/tf_static']) == 1
    assert facts['message_count'] == 8 * ticks + 3 + 1 == sum(summary.message_counts.values())


def test_types_and_frames_are_the_nodes(van_zon_bag):
    bag, _, _ = van_zon_bag
    facts, messages = read_rosbags(bag)
    assert {t: c.msgtype for t, c in facts['connections'].items()} == TYPE_NAMES
    for topic in STAMPED:
        assert {m.header.frame_id for _, m in messages[topic]} == {'world'}, topic
    assert {m.child_frame_id for _, m in messages['/odom']} == {'body'}
    marker = messages['/marker'][0][1]
    assert (marker.ns, marker.id, marker.action) == ('rigid_body', 0, Marker.ADD)
    # Covariances are zero: the simulated state is exact.
    odom = messages['/odom'][0][1]
    assert not np.any(odom.pose.covariance) and not np.any(odom.twist.covariance)
    status = messages['/diagnostics'][0][1].status[0]
    assert (status.name, status.hardware_id) == (f'{NODE_NAME}: simulation', f'/{NODE_NAME}')


def test_stamps_and_log_times_are_strictly_increasing_at_the_nominal_spacing(van_zon_bag):
    bag, _, _ = van_zon_bag
    _, messages = read_rosbags(bag)
    expected = 12_500_000_000 + 1_000_000 * np.arange(1, 3501)
    for topic in STAMPED:
        stamps = np.array([stamp_of(m) for _, m in messages[topic]])
        np.testing.assert_array_equal(stamps, expected, err_msg=topic)
        np.testing.assert_array_equal([t for t, _ in messages[topic]], expected)
    np.testing.assert_array_equal([t for t, _ in messages['/twist']], expected)
    clock = [m.clock.sec * 1_000_000_000 + m.clock.nanosec for _, m in messages['/clock']]
    np.testing.assert_array_equal(clock, expected)
    diagnostics = [stamp_of(m) for _, m in messages['/diagnostics']]
    assert diagnostics == [12_500_000_000 + k * 1_000_000_000 for k in (1, 2, 3)]


def test_stamps_of_a_rate_that_is_no_whole_number_of_nanoseconds_stay_within_1_ns():
    # 1e9 / 30 = 33333333.33 ns: rounded per tick, never accumulated.
    stamps = np.array([stamp_nanoseconds(0, k, 30.0) for k in range(1, 100001)])
    exact = np.arange(1, 100001) * (1e9 / 30.0)
    assert np.max(np.abs(stamps - exact)) <= 0.5 + 1e-6 * 1e-9 * exact.max()
    assert np.all(np.diff(stamps) > 0)
    vector = stamp_nanoseconds(7, np.arange(1, 100001), 30.0)
    np.testing.assert_array_equal(vector, stamps + 7)
    # A fractional rate goes the same way.
    fractional = stamp_nanoseconds(0, np.arange(1, 1001), 29.97)
    assert np.max(np.abs(fractional - np.arange(1, 1001) * 1e9 / 29.97)) <= 0.5


def test_mcap_reader_sees_the_same_messages_as_rosbags(van_zon_bag):
    bag, _, _ = van_zon_bag
    _, by_rosbags = read_rosbags(bag)
    channels, schemas, by_mcap = read_mcap(bag / 'van_zon.mcap')
    assert set(by_mcap) == set(by_rosbags)
    for topic, messages in by_rosbags.items():
        assert [t for t, _ in by_mcap[topic]] == [t for t, _ in messages], topic
    for (_, a), (_, b) in zip(by_rosbags['/odom'], by_mcap['/odom']):
        assert (a.pose.pose.orientation.w, a.twist.twist.angular.y) == (
            b.pose.pose.orientation.w, b.twist.twist.angular.y)
    for topic, channel in channels.items():
        assert channel.message_encoding == 'cdr'
        assert schemas[channel.schema_id].name == TYPE_NAMES[topic]
        assert schemas[channel.schema_id].encoding == 'ros2msg'


def test_type_hashes_are_those_of_the_installed_interfaces(van_zon_bag):
    bag, _, _ = van_zon_bag
    facts, _ = read_rosbags(bag)
    channels, _, _ = read_mcap(bag / 'van_zon.mcap')
    for topic, connection in facts['connections'].items():
        package, _, name = connection.msgtype.split('/')
        description = json.loads((SHARE / package / 'msg' / f'{name}.json').read_text())
        installed = description['type_hashes'][0]['hash_string']
        assert connection.digest == installed, topic
        assert channels[topic].metadata['topic_type_hash'] == installed


def test_offered_qos_is_what_discovery_reports_for_the_node_publishers(van_zon_bag):
    bag, _, _ = van_zon_bag
    facts, _ = read_rosbags(bag)
    channels, _, _ = read_mcap(bag / 'van_zon.mcap')
    for topic, connection in facts['connections'].items():
        (offer,) = connection.ext.offered_qos_profiles
        reliability = (QosReliability.BEST_EFFORT if topic == '/clock'
                       else QosReliability.RELIABLE)
        durability = (QosDurability.TRANSIENT_LOCAL if topic == '/tf_static'
                      else QosDurability.VOLATILE)
        assert (offer.history, offer.depth, offer.reliability, offer.durability) == (
            QosHistory.UNKNOWN, 0, reliability, durability), topic
        assert offer.deadline == offer.lifespan == offer.liveliness_lease_duration \
            == INFINITE_DURATION
        # In the MCAP channel: the same list as YAML text, policies by name (version 9).
        text = channels[topic].metadata['offered_qos_profiles']
        assert 'reliability: reliable' in text or 'reliability: best_effort' in text
    metadata = (bag / 'metadata.yaml').read_text()
    assert 'version: 9' in metadata and 'history: unknown' in metadata


def test_angular_momentum_read_from_the_bag_is_constant_in_torque_free_scenes(tmp_path):
    # (rk4 integrates the body momentum, so its world L moves at its order: not here.)
    for name, integrator in (('van_zon', None), ('van_zon', 'splitting'), ('thrown_box', None),
                             ('tennis_racket', 'exact')):
        scene = load_scene(name)
        bag = tmp_path / f'{name}_{integrator}'
        simulate_to_bag(scene, bag, 2.0, rate=200.0, integrator=integrator)
        _, messages = read_rosbags(bag)
        momenta = np.array([(m.vector.x, m.vector.y, m.vector.z)
                            for _, m in messages['/angular_momentum']])
        # Exact: a torque-free step adds h * 0 to L.
        np.testing.assert_array_equal(momenta, np.tile(scene.state.angular_momentum,
                                                       (len(momenta), 1)), err_msg=name)


def test_the_imu_rows_take_the_compiled_wrench_and_no_effect_runs_in_python(
        tmp_path, monkeypatch):
    """The imu messages of simulate come from Simulator.applied_wrench (compiled, once a tick)."""
    faces = []
    for name, effect_class in EFFECTS.items():
        if hasattr(effect_class, 'wrench'):
            def python_face(self, *arguments, original=effect_class.wrench, name=name):
                faces.append(name)
                return original(self, *arguments)
            monkeypatch.setattr(effect_class, 'wrench', python_face)
    scene = load_scene('heavy_top')  # gravity through a pivot: its wrench is not zero
    simulate_to_bag(scene, tmp_path / 'imu', 0.2, rate=100.0)
    _, messages = read_rosbags(tmp_path / 'imu')
    assert len(messages['/imu']) == 20
    assert faces == [], f'Python faces ran: {sorted(set(faces))}'


def test_each_message_is_the_nodes_serialisation_of_the_simulated_state(van_zon_bag):
    bag, scene, _ = van_zon_bag
    simulator = scene.simulator()
    serializer = StateSerializer(scene.body, geometry=marker_geometry_from_drawing(scene.drawing))
    raw = {}
    with Reader(bag) as reader:
        for connection, log_time, data in reader.messages():
            if connection.topic in {f'/{t}' for t in STATE_TOPICS}:
                raw.setdefault(connection.topic[1:], []).append(data)
    for tick in range(1, 801):
        simulator.step(1e-3)
        expected = serializer.serialize(simulator.state, 12_500_000_000 + tick * 1_000_000)
        for topic, message_type in STATE_TYPES.items():
            assert deserialize_message(raw[topic][tick - 1], message_type) == \
                deserialize_message(expected[topic], message_type), (topic, tick)


def test_batch_serializer_equals_the_node_serializer_on_random_states():
    rng = np.random.default_rng(6)
    axes = rng.normal(size=4)
    rotation = State(axes / np.linalg.norm(axes)).rotation
    inertia = rotation @ np.diag([1.0, 2.5, 3.0]) @ rotation.T
    bodies = [(RigidBody(2.0, inertia), None),  # non-diagonal: marker along principal axes
              (RigidBody.box(0.5, (0.3, 0.2, 0.1)),
               marker_geometry(RigidBody.box(0.5, (0.3, 0.2, 0.1)), 'box', (0.3, 0.2, 0.1)))]
    for body, geometry in bodies:
        reference = StateSerializer(body, 'map', 'base', geometry)
        batch_serializer = BatchSerializer(body, 'map', 'base', geometry)
        batch = StateBatch(200)
        states = []
        for _ in range(200):
            quaternion = rng.normal(size=4)
            state = State(quaternion / np.linalg.norm(quaternion), rng.normal(size=3) * 10,
                          rng.normal(size=3), rng.normal(size=3) * 3)
            states.append(state)
            batch.append(state)
        # builtin_interfaces/Time: int32 seconds.
        stamps = rng.integers(0, 2**31 * 10**9, size=200)
        rows = batch_serializer.serialize(batch.filled(), stamps)
        for k, state in enumerate(states):
            expected = reference.serialize(state, int(stamps[k]))
            for topic, message_type in STATE_TYPES.items():
                # Field by field (CDR padding bytes are unspecified); floats compare exactly.
                assert deserialize_message(rows[topic][k].tobytes(), message_type) == \
                    deserialize_message(expected[topic], message_type), (topic, k)


def test_batch_serializer_writes_zeros_in_the_cdr_padding():
    """
    The padding bytes are zero: rosbags' serializer, which zeroes them, writes the same bytes.

    rclpy's serializer leaves padding as its buffer held it; a template taken from it
    unzeroed would put leftover memory into every message, different from run to run.
    """
    body = RigidBody.box(0.5, (0.3, 0.2, 0.1))
    serializer = BatchSerializer(body, 'map', 'base_link_12',
                                 marker_geometry(body, 'box', (0.3, 0.2, 0.1)))
    batch = StateBatch(3)
    for k in range(3):
        batch.append(State((0.0, 0.6, 0.0, 0.8), (k, 2.0, 3.0), (0.1, 0.2, k), (1.0, k, 0.5)))
    rows = serializer.serialize(batch.filled(), [1, 2_000_000_001, 3])
    store = typestore()
    for topic in STATE_TYPES:
        name = TYPE_NAMES[f'/{topic}']
        for row in rows[topic]:
            data = row.tobytes()
            assert bytes(store.serialize_cdr(store.deserialize_cdr(data, name), name)) == data, \
                topic


# /diagnostics reports how fast the run went: these values differ between any two runs.
WALL_CLOCK_KEYS = {'achieved rate [Hz]', 'achieved real-time factor',
                   'integration CPU per simulated s [s]', 'step time p50 [ms]',
                   'step time max [ms]', 'tick duration p50 [ms]', 'tick duration p99 [ms]'}


@pytest.fixture(scope='module')
def twin_runs(tmp_path_factory):
    """Run the same simulate command twice, each in a process of its own: the two bags."""
    root = tmp_path_factory.mktemp('twins')
    bags = []
    for name in ('first', 'second'):
        bags.append(root / name)
        subprocess.run(
            [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 'default',
             '--duration', '2', '--rate', '1000', '--clock', '--bag', str(bags[-1]),
             '--quiet'], check=True, capture_output=True, cwd=PACKAGE_ROOT, timeout=300)
    return bags


def _raw_messages(bag):
    """Return topic -> [(log time, data)] in the bag's order, read with rosbags' Reader."""
    messages = {}
    with Reader(bag) as reader:
        for connection, log_time, data in reader.messages():
            messages.setdefault(connection.topic, []).append((log_time, bytes(data)))
    return messages


def _without_wall_clock(diagnostics):
    """Return a DiagnosticArray's statuses as tuples, the wall-clock values left out."""
    return [(status.level, status.name, status.message, status.hardware_id,
             [(pair.key, None if pair.key in WALL_CLOCK_KEYS else pair.value)
              for pair in status.values]) for status in diagnostics.status]


@pytest.mark.parametrize('topic', list(TYPE_NAMES))
def test_two_identical_simulate_runs_write_byte_identical_messages_on_every_topic(
        twin_runs, topic):
    """
    Same command, same bytes: every message's data, log time and order, topic by topic.

    /diagnostics excepted, as it reports the run's speed: its messages are compared
    deserialised, all but the wall-clock values (WALL_CLOCK_KEYS) equal.  Every message's
    CDR padding is zero (rosbags writes zeros there: its serialisation of the message is
    the very bytes), which once held what rclpy's buffer held on /tf, /tf_static and /imu.
    """
    first, second = (_raw_messages(bag) for bag in twin_runs)
    assert set(first) == set(second) == set(TYPE_NAMES)
    assert len(first[topic]) == len(second[topic]) > 0
    store = typestore()
    name = TYPE_NAMES[topic]
    for _, data in first[topic] + second[topic]:
        assert bytes(store.serialize_cdr(store.deserialize_cdr(data, name), name)) == data
    if topic == '/diagnostics':
        for (time_a, a), (time_b, b) in zip(first[topic], second[topic]):
            assert time_a == time_b
            assert _without_wall_clock(store.deserialize_cdr(a, TYPE_NAMES[topic])) == \
                _without_wall_clock(store.deserialize_cdr(b, TYPE_NAMES[topic]))
        return
    differing = [k for k, (a, b) in enumerate(zip(first[topic], second[topic])) if a != b]
    assert not differing, (f'{len(differing)} of {len(first[topic])} messages differ, '
                           f'the first at index {differing[0]}')


def test_sqlite3_bag_holds_the_same_messages(tmp_path):
    scene = load_scene('tennis_racket')
    simulate_to_bag(scene, tmp_path / 'mcap', 2.0, storage='mcap')
    simulate_to_bag(scene, tmp_path / 'db', 2.0, storage='sqlite3')
    assert (tmp_path / 'db' / 'db.db3').is_file()
    facts, from_sqlite = read_rosbags(tmp_path / 'db')
    _, from_mcap = read_rosbags(tmp_path / 'mcap')
    assert 'storage_identifier: sqlite3' in (tmp_path / 'db' / 'metadata.yaml').read_text()
    assert set(from_sqlite) == set(from_mcap)
    for topic in from_mcap:
        assert len(from_sqlite[topic]) == len(from_mcap[topic]) == facts['connections'][
            topic].msgcount
        assert [t for t, _ in from_sqlite[topic]] == [t for t, _ in from_mcap[topic]]
    for (_, a), (_, b) in zip(from_sqlite['/pose'], from_mcap['/pose']):
        assert a.pose.orientation.x == b.pose.orientation.x


def test_custom_data_names_the_run(van_zon_bag):
    bag, scene, _ = van_zon_bag
    facts, _ = read_rosbags(bag)
    custom = facts['custom']
    assert custom['rigid_body_sim.scene'] == 'van_zon'
    assert custom['rigid_body_sim.integrator'] == scene.integrator
    assert float(custom['rigid_body_sim.rate']) == 1000.0
    inertia = np.array(custom['rigid_body_sim.inertia'].split(), dtype=float).reshape(3, 3)
    np.testing.assert_array_equal(inertia, scene.body.inertia)
    assert custom['rigid_body_sim.body_shape'] == scene.data['body'].get('shape', '')


def test_metadata_names_jazzy_as_ros_distro_in_every_place_rosbag2_keeps_it(tmp_path):
    """metadata.yaml, the MCAP 'rosbag2' metadata record, the sqlite3 metadata table."""
    for storage in ('mcap', 'sqlite3'):
        bag = tmp_path / storage
        simulate_to_bag(load_scene('default'), bag, 0.1, storage=storage)
        assert 'ros_distro: jazzy\n' in (bag / 'metadata.yaml').read_text()
        if storage == 'mcap':
            with open(bag / 'mcap.mcap', 'rb') as stream:
                records = [m for m in make_reader(stream).iter_metadata() if m.name == 'rosbag2']
            (record,) = records
            serialized = record.metadata['serialized_metadata']
        else:
            with contextlib.closing(sqlite3.connect(bag / 'sqlite3.db3')) as connection:
                ((serialized,),) = connection.execute('SELECT metadata FROM metadata')
        assert 'ros_distro: jazzy\n' in serialized + '\n' and 'rosbags' not in serialized


def test_namespace_moves_the_state_topics_and_the_frames(tmp_path):
    simulate_to_bag(load_scene('default'), tmp_path / 'ns', 0.1, namespace='sat1')
    facts, messages = read_rosbags(tmp_path / 'ns')
    assert set(facts['connections']) == {'/sat1/pose', '/sat1/twist', '/sat1/angular_momentum',
                                         '/sat1/odom', '/sat1/marker', '/sat1/imu',
                                         '/diagnostics', '/tf', '/tf_static'}
    assert len(messages['/sat1/pose']) == 10 and '/diagnostics' not in messages
    assert len(messages['/tf']) == 10
    # The frames follow the namespace, as the node's (frame_prefix's default).
    assert {m.header.frame_id for _, m in messages['/sat1/pose']} == {'sat1/world'}
    assert {(t.header.frame_id, t.child_frame_id) for _, m in messages['/tf']
            for t in m.transforms} == {('sat1/world', 'sat1/body')}


def test_cli_writes_a_bag_and_refuses_bad_input(tmp_path, capsys):
    bag = tmp_path / 'cli'
    assert cli_main(['simulate', '--scene', 'tennis_racket', '--duration', '1', '--bag',
                     str(bag), '--quiet']) == 0
    assert 'x real time' in capsys.readouterr().out
    assert (bag / 'metadata.yaml').is_file() and (bag / 'cli.mcap').is_file()
    assert cli_main(['simulate', '--duration', '1', '--bag', str(bag), '--quiet']) == 2
    assert 'exists already' in capsys.readouterr().err
    assert cli_main(['simulate', '--duration', '0.005', '--bag', str(tmp_path / 'x'),
                     '--quiet']) == 2
    assert 'not a whole number of ticks' in capsys.readouterr().err
    assert cli_main(['simulate', '--duration', '1', '--start-time', 'soon', '--bag',
                     str(tmp_path / 'y'), '--quiet']) == 2
    assert not (tmp_path / 'x').exists() and not (tmp_path / 'y').exists()


def test_an_interrupted_run_leaves_a_complete_bag_of_what_was_written(tmp_path, monkeypatch):
    from rigid_body_sim.recording import simulate as simulate_module

    calls = []

    def interrupt(*args):
        calls.append(args)
        if len(calls) == 3:
            raise KeyboardInterrupt

    monkeypatch.setattr(simulate_module._OfflineDiagnostics, 'record',
                        lambda self, *args: interrupt(*args))
    with pytest.raises(KeyboardInterrupt):
        simulate_to_bag(load_scene('default'), tmp_path / 'cut', 10.0, rate=100.0)
    facts, messages = read_rosbags(tmp_path / 'cut')
    # Interrupted after writing its third batch (each a simulated second at 100 Hz): three
    # whole seconds are in the bag, closed and indexed.
    assert len(messages['/pose']) == facts['connections']['/pose'].msgcount == 300


@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_stop_simulate_with_a_complete_bag(tmp_path, signal_number):
    """
    The command stops after the batch it is simulating and finishes the bag.

    At 100 Hz a batch is one simulated second, so the bag holds a whole number of seconds,
    each tick's messages on every state topic, /diagnostics once per second.  Exit code
    128 + the signal's number, as a shell reports a process ended by it.
    """
    bag = tmp_path / 'stopped'
    process = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 'default',
         '--duration', '100000', '--rate', '100', '--bag', str(bag), '--quiet'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=PACKAGE_ROOT)
    try:
        # The storage file is created inside the signal handling: from then on a signal
        # only stops the run.  Then let it simulate a few seconds.
        deadline = time.monotonic() + 60.0
        while not (bag / 'stopped.mcap').exists():
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.05)  # waits-for: poll interval of the loop waiting for the file
        # Then until a flush has written 100 ticks (simulate flushes every second).
        metadata = bag / 'metadata.yaml'
        while not (metadata.exists() and _flushed_poses(metadata) >= 100):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.05)  # waits-for: poll interval of the loop waiting for the flush
        process.send_signal(signal_number)
        out, err = process.communicate(timeout=60.0)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 128 + signal_number, err
    assert 'Traceback' not in err
    assert f'{signal.Signals(signal_number).name}: stopped after' in err
    assert '(stopped early)' in out
    assert bag_is_complete(bag)
    facts, messages = read_rosbags(bag)
    ticks = len(messages['/pose'])
    assert ticks >= 100 and ticks % 100 == 0
    for topic in ('/pose', '/twist', '/angular_momentum', '/odom', '/marker'):
        assert len(messages[topic]) == facts['connections'][topic].msgcount == ticks
    assert len(messages['/diagnostics']) == ticks // 100
    assert f'/pose: {ticks}' in out


def test_a_bag_path_that_cannot_be_created_is_one_clear_line(tmp_path, capsys):
    (tmp_path / 'a_file').write_text('')
    bag = tmp_path / 'a_file' / 'bag'
    assert cli_main(['simulate', '--duration', '1', '--bag', str(bag), '--quiet']) == 1
    err = capsys.readouterr().err
    assert err == f'rigid-body-sim simulate: error: {bag}: Not a directory\n'


@pytest.mark.xdist_group('node')
def test_offline_bag_equals_what_the_live_node_publishes(tmp_path):
    """The node (default scene, 100 Hz) publishes the offline bag's messages, bit for bit."""
    isolate_ros_environment()
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'rate': 100.0})
    client = Client(namespace)
    try:
        client.wait_until_connected(inputs=False)
        client.wait_for_messages('pose', 50)
        client.wait_for(lambda: client.messages('/diagnostics'), 10.0, 'diagnostics')
        live = {topic: [m for _, m in client.received(topic)] for topic in STATE_TYPES}
        live_diagnostics = client.received('/diagnostics')[-1][1]
        offers = {topic: [qos_from_profile(info.qos_profile) for info in
                          client.node.get_publishers_info_by_topic(f'{namespace}/{topic}')]
                  for topic in STATE_TYPES}
    finally:
        client.close()
        node.stop()
    scene = load_scene('default')
    bag = tmp_path / 'offline'
    # Long enough to contain the ticks the node published while the client listened.
    simulate_to_bag(scene, bag, 120.0, rate=100.0, namespace=namespace)
    store = typestore()
    offline = {}
    with Reader(bag) as reader:
        connections = {c.topic: c for c in reader.connections}
        for connection, _, data in reader.messages():
            if connection.topic.startswith(namespace):
                offline.setdefault(connection.topic[len(namespace) + 1:], []).append(data)
            else:
                offline_diagnostics = store.deserialize_cdr(data, connection.msgtype)
    for topic, message_type in STATE_TYPES.items():
        # Each subscription matched at a tick of its own: find the offline tick of the
        # first live message (equal state fields), then every later one follows tick by
        # tick, equal but for the stamp (wall clock live, simulated time offline).
        offset = _offline_index(live[topic][0], offline[topic], message_type)
        assert len(live[topic]) >= 20
        for k, received in enumerate(live[topic]):
            expected = deserialize_message(offline[topic][offset + k], message_type)
            if hasattr(received, 'header'):
                expected.header.stamp = received.header.stamp
            assert received == expected, (topic, k)
        assert connections[f'{namespace}/{topic}'].ext.offered_qos_profiles == offers[topic]
    assert offers['pose'] == [offered_qos(qos.STATE_QOS)]
    live_status, offline_status = live_diagnostics.status[0], offline_diagnostics.status[0]
    assert [v.key for v in live_status.values] == [v.key for v in offline_status.values]
    live_values = {v.key: v.value for v in live_status.values}
    offline_values = {v.key: v.value for v in offline_status.values}
    for key in ('scene', 'effects', 'integrator', 'requested rate [Hz]', 'substeps',
                'step [s]', 'paused', 'external wrench active'):
        assert live_values[key] == offline_values[key], key
    assert live_status.name == offline_status.name
    assert live_status.hardware_id == offline_status.hardware_id


def _offline_index(first, offline, message_type):
    """Return the index of the offline message equal to `first` but for its stamp."""
    for index, data in enumerate(offline):
        candidate = deserialize_message(data, message_type)
        if hasattr(first, 'header'):
            candidate.header.stamp = first.header.stamp
        if candidate == first:
            return index
    raise AssertionError(f'no offline {message_type.__name__} equals the first live one')


def test_simulate_is_faster_than_real_time_at_1_khz(tmp_path):
    # A loose floor for CI (the benchmark measures the real figure): at 1 kHz with every
    # topic the run must at least keep ahead of the wall clock.
    scene = load_scene('default')
    simulate_to_bag(scene, tmp_path / 'warm', 0.1, rate=1000.0)
    summary = simulate_to_bag(scene, tmp_path / 'speed', 5.0, rate=1000.0)
    assert summary.speed > 1.0, str(summary)
    assert math.isclose(summary.duration, 5.0)


def _flushed_count(bag):
    """Return the message count of the bag's metadata.yaml (0 if none, or caught mid-write)."""
    metadata = bag / 'metadata.yaml'
    if not metadata.exists():
        return 0
    try:
        return int(yaml.safe_load(metadata.read_text())['rosbag2_bagfile_information'][
            'message_count'])
    except (yaml.YAMLError, KeyError, TypeError, ValueError):
        return 0


def _messages_per_topic(bag):
    read = {}
    with Reader(bag) as reader:
        for connection, _, _ in reader.messages():
            read[connection.topic] = read.get(connection.topic, 0) + 1
    return read


def test_simulate_killed_by_sigkill_keeps_every_message_up_to_its_last_flush(tmp_path):
    """
    Kill -9 mid-run: metadata.yaml is there and nothing up to the last flush is lost.

    The flush (every 0.2 s here) writes the MCAP file's pending chunk with a provisional end
    and metadata.yaml with the counts, and every chunk completed after it gets a provisional
    end too: the bag then opens with rosbags as it is.  Killed while a chunk is being
    written (a few syscalls; at 1 kHz simulate writes most of the time) the file's end is
    torn: `record --recover` rebuilds it, and still nothing up to the last flush is lost.
    """
    bag = tmp_path / 'killed'
    process = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 't_handle',
         '--duration', '100000', '--rate', '1000', '--bag', str(bag), '--quiet',
         '--flush-period', '0.2'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=PACKAGE_ROOT)
    try:
        deadline = time.monotonic() + 120.0
        # Two flushes seen: the run is well under way, whatever the machine's speed.
        first = 0
        while first == 0 or _flushed_count(bag) == first:
            first = first or _flushed_count(bag)
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, 'no flush seen'
            time.sleep(0.05)  # waits-for: poll interval of the loop waiting for the flushes
        seen = _flushed_count(bag)
    finally:
        process.kill()
        process.wait()
    counted = _flushed_count(bag)
    assert counted >= seen > first > 0
    try:
        read = _messages_per_topic(bag)
    except ReaderError:
        assert cli_main(['record', '--recover', str(bag)]) == 0
        read = _messages_per_topic(bag)
    assert sum(read.values()) >= counted
    # Whole ticks: each state topic has the same count.
    assert len({read[f'/{topic}'] for topic in ('pose', 'twist', 'odom', 'marker')}) == 1


def test_a_negative_flush_period_is_refused_in_one_line(tmp_path, capsys):
    assert cli_main(['simulate', '--duration', '1', '--bag', str(tmp_path / 'x'),
                     '--flush-period', '-1']) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and '--flush-period must be' in error


def test_tf_in_the_bag_is_the_pose_bit_for_bit_and_the_imu_mount_is_static(van_zon_bag):
    """Each /tf transform world -> body: the pose's stamp, position and quaternion exactly."""
    bag, _, _ = van_zon_bag
    _, messages = read_rosbags(bag)
    poses = messages['/pose']
    transforms = messages['/tf']
    assert len(transforms) == len(poses)
    for (pose_time, pose), (tf_time, tf) in zip(poses, transforms):
        (transform,) = tf.transforms
        assert tf_time == pose_time
        assert (transform.header.frame_id, transform.child_frame_id) == ('world', 'body')
        assert stamp_of(transform) == stamp_of(pose)
        position, orientation = pose.pose.position, pose.pose.orientation
        translation, rotation = transform.transform.translation, transform.transform.rotation
        assert (translation.x, translation.y, translation.z) == (
            position.x, position.y, position.z)
        assert (rotation.x, rotation.y, rotation.z, rotation.w) == (
            orientation.x, orientation.y, orientation.z, orientation.w)
    ((_, static),) = messages['/tf_static']
    (mount,) = static.transforms
    assert (mount.header.frame_id, mount.child_frame_id) == ('body', 'imu')

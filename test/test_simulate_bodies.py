"""
`simulate` of a scene of several bodies: the bag holds what the node of bodies publishes.

Read with rosbags (its Reader and typestore), independently of the package's writer; each
body's poses are compared with the same body simulated alone.
"""

import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from rigid_body_sim.physics import State
from rigid_body_sim.recording.bag_writer import typestore
from rigid_body_sim.recording.simulate_bodies import simulate_bodies_to_bag
from rigid_body_sim.scenes import load_scene
from rosbags.rosbag2 import Reader
import yaml

BODY_TOPICS = ('pose', 'twist', 'angular_momentum', 'odom', 'imu')
RATE = 100.0
DURATION = 1.5


def read_bag(bag):
    """Return (topic -> type name, topic -> [(log time, message)], custom data)."""
    store = typestore()
    messages = {}
    with Reader(bag) as reader:
        types = {connection.topic: connection.msgtype for connection in reader.connections}
        for connection, log_time, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (log_time, store.deserialize_cdr(raw, connection.msgtype)))
    information = yaml.safe_load((Path(bag) / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    return types, messages, information.get('custom_data') or {}


@pytest.fixture(scope='module')
def clubs_bag(tmp_path_factory):
    """Simulate the juggling clubs 1.5 s at 100 Hz, in namespace /act, with /clock."""
    bag = tmp_path_factory.mktemp('bodies') / 'clubs'
    scene = load_scene('juggling_clubs')
    summary = simulate_bodies_to_bag(scene, bag, DURATION, rate=RATE, namespace='/act',
                                     clock=True)
    return bag, scene, summary, read_bag(bag)


def test_every_body_has_its_topics_under_its_name_and_all_share_one_tf_and_marker_array(
        clubs_bag):
    _, scene, summary, (types, messages, _) = clubs_bag
    names = [member.name for member in scene.members]
    expected = {f'/act/{name}/{topic}' for name in names for topic in BODY_TOPICS}
    expected |= {'/act/markers', '/tf', '/tf_static', '/diagnostics', '/clock'}
    assert set(types) == expected
    ticks = round(DURATION * RATE)
    assert summary.ticks == ticks
    for name in names:
        for topic in BODY_TOPICS:
            assert len(messages[f'/act/{name}/{topic}']) == ticks
    assert types['/act/markers'] == 'visualization_msgs/msg/MarkerArray'
    for _, transforms in messages['/tf']:
        assert [t.child_frame_id for t in transforms.transforms] == [f'act/{n}' for n in names]
        assert {t.header.frame_id for t in transforms.transforms} == {'act/world'}
    for _, array in messages['/act/markers']:
        assert [marker.ns for marker in array.markers] == names
    (_, static), = messages['/tf_static']
    assert [(t.header.frame_id, t.child_frame_id) for t in static.transforms] == [
        (f'act/{name}', f'act/{name}/imu') for name in names]
    assert len(messages['/diagnostics']) == int(DURATION)


def test_each_body_in_the_bag_moves_exactly_as_the_same_body_simulated_alone(clubs_bag):
    _, scene, _, (_, messages, _) = clubs_bag
    for member in scene.members:
        simulator = member.simulator()
        poses = messages[f'/act/{member.name}/pose']
        for tick, (log_time, pose) in enumerate(poses, start=1):
            simulator.step(1.0 / RATE)
            state = simulator.state
            assert log_time == round(tick * 1e9 / RATE)
            stamp = pose.header.stamp.sec * 1_000_000_000 + pose.header.stamp.nanosec
            assert stamp == log_time
            position = pose.pose.position
            orientation = pose.pose.orientation
            # Bit for bit: the World calls the same compiled step on the same numbers.
            assert [position.x, position.y, position.z] == state.position.tolist()
            assert [orientation.x, orientation.y, orientation.z, orientation.w] == \
                state.quaternion.tolist()


def test_the_world_frame_transforms_are_the_bodies_poses_of_the_same_tick(clubs_bag):
    _, scene, _, (_, messages, _) = clubs_bag
    names = [member.name for member in scene.members]
    for tick, (log_time, transforms) in enumerate(messages['/tf']):
        for name, transform in zip(names, transforms.transforms):
            _, pose = messages[f'/act/{name}/pose'][tick]
            assert transform.transform.translation.z == pose.pose.position.z
            assert transform.transform.rotation.w == pose.pose.orientation.w


def test_the_bag_says_which_bodies_it_holds_with_their_mass_inertia_and_effects(clubs_bag):
    _, scene, _, (_, _, custom) = clubs_bag
    bodies = json.loads(custom['rigid_body_sim.bodies'])
    assert [entry['name'] for entry in bodies] == [member.name for member in scene.members]
    for entry, member in zip(bodies, scene.members):
        assert entry['mass'] == member.body.mass
        assert np.array_equal(np.reshape(entry['inertia'], (3, 3)), member.body.inertia)
        assert entry['effects'] == member.effect_names()
    assert custom['rigid_body_sim.scene'] == 'juggling_clubs'


def test_gravity_pulls_every_club_down_at_g(clubs_bag):
    _, scene, _, (_, messages, _) = clubs_bag
    for member in scene.members:
        (gravity,) = [e for e in member.effects if type(e).__name__ == 'Gravity']
        mass = member.body.mass
        initial = member.state
        time = DURATION
        _, last = messages[f'/act/{member.name}/pose'][-1]
        expected = (initial.position + initial.linear_momentum / mass * time
                    + 0.5 * np.asarray(gravity.acceleration) * time ** 2)
        got = np.array([last.pose.position.x, last.pose.position.y, last.pose.position.z])
        # A uniform field: the COM's parabola is exact for every integrator, to rounding.
        assert np.allclose(got, expected, rtol=0.0, atol=1e-9)


def test_a_one_body_scene_is_refused_by_the_writer_of_bodies(tmp_path):
    with pytest.raises(ValueError, match='one body'):
        simulate_bodies_to_bag(load_scene('default'), tmp_path / 'bag', 1.0)


def run_cli(*arguments, cwd):
    return subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', *arguments], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_simulate_command_writes_a_scene_of_bodies_and_lists_every_topic(tmp_path):
    result = run_cli('simulate', '--scene', 'juggling_clubs', '--duration', '0.5', '--bag',
                     'clubs', '--quiet', cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert 'ticks' in result.stdout
    assert '  /<name>/pose: 50 each, 3 bodies' in result.stdout
    assert '/markers: 50' in result.stdout
    with Reader(tmp_path / 'clubs') as reader:
        assert {c.topic for c in reader.connections} >= {'/club_middle/odom', '/tf'}


def test_simulate_command_refuses_a_body_frame_for_a_scene_of_bodies_in_one_line(tmp_path):
    result = run_cli('simulate', '--scene', 'juggling_clubs', '--duration', '0.5', '--bag',
                     'clubs', '--body-frame', 'base_link', cwd=tmp_path)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1
    assert '--body-frame' in result.stderr and 'Traceback' not in result.stderr
    assert not (tmp_path / 'clubs').exists()


def test_a_body_that_turns_non_finite_is_reported_stopped_and_the_others_go_on(tmp_path):
    scene = load_scene('juggling_clubs')
    # A club spun so fast the first step leaves the finite numbers, the others as given.
    first = scene.members[0]
    spun = State(first.state.quaternion, first.state.position, first.state.linear_momentum,
                 np.array([1e308, 1e308, 1e308]))
    members = (type(first)(**{**first.__dict__, 'state': spun}),) + scene.members[1:]
    scene = type(scene)(**{**scene.__dict__, 'bodies': members})
    bag = tmp_path / 'bag'
    simulate_bodies_to_bag(scene, bag, 1.0, rate=RATE, tolerance=0.0)
    _, messages, _ = read_bag(bag)
    (_, report), = messages['/diagnostics']
    values = {value.key: value.value for value in report.status[0].values}
    assert values['bodies stopped'] == first.name
    _, last = messages[f'/{scene.members[1].name}/pose'][-1]
    assert np.isfinite(last.pose.position.z)

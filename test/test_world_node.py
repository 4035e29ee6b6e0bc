"""
The node of a scene of several bodies: each body's topics and frames under its name.

Over DDS, the juggler's three clubs (config/scenes/juggling_clubs.yaml): each club's topics
carry its own state (thrown up, they rise, then fall under gravity), one /tf message a tick
holds the three transforms, /tf_static the three IMU mounts, one MarkerArray the three
markers; a body without external_wrench takes no input; ~/reset puts every club back.  In
this process: the interface the simulation services are built on (spawn, delete, set a
state, reset, pause, step while paused), and how the node chooses to publish less often.
"""

import math
import re

from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from node_harness import applied_from
from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import nanoseconds
from node_harness import NodeProcess
from node_harness import start_node_in_process
from node_harness import stop_node_in_process
from node_harness import unique_namespace
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rigid_body_sim.messages.qos import STATE_QOS
from rigid_body_sim.messages.qos import TF_QOS
from rigid_body_sim.messages.qos import TF_STATIC_QOS
from rigid_body_sim.node.world_node import publish_every
from rigid_body_sim.node.world_node import WorldNode
from rigid_body_sim.physics import State
from rigid_body_sim.scenes import load_scene
from sensor_msgs.msg import Imu
from visualization_msgs.msg import Marker
from visualization_msgs.msg import MarkerArray

pytestmark = pytest.mark.xdist_group('node')

CLUBS = ('club_left', 'club_middle', 'club_right')
INITIAL_X = {'club_left': -0.3, 'club_middle': 0.0, 'club_right': 0.3}

# Two bodies, one of them driven from outside: only it subscribes to torque and wrench.
DRIVEN_PAIR = """\
name: driven_pair
description: two boxes, one taking torque and wrench from outside
rate: 100
body: {mass: 1.0, shape: box, size: [0.3, 0.2, 0.1]}
bodies:
  - name: driven
    effects: [external_wrench]
    initial: {angular_velocity_body: [0.0, 0.0, 0.0]}
  - name: free
    initial: {position: [1.0, 0.0, 0.0], angular_velocity_body: [0.1, 2.0, 0.1]}
"""


@pytest.fixture(scope='module')
def clubs(tmp_path_factory):
    """Give (node process, client) of juggling_clubs at 100 Hz in a namespace of its own."""
    from tf2_msgs.msg import TFMessage
    isolate_ros_environment()
    namespace = unique_namespace()
    node = NodeProcess(tmp_path_factory.mktemp('clubs') / 'node.log', namespace=namespace,
                       parameters={'scene': 'juggling_clubs'})
    topics = {'/tf': (TFMessage, TF_QOS), '/tf_static': (TFMessage, TF_STATIC_QOS),
              'markers': (MarkerArray, STATE_QOS)}
    for club in CLUBS:
        topics[f'{club}/pose'] = (PoseStamped, STATE_QOS)
        topics[f'{club}/odom'] = (Odometry, STATE_QOS)
        topics[f'{club}/imu'] = (Imu, STATE_QOS)
    client = Client(namespace, extra_topics=topics)
    try:
        yield node, client
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def _wait(client, node, condition, what):
    try:
        client.wait_for(condition, DISCOVERY_TIMEOUT, what)
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None


def test_each_club_publishes_its_own_state_under_its_name_rising_then_falling(clubs):
    """
    Each club's pose is its own (its own x), and under gravity it rises, then falls.

    Thrown up at 4 m/s, a club tops out after about 0.41 s: its height then decreases
    (watched from a reset on).
    The odometry names the club's frame as its child, the IMU the club's IMU frame.
    """
    node, client = clubs
    _wait(client, node, lambda: all(client.messages(f'{club}/pose') for club in CLUBS),
          'a pose of every club')
    # From the throw on: a reset starts it again (the node ran before the client heard it).
    stamp = applied_from(client.reset())
    for club in CLUBS:
        poses = client.stamped_after(f'{club}/pose', stamp, 80)
        x = [message.pose.position.x for message in poses]
        assert np.allclose(x, INITIAL_X[club], atol=1e-9), (club, x[:5])
        heights = [message.pose.position.z for message in poses]
        top = int(np.argmax(heights))
        assert 0 < top < len(heights) - 1, f'{club} did not rise then fall: {heights}'
        assert heights[-1] < heights[top]
        odom = client.wait_for_messages(f'{club}/odom', 1)[-1]
        assert odom.child_frame_id == client.frame(club)
        assert odom.header.frame_id == client.frame('world')
        imu = client.wait_for_messages(f'{club}/imu', 1)[-1]
        assert imu.header.frame_id == client.frame(f'{club}/imu')
        # In free fall an accelerometer reads nothing (gravity acts on it as on the club).
        acceleration = imu.linear_acceleration
        assert math.hypot(acceleration.x, acceleration.y, acceleration.z) < 1e-6


def test_one_tf_message_a_tick_holds_every_club_and_tf_static_every_imu(clubs):
    """Each /tf message carries the three clubs' transforms from the world frame, one stamp."""
    node, client = clubs
    _wait(client, node, lambda: len(client.messages('/tf')) >= 10, '10 /tf messages')
    world = client.frame('world')
    for message in client.messages('/tf'):
        assert [t.child_frame_id for t in message.transforms] == [
            client.frame(club) for club in CLUBS]
        assert {t.header.frame_id for t in message.transforms} == {world}
        assert len({nanoseconds(t.header.stamp) for t in message.transforms}) == 1
    _wait(client, node, lambda: client.messages('/tf_static'), 'the /tf_static message')
    (mounts,) = client.messages('/tf_static')[-1:]
    assert {(t.header.frame_id, t.child_frame_id) for t in mounts.transforms} == {
        (client.frame(club), client.frame(f'{club}/imu')) for club in CLUBS}
    # The transform is the pose of that tick, bit for bit.
    last = client.messages('/tf')[-1]
    stamp = nanoseconds(last.transforms[0].header.stamp)
    _wait(client, node, lambda: any(nanoseconds(m.header.stamp) == stamp
                                    for m in client.messages('club_right/pose')),
          'the pose of the last /tf stamp')
    pose = next(m for m in client.messages('club_right/pose')
                if nanoseconds(m.header.stamp) == stamp).pose
    translation = last.transforms[2].transform.translation
    assert (translation.x, translation.y, translation.z) == (
        pose.position.x, pose.position.y, pose.position.z)


def test_one_marker_array_a_tick_holds_every_club_named_after_it(clubs):
    """The markers topic: one MarkerArray, a marker per club, ns its name, ids unique."""
    node, client = clubs
    _wait(client, node, lambda: client.messages('markers'), 'a MarkerArray')
    array = client.messages('markers')[-1]
    assert [marker.ns for marker in array.markers] == list(CLUBS)
    assert len({marker.id for marker in array.markers}) == 3
    assert all(marker.action == Marker.ADD and marker.type == Marker.CYLINDER
               and marker.header.frame_id == client.frame('world') for marker in array.markers)


def test_a_club_without_external_wrench_takes_no_input(clubs):
    """No club has external_wrench: none subscribes to torque or wrench."""
    node, client = clubs
    _wait(client, node, lambda: client.messages('club_left/pose'), 'a pose')
    for club in CLUBS:
        for topic in ('torque', 'wrench'):
            assert client.node.count_subscribers(f'{client.namespace}/{club}/{topic}') == 0


def test_reset_puts_every_club_back_to_its_throw(clubs):
    """After ~/reset every club's pose is its initial one, a few ticks into its throw."""
    node, client = clubs
    _wait(client, node, lambda: len(client.messages('club_left/pose')) >= 100,
          '100 poses of club_left')
    response = client.reset()
    assert response.success, response.message
    stamp = applied_from(response)
    for club in CLUBS:
        first = next(m for m in client.stamped_after(f'{club}/pose', stamp)
                     if nanoseconds(m.header.stamp) > stamp)
        position = first.pose.position
        # At most a few ticks of 0.01 s after the throw from 1 m at 4 m/s up.
        assert position.x == INITIAL_X[club]
        assert 1.0 < position.z < 1.2, (club, position)


def test_only_a_body_with_external_wrench_takes_torque_and_it_turns_that_body(tmp_path):
    """In a scene of a driven body and a free one, only the driven one has inputs."""
    scene = tmp_path / 'driven_pair.yaml'
    scene.write_text(DRIVEN_PAIR)
    isolate_ros_environment()
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'scene': str(scene)})
    client = Client(namespace, extra_topics={
        'driven/pose': (PoseStamped, STATE_QOS),
        'driven/angular_momentum': (Vector3Stamped, STATE_QOS)})
    torque = client.node.create_publisher(Vector3Stamped, 'driven/torque', STATE_QOS)
    try:
        _wait(client, node, lambda: torque.get_subscription_count() > 0 and client.messages(
            'driven/angular_momentum'), 'the driven body to connect')
        assert client.node.count_subscribers(f'{namespace}/free/torque') == 0
        assert client.node.count_subscribers(f'{namespace}/free/wrench') == 0
        assert client.node.count_subscribers(f'{namespace}/driven/wrench') == 1
        message = Vector3Stamped()
        message.vector.z = 0.5  # N m, world frame (empty frame id)
        torque.publish(message)
        _wait(client, node, lambda: any(m.vector.z > 0.004 for m in client.messages(
            'driven/angular_momentum')), 'the torque to spin the driven body up')
    finally:
        client.close()
        assert node.stop() == 0, node.output()


# -- in this process: the interface of the simulation services

def _start(scene='juggling_clubs'):
    return start_node_in_process(WorldNode, scene)


@pytest.fixture
def world_node():
    """Give a WorldNode of juggling_clubs in this process, not spun."""
    node = _start()
    yield node
    stop_node_in_process(node)


def _topics(node):
    return {publisher.topic_name for publisher in node.publishers}


def test_the_interface_spawns_steps_sets_and_deletes_bodies(world_node, monkeypatch):
    """
    spawn_body, set_body_state, step_while_paused, delete_body, reset: what they promise.

    A spawned body gets its topics and joins the world at its time; a duplicate or
    malformed name is a one-line ValueError; stepping while playing is refused, while
    paused it advances exactly the ticks asked for and publishes each; a deleted body's
    topics go and its marker is deleted once; a reset puts all back at time 0.
    """
    node = world_node
    namespace = node.get_namespace().rstrip('/')
    assert node.world.names == CLUBS
    assert node.world_frame == 'world' and node.scene.name == 'juggling_clubs'
    assert node.playing
    box = load_scene('thrown_box')
    node.spawn_body('box', box)
    assert node.world.names == CLUBS + ('box',)
    assert {f'{namespace}/box/pose', f'{namespace}/box/imu'} <= _topics(node)
    for name, member, words in (('box', box, 'exists already'),
                                ('2box', box, 'letters, digits'),
                                ('pair', node.scene, 'one body')):
        with pytest.raises(ValueError, match=words) as error:
            node.spawn_body(name, member)
        assert '\n' not in str(error.value)
    with pytest.raises(ValueError, match='playing'):
        node.step_while_paused(1)
    node.set_playing(False)
    assert not node.playing
    state = State(position=(5.0, 0.0, 0.0))
    node.set_body_state('box', state)
    assert np.array_equal(node.world.state('box').position, (5.0, 0.0, 0.0))
    published = []
    node._markers_subscribed = True
    monkeypatch.setattr(node._markers_publisher, 'publish', published.append)
    before = node.simulated_time
    node.step_while_paused(5)
    assert node.simulated_time == pytest.approx(before + 5 / node.scene.rate, abs=1e-12)
    assert len(published) == 5
    assert node.stamp_nanoseconds() > 0
    node.delete_body('box')
    assert node.world.names == CLUBS
    assert f'{namespace}/box/pose' not in _topics(node)
    deleted = published[-1]
    assert [(m.ns, m.action) for m in deleted.markers] == [('box', Marker.DELETE)]
    with pytest.raises(KeyError):
        node.delete_body('box')
    with pytest.raises(KeyError):
        node.set_body_state('box', state)
    node.reset_simulation()
    assert node.simulated_time == 0.0
    assert np.array_equal(node.world.state('club_left').position, (-0.3, 0.0, 1.0))


@pytest.mark.parametrize('step, publish, expected', [
    (0.001, 0.002, 1),     # both fit the period of 10 ms
    (0.002, 0.008, 2),     # publishing every other tick fits (5 ms of room)
    (0.0055, 0.010, 7),    # 1.5 ms of room left: 7 ticks per publication
    (0.009, 0.010, 100),   # the integration alone takes more than the room: the most
])
def test_the_node_publishes_less_often_as_the_tick_costs_more(step, publish, expected):
    """The k chosen keeps the mean tick within its share of the period, if the step allows."""
    k = publish_every(step, publish, 0.0, 0.01, 100)
    assert k == expected
    if k < 100:
        assert step + publish / k <= 0.7 * 0.01 + 1e-15


def test_one_body_parameters_are_refused_for_a_scene_of_bodies():
    """body.mass describes one body: for a scene of bodies it stops the node in one line."""
    from rigid_body_sim.node.rigid_body_node import ConfigurationError
    isolate_ros_environment()
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        with pytest.raises(ConfigurationError, match=re.escape('body.mass')) as error:
            WorldNode(context=context, start_parameter_services=False,
                      parameter_overrides=[Parameter('scene', value='juggling_clubs'),
                                           Parameter('body.mass', value=2.0)])
        error.value.node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_the_integrator_switches_at_run_time_for_every_body_and_the_status_says_so(
        world_node, monkeypatch):
    """The integrator and tolerance set at run time act on every body, as the status says."""
    node = world_node
    results = node.set_parameters([Parameter('integrator', value='rk4'),
                                   Parameter('tolerance', value=0.0)])
    assert all(result.successful for result in results), results
    assert node.world.integrator == 'rk4' and node.world.tolerance is None
    for _ in range(3):
        node._tick()
    assert node.simulated_time == pytest.approx(3 / node.scene.rate, abs=1e-12)
    reports = []
    monkeypatch.setattr(node._diagnostics_publisher, 'publish', reports.append)
    node._publish_diagnostics()
    (status,) = reports[-1].status
    values = {kv.key: kv.value for kv in status.values}
    assert values['bodies'] == '3' and values['integrator'] == 'rk4'
    assert values['tolerance [rad/s]'] == 'off'
    assert values['rate kept'] in ('yes', 'no')
    assert values['state published every k-th tick'] == '1'
    # All bodies' integration per simulated second, the key the one-body node reports too.
    assert 0.0 < float(values['integration CPU per simulated s [s]']) < math.inf


def test_a_deleted_body_leaves_no_publisher_behind_in_a_world_checked_in_turns():
    """
    In a world whose subscribers are looked for a part at a time, a deletion re-indexes all.

    debris_field's 100 bodies are more than one check looks at; after a body is deleted
    no subscriber table names a body index past the end or the deleted body's publisher.
    """
    node = _start('debris_field')
    try:
        subscribers = node._body_subscribers['pose']
        for index, body in enumerate(node._body_list):
            subscribers[index] = body.publishers['pose']  # as if each had a subscriber
        deleted = node._body_list[0].publishers['pose']
        node.delete_body('debris_000')
        assert all(index < 99 for index in subscribers)
        assert deleted not in subscribers.values()
        node._publish_state(0)
    finally:
        context = node.context
        node.destroy_node()
        rclpy.try_shutdown(context=context)

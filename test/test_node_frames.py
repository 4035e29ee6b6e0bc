"""
Frames follow the namespace and are checked as tf2 reads them.

Two nodes in two namespaces publish distinct frames on the one global /tf (frame_prefix,
by default the namespace, as robot_state_publisher's); REP 105 names come from
config/rep105.yaml; a frame name tf2 would read as another frame, as no frame, or that no
tool can name stops the node with one line naming the parameter.
"""

import math

from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import PACKAGE_ROOT
from node_harness import unique_namespace
import numpy as np
import pytest
from rclpy.qos import QoSProfile
from rigid_body_sim.messages.frames import default_frame_prefix
from rigid_body_sim.messages.frames import frame_ids
from rigid_body_sim.messages.frames import MAX_FRAME_ID_LENGTH
from rigid_body_sim.messages.qos import STATE_QOS
from rigid_body_sim.messages.qos import TF_QOS
from rigid_body_sim.messages.qos import TF_STATIC_QOS
from rigid_body_sim.node.parameters import DEFAULTS
from rigid_body_sim.node.parameters import frame_ids_from_parameters
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.text import one_line

pytestmark = pytest.mark.xdist_group('node')

RATE = 100.0
DEFAULT_FRAMES = {name: DEFAULTS[name] for name in ('world_frame', 'body_frame', 'imu_frame')}


@pytest.fixture
def ros_environment():
    """Isolate this process's ROS domain (and so its children's)."""
    isolate_ros_environment()


# -- the names, without a node

@pytest.mark.parametrize('namespace, prefix', [
    ('/', ''), ('', ''), ('/sat1', 'sat1/'), ('/fleet/sat1', 'fleet/sat1/')])
def test_the_default_frame_prefix_is_the_namespace(namespace, prefix):
    assert default_frame_prefix(namespace) == prefix


@pytest.mark.parametrize('prefix, world, expected', [
    ('sat1/', 'world', {'world_frame': 'sat1/world', 'body_frame': 'sat1/body',
                        'imu_frame': 'sat1/imu'}),
    # robot_state_publisher's rule: the prefix verbatim, its '/' included.
    ('robot_', 'world', {'world_frame': 'robot_world', 'body_frame': 'robot_body',
                         'imu_frame': 'robot_imu'}),
    # As tf2 reads them: one leading '/' dropped, from the prefix or from the name.
    ('/sat1/', 'world', {'world_frame': 'sat1/world', 'body_frame': 'sat1/body',
                         'imu_frame': 'sat1/imu'}),
    ('/', 'odom', {'world_frame': 'odom', 'body_frame': 'body', 'imu_frame': 'imu'}),
    ('', '/odom', {'world_frame': 'odom', 'body_frame': 'body', 'imu_frame': 'imu'}),
    # An absolute name (a leading '/', as tf1's tf_prefix had it) takes no prefix: one world
    # frame that nodes in two namespaces share.
    ('sat1/', '/world', {'world_frame': 'world', 'body_frame': 'sat1/body',
                         'imu_frame': 'sat1/imu'}),
])
def test_frames_are_prefixed_verbatim_and_read_as_tf2_reads_them(prefix, world, expected):
    values = dict(DEFAULT_FRAMES, frame_prefix=prefix, world_frame=world)
    assert frame_ids_from_parameters(values) == expected


# (parameter, value, frame_prefix, what the refusal says)
REFUSED_FRAMES = [
    ('world_frame', '/body', '',
     "parameters 'world_frame' and 'body_frame' name one frame: '/body' and 'body' are both "
     "'body' as tf2 reads them"),
    ('imu_frame', 'body', 'sat1/', "parameters 'body_frame' and 'imu_frame' name one frame"),
    ('world_frame', '/sat1/body', 'sat1/',
     "parameters 'world_frame' and 'body_frame' name one frame: '/sat1/body' and 'body' (with "
     "frame_prefix 'sat1/') are both 'sat1/body'"),
    ('world_frame', '/', '', "parameter 'world_frame': '/' is empty as tf2 reads it"),
    ('body_frame', '', '', "parameter 'body_frame': '' is empty as tf2 reads it"),
    ('body_frame', '//body', '', "'//body' still starts with / once tf2 dropped one"),
    ('body_frame', 'my body', '', "parameter 'body_frame': 'my body' holds whitespace"),
    ('imu_frame', 'imu\t2', '', "parameter 'imu_frame': 'imu\\t2' holds whitespace"),
    ('world_frame', 'wor\x1bld', '', "parameter 'world_frame': 'wor\\x1bld' holds a control"),
    ('imu_frame', 'imu\x7f', '', "parameter 'imu_frame': 'imu\\x7f' holds a control"),
    ('body_frame', 'b' * 10_000, '', 'is 10000 characters long; frame ids are at most 256'),
    ('body_frame', 'b' * (MAX_FRAME_ID_LENGTH - 4), 'sat1/',
     f"(with frame_prefix 'sat1/') is {MAX_FRAME_ID_LENGTH + 1} characters long"),
    ('world_frame', 'world', 'my sat/', "(with frame_prefix 'my sat/') holds whitespace"),
]


@pytest.mark.parametrize('parameter, value, prefix, words', REFUSED_FRAMES)
def test_a_frame_tf2_cannot_use_is_refused_in_one_line_naming_the_parameter(
        parameter, value, prefix, words):
    values = dict(DEFAULT_FRAMES, frame_prefix=prefix)
    values[parameter] = value
    with pytest.raises(ValueError) as refusal:
        frame_ids_from_parameters(values)
    message = str(refusal.value)
    assert words in message, message
    assert one_line(message) == message and len(message) <= 500, message


def test_the_longest_frame_id_is_accepted():
    name = 'b' * MAX_FRAME_ID_LENGTH
    assert frame_ids('', {'body_frame': name}) == {'body_frame': name}


# -- over DDS

def _transforms(client, topic, child):
    """Return the transforms to frame `child` received on `topic`, in arrival order."""
    return [t for message in client.messages(topic) for t in message.transforms
            if t.child_frame_id == child]


def _stamp(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def _rotation_angle(q1, q2):
    """Return the angle (rad) of the rotation from unit quaternion q1 to q2."""
    dot = abs(sum(a * b for a, b in zip(q1, q2)))
    return 2.0 * math.acos(min(1.0, dot))


def _check_own_motion(client, transforms, max_angular_speed):
    """
    Check that `transforms` are the node's own poses and never jump; return how many matched.

    Each transform equals the node's pose of its stamp bit for bit; from one to the next (one
    tick: /tf is reliable and published every tick) the body turns by at most its largest
    angular speed (rad/s) times the tick's simulated 1/RATE s.  (The stamps are the node's
    clock: ticks caught up after a late one are stamped closer together.)
    """
    poses = {_stamp(p.header): p.pose for p in client.messages('pose')}
    matched = 0
    for transform in transforms:
        pose = poses.get(_stamp(transform.header))
        if pose is None:
            continue  # that tick's pose not (yet) received here
        t, r = transform.transform.translation, transform.transform.rotation
        assert (t.x, t.y, t.z, r.x, r.y, r.z, r.w) == (
            pose.position.x, pose.position.y, pose.position.z, pose.orientation.x,
            pose.orientation.y, pose.orientation.z, pose.orientation.w)
        matched += 1
    for before, after in zip(transforms, transforms[1:]):
        assert _stamp(after.header) > _stamp(before.header), 'a transform older than the last'
        turned = _rotation_angle(*([q.x, q.y, q.z, q.w] for q in (
            before.transform.rotation, after.transform.rotation)))
        assert turned <= max_angular_speed / RATE + 1e-9, turned
    return matched


def _max_angular_speed(scene):
    """Return a bound of |omega| (rad/s) of a torque-free body: |L| / its least moment."""
    body, state = scene.body, scene.state
    return float(np.linalg.norm(state.angular_momentum)) / min(body.principal_moments)


def test_two_namespaced_nodes_publish_distinct_frames_and_neither_jumps(
        tmp_path, ros_environment):
    """
    Two nodes at once, in two namespaces, default frame_prefix: both on the global /tf.

    Each publishes <ns>/world -> <ns>/body (and <ns>/body -> <ns>/imu on /tf_static); each
    body frame's transforms are its own node's poses, bit for bit, and turn smoothly: a TF
    consumer never sees one frame jump between two bodies (the second body starts upside
    down, so a transform of the other would be a half turn away).
    """
    from tf2_msgs.msg import TFMessage
    flipped = {'initial.orientation': '[1.0, 0.0, 0.0, 0.0]'}
    namespaces = [unique_namespace(), unique_namespace()]
    nodes = [NodeProcess(tmp_path / f'node{index}.log', namespace=namespace,
                         parameters=dict({'rate': RATE}, **(flipped if index else {})))
             for index, namespace in enumerate(namespaces)]
    # A reader queue no stall of this loaded test process fills: a transform dropped here
    # would look like a jump of the body between the two it received.
    deep_tf = QoSProfile(depth=100_000, reliability=TF_QOS.reliability,
                         durability=TF_QOS.durability)
    tf_topics = {'/tf': (TFMessage, deep_tf), '/tf_static': (TFMessage, TF_STATIC_QOS)}
    clients = [Client(namespace, extra_topics=tf_topics) for namespace in namespaces]
    try:
        bodies = [client.frame('body') for client in clients]
        assert bodies == [namespace.strip('/') + '/body' for namespace in namespaces]
        assert len(set(bodies)) == 2
        for client, body in zip(clients, bodies):
            client.wait_for(lambda client=client, body=body: len(
                _transforms(client, '/tf', body)) >= 200, DISCOVERY_TIMEOUT,
                f'200 transforms to {body}')
            client.wait_for(lambda client=client: _transforms(
                client, '/tf_static', client.frame('imu')), DISCOVERY_TIMEOUT,
                'the static transform of the IMU')
        # One client hears both nodes on the global topics (once it discovered the other
        # node, which on a loaded machine may come after its own node's 200 transforms).
        listener = clients[0]
        for client, body in zip(clients, bodies):
            listener.wait_for(lambda body=body: _transforms(listener, '/tf', body),
                              DISCOVERY_TIMEOUT, f'a transform to {body} on the other client')
            # The other node's latched /tf_static writer is discovered on its own, maybe
            # after its /tf writer.
            listener.wait_for(lambda client=client: _transforms(
                listener, '/tf_static', client.frame('imu')), DISCOVERY_TIMEOUT,
                f"the static transform of {client.frame('imu')} on the other client")
            transforms = _transforms(listener, '/tf', body)
            assert transforms, f'no transform to {body} heard by the other client'
            assert {t.header.frame_id for t in transforms} == {client.frame('world')}
            (mount,) = {(t.header.frame_id, t.child_frame_id)
                        for t in _transforms(listener, '/tf_static', client.frame('imu'))}
            assert mount == (body, client.frame('imu'))
            # Against the node's own poses, from its own client's subscription.
            own = _transforms(client, '/tf', body)
            speed = _max_angular_speed(load_scene('default'))
            assert _check_own_motion(client, own, speed) >= 150
        frames = {t.child_frame_id for m in listener.messages('/tf') for t in m.transforms}
        assert {'body', 'world'}.isdisjoint(frames), frames
    except AssertionError as error:
        outputs = '\n'.join(node.output() for node in nodes)
        raise AssertionError(f'{error}\nnode output:\n{outputs}') from None
    finally:
        for client in clients:
            client.close()
        for node in nodes:
            assert node.stop() == 0, node.output()


def test_the_rep105_params_file_publishes_odom_to_base_link_in_the_namespace(
        tmp_path, ros_environment):
    """
    config/rep105.yaml after the shipped file: odom -> base_link, base_link -> imu_link.

    The frames carry the namespace; an input in base_link (with a leading '/', which tf2
    drops) is body-fixed, accepted.
    """
    from tf2_msgs.msg import TFMessage
    from sensor_msgs.msg import Imu
    namespace = unique_namespace()
    config = PACKAGE_ROOT / 'config'
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace, parameters={'rate': RATE},
                       extra_arguments=['--params-file', str(config / 'rigid_body_sim.yaml'),
                                        '--params-file', str(config / 'rep105.yaml')])
    client = Client(namespace, extra_topics={
        '/tf': (TFMessage, TF_QOS), '/tf_static': (TFMessage, TF_STATIC_QOS),
        'imu': (Imu, STATE_QOS)})
    odom, base_link, imu_link = (client.frame(name) for name in ('odom', 'base_link',
                                                                 'imu_link'))
    try:
        client.wait_until_connected()
        client.wait_for(lambda: _transforms(client, '/tf', base_link), DISCOVERY_TIMEOUT,
                        f'a transform to {base_link}')
        client.wait_for(lambda: _transforms(client, '/tf_static', imu_link),
                        DISCOVERY_TIMEOUT, f'the static transform to {imu_link}')
        assert {t.header.frame_id for t in _transforms(client, '/tf', base_link)} == {odom}
        assert {t.header.frame_id for t in _transforms(client, '/tf_static', imu_link)} == {
            base_link}
        message = client.messages('odom')[-1]
        assert (message.header.frame_id, message.child_frame_id) == (odom, base_link)
        assert client.messages('pose')[-1].header.frame_id == odom
        assert client.wait_for_messages('imu', 1)[-1].header.frame_id == imu_link
        momentum = client.messages('angular_momentum')[-1].vector
        before = np.array([momentum.x, momentum.y, momentum.z])

        def momentum_moved():
            latest = client.messages('angular_momentum')[-1].vector
            return np.linalg.norm(np.array([latest.x, latest.y, latest.z]) - before) > 0.01
        client.publish_torque([0.0, 0.0, 1.0], '/' + base_link)
        client.wait_for(momentum_moved, DISCOVERY_TIMEOUT, 'the body-fixed torque to act')
        assert 'rejected' not in node.output()
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()


# (label: parameters, what the one error line says); control characters come through a
# params file (a -p value cannot carry them).
STARTUP_REFUSALS = {
    'slash alias': ({'frame_prefix': "''", 'world_frame': '/body'},
                    "'/body' and 'body' are both 'body'"),
    'root slash': ({'world_frame': '/'}, "parameter 'world_frame': '/' is empty"),
    'overlong': ({'imu_frame': 'i' * 10_000}, 'characters long; frame ids are at most 256'),
    'control': ('    body_frame: "bo\\x07dy"\n', "parameter 'body_frame': 'bo\\x07dy'"),
    'whitespace': ('    world_frame: "my world"\n', "parameter 'world_frame': 'my world'"),
}


def test_a_frame_tf2_cannot_use_stops_the_node_with_one_line(tmp_path, ros_environment):
    """Each refused frame: one ERROR line naming the parameter, no traceback, exit code 1."""
    nodes = {}
    for label, (parameters, _) in STARTUP_REFUSALS.items():  # started together
        arguments = []
        if isinstance(parameters, str):
            params = tmp_path / f'{label}.yaml'
            params.write_text('/**/rigid_body_sim:\n  ros__parameters:\n' + parameters)
            parameters, arguments = {}, ['--params-file', str(params)]
        nodes[label] = NodeProcess(tmp_path / f'{label}.log', namespace=unique_namespace(),
                                   parameters=parameters, extra_arguments=arguments)
    try:
        for label, node in nodes.items():
            code = node.wait(DISCOVERY_TIMEOUT)
            output = node.output()
            assert code == 1, (label, code, output)
            errors = [line for line in output.splitlines() if 'ERROR' in line]
            assert len(errors) == 1, output
            assert 'invalid configuration' in errors[0], errors[0]
            assert STARTUP_REFUSALS[label][1] in errors[0], (label, errors[0])
            reason = {'control': 'holds a control character', 'whitespace': 'holds whitespace'}
            assert reason.get(label, '') in errors[0], (label, errors[0])
            assert len(errors[0]) < 600 and 'Traceback' not in output, output[:2000]
    finally:
        for node in nodes.values():
            node.stop()


def test_frame_prefix_slash_gives_a_namespaced_node_the_bare_frames(tmp_path, ros_environment):
    """frame_prefix:=/ (or ''): no prefix; the frames are world and body as given."""
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'rate': RATE, 'frame_prefix': '/',
                                   'world_frame': f'world_{namespace.strip("/")}'})
    client = Client(namespace)
    try:
        message = client.wait_for_messages('odom', 1)[-1]
        assert (message.header.frame_id, message.child_frame_id) == (
            f'world_{namespace.strip("/")}', 'body')
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()

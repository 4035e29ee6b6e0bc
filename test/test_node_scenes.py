"""
The node simulates a scene, over real DDS.

Inputs only where the scene takes them, the scene's drawing, rate and integrator, its input
limits, and the total energy in /diagnostics.

Each test starts its own nodes (in namespaces of their own) and clients.
"""

import time

from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import PACKAGE_ROOT
from node_harness import unique_namespace
import numpy as np
import pytest
from rigid_body_sim.scenes import load_scene
from visualization_msgs.msg import Marker

pytestmark = pytest.mark.xdist_group('node')


@pytest.fixture(autouse=True)
def ros_environment():
    """Isolate this process's ROS domain (and so its children's)."""
    isolate_ros_environment()


def status_values(client):
    """Return {key: value} of the node's latest /diagnostics status."""
    message = client.wait_for_messages('/diagnostics', 1, timeout=10.0)[-1]
    status = next(s for s in message.status
                  if s.hardware_id == f'{client.namespace}/{NODE_NAME}')
    return {kv.key: kv.value for kv in status.values}


def float32(values):
    """Return `values` rounded to float32, as a Marker's colour carries them."""
    return [float(np.float32(v)) for v in values]


def connected(node, inputs):
    """Return a Client connected to `node`; stop the node if it does not connect."""
    client = Client(node.namespace)
    try:
        client.wait_until_connected(inputs=inputs)
    except AssertionError as error:
        client.close()
        node.stop()
        raise AssertionError(f'{error}; node output:\n{node.output()}') from None
    return client


def test_only_a_scene_with_external_wrench_subscribes_and_each_is_drawn_its_way(tmp_path):
    """t_handle takes no input; default and driven do; each marker is its scene's drawing."""
    names = ('t_handle', 'default', 'driven')
    nodes = {name: NodeProcess(tmp_path / f'{name}.log', namespace=unique_namespace(),
                               parameters={'scene': name})
             for name in names}  # started together
    clients = {}
    try:
        for name, node in nodes.items():
            scene = load_scene(name)
            client = clients[name] = connected(node, scene.accepts_external_wrench)
            inputs = {f'{node.namespace}/torque', f'{node.namespace}/wrench'}

            def subscribed(client=client, node=node):
                return {topic for topic, _ in
                        client.node.get_subscriber_names_and_types_by_node(
                            NODE_NAME, node.namespace)}

            def known(client=client, node=node):
                # The client's graph has the node itself (asking before raises).
                return (NODE_NAME, node.namespace) in \
                    client.node.get_node_names_and_namespaces()
            client.wait_for(known, 30.0, 'the node in the graph')
            if scene.accepts_external_wrench:
                client.wait_for(lambda: inputs <= subscribed(), 30.0, 'the input subscriptions')
            else:
                # Absent in the graph as the node's own log line says (it subscribes before it
                # offers its services, which the client has seen).
                assert not inputs & subscribed(), (name, subscribed())
                assert client.torque_publisher.get_subscription_count() == 0
                assert client.wrench_publisher.get_subscription_count() == 0
            assert 'subscribed to ' + ('torque and wrench' if scene.accepts_external_wrench
                                       else 'no inputs') in node.output()

            marker = client.messages('marker')[-1]
            assert marker.type == Marker.CUBE, name
            np.testing.assert_array_equal(
                [marker.scale.x, marker.scale.y, marker.scale.z], scene.drawing.size)
            assert [marker.color.r, marker.color.g, marker.color.b, marker.color.a] == \
                float32(scene.drawing.color), name
            values = status_values(client)
            assert values['scene'] == name
            assert values['integrator'] == scene.integrator
    finally:
        for client in clients.values():
            client.close()
        for node in nodes.values():
            node.stop()


def test_a_pivot_scene_runs_at_its_rate_and_reports_its_total_energy(tmp_path):
    """
    heavy_top with the shipped params file: the scene's 1 kHz, Buss and cylinder stay.

    /diagnostics reports the total energy, kinetic plus gravity's potential, exactly as the
    scene's Simulator gives it after the same number of ticks: the node's steps are the
    Simulator's.  The kinetic energy alone differs from it by m g z_COM, ~4 % here.
    """
    scene = load_scene('heavy_top')
    node = NodeProcess(tmp_path / 'node.log', namespace=unique_namespace(), extra_arguments=[
        '--params-file', str(PACKAGE_ROOT / 'config' / 'rigid_body_sim.yaml'),
        '-p', 'scene:=heavy_top'])
    client = connected(node, inputs=False)
    try:
        marker = client.messages('marker')[-1]
        assert marker.type == Marker.CYLINDER
        np.testing.assert_array_equal([marker.scale.x, marker.scale.y, marker.scale.z],
                                      [0.08, 0.08, 0.01])
        start = time.monotonic()
        client.wait_for_messages('/diagnostics', 2, since=start, timeout=10.0)
        values = status_values(client)
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    assert float(values['requested rate [Hz]']) == 1000.0
    assert values['integrator'] == 'buss'
    assert values['effects'] == 'pivot, gravity'

    ticks = round(float(values['simulated time [s]']) * scene.rate)
    assert ticks > 0
    simulator = scene.simulator()
    initial_energy = simulator.energy()
    for _ in range(ticks):
        simulator.step(scene.dt)
    energy = simulator.energy()
    kinetic = simulator.state.kinetic_energy(scene.body)
    # The value is printed to 12 significant digits.
    assert float(values['energy [J]']) == pytest.approx(energy, rel=1e-11, abs=0.0)
    assert abs(kinetic - energy) > 0.03 * energy
    drift = (energy - initial_energy) / initial_energy
    assert float(values['energy drift since last input']) == pytest.approx(
        drift, rel=1e-3, abs=1e-16)


LIMITED_SCENE = """\
name: limited
description: a box at rest that takes at most 0.5 N m and 2 N from outside
body: {mass: 2.0, shape: box, size: [0.4, 0.2, 0.1]}
effects:
  - external_wrench: {max_torque: 0.5, max_force: 2.0}
integrator: buss
rate: 100
# One step per tick (no error control): each tick changes L by exactly one kick of tau h.
tolerance: 0
"""


def test_an_input_beyond_the_scenes_limits_is_scaled_down_to_them(tmp_path):
    """A 2 N m torque on a scene limited to 0.5 N m adds 0.5 N m x h per tick, direction kept."""
    path = tmp_path / 'limited.yaml'
    path.write_text(LIMITED_SCENE)
    rate = load_scene(str(path)).rate
    node = NodeProcess(tmp_path / 'node.log', namespace=unique_namespace(),
                       parameters={'scene': str(path), 'input_timeout': 0.0})
    client = connected(node, inputs=True)
    try:
        since = time.monotonic()
        client.publish_torque([0.0, 1.2, 1.6], client.frame('world'))  # |tau| = 2 N m
        client.publish_wrench([0.0, 0.0, 8.0], [0.0, 0.0, 0.0], client.frame('world'))
        client.wait_for(lambda: 'scaled a torque input down' in node.output()
                        and 'scaled a wrench input down' in node.output(), DISCOVERY_TIMEOUT,
                        'both inputs to be scaled down')
        client.wait_for_messages('angular_momentum', int(rate), since=since)
        client.wait_for_messages('twist', int(rate), since=since)
        momenta = [np.array([m.vector.x, m.vector.y, m.vector.z])
                   for m in client.messages('angular_momentum', since)]
        velocities = [np.array([t.linear.x, t.linear.y, t.linear.z])
                      for t in client.messages('twist', since)]
        client.wait_for(lambda: 'scaled a torque input down' in node.output(), 5.0,
                        'the warning')
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    kick = np.array([0.0, 0.3, 0.4]) / rate  # 0.5 N m along (0, 0.6, 0.8), for 1/rate s
    changes = [after - before for before, after in zip(momenta, momenta[1:])
               if np.any(after != before)]
    counts = [round(float(change @ kick / (kick @ kick))) for change in changes]
    assert counts.count(1) >= 0.5 * rate, counts
    for change, count in zip(changes, counts):
        np.testing.assert_allclose(change, count * kick, rtol=0, atol=1e-14)
    # 2 N on 2 kg: the COM speeds up by 1 m/s^2 along z, not 4.
    speed_ups = [after - before for before, after in zip(velocities, velocities[1:])
                 if np.any(after != before)]
    assert speed_ups
    for speed_up in speed_ups:
        ticks = round(speed_up[2] * rate)
        np.testing.assert_allclose(speed_up, [0.0, 0.0, ticks / rate], rtol=0, atol=1e-14)

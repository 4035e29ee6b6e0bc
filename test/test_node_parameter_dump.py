"""
Every parameter has a value, so the ROS tools that list and get parameters see the simulation.

``ros2 param dump`` (and rqt_reconfigure, launch tooling) calls the node's
``list_parameters`` service, then ``get_parameters`` with every listed name; rclpy answers
the whole request with nothing if one of the names has no value.  These tests do what the
tools do, over DDS, then start a second node from the dumped YAML and compare the two
nodes' published states bit for bit, matched by their simulated-time stamps.
"""

from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import unique_namespace
import numpy as np
import pytest
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters
from rcl_interfaces.srv import ListParameters
from rclpy.parameter import parameter_value_to_python
import yaml

STATES_COMPARED = 100


@pytest.fixture(autouse=True, scope='module')
def ros_environment():
    """Give this test process a ROS domain of its own."""
    isolate_ros_environment()


def dump(client):
    """
    Return the node's parameters as ``ros2 param dump`` writes them (a YAML text).

    As ros2cli's dump verb (jazzy): list_parameters, get_parameters of every listed name,
    names split at '.' into nested mappings under ``<node full name>: ros__parameters``.
    """
    lister = client.node.create_client(ListParameters, f'{NODE_NAME}/list_parameters')
    getter = client.node.create_client(GetParameters, f'{NODE_NAME}/get_parameters')
    client.wait_for(lambda: lister.service_is_ready() and getter.service_is_ready(),
                    DISCOVERY_TIMEOUT, 'the parameter services')
    names = sorted(client.call(lister, ListParameters.Request()).result.names)
    values = client.call(getter, GetParameters.Request(names=names)).values
    # rclpy's answer to a request naming one parameter without a value: no values at all.
    assert len(values) == len(names), f'{len(values)} values for {len(names)} names'
    unset = [name for name, value in zip(names, values)
             if value.type == ParameterType.PARAMETER_NOT_SET]
    assert not unset, f'parameters without a value: {unset}'
    tree = {}
    for name, value in zip(names, values):
        *sections, leaf = name.split('.')
        target = tree
        for section in sections:
            target = target.setdefault(section, {})
        target[leaf] = parameter_value_to_python(value)
    full_name = f'{client.namespace}/{NODE_NAME}'
    return yaml.dump({full_name: {'ros__parameters': tree}}, default_flow_style=False), names


def states_by_stamp(client):
    """Return {stamp ns: (odom pose and twist, angular momentum)} as float arrays."""
    odom = {}
    for message in client.messages('odom'):
        pose, twist = message.pose.pose, message.twist.twist
        odom[_stamp(message)] = np.array([
            pose.position.x, pose.position.y, pose.position.z, pose.orientation.x,
            pose.orientation.y, pose.orientation.z, pose.orientation.w, twist.linear.x,
            twist.linear.y, twist.linear.z, twist.angular.x, twist.angular.y, twist.angular.z])
    momentum = {_stamp(m): np.array([m.vector.x, m.vector.y, m.vector.z])
                for m in client.messages('angular_momentum')}
    return {stamp: np.concatenate((odom[stamp], momentum[stamp]))
            for stamp in odom.keys() & momentum.keys()}


def _stamp(message):
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def common_stamps(first, second):
    return sorted(states_by_stamp(first).keys() & states_by_stamp(second).keys())


@pytest.mark.parametrize('scene, overrides', [
    ('default', {}),
    # A pivot scene with a new mass (the shape's inertia scales) and a turned start: the
    # dump then holds values that follow from others (inertia, position, velocity).
    ('heavy_top', {'body.mass': '2.5',
                   'initial.orientation': '[0.1, 0.0, 0.0, 0.99498743710662]'}),
])
def test_a_dumped_parameter_file_starts_a_node_that_publishes_the_same_states_bit_for_bit(
        tmp_path, scene, overrides):
    first_namespace, second_namespace = unique_namespace(), unique_namespace()
    first_client = Client(first_namespace)
    second_client = Client(second_namespace)
    first = second = None
    try:
        # publish_clock: stamps count simulated ticks, so the two runs' states pair up.
        first = NodeProcess(tmp_path / 'first.log', namespace=first_namespace,
                            parameters={'scene': scene, 'publish_clock': 'true', **overrides})
        first_client.wait_until_connected(inputs=False)
        text, names = dump(first_client)
        (tmp_path / 'dump.yaml').write_text(text)
        # The dump names the node by its full name; loaded into another namespace the key
        # must match that node, as a user would write it for a second node.
        dumped = yaml.safe_load(text)
        assert dumped[f'{first_namespace}/{NODE_NAME}']['ros__parameters']['scene'] == scene
        parameters = dumped[f'{first_namespace}/{NODE_NAME}']
        (tmp_path / 'second.yaml').write_text(yaml.dump(
            {f'{second_namespace}/{NODE_NAME}': parameters}, default_flow_style=False))
        second = NodeProcess(tmp_path / 'second.log', namespace=second_namespace,
                             extra_arguments=['--params-file', str(tmp_path / 'second.yaml')])
        second_client.wait_until_connected(inputs=False)
        second_dump, second_names = dump(second_client)
        assert second_names == names
        assert yaml.safe_load(second_dump)[f'{second_namespace}/{NODE_NAME}'] == parameters
        first_client.wait_for(
            lambda: len(common_stamps(first_client, second_client)) >= STATES_COMPARED,
            DISCOVERY_TIMEOUT, f'{STATES_COMPARED} states of both nodes at the same stamps')
    finally:
        for process in (first, second):
            if process is not None:
                process.stop()
        first_client.close()
        second_client.close()
    first_states = states_by_stamp(first_client)
    second_states = states_by_stamp(second_client)
    stamps = common_stamps(first_client, second_client)[:STATES_COMPARED]
    for stamp in stamps:
        assert np.array_equal(first_states[stamp], second_states[stamp]), (
            stamp, first_states[stamp] - second_states[stamp])
    # Both nodes say which values override the scene: the same ones.
    overriding = f"overriding the scene {scene!r}: {', '.join(overrides) or 'none'};"
    assert overriding in first.output()
    assert overriding in second.output()

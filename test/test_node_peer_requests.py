"""
What any peer on the DDS domain can send to the node: every request answered, the node alive.

One node (the default scene at 100 Hz) for the module, in a namespace of its own; its
parameter services are called with hand-made requests, malformed ones included.
"""

from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import unique_namespace
import pytest
from rcl_interfaces.msg import Log
from rcl_interfaces.msg import Parameter as ParameterMessage
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.msg import ParameterValue
from rcl_interfaces.srv import GetParameters
from rcl_interfaces.srv import GetParameterTypes
from rcl_interfaces.srv import ListParameters
from rcl_interfaces.srv import SetParameters
from rcl_interfaces.srv import SetParametersAtomically
from rclpy.qos import DurabilityPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rigid_body_sim.messages.qos import SERVICE_QOS
from rigid_body_sim.node.parameters import PARAMETERS
from std_srvs.srv import SetBool
from std_srvs.srv import Trigger

pytestmark = pytest.mark.xdist_group('node')

RATE = 100.0
# One valid value of each parameter type, by type number.
VALUES = {
    ParameterType.PARAMETER_BOOL: ('bool_value', True),
    ParameterType.PARAMETER_INTEGER: ('integer_value', 3),
    ParameterType.PARAMETER_DOUBLE: ('double_value', 0.5),
    ParameterType.PARAMETER_STRING: ('string_value', 'buss'),
    ParameterType.PARAMETER_BYTE_ARRAY: ('byte_array_value', [b'\x01']),
    ParameterType.PARAMETER_BOOL_ARRAY: ('bool_array_value', [True]),
    ParameterType.PARAMETER_INTEGER_ARRAY: ('integer_array_value', [1, 2]),
    ParameterType.PARAMETER_DOUBLE_ARRAY: ('double_array_value', [1.0, 2.0]),
    ParameterType.PARAMETER_STRING_ARRAY: ('string_array_value', ['a']),
}
KIND_TYPES = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
              float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING,
              list: ParameterType.PARAMETER_DOUBLE_ARRAY}


def parameter_message(name, type_number, value=None):
    """Return an rcl_interfaces/Parameter of any type number, with a value of its type."""
    message = ParameterMessage(name=name, value=ParameterValue(type=type_number))
    if type_number in VALUES:
        field, default = VALUES[type_number]
        setattr(message.value, field, default if value is None else value)
    return message


@pytest.fixture(scope='module')
def peer(tmp_path_factory):
    """Start the node and a client with raw parameter service clients; stop both after."""
    isolate_ros_environment()
    namespace = unique_namespace()
    node = NodeProcess(tmp_path_factory.mktemp('node') / 'node.log', namespace=namespace,
                       parameters={'rate': RATE})
    client = Client(namespace)
    try:
        client.wait_until_connected()
        client.clients = {
            service_type: client.node.create_client(service_type, f'{NODE_NAME}/{name}')
            for service_type, name in ((SetParameters, 'set_parameters'),
                                       (SetParametersAtomically, 'set_parameters_atomically'),
                                       (GetParameters, 'get_parameters'),
                                       (ListParameters, 'list_parameters'))}
        client.wait_for(lambda: all(c.service_is_ready() for c in client.clients.values()),
                        60.0, 'the parameter services')
        client.await_matched(client.clients.values())
    except AssertionError as error:
        client.close()
        node.stop()
        raise AssertionError(f'{error}; node output:\n{node.output()}') from None
    client.process = node
    yield client
    client.close()
    assert node.stop() == 0, node.output()


def set_one(peer, message, atomically):
    """Send one parameter message with SetParameters(Atomically); return its result."""
    if atomically:
        response = peer.call(peer.clients[SetParametersAtomically],
                             SetParametersAtomically.Request(parameters=[message]))
        return response.result
    response = peer.call(peer.clients[SetParameters],
                         SetParameters.Request(parameters=[message]))
    assert len(response.results) == 1
    return response.results[0]


def assert_alive_and_ticking(peer):
    """Assert that the node runs and still publishes poses."""
    assert peer.process.alive(), peer.process.output()
    before = len(peer.messages('pose'))
    peer.wait_for(lambda: len(peer.messages('pose')) > before + 2, 60.0, 'new poses')


@pytest.mark.parametrize('atomically', [False, True])
@pytest.mark.parametrize('type_number', [99, 10, 255, ParameterType.PARAMETER_NOT_SET])
def test_a_value_of_no_parameter_type_is_refused_with_a_reason(peer, atomically,
                                                               type_number):
    """A type such as 99 stopped the node (ValueError in rclpy's service): now refused."""
    result = set_one(peer, parameter_message('real_time_factor', type_number), atomically)
    assert not result.successful
    assert f'value type {type_number}' in result.reason, result.reason
    assert_alive_and_ticking(peer)


@pytest.mark.parametrize('atomically', [False, True])
@pytest.mark.parametrize('name', ['', 'no_such_parameter', 'x' * 100_000])
def test_an_empty_or_unknown_name_is_refused_and_declares_nothing(peer, atomically, name):
    """An empty name was declared by rclpy's service; unknown names are refused too."""
    result = set_one(peer, parameter_message(name, ParameterType.PARAMETER_DOUBLE), atomically)
    assert not result.successful
    assert result.reason and len(result.reason) < 400, result.reason
    listed = peer.call(peer.clients[ListParameters], ListParameters.Request()).result.names
    assert name not in listed
    assert_alive_and_ticking(peer)


@pytest.mark.parametrize('atomically', [False, True])
def test_every_type_mismatch_is_refused_with_a_reason(peer, atomically):
    """Each parameter with each other type: refused, the value unchanged."""
    names = [spec.name for spec in PARAMETERS]
    before = peer.call(peer.clients[GetParameters], GetParameters.Request(names=names)).values
    assert len(before) == len(names)
    for spec in PARAMETERS:
        for type_number in VALUES:
            if type_number == KIND_TYPES[spec.kind]:
                continue
            result = set_one(peer, parameter_message(spec.name, type_number), atomically)
            assert not result.successful, (spec.name, type_number)
            assert result.reason, (spec.name, type_number)
    after = peer.call(peer.clients[GetParameters], GetParameters.Request(names=names)).values
    assert after == before
    assert_alive_and_ticking(peer)


def test_an_atomic_request_with_one_bad_parameter_sets_none(peer):
    """A good value beside a malformed one: refused whole, the good one not set."""
    response = peer.call(peer.clients[SetParametersAtomically], SetParametersAtomically.Request(
        parameters=[parameter_message('input_timeout', ParameterType.PARAMETER_DOUBLE, 0.25),
                    parameter_message('max_wrench', 99)]))
    assert not response.result.successful
    values = peer.call(peer.clients[GetParameters],
                       GetParameters.Request(names=['input_timeout'])).values
    assert values[0].double_value != 0.25
    assert_alive_and_ticking(peer)


def test_a_burst_of_1000_asynchronous_reset_and_pause_requests_is_answered_whole(peer):
    """
    1,000 requests sent at once, none awaited: every one gets its answer.

    rclpy's default service queue (keep last 10) dropped all but the last few silently
    (38 answers of 1,000 in 15 s); the node's reset and pause services hold 1,000 requests
    (SERVICE_QOS).  A client sending bursts needs a queue as deep for its answers: these
    clients have the same QoS.
    """
    reset = peer.node.create_client(Trigger, 'reset', qos_profile=SERVICE_QOS)
    pause = peer.node.create_client(SetBool, 'pause', qos_profile=SERVICE_QOS)
    peer.wait_for(lambda: reset.service_is_ready() and pause.service_is_ready(), 60.0,
                  'the reset and pause services')
    peer.await_matched((reset, pause))
    futures = []
    for index in range(1000):
        if index % 3 == 0:
            futures.append(reset.call_async(Trigger.Request()))
        else:
            # Paused and running in turn, the last one running.
            futures.append(pause.call_async(SetBool.Request(data=index % 3 == 1)))
    try:
        # A failure detector: 1,000 answers take well under a second on an idle machine.
        peer.wait_for(lambda: all(future.done() for future in futures), 120.0,
                      f'1000 answers ({sum(f.done() for f in futures)} came)')
    finally:
        peer.call(pause, SetBool.Request(data=False))
    assert all(future.result().success for future in futures)
    assert_alive_and_ticking(peer)


def test_a_megabyte_frame_id_reaches_the_log_and_rosout_as_one_short_line(peer):
    """A 1 MB frame_id with control characters: the warning quotes 200 characters, escaped."""
    logs = []
    # Transient local, as rcl's /rosout publisher: a warning logged before the match comes.
    peer.node.create_subscription(
        Log, '/rosout', lambda message: logs.append(message) if 'frame_id' in message.msg
        else None, QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.TRANSIENT_LOCAL))
    peer.publish_torque((1.0, 0.0, 0.0), '\x1b[2J' + 'f' * 1_000_000)
    peer.wait_for(lambda: logs, 60.0, 'the warning on /rosout')
    warning = logs[0].msg
    assert 'unknown frame_id' in warning and len(warning) < 500, warning[:1000]
    assert warning.isprintable()
    printed = [line for line in peer.process.output().splitlines() if 'unknown frame_id' in line]
    assert printed and all(len(line) < 600 for line in printed)
    assert_alive_and_ticking(peer)


def test_get_parameter_types_answers_the_types_as_ros2_param_list_asks_them(peer):
    """``ros2 param list --param-type``'s request: it stopped the node (AttributeError)."""
    client = peer.node.create_client(GetParameterTypes, f'{NODE_NAME}/get_parameter_types')
    peer.wait_for(client.service_is_ready, 60.0, 'get_parameter_types')
    response = peer.call(client, GetParameterTypes.Request(
        names=['integrator', 'substeps', 'rate', 'publish_clock', 'body.size']))
    assert list(response.types) == [
        ParameterType.PARAMETER_STRING, ParameterType.PARAMETER_INTEGER,
        ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_BOOL,
        ParameterType.PARAMETER_DOUBLE_ARRAY]
    assert_alive_and_ticking(peer)

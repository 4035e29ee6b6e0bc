"""
Property-based fuzzing of the node's services over DDS: any request is answered, the node lives.

One node (the default scene at 100 Hz) for the module, in a namespace of its own; a peer in
this process calls its six parameter services (describe, get, get_types, list, set,
set_atomically) and its reset and pause services with request contents drawn by
hypothesis: parameter names of any text (the node's own among them), values of any type
number 0-255 with every value field filled with anything it can hold (NaN, infinities,
64-bit extremes, long and non-ASCII strings), list prefixes and depths of any size.  The
properties, per request:

- an answer comes (the timeout is only a failure detector: each takes milliseconds);
- a set's answer has one result per parameter (one for the atomic set), and every refusal
  gives its reason in one line of bounded length;
- a get, describe or get_types answers for every name or for none;
- the node process is alive after it; at the end it still ticks.

Derandomized (the examples follow from the test's code alone), no example database, a fixed
number of examples, no deadline (a loaded machine is no failure).  The case count and time
are printed (``pytest -s``).
"""

import time

from hypothesis import given
from hypothesis import HealthCheck
from hypothesis import settings
from hypothesis import strategies as st
from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import unique_namespace
import pytest
from rcl_interfaces.msg import Parameter as ParameterMessage
from rcl_interfaces.msg import ParameterValue
from rcl_interfaces.srv import DescribeParameters
from rcl_interfaces.srv import GetParameters
from rcl_interfaces.srv import GetParameterTypes
from rcl_interfaces.srv import ListParameters
from rcl_interfaces.srv import SetParameters
from rcl_interfaces.srv import SetParametersAtomically
from rigid_body_sim.messages.qos import SERVICE_QOS
from rigid_body_sim.node.parameters import PARAMETERS
from rigid_body_sim.physics import INTEGRATORS
from std_srvs.srv import SetBool
from std_srvs.srv import Trigger

pytestmark = pytest.mark.xdist_group('node')

EXAMPLES = 1000
DETERMINISTIC = settings(derandomize=True, database=None, deadline=None, max_examples=EXAMPLES,
                         suppress_health_check=[HealthCheck.too_slow])
ANSWER_TIMEOUT = 60.0  # s: a failure detector
LONGEST_REASON = 2000  # characters: refusals quote at most 200 of what they were sent

# A DDS string is UTF-8 without NUL (rmw passes C strings): any other character, lone
# surrogates (which UTF-8 cannot encode, so no peer can send them) excepted.
TEXT = st.text(st.characters(blacklist_characters='\x00', blacklist_categories=('Cs',)),
               max_size=40)
NAMES = st.one_of(st.sampled_from([spec.name for spec in PARAMETERS]), TEXT,
                  st.sampled_from(['', '.', 'use_sim_time', 'integrator.x', 'x' * 5000]))
INT64 = st.integers(-2**63, 2**63 - 1)
ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)
WRITABLE = {'integrator', 'substeps', 'tolerance', 'real_time_factor', 'input_timeout',
            'max_wrench'}


@st.composite
def parameter_values(draw):
    """Draw an rcl_interfaces/ParameterValue: any type number, every field anything."""
    value = ParameterValue(type=draw(st.integers(0, 255)))
    value.bool_value = draw(st.booleans())
    value.integer_value = draw(INT64)
    value.double_value = draw(ANY_FLOAT)
    value.string_value = draw(st.one_of(TEXT, st.sampled_from(sorted(INTEGRATORS))))
    value.byte_array_value = [bytes([b]) for b in draw(st.lists(st.integers(0, 255),
                                                                max_size=5))]
    value.bool_array_value = draw(st.lists(st.booleans(), max_size=5))
    value.integer_array_value = draw(st.lists(INT64, max_size=5))
    value.double_array_value = draw(st.lists(ANY_FLOAT, max_size=5))
    value.string_array_value = draw(st.lists(TEXT, max_size=3))
    return value


@st.composite
def parameter_messages(draw):
    """Draw an rcl_interfaces/Parameter, mostly of the node's writable ones, well typed."""
    name = draw(st.one_of(st.sampled_from(sorted(WRITABLE)), NAMES))
    value = draw(parameter_values())
    if draw(st.booleans()):
        # A value of a plausible type, in or out of range: the checks beyond the type.
        value.type = draw(st.sampled_from([1, 2, 3, 4]))
        value.double_value = draw(st.one_of(st.floats(-10.0, 2000.0), ANY_FLOAT))
        value.integer_value = draw(st.one_of(st.integers(-5, 200_000), INT64))
    return ParameterMessage(name=name, value=value)


REQUESTS = st.one_of(
    st.builds(lambda names: (DescribeParameters, DescribeParameters.Request(names=names)),
              st.lists(NAMES, max_size=4)),
    st.builds(lambda names: (GetParameters, GetParameters.Request(names=names)),
              st.lists(NAMES, max_size=4)),
    st.builds(lambda names: (GetParameterTypes, GetParameterTypes.Request(names=names)),
              st.lists(NAMES, max_size=4)),
    st.builds(lambda prefixes, depth: (ListParameters, ListParameters.Request(
        prefixes=prefixes, depth=depth)), st.lists(NAMES, max_size=3),
        st.integers(0, 2**64 - 1)),
    st.builds(lambda parameters: (SetParameters, SetParameters.Request(parameters=parameters)),
              st.lists(parameter_messages(), max_size=4)),
    st.builds(lambda parameters: (SetParametersAtomically, SetParametersAtomically.Request(
        parameters=parameters)), st.lists(parameter_messages(), max_size=4)),
    st.just((Trigger, Trigger.Request())),
    st.builds(lambda data: (SetBool, SetBool.Request(data=data)), st.booleans()),
)

SERVICES = {DescribeParameters: f'{NODE_NAME}/describe_parameters',
            GetParameters: f'{NODE_NAME}/get_parameters',
            GetParameterTypes: f'{NODE_NAME}/get_parameter_types',
            ListParameters: f'{NODE_NAME}/list_parameters',
            SetParameters: f'{NODE_NAME}/set_parameters',
            SetParametersAtomically: f'{NODE_NAME}/set_parameters_atomically',
            Trigger: 'reset', SetBool: 'pause'}


@pytest.fixture(scope='module')
def peer(tmp_path_factory):
    """Start the node and a peer with a client for each service; stop both after."""
    isolate_ros_environment()
    namespace = unique_namespace()
    node = NodeProcess(tmp_path_factory.mktemp('node') / 'node.log', namespace=namespace,
                       parameters={'rate': 100.0})
    client = Client(namespace)
    try:
        client.wait_until_connected()
        client.services = {kind: client.node.create_client(kind, name, qos_profile=SERVICE_QOS)
                           for kind, name in SERVICES.items()}
        client.wait_for(lambda: all(c.service_is_ready() for c in client.services.values()),
                        60.0, 'the services')
        client.await_matched(client.services.values())
    except AssertionError as error:
        client.close()
        node.stop()
        raise AssertionError(f'{error}; node output:\n{node.output()}') from None
    client.process = node
    client.cases = 0
    started = time.monotonic()
    yield client
    print(f'\nservice fuzz: {client.cases} requests over DDS in '
          f'{time.monotonic() - started:.1f} s')
    try:
        # Still simulating after all of it, and stopping cleanly.
        client.call(client.services[SetBool], SetBool.Request(data=False), ANSWER_TIMEOUT)
        before = len(client.messages('pose'))
        client.wait_for(lambda: len(client.messages('pose')) > before + 2, 60.0, 'new poses')
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def _assert_refusal_reason(result):
    if not result.successful:
        assert result.reason, result
        assert '\n' not in result.reason and len(result.reason) <= LONGEST_REASON, \
            result.reason[:LONGEST_REASON]


@DETERMINISTIC
@given(requests=st.lists(REQUESTS, min_size=1, max_size=3))
def test_any_service_request_is_answered_and_the_node_lives(peer, requests):
    for kind, request in requests:
        peer.cases += 1
        future = peer.services[kind].call_async(request)
        peer.wait_for(lambda: future.done() or not peer.process.alive(), ANSWER_TIMEOUT,
                      f'an answer to {kind.__name__}')
        assert peer.process.alive(), peer.process.output()[-5000:]
        response = future.result()
        if kind is SetParameters:
            assert len(response.results) == len(request.parameters)
            for result in response.results:
                _assert_refusal_reason(result)
        elif kind is SetParametersAtomically:
            _assert_refusal_reason(response.result)
        elif kind is GetParameters:
            assert len(response.values) in (0, len(request.names))
        elif kind is GetParameterTypes:
            assert len(response.types) in (0, len(request.names))
        elif kind is DescribeParameters:
            assert len(response.descriptors) in (0, len(request.names))
        elif kind in (Trigger, SetBool):
            assert response.success, response.message
    # No request made the node log a failure (the services' safety net).
    assert 'a request failed' not in peer.process.output()

"""
Property-based fuzzing (hypothesis) of what users feed the product: scene files and node inputs.

Complements test_scene_mutations.py (every key x a fixed list of hostile values) with
generated input: scene documents mutated at random key paths with random values of every
YAML type, scene file texts with random edits, torque and wrench messages with any float
(NaN, inf, subnormal, 1e308) and any frame id, and parameter sets of any name, type and
value applied to a node.  The properties:

- a scene is refused with one line naming the file (ValueError, no numpy warning on the
  way), or it is valid: finite inertia, state and first ticks;
- an input is rejected (counted; held wrench and state untouched) or accepted, and the
  ticks after it stay finite;
- a parameter set is refused with a one-line reason (every parameter keeps its value, the
  state is untouched) or applied, and the ticks after it stay finite.

Deterministic in CI: derandomized (the examples follow from the test's code alone), no
example database, a fixed number of examples, no deadline (a slow machine is no failure).
No example can hang: each runs a bounded number of ticks.
"""

import copy
import math
import warnings

from geometry_msgs.msg import Vector3Stamped
from geometry_msgs.msg import WrenchStamped
from hypothesis import given
from hypothesis import HealthCheck
from hypothesis import settings
from hypothesis import strategies as st
from node_harness import isolate_ros_environment
import numpy as np
import pytest
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rigid_body_sim.node.parameters import PARAMETERS
from rigid_body_sim.node.rigid_body_node import RigidBodyNode
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import unresolved_rotation
from rigid_body_sim.scenes import find_scene
from rigid_body_sim.scenes import parse_scene
from rigid_body_sim.scenes import read_scene_yaml
from rigid_body_sim.scenes import scene_names
import yaml

SOURCE = 'fuzz.yaml'
DETERMINISTIC = settings(derandomize=True, database=None, deadline=None,
                         suppress_health_check=[HealthCheck.too_slow,
                                                HealthCheck.function_scoped_fixture])

ONE_BODY_SCENES = scene_names(several_bodies=False)
SCENES = {name: yaml.safe_load(find_scene(name).read_text()) for name in ONE_BODY_SCENES}
TEXTS = {name: find_scene(name).read_text() for name in ONE_BODY_SCENES}

# Any float a message or a YAML file can carry: NaN, +-inf, subnormals, +-1e308, -0.0.
ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)
PLAIN_FLOAT = st.one_of(st.floats(-1e3, 1e3), ANY_FLOAT)
SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), PLAIN_FLOAT,
                    st.text(max_size=12))
YAML_VALUES = st.recursive(
    SCALARS,
    lambda children: st.one_of(st.lists(children, max_size=4),
                               st.dictionaries(st.text(max_size=8), children, max_size=3)),
    max_leaves=10)


def _paths(value, prefix=()):
    """Return the key path (keys and indices) of every node under value."""
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return []
    paths = []
    for key, item in items:
        paths.append(prefix + (key,))
        paths.extend(_paths(item, prefix + (key,)))
    return paths


def _check_scene(parse):
    """Run parse() -> Scene: return 'refused' or 'accepted' (or fail the test)."""
    with warnings.catch_warnings():
        warnings.simplefilter('error')  # a numpy RuntimeWarning reaching the user fails
        try:
            scene = parse()
        except ValueError as error:
            message = str(error)
            assert message.startswith(f'{SOURCE}: ') and '\n' not in message, message
            return 'refused'
        assert np.all(np.isfinite(scene.body.inertia))
        assert np.all(np.isfinite(scene.state.angular_momentum))
        assert math.isfinite(scene.state.kinetic_energy(scene.body))
        # A spin the step cannot resolve is accepted with a warning (tested elsewhere);
        # its ticks are then meaningless by design, though finite.
        if unresolved_rotation(scene.body, scene.state, scene.dt, 1, scene.tolerance) is None:
            simulator = scene.simulator()
            for _ in range(3):
                simulator.step(scene.dt)
            assert np.all(np.isfinite(simulator.state.quaternion))
            assert np.all(np.isfinite(simulator.state.angular_momentum))
            assert np.all(np.isfinite(simulator.state.position))
    return 'accepted'


@st.composite
def mutated_scene_documents(draw):
    """Draw a shipped scene with 1 to 3 of its key paths given arbitrary YAML values."""
    data = copy.deepcopy(SCENES[draw(st.sampled_from(sorted(SCENES)))])
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(data)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        target = data
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = draw(YAML_VALUES)
    return data


@settings(DETERMINISTIC, max_examples=1000)
@given(mutated_scene_documents())
def test_a_mutated_scene_document_is_refused_in_one_line_or_simulates_finite(data):
    _check_scene(lambda: parse_scene(data, SOURCE))


@st.composite
def edited_scene_texts(draw):
    """Draw a shipped scene file's text with one slice replaced by arbitrary text."""
    text = TEXTS[draw(st.sampled_from(sorted(TEXTS)))]
    # Edits in the YAML after the schema comment, where they change the document.
    start_of_yaml = text.index('\nname:') + 1
    start = draw(st.integers(start_of_yaml, len(text)))
    end = draw(st.integers(start, min(len(text), start + 20)))
    inserted = draw(st.one_of(
        st.text(max_size=12),
        st.sampled_from(['1e308', '-.inf', '.nan', '[', ']', '{', ': ', '- ', '\n  ', '!!float',
                         '0x1F', '0o17', '1_000', '~', 'null', '&a ', '*a', '"', "'", '\t'])))
    return text[:start] + inserted + text[end:]


@settings(DETERMINISTIC, max_examples=1000)
@given(edited_scene_texts())
def test_an_edited_scene_file_is_refused_in_one_line_or_simulates_finite(text):
    _check_scene(lambda: parse_scene(read_scene_yaml(text, SOURCE), SOURCE))


# -- the node


@pytest.fixture(scope='module')
def node():
    """Give the module one node of the default scene (it takes torques and wrenches)."""
    isolate_ros_environment()
    context = rclpy.Context()
    rclpy.init(context=context)
    node = RigidBodyNode(context=context, start_parameter_services=False)
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def _vector(draw, message_vector):
    message_vector.x, message_vector.y, message_vector.z = (draw(PLAIN_FLOAT) for _ in range(3))


FRAME_IDS = st.one_of(st.sampled_from(['', 'world', 'body', 'World', ' body', 'base_link']),
                      st.text(max_size=10))


@st.composite
def input_messages(draw):
    """Draw a torque (Vector3Stamped) or wrench (WrenchStamped) message, any content."""
    if draw(st.booleans()):
        message = Vector3Stamped()
        _vector(draw, message.vector)
        topic = 'torque'
    else:
        message = WrenchStamped()
        _vector(draw, message.wrench.force)
        _vector(draw, message.wrench.torque)
        topic = 'wrench'
    message.header.frame_id = draw(FRAME_IDS)
    return topic, message


def _state_arrays(node):
    state = node._simulator.state
    return [np.copy(a) for a in (state.quaternion, state.position, state.angular_momentum,
                                 state.linear_momentum)]


def _assert_finite_ticks(node, ticks=3):
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        for _ in range(ticks):
            node._tick()
    for array in _state_arrays(node):
        assert np.all(np.isfinite(array)), array


@settings(DETERMINISTIC, max_examples=150)
@given(messages=st.lists(input_messages(), min_size=1, max_size=3))
def test_an_input_message_is_rejected_without_a_trace_or_held_and_the_ticks_stay_finite(
        node, messages):
    for topic, message in messages:
        held_before = dict(node._inputs)
        state_before = _state_arrays(node)
        rejected_before = node._rejected
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            # What the subscription does with a message it receives (it keeps its bytes),
            # and the next tick (it reads them).
            node._input_callback(topic, serialize_message(message))
            node._take_received_inputs()
        if node._rejected == rejected_before + 1:
            assert node._inputs == held_before
            for before, after in zip(state_before, _state_arrays(node)):
                assert np.array_equal(before, after)
        else:
            assert node._rejected == rejected_before
            wrench, held_from = node._inputs[topic]
            assert held_from is None  # held from the next tick on
            assert np.all(np.isfinite(wrench.force)) and np.all(np.isfinite(wrench.torque))
        _assert_finite_ticks(node)


PARAMETER_NAMES = st.one_of(st.sampled_from([spec.name for spec in PARAMETERS]),
                            st.text(max_size=10))
PARAMETER_VALUES = st.one_of(
    st.booleans(), st.integers(-10**18, 10**18), PLAIN_FLOAT, st.text(max_size=12),
    st.sampled_from(sorted(INTEGRATORS)),
    st.lists(PLAIN_FLOAT, min_size=1, max_size=4), st.lists(st.integers(-5, 5), min_size=1,
                                                            max_size=4))


def _simulation_settings(node):
    """Return what a parameter changes in the running simulation."""
    simulator = node._simulator
    return (simulator.integrator, simulator.tolerance, simulator.substeps,
            node._wall_period, node._input_timeout_ns, node._max_wrench)


def _parameter_snapshot(node):
    snapshot = {}
    for spec in PARAMETERS:
        parameter = node.get_parameter(spec.name)
        snapshot[spec.name] = (parameter.type_, repr(parameter.value))
    return snapshot


@settings(DETERMINISTIC, max_examples=200)
@given(changes=st.lists(st.tuples(PARAMETER_NAMES, PARAMETER_VALUES), min_size=1,
                        max_size=3))
def test_a_parameter_set_is_refused_with_a_reason_or_applied_and_the_ticks_stay_finite(
        node, changes):
    before = _parameter_snapshot(node)
    settings_before = _simulation_settings(node)
    state_before = _state_arrays(node)
    try:
        parameters = [Parameter(name, value=value) for name, value in changes]
    except TypeError:
        return  # no ROS parameter type holds the value (a mixed list): nothing to send
    try:
        results = node.set_parameters_atomically(parameters)
    except ParameterNotDeclaredException:
        # rclpy's set_parameters_atomically service answers this with "not declared".
        results = SetParametersResult(successful=False, reason='not declared')
    if not results.successful:
        assert results.reason and '\n' not in results.reason, results.reason
        assert _parameter_snapshot(node) == before
        assert _simulation_settings(node) == settings_before  # nothing reaches it
        for state, again in zip(state_before, _state_arrays(node)):
            assert np.array_equal(state, again)
    _assert_finite_ticks(node)

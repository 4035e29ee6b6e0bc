"""
The node's parameters: declared once, documented, and applied to the scene.

The declarations run on in-process rclpy nodes with parameter overrides (what ``-p`` and
``--params-file`` give); no topics.  The node's use of them over DDS is in test_node_dds.py,
test_node_scenes.py and test_node_lifecycle.py.
"""

import math
from pathlib import Path
import re

import numpy as np
import pytest
from rcl_interfaces.msg import ParameterType
import rclpy
from rclpy.parameter import Parameter
from rigid_body_sim.node.parameters import check_integrator
from rigid_body_sim.node.parameters import declare_parameters
from rigid_body_sim.node.parameters import declare_scene_parameter
from rigid_body_sim.node.parameters import DEFAULTS
from rigid_body_sim.node.parameters import effective_values
from rigid_body_sim.node.parameters import given_overrides
from rigid_body_sim.node.parameters import imu_model_from_parameters
from rigid_body_sim.node.parameters import NAMESPACE_VALUE
from rigid_body_sim.node.parameters import NOT_SET
from rigid_body_sim.node.parameters import parameter_descriptor
from rigid_body_sim.node.parameters import PARAMETERS
from rigid_body_sim.node.parameters import scene_from_parameters
from rigid_body_sim.node.parameters import SCENE_VALUE
from rigid_body_sim.node.rigid_body_node import RigidBodyNode
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import scene_names
import yaml

CONFIG = Path(__file__).resolve().parent.parent / 'config' / 'rigid_body_sim.yaml'
RUNTIME_SETTABLE = {'integrator', 'substeps', 'tolerance', 'input_timeout', 'max_wrench',
                    'real_time_factor'}
# Without a fixed default: the scene's value, or (frame_prefix) the node's namespace's.
SCENE_DEPENDENT = {spec.name for spec in PARAMETERS
                   if spec.name not in DEFAULTS and spec.default is not NAMESPACE_VALUE}
NAMESPACE_DEPENDENT = {spec.name for spec in PARAMETERS if spec.default is NAMESPACE_VALUE}
TYPES = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
         float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING,
         list: ParameterType.PARAMETER_DOUBLE_ARRAY}


def flatten(tree, prefix=''):
    """Return {dotted.name: value} of a nested parameter dict."""
    flat = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            flat.update(flatten(value, f'{prefix}{key}.'))
        else:
            flat[f'{prefix}{key}'] = value
    return flat


@pytest.fixture(scope='module')
def context():
    """Give this module an rclpy context of its own."""
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


def declared(context, overrides=None):
    """
    Declare the node's parameters on a node with `overrides`; return (scene, values).

    As the node does: the scene parameter, the scene it names, then the rest.
    """
    node = rclpy.create_node(
        'rigid_body_sim', context=context, start_parameter_services=False,
        parameter_overrides=[Parameter(name, value=value)
                             for name, value in (overrides or {}).items()])
    try:
        given = given_overrides(node)
        scene = load_scene(declare_scene_parameter(node, given))
        return scene, declare_parameters(node, scene, given)
    finally:
        node.destroy_node()


def test_config_file_lists_every_parameter_with_its_default():
    """Values with a default are set to it; the scene's ones are commented-out examples."""
    text = CONFIG.read_text()
    document = yaml.safe_load(text)
    assert list(document) == ['/**/rigid_body_sim']
    values = flatten(document['/**/rigid_body_sim']['ros__parameters'])
    assert values == DEFAULTS
    for name, value in values.items():
        assert type(value) is type(DEFAULTS[name]), name
    # The commented-out keys, uncommented, are every scene-dependent parameter, each with
    # a value of its type: a user who uncomments one gets a valid override.
    body = text.split('ros__parameters:\n', 1)[1]
    examples = '\n'.join(line.replace('# ', '', 1) for line in body.splitlines()
                         if re.match(r'^\s*#\s*[a-z_]+:', line))
    commented = flatten(yaml.safe_load(examples))
    assert set(commented) == SCENE_DEPENDENT | NAMESPACE_DEPENDENT
    kinds = {spec.name: spec.kind for spec in PARAMETERS}
    for name, value in commented.items():
        assert isinstance(value, kinds[name]), name
        if isinstance(value, list):
            assert all(isinstance(v, float) for v in value), name


def test_every_parameter_has_a_typed_documented_descriptor():
    """Each descriptor has a description and its type; ranges contain a set default."""
    names = [spec.name for spec in PARAMETERS]
    assert len(names) == len(set(names))
    assert names[0] == 'scene'  # declared first: the others depend on it
    for spec in PARAMETERS:
        descriptor = parameter_descriptor(spec)
        assert descriptor.description, spec.name
        assert descriptor.type == TYPES[spec.kind], spec.name
        assert descriptor.read_only == (spec.name not in RUNTIME_SETTABLE), spec.name
        if spec.default in (NOT_SET, SCENE_VALUE):
            assert "the scene's" in descriptor.description, spec.name
            continue
        if spec.default is NAMESPACE_VALUE:
            assert "the node's namespace" in descriptor.description, spec.name
            continue
        assert isinstance(spec.default, spec.kind), spec.name
        for value_range in list(descriptor.floating_point_range) + \
                list(descriptor.integer_range):
            assert value_range.from_value <= spec.default <= value_range.to_value


def test_no_parameters_simulate_the_default_scene_as_it_is(context):
    """Nothing set: the default scene, its integrator, rate and tolerance, no override."""
    scene, values = declared(context)
    assert scene.name == 'default'
    assert values['integrator'] == scene.integrator and values['rate'] == scene.rate
    assert values['tolerance'] == scene.tolerance
    assert all(values[name] is None for name in SCENE_DEPENDENT
               if name not in ('integrator', 'rate', 'tolerance') and
               not name.startswith('imu.'))
    assert imu_model_from_parameters(values) == scene.imu
    assert scene_from_parameters(scene, values) is scene


@pytest.mark.parametrize('name', scene_names(several_bodies=False))
def test_the_shipped_config_file_leaves_every_scene_as_it_is(context, name):
    """Its defaults do not override a scene's body, state, integrator or rate."""
    document = yaml.safe_load(CONFIG.read_text())
    overrides = flatten(document['/**/rigid_body_sim']['ros__parameters'])
    overrides['scene'] = name
    scene, values = declared(context, overrides)
    assert (values['integrator'], values['rate']) == (scene.integrator, scene.rate)
    assert scene_from_parameters(scene, values) is scene


def test_integrator_and_rate_replace_the_scenes(context):
    """Set, they win; the body and state stay the scene's."""
    scene, values = declared(context, {'scene': 'heavy_top', 'integrator': 'rk4',
                                       'rate': 250.0})
    simulated = scene_from_parameters(scene, values)
    assert (simulated.integrator, simulated.rate) == ('rk4', 250.0)
    assert simulated.state == scene.state
    np.testing.assert_array_equal(simulated.body.inertia, scene.body.inertia)


def test_a_mass_keeps_the_scenes_shape_and_drawing():
    """Twice the mass of the driven box: twice its inertia, the same box drawn."""
    scene = load_scene('driven')
    heavier = scene_from_parameters(scene, {'body.mass': 2.0 * scene.body.mass})
    np.testing.assert_allclose(heavier.body.inertia, 2.0 * scene.body.inertia, rtol=1e-15)
    assert heavier.drawing == scene.drawing
    assert heavier.state == scene.state  # at rest: nothing to scale


def test_a_size_alone_resizes_the_scenes_shape():
    """body.size without body.shape: the scene's box with new edges, drawn so."""
    scene = scene_from_parameters(load_scene('driven'), {'body.size': [1.0, 2.0, 3.0]})
    np.testing.assert_allclose(scene.body.inertia,
                               RigidBody.box(load_scene('driven').body.mass,
                                             [1.0, 2.0, 3.0]).inertia, rtol=1e-15)
    assert scene.drawing.size == (1.0, 2.0, 3.0)


def test_full_inertia_is_read_row_major():
    """Nine numbers are the 3x3 tensor row by row."""
    tensor = np.array([[2.0, 0.1, 0.2], [0.1, 3.0, 0.3], [0.2, 0.3, 4.0]])
    scene = scene_from_parameters(load_scene('default'),
                                  {'body.inertia': tensor.ravel().tolist()})
    np.testing.assert_array_equal(scene.body.inertia, tensor)


@pytest.mark.parametrize('shape, size, expected, scale', [
    ('box', [1.0, 2.0, 3.0], RigidBody.box(2.0, [1.0, 2.0, 3.0]), (1.0, 2.0, 3.0)),
    ('cylinder', [0.5, 2.0], RigidBody.cylinder(2.0, 0.5, 2.0), (1.0, 1.0, 2.0)),
    ('sphere', [0.5], RigidBody.sphere(2.0, 0.5), (1.0, 1.0, 1.0)),
    ('ellipsoid', [1.0, 2.0, 3.0], RigidBody.ellipsoid(2.0, [1.0, 2.0, 3.0]),
     (2.0, 4.0, 6.0)),
])
def test_a_shape_gives_its_closed_form_inertia_and_drawing(shape, size, expected, scale):
    """body.shape with body.size and body.mass replaces the scene's body and drawing."""
    scene = scene_from_parameters(load_scene('default'),
                                  {'body.mass': 2.0, 'body.shape': shape, 'body.size': size})
    assert scene.body.mass == 2.0
    np.testing.assert_allclose(scene.body.inertia, expected.inertia, rtol=1e-15)
    assert (scene.drawing.shape, scene.drawing.size) == (shape, scale)
    # The scene's angular velocity is kept for the new body (not its angular momentum).
    np.testing.assert_allclose(scene.state.angular_velocity_body(scene.body),
                               load_scene('default').state.angular_velocity_body(
                                   load_scene('default').body), rtol=1e-14)


def test_initial_state_follows_the_parameters():
    """Orientation, position, velocity and body angular velocity give the initial state."""
    quaternion = np.array([0.0, 0.0, np.sin(0.25), np.cos(0.25)])
    scene = scene_from_parameters(load_scene('default'), {
        'initial.orientation': quaternion.tolist(), 'initial.position': [1.0, 2.0, 3.0],
        'initial.velocity': [0.5, 0.0, 0.0], 'initial.angular_velocity_body': [0.0, 0.0, 1.0],
        'body.mass': 2.0})
    body, state = scene.body, scene.state
    np.testing.assert_allclose(state.quaternion, quaternion, rtol=1e-15)
    np.testing.assert_array_equal(state.position, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(state.linear_momentum, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(state.angular_velocity_body(body), [0.0, 0.0, 1.0],
                               atol=1e-15)


def test_a_world_angular_velocity_replaces_the_scenes_body_one():
    """initial.angular_velocity_world is the world-frame omega of the initial state."""
    quaternion = [0.0, math.sin(0.4), 0.0, math.cos(0.4)]
    scene = scene_from_parameters(load_scene('t_handle'), {
        'initial.orientation': quaternion, 'initial.angular_velocity_world': [0.0, 0.0, 3.0]})
    np.testing.assert_allclose(scene.state.angular_velocity(scene.body), [0.0, 0.0, 3.0],
                               atol=1e-14)


def test_a_pivot_scene_keeps_its_body_on_the_pivot():
    """heavy_top with another tilt: the COM follows the pivot from the new orientation."""
    tilt = 0.5
    scene = scene_from_parameters(load_scene('heavy_top'), {
        'initial.orientation': [math.sin(tilt / 2.0), 0.0, 0.0, math.cos(tilt / 2.0)]})
    pivot = scene.pivot
    np.testing.assert_allclose(scene.state.position + scene.state.rotation @ pivot.point,
                               pivot.anchor, atol=1e-15)


def test_a_nearly_unit_quaternion_is_normalised():
    """Four decimals of a unit quaternion are accepted and made exactly unit."""
    scene = scene_from_parameters(load_scene('default'),
                                  {'initial.orientation': [0.0, 0.0, 0.7071, 0.7071]})
    assert np.linalg.norm(scene.state.quaternion) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize('scene_name, values, words', [
    ('default', {'body.inertia': [1.0, 2.0]}, "'body.inertia' must have 9 values"),
    ('default', {'body.inertia': [1.0, 1.0, 3.0]}, 'triangle inequality'),
    ('default', {'body.mass': -1.0}, 'body.mass: must be > 0 kg'),
    ('default', {'body.shape': 'cube', 'body.size': [1.0]}, "got 'cube'"),
    ('default', {'body.shape': 'sphere', 'body.size': [1.0, 2.0]},
     "'body.size' of a sphere must have 1 value(s)"),
    ('default', {'body.size': [1.0, 2.0, 3.0]}, "'body.size' needs body.shape"),
    ('driven', {'body.shape': 'sphere'}, 'set body.size too'),
    ('default', {'body.shape': 'box', 'body.size': [1.0, 2.0, 3.0],
                 'body.inertia': [1.0, 2.0, 3.0]}, 'body.shape (with body.size) or'),
    ('default', {'initial.orientation': [0.0, 0.0, 0.0, 2.0]},
     "'initial.orientation' must be a unit"),
    ('default', {'initial.position': [0.0, 0.0]}, 'initial.position: expected 3 numbers'),
    ('default', {'initial.velocity': [0.0, float('nan'), 0.0]},
     'initial.velocity: expected finite numbers'),
    ('default', {'initial.angular_velocity_body': [0.0, 0.0, 1.0],
                 'initial.angular_velocity_world': [0.0, 1.0, 0.0]}, 'disagree'),
    ('heavy_top', {'initial.position': [0.0, 0.0, 1.0]}, 'not allowed with a pivot'),
    ('default', {'integrator': 'euler'}, "parameter 'integrator': unknown integrator"),
])
def test_an_invalid_configuration_names_what_is_wrong(scene_name, values, words):
    """Every rejected value gives a ValueError naming the parameter and the rule."""
    with pytest.raises(ValueError, match=re.escape(words)):
        scene_from_parameters(load_scene(scene_name), values)


def test_a_wrongly_typed_override_names_the_type_it_needs(context):
    """ROS parameters are typed: an integer rate is refused with an example."""
    with pytest.raises(ValueError, match=re.escape(
            "parameter 'rate' must be a double; got 100 (ROS parameters are typed")):
        declared(context, {'rate': 100})
    with pytest.raises(ValueError, match="parameter 'body.mass' must be a double"):
        declared(context, {'body.mass': 'heavy'})


def test_integrator_check_lists_the_valid_names():
    """A known name passes; an unknown one gets a reason that lists the valid ones."""
    assert check_integrator('buss') is None
    reason = check_integrator('euler')
    assert "unknown integrator 'euler'" in reason and 'rk4' in reason


ROUND_TRIP_OVERRIDES = [
    {},
    {'body.mass': 2.5},
    {'initial.orientation': [0.1, 0.0, 0.0, 0.99498743710662]},
    {'initial.angular_velocity_world': [0.3, -0.2, 1.1]},
    {'initial.angular_velocity_body': [0.3, -0.2, 1.1], 'body.mass': 0.7},
    {'body.inertia': [1.5, 2.5, 3.5]},
]


@pytest.mark.parametrize('overrides', ROUND_TRIP_OVERRIDES, ids=str)
@pytest.mark.parametrize('scene_name', scene_names(several_bodies=False))
def test_the_values_a_node_shows_given_back_make_the_same_scene_bit_for_bit(
        scene_name, overrides):
    """A parameter dump (every value set) loaded back changes nothing, in every scene."""
    scene = load_scene(scene_name)
    if scene.pivot is not None:
        overrides = {k: v for k, v in overrides.items() if 'velocity' not in k}
    try:
        first = scene_from_parameters(scene, overrides)
    except ValueError:
        pytest.skip('an override this scene refuses')  # e.g. an inertia against its shape
    shown = effective_values(first)
    dumped = {**shown, **overrides}  # what the node shows: the given values as given
    second = scene_from_parameters(scene, dumped)
    for field in ('quaternion', 'position', 'linear_momentum', 'angular_momentum'):
        assert np.array_equal(getattr(first.state, field), getattr(second.state, field)), field
    assert np.array_equal(first.body.inertia, second.body.inertia)
    assert first.body.mass == second.body.mass
    assert first.drawing == second.drawing
    assert effective_values(second) == shown


def test_every_parameter_of_a_started_node_has_a_value(context):
    """Tools that get every listed parameter (ros2 param dump) get none if one is unset."""
    node = RigidBodyNode(context=context, start_parameter_services=False)
    try:
        for name in node._parameters:
            parameter = node.get_parameter(name)  # raises for an unset one
            assert parameter.type_ != Parameter.Type.NOT_SET, name
        shown = effective_values(node._scene)
        assert list(node.get_parameter('body.inertia').value) == shown['body.inertia']
        assert node.get_parameter('body.size').type_ == Parameter.Type.DOUBLE_ARRAY
        assert node.describe_parameter('body.mass').read_only
    finally:
        node.destroy_node()

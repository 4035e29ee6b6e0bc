"""
The node's parameters: declared once, documented, and turned into a body and a state.

No DDS here; the node's use of them is in test_node_dds.py and test_node_lifecycle.py.
"""

from pathlib import Path

import numpy as np
import pytest
from rcl_interfaces.msg import ParameterType
from rigid_body_sim.defaults import default_body
from rigid_body_sim.defaults import default_state
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.ros.parameters import body_and_state_from_parameters
from rigid_body_sim.ros.parameters import check_integrator
from rigid_body_sim.ros.parameters import DEFAULTS
from rigid_body_sim.ros.parameters import parameter_descriptor
from rigid_body_sim.ros.parameters import PARAMETERS
import yaml

CONFIG = Path(__file__).resolve().parent.parent / 'config' / 'rigid_body_sim.yaml'
RUNTIME_SETTABLE = {'integrator', 'substeps', 'input_timeout', 'max_wrench'}


def flatten(tree, prefix=''):
    """Return {dotted.name: value} of a nested parameter dict."""
    flat = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            flat.update(flatten(value, f'{prefix}{key}.'))
        else:
            flat[f'{prefix}{key}'] = value
    return flat


def test_config_file_lists_every_parameter_with_its_default():
    """config/rigid_body_sim.yaml is the declared defaults, same names, types and values."""
    document = yaml.safe_load(CONFIG.read_text())
    assert list(document) == ['/**/rigid_body_sim']
    values = flatten(document['/**/rigid_body_sim']['ros__parameters'])
    assert values == DEFAULTS
    for name, value in values.items():
        assert type(value) is type(DEFAULTS[name]), name
        if isinstance(value, list):
            assert all(isinstance(v, float) for v in value), name


def test_every_parameter_has_a_typed_documented_descriptor():
    """Each descriptor has a description and the default's type; ranges contain it."""
    names = [spec.name for spec in PARAMETERS]
    assert len(names) == len(set(names))
    for spec in PARAMETERS:
        descriptor = parameter_descriptor(spec)
        assert descriptor.description, spec.name
        assert descriptor.type != ParameterType.PARAMETER_NOT_SET
        assert descriptor.read_only == (spec.name not in RUNTIME_SETTABLE), spec.name
        for value_range in list(descriptor.floating_point_range) + \
                list(descriptor.integer_range):
            assert value_range.from_value <= spec.default <= value_range.to_value


def test_defaults_are_the_default_body_and_state():
    """No parameters given: the T-handle of rigid_body_sim.defaults, in its initial state."""
    body, state = body_and_state_from_parameters({})
    expected_body = default_body()
    assert body.mass == expected_body.mass
    np.testing.assert_array_equal(body.inertia, expected_body.inertia)
    assert state == default_state(expected_body)


def test_full_inertia_is_read_row_major():
    """Nine numbers are the 3x3 tensor row by row."""
    tensor = np.array([[2.0, 0.1, 0.2], [0.1, 3.0, 0.3], [0.2, 0.3, 4.0]])
    body, _ = body_and_state_from_parameters({'body.inertia': tensor.ravel().tolist()})
    np.testing.assert_array_equal(body.inertia, tensor)


@pytest.mark.parametrize('shape, size, expected', [
    ('box', [1.0, 2.0, 3.0], RigidBody.box(2.0, [1.0, 2.0, 3.0])),
    ('cylinder', [0.5, 2.0], RigidBody.cylinder(2.0, 0.5, 2.0)),
    ('sphere', [0.5], RigidBody.sphere(2.0, 0.5)),
    ('ellipsoid', [1.0, 2.0, 3.0], RigidBody.ellipsoid(2.0, [1.0, 2.0, 3.0])),
])
def test_a_shape_gives_its_closed_form_inertia(shape, size, expected):
    """body.shape with body.size and body.mass replaces body.inertia."""
    body, _ = body_and_state_from_parameters(
        {'body.mass': 2.0, 'body.shape': shape, 'body.size': size,
         'body.inertia': [9.0, 9.0, 9.0]})
    assert body.mass == 2.0
    np.testing.assert_allclose(body.inertia, expected.inertia, rtol=1e-15)


def test_initial_state_follows_the_parameters():
    """Orientation, position, velocity and body angular velocity give the initial state."""
    quaternion = np.array([0.0, 0.0, np.sin(0.25), np.cos(0.25)])
    body, state = body_and_state_from_parameters({
        'initial.orientation': quaternion.tolist(), 'initial.position': [1.0, 2.0, 3.0],
        'initial.velocity': [0.5, 0.0, 0.0], 'initial.angular_velocity_body': [0.0, 0.0, 1.0],
        'body.mass': 2.0})
    np.testing.assert_allclose(state.quaternion, quaternion, rtol=1e-15)
    np.testing.assert_array_equal(state.position, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(state.linear_momentum, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(state.angular_velocity_body(body), [0.0, 0.0, 1.0],
                               atol=1e-15)


def test_a_nearly_unit_quaternion_is_normalised():
    """Four decimals of a unit quaternion are accepted and made exactly unit."""
    _, state = body_and_state_from_parameters(
        {'initial.orientation': [0.0, 0.0, 0.7071, 0.7071]})
    assert np.linalg.norm(state.quaternion) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize('values, words', [
    ({'body.inertia': [1.0, 2.0]}, 'body.inertia must have 9 values'),
    ({'body.inertia': [1.0, 1.0, 3.0]}, 'triangle inequality'),
    ({'body.mass': -1.0}, 'mass must be > 0'),
    ({'body.shape': 'cube'}, "got 'cube'"),
    ({'body.shape': 'sphere', 'body.size': [1.0, 2.0]}, 'a sphere needs 1 size value'),
    ({'initial.orientation': [0.0, 0.0, 0.0, 2.0]}, "'initial.orientation' must be a unit"),
    ({'initial.position': [0.0, 0.0]}, "'initial.position' must have 3 values"),
    ({'initial.velocity': [0.0, float('nan'), 0.0]}, "'initial.velocity' must be finite"),
])
def test_an_invalid_configuration_names_what_is_wrong(values, words):
    """Every rejected value gives a ValueError naming the parameter and the rule."""
    with pytest.raises(ValueError, match=words):
        body_and_state_from_parameters(values)


def test_integrator_check_lists_the_valid_names():
    """A known name passes; an unknown one gets a reason that lists the valid ones."""
    assert check_integrator('buss') is None
    reason = check_integrator('euler')
    assert "unknown integrator 'euler'" in reason and 'rk4' in reason

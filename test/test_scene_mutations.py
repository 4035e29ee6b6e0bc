"""
Every shipped scene, every key given a value of the wrong kind: a clean error or a valid run.

A deterministic fuzz over the built-in scene files: each key path of each scene (sections,
leaves and list items) is replaced in turn by each of a set of hostile values (a nested list,
a mapping, a bool, null, a string, huge and non-finite numbers, an empty list, zero).  The
scene reader must then either refuse with one line that names the file (a ValueError, no
other exception, no numpy warning on the way) or accept a scene whose inertia, state and
first ticks are finite.  The issue's finds are checked by name below.
"""

import copy
import math
import warnings

import numpy as np
import pytest
from rigid_body_sim.physics import unresolved_rotation
from rigid_body_sim.scenes import find_scene
from rigid_body_sim.scenes import parse_scene
from rigid_body_sim.scenes import scene_names
import yaml

SOURCE = 'fuzz.yaml'
HOSTILE = ([[1, 2, 3], [2, 1, 0], [3, 0, 1]], {'a': 1}, True, None, 'text', 1.0e308,
           -1.0e308, math.nan, math.inf, [], 0, [0.05, 12.0, 1.0e308])


def _paths(value, prefix=()):
    """Yield the key path (a tuple of keys and indices) of every node under value."""
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return
    for key, item in items:
        path = prefix + (key,)
        yield path
        yield from _paths(item, path)


def _replaced(data, path, value):
    mutated = copy.deepcopy(data)
    target = mutated
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = copy.deepcopy(value)
    return mutated


def _documents():
    for name in scene_names(several_bodies=False):
        with open(find_scene(name)) as scene_file:
            yield name, yaml.safe_load(scene_file)


def _check_one(data):
    """Parse a mutated scene: return 'refused' or 'accepted' (or fail the test)."""
    with warnings.catch_warnings():
        warnings.simplefilter('error')  # a numpy RuntimeWarning is a failure here
        try:
            scene = parse_scene(data, SOURCE)
        except ValueError as error:
            message = str(error)
            assert message.startswith(f'{SOURCE}: ') and '\n' not in message, message
            return 'refused'
        assert np.all(np.isfinite(scene.body.inertia))
        state = scene.state
        assert np.all(np.isfinite(state.angular_momentum))
        assert math.isfinite(state.kinetic_energy(scene.body))
        simulator = scene.simulator()
        if unresolved_rotation(scene.body, state, scene.dt, 1, scene.tolerance) is None:
            for _ in range(3):
                simulator.step(scene.dt)
            assert np.all(np.isfinite(simulator.state.angular_momentum))
            assert np.all(np.isfinite(simulator.state.quaternion))
    return 'accepted'


def test_every_key_of_every_shipped_scene_with_a_hostile_value_is_refused_cleanly_or_valid():
    outcomes = {'refused': 0, 'accepted': 0}
    for name, data in _documents():
        for path in _paths(data):
            for value in HOSTILE:
                mutated = _replaced(data, path, value)
                try:
                    outcomes[_check_one(mutated)] += 1
                except AssertionError as error:
                    raise AssertionError(f'{name}: {path} = {value!r}: {error}') from None
    # Most hostile values must be refused; some are valid (0 for a tolerance, a string
    # for a description) and then ran finite.
    assert outcomes['refused'] > 10 * outcomes['accepted'] > 0, outcomes


def _default_with(section, key, value):
    data = next(data for name, data in _documents() if name == 'default')
    return _replaced(data, (section, key), value)


def test_a_shape_of_the_wrong_yaml_type_names_the_key():
    data = _default_with('body', 'shape', [[1, 2, 3], [2, 1, 0], [3, 0, 1]])
    data['body'].pop('inertia', None)
    with pytest.raises(ValueError, match=r'^fuzz\.yaml: body(\.shape)?: '):
        parse_scene(data, SOURCE)


def test_a_mass_that_overflows_the_inertia_names_body_mass_without_numpy_warnings():
    data = {'name': 'big', 'description': 'huge mass',
            'body': {'mass': 1.0e308, 'shape': 'box', 'size': [1.0, 2.0, 3.0]}}
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        with pytest.raises(ValueError, match=r'^fuzz\.yaml: body\.mass: 1e\+308 kg'):
            parse_scene(data, SOURCE)


@pytest.mark.parametrize('omega', [[0.05, 12.0, 1.0e308], [0.0, 0.0, 1.0e200]])
def test_a_state_whose_momentum_or_energy_is_not_finite_is_refused(omega):
    data = {'name': 'fast', 'description': 'overflowing spin',
            'body': {'mass': 1.0, 'inertia': [1.0, 2.0, 3.0]},
            'initial': {'angular_velocity_body': omega}}
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        with pytest.raises(ValueError,
                           match=r'^fuzz\.yaml: initial\.angular_velocity_body: .*not finite'):
            parse_scene(data, SOURCE)


def test_a_spin_the_steps_cannot_resolve_is_warned_about_naming_rate_and_substeps():
    data = {'name': 'fast', 'description': 'too fast for the step',
            'body': {'mass': 1.0, 'inertia': [1.0, 2.0, 3.0]},
            'initial': {'angular_velocity_body': [0.0, 0.0, 1.0e10]}, 'rate': 1000}
    scene = parse_scene(data, SOURCE)
    # |omega| h = 1e10 rad/s x 1e-3 s = 1e7 rad per step at one substep.
    warning = unresolved_rotation(scene.body, scene.state, scene.dt, 1, None)
    assert warning is not None and '1e+07 rad per integrator step' in warning
    assert 'rate' in warning and 'substeps' in warning
    # 0.4 rad per step is resolved: no warning.
    data['initial']['angular_velocity_body'] = [0.0, 0.0, 400.0]
    scene = parse_scene(data, SOURCE)
    assert unresolved_rotation(scene.body, scene.state, scene.dt, 1, None) is None


@pytest.mark.parametrize('key', ['\n', 'b\tad', '\x1b[31m'])
def test_a_key_with_a_control_character_is_named_escaped_in_one_line(key):
    data = {'name': 'x', 'description': 'y', 'body': {'mass': 1.0, 'inertia': [1.0, 2.0, 3.0]},
            'effects': [{'pivot': {key: None}}]}
    with pytest.raises(ValueError) as raised:
        parse_scene(data, SOURCE)
    message = str(raised.value)
    assert message.isprintable() and repr(key)[1:-1] in message, message

"""
Scene files: loading, strict validation with messages naming file and key path, overrides.

The physics of each built-in scene is tested in test_scene_physics.py.
"""

import copy
import math
import os
import re
import signal
import subprocess
import sys

import numpy as np
import pytest
from reference import random_rotation
from rigid_body_sim import cli
from rigid_body_sim.paths import scenes_dir
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics.effects import effect_parameters
from rigid_body_sim.physics.effects import EFFECTS
from rigid_body_sim.physics.effects import register_effect
from rigid_body_sim.physics.effects.registry import check_number
from rigid_body_sim.physics.effects.registry import Effect
from rigid_body_sim.physics.kernels.model import wrench_term
from rigid_body_sim.physics.rotations import matrix_from_quaternion
from rigid_body_sim.scenes import DEFAULT_SCENE
from rigid_body_sim.scenes import find_scene
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import parse_scene
from rigid_body_sim.scenes import read_scene_yaml
from rigid_body_sim.scenes import scene_names
import yaml

BUILTIN_SCENES = ('bike_wheel', 'constellation', 'debris_field', 'default', 'driven',
                  'flat_spin', 'heavy_top', 'juggling_clubs', 'stable_spin', 't_handle',
                  'tennis_racket', 'thrown_box', 'van_zon')
SEVERAL_BODIES = ('constellation', 'debris_field', 'juggling_clubs')
SOURCE = 'scenes/heavy_top.yaml'


def _heavy_top_data():
    with open(find_scene('heavy_top'), encoding='utf-8') as stream:
        return yaml.safe_load(stream)


# -- built-in scenes


def test_every_builtin_scene_loads_under_its_file_name():
    assert set(scene_names()) == set(BUILTIN_SCENES)
    assert scene_names(several_bodies=True) == list(SEVERAL_BODIES)
    assert scene_names(several_bodies=False) == sorted(
        set(BUILTIN_SCENES) - set(SEVERAL_BODIES))
    for name in BUILTIN_SCENES:
        scene = load_scene(name)
        assert scene.name == name
        assert scene.source == f'scenes/{name}.yaml'
        assert scene.description and '\n' not in scene.description
        assert scene.integrator in INTEGRATORS
        assert scene.rate > 0.0


def test_default_scene_is_the_t_handle_with_external_wrench():
    default, t_handle = load_scene(DEFAULT_SCENE), load_scene('t_handle')
    assert default.accepts_external_wrench and default.external_wrench is not None
    assert not t_handle.accepts_external_wrench and t_handle.external_wrench is None
    # The same body and state (`rigid-body-sim run` simulates them too).
    assert default.body.mass == t_handle.body.mass
    np.testing.assert_array_equal(default.body.inertia, t_handle.body.inertia)
    assert default.state == t_handle.state
    assert default.integrator == t_handle.integrator and default.rate == t_handle.rate


def test_only_scenes_naming_external_wrench_accept_outside_input():
    accepting = {name for name in BUILTIN_SCENES if load_scene(name).accepts_external_wrench}
    assert accepting == {'default', 'driven'}


def test_torque_free_scenes_build_simulators_without_any_wrench():
    for name in ('t_handle', 'stable_spin', 'tennis_racket', 'van_zon', 'default', 'driven',
                 'flat_spin'):
        simulator = load_scene(name).simulator()
        assert simulator.wrench_function() is None, name
    for name in ('heavy_top', 'bike_wheel', 'thrown_box'):
        assert load_scene(name).simulator().wrench_function() is not None, name


def test_scene_simulator_carries_the_scene_effects_integrator_and_state():
    scene = load_scene('heavy_top')
    simulator = scene.simulator()
    assert simulator.effects == scene.effects
    assert simulator.integrator == scene.integrator
    assert simulator.state == scene.state
    assert scene.simulator(integrator='rk4').integrator == 'rk4'
    assert scene.pivot is scene.effects[0]
    assert scene.dt == pytest.approx(1e-3)


def test_pivot_scene_state_starts_on_the_constraint():
    for name in ('heavy_top', 'bike_wheel'):
        scene = load_scene(name)
        state, pivot = scene.state, scene.pivot
        np.testing.assert_allclose(state.position + state.rotation @ pivot.point, pivot.anchor,
                                   atol=1e-15)


def _schema_comment():
    text = find_scene(DEFAULT_SCENE).read_text(encoding='utf-8')
    return [line for line in text.splitlines() if line.startswith('#')]


def _schema_problems():
    """
    Return what the schema comment of default.yaml gets wrong about the effects, if anything.

    The registry is the authority on effects and `rigid-body-sim scenes --effects` prints it;
    the schema documents some effects and points there.  So an effect it names must exist
    with the parameters it names, and a new effect needs no edit of the schema.
    """
    lines = _schema_comment()
    prose = ' '.join(line.lstrip('#').strip() for line in lines)
    problems = []
    if '`rigid-body-sim scenes --effects`' not in prose:
        problems.append('does not point to `rigid-body-sim scenes --effects`')
    listed = re.findall(r'^#\s+- (\w+)', '\n'.join(lines), flags=re.MULTILINE)
    if not listed:
        problems.append('documents no effect')
    for name in listed:
        if name not in EFFECTS:
            problems.append(f'documents {name!r}, which is not a registered effect')
            continue
        for parameter in effect_parameters(name):
            if f'{parameter}:' not in prose:
                problems.append(f'documents {name!r} without its parameter {parameter!r}')
    return problems


def test_the_schema_comment_documents_every_key_and_only_registered_effects():
    assert _schema_problems() == []
    schema = '\n'.join(_schema_comment())
    for key in ('name:', 'description:', 'body:', 'mass:', 'shape:', 'size:', 'radius:',
                'height:', 'semi_axes:', 'inertia:', 'initial:', 'orientation:',
                'angular_velocity_body:', 'angular_velocity_world:', 'position:', 'velocity:',
                'effects:', 'integrator:', 'rate:', 'draw:', 'color:'):
        assert key in schema, key


def test_the_schema_check_sees_an_effect_it_documents_wrongly(monkeypatch):
    # The check above can fail: without pivot in the registry, the schema's '- pivot' is wrong.
    monkeypatch.delitem(EFFECTS, 'pivot')
    assert _schema_problems() == ["documents 'pivot', which is not a registered effect"]


# -- strict validation: every error names the file, the key path and the problem


def _set(data, path, value):
    keys = path.split('.')
    target = data
    for key in keys[:-1]:
        target = target[int(key)] if isinstance(target, list) else target.setdefault(key, {})
    last = int(keys[-1]) if isinstance(target, list) else keys[-1]
    if value is _DELETE:
        del target[last]
    else:
        target[last] = value


_DELETE = object()


@pytest.mark.parametrize('path, value, message', [
    ('colour', 'red', 'colour: unknown key; the scene takes: name, description'),
    ('name', _DELETE, 'name: missing'),
    ('description', 3, 'description: expected a non-empty string, got int 3'),
    ('description', 'two\nlines', 'description: expected one line'),
    ('body.mass', '0.3', "body.mass: expected a number in kg, got the string '0.3'"),
    ('body.mass', -1.0, 'body.mass: must be > 0 kg, got -1'),
    ('body.mass', True, 'body.mass: expected a number in kg, got the boolean true'),
    ('body.mass', _DELETE, 'body.mass: missing'),
    ('body.shape', 'cone', 'body.shape: expected one of box, cylinder, sphere, ellipsoid'),
    ('body.size', [1, 2, 3], 'body.size: not a size of shape cylinder; it takes: radius, height'),
    ('body.height', _DELETE, 'body.height: missing; shape cylinder requires it'),
    ('body.radius', 0.0, 'body.radius: must be > 0 m, got 0'),
    ('body.inertia', [1, 2, 3], 'body: give shape (with its sizes) or inertia, not both'),
    ('body.density', 1.0, 'body.density: unknown key'),
    ('initial.spin', 1.0, 'initial.spin: unknown key'),
    ('initial.orientation', [0, 0, 0, 2], 'initial.orientation: expected a unit quaternion'),
    ('initial.orientation', [0, 0, 1], 'initial.orientation: expected 4 numbers'),
    ('initial.angular_velocity_world', [0, 0, 1],
     'initial: give angular_velocity_body or angular_velocity_world, not both'),
    ('initial.angular_velocity_body', [0, 'fast', 1],
     'initial.angular_velocity_body: expected 3 numbers, item 1 is the string'),
    ('initial.position', [0, 0, 1], 'initial.position: not allowed with a pivot'),
    ('effects.0.pivot.point', [0, 0], 'effects[0].pivot.point: expected 3 numbers, got 2'),
    ('effects.0.pivot.place', [0, 0, 1], 'effects[0].pivot.place: unknown parameter'),
    ('effects.0.pivot', [0, 0, 1], 'effects[0].pivot: expected a mapping of parameters'),
    ('effects.1', 'gravitation', "effects[1]: unknown effect 'gravitation'; valid effects:"),
    ('effects.1', 'pivot', "effects[1]: effect 'pivot' is named twice"),
    ('effects.1', {'gravity': {}, 'drag': {}}, 'effects[1]: expected an effect name or'),
    ('effects', 'gravity', 'effects: expected a list of effects'),
    ('integrator', 'verlet', "integrator: unknown integrator 'verlet'; valid: "),
    ('integrator', ['buss'], "integrator: unknown integrator ['buss']; valid: "),
    ('rate', 0, 'rate: must be > 0 Hz, got 0'),
    ('draw.color', [1, 0, 2], 'draw.color: each of r, g, b, a must be in 0..1'),
    ('draw.shape', 'cone', 'draw.shape: expected one of'),
    ('draw.size', [1, -1, 1], 'draw.size: must be > 0 m'),
])
def test_scene_errors_name_the_file_the_key_path_and_the_problem(path, value, message):
    data = _heavy_top_data()
    _set(data, path, value)
    with pytest.raises(ValueError) as caught:
        parse_scene(data, SOURCE)
    assert str(caught.value).startswith(f'{SOURCE}: {message}'), str(caught.value)


def test_non_physical_bodies_are_errors_naming_the_rule():
    data = _heavy_top_data()
    data['body'] = {'mass': 1.0, 'inertia': [1.0, 1.0, 3.0]}
    with pytest.raises(ValueError, match=r'^scenes/heavy_top.yaml: body.inertia: principal '
                                         r'moments must satisfy the triangle inequality'):
        parse_scene(data, SOURCE)
    data['body'] = {'mass': 1.0, 'inertia': [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]}
    with pytest.raises(ValueError, match=r'body.inertia: inertia tensor must be symmetric'):
        parse_scene(data, SOURCE)
    data['body'] = {'mass': 1.0, 'inertia': [1.0, -2.0, 2.0]}
    with pytest.raises(ValueError, match=r'body.inertia: inertia tensor must be positive '):
        parse_scene(data, SOURCE)


def test_a_full_inertia_tensor_is_accepted_as_rows_or_nine_numbers():
    data = _heavy_top_data()
    tensor = [[2.0, 0.1, 0.0], [0.1, 3.0, 0.2], [0.0, 0.2, 4.0]]
    data['body'] = {'mass': 1.0, 'inertia': tensor}
    np.testing.assert_array_equal(parse_scene(data, SOURCE).body.inertia, tensor)
    data['body']['inertia'] = sum(tensor, [])
    np.testing.assert_array_equal(parse_scene(data, SOURCE).body.inertia, tensor)


def test_files_that_are_not_scenes_are_errors_naming_the_file(tmp_path):
    broken = tmp_path / 'broken.yaml'
    broken.write_text('name: [unclosed\n', encoding='utf-8')
    with pytest.raises(ValueError, match=f'^{broken}: not valid YAML'):
        load_scene(str(broken))
    listing = tmp_path / 'list.yaml'
    listing.write_text('- a\n- b\n', encoding='utf-8')
    with pytest.raises(ValueError, match=f'^{listing}: expected a mapping of keys, got a list'):
        load_scene(str(listing))
    with pytest.raises(ValueError, match='does not exist'):
        load_scene(str(tmp_path / 'missing.yaml'))
    with pytest.raises(ValueError, match='is a directory; give the path of a .yaml file'):
        load_scene(str(tmp_path) + '/')
    with pytest.raises(ValueError, match="unknown scene 'nope'; built-in scenes: bike_wheel"):
        load_scene('nope')


def test_a_scene_path_that_is_no_regular_file_says_what_it_is_without_reading_it(tmp_path):
    """
    A FIFO, a device, a symlink loop, a broken symlink: one line saying what the path is.

    Each was "does not exist".  The FIFO is given to the command line in a process of its
    own: opening it would block until a writer came, and the process would not end.
    """
    fifo = tmp_path / 'fifo.yaml'
    os.mkfifo(fifo)
    done = subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'scenes', str(fifo)],
                          capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
    assert done.returncode != 0
    assert done.stderr.strip().splitlines()[-1].endswith(
        f"scene '{fifo}' is a FIFO (named pipe), not a regular file; give the path of a "
        '.yaml file'), done.stderr
    loop = tmp_path / 'loop.yaml'
    loop.symlink_to(tmp_path / 'other.yaml')
    (tmp_path / 'other.yaml').symlink_to(loop)
    dangling = tmp_path / 'dangling.yaml'
    dangling.symlink_to(tmp_path / 'gone.yaml')
    for path, kind in (('/dev/zero', 'a character device'), (str(loop), 'a symlink loop'),
                       (str(dangling), 'a broken symlink')):
        with pytest.raises(ValueError, match=f'^scene {re.escape(repr(path))} is {kind}, not '
                                             'a regular file'):
            load_scene(path)


def test_a_scene_file_anywhere_loads_by_path(tmp_path):
    path = tmp_path / 'mine.yaml'
    path.write_text(
        'name: mine\n'
        'description: a sphere falling with drag\n'
        'body: {mass: 2.0, shape: sphere, radius: 0.1}\n'
        'initial: {position: [0, 0, 10]}\n'
        'effects: [gravity, {drag: {quadratic: 0.01}}]\n', encoding='utf-8')
    scene = load_scene(str(path))
    assert scene.name == 'mine' and scene.source == str(path)
    assert scene.effect_names() == ['gravity', 'drag']
    assert scene.integrator == 'buss' and scene.rate == 100.0
    assert scene.drawing.shape == 'sphere' and scene.drawing.size == (0.2, 0.2, 0.2)
    np.testing.assert_array_equal(scene.state.position, [0.0, 0.0, 10.0])


# -- the YAML itself: duplicate keys, YAML 1.2 numbers, empty sections

# A small valid scene file; tests append or replace lines.
MINE = ('name: mine\n'
        'description: a box\n'
        'body:\n'
        '  mass: 2.0\n'
        '  shape: box\n'
        '  size: [0.3, 0.2, 0.1]\n')


def _write(tmp_path, text):
    path = tmp_path / 'mine.yaml'
    path.write_text(text, encoding='utf-8')
    return str(path)


@pytest.mark.parametrize('text, message', [
    (MINE + 'name: other\n', 'name: duplicate key (lines 1 and 7)'),
    (MINE + '  size: [1.0, 1.0, 1.0]\n', 'body.size: duplicate key (lines 6 and 7)'),
    (MINE + '  "size": [1, 1, 1]\n', 'body.size: duplicate key (lines 6 and 7)'),
    (MINE + 'effects:\n  - pivot: {point: [0, 0, 1], point: [0, 0, 2]}\n',
     'effects[0].pivot.point: duplicate key (line 8, columns 13 and 31)'),
    (MINE + 'draw: {color: [1, 0, 0], shape: box, color: [0, 1, 0]}\n',
     'draw.color: duplicate key (line 7, columns 8 and 38)'),
], ids=['top_level', 'nested', 'quoted_and_plain', 'effect_parameter', 'flow_mapping'])
def test_a_key_given_twice_is_an_error_naming_its_path_and_lines(tmp_path, text, message):
    # yaml.safe_load keeps the last value silently: the scene would run with one of two
    # sizes the author wrote.
    path = _write(tmp_path, text)
    with pytest.raises(ValueError) as caught:
        load_scene(path)
    assert str(caught.value) == f'{path}: {message}; give each key once'


def test_merge_keys_and_aliases_are_not_duplicates(tmp_path):
    # A YAML merge (<<) overridden by an explicit key is that key written once in this
    # mapping; an alias repeats a value, not a key.
    text = (MINE.replace('  mass: 2.0\n', '  <<: {mass: 1.0}\n  mass: 2.0\n')
            + 'initial:\n  position: &p [0, 0, 1]\n  velocity: *p\n')
    scene = load_scene(_write(tmp_path, text))
    assert scene.body.mass == 2.0
    np.testing.assert_array_equal(scene.state.position, [0.0, 0.0, 1.0])


@pytest.mark.parametrize('text, value', [
    ('1e-3', 1e-3), ('1E+3', 1000.0), ('2.5e-1', 0.25), ('1.0e3', 1000.0), ('.5', 0.5),
    ('-.5', -0.5), ('+.5', 0.5), ('1.', 1.0), ('-2', -2), ('010', 10), ('0o10', 8),
    ('0x1F', 31), ('.inf', math.inf), ('-.Inf', -math.inf),
])
def test_numbers_are_read_in_yaml_1_2_forms(text, value):
    # PyYAML's YAML 1.1 resolver wants a dot and a signed exponent (1e-3 was a string),
    # and reads 010 as octal 8.
    read = read_scene_yaml(f'a: {text}\n')['a']
    assert read == value and type(read) is type(value)


def test_a_number_in_exponent_form_loads_as_an_effect_parameter(tmp_path):
    text = (MINE + 'effects:\n  - dissipation: {damping: 1e-3}\n'
            '  - gravity: {acceleration: [0, 0, -9.81E+0]}\n')
    scene = load_scene(_write(tmp_path, text))
    assert scene.effects[0].damping == 1e-3
    np.testing.assert_array_equal(scene.effects[1].acceleration, [0.0, 0.0, -9.81])


@pytest.mark.parametrize('line, message', [
    ('  mass: "1e-3"', "body.mass: expected a number in kg, got the string '1e-3'; write it "
                       'without quotes to make it a number'),
    ('  mass: 1e-3 kg', "body.mass: expected a number in kg, got the string '1e-3 kg'"),
    ('  mass: 1:30', "body.mass: expected a number in kg, got the string '1:30'"),
    ('  mass: 1_000', "body.mass: expected a number in kg, got the string '1_000'"),
    ('  mass: nan', "body.mass: expected a number in kg, got the string 'nan'"),
    ('  mass: .nan', 'body.mass: expected a finite number, got nan'),
    ('  size: [0.3, "0.2", 0.1]', "body.size: expected 3 numbers, item 1 is the string '0.2'; "
                                  'write it without quotes'),
])
def test_strings_that_are_not_numbers_stay_errors(tmp_path, line, message):
    key = line.split(':')[0]
    text = '\n'.join(line if old.startswith(key + ':') else old
                     for old in MINE.splitlines()) + '\n'
    path = _write(tmp_path, text)
    with pytest.raises(ValueError) as caught:
        load_scene(path)
    assert str(caught.value).startswith(f'{path}: {message}'), str(caught.value)
    if 'quotes' not in message:
        assert 'quotes' not in str(caught.value)


def test_a_quoted_effect_parameter_gets_the_same_hint(tmp_path):
    path = _write(tmp_path, MINE + 'effects: [{dissipation: {damping: "1e-3"}}]\n')
    with pytest.raises(ValueError, match=r'effects\[0\]\.dissipation\.damping: expected a '
                                         r".*'1e-3'; write it without quotes"):
        load_scene(path)


@pytest.mark.parametrize('text', ['a: !!float abc\n', 'a: !!int 0b11\n',
                                  'a: !!timestamp 2024-13-45\n', 'a: [1, 2\n'])
def test_yaml_that_python_cannot_convert_is_invalid_yaml_naming_the_file(tmp_path, text):
    path = _write(tmp_path, text)
    with pytest.raises(ValueError, match=f'^{path}: not valid YAML: '):
        load_scene(path)


@pytest.mark.parametrize('lines, message', [
    ('initial:\n', 'initial: empty; give its keys, or leave the line out for the defaults'),
    ('draw:\n', 'draw: empty; give its keys, or leave the line out for the defaults'),
    ('effects:\n', 'effects: empty; list the effects, or write effects: [] for none'),
    ('effects:\n  - gravity:\n', 'effects[0].gravity: no parameters after the colon; give '
                                 'them, or write "- gravity" for the defaults'),
])
def test_an_empty_section_is_an_error_not_its_defaults(tmp_path, lines, message):
    # A key with nothing after it most likely lost the lines below it (commented out,
    # mis-indented): taking the defaults would run another experiment than the one meant.
    path = _write(tmp_path, MINE + lines)
    with pytest.raises(ValueError) as caught:
        load_scene(path)
    assert str(caught.value) == f'{path}: {message}'


def test_an_empty_body_is_an_error():
    text = MINE.split('body:')[0] + 'body:\n'
    with pytest.raises(ValueError, match=r'^mine.yaml: body: empty; the scene requires it$'):
        parse_scene(read_scene_yaml(text), 'mine.yaml')


def test_sections_left_out_or_written_empty_give_the_defaults(tmp_path):
    left_out = load_scene(_write(tmp_path, MINE))
    for extra in ('effects: []\n', 'initial: {}\ndraw: {}\neffects: []\n',
                  'effects: [gravity: {}]\n'):
        scene = load_scene(_write(tmp_path, MINE + extra))
        assert scene.state == left_out.state and scene.drawing == left_out.drawing
        assert scene.effect_names() == (['gravity'] if 'gravity' in extra else [])
    assert left_out.effects == () and left_out.simulator().wrench_function() is None


# -- overrides (the node's body and initial-state parameters win over the scene)


def test_mass_override_keeps_the_shape_and_scales_its_inertia():
    scene = load_scene('thrown_box')
    heavier = scene.with_overrides(mass=2.0 * scene.body.mass)
    np.testing.assert_allclose(heavier.body.inertia, 2.0 * scene.body.inertia, rtol=1e-15)
    # The initial velocities are kept, so the momenta double.
    np.testing.assert_allclose(heavier.state.linear_momentum,
                               2.0 * scene.state.linear_momentum, rtol=1e-15)
    assert heavier.drawing == scene.drawing


def test_inertia_override_replaces_the_shape_and_keeps_the_angular_velocity():
    scene = load_scene('thrown_box')
    changed = scene.with_overrides(inertia=[1.0, 2.0, 2.5])
    np.testing.assert_array_equal(np.diag(changed.body.inertia), [1.0, 2.0, 2.5])
    assert changed.body.mass == scene.body.mass
    np.testing.assert_allclose(changed.state.angular_velocity_body(changed.body),
                               scene.state.angular_velocity_body(scene.body), rtol=1e-14)
    # A drawing derived from the body follows it: now the box of that inertia.
    assert changed.drawing.shape == 'box' and changed.drawing.size != scene.drawing.size
    assert changed.effects[0].effect_name == 'gravity'


def test_body_override_replaces_the_body_section_and_is_validated():
    scene = load_scene('heavy_top')
    wider = scene.with_overrides(body={'shape': 'cylinder', 'radius': 0.05,
                                       'height': np.float64(0.01)})
    assert wider.body.mass == scene.body.mass
    assert wider.body.inertia[2, 2] == pytest.approx(0.5 * 0.3 * 0.05 ** 2)
    assert wider.drawing.size == (0.1, 0.1, 0.01)
    assert wider.with_overrides(mass=0.6).body.mass == 0.6
    with pytest.raises(ValueError, match=r'\(overrides\): body.height: missing; shape '
                                         r'cylinder requires it'):
        scene.with_overrides(body={'shape': 'cylinder', 'radius': 0.05})


def test_state_overrides_rebuild_the_initial_state():
    scene = load_scene('driven')
    q = [0.0, 0.0, np.sin(0.3), np.cos(0.3)]
    changed = scene.with_overrides(orientation=q, angular_velocity_world=[0.0, 0.0, 2.0],
                                   position=[1.0, 2.0, 3.0], velocity=[0.5, 0.0, 0.0])
    np.testing.assert_allclose(changed.state.quaternion, q, atol=1e-15)
    np.testing.assert_allclose(changed.state.angular_velocity(changed.body), [0, 0, 2.0],
                               atol=1e-14)
    np.testing.assert_array_equal(changed.state.position, [1.0, 2.0, 3.0])
    again = changed.with_overrides(angular_velocity_body=np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(again.state.angular_velocity_body(again.body), [1.0, 0, 0],
                               atol=1e-14)


def test_overrides_are_validated_like_the_file():
    scene = load_scene('heavy_top')
    with pytest.raises(ValueError, match=r'^scenes/heavy_top.yaml \(overrides\): '
                                         r'initial.position: not allowed with a pivot'):
        scene.with_overrides(position=[0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r'body.inertia: principal moments must satisfy'):
        scene.with_overrides(inertia=[1.0, 1.0, 5.0])
    with pytest.raises(ValueError, match=r'body.mass: must be > 0'):
        scene.with_overrides(mass=0.0)
    with pytest.raises(ValueError, match=r'integrator: unknown integrator'):
        scene.with_overrides(integrator='euler')
    assert scene.with_overrides(rate=250).dt == pytest.approx(0.004)


def test_no_override_gives_the_same_scene():
    for name in scene_names(several_bodies=False):
        scene = load_scene(name)
        # Passing back the scene's own mass and inertia (as flat parameters) changes nothing.
        for same in (scene.with_overrides(),
                     scene.with_overrides(mass=scene.body.mass,
                                          inertia=scene.body.inertia.reshape(-1).tolist())):
            assert same.state == scene.state
            np.testing.assert_array_equal(same.body.inertia, scene.body.inertia)
            assert same.drawing == scene.drawing


# -- drawing


@pytest.mark.parametrize('shape, factor', [('box', 12.0), ('ellipsoid', 20.0)])
def test_a_body_given_by_inertia_is_drawn_with_that_inertia(shape, factor):
    # A solid box of edges s has I1 = m (s2^2 + s3^2) / 12; a solid ellipsoid of diameters
    # s has I1 = m (s2^2 + s3^2) / 20: the drawing must reproduce the body's inertia.
    rng = np.random.default_rng(8)
    for _ in range(10):
        moments = np.sort(rng.uniform(1.0, 2.0, size=3))
        rotation = random_rotation(rng)
        mass = rng.uniform(0.5, 5.0)
        data = {'name': 'x', 'description': 'x',
                'body': {'mass': float(mass),
                         'inertia': (rotation @ np.diag(moments) @ rotation.T).tolist()},
                'draw': {'shape': shape}}
        drawing = parse_scene(data).drawing
        size = np.array(drawing.size)
        squared = size ** 2
        drawn = mass / factor * np.array([squared[1] + squared[2], squared[0] + squared[2],
                                          squared[0] + squared[1]])
        axes = matrix_from_quaternion(drawing.orientation)
        body = RigidBody(mass, rotation @ np.diag(moments) @ rotation.T)
        np.testing.assert_allclose(axes @ np.diag(drawn) @ axes.T, body.inertia, rtol=1e-12)


def test_a_flat_body_is_drawn_thin_but_visible():
    drawing = load_scene('t_handle').drawing
    assert drawing.shape == 'box'
    assert min(drawing.size) == pytest.approx(0.01 * max(drawing.size))


def test_a_cylinder_cannot_be_drawn_from_an_inertia_without_a_size():
    data = {'name': 'x', 'description': 'x', 'body': {'mass': 1.0, 'inertia': [1, 1, 1]},
            'draw': {'shape': 'cylinder'}}
    with pytest.raises(ValueError, match=r'draw.size: missing: a cylinder cannot be derived'):
        parse_scene(data, 'mine.yaml')


# -- the command line


def test_scenes_command_lists_every_builtin_scene_with_its_description(capsys):
    assert cli.main(['scenes']) == 0
    out = capsys.readouterr().out
    assert str(scenes_dir()) in out
    for name in BUILTIN_SCENES:
        line = next(line for line in out.splitlines() if line[2:].startswith(name + ' '))
        assert load_scene(name).description in line


def test_scenes_command_describes_one_scene_and_reports_bad_files(capsys, tmp_path):
    assert cli.main(['scenes', 'heavy_top']) == 0
    out = capsys.readouterr().out
    assert 'Pivot(point=[0.0, 0.0, -0.04]' in out and 'buss at 1000 Hz' in out
    bad = tmp_path / 'bad.yaml'
    data = copy.deepcopy(_heavy_top_data())
    data['effects'][0]['pivot']['point'] = [0, 0]
    bad.write_text(yaml.safe_dump(data), encoding='utf-8')
    assert cli.main(['scenes', str(bad)]) == 2
    assert f'{bad}: effects[0].pivot.point: expected 3 numbers, got 2' in capsys.readouterr().err
    assert cli.main(['scenes', '--effects']) == 0
    out = capsys.readouterr().out
    for name in EFFECTS:
        assert f'{name}: ' in out
        for parameter in effect_parameters(name):
            assert f'    {parameter} (' in out, (name, parameter)


def test_a_broken_scene_file_is_one_line_on_stderr_and_exit_code_2(tmp_path):
    # In a process of its own, as a user runs it: no traceback.
    path = _write(tmp_path, MINE + '  size: [1.0, 1.0, 1.0]\n')
    result = subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'scenes', path],
                            capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 2
    assert result.stdout == ''
    assert result.stderr.splitlines() == [
        f'rigid-body-sim scenes: error: {path}: body.size: duplicate key (lines 6 and 7); '
        'give each key once']


# -- a new effect needs no edit outside its module and the registry


@wrench_term
def _anchor_spring(state, time, parameters):
    """Return (-k x, 0): a spring of stiffness parameters[0] pulling the COM to the origin."""
    k = parameters[0]
    return -k * state[4], -k * state[5], -k * state[6], 0.0, 0.0, 0.0


@pytest.fixture
def anchor_spring():
    """Register a test effect for the test's duration (it sorts first among the effects)."""

    @register_effect('anchor_spring')
    class AnchorSpring(Effect):
        """A linear spring pulling the COM to the world origin (a test effect)."""

        compiled_wrench = staticmethod(_anchor_spring)
        reads_state = True
        exerts_torque = False
        example = {'stiffness': 2.0}

        def __init__(self, stiffness=1.0):
            self.stiffness = check_number(stiffness, 'stiffness', 'N/m', positive=True)

        def wrench_parameters(self, body):
            return np.array([self.stiffness])

    yield AnchorSpring
    del EFFECTS['anchor_spring']


def test_a_new_effect_is_listed_loaded_and_documented_without_other_edits(anchor_spring, capsys,
                                                                          tmp_path):
    assert cli.main(['scenes', '--effects']) == 0
    out = capsys.readouterr().out
    assert 'anchor_spring: A linear spring pulling the COM to the world origin' in out
    assert '    stiffness (default 1.0)' in out
    text = MINE + 'initial: {position: [1, 0, 0]}\neffects: [anchor_spring: {stiffness: 4e+0}]\n'
    scene = load_scene(_write(tmp_path, text))
    assert scene.effect_names() == ['anchor_spring'] and scene.effects[0].stiffness == 4.0
    assert scene.simulator().wrench_function() is not None
    # The schema comment needs no entry for it.
    assert _schema_problems() == []
    with pytest.raises(ValueError, match=r"unknown effect 'springs'; valid effects: "
                                         r'anchor_spring, dissipation'):
        load_scene(_write(tmp_path, MINE + 'effects: [springs]\n'))


@pytest.mark.parametrize('integrator', sorted(INTEGRATORS))
def test_a_new_effect_runs_compiled_under_every_integrator_at_its_order(
        anchor_spring, integrator, tmp_path):
    # x(t) = cos(sqrt(k/m) t) from x = 1 m at rest: halving the step divides the error by
    # ~2^order (kicks around the drift are second order at most; rk4 takes the stages).
    text = MINE + 'initial: {position: [1, 0, 0]}\neffects: [anchor_spring: {stiffness: 4e+0}]\n'
    scene = load_scene(_write(tmp_path, text))
    rate = math.sqrt(4.0 / scene.body.mass)
    order = INTEGRATORS[integrator].order

    def error(dt):
        simulator = scene.simulator(integrator=integrator, tolerance=0.0)
        assert simulator.path == 'compiled'
        return abs(simulator.run(1.0, dt).position[0] - math.cos(rate))

    coarse, fine = error(0.02), error(0.01)
    assert coarse < 1e-2
    assert math.log2(coarse / fine) > min(order, 2) - 0.3, (coarse, fine)


def test_output_into_a_closed_pipe_ends_quietly_with_the_sigpipe_status():
    """`rigid-body-sim scenes | head -1`: no traceback, no error line, exit 128 + SIGPIPE."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before anything is written
    try:
        result = subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'scenes'],
                                stdout=write_end, stderr=subprocess.PIPE, text=True,
                                timeout=60)
    finally:
        os.close(write_end)
    assert result.returncode == 128 + signal.SIGPIPE, result.stderr
    assert result.stderr == ''

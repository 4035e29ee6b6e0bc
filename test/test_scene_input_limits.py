"""
Scene input is bounded: size, nesting, number of values, length of numbers and strings.

Whatever a scene file (or a ``-p`` value of the node) holds, loading it ends soon and a
refusal is one line of printable text of bounded length that names the file and the key or
line: never a traceback (OverflowError, RecursionError), never a megabyte echoed back,
never a control character reaching the terminal.
"""

import pytest
from rigid_body_sim import cli
from rigid_body_sim.node.parameters import scene_from_parameters
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import MAX_SCENE_DEPTH
from rigid_body_sim.scenes import MAX_SCENE_SIZE
from rigid_body_sim.scenes import MAX_SCENE_VALUES
from rigid_body_sim.scenes import read_scene_yaml
from rigid_body_sim.text import MESSAGE_LIMIT

MINE = ('name: mine\n'
        'description: a box\n'
        'body:\n'
        '  mass: 2.0\n'
        '  shape: box\n'
        '  size: [0.3, 0.2, 0.1]\n')
HUGE = '9' * 400  # an integer beyond a float's range (1.8e308)


def _write(tmp_path, text):
    path = tmp_path / 'mine.yaml'
    path.write_text(text, encoding='utf-8')
    return str(path)


def _refusal(path):
    with pytest.raises(ValueError) as caught:
        load_scene(path)
    message = str(caught.value)
    assert message.startswith(f'{path}: '), message
    assert message.isprintable() and len(message) <= MESSAGE_LIMIT, message[:1000]
    return message


@pytest.mark.parametrize('old, new, key', [
    ('mass: 2.0', f'mass: {HUGE}', 'body.mass'),
    ('mass: 2.0', f'mass: -{HUGE}', 'body.mass'),
    ('size: [0.3, 0.2, 0.1]', f'size: [0.3, {HUGE}, 0.1]', 'body.size[1]'),
    ('size: [0.3, 0.2, 0.1]', f'size: [0.3, 0.2, 0x{"f" * 300}]', 'body.size[2]'),
    ('mass: 2.0', 'mass: 1' + '0' * 5000, 'body.mass'),  # beyond int()'s 4300 digits
])
def test_an_integer_beyond_a_float_is_refused_in_one_line_naming_its_key(
        tmp_path, old, new, key):
    message = _refusal(_write(tmp_path, MINE.replace(old, new)))
    assert f': {key}: ' in message and 'beyond' in message, message


@pytest.mark.parametrize('key', ['rate', 'tolerance'])
def test_an_integer_beyond_a_float_is_refused_for_rate_and_tolerance(tmp_path, key):
    message = _refusal(_write(tmp_path, MINE + f'{key}: {HUGE}\n'))
    assert f': {key}: ' in message, message


def test_a_long_integer_within_a_float_loads(tmp_path):
    # 300 digits: 1e299, a float; and leading zeros do not count.
    scene = load_scene(_write(tmp_path, MINE.replace('mass: 2.0', 'mass: 0000' + '0' * 5000
                                                     + '2')))
    assert scene.body.mass == 2.0
    assert read_scene_yaml('a: 1' + '0' * 299)['a'] == 10 ** 299


@pytest.mark.parametrize('body', [
    '[' * 3000 + ']' * 3000,
    '[' * 100000,
    '{a: ' * 3000 + '1' + '}' * 3000,
    ''.join(f'\n{"  " * level}a:' for level in range(1, 300)) + ' 1',
])
def test_nesting_of_any_depth_is_refused_in_one_line(tmp_path, body):
    message = _refusal(_write(tmp_path, MINE.replace('body:\n', f'body: {body}\nx:\n')))
    assert f'more than {MAX_SCENE_DEPTH} levels' in message, message


def test_a_scene_file_larger_than_the_limit_is_refused_naming_it(tmp_path):
    # A valid scene with a long comment: loaded whole before, at any size.
    text = MINE + '#' + 'x' * MAX_SCENE_SIZE + '\n'
    message = _refusal(_write(tmp_path, text))
    assert f'more than {MAX_SCENE_SIZE} characters' in message, message
    with pytest.raises(ValueError, match=f'^text: more than {MAX_SCENE_SIZE} characters'):
        read_scene_yaml(text, 'text')
    assert load_scene(_write(tmp_path, MINE + '#' * (MAX_SCENE_SIZE - len(MINE) - 1) + '\n'))


@pytest.mark.parametrize('extra', [
    # More values than the limit in one list
    'draw: {size: [' + '0, ' * MAX_SCENE_VALUES + '0]}\n',
    # An alias bomb: ten aliases of ten aliases of ... ten values, echoed by the message
    # refusing the integrator (10 million values: a 30 MB message).
    'integrator: [&a0 [0, 0, 0, 0, 0, 0, 0, 0, 0, 0], ' + ', '.join(
        f'&a{level} [' + ', '.join([f'*a{level - 1}'] * 10) + ']' for level in range(1, 7))
    + ']\n',
])
def test_more_values_than_the_limit_are_refused_in_one_line(tmp_path, extra):
    message = _refusal(_write(tmp_path, MINE + extra))
    assert f'more than {MAX_SCENE_VALUES} values' in message, message


@pytest.mark.parametrize('key, value', [
    ('name', r'"evil \e[31mred\e[0m"'),
    ('description', r'"bell \x07 here"'),
    ('description', r'"tab\there"'),
    ('name', r'"line\u2028separator"'),
    ('description', r'"next\x85line"'),
    ('name', r'"null\0byte"'),
])
def test_control_characters_in_name_or_description_are_refused_shown_escaped(
        tmp_path, capsys, key, value):
    old = 'name: mine' if key == 'name' else 'description: a box'
    path = _write(tmp_path, MINE.replace(old, f'{key}: {value}'))
    message = _refusal(path)
    assert f': {key}: ' in message and 'not printable' in message, message
    assert cli.main(['scenes', path]) == 2
    captured = capsys.readouterr()
    shown = captured.out + captured.err
    assert shown.endswith('\n') and shown[:-1].isprintable(), shown


@pytest.mark.parametrize('key, limit', [('name', 100), ('description', 300)])
def test_a_name_or_description_longer_than_its_limit_is_refused(tmp_path, key, limit):
    old = 'name: mine' if key == 'name' else 'description: a box'
    message = _refusal(_write(tmp_path, MINE.replace(old, f'{key}: {"x" * (limit + 1)}')))
    assert f': {key}: ' in message and f'at most {limit} characters' in message, message
    assert load_scene(_write(tmp_path, MINE.replace(old, f'{key}: {"x" * limit}')))


@pytest.mark.parametrize('old, new', [
    ('mass: 2.0', 'mass: ' + 'a' * 5000),  # the string echoed: 5 KB
    ('mass: 2.0', 'mass: "' + '1' * 5000 + '"'),
    ('mass: 2.0', 'mass: !!float ' + 'x' * 5000),
    ('mass: 2.0', 'mass: !!int ' + '1.' * 5000),
    ('mass: 2.0', 'mass: 2.0\n  ? ' + 'k' * 5000 + '\n  : 1'),  # an unknown key
    ('mass: 2.0', 'mass: 2.0\n  ? ' + 'k' * 5000 + '\n  : 1\n  ? ' + 'k' * 5000 + '\n  : 2'),
    ('shape: box', 'shape: ' + 'b' * 5000),
    ('description: a box', 'description: a box\nintegrator: ' + 'i' * 5000),
    ('description: a box', 'description: a box\neffects: [' + 'e' * 5000 + ']'),
    ('description: a box', 'description: a box\nintegrator: [' + '"\\e", ' * 2000 + '1]'),
])
def test_a_message_echoing_a_long_value_is_cut_to_one_short_line(tmp_path, old, new):
    _refusal(_write(tmp_path, MINE.replace(old, new)))


def test_a_long_scene_path_is_cut_in_the_message(capsys):
    assert cli.main(['scenes', '/nowhere/' + 'p' * 5000 + '.yaml']) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and len(error) <= MESSAGE_LIMIT + 40, error[:1000]


@pytest.mark.parametrize('name, value', [
    ('initial.velocity', [1e308, 0.0, 0.0]),
    ('initial.angular_velocity_body', [1e200, 0.0, 0.0]),
])
def test_a_parameter_that_overflows_the_state_is_refused_naming_itself(name, value):
    # The default scene gives angular_velocity_body: a velocity of 1e308 m/s was refused
    # naming initial.angular_velocity_body.
    scene = load_scene('default')
    with pytest.raises(ValueError) as caught:
        scene_from_parameters(scene, {name: value})
    assert f'(overrides): {name}: ' in str(caught.value), str(caught.value)


def test_a_velocity_that_overflows_the_momentum_is_refused_naming_it(tmp_path):
    # 2 kg at 1e308 m/s: p = m v is inf already (the energy overflowed for 1 kg).
    message = _refusal(_write(tmp_path, MINE + 'initial:\n  velocity: [1e308, 0, 0]\n'
                              '  angular_velocity_body: [0, 0, 1]\n'))
    assert ': initial.velocity: ' in message, message


@pytest.mark.parametrize('name, value', [
    ('body.inertia', [1.0] * 20000),  # its count and values were echoed: 100 KB
    ('body.shape', 's' * 20000),
    ('initial.orientation', [0.5] * 20000),
])
def test_a_long_parameter_value_is_cut_in_the_message(name, value):
    with pytest.raises(ValueError) as caught:
        scene_from_parameters(load_scene('default'), {name: value})
    message = str(caught.value)
    assert message.startswith(f"parameter '{name}'"), message[:200]
    assert message.isprintable() and len(message) <= MESSAGE_LIMIT, message[:1000]


@pytest.mark.parametrize('name', ['n' * 5000, 'null\0character'])
def test_a_scene_name_the_file_system_refuses_is_one_line_naming_it(name):
    # A built-in name too long for a file name was an OSError traceback in the node.
    with pytest.raises(ValueError) as caught:
        load_scene(name)
    message = str(caught.value)
    assert message.startswith(("scene 'nnn", "unknown scene 'null\\x00",
                               "scene 'null\\x00")), message
    assert message.isprintable() and len(message) <= MESSAGE_LIMIT, message[:1000]

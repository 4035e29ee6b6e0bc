"""
Scenes of several bodies (``bodies:``): each body a one-body scene, the file's errors named.

A ``bodies:`` list names each body; the scene-wide body, initial, effects, imu and draw are
every body's defaults, an entry's own section replacing one whole.  The one-body schema is
unchanged and means one body.
"""

from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import parse_scene
from rigid_body_sim.scenes.limits import MAX_BODIES

ROOT = Path(__file__).resolve().parent.parent

TWO_BODIES = {
    'name': 'pair',
    'description': 'two boxes',
    'body': {'mass': 1.0, 'shape': 'box', 'size': [0.3, 0.2, 0.1]},
    'effects': ['gravity'],
    'tolerance': 0,
    'bodies': [
        {'name': 'first', 'initial': {'position': [1.0, 0.0, 0.0]}},
        {'name': 'second', 'body': {'mass': 2.0, 'shape': 'sphere', 'radius': 0.1},
         'effects': [], 'draw': {'color': [0.1, 0.2, 0.3, 1.0]}},
    ],
}


def with_bodies(*entries, **top):
    """Return TWO_BODIES with its bodies (and top-level keys) replaced."""
    data = dict(TWO_BODIES, **top)
    data['bodies'] = list(entries)
    return data


def test_each_body_takes_the_scene_wide_sections_it_does_not_give_itself():
    scene = parse_scene(TWO_BODIES, 'pair.yaml')
    assert scene.has_named_bodies and scene.name == 'pair'
    first, second = scene.members
    assert (first.name, second.name) == ('first', 'second')
    assert first.body.mass == 1.0 and first.effect_names() == ['gravity']
    assert first.state.position.tolist() == [1.0, 0.0, 0.0]
    # An entry's section replaces the scene-wide one whole.
    assert second.body.mass == 2.0 and second.effect_names() == []
    assert second.drawing.color == (0.1, 0.2, 0.3, 1.0) and second.drawing.shape == 'sphere'
    # The run settings are the scene's, for every body.
    assert {member.tolerance for member in scene.members} == {None}
    assert {member.rate for member in scene.members} == {scene.rate}


def test_a_one_body_scene_is_its_own_only_member():
    scene = load_scene('default')
    assert not scene.has_named_bodies and scene.members == (scene,)
    assert scene.world().names == ('default',)


def test_the_world_of_a_scene_holds_each_body_at_its_initial_state():
    scene = parse_scene(TWO_BODIES, 'pair.yaml')
    world = scene.world()
    assert world.names == ('first', 'second') and world.tolerance is None
    for member in scene.members:
        np.testing.assert_array_equal(world.state(member.name).position, member.state.position)
    world.step(scene.dt)
    # Gravity pulls the first body only.
    assert world.state('first').velocity(scene.members[0].body)[2] < 0.0
    assert world.state('second').velocity(scene.members[1].body).tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize('data, message', [
    (with_bodies({'name': 'a'}, {'name': 'a'}),
     "pair.yaml: bodies[1].name: 'a' is the name of bodies[0] too"),
    (with_bodies({'name': '1st'}), 'pair.yaml: bodies[0].name: expected a name of letters'),
    (with_bodies({'name': 'a/b'}), 'pair.yaml: bodies[0].name: expected a name of letters'),
    (with_bodies({'name': 'x' * 65}), 'pair.yaml: bodies[0].name: 65 characters'),
    (with_bodies({'body': {'mass': 1.0, 'shape': 'sphere', 'radius': 1.0}}),
     'pair.yaml: bodies[0].name: missing'),
    (with_bodies({'name': 'a', 'rate': 5}), 'pair.yaml: bodies[0].rate: unknown key'),
    (with_bodies({'name': 'a', 'body': {'mass': -1.0, 'shape': 'sphere', 'radius': 1.0}}),
     'pair.yaml: bodies[0]: body.mass: '),
    (with_bodies({'name': 'a', 'initial': {'position': [0, 0]}}),
     'pair.yaml: bodies[0]: initial.position: expected 3 numbers'),
    (dict(with_bodies({'name': 'a'}), body=None),
     'pair.yaml: body: empty'),
    ({key: value for key, value in with_bodies({'name': 'a'}).items() if key != 'body'},
     'pair.yaml: bodies[0].body: missing; give the body here or a scene-wide body'),
    (with_bodies(), 'pair.yaml: bodies: expected a list of bodies'),
    (dict(TWO_BODIES, bodies={'name': 'a'}), 'pair.yaml: bodies: expected a list of bodies'),
    (with_bodies(*({'name': f'b{index}'} for index in range(MAX_BODIES + 1))),
     f'pair.yaml: bodies: {MAX_BODIES + 1} bodies; a scene takes at most {MAX_BODIES}'),
])
def test_a_scene_of_bodies_names_the_entry_and_key_of_each_error(data, message):
    with pytest.raises(ValueError) as raised:
        parse_scene(data, 'pair.yaml')
    assert str(raised.value).startswith(message), str(raised.value)


def test_body_overrides_are_refused_for_a_scene_of_bodies_and_run_settings_taken():
    scene = parse_scene(TWO_BODIES, 'pair.yaml')
    with pytest.raises(ValueError, match='the body and initial overrides are for a scene of '
                                         'one body; this one has 2'):
        scene.with_overrides(mass=2.0)
    faster = scene.with_overrides(rate=250.0, integrator='rk4')
    assert faster.rate == 250.0 and {m.integrator for m in faster.members} == {'rk4'}
    assert [m.name for m in faster.members] == ['first', 'second']


@pytest.mark.parametrize('name, count', [('juggling_clubs', 3), ('debris_field', 100),
                                         ('constellation', 1000)])
def test_the_built_in_scenes_of_bodies_load_with_their_bodies(name, count):
    scene = load_scene(name)
    assert len(scene.members) == count
    assert len({member.name for member in scene.members}) == count


def test_the_seeded_scenes_are_what_their_generator_writes():
    checked = subprocess.run([sys.executable, str(ROOT / 'benchmarks' / 'many_body_scenes.py'),
                              '--check'], capture_output=True, text=True, timeout=300)
    assert checked.returncode == 0, checked.stdout + checked.stderr


def test_the_scenes_command_lists_and_describes_scenes_of_bodies():
    def scenes(*arguments):
        done = subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'scenes', *arguments],
                              capture_output=True, text=True, timeout=300, cwd=ROOT)
        return done.returncode, done.stdout + done.stderr
    code, listing = scenes()
    assert code == 0 and 'juggling_clubs' in listing and '(1000 bodies)' in listing
    code, described = scenes('juggling_clubs')
    assert code == 0
    assert 'bodies:      3;' in described and 'club_middle  0.2 kg cylinder' in described
    code, one = scenes('constellation', '--body', 'sat_3_07')
    assert code == 0 and 'sat_3_07:' in one and 'mass 4 kg' in one
    code, unknown = scenes('juggling_clubs', '--body', 'ball')
    assert code == 2 and "no body called 'ball'; its bodies: club_left, club_middle" in unknown

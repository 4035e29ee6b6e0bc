"""
rigid-body-sim plot of a bag of several bodies: all of them in one figure, or one named.

The bag is the juggling clubs' (three bodies under gravity) simulated 1 s at 100 Hz; a
body read from it is compared with the same body simulated alone into a bag of one body:
its motion, its mass, inertia and effects, and so what the plot says it conserves, must be
the same (the many-body step is bit-identical to the one-body one, and so are the
messages).
"""

from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from rigid_body_sim.cli import main as cli_main
from rigid_body_sim.recording.motion import bag_bodies
from rigid_body_sim.recording.motion import BagBodies
from rigid_body_sim.recording.motion import conserved_quantities
from rigid_body_sim.recording.motion import read_body_motions
from rigid_body_sim.recording.motion import read_motion
from rigid_body_sim.recording.plot_bodies import _title
from rigid_body_sim.recording.plot_bodies import drawn_bodies
from rigid_body_sim.recording.plot_bodies import plot_bodies
from rigid_body_sim.recording.plot_bodies import plot_body_motions
from rigid_body_sim.recording.simulate import simulate_to_bag
from rigid_body_sim.recording.simulate_bodies import simulate_bodies_to_bag
from rigid_body_sim.scenes import load_scene
from rosbags.rosbag2 import Reader
from rosbags.rosbag2 import Writer

RATE = 100.0
DURATION = 1.0


@pytest.fixture(scope='module')
def clubs(tmp_path_factory):
    """Simulate the juggling clubs 1 s at 100 Hz: (bag, scene)."""
    bag = tmp_path_factory.mktemp('plot_bodies') / 'clubs'
    scene = load_scene('juggling_clubs')
    simulate_bodies_to_bag(scene, bag, DURATION, rate=RATE)
    return bag, scene


def _not_blank(png):
    image = matplotlib.image.imread(png)
    assert image.shape[0] > 800 and image.shape[1] > 1000
    # Lines of several colours, not an empty canvas.
    assert len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > 50


def test_plot_of_a_bag_of_bodies_draws_all_of_them_into_one_png_beside_the_bag(
        clubs, capsys):
    bag, _ = clubs
    assert cli_main(['plot', str(bag)]) == 0
    out = bag.with_name('clubs.png')
    assert capsys.readouterr().out.strip() == str(out)
    _not_blank(out)


def test_plot_body_draws_that_body_alone_into_a_png_named_after_it(clubs, capsys):
    bag, _ = clubs
    assert cli_main(['plot', str(bag), '--body', 'club_middle']) == 0
    out = bag.with_name('clubs_club_middle.png')
    assert capsys.readouterr().out.strip() == str(out)
    _not_blank(out)


def test_a_body_of_the_bag_is_read_as_the_same_body_simulated_alone(clubs, tmp_path):
    bag, scene = clubs
    together = read_body_motions(bag)
    assert [motion.body for motion in together] == [m.name for m in scene.members]
    for member, motion in zip(scene.members, together):
        alone_bag = tmp_path / member.name
        simulate_to_bag(member, alone_bag, DURATION, rate=RATE)
        alone = read_motion(alone_bag)
        named = read_motion(bag, body=member.name)
        for body in (motion, named):
            np.testing.assert_array_equal(body.time, alone.time)
            np.testing.assert_array_equal(body.quaternion, alone.quaternion)
            np.testing.assert_array_equal(body.position, alone.position)
            np.testing.assert_array_equal(body.angular_momentum, alone.angular_momentum)
            assert body.mass == alone.mass
            np.testing.assert_array_equal(body.inertia, alone.inertia)
            assert body.effects == alone.effects and body.effects  # gravity, its vector
            assert body.body_shape == alone.body_shape
            # So the conserved-quantity panel is this body's: the same title and values.
            title, quantities = conserved_quantities(body)
            alone_title, alone_quantities = conserved_quantities(alone)
            assert title == alone_title and 'the bag does not name' not in title
            assert [q.label for q in quantities] == [q.label for q in alone_quantities]
            for quantity, alone_quantity in zip(quantities, alone_quantities):
                np.testing.assert_array_equal(quantity.drift, alone_quantity.drift)


def test_an_unknown_body_is_one_line_naming_the_bags_bodies_and_exit_2(clubs, capsys):
    bag, _ = clubs
    assert cli_main(['plot', str(bag), '--body', 'club_fourth']) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and 'Traceback' not in captured.err
    assert "no body 'club_fourth'" in lines[0]
    assert 'club_left, club_middle, club_right' in lines[0]
    assert not bag.with_name('clubs_club_fourth.png').exists()


def test_body_on_a_bag_of_one_body_is_one_line_saying_so(tmp_path, capsys):
    bag = tmp_path / 'thrown'
    simulate_to_bag(load_scene('thrown_box'), bag, 0.2)
    assert cli_main(['plot', str(bag), '--body', 'box']) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and 'holds one body' in lines[0] and '--body box' in lines[0]


def test_a_many_bodies_listing_names_the_first_few_and_how_many():
    names = [f'debris_{k:03d}' for k in range(100)]
    bodies = BagBodies(names, {})
    with pytest.raises(ValueError) as caught:
        bodies.check(Path('field'), 'debris_100')
    message = str(caught.value)
    assert 'debris_000, debris_001, debris_002, debris_003, debris_004, ...' in message
    assert '(100 bodies)' in message and 'debris_005' not in message


def _copy_without_custom_data(source, target):
    """Copy a bag's topics without its custom data: as a live recording of the node."""
    with Reader(source) as reader, Writer(target, version=8) as writer:
        connections = {}
        for connection in reader.connections:
            connections[connection.id] = writer.add_connection(
                connection.topic, connection.msgtype, typestore=None,
                msgdef=connection.msgdef.data, rihs01=connection.digest,
                serialization_format='cdr',
                offered_qos_profiles=connection.ext.offered_qos_profiles)
        for connection, stamp, raw in reader.messages():
            writer.write(connections[connection.id], stamp, raw)


def test_a_live_bag_of_bodies_is_found_by_its_topics_and_plotted(clubs, tmp_path):
    bag, scene = clubs
    live = tmp_path / 'live'
    _copy_without_custom_data(bag, live)
    names = [member.name for member in scene.members]
    assert bag_bodies(live).names == sorted(names)
    motion = read_motion(live, body='club_right')
    # A live bag names no effects: treated as torque-free about the COM, which it says.
    assert motion.mass is None and motion.effects is None
    assert 'does not name the effects' in conserved_quantities(motion)[0]
    assert plot_bodies(live, tmp_path / 'live.png').is_file()


def test_more_bodies_than_drawn_are_every_kth_so_each_group_shows():
    # A constellation's 10 rings of 100: every 10th body, ten of each ring.
    names = [f'sat_{ring}_{k:02d}' for ring in range(10) for k in range(100)]
    drawn, every = drawn_bodies(names, 100)
    assert every == 10 and len(drawn) == 100
    assert {name.split('_')[1] for name in drawn} == {str(ring) for ring in range(10)}
    assert drawn_bodies(names[:3], 100) == (names[:3], 1)
    assert drawn_bodies(names[:101], 100) == (names[:101:2], 2)


def test_a_subsampled_plot_says_how_many_of_how_many_it_draws(clubs, tmp_path):
    bag, _ = clubs
    motions = read_body_motions(bag, names=['club_left', 'club_right'])
    out = plot_body_motions(motions, tmp_path / 'two.png', total=3, every=2)
    assert out.is_file()
    assert '1 in 2 of 3 bodies: 2 drawn' in _title(motions, 3, 2)


def test_a_bag_of_bodies_in_a_namespace_not_given_is_one_line_naming_it(tmp_path, capsys):
    bag = tmp_path / 'act'
    simulate_bodies_to_bag(load_scene('juggling_clubs'), bag, 0.2, namespace='/act')
    assert cli_main(['plot', str(bag)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and '--namespace /act?' in lines[0]
    assert cli_main(['plot', str(bag), '--namespace', '/act', '--out',
                     str(tmp_path / 'act.png')]) == 0

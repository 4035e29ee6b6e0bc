"""
Plots of bags: the quantities come from the messages alone and equal the simulator's.

T_rot = 1/2 Omega . (R^T L) uses no inertia, yet equals the simulator's 1/2 Omega . I Omega
to round-off: both come from the same state through a few products of 3-vectors and 3x3
matrices (R from q, R^T L, I^-1 (R^T L), a dot product), each term a few roundings of
u = 2^-53 relative, of positive quantities of one scale.  32 u bounds the sum.
"""

import dataclasses
import shutil

import matplotlib.image
import matplotlib.pyplot
import numpy as np
import pytest
from rigid_body_sim.cli import main as cli_main
from rigid_body_sim.recording.bag_writer import BagWriter
from rigid_body_sim.recording.motion import BagMotion
from rigid_body_sim.recording.motion import conserved_quantities
from rigid_body_sim.recording.motion import read_motion
from rigid_body_sim.recording.motion import symmetry_axis
from rigid_body_sim.recording.plot import _orientation_panel
from rigid_body_sim.recording.plot import apex_index
from rigid_body_sim.recording.plot import com_moves
from rigid_body_sim.recording.plot import oscillations
from rigid_body_sim.recording.plot import plane_of_motion
from rigid_body_sim.recording.plot import plot_bag
from rigid_body_sim.recording.simulate import simulate_to_bag
from rigid_body_sim.scenes import load_scene
import yaml

ROUND_OFF = 32 * 2.0**-53


@pytest.fixture(scope='module')
def van_zon(tmp_path_factory):
    """Van Zon & Schofield's body, torque-free, 2 s at 100 Hz: (bag, scene)."""
    bag = tmp_path_factory.mktemp('plot') / 'van_zon'
    scene = load_scene('van_zon')
    simulate_to_bag(scene, bag, 2.0, rate=100.0)
    return bag, scene


def test_rotational_energy_and_momentum_from_the_messages_equal_the_simulators(van_zon):
    bag, scene = van_zon
    motion = read_motion(bag)
    simulator = scene.simulator()
    energies, omegas = [], []
    for _ in range(200):
        simulator.step(0.01)
        omega = simulator.state.angular_velocity_body(scene.body)
        omegas.append(omega)
        energies.append(0.5 * omega @ scene.body.inertia @ omega)
    energies = np.array(energies)
    assert len(motion.time) == 200
    # Simulated time from the scene's start: tick k at k / rate, the last at 2 s.
    np.testing.assert_allclose(motion.time, 0.01 * np.arange(1, 201), rtol=0, atol=1e-12)
    assert motion.time_is_simulated and motion.time[-1] == 2.0
    assert np.max(np.abs(motion.rotational_energy - energies) / energies) <= ROUND_OFF
    np.testing.assert_allclose(motion.angular_velocity_body, omegas, rtol=0,
                               atol=ROUND_OFF * np.abs(omegas).max())
    # Torque-free, buss never writes L: every message carries the initial L, bit for bit.
    assert np.all(motion.angular_momentum == scene.state.angular_momentum)
    # |L| of the rows (numpy's sum of squares) against |L| of one vector (a BLAS dot
    # product, whose kernel, so the order of the sum and whether it fuses, is chosen per
    # CPU): two ways to one number.  Each rounds three squares and two sums of positive terms
    # (<= 3 u relative, u = 2^-53), which the square root halves and rounds once more:
    # <= 2.5 u each, 5 u between the two.
    np.testing.assert_allclose(motion.momentum_magnitude,
                               np.linalg.norm(scene.state.angular_momentum), rtol=5 * 2.0**-53,
                               atol=0)
    assert motion.custom_data['rigid_body_sim.scene'] == 'van_zon'


def test_plot_writes_a_png_beside_the_bag(van_zon):
    bag, _ = van_zon
    out = plot_bag(bag)
    assert out == bag.with_name('van_zon.png')
    image = matplotlib.image.imread(out)
    assert image.shape[0] > 800 and image.shape[1] > 1000
    # Not blank: the panels hold lines of several colours.
    assert len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > 50


def test_com_panel_follows_whether_the_com_moves(tmp_path, van_zon):
    bag, _ = van_zon
    assert not com_moves(read_motion(bag))
    thrown = tmp_path / 'thrown'
    simulate_to_bag(load_scene('thrown_box'), thrown, 0.5)
    motion = read_motion(thrown)
    assert com_moves(motion)
    # The exact parabola of the scene: z(t) - z(0) = v_z t - g t^2 / 2 after the first tick.
    state = load_scene('thrown_box').state
    velocity = state.velocity(load_scene('thrown_box').body)
    t = motion.time
    expected = state.position[2] + velocity[2] * t - 0.5 * 9.81 * t * t
    np.testing.assert_allclose(motion.position[:, 2], expected, rtol=0, atol=1e-12)
    assert plot_bag(thrown, tmp_path / 'thrown.png').is_file()


def test_time_axis_is_simulated_time_from_the_start_or_wall_time_from_the_first_message():
    quaternion = np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))
    zeros = np.zeros((3, 3))

    def motion(stamps, custom=None):
        return BagMotion(stamps, quaternion, zeros, zeros, zeros, custom, 'bag')

    # An offline bag names its start; the node's publish_clock stamps are simulated time.
    offline = motion([12_510_000_000, 12_520_000_000, 12_530_000_000],
                     {'rigid_body_sim.start_time': '12500000000'})
    assert offline.time_is_simulated
    np.testing.assert_allclose(offline.time, [0.01, 0.02, 0.03], rtol=0, atol=1e-12)
    clock = motion([10_000_000, 20_000_000, 30_000_000])
    assert clock.time_is_simulated and clock.time[-1] == 0.03
    # Wall-clock stamps (2024): from the first message.
    wall = motion([1_700_000_000_000_000_000 + k * 10_000_000 for k in range(3)])
    assert not wall.time_is_simulated and wall.time[0] == 0.0 and wall.time[-1] == 0.02


@pytest.fixture(scope='module')
def heavy_top_bags(tmp_path_factory):
    """
    Simulate the heavy top 1 s at 1 kHz and at 2 kHz, one fixed step per tick.

    Error control is off (tolerance 0): the order test below needs the step to halve.
    Returns (scene, {rate: BagMotion}).
    """
    directory = tmp_path_factory.mktemp('top')
    scene = dataclasses.replace(load_scene('heavy_top'), tolerance=0.0)
    motions = {}
    for rate in (1000.0, 2000.0):
        simulate_to_bag(scene, directory / f'top_{rate:g}', 1.0, rate=rate)
        motions[rate] = read_motion(directory / f'top_{rate:g}')
    return scene, motions


def test_a_pivot_scene_shows_energy_vertical_and_spin_momentum_as_the_simulator_has_them(
        heavy_top_bags):
    """
    E, L_p . z and L . e3 from the messages are the simulator's, to round-off.

    Each is a sum of a few products of quantities of one scale (T_rot, 1/2 m v^2, m g z;
    L and m r x v), each rounded a few times: 32 u of the sum of the terms' sizes bounds the
    difference, as for T_rot above.
    """
    scene, motions = heavy_top_bags
    motion = motions[1000.0]
    title, quantities = conserved_quantities(motion)
    energy, vertical, spin = quantities
    assert title.startswith('Conserved about the pivot')
    assert all(q.conserved for q in quantities)
    simulator = scene.simulator()
    pivot = next(e for e in scene.effects if e.effect_name == 'pivot')
    energies, vertical_momenta, spins = [], [], []
    for _ in range(1000):
        simulator.step(0.001)
        state = simulator.state
        energies.append(simulator.energy())
        vertical_momenta.append(pivot.angular_momentum_about_pivot(scene.body, state)[2])
        omega = state.angular_velocity_body(scene.body)
        spins.append(scene.body.inertia[2, 2] * omega[2])
    mass = scene.body.mass
    velocity = motion.velocity
    sizes = (np.abs(motion.rotational_energy)
             + 0.5 * mass * np.einsum('ni,ni->n', velocity, velocity)
             + mass * 9.81 * np.abs(motion.position[:, 2]))
    assert np.all(np.abs(energy.values - energies) <= ROUND_OFF * sizes)
    momentum_size = np.linalg.norm(motion.angular_momentum, axis=1) + mass * np.linalg.norm(
        np.cross(motion.position, velocity), axis=1)
    assert np.all(np.abs(vertical.values - vertical_momenta) <= ROUND_OFF * momentum_size)
    assert np.all(np.abs(spin.values - spins) <= ROUND_OFF * momentum_size)


def test_a_pivot_scenes_conserved_quantities_drift_as_the_integrator_order_says(
        heavy_top_bags):
    """
    L_p . z stays to round-off; E and L . e3 drift as a second-order method's error does.

    The weight's torque about the pivot, r x (0, 0, -m g), has a z component
    r_x 0 - r_y 0 = 0 exactly, so the integrator never changes L_p . z: what is left is the
    round-off of L + m r x v (32 u of |L_p|).  E and L . e3 are conserved by the physics
    only: the method (buss, second order) drifts them by O(h^2) over a fixed time, so
    halving the step divides the largest drift over 1 s by 4 (more where the method does
    better), never less than 3.5; meanwhile T_rot, traded against the potential energy,
    varies a hundred times more.
    """
    _, motions = heavy_top_bags
    drifts = {}
    for rate, motion in motions.items():
        _, quantities = conserved_quantities(motion)
        drifts[rate] = [float(np.max(np.abs(q.drift))) for q in quantities]
    energy, vertical, spin = drifts[1000.0]
    assert vertical <= ROUND_OFF and drifts[2000.0][1] <= ROUND_OFF
    assert energy / drifts[2000.0][0] >= 3.5, drifts
    assert spin / drifts[2000.0][2] >= 3.5, drifts
    rotational = motions[1000.0].rotational_energy
    assert np.ptp(rotational) / rotational[0] > 100.0 * max(energy, spin)


def test_conserved_quantities_follow_the_effects(tmp_path, van_zon):
    bag, _ = van_zon
    title, (rotational, magnitude) = conserved_quantities(read_motion(bag))
    assert 'without torque' in title and rotational.conserved and magnitude.conserved
    simulate_to_bag(load_scene('flat_spin'), tmp_path / 'flat', 2.0)
    title, (magnitude, rotational) = conserved_quantities(read_motion(tmp_path / 'flat'))
    assert magnitude.conserved and not rotational.conserved
    assert 'dissipation' in title and np.max(np.abs(magnitude.drift)) <= ROUND_OFF
    assert rotational.drift[-1] < 0.0
    # A live bag names no effects: torque-free assumed, and said so.
    motion = read_motion(bag)
    motion.custom_data = {}
    title, _ = conserved_quantities(motion)
    assert 'does not name the effects' in title


def test_the_symmetry_axis_is_the_one_of_the_odd_moment():
    np.testing.assert_array_equal(np.abs(symmetry_axis(np.diag([2.0, 2.0, 3.0]))), [0, 0, 1])
    np.testing.assert_array_equal(np.abs(symmetry_axis(np.diag([1.0, 4.0, 4.0]))), [1, 0, 0])
    assert symmetry_axis(np.diag([1.0, 2.0, 3.0])) is None
    assert symmetry_axis(np.diag([2.0, 2.0, 2.0])) is None


def test_oscillations_count_swings_across_the_range_not_round_off():
    time = np.linspace(0.0, 1.0, 10001)
    assert oscillations(np.cos(2 * np.pi * 50 * time)) == 50.0
    assert oscillations(150.0 + 1e-13 * np.sin(2 * np.pi * 900 * time)) == 0.0
    # A drift with a small ripple: one rise, the ripple below the trigger's band.
    assert oscillations(time + 0.1 * np.sin(2 * np.pi * 200 * time)) == 0.5


def test_the_com_panel_shows_the_plane_of_the_throw_and_its_apex(tmp_path):
    scene = load_scene('thrown_box')
    simulate_to_bag(scene, tmp_path / 'thrown', 1.0)
    motion = read_motion(tmp_path / 'thrown')
    assert plane_of_motion(motion.position) == (0, 2, 1)  # x-z: thrown along x and up
    apex = apex_index(motion)
    # The apex is the tick nearest v_z / g after the throw.
    v_z = scene.state.velocity(scene.body)[2]
    assert abs(motion.time[apex] - v_z / 9.81) <= 0.005
    top = read_motion(tmp_path / 'thrown')
    top.custom_data['rigid_body_sim.effect_parameters'] = '[{"effect": "pivot"}]'
    assert apex_index(top) is None
    for name, duration in (('heavy_top', 0.5), ('flat_spin', 2.0)):
        simulate_to_bag(load_scene(name), tmp_path / name, duration)
        assert plot_bag(tmp_path / name).is_file()


def test_cli_plots_and_reports_bags_it_cannot_plot(tmp_path, van_zon, capsys):
    bag, _ = van_zon
    out = tmp_path / 'cli.png'
    assert cli_main(['plot', str(bag), '--out', str(out)]) == 0
    assert str(out) in capsys.readouterr().out and out.is_file()
    assert cli_main(['plot', str(tmp_path / 'missing')]) == 2
    assert 'no bag at' in capsys.readouterr().err
    partial = tmp_path / 'partial'
    with BagWriter(partial) as writer:
        writer.add_topic('/pose', 'geometry_msgs/msg/PoseStamped')
    assert cli_main(['plot', str(partial)]) == 2
    assert "no single nav_msgs/msg/Odometry topic named '/odom'" in capsys.readouterr().err
    cut = tmp_path / 'cut'
    cut.mkdir()
    (cut / 'cut.mcap').write_bytes((bag / 'van_zon.mcap').read_bytes()[:5000])
    (cut / 'metadata.yaml').write_bytes((bag / 'metadata.yaml').read_bytes())
    (cut / 'metadata.yaml').write_text((cut / 'metadata.yaml').read_text().replace(
        'van_zon.mcap', 'cut.mcap'))
    assert cli_main(['plot', str(cut)]) == 2
    assert 'rigid-body-sim record --recover' in capsys.readouterr().err


def test_plot_of_a_folder_that_is_no_bag_says_so_and_suggests_no_recovery(tmp_path, van_zon,
                                                                          capsys):
    """
    A photo album, an empty folder, a text file: "is not a bag", in one line.

    A folder with a metadata.yaml that is not rosbag2's once got "try: rigid-body-sim
    record --recover", which suits only a killed recorder's storage file without its
    metadata.yaml: that one still gets it.
    """
    album = tmp_path / 'album'
    album.mkdir()
    (album / 'metadata.yaml').write_text('title: my photo album\n')
    (album / 'IMG_0001.jpg').write_bytes(b'\xff\xd8\xff')
    empty = tmp_path / 'empty'
    empty.mkdir()
    text = tmp_path / 'notes.txt'
    text.write_text('notes\n')
    for path, why in ((album, 'its metadata.yaml is not a rosbag2 one'),
                      (empty, 'a folder with no metadata.yaml and no .mcap or .db3 file'),
                      (text, 'a file that is not a storage file of one')):
        assert cli_main(['plot', str(path)]) == 2
        error = capsys.readouterr().err
        assert error.count('\n') == 1 and f'{path} is not a bag: {why}' in error, error
        assert 'recover' not in error
    killed = tmp_path / 'killed'
    killed.mkdir()
    bag, _ = van_zon
    (killed / 'van_zon.mcap').write_bytes((bag / 'van_zon.mcap').read_bytes())
    assert cli_main(['plot', str(killed)]) == 2
    error = capsys.readouterr().err
    assert 'has storage files (van_zon.mcap) but no metadata.yaml' in error
    assert f'try: rigid-body-sim record --recover {killed}' in error


def test_the_custom_data_is_that_of_metadata_yaml_in_either_storage(tmp_path, van_zon):
    """rosbag2 keeps it in metadata.yaml; a bag without any (a live one) has none."""
    bag, scene = van_zon
    simulate_to_bag(scene, tmp_path / 'db', 0.1, rate=100.0, storage='sqlite3')
    for path in (bag, tmp_path / 'db'):
        information = yaml.safe_load((path / 'metadata.yaml').read_text())[
            'rosbag2_bagfile_information']
        assert read_motion(path).custom_data == information['custom_data']
        assert information['custom_data']['rigid_body_sim.scene'] == 'van_zon'
    live = tmp_path / 'live'
    shutil.copytree(bag, live)
    document = yaml.safe_load((live / 'metadata.yaml').read_text())
    document['rosbag2_bagfile_information']['custom_data'] = None
    (live / 'metadata.yaml').write_text(yaml.safe_dump(document))
    assert read_motion(live).custom_data == {}


def test_a_live_bag_is_timed_by_the_nodes_reports_not_by_its_arrival_stamps():
    from rigid_body_sim.recording.motion import simulated_time_from_reports
    # Ticks of 10 ms stamped as they were scheduled under load (irregular), a pause of
    # three ticks (no state change), and a reset: reports say the simulated time.
    stamps = 1_700_000_000_000_000_000 + np.cumsum(
        [3, 17, 1, 9, 30, 2, 8, 10, 10, 10, 12, 8]) * 1_000_000
    moved = np.array([1, 1, 1, 1, 1, 0, 0, 0, 1, 1, 1, 1], dtype=bool)
    reports = [(stamps[1] + 1000, 7.52, 100.0),   # tick 1 is at 7.52 s
               (stamps[9] + 1000, 0.02, 100.0)]   # a reset: tick 9 is at 0.02 s
    time = simulated_time_from_reports(stamps, moved, reports)
    np.testing.assert_allclose(time, [7.51, 7.52, 7.53, 7.54, 7.55, 7.55, 7.55, 7.55, 7.56,
                                      0.02, 0.03, 0.04], atol=1e-12)
    quaternion = np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))
    zeros = np.zeros((3, 3))
    wall = BagMotion(stamps[:3], quaternion, zeros, zeros, zeros, {}, 'live')
    assert not wall.time_is_simulated and wall.stamp_spacing == (0.001, 0.017)


def test_a_spin_constant_to_many_digits_is_drawn_from_a_round_value():
    from rigid_body_sim.recording.plot import _reference_value
    assert _reference_value(150.0 + np.linspace(1e-7, 5.5e-7, 50)) == 150.0
    assert _reference_value(np.linspace(-2.0, 2.0, 50)) == 0.0


def test_the_orientation_panel_names_the_axis_that_flips(van_zon):
    """Van Zon's body, I = (10, 20, 26): body y is the middle axis, as animate and watch say."""
    bag, _ = van_zon
    figure = matplotlib.pyplot.figure()
    try:
        axes = figure.add_subplot(projection='3d')
        _orientation_panel(axes, read_motion(bag))
        labels = [text.get_text() for text in axes.get_legend().get_texts()]
        assert labels[1] == 'body y axis (the middle principal axis: it flips)', labels
        assert 'flips' not in labels[0] + labels[2]
    finally:
        matplotlib.pyplot.close(figure)

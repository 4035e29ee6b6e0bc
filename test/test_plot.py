"""
Plots of bags: the quantities come from the messages alone and equal the simulator's.

T_rot = 1/2 Omega . (R^T L) uses no inertia, yet equals the simulator's 1/2 Omega . I Omega
to round-off: both come from the same state through a few products of 3-vectors and 3x3
matrices (R from q, R^T L, I^-1 (R^T L), a dot product), each term a few roundings of
u = 2^-53 relative, of positive quantities of one scale.  32 u bounds the sum.
"""

import matplotlib.image
import numpy as np
import pytest
from rigid_body_sim.cli import main as cli_main
from rigid_body_sim.recording.bag_writer import BagWriter
from rigid_body_sim.recording.plot import com_moves
from rigid_body_sim.recording.plot import plot_bag
from rigid_body_sim.recording.plot import read_motion
from rigid_body_sim.recording.simulate import simulate_to_bag
from rigid_body_sim.scenes import load_scene

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
    np.testing.assert_allclose(motion.time, 0.01 * np.arange(200), rtol=0, atol=1e-12)
    assert np.max(np.abs(motion.rotational_energy - energies) / energies) <= ROUND_OFF
    np.testing.assert_allclose(motion.angular_velocity_body, omegas, rtol=0,
                               atol=ROUND_OFF * np.abs(omegas).max())
    # Torque-free, L is untouched: |L| is the same number in every message.
    assert np.all(motion.momentum_magnitude == np.linalg.norm(scene.state.angular_momentum))
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
    t = motion.time + 0.01
    expected = state.position[2] + velocity[2] * t - 0.5 * 9.81 * t * t
    np.testing.assert_allclose(motion.position[:, 2], expected, rtol=0, atol=1e-12)
    assert plot_bag(thrown, tmp_path / 'thrown.png').is_file()


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

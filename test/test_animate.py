"""
rigid-body-sim animate: the frames show the bag's motion, at the times fps and speed say.

The drawn body axes are checked against the bag's quaternions through an independent
rotation (scipy's), before and after matplotlib's projection; the inertia-equivalent box
against the closed form of a box's moments; the GIF's frame count and delays against the
plan.
"""

import math
from pathlib import Path

from mpl_toolkits.mplot3d import proj3d
import numpy as np
from PIL import Image
import pytest
from rigid_body_sim.cli import main as cli_main
from rigid_body_sim.drawing import trail_points
from rigid_body_sim.recording.animate import _Scene3D
from rigid_body_sim.recording.animate import plan_frames
from rigid_body_sim.recording.animate import read_shape
from rigid_body_sim.recording.animate import read_trail_axis
from rigid_body_sim.recording.motion import read_motion
from rigid_body_sim.recording.simulate import simulate_to_bag
from rigid_body_sim.scenes import load_scene
from rosbags.rosbag2 import Reader
from rosbags.rosbag2 import Writer
from scipy.spatial.transform import Rotation
import yaml

DURATION = 2.0


@pytest.fixture(scope='module')
def flip_bag(tmp_path_factory):
    """Two seconds of the default scene (the T-handle) at its 100 Hz."""
    bag = tmp_path_factory.mktemp('animate') / 'flip'
    simulate_to_bag(load_scene('default'), bag, DURATION)
    return bag


def _custom_data(bag):
    """Return the custom_data of a bag's metadata.yaml ({} if none)."""
    document = yaml.safe_load((Path(bag) / 'metadata.yaml').read_text())
    return document['rosbag2_bagfile_information'].get('custom_data') or {}


def _copy_without_marker(source, target, keep_custom_data=True):
    """Copy a bag without its marker topic (and without its custom data if asked)."""
    with Reader(source) as reader, Writer(target, version=8) as writer:
        connections = {}
        for connection in reader.connections:
            if connection.topic.endswith('/marker'):
                continue
            connections[connection.id] = writer.add_connection(
                connection.topic, connection.msgtype, typestore=None,
                msgdef=connection.msgdef.data, rihs01=connection.digest,
                serialization_format='cdr',
                offered_qos_profiles=connection.ext.offered_qos_profiles)
        if keep_custom_data:
            # rosbags' Reader has no public accessor for custom_data: rosbag2 keeps it in
            # metadata.yaml.
            for key, value in _custom_data(source).items():
                writer.set_custom_data(key, value)
        for connection, stamp, raw in reader.messages():
            if connection.id in connections:
                writer.write(connections[connection.id], stamp, raw)


def test_the_gif_has_one_frame_per_speed_over_fps_of_simulated_time(flip_bag, tmp_path):
    out = tmp_path / 'flip.gif'
    assert cli_main(['animate', str(flip_bag), '--out', str(out), '--fps', '10',
                     '--speed', '2']) == 0
    motion = read_motion(flip_bag)
    span = motion.time[-1] - motion.time[0]
    # A frame every speed / fps = 0.2 simulated s from the first tick to the last.
    expected = math.floor(span / 0.2 + 1e-6) + 1
    with Image.open(out) as gif:
        assert gif.n_frames == expected == plan_frames(motion.time, 10.0, 2.0).frames
        # GIF delays are whole hundredths: 1 / 10 fps = 100 ms exactly.
        delays = []
        for index in range(gif.n_frames):
            gif.seek(index)
            delays.append(gif.info['duration'])
    assert delays == [100] * expected


def test_each_frame_shows_the_latest_tick_at_or_before_its_time():
    time = np.arange(1, 201) * 0.01
    plan = plan_frames(time, fps=10.0, speed=1.0)
    assert plan.frames == 20 and plan.duration == 2.0
    for index, moment in zip(plan.indices, plan.times):
        assert time[index] <= moment + 1e-9
        assert index == len(time) - 1 or time[index + 1] > moment + 1e-9


@pytest.mark.parametrize('fps, speed', [(0.0, 1.0), (10.0, -1.0), (math.nan, 1.0)])
def test_a_frame_rate_or_speed_that_is_not_positive_is_refused(fps, speed):
    with pytest.raises(ValueError, match='must be a number > 0'):
        plan_frames(np.arange(10) * 0.1, fps, speed)


def test_the_drawn_body_axes_are_the_bags_orientation(flip_bag):
    motion = read_motion(flip_bag)
    shape = read_shape(flip_bag, motion)
    scene = _Scene3D(shape, motion, 'test', pixels=200)
    try:
        for index in (0, len(motion.time) // 3, len(motion.time) - 1):
            scene.draw(index, motion.time[index])
            scene.figure.canvas.draw()
            # Independent of the module's quaternion code: scipy, scalar-last (x, y, z, w).
            columns = Rotation.from_quat(motion.quaternion[index]).as_matrix()
            projection = scene.axes.get_proj()
            for axis, line in enumerate(scene.axis_lines):
                xs, ys, zs = line.get_data_3d()
                expected = scene.axis_length * columns[:, axis]
                np.testing.assert_allclose([xs[1], ys[1], zs[1]], expected, rtol=0.0,
                                           atol=1e-12 * scene.axis_length)
                drawn = proj3d.proj_transform(xs[1], ys[1], zs[1], projection)
                wanted = proj3d.proj_transform(*expected, projection)
                np.testing.assert_allclose(drawn, wanted, rtol=0.0, atol=1e-9)
    finally:
        scene.close()


def test_the_marker_gives_the_drawn_shape_and_its_orientation_in_the_body(flip_bag):
    motion = read_motion(flip_bag)
    shape = read_shape(flip_bag, motion)
    scene = load_scene('default')
    # The default scene gives the T-handle by its moments alone: the node's marker is the
    # inertia-equivalent box, and the drawing says so rather than pass it off as the shape.
    assert shape.origin == 'marker: inertia-equivalent box' and shape.kind == scene.drawing.shape
    assert shape.equivalent and 'not its shape' in shape.label
    np.testing.assert_allclose(shape.scale, scene.drawing.size, rtol=1e-15)
    drawing_axes = Rotation.from_quat(scene.drawing.orientation).as_matrix()
    np.testing.assert_allclose(shape.orientation, drawing_axes, atol=1e-12)


def test_a_bag_without_marker_draws_the_inertia_equivalent_box(flip_bag, tmp_path):
    bare = tmp_path / 'bare'
    _copy_without_marker(flip_bag, bare)
    motion = read_motion(bare)
    shape = read_shape(bare, motion)
    assert shape.origin == 'inertia-equivalent box' and shape.kind == 'box'
    # A solid box of edges a_i has I_i = m (a_j^2 + a_k^2) / 12 about the axis along a_i, so
    # a_i = sqrt(6 (I_j + I_k - I_i) / m) gives back the principal moments I_i; a lamina's
    # zero edge (the T-handle: I1 + I2 = I3) is drawn as a slab 2% of the longest edge.
    moments = np.linalg.eigvalsh(motion.inertia)
    edges = np.sqrt(np.clip(6.0 * (moments.sum() - 2.0 * moments) / motion.mass, 0.0, None))
    edges = np.maximum(edges, 0.02 * edges.max())
    np.testing.assert_allclose(shape.scale, edges, rtol=1e-12)
    # The box lies along the principal axes: they diagonalise the inertia, in that order.
    principal = shape.orientation.T @ motion.inertia @ shape.orientation
    np.testing.assert_allclose(principal, np.diag(moments), atol=1e-12 * moments.max())
    out = tmp_path / 'bare.gif'
    assert cli_main(['animate', str(bare), '--out', str(out), '--speed', '4']) == 0
    assert out.stat().st_size > 0


def test_a_live_bag_without_marker_or_inertia_is_refused_in_one_line(flip_bag, tmp_path,
                                                                     capsys):
    bare = tmp_path / 'live'
    _copy_without_marker(flip_bag, bare, keep_custom_data=False)
    assert cli_main(['animate', str(bare), '--out', str(tmp_path / 'x.gif')]) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and 'no marker topic' in error and 'Traceback' not in error


@pytest.mark.parametrize('arguments, message', [
    (['--out', 'clip.avi'], 'must end in .gif or .mp4'),
    (['--fps', '0'], '--fps must be a number > 0'),
    (['--speed', 'nan'], '--speed must be a number > 0'),
    (['--max-size', '-1'], '--max-size must be'),
])
def test_bad_options_get_a_one_line_error(flip_bag, tmp_path, capsys, arguments, message):
    arguments = [a if a != 'clip.avi' else str(tmp_path / a) for a in arguments]
    assert cli_main(['animate', str(flip_bag), *arguments]) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and message in error


def test_a_missing_bag_gets_a_one_line_error(tmp_path, capsys):
    assert cli_main(['animate', str(tmp_path / 'nothing')]) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and 'no bag at' in error


def test_mp4_is_written_with_ffmpeg_and_refused_clearly_without(flip_bag, tmp_path, capsys):
    from matplotlib.animation import FFMpegWriter
    out = tmp_path / 'flip.mp4'
    code = cli_main(['animate', str(flip_bag), '--out', str(out), '--speed', '4'])
    if FFMpegWriter.isAvailable():
        assert code == 0 and out.stat().st_size > 0
    else:
        assert code == 2 and not out.exists()
        error = capsys.readouterr().err
        assert 'ffmpeg' in error and '.gif' in error and error.count('\n') == 1


def test_a_gif_over_the_budget_is_scaled_down_to_fit(flip_bag, tmp_path):
    out = tmp_path / 'small.gif'
    budget = 0.03125  # MiB: 32 KiB, well under what 20 frames of 400 px take
    assert cli_main(['animate', str(flip_bag), '--out', str(out), '--max-size',
                     str(budget)]) == 0
    assert out.stat().st_size <= budget * 2 ** 20
    with Image.open(out) as gif:
        assert gif.size[0] < 400


def test_simulate_animate_writes_the_bag_and_its_gif(tmp_path):
    bag = tmp_path / 'racket'
    assert cli_main(['simulate', '--scene', 'tennis_racket', '--duration', '1', '--bag',
                     str(bag), '--quiet', '--animate', '--animate-speed', '2']) == 0
    gif = Path(str(bag) + '.gif')
    with Image.open(gif) as image:
        assert image.n_frames == plan_frames(read_motion(bag).time, 10.0, 2.0).frames


@pytest.fixture(scope='module')
def box_bag(tmp_path_factory):
    """Half a second of thrown_box: a body given as a box, drawn as its own box."""
    bag = tmp_path_factory.mktemp('animate') / 'box'
    simulate_to_bag(load_scene('thrown_box'), bag, 0.5)
    return bag


def test_a_box_body_is_labelled_as_the_box_it_is(box_bag):
    """
    A box body's marker is its box, not an inertia-equivalent stand-in.

    A box has the moments of its own equivalent box, so the edges alone once labelled
    thrown_box "inertia-equivalent box ... (the body's moments, not its shape)".
    """
    motion = read_motion(box_bag)
    shape = read_shape(box_bag, motion)
    assert motion.body_shape == 'box'
    assert shape.origin == 'marker' and not shape.equivalent
    assert shape.label == 'body: box 0.15 x 0.075 x 0.01 m'


def test_the_trail_is_the_tip_of_the_middle_axis_at_every_tick(flip_bag):
    """
    The trail follows the middle principal axis (body y of I = (1, 2, 3)), tick by tick.

    The trail once followed the axis that moved most, sampled at frames only: the spin
    axis of a fast spin, drawn as stars.  Here each frame's trail ends at the drawn tip of
    body y, and between two frames it passes through each tick's tip.
    """
    motion = read_motion(flip_bag)
    shape = read_shape(flip_bag, motion)
    scene = _Scene3D(shape, motion, 'test', pixels=200)
    try:
        assert np.array_equal(scene.view.trail_axis.direction, [0.0, 1.0, 0.0])
        assert 'middle' in scene.view.trail_axis.name
        labels = [text.get_text() for text in scene.axes.get_legend().get_texts()]
        assert any(label.startswith('trail: tip of body y: the middle') for label in labels)
        first, second = 40, 60
        scene.draw(first, motion.time[first])
        scene.draw(second, motion.time[second])
        segments = scene.axis_length * np.vstack(scene.view.trail_points)
        tips = scene.axis_length * Rotation.from_quat(
            motion.quaternion[first:second + 1]).as_matrix()[:, :, 1]
        distance = np.min(np.linalg.norm(segments[None, :, :] - tips[:, None, :], axis=2),
                          axis=1)
        # Ticks closer than 0.005 rad to the last point kept are thinned out, no farther.
        assert distance.max() <= 0.005 * scene.axis_length
        np.testing.assert_allclose(segments[-1], tips[-1], atol=1e-12 * scene.axis_length)
    finally:
        scene.close()


def test_a_live_bag_trails_the_middle_axis_its_motion_shows(flip_bag, tmp_path):
    """A bag naming no inertia: L = I Omega over its ticks gives it, and its middle axis."""
    live = tmp_path / 'live'
    _copy_without_marker(flip_bag, live, keep_custom_data=False)
    motion = read_motion(live)
    assert motion.inertia is None
    np.testing.assert_allclose(motion.inertia_seen(), np.diag([1.0, 2.0, 3.0]), rtol=1e-9,
                               atol=1e-9)
    assert np.array_equal(read_trail_axis(motion).direction, [0.0, 1.0, 0.0])


def test_a_fast_spin_trail_is_a_smooth_curve_on_its_true_path():
    """
    A spin of 40 rad/s sampled at 100 Hz (0.4 rad a tick) trails in steps of 0.02 rad at most.

    Each added point lies on the tip's true path, the cone about the spin axis: the
    samples' polygon drew a fast spin as stars and squares.
    """
    rate, spin = 100.0, 40.0
    times = np.arange(0.0, 0.5, 1.0 / rate)
    rotations = Rotation.from_rotvec(np.outer(times * spin, [0.0, 0.0, 1.0])).as_matrix()
    direction = np.array([np.sin(0.3), 0.0, np.cos(0.3)])
    points = trail_points(rotations, direction)
    assert len(points) >= spin * times[-1] / 0.02
    steps = np.arccos(np.clip(np.einsum('ni,ni->n', points[:-1], points[1:]), -1.0, 1.0))
    assert steps.max() <= 0.02 + 1e-12
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(points[:, 2], np.cos(0.3), rtol=1e-12)
    np.testing.assert_allclose(points[-1], rotations[-1] @ direction, atol=1e-15)

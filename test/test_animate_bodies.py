"""
rigid-body-sim animate of a bag of several bodies: all in one scene, or one named.

The bag is the juggling clubs' (three bodies under gravity) simulated 1 s at 100 Hz.  The
frames of all bodies are checked to show each body where its own odom says it is at the
tick the frame plan picks (the marker arrays are read only for those ticks); --body against
the body's marker in the array.
"""

from mpl_toolkits.mplot3d import proj3d
import numpy as np
from PIL import Image
import pytest
from rigid_body_sim.cli import main as cli_main
from rigid_body_sim.physics import matrix_from_quaternion
from rigid_body_sim.recording import animate_bodies
from rigid_body_sim.recording.animate import plan_frames
from rigid_body_sim.recording.animate import prepare_animation
from rigid_body_sim.recording.animate import read_shape
from rigid_body_sim.recording.animate import render_animation
from rigid_body_sim.recording.animate_bodies import BodiesAnimation
from rigid_body_sim.recording.motion import read_body_motions
from rigid_body_sim.recording.motion import read_motion
from rigid_body_sim.recording.simulate_bodies import simulate_bodies_to_bag
from rigid_body_sim.scenes import load_scene

RATE = 100.0
DURATION = 1.0


@pytest.fixture(scope='module')
def clubs(tmp_path_factory):
    """Simulate the juggling clubs 1 s at 100 Hz: (bag, scene)."""
    bag = tmp_path_factory.mktemp('animate_bodies') / 'clubs'
    scene = load_scene('juggling_clubs')
    simulate_bodies_to_bag(scene, bag, DURATION, rate=RATE)
    return bag, scene


def test_animate_draws_all_bodies_one_frame_per_speed_over_fps(clubs, tmp_path):
    bag, _ = clubs
    out = tmp_path / 'clubs.gif'
    assert cli_main(['animate', str(bag), '--out', str(out), '--fps', '20',
                     '--speed', '1']) == 0
    motion = read_motion(bag, body='club_left')
    expected = plan_frames(motion.time, 20.0, 1.0).frames
    with Image.open(out) as gif:
        assert gif.n_frames == expected == 20
        # GIF delays are whole hundredths: 1 / 20 fps = 50 ms exactly.
        gif.seek(gif.n_frames - 1)
        assert gif.info['duration'] == 50


def test_each_frame_shows_every_body_at_its_pose_of_the_planned_tick(clubs, tmp_path):
    bag, scene = clubs
    animation = prepare_animation(bag, tmp_path / 'clubs.gif', fps=10.0, speed=0.5)
    assert isinstance(animation, BodiesAnimation)
    motions = read_body_motions(bag)
    assert np.array_equal(animation.plan.indices,
                          plan_frames(motions[0].time, 10.0, 0.5).indices)
    for index in animation.plan.indices:
        array = animation.arrays[int(index)]
        assert list(array) == [member.name for member in scene.members]
        for motion in motions:
            position = array[motion.body].pose.position
            assert (position.x, position.y, position.z) == tuple(motion.position[index])
    # And the drawn polygons are the clubs' cylinders there: their vertices' mean is the COM.
    frame = animation.scene(pixels=200)
    try:
        index = int(animation.plan.indices[-1])
        frame.draw(index, motions[0].time[index])
        frame.figure.canvas.draw()
        vertices = np.vstack([np.asarray(polygon) for polygon in frame.polygons_world])
        faces_each = len(vertices) // len(motions)
        for k, motion in enumerate(motions):
            mean = vertices[k * faces_each:(k + 1) * faces_each].mean(axis=0)
            np.testing.assert_allclose(mean, motion.position[index], atol=1e-9)
        # Projected as the axes project the world: the COM of each lies inside the picture.
        projection = frame.axes.get_proj()
        for motion in motions:
            x, y, _ = proj3d.proj_transform(*motion.position[index], projection)
            assert abs(x) < 1.0 and abs(y) < 1.0
    finally:
        frame.close()


def test_body_animates_that_body_with_its_markers_shape_and_colour(clubs, capsys):
    bag, scene = clubs
    assert cli_main(['animate', str(bag), '--body', 'club_right']) == 0
    out = bag.with_name('clubs_club_right.gif')
    assert str(out) in capsys.readouterr().out
    with Image.open(out) as gif:
        assert gif.n_frames == 10
    motion = read_motion(bag, body='club_right')
    shape = read_shape(bag, motion)
    member = scene.members[2]
    assert shape.kind == 'cylinder' and shape.origin == 'marker'
    np.testing.assert_allclose(shape.scale, member.drawing.size, rtol=1e-15)
    np.testing.assert_allclose(shape.colour, member.drawing.color, rtol=1e-6)


def test_an_unknown_body_is_one_line_and_exit_2(clubs, capsys):
    bag, _ = clubs
    assert cli_main(['animate', str(bag), '--body', 'club_fourth']) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and 'Traceback' not in captured.err
    assert "no body 'club_fourth'" in lines[0] and 'club_middle' in lines[0]


def test_more_bodies_than_shapes_are_drawn_as_points(clubs, tmp_path, monkeypatch):
    bag, _ = clubs
    monkeypatch.setattr(animate_bodies, 'MOST_SHAPES', 2)
    animation = prepare_animation(bag, tmp_path / 'points.gif', fps=5.0, speed=1.0)
    assert 'as points' in animation.title and '--body NAME' in animation.title
    assert render_animation(animation, pixels=200) == (tmp_path / 'points.gif').stat().st_size


def test_simulate_animate_renders_a_scene_of_bodies(tmp_path, capsys):
    bag = tmp_path / 'thrown'
    out = tmp_path / 'thrown.gif'
    assert cli_main(['simulate', '--scene', 'juggling_clubs', '--duration', '0.5', '--bag',
                     str(bag), '--quiet', '--animate', str(out)]) == 0
    with Image.open(out) as gif:
        assert gif.n_frames == 5
    assert f'{out}: 5 frames' in capsys.readouterr().out


def test_a_rotation_of_the_marker_turns_the_drawn_shape(clubs):
    bag, _ = clubs
    animation = prepare_animation(bag, None, fps=10.0, speed=1.0)
    frame = animation.scene(pixels=200)
    try:
        index = int(animation.plan.indices[3])
        frame.draw(index, 0.0)
        marker = animation.arrays[index]['club_left']
        o = marker.pose.orientation
        rotation = matrix_from_quaternion((o.x, o.y, o.z, o.w))
        vertices = np.vstack([np.asarray(p) for p in frame.polygons_world[:len(
            frame.faces['club_left'])]])
        centre = np.array([marker.pose.position.x, marker.pose.position.y,
                           marker.pose.position.z])
        # Back in the drawing's frame the vertices span the cylinder's 0.5 m along its z.
        local = (vertices - centre) @ rotation
        np.testing.assert_allclose(np.ptp(local, axis=0), [0.06, 0.06, 0.5], rtol=1e-9)
    finally:
        frame.close()

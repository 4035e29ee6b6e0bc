"""``rigid-body-sim run``: the default scene's body offline, flipping when theory says."""

from rigid_body_sim import cli
from rigid_body_sim.scenes import default_body
from rigid_body_sim.scenes import default_state
from rigid_body_sim.scenes import load_scene


def test_run_simulates_the_default_scene_and_shows_the_first_flip(capsys):
    """
    The body rate about the middle axis reverses between 7 s and 8 s (the flip at ~7.2 s).

    The default scene's T-handle flips first after ~7.2 s (the elliptic solution, see
    test_hard_cases.py), then every ~14.4 s; the table prints once a second.
    """
    assert cli.main(['run', '--duration', '8']) == 0
    output = capsys.readouterr().out
    assert ('principal moments [1. 2. 3.] kg m^2; integrator buss, dt 0.01 s, tolerance 1e-07 '
            'rad/s') in output
    rows = {}
    for line in output.splitlines():
        # t, quaternion (4), body angular velocity (3), dE/E, d|L|/|L|
        fields = line.split()
        if len(fields) == 10 and fields[0].count('.') == 1 \
                and fields[0].replace('.', '').isdigit():
            rows[float(fields[0])] = [float(w) for w in fields[5:8]]
    assert sorted(rows) == [float(t) for t in range(9)]
    assert all(rows[t][1] > 0.0 for t in range(8))
    assert rows[8.0][1] < 0.0


def test_defaults_are_the_default_scenes_body_and_state():
    """default_body and default_state read the scene file: one source of truth."""
    scene = load_scene('default')
    body = default_body()
    assert body.mass == scene.body.mass and (body.inertia == scene.body.inertia).all()
    assert default_state() == scene.state

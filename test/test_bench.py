"""
The work-precision benchmark: `rigid-body-sim bench --quick` runs and its measures are right.

- The quick benchmark writes the markdown table and the PNG plot, with a row for every
  registered integrator and, when mujoco imports, for MuJoCo's integrators.
- The orientation error measure returns the angle of a known rotation to round-off.
- The ODE reference matches the closed-form motion of a free symmetric top.
- The MuJoCo peer converges to the reference at fourth order with its RK4 (so it models the
  same body with the same frame conventions: a wrong inertia, frame or quaternion order
  would leave an O(1) error that no step size removes).
- The cost interpolation recovers the cost of a known power-law work-precision curve.
"""

import math

import numpy as np
import pytest
from rigid_body_sim import cli
from rigid_body_sim.benchmark.bodies import benchmark_cases
from rigid_body_sim.benchmark.peer_mujoco import mjcf_model
from rigid_body_sim.benchmark.peer_mujoco import mujoco_available
from rigid_body_sim.benchmark.peer_mujoco import MUJOCO_INTEGRATORS
from rigid_body_sim.benchmark.peer_mujoco import MujocoPeer
from rigid_body_sim.benchmark.reference import ode_reference
from rigid_body_sim.benchmark.reference import rotation_angle
from rigid_body_sim.benchmark.report import cost_to_reach
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import State
from rigid_body_sim.physics.rotations import rotation_matrix_from_rotation_vector

EPS = np.finfo(float).eps


def test_bench_quick_writes_a_table_and_a_plot_with_every_integrator(tmp_path, capsys):
    """`bench --quick` exits 0 and writes results.md (all methods) and a PNG plot."""
    out = tmp_path / 'bench'
    assert cli.main(['bench', '--quick', '--out', str(out)]) == 0
    table = (out / 'results.md').read_text()
    with open(out / 'work_precision.png', 'rb') as plot:
        assert plot.read(8) == b'\x89PNG\r\n\x1a\n'
    assert (out / 'results.json').stat().st_size > 0
    assert (out / 'results.csv').stat().st_size > 0
    methods = list(INTEGRATORS)
    if mujoco_available():
        methods += list(MUJOCO_INTEGRATORS)
    else:
        assert 'not installed' in table
    for method in methods:
        assert f'\n| {method} | 0.1 |' in table, f'no row for {method}'
        assert f'\n| {method} | 0.01 |' in table, f'no row for {method}'


@pytest.mark.parametrize('angle', [0.0, 1e-14, 1e-9, 1e-3, 0.5, 2.0, math.pi - 1e-7])
def test_orientation_error_of_a_known_rotation_is_its_angle(angle):
    """rotation_angle(R, R exp(angle [n]x)) = angle, to a few ulp, for any R and axis n."""
    rng = np.random.default_rng(11)
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        rotation = rotation_matrix_from_rotation_vector(rng.normal(size=3))
        turned = rotation @ rotation_matrix_from_rotation_vector(angle * axis)
        # The entries of both matrices carry a few eps of rounding from the products; sine
        # and cosine are sums of a few of them, so the angle is good to ~10 eps absolute.
        assert abs(rotation_angle(rotation, turned) - angle) <= 10.0 * EPS
        assert abs(rotation_angle(turned, rotation) - angle) <= 10.0 * EPS


def test_ode_reference_matches_the_closed_form_free_symmetric_top():
    """
    For I = (I1, I1, I3): R(t) = exp(t [L]x / I1) R0 exp(t c [e3]x), c = (1/I3 - 1/I1) M3.

    With I_b = I1 E + (I3 - I1) e3 e3^T the world angular velocity is
    omega = L / I1 + c R e3, and [R e3]x R = R [e3]x, so dR/dt = [L / I1]x R + c R [e3]x
    is solved by the product of two fixed-axis rotations.
    """
    body = RigidBody(1.0, (1.0, 1.0, 2.0))
    rotation0 = rotation_matrix_from_rotation_vector([0.3, -0.8, 0.5])
    state = State.from_velocity(body, rotation=rotation0,
                                angular_velocity_body=(0.7, -0.4, 3.0))
    momentum = state.angular_momentum
    rate = (1.0 / 2.0 - 1.0 / 1.0) * (rotation0.T @ momentum)[2]
    time = 10.0
    exact = (rotation_matrix_from_rotation_vector(time * momentum / 1.0) @ rotation0
             @ rotation_matrix_from_rotation_vector([0.0, 0.0, time * rate]))
    # DOP853 at rtol 1e-13 over ~30 rad of rotation: ~1e-13 per rad at worst.
    assert rotation_angle(ode_reference(body, state, [time])[time], exact) < 3e-12


def test_mujoco_model_uses_fullinertia_only_for_a_non_diagonal_tensor():
    """A diagonal tensor is given as diaginertia, a non-diagonal one as fullinertia."""
    diagonal, non_diagonal = benchmark_cases(['van_zon', 'non_diagonal'])
    assert 'diaginertia="10.0 20.0 26.0"' in mjcf_model(diagonal.body, 'RK4', 0.01)
    assert 'fullinertia="2.0 3.0 4.0 -0.3 0.2 0.4"' in mjcf_model(non_diagonal.body, 'RK4',
                                                                  0.01)


@pytest.mark.skipif(not mujoco_available(), reason='mujoco is not installed')
def test_mujoco_peer_converges_to_the_reference_at_fourth_order():
    """
    The peer's RK4 at dt = 1e-3 agrees with the reference; halving dt cuts the error 16x.

    Every benchmark body, over 1 s: the non-diagonal one at an oblique orientation checks
    the inertia tensor, the body-frame angular velocity and the (w, x, y, z) order at once.
    """
    duration = 1.0
    for case in benchmark_cases():
        reference = ode_reference(case.body, case.state, [duration])[duration]
        errors = []
        for dt in (2e-3, 1e-3):
            peer = MujocoPeer(case.body, case.state, 'mujoco_rk4', dt)
            peer.step(round(duration / dt))
            errors.append(rotation_angle(peer.rotation, reference))
            momentum_error = (np.linalg.norm(peer.angular_momentum - case.state.angular_momentum)
                              / np.linalg.norm(case.state.angular_momentum))
            assert momentum_error < 1e-8, case.name
        # Fastest body (van_zon, |Omega| ~ 15 rad/s): RK4's error ~ (|Omega| dt)^4 per
        # radian turned is ~1e-12 per rad at dt = 1e-3, times ~15 rad.
        assert errors[1] < 1e-9, (case.name, errors)
        if errors[0] > 1e-11:  # above round-off, where the order shows
            assert 8.0 < errors[0] / errors[1] < 32.0, (case.name, errors)


def test_cost_to_reach_interpolates_a_power_law_curve():
    """On error = dt^2, cost = 1e-6 / dt, the cost to reach e is 1e-6 / sqrt(e)."""
    dts = [0.1, 0.03, 0.01, 0.003, 0.001]
    points = [(1e-6 / dt, dt * dt) for dt in dts]
    cost, at_coarsest = cost_to_reach(points, 1e-4)
    assert cost == pytest.approx(1e-6 / 1e-2, rel=1e-12)
    assert not at_coarsest
    cost, at_coarsest = cost_to_reach(points, 0.1)
    assert cost == pytest.approx(1e-5) and at_coarsest
    assert cost_to_reach(points, 1e-7) == (math.inf, False)

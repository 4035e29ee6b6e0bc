"""
Mass properties: the closed-form constructors, and every validation error with its message.

RigidBody, State and Simulator validate at the public boundary with a ValueError that names
the rule and the value; these tests pin both the rule and the message.  Units SI, body frame
about the COM.
"""

import itertools
import math
import re

import numpy as np
import pytest
from reference import random_rotation
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State

# Round-off of a 3x3 eigen-decomposition or a short sum, relative to the largest entry.
ROUND_OFF = 1e-14


def _hand_inertia(masses, positions):
    """Return (COM, inertia about it) by the definition, one point at a time."""
    total = sum(masses)
    com = [sum(m * r[k] for m, r in zip(masses, positions)) / total for k in range(3)]
    inertia = [[0.0] * 3 for _ in range(3)]
    for m, r in zip(masses, positions):
        d = [r[k] - com[k] for k in range(3)]
        squared = d[0] ** 2 + d[1] ** 2 + d[2] ** 2
        for j in range(3):
            for k in range(3):
                inertia[j][k] += m * ((squared if j == k else 0.0) - d[j] * d[k])
    return np.array(com), np.array(inertia)


# -- closed forms of the shape constructors (physics.md, "Mass properties")


def test_box_has_closed_form_inertia_m_over_12():
    a, b, c, m = 0.3, 0.5, 1.1, 2.5
    body = RigidBody.box(m, (a, b, c))
    expected = m / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(np.diag(body.inertia), expected, rtol=ROUND_OFF)
    np.testing.assert_array_equal(body.inertia - np.diag(np.diag(body.inertia)), 0.0)
    assert body.mass == m


def test_cylinder_has_closed_form_inertia_about_its_z_axis():
    r, h, m = 0.2, 0.7, 3.0
    body = RigidBody.cylinder(m, r, h)
    side = m * (3 * r * r + h * h) / 12.0
    np.testing.assert_allclose(np.diag(body.inertia), [side, side, m * r * r / 2.0],
                               rtol=ROUND_OFF)
    assert body.is_symmetric_top


def test_sphere_has_two_fifths_m_r_squared_about_every_axis():
    body = RigidBody.sphere(4.0, 0.5)
    np.testing.assert_allclose(body.inertia, np.eye(3) * 0.4 * 4.0 * 0.25, rtol=ROUND_OFF)
    assert body.is_symmetric_top and body.is_spherical_top


def test_ellipsoid_has_closed_form_inertia_m_over_5():
    a, b, c, m = 0.3, 0.5, 1.1, 2.5
    body = RigidBody.ellipsoid(m, (a, b, c))
    expected = m / 5.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(np.diag(body.inertia), expected, rtol=ROUND_OFF)


def test_inertia_inverse_is_the_inverse_of_the_tensor():
    rng = np.random.default_rng(11)
    rotation = random_rotation(rng)
    body = RigidBody(1.0, rotation @ np.diag([2.0, 3.0, 4.5]) @ rotation.T)
    np.testing.assert_allclose(body.inertia @ body.inertia_inverse, np.eye(3), atol=ROUND_OFF)
    np.testing.assert_array_equal(body.inertia_inverse, body.inertia_inverse.T)


# -- point masses


def test_point_masses_give_the_hand_computed_com_and_inertia():
    masses = [1.0, 2.0, 3.0, 0.5]
    positions = [[0.1, 0.2, 0.3], [-0.4, 0.5, 0.0], [0.3, -0.2, 0.7], [1.0, 1.0, -1.0]]
    body = RigidBody.from_point_masses(masses, positions)
    com, inertia = _hand_inertia(masses, positions)
    np.testing.assert_allclose(body.center_of_mass, com, rtol=ROUND_OFF, atol=ROUND_OFF)
    np.testing.assert_allclose(body.inertia, inertia, rtol=1e-13, atol=1e-13)
    assert body.mass == pytest.approx(6.5, rel=ROUND_OFF)


def test_eight_box_corners_give_m_over_4_inertia():
    a, b, c, m = 0.4, 1.0, 1.6, 2.0
    corners = [[sx * a / 2, sy * b / 2, sz * c / 2]
               for sx, sy, sz in itertools.product((-1, 1), repeat=3)]
    offset = np.array([3.0, -2.0, 5.0])
    body = RigidBody.from_point_masses([m / 8] * 8, np.array(corners) + offset)
    # Each corner mass sits at (+-a/2, +-b/2, +-c/2): I_xx = m (b^2 + c^2) / 4, and cyclic.
    expected = m / 4.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(np.diag(body.inertia), expected, rtol=1e-13)
    np.testing.assert_allclose(body.inertia - np.diag(np.diag(body.inertia)), 0.0, atol=1e-13)
    np.testing.assert_allclose(body.center_of_mass, offset, rtol=ROUND_OFF)


def test_point_masses_inertia_turns_with_the_points():
    rng = np.random.default_rng(5)
    masses = rng.uniform(0.5, 2.0, size=6)
    positions = rng.normal(size=(6, 3))
    rotation = random_rotation(rng)
    body = RigidBody.from_point_masses(masses, positions)
    turned = RigidBody.from_point_masses(masses, positions @ rotation.T)
    np.testing.assert_allclose(turned.inertia, rotation @ body.inertia @ rotation.T,
                               atol=1e-13 * np.max(body.inertia))
    np.testing.assert_allclose(turned.center_of_mass, rotation @ body.center_of_mass,
                               atol=1e-14)


def test_three_points_make_a_valid_lamina():
    body = RigidBody.from_point_masses([1.0, 1.0, 1.0], [[0, 0, 0], [1, 0, 0], [0, 2, 0]])
    i1, i2, i3 = body.principal_moments
    assert i3 == pytest.approx(i1 + i2, rel=1e-13)


# Each message names the rule and the values: the offending entry, or for a degenerate set
# its points (up to 4) and the singular values of their offsets from the COM (the spread
# along each principal direction: one or none non-zero for collinear or coincident points,
# the others zero to round-off, so only their count is matched).
@pytest.mark.parametrize('masses, positions, message', [
    ([1.0, 1.0, 1.0], [[0, 0, 0], [1, 1, 1], [2, 2, 2]],
     re.escape('degenerate point set: 3 point(s) at [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], '
               '[2.0, 2.0, 2.0]] m that are coincident or collinear')
     + r'.*offsets from the COM: 2\.45, \S+, \S+ m\)'),
    ([1.0, 2.0, 3.0, 4.0], [[1, 2, 3]] * 4,
     r'4 point\(s\) at \[\[1\.0, 2\.0, 3\.0\], .*COM: 0, 0, 0 m\)'),
    ([1.0, 1.0], [[0, 0, 0], [1, 0, 0]],
     r'2 point\(s\) at .*COM: 0\.707, 0 m\); need at least 3 non-collinear points'),
    ([1.0], [[0, 0, 0]], r'degenerate point set: 1 point\(s\) at \[\[0\.0, 0\.0, 0\.0\]\] m'),
    ([1.0] * 5, [[k, 2 * k, 0] for k in range(5)],
     r'degenerate point set: 5 point\(s\) that are .*COM: 7\.07, \S+, \S+ m\)'),
    (np.zeros(0), np.zeros((0, 3)), 'need at least 3 non-collinear points; got none'),
    ([1.0, 1.0, 1.0], [[0, 0], [1, 0], [0, 1]], r'positions must have shape \(n, 3\)'),
    ([1.0, 1.0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]], r'n = len\(masses\) = 2'),
    ([1.0, 0.0, 1.0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
     re.escape('point masses must each be > 0 kg; got [1.0, 0.0, 1.0]')),
    ([1.0, -1.0, 1.0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
     re.escape('point masses must each be > 0 kg; got [1.0, -1.0, 1.0]')),
    ([1.0, 1.0, 1.0], [[0, 0, 0], [1, math.nan, 0], [0, 1, 0]],
     re.escape('point mass positions must be finite; got position 1 = [1.0, nan, 0.0] m')),
    ([1.0, math.inf, 1.0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
     re.escape('point masses must be finite; got [1.0, inf, 1.0] kg')),
])
def test_point_masses_reject_degenerate_and_malformed_sets(masses, positions, message):
    with pytest.raises(ValueError, match=message):
        RigidBody.from_point_masses(masses, positions)


def test_nearly_collinear_points_with_real_width_are_accepted():
    # 1e-6 m off a 1 m line: thin but a genuine body with finite moments.
    body = RigidBody.from_point_masses([1.0, 1.0, 1.0], [[0, 0, 0], [1, 0, 0], [2, 1e-6, 0]])
    assert body.principal_moments[0] > 0.0


# -- principal moments and axes


def test_principal_axes_diagonalise_the_tensor_right_handed_with_ascending_moments():
    rng = np.random.default_rng(2)
    for _ in range(50):
        # Moments in [1, 2) always satisfy I1 + I2 >= I3.
        moments = np.sort(rng.uniform(1.0, 2.0, size=3))
        rotation = random_rotation(rng)
        body = RigidBody(1.0, rotation @ np.diag(moments) @ rotation.T)
        axes = body.principal_axes
        assert np.all(np.diff(body.principal_moments) >= 0.0)
        np.testing.assert_allclose(body.principal_moments, moments, rtol=1e-13)
        assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-13)
        np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-13)
        np.testing.assert_allclose(body.inertia @ axes, axes * body.principal_moments,
                                   atol=1e-13)


@pytest.mark.parametrize('moments, symmetric, spherical', [
    ((1.0, 2.0, 3.0), False, False),
    ((1.0, 1.0, 1.5), True, False),
    ((1.0, 1.5, 1.5), True, False),
    ((1.0, 1.0 * (1 + 1e-12), 1.5), True, False),
    ((1.0, 1.0 + 1e-6, 1.5), False, False),
    ((2.0, 2.0, 2.0), True, True),
    ((1e-6, 1.0, 1.0), True, False),
])
def test_symmetric_top_is_two_equal_moments(moments, symmetric, spherical):
    body = RigidBody(1.0, moments)
    assert body.is_symmetric_top is symmetric
    assert body.is_spherical_top is spherical


def test_mass_properties_are_read_only():
    body = RigidBody.box(1.0, (1.0, 2.0, 3.0))
    for array in (body.inertia, body.inertia_inverse, body.principal_moments,
                  body.principal_axes):
        with pytest.raises(ValueError, match='read-only'):
            array[0] = 1.0


# -- RigidBody validation


@pytest.mark.parametrize('mass, message', [
    (math.nan, 'mass must be finite; got nan'),
    (math.inf, 'mass must be finite; got inf'),
    (0.0, 'mass must be > 0 kg; got 0'),
    (-2.0, 'mass must be > 0 kg; got -2'),
    ('heavy', 'mass must be a number in kg'),
    (None, 'mass must be a number in kg'),
])
def test_rigid_body_rejects_a_mass_that_is_not_positive_and_finite(mass, message):
    with pytest.raises(ValueError, match=message):
        RigidBody(mass, (1.0, 2.0, 3.0))


@pytest.mark.parametrize('inertia, message', [
    ((1.0, math.nan, 1.0),
     re.escape('inertia must be finite; got [[1.0, 0.0, 0.0], [0.0, nan, 0.0], '
               '[0.0, 0.0, 1.0]]')),
    (np.diag([1.0, 1.0, math.inf]), re.escape('got [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], '
                                              '[0.0, 0.0, inf]]')),
    (np.eye(2), r'inertia must be a 3x3 tensor .* got shape \(2, 2\)'),
    ((1.0, 2.0, 3.0, 4.0), r'got shape \(4,\)'),
    ([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
     r'inertia tensor must be symmetric: I\[0\]\[1\] = 0.1 but I\[1\]\[0\] = 0'),
    ((-1.0, 1.0, 1.0), re.escape('inertia tensor must be positive definite (a body with '
                                 'volume); got principal moments [-1.0, 1.0, 1.0] kg m^2')),
    ((0.0, 1.0, 1.0), re.escape('positive definite (a body with volume); got principal '
                                'moments [0.0, 1.0, 1.0] kg m^2')),
    (np.zeros((3, 3)), re.escape('positive definite (a body with volume); got principal '
                                 'moments [0.0, 0.0, 0.0] kg m^2')),
    ((1.0, 1.0, 3.0), re.escape('triangle inequality I1 + I2 >= I3; got I1 + I2 = 2 < I3 = 3 '
                                '(moments [1.0, 1.0, 3.0] kg m^2): no real body has these')),
    ((1.0, 2.0, 3.0 * (1 + 1e-8)),
     re.escape('got I1 + I2 = 3 < I3 = 3.00000003 (moments [1.0, 2.0, 3.00000003] kg m^2)')),
    (np.diag([1.0, 1.0, 2.0 + 1e-9]),
     re.escape('got I1 + I2 = 2 < I3 = 2 (moments [1.0, 1.0, 2.000000001] kg m^2)')),
])
def test_rigid_body_rejects_an_impossible_inertia_tensor(inertia, message):
    with pytest.raises(ValueError, match=message):
        RigidBody(1.0, inertia)


def test_lamina_on_the_triangle_inequality_is_a_valid_body():
    rng = np.random.default_rng(9)
    rotation = random_rotation(rng)
    # I3 = I1 + I2 exactly (a flat plate), also after rotation round-off.
    for tensor in (np.diag([1.0, 2.0, 3.0]), rotation @ np.diag([1.0, 2.0, 3.0]) @ rotation.T):
        body = RigidBody(1.0, tensor)
        i1, i2, i3 = body.principal_moments
        assert i3 == pytest.approx(i1 + i2, rel=1e-13)


def test_round_off_asymmetry_is_accepted_and_symmetrised():
    tensor = np.diag([1.0, 2.0, 2.5])
    tensor[0, 1] = 1e-13
    body = RigidBody(1.0, tensor)
    np.testing.assert_array_equal(body.inertia, body.inertia.T)


@pytest.mark.parametrize('make, message', [
    (lambda: RigidBody.box(1.0, (1.0, 2.0)), r'box size must have 3 value\(s\) in m; got 2'),
    (lambda: RigidBody.box(1.0, (1.0, 0.0, 2.0)),
     re.escape('box size must be > 0 m; got [1.0, 0.0, 2.0]')),
    (lambda: RigidBody.box(1.0, (1.0, math.nan, 2.0)),
     re.escape('box size must be finite; got [1.0, nan, 2.0]')),
    (lambda: RigidBody.box(-1.0, (1.0, 1.0, 1.0)), 'mass must be > 0 kg; got -1'),
    (lambda: RigidBody.cylinder(1.0, 0.0, 1.0),
     re.escape('cylinder radius must be > 0 m; got [0.0]')),
    (lambda: RigidBody.cylinder(1.0, 1.0, -1.0),
     re.escape('cylinder height must be > 0 m; got [-1.0]')),
    (lambda: RigidBody.sphere(1.0, math.inf),
     re.escape('sphere radius must be finite; got [inf]')),
    (lambda: RigidBody.sphere(0.0, 1.0), 'mass must be > 0 kg; got 0'),
    (lambda: RigidBody.ellipsoid(1.0, (1.0, 1.0, -1.0)),
     re.escape('ellipsoid semi_axes must be > 0 m; got [1.0, 1.0, -1.0]')),
])
def test_shape_constructors_reject_bad_dimensions(make, message):
    with pytest.raises(ValueError, match=message):
        make()


# -- State validation


@pytest.mark.parametrize('kwargs, message', [
    ({'position': (0.0, math.nan, 0.0)}, 'position must be finite'),
    ({'linear_momentum': (math.inf, 0.0, 0.0)}, 'linear_momentum must be finite'),
    ({'angular_momentum': (0.0, 0.0, -math.inf)}, 'angular_momentum must be finite'),
    ({'position': (1.0, 2.0)}, r'position must be a 3-vector in m; got \(2,\)'),
    ({'angular_momentum': np.zeros((3, 3))}, 'angular_momentum must be a 3-vector in kg m'),
    ({'rotation': np.full((3, 3), math.nan)}, 'rotation must be finite'),
    ({'rotation': 1.001 * np.eye(3)}, r'rotation must be orthonormal \(max \|R\^T R - E\|'),
    ({'rotation': [[1.0, 1e-3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}, 'orthonormal'),
    ({'rotation': np.diag([1.0, 1.0, -1.0])}, r'proper rotation \(det R = \+1\); got det R = -1'),
    ({'rotation': -np.eye(3)}, 'a reflection'),
    ({'rotation': np.eye(2)}, r'rotation must be a 3x3 rotation matrix; got shape \(2, 2\)'),
    ({'rotation': (0.0, 0.0, 0.0, 2.0)}, r'must have unit norm; got \|q\| = 2'),
    ({'rotation': (0.0, 0.0, 0.0, 0.0)}, 'must have unit norm'),
    ({'rotation': (0.0, 0.0, math.nan, 1.0)}, 'rotation quaternion must be finite'),
])
def test_state_rejects_invalid_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        State(**kwargs)


def test_state_from_velocity_rejects_both_angular_velocities():
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    with pytest.raises(ValueError, match='not both'):
        State.from_velocity(body, angular_velocity_body=(1, 0, 0),
                            angular_velocity_world=(1, 0, 0))


def test_state_from_velocity_rejects_non_finite_velocity():
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    with pytest.raises(ValueError, match='velocity must be finite'):
        State.from_velocity(body, velocity=(math.nan, 0, 0))
    with pytest.raises(ValueError, match='angular_velocity_world must be finite'):
        State.from_velocity(body, angular_velocity_world=(0, math.inf, 0))


# -- Simulator validation


def _simulator(**kwargs):
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    return Simulator(body, State.from_velocity(body, angular_velocity_body=(0, 1, 0)),
                     **kwargs)


def test_unknown_integrator_error_lists_every_valid_name():
    with pytest.raises(ValueError, match="unknown integrator 'euler'") as raised:
        _simulator(integrator='euler')
    message = str(raised.value)
    assert 'valid integrators:' in message
    for name in INTEGRATORS:
        assert name in message


def test_setting_an_unknown_integrator_keeps_the_previous_one():
    simulator = _simulator(integrator='rk4')
    with pytest.raises(ValueError, match='valid integrators'):
        simulator.integrator = 'nope'
    assert simulator.integrator == 'rk4'


@pytest.mark.parametrize('dt, message', [
    (0.0, 'dt must be finite and > 0 s; got 0.0'),
    (-1e-3, 'dt must be finite and > 0 s'),
    (math.nan, 'dt must be finite and > 0 s'),
    (math.inf, 'dt must be finite and > 0 s'),
    ('fast', "dt must be a number of seconds; got 'fast'"),
])
def test_step_and_run_reject_a_bad_dt(dt, message):
    simulator = _simulator()
    before = simulator.state
    with pytest.raises(ValueError, match=message):
        simulator.step(dt)
    with pytest.raises(ValueError, match=message):
        simulator.run(1.0, dt)
    assert simulator.state is before and simulator.time == 0.0


@pytest.mark.parametrize('duration, message', [
    (-1.0, 'duration must be finite and >= 0 s'),
    (math.nan, 'duration must be finite and >= 0 s'),
    (math.inf, 'duration must be finite and >= 0 s'),
    ('long', 'duration must be a number of seconds'),
])
def test_run_rejects_a_bad_duration(duration, message):
    simulator = _simulator()
    with pytest.raises(ValueError, match=message):
        simulator.run(duration, 1e-3)


def test_run_of_zero_duration_leaves_the_state_unchanged():
    simulator = _simulator()
    before = simulator.state
    simulator.run(0.0, 1e-3)
    assert simulator.state == before and simulator.time == 0.0


@pytest.mark.parametrize('kwargs, message', [
    ({'frame': 'inertial'}, "frame must be one of world, body; got 'inertial'"),
    ({'force': (1.0, 2.0)}, 'force must be a 3-vector'),
    ({'torque': (0.0, math.nan, 0.0)}, 'torque must be finite'),
])
def test_set_wrench_rejects_bad_frames_and_vectors(kwargs, message):
    simulator = _simulator()
    with pytest.raises(ValueError, match=message):
        simulator.set_wrench(**kwargs)


def test_simulator_rejects_a_state_that_is_not_a_state():
    with pytest.raises(ValueError, match='state must be a State; got tuple'):
        Simulator(RigidBody(1.0, (1.0, 2.0, 3.0)), (0, 0, 0))
    simulator = _simulator()
    with pytest.raises(ValueError, match='state must be a State; got dict'):
        simulator.reset({})


@pytest.mark.parametrize('time', [float('nan'), float('inf'), 'soon'])
def test_simulator_reset_rejects_a_time_that_is_not_a_finite_number(time):
    body = RigidBody(1.0, (1.0, 2.0, 3.0))
    simulator = Simulator(body, State())
    with pytest.raises(ValueError, match='time must be'):
        simulator.reset(State(), time=time)
    assert simulator.time == 0.0

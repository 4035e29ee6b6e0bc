"""
State: an immutable world-frame value, its rotation forms and the derived velocities.

Conventions (physics.md): R maps body to world, quaternions are (x, y, z, w) composed with
the Hamilton product, L is about the COM in the world frame, omega = I_w^{-1} L,
Omega = R^T omega, v = p / m.
"""

import math

import numpy as np
import pytest
from reference import random_rotation
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import State

EPS = np.finfo(float).eps


def _body():
    rng = np.random.default_rng(21)
    rotation = random_rotation(rng)
    return RigidBody(2.0, rotation @ np.diag([1.0, 1.5, 2.2]) @ rotation.T)


def test_default_state_is_at_rest_at_the_origin_with_identity_rotation():
    state = State()
    np.testing.assert_array_equal(state.rotation, np.eye(3))
    np.testing.assert_array_equal(state.quaternion, [0.0, 0.0, 0.0, 1.0])
    for vector in (state.position, state.linear_momentum, state.angular_momentum):
        np.testing.assert_array_equal(vector, np.zeros(3))


def test_quaternion_is_x_y_z_w_and_maps_body_to_world():
    # A quarter turn about world z: the body x axis points along world y.
    half = math.pi / 4
    state = State((0.0, 0.0, math.sin(half), math.cos(half)))
    np.testing.assert_allclose(state.rotation @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=EPS)
    np.testing.assert_allclose(state.rotation @ [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], atol=EPS)


def test_rotation_matrix_and_quaternion_agree_both_ways():
    rng = np.random.default_rng(4)
    for _ in range(100):
        rotation = random_rotation(rng)
        from_matrix = State(rotation)
        from_quaternion = State(from_matrix.quaternion)
        # Shepperd's method: R -> q -> R reproduces R to a few ulps.
        np.testing.assert_allclose(from_matrix.rotation, rotation, atol=8 * EPS)
        # The quaternion is re-normalised on input, which may move it by an ulp.
        np.testing.assert_allclose(from_quaternion.rotation, from_matrix.rotation, atol=4 * EPS)
        assert from_matrix.quaternion[3] >= 0.0
        assert np.linalg.norm(from_matrix.quaternion) == pytest.approx(1.0, abs=2 * EPS)


def test_opposite_quaternions_give_the_same_rotation():
    rng = np.random.default_rng(6)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    np.testing.assert_allclose(State(q).rotation, State(-q).rotation, atol=4 * EPS)


def test_nearly_orthonormal_input_is_stored_orthonormal_to_round_off():
    rng = np.random.default_rng(8)
    rotation = random_rotation(rng) + 1e-8 * rng.normal(size=(3, 3))
    state = State(rotation)
    error = np.max(np.abs(state.rotation.T @ state.rotation - np.eye(3)))
    assert error <= 4 * EPS
    assert np.linalg.det(state.rotation) == pytest.approx(1.0, abs=4 * EPS)


def test_from_velocity_round_trips_body_and_world_angular_velocity():
    body = _body()
    rng = np.random.default_rng(12)
    rotation = random_rotation(rng)
    omega_body = rng.normal(size=3)
    state = State.from_velocity(body, rotation=rotation, angular_velocity_body=omega_body)
    # L = R I_b Omega; the stored R is re-derived from q, so allow a few ulps of it.
    np.testing.assert_allclose(state.angular_momentum, rotation @ body.inertia @ omega_body,
                               atol=1e-14)
    np.testing.assert_allclose(state.angular_velocity_body(body), omega_body, atol=1e-14)
    np.testing.assert_allclose(state.angular_velocity(body), rotation @ omega_body, atol=1e-14)
    world = State.from_velocity(body, rotation=rotation,
                                angular_velocity_world=rotation @ omega_body)
    np.testing.assert_allclose(world.angular_momentum, state.angular_momentum, atol=1e-14)
    inertia_world = state.inertia_world(body)
    np.testing.assert_allclose(inertia_world @ state.angular_velocity(body),
                               state.angular_momentum, atol=1e-14)


def test_linear_momentum_is_mass_times_velocity():
    body = _body()
    state = State.from_velocity(body, position=(1.0, 2.0, 3.0), velocity=(0.5, -1.0, 2.0))
    np.testing.assert_array_equal(state.linear_momentum, [1.0, -2.0, 4.0])
    np.testing.assert_array_equal(state.velocity(body), [0.5, -1.0, 2.0])
    np.testing.assert_array_equal(state.position, [1.0, 2.0, 3.0])


def test_kinetic_energy_is_translational_plus_rotational():
    body = _body()
    rng = np.random.default_rng(13)
    velocity = rng.normal(size=3)
    omega_body = rng.normal(size=3)
    state = State.from_velocity(body, rotation=random_rotation(rng), velocity=velocity,
                                angular_velocity_body=omega_body)
    expected = 0.5 * body.mass * velocity @ velocity + 0.5 * omega_body @ body.inertia @ omega_body
    assert state.kinetic_energy(body) == pytest.approx(expected, rel=1e-14)


def test_state_is_immutable():
    state = State(position=(1.0, 2.0, 3.0))
    with pytest.raises(AttributeError, match='State is immutable'):
        state.position = np.zeros(3)
    for array in (state.rotation, state.quaternion, state.position, state.linear_momentum,
                  state.angular_momentum):
        with pytest.raises(ValueError, match='read-only'):
            array[0] = 0.0


def test_state_does_not_alias_its_inputs():
    position = np.array([1.0, 2.0, 3.0])
    rotation = np.eye(3)
    state = State(rotation, position)
    position[0] = 99.0
    rotation[0, 0] = -1.0
    np.testing.assert_array_equal(state.position, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(state.rotation, np.eye(3))


def test_replace_changes_only_the_given_fields_and_validates():
    state = State(position=(1.0, 2.0, 3.0), angular_momentum=(0.0, 1.0, 0.0))
    moved = state.replace(linear_momentum=(4.0, 5.0, 6.0))
    np.testing.assert_array_equal(moved.linear_momentum, [4.0, 5.0, 6.0])
    np.testing.assert_array_equal(moved.position, state.position)
    np.testing.assert_array_equal(moved.angular_momentum, state.angular_momentum)
    np.testing.assert_array_equal(moved.quaternion, state.quaternion)
    with pytest.raises(ValueError, match='position must be finite'):
        state.replace(position=(math.nan, 0.0, 0.0))


def test_equality_is_bitwise_and_states_are_unhashable():
    state = State(position=(1.0, 2.0, 3.0))
    assert state == State(position=(1.0, 2.0, 3.0))
    assert state != State(position=(1.0, 2.0, np.nextafter(3.0, 4.0)))
    assert state != (1.0, 2.0, 3.0)
    with pytest.raises(TypeError):
        hash(state)


def test_trusted_constructor_normalises_the_quaternion():
    state = State._from_arrays(np.array([0.0, 0.0, 0.0, 2.0]), np.zeros(3), np.zeros(3),
                               np.zeros(3))
    np.testing.assert_array_equal(state.quaternion, [0.0, 0.0, 0.0, 1.0])
    np.testing.assert_array_equal(state.rotation, np.eye(3))


def test_repr_shows_the_state_variables():
    text = repr(State(position=(1.0, 2.0, 3.0)))
    assert text.startswith('State(quaternion=') and 'position=[1., 2., 3.]' in text

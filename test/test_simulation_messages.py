"""
The core as simulation_interfaces messages (rigid_body_sim.messages.simulation).

EntityState carries pose and twist in its header's frame, the world frame here: a State
goes out and comes back within float64 rounding, the twist is the COM velocity and the
world-frame angular velocity, and what is not a state is refused with a one-line reason.
Where simulation_interfaces could not be built (no cmake or compiler), these tests skip
saying why; the one that checks the module without it runs everywhere.
"""

import math
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from rigid_body_sim.messages import simulation
from rigid_body_sim.physics.body import RigidBody
from rigid_body_sim.physics.state import State
from rigid_body_sim.text import MESSAGE_LIMIT

ROOT = Path(__file__).resolve().parent.parent
UNAVAILABLE = simulation.unavailable_reason()
needs_simulation_interfaces = pytest.mark.skipif(
    UNAVAILABLE is not None, reason=UNAVAILABLE or 'simulation_interfaces imports')

# An asymmetric body with a tilted (non-diagonal) inertia tensor: every axis matters.
BODY = RigidBody(2.5, [[0.30, 0.02, -0.01], [0.02, 0.50, 0.03], [-0.01, 0.03, 0.70]])
WORLD = 'world'


def _random_states(count, seed=7):
    """Return states of BODY with random orientation, position and velocities."""
    generator = np.random.default_rng(seed)
    states = []
    for _ in range(count):
        quaternion = generator.normal(size=4)
        states.append(State.from_velocity(
            BODY, rotation=quaternion / np.linalg.norm(quaternion),
            position=generator.uniform(-1e3, 1e3, 3), velocity=generator.normal(0, 10, 3),
            angular_velocity_world=generator.normal(0, 5, 3)))
    return states


def _entity_state(position=(1.0, 2.0, 3.0), orientation=(0.0, 0.0, 0.0, 1.0),
                  linear=(0.0, 0.0, 0.0), angular=(0.0, 0.0, 0.0), frame_id=WORLD):
    from simulation_interfaces.msg import EntityState
    message = EntityState()
    message.header.frame_id = frame_id
    pose = message.pose
    pose.position.x, pose.position.y, pose.position.z = position
    q = pose.orientation
    q.x, q.y, q.z, q.w = orientation
    twist = message.twist
    twist.linear.x, twist.linear.y, twist.linear.z = linear
    twist.angular.x, twist.angular.y, twist.angular.z = angular
    return message


def _vector(message):
    return np.array([message.x, message.y, message.z])


@needs_simulation_interfaces
def test_a_state_goes_through_an_entity_state_on_the_wire_and_back_within_float64_rounding():
    """Pose exact, quaternion and momenta to a few ulps (L within the inertia's condition)."""
    from rclpy.serialization import deserialize_message
    from rclpy.serialization import serialize_message
    from simulation_interfaces.msg import EntityState
    eps = np.finfo(float).eps
    condition = np.linalg.cond(BODY.inertia)
    for state in _random_states(50):
        sent = simulation.entity_state_message(BODY, state, 12_345, WORLD)
        received = deserialize_message(serialize_message(sent), EntityState)
        back = simulation.state_from_entity_state(received, BODY, WORLD)
        assert np.array_equal(back.position, state.position)
        np.testing.assert_allclose(back.quaternion, state.quaternion, rtol=0, atol=4 * eps)
        p_scale = np.linalg.norm(state.linear_momentum)
        np.testing.assert_allclose(back.linear_momentum, state.linear_momentum, rtol=0,
                                   atol=4 * eps * p_scale)
        l_scale = np.linalg.norm(state.angular_momentum)
        np.testing.assert_allclose(back.angular_momentum, state.angular_momentum, rtol=0,
                                   atol=16 * eps * condition * l_scale)


@needs_simulation_interfaces
def test_the_pose_is_the_com_and_body_to_world_quaternion_stamped_in_the_world_frame():
    state = _random_states(1)[0]
    message = simulation.entity_state_message(BODY, state, 3_000_000_007, 'odom')
    assert message.header.frame_id == 'odom'
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (3, 7)
    assert np.array_equal(_vector(message.pose.position), state.position)
    q = message.pose.orientation
    assert np.array_equal([q.x, q.y, q.z, q.w], state.quaternion)


@needs_simulation_interfaces
def test_the_twist_is_the_com_velocity_and_the_angular_velocity_in_world_axes():
    """A body turned 90 deg about world z, spinning about its own x: omega is along world y."""
    half = math.sqrt(0.5)
    body = RigidBody(2.0, [1.0, 2.0, 2.5])
    state = State.from_velocity(body, rotation=[0.0, 0.0, half, half], velocity=[1, -2, 3],
                                angular_velocity_body=[4.0, 0.0, 0.0])
    message = simulation.entity_state_message(body, state, 0)
    np.testing.assert_allclose(_vector(message.twist.linear), [1, -2, 3], rtol=1e-15)
    np.testing.assert_allclose(_vector(message.twist.angular), [0.0, 4.0, 0.0], atol=1e-15)


@needs_simulation_interfaces
def test_the_angular_acceleration_is_eulers_equations_turned_into_world_axes():
    """I dOmega/dt = tau_b - Omega x I Omega in body axes, domega/dt = R dOmega/dt; a = F/m."""
    force, torque = np.array([0.5, -1.0, 2.0]), np.array([0.1, 0.2, -0.3])
    for state in _random_states(10, seed=3):
        message = simulation.entity_state_message(BODY, state, 0, WORLD, force=force,
                                                  torque=torque)
        rotation = state.rotation
        omega_body = state.angular_velocity_body(BODY)
        torque_body = rotation.T @ torque
        expected = rotation @ np.linalg.solve(
            BODY.inertia, torque_body - np.cross(omega_body, BODY.inertia @ omega_body))
        np.testing.assert_allclose(_vector(message.acceleration.angular), expected,
                                   rtol=1e-12, atol=1e-12 * np.linalg.norm(expected))
        np.testing.assert_allclose(_vector(message.acceleration.linear), force / BODY.mass,
                                   rtol=1e-15)


@needs_simulation_interfaces
def test_a_body_spinning_about_a_principal_axis_untorqued_has_no_acceleration():
    body = RigidBody(1.0, [1.0, 2.0, 2.5])
    state = State.from_velocity(body, angular_velocity_body=[0.0, 3.0, 0.0])
    message = simulation.entity_state_message(body, state, 0)
    assert np.allclose(_vector(message.acceleration.angular), 0.0, atol=1e-15)
    assert np.array_equal(_vector(message.acceleration.linear), [0.0, 0.0, 0.0])


@needs_simulation_interfaces
def test_a_nearly_unit_quaternion_is_accepted_and_normalised():
    """Within 1e-6 of unit norm, as a scene file's orientation; the result is unit."""
    scale = 1.0 + 0.9e-6
    state = simulation.state_from_entity_state(
        _entity_state(orientation=(0.0, 0.0, 0.6 * scale, 0.8 * scale)), BODY)
    assert math.isclose(np.linalg.norm(state.quaternion), 1.0, abs_tol=1e-15)
    np.testing.assert_allclose(state.quaternion, [0.0, 0.0, 0.6, 0.8], atol=1e-15)


@needs_simulation_interfaces
@pytest.mark.parametrize('frame_id', ['', 'map', '/map'])
def test_the_world_frame_is_named_as_tf2_reads_it_or_left_empty(frame_id):
    state = simulation.state_from_entity_state(_entity_state(frame_id=frame_id), BODY, 'map')
    assert np.array_equal(state.position, [1.0, 2.0, 3.0])


REFUSALS = {
    'non-finite position': ({'position': (0.0, math.nan, 0.0)}, 'pose.position'),
    'infinite position': ({'position': (math.inf, 0.0, 0.0)}, 'pose.position'),
    'non-finite orientation': ({'orientation': (0.0, 0.0, math.nan, 1.0)},
                               'pose.orientation'),
    'zero quaternion': ({'orientation': (0.0, 0.0, 0.0, 0.0)}, 'unit quaternion'),
    'quaternion off unit by 2e-6': ({'orientation': (0.0, 0.0, 0.0, 1.0 + 2e-6)},
                                    'unit quaternion'),
    'huge quaternion': ({'orientation': (1e308, 1e308, 0.0, 0.0)}, 'unit quaternion'),
    'non-finite linear velocity': ({'linear': (math.inf, 0.0, 0.0)}, 'twist.linear'),
    'non-finite angular velocity': ({'angular': (0.0, 0.0, -math.nan)}, 'twist.angular'),
    'momentum overflowing': ({'linear': (1e308, 0.0, 0.0)}, 'overflows'),
    'angular momentum overflowing': ({'angular': (1e308, 0.0, 0.0),
                                      'body': RigidBody(1.0, [10.0, 20.0, 25.0])},
                                     'overflows'),
    'another frame': ({'frame_id': 'map'}, "header.frame_id is 'map'"),
    'the world frame with two slashes': ({'frame_id': '//world'}, "header.frame_id is '//world'"),
    'a frame id of control characters, a megabyte long': (
        {'frame_id': '\x1b[2J' * 250_000}, 'header.frame_id'),
}


@needs_simulation_interfaces
@pytest.mark.parametrize('fields, reason', REFUSALS.values(), ids=REFUSALS)
def test_what_is_not_a_state_is_refused_with_a_one_line_reason_naming_it(fields, reason):
    fields = dict(fields)
    body = fields.pop('body', BODY)
    with pytest.raises(ValueError) as refused:
        simulation.state_from_entity_state(_entity_state(**fields), body, WORLD)
    message = str(refused.value)
    assert reason in message
    assert message.isprintable() and len(message) <= MESSAGE_LIMIT, message[:300]


@needs_simulation_interfaces
def test_a_result_keeps_its_code_and_makes_its_reason_one_printable_bounded_line():
    from simulation_interfaces.msg import Result
    made = simulation.result(Result.RESULT_NOT_FOUND, 'no entity\n\x1b[31m' + 'x' * 10 ** 6)
    assert made.result == Result.RESULT_NOT_FOUND
    assert made.error_message.isprintable() and len(made.error_message) <= MESSAGE_LIMIT
    assert made.error_message.startswith('no entity\\n\\x1b[31m')
    assert simulation.result(Result.RESULT_OK).error_message == ''


@needs_simulation_interfaces
def test_the_features_are_listed_once_each_in_order_and_unknown_numbers_refused():
    from simulation_interfaces.msg import SimulatorFeatures as Features
    served = [Features.STEP_SIMULATION_ACTION, Features.SPAWNING, Features.SPAWNING,
              Features.ENTITY_STATE_GETTING]
    message = simulation.features_message(served, spawn_formats=['yaml'])
    assert list(message.features) == sorted({Features.SPAWNING, Features.ENTITY_STATE_GETTING,
                                             Features.STEP_SIMULATION_ACTION})
    assert list(message.spawn_formats) == ['yaml']
    with pytest.raises(ValueError, match=r'\[99\]'):
        simulation.features_message([Features.SPAWNING, 99])


def test_without_simulation_interfaces_the_module_imports_and_says_why_in_one_line():
    """The node imports the module anyway: it must load, say why, and refuse to convert."""
    script = (
        'import sys\n'
        "sys.modules['simulation_interfaces'] = None\n"  # what a venv without it does
        'from rigid_body_sim.messages import simulation\n'
        'reason = simulation.unavailable_reason()\n'
        'print(reason)\n'
        'try:\n'
        "    simulation.result(1, 'ok')\n"
        'except ImportError as error:\n'
        '    assert str(error) == reason\n'
        'else:\n'
        "    raise SystemExit('converted without the messages')\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    ran = subprocess.run([sys.executable, '-c', script], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=120)
    assert ran.returncode == 0, ran.stderr
    (reason,) = ran.stdout.splitlines()
    assert reason.startswith('simulation_interfaces cannot be imported (')
    assert 'make venv' in reason

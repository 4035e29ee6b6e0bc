"""
The node driven in this process: its callbacks called directly, as the executor would.

No executor spins the node here: each test sets the node up as a late or busy node finds
it (deadlines on the steady clock in the past, a subscriber present), calls the callbacks
the executor would call, and reads what the simulation and the publishers did.
"""

import time

from geometry_msgs.msg import Vector3Stamped
from node_harness import isolate_ros_environment
from node_harness import start_node_in_process
from node_harness import stop_node_in_process
import numpy as np
import pytest
from rcl_interfaces.srv import DescribeParameters
import rclpy
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rigid_body_sim.node.parameter_services import ParameterServices
from rigid_body_sim.node.rigid_body_node import RigidBodyNode
from std_srvs.srv import Trigger


def start_node(scene='default'):
    """Return a node of `scene` in a context of its own, not spun."""
    return start_node_in_process(RigidBodyNode, scene)


stop_node = stop_node_in_process


@pytest.fixture
def node():
    """Give a node of the default scene (100 Hz), not spun."""
    node = start_node()
    yield node
    stop_node(node)


def test_ticks_due_before_a_reset_are_not_run_after_it(node):
    """
    A reset restarts simulated time at 0 now: the late node's backlog does not follow it.

    Ticks are due every wall period after the reset, and one runs at most half a period
    before it is due: so the simulated time after a reset is at most the wall time since
    it (at real_time_factor 1) plus half a period, however late the node was.
    """
    period = node._period
    assert node._real_time_factor == 1.0
    # 0.3 s of ticks overdue (below MAX_LAG, so a late node would catch them all up).
    node._next_due = time.monotonic() - 0.3
    reset_at = time.monotonic()
    response = node._reset_callback(Trigger.Request(), Trigger.Response())
    assert response.success
    node._timer_callback()
    elapsed = time.monotonic() - reset_at
    assert node._simulator.time <= elapsed + 0.5 * period + 1e-12, \
        (node._simulator.time, elapsed)


@pytest.mark.parametrize('scene', ['heavy_top', 'flat_spin', 'thrown_box', 'default'])
def test_the_imu_reads_the_compiled_wrench_and_no_effect_runs_in_python_per_tick(
        scene, monkeypatch):
    """
    The IMU's accelerations come from the simulator's compiled wrench (one call a tick).

    They equal what the effects' readable Python faces give (the held input added), while
    no Python face runs during the ticks.
    """
    node = start_node(scene)
    try:
        if scene == 'default':  # a held input, world- and body-fixed parts
            torque = Vector3Stamped()
            torque.header.frame_id = 'body'
            torque.vector.x, torque.vector.y, torque.vector.z = 0.2, -0.1, 0.3
            node._input_callback('torque', serialize_message(torque))
        node._imu_subscribed = True  # as with a subscriber on imu
        published = []
        monkeypatch.setattr(node._imu_publisher, 'publish', published.append)
        simulator = node._simulator
        readable = simulator.wrench_function()
        faces = []
        for effect in simulator.effects:
            def python_face(*arguments, effect=effect):
                faces.append(effect)
                return type(effect).wrench(effect, *arguments)
            monkeypatch.setattr(effect, 'wrench', python_face)
        for _ in range(3):
            node._tick()
        assert faces == [], f'Python faces ran per tick: {faces}'
        assert len(published) == 3
        readable = simulator.wrench_function()
        force, torque = (np.zeros(3), np.zeros(3)) if readable is None else readable(
            simulator.state, simulator.time)
        expected = node._imu.reading(simulator.state, force, torque)
        message = published[-1]
        for field, values in zip(('orientation', 'angular_velocity', 'linear_acceleration'),
                                 expected):
            vector = getattr(message, field)
            keys = 'xyzw' if field == 'orientation' else 'xyz'
            np.testing.assert_allclose([getattr(vector, key) for key in keys], values,
                                       rtol=1e-12, atol=1e-12)
    finally:
        stop_node(node)


def test_a_parameter_service_answers_empty_and_logs_when_its_callback_fails(monkeypatch):
    """Whatever a request makes a parameter service raise, it answers (and logs one line)."""
    isolate_ros_environment()
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('services', context=context, start_parameter_services=False)
    try:
        node.declare_parameter('x', 1.0)
        ParameterServices(node)
        service = next(s for s in node.services if s.srv_name.endswith('/describe_parameters'))

        def failing(names):
            raise RuntimeError('x' * 10_000)
        monkeypatch.setattr(node, 'describe_parameters', failing)
        logged = []
        monkeypatch.setattr(node, 'get_logger', lambda: type(
            'Logger', (), {'error': staticmethod(logged.append)})())
        response = service.callback(DescribeParameters.Request(names=['x']),
                                    DescribeParameters.Response())
        assert list(response.descriptors) == []
        assert len(logged) == 1 and 'a request failed, answered empty' in logged[0]
        assert len(logged[0]) < 400
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_a_diverged_simulation_stops_the_state_topics_and_reports_error_until_a_reset(
        node, monkeypatch):
    """
    A step whose state turns non-finite stops the simulation at the last finite state.

    The state topics stop (no NaN is published), /diagnostics is ERROR naming the cause
    the simulator gave, one error line is logged, and a reset starts it again.
    """
    from diagnostic_msgs.msg import DiagnosticStatus
    from rigid_body_sim.physics.simulator import DivergedError

    published_states = []
    monkeypatch.setattr(node, '_publish_state', published_states.append)
    diagnostics = []
    monkeypatch.setattr(node._diagnostics_publisher, 'publish', diagnostics.append)
    errors = []

    class Logger:

        def error(self, text):
            errors.append(text)

        def __getattr__(self, name):
            return lambda *args, **kwargs: None

    monkeypatch.setattr(node, 'get_logger', Logger)
    simulator = node._simulator
    node._tick()
    assert len(published_states) == 1
    last_finite = simulator.state
    cause = 'the state turned non-finite between t = 0.01 s and 0.02 s under drag'

    def diverging_step(duration):
        raise DivergedError(cause, simulator.time)

    monkeypatch.setattr(simulator, 'step', diverging_step)
    for _ in range(3):
        node._tick()
    assert len(published_states) == 1, 'state published after the divergence'
    assert len(errors) == 1 and cause in errors[0], errors
    assert np.array_equal(simulator.state.angular_momentum, last_finite.angular_momentum)
    node._publish_diagnostics()
    for array in diagnostics:
        status = array.status[0]
        assert status.level == DiagnosticStatus.ERROR, status
        assert cause in status.message, status.message
    assert len(diagnostics) == 2  # at the divergence, and the periodic report
    monkeypatch.undo()
    monkeypatch.setattr(node, '_publish_state', published_states.append)
    response = node._reset_callback(Trigger.Request(), Trigger.Response())
    assert response.success
    node._tick()
    assert len(published_states) == 2


def test_a_fixed_step_too_long_for_a_stiff_effect_is_refused_as_a_parameter(tmp_path):
    """
    Turning error control off where the fixed step cannot carry a stiff drag is refused.

    The refusal says what to change (it is the scene check's own message); the simulator
    keeps its error control, and a fixed step with enough substeps is accepted.
    """
    scene = tmp_path / 'stiff.yaml'
    scene.write_text('name: stiff\ndescription: a light box under rotational drag\n'
                     'body: {mass: 0.1, shape: box, size: [0.4, 0.2, 0.1]}\n'
                     'initial: {angular_velocity_body: [0.1, 2.0, 0.1]}\n'
                     'effects:\n  - drag: {rotational_linear: 0.5}\n'
                     'integrator: buss\nrate: 100\ntolerance: 1.0e-6\n')
    node = start_node(str(scene))
    try:
        result = node.set_parameters([Parameter('tolerance', value=0.0)])[0]
        assert not result.successful
        assert 'unstable for buss' in result.reason and 'substeps to' in result.reason, \
            result.reason
        assert node._simulator.tolerance == 1e-6
        needed = int(result.reason.rsplit('substeps to ', 1)[1].split()[0].rstrip(','))
        result = node.set_parameters([Parameter('substeps', value=needed),
                                      Parameter('tolerance', value=0.0)])
        assert all(r.successful for r in result), result
        node._tick()
        assert np.isfinite(node._simulator.state.angular_momentum).all()
    finally:
        stop_node(node)

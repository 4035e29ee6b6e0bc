"""
The node's tick schedule, driven in this process: its timer callback called directly.

No executor spins the node here: each test sets the schedule up as a late or busy node
finds it (deadlines on the steady clock in the past) and calls the callbacks the executor
would call, then reads what the simulation did.
"""

import time

from node_harness import isolate_ros_environment
import pytest
import rclpy
from rigid_body_sim.ros.node import RigidBodyNode
from std_srvs.srv import Trigger


@pytest.fixture
def node():
    """Give a node of the default scene (100 Hz), not spun."""
    isolate_ros_environment()
    context = rclpy.Context()
    rclpy.init(context=context)
    node = RigidBodyNode(context=context, start_parameter_services=False)
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=context)


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

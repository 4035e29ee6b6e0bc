"""
The quality of service of every topic of the node, defined in one place.

Reliable, keep-last 10, volatile: a subscriber that keeps up (``ros2 bag record``, a test, a
controller) receives every message, and nobody receives stale state from before it joined.
``/clock`` is the exception: it has the QoS every ROS 2 clock publisher and subscriber uses.
"""

from rclpy.qos import DurabilityPolicy
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy

__all__ = ['STATE_QOS', 'INPUT_QOS', 'DIAGNOSTICS_QOS', 'CLOCK_QOS']

_DEPTH = 10

STATE_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=_DEPTH,
    durability=DurabilityPolicy.VOLATILE)
"""QoS of the state publishers (pose, twist, angular_momentum, odom, marker)."""

INPUT_QOS = STATE_QOS
"""QoS of the torque and wrench subscriptions (matches ``ros2 topic pub``'s default)."""

DIAGNOSTICS_QOS = STATE_QOS
"""QoS of /diagnostics (what diagnostic_aggregator expects)."""

# Best effort, keep last 1: only the newest time matters, and a late one is useless.
CLOCK_QOS = QoSProfile(
    reliability=ReliabilityPolicy.BEST_EFFORT,
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    durability=DurabilityPolicy.VOLATILE)
"""QoS of /clock: rclcpp's ClockQoS, as rosbag2's player and rclpy's TimeSource use it."""

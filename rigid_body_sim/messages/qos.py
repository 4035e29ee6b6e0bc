"""
The quality of service of every topic of the node, defined in one place.

State topics: reliable, keep-last 1000, volatile.  A subscriber that keeps up on average
(``ros2 bag record``, a test, a controller) receives every message, and nobody receives
stale state from before it joined.  The history is a second of ticks at 1 kHz (ten at
100 Hz) because a reliable writer can resend only what its history still holds: Fast DDS
delivers over shared memory through a port queue of 512 samples, under a tenth of a second
of the six topics at 1 kHz, and a subscriber that stalls for longer (a recorder flushing to
a slow disk, a scheduler hiccup on a busy machine) had every later message overwritten in a
keep-last-10 history and lost for good; none with this depth (what each depth loses:
``benchmarks/recording_benchmark.py --stalls``, figures in docs/recording.md).  Keep-last
never blocks the publisher, and the history costs memory only for messages not yet
acknowledged.  The inputs and /diagnostics keep the usual depth of 10, and ``/clock`` has
the QoS every ROS 2 clock publisher and subscriber uses.
"""

from rclpy.qos import DurabilityPolicy
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy

__all__ = ['STATE_QOS', 'INPUT_QOS', 'DIAGNOSTICS_QOS', 'CLOCK_QOS', 'TF_QOS', 'TF_STATIC_QOS',
           'SERVICE_QOS']

_STATE_DEPTH = 1000  # 1 s at 1 kHz: resends cover a subscriber's stall of up to a second
_DEPTH = 10


def _keep_last(depth, reliability=ReliabilityPolicy.RELIABLE,
               durability=DurabilityPolicy.VOLATILE):
    # Every topic of the node keeps the last `depth` samples: none blocks its publisher.
    return QoSProfile(reliability=reliability, history=HistoryPolicy.KEEP_LAST, depth=depth,
                      durability=durability)


STATE_QOS = _keep_last(_STATE_DEPTH)
"""QoS of the state publishers (pose, twist, angular_momentum, odom, marker)."""

INPUT_QOS = _keep_last(_DEPTH)
"""QoS of the torque and wrench subscriptions (matches ``ros2 topic pub``'s default)."""

DIAGNOSTICS_QOS = INPUT_QOS
"""QoS of /diagnostics (what diagnostic_aggregator expects)."""

# Best effort, keep last 1: only the newest time matters, and a late one is useless.
CLOCK_QOS = _keep_last(1, reliability=ReliabilityPolicy.BEST_EFFORT)
"""QoS of /clock: rclcpp's ClockQoS, as rosbag2's player and rclpy's TimeSource use it."""

TF_QOS = _keep_last(100)
"""QoS of /tf: tf2_ros's DynamicBroadcasterQoS."""

TF_STATIC_QOS = _keep_last(1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""QoS of /tf_static: tf2_ros's StaticBroadcasterQoS (a late subscriber gets it too)."""

SERVICE_QOS = _keep_last(1000)
"""QoS of the reset and pause services: a deep queue, so a burst of requests (a client
calling asynchronously in a loop) is answered whole instead of losing all but the last 10
(rclpy's default depth); each request costs microseconds to answer."""

"""
The ``angular_momentum_arrow`` node: the body's angular momentum drawn as a labelled arrow.

RViz has no display for ``geometry_msgs/Vector3Stamped``, the type of the simulator's
``angular_momentum`` topic.  This node turns it into what RViz does draw: a
``visualization_msgs/MarkerArray`` on ``angular_momentum_arrow`` with

- an ARROW from the centre of mass (the latest ``pose``) along L, ``scale`` m long per
  N m s of |L|, in the frame of the ``angular_momentum`` message (the world frame);
- a TEXT_VIEW_FACING label at its tip, ``L = 4 N m s`` (with the scale when it is not 1),
  so that nobody reads the arrow as a force, a torque or a velocity.

RViz's Wrench display could draw L as a "torque" without this node, but only from a
``WrenchStamped`` (a converter node all the same), and it would tell its reader that L is a
torque.  The topic names are relative: started in the simulator's namespace, this node
pairs with that simulator.  The markers go out at most ``max_rate`` Hz of wall-clock time
(the simulator publishes L at every tick, up to 10 kHz; a display needs no more than its
frame rate).  A zero L (a body at rest) deletes the arrow and the label.
"""

import math
import signal
import sys
import threading
import time

from geometry_msgs.msg import Point
from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Vector3Stamped
from visualization_msgs.msg import Marker
from visualization_msgs.msg import MarkerArray

__all__ = ['ARROW_COLOR', 'NODE_NAME', 'arrow_markers', 'label', 'main']

NODE_NAME = 'angular_momentum_arrow'
MARKER_NAMESPACE = 'angular_momentum'
ARROW_COLOR = (0.2, 0.8, 1.0, 1.0)
"""Cyan (r, g, b, a): apart from the body's default orange and from RViz's red odometry."""
# Shorter arrows than this (m) are not drawn: their direction would be noise.
_SHORTEST_ARROW = 1.0e-6
# Longest time (s) the loop waits before it looks for a noted signal.
_STOP_LATENCY = 0.1


def label(magnitude, scale):
    """
    Return the arrow's label: ``L = 4 N m s``, and the drawing scale when it is not 1.

    :param magnitude: |L| in N m s.
    :param scale: the arrow's length in m per N m s.
    """
    text = f'L = {magnitude:.3g} N m s'
    if scale != 1.0:
        text += f' (arrow {scale:g} m per N m s)'
    return text


def arrow_markers(momentum, position, scale):
    """
    Return the MarkerArray that draws an angular momentum as a labelled arrow.

    :param momentum: the ``geometry_msgs/Vector3Stamped`` L about the centre of mass
        (N m s), in the frame its header names; its header becomes the markers'.
    :param position: (x, y, z) of the centre of mass in m, in that same frame.
    :param scale: the arrow's length in m per N m s (> 0).
    :returns: a ``visualization_msgs/MarkerArray`` of the ARROW (id 0) and its
        TEXT_VIEW_FACING label (id 1), both ADD; both DELETE when the arrow would be
        shorter than a micrometre.
    """
    vector = (momentum.vector.x, momentum.vector.y, momentum.vector.z)
    magnitude = math.sqrt(sum(c * c for c in vector))
    length = magnitude * scale
    arrow, text = Marker(), Marker()
    for marker_id, marker in enumerate((arrow, text)):
        marker.header = momentum.header
        marker.ns = MARKER_NAMESPACE
        marker.id = marker_id
        marker.pose.orientation.w = 1.0
    if not math.isfinite(length) or length < _SHORTEST_ARROW:
        arrow.action = text.action = Marker.DELETE
        return MarkerArray(markers=[arrow, text])
    tail = Point(x=float(position[0]), y=float(position[1]), z=float(position[2]))
    tip = Point(x=tail.x + scale * vector[0], y=tail.y + scale * vector[1],
                z=tail.z + scale * vector[2])
    arrow.type = Marker.ARROW
    arrow.points = [tail, tip]
    # For an ARROW given by points: shaft diameter, head diameter, head length (m).
    arrow.scale.x, arrow.scale.y, arrow.scale.z = 0.05 * length, 0.1 * length, 0.2 * length
    text.type = Marker.TEXT_VIEW_FACING
    text.text = label(magnitude, scale)
    # The label just beyond the tip, its letters a tenth of the arrow high.
    beyond = 1.0 + 0.08
    text.pose.position = Point(x=tail.x + beyond * scale * vector[0],
                               y=tail.y + beyond * scale * vector[1],
                               z=tail.z + beyond * scale * vector[2])
    text.scale.z = 0.1 * length
    for marker in (arrow, text):
        marker.action = Marker.ADD
        marker.color.r, marker.color.g, marker.color.b, marker.color.a = ARROW_COLOR
    return MarkerArray(markers=[arrow, text])


def _make_node():
    """Return the rclpy node: the parameters, the two subscriptions and the publisher."""
    from rcl_interfaces.msg import FloatingPointRange
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile

    class AngularMomentumArrow(Node):
        """Republish ``angular_momentum`` as a labelled arrow at the latest ``pose``."""

        def __init__(self):
            super().__init__(NODE_NAME)
            self._scale = self.declare_parameter(
                'scale', 1.0, ParameterDescriptor(
                    description='Arrow length in m per N m s of angular momentum.',
                    floating_point_range=[FloatingPointRange(
                        from_value=1.0e-9, to_value=1.0e9)])).value
            max_rate = self.declare_parameter(
                'max_rate', 30.0, ParameterDescriptor(
                    description='Most markers per second of wall-clock time (Hz).',
                    floating_point_range=[FloatingPointRange(
                        from_value=0.1, to_value=1000.0)])).value
            self._period = 1.0 / max_rate
            self._last_sent = -math.inf
            self._position = None
            qos = QoSProfile(depth=10)
            self._publisher = self.create_publisher(MarkerArray, 'angular_momentum_arrow', qos)
            self.create_subscription(PoseStamped, 'pose', self._on_pose, qos)
            self.create_subscription(Vector3Stamped, 'angular_momentum', self._on_momentum,
                                     qos)

        def _on_pose(self, message):
            position = message.pose.position
            self._position = (position.x, position.y, position.z)

        def _on_momentum(self, message):
            now = time.monotonic()
            if self._position is None or now - self._last_sent < self._period:
                return
            self._last_sent = now
            self._publisher.publish(arrow_markers(message, self._position, self._scale))

    return AngularMomentumArrow()


def main(args=None):
    """Run the node until SIGINT or SIGTERM (Ctrl-C, or the launch stopping); return 0."""
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.signals import SignalHandlerOptions

    stop = threading.Event()

    def note(signum, frame):
        stop.set()

    # The signals only set the flag that the loop below checks: rclpy's handlers stay out
    # (init), and ours go back in front of the executor's own (asio's), which it installs
    # when it is made and would act on late.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    try:
        node = _make_node()
        # The EventsExecutor: the pose and L come at every tick of the simulator (up to
        # 10 kHz), and it costs a fraction of the SingleThreadedExecutor's time per callback.
        executor = EventsExecutor(context=node.context)
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, note)
        executor.add_node(node)
        while node.context.ok() and not stop.is_set():
            executor.spin_once(timeout_sec=_STOP_LATENCY)
    finally:
        if executor is not None:
            executor.remove_node(node)
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""
Measure what publishing costs at 1 kHz with rclpy and Fast DDS, without the simulator.

The node's CPU at 1 kHz (``benchmarks/node_benchmark.py``) is mostly not its own: this
script times a bare 1 kHz loop in one thread, as the node's tick thread runs it, doing
only this each period, over 5 s of CPU time of the whole process (all threads, DDS's too):

- ``idle``: nothing (the cost of waking up 1000 times a second);
- ``unmatched``: publish a serialised Vector3Stamped that no one subscribes to;
- ``reliable`` / ``best_effort``: publish it to one subscriber in another process, with the
  QoS of the node's state topics (reliable, keep-last 1000, volatile) or best effort.

Usage: ``.venv/bin/python benchmarks/dds_publish_cost.py [--seconds S]``.  The subscriber
is this script started again with ``--subscriber``.
"""

import argparse
import os
import subprocess
import sys
import threading
import time

from geometry_msgs.msg import Vector3Stamped
import rclpy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.serialization import serialize_message

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))

from rigid_body_sim.messages.qos import STATE_QOS  # noqa: E402  (after the path set-up)

TOPIC = 'publish_cost'


def _qos(kind):
    if kind == 'best_effort':
        return QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT, history=STATE_QOS.history,
                          depth=STATE_QOS.depth, durability=STATE_QOS.durability)
    return STATE_QOS


def subscriber(kind):
    """Subscribe and spin until killed."""
    rclpy.init()
    node = rclpy.create_node('publish_cost_subscriber')
    node.create_subscription(Vector3Stamped, TOPIC, lambda message: None, _qos(kind))
    try:
        rclpy.spin(node)
    except BaseException:  # noqa: B902 (killed by the measuring process: end quietly)
        pass


def measure(case, seconds):
    """Return the CPU % of one core this process spends on `case` at 1 kHz."""
    node = rclpy.create_node(f'publish_cost_{case}')
    kind = 'best_effort' if case == 'best_effort' else 'reliable'
    publisher = node.create_publisher(Vector3Stamped, TOPIC, _qos(kind))
    reader = None
    if case in ('reliable', 'best_effort'):
        reader = subprocess.Popen([sys.executable, __file__, '--subscriber', kind],
                                  stderr=subprocess.DEVNULL)
        while publisher.get_subscription_count() == 0:
            time.sleep(0.05)
        time.sleep(1.0)
    data = serialize_message(Vector3Stamped())

    def loop(periods):
        deadline = time.monotonic()
        for _ in range(periods):
            deadline += 0.001
            delay = deadline - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            if case != 'idle':
                publisher.publish(data)

    cpu, wall = time.process_time(), time.monotonic()
    thread = threading.Thread(target=loop, args=(int(1000 * seconds),))
    thread.start()
    thread.join()
    percent = 100.0 * (time.process_time() - cpu) / (time.monotonic() - wall)
    if reader is not None:
        reader.terminate()
        reader.wait()
    node.destroy_node()
    return percent


def main(argv=None):
    """Print the CPU of each case; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--seconds', type=float, default=5.0)
    parser.add_argument('--subscriber', choices=('reliable', 'best_effort'),
                        help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if args.subscriber:
        subscriber(args.subscriber)
        return 0
    rclpy.init()
    print(f'1 kHz loop, one Vector3Stamped per period, {args.seconds:g} s each; CPU % of one '
          f'core, all threads of this process; load average {os.getloadavg()[0]:.2f}')
    for case in ('idle', 'unmatched', 'reliable', 'best_effort'):
        print(f'  {case:12s} {measure(case, args.seconds):5.1f} %', flush=True)
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

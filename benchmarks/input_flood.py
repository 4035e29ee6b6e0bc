#!/usr/bin/env python3
"""
Measure the node's tick rate while one peer floods its input topics, side by side.

A node (default scene, 1 kHz unless --rate) runs in a ROS domain of its own on the loopback;
a flooder process publishes /torque and /wrench as fast as it can (pre-serialised messages,
reliable, keep last --depth), cycling through values a hostile or broken peer sends (1e300,
NaN, 5e-324, -inf, a valid torque; frame ids '', world, body, bogus).  The node's own
/diagnostics reports (achieved rate, inputs rejected) are read for --quiet seconds without the
flood, --flood seconds with it, then --quiet again; the node's resident memory (/proc) before
and after, the flooder's messages per second.

The goal (issue 33): at least 90 % of the quiet rate under the flood, memory flat.

Usage: .venv/bin/python benchmarks/input_flood.py [--rate HZ] [--flood S] [--quiet S] [--depth N]
"""

import argparse
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time

FLOODER = r"""
import itertools, sys, time
import rclpy
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rclpy.qos import QoSProfile, HistoryPolicy, ReliabilityPolicy
from rclpy.serialization import serialize_message
# The peer's choice: reliable (the node's inputs are), a deep history.
QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                 depth=int(sys.argv[2]))
rclpy.init()
node = rclpy.create_node('flooder')
torque = node.create_publisher(Vector3Stamped, 'torque', QOS)
wrench = node.create_publisher(WrenchStamped, 'wrench', QOS)
values = [1e300, float('nan'), 5e-324, float('-inf'), 0.01]
frames = ['', 'world', 'body', 'bogus']
deadline = time.monotonic() + float(sys.argv[1])
count = 0
messages = []
for value, frame in itertools.product(values, frames):
    t = Vector3Stamped(); t.header.frame_id = frame; t.vector.z = value
    w = WrenchStamped(); w.header.frame_id = frame; w.wrench.force.x = value
    w.wrench.torque.y = value
    messages.append((serialize_message(t), serialize_message(w)))
started = time.monotonic()
while time.monotonic() < deadline:
    for t, w in messages:
        torque.publish(t)
        wrench.publish(w)
    count += 2 * len(messages)
print(f'{count / (time.monotonic() - started):.0f}')
"""


def _resident_kilobytes(pid):
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    return 0


def _cpu_seconds(pid):
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def main():
    """Print the figures; return 0."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rate', type=float, default=1000.0, help='the node rate, Hz')
    parser.add_argument('--flood', type=float, default=20.0, help='seconds of flood')
    parser.add_argument('--depth', type=int, default=10,
                        help="the flooder's history depth (reliable, keep last)")
    parser.add_argument('--quiet', type=float, default=10.0,
                        help='seconds before and after the flood')
    args = parser.parse_args()
    os.environ.update(ROS_DOMAIN_ID=str(150 + os.getpid() % 80),
                      ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray

    node = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args', '-p',
         f'rate:={args.rate}', '-p', 'scene:=default'],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tempfile.gettempdir())
    rclpy.init()
    probe = rclpy.create_node('flood_benchmark')
    reports = []

    def diagnostics(message):
        for status in message.status:
            values = {item.key: item.value for item in status.values}
            if 'achieved rate [Hz]' in values:
                reports.append((time.monotonic(), float(values['achieved rate [Hz]']),
                                int(values['inputs rejected'])))

    probe.create_subscription(DiagnosticArray, '/diagnostics', diagnostics, 10)

    def listen(seconds):
        start = time.monotonic()
        while time.monotonic() - start < seconds:
            rclpy.spin_once(probe, timeout_sec=0.05)
        return [rate for when, rate, _ in reports if when >= start + 1.0]

    try:
        while not reports:
            rclpy.spin_once(probe, timeout_sec=0.1)
        listen(2.0)  # start-up settles
        memory_before, cpu_before = _resident_kilobytes(node.pid), _cpu_seconds(node.pid)
        quiet = listen(args.quiet)
        flooder = subprocess.Popen([sys.executable, '-c', FLOODER, str(args.flood),
                                    str(args.depth)],
                                   stdout=subprocess.PIPE, text=True)
        rejected_before = reports[-1][2]
        flooded = listen(args.flood)
        sent = float(flooder.communicate(timeout=60)[0] or 0)
        taken = (reports[-1][2] - rejected_before) / args.flood
        after = listen(args.quiet)
        memory_after = _resident_kilobytes(node.pid)
        cpu = _cpu_seconds(node.pid) - cpu_before
    finally:
        node.terminate()
        node.wait(timeout=60)
        probe.destroy_node()
        rclpy.try_shutdown()
    quiet_rate = statistics.median(quiet)
    flood_rate = statistics.median(flooded)
    print(f'load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores; node at '
          f'{args.rate:g} Hz, flooder {sent:.0f} messages/s on /torque and /wrench together')
    print(f'inputs the node refused (every hostile value): {taken:.0f} per second')
    below = sum(rate < 0.9 * quiet_rate for rate in flooded)
    print(f'ticks/s: quiet {quiet_rate:.1f}, under the flood {flood_rate:.1f} (median; lowest '
          f'{min(flooded):.1f}; {below} of {len(flooded)} reports below 90 %), after '
          f'{statistics.median(after):.1f}: {flood_rate / quiet_rate:.3f} of the quiet rate')
    print(f'node memory {memory_before / 1024:.1f} -> {memory_after / 1024:.1f} MB; node CPU '
          f'{cpu / (2 * args.quiet + args.flood):.2f} s per wall second over the run')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

#!/usr/bin/env python3
"""
The node's CPU at 1 kHz against a bare rclpy timer loop beside it, as a ratio (issue 21).

Three processes run side by side in one ROS domain of their own on the loopback:

- the node (default scene, ``rate:=1000.0``), started as ``rigid_body_node`` starts it;
- a bare loop: an rclpy node whose ``create_timer`` at 1 kHz publishes one PoseStamped,
  spun by ``rclpy.experimental.EventsExecutor`` (this script with ``--bare``);
- one subscriber (this script with ``--subscriber``) to the node's ``pose`` and to the bare
  loop's pose: each publisher has one matched subscriber, as in the goal.

After a warm-up the CPU time of the node and of the bare loop (user + system, all
threads, from /proc/<pid>/stat) is read over `--windows` consecutive windows of
`--seconds` s; the ratio node / bare of each window is printed and their median is the
figure.  The goal is a median at most 1.3.

Usage: ``.venv/bin/python benchmarks/node_vs_bare_loop.py [--windows 5] [--seconds 10]
[--source DIR]``; ``--source`` runs the node from another checkout's sources (for a
before/after comparison), with this venv.
"""

import argparse
import os
from pathlib import Path
import signal
import statistics
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
RATE = 1000.0
BARE_TOPIC = '/bare_loop/pose'


def process_cpu_seconds(pid):
    """Return the user + system CPU time of a process (all threads) in s."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def bare_loop():
    """Publish one PoseStamped from a 1 kHz create_timer under the EventsExecutor."""
    from geometry_msgs.msg import PoseStamped
    import rclpy
    from rclpy.experimental import EventsExecutor

    sys.path.insert(0, str(ROOT))
    from rigid_body_sim.messages.qos import STATE_QOS

    rclpy.init()
    node = rclpy.create_node('bare_loop')
    publisher = node.create_publisher(PoseStamped, BARE_TOPIC, STATE_QOS)
    message = PoseStamped()
    message.header.frame_id = 'world'
    clock = node.get_clock()

    def tick():
        message.header.stamp = clock.now().to_msg()
        message.pose.position.x += 1e-3
        publisher.publish(message)

    node.create_timer(1.0 / RATE, tick)
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass


def subscriber(namespace):
    """Subscribe to the node's pose and to the bare loop's; count them."""
    from geometry_msgs.msg import PoseStamped
    import rclpy
    from rclpy.experimental import EventsExecutor

    sys.path.insert(0, str(ROOT))
    from rigid_body_sim.messages.qos import STATE_QOS

    rclpy.init()
    node = rclpy.create_node('bare_loop_subscriber')
    for topic in (f'{namespace}/pose', BARE_TOPIC):
        node.create_subscription(PoseStamped, topic, lambda message: None, STATE_QOS)
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass


def main(argv=None):
    """Run the three processes side by side and print the CPU ratio per window."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--windows', type=int, default=5)
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--warmup', type=float, default=10.0)
    parser.add_argument('--source', type=Path, default=ROOT,
                        help='checkout whose rigid_body_sim runs as the node')
    parser.add_argument('--bare', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--subscriber', help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    if arguments.bare:
        return bare_loop()
    if arguments.subscriber is not None:
        return subscriber(arguments.subscriber)

    environment = dict(os.environ)
    environment['ROS_DOMAIN_ID'] = str(150 + os.getpid() % 80)
    environment['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    node_environment = dict(environment, PYTHONPATH=str(arguments.source.resolve()))
    namespace = '/vs_bare'
    script = str(Path(__file__).resolve())
    logs = ROOT / 'build' / 'node_vs_bare_loop'
    logs.mkdir(parents=True, exist_ok=True)
    processes = {
        'node': subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args',
             '-r', f'__ns:={namespace}', '-p', f'rate:={RATE}'],
            env=node_environment, cwd=arguments.source,
            stdout=open(logs / 'node.log', 'w'), stderr=subprocess.STDOUT),
        'bare': subprocess.Popen([sys.executable, script, '--bare'], env=environment,
                                 stdout=open(logs / 'bare.log', 'w'),
                                 stderr=subprocess.STDOUT),
        'subscriber': subprocess.Popen([sys.executable, script, '--subscriber', namespace],
                                       env=environment, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL),
    }
    try:
        time.sleep(arguments.warmup)  # start-up, discovery, kernels loaded
        for name, process in processes.items():
            if process.poll() is not None:
                raise SystemExit(f'{name} exited with {process.returncode}; see {logs}')
        ratios = []
        print(f'node from {arguments.source.resolve()}; 1 kHz, one pose subscriber each')
        print('window  node CPU %  bare loop CPU %  ratio')
        for window in range(arguments.windows):
            before = {name: process_cpu_seconds(processes[name].pid)
                      for name in ('node', 'bare')}
            started = time.monotonic()
            time.sleep(arguments.seconds)
            elapsed = time.monotonic() - started
            used = {name: process_cpu_seconds(processes[name].pid) - before[name]
                    for name in ('node', 'bare')}
            ratio = used['node'] / used['bare']
            ratios.append(ratio)
            print(f'{window + 1:6d}  {100 * used["node"] / elapsed:10.1f}  '
                  f'{100 * used["bare"] / elapsed:15.1f}  {ratio:5.2f}')
        median = statistics.median(ratios)
        verdict = 'holds' if median <= 1.3 else 'fails'
        print(f'median ratio node / bare loop: {median:.2f} (goal <= 1.3: {verdict}); '
              f'load average {os.getloadavg()[0]:.1f}')
    finally:
        for process in processes.values():
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        for process in processes.values():
            try:
                process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                process.kill()


if __name__ == '__main__':
    sys.exit(main())

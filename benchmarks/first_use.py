#!/usr/bin/env python3
"""
Measure what a user waits for on first use: the node's first pose, simulate, a colcon build.

Every figure is a wall-clock time of this run (printed with the load average), measured from
the moment the command is started; the node runs in a ROS domain of its own on the loopback.

- the node (``rigid_body_node``, default scene, 100 Hz): its start to its parameter
  services answering, to its first /pose, and to the first /diagnostics report that says
  its kernels are compiled (``kernels: compiled``: before that it integrates with the
  kernels' source interpreted while a compile runs beside it);
- ``simulate --scene default --duration 5``, twice: the first includes compiling what it
  needs when the machine never did (in a process of its own, in parallel), the second not;
- ``--colcon``: a colcon build of the checkout into a temporary workspace (the ROS user's
  way), then the node of that install, started as ``ros2 run`` starts it.

``--cold`` gives every step a kernel cache that is empty (a temporary
RIGID_BODY_SIM_CACHE_DIR): a machine that never compiled them.  Without it, the machine's
cache (``rigid-body-sim compile --where``).

Usage: .venv/bin/python benchmarks/first_use.py [--cold] [--colcon] [--rate HZ]
"""

import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
TIMEOUT = 600.0


def _simulate_twice(environment):
    with tempfile.TemporaryDirectory() as directory:
        for run in ('first', 'second'):
            started = time.monotonic()
            result = subprocess.run(
                [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 'default',
                 '--duration', '5', '--quiet', '--bag', str(Path(directory) / run)],
                capture_output=True, text=True, env=environment, check=False, cwd=ROOT,
                timeout=TIMEOUT)
            if result.returncode != 0:
                raise SystemExit(f'simulate failed: {result.stderr.strip()}')
            said = result.stderr.strip().splitlines()
            print(f'simulate --duration 5, {run} run: {time.monotonic() - started:.2f} s'
                  + (f' (it said: {said[0]})' if said else ''))


def _node_timeline(command, environment, label):
    """Start the node with `command`; print when it answers, publishes, runs compiled."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped
    from rcl_interfaces.srv import GetParameters

    rclpy.init()
    probe = rclpy.create_node('first_use_benchmark')
    events = {}
    started = time.monotonic()

    def note(event):
        events.setdefault(event, time.monotonic() - started)

    def diagnostics(message):
        for status in message.status:
            values = {item.key: item.value for item in status.values}
            if values.get('kernels'):
                note(f'kernels: {values["kernels"]}')

    probe.create_subscription(PoseStamped, '/pose', lambda message: note('first /pose'), 10)
    probe.create_subscription(DiagnosticArray, '/diagnostics', diagnostics, 10)
    client = probe.create_client(GetParameters, '/rigid_body_sim/get_parameters')
    node = subprocess.Popen(command, env=environment, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, cwd=tempfile.gettempdir())
    try:
        while time.monotonic() - started < TIMEOUT and 'kernels: compiled' not in events:
            if client.service_is_ready():
                note('parameter services')
            rclpy.spin_once(probe, timeout_sec=0.02)
            if node.poll() is not None:
                raise SystemExit(f'the node ended (exit {node.returncode})')
    finally:
        node.terminate()
        node.wait(timeout=60)
        probe.destroy_node()
        rclpy.try_shutdown()
    print(f'{label}:')
    for event, seconds in sorted(events.items(), key=lambda item: item[1]):
        print(f'  {event:22s} {seconds:7.2f} s after its start')


def _colcon_build(workspace, environment):
    source = workspace / 'src' / 'rigid_body_sim'
    files = subprocess.run(['git', 'ls-files', '-z'], cwd=ROOT, check=True,
                           capture_output=True).stdout.decode().split('\0')
    for name in filter(None, files):
        target = source / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target)
    colcon = Path(sys.executable).parent / 'colcon'
    started = time.monotonic()
    subprocess.run([str(colcon), 'build', '--base-paths', 'src'], cwd=workspace,
                   env={**environment, 'COLCON_HOME': str(workspace / 'colcon_home')},
                   check=True, capture_output=True, timeout=TIMEOUT)
    print(f'colcon build: {time.monotonic() - started:.2f} s')
    return workspace / 'install'


def main():
    """Print the figures; return 0."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--cold', action='store_true',
                        help='an empty kernel cache (a machine that never compiled them)')
    parser.add_argument('--colcon', action='store_true',
                        help='build a colcon workspace and time its node too')
    parser.add_argument('--rate', type=float, default=100.0, help='the node rate, Hz')
    args = parser.parse_args()
    os.environ.update(ROS_DOMAIN_ID=str(150 + os.getpid() % 80),
                      ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    print(f'load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores')
    with tempfile.TemporaryDirectory() as scratch:
        scratch = Path(scratch)

        def environment():
            # Each step of a cold run on a machine that never compiled: a new empty cache.
            if not args.cold:
                return dict(os.environ)
            cache = Path(tempfile.mkdtemp(dir=scratch, prefix='cache-'))
            return {**os.environ, 'RIGID_BODY_SIM_CACHE_DIR': str(cache)}

        node = [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args', '-p',
                f'rate:={args.rate}']
        _node_timeline(node, environment(), 'node (this checkout)')
        _simulate_twice(environment())
        if args.colcon:
            install = _colcon_build(scratch / 'workspace', environment())
            executable = install / 'rigid_body_sim' / 'lib' / 'rigid_body_sim' / 'rigid_body_node'
            command = ['bash', '-c', f'source "{install}/setup.bash" && exec "{executable}" '
                       f'--ros-args -p rate:={args.rate}']
            _node_timeline(command, environment(), 'node (colcon install, as ros2 run)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

#!/usr/bin/env python3
"""
Measure what a user waits for on first use: the node's start, each integrator switch, simulate.

Run it right after the set-up (``make venv``, which compiles the kernels) on a fresh clone:

- ``simulate``: the wall time and the CPU time (user + system, of the child process) of two
  identical runs in a row (``--scene default --duration 5``); the first must cost no more
  than the second (nothing is left to compile).  A first run's wall time can exceed its CPU
  time by what the OS reads from disk that the second finds in its page cache (the
  libraries, ~1 s after ``echo 3 > /proc/sys/vm/drop_caches``): the CPU times tell the two
  apart;
- the node: the wall time from its start to its parameter services answering, and for each
  integrator the time from a ``set_parameters`` request to its reply, and to the first
  /diagnostics report that names the new integrator (the switch has then happened).

Every figure is a wall-clock time of this run, printed with the load average; the node runs
in a ROS domain of its own on the loopback.  ``--cold`` empties the compiled-kernel markers
first: the node and simulate then say what they compile (the first-use announcements), and
the switches show how a node without compiled kernels keeps answering.

Usage: .venv/bin/python benchmarks/first_use.py [--cold] [--rate HZ]
"""

import argparse
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent


def _simulate_twice(environment):
    times = []
    with tempfile.TemporaryDirectory() as directory:
        for run in range(2):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            started = time.monotonic()
            result = subprocess.run(
                [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 'default',
                 '--duration', '5', '--quiet', '--bag', str(Path(directory) / f'bag{run}')],
                capture_output=True, text=True, env=environment, check=False, timeout=900)
            wall = time.monotonic() - started
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            times.append((wall, cpu))
            if result.returncode != 0:
                raise SystemExit(f'simulate failed: {result.stderr.strip()}')
            if result.stderr.strip():
                print(f'  simulate said: {result.stderr.strip()}')
    return times


def _node_switches(environment, rate):
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.msg import Parameter
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.msg import ParameterValue
    from rcl_interfaces.srv import SetParameters
    from rigid_body_sim.physics import INTEGRATORS

    started = time.monotonic()
    node_process = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.ros.entry_point', '--ros-args', '-p',
         f'rate:={rate}'], env=environment, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL)
    rclpy.init()
    client_node = rclpy.create_node('first_use_benchmark')
    reports = []
    client_node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda message: reports.append((time.monotonic(), message)), 10)
    client = client_node.create_client(SetParameters, '/rigid_body_sim/set_parameters')
    try:
        while not client.wait_for_service(timeout_sec=0.05):
            if time.monotonic() - started > 300:
                raise SystemExit('the node offered no parameter service within 300 s')
        print(f'node: parameter services answer {time.monotonic() - started:.2f} s after '
              'its start')
        for name in sorted(INTEGRATORS, key=lambda n: n != 'rk4'):
            request = SetParameters.Request()
            request.parameters = [Parameter(name='integrator', value=ParameterValue(
                type=ParameterType.PARAMETER_STRING, string_value=name))]
            asked = time.monotonic()
            future = client.call_async(request)
            rclpy.spin_until_future_complete(client_node, future, timeout_sec=300)
            replied = time.monotonic() - asked
            del reports[:]
            switched = None
            while time.monotonic() - asked < 300 and switched is None:
                rclpy.spin_once(client_node, timeout_sec=0.05)
                for when, message in reports:
                    for status in message.status:
                        values = {item.key: item.value for item in status.values}
                        if values.get('integrator') == name:
                            switched = when - asked
            shown = f'{switched:.3f} s' if switched is not None else 'not within 300 s'
            print(f'  switch to {name:12s} reply {replied:.3f} s, in /diagnostics {shown}')
    finally:
        client_node.destroy_node()
        rclpy.try_shutdown()
        node_process.terminate()
        node_process.wait(timeout=60)


def main():
    """Print the figures; return 0."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--cold', action='store_true',
                        help='forget which kernels are compiled first (they compile again)')
    parser.add_argument('--rate', type=float, default=100.0, help='the node rate, Hz')
    args = parser.parse_args()
    # The node and this process's client in a domain of their own, on the loopback.
    os.environ.update(ROS_DOMAIN_ID=str(150 + os.getpid() % 80),
                      ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    environment = dict(os.environ)
    if args.cold:
        from rigid_body_sim.physics import kernels
        for path in kernels.cached_kernel_files():
            path.unlink()
    print(f'load average {os.getloadavg()[0]:.1f}')
    (first, first_cpu), (second, second_cpu) = _simulate_twice(environment)
    print(f'simulate --duration 5: first run {first:.2f} s ({first_cpu:.2f} s CPU), second '
          f'{second:.2f} s ({second_cpu:.2f} s CPU): {first / second:.2f}x wall, '
          f'{first_cpu / second_cpu:.2f}x CPU')
    _node_switches(environment, args.rate)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

#!/usr/bin/env python3
"""
Measure the rigid_body_sim node: achieved rate, CPU, tick duration, input latency.

For each rate (default 100 Hz and 1 kHz) the node runs as a subprocess with the default
body, in a ROS domain of its own on the loopback, while this script subscribes to
``angular_momentum`` and ``/diagnostics`` and measures, after a warm-up:

- achieved rate: angular_momentum messages received per second (the node's own count,
  from /diagnostics, is printed beside it);
- CPU of the node process, all threads (DDS included), from /proc/<pid>/stat: 100% is
  one core;
- tick duration p50 and p99, as the node reports them in /diagnostics (median over the
  window's reports);
- latency from publishing a torque to the first angular_momentum message that shows it:
  to its stamp (when the node published it) and to its arrival here.  Each trial applies
  a torque, waits for its effect, then removes it (input_timeout 0 holds inputs until
  replaced) and waits until L is steady again.

With ``--unsubscribed`` it also runs the node alone (no subscriber: nothing is serialised
or published) and reports its CPU: the node's own cost, without DDS delivery.

Usage: ``.venv/bin/python benchmarks/node_benchmark.py [--rates 100 1000] [--duration 10]
[--unsubscribed]``
"""

import argparse
import bisect
import os
from pathlib import Path
import random
import statistics
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
import rclpy
from rclpy.executors import SingleThreadedExecutor

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rigid_body_sim.messages.qos import STATE_QOS  # noqa: E402  (after the path set-up)

NODE_NAME = 'rigid_body_sim'


def process_cpu_seconds(pid):
    """Return the user + system CPU time of a process (all threads) in s."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    # After the command name: state is field 3; utime and stime are fields 14 and 15.
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


class Probe:
    """A client node recording angular_momentum and our node's diagnostics."""

    def __init__(self, namespace):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('benchmark_probe', namespace=namespace,
                                      context=self.context)
        self.hardware_id = f'{namespace}/{NODE_NAME}'
        self.lock = threading.Lock()
        # Arrival times (monotonic s, ascending) and (arrival, stamp s, (Lx, Ly, Lz)).
        self.arrivals = []
        self.momenta = []
        self.diagnostics = []  # (arrival monotonic s, {key: value})
        self.node.create_subscription(Vector3Stamped, 'angular_momentum', self._momentum,
                                      STATE_QOS)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._diagnostics,
                                      STATE_QOS)
        self.torque = self.node.create_publisher(Vector3Stamped, 'torque', STATE_QOS)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stopping = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        # spin_once in a loop, not spin(): close() stops the loop and joins this thread
        # before anything is destroyed, so no wait set is ever built on a dead context.
        while not self._stopping.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def _momentum(self, message):
        arrival = time.monotonic()
        stamp = message.header.stamp.sec + 1e-9 * message.header.stamp.nanosec
        vector = (message.vector.x, message.vector.y, message.vector.z)
        with self.lock:
            self.arrivals.append(arrival)
            self.momenta.append((arrival, stamp, vector))

    def _diagnostics(self, message):
        for status in message.status:
            if status.hardware_id == self.hardware_id:
                values = {kv.key: kv.value for kv in status.values}
                with self.lock:
                    self.diagnostics.append((time.monotonic(), values))

    def momenta_since(self, since):
        """Return the recorded angular momenta that arrived after `since`."""
        with self.lock:
            return self.momenta[bisect.bisect_right(self.arrivals, since):]

    def latest_momentum(self):
        """Return the latest angular momentum received (a tuple)."""
        with self.lock:
            return self.momenta[-1][2]

    def publish_torque(self, torque):
        """Publish a world-frame torque (N m)."""
        message = Vector3Stamped()
        message.header.frame_id = 'world'
        message.vector.x, message.vector.y, message.vector.z = torque
        self.torque.publish(message)

    def close(self):
        """Stop spinning and release the context."""
        self._stopping.set()
        self.thread.join(5.0)
        self.executor.shutdown(timeout_sec=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def wait_for(condition, timeout):
    """Poll condition() every ms until true; return whether it became true in time."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.001)
    return True


def measure_latency(probe, rate, trials):
    """Return [(to stamp s, to arrival s)] of torque -> first changed L, `trials` times."""
    latencies = []
    torque = (0.0, 0.0, 0.05)
    for _ in range(trials):
        # Let L settle (no input) and pick a random phase relative to the ticks.
        time.sleep(random.uniform(5.0, 10.0) / rate)
        baseline = probe.latest_momentum()
        sent_wall = time.time()
        sent = time.monotonic()
        probe.publish_torque(torque)

        def changed():
            return any(m[2] != baseline for m in probe.momenta_since(sent))

        if not wait_for(changed, 2.0):
            raise RuntimeError('the torque did not reach the angular momentum within 2 s')
        first = next(m for m in probe.momenta_since(sent) if m[2] != baseline)
        latencies.append((first[1] - sent_wall, first[0] - sent))
        probe.publish_torque((0.0, 0.0, 0.0))
        removed = time.monotonic()

        def steady():
            recent = probe.momenta_since(removed + 3.0 / rate)
            return len(recent) >= 2 and recent[-1][2] == recent[-2][2]

        if not wait_for(steady, 2.0):
            raise RuntimeError('the angular momentum did not settle after the torque')
    return latencies


def run_rate(rate, duration, warmup, trials, log_dir):
    """Run the node at `rate` Hz and return its figures (dict)."""
    namespace = f'/bench_{os.getpid()}_{int(rate)}'
    log_path = log_dir / f'node_{int(rate)}hz.log'
    with open(log_path, 'w') as log:
        node = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args',
             '-r', f'__ns:={namespace}', '-p', f'rate:={float(rate)}',
             '-p', 'input_timeout:=0.0', '-p', 'integrator:=buss'],
            stdout=log, stderr=subprocess.STDOUT, cwd=ROOT)
    probe = Probe(namespace)
    try:
        if not wait_for(lambda: probe.momenta and probe.torque.get_subscription_count(), 30.0):
            raise RuntimeError(f'the node did not connect; see {log_path}')
        time.sleep(warmup)
        start = time.monotonic()
        cpu_start = process_cpu_seconds(node.pid)
        time.sleep(duration)
        end = time.monotonic()
        cpu = (process_cpu_seconds(node.pid) - cpu_start) / (end - start)
        received = [m for m in probe.momenta_since(start) if m[0] <= end]
        with probe.lock:
            reports = [values for arrival, values in probe.diagnostics
                       if start < arrival <= end]
        latencies = measure_latency(probe, rate, trials)
    finally:
        probe.close()
        node.send_signal(2)
        node.wait(15.0)

    def median_of(key):
        return statistics.median(float(r[key]) for r in reports) if reports else float('nan')

    return {
        'rate': rate,
        'achieved': (len(received) - 1) / (received[-1][0] - received[0][0]),
        'node_achieved': median_of('achieved rate [Hz]'),
        'cpu': 100.0 * cpu,
        'tick_p50': median_of('tick duration p50 [ms]'),
        'tick_p99': median_of('tick duration p99 [ms]'),
        'latency_stamp': [1e3 * s for s, _ in latencies],
        'latency_arrival': [1e3 * a for _, a in latencies],
    }


def unsubscribed_cpu(rate, duration, warmup, log_dir):
    """Return the node's CPU (% of one core) at `rate` Hz with no subscriber at all."""
    log_path = log_dir / f'node_{int(rate)}hz_unsubscribed.log'
    with open(log_path, 'w') as log:
        node = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args',
             '-r', f'__ns:=/bench_{os.getpid()}_alone', '-p', f'rate:={float(rate)}',
             '-p', 'integrator:=buss'], stdout=log, stderr=subprocess.STDOUT, cwd=ROOT)
    try:
        # Start-up (imports, kernels) takes a few seconds of CPU: wait for the first tick.
        if not wait_for(lambda: 'simulating scene' in log_path.read_text(), 60.0):
            raise RuntimeError(f'the node did not start; see {log_path}')
        time.sleep(warmup)
        start, cpu_start = time.monotonic(), process_cpu_seconds(node.pid)
        time.sleep(duration)
        return 100.0 * (process_cpu_seconds(node.pid) - cpu_start) / (time.monotonic() - start)
    finally:
        node.send_signal(2)
        node.wait(15.0)


def main(argv=None):
    """Measure each rate and print a table; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--rates', type=float, nargs='+', default=[100.0, 1000.0])
    parser.add_argument('--duration', type=float, default=10.0,
                        help='measurement window per rate in s (default 10)')
    parser.add_argument('--warmup', type=float, default=2.0, help='s before measuring')
    parser.add_argument('--trials', type=int, default=20, help='latency trials per rate')
    parser.add_argument('--log-dir', type=Path, default=Path('/tmp'),
                        help='where the node logs go (default /tmp)')
    parser.add_argument('--unsubscribed', action='store_true',
                        help="also measure the node's CPU with no subscriber (nothing is "
                             'published: its own cost, without DDS delivery)')
    args = parser.parse_args(argv)
    # The probe's executor thread takes every angular_momentum message (1000/s at 1 kHz);
    # without a short GIL switch interval (default 5 ms) the main thread would wait that
    # long to publish a torque, and the measured latency would be the probe's.
    sys.setswitchinterval(1e-4)
    os.environ['ROS_DOMAIN_ID'] = str(101 + os.getpid() % 100)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    print(f'node benchmark: default body, buss, 1 substep; {args.duration:g} s per rate; '
          f'{os.cpu_count()} CPUs; CPU% of one core, all node threads')
    header = (f'{"rate":>7} {"achieved":>9} {"(node)":>8} {"CPU %":>6} {"tick p50":>9} '
              f'{"tick p99":>9} {"latency p50/max to stamp":>25} {"to arrival p50/max":>19}')
    print(header)
    print(f'{"[Hz]":>7} {"[Hz]":>9} {"[Hz]":>8} {"":>6} {"[ms]":>9} {"[ms]":>9} '
          f'{"[ms]":>25} {"[ms]":>19}')
    for rate in args.rates:
        r = run_rate(rate, args.duration, args.warmup, args.trials, args.log_dir)
        stamp = f'{statistics.median(r["latency_stamp"]):.2f} / {max(r["latency_stamp"]):.2f}'
        arrival = (f'{statistics.median(r["latency_arrival"]):.2f} / '
                   f'{max(r["latency_arrival"]):.2f}')
        print(f'{rate:7g} {r["achieved"]:9.1f} {r["node_achieved"]:8.1f} {r["cpu"]:6.1f} '
              f'{r["tick_p50"]:9.3f} {r["tick_p99"]:9.3f} {stamp:>25} {arrival:>19}',
              flush=True)
    print('one tick is 1/rate: 10 ms at 100 Hz, 1 ms at 1 kHz')
    if args.unsubscribed:
        for rate in args.rates:
            cpu = unsubscribed_cpu(rate, args.duration, args.warmup, args.log_dir)
            print(f'{rate:7g} Hz with no subscriber (nothing published): CPU {cpu:.1f}%',
                  flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""
Measure `rigid-body-sim watch` while a peer sends megabyte /diagnostics reports in the node's name.

A node (default scene) runs in a ROS domain of its own on the loopback; `rigid-body-sim
watch --terminal` watches it (its output read and counted); once it shows the node running,
a peer publishes /diagnostics arrays of --megabytes MB (one status whose hardware_id is the
node's, one value that large) --rate times a second for --seconds s.  Printed: watch's
resident memory (/proc) before, at its highest and at the end, the characters it printed,
whether its view still advanced during the flood, and how long after SIGINT (Ctrl-C, sent at
the end of the flood) it said it stopped and its process ended.  With --window, watch draws
its window on an Xvfb display of its own (the view is then not followed).

The goal (issue 33): memory at most +50 MB over 60 s of 5 MB reports, Ctrl-C answered
within 1 s.

Usage: .venv/bin/python benchmarks/watch_large_reports.py [--megabytes MB] [--seconds S]
"""

import argparse
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

PEER = r"""
import sys, time
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message
rclpy.init()
node = rclpy.create_node('large_reports')
publisher = node.create_publisher(DiagnosticArray, '/diagnostics', 10)
value = 'x' * int(float(sys.argv[1]) * 1e6)
status = DiagnosticStatus(name='rigid_body_sim: simulation', hardware_id='/rigid_body_sim',
                          message='running ' + value[:10],
                          values=[KeyValue(key='scene', value=value)])
data = serialize_message(DiagnosticArray(status=[status]))
deadline = time.monotonic() + float(sys.argv[2])
sent = 0
while time.monotonic() < deadline:
    publisher.publish(data)
    sent += 1
    time.sleep(1.0 / float(sys.argv[3]))
print(sent)
"""


def _start_xvfb():
    read, write = os.pipe()
    process = subprocess.Popen([shutil.which('Xvfb'), '-displayfd', str(write), '-screen', '0',
                                '1400x900x24', '-nolisten', 'tcp', '-s', '0'],
                               pass_fds=(write,), stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as pipe:
        return process, f':{pipe.readline().strip()}'


def _resident_megabytes(pid):
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return 0.0


def main():
    """Print the figures; return 0."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--megabytes', type=float, default=5.0, help='MB per report')
    parser.add_argument('--seconds', type=float, default=60.0, help='seconds of reports')
    parser.add_argument('--rate', type=float, default=2.0, help='reports per second')
    parser.add_argument('--window', action='store_true',
                        help='watch with its window, on an Xvfb display of its own')
    parser.add_argument('--ctrl-c-wait', type=float, default=60.0,
                        help='seconds to wait for watch to end after Ctrl-C before killing it')
    args = parser.parse_args()
    environment = dict(os.environ, ROS_DOMAIN_ID=str(150 + os.getpid() % 80),
                       ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    node = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.node.entry_point'],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tempfile.gettempdir(),
        env=environment)
    xvfb = None
    view = ['--terminal', '--interval', '0.2']
    if args.window:
        xvfb, display = _start_xvfb()
        environment['DISPLAY'] = display
        view = []
    watch = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.cli', 'watch', *view],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=environment)
    printed = [0]
    times = []
    stopped = []

    def read():
        for line in watch.stdout:
            printed[0] += len(line)
            if (line.startswith(b'  time ') and b'simulated' in line) or (
                    b'window shows' in line):
                times.append((time.monotonic(), line[:60].decode(errors='replace').strip()))

    def read_errors():
        for line in watch.stderr:
            if b'stopped (SIGINT)' in line:
                stopped.append(time.monotonic())
    readers = [threading.Thread(target=read, daemon=True),
               threading.Thread(target=read_errors, daemon=True)]
    for reader in readers:
        reader.start()
    peer = None
    try:
        while not times:
            if watch.poll() is not None:
                raise SystemExit('watch ended before it showed the node')
            time.sleep(0.1)
        before = _resident_megabytes(watch.pid)
        printed_before = printed[0]
        peer = subprocess.Popen([sys.executable, '-c', PEER, str(args.megabytes),
                                 str(args.seconds), str(args.rate)],
                                stdout=subprocess.PIPE, text=True, env=environment)
        started = time.monotonic()
        highest = before
        while peer.poll() is None:
            highest = max(highest, _resident_megabytes(watch.pid))
            time.sleep(0.5)
        sent = peer.stdout.read().strip()
        end = _resident_megabytes(watch.pid)
        advancing = [text for when, text in times if when > started]
        signalled = time.monotonic()
        watch.send_signal(signal.SIGINT)
        try:
            watch.wait(args.ctrl_c_wait)
            latency = f'{time.monotonic() - signalled:.2f} s'
        except subprocess.TimeoutExpired:
            watch.kill()
            latency = f'more than {args.ctrl_c_wait:g} s (killed)'
        readers[1].join(5.0)
        answered = f'{stopped[0] - signalled:.2f} s' if stopped else 'never said'
    finally:
        for process in (peer, watch, node, xvfb):
            if process is not None and process.poll() is None:
                process.terminate()
                process.wait(30)
    print(f'load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores; a peer sent '
          f'{sent} reports of {args.megabytes:g} MB in {args.seconds:g} s, claiming the node')
    print(f'watch memory: {before:.1f} MB before, {highest:.1f} MB at most, {end:.1f} MB at '
          f'the end: +{highest - before:.1f} MB at most')
    print(f'watch printed {printed[0] - printed_before} characters during the reports; its '
          f'view advanced {len(advancing)} times (last: {advancing[-1] if advancing else "-"})')
    print(f'Ctrl-C: watch said it stopped after {answered}, its process ended after {latency}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

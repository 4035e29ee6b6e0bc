#!/usr/bin/env python3
"""
Measure the CPU of `rigid-body-sim watch`'s window against the node's, side by side.

A node (default scene, its default rate unless --rate) runs in a ROS domain of its own on the
loopback; `rigid-body-sim watch` opens its window on an Xvfb display of its own and watches it.
Once the window says it shows the node, both processes' CPU time (user + system, /proc) is
read over --seconds s, as a share of one core each, with the load average of the machine,
and watch's own count of its redraws and their CPU (it slows its refresh when the machine
is busy: the load average says how much).

The goal (issue 32): the window at most 25 % of a core at its default refresh: measure it
with --args --refresh 0.2 (kept whatever the load); without, the window lengthens its
refresh on a busy machine, and the figure is what it takes there.

Usage: .venv/bin/python benchmarks/watch_window_cpu.py [--rate HZ] [--seconds S] [--args ...]
"""

import argparse
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import time


def _cpu_seconds(pid):
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _start_xvfb():
    read, write = os.pipe()
    process = subprocess.Popen([shutil.which('Xvfb'), '-displayfd', str(write), '-screen', '0',
                                '1400x900x24', '-nolisten', 'tcp', '-s', '0'],
                               pass_fds=(write,), stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as pipe:
        return process, f':{pipe.readline().strip()}'


def main():
    """Print the figures; return 0."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rate', type=float, help="the node's rate, Hz (default: the scene's)")
    parser.add_argument('--seconds', type=float, default=30.0, help='seconds measured')
    parser.add_argument('--args', nargs=argparse.REMAINDER, default=[],
                        help='more arguments of rigid-body-sim watch')
    args = parser.parse_args()
    environment = dict(os.environ, ROS_DOMAIN_ID=str(150 + os.getpid() % 80),
                       ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    xvfb, display = _start_xvfb()
    rate = [] if args.rate is None else ['-p', f'rate:={args.rate}']
    node = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args', *rate],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tempfile.gettempdir(),
        env=environment)
    watch = subprocess.Popen([sys.executable, '-m', 'rigid_body_sim.cli', 'watch', *args.args],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(environment, DISPLAY=display))
    try:
        for line in watch.stdout:
            if 'window shows' in line:
                break
        else:
            raise SystemExit('watch ended before its window showed the node')
        load = os.getloadavg()[0]
        start = time.monotonic()
        node_before, watch_before = _cpu_seconds(node.pid), _cpu_seconds(watch.pid)
        time.sleep(args.seconds)
        elapsed = time.monotonic() - start
        node_share = (_cpu_seconds(node.pid) - node_before) / elapsed
        watch_share = (_cpu_seconds(watch.pid) - watch_before) / elapsed
    finally:
        watch.send_signal(signal.SIGINT)
        for process in (watch, node):
            process.terminate()
            try:
                process.wait(30)
            except subprocess.TimeoutExpired:
                process.kill()
        xvfb.terminate()
        xvfb.wait(10)
    redraws = [line for line in watch.stderr.read().splitlines() if 'redraws in' in line]
    print(f'load average {load:.1f} at the start, {os.cpu_count()} cores; {args.seconds:g} s')
    print(f'watch window: {100 * watch_share:.1f} % of a core; node: {100 * node_share:.1f} % '
          f'of a core; window / node {watch_share / max(node_share, 1e-9):.1f}')
    print(redraws[-1] if redraws else 'watch did not say how often it redrew')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

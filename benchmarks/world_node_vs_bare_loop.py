#!/usr/bin/env python3
"""
The node of 100 bodies at 100 Hz against a bare rclpy loop beside it; the 1,000-body memory.

CPU (issue 29, item 3; modelled on benchmarks/node_vs_bare_loop.py).  Three processes run
side by side in one ROS domain (``$ROS_DOMAIN_ID``, else one of this script's own) on the
loopback:

- the node with ``scene:=debris_field`` (100 bodies, its rate 100 Hz), started as
  ``rigid_body_node`` starts it;
- a bare loop (this script with ``--bare``): an rclpy node whose 100 Hz timer publishes the
  same messages: for each of the 100 bodies a PoseStamped on its own topic (with
  ``--topics``, the other per-body topics too), one TFMessage of 100 transforms and one
  MarkerArray of 100 markers, each filled as rclpy messages (a field changed a tick), and
  /diagnostics at 1 Hz; spun exactly as the node is (a context without rclpy's signal
  handlers, timers on the steady clock, :func:`rigid_body_sim.node.process.spin`: the
  EventsExecutor's ``spin_once``);
- one subscriber (``--subscriber``) to every one of those topics of the node and of the bare
  loop (raw, so that it deserialises nothing): each publisher has one subscriber.

After a warm-up the CPU time of the node and of the bare loop (user + system, all threads,
/proc/<pid>/stat) is read over ``--windows`` windows of ``--seconds`` s; each window's ratio
node / bare is printed, their median is the figure (goal: at most 1.3).

Memory (``--memory``): a node of ``scene:=constellation`` (1,000 bodies) and a node of the
default scene (one body) run side by side, no subscribers; after ``--settle`` s each one's
VmRSS is read (/proc/<pid>/status), with the 1,000-body node's /diagnostics (does it keep
its rate).  1,000 one-body nodes are estimated as 1,000 x the one-body node's RSS (an
estimate: each would be a process and a DDS participant of its own; none was started).

Usage: ``.venv/bin/python benchmarks/world_node_vs_bare_loop.py [--windows 5]
[--seconds 10] [--topics pose twist ...] [--bare-bytes]`` and ``... --memory
[--settle 30]``; ``--bare-bytes``: the bare loop publishes its messages serialised once (no
conversion a tick: the least any loop publishing them costs).  The
figures, with the commands, are in docs/node.md ("Many bodies").
"""

import argparse
import os
from pathlib import Path
import re
import signal
import statistics
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

# The CPU windows of the one-body comparison (this script's folder is on the path).
from node_vs_bare_loop import cpu_windows  # noqa: E402
from node_vs_bare_loop import exit_if_any_stopped  # noqa: E402
from node_vs_bare_loop import script_process  # noqa: E402

NAMESPACE = '/vs_bare_world'
BARE = '/bare_world'
RATE = 100.0
SCENE = 'debris_field'
BODY_TOPICS = ('pose', 'twist', 'angular_momentum', 'odom')


def resident_megabytes(pid):
    """Return a process's VmRSS in MB."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError(f'no VmRSS for {pid}')


def _names():
    from rigid_body_sim.scenes import load_scene
    return [member.name for member in load_scene(SCENE).members]


def _messages(topics, scene=SCENE):
    """Return {topic: message} the bare loop publishes, the node's for debris_field."""
    from geometry_msgs.msg import PoseStamped
    from geometry_msgs.msg import TransformStamped
    from geometry_msgs.msg import Twist
    from geometry_msgs.msg import Vector3Stamped
    from nav_msgs.msg import Odometry
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    from rigid_body_sim.messages.marker import marker_geometry_from_drawing
    from rigid_body_sim.messages.marker import new_marker
    from rigid_body_sim.scenes import load_scene

    members = load_scene(scene).members
    kinds = {'pose': PoseStamped, 'twist': Twist, 'angular_momentum': Vector3Stamped,
             'odom': Odometry}
    messages = {}
    for member in members:
        for topic in topics:
            message = kinds[topic]()
            if topic != 'twist':
                message.header.frame_id = 'world'
            if topic == 'odom':
                message.child_frame_id = member.name
            messages[f'{BARE}/{member.name}/{topic}'] = message
    transforms = []
    for member in members:
        transform = TransformStamped()
        transform.header.frame_id = 'world'
        transform.child_frame_id = member.name
        transforms.append(transform)
    messages[f'{BARE}/tf'] = TFMessage(transforms=transforms)
    messages[f'{BARE}/markers'] = MarkerArray(markers=[
        new_marker(marker_geometry_from_drawing(member.drawing), 'world', member.name, index)
        for index, member in enumerate(members)])
    return messages


def bare_loop(topics, serialized=False):
    """Publish what the node publishes for debris_field at 100 Hz, spun as the node spins."""
    from diagnostic_msgs.msg import DiagnosticArray
    from diagnostic_msgs.msg import DiagnosticStatus
    import rclpy
    from rclpy.clock import Clock
    from rclpy.clock import ClockType
    from rclpy.serialization import serialize_message
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import Imu

    from rigid_body_sim.messages.qos import DIAGNOSTICS_QOS
    from rigid_body_sim.messages.qos import STATE_QOS
    from rigid_body_sim.messages.qos import TF_QOS
    from rigid_body_sim.node.process import install_signal_handlers
    from rigid_body_sim.node.process import spin

    install_signal_handlers()
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bare_world', context=context)
    messages = _messages(topics)
    publishers = [(node.create_publisher(type(message), topic,
                                         TF_QOS if topic.endswith('/tf') else STATE_QOS),
                   message) for topic, message in messages.items()]
    # The node offers every body's topics, subscribed or not: so does the bare loop (the
    # others are never published, as the node publishes only what has subscribers).
    offered = [node.create_publisher(type(message), topic, STATE_QOS)
               for topic, message in _messages(BODY_TOPICS).items() if topic not in messages]
    offered += [node.create_publisher(Imu, f'{BARE}/{member}/imu', STATE_QOS)
                for member in _names()]
    diagnostics = node.create_publisher(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    report = DiagnosticArray()
    report.status = [DiagnosticStatus(name='bare_world', message='running')]
    transforms = messages[f'{BARE}/tf'].transforms
    markers = messages[f'{BARE}/markers'].markers
    data = [(publisher, serialize_message(message)) for publisher, message in publishers]

    def tick_serialized():
        # The least a loop can do: the same bytes again, no field changed, no conversion.
        for publisher, message in data:
            publisher.publish(message)

    def tick():
        stamp = divmod(time.time_ns(), 1_000_000_000)
        for publisher, message in publishers:
            header = getattr(message, 'header', None)
            if header is not None:
                header.stamp.sec, header.stamp.nanosec = stamp
            publisher.publish(message)
        for part in transforms:
            part.header.stamp.sec, part.header.stamp.nanosec = stamp
            part.transform.translation.x += 1e-3
        for marker in markers:
            marker.header.stamp.sec, marker.header.stamp.nanosec = stamp
            marker.pose.position.x += 1e-3

    def publish_diagnostics():
        diagnostics.publish(report)
        count = min(publisher.get_subscription_count() for publisher, _ in publishers)
        print(f'least subscribers: {count} at {time.monotonic():.3f}', flush=True)

    steady = Clock(clock_type=ClockType.STEADY_TIME)
    node.create_timer(1.0 / RATE, tick_serialized if serialized else tick, clock=steady)
    node.create_timer(1.0, publish_diagnostics, clock=steady)
    try:
        spin(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def subscriber(topics, scene=SCENE, namespace=NAMESPACE, with_bare=True):
    """Subscribe (raw) to the node's (and the bare loop's) topics; take every message."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from rigid_body_sim.messages.qos import STATE_QOS
    from rigid_body_sim.messages.qos import TF_QOS
    from rigid_body_sim.node.process import install_signal_handlers
    from rigid_body_sim.node.process import spin

    install_signal_handlers()
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('world_subscriber', context=context)
    bare = _messages(topics, scene)
    names = {topic: type(message) for topic, message in bare.items()} if with_bare else {}
    for topic, message in bare.items():
        if topic == f'{BARE}/tf':
            names['/tf'] = type(message)
        else:
            names[namespace + topic[len(BARE):]] = type(message)
    for topic, kind in names.items():
        node.create_subscription(kind, topic, lambda data: None,
                                 TF_QOS if topic.endswith('/tf') else STATE_QOS, raw=True)
    try:
        spin(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _node(scene, namespace, log, environment):
    return subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args', '-r',
         f'__ns:={namespace}', '-p', f'scene:={scene}'],
        env=environment, cwd=ROOT, stdout=open(log, 'w'), stderr=subprocess.STDOUT)


def _stop(processes):
    for process in processes.values():
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
    for process in processes.values():
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()


def cpu(arguments, environment, logs):
    """Run node, bare loop and subscriber side by side; print the CPU ratio per window."""
    script = str(Path(__file__).resolve())
    topics = ['--topics', *arguments.topics]
    processes = {
        'node': _node(SCENE, NAMESPACE, logs / 'node.log', environment),
        'bare': script_process(script, ['--bare', *topics, *(['--bare-bytes'] if
                                                             arguments.bare_bytes else [])],
                               environment, logs / 'bare.log'),
        'subscriber': script_process(script, ['--subscriber', *topics], environment,
                                     logs / 'subscriber.log'),
    }
    try:
        time.sleep(arguments.warmup)  # start-up, discovery, kernels loaded
        exit_if_any_stopped(processes, logs)
        print(f'{SCENE} (100 bodies) at {RATE:g} Hz; per body {", ".join(arguments.topics)}, '
              'one /tf and one MarkerArray, one subscriber each; the bare loop publishes '
              + ('the same bytes again each tick' if arguments.bare_bytes else
                 'rclpy messages, a field changed each tick'))
        measured_from = time.time()
        ratios = cpu_windows(processes, arguments.windows, arguments.seconds)
        exit_if_any_stopped(processes, logs, ' during the windows')
        measured = (measured_from, time.time())
        counts = [line for line in (logs / 'bare.log').read_text().splitlines()
                  if line.startswith('least subscribers: ')]
        every = _publish_every(logs / 'node.log', *measured)
        print(f'the node published every {every} tick(s) during the windows (its log)')
        median = statistics.median(ratios)
        verdict = 'holds' if median <= 1.3 else 'fails'
        print(f'median ratio node / bare loop: {median:.2f} (goal <= 1.3: {verdict}); '
              f'bare loop {counts[-1] if counts else "never reported"}; load average '
              f'{os.getloadavg()[0]:.1f}')
    finally:
        _stop(processes)


def _publish_every(log, start, end):
    """Return the k (publish every k-th tick) the node's log shows in force from start to end."""
    changes = []
    for line in log.read_text().splitlines():
        match = re.search(r'\[(\d+\.\d+)\].*publishing the state topics, /tf and markers every '
                          r'(\d+) tick', line)
        if match:
            changes.append((float(match.group(1)), int(match.group(2))))
    before = [k for at, k in changes if at <= start]
    during = [k for at, k in changes if start < at <= end]
    return ', then '.join(str(k) for k in (before[-1:] or [1]) + during)


def memory(arguments, environment, logs):
    """Print the VmRSS of a 1,000-body node and of a one-body node, side by side."""
    processes = {
        'constellation': _node('constellation', '/memory_world', logs / 'constellation.log',
                               environment),
        'default': _node('default', '/memory_one', logs / 'default.log', environment),
    }
    try:
        time.sleep(arguments.settle)
        rss = {name: resident_megabytes(process.pid) for name, process in processes.items()}
        time.sleep(2.0)
        later = {name: resident_megabytes(process.pid) for name, process in processes.items()}
        print(f'VmRSS after {arguments.settle:g} s (and 2 s later):')
        for name in processes:
            print(f'  {name}: {rss[name]:.0f} MB ({later[name]:.0f} MB)')
        estimate = 1000 * later['default']
        print(f'one node of 1,000 bodies: {later["constellation"]:.0f} MB; 1,000 one-body '
              f'nodes (estimate: 1,000 x one default-scene node): {estimate / 1024:.1f} GB; '
              f'ratio {estimate / later["constellation"]:.0f}x')
    finally:
        _stop(processes)
    for line in (logs / 'constellation.log').read_text().splitlines():
        if 'publishing the state topics' in line or 'falling behind' in line \
                or 'simulating scene' in line:
            print('  constellation log:', line[:300])


def constellation(arguments, environment, logs):
    """Run the 1,000-body node with a subscriber to every pose, /tf and markers; its status."""
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy
    import rclpy.executors

    from rigid_body_sim.messages.qos import DIAGNOSTICS_QOS

    namespace = '/many_world'
    script = str(Path(__file__).resolve())
    processes = {
        'node': _node('constellation', namespace, logs / 'many.log', environment),
        'subscriber': subprocess.Popen(
            [sys.executable, script, '--subscriber', '--scene', 'constellation',
             '--namespace', namespace, '--no-bare', '--topics', *arguments.topics],
            env=environment, stdout=open(logs / 'many_subscriber.log', 'w'),
            stderr=subprocess.STDOUT),
    }
    context = rclpy.Context()
    rclpy.init(context=context)
    listener = rclpy.create_node('many_listener', context=context)
    reports = []
    listener.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda message: reports.extend(
            status for status in message.status
            if status.hardware_id == f'{namespace}/rigid_body_sim'), DIAGNOSTICS_QOS)
    try:
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        executor.add_node(listener)
        end = time.monotonic() + arguments.settle
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.5)
        keys = ('bodies', 'rate kept', 'state published every k-th tick', 'achieved rate [Hz]',
                'missed ticks', 'step time p50 [ms]', 'tick duration p50 [ms]',
                'tick duration p99 [ms]', 'integration per body-tick [us]',
                'publishing CPU per publishing tick [ms]')
        print("constellation (1,000 bodies) at 100 Hz, one subscriber to every body's "
              f'{", ".join(arguments.topics)}, /tf and markers; its last 5 reports of '
              f'{len(reports)}:')
        for status in reports[-5:]:
            values = {kv.key: kv.value for kv in status.values}
            print(f'  [{status.level[0] if isinstance(status.level, bytes) else status.level}] '
                  f'{status.message[:160]}')
            print('    ' + '; '.join(f'{key}: {values.get(key)}' for key in keys))
    finally:
        listener.destroy_node()
        rclpy.try_shutdown(context=context)
        _stop(processes)
    for line in (logs / 'many.log').read_text().splitlines():
        if 'publishing the state topics' in line:
            print('  log:', line[line.index('publishing'):][:200])


def main(argv=None):
    """Run the CPU comparison, or the memory one."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--windows', type=int, default=5)
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--warmup', type=float, default=30.0)
    parser.add_argument('--topics', nargs='+', default=['pose'], choices=BODY_TOPICS,
                        help='the per-body topics subscribed (default: pose)')
    parser.add_argument('--memory', action='store_true',
                        help='instead: the VmRSS of a 1,000-body node and a one-body node')
    parser.add_argument('--settle', type=float, default=30.0)
    parser.add_argument('--constellation', action='store_true',
                        help='instead: the 1,000-body node with a subscriber to every body, '
                             'its /diagnostics (rate kept, publishing every k-th tick)')
    parser.add_argument('--scene', default=SCENE, help=argparse.SUPPRESS)
    parser.add_argument('--namespace', default=NAMESPACE, help=argparse.SUPPRESS)
    parser.add_argument('--no-bare', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--bare-bytes', action='store_true',
                        help='the bare loop publishes its messages serialised once (the '
                             'same bytes each tick): the least a loop can cost')
    parser.add_argument('--bare', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--subscriber', action='store_true', help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    if arguments.bare:
        return bare_loop(arguments.topics, arguments.bare_bytes)
    if arguments.subscriber:
        return subscriber(arguments.topics, arguments.scene, arguments.namespace,
                          not arguments.no_bare)
    environment = dict(os.environ, PYTHONPATH=str(ROOT))
    environment.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 80))
    environment['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    logs = ROOT / 'build' / 'world_node_vs_bare_loop'
    logs.mkdir(parents=True, exist_ok=True)
    if arguments.memory:
        return memory(arguments, environment, logs)
    if arguments.constellation:
        return constellation(arguments, environment, logs)
    return cpu(arguments, environment, logs)


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""
The node's CPU at 1 kHz against a bare rclpy timer loop beside it, as a ratio (issue 21).

Three processes run side by side in one ROS domain (``$ROS_DOMAIN_ID``, else one of this
script's own) on the loopback:

- the node (default scene, ``rate:=1000.0``), started as ``rigid_body_node`` starts it;
- a bare loop (this script with ``--bare``): an rclpy node whose 1 kHz timer publishes one
  PoseStamped, the node's ``pose`` message, and whose 1 Hz timer publishes one
  DiagnosticArray on ``/diagnostics`` as the node does; spun exactly as the node is spun:
  a context of its own initialised without rclpy's signal handlers, timers on the steady
  clock, and the node's own spin (:func:`rigid_body_sim.node.process.spin`:
  ``EventsExecutor.spin_once(timeout_sec=...)`` until a signal), so that the ratio compares
  the node's work per tick, not two ways of waiting (``EventsExecutor.spin()`` runs hot:
  most of a core for the same loop);
- one subscriber (this script with ``--subscriber``) to the node's ``pose`` and to the bare
  loop's pose: each publisher has one matched subscriber, as in the goal.  (The node
  serialises and publishes only the topics that have a subscriber.)

After a warm-up the CPU time of the node and of the bare loop (user + system, all
threads, from /proc/<pid>/stat, both read the same way) is read over `--windows`
consecutive windows of `--seconds` s; the ratio node / bare of each window is printed and
their median is the figure.  The goal is a median at most 1.3.

Usage: ``.venv/bin/python benchmarks/node_vs_bare_loop.py [--windows 5] [--seconds 10]
[--parameter NAME:=VALUE] [--source DIR]``; ``--parameter`` gives the node a parameter
(``tolerance:=0.0``: fixed steps instead of the scene's error control), ``--source`` runs the
node from another checkout's sources (for a before/after comparison), with this venv.

``--breakdown`` instead runs the node in this process and prints, per tick, the CPU of its
parts (the integration, the state's serialisation and publication, the rest of the tick,
what runs outside the tick: executor, DDS, timers) with no subscriber and with a subscriber
to each of its per-tick topics in turn: what each topic costs.  The results, with the
command, are in docs/node.md.
"""

import argparse
import ast
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
SUBSCRIBERS_LINE = 'pose subscribers: '


def process_cpu_seconds(pid):
    """Return the user + system CPU time of a process (all threads) in s."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def script_process(script, role, environment, log):
    """Start `script` in a role (its options, e.g. ['--bare']), its output written to `log`."""
    return subprocess.Popen([sys.executable, str(script), *role], env=environment,
                            stdout=open(log, 'w'), stderr=subprocess.STDOUT)


def exit_if_any_stopped(processes, logs, when=''):
    """Exit, naming it and the logs, if one of `processes` (by name) has stopped."""
    for name, process in processes.items():
        if process.poll() is not None:
            raise SystemExit(f'{name} exited with {process.returncode}{when}; see {logs}')


def cpu_windows(processes, windows, seconds):
    """
    Print and return node CPU / bare loop CPU in each of `windows` windows of `seconds` s.

    processes: {'node': Popen, 'bare': Popen}; both read in the same windows, side by side.
    """
    print('window  node CPU %  bare loop CPU %  ratio')
    ratios = []
    for window in range(windows):
        before = {name: process_cpu_seconds(processes[name].pid) for name in ('node', 'bare')}
        started = time.monotonic()
        time.sleep(seconds)
        elapsed = time.monotonic() - started
        used = {name: process_cpu_seconds(processes[name].pid) - before[name]
                for name in ('node', 'bare')}
        ratio = used['node'] / used['bare']
        ratios.append(ratio)
        print(f'{window + 1:6d}  {100 * used["node"] / elapsed:10.1f}  '
              f'{100 * used["bare"] / elapsed:15.1f}  {ratio:5.2f}', flush=True)
    return ratios


def bare_loop():
    """Publish the node's pose at 1 kHz and /diagnostics at 1 Hz, spun as the node spins."""
    from diagnostic_msgs.msg import DiagnosticArray
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import PoseStamped
    import rclpy
    from rclpy.clock import Clock
    from rclpy.clock import ClockType
    from rclpy.signals import SignalHandlerOptions

    sys.path.insert(0, str(ROOT))
    from rigid_body_sim.node.process import install_signal_handlers
    from rigid_body_sim.node.process import spin
    from rigid_body_sim.messages.qos import DIAGNOSTICS_QOS
    from rigid_body_sim.messages.qos import STATE_QOS

    # As run_node: signals only noted, a context of our own without rclpy's handlers.
    install_signal_handlers()
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bare_loop', context=context)
    publisher = node.create_publisher(PoseStamped, BARE_TOPIC, STATE_QOS)
    diagnostics = node.create_publisher(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    message = PoseStamped()
    message.header.frame_id = 'world'
    report = DiagnosticArray()
    report.status = [DiagnosticStatus(name='bare_loop', message='running')]

    def tick():
        # The node's stamp on system time: time.time_ns(), not Clock.now().
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(time.time_ns(),
                                                                        1_000_000_000)
        message.pose.position.x += 1e-3
        publisher.publish(message)

    matched = [None]

    def publish_diagnostics():
        report.header.stamp.sec, report.header.stamp.nanosec = divmod(time.time_ns(),
                                                                      1_000_000_000)
        diagnostics.publish(report)
        # The log tells main() whether the pose reaches a subscriber (an unmatched publish
        # costs a fraction of a matched one).
        count = publisher.get_subscription_count()
        if count != matched[0]:
            matched[0] = count
            # time.monotonic is the system's CLOCK_MONOTONIC: main() compares it with its own.
            print(f'{SUBSCRIBERS_LINE}{count} at {time.monotonic():.3f}', flush=True)

    steady = Clock(clock_type=ClockType.STEADY_TIME)
    node.create_timer(1.0 / RATE, tick, clock=steady)
    node.create_timer(1.0, publish_diagnostics, clock=steady)
    try:
        spin(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _topic_types():
    """Return {topic: (message class, QoS)} of every topic the node serialises per tick."""
    from sensor_msgs.msg import Imu

    sys.path.insert(0, str(ROOT))
    from rigid_body_sim.messages.state import STATE_TYPES
    from rigid_body_sim.messages.qos import STATE_QOS
    from rigid_body_sim.messages.qos import TF_QOS
    from rigid_body_sim.messages.tf import transform_message_class

    types = {topic: (message, STATE_QOS) for topic, message in STATE_TYPES.items()}
    types['imu'] = (Imu, STATE_QOS)
    message, _ = transform_message_class()
    if message is not None:
        types['/tf'] = (message, TF_QOS)
    return types


def subscriber(namespace, topics, with_bare=True):
    """Subscribe to the node's `topics` (and to the bare loop's pose); take every message."""
    from geometry_msgs.msg import PoseStamped
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    types = _topic_types()
    from rigid_body_sim.node.process import install_signal_handlers
    from rigid_body_sim.node.process import spin
    from rigid_body_sim.messages.qos import STATE_QOS

    # Spun as the node spins: EventsExecutor.spin() here ran hot under load and its
    # participant's liveliness then lapsed (the publishers lost their match after ~20 s).
    install_signal_handlers()
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bare_loop_subscriber', context=context)
    for topic in topics:
        message, qos = types[topic]
        name = topic if topic.startswith('/') else f'{namespace}/{topic}'
        node.create_subscription(message, name, lambda message: None, qos)
    if with_bare:
        node.create_subscription(PoseStamped, BARE_TOPIC, lambda message: None, STATE_QOS)
    try:
        spin(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def breakdown(environment, seconds, parameters=()):
    """
    Print what the node's tick and each of its topics cost, the node run in this process.

    The node (default scene, 1 kHz) is built here and spun as process.spin spins it; its
    tick's parts are timed in CPU time of the executor's thread (time.thread_time):
    the integration (Simulator.step), the state's serialisation and publication
    (_publish_state), the rest of the tick, the subscriber check (10 Hz) and /diagnostics
    (1 Hz); the process's CPU (all threads: executor, DDS) is read beside them.  One window
    per subscribed topic (a subscriber process takes that topic alone), and one with no
    subscriber: a topic's cost is its window's CPU less that one's.
    """
    os.environ.update(environment)
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions

    sys.path.insert(0, str(ROOT))
    from rigid_body_sim.node.rigid_body_node import RigidBodyNode
    from rigid_body_sim.node.process import STOP_LATENCY

    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    overrides = [Parameter('rate', value=RATE)]
    for parameter in parameters:
        name, _, value = parameter.partition(':=')
        overrides.append(Parameter(name, value=ast.literal_eval(value)))
    node = RigidBodyNode(context=context, namespace='/vs_bare', parameter_overrides=overrides)
    spent = {}

    def timed(owner, name, key):
        original = getattr(owner, name)

        def wrapper(*args, **kwargs):
            started = time.thread_time()
            try:
                return original(*args, **kwargs)
            finally:
                spent[key] = spent.get(key, 0.0) + time.thread_time() - started
        setattr(owner, name, wrapper)

    # The tick's parts, looked up at each call (the timers hold the callbacks themselves).
    timed(node._simulator, 'step', 'integration (Simulator.step)')
    timed(node, '_publish_state', 'serialise + publish the state')
    timed(node, '_tick', 'tick')
    executor = EventsExecutor(context=context)
    executor.add_node(node)

    def spin(duration):
        end = time.monotonic() + duration
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=STOP_LATENCY)

    script = str(Path(__file__).resolve())
    spin(5.0)  # kernels loaded, first ticks
    print(f'node in this process, {RATE:g} Hz, default scene'
          + ''.join(f', {parameter}' for parameter in parameters)
          + f'; {seconds:g} s per window; CPU per tick in us (process: all threads)')
    columns = ['process', 'tick', 'integration (Simulator.step)',
               'serialise + publish the state']
    print('| subscribed | ' + ' | '.join(columns) + ' | rest of the tick | outside the tick '
          '| process less none’s |')
    print('|' + ' --- |' * (len(columns) + 4))
    baseline = None
    for topic in [None, *_topic_types()]:
        listener = None if topic is None else subprocess.Popen(
            [sys.executable, script, '--subscriber', '/vs_bare', '--topics', topic,
             '--no-bare'], env=environment, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        try:
            spin(4.0)  # discovery, and the node's next subscriber check
            spent.clear()
            ticks, cpu = node._ticks, time.process_time()
            spin(seconds)
            ticks, cpu = node._ticks - ticks, time.process_time() - cpu
        finally:
            if listener is not None:
                listener.kill()  # ours; a window's figures need no orderly stop
                listener.wait()
        per_tick = {key: 1e6 * value / ticks for key, value in spent.items()}
        per_tick['process'] = 1e6 * cpu / ticks
        if baseline is None:
            baseline = per_tick['process']
        rest = per_tick['tick'] - per_tick['integration (Simulator.step)'] - per_tick[
            'serialise + publish the state']
        print(f'| {topic or "none"} | '
              + ' | '.join(f'{per_tick.get(key, 0.0):.1f}' for key in columns)
              + f' | {rest:.1f} | {per_tick["process"] - per_tick["tick"]:.1f} '
              f'| {per_tick["process"] - baseline:+.1f} |', flush=True)
    # The timers outside the tick, per call, spread over the ticks of their period.
    for name, call, period in (('subscriber check', node._check_subscribers, 0.1),
                               ('/diagnostics', node._publish_diagnostics, 1.0)):
        calls = 200
        started = time.thread_time()
        for _ in range(calls):
            call()
        each = (time.thread_time() - started) / calls
        print(f'{name} every {period:g} s: {1e6 * each:.0f} us a call, '
              f'{1e6 * each / (period * RATE):.2f} us per tick')
    executor.remove_node(node)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def _check_bare_loop_matched(log, start, end):
    """Exit with a message unless the bare loop's pose had one subscriber from start to end."""
    changes = []
    for line in log.read_text().splitlines():
        if line.startswith(SUBSCRIBERS_LINE):
            count, _, at = line[len(SUBSCRIBERS_LINE):].partition(' at ')
            changes.append((float(at), int(count)))
    before = [count for at, count in changes if at <= start]
    during = [count for at, count in changes if start < at <= end]
    if not before or before[-1] != 1 or any(count != 1 for count in during):
        raise SystemExit(f'the bare loop had not one pose subscriber throughout the windows '
                         f'({changes}); see {log}')


def main(argv=None):
    """Run the three processes side by side and print the CPU ratio per window."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--windows', type=int, default=5)
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--warmup', type=float, default=30.0,
                        help='s before the first window (start-up and discovery; the bare '
                             'loop was seen busier during its first 20 s)')
    parser.add_argument('--parameter', action='append', default=[], metavar='NAME:=VALUE',
                        help='a parameter of the node besides rate, e.g. tolerance:=0.0 '
                             '(repeatable)')
    parser.add_argument('--source', type=Path, default=ROOT,
                        help='checkout whose rigid_body_sim runs as the node')
    parser.add_argument('--breakdown', action='store_true',
                        help="instead: what the node's tick and each topic cost, per tick")
    parser.add_argument('--bare', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--subscriber', help=argparse.SUPPRESS)
    parser.add_argument('--topics', nargs='+', default=['pose'], help=argparse.SUPPRESS)
    parser.add_argument('--no-bare', action='store_true', help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    if arguments.bare:
        return bare_loop()
    if arguments.subscriber is not None:
        return subscriber(arguments.subscriber, arguments.topics, not arguments.no_bare)

    environment = dict(os.environ)
    environment.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 80))
    environment['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if arguments.breakdown:
        return breakdown(environment, arguments.seconds, arguments.parameter)
    node_environment = dict(environment, PYTHONPATH=str(arguments.source.resolve()))
    namespace = '/vs_bare'
    script = str(Path(__file__).resolve())
    logs = ROOT / 'build' / 'node_vs_bare_loop'
    logs.mkdir(parents=True, exist_ok=True)
    processes = {
        'node': subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args',
             '-r', f'__ns:={namespace}', '-p', f'rate:={RATE}',
             *(word for parameter in arguments.parameter for word in ('-p', parameter))],
            env=node_environment, cwd=arguments.source,
            stdout=open(logs / 'node.log', 'w'), stderr=subprocess.STDOUT),
        'bare': script_process(script, ['--bare'], environment, logs / 'bare.log'),
        'subscriber': script_process(script, ['--subscriber', namespace], environment,
                                     logs / 'subscriber.log'),
    }
    try:
        time.sleep(arguments.warmup)  # start-up, discovery, kernels loaded
        exit_if_any_stopped(processes, logs)
        measured_from = time.monotonic()
        print(f'node from {arguments.source.resolve()}; 1 kHz, one pose subscriber each'
              + ''.join(f'; {parameter}' for parameter in arguments.parameter))
        ratios = cpu_windows(processes, arguments.windows, arguments.seconds)
        exit_if_any_stopped(processes, logs, ' during the windows')
        _check_bare_loop_matched(logs / 'bare.log', measured_from, time.monotonic())
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

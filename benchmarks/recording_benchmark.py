#!/usr/bin/env python3
"""
Measure offline simulate speed and the live recorder's CPU and losses at 1 kHz.

Usage: .venv/bin/python benchmarks/recording_benchmark.py [--seconds S] [--repeats K]
       [--record-seconds R] [--no-record] [--stalls [--stall-repeats N]]

1. Offline: each built-in scene simulated at 1 kHz for S simulated seconds into an MCAP
   bag with every topic the node publishes plus /clock (6 topics at 1 kHz, /diagnostics at
   1 Hz), by ``simulate_to_bag`` in this process after a warm-up run (numba's compiled
   kernels loaded): the median over K runs of simulated s per wall-clock s.  Then the
   same for the default scene through the command line (``rigid-body-sim simulate``, a new
   process: imports, kernel loading and all), timed from outside.
2. Live: the node at 1 kHz with publish_clock (``python -m rigid_body_sim.node.entry_point``)
   and ``rigid-body-sim record`` of its topics for R s, both subprocesses in a ROS domain of
   their own on the loopback: messages per topic, messages lost (gaps in the publishers'
   sequence numbers and in the node's simulated-time stamps, read back from the bag), the
   recorder's CPU while recording (its own report: process time / wall time) and in total
   (from /proc, start-up included), and the node's CPU over the same time.
3. With --stalls (instead of 1 and 2): where messages are lost at 1 kHz.  The node and the
   recorder as in 2, and 2 s into the recording one of them is stopped (SIGSTOP) for 0.3 or
   0.6 s and continued (SIGCONT): a stopped node catches up by ticking back to back (a
   burst), a stopped recorder receives nothing meanwhile.  Each case is run N times and
   prints, per case, the messages lost per state topic and on /clock and where the first
   gap starts (ms after the stop).  Variants: Fast DDS shared memory with an 8 MiB segment
   (default 512 KiB) with and without a deeper port queue (8192 descriptors; default 512),
   given by an XML profile (FASTRTPS_DEFAULT_PROFILES_FILE); and the node's state
   publishers at keep-last 10, their depth before it became 1000 (rigid_body_sim.messages.qos
   .STATE_QOS patched before the node is imported, in the node's process only).
"""

import argparse
import os
from pathlib import Path
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from mcap.reader import make_reader
import numpy as np
from rigid_body_sim.recording.simulate import simulate_to_bag
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import scene_names

RATE = 1000.0
STATE_TOPICS = ('pose', 'twist', 'angular_momentum', 'odom', 'marker')
STAMPED = ('pose', 'angular_momentum', 'odom', 'marker')


def offline(seconds, repeats, directory):
    """Print the speed of simulate_to_bag per scene."""
    print(f'Offline simulate at {RATE:g} Hz, {seconds:g} s simulated, all topics + /clock, '
          f'median of {repeats}:')
    print(f'  {"scene":<14} {"integrator":<10} {"effects":<26} {"x real time":>11} '
          f'{"us/tick":>8} {"MB/s sim":>9}')
    for name in scene_names(several_bodies=False):
        scene = load_scene(name)
        simulate_to_bag(scene, directory / f'{name}_warm', 0.2, rate=RATE, clock=True)
        speeds = []
        size = 0
        for k in range(repeats):
            bag = directory / f'{name}_{k}'
            summary = simulate_to_bag(scene, bag, seconds, rate=RATE, clock=True)
            speeds.append(summary.speed)
            size = sum(f.stat().st_size for f in bag.iterdir())
            shutil.rmtree(bag)
        speed = statistics.median(speeds)
        effects = ', '.join(scene.effect_names()) or 'none'
        print(f'  {name:<14} {scene.integrator:<10} {effects:<26} {speed:>10.1f}x '
              f'{1e6 / (speed * RATE):>8.1f} {size / seconds / 1e6:>9.2f}')
    bag = directory / 'cli'
    command = [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 'default',
               '--duration', f'{seconds:g}', '--rate', f'{RATE:g}', '--clock', '--quiet',
               '--bag', str(bag)]
    started = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    print(f'  command line, default scene, new process (start-up included): {wall:.2f} s '
          f'for {seconds:g} s = {seconds / wall:.1f}x real time')
    print(f'    {" ".join(command[1:])}')


def _cpu_seconds(pid):
    """Return user + system CPU seconds of a process (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _ros_environment(extra=None):
    """Return os.environ with a ROS domain of its own (ROS_DOMAIN_ID if set) on the loopback."""
    environment = dict(os.environ)
    environment.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 80))
    environment['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    environment.update(extra or {})
    return environment


def live(record_seconds, directory):
    """Run the node and the recorder at 1 kHz; print losses and CPU."""
    environment = _ros_environment()
    namespace = '/bench'
    node = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.node.entry_point', '--ros-args', '-r',
         f'__ns:={namespace}', '-p', f'rate:={RATE}', '-p', 'publish_clock:=true'],
        env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    bag = directory / 'live'
    try:
        time.sleep(2.0)
        node_cpu = _cpu_seconds(node.pid)
        started = time.monotonic()
        recorder = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.cli', 'record', '--namespace', namespace,
             '--bag', str(bag), '--duration', f'{record_seconds:g}'],
            env=environment, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        total_cpu = 0.0
        while recorder.poll() is None:
            try:
                total_cpu = _cpu_seconds(recorder.pid)
            except (FileNotFoundError, ProcessLookupError):
                break
            time.sleep(0.2)
        report = recorder.communicate()[0]
        wall = time.monotonic() - started
        node_cpu = _cpu_seconds(node.pid) - node_cpu
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(20)
    print(f'Live recorder: node at {RATE:g} Hz (publish_clock), rigid-body-sim record of its '
          f'topics for {record_seconds:g} s:')
    print('  ' + report.strip().replace('\n', '\n  '))
    print(f'  recorder CPU including start-up: {total_cpu:.1f} s in {wall:.1f} s = '
          f'{100 * total_cpu / wall:.1f}% of a core; node CPU meanwhile: '
          f'{100 * node_cpu / wall:.1f}% of a core')
    with open(bag / 'live.mcap', 'rb') as stream:
        messages = {}
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            messages.setdefault(channel.topic, []).append(message)
    print('  read back from the bag (mcap): received, lost between first and last '
          '(sequence gaps / stamp gaps)')
    for topic in STATE_TOPICS:
        records = messages.get(f'{namespace}/{topic}', [])
        sequences = np.array([m.sequence for m in records])
        lost = int(np.sum(np.diff(sequences) - 1)) if len(records) > 1 else 0
        stamp_lost = 'n/a'
        if topic in STAMPED and len(records) > 1:
            stamps = np.array([int.from_bytes(m.data[4:8], 'little') * 10**9
                               + int.from_bytes(m.data[8:12], 'little') for m in records])
            stamp_lost = str(int(np.sum(np.diff(stamps) // 1_000_000 - 1)))
        where = ''
        if lost:
            # Where the gaps are (s after the topic's first message) and how long the
            # publisher paused there: a gap after a long pause points at the publisher.
            publish = np.array([m.publish_time for m in records])
            at = np.flatnonzero(np.diff(sequences) != 1)
            where = '; gaps at ' + ', '.join(
                f'{(publish[k] - publish[0]) * 1e-9:.2f} s ({sequences[k + 1] - sequences[k] - 1}'
                f' lost, publisher pause {(publish[k + 1] - publish[k]) * 1e-6:.1f} ms)'
                for k in at[:5])
        print(f'    {topic:<17} {len(records):>7} received, lost {lost} / {stamp_lost}{where}')
    diagnostics = messages.get('/diagnostics', [])
    if diagnostics:
        from rigid_body_sim.recording.bag_writer import typestore
        store = typestore()
        worst = max((store.deserialize_cdr(m.data, 'diagnostic_msgs/msg/DiagnosticArray')
                     for m in diagnostics),
                    key=lambda array: float({kv.key: kv.value for kv in
                                             array.status[0].values}['tick duration p99 [ms]']))
        values = {kv.key: kv.value for kv in worst.status[0].values}
        print(f"  node's worst second: tick p99 {values['tick duration p99 [ms]']} ms, step max "
              f"{values['step time max [ms]']} ms, missed ticks {values['missed ticks']}")


# A Fast DDS XML profile: a shared-memory transport beside the built-in ones (rmw_fastrtps
# with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST adds its own UDP and default shared memory
# whatever the profile says, and ignores FASTDDS_BUILTIN_TRANSPORTS: checked in /dev/shm,
# where a 549408-byte segment appears either way).
_SHM_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>shm_big</transport_id>
      <type>SHM</type>
      <segment_size>8388608</segment_size>{queue}
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="shm_big" is_default_profile="true">
    <rtps>
      <userTransports><transport_id>shm_big</transport_id></userTransports>
      <useBuiltinTransports>true</useBuiltinTransports>
    </rtps>
  </participant>
</profiles>
"""


def _stall_run(directory, name, stopped, stall, extra_environment, depth, record_seconds):
    """Record the node at 1 kHz, stop one process for `stall` s; return the losses."""
    environment = _ros_environment(extra_environment)
    namespace = f'/stall_{os.getpid()}_{name}'
    if depth is None:
        command = [sys.executable, '-m', 'rigid_body_sim.node.entry_point']
    else:
        # The node's state QoS at another depth, in this node process only.
        command = [sys.executable, '-c',
                   'import sys; import rigid_body_sim.messages.qos as qos; '
                   f'qos.STATE_QOS.depth = {depth}; '
                   'from rigid_body_sim.node.process import main; sys.exit(main(sys.argv))']
    node = subprocess.Popen(
        command + ['--ros-args', '-r', f'__ns:={namespace}', '-p', f'rate:={RATE}', '-p',
                   'publish_clock:=true'],
        env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    bag = directory / name
    try:
        time.sleep(3.0)
        recorder = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.cli', 'record', '--namespace', namespace,
             '--bag', str(bag), '--duration', f'{record_seconds:g}'],
            env=environment, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        metadata = bag / 'metadata.yaml'
        deadline = time.monotonic() + 60.0
        while not (metadata.exists() and f'{namespace}/pose' in metadata.read_text()):
            if time.monotonic() > deadline or recorder.poll() is not None:
                raise RuntimeError('the recorder recorded nothing: ' + recorder.communicate()[0])
            time.sleep(0.05)
        time.sleep(2.0)
        stopped_at = time.time_ns()
        target = {'node': node, 'recorder': recorder}.get(stopped)
        if target is not None:
            os.kill(target.pid, signal.SIGSTOP)
            time.sleep(stall)
            os.kill(target.pid, signal.SIGCONT)
        recorder.communicate()
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(20)
    messages = {}
    with open(bag / f'{name}.mcap', 'rb') as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            messages.setdefault(channel.topic, []).append(message)
    shutil.rmtree(bag)
    lost, onsets, pauses = {}, [], []
    for topic in [f'{namespace}/{t}' for t in STATE_TOPICS] + ['/clock']:
        records = messages.get(topic, [])
        sequences = np.array([m.sequence for m in records])
        publish = np.array([m.publish_time for m in records])
        lost[topic.rsplit('/', 1)[1]] = int(np.sum(np.diff(sequences) - 1))
        # Gaps from the stop on (a single lost sample at any time is /clock's best effort).
        at = [k for k in np.flatnonzero(np.diff(sequences) > 1) if publish[k] >= stopped_at]
        if at:
            onsets.append((publish[at[0]] - stopped_at) * 1e-6)
        if topic.endswith('/pose'):
            # The longest gap between the publish times of the pose messages received (a
            # stopped node's pause, or the messages a stopped recorder lost) and the ticks
            # published in the 50 ms after it (a catch-up burst: more than 50).
            k = int(np.argmax(np.diff(publish)))
            burst = int(np.sum((publish > publish[k + 1] - 1)
                               & (publish < publish[k + 1] + 50_000_000)))
            pauses.append((np.diff(publish)[k] * 1e-6, burst))
    return lost, (min(onsets) if onsets else None), pauses[0]


def stalls(directory, repeats, record_seconds=9.0):
    """Print the losses of the stall cases (see the module docstring, 3)."""
    profiles = {}
    deeper_queue = '\n      <port_queue_capacity>8192</port_queue_capacity>'
    for name, queue in (('segment', ''), ('queue', deeper_queue)):
        profiles[name] = directory / f'shm_{name}.xml'
        profiles[name].write_text(_SHM_PROFILE.format(queue=queue))
    xml = 'FASTRTPS_DEFAULT_PROFILES_FILE'
    cases = [
        ('no stop', None, 0.0, {}, None),
        ('node stopped 0.3 s (catch-up burst)', 'node', 0.3, {}, None),
        ('recorder stopped 0.3 s', 'recorder', 0.3, {}, None),
        ('recorder stopped 0.6 s', 'recorder', 0.6, {}, None),
        ('recorder 0.3 s, shm segment 8 MiB', 'recorder', 0.3, {xml: str(profiles['segment'])},
         None),
        ('recorder 0.3 s, shm 8 MiB + port queue 8192', 'recorder', 0.3,
         {xml: str(profiles['queue'])}, None),
        ('recorder 0.3 s, node state depth 10 (before)', 'recorder', 0.3, {}, 10),
        ('recorder 0.6 s, node state depth 10 (before)', 'recorder', 0.6, {}, 10),
    ]
    print(f'Stalls: node at {RATE:g} Hz with /clock, rigid-body-sim record for '
          f'{record_seconds:g} s, one process stopped 2 s in; {repeats} runs per case.')
    print('  lost per state topic (min-max over the 5) / lost on /clock (best effort, depth 1) '
          '@ first gap (ms after the stop) [longest gap between received pose publish times, '
          'ticks published in the 50 ms after it]')
    for number, (label, stopped, stall, extra, depth) in enumerate(cases):
        runs = []
        for repeat in range(repeats):
            lost, onset, (pause, burst) = _stall_run(directory, f'case{number}_{repeat}', stopped,
                                                     stall, extra, depth, record_seconds)
            state = [lost[t] for t in STATE_TOPICS]
            text = f'{min(state)}-{max(state)}' if min(state) != max(state) else str(min(state))
            at = f'{onset:.0f}' if onset is not None else '-'
            runs.append(f'{text}/{lost["clock"]} @{at} [{pause:.0f} ms, {burst}]')
        print(f'  {label:<44} ' + '; '.join(runs))


def main():
    """Run the measurements and print them."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=30.0,
                        help='simulated seconds per offline run (default 30)')
    parser.add_argument('--repeats', type=int, default=3, help='offline runs (default 3)')
    parser.add_argument('--record-seconds', type=float, default=30.0,
                        help='seconds of live recording (default 30)')
    parser.add_argument('--no-record', action='store_true', help='offline only')
    parser.add_argument('--stalls', action='store_true',
                        help='only the stall experiment (losses at 1 kHz; see 3. above)')
    parser.add_argument('--stall-repeats', type=int, default=2,
                        help='runs per stall case (default 2)')
    args = parser.parse_args()
    print(f'machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}')
    with tempfile.TemporaryDirectory() as directory:
        if args.stalls:
            stalls(Path(directory), args.stall_repeats)
            return
        offline(args.seconds, args.repeats, Path(directory))
        if not args.no_record:
            live(args.record_seconds, Path(directory))


if __name__ == '__main__':
    main()

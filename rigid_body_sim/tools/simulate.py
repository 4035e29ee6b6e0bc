"""
Simulate a scene faster than real time and write a rosbag2 bag of what the node publishes.

No DDS, no running node: the scene's simulator advances tick by tick at the node's rate and
each tick's state goes into the bag on the node's topics (pose, twist, angular_momentum,
odom, marker; /diagnostics every simulated second; /clock with --clock), with the node's
types, frame ids and QoS, stamped in simulated time counted from --start-time (default 0:
stamps read as simulated time; 'now' for the wall clock at start).  The bag is MCAP by
default (sqlite3 with --storage sqlite3) and plays with `ros2 bag play`, reads with rosbags
or the mcap tools, and plots with `rigid-body-sim plot`.

A scene of several bodies (bodies:, e.g. juggling_clubs) is written as the node of bodies
publishes it: each body's topics under its name (club_left/pose ...), one /tf and one
MarkerArray `markers` a tick for all of them.

Typical use:
  rigid-body-sim simulate --scene tennis_racket --duration 30
  rigid-body-sim simulate --scene juggling_clubs --duration 2 --bag clubs
  rigid-body-sim simulate --scene default --duration 60 --rate 1000 --bag t_handle_1khz
  rigid-body-sim simulate --scene default --duration 60 --bag t_handle_1khz --overwrite
  rigid-body-sim plot t_handle_1khz --out t_handle.png
"""

from __future__ import annotations

import argparse
from datetime import datetime
import math
from pathlib import Path
import sys
import time

from .compile import ensure_compiled
from .run_limits import check_duration
from .run_limits import check_rate
from .run_limits import check_substeps
from .run_limits import check_tolerance
from ..physics import INTEGRATORS
from ..physics import unresolved_rotation
from ..recording.bag_writer import STORAGES
from ..scenes import DEFAULT_SCENE
from ..scenes import load_scene
from ..text import one_line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim simulate``."""
    parser.add_argument('--scene', default=DEFAULT_SCENE,
                        help='built-in scene name (see rigid-body-sim scenes) or path to a '
                             f'.yaml file (default: {DEFAULT_SCENE})')
    parser.add_argument('--duration', type=float, required=True,
                        help='simulated time in s (a whole number of ticks, at most 2^31)')
    parser.add_argument('--rate', type=float,
                        help="tick rate in Hz, 0.1 to 10000 as the node's rate parameter "
                             "(default: the scene's)")
    parser.add_argument('--integrator',
                        help=f'one of: {", ".join(sorted(INTEGRATORS))} (default: the '
                             "scene's)")
    parser.add_argument('--substeps', type=int, default=1,
                        help='integrator steps per tick, 1 to 100000; with a tolerance the '
                             'least number (default: 1)')
    parser.add_argument('--tolerance', type=float, default=None,
                        help="error control in rad per simulated s, as the node's tolerance "
                             'parameter: each tick is split into as many substeps as keep the '
                             'orientation error added per second below it; 0: off, at most 1 '
                             "(default: the scene's)")
    parser.add_argument('--bag',
                        help='bag directory to create (default: <scene>_<date>_<time>)')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace the bag at --bag if there is one (a directory that is '
                             'not a bag is never removed)')
    parser.add_argument('--storage', choices=STORAGES, default='mcap',
                        help='storage format (default: mcap)')
    parser.add_argument('--start-time', default='0',
                        help='stamp of simulated time 0: seconds since the epoch, or "now" '
                             '(default: 0, so stamps are simulated time)')
    parser.add_argument('--clock', action='store_true',
                        help='also write /clock (rosgraph_msgs/Clock) at every tick')
    parser.add_argument('--namespace', default='',
                        help="namespace of the state topics, as the node's __ns (default: "
                             'none)')
    parser.add_argument('--frame-prefix', default=None,
                        help="put before the frame names, as the node's frame_prefix (default: "
                             "the namespace's, 'sat1/' for /sat1, as the node's)")
    parser.add_argument('--world-frame', default='world', help='world frame id (default: world)')
    parser.add_argument('--body-frame', default=None,
                        help='body frame id (default: body); a scene of bodies frames each '
                             'body by its name')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    parser.add_argument('--flush-period', type=float, default=1.0, metavar='S',
                        help='wall-clock s between flushes: killed at any moment (even kill '
                             '-9), the bag reads as it is up to the last one (default 1; 0: '
                             'only at the end)')
    parser.add_argument('--animate', nargs='?', const='', default=None, metavar='FILE',
                        help='then animate the bag (rigid-body-sim animate) into FILE, .gif '
                             'or .mp4 (default: <bag>.gif beside the bag)')
    from .animate import add_animation_options
    add_animation_options(parser, prefix='animate-')


def count_lines(counts: dict[str, int], bodies: list[str], namespace: str = '') -> list[str]:
    """
    Return the summary's lines of messages per topic: one a topic, each body's alike at once.

    A scene of bodies has five topics a body: those whose every body's count is the same are
    one line (``  <name>/pose: 200 each, 3 bodies``), the others one a topic.
    """
    prefix = '/' + namespace.strip('/') + '/' if namespace.strip('/') else '/'
    by_kind: dict[str, list[int]] = {}
    shared = []
    for topic, count in counts.items():
        name, _, kind = topic[len(prefix):].partition('/') if topic.startswith(prefix) \
            else ('', '', '')
        if name in bodies and kind and '/' not in kind:
            by_kind.setdefault(kind, []).append(count)
        else:
            shared.append(f'  {topic}: {count}')
    lines = []
    for kind, values in by_kind.items():
        if len(values) == len(bodies) and len(set(values)) == 1:
            lines.append(f'  {prefix}<name>/{kind}: {values[0]} each, {len(values)} bodies')
        else:
            lines.extend(f'  {topic}: {count}' for topic, count in counts.items()
                         if topic.startswith(prefix) and topic.endswith('/' + kind)
                         and topic[len(prefix):].partition('/')[0] in bodies)
    return lines + shared


def start_time_nanoseconds(text: str) -> int:
    """Return the --start-time value in ns since the epoch: a number of s, or 'now'."""
    if text == 'now':
        return time.time_ns()
    try:
        seconds = float(text)
    except ValueError:
        raise ValueError(f'--start-time must be seconds since the epoch or "now"; got '
                         f'{text!r}') from None
    if not 0.0 <= seconds < 2.0**31:
        raise ValueError(f'--start-time must be between 0 and 2^31 s (a stamp holds int32 '
                         f'seconds); got {text}')
    return round(seconds * 1e9)


# Beside a storage file its metadata.yaml names, what SQLite and this package's writer may
# leave: SQLite's journals, and the sqlite3 writer's second file while it writes
# (recording/bag_writer.py: <bag>_alternate.db3).
_COMPANIONS = ('-journal', '-wal', '-shm')


def _named_by_metadata(path: Path) -> list[str]:
    """Return the names metadata.yaml of the bag directory `path` lists, or raise ValueError."""
    import yaml

    metadata = path / 'metadata.yaml'
    if not metadata.is_file() or metadata.is_symlink():
        raise ValueError(f'{path} exists and is not a bag (it holds no metadata.yaml); not '
                         'replaced: give a new --bag directory')
    try:
        information = yaml.safe_load(metadata.read_text())['rosbag2_bagfile_information']
        named = [str(name) for name in information['relative_file_paths']]
    except (OSError, UnicodeDecodeError, yaml.YAMLError, KeyError, TypeError) as error:
        reason = type(error).__name__ if isinstance(error, (KeyError, TypeError)) else error
        raise ValueError(f'{path} exists and its metadata.yaml is not that of a rosbag2 bag '
                         f'({one_line(str(reason), 120)}); not replaced: give a new --bag '
                         'directory') from None
    if any(Path(name).name != name or name in ('', '.', '..') for name in named):
        raise ValueError(f'{path} exists and its metadata.yaml names files outside it; not '
                         'replaced')
    return named


def remove_bag(path: Path) -> None:
    """
    Remove the bag directory `path` (for --overwrite).

    Only a bag goes, and only what it is made of: its metadata.yaml (rosbag2's, naming its
    storage files in ``relative_file_paths``), those files, their SQLite journals and this
    package's sqlite3 writer's second file.  A directory holding anything else, or no
    metadata.yaml, is an error naming what it found, so a mistyped --bag never deletes
    other files.
    """
    if path.is_symlink() or not path.is_dir():
        raise ValueError(f'{path} exists and is not a bag directory; not replaced')
    named = _named_by_metadata(path)
    allowed = {'metadata.yaml'}
    for name in named:
        stem = name[:-len('.db3')] if name.endswith('.db3') else None
        for file in [name] + ([f'{stem}_alternate.db3'] if stem else []):
            allowed.update([file] + [file + suffix for suffix in _COMPANIONS])
    found = sorted(entry.name for entry in path.iterdir())
    foreign = [name for name in found
               if name not in allowed or not (path / name).is_file()
               or (path / name).is_symlink()]
    if foreign:
        shown = ', '.join(one_line(name, 60) for name in foreign[:3])
        more = f' and {len(foreign) - 3} more' if len(foreign) > 3 else ''
        raise ValueError(f'{path} holds what its metadata.yaml does not name ({shown}{more}); '
                         'not replaced: give a new --bag directory')
    for name in found:
        (path / name).unlink()
    path.rmdir()


def main(args: argparse.Namespace) -> int:
    """
    Run the simulation into the bag and print what was written; return 0.

    Ctrl-C (SIGINT) or SIGTERM stops the run after the batch of ticks being simulated; the
    bag is then complete up to there, and the exit code is 128 + the signal's number.
    """
    from ..recording.signals import StopOnSignals
    from ..recording.simulate import simulate_to_bag
    from ..recording.simulate_bodies import simulate_bodies_to_bag

    scene = load_scene(args.scene)
    check_duration(args.duration)
    rate = scene.rate if args.rate is None else check_rate(args.rate)
    check_substeps(args.substeps)
    if args.tolerance is not None:
        check_tolerance(args.tolerance)
    if args.integrator is not None and args.integrator not in INTEGRATORS:
        raise ValueError(f'unknown integrator {args.integrator!r}; valid: '
                         f'{", ".join(sorted(INTEGRATORS))}')
    bag = args.bag
    if bag is None:
        bag = f'{scene.name}_{datetime.now().strftime("%Y_%m_%d-%H_%M_%S")}'
    if not bag.strip():
        raise ValueError('--bag is empty: give the directory to write the bag to (a new one)')
    if Path(bag).exists():
        if not args.overwrite:
            raise ValueError(f'{one_line(bag, 200)} exists already; give a new --bag '
                             'directory, or --overwrite to replace it')
        remove_bag(Path(bag))
    start_time = start_time_nanoseconds(args.start_time)
    if not (math.isfinite(args.flush_period) and args.flush_period >= 0.0):
        raise ValueError(f'--flush-period must be a number of s >= 0; got {args.flush_period:g}')
    if scene.has_named_bodies and args.body_frame is not None:
        raise ValueError(f"--body-frame names the one body's frame; scene {scene.name!r} has "
                         f'{len(scene.bodies)} bodies, each framed by its name (and '
                         '<name>/imu): leave --body-frame out')
    tolerance = scene.tolerance if args.tolerance is None else (args.tolerance or None)
    for member in scene.members:
        warning = unresolved_rotation(member.body, member.state, 1.0 / rate, args.substeps,
                                      tolerance)
        if warning is not None:
            where = f'body {member.name!r}: ' if scene.has_named_bodies else ''
            print(f'rigid-body-sim simulate: warning: {where}{warning}', file=sys.stderr)
    ensure_compiled('simulate', [args.integrator or scene.integrator], quiet=args.quiet)
    options = {'rate': args.rate, 'integrator': args.integrator, 'substeps': args.substeps,
               'tolerance': args.tolerance, 'storage': args.storage, 'start_time': start_time,
               'clock': args.clock, 'namespace': args.namespace,
               'world_frame': args.world_frame, 'frame_prefix': args.frame_prefix,
               'progress': not args.quiet, 'flush_period': args.flush_period}
    with StopOnSignals() as signals:
        if scene.has_named_bodies:
            summary = simulate_bodies_to_bag(scene, bag, args.duration, stop=signals.stop,
                                             **options)
        else:
            summary = simulate_to_bag(scene, bag, args.duration, stop=signals.stop,
                                      body_frame=args.body_frame or 'body', **options)
    print(summary)
    for line in count_lines(summary.message_counts,
                            [member.name for member in scene.bodies], args.namespace):
        print(line)
    if signals.received is not None:
        print(f'rigid-body-sim simulate: {signals.received.name}: stopped after '
              f'{summary.duration:g} of {args.duration:g} simulated s; the bag is complete up '
              'to there', file=sys.stderr)
        return signals.exit_code
    if args.animate is not None:
        from .animate import render
        return render(bag, args.animate or None, args.animate_fps, args.animate_speed,
                      args.animate_max_size, args.namespace, quiet=args.quiet)
    return signals.exit_code

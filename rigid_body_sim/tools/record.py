"""
Record ROS 2 topics into a rosbag2 bag, without rosbag2 (default: the node's topics).

Subscribes with QoS that matches the publishers (reliable where they are, a deep keep-last
queue) and writes every message with its receive time, its publish time and its
publisher's sequence number, until Ctrl-C or SIGTERM, then finishes the bag and prints,
per topic, the messages recorded and those lost (gaps in the sequence numbers).  The bag
is flushed every --flush-period s, so a recorder killed outright (SIGKILL, power loss)
leaves a bag that rosbags and the mcap tools read up to the last flush; --recover BAG
rewrites such a bag into a complete one (index, summary, metadata.yaml), keeping the
original as BAG.orig.

A node of several bodies (a scene of bodies:) is recorded whole by default: each body's
topics under its name, found as they appear (a body spawned while recording too).

Typical use:
  rigid-body-sim record --bag run1                 the node's topics until Ctrl-C
  rigid-body-sim record --bag run2 pose twist --duration 60
  rigid-body-sim record --recover run1             after a kill -9
"""

from __future__ import annotations

import argparse
from datetime import datetime
from pathlib import Path

from ..recording.bag_writer import STORAGES


def default_record_topics(namespace: str = '') -> list[str]:
    """
    Return the topics ``record`` records by default: what the node publishes.

    Its state topics under `namespace`, /diagnostics and /clock, its imu and TF (/tf,
    /tf_static), whose types the recorder finds by discovery: what ``simulate`` writes, so
    a live bag holds the same topics.
    """
    from ..messages.tf import TF_STATIC_TOPIC
    from ..messages.tf import TF_TOPIC
    from ..recording.recorder import default_topics
    namespace = '/' + namespace.strip('/') if namespace.strip('/') else ''
    return [*default_topics(namespace), f'{namespace}/imu', TF_TOPIC, TF_STATIC_TOPIC]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim record``."""
    parser.add_argument('topics', nargs='*', metavar='TOPIC',
                        help='topics to record; relative names are under --namespace '
                             "(default: the node's pose, twist, angular_momentum, odom, "
                             'marker, imu, /diagnostics, /clock, /tf, /tf_static and, of a '
                             "node of bodies, every body's <name>/pose ... <name>/imu and "
                             'markers, a body spawned later too)')
    parser.add_argument('--bag', help='bag directory to create (default: '
                                      'rigid_body_sim_<date>_<time>)')
    parser.add_argument('--storage', choices=STORAGES, default='mcap',
                        help='storage format (default: mcap)')
    parser.add_argument('--namespace', default='',
                        help="the node's namespace (default: none)")
    parser.add_argument('--duration', type=float,
                        help='stop after this many seconds (default: at Ctrl-C/SIGTERM)')
    parser.add_argument('--depth', type=int, default=30000,
                        help='keep-last queue depth of each subscription (default: 30000, '
                             '30 s at 1 kHz: what a stalled recorder can catch up)')
    parser.add_argument('--flush-period', type=float, default=0.25,
                        help='seconds between flushes to disk (default: 0.25)')
    parser.add_argument('--no-fsync', action='store_true',
                        help='flush to the OS only (survives SIGKILL, not power loss)')
    parser.add_argument('--use-sim-time', action='store_true',
                        help='bag times from /clock instead of the reception time')
    parser.add_argument('--recover', metavar='BAG',
                        help='rewrite the bag of a killed recorder into a complete bag, '
                             'and exit')
    parser.add_argument('--force', action='store_true',
                        help='with --recover: rewrite even a complete bag')


def main(args: argparse.Namespace) -> int:
    """Record until stopped, or recover a bag; print the summary; return 0."""
    if args.recover is not None:
        from ..recording.recovery import recover_bag

        if args.topics or args.bag:
            raise ValueError('--recover takes a bag and no topics or --bag')
        print(recover_bag(args.recover, force=args.force))
        return 0
    from ..recording.recorder import record

    bag = args.bag or f'rigid_body_sim_{datetime.now().strftime("%Y_%m_%d-%H_%M_%S")}'
    if Path(bag).exists():
        raise ValueError(f'{bag} exists already; give a new --bag directory')
    topics = args.topics or default_record_topics(args.namespace)
    summary = record(bag, topics=topics, storage=args.storage,
                     namespace=args.namespace, depth=args.depth,
                     flush_period=args.flush_period, sync=not args.no_fsync,
                     use_sim_time=args.use_sim_time, duration=args.duration,
                     bodies=not args.topics)
    print(summary)
    return 0

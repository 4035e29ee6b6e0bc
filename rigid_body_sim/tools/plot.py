"""
Plot the motion in a bag of the node: angular velocity, drift of energy and |L|, orientation.

Reads the node's odom and angular_momentum topics (any bag: `rigid-body-sim simulate`,
`rigid-body-sim record`, `ros2 bag record`) and draws four panels into a PNG, against
simulated time from the scene's start: the body-frame angular velocity (a fast spin on a
scale of its own, fast oscillations as their envelope); the drift of what the scene
conserves (torque-free: 1/2 omega.L and |L|; with a pivot: the total energy, L about the
pivot along gravity and, for a symmetric body, L.e3; mass and effects come from an offline
bag's custom data); the paths of the body axes on the unit sphere; and, when the COM moves,
its path in the plane it moves in and its height z(t) with the apex, else the polhode.

Typical use:
  rigid-body-sim simulate --scene tennis_racket --duration 30 --bag racket
  rigid-body-sim plot racket                       writes racket.png beside the bag
  rigid-body-sim plot racket --out /tmp/racket.png
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim plot``."""
    parser.add_argument('bag', help='bag directory')
    parser.add_argument('--out', help='PNG file to write (default: <bag>.png beside the bag)')
    parser.add_argument('--namespace', default='',
                        help="the node's namespace in the bag (default: none)")


def main(args: argparse.Namespace) -> int:
    """Plot the bag; print the PNG's path; return 0."""
    from ..recording.plot import plot_bag

    print(plot_bag(args.bag, args.out, args.namespace))
    return 0

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

A bag of several bodies (a scene of `bodies:`, each body's topics under its name) is drawn
all in one figure: the COM paths (in the plane they move in beside their heights z(t), or in
3-D with each body's longest axis every tenth of the run), each body's largest drift so far
of what it conserves (log scale), |Omega| of each, and each body's largest drift over the
run, the worst named.  Up to 10 bodies are named in a legend; more are coloured by their
initial |Omega|; at most 100 are drawn (every k-th of more), and the title says so.
--body NAME draws that one body as a bag of one body is drawn, with what it conserves by
its own effects.

Typical use:
  rigid-body-sim simulate --scene tennis_racket --duration 30 --bag racket
  rigid-body-sim plot racket                       writes racket.png beside the bag
  rigid-body-sim plot racket --out /tmp/racket.png
  rigid-body-sim simulate --scene juggling_clubs --duration 1 --bag clubs
  rigid-body-sim plot clubs                        all three clubs: clubs.png
  rigid-body-sim plot clubs --body club_left       one club: clubs_club_left.png
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim plot``."""
    parser.add_argument('bag', help='bag directory')
    parser.add_argument('--out', help='PNG file to write (default: <bag>.png beside the bag, '
                                      '<bag>_<NAME>.png with --body)')
    parser.add_argument('--namespace', default='',
                        help="the node's namespace in the bag (default: none)")
    parser.add_argument('--body', metavar='NAME',
                        help='in a bag of several bodies, plot this one alone (default: all)')


def main(args: argparse.Namespace) -> int:
    """Plot the bag; print the PNG's path; return 0."""
    from ..recording.plot import plot_bag

    print(plot_bag(args.bag, args.out, args.namespace, args.body))
    return 0

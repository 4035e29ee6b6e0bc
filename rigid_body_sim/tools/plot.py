"""
Plot the motion in a bag of the node: angular velocity, drift of energy and |L|, orientation.

Reads the node's odom and angular_momentum topics (any bag: `rigid-body-sim simulate`,
`rigid-body-sim record`, `ros2 bag record`) and draws four panels into a PNG: the body-frame
angular velocity against time; the relative drift of the rotational kinetic energy
1/2 omega.L and of |L| (both from the messages alone: no inertia needed); the paths of the
body axes on the unit sphere; and the COM path when the COM moves, else the polhode.

Typical use:
  rigid-body-sim simulate --scene tennis_racket --duration 30 --bag racket
  rigid-body-sim plot racket                       writes racket.png beside the bag
  rigid-body-sim plot racket --out /tmp/racket.png
"""


def add_arguments(parser):
    """Add the options of ``rigid-body-sim plot``."""
    parser.add_argument('bag', help='bag directory')
    parser.add_argument('--out', help='PNG file to write (default: <bag>.png beside the bag)')
    parser.add_argument('--namespace', default='',
                        help="the node's namespace in the bag (default: none)")


def main(args):
    """Plot the bag; print the PNG's path; return 0."""
    from ..recording.plot import plot_bag

    print(plot_bag(args.bag, args.out, args.namespace))
    return 0

"""
The ``rigid_body_node`` executable: quiet about SIGINT and SIGTERM from its first moment.

Importing the node (rclpy, the DDS middleware, numba's compiled kernels) takes one to two
seconds.  A Ctrl-C in that time would otherwise end it with a KeyboardInterrupt traceback,
and a SIGTERM (``kill``, a launch file shutting down) would kill it with status -15 before
rclpy installs its own handlers.  This module imports nothing heavy: it sets both signals
to end the start-up quietly with exit code 0, then imports and runs
:func:`rigid_body_sim.ros.node.main`, where rclpy's handlers take over.
"""

import signal
import sys

__all__ = ['main']


def _interrupt(signal_number, frame):
    raise KeyboardInterrupt


def _asks_for_help(arguments):
    # Only before --ros-args: what follows it belongs to ROS.
    ours = arguments[1:arguments.index('--ros-args')] if '--ros-args' in arguments \
        else arguments[1:]
    return '-h' in ours or '--help' in ours


def main(args=None):
    """Run the node (see :func:`rigid_body_sim.ros.node.main`); return the exit code."""
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        if _asks_for_help(sys.argv if args is None else args):
            from .node_help import help_text
            print(help_text())
            return 0
        from .node import main as run_node
    except KeyboardInterrupt:
        return 0
    return run_node(args)


if __name__ == '__main__':
    sys.exit(main())

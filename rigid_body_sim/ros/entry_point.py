"""
The ``rigid_body_node`` executable: quiet about SIGINT and SIGTERM from its first statement.

Importing the node (rclpy, the DDS middleware, numba's compiled kernels) takes one to two
seconds.  A Ctrl-C in that time would otherwise end it with a KeyboardInterrupt traceback,
and a SIGTERM (``kill``, a launch file shutting down) would kill it with status -15 before
rclpy installs its own handlers.  This module imports nothing heavy, and its first statement
sets both signals to be noted (:mod:`.start_up`); :func:`main`, inside its try, makes them
raise KeyboardInterrupt from then on and ends at once if one came during the import, then
imports and runs :func:`rigid_body_sim.ros.node.main`, where rclpy's handlers take over
(chaining to this one).  A KeyboardInterrupt raised inside an extension module's
initialisation comes out as another exception (numba's ``ImportError: numba._devicearray
failed to import``), so any exception after a signal ends the start-up quietly with exit
code 0, not only KeyboardInterrupt.

What no Python program can cover is the interpreter's own start before this module's first
statement (about 50 ms on the 2-core build machine, site-packages' ``.pth`` files included):
a signal then takes its default action, as for any Python executable.
"""

import sys

from .start_up import install_signal_handlers
from .start_up import only_note_signals
from .start_up import raise_on_signals
from .start_up import signalled
from .start_up import start_up_phase

__all__ = ['main']

# The first statement that runs (the console script's first import), before anything heavy.
install_signal_handlers()
start_up_phase('handlers')


def _asks_for_help(arguments):
    # Only before --ros-args: what follows it belongs to ROS.
    ours = arguments[1:arguments.index('--ros-args')] if '--ros-args' in arguments \
        else arguments[1:]
    return '-h' in ours or '--help' in ours


def main(args=None):
    """Run the node (see :func:`rigid_body_sim.ros.node.main`); return the exit code."""
    try:
        try:
            # A signal noted since the handlers were set (during this module's import) ends
            # the start-up here; from now on one raises KeyboardInterrupt, caught below.
            raise_on_signals()
            if signalled():
                return 0
            if _asks_for_help(sys.argv if args is None else args):
                from .node_help import help_text
                print(help_text())
                return 0
            start_up_phase('imports')
            from .node import main as run_node
            return run_node(args)
        finally:
            # Python runs a signal's handler when it gets to it, which can be after the
            # node has stopped (rclpy acts on the signal first, in its own thread): from
            # here a late one is only noted, so it cannot escape past this function.
            only_note_signals()
    except BaseException:
        # The signal's KeyboardInterrupt, or what an import made of it: a clean stop.
        if signalled():
            return 0
        raise


if __name__ == '__main__':
    sys.exit(main())

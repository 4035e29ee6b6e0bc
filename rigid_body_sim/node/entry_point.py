"""
The ``rigid_body_node`` executable: quiet about SIGINT and SIGTERM from its first statement.

This module imports nothing heavy, and its first statement sets both signals to be noted;
the rest (the imports, rclpy, the node, its spin and shutdown) is :mod:`.process`'s, which
holds the start-up and signal handling of the node's process in one place.
"""

import sys

from .process import install_signal_handlers
from .process import main
from .process import start_up_phase

__all__ = ['main']

# The first statement that runs (the console script's first import), before anything heavy.
install_signal_handlers()
start_up_phase('handlers')


if __name__ == '__main__':
    sys.exit(main())

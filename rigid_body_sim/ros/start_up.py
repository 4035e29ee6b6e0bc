"""
The node's start-up: signals that end it quietly, and a trace of its phases.

Kept apart from :mod:`.entry_point` so that one module holds this state however the node is
started (``rigid_body_node``, or ``python -m rigid_body_sim.ros.entry_point``, where the
entry point runs as ``__main__`` and a second import of it would hold a second state).

RIGID_BODY_SIM_TRACE_START_UP=1 prints a line to stderr as each phase of the start-up
begins (handlers, imports, rclpy.init, node, spin), so that a test can send a signal in
every phase by waiting for its line, whatever the machine's speed.
"""

import os
import signal
import sys

__all__ = ['install_signal_handlers', 'signalled', 'start_up_phase']

_TRACE = os.environ.get('RIGID_BODY_SIM_TRACE_START_UP') == '1'
# The signals that arrived: an exception that follows one is its consequence.
_received = []


def _interrupt(signal_number, frame):
    _received.append(signal_number)
    raise KeyboardInterrupt


def install_signal_handlers():
    """Make SIGINT and SIGTERM raise KeyboardInterrupt and note that they came."""
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, _interrupt)


def signalled():
    """Return whether SIGINT or SIGTERM has arrived since the handlers were installed."""
    return bool(_received)


def start_up_phase(name):
    """Note that a phase of the start-up begins (printed only when tracing is asked for)."""
    if _TRACE:
        print(f'start-up phase: {name}', file=sys.stderr, flush=True)

"""
The node's start-up: signals that end it quietly, and a trace of its phases.

Kept apart from :mod:`.entry_point` so that one module holds this state however the node is
started (``rigid_body_node``, or ``python -m rigid_body_sim.ros.entry_point``, where the
entry point runs as ``__main__`` and a second import of it would hold a second state).

RIGID_BODY_SIM_TRACE_START_UP=1 prints a line to stderr as each phase of the start-up
begins (handlers, imports, rclpy.init, node, spin), so that a test can send a signal in
every phase by waiting for its line, whatever the machine's speed.
"""

import contextlib
import os
import signal
import sys

__all__ = ['install_signal_handlers', 'only_note_signals', 'raise_on_signals',
           'signals_deferred', 'signalled', 'start_up_phase']

_TRACE = os.environ.get('RIGID_BODY_SIM_TRACE_START_UP') == '1'
# The signals that arrived: an exception that follows one is its consequence.
_received = []
# Whether a signal raises KeyboardInterrupt: not before the caller can catch it (the rest
# of the entry point's own import, where only noting it is safe).
_raising = []


def _interrupt(signal_number, frame):
    _received.append(signal_number)
    if _raising:
        raise KeyboardInterrupt


def install_signal_handlers():
    """Make SIGINT and SIGTERM noted (and, after raise_on_signals(), raise KeyboardInterrupt)."""
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, _interrupt)


def raise_on_signals():
    """From now on a signal raises KeyboardInterrupt (call it inside a try that catches it)."""
    _raising.append(True)


def only_note_signals():
    """From now on a signal is only noted again (the end: nothing left to interrupt)."""
    _raising.clear()


@contextlib.contextmanager
def signals_deferred():
    """
    Only note signals inside the block; raise KeyboardInterrupt after it if one came.

    For constructors that a KeyboardInterrupt would leave half-built (rclpy's executor then
    prints a traceback from its __del__).
    """
    raising = bool(_raising)
    _raising.clear()
    before = len(_received)
    try:
        yield
    finally:
        if raising:
            _raising.append(True)
    if raising and len(_received) > before:
        raise KeyboardInterrupt


def signalled():
    """Return whether SIGINT or SIGTERM has arrived since the handlers were installed."""
    return bool(_received)


def start_up_phase(name):
    """Note that a phase of the start-up begins (printed only when tracing is asked for)."""
    if _TRACE:
        print(f'start-up phase: {name}', file=sys.stderr, flush=True)

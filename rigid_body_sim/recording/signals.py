"""
SIGINT (Ctrl-C) and SIGTERM as a request to stop, not an exception.

A long run that writes a bag (``rigid-body-sim simulate``, ``rigid-body-sim record``) checks a
stop flag between two pieces of work and then finishes the bag (summary, index,
``metadata.yaml``).  Python's default turns SIGINT into a KeyboardInterrupt at whatever line
runs, possibly in the middle of writing a record, and SIGTERM ends the process at once,
leaving a bag without its end; here both only set the flag.
"""

import signal
import threading

__all__ = ['StopOnSignals']

_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopOnSignals:
    """
    A context in which SIGINT and SIGTERM set `stop` (a threading.Event) and nothing else.

    Signal handlers can only be set in the main thread: elsewhere the context changes
    nothing and only `stop` (set by the caller) stops the work.  The handlers in place
    before are restored on exit.

    Attributes
    ----------
    stop : threading.Event
        Set by the first SIGINT or SIGTERM.
    received : signal.Signals or None
        The last signal received, if any.

    """

    def __init__(self, stop=None):
        self.stop = stop if stop is not None else threading.Event()
        self.received = None
        self._previous = {}

    def __enter__(self):
        self.install()
        return self

    def __exit__(self, exc_type, exc_value, traceback):
        self.restore()
        return False

    def install(self):
        """Set the handlers (in the main thread; elsewhere nothing happens)."""
        if threading.current_thread() is threading.main_thread() and not self._previous:
            for number in _SIGNALS:
                self._previous[number] = signal.signal(number, self._handle)

    def restore(self):
        """Put back the handlers that were in place before :meth:`install`."""
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        self._previous.clear()

    def _handle(self, number, frame):
        self.received = signal.Signals(number)
        self.stop.set()

    @property
    def exit_code(self):
        """Return 128 + the signal's number (the shell's convention), or 0 if none came."""
        return 0 if self.received is None else 128 + int(self.received)

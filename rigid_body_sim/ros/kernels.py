"""
The integrators' compiled kernels, as the node gets them: compiled in a process of their own.

A kernel not compiled yet (a colcon install not followed by ``rigid-body-sim compile``, an
edited source) takes seconds to minutes to compile (about
:data:`rigid_body_sim.physics.warm_up.COMPILE_SECONDS`, several times that on a loaded
machine), and the process compiling it runs no other Python meanwhile: in the node's process
its services, inputs, timers and signals would wait that long.  So the node asks
:func:`kernels_compiled` first; if they are not, a :class:`BackgroundCompilation` runs
``python -m rigid_body_sim.cli compile NAME --quiet`` beside it, the node polls it from a
timer, and loads the kernels numba cached (tens of milliseconds) once it succeeded.

``RIGID_BODY_SIM_ASSUME_UNCOMPILED`` (a test hook, read by the node only): a comma-separated
list of integrators the node takes for not compiled whatever the cache holds, so that a test
sees the background path with the cache that the set-up filled.
"""

import os
import subprocess
import sys
import tempfile
import time

from .text import shortened
from ..physics.warm_up import compile_estimate
from ..physics.warm_up import COMPILE_SECONDS
from ..physics.warm_up import is_compiled

__all__ = ['ASSUME_UNCOMPILED', 'BackgroundCompilation', 'kernels_compiled']

ASSUME_UNCOMPILED = 'RIGID_BODY_SIM_ASSUME_UNCOMPILED'
"""Environment variable (test hook): integrators taken for not compiled, comma-separated."""


def kernels_compiled(name):
    """Return whether the kernels of integrator `name` load from the cache (see above)."""
    if name in os.environ.get(ASSUME_UNCOMPILED, '').split(','):
        return False
    return is_compiled(name)


class BackgroundCompilation:
    """
    ``rigid-body-sim compile NAME --quiet`` in a child process; :meth:`poll` for its end.

    Attributes
    ----------
    name : str
        The integrator whose kernels it compiles.
    estimate : float
        About how many seconds it takes (on the reference machine).

    """

    def __init__(self, name):
        self.name = name
        # (Under the test hook the cache has them: the reference machine's figure.)
        self.estimate = compile_estimate([name]) or COMPILE_SECONDS.get(name, 10.0)
        self._started = time.monotonic()
        self._output = tempfile.TemporaryFile()
        self._process = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.cli', 'compile', name, '--quiet'],
            stdin=subprocess.DEVNULL, stdout=self._output, stderr=subprocess.STDOUT)

    def poll(self):
        """
        Return None while it runs; then (succeeded, what happened) once.

        What happened is the time it took, or why it failed (its last line of output,
        shortened).
        """
        code = self._process.poll()
        if code is None:
            return None
        elapsed = time.monotonic() - self._started
        if code == 0:
            self._close()
            return True, f'compiled in {elapsed:.1f} s'
        self._output.seek(0)
        lines = [line for line in self._output.read().decode(errors='replace').splitlines()
                 if line.strip()]
        self._close()
        reason = shortened(lines[-1]) if lines else 'no output'
        return False, f'exit code {code} after {elapsed:.1f} s: {reason}'

    def stop(self):
        """End the child process (its compiled kernels so far stay cached)."""
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(5.0)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        self._close()

    def _close(self):
        if not self._output.closed:
            self._output.close()

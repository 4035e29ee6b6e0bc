"""
The integrators' compiled kernels, as the node gets them: compiled in a process of their own.

A kernel not compiled yet on this machine (a fresh install, an edited source) takes tens of
seconds to compile (``rigid-body-sim compile`` prints each job's time), and the process
compiling it runs no other Python meanwhile: in the node's process its services, inputs,
timers and signals would wait that long.  So the node asks :func:`kernels_compiled` first;
if they are not, a :class:`BackgroundCompilation` runs ``python -m rigid_body_sim.cli compile
NAME --quiet`` beside it (at a lower priority: the node comes first), the node integrates
with the kernels' source interpreted meanwhile (kernels/interpreted.py), polls the compile
from a timer, and loads the kernels it cached (tens of milliseconds) once it succeeded.  A
damaged cache file is the compile's to find and replace, never the node's to load.

``RIGID_BODY_SIM_ASSUME_UNCOMPILED`` (a test hook, read by the node only): a comma-separated
list of integrators the node takes for not compiled whatever the cache holds, so that a test
sees the background path with the cache that the set-up filled.
"""

import os
import subprocess
import sys
import tempfile
import time

from ..physics.warm_up import compile_estimate
from ..physics.warm_up import is_compiled
from ..physics.warm_up import job_estimate
from ..physics.warm_up import jobs_of
from ..text import shortened

__all__ = ['ASSUME_UNCOMPILED', 'BackgroundCompilation', 'compile_seconds', 'kernels_compiled',
           'NICENESS']

ASSUME_UNCOMPILED = 'RIGID_BODY_SIM_ASSUME_UNCOMPILED'
"""Environment variable (test hook): integrators taken for not compiled, comma-separated."""
NICENESS = 10
"""How much lower the compile's CPU priority is than the node's (nice(2) increment)."""


def kernels_compiled(name):
    """Return whether the kernels of integrator `name` load from the cache (see above)."""
    if name in os.environ.get(ASSUME_UNCOMPILED, '').split(','):
        return False
    return is_compiled(name)


def compile_seconds(name):
    """
    Return about how many seconds compiling the kernels of integrator `name` takes here.

    The registry's estimate (:func:`~rigid_body_sim.physics.warm_up.compile_estimate`: what
    each job took here, else its declared time on the reference machine), for this
    machine's workers; under the test hook (the cache has them) its longest job.
    """
    return compile_estimate([name], _workers()) or max(
        job_estimate(job) for job in jobs_of([name]))


def _workers():
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def _lower_priority():
    os.nice(NICENESS)


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
        self.estimate = compile_seconds(name)
        self._started = time.monotonic()
        self._output = tempfile.TemporaryFile()
        self._process = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.cli', 'compile', name, '--quiet'],
            stdin=subprocess.DEVNULL, stdout=self._output, stderr=subprocess.STDOUT,
            preexec_fn=_lower_priority)

    def elapsed(self):
        """Return the seconds since it started."""
        return time.monotonic() - self._started

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

"""
The kernels of a sweep, made usable once per process (compiled first, once per machine).

A worker runs many simulations in one process: it loads the kernels of the sweep's
integrators when it starts (:class:`rigid_body_sim.sweep.engine.KernelPlugin` calls
:func:`ready`), and each run finds them loaded.  On a machine that never compiled them,
the first worker compiles them in a process of its own (``rigid-body-sim compile``, under
the machine-wide compile lock: the other workers of that machine wait for it and then load
what it cached); no run ever compiles.
"""

import os
import subprocess
import sys
import threading
import time

from ..physics import warm_up
from ..physics.kernels import cache

__all__ = ['loaded', 'ready']

_lock = threading.Lock()
_loaded = set()


def ready(integrators):
    """
    Load the kernels of `integrators` into this process once; return the seconds it took.

    0 when they were loaded already.  What this machine has not compiled is compiled
    first, in a compile process of its own (a one-line note on stderr says so).
    """
    with _lock:
        todo = [name for name in integrators if name not in _loaded]
        if not todo:
            return 0.0
        started = time.perf_counter()
        if warm_up.missing(todo):
            _compile(todo)
        for name in todo:
            warm_up.load_kernels(name)
            _loaded.add(name)
        return time.perf_counter() - started


def loaded():
    """Return the integrators whose kernels this process has loaded."""
    with _lock:
        return sorted(_loaded)


def _compile(integrators):
    """Compile what `integrators` lack with the compile command, in a process of its own."""
    if cache.PROBLEM is not None:
        # No cache to share: numba compiles in this process what it runs, once.
        return
    cores = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else 1
    print(f'rigid-body-sim sweep: compiling the {", ".join(integrators)} kernels for their '
          'first use on this machine (about '
          f'{warm_up.compile_estimate(integrators, cores):.0f} s, once)', file=sys.stderr,
          flush=True)
    # The command, not its function: a damaged cache file that aborts LLVM takes down the
    # compile process, not this worker; it holds the machine's compile lock, so the other
    # workers here wait for it and then load what it cached.
    subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'compile', *integrators,
                    '--quiet'], stdout=sys.stderr, check=False)
    warm_up.forget_verification()

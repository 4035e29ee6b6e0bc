"""
The kernels of a sweep, made usable once per process (compiled first, once per machine).

A worker runs many simulations in one process: it loads the kernels of the sweep's
integrators when it starts (:class:`rigid_body_sim.sweep.engine.KernelPlugin` calls
:func:`ready`), and each run finds them loaded.  On a machine that never compiled them,
the first worker compiles them in a process of its own (``rigid-body-sim compile``, under
the machine-wide compile lock: the other workers of that machine wait for it and then load
what it cached); no run ever compiles.
"""

import threading
import time

from ..physics import warm_up
from ..tools.compile import ensure_compiled

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
            ensure_compiled('sweep', todo, quiet=True)
        for name in todo:
            warm_up.load_kernels(name)
            _loaded.add(name)
        return time.perf_counter() - started


def loaded():
    """Return the integrators whose kernels this process has loaded."""
    with _lock:
        return sorted(_loaded)

"""
Compile every integrator's numba kernels now, so that no later run waits for it.

The compiled kernels are cached beside the package (``__pycache__``): from an empty cache
they take about a minute on a 2-core machine (each integrator 1-25 s), and every later run
loads them in a fraction of a second.  A source that changed drops the cache (its kernels
are compiled again: never a stale one).  The set-up (``make venv``, so ``make run`` and
``make test``) runs this once; a colcon build does not (run
``ros2 run rigid_body_sim rigid-body-sim compile`` after it).
"""

import time

from ..physics import INTEGRATORS
from ..physics.warm_up import COMPILE_SECONDS
from ..physics.warm_up import is_compiled
from ..physics.warm_up import warm_up


def add_arguments(parser):
    """Add the options of ``rigid-body-sim compile``."""
    parser.add_argument('integrators', nargs='*', metavar='INTEGRATOR',
                        help=f'compile only these (default: all of '
                             f'{", ".join(sorted(INTEGRATORS))})')
    parser.add_argument('--quiet', action='store_true',
                        help='print nothing but errors (the set-up uses it)')


def main(args):
    """Compile the kernels, printing each integrator's time; return 0 (2: an unknown name)."""
    unknown = sorted(set(args.integrators) - set(INTEGRATORS))
    if unknown:
        print(f'rigid-body-sim compile: error: unknown integrator(s) {", ".join(unknown)}; '
              f'valid: {", ".join(sorted(INTEGRATORS))}')
        return 2
    names = args.integrators or sorted(INTEGRATORS)
    started = time.monotonic()
    compiled = 0
    for name in names:
        if is_compiled(name):
            if not args.quiet:
                print(f'  {name:12s} already compiled', flush=True)
            continue
        if not args.quiet:
            print(f'  {name:12s} compiling (about {COMPILE_SECONDS.get(name, 10.0):.0f} s) ...',
                  end='', flush=True)
        seconds = warm_up(name)
        compiled += 1
        if not args.quiet:
            print(f' {seconds:.1f} s', flush=True)
    if not args.quiet:
        print(f'compiled the kernels of {compiled} integrator(s) in '
              f'{time.monotonic() - started:.1f} s (cached for later runs)')
    return 0

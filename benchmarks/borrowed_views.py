#!/usr/bin/env python3
"""
Print what the borrowed array views save per step: the kernels with and without them.

Usage: .venv/bin/python benchmarks/borrowed_views.py [--steps N] [--repeats K] [--rounds R]
       [--machine-cache] [--keep-cache] [NAME ...]

physics/kernels/borrow.py passes the Model's arrays and the state down a kernel without a
reference (a borrowed view); ``RIGID_BODY_SIM_BORROW=0`` compiles the same kernels with
plain, reference-counted arrays.  The kernel cache's key does not see that switch, so each
variant compiles into a kernel cache of its own (RIGID_BODY_SIM_CACHE_DIR, a fresh temporary
folder; ``--machine-cache``: the borrowing variant uses the machine's cache instead, as a
user's run does).  Each variant first compiles what NAME ... need (``rigid-body-sim compile
NAME ... --quiet`` in its environment, not timed), then a child process per variant and
round times them with benchmarks/step_cost.py's function: the default T-handle body,
torque-free and under a held body-frame torque, warmed up, CPU time of that child
(time.process_time: the machine may be loaded), the median over K repeats:

- run: N steps in one Simulator.run call (the offline tools; the view is made once a call);
- step(): one Simulator.step call per step, as the node ticks (N / 10 calls; the views are
  made at each call).

The two variants alternate R rounds (with, without, with, ...); the table gives the median
over the rounds, in microseconds per step, and the saving: (without - with) / without, the
share of the reference-counted step that borrowing removes (the range is over the rounds,
each round's two children paired).  The views are worth their numba-specific code only if
that share is at least 10 % on the path they sit on (the issue's rule).

NAME ... are the integrators to time (default: buss rk4 splitting).  A child that had to
compile anything after the compile step says so (it is then not timed on what was asked).
"""

import argparse
import importlib.util
import json
import os
from pathlib import Path
import shutil
import statistics
import subprocess
import sys
import tempfile

DEFAULT_NAMES = ('buss', 'rk4', 'splitting')
VARIANTS = (('with', '1'), ('without', '0'))
"""(label, RIGID_BODY_SIM_BORROW) of the two variants, in the order each round runs them."""
PATHS = (('run', False), ('step()', True))
"""(label, per_call) of the paths timed: one run call, one step() call per step."""
THRESHOLD = 10.0
"""The saving (% of the step) below which the views are not worth keeping."""
HERE = Path(__file__).resolve().parent


def _package_root():
    """Return the folder holding the rigid_body_sim this interpreter imports (not importing it)."""
    spec = importlib.util.find_spec('rigid_body_sim')
    if spec is None or spec.origin is None:
        raise SystemExit('borrowed_views.py: rigid_body_sim is not importable here')
    return Path(spec.origin).resolve().parent.parent


def _environment(borrow, cache_dir):
    """Return the environment of a child: this checkout first, the switch, its cache."""
    environment = dict(os.environ)
    root = str(_package_root())
    path = environment.get('PYTHONPATH')
    environment['PYTHONPATH'] = root if not path else os.pathsep.join((root, path))
    environment['RIGID_BODY_SIM_BORROW'] = borrow
    if cache_dir is None:
        environment.pop('RIGID_BODY_SIM_CACHE_DIR', None)
    else:
        environment['RIGID_BODY_SIM_CACHE_DIR'] = str(cache_dir)
    return environment


def _compile(names, environment):
    """Compile the kernels of `names` in `environment` (not timed); exit if it fails."""
    result = subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'compile', *names,
                             '--quiet'], env=environment, check=False)
    if result.returncode != 0:
        raise SystemExit(f'borrowed_views.py: the compile of {" ".join(names)} failed '
                         f'(exit {result.returncode})')


def _measure(names, steps, repeats, environment):
    """Run a timing child in `environment`; return its report (see :func:`_child`)."""
    result = subprocess.run([sys.executable, str(Path(__file__).resolve()), '--child',
                             '--steps', str(steps), '--repeats', str(repeats), *names],
                            env=environment, check=True, capture_output=True, text=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def _child(names, steps, repeats):
    """Time `names` in this process; print one JSON line: the switch, the cache, the times."""
    spec = importlib.util.spec_from_file_location('step_cost', HERE / 'step_cost.py')
    step_cost = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(step_cost)
    from rigid_body_sim.physics import warm_up
    from rigid_body_sim.physics.kernels import borrow
    from rigid_body_sim.physics.kernels import cache
    missing = warm_up.missing(list(names))
    times = {}
    for name in names:
        for label, per_call in PATHS:
            for torque in (False, True):
                count = max(steps // 10, 1000) if per_call else steps
                cost = step_cost.microseconds_per_step(name, count, repeats, True, torque,
                                                       per_call)
                times[f'{name}|{label}|{"torque" if torque else "free"}'] = cost
    print(json.dumps({'borrowing': borrow.borrowing, 'kernel_dir': str(cache.kernel_dir()),
                      'missing': missing, 'times': times}))


def _saving(without, with_):
    return (without - with_) / without * 100.0


def main():
    """Compile both variants, time them in alternation, print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=200000,
                        help='steps per timed run (step(): a tenth, one call each)')
    parser.add_argument('--repeats', type=int, default=5, help='timed runs per cell and child')
    parser.add_argument('--rounds', type=int, default=3,
                        help='alternations of the two variants (one child each)')
    parser.add_argument('--machine-cache', action='store_true',
                        help="the borrowing variant uses the machine's kernel cache, not a "
                             'fresh one')
    parser.add_argument('--keep-cache', action='store_true',
                        help='keep the temporary kernel caches (their paths are printed)')
    parser.add_argument('--child', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('names', nargs='*', metavar='NAME',
                        help=f'integrators to time (default: {" ".join(DEFAULT_NAMES)})')
    args = parser.parse_args()
    names = tuple(args.names) or DEFAULT_NAMES
    if args.child:
        _child(names, args.steps, args.repeats)
        return 0
    if args.steps < 1 or args.repeats < 1 or args.rounds < 1:
        parser.error('--steps, --repeats and --rounds must be at least 1')

    root = Path(tempfile.mkdtemp(prefix='rigid_body_sim-borrowed-views-'))
    caches = {'with': None if args.machine_cache else root / 'with', 'without': root / 'without'}
    environments = {label: _environment(borrow, caches[label]) for label, borrow in VARIANTS}
    try:
        for label, _ in VARIANTS:
            print(f'compiling {" ".join(names)} {label} borrowed views into '
                  f'{caches[label] or "the machine cache"} ...', file=sys.stderr, flush=True)
            _compile(names, environments[label])
        samples = {label: [] for label, _ in VARIANTS}
        for round_ in range(args.rounds):
            for label, _ in VARIANTS:
                report = _measure(names, args.steps, args.repeats, environments[label])
                if report['borrowing'] != (label == 'with'):
                    raise SystemExit(f'borrowed_views.py: the {label} child reports borrowing='
                                     f'{report["borrowing"]}')
                if report['missing']:
                    print(f'note: the {label} child found {", ".join(report["missing"])} not '
                          'compiled (compiled in its warm-up, not timed)', file=sys.stderr)
                samples[label].append(report['times'])
                print(f'round {round_ + 1}/{args.rounds}: {label} borrowed views timed '
                      f'({report["kernel_dir"]})', file=sys.stderr, flush=True)
    finally:
        if args.keep_cache:
            print(f'kept the temporary kernel caches in {root}', file=sys.stderr)
        else:
            shutil.rmtree(root, ignore_errors=True)

    print(f'{"integrator":<12}{"path":<16}{"with":>10}{"without":>10}{"saving":>10}'
          f'{"range":>18}   (CPU us/step, median of {args.rounds} rounds x {args.repeats}; '
          'saving = (without - with) / without)')
    largest = None
    for name in names:
        for label, _ in PATHS:
            for kind in ('free', 'torque'):
                key = f'{name}|{label}|{kind}'
                with_ = statistics.median(times[key] for times in samples['with'])
                without = statistics.median(times[key] for times in samples['without'])
                saving = _saving(without, with_)
                paired = [_saving(b[key], a[key])
                          for a, b in zip(samples['with'], samples['without'])]
                spread = f'{min(paired):.1f} .. {max(paired):.1f} %'
                print(f'{name:<12}{f"{label}, {kind}":<16}{with_:>10.3f}{without:>10.3f}'
                      f'{saving:>8.1f} %{spread:>18}')
                if largest is None or saving > largest[0]:
                    largest = (saving, name, f'{label}, {kind}')
    saving, name, path = largest
    verdict = 'at least' if saving >= THRESHOLD else 'under'
    print(f'largest saving: {saving:.1f} % of the step ({name}, {path}): {verdict} the '
          f'{THRESHOLD:.0f} % a numba-specific optimisation must save to be kept')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

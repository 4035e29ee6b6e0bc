"""
Compile the integrators' numba kernels now, in parallel, so that no later run waits for them.

The kernels are cached once per machine, by the content of the sources they are compiled
from and the CPU (not by where the package sits: a second clone or a colcon install finds
them compiled); --where prints the folder, --clear empties it.  A kernel is compiled by
jobs (shared, controller, one run kernel per method), in as many processes as there are
cores (--jobs); each job's time is printed and kept, and later estimates use it.  A cached
file found damaged is dropped and compiled again; two compiles of the same kernels at once
do the work once (the second waits).  The set-up (`make test`) runs this; the node and
`simulate` run it in a process of their own when they need it.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from collections.abc import Iterable
import concurrent.futures
import multiprocessing
import os
import subprocess
import sys
import time
from typing import TextIO

from ..physics import INTEGRATORS
from ..physics import warm_up
from ..physics.kernels import cache

__all__ = ['add_arguments', 'main', 'announce_compile', 'ensure_compiled', 'SOURCES_CHANGED']

SOURCES_CHANGED = 3
"""Exit code of a compile whose sources changed while it ran (nothing of it is kept)."""


class _SourcesChanged(Exception):
    pass


def _workers(requested: int | None) -> int:
    if requested:
        return max(1, requested)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def announce_compile(command: str, integrators: Iterable[str],
                     stream: TextIO | None = None) -> None:
    """
    Say, in one line, which kernels a command is about to compile and about how long.

    Nothing when they are compiled; otherwise the user hears why the command waits.
    """
    waiting = warm_up.missing(integrators)
    if waiting:
        seconds = warm_up.compile_estimate(waiting, _workers(None))
        print(f'rigid-body-sim {command}: compiling the {", ".join(waiting)} kernel(s) for '
              f'their first use on this machine (about {seconds:.0f} s, once; '
              '`rigid-body-sim compile` does them all)', file=stream or sys.stderr, flush=True)


def ensure_compiled(command: str, integrators: Iterable[str], quiet: bool = False) -> int:
    """
    Compile what `integrators` need, if anything, in a process of its own; return its code.

    In parallel processes, and in another process than this one: a damaged cache file
    cannot take this one down (LLVM aborts on a corrupt object file); the compile drops it
    and compiles it again.  One line says what and how long; the compile's progress follows
    on stderr unless `quiet`.  If it fails, this process compiles what it runs itself.
    """
    if cache.PROBLEM is not None:
        print(cache.PROBLEM, file=sys.stderr, flush=True)
        return 0
    if not warm_up.missing(integrators):
        return 0
    announce_compile(command, integrators)
    result = subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'compile',
                             *integrators, *(['--quiet'] if quiet else [])],
                            stdout=sys.stderr, check=False)
    warm_up.forget_verification()
    return result.returncode


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim compile``."""
    parser.add_argument('integrators', nargs='*', metavar='INTEGRATOR',
                        help=f'compile only what these need (default: all of '
                             f'{", ".join(sorted(INTEGRATORS))})')
    parser.add_argument('--jobs', type=int, default=0, metavar='N',
                        help='compile in N processes (default: one per core)')
    parser.add_argument('--quiet', action='store_true',
                        help='print nothing but errors (the set-up uses it)')
    parser.add_argument('--where', action='store_true',
                        help='print the folder the kernels of these sources are cached in, '
                             'and exit')
    parser.add_argument('--clear', action='store_true',
                        help='remove every cached kernel folder (all sources, all CPUs) and '
                             'exit')


def _worker(job: str, sources: str) -> float:
    """Compile `job` in a worker process; return its CPU seconds."""
    # The worker read the sources when it started: if they are not those of the compile
    # it works for, what it compiles is not what will be marked.
    if cache.SOURCES != sources:
        raise _SourcesChanged()
    return warm_up.compile_job(job)


def _run_jobs(jobs: Iterable[str], workers: int,
              say: Callable[[str], None]) -> dict[str, float]:
    """Compile `jobs`, longest first, in `workers` processes; return job -> CPU seconds."""
    ordered = sorted(jobs, key=warm_up.job_estimate, reverse=True)
    seconds = {}
    if workers == 1 or len(ordered) == 1:
        for job in ordered:
            seconds[job] = warm_up.compile_job(job)
            say(f'  {job:16s} {seconds[job]:6.1f} s')
        return seconds
    context = multiprocessing.get_context('spawn')
    with concurrent.futures.ProcessPoolExecutor(min(workers, len(ordered)),
                                                mp_context=context) as pool:
        futures = {pool.submit(_worker, job, cache.SOURCES): job for job in ordered}
        try:
            for future in concurrent.futures.as_completed(futures):
                job = futures[future]
                seconds[job] = future.result()
                say(f'  {job:16s} {seconds[job]:6.1f} s')
        except BaseException:
            for future in futures:
                future.cancel()
            raise
    return seconds


def main(args: argparse.Namespace) -> int:
    """Compile the kernels; return 0 (1: cannot cache, 2: unknown name, 3: sources changed)."""
    unknown = sorted(set(args.integrators) - set(INTEGRATORS))
    if unknown:
        print(f'rigid-body-sim compile: error: unknown integrator(s) {", ".join(unknown)}; '
              f'valid: {", ".join(sorted(INTEGRATORS))}')
        return 2

    def say(line: str) -> None:
        if not args.quiet:
            print(line, flush=True)

    if args.clear:
        removed = cache.clear()
        print(f'removed {removed} cached kernel folder(s) from {cache.cache_root()}')
        return 0
    if args.where:
        print(cache.kernel_dir())
        return 0
    if cache.PROBLEM is not None:
        print(cache.PROBLEM, file=sys.stderr)
        return 1
    names = args.integrators or sorted(INTEGRATORS)
    jobs = warm_up.jobs_of(names)
    started = time.monotonic()
    with cache.compile_lock(waiting=lambda folder: say(
            'waiting for another compile of these kernels to finish ...')) as folder:
        damaged = cache.verify(folder)
        if damaged:
            print(f'rigid-body-sim compile: {len(damaged)} cached kernel file(s) damaged '
                  f'({damaged[0]}, in {folder}): dropped, compiling them again',
                  file=sys.stderr, flush=True)
            cache.drop(damaged, folder)
        warm_up.forget_verification()
        todo = warm_up.missing_jobs(jobs)
        if not todo:
            for name in names:
                say(f'  {name:12s} already compiled')
            return 0
        workers = _workers(args.jobs)
        say(f'compiling {len(todo)} kernel job(s) for {", ".join(names)} in '
            f'{min(workers, len(todo))} process(es), about '
            f'{warm_up.compile_estimate(names, workers):.0f} s, into {folder}')
        try:
            seconds = _run_jobs(todo, workers, say)
        except _SourcesChanged:
            seconds = None
        except concurrent.futures.process.BrokenProcessPool:
            # A worker died: killed, or aborted by LLVM on a damaged file written since the
            # last seal.  What was not sealed goes; the next compile starts from the rest.
            cache.drop_unsealed(folder)
            print('rigid-body-sim compile: a compile process ended abruptly: the files it '
                  'may have left are dropped; run it again', file=sys.stderr)
            return 1
        if seconds is None or cache.source_key() != cache.SOURCES:
            cache.drop_unsealed(folder)
            print('rigid-body-sim compile: the sources changed while compiling: nothing of '
                  'this compile is kept; run it again', file=sys.stderr)
            return SOURCES_CHANGED
        cache.seal(folder)
        for job, cpu in seconds.items():
            cache.mark(job, cpu, folder)
        warm_up.forget_verification()
    cache.touch_used(folder)
    cache.prune()
    say(f'compiled {len(seconds)} job(s) in {time.monotonic() - started:.1f} s '
        f'({sum(seconds.values()):.1f} s of CPU); cached for every later run on this machine')
    return 0

"""
The engine: many independent tasks on a Dask cluster, each worker loading the kernels once.

:class:`Engine` starts a ``distributed.LocalCluster`` of one single-threaded worker process
per core, or connects to the cluster at a scheduler address (or the one Dask's own
configuration names, ``scheduler-address``); every worker, also one that joins later, runs
:class:`KernelPlugin` once when it starts: it loads the numba kernels the work needs
(compiling them first if its machine never did, once per machine).  :meth:`Engine.run_each`
then runs a function over items on the workers and yields each item's outcome as it
arrives: the result, where it ran (host, worker, process) or the error.

Tasks.  Items go to the workers in tasks of a few items each, sized as they go so that a
task takes about `target_seconds` (the first are single items: their cost sets the size),
which keeps the scheduler's cost per task (about a millisecond) small against the work
however cheap an item is; at most about two tasks per worker thread are out at once, so a
stop leaves little to cancel and a sweep of any size keeps a small footprint in the driver.
A task's key is a digest of its items' keys: the same work has the same name on the
cluster.

Failures.  A worker that dies (killed, out of memory) takes its tasks with it; the
scheduler gives them to other workers (a task that kills ``distributed.scheduler.
allowed-failures`` + 1 workers is given up: an error outcome).  A result that reached the
driver is never lost, and each item's outcome is yielded once.

A stop (an event set, e.g. by Ctrl-C) cancels what is out and ends the iteration.  The
worker processes of a local cluster ignore SIGINT: Ctrl-C in a terminal reaches every
process of the foreground group, and the driver, not each worker, decides what it means.
"""

import asyncio
from collections import deque
from dataclasses import dataclass
import hashlib
import itertools
import logging
import math
import os
import queue
import signal
import socket
import threading
import time

import dask.config
from distributed import Client
from distributed import get_worker
from distributed import LocalCluster
from distributed import WorkerPlugin

from .kernels import ready

__all__ = ['Engine', 'KernelPlugin', 'Outcome', 'local_workers']

_REFRESH_SECONDS = 5.0


def local_workers():
    """Return the cores this process may run on: a local cluster's default worker count."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


class KernelPlugin(WorkerPlugin):
    """
    Run on every worker once, at its start: load the kernels of `integrators`.

    With `ignore_interrupts` (a local cluster's workers) the worker also ignores SIGINT.
    The loading runs in a thread, so the worker keeps answering the scheduler while a new
    machine compiles.
    """

    idempotent = True

    def __init__(self, integrators, ignore_interrupts=False):
        """Keep what to load (the plugin travels to the workers pickled)."""
        self.integrators = sorted(integrators)
        self.ignore_interrupts = ignore_interrupts
        self.name = 'rigid_body_sim-kernels-' + '-'.join(self.integrators)

    async def setup(self, worker):
        """Load the kernels in this worker's process (compiling what its machine lacks)."""
        if self.ignore_interrupts and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        await asyncio.get_running_loop().run_in_executor(None, ready, self.integrators)


@dataclass
class Outcome:
    """
    What became of one item of :meth:`Engine.run_each`.

    result is the function's result for it (None if `error`); where says which process ran
    it (host, worker address, pid) and `task_seconds` how long its whole task took there;
    error is the exception that ended its task (None if it ran).
    """

    item: object
    result: object
    where: dict
    task_seconds: float
    error: object = None


def _run_task(function, items, arguments):
    """Run `function(items, *arguments)` on a worker; return its results and where it ran."""
    started = time.perf_counter()
    results = function(items, *arguments)
    try:
        address = get_worker().address
    except ValueError:
        address = ''
    return {'results': results, 'seconds': time.perf_counter() - started,
            'where': {'host': socket.gethostname(), 'worker': address, 'pid': os.getpid()}}


class _interrupts_ignored:
    """A context in which SIGINT is ignored (the main thread only): what children inherit."""

    def __enter__(self):
        self._previous = None
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        return self

    def __exit__(self, *exc):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
        return False


class Engine:
    """
    A Dask cluster to run tasks on, with the kernels loaded on every worker.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``).  Default: Dask's
        configuration's ``scheduler-address`` if set, else a local cluster.
    workers : int, optional
        Worker processes of a local cluster (default: one per core), one thread each.
    integrators : iterable of str
        The integrators whose kernels every worker loads at its start.
    verbose : bool
        Let distributed's warnings through (a worker restarted, a slow event loop).

    Use it as a context manager; :attr:`client` is the ``distributed.Client``.

    """

    def __init__(self, scheduler=None, workers=None, integrators=(), verbose=False):
        """Keep the settings; the cluster starts on entering the context."""
        self.scheduler = scheduler or dask.config.get('scheduler-address', None)
        self.workers = workers
        self.integrators = sorted(set(integrators))
        self.verbose = verbose
        self.cluster = None
        self.client = None
        self.start_seconds = None
        self._threads = None
        self._threads_read = -math.inf
        self._out = {}

    @property
    def is_local(self):
        """Return True if the engine runs its own local cluster."""
        return self.scheduler is None

    def __enter__(self):
        """Start (or connect to) the cluster and load the kernels on every worker."""
        started = time.perf_counter()
        level = logging.WARNING if self.verbose else logging.ERROR
        try:
            if self.is_local:
                with _interrupts_ignored():
                    self.cluster = LocalCluster(
                        n_workers=self.workers or local_workers(), threads_per_worker=1,
                        processes=True, dashboard_address=None, silence_logs=level)
                self.client = Client(self.cluster)
            else:
                logging.getLogger('distributed').setLevel(level)
                self.client = Client(self.scheduler)
            self.client.register_plugin(KernelPlugin(self.integrators, self.is_local))
        except BaseException:
            self.close()
            raise
        self.start_seconds = time.perf_counter() - started
        return self

    def __exit__(self, *exc):
        """Close the client and a local cluster."""
        self.close()
        return False

    def close(self):
        """Close the client and a local cluster (their workers end)."""
        if self.client is not None:
            self.client.close()
            self.client = None
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None

    def machines(self):
        """Return {host: worker processes} of the cluster now."""
        hosts = {}
        for info in self.client.scheduler_info(n_workers=-1)['workers'].values():
            host = info.get('host', '?')
            hosts[host] = hosts.get(host, 0) + 1
        return hosts

    def threads(self):
        """Return the worker threads of the cluster (read at most every few seconds)."""
        now = time.monotonic()
        if now - self._threads_read > _REFRESH_SECONDS:
            self._threads = sum(self.client.nthreads().values())
            self._threads_read = now
        return self._threads

    def items_on(self, worker):
        """Return the items of the tasks the scheduler has given `worker` (an address) now."""
        keys = self.client.processing(workers=[worker]).get(worker, ())
        return [item for key in keys for item in self._out.get(key, (None, ()))[1]]

    def run_each(self, function, items, key, arguments=(), total=None, stop=None,
                 items_per_task=None, target_seconds=1.0, max_items_per_task=64):
        """
        Run ``function(list of items, *arguments)`` on the workers; yield each item's Outcome.

        `function` (importable on the workers) returns one result per item, in order.
        `key(item)` names an item (a content address); `total` (the number of items, if
        known) keeps the last tasks small enough to share among the workers.  A fixed
        `items_per_task` replaces the sizing by `target_seconds` (see the module).  When
        `stop` (a threading.Event) is set, what is out is cancelled and the iteration ends.
        """
        done = queue.Queue()
        out = self._out = {}
        try:
            yield from self._outcomes(function, iter(items), key, arguments, total, stop,
                                      items_per_task, target_seconds, max_items_per_task,
                                      done, out)
        finally:
            # Stopped, or the caller left the loop: nothing of this call stays on the cluster.
            if out and self.client is not None:
                self.client.cancel([future for future, _ in out.values()])

    def _outcomes(self, function, source, key, arguments, total, stop, items_per_task,
                  target_seconds, max_items_per_task, done, out):
        costs = deque(maxlen=64)
        submitted = 0
        exhausted = False
        while out or not exhausted:
            if stop is not None and stop.is_set():
                return
            threads = max(1, self.threads())
            while not exhausted and len(out) < 2 * threads:
                size = items_per_task or _task_size(costs, target_seconds, max_items_per_task,
                                                    None if total is None else total - submitted,
                                                    threads)
                batch = list(itertools.islice(source, size))
                if not batch:
                    exhausted = True
                    break
                submitted += len(batch)
                name = hashlib.sha256('\n'.join(key(item) for item in batch).encode())
                future = self.client.submit(_run_task, function, batch, arguments,
                                            key=f'rigid_body_sim-{name.hexdigest()[:32]}')
                out[future.key] = (future, batch)
                future.add_done_callback(done.put)
            try:
                future = done.get(timeout=0.2)
            except queue.Empty:
                continue
            if future.key not in out:
                continue
            future, batch = out.pop(future.key)
            if future.status == 'finished':
                value = future.result()
                costs.append(value['seconds'] / len(batch))
                outcomes = [Outcome(item, result, value['where'], value['seconds'])
                            for item, result in zip(batch, value['results'])]
            else:
                error = future.exception() if future.status == 'error' else RuntimeError(
                    f'task {future.key} {future.status}')
                outcomes = [Outcome(item, None, {}, 0.0, error) for item in batch]
            future.release()
            yield from outcomes


def _task_size(costs, target_seconds, largest, remaining, threads):
    """Return the items for the next task: about target_seconds of work, by the costs seen."""
    if not costs:
        return 1
    cost = sorted(costs)[len(costs) // 2]
    size = largest if cost <= 0.0 else int(target_seconds / cost)
    if remaining is not None:
        # The tail: enough tasks left for every thread twice.
        size = min(size, math.ceil(remaining / (2 * threads)))
    return max(1, min(largest, size))

"""
A sweep from spec to table: what runs, what is done already, the engine, the rows.

:func:`run_sweep` is the ``sweep`` command without its command line: it locks the output
folder (one sweep writes to it at a time), opens its table (a journal left by a killed
session is recovered), removes the bags a stopped run left half-written, expands the spec,
skips the runs the table holds, runs the others on the engine and adds each row to the
table as it arrives.  A stop (the `stop` event: Ctrl-C) keeps every row that arrived; the
next call with the same spec and folder runs the rest.
"""

from dataclasses import dataclass
from dataclasses import field
import fcntl
import os
from pathlib import Path
import time

from .engine import Engine
from .engine import local_workers
from .run import execute_runs
from .run import has_reference
from .run import REFERENCE_INTEGRATOR
from .run import remove_partial_bags
from .spec import resolve
from .table import ResultTable
from ..scenes import parse_scene

__all__ = ['SweepResult', 'run_sweep', 'needed_integrators']

LOCK_FILE = '.sweep.lock'


@dataclass
class SweepResult:
    """
    What one call of :func:`run_sweep` did.

    Attributes
    ----------
    total : int
        Runs of the spec.
    skipped : int
        Runs found finished in the table (not run again).
    done : int
        Runs run now and added to the table.
    not_done : list of (run_id, str)
        Runs whose task failed (no row: a re-run retries them), with the error.
    stopped : bool
        Stopped by the `stop` event before the end.
    seconds : float
        Wall time of the runs, from the first submission to the last row.
    engine_seconds : float
        Wall time to start the cluster and load the kernels on its workers.
    machines : dict
        {host: worker processes} of the cluster.
    statuses : dict
        {status: runs} of the rows added now.
    ids : set of str
        The run ids of the spec.

    """

    total: int
    skipped: int = 0
    done: int = 0
    not_done: list = field(default_factory=list)
    stopped: bool = False
    seconds: float = 0.0
    engine_seconds: float = 0.0
    machines: dict = field(default_factory=dict)
    statuses: dict = field(default_factory=dict)
    ids: set = field(default_factory=set)


def needed_integrators(spec):
    """Return the integrators every worker loads: the spec's, and the reference's if used."""
    names = set(spec.integrators())
    for scene in spec.scenes:
        if has_reference(parse_scene(resolve(scene.data, spec.fixed), scene.source)):
            names.add(REFERENCE_INTEGRATOR)
    return sorted(names)


class _OutputLock:
    """An exclusive lock on the output folder: a second sweep into it is refused at once."""

    def __init__(self, out):
        self.path = Path(out) / LOCK_FILE
        self._file = None

    def __enter__(self):
        self._file = open(self.path, 'a+')
        try:
            fcntl.flock(self._file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._file.seek(0)
            holder = self._file.read().strip() or '?'
            self._file.close()
            raise ValueError(f'{self.path.parent}: another sweep (process {holder}) writes to '
                             'this folder; wait for it or give another --out') from None
        self._file.seek(0)
        self._file.truncate()
        self._file.write(str(os.getpid()))
        self._file.flush()
        return self

    def __exit__(self, *exc):
        self._file.close()
        return False


def run_sweep(spec, out, scheduler=None, workers=None, stop=None, on_row=None,
              items_per_task=None, engine=None, verbose=False, on_starting=None,
              on_started=None):
    """
    Run the runs of `spec` not yet in the table of output folder `out`; return a SweepResult.

    Parameters
    ----------
    spec : Spec
        What to run (:func:`rigid_body_sim.sweep.spec.load_spec`).
    out : str or Path
        Output folder: ``table/`` (the Parquet data set), ``bags/``.  On a cluster of many
        machines it must be the same path on each (a shared file system) when the spec
        writes bags; rows travel to the driver through Dask.
    scheduler, workers, verbose :
        As :class:`Engine` takes them.
    engine : Engine, optional
        An engine already started, used instead of one of its own (left running).
    stop : threading.Event, optional
        Set it to stop (Ctrl-C): what is out is cancelled, every row received is kept.
    on_row : callable, optional
        Called with each row as it is added (the progress bar), in this thread.
    on_starting, on_started : callable, optional
        Called with the SweepResult (its total and skipped counts set) before the engine
        starts and once it runs, when there are runs to do.
    items_per_task : int, optional
        Runs per task (default: sized to about a second of work each).

    """
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    spec.check()
    result = SweepResult(spec.run_count)
    with _OutputLock(out):
        table = ResultTable(out)
        finished = table.start()
        try:
            remove_partial_bags(out)
            result.ids = {run.run_id for run in spec.runs()}
            result.total = len(result.ids)
            result.skipped = len(result.ids & finished)
            todo = len(result.ids) - result.skipped
            if todo == 0:
                return result
            owned = engine is None
            if on_starting is not None:
                on_starting(result)
            integrators = needed_integrators(spec)
            if owned:
                count = None if scheduler else min(workers or local_workers(), todo)
                engine = Engine(scheduler, count, integrators, verbose).__enter__()
            try:
                result.engine_seconds = engine.start_seconds or 0.0
                result.machines = engine.machines()
                if on_started is not None:
                    on_started(result)
                started = time.perf_counter()
                for outcome in engine.run_each(
                        execute_runs, _pending(spec, finished), key=lambda run: run.run_id,
                        arguments=(str(out), integrators), total=todo, stop=stop,
                        items_per_task=items_per_task):
                    if outcome.error is not None:
                        result.not_done.append((outcome.item.run_id, _one_line(outcome.error)))
                        continue
                    row = dict(outcome.result, **_where(outcome.where))
                    if table.add(row):
                        result.done += 1
                        status = row['status']
                        result.statuses[status] = result.statuses.get(status, 0) + 1
                        if on_row is not None:
                            on_row(row)
                result.seconds = time.perf_counter() - started
                result.stopped = stop is not None and stop.is_set() and (
                    result.done + len(result.not_done) < todo)
                if not result.stopped:
                    # Every task has ended: what a killed worker left half-written goes.
                    remove_partial_bags(out)
            finally:
                if owned:
                    engine.close()
        finally:
            table.close()
    return result


def _pending(spec, finished):
    """Yield the runs of `spec` not in `finished`, each once (a spec may repeat a run)."""
    seen = set(finished)
    for run in spec.runs():
        if run.run_id not in seen:
            seen.add(run.run_id)
            yield run


def _where(where):
    return {'host': where.get('host', ''), 'worker': where.get('worker', ''),
            'pid': where.get('pid')}


def _one_line(error):
    return f'{type(error).__name__}: {" ".join(str(error).split())}'[:300]

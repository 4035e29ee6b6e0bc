"""
The benchmark's cells: each measurement a function of its parameters alone, to run anywhere.

Each part of the benchmark (work-precision, tolerance sweep, forces) is a :class:`Plan`:
its references first (each a :class:`Cell`), then its cells, each of which takes the
reference it is scored against as its last argument, then :attr:`Plan.assemble`, which
puts the values together into the part's result, in the order the report reads them.  A
cell's function is a module-level function of this package (it travels to another process
by name), its arguments travel pickled (names and numbers: a case is named and built again
where the cell runs, as a Scene's State does not unpickle), and its figures depend on its
arguments only: where it runs changes its CPU times, not its errors.  Its CPU time is
measured in the cell itself, on the thread that runs it (:data:`CPU_CLOCK`), so it is the
CPU of the machine that ran it, whatever else that process does (a Dask worker's own
threads are not counted).

:func:`run_in_process` runs a plan here, cell after cell; :func:`run_cells` is what runs a
batch of cells in any process (a Dask task: ``rigid-body-sim bench`` gives the cells to the
sweep engine, rigid_body_sim/tools/bench.py).
"""

from contextlib import contextmanager
from dataclasses import dataclass
import functools
import platform
import socket
import time

__all__ = ['Cell', 'CPU_CLOCK', 'CPU_CLOCK_NAME', 'cpu_model', 'Plan', 'run_cells',
           'run_in_process']

CPU_CLOCK = time.thread_time
"""The clock of every timed run: CPU time of the calling thread (s)."""
CPU_CLOCK_NAME = 'time.thread_time (CPU time of the thread that ran the cell, on its machine)'


@functools.lru_cache(maxsize=1)
def cpu_model():
    """Return (CPU model name, number of physical cores or None) from /proc/cpuinfo."""
    model, cores, current = None, set(), {}
    try:
        with open('/proc/cpuinfo') as cpuinfo:
            for line in cpuinfo:
                key, _, value = (part.strip() for part in line.partition(':'))
                if key == 'model name' and model is None:
                    model = value
                elif key in ('physical id', 'core id'):
                    current[key] = value
                elif not key and current:
                    cores.add((current.get('physical id'), current.get('core id')))
                    current = {}
    except OSError:
        pass
    if current:
        cores.add((current.get('physical id'), current.get('core id')))
    return model or platform.processor() or 'unknown', len(cores) or None


@dataclass(frozen=True)
class Cell:
    """
    One measurement: ``function(*arguments)``.

    name says what it measures (part, case, method, step): unique in a run of the benchmark.
    weight is a rough relative cost (integrator steps), so the dearest go out first.
    """

    name: str
    function: object
    arguments: tuple
    weight: float = 1.0


@dataclass(frozen=True)
class _Pending:
    """A cell waiting for its reference: `pick` takes its part of the reference's value."""

    name: str
    function: object
    arguments: tuple
    reference: str
    pick: object
    weight: float


class Plan:
    """
    One part of the benchmark: references, the cells scored against them, the assembly.

    `assemble(references, values)` takes {name: value} of the references and of the cells
    and returns the part's result dict.
    """

    def __init__(self, part, assemble):
        """Start an empty plan of `part` (its name, the prefix of its cells' names)."""
        self.part = part
        self.assemble = assemble
        self.references = []
        self._pending = []

    def add_reference(self, name, function, arguments, weight=1.0):
        """Add a reference cell; return its full name."""
        full = f'{self.part}/{name}'
        self.references.append(Cell(full, function, tuple(arguments), weight))
        return full

    def add_cell(self, name, function, arguments, reference, pick=None, weight=1.0):
        """
        Add a cell: ``function(*arguments, pick(value of reference))`` (pick: the identity).

        Returns its full name.
        """
        full = f'{self.part}/{name}'
        self._pending.append(_Pending(full, function, tuple(arguments), reference,
                                      pick or _identity, weight))
        return full

    @property
    def units(self):
        """Return the number of cells, references included."""
        return len(self.references) + len(self._pending)

    def cells(self, references):
        """Return the cells, each given its reference from {name: value} `references`."""
        return [Cell(p.name, p.function, p.arguments + (p.pick(references[p.reference]),),
                     p.weight) for p in self._pending]


def _identity(value):
    return value


@contextmanager
def _mujoco_warnings_silenced():
    """
    Swallow MuJoCo's warning prints while measuring.

    MuJoCo prints a line for each diverging run; the benchmark reads the divergence from
    MuJoCo's counters and reports it in the table instead.
    """
    try:
        import mujoco
    except ImportError:
        yield
        return
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda message: None)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def run_cells(cells):
    """
    Run `cells` in this process, one after another; return one dict per cell.

    Each: 'value' (the cell's), 'host' and 'cpu_model' (the machine that ran it).
    """
    host, model = socket.gethostname(), cpu_model()[0]
    with _mujoco_warnings_silenced():
        return [{'value': cell.function(*cell.arguments), 'host': host, 'cpu_model': model}
                for cell in cells]


def run_in_process(plan, progress=None):
    """Run `plan` here, cell after cell; return its result (progress(label) after each)."""
    references, values = {}, {}
    for cell in plan.references:
        references[cell.name] = run_cells([cell])[0]['value']
        if progress is not None:
            progress(cell.name)
    for cell in plan.cells(references):
        values[cell.name] = run_cells([cell])[0]['value']
        if progress is not None:
            progress(cell.name)
    return plan.assemble(references, values)

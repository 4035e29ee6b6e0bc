"""
Sweeps: thousands of offline runs on a Dask cluster, each a bag and a row of one table.

- :mod:`.spec`: the spec file (scenes, run axes, grid, random draws) and its runs, each
  named by a digest of its content;
- :mod:`.run`: one run in the process that executes it (simulation, bag, row);
- :mod:`.table`: the results table, a Parquet data set written as runs finish;
- :mod:`.engine`: the Dask cluster, its workers loading the kernels once, tasks sized to
  their cost; what ``bench`` can run its cells on as well;
- :mod:`.driver`: spec to table, skipping what is done (:func:`run_sweep`);
- :mod:`.summary`: the lines printed at the end.

The command: ``rigid-body-sim sweep SPEC --out DIR`` (:mod:`rigid_body_sim.tools.sweep`);
the guide: docs/sweep.md.
"""

from .driver import run_sweep
from .driver import SweepResult
from .engine import Engine
from .spec import load_spec
from .spec import parse_spec
from .spec import Spec
from .table import read_table

__all__ = ['Engine', 'Spec', 'SweepResult', 'load_spec', 'parse_spec', 'read_table',
           'run_sweep']

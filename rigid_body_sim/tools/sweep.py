"""
Run a sweep: many offline simulations from one spec file, each a bag and a row of one table.

The runs go to Dask: without --scheduler, a local cluster of one worker process per core;
with --scheduler ADDRESS (or Dask's configuration, DASK_SCHEDULER_ADDRESS), your cluster.
Each worker loads the kernels once and runs many simulations in its process.  Each run is
named by a digest of what it simulates, so running the same command again skips the runs
the table holds and redoes the rest: after Ctrl-C (which stops cleanly, keeping every
finished run), a crash, or a worker killed on the way.  The table is a Parquet data set,
DIR/table (one row per run: its parameters, final state, drift of what the physics
conserves, error against the exact flow where the scene is torque-free, CPU per simulated
second, status); the bags are under DIR/bags.  docs/sweep.md has the details.

The spec (YAML; examples in config/sweeps, run by name: small, imu_dataset):

  description: integrators on two tumbling bodies   # optional, one line
  scenes: [t_handle, tennis_racket]    # built-in names or .yaml paths (relative to the spec)
  integrators: [buss, rk4]             # default: each scene's
  rates: [100]                         # Hz; default: each scene's
  tolerances: [1.0e-5, 0]              # rad per simulated s, 0: off; default: each scene's
  substeps: [1]                        # integrator steps per tick (default 1)
  durations: [10]                      # simulated s (required), whole ticks at each rate
  bags: false                          # default true: each run writes its bag
  storage: mcap                        # or sqlite3 (default mcap)
  set:                                 # fixed scene values for every run, by key path
    imu.gyro_noise_density: 1.7e-4     #   (the scene schema: rigid-body-sim scenes)
  grid:                                # every combination of these values
    body.mass: [0.5, 1.0]
  random:                              # `count` draws for each combination above
    count: 100
    seed: 7                            # draw k comes from (seed, k): same for every method
    draw:
      initial.angular_velocity_body: {uniform: [[-0.1, 1.9, -0.1], [0.1, 2.1, 0.1]]}
      initial.orientation: {uniform_rotation: true}
      imu.seed: {integers: [0, 1000000000]}

A key path names a scene value: body.<key>, initial.<key>, imu.<key>, or effects (the
whole list).  Distributions: uniform [low, high], log_uniform [low, high], normal [mean,
sd] (numbers, or lists drawn element by element), integers [low, high] (both included),
choice [values...], uniform_rotation (a unit quaternion x, y, z, w).  Runs: scenes x
integrators x rates x tolerances x substeps x durations x grid x count.

Typical use:
  rigid-body-sim sweep small --out runs/small          # the bar shows the time left
  rigid-body-sim sweep small --out runs/small          # again: every run found done
  rigid-body-sim sweep my_spec.yaml --out runs/mine --dry-run   # its runs, none run
  rigid-body-sim sweep imu_dataset --out runs/imu --scheduler tcp://HOST:8786
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path
import sys
from typing import Any
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # for the annotations: the command imports the sweep (Dask) when it runs
    from ..sweep.driver import SweepResult
    from ..sweep.spec import Run
    from ..sweep.spec import Spec

__all__ = ['add_arguments', 'main']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim sweep``."""
    parser.add_argument('spec', metavar='SPEC',
                        help='a spec file (.yaml) or the name of an example in config/sweeps')
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output folder: DIR/table (Parquet), DIR/bags; a second run into '
                             'it skips what is done')
    parser.add_argument('--scheduler', metavar='ADDRESS',
                        help="a Dask scheduler's address (tcp://host:8786); default: Dask's "
                             'configured scheduler-address, else a local cluster')
    parser.add_argument('--workers', type=int, metavar='N',
                        help='worker processes of the local cluster (default: one per core)')
    parser.add_argument('--runs-per-task', type=int, metavar='N',
                        help='runs per Dask task (default: sized to about 1 s of work each, '
                             "so the scheduler's cost per task stays small)")
    parser.add_argument('--dry-run', action='store_true',
                        help='print the runs the spec makes and how many are done; run none')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    parser.add_argument('--verbose', action='store_true',
                        help="show distributed's warnings (a worker restarted, ...)")


def main(args: argparse.Namespace) -> int:
    """
    Run the sweep and print its summary; return 0 when every run is in the table.

    1 if runs failed to run (a re-run retries them), 128 + n when signal n stopped it.
    """
    from pathlib import Path

    from ..recording.signals import StopOnSignals
    from ..sweep.spec import load_spec

    spec = load_spec(args.spec)
    if args.workers is not None and args.workers < 1:
        raise ValueError(f'--workers must be at least 1; got {args.workers}')
    if args.runs_per_task is not None and args.runs_per_task < 1:
        raise ValueError(f'--runs-per-task must be at least 1; got {args.runs_per_task}')
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f'--out {out} is not a folder')
    if args.dry_run:
        return _dry_run(spec, out)
    from ..sweep.driver import run_sweep
    from ..sweep.summary import summary_lines

    progress = _Progress(quiet=args.quiet)
    with StopOnSignals() as signals:
        try:
            result = run_sweep(spec, out, scheduler=args.scheduler, workers=args.workers,
                               stop=signals.stop, on_row=progress.row,
                               items_per_task=args.runs_per_task, verbose=args.verbose,
                               on_starting=progress.starting, on_started=progress.started)
        finally:
            progress.close()
    for line in summary_lines(result, out.resolve(), spec.source):
        print(line)
    if signals.received is not None:
        print(f'rigid-body-sim sweep: {signals.received.name}: stopped; the table keeps the '
              f'{result.skipped + result.done} finished runs; run the same command again to '
              'do the rest', file=sys.stderr)
        return signals.exit_code
    return 1 if result.not_done else 0


class _Progress:
    """What the command says while it runs: the start, then a progress bar (tqdm, stderr)."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bar = None
        self.not_ok = 0

    def starting(self, result: SweepResult) -> None:
        if not self.quiet:
            print(f'rigid-body-sim sweep: {result.total} runs, {result.skipped} in the table '
                  'already; starting the workers (each loads the kernels once) ...',
                  file=sys.stderr, flush=True)

    def started(self, result: SweepResult) -> None:
        if not self.quiet:
            from tqdm import tqdm
            self.bar = tqdm(total=len(result.ids), initial=result.skipped, unit='run',
                            desc='runs', file=sys.stderr, dynamic_ncols=True)

    def row(self, row: Mapping[str, Any]) -> None:
        if self.bar is None:
            return
        if row['status'] != 'ok':
            self.not_ok += 1
            self.bar.set_postfix_str(f'{self.not_ok} not ok', refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _dry_run(spec: Spec, out: Path) -> int:
    from ..sweep.driver import needed_integrators
    from ..sweep.table import finished_ids

    done = finished_ids(out) if out.is_dir() else set()
    runs = spec.runs()
    shown: list[Run] = []
    found = 0
    for run in runs:
        found += run.run_id in done
        if len(shown) < 5:
            shown.append(run)
    spec.check()
    print(f'{spec.source}: {spec.run_count} runs ({found} in {out} already); every worker '
          f'loads the kernels of {", ".join(needed_integrators(spec))}')
    for run in shown:
        print(f'  {run.run_id}  {run.base.get("name")}  {run.parameters()}')
    if spec.run_count > len(shown):
        print(f'  ... {spec.run_count - len(shown)} more')
    return 0

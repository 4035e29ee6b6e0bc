"""
Measure what accuracy costs in time: the work-precision benchmark, MuJoCo included.

Runs every registered integrator (and MuJoCo's Euler, RK4 and implicitfast when mujoco is
installed) on five torque-free benchmark bodies at dt = 10 .. 0.001 s, measures the
orientation error at 10 s and 100 s against an extended-precision reference, the energy and
|L| drift, and the CPU time per step, and writes results.md (tables), results.json,
results.csv and work_precision.png / work_precision_100s.png (error against CPU per simulated
second) to --out.  Then the tolerance sweep (work_precision/tolerance_sweep.py): every built-in
scene at its own rate over 60 s, error-controlled buss at tolerances 3e-2 .. 1e-10 rad/s
beside fixed-step buss, splitting and rk4, written as tolerance_sweep.md/.json/.csv/.png.
Then the forced benchmark (work_precision/forces.py): heavy_top, bike_wheel, a non-diagonal body
on an off-axis pivot, van Zon's body under an oscillating world torque and a box under a
body-fixed torque, every integrator and error-controlled buss beside MuJoCo, against DOP853
references, written as forces.md/.json/.csv and forces_work_precision.png.
--quick: two bodies, three steps and horizons of 2 s and 10 s, a 2 s sweep of two scenes and
two forced bodies over 0.5 s, for CI (seconds, not minutes); it refuses to write into a
directory that holds a full run's results.  --tolerance-sweep: the sweep alone; --forces: the
forced benchmark alone.  How long a run takes: its progress bar counts the runs and the time
left, and each part's results file records its last run's wall time (``wall_seconds`` of
results.json, tolerance_sweep.json and forces.json, also near the top of the .md files;
the committed run's are in docs/benchmark/).  The tolerance sweep is the longest part.

Where it runs: each measurement is a cell, a task of the sweep engine (rigid-body-sim sweep's
Dask engine): without --scheduler, a local cluster of one worker process per core (--workers
N for another count); with --scheduler ADDRESS (or Dask's configuration), your cluster.  The
references go first, then every cell of the parts run, the dearest first.  A cell's errors
do not depend on where it ran; its CPU time is measured on the worker that ran it (the CPU
time of the thread that ran it), and each report says which machines (hostname, CPU) and how
many workers ran its cells.  With the parts run together, each part's wall_seconds is the
time from the first reference sent to its last cell back.  --in-process runs the cells in
this process, one after another: for --quick on a machine of a few cores the quicker, as the
cluster's start (its workers import the package and load every kernel) costs more than the
few seconds of cells it shares out (docs/benchmark.md).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
import os
from pathlib import Path
import sys
import time
from typing import Any

# The benchmark package (scipy, mujoco, matplotlib) is imported inside main(): the command
# line builds every tool's parser at start-up, and `rigid-body-sim run` should not pay for it.


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim bench``."""
    parser.add_argument('--quick', action='store_true',
                        help='a small sweep for CI: 2 bodies, dt 1, 0.1 and 0.01, 2 s and 10 s')
    parser.add_argument('--out', default='bench-results', metavar='DIR',
                        help='directory for results.md/.json/.csv and work_precision.png '
                             '(default: ./bench-results)')
    parser.add_argument('--repeats', type=int, default=None,
                        help='timing repeats, the median is kept (default: 5, quick: 3)')
    parser.add_argument('--no-mujoco', action='store_true',
                        help='leave out the MuJoCo peer even if it is installed')
    sweep = parser.add_mutually_exclusive_group()
    sweep.add_argument('--forces', action='store_true',
                       help='run only the forced benchmark (torques, gravity, a pivot; '
                            'MuJoCo beside; minutes: forces.json of the last run says how '
                            'long it took, as wall_seconds; with --quick: seconds)')
    sweep.add_argument('--tolerance-sweep', action='store_true',
                       help='run only the tolerance sweep (error-controlled buss against '
                            'fixed steps on the built-in scenes; the longest part: '
                            'tolerance_sweep.json of the last run says how long it took, as '
                            'wall_seconds; with --quick: seconds)')
    sweep.add_argument('--no-tolerance-sweep', action='store_true',
                       help='skip the tolerance sweep that follows the work-precision runs')
    parser.add_argument('--scenes', nargs='+', metavar='SCENE', default=None,
                        help='the built-in scenes the sweep takes (default: all; quick: '
                             'van_zon and heavy_top)')
    parser.add_argument('--scheduler', metavar='ADDRESS',
                        help='run the cells on the Dask cluster of this scheduler '
                             "(tcp://host:8786); default: Dask's configured scheduler-address, "
                             'else a local cluster')
    parser.add_argument('--workers', type=int, metavar='N',
                        help='worker processes of the local cluster (default: one per core)')
    parser.add_argument('--in-process', action='store_true',
                        help='run the cells in this process, one after another (no Dask)')


def _progress_bar(total: int) -> tuple[Any, Callable[[str], None]]:
    from tqdm import tqdm
    bar = tqdm(total=total, desc='bench', unit='cell', file=sys.stderr,
               dynamic_ncols=True, leave=True)

    def advance(label: str) -> None:
        bar.set_postfix_str(label, refresh=False)
        bar.update(1)
    return bar, advance


def _command(args: argparse.Namespace) -> str:
    return ('rigid-body-sim bench' + (' --quick' if args.quick else '')
            + ('' if args.repeats is None else f' --repeats {args.repeats}')
            + (' --no-mujoco' if args.no_mujoco else '')
            + (' --tolerance-sweep' if args.tolerance_sweep else '')
            + (' --forces' if getattr(args, 'forces', False) else '')
            + (' --no-tolerance-sweep' if args.no_tolerance_sweep else '')
            + (' --scenes ' + ' '.join(args.scenes) if args.scenes else '')
            + (f' --scheduler {args.scheduler}' if getattr(args, 'scheduler', None) else '')
            + (f' --workers {args.workers}' if getattr(args, 'workers', None) else '')
            + (' --in-process' if getattr(args, 'in_process', False) else '')
            + f' --out {args.out}')


class _Part:
    """One part of the benchmark to run: its plan, its config for the report, its writer."""

    def __init__(self, plan: Any, config: dict[str, Any],
                 finish: Callable[..., Any]) -> None:
        self.plan, self.config, self.finish = plan, config, finish


def _work_precision_part(args: argparse.Namespace) -> _Part:
    from ..work_precision.bodies import benchmark_cases
    from ..work_precision.measure import benchmark_plan
    from ..work_precision.measure import FULL
    from ..work_precision.measure import QUICK
    from ..work_precision.report import goal_summary
    from ..work_precision.report import goal_table
    from ..work_precision.report import write_outputs

    config = QUICK if args.quick else FULL
    if args.repeats is not None:
        if args.repeats < 1:
            raise ValueError(f'--repeats must be >= 1; got {args.repeats}')
        config = config.__class__(config.cases, config.dts, config.horizons, args.repeats,
                                  config.time_budget)

    def finish(result: dict[str, Any]) -> dict[str, Path]:
        result['cases'] = {case.name: case.description
                           for case in benchmark_cases(config.cases)}
        paths = write_outputs(result, args.out)
        print(f'bench: {len(result["records"])} runs in {result["wall_seconds"]:.0f} s '
              f'({result["cpu_seconds"]:.0f} CPU s in this process); MuJoCo peer: '
              f'{result["mujoco"]}')
        for horizon, seconds in zip(('short', 'long'), config.horizons):
            rows = goal_table(result, horizon=horizon)
            counts = goal_summary(rows)
            if counts['no peer'] == len(rows):
                break
            others = ', '.join(f'{count} {name}' for name, count in counts.items()
                               if count and name != 'holds')
            print(f"bench: at {seconds:g} s our best needs at most half of MuJoCo's best CPU "
                  f'at {counts["holds"]} of {len(rows)} (body, error level) pairs'
                  + (f'; {others}' if others else '')
                  + ('' if horizon == 'short' else ' (information only)'))
        return paths
    return _Part(benchmark_plan(config, with_mujoco=not args.no_mujoco),
                 {'cases': list(config.cases), 'dts': list(config.dts),
                  'horizons': list(config.horizons), 'repeats': config.repeats,
                  'time_budget': config.time_budget, 'quick': bool(args.quick)}, finish)


def _tolerance_sweep_part(args: argparse.Namespace) -> _Part:
    from ..scenes import scene_names
    from ..work_precision.tolerance_report import control_goal_table
    from ..work_precision.tolerance_report import write_sweep_outputs
    from ..work_precision.tolerance_sweep import FIXED_SUBSTEPS
    from ..work_precision.tolerance_sweep import SAMPLE_INTERVAL
    from ..work_precision.tolerance_sweep import scene_cases
    from ..work_precision.tolerance_sweep import sweep_plan
    from ..work_precision.tolerance_sweep import SWEEP_SPAN
    from ..work_precision.tolerance_sweep import TOLERANCES

    tolerances: tuple[float, ...]
    substeps: tuple[int, ...]
    if args.quick:
        names = args.scenes or ['van_zon', 'heavy_top']
        span, tolerances, substeps = 2.0, (1e-3, 1e-5, 1e-7), (1, 2, 4, 8)
    else:
        names = args.scenes or scene_names(several_bodies=False)
        span, tolerances, substeps = SWEEP_SPAN, TOLERANCES, FIXED_SUBSTEPS
    unknown = sorted(set(names) - set(scene_names(several_bodies=False)))
    if unknown:
        raise ValueError(f'--scenes: no built-in scene {", ".join(unknown)} of one body (the '
                         'benchmark takes those); the scenes are '
                         f'{", ".join(scene_names(several_bodies=False))}')
    repeats = args.repeats or 3

    def finish(result: dict[str, Any]) -> dict[str, Path]:
        paths = write_sweep_outputs(result, args.out)
        rows = control_goal_table(result)
        judged = [row for row in rows if row['verdict'] in ('holds', 'fails')]
        print(f'bench: error-controlled buss costs at most 1.5x the best fixed-step buss at '
              f'{sum(row["verdict"] == "holds" for row in judged)} of {len(judged)} judged '
              f'(scene, error level) pairs ({len(rows) - len(judged)} not reached or '
              'unresolved)')
        return paths
    plan = sweep_plan(scene_cases(names, span=span), tolerances, fixed_substeps=substeps,
                      repeats=repeats)
    return _Part(plan, {'scenes': names, 'span': span, 'tolerances': list(tolerances),
                        'fixed_substeps': list(substeps), 'sample_interval': SAMPLE_INTERVAL,
                        'repeats': repeats, 'quick': bool(args.quick)}, finish)


def _forces_part(args: argparse.Namespace) -> _Part:
    from ..work_precision.forces import FORCES_FULL
    from ..work_precision.forces import FORCES_QUICK
    from ..work_precision.forces import forces_goal_table
    from ..work_precision.forces import forces_plan
    from ..work_precision.forces_report import forces_goal_counts
    from ..work_precision.forces_report import write_forces_outputs

    config = FORCES_QUICK if args.quick else FORCES_FULL
    if args.repeats is not None:
        config = config.__class__(config.cases, config.horizon, config.tolerances,
                                  args.repeats, config.time_budget, config.dts_per_case)

    def finish(result: dict[str, Any]) -> dict[str, Path]:
        paths = write_forces_outputs(result, args.out)
        counts = forces_goal_counts(forces_goal_table(result))
        summary = '; '.join(f'{case} {count["holds"]} hold, {count["fails"]} fail, '
                            f'{count["peer not reached"]} MuJoCo not reached, '
                            f'{count["undecided"] + count["no peer"]} undecided'
                            for case, count in counts.items())
        print(f"bench: forced bodies, our best at most half of MuJoCo's best CPU per error "
              f'level 1e-2..1e-10: {summary}')
        return paths
    return _Part(forces_plan(config, with_mujoco=not args.no_mujoco),
                 {'cases': list(config.cases), 'horizon': config.horizon,
                  'tolerances': list(config.tolerances), 'repeats': config.repeats,
                  'quick': bool(args.quick)}, finish)


def _parts(args: argparse.Namespace) -> list[_Part]:
    """Return the parts this invocation runs, in the order their reports are written."""
    if getattr(args, 'forces', False):
        return [_forces_part(args)]
    if args.tolerance_sweep:
        return [_tolerance_sweep_part(args)]
    return [_work_precision_part(args)] + (
        [] if args.no_tolerance_sweep else [_tolerance_sweep_part(args)]) + [_forces_part(args)]


def _run_in_process(parts: list[_Part],
                    advance: Callable[[str], None]) -> list[tuple[Any, float, Any]]:
    """Run each part's cells here; return [(result, wall s, cells_ran_on)]."""
    from ..work_precision.cells import run_in_process

    done = []
    for part in parts:
        started = time.perf_counter()
        result = run_in_process(part.plan, advance)
        done.append((result, time.perf_counter() - started, None))
    return done


def _run_on_engine(args: argparse.Namespace, parts: list[_Part],
                   advance: Callable[[str], None]) -> list[tuple[Any, float, Any]]:
    """
    Run every part's cells on the sweep engine; return [(result, wall s, cells_ran_on)].

    All the references first, then all the cells, the dearest first (the window of tasks
    out keeps the workers busy to the end).  A part's wall time runs from the first
    reference out to its last cell back.  A cell that fails raises its error here.
    """
    from ..sweep.engine import Engine
    from ..sweep.engine import local_workers
    from ..work_precision.cells import run_cells
    from ..work_precision.measure import our_integrators

    units = sum(part.plan.units for part in parts)
    workers = min(args.workers or local_workers(), units)
    engine = Engine(args.scheduler, workers, our_integrators())
    cluster = ('a local Dask cluster' if engine.is_local
               else f'the Dask cluster at {engine.scheduler}')
    print(f'bench: {units} cells on {cluster}'
          + (f' of {workers} worker process(es)' if engine.is_local else '')
          + '; starting the workers (each loads the kernels once) ...', file=sys.stderr,
          flush=True)
    placement, finished = {}, {}

    def run(engine: Any, cells: Any) -> Any:
        values = {}
        for outcome in engine.run_each(run_cells, sorted(cells, key=lambda c: -c.weight),
                                       key=lambda cell: cell.name, total=len(cells),
                                       items_per_task=1):
            if outcome.error is not None:
                raise outcome.error
            name = outcome.item.name
            values[name] = outcome.result['value']
            placement[name] = (outcome.where.get('worker', ''), outcome.result['host'],
                               outcome.result['cpu_model'])
            finished[name] = time.perf_counter()
            advance(name)
        return values

    with engine:
        started = time.perf_counter()
        references = run(engine, [cell for part in parts for cell in part.plan.references])
        cells = [part.plan.cells(references) for part in parts]
        values = run(engine, [cell for part_cells in cells for cell in part_cells])
    done = []
    for part, part_cells in zip(parts, cells):
        names = [cell.name for cell in part.plan.references + part_cells]
        done.append((part.plan.assemble(references, values),
                     max(finished[name] for name in names) - started,
                     dict(_ran_on(cluster, [placement[name] for name in names]),
                          start_seconds=engine.start_seconds)))
    return done


def _ran_on(engine_words: str,
            placements: list[tuple[str, str, str]]) -> dict[str, Any]:
    """Return the machine info's 'cells_ran_on' from (worker, host, CPU) of each cell."""
    hosts: dict[str, dict[str, Any]] = {}
    for worker, host, model in placements:
        entry = hosts.setdefault(host, {'host': host, 'cpu_model': model, 'workers': set(),
                                        'cells': 0})
        entry['workers'].add(worker)
        entry['cells'] += 1
    listed = [dict(entry, workers=len(entry['workers'])) for entry in hosts.values()]
    return {'engine': engine_words, 'workers': sum(entry['workers'] for entry in listed),
            'hosts': sorted(listed, key=lambda entry: entry['host'])}


def _outputs(args: argparse.Namespace) -> list[str]:
    """Return the JSON results this invocation writes (one per part it runs)."""
    if getattr(args, 'forces', False):
        return ['forces.json']
    if args.tolerance_sweep:
        return ['tolerance_sweep.json']
    return ['results.json', 'forces.json'] + ([] if args.no_tolerance_sweep
                                              else ['tolerance_sweep.json'])


def refuse_quick_over_full_results(args: argparse.Namespace) -> None:
    """
    Raise ValueError if a --quick run would overwrite full results in --out.

    The committed results in docs/benchmark are full runs (tens of minutes); a quick run's
    few-second figures must never replace them by a typo or a copied command.
    """
    import json

    if not args.quick:
        return
    for name in _outputs(args):
        path = Path(args.out) / name
        try:
            result = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if not result.get('config', {}).get('quick', True):
            raise ValueError(f'{path} holds the results of a full run ({result.get("command")}'
                             f'); a --quick run would overwrite them: give it another --out '
                             'DIR (default ./bench-results)')


def missing_mujoco_line(args: argparse.Namespace) -> str | None:
    """
    Return the one line to print when the run wants MuJoCo's peer and mujoco is missing.

    None when mujoco imports, when --no-mujoco leaves the peer out, or for the tolerance
    sweep alone (no peer there).  mujoco is in the test set, not the run-time set.
    """
    from ..work_precision.peer_mujoco import INSTALL_HINT
    from ..work_precision.peer_mujoco import mujoco_available

    if args.no_mujoco or args.tolerance_sweep or mujoco_available():
        return None
    return (f'bench: MuJoCo is not installed, so its peer is left out; to compare with it: '
            f'{INSTALL_HINT}')


def main(args: argparse.Namespace) -> int:
    """Run the benchmark, write the outputs, print where they are; return 0."""
    if args.in_process and (args.scheduler or args.workers is not None):
        raise ValueError('--in-process runs no cluster: it takes neither --scheduler nor '
                         '--workers')
    if args.workers is not None and args.workers < 1:
        raise ValueError(f'--workers must be at least 1; got {args.workers}')
    refuse_quick_over_full_results(args)
    missing = missing_mujoco_line(args)
    if missing:
        print(missing, file=sys.stderr)
    from ..work_precision.report import machine_info

    parts = _parts(args)
    machine = machine_info()
    cpu_started = time.process_time()
    bar, advance = _progress_bar(sum(part.plan.units for part in parts))
    try:
        if args.in_process:
            done = _run_in_process(parts, advance)
        else:
            done = _run_on_engine(args, parts, advance)
    finally:
        bar.close()
    machine['load_average_end'] = list(os.getloadavg())
    paths = {}
    for part, (result, seconds, ran_on) in zip(parts, done):
        info = dict(machine)
        if ran_on is not None:
            info['cells_ran_on'] = ran_on
        result.update({'machine': info, 'config': part.config, 'command': _command(args),
                       'wall_seconds': seconds,
                       'cpu_seconds': time.process_time() - cpu_started})
        paths.update(part.finish(result))
    for path in paths.values():
        print(f'bench: wrote {path}')
    return 0

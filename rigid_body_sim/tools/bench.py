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
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from collections.abc import Iterator
import contextlib
import os
from pathlib import Path
import sys
import time

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


@contextlib.contextmanager
def _progress(total: int, description: str = 'bench',
              mujoco: bool = True) -> Iterator[Callable[[str], None]]:
    """
    Show a progress bar of `total` runs while a part of the benchmark runs; yield its advance.

    advance(label) counts one run, labelled.  With `mujoco`, MuJoCo's warning prints are
    swallowed meanwhile (see :func:`_silence_mujoco_warnings`).
    """
    from tqdm import tqdm
    bar = tqdm(total=total, desc=description, unit='run', file=sys.stderr,
               dynamic_ncols=True, leave=True)

    def advance(label: str) -> None:
        bar.set_postfix_str(label, refresh=False)
        bar.update(1)
    restore_warnings = _silence_mujoco_warnings() if mujoco else (lambda: None)
    try:
        yield advance
    finally:
        bar.close()
        restore_warnings()


def _silence_mujoco_warnings() -> Callable[[], None]:
    """
    Swallow MuJoCo's warning prints; return a function that restores them.

    MuJoCo prints a line for each diverging run; the benchmark reads the divergence from
    MuJoCo's counters and reports it in the table instead.
    """
    try:
        import mujoco
    except ImportError:
        return lambda: None
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda message: None)
    return lambda: mujoco.set_mju_user_warning(previous)


def _command(args: argparse.Namespace) -> str:
    return ('rigid-body-sim bench' + (' --quick' if args.quick else '')
            + ('' if args.repeats is None else f' --repeats {args.repeats}')
            + (' --no-mujoco' if args.no_mujoco else '')
            + (' --tolerance-sweep' if args.tolerance_sweep else '')
            + (' --forces' if getattr(args, 'forces', False) else '')
            + (' --no-tolerance-sweep' if args.no_tolerance_sweep else '')
            + (' --scenes ' + ' '.join(args.scenes) if args.scenes else '')
            + f' --out {args.out}')


def run_tolerance_sweep(args: argparse.Namespace) -> dict[str, Path]:
    """Run the tolerance sweep, write tolerance_sweep.*, print the goal's count; return paths."""
    from ..work_precision.report import machine_info
    from ..work_precision.tolerance_report import control_goal_table
    from ..work_precision.tolerance_report import write_sweep_outputs
    from ..work_precision.tolerance_sweep import FIXED_SUBSTEPS
    from ..work_precision.tolerance_sweep import SAMPLE_INTERVAL
    from ..work_precision.tolerance_sweep import scene_cases
    from ..work_precision.tolerance_sweep import sweep_units
    from ..work_precision.tolerance_sweep import SWEEP_SPAN
    from ..work_precision.tolerance_sweep import tolerance_sweep
    from ..work_precision.tolerance_sweep import TOLERANCES
    from ..scenes import scene_names

    tolerances: tuple[float, ...]
    substeps: tuple[int, ...]
    if args.quick:
        names = args.scenes or ['van_zon', 'heavy_top']
        span, tolerances, substeps = 2.0, (1e-3, 1e-5, 1e-7), (1, 2, 4, 8)
    else:
        names = args.scenes or scene_names()
        span, tolerances, substeps = SWEEP_SPAN, TOLERANCES, FIXED_SUBSTEPS
    unknown = sorted(set(names) - set(scene_names()))
    if unknown:
        raise ValueError(f'--scenes: no built-in scene {", ".join(unknown)}; '
                         f'the scenes are {", ".join(scene_names())}')
    repeats = args.repeats or 3
    cases = scene_cases(names, span=span)
    machine = machine_info()
    started = time.perf_counter()
    with _progress(sweep_units(cases, tolerances, fixed_substeps=substeps), 'tolerance sweep',
                   mujoco=False) as advance:
        result = tolerance_sweep(cases, tolerances, fixed_substeps=substeps, repeats=repeats,
                                 progress=advance)
    machine['load_average_end'] = list(os.getloadavg())
    result.update({
        'machine': machine, 'command': _command(args),
        'config': {'scenes': names, 'span': span, 'tolerances': list(tolerances),
                   'fixed_substeps': list(substeps), 'sample_interval': SAMPLE_INTERVAL,
                   'repeats': repeats, 'quick': bool(args.quick)},
        'wall_seconds': time.perf_counter() - started,
    })
    paths = write_sweep_outputs(result, args.out)
    rows = control_goal_table(result)
    judged = [row for row in rows if row['verdict'] in ('holds', 'fails')]
    print(f'bench: error-controlled buss costs at most 1.5x the best fixed-step buss at '
          f'{sum(row["verdict"] == "holds" for row in judged)} of {len(judged)} judged '
          f'(scene, error level) pairs ({len(rows) - len(judged)} not reached or unresolved)')
    return paths


def run_forces_benchmark(args: argparse.Namespace) -> dict[str, Path]:
    """Run the forced benchmark, write forces.*, print the goal's count; return paths."""
    from ..work_precision.forces import FORCES_FULL
    from ..work_precision.forces import FORCES_QUICK
    from ..work_precision.forces import forces_goal_table
    from ..work_precision.forces import forces_units
    from ..work_precision.forces import run_forces
    from ..work_precision.forces_report import forces_goal_counts
    from ..work_precision.forces_report import write_forces_outputs
    from ..work_precision.report import machine_info

    config = FORCES_QUICK if args.quick else FORCES_FULL
    if args.repeats is not None:
        config = config.__class__(config.cases, config.horizon, config.tolerances,
                                  args.repeats, config.time_budget, config.dts_per_case)
    with_mujoco = not args.no_mujoco
    machine = machine_info()
    started = time.perf_counter()
    with _progress(forces_units(config, with_mujoco), 'forces') as advance:
        result = run_forces(config, with_mujoco=with_mujoco, progress=advance)
    machine['load_average_end'] = list(os.getloadavg())
    result.update({'machine': machine, 'command': _command(args),
                   'config': {'cases': list(config.cases), 'horizon': config.horizon,
                              'tolerances': list(config.tolerances),
                              'repeats': config.repeats, 'quick': bool(args.quick)},
                   'wall_seconds': time.perf_counter() - started})
    paths = write_forces_outputs(result, args.out)
    counts = forces_goal_counts(forces_goal_table(result))
    summary = '; '.join(f'{case} {count["holds"]} hold, {count["fails"]} fail, '
                        f'{count["peer not reached"]} MuJoCo not reached, '
                        f'{count["undecided"] + count["no peer"]} undecided'
                        for case, count in counts.items())
    print(f"bench: forced bodies, our best at most half of MuJoCo's best CPU per error "
          f'level 1e-2..1e-10: {summary}')
    return paths


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
    refuse_quick_over_full_results(args)
    missing = missing_mujoco_line(args)
    if missing:
        print(missing, file=sys.stderr)
    if getattr(args, 'forces', False):
        for path in run_forces_benchmark(args).values():
            print(f'bench: wrote {path}')
        return 0
    if args.tolerance_sweep:
        for path in run_tolerance_sweep(args).values():
            print(f'bench: wrote {path}')
        return 0
    from ..work_precision.bodies import benchmark_cases
    from ..work_precision.measure import FULL
    from ..work_precision.measure import QUICK
    from ..work_precision.measure import run_benchmark
    from ..work_precision.measure import work_units
    from ..work_precision.report import goal_summary
    from ..work_precision.report import goal_table
    from ..work_precision.report import machine_info
    from ..work_precision.report import write_outputs

    config = QUICK if args.quick else FULL
    if args.repeats is not None:
        if args.repeats < 1:
            raise ValueError(f'--repeats must be >= 1; got {args.repeats}')
        config = config.__class__(config.cases, config.dts, config.horizons, args.repeats,
                                  config.time_budget)
    with_mujoco = not args.no_mujoco
    machine = machine_info()
    started = time.perf_counter()
    cpu_started = time.process_time()
    with _progress(work_units(config, with_mujoco)) as advance:
        result = run_benchmark(config, with_mujoco=with_mujoco, progress=advance)
    machine['load_average_end'] = list(os.getloadavg())
    result.update({
        'machine': machine,
        'config': {'cases': list(config.cases), 'dts': list(config.dts),
                   'horizons': list(config.horizons), 'repeats': config.repeats,
                   'time_budget': config.time_budget, 'quick': bool(args.quick)},
        'cases': {case.name: case.description for case in benchmark_cases(config.cases)},
        'command': _command(args),
        'wall_seconds': time.perf_counter() - started,
        'cpu_seconds': time.process_time() - cpu_started,
    })
    paths = write_outputs(result, args.out)
    print(f'bench: {len(result["records"])} runs in {result["wall_seconds"]:.0f} s '
          f'({result["cpu_seconds"]:.0f} CPU s); MuJoCo peer: {result["mujoco"]}')
    for horizon, seconds in zip(('short', 'long'), config.horizons):
        rows = goal_table(result, horizon=horizon)
        counts = goal_summary(rows)
        if counts['no peer'] == len(rows):
            break
        others = ', '.join(f'{count} {name}' for name, count in counts.items()
                           if count and name != 'holds')
        print(f"bench: at {seconds:g} s our best needs at most half of MuJoCo's best CPU at "
              f'{counts["holds"]} of {len(rows)} (body, error level) pairs'
              + (f'; {others}' if others else '')
              + ('' if horizon == 'short' else ' (information only)'))
    if not args.no_tolerance_sweep:
        paths.update(run_tolerance_sweep(args))
    paths.update(run_forces_benchmark(args))
    for path in paths.values():
        print(f'bench: wrote {path}')
    return 0

"""
Measure what accuracy costs in time: the work-precision benchmark, MuJoCo included.

Runs every registered integrator (and MuJoCo's Euler, RK4 and implicitfast when mujoco is
installed) on five torque-free benchmark bodies at dt = 10 .. 0.001 s, measures the
orientation error at 10 s and 100 s against an extended-precision reference, the energy and
|L| drift, and the CPU time per step, and writes results.md (tables), results.json,
results.csv and work_precision.png / work_precision_100s.png (error against CPU per simulated
second) to --out.  --quick: two bodies, three steps and horizons of 2 s and 10 s, for CI
(seconds, not minutes).
"""

import os
import sys
import time

# The benchmark package (scipy, mujoco, matplotlib) is imported inside main(): the command
# line builds every tool's parser at start-up, and `rigid-body-sim run` should not pay for it.


def add_arguments(parser):
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


def _progress_bar(total):
    from tqdm import tqdm
    bar = tqdm(total=total, desc='bench', unit='run', file=sys.stderr,
               dynamic_ncols=True, leave=True)

    def advance(label):
        bar.set_postfix_str(label, refresh=False)
        bar.update(1)
    return bar, advance


def _silence_mujoco_warnings():
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


def main(args):
    """Run the benchmark, write the outputs, print where they are; return 0."""
    from ..benchmark.bodies import benchmark_cases
    from ..benchmark.measure import FULL
    from ..benchmark.measure import QUICK
    from ..benchmark.measure import run_benchmark
    from ..benchmark.measure import work_units
    from ..benchmark.peer_mujoco import mujoco_available
    from ..benchmark.report import goal_summary
    from ..benchmark.report import goal_table
    from ..benchmark.report import machine_info
    from ..benchmark.report import write_outputs

    config = QUICK if args.quick else FULL
    if args.repeats is not None:
        if args.repeats < 1:
            raise ValueError(f'--repeats must be >= 1; got {args.repeats}')
        config = config.__class__(config.cases, config.dts, config.horizons, args.repeats,
                                  config.time_budget)
    with_mujoco = not args.no_mujoco
    if with_mujoco and not mujoco_available():
        print('bench: mujoco is not installed (pip install .[mujoco]): running without the '
              'MuJoCo peer', file=sys.stderr)
    machine = machine_info()
    started = time.perf_counter()
    cpu_started = time.process_time()
    bar, advance = _progress_bar(work_units(config, with_mujoco))
    restore_warnings = _silence_mujoco_warnings()
    try:
        result = run_benchmark(config, with_mujoco=with_mujoco, progress=advance)
    finally:
        bar.close()
        restore_warnings()
    machine['load_average_end'] = list(os.getloadavg())
    result.update({
        'machine': machine,
        'config': {'cases': list(config.cases), 'dts': list(config.dts),
                   'horizons': list(config.horizons), 'repeats': config.repeats,
                   'time_budget': config.time_budget, 'quick': bool(args.quick)},
        'cases': {case.name: case.description for case in benchmark_cases(config.cases)},
        'command': 'rigid-body-sim bench' + (' --quick' if args.quick else '')
                   + ('' if args.repeats is None else f' --repeats {args.repeats}')
                   + (' --no-mujoco' if args.no_mujoco else '') + f' --out {args.out}',
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
    for path in paths.values():
        print(f'bench: wrote {path}')
    return 0

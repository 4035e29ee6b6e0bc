#!/usr/bin/env python3
"""
Measure the sweep engine: 1 vs 2 local workers, its overhead per run, Dask's per task.

Usage: .venv/bin/python benchmarks/sweep_scaling.py [--runs N] [--duration S] [--scene NAME]
       [--rate HZ] [--no-bags] [--rounds R] [--noop-tasks N] [--workers W ...] [--json FILE]

Three measurements, each printed with the machine's load average (/proc/loadavg) before and
after it, since the figures mean little on a loaded machine:

1. Dask's cost per task: N no-op tasks (default 1,000) on a local cluster of 1 and of 2
   single-threaded worker processes: submitted at once (``client.map`` + ``gather``), and
   through the engine (``Engine.run_each``, one item per task: its window of two tasks per
   worker thread); beside them concurrent.futures' ProcessPoolExecutor and multiprocessing's
   Pool (chunksize 1) on the same no-ops, the local alternatives.  Median of 3 repeats,
   wall time per task.
2. Throughput, 1 vs 2 workers side by side: a sweep of N runs (default 200) of the scene
   for S simulated s each (default: `default`, the T-handle, 10 s, every run writing its
   bag), the runs made distinct by a random initial angular velocity.  The worker counts
   alternate in R rounds as 1, 2, 2, 1, ... (ABBA: a drift of the machine's load falls on
   both alike); each measurement starts its own cluster (not timed in the throughput: from
   the first task to the last row) into a fresh output folder.  Throughput is runs per
   wall-clock s; the speed-up is the ratio of the medians.
3. The engine's overhead per run, from the 1-worker sweeps: the wall time per run of the
   sweep less the wall time of a run on its worker (the table's ``wall_seconds``, which is
   the simulation, bag and row), as a share of the latter; and the driver's CPU per run
   (its process holds the client, the scheduler of the local cluster and the table writer:
   on a machine whose cores all run workers, this is what it takes from them).

At the end: the figures the projection of docs/sweep.md rests on (per-run cost, per-task
overhead, driver CPU per row, worker start), as JSON with --json, and the two blocks of text
to paste into the docs as they are: the Scale section of docs/sweep.md (the measured figures
and the projected wall time of a 100,000-run sweep on 100 machines, with the assumption each
term rests on) and the measured bullet of Dask's entry in docs/dependencies.md.
"""

import argparse
import concurrent.futures
import json
import multiprocessing
import os
from pathlib import Path
import platform
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time


def _noop(value):
    return value


def _noop_items(items):
    return items


def _load():
    with open('/proc/loadavg') as loadavg:
        return float(loadavg.read().split()[0])


def _git_revision():
    try:
        return subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], capture_output=True,
                              text=True, check=True,
                              cwd=Path(__file__).resolve().parent).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return '?'


def measure_noops(workers, tasks, repeats=3):
    """Return {method: wall s per task} for `tasks` no-ops on `workers` processes."""
    from rigid_body_sim.sweep import Engine

    figures = {}
    with Engine(workers=workers) as engine:
        client = engine.client
        client.gather(client.map(_noop, range(10), pure=False))
        samples = []
        for _ in range(repeats):
            started = time.perf_counter()
            client.gather(client.map(_noop, range(tasks), pure=False))
            samples.append((time.perf_counter() - started) / tasks)
        figures['dask client.map'] = statistics.median(samples)
        samples = []
        for repeat in range(repeats):
            started = time.perf_counter()
            outcomes = list(engine.run_each(_noop_items, (f'{repeat}-{k}' for k in range(tasks)),
                                            key=str, items_per_task=1))
            assert len(outcomes) == tasks and all(o.error is None for o in outcomes)
            samples.append((time.perf_counter() - started) / tasks)
        figures['engine run_each'] = statistics.median(samples)
    context = multiprocessing.get_context('spawn')
    with concurrent.futures.ProcessPoolExecutor(workers, mp_context=context) as pool:
        list(pool.map(_noop, range(10)))
        samples = []
        for _ in range(repeats):
            started = time.perf_counter()
            futures = [pool.submit(_noop, k) for k in range(tasks)]
            [future.result() for future in futures]
            samples.append((time.perf_counter() - started) / tasks)
        figures['concurrent.futures'] = statistics.median(samples)
    with context.Pool(workers) as pool:
        pool.map(_noop, range(10))
        samples = []
        for _ in range(repeats):
            started = time.perf_counter()
            pool.map(_noop, range(tasks), chunksize=1)
            samples.append((time.perf_counter() - started) / tasks)
        figures['multiprocessing.Pool'] = statistics.median(samples)
    return figures


def scaling_spec(runs, duration, scene, rate, bags, seed):
    """Return the benchmark's spec: `runs` runs of `scene`, distinct initial spins."""
    from rigid_body_sim.scenes import load_scene
    from rigid_body_sim.sweep import parse_spec

    omega = load_scene(scene).state.angular_velocity_body(load_scene(scene).body)
    spread = [0.01 * max(1.0, abs(float(value))) for value in omega]
    data = {'scenes': [scene], 'durations': [duration], 'bags': bags,
            'random': {'count': runs, 'seed': seed, 'draw': {
                'initial.angular_velocity_body': {'uniform': [
                    [float(w) - s for w, s in zip(omega, spread)],
                    [float(w) + s for w, s in zip(omega, spread)]]}}}}
    if rate:
        data['rates'] = [rate]
    return parse_spec(data, 'sweep_scaling')


def measure_sweep(spec, workers, folder):
    """Run `spec` on a fresh local cluster of `workers`; return its figures."""
    from rigid_body_sim.sweep import Engine
    from rigid_body_sim.sweep import read_table
    from rigid_body_sim.sweep import run_sweep
    from rigid_body_sim.sweep.driver import needed_integrators

    load_before = _load()
    started = time.perf_counter()
    with Engine(workers=workers, integrators=needed_integrators(spec)) as engine:
        start_seconds = time.perf_counter() - started
        cpu = time.process_time()
        result = run_sweep(spec, folder, engine=engine)
        driver_cpu = time.process_time() - cpu
    bags = Path(folder) / 'bags'
    bag_bytes = sum(path.stat().st_size for path in bags.rglob('*') if path.is_file()) \
        if bags.is_dir() else 0
    table = read_table(folder, ['wall_seconds', 'cpu_seconds', 'status'])
    walls = table.column('wall_seconds').to_pylist()
    cpus = table.column('cpu_seconds').to_pylist()
    assert result.done == len(walls) == spec.run_count, (result.done, len(walls))
    assert set(table.column('status').to_pylist()) == {'ok'}
    return {'workers': workers, 'runs': result.done, 'seconds': result.seconds,
            'throughput': result.done / result.seconds, 'start_seconds': start_seconds,
            'run_wall_mean': statistics.fmean(walls), 'run_cpu_mean': statistics.fmean(cpus),
            'driver_cpu_per_run': driver_cpu / result.done,
            'bag_bytes_per_run': bag_bytes / result.done, 'load': (load_before, _load())}


def _cpu_name():
    try:
        with open('/proc/cpuinfo') as cpuinfo:
            for line in cpuinfo:
                if line.startswith('model name'):
                    return line.partition(':')[2].strip()
    except OSError:
        pass
    return platform.processor() or 'unknown CPU'


def _wrap(text, indent=''):
    """Return `text` wrapped at 95 columns; a list item's lines go under its first word."""
    words = ' '.join(text.split())
    under = indent + ('  ' if words.startswith('- ') else '')
    return textwrap.fill(words, 95, initial_indent=indent, subsequent_indent=under,
                         break_on_hyphens=False)


def _duration(seconds):
    if seconds >= 3600:
        return f'{seconds / 3600:.1f} h'
    return f'{seconds / 60:.0f} min' if seconds >= 120 else f'{seconds:.0f} s'


def scale_block(figures, args, started_load, revision, date):
    """Return the Scale section's text for docs/sweep.md (replacing its placeholder)."""
    summary = figures['summary']
    first, second = args.workers
    throughput = summary['throughput']
    ones = [s for s in figures['sweeps'] if s['workers'] == first]
    run_wall, run_cpu = summary['run_wall'], summary['run_cpu']
    noop = figures['noop'].get(second) or figures['noop'].get(first) or {}
    per_task = noop.get('engine run_each', 0.0)
    runs, machines, workers = 100_000, 100, os.cpu_count()
    runs_per_task = max(1, int(1.0 / run_wall))  # as the engine sizes its tasks
    compute = runs * run_wall / (machines * workers)
    scheduling = runs / runs_per_task * per_task
    driver = runs * summary['driver_cpu_per_run']
    start = summary['start_seconds']
    tail = runs_per_task * run_wall
    wall = start + max(compute, scheduling, driver) + tail
    bag_bytes = statistics.median(s['bag_bytes_per_run'] for s in figures['sweeps'])
    bags = 'rows only' if args.no_bags else f'each writing its bag ({bag_bytes / 1e6:.2f} MB)'
    loads = [load for s in figures['sweeps'] for load in s['load']]
    lines = [
        _wrap(f'Measured by `.venv/bin/python benchmarks/sweep_scaling.py'
              f'{"" if args.runs == 200 else f" --runs {args.runs}"}` (git {revision}, {date}, '
              f'{_cpu_name()}, {os.cpu_count()} cores; load average {started_load:.2f} at the '
              f'start, {min(loads):.2f} to {max(loads):.2f} during the sweeps): {args.runs} runs '
              f'of `{args.scene}` for {args.duration:g} simulated s, {bags}, each distinct (a '
              f'random initial spin), on a local cluster of {first} and of {second} worker '
              f'processes, alternated {", ".join(str(s["workers"]) for s in figures["sweeps"])} '
              f'(ABBA), each from its first task to its last row.'),
        '',
        f'| workers | runs/s (median of {len(ones)}) | speed-up |',
        '| --- | --- | --- |',
        f'| {first} | {throughput[first]:.2f} | 1 |',
        f'| {second} | {throughput[second]:.2f} | {summary["speedup"]:.2f}x (goal: at least '
        '1.8x) |',
        '',
        _wrap(f'- A run costs {run_wall * 1e3:.0f} ms wall, {run_cpu * 1e3:.0f} ms CPU on its '
              'worker (scene, simulation, bag, row).'),
        _wrap(f'- The overhead of the engine per run, with {first} worker: the wall time of '
              'the sweep per run less the wall time of the run on its worker (scheduling, '
              f'transfer, the row of the table), {summary["overhead_per_run"] * 1e3:.1f} ms, '
              f'{100 * summary["overhead_share"]:.1f} % of a run (goal: at most 5 %); the '
              'driver (client, local scheduler, table writer) spends '
              f'{summary["driver_cpu_per_run"] * 1e3:.2f} ms of CPU per row.'),
        _wrap(f'- The cost per task, {args.noop_tasks:,} no-op tasks on {second} workers '
              '(median of 3): ' + ', '.join(f'{name} {seconds * 1e3:.2f} ms'
                                            for name, seconds in noop.items()) + '.'),
        _wrap(f'- A local cluster starts with its kernels loaded in {start:.1f} s (median; '
              'the machine has the kernels compiled: a new machine compiles them once first, '
              'see [Kernels on the workers](#kernels-on-the-workers)).'),
        '',
        _wrap(f'Projected: {runs:,} such runs on {machines} machines like this one, '
              f'{workers} single-threaded workers each ({machines * workers} workers), one '
              f'scheduler, one driver: about **{_duration(wall)}**, the largest of three '
              'rates plus the start and the last task:'),
        '',
        _wrap(f'- compute, {runs:,} x {run_wall * 1e3:.0f} ms / {machines * workers} workers = '
              f'{_duration(compute)}: each worker as fast as here and busy throughout (tasks '
              'are sized to about 1 s, two out per worker thread, so a worker waits for no '
              'round trip);'),
        _wrap(f'- the scheduler, {runs // runs_per_task:,} tasks of {runs_per_task} runs (1 s '
              f'/ {run_wall * 1e3:.0f} ms) x {per_task * 1e3:.2f} ms = '
              f'{_duration(scheduling)}: its cost per task as measured on the local cluster '
              '(no network; the network round trip of a task overlaps the work of the next), '
              'the same with 200 workers (the scheduler of Dask handles tasks one at a time);'),
        _wrap(f'- the driver, {runs:,} rows x {summary["driver_cpu_per_run"] * 1e3:.2f} ms = '
              f'{_duration(driver)}: every row reaches one driver, which writes the table '
              '(measured with the local scheduler in the same process, so an upper bound);'),
        _wrap(f'- plus the start, {start:.0f} s (the workers start in parallel, on machines '
              f'whose kernels are compiled), and the last task, {tail:.0f} s.'),
    ]
    if not args.no_bags:
        lines.append(_wrap(
            f'- The bags, {runs:,} x {bag_bytes / 1e6:.2f} MB = {runs * bag_bytes / 1e9:.0f} '
            f'GB, reach the shared file system at {runs * bag_bytes / wall / 1e6:.0f} MB/s '
            'over that time: a file system slower than that is the limit instead.'))
    return '\n'.join(lines)


def dask_block(figures, args):
    """Return the measured bullet of Dask's entry in docs/dependencies.md."""
    summary = figures['summary']
    parts = []
    for workers, noop in figures['noop'].items():
        parts.append(f'on {workers} worker(s): ' + ', '.join(
            f'{name} {seconds * 1e3:.2f} ms' for name, seconds in noop.items()))
    return _wrap(
        f'- the cost per task, {args.noop_tasks:,} no-op tasks (median of 3), '
        + '; '.join(parts) + f'; on the {args.runs}-run sweep of {args.duration:g}-s runs the '
        f'whole overhead of the engine is {summary["overhead_per_run"] * 1e3:.1f} ms per run, '
        f'{100 * summary["overhead_share"]:.1f} % of a run, and {args.workers[1]} workers give '
        f'{summary["speedup"]:.2f}x the throughput of {args.workers[0]}'
        + (': the lower cost per task of the pools buys nothing that shows at tasks of a second;'
           if summary['overhead_share'] <= 0.05 else
           ': more overhead than the 5 % of a run the engine is allowed (docs/sweep.md, Scale);'),
        '  ')


def main():
    """Run the measurements and print them."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--runs', type=int, default=200, help='runs per sweep (default 200)')
    parser.add_argument('--duration', type=float, default=10.0,
                        help='simulated s per run (default 10)')
    parser.add_argument('--scene', default='default', help='scene (default: default)')
    parser.add_argument('--rate', type=float, help="tick rate in Hz (default: the scene's)")
    parser.add_argument('--no-bags', action='store_true', help='rows only, no bags')
    parser.add_argument('--rounds', type=int, default=2,
                        help='ABBA rounds of 1 and 2 workers (default 2: 1, 2, 2, 1)')
    parser.add_argument('--noop-tasks', type=int, default=1000,
                        help='no-op tasks per repeat (default 1000); 0: skip')
    parser.add_argument('--workers', type=int, nargs=2, default=(1, 2), metavar=('A', 'B'),
                        help='the two worker counts compared (default 1 2)')
    parser.add_argument('--json', help='also write the figures to this JSON file')
    args = parser.parse_args()

    started_load = _load()
    revision = _git_revision()
    date = time.strftime('%Y-%m-%d', time.gmtime())
    print(f'git {revision}, {os.cpu_count()} cores, load average {started_load:.2f} at '
          'start', flush=True)
    figures = {'noop': {}, 'sweeps': []}
    if args.noop_tasks:
        for workers in args.workers:
            load = _load()
            noop = measure_noops(workers, args.noop_tasks)
            figures['noop'][workers] = noop
            print(f'{args.noop_tasks} no-op tasks, {workers} worker(s) (load {load:.2f} -> '
                  f'{_load():.2f}): ' + ', '.join(f'{name} {seconds * 1e3:.3f} ms'
                                                  for name, seconds in noop.items()),
                  flush=True)
    first, second = args.workers
    order = []
    for round_ in range(args.rounds):
        order += [first, second] if round_ % 2 == 0 else [second, first]
    with tempfile.TemporaryDirectory(prefix='sweep_scaling-') as scratch:
        for index, workers in enumerate(order):
            spec = scaling_spec(args.runs, args.duration, args.scene, args.rate,
                                not args.no_bags, seed=index)
            sweep = measure_sweep(spec, workers, Path(scratch) / f'sweep{index}')
            figures['sweeps'].append(sweep)
            print(f'{sweep["runs"]} runs of {args.duration:g} s ({args.scene}, '
                  f'{"rows only" if args.no_bags else "bags"}), {workers} worker(s): '
                  f'{sweep["seconds"]:.1f} s, {sweep["throughput"]:.2f} runs/s; a run '
                  f'{sweep["run_wall_mean"] * 1e3:.0f} ms wall, {sweep["run_cpu_mean"] * 1e3:.0f} '
                  f'ms CPU on its worker; driver CPU {sweep["driver_cpu_per_run"] * 1e3:.2f} ms '
                  f'per run; cluster start {sweep["start_seconds"]:.1f} s; load '
                  f'{sweep["load"][0]:.2f} -> {sweep["load"][1]:.2f}', flush=True)
    by_workers = {workers: [s for s in figures['sweeps'] if s['workers'] == workers]
                  for workers in args.workers}
    throughput = {workers: statistics.median(s['throughput'] for s in sweeps)
                  for workers, sweeps in by_workers.items()}
    speedup = throughput[second] / throughput[first]
    ones = by_workers[first]
    overhead = statistics.median(s['seconds'] / s['runs'] - s['run_wall_mean'] for s in ones)
    run_wall = statistics.median(s['run_wall_mean'] for s in ones)
    figures['summary'] = {
        'throughput': throughput, 'speedup': speedup, 'overhead_per_run': overhead,
        'overhead_share': overhead / run_wall, 'run_wall': run_wall,
        'run_cpu': statistics.median(s['run_cpu_mean'] for s in figures['sweeps']),
        'driver_cpu_per_run': statistics.median(s['driver_cpu_per_run']
                                                for s in figures['sweeps']),
        'start_seconds': statistics.median(s['start_seconds'] for s in figures['sweeps'])}
    summary = figures['summary']
    print(f'throughput: {first} worker(s) {throughput[first]:.2f} runs/s, {second} worker(s) '
          f'{throughput[second]:.2f} runs/s: {speedup:.2f}x')
    print(f'engine overhead per run ({first} worker): {overhead * 1e3:.1f} ms, '
          f'{100 * summary["overhead_share"]:.1f} % of a run ({run_wall * 1e3:.0f} ms on its '
          f'worker); driver CPU {summary["driver_cpu_per_run"] * 1e3:.2f} ms per run')
    print(f'load average {_load():.2f} at the end')
    print('\n---- docs/sweep.md: in place of the placeholder SCALE_FIGURES ----')
    print(scale_block(figures, args, started_load, revision, date))
    if args.noop_tasks:
        print('\n---- docs/dependencies.md: in place of the placeholder DASK_FIGURES ----')
        print(dask_block(figures, args))
    print('---- end ----')
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())

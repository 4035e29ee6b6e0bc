"""
The benchmark's outputs: analysis, markdown report, JSON/CSV data and the plot.

Analysis (pure functions of the measured records):

- :func:`cost_to_reach`: the CPU per simulated second a method needs to reach an orientation
  error level at a horizon, interpolated linearly in log-log between two measured time steps
  that both track the motion (error ~ C dt^p and cost ~ 1/dt make a straight line there),
  or bounded from above / below where the measured steps only bracket it (a :class:`Reach`).
  Measured errors below the reference's uncertainty are raised to it first: nobody is
  credited with an accuracy the reference cannot resolve.
- :func:`goal_table`: per body and level 1e-2 .. 1e-12 rad, our best integrator against
  MuJoCo's best, and whether ours needs at most half the CPU (:func:`verdict`), from the
  bounds only: never a verdict without a number.
- :func:`augmentation_table`: Buss's augmented method against buss_plain, body by body.

Files: results.md, results.json, results.csv, work_precision.png (the short horizon, where the
goal is defined) and work_precision_<long>s.png in one directory.
"""

import csv
from dataclasses import asdict
from dataclasses import dataclass
import datetime
import json
import math
import os
from pathlib import Path
import platform
import statistics
import subprocess

import numpy as np

from .cells import CPU_CLOCK_NAME
from .cells import cpu_model
from .extended_reference import key_string
from .reference import MEASUREMENT_FLOOR

__all__ = ['machine_info', 'workers_line', 'cost_to_reach', 'Reach', 'verdict', 'goal_table',
           'goal_summary', 'augmentation_table', 'step_costs', 'write_outputs', 'case_panels',
           'save_figure', 'write_records_csv', 'method_styles', 'read_results',
           'work_precision_figure', 'GOAL_LEVELS', 'SATURATION']

# Orientation error levels (rad) at which the CPU cost of ours and MuJoCo's are compared.
GOAL_LEVELS = tuple(10.0 ** -k for k in range(2, 13))
GOAL_RATIO = 0.5
# An orientation error (rad) at or above which a method is not tracking the motion: errors
# of random rotations are O(1) (mean ~2.1 rad), so 0.5 rad is far from converging, and the
# log-log interpolation is never taken across such a point.
SATURATION = 0.5
# The steps the issue names for the sweep: the goal is judged on these first (both sides),
# then again with the coarse steps the sweep adds, which only the exact flow can use well.
ISSUE_DTS = (0.1, 0.03, 0.01, 0.003, 0.001)
VERDICTS = ('holds', 'holds*', 'not decided', 'fails', 'neither reaches', 'unresolved',
            'no peer')


def _version(module_name):
    try:
        module = __import__(module_name)
    except ImportError:
        return 'not installed'
    return getattr(module, '__version__', 'unknown')


def _git(*args):
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        # rstrip only: porcelain status lines start with a space ( M path).
        return subprocess.run(['git', *args], cwd=here, capture_output=True, text=True,
                              timeout=10, check=True).stdout.rstrip()
    except (OSError, subprocess.SubprocessError):
        return None


def _git_commit():
    """Return (short commit, [tracked package files with uncommitted changes]) or 'unknown'."""
    commit = _git('rev-parse', '--short', 'HEAD')
    if commit is None:
        return 'unknown', []
    # The code the benchmark measures and runs: the physics core and the benchmark itself.
    status = _git('status', '--porcelain', '--untracked-files=no', '--', '.', '../physics',
                  '../tools/bench.py')
    return commit, sorted(line[3:] for line in (status or '').splitlines() if line.strip())


def workers_line(info):
    """
    Return the sentence saying where the cells ran, from a result's machine info.

    info['cells_ran_on'] (set by the bench command): 'engine' (in words), 'workers' (worker
    processes), 'hosts' ([{'host', 'cpu_model', 'workers', 'cells'}]) and 'start_seconds'
    (the cluster's start, its workers' kernels loaded); without it, the cells ran in the
    process that wrote the report.
    """
    ran_on = info.get('cells_ran_on')
    if not ran_on or not ran_on.get('hosts'):
        return 'Cells ran in this process, one after another.'
    hosts = '; '.join(f'{h["host"]} ({h["cpu_model"]}): {h["workers"]} worker(s), '
                      f'{h["cells"]} cells' for h in ran_on['hosts'])
    started = ran_on.get('start_seconds')
    return (f'Cells ran on {ran_on["engine"]}, {ran_on["workers"]} worker process(es), each '
            f'cell timed on the worker that ran it: {hosts}'
            + ('.' if started is None else
               f' (the cluster started, kernels loaded, in {started:.1f} s).'))


def machine_info():
    """Return a dict describing this machine and the software versions."""
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    model, physical = cpu_model()
    commit, modified = _git_commit()
    return {
        'cpu_model': model,
        'physical_cores': physical,
        'logical_cores': os.cpu_count(),
        'usable_cores': usable,
        'platform': platform.platform(),
        'python': platform.python_version(),
        'numpy': _version('numpy'),
        'scipy': _version('scipy'),
        'numba': _version('numba'),
        'mujoco': _version('mujoco'),
        'git_commit': commit,
        'git_modified': modified,
        'timer': CPU_CLOCK_NAME,
        'date_utc': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
        'load_average_start': list(os.getloadavg()),
    }


# -- analysis

HORIZONS = ('short', 'long')


def _floors(result, case, horizon):
    """Return {dt: reference uncertainty (rad)} at the runs' times at one horizon."""
    uncertainty = result['references'][case]['uncertainty']
    return {r['dt']: uncertainty.get(key_string(r[f'steps_{horizon}'], r['dt']), 0.0)
            for r in result['records'] if r['case'] == case}


def resolution(result, case, horizon='short'):
    """Return the largest uncertainty (rad) of the reference at a horizon: its resolution."""
    return max(_floors(result, case, horizon).values(), default=0.0)


def _curve(result, case, method, horizon='short', dts=None):
    """
    Return [(dt, cost, error)] of one method, in order of decreasing dt (those in `dts`).

    The error at the horizon is raised to the reference's uncertainty (nobody is credited
    with an accuracy the reference cannot resolve); a diverged run's error is inf.
    """
    floors = _floors(result, case, horizon)
    records = [r for r in result['records'] if r['case'] == case and r['method'] == method
               and (dts is None or any(math.isclose(r['dt'], dt) for dt in dts))]
    records.sort(key=lambda r: -r['dt'])
    return [(r['dt'], r['cpu_per_sim_second'], max(r[f'error_{horizon}'], floors[r['dt']]))
            for r in records]


def tracking(error):
    """Return True when a measured error shows the method follows the motion (< SATURATION)."""
    return math.isfinite(error) and error < SATURATION


@dataclass(frozen=True)
class Reach:
    """
    What one method costs to reach an error level, as far as the measured steps tell.

    cost: the CPU s per simulated s to reach the level (inf: no measured step reaches it);
    lower: a lower bound on that cost (0: none known); kind: 'interpolated' (log-log
    between two tracking steps, taken as the cost: lower = cost), 'coarsest' (the coarsest
    measured step already reaches the level: an upper bound only), 'after saturated' (the
    first step that reaches it follows a step with a saturated or diverged error, across
    which nothing is interpolated: the cost is in (lower, cost]), 'not reached' (lower is
    the cost of the finest measured step: reaching the level needs a finer, dearer step);
    dts: the measured step(s) the figure comes from.
    """

    cost: float
    lower: float
    kind: str
    dts: tuple


def cost_to_reach(points, level):
    """
    Return the Reach of error <= `level` on a work-precision curve.

    Parameters
    ----------
    points : list of (dt, cost, error)
        In order of decreasing dt (dt in s, cost in CPU s per simulated s, error in rad;
        inf for a diverged run).
    level : float
        Target error (rad).

    Assumes what holds for a convergent method above its round-off: cost rises and error
    falls as dt falls.  The first measured step that reaches the level is found; the cost
    there is interpolated in log-log from the step before it only when both track the
    motion (error < SATURATION): an error of O(1) rad says nothing about the rate, and a
    line through it would put the crossing at a made-up cost.

    """
    for index, (dt, cost, error) in enumerate(points):
        if not (tracking(error) and error <= level):
            continue
        if index == 0:
            return Reach(cost, 0.0, 'coarsest', (dt,))
        dt_a, cost_a, error_a = points[index - 1]
        if not tracking(error_a):
            return Reach(cost, cost_a, 'after saturated', (dt_a, dt))
        fraction = (math.log(level) - math.log(error_a)) / (math.log(error) - math.log(error_a))
        value = math.exp(math.log(cost_a) + fraction * (math.log(cost) - math.log(cost_a)))
        return Reach(value, value, 'interpolated', (dt_a, dt))
    if not points:
        return Reach(math.inf, 0.0, 'not reached', ())
    return Reach(math.inf, points[-1][1], 'not reached', (points[-1][0],))


def _family(result, case, methods, level, horizon, dts=None):
    """Return (best method, its Reach, lower bound of the family, method giving that bound)."""
    reaches = {method: cost_to_reach(_curve(result, case, method, horizon, dts), level)
               for method in methods}
    if not reaches:
        return None, None, 0.0, None
    best = min(reaches, key=lambda method: (reaches[method].cost, reaches[method].lower))
    # Whichever of the family reaches the level, it pays at least its own lower bound.
    bound = min(reaches, key=lambda method: reaches[method].lower)
    return best, reaches[best], reaches[bound].lower, bound


def verdict(ours, ours_lower, peer, peer_lower, level, reference_resolution):
    """
    Return (verdict, ratio_low, ratio_high) for one level from both sides' cost bounds.

    ours, peer: the best cost of each side (inf: not reached); ours_lower, peer_lower: the
    lower bounds (0: none known).  The goal needs ours <= GOAL_RATIO x peer.  'holds' when
    even ours' upper figure is at most half of the peer's lower bound; 'fails' when ours'
    lower bound is above half of the peer's upper figure; 'holds*' when it holds against
    the peer's cost at its coarsest measured step, which has no lower bound (a coarser step,
    not measured, might be cheaper); otherwise 'not decided'.  'unresolved': the level is
    below the reference's resolution; 'neither reaches': no measured step of either side.
    """
    ratio_high = ours / peer_lower if peer_lower > 0.0 else math.inf
    ratio_low = ours_lower / peer if math.isfinite(peer) else 0.0
    if level < reference_resolution:
        return 'unresolved', ratio_low, ratio_high
    if math.isinf(ours) and math.isinf(peer):
        return 'neither reaches', ratio_low, ratio_high
    if ratio_high <= GOAL_RATIO:
        return 'holds', ratio_low, ratio_high
    if ratio_low > GOAL_RATIO:
        return 'fails', ratio_low, ratio_high
    if peer_lower == 0.0 and ours / peer <= GOAL_RATIO:
        return 'holds*', ratio_low, ratio_high
    return 'not decided', ratio_low, ratio_high


def goal_table(result, levels=GOAL_LEVELS, horizon='short', dts=None):
    """
    Return rows comparing our best and MuJoCo's best per case and error level at a horizon.

    `dts`: judge on these measured steps only (both sides); None: on every measured step.

    Each row: dict with case, horizon, level, ours (method), ours_reach and mujoco_reach
    (Reach as a dict), mujoco (method), mujoco_lower (the lower bound of MuJoCo's best cost,
    over all its integrators) and mujoco_bound_method, resolution (the reference's, rad),
    ratio_low / ratio_high (bounds of ours / MuJoCo; equal when both are interpolated) and
    verdict (see :func:`verdict`; 'no peer' without MuJoCo).
    """
    ours = [m for m in result['methods'] if not m.startswith('mujoco_')]
    peers = [m for m in result['methods'] if m.startswith('mujoco_')]
    rows = []
    for case in result['references']:
        floor = resolution(result, case, horizon)
        for level in levels:
            ours_method, ours_reach, ours_lower, _ = _family(
                result, case, ours, level, horizon, dts)
            peer_method, peer_reach, peer_lower, bound_method = _family(
                result, case, peers, level, horizon, dts)
            if peers:
                outcome, ratio_low, ratio_high = verdict(
                    ours_reach.cost, ours_lower, peer_reach.cost, peer_lower, level, floor)
            else:
                outcome, ratio_low, ratio_high = 'no peer', math.nan, math.nan
            rows.append({
                'case': case, 'horizon': horizon, 'level': level,
                'ours': ours_method, 'ours_reach': asdict(ours_reach),
                'ours_lower': ours_lower,
                'mujoco': peer_method,
                'mujoco_reach': None if peer_reach is None else asdict(peer_reach),
                'mujoco_lower': peer_lower, 'mujoco_bound_method': bound_method,
                'resolution': floor, 'ratio_low': ratio_low, 'ratio_high': ratio_high,
                'verdict': outcome})
    return rows


def goal_summary(rows):
    """Return {verdict: count} over goal rows, every verdict present (0 when absent)."""
    counts = dict.fromkeys(VERDICTS, 0)
    for row in rows:
        counts[row['verdict']] = counts.get(row['verdict'], 0) + 1
    return counts


def augmentation_table(result):
    """
    Return rows comparing 'buss' with 'buss_plain' per case and dt.

    Each row: case, dt, the error ratios plain/buss at both horizons and for the energy,
    cost_ratio (buss/plain us per step, the median over the whole run: the per-run timings
    are too noisy to decide on), and verdict: 'yes' when buss's error at the short horizon is
    lower by more than max(1, cost_ratio^2) (a second-order method buys an error ratio r^2
    with r times the steps, so that is the break-even), 'no' otherwise, and 'n/a' when both
    errors exceed 0.1 rad (neither tracks the motion, so there is no accuracy to compare).
    """
    if 'buss' not in result['methods'] or 'buss_plain' not in result['methods']:
        return []
    index = {(r['case'], r['method'], r['dt']): r for r in result['records']}
    # Runs of >= 1000 steps when there are any: shorter ones time mostly the call overhead.
    pairs = [(index[(case, 'buss', dt)], index[(case, 'buss_plain', dt)])
             for case, method, dt in index if method == 'buss']
    pairs = [pair for pair in pairs if pair[0]['steps_long'] >= 1000] or pairs
    cost_ratio = statistics.median(buss['us_per_step'] / plain['us_per_step']
                                   for buss, plain in pairs)
    rows = []
    for case in result['references']:
        for dt in sorted({r['dt'] for r in result['records'] if r['case'] == case},
                         reverse=True):
            buss, plain = index[(case, 'buss', dt)], index[(case, 'buss_plain', dt)]

            def ratio(key, plain=plain, buss=buss):
                a, b = max(plain[key], 1e-300), max(buss[key], 1e-300)
                return a / b if math.isfinite(a) and math.isfinite(b) else math.nan
            short_ratio = ratio('error_short')
            if not min(buss['error_short'], plain['error_short']) < 0.1:
                pays_off = 'n/a'
            else:
                pays_off = 'yes' if short_ratio > max(1.0, cost_ratio ** 2) else 'no'
            rows.append({'case': case, 'dt': dt, 'short_ratio': short_ratio,
                         'long_ratio': ratio('error_long'),
                         'energy_ratio': ratio('max_energy_error'),
                         'cost_ratio': cost_ratio, 'verdict': pays_off})
    return rows


def step_costs(result):
    """
    Return {method: (median, min, max)} of the us per step over its runs.

    Only runs of >= 1000 steps count when a method has any (shorter ones mostly time the
    per-call overhead).
    """
    costs = {}
    for method in result['methods']:
        runs = [r for r in result['records'] if r['method'] == method]
        long_runs = [r for r in runs if r['steps_long'] >= 1000] or runs
        values = [r['us_per_step'] for r in long_runs]
        costs[method] = (statistics.median(values), min(values), max(values))
    return costs


# -- formatting

def _error(value, floor=0.0):
    if not math.isfinite(value):
        return 'diverged'
    if value < floor:
        return f'<{floor:.0e}'
    return f'{value:.2e}'


def _dts(dts):
    return '-'.join(f'{dt:g}' for dt in dts)


def _reach_cell(method, reach):
    """Return the (method, cost) cells of one side's best at a level."""
    if reach is None:
        return '-', ''
    cost, lower, kind = reach['cost'], reach['lower'], reach['kind']
    where = f'{method} (dt {_dts(reach["dts"])})' if method else '-'
    if kind == 'interpolated':
        return where, f'{cost:.2e}'
    if kind == 'coarsest':
        return where, f'<= {cost:.2e}'
    if kind == 'after saturated':
        return where, f'{lower:.1e} - {cost:.2e}'
    return '-', 'not reached'


def _ratio_cell(row):
    low, high = row['ratio_low'], row['ratio_high']
    if math.isnan(low) or (math.isinf(high) and low == 0.0):
        return ''
    if low == high:
        return f'{high:.2g}'
    if low == 0.0:
        return f'<= {high:.2g}'
    if math.isinf(high):
        return f'>= {low:.2g}'
    return f'{low:.2g} - {high:.2g}'


def _verdict_cell(row):
    outcome = row['verdict']
    peer = row['mujoco_reach']
    if outcome == 'unresolved':
        return f'unresolved (reference +- {row["resolution"]:.0e} rad)'
    never_reached = peer is not None and peer['kind'] == 'not reached'
    if never_reached and outcome in ('holds', 'not decided'):
        return (f'{outcome} (MuJoCo > {row["mujoco_lower"]:.2e}: '
                f'{row["mujoco_bound_method"]} at its finest step does not reach the level)')
    if outcome == 'not decided':
        return 'not decided (the cost bounds straddle 1/2)'
    if outcome == 'holds*':
        return 'holds* (against MuJoCo at its coarsest step only)'
    return outcome


def _goal_section(result, rows, horizon_seconds, informational, steps=''):
    counts = goal_summary(rows)
    total = len(rows)
    held = counts['holds']
    parts = [f'{counts[v]} {v}' for v in VERDICTS[1:] if counts[v]]
    title = (f'### At {horizon_seconds:g} s{steps} (information only: the goal is defined at '
             '10 s)' if informational else f'### At {horizon_seconds:g} s{steps}: the goal')
    lines = [title, '',
             f"Our best needs at most half the CPU of MuJoCo's best at **{held} of {total}** "
             '(body, level) pairs' + (f'; {", ".join(parts)}' if parts else '') + '.  '
             'No pair is left out of the count.', '']
    for case in result['references']:
        lines += [f'#### {case} ({horizon_seconds:g} s{steps})', '',
                  '| error level (rad) | our best | CPU s/sim s | MuJoCo best | CPU s/sim s | '
                  'ours / MuJoCo | at most half? |',
                  '|---|---|---|---|---|---|---|']
        for row in (r for r in rows if r['case'] == case):
            ours_where, ours_cost = _reach_cell(row['ours'], row['ours_reach'])
            if row['mujoco_reach'] is not None and row['mujoco_reach']['kind'] == 'not reached':
                peer_where, peer_cost = '- (none reaches)', f'> {row["mujoco_lower"]:.2e}'
            else:
                peer_where, peer_cost = _reach_cell(row['mujoco'], row['mujoco_reach'])
                if row['mujoco_reach'] is not None and (
                        row['mujoco_lower'] < row['mujoco_reach']['lower']):
                    # Another MuJoCo integrator might reach the level more cheaply at a step
                    # that was not measured: the lower bound comes from it.
                    peer_cost += f' (>= {row["mujoco_lower"]:.1e})'
            lines.append(f'| {row["level"]:.0e} | {ours_where} | {ours_cost} | {peer_where} | '
                         f'{peer_cost} | {_ratio_cell(row)} | {_verdict_cell(row)} |')
        lines.append('')
    return lines


def _off_horizon(result):
    """Return ' (for dt = ...: ... s)' naming the runs whose N dt misses the horizons."""
    short, long = result['config']['horizons']
    missed = []
    for dt in result['config']['dts']:
        times = [round(horizon / dt) * dt for horizon in (short, long)]
        if any(abs(t - h) > 1e-9 * h for t, h in zip(times, (short, long))):
            missed.append(f'dt = {dt:g}: {times[0]:.6g} and {times[1]:.6g} s')
    return f' ({"; ".join(missed)})' if missed else ''


def _markdown(result, goal_rows, long_rows, augmentation_rows, issue_rows=()):
    info = result['machine']
    config = result['config']
    short, long = config['horizons']
    dts = ', '.join(f'{d:g}' for d in config['dts'])
    modified = info.get('git_modified') or []
    cores = (f'{info["physical_cores"]} physical / ' if info.get('physical_cores') else '')
    lines = [
        '# Work-precision benchmark: what accuracy costs in time',
        '',
        f'Produced by `{result["command"]}` on {info["date_utc"]} (git {info["git_commit"]}'
        + (f', with uncommitted changes in {", ".join(modified)}' if modified else '')
        + "). Regenerate with the same command; the numbers below are this run's.",
        '',
        '## Machine',
        '',
        f'- CPU: {info["cpu_model"]}, {cores}{info["logical_cores"]} logical cores '
        f'({info["usable_cores"]} usable by this process); {info["platform"]}',
        f'- Python {info["python"]}, numpy {info["numpy"]}, scipy {info["scipy"]}, '
        f'numba {info["numba"]}, mujoco {info["mujoco"]}',
        '- Load average (1, 5, 15 min) at start: '
        + ', '.join(f'{v:.2f}' for v in info['load_average_start'])
        + '; at end: ' + ', '.join(f'{v:.2f}' for v in info['load_average_end'])
        + f'. Wall time of the whole run: {result["wall_seconds"]:.0f} s; CPU time of the '
        f'command\'s own process: {result.get("cpu_seconds", math.nan):.0f} s.',
        f'- {workers_line(info)}',
        f'- Timer: {info.get("timer", "time.process_time")}.  On a loaded machine the CPU '
        'times still vary by tens of percent from run to run (caches and frequency are '
        'shared): read costs to about a factor 1.5.',
        '',
        '## What is measured',
        '',
        f'Every body x integrator x dt in {{{dts}}} s, torque-free, 1 kg at rest at the '
        'origin, starting at its initial orientation R0 and body angular velocity Omega0.  '
        f'The coarse steps (up to one step per {max(config["dts"]):g} s) are there so that '
        'every front reaches its cheap end: the exact flow is at its most accurate with the '
        'fewest steps, and the explicit methods simply show O(1) errors there.',
        '',
        f'- **err {short:g} s / err {long:g} s**: orientation error, the rotation angle (rad) '
        'between the computed R and the reference R, after N = round(T/dt) steps of exactly '
        'dt; the reference is taken at exactly N x dt' + _off_horizon(result) + '.',
        '- **max dE/E**: max relative kinetic-energy error, sampled every ~0.1 s of simulated '
        f'time (every step for dt >= 0.1) over {long:g} s: the informative conservation '
        'column (symplectic methods keep it bounded, the others drift).',
        '- **max d|L|/|L|**: the same for the magnitude of the angular momentum.  It is 0 '
        "for all of this project's integrators by construction: the world angular momentum "
        'L is part of their state and a torque-free step never changes it (only the '
        "orientation moves).  MuJoCo's state is the body angular velocity, so for its "
        'integrators this column measures something.',
        f'- **us/step** and **CPU s/sim s**: CPU time of one call that advances {long:g} s '
        'from a fresh start, `Simulator.run` for ours and `mujoco.mj_step(model, data, nstep)` '
        'for MuJoCo (each its own compiled loop, the per-call overhead included: it matters '
        'only at the coarsest steps), as the mean over enough fresh calls to fill 2 ms, '
        f'median of up to {config["repeats"]} such samples (fewer once '
        f'{config["time_budget"]:g} CPU s are spent), after an untimed warm-up run (numba '
        'compilation is never timed).',
        f'- MuJoCo: {result["mujoco"]}.  One free body with the same mass and inertia '
        'tensor (`fullinertia` when it is not diagonal), gravity 0, contacts and '
        'constraints disabled; its qvel angular part is the body-frame angular velocity and '
        'qpos holds (w, x, y, z): converted at the boundary, and the errors are computed by '
        'the same code as ours.  `diverged`: the run blew up before that measurement (a '
        "non-finite state, or MuJoCo's QACC warning).",
        '',
        '### Bodies',
        '',
    ]
    for name, description in result['cases'].items():
        lines.append(f'- `{name}`: {description}')
    lines += [
        '',
        '### Reference',
        '',
        "An extended-precision solution, independent of every integrator it scores: Euler's "
        'equations for the body angular momentum with the orientation quaternion, integrated '
        'by a Taylor series method (orders 40 and 49, Jorba-Zou step control) in decimal '
        'arithmetic at 34 and at 42 digits, from the exact double values of the initial '
        'state and inertia tensor, at exactly N x dt (`rigid_body_sim/work_precision/'
        'extended_reference.py`; its values for these bodies are committed in '
        '`data/reference_values.json`, and `benchmarks/regenerate_references.py --set bodies` '
        'recomputes them in about half a CPU minute).  Its uncertainty is the angle between '
        f'the two solves, and never below {MEASUREMENT_FLOOR:.0e} rad (what the angle between '
        'two double rotation matrices resolves).  Errors below it are shown as `<` that '
        'value and raised to it in the analysis; an error level below it is `unresolved`.  '
        'Two double-precision solutions are compared with it: the exact flow '
        '(`INTEGRATORS["exact"]`) in one step from t = 0, and a DOP853 solve (rtol 1e-13, '
        'atol 1e-16, restarted at each time).',
        '',
        f'| body | values | uncertainty at {short:g} s (rad) | at {long:g} s | '
        'drift of \\|M\\|, 2T '
        f'| exact one step vs reference at {short:g} s (rad) | at {long:g} s | DOP853 vs '
        f'reference at {short:g} s (rad) | at {long:g} s |',
        '|---|---|---|---|---|---|---|---|---|',
    ]
    for case, reference in result['references'].items():
        keys = [{key_string(r[f'steps_{h}'], r['dt']) for r in result['records']
                 if r['case'] == case} for h in HORIZONS]
        cells = []
        for name in ('uncertainty', 'exact_gap', 'ode_gap'):
            values = reference[name]
            for horizon_keys in keys:
                cells.append('n/a' if values is None
                             else f'{max(values[k] for k in horizon_keys):.1e}')
        lines.append(f'| {case} | {reference["origin"]} | {cells[0]} | {cells[1]} | '
                     f'{reference["drift"]:.0e} | {" | ".join(cells[2:])} |')
    lines += [
        '',
        'Each figure is the largest over the times the steps land on.',
        '',
        '## Cost per step',
        '',
        'Microseconds per step, median (min - max) over the runs of at least 1000 steps (all '
        'bodies and steps; shorter runs are dominated by the per-call overhead).',
        '',
        '| integrator | us/step, median | min - max |',
        '|---|---|---|',
    ]
    for method, (median, low, high) in step_costs(result).items():
        lines.append(f'| {method} | {median:.2f} | {low:.2f} - {high:.2f} |')
    lines += [
        '',
        '## Work-precision plots',
        '',
        f'![work-precision plot: orientation error at {short:g} s against CPU seconds per '
        'simulated second, one panel per body](work_precision.png)',
        '',
        f'![the same at {long:g} s](work_precision_{long:g}s.png)',
        '',
        f'x: CPU seconds per simulated second (log); y: orientation error at {short:g} s, '
        f'and at {long:g} s in the second plot (rad, log).  One marker per measured step; '
        "solid lines and filled markers: this project's integrators; dashed lines and open "
        "markers: MuJoCo's.  Along each line dt shrinks from left to right.  Lines join "
        f'only steps that track the motion (error < {SATURATION:g} rad, below the red '
        'band); saturated or diverged steps are drawn as crosses and not joined.  The grey '
        "band is below the reference's resolution.",
        '',
        "## The goal: our best needs at most half the CPU of MuJoCo's best",
        '',
        'For each body and error level 1e-2 .. 1e-12 rad, the CPU seconds per simulated '
        "second each side needs to reach it, best over our integrators and over MuJoCo's.  "
        'How a cost is read off the measured steps (assuming, as for any convergent method '
        'above round-off, that cost rises and error falls as dt falls):',
        '',
        '- `X`: interpolated in log-log between the two measured steps named (dt a-b), both '
        f'tracking the motion.  Steps with an error >= {SATURATION:g} rad, or diverged, are '
        'not tracking: no line is drawn through them, since an O(1) error says nothing '
        'about the convergence rate.',
        '- `<= X`: the coarsest measured step already reaches the level: an upper bound.',
        '- `Y - X`: the first step that reaches the level follows a saturated one: the cost '
        'lies between the two.',
        '- `> Y` (MuJoCo `none reaches`): no measured step reaches the level; the cost is '
        'then more than that of the cheapest MuJoCo integrator at its finest step.  `(>= Y)` '
        'after a MuJoCo cost: another MuJoCo integrator might reach the level at an '
        'unmeasured step for as little as Y.',
        '',
        "The verdict compares the bounds: `holds` when ours' upper figure is at most half of "
        "MuJoCo's lower bound, `fails` when ours' lower bound is above half of MuJoCo's "
        'upper figure, otherwise `not decided`.  `unresolved`: the level is below the '
        "reference's resolution.  `holds*`: holds against MuJoCo's cost at its coarsest "
        'measured step, which bounds it only from above.',
        '',
    ]
    if issue_rows:
        issue_steps = ', '.join(f'{dt:g}' for dt in _issue_dts(result))
        lines += [f'First on the steps the issue names (dt = {issue_steps} s), on both '
                  'sides; then with every measured step, the coarse ones included, where the '
                  "exact flow's best (fewest steps) setting shows.", '']
        lines += _goal_section(result, issue_rows, short, informational=False,
                               steps=f', dt = {issue_steps} s')
    lines += _goal_section(result, goal_rows, short, informational=False,
                           steps=', every measured dt' if issue_rows else '')
    if long_rows:
        lines += [f'The same comparison at {long:g} s, measured and read the same way, for '
                  f'information: the goal is defined at {short:g} s.', '']
        lines += _goal_section(result, long_rows, long, informational=True)
    if augmentation_rows:
        lines += [
            "## Does Buss's augmentation pay off against buss_plain?",
            '',
            'Error ratios plain / augmented at the same dt (> 1: the augmented h^2/12 term '
            'helps).  The augmented step costs {:.2f}x the plain one (median over the runs '
            'of >= 1000 steps).  It pays off when its error at {:g} s is lower by more than '
            'max(1, cost ratio^2): a second-order method buys an error ratio r^2 with r '
            'times the steps.  `n/a`: both errors exceed 0.1 rad, neither tracks the '
            'motion.'.format(augmentation_rows[0]['cost_ratio'], short),
            '',
            f'| body | dt (s) | err {short:g} s plain/buss | err {long:g} s plain/buss | '
            'max dE/E plain/buss | pays off? |',
            '|---|---|---|---|---|---|',
        ]
        for row in augmentation_rows:
            lines.append(f'| {row["case"]} | {row["dt"]:g} | {row["short_ratio"]:.3g} | '
                         f'{row["long_ratio"]:.3g} | {row["energy_ratio"]:.3g} | '
                         f'{row["verdict"]} |')
        lines.append('')
    lines += ['## Results per body', '']
    for case in result['references']:
        lines += [f'### {case}', '', f'{result["cases"][case]}', '',
                  f'| integrator | dt (s) | err {short:g} s (rad) | err {long:g} s (rad) | '
                  'max dE/E | max d\\|L\\|/\\|L\\| | us/step | CPU s/sim s |',
                  '|---|---|---|---|---|---|---|---|']
        uncertainty = result['references'][case]['uncertainty']
        for record in (r for r in result['records'] if r['case'] == case):
            floor_short = uncertainty.get(key_string(record['steps_short'], record['dt']), 0.0)
            floor_long = uncertainty.get(key_string(record['steps_long'], record['dt']), 0.0)
            lines.append(
                f'| {record["method"]} | {record["dt"]:g} | '
                f'{_error(record["error_short"], floor_short)} | '
                f'{_error(record["error_long"], floor_long)} | '
                f'{_error(record["max_energy_error"])} | '
                f'{_error(record["max_momentum_magnitude_error"])} | '
                f'{record["us_per_step"]:.3f} | {record["cpu_per_sim_second"]:.2e} |')
        lines.append('')
    return '\n'.join(lines)


# Ours: filled markers, solid lines, tab10 colours; MuJoCo: open markers, dashed lines,
# dark colours of their own, so the peer reads apart from ours at a glance.  Ten colours and
# nine markers: coprime counts, so stepping both with the method's index gives ninety
# distinct pairs before one repeats (with nine of each, the tenth method drew as the first).
_OUR_COLOURS = ('tab:blue', 'tab:orange', 'tab:green', 'tab:red', 'tab:purple', 'tab:brown',
                'tab:pink', 'tab:cyan', 'tab:olive', 'navy')
_OUR_MARKERS = ('o', 'v', '^', '<', '>', 'D', 'p', 'h', '*')
_PEER_COLOURS = ('black', '0.45', 'darkgoldenrod')
_PEER_MARKERS = ('s', 'o', 'D', 'P')


def method_styles(methods):
    """
    Return {method: matplotlib line style} with every method told apart by colour and marker.

    MuJoCo's methods (``mujoco_*``) are dashed with open markers in dark colours; ours solid
    with filled markers.  Each method gets a (colour, marker) pair no other method has.

    Raises
    ------
    ValueError
        If there are more methods of one kind than distinct pairs.

    """
    styles = {}
    ours = [m for m in methods if not m.startswith('mujoco_')]
    peers = [m for m in methods if m.startswith('mujoco_')]
    for group, colours, markers, line, face in (
            (ours, _OUR_COLOURS, _OUR_MARKERS, '-', None),
            (peers, _PEER_COLOURS, _PEER_MARKERS, '--', 'white')):
        if len(group) > math.lcm(len(colours), len(markers)):
            raise ValueError(f'{len(group)} methods to draw; the styles tell apart '
                             f'{math.lcm(len(colours), len(markers))}')
        for index, method in enumerate(group):
            styles[method] = {'color': colours[index % len(colours)],
                              'marker': markers[index % len(markers)],
                              'linestyle': line, 'markerfacecolor': face}
    return styles


def case_panels(count, columns, panel_size, spare=0):
    """
    Return (figure, panels, spares): a grid of plot panels, one for each of `count` cases.

    `columns` panels a row, each `panel_size` (width, height) inches; `spare` more panels
    (for a legend) and the grid's unused ones are switched off and returned as `spares`.
    The benchmark's figures are drawn off screen (matplotlib's Agg backend).
    """
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot

    rows = math.ceil((count + spare) / columns)
    figure, axes = pyplot.subplots(rows, columns, squeeze=False,
                                   figsize=(panel_size[0] * columns, panel_size[1] * rows))
    panels = list(axes.flat)
    for axis in panels[count:]:
        axis.axis('off')
    return figure, panels[:count], panels[count:]


def write_records_csv(records, path):
    """Write `records` (dicts with the same keys, in order) to `path` as CSV, a row each."""
    with open(path, 'w', newline='') as table:
        writer = csv.DictWriter(table, fieldnames=list(records[0]))
        writer.writeheader()
        writer.writerows(records)


def save_figure(figure, path, dpi):
    """Lay out `figure`, write it to `path` at `dpi` and free it."""
    from matplotlib import pyplot

    figure.tight_layout()
    figure.savefig(path, dpi=dpi)
    pyplot.close(figure)


def work_precision_figure(result, horizon='short'):
    """Return the work-precision figure (matplotlib) of a benchmark result at a horizon."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    cases = list(result['references'])
    figure, panels, spare = case_panels(len(cases), 3, (6.0, 4.8), spare=1)
    styles = method_styles(result['methods'])
    seconds = result['config']['horizons'][HORIZONS.index(horizon)]
    for axis, case in zip(panels, cases):
        floor = resolution(result, case, horizon)
        for method in result['methods']:
            points = _curve(result, case, method, horizon)
            style = styles[method]
            face = style['markerfacecolor'] or style['color']
            # Lines join consecutive tracking steps only (see cost_to_reach).
            runs, current = [], []
            for _, cost, error in points:
                if tracking(error):
                    current.append((cost, error))
                else:
                    runs.append(current)
                    current = []
            runs.append(current)
            for run in (r for r in runs if r):
                cost, error = np.array(run).T
                axis.plot(cost, error, linestyle=style['linestyle'], marker=style['marker'],
                          color=style['color'], markerfacecolor=face, markersize=5,
                          linewidth=1.4)
            saturated = [(cost, min(error, 3.0)) for _, cost, error in points
                         if not tracking(error)]
            if saturated:
                cost, error = np.array(saturated).T
                axis.plot(cost, error, linestyle='none', marker='x', color=style['color'],
                          markersize=5, alpha=0.7)
        axis.set_xscale('log')
        axis.set_yscale('log')
        axis.axhspan(1e-17, floor, color='0.85', zorder=0)
        axis.axhspan(SATURATION, 10.0, color='mistyrose', zorder=0)
        axis.set_ylim(max(floor / 10.0, 1e-16), 5.0)
        axis.set_title(case)
        axis.set_xlabel('CPU seconds per simulated second')
        axis.set_ylabel(f'orientation error at {seconds:g} s (rad)')
        axis.grid(True, which='major', alpha=0.3)
    handles = []
    for method in result['methods']:
        style = styles[method]
        handles.append(Line2D([], [], color=style['color'], marker=style['marker'],
                              linestyle=style['linestyle'],
                              markerfacecolor=style['markerfacecolor'] or style['color'],
                              label=method))
    handles.append(Line2D([], [], color='0.3', marker='x', linestyle='none',
                          label=f'not tracking (>= {SATURATION:g} rad) or diverged'))
    handles.append(Patch(color='mistyrose', label=f'error >= {SATURATION:g} rad'))
    handles.append(Patch(color='0.85', label="below the reference's resolution"))
    spare[0].legend(handles=handles, loc='center', fontsize=10, ncol=2,
                    title='solid: this project; dashed, open: MuJoCo')
    figure.suptitle(f'Work-precision at {seconds:g} s: orientation error vs CPU per simulated '
                    f'second; dt from {max(result["config"]["dts"]):g} s (left) to '
                    f'{min(result["config"]["dts"]):g} s (right)')
    figure.tight_layout()
    return figure


def _plot(result, path, horizon='short'):
    save_figure(work_precision_figure(result, horizon), path, dpi=100)


def _json_safe(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ('inf' if value > 0 else '-inf')
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(item) for item in value]
    if isinstance(value, np.generic):
        return _json_safe(value.item())
    return value


def read_results(path):
    """
    Return the results a benchmark wrote to JSON (results.json, forces.json, ...).

    The JSON writes an infinite value as the string 'inf' (JSON has no infinity): the
    records' are read back as floats, so the plots can be drawn again from the file.
    """
    result = json.loads(Path(path).read_text(encoding='utf-8'))
    result['records'] = [{key: float(value) if value in ('inf', '-inf') else value
                          for key, value in record.items()} for record in result['records']]
    return result


def _issue_dts(result):
    """Return the issue's steps that this run measured (descending)."""
    return tuple(dt for dt in ISSUE_DTS
                 if any(math.isclose(dt, measured) for measured in result['config']['dts']))


def write_outputs(result, directory):
    """
    Write results.md, .json, .csv and the plots at both horizons; return {name: path}.

    `result` is :func:`..measure.run_benchmark`'s dict with 'machine', 'config', 'cases',
    'command' and 'wall_seconds' added.
    """
    os.makedirs(directory, exist_ok=True)
    goal_rows = goal_table(result)
    issue_dts = _issue_dts(result)
    issue_rows = goal_table(result, dts=issue_dts) \
        if issue_dts and len(issue_dts) < len(result['config']['dts']) else []
    long_rows = goal_table(result, horizon='long')
    augmentation_rows = augmentation_table(result)
    long_plot = f'work_precision_{result["config"]["horizons"][1]:g}s.png'
    paths = {name: os.path.join(directory, name) for name in
             ('results.md', 'results.json', 'results.csv', 'work_precision.png', long_plot)}
    with open(paths['results.md'], 'w') as markdown:
        markdown.write(_markdown(result, goal_rows, long_rows, augmentation_rows,
                                 issue_rows) + '\n')
    with open(paths['results.json'], 'w') as data:
        json.dump(_json_safe({**result, 'goal': goal_rows, 'goal_issue_steps': issue_rows,
                              'goal_long': long_rows,
                              'augmentation': augmentation_rows}), data, indent=1)
        data.write('\n')
    write_records_csv(result['records'], paths['results.csv'])
    _plot(result, paths['work_precision.png'], 'short')
    _plot(result, paths[long_plot], 'long')
    return paths

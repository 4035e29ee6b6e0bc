"""
The benchmark's outputs: analysis, markdown report, JSON/CSV data and the plot.

Analysis (pure functions of the measured records):

- :func:`cost_to_reach`: the CPU per simulated second a method needs to reach an orientation
  error level at the short horizon, interpolated linearly in log-log between the measured
  time steps (error ~ C dt^p and cost ~ 1/dt make both a straight line there).  Measured
  errors below the reference's estimated error are raised to it first: nobody is credited
  with an accuracy the reference cannot resolve.
- :func:`goal_table`: per body and level 1e-2 .. 1e-12 rad, our best integrator against
  MuJoCo's best, and whether ours needs at most half the CPU.
- :func:`augmentation_table`: Buss's augmented method against buss_plain, body by body.

Files: results.md, results.json, results.csv and work_precision.png in one directory.
"""

import csv
import datetime
import json
import math
import os
import platform
import statistics
import subprocess

import numpy as np

__all__ = ['machine_info', 'cost_to_reach', 'goal_table', 'augmentation_table', 'step_costs',
           'write_outputs', 'GOAL_LEVELS']

# Orientation error levels (rad) at which the CPU cost of ours and MuJoCo's are compared.
GOAL_LEVELS = tuple(10.0 ** -k for k in range(2, 13))
GOAL_RATIO = 0.5


def _cpu_model():
    try:
        with open('/proc/cpuinfo') as cpuinfo:
            for line in cpuinfo:
                if line.lower().startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or 'unknown'


def _version(module_name):
    try:
        module = __import__(module_name)
    except ImportError:
        return 'not installed'
    return getattr(module, '__version__', 'unknown')


def _git_commit():
    try:
        here = os.path.dirname(os.path.abspath(__file__))
        commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=here,
                                capture_output=True, text=True, timeout=10, check=True)
        return commit.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return 'unknown'


def machine_info():
    """Return a dict describing this machine and the software versions."""
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return {
        'cpu_model': _cpu_model(),
        'logical_cores': os.cpu_count(),
        'usable_cores': usable,
        'platform': platform.platform(),
        'python': platform.python_version(),
        'numpy': _version('numpy'),
        'scipy': _version('scipy'),
        'numba': _version('numba'),
        'mujoco': _version('mujoco'),
        'git_commit': _git_commit(),
        'date_utc': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
        'load_average_start': list(os.getloadavg()),
    }


# -- analysis

def _floor(result, record):
    uncertainty = result['references'][record['case']]['uncertainty']
    return uncertainty.get(repr(record['time_short']), 0.0)


def _curve(result, case, method):
    records = [r for r in result['records'] if r['case'] == case and r['method'] == method]
    records.sort(key=lambda r: -r['dt'])
    return [(r['cpu_per_sim_second'], max(r['error_short'], _floor(result, r)))
            for r in records if math.isfinite(r['error_short'])]


def cost_to_reach(points, level):
    """
    Return (cost, at_coarsest) to reach error <= `level` on a work-precision curve.

    Parameters
    ----------
    points : list of (cost, error)
        In order of decreasing dt (cost in CPU s per simulated s, error in rad).
    level : float
        Target error (rad).

    Returns
    -------
    (float, bool)
        The least cost on the log-log piecewise-linear curve with error <= level (inf if
        none), and whether it is the coarsest measured step (then it is only an upper
        bound: a larger step, not measured, might reach the level too).

    """
    best, at_coarsest = math.inf, False
    for index, (cost, error) in enumerate(points):
        if error <= level and cost < best:
            best, at_coarsest = cost, index == 0
    for (cost_a, error_a), (cost_b, error_b) in zip(points, points[1:]):
        if (error_a - level) * (error_b - level) < 0.0:
            fraction = (math.log(level) - math.log(error_a)) / (
                math.log(error_b) - math.log(error_a))
            cost = math.exp(math.log(cost_a) + fraction * (math.log(cost_b) - math.log(cost_a)))
            if cost < best:
                best, at_coarsest = cost, False
    return best, at_coarsest


def _best(result, case, methods, level):
    best = (math.inf, False, None)
    for method in methods:
        cost, at_coarsest = cost_to_reach(_curve(result, case, method), level)
        if cost < best[0]:
            best = (cost, at_coarsest, method)
    return best


def goal_table(result, levels=GOAL_LEVELS):
    """
    Return rows comparing our best and MuJoCo's best per case and error level.

    Each row: dict with case, level, ours (method), ours_cost, ours_upper_bound, mujoco,
    mujoco_cost, mujoco_upper_bound, ratio (ours/MuJoCo cost) and verdict ('holds',
    'fails', 'neither reaches', or 'no peer').
    """
    ours = [m for m in result['methods'] if not m.startswith('mujoco_')]
    peers = [m for m in result['methods'] if m.startswith('mujoco_')]
    rows = []
    for case in result['references']:
        for level in levels:
            ours_cost, ours_bound, ours_method = _best(result, case, ours, level)
            peer_cost, peer_bound, peer_method = _best(result, case, peers, level)
            ratio = ours_cost / peer_cost if math.isfinite(ours_cost) and math.isfinite(
                peer_cost) else None
            if not peers:
                verdict = 'no peer'
            elif math.isinf(ours_cost) and math.isinf(peer_cost):
                verdict = 'neither reaches'
            elif math.isinf(ours_cost):
                verdict = 'fails'
            elif math.isinf(peer_cost):
                verdict = 'holds'
            else:
                verdict = 'holds' if ratio <= GOAL_RATIO else 'fails'
            rows.append({'case': case, 'level': level, 'ours': ours_method,
                         'ours_cost': ours_cost, 'ours_upper_bound': ours_bound,
                         'mujoco': peer_method, 'mujoco_cost': peer_cost,
                         'mujoco_upper_bound': peer_bound, 'ratio': ratio,
                         'verdict': verdict})
    return rows


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
    cost_ratio = statistics.median(
        index[(case, 'buss', dt)]['us_per_step'] / index[(case, 'buss_plain', dt)]['us_per_step']
        for case, method, dt in index if method == 'buss')
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
                verdict = 'n/a'
            else:
                verdict = 'yes' if short_ratio > max(1.0, cost_ratio ** 2) else 'no'
            rows.append({'case': case, 'dt': dt, 'short_ratio': short_ratio,
                         'long_ratio': ratio('error_long'),
                         'energy_ratio': ratio('max_energy_error'),
                         'cost_ratio': cost_ratio, 'verdict': verdict})
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


def _cost(value, upper_bound=False):
    if not math.isfinite(value):
        return 'not reached'
    return ('<= ' if upper_bound else '') + f'{value:.2e}'


def _markdown(result, goal_rows, augmentation_rows):
    info = result['machine']
    config = result['config']
    short, long = config['horizons']
    lines = [
        '# Work-precision benchmark: what accuracy costs in time',
        '',
        f'Produced by `{result["command"]}` on {info["date_utc"]} (git {info["git_commit"]}). '
        "Regenerate with the same command; the numbers below are this run's.",
        '',
        '## Machine',
        '',
        f'- CPU: {info["cpu_model"]}, {info["logical_cores"]} logical cores '
        f'({info["usable_cores"]} usable by this process); {info["platform"]}',
        f'- Python {info["python"]}, numpy {info["numpy"]}, scipy {info["scipy"]}, '
        f'numba {info["numba"]}, mujoco {info["mujoco"]}',
        '- Load average (1, 5, 15 min) at start: '
        + ', '.join(f'{v:.2f}' for v in info['load_average_start'])
        + '; at end: ' + ', '.join(f'{v:.2f}' for v in info['load_average_end'])
        + f'. Wall time of the whole run: {result["wall_seconds"]:.0f} s.',
        '',
        '## What is measured',
        '',
        f'Every body x integrator x dt in {{{", ".join(f"{d:g}" for d in config["dts"])}}} s, '
        'torque-free, 1 kg at rest at the origin, starting at its initial orientation R0 and '
        'body angular velocity Omega0:',
        '',
        f'- **err {short:g} s / err {long:g} s**: orientation error, the rotation angle (rad) '
        'between the computed R and the reference R, after round(T/dt) steps of exactly dt '
        '(the reference is taken at that same time).',
        '- **max dE/E**: max relative kinetic-energy error; **max d|L|/|L|**: max relative '
        'error of the magnitude of the angular momentum (both sampled every ~0.1 s of '
        f'simulated time over {long:g} s).',
        f'- **us/step** and **CPU s/sim s**: CPU time (`time.process_time`) of one call that '
        f'advances {long:g} s from a fresh start, `Simulator.run` for ours and '
        '`mujoco.mj_step(model, data, nstep)` for MuJoCo (each its own compiled loop), '
        f'median of up to {config["repeats"]} repeats (fewer once {config["time_budget"]:g} '
        'CPU s are spent), after an untimed warm-up run (numba compilation is never timed).',
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
        'The exact torque-free flow (`INTEGRATORS["exact"]`, one step from t = 0) when it is '
        "registered and agrees with an independent DOP853 solve of Euler's equations (body "
        "momentum + quaternion, rtol 1e-13, atol 1e-16) within 3x the solve's estimated "
        'error (its gap to the same solve at rtol 1e-12); otherwise the DOP853 solve.  '
        "Errors below the reference's estimated error are shown as `<` that value and are "
        'raised to it in the analysis.',
        '',
        f'| body | reference | exact vs DOP853 at {short:g} s (rad) | at {long:g} s (rad) | '
        f'resolution at {short:g} s (rad) | at {long:g} s (rad) | note |',
        '|---|---|---|---|---|---|---|',
    ]
    for case, reference in result['references'].items():
        horizon_times = [{repr(r[key]) for r in result['records'] if r['case'] == case}
                         for key in ('time_short', 'time_long')]
        cells = []
        for values in (reference['ode_gap'], reference['uncertainty']):
            for times in horizon_times:
                cells.append('n/a' if values is None
                             else f'{max(values[t] for t in times):.1e}')
        lines.append(f'| {case} | {reference["source"]} | {" | ".join(cells)} | '
                     f'{reference["note"]} |')
    lines += [
        '',
        "Resolution: the exact flow's round-off level (the largest of its gap to itself in 2 "
        'and 10 steps and the change from a one-ulp change of L(0)), or for DOP853 its '
        'estimated error; max over the times the steps land on.  Note that the `exact` '
        'integrator is measured against its own one-step flow: its rows show its round-off '
        'growth over many steps; its agreement with the independent solve is the column '
        '"exact vs DOP853".',
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
        '## Work-precision plot',
        '',
        f'![work-precision plot: orientation error at {short:g} s against CPU seconds per '
        'simulated second, one panel per body](work_precision.png)',
        '',
        f'x: CPU seconds per simulated second (log); y: orientation error at {short:g} s '
        "(rad, log).  Solid lines: this project's integrators; dashed: MuJoCo's.  Along "
        "each line dt shrinks from left to right.  The grey band is below the reference's "
        'resolution.',
        '',
        "## The goal: our best needs at most half the CPU of MuJoCo's best",
        '',
        f'CPU seconds per simulated second needed to reach each orientation error at '
        f'{short:g} s, interpolated in log-log between the measured steps; best over our '
        "integrators and over MuJoCo's.  `<=` marks a cost that is the coarsest measured "
        'step (dt = {:g}), which already reaches the level: only an upper bound.  '
        '`not reached`: no measured step reaches it.'.format(max(config['dts'])),
        '',
    ]
    holds = sum(1 for row in goal_rows if row['verdict'] == 'holds')
    compared = sum(1 for row in goal_rows if row['verdict'] in ('holds', 'fails'))
    bounded = sum(1 for row in goal_rows
                  if row['verdict'] == 'holds' and row['mujoco_upper_bound'])
    ratios = [row['ratio'] for row in goal_rows if row['ratio'] is not None]
    lines.append(f'The goal holds at **{holds} of {compared}** (body, level) pairs that '
                 'either side reaches' + (
                     f'; ours / MuJoCo is {min(ratios):.3f} to {max(ratios):.2f} where both '
                     'reach the level' if ratios else '') + '.')
    if bounded:
        lines.append(f"At {bounded} of them (marked `holds*`) MuJoCo's cost is that of its "
                     'coarsest measured step, which already reaches the level: a larger '
                     'step, not measured, could be cheaper, so there the verdict holds for '
                     'the measured steps only.')
    lines.append('')
    for case in result['references']:
        lines += [f'### {case}', '',
                  '| error level (rad) | our best | CPU s/sim s | MuJoCo best | CPU s/sim s | '
                  'ours / MuJoCo | at most half? |',
                  '|---|---|---|---|---|---|---|']
        for row in (r for r in goal_rows if r['case'] == case):
            ratio = '' if row['ratio'] is None else f'{row["ratio"]:.2f}'
            lines.append(
                f'| {row["level"]:.0e} | {row["ours"] or "-"} | '
                f'{_cost(row["ours_cost"], row["ours_upper_bound"])} | '
                f'{row["mujoco"] or "-"} | '
                f'{_cost(row["mujoco_cost"], row["mujoco_upper_bound"])} | {ratio} | '
                f'{row["verdict"]}{"*" if row["mujoco_upper_bound"] else ""} |')
        lines.append('')
    if augmentation_rows:
        lines += [
            "## Does Buss's augmentation pay off against buss_plain?",
            '',
            'Error ratios plain / augmented at the same dt (> 1: the augmented h^2/12 term '
            'helps).  The augmented step costs {:.2f}x the plain one (median over the run).  '
            'It pays off when its error at {:g} s is lower by more than max(1, cost ratio^2): '
            'a second-order method buys an error ratio r^2 with r times the steps.  `n/a`: '
            'both errors exceed 0.1 rad, neither tracks the motion.'.format(
                augmentation_rows[0]['cost_ratio'], short),
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
            floor_short = uncertainty.get(repr(record['time_short']), 0.0)
            floor_long = uncertainty.get(repr(record['time_long']), 0.0)
            lines.append(
                f'| {record["method"]} | {record["dt"]:g} | '
                f'{_error(record["error_short"], floor_short)} | '
                f'{_error(record["error_long"], floor_long)} | '
                f'{_error(record["max_energy_error"])} | '
                f'{_error(record["max_momentum_magnitude_error"])} | '
                f'{record["us_per_step"]:.3f} | {record["cpu_per_sim_second"]:.2e} |')
        lines.append('')
    return '\n'.join(lines)


def _plot(result, path):
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot

    cases = list(result['references'])
    columns = 3
    rows = (len(cases) + 1 + columns - 1) // columns
    figure, axes = pyplot.subplots(rows, columns, figsize=(5.0 * columns, 4.2 * rows),
                                   squeeze=False)
    colours = pyplot.get_cmap('tab10')
    styles = {method: colours(index % 10) for index, method in enumerate(result['methods'])}
    short = result['config']['horizons'][0]
    for axis, case in zip(axes.flat, cases):
        floor = max((_floor(result, r) for r in result['records'] if r['case'] == case),
                    default=0.0)
        for method in result['methods']:
            points = _curve(result, case, method)
            if not points:
                continue
            cost, error = np.array(points).T
            peer = method.startswith('mujoco_')
            axis.loglog(cost, error, linestyle='--' if peer else '-',
                        marker='s' if peer else 'o', markersize=4, color=styles[method],
                        label=method)
        axis.axhspan(1e-17, floor, color='0.85', zorder=0)
        axis.set_ylim(max(floor / 10.0, 1e-16), 10.0)
        axis.set_title(case)
        axis.set_xlabel('CPU s per simulated s')
        axis.set_ylabel(f'orientation error at {short:g} s (rad)')
        axis.grid(True, which='major', alpha=0.3)
    spare = list(axes.flat)[len(cases):]
    handles, labels = axes.flat[0].get_legend_handles_labels()
    for axis in spare:
        axis.axis('off')
    spare[0].legend(handles, labels, loc='center', fontsize=10, title='integrator')
    figure.suptitle('Work-precision: orientation error vs CPU per simulated second '
                    f'({result["machine"]["cpu_model"]})')
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    pyplot.close(figure)


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


def write_outputs(result, directory):
    """
    Write results.md, results.json, results.csv and work_precision.png; return paths.

    `result` is :func:`..measure.run_benchmark`'s dict with 'machine', 'config', 'cases',
    'command' and 'wall_seconds' added.
    """
    os.makedirs(directory, exist_ok=True)
    goal_rows = goal_table(result)
    augmentation_rows = augmentation_table(result)
    paths = {name: os.path.join(directory, name) for name in
             ('results.md', 'results.json', 'results.csv', 'work_precision.png')}
    with open(paths['results.md'], 'w') as markdown:
        markdown.write(_markdown(result, goal_rows, augmentation_rows) + '\n')
    with open(paths['results.json'], 'w') as data:
        json.dump(_json_safe({**result, 'goal': goal_rows, 'augmentation': augmentation_rows}),
                  data, indent=1)
        data.write('\n')
    with open(paths['results.csv'], 'w', newline='') as table:
        writer = csv.DictWriter(table, fieldnames=list(result['records'][0]))
        writer.writeheader()
        writer.writerows(result['records'])
    _plot(result, paths['work_precision.png'])
    return paths

"""
The tolerance sweep's outputs: the goal table, the markdown, JSON, CSV and the plot.

Analysis (pure functions of :func:`.tolerance_sweep.tolerance_sweep`'s records):
:func:`control_goal_table` reads, per case and error level 1e-2 .. 1e-8 rad, the CPU per
simulated second that error-controlled ``buss`` and the fixed-step ``buss`` runs need to
reach it (:func:`.report.cost_to_reach`: log-log interpolation between the two runs that
bracket the level, both tracking the motion), and their ratio; the goal is a ratio of at
most :data:`GOAL_RATIO` (the price of not knowing the right step in advance).
"""

import json
import math
import os

from .report import case_panels
from .report import cost_to_reach
from .report import SATURATION
from .report import save_figure
from .report import workers_line
from .report import write_records_csv

__all__ = ['control_goal_table', 'sweep_markdown', 'tolerance_figure', 'write_sweep_outputs',
           'CONTROL_LEVELS', 'GOAL_RATIO']

CONTROL_LEVELS = tuple(10.0 ** -k for k in range(2, 9))
"""Error levels (rad over the span) at which controlled and fixed-step buss are compared."""
GOAL_RATIO = 1.5


def _curve(result, case, method):
    """Return [(label, cost, error)] of a method in order of rising cost (run order)."""
    floor = result['references'][case]['uncertainty']
    records = [r for r in result['records'] if r['case'] == case and r['method'] == method]
    if method.endswith('+control'):
        records.sort(key=lambda r: -r['tolerance'])
        label = 'tolerance'
    else:
        records.sort(key=lambda r: r['substeps'])
        label = 'substeps'
    return [(r[label], r['cpu_per_second'], max(r['error'], floor)) for r in records]


def control_goal_table(result, levels=CONTROL_LEVELS):
    """
    Return one row per (case, level): controlled and fixed buss costs, ratio, verdict.

    Verdicts: 'holds' (ratio <= GOAL_RATIO), 'fails', 'unresolved' (the level is below the
    reference's uncertainty), 'not reached' (a side has no run that reaches it; the ratio
    is then bounded by the measured costs if possible).
    """
    rows = []
    for case in result['references']:
        floor = result['references'][case]['uncertainty']
        controlled = _curve(result, case, 'buss+control')
        fixed = _curve(result, case, 'buss')
        for level in levels:
            ours = cost_to_reach(controlled, level)
            best = cost_to_reach(fixed, level)
            if level <= floor:
                verdict, ratio = 'unresolved', math.nan
            elif math.isinf(ours.cost) or math.isinf(best.cost):
                verdict, ratio = 'not reached', math.nan
            else:
                ratio = ours.cost / best.cost
                verdict = 'holds' if ratio <= GOAL_RATIO else 'fails'
            rows.append({'case': case, 'level': level, 'controlled': ours.cost,
                         'controlled_kind': ours.kind, 'controlled_from': ours.dts,
                         'fixed': best.cost, 'fixed_kind': best.kind, 'fixed_from': best.dts,
                         'ratio': ratio, 'verdict': verdict})
    return rows


def _cost(value):
    return '-' if math.isinf(value) or math.isnan(value) else f'{value:.2e}'


def sweep_markdown(result, rows):
    """Return the markdown of the tolerance sweep (the goal table, then every run)."""
    config = result['config']
    lines = [
        '# Error control: what each tolerance buys and costs on the built-in scenes',
        '',
        f'Produced by `{result["command"]}` (the sweep after the work-precision benchmark) on '
        f'{result["machine"]["date_utc"]}; machine, load and timer as in results.md.  '
        f'Wall time of the sweep: {result["wall_seconds"]:.0f} s.  '
        + workers_line(result['machine']),
        '',
        'Each built-in scene at its own tick (1 / rate) over '
        f"{config['span']:g} s: `buss` under error control at each tolerance (rad per "
        'simulated second; the substeps per tick chosen by physics/error_control.py), and '
        'fixed-step `buss`, `splitting` and `rk4` at 1, 2, 3, 4, 6, 8, ... substeps per tick.  '
        '**error**: the largest orientation error (rad) over samples every '
        f'{config["sample_interval"]:g} s, against the reference (the extended-precision '
        'Taylor solve for torque-free rotation, else rk4 at 128 substeps per tick; its '
        'uncertainty is listed per scene).  **steps/tick**: integrator steps per tick, the '
        "estimates' extra steps included.  **CPU s/sim s**: CPU time (`time.thread_time`) of "
        'one `Simulator.run` over the span (tick by tick for `driven`, whose pushed wrench '
        f'changes every tick), median of {config["repeats"]}.',
        '',
        '## The goal: error control costs at most 1.5x the best fixed step',
        '',
        f'For each scene and error level, the CPU per simulated second that controlled buss '
        'needs to reach it, read off its runs in order of falling tolerance, and the same for '
        'fixed-step buss in order of rising substeps (log-log interpolation between the two '
        f'runs that bracket the level; none across a run with an error >= {SATURATION:g} '
        'rad); the ratio must be at most 1.5.',
        '',
        '| scene | ' + ' | '.join(f'{level:.0e}' for level in CONTROL_LEVELS) + ' |',
        '|---|' + '---|' * len(CONTROL_LEVELS),
    ]
    for case in result['references']:
        cells = []
        for row in (r for r in rows if r['case'] == case):
            if row['verdict'] in ('holds', 'fails'):
                mark = '' if row['verdict'] == 'holds' else ' **fails**'
                cells.append(f'{row["ratio"]:.2f}{mark}')
            else:
                cells.append(row['verdict'])
        lines.append(f'| {case} | ' + ' | '.join(cells) + ' |')
    counts = {}
    for row in rows:
        counts[row['verdict']] = counts.get(row['verdict'], 0) + 1
    lines += ['', 'Verdicts: ' + ', '.join(f'{n} {verdict}' for verdict, n in
                                           sorted(counts.items())) + '.', '',
              '![error against CPU per simulated second, one panel per scene: '
              'controlled buss (tolerances marked), fixed-step buss, splitting and rk4]'
              '(tolerance_sweep.png)', '', '## Runs per scene', '']
    for case, reference in result['references'].items():
        lines += [f'### {case}', '',
                  f'Tick {reference["tick"]:g} s; reference: {reference["origin"]}, '
                  f'uncertainty {reference["uncertainty"]:.1e} rad.', '',
                  '| method | tolerance (rad/s) | substeps | steps/tick | error (rad) | '
                  'CPU s/sim s | us/tick |', '|---|---|---|---|---|---|---|']
        for record in (r for r in result['records'] if r['case'] == case):
            tolerance = '-' if record['tolerance'] is None else f'{record["tolerance"]:g}'
            substeps = (f'{record["substeps_min"]}-{record["substeps_max"]}'
                        if record['tolerance'] else f'{record["substeps"]}')
            error = record['error']
            shown = (f'< {reference["uncertainty"]:.0e}' if error < reference['uncertainty']
                     else f'{error:.2e}')
            lines.append(f'| {record["method"]} | {tolerance} | {substeps} | '
                         f'{record["steps_per_tick"]:.2f} | {shown} | '
                         f'{record["cpu_per_second"]:.2e} | {record["us_per_tick"]:.2f} |')
        lines.append('')
    return '\n'.join(lines)


_STYLES = {'buss+control': ('tab:red', 'o', '-'), 'buss': ('tab:blue', 's', '--'),
           'splitting': ('tab:green', '^', '--'), 'rk4': ('tab:purple', 'D', '--')}


def tolerance_figure(result):
    """Return the tolerance sweep's figure (matplotlib): error against cost, per case."""
    cases = list(result['references'])
    columns = 4
    rows = math.ceil(len(cases) / columns)
    figure, panels, _ = case_panels(len(cases), columns, (4.2, 3.6))
    for index, (axis, case) in enumerate(zip(panels, cases)):
        for method, (colour, marker, line) in _STYLES.items():
            curve = _curve(result, case, method)
            if not curve:
                continue
            costs = [cost for _, cost, _ in curve]
            errors = [error for _, _, error in curve]
            axis.plot(costs, errors, color=colour, marker=marker, linestyle=line,
                      markersize=4, label=method.replace('+control', ' (error control)'))
            if method.endswith('+control'):
                for label, cost, error in curve[::2]:
                    axis.annotate(f'{label:.0e}', (cost, error), fontsize=6,
                                  textcoords='offset points', xytext=(3, 3))
        axis.axhspan(SATURATION, 10.0, color='red', alpha=0.08)
        axis.set_xscale('log')
        axis.set_yscale('log')
        axis.set_ylim(max(1e-12, result['references'][case]['uncertainty']), 5.0)
        axis.set_title(case, fontsize=10)
        axis.grid(True, which='major', alpha=0.3)
        if index % columns == 0:
            axis.set_ylabel('largest error over the span (rad)')
        if index // columns == rows - 1:
            axis.set_xlabel('CPU s per simulated s')
    panels[0].legend(fontsize=7)
    figure.suptitle(f'Error control: error over {result["config"]["span"]:g} s against '
                    'CPU per simulated second', fontsize=11)
    figure.tight_layout()
    return figure


def _plot(result, path):
    save_figure(tolerance_figure(result), path, dpi=110)


def write_sweep_outputs(result, directory):
    """Write tolerance_sweep.md, .json, .csv and .png; return {name: path}."""
    os.makedirs(directory, exist_ok=True)
    rows = control_goal_table(result)
    paths = {name: os.path.join(directory, name) for name in (
        'tolerance_sweep.md', 'tolerance_sweep.json', 'tolerance_sweep.csv',
        'tolerance_sweep.png')}
    with open(paths['tolerance_sweep.md'], 'w') as markdown:
        markdown.write(sweep_markdown(result, rows) + '\n')
    with open(paths['tolerance_sweep.json'], 'w') as data:
        json.dump(_json_safe({**result, 'goal': rows}), data, indent=1)
        data.write('\n')
    write_records_csv(result['records'], paths['tolerance_sweep.csv'])
    _plot(result, paths['tolerance_sweep.png'])
    return paths


def _json_safe(value):
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return value

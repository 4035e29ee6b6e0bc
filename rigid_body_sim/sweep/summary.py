"""
The few lines a sweep prints at its end: what was run, how fast, and per group of runs.

A group is the runs of one scene, integrator, tolerance and rate: how many, their median
CPU per simulated second, and their worst drift and reference error (what the table holds
run by run).
"""

import math

import pyarrow as pa
import pyarrow.compute as pc

from .table import read_table
from .table import TABLE_FOLDER

__all__ = ['GROUP_COLUMNS', 'group_table', 'summary_lines']

GROUP_COLUMNS = ('scene', 'integrator', 'tolerance', 'rate')
_MOST_GROUPS = 20


def group_table(table):
    """Return one row per group (scene, integrator, tolerance, rate) of the runs of `table`."""
    table = table.append_column('abs_energy_drift', pc.abs(table['energy_drift']))
    table = table.append_column('abs_momentum_drift', pc.abs(table['angular_momentum_drift']))
    grouped = table.group_by(list(GROUP_COLUMNS)).aggregate([
        ('run_id', 'count'), ('cpu_per_simulated_second', 'approximate_median'),
        ('abs_energy_drift', 'max'), ('abs_momentum_drift', 'max'),
        ('orientation_error', 'max')])
    return grouped.sort_by([(name, 'ascending') for name in GROUP_COLUMNS])


def _figure(value, form='.2e'):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return '-'
    return format(value, form)


def summary_lines(result, out, source):
    """Return the summary's lines: the counts, the speed, the groups, where the table is."""
    table = read_table(out)
    ids = pa.array(sorted(result.ids), pa.string())
    table = table.filter(pc.is_in(table['run_id'], value_set=ids))
    statuses = {}
    for status in table['status'].to_pylist():
        statuses[status] = statuses.get(status, 0) + 1
    lines = [f'sweep {source}: {result.total} runs, {table.num_rows} in the table '
             f'({result.done} run now, {result.skipped} found done)'
             + (', stopped early' if result.stopped else '')]
    if statuses:
        lines.append('  status: ' + ', '.join(f'{count} {status}'
                                              for status, count in sorted(statuses.items())))
    if result.not_done:
        run_id, error = result.not_done[0]
        lines.append(f'  not done: {len(result.not_done)} run(s) whose task failed (e.g. '
                     f'{run_id}: {error}); a re-run retries them')
    if result.done and result.seconds > 0.0:
        workers = sum(result.machines.values())
        lines.append(f'  {workers} worker(s) on {len(result.machines)} machine(s), started '
                     f'with their kernels in {result.engine_seconds:.1f} s; {result.done} '
                     f'runs in {result.seconds:.1f} s ({result.done / result.seconds:.2f} '
                     'runs/s)')
    if table.num_rows:
        groups = group_table(table)
        header = (f'  {"scene":<16}{"integrator":<12}{"tol rad/s":>10}{"rate Hz":>9}'
                  f'{"runs":>7}{"CPU/sim s":>11}{"|dE|/T0":>10}{"|d|L||/|L|":>11}'
                  f'{"orient rad":>11}')
        lines.append(header)
        for row in groups.to_pylist()[:_MOST_GROUPS]:
            lines.append(
                f'  {row["scene"]:<16.16}{row["integrator"]:<12.12}'
                f'{_figure(row["tolerance"], ".0e"):>10}{_figure(row["rate"], "g"):>9}'
                f'{row["run_id_count"]:>7}'
                f'{_figure(row["cpu_per_simulated_second_approximate_median"], ".4f"):>11}'
                f'{_figure(row["abs_energy_drift_max"]):>10}'
                f'{_figure(row["abs_momentum_drift_max"]):>11}'
                f'{_figure(row["orientation_error_max"]):>11}')
        if groups.num_rows > _MOST_GROUPS:
            lines.append(f'  ... {groups.num_rows - _MOST_GROUPS} more groups in the table')
    lines.append(f'table: {out / TABLE_FOLDER} (one Parquet data set: '
                 f"pyarrow.parquet.read_table('{out / TABLE_FOLDER}'))")
    return lines

"""
The tolerance sweep's report: its goal verdicts follow from the runs, and `bench` writes it.

The verdict logic is checked on made-up runs whose costs are known in closed form (power
laws in log-log, where the report's interpolation is exact); the command on the quick sweep.
"""

import json
import math

from rigid_body_sim import cli
from rigid_body_sim.work_precision import tolerance_sweep
from rigid_body_sim.work_precision.tolerance_report import control_goal_table
from rigid_body_sim.work_precision.tolerance_report import CONTROL_LEVELS
from rigid_body_sim.work_precision.tolerance_report import GOAL_RATIO


def _record(method, error, cost, tolerance=None, substeps=1):
    return {'case': 'body', 'method': method, 'tolerance': tolerance, 'substeps': substeps,
            'error': error, 'cpu_per_second': cost}


def _result(controlled_factor, floor=1e-15):
    """
    Make runs: fixed buss error = 1e-2 / n^2 at cost n; controlled the same curve, dearer.

    Every level 1e-2 .. 1e-8 is crossed by both (n up to 1e3 reaches 1e-8), so the ratio at
    each level is exactly controlled_factor: both curves are straight in log-log.
    """
    records = [_record('buss', 1e-2 / n ** 2, float(n), substeps=n)
               for n in (1, 10, 100, 1000, 10000)]
    records += [_record('buss+control', 1e-2 / n ** 2, controlled_factor * n, tolerance=1e-2 / n)
                for n in (1, 10, 100, 1000, 10000)]
    return {'references': {'body': {'uncertainty': floor, 'origin': 'made up', 'span': 60.0,
                                    'tick': 0.01}},
            'records': records}


def test_control_goal_holds_at_every_level_when_control_costs_less_than_the_goal_ratio():
    factor = GOAL_RATIO * 0.99
    rows = control_goal_table(_result(factor))
    assert [row['level'] for row in rows] == list(CONTROL_LEVELS)
    assert all(row['verdict'] == 'holds' for row in rows), rows
    for row in rows:
        # Exact in log-log up to the logs' and exps' rounding.
        assert math.isclose(row['ratio'], factor, rel_tol=1e-12)


def test_control_goal_fails_at_every_level_when_control_costs_more_than_the_goal_ratio():
    rows = control_goal_table(_result(GOAL_RATIO * 1.01))
    assert all(row['verdict'] == 'fails' for row in rows), rows


def test_levels_below_the_references_uncertainty_are_not_judged():
    rows = control_goal_table(_result(1.0, floor=3e-7))
    verdicts = {row['level']: row['verdict'] for row in rows}
    assert verdicts[1e-7] == verdicts[1e-8] == 'unresolved'
    assert verdicts[1e-6] == 'holds'


def test_a_level_no_controlled_run_reaches_is_not_reached():
    result = _result(1.0)
    result['records'] = [r for r in result['records']
                         if r['method'] == 'buss' or r['error'] > 1e-5]
    verdicts = {row['level']: row['verdict'] for row in control_goal_table(result)}
    assert verdicts[1e-4] == 'holds'
    assert verdicts[1e-6] == verdicts[1e-8] == 'not reached'


def test_bench_quick_tolerance_sweep_writes_the_table_data_and_plot(tmp_path, capsys):
    out = tmp_path / 'sweep'
    assert cli.main(['bench', '--quick', '--tolerance-sweep', '--out', str(out)]) == 0
    printed = capsys.readouterr().out
    assert 'judged (scene, error level) pairs' in printed
    result = json.loads((out / 'tolerance_sweep.json').read_text())
    assert result['config']['scenes'] == ['van_zon', 'heavy_top']
    assert len(result['goal']) == 2 * len(CONTROL_LEVELS)
    methods = {(r['case'], r['method']) for r in result['records']}
    for scene in ('van_zon', 'heavy_top'):
        for method in ('buss+control',) + tolerance_sweep.FIXED_METHODS:
            assert (scene, method) in methods
    # Error control at a tighter tolerance never takes fewer steps per tick.
    for scene in ('van_zon', 'heavy_top'):
        controlled = sorted((r for r in result['records']
                             if r['case'] == scene and r['method'] == 'buss+control'),
                            key=lambda r: -r['tolerance'])
        steps = [r['steps_per_tick'] for r in controlled]
        assert steps == sorted(steps) and steps[-1] > steps[0]
    markdown = (out / 'tolerance_sweep.md').read_text()
    assert '| scene | 1e-02 |' in markdown and '### heavy_top' in markdown
    with open(out / 'tolerance_sweep.png', 'rb') as plot:
        assert plot.read(8) == b'\x89PNG\r\n\x1a\n'
    assert (out / 'tolerance_sweep.csv').read_text().startswith('case,method,')


def test_bench_rejects_an_unknown_scene_for_the_sweep(tmp_path, capsys):
    assert cli.main(['bench', '--quick', '--tolerance-sweep', '--scenes', 'teapot',
                     '--out', str(tmp_path)]) != 0
    error = capsys.readouterr().err
    assert 'no built-in scene teapot' in error and error.count('\n') == 1

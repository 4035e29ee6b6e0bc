"""
The sweep: specs expand into content-addressed runs; nothing lost, nothing twice.

The engine's promises are tested on a real local Dask cluster of two workers: a worker
killed with SIGKILL while it runs a task loses no finished run and its runs finish on
another process, each run once in the table; a sweep stopped by Ctrl-C (SIGINT to its
process group, as a terminal sends it) keeps what is done and a second run of the same
command does the rest, half-written bags removed and whole ones replaced.  Every wait is
for an event (a row, a journal line, a process's end), with a deadline.
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest
from rigid_body_sim.cli import build_parser
from rigid_body_sim.cli import main
from rigid_body_sim.sweep import Engine
from rigid_body_sim.sweep import parse_spec
from rigid_body_sim.sweep import read_table
from rigid_body_sim.sweep import run_sweep
from rigid_body_sim.sweep.kernels import loaded
from rigid_body_sim.sweep.run import execute_run
from rigid_body_sim.sweep.spec import DISTRIBUTIONS
from rigid_body_sim.sweep.spec import load_spec
from rigid_body_sim.sweep.spec import SPEC_KEYS
from rigid_body_sim.sweep.table import COLUMNS
from rigid_body_sim.sweep.table import JOURNAL
from rigid_body_sim.sweep.table import ResultTable
from rigid_body_sim.sweep.table import SCHEMA
from rosbags.rosbag2 import Reader

ROOT = Path(__file__).resolve().parent.parent
DEADLINE = 240.0

# Runs of a few tenths of a second each, so that a kill or a Ctrl-C lands mid-sweep.
THROWN = {
    'scenes': ['thrown_box'], 'rates': [200], 'durations': [4.0],
    'set': {'imu.gyro_noise_density': 1.7e-4},
    'random': {'count': 10, 'seed': 3, 'draw': {
        'initial.angular_velocity_body': {'uniform': [[-1.0, 8.0, -1.0], [1.0, 16.0, 1.0]]},
        'imu.seed': {'integers': [0, 1000]}}},
}


def _spec(**changes):
    data = json.loads(json.dumps(THROWN))
    data.update(changes)
    return parse_spec(data, '<test spec>')


def _wait_for(condition, what, deadline=DEADLINE):
    end = time.monotonic() + deadline
    while not condition():
        assert time.monotonic() < end, f'waited {deadline} s for {what}'
        time.sleep(0.05)  # waits-for: poll interval of _wait_for(condition)


# -- the spec


def test_the_example_specs_expand_to_the_runs_their_comments_promise():
    small = load_spec('small')
    assert small.run_count == 18 and len({run.run_id for run in small.runs()}) == 18
    small.check()
    dataset = load_spec('imu_dataset')
    assert dataset.run_count == 1000
    runs = list(dataset.runs())
    assert len({run.run_id for run in runs}) == 1000
    scenes = [runs[k].scene() for k in (0, 999)]
    assert all(scene.name == 'thrown_box' and scene.rate == 200.0 for scene in scenes)
    assert scenes[0].imu.gyro_noise_density == 1.7e-4 and scenes[0].imu.seed != scenes[1].imu.seed


def test_a_runs_id_is_its_content_not_how_the_spec_spells_it():
    ids = [run.run_id for run in _spec().runs()]
    assert ids == [run.run_id for run in _spec().runs()], 'the same spec, the same ids'
    assert ids == [run.run_id for run in _spec(rates=[200.0]).runs()], '200 and 200.0 are one'
    assert ids[:10] == [run.run_id for run in _spec(random={
        **THROWN['random'], 'count': 20}).runs()][:10], 'a larger count keeps the first runs'
    changed = [run.run_id for run in _spec(durations=[1.0]).runs()]
    assert not set(changed) & set(ids)
    no_bags = [run.run_id for run in _spec(bags=False).runs()]
    assert not set(no_bags) & set(ids), 'a run without its bag is another output'


def test_the_methods_of_a_sweep_meet_the_same_random_initial_states():
    spec = _spec(integrators=['buss', 'rk4'])
    runs = list(spec.runs())
    buss, rk4 = runs[:10], runs[10:]
    assert [run.changes['initial.angular_velocity_body'] for run in buss] == \
        [run.changes['initial.angular_velocity_body'] for run in rk4]
    assert {run.changes['integrator'] for run in rk4} == {'rk4'}
    velocities = np.array([run.changes['initial.angular_velocity_body'] for run in buss])
    assert np.all((velocities >= [-1.0, 8.0, -1.0]) & (velocities <= [1.0, 16.0, 1.0]))
    assert len(np.unique(velocities[:, 1])) == 10


@pytest.mark.parametrize('changes, expected', [
    ({'frequency': 3}, 'frequency: unknown key'),
    ({'durations': [0.0123]}, 'not a whole number of ticks at 200 Hz'),
    ({'integrators': ['leapfrog']}, "unknown integrator 'leapfrog'"),
    ({'set': {'body.mass': -1.0}}, 'body.mass'),
    ({'set': {'draw.color': [1, 0, 0]}}, 'draw.color: not a scene value a spec may change'),
    ({'grid': {'imu.seed': [1, 2]}}, 'imu.seed: given in more than one'),
    ({'random': {'count': 2, 'seed': 1, 'draw': {'body.mass': {'gaussian': [1, 2]}}}},
     'random.draw.body.mass: expected one of uniform'),
    ({'random': {'count': 2, 'seed': 1, 'draw': {'body.mass': {'uniform': [2, 1]}}}},
     'low above high'),
])
def test_a_bad_spec_is_one_error_naming_the_key(changes, expected):
    with pytest.raises(ValueError, match='^<test spec>') as error:
        _spec(**changes).check()
    assert expected in str(error.value) and '\n' not in str(error.value)


def test_the_help_teaches_every_key_of_the_spec_with_an_example():
    subparsers = next(action for action in build_parser()._actions
                      if hasattr(action, 'choices') and action.choices)
    text = subparsers.choices['sweep'].format_help()
    for key in SPEC_KEYS + DISTRIBUTIONS:
        assert f'{key}' in text, key
    assert 'random:' in text and 'draw:' in text and 'rigid-body-sim sweep small' in text


def test_a_dry_run_lists_the_runs_and_runs_none(tmp_path, capsys):
    assert main(['sweep', 'small', '--out', str(tmp_path / 'out'), '--dry-run']) == 0
    out = capsys.readouterr().out
    assert out.count('\n') == 7 and '18 runs (0 in' in out and '... 13 more' in out
    assert 'buss, exact, rk4, splitting4' in out, 'the reference integrator is loaded too'
    assert not (tmp_path / 'out').exists()


# -- one run, in this process


def test_a_run_without_its_bag_has_the_physics_of_the_run_with_it(tmp_path):
    with_bag, = list(_spec(random={**THROWN['random'], 'count': 1}).runs())
    without, = list(_spec(random={**THROWN['random'], 'count': 1}, bags=False).runs())
    rows = [execute_run(with_bag, tmp_path), execute_run(without, tmp_path)]
    assert {row['status'] for row in rows} == {'ok'}
    final = [name for name, *_ in COLUMNS if name.startswith('final_')]
    assert [rows[0][name] for name in final] == [rows[1][name] for name in final]
    assert set(rows[0]) - {'worker'} <= set(SCHEMA.names)
    assert rows[1]['bag'] is None and rows[0]['bag'] == f'bags/{with_bag.run_id[:2]}/' \
        f'{with_bag.run_id}'
    with Reader(tmp_path / rows[0]['bag']) as reader:
        counts = {connection.topic: connection.msgcount for connection in reader.connections}
    assert counts['/imu'] == counts['/pose'] == 800
    # Torque-free about the COM under gravity: the exact flow is the reference, and buss at
    # the scene's tolerance stays within what that tolerance allows over 4 s.
    assert 0.0 < rows[0]['orientation_error'] < 2 * 3e-6 * 4.0
    assert rows[0]['position_error'] < 1e-9
    assert rows[0]['conserved'] == 'angular_momentum,energy,rotational_energy'
    assert abs(rows[0]['energy_drift']) < 1e-7


def test_values_that_make_no_scene_give_an_invalid_row_not_an_error(tmp_path):
    run, = list(_spec(random={'count': 1, 'seed': 0, 'draw': {
        'body.mass': {'uniform': [-2.0, -1.0]}}}).runs())
    row = execute_run(run, tmp_path)
    assert row['status'] == 'invalid' and 'body.mass' in row['message']
    table = ResultTable(tmp_path)
    table.start()
    table.add(row)
    table.close()
    assert read_table(tmp_path).to_pylist()[0]['status'] == 'invalid'


# -- the table


def test_rows_of_a_killed_driver_are_recovered_from_the_journal_each_once(tmp_path):
    rows = [{'run_id': f'{k:024x}', 'status': 'ok', 'message': '', 'finished': k}
            for k in range(5)]
    table = ResultTable(tmp_path, part_rows=3)
    assert table.start() == set()
    for row in rows:
        table.add(row)
    # Killed here: rows 0-2 are in a part, 3-4 only in the journal, and a last line cut.
    with open(tmp_path / JOURNAL, 'a', encoding='utf-8') as journal:
        journal.write('{"run_id": "cut')
    again = ResultTable(tmp_path)
    assert again.start() == {row['run_id'] for row in rows}
    again.add(rows[1])
    again.close()
    ids = read_table(tmp_path).column('run_id').to_pylist()
    assert sorted(ids) == [row['run_id'] for row in rows]
    assert not (tmp_path / JOURNAL).exists()
    schema = pq.read_schema(next((tmp_path / 'table').glob('part-*.parquet')))
    assert schema.field('final_angular_momentum_x').metadata[b'unit'] == b'kg m^2/s'


# -- on the cluster


@pytest.mark.xdist_group('sweep_cluster')
def test_a_worker_killed_mid_sweep_loses_no_run_and_its_runs_finish_elsewhere(tmp_path):
    spec = _spec()
    killed = {}
    received = []

    with Engine(workers=2, integrators=['buss', 'exact']) as engine:
        # Each worker loaded the kernels when it started, before any task.
        assert all(names == ['buss', 'exact'] for names in engine.client.run(loaded).values())
        pids = engine.client.run(os.getpid)

        def on_row(row):
            received.append(dict(row))
            if killed:
                return
            for address, pid in pids.items():
                runs = engine.items_on(address)
                if runs and address != row['worker']:
                    killed.update(pid=pid, runs={run.run_id for run in runs})
                    os.kill(pid, signal.SIGKILL)
                    return

        result = run_sweep(spec, tmp_path, engine=engine, on_row=on_row, items_per_task=1)
        engine.client.wait_for_workers(2, timeout=DEADLINE)
        restarted = engine.client.run(loaded)
    assert killed, 'no worker had a task to kill it in'
    table = read_table(tmp_path).to_pylist()
    ids = [row['run_id'] for row in table]
    assert sorted(ids) == sorted(run.run_id for run in spec.runs()), 'each run exactly once'
    assert result.done == 10 and not result.not_done and not result.stopped
    assert {row['status'] for row in table} == {'ok'}
    by_id = {row['run_id']: row for row in table}
    for row in received:
        assert by_id[row['run_id']]['finished'].timestamp() * 1000 == \
            pytest.approx(row['finished']), 'a row received before the kill is kept as it was'
    for run_id in killed['runs']:
        assert by_id[run_id]['pid'] != killed['pid'], 'a killed run finished elsewhere'
    assert all(names == ['buss', 'exact'] for names in restarted.values()), \
        'the restarted worker loaded the kernels too'
    bags = sorted(path.name for path in (tmp_path / 'bags').glob('*/*'))
    assert bags == sorted(ids), 'one whole bag per run, no half-written one'


def _sweep_command(spec_file, out):
    return subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.cli', 'sweep', str(spec_file), '--out',
         str(out), '--workers', '2', '--runs-per-task', '1'],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
        # As a terminal's shell starts a command: SIGINT at its default, whatever pytest's is.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _journal_rows(out):
    try:
        return (out / JOURNAL).read_text().count('\n')
    except FileNotFoundError:
        return 0


@pytest.mark.xdist_group('sweep_cluster')
def test_a_sweep_stopped_by_ctrl_c_keeps_what_is_done_and_a_rerun_does_the_rest(tmp_path):
    spec_file = tmp_path / 'thrown.yaml'
    spec_file.write_text(json.dumps(dict(THROWN, durations=[10.0],
                                         random={**THROWN['random'], 'count': 12})))
    out = tmp_path / 'out'
    first = _sweep_command(spec_file, out)
    _wait_for(lambda: _journal_rows(out) >= 3 or first.poll() is not None, 'three rows')
    assert first.poll() is None, 'the sweep ended before it could be stopped'
    os.killpg(first.pid, signal.SIGINT)
    stdout, stderr = first.communicate(timeout=DEADLINE)
    assert first.returncode == 128 + signal.SIGINT, stderr
    assert 'SIGINT: stopped' in stderr and 'Traceback' not in stderr, stderr
    kept = read_table(out).to_pylist()
    assert 3 <= len(kept) < 12 and len({row['run_id'] for row in kept}) == len(kept)
    assert not (out / JOURNAL).exists()

    # A run finished but not in the table (its row lost with a killed driver): its whole
    # bag is replaced; a run half-written: its hidden folder goes.
    spec = load_spec(spec_file)
    missing = next(run for run in spec.runs() if run.run_id not in {r['run_id'] for r in kept})
    stale = out / 'bags' / missing.run_id[:2] / missing.run_id
    stale.mkdir(parents=True, exist_ok=True)
    (stale / 'metadata.yaml').write_text('left by an earlier attempt\n')
    partial = out / 'bags' / 'ab' / '.partial-abcdef-12345678'
    partial.mkdir(parents=True)

    second = _sweep_command(spec_file, out)
    stdout, stderr = second.communicate(timeout=DEADLINE)
    assert second.returncode == 0, stderr
    assert f'({12 - len(kept)} run now, {len(kept)} found done)' in stdout, stdout
    table = read_table(out).to_pylist()
    assert sorted(row['run_id'] for row in table) == sorted(run.run_id for run in spec.runs())
    by_id = {row['run_id']: row for row in table}
    for row in kept:
        assert by_id[row['run_id']] == row, 'a kept row is not run again'
    assert not list((out / 'bags').glob('*/.partial-*'))
    assert 'earlier attempt' not in (stale / 'metadata.yaml').read_text()
    assert sorted(path.name for path in (out / 'bags').glob('*/*')) == sorted(by_id)

    assert main(['sweep', str(spec_file), '--out', str(out), '--quiet']) == 0, \
        'a third run finds every run done'

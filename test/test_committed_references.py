"""
The committed extended-precision references are package data the benchmark finds, and a script.

The script, benchmarks/regenerate_references.py, regenerates them.

- Each set (rigid_body_sim/work_precision/data/*.json) keeps its quaternions as decimal strings
  (unit norm to their digits) under the 'N x dt' keys the benchmark looks up.
- Every benchmark body at every (N, dt) of both sweeps, and every torque-free built-in scene
  at every sample of the tolerance sweep, finds its reference committed: nothing is solved.
- benchmarks/regenerate_references.py --only recomputes the named problem into the file and
  keeps the others as they are; its --help says what it does and how long it takes; an
  unknown name is an error that lists the known ones.
"""

import decimal
from decimal import Decimal
import json
from pathlib import Path
import subprocess
import sys

import pytest
from rigid_body_sim.work_precision import extended_reference
from rigid_body_sim.work_precision.bodies import benchmark_cases
from rigid_body_sim.work_precision.bodies import CASE_NAMES
from rigid_body_sim.work_precision.extended_reference import committed_references
from rigid_body_sim.work_precision.extended_reference import key_string
from rigid_body_sim.work_precision.extended_reference import problem_fingerprint
from rigid_body_sim.work_precision.extended_reference import quaternion_angle
from rigid_body_sim.work_precision.extended_reference import reference_quaternions
from rigid_body_sim.work_precision.extended_reference import REFERENCE_SETS
from rigid_body_sim.work_precision.measure import FULL
from rigid_body_sim.work_precision.measure import QUICK
from rigid_body_sim.work_precision.measure import reference_keys
from rigid_body_sim.work_precision.tolerance_sweep import case_reference_keys
from rigid_body_sim.work_precision.tolerance_sweep import is_torque_free
from rigid_body_sim.work_precision.tolerance_sweep import scene_cases
from rigid_body_sim.work_precision.tolerance_sweep import SWEEP_SPAN

SCRIPT = Path(__file__).resolve().parent.parent / 'benchmarks' / 'regenerate_references.py'


@pytest.mark.parametrize('which', sorted(REFERENCE_SETS))
def test_committed_references_keep_unit_quaternions_as_decimal_strings(which):
    problems = committed_references(which)
    assert problems
    for fingerprint, entry in problems.items():
        assert len(fingerprint.split()) == 16  # inertia (9), quaternion (4), L (3)
        assert entry['drift'] < 1e-25, entry['name']
        for key, value in entry['values'].items():
            steps, dt = key.split(' x ')
            assert key == key_string(int(steps), float(dt))
            *quaternion, uncertainty = value
            assert [type(component) for component in quaternion] == [str] * 4, key
            with decimal.localcontext() as context:
                context.prec = 50
                norm = sum(Decimal(component) ** 2 for component in quaternion)
            # 24 significant digits at least: |q|^2 is 1 to a few 1e-24.
            assert abs(norm - 1) < Decimal('1e-23'), (entry['name'], key)
            assert 0.0 <= uncertainty < 1e-20, (entry['name'], key)


def _benchmark_problems():
    for case in benchmark_cases(CASE_NAMES):
        keys = set()
        for config in (FULL, QUICK):
            if case.name in config.cases:
                keys |= set(reference_keys(config))
        yield f'body {case.name}', case.body, case.state, sorted(keys)
    for case in scene_cases(span=SWEEP_SPAN):
        if is_torque_free(case):
            yield f'scene {case.name}', case.scene.body, case.scene.state, \
                case_reference_keys(case)


def test_every_benchmark_body_and_torque_free_scene_finds_its_reference_committed(monkeypatch):
    """The lookups the bench and the tolerance sweep make hit the package data, every key."""
    def never_solve(*args, **kwargs):
        raise AssertionError('a committed reference was solved again')
    monkeypatch.setattr(extended_reference, 'extended_reference', never_solve)
    problems = list(_benchmark_problems())
    assert {name.split()[0] for name, *_ in problems} == {'body', 'scene'}
    for name, body, state, keys in problems:
        values, _, origin = reference_quaternions(body, state, keys, use_cache=False)

        assert origin == 'committed', name
        assert sorted(values) == sorted(keys)
        # The benchmark gets the stored strings themselves (van_zon is in both sets).
        stored = {}
        for which in REFERENCE_SETS:
            entry = committed_references(which).get(problem_fingerprint(body, state))
            stored.update(entry['values'] if entry else {})
        for key in keys:
            assert list(values[key][0]) == stored[key_string(*key)][:4], (name, key)


def _run_script(*arguments):
    return subprocess.run([sys.executable, str(SCRIPT), *arguments], capture_output=True,
                          text=True, timeout=600)


def test_regenerating_one_body_rewrites_its_entry_and_keeps_the_others(tmp_path):
    """--only t_handle recomputes t_handle (its values were emptied) and leaves the rest."""
    committed = committed_references('bodies')
    emptied = json.loads(json.dumps(committed))
    t_handle = next(fingerprint for fingerprint, entry in emptied.items()
                    if entry['name'] == 't_handle')
    emptied[t_handle]['values'] = {}
    path = tmp_path / REFERENCE_SETS['bodies']
    path.write_text(json.dumps({'problems': emptied}))

    ran = _run_script('--set', 'bodies', '--only', 't_handle', '--output-dir', str(tmp_path))

    assert ran.returncode == 0, ran.stderr
    written = json.loads(path.read_text())['problems']
    assert set(written) == set(committed)
    for fingerprint, entry in committed.items():
        if fingerprint != t_handle:
            assert written[fingerprint] == entry
    again = written[t_handle]['values']
    assert list(again) == list(committed[t_handle]['values'])
    with decimal.localcontext() as context:
        context.prec = 50
        for key, value in committed[t_handle]['values'].items():
            # The same solve; bit for bit on one machine, within its own error across libms.
            angle = quaternion_angle([Decimal(c) for c in again[key][:4]],
                                     [Decimal(c) for c in value[:4]])
            assert angle < 1e-30, key


def test_regenerate_help_says_what_it_writes_and_how_long_it_takes():
    ran = _run_script('--help')

    assert ran.returncode == 0, ran.stderr
    for words in ('reference_values.json', 'scene_reference_values.json', 'CPU', '--only',
                  '--set', '--output-dir'):
        assert words in ran.stdout, words


def test_regenerating_an_unknown_body_is_an_error_that_lists_the_known_ones(tmp_path):
    ran = _run_script('--set', 'bodies', '--only', 'teapot', '--output-dir', str(tmp_path))

    assert ran.returncode == 2
    assert 'Traceback' not in ran.stderr
    assert 'teapot' in ran.stderr and 'van_zon' in ran.stderr
    assert not list(tmp_path.iterdir())

#!/usr/bin/env python3
"""
Print every built-in scene's physics check against theory, as the scene tests measure it.

The same measurement as ``test/test_scene_physics.py``: this script calls the test module's
own helpers (flip times, cones, top runs, flights, pushes, state hashes) on the same cases
the tests are parametrized with, and prints one row per check: the measured quantity, the
theory's value, their difference (relative where the test bounds a relative error, absolute
where it bounds an absolute one) and the tolerance the test uses, with ``ok`` where the test's
own comparison holds.  Frames world, units SI; the scene's own integrator and default step
unless the row says otherwise.

Usage: ``.venv/bin/python benchmarks/scene_theory.py`` (about ten seconds).
"""

from collections import namedtuple
from pathlib import Path
import sys

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'test'))

import test_scene_physics as scene_tests  # noqa: E402  (after the path set-up)

Row = namedtuple('Row', 'scene check measured theory difference tolerance holds')
COLUMNS = (('scene', 13), ('check', 40), ('measured', 16), ('theory', 16),
           ('difference', 13), ('tolerance', 20), ('', 4))


def _cases(test):
    """Return the argument tuples `test` is parametrized with, so the rows run exactly those."""
    (mark,) = [mark for mark in test.pytestmark if mark.name == 'parametrize']
    return [case if isinstance(case, tuple) else (case,) for case in mark.args[1]]


def _number(value):
    return f'{value:.9g}'


def _relative(measured, theory):
    return f'rel {(measured - theory) / abs(theory):+.2e}'


def _absolute(difference):
    return f'abs {difference:.2e}'


def _largest(a, b):
    """Return max |a - b| over the components (the quantity an atol bounds)."""
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))))


def _torque_free_rows():
    rows = []
    flip_test = scene_tests.test_middle_axis_flip_period_matches_the_elliptic_closed_form
    for name, periods in _cases(flip_test):
        measured, expected, flips = scene_tests._flip_period(name, periods)
        rows.append(Row(name, f'flip period T (s), {periods} periods', _number(measured),
                        _number(expected), _relative(measured, expected), '<= 5.0e-03',
                        len(flips) >= 2 * periods - 1
                        and measured == pytest.approx(expected, rel=0.005)))
    for (name,) in _cases(scene_tests.test_first_flip_comes_after_a_quarter_period_even_with_buss):
        scene = scene_tests.load_scene(name)
        # The test checks the scene's integrator and buss; once where they are the same.
        for integrator in dict.fromkeys((scene.integrator, 'buss')):
            first, expected, tolerance = scene_tests._first_flip(scene, integrator)
            rows.append(Row(name, f'first flip at T/4 (s), {integrator}', _number(first),
                            _number(expected), _relative(first, expected),
                            f'<= {tolerance:.1e}',
                            first == pytest.approx(expected, rel=tolerance)))
    for name, omega_body, axis in _cases(
            scene_tests.test_spin_about_the_largest_and_smallest_axes_stays_in_its_cone):
        widest, bound, limit = scene_tests._stable_cone(name, omega_body, axis)
        start = 'of scene' if omega_body is None else '(' + ','.join(
            f'{value:g}' for value in omega_body) + ')'
        rows.append(Row(name, f'cone about e{axis + 1}, Omega0 {start} rad/s',
                        _number(widest), _number(bound), _relative(widest, bound),
                        f'<= {limit / bound - 1.0:.1e}', widest <= limit))
    for (name,) in _cases(scene_tests.test_spin_about_the_middle_axis_flips_over):
        lowest, flipped, tolerance = scene_tests._middle_axis_flip(name)
        rows.append(Row(name, 'middle axis flips: min Omega2 (rad/s)', _number(lowest),
                        _number(flipped), _relative(lowest, flipped), f'<= {tolerance:.1e}',
                        lowest == pytest.approx(flipped, rel=tolerance)))
    start_momentum, momentum, start_energy, energy, tolerance = scene_tests._van_zon_run()
    # assert_allclose(rtol=1e-13) bounds each component's relative change.
    change = np.abs(momentum - start_momentum)
    rows.append(Row('van_zon', '|L| after 20 s (kg m^2/s)', _number(np.linalg.norm(momentum)),
                    _number(np.linalg.norm(start_momentum)),
                    f'rel {float(np.max(change / np.abs(start_momentum))):.2e}',
                    '<= 1e-13 each', bool(np.all(change <= 1e-13 * np.abs(start_momentum)))))
    rows.append(Row('van_zon', 'energy after 20 s (J)', _number(energy), _number(start_energy),
                    _relative(energy, start_energy), f'<= {tolerance:.1e}',
                    energy == pytest.approx(start_energy, rel=tolerance)))
    return rows


def _top_rows():
    rows = []
    runs = scene_tests._top_runs()
    # The four top tests share these cases and the module's runs (dt and dt/2).
    for (name,) in _cases(scene_tests.test_top_keeps_energy_vertical_momentum_and_spin):
        run, finer = runs[name], runs[name, 'half step']
        theory = run.theory
        rate, phase = run.precession_rate, run.phase_error
        exact = theory.mean_precession_rate()
        rows.append(Row(name, 'precession vs quadrature (rad/s)', _number(rate), _number(exact),
                        _relative(rate, exact), f'<= {phase:.1e}',
                        rate == pytest.approx(exact, rel=phase)))
        # The fast-top test: within 2 eps of m g d / (I3 omega3), and within
        # 3 eps^2 + (a dt)^2 of its first-order correction eps cos(theta0); counterclockwise.
        eps, fast = theory.smallness(), theory.fast_top_rate()
        relative = rate / fast - 1.0
        rows.append(Row(name, 'precession vs m g d/(I3 w3) (rad/s)', _number(rate),
                        _number(fast), _relative(rate, fast), f'<= 2 eps {2.0 * eps:.1e}',
                        abs(relative) <= 2.0 * eps and rate > 0.0))
        second = 3.0 * eps ** 2 + phase
        rows.append(Row(name, '  rel. excess vs eps cos(theta0)', f'{relative:.6e}',
                        f'{eps * theory.u0:.6e}', _absolute(abs(relative - eps * theory.u0)),
                        f'<= {second:.1e}', abs(relative - eps * theory.u0) <= second))
        lower, upper = theory.roots[0], theory.roots[1]
        swing = upper - lower
        start_limit = 1e-12 * swing + 1e-15
        rows.append(Row(name, 'start u0 = cos(theta0) at root u2', _number(theory.u0),
                        _number(upper), _absolute(abs(theory.u0 - upper)),
                        f'< {start_limit:.1e}',
                        swing > 0.0 and abs(theory.u0 - upper) < start_limit))
        tolerance = phase * swing
        for label, measured, root in (('nutation: min u = root u1', min(run.heights), lower),
                                      ('nutation: max u = root u2', max(run.heights), upper)):
            rows.append(Row(name, label, _number(measured), _number(root),
                            _absolute(abs(measured - root)), f'<= {tolerance:.1e}',
                            measured == pytest.approx(root, abs=tolerance)))
        bound = phase * theory.exchanged_energy()
        rows.append(Row(name, 'energy: max |E - E0| (J)', f'{run.energy_error:.3e}', '0',
                        _absolute(run.energy_error), f'<= {bound:.1e}',
                        run.energy_error <= bound))
        vertical = 1e-14 * run.momentum
        rows.append(Row(name, 'vertical L: max |Lz - Lz0| (kg m^2/s)',
                        f'{run.vertical_error:.3e}', '0', _absolute(run.vertical_error),
                        f'<= {vertical:.1e}', run.vertical_error <= vertical))
        spin = phase * abs(run.spin)
        rows.append(Row(name, 'spin: max |L.e3 - L0.e3| (kg m^2/s)', f'{run.spin_error:.3e}',
                        '0', _absolute(run.spin_error), f'<= {spin:.1e}',
                        run.spin_error <= spin))
        for label, coarse, fine in (('energy error ratio dt : dt/2', run.energy_error,
                                     finer.energy_error),
                                    ('spin error ratio dt : dt/2', run.spin_error,
                                     finer.spin_error)):
            # The test's bound: 3.4 per halved step, scaled by (step ratio)^2 (error
            # control's whole substeps halve the step only nearly).
            least = scene_tests.SECOND_ORDER * (run.step / finer.step) ** 2 / 4.0
            rows.append(Row(name, label, f'{coarse / fine:.3f}', '4 (2nd order)', '-',
                            f'>= {least:.2f}', coarse >= least * fine))
    return rows


def _thrown_box_rows():
    scene = scene_tests.load_scene('thrown_box')
    body, start = scene.body, scene.state
    position = velocity = momentum = rotation = 0.0
    # The test's bound: each step rounds x and p once (<= 1 ulp of the largest component),
    # summed over the steps so far, error control's extra steps counted too.
    position_ok = velocity_ok = True
    for state, free_state, parabola, parabola_velocity, steps in \
            scene_tests._thrown_box_flight(scene):
        for value, exact, name in ((state.position, parabola, 'position'),
                                   (state.velocity(body), parabola_velocity, 'velocity')):
            error = _largest(value, exact)
            holds = error <= 2.0 * steps * scene_tests.EPS * np.max(np.abs(exact))
            if name == 'position':
                position, position_ok = max(position, error), position_ok and holds
            else:
                velocity, velocity_ok = max(velocity, error), velocity_ok and holds
        momentum = max(momentum, _largest(state.angular_momentum, start.angular_momentum))
        rotation = max(rotation, _largest(state.quaternion, free_state.quaternion))
    bound = '<= 2 steps ulp'
    return [
        Row('thrown_box', 'COM: max |x - parabola|, 1 s (m)', f'{position:.3e}', '0',
            _absolute(position), bound, position_ok),
        Row('thrown_box', 'COM: max |v - (v0 + g t)|, 1 s (m/s)', f'{velocity:.3e}', '0',
            _absolute(velocity), bound, velocity_ok),
        Row('thrown_box', 'max |L - L0|, 1 s (kg m^2/s)', f'{momentum:.3e}', '0',
            _absolute(momentum), 'bit-identical', momentum == 0.0),
        Row('thrown_box', 'max |q - q of torque-free twin|', f'{rotation:.3e}', '0',
            _absolute(rotation), 'bit-identical', rotation == 0.0),
    ]


def _flat_spin_rows():
    scene = scene_tests.load_scene('flat_spin')
    body, start = scene.body, scene.state
    momentum = start.angular_momentum
    flat_energy = (momentum @ momentum) / (2.0 * body.principal_moments[2])
    energies, free_energies, momenta, state = scene_tests._flat_spin_run(scene)
    change = max(_largest(current, momentum) for current in momenta)
    norm_change = max(abs(np.linalg.norm(current) - np.linalg.norm(momentum))
                      for current in momenta)
    wobble = max(free_energies) - min(free_energies)
    rise = float(np.max(np.diff(energies)))
    axis = body.principal_axes[:, 2]
    omega = state.angular_velocity_body(body)
    alignment = abs(omega @ axis) / np.linalg.norm(omega)
    return [
        Row('flat_spin', 'max |L - L0| over 80 s (kg m^2/s)', f'{change:.3e}', '0',
            _absolute(change), 'bit-identical', change == 0.0),
        # Not a separate assertion (the bits above imply it): the issue's own figure.
        Row('flat_spin', 'max ||L| - |L0|| over 80 s (kg m^2/s)', f'{norm_change:.3e}', '0',
            _absolute(norm_change), '<= 1e-9 (issue)', norm_change <= 1e-9),
        Row('flat_spin', 'energy: largest rise per 0.5 s (J)', f'{rise:.3e}', '<= 0', '-',
            f'<= {wobble:.1e} wobble', rise <= wobble),
        Row('flat_spin', 'start energy / (|L|^2 / (2 I3))', f'{energies[0] / flat_energy:.4f}',
            '> 8', '-', '> 8', energies[0] > 8.0 * flat_energy),
        Row('flat_spin', 'energy at 80 s -> |L|^2/(2 I3) (J)', _number(energies[-1]),
            _number(flat_energy), _relative(energies[-1], flat_energy), '<= 1.0e-04',
            energies[-1] == pytest.approx(flat_energy, rel=1e-4)),
        Row('flat_spin', 'spin along e3: 1 - |cos| at 80 s', f'{1.0 - alignment:.3e}', '0',
            _absolute(1.0 - alignment), '< 1.0e-04', alignment > 1.0 - 1e-4),
    ]


def _driven_rows():
    rows = []
    for (name,) in _cases(scene_tests.test_outside_push_changes_the_momenta_exactly_as_held):
        scene = scene_tests.load_scene(name)
        simulator = scene.simulator()
        torque_free = scene.accepts_external_wrench and simulator.wrench_function() is None
        unpushed, before, after, force, torque = scene_tests._held_push(scene, simulator)
        steps = simulator.substep_statistics()['steps']
        drift = _largest(unpushed.angular_momentum, scene.state.angular_momentum)
        rows.append(Row(name, 'unpushed 1 s: |L - L0| (kg m^2/s)', f'{drift:.3e}', '0',
                        _absolute(drift), 'bit-identical', torque_free and drift == 0.0))
        for label, measured, theory in (
                ('held 2 s: |L - (L0 + tau t)| (kg m^2/s)', after.angular_momentum,
                 before.angular_momentum + 2.0 * torque),
                ('held 2 s: |p - (p0 + F t)| (kg m/s)', after.linear_momentum,
                 before.linear_momentum + 2.0 * force),
                ('held 2 s: |x - (x0 + F t^2/2m)| (m)', after.position,
                 before.position + 0.5 * force / scene.body.mass * 4.0)):
            # The test's bound: 1 ulp per kick and drift over the run's steps, or 1e-13.
            bound = max(1e-13, 2.0 * steps * scene_tests.EPS * np.max(np.abs(theory)))
            difference = _largest(measured, theory)
            rows.append(Row(name, label, f'{difference:.3e}', '0', _absolute(difference),
                            f'<= {bound:.1e}', difference <= bound))
    return rows


def _exactness_rows():
    rows = []
    for (name,) in _cases(scene_tests.test_unpushed_com_stays_exactly_where_it_was):
        scene = scene_tests.load_scene(name)
        final = scene_tests._one_second_later(scene)
        moved = max(_largest(final.position, scene.state.position),
                    _largest(final.linear_momentum, scene.state.linear_momentum))
        rows.append(Row(name, 'unpushed 1 s: |x - x0|, |p - p0|', f'{moved:.3e}', '0',
                        _absolute(moved), 'bit-identical', moved == 0.0))
    for (name,) in _cases(
            scene_tests.test_same_scene_integrator_and_step_give_a_bit_identical_trajectory):
        scene = scene_tests.load_scene(name)
        repeats = []
        for one_at_a_time in (False, True):
            first = scene_tests._final_hash(scene, 300, scene.dt, one_at_a_time)
            repeats.append(scene_tests._final_hash(scene, 300, scene.dt, one_at_a_time) == first)
        # Under error control half the tick may mean the very same substeps: the test
        # takes a fixed step for this.
        sees = scene_tests._final_hash(scene.with_overrides(tolerance=0.0), 600,
                                       0.5 * scene.dt, False) != first
        # Twice the same 300 steps, by run() and step by step; dt/2 must change the hash.
        measured = ', '.join('same' if same else 'DIFFERENT' for same in repeats)
        rows.append(Row(name, 'state hash, 300 steps: run(), step()', measured, 'same, same',
                        '-', 'equal; dt/2 differs', all(repeats) and sees))
    return rows


def _print(rows):
    print('  '.join(f'{title:{width}s}' for title, width in COLUMNS).rstrip())
    print('  '.join('-' * width for _, width in COLUMNS[:-1]) + '  ' + '-' * 4)
    for row in rows:
        cells = list(row[:-1]) + ['ok' if row.holds else 'FAIL']
        print('  '.join(f'{cell:{width}s}' for cell, (_, width) in zip(cells, COLUMNS)).rstrip())


def main(argv=None):
    """Print the table; return 0 if every check holds, 1 otherwise."""
    import argparse
    argparse.ArgumentParser(description=__doc__.strip().splitlines()[0],
                            epilog='Usage: .venv/bin/python benchmarks/scene_theory.py (no '
                                   'options; about ten seconds)').parse_args(argv)
    rows = (_torque_free_rows() + _top_rows() + _thrown_box_rows() + _flat_spin_rows()
            + _driven_rows() + _exactness_rows())
    _print(rows)
    failed = sum(not row.holds for row in rows)
    print(f'{len(rows)} checks, {failed} failing')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())

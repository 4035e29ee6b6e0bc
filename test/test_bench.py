"""
The work-precision benchmark: `rigid-body-sim bench --quick` runs and its measures are right.

- The quick benchmark writes the markdown table and the PNG plots, with a row for every
  registered integrator and, when mujoco imports, for MuJoCo's integrators, and a goal
  table at both horizons.
- Where the cells run changes no error: the quick benchmark on a local Dask cluster (the
  default) gives every error of every part exactly as it is in one process, and so does the
  forced part on a cluster given by its scheduler's address; each report names the machine
  and the workers that ran its cells.
- The orientation error measure returns the angle of a known rotation to round-off.
- The ODE reference and the extended-precision (decimal Taylor) reference match the
  closed-form motion of a free symmetric top, the latter to 1e-28 rad; the committed
  extended values cover every run of both sweeps and are reproduced by recomputing one;
  an uncommitted problem is computed once and then read from the cache.
- The MuJoCo peer converges to the reference at fourth order with its RK4 (so it models the
  same body with the same frame conventions: a wrong inertia, frame or quaternion order
  would leave an O(1) error that no step size removes).
- The cost read off a front: the interpolation recovers a known power law; saturated or
  diverged steps are never interpolated across; a level no step reaches is bounded below
  by the finest step's cost.
- The goal verdicts: a level MuJoCo never reaches holds only with a 2x margin on that bound
  (else 'not decided'); a level below the reference's resolution is 'unresolved'; every
  (body, level) pair is counted, none dropped.
"""

import decimal
from decimal import Decimal
import json
import math
import os
import socket

import numpy as np
import pytest
from rigid_body_sim import cli
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import State
from rigid_body_sim.physics.rotations import rotation_matrix_from_rotation_vector
from rigid_body_sim.work_precision.bodies import benchmark_cases
from rigid_body_sim.work_precision.bodies import CASE_NAMES
from rigid_body_sim.work_precision.extended_reference import committed_references
from rigid_body_sim.work_precision.extended_reference import exact_time
from rigid_body_sim.work_precision.extended_reference import key_string
from rigid_body_sim.work_precision.extended_reference import problem_fingerprint
from rigid_body_sim.work_precision.extended_reference import quaternion_angle
from rigid_body_sim.work_precision.extended_reference import reference_quaternions
from rigid_body_sim.work_precision.extended_reference import taylor_flow
from rigid_body_sim.work_precision.measure import FULL
from rigid_body_sim.work_precision.measure import QUICK
from rigid_body_sim.work_precision.measure import reference_keys
from rigid_body_sim.work_precision.peer_mujoco import mjcf_model
from rigid_body_sim.work_precision.peer_mujoco import mujoco_available
from rigid_body_sim.work_precision.peer_mujoco import MUJOCO_INTEGRATORS
from rigid_body_sim.work_precision.peer_mujoco import MujocoPeer
from rigid_body_sim.work_precision.reference import ode_reference
from rigid_body_sim.work_precision.reference import rotation_angle
from rigid_body_sim.work_precision.report import cost_to_reach
from rigid_body_sim.work_precision.report import GOAL_LEVELS
from rigid_body_sim.work_precision.report import goal_summary
from rigid_body_sim.work_precision.report import goal_table
from rigid_body_sim.work_precision.report import SATURATION
from rigid_body_sim.work_precision.report import verdict

EPS = np.finfo(float).eps


# The figures of a cell that do not depend on where it ran (its CPU times do), per part.
ERROR_FIELDS = {
    'results.json': ('error_short', 'error_long', 'max_energy_error',
                     'max_momentum_magnitude_error', 'max_world_momentum_error', 'diverged'),
    'tolerance_sweep.json': ('error', 'steps_per_tick', 'substeps_min', 'substeps_max'),
    'forces.json': ('error', 'diverged'),
}


@pytest.fixture(scope='module')
def quick_on_a_local_cluster(tmp_path_factory):
    """Run `bench --quick` as a user does (a local cluster, a worker per core); its folder."""
    out = tmp_path_factory.mktemp('bench') / 'quick'
    assert cli.main(['bench', '--quick', '--out', str(out)]) == 0
    return out


def _errors(out, name):
    """Return [(the cell, its error figures)] of one part's results, in the report's order."""
    result = json.loads((out / name).read_text())
    return [((r['case'], r['method'], r['dt'] if 'dt' in r else None, r.get('tolerance'),
              r.get('substeps')), tuple(r[field] for field in ERROR_FIELDS[name]))
            for r in result['records']]


def _ran_on(out, name):
    return json.loads((out / name).read_text())['machine']['cells_ran_on']


@pytest.mark.xdist_group('bench_cluster')
def test_bench_quick_writes_a_table_and_a_plot_with_every_integrator(quick_on_a_local_cluster):
    """`bench --quick` exits 0 and writes results.md (all methods) and PNG plots."""
    out = quick_on_a_local_cluster
    table = (out / 'results.md').read_text()
    short, long = QUICK.horizons
    for name in ('work_precision.png', f'work_precision_{long:g}s.png'):
        with open(out / name, 'rb') as plot:
            assert plot.read(8) == b'\x89PNG\r\n\x1a\n'
    assert (out / 'results.csv').stat().st_size > 0
    result = json.loads((out / 'results.json').read_text())
    # Both horizons get a goal table with every (body, level) pair: none is dropped.
    for key in ('goal', 'goal_long', 'goal_issue_steps'):
        assert len(result[key]) == len(QUICK.cases) * len(GOAL_LEVELS)
    # First on the steps that the sweep measured (the quick one: 0.1 and 0.01 s),
    # then on every measured step.
    assert f'### At {short:g} s, dt = 0.1, 0.01 s: the goal' in table
    assert f'### At {short:g} s, every measured dt: the goal' in table
    assert {row['ours_reach']['dts'][-1] for row in result['goal_issue_steps']
            if row['ours_reach']['dts']} <= {0.1, 0.01}
    assert f'### At {long:g} s (information only' in table
    # The quick sweep needs no reference computation: its values are committed.
    assert {r['origin'] for r in result['references'].values()} == {'committed'}
    methods = list(INTEGRATORS)
    if mujoco_available():
        methods += list(MUJOCO_INTEGRATORS)
    else:
        assert 'not installed' in table
    for method in methods:
        assert f'\n| {method} | 0.1 |' in table, f'no row for {method}'
        assert f'\n| {method} | 0.01 |' in table, f'no row for {method}'


@pytest.mark.xdist_group('bench_cluster')
def test_cells_on_a_local_cluster_give_the_errors_they_give_in_one_process(
        quick_on_a_local_cluster, tmp_path):
    """Every error of the three parts is the same, bit for bit; the reports name the workers."""
    here = tmp_path / 'in_process'
    assert cli.main(['bench', '--quick', '--in-process', '--out', str(here)]) == 0
    for name in ERROR_FIELDS:
        on_cluster = _errors(quick_on_a_local_cluster, name)
        assert len(on_cluster) > 10
        assert on_cluster == _errors(here, name), f'{name}: an error depends on where it ran'
        ran_on = _ran_on(quick_on_a_local_cluster, name)
        cores = len(os.sched_getaffinity(0))
        assert ran_on['engine'] == 'a local Dask cluster' and ran_on['workers'] <= cores
        [host] = ran_on['hosts']
        assert host['host'] == socket.gethostname() and host['cpu_model']
        # Every record's cell, and each case's reference (forces: and its check), ran there.
        references = len(json.loads((here / name).read_text())['references'])
        cells = len({cell for cell, _ in on_cluster}) if name != 'tolerance_sweep.json' else \
            len({cell[:2] for cell, _ in on_cluster})
        assert host['cells'] == cells + references * (2 if name == 'forces.json' else 1)
        assert 'cells_ran_on' not in json.loads((here / name).read_text())['machine']
    table = (quick_on_a_local_cluster / 'results.md').read_text()
    assert (f'Cells ran on a local Dask cluster, {ran_on["workers"]} worker process(es)'
            in table and f'{socket.gethostname()} (' in table)
    assert 'Cells ran in this process' in (here / 'results.md').read_text()


@pytest.mark.xdist_group('bench_cluster')
def test_cells_on_a_cluster_given_by_its_address_give_the_same_errors(
        quick_on_a_local_cluster, tmp_path):
    """`bench --forces --quick --scheduler ADDRESS`: a user's cluster, one worker here."""
    from distributed import LocalCluster

    out = tmp_path / 'remote'
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        assert cli.main(['bench', '--forces', '--quick', '--scheduler',
                         cluster.scheduler_address, '--out', str(out)]) == 0
    assert _errors(out, 'forces.json') == _errors(quick_on_a_local_cluster, 'forces.json')
    ran_on = _ran_on(out, 'forces.json')
    assert ran_on['engine'] == f'the Dask cluster at {cluster.scheduler_address}'
    assert ran_on['workers'] == 1 and ran_on['hosts'][0]['host'] == socket.gethostname()
    assert f'Cells ran on the Dask cluster at {cluster.scheduler_address}' in \
        (out / 'forces.md').read_text()


@pytest.mark.parametrize('angle', [0.0, 1e-14, 1e-9, 1e-3, 0.5, 2.0, math.pi - 1e-7])
def test_orientation_error_of_a_known_rotation_is_its_angle(angle):
    """rotation_angle(R, R exp(angle [n]x)) = angle, to a few ulp, for any R and axis n."""
    rng = np.random.default_rng(11)
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        rotation = rotation_matrix_from_rotation_vector(rng.normal(size=3))
        turned = rotation @ rotation_matrix_from_rotation_vector(angle * axis)
        # The entries of both matrices carry a few eps of rounding from the products; sine
        # and cosine are sums of a few of them, so the angle is good to ~10 eps absolute.
        assert abs(rotation_angle(rotation, turned) - angle) <= 10.0 * EPS
        assert abs(rotation_angle(turned, rotation) - angle) <= 10.0 * EPS


def test_ode_reference_matches_the_closed_form_free_symmetric_top():
    """
    For I = (I1, I1, I3): R(t) = exp(t [L]x / I1) R0 exp(t c [e3]x), c = (1/I3 - 1/I1) M3.

    With I_b = I1 E + (I3 - I1) e3 e3^T the world angular velocity is
    omega = L / I1 + c R e3, and [R e3]x R = R [e3]x, so dR/dt = [L / I1]x R + c R [e3]x
    is solved by the product of two fixed-axis rotations.
    """
    body = RigidBody(1.0, (1.0, 1.0, 2.0))
    rotation0 = rotation_matrix_from_rotation_vector([0.3, -0.8, 0.5])
    state = State.from_velocity(body, rotation=rotation0,
                                angular_velocity_body=(0.7, -0.4, 3.0))
    momentum = state.angular_momentum
    rate = (1.0 / 2.0 - 1.0 / 1.0) * (rotation0.T @ momentum)[2]
    time = 10.0
    exact = (rotation_matrix_from_rotation_vector(time * momentum / 1.0) @ rotation0
             @ rotation_matrix_from_rotation_vector([0.0, 0.0, time * rate]))
    # DOP853 at rtol 1e-13 over ~30 rad of rotation: ~1e-13 per rad at worst.
    assert rotation_angle(ode_reference(body, state, [time])[time], exact) < 3e-12


def test_mujoco_model_uses_fullinertia_only_for_a_non_diagonal_tensor():
    """A diagonal tensor is given as diaginertia, a non-diagonal one as fullinertia."""
    diagonal, non_diagonal = benchmark_cases(['van_zon', 'non_diagonal'])
    assert 'diaginertia="10.0 20.0 26.0"' in mjcf_model(diagonal.body, 'RK4', 0.01)
    assert 'fullinertia="2.0 3.0 4.0 -0.3 0.2 0.4"' in mjcf_model(non_diagonal.body, 'RK4',
                                                                  0.01)


@pytest.mark.skipif(not mujoco_available(), reason='mujoco is not installed')
def test_mujoco_peer_converges_to_the_reference_at_fourth_order():
    """
    The peer's RK4 at dt = 1e-3 agrees with the reference; halving dt cuts the error 16x.

    Every benchmark body, over 1 s: the non-diagonal one at an oblique orientation checks
    the inertia tensor, the body-frame angular velocity and the (w, x, y, z) order at once.
    """
    duration = 1.0
    for case in benchmark_cases():
        reference = ode_reference(case.body, case.state, [duration])[duration]
        errors = []
        for dt in (2e-3, 1e-3):
            peer = MujocoPeer(case.body, case.state, 'mujoco_rk4', dt)
            peer.step(round(duration / dt))
            errors.append(rotation_angle(peer.rotation, reference))
            momentum_error = (np.linalg.norm(peer.angular_momentum - case.state.angular_momentum)
                              / np.linalg.norm(case.state.angular_momentum))
            assert momentum_error < 1e-8, case.name
        # Fastest body (van_zon, |Omega| ~ 15 rad/s): RK4's error ~ (|Omega| dt)^4 per
        # radian turned is ~1e-12 per rad at dt = 1e-3, times ~15 rad.
        assert errors[1] < 1e-9, (case.name, errors)
        if errors[0] > 1e-11:  # above round-off, where the order shows
            assert 8.0 < errors[0] / errors[1] < 32.0, (case.name, errors)


def test_extended_reference_matches_the_closed_form_free_symmetric_top_to_1e_28_rad():
    """
    The decimal Taylor solve of a symmetric top equals its closed form far below double eps.

    q(t) = q_L(t) q0 q_3(t): a turn by t |L| / I1 about L (world) times a turn by
    t c, c = (1/I3 - 1/I1) M3, about the body e3 (see the ODE test above), evaluated in
    decimal.  Per step the Taylor truncation is ~e^(-2p) ~ 1e-35 and the rounding ~1e-34 at
    34 digits; a few hundred steps stay far below 1e-28 rad.
    """
    body = RigidBody(1.0, (1.0, 1.0, 2.0))
    state = State.from_velocity(body, rotation=rotation_matrix_from_rotation_vector(
        [0.3, -0.8, 0.5]), angular_velocity_body=(0.7, -0.4, 3.0))
    time = exact_time(1000, 0.01)
    values, drift = taylor_flow(body.inertia, state.quaternion, state.angular_momentum,
                                [time])
    with decimal.localcontext() as context:
        context.prec = 50
        q0 = [Decimal(float(c)) for c in state.quaternion]
        norm = sum(c * c for c in q0).sqrt()
        q0 = [c / norm for c in q0]
        momentum = [Decimal(float(c)) for c in state.angular_momentum]
        size = sum(c * c for c in momentum).sqrt()
        # M3 = (R0^T L)_3 = L . (R0 e3), the third column of R(q0).
        x, y, z, w = q0
        column3 = (2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y))
        m3 = sum(a * b for a, b in zip(momentum, column3))
        inertia_1, inertia_3 = Decimal(1), Decimal(2)
        precession = time * size / inertia_1
        spin = time * (1 / inertia_3 - 1 / inertia_1) * m3
        half_sine, half_cosine = _sine(precession / 2), _cosine(precession / 2)
        q_l = [half_sine * c / size for c in momentum] + [half_cosine]
        q_3 = [Decimal(0), Decimal(0), _sine(spin / 2), _cosine(spin / 2)]
        expected = _product(_product(q_l, q0), q_3)
        assert quaternion_angle(values[time], expected) < 1e-28
    assert drift < 1e-30


def _sine(x):
    """Return sin(x) for a Decimal x by its Taylor series (current context)."""
    return _series(x, x, 1)


def _cosine(x):
    """Return cos(x) for a Decimal x by its Taylor series (current context)."""
    return _series(x, Decimal(1), 0)


def _series(x, term, k):
    """Sum term - term x^2 / ((k+1)(k+2)) + ... until the terms drop below the precision."""
    # |x| <= ~30 here: the largest term is ~1e12, so 50 digits leave ~38 after cancellation.
    total = Decimal(0)
    smallest = Decimal(10) ** -(decimal.getcontext().prec + 2)
    while abs(term) >= smallest or k < 2:
        total += term
        term = -term * x * x / ((k + 1) * (k + 2))
        k += 2
    return total


def _product(a, b):
    """Hamilton product of quaternions stored (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return [aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz]


def test_committed_extended_reference_covers_every_run_and_is_reproduced():
    """
    Every (N, dt) of both sweeps has a committed value, and recomputing one gives it again.

    Recomputed: van_zon at 2 s, which must agree within the solves' own agreement.
    """
    cases = {case.name: case for case in benchmark_cases(CASE_NAMES)}
    for name, case in cases.items():
        entry = committed_references('bodies')[problem_fingerprint(case.body, case.state)]
        needed = set()
        for config in (FULL, QUICK):
            if name in config.cases:
                needed |= {key_string(*key) for key in reference_keys(config)}
        assert needed <= set(entry['values']), (name, needed - set(entry['values']))
        assert max(value[4] for value in entry['values'].values()) < 1e-20
    case = cases['van_zon']
    time = exact_time(20, 0.1)
    # One solve at 34 digits (the committed value is the 42-digit one of the pair).
    values, _ = taylor_flow(case.body.inertia, case.state.quaternion,
                            case.state.angular_momentum, [time])
    fingerprint = problem_fingerprint(case.body, case.state)
    committed = committed_references('bodies')[fingerprint]['values']
    with decimal.localcontext() as context:
        context.prec = 50
        again = values[time]
        stored = [Decimal(c) for c in committed[key_string(20, 0.1)][:4]]
        # Not bit for bit: another precision, and the step sizes come from float powers,
        # which may differ by an ulp between libms; the solves agree to ~1e-30 rad.
        assert quaternion_angle(again, stored) < 1e-25


def test_an_uncommitted_problem_is_computed_once_then_read_from_the_cache(tmp_path,
                                                                          monkeypatch):
    """A body not in the committed values is solved and cached; the second call reads it."""
    monkeypatch.setenv('RIGID_BODY_SIM_CACHE', str(tmp_path))
    body = RigidBody(1.0, (1.0, 1.5, 2.0))
    state = State.from_velocity(body, angular_velocity_body=(0.2, 0.3, 0.5))
    first, _, origin = reference_quaternions(body, state, [(2, 0.5)])
    assert origin == 'computed now'
    assert (tmp_path / 'benchmark_reference.json').exists()
    second, _, origin = reference_quaternions(body, state, [(2, 0.5)])
    assert origin == 'cached'
    assert second == first
    assert first[(2, 0.5)][1] < 1e-25


def test_cost_to_reach_interpolates_a_power_law_curve():
    """On error = dt^2, cost = 1e-6 / dt, the cost to reach e is 1e-6 / sqrt(e)."""
    dts = [0.1, 0.03, 0.01, 0.003, 0.001]
    points = [(dt, 1e-6 / dt, dt * dt) for dt in dts]
    reach = cost_to_reach(points, 1e-4)
    assert reach.cost == pytest.approx(1e-6 / 1e-2, rel=1e-12)
    assert reach.kind == 'interpolated' and reach.lower == reach.cost
    assert reach.dts == (0.03, 0.01)
    reach = cost_to_reach(points, 0.1)
    # The coarsest step already reaches 0.1: an upper bound, with no lower bound.
    assert (reach.cost, reach.lower, reach.kind) == (pytest.approx(1e-5), 0.0, 'coarsest')


@pytest.mark.parametrize('not_tracking', [SATURATION, 2.5, math.inf])
def test_cost_to_reach_never_interpolates_across_a_saturated_or_diverged_step(not_tracking):
    """
    Error 2.5 rad at dt = 1 then 1e-3 at dt = 0.1: the 1e-2 level costs between the two.

    A log-log line from the saturated point would cross 1e-2 at a made-up cost (here
    ~84 % of the way to the second step); the reach is instead bracketed by the two steps.
    """
    points = [(1.0, 1e-6, not_tracking), (0.1, 1e-5, 1e-3), (0.01, 1e-4, 1e-5)]
    reach = cost_to_reach(points, 1e-2)
    assert (reach.cost, reach.lower, reach.kind) == (1e-5, 1e-6, 'after saturated')
    assert reach.dts == (1.0, 0.1)
    # Between the two tracking steps the interpolation is used as usual.
    reach = cost_to_reach(points, 1e-4)
    assert reach.kind == 'interpolated'
    assert reach.cost == pytest.approx(10 ** -4.5, rel=1e-12)


def test_a_level_no_step_reaches_is_bounded_below_by_the_finest_step():
    """Not reached: cost inf, lower bound = the finest measured step's cost."""
    points = [(1.0, 1e-6, 3.0), (0.1, 1e-5, 1e-3), (0.01, 1e-4, 1e-6)]
    reach = cost_to_reach(points, 1e-9)
    assert (reach.cost, reach.lower, reach.kind) == (math.inf, 1e-4, 'not reached')
    assert reach.dts == (0.01,)


@pytest.mark.parametrize('ours, peer, peer_lower, expected', [
    (1e-5, 2e-5, 2e-5, 'holds'),             # both interpolated: ratio exactly 1/2
    (1e-5, 1.9e-5, 1.9e-5, 'fails'),         # ratio 0.53
    (1e-5, math.inf, 2e-5, 'holds'),          # MuJoCo never reaches; its finest costs 2x
    (1e-5, math.inf, 1.5e-5, 'not decided'),  # ... only 1.5x: no 2x margin shown
    (math.inf, math.inf, 1e-3, 'neither reaches'),
    (1e-5, 1e-4, 0.0, 'holds*'),              # MuJoCo reaches at its coarsest step only
    (1e-5, 3e-5, 1e-5, 'not decided'),        # MuJoCo between 1e-5 and 3e-5: ratio 1/3 .. 1
])
def test_goal_verdict_needs_a_2x_margin_on_the_bounds(ours, peer, peer_lower, expected):
    """'holds' needs ours <= 1/2 MuJoCo's lower bound; never a verdict without a number."""
    outcome, low, high = verdict(ours, ours, peer, peer_lower, 1e-6, 1e-15)
    assert outcome == expected
    if outcome == 'holds':
        assert high <= 0.5 and math.isfinite(high)


def test_goal_verdict_is_unresolved_below_the_reference_resolution():
    """A level below the reference's resolution is 'unresolved' even when both reach it."""
    assert verdict(1e-6, 1e-6, 1e-3, 1e-3, 1e-12, 2e-12)[0] == 'unresolved'
    assert verdict(1e-6, 1e-6, 1e-3, 1e-3, 1e-11, 2e-12)[0] == 'holds'


def _synthetic_result(uncertainty):
    """One body, 'exact' (ours) and 'mujoco_rk4' at three steps; MuJoCo stops at 1e-8."""
    records = []
    fronts = {'exact': [(1.0, 1e-6, 1e-13), (0.1, 1e-5, 1e-13), (0.01, 1e-4, 1e-12)],
              'mujoco_rk4': [(1.0, 1e-5, 2.0), (0.1, 1e-4, 1e-4), (0.01, 1e-3, 1e-8)]}
    for method, front in fronts.items():
        for dt, cost, error in front:
            steps = round(10.0 / dt)
            records.append({'case': 'body', 'method': method, 'dt': dt, 'steps_short': steps,
                            'steps_long': 10 * steps, 'error_short': error,
                            'error_long': error, 'cpu_per_sim_second': cost})
    keys = {key_string(r[f'steps_{h}'], r['dt']): uncertainty for r in records
            for h in ('short', 'long')}
    return {'methods': list(fronts), 'records': records,
            'references': {'body': {'uncertainty': keys}}}


def test_goal_table_bounds_never_reached_levels_and_flags_unresolved_ones():
    """
    Goal rows of a synthetic front: bounds where MuJoCo never reaches, unresolved levels.

    MuJoCo (finest step: 1e-3 CPU s/sim s) reaches 1e-8 at best; ours costs 1e-6 at every
    level.  1e-2: MuJoCo's first tracking step follows a
    saturated one, so its cost lies in (1e-5, 1e-4]: holds (ratio <= 0.1).  1e-9 .. 1e-11:
    holds against the bound 1e-3 (ratio <= 1e-3).  With a reference good to 5e-12 only,
    1e-12 is 'unresolved'.  Every pair is counted.
    """
    rows = goal_table(_synthetic_result(5e-12))
    by_level = {row['level']: row for row in rows}
    first = by_level[1e-2]
    assert first['verdict'] == 'holds'
    assert first['mujoco_reach']['kind'] == 'after saturated'
    assert first['ratio_high'] == pytest.approx(1e-6 / 1e-5)
    for level in (1e-9, 1e-10, 1e-11):
        row = by_level[level]
        assert row['mujoco_reach']['kind'] == 'not reached'
        assert row['mujoco_lower'] == 1e-3
        assert row['verdict'] == 'holds' and row['ratio_high'] == pytest.approx(1e-3)
    assert by_level[1e-12]['verdict'] == 'unresolved'
    counts = goal_summary(rows)
    assert sum(counts.values()) == len(GOAL_LEVELS)
    assert counts['unresolved'] == 1 and counts['holds'] == len(GOAL_LEVELS) - 1

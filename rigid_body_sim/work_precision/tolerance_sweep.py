"""
What error control buys on the built-in scenes: tolerance -> error -> substeps -> CPU.

A :class:`SweepCase` is a scene (body, initial state, effects, rate), a span of simulated
time, and optionally a forcing (a wrench held by the simulator, changed between ticks).
For each case :func:`tolerance_sweep` runs

- ``buss`` under error control at each tolerance (rad per simulated s), and
- fixed-step runs of ``buss``, ``splitting`` and ``rk4`` at 1, 2, 3, 4, 6, 8, ... substeps
  per tick (the scene's tick, 1 / rate),

and measures for each run: the orientation error (rad, rotation angle to the reference)
at its largest over samples every :data:`SAMPLE_INTERVAL` s of the span; the integrator
steps per tick (the estimates' extra steps included); the substeps' range; and the CPU time
per simulated second (:data:`.cells.CPU_CLOCK` around one call that takes the whole span:
``Simulator.run``, so the compiled kernel takes every tick; a forced case steps tick by
tick, as the node does).

The sweep is a :class:`.cells.Plan` (:func:`sweep_plan`): a reference per case, then a cell
per (case, method), the method's runs in order (each decides whether the next is worth
running), which any process can run; :func:`tolerance_sweep` runs it here.

References (:func:`case_reference`):

- torque-free rotation (no effect that turns the body: gravity acts at the COM, and an
  external_wrench without input does nothing; no forcing): the extended-precision Taylor
  solve of :mod:`.extended_reference`, independent of every integrator, taken at exactly
  N ticks (:func:`case_reference_keys`); its values for the built-in scenes are committed
  (:func:`.extended_reference.committed_references`, ``benchmarks/regenerate_references.py``
  recomputes them, minutes), other problems are computed and cached;
- otherwise a converged fine-step run: the classical ``rk4`` at REFERENCE_SUBSTEPS substeps
  per tick, its uncertainty the largest difference to the run at twice as many.

Errors below the reference's uncertainty are not resolved (the report marks them).
"""

from dataclasses import dataclass
import functools
import math
import statistics

import numpy as np

from .cells import CPU_CLOCK
from .cells import Plan
from .cells import run_in_process
from .extended_reference import reference_quaternions
from .reference import MEASUREMENT_FLOOR
from .reference import rotation_angle
from ..physics import matrix_from_quaternion
from ..scenes import load_scene
from ..scenes import scene_names

__all__ = ['SweepCase', 'scene_cases', 'case_reference', 'measure_case_run', 'advance',
           'measure_method_runs', 'reference_of', 'tolerance_sweep', 'sweep_plan',
           'sweep_units', 'is_torque_free', 'SAMPLE_INTERVAL', 'TOLERANCES', 'FIXED_SUBSTEPS',
           'FIXED_METHODS', 'NATURAL_SPANS', 'SWEEP_SPAN', 'FINEST_ERROR', 'MOST_STEPS_PER_SECOND',
           'case_reference_keys']

SAMPLE_INTERVAL = 0.5
"""Simulated time (s) between the samples at which the error is measured."""
SWEEP_SPAN = 60.0
"""The span (s) of the benchmark's sweep: errors 'over 60 s'."""
TOLERANCES = tuple(float(f'{m}e{e}') for e in range(-2, -11, -1) for m in (3, 1))
"""The tolerances (rad per simulated s) swept, 3e-2 down to 1e-10 (until a run is fine
enough or too dear, see tolerance_sweep)."""
FIXED_SUBSTEPS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768,
                  1024, 1536, 2048, 3072, 4096)
"""Substeps per tick of the fixed-step runs (a dense grid: costs are interpolated on it)."""
FIXED_METHODS = ('buss', 'splitting', 'rk4')
REFERENCE_SUBSTEPS = 64
# A method's sweep stops once its error is below this (rad): a decade under the finest level
# the report compares (1e-8).
FINEST_ERROR = 1e-9
# Nor does it go on past this many integrator steps per simulated second of the span.
MOST_STEPS_PER_SECOND = 5.0e5
# Timed runs per record stop after this much CPU (s), after at least one.
TIMING_BUDGET = 1.0

NATURAL_SPANS = {
    'default': 60.0,        # 4 flips (every 14.4 s)
    't_handle': 60.0,
    'tennis_racket': 12.0,  # 4 periods of 2.77 s, 8 flips
    'van_zon': 10.0,        # 4 periods of 2.35 s
    'stable_spin': 20.0,    # 6 nutation periods of 3.14 s
    'thrown_box': 6.0,      # 3 periods of 1.99 s (the flight itself ends at 0.82 s)
    'heavy_top': 6.0,       # 3 precession periods (~1.9 s), ~9 nutations
    'bike_wheel': 12.0,     # 2 precession periods (~5.7 s)
    'flat_spin': 40.0,      # the whole migration to the flat spin
    'driven': 10.0,         # 10 different pushes, one per second
}
"""Each built-in scene's natural span (s): several flips or precession periods."""


@dataclass(frozen=True)
class SweepCase:
    """
    A scene to sweep: its simulator, span and forcing.

    Attributes
    ----------
    name : str
    scene : Scene
        Body, initial state, effects, rate (the tick is 1 / rate).
    span : float
        Simulated time (s), a multiple of SAMPLE_INTERVAL.
    forcing : callable or None
        forcing(simulator, time) before each tick (time: its start, s): holds the wrench of
        that tick (Simulator.hold_wrench), e.g. a torque that changes every second; the same
        for the runs and the reference.

    """

    name: str
    scene: object
    span: float
    forcing: object = None

    @property
    def tick(self):
        """Get the scene's tick in s (1 / rate)."""
        return self.scene.dt

    @property
    def ticks(self):
        """Get the number of ticks in the span."""
        return int(round(self.span / self.tick))

    def simulator(self, integrator, tolerance=None, substeps=1):
        """Return a fresh Simulator of the case (tolerance None: fixed `substeps`)."""
        simulator = self.scene.simulator(integrator=integrator, tolerance=tolerance or 0.0)
        simulator.substeps = substeps
        return simulator


def _driven_forcing(simulator, time):
    """Hold a new torque every second (world and body parts, ~2 mN m), swelling each tick."""
    rng = np.random.default_rng(int(time))
    world = rng.uniform(-2e-3, 2e-3, 3) * (1.0 + 0.5 * math.sin(3.0 * time))
    simulator.hold_wrench(torque_world=world, torque_body=rng.uniform(-1e-3, 1e-3, 3))


def scene_cases(names=None, span=None):
    """
    Return a SweepCase per built-in scene (all by default), over `span` s or its natural span.

    The scene `driven` (a body at rest, pushed only from outside) is driven by a torque that
    changes every second (world and body parts, ~2 mN m) and swells with a 2 s period in
    between: a wrench that changes between ticks.
    """
    cases = []
    for name in names or scene_names(several_bodies=False):
        scene = load_scene(name)
        forcing = _driven_forcing if name == 'driven' else None
        cases.append(SweepCase(name, scene, span or NATURAL_SPANS.get(name, SWEEP_SPAN),
                               forcing))
    return cases


def is_torque_free(case):
    """Return True if nothing turns the body in `case` (the reference is then extended)."""
    if case.forcing is not None:
        return False
    for effect in case.scene.effects:
        name = getattr(effect, 'effect_name', None)
        if name not in ('gravity', 'external_wrench'):
            return False
    return True


def _sample_ticks(case):
    every = int(round(SAMPLE_INTERVAL / case.tick))
    return list(range(every, case.ticks + 1, every))


def case_reference_keys(case):
    """Return the (N, dt) of each sample: N ticks of dt, the case's tick (s)."""
    return [(mark, case.tick) for mark in _sample_ticks(case)]


def advance(simulator, case, start, stop):
    """Take ticks start .. stop - 1 of the case (forced tick by tick)."""
    if case.forcing is None:
        simulator.run((stop - start) * case.tick, case.tick)
        return
    for index in range(start, stop):
        case.forcing(simulator, index * case.tick)
        simulator.step(case.tick)


def _fine_rotations(case, substeps):
    simulator = case.simulator('rk4', substeps=substeps)
    rotations, done = {}, 0
    for mark in _sample_ticks(case):
        advance(simulator, case, done, mark)
        done = mark
        rotations[mark] = np.array(simulator.state.rotation)
    return rotations


def case_reference(case):
    """
    Return (rotations, uncertainty, origin) of the case's reference at the sample ticks.

    rotations: {tick count: R (3x3, body to world)}; uncertainty: the reference's own error
    estimate (rad, the largest over the samples, at least MEASUREMENT_FLOOR); origin: how
    it was obtained.
    """
    marks = _sample_ticks(case)
    scene = case.scene
    if is_torque_free(case):
        values, _, origin = reference_quaternions(scene.body, scene.state,
                                                  case_reference_keys(case))
        rotations = {mark: _double_rotation(values[(mark, case.tick)][0]) for mark in marks}
        uncertainty = max(values[key][1] for key in values)
        return rotations, max(uncertainty, MEASUREMENT_FLOOR), f'extended precision ({origin})'
    fine = _fine_rotations(case, REFERENCE_SUBSTEPS)
    finer = _fine_rotations(case, 2 * REFERENCE_SUBSTEPS)
    uncertainty = max(rotation_angle(fine[mark], finer[mark]) for mark in marks)
    return finer, max(uncertainty, MEASUREMENT_FLOOR), (
        f'rk4 at {2 * REFERENCE_SUBSTEPS} substeps per tick (gap to {REFERENCE_SUBSTEPS}: '
        f'{uncertainty:.1e} rad)')


def _double_rotation(quaternion):
    return matrix_from_quaternion(np.array([float(c) for c in quaternion]))


def measure_case_run(case, reference, integrator, tolerance=None, substeps=1, repeats=3):
    """
    Measure one run of a case; return a dict (see the module docstring).

    Keys: case, method ('<integrator>' fixed or '<integrator>+control'), tolerance,
    substeps (the fixed count, or the lower bound), error (rad, largest over the samples),
    steps_per_tick, substeps_min, substeps_max, cpu_per_second (CPU s per simulated s,
    median of `repeats` timed runs), us_per_tick.
    """
    simulator = case.simulator(integrator, tolerance, substeps)
    error, done = 0.0, 0
    for mark in _sample_ticks(case):
        advance(simulator, case, done, mark)
        done = mark
        error = max(error, rotation_angle(simulator.state.rotation, reference[mark]))
    figures = simulator.substep_statistics()
    # The accuracy run was the warm-up: the kernels are loaded, none is compiled while timed.
    samples = []
    while len(samples) < repeats and not (samples and sum(samples) > TIMING_BUDGET):
        timed = case.simulator(integrator, tolerance, substeps)
        started = CPU_CLOCK()
        advance(timed, case, 0, case.ticks)
        samples.append(CPU_CLOCK() - started)
    cpu = statistics.median(samples) / case.span
    steps = figures['steps'] / figures['ticks'] if tolerance else float(substeps)
    return {
        'case': case.name, 'method': integrator + ('+control' if tolerance else ''),
        'tolerance': tolerance, 'substeps': substeps, 'error': error,
        'steps_per_tick': steps, 'substeps_min': figures['substeps_min'],
        'substeps_max': figures['substeps_max'], 'cpu_per_second': cpu,
        'us_per_tick': cpu * case.tick * 1e6,
    }


@functools.lru_cache(maxsize=None)
def _sweep_case(name, span):
    """Return the SweepCase of a built-in scene over `span` s, built once per process."""
    return scene_cases([name], span)[0]


def reference_of(name, span):
    """Return :func:`case_reference` of a built-in scene's case over `span` s."""
    return case_reference(_sweep_case(name, span))


def measure_method_runs(name, span, integrator, runs, repeats, reference):
    """
    Measure one method's runs of a built-in scene over `span` s in order; return the records.

    runs: (tolerance or None, substeps) each.  A fixed-step run past MOST_STEPS_PER_SECOND
    is not run; the runs end after one whose error falls below FINEST_ERROR or whose steps
    pass MOST_STEPS_PER_SECOND.  reference: the rotations of :func:`case_reference`.
    """
    case = _sweep_case(name, span)
    records = []
    for tolerance, substeps in runs:
        if tolerance is None and substeps / case.tick > MOST_STEPS_PER_SECOND:
            break
        record = measure_case_run(case, reference, integrator, tolerance, substeps, repeats)
        records.append(record)
        if record['error'] < FINEST_ERROR or (
                record['steps_per_tick'] / case.tick > MOST_STEPS_PER_SECOND):
            break
    return records


def _rotations(reference):
    return reference[0]


def sweep_plan(cases, tolerances=TOLERANCES, fixed_methods=FIXED_METHODS,
               fixed_substeps=FIXED_SUBSTEPS, repeats=3):
    """
    Return the sweep over `cases` as a Plan (its result: see :func:`tolerance_sweep`).

    The cases are built-in scenes (:func:`scene_cases`): a cell names its scene and span, and
    the process that runs it builds the case again (a Scene does not travel pickled).
    """
    plan = None

    def assemble(references, values):
        found, records = {}, []
        for case in cases:
            _, uncertainty, origin = references[f'{plan.part}/{case.name}/reference']
            found[case.name] = {'uncertainty': uncertainty, 'origin': origin,
                                'span': case.span, 'tick': case.tick}
            for name in order[case.name]:
                records.extend(values[name])
        return {'references': found, 'records': records}

    plan = Plan('tolerance_sweep', assemble)
    order = {}
    methods = [('buss', [(tolerance, 1) for tolerance in tolerances])] + [
        (method, [(None, substeps) for substeps in fixed_substeps]) for method in fixed_methods]
    for case in cases:
        reference = plan.add_reference(f'{case.name}/reference', reference_of,
                                       (case.name, case.span), weight=math.inf)
        order[case.name] = [
            plan.add_cell(f'{case.name}/{integrator}{"+control" if runs[0][0] else ""}',
                          measure_method_runs, (case.name, case.span, integrator, runs, repeats),
                          reference,
                          _rotations, weight=case.ticks * len(runs))
            for integrator, runs in methods if runs]
    return plan


def tolerance_sweep(cases, tolerances=TOLERANCES, fixed_methods=FIXED_METHODS,
                    fixed_substeps=FIXED_SUBSTEPS, repeats=3, progress=None):
    """
    Run the sweep over `cases` here; return {'references': {...}, 'records': [...]}.

    Error-controlled ``buss`` at each tolerance, and each of `fixed_methods` at each count
    of `fixed_substeps`, each in order until a run's error falls below FINEST_ERROR or its
    steps pass MOST_STEPS_PER_SECOND of simulated time (:func:`measure_method_runs`).
    `progress(label)` is called after each case's reference and each method's runs.
    """
    return run_in_process(sweep_plan(cases, tolerances, fixed_methods, fixed_substeps,
                                     repeats), progress)


def sweep_units(cases, tolerances=TOLERANCES, fixed_methods=FIXED_METHODS,
                fixed_substeps=FIXED_SUBSTEPS):
    """Return the progress units tolerance_sweep reports (a reference, then each method)."""
    return sweep_plan(cases, tolerances, fixed_methods, fixed_substeps).units

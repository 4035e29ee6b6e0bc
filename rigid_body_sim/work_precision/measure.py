"""
Errors and CPU time of one benchmark run, and the whole sweep.

For one case (body + initial state), one method (a registered integrator or a MuJoCo
integrator) and one time step dt:

- accuracy run: N_short = round(T_short / dt) and N_long = round(T_long / dt) steps of exactly
  dt (so both methods take the same steps; the reference is taken at exactly N x dt: 9.9 s
  for dt = 0.3), sampled every ~0.1 s of simulated time (every step for dt >= 0.1).
  Measured: the orientation error (rotation angle, rad, between the computed R and the
  reference R) at t = N_short dt and t = N_long dt; the max relative
  kinetic-energy error max |T(t) - T(0)| / T(0); the max relative error of the magnitude of
  the angular momentum max ||L(t)| - |L(0)|| / |L(0)|; and, for the JSON, the max relative
  error of the world vector L, max |L(t) - L(0)| / |L(0)|.
- timing runs: a fresh start, then N_long steps in ONE call (``Simulator.run`` for ours,
  ``mujoco.mj_step(..., nstep=N_long)`` for MuJoCo: each its own compiled loop where it has
  one), timed with :data:`.cells.CPU_CLOCK` (CPU time of the thread that runs it, so other
  processes on a shared machine, and a Dask worker's own threads, count less).  One timing
  sample is the mean over as many such fresh runs as it takes to spend
  :data:`MIN_SAMPLE_CPU` (a run of 10 steps of dt = 10 s takes only microseconds, too close
  to the timer's own cost); samples are repeated and the median
  kept.  The accuracy run before it is the warm-up, so numba compilation is never timed.
  Reported: us per step and CPU seconds per simulated second.

The sweep is a :class:`.cells.Plan` (:func:`benchmark_plan`): a reference per case, then a
cell per (case, method, dt), which any process can run (``bench`` gives them to Dask
workers); :func:`run_benchmark` runs it here.
"""

from dataclasses import asdict
from dataclasses import dataclass
import functools
import math
import statistics

import numpy as np

from .bodies import benchmark_cases
from .bodies import CASE_NAMES
from .bodies import QUICK_CASE_NAMES
from .cells import CPU_CLOCK
from .cells import Plan
from .cells import run_in_process
from .extended_reference import key_string
from .peer_mujoco import mujoco_available
from .peer_mujoco import MUJOCO_INTEGRATORS
from .peer_mujoco import MujocoPeer
from .reference import reference_rotations
from ..physics import INTEGRATORS
from ..physics import Simulator
from ..physics.simulator import DivergedError

__all__ = ['BenchmarkConfig', 'FULL', 'QUICK', 'step_counts', 'measure_run', 'run_benchmark',
           'benchmark_plan', 'our_integrators', 'reference_keys', 'work_units']

# Simulated time (s) between the energy / momentum samples of an accuracy run.
SAMPLE_INTERVAL = 0.1
# Least CPU time (s) of one timing sample: short runs are repeated (fresh each time) until
# they add up to this, so the timer's own cost stays a negligible part of a sample.
MIN_SAMPLE_CPU = 2e-3


@dataclass(frozen=True)
class BenchmarkConfig:
    """
    What one benchmark sweep covers.

    Attributes
    ----------
    cases : tuple of str
        Benchmark body names (see :mod:`.bodies`).
    dts : tuple of float
        Time steps in s.
    horizons : (float, float)
        The short and the long horizon in s (orientation errors are taken at both).
    repeats : int
        Timing repeats (median kept).
    time_budget : float
        Stop repeating a timing once this much CPU time (s) is spent, after >= 1 repeat.

    """

    cases: tuple
    dts: tuple
    horizons: tuple
    repeats: int
    time_budget: float


# The steps 0.1 .. 0.001 s, and coarser ones so that every method's front reaches its
# cheapest end: dt = 10 s is one step to the 10 s horizon, where the exact flow is at its most
# accurate (the fewest roundings); the explicit methods just show O(1) errors there.
FULL = BenchmarkConfig(CASE_NAMES, (10.0, 1.0, 0.3, 0.1, 0.03, 0.01, 0.003, 0.001),
                       (10.0, 100.0), 5, 4.0)
QUICK = BenchmarkConfig(QUICK_CASE_NAMES, (1.0, 0.1, 0.01), (2.0, 10.0), 3, 0.5)


def our_integrators():
    """Return the registered integrator names, sorted (whatever is registered now)."""
    return sorted(INTEGRATORS)


def step_counts(dt, horizons):
    """Return (N_short, N_long, stride): steps to each horizon and between samples."""
    short, long = (max(1, int(round(h / dt))) for h in horizons)
    return short, long, max(1, int(round(SAMPLE_INTERVAL / dt)))


class _OurRun:
    """Adapter: a Simulator behind the interface the measurements use."""

    family = 'ours'

    def __init__(self, case, integrator, dt):
        self.case, self.integrator, self.dt = case, integrator, dt
        self.reset()

    def reset(self):
        self.simulator = Simulator(self.case.body, self.case.state, integrator=self.integrator)
        self.blew_up = False

    def advance(self, steps):
        # A method that diverges at a long step is a result here (an error beyond any
        # level), not a failure: the Simulator stops it at its last finite state.
        if not self.blew_up:
            try:
                self.simulator.run(steps * self.dt, self.dt)
            except DivergedError:
                self.blew_up = True

    def diverged(self):
        return self.blew_up

    def observe(self):
        state = self.simulator.state
        return state.rotation, state.kinetic_energy(self.case.body), state.angular_momentum


class _MujocoRun:
    """Adapter: a MujocoPeer behind the interface the measurements use."""

    family = 'mujoco'

    def __init__(self, case, integrator, dt):
        self.peer = MujocoPeer(case.body, case.state, integrator, dt)

    def reset(self):
        self.peer.reset()

    def advance(self, steps):
        self.peer.step(steps)

    def diverged(self):
        # MuJoCo resets the state itself when qacc blows up, so a divergence must be read
        # from its warning counters, not from the (reset, finite) state.
        return any(self.peer.data.warning[i].number > 0
                   for i in range(len(self.peer.data.warning)))

    def observe(self):
        peer = self.peer
        return peer.rotation, peer.kinetic_energy(), peer.angular_momentum


@dataclass
class RunRecord:
    """
    The measurements of one (case, method, dt); see the module docstring.

    Errors are inf when the run diverged before they were measured (energy and momentum
    errors always are then).  Times: us_per_step (microseconds per step) and
    cpu_per_sim_second (CPU s per simulated s), medians over `timing_repeats`.
    """

    case: str
    method: str
    family: str
    dt: float
    steps_short: int
    steps_long: int
    time_short: float
    time_long: float
    error_short: float
    error_long: float
    max_energy_error: float
    max_momentum_magnitude_error: float
    max_world_momentum_error: float
    us_per_step: float
    cpu_per_sim_second: float
    timing_repeats: int
    diverged: bool


def _accuracy(run, dt, horizons, reference):
    n_short, n_long, stride = step_counts(dt, horizons)
    _, energy0, momentum0 = run.observe()
    magnitude0 = np.linalg.norm(momentum0)
    marks = sorted(set(range(stride, n_long, stride)) | {n_short, n_long})
    energy_error = magnitude_error = world_error = 0.0
    errors = {}
    done = 0
    for mark in marks:
        run.advance(mark - done)
        done = mark
        if run.diverged():
            # An error measured before the blow-up stands; everything after it is lost.
            return (errors.get(n_short, math.inf), math.inf, math.inf, math.inf, math.inf,
                    True)
        rotation, energy, momentum = run.observe()
        energy_error = max(energy_error, abs(energy - energy0) / energy0)
        magnitude_error = max(magnitude_error,
                              abs(np.linalg.norm(momentum) - magnitude0) / magnitude0)
        world_error = max(world_error, np.linalg.norm(momentum - momentum0) / magnitude0)
        if mark in (n_short, n_long):
            errors[mark] = reference.angle_error(mark, dt, rotation)
    return (errors[n_short], errors[n_long], energy_error, magnitude_error, world_error,
            False)


def _timing(run, steps, repeats, budget):
    samples = []
    spent = 0.0
    while len(samples) < repeats and not (samples and spent > budget):
        elapsed, runs = 0.0, 0
        while runs == 0 or elapsed < MIN_SAMPLE_CPU:
            run.reset()
            started = CPU_CLOCK()
            run.advance(steps)
            elapsed += CPU_CLOCK() - started
            runs += 1
        samples.append(elapsed / runs)
        spent += elapsed
    return statistics.median(samples), len(samples)


def measure_run(case, method, dt, reference, config):
    """
    Measure one (case, method, dt) and return its RunRecord.

    Parameters
    ----------
    case : BenchmarkCase
        The body and its initial state.
    method : str
        A registered integrator name, or a key of :data:`MUJOCO_INTEGRATORS`.
    dt : float
        Time step in s.
    reference : Reference
        Reference orientations after N_short and N_long steps of dt (see
        :func:`reference_keys`).
    config : BenchmarkConfig
        Horizons and timing repeats.

    """
    adapter = _MujocoRun if method in MUJOCO_INTEGRATORS else _OurRun
    run = adapter(case, method, dt)
    n_short, n_long, _ = step_counts(dt, config.horizons)
    (error_short, error_long, energy_error, magnitude_error, world_error,
     diverged) = _accuracy(run, dt, config.horizons, reference)
    cpu, repeats = _timing(run, n_long, config.repeats, config.time_budget)
    return RunRecord(case.name, method, run.family, dt, n_short, n_long, n_short * dt,
                     n_long * dt, error_short, error_long, energy_error, magnitude_error,
                     world_error, cpu / n_long * 1e6, cpu / (n_long * dt), repeats, diverged)


def reference_keys(config):
    """Return every (N, dt) after which a reference orientation is needed (N steps of dt)."""
    keys = set()
    for dt in config.dts:
        n_short, n_long, _ = step_counts(dt, config.horizons)
        keys.update(((n_short, float(dt)), (n_long, float(dt))))
    return sorted(keys)


def _methods(with_mujoco):
    """Return (the methods measured, what became of the MuJoCo peer)."""
    methods = our_integrators()
    if with_mujoco and mujoco_available():
        return methods + list(MUJOCO_INTEGRATORS), 'included'
    if with_mujoco:
        return methods, 'not installed (import mujoco failed): peer skipped'
    return methods, 'skipped on request (--no-mujoco)'


@functools.lru_cache(maxsize=None)
def _benchmark_case(name):
    """Return the BenchmarkCase of a name, built once per process."""
    return benchmark_cases([name])[0]


def case_reference(name, keys):
    """Return the Reference of the named case after N steps of dt, each (N, dt) in keys."""
    case = _benchmark_case(name)
    return reference_rotations(case.body, case.state, keys)


def measure_cell(name, method, dt, config, reference):
    """Measure one (named case, method, dt) against its Reference; return its record."""
    return asdict(measure_run(_benchmark_case(name), method, dt, reference, config))


def benchmark_plan(config, with_mujoco=True):
    """
    Return the sweep of `config` as a Plan: a reference per case, a cell per run.

    Its result: see :func:`run_benchmark`.
    """
    methods, mujoco_status = _methods(with_mujoco)
    keys = reference_keys(config)
    cases = benchmark_cases(config.cases)
    plan = None

    def assemble(references, values):
        def by_key(values):
            return None if values is None else {key_string(*key): value
                                                for key, value in values.items()}
        found = {}
        for case in cases:
            reference = references[f'{plan.part}/{case.name}/reference']
            found[case.name] = {
                'origin': reference.origin, 'drift': reference.drift,
                'uncertainty': by_key(reference.uncertainty),
                'exact_gap': by_key(reference.exact_gap), 'ode_gap': by_key(reference.ode_gap),
            }
        return {'methods': methods, 'mujoco': mujoco_status, 'references': found,
                'records': [values[name] for name in order]}

    plan = Plan('work_precision', assemble)
    order = []
    for case in cases:
        reference = plan.add_reference(f'{case.name}/reference', case_reference,
                                       (case.name, keys), weight=math.inf)
        for method in methods:
            for dt in config.dts:
                order.append(plan.add_cell(f'{case.name}/{method}/dt={dt:g}', measure_cell,
                                           (case.name, method, dt, config), reference,
                                           weight=step_counts(dt, config.horizons)[1]))
    return plan


def run_benchmark(config, with_mujoco=True, progress=None):
    """
    Run the whole sweep in this process; return a dict with the records and the references.

    Parameters
    ----------
    config : BenchmarkConfig
        Bodies, time steps, horizons and timing repeats.
    with_mujoco : bool
        Include the MuJoCo peer (ignored, and said so in the result, when mujoco does not
        import).
    progress : callable, optional
        Called with a short label after each unit of work; there are
        ``len(cases) * (1 + len(methods) * len(dts))`` units.

    Returns
    -------
    dict
        'methods' (list of str), 'mujoco' (str status), 'references' (per case: origin,
        drift, and uncertainty, exact_gap and ode_gap as {'N x dt': rad}), 'records' (list
        of dict, see RunRecord).

    """
    return run_in_process(benchmark_plan(config, with_mujoco), progress)


def work_units(config, with_mujoco=True):
    """Return the number of progress units :func:`run_benchmark` will report."""
    methods = len(our_integrators())
    if with_mujoco and mujoco_available():
        methods += len(MUJOCO_INTEGRATORS)
    return len(config.cases) * (1 + methods * len(config.dts))

"""
The compiled kernels as units of work: what an integrator needs, whether it is compiled.

The kernels fall into independent jobs, each compiled (or loaded from the cache) in one call
of :func:`compile_job`, so that the ``compile`` command can take them in parallel processes:

- ``shared``: what every scene uses whatever the integrator: the Model, the effects' terms,
  flows and constraint, the IMU, the derived quantities the messages are made of;
- ``controller``: the error controller (error_control.controlled) and the constructor of
  the structure that hands it a run kernel, one for every method; the tick of a World of
  many bodies (world.step_bodies), which calls them;
- ``run-<module>``: a method's run kernel (``run-buss`` serves buss and buss_plain,
  ``run-splitting`` splitting and splitting4).

An integrator is compiled when its jobs are marked compiled in the kernel folder of these
sources and the folder's sealed files are intact (:mod:`.kernels.cache`).  How long a job
takes: the CPU seconds it took on this machine, read from its marker (of these sources or of
earlier ones), else the estimate declared with its kernel (the run kernels' and the
controller's ``compile_seconds``; :data:`SHARED_SECONDS`).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
import time

import numpy as np

from . import error_control
from . import world
from .body import RigidBody
from .effects import create_effect
from .effects import EFFECTS
from .imu import Imu
from .imu import ImuModel
from .integrators import get_integrator
from .integrators import INTEGRATORS
from .kernels import cache
from .kernels.derived import derived_quantities
from .simulator import Simulator
from .state import State

__all__ = ['SHARED', 'CONTROLLER', 'SHARED_SECONDS', 'run_job', 'jobs_of', 'all_jobs',
           'missing_jobs', 'is_compiled', 'missing', 'declared_seconds', 'job_estimate',
           'compile_estimate', 'compile_job', 'load_kernels', 'damaged_files', 'WORKER_START']

SHARED = 'shared'
CONTROLLER = 'controller'

SHARED_SECONDS = 4.0
"""CPU seconds the shared job (:func:`_shared`) takes to compile on the 2-core development
machine (`rigid-body-sim compile` prints each job's figure): its estimate where this machine
has not compiled it yet."""


def run_job(name: str) -> str:
    """Return the job of integrator `name`'s run kernel (``run-<its module>``)."""
    return get_integrator(name).compile_job


def jobs_of(names: Iterable[str]) -> list[str]:
    """Return the jobs the integrators `names` need, in a fixed order."""
    runs = sorted({run_job(name) for name in names})
    return [SHARED, CONTROLLER] + runs


def all_jobs() -> list[str]:
    """Return every job (every integrator's)."""
    return jobs_of(sorted(INTEGRATORS))


_verified: dict[Path, list[str]] = {}


def damaged_files() -> list[str]:
    """Return the sealed cache files that are not as sealed (checked once per process)."""
    folder = cache.kernel_dir()
    if folder not in _verified:
        _verified[folder] = cache.verify(folder)
    return _verified[folder]


def forget_verification() -> None:
    """Check the sealed files again at the next :func:`damaged_files` (after a compile)."""
    _verified.clear()


def missing_jobs(jobs: Iterable[str]) -> list[str]:
    """Return the jobs among `jobs` that are not marked compiled (all of them if damaged)."""
    if not cache.caching_enabled():
        return list(jobs)
    if damaged_files():
        return list(jobs)
    return [job for job in jobs if not cache.is_marked(job)]


def is_compiled(name: str) -> bool:
    """Return True if the kernels of integrator `name` are compiled, sealed and intact."""
    return not missing_jobs(jobs_of([name]))


def missing(names: Iterable[str] | None = None) -> list[str]:
    """Return the integrators among `names` (default: all) whose kernels are not compiled."""
    return [name for name in (sorted(INTEGRATORS) if names is None else names)
            if not is_compiled(name)]


def declared_seconds() -> dict[str, float]:
    """Return {job: the CPU seconds declared with its kernels} for every job."""
    # Every run kernel and the controller declare theirs (kernels/loop.py's run_kernel).
    def declared_by(owner: object) -> float:
        seconds = getattr(owner, 'compile_seconds', None)
        if seconds is None:
            raise ValueError(f'{owner!r} declares no compile_seconds')
        return float(seconds)

    declared = {SHARED: SHARED_SECONDS, CONTROLLER: sum(
        declared_by(kernel)
        for kernel in error_control.CONTROLLER_KERNELS + world.WORLD_KERNELS)}
    for integrator in INTEGRATORS.values():
        declared[integrator.compile_job] = declared_by(integrator)
    return declared


def job_estimate(job: str) -> float:
    """Return the CPU seconds `job` takes to compile here, roughly (see the module)."""
    measured = cache.measured_seconds(job)
    if measured is not None:
        return measured
    declared = declared_seconds()
    if job not in declared:
        raise ValueError(f'unknown kernel job {job!r}; jobs: {", ".join(all_jobs())}')
    return declared[job]


WORKER_START = 1.5
"""Seconds a compile process takes to start and import the package, roughly."""


def compile_estimate(names: Iterable[str], workers: int = 1) -> float:
    """
    Return the seconds compiling the kernels of `names` takes, roughly (0 if compiled).

    With `workers` processes, the longest job or the total shared among them, whichever is
    longer, after the processes started (on an idle machine: a loaded one takes longer).
    """
    seconds = [job_estimate(job) for job in missing_jobs(jobs_of(names))]
    if not seconds:
        return 0.0
    return WORKER_START + max(max(seconds), sum(seconds) / max(1, workers))


def _shared() -> None:
    """Compile what every integrator shares: the model, the effects, the IMU, the messages."""
    body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
    state = State.from_velocity(body, angular_velocity_body=(0.1, 2.0, 0.1))
    effects = [create_effect(name, cls.example) for name, cls in sorted(EFFECTS.items())]
    simulator = Simulator(body, state, effects=effects)
    simulator.applied_wrench()
    simulator.state  # the pivot's expansion
    for effect in effects:
        if effect.compiled_wrench is not None:
            effect.wrench(body, state, 0.0)
        if effect.compiled_flow is not None:
            effect.flow(body, state, 0.01)
    imu = Imu(ImuModel(), body)
    imu.truth(state, np.zeros(3), np.zeros(3))
    Imu(ImuModel(), body, gravity=(0.0, 0.0, -9.81), pivot_offset=(0.0, 0.0, 0.1)).truth(
        state, np.zeros(3), np.zeros(3))
    # The velocities and marker turn the node's messages and simulate's bags are made of.
    derived_quantities(np.concatenate(state._fields())[None, :],
                       np.ascontiguousarray(body.inertia_inverse).reshape(9), body.mass,
                       np.array([0.0, 0.0, 0.0, 1.0]))


def compile_job(job: str) -> float:
    """
    Compile (or load from the cache) the kernels of `job` in this process.

    Returns the CPU seconds it took.  Marking it compiled is the compile command's, once
    every job is done and the folder sealed.
    """
    started = time.process_time()
    if job == SHARED:
        _shared()
    elif job == CONTROLLER:
        for kernel in error_control.CONTROLLER_KERNELS + world.WORLD_KERNELS:
            kernel.dispatcher
    else:
        kernels = {integrator.compile_job: integrator.run_kernel
                   for integrator in INTEGRATORS.values()}
        if job not in kernels:
            raise ValueError(f'unknown kernel job {job!r}; jobs: {", ".join(all_jobs())}')
        kernels[job].dispatcher
    return time.process_time() - started


def load_kernels(name: str) -> None:
    """
    Load the kernels of integrator `name` into this process (compiling what is not cached).

    The shared kernels, the controller and its run kernel: everything a scene runs with it.
    """
    for job in jobs_of([name]):
        compile_job(job)
    cache.touch_used()

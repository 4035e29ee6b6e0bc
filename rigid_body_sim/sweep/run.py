"""
One run of a sweep, in the process that executes it: its simulation, bag and table row.

:func:`execute_runs` is what a worker runs for a task (a few runs, one after another in
one process, the kernels loaded once before).  A run writes its bag, if the spec asks for
one, into a hidden folder beside its final place and renames it there when complete: a bag
under ``bags/`` is whole, and a run stopped half-way (a worker killed, Ctrl-C) leaves only a
hidden folder, which the next session removes before it runs that run again.

The row (:data:`rigid_body_sim.sweep.table.COLUMNS`): the run's body and initial state as
the scene resolved them, the final state, the drift of the conserved quantities, the error
against the reference where the scene has one, and the run's cost on its worker.  The
reference is the exact torque-free flow (the ``exact`` integrator: round-off at any step,
the parabola of the COM exact under uniform gravity), for a scene torque-free about the COM
(no effect, gravity, or external_wrench, which has no input offline); other scenes (a
pivot, drag, dissipation, a torque) have none and their error columns are null.
"""

import json
import os
from pathlib import Path
import shutil
import socket
import time
import uuid

import numpy as np

from .kernels import ready
from ..physics.effects import EFFECTS
from ..physics.simulator import DivergedError
from ..recording.simulate import simulate_to_bag

__all__ = ['BAGS_FOLDER', 'bag_path', 'execute_run', 'execute_runs', 'has_reference',
           'remove_partial_bags']

BAGS_FOLDER = 'bags'
REFERENCE_INTEGRATOR = 'exact'
_PARTIAL = '.partial-'
_BOTH = {'angular_momentum', 'rotational_energy'}


def bag_path(run_id):
    """Return a run's bag folder relative to the output folder (bags/<2 hex>/<id>)."""
    return f'{BAGS_FOLDER}/{run_id[:2]}/{run_id}'


def remove_partial_bags(out):
    """Remove the hidden folders of bags a stopped run left; return how many."""
    removed = 0
    for partial in Path(out, BAGS_FOLDER).glob(f'*/{_PARTIAL}*'):
        shutil.rmtree(partial, ignore_errors=True)
        removed += 1
    return removed


def has_reference(scene):
    """Return True if the scene is torque-free about the COM (its reference: the exact flow)."""
    return all(name in EFFECTS and _BOTH <= set(EFFECTS[name].conserves)
               and name != 'pivot' for name in scene.effect_names())


def conserved(scene):
    """Return what the scene's physics conserves: a sorted list of quantity names."""
    classes = [EFFECTS.get(name) for name in scene.effect_names()]
    names = set(_BOTH)
    for cls in classes:
        names &= set(() if cls is None else cls.conserves)
    # Kinetic plus potential energy: kept by the effects a pivot keeps its invariants under
    # (gravity, no input), and by the pivot itself (its reaction does no work).
    if all(cls is not None and (cls.keeps_pivot_invariants or cls.effect_name == 'pivot')
           for cls in classes):
        names.add('energy')
    return sorted(names)


def execute_runs(runs, out, integrators):
    """
    Execute `runs` one after another in this process; return their rows, in order.

    The kernels of `integrators` are loaded first (once per process).  `out` is the
    output folder as this process sees it.
    """
    ready(integrators)
    return [execute_run(run, out) for run in runs]


def execute_run(run, out):
    """
    Simulate `run`, write its bag (if it has one) under `out`; return its table row.

    A value that makes no valid scene gives an ``invalid`` row, a state that turns
    non-finite a ``diverged`` one (with the last finite state, and the bag up to it).
    Anything else (a bag that cannot be written) is raised: the run is not done.
    """
    cpu_started, wall_started = time.process_time(), time.perf_counter()
    row = {'run_id': run.run_id, 'status': 'ok', 'message': '', 'duration': run.duration,
           'substeps': run.substeps, 'parameters': json.dumps(run.parameters()),
           'host': socket.gethostname(), 'pid': os.getpid(), 'bag': None}
    try:
        scene = run.scene()
    except ValueError as error:
        row.update(status='invalid', message=str(error),
                   scene=str(run.base.get('name', '')),
                   integrator=str(run.changes.get('integrator', '')))
        return _finished(row, cpu_started, wall_started, 0.0)
    row.update(_run_columns(scene, run))
    watched = _WatchedScene(scene)
    try:
        if run.bag_storage is not None:
            row['bag'] = _write_bag(run, watched, out)
        else:
            simulator = watched.simulator()
            simulator.substeps = run.substeps
            simulator.run(run.duration, 1.0 / scene.rate)
    except DivergedError as error:
        row.update(status='diverged', message=str(error))
        if run.bag_storage is not None:
            row['bag'] = bag_path(run.run_id)
    simulator = watched.made
    row.update(_final_columns(scene, simulator, watched.initial))
    if has_reference(scene) and row['status'] == 'ok':
        row.update(_reference_errors(scene, simulator))
    return _finished(row, cpu_started, wall_started, simulator.time)


def _finished(row, cpu_started, wall_started, simulated):
    cpu = time.process_time() - cpu_started
    row.update(cpu_seconds=cpu, wall_seconds=time.perf_counter() - wall_started,
               cpu_per_simulated_second=cpu / simulated if simulated > 0.0 else None,
               finished=int(time.time() * 1000))
    return row


class _WatchedScene:
    """
    A scene that keeps the Simulator it makes, and the initial figures of its state.

    simulate_to_bag builds its simulator from the scene (Scene.simulator, the documented
    way); the row needs that simulator's final state without reading the bag back.
    """

    def __init__(self, scene):
        self._scene = scene
        self.made = None
        self.initial = None

    def __getattr__(self, name):
        return getattr(self._scene, name)

    def simulator(self, *args, **kwargs):
        simulator = self._scene.simulator(*args, **kwargs)
        self.made = simulator
        self.initial = _figures(simulator)
        return simulator


def _figures(simulator):
    """Return (T_rot, |L|, E, T) of the simulator's state now."""
    state, body = simulator.state, simulator.body
    momentum = state.angular_momentum
    rotational = 0.5 * float(state.angular_velocity(body) @ momentum)
    return (rotational, float(np.linalg.norm(momentum)), float(simulator.energy()),
            float(state.kinetic_energy(body)))


def _write_bag(run, scene, out):
    """Simulate into a hidden folder, then rename the whole bag into place; return its path."""
    relative = bag_path(run.run_id)
    final = Path(out) / relative
    staging = final.parent / f'{_PARTIAL}{run.run_id}-{uuid.uuid4().hex[:8]}'
    staging.mkdir(parents=True)
    try:
        try:
            simulate_to_bag(scene, staging / run.run_id, run.duration, substeps=run.substeps,
                            storage=run.bag_storage, flush_period=0.0)
        finally:
            _place(staging / run.run_id, final)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return relative


def _place(bag, final):
    """Rename a finished bag to its final folder, replacing one left by an earlier attempt."""
    if not bag.exists():
        return
    try:
        os.rename(bag, final)
    except OSError:
        # An earlier attempt of this run (a worker killed before its row reached the table)
        # left a whole bag: replaced by this one, whose row is the table's.
        old = final.parent / f'{_PARTIAL}old-{uuid.uuid4().hex[:8]}'
        os.rename(final, old)
        os.rename(bag, final)
        shutil.rmtree(old, ignore_errors=True)


def _vector(prefix, values, axes='xyz'):
    return {f'{prefix}_{axis}': float(value) for axis, value in zip(axes, values)}


def _run_columns(scene, run):
    """Return the columns of what was run: the scene's values after the spec's."""
    body, state = scene.body, scene.state
    inertia = body.inertia
    columns = {'scene': scene.name, 'integrator': scene.integrator, 'rate': scene.rate,
               'tolerance': scene.tolerance or 0.0, 'mass': body.mass,
               'imu_seed': int(scene.imu.seed)}
    for pair, (i, j) in zip(('xx', 'yy', 'zz', 'xy', 'xz', 'yz'),
                            ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))):
        columns[f'inertia_{pair}'] = float(inertia[i, j])
    columns.update(_vector('initial_orientation', state.quaternion, 'xyzw'))
    columns.update(_vector('initial_angular_velocity_body', state.angular_velocity_body(body)))
    columns.update(_vector('initial_position', state.position))
    columns.update(_vector('initial_velocity', state.velocity(body)))
    return columns


def _final_columns(scene, simulator, initial):
    """Return the final state, the drifts and the cost columns of a finished simulator."""
    state, body = simulator.state, simulator.body
    columns = {'final_time': simulator.time,
               'steps': int(simulator.substep_statistics()['steps']),
               'conserved': ','.join(conserved(scene))}
    columns.update(_vector('final_orientation', state.quaternion, 'xyzw'))
    columns.update(_vector('final_angular_velocity_body', state.angular_velocity_body(body)))
    columns.update(_vector('final_angular_momentum', state.angular_momentum))
    columns.update(_vector('final_position', state.position))
    columns.update(_vector('final_velocity', state.velocity(body)))
    rotational, momentum, energy, _ = _figures(simulator)
    rotational0, momentum0, energy0, kinetic0 = initial
    columns.update(
        rotational_energy_drift=_relative(rotational - rotational0, rotational0),
        angular_momentum_drift=_relative(momentum - momentum0, momentum0),
        energy_drift=_relative(energy - energy0, kinetic0))
    return columns


def _relative(change, scale):
    return change / scale if scale != 0.0 else change


def _reference_errors(scene, simulator):
    """Return the orientation and position errors against the exact flow (same ticks)."""
    # Loaded at the worker's start when the spec's scenes have a reference; a grid that
    # changes the effects may give one only here: then loaded (or compiled) once, now.
    ready([REFERENCE_INTEGRATOR])
    reference = scene.simulator(integrator=REFERENCE_INTEGRATOR, tolerance=0.0)
    reference.run(simulator.time, 1.0 / scene.rate)
    q, q_reference = simulator.state.quaternion, reference.state.quaternion
    # The angle of q_ref^-1 q, from the norm of their difference (accurate for small angles).
    chord = min(np.linalg.norm(q - q_reference), np.linalg.norm(q + q_reference))
    return {'orientation_error': 4.0 * float(np.arcsin(min(1.0, chord / 2.0))),
            'position_error': float(np.linalg.norm(simulator.state.position
                                                   - reference.state.position))}

"""
Compile the kernels ahead of use, and tell whether an integrator's are compiled already.

numba compiles a kernel the first time it runs and caches it beside the sources; a cached
kernel loads in a fraction of a second, a first compile takes seconds (measured on this
project's reference machine, 2 cores: :data:`COMPILE_SECONDS`).  The set-up (`make venv`,
`rigid-body-sim compile`) compiles every integrator so that no user waits; the node and
`simulate` ask :func:`is_compiled` first and say what they compile when they must.

The answer comes from a marker file per integrator, written after its kernels compiled,
named by the fingerprint of the core's sources (kernels/__init__.py): a changed source has
no marker, and its stale kernels were dropped at import.
"""

import time

import numpy as np

from .body import RigidBody
from .effects import create_effect
from .effects import EFFECTS
from .imu import Imu
from .imu import ImuModel
from .integrators import INTEGRATORS
from .kernels import compiled_marker
from .kernels.derived import derived_quantities
from .simulator import Simulator
from .state import State

__all__ = ['COMPILE_SECONDS', 'is_compiled', 'missing', 'warm_up', 'load_kernels',
           'compile_estimate']

COMPILE_SECONDS = {'buss': 57.0, 'buss_plain': 1.0, 'exact': 72.0, 'first_order': 16.0,
                   'rk4': 76.0, 'splitting': 31.0, 'splitting4': 3.0}
"""Seconds each integrator's kernels took to compile from an empty cache (run, controlled,
and what they share with the others for the first one), on the reference machine; a guide
for the announcements, which say 'about'."""

_SHARED = 'shared'


def is_compiled(name):
    """Return True if the kernels of integrator `name` are compiled for these sources."""
    return compiled_marker(name).exists() and compiled_marker(_SHARED).exists()


def missing(names=None):
    """Return the integrators among `names` (default: all) whose kernels are not compiled."""
    return [name for name in (sorted(INTEGRATORS) if names is None else names)
            if not is_compiled(name)]


def compile_estimate(names):
    """Return the seconds compiling the kernels of `names` takes, roughly (0 if compiled)."""
    return sum(COMPILE_SECONDS.get(name, 10.0) for name in missing(names))


def _mark(name):
    marker = compiled_marker(name)
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.touch()
    except OSError:
        pass  # a read-only installation: its installer compiled it, or every run will


def _shared():
    """Compile what every integrator shares: the effects, the model, the IMU, the faces."""
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
    _mark(_SHARED)


def warm_up(name):
    """
    Compile (or load) the kernels of integrator `name` and mark them compiled.

    Returns the seconds it took.  One step at a fixed step and one under error control, of
    a body under every effect: every kernel of the integrator has the one signature, so
    this compiles all it will ever run.
    """
    started = time.monotonic()
    if not compiled_marker(_SHARED).exists():
        _shared()
    load_kernels(name)
    _mark(name)
    return time.monotonic() - started


def load_kernels(name):
    """
    Load the kernels of integrator `name` into this process (compiling what is not cached).

    One step at a fixed step and one under error control, of a torque-free box: the kernels
    take every scene's effects through one signature, so these are the ones a scene runs.
    """
    body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
    state = State.from_velocity(body, angular_velocity_body=(0.1, 2.0, 0.1))
    for tolerance in (None, 1e-6):
        simulator = Simulator(body, state, integrator=name, tolerance=tolerance)
        simulator.step(1e-3)

"""The simulator: a body, its state, an integrator chosen by name, and what pushes it.

Data flow: body + state + effects -> Simulator -> (node, recorder, report).  The simulator
owns the only mutable thing, the current state and time; bodies, states and integrators are
values and pure functions.
"""

import math

import numpy as np

from .integrators import FAST_KERNELS
from .integrators import get_integrator
from .state import State

__all__ = ['Simulator']

_FRAMES = ('world', 'body')
# Steps per kernel call when a progress callback wants to hear about a long run.
_PROGRESS_CHUNK = 20000


def _checked_vector(value, name):
    array = np.zeros(3) if value is None else np.array(value, dtype=float).reshape(-1)
    if array.shape != (3,):
        raise ValueError(f'{name} must be a 3-vector; got shape {np.shape(value)}')
    if not np.all(np.isfinite(array)):
        raise ValueError(f'{name} must be finite; got {array.tolist()}')
    return array


def _checked_positive(value, name):
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a number of seconds; got {value!r}') from None
    if not math.isfinite(number) or number <= 0.0:
        raise ValueError(f'{name} must be finite and > 0 s; got {value!r}')
    return number


class Simulator:
    """Advance a rigid body in time with a named integrator.

    Parameters
    ----------
    body : RigidBody
    state : State
        Initial state (world frame) at time 0.
    integrator : str
        A name in :data:`INTEGRATORS` (default ``'buss'``).
    effects : sequence, optional
        Objects with ``wrench(body, state, time) -> (force, torque)`` (world frame, N and
        N m about the COM), optionally ``potential_energy(body, state)`` (J) and
        ``momentum_dependent`` (bool).  Only these are evaluated: with none, and no held
        wrench, the motion is torque-free and no force code runs.
    fast : bool
        Use the integrator's compiled kernel when the wrench is a held one (default True).
        The kernel equals the readable step to round-off.
    """

    def __init__(self, body, state, integrator='buss', effects=(), fast=True):
        if not isinstance(state, State):
            raise ValueError(f'state must be a State; got {type(state).__name__}')
        self._body = body
        self._state = state
        self._time = 0.0
        self._time_compensation = 0.0
        self._effects = tuple(effects)
        self._fast = bool(fast)
        self.integrator = integrator
        self.set_wrench()

    # -- configuration

    @property
    def body(self):
        """The simulated RigidBody."""
        return self._body

    @property
    def effects(self):
        """The effects evaluated every step (a tuple)."""
        return self._effects

    @property
    def integrator(self):
        """Name of the integrator in use; settable, an unknown name is a ValueError."""
        return self._integrator_name

    @integrator.setter
    def integrator(self, name):
        self._step = get_integrator(name)
        self._integrator_name = name
        self._kernel = FAST_KERNELS.get(name) if self._fast else None

    def set_wrench(self, force=None, torque=None, frame='world'):
        """Hold a force through the COM (N) and a torque about it (N m) until changed.

        frame='world': fixed in the world.  frame='body': fixed in the body, so it turns with
        it.  Each call replaces the whole held wrench (what is not given is zero);
        ``set_wrench()`` removes it.
        """
        if frame not in _FRAMES:
            raise ValueError(f'frame must be one of {", ".join(_FRAMES)}; got {frame!r}')
        force = _checked_vector(force, 'force')
        torque = _checked_vector(torque, 'torque')
        zero = np.zeros(3)
        if frame == 'world':
            self._held = (force, torque, zero, zero.copy())
        else:
            self._held = (zero, zero.copy(), force, torque)
        self._held_active = bool(np.any(force) or np.any(torque))

    def hold_wrench(self, force_world=None, torque_world=None, force_body=None,
                    torque_body=None):
        """Hold world-fixed and body-fixed parts of the wrench at once (N, N m).

        The total held wrench is force_world + R force_body through the COM and
        torque_world + R torque_body about it; the body parts turn with the body during the
        steps.  What is not given is zero.  Use it when inputs in both frames are active.
        """
        parts = (_checked_vector(force_world, 'force_world'),
                 _checked_vector(torque_world, 'torque_world'),
                 _checked_vector(force_body, 'force_body'),
                 _checked_vector(torque_body, 'torque_body'))
        self._held = parts
        self._held_active = any(bool(np.any(part)) for part in parts)

    @property
    def held_wrench(self):
        """The held wrench: (force_world, torque_world, force_body, torque_body)."""
        return tuple(a.copy() for a in self._held)

    # -- state

    @property
    def state(self):
        """Current State (world frame)."""
        return self._state

    @state.setter
    def state(self, state):
        if not isinstance(state, State):
            raise ValueError(f'state must be a State; got {type(state).__name__}')
        self._state = state

    @property
    def time(self):
        """Simulated time in s since the start."""
        return self._time

    def reset(self, state, time=0.0):
        """Set the state and the time (s)."""
        self.state = state
        self._time = float(time)
        self._time_compensation = 0.0

    def energy(self):
        """Return the total energy in J: kinetic plus the effects' potential energies."""
        energy = self._state.kinetic_energy(self._body)
        for effect in self._effects:
            potential = getattr(effect, 'potential_energy', None)
            if potential is not None:
                energy += potential(self._body, self._state)
        return energy

    def wrench_function(self):
        """Return the total wrench as ``wrench(state, time)``, or None when nothing pushes."""
        if not self._effects and not self._held_active:
            return None
        force_world, torque_world, force_body, torque_body = self._held
        held = self._held_active
        body = self._body
        effects = self._effects

        def wrench(state, time):
            force = force_world + state.rotation @ force_body if held else np.zeros(3)
            torque = torque_world + state.rotation @ torque_body if held else np.zeros(3)
            for effect in effects:
                effect_force, effect_torque = effect.wrench(body, state, time)
                force = force + effect_force
                torque = torque + effect_torque
            return force, torque

        wrench.momentum_dependent = any(
            getattr(effect, 'momentum_dependent', False) for effect in effects)
        return wrench

    # -- time stepping

    def step(self, dt):
        """Advance one step of dt s; return the new State."""
        self._advance(1, _checked_positive(dt, 'dt'))
        return self._state

    def run(self, duration, dt, progress=None):
        """Advance by `duration` s in steps of dt s; return the final State.

        If dt does not divide the duration, a last shorter step ends exactly at it.
        `progress`, if given, is called with the fraction done (0..1) during long runs.
        """
        dt = _checked_positive(dt, 'dt')
        try:
            duration = float(duration)
        except (TypeError, ValueError):
            raise ValueError(f'duration must be a number of seconds; got {duration!r}') from None
        if not math.isfinite(duration) or duration < 0.0:
            raise ValueError(f'duration must be finite and >= 0 s; got {duration!r}')
        steps = int(round(duration / dt))
        if abs(steps * dt - duration) > 1e-9 * dt:
            steps = int(math.floor(duration / dt))
        remainder = duration - steps * dt
        done = 0
        chunk = steps if progress is None else _PROGRESS_CHUNK
        while done < steps:
            count = min(chunk, steps - done)
            self._advance(count, dt)
            done += count
            if progress is not None:
                progress(done / steps)
        if remainder > 1e-9 * dt:
            self._advance(1, remainder)
        if progress is not None:
            progress(1.0)
        return self._state

    def _advance(self, steps, dt):
        if self._kernel is not None and not self._effects:
            self._advance_fast(steps, dt)
        else:
            wrench = self.wrench_function()
            state, time = self._state, self._time
            for k in range(steps):
                state = self._step(self._body, state, time + k * dt, dt, wrench)
            self._state = state
        self._add_time(steps * dt)

    def _advance_fast(self, steps, dt):
        state = self._state
        quaternion = np.array(state.quaternion)
        position = np.array(state.position)
        linear_momentum = np.array(state.linear_momentum)
        angular_momentum = np.array(state.angular_momentum)
        force_world, torque_world, force_body, torque_body = self._held
        self._kernel(quaternion, position, linear_momentum, angular_momentum,
                     self._body.inertia, self._body.inertia_inverse, self._body.mass,
                     dt, steps, force_world, torque_world, force_body, torque_body)
        self._state = State._from_arrays(quaternion, position, linear_momentum,
                                         angular_momentum)

    def _add_time(self, increment):
        # Kahan summation: keeps the clock exact to round-off over millions of ticks, where a
        # plain running sum would drift by ~steps * eps * time.
        y = increment - self._time_compensation
        total = self._time + y
        self._time_compensation = (total - self._time) - y
        self._time = total

"""
The simulator: a body, its state, an integrator chosen by name, and what pushes it.

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
    """
    Advance a rigid body in time with a named integrator.

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
        ``momentum_dependent`` (bool); see :mod:`.effects.registry` for the whole protocol:
        a ``constant_force(body)`` (uniform gravity) is folded into the held wrench, so the
        compiled kernel still runs; a ``flow(body, state, dt)`` (dissipation) is composed
        with each step as flow(dt/2), step(dt), flow(dt/2); ``constrain(body)`` (a pivot)
        makes the simulator advance the constrained system and show its physical state.
        Only these are evaluated: with none, and no held wrench, the motion is torque-free
        and no force code runs.
    fast : bool
        Use the integrator's compiled kernel when the wrench is a held one (default True).
        The kernel equals the readable step to round-off.

    With a constraint (a pivot), :attr:`state` is always the physical state (COM position,
    linear momentum, angular momentum about the COM), and a state that is set is projected
    onto the constraint first (rotation and angular velocity kept).

    """

    def __init__(self, body, state, integrator='buss', effects=(), fast=True):
        if not isinstance(state, State):
            raise ValueError(f'state must be a State; got {type(state).__name__}')
        self._body = body
        self._time = 0.0
        self._time_compensation = 0.0
        self._effects = tuple(effects)
        self._sort_effects()
        self.state = state
        self._fast = bool(fast)
        self.integrator = integrator
        self.set_wrench()

    def _sort_effects(self):
        """Sort the effects by what they do, once, so that a step runs only what is there."""
        constant_force = np.zeros(3)
        wrenches, flows, constraints = [], [], []
        for effect in self._effects:
            if getattr(effect, 'constant_force', None) is not None:
                constant_force = constant_force + _checked_vector(
                    effect.constant_force(self._body), 'constant_force')
            elif getattr(effect, 'wrench', None) is not None:
                wrenches.append(effect)
            if getattr(effect, 'flow', None) is not None:
                flows.append(effect)
            if getattr(effect, 'constrain', None) is not None:
                constraints.append(effect)
        if len(constraints) > 1:
            raise ValueError(f'at most one constraint effect (pivot); got {len(constraints)}')
        self._constant_force = constant_force
        self._pushing_effects = tuple(wrenches)
        self._flows = tuple(flows)
        self._constraint = constraints[0].constrain(self._body) if constraints else None
        # The body the integrator advances: about the pivot under a pivot constraint.
        self._integrated_body = (self._body if self._constraint is None
                                 else self._constraint.body)

    # -- configuration

    @property
    def body(self):
        """Get the simulated RigidBody."""
        return self._body

    @property
    def effects(self):
        """Get the effects evaluated every step (a tuple)."""
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
        """
        Hold a force through the COM (N) and a torque about it (N m) until changed.

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
        """
        Hold world-fixed and body-fixed parts of the wrench at once (N, N m).

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
        """Get the held wrench: (force_world, torque_world, force_body, torque_body)."""
        return tuple(a.copy() for a in self._held)

    # -- state

    @property
    def state(self):
        """Get the current State (world frame)."""
        return self._state

    @state.setter
    def state(self, state):
        if not isinstance(state, State):
            raise ValueError(f'state must be a State; got {type(state).__name__}')
        if self._constraint is None:
            self._integrated_state = state
        else:
            state = self._constraint.project(state)
            self._integrated_state = self._constraint.reduce(state)
        self._state = state

    @property
    def time(self):
        """Get the simulated time in s since the start."""
        return self._time

    def reset(self, state, time=0.0):
        """Set the state and the time (s, finite)."""
        try:
            time = float(time)
        except (TypeError, ValueError):
            raise ValueError(f'time must be a number of seconds; got {time!r}') from None
        if not math.isfinite(time):
            raise ValueError(f'time must be finite; got {time!r}')
        self.state = state
        self._time = time
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
        """
        Return the total wrench as ``wrench(state, time)``, or None when nothing pushes.

        It acts on physical states: the held wrench, the effects' constant forces and their
        wrenches (force through the COM, torque about it; world frame).  A constraint's
        reaction is not part of it.
        """
        held = self._held_active or bool(np.any(self._constant_force))
        effects = self._pushing_effects
        if not effects and not held:
            return None
        force_world, torque_world, force_body, torque_body = self._held
        force_world = force_world + self._constant_force
        body = self._body

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
        # Held and constant parts depend on the rotation alone (a pivot can skip expanding).
        wrench.rotation_only = not effects
        return wrench

    # -- time stepping

    def step(self, dt):
        """Advance one step of dt s; return the new State."""
        self._advance(1, _checked_positive(dt, 'dt'))
        return self._state

    def run(self, duration, dt, progress=None):
        """
        Advance by `duration` s in steps of dt s; return the final State.

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
        constraint, flows = self._constraint, self._flows
        state = self._integrated_state
        fast = self._runs_fast()
        if fast and not flows:
            state = self._kernel_steps(state, steps, dt)
        else:
            if fast:
                step, wrench = self._kernel_step, None
            else:
                step, wrench = self._step, self.wrench_function()
                if constraint is not None:
                    wrench = constraint.wrench(wrench)
            body, time, half = self._integrated_body, self._time, 0.5 * dt
            for k in range(steps):
                for effect in flows:
                    state = effect.flow(body, state, half)
                state = step(body, state, time + k * dt, dt, wrench)
                for effect in reversed(flows):
                    state = effect.flow(body, state, half)
        self._integrated_state = state
        self._state = state if constraint is None else constraint.expand(state)
        self._add_time(steps * dt)

    def _runs_fast(self):
        """
        Return True when the compiled kernel can take the steps: a held wrench only.

        Constant forces (gravity) are held too, except under a constraint, where a force at
        the COM has a torque about the pivot that turns with the body.  Flows do not stop
        it: they are composed with single kernel steps.
        """
        if self._kernel is None or self._pushing_effects:
            return False
        if self._constraint is None:
            return True
        force_world, _, force_body, _ = self._held
        return not (np.any(force_world) or np.any(force_body) or np.any(self._constant_force))

    def _kernel_step(self, body, state, time, dt, wrench):
        # The step-function form of one kernel step; the held wrench is the kernel's own.
        return self._kernel_steps(state, 1, dt)

    def _kernel_steps(self, state, steps, dt):
        body = self._integrated_body
        quaternion = np.array(state.quaternion)
        position = np.array(state.position)
        linear_momentum = np.array(state.linear_momentum)
        angular_momentum = np.array(state.angular_momentum)
        force_world, torque_world, force_body, torque_body = self._held
        self._kernel(quaternion, position, linear_momentum, angular_momentum,
                     body.inertia, body.inertia_inverse, body.mass,
                     dt, steps, force_world + self._constant_force, torque_world, force_body,
                     torque_body)
        return State._from_arrays(quaternion, position, linear_momentum, angular_momentum)

    def _add_time(self, increment):
        # Kahan summation: keeps the clock exact to round-off over millions of ticks, where a
        # plain running sum would drift by ~steps * eps * time.
        y = increment - self._time_compensation
        total = self._time + y
        self._time_compensation = (total - self._time) - y
        self._time = total

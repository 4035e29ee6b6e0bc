"""
The simulator: a body, its state, an integrator chosen by name, and what pushes it.

Data flow: body + state + effects -> Simulator -> (node, recorder, report).  The simulator
owns the only mutable thing, the current state and time; bodies, states and integrators are
values and pure functions.
"""

from __future__ import annotations

from collections.abc import Callable
from collections.abc import Iterable
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from . import error_control
from .body import RigidBody
from .effects.registry import Effect
from .integrators import get_integrator
from .integrators import Integrator
from .kernels import interpreting
from .kernels.interpreted import ARITHMETIC_ERRORS
from .kernels.layout import body_values
from .kernels.layout import STATE_SIZE
from .kernels.model import applied_wrench_of
from .kernels.model import HELD_FORCE_BODY
from .kernels.model import HELD_FORCE_WORLD
from .kernels.model import HELD_TORQUE_BODY
from .kernels.model import HELD_TORQUE_WORLD
from .kernels.model import new_model
from .kernels.model_table import move_model_arrays
from .stability import stiffness_problem
from .state import State

__all__ = ['Simulator', 'DivergedError', 'unresolved_rotation', 'RESOLVED_ROTATION', 'Wrench']

RESOLVED_ROTATION = 0.5
"""The largest rotation (rad) per integrator step that the steps resolve: beyond it every
method's error per step is O(1) (the Taylor and Magnus series the methods truncate are in
|omega| h), so the motion is not followed, whatever the method keeps conserved."""

MAX_STEPS_PER_RUN = 10 ** 12
"""The most outer steps one :meth:`Simulator.run` takes (duration / dt beyond it is refused:
at a compiled step's cost it would run for days)."""

_FRAMES = ('world', 'body')
# Steps per kernel call when a progress callback wants to hear about a long run.
_PROGRESS_CHUNK = 20000

Wrench = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]
"""A wrench as (force N, torque N m), world frame, each an array (3,)."""

# What takes the steps (Simulator.path).
COMPILED = 'compiled'  # the integrator's kernel, every effect compiled (kernels/model.py)
INTERPRETED = 'interpreted'  # the kernels' own source, interpreted (kernels/interpreted.py)


class DivergedError(ValueError):
    """
    The state turned non-finite in a step: the Simulator kept the last finite state.

    ``time`` is the simulated time of that state (s); the message says what acted (the
    integrator, the step, the effects and the held wrench) and what to change.
    """

    def __init__(self, message: str, time: float) -> None:
        super().__init__(message)
        self.time = time


def _checked_vector(value: Any, name: str) -> npt.NDArray[np.float64]:
    array = np.zeros(3) if value is None else np.array(value, dtype=float).reshape(-1)
    if array.shape != (3,):
        raise ValueError(f'{name} must be a 3-vector; got shape {np.shape(value)}')
    if not np.all(np.isfinite(array)):
        raise ValueError(f'{name} must be finite; got {array.tolist()}')
    return array


def checked_positive(value: Any, name: str) -> float:
    """Return `value` as a float of seconds, finite and > 0, or raise ValueError naming it."""
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
        Effects (:mod:`.effects.registry` gives the protocol): their compiled wrench terms
        act through every integrator's kicks or stages, their flows are composed with each
        step as flow(dt/2), step(dt), flow(dt/2), and a constraint (a pivot) makes the
        simulator advance the constrained system and show its physical state.  Only these
        are evaluated: with none, and no held wrench, the motion is torque-free and no force
        code runs.
    tolerance : float, optional
        Error control (rad per simulated second): every outer step (``step(dt)``, and each
        ``dt`` of ``run(duration, dt)``) is split into as many equal substeps as keep the
        orientation error the integrator adds per simulated second at or below it, by a
        step-doubling estimate with the integrator's order (:mod:`.error_control`).  None
        or 0: off, each outer step is `substeps` fixed steps.  Settable.
    substeps : int
        Steps per outer step without a tolerance (default 1: a step of dt is one
        integrator step); with one, the least number of substeps.  Settable.

    With a constraint (a pivot), :attr:`state` is always the physical state (COM position,
    linear momentum, angular momentum about the COM), and a state that is set is projected
    onto the constraint first (rotation and angular velocity kept).

    The integrated state lives in one packed array (kernels/layout.py), advanced in place by
    the compiled kernel between calls; the immutable :class:`State` is built from it when
    :attr:`state` is read (step() and run() return it), so a step costs one kernel call and
    one State.  The body, the held wrench and the effects are one compiled
    :class:`~.kernels.model.Model`, built once; the held wrench is written into it in place.

    """

    def __init__(self, body: RigidBody, state: State, integrator: str = 'buss',
                 effects: Iterable[Any] = (), tolerance: float | None = None,
                 substeps: int = 1) -> None:
        if not isinstance(state, State):
            raise ValueError(f'state must be a State; got {type(state).__name__}')
        self._body = body
        self._time = 0.0
        self._time_compensation = 0.0
        self._effects = tuple(effects)
        # The held wrench, rows kernels.model.HELD_*: shared with the compiled model.
        self._held = np.zeros((4, 3))
        self._interpreted = interpreting()
        self._sort_effects()
        # The error controller's state (error_control.new_control).
        self._control = error_control.new_control(2)
        self._tolerance: float | None = None
        # The integrated state, packed [q, x, p, L], and the States made of it when read.
        self._values = np.zeros(STATE_SIZE)
        self._state: State | None = None
        self._integrated: State | None = None
        self.state = state
        self._interpreted = interpreting()
        # The last finite packed state (restored if a step turns the state non-finite), and
        # the configuration whose steps were last checked against the stiff effects.
        self._checkpoint = np.zeros(STATE_SIZE)
        self._checked: tuple[float, int, Integrator, float | None] | None = None
        self.integrator = integrator
        self.substeps = substeps
        self.tolerance = tolerance

    def _sort_effects(self) -> None:
        """Sort the effects by what they do and build the compiled model, once."""
        wrenches, flows, constraints = [], [], []
        for effect in self._effects:
            if getattr(effect, 'compiled_wrench', None) is not None:
                wrenches.append(effect)
            elif callable(getattr(effect, 'wrench', None)) and not isinstance(effect, Effect):
                raise ValueError(
                    f'effect {type(effect).__name__} has a Python wrench() but no '
                    'compiled_wrench: write the wrench as a compiled term (decorate it with '
                    'rigid_body_sim.physics.kernels.model.wrench_term, give its parameters '
                    'with wrench_parameters(body); see physics/effects/registry.py)')
            if getattr(effect, 'compiled_flow', None) is not None:
                flows.append(effect)
            if getattr(effect, 'constrain', None) is not None:
                constraints.append(effect)
        if len(constraints) > 1:
            raise ValueError(f'at most one constraint effect (pivot); got {len(constraints)}')
        self._pushing_effects = tuple(wrenches)
        self._flows = tuple(flows)
        self._constraint = constraints[0].constrain(self._body) if constraints else None
        # The body the integrator advances: about the pivot under a pivot constraint.
        self._integrated_body = (self._body if self._constraint is None
                                 else self._constraint.body)
        body = self._integrated_body
        constraint = self._constraint
        self._model_arguments: dict[str, Any] = {
            'body': body_values(body.inertia, body.inertia_inverse, body.mass),
            'held': self._held,
            'terms': [(effect.compiled_wrench, effect.wrench_parameters(self._body))
                      for effect in wrenches],
            'flows': [(effect.compiled_flow, effect.flow_parameters(body)) for effect in flows],
            'constraint': None if constraint is None else (
                constraint.expand_function, constraint.transmit_function,
                constraint.parameters),
            'momentum_dependent': any(effect.momentum_dependent for effect in wrenches),
            'reads_state': any(effect.reads_state for effect in wrenches)}
        self._model = new_model(**self._model_arguments, interpreted=self._interpreted)

    # -- configuration

    @property
    def body(self) -> RigidBody:
        """Get the simulated RigidBody."""
        return self._body

    @property
    def effects(self) -> tuple[Any, ...]:
        """Get the effects evaluated every step (a tuple)."""
        return self._effects

    @property
    def path(self) -> str:
        """
        Get what takes the steps: 'compiled' (the kernels) or 'interpreted'.

        'interpreted': the kernels' source run as Python (:attr:`interpreted`).
        """
        return INTERPRETED if self._interpreted else COMPILED

    @property
    def interpreted(self) -> bool:
        """
        Whether the kernels run as their Python source instead of compiled (settable).

        The same steps, orders of magnitude slower, with nothing to compile
        (kernels/interpreted.py): what a process that must not wait runs while the kernels
        compile elsewhere.  Defaults to
        kernels.interpreting() when the Simulator is made; set it False once they are
        compiled, and the next step loads them (the state is kept).
        """
        return self._interpreted

    @interpreted.setter
    def interpreted(self, interpreted: bool) -> None:
        interpreted = bool(interpreted)
        if interpreted != self._interpreted:
            self._interpreted = interpreted
            self._model = new_model(**self._model_arguments, interpreted=interpreted)
            self._run: Callable[..., int] | None = None

    @property
    def integrator(self) -> str:
        """Name of the integrator in use; settable, an unknown name is a ValueError."""
        return self._integrator.name

    @integrator.setter
    def integrator(self, name: str) -> None:
        self._integrator = get_integrator(name)
        # Its compiled run kernel, fetched on the first compiled step (compiled or loaded).
        self._run = None
        self._set_order()
        self._plan()

    def _set_order(self) -> None:
        """
        Give the controller the order of the steps as taken.

        The integrator's (its order under a momentum-dependent wrench if an effect is one),
        at most 2 with a flow (flow(h/2) step(h) flow(h/2) is a Strang composition: second
        order).
        """
        integrator = self._integrator
        order = (integrator.momentum_dependent_order
                 if self._model_arguments['momentum_dependent'] else integrator.order)
        if self._flows:
            order = min(order, 2)
        error_control.set_order(self._control, order)

    @property
    def tolerance(self) -> float | None:
        """
        Error control: rad per simulated second, or None (off: fixed `substeps`).

        Settable at any time (0 or None turns it off); the state stays as it is, and the
        next outer step is estimated at once.  ValueError unless finite and >= 0.
        """
        return self._tolerance

    @tolerance.setter
    def tolerance(self, tolerance: float | None) -> None:
        if tolerance is not None:
            try:
                tolerance = float(tolerance)
            except (TypeError, ValueError):
                raise ValueError(f'tolerance must be a number of rad/s; got {tolerance!r}') \
                    from None
            if not math.isfinite(tolerance) or tolerance < 0.0:
                raise ValueError(f'tolerance must be finite and >= 0 rad/s (0: off); got '
                                 f'{tolerance!r}')
            if tolerance == 0.0:
                tolerance = None
        self._tolerance = tolerance
        if tolerance is not None:
            error_control.set_tolerance(self._control, tolerance)

    @property
    def substeps(self) -> int:
        """
        Get the steps per outer step without a tolerance, the least with one (int >= 1).

        Settable at any time; ValueError for anything but a whole number >= 1.
        """
        return self._substeps

    @substeps.setter
    def substeps(self, substeps: int) -> None:
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) \
                or substeps < 1:
            raise ValueError(f'substeps must be a whole number >= 1; got {substeps!r}')
        self._substeps = int(substeps)
        error_control.set_bounds(self._control, self._substeps)
        self._control_floor = self._substeps

    def substep_statistics(self, reset: bool = False) -> dict[str, Any]:
        """
        Return the substeps and the error estimates since the last reset, as a dict.

        Keys: tolerance (rad/s, None when off); substeps (of the last outer step),
        substeps_min, substeps_max, substeps_mean; error_rate (the last estimate, rad/s;
        nan when off or before the first) and error_rate_max (the largest in the period);
        steps (integrator steps taken, the estimates' extra steps included), ticks (outer
        steps), estimates, rejected (outer steps taken again with more substeps).  Without
        a tolerance only tolerance and the substeps are meaningful (the fixed count).
        reset=True starts a new period after reading.
        """
        figures = error_control.statistics(self._control)
        if self._tolerance is None:
            figures.update(substeps=self._substeps, substeps_min=self._substeps,
                           substeps_max=self._substeps, substeps_mean=float(self._substeps),
                           error_rate=math.nan, error_rate_max=math.nan)
        figures['tolerance'] = self._tolerance
        if reset:
            error_control.reset_statistics(self._control)
        return figures

    def set_wrench(self, force: npt.ArrayLike | None = None, torque: npt.ArrayLike | None = None,
                   frame: str = 'world') -> None:
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
        if frame == 'world':
            self._hold(force, torque, None, None)
        else:
            self._hold(None, None, force, torque)

    def hold_wrench(self, force_world: npt.ArrayLike | None = None,
                    torque_world: npt.ArrayLike | None = None,
                    force_body: npt.ArrayLike | None = None,
                    torque_body: npt.ArrayLike | None = None) -> None:
        """
        Hold world-fixed and body-fixed parts of the wrench at once (N, N m).

        The total held wrench is force_world + R force_body through the COM and
        torque_world + R torque_body about it; the body parts turn with the body during the
        steps.  What is not given is zero.  Use it when inputs in both frames are active.
        """
        self._hold(_checked_vector(force_world, 'force_world'),
                   _checked_vector(torque_world, 'torque_world'),
                   _checked_vector(force_body, 'force_body'),
                   _checked_vector(torque_body, 'torque_body'))

    def _hold(self, force_world: npt.NDArray[np.float64] | None,
              torque_world: npt.NDArray[np.float64] | None,
              force_body: npt.NDArray[np.float64] | None,
              torque_body: npt.NDArray[np.float64] | None) -> None:
        # Written in place: the compiled model holds this very array.
        for row, part in ((HELD_FORCE_WORLD, force_world), (HELD_TORQUE_WORLD, torque_world),
                          (HELD_FORCE_BODY, force_body), (HELD_TORQUE_BODY, torque_body)):
            self._held[row] = 0.0 if part is None else part
        self._plan()

    @property
    def held_wrench(self) -> tuple[npt.NDArray[np.float64], ...]:
        """Get the held wrench: (force_world, torque_world, force_body, torque_body)."""
        return tuple(self._held[row].copy() for row in range(4))

    # -- state

    @property
    def state(self) -> State:
        """Get the current State (world frame)."""
        state = self._state
        if state is None:
            if self._constraint is None:
                state = self._integrated_state()
            else:
                state = State._from_values(self._constraint.expand_values(self._values))
            self._state = state
        return state

    @state.setter
    def state(self, state: State) -> None:
        if not isinstance(state, State):
            raise ValueError(f'state must be a State; got {type(state).__name__}')
        if self._constraint is None:
            integrated = state
        else:
            state = self._constraint.project(state)
            integrated = self._constraint.reduce(state)
        self._store(integrated)
        self._state = state
        # A new state: estimate at the next outer step, from scratch.
        error_control.changed(self._control, forget=True)

    def _store(self, integrated: State) -> None:
        """Make `integrated` (a State of the integrated system) the current one."""
        np.concatenate(integrated._fields(), out=self._values)
        self._integrated = integrated
        self._state = None

    def _integrated_state(self) -> State:
        """Return the State of the integrated system (the pivot system under a pivot)."""
        if self._integrated is None:
            self._integrated = State._from_values(self._values)
        return self._integrated

    @property
    def time(self) -> float:
        """Get the simulated time in s since the start."""
        return self._time

    def reset(self, state: State, time: float = 0.0) -> None:
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

    def energy(self) -> float:
        """Return the total energy in J: kinetic plus the effects' potential energies."""
        state = self.state
        energy = state.kinetic_energy(self._body)
        for effect in self._effects:
            potential = getattr(effect, 'potential_energy', None)
            if potential is not None:
                energy += potential(self._body, state)
        return energy

    def applied_wrench(self) -> Wrench:
        """
        Return (force N, torque N m) applied now: held plus effects, about the COM (world).

        A constraint's reaction is not in it (the IMU's accelerations start from this).
        """
        values = np.concatenate(self.state._fields())
        applied = applied_wrench_of.source if self._interpreted else applied_wrench_of
        wrench = applied(values, self._time, self._model)
        return np.array(wrench[:3]), np.array(wrench[3:])

    def wrench_function(self) -> Callable[[State, float], Wrench] | None:
        """
        Return the total wrench as ``wrench(state, time)``, or None when nothing pushes.

        It acts on physical states: the held wrench and the effects' wrenches (force through
        the COM, torque about it; world frame), each effect's compiled term called from
        Python (Effect.wrench).  A constraint's reaction is not part of it.
        """
        held = bool(np.any(self._held))
        effects = self._pushing_effects
        if not effects and not held:
            return None
        force_world, torque_world, force_body, torque_body = self.held_wrench
        body = self._body

        def wrench(state: State, time: float) -> Wrench:
            force = force_world + state.rotation @ force_body
            torque = torque_world + state.rotation @ torque_body
            for effect in effects:
                effect_force, effect_torque = effect.wrench(body, state, time)
                force = force + effect_force
                torque = torque + effect_torque
            return force, torque

        wrench.momentum_dependent = any(
            effect.momentum_dependent for effect in effects)
        return wrench

    # -- time stepping

    def step(self, dt: float) -> State:
        """
        Advance one outer step of dt s; return the new State.

        One integrator step, or `substeps` equal ones; with a tolerance, as many as the
        error control chooses (at least `substeps`).
        """
        # A finite positive float needs no conversion (the node passes one every tick).
        if dt.__class__ is not float or not 0.0 < dt < math.inf:
            dt = checked_positive(dt, 'dt')
        if self._checked != (dt, self._substeps, self._integrator, self._tolerance):
            self._check_stiffness(dt)
        if self._tolerance is not None:
            self._controlled(dt, 1)
        elif self._substeps == 1:
            self._advance(1, dt)
        else:
            self._advance(self._substeps, dt / self._substeps, dt)
        return self.state

    def run(self, duration: float, dt: float,
            progress: Callable[[float], Any] | None = None) -> State:
        """
        Advance by `duration` s in outer steps of dt s; return the final State.

        Each outer step is as :meth:`step` takes it (one step, `substeps` steps, or under
        error control as many as needed).  If dt does not divide the duration, a last
        shorter outer step ends exactly at it (a duration shorter than dt is one such step).
        `progress`, if given, is called with the fraction done (0..1) during long runs.
        ValueError for a duration that is not finite and >= 0, and for more than
        :data:`MAX_STEPS_PER_RUN` outer steps.
        """
        dt = checked_positive(dt, 'dt')
        try:
            duration = float(duration)
        except (TypeError, ValueError):
            raise ValueError(f'duration must be a number of seconds; got {duration!r}') from None
        if not math.isfinite(duration) or duration < 0.0:
            raise ValueError(f'duration must be finite and >= 0 s; got {duration!r}')
        ratio = duration / dt
        if not ratio <= MAX_STEPS_PER_RUN:
            raise ValueError(f'duration / dt = {ratio:.3g} steps: more than the '
                             f'{MAX_STEPS_PER_RUN:.0e} one run takes; raise dt or shorten it')
        steps = int(round(ratio))
        if abs(steps * dt - duration) > 1e-9 * dt:
            steps = int(math.floor(ratio))
        remainder = duration - steps * dt
        self._check_stiffness(dt)
        done = 0
        controlled = self._tolerance is not None
        per_step = 1 if controlled else self._substeps
        chunk = steps if progress is None else max(1, _PROGRESS_CHUNK // per_step)
        while done < steps:
            count = min(chunk, steps - done)
            if controlled:
                self._controlled(dt, count)
            else:
                self._advance(count * per_step, dt / per_step, count * dt)
            done += count
            if progress is not None:
                progress(done / steps)
        # A remainder of round-off (duration a multiple of dt to 1e-9) is not a step; a
        # duration shorter than dt is one.
        if remainder > 1e-9 * dt or (steps == 0 and remainder > 0.0):
            if controlled:
                self._controlled(remainder, 1)
            else:
                self._advance(per_step, remainder / per_step, remainder)
        if progress is not None:
            progress(1.0)
        return self.state

    # -- stepped from outside: a World advances many simulators' arrays in one kernel call

    def kernel_arguments(self) -> tuple[npt.NDArray[np.float64], Any, npt.NDArray[np.float64]]:
        """
        Return (packed state, compiled model, control array): what its kernels advance.

        The arrays themselves, not copies: a :class:`~.world.World` advances them in place
        by this simulator's own run kernel or controller (:meth:`move_arrays`), then tells it
        with :meth:`advanced_to`.  Packed state (13,): kernels/layout.py; the model holds the
        body, the held wrench and the effects; the control array error_control's.
        """
        return self._values, self._model, self._control

    def move_arrays(self, values: npt.NDArray[np.float64],
                    control: npt.NDArray[np.float64]) -> None:
        """
        Keep the packed state and the control array in `values` and `control` from now on.

        Their contents are copied in first: nothing changes but where they live.  A World
        gives each body a row of its own two arrays, so that its kernel takes every body's
        state from one block of memory; shapes (13,) and error_control's CONTROL_SIZE,
        float64, C-contiguous.
        """
        values[:] = self._values
        control[:] = self._control
        self._values = values
        self._control = control

    def move_model_arrays(self, floats: npt.NDArray[np.float64],
                          integers: npt.NDArray[np.int64]) -> None:
        """
        Keep the compiled model's arrays in `floats` and `integers` from now on.

        As :meth:`move_arrays`, for the model (kernels/model_table.move_model_arrays: the
        blocks' sizes, what moves); the held wrench, which it shares with its model, moves
        with them.  Nothing for a model run as Python (:attr:`interpreted`).
        """
        if self._interpreted:
            return
        held = move_model_arrays(self._model, floats, integers)
        self._held = self._model_arguments['held'] = held

    def stepping_kernels(self) -> tuple[Any, Callable[..., int], Callable[..., int]]:
        """
        Return (controller, run kernel, controlled kernel) of its integrator, loaded once.

        Compiled, or interpreted while :attr:`interpreted` (kernels/interpreted.py).
        """
        run = self._run
        if run is None:
            run = self._load_kernels()
        return self._controller, run, self._controlled_kernel

    def prepare_step(self, dt: float) -> None:
        """
        Check a step of dt s against the stiff effects, as :meth:`step` does first.

        ValueError (the reason, what to change) for a fixed step that would diverge; under
        error control the least substeps are raised to what keeps the steps stable.  Only
        when the step, the substeps, the integrator or the tolerance changed.
        """
        if self._checked != (dt, self._substeps, self._integrator, self._tolerance):
            self._check_stiffness(dt)

    def advanced_to(self, time: float, compensation: float = 0.0) -> None:
        """
        Take the packed state as advanced outside, to simulated `time` (s).

        `compensation`: the low bits of a Kahan-summed clock (see :meth:`_add_time`), so that
        a clock kept outside goes on exactly as this one would.
        """
        self._integrated = self._state = None
        self._time = time
        self._time_compensation = compensation

    def divergence(self, duration: float) -> str:
        """Return the one-line message of a state that turned non-finite within `duration` s."""
        return self._divergence(duration)

    def _plan(self) -> None:
        """Tell the error controller the configuration changed, and if it is torque-free."""
        held = self._held
        torque_free = not (self._flows or np.any(held[HELD_TORQUE_WORLD])
                           or np.any(held[HELD_TORQUE_BODY])
                           or any(effect.exerts_torque for effect in self._pushing_effects))
        if self._constraint is not None:
            # About a pivot every force has a moment.
            torque_free = torque_free and not (self._pushing_effects or np.any(held))
        error_control.set_torque_free(self._control, torque_free)
        error_control.changed(self._control)

    def _check_stiffness(self, dt: float) -> None:
        """
        Refuse a fixed step too long for a stiff effect; under error control, bound it.

        See :mod:`.stability`: an explicit step of a linear decay faster than the method
        follows grows without bound.  Under error control the controller's lower bound on
        the substeps is raised to what keeps the steps stable (the `substeps` set stays).
        """
        self._checked = (dt, self._substeps, self._integrator, self._tolerance)
        problem = stiffness_problem(self, dt)
        if problem is not None and (self._tolerance is None or not math.isfinite(problem[0])):
            raise ValueError(problem[1])
        floor = self._substeps if problem is None else max(self._substeps, int(problem[0]))
        if self._tolerance is not None and floor != self._control_floor:
            error_control.set_bounds(self._control, floor)
            self._control_floor = floor

    def _advanced(self, duration: float, finite: bool) -> None:
        """
        Take the state a kernel left after `duration` s: finite, or the last one restored.

        The caller copied the values to the checkpoint before the kernel ran and says
        whether they are all `finite` now; a non-finite state is replaced by the checkpoint
        and DivergedError raised.
        """
        self._integrated = self._state = None
        if not finite:
            self._values[:] = self._checkpoint
            raise DivergedError(self._divergence(duration), self._time)
        self._add_time(duration)

    def _divergence(self, duration: float) -> str:
        """Return the one-line message of a state that turned non-finite."""
        acting = [repr(effect) for effect in self._effects
                  if getattr(effect, 'compiled_wrench', None) is not None
                  or getattr(effect, 'compiled_flow', None) is not None]
        if np.any(self._held):
            acting.append('the held wrench ' + ', '.join(
                f'{name} {self._held[row].tolist()}' for row, name in enumerate(
                    ('force_world', 'torque_world', 'force_body', 'torque_body'))
                if np.any(self._held[row])))
        control = (f'error control at {self._tolerance:g} rad/s' if self._tolerance
                   else f'{self._substeps} substep(s) per step')
        return (f'the state turned non-finite between t = {self._time:.9g} s and '
                f'{self._time + duration:.9g} s under {self.integrator} ({control}) with '
                f'{"; ".join(acting) or "no effect"}; kept the last finite state, at '
                f't = {self._time:.9g} s: a shorter step (rate, substeps) or smaller '
                'coefficients or inputs keep it finite')

    def _advance(self, steps: int, dt: float, duration: float | None = None) -> None:
        """Take `steps` steps of dt s; the clock moves by `duration` (default steps x dt)."""
        # Called once a tick by the node: no closure, no call more than needed.
        values = self._values
        self._checkpoint[:] = values
        run = self._run
        if run is None:
            run = self._load_kernels()
        # The kernel tests the state it leaves (kernels/loop.py): -1 if not finite.
        finite = run(values, self._model, self._integrator.method, dt, steps, self._time) >= 0
        self._advanced(steps * dt if duration is None else duration, finite)

    def _controlled(self, tick: float, ticks: int) -> None:
        """
        Take `ticks` outer steps of `tick` s under error control (error_control.py).

        One call of the controller takes them all, around the integrator's run kernel.
        """
        values = self._values
        self._checkpoint[:] = values
        if self._run is None:
            self._load_kernels()
        # The controller tests the state it leaves (error_control.py): -1 if not finite.
        finite = self._controlled_kernel(self._controller, values, self._model,
                                         self._integrator.method, tick, ticks, self._time,
                                         self._control) >= 0
        self._advanced(ticks * tick, finite)

    def _load_kernels(self) -> Callable[..., int]:
        """
        Fetch the run kernel and the controller, compiled or interpreted; return the run.

        Once per integrator (and per switch of :attr:`interpreted`): the Controller holding
        the run is built here, so that no step pays for handing the run to the controller.
        """
        run_kernel = self._integrator.run_kernel
        # Interpreted, the controller calls the run as it is (an error ends the whole call:
        # -1).
        self._controller = error_control.new_controller(run_kernel, self._interpreted)
        if self._interpreted:
            self._run = _interpreted(run_kernel.source)
            self._controlled_kernel = _interpreted(error_control.controlled.source)
        else:
            self._run = self._integrator.run
            self._controlled_kernel = error_control.controlled.dispatcher
        return self._run

    def _add_time(self, increment: float) -> None:
        # Kahan summation: keeps the clock exact to round-off over millions of ticks, where a
        # plain running sum would drift by ~steps * eps * time.
        y = increment - self._time_compensation
        total = self._time + y
        self._time_compensation = (total - self._time) - y
        self._time = total


def _interpreted(function: Callable[..., int]) -> Callable[..., int]:
    """Return an interpreted kernel that says -1 (not finite) where Python's math raises."""
    def guarded(*arguments: Any) -> int:
        try:
            return function(*arguments)
        except ARITHMETIC_ERRORS:
            return -1
    return guarded


def unresolved_rotation(body: RigidBody, state: State, period: float, substeps: int = 1,
                        tolerance: float | None = None) -> str | None:
    """
    Return a one-line warning if a tick's steps turn the body too far, else None.

    The body turns by |omega| h per step of h = period / substeps s (period: one tick, s);
    under error control (`tolerance` not None) the steps can shrink down to period /
    error_control.MAX_SUBSTEPS.  Beyond :data:`RESOLVED_ROTATION` rad per step the warning
    says by how much and names what to raise (``rate`` or ``substeps``).  Shared by the node
    and ``rigid-body-sim simulate``, which show it once, at the start.
    """
    with np.errstate(over='ignore', invalid='ignore'):
        speed = float(np.linalg.norm(state.angular_velocity(body)))
    finest = error_control.MAX_SUBSTEPS if tolerance else substeps
    angle = speed * period / finest
    if not angle > RESOLVED_ROTATION:
        return None
    control = (f'even at {finest} substeps, the most error control takes' if tolerance
               else f'at {substeps} substep(s) per tick')
    return (f'the body turns {angle:.3g} rad per integrator step (|omega| {speed:.3g} rad/s, '
            f'a tick of {period:g} s {control}): more than the {RESOLVED_ROTATION:g} rad a '
            'step resolves, so the motion is not followed; raise rate or substeps')

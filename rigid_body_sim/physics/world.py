"""
Many rigid bodies advanced together: one compiled call a tick for all of them.

A :class:`World` holds named :class:`~.simulator.Simulator` s, one per body, each with its
own body, effects, held wrench and error control, all with one integrator, one tolerance
and one least number of substeps.  The bodies do not touch each other: each moves as it
would alone.

What one tick costs.  :meth:`World.step` makes one call of :data:`step_bodies`, which
takes every body in turn through the very compiled kernels its Simulator's own
:meth:`~.simulator.Simulator.step` calls: the integrator's run kernel for fixed substeps,
the error controller (error_control.controlled) under a tolerance, each reached as a
first-class function held in a :class:`Stepper`.  So each body is advanced by the same
machine code as when it is simulated alone, and under error control each chooses its own
substeps: a fast tumbler does not make the others substep.  The bodies' states, control
arrays and their models' arrays are rows of blocks the World owns (Simulator.move_arrays,
Simulator.move_model_arrays), read in order, the models from a table (kernels/model_table.py);
what the loop adds per body is the call through a function pointer and a copy of its state
kept to restore, should it turn non-finite (benchmarks/many_bodies.py measures the whole
against the single body's kernel).  The bodies' Simulators are told their new time only when read
(:meth:`World.simulator`, :meth:`World.state`): a tick touches no Python object per body.

A body whose state turns non-finite is put back to its last finite state and stopped
(:attr:`World.diverged` says why) until its state is set or the world is reset; the
others go on.
"""

from __future__ import annotations

import collections
from collections.abc import Iterable
from collections.abc import Iterator
import math
from typing import Any

from numba import types
from numba.experimental import structref
from numba.typed import List
import numpy as np
import numpy.typing as npt

from . import error_control
from .integrators import get_integrator
from .kernels import interpreting
from .kernels import LazyKernel
from .kernels.borrow import borrowed
from .kernels.interpreted import stand_in
from .kernels.layout import STATE_SIZE
from .kernels.loop import METHOD_TYPE
from .kernels.model import MODEL_TYPE
from .kernels.model_table import model_array_sizes
from .kernels.model_table import model_at
from .kernels.model_table import model_table
from .kernels.model_table import MODEL_TABLE_KERNELS
from .kernels.model_table import MODEL_TABLE_TYPE
from .kernels.model_table import prefetch_model
from .simulator import checked_positive
from .simulator import Simulator
from .state import State

__all__ = ['World', 'Stepper', 'step_bodies', 'WORLD_KERNELS']


@structref.register
class StepperType(types.StructRef):
    """numba's type of a :class:`Stepper`."""

    def preprocess_fields(self, fields: Any) -> tuple[Any, ...]:
        """Drop literal types: every Stepper has the one type."""
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class Stepper(structref.StructRefProxy):
    """
    The kernels a tick of a World calls per body: an integrator's, held compiled.

    Fields ``controller`` (error_control's Controller, which holds the integrator's run
    kernel) and ``controlled`` (error_control.controlled, a first-class function of its
    CONTROLLED_SIGNATURE).  Built once per integrator by :func:`new_stepper`.
    """

    controller: Any
    controlled: Any


_CONTROLLED_FUNCTION = types.FunctionType(error_control.CONTROLLED_SIGNATURE)
structref.define_proxy(Stepper, StepperType, ['controller', 'controlled'])
# Run as Python (kernels/interpreted.py), a Stepper is a named tuple.
stand_in(Stepper, collections.namedtuple('InterpretedStepper', ['controller', 'controlled']))
STEPPER_TYPE = StepperType([('controller', error_control.CONTROLLER_TYPE),
                            ('controlled', _CONTROLLED_FUNCTION)])


def _stepper_of(controller: Any, controlled: Any) -> Stepper:
    return Stepper(controller, controlled)


stepper_of = LazyKernel(STEPPER_TYPE(error_control.CONTROLLER_TYPE, _CONTROLLED_FUNCTION),
                        _stepper_of, compile_seconds=0.1)
"""The compiled constructor of a :class:`Stepper`."""


def step_all(stepper: Stepper, states: npt.NDArray[np.float64], models: Any,
             controls: npt.NDArray[np.float64], checkpoints: npt.NDArray[np.float64],
             method: tuple[float, ...], tick: float, substeps: int, time: float,
             active: npt.NDArray[np.uint8], taken: npt.NDArray[np.int64]) -> int:
    """
    Advance every active body by one tick of `tick` s from `time` (s), in place.

    states (N, 13), controls (N, CONTROL_SIZE): each body's packed state and control array,
    a row each, in the bodies' order; models: their compiled models (a table:
    kernels/model_table.py); substeps:
    the fixed steps per tick, or 0 for error control;
    checkpoints (N, 13): scratch, each body's state before the tick; active (N,): 0 for a
    body left as it is; taken (N,): set to each body's integrator steps, 0 if not active,
    -1 if it turned non-finite (its state is then put back as it was).  Returns how many
    bodies turned non-finite.  The calls per body are those of Simulator.step: the run
    kernel for substeps steps of tick / substeps, or the controller for one tick.
    """
    controller = stepper.controller
    run = controller.run
    controlled = stepper.controlled
    diverged = 0
    for index in range(states.shape[0]):
        # The model after next: its fields arrive while this body and the next are stepped.
        prefetch_model(models, index + 2)
        if active[index] == 0:
            taken[index] = 0
            continue
        state = borrowed(states[index])
        checkpoint = borrowed(checkpoints[index])
        checkpoint[:] = state
        model = model_at(models, index)
        if substeps == 0:
            steps = controlled(controller, state, model, method, tick, 1, time,
                               borrowed(controls[index]))
        else:
            steps = run(state, model, method, tick / substeps, substeps, time)
        if steps < 0:
            state[:] = checkpoint
            diverged += 1
        taken[index] = steps
    return diverged


STEP_BODIES_SIGNATURE = types.int64(STEPPER_TYPE, types.float64[:, ::1], MODEL_TABLE_TYPE,
                                    types.float64[:, ::1], types.float64[:, ::1],
                                    METHOD_TYPE, types.float64,
                                    types.int64, types.float64, types.uint8[::1],
                                    types.int64[::1])
step_bodies = LazyKernel(STEP_BODIES_SIGNATURE, step_all, compile_seconds=1.5)
"""The compiled tick of a World (see :func:`step_all`): one kernel for every integrator."""

WORLD_KERNELS = (stepper_of, step_bodies) + MODEL_TABLE_KERNELS
"""The kernels of a World, compiled in the ``controller`` job (physics/warm_up.py)."""


def new_stepper(simulator: Simulator, interpreted: bool = False) -> Stepper:
    """Return the :class:`Stepper` of `simulator`'s integrator (compiled, or its source)."""
    controller, run, controlled = simulator.stepping_kernels()
    if interpreted:
        # The guarded run (an arithmetic error is -1) in the controller's stand-in.
        return stepper_of.source(type(controller)(run), controlled)
    return stepper_of.dispatcher(controller, controlled)


class World:
    """
    Named rigid bodies, each its own Simulator, advanced together one tick at a time.

    Parameters
    ----------
    bodies : iterable of (str, Simulator)
        The bodies by unique name, in order.  Each Simulator is taken over: its integrator,
        tolerance and substeps are set to the world's, its time to the world's.
    integrator : str
        A name in INTEGRATORS, for every body (default ``'buss'``).
    tolerance : float, optional
        Error control (rad per simulated s) of every body, each choosing its own substeps;
        None or 0: off.
    substeps : int
        Fixed steps per tick without a tolerance, the least with one.

    Settable: :attr:`integrator`, :attr:`tolerance`, :attr:`substeps`,
    :attr:`interpreted`.  Bodies come and go with :meth:`add` and :meth:`remove`.

    """

    def __init__(self, bodies: Iterable[tuple[str, Simulator]] = (),
                 integrator: str = 'buss', tolerance: float | None = None,
                 substeps: int = 1) -> None:
        self._simulators: dict[str, Simulator] = {}
        self._integrator = integrator
        self._tolerance = tolerance
        self._substeps = substeps
        self._interpreted = interpreting()
        self._time = 0.0
        self._time_compensation = 0.0
        # Ticks taken, and the tick at which each body's Simulator was last told its time.
        self._ticks = 0
        self._told: dict[str, int] = {}
        self.diverged: dict[str, str] = {}
        """{name: why} of the bodies stopped at their last finite state."""
        self._stepper: Stepper | None = None
        self._prepared: float | None = None
        get_integrator(integrator)
        for name, simulator in bodies:
            self._add(name, simulator)
        self._rebuild()

    # -- the bodies

    @property
    def names(self) -> tuple[str, ...]:
        """Get the bodies' names, in order."""
        return tuple(self._simulators)

    def __len__(self) -> int:
        """Return the number of bodies."""
        return len(self._simulators)

    def __contains__(self, name: object) -> bool:
        """Return True if a body is called `name`."""
        return name in self._simulators

    def __iter__(self) -> Iterator[str]:
        """Iterate over the bodies' names, in order."""
        return iter(self._simulators)

    def add(self, name: str, simulator: Simulator) -> None:
        """
        Add a body called `name` (unique) at the world's time, its state as it is.

        ValueError for a name already taken or not a non-empty string, or a Simulator
        whose step is refused at the world's settings (a stiff effect).
        """
        self._add(name, simulator)
        self._rebuild()

    def _add(self, name: str, simulator: Simulator) -> None:
        if not isinstance(name, str) or not name:
            raise ValueError(f'a body name must be a non-empty string; got {name!r}')
        if name in self._simulators:
            raise ValueError(f'a body called {name!r} exists already')
        if not isinstance(simulator, Simulator):
            raise ValueError(f'expected a Simulator for {name!r}; got '
                             f'{type(simulator).__name__}')
        simulator.integrator = self._integrator
        simulator.substeps = self._substeps
        simulator.tolerance = self._tolerance
        simulator.interpreted = self._interpreted
        if self._prepared is not None:
            simulator.prepare_step(self._prepared)
        simulator.advanced_to(self._time, self._time_compensation)
        self._simulators[name] = simulator
        self._told[name] = self._ticks

    def remove(self, name: str) -> Simulator:
        """Remove the body called `name` and return its Simulator (KeyError if none)."""
        simulator = self.simulator(name)
        simulator.move_arrays(np.zeros(STATE_SIZE), np.zeros(error_control.CONTROL_SIZE))
        del self._simulators[name]
        del self._told[name]
        self.diverged.pop(name, None)
        self._rebuild()
        return simulator

    def simulator(self, name: str) -> Simulator:
        """
        Return the Simulator of the body called `name`, told the world's time.

        Read it (state, energy, wrench) or change it (its state, its held wrench): the
        world steps the same arrays.  KeyError naming the bodies for an unknown name.
        """
        try:
            simulator = self._simulators[name]
        except KeyError:
            raise KeyError(f'no body called {name!r}; bodies: '
                           f'{", ".join(self._simulators) or "none"}') from None
        if self._told[name] != self._ticks:
            simulator.advanced_to(self._time, self._time_compensation)
            self._told[name] = self._ticks
        return simulator

    def state(self, name: str) -> State:
        """Return the State (world frame) of the body called `name`."""
        return self.simulator(name).state

    def set_state(self, name: str, state: State) -> None:
        """Set the state of the body called `name`; a stopped body goes on from it."""
        self.simulator(name).state = state
        if self.diverged.pop(name, None) is not None:
            self._active[self._index[name]] = 1

    def reset(self, states: dict[str, State], time: float = 0.0) -> None:
        """Set every body's state (`states` by name, all of them) and the time (s)."""
        missing = [name for name in self._simulators if name not in states]
        if missing:
            raise ValueError(f'no state for {", ".join(missing)}')
        if not math.isfinite(time):
            raise ValueError(f'time must be finite; got {time!r}')
        self._time = float(time)
        self._time_compensation = 0.0
        self._ticks += 1
        for name, simulator in self._simulators.items():
            simulator.reset(states[name], self._time)
            self._told[name] = self._ticks
        self.diverged.clear()
        self._active[:] = 1

    # -- what every body shares

    @property
    def time(self) -> float:
        """Get the simulated time in s."""
        return self._time

    @property
    def integrator(self) -> str:
        """Get or set the integrator of every body (a name in INTEGRATORS)."""
        return self._integrator

    @integrator.setter
    def integrator(self, name: str) -> None:
        self._set_every_body('integrator', name)
        self._integrator = name
        self._stepper = None
        self._prepared = None
        self._method = get_integrator(name).method

    @property
    def tolerance(self) -> float | None:
        """Get or set the error control of every body (rad/s; None or 0: off)."""
        return self._tolerance

    @tolerance.setter
    def tolerance(self, tolerance: float | None) -> None:
        self._set_every_body('tolerance', tolerance)
        self._tolerance = tolerance or None
        self._prepared = None

    @property
    def substeps(self) -> int:
        """Get or set the fixed steps per tick (the least under error control)."""
        return self._substeps

    @substeps.setter
    def substeps(self, substeps: int) -> None:
        self._set_every_body('substeps', substeps)
        self._substeps = substeps
        self._prepared = None

    @property
    def interpreted(self) -> bool:
        """Get or set whether the kernels run as their source (kernels/interpreted.py)."""
        return self._interpreted

    @interpreted.setter
    def interpreted(self, interpreted: bool) -> None:
        self._set_every_body('interpreted', interpreted)
        self._interpreted = bool(interpreted)
        self._stepper = None
        self._rebuild()

    def _set_every_body(self, attribute: str, value: Any) -> None:
        for simulator in self._simulators.values():
            setattr(simulator, attribute, value)

    # -- time stepping

    def step(self, dt: float) -> dict[str, str]:
        """
        Advance every body that is not stopped by one tick of dt s, in one kernel call.

        Returns {name: why} of the bodies that turned non-finite in it (each put back to
        its last finite state and stopped: :attr:`diverged`).  ValueError naming the body
        for a step its stiff effects refuse (checked when dt or the settings change).
        """
        # A finite positive float needs no conversion (the node passes one every tick).
        if dt.__class__ is not float or not 0.0 < dt < math.inf:
            dt = checked_positive(dt, 'dt')
        if self._prepared != dt:
            for name, simulator in self._simulators.items():
                try:
                    simulator.prepare_step(dt)
                except ValueError as error:
                    raise ValueError(f'body {name!r}: {error}') from None
            self._prepared = dt
        stepper = self._stepper
        if stepper is None and self._simulators:
            stepper = self._stepper = new_stepper(next(iter(self._simulators.values())),
                                                  self._interpreted)
        if stepper is not None:
            kernel = step_bodies.source if self._interpreted else step_bodies.dispatcher
            diverged = kernel(stepper, self._states, self._model_table, self._controls,
                              self._checkpoints, self._method, dt,
                              0 if self._tolerance else self._substeps, self._time,
                              self._active, self._taken)
        else:
            diverged = 0
        stopped = {}
        if diverged:
            for index in np.flatnonzero(self._taken < 0):
                name = self._order[index]
                stopped[name] = self._simulators[name].divergence(dt)
                self._active[index] = 0
            self.diverged.update(stopped)
        self._add_time(dt)
        self._ticks += 1
        return stopped

    @property
    def steps_taken(self) -> npt.NDArray[np.int64]:
        """Get each body's integrator steps in the last tick (0: stopped), in order."""
        return self._taken

    def _rebuild(self) -> None:
        """
        Give every body a row of the arrays the kernel takes, in the bodies' order.

        The states (N, 13) and the control arrays are one block each (Simulator.move_arrays),
        and so are the compiled models' arrays (Simulator.move_model_arrays), the models
        read from a table of them (kernels/model_table.py): a tick reads them in order,
        where arrays scattered in memory and a typed list's lookups cost the tick a good part
        of a body's step (benchmarks/world_step_breakdown.py, docs/benchmark.md).
        """
        simulators = list(self._simulators.values())
        count = len(simulators)
        states = np.zeros((count, STATE_SIZE))
        controls = np.zeros((count, error_control.CONTROL_SIZE))
        models = [] if self._interpreted else List.empty_list(MODEL_TYPE)
        for index, simulator in enumerate(simulators):
            simulator.move_arrays(states[index], controls[index])
        if not self._interpreted:
            _move_model_arrays(simulators)
        for simulator in simulators:
            models.append(simulator.kernel_arguments()[1])
        self._states, self._models, self._controls = states, models, controls
        # The table holds the models' addresses: valid while self._models holds them.
        self._model_table = model_table(models, self._interpreted)
        self._order = list(self._simulators)
        self._index = {name: index for index, name in enumerate(self._order)}
        self._checkpoints = np.zeros((count, STATE_SIZE))
        active = np.ones(count, dtype=np.uint8)
        for name in self.diverged:
            active[self._index[name]] = 0
        self._active = active
        self._taken = np.zeros(count, dtype=np.int64)
        self._method = get_integrator(self._integrator).method

    def _add_time(self, increment: float) -> None:
        # The Simulator's Kahan sum (Simulator._add_time), so that a body's clock here is
        # the one it has alone.
        y = increment - self._time_compensation
        total = self._time + y
        self._time_compensation = (total - self._time) - y
        self._time = total


def _move_model_arrays(simulators: list[Simulator]) -> None:
    """Give every body's compiled model a row of two blocks (floats, integers), in order."""
    if not simulators:
        return
    sizes = [model_array_sizes(simulator.kernel_arguments()[1]) for simulator in simulators]
    floats_width = max(floats for floats, _ in sizes)
    integers_width = max(integers for _, integers in sizes)
    floats = _line_aligned_zeros(len(simulators) * floats_width)
    integers = np.zeros(len(simulators) * integers_width, dtype=np.int64)
    for index, simulator in enumerate(simulators):
        simulator.move_model_arrays(
            floats[index * floats_width:(index + 1) * floats_width],
            integers[index * integers_width:(index + 1) * integers_width])


def _line_aligned_zeros(size: int) -> npt.NDArray[np.float64]:
    """Return `size` float64 zeros starting on a 64-byte cache line (each row's floats do)."""
    line = 64 // 8
    block = np.zeros(size + line)
    start = (-block.ctypes.data % 64) // 8
    return block[start:start + size]

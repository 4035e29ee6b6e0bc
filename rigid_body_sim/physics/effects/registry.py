"""
The effect registry: one name -> one effect class, and the checks of effect parameters.

An effect is a small object that says what acts on a body besides its own inertia.  What it
does is told by which of these it has (all optional; frames world, units SI), each written
once, as compiled code (kernels/model.py), so that every integrator runs it compiled:

- ``compiled_wrench``, a :func:`~rigid_body_sim.physics.kernels.model.wrench_term`
  ``(state, time, parameters) -> (Fx, Fy, Fz, tx, ty, tz)``, with
  ``wrench_parameters(body) -> array``: a force through the COM (N) and a torque about it
  (N m) on the physical packed state at `time`.  Declare what it reads and does:
  ``momentum_dependent = True`` if it depends on p or L (the kicks then keep their order
  for it), ``reads_state = True`` if it reads more of the state than the orientation and
  the time (a constrained body's full state is then expanded for it), ``exerts_torque =
  False`` if it never exerts a torque about the COM (the error control can then treat
  the motion as torque-free);
- ``compiled_flow``, a :func:`~rigid_body_sim.physics.kernels.model.flow_function`
  ``(state, parameters, duration)``, with ``flow_parameters(body) -> array`` (body: the
  integrated one): a change of the state that is not a wrench (internal dissipation),
  composed with each integrator step symmetrically: flow(dt/2), step(dt), flow(dt/2);
- ``constrain(body) -> constraint``: a holonomic constraint (a pivot); see
  :class:`rigid_body_sim.physics.effects.pivot.PivotConstraint` for what the Simulator uses;
- ``potential_energy(body, state)``: its potential energy in J, added by Simulator.energy();
- ``conserves``: which of 'angular_momentum' (|L| about the COM) and 'rotational_energy'
  (T_rot) the effect leaves constant (default: neither), and ``keeps_pivot_invariants``:
  under a pivot it keeps the pivot's (total energy, L about the pivot along gravity): the
  plots show as conserved only what every effect of a scene conserves;
- ``accepts_external_wrench = True``: the body may be pushed from outside (the node's
  torque and wrench topics write the Simulator's held wrench);
- ``damping_rate(body) -> (rate, what)``: the fastest rate (1/s) at which it damps the motion
  linearly, and what sets it: the Simulator refuses a fixed step the integrator cannot
  follow (physics/stability.py), and under error control never takes fewer substeps;
- ``example``: a dict of typical parameters (required): the tests run every effect, built
  from it, under every integrator, so a new effect is covered without editing them;
- ``units``: parameter -> its unit and frame (``'N m, world frame'``), which ``rigid-body-sim
  scenes --effects`` shows.

The base class :class:`Effect` lets Python call the compiled code on a State:
``wrench(body, state, time) -> (force, torque)`` and ``flow(body, state, dt) -> State`` (what
the kernels compute, not a second form of it: the tests' independent references of each
effect are in test/).
Only what a scene names is computed: an effect that has none of these costs nothing.

Adding an effect: one module with a class decorated by :func:`register_effect`, imported in
``effects/__init__.py``; it runs compiled under every integrator without an edit anywhere
else.  Its keyword arguments are its scene parameters (the scene loader reads names,
defaults and required ones from the signature); it checks their values with the ``check_*``
helpers here, which raise :class:`ParameterError` naming the parameter.  The same module
outside the package is a plugin (:mod:`.plugins`): :data:`EFFECTS` finds a name it does not
hold among the installed plugins' entry points when it is first asked for it.
"""

from __future__ import annotations

from collections.abc import Callable
from collections.abc import Iterator
from collections.abc import Mapping
from collections.abc import MutableMapping
import inspect
import math
from typing import Any
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ..body import RigidBody
from ..state import State

__all__ = [
    'EFFECTS',
    'Effect',
    'EffectRegistry',
    'ParameterError',
    'check_number',
    'check_vector',
    'create_effect',
    'describe_value',
    'effect_parameters',
    'register_effect',
    'unknown_effect',
]


class EffectRegistry(MutableMapping[str, 'type[Effect]']):
    """
    Effect name -> effect class: the built-in effects and the plugins found so far.

    A mapping like a dict, but a name it does not hold is first looked for by its
    `discover` function (set by :mod:`.plugins`: the installed plugins' entry points), and
    listing it (iterating, ``len``) discovers every plugin first.  So a lookup by name loads
    only the plugin of that name, and importing the package loads none.
    """

    def __init__(self) -> None:
        self._classes: dict[str, type[Effect]] = {}
        self._discover: Callable[[str | None], None] | None = None
        self._discovered_all = False
        self._discovering = False
        self.problems: dict[str, str] = {}
        """Effect name -> the one line saying why the plugin that declares it did not load."""

    def set_discover(self, discover: Callable[[str | None], None]) -> None:
        """Set ``discover(name)``: load the plugins of effect `name` (None: every plugin)."""
        self._discover = discover

    def _find(self, name: str | None) -> None:
        if self._discover is None or self._discovering or self._discovered_all:
            return
        self._discovering = True
        try:
            self._discover(name)
            if name is None:
                self._discovered_all = True
        finally:
            self._discovering = False

    def __getitem__(self, name: str) -> type[Effect]:
        """Return the class of effect `name`, discovering its plugin if needed."""
        if name not in self._classes and isinstance(name, str):
            self._find(name)
        return self._classes[name]

    def __setitem__(self, name: str, cls: type[Effect]) -> None:
        """Register `cls` as effect `name` (register_effect checks for a name given twice)."""
        self._classes[name] = cls

    def __delitem__(self, name: str) -> None:
        """Forget effect `name` (a test's effect, a plugin found broken)."""
        del self._classes[name]

    def __iter__(self) -> Iterator[str]:
        """Iterate over the names, every plugin discovered first."""
        self._find(None)
        return iter(list(self._classes))

    def __len__(self) -> int:
        """Return how many effects there are, every plugin discovered first."""
        self._find(None)
        return len(self._classes)

    def registered(self, name: str) -> bool:
        """Return whether `name` is registered already (no discovery)."""
        return name in self._classes

    def registered_names(self) -> list[str]:
        """Return the names registered so far (no discovery)."""
        return list(self._classes)

    def __repr__(self) -> str:
        """Return the registered names (without discovering)."""
        return f'EffectRegistry({sorted(self._classes)})'


EFFECTS = EffectRegistry()
"""Effect name -> effect class (see the module docstring for what an effect provides)."""


class ParameterError(ValueError):
    """A bad effect parameter: `key` names the parameter, `problem` says what is wrong."""

    def __init__(self, key: str, problem: str) -> None:
        super().__init__(f'{key}: {problem}')
        self.key = key
        self.problem = problem


# An effect class, given back by the decorator that registers it.
_Effect = TypeVar('_Effect', bound='Effect')


def register_effect(name: str) -> Callable[[type[_Effect]], type[_Effect]]:
    """Register the decorated effect class under `name`; it gains ``effect_name``."""
    def decorate(cls: type[_Effect]) -> type[_Effect]:
        if EFFECTS.registered(name):
            raise ValueError(f'effect {name!r} is registered twice')
        cls.effect_name = name
        EFFECTS[name] = cls
        return cls
    return decorate


def effect_parameters(name: str) -> dict[str, Any]:
    """
    Return {parameter: default} of the effect `name`; a required one has no default.

    Required parameters map to :data:`inspect.Parameter.empty`.
    """
    signature = inspect.signature(_effect_class(name))
    return {key: parameter.default for key, parameter in signature.parameters.items()}


def create_effect(name: str, parameters: Mapping[str, Any] | None = None) -> Effect:
    """
    Return the effect `name` built from a mapping of its parameters.

    Raises
    ------
    ValueError
        For an unknown effect (the message lists the valid names).
    ParameterError
        For an unknown or missing parameter or a bad value; ``key`` names the parameter.

    """
    cls = _effect_class(name)
    parameters = dict(parameters or {})
    accepted = effect_parameters(name)
    for key in parameters:
        if key not in accepted:
            valid = ', '.join(accepted) or 'none'
            raise ParameterError(key, f'unknown parameter of effect {name!r}; valid: {valid}')
    for key, default in accepted.items():
        if default is inspect.Parameter.empty and key not in parameters:
            raise ParameterError(key, f'missing; effect {name!r} requires it')
    return cls(**parameters)


def _effect_class(name: str) -> type[Effect]:
    try:
        return EFFECTS[name]
    except (KeyError, TypeError):
        raise ValueError(unknown_effect(name)) from None


def unknown_effect(name: object) -> str:
    """Return the message for an unknown effect: the valid names, or why its plugin failed."""
    valid = ', '.join(sorted(EFFECTS))
    problem = EFFECTS.problems.get(name) if isinstance(name, str) else None
    if problem is not None:
        return f'unknown effect {name!r}: {problem}'
    return f'unknown effect {name!r}; valid effects: {valid}'


class Effect:
    """
    Base of the effects: the protocol's defaults, Python faces of the compiled code, a repr.

    :meth:`wrench` and :meth:`flow` call the compiled wrench and flow from Python.

    Subclasses keep each constructor argument as an attribute of the same name, so that the
    repr shows the parameters in force.
    """

    effect_name: str | None = None
    momentum_dependent = False
    reads_state = False
    exerts_torque = True
    accepts_external_wrench = False
    compiled_wrench: Callable[..., Any] | None = None
    compiled_flow: Callable[..., Any] | None = None
    example: dict[str, Any] | None = None
    units: dict[str, str] = {}
    conserves: tuple[str, ...] = ()
    keeps_pivot_invariants = False
    # Optional members, absent unless an effect defines them (read with getattr): declared
    # here for their types only.
    constrain: Callable[[RigidBody], Any]
    damping_rate: Callable[[RigidBody], tuple[float, str]]
    potential_energy: Callable[[RigidBody, State], float]

    def wrench_parameters(self, body: RigidBody) -> NDArray[np.float64]:
        """Return the parameters (1-D float array) of the compiled wrench on `body`."""
        raise NotImplementedError

    def flow_parameters(self, body: RigidBody) -> NDArray[np.float64]:
        """Return the parameters (1-D float array) of the compiled flow on `body`."""
        raise NotImplementedError

    def wrench(self, body: RigidBody, state: State,
               time: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return (force N, torque N m) about the COM, world frame, at `state` and `time` s."""
        if self.compiled_wrench is None:
            raise NotImplementedError
        values = np.concatenate(state._fields())
        result = self.compiled_wrench(values, float(time), np.ascontiguousarray(
            self.wrench_parameters(body), dtype=float))
        return np.array(result[:3]), np.array(result[3:])

    def flow(self, body: RigidBody, state: State, dt: float) -> State:
        """Return the state after dt s of this effect's flow alone."""
        if self.compiled_flow is None:
            raise NotImplementedError
        values = np.concatenate(state._fields())
        self.compiled_flow(values, np.ascontiguousarray(self.flow_parameters(body),
                                                        dtype=float), float(dt))
        return State._from_values(values)

    def __repr__(self) -> str:
        """Return ``Name(parameter=value, ...)`` with the parameters in force."""
        signature = inspect.signature(type(self))
        parts = []
        for key in signature.parameters:
            value = getattr(self, key)
            if isinstance(value, np.ndarray):
                value = value.tolist()
            parts.append(f'{key}={value!r}')
        return f'{type(self).__name__}({", ".join(parts)})'


# -- parameter checks (the loader's messages come from here, prefixed with the key path)

def describe_value(value: object) -> str:
    """Return how a (YAML) value reads in a message: "the string '0.3'", "a list of 2"."""
    if isinstance(value, str):
        return f'the string {value!r}'
    if isinstance(value, (bool, np.bool_)):
        return f'the boolean {str(bool(value)).lower()}'
    if value is None:
        return 'nothing (null)'
    if isinstance(value, dict):
        return 'a mapping'
    if isinstance(value, (list, tuple)):
        return f'a list of {len(value)}'
    return f'{type(value).__name__} {value!r}'


def _is_number(value: object) -> bool:
    # bool is an int in Python, but `true` in a scene file is never meant as 1.
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def check_number(value: Any, key: str, unit: str = '', minimum: float | None = None,
                 positive: bool = False, maximum: float | None = None) -> float:
    """
    Return `value` as a finite float, else raise ParameterError naming `key`.

    minimum / maximum: the smallest / largest allowed value (inclusive); positive=True
    requires > 0.  The effects give a maximum that keeps their arithmetic finite.
    """
    if not _is_number(value):
        raise ParameterError(key, f'expected a number{_unit(unit)}, got {describe_value(value)}')
    number = float(value)
    if not math.isfinite(number):
        raise ParameterError(key, f'expected a finite number, got {number}')
    unit = f' {unit}' if unit else ''
    if positive and number <= 0.0:
        raise ParameterError(key, f'must be > 0{unit}, got {number:g}')
    if minimum is not None and number < minimum:
        raise ParameterError(key, f'must be >= {minimum:g}{unit}, got {number:g}')
    if maximum is not None and number > maximum:
        raise ParameterError(key, f'must be at most {maximum:g}{unit}, got {number:g}')
    return number


def check_vector(value: object, key: str, unit: str = '', size: int = 3,
                 largest: float | None = None) -> NDArray[np.float64]:
    """
    Return `value` as a float array of `size` finite numbers, else raise ParameterError.

    largest: the largest magnitude |v| allowed (the effects' bound on their arithmetic).
    """
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise ParameterError(
            key, f'expected {size} numbers{_unit(unit)}, got {describe_value(value)}')
    if len(value) != size:
        raise ParameterError(key, f'expected {size} numbers, got {len(value)}')
    for index, item in enumerate(value):
        if not _is_number(item):
            raise ParameterError(key, f'expected {size} numbers, item {index} is '
                                      f'{describe_value(item)}')
    array = np.array(value, dtype=float)
    if not np.all(np.isfinite(array)):
        raise ParameterError(key, f'expected finite numbers, got {array.tolist()}')
    if largest is not None:
        # |v| scaled by its largest component, so that 1e300 does not overflow to inf.
        scale = float(np.max(np.abs(array)))
        magnitude = scale * float(np.linalg.norm(array / scale)) if scale > 0.0 else 0.0
        if not magnitude <= largest:
            raise ParameterError(key, f'must be at most {largest:g}{_unit(unit)} in magnitude, '
                                      f'got {magnitude:.4g}')
    array.flags.writeable = False
    return array


def _unit(unit: str) -> str:
    return f' in {unit}' if unit else ''

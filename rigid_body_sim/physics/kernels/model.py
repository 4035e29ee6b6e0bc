"""
What pushes a body, as compiled code: the held wrench, the effects and a constraint.

A :class:`Model` (MuJoCo's mjModel to the packed state's mjData) holds everything fixed
between two changes of configuration: the packed body being integrated, the held wrench, and
the scene's effects as first-class compiled functions with their parameters:

- wrench terms, ``term(state, time, parameters) -> (Fx, Fy, Fz, tx, ty, tz)``: a force
  through the COM (N) and a torque about it (N m), world frame, on the physical state
  (a packed state of the COM: see :mod:`.layout`) at `time` (s);
- flows, ``flow(state, parameters, duration)``: a change of the integrated state in place
  that is not a wrench (internal dissipation), composed around each step;
- a constraint (a pivot): ``expand(integrated, parameters, physical)`` writes the physical
  state of the integrated one, ``transmit(state, wrench, parameters)`` returns the wrench
  the integrated system takes from a physical one (about the pivot, the reaction taking
  the force).

The integrators' kernels are compiled once each, for the one type of a Model, and call the
terms through the function pointers it holds: a combination of effects no kernel has seen
runs compiled without compiling anything but the effects' own small functions, and a
scene pays only for the terms it has (a loop over ``term_count`` entries).  Effects declare
their functions with the decorators here (:func:`wrench_term`, :func:`flow_function`, ...),
which compile them for the one signature each kind has.

Per call of a kernel the Model is unboxed, cheaply: its function pointers, the dear part,
were unboxed once, when it was built; an effect's term is an indirect call, a little dearer
than an inlined one (benchmarks/effect_cost.py measures what each effect adds to a step).
"""

from __future__ import annotations

import collections
from collections.abc import Callable
from collections.abc import Iterable
from collections.abc import Sequence
import os
from typing import Any
from typing import cast
import warnings

from numba import types
from numba.core.errors import NumbaExperimentalFeatureWarning
from numba.experimental import structref
import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from . import cache as kernel_cache
from . import inline
from . import kernel
from . import LazyKernel
from .algebra import Quaternion
from .algebra import rotate
from .borrow import borrowed
from .interpreted import stand_in
from .layout import STATE_SIZE

__all__ = ['Model', 'Forcing', 'MODEL_TYPE', 'new_model', 'unpacked', 'applied_wrench_of',
           'wrench_term', 'flow_function', 'expand_function', 'transmit_function', 'MAX_TERMS',
           'MAX_FLOWS', 'HELD_FORCE_WORLD', 'HELD_TORQUE_WORLD', 'HELD_FORCE_BODY',
           'HELD_TORQUE_BODY', 'integrated_wrench', 'applied_wrench', 'impulse', 'kick',
           'NO_ESTIMATE', 'apply_flows', 'held_is_zero', 'no_term', 'no_flow', 'no_expand',
           'no_transmit', 'compiled']

MAX_TERMS = 8
"""Most wrench terms a model holds (the tuple of function pointers has this fixed length,
so that its type, and with it every kernel, is the same for every scene)."""
MAX_FLOWS = 2
"""Most flows a model holds."""

# Rows of the held wrench (4, 3): fixed in the world or in the body (turning with it).
HELD_FORCE_WORLD, HELD_TORQUE_WORLD, HELD_FORCE_BODY, HELD_TORQUE_BODY = range(4)

Array = NDArray[np.float64]
"""The annotations' type of a float array: a packed state, parameters, the held wrench."""
Wrench = tuple[float, float, float, float, float, float]
"""The annotations' type of a wrench (Fx, Fy, Fz, tx, ty, tz), or an impulse."""

_vector = types.float64[::1]
_wrench = types.UniTuple(types.float64, 6)
TERM_SIGNATURE = _wrench(_vector, types.float64, _vector)
FLOW_SIGNATURE = types.none(_vector, _vector, types.float64)
EXPAND_SIGNATURE = types.none(_vector, _vector, _vector)
TRANSMIT_SIGNATURE = _wrench(_vector, _wrench, _vector)


def _signed(signature: Any, function: Callable[..., Any]) -> LazyKernel:
    """
    Declare `function` compiled for `signature` on first use, cached with the kernels.

    A function with no file (``python -c``, a notebook cell) cannot be cached: it is
    compiled in every process instead, a fraction of a second for an effect's wrench.  One
    in a file outside the package (a user's effect) is cached beside the kernels, under
    their sources' key: it may inline the toolkit.
    """
    filename = function.__code__.co_filename
    cached = os.path.isfile(filename)
    if cached:
        kernel_cache.claim_file(filename)
    return LazyKernel(signature, function, cached)


def compiled(function: LazyKernel | Callable[..., Any],
             interpreted: bool = False) -> Callable[..., Any]:
    """
    Return what a Model holds of a declared term, flow or constraint function.

    Its compiled function; for an interpreted Model, its source (kernels/interpreted.py).
    """
    if not isinstance(function, LazyKernel):
        return function
    return function.source if interpreted else function.dispatcher


def wrench_term(function: Callable[[Array, float, Array], Wrench]) -> LazyKernel:
    """Compile `function` as a wrench term: ``(state, time, parameters) -> 6-tuple``."""
    return _signed(TERM_SIGNATURE, function)


def flow_function(function: Callable[[Array, Array, float], None]) -> LazyKernel:
    """Compile `function` as a flow: ``(state, parameters, duration) -> None``, in place."""
    return _signed(FLOW_SIGNATURE, function)


def expand_function(function: Callable[[Array, Array, Array], None]) -> LazyKernel:
    """Compile `function` as a constraint's ``expand(integrated, parameters, physical)``."""
    return _signed(EXPAND_SIGNATURE, function)


def transmit_function(function: Callable[[Array, Wrench, Array], Wrench]) -> LazyKernel:
    """Compile `function` as a constraint's ``transmit(state, wrench, parameters)``."""
    return _signed(TRANSMIT_SIGNATURE, function)


@wrench_term
def no_term(state: Array, time: float, parameters: Array) -> Wrench:
    """Fill the unused entries of the terms (never called)."""
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


@flow_function
def no_flow(state: Array, parameters: Array, duration: float) -> None:
    """Fill the unused entries of the flows (never called)."""


@expand_function
def no_expand(integrated: Array, parameters: Array, physical: Array) -> None:
    """Stand for the expansion of an unconstrained body (never called)."""


@transmit_function
def no_transmit(state: Array, wrench: Wrench, parameters: Array) -> Wrench:
    """Stand for the transmission of an unconstrained body (never called)."""
    return wrench


@structref.register
class ModelType(types.StructRef):
    """numba's type of a :class:`Model`."""

    def preprocess_fields(self, fields: Iterable[tuple[str, Any]]
                          ) -> tuple[tuple[str, Any], ...]:
        """Drop literal types: every Model has the one type."""
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class Model(structref.StructRefProxy):
    """
    The fixed part of a simulation, compiled: body, held wrench, effects (see the module).

    Build one with :func:`new_model`; its arrays are shared with the caller, so writing the
    held wrench or a parameter array takes effect at the next kernel call.
    """


_TERM = types.FunctionType(TERM_SIGNATURE)
_FLOW = types.FunctionType(FLOW_SIGNATURE)
_FIELDS = (('body', _vector), ('held', types.float64[:, ::1]),
           ('terms', types.UniTuple(_TERM, MAX_TERMS)), ('term_count', types.int64),
           ('term_parameters', _vector), ('term_offsets', types.int64[::1]),
           ('momentum_dependent', types.boolean),
           ('flows', types.UniTuple(_FLOW, MAX_FLOWS)), ('flow_count', types.int64),
           ('flow_parameters', _vector), ('flow_offsets', types.int64[::1]),
           ('constrained', types.boolean), ('needs_physical', types.boolean),
           ('reads_state', types.boolean),
           ('expand', types.FunctionType(EXPAND_SIGNATURE)),
           ('transmit', types.FunctionType(TRANSMIT_SIGNATURE)),
           ('constraint_parameters', _vector),
           ('physical', _vector), ('stage', _vector), ('carry', _vector))
_NAMES = tuple(name for name, _ in _FIELDS)
structref.define_proxy(Model, ModelType, list(_NAMES))
# The kernels run as Python (kernels/interpreted.py) see a Model as a named tuple.
stand_in(Model, collections.namedtuple('InterpretedModel', _NAMES))
MODEL_TYPE = ModelType(list(_FIELDS))
"""numba's type of every Model: one type, so each kernel compiles once."""

# The Forcing adds what a call finds: whether the held wrench is not zero.
# Any to mypy, which types a namedtuple only from a literal list of fields.
Forcing = cast(Any, collections.namedtuple('Forcing', _NAMES + ('holding',)))
Forcing.__doc__ = """A Model's fields as one tuple of local values, unpacked once per kernel call.

Reading a field of the Model in the hot loop costs a load through its reference each time
(and a function pointer's unboxing); the kernels pass this tuple down instead (all inlined)."""


def _model_of(body: Array, held: Array, terms: tuple[Any, ...], term_count: int,
              term_parameters: Array, term_offsets: NDArray[np.int64],
              momentum_dependent: bool, flows: tuple[Any, ...], flow_count: int,
              flow_parameters: Array, flow_offsets: NDArray[np.int64],
              constrained: bool, needs_physical: bool, reads_state: bool,
              expand: Callable[..., None], transmit: Callable[..., Wrench],
              constraint_parameters: Array) -> Model:
    return Model(body, held, terms, term_count, term_parameters, term_offsets,
                 momentum_dependent, flows, flow_count, flow_parameters, flow_offsets,
                 constrained, needs_physical, reads_state, expand, transmit,
                 constraint_parameters,
                 np.zeros(STATE_SIZE), np.zeros(STATE_SIZE), np.zeros(STATE_SIZE))


_new_model = LazyKernel(MODEL_TYPE(*(kind for name, kind in _FIELDS[:17])), _model_of)


@kernel
def _body(model: Model) -> Array:
    return model.body


@kernel
def _term_count(model: Model) -> int:
    return model.term_count


@kernel
def _term_parameters(model: Model) -> Array:
    return model.term_parameters


@kernel
def _flow_count(model: Model) -> int:
    return model.flow_count


@kernel
def _constrained(model: Model) -> bool:
    return model.constrained


# What Python reads of a Model (numba gives a proxy no attribute of its own).
Model.body = property(_body, doc='The packed body integrated (27,).')
Model.term_count = property(_term_count, doc='The number of wrench terms.')
Model.term_parameters = property(_term_parameters,
                                 doc="The terms' parameters, concatenated (shared).")
Model.flow_count = property(_flow_count, doc='The number of flows.')
Model.constrained = property(_constrained, doc='True under a constraint.')


@inline
def unpacked(model: Model) -> Any:
    """Return the :class:`Forcing` of a Model (its fields as values)."""
    return Forcing(borrowed(model.body), borrowed(model.held), model.terms,
                   model.term_count, borrowed(model.term_parameters),
                   borrowed(model.term_offsets), model.momentum_dependent, model.flows,
                   model.flow_count, borrowed(model.flow_parameters),
                   borrowed(model.flow_offsets), model.constrained, model.needs_physical,
                   model.reads_state, model.expand, model.transmit,
                   borrowed(model.constraint_parameters), borrowed(model.physical),
                   borrowed(model.stage), borrowed(model.carry),
                   not held_is_zero(model.held))


def _packed(functions: Iterable[LazyKernel | Callable[..., Any]],
            parameters: Iterable[ArrayLike],
            limit: int, filler: LazyKernel, kind: str,
            interpreted: bool) -> tuple[tuple[Callable[..., Any], ...], int, Array,
                                        NDArray[np.int64]]:
    functions = tuple(compiled(function, interpreted) for function in functions)
    if len(functions) > limit:
        raise ValueError(f'at most {limit} {kind} can act on a body; got {len(functions)}')
    arrays = [np.ascontiguousarray(p, dtype=float).reshape(-1) for p in parameters]
    offsets = np.zeros(len(arrays) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([a.size for a in arrays])
    values = np.concatenate(arrays) if arrays else np.zeros(0)
    return (functions + (compiled(filler, interpreted),) * (limit - len(functions)),
            len(functions), values, offsets)


def new_model(body: ArrayLike, held: Array,
              terms: Sequence[tuple[LazyKernel | Callable[..., Any], ArrayLike]] = (),
              flows: Sequence[tuple[LazyKernel | Callable[..., Any], ArrayLike]] = (),
              constraint: tuple[LazyKernel, LazyKernel, Array] | None = None,
              momentum_dependent: bool = False, reads_state: bool = False,
              interpreted: bool = False) -> Model:
    """
    Return a :class:`Model`.

    body : (27,) the packed body integrated (layout.body_values); held : (4, 3) float array,
    the held wrench (rows HELD_*), shared: written in place, it acts at the next call;
    terms, flows : sequences of (compiled function, parameters array); constraint : None or
    (expand, transmit, parameters); momentum_dependent : some term depends on p or L (the
    kicks then take the midpoint rule, keeping their order); reads_state : some term reads
    more of the state than the orientation (the methods then give it their stages' whole
    state, and under the constraint the physical state is expanded for it; the
    orientation is the same in both); interpreted : a Model for the kernels run as
    Python (kernels/interpreted.py), made without compiling anything.
    """
    term_functions, term_count, term_parameters, term_offsets = _packed(
        [f for f, _ in terms], [p for _, p in terms], MAX_TERMS, no_term, 'wrench terms',
        interpreted)
    flow_functions, flow_count, flow_parameters, flow_offsets = _packed(
        [f for f, _ in flows], [p for _, p in flows], MAX_FLOWS, no_flow, 'flows', interpreted)
    if constraint is None:
        expand, transmit, constraint_parameters = no_expand, no_transmit, np.zeros(0)
    else:
        expand, transmit, constraint_parameters = constraint
    with warnings.catch_warnings():
        # numba labels first-class functions experimental (stable since 0.49; tested here),
        # and says so whenever it types a tuple of them: here, once per model.
        warnings.simplefilter('ignore', NumbaExperimentalFeatureWarning)
        make = _new_model.source if interpreted else _new_model.dispatcher
        return make(np.ascontiguousarray(body, dtype=float), held, term_functions,
                    term_count, term_parameters, term_offsets, bool(momentum_dependent),
                    flow_functions, flow_count, flow_parameters, flow_offsets,
                    constraint is not None, bool(reads_state and constraint is not None),
                    bool(reads_state), compiled(expand, interpreted),
                    compiled(transmit, interpreted),
                    np.ascontiguousarray(constraint_parameters, dtype=float))


@inline
def held_is_zero(held: Array) -> bool:
    """Return True if every entry of the held wrench (4, 3) is zero."""
    total = 0.0
    for row in range(4):
        total += abs(held[row, 0]) + abs(held[row, 1]) + abs(held[row, 2])
    return total == 0.0


@inline
def _held_wrench(q: Quaternion, held: Array) -> Wrench:
    """Return the held wrench at orientation q: F_w + R F_b, tau_w + R tau_b (world)."""
    # Entries read as scalars: a row view of the array would cost a reference count.
    fx, fy, fz = rotate(q, (held[HELD_FORCE_BODY, 0], held[HELD_FORCE_BODY, 1],
                            held[HELD_FORCE_BODY, 2]))
    tx, ty, tz = rotate(q, (held[HELD_TORQUE_BODY, 0], held[HELD_TORQUE_BODY, 1],
                            held[HELD_TORQUE_BODY, 2]))
    return (held[HELD_FORCE_WORLD, 0] + fx, held[HELD_FORCE_WORLD, 1] + fy,
            held[HELD_FORCE_WORLD, 2] + fz, held[HELD_TORQUE_WORLD, 0] + tx,
            held[HELD_TORQUE_WORLD, 1] + ty, held[HELD_TORQUE_WORLD, 2] + tz)


@inline
def applied_wrench(physical: Array, time: float, forcing: Any) -> Wrench:
    """
    Return the applied wrench on a physical state: held plus terms, about the COM (world).

    A constraint's reaction is not in it.  The IMU's accelerations start from it.
    """
    wrench = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if forcing.holding:
        wrench = _held_wrench((physical[0], physical[1], physical[2], physical[3]),
                              forcing.held)
    terms, offsets, parameters = forcing.terms, forcing.term_offsets, forcing.term_parameters
    for i in range(forcing.term_count):
        term = terms[i](physical, time, parameters[offsets[i]:offsets[i + 1]])
        wrench = (wrench[0] + term[0], wrench[1] + term[1], wrench[2] + term[2],
                  wrench[3] + term[3], wrench[4] + term[4], wrench[5] + term[5])
    return wrench


@inline
def integrated_wrench(state: Array, time: float, forcing: Any) -> Wrench:
    """
    Return the wrench the integrated system takes at the packed `state` and `time`.

    Free body: the applied wrench.  Constrained: the applied wrench on the physical state
    (expanded only if a term reads more than the orientation), transmitted to the
    integrated system (about a pivot: no force, the torque tau + r x F).
    """
    physical = state
    if forcing.needs_physical:
        forcing.expand(state, forcing.constraint_parameters, forcing.physical)
        physical = forcing.physical
    wrench = applied_wrench(physical, time, forcing)
    if forcing.constrained:
        return forcing.transmit(state, wrench, forcing.constraint_parameters)
    return wrench


NO_ESTIMATE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
"""The estimate an opening kick is given (it evaluates its own; see :func:`impulse`)."""


@inline
def impulse(state: Array, time: float, duration: float, forcing: Any, estimate: Wrench,
            estimated: bool) -> tuple[Wrench, Wrench]:
    """
    Return (h F, h tau), 6 numbers, of a kick of `duration` s from `state`, and an estimate.

    The kick changes p and L with the configuration (R, x) fixed: for a wrench of the
    configuration and time it is exact, h times the wrench at the state.  For one that
    depends on the momenta (drag) the explicit midpoint rule keeps it second order, so
    kick-drift-kick stays second order: h times the wrench W_mid at the state moved by half
    a kick of a first estimate W_0, the wrench at the state itself or, if `estimated`, the
    given `estimate`.  The estimate returned is the wrench extrapolated along the momenta to
    the kick's end, 2 W_mid - W_0: a Strang step's closing kick starts from its opening
    kick's, which is within O(h) of the wrench at its state (the drift turned the body) and
    within O(h^2) in the momenta, so it keeps its order with one evaluation instead of two:
    three a step, not four.  Against two evaluations a kick: about the same error (its z^3
    term, for the test equation y' = -lambda y, is -z^3/8 in both), a cheaper step under drag
    (benchmarks/effect_cost.py), and a lower stability limit lambda h for a stiff linear
    decay (physics/stability.py measures it and the Simulator refuses a step beyond it;
    docs/physics_api.md has the figures).  Without momentum dependence the estimate is the
    wrench at the state, unused.
    """
    if not forcing.momentum_dependent:
        wrench = integrated_wrench(state, time, forcing)
        return (duration * wrench[0], duration * wrench[1], duration * wrench[2],
                duration * wrench[3], duration * wrench[4], duration * wrench[5]), wrench
    # One call site of the wrench, in a loop of one or two evaluations (the first estimate
    # unless given, then the midpoint): its code compiled once here, not twice.
    evaluations = 1 if estimated else 2
    first = estimate
    half = 0.5 * duration
    p0, l0 = (state[7], state[8], state[9]), (state[10], state[11], state[12])
    wrench = NO_ESTIMATE
    for evaluation in range(evaluations):
        midpoint = evaluation == evaluations - 1
        if midpoint:
            # The midpoint is the state itself with p and L moved for the one evaluation,
            # then put back bit for bit: six stores each way instead of a copy of the state.
            for i in range(3):
                state[7 + i] = p0[i] + half * first[i]
                state[10 + i] = l0[i] + half * first[3 + i]
        wrench = integrated_wrench(state, time, forcing)
        if midpoint:
            for i in range(3):
                state[7 + i] = p0[i]
                state[10 + i] = l0[i]
        else:
            first = wrench
    estimate = (2.0 * wrench[0] - first[0], 2.0 * wrench[1] - first[1],
                2.0 * wrench[2] - first[2], 2.0 * wrench[3] - first[3],
                2.0 * wrench[4] - first[4], 2.0 * wrench[5] - first[5])
    return (duration * wrench[0], duration * wrench[1], duration * wrench[2],
            duration * wrench[3], duration * wrench[4], duration * wrench[5]), estimate


@inline
def kick(state: Array, time: float, duration: float, forcing: Any, estimate: Wrench,
         estimated: bool) -> Wrench:
    """
    Kick the momenta of the packed state in place: p += h F, L += h tau (see impulse).

    Returns the estimate for the closing kick of the same step.
    """
    change, estimate = impulse(state, time, duration, forcing, estimate, estimated)
    for i in range(3):
        state[7 + i] += change[i]
        state[10 + i] += change[3 + i]
    return estimate


@inline
def apply_flows(state: Array, forcing: Any, duration: float, reverse: bool) -> None:
    """Apply the flows to the packed state in place for `duration` s, in order or reversed."""
    count = forcing.flow_count
    offsets, parameters = forcing.flow_offsets, forcing.flow_parameters
    for k in range(count):
        i = count - 1 - k if reverse else k
        forcing.flows[i](state, parameters[offsets[i]:offsets[i + 1]], duration)


@kernel
def applied_wrench_of(physical: Array, time: float, model: Model) -> Wrench:
    """Return :func:`applied_wrench` of a Model (the entry point for Python)."""
    return applied_wrench(physical, time, unpacked(model))

"""
Many compiled models read by one kernel: a table of them, their arrays in one block.

A World (physics/world.py) advances N bodies in one kernel call, each through its own
:class:`~.model.Model`.  Read from a numba typed list, each with its arrays allocated apart,
N models cost the World's tick markedly more per body than the single body's kernel pays
for its one model, hot in the cache (benchmarks/world_step_breakdown.py times the parts;
docs/benchmark.md "Many bodies" has the figures):

- a typed list's item is taken by a call into the list's C code, with its checks and an
  atomic reference count: a :func:`model_table` holds the models' addresses instead, and
  :func:`model_at` reads one in a kernel with one load, borrowed (no reference counted:
  :class:`BorrowedModelType`).  A table is valid while the models in it are alive: its
  owner (the World) keeps the list it was made of.
- each array of each model is its own allocation, so the kernel's reads jump about
  memory: :func:`move_model_arrays` copies a model's arrays into the next part of two
  blocks (floats, integers) and points the model at them, body after body, as the World
  already keeps the states; :func:`model_array_sizes` says how much room a model takes.
- the models' fields themselves, one allocation per model: :func:`prefetch_model` asks
  the CPU for the next models' while the kernel steps one.

Written with numba's public extension API (``overload``, ``intrinsic``, ``lower_cast``,
``register_model``) and llvmlite's IR builder.  It relies on one fact of numba's StructRef
data model: its one member is the meminfo pointer :func:`model_at` reads from the table;
test/test_kernel_cache.py checks that fact and says so if a numba release changes it.  Run
as Python (the kernels interpreted), a table is the list of models itself, :func:`model_at`
an index into it and :func:`prefetch_model` nothing.
"""

from __future__ import annotations

from typing import Any

from llvmlite import ir
from numba import types
from numba.core.typeconv import Conversion
from numba.extending import intrinsic
from numba.extending import lower_cast
from numba.extending import models
from numba.extending import overload
from numba.extending import register_model
import numpy as np
from numpy.typing import NDArray

from . import inline
from . import LazyKernel
from .model import Model
from .model import MODEL_TYPE

__all__ = ['model_table', 'model_at', 'prefetch_model', 'BORROWED_MODEL_TYPE',
           'BorrowedModelType', 'model_array_sizes', 'move_model_arrays',
           'MODEL_TABLE_TYPE', 'MODEL_TABLE_KERNELS', 'STRUCTREF_MEMBERS', 'MOVED_ARRAYS']

MODEL_TABLE_TYPE = types.int64[::1]
"""numba's type of a table of models, as kernels take it: their addresses."""

STRUCTREF_MEMBERS = ('meminfo',)
"""The members of numba's StructRef data model :func:`model_at` builds (just the one)."""

MOVED_ARRAYS = ('body', 'held', 'term_parameters', 'flow_parameters', 'constraint_parameters',
                'physical', 'stage', 'carry', 'term_offsets', 'flow_offsets')
"""A Model's arrays, in the order :func:`move_model_arrays` lays them out (floats, then
integers): every array field of a Model (test/test_world.py checks)."""
_LINE = 8
"""Float64 entries in a 64-byte cache line: each model's floats start on a line of its own."""


class BorrowedModelType(types.Type):
    """
    numba's type of a model read from a table: a Model without a reference of its own.

    A kernel passes it where a Model is taken (numba casts it, at no cost); it counts no
    reference (an atomic increment and decrement per body a tick: docs/benchmark.md), so it
    is valid while the table's owner holds the models, and a kernel never stores one.
    """

    def __init__(self) -> None:
        super().__init__(name='BorrowedModel')

    def can_convert_to(self, typingctx: Any, other: Any) -> Any:
        """Convert to a Model, safely: the same pointer."""
        return Conversion.safe if other == MODEL_TYPE else None


BORROWED_MODEL_TYPE = BorrowedModelType()
"""numba's type of what :func:`model_at` returns in a kernel."""
register_model(BorrowedModelType)(models.OpaqueModel)


@lower_cast(BorrowedModelType, type(MODEL_TYPE))
def _as_model(context: Any, builder: Any, from_type: Any, to_type: Any, value: Any) -> Any:
    value_type = context.get_value_type(MODEL_TYPE)
    meminfo = builder.bitcast(value, value_type.elements[0])
    return builder.insert_value(ir.Constant(value_type, None), meminfo, 0)


def model_at(table: Any, index: int) -> Model:
    """Return the `index`-th model of a table (compiled: borrowed, read from its address)."""
    return table[index]


@intrinsic
def _model_at_address(typingctx: Any, address: Any) -> Any:
    if not isinstance(address, types.Integer):
        return None

    def codegen(context: Any, builder: Any, signature: Any, arguments: Any) -> Any:
        return builder.inttoptr(arguments[0], context.get_value_type(BORROWED_MODEL_TYPE))

    return BORROWED_MODEL_TYPE(address), codegen


@intrinsic
def _address_of(typingctx: Any, model: Any) -> Any:
    if model != MODEL_TYPE:
        return None

    def codegen(context: Any, builder: Any, signature: Any, arguments: Any) -> Any:
        return builder.ptrtoint(builder.extract_value(arguments[0], 0), ir.IntType(64))

    return types.int64(model), codegen


# Not annotated: numba requires the implementation it returns (a lambda) to have the same
# parameters as this function, annotations included.
@overload(model_at, inline='always')
def _model_at_compiled(table, index):  # type: ignore[no-untyped-def]
    if not (isinstance(table, types.Array) and table.dtype == types.int64):
        return None
    return lambda table, index: _model_at_address(table[index])


def prefetch_model(table: Any, index: int) -> None:
    """
    Ask the CPU to bring the `index`-th model of a table into the cache (if there is one).

    What a kernel calls for the model it reads next but one, so that its fields arrive
    while it steps the one before: numba allocates a model's fields right after its
    reference count's header, so the lines from its address on hold both.  A hint: it
    changes no value, and were numba to lay them out otherwise, only the time would tell.
    Run as Python: nothing.
    """


_MEMINFO_HEADER_BYTES = 40
"""The size of numba's meminfo header (refct, dtor, dtor_info, data, size), before the data."""


@intrinsic
def _prefetch(typingctx: Any, address: Any) -> Any:
    if not isinstance(address, types.Integer):
        return None

    def codegen(context: Any, builder: Any, signature: Any, arguments: Any) -> Any:
        fields = context.get_abi_sizeof(context.get_data_type(MODEL_TYPE.get_data_type()))
        lines = (_MEMINFO_HEADER_BYTES + fields + 63) // 64 + 1  # the first may start mid-line
        byte_pointer = ir.IntType(8).as_pointer()
        integer = ir.IntType(32)
        name = 'llvm.prefetch.p0'
        prefetch = builder.module.globals.get(name)
        if prefetch is None:
            prefetch = ir.Function(builder.module, ir.FunctionType(
                ir.VoidType(), [byte_pointer, integer, integer, integer]), name)
        start = builder.inttoptr(arguments[0], byte_pointer)
        for line in range(lines):
            # read (0), keep in every level of the cache (3), data (1)
            builder.call(prefetch, [builder.gep(start, [ir.IntType(64)(64 * line)]),
                                    integer(0), integer(3), integer(1)])
        return context.get_dummy_value()

    return types.none(address), codegen


@overload(prefetch_model, inline='always')
def _prefetch_model_compiled(table, index):  # type: ignore[no-untyped-def]
    if not (isinstance(table, types.Array) and table.dtype == types.int64):
        return None

    def prefetch(table, index):  # type: ignore[no-untyped-def]
        if index < table.shape[0]:
            _prefetch(table[index])
    return prefetch


def _table_of(models: Any) -> NDArray[np.int64]:
    table = np.empty(len(models), dtype=np.int64)
    for index in range(len(models)):
        table[index] = _address_of(models[index])
    return table


_table = LazyKernel(MODEL_TABLE_TYPE(types.ListType(MODEL_TYPE)), _table_of,
                    compile_seconds=0.2)


def model_table(models: Any, interpreted: bool = False) -> Any:
    """
    Return the table a kernel reads `models` from (a numba typed list of Models).

    Valid while those models are alive: keep the list.  Interpreted: `models` itself.
    """
    return models if interpreted else _table.dispatcher(models)


def _sizes(model: Model) -> tuple[int, int]:
    floats = (model.body.size + model.held.size + model.term_parameters.size
              + model.flow_parameters.size + model.constraint_parameters.size
              + model.physical.size + model.stage.size + model.carry.size)
    integers = model.term_offsets.size + model.flow_offsets.size
    return (floats + _LINE - 1) // _LINE * _LINE, integers


_model_array_sizes = LazyKernel(types.UniTuple(types.int64, 2)(MODEL_TYPE), _sizes,
                                compile_seconds=0.2)


def model_array_sizes(model: Model) -> tuple[int, int]:
    """Return (floats, integers): the room a model's arrays take (:func:`move_model_arrays`)."""
    return _model_array_sizes.dispatcher(model)


@inline
def _moved(array: Any, block: Any, at: int) -> Any:
    view = block[at:at + array.size]
    view[:] = array
    return view


def _move(model: Model, floats: NDArray[np.float64],
          integers: NDArray[np.int64]) -> NDArray[np.float64]:
    at = 0
    model.body = _moved(model.body, floats, at)
    at += model.body.size
    held = _moved(model.held.reshape(-1), floats, at).reshape(model.held.shape)
    at += held.size
    model.held = held
    model.term_parameters = _moved(model.term_parameters, floats, at)
    at += model.term_parameters.size
    model.flow_parameters = _moved(model.flow_parameters, floats, at)
    at += model.flow_parameters.size
    model.constraint_parameters = _moved(model.constraint_parameters, floats, at)
    at += model.constraint_parameters.size
    model.physical = _moved(model.physical, floats, at)
    at += model.physical.size
    model.stage = _moved(model.stage, floats, at)
    at += model.stage.size
    model.carry = _moved(model.carry, floats, at)
    model.term_offsets = _moved(model.term_offsets, integers, 0)
    model.flow_offsets = _moved(model.flow_offsets, integers, model.term_offsets.size)
    return held


_move_model_arrays = LazyKernel(
    types.float64[:, ::1](MODEL_TYPE, types.float64[::1], types.int64[::1]), _move,
    compile_seconds=0.5)


def move_model_arrays(model: Model, floats: NDArray[np.float64],
                      integers: NDArray[np.int64]) -> NDArray[np.float64]:
    """
    Copy a compiled model's arrays into `floats` and `integers` and point it at them.

    The blocks are 1-D, C-contiguous, of at least :func:`model_array_sizes`; nothing
    changes but where the arrays live (the same values, the same bits of every step).
    Returns the model's held wrench (4, 3) as it now lives, a view of `floats`: the one
    array a Simulator shares with its model, which it must write from now on.
    """
    return _move_model_arrays.dispatcher(model, floats, integers)


MODEL_TABLE_KERNELS = (_table, _model_array_sizes, _move_model_arrays)
"""The kernels of this module, compiled with the World's (physics/warm_up.py)."""

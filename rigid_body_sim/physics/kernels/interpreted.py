"""
The kernels' own source run by the Python interpreter: nothing to compile, the same method.

numba compiles each kernel from a Python function (``py_func``).  :func:`source_function`
gives that function back with every compiled function it reaches replaced by its own
source in turn, and numba's objects that have no Python form replaced by their stand-ins
(:func:`stand_in`: a Model is a named tuple of the same fields).  It is what runs while the
kernels compile (the node's first seconds on a machine that never compiled them), orders of
magnitude slower than the kernels and computing the same steps: the same operations in
the same order (numba does not reorder or fuse them), so the results agree to the last bits
but where a library function (sqrt, sin) or numpy rounds differently.

One difference of semantics: IEEE arithmetic.  A float division by zero or an overflowing
math function raises in Python (ZeroDivisionError, OverflowError, ValueError) where the
kernels give inf or nan; the Simulator takes either as a state that is not finite.
"""

from __future__ import annotations

from collections.abc import Callable
import types
from typing import Any

from numba.extending import is_jitted

__all__ = ['source_function', 'stand_in', 'ARITHMETIC_ERRORS']

ARITHMETIC_ERRORS = (ArithmeticError, ValueError)
"""What the interpreter raises where the compiled kernels give inf or nan."""

_stand_ins: dict[int, tuple[object, object]] = {}
_sources: dict[Callable[..., Any], Callable[..., Any]] = {}


def stand_in(compiled_object: object, python_object: object) -> None:
    """Make the interpreted kernels see `python_object` wherever they name `compiled_object`."""
    _stand_ins[id(compiled_object)] = (compiled_object, python_object)


def _is_compiled(value: Any) -> bool:
    return is_jitted(value) or type(value).__name__ == 'LazyKernel'


def _interpreted(value: Any) -> Any:
    """Return what the interpreted kernels use for `value` (itself if nothing else)."""
    entry = _stand_ins.get(id(value))
    if entry is not None and entry[0] is value:
        return entry[1]
    if _is_compiled(value):
        return source_function(value)
    return value


def _names(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for constant in code.co_consts:
        if isinstance(constant, types.CodeType):
            names |= _names(constant)
    return names


def source_function(function: Callable[..., Any]) -> Callable[..., Any]:
    """
    Return the Python source function of a compiled function, its callees interpreted too.

    `function`: a numba dispatcher, a LazyKernel, or a plain function (returned as it is).
    The result is built once per function and kept; its globals are a copy of its module's,
    with the compiled functions and stand-ins replaced (so a module global reassigned later
    is not seen: the kernels read constants only).
    """
    python = getattr(function, 'py_func', None) if _is_compiled(function) else None
    if python is None:
        return function
    made = _sources.get(python)
    if made is not None:
        return made
    namespace = dict(python.__globals__)
    closure = None
    if python.__closure__ is not None:
        closure = tuple(types.CellType(_interpreted(cell.cell_contents))
                        for cell in python.__closure__)
    made = types.FunctionType(python.__code__, namespace, python.__name__,
                              python.__defaults__, closure)
    made.__kwdefaults__ = python.__kwdefaults__
    made.__doc__ = python.__doc__
    made.__qualname__ = python.__qualname__
    made.__module__ = python.__module__
    _sources[python] = made
    for name in _names(python.__code__):
        if name in namespace:
            namespace[name] = _interpreted(namespace[name])
    return made

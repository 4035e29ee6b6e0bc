"""
Borrowed array views: the kernels' hot loops without reference counting.

numba counts references to every array it passes or stores (an atomic increment and
decrement a pair), and the kernels pass the Model's arrays down through their
steps, kicks and wrench terms several times a step.  A borrowed view is the same array
without its reference (numba's own views of foreign memory, numba.carray, are made the same
way): counting it is a no-op.  It is valid while the array it borrows from is alive, which
the kernel's caller guarantees for the duration of the call; the kernels never store one.
What it saves is measured by benchmarks/borrowed_views.py (the kernels with and without it,
side by side).

Written with numba's public extension API (``overload``, ``intrinsic``) and llvmlite's IR
builder.  It relies on one fact of numba's array data model: its first two members are the
reference (``meminfo``) and the parent object; test/test_kernel_cache.py checks that fact
and says so if a numba release changes it.  Run as Python (the kernels interpreted), a
borrowed view is the array itself.
"""

from __future__ import annotations

import os
from typing import Any
from typing import TypeVar

from llvmlite import ir
from numba import types
from numba.extending import intrinsic
from numba.extending import overload
import numpy as np
from numpy.typing import NDArray

__all__ = ['borrowed', 'BORROWED_MEMBERS', 'borrowing']

# A borrowed view has the type of the array it borrows from.
_Array = TypeVar('_Array', bound=NDArray[np.float64] | NDArray[np.int64])

BORROWED_MEMBERS = ('meminfo', 'parent')
"""The members of numba's array structure a borrowed view sets to null, by position 0, 1."""

borrowing = os.environ.get('RIGID_BODY_SIM_BORROW', '1') != '0'
"""False (``RIGID_BODY_SIM_BORROW=0``) makes :func:`borrowed` count references like any
array: for benchmarks/borrowed_views.py only, which compiles such kernels in a cache folder
of their own (the cache's key does not see this switch)."""


def borrowed(array: _Array) -> _Array:
    """Return `array` as a view without a reference (see the module docstring)."""
    return array


@intrinsic
def _view_without_reference(typingctx: Any, array: Any) -> Any:
    if not isinstance(array, types.Array):
        return None

    def codegen(context: Any, builder: Any, signature: Any, arguments: Any) -> Any:
        view = arguments[0]
        for position in range(len(BORROWED_MEMBERS)):
            member = view.type.elements[position]
            view = builder.insert_value(view, ir.Constant(member, None), position)
        return view

    return array(array), codegen


# Not annotated: numba requires the implementation it returns (a lambda, which cannot be
# annotated) to have the same parameters as this function, annotations included.
@overload(borrowed, inline='always')
def _borrowed_compiled(array):  # type: ignore[no-untyped-def]
    if not isinstance(array, types.Array):
        return None
    if not borrowing:
        return lambda array: array
    return lambda array: _view_without_reference(array)

"""
Borrowed array views: the kernels' hot loops without reference counting.

numba counts references to every array it passes or stores (an atomic increment and
decrement, ~5 ns a pair here), and the kernels pass the Model's arrays down through their
steps, kicks and wrench terms several times a step: measured, that counting cost more than
the steps' arithmetic (a torque-free Buss step 0.05 -> 0.14 us, a kick under a held wrench
~40 ns).  A borrowed view is the same array without its reference (numba's own views of
foreign memory, numba.carray, are made the same way): counting it is a no-op.  It is valid
while the array it borrows from is alive, which the kernel's caller guarantees for the
duration of the call; the kernels never store one.
"""

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ['borrowed']


@intrinsic
def borrowed(typingctx, array):
    """Return `array` as a view without a reference (see the module docstring)."""
    if not isinstance(array, types.Array):
        return None

    def codegen(context, builder, signature, arguments):
        view = cgutils.create_struct_proxy(signature.return_type)(
            context, builder, value=arguments[0])
        view.meminfo = cgutils.get_null_value(view.meminfo.type)
        view.parent = cgutils.get_null_value(view.parent.type)
        return view._getvalue()

    return array(array), codegen

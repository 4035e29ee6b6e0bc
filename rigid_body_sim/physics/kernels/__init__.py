"""
The compiled toolkit of the physics core: every piece of rigid-body algebra written once.

- :mod:`.layout`: the packed state (13) and body (27) the kernels work on, and packing them;
- :mod:`.algebra`: the quaternion product, R v and R^T v, the exponential map (one cut-off,
  its truncation error stated), cross and dot products, on scalars and tuples;
- :mod:`.model`: the scene's forcing as compiled code: the held wrench, the effects' wrench
  terms and flows and a constraint, reached through first-class function pointers held in
  one structure (:class:`Model`), so that one compiled loop per integrator serves every
  combination of effects without being compiled again;
- :mod:`.loop`: the one run loop (flows around each step) every integrator's kernel inlines.

Compiled functions are cached by what they are compiled from, once per machine, wherever the
package sits (:mod:`.cache`); the decorators here tell numba so.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any
from typing import TypeVar

import numba

from . import cache

__all__ = ['kernel', 'helper', 'outlined', 'inline', 'LazyKernel', 'cache', 'interpreting',
           'set_interpreted']

# A compiled function is typed as its source: numba's dispatcher takes the same arguments.
_Compiled = TypeVar('_Compiled', bound=Callable[..., Any])


class _Mode:
    interpreted = False


def interpreting() -> bool:
    """Return whether entry points called from Python run their source interpreted."""
    return _Mode.interpreted


def set_interpreted(interpreted: bool) -> None:
    """
    Run every entry point called from Python as its source, interpreted (or compiled again).

    While the kernels compile in another process, a process that must not wait (the node)
    runs their source with nothing compiled (:mod:`.interpreted`); a Simulator follows
    through its own ``interpreted`` switch.
    """
    _Mode.interpreted = bool(interpreted)


def _njit(signature: Any = None, cached: bool = True,
          **options: Any) -> Callable[[Callable[..., Any]], Any]:
    """Return numba's njit decorator with this package's options (cached where possible)."""
    cache.install_locator()
    options = dict(cache=cached and cache.caching_enabled(), nogil=True, error_model='numpy',
                   **options)
    if signature is None:
        return numba.njit(**options)
    return numba.njit(signature, **options)


# error_model='numpy': a float division by zero gives inf or nan, as IEEE arithmetic does, not
# a ZeroDivisionError out of a kernel (the Simulator stops a state that turns non-finite and
# says why); it also spares every division its zero test.


def kernel(function: Callable[..., Any]) -> LazyKernel:
    """Decorate an entry point called from Python: compiled on first use, cached to disk."""
    return LazyKernel(None, function)


def helper(function: _Compiled) -> _Compiled:
    """
    Decorate a compiled helper called from other compiled code (also callable from Python).

    Inlined into its callers at numba's IR level: left to LLVM, calls of the algebra's small
    tuple functions were a visible part of a Buss step (numba's calling convention around each); a
    Python caller gets the helper compiled on its own, cached.
    """
    return _njit(inline='always')(function)


def outlined(function: _Compiled) -> _Compiled:
    """
    Decorate a compiled helper too large to inline: compiled once and called.

    The call costs nothing beside the work of a helper such as the exact torque-free flow;
    inlined at the IR level into each copy of each loop, that one made the exact integrator's
    kernels many times slower to compile.
    """
    return _njit()(function)


def inline(function: _Compiled) -> _Compiled:
    """
    Decorate a compiled function that takes other compiled functions as arguments.

    numba inlines it into its caller at the IR level, so the function arguments become direct
    calls; a call that passed them at run time would make numba refuse to cache the caller.
    """
    return numba.njit(inline='always', nogil=True, error_model='numpy')(function)


class LazyKernel:
    """
    An entry point called from Python, compiled (or loaded from the cache) on first use.

    Given a signature, numba compiles a function at once, when it is decorated; declared this
    way the compile waits until :attr:`dispatcher` is first read, so that importing the
    package compiles nothing.  With one declared signature numba never compiles a second
    specialisation behind the caller's back (a literal argument, a new tuple length), and a
    kernel that takes another kernel takes it as a first-class function of that signature
    (cached, where a kernel passed as a dispatcher is not).  Without one (signature None),
    it is typed from its first call's arguments, as numba's njit.

    Called while :func:`interpreting`, it runs its source instead (:attr:`source`).

    Attributes
    ----------
    signature : numba signature or None
        What it is compiled for.
    py_func : function
        Its source as a Python function (without compiling).
    cached : bool
        Whether its compiled code is cached (not for a function with no source file).
    compile_seconds : float or None
        The CPU seconds it takes to compile, as declared (an estimate), or None.

    """

    def __init__(self, signature: Any, function: Callable[..., Any], cached: bool = True,
                 compile_seconds: float | None = None) -> None:
        self.signature = signature
        self.py_func = function
        self.cached = cached
        self.compile_seconds = compile_seconds
        self.__name__ = function.__name__
        self.__qualname__ = function.__qualname__
        self.__module__ = function.__module__
        self.__doc__ = function.__doc__
        self._dispatcher: Any = None
        self._source: Callable[..., Any] | None = None

    @property
    def dispatcher(self) -> Any:
        """Get the compiled function (compiling it, or loading it from the cache, once)."""
        if self._dispatcher is None:
            self._dispatcher = _njit(self.signature, self.cached)(self.py_func)
        return self._dispatcher

    @property
    def source(self) -> Callable[..., Any]:
        """Get its source as Python, every compiled function it calls interpreted too."""
        if self._source is None:
            from .interpreted import source_function
            self._source = source_function(self)
        return self._source

    @property
    def loaded(self) -> bool:
        """Get whether :attr:`dispatcher` was made in this process."""
        return self._dispatcher is not None

    def __call__(self, *arguments: Any) -> Any:
        """Call the compiled function, or the source while interpreting."""
        if _Mode.interpreted:
            return self.source(*arguments)
        return self.dispatcher(*arguments)

    def __repr__(self) -> str:
        """Return ``LazyKernel(module.name)``."""
        return f'LazyKernel({self.__module__}.{self.__qualname__})'

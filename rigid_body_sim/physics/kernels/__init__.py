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

Compiled functions are cached by numba beside their sources (``__pycache__``).  numba's cache
sees edits to a function's own file only, not to a helper it calls from another file, so
:func:`ensure_fresh_cache` (run when this package is imported, before anything compiles)
keeps a fingerprint of the physics core's sources and, when it changed, deletes the core's
cached kernels: a changed source never runs a stale kernel.  The effects (``effects/``) are
left out of the fingerprint: the kernels reach an effect's compiled functions only through
the pointers a Model holds, never inline its code, and an effect's own file is numba's to
watch; so a new or edited effect compiles its own functions (under a second) and every
integrator's kernels stay compiled.  An effect's compiled code may call this toolkit (in
the fingerprint) and its own file, not another effect's file.
"""

import functools
import hashlib
import os
from pathlib import Path

import numba

__all__ = ['kernel', 'helper', 'outlined', 'inline', 'LazyKernel', 'ensure_fresh_cache',
           'source_fingerprint', 'PHYSICS_ROOT', 'FINGERPRINT', 'compiled_marker']

PHYSICS_ROOT = Path(__file__).resolve().parent.parent
"""The directory of the physics core, whose sources the kernels are compiled from."""

_FINGERPRINT_FILE = '__pycache__/kernel-sources.sha256'


# error_model='numpy': a float division by zero gives inf or nan, as IEEE arithmetic does, not
# a ZeroDivisionError out of a kernel (the Simulator stops a state that turns non-finite and
# says why); it also spares every division its zero test.
kernel = functools.partial(numba.njit, cache=True, nogil=True, error_model='numpy')
"""Decorator of an entry point called from Python: compiled on first use, cached to disk."""

helper = functools.partial(numba.njit, cache=True, nogil=True, inline='always',
                           error_model='numpy')
"""Decorator of a compiled helper called from other compiled code (also callable from Python).

Inlined into its callers at numba's IR level: left to LLVM, calls of the algebra's small
tuple functions cost 5 of a Buss step's 48 ns (numba's calling convention around each); a
Python caller gets the helper compiled on its own, cached."""

outlined = functools.partial(numba.njit, cache=True, nogil=True, error_model='numpy')
"""Decorator of a compiled helper too large to inline: compiled once and called.

The call costs a few ns, nothing beside the work of a helper such as the exact torque-free
flow (~500 ns); inlined at the IR level into each copy of each loop, that one made the exact
integrator's kernels take 288 s to compile (25 s called)."""

inline = functools.partial(numba.njit, inline='always', nogil=True, error_model='numpy')
"""Decorator of a compiled function that takes other compiled functions as arguments.

numba inlines it into its caller at the IR level, so the function arguments become direct
calls; a call that passed them at run time would make numba refuse to cache the caller."""


class LazyKernel:
    """
    An entry point declared with its one signature, compiled (or loaded) on first use.

    numba compiles a function given a signature at once, when it is decorated; declared
    this way the compile waits until :attr:`dispatcher` is first read, so that importing
    the package compiles nothing.  One signature, declared: numba never compiles a second
    specialisation (a literal argument, a new tuple length) behind the caller's back, and a
    kernel that takes another kernel takes it as a first-class function of that signature
    (cached, where a kernel passed as a dispatcher is not).

    Attributes
    ----------
    signature : numba signature
        What it is compiled for.
    py_func : function
        Its source as a Python function (``dispatcher.py_func``, without compiling).

    """

    def __init__(self, signature, function):
        self.signature = signature
        self.py_func = function
        self.__name__ = function.__name__
        self.__qualname__ = function.__qualname__
        self.__module__ = function.__module__
        self.__doc__ = function.__doc__
        self._dispatcher = None

    @property
    def dispatcher(self):
        """Get the compiled function (compiling it, or loading it from the cache, once)."""
        if self._dispatcher is None:
            self._dispatcher = numba.njit(self.signature, cache=True, nogil=True,
                                          error_model='numpy')(self.py_func)
        return self._dispatcher

    @property
    def loaded(self):
        """Get whether :attr:`dispatcher` was made in this process."""
        return self._dispatcher is not None

    def __call__(self, *arguments):
        """Call the compiled function (a caller in a loop keeps :attr:`dispatcher`)."""
        return self.dispatcher(*arguments)

    def __repr__(self):
        """Return ``LazyKernel(module.name)``."""
        return f'LazyKernel({self.__module__}.{self.__qualname__})'


def source_fingerprint(root=PHYSICS_ROOT):
    """
    Return the SHA-256 of the ``*.py`` files under `root` (names and contents), as hex.

    Every file but the effects' (``effects/``: see the module docstring).
    """
    digest = hashlib.sha256()
    for path in sorted(root.rglob('*.py')):
        relative = path.relative_to(root)
        if relative.parts[0] == 'effects':
            continue
        digest.update(str(relative).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cached_kernel_files(root=PHYSICS_ROOT):
    """Return numba's cache files (index and data) of the physics core, and the markers."""
    return [path for pattern in ('*.nbi', '*.nbc', 'compiled/*')
            for path in root.rglob(f'__pycache__/{pattern}')]


def ensure_fresh_cache(root=PHYSICS_ROOT):
    """
    Delete the core's cached kernels if any source changed since they were compiled.

    Returns the number of files deleted.  The fingerprint of the sources is kept in
    ``physics/__pycache__``; a read-only installation (nothing can be written there) is left
    alone, its kernels being those its installer compiled.
    """
    fingerprint_path = root / _FINGERPRINT_FILE
    fingerprint = FINGERPRINT if root == PHYSICS_ROOT else source_fingerprint(root)
    try:
        if fingerprint_path.read_text().strip() == fingerprint:
            return 0
    except OSError:
        pass
    deleted = 0
    for path in cached_kernel_files(root):
        try:
            path.unlink()
            deleted += 1
        except OSError:
            pass
    try:
        fingerprint_path.parent.mkdir(exist_ok=True)
        temporary = fingerprint_path.with_suffix(f'.{os.getpid()}.tmp')
        temporary.write_text(fingerprint + '\n')
        os.replace(temporary, fingerprint_path)
    except OSError:
        pass
    return deleted


def compiled_marker(name, root=PHYSICS_ROOT):
    """Return the path of the marker that says `name`'s kernels are compiled for FINGERPRINT."""
    return root / '__pycache__' / 'compiled' / f'{name}.{FINGERPRINT[:16]}'


FINGERPRINT = source_fingerprint()
"""The fingerprint of the physics core's sources this process compiles and loads."""

ensure_fresh_cache()

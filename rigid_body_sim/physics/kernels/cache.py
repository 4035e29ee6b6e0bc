"""
Where the compiled kernels are cached: by what they are, not by where the package sits.

numba caches a compiled function beside its source file (``__pycache__``) or under
``NUMBA_CACHE_DIR`` in a folder named after the source's path, and checks the function's own
file only.  Both fail this package: every copy of it (a second clone, a colcon install, a
``pip install --target``) compiled its kernels again, and an edit to a helper in another
file (kernels/algebra.py, inlined into every kernel) left the cached kernels stale.  So the
kernels live in one folder per machine, named by what they are compiled from:

    <cache root>/kernels-<sources>-<cpu>/

- ``<sources>``: the SHA-256 of every source of the physics core but the effects (names
  and contents: a kernel may inline a helper from any of them), numba's, llvmlite's and
  Python's versions.  A changed source is a new folder: nothing stale can be found;
- ``<cpu>``: the CPU numba compiles for (``NUMBA_CPU_NAME``/``NUMBA_CPU_FEATURES`` or the
  host's name and features), so that a machine's kernels never load on another CPU.

Inside, numba's own files, one folder per package folder (``integrators/``, ``effects/``,
...; numba checks each function's own file by its content).  The effects are left out of
``<sources>``: the kernels reach an effect only through a Model's function pointers, never
inline its code, so a new or edited effect compiles its own small functions and no kernel
again; an effect's code may inline the toolkit (in ``<sources>``) and its own file.

An effect plugin's functions (a file outside the package: :func:`claim_file`) go to
``plugins/<its sources>/``, where ``<its sources>`` is the SHA-256 of the plugin's own
sources (:func:`plugin_source_key`: every ``*.py`` file of its top-level package, or the
module file alone) and of the name its module was imported as (numba's cached code imports
its module by name), so that a changed plugin, or a helper it inlines from its own package,
is compiled again and two versions of one plugin never share a file.  They are not sealed:
any process compiles a plugin when it first uses it, after the compile that sealed the
folder (numba writes each file whole and checks the plugin's file by its content).

The root is the first of: ``RIGID_BODY_SIM_CACHE_DIR``; ``NUMBA_CACHE_DIR``/rigid_body_sim
(the user chose where numba caches); ``XDG_CACHE_HOME``/rigid_body_sim, else
``~/.cache/rigid_body_sim``.  If it cannot be written, the kernels compile in memory in
every process (minutes) and :data:`PROBLEM` says, in one line, what to set.

Trust: a compile (the ``compile`` command, tools/compile.py) writes the folder under an
exclusive lock, then seals it: ``manifest.json`` records each file's size and SHA-256, and
a marker per job (``compiled/<job>``) says what is complete.  :func:`verify` re-hashes the
sealed files (cheap beside loading them); a file that differs is damaged (a truncated
copy, a disk error), is dropped with the markers, and compiled again by a compile in another
process: a damaged object file would abort the process that loads it (LLVM reads it
unchecked).  Folders of other sources are removed once unused for :data:`KEEP_DAYS` days.

numba is told to ask :class:`KernelCacheLocator` first (numba's ``CACHE_LOCATOR_CLASSES``
setting, documented in its caching notes), for this package's files only; any other
function keeps numba's own locators.
"""

from __future__ import annotations

from collections.abc import Callable
from collections.abc import Iterable
from collections.abc import Iterator
import contextlib
import errno
import fcntl
import hashlib
import json
import os
from pathlib import Path
import pickle
import shutil
import sys
import time
from typing import Any

import llvmlite
import llvmlite.binding
import numba
from numba.core import caching

__all__ = ['KernelCacheLocator', 'PHYSICS_ROOT', 'SOURCES', 'CACHE_DIR_VARIABLE', 'PROBLEM',
           'cache_root', 'kernel_dir', 'install_locator', 'source_key', 'cpu_key',
           'plugin_source_key', 'PLUGINS_FOLDER',
           'caching_enabled',
           'compile_lock', 'seal', 'verify', 'marker', 'is_marked', 'mark', 'unmark_all',
           'drop', 'drop_unsealed', 'prune', 'clear', 'claim_file', 'measured_seconds',
           'touch_used', 'KEEP_DAYS']

PHYSICS_ROOT = Path(__file__).resolve().parent.parent
"""The directory of the physics core, whose sources the kernels are compiled from."""
CACHE_DIR_VARIABLE = 'RIGID_BODY_SIM_CACHE_DIR'
"""Environment variable: the folder to cache the compiled kernels in (see the module)."""
KEEP_DAYS = 30
"""A folder of other sources' kernels unused this long is removed (by the next compile)."""

PLUGINS_FOLDER = 'plugins'
"""The folder of a kernel folder that holds the effect plugins' compiled functions."""

_MANIFEST = 'manifest.json'
_LOCK = 'compile.lock'
_MARKERS = 'compiled'
_LAST_USED = 'last-used'
_CACHE_SUFFIXES = ('.nbi', '.nbc')


def source_key(root: Path = PHYSICS_ROOT) -> str:
    """
    Return the SHA-256 (hex) of what the kernels are compiled from.

    The names and contents of the ``*.py`` files under `root` but ``effects/`` (see the
    module docstring), and the versions of numba, llvmlite and Python.
    """
    digest = hashlib.sha256()
    for version in (numba.__version__, llvmlite.__version__, sys.version):
        digest.update(version.encode() + b'\0')
    for path in sorted(root.rglob('*.py')):
        relative = path.relative_to(root)
        if relative.parts[0] == 'effects':
            continue
        digest.update(str(relative).encode() + b'\0')
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cpu_key() -> str:
    """Return a short hash of the CPU numba compiles for (its name and features)."""
    config = numba.config
    name = config.CPU_NAME or llvmlite.binding.get_host_cpu_name()
    features = (config.CPU_FEATURES if config.CPU_FEATURES is not None
                else llvmlite.binding.get_host_cpu_features().flatten())
    return hashlib.sha256(f'{name}\0{features}'.encode()).hexdigest()[:12]


def cache_root() -> Path:
    """Return the folder the kernel folders live in (see the module docstring)."""
    explicit = os.environ.get(CACHE_DIR_VARIABLE)
    if explicit:
        return Path(explicit).expanduser()
    numba_dir = os.environ.get('NUMBA_CACHE_DIR')
    if numba_dir:
        return Path(numba_dir).expanduser() / 'rigid_body_sim'
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(base) / 'rigid_body_sim'


SOURCES = source_key()
"""The key of the sources this process compiles and loads (read once, at import)."""


def kernel_dir(sources: str | None = None) -> Path:
    """Return the folder of the kernels of `sources` (default: this process's) for this CPU."""
    return cache_root() / f'kernels-{(sources or SOURCES)[:20]}-{cpu_key()}'


def _usable(folder: Path) -> str | None:
    """Return None if `folder` can be created and written, else the reason (one phrase)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f'.probe-{os.getpid()}'
        probe.write_bytes(b'')
        probe.unlink()
    except OSError as error:
        return f'{folder}: {error.strerror or error}'
    return None


def _problem() -> str | None:
    reason = _usable(kernel_dir())
    if reason is None:
        return None
    return (f'rigid_body_sim: cannot cache the compiled kernels ({reason}): every process '
            f'compiles them again, for minutes; set {CACHE_DIR_VARIABLE} to a writable folder '
            '(docs/install.md, "Where the kernels are cached")')


PROBLEM = _problem()
"""None, or the one line that says why the kernels cannot be cached and what to set."""


def caching_enabled() -> bool:
    """Return whether compiled kernels are cached (False: see :data:`PROBLEM`)."""
    return PROBLEM is None


_claimed: dict[str, tuple[str, Path] | None] = {}


def claim_file(path: str) -> None:
    """
    Cache the compiled functions of the source file `path` with the kernels.

    For an effect written outside the package (its wrench may inline the toolkit, so its
    cache must follow the toolkit's sources): the effects' decorators claim their file.
    Its folder is keyed by its own sources too (:func:`plugin_source_key`).
    """
    _claimed.setdefault(os.path.realpath(path), None)


def plugin_source_key(path: str | Path) -> tuple[str, Path]:
    """
    Return (SHA-256 hex of a plugin's sources, the folder of `path` relative to them).

    The sources: the names and contents of every ``*.py`` file of the top-level package
    `path` is in (its folder and the folders above it with an ``__init__.py``), or of the
    file alone if its folder is no package (a module file beside a scene).
    """
    file = Path(path)
    root = file.parent
    if (root / '__init__.py').is_file():
        while (root.parent / '__init__.py').is_file() and root.parent != root:
            root = root.parent
        files = sorted(root.rglob('*.py'))
    else:
        files = [file]
    digest = hashlib.sha256()
    for source in files:
        digest.update(str(source.relative_to(root)).encode() + b'\0')
        digest.update(source.read_bytes())
    return digest.hexdigest(), file.parent.relative_to(root)


def _plugin_folder(real: str, module: str | None) -> Path:
    """
    Return the folder (relative to the kernel folder) of the claimed file `real`.

    Keyed by the plugin's sources and the name its module was imported as: numba's cached
    code imports its module by that name when it loads, so a file imported under two names
    (a scene's plugin file, then ``import`` of the same file) keeps two caches.
    """
    sources = _claimed.get(real)
    if sources is None:
        sources = _claimed[real] = plugin_source_key(real)
    key, relative = sources
    named = hashlib.sha256(f'{key}\0{module}'.encode()).hexdigest()
    return Path(PLUGINS_FOLDER) / named[:20] / relative


class KernelCacheLocator(caching.InTreeCacheLocator):
    """
    numba's cache locator for this package's compiled functions (see the module docstring).

    A function in the physics core is cached under :func:`kernel_dir`, in the folder of its
    file relative to the core (one location whatever the package's path); a function of a
    claimed file (:func:`claim_file`) under ``plugins/<its sources>/`` (see the module).  The
    freshness stamp is numba's own: the content of the function's file.  Any other function
    is left to numba's other locators.
    """

    def __init__(self, py_func: Callable[..., Any], py_file: str) -> None:
        super().__init__(py_func, py_file)
        real = os.path.realpath(py_file)
        path = Path(real)
        try:
            relative = path.parent.relative_to(PHYSICS_ROOT)
        except ValueError:
            relative = _plugin_folder(real, getattr(py_func, '__module__', None))
        self._kernel_folder = str(kernel_dir() / relative)

    def get_cache_path(self) -> str:
        """Return the folder this function's cache files go to."""
        return self._kernel_folder

    @classmethod
    def from_function(cls, py_func: Callable[..., Any],
                      py_file: str) -> KernelCacheLocator | None:
        """Return a locator for a function of this package, else None (numba's decide)."""
        if not caching_enabled() or not os.path.isfile(py_file):
            return None
        real = os.path.realpath(py_file)
        if not (real.startswith(str(PHYSICS_ROOT) + os.sep) or real in _claimed):
            return None
        locator = cls(py_func, py_file)
        locator.ensure_cache_path()
        return locator


# numba's own locators, in its default order (its caching notes list them).
_NUMBA_LOCATORS = ('UserProvidedCacheLocator,InTreeCacheLocator,UserWideCacheLocator,'
                   'IPythonCacheLocator,ZipCacheLocator')


def install_locator() -> None:
    """
    Tell numba to ask :class:`KernelCacheLocator` first, then its own locators.

    numba reads the setting (``NUMBA_CACHE_LOCATOR_CLASSES``) each time a function with
    ``cache=True`` is decorated; the package's decorators call this first.  Not set in the
    environment: a child process without this package would fail to import the class.
    """
    ours = f'{__name__}.{KernelCacheLocator.__name__}'
    current = numba.config.CACHE_LOCATOR_CLASSES
    if current.split(',')[0].strip() == ours:
        return
    rest = current or _NUMBA_LOCATORS
    numba.config.CACHE_LOCATOR_CLASSES = f'{ours},{rest}'


# -- the compile lock, the seal and the markers


@contextlib.contextmanager
def compile_lock(folder: Path | None = None,
                 waiting: Callable[[Path], object] | None = None) -> Iterator[Path]:
    """
    Hold the exclusive lock of a kernel folder while compiling into it.

    Two compiles of the same kernels at once: the second waits (`waiting`, if given, is
    called once with the folder first) and then finds them compiled.
    """
    folder = folder or kernel_dir()
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / _LOCK, 'a') as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            if error.errno not in (errno.EAGAIN, errno.EACCES):
                raise
            if waiting is not None:
                waiting(folder)
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield folder
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _cache_files(folder: Path) -> list[Path]:
    """Return the kernels' cache files of the folder (the plugins' are not sealed)."""
    return sorted(path for path in folder.rglob('*')
                  if path.suffix in _CACHE_SUFFIXES and path.is_file()
                  and path.relative_to(folder).parts[0] != PLUGINS_FOLDER)


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_atomically(path: Path, text: str) -> None:
    temporary = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    temporary.write_text(text)
    os.replace(temporary, path)


def _manifest(folder: Path) -> dict[str, list[Any]]:
    try:
        return json.loads((folder / _MANIFEST).read_text())
    except (OSError, ValueError):
        return {}


def seal(folder: Path | None = None) -> int:
    """Record the size and SHA-256 of every cache file in the folder (under the lock)."""
    folder = folder or kernel_dir()
    entries = {str(path.relative_to(folder)): [path.stat().st_size, _digest(path)]
               for path in _cache_files(folder)}
    _write_atomically(folder / _MANIFEST, json.dumps(entries, indent=0, sort_keys=True))
    return len(entries)


def _index_readable(path: Path) -> bool:
    """Return whether an index file (numba's: pickles one after another) reads to its end."""
    try:
        with open(path, 'rb') as handle:
            size = os.fstat(handle.fileno()).st_size
            while handle.tell() < size:
                pickle.load(handle)
    except Exception:  # noqa: B902 (any failure to read it back is damage)
        return False
    return True


def verify(folder: Path | None = None) -> list[str]:
    """
    Return the sealed files of the folder that are missing or damaged (relative paths).

    A data file (``.nbc``: object code, which LLVM loads unchecked) must be as sealed.  An
    index (``.nbi``) numba rewrites when it adds a compiled signature (a Python caller's new
    argument types): one that differs from its seal must still read to its end.  Files
    numba wrote since the seal are not checked.
    """
    folder = folder or kernel_dir()
    damaged = []
    for name, (size, digest) in _manifest(folder).items():
        path = folder / name
        try:
            if path.stat().st_size == size and _digest(path) == digest:
                continue
        except OSError:
            damaged.append(name)
            continue
        if not (path.suffix == '.nbi' and _index_readable(path)):
            damaged.append(name)
    return damaged


def drop(names: Iterable[str], folder: Path | None = None) -> None:
    """Delete the named cache files and every marker (their jobs compile again)."""
    folder = folder or kernel_dir()
    for name in names:
        with contextlib.suppress(OSError):
            (folder / name).unlink()
    unmark_all(folder)


def drop_unsealed(folder: Path | None = None) -> int:
    """Delete the cache files the seal does not know (a compile whose sources changed)."""
    folder = folder or kernel_dir()
    sealed = set(_manifest(folder))
    count = 0
    for path in _cache_files(folder):
        if str(path.relative_to(folder)) not in sealed:
            with contextlib.suppress(OSError):
                path.unlink()
                count += 1
    return count


def marker(job: str, folder: Path | None = None) -> Path:
    """Return the marker file that says `job`'s kernels are compiled and sealed."""
    return (folder or kernel_dir()) / _MARKERS / job


def is_marked(job: str, folder: Path | None = None) -> bool:
    """Return whether `job`'s kernels are compiled and sealed in the folder."""
    return marker(job, folder).exists()


def mark(job: str, seconds: float, folder: Path | None = None) -> None:
    """Mark `job` compiled; the marker holds the CPU seconds it took (estimates read it)."""
    path = marker(job, folder)
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_atomically(path, f'{seconds:.3f}\n')


def unmark_all(folder: Path | None = None) -> None:
    """Delete every marker of the folder."""
    shutil.rmtree((folder or kernel_dir()) / _MARKERS, ignore_errors=True)


def measured_seconds(job: str) -> float | None:
    """
    Return the CPU seconds `job` took to compile on this machine, or None if never measured.

    From this folder's marker or, for sources compiled before (any kernel folder of this
    CPU under the root), the most recent one: so estimates follow the machine's speed.
    """
    candidates = [marker(job)]
    try:
        folders = sorted(cache_root().glob(f'kernels-*-{cpu_key()}'),
                         key=lambda folder: folder.stat().st_mtime, reverse=True)
        candidates += [marker(job, folder) for folder in folders]
    except OSError:
        pass
    for path in candidates:
        try:
            return float(path.read_text())
        except (OSError, ValueError):
            continue
    return None


def touch_used(folder: Path | None = None) -> None:
    """Stamp the folder as used now (pruning keeps what is used)."""
    folder = folder or kernel_dir()
    with contextlib.suppress(OSError):
        (folder / _LAST_USED).touch()


def prune(keep_days: float = KEEP_DAYS) -> list[Path]:
    """Remove the kernel folders of other sources unused for `keep_days` days; return them."""
    removed = []
    now = time.time()
    current = kernel_dir()
    for folder in cache_root().glob('kernels-*'):
        if folder == current or not folder.is_dir():
            continue
        stamp = folder / _LAST_USED
        try:
            used = stamp.stat().st_mtime if stamp.exists() else folder.stat().st_mtime
        except OSError:
            continue
        if now - used > keep_days * 86400:
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    return removed


def clear() -> int:
    """Remove every cached kernel folder under the root; return how many."""
    folders = [folder for folder in cache_root().glob('kernels-*') if folder.is_dir()]
    for folder in folders:
        shutil.rmtree(folder, ignore_errors=True)
    return len(folders)


install_locator()

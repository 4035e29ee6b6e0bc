"""
Effect plugins: effects declared outside this package, found without an edit to it.

A plugin is a Python module with effect classes decorated by ``register_effect``, exactly
as a built-in effect's module (:mod:`.registry` says what an effect provides).  Two routes
bring one in:

- an installed distribution declares each effect under the entry-point group
  :data:`ENTRY_POINT_GROUP` (``rigid_body_sim.effects``), the entry point's name the
  effect's name and its value the class (``anchor_spring = my_effects.spring:AnchorSpring``).
  :data:`~.registry.EFFECTS` loads the plugin of a name the first time it is asked for it
  (a scene naming it), and every plugin when it is listed (``rigid-body-sim scenes
  --effects``); importing the package loads none;
- a scene names module files (its ``plugins:`` key, paths relative to the scene file):
  :func:`load_effect_file` imports each once per process.

Every effect a plugin registers is checked before it can be used (:func:`check_effect`):
it is an :class:`~.registry.Effect`, built from its ``example`` parameters its compiled
wrench and flow compile for their signatures (:func:`~..kernels.model.wrench_term`,
:func:`~..kernels.model.flow_function`) and give finite numbers on a tumbling, moving box.
A plugin that fails (an import error, a wrong signature, a non-finite wrench) is one line
naming it and what is wrong, never a traceback: an entry point's line is in
:func:`problems` and ``EFFECTS.problems`` (the other plugins still load); a module file's
is the :class:`PluginError` raised.

The compiled functions of a plugin are cached with the kernels, keyed by the plugin's own
sources (:func:`..kernels.cache.claim_file`): they compile once per machine and again
only when the plugin or the physics core changes.  A plugin's compiled code may call the
compiled toolkit (``rigid_body_sim.physics.kernels``) and its own package's code.
"""

from __future__ import annotations

from collections.abc import Callable
from collections.abc import Iterable
import hashlib
import importlib.metadata
import importlib.util
import inspect
import math
from pathlib import Path
import re
import sys
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from .registry import create_effect
from .registry import Effect
from .registry import EFFECTS
from ..body import RigidBody
from ..kernels import LazyKernel
from ..kernels.model import FLOW_SIGNATURE
from ..kernels.model import TERM_SIGNATURE
from ..state import State
from ...text import one_line

__all__ = ['ENTRY_POINT_GROUP', 'PluginError', 'check_effect', 'load_effect_file',
           'problems']

ENTRY_POINT_GROUP = 'rigid_body_sim.effects'
"""The entry-point group a distribution declares its effects under (name: the effect's)."""

_MESSAGE_LIMIT = 400

_attempted: set[tuple[str, str]] = set()
_problems: list[str] = []
_files: dict[Path, tuple[str, tuple[str, ...]]] = {}


class PluginError(ValueError):
    """A plugin that cannot be used: the message is one line naming it and what is wrong."""


def problems() -> list[str]:
    """Return the lines of the entry-point plugins that did not load in this process."""
    return list(_problems)


# -- the check of an effect


def _sample_body_and_state() -> tuple[RigidBody, State]:
    """Return a box and a state that moves, turns and is off the origin (SI, world frame)."""
    body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
    state = State.from_velocity(body, rotation=(0.1, 0.2, 0.3, math.sqrt(0.86)),
                                position=(0.3, -0.2, 0.1), velocity=(0.5, 0.1, -0.2),
                                angular_velocity_body=(0.1, 2.0, 0.1))
    return body, state


def _first_line(error: BaseException) -> str:
    """Return the line of an exception that says what is wrong (numba's first detail)."""
    text = re.sub(r'\x1b\[[0-9;]*m', '', str(error))
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    lines = [line for line in lines if not line.startswith(('Failed in ', 'During: '))]
    return f'{type(error).__name__}: {lines[0] if lines else ""}'.rstrip(': ')


def _compiled(function: object, signature: object, attribute: str, decorator: str,
              cls: type[Effect]) -> Callable[..., Any]:
    """Return the compiled `function`, or raise ValueError saying why it is not one."""
    if not (isinstance(function, LazyKernel) and function.signature == signature):
        raise ValueError(f'{attribute} of {cls.__name__} is not declared with @{decorator} '
                         f'(rigid_body_sim.physics.kernels.model)')
    try:
        return function.dispatcher
    except Exception as error:  # noqa: B902 (numba's errors have no one base)
        raise ValueError(f'{attribute} {function.__name__} does not compile as '
                         f'{_SIGNATURES[decorator]}: {_first_line(error)}') from None


_SIGNATURES = {'wrench_term': '(state, time, parameters) -> (Fx, Fy, Fz, tx, ty, tz)',
               'flow_function': '(state, parameters, duration), in place'}


def _finite(values: ArrayLike, what: str) -> NDArray[np.float64]:
    array = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(array)):
        raise ValueError(f'{what} is not finite: {array.tolist()}')
    return array


def check_effect(name: str, cls: object) -> None:
    """
    Check that `cls`, registered as effect `name`, can be used; ValueError says why not.

    Built from its ``example`` on a sample body and state (a 1 kg box, turning, moving, off
    the origin): its compiled wrench and flow compile for their signatures and give finite
    numbers, and its potential energy and damping rate, if it has them, are finite.
    """
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise ValueError(f'{cls!r} is not an Effect class (rigid_body_sim.physics.effects.'
                         'registry.Effect)')
    if not isinstance(cls.example, dict):
        raise ValueError(f'{cls.__name__} has no example parameters (example = {{...}}, a '
                         'dict: the tests and this check build it from them)')
    try:
        effect = create_effect(name, cls.example)
    except Exception as error:  # noqa: B902 (a plugin's constructor may raise anything)
        raise ValueError(f'its example {cls.example!r} is refused: {_first_line(error)}') \
            from None
    body, state = _sample_body_and_state()
    values = np.concatenate([state.quaternion, state.position, state.linear_momentum,
                             state.angular_momentum])
    try:
        if cls.compiled_wrench is not None:
            term = _compiled(cls.compiled_wrench, TERM_SIGNATURE, 'compiled_wrench',
                             'wrench_term', cls)
            parameters = np.ascontiguousarray(effect.wrench_parameters(body), dtype=float)
            wrench = term(values.copy(), 0.5, parameters.reshape(-1))
            _finite(wrench, f'its wrench at its example ({cls.example!r})')
        if cls.compiled_flow is not None:
            flow = _compiled(cls.compiled_flow, FLOW_SIGNATURE, 'compiled_flow',
                             'flow_function', cls)
            parameters = np.ascontiguousarray(effect.flow_parameters(body), dtype=float)
            after = values.copy()
            flow(after, parameters.reshape(-1), 0.01)
            _finite(after, f'the state after its flow at its example ({cls.example!r})')
        if hasattr(effect, 'potential_energy'):
            _finite(effect.potential_energy(body, state), 'its potential energy')
        if hasattr(effect, 'damping_rate'):
            rate, _ = effect.damping_rate(body)
            if not (math.isfinite(rate) and rate >= 0.0):
                raise ValueError(f'its damping rate is {rate!r} 1/s: not finite and >= 0')
    except ValueError:
        raise
    except Exception as error:  # noqa: B902 (a plugin's methods may raise anything)
        raise ValueError(_first_line(error)) from None


# -- loading


def _registered() -> set[str]:
    return set(EFFECTS.registered_names())


def _take_checked(label: str, before: set[str]) -> list[str]:
    """
    Check every effect registered since `before`; drop them all if one fails.

    Returns the new names; raises PluginError (one line starting with `label`).
    """
    names = sorted(_registered() - before)
    for name in names:
        try:
            check_effect(name, EFFECTS[name])
        except ValueError as error:
            _forget(names)
            raise PluginError(one_line(f'{label}: effect {name!r}: {error}',
                                       _MESSAGE_LIMIT)) from None
    return names


def _forget(names: Iterable[str]) -> None:
    for name in names:
        if EFFECTS.registered(name):
            del EFFECTS[name]


def _import_failure(label: str, error: BaseException) -> PluginError:
    return PluginError(one_line(f'{label}: cannot import it: {_first_line(error)}',
                                _MESSAGE_LIMIT))


def _module_name(path: Path, digest: str) -> str:
    stem = re.sub(r'\W', '_', path.stem)
    return f'rigid_body_sim_plugin_{stem}_{digest[:12]}'


def load_effect_file(path: str | Path, shown: str | None = None) -> tuple[str, ...]:
    """
    Import the plugin module file `path` (once per process) and return its effects' names.

    `shown` is how messages name it (default: the path).  Raises PluginError, one line,
    if it is not a readable .py file, cannot be imported, registers no effect, or an
    effect it registers fails :func:`check_effect` (then none of its effects stays).
    """
    label = f'effect plugin {shown or path}'
    file = Path(path).expanduser()
    if file.suffix != '.py':
        raise PluginError(f'{label}: not a Python file (.py)')
    try:
        file = file.resolve()
        source = file.read_bytes()
    except (OSError, RuntimeError) as error:
        raise PluginError(one_line(f'{label}: cannot read it: '
                                   f'{getattr(error, "strerror", None) or error}',
                                   _MESSAGE_LIMIT)) from None
    digest = hashlib.sha256(source).hexdigest()
    known = _files.get(file)
    if known is not None:
        if known[0] != digest:
            raise PluginError(f'{label}: changed since this process imported it; start the '
                              'program again to load the new version')
        return known[1]
    name = _module_name(file, digest)
    before = _registered()
    spec = importlib.util.spec_from_file_location(name, file)
    if spec is None or spec.loader is None:
        raise PluginError(f'{label}: cannot import it: no module loader for the file')
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as error:  # noqa: B902 (a plugin's import may raise anything)
        sys.modules.pop(name, None)
        _forget(_registered() - before)
        raise _import_failure(label, error) from None
    try:
        names = _take_checked(label, before)
    except PluginError:
        sys.modules.pop(name, None)
        raise
    if not names:
        sys.modules.pop(name, None)
        raise PluginError(f'{label}: registers no effect (decorate an Effect class with '
                          "@register_effect('name'))")
    _files[file] = (digest, tuple(names))
    return tuple(names)


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    """Return this group's entry points, each (name, value) once, in a stable order."""
    seen: set[tuple[str, str]] = set()
    found: list[importlib.metadata.EntryPoint] = []
    for entry_point in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        key = (entry_point.name, entry_point.value)
        if key not in seen:
            seen.add(key)
            found.append(entry_point)
    return sorted(found, key=lambda entry_point: entry_point.name)


def _entry_point_label(entry_point: importlib.metadata.EntryPoint) -> str:
    distribution = getattr(entry_point, 'dist', None)
    origin = '' if distribution is None else \
        f' of {distribution.metadata["Name"]} {distribution.version}'
    return f'effect plugin {entry_point.name!r} ({entry_point.value}{origin})'


def _load_entry_point(entry_point: importlib.metadata.EntryPoint) -> None:
    """Load one entry point; a failure is recorded as a problem line, never raised."""
    label = _entry_point_label(entry_point)
    before = _registered()
    try:
        loaded = entry_point.load()
    except Exception as error:  # noqa: B902 (a plugin's import may raise anything)
        _forget(_registered() - before)
        _record(entry_point.name, _import_failure(label, error))
        return
    try:
        if not (inspect.isclass(loaded) and issubclass(loaded, Effect)):
            raise PluginError(f'{label}: names {loaded!r}, not an Effect class')
        if getattr(loaded, 'effect_name', None) is None:
            if EFFECTS.registered(entry_point.name):
                raise PluginError(f'{label}: effect {entry_point.name!r} is registered '
                                  'already (built in, or by another plugin)')
            loaded.effect_name = entry_point.name
            EFFECTS[entry_point.name] = loaded
        elif loaded.effect_name != entry_point.name:
            raise PluginError(f'{label}: the class is registered as '
                              f'{loaded.effect_name!r}; name the entry point so')
        _take_checked(label, before)
    except PluginError as error:
        _forget(_registered() - before)
        _record(entry_point.name, error)


def _record(name: str, error: BaseException) -> None:
    line = one_line(str(error), _MESSAGE_LIMIT)
    EFFECTS.problems[name] = line
    if line not in _problems:
        _problems.append(line)


def discover(name: str | None = None) -> None:
    """Load the entry points of effect `name` (None: every one not tried yet)."""
    try:
        entry_points = _entry_points()
    except Exception as error:  # noqa: B902 (a broken installed distribution's metadata)
        _record(name or '*', PluginError(f'effect plugins: cannot read the installed '
                                         f'entry points: {_first_line(error)}'))
        return
    for entry_point in entry_points:
        key = (entry_point.name, entry_point.value)
        if (name is None or entry_point.name == name) and key not in _attempted:
            _attempted.add(key)
            _load_entry_point(entry_point)


EFFECTS.set_discover(discover)

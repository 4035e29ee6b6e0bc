"""
A sweep's spec: which runs to make, read from YAML and expanded into content-addressed runs.

A spec (``config/sweeps/*.yaml`` holds examples; ``rigid-body-sim sweep --help`` the keys)
names scenes, the run axes (integrators, rates, tolerances, substeps, durations), fixed
changes to the scenes (``set``), a grid of scene values (``grid``) and random draws of
scene values (``random``: a count and a seed).  Every combination of the axes and of the
grid is run once per draw, so the run count is the product of their lengths times the
count.

A scene value is named by its key path in the scene's schema (``body.mass``,
``initial.angular_velocity_body``, ``imu.seed``, ...; ``effects`` as a whole list): a run's
scene is the scene file's mapping with these values put in, validated as a scene file is
(:func:`rigid_body_sim.scenes.parse_scene`), so every unit and frame is the scene schema's.

Content addressing.  A run's id is a digest of everything that makes its output: the
resolved scene mapping (the file's content, not its name, so an edited scene is a new run),
the duration, the substeps and whether and how its bag is written.  A re-run of a spec finds
its finished runs by id; the same run reached through another spec is found too.

Random draws.  Draw k (k = 0 .. count - 1) comes from numpy's generator seeded with
(seed, k), the same for every scene, integrator and grid point: the methods of a sweep meet
the same initial states (common random numbers), and a larger count keeps the runs of a
smaller one.
"""

from dataclasses import dataclass
import hashlib
import itertools
import json
import math
from pathlib import Path

import numpy as np

from ..paths import config_dir
from ..physics import INTEGRATORS
from ..scenes import load_scene
from ..scenes import parse_scene
from ..scenes import read_scene_yaml

__all__ = ['DISTRIBUTIONS', 'Run', 'SCENE_SECTIONS', 'SPEC_KEYS', 'Spec', 'find_spec',
           'load_spec', 'parse_spec', 'sweep_names']

SPEC_KEYS = ('description', 'scenes', 'integrators', 'rates', 'tolerances', 'substeps',
             'durations', 'bags', 'storage', 'set', 'grid', 'random')
"""The keys a spec may have; anything else is an error."""
_RANDOM_KEYS = ('count', 'seed', 'draw')
SCENE_SECTIONS = ('body', 'initial', 'imu', 'effects')
"""The scene sections a spec may change: ``<section>.<key>``, or ``effects`` whole."""
DISTRIBUTIONS = ('uniform', 'normal', 'log_uniform', 'integers', 'choice', 'uniform_rotation')
"""The distributions of ``random.draw``: each a one-key mapping, ``{uniform: [low, high]}``."""
STORAGES = ('mcap', 'sqlite3')
MAX_RUNS = 10_000_000
"""The most runs one spec may expand to (ids alone then take about a GB in the driver)."""
_ID_LENGTH = 24
# Keys of a body section that give its shape; an inertia replaces them (as with_overrides).
_SHAPE_KEYS = ('shape', 'size', 'radius', 'height', 'semi_axes')
_EXCLUSIVE = {'angular_velocity_body': 'angular_velocity_world',
              'angular_velocity_world': 'angular_velocity_body'}


def sweep_names():
    """Return the names of the example specs (``config/sweeps/*.yaml``), sorted."""
    return sorted(path.stem for path in (config_dir() / 'sweeps').glob('*.yaml'))


def find_spec(name_or_path):
    """Return the file of a spec given by example name (``config/sweeps``) or by path."""
    text = str(name_or_path)
    if '/' in text or text.endswith(('.yaml', '.yml')):
        path = Path(text).expanduser()
        if not path.is_file():
            raise ValueError(f'sweep spec {text!r} is not a file')
        return path
    path = config_dir() / 'sweeps' / f'{text}.yaml'
    if not path.is_file():
        raise ValueError(f'unknown sweep spec {text!r}; examples: {", ".join(sweep_names())} '
                         '(or give a path to a .yaml file)')
    return path


def load_spec(name_or_path):
    """Read and validate a spec file (an example's name or a path); return the Spec."""
    path = find_spec(name_or_path)
    try:
        with open(path, encoding='utf-8') as stream:
            data = read_scene_yaml(stream, str(path))
    except OSError as error:
        raise ValueError(f'{path}: cannot read: {error.strerror}') from None
    return parse_spec(data, str(path), base=path.parent)


@dataclass(frozen=True)
class Run:
    """
    One run of a sweep: a scene with its values put in, how long and how to write it.

    Attributes
    ----------
    run_id : str
        The digest that names the run's output (see the module docstring).
    index : int
        Its place in the spec's order.
    base : dict
        The scene file's validated mapping (shared by every run of that scene: not copied).
    source : str
        Where the scene came from, for messages.
    changes : dict
        Key path -> value put into the mapping (``rate``, ``tolerance``, ``integrator`` at
        the top; ``body.mass`` ...), in the spec's order.
    duration : float
        Simulated s, a whole number of ticks at the rate.
    substeps : int
        Integrator steps per tick (the least under error control).
    bag_storage : str or None
        'mcap' or 'sqlite3': the run writes its bag; None: its row only.

    """

    run_id: str
    index: int
    base: dict
    source: str
    changes: dict
    duration: float
    substeps: int
    bag_storage: object

    def scene_data(self):
        """Return the run's scene mapping: the file's with the changes put in (a copy)."""
        return resolve(self.base, self.changes)

    def scene(self):
        """Return the run's validated Scene (ValueError naming the key path if it is not)."""
        return parse_scene(self.scene_data(), f'{self.source} (run {self.run_id})')

    def parameters(self):
        """Return what the spec chose for this run, as a JSON-ready dict."""
        values = dict(self.changes)
        values.update(duration=self.duration, substeps=self.substeps)
        return _plain(values)


def resolve(base, changes):
    """Return a copy of the scene mapping `base` with `changes` (key path -> value) put in."""
    data = json.loads(json.dumps(base))
    for path, value in changes.items():
        _put(data, path, value)
    return data


def _put(data, path, value):
    if '.' not in path:
        data[path] = _plain(value)
        return
    section, key = path.split('.', 1)
    mapping = data.get(section)
    if not isinstance(mapping, dict):
        mapping = data[section] = {}
    if section == 'body' and key == 'inertia':
        for shape_key in _SHAPE_KEYS:
            mapping.pop(shape_key, None)
    if section == 'initial' and key in _EXCLUSIVE:
        mapping.pop(_EXCLUSIVE[key], None)
    mapping[key] = _plain(value)


@dataclass(frozen=True)
class Spec:
    """
    A validated sweep spec (:func:`parse_spec` makes one); :meth:`runs` expands it.

    Attributes
    ----------
    source : str
        Where it came from, for messages.
    description : str
    scenes : list of Scene
        The scenes as their files give them.
    axes : dict
        integrators, rates, tolerances, substeps, durations: lists, None where the scene's
        own value is used (integrators, rates, tolerances).
    bags : bool
    storage : str
    fixed : dict
        ``set``: key path -> value.
    grid : dict
        key path -> list of values.
    count, seed : int
        Random draws per combination (1 and None without ``random``).
    draws : dict
        key path -> distribution mapping.

    """

    source: str
    description: str
    scenes: list
    axes: dict
    bags: bool
    storage: str
    fixed: dict
    grid: dict
    count: int
    seed: object
    draws: dict

    @property
    def run_count(self):
        """Return how many runs the spec makes."""
        per_scene = 1
        for name in ('integrators', 'rates', 'tolerances', 'substeps', 'durations'):
            values = self.axes[name]
            per_scene *= 1 if values is None else len(values)
        for values in self.grid.values():
            per_scene *= len(values)
        return self.count * per_scene * len(self.scenes)

    def integrators(self):
        """Return the integrators the runs use (to load on every worker)."""
        if self.axes['integrators'] is not None:
            return sorted(set(self.axes['integrators']))
        return sorted({scene.integrator for scene in self.scenes})

    def drawn(self, k):
        """Return draw k: key path -> value (empty without ``random``)."""
        if not self.draws:
            return {}
        generator = np.random.default_rng([self.seed, k])
        return {path: _sample(self.draws[path], generator) for path in sorted(self.draws)}

    def _points(self):
        """Yield (scene, changes without draws, duration, substeps) in the spec's order."""
        axes = self.axes
        grid_paths = list(self.grid)
        for scene in self.scenes:
            for integrator, rate, tolerance, substeps, duration in itertools.product(
                    *(axes[name] or [None] for name in (
                        'integrators', 'rates', 'tolerances', 'substeps', 'durations'))):
                top = {'integrator': integrator or scene.integrator,
                       'rate': scene.rate if rate is None else rate,
                       'tolerance': (scene.tolerance or 0.0) if tolerance is None
                       else tolerance}
                for values in itertools.product(*(self.grid[path] for path in grid_paths)):
                    changes = dict(top)
                    changes.update(self.fixed)
                    changes.update(zip(grid_paths, values))
                    yield scene, changes, duration, substeps or 1

    def runs(self):
        """Yield every Run in the spec's order (lazily: a large sweep is never all in memory)."""
        draws = [self.drawn(k) for k in range(self.count)] if self.count <= 10_000 else None
        index = 0
        for scene, changes, duration, substeps in self._points():
            for k in range(self.count):
                drawn = draws[k] if draws is not None else self.drawn(k)
                run_changes = dict(changes)
                run_changes.update(drawn)
                yield self._run(index, scene, run_changes, duration, substeps)
                index += 1

    def _run(self, index, scene, changes, duration, substeps):
        storage = self.storage if self.bags else None
        content = {'scene': _canonical(resolve(scene.data, changes)), 'duration': duration,
                   'substeps': substeps, 'bag': storage}
        digest = hashlib.sha256(json.dumps(content, sort_keys=True, separators=(',', ':'),
                                           allow_nan=False).encode()).hexdigest()
        return Run(digest[:_ID_LENGTH], index, scene.data, scene.source, changes,
                   float(duration), int(substeps), storage)

    def check(self):
        """
        Validate the first draw of every combination as a scene (ValueError if one fails).

        The other draws are checked where they run (a value drawn outside what a scene
        takes makes an ``invalid`` row); checking each here would cost the driver a scene's
        validation a run, in one process, for every run.
        """
        first = self.drawn(0)
        for scene, changes, duration, substeps in self._points():
            changes = dict(changes, **first)
            checked = parse_scene(resolve(scene.data, changes),
                                  f'{self.source}: scene {scene.name} with '
                                  f'{_describe(changes)}')
            _check_ticks(duration, checked.rate, self.source)


def _describe(changes):
    return ', '.join(f'{key} {value}' for key, value in changes.items())


def _check_ticks(duration, rate, source):
    # As simulate's: a bag has one state per tick, so the duration is a whole number of them.
    ticks = round(duration * rate)
    if ticks < 1 or abs(ticks - duration * rate) > 1e-6 * max(1.0, ticks):
        raise ValueError(f'{source}: durations: {duration:g} s is not a whole number of ticks '
                         f'at {rate:g} Hz (period {1.0 / rate:g} s)')


def parse_spec(data, source='<spec>', base=None):
    """
    Validate a spec's mapping (as from YAML) and return the :class:`Spec`.

    `base` is the folder relative scene paths are read from (the spec file's).  Every error
    is a ValueError naming `source` and the key.
    """
    def error(key, problem):
        return ValueError(f'{source}: {key}: {problem}' if key else f'{source}: {problem}')

    if not isinstance(data, dict):
        raise error('', 'expected a mapping of keys (see rigid-body-sim sweep --help)')
    for key in data:
        if key not in SPEC_KEYS:
            raise error(str(key), f'unknown key; a spec takes: {", ".join(SPEC_KEYS)}')
    for key in ('scenes', 'durations'):
        if key not in data:
            raise error(key, 'missing; a spec requires it')
    scenes = [_load(name, base, error) for name in _list(data['scenes'], 'scenes', error, str)]
    axes = {'integrators': _optional_list(data, 'integrators', error, str),
            'rates': _optional_list(data, 'rates', error, _number),
            'tolerances': _optional_list(data, 'tolerances', error, _number),
            'substeps': _optional_list(data, 'substeps', error, _whole),
            'durations': _list(data['durations'], 'durations', error, _number)}
    for name in axes['integrators'] or ():
        if name not in INTEGRATORS:
            raise error('integrators', f'unknown integrator {name!r}; valid: '
                                       f'{", ".join(sorted(INTEGRATORS))}')
    for duration in axes['durations']:
        if not 0.0 < duration <= 2.0 ** 31:
            raise error('durations', f'each must be above 0 and at most 2^31 s; got '
                                     f'{duration:g}')
    for substeps in axes['substeps'] or ():
        if not 1 <= substeps <= 100000:
            raise error('substeps', f'each must be 1 to 100000; got {substeps}')
    bags = data.get('bags', True)
    if not isinstance(bags, bool):
        raise error('bags', f'expected true or false, got {bags!r}')
    storage = data.get('storage', 'mcap')
    if storage not in STORAGES:
        raise error('storage', f'expected one of {", ".join(STORAGES)}, got {storage!r}')
    fixed = _mapping(data.get('set', {}), 'set', error)
    grid = _mapping(data.get('grid', {}), 'grid', error)
    for path, values in grid.items():
        grid[path] = _list(values, f'grid.{path}', error, None)
    for path in list(fixed) + list(grid):
        _check_path(path, error)
    count, seed, draws = 1, None, {}
    if 'random' in data:
        section = _mapping(data['random'], 'random', error)
        for key in section:
            if key not in _RANDOM_KEYS:
                raise error(f'random.{key}', f'unknown key; random takes: '
                                             f'{", ".join(_RANDOM_KEYS)}')
        for key in _RANDOM_KEYS:
            if key not in section:
                raise error(f'random.{key}', 'missing; random requires it')
        count = _whole(section['count'])
        seed = _whole(section['seed'])
        if count is None or count < 1:
            raise error('random.count', f'expected a whole number >= 1, got '
                                        f'{section["count"]!r}')
        if seed is None or seed < 0:
            raise error('random.seed', f'expected a whole number >= 0, got {section["seed"]!r}')
        draws = _mapping(section['draw'], 'random.draw', error)
        for path, distribution in draws.items():
            _check_path(path, error)
            _check_distribution(distribution, f'random.draw.{path}', error)
    description = data.get('description', '')
    if not isinstance(description, str):
        raise error('description', 'expected one line of text')
    overlap = (set(fixed) & set(grid)) | (set(fixed) & set(draws)) | (set(grid) & set(draws))
    if overlap:
        raise error('', f'{", ".join(sorted(overlap))}: given in more than one of set, grid '
                        'and random.draw')
    spec = Spec(source, description, scenes, axes, bags, storage, fixed, grid, count, seed,
                draws)
    if spec.run_count > MAX_RUNS:
        raise error('', f'{spec.run_count} runs; a spec makes at most {MAX_RUNS}')
    return spec


def _load(name, base, error):
    text = str(name)
    is_path = '/' in text or text.endswith(('.yaml', '.yml'))
    if is_path and base is not None and not Path(text).expanduser().is_absolute():
        text = str(Path(base) / text)
    try:
        return load_scene(text)
    except ValueError as problem:
        raise error('scenes', str(problem)) from None


def _number(value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value):
        return None
    return float(value)


def _whole(value):
    if isinstance(value, bool) or not isinstance(value, int):
        return None
    return value


def _list(value, key, error, convert):
    values = value if isinstance(value, list) else [value]
    if not values:
        raise error(key, 'empty; give at least one value')
    if convert is None:
        return values
    converted = [convert(item) for item in values]
    for item, result in zip(values, converted):
        if result is None:
            raise error(key, f'{item!r} is not a valid value here')
    return converted


def _optional_list(data, key, error, convert):
    return None if key not in data else _list(data[key], key, error, convert)


def _mapping(value, key, error):
    if not isinstance(value, dict):
        raise error(key, f'expected a mapping of keys, got {value!r}')
    return dict(value)


def _check_path(path, error):
    section = path.split('.', 1)[0]
    if section not in SCENE_SECTIONS or (section == 'effects') != ('.' not in path) \
            or path.count('.') > 1:
        raise error(path, f'not a scene value a spec may change: give <section>.<key> with '
                          f'a section of {", ".join(SCENE_SECTIONS[:-1])}, or effects whole')


def _check_distribution(distribution, key, error):
    if not isinstance(distribution, dict) or len(distribution) != 1 \
            or next(iter(distribution)) not in DISTRIBUTIONS:
        raise error(key, f'expected one of {", ".join(DISTRIBUTIONS)} as a one-key mapping, '
                         'e.g. {uniform: [low, high]}')
    name, arguments = next(iter(distribution.items()))
    if name == 'uniform_rotation':
        return
    if name == 'choice':
        if not isinstance(arguments, list) or not arguments:
            raise error(key, 'choice: expected a list of values')
        return
    if not isinstance(arguments, list) or len(arguments) != 2:
        raise error(key, f'{name}: expected [a, b] (scalars or lists of one length)')
    try:
        first, second = (np.asarray(argument, dtype=float) for argument in arguments)
    except (TypeError, ValueError):
        raise error(key, f'{name}: expected numbers or lists of numbers') from None
    if first.shape != second.shape or first.ndim > 1 or not (
            np.all(np.isfinite(first)) and np.all(np.isfinite(second))):
        raise error(key, f'{name}: expected two finite numbers or two lists of one length')
    if name in ('uniform', 'log_uniform', 'integers') and np.any(first > second):
        raise error(key, f'{name}: low above high')
    if name == 'log_uniform' and np.any(first <= 0.0):
        raise error(key, 'log_uniform: expected low > 0')
    if name == 'normal' and np.any(second < 0.0):
        raise error(key, 'normal: expected [mean, standard deviation >= 0]')
    if name == 'integers' and (first.ndim or not all(
            float(v).is_integer() for v in (first, second))):
        raise error(key, 'integers: expected two whole numbers')


def _sample(distribution, generator):
    """Return one value of `distribution` (a validated one-key mapping) from `generator`."""
    name, arguments = next(iter(distribution.items()))
    if name == 'uniform_rotation':
        # A normalised 4-D Gaussian is uniform over the rotations (x, y, z, w).
        quaternion = generator.standard_normal(4)
        return (quaternion / np.linalg.norm(quaternion)).tolist()
    if name == 'choice':
        return arguments[int(generator.integers(len(arguments)))]
    first, second = (np.asarray(argument, dtype=float) for argument in arguments)
    if name == 'uniform':
        value = generator.uniform(first, second)
    elif name == 'log_uniform':
        value = np.exp(generator.uniform(np.log(first), np.log(second)))
    elif name == 'normal':
        value = generator.normal(first, second)
    else:
        return int(generator.integers(int(first), int(second), endpoint=True))
    return np.asarray(value).tolist()


def _plain(value):
    """Return `value` with numpy scalars and arrays as Python numbers and lists."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(item) for item in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _canonical(value, key=None):
    """Return `value` with whole numbers as floats (1 and 1.0 are one scene), seeds aside."""
    if isinstance(value, dict):
        return {k: _canonical(item, k) for k, item in value.items()}
    if isinstance(value, list):
        return [_canonical(item, key) for item in value]
    if isinstance(value, int) and not isinstance(value, bool) and key != 'seed':
        return float(value)
    return value

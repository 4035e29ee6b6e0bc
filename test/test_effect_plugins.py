"""
Effect plugins: an effect of one's own reaches the tools and the node without an edit here.

Two routes (rigid_body_sim/physics/effects/plugins.py, docs/scenes.md): a module file a scene
names (``plugins:``, relative to the scene file), and an installed distribution's entry point
in the group ``rigid_body_sim.effects``.  The installed one is a real distribution: a package
and its ``.dist-info`` (METADATA, entry_points.txt) in a folder of its own put on PYTHONPATH,
as ``pip install --target`` lays it out; ``simulate`` and the node (over DDS) run a scene
naming its effect.  A broken plugin is one line naming it, and the rest still load.
"""

import json
import math
import os
from pathlib import Path
import subprocess
import sys
import textwrap
import time

from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import PACKAGE_ROOT
from node_harness import unique_namespace
import numpy as np
import pytest
from rigid_body_sim.physics.effects import EFFECTS
from rigid_body_sim.physics.kernels import cache
from rigid_body_sim.recording.motion import conserved_quantities
from rigid_body_sim.recording.motion import read_motion
from rigid_body_sim.scenes import load_scene

# A spring of stiffness k pulling the COM to the origin: from x = 1 m at rest, x = cos(w t)
# with w = sqrt(k / m).  NAME is the effect's name, FACTOR scales the wrench (nan: broken).
PLUGIN = '''\
"""A test plugin: a linear spring pulling the COM to the world origin."""

import numpy as np
from rigid_body_sim.physics.effects.registry import check_number, Effect, register_effect
from rigid_body_sim.physics.kernels.model import wrench_term


@wrench_term
def spring(state, time, parameters):
    k = parameters[0] * FACTOR
    return -k * state[4], -k * state[5], -k * state[6], 0.0, 0.0, 0.0


@register_effect('NAME')
class Spring(Effect):
    """A linear spring pulling the COM to the world origin (a test plugin)."""

    compiled_wrench = staticmethod(spring)
    reads_state = True
    exerts_torque = False
    conserves = ('angular_momentum', 'rotational_energy')
    units = {'stiffness': 'N/m'}
    example = {'stiffness': 2.0}

    def __init__(self, stiffness=1.0):
        self.stiffness = check_number(stiffness, 'stiffness', 'N/m', positive=True)

    def wrench_parameters(self, body):
        return np.array([self.stiffness])
'''

SCENE = """\
name: spring_box
description: a box on a spring to the origin
{plugins}body: {{mass: 1.0, shape: box, size: [0.3, 0.2, 0.1]}}
initial: {{position: [1.0, 0.0, 0.0], angular_velocity_body: [0.1, 3.0, 0.1]}}
effects:
  - {name}: {{stiffness: 4.0}}
"""
STIFFNESS = 4.0  # N/m, on 1 kg: w = 2 rad/s


def plugin_source(name, factor='1.0', replace=()):
    """Return the plugin module's source for effect `name` (`replace`: (old, new) edits)."""
    text = PLUGIN.replace('NAME', name).replace('FACTOR', factor)
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    return text


def write_scene(folder, effect, plugins=None):
    """Write a scene naming `effect` (and the plugin files `plugins`); return its path."""
    listed = '' if plugins is None else f'plugins: {json.dumps(plugins)}\n'
    path = Path(folder) / f'{effect}.yaml'
    path.write_text(SCENE.format(plugins=listed, name=effect))
    return path


def install_distribution(site, distribution, package, entry_points):
    """
    Lay out an installed distribution in `site`, as pip install --target does.

    `package`: {module file relative to site: source}; `entry_points`: {effect name:
    'module:Class'} in the group rigid_body_sim.effects.
    """
    for relative, source in package.items():
        path = Path(site) / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(source)
    info = Path(site) / f'{distribution}-1.0.dist-info'
    info.mkdir(parents=True)
    (info / 'METADATA').write_text(f'Metadata-Version: 2.1\nName: {distribution}\n'
                                   'Version: 1.0\n')
    lines = ''.join(f'{name} = {value}\n' for name, value in entry_points.items())
    (info / 'entry_points.txt').write_text(f'[rigid_body_sim.effects]\n{lines}')
    (info / 'RECORD').write_text('')


def environment_with(site):
    """Return this process's environment with `site` (and the package) on PYTHONPATH."""
    variables = dict(os.environ)
    variables['PYTHONPATH'] = os.pathsep.join(
        [str(site), str(PACKAGE_ROOT), *filter(None, [os.environ.get('PYTHONPATH')])])
    return variables


def run_cli(arguments, site=None, cwd=PACKAGE_ROOT):
    """Run ``rigid-body-sim`` in a process of its own; return the CompletedProcess."""
    return subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', *arguments],
                          capture_output=True, text=True, timeout=600, cwd=cwd,
                          env=environment_with(site or PACKAGE_ROOT))


def assert_spring_motion(bag, duration):
    """Check the bag's COM follows x = cos(2 t) of the spring (and is not at rest)."""
    motion = read_motion(bag)
    assert motion.time[-1] == pytest.approx(duration)
    expected = np.cos(math.sqrt(STIFFNESS) * motion.time)
    np.testing.assert_allclose(motion.position[:, 0], expected, atol=1e-3)
    assert motion.position[:, 0].min() < 0.0


# -- a module file beside the scene


def test_a_scene_names_a_plugin_file_beside_it_and_simulate_runs_its_effect(tmp_path):
    (tmp_path / 'spring.py').write_text(plugin_source('file_spring'))
    scene = write_scene(tmp_path, 'file_spring', ['spring.py'])
    bag = tmp_path / 'bag'
    # From another working directory: the plugin's path is relative to the scene file.
    result = run_cli(['simulate', '--scene', str(scene), '--duration', '2', '--bag', str(bag),
                      '--quiet'])
    assert result.returncode == 0, result.stderr
    assert_spring_motion(bag, 2.0)
    # The plot learns what the plugin's effect conserves from the plugin itself (the file
    # the bag records): a force through the COM keeps T_rot and |L|.
    title, _ = conserved_quantities(read_motion(bag))
    assert title.startswith('Conserved without torque about the COM'), title
    plot = run_cli(['plot', str(bag), '--out', str(tmp_path / 'plot.png')])
    assert plot.returncode == 0, plot.stderr
    assert (tmp_path / 'plot.png').stat().st_size > 0
    listed = run_cli(['scenes', str(scene)])
    assert listed.returncode == 0 and 'effects:     Spring(stiffness=4.0)' in listed.stdout


def test_a_scene_with_a_plugin_file_loads_it_once_and_keeps_it_through_overrides(tmp_path):
    (tmp_path / 'spring.py').write_text(plugin_source('override_spring'))
    scene = load_scene(str(write_scene(tmp_path, 'override_spring', ['spring.py'])))
    assert scene.plugins == (str((tmp_path / 'spring.py').resolve()),)
    assert scene.effect_names() == ['override_spring']
    again = load_scene(str(tmp_path / 'override_spring.yaml'))  # the same file: no new import
    assert type(again.effects[0]) is type(scene.effects[0])
    heavier = scene.with_overrides(mass=2.0)
    assert heavier.effect_names() == ['override_spring'] and heavier.body.mass == 2.0


BROKEN_FILES = {
    'an import error': ({}, ('import numpy as np\n',
                             'import numpy as np\nimport no_such_module\n'),
                        "cannot import it: ModuleNotFoundError: No module named 'no_such_module'"),
    'a wrong signature': ({}, ('def spring(state, time, parameters):',
                               'def spring(state, parameters):'),
                          'does not compile as (state, time, parameters) -> (Fx, Fy, Fz, tx, '
                          'ty, tz): TypeError: Signature mismatch'),
    'three numbers for six': ({}, ('-k * state[6], 0.0, 0.0, 0.0', '-k * state[6]'),
                              'does not compile as (state, time, parameters)'),
    'a non-finite wrench': ({'factor': 'np.nan'}, None,
                            "its wrench at its example ({'stiffness': 2.0}) is not finite: "
                            '[nan, nan, nan, 0.0, 0.0, 0.0]'),
    'an undeclared term': ({}, ('@wrench_term\n', ''), 'is not declared with @wrench_term'),
}


@pytest.mark.parametrize('broken', sorted(BROKEN_FILES))
def test_a_broken_plugin_file_is_one_line_naming_it_and_nothing_of_it_stays(tmp_path, broken):
    options, replace, problem = BROKEN_FILES[broken]
    name = 'broken_' + broken.replace(' ', '_').replace('-', '_')
    (tmp_path / 'broken.py').write_text(plugin_source(
        name, options.get('factor', '1.0'), [replace] if replace else ()))
    scene = write_scene(tmp_path, name, ['broken.py'])
    with pytest.raises(ValueError) as raised:
        load_scene(str(scene))
    message = str(raised.value)
    assert '\n' not in message and 'Traceback' not in message
    assert message.startswith(f'{scene}: plugins[0]: effect plugin broken.py: ')
    assert problem in message
    assert not EFFECTS.registered(name)


def test_a_broken_plugin_file_refuses_its_scene_in_simulate_with_one_line(tmp_path):
    (tmp_path / 'nan.py').write_text(plugin_source('nan_spring', 'np.nan'))
    scene = write_scene(tmp_path, 'nan_spring', ['nan.py'])
    result = run_cli(['simulate', '--scene', str(scene), '--duration', '1', '--bag',
                      str(tmp_path / 'bag')])
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f'rigid-body-sim simulate: error: {scene}: plugins[0]: effect plugin nan.py: effect '
        "'nan_spring': its wrench at its example ({'stiffness': 2.0}) is not finite: "
        '[nan, nan, nan, 0.0, 0.0, 0.0]']
    assert not (tmp_path / 'bag').exists()


# -- an installed distribution's entry points


@pytest.fixture
def site(tmp_path):
    """
    Return a folder of installed distributions: one good plugin, three broken ones.

    The good one is a package whose wrench term calls a helper of its own (another module
    of the package).
    """
    folder = tmp_path / 'site'
    good = plugin_source('installed_spring', replace=[(
        'from rigid_body_sim.physics.kernels.model import wrench_term\n',
        'from rigid_body_sim.physics.kernels.model import wrench_term\n\n'
        'from .helpers import restoring\n'), (
        '    return -k * state[4], -k * state[5], -k * state[6], 0.0, 0.0, 0.0\n',
        '    return restoring(k, state[4]), restoring(k, state[5]), restoring(k, state[6]), '
        '0.0, 0.0, 0.0\n')])
    helpers = textwrap.dedent('''\
        """Compiled helpers of the test plugin."""

        from rigid_body_sim.physics.kernels import helper


        @helper
        def restoring(k, x):
            return -k * x
        ''')
    install_distribution(folder, 'spring-plugin', {
        'spring_plugin/__init__.py': '', 'spring_plugin/effect.py': good,
        'spring_plugin/helpers.py': helpers}, {
        'installed_spring': 'spring_plugin.effect:Spring'})
    install_distribution(folder, 'missing-plugin', {
        'missing_plugin.py': plugin_source('missing_spring', replace=[(
            'import numpy as np\n', 'import numpy as np\nimport no_such_module\n')])},
        {'missing_spring': 'missing_plugin:Spring'})
    install_distribution(folder, 'nan-plugin', {
        'nan_plugin.py': plugin_source('nan_installed', 'np.nan')},
        {'nan_installed': 'nan_plugin:Spring'})
    install_distribution(folder, 'signature-plugin', {
        'signature_plugin.py': plugin_source('signature_installed', replace=[(
            'def spring(state, time, parameters):', 'def spring(state, parameters):')])},
        {'signature_installed': 'signature_plugin:Spring'})
    return folder


def test_an_installed_plugin_runs_in_simulate_and_plot_by_its_entry_point(site, tmp_path):
    scene = write_scene(tmp_path, 'installed_spring')
    bag = tmp_path / 'bag'
    result = run_cli(['simulate', '--scene', str(scene), '--duration', '2', '--bag', str(bag),
                      '--quiet'], site)
    assert result.returncode == 0, result.stderr
    # Only the plugin the scene names is loaded: the broken ones say nothing.
    assert 'plugin' not in result.stderr
    assert_spring_motion(bag, 2.0)
    plot = run_cli(['plot', str(bag), '--out', str(tmp_path / 'plot.png')], site)
    assert plot.returncode == 0, plot.stderr


def test_broken_installed_plugins_are_one_line_each_and_the_rest_are_listed(site):
    result = run_cli(['scenes', '--effects'], site)
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 3, result.stderr
    assert lines[0] == ("rigid-body-sim scenes: effect plugin 'missing_spring' "
                        '(missing_plugin:Spring of missing-plugin 1.0): cannot import it: '
                        "ModuleNotFoundError: No module named 'no_such_module'")
    assert lines[1].startswith("rigid-body-sim scenes: effect plugin 'nan_installed' "
                               '(nan_plugin:Spring of nan-plugin 1.0): effect '
                               "'nan_installed': its wrench at its example")
    assert lines[2].startswith("rigid-body-sim scenes: effect plugin 'signature_installed' "
                               '(signature_plugin:Spring of signature-plugin 1.0): effect '
                               "'signature_installed': compiled_wrench spring does not compile")
    assert 'installed_spring: A linear spring pulling the COM to the world origin' \
        in result.stdout
    assert '    stiffness (N/m; default 1.0)' in result.stdout
    for name in ('missing_spring', 'nan_installed', 'signature_installed'):
        assert f'{name}:' not in result.stdout


def test_a_scene_naming_a_broken_installed_plugin_is_refused_with_its_line(site, tmp_path):
    scene = write_scene(tmp_path, 'missing_spring')
    result = run_cli(['scenes', str(scene)], site)
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f'rigid-body-sim scenes: error: {scene}: effects[0]: unknown effect '
        "'missing_spring': effect plugin 'missing_spring' (missing_plugin:Spring of "
        'missing-plugin 1.0): cannot import it: ModuleNotFoundError: No module named '
        "'no_such_module'"]


@pytest.mark.xdist_group('node')
def test_the_node_runs_a_scene_naming_an_installed_plugins_effect(site, tmp_path):
    isolate_ros_environment()
    scene = write_scene(tmp_path, 'installed_spring')
    node = NodeProcess(tmp_path / 'node.log', namespace=unique_namespace(),
                       parameters={'scene': str(scene)},
                       environment={'PYTHONPATH': environment_with(site)['PYTHONPATH']})
    client = Client(node.namespace)
    try:
        try:
            client.wait_until_connected(inputs=False)
            start = time.monotonic()
            # The node may have run a while before the client connected (a busy machine), so
            # the poses start at any phase of x = cos(2 t): at 100 Hz, 320 poses are 3.2 s of
            # the node's time, more than the period (pi s), so they pass both turning points.
            poses = client.wait_for_messages('pose', 320, since=start)
        except AssertionError as error:
            raise AssertionError(f'{error}; node output:\n{node.output()}') from None
        x = np.array([message.pose.position.x for message in poses])
        assert np.all(np.abs(x) <= 1.0 + 1e-9)
        assert x.min() < -0.9 and x.max() > 0.9, x
        assert 'installed_spring' in node.output()
    finally:
        client.close()
        node.stop()


# -- the compiled code of a plugin, cached by its own sources


def _cache_folder(path):
    """Return where the kernel cache puts the compiled functions of the file `path`."""
    cache.claim_file(path)

    def function():
        pass
    locator = cache.KernelCacheLocator.from_function(function, str(path))
    assert locator is not None
    return Path(locator.get_cache_path()).relative_to(cache.kernel_dir())


def test_a_plugins_compiled_code_is_cached_by_its_own_sources(tmp_path):
    if not cache.caching_enabled():
        pytest.skip(cache.PROBLEM)
    lone = tmp_path / 'a' / 'spring.py'
    copy = tmp_path / 'b' / 'spring.py'
    for path in (lone, copy):
        path.parent.mkdir()
        path.write_text(plugin_source('cached_spring'))
    # The same source anywhere: one folder; under plugins/, away from the sealed kernels.
    assert _cache_folder(lone) == _cache_folder(copy)
    assert _cache_folder(lone).parts[0] == cache.PLUGINS_FOLDER
    package = tmp_path / 'package'
    (package / 'inner').mkdir(parents=True)
    (package / '__init__.py').write_text('')
    (package / 'inner' / '__init__.py').write_text('')
    (package / 'inner' / 'effect.py').write_text(plugin_source('cached_spring'))
    (package / 'helpers.py').write_text('SCALE = 1.0\n')
    key, relative = cache.plugin_source_key(package / 'inner' / 'effect.py')
    assert relative == Path('inner')
    # A helper of the package edited: another key, so nothing compiled from the old stays.
    (package / 'helpers.py').write_text('SCALE = 2.0\n')
    assert cache.plugin_source_key(package / 'inner' / 'effect.py')[0] != key
    lone.write_text(plugin_source('cached_spring', '2.0'))
    assert cache.plugin_source_key(lone)[0] != cache.plugin_source_key(copy)[0]


def test_the_seal_leaves_the_plugins_compiled_code_out(tmp_path):
    (tmp_path / 'integrators').mkdir()
    (tmp_path / 'integrators' / 'run.nbc').write_bytes(b'kernel')
    (tmp_path / cache.PLUGINS_FOLDER / 'key').mkdir(parents=True)
    (tmp_path / cache.PLUGINS_FOLDER / 'key' / 'spring.nbc').write_bytes(b'plugin')
    assert cache.seal(tmp_path) == 1
    # A plugin compiled again after the seal is no damage to the kernels.
    (tmp_path / cache.PLUGINS_FOLDER / 'key' / 'spring.nbc').write_bytes(b'recompiled')
    assert cache.verify(tmp_path) == []
    assert cache.drop_unsealed(tmp_path) == 0

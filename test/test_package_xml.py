"""
package.xml names every package the code imports (what rosdep installs), run time apart.

Run time is the installed package less the benchmark (rigid_body_sim/work_precision/ and
rigid_body_sim/tools/bench.py, which only `rigid-body-sim bench` imports), and the launch
files (launch/*.py, which `ros2 launch` runs): its imports are package.xml's exec_depends
and requirements.txt's pins.  What only the benchmark and the
tests import or run is a test_depend, pinned in requirements-test.txt.
"""

import ast
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ElementTree

ROOT = Path(__file__).resolve().parent.parent
# Top-level import -> its key in package.xml: rosdep keys where they exist, pip keys
# (python3-<name>-pip) otherwise; ROS packages are their own keys.
KEYS = {
    'numpy': 'python3-numpy', 'llvmlite': 'python3-llvmlite',
    'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
    'numba': 'python3-numba', 'matplotlib': 'python3-matplotlib',
    'mpl_toolkits': 'python3-matplotlib', 'tqdm': 'python3-tqdm',
    'rosbags': 'python3-rosbags-pip', 'mcap': 'python3-mcap-pip',
    'ruamel': 'python3-ruamel.yaml', 'PIL': 'python3-pil',
    'pytest': 'python3-pytest', 'hypothesis': 'python3-hypothesis',
    'mujoco': 'python3-mujoco-pip', 'mcap_ros2': 'mcap-ros2-support',
    'dask': 'python3-dask-pip', 'distributed': 'python3-distributed-pip',
    'pyarrow': 'python3-pyarrow-pip',
}
# Run by the tests as programs, not imported: colcon (test_colcon_build.py), mypy
# (test_types.py), ament_flake8 (test_flake8.py, a process of its own) and pytest-xdist
# (make test's `pytest -n 2`).
TEST_TOOLS = {'python3-colcon-common-extensions', 'python3-mypy', 'python3-pytest-xdist',
              'ament_flake8'}
# package.xml key -> the distribution pinned in the requirements files (a ROS package
# <name> comes as the wheel ros-<name>).
DISTRIBUTIONS = {
    'python3-numpy': 'numpy', 'python3-llvmlite': 'llvmlite',
    'python3-scipy': 'scipy', 'python3-yaml': 'pyyaml',
    'python3-numba': 'numba', 'python3-matplotlib': 'matplotlib', 'python3-tqdm': 'tqdm',
    'python3-rosbags-pip': 'rosbags', 'python3-mcap-pip': 'mcap',
    'python3-ruamel.yaml': 'ruamel-yaml', 'python3-pil': 'pillow',
    'python3-pytest': 'pytest', 'python3-hypothesis': 'hypothesis',
    'python3-mujoco-pip': 'mujoco', 'mcap-ros2-support': 'mcap-ros2-support',
    'python3-colcon-common-extensions': 'colcon-common-extensions',
    'python3-pytest-xdist': 'pytest-xdist', 'python3-mypy': 'mypy',
    'python3-dask-pip': 'dask', 'python3-distributed-pip': 'distributed',
    'python3-pyarrow-pip': 'pyarrow',
}
# Built into the venv from interfaces/tf2_msgs and interfaces/simulation_interfaces (no
# wheel): never pinned.  launch and launch_ros, which the launch files import, have no wheel
# either: a ROS 2 installation has them (test/launch_env.py builds them from their sources
# for the tests, outside the venv).
BUILT = {'tf2_msgs', 'simulation_interfaces', 'launch', 'launch_ros'}
# Test_depends that the run-time set brings anyway (geometry_msgs needs std_msgs).
PULLED_AT_RUN_TIME = {'std_msgs'}


def _imports(paths):
    """Return the top-level modules the files import (absolute imports, not the stdlib)."""
    modules = set()
    for path in paths:
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name.split('.')[0] for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module.split('.')[0]]
            else:
                continue
            modules.update(names)
    return modules - set(sys.stdlib_module_names) - {'rigid_body_sim'}


def _is_bench(path):
    relative = path.relative_to(ROOT / 'rigid_body_sim').as_posix()
    return relative.startswith('work_precision/') or relative == 'tools/bench.py'


def run_time_modules():
    """Return the top-level modules the installed package imports, the benchmark aside."""
    sources = [path for path in (ROOT / 'rigid_body_sim').rglob('*.py') if not _is_bench(path)]
    return _imports(sources + sorted((ROOT / 'launch').glob('*.py')))


def bench_and_test_modules():
    """Return what only the benchmark and the tests import (their own helpers aside)."""
    benchmark = [path for path in (ROOT / 'rigid_body_sim').rglob('*.py') if _is_bench(path)]
    tests = sorted((ROOT / 'test').glob('*.py'))
    helpers = {path.stem for path in tests}
    return _imports(benchmark + tests) - helpers - run_time_modules()


def _depends(tag):
    root = ElementTree.parse(ROOT / 'package.xml').getroot()
    return {element.text for element in root.iter(tag)}


def _pins(name):
    """Return {normalized distribution: the line} of a requirements file (-r lines aside)."""
    pins = {}
    for line in (ROOT / name).read_text().splitlines():
        if line and not line.startswith(('#', '-')):
            assert '==' in line, f'{name}: {line!r} is not pinned exactly'
            distribution = re.split(r'[=<>\[; ]', line, maxsplit=1)[0]
            pins.setdefault(re.sub(r'[-_.]+', '-', distribution).lower(), []).append(line)
    return pins


def _distribution(key):
    return DISTRIBUTIONS.get(key, 'ros-' + key.replace('_', '-'))


def test_package_xml_lists_every_run_time_import_as_an_exec_depend():
    """Each third-party import of the run-time code has its exec_depend; none more."""
    listed = _depends('exec_depend')
    needed = {KEYS.get(module, module) for module in run_time_modules()}
    assert needed - listed == set(), 'missing from package.xml'
    assert listed - needed == set(), 'listed in package.xml but imported nowhere at run time'


def test_package_xml_lists_what_only_tests_and_bench_need_as_test_depends():
    """mujoco, pytest, hypothesis ... are test_depends, and no run-time package is one."""
    listed = _depends('test_depend')
    needed = {KEYS.get(module, module) for module in bench_and_test_modules()} | TEST_TOOLS
    assert needed - listed == set(), 'missing from package.xml'
    assert listed - needed == set(), 'a test_depend nothing of the tests or bench imports'
    assert listed & _depends('exec_depend') == set()


def test_requirement_files_pin_the_exec_depends_to_run_and_the_test_depends_to_test():
    """requirements.txt (make run) pins every exec_depend; requirements-test.txt the rest."""
    run, test = _pins('requirements.txt'), _pins('requirements-test.txt')
    assert (ROOT / 'requirements-test.txt').read_text().count('-r requirements.txt\n') == 1
    for key in _depends('exec_depend') - BUILT:
        assert _distribution(key) in run, f'{key}: {_distribution(key)} not in requirements.txt'
    for key in _depends('test_depend') - BUILT - PULLED_AT_RUN_TIME:
        distribution = _distribution(key)
        assert distribution in test, f'{key}: {distribution} not in requirements-test.txt'
    for key in PULLED_AT_RUN_TIME:
        assert _distribution(key) in run
    assert set(run) & set(test) == set(), 'pinned in both requirements.txt and the test set'


# What the interface packages of interfaces/ link against: tf2_msgs geometry_msgs (and
# below), simulation_interfaces also std_msgs and action_msgs (and its unique_identifier_msgs).
LINKED = {'numpy', 'ros-rosidl-runtime-c', 'ros-fastcdr', 'ros-builtin-interfaces',
          'ros-service-msgs', 'ros-geometry-msgs', 'ros-std-msgs', 'ros-action-msgs',
          'ros-unique-identifier-msgs'}


def test_the_interfaces_build_venv_pins_what_it_shares_with_the_run_venv_alike():
    """Built in the build venv, run in .venv: the wheels they link against must match."""
    run, build = _pins('requirements.txt'), _pins('requirements-tf2.txt')
    shared = set(run) & set(build)
    assert LINKED <= shared, f'pinned in one venv only: {sorted(LINKED - shared)}'
    differing = {name: (run[name], build[name]) for name in shared if run[name] != build[name]}
    assert differing == {}

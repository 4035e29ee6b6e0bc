"""
Build the package with colcon, as in a ROS 2 workspace, and use the install.

The package's files are copied to a temporary workspace first, so that colcon
crawls nothing else in the checkout (``.venv/``, ``build/``, ``install/``).
"""

import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys

import pytest

PACKAGE_NAME = 'rigid_body_sim'
PACKAGE_ROOT = Path(__file__).resolve().parent.parent

# Never copied when the checkout is not a git repository.
_NOT_SOURCES = ('.git', '.venv', 'build', 'install', 'log', '__pycache__', '*.egg-info',
                '.pytest_cache', '*.pyc')

pytestmark = pytest.mark.xdist_group('colcon')


def _package_files():
    """
    Return the package's files, relative to its root.

    :returns: the tracked files plus the untracked ones git does not ignore,
        or None when the root is not a git checkout.
    """
    if shutil.which('git') is None or not (PACKAGE_ROOT / '.git').exists():
        return None
    listed = subprocess.run(
        ['git', 'ls-files', '-z', '--cached', '--others', '--exclude-standard'],
        cwd=PACKAGE_ROOT, check=True, capture_output=True).stdout.decode()
    return [name for name in listed.split('\0') if name and (PACKAGE_ROOT / name).is_file()]


def _copy_package(destination):
    """
    Copy the package's sources (nothing generated or ignored) to a directory.

    :param destination: the directory to create, which must not exist.
    """
    files = _package_files()
    if files is None:
        shutil.copytree(PACKAGE_ROOT, destination,
                        ignore=shutil.ignore_patterns(*_NOT_SOURCES))
        return
    for name in files:
        target = destination / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(PACKAGE_ROOT / name, target)


def _colcon():
    """
    Return the colcon executable of the interpreter running the tests.

    :returns: the path of colcon beside ``sys.executable``, else the one on PATH.
    """
    beside = Path(sys.executable).parent / 'colcon'
    if beside.is_file():
        return str(beside)
    found = shutil.which('colcon')
    if found is None:
        pytest.fail('colcon is not installed (pip install colcon-common-extensions)')
    return found


def _in_sourced_workspace(install, command):
    """
    Run a shell command after sourcing the workspace, as a ROS 2 user would.

    The command runs in the workspace, not in the checkout, so that
    ``python -c`` cannot import the package from the current directory.

    :param install: the colcon install base.
    :param command: the bash command to run once ``setup.bash`` is sourced.
    :returns: the completed process, with text output captured.
    """
    script = 'source "{0}/setup.bash" && {1}'.format(install, command)
    return subprocess.run(['bash', '-c', script], cwd=install.parent, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    """
    Build the package with colcon into a temporary workspace.

    :returns: the install base of that workspace.
    """
    workspace = tmp_path_factory.mktemp('colcon_ws')
    source = workspace / 'src' / PACKAGE_NAME
    _copy_package(source)
    env = dict(os.environ)
    env['COLCON_HOME'] = str(workspace / 'colcon_home')  # no user defaults.yaml
    built = subprocess.run(
        [_colcon(), '--log-base', str(workspace / 'log'), 'build',
         '--base-paths', str(workspace / 'src'),
         '--build-base', str(workspace / 'build'),
         '--install-base', str(workspace / 'install'),
         '--event-handlers', 'console_direct+'],
        cwd=workspace, env=env, capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, \
        'colcon build failed:\n' + built.stdout + built.stderr
    return workspace / 'install'


def test_colcon_build_installs_executables_where_ros2_run_finds_them(colcon_install):
    """``ros2 run rigid_body_sim rigid-body-sim`` runs <prefix>/lib/<package>/<name>."""
    executable = colcon_install / PACKAGE_NAME / 'lib' / PACKAGE_NAME / 'rigid-body-sim'
    assert executable.is_file(), 'no executable at ' + str(executable)
    assert os.access(executable, os.X_OK), str(executable) + ' is not executable'

    ran = _in_sourced_workspace(colcon_install, '"{0}" --help'.format(executable))

    assert ran.returncode == 0, ran.stdout + ran.stderr
    assert 'usage: rigid-body-sim' in ran.stdout, ran.stdout + ran.stderr


# A --help that works prints its usage within seconds (argparse, before any ROS set-up); a
# node that ignores --help starts simulating instead and runs until it is stopped.
HELP_TIMEOUT = 30.0


def _help_of_installed(install, executable):
    """
    Run ``<executable> --help`` in the sourced workspace; stop it if it does not exit.

    :returns: (exit code or None when it had to be stopped, stdout, stderr).
    """
    script = 'source "{0}/setup.bash" && exec "{1}" --help'.format(install, executable)
    process = subprocess.Popen(['bash', '-c', script], cwd=install.parent,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    try:
        out, err = process.communicate(timeout=HELP_TIMEOUT)
        return process.returncode, out, err
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGINT)
        try:
            out, err = process.communicate(timeout=10.0)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            out, err = process.communicate()
        return None, out, err


def test_colcon_build_installs_the_node_and_its_help_exits_with_usage(colcon_install):
    """``ros2 run rigid_body_sim rigid_body_node --help`` prints usage and exits 0."""
    executable = colcon_install / PACKAGE_NAME / 'lib' / PACKAGE_NAME / 'rigid_body_node'
    assert executable.is_file(), 'no executable at ' + str(executable)
    assert os.access(executable, os.X_OK), str(executable) + ' is not executable'

    code, out, err = _help_of_installed(colcon_install, executable)

    assert code is not None, \
        'still running after {0} s (stopped):\n{1}{2}'.format(HELP_TIMEOUT, out, err)
    assert code == 0, out + err
    assert 'usage: rigid_body_node' in out, out + err


def test_colcon_install_runs_the_installed_copy_not_the_source_tree(colcon_install):
    """After sourcing setup.bash, the package imports from the install prefix."""
    site = colcon_install / PACKAGE_NAME / 'lib'
    ran = _in_sourced_workspace(
        colcon_install,
        '"{0}" -c "import rigid_body_sim; print(rigid_body_sim.__file__)"'.format(
            sys.executable))

    assert ran.returncode == 0, ran.stdout + ran.stderr
    imported = Path(ran.stdout.strip().splitlines()[-1]).resolve()
    assert site.resolve() in imported.parents, imported


def test_colcon_install_registers_the_package_in_the_ament_index(colcon_install):
    """The ament index marker and package.xml are where ROS 2 tools look for them."""
    prefix = colcon_install / PACKAGE_NAME
    marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE_NAME
    assert marker.is_file(), 'no ament index marker at ' + str(marker)
    assert (prefix / 'share' / PACKAGE_NAME / 'package.xml').is_file()


def test_colcon_install_ships_the_config_and_paths_find_it(colcon_install):
    """paths.config_dir() resolves to the installed share directory via the index."""
    share = colcon_install / PACKAGE_NAME / 'share' / PACKAGE_NAME
    assert (share / 'config' / 'rigid_body_sim.yaml').is_file()
    assert not (share / 'config' / 'scenes' / '.gitkeep').exists()
    # Every YAML of config/, config/scenes/ and config/sweeps/ is installed (setup.py
    # data_files), no more.
    for folder in ('config', 'config/scenes', 'config/sweeps'):
        source = sorted(path.name for path in (PACKAGE_ROOT / folder).glob('*.yaml'))
        installed = sorted(path.name for path in (share / folder).glob('*.yaml'))
        assert source, 'no YAML in ' + folder
        assert installed == source, (folder, installed, source)
    assert (share / 'config' / 'scenes' / 'default.yaml').is_file()

    ran = _in_sourced_workspace(
        colcon_install,
        '"{0}" -c "from rigid_body_sim import paths; print(paths.config_dir())"'.format(
            sys.executable))

    assert ran.returncode == 0, ran.stdout + ran.stderr
    found = Path(ran.stdout.strip().splitlines()[-1]).resolve()
    assert found == (share / 'config').resolve()


def test_colcon_install_ships_the_committed_benchmark_references(colcon_install):
    """The benchmark's reference values (package data) load from the installed copy."""
    site = colcon_install / PACKAGE_NAME / 'lib'
    data = sorted(path.name for path in
                  (PACKAGE_ROOT / PACKAGE_NAME / 'work_precision' / 'data').glob('*.json'))
    installed = sorted(path.name for path in site.rglob('work_precision/data/*.json'))
    assert data and installed == data, (installed, data)
    ran = _in_sourced_workspace(
        colcon_install,
        '"{0}" -c "from rigid_body_sim.work_precision import extended_reference as e; '
        'print(e.__file__); print(sum(len(e.committed_references(n)) '
        'for n in e.REFERENCE_SETS))"'.format(sys.executable))

    assert ran.returncode == 0, ran.stdout + ran.stderr
    module, problems = ran.stdout.strip().splitlines()[-2:]
    assert site.resolve() in Path(module).resolve().parents, module
    assert int(problems) > 0


def test_colcon_install_ships_the_py_typed_marker_beside_the_package(colcon_install):
    """The installed package carries py.typed (PEP 561): a type checker reads its annotations."""
    site = colcon_install / PACKAGE_NAME / 'lib'
    markers = [path for path in site.rglob('py.typed') if path.parent.name == PACKAGE_NAME]
    assert len(markers) == 1, markers
    assert (markers[0].parent / '__init__.py').is_file(), markers[0]


def test_colcon_install_finds_the_kernels_the_checkout_compiled(colcon_install):
    """
    The install is another copy of the same sources: its kernels are compiled already.

    The kernels are cached by the content of their sources, not by where the package sits
    (physics/kernels/cache.py): `make test` compiled them for this checkout.
    """
    ran = _in_sourced_workspace(
        colcon_install,
        '"{0}" -c "from rigid_body_sim.physics import warm_up; print(warm_up.__file__); '
        'print(warm_up.missing())"'.format(sys.executable))

    assert ran.returncode == 0, ran.stdout + ran.stderr
    module, missing = ran.stdout.strip().splitlines()[-2:]
    assert (colcon_install / PACKAGE_NAME).resolve() in Path(module).resolve().parents, module
    assert missing == '[]', ran.stdout

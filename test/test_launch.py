"""
``ros2 launch rigid_body_sim sim.launch.py``: the real ``ros2 launch``, over real DDS.

``ros2 launch`` (ros2/launch, launch_ros and ros2cli's ros2launch, ROS 2 Jazzy) has no PyPI
wheel: test/launch_env.py builds it from its public sources into a scratch prefix outside
the repository, once per machine, and these tests skip, saying why, where it cannot (no
checkouts of those sources, no cmake or compiler).  The package is built with colcon, as a
ROS 2 user builds it, and the launch file is run as they run it: by package name in the
sourced workspace, and by its path with the executables on PATH.

Not tested here: RViz (no rviz2 wheel, no display): test_rviz_config.py checks its config.
"""

import os
from pathlib import Path
import re
import shutil
import signal
import subprocess
import sys

import launch_env
from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import unique_namespace
import pytest
from rclpy.qos import QoSProfile
from test_colcon_build import _colcon
from test_colcon_build import _copy_package
from visualization_msgs.msg import Marker
from visualization_msgs.msg import MarkerArray

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = 'rigid_body_sim'
# The arguments sim.launch.py declares, each with a description (--show-args prints them).
ARGUMENTS = ('scene', 'namespace', 'frame_prefix', 'rate', 'integrator', 'publish_clock',
             'use_sim_time', 'params_file', 'rviz', 'rviz_config', 'fixed_frame',
             'momentum_arrow', 'momentum_scale')
# A stop on SIGINT: the node's teardown takes ~0.1 s, launch's own shutdown a few s.
STOP_TIMEOUT = 60.0

pytestmark = pytest.mark.xdist_group('launch')


@pytest.fixture(scope='module')
def launch_prefix():
    """
    Return the prefix of the scratch ``ros2 launch`` (built once per machine).

    None in a sourced ROS 2 Jazzy installation, whose own ``ros2 launch`` is then tested.
    """
    if os.environ.get('ROS_DISTRO') == 'jazzy' and shutil.which('ros2') is not None:
        return None
    try:
        return launch_env.ensure_built()
    except launch_env.Unavailable as error:
        pytest.skip(f'no ros2 launch to test with: {error}')


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    """Return a colcon workspace with this package built (its root, holding install/)."""
    root = tmp_path_factory.mktemp('launch_ws')
    _copy_package(root / 'src' / PACKAGE)
    env = dict(os.environ, COLCON_HOME=str(root / 'colcon_home'))
    built = subprocess.run(
        [_colcon(), '--log-base', str(root / 'log'), 'build', '--base-paths', str(root / 'src'),
         '--build-base', str(root / 'build'), '--install-base', str(root / 'install')],
        cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stdout + built.stderr
    return root


@pytest.fixture(scope='module')
def ros_domain():
    return isolate_ros_environment()


def _in_workspace(workspace, command):
    """Return the bash command that runs `command` in the sourced workspace."""
    return f'source "{workspace}/install/setup.bash" && exec {command}'


class Launch:
    """A ``ros2 launch`` running in a process group of its own, its output in a file."""

    def __init__(self, script, env, cwd, log_path):
        self.log_path = log_path
        self._log = open(log_path, 'w')
        self.process = subprocess.Popen(['bash', '-c', script], env=env, cwd=cwd,
                                        stdout=self._log, stderr=subprocess.STDOUT,
                                        start_new_session=True)

    def output(self):
        return Path(self.log_path).read_text()

    def commands(self):
        """Return the command lines (lists of words) of the processes of its group."""
        found = []
        for entry in Path('/proc').iterdir():
            try:
                if entry.name.isdigit() and os.getpgid(int(entry.name)) == self.process.pid:
                    words = (entry / 'cmdline').read_bytes().split(b'\0')
                    found.append([word.decode() for word in words if word])
            except (OSError, ProcessLookupError):
                continue  # gone meanwhile
        return found

    def command_of(self, executable):
        """Return the path the group runs `executable` from (the python script's path)."""
        for words in self.commands():
            for word in words[:2]:
                if Path(word).name == executable:
                    return word
        raise AssertionError(f'no {executable} among {self.commands()}')

    def ctrl_c(self, timeout=STOP_TIMEOUT):
        """Send SIGINT to the whole group, as Ctrl-C in a terminal; return the exit code."""
        os.killpg(self.process.pid, signal.SIGINT)
        try:
            return self.process.wait(timeout)
        finally:
            self.close()

    def close(self):
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()
        self._log.close()


def _arrow_topic():
    return {'angular_momentum_arrow': (MarkerArray, QoSProfile(depth=10))}


def _assert_started_and_stops_cleanly(launch, namespace, scene_line, world_frame=None):
    """
    Check the node publishes in `namespace`, the arrow follows L; Ctrl-C ends all with 0.

    The poses are in `world_frame` (default: the node's, its namespace as frame prefix).

    :returns: {executable: the path it ran from} of the node and the arrow helper.
    """
    client = Client(namespace, extra_topics=_arrow_topic())
    try:
        poses = client.wait_for_messages('pose', 1, timeout=DISCOVERY_TIMEOUT)
        assert poses[0].header.frame_id == (world_frame or client.frame('world'))
        arrays = client.wait_for_messages('angular_momentum_arrow', 1)
        momenta = client.wait_for_messages('angular_momentum', 1)
    finally:
        client.close()
    arrow = arrays[-1].markers[0]
    assert arrow.type == Marker.ARROW and len(arrow.points) == 2
    tail, tip = arrow.points
    length = ((tip.x - tail.x) ** 2 + (tip.y - tail.y) ** 2 + (tip.z - tail.z) ** 2) ** 0.5
    vector = momenta[-1].vector
    # heavy_top precesses, so the arrow is one of the L published; its length is |L|
    # (momentum_scale 1), which gravity about the pivot changes slowly.
    magnitude = (vector.x ** 2 + vector.y ** 2 + vector.z ** 2) ** 0.5
    assert length == pytest.approx(magnitude, rel=0.05)
    output = launch.output()
    assert scene_line in output, output
    paths = {name: launch.command_of(name)
             for name in ('rigid_body_node', 'angular_momentum_arrow')}
    code = launch.ctrl_c()
    output = launch.output()
    assert code == 0, output
    for process in ('rigid_body_node-1', 'angular_momentum_arrow-2'):
        assert re.search(rf'\[INFO\] \[{process}\]: process has finished cleanly', output), \
            output
    return paths


def test_show_args_lists_every_argument_with_its_description(launch_prefix, workspace):
    shown = subprocess.run(
        ['bash', '-c', _in_workspace(workspace, f'ros2 launch {PACKAGE} sim.launch.py '
                                                '--show-args')],
        env=launch_env.environment(launch_prefix), cwd=workspace, capture_output=True,
        text=True, timeout=120)
    assert shown.returncode == 0, shown.stdout + shown.stderr
    # ros2launch prints: 'name':, its description, (default: ...), a blank line.
    blocks = re.findall(r"^    '(\w+)':\n        (.+)\n        \(default: (.*)\)$",
                        shown.stdout, re.M)
    assert [name for name, _, _ in blocks] == list(ARGUMENTS), shown.stdout
    for name, description, default in blocks:
        assert len(description) > 30, (name, description)
    defaults = {name: default for name, _, default in blocks}
    assert defaults['rviz'] == "'false'" and defaults['scene'] == "''"
    installed_config = workspace / 'install' / PACKAGE / 'share' / PACKAGE / 'rviz'
    assert defaults['rviz_config'] == f"'{installed_config / 'rigid_body_sim.rviz'}'"


def test_ros2_launch_by_package_name_starts_the_scene_and_stops_on_ctrl_c(
        launch_prefix, workspace, ros_domain, tmp_path):
    namespace = unique_namespace()
    command = (f'ros2 launch {PACKAGE} sim.launch.py scene:=heavy_top rviz:=false '
               f'momentum_arrow:=true namespace:={namespace}')
    launch = Launch(_in_workspace(workspace, command), launch_env.environment(launch_prefix),
                    workspace, tmp_path / 'launch.log')
    try:
        paths = _assert_started_and_stops_cleanly(launch, namespace,
                                                  "simulating scene 'heavy_top'")
    finally:
        launch.close()
    # The executables came from the package, where ros2 run finds them.
    for executable, path in paths.items():
        assert path == str(workspace / 'install' / PACKAGE / 'lib' / PACKAGE / executable)


def test_the_launch_file_by_path_finds_the_executables_on_path_and_says_rviz_is_missing(
        launch_prefix, workspace, ros_domain, tmp_path):
    # A venv user with a ROS 2 installation: the package is not in the ament index, its
    # executables are on PATH (here links to the install's, in a bin/ as a venv's).
    install = workspace / 'install' / PACKAGE
    bin_dir = tmp_path / 'bin'
    bin_dir.mkdir()
    for executable in ('rigid_body_node', 'angular_momentum_arrow'):
        (bin_dir / executable).symlink_to(install / 'lib' / PACKAGE / executable)
    env = launch_env.environment(launch_prefix)
    env['PATH'] = f'{bin_dir}{os.pathsep}{env["PATH"]}'
    env['PYTHONPATH'] = os.pathsep.join(
        [str(launch_env.site_packages(install)), env['PYTHONPATH']])
    scene = tmp_path / 'my_top.yaml'
    scene.write_text((ROOT / 'config' / 'scenes' / 'heavy_top.yaml').read_text()
                     .replace('name: heavy_top', 'name: my_top'))
    # scene:=my_top.yaml, relative to the directory ros2 launch runs in: the node's
    # "simulating scene 'my_top'" says it read that file.
    namespace = unique_namespace()
    launch_file = install / 'share' / PACKAGE / 'launch' / 'sim.launch.py'
    # frame_prefix passed through to the node, verbatim.
    prefix = namespace.strip('/') + '_robot/'
    command = (f'exec ros2 launch {launch_file} scene:=my_top.yaml rviz:=true '
               f'namespace:={namespace} frame_prefix:={prefix}')
    launch = Launch(command, env, tmp_path, tmp_path / 'launch.log')
    try:
        paths = _assert_started_and_stops_cleanly(launch, namespace, "simulating scene 'my_top'",
                                                  world_frame=prefix + 'world')
    finally:
        launch.close()
    assert paths == {name: str(bin_dir / name) for name in paths}
    output = launch.output()
    assert 'rviz2 is not installed here' in output, output


def test_a_wrong_argument_is_one_line_naming_it_and_nothing_starts(
        launch_prefix, workspace, ros_domain):
    ran = subprocess.run(
        ['bash', '-c', _in_workspace(workspace, f'ros2 launch {PACKAGE} sim.launch.py '
                                                'rate:=fast')],
        env=launch_env.environment(launch_prefix), cwd=workspace, capture_output=True,
        text=True, timeout=120)
    assert ran.returncode != 0
    errors = [line for line in (ran.stdout + ran.stderr).splitlines() if 'rate:=' in line]
    assert len(errors) == 1 and 'expected a number' in errors[0], ran.stdout + ran.stderr
    assert 'process started' not in ran.stdout + ran.stderr
    assert 'Traceback' not in ran.stdout + ran.stderr


def test_the_colcon_install_lays_the_launch_file_and_rviz_config_where_ros2_finds_them(
        launch_prefix, workspace):
    share = workspace / 'install' / PACKAGE / 'share' / PACKAGE
    assert (share / 'launch' / 'sim.launch.py').read_text() == \
        (ROOT / 'launch' / 'sim.launch.py').read_text()
    assert (share / 'rviz' / 'rigid_body_sim.rviz').read_text() == \
        (ROOT / 'rviz' / 'rigid_body_sim.rviz').read_text()
    found = subprocess.run(
        ['bash', '-c', _in_workspace(
            workspace, f'{sys.executable} -c "from ament_index_python.packages import '
                       f'get_package_share_directory as g; print(g(\'{PACKAGE}\'))"')],
        env=launch_env.environment(launch_prefix), cwd=workspace, capture_output=True,
        text=True, timeout=120)
    assert found.returncode == 0, found.stderr
    assert Path(found.stdout.split()[-1]) == share


def _documented_launch_commands():
    """Return the ``ros2 launch`` lines of the pages' shell blocks, comments dropped."""
    text = '\n'.join(page.read_text() for page in
                     [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))])
    commands = []
    for block in re.findall(r'```sh\n(.*?)```', text, re.S):
        for line in block.replace('\\\n', ' ').splitlines():
            if line.startswith('ros2 launch '):
                commands.append(line.split(' #')[0].strip())
    return commands


def test_the_documented_ros2_launch_commands_run_as_written(
        launch_prefix, workspace, ros_domain, tmp_path):
    commands = _documented_launch_commands()
    assert len(commands) >= 3 and any('rviz:=true' in command for command in commands)
    env = launch_env.environment(launch_prefix)
    for index, command in enumerate(commands):
        if '--show-args' in command:
            shown = subprocess.run(['bash', '-c', _in_workspace(workspace, command)], env=env,
                                   cwd=workspace, capture_output=True, text=True, timeout=120)
            assert shown.returncode == 0 and "'scene':" in shown.stdout, (command, shown)
            continue
        namespace = re.search(r'namespace:=(\S+)', command)
        namespace = namespace.group(1) if namespace else '/'
        launch = Launch(_in_workspace(workspace, command), env, workspace,
                        tmp_path / f'launch{index}.log')
        try:
            client = Client(namespace)
            try:
                client.wait_for_messages('pose', 1, timeout=DISCOVERY_TIMEOUT)
            finally:
                client.close()
            code = launch.ctrl_c()
        finally:
            launch.close()
        assert code == 0, (command, launch.output())
        assert 'process has finished cleanly' in launch.output(), (command, launch.output())

"""
Start rigid_body_node with a scene and, with ``rviz:=true``, RViz with the package's config.

    ros2 launch rigid_body_sim sim.launch.py scene:=heavy_top rviz:=true
    ros2 launch rigid_body_sim sim.launch.py --show-args     (every argument, explained)

What starts:

- ``rigid_body_node`` (output on the screen); when it exits, for whatever reason, the launch
  shuts down with it;
- with ``rviz:=true``: ``rviz2`` with ``rviz/rigid_body_sim.rviz`` (TF, the body's marker,
  the odometry and the angular momentum arrow), its fixed frame ``fixed_frame``;
- with ``momentum_arrow:=true`` (the default when ``rviz:=true``): ``angular_momentum_arrow``,
  which draws the node's ``angular_momentum`` (a Vector3Stamped, which RViz cannot show) as
  a labelled arrow marker.

All three share ``namespace``: the RViz config names its topics relatively (``marker``,
``odom``, ...), so an RViz started in the node's namespace shows that node.  TF is global,
and the node's frames follow the namespace (its ``frame_prefix``, by default ``sat1/`` in
``/sat1``): RViz's fixed frame is the node's world frame, ``sat1/world`` there.

The executables are looked up in the package (``lib/rigid_body_sim``, as ``ros2 run`` does)
when the ament index knows it (a sourced colcon workspace), else on PATH (a venv whose
``bin`` is on PATH, with this file run by its path); the RViz config is found beside this
file (``../rviz``), in an install's share directory and in a source checkout alike.
"""

import os
from pathlib import Path
import shutil

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.actions import LogInfo
from launch.actions import OpaqueFunction
from launch.actions import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = 'rigid_body_sim'
RVIZ_CONFIG = Path(__file__).resolve().parent.parent / 'rviz' / 'rigid_body_sim.rviz'

# (name, default, description): what `ros2 launch ... --show-args` prints.  An empty default
# leaves the node's own value (its params_file's, else the scene's).
ARGUMENTS = (
    ('scene', '',
     'The scene to simulate: a built-in name (default, heavy_top, tennis_racket, ...; '
     '`rigid-body-sim scenes` lists them) or the path of a scene file (a relative path is '
     "taken from the directory ros2 launch runs in).  Empty: params_file's scene, else "
     "'default'."),
    ('namespace', '',
     'Namespace of the node, of RViz and of the arrow helper (e.g. /sat1): the topics become '
     '/sat1/pose, /sat1/marker, ... and the frames sat1/world, sat1/body (see frame_prefix).  '
     'Empty: the root namespace.'),
    ('frame_prefix', '',
     "The node's frame_prefix, put before its frame names verbatim (robot_state_publisher's "
     "rule): 'robot_a/' gives robot_a/world -> robot_a/body; '/' none.  Empty: the node's "
     "default, the namespace ('sat1/' in /sat1, none at the root)."),
    ('rate', '',
     'Tick rate of the node in Hz (0.1 to 10000); each tick advances the simulation by '
     "1/rate s.  Empty: the scene's."),
    ('integrator', '',
     'Integration method (buss, rk4, splitting, ...; `rigid_body_node --help` lists them).  '
     "Empty: the scene's."),
    ('publish_clock', 'false',
     'true: the node publishes the simulated time on /clock and stamps its messages with it '
     '(simulated time from 0 at start-up).'),
    ('use_sim_time', LaunchConfiguration('publish_clock'),
     "true: RViz and the arrow helper follow /clock (the node's own tick never does).  "
     "Default: publish_clock's value."),
    ('params_file', '',
     'A parameters YAML file for the node (as rigid_body_node --ros-args --params-file '
     'takes); the arguments above that are set override its values.  Empty: none.'),
    ('rviz', 'false',
     "true: start RViz (rviz2, from a ROS 2 installation) with the package's config."),
    ('rviz_config', str(RVIZ_CONFIG),
     'The RViz config file RViz starts with.'),
    ('fixed_frame', '',
     "RViz's fixed frame.  Empty: the node's world frame, frame_prefix + world (sat1/world in "
     '/sat1); give it when a params_file renames world_frame (config/rep105.yaml: '
     '<prefix>odom).'),
    ('momentum_arrow', LaunchConfiguration('rviz'),
     'true: start angular_momentum_arrow, which draws the angular momentum L (the '
     'angular_momentum topic) as a labelled arrow (marker array angular_momentum_arrow).  '
     "Default: rviz's value."),
    ('momentum_scale', '1.0',
     'Length of the angular momentum arrow in m per N m s of |L|.'),
)

_TRUE = ('true', '1', 'yes', 'on')
_FALSE = ('false', '0', 'no', 'off')


def _flag(context, name):
    """Return a true/false launch argument as a bool; anything else is an error naming it."""
    value = LaunchConfiguration(name).perform(context).strip().lower()
    if value not in _TRUE + _FALSE:
        raise ValueError(f'launch argument {name}:={value!r}: expected true or false')
    return value in _TRUE


def _number(context, name):
    """Return a numeric launch argument as a float (None when empty)."""
    value = LaunchConfiguration(name).perform(context).strip()
    if not value:
        return None
    try:
        return float(value)
    except ValueError:
        raise ValueError(f'launch argument {name}:={value!r}: expected a number') from None


def _in_package(executable):
    """
    Return the Node keywords that start one of this package's executables.

    :returns: ``package``/``executable`` when the ament index knows the package and it has
        the executable (``ros2 run``'s lookup), else the executable's path on PATH.
    :raises RuntimeError: when neither has it.
    """
    try:
        from ament_index_python.packages import get_package_prefix
        prefix = Path(get_package_prefix(PACKAGE))
    except (ImportError, LookupError, ValueError):
        prefix = None
    if prefix is not None and (prefix / 'lib' / PACKAGE / executable).is_file():
        return {'package': PACKAGE, 'executable': executable}
    found = shutil.which(executable)
    if found is None:
        raise RuntimeError(
            f'{executable} not found: neither in the package {PACKAGE} of the ament index '
            f'(source the workspace: source install/setup.bash) nor on PATH')
    return {'executable': found}


def _rviz_found():
    """Return whether rviz2 can be started (a package of the ament index, or on PATH)."""
    try:
        from ament_index_python.packages import get_package_prefix
        get_package_prefix('rviz2')
        return True
    except (ImportError, LookupError, ValueError):
        return shutil.which('rviz2') is not None


def _scene(context):
    """Return the scene argument, a relative path made absolute (None when empty)."""
    scene = LaunchConfiguration('scene').perform(context).strip()
    if not scene:
        return None
    # A path (not a built-in name): absolute, so that the node's log names the very file.
    if os.sep in scene or scene.endswith(('.yaml', '.yml')):
        scene = os.path.abspath(os.path.expanduser(scene))
    return scene


def _frame_prefix(context, namespace):
    """Return the node's frame_prefix: the argument's, else the namespace's (as the node's)."""
    prefix = LaunchConfiguration('frame_prefix').perform(context).strip()
    if prefix:
        return prefix
    path = namespace.strip('/')  # rigid_body_sim.messages.frames.default_frame_prefix
    return f'{path}/' if path else ''


def _actions(context):
    """Return the node, and RViz and the arrow helper if asked, from the arguments' values."""
    namespace = LaunchConfiguration('namespace').perform(context).strip()
    overrides = {}
    scene = _scene(context)
    if scene is not None:
        overrides['scene'] = scene
    rate = _number(context, 'rate')
    if rate is not None:
        overrides['rate'] = rate
    integrator = LaunchConfiguration('integrator').perform(context).strip()
    if integrator:
        overrides['integrator'] = integrator
    overrides['publish_clock'] = _flag(context, 'publish_clock')
    if LaunchConfiguration('frame_prefix').perform(context).strip():
        overrides['frame_prefix'] = _frame_prefix(context, namespace)
    use_sim_time = _flag(context, 'use_sim_time')
    parameters = []
    params_file = LaunchConfiguration('params_file').perform(context).strip()
    if params_file:
        parameters.append(os.path.abspath(os.path.expanduser(params_file)))
    parameters.append(overrides)
    actions = [Node(**_in_package('rigid_body_node'), namespace=namespace,
                    parameters=parameters, output='screen', emulate_tty=True,
                    on_exit=[Shutdown(reason='rigid_body_node exited')])]
    if _flag(context, 'momentum_arrow'):
        scale = _number(context, 'momentum_scale')
        if scale is None or not scale > 0.0:
            raise ValueError(f'launch argument momentum_scale:={scale!r}: expected a number '
                             '> 0 (m per N m s)')
        actions.append(Node(**_in_package('angular_momentum_arrow'), namespace=namespace,
                            parameters=[{'scale': scale, 'use_sim_time': use_sim_time}],
                            output='screen'))
    if _flag(context, 'rviz'):
        if not _rviz_found():
            actions.append(LogInfo(msg='rviz:=true, but rviz2 is not installed here (it '
                                   'comes with ROS 2, not with pip): the node runs without '
                                   'it'))
        else:
            config = LaunchConfiguration('rviz_config').perform(context)
            frame = LaunchConfiguration('fixed_frame').perform(context).strip() or (
                _frame_prefix(context, namespace) + 'world').lstrip('/')
            actions.append(Node(package='rviz2', executable='rviz2', name='rviz2',
                                namespace=namespace, arguments=['-d', config, '-f', frame],
                                parameters=[{'use_sim_time': use_sim_time}],
                                output='screen'))
    return actions


def generate_launch_description():
    """Return the launch description: the arguments, then what their values start."""
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, default, description in ARGUMENTS]
        + [OpaqueFunction(function=_actions)])

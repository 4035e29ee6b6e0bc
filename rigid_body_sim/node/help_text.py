"""
The ``rigid_body_node --help`` text: what the node does, its interface and its parameters.

Built from the parameter specifications (:data:`rigid_body_sim.node.parameters.PARAMETERS`)
and the built-in scenes, so it cannot fall out of step with what the node declares.
"""

import shutil
import textwrap

from .parameters import NAMESPACE_VALUE
from .parameters import NOT_SET
from .parameters import PARAMETERS
from .parameters import SCENE_VALUE
from ..scenes import scene_names

__all__ = ['help_text']

_KINDS = {float: 'double', int: 'int', str: 'string', bool: 'bool', list: 'double[]'}

_INTRODUCTION = """\
usage: rigid_body_node [-h] [--ros-args -p NAME:=VALUE ... --params-file FILE
                        -r __ns:=/NAMESPACE -r __node:=NAME]

Simulate one rigid body of a scene (body, initial state, effects such as gravity or a
pivot) and publish its state at `rate` Hz; push it through the torque and wrench
topics when the scene has the effect external_wrench.  Ctrl-C or SIGTERM stop it
(exit code 0); an invalid configuration is one error line and exit code 1.

published (relative names; QoS reliable, keep-last 1000 (1 s at 1 kHz), volatile):
  pose              geometry_msgs/PoseStamped      COM position, orientation (body to world)
  twist             geometry_msgs/Twist            COM velocity, angular velocity (world)
  angular_momentum  geometry_msgs/Vector3Stamped   L about the COM (world)
  odom              nav_msgs/Odometry              pose (world), twist (body frame)
  marker            visualization_msgs/Marker      the scene's drawing, for RViz
  imu               sensor_msgs/Imu                the simulated IMU (frame imu_frame)
  /tf               tf2_msgs/TFMessage             world_frame -> body_frame, every tick
  /tf_static        tf2_msgs/TFMessage             body_frame -> imu_frame (transient local)
  /diagnostics      diagnostic_msgs/DiagnosticArray  1 Hz: rates, step time, drift
  /clock            rosgraph_msgs/Clock            only with publish_clock:=true
subscribed (only with external_wrench; frame_id world_frame or empty: world-fixed,
            body_frame: body-fixed):
  torque            geometry_msgs/Vector3Stamped   N m
  wrench            geometry_msgs/WrenchStamped    force through the COM (N), torque (N m)
services:
  reset             std_srvs/Trigger               back to the initial state at time 0
  pause             std_srvs/SetBool               true: freeze the state, false: resume

frames: frame_prefix (default: the namespace, 'sat1/' in /sat1) + world_frame, body_frame,
imu_frame; REP 105 names: --params-file config/rep105.yaml (odom, base_link, imu_link).

parameters (ros2 param describe <node> <name> says the same; 'run time' ones can be set
while it runs):"""

_EXAMPLES = """
built-in scenes (rigid-body-sim scenes describes them):
{scenes}

examples:
  rigid_body_node --ros-args -p scene:=heavy_top
  rigid_body_node --ros-args -p integrator:=rk4 -p rate:=1000.0 -r __ns:=/sat1
  rigid_body_node --ros-args -p body.shape:=box -p body.size:="[0.3, 0.2, 0.1]"
  ros2 topic pub --once /torque geometry_msgs/msg/Vector3Stamped "{{vector: {{z: 0.5}}}}"
  ros2 param set /rigid_body_sim integrator splitting
  ros2 param set /rigid_body_sim tolerance 1.0e-6    (1e-6 would be read as a string)
"""


def _default(spec):
    if spec.default is NOT_SET:
        return "the scene's (shown once running)"
    if spec.default is SCENE_VALUE:
        return "the scene's"
    if spec.default is NAMESPACE_VALUE:
        return "the namespace's ('sat1/' in /sat1)"
    return repr(spec.default) if isinstance(spec.default, str) else str(spec.default).lower() \
        if isinstance(spec.default, bool) else str(spec.default)


def help_text(width=None):
    """Return the help text, wrapped to `width` columns (default: the terminal's, <= 100)."""
    width = width or min(100, shutil.get_terminal_size((100, 24)).columns)
    lines = [_INTRODUCTION]
    for spec in PARAMETERS:
        facts = [_KINDS[spec.kind], f'default {_default(spec)}',
                 'run time' if not spec.read_only else 'read-only']
        if spec.value_range is not None:
            facts.append(f'{spec.value_range[0]:g} to {spec.value_range[1]:g}')
        lines.append(f'  {spec.name} ({", ".join(facts)})')
        text = spec.description + (f'  ({spec.constraints})' if spec.constraints else '')
        lines.extend(textwrap.wrap(text, width=width, initial_indent=' ' * 6,
                                   subsequent_indent=' ' * 6, break_on_hyphens=False))
    scenes = textwrap.fill(', '.join(scene_names()), width=width, initial_indent='  ',
                           subsequent_indent='  ')
    lines.append(_EXAMPLES.format(scenes=scenes))
    return '\n'.join(lines)

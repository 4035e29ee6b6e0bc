"""
Plot the motion recorded in a bag, from the messages alone.

Everything comes from two of the node's topics, so any bag of the node works (recorded
live, by ``ros2 bag record``, or written offline), with no knowledge of the body:

- ``odom`` (nav_msgs/Odometry): the orientation q and COM position in the world frame, and
  the body-frame angular velocity Omega (the node gives odom's twist in the body frame);
- ``angular_momentum`` (geometry_msgs/Vector3Stamped): L about the COM, world frame.

Rotational kinetic energy needs no inertia: T_rot = 1/2 omega . L = 1/2 Omega . (R^T L),
with R the rotation of q.  Messages of the two topics are paired by their header stamp
(each tick stamps all of them alike).  Translational energy would need the mass, which no
message carries, so the energy plotted is the rotational one: constant when the body is
torque-free about its COM (a free body, also under uniform gravity), not under a pivot or
drag.

The figure (matplotlib, Agg backend) has four panels: Omega's components against time;
the relative drift of T_rot and |L| against time; the orientation as the paths the tips of
the body's x, y, z axes trace on the unit sphere (world frame), until the busiest has gone
round four times (an axis spinning many times faster than the others, such as a top's,
shows only its ends); and the COM path when the COM moves, else the polhode (the path of
Omega in the body frame).
"""

from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader

from .bag_writer import typestore

__all__ = ['BagMotion', 'com_moves', 'read_motion', 'plot_bag', 'plot_motion']

_ODOMETRY = 'nav_msgs/msg/Odometry'
_VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
# The COM "moves" when its path spans more than this (m): below, it is at rest up to
# round-off and its panel shows the polhode instead.
_MOTION_THRESHOLD = 1e-9
_AXIS_COLORS = ('tab:red', 'tab:green', 'tab:blue')
# An axis whose tip travels more than this many turns, and 20 times as far as the slowest
# axis, spins: its path would cover the sphere.
_FAST_TURNS = 10
# Turns of the busiest drawn axis shown on the sphere.
_DRAWN_TURNS = 4
# Points per 3D path: more only slow the drawing down, the lines look the same.
_PATH_POINTS = 6000
_CUSTOM_PREFIX = 'rigid_body_sim.'


class BagMotion:
    """
    The motion in a bag, as arrays over the paired ticks (n of them).

    Attributes
    ----------
    time : ndarray (n,)
        Header stamps in s, from the first.
    start_stamp : int
        The first header stamp, ns.
    quaternion : ndarray (n, 4)
        Orientation (x, y, z, w), body to world.
    position : ndarray (n, 3)
        COM position in m, world frame.
    angular_velocity_body : ndarray (n, 3)
        Omega in rad/s, body frame.
    angular_momentum : ndarray (n, 3)
        L in kg m^2/s, world frame.
    custom_data : dict
        The bag's custom data (scene, integrator, ... of an offline run).

    """

    def __init__(self, stamps, quaternion, position, angular_velocity_body, angular_momentum,
                 custom_data, name):
        stamps = np.asarray(stamps, dtype=np.int64)
        self.start_stamp = int(stamps[0])
        self.time = (stamps - stamps[0]) * 1e-9
        self.quaternion = np.asarray(quaternion, dtype=float)
        self.position = np.asarray(position, dtype=float)
        self.angular_velocity_body = np.asarray(angular_velocity_body, dtype=float)
        self.angular_momentum = np.asarray(angular_momentum, dtype=float)
        self.custom_data = dict(custom_data or {})
        self.name = name

    @property
    def rotation(self):
        """Return R (n, 3, 3), body to world, of the quaternions."""
        x, y, z, w = self.quaternion.T
        return np.stack([
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ], -2)

    @property
    def rotational_energy(self):
        """Return T_rot = 1/2 Omega . (R^T L) in J, (n,)."""
        momentum_body = np.einsum('nji,nj->ni', self.rotation, self.angular_momentum)
        return 0.5 * np.einsum('ni,ni->n', self.angular_velocity_body, momentum_body)

    @property
    def momentum_magnitude(self):
        """Return |L| in kg m^2/s, (n,)."""
        return np.linalg.norm(self.angular_momentum, axis=1)


def _find_topic(connections, suffix, message_type, namespace):
    wanted = f'{namespace}/{suffix}'
    candidates = [c for c in connections if c.msgtype == message_type]
    for connection in candidates:
        if connection.topic == wanted:
            return connection
    matching = [c for c in candidates if c.topic.endswith('/' + suffix)]
    if len(matching) == 1:
        return matching[0]
    found = ', '.join(f'{c.topic} ({c.msgtype})' for c in connections) or 'none'
    raise ValueError(f'the bag has no single {message_type} topic named {wanted!r} (or '
                     f'ending in /{suffix}); its topics: {found}')


def read_motion(bag, namespace=''):
    """
    Read the node's odom and angular_momentum topics of a bag; return a :class:`BagMotion`.

    Raises
    ------
    ValueError
        If the bag cannot be read or lacks the topics, or no stamp is in both.

    """
    from rosbags.rosbag2.errors import ReaderError

    bag = Path(bag)
    namespace = (namespace or '').rstrip('/')
    store = typestore()
    odometry = {}
    momentum = {}
    try:
        with Reader(bag) as reader:
            odom = _find_topic(reader.connections, 'odom', _ODOMETRY, namespace)
            angular = _find_topic(reader.connections, 'angular_momentum', _VECTOR3_STAMPED,
                                  namespace)
            for connection, _, raw in reader.messages(connections=[odom, angular]):
                message = store.deserialize_cdr(raw, connection.msgtype)
                stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
                if connection.topic == odom.topic:
                    pose, twist = message.pose.pose, message.twist.twist.angular
                    odometry[stamp] = (
                        (pose.orientation.x, pose.orientation.y, pose.orientation.z,
                         pose.orientation.w),
                        (pose.position.x, pose.position.y, pose.position.z),
                        (twist.x, twist.y, twist.z))
                else:
                    vector = message.vector
                    momentum[stamp] = (vector.x, vector.y, vector.z)
            # rosbags has no public accessor for custom_data.
            custom = getattr(reader.storage.metadata, 'custom', None) or {}
    except FileNotFoundError:
        raise ValueError(f'no bag at {bag}') from None
    except ReaderError as error:
        raise ValueError(f'cannot read the bag {bag}: {error} (if a recorder was killed, '
                         f'try: rigid-body-sim record --recover {bag})') from None
    stamps = sorted(set(odometry) & set(momentum))
    if not stamps:
        raise ValueError(f'{bag}: no stamp has both an odom and an angular_momentum message')
    rows = [odometry[stamp] for stamp in stamps]
    return BagMotion(stamps, [row[0] for row in rows], [row[1] for row in rows],
                     [row[2] for row in rows], [momentum[stamp] for stamp in stamps],
                     custom, bag.name)


def _relative_drift(values):
    reference = values[0]
    if reference == 0.0:
        return values - reference, 'absolute'
    return (values - reference) / abs(reference), 'relative'


def plot_motion(motion, out):
    """Draw the four panels of `motion` (a :class:`BagMotion`) into the PNG `out`."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot

    figure = pyplot.figure(figsize=(13.0, 10.0), layout='constrained')
    grid = figure.add_gridspec(2, 2)
    time = motion.time

    axes = figure.add_subplot(grid[0, 0])
    omega = motion.angular_velocity_body
    peaks = np.abs(omega).max(axis=0)
    order = np.argsort(peaks)
    # A fast spin about one axis would flatten the other two components to a line: it
    # then gets the right-hand axis of its own.
    dominant = order[2] if peaks[order[2]] > 10.0 * max(peaks[order[1]], 1e-300) else None
    lines = []
    for k, (label, color) in enumerate(zip('xyz', _AXIS_COLORS)):
        target = axes
        if k == dominant:
            target = axes.twinx()
            target.set_ylabel(f'$\\Omega_{label}$ [rad/s] (right axis)', color=color)
            target.tick_params(axis='y', colors=color)
        lines += target.plot(time, omega[:, k], color=color, label=f'$\\Omega_{label}$')
    axes.set(title='Angular velocity in the body frame', xlabel='time [s]',
             ylabel='$\\Omega$ [rad/s]')
    axes.legend(lines, [line.get_label() for line in lines], loc='best')
    axes.grid(True, alpha=0.3)

    axes = figure.add_subplot(grid[0, 1])
    energy, energy_kind = _relative_drift(motion.rotational_energy)
    magnitude, magnitude_kind = _relative_drift(motion.momentum_magnitude)
    axes.plot(time, energy, color='tab:orange',
              label=f'$T_{{rot}} = \\frac{{1}}{{2}}\\omega\\cdot L$ ({energy_kind}; '
                    f'$T_0$ = {motion.rotational_energy[0]:.6g} J)')
    axes.plot(time, magnitude, color='tab:purple', linestyle='--',
              label=f'$|L|$ ({magnitude_kind}; $|L_0|$ = {motion.momentum_magnitude[0]:.6g} '
                    'kg m$^2$/s)')
    title = 'Drift of rotational energy and $|L|$ since the first message'
    torques = _torque_effects(motion)
    if torques:
        title += f'\n(not conserved here: torque about the COM from {", ".join(torques)})'
    axes.set(title=title, xlabel='time [s]', ylabel='(X(t) - X(0)) / |X(0)|')
    axes.ticklabel_format(axis='y', style='sci', scilimits=(-2, 3), useMathText=True)
    axes.legend(loc='best', fontsize='small')
    axes.grid(True, alpha=0.3)

    stride = max(1, -(-len(time) // _PATH_POINTS))
    axes = figure.add_subplot(grid[1, 0], projection='3d')
    _unit_sphere(axes)
    rotation = motion.rotation
    # Distance each axis tip has travelled on the sphere up to each message (rad).
    travelled = np.vstack([np.concatenate(([0.0], np.cumsum(np.linalg.norm(
        np.diff(rotation[:, :, k], axis=0), axis=1)))) for k in range(3)])
    lengths = travelled[:, -1]
    spinning = [lengths[k] > _FAST_TURNS * 2.0 * np.pi and lengths[k] > 20.0 * lengths.min()
                for k in range(3)]
    # The other axes are drawn until one of them has gone round _DRAWN_TURNS times: more
    # loops would only tangle.
    drawn = [k for k in range(3) if not spinning[k]]
    end = len(time)
    if drawn:
        beyond = np.flatnonzero(travelled[drawn].max(axis=0) > _DRAWN_TURNS * 2.0 * np.pi)
        if beyond.size:
            end = int(beyond[0]) + 1
    window_stride = max(1, -(-end // _PATH_POINTS))
    for k, (label, color) in enumerate(zip('xyz', _AXIS_COLORS)):
        tips = rotation[:, :, k]
        if spinning[k]:
            # A fast-spinning axis would paint the whole sphere: only its ends are shown.
            label = f'body {label} axis (spins: {lengths[k] / (2 * np.pi):.0f} turns, ends only)'
            last = tips[-1]
        else:
            path = np.vstack((tips[:end:window_stride], tips[end - 1:end]))
            axes.plot(path[:, 0], path[:, 1], path[:, 2], color=color, linewidth=0.7,
                      alpha=0.85)
            label = f'body {label} axis'
            last = tips[end - 1]
        axes.plot([], [], color=color, label=label)
        axes.scatter(*tips[0], color=color, marker='o', s=25)
        axes.scatter(*last, color=color, marker='s', s=25)
    shown = 'o start, \u25a1 end' if end == len(time) else \
        f'o start, \u25a1 at {time[end - 1]:.3g} s: the first {_DRAWN_TURNS} turns'
    axes.set(title=f'Orientation: body axes on the unit sphere ({shown})',
             xlabel='world x', ylabel='world y', zlabel='world z')
    _equal_3d(axes, np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]))
    axes.legend(loc='upper left', fontsize='small')

    axes = figure.add_subplot(grid[1, 1], projection='3d')
    position = motion.position
    if com_moves(motion):
        path = np.vstack((position[::stride], position[-1:]))
        axes.plot(path[:, 0], path[:, 1], path[:, 2], color='tab:blue')
        axes.scatter(*position[0], color='tab:green', marker='o', s=30, label='start')
        axes.scatter(*position[-1], color='tab:red', marker='s', s=30, label='end')
        axes.set(title='Centre of mass path (world frame)', xlabel='x [m]', ylabel='y [m]',
                 zlabel='z [m]')
        _equal_3d(axes, position)
    else:
        omega = motion.angular_velocity_body
        path = np.vstack((omega[::stride], omega[-1:]))
        axes.plot(path[:, 0], path[:, 1], path[:, 2], color='tab:blue', linewidth=0.8)
        axes.scatter(*omega[0], color='tab:green', marker='o', s=30, label='start')
        axes.scatter(*omega[-1], color='tab:red', marker='s', s=30, label='end')
        at = ', '.join(f'{c:.3g}' for c in position[0])
        axes.set(title=f'Polhode: $\\Omega$ in the body frame (COM at rest at ({at}) m)',
                 xlabel='$\\Omega_x$ [rad/s]', ylabel='$\\Omega_y$ [rad/s]',
                 zlabel='$\\Omega_z$ [rad/s]')
        _equal_3d(axes, omega)
    axes.legend(loc='upper left', fontsize='small')

    figure.suptitle(_title(motion))
    out = Path(out)
    figure.savefig(out, dpi=110)
    pyplot.close(figure)
    return out


def com_moves(motion):
    """Return True if the COM path spans more than round-off (1e-9 m) in the bag."""
    return bool(np.ptp(motion.position, axis=0).max() > _MOTION_THRESHOLD)


def _torque_effects(motion):
    # Offline bags name the scene's effects; those that torque the body about its COM
    # (dissipation keeps |L| but drains the energy).
    effects = motion.custom_data.get(_CUSTOM_PREFIX + 'effects', '')
    return [name for name in (e.strip() for e in effects.split(','))
            if name in ('pivot', 'drag', 'dissipation')]


def _title(motion):
    custom = {key[len(_CUSTOM_PREFIX):]: value for key, value in motion.custom_data.items()
              if key.startswith(_CUSTOM_PREFIX)}
    parts = [f'bag {motion.name}', f'{len(motion.time)} ticks over {motion.time[-1]:g} s']
    if 'scene' in custom:
        parts.append(f'scene {custom["scene"]}')
    if 'integrator' in custom:
        rate = custom.get('rate')
        parts.append(f'{custom["integrator"]}' + (f' at {float(rate):g} Hz' if rate else ''))
    if 'effects' in custom:
        parts.append(f'effects: {custom["effects"]}')
    return ' \u2014 '.join(parts)


def _unit_sphere(axes):
    u = np.linspace(0.0, 2.0 * np.pi, 37)
    v = np.linspace(0.0, np.pi, 19)
    axes.plot_wireframe(np.outer(np.cos(u), np.sin(v)), np.outer(np.sin(u), np.sin(v)),
                        np.outer(np.ones_like(u), np.cos(v)), color='0.88', linewidth=0.3)


def _equal_3d(axes, points):
    """Give the 3D axes equal scales around the points' bounding box."""
    low, high = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (low + high)
    half = 0.5 * max(float((high - low).max()), 1e-12)
    axes.set_xlim(centre[0] - half, centre[0] + half)
    axes.set_ylim(centre[1] - half, centre[1] + half)
    axes.set_zlim(centre[2] - half, centre[2] + half)
    axes.set_box_aspect((1.0, 1.0, 1.0))


def plot_bag(bag, out=None, namespace=''):
    """Read a bag and plot it; return the PNG path (default ``<bag>.png`` beside it)."""
    motion = read_motion(bag, namespace)
    if out is None:
        bag = Path(bag)
        out = bag.with_name(bag.name + '.png')
    return plot_motion(motion, out)

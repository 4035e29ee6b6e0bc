"""
The peer simulator: the benchmark bodies in MuJoCo (PyPI ``mujoco``, an optional extra).

One free body with the case's mass and inertia tensor about its COM (``fullinertia`` when
the tensor is not diagonal, else ``diaginertia``) at the body origin, gravity 0, contacts
and constraints disabled (there are none to solve; this keeps MuJoCo's step as cheap as it
can be for this problem), with one of MuJoCo's integrators at timestep dt.

MuJoCo's conventions, converted at this boundary: the free joint's qpos is the body-origin
position (world) followed by the quaternion (w, x, y, z), body to world; its qvel is the
world linear velocity followed by the BODY-frame angular velocity Omega.  Energy and angular
momentum are computed here from qvel with the case's own inertia tensor, exactly as for the
project's integrators: T = 1/2 Omega . I_b Omega + 1/2 m |v|^2, L = R I_b Omega.
"""

import numpy as np

from ..physics import matrix_from_quaternion

__all__ = ['mujoco_available', 'mujoco_version', 'MujocoPeer', 'MUJOCO_INTEGRATORS',
           'mjcf_model']

# Benchmark name -> MuJoCo's integrator name (mjOption.integrator).  'implicit' is left
# out: for a free body without damping it only adds the Coriolis derivative to
# 'implicitfast', at a higher cost.
MUJOCO_INTEGRATORS = {
    'mujoco_euler': 'Euler',
    'mujoco_rk4': 'RK4',
    'mujoco_implicitfast': 'implicitfast',
}

# What to install for the peer, for the one line `rigid-body-sim bench` prints without it.
INSTALL_HINT = 'pip install -r requirements-test.txt (make test installs it)'

try:
    import mujoco
except ImportError:  # test set only: the benchmark runs without the peer and says so
    mujoco = None


def mujoco_available():
    """Return True when ``import mujoco`` works."""
    return mujoco is not None


def mujoco_version():
    """Return MuJoCo's version string, or None when it is not installed."""
    return None if mujoco is None else mujoco.__version__


def _number(value):
    # repr() round-trips a double exactly, so MuJoCo parses the very same mass properties.
    return repr(float(value))


def mjcf_model(body, integrator, dt):
    """
    Return the MJCF text of one free `body` with MuJoCo's `integrator` at timestep dt.

    Parameters
    ----------
    body : RigidBody
        Mass (kg) and inertia tensor about the COM in the body frame (kg m^2).
    integrator : str
        MuJoCo's name: 'Euler', 'RK4', 'implicitfast' or 'implicit'.
    dt : float
        Time step in s.

    """
    inertia = np.asarray(body.inertia)
    if np.any(inertia - np.diag(np.diag(inertia))):
        ixx, iyy, izz = np.diag(inertia)
        moments = (f'fullinertia="{_number(ixx)} {_number(iyy)} {_number(izz)} '
                   f'{_number(inertia[0, 1])} {_number(inertia[0, 2])} '
                   f'{_number(inertia[1, 2])}"')
    else:
        moments = 'diaginertia="{} {} {}"'.format(*(_number(v) for v in np.diag(inertia)))
    return f"""<mujoco model="rigid_body_sim_benchmark">
  <option timestep="{_number(dt)}" integrator="{integrator}" gravity="0 0 0">
    <flag contact="disable" constraint="disable"/>
  </option>
  <worldbody>
    <body name="body">
      <freejoint name="free"/>
      <inertial pos="0 0 0" mass="{_number(body.mass)}" {moments}/>
    </body>
  </worldbody>
</mujoco>
"""


class MujocoPeer:
    """
    One benchmark case simulated by MuJoCo.

    Parameters
    ----------
    body : RigidBody
    state : State
        Initial state (world frame): orientation, COM position, momenta.
    integrator : str
        A key of :data:`MUJOCO_INTEGRATORS` ('mujoco_euler', ...).
    dt : float
        Time step in s.

    """

    def __init__(self, body, state, integrator, dt):
        if mujoco is None:
            raise RuntimeError(f'mujoco is not installed ({INSTALL_HINT})')
        if integrator not in MUJOCO_INTEGRATORS:
            raise ValueError(f'unknown MuJoCo integrator {integrator!r}; valid: '
                             f'{", ".join(MUJOCO_INTEGRATORS)}')
        self.body = body
        self.initial_state = state
        self.model = mujoco.MjModel.from_xml_string(
            mjcf_model(body, MUJOCO_INTEGRATORS[integrator], dt))
        self.data = mujoco.MjData(self.model)
        self.reset()

    def reset(self):
        """Set MuJoCo's state to the initial state at time 0."""
        mujoco.mj_resetData(self.model, self.data)
        state = self.initial_state
        x, y, z, w = state.quaternion
        self.data.qpos[:] = np.concatenate([state.position, [w, x, y, z]])
        self.data.qvel[:] = np.concatenate([state.velocity(self.body),
                                            state.angular_velocity_body(self.body)])

    def step(self, steps):
        """Advance `steps` MuJoCo steps (one call, MuJoCo's own C loop)."""
        mujoco.mj_step(self.model, self.data, nstep=int(steps))

    @property
    def rotation(self):
        """Get the orientation R (body to world) from qpos."""
        w, x, y, z = self.data.qpos[3:7]
        return matrix_from_quaternion([x, y, z, w])

    @property
    def angular_velocity_body(self):
        """Get the body angular velocity Omega (rad/s), qvel's angular part."""
        return np.array(self.data.qvel[3:6])

    @property
    def angular_momentum(self):
        """Get the world angular momentum L = R I_b Omega (kg m^2/s)."""
        return self.rotation @ (self.body.inertia @ self.angular_velocity_body)

    def kinetic_energy(self):
        """Return T = 1/2 Omega . I_b Omega + 1/2 m |v|^2 (J)."""
        omega = self.angular_velocity_body
        velocity = np.array(self.data.qvel[:3])
        return (0.5 * omega @ (self.body.inertia @ omega)
                + 0.5 * self.body.mass * velocity @ velocity)

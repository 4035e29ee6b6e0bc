"""drag: linear and quadratic resistance of the surrounding fluid, on translation and rotation."""

from __future__ import annotations

import math

import numpy as np

from .registry import check_number
from .registry import Effect
from .registry import register_effect
from ..body import RigidBody
from ..kernels.algebra import rotate
from ..kernels.algebra import rotate_back
from ..kernels.layout import inverse_inertia_times
from ..kernels.model import Array
from ..kernels.model import Wrench
from ..kernels.model import wrench_term


MAX_COEFFICIENT = 1.0e6
"""The largest drag coefficient accepted (SI): far beyond any fluid (water on a 1 m body is
~1e3), and products with speeds of 1e6 m/s stay finite."""


@wrench_term
def fluid_resistance(state: Array, time: float, parameters: Array) -> Wrench:
    """
    Return the drag force (N) and torque (N m), world frame, of a packed physical state.

    parameters: c1, c2, k1, k2, 1/m, I_b^-1 (9, row-major).  F = -(c1 + c2 |v|) v with
    v = p / m; tau = -(k1 + k2 |omega|) omega with omega = R I_b^-1 R^T L.  A part whose
    coefficients are both zero is not computed.
    """
    fx = fy = fz = tx = ty = tz = 0.0
    if parameters[0] != 0.0 or parameters[1] != 0.0:
        vx, vy, vz = (state[7] * parameters[4], state[8] * parameters[4],
                      state[9] * parameters[4])
        scale = -(parameters[0] + parameters[1] * math.sqrt(vx * vx + vy * vy + vz * vz))
        fx, fy, fz = scale * vx, scale * vy, scale * vz
    if parameters[2] != 0.0 or parameters[3] != 0.0:
        q = (state[0], state[1], state[2], state[3])
        ox, oy, oz = inverse_inertia_times(parameters[5:14], rotate_back(
            q, (state[10], state[11], state[12])))
        # |omega| from the body frame's Omega (the same length): the square root then runs
        # beside the rotation to the world frame, not after it (a kick's midpoint rule calls
        # this twice in a row, so its latency is the step's).
        scale = -(parameters[2] + parameters[3] * math.sqrt(ox * ox + oy * oy + oz * oz))
        wx, wy, wz = rotate(q, (ox, oy, oz))
        tx, ty, tz = scale * wx, scale * wy, scale * wz
    return fx, fy, fz, tx, ty, tz


@register_effect('drag')
class Drag(Effect):
    """
    Fluid drag: F = -(c1 + c2 |v|) v through the COM, tau = -(k1 + k2 |omega|) omega.

    v is the COM velocity and omega the angular velocity, both world frame.  The wrench
    depends on the momenta, so it is ``momentum_dependent`` (the kicks keep their order
    for it); a part whose coefficients are zero is not computed, so rotational drag alone
    never touches the translation.

    Parameters
    ----------
    linear : float
        c1 in N s/m (>= 0, default 0).
    quadratic : float
        c2 in N s^2/m^2 (>= 0, default 0).
    rotational_linear : float
        k1 in N m s (>= 0, default 0).
    rotational_quadratic : float
        k2 in N m s^2 (>= 0, default 0).

    """

    momentum_dependent = True
    reads_state = True
    compiled_wrench = staticmethod(fluid_resistance)
    units = {'linear': 'N s/m', 'quadratic': 'N s^2/m^2', 'rotational_linear': 'N m s',
             'rotational_quadratic': 'N m s^2'}
    example = {'linear': 0.2, 'quadratic': 0.05, 'rotational_linear': 0.01,
               'rotational_quadratic': 0.002}

    def __init__(self, linear: float = 0.0, quadratic: float = 0.0,
                 rotational_linear: float = 0.0, rotational_quadratic: float = 0.0) -> None:
        self.linear = check_number(linear, 'linear', 'N s/m', minimum=0.0,
                                   maximum=MAX_COEFFICIENT)
        self.quadratic = check_number(quadratic, 'quadratic', 'N s^2/m^2', minimum=0.0,
                                      maximum=MAX_COEFFICIENT)
        self.rotational_linear = check_number(rotational_linear, 'rotational_linear', 'N m s',
                                              minimum=0.0, maximum=MAX_COEFFICIENT)
        self.rotational_quadratic = check_number(rotational_quadratic, 'rotational_quadratic',
                                                 'N m s^2', minimum=0.0,
                                                 maximum=MAX_COEFFICIENT)
        translational = self.linear > 0.0 or self.quadratic > 0.0
        self.exerts_torque = self.rotational_linear > 0.0 or self.rotational_quadratic > 0.0
        if not (translational or self.exerts_torque):
            raise ValueError('drag: every coefficient is zero; give one, or drop the effect')

    def damping_rate(self, body: RigidBody) -> tuple[float, str]:
        """
        Return (the fastest linear decay rate in 1/s, what it is) on `body`.

        c1 / m for the translation, k1 / I1 about the axis of least inertia for the
        rotation: the rates of dp/dt = -c1 p / m and dL/dt = -k1 omega.  The quadratic parts
        damp at c2 |v| / m and k2 |omega| / I1, which grow with the speed: not counted.
        """
        rotational = self.rotational_linear / float(body.principal_moments[0])
        translational = self.linear / body.mass
        if rotational >= translational:
            return rotational, (f'rotational_linear {self.rotational_linear:g} N m s over the '
                                f'least moment {float(body.principal_moments[0]):.4g} kg m^2')
        return translational, f'linear {self.linear:g} N s/m over the mass {body.mass:.4g} kg'

    def wrench_parameters(self, body: RigidBody) -> Array:
        """Return c1, c2, k1, k2, 1/m and I_b^-1 (row-major) of `body`."""
        return np.concatenate([[self.linear, self.quadratic, self.rotational_linear,
                                self.rotational_quadratic, 1.0 / body.mass],
                               body.inertia_inverse.reshape(9)])

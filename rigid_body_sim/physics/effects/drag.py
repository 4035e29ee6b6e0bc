"""drag: linear and quadratic resistance of the surrounding fluid, on translation and rotation."""

import numpy as np

from .registry import check_number
from .registry import Effect
from .registry import register_effect

_NO_VECTOR = np.zeros(3)
_NO_VECTOR.flags.writeable = False


@register_effect('drag')
class Drag(Effect):
    """
    Fluid drag: F = -(c1 + c2 |v|) v through the COM, tau = -(k1 + k2 |omega|) omega.

    v is the COM velocity and omega the angular velocity, both world frame.  The wrench
    depends on the momenta, so it is marked ``momentum_dependent`` (the readable
    integrators then keep their order); a part whose coefficients are zero is not computed,
    so rotational drag alone never touches the translation.

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

    def __init__(self, linear=0.0, quadratic=0.0, rotational_linear=0.0,
                 rotational_quadratic=0.0):
        self.linear = check_number(linear, 'linear', 'N s/m', minimum=0.0)
        self.quadratic = check_number(quadratic, 'quadratic', 'N s^2/m^2', minimum=0.0)
        self.rotational_linear = check_number(rotational_linear, 'rotational_linear', 'N m s',
                                              minimum=0.0)
        self.rotational_quadratic = check_number(rotational_quadratic, 'rotational_quadratic',
                                                 'N m s^2', minimum=0.0)
        self._translational = self.linear > 0.0 or self.quadratic > 0.0
        self._rotational = self.rotational_linear > 0.0 or self.rotational_quadratic > 0.0
        if not (self._translational or self._rotational):
            raise ValueError('drag: every coefficient is zero; give one, or drop the effect')

    def wrench(self, body, state, time):
        """Return the drag force (N, world) and torque about the COM (N m, world)."""
        force = torque = _NO_VECTOR
        if self._translational:
            velocity = state.linear_momentum / body.mass
            force = -(self.linear + self.quadratic * np.sqrt(velocity @ velocity)) * velocity
        if self._rotational:
            omega = state.angular_velocity(body)
            torque = -(self.rotational_linear
                       + self.rotational_quadratic * np.sqrt(omega @ omega)) * omega
        return force, torque

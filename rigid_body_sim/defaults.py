"""
The default body and initial state: a T-handle spun near its intermediate axis.

Shared by ``rigid-body-sim run`` and the node, so a newcomer sees the same thing in both:
the Dzhanibekov flip, which with these numbers first happens after about 7.2 s and then
repeats every ~14.4 s of simulated time (half the 28.7 s period of the body rates).
"""

import numpy as np

from .physics import RigidBody
from .physics import State

# Principal moments (kg m^2) of the standard T-handle test body, I = (1, 2, 3).
DEFAULT_INERTIA = (1.0, 2.0, 3.0)
DEFAULT_MASS = 1.0
# Body angular velocity (rad/s): 2 rad/s about the middle axis with a 1e-3-relative nudge.
DEFAULT_ANGULAR_VELOCITY_BODY = (0.002, 2.0, 0.0)
DEFAULT_INTEGRATOR = 'buss'


def default_body():
    """Return the default T-handle body (mass 1 kg, I = diag(1, 2, 3) kg m^2)."""
    return RigidBody(DEFAULT_MASS, np.diag(DEFAULT_INERTIA))


def default_state(body):
    """Return the default initial state: at the origin, at rest, spinning near axis 2."""
    return State.from_velocity(body, angular_velocity_body=DEFAULT_ANGULAR_VELOCITY_BODY)

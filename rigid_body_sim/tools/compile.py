"""
Compile every integrator's numba kernels now, so that no later run waits for it.

The compiled kernels are cached beside the package (``__pycache__``): the first simulation
after an install or an upgrade compiles the ones it needs, 4-10 s each on the reference
machine (a node's start-up then takes that much longer), and every later one loads them in
well under a second.  This takes each registered integrator through one step of a free
body, of a body under a held wrench, under a pivot with gravity and with dissipation, each
at a fixed step and under error control (the controlled kernel): the paths the Simulator
compiles.  ``make test`` runs it first, so the tests' nodes start fast.
"""

import time

from ..physics import INTEGRATORS
from ..physics import RigidBody
from ..physics import Simulator
from ..physics import State
from ..physics.effects import Dissipation
from ..physics.effects import Gravity
from ..physics.effects import Pivot
from ..physics.imu import Imu
from ..physics.imu import ImuModel


def add_arguments(parser):
    """Add the options of ``rigid-body-sim compile`` (none)."""


def main(args):
    """Compile the kernels, printing each integrator's time; return 0."""
    body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
    state = State.from_velocity(body, angular_velocity_body=(0.1, 2.0, 0.1))
    setups = (
        ('free', ()),
        ('pivot', (Pivot(point=(0.0, 0.0, -0.05)), Gravity())),
        ('dissipation', (Dissipation(damping=0.01),)),
    )
    total = time.monotonic()
    for name in sorted(INTEGRATORS):
        started = time.monotonic()
        for _, effects in setups:
            for tolerance in (None, 1e-6):
                simulator = Simulator(body, state, integrator=name, effects=effects,
                                      tolerance=tolerance)
                simulator.step(1e-3)
                simulator.set_wrench(force=(0.0, 0.0, 1.0), torque=(0.1, 0.0, 0.0),
                                     frame='body')
                simulator.step(1e-3)
        print(f'  {name:12s} {time.monotonic() - started:6.2f} s', flush=True)
    # The simulated IMU's reading (one kernel for free and pivoted bodies).
    Imu(ImuModel(), body).truth(state, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    print(f'compiled the kernels of {len(INTEGRATORS)} integrators in '
          f'{time.monotonic() - total:.1f} s (cached for later runs)')
    return 0

"""
The physics core: mass properties, world-frame state, integrators and the simulator.

Pure numpy/scipy (and numba for the compiled fast paths): no ROS, no messages, no I/O.
"""

from .body import RigidBody
from .integrators import FAST_KERNELS
from .integrators import get_integrator
from .integrators import INTEGRATORS
from .integrators import register_integrator
from .rotations import matrix_from_quaternion
from .rotations import quaternion_from_matrix
from .simulator import Simulator
from .simulator import unresolved_rotation
from .state import State

__all__ = [
    'RigidBody',
    'State',
    'Simulator',
    'unresolved_rotation',
    'INTEGRATORS',
    'FAST_KERNELS',
    'get_integrator',
    'register_integrator',
    'matrix_from_quaternion',
    'quaternion_from_matrix',
]

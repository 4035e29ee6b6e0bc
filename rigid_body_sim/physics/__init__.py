"""
The physics core: mass properties, world-frame state, integrators and the simulator.

numpy, with numba for the compiled kernels (:mod:`.kernels`): no ROS, no messages, no I/O
but numba's cache of compiled kernels.
"""

from . import kernels  # noqa: F401  (first: drops cached kernels of changed sources)

from .body import RigidBody
from .integrators import get_integrator
from .integrators import INTEGRATORS
from .integrators import register_integrator
from .rotations import matrix_from_quaternion
from .rotations import quaternion_from_matrix
from .simulator import Simulator
from .simulator import unresolved_rotation
from .state import State
from .world import World

__all__ = [
    'RigidBody',
    'State',
    'Simulator',
    'World',
    'unresolved_rotation',
    'INTEGRATORS',
    'get_integrator',
    'register_integrator',
    'matrix_from_quaternion',
    'quaternion_from_matrix',
]

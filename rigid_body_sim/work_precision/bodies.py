"""
The five benchmark bodies and their torque-free initial states.

Every case is a 1 kg body at rest at the origin (its translation is a trivial drift, so the
benchmark measures rotation only), with its inertia tensor about the COM in the body frame
(kg m^2), an initial orientation R0 (body to world) and an initial body angular velocity
Omega0 (rad/s).  Each is chosen to stress something different:

- ``van_zon``: van Zon & Schofield's test body (J. Comput. Phys. 225:145, 2007),
  I = (10, 20, 26), Omega0 = (1, 15, 1): a fast tumble (1.5 rad per step at dt = 0.1) close
  to the separatrix (elliptic parameter m = 0.9967, period of Omega 2.35 s).
- ``t_handle``: the T-handle I = (1, 2, 3) spun at 2 rad/s about its unstable middle axis
  with a 1e-3 rad/s nudge on each of the other axes, Omega0 = (0.001, 2, 0.001): it flips
  every ~15 s (Dzhanibekov; period of Omega 29.9 s) and sits next to the separatrix
  (m = 1 - 5e-7), where the flip times, and so the orientation, are very sensitive to any
  error.
- ``fast_spin``: the same body spun fast about its stable major axis,
  Omega0 = (0.3, 0.2, 5): a smooth, nearly steady spin with a small nutation (m = 0.0017).
- ``near_symmetric``: a near-symmetric (oblate) top I = (1, 1 + 1e-6, 2),
  Omega0 = (1, 0.5, 3): precession and nutation with m = 7e-8, the case where formulas for
  the asymmetric top lose accuracy if written carelessly.
- ``non_diagonal``: a body whose inertia tensor in its own frame is not diagonal
  (principal moments ~ (1.87, 2.98, 4.14)), started at an oblique orientation
  (rotation vector (0.4, -0.7, 1.1) rad) with Omega0 = (1.5, -1, 2): the methods must not
  assume principal axes.
"""

from dataclasses import dataclass

import numpy as np

from ..physics import RigidBody
from ..physics import State
from ..physics.rotations import matrix_from_quaternion

__all__ = ['BenchmarkCase', 'benchmark_cases', 'CASE_NAMES', 'QUICK_CASE_NAMES']

CASE_NAMES = ('van_zon', 't_handle', 'fast_spin', 'near_symmetric', 'non_diagonal')
# `bench --quick` (CI): one diagonal and one non-diagonal body are enough to exercise every
# code path (principal and non-principal inertia, the MuJoCo fullinertia model).
QUICK_CASE_NAMES = ('van_zon', 'non_diagonal')

_NON_DIAGONAL_INERTIA = ((2.0, -0.3, 0.2),
                         (-0.3, 3.0, 0.4),
                         (0.2, 0.4, 4.0))
# The oblique start R0 = exp([(0.4, -0.7, 1.1)]x) and its L0 = R0 I Omega0, given as the exact
# doubles they rounded to on the machine that computed the committed references: computed
# anew, sin/cos and OpenBLAS's CPU-selected kernels differ in the last bit across machines,
# and a problem 1 ulp away has no committed reference (data/reference_values.json is keyed by
# the exact doubles).  Near the separatrix that ulp matters at the reference's resolution.
_NON_DIAGONAL_QUATERNION = tuple(float.fromhex(value) for value in (
    '0x1.7a95ff7680917p-3', '-0x1.4b433f87b07f2p-2', '0x1.04471fa17863fp-1',
    '0x1.8d807c0271556p-1'))
_NON_DIAGONAL_ANGULAR_MOMENTUM = tuple(float.fromhex(value) for value in (
    '0x1.e07e04a5ad610p-1', '-0x1.be5975f9d10dbp+1', '0x1.0be34465f212fp+3'))


@dataclass(frozen=True)
class BenchmarkCase:
    """
    One benchmark body with its initial state.

    Attributes
    ----------
    name : str
        Short identifier used in tables and file names.
    description : str
        One line for the report.
    body : RigidBody
        Mass (kg) and inertia tensor about the COM in the body frame (kg m^2).
    angular_velocity_body : numpy.ndarray, shape (3,)
        Initial body angular velocity Omega0 (rad/s).
    rotation : numpy.ndarray, shape (3, 3)
        Initial orientation R0, body to world.
    quaternion, angular_momentum : tuple of floats or None
        The initial quaternion (x, y, z, w) and world angular momentum (kg m^2/s) as exact
        doubles, for a start whose computation is not bit-reproducible across machines;
        None: the identity and I Omega0.

    """

    name: str
    description: str
    body: RigidBody
    angular_velocity_body: np.ndarray
    rotation: np.ndarray
    quaternion: tuple = None
    angular_momentum: tuple = None

    @property
    def state(self):
        """Get the initial State (world frame): at rest at the origin, rotating."""
        if self.quaternion is not None:
            # The committed doubles as they are (unit to round-off, so kept unscaled).
            return State._from_arrays(np.array(self.quaternion), np.zeros(3), np.zeros(3),
                                      np.array(self.angular_momentum))
        return State.from_velocity(self.body, rotation=self.rotation,
                                   angular_velocity_body=self.angular_velocity_body)


def _case(name, description, inertia, angular_velocity_body, quaternion=None,
          angular_momentum=None):
    rotation = np.eye(3) if quaternion is None else matrix_from_quaternion(
        np.array(quaternion))
    return BenchmarkCase(name, description, RigidBody(1.0, inertia),
                         np.array(angular_velocity_body, dtype=float), rotation, quaternion,
                         angular_momentum)


def benchmark_cases(names=CASE_NAMES):
    """
    Return the BenchmarkCase of each name in `names`, in that order.

    Raises ValueError for an unknown name, listing the valid ones.
    """
    builders = {
        'van_zon': lambda: _case(
            'van_zon', 'van Zon & Schofield: I = (10, 20, 26), Omega0 = (1, 15, 1)',
            (10.0, 20.0, 26.0), (1.0, 15.0, 1.0)),
        't_handle': lambda: _case(
            't_handle', 'T-handle near its middle axis: I = (1, 2, 3), '
            'Omega0 = (0.001, 2, 0.001)',
            (1.0, 2.0, 3.0), (0.001, 2.0, 0.001)),
        'fast_spin': lambda: _case(
            'fast_spin', 'fast stable spin: I = (1, 2, 3), Omega0 = (0.3, 0.2, 5)',
            (1.0, 2.0, 3.0), (0.3, 0.2, 5.0)),
        'near_symmetric': lambda: _case(
            'near_symmetric', 'near-symmetric top: I = (1, 1 + 1e-6, 2), '
            'Omega0 = (1, 0.5, 3)',
            (1.0, 1.0 + 1e-6, 2.0), (1.0, 0.5, 3.0)),
        'non_diagonal': lambda: _case(
            'non_diagonal', 'non-diagonal I = ((2, -0.3, 0.2), (-0.3, 3, 0.4), (0.2, 0.4, 4)), '
            'R0 = exp([(0.4, -0.7, 1.1)]x), Omega0 = (1.5, -1, 2)',
            _NON_DIAGONAL_INERTIA, (1.5, -1.0, 2.0), _NON_DIAGONAL_QUATERNION,
            _NON_DIAGONAL_ANGULAR_MOMENTUM),
    }
    unknown = [name for name in names if name not in builders]
    if unknown:
        raise ValueError(f'unknown benchmark bodies {unknown}; valid: {", ".join(CASE_NAMES)}')
    return [builders[name]() for name in names]

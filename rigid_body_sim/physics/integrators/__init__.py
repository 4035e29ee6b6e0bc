"""
Integrators, registered by name in :data:`INTEGRATORS` (see :mod:`.registry`).

Importing this package imports every integrator module, which registers itself.  Adding an
integrator: write one module with a step function decorated by ``register_integrator`` and
import it here.
"""

from . import exact  # noqa: F401  (registers exact)
from . import rk4  # noqa: F401  (registers rk4)
from . import seed  # noqa: F401  (registers first_order, buss, buss_plain)
from . import splitting  # noqa: F401  (registers splitting, splitting4)
from .registry import FAST_KERNELS
from .registry import get_integrator
from .registry import INTEGRATORS
from .registry import register_integrator

__all__ = ['INTEGRATORS', 'FAST_KERNELS', 'get_integrator', 'register_integrator']

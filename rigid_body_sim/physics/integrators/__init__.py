"""
Integrators, registered by name in :data:`INTEGRATORS` (see :mod:`.registry`).

One module per method, named by it; importing this package imports each, which registers
itself.  Adding an integrator: its module (its compiled step and run kernel, registered with
``register_integrator``) and its import here.
"""

from . import buss  # noqa: F401  (registers buss, buss_plain)
from . import exact  # noqa: F401  (registers exact)
from . import first_order  # noqa: F401  (registers first_order)
from . import rk4  # noqa: F401  (registers rk4)
from . import splitting  # noqa: F401  (registers splitting, splitting4)
from .registry import get_integrator
from .registry import Integrator
from .registry import INTEGRATORS
from .registry import register_integrator

__all__ = ['INTEGRATORS', 'Integrator', 'get_integrator', 'register_integrator']

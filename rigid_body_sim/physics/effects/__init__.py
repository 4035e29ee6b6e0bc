"""
Effects: what acts on a body besides its own inertia, registered by name in EFFECTS.

Importing this package imports every effect module, which registers its class.  The protocol
(what an effect may provide and how the Simulator uses it) is described in
:mod:`.registry`.  Adding an effect: one module with a class decorated by
``register_effect``, imported here.
"""

from .dissipation import Dissipation
from .drag import Drag
from .external_wrench import ExternalWrench
from .gravity import Gravity
from .pivot import Pivot
from .registry import create_effect
from .registry import effect_parameters
from .registry import EFFECTS
from .registry import ParameterError
from .registry import register_effect
from .sinusoidal_torque import SinusoidalTorque

__all__ = [
    'EFFECTS',
    'Dissipation',
    'Drag',
    'ExternalWrench',
    'Gravity',
    'ParameterError',
    'Pivot',
    'SinusoidalTorque',
    'create_effect',
    'effect_parameters',
    'register_effect',
]

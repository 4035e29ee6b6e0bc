"""
Effects: what acts on a body besides its own inertia, registered by name in EFFECTS.

Importing this package imports every effect module, which registers its class.  The protocol
(what an effect may provide and how the Simulator uses it) is described in
:mod:`.registry`.  Adding an effect: one module with a class decorated by
``register_effect``, imported here; or the same module outside the package, a plugin
(:mod:`.plugins`: an entry point of an installed distribution, or a file a scene names).
"""

from .dissipation import Dissipation
from .drag import Drag
from .external_wrench import ExternalWrench
from .gravity import Gravity
from .pivot import Pivot
from .plugins import ENTRY_POINT_GROUP
from .plugins import load_effect_file
from .plugins import PluginError
from .registry import create_effect
from .registry import effect_parameters
from .registry import EFFECTS
from .registry import ParameterError
from .registry import register_effect
from .sinusoidal_torque import SinusoidalTorque

__all__ = [
    'EFFECTS',
    'ENTRY_POINT_GROUP',
    'Dissipation',
    'Drag',
    'ExternalWrench',
    'Gravity',
    'ParameterError',
    'Pivot',
    'PluginError',
    'SinusoidalTorque',
    'create_effect',
    'effect_parameters',
    'load_effect_file',
    'register_effect',
]

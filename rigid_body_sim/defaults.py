"""
The default body and initial state: those of the node's default scene.

The one source of truth is ``config/scenes/default.yaml`` (read with
:func:`rigid_body_sim.scenes.load_scene`): the T-handle I = (1, 2, 3) kg m^2 spun at 2 rad/s
near its intermediate axis, which flips (the Dzhanibekov effect) first after about 7.2 s and
then every ~14.4 s of simulated time (half the 28.7 s period of the body rates).  These
functions only save callers that want the body or the state alone from loading the scene.
"""

from .scenes import DEFAULT_SCENE
from .scenes import load_scene

__all__ = ['default_body', 'default_state']


def default_body():
    """Return the default scene's RigidBody (mass 1 kg, I = diag(1, 2, 3) kg m^2)."""
    return load_scene(DEFAULT_SCENE).body


def default_state():
    """Return the default scene's initial State: at the origin, at rest, spinning near axis 2."""
    return load_scene(DEFAULT_SCENE).state

"""
The limits of a scene and of a run: the ranges of its settings and the bounds of its file.

The ranges (rate, tolerance, substeps) are the node's parameters' and the command line's
as much as a scene file's: one place, so the three cannot disagree.  The bounds (size,
nesting, values, text lengths) keep reading any file cheap and every message short.
"""

__all__ = [
    'MAX_BODIES',
    'MAX_BODY_NAME_LENGTH',
    'MAX_DESCRIPTION_LENGTH',
    'MAX_NAME_LENGTH',
    'MAX_SCENE_DEPTH',
    'MAX_SCENE_SIZE',
    'MAX_SCENE_VALUES',
    'RATE_RANGE',
    'SUBSTEPS_RANGE',
    'TOLERANCE_RANGE',
]

RATE_RANGE = (0.1, 10000.0)
"""The tick rates (Hz) a scene, the node and the command line take."""
TOLERANCE_RANGE = (0.0, 1.0)
"""The error control (rad per simulated s; 0: off) a scene, the node and the command line
take."""
SUBSTEPS_RANGE = (1, 100000)
"""The integrator steps per tick the node and the command line take."""
MAX_SCENE_SIZE = 256 * 1024
"""The most characters of a scene file: far above what a built-in scene holds, and small enough
that PyYAML reads it in well under a second (docs/scenes.md has the figures)."""
MAX_SCENE_DEPTH = 20
"""The deepest nesting of a scene's YAML (a scene needs 5: effects, an effect, its parameters,
a vector)."""
MAX_SCENE_VALUES = 50000
"""The most values (YAML nodes: mappings, lists, keys and scalars) in a scene; an alias counts
as the values it repeats.  The built-in scenes of one body have 33 to 53, the 1,000-body
constellation ~21,000."""
MAX_NAME_LENGTH = 100
MAX_DESCRIPTION_LENGTH = 300
"""The longest name and description (characters): they are shown on one line (the built-in
scenes' are under 20 and 100), and a name starts the default bag directory's name."""
MAX_BODIES = 10000
"""The most bodies a scene lists (``bodies:``): ten times the benchmark's constellation."""
MAX_BODY_NAME_LENGTH = 64
"""The longest body name (characters): it starts each of the body's topic and frame names."""

"""
A compiled effect that counts its own evaluations, for tests of what the kernels evaluate.

The count lives in the parameters the Simulator copies into its compiled model: read it with
:func:`evaluations`.
"""

import numpy as np
from rigid_body_sim.physics.effects.registry import Effect
from rigid_body_sim.physics.kernels.model import wrench_term


@wrench_term
def counted_nothing(state, time, parameters):
    """Push with nothing, and count the evaluations in parameters[0]."""
    parameters[0] += 1.0
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


class CountingWrench(Effect):
    """A compiled pushing effect that counts its evaluations (and pushes with nothing)."""

    compiled_wrench = staticmethod(counted_nothing)

    def wrench_parameters(self, body):
        """Return the counter, zero."""
        return np.zeros(1)


def evaluations(simulator):
    """Return how often the simulator's kernels evaluated the CountingWrench."""
    return int(simulator._model.term_parameters[0])

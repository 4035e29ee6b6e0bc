"""
external_wrench: the body may be pushed from outside (the node's torque and wrench topics).

In the core the external wrench is the Simulator's held wrench (Simulator.set_wrench /
hold_wrench), so this effect computes nothing: it marks that a scene accepts outside input
(only scenes naming it subscribe to the topics) and carries optional magnitude limits that
the input is clamped to before it is held.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .registry import check_number
from .registry import Effect
from .registry import register_effect
from ..kernels.model import Array


@register_effect('external_wrench')
class ExternalWrench(Effect):
    """
    Accept a force through the COM and a torque about it from outside, held until changed.

    Parameters
    ----------
    max_force : float or None
        Largest accepted force magnitude in N; larger inputs are scaled down to it.  None
        (default): no limit.
    max_torque : float or None
        Largest accepted torque magnitude in N m, likewise.

    """

    accepts_external_wrench = True
    # It computes nothing: what conserves depends on the inputs, none offline.
    conserves = ('angular_momentum', 'rotational_energy')
    keeps_pivot_invariants = True
    units = {'max_force': 'N', 'max_torque': 'N m'}
    example = {'max_force': 10.0, 'max_torque': 1.0}

    def __init__(self, max_force: float | None = None, max_torque: float | None = None) -> None:
        self.max_force = None if max_force is None else check_number(
            max_force, 'max_force', 'N', positive=True, maximum=1e12)
        self.max_torque = None if max_torque is None else check_number(
            max_torque, 'max_torque', 'N m', positive=True, maximum=1e12)

    def limit(self, force: ArrayLike, torque: ArrayLike) -> tuple[Array, Array]:
        """Return (force, torque) scaled down, direction kept, to the magnitude limits."""
        return _clamped(force, self.max_force), _clamped(torque, self.max_torque)


def _clamped(vector: ArrayLike, limit: float | None) -> Array:
    vector = np.array(vector, dtype=float)
    if limit is None:
        return vector
    norm = float(np.linalg.norm(vector))
    return vector * (limit / norm) if norm > limit else vector

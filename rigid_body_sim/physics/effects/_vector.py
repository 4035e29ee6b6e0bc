"""Small vector helpers for the effects' per-step code."""

import numpy as np


def cross(a, b):
    """
    Return the cross product a x b of two 3-vectors.

    Written out because numpy's general np.cross costs ~20x more for one pair of
    3-vectors, and the effects call it several times per step.
    """
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])

"""
Mass properties of a rigid body: mass and the inertia tensor about the centre of mass.

Everything here is fixed body data (the analogue of MuJoCo's mjModel); the changing state
lives in :mod:`rigid_body_sim.physics.state`.  Frame: the body frame, origin at the centre of
mass (COM).  Units: kg, m, kg m^2.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

__all__ = ['RigidBody']

# Relative tolerances of the physical checks.  Symmetry and the triangle inequality are
# compared against the largest moment so that they are scale-free; 1e-10 is far above the
# round-off of an eigen-decomposition (~1e-15) and far below any real body's asymmetry.
_SYMMETRY_RTOL = 1e-10
_TRIANGLE_RTOL = 1e-10
# Two principal moments closer than this (relative) make a symmetric top.
_EQUAL_MOMENTS_RTOL = 1e-9


MIN_MASS = 1.0e-9
"""The lightest body accepted, kg."""
MAX_MASS = 1.0e15
"""The heaviest body accepted, kg."""


def _check_mass(mass: float) -> float:
    try:
        value = float(mass)
    except (TypeError, ValueError):
        raise ValueError(f'mass must be a number in kg; got {mass!r}') from None
    if not np.isfinite(value):
        raise ValueError(f'mass must be finite; got {value}')
    if value <= 0.0:
        raise ValueError(f'mass must be > 0 kg; got {value:g}')
    if not MIN_MASS <= value <= MAX_MASS:
        raise ValueError(f'mass must be within {MIN_MASS:g} .. {MAX_MASS:g} kg (a microgram to '
                         f'a mountain; beyond, a 1 N push overflows); got {value:g}')
    return value


def _check_positive_lengths(values: ArrayLike, name: str, count: int) -> NDArray[np.float64]:
    array = np.array(values, dtype=float).reshape(-1)
    if array.size != count:
        raise ValueError(f'{name} must have {count} value(s) in m; got {array.size}')
    if not np.all(np.isfinite(array)):
        raise ValueError(f'{name} must be finite; got {array.tolist()}')
    if np.any(array <= 0.0):
        raise ValueError(f'{name} must be > 0 m; got {array.tolist()}')
    return array


class RigidBody:
    """
    A rigid body: its mass and its inertia tensor about the COM, in the body frame.

    Parameters
    ----------
    mass : float
        Mass in kg, > 0.
    inertia : array_like, shape (3, 3) or (3,)
        Inertia tensor about the COM in the body frame, kg m^2.  It need not be diagonal; a
        length-3 sequence is taken as the diagonal.

    Raises
    ------
    ValueError
        If an entry is not finite, the mass is not positive, the tensor is not symmetric or
        not positive definite, or its principal moments violate the triangle inequality
        I1 + I2 >= I3 (equality, a flat plate, is allowed).  The message names the rule and
        the values.

    """

    def __init__(self, mass: float, inertia: ArrayLike) -> None:
        self._mass = _check_mass(mass)
        tensor = np.array(inertia, dtype=float)
        if tensor.shape == (3,):
            tensor = np.diag(tensor)
        if tensor.shape != (3, 3):
            raise ValueError(
                f'inertia must be a 3x3 tensor (or its 3 diagonal entries) in kg m^2; got '
                f'shape {tensor.shape}')
        if not np.all(np.isfinite(tensor)):
            raise ValueError(f'inertia must be finite; got {tensor.tolist()}')
        scale = np.max(np.abs(tensor))
        asymmetry = np.max(np.abs(tensor - tensor.T))
        if asymmetry > _SYMMETRY_RTOL * scale:
            i, j = np.unravel_index(np.argmax(np.abs(tensor - tensor.T)), (3, 3))
            raise ValueError(
                f'inertia tensor must be symmetric: I[{i}][{j}] = {tensor[i, j]:.9g} but '
                f'I[{j}][{i}] = {tensor[j, i]:.9g}')
        tensor = 0.5 * (tensor + tensor.T)
        moments, axes = np.linalg.eigh(tensor)
        if moments[0] <= 0.0:
            raise ValueError(
                'inertia tensor must be positive definite (a body with volume); got principal '
                f'moments {moments.tolist()} kg m^2')
        if moments[0] + moments[1] < moments[2] * (1.0 - _TRIANGLE_RTOL):
            raise ValueError(
                'principal moments must satisfy the triangle inequality I1 + I2 >= I3; got '
                f'I1 + I2 = {moments[0] + moments[1]:.9g} < I3 = {moments[2]:.9g} '
                f'(moments {moments.tolist()} kg m^2): no real body has these')
        if np.linalg.det(axes) < 0.0:
            axes[:, 2] = -axes[:, 2]
        self._inertia = tensor
        self._inertia_inverse = np.linalg.inv(tensor)
        self._inertia_inverse = 0.5 * (self._inertia_inverse + self._inertia_inverse.T)
        self._principal_moments = moments
        self._principal_axes = axes
        for array in (self._inertia, self._inertia_inverse, moments, axes):
            array.flags.writeable = False
        self.center_of_mass = np.zeros(3)

    # -- constructors for common shapes (solid, uniform density, principal axes = body axes)

    @classmethod
    def box(cls, mass: float, size: ArrayLike) -> RigidBody:
        """
        Return a solid box of edge lengths size = (a, b, c) along body x, y, z (m).

        I = m/12 (b^2 + c^2, a^2 + c^2, a^2 + b^2).
        """
        a, b, c = _check_positive_lengths(size, 'box size', 3) ** 2
        m = _check_mass(mass)
        return cls(m, np.diag([b + c, a + c, a + b]) * m / 12.0)

    @classmethod
    def cylinder(cls, mass: float, radius: float, height: float) -> RigidBody:
        """
        Return a solid cylinder of `radius` and `height` (m), its axis along body z.

        I = (m (3 r^2 + h^2)/12, same, m r^2 / 2).
        """
        (r,) = _check_positive_lengths([radius], 'cylinder radius', 1)
        (h,) = _check_positive_lengths([height], 'cylinder height', 1)
        m = _check_mass(mass)
        side = m * (3.0 * r * r + h * h) / 12.0
        return cls(m, np.diag([side, side, 0.5 * m * r * r]))

    @classmethod
    def sphere(cls, mass: float, radius: float) -> RigidBody:
        """Return a solid sphere of `radius` (m): I = 2/5 m r^2 about every axis."""
        (r,) = _check_positive_lengths([radius], 'sphere radius', 1)
        m = _check_mass(mass)
        return cls(m, np.eye(3) * 0.4 * m * r * r)

    @classmethod
    def ellipsoid(cls, mass: float, semi_axes: ArrayLike) -> RigidBody:
        """
        Return a solid ellipsoid of semi-axes (a, b, c) along body x, y, z (m).

        I = m/5 (b^2 + c^2, a^2 + c^2, a^2 + b^2).
        """
        a, b, c = _check_positive_lengths(semi_axes, 'ellipsoid semi_axes', 3) ** 2
        m = _check_mass(mass)
        return cls(m, np.diag([b + c, a + c, a + b]) * m / 5.0)

    @classmethod
    def from_point_masses(cls, masses: ArrayLike, positions: ArrayLike) -> RigidBody:
        """
        Return the body made of point masses rigidly joined.

        Parameters
        ----------
        masses : array_like, shape (n,)
            Masses in kg, each > 0.
        positions : array_like, shape (n, 3)
            Positions in m, in any frame parallel to the body frame.

        The centre of mass is computed and reported as the attribute ``center_of_mass`` (in
        the frame of `positions`); the inertia is about it:
        I = sum_i m_i (|r_i|^2 E - r_i r_i^T) with r_i = position_i - COM.
        Collinear points (fewer than two independent directions) have no finite-inertia
        rotation about their line and are rejected.

        """
        m = np.array(masses, dtype=float).reshape(-1)
        r = np.array(positions, dtype=float)
        if r.ndim != 2 or r.shape[1] != 3 or r.shape[0] != m.size:
            raise ValueError(
                f'positions must have shape (n, 3) with n = len(masses) = {m.size}; got '
                f'shape {r.shape}')
        if m.size == 0:
            raise ValueError('point masses: need at least 3 non-collinear points; got none')
        if not np.all(np.isfinite(m)):
            raise ValueError(f'point masses must be finite; got {m.tolist()} kg')
        if not np.all(np.isfinite(r)):
            bad = int(np.flatnonzero(~np.all(np.isfinite(r), axis=1))[0])
            raise ValueError(
                f'point mass positions must be finite; got position {bad} = {r[bad].tolist()} m')
        if np.any(m <= 0.0):
            raise ValueError(f'point masses must each be > 0 kg; got {m.tolist()}')
        total = float(np.sum(m))
        com = (m @ r) / total
        offsets = r - com
        # Collinear or coincident points: the spread of offsets has rank < 2.
        spread = np.linalg.svd(offsets, compute_uv=False) if m.size > 1 else np.zeros(1)
        extent = np.max(np.abs(offsets)) if m.size > 1 else 0.0
        if m.size < 3 or spread.size < 2 or spread[1] <= 1e-9 * max(spread[0], extent):
            extents = ', '.join(f'{value:.3g}' for value in spread)
            listed = f' at {r.tolist()} m' if m.size <= 4 else ''
            raise ValueError(
                f'degenerate point set: {m.size} point(s){listed} that are coincident or '
                'collinear have zero inertia about their common line (singular values of '
                f'their offsets from the COM: {extents} m); need at least 3 non-collinear '
                'points')
        squared = np.einsum('ij,ij->i', offsets, offsets)
        inertia = np.eye(3) * np.sum(m * squared) - np.einsum('i,ij,ik->jk', m, offsets, offsets)
        body = cls(total, inertia)
        body.center_of_mass = com
        return body

    # -- properties

    @property
    def mass(self) -> float:
        """Mass in kg."""
        return self._mass

    @property
    def inertia(self) -> NDArray[np.float64]:
        """Inertia tensor about the COM in the body frame (3x3, kg m^2, read-only)."""
        return self._inertia

    @property
    def inertia_inverse(self) -> NDArray[np.float64]:
        """Inverse of :attr:`inertia` (3x3, 1/(kg m^2), read-only)."""
        return self._inertia_inverse

    @property
    def principal_moments(self) -> NDArray[np.float64]:
        """Principal moments I1 <= I2 <= I3 (kg m^2), ascending."""
        return self._principal_moments

    @property
    def principal_axes(self) -> NDArray[np.float64]:
        """Principal axes in the body frame as columns, right-handed (det = +1)."""
        return self._principal_axes

    @property
    def is_symmetric_top(self) -> bool:
        """Tell whether two principal moments agree within a relative 1e-9 (spherical tops too)."""
        i1, i2, i3 = self._principal_moments
        return bool(i2 - i1 <= _EQUAL_MOMENTS_RTOL * i3 or i3 - i2 <= _EQUAL_MOMENTS_RTOL * i3)

    @property
    def is_spherical_top(self) -> bool:
        """Tell whether all three principal moments agree within a relative 1e-9."""
        i1, _, i3 = self._principal_moments
        return bool(i3 - i1 <= _EQUAL_MOMENTS_RTOL * i3)

    def __repr__(self) -> str:
        """Return a readable summary of the mass properties."""
        tensor = np.array2string(self._inertia, precision=6, separator=', ')
        return f'RigidBody(mass={self._mass:g}, inertia={tensor})'

"""
An extended-precision reference for the torque-free motion: Taylor series in decimals.

Independent of the package (only its State and RigidBody are read): used by test_exact.py and
benchmarks/exact_roundoff_floor.py to measure the exact flow's round-off, where no
double-precision ODE solve is accurate enough (scipy's DOP853 at its tightest rtol, 2.5e-14,
is ~1e-12 rad off after 10 s of the T-handle).
"""

import decimal
from fractions import Fraction
import math

import numpy as np
from rigid_body_sim.physics import State

__all__ = ['TAYLOR_DIGITS', 'TaylorReference', 'angle_to_reference', 'reference_orientations',
           'rounded_flow_steps']

TAYLOR_DIGITS = 30


class TaylorReference:
    """
    The torque-free motion from a double state, by Taylor series in decimal arithmetic.

    Body frame: dq/dt = 1/2 q (x) (W, 0) (q = (x, y, z, w), body to world), dM/dt = M x W,
    W = I_b^{-1} M, started from the double state taken exactly: q normalised and M = R(q)^T L
    in `digits`-digit decimals, I_b^{-1} the exact rational inverse of the double tensor.  Both
    right-hand sides are quadratic, so the Taylor coefficients follow from Cauchy products;
    each substep sums them until three in a row are below 10^-(digits + 2), on substeps of at
    most 0.75/|W(0)| s (|W| is constant in norm only up to the energy's spread; a substep whose
    series does not settle in 60 terms is halved).  Shares no code with the package: its error
    is ~10^-digits per substep (tested below), which makes it a reference for round-off.
    """

    def __init__(self, body, state, digits=TAYLOR_DIGITS, substep_scale=0.75):
        self.context = decimal.Context(prec=digits)
        self.tiny = decimal.Decimal(10) ** -(digits + 2)
        with decimal.localcontext(self.context):
            tensor = [[Fraction(float(body.inertia[i, j])) for j in range(3)] for i in range(3)]
            inverse = _rational_inverse(tensor)
            self.inverse = [[decimal.Decimal(inverse[i][j].numerator)
                             / decimal.Decimal(inverse[i][j].denominator) for j in range(3)]
                            for i in range(3)]
            q = [decimal.Decimal(float(c)) for c in state.quaternion]
            norm = sum(c * c for c in q).sqrt()
            self.q = [c / norm for c in q]
            momentum = [decimal.Decimal(float(c)) for c in state.angular_momentum]
            self.m = _decimal_rotate_inverse(self.q, momentum)
            rate = sum(c * c for c in self._rate(self.m)).sqrt()
            self.longest = (decimal.Decimal(substep_scale) / rate if rate
                            else decimal.Decimal(1))
        self.time = decimal.Decimal(0)

    def _rate(self, m):
        return [sum(self.inverse[i][j] * m[j] for j in range(3)) for i in range(3)]

    def _substep(self, h):
        """Advance by h (Decimal) if the series settles, and return True; else False."""
        qs, ms, ws = [self.q], [self.m], []
        settled = 0
        for k in range(60):
            ws.append(self._rate(ms[k]))
            f = h / (k + 1)
            mk = [decimal.Decimal(0)] * 3
            qk = [decimal.Decimal(0)] * 4
            for j in range(k + 1):
                a, w, (x, y, z, s) = ms[j], ws[k - j], qs[j]
                mk[0] += a[1] * w[2] - a[2] * w[1]
                mk[1] += a[2] * w[0] - a[0] * w[2]
                mk[2] += a[0] * w[1] - a[1] * w[0]
                qk[0] += s * w[0] + y * w[2] - z * w[1]
                qk[1] += s * w[1] + z * w[0] - x * w[2]
                qk[2] += s * w[2] + x * w[1] - y * w[0]
                qk[3] -= x * w[0] + y * w[1] + z * w[2]
            ms.append([f * c for c in mk])
            qs.append([f / 2 * c for c in qk])
            if max(abs(c) for c in ms[-1] + qs[-1]) < self.tiny:
                settled += 1
                if settled == 3:
                    self.q = [sum(term[i] for term in reversed(qs)) for i in range(4)]
                    self.m = [sum(term[i] for term in reversed(ms)) for i in range(3)]
                    return True
            else:
                settled = 0
        return False

    def advance_to(self, time):
        """Integrate to `time` (a float taken exactly, or a Decimal); return q, normalised."""
        with decimal.localcontext(self.context):
            span = decimal.Decimal(time) - self.time
            count = int(abs(span) / self.longest) + 1
            while True:
                saved = self.q, self.m
                if all(self._substep(span / count) for _ in range(count)):
                    break
                self.q, self.m = saved
                count *= 2
            self.time += span
            norm = sum(c * c for c in self.q).sqrt()
            return [c / norm for c in self.q]


def _rational_inverse(matrix):
    """Return the exact inverse of a 3x3 matrix of Fractions (adjugate over determinant)."""
    def minor(i, j):
        rows = [r for r in range(3) if r != i]
        cols = [c for c in range(3) if c != j]
        return (matrix[rows[0]][cols[0]] * matrix[rows[1]][cols[1]]
                - matrix[rows[0]][cols[1]] * matrix[rows[1]][cols[0]])
    determinant = sum((-1) ** j * matrix[0][j] * minor(0, j) for j in range(3))
    return [[(-1) ** (i + j) * minor(j, i) / determinant for j in range(3)] for i in range(3)]


def _decimal_rotate_inverse(q, v):
    """Return R(q)^T v for a unit quaternion q (x, y, z, w), in decimals."""
    x, y, z, w = q
    return [(1 - 2 * (y * y + z * z)) * v[0] + 2 * (x * y + z * w) * v[1]
            + 2 * (x * z - y * w) * v[2],
            2 * (x * y - z * w) * v[0] + (1 - 2 * (x * x + z * z)) * v[1]
            + 2 * (y * z + x * w) * v[2],
            2 * (x * z + y * w) * v[0] + 2 * (y * z - x * w) * v[1]
            + (1 - 2 * (x * x + y * y)) * v[2]]


def angle_to_reference(quaternion, reference):
    """Return the rotation angle (rad) between a double quaternion and a decimal one."""
    with decimal.localcontext(decimal.Context(prec=TAYLOR_DIGITS)):
        q = [decimal.Decimal(float(c)) for c in quaternion]
        norm = sum(c * c for c in q).sqrt()
        ax, ay, az, aw = (c / norm for c in q)
        bx, by, bz, bw = reference
        # conj(a) (x) b: its vector part has norm sin(angle/2).
        vx = aw * bx - ax * bw - ay * bz + az * by
        vy = aw * by + ax * bz - ay * bw - az * bx
        vz = aw * bz - ax * by + ay * bx - az * bw
        s = aw * bw + ax * bx + ay * by + az * bz
        return 2.0 * math.atan2(float((vx * vx + vy * vy + vz * vz).sqrt()), abs(float(s)))


def reference_orientations(body, state, times, **options):
    """Return the reference q(t) (decimals) at each of `times` (increasing; floats or decimals)."""
    reference = TaylorReference(body, state, **options)
    return [reference.advance_to(t) for t in times]


def rounded_flow_steps(body, state, dt, steps, digits=TAYLOR_DIGITS):
    """
    Return the quaternion after `steps` ideal steps: the flow in decimals, rounded each step.

    Each step integrates dt from the double state exactly as stored and rounds the
    normalised quaternion to double (L is constant): what a stepper that evaluated the
    exact flow without error would store.  Its error is the round-off floor of any
    double-precision stepper that keeps (q, L) as its state.
    """
    quaternion = np.array(state.quaternion, dtype=float)
    momentum = np.array(state.angular_momentum, dtype=float)
    for _ in range(steps):
        reference = TaylorReference(body, State(quaternion, angular_momentum=momentum),
                                    digits=digits)
        quaternion = np.array([float(c) for c in reference.advance_to(dt)])
    return quaternion

"""
An extended-precision reference for the torque-free benchmark bodies: Taylor series in decimal.

The benchmark scores double-precision integrators down to 1e-12 rad, so its reference must
be independent of them and resolve far less than that.  This module integrates Euler's
equations for the body angular momentum M = I_b Omega together with the orientation
quaternion q = (x, y, z, w), body to world,

    dM/dt = M x Omega,   dq/dt = 1/2 q * (Omega, 0),   Omega = A M,   A = I_b^{-1},

in Python's :mod:`decimal` arithmetic (``digits`` significant decimal digits, 34 by default)
with a Taylor series method.  The right-hand side is quadratic, so the Taylor coefficients
follow exactly from Cauchy products (no derivatives to approximate): with y(t0 + s) =
sum_k y_k s^k,

    Omega_k = A M_k,
    M_{k+1} = 1/(k+1) sum_{j<=k} M_j x Omega_{k-j},
    q_{k+1} = 1/(2(k+1)) sum_{j<=k} q_j * (Omega_{k-j}, 0).

Order and step follow Jorba & Zou (Experiment. Math. 14:99, 2005): for a tolerance eps the
order is p = ceil(-ln(eps) / 2) + 1 and the step h = rho / e^2, where rho = min over
j in {p-1, p} of |y_j|^(-1/j) estimates the radius of convergence (the distance to the nearest
complex singularity of the elliptic functions); the truncation error per step is then
~ (h / rho)^p = e^(-2p) <= eps.  Steps are shortened to land on every requested time, so
each value is a step end point.

The problem is the one the double-precision integrators solve: the initial state's double
values (quaternion, world L) and the double-valued inertia tensor are converted to decimal
exactly; q(0) is normalised in decimal (the state means R(q / |q|)), M(0) = R(0)^T L(0) and A
are computed in decimal.  The requested times are N dt with dt the double time step, taken
exactly (N x the double dt, not its rounded product), since the integrators take N steps of
that very dt.

Uncertainty: :func:`extended_reference` solves twice, at ``digits`` and at ``digits + 8``
digits with the tolerance tightened to match (so different orders, step sizes and step
points), and reports the angle between the two at every time: the error estimate of the
first solve (conservative for the second, which is the one kept).  The conserved |M| and
2T = M . A M give a further, independent check (their relative drift is returned too).

The values of the benchmark's own problems are committed as package data
(:func:`committed_references`); ``benchmarks/regenerate_references.py`` recomputes them
(minutes: ~10^4 Taylor steps per body in pure Python).
"""

import decimal
from decimal import Decimal
import functools
import importlib.resources
import json
import math
import os
import sys

__all__ = ['taylor_flow', 'extended_reference', 'exact_time', 'rotation_matrix_decimal',
           'quaternion_angle', 'reference_quaternions', 'problem_fingerprint', 'key_string',
           'committed_references', 'REFERENCE_SETS', 'DIGITS']

DIGITS = 34
# Digits added for the second, checking solve.
CHECK_DIGITS = 8


def exact_time(steps, dt):
    """Return the time (s) of `steps` steps of the double dt, as an exact Decimal."""
    return int(steps) * Decimal(float(dt))


def _inverse(matrix):
    """Return the inverse of a 3x3 matrix of Decimals, by its adjugate (current context)."""
    (a, b, c), (d, e, f), (g, h, i) = matrix
    cofactors = ((e * i - f * h, c * h - b * i, b * f - c * e),
                 (f * g - d * i, a * i - c * g, c * d - a * f),
                 (d * h - e * g, b * g - a * h, a * e - b * d))
    determinant = a * cofactors[0][0] + b * cofactors[1][0] + c * cofactors[2][0]
    return tuple(tuple(value / determinant for value in row) for row in cofactors)


def rotation_matrix_decimal(quaternion):
    """Return R(q / |q|), body to world, as rows of Decimals (current context)."""
    x, y, z, w = quaternion
    norm2 = x * x + y * y + z * z + w * w
    s = 2 / norm2
    return ((1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)),
            (s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)),
            (s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)))


def quaternion_angle(q_a, q_b):
    """
    Return the rotation angle (rad, float) between two quaternions of Decimals.

    2 atan2(|vec(conj(a) b)|, |scalar(conj(a) b)|): exact for tiny angles, unlike acos.
    """
    ax, ay, az, aw = q_a
    bx, by, bz, bw = q_b
    scalar = aw * bw + ax * bx + ay * by + az * bz
    vx = aw * bx - bw * ax - (ay * bz - az * by)
    vy = aw * by - bw * ay - (az * bx - ax * bz)
    vz = aw * bz - bw * az - (ax * by - ay * bx)
    vector = (vx * vx + vy * vy + vz * vz).sqrt()
    return 2.0 * math.atan2(float(vector), abs(float(scalar)))


def _coefficients(inverse, momentum, quaternion, order):
    """Return the Taylor coefficients (lists per component) up to `order` (module doc)."""
    (a11, a12, a13), (a21, a22, a23), (a31, a32, a33) = inverse
    mx, my, mz = [momentum[0]], [momentum[1]], [momentum[2]]
    qx, qy, qz, qw = ([component] for component in quaternion)
    wx, wy, wz = [], [], []
    for k in range(order):
        wx.append(a11 * mx[k] + a12 * my[k] + a13 * mz[k])
        wy.append(a21 * mx[k] + a22 * my[k] + a23 * mz[k])
        wz.append(a31 * mx[k] + a32 * my[k] + a33 * mz[k])
        # Cauchy products: sum_j u_j v_{k-j}, with the second series reversed.
        rx, ry, rz = wx[::-1], wy[::-1], wz[::-1]
        my_wz = sum(map(Decimal.__mul__, my, rz))
        mz_wy = sum(map(Decimal.__mul__, mz, ry))
        mz_wx = sum(map(Decimal.__mul__, mz, rx))
        mx_wz = sum(map(Decimal.__mul__, mx, rz))
        mx_wy = sum(map(Decimal.__mul__, mx, ry))
        my_wx = sum(map(Decimal.__mul__, my, rx))
        qw_wx = sum(map(Decimal.__mul__, qw, rx))
        qw_wy = sum(map(Decimal.__mul__, qw, ry))
        qw_wz = sum(map(Decimal.__mul__, qw, rz))
        qy_wz = sum(map(Decimal.__mul__, qy, rz))
        qz_wy = sum(map(Decimal.__mul__, qz, ry))
        qz_wx = sum(map(Decimal.__mul__, qz, rx))
        qx_wz = sum(map(Decimal.__mul__, qx, rz))
        qx_wy = sum(map(Decimal.__mul__, qx, ry))
        qy_wx = sum(map(Decimal.__mul__, qy, rx))
        qx_wx = sum(map(Decimal.__mul__, qx, rx))
        qy_wy = sum(map(Decimal.__mul__, qy, ry))
        qz_wz = sum(map(Decimal.__mul__, qz, rz))
        scale = Decimal(1) / (k + 1)
        half = scale / 2
        # dM/dt = M x Omega
        mx.append((my_wz - mz_wy) * scale)
        my.append((mz_wx - mx_wz) * scale)
        mz.append((mx_wy - my_wx) * scale)
        # dq/dt = 1/2 q * (Omega, 0), Hamilton product, (x, y, z, w) storage.
        qx.append((qw_wx + qy_wz - qz_wy) * half)
        qy.append((qw_wy + qz_wx - qx_wz) * half)
        qz.append((qw_wz + qx_wy - qy_wx) * half)
        qw.append(-(qx_wx + qy_wy + qz_wz) * half)
    return (mx, my, mz), (qx, qy, qz, qw)


def _horner(series, step):
    value = series[-1]
    for coefficient in reversed(series[:-1]):
        value = value * step + coefficient
    return value


def taylor_flow(inertia, quaternion, angular_momentum, times, digits=DIGITS):
    """
    Return {time: q(time)} (Decimals) for a torque-free body; see the module docstring.

    Parameters
    ----------
    inertia : array_like, shape (3, 3)
        Inertia tensor about the COM, body frame (kg m^2), double values taken exactly.
    quaternion : array_like, shape (4,)
        Initial orientation (x, y, z, w), body to world, double values taken exactly.
    angular_momentum : array_like, shape (3,)
        Initial world angular momentum L (kg m^2/s), double values taken exactly.
    times : iterable of Decimal
        Times (s), >= 0.
    digits : int
        Decimal digits of the arithmetic; the tolerance per step is 10^-digits.

    Returns
    -------
    (dict, float)
        time -> unit quaternion (4 Decimals, (x, y, z, w)); and the largest relative drift of
        |M| and of 2T over the steps (a consistency check: both are conserved).

    """
    with decimal.localcontext() as context:
        context.prec = digits
        tolerance = 10.0 ** -digits
        order = math.ceil(-math.log(tolerance) / 2.0) + 1
        exact = [[Decimal(float(value)) for value in row] for row in inertia]
        inverse = _inverse(exact)
        q = [Decimal(float(value)) for value in quaternion]
        norm = sum(c * c for c in q).sqrt()
        q = [c / norm for c in q]
        rotation = rotation_matrix_decimal(q)
        world = [Decimal(float(value)) for value in angular_momentum]
        momentum = [sum(rotation[row][column] * world[row] for row in range(3))
                    for column in range(3)]

        def invariants(m):
            omega = [sum(inverse[r][c] * m[c] for c in range(3)) for r in range(3)]
            return sum(c * c for c in m), sum(a * b for a, b in zip(m, omega))
        start = invariants(momentum)
        drift = 0.0
        scale = 1 / sum(c * c for c in momentum).sqrt()
        now = Decimal(0)
        values = {}
        for target in sorted(set(times)):
            while now < target:
                m_series, q_series = _coefficients(inverse, momentum, q, order + 1)
                # Radius of convergence from the last two coefficients (M scaled to O(1)).
                radius = math.inf
                for j in (order - 1, order):
                    size = max([abs(float(s[j] * scale)) for s in m_series]
                               + [abs(float(s[j])) for s in q_series])
                    if size > 0.0:
                        radius = min(radius, size ** (-1.0 / j))
                step = Decimal(radius / math.e ** 2) if math.isfinite(radius) else target - now
                step = min(step, target - now)
                momentum = [_horner(s, step) for s in m_series]
                q = [_horner(s, step) for s in q_series]
                now += step
                current = invariants(momentum)
                drift = max(drift, *(abs(float((c - s) / s)) for c, s in zip(current, start)))
            norm = sum(c * c for c in q).sqrt()
            values[target] = tuple(c / norm for c in q)
        return values, drift


def extended_reference(inertia, quaternion, angular_momentum, times, digits=DIGITS):
    """
    Return {time: (q, uncertainty)} from two Taylor solves (module docstring).

    q: 4 decimal strings, (x, y, z, w), of the solve at ``digits + CHECK_DIGITS``;
    uncertainty: the angle (rad) between it and the solve at ``digits``, an estimate of the
    latter's error and so an upper estimate of the former's.  Also returns the larger
    invariant drift of the two solves.
    """
    times = sorted(set(times))
    coarse, drift_coarse = taylor_flow(inertia, quaternion, angular_momentum, times, digits)
    fine, drift_fine = taylor_flow(inertia, quaternion, angular_momentum, times,
                                   digits + CHECK_DIGITS)
    with decimal.localcontext() as context:
        context.prec = digits + CHECK_DIGITS
        result = {t: (tuple(str(c) for c in fine[t]), quaternion_angle(coarse[t], fine[t]))
                  for t in times}
    return result, max(drift_coarse, drift_fine)


# -- committed values and the cache

def problem_fingerprint(body, state):
    """
    Return the exact double values that define a torque-free problem, as hex strings.

    The inertia tensor (9 entries, body frame), the quaternion (x, y, z, w) and the world
    angular momentum: a reference value is reused only for the very same doubles.
    """
    values = (list(map(float, _flat(body.inertia))) + list(map(float, state.quaternion))
              + list(map(float, state.angular_momentum)))
    return ' '.join(value.hex() for value in values)


def _flat(matrix):
    return [value for row in matrix for value in row]


def key_string(steps, dt):
    """Return the text key of N steps of dt: 'N x repr(dt)', e.g. '100 x 0.1'."""
    return f'{int(steps)} x {float(dt)!r}'


def cache_path():
    """
    Return the cache file of computed reference values.

    ``$RIGID_BODY_SIM_CACHE`` if set, else ``$XDG_CACHE_HOME/rigid_body_sim`` (default
    ``~/.cache/rigid_body_sim``), file ``benchmark_reference.json``.
    """
    directory = os.environ.get('RIGID_BODY_SIM_CACHE') or os.path.join(
        os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache'),
        'rigid_body_sim')
    return os.path.join(directory, 'benchmark_reference.json')


def _read_cache(path):
    try:
        with open(path) as cache:
            return json.load(cache)
    except (OSError, ValueError):
        return {}


def _write_cache(path, content):
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        temporary = f'{path}.{os.getpid()}.tmp'
        with open(temporary, 'w') as cache:
            json.dump(content, cache, indent=1, sort_keys=True)
        os.replace(temporary, path)
    except OSError as error:  # a read-only home only costs the recomputation next time
        print(f'bench: could not write the reference cache {path}: {error}', file=sys.stderr)


REFERENCE_SETS = {
    'bodies': 'reference_values.json',
    'scenes': 'scene_reference_values.json',
}
"""The committed reference sets, files of the package's ``data/`` folder: the benchmark bodies
at every (N, dt) of both sweeps, and the torque-free built-in scenes every 0.5 s over 60 s at
each scene's tick."""


@functools.cache
def committed_references(name):
    """
    Return the committed reference set `name` (a key of :data:`REFERENCE_SETS`), read once.

    {fingerprint (:func:`problem_fingerprint`): {'name': str, 'drift': float, 'values':
    {'N x dt' (:func:`key_string`): [x, y, z, w, uncertainty]}}}: the unit quaternion, body
    to world, at exactly N x dt s as 4 decimal strings, and the angle (rad) between the two
    solves; drift: the largest relative drift of |M| and 2T over the solves.  The same dict
    is returned to every caller: read it, never change it.
    """
    data = importlib.resources.files(__package__) / 'data' / REFERENCE_SETS[name]
    return json.loads(data.read_text(encoding='utf-8'))['problems']


def _committed(fingerprint):
    # A scene may be one of the benchmark bodies (van Zon's): both sets of times count.
    entries = [problems[fingerprint] for problems in map(committed_references, REFERENCE_SETS)
               if fingerprint in problems]
    values = {key: value for entry in entries for key, value in entry['values'].items()}
    return values, max((entry['drift'] for entry in entries), default=0.0)


def reference_quaternions(body, state, keys, use_cache=True):
    """
    Return the extended-precision reference of a torque-free problem at N steps of dt.

    Values come from :func:`committed_references` (for the benchmark's own bodies and sweeps
    and the built-in scenes) when the problem's doubles match bit for bit, else from the cache
    (:func:`cache_path`), else they are computed (:func:`extended_reference`) and cached.

    Parameters
    ----------
    body : RigidBody
        Mass properties (the inertia tensor in the body frame, kg m^2).
    state : State
        Torque-free initial state at t = 0.
    keys : iterable of (int, float)
        (N, dt) pairs; the reference is taken at exactly N x dt s.
    use_cache : bool
        False: neither read nor write the cache (committed values are still used).

    Returns
    -------
    (dict, float, str)
        (N, dt) -> (quaternion (x, y, z, w) as 4 decimal strings, uncertainty in rad); the
        invariant drift of the solves; and where the values came from.

    """
    keys = sorted({(int(n), float(dt)) for n, dt in keys})
    fingerprint = problem_fingerprint(body, state)
    committed, drift = _committed(fingerprint)
    found = {key: committed[key_string(*key)] for key in keys if key_string(*key) in committed}
    sources = {'committed'} if found else set()
    missing = [key for key in keys if key not in found]
    path = cache_path()
    cached = _read_cache(path).get(fingerprint, {}) if (missing and use_cache) else {}
    for key in missing:
        if key_string(*key) in cached.get('values', {}):
            found[key] = tuple(cached['values'][key_string(*key)])
            drift = max(drift, cached['drift'])
            sources.add('cached')
    missing = [key for key in keys if key not in found]
    if missing:
        times = {key: exact_time(*key) for key in missing}
        values, computed_drift = extended_reference(body.inertia, state.quaternion,
                                                    state.angular_momentum, times.values())
        drift = max(drift, computed_drift)
        sources.add('computed now')
        for key, time in times.items():
            quaternion, uncertainty = values[time]
            found[key] = (*quaternion, uncertainty)
        if use_cache:
            content = _read_cache(path)
            entry = content.setdefault(fingerprint, {'values': {}, 'drift': 0.0})
            entry['drift'] = max(entry['drift'], computed_drift)
            entry['values'].update({key_string(*key): list(found[key]) for key in missing})
            _write_cache(path, content)
    result = {key: (tuple(found[key][:4]), float(found[key][4])) for key in keys}
    return result, drift, ' + '.join(sorted(sources))

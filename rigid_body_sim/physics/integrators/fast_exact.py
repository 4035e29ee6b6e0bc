"""
Compiled fast path (numba) of the `exact` integrator, on the packed arrays of :mod:`.fast`.

The same construction as the readable :mod:`.exact` (see its docstring for the derivation),
line for line, with scalars instead of small arrays and the compiled elliptic functions of
:mod:`rigid_body_sim.physics.elliptic`.  The readable definition holds the unrounded end of a
step exactly (integers over a power of two); here it is held in double-double arithmetic
(Dekker's exact products and Knuth's exact sums, relative error ~1e-32), which rounds to the
same double but in the rarest ties.  The tests prove both equal to round-off, and the last
rounding of the same increment equal to the bit.

A step under a held wrench is kick(dt/2), exact free flow(dt), kick(dt/2) (Strang), as in
the readable step, with the whole wrench, the lever force's moment (R r) x F included,
taken at the kick points as the other compiled integrators do; a dissipation flow is fused
around it as flow(dt/2), step(dt), flow(dt/2).  Packed arrays and the run signature: see
:mod:`.fast`.
"""

import functools
import math

import numba

from .fast import BODY_AXES
from .fast import BODY_KIND
from .fast import BODY_MASS
from .fast import BODY_MOMENTS
from .fast import CompiledIntegrator
from .fast import dissipate
from .fast import kick
from .fast import nonzero_momentum
from .fast import pushes
from .principal import ASYMMETRIC
from .principal import OBLATE
from .principal import PROLATE
from .principal import SPHERICAL
from ..elliptic import carlson_rf_compiled
from ..elliptic import carlson_rj_compiled
from ..elliptic import jacobi_elliptic_compiled
from ..error_control import controlled_ticks

__all__ = ['exact_kernel']

_jit = functools.partial(numba.njit, cache=True, nogil=True)

# The constants of the readable module (exact.py), which imports this one.
_QUARTER_PERIOD_FLOOR = 0.5 * math.pi
_SHORT_STEP_SN = 0.75
_WELL_CONDITIONED = 0.25
_LARGEST_CORRECTION = 16.0 * 2.0 ** -52
# Dekker's splitting constant 2^27 + 1: a = hi + lo with 26-bit halves, so hi * hi is exact.
_SPLITTER = 134217729.0


# -- double-double arithmetic (a value is a pair hi + lo, |lo| <= ulp(hi)/2) -------------


@_jit
def _two_sum(a, b):
    """Return (s, e) with s = fl(a + b) and s + e = a + b exactly (Knuth)."""
    s = a + b
    v = s - a
    return s, (a - (s - v)) + (b - v)


@_jit
def _fast_two_sum(a, b):
    """Return (s, e), s + e = a + b exactly, for |a| >= |b| (Dekker)."""
    s = a + b
    return s, b - (s - a)


@_jit
def _two_product(a, b):
    """Return (p, e) with p = fl(a b) and p + e = a b exactly (Dekker, Veltkamp split)."""
    p = a * b
    t = _SPLITTER * a
    ah = t - (t - a)
    al = a - ah
    t = _SPLITTER * b
    bh = t - (t - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


@_jit
def _dd_add(a, b):
    s, e = _two_sum(a[0], b[0])
    return _fast_two_sum(s, e + (a[1] + b[1]))


@_jit
def _dd_sub(a, b):
    return _dd_add(a, (-b[0], -b[1]))


@_jit
def _dd_mul(a, b):
    p, e = _two_product(a[0], b[0])
    return _fast_two_sum(p, e + (a[0] * b[1] + a[1] * b[0]))


@_jit
def _dd_scale(a, b):
    """Return a b for a double-double a and a double b."""
    p, e = _two_product(a[0], b)
    return _fast_two_sum(p, e + a[1] * b)


@_jit
def _dd_div(a, b):
    q1 = a[0] / b[0]
    r = _dd_sub(a, _dd_scale(b, q1))
    return _fast_two_sum(q1, (r[0] + r[1]) / b[0])


@_jit
def _twice_energy(qx, qy, qz, qw, lx, ly, lz, axes, moments):
    """
    Return (2T, |q|^2) as double-doubles for the orientation q/|q|, q given as double-doubles.

    The readable _twice_energy_exactly: 2T = 2T_h(q) / |q|^4 with the homogeneous R_h(q).
    """
    xx, yy, zz, ww = _dd_mul(qx, qx), _dd_mul(qy, qy), _dd_mul(qz, qz), _dd_mul(qw, qw)
    xy, xz, yz = _dd_mul(qx, qy), _dd_mul(qx, qz), _dd_mul(qy, qz)
    xw, yw, zw = _dd_mul(qx, qw), _dd_mul(qy, qw), _dd_mul(qz, qw)
    norm_squared = _dd_add(_dd_add(xx, yy), _dd_add(zz, ww))
    r00 = _dd_sub(_dd_add(ww, xx), _dd_add(yy, zz))
    r11 = _dd_sub(_dd_add(ww, yy), _dd_add(xx, zz))
    r22 = _dd_sub(_dd_add(ww, zz), _dd_add(xx, yy))
    r01 = _dd_scale(_dd_sub(xy, zw), 2.0)
    r10 = _dd_scale(_dd_add(xy, zw), 2.0)
    r02 = _dd_scale(_dd_add(xz, yw), 2.0)
    r20 = _dd_scale(_dd_sub(xz, yw), 2.0)
    r12 = _dd_scale(_dd_sub(yz, xw), 2.0)
    r21 = _dd_scale(_dd_add(yz, xw), 2.0)
    # m_j = sum_i R_ij L_i (body frame, times |q|^2)
    b0 = _dd_add(_dd_add(_dd_scale(r00, lx), _dd_scale(r10, ly)), _dd_scale(r20, lz))
    b1 = _dd_add(_dd_add(_dd_scale(r01, lx), _dd_scale(r11, ly)), _dd_scale(r21, lz))
    b2 = _dd_add(_dd_add(_dd_scale(r02, lx), _dd_scale(r12, ly)), _dd_scale(r22, lz))
    total = (0.0, 0.0)
    for k in range(3):
        p = _dd_add(_dd_add(_dd_scale(b0, axes[0, k]), _dd_scale(b1, axes[1, k])),
                    _dd_scale(b2, axes[2, k]))
        total = _dd_add(total, _dd_div(_dd_mul(p, p), (moments[k], 0.0)))
    return _dd_div(total, _dd_mul(norm_squared, norm_squared)), norm_squared


# -- quaternions and the increment --------------------------------------------------------


@_jit
def _normalised(q):
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)


@_jit
def _momentum_body(q, lx, ly, lz):
    """Return R(q)^T L: world vector L in the body frame (q a unit quaternion)."""
    x, y, z, w = q
    return ((1.0 - 2.0 * (y * y + z * z)) * lx + 2.0 * (x * y + z * w) * ly
            + 2.0 * (x * z - y * w) * lz,
            2.0 * (x * y - z * w) * lx + (1.0 - 2.0 * (x * x + z * z)) * ly
            + 2.0 * (y * z + x * w) * lz,
            2.0 * (x * z + y * w) * lx + 2.0 * (y * z - x * w) * ly
            + (1.0 - 2.0 * (x * x + y * y)) * lz)


@_jit
def _half_turn_increment(ax, ay, az, angle):
    quarter = math.sin(0.25 * angle)
    s = math.sin(0.5 * angle)
    return s * ax, s * ay, s * az, -2.0 * quarter * quarter


@_jit
def _compose_increments(x, y):
    xx, xy, xz, xw = x
    yx, yy, yz, yw = y
    return (xx + yx + xw * yx + yw * xx + (xy * yz - xz * yy),
            xy + yy + xw * yy + yw * xy + (xz * yx - xx * yz),
            xz + yz + xw * yz + yw * xz + (xx * yy - xy * yx),
            xw + yw + xw * yw - (xx * yx + xy * yy + xz * yz))


@_jit
def _symmetric_increment(mx, my, mz, momentum_norm, moments, axes, kind, duration):
    if kind == PROLATE:
        column, axial, transverse = 2, moments[2], moments[0]
    elif kind == OBLATE:
        column, axial, transverse = 0, moments[0], moments[1]
    else:
        column, axial, transverse = 2, moments[2], moments[2]
    ax, ay, az = axes[0, column], axes[1, column], axes[2, column]
    spin = duration * (ax * mx + ay * my + az * mz) * (1.0 / axial - 1.0 / transverse)
    precession = _half_turn_increment(mx / momentum_norm, my / momentum_norm,
                                      mz / momentum_norm, duration * momentum_norm / transverse)
    return _compose_increments(precession, _half_turn_increment(ax, ay, az, spin))


@_jit
def _third_kind_part(sn, cn, dn, b_over_a):
    return sn ** 3 * carlson_rj_compiled(cn * cn, dn * dn, 1.0, 1.0 + b_over_a * sn * sn)


@_jit
def _increments_by_addition(s0, c0, d0, sh, ch, dh, parameter, b_over_a):
    """Compute the readable increments by addition; ok is False where it returns None."""
    sum_form = c0 * c0 + s0 * s0 * dh * dh
    if sum_form < _WELL_CONDITIONED:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0
    sh2 = sh * sh
    dh_minus_1 = -parameter * sh2 / (1.0 + dh)
    ch_minus_1 = -sh2 / (1.0 + ch) if ch >= 0.0 else ch - 1.0
    if abs(sh) <= _SHORT_STEP_SN:
        shrink = parameter * s0 * s0 * sh2
        denominator = 1.0 - shrink
        d_sn = (s0 * (ch_minus_1 * dh + dh_minus_1) + sh * c0 * d0 + shrink * s0) / denominator
        d_cn = (c0 * ch_minus_1 - s0 * d0 * sh * dh + shrink * c0) / denominator
        d_dn = (d0 * dh_minus_1 - parameter * s0 * c0 * sh * ch + shrink * d0) / denominator
    else:
        denominator = sum_form
        d_sn = (s0 * ch * dh + sh * c0 * d0) / denominator - s0
        d_cn = (c0 * ch - s0 * d0 * sh * dh) / denominator - c0
        d_dn = (d0 * dh - parameter * s0 * c0 * sh * ch) / denominator - d0
    s1, c1 = s0 + d_sn, c0 + d_cn
    alpha_squared = 1.0 + b_over_a
    sine_difference = (s0 * c0 * ch * dh_minus_1 + sh * d0 * (c0 * c0 + s0 * s0 * dh)) \
        / denominator
    theta = math.atan2(math.sqrt(alpha_squared) * sine_difference,
                       c1 * c0 + alpha_squared * s1 * s0)
    if sh > 0.0 and theta < 0.0:
        theta += 2.0 * math.pi
    elif sh < 0.0 and theta > 0.0:
        theta -= 2.0 * math.pi
    third = 0.0
    if b_over_a != 0.0:
        rho = math.sqrt(alpha_squared * (parameter + b_over_a) * b_over_a)
        product = s0 * sh * s1
        quotient = 1.0 + b_over_a * (1.0 - c0 * ch * c1)
        x = rho * product / quotient
        ratio = math.atan(x) / x if x != 0.0 else 1.0
        third = _third_kind_part(sh, ch, dh, b_over_a) + 3.0 * ratio * product / quotient
    return True, d_sn, d_cn, d_dn, theta, third


@_jit
def _increments_from_the_ends(s0, c0, d0, reduced, parameter, complement, b_over_a):
    """Compute the readable _increments_from_the_ends."""
    u0 = s0 * carlson_rf_compiled(c0 * c0, d0 * d0, 1.0)
    end = u0 + reduced
    turns = 0
    if complement > 0.0:
        half_period = 2.0 * carlson_rf_compiled(0.0, complement, 1.0)
        turns = int(round(end / half_period))
        end -= half_period * turns
    s1, c1, d1 = jacobi_elliptic_compiled(end, parameter, complement)
    theta = (turns * math.pi + math.atan2(math.sqrt(1.0 + b_over_a) * s1, c1)
             - math.atan2(math.sqrt(1.0 + b_over_a) * s0, c0))
    third = 0.0
    if b_over_a != 0.0:
        third = _third_kind_part(s1, c1, d1, b_over_a) - _third_kind_part(s0, c0, d0, b_over_a)
        if turns != 0:
            third += 2.0 * turns * carlson_rj_compiled(0.0, complement, 1.0, 1.0 + b_over_a)
    if turns % 2 != 0:
        s1, c1 = -s1, -c1
    return s1 - s0, c1 - c0, d1 - d0, theta, third


@_jit
def _turn_about_momentum_increment(nx, ny, nz, dx, dy, dz, angle):
    """Compute the readable turn-about-momentum increment (body frame)."""
    tx, ty, tz = dy * nz - dz * ny, dz * nx - dx * nz, dx * ny - dy * nx
    tilt_squared = tx * tx + ty * ty + tz * tz
    alignment = 1.0 + (nx * nx + ny * ny + nz * nz) + (nx * dx + ny * dy + nz * dz)
    norm = math.sqrt(tilt_squared + alignment * alignment)
    return _compose_increments(_half_turn_increment(nx, ny, nz, angle),
                               (tx / norm, ty / norm, tz / norm,
                                -tilt_squared / (norm * (alignment + norm))))


@_jit
def _pole_turn_increment(nx, ny, nz, dx, dy, dz, precession):
    lz = nz + 1.0
    start_squared = nx * nx + ny * ny + lz * lz
    start_length = math.sqrt(start_squared)
    ax, ay, az = nx / start_length, ny / start_length, lz / start_length
    growth = 2.0 * (nx * dx + ny * dy + lz * dz) + (dx * dx + dy * dy + dz * dz)
    end_length = math.sqrt(start_squared + growth)
    f = growth / (start_length + end_length)
    ex, ey, ez = (dx - ax * f) / end_length, (dy - ay * f) / end_length, \
        (dz - az * f) / end_length
    bx, by, bz = ax + ex, ay + ey, az + ez
    sine = math.sin(0.5 * precession)
    quarter = math.sin(0.25 * precession)
    cosine_minus_1 = -2.0 * quarter * quarter
    cosine = 1.0 + cosine_minus_1
    cx, cy, cz = ey * az - ez * ay, ez * ax - ex * az, ex * ay - ey * ax
    e_squared = ex * ex + ey * ey + ez * ez
    return (cosine * cx - sine * (-az * bx - bz * ax),
            cosine * cy - sine * (-az * by - bz * ay),
            cosine * cz - sine * ((1.0 - 0.5 * e_squared) - az * bz - bz * az),
            cosine_minus_1 - 0.5 * cosine * e_squared + sine * cz)


@_jit
def _asymmetric_increment(bx, by, bz, momentum_norm, moments, axes, duration):
    # Principal coordinates: axes^T m_body.
    p1 = axes[0, 0] * bx + axes[1, 0] * by + axes[2, 0] * bz
    p2 = axes[0, 1] * bx + axes[1, 1] * by + axes[2, 1] * bz
    p3 = axes[0, 2] * bx + axes[1, 2] * by + axes[2, 2] * bz
    i1, i2, i3 = moments[0], moments[1], moments[2]
    separatrix = p1 * p1 * (i1 - i2) / i1 + p3 * p3 * (i3 - i2) / i3
    # The circulation frame F = axes @ change, as principal-axis columns with signs.
    if separatrix >= 0.0:
        j1, j2, j3 = i1, i2, i3
        m1, m2, m3 = p1, p2, p3
        column1, column2, column3 = 0, 1, 2
        f1, f2, f3 = 1.0, 1.0, 1.0
    else:
        # New axes (e3, -e2, e1).
        j1, j2, j3 = i3, i2, i1
        m1, m2, m3 = p3, -p2, p1
        column1, column2, column3 = 2, 1, 0
        f1, f2, f3 = 1.0, -1.0, 1.0
    if m3 < 0.0:
        m2, m3 = -m2, -m3
        f2, f3 = -f2, -f3
    if m1 < 0.0:
        m1, m2 = -m1, -m2
        f1, f2 = -f1, -f2
    twice_energy = m1 * m1 / j1 + m2 * m2 / j2 + m3 * m3 / j3
    a = m1 * m1 + m2 * m2 * j1 * (j3 - j2) / (j2 * (j3 - j1))
    if a == 0.0 or (m1 == 0.0 and m3 == 0.0):
        return _half_turn_increment(bx / momentum_norm, by / momentum_norm,
                                    bz / momentum_norm, duration * twice_energy / momentum_norm)
    b_squared = m2 * m2 + m1 * m1 * j2 * (j3 - j1) / (j1 * (j3 - j2))
    c_squared = m3 * m3 + m2 * m2 * j3 * (j2 - j1) / (j2 * (j3 - j1))
    amplitude_a, amplitude_b = math.sqrt(a), math.sqrt(b_squared)
    amplitude_c = math.sqrt(c_squared)
    g = m2 * m2 * (j2 - j1) / j2 + m3 * m3 * (j3 - j1) / j3
    h = m1 * m1 * (j3 - j1) / j1 + m2 * m2 * (j3 - j2) / j2
    parameter = (j2 - j1) * h / ((j3 - j2) * g)
    complement = (j3 - j1) * separatrix / ((j3 - j2) * g)
    rate = math.copysign(math.sqrt((j3 - j2) * g / (j1 * j2 * j3)), j3 - j2)
    s0, c0, d0 = m2 / amplitude_b, m1 / amplitude_a, m3 / amplitude_c
    step = rate * duration
    turns, reduced = 0, step
    if complement > 0.0 and abs(step) > _QUARTER_PERIOD_FLOOR:
        half_period = 2.0 * carlson_rf_compiled(0.0, complement, 1.0)
        turns = int(round(step / half_period))
        reduced = step - half_period * turns
    b_over_a = c_squared * parameter / a
    sh, ch, dh = jacobi_elliptic_compiled(reduced, parameter, complement)
    ok, d_sn, d_cn, d_dn, theta, third_kind = _increments_by_addition(
        s0, c0, d0, sh, ch, dh, parameter, b_over_a)
    if not ok:
        d_sn, d_cn, d_dn, theta, third_kind = _increments_from_the_ends(
            s0, c0, d0, reduced, parameter, complement, b_over_a)
    theta += turns * math.pi
    if turns != 0 and b_over_a != 0.0:
        third_kind += 2.0 * turns * carlson_rj_compiled(0.0, complement, 1.0, 1.0 + b_over_a)
    third_kind *= momentum_norm * momentum_norm * amplitude_c * parameter / (3.0 * a * a)
    alpha = math.sqrt(1.0 + b_over_a)
    integral = -amplitude_c / a * step + momentum_norm / (a * alpha) * theta + third_kind
    precession = (duration * twice_energy / momentum_norm
                  - amplitude_a * amplitude_b / momentum_norm * integral)
    if turns % 2 != 0:
        dx, dy = -(2.0 * m1 + amplitude_a * d_cn), -(2.0 * m2 + amplitude_b * d_sn)
    else:
        dx, dy = amplitude_a * d_cn, amplitude_b * d_sn
    dz = amplitude_c * d_dn
    nx, ny, nz = m1 / momentum_norm, m2 / momentum_norm, m3 / momentum_norm
    dx, dy, dz = dx / momentum_norm, dy / momentum_norm, dz / momentum_norm
    if nx * (nx + dx) + ny * (ny + dy) + nz * (nz + dz) >= 0.0:
        excess = 2.0 * math.atan2(nx * dy - ny * dx, 1.0 + nz + (nz + dz)
                                  + (nx * (nx + dx) + ny * (ny + dy) + nz * (nz + dz)))
        ex, ey, ez = _to_body(dx, dy, dz, f1, f2, f3, column1, column2, column3, axes)
        return _turn_about_momentum_increment(bx / momentum_norm, by / momentum_norm,
                                              bz / momentum_norm, ex, ey, ez,
                                              precession + excess)
    vx, vy, vz, w = _pole_turn_increment(nx, ny, nz, dx, dy, dz, precession)
    ux, uy, uz = _to_body(vx, vy, vz, f1, f2, f3, column1, column2, column3, axes)
    return ux, uy, uz, w


@_jit
def _to_body(vx, vy, vz, f1, f2, f3, column1, column2, column3, axes):
    """Return F v = sum_k f_k v_k axes[:, column_k] (circulation frame to body frame)."""
    ux, uy, uz = f1 * vx, f2 * vy, f3 * vz
    return (ux * axes[0, column1] + uy * axes[0, column2] + uz * axes[0, column3],
            ux * axes[1, column1] + uy * axes[1, column2] + uz * axes[1, column3],
            ux * axes[2, column1] + uy * axes[2, column2] + uz * axes[2, column3])


@_jit
def _rounded_step(q, increment, lx, ly, lz, moments, axes, kind):
    """Round q + q (D - 1) once, normalised, with the energy of q (readable _rounded_step)."""
    x, y, z, w = q
    vx, vy, vz, s = increment
    change = (w * vx + s * x + (y * vz - z * vy), w * vy + s * y + (z * vx - x * vz),
              w * vz + s * z + (x * vy - y * vx), w * s - (x * vx + y * vy + z * vz))
    hx, ex = _two_sum(x, change[0])
    hy, ey = _two_sum(y, change[1])
    hz, ez = _two_sum(z, change[2])
    hw, ew = _two_sum(w, change[3])
    target, _ = _twice_energy((x, 0.0), (y, 0.0), (z, 0.0), (w, 0.0), lx, ly, lz, axes,
                              moments)
    reached, norm_squared = _twice_energy((hx, ex), (hy, ey), (hz, ez), (hw, ew), lx, ly, lz,
                                          axes, moments)
    excess = (reached[0] - target[0]) + (reached[1] - target[1])
    mx, my, mz = _momentum_body((hx, hy, hz, hw), lx, ly, lz)
    p1 = axes[0, 0] * mx + axes[1, 0] * my + axes[2, 0] * mz
    p2 = axes[0, 1] * mx + axes[1, 1] * my + axes[2, 1] * mz
    p3 = axes[0, 2] * mx + axes[1, 2] * my + axes[2, 2] * mz
    o1, o2, o3 = p1 / moments[0], p2 / moments[1], p3 / moments[2]
    k1, k2, k3 = p2 * o3 - p3 * o2, p3 * o1 - p1 * o3, p1 * o2 - p2 * o1
    kx = axes[0, 0] * k1 + axes[0, 1] * k2 + axes[0, 2] * k3
    ky = axes[1, 0] * k1 + axes[1, 1] * k2 + axes[1, 2] * k3
    kz = axes[2, 0] * k1 + axes[2, 1] * k2 + axes[2, 2] * k3
    axis_squared = kx * kx + ky * ky + kz * kz
    cx = cy = cz = cw = 0.0
    if axis_squared > 0.0 and kind != SPHERICAL:
        f = excess / (4.0 * axis_squared)
        tx, ty, tz = f * kx, f * ky, f * kz
        if tx * tx + ty * ty + tz * tz <= (0.5 * _LARGEST_CORRECTION) ** 2:
            cx = hw * tx + (hy * tz - hz * ty)
            cy = hw * ty + (hz * tx - hx * tz)
            cz = hw * tz + (hx * ty - hy * tx)
            cw = -(hx * tx + hy * ty + hz * tz)
    half_excess = 0.5 * ((norm_squared[0] - 1.0) + norm_squared[1])
    return (hx + ((ex - hx * half_excess) + cx), hy + ((ey - hy * half_excess) + cy),
            hz + ((ez - hz * half_excess) + cz), hw + ((ew - hw * half_excess) + cw))


@_jit
def _free_rotation(q, lx, ly, lz, moments, axes, kind, duration):
    if (lx == 0.0 and ly == 0.0 and lz == 0.0) or duration == 0.0:
        return q
    mx, my, mz = _momentum_body(q, lx, ly, lz)
    momentum_norm = math.sqrt(lx * lx + ly * ly + lz * lz)
    if kind == ASYMMETRIC:
        increment = _asymmetric_increment(mx, my, mz, momentum_norm, moments, axes, duration)
    else:
        increment = _symmetric_increment(mx, my, mz, momentum_norm, moments, axes, kind,
                                         duration)
    return _rounded_step(q, increment, lx, ly, lz, moments, axes, kind)


@_jit
def _exact_run(state, wrench, body, method, damping, dt, steps):
    """Run the exact integrator (signature: fast.py; no method constants)."""
    linear_momentum, angular_momentum = state[7:10], state[10:13]
    mass = body[BODY_MASS]
    moments = body[BODY_MOMENTS:BODY_MOMENTS + 3]
    axes = body[BODY_AXES:BODY_AXES + 9].reshape((3, 3))
    kind = int(body[BODY_KIND])
    pushed, forced = pushes(wrench)
    # Unforced, p is constant: a body at rest stays where it is without any arithmetic.
    translates = forced or nonzero_momentum(state)
    half = 0.5 * dt
    moved = 0
    for _ in range(steps):
        if damping > 0.0:
            dissipate(state, body, damping, half)
        q = (state[0], state[1], state[2], state[3])
        if abs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0) > 1e-12:
            # The last rounding normalises to first order: start from a unit quaternion.
            q = _normalised(q)
        if pushed:
            kick(q, linear_momentum, angular_momentum, wrench, half)
        q = _free_rotation(q, angular_momentum[0], angular_momentum[1], angular_momentum[2],
                           moments, axes, kind, dt)
        if translates:
            for i in range(3):
                state[4 + i] += dt * linear_momentum[i] / mass
            moved += 1
        if pushed:
            kick(q, linear_momentum, angular_momentum, wrench, half)
        state[0], state[1], state[2], state[3] = q
        if damping > 0.0:
            dissipate(state, body, damping, half)
    return moved


@_jit
def _exact_controlled(state, wrench, body, method, damping, tick, ticks, control, clock):
    return controlled_ticks(_exact_run, state, wrench, body, method, damping, tick, ticks,
                            control, clock)


exact_kernel = CompiledIntegrator(_exact_run, controlled=_exact_controlled)
"""The compiled exact integrator (run signature and registry form: :mod:`.fast`)."""

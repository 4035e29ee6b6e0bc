"""
Reference elliptic functions on scipy.special, for the compiled ones of physics/elliptic.py.

scipy's ellipj forms 1 - m itself, so next to m = 1 (a body near its separatrix) it loses the
complementary parameter m1 = k'^2; here, above m = 1/2, descending Landen transformations
(Abramowitz & Stegun 16.12) computed from m and m1 separately bring m below 1/2 first, where
ellipj is accurate.  Carlson's integrals are scipy's elliprf and elliprj.  The package's
compiled versions descend to m < 1e-9 and use A&S 16.13 there, and run Carlson's duplication
in their own code: the two share the Landen relations, not the code.
"""

import math

from scipy.special import ellipj
from scipy.special import elliprf
from scipy.special import elliprj

__all__ = ['jacobi_elliptic', 'carlson_rf', 'carlson_rj']


def _landen_step(parameter, complement):
    """
    Return sqrt(mu), mu, 1 - mu and 1 - sqrt(mu) of the descending Landen transformation.

    sqrt(mu) = (1 - k') / (1 + k') = m / (1 + k')^2 and 1 - mu = 4 k' / (1 + k')^2: both are
    formed without cancellation, from m and m1 = k'^2 separately.
    """
    modulus_complement = math.sqrt(complement)
    root = parameter / (1.0 + modulus_complement) ** 2
    return (root, root * root, 4.0 * modulus_complement / (1.0 + modulus_complement) ** 2,
            2.0 * modulus_complement / (1.0 + modulus_complement))


def _landen_ascend(sn, cn, dn, root, one_minus_root):
    """
    Return sn, cn, dn at (u | m) from those at (u / (1 + sqrt(mu)) | mu) (A&S 16.12).

    dn = (1 - sqrt(mu) sn^2) / (1 + sqrt(mu) sn^2) is evaluated as
    ((1 - sqrt(mu)) + sqrt(mu) cn^2) / (...), free of cancellation where dn is small.
    """
    denominator = 1.0 + root * sn * sn
    return ((1.0 + root) * sn / denominator, cn * dn / denominator,
            (one_minus_root + root * cn * cn) / denominator)


def jacobi_elliptic(u, parameter, complement):
    """
    Return the Jacobi elliptic functions (sn, cn, dn) of (u | m).

    Parameters
    ----------
    u : float
        Argument (for accuracy, reduce it to |u| <= K(m) first).
    parameter, complement : float
        m = k^2 in [0, 1] and m1 = 1 - m, each given to full relative precision.

    Notes
    -----
    For m <= 1/2 this is scipy.special.ellipj.  Above, descending Landen transformations
    (A&S 16.12) map m to smaller parameters, computed from m1 without forming 1 - m, until
    m <= 1/2; m = 1 gives the hyperbolic limit sn = tanh u, cn = dn = sech u.

    """
    if complement == 0.0:
        return math.tanh(u), 1.0 / math.cosh(u), 1.0 / math.cosh(u)
    if parameter <= 0.5:
        sn, cn, dn, _ = ellipj(u, parameter)
        return float(sn), float(cn), float(dn)
    root, reduced, reduced_complement, one_minus_root = _landen_step(parameter, complement)
    sn, cn, dn = jacobi_elliptic(u / (1.0 + root), reduced, reduced_complement)
    return _landen_ascend(sn, cn, dn, root, one_minus_root)


def carlson_rf(x, y, z):
    """Return Carlson's R_F(x, y, z) = 1/2 int_0^inf dt / sqrt((t+x)(t+y)(t+z)) (scipy)."""
    return float(elliprf(x, y, z))


def carlson_rj(x, y, z, p):
    """Return Carlson's R_J(x, y, z, p) = 3/2 int_0^inf dt / ((t+p) sqrt((t+x)(t+y)(t+z)))."""
    return float(elliprj(x, y, z, p))

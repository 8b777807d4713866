"""Small statistics helpers for the sampler tests (no SciPy).

* :func:`gammaincc` -- regularised upper incomplete gamma Q(a, x), by the power series of
  P(a, x) for x < a + 1 and by the Lentz continued fraction of Q(a, x) otherwise
  (Numerical Recipes 6.2), with ``math.lgamma`` for the prefactor;
* :func:`chi2_sf` -- the chi-square survival function Q(k/2, x/2) (the p-value of a statistic x
  with k degrees of freedom);
* :func:`normal_sf` / :func:`normal_isf` -- the standard normal tail and its inverse;
* :func:`sidak` -- the per-test significance that keeps the family-wise level at ``alpha``.
"""
from __future__ import annotations

import math

_EPS = 1e-15
_TINY = 1e-300
_MAX_ITER = 100_000


def _series_p(a, x):
    """Regularised lower incomplete gamma P(a, x) by its power series (x < a + 1)."""
    term = 1.0 / a
    total = term
    ap = a
    for _ in range(_MAX_ITER):
        ap += 1.0
        term *= x / ap
        total += term
        if abs(term) < abs(total) * _EPS:
            break
    else:
        raise ArithmeticError(f"series for P({a}, {x}) did not converge")
    return total * math.exp(-x + a * math.log(x) - math.lgamma(a))


def _continued_fraction_q(a, x):
    """Regularised upper incomplete gamma Q(a, x) by the modified Lentz continued fraction."""
    b = x + 1.0 - a
    c = 1.0 / _TINY
    d = 1.0 / b
    h = d
    for i in range(1, _MAX_ITER):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        if abs(d) < _TINY:
            d = _TINY
        c = b + an / c
        if abs(c) < _TINY:
            c = _TINY
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < _EPS:
            break
    else:
        raise ArithmeticError(f"continued fraction for Q({a}, {x}) did not converge")
    return math.exp(-x + a * math.log(x) - math.lgamma(a)) * h


def gammaincc(a, x):
    """Regularised upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a), a > 0."""
    if a <= 0:
        raise ValueError("a must be positive")
    if x <= 0:
        return 1.0
    if x < a + 1.0:
        return max(0.0, 1.0 - _series_p(a, x))
    return _continued_fraction_q(a, x)


def chi2_sf(x, dof):
    """P(X >= x) for X chi-square distributed with ``dof`` degrees of freedom."""
    return gammaincc(0.5 * dof, 0.5 * x)


def normal_sf(z):
    """P(Z >= z) for a standard normal Z."""
    return 0.5 * math.erfc(z / math.sqrt(2.0))


def normal_isf(p):
    """The z with P(Z >= z) = p (bisection; 0 < p < 1)."""
    if not 0.0 < p < 1.0:
        raise ValueError("p must be in (0, 1)")
    lo, hi = -40.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if normal_sf(mid) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def sidak(alpha, tests):
    """Per-test significance level for ``tests`` independent tests at family-wise level ``alpha``."""
    return 1.0 - (1.0 - alpha) ** (1.0 / tests)

"""Chi-square goodness-of-fit test for samplers over a 2-D parametrisation (Mitsuba 3 ``chi2.py``).

A test draws ``sample_count`` samples, maps them to a rectangle ``domain`` of parameters (for example
(cos theta, phi) for directions or (x, y) for shapes), histograms them on ``res`` bins per axis and
compares the histogram with the expected counts: ``sample_count`` times the integral of the density
over each bin, by Gauss-Legendre quadrature with ``ires`` nodes per axis and bin.  Bins with
expected counts under 5 are pooled (in increasing order of expected count, as Mitsuba does) and the
statistic is compared with the chi-square distribution at the caller's significance level.

Hard failures, whatever the statistic (Mitsuba and pbrt-v4 ``bsdfs_test.cpp``):

* a sample with a NaN/infinite or negative weight;
* a sample with positive weight that is not finite or lies outside ``domain``;
* a non-finite or negative density, or a density integrating to more than 1.1;
* more than 1e-5 * ``sample_count`` samples in bins whose density integrates to 0.

Samples with weight 0 are failed samples (absorbed, below the surface...): they are not counted in
the histogram but they are in ``sample_count``, so a sampler that loses mass the density claims
fails the test.  The density is in parameter space: it includes the Jacobian of the parametrisation.
"""
from __future__ import annotations

import numpy as np

from stats_utils import chi2_sf

MIN_EXPECTED = 5.0
ZERO_BIN_FRACTION = 1e-5


def integrate_bins(pdf_func, domain, res, ires):
    """Integrals (rx, ry) of ``pdf_func`` over the bins of ``domain``, Gauss-Legendre per bin.

    Raises ``ValueError`` if the density is not finite or negative at a quadrature node.
    """
    nodes, weights = np.polynomial.legendre.leggauss(ires)
    (x0, x1), (y0, y1) = np.asarray(domain, np.float64)
    rx, ry = (res, res) if np.isscalar(res) else res
    hx, hy = (x1 - x0) / rx, (y1 - y0) / ry
    px = (x0 + (np.arange(rx)[:, None] + 0.5 * (nodes[None, :] + 1.0)) * hx).reshape(-1)
    py = (y0 + (np.arange(ry)[:, None] + 0.5 * (nodes[None, :] + 1.0)) * hy).reshape(-1)
    wy = np.tile(weights, ry)
    k = ires
    integral = np.zeros((rx, ry))
    bins_per_chunk = max(1, 2_000_000 // (len(py) * k))
    for b0 in range(0, rx, bins_per_chunk):
        b1 = min(rx, b0 + bins_per_chunk)
        xs = px[b0 * k:b1 * k]
        grid = np.stack(np.broadcast_arrays(xs[:, None], py[None, :]), axis=-1).reshape(-1, 2)
        pdf = np.asarray(pdf_func(grid), np.float64).reshape(len(xs), len(py))
        if not np.isfinite(pdf).all():
            where = grid[~np.isfinite(pdf).reshape(-1)][:3].tolist()
            raise ValueError(f"the density is NaN/infinite at {where}")
        if (pdf < 0).any():
            raise ValueError(f"the density is negative (min {pdf.min():.6g})")
        wx = np.tile(weights, b1 - b0)
        integral[b0:b1] = (pdf * wx[:, None] * wy[None, :]).reshape(b1 - b0, k, ry, k).sum(axis=(1, 3))
    return integral * (0.25 * hx * hy)


class ChiSquareTest:
    """Mitsuba-style chi-square test of ``sample_func`` against ``pdf_func``.

    sample_func(n) -> (xy (n, 2) parameters, weight (n,) or None)
    pdf_func(xy (m, 2)) -> (m,) density per unit parameter area
    domain: ((x0, x1), (y0, y1))
    """

    def __init__(self, sample_func, pdf_func, domain, sample_count=1_000_000, res=101, ires=6,
                 domain_tolerance=1e-9, bin_probabilities=None):
        self.sample_func = sample_func
        self.pdf_func = pdf_func
        # Optional exact per-bin probabilities f(x_edges, y_edges) -> (rx, ry), instead of quadrature.
        self.bin_probabilities = bin_probabilities
        self.domain = np.asarray(domain, np.float64)
        self.sample_count = int(sample_count)
        self.res = (res, res) if np.isscalar(res) else tuple(res)
        self.ires = ires
        self.tolerance = domain_tolerance
        self.histogram = None
        self.expected = None
        self.messages = []
        self.p_value = None
        self.statistic = None
        self.dof = None

    def _fail(self, msg):
        self.messages.append(msg)
        return False

    # ------------------------------------------------------------------ histogram
    def tabulate_histogram(self):
        xy, weight = self.sample_func(self.sample_count)
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        if len(xy) != self.sample_count:
            return self._fail(f"sample_func returned {len(xy)} samples, expected {self.sample_count}")
        w = np.ones(len(xy)) if weight is None else np.asarray(weight, np.float64).reshape(-1)
        if not np.isfinite(w).all():
            return self._fail(f"{int((~np.isfinite(w)).sum())} samples have a NaN/infinite weight")
        if (w < 0).any():
            return self._fail(f"{int((w < 0).sum())} samples have a negative weight "
                              f"(min {w.min():.6g})")
        xy = xy[w > 0]
        bad = ~np.isfinite(xy).all(axis=1)
        if bad.any():
            return self._fail(f"{int(bad.sum())} valid samples are NaN/infinite, e.g. {xy[bad][0]}")
        lo, hi = self.domain[:, 0], self.domain[:, 1]
        tol = self.tolerance * (hi - lo)
        outside = ((xy < lo - tol) | (xy > hi + tol)).any(axis=1)
        if outside.any():
            return self._fail(f"{int(outside.sum())} samples lie outside the domain "
                              f"{self.domain.tolist()}, e.g. {xy[outside][:3].tolist()}")
        rx, ry = self.res
        ix = np.clip(((xy[:, 0] - lo[0]) / (hi[0] - lo[0]) * rx).astype(np.int64), 0, rx - 1)
        iy = np.clip(((xy[:, 1] - lo[1]) / (hi[1] - lo[1]) * ry).astype(np.int64), 0, ry - 1)
        self.histogram = np.bincount(ix * ry + iy, minlength=rx * ry).reshape(rx, ry).astype(np.float64)
        return True

    # ------------------------------------------------------------------ expected counts
    def tabulate_pdf(self):
        if self.bin_probabilities is not None:
            (x0, x1), (y0, y1) = self.domain
            integral = np.asarray(self.bin_probabilities(np.linspace(x0, x1, self.res[0] + 1),
                                                         np.linspace(y0, y1, self.res[1] + 1)), np.float64)
        else:
            try:
                integral = integrate_bins(self.pdf_func, self.domain, self.res, self.ires)
            except ValueError as e:
                return self._fail(str(e))
        if not np.isfinite(integral).all() or (integral < 0).any():
            return self._fail("the bin probabilities are NaN/infinite or negative")
        self.integral = integral
        total = float(integral.sum())
        if total > 1.1:
            return self._fail(f"the density integrates to {total:.6g} > 1.1")
        self.expected = integral * self.sample_count
        return True

    # ------------------------------------------------------------------ test
    def run(self, significance_level):
        """True if the test passes at ``significance_level``; failures fill ``messages``."""
        self.messages = []
        if not self.tabulate_histogram() or not self.tabulate_pdf():
            return False
        obs = self.histogram.reshape(-1)
        exp = self.expected.reshape(-1)
        in_zero = float(obs[exp <= 0].sum())
        if in_zero > ZERO_BIN_FRACTION * self.sample_count:
            idx = np.flatnonzero((exp <= 0) & (obs > 0))
            return self._fail(f"{in_zero:.0f} samples fall into bins of zero density, e.g. bins "
                              f"{[self._bin_center(i) for i in idx[:3]]}")
        order = np.argsort(exp, kind="stable")
        obs_s, exp_s = obs[order], exp[order]
        # Pool the cells with expected counts under 5, extended until the pool itself reaches 5.
        n_small = int(np.searchsorted(exp_s, MIN_EXPECTED, side="left"))
        n_pool = n_small
        if n_small:
            csum = np.cumsum(exp_s)
            if csum[n_small - 1] < MIN_EXPECTED:
                n_pool = min(int(np.searchsorted(csum, MIN_EXPECTED, side="left")) + 1, len(exp_s))
        cells_obs = obs_s[n_pool:]
        cells_exp = exp_s[n_pool:]
        stat = float(np.sum((cells_obs - cells_exp) ** 2 / cells_exp))
        dof = len(cells_exp)
        pool_exp = float(exp_s[:n_pool].sum())
        pool_obs = float(obs_s[:n_pool].sum())
        if pool_exp > 0:
            stat += (pool_obs - pool_exp) ** 2 / pool_exp
            dof += 1
        elif pool_obs > 0:
            return self._fail(f"{pool_obs:.0f} samples fall into bins of zero density")
        dof -= 1
        if dof < 1:
            return self._fail(f"too few cells for a chi-square test (dof = {dof})")
        self.statistic, self.dof = stat, dof
        self.p_value = chi2_sf(stat, dof)
        if self.p_value < significance_level or not np.isfinite(self.p_value):
            contrib = np.where(exp > 0, (obs - exp) ** 2 / np.where(exp > 0, exp, 1.0), 0.0)
            worst = np.argsort(contrib)[::-1][:5]
            detail = ", ".join(f"bin {self._bin_center(i)}: observed {obs[i]:.0f}, expected {exp[i]:.1f}"
                               for i in worst)
            return self._fail(f"chi-square rejects the sampler: statistic {stat:.1f} with {dof} dof, "
                              f"p = {self.p_value:.3g} < {significance_level:.3g}; "
                              f"samples with weight > 0: {obs.sum():.0f} of {self.sample_count}, "
                              f"expected {exp.sum():.1f}; largest terms: {detail}")
        return True

    def _bin_center(self, flat):
        rx, ry = self.res
        i, j = divmod(int(flat), ry)
        (x0, x1), (y0, y1) = self.domain
        return (round(x0 + (i + 0.5) * (x1 - x0) / rx, 6), round(y0 + (j + 0.5) * (y1 - y0) / ry, 6))

    @property
    def message(self):
        return "\n".join(self.messages)

"""Phase functions of scattering volumes: those of Blender 5.0's Volume Scatter (and Volume
Coefficients) node, as Cycles evaluates and samples them (``kernel/closure/volume_util.h``).

Henyey-Greenstein (anisotropy g), Rayleigh, Draine (g and alpha; Rayleigh at g = 0, alpha = 1,
Henyey-Greenstein at alpha = 0), Fournier-Forand (the particles' backscatter fraction B and IOR)
and Mie (the droplets' diameter in micrometres: Jendersie and d'Eon's mixture of a
Henyey-Greenstein and a Draine lobe, Cycles' ``phase_mie_fitted_parameters``).  A medium's phase is
resolved once into a row of :data:`ROW` numbers: (1 - w) HG(g_hg) + w Draine(g_d, alpha), or
Fournier-Forand's coefficients (n, v, c) where ``ff`` is 1.  Every function here samples its
phase exactly (the sampled direction's weight is 1) and takes rows (k, ROW) per direction.
"""
from __future__ import annotations

import numpy as np

from .sampling import direction_at, hg_cosine, hg_phase

HENYEY_GREENSTEIN, RAYLEIGH, DRAINE, FOURNIER_FORAND, MIE = range(5)
# Blender's enum items of Volume Scatter's ``phase``, in this order.
PHASE_NAMES = ("HENYEY_GREENSTEIN", "RAYLEIGH", "DRAINE", "FOURNIER_FORAND", "MIE")
# Columns of a resolved row.
G_HG, G_D, ALPHA, W, FF, FF_N, FF_V, FF_C = range(8)
ROW = 8
MAX_G = 1.0 - 1e-3                         # Cycles clamps |g| of both lobes to this


def resolve(kind, g, params):
    """(M, ROW) float64 rows of media of phase ``kind`` (M,) int (:data:`PHASE_NAMES` order),
    anisotropy ``g`` (M,) (Henyey-Greenstein and Draine) and ``params`` (M, 3): Draine's alpha,
    Fournier-Forand's (B, IOR), Mie's diameter (micrometres), each first; unused columns ignored."""
    kind = np.asarray(kind, np.int64).reshape(-1)
    m = len(kind)
    g = np.clip(np.asarray(g, np.float64).reshape(m), -MAX_G, MAX_G)
    params = np.asarray(params, np.float64).reshape(m, 3)
    rows = np.zeros((m, ROW))
    rows[:, G_HG] = np.where(kind == HENYEY_GREENSTEIN, g, 0.0)
    # Rayleigh: Draine at g = 0, alpha = 1; Draine: its own g and alpha.
    draine = (kind == RAYLEIGH) | (kind == DRAINE)
    rows[:, W] = draine
    rows[:, G_D] = np.where(kind == DRAINE, g, 0.0)
    rows[:, ALPHA] = np.where(kind == DRAINE, params[:, 0], np.where(kind == RAYLEIGH, 1.0, 0.0))
    mie = np.flatnonzero(kind == MIE)
    if len(mie):
        g_hg, g_d, alpha, w = mie_parameters(params[mie, 0])
        rows[mie, G_HG], rows[mie, G_D], rows[mie, ALPHA], rows[mie, W] = g_hg, g_d, alpha, w
    ff = np.flatnonzero(kind == FOURNIER_FORAND)
    if len(ff):
        rows[ff, FF] = 1.0
        rows[ff, FF_N], rows[ff, FF_V], rows[ff, FF_C] = fournier_forand_coefficients(params[ff, 0],
                                                                                       params[ff, 1])
    rows[:, G_HG] = np.clip(rows[:, G_HG], -MAX_G, MAX_G)
    rows[:, G_D] = np.clip(rows[:, G_D], -MAX_G, MAX_G)
    return rows


def isotropic(rows):
    """(k,) bool: rows that scatter evenly (1 / (4 pi) in every direction)."""
    rows = np.asarray(rows, np.float64)
    return ((rows[:, FF] == 0) & (np.abs(rows[:, G_HG]) < 1e-3) & ((rows[:, W] == 0)
            | ((np.abs(rows[:, G_D]) < 1e-3) & (np.abs(rows[:, ALPHA]) < 1e-3))))


def mie_parameters(d):
    """(g_hg, g_d, alpha, w) (n,) each of water droplets of diameter ``d`` (n,) micrometres (Cycles'
    ``phase_mie_fitted_parameters``, after Jendersie and d'Eon's supplemental equations 7-22)."""
    d = np.maximum(np.asarray(d, np.float64), 0.0)
    out = [np.zeros(len(d)) for _ in range(4)]
    ranges = (d <= 0.1, (d > 0.1) & (d < 1.5), (d >= 1.5) & (d < 5.0), d >= 5.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_d = np.log(np.maximum(d, 1e-30))
        loglog = np.log(np.maximum(log_d, 1e-30))
        a = (log_d - 0.238604) * (log_d + 1.00667)
        b = 0.507522 - 0.15677 * log_d
        c = 1.19692 * np.cos(a / b) + 1.37932 * log_d + 0.0625835
        fits = (
            (13.8 * d ** 2, 1.1456 * d * np.sin(9.29044 * d), np.full(len(d), 250.0),
             0.252977 - 312.983 * d ** 4.3),
            (0.862 - 0.143 * log_d ** 2, 0.379685 * np.cos(c) + 0.344213, np.full(len(d), 250.0),
             0.146209 * np.cos(3.38707 * log_d + 2.11193) + 0.316072 + 0.0778917 * log_d),
            (0.0604931 * loglog + 0.940256, 0.500411 - 0.081287 / (-2.0 * log_d + np.tan(log_d) + 1.27551),
             7.30354 * log_d + 6.31675,
             0.026914 * (log_d - np.cos(5.68947 * (loglog - 0.0292149))) + 0.3764),
            (np.exp(-0.0990567 / (d - 1.67154)), np.exp(-2.20679 / (d + 3.91029) - 0.428934),
             np.exp(3.62489 - 8.29288 / (d + 5.52825)), np.exp(-0.599085 / (d - 0.641583) - 0.665888)))
    for where, fit in zip(ranges, fits):
        for k in range(4):
            out[k] = np.where(where, fit[k], out[k])
    return tuple(out)


def fournier_forand_coefficients(backscatter, ior):
    """(n, v, c) (k,) each: Cycles' ``phase_fournier_forand_coeffs`` of the clamped backscatter
    fraction B (< 0.5) and IOR (> 1)."""
    b = np.minimum(np.abs(np.asarray(backscatter, np.float64)), 0.5 - 1e-3)
    n = np.maximum(np.asarray(ior, np.float64), 1.0 + 1e-3)
    d90 = _ff_delta(n, 0.5)
    d180 = _ff_delta(n, 1.0)
    v = -np.log(2.0 * b * (d90 - 1.0) + 1.0) / np.log(d90)
    return n, v, (d180 ** -v - 1.0) / (d180 - 1.0)


def _ff_delta(n, sin_half_sqr):
    return 4.0 * sin_half_sqr / (3.0 * (n - 1.0) ** 2)


def value(rows, cos):
    """(k,) the phase function (per steradian) of rows (k, ROW) at the cosines ``cos`` (k,) between
    the direction light travels in and the one it leaves in."""
    rows = np.asarray(rows, np.float64)
    cos = np.clip(np.asarray(cos, np.float64), -1.0, 1.0)
    out = (1.0 - rows[:, W]) * henyey_greenstein(cos, rows[:, G_HG])
    d = np.flatnonzero(rows[:, W] > 0)
    if len(d):
        out[d] += rows[d, W] * draine(cos.take(d), rows[d, G_D], rows[d, ALPHA])
    f = np.flatnonzero(rows[:, FF] > 0)
    if len(f):
        out[f] = fournier_forand(cos.take(f), rows[f, FF_N], rows[f, FF_V], rows[f, FF_C])
    return out


def henyey_greenstein(cos, g):
    """Henyey and Greenstein's phase function (:func:`~core.sampling.hg_phase`)."""
    return hg_phase(cos, g)


def rayleigh(cos):
    return (0.1875 / np.pi) * (1.0 + cos * cos)


def draine(cos, g, alpha):
    """Draine's phase function (Cycles' ``phase_draine``)."""
    g2 = g * g
    fac = 1.0 + g2 - 2.0 * g * cos
    norm = (1.0 + alpha * (1.0 + 2.0 * g2) / 3.0) * 4.0 * np.pi
    general = (1.0 - g2) * (1.0 + alpha * cos * cos) / (norm * fac * np.sqrt(np.maximum(fac, 1e-300)))
    return np.where((np.abs(g) < 1e-3) & (alpha > 0.999), rayleigh(cos),
                    np.where(np.abs(alpha) < 1e-3, henyey_greenstein(cos, g), general))


def fournier_forand(cos, n, v, c):
    """Fournier and Forand's phase function (Cycles' ``phase_fournier_forand``)."""
    s2 = 0.5 * (1.0 - cos)
    delta = _ff_delta(n, s2)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = _ff_value(cos, delta, delta ** v, v, s2, c / (16.0 * np.pi))
    return np.where(np.abs(cos) >= 1.0, 0.0, out)


def _ff_value(cos, delta, pow_dv, v, s2, pf_coeff):
    with np.errstate(divide="ignore", invalid="ignore"):
        m_delta = 1.0 - delta
        m_pow = 1.0 - pow_dv
        s2 = np.maximum(s2, 1e-300)
        taylor = (v * ((v - 1.0) - (v + 1.0) / s2) / (8.0 * np.pi)
                  + v * (v + 1.0) * m_delta * (2.0 * (v - 1.0) - (2.0 * v + 1.0) / s2) / (24.0 * np.pi))
        exact = ((v * m_delta - m_pow + (delta * m_pow - v * m_delta) / s2)
                 / (4.0 * np.pi * m_delta ** 2 * pow_dv))
    return np.where(np.abs(m_delta) < 1e-3, taylor, exact) + pf_coeff * (3.0 * cos * cos - 1.0)


def sample(rows, d, u1, u2):
    """Directions (k, 3) scattered from travel directions ``d`` (k, 3) by rows (k, ROW), from
    uniform numbers ``u1``, ``u2`` (k,): the lobe of a mixture by ``u1`` (rescaled), the cosine
    by inverting the lobe's distribution (Cycles' samplers), the azimuth by ``u2``."""
    rows = np.asarray(rows, np.float64)
    u1 = np.asarray(u1, np.float64)
    w = rows[:, W]
    on_d = u1 < w
    u = np.clip(np.where(on_d, u1 / np.where(w > 0, w, 1.0), (u1 - w) / np.where(w < 1, 1.0 - w, 1.0)),
                0.0, 1.0)
    cos = hg_cosine(rows[:, G_HG], u)
    d_rows = np.flatnonzero(on_d)
    if len(d_rows):
        cos[d_rows] = sample_draine(rows[d_rows, G_D], rows[d_rows, ALPHA], u.take(d_rows))
    f = np.flatnonzero(rows[:, FF] > 0)
    if len(f):
        cos[f] = sample_fournier_forand(rows[f, FF_N], rows[f, FF_V], rows[f, FF_C], u1.take(f))
    return direction_at(d, cos, u2)


def sample_rayleigh(u):
    a = 2.0 - 4.0 * u
    inv_u = -1.0 / np.cbrt(np.sqrt(1.0 + a * a) + a)
    return 1.0 / inv_u - inv_u


def sample_draine(g, alpha, u):
    """(k,) cosines distributed by Draine(g, alpha) (Cycles' ``phase_draine_sample``; the general
    case after Jendersie and d'Eon's closed form)."""
    g, alpha, u = (np.asarray(a, np.float64) for a in (g, alpha, u))
    out = np.empty(len(u))
    ray = (np.abs(g) < 1e-3) & (alpha > 0.999)
    hg = ~ray & (np.abs(alpha) < 1e-3)
    small = ~ray & ~hg & (np.abs(g) < 1e-2)
    general = ~(ray | hg | small)
    out[ray] = sample_rayleigh(u[ray])
    out[hg] = hg_cosine(g[hg], u[hg])
    if small.any():
        a, v = alpha[small], u[small]
        inv_a = 1.0 / a
        b_2 = (3.0 + a) * inv_a * (0.5 - v)
        inv_u = -1.0 / np.cbrt(b_2 + np.sqrt(b_2 * b_2 + inv_a ** 3))
        out[small] = 1.0 / inv_u - inv_u / a
    if general.any():
        out[general] = _draine_general(g[general], alpha[general], u[general])
    return out


def _draine_general(g, alpha, u):
    cbrt2 = 2.0 ** (1.0 / 3.0)
    g2 = g * g
    g3, g4 = g * g2, g2 * g2
    g6 = g2 * g4
    pgp1_2 = (1.0 + g2) ** 2
    t1a = alpha * (g4 - 1.0)
    t1a3 = t1a ** 3
    t2 = -1296.0 * (g2 - 1.0) * (alpha - alpha * g2) * t1a * (4.0 * g2 + alpha * pgp1_2)
    t9 = 2.0 + g2 + g3 * (1.0 + 2.0 * g2) * (2.0 * u - 1.0)
    t3 = 3.0 * g2 * (1.0 + g * (2.0 * u - 1.0)) + alpha * t9
    t4a = 432.0 * t1a3 + t2 + 432.0 * (alpha * (1.0 - g2)) * t3 * t3
    t10 = alpha * (2.0 * g4 - g2 - g6)
    t4b = 144.0 * t10
    t4 = t4a + np.sqrt(np.maximum(-4.0 * t4b ** 3 + t4a * t4a, 0.0))
    inv_t4p3 = 1.0 / np.cbrt(t4)
    t8 = 48.0 * cbrt2 * t10
    t6 = (2.0 * t1a + t8 * inv_t4p3 + 1.0 / (3.0 * cbrt2 * inv_t4p3)) / (alpha * (1.0 - g2))
    t5 = 6.0 * (1.0 + g2) + t6
    t7 = 6.0 * (1.0 + g2) - (8.0 * t3) / (alpha * (g2 - 1.0) * np.sqrt(np.maximum(t5, 0.0))) - t6
    return (1.0 + g2 - 0.25 * (np.sqrt(np.maximum(t7, 0.0)) - np.sqrt(np.maximum(t5, 0.0))) ** 2) / (2.0 * g)


def sample_fournier_forand(n, v, c, u):
    """(k,) cosines distributed by Fournier-Forand (Cycles' Newton iteration on its distribution,
    at most 20 steps, from 50 degrees)."""
    cdf_coeff, pf_coeff = c / 8.0, c / (16.0 * np.pi)
    cos = np.full(len(u), 0.64278760968)
    active = np.ones(len(u), bool)
    for _ in range(20):
        s2 = 0.5 * (1.0 - cos)
        delta = _ff_delta(n, s2)
        m_delta = 1.0 - delta
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            pow_dv = delta ** v
            cdf = np.where(np.abs(m_delta) < 1e-3, 1.0 + v * (1.0 - s2) * (1.0 - 0.5 * (v + 1.0) * m_delta),
                           (1.0 - pow_dv * delta - (1.0 - pow_dv) * s2) / (m_delta * pow_dv))
            cdf = cdf + cdf_coeff * cos * (1.0 - cos * cos)
            pf = _ff_value(cos, delta, pow_dv, v, s2, pf_coeff)
            new = cos + (cdf - u) / (2.0 * np.pi * pf)
        new = np.where(np.isfinite(new), new, cos)
        new = np.where(new >= 1.0, np.maximum(0.5 * (cos + 1.0), 0.99), new)
        done = (np.abs(cos - new) < 1e-6) | (new == 1.0)
        cos = np.where(active, new, cos)
        active &= ~done
        if not active.any():
            break
    return cos

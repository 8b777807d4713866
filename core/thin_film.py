"""Thin-film iridescence: the reflectance of a dielectric layer coated with a thin film, in RGB.

As Cycles (Blender 4.2 and later) computes it for the Principled BSDF's Thin Film, after Belcour
and Barla 2017 ("A Practical Extension to Microfacet Theory for the Modeling of Varying
Iridescence"): the Airy series of the waves reflected inside the film, for s and p polarised
light apart, each term's spectrum integrated against the colour matching functions in Fourier
space, so that a term of optical path difference OPD and phase phi costs one look-up of the
sensitivity S(OPD), the Fourier transform of the RGB colour matching functions taken over
frequency (:func:`sensitivity_table`), and the series stops after its third term as Cycles'.

The sensitivity table is rebuilt here the way Cycles' ``doc/precompute/thin_film_table.py`` builds
``table_thin_film_cmf``: the CMFs at 1022 frequencies nu from 0 to 1021 pi / 60 um^-1 (at the
wavelength 1 / nu), divided by nu^2, one real FFT of them, 512 complex values for OPDs from 0 to
60 / (2 pi) um.  Ours starts from the CIE 1931 functions at 5 nm (``procedural.CIE_XYZ``, 380 to
780 nm) through a natural cubic spline, where Cycles starts from them at 1 nm from 360 to 830 nm;
then, as Cycles' ``compute_thin_film_table``, the table is taken to linear Rec. 709 and normalised
so that each channel's term at OPD 0 is 1.  Rendered against Cycles, the film's colours agree to
four digits (``test_a_filmed_principled_glass_matches_cycles``).
"""
from __future__ import annotations

import numpy as np

from . import procedural          # (its CIE tables; procedural imports bsdf, which imports this)
from .sampling import dielectric_f0

TABLE_SIZE = 512          # Cycles' THIN_FILM_TABLE_SIZE: complex values of the sensitivity
_SAMPLES = 1022           # real samples over frequency (one real FFT of them gives TABLE_SIZE values)
_END = 60.0               # the table covers OPD from 0 to _END / (2 pi) um
THICKNESS_CUTOFF = 0.1    # Cycles' THINFILM_THICKNESS_CUTOFF (nm): no film at or below it (as float32)


def _natural_spline(x, y, at):
    """Natural cubic spline through (x, y) (x uniform, ascending) at ``at``; NaN outside [x0, xn]."""
    n = len(x)
    h = x[1] - x[0]
    a = np.zeros((n, n))
    r = np.zeros(n)
    a[0, 0] = a[-1, -1] = 1.0
    i = np.arange(1, n - 1)
    a[i, i - 1] = a[i, i + 1] = h / 6.0
    a[i, i] = 2.0 * h / 3.0
    r[i] = (y[i + 1] - 2.0 * y[i] + y[i - 1]) / h
    m = np.linalg.solve(a, r)                           # second derivatives
    k = np.clip((np.clip(at, x[0], x[-1]) - x[0]) // h, 0, n - 2).astype(np.int64)
    t1 = x[k + 1] - at
    t0 = at - x[k]
    out = (m[k] * t1 ** 3 + m[k + 1] * t0 ** 3) / (6.0 * h) \
        + (y[k] / h - m[k] * h / 6.0) * t1 + (y[k + 1] / h - m[k + 1] * h / 6.0) * t0
    return np.where((at >= x[0]) & (at <= x[-1]), out, np.nan)


def sensitivity_table():
    """(TABLE_SIZE, 3) complex: the RGB sensitivity S(OPD) at OPD = k / (TABLE_SIZE - 1) of the range,
    S = sum over frequency nu of cmf(1 / nu) / nu^2 exp(-2 pi i OPD nu) normalised to S(0) = 1
    per channel.  A few milliseconds; callers keep it (``MaterialTable``)."""
    # The CIE functions padded with a zero 5 nm beyond each end (Cycles pads its 1 nm table so).
    lam = np.arange(375.0, 790.0, 5.0)
    cmf = np.vstack([np.zeros(3), procedural.CIE_XYZ, np.zeros(3)])
    freqs = np.maximum(np.linspace(0.0, np.pi * (_SAMPLES - 1) / _END, _SAMPLES), 1e-40)
    wavelength = 1000.0 / freqs                          # nm
    samples = np.stack([np.nan_to_num(_natural_spline(lam, cmf[:, c], wavelength)) for c in range(3)], axis=1)
    samples /= (freqs * freqs)[:, None]
    spectrum = np.fft.rfft(samples, axis=0)              # (TABLE_SIZE, 3) XYZ
    rgb = spectrum @ procedural.XYZ_TO_RGB.T
    return rgb / rgb[0].real


def sensitivity(table, opd):
    """(n, 3) complex S at optical path differences ``opd`` (nm), linear in the table as Cycles'
    ``lookup_table_read`` (beyond the table's end: its last value)."""
    x = np.clip(2.0 * np.pi * np.asarray(opd, np.float64) / (_END * 1000.0), 0.0, 1.0) * (TABLE_SIZE - 1)
    i = np.minimum(x.astype(np.int64), TABLE_SIZE - 1)
    j = np.minimum(i + 1, TABLE_SIZE - 1)
    t = (x - i)[:, None]
    return (1.0 - t) * table[i] + t * table[j]


def _film_index(thickness, film_ior):
    """The film's index, blended towards 1 below 1 nm by smoothstep(thickness) (Cycles: the Airy
    series no longer applies there)."""
    t = np.clip(thickness, 0.0, 1.0)
    return np.where(thickness < 1.0, 1.0 + (film_ior - 1.0) * t * t * (3.0 - 2.0 * t), film_ior)


def _polarized(cos_i, eta):
    """Cycles' ``fresnel_dielectric_polarized``: (R_s, R_p, cos_t, phase_s, phase_p, tir) for cosines
    ``cos_i`` and relative indices ``eta`` (arrays); cos_t < 0 (relative to the normal), the phases
    +-1 (the sign of each amplitude), R = 1 and phases 1 under total internal reflection."""
    e2 = eta * eta - (1.0 - cos_i * cos_i)
    tir = e2 <= 0.0
    c = np.abs(cos_i)
    cos_t = -np.sqrt(np.maximum(e2, 0.0)) / eta
    with np.errstate(divide="ignore", invalid="ignore"):
        r_s = (c + eta * cos_t) / (c - eta * cos_t)
        r_p = (cos_t + eta * c) / (eta * c - cos_t)
    r_s = np.where(tir, 1.0, np.nan_to_num(r_s, nan=1.0))
    r_p = np.where(tir, 1.0, np.nan_to_num(r_p, nan=1.0))
    return (r_s * r_s, r_p * r_p, cos_t, np.where(r_s >= 0.0, 1.0, -1.0), np.where(r_p >= 0.0, 1.0, -1.0),
            tir)


def _airy(table, r12, r23, opd, phase):
    """(n, 3) Cycles' ``iridescence_airy_summation`` for one polarisation: reflectances ``r12`` (n,)
    and ``r23`` (n,) or (n, 3), ``opd`` (n,) nm and the reflections' joint phase ``phase`` as
    exp(i phi) ((n,) +-1 for a dielectric, (n, 3) complex for a conductor)."""
    r12 = r12[:, None]
    r23 = r23[:, None] if np.ndim(r23) == 1 else r23
    phase = phase[:, None] if np.ndim(phase) == 1 else phase
    t121 = 1.0 - r12
    r123 = r12 * r23
    root = np.sqrt(r123)
    rs = t121 * t121 * r23 / np.maximum(1.0 - r123, 1e-30)
    out = np.broadcast_to(rs + r12, (len(opd), 3)).copy()
    cm = rs - t121
    acc = phase
    for m in range(1, 4):
        cm = cm * root
        s = sensitivity(table, m * opd)
        out += 2.0 * cm * (acc.real * s.real + acc.imag * s.imag)
        acc = acc * phase
    return out


def reflectance(table, cos_i, thickness, film_ior, eta):
    """(n, 3) reflectance of a dielectric of relative index ``eta`` coated by a film ``thickness``
    nm thick of index ``film_ior``, seen from outside (index 1) at cosines ``cos_i``: Cycles'
    ``fresnel_iridescence`` for a dielectric substrate (all arguments broadcast to (n,)).  Films
    below 1 nm blend their index towards 1 (Cycles: the Airy series no longer applies); total
    internal reflection at either interface reflects everything."""
    cos_i, thickness, film_ior, eta = np.broadcast_arrays(
        np.asarray(cos_i, np.float64), np.asarray(thickness, np.float64),
        np.asarray(film_ior, np.float64), np.asarray(eta, np.float64))
    n_film = _film_index(thickness, film_ior)
    r12_s, r12_p, cos_2, ph12_s, ph12_p, tir12 = _polarized(cos_i, n_film)
    r23_s, r23_p, _, ph23_s, ph23_p, tir23 = _polarized(-cos_2, eta / n_film)
    opd = -2.0 * n_film * thickness * cos_2
    out = 0.5 * (_airy(table, r12_s, r23_s, opd, -ph12_s * ph23_s)
                 + _airy(table, r12_p, r23_p, opd, -ph12_p * ph23_p))
    return np.where((tir12 | tir23)[:, None], 1.0, np.clip(out, 0.0, 1.0))


def f82(cos_i, f0, b):
    """Cycles' F82-tint curve ``fresnel_f82``: saturate(F0 + (1 - F0) s^5 - b cos s^6), s = 1 - cos."""
    s = np.clip(1.0 - cos_i, 0.0, 1.0)
    s5 = s ** 5
    return np.clip(f0 + (1.0 - f0) * s5 - b * cos_i * s5 * s, 0.0, 1.0)


def f82_b(f0, f82_value):
    """Cycles' ``fresnel_f82_B``: the b that puts the curve of ``f0`` at ``f82_value`` at cos = 1/7."""
    f = 6.0 / 7.0
    f5 = f ** 5
    return (7.0 / (f5 * f)) * (f0 + (1.0 - f0) * f5 - f82_value)


def conductor_reflectance(table, cos_i, thickness, film_ior, f0, b):
    """(n, 3) reflectance of an F82-tint metal (normal-incidence colour ``f0``, tint term ``b``,
    each (n, 3)) coated by a film ``thickness`` nm thick of index ``film_ior``, at cosines
    ``cos_i``: Cycles' ``microfacet_fresnel`` for an F82 tint with a film, which reads the metal as
    the complex index n + ik of Gulbrandsen's artist-friendly mapping of F0 and the curve's value
    at cos = 1/7, and ``fresnel_iridescence`` for a conductor: the film-to-metal reflectance by the
    F82 curve of the metal's F0 relative to the film, the phases of the complex index."""
    n_rows = len(np.asarray(cos_i))
    f0 = np.broadcast_to(np.asarray(f0, np.float64), (n_rows, 3))
    b = np.broadcast_to(np.asarray(b, np.float64), (n_rows, 3))
    g = f82(1.0 / 7.0, f0, b)
    r = np.minimum(f0, 0.999)
    root = np.sqrt(r)
    n = (1.0 - g) * (1.0 + root) / (1.0 - root) + g * (1.0 - r) / (1.0 + r)
    k = np.sqrt(np.maximum((r * (n + 1.0) ** 2 - (n - 1.0) ** 2) / (1.0 - r), 0.0))
    return _filmed_conductor(table, cos_i, thickness, film_ior, n, k, g)


def physical_conductor_reflectance(table, cos_i, thickness, film_ior, n, k):
    """(n, 3) reflectance of a metal of complex index ``n`` + i ``k`` (each (n, 3)) coated by a
    film ``thickness`` nm thick of index ``film_ior``, at cosines ``cos_i``: Cycles'
    ``fresnel_iridescence`` for a physical conductor (the Metallic BSDF's), whose film-to-metal
    reflectance is the conductor's own Fresnel for each polarisation."""
    n_rows = len(np.asarray(cos_i))
    n, k = (np.broadcast_to(np.asarray(x, np.float64), (n_rows, 3)) for x in (n, k))
    return _filmed_conductor(table, cos_i, thickness, film_ior, n, k, None)


def _filmed_conductor(table, cos_i, thickness, film_ior, n, k, g):
    """Cycles' ``fresnel_iridescence`` over a conductor of index ``n`` + i ``k`` (n, 3): the
    film-to-metal reflectance by the F82 curve of the metal's F0 relative to the film through
    ``g`` (its value at cos = 1/7) or, ``g`` None, by the conductor's polarised Fresnel
    (``fresnel_conductor_polarized``); the phases those of the complex index."""
    cos_i, thickness, film_ior = (np.asarray(x, np.float64) for x in (cos_i, thickness, film_ior))
    n_rows = len(cos_i)
    thickness = np.broadcast_to(thickness, (n_rows,))
    n_film = _film_index(thickness, np.broadcast_to(film_ior, (n_rows,)))
    r12_s, r12_p, cos_2, ph12_s, ph12_p, tir12 = _polarized(cos_i, n_film)
    c = (-cos_2)[:, None]                                   # the film-to-metal cosine
    e1 = n_film[:, None]
    t1 = n * n - k * k - e1 * e1 * (1.0 - c * c)
    t2 = np.sqrt(t1 * t1 + (2.0 * n * k) ** 2)
    u2, v2 = np.maximum(0.5 * (t2 + t1), 0.0), np.maximum(0.5 * (t2 - t1), 0.0)
    u, v = np.sqrt(u2), np.sqrt(v2)
    if g is not None:
        rel_f0 = ((n / e1 - 1.0) ** 2 + (k / e1) ** 2) / ((n / e1 + 1.0) ** 2 + (k / e1) ** 2)
        r23_s = r23_p = f82(c, rel_f0, f82_b(rel_f0, g))     # (both polarisations: Cycles' F82 model)
    else:
        r23_s = _safe_ratio((e1 * c - u) ** 2 + v2, (e1 * c + u) ** 2 + v2)
        t3, t4 = (n * n - k * k) * c, 2.0 * n * k * c
        r23_p = _safe_ratio((t3 - e1 * u) ** 2 + (t4 - e1 * v) ** 2, (t3 + e1 * u) ** 2 + (t4 + e1 * v) ** 2)

    def phasor(re, im):
        mag = np.sqrt(re * re + im * im)
        safe = np.where(mag == 0.0, 1.0, mag)
        return np.where(mag == 0.0, 1.0 + 0j, (re + 1j * im) / safe)

    phase_s = phasor(-u2 - v2 + (e1 * c) ** 2, -2.0 * e1 * c * v)
    phase_p = phasor(((n * n + k * k) * c) ** 2 - e1 * e1 * (u2 + v2),
                     2.0 * e1 * c * (2.0 * n * k * u - (n * n - k * k) * v))
    opd = -2.0 * n_film * thickness * cos_2
    out = 0.5 * (_airy(table, r12_s, r23_s, opd, phase_s * -ph12_s[:, None])
                 + _airy(table, r12_p, r23_p, opd, phase_p * -ph12_p[:, None]))
    return np.where(tir12[:, None], 1.0, np.clip(out, 0.0, 1.0))


def _safe_ratio(a, b):
    """a / b, 0 where b is 0 (Cycles' ``safe_divide``)."""
    return np.divide(a, b, out=np.zeros(np.broadcast(a, b).shape), where=b != 0)


def principled_reflectance(table, cos_i, thickness, film_ior, eta, f0_tint):
    """(n, 3) the Principled BSDF's specular layer with a film: :func:`reflectance` scaled per channel
    towards ``f0_tint`` / F0 (Cycles' ``microfacet_fresnel`` for a generalized Schlick Fresnel with a
    film: F times mix(1, f0 / F0, saturate((F - 1) / (F0 - 1))), F0 the layer's own reflectance
    face on); ``f0_tint`` (n, 3) or (3,) its tinted normal-incidence colour."""
    f = reflectance(table, cos_i, thickness, film_ior, eta)
    f0_real = np.broadcast_to(dielectric_f0(np.asarray(eta, np.float64)), f.shape[:1])[:, None]
    scale = f0_real > 1e-5
    safe = np.where(scale, f0_real, 0.5)
    s = np.clip((f - 1.0) / (safe - 1.0), 0.0, 1.0)
    factor = np.clip(np.asarray(f0_tint, np.float64), 0.0, 1.0) / safe
    scaled = f * (1.0 + (factor - 1.0) * s)
    return np.where(scale & (f < 1.0), scaled, f)

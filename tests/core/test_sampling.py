"""Statistical tests of the sampling routines (``shared/docs/testing.md`` sections 1 and 2b).

Covers the warps of ``core.sampling``, GGX visible-normal sampling, the four lobes of
``core.bsdf.scatter``, ``choose_lobe``, photon emission in ``core.lights.LightSampler`` and the MCMC
mutation kernel of ``core.mcmc``.  Distributions are checked by a Mitsuba-style chi-square test
(``chi2.py``) with 10^6 samples, frequencies by binomial z-tests, means by z-tests or the fixed
tolerances the brief gives.  Every statistical test runs at the family-wise level ALPHA = 0.01
with a Sidak correction over the STAT_TESTS hypothesis tests of this file; all seeds are fixed.

Reference formulas (GGX, Fresnel, spot mask, light powers) are written out here from the papers,
independently of ``core``, so that a test compares the code with the mathematics, not with itself.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from chi2 import ChiSquareTest, integrate_bins
from core import bsdf
from core import mcmc
from core import sampling as smp
from core.context import RenderContext
from core.lights import Focus
from core.scene import Lights, Materials, World
from core.testing.scenes import MeshBuilder
from stats_utils import chi2_sf, gammaincc, normal_isf, sidak

N = 1_000_000                     # samples per chi-square test
TWO_PI = 2.0 * math.pi

# ---------------------------------------------------------------- test parameters
CONE_COS_MAX = (-0.6, 0.0, 0.5, 0.95, 0.9999)
GGX_ALPHAS = (0.05, 0.3, 0.8)
GGX_THETAS_DEG = (0.0, 45.0, 80.0, 89.0)
DIELECTRIC_CASES = (          # (angle of wo to the normal in degrees, wo outside the glass)
    (0.0, True), (45.0, True), (80.0, True), (20.0, False), (40.0, False))
CHOOSE_LOBE_SCORES = (
    (0.1, 0.2, 0.3, 0.4), (0.0, 1.0, 0.0, 3.0), (2.5, 0.0, 0.0, 0.0), (0.0, 0.0, 1e-3, 1.0),
    (0.7, 0.0, 0.2, 0.0))
SPOT_BLENDS = (0.0, 0.3, 1.0)
ROUGH_DIELECTRIC_CASES = (     # (Blender roughness, angle of wo in degrees, wo outside the glass)
    (0.3, 30.0, True), (0.6, 70.0, True), (0.3, 35.0, False))
MUTATION_THETAS = (0.05, 1.0, 20.0)

# Every hypothesis test of this file (chi-square tests and z-tests), for the Sidak correction.
STAT_TESTS = (
    3                                       # cosine hemisphere, uniform sphere, concentric disk
    + len(CONE_COS_MAX) + 1                 # uniform cone per cos_max, and per-sample cos_max
    + 1                                     # uniform triangle
    + len(GGX_ALPHAS) * len(GGX_THETAS_DEG)  # GGX reflection chi-square
    + 2                                     # diffuse lobe: chi-square, front and back side
    + 2                                     # glossy lobe: chi-square and E[weight] z-test
    + 3                                     # mixed material: E[weight] z-test per channel
    + 2 * 3 * 3                             # multiscatter glossy: E[weight] per colour, angle, channel
    + len(ROUGH_DIELECTRIC_CASES)           # rough dielectric chi-square
    + 3                                     # environment image: E[L / pdf] per channel
    + 3 * 20                                # area light spread: flux-weighted angle, per bin
    + len(DIELECTRIC_CASES)                 # dielectric reflection frequency
    + sum(sum(v > 0 for v in s) > 1 for s in CHOOSE_LOBE_SCORES)   # choose_lobe frequencies
    + 2                                     # point light: directions, positions on its sphere
    + 1                                     # spot light directions
    + 4                                     # rectangle and disk lights: directions and positions
    + 2                                     # sun: directions and disk origins
    + 2                                     # world: directions and disk origins
    + 4                                     # emissive triangles: choice, side, directions, positions
    + 1                                     # mixed lights: photon share per light (one chi-square)
    + 2                                     # MCMC chain stays uniform: small and mixed sizes
    + 2 * len(MUTATION_THETAS)              # mutation step density and E|step|
    + 1                                     # wrapped mutation step
)
ALPHA = 0.01
ALPHA_EACH = sidak(ALPHA, STAT_TESTS)
Z_CRIT = normal_isf(0.5 * ALPHA_EACH)      # two-sided z threshold


def check_chi2(sample_func, pdf_func, domain, **kwargs):
    test = ChiSquareTest(sample_func, pdf_func, domain, sample_count=kwargs.pop("sample_count", N), **kwargs)
    assert test.run(ALPHA_EACH), test.message
    return test


def assert_binomial(successes, trials, p, what):
    """Two-sided z-test of a frequency against probability ``p``."""
    sd = math.sqrt(max(p * (1.0 - p), 1e-300) / trials)
    z = (successes / trials - p) / sd
    assert abs(z) < Z_CRIT, f"{what}: frequency {successes / trials:.6f}, expected {p:.6f} (z = {z:.2f})"


def assert_mean(values, expected, what, extra_tolerance=0.0):
    """Two-sided z-test of a sample mean (sd estimated from the sample)."""
    values = np.asarray(values, np.float64)
    mean = values.mean()
    se = values.std() / math.sqrt(len(values))
    assert abs(mean - expected) <= Z_CRIT * se + extra_tolerance, \
        f"{what}: mean {mean:.6g}, expected {expected:.6g} (z = {(mean - expected) / max(se, 1e-300):.2f})"


# ---------------------------------------------------------------- frames and parametrisations
def frames_for(axes):
    """(n, 3, 3) rotations whose rows are (t, b, axis) for unit ``axes`` (n, 3); Gram-Schmidt."""
    axes = np.atleast_2d(np.asarray(axes, np.float64))
    axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    helper = np.where((np.abs(axes[:, 0]) < 0.6)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t = np.cross(helper, axes)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(axes, t)
    return np.stack([t, b, axes], axis=1)


def polar_angle(x, y):
    """Angle of (x, y) in [0, 2 pi]."""
    return np.mod(np.arctan2(y, x), TWO_PI)


def dir_to_cos_phi(d, axis):
    """(cos theta, phi) of directions ``d`` (n, 3) about ``axis`` (3,)."""
    f = frames_for(axis)[0]
    loc = d @ f.T
    return np.stack([loc[:, 2], polar_angle(loc[:, 0], loc[:, 1])], axis=1)


def cos_phi_to_dir(xy, axis):
    f = frames_for(axis)[0]
    c = xy[:, 0]
    s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
    loc = np.stack([s * np.cos(xy[:, 1]), s * np.sin(xy[:, 1]), c], axis=1)
    return loc @ f


def dir_to_warped(d, axis, p):
    """(t, phi) about ``axis`` with sin^2(theta/2) = t^p, i.e. 1 - cos theta = 2 t^p.

    p > 1 spreads a lobe peaked around ``axis`` over many bins; the Jacobian is in :func:`warped_to_dir`.
    """
    f = frames_for(axis)[0]
    loc = d @ f.T
    s2 = 0.25 * np.sum((loc - [0.0, 0.0, 1.0]) ** 2, axis=1)      # sin^2(theta / 2), accurate near 0
    return np.stack([np.clip(s2, 0.0, 1.0) ** (1.0 / p), polar_angle(loc[:, 0], loc[:, 1])], axis=1)


def warped_to_dir(xy, axis, p):
    """Directions and the Jacobian |d omega / d(t, phi)| = 2 p t^(p - 1) of :func:`dir_to_warped`."""
    f = frames_for(axis)[0]
    t = xy[:, 0]
    s2 = t ** p
    c = 1.0 - 2.0 * s2
    s = 2.0 * np.sqrt(np.maximum(0.0, s2 * (1.0 - s2)))
    loc = np.stack([s * np.cos(xy[:, 1]), s * np.sin(xy[:, 1]), c], axis=1)
    return loc @ f, 2.0 * p * t ** (p - 1.0)


def dir_to_horizon(d, phi_m, q=2.0, r=2.0):
    """(v, w) in [0, 1] x [-1, 1] with cos theta = v^q about +Z and phi = phi_m + pi sgn(w) |w|^r.

    The horizon cos theta = 0 is a bin edge and bins crowd near the horizon and the azimuth phi_m:
    for lobes reflected at grazing angles.  Jacobian in :func:`horizon_to_dir`.
    """
    v = np.clip(d[:, 2], 0.0, 1.0) ** (1.0 / q)
    dphi = np.mod(np.arctan2(d[:, 1], d[:, 0]) - phi_m + np.pi, TWO_PI) - np.pi
    return np.stack([v, np.sign(dphi) * (np.abs(dphi) / np.pi) ** (1.0 / r)], axis=1)


def horizon_to_dir(xy, phi_m, q=2.0, r=2.0):
    """Directions and |d omega / d(v, w)| = q v^(q - 1) pi r |w|^(r - 1) of :func:`dir_to_horizon`."""
    v, w = xy[:, 0], xy[:, 1]
    c = v ** q
    s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
    phi = phi_m + np.pi * np.sign(w) * np.abs(w) ** r
    d = np.stack([s * np.cos(phi), s * np.sin(phi), c], axis=1)
    return d, q * v ** (q - 1.0) * np.pi * r * np.abs(w) ** (r - 1.0)


def disk_polar(x, y):
    """(r^2, phi) of points (x, y): uniform points on the unit disk are uniform on [0, 1] x [0, 2 pi)."""
    return np.stack([x * x + y * y, polar_angle(x, y)], axis=1)


def cone_param(d, axis, cos_max):
    """(s, phi) with s = (1 - cos theta) / (1 - cos_max): uniform in the cone <=> uniform in s, phi."""
    f = frames_for(axis)[0]
    loc = d @ f.T
    one_minus_cos = 0.5 * np.sum((loc - [0.0, 0.0, 1.0]) ** 2, axis=1)
    return np.stack([one_minus_cos / (1.0 - cos_max), polar_angle(loc[:, 0], loc[:, 1])], axis=1)


HEMISPHERE = ((0.0, 1.0), (0.0, TWO_PI))
SPHERE = ((-1.0, 1.0), (0.0, TWO_PI))
UNIT_SQUARE = ((0.0, 1.0), (0.0, 1.0))
DISK_POLAR = ((0.0, 1.0), (0.0, TWO_PI))
WARPED = ((0.0, 1.0), (0.0, TWO_PI))       # (t, phi) of dir_to_warped


def uniform_polar_pdf(xy):
    return np.full(len(xy), 1.0 / TWO_PI)


def f32(v):
    """Values as the scene stores them (float32), in float64."""
    return np.asarray(v, np.float32).astype(np.float64)


def unit_vector(*v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


# ---------------------------------------------------------------- reference GGX (Walter 2007, Heitz 2018)
def ref_ggx_d(cos_m, alpha):
    """D(m) = 1 / (pi alpha^2 cos^4 (1 + tan^2 / alpha^2)^2) for cos_m > 0."""
    c = np.clip(cos_m, 1e-30, 1.0)
    tan2 = (1.0 - c * c) / (c * c)
    d = 1.0 / (np.pi * alpha ** 2 * c ** 4 * (1.0 + tan2 / alpha ** 2) ** 2)
    return np.where(cos_m > 0, d, 0.0)


def ref_ggx_lambda(cos_v, alpha):
    c = np.clip(np.abs(cos_v), 1e-30, 1.0)
    tan2 = (1.0 - c * c) / (c * c)
    return 0.5 * (np.sqrt(1.0 + alpha ** 2 * tan2) - 1.0)


def ref_ggx_f_and_pdf(wo, wi, alpha):
    """Reflection f(wo, wi) = D G2 / (4 cos_o cos_i) and the visible-normal reflection pdf
    G1(wo) max(0, wo.m) D(m) / cos_o / (4 wo.m), for local directions (n, 3); 0 below the surface."""
    h = wo + wi
    m = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
    cos_o, cos_i = wo[:, 2], wi[:, 2]
    om = np.sum(wo * m, axis=1)
    lo, li = ref_ggx_lambda(cos_o, alpha), ref_ggx_lambda(cos_i, alpha)
    d = ref_ggx_d(m[:, 2], alpha)
    valid = (cos_o > 0) & (cos_i > 0) & (om > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = d / (1.0 + lo + li) / (4.0 * cos_o * cos_i)
        pdf = d / (1.0 + lo) / (4.0 * cos_o)         # G1 (wo.m) D / cos_o / (4 wo.m)
    return np.where(valid, f, 0.0), np.where(valid, pdf, 0.0)


def ggx_warp_power(alpha):
    """Radial warp for chi-square histograms of GGX lobes (about 20+ bins across the lobe)."""
    return 4.0 if alpha < 0.1 else (2.0 if alpha < 0.5 else 1.0)


def local_direction(theta_deg, phi=0.7):
    th = math.radians(theta_deg)
    return np.array([math.sin(th) * math.cos(phi), math.sin(th) * math.sin(phi), math.cos(th)])


# ---------------------------------------------------------------- reference Fresnel
def ref_fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance (Born & Wolf) and cos_t; eta = n_t / n_i; 1 under TIR."""
    cos_i = np.asarray(cos_i, np.float64)
    sin2_t = (1.0 - cos_i ** 2) / eta ** 2
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.clip(1.0 - sin2_t, 0.0, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp)), np.where(tir, 0.0, cos_t)


# ================================================================ statistics helpers themselves
def test_chi2_pvalue_matches_known_chi2_quantiles_and_closed_forms():
    # Tabulated upper quantiles of the chi-square distribution.
    known = [(3.841458820694124, 1, 0.05), (6.634896601021214, 1, 0.01), (23.209251158954356, 10, 0.01),
             (135.80672317102676, 100, 0.01), (124.34211340400407, 100, 0.05)]
    for x, k, p in known:
        assert chi2_sf(x, k) == pytest.approx(p, rel=1e-9), (x, k)
    # Closed forms: odd k = 1, 3 via erfc; even k via the Poisson sum, up to 10^4 dof.
    for x in (0.01, 0.5, 1.0, 3.0, 10.0, 40.0):
        assert chi2_sf(x, 1) == pytest.approx(math.erfc(math.sqrt(x / 2)), rel=1e-12, abs=1e-300)
        assert chi2_sf(x, 3) == pytest.approx(
            math.erfc(math.sqrt(x / 2)) + math.sqrt(2 * x / math.pi) * math.exp(-x / 2), rel=1e-11)
        assert chi2_sf(x, 2) == pytest.approx(math.exp(-x / 2), rel=1e-12)
    for k in (10, 200, 2000, 10_000):
        for x in (0.8 * k, k - 1.0, k + 3.0 * math.sqrt(2 * k), 1.3 * k):
            m, h = k // 2, x / 2
            log_terms = [j * math.log(h) - math.lgamma(j + 1) for j in range(m)]
            top = max(log_terms)
            expected = math.exp(-h + top + math.log(sum(math.exp(t - top) for t in log_terms)))
            assert chi2_sf(x, k) == pytest.approx(expected, rel=1e-9), (x, k)
    assert gammaincc(0.5, 0.0) == 1.0
    assert 0.0 < ALPHA_EACH < ALPHA / STAT_TESTS * 1.01


def test_chi2_helper_rejects_a_wrong_density_and_reports_hard_failures():
    n = 100_000
    rng = np.random.default_rng(99)
    uniform = rng.random((n, 2))

    def run(xy, pdf, weight=None, domain=UNIT_SQUARE):
        test = ChiSquareTest(lambda m: (xy, weight), pdf, domain, sample_count=n)
        return test.run(ALPHA_EACH), test.message

    ok, msg = run(uniform, lambda xy: np.ones(len(xy)))
    assert ok, msg
    ok, msg = run(uniform, lambda xy: 2.0 * xy[:, 0])                      # wrong density
    assert not ok and "rejects" in msg
    ok, msg = run(uniform * 1.01, lambda xy: np.ones(len(xy)))              # outside the domain
    assert not ok and "outside" in msg
    weight = np.ones(n)
    weight[7] = np.nan
    assert "NaN" in run(uniform, lambda xy: np.ones(len(xy)), weight)[1]
    weight[7] = -1.0
    assert "negative weight" in run(uniform, lambda xy: np.ones(len(xy)), weight)[1]
    ok, msg = run(uniform, lambda xy: 2.0 * (xy[:, 0] < 0.5))               # mass where the pdf is 0
    assert not ok and "zero density" in msg
    ok, msg = run(uniform, lambda xy: np.full(len(xy), 1.2))                 # pdf integrates to 1.2
    assert not ok and "integrates" in msg
    weight = (uniform[:, 0] < 0.5).astype(np.float64)                       # half the samples fail
    # Failed samples (weight 0) count in N: a pdf that loses the same mass in the same place passes,
    # one that loses it elsewhere does not.
    ok, msg = run(uniform, lambda xy: 1.0 * (xy[:, 0] < 0.5), weight)
    assert ok, msg
    ok, msg = run(uniform, lambda xy: 1.0 * (xy[:, 1] < 0.5), weight)
    assert not ok


# ================================================================ 1. warps
def test_cosine_hemisphere_has_density_cos_over_pi():
    rng = np.random.default_rng(101)

    def sample(n):
        d = smp.cosine_hemisphere(rng.random(n), rng.random(n))
        assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        return np.stack([d[:, 2], polar_angle(d[:, 0], d[:, 1])], axis=1), None

    check_chi2(sample, lambda xy: xy[:, 0] / np.pi, HEMISPHERE)
    c = np.linspace(-1, 1, 11)
    assert np.allclose(smp.cosine_hemisphere_pdf(c), np.maximum(c, 0) / np.pi)


@pytest.mark.parametrize("g", [0.0, 0.45, -0.8])
def test_henyey_greenstein_sampling_has_the_phase_function_as_density(g):
    """Volumes scatter photons by the Henyey-Greenstein phase function: the sampled directions
    about a travel direction have density ``hg_phase`` exactly (chi-square, the travel direction
    off every axis), and the mean cosine is g."""
    rng = np.random.default_rng(140 + int(10 * g))
    axis = unit_vector(0.3, -0.5, 0.8)

    def sample(n):
        d = smp.sample_hg(np.tile(axis, (n, 1)), np.full(n, g), rng.random(n), rng.random(n))
        assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        return dir_to_cos_phi(d, axis), None

    check_chi2(sample, lambda xy: smp.hg_phase(xy[:, 0], g), SPHERE)
    n = 200_000
    d = smp.sample_hg(np.tile(axis, (n, 1)), np.full(n, g), rng.random(n), rng.random(n))
    assert_mean(d @ axis, g, "mean cosine")


def test_free_flight_weights_keep_the_transmitted_and_scattered_light():
    """Over a segment of length L in a medium of coloured extinction, the distances sampled by
    ``free_flight`` with weights give E[weight; reaches L] = exp(-sigma_t L) per channel and
    E[weight sigma_s f(t); stops] = int_0^L sigma_s exp(-sigma_t t) f(t) dt (here f = 1 and f = t),
    whatever the throughput that picks the channel; the weights stay bounded."""
    rng = np.random.default_rng(150)
    n = 400_000
    sigma_s = np.array([0.2, 1.0, 2.5])
    sigma_t = sigma_s + np.array([0.3, 0.0, 0.5])
    length = 1.3
    for throughput in (None, np.array([1.0, 0.2, 0.05])):
        thr = None if throughput is None else np.tile(throughput, (n, 1))
        t, stops, w = smp.free_flight(np.tile(sigma_t, (n, 1)), np.tile(sigma_s, (n, 1)), rng.random(n),
                                      np.full(n, length), thr)
        assert np.isfinite(w).all() and (w >= 0).all()
        assert (t[stops] < length).all() and (t[~stops] >= length).all()
        for c in range(3):
            passed = np.where(stops, 0.0, w[:, c])
            assert_mean(passed, np.exp(-sigma_t[c] * length), f"transmittance {c}")
            scattered = np.where(stops, w[:, c] * sigma_s[c], 0.0)
            a = sigma_t[c]
            assert_mean(scattered, sigma_s[c] / a * (1 - np.exp(-a * length)), f"scattered {c}")
            first_moment = sigma_s[c] * (1 - np.exp(-a * length) * (1 + a * length)) / a ** 2
            assert_mean(np.where(stops, w[:, c] * sigma_s[c] * t, 0.0), first_moment, f"int t {c}")


def test_uniform_sphere_has_density_one_over_four_pi():
    rng = np.random.default_rng(102)

    def sample(n):
        d = smp.uniform_sphere(rng.random(n), rng.random(n))
        assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        return dir_to_cos_phi(d, [0.0, 0.0, 1.0]), None

    check_chi2(sample, lambda xy: np.full(len(xy), 1.0 / (4 * np.pi)), SPHERE)


@pytest.mark.parametrize("cos_max", CONE_COS_MAX)
def test_uniform_cone_is_uniform_within_cos_max(cos_max):
    rng = np.random.default_rng(110 + CONE_COS_MAX.index(cos_max))

    def sample(n):
        d = smp.uniform_cone(rng.random(n), rng.random(n), cos_max)
        assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        assert (d[:, 2] >= cos_max - 1e-12).all()
        return cone_param(d, [0.0, 0.0, 1.0], cos_max), None

    # Uniform in the cone <=> uniform in (s, phi): density 1 / (2 pi (1 - cos_max)) per solid angle.
    check_chi2(sample, uniform_polar_pdf, DISK_POLAR)


def test_uniform_cone_accepts_per_sample_cos_max():
    rng = np.random.default_rng(104)
    choices = np.array([-0.5, 0.3, 0.9])

    def sample(n):
        cos_max = choices[rng.integers(0, 3, n)]
        d = smp.uniform_cone(rng.random(n), rng.random(n), cos_max)
        assert (d[:, 2] >= cos_max - 1e-12).all()
        f = frames_for([0.0, 0.0, 1.0])[0]
        loc = d @ f.T
        s = 0.5 * np.sum((loc - [0.0, 0.0, 1.0]) ** 2, axis=1) / (1.0 - cos_max)
        return np.stack([s, polar_angle(loc[:, 0], loc[:, 1])], axis=1), None

    check_chi2(sample, uniform_polar_pdf, DISK_POLAR)


def test_concentric_disk_is_uniform_on_the_unit_disk():
    rng = np.random.default_rng(105)

    def sample(n):
        x, y = smp.concentric_disk(rng.random(n), rng.random(n))
        assert (x * x + y * y <= 1.0 + 1e-12).all()
        return disk_polar(x, y), None

    check_chi2(sample, uniform_polar_pdf, DISK_POLAR)
    # The corners and centre of the square map to the boundary and the centre.
    x, y = smp.concentric_disk(np.array([0.5, 0.0, 1.0, 0.5]), np.array([0.5, 0.0, 0.5, 1.0]))
    assert np.allclose(np.hypot(x, y), [0.0, 1.0, 1.0, 1.0])


def test_uniform_triangle_barycentrics_are_uniform_over_the_triangle():
    rng = np.random.default_rng(106)

    def sample(n):
        b1, b2 = smp.uniform_triangle(rng.random(n), rng.random(n))
        assert ((b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1.0 + 1e-12)).all()
        # (b1, v = b2 / (1 - b1)) maps the triangle onto the unit square; density 2 (1 - b1) there.
        return np.stack([b1, b2 / (1.0 - b1)], axis=1), None

    check_chi2(sample, lambda xy: 2.0 * (1.0 - xy[:, 0]), UNIT_SQUARE)


def test_orthonormal_frames_to_world_and_to_local_are_rotations():
    rng = np.random.default_rng(107)
    n = smp.uniform_sphere(rng.random(10000), rng.random(10000))
    special = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 0], [0, 0, 1.0]], np.float64)
    near_minus_z = unit_vector(1e-9, -2e-9, -1.0)
    n = np.concatenate([n, special, near_minus_z[None], unit_vector(1, 1, -1e-12)[None]])
    t, b = smp.orthonormal_frames(n)
    for u, v in ((t, t), (b, b), (n, n)):
        assert np.allclose(np.sum(u * v, axis=1), 1.0, atol=1e-12)
    for u, v in ((t, b), (t, n), (b, n)):
        assert np.allclose(np.sum(u * v, axis=1), 0.0, atol=1e-12)
    assert np.allclose(np.cross(t, b), n, atol=1e-12)             # right-handed (Duff et al. 2017)
    v = rng.normal(size=(len(n), 3))
    assert np.allclose(smp.to_world(smp.to_local(v, n), n), v, atol=1e-12)
    assert np.allclose(smp.to_local(v, n)[:, 2], np.sum(v * n, axis=1), atol=1e-12)
    e_z = np.tile([0.0, 0.0, 1.0], (len(n), 1))
    assert np.allclose(smp.to_world(e_z, n), n, atol=1e-12)


def test_reflect_and_refract_obey_mirror_law_and_snell():
    rng = np.random.default_rng(108)
    n = smp.uniform_sphere(rng.random(1000), rng.random(1000))
    wo = smp.to_world(smp.cosine_hemisphere(rng.random(1000), rng.random(1000)), n)
    r = smp.reflect(wo, n)
    assert np.allclose(r + wo, 2 * np.sum(wo * n, axis=1)[:, None] * n, atol=1e-12)
    assert np.allclose(np.linalg.norm(r, axis=1), 1.0, atol=1e-12)
    for eta_value in (1.5, 1.0 / 1.5, 1.33):
        eta = np.full(1000, eta_value)
        cos_i = np.sum(wo * n, axis=1)
        f, cos_t = smp.fresnel_dielectric(cos_i, eta)
        ok = f < 1.0
        t = smp.refract(wo[ok], n[ok], eta[ok], cos_t[ok])
        assert np.allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-9)
        assert np.allclose(-np.sum(t * n[ok], axis=1), cos_t[ok], atol=1e-9)
        sin_i = np.linalg.norm(np.cross(wo[ok], n[ok]), axis=1)
        sin_t = np.linalg.norm(np.cross(t, n[ok]), axis=1)
        assert np.allclose(sin_i, eta_value * sin_t, atol=1e-9)            # Snell
        # Coplanar with wo and n, on the far side of the tangent plane.
        assert np.allclose(np.sum(np.cross(wo[ok], n[ok]) * t, axis=1), 0.0, atol=1e-9)


# ================================================================ 2. GGX
# (sampler, density of the reflected direction, first seed) of each microfacet distribution
VISIBLE_NORMALS = {"ggx": (smp.ggx_sample_visible_normal, smp.ggx_reflection_pdf, 1000),
                   "beckmann": (smp.beckmann_sample_visible_normal, smp.beckmann_reflection_pdf, 3000)}


@pytest.mark.parametrize("theta_deg", GGX_THETAS_DEG)
@pytest.mark.parametrize("alpha", GGX_ALPHAS)
@pytest.mark.parametrize("distribution", VISIBLE_NORMALS)
def test_visible_normal_reflection_matches_its_pdf(distribution, alpha, theta_deg):
    """Visible normals of GGX (Heitz 2018) and Beckmann (Heitz and d'Eon 2014; the exact Smith G1
    in its density), reflected: chi-square against the density of the reflected direction."""
    sampler, density, seed = VISIBLE_NORMALS[distribution]
    phi_o = 0.7
    wo = local_direction(theta_deg, phi_o)
    mirror = np.array([-wo[0], -wo[1], wo[2]])
    p = ggx_warp_power(alpha)
    # Bins crowd around the mirror direction, or along the horizon for grazing incidence (where the
    # horizon cuts the lobe and must be a bin edge).
    grazing = theta_deg >= 60.0
    rng = np.random.default_rng(seed + 10 * GGX_ALPHAS.index(alpha) + GGX_THETAS_DEG.index(theta_deg))

    def sample(n):
        wo_n = np.tile(wo, (n, 1))
        m = sampler(wo_n, np.full(n, alpha), rng.random(n), rng.random(n))
        assert np.allclose(np.linalg.norm(m, axis=1), 1.0, atol=1e-9)
        assert (m[:, 2] > 0).all() and (np.sum(m * wo_n, axis=1) >= -1e-9).all()
        wi = smp.reflect(wo_n, m)
        xy = dir_to_horizon(wi, phi_o + np.pi) if grazing else dir_to_warped(wi, mirror, p)
        return xy, (wi[:, 2] > 0).astype(np.float64)

    def pdf(xy):
        d, jac = horizon_to_dir(xy, phi_o + np.pi) if grazing else warped_to_dir(xy, mirror, p)
        return density(np.tile(wo, (len(d), 1)), d, alpha) * jac

    test = check_chi2(sample, pdf, ((0.0, 1.0), (-1.0, 1.0)) if grazing else WARPED, ires=8)
    assert test.integral.sum() <= 1.0 + 1e-3


def test_ggx_reflection_pdf_and_f_equal_the_reference_formulas():
    rng = np.random.default_rng(1200)
    n = 20000
    wo = smp.cosine_hemisphere(rng.random(n), rng.random(n))
    wi = smp.uniform_sphere(rng.random(n), rng.random(n))
    wo[:10, 2] = np.array([1e-4, 1e-3, 0.01, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0])
    wo[:10] /= np.linalg.norm(wo[:10], axis=1, keepdims=True)
    for alpha in GGX_ALPHAS + (1e-3, 1.0):
        f_ref, pdf_ref = ref_ggx_f_and_pdf(wo, wi, alpha)
        assert np.allclose(smp.ggx_reflection_pdf(wo, wi, alpha), pdf_ref, rtol=1e-9, atol=1e-300)
        assert np.allclose(smp.ggx_reflection_f(wo, wi, alpha), f_ref, rtol=1e-9, atol=1e-300)


@pytest.mark.parametrize("alpha", GGX_ALPHAS)
def test_ggx_albedo_is_below_1_01_and_sample_weight_is_f_cos_over_pdf(alpha):
    """pbrt's energy test: E[f cos / pdf] < 1.01 over 10 directions x 16384 samples, and the weight
    f cos / pdf of each sample equals the G2 / G1 that bsdf.scatter uses."""
    rng = np.random.default_rng(1100 + GGX_ALPHAS.index(alpha))
    n = 16384
    for cos_o in np.linspace(0.02, 1.0, 10):
        wo = np.tile([math.sqrt(1 - cos_o ** 2), 0.0, cos_o], (n, 1))
        m = smp.ggx_sample_visible_normal(wo, np.full(n, alpha), rng.random(n), rng.random(n))
        wi = smp.reflect(wo, m)
        ok = wi[:, 2] > 0
        f = smp.ggx_reflection_f(wo[ok], wi[ok], alpha)
        pdf = smp.ggx_reflection_pdf(wo[ok], wi[ok], alpha)
        assert (pdf > 0).all() and np.isfinite(f).all()
        w = f * wi[ok, 2] / pdf
        ratio = smp.ggx_g2(wo[ok, 2], wi[ok, 2], alpha) / smp.ggx_g1(wo[ok, 2], alpha)
        assert np.allclose(w, ratio, rtol=1e-6)
        albedo = w.sum() / n
        assert 0.0 < albedo < 1.01, (alpha, cos_o, albedo)


@pytest.mark.parametrize("alpha", GGX_ALPHAS)
def test_ggx_reflection_pdf_integrates_to_at_most_one(alpha):
    # Normal incidence: wi falls below the horizon exactly when the sampled normal is more than
    # 45 degrees off, P(tan^2 theta_m > 1) = alpha^2 / (1 + alpha^2) for GGX, so the pdf integrates
    # to 1 / (1 + alpha^2).  Quadrature about the mirror direction, split at the horizon.
    p = ggx_warp_power(alpha)
    wo = local_direction(0.0)

    def pdf_normal(xy):
        d, jac = warped_to_dir(xy, wo, p)
        return smp.ggx_reflection_pdf(np.tile(wo, (len(d), 1)), d, alpha) * jac

    t_horizon = 0.5 ** (1.0 / p)
    total = (integrate_bins(pdf_normal, ((0.0, t_horizon), (0.0, TWO_PI)), (100, 8), 8).sum()
             + integrate_bins(pdf_normal, ((t_horizon, 1.0), (0.0, TWO_PI)), (50, 8), 8).sum())
    assert total == pytest.approx(1.0 / (1.0 + alpha ** 2), abs=1e-9)
    # Oblique and grazing incidence: at most 1 (quadrature with the horizon on a bin edge).
    for theta_deg in (60.0, 89.0, 89.9):
        wo = local_direction(theta_deg)

        def pdf(xy):
            d, jac = horizon_to_dir(xy, 0.7 + np.pi)
            return smp.ggx_reflection_pdf(np.tile(wo, (len(d), 1)), d, alpha) * jac

        total = integrate_bins(pdf, ((0.0, 1.0), (-1.0, 1.0)), (96, 96), 8).sum()
        assert 0.5 < total <= 1.0 + 1e-5, (theta_deg, total)


# ---------------------------------------------------------------- Beckmann (the Refraction BSDF's default)
def test_erf_erfc_and_erfinv_match_the_standard_library():
    x = np.concatenate([np.linspace(-8.0, 8.0, 4001), [0.0, 1e-9, -1e-9, 30.0, -30.0, 1e6]])
    assert np.allclose(smp.erf(x), [math.erf(v) for v in x], rtol=0.0, atol=2e-7)
    reference = np.array([math.erfc(v) for v in x])
    assert np.allclose(smp.erfc(x), reference, rtol=2e-7, atol=1e-300)          # tails: relative
    y = np.concatenate([np.linspace(-1.0 + 1e-12, 1.0 - 1e-12, 4001), [0.0, 1e-12, -0.5]])
    x = smp.erfinv(y)
    assert np.isfinite(x).all()
    assert np.allclose([math.erf(v) for v in x], y, rtol=0.0, atol=2e-7)
    assert smp.erfinv(np.array([1.0]))[0] == np.inf and smp.erfinv(np.array([-1.0]))[0] == -np.inf


def test_beckmann_d_is_normalised_and_the_lambda_fit_follows_the_exact_one():
    """int D(m) cos(m) dm = 1; Walter et al.'s fit of Lambda (Cycles') within 0.5 % of 1 + Lambda."""
    for alpha in (0.05, 0.3, 0.8, 1.0):
        c = np.linspace(1e-4, 1.0, 200_001)
        total = np.trapz(smp.beckmann_d(c, alpha) * c, c) * 2.0 * np.pi
        assert total == pytest.approx(1.0, rel=2e-3 if alpha < 0.1 else 1e-4)
        cos_v = np.linspace(0.01, 1.0, 500)
        fit, exact = smp.beckmann_lambda(cos_v, alpha), smp.beckmann_lambda_exact(cos_v, alpha)
        assert np.allclose(1.0 + fit, 1.0 + exact, rtol=5e-3)
        assert (exact >= 0).all() and (fit > -1e-3).all()     # (the fit dips to -6e-4 near a = 1.6)


def test_anisotropic_beckmann_visible_normals_have_the_stretched_density():
    """Anisotropic Beckmann visible normals: the mean of m and of its squares against quadrature
    of G1(wo) max(0, wo.m) D(m) / wo.z with D = exp(-(x^2 / ax^2 + y^2 / ay^2) / z^2) / (pi ax ay
    z^4) and G1 its normaliser (the density integrates to 1 by construction)."""
    rng = np.random.default_rng(3100)
    ax, ay = 0.6, 0.15
    g = 600
    c = (np.arange(g) + 0.5) / g
    phi = (np.arange(2 * g) + 0.5) / (2 * g) * 2.0 * np.pi
    cc, pp = np.meshgrid(c, phi, indexing="ij")
    ss = np.sqrt(1.0 - cc * cc)
    m_grid = np.stack([ss * np.cos(pp), ss * np.sin(pp), cc], axis=-1).reshape(-1, 3)
    x, y, z = m_grid.T
    d = np.exp(-((x / ax) ** 2 + (y / ay) ** 2) / z ** 2) / (np.pi * ax * ay * z ** 4)
    for wo in (local_direction(50.0, 0.4), local_direction(75.0, 2.0)):
        dens = np.maximum(0.0, m_grid @ wo) * d
        dens /= dens.sum()
        n = 400_000
        m = smp.beckmann_sample_visible_normal(np.tile(wo, (n, 1)), np.full(n, ax), rng.random(n),
                                               rng.random(n), np.full(n, ay))
        for k in range(3):
            assert_mean(m[:, k], (dens * m_grid[:, k]).sum(), f"m[{k}]", extra_tolerance=2e-4)
            assert_mean(m[:, k] ** 2, (dens * m_grid[:, k] ** 2).sum(), f"m[{k}]^2", extra_tolerance=2e-4)


# ================================================================ 3. bsdf.scatter per lobe
def glossy_albedo(wo_local, alpha, factor=None):
    """Integral of the reference f cos over the hemisphere (horizon on a bin edge), times
    ``factor(wo, wi)`` (n,) if given."""
    phi_m = math.atan2(wo_local[1], wo_local[0]) + np.pi

    def f_cos(xy):
        d, jac = horizon_to_dir(xy, phi_m)
        wo = np.tile(wo_local, (len(d), 1))
        v = ref_ggx_f_and_pdf(wo, d, alpha)[0] * d[:, 2] * jac
        return v if factor is None else v * factor(wo, d)

    return integrate_bins(f_cos, ((0.0, 1.0), (-1.0, 1.0)), (96, 96), 8).sum()


def material_table(spec):
    return bsdf.MaterialTable.from_materials(Materials.build([dict(name="m", **spec)]))


def scatter_lobe(table, lobe, wo, ng, ns, u1, u2, mode):
    n = len(u1)
    mat = np.zeros(n, np.int32)
    colors = bsdf.lobe_colors(table, mat, table.color[mat, bsdf.DIFFUSE])
    return bsdf.scatter(table, mat, colors, np.full(n, lobe), np.ones(n), np.tile(wo, (n, 1)),
                        np.tile(ng, (n, 1)), np.tile(ns, (n, 1)), u1, u2, mode)


@pytest.mark.parametrize("lobe", ("diffuse", "translucent"))
@pytest.mark.parametrize("side", (1.0, -1.0), ids=("front", "back"))
def test_diffuse_and_translucent_lobes_sample_the_cosine_with_weight_colour(side, lobe):
    """Camera paths: the diffuse lobe samples the cosine about the shading normal on wo's side; the
    translucent lobe (Blender's Translucent BSDF: f = colour / pi on the other side) about the
    flipped one; every kept sample weighs the colour, and samples that the shading normal sends to
    the wrong side of the geometric normal die.  Photons: Cycles' lobe is max(N_s . wo, 0) / pi
    for wo the light's side and any view on the outgoing side of the surface, so its exact adjoint
    leaves cosine-distributed about the geometric normal on that side, weighing the colour times
    |wo . N_s| / |wo . N_g| (none die; before, photons took the camera paths' directions, and the
    views between the two hemispheres got no light)."""
    colour = f32([0.8, 0.5, 0.2])
    table = material_table({lobe: colour})
    k, away = (bsdf.DIFFUSE, 1.0) if lobe == "diffuse" else (bsdf.TRANSLUCENT, -1.0)
    assert table.lobes == (4 if lobe == "diffuse" else 5) and table.has_nondelta[0]
    ng = unit_vector(0.2, -0.3, 0.9) * side
    ns = unit_vector(0.45, -0.1, 0.85) * side          # perturbed shading normal, same side
    wo = unit_vector(-0.3, 0.5, 0.6)                  # wo on the front side for side = 1
    ngf = ng if wo @ ng > 0 else -ng
    nsf = ns if ns @ ngf > 0 else -ns
    rng = np.random.default_rng((2000 if side > 0 else 2001) + 20 * (lobe != "diffuse"))
    out = {}

    def sampler(mode):
        def sample(n):
            u1, u2 = rng.random(n), rng.random(n)
            wi, w, alive = scatter_lobe(table, k, wo, ng, ns, u1, u2, mode)
            out.update(wi=wi, w=w, alive=alive)
            return dir_to_cos_phi(wi, away * ngf), alive.astype(np.float64)
        return sample

    def pdf(normal):
        return lambda xy: np.maximum(away * (cos_phi_to_dir(xy, away * ngf) @ normal), 0.0) / np.pi

    check_chi2(sampler("radiance"), pdf(nsf), HEMISPHERE, ires=8)
    wi, w, alive = out["wi"], out["w"], out["alive"]
    assert np.isfinite(w).all() and np.isfinite(wi).all()
    assert np.array_equal(alive, away * (wi @ ngf) > 0) and 0.9 < alive.mean() < 1.0
    assert np.allclose(w[alive], colour, rtol=1e-6) and (w[~alive] == 0).all()
    check_chi2(sampler("importance"), pdf(ngf), HEMISPHERE, ires=8)
    wi, w, alive = out["wi"], out["w"], out["alive"]
    assert alive.all() and (away * (wi @ ngf) > 0).all()
    assert np.allclose(w, colour * (wo @ nsf) / (wo @ ngf), rtol=1e-6)
    # A photon from below the shading normal (above the geometric one) is not scattered at all.
    low = unit_vector(-0.9, -0.1, 0.3)
    assert low @ ngf > 0 and low @ nsf < 0
    _, w_low, alive_low = scatter_lobe(table, k, low, ng, ns, rng.random(100), rng.random(100), "importance")
    assert not alive_low.any() and (w_low == 0).all()


def test_diffuse_lobe_with_flat_shading_keeps_every_sample_with_weight_colour():
    colour = f32([0.3, 0.6, 0.9])
    table = material_table({"diffuse": colour})
    n_ = unit_vector(-0.5, 0.5, -0.7)
    rng = np.random.default_rng(2002)
    for wo in (unit_vector(0.1, 0.2, -0.9), unit_vector(0.1, 0.2, 0.9)):
        for mode in ("radiance", "importance"):
            wi, w, alive = scatter_lobe(table, bsdf.DIFFUSE, wo, n_, n_, rng.random(20000),
                                        rng.random(20000), mode)
            assert alive.all()
            assert np.allclose(w, colour, rtol=1e-9)
            assert ((wi @ n_) * (wo @ n_) > 0).all()       # on wo's side


def test_translucent_beside_other_lobes_keeps_the_throughput_unbiased_on_both_sides():
    """Diffuse 0.4 + translucent 0.35 + mirror 0.25 with flat shading: E[weight] is the sum of
    weight * colour, split by side: the reflected part above, the translucent colour below.
    Without translucency the table keeps four lobe columns."""
    spec = {"diffuse": (0.8, 0.4, 0.2), "diffuse_weight": 0.4, "translucent": (0.2, 0.9, 0.5),
            "translucent_weight": 0.35, "mirror": (0.5, 0.5, 1.0), "mirror_weight": 0.25}
    table = material_table(spec)
    assert material_table({"diffuse": 0.5}).lobes == 4 and table.lobes == 5
    n_ = unit_vector(-0.2, 0.1, 1.0)
    wo = unit_vector(0.3, -0.2, 0.8)
    rng = np.random.default_rng(2022)
    mat = np.zeros(N, np.int32)
    colors = bsdf.lobe_colors(table, mat, table.color[mat, bsdf.DIFFUSE])
    scores = bsdf.lobe_scores(table, mat, colors)
    u = rng.random(N)
    lobe, prob = bsdf.choose_lobe(scores, u)
    r = bsdf.lobe_remainder(scores, u, lobe)
    assert set(np.unique(lobe)) == {bsdf.DIFFUSE, bsdf.MIRROR, bsdf.TRANSLUCENT}
    assert 0.0 <= r.min() and r.max() < 1.0 and abs(r.mean() - 0.5) < 0.002
    wi, w, alive = bsdf.scatter(table, mat, colors, lobe, prob, np.tile(wo, (N, 1)), np.tile(n_, (N, 1)),
                                np.tile(n_, (N, 1)), rng.random(N), rng.random(N), "importance")
    assert alive.all() and np.isfinite(w).all()
    below = wi @ n_ < 0
    assert np.array_equal(below, lobe == bsdf.TRANSLUCENT)
    reflected = 0.4 * f32(spec["diffuse"]) + 0.25 * f32(spec["mirror"])
    for c in range(3):
        assert_mean(np.where(below, 0.0, w[:, c]), reflected[c], f"reflected, channel {c}")
        assert_mean(np.where(below, w[:, c], 0.0), 0.35 * spec["translucent"][c], f"transmitted, channel {c}")


@pytest.mark.parametrize("stretch", (1.0, 3.0))
def test_a_beckmann_glossy_lobe_scatters_what_its_value_reflects(stretch):
    """A glossy lobe of Beckmann microfacets (``glossy_distribution``; Cycles has no multiscatter
    for them): the weights of :func:`~core.bsdf.scatter` (camera paths and photons) average to
    the integral of :func:`~core.bsdf.eval_glossy` (or ``glossy_anisotropic_value``) cos over
    the hemisphere (what the gather weighs photons by), within the 0.5 % of Cycles' Lambda fit
    against the exact Lambda of the sampled visible normals; and that is not GGX's albedo."""
    colour = f32([0.9, 0.7, 0.4])
    table = material_table({"glossy": colour, "roughness": 0.55, "glossy_stretch": stretch,
                            "glossy_distribution": bsdf.DISTRIBUTION_BECKMANN})
    assert table.glossy_beckmann[0] and (table.ms_fresnel == 0).all()
    n_ = np.array([0.0, 0.0, 1.0])
    wo = local_direction(55.0, 0.3)
    rng = np.random.default_rng(2050)
    n = 400_000
    tangent = np.tile([1.0, 0.0, 0.0], (n, 1))
    mat = np.zeros(n, np.int32)
    colors = bsdf.lobe_colors(table, mat, table.color[mat, bsdf.DIFFUSE])
    normals = np.tile(n_, (n, 1))
    wi, w, alive = bsdf.scatter(table, mat, colors, np.full(n, bsdf.GLOSSY), np.ones(n), np.tile(wo, (n, 1)),
                                normals, normals, rng.random(n), rng.random(n), "radiance", tangent=tangent)
    assert np.isfinite(w).all() and (w[~alive] == 0).all()

    def f_cos(xy, beckmann=True):
        d, jac = horizon_to_dir(xy, 0.3 + np.pi)
        k = len(d)
        if stretch == 1.0:
            f = bsdf.eval_glossy(np.full(k, table.alpha[0]), np.tile(wo, (k, 1)), d, np.tile(n_, (k, 1)),
                                 beckmann=np.full(k, beckmann))
        else:
            f, _ = bsdf.glossy_anisotropic_value(
                np.full(k, table.alpha_x[0]), np.full(k, table.alpha_y[0]), np.full(k, wo[2]), d[:, 2],
                d @ wo, np.full(k, wo[0]), d[:, 0], np.full(k, beckmann))
        return f * d[:, 2] * jac

    albedo = integrate_bins(f_cos, ((0.0, 1.0), (-1.0, 1.0)), (96, 96), 8).sum()
    ggx = integrate_bins(lambda xy: f_cos(xy, False), ((0.0, 1.0), (-1.0, 1.0)), (96, 96), 8).sum()
    assert 0.5 < albedo < 1.0 and abs(albedo - ggx) > 0.02
    assert_mean(w[:, 1] / colour[1], albedo, "Beckmann E[weight] / colour", extra_tolerance=5e-3 * albedo)


def test_glossy_lobe_samples_ggx_reflection_with_weight_colour_g2_over_g1():
    """Single-scattering GGX (``glossy_multiscatter`` 0)."""
    colour = f32([0.9, 0.7, 0.4])
    roughness = 0.55
    table = material_table({"glossy": colour, "roughness": roughness, "glossy_multiscatter": 0.0})
    alpha = float(np.float32(roughness)) ** 2
    assert table.alpha[0] == pytest.approx(alpha, rel=1e-12)
    n_ = unit_vector(0.3, 0.2, 0.93)
    f = frames_for(n_)[0]
    wo_local = local_direction(55.0)
    wo = wo_local @ f
    mirror = np.array([-wo_local[0], -wo_local[1], wo_local[2]])
    p = ggx_warp_power(alpha)
    rng = np.random.default_rng(2010)
    out = {}

    def sample(n):
        u1, u2 = rng.random(n), rng.random(n)
        wi, w, alive = scatter_lobe(table, bsdf.GLOSSY, wo, n_, n_, u1, u2, "radiance")
        out.update(wi=wi, w=w, alive=alive, u1=u1, u2=u2)
        return dir_to_warped(wi @ f.T, mirror, p), alive.astype(np.float64)

    def pdf_local(xy):
        d, jac = warped_to_dir(xy, mirror, p)
        return ref_ggx_f_and_pdf(np.tile(wo_local, (len(d), 1)), d, alpha)[1] * jac

    check_chi2(sample, pdf_local, WARPED, ires=8)
    wi, w, alive = out["wi"], out["w"], out["alive"]
    assert np.isfinite(w).all() and (w[~alive] == 0).all()
    wi_l = wi[alive] @ f.T
    g2_over_g1 = (1.0 + ref_ggx_lambda(wo_local[2], alpha)) / (
        1.0 + ref_ggx_lambda(wo_local[2], alpha) + ref_ggx_lambda(wi_l[:, 2], alpha))
    # atol: core clamps cos^2 >= 1e-12 in Lambda, which changes G2 / G1 ~ 1e-6 for cos_i < 1e-6.
    assert np.allclose(w[alive], colour * g2_over_g1[:, None], rtol=1e-6, atol=1e-5)

    # E[weight] = colour * integral of f cos over the hemisphere (quadrature of the reference f).
    albedo = glossy_albedo(wo_local, alpha)
    assert 0.5 < albedo < 1.0
    assert_mean(w[:, 1] / colour[1], albedo, "glossy E[weight] / colour", extra_tolerance=1e-5)
    # Importance mode with flat shading: the same directions and weights (the correction is 1).
    wi_i, w_i, alive_i = scatter_lobe(table, bsdf.GLOSSY, wo, n_, n_, out["u1"][:100_000],
                                      out["u2"][:100_000], "importance")
    assert np.array_equal(alive_i, alive[:100_000]) and np.allclose(wi_i, wi[:100_000], atol=1e-15)
    assert np.allclose(w_i, w[:100_000], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("roughness", (0.3, 0.6, 1.0))
def test_multiscatter_table_holds_the_single_scattering_albedo_by_quadrature(roughness):
    """With F_ss = 1 the factor is 1 / E(mu): E interpolated from the table against the
    quadrature of the reference f cos, at angles between and on the nodes."""
    table = material_table({"glossy": 1.0, "roughness": roughness})
    alpha = table.alpha[0]
    for theta in (0.0, 20.0, 45.0, 60.0, 75.0, 85.0, 88.0):
        wo_local = local_direction(theta)
        e = 1.0 / table.multiscatter(np.zeros(1, np.int32), wo_local[2:3])[0]
        assert e == pytest.approx(glossy_albedo(wo_local, alpha), abs=1.5e-3), theta   # 6e-4 measured
        assert np.all(e == e[0])
    single = material_table({"glossy": 1.0, "roughness": roughness, "glossy_multiscatter": 0.0})
    assert (single.multiscatter(np.zeros(3, np.int32), np.array([0.0, 0.5, 1.0])) == 1.0).all()


@pytest.mark.parametrize("colour", (1.0, (0.9, 0.5, 0.1)), ids=("white", "copper"))
def test_multiscatter_glossy_weights_are_single_scattering_times_the_view_factor(colour):
    """Radiance mode: the factor of wo, so a white lobe has E[weight] = 1 at every angle and a
    coloured one c (E + F_ms (1 - E)), F_ms = c E_avg / (1 - c (1 - E_avg)) (Cycles).  Importance
    mode: the same directions, weighted by the factor of wi, the direction towards the camera."""
    roughness = 0.8
    c = np.broadcast_to(f32(colour), (3,))
    table = material_table({"glossy": colour, "roughness": roughness})
    alpha = table.alpha[0]
    n_ = unit_vector(0.1, -0.2, 0.95)
    f = frames_for(n_)[0]
    # E_avg = 2 int E(mu) mu dmu by Gauss-Legendre over mu, then F_ms as Cycles computes it.
    x, gw = np.polynomial.legendre.leggauss(12)
    mus = 0.5 * (x + 1.0)
    e_avg = sum(wk * glossy_albedo(local_direction(math.degrees(math.acos(m))), alpha) * m
                for wk, m in zip(gw, mus))
    fms = c * e_avg / (1.0 - c * (1.0 - e_avg))
    assert table.ms_fresnel[0] == pytest.approx(fms, rel=3e-3)
    rng = np.random.default_rng(2030)
    n = 400_000
    for theta in (10.0, 50.0, 80.0):
        wo_local = local_direction(theta)
        wo = wo_local @ f
        u1, u2 = rng.random(n), rng.random(n)
        wi, w, alive = scatter_lobe(table, bsdf.GLOSSY, wo, n_, n_, u1, u2, "radiance")
        wi_i, w_i, alive_i = scatter_lobe(table, bsdf.GLOSSY, wo, n_, n_, u1, u2, "importance")
        assert np.array_equal(alive, alive_i) and np.isfinite(w).all() and np.isfinite(w_i).all()
        wi_l = wi[alive] @ f.T
        g2_over_g1 = (1.0 + ref_ggx_lambda(wo_local[2], alpha)) / (
            1.0 + ref_ggx_lambda(wo_local[2], alpha) + ref_ggx_lambda(wi_l[:, 2], alpha))
        mat = np.zeros(len(wi_l), np.int32)
        k_o = table.multiscatter(mat, np.full(len(wi_l), wo_local[2]))
        k_i = table.multiscatter(mat, wi_l[:, 2])
        assert np.allclose(w[alive], c * g2_over_g1[:, None] * k_o, rtol=1e-6, atol=1e-5)
        assert np.allclose(w_i[alive], c * g2_over_g1[:, None] * k_i, rtol=1e-6, atol=1e-5)
        e = glossy_albedo(wo_local, alpha)
        expected = c * (e + fms * (1 - e))
        if colour == 1.0:
            assert expected == pytest.approx(np.ones(3), abs=1.5e-3)
        for ch in range(3):
            assert_mean(w[:, ch], expected[ch], f"multiscatter E[weight] at {theta} deg",
                        extra_tolerance=1.5e-3 * c[ch])


def test_eval_glossy_equals_the_reference_f_in_any_frame_and_gives_the_half_vector_cosine():
    """The deposits' frame-free GGX value against the reference in the local frame of random normals."""
    rng = np.random.default_rng(2042)
    n = 20_000
    ns = rng.normal(size=(n, 3))
    ns /= np.linalg.norm(ns, axis=1, keepdims=True)
    wo, wi = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, n, 3)))
    alpha = rng.uniform(0.02, 1.0, n)
    f, cos_h = bsdf.eval_glossy(alpha, wo, wi, ns, with_cos_h=True)
    frames = frames_for(ns)
    wo_l, wi_l = np.einsum("nij,nj->ni", frames, wo), np.einsum("nij,nj->ni", frames, wi)
    ref = ref_ggx_f_and_pdf(wo_l, wi_l, alpha)[0]
    assert (f[ref == 0] == 0).all() and (ref > 0).sum() > n // 8
    assert np.allclose(f, ref, rtol=1e-9, atol=0)
    h = (wo + wi) / np.linalg.norm(wo + wi, axis=1, keepdims=True)
    assert np.allclose(cos_h, np.sum(wo * h, axis=1), atol=1e-12)


def ref_fresnel_rise(wo, wi, eta):
    """Cycles' Principled blend factor saturate((F(wo.h) - F0) / (1 - F0)) from the reference Fresnel."""
    h = wo + wi
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    f0 = ((eta - 1) / (eta + 1)) ** 2
    return np.clip((ref_fresnel(np.clip(np.sum(wo * h, axis=1), 0, 1), eta)[0] - f0) / (1 - f0), 0, 1)


@pytest.mark.parametrize("roughness", (0.0, 0.5, 1.0))
@pytest.mark.parametrize("tint", ((1.0, 1.0, 1.0), (1.0, 0.5, 0.2)), ids=("white", "tinted"))
def test_principled_layer_reflects_its_fresnel_albedo_and_leaves_the_rest_to_the_diffuse(roughness, tint):
    """Cycles' Principled dielectric: a GGX layer reflecting f0 + (1 - f0) s(wo.m), s the real
    Fresnel curve of IOR 1.5 rescaled to [0, 1], over a diffuse lobe weighted by
    L = 1 - max_c K_c (f0_c + (1 - f0_c) S) with S the layer's lobe mean of s and K = E + F_ms (1 - E)
    (multiscatter).  Radiance mode, through lobe choice and scatter: E[weight] = L base + K A,
    with E and S by quadrature of the reference f cos.  A white base and tint make it a white
    furnace (1 at every angle), which a constant specular weight (the earlier model) is not."""
    eta = 1.5
    f0 = ((eta - 1) / (eta + 1)) ** 2 * f32(tint)
    base = f32((0.8, 0.8, 0.8)) if tint[1] < 1 else np.ones(3)
    spec = {"diffuse": base, "glossy": f0, "roughness": roughness, "glossy_fresnel_ior": eta,
            "glossy_fresnel_rise": 1.0 - f0, "diffuse_layer": f0, "glossy_multiscatter": f0 + 0.1}
    table = material_table(spec)
    alpha = table.alpha[0]
    n_ = unit_vector(0.1, 0.2, 0.9)
    f = frames_for(n_)[0]
    rng = np.random.default_rng(2041)
    mat = np.zeros(N, np.int32)
    for theta in (10.0, 50.0, 80.0):
        wo_local = local_direction(theta)
        if roughness == 0.0:
            e = 1.0
            s_mean = ref_fresnel_rise(wo_local[None], wo_local[None] * (-1, -1, 1), eta)[0]
        else:
            e = glossy_albedo(wo_local, alpha)
            s_mean = glossy_albedo(wo_local, alpha, lambda wo, wi: ref_fresnel_rise(wo, wi, eta)) / e
        k = e + table.ms_fresnel[0] * (1 - e) if roughness > 0 else np.ones(3)
        a = k * (f0 + (1 - f0) * s_mean)
        expected = (1 - a.max()) * base + a
        if tint[1] == 1.0:
            assert expected == pytest.approx(np.ones(3), abs=1e-9)
        colors = bsdf.lobe_colors(table, mat, table.color[mat, bsdf.DIFFUSE])
        lobe, prob = bsdf.choose_lobe(bsdf.lobe_scores(table, mat, colors), rng.random(N))
        wo = np.tile(wo_local @ f, (N, 1))
        nn = np.tile(n_, (N, 1))
        _, w, _ = bsdf.scatter(table, mat, colors, lobe, prob, wo, nn, nn, rng.random(N), rng.random(N),
                               "radiance")
        assert np.isfinite(w).all() and (w >= 0).all()
        for c in range(3):
            assert_mean(w[:, c], expected[c], f"layered E[weight] at {theta} deg, channel {c}",
                        extra_tolerance=2e-3)


def test_mixed_material_throughput_is_unbiased_through_lobe_choice_and_scatter():
    """Diffuse 0.5 + glossy 0.3 + mirror 0.2: E[weight] = sum of weight * colour * lobe albedo."""
    spec = {"diffuse": (0.8, 0.4, 0.2), "diffuse_weight": 0.5,
            "glossy": (0.3, 0.9, 0.6), "glossy_weight": 0.3, "roughness": 0.55, "glossy_multiscatter": 0.0,
            "mirror": (0.5, 0.5, 1.0), "mirror_weight": 0.2}
    table = material_table(spec)
    alpha = table.alpha[0]
    n_ = unit_vector(-0.2, 0.1, 1.0)
    wo_local = local_direction(40.0)
    wo = wo_local @ frames_for(n_)[0]
    rng = np.random.default_rng(2015)
    mat = np.zeros(N, np.int32)
    colors = bsdf.lobe_colors(table, mat, table.color[mat, bsdf.DIFFUSE])
    lobe, prob = bsdf.choose_lobe(bsdf.lobe_scores(table, mat, colors), rng.random(N))
    wi, w, alive = bsdf.scatter(table, mat, colors, lobe, prob, np.tile(wo, (N, 1)), np.tile(n_, (N, 1)),
                                np.tile(n_, (N, 1)), rng.random(N), rng.random(N), "radiance")
    assert np.isfinite(w).all() and (w >= 0).all()
    expected = (0.5 * f32(spec["diffuse"]) + 0.3 * f32(spec["glossy"]) * glossy_albedo(wo_local, alpha)
                + 0.2 * f32(spec["mirror"]))
    for c in range(3):
        assert_mean(w[:, c], expected[c], f"mixed material E[weight], channel {c}", extra_tolerance=1e-5)


def test_material_table_merges_near_specular_glossy_into_the_mirror_lobe():
    mats = Materials.build([
        {"name": "sharp", "glossy": (0.2, 0.4, 0.8), "glossy_weight": 0.5, "roughness": 0.01,
         "mirror": (1.0, 0.5, 0.25), "mirror_weight": 0.25},
        {"name": "rough", "glossy": (0.2, 0.4, 0.8), "roughness": 0.02},
        {"name": "black diffuse", "diffuse": 0.0}])
    table = bsdf.MaterialTable.from_materials(mats)
    assert table.weight[0].tolist() == [0.0, 0.0, 0.75, 0.0]
    merged = (0.5 * f32([0.2, 0.4, 0.8]) + 0.25 * f32([1.0, 0.5, 0.25])) / 0.75
    assert np.allclose(table.color[0, bsdf.MIRROR], merged)
    assert table.weight[1, bsdf.GLOSSY] == 1.0
    assert table.alpha[1] == pytest.approx(float(np.float32(0.02)) ** 2)
    assert table.has_nondelta.tolist() == [False, True, False]
    assert table.has_glossy.tolist() == [False, True, False]


def test_mirror_lobe_returns_the_exact_reflection_with_weight_colour():
    colour = f32([0.95, 0.9, 0.8])
    table = material_table({"mirror": colour})
    rng = np.random.default_rng(2020)
    n = 5000
    ng = smp.uniform_sphere(rng.random(n), rng.random(n))
    wo = smp.uniform_sphere(rng.random(n), rng.random(n))
    mat = np.zeros(n, np.int32)
    colors = bsdf.lobe_colors(table, mat, table.color[mat, 0])
    for mode in ("radiance", "importance"):
        wi, w, alive = bsdf.scatter(table, mat, colors, np.full(n, bsdf.MIRROR), np.ones(n), wo, ng, ng,
                                    rng.random(n), rng.random(n), mode)
        expected = 2.0 * np.sum(wo * ng, axis=1)[:, None] * ng - wo
        grazing = np.abs(np.sum(wo * ng, axis=1)) < 1e-6
        assert np.allclose(wi, expected, atol=1e-12)
        assert alive[~grazing].all()
        assert np.allclose(w[alive], colour, rtol=1e-9)


def ref_rough_dielectric_pdf(wo, wi, alpha, eta):
    """Walter et al. (2007) density of wi (local, wo.z > 0) for visible-normal sampling of GGX
    microfacets followed by Fresnel reflection or refraction (relative index ``eta``)."""
    cos_o = wo[:, 2]
    refl = wi[:, 2] > 0
    m = np.where(refl[:, None], wo + wi, -(wo + eta * wi))
    m = m / np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-300)
    m = m * np.where(m[:, 2] < 0, -1.0, 1.0)[:, None]
    om, im = np.sum(wo * m, axis=1), np.sum(wi * m, axis=1)
    a2, c2 = alpha * alpha, m[:, 2] ** 2
    d = a2 / (np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2)
    d_vis = np.maximum(om, 0.0) * d / (1.0 + ref_ggx_lambda(cos_o, alpha)) / cos_o
    fr = ref_fresnel(np.clip(om, 0.0, 1.0), np.full(len(om), eta))[0]
    pdf_r = fr * d_vis / np.maximum(4.0 * om, 1e-300)
    denom = (om + eta * im) ** 2
    pdf_t = (1.0 - fr) * d_vis * np.abs(im) * eta * eta / np.maximum(denom, 1e-300)
    valid_t = (om > 0) & (im < 0)
    return np.where(refl, pdf_r, np.where(valid_t, pdf_t, 0.0))


@pytest.mark.parametrize("roughness,theta_deg,outside", ROUGH_DIELECTRIC_CASES)
def test_rough_dielectric_samples_walter_microfacet_glass_with_weight_g2_over_g1(roughness, theta_deg,
                                                                                 outside):
    """Chi-square of the sampled directions over the sphere against Walter's density (reflection
    above, refraction below), and each weight colour G2 / G1 (radiance: refraction / eta^2)."""
    ior = 1.5
    colour = f32([0.9, 0.8, 0.7])
    table = material_table({"dielectric": colour, "ior": ior, "dielectric_roughness": roughness})
    alpha = float(np.float32(roughness)) ** 2
    assert table.dielectric_alpha[0] == pytest.approx(alpha, rel=1e-12)
    n_ = unit_vector(0.1, 0.2, 0.95)
    ng = n_ if outside else -n_                       # wo on the back side: leaving the glass
    eta = ior if outside else 1.0 / ior
    f = frames_for(n_)[0]
    wo_local = local_direction(theta_deg)
    wo = wo_local @ f
    rng = np.random.default_rng(2040 + ROUGH_DIELECTRIC_CASES.index((roughness, theta_deg, outside)))
    out = {}

    def sample(n):
        u1, u2, u3 = rng.random(n), rng.random(n), rng.random(n)
        m_ = np.zeros(n, np.int32)
        colors = bsdf.lobe_colors(table, m_, table.color[m_, bsdf.DIFFUSE])
        wi, w, alive = bsdf.scatter(table, m_, colors, np.full(n, bsdf.DIELECTRIC), np.ones(n),
                                    np.tile(wo, (n, 1)), np.tile(ng, (n, 1)), np.tile(ng, (n, 1)),
                                    u1, u2, "radiance", u3)
        out.update(wi=wi, w=w, alive=alive)
        return dir_to_cos_phi(wi, n_), alive.astype(np.float64)

    def pdf(xy):
        d = cos_phi_to_dir(xy, n_) @ f.T
        return ref_rough_dielectric_pdf(np.tile(wo_local, (len(d), 1)), d, alpha, eta)

    check_chi2(sample, pdf, SPHERE, ires=8)
    wi, w, alive = out["wi"], out["w"], out["alive"]
    assert np.isfinite(w).all() and (w[~alive] == 0).all()
    wi_l = wi[alive] @ f.T
    refracted = wi_l[:, 2] < 0
    assert 0.02 < refracted.mean() < 0.999
    g2_over_g1 = (1.0 + ref_ggx_lambda(wo_local[2], alpha)) / (
        1.0 + ref_ggx_lambda(wo_local[2], alpha) + ref_ggx_lambda(wi_l[:, 2], alpha))
    expected = colour * g2_over_g1[:, None]              # (camera paths: no 1 / eta^2, as Cycles)
    assert np.allclose(w[alive], expected, rtol=1e-6, atol=1e-6)


def test_dielectric_reflections_take_the_reflection_colour_and_refractions_the_lobe_colour():
    colour, reflection = f32([0.9, 0.6, 0.3]), f32([1.0, 1.0, 0.5])
    table = material_table({"dielectric": colour, "dielectric_reflection": reflection, "ior": 1.5})
    n_ = unit_vector(0.0, 0.0, 1.0)
    wo = local_direction(60.0)
    rng = np.random.default_rng(2050)
    wi, w, alive = scatter_lobe(table, bsdf.DIELECTRIC, wo, n_, n_, rng.random(20000), rng.random(20000),
                                "radiance")
    refl = wi @ n_ > 0
    assert alive.all() and 0 < refl.sum() < len(refl)
    assert np.allclose(w[refl], reflection, rtol=1e-6) and np.allclose(w[~refl], colour, rtol=1e-6)


def test_dielectric_below_the_mirror_roughness_is_smooth_glass():
    smooth = material_table({"dielectric": 1.0, "ior": 1.5})
    almost = material_table({"dielectric": 1.0, "ior": 1.5, "dielectric_roughness": 0.019})
    assert smooth.dielectric_alpha[0] == 0.0 and almost.dielectric_alpha[0] == 0.0
    assert not smooth.has_rough_dielectric and not almost.has_rough_dielectric


@pytest.mark.parametrize("theta_deg,outside", DIELECTRIC_CASES)
def test_dielectric_reflects_with_fresnel_frequency_and_scales_refraction_by_eta_squared(theta_deg, outside):
    ior = 1.5
    colour = f32([1.0, 0.9, 0.8])
    table = material_table({"dielectric": colour, "ior": ior})
    ng = unit_vector(0.1, -0.4, 0.9)
    f = frames_for(ng)[0]
    wo = local_direction(theta_deg) @ f * (1.0 if outside else -1.0)
    eta = ior if outside else 1.0 / ior
    nf = ng if outside else -ng                       # normal on wo's side
    cos_i = math.cos(math.radians(theta_deg))
    fr, cos_t = (float(v) for v in ref_fresnel(cos_i, eta))
    rng = np.random.default_rng(2030 + DIELECTRIC_CASES.index((theta_deg, outside)))
    u1, u2 = rng.random(N), rng.random(N)
    wi, w, alive = scatter_lobe(table, bsdf.DIELECTRIC, wo, ng, ng, u1, u2, "radiance")
    m = 100_000
    wi_i, w_i, alive_i = scatter_lobe(table, bsdf.DIELECTRIC, wo, ng, ng, u1[:m], u2[:m], "importance")
    assert np.isfinite(wi).all() and np.isfinite(w).all() and alive.all() and alive_i.all()
    assert np.array_equal(wi[:m], wi_i)
    refl = wi @ nf > 0
    assert_binomial(int(refl.sum()), N, fr, f"reflection frequency at {theta_deg} deg")
    # Reflection exactly when u1 < F (up to rounding of F itself).
    assert (np.abs(u1[refl != (u1 < fr)] - fr) < 1e-9).all()
    mirror = 2 * cos_i * nf - wo
    refracted = -wo / eta + (cos_i / eta - cos_t) * nf
    assert np.allclose(wi[refl], mirror, atol=1e-9)
    assert np.allclose(wi[~refl], refracted, atol=1e-9)
    assert np.allclose(-(wi[~refl] @ nf), cos_t, atol=1e-9)
    # Refraction: radiance mode unscaled, importance (photons) 1/eta^2 (1/1.5^2 entering, 1.5^2
    # leaving): Cycles' convention (before stop 43, the other way round).
    refl_i = refl[:m]
    assert np.allclose(w[refl], colour, rtol=1e-9)
    assert np.allclose(w[~refl], colour, rtol=1e-6)
    assert np.allclose(w_i[refl_i], colour, rtol=1e-6)
    assert np.allclose(w_i[~refl_i], colour / eta ** 2, rtol=1e-6)


def test_dielectric_known_values_normal_incidence_and_80_degrees():
    f, cos_t = smp.fresnel_dielectric(np.array([1.0, math.cos(math.radians(80.0))]), np.array([1.5, 1.5]))
    assert f[0] == pytest.approx(0.04, abs=1e-12)
    assert cos_t[0] == pytest.approx(1.0, abs=1e-12)
    assert f[1] == pytest.approx(0.387704354691473, abs=1e-12)
    assert math.degrees(math.acos(cos_t[1])) == pytest.approx(41.0364, abs=1e-4)
    # Through scatter: the refracted direction at 80 degrees makes 41.0364 degrees with -n.
    table = material_table({"dielectric": 1.0, "ior": 1.5})
    wo = local_direction(80.0, phi=0.0)
    wi, w, alive = scatter_lobe(table, bsdf.DIELECTRIC, wo, [0, 0, 1.0], [0, 0, 1.0],
                                np.array([0.999]), np.array([0.5]), "importance")
    assert wi[0, 2] < 0 and math.degrees(math.acos(-wi[0, 2])) == pytest.approx(41.0364, abs=1e-4)


@pytest.mark.parametrize("theta_deg", (41.9, 45.0, 60.0, 89.9, 90.0))
def test_dielectric_total_internal_reflection_from_inside_gives_r1_t0_without_nan(theta_deg):
    assert math.degrees(math.asin(1 / 1.5)) == pytest.approx(41.81, abs=5e-3)
    cos_i = math.cos(math.radians(theta_deg))
    f, cos_t = smp.fresnel_dielectric(np.array([cos_i]), np.array([1 / 1.5]))
    assert f[0] == 1.0 and cos_t[0] == 0.0
    colour = f32([0.9, 0.8, 0.7])
    table = material_table({"dielectric": colour, "ior": 1.5})
    ng = np.array([0.0, 0.0, 1.0])
    wo = -local_direction(theta_deg)               # inside the glass: below the outward normal
    rng = np.random.default_rng(2040)
    n = 10000
    for mode in ("radiance", "importance"):
        wi, w, alive = scatter_lobe(table, bsdf.DIELECTRIC, wo, ng, ng, rng.random(n), rng.random(n), mode)
        assert np.isfinite(wi).all() and np.isfinite(w).all()
        if theta_deg < 90.0:
            assert alive.all()
            assert (wi[:, 2] < 0).all()            # every photon/path stays inside
            assert np.allclose(wi, np.array([-wo[0], -wo[1], wo[2]]), atol=1e-9)
            assert np.allclose(w, colour, rtol=1e-9)


def test_fresnel_reflectance_plus_transmittance_is_one_at_every_angle():
    cos_i = np.concatenate([np.linspace(0.0, 1.0, 20001), [1e-12, 1e-6]])
    for eta in (1.5, 1 / 1.5, 1.33, 2.4, 1.0):
        f, cos_t = smp.fresnel_dielectric(cos_i, np.full(len(cos_i), eta))
        f_ref, cos_t_ref = ref_fresnel(cos_i, eta)
        assert np.isfinite(f).all() and ((f >= 0) & (f <= 1)).all()
        assert np.allclose(f, f_ref, atol=1e-12) and np.allclose(cos_t, cos_t_ref, atol=1e-12)
        # Transmittance from the Fresnel amplitude coefficients t_s, t_p (energy flux ratio).
        ok = (cos_t > 0) & (cos_i > 0)
        ci, ct = cos_i[ok], cos_t[ok]
        ts = 2 * ci / (ci + eta * ct)
        tp = 2 * ci / (eta * ci + ct)
        t = eta * ct / ci * 0.5 * (ts * ts + tp * tp)
        assert np.allclose(f[ok] + t, 1.0, atol=1e-12), eta
        assert (f[~ok] == 1.0).all() or eta == 1.0
        # Reciprocity: F(cos_i, eta) = F(cos_t, 1 / eta).
        f_back, _ = smp.fresnel_dielectric(ct, np.full(len(ct), 1 / eta))
        assert np.allclose(f_back, f[ok], atol=1e-9)


# ================================================================ 4. choose_lobe
@pytest.mark.parametrize("scores", CHOOSE_LOBE_SCORES)
def test_choose_lobe_frequencies_are_proportional_to_scores(scores):
    s = np.asarray(scores, np.float64)
    rng = np.random.default_rng(3000 + CHOOSE_LOBE_SCORES.index(scores))
    lobe, prob = bsdf.choose_lobe(np.tile(s, (N, 1)), rng.random(N))
    counts = np.bincount(lobe, minlength=4)
    p = s / s.sum()
    assert (counts[p == 0] == 0).all(), counts
    assert np.allclose(prob, p[lobe], rtol=1e-12)
    nz = p > 0
    if nz.sum() > 1:
        stat = float(np.sum((counts[nz] - N * p[nz]) ** 2 / (N * p[nz])))
        pv = chi2_sf(stat, int(nz.sum()) - 1)
        assert pv >= ALPHA_EACH, (counts, N * p, pv)
    else:
        assert counts[nz][0] == N


def test_choose_lobe_never_picks_a_zero_score_lobe_at_cdf_steps():
    rng = np.random.default_rng(3100)
    rows = rng.random((20000, 4)) * (rng.random((20000, 4)) < 0.5)
    rows[:, 3] *= rng.random(20000) < 0.3
    rows = rows[rows.sum(axis=1) > 0]
    rows = np.concatenate([rows, [[1, 0, 0, 0], [0, 0, 0, 1], [0, 1, 0, 0], [0.25, 0, 0.25, 0],
                                  [1e-300, 0, 0, 1], [0, 0, 1, 1e-300]]])
    total = rows.sum(axis=1)
    cdf = np.cumsum(rows, axis=1)
    us = [cdf[:, k] / total for k in range(4)] + [np.zeros(len(rows)), np.full(len(rows), np.nextafter(1, 0))]
    us += [np.nextafter(cdf[:, k] / total, 0) for k in range(4)]
    us += [np.nextafter(cdf[:, k] / total, 2) for k in range(4)]
    for u in us:
        u = np.clip(u, 0.0, np.nextafter(1, 0))
        lobe, prob = bsdf.choose_lobe(rows, u)
        picked = rows[np.arange(len(rows)), lobe]
        assert (lobe >= 0).all() and (picked > 0).all()
        assert np.allclose(prob, picked / total, rtol=1e-12)


def test_choose_lobe_returns_minus_one_when_all_scores_are_zero():
    scores = np.zeros((5, 4))
    scores[2, 1] = 1.0
    lobe, prob = bsdf.choose_lobe(scores, np.array([0.0, 0.3, 0.5, 0.7, np.nextafter(1, 0)]))
    assert lobe.tolist() == [-1, -1, 1, -1, -1]
    assert prob.tolist() == [0.0, 0.0, 1.0, 0.0, 0.0]


# ================================================================ 5. LightSampler
BOX_LO, BOX_HI = np.array([-1.0, -1.5, -0.5]), np.array([2.0, 1.0, 1.5])
BOX_CENTER = 0.5 * (BOX_LO + BOX_HI)
BOX_RADIUS = 0.5 * float(np.linalg.norm(BOX_HI - BOX_LO))


def light_context(lights=(), emissive_triangles=(), emission=(1.0, 2.0, 0.5), world=(0.0, 0.0, 0.0)):
    """A black box [BOX_LO, BOX_HI] (bounding sphere radius BOX_RADIUS) holding the given emitters."""
    mats = Materials.build([{"name": "black"}, {"name": "lamp", "emission": emission}])
    m = MeshBuilder()
    m.add_box(tuple(BOX_LO), tuple(BOX_HI), 0, inward=True)
    for tri in emissive_triangles:
        m.add_triangles([tri], 1)
    scene = m.build(mats, Lights.build(list(lights)), world=World(color=np.asarray(world, np.float32)))
    return RenderContext(scene)


def sample_photons(ctx, n, seed):
    u = np.random.default_rng(seed).random((n, 6))
    o, d, flux, normals = ctx.lights.sample(u)
    assert np.isfinite(o).all() and np.isfinite(d).all() and np.isfinite(flux).all()
    assert (flux >= 0).all()
    # Unit to float32 precision here (rays are traced in float32 by accel.intersect); the documented
    # float64 unit length is checked by test_photon_directions_are_unit_to_float64_precision.
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    return o, d, flux, normals


def assert_mean_flux(flux, power, what):
    power = np.asarray(power, np.float64)
    mean = flux.mean(axis=0)
    assert np.allclose(mean, power, rtol=0.01), f"{what}: mean flux {mean}, emitted power {power}"


def test_point_light_emits_its_power_uniformly_over_the_sphere():
    power = np.array([10.0, 20.0, 30.0])
    pos = np.array([0.2, 0.1, 0.3])
    ctx = light_context([{"kind": "point", "position": pos, "power": power}])
    o, d, flux, _ = sample_photons(ctx, N, 4000)
    assert_mean_flux(flux, power, "point light")
    assert np.allclose(o, pos, atol=1e-12)
    check_chi2(lambda n: (dir_to_cos_phi(d, [0.0, 0.0, 1.0]), None),
               lambda xy: np.full(len(xy), 1 / (4 * np.pi)), SPHERE)


def test_point_light_with_radius_starts_photons_on_the_hemisphere_facing_them():
    """A Lambertian sphere seen from direction d is a uniformly bright disk: origins projected on
    the plane perpendicular to d are uniform on the disk of the sphere's radius."""
    radius, pos = 0.25, np.array([0.5, -0.5, 0.5])
    ctx = light_context([{"kind": "point", "position": pos, "power": 7.0, "radius": radius}])
    o, d, flux, _ = sample_photons(ctx, N, 4001)
    assert_mean_flux(flux, [7.0] * 3, "spherical point light")
    q = (o - pos) / radius
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)
    z = np.sum(q * d, axis=1)
    assert (z >= -1e-6).all()
    fr = frames_for(d)
    x, y = np.einsum("ij,ij->i", q, fr[:, 0]), np.einsum("ij,ij->i", q, fr[:, 1])
    check_chi2(lambda n: (disk_polar(x, y), None), uniform_polar_pdf, DISK_POLAR)


@pytest.mark.parametrize("blend", SPOT_BLENDS)
def test_spot_light_is_uniform_in_its_cone_with_flux_following_the_smoothstep_mask(blend):
    power, angle = np.array([40.0, 30.0, 10.0]), 1.2
    axis = unit_vector(1.0, -1.0, -2.0)
    ctx = light_context([{"kind": "spot", "position": (0.0, 0.0, 1.0), "direction": axis, "power": power,
                          "spot_angle": angle, "spot_blend": blend}])
    o, d, flux, _ = sample_photons(ctx, N, 4010 + SPOT_BLENDS.index(blend))
    cos_half = math.cos(float(np.float32(angle)) / 2)
    blend32 = float(np.float32(blend))
    # Cycles: intensity P/(4 pi) times smoothstep((cos - cos_half) / ((1 - cos_half) blend)).
    cos_theta = d @ ctx.scene.lights.direction[0].astype(np.float64)
    t = np.clip((cos_theta - cos_half) / ((1 - cos_half) * blend32), 0, 1) if blend32 > 0 else \
        np.ones_like(cos_theta)
    mask = t * t * (3 - 2 * t)
    # atol: the float32 light direction is unit only to ~1e-8, so cos theta recomputed from the photon
    # direction differs by ~1e-7 from the cone-local one; the mask's slope is up to 1.5 / width.
    scale = power * 0.5 * (1 - cos_half)
    assert np.allclose(flux, scale * mask[:, None], rtol=1e-6, atol=1e-5 * scale.max())
    # Emitted power by quadrature of the intensity over the cone.
    c = np.linspace(cos_half, 1.0, 200001)
    tt = np.clip((c - cos_half) / ((1 - cos_half) * blend32), 0, 1) if blend32 > 0 else np.ones_like(c)
    emitted = power / (4 * np.pi) * TWO_PI * np.trapz(tt * tt * (3 - 2 * tt), c)
    assert np.allclose(emitted, power / 2 * (1 - cos_half) * (1 - blend32 / 2), rtol=1e-6)
    assert_mean_flux(flux, emitted, f"spot light, blend {blend}")
    if blend == SPOT_BLENDS[1]:
        check_chi2(lambda n: (cone_param(d, axis, cos_half), None), uniform_polar_pdf, DISK_POLAR)


@pytest.mark.parametrize("spread_deg", (10.0, 60.0, 120.0))
def test_area_light_spread_emits_its_power_with_cycles_soft_box_distribution(spread_deg):
    """Cycles: radiance times max(0, (tan h - tan a) / (tan h - h)), h = spread / 2.  The photons'
    flux, weighted by direction, must follow the density cos a att(a) / pi (a chi-square test of
    the flux-weighted angle on bins of equal probability under it) and average to the power."""
    from core.lights import spread_attenuation
    power = np.array([12.0, 6.0, 3.0])
    axis = unit_vector(-0.2, 0.3, -1.0)
    spread = math.radians(spread_deg)
    ctx = light_context([{"kind": "area", "position": (0.0, 0.0, 1.0), "direction": axis, "size": (0.5, 0.5),
                          "power": power, "spread": spread}])
    o, d, flux, _ = sample_photons(ctx, N, 4030 + int(spread_deg))
    assert_mean_flux(flux, power, f"area light, spread {spread_deg}")
    h = float(np.float32(spread)) / 2
    cos_a = d @ ctx.scene.lights.direction[0].astype(np.float64)
    assert (cos_a >= math.cos(h) - 1e-6).all()
    # CDF of the angle under cos a att(a) / pi by quadrature; 20 bins of equal probability.
    a = np.linspace(0.0, h, 200001)
    dens = 2.0 * np.cos(a) * np.sin(a) * spread_attenuation(np.cos(a), h)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(a))])
    assert cdf[-1] == pytest.approx(1.0, abs=1e-6)              # the attenuation keeps the power
    edges = np.interp(np.linspace(0, 1, 21), cdf, a)
    weights = flux[:, 0] / power[0]
    counts = np.histogram(np.arccos(np.clip(cos_a, -1, 1)), bins=edges, weights=weights)[0]
    sums2 = np.histogram(np.arccos(np.clip(cos_a, -1, 1)), bins=edges, weights=weights ** 2)[0]
    expected = len(weights) / 20
    z = (counts - expected) / np.sqrt(sums2)
    assert np.abs(z).max() < Z_CRIT, z


@pytest.mark.parametrize("kind", ("area", "disk"))
def test_area_light_is_cosine_about_its_direction_and_uniform_over_its_shape(kind):
    power = np.array([25.0, 20.0, 5.0])
    axis = unit_vector(0.3, 0.2, -1.0)
    pos = np.array([0.5, -0.2, 1.2])
    ctx = light_context([{"kind": kind, "position": pos, "direction": axis, "size": (0.8, 0.5),
                          "power": power}])
    lights = ctx.scene.lights
    au, av = lights.axis_u[0].astype(np.float64), lights.axis_v[0].astype(np.float64)
    assert abs(au @ av) < 1e-6 and abs(au @ axis) < 1e-6
    assert np.linalg.norm(au) == pytest.approx(0.4, rel=1e-6)
    assert np.linalg.norm(av) == pytest.approx(0.25, rel=1e-6)
    o, d, flux, _ = sample_photons(ctx, N, 4020 if kind == "area" else 4021)
    assert np.allclose(flux, power, rtol=1e-9)                  # one-sided: flux = power per photon
    assert_mean_flux(flux, power, f"{kind} light")
    assert np.allclose((o - pos) @ axis, 0.0, atol=1e-6)
    check_chi2(lambda n: (dir_to_cos_phi(d, axis), None), lambda xy: xy[:, 0] / np.pi, HEMISPHERE)
    x = (o - pos) @ au / (au @ au)
    y = (o - pos) @ av / (av @ av)
    if kind == "area":
        check_chi2(lambda n: (np.stack([x, y], axis=1), None), lambda xy: np.full(len(xy), 0.25),
                   ((-1.0, 1.0), (-1.0, 1.0)))
    else:
        check_chi2(lambda n: (disk_polar(x, y), None), uniform_polar_pdf, DISK_POLAR)


def check_distant_origins(o, d):
    """Origins of distant-light photons: uniform on the disk of radius R perpendicular to d, 2R
    before the scene centre."""
    q = o - BOX_CENTER
    assert np.allclose(np.sum(q * d, axis=1), -2 * BOX_RADIUS, atol=1e-9)
    q = q + 2 * BOX_RADIUS * d
    fr = frames_for(d)
    x = np.einsum("ij,ij->i", q, fr[:, 0]) / BOX_RADIUS
    y = np.einsum("ij,ij->i", q, fr[:, 1]) / BOX_RADIUS
    check_chi2(lambda n: (disk_polar(x, y), None), uniform_polar_pdf, DISK_POLAR)


def test_sun_carries_irradiance_times_bounding_disk_area_uniformly_in_its_cone():
    irradiance = np.array([3.0, 2.5, 2.0])
    axis = unit_vector(-0.2, 0.4, -1.0)
    sun_angle = 0.2
    ctx = light_context([{"kind": "sun", "direction": axis, "power": irradiance, "sun_angle": sun_angle}])
    assert ctx.lights.radius == pytest.approx(BOX_RADIUS, rel=1e-9)
    o, d, flux, _ = sample_photons(ctx, N, 4030)
    assert_mean_flux(flux, irradiance * np.pi * BOX_RADIUS ** 2, "sun")
    cos_half = math.cos(float(np.float32(sun_angle)) / 2)
    check_chi2(lambda n: (cone_param(d, axis, cos_half), None), uniform_polar_pdf, DISK_POLAR)
    check_distant_origins(o, d)


def test_world_light_emits_4_pi_squared_r_squared_radiance_uniformly():
    radiance = np.array([0.5, 0.25, 1.0])
    ctx = light_context(world=radiance)
    o, d, flux, _ = sample_photons(ctx, N, 4040)
    assert_mean_flux(flux, 4 * np.pi ** 2 * BOX_RADIUS ** 2 * radiance, "world")
    check_chi2(lambda n: (dir_to_cos_phi(d, [0.0, 0.0, 1.0]), None),
               lambda xy: np.full(len(xy), 1 / (4 * np.pi)), SPHERE)
    check_distant_origins(o, d)


def afar_context(emitter, axis, power):
    """:func:`light_context` with a sun along ``axis`` of irradiance ``power`` ("sun"), or a constant
    world of radiance ``power`` (else)."""
    if emitter == "sun":
        return light_context([{"kind": "sun", "direction": axis, "power": power, "sun_angle": 0.0}])
    return light_context(world=power)


def power_into_sphere(o, d, flux, centre, rho):
    """(mean, standard error) per channel of the photons' flux that enters the sphere (centre,
    rho): the rays from ``o`` along ``d`` that pass within rho of its centre, ahead of them."""
    q = np.asarray(centre) - o
    t = np.einsum("ij,ij->i", q, d)
    hit = (t > 0) & (np.einsum("ij,ij->i", q, q) - t * t < rho * rho)
    v = flux * hit[:, None]
    return v.mean(axis=0), v.std(axis=0) / math.sqrt(len(v))


@pytest.mark.parametrize("emitter", ("sun", "world"))
def test_focused_photons_from_afar_carry_the_same_light_into_any_sphere(emitter):
    """A :class:`Focus` starts half the sun's or the world's photons on its sphere's disc; their
    fluxes (the scene disc's density over the mixture's) keep every estimate exact.  The power
    entering spheres at the focus, across its edge and far from it (only the uniform half reaches
    that one) matches the closed form (sun: irradiance E times pi rho^2; a constant world:
    pi L over the sphere's 4 pi rho^2) within 5 standard errors, also for a focus that reaches past
    the scene's disc; every origin stays on the plane 2 R before the scene's centre."""
    power = np.array([3.0, 2.0, 1.0])
    axis = unit_vector(-0.2, 0.4, -1.0)
    ctx = afar_context(emitter, axis, power)
    rho = 0.3
    exact = power * (np.pi * rho ** 2 if emitter == "sun" else 4 * np.pi ** 2 * rho ** 2)
    u = np.random.default_rng(4095).random((N, 6))
    spheres = {"at the focus": BOX_CENTER + [0.5, 0.2, 0.0], "across its edge": BOX_CENTER + [0.5, 0.9, 0.0],
               "far from it": BOX_CENTER + [-0.8, -0.9, 0.3]}
    focuses = {"inside the scene": Focus(BOX_CENTER + [0.5, 0.2, 0.0], 0.7, 0.5),
               "past the scene's disc": Focus(BOX_HI, 1.5, 0.3)}
    for name, focus in focuses.items():
        o, d, flux, _ = ctx.lights.sample(u, focus)
        assert np.isfinite(flux).all() and (flux >= 0).all()
        assert np.allclose(np.einsum("ij,ij->i", o - BOX_CENTER, d), -2 * BOX_RADIUS, atol=1e-9)
        for where, centre in spheres.items():
            mean, se = power_into_sphere(o, d, flux, centre, rho)
            assert (np.abs(mean - exact) < 5 * se + 1e-12).all(), \
                f"{emitter}, focus {name}, sphere {where}: {mean} against {exact} (standard error {se})"
    # The focus pays where it aims: far more of the photons enter the sphere at it.
    plain = power_into_sphere(*ctx.lights.sample(u)[:3], spheres["at the focus"], rho)[1]
    aimed = power_into_sphere(*ctx.lights.sample(u, focuses["inside the scene"])[:3], spheres["at the focus"],
                              rho)[1]
    assert (aimed < 0.5 * plain).all(), f"{emitter}: standard error {aimed} aimed against {plain} not"


def power_through_window(o, d, flux, centre, u, v):
    """(mean, standard error) per channel of the photons' flux that crosses the parallelogram
    centre + a u + b v (|a|, |b| <= 1) along u x v, ahead of them."""
    n = np.cross(u, v)
    facing = d @ n
    t = ((np.asarray(centre) - o) @ n) / np.where(facing > 0, facing, 1.0)
    p = o + t[:, None] * d - centre
    a = np.linalg.lstsq(np.column_stack([u, v]), p.T, rcond=None)[0]
    hit = (facing > 0) & (t > 0) & (np.abs(a) <= 1.0).all(axis=0)
    f = flux * hit[:, None]
    return f.mean(axis=0), f.std(axis=0) / math.sqrt(len(f))


@pytest.mark.parametrize("emitter", ("sun", "world"))
def test_photons_from_afar_through_portals_carry_the_same_light_through_any_window(emitter):
    """A :class:`Focus` on light portals (:meth:`Focus.through`, Cycles' portals in windows) starts
    half the sun's or the world's photons where they pass through a portal, the portal chosen by
    its area projected across their direction; their fluxes keep every estimate exact.  The power
    crossing windows in the portal, partly in it and away from it (sun: irradiance E times the
    window's projected area; a constant world: pi L times its area) matches the closed form within
    5 standard errors for a rectangle, an ellipse, a portal facing the other way (only the uniform
    half brings that light) and two that overlap; through the portal the standard error is a third
    of the photons' without it or less."""
    power = np.array([3.0, 2.0, 1.0])
    axis = unit_vector(-0.9, 0.2, -0.4)
    ctx = afar_context(emitter, axis, power)
    # A window in the plane x = 1.2 across the box, light crossing it along -x (u x v).
    centre, u, v = np.array([1.2, -0.3, 0.4]), np.array([0.0, 0.0, 0.2]), np.array([0.0, 0.15, 0.0])
    windows = {"in the portal": (centre, u, v), "partly in it": (centre + [0, 0.2, 0.1], u, v),
               "away from it": (np.array([-0.5, 0.0, 0.9]), np.array([0.0, 0.1, 0.0]), np.array([0.2, 0, 0]))}
    portals = {"a rectangle": ([[centre, u, v]], [False]), "an ellipse": ([[centre, u, v]], [True]),
               "facing the other way": ([[centre, v, u]], [False]),
               "two that overlap": ([[centre, u, v], [centre + [0, 0.1, 0], u, v]], [False, False])}
    u01 = np.random.default_rng(4097).random((N, 6))
    for name, (frames, disks) in portals.items():
        focus = Focus.through(World(portals=np.array(frames), portal_disks=np.array(disks)), ctx.lights)
        assert focus is not None and focus.portal_count == len(frames)
        assert Focus.from_array(focus.to_array()).to_array().tolist() == focus.to_array().tolist()
        o, d, flux, _ = ctx.lights.sample(u01, focus)
        assert np.isfinite(flux).all() and (flux >= 0).all()
        assert np.allclose(np.einsum("ij,ij->i", o - BOX_CENTER, d), -2 * BOX_RADIUS, atol=1e-9)
        for where, (c, wu, wv) in windows.items():
            area = 4.0 * np.linalg.norm(np.cross(wu, wv))
            across = np.cross(wu, wv) / np.linalg.norm(np.cross(wu, wv))
            exact = power * (area * max(float(axis @ across), 0.0) if emitter == "sun" else np.pi * area)
            mean, se = power_through_window(o, d, flux, c, wu, wv)
            assert (np.abs(mean - exact) < 5 * se + 1e-12).all(), \
                f"{emitter}, portals {name}, window {where}: {mean} against {exact} (standard error {se})"
    plain = power_through_window(*ctx.lights.sample(u01)[:3], centre, u, v)[1]
    one = World(portals=np.array([[centre, u, v]]), portal_disks=np.array([False]))
    focus = Focus.through(one, ctx.lights)
    aimed = power_through_window(*ctx.lights.sample(u01, focus)[:3], centre, u, v)[1]
    assert (aimed < plain / 3).all(), f"{emitter}: standard error {aimed} through the portal against {plain}"
    assert Focus.through(World(), ctx.lights) is None
    point = light_context([{"kind": "point", "position": BOX_CENTER, "power": 1.0}]).lights
    assert Focus.through(one, point) is None


def test_focus_covers_the_points_where_it_pays_and_stays_off_elsewhere():
    """:meth:`Focus.around` picks the sphere around most of the points that lowers the modelled
    variance most: a tight cluster with a few far points (a glass ball's reflections) gets a sphere
    around the cluster and most of the rest; points all over the scene, no points, and a scene
    without the sun or the world get none."""
    sun = light_context([{"kind": "sun", "direction": (0, 0, -1), "power": 1.0}]).lights
    rng = np.random.default_rng(4096)
    cluster = BOX_CENTER + 0.05 * rng.standard_normal((2000, 3))
    far = BOX_LO + (BOX_HI - BOX_LO) * rng.random((10, 3))
    focus = Focus.around(np.vstack([cluster, far]), np.full(2010, 0.01), sun)
    assert focus is not None and focus.uniform_share == 0.5
    assert np.linalg.norm(focus.center - BOX_CENTER) < 0.02
    inside = np.linalg.norm(np.vstack([cluster, far]) - focus.center, axis=1) <= focus.radius
    assert inside[:2000].all() and focus.radius < 0.5 * BOX_RADIUS
    spread = BOX_LO + (BOX_HI - BOX_LO) * rng.random((2000, 3))
    assert Focus.around(spread, np.full(2000, 0.01), sun) is None
    assert Focus.around(np.zeros((0, 3)), np.zeros(0), sun) is None
    point = light_context([{"kind": "point", "position": BOX_CENTER, "power": 1.0}]).lights
    assert Focus.around(cluster, np.full(2000, 0.01), point) is None


def test_emissive_triangles_emit_two_pi_area_radiance_from_both_sides_by_area():
    emission = np.array([1.0, 2.0, 0.5])
    # Triangle A in the plane z = 0.25 (area 0.5), triangle B in the plane x = 0.5 (area 0.75).
    tri_a = np.array([[0.0, 0.0, 0.25], [1.0, 0.0, 0.25], [0.0, 1.0, 0.25]])
    tri_b = np.array([[0.5, -1.0, 0.0], [0.5, 0.5, 0.0], [0.5, -1.0, 1.0]])
    area_a, area_b = 0.5, 0.75
    ctx = light_context(emissive_triangles=[tri_a, tri_b], emission=emission)
    o, d, flux, normals = sample_photons(ctx, N, 4050)
    assert_mean_flux(flux, TWO_PI * (area_a + area_b) * emission, "emissive triangles")
    assert np.allclose(flux, TWO_PI * (area_a + area_b) * emission, rtol=1e-6)   # same radiance
    on_a = np.abs(normals[:, 2]) > 0.5
    on_b = np.abs(normals[:, 0]) > 0.5
    assert (on_a ^ on_b).all()
    assert_binomial(int(on_a.sum()), N, area_a / (area_a + area_b), "choice of triangle A")
    # Triangle A: sides equally likely, directions cosine about the chosen side's normal.
    da, na = d[on_a], normals[on_a]
    ng = np.array([0.0, 0.0, 1.0])
    assert np.allclose(np.abs(na @ ng), 1.0, atol=1e-12)
    assert (np.sum(da * na, axis=1) >= 0).all()
    assert_binomial(int((na @ ng > 0).sum()), len(na), 0.5, "front side of triangle A")
    check_chi2(lambda n: (dir_to_cos_phi(da, ng), None), lambda xy: np.abs(xy[:, 0]) / TWO_PI, SPHERE,
               sample_count=len(da))
    # Triangle B: positions uniform (barycentrics from the origin, minus the normal offset).
    ob = o[on_b]
    assert np.allclose(ob[:, 0], 0.5, atol=1e-5)
    e1, e2 = tri_b[1] - tri_b[0], tri_b[2] - tri_b[0]
    b1 = (ob - tri_b[0]) @ e1 / (e1 @ e1)
    b2 = (ob - tri_b[0]) @ e2 / (e2 @ e2)                   # e1 is perpendicular to e2
    assert ((b1 >= -1e-9) & (b2 >= -1e-9) & (b1 + b2 <= 1 + 1e-9)).all()
    v = np.clip(b2 / np.maximum(1.0 - b1, 1e-300), 0, 1)
    check_chi2(lambda n: (np.stack([np.clip(b1, 0, 1), v], axis=1), None),
               lambda xy: 2.0 * (1.0 - xy[:, 0]), UNIT_SQUARE, sample_count=len(ob))


def test_mixed_lights_each_receive_photons_carrying_their_own_power():
    """Point, spot, area and sun together: per emitter, the summed flux / N equals its power
    (one chi-square over the photon counts per emitter, fixed 1 % tolerance on the powers)."""
    lights = [{"kind": "point", "position": (-0.5, 0.0, 0.0), "power": (5.0, 5.0, 5.0)},
              {"kind": "spot", "position": (1.5, 0.0, 0.0), "direction": (0, 0, -1),
               "power": (40.0, 10.0, 10.0), "spot_angle": 1.0, "spot_blend": 0.5},
              {"kind": "area", "position": (0.0, 0.5, 1.0), "direction": (0, 0, -1), "size": 0.5,
               "power": (20.0, 20.0, 20.0)},
              {"kind": "sun", "direction": (0, 0, -1), "power": (0.5, 0.5, 0.5)}]
    ctx = light_context(lights)
    o, d, flux, _ = sample_photons(ctx, N, 4060)
    ids = np.full(N, -1)
    ids[np.linalg.norm(o - [-0.5, 0.0, 0.0], axis=1) < 1e-9] = 0
    ids[np.linalg.norm(o - [1.5, 0.0, 0.0], axis=1) < 1e-9] = 1
    ids[np.abs(o[:, 2] - 1.0) < 1e-9] = 2
    ids[np.abs(o[:, 2] - (BOX_CENTER[2] + 2 * BOX_RADIUS)) < 1e-6] = 3
    assert (ids >= 0).all()
    cos_half = math.cos(float(np.float32(1.0)) / 2)
    powers = np.array([[5.0] * 3, np.array([40.0, 10.0, 10.0]) / 2 * (1 - cos_half) * 0.75, [20.0] * 3,
                       [0.5 * np.pi * BOX_RADIUS ** 2] * 3])
    lum = powers @ [0.2126, 0.7152, 0.0722]
    counts = np.bincount(ids, minlength=4)
    expected = N * lum / lum.sum()
    assert chi2_sf(float(np.sum((counts - expected) ** 2 / expected)), 3) >= ALPHA_EACH, (counts, expected)
    for k in range(4):
        share = flux[ids == k].sum(axis=0) / N
        assert np.allclose(share, powers[k], rtol=0.01), (k, share, powers[k])
    assert_mean_flux(flux, powers.sum(axis=0), "all lights")


def test_zero_power_lights_and_black_or_degenerate_emitters_are_never_chosen():
    lights = [{"kind": "point", "position": (0.0, 0.0, 0.0), "power": 0.0},
              {"kind": "spot", "position": (1.0, 0.0, 0.0), "power": 0.0},
              {"kind": "area", "position": (0.0, 0.5, 1.0), "direction": (0, 0, -1), "size": 0.5,
               "power": 5.0},
              {"kind": "sun", "direction": (0, 0, -1), "power": 0.0},
              {"kind": "disk", "position": (0.0, -0.5, 1.0), "direction": (0, 0, -1), "power": 0.0}]
    degenerate = np.array([[0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [2.0, 0.0, 0.5]])      # zero area
    ctx = light_context(lights, emissive_triangles=[degenerate], emission=(3.0, 3.0, 3.0))
    o, d, flux, normals = sample_photons(ctx, 100_000, 4070)
    assert np.allclose(o[:, 2], 1.0, atol=1e-9) and (np.abs(o[:, 1] - 0.5) <= 0.25 + 1e-9).all()
    assert np.allclose(flux, 5.0, rtol=1e-9)
    assert (normals == 0).all()


def test_photon_directions_are_unit_to_float64_precision():
    """``LightSampler.sample`` documents ``directions (n, 3) float64 unit``, for every light kind."""
    direction = unit_vector(0.3, -0.7, -0.5)
    contexts = {kind: light_context([{"kind": kind, "position": (0.1, 0.2, 0.3), "direction": direction,
                                      "power": 1.0, "sun_angle": 0.1, "spot_angle": 1.0, "size": 0.5}])
                for kind in ("point", "spot", "area", "disk", "sun")}
    contexts["world"] = light_context(world=(1.0, 1.0, 1.0))
    triangle = np.array([[0.0, 0.0, 0.3], [0.7, 0.1, 0.5], [0.0, 1.0, 0.0]])
    contexts["triangle"] = light_context(emissive_triangles=[triangle])
    errors = {}
    for kind, ctx in contexts.items():
        _, d, _, _ = ctx.lights.sample(np.random.default_rng(4090).random((10_000, 6)))
        errors[kind] = float(np.abs(np.linalg.norm(d, axis=1) - 1.0).max())
    bad = {k: v for k, v in errors.items() if not v < 1e-12}
    assert not bad, f"photon directions deviate from unit length by {bad}"


@pytest.mark.parametrize("case", ("no lights", "all zero"))
def test_no_emitters_give_zero_flux_without_nan(case):
    if case == "no lights":
        ctx = light_context()
    else:
        ctx = light_context([{"kind": "point", "power": 0.0}, {"kind": "sun", "power": 0.0}],
                            emissive_triangles=[np.array([[0, 0, 0.5], [1, 0, 0.5], [0, 1, 0.5]])],
                            emission=(0.0, 0.0, 0.0))
    assert ctx.lights.count == 0
    o, d, flux, normals = sample_photons(ctx, 1000, 4080)
    assert (flux == 0).all() and (normals == 0).all()
    o, d, flux, normals = ctx.lights.sample(np.zeros((0, 6)))
    assert flux.shape == (0, 3)


# ================================================================ 6. MCMC mutation
def mutation_cdf(x, theta):
    """CDF of the step k(x) = theta / (2 (1 + theta)) |x|^(-1 / (1 + theta)) on (-1, 1)."""
    x = np.asarray(x, np.float64)
    return 0.5 + 0.5 * np.sign(x) * np.abs(x) ** (theta / (1.0 + theta))


@pytest.mark.parametrize("theta_kind", ("small", "mixed"))
def test_mutation_chain_under_constant_target_keeps_uniform_marginals(theta_kind):
    rng = np.random.default_rng(5000 if theta_kind == "small" else 5001)
    chains, dims, steps = N // 2, 4, 16
    u = rng.random((chains, dims))
    if theta_kind == "small":
        theta = np.full(chains, 0.02)
    else:
        theta = 10.0 ** rng.uniform(np.log10(mcmc.THETA_MIN), np.log10(mcmc.THETA_MAX), chains)
    for _ in range(steps):
        u = mcmc.mutate(u, theta, rng)           # constant target: every proposal is accepted
        assert ((u >= 0) & (u < 1)).all()
    pairs = np.concatenate([u[:, 0:2], u[:, 2:4]])
    check_chi2(lambda n: (pairs, None), lambda xy: np.ones(len(xy)), UNIT_SQUARE)


@pytest.mark.parametrize("theta", MUTATION_THETAS)
def test_mutation_step_before_wrapping_has_density_k_and_mean_abs_theta_over_1_plus_2theta(
        theta, monkeypatch):
    monkeypatch.setattr(mcmc, "wrap_unit", lambda x: x)     # observe u + step before the wrap
    rng = np.random.default_rng(5010 + MUTATION_THETAS.index(theta))
    n = N // 2
    step = mcmc.mutate(np.zeros((n, 2)), np.full(n, theta), rng)       # u = 0: the result is the step
    assert ((step > -1) & (step < 1)).all()
    q = theta / (1.0 + theta)
    # Histogram of y = sign(step) |step|^q (the steps' own CDF scale); expected counts are CDF
    # differences of k at the corresponding step edges: the test compares with k itself.
    y = np.sign(step) * np.abs(step) ** q

    def bin_probabilities(ex, ey):
        sx = np.sign(ex) * np.abs(ex) ** (1 / q)
        sy = np.sign(ey) * np.abs(ey) ** (1 / q)
        return np.outer(np.diff(mutation_cdf(sx, theta)), np.diff(mutation_cdf(sy, theta)))

    check_chi2(lambda m: (y.reshape(-1, 2), None), None, ((-1.0, 1.0), (-1.0, 1.0)), sample_count=n,
               bin_probabilities=bin_probabilities)
    expected_abs = theta / (1 + 2 * theta)
    var = theta / (3 + 2 * theta) - expected_abs ** 2
    mean_abs = np.abs(step).mean()
    z = (mean_abs - expected_abs) / math.sqrt(var / step.size)
    assert abs(z) < Z_CRIT, (mean_abs, expected_abs, z)


def test_wrapped_mutation_from_zero_has_the_folded_step_density():
    theta = 0.5
    rng = np.random.default_rng(5020)
    n = N // 2
    u = mcmc.mutate(np.zeros((n, 2)), np.full(n, theta), rng)
    assert ((u >= 0) & (u < 1)).all()

    def folded(e):                  # P(wrap(step) < x) = F(x) - F(0) + F(x - 1) - F(-1), x in [0, 1]
        return mutation_cdf(e, theta) - 0.5 + mutation_cdf(e - 1.0, theta)

    check_chi2(lambda m: (u, None), None, UNIT_SQUARE, sample_count=n,
               bin_probabilities=lambda ex, ey: np.outer(np.diff(folded(ex)), np.diff(folded(ey))))


def test_mutation_at_the_theta_clamps_stays_finite_and_in_unit_interval():
    rng = np.random.default_rng(5030)
    u = np.concatenate([rng.random((1000, 3)), [[0.0, np.nextafter(1, 0), 0.5]]])
    for theta in (mcmc.THETA_MIN, mcmc.THETA_MAX):
        v = mcmc.mutate(u, np.full(len(u), theta), rng)
        assert np.isfinite(v).all() and ((v >= 0) & (v < 1)).all()


@pytest.mark.parametrize("dtype", (np.float32, np.float64))
def test_wrap_unit_maps_tiny_negatives_and_values_just_below_one_into_unit_interval(dtype):
    below_one = np.nextafter(dtype(1), dtype(0))
    x = np.array([-1e-9, -1e-20, 1 - 1e-12, -0.0, 0.0, 1.0, -1.0, 2.5, -3.25, 0.3, below_one, -below_one,
                  -np.finfo(dtype).tiny], dtype)
    y = mcmc.wrap_unit(x.copy())
    assert y.dtype == dtype
    assert ((y >= 0) & (y < 1)).all(), y
    assert (y != 1.0).all()
    # Where x mod 1 is representable below 1 it is kept (within one rounding).
    exact = np.mod(x.astype(np.float64), 1.0)
    keep = exact.astype(dtype) < 1
    assert np.allclose(y[keep], exact[keep], atol=2 * np.finfo(dtype).eps)
    if dtype == np.float64:
        assert y[0] == pytest.approx(1 - 1e-9, abs=1e-16)
        assert y[2] == pytest.approx(1 - 1e-12, abs=1e-16)


def test_environment_image_convention_density_and_integral():
    """Cycles' equirectangular convention (+X the image centre, +Z the top row, +Y a quarter
    from the left), the density of the sampled directions equal to pdf(), and the flux
    weights L / pdf averaging to the integral of the radiance (a z-test per channel)."""
    from core.environment import Environment
    rng = np.random.default_rng(2060)
    tex = (rng.random((8, 16, 3)) ** 3).astype(np.float32)
    env = Environment(np.array([1.0, 2.0, 0.5]), tex)
    u, v = env.uv(np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0, 0, -1.0]]))
    assert u[:2] == pytest.approx([0.5, 0.25]) and v[2:] == pytest.approx([1.0, 0.0])
    # Radiance at a pixel centre is that pixel's value (bilinear weights 1 there).
    phi, theta = np.pi - 2 * np.pi * (5.5 / 16), np.pi * (1 - 3.5 / 8)
    d = np.array([[np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]])
    assert env.radiance(d)[0] == pytest.approx(tex[3, 5] * np.array([1.0, 2.0, 0.5]), rel=1e-6)
    n = 400_000
    d, pdf = env.sample(rng.random(n), rng.random(n))
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0) and np.allclose(env.pdf(d), pdf, rtol=1e-9)
    w = env.radiance(d) / pdf[:, None]
    # Turned by R, the image is looked up at R d and sampled directions come back as R^T d_image.
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    turned = Environment(np.array([1.0, 2.0, 0.5]), tex, rot)
    dirs = rng.normal(size=(1000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    assert np.allclose(turned.radiance(dirs), env.radiance(dirs @ rot.T))
    d_t, pdf_t = turned.sample(rng.random(1000), rng.random(1000))
    assert np.allclose(turned.pdf(d_t), pdf_t, rtol=1e-9) and np.allclose(turned.integral, env.integral)
    for c in range(3):
        assert_mean(w[:, c], env.integral[c], f"environment integral, channel {c}",
                    extra_tolerance=0.01 * env.integral[c])


def test_valid_reflection_normal_keeps_the_view_reflection_above_the_surface():
    """Cycles' ensure_valid_specular_reflection: unchanged where the mirror direction of the view
    is above the surface, else tilted towards ng, in the plane of n and ng, just enough."""
    rng = np.random.default_rng(4)
    k = 20000
    ng = np.tile([0.0, 0.0, 1.0], (k, 1))
    i = rng.normal(size=(k, 3))
    i[:, 2] = np.abs(i[:, 2]) + 1e-3
    i /= np.linalg.norm(i, axis=1, keepdims=True)
    n = rng.normal(size=(k, 3))
    n[:, 2] = np.abs(n[:, 2]) + 0.2
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    out = bsdf.valid_reflection_normal(ng, i, n)

    def reflect_z(m):
        return (2 * np.einsum("ki,ki->k", m, i)[:, None] * m - i)[:, 2]

    threshold = np.minimum(0.9 * i[:, 2], 0.01)
    was_valid = reflect_z(n) >= threshold
    assert 0.05 < was_valid.mean() < 0.95                       # both cases occur
    np.testing.assert_array_equal(out[was_valid], n[was_valid])
    fixed = ~was_valid
    np.testing.assert_allclose(np.linalg.norm(out[fixed], axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(reflect_z(out)[fixed], threshold[fixed], atol=1e-6)   # just enough
    plane = np.cross(n[fixed], ng[fixed])
    np.testing.assert_allclose(np.einsum("ki,ki->k", plane, out[fixed]), 0.0, atol=1e-9)


@pytest.mark.parametrize("roughness", [0.3, 0.6, 1.0])
@pytest.mark.parametrize("outside", [True, False])
def test_multiscatter_glass_keeps_all_the_light_it_scatters(roughness, outside):
    """Cycles' Multiscatter GGX glass (stop 45, ``dielectric_multiscatter`` F_ss = 1): camera paths
    scatter off a white rough glass with mean weight 1 from outside and inside, at 0, 45 and 75
    degrees (within 4 standard errors and the tables' 3e-3); single-scattering glass loses the
    albedo's shortfall (``ggx_glass_albedo``, up to half the light inside at roughness 1), which
    its own mean shows.  A grey one (F_ss 0.5) keeps 1 + F_ms (1 - E) / E of E."""
    ior = 1.5
    n_ = unit_vector(0.1, 0.2, 0.95)
    ng = n_ if outside else -n_
    f = frames_for(n_)[0]
    rng = np.random.default_rng(7)
    n = 200_000
    for theta in (0.0, 45.0, 75.0):
        wo = local_direction(theta) @ f
        means = {}
        for name, spec in (("single", {}), ("white", {"dielectric_multiscatter": 1.0}),
                           ("grey", {"dielectric_multiscatter": 0.5})):
            colour = 0.5 if name == "grey" else 1.0
            table = material_table({"dielectric": colour, "ior": ior, "dielectric_roughness": roughness,
                                    **spec})
            m_ = np.zeros(n, np.int32)
            colors = bsdf.lobe_colors(table, m_, table.color[m_, bsdf.DIFFUSE])
            _, w, _ = bsdf.scatter(table, m_, colors, np.full(n, bsdf.DIELECTRIC), np.ones(n),
                                   np.tile(wo, (n, 1)), np.tile(ng, (n, 1)), np.tile(ng, (n, 1)),
                                   rng.random(n), rng.random(n), "radiance", rng.random(n))
            means[name] = (w[:, 0].mean(), w[:, 0].std() / np.sqrt(n))
        mu = abs(np.cos(np.radians(theta)))
        e = smp.ggx_glass_albedo(roughness ** 2, np.array([mu]), ior if outside else 1.0 / ior)[0]
        (single, s_err), (white, w_err), (grey, g_err) = means["single"], means["white"], means["grey"]
        assert abs(single - e) < 4.0 * s_err + 3e-3, (theta, single, e)
        assert abs(white - 1.0) < 4.0 * w_err + 3e-3, (theta, white)
        mus = (np.arange(bsdf.MS_NODES + 1) / bsdf.MS_NODES) ** 2
        e_nodes = smp.ggx_glass_albedo(roughness ** 2, mus, ior if outside else 1.0 / ior)
        e_avg = 2.0 * np.trapz(e_nodes * mus, mus)
        f_ms = 0.5 * e_avg / (1.0 - 0.5 * (1.0 - e_avg))
        want = 0.5 * e * (1.0 + f_ms * (1.0 - e) / e)
        assert abs(grey - want) < 4.0 * g_err + 3e-3, (theta, grey, want)


def assert_uniform_in_every_pass(numbers, dims):
    """``numbers(pass, pixel ids)``, (n, dims) in [0, 1), are uniform over 40,000 pixels in passes
    0, 1 and 999: a chi-square over 10 x 10 cells of each pair of neighbouring columns at the
    1e-4 level."""
    from stats_utils import chi2_sf
    pixels = np.arange(40_000)
    for k in (0, 1, 999):
        u = numbers(k, pixels)
        assert u.shape == (40_000, dims) and (u >= 0).all() and (u < 1).all()
        for a in range(dims - 1):
            counts = np.histogram2d(u[:, a], u[:, a + 1], bins=10, range=[[0, 1], [0, 1]])[0]
            stat = ((counts - 400.0) ** 2 / 400.0).sum()
            assert chi2_sf(stat, 99) > 1e-4, (k, a, stat)


def test_stratified_jitter_is_uniform_in_every_pass_and_even_in_every_pixel():
    """``camera.stratified_jitter`` (RenderSettings.pixel_jitter): over 40,000 pixels one pass's
    numbers are uniform (a chi-square over 10 x 10 cells at the 1e-4 level, in passes 0, 1 and
    999) and differ from pixel to pixel; one pixel's first 64 passes put exactly 4 in each of 16
    cells and one in each of 64 strips across either axis (a (0, 6, 2)-net; independent numbers: a
    binomial of mean 4 and spread 1.9 in a cell); 8 passes in a row from pass 8 one in each of 8
    strips; the same salt, pass and pixel give the same numbers, another salt others."""
    from core.camera import stratified_jitter
    pixels = np.arange(40_000)
    assert_uniform_in_every_pass(lambda k, pix: stratified_jitter(12345, k, pix), 2)
    assert len(np.unique(stratified_jitter(12345, 3, pixels)[:, 0])) > 39_000
    for pixel in (0, 7, 123_456):
        u = np.array([stratified_jitter(12345, k, np.array([pixel]))[0] for k in range(64)])
        np.testing.assert_array_equal(np.histogram2d(u[:, 0], u[:, 1], bins=4, range=[[0, 1], [0, 1]])[0], 4)
        for axis in (0, 1):
            np.testing.assert_array_equal(np.histogram(u[:, axis], bins=64, range=(0, 1))[0], 1)
            np.testing.assert_array_equal(np.histogram(u[8:16, axis], bins=8, range=(0, 1))[0], 1)
    np.testing.assert_array_equal(stratified_jitter(5, 3, pixels[:10]), stratified_jitter(5, 3, pixels[:10]))
    assert not np.allclose(stratified_jitter(5, 3, pixels[:10]), stratified_jitter(6, 3, pixels[:10]))


def test_stratified_lens_and_lobe_numbers_are_uniform_in_every_pass_and_even_with_the_jitter():
    """``camera.stratified_lens`` (depth of field): over 40,000 pixels one pass's lens numbers are
    uniform (a chi-square over 10 x 10 cells at the 1e-4 level, passes 0, 1 and 999); one pixel's
    first 64 passes put one in each of 64 strips across either axis and 4 in each of 16 cells and,
    paired with the same passes' pixel jitter (``stratified_jitter``, another salt), one in each of
    the 8 x 8 cells of every (pixel axis, lens axis) pair: the 4-dimensional Sobol sequence (random
    numbers fill about 41 of those 64 cells; the jitter's own (0, 2)-sequence taken for the lens as
    well would tie the lens to the pixel point and fill 8).  ``sampling.sobol`` of dimensions 3 to
    7: its points at the Gray codes of 0 to 7 are those of SciPy's unscrambled ``qmc.Sobol(7)``
    (which runs in Gray-code order; all 4,096 first points checked when written).  The first
    surface's lobe numbers (``camera.stratified_choices``, dimensions 5 to 7) are uniform in every
    pass, one in each of 64 strips over a pixel's 64 passes, and the first of them (non-delta or
    delta) paired with either pixel axis one in each 8 x 8 cell."""
    from core.camera import stratified_choices, stratified_jitter, stratified_lens
    scipy_first = [(0, 0, 0, 0, 0), (4, 4, 4, 4, 4), (2, 2, 6, 6, 2), (6, 6, 2, 2, 6), (5, 7, 3, 1, 3),
                   (1, 3, 7, 5, 7), (7, 5, 5, 7, 1), (3, 1, 1, 3, 5)]                    # eighths
    assert [smp.sobol(i ^ (i >> 1), (3, 4, 5, 6, 7)) for i in range(8)] == [tuple(a << 29 for a in p)
                                                                          for p in scipy_first]
    pixels = np.arange(40_000)
    assert_uniform_in_every_pass(lambda k, pix: stratified_lens(777, k, pix), 2)
    assert_uniform_in_every_pass(lambda k, pix: stratified_choices(555, k, pix), 3)
    for pixel in (0, 7, 123_456):
        lens = np.array([stratified_lens(777, k, np.array([pixel]))[0] for k in range(64)])
        jitter = np.array([stratified_jitter(12345, k, np.array([pixel]))[0] for k in range(64)])
        cells = np.histogram2d(lens[:, 0], lens[:, 1], bins=4, range=[[0, 1], [0, 1]])[0]
        np.testing.assert_array_equal(cells, 4)
        for a in (0, 1):
            np.testing.assert_array_equal(np.histogram(lens[:, a], bins=64, range=(0, 1))[0], 1)
            for b in (0, 1):
                cells = np.histogram2d(jitter[:, a], lens[:, b], bins=8, range=[[0, 1], [0, 1]])[0]
                np.testing.assert_array_equal(cells, 1, err_msg=f"pixel {pixel}, axes {a} and {b}")
        choice = np.array([stratified_choices(555, k, np.array([pixel]))[0] for k in range(64)])
        for c in range(3):
            np.testing.assert_array_equal(np.histogram(choice[:, c], bins=64, range=(0, 1))[0], 1)
        for a in (0, 1):
            cells = np.histogram2d(jitter[:, a], choice[:, 0], bins=8, range=[[0, 1], [0, 1]])[0]
            np.testing.assert_array_equal(cells, 1)
    np.testing.assert_array_equal(stratified_lens(5, 3, pixels[:10]), stratified_lens(5, 3, pixels[:10]))
    assert not np.allclose(stratified_lens(5, 3, pixels[:10]), stratified_lens(6, 3, pixels[:10]))


def test_stratified_light_numbers_are_uniform_in_every_pass_and_fill_a_pixels_strata():
    """``direct.stratified_light`` (light samples, RenderSettings.pixel_jitter): over 40,000 pixels
    one pass's numbers of any sample are uniform (a chi-square over 10 x 10 cells of neighbouring
    columns at the 1e-4 level, passes 0, 1 and 999).  One pixel's 64 samples of its first 16
    passes (4 a pass) put one point on the light in each of 64 strips across either axis and 4 in
    each of 16 cells (a (0, 6, 2)-net; independent numbers: a binomial of mean 4 and spread 1.9),
    and one emitter choice in each of 64 strips; each pass's 4 samples lie in the 4 quarters of
    either axis.  ``sampling.owen_scramble`` maps each aligned block of 2^k integers onto another, a
    different one and in another order for another seed; ``sampling.sobol_points`` is
    ``sobol_02`` and ``sobol`` for any index.  ``direct.point_keys``: a pixel's, times 64, or
    with the rank among the pixel's points where it has several."""
    from core.camera import stratified_jitter
    from core.direct import point_keys, stratified_light

    def third_sample(k, pix):
        return stratified_light(99, k, 4, pix * 64)(pix, np.full(len(pix), 3))
    assert_uniform_in_every_pass(third_sample, 4)
    for pixel in (0, 7, 123_456):
        u = np.concatenate([stratified_light(99, k, 4, np.array([pixel * 64]))(np.zeros(4, int), np.arange(4))
                            for k in range(16)])
        np.testing.assert_array_equal(np.histogram2d(u[:, 1], u[:, 2], bins=4, range=[[0, 1], [0, 1]])[0], 4)
        for axis in (0, 1, 2):
            np.testing.assert_array_equal(np.histogram(u[:, axis], bins=64, range=(0, 1))[0], 1)
        for axis in (1, 2):
            quarters = np.floor(u[:, axis].reshape(16, 4) * 4)
            np.testing.assert_array_equal(np.sort(quarters, axis=1), np.tile(np.arange(4.0), (16, 1)))
    # Paired with the pixel jitter at random: a penumbra across the pixel and the light, 1[x + y < 1]
    # (x the jitter's first number, y the light's), one sample a pass, 4,000 pixels' RMS error after
    # 64 passes below independent numbers' (measured 0.042 against 0.051; the light's points shifted
    # per pixel instead of scrambled, 0.062: tied to the jitter).
    pixels = np.arange(4000)
    x = np.stack([stratified_jitter(5, k, pixels)[:, 0] for k in range(64)], axis=1)
    one = np.zeros(4000, int)
    y = np.stack([stratified_light(6, k, 1, pixels * 64)(pixels, one)[:, 1] for k in range(64)], axis=1)
    independent = np.random.default_rng(3).random((4000, 64))
    rms = [np.sqrt(np.mean(((x + v < 1).mean(axis=1) - 0.5) ** 2)) for v in (y, independent)]
    assert rms[0] < 0.9 * rms[1], rms
    index = np.arange(1 << 12)
    a, b = smp.owen_scramble(index, np.full(len(index), 7)), smp.owen_scramble(index, np.full(len(index), 8))
    for k in (1, 3, 8):
        for o in (a, b):
            blocks = o.reshape(-1, 1 << k) >> np.uint32(k)
            assert (blocks == blocks[:, :1]).all() and len(np.unique(blocks[:, 0])) == len(blocks)
    assert not (a == b).all() and not (a == index).all() and len(np.unique(a)) == len(index)
    some = np.array([0, 1, 5, 1000, 123_456_789, (1 << 32) - 1])
    assert smp.sobol_points(some, (1, 2, 3, 7)).tolist() == [
        list(smp.sobol_02(int(i)) + smp.sobol(int(i), (3, 7))) for i in some]
    np.testing.assert_array_equal(point_keys(np.array([2, 5, 9])), [128, 320, 576])
    np.testing.assert_array_equal(point_keys(np.array([5, 2, 5, 9, 5])), [320, 128, 321, 576, 322])

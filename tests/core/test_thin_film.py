"""Thin-film iridescence (stop 43, ``core/thin_film.py``, ``Materials.film_thickness``).

The references here are independent of the Fourier-space method the core uses (Cycles'): the
exact Airy reflectance of the film per wavelength, r = (r12 + r23 e^(i phi)) / (1 + r12 r23
e^(i phi)) for s and p light, integrated against the colour matching functions at 1 nm and
taken to linear Rec. 709 with each channel's functions normalised to 1.
"""
from __future__ import annotations

import numpy as np
import pytest

from core import thin_film
from core.bsdf import DIELECTRIC, GLOSSY, MIRROR, MaterialTable, lobe_scores, scatter
from core.procedural import CIE_XYZ, XYZ_TO_RGB
from core.sampling import fresnel_dielectric
from core.scene import Materials, Scene, SceneError

from test_metal_fresnel import floor_scene, render_mean

TABLE = thin_film.sensitivity_table()
GOLD = (np.array([0.18, 0.42, 1.37]), np.array([3.42, 2.35, 1.77]))       # (Blender's conductor defaults)


def spectral_reflectance(cos1, thickness, n_film, eta):
    """(3,) the exact film reflectance integrated over wavelength (see the module docstring)."""
    lam = np.arange(380.0, 781.0, 1.0)
    cmf = np.stack([np.interp(lam, np.arange(380.0, 781.0, 5.0), CIE_XYZ[:, c]) for c in range(3)],
                   axis=1) @ XYZ_TO_RGB.T
    s1 = np.sqrt(1.0 - cos1 ** 2)
    c2 = np.sqrt(1.0 - (s1 / n_film) ** 2)
    c3 = np.sqrt(1.0 - (s1 / eta) ** 2 + 0j)
    phase = np.exp(4j * np.pi * n_film * thickness * c2 / lam)
    total = 0.0
    n1, n2, n3 = 1.0, n_film, eta
    s_waves = ((n1 * cos1 - n2 * c2) / (n1 * cos1 + n2 * c2), (n2 * c2 - n3 * c3) / (n2 * c2 + n3 * c3))
    p_waves = ((n2 * cos1 - n1 * c2) / (n2 * cos1 + n1 * c2), (n3 * c2 - n2 * c3) / (n3 * c2 + n2 * c3))
    for r12, r23 in (s_waves, p_waves):
        total = total + 0.5 * np.abs((r12 + r23 * phase) / (1.0 + r12 * r23 * phase)) ** 2
    # (a pure film colour may lie outside Rec. 709: clamped to [0, 1], as Cycles' saturate)
    return np.clip((total[:, None] * cmf).sum(axis=0) / cmf.sum(axis=0), 0.0, 1.0)


@pytest.mark.parametrize("thickness", [50.0, 250.0, 500.0, 900.0, 2500.0])
@pytest.mark.parametrize("n_film, eta", [(1.33, 1.5), (1.4, 1.0), (1.8, 1.45)])
def test_the_fourier_series_matches_the_spectral_integral(thickness, n_film, eta):
    """At five angles down to 85 degrees: within 2e-3 (measured up to 4e-4), though the film's
    colour differs by more than 0.02 between them and between channels.  The series stops after
    three orders as Cycles' does, which a free film (``eta`` 1: no layer under it) shows near
    grazing, where its two faces reflect much alike (off the exact colour by up to 0.008 at 75
    degrees and 0.06 at 85, measured): there, down to 60 degrees."""
    cos = np.array([1.0, 0.8, 0.5, 0.25, 0.08]) if eta > 1.0 else np.array([1.0, 0.8, 0.5])
    got = thin_film.reflectance(TABLE, cos, thickness, n_film, eta)
    want = np.array([spectral_reflectance(c, thickness, n_film, eta) for c in cos])
    np.testing.assert_allclose(got, want, atol=2e-3)
    assert np.ptp(want) > 0.02                # (the film's colour does change, by angle and channel)


def test_the_table_is_one_at_zero_path_and_fades_far_out():
    """Each channel's sensitivity integrates its functions to 1 (OPD 0) and has all but faded
    (under 1 %) at the table's end, 9.5 um, where the table holds its last value."""
    np.testing.assert_allclose(TABLE[0], 1.0)
    assert (np.abs(TABLE[-1]) < 0.01).all()
    far = thin_film.sensitivity(TABLE, np.array([9000.0, 60000.0, 1e9]))
    np.testing.assert_allclose(far[1:], np.repeat(TABLE[-1:], 2, axis=0))


def test_a_vanishing_film_leaves_the_bare_layer_and_grows_continuously():
    """Below 1 nm the film's index blends to 1 (Cycles): at 0 nm the layer's own Fresnel
    reflectance, and no jump at 1 nm; total internal reflection in the film reflects all."""
    cos = np.linspace(0.05, 1.0, 9)
    bare, _ = fresnel_dielectric(cos, 1.5)
    np.testing.assert_allclose(thin_film.reflectance(TABLE, cos, 0.0, 1.33, 1.5),
                               np.repeat(bare[:, None], 3, 1), atol=1e-12)
    below, at = (thin_film.reflectance(TABLE, cos, d, 1.33, 1.5) for d in (1.0 - 1e-6, 1.0))
    np.testing.assert_allclose(below, at, atol=1e-5)
    np.testing.assert_allclose(thin_film.reflectance(TABLE, np.array([0.3]), 300.0, 0.8, 1.5), 1.0)


def test_the_specular_tint_scales_the_film_towards_its_colour():
    """Cycles' rule: F mix(1, f0 t / F0, saturate((F - 1) / (F0 - 1))): untinted the film alone;
    tinted, where the film reflects F0 exactly the tinted F0, and near grazing (F -> 1) the tint
    fades out."""
    cos = np.linspace(0.02, 1.0, 50)
    f0 = ((1.5 - 1.0) / 2.5) ** 2
    film = thin_film.reflectance(TABLE, cos, 400.0, 1.33, 1.5)
    np.testing.assert_allclose(thin_film.principled_reflectance(TABLE, cos, 400.0, 1.33, 1.5, np.full(3, f0)),
                               film)
    tint = np.array([0.2, 0.6, 1.0])
    tinted = thin_film.principled_reflectance(TABLE, cos, 400.0, 1.33, 1.5, f0 * tint)
    s = np.clip((film - 1.0) / (f0 - 1.0), 0.0, 1.0)
    np.testing.assert_allclose(tinted, film * (1.0 + (tint - 1.0) * s))
    assert np.abs(tinted[0] / film[0] - 1.0).max() < 0.2 < np.abs(tinted[-1] / film[-1] - 1.0).max()


def filmed(roughness=0.0, diffuse=0.0, thickness=400.0, **kw):
    f0 = ((1.5 - 1.0) / 2.5) ** 2
    return {"name": "film", "glossy": f0, "roughness": roughness, "glossy_fresnel_ior": 1.5,
            "glossy_fresnel_rise": 1.0 - f0, "glossy_multiscatter": 0.0, "diffuse": diffuse,
            "diffuse_weight": 1.0 if diffuse else 0.0, "diffuse_layer": f0,
            "film_thickness": thickness, "film_ior": 1.33, **kw}


@pytest.mark.parametrize("theta", [0.0, 45.0, 70.0, 85.0])
def test_a_smooth_filmed_floor_reflects_the_sky_by_the_films_colour(theta):
    """A smooth layer (merged into the mirror lobe) under a constant sky seen at ``theta``: the
    film's spectral reflectance (before stop 43, the bare layer's grey Fresnel reflectance)."""
    t = np.radians(theta)
    got = render_mean(floor_scene(filmed(), t), method="ppm", passes=1, photons_per_pass=1000)
    np.testing.assert_allclose(got, spectral_reflectance(np.cos(t), 400.0, 1.33, 1.5), atol=2e-3)


def test_the_filmed_lobe_its_layer_and_scores_follow_the_film():
    """The table's colour at microfacet cosines is the film's (a rough lobe and the mirror one), the
    diffuse under it takes 1 - max over channels of the film at the view cosine (Cycles'
    ``closure_layering_weight`` without a lobe mean for a film), and the lobe is chosen."""
    mats = Materials.build([filmed(0.3, 0.5), filmed(0.0, 0.5), filmed(0.3, 0.5, thickness=0.0)])
    table = MaterialTable.from_materials(mats)
    cos = np.linspace(0.02, 1.0, 23)
    want = np.array([spectral_reflectance(c, 400.0, 1.33, 1.5) for c in cos])
    for row, lobe in ((0, GLOSSY), (1, MIRROR)):
        ids = np.full(len(cos), row)
        got = table.color[row, lobe] + table.fresnel_color(ids, lobe, cos)
        np.testing.assert_allclose(got, want, atol=2e-3)
    mu = np.array([0.1, 0.4, 0.9])
    expected = 1.0 - thin_film.reflectance(TABLE, mu, 400.0, 1.33, 1.5).max(axis=1)
    np.testing.assert_allclose(table.layer_factor(np.zeros(3, np.int64), mu), expected, atol=3e-3)
    assert not np.allclose(table.layer_factor(np.full(3, 2), mu), expected, atol=0.01)   # no film
    scores = lobe_scores(table, np.array([0, 1]), table.color[[0, 1]])
    assert scores[0, GLOSSY] > 0 and scores[1, MIRROR] > 0


def test_film_fields_survive_a_file_round_trip_and_bad_values_are_refused(tmp_path):
    spec = dict(film_tint=(0.2, 0.5, 1.0), film_metal=0.25, film_metal_ior=GOLD[0],
                film_metal_extinction=GOLD[1])
    mats = Materials.build([filmed(**spec)])
    scene = floor_scene(filmed(**spec), 0.3)
    scene.save(tmp_path / "s.npz")
    back = Scene.load(tmp_path / "s.npz").materials
    for name in ("film_thickness", "film_ior", "film_tint", "film_metal", "film_metal_ior",
                 "film_metal_extinction"):
        np.testing.assert_array_equal(getattr(back, name), getattr(mats, name), err_msg=name)
    for bad, name in (({"film_thickness": -1.0}, "film_thickness"), ({"film_ior": 0.0}, "film_ior"),
                      ({"film_tint": (0.5, 1.5, 0.5)}, "film_tint"), ({"film_metal": 1.5}, "film_metal"),
                      ({"film_thickness": np.nan}, "film_thickness"),
                      ({"film_metal_ior": (0.2, -0.1, 1.0)}, "film_metal_ior"),
                      ({"film_metal_extinction": (3.0, 200.0, 1.0)}, "film_metal_extinction")):
        with pytest.raises(SceneError, match=name):
            floor_scene(filmed(**bad), 0.3)


def glass_scatter(spec, cos_theta, entering, n=400_000, seed=5):
    """Mean weights (reflected, refracted) (3,) each of ``bsdf.scatter`` at a smooth glass of
    material ``spec`` for light arriving at ``cos_theta`` from outside (``entering``) or inside."""
    table = MaterialTable.from_materials(Materials.build([spec]))
    rng = np.random.default_rng(seed)
    up = np.array([0.0, 0.0, 1.0])
    side = 1.0 if entering else -1.0
    wo = np.tile([np.sqrt(1.0 - cos_theta ** 2), 0.0, side * cos_theta], (n, 1))
    normals = np.tile(up, (n, 1))
    colors = np.repeat(table.color[:1], n, axis=0)
    wi, weight, alive = scatter(table, np.zeros(n, np.int64), colors, np.full(n, DIELECTRIC), np.ones(n), wo,
                                normals, normals, rng.random(n), rng.random(n), "radiance")
    reflected = (wi[:, 2] * side > 0) & alive
    return weight[reflected].sum(axis=0) / n, weight[~reflected & alive].sum(axis=0) / n


@pytest.mark.parametrize("cos_theta", [0.9, 0.4])
def test_a_filmed_glass_reflects_its_films_colour_and_lets_the_rest_through(cos_theta):
    """A smooth Principled glass with a film (stop 43): from outside it reflects the film's
    spectral reflectance by channel and lets 1 - that through (before, a grey F); from inside
    Cycles takes the film's and the outside's indices relative to the glass (the film's optical
    path then shrinks by the glass's index, as Cycles'); a tint scales the reflection towards F0 t."""
    spec = {"name": "bubble", "dielectric": 1.0, "ior": 1.5, "film_thickness": 400.0, "film_ior": 1.33}
    reflected, through = glass_scatter(spec, cos_theta, True)
    want = spectral_reflectance(cos_theta, 400.0, 1.33, 1.5)
    np.testing.assert_allclose(reflected, want, rtol=0.04)
    np.testing.assert_allclose(through, 1.0 - want, rtol=0.01)
    assert np.ptp(want) > 0.01
    reflected, through = glass_scatter(spec, 0.95, False)
    inside = thin_film.reflectance(TABLE, np.array([0.95]), 400.0, 1.33 / 1.5, 1.0 / 1.5)[0]
    np.testing.assert_allclose(reflected, inside, rtol=0.04)
    np.testing.assert_allclose(through, 1.0 - inside, rtol=0.01)
    tint = np.array([0.3, 0.7, 1.0])
    reflected, _ = glass_scatter({**spec, "film_tint": tint}, cos_theta, True)
    f0 = 0.04
    want = thin_film.principled_reflectance(TABLE, np.array([cos_theta]), 400.0, 1.33, 1.5, f0 * tint)[0]
    np.testing.assert_allclose(reflected, want, rtol=0.04)


@pytest.mark.parametrize("share", [1.0, 0.4])
@pytest.mark.parametrize("roughness", [0.3, 0.0])
def test_a_filmed_metal_reflects_the_films_colour_over_its_curve(share, roughness):
    """A metal (F82 tint: F0 and an edge tint as Blender's Metallic BSDF defaults) under a film of
    500 nm (``film_metal``), alone or as 0.4 of the lobe beside a filmed dielectric layer (a half
    metallic Principled BSDF), rough or smooth (merged into the mirror lobe): the lobe's colour at
    microfacet cosines is k G_m(c) plus the layer's part, G_m Cycles' conductor film (which matched
    a Metallic BSDF render to four digits: 0.6441 / 0.5108 / 0.3995 at 40 degrees, against Cycles'
    0.6441 / 0.5108 / 0.3996); before stop 43 the bare curve."""
    f0, tint = np.array([0.617, 0.577, 0.540]), np.array([0.695, 0.726, 0.770])
    b = (f0 + (1.0 - f0) * (6.0 / 7.0) ** 5) * 7.0 / (6.0 / 7.0) ** 6 * (1.0 - tint)
    layer = 1.0 - share
    eta, f0_layer = 1.5, 0.04
    spec = {"name": "metal", "glossy": share * f0 + layer * f0_layer, "roughness": roughness,
            "glossy_metal_rise": share * (1.0 - f0), "glossy_metal_dip": share * b,
            "glossy_multiscatter": 0.0,
            "film_thickness": 500.0, "film_ior": 1.33, "film_metal": share}
    if layer > 0:
        spec.update(glossy_fresnel_ior=eta, glossy_fresnel_rise=layer * (1.0 - f0_layer))
    table = MaterialTable.from_materials(Materials.build([spec]))
    lobe = MIRROR if roughness == 0.0 else GLOSSY
    cos = np.linspace(0.02, 1.0, 17)
    got = table.color[0, lobe] + table.fresnel_color(np.zeros(len(cos), np.int64), lobe, cos)
    want = share * thin_film.conductor_reflectance(TABLE, cos, 500.0, 1.33, f0, b)
    if layer > 0:
        want += layer * thin_film.reflectance(TABLE, cos, 500.0, 1.33, eta)
    np.testing.assert_allclose(got, want, atol=5e-4)          # (the table's 257 nodes: up to 2.2e-4)
    at40 = thin_film.conductor_reflectance(TABLE, np.array([np.cos(np.radians(40.0))]), 500.0, 1.33, f0, b)
    np.testing.assert_allclose(at40[0], [0.6441, 0.5108, 0.3996], atol=2e-4)



@pytest.mark.parametrize("thickness", [120.0, 250.0, 500.0])
def test_a_filmed_physical_conductor_matches_the_spectral_integral(thickness):
    """A film over a physical conductor (Cycles' Metallic BSDF; stop 45, before noted and left out):
    each channel as the exact film over a substrate of that channel's complex index n + ik
    (:func:`spectral_reflectance`), within 3e-3 at three angles down to 63 degrees (measured up to
    1.3e-3).  Nearer grazing the metal under the film reflects nearly all, the film's waves fade
    slowly, and the series' three orders (Cycles') miss the exact colour by up to 0.02 at 75
    degrees."""
    n, k = GOLD
    cos = np.array([1.0, 0.7, 0.45])
    rows = len(cos)
    got = thin_film.physical_conductor_reflectance(TABLE, cos, thickness, 1.33, np.tile(n, (rows, 1)),
                                                   np.tile(k, (rows, 1)))
    want = np.array([[spectral_reflectance(c, thickness, 1.33, n[ch] + 1j * k[ch])[ch] for ch in range(3)]
                     for c in cos])
    np.testing.assert_allclose(got, want, atol=3e-3)
    assert np.ptp(want) > 0.1


def test_a_vanishing_film_leaves_a_physical_conductor_its_own_fresnel():
    """A film just over Cycles' cut-off (its index blended to about 1): the conductor's unpolarised
    Fresnel reflectance, down to 81 degrees."""
    n, k = GOLD
    cos = np.linspace(0.15, 1.0, 9)
    rows = len(cos)
    got = thin_film.physical_conductor_reflectance(TABLE, cos, 0.1001, 1.33, np.tile(n, (rows, 1)),
                                                   np.tile(k, (rows, 1)))
    eta = (n + 1j * k)[None, :]
    c = cos[:, None]
    cos_t = np.sqrt(1.0 - (1.0 - c * c) / (eta * eta))
    rs, rp = (c - eta * cos_t) / (c + eta * cos_t), (eta * c - cos_t) / (eta * c + cos_t)
    np.testing.assert_allclose(got, 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2), atol=2e-3)


def test_a_filmed_physical_conductor_lobe_follows_its_film():
    """``film_metal_ior`` > 0: the metal lobe's colour at microfacet cosines is the film over that
    complex index, not over the F82 fit its curve holds (the lobe's colour 1 / its weight)."""
    n, k = GOLD
    f0, tint = np.array([0.8, 0.5, 0.2]), np.array([0.9, 0.9, 0.9])
    b = (f0 + (1.0 - f0) * (6.0 / 7.0) ** 5) * 7.0 / (6.0 / 7.0) ** 6 * (1.0 - tint)
    spec = {"name": "gold", "glossy": f0, "roughness": 0.3, "glossy_metal_rise": 1.0 - f0,
            "glossy_metal_dip": b, "glossy_multiscatter": 0.0, "film_thickness": 300.0, "film_ior": 1.4,
            "film_metal": 1.0, "film_metal_ior": n, "film_metal_extinction": k}
    table = MaterialTable.from_materials(Materials.build([spec]))
    cos = np.linspace(0.02, 1.0, 17)
    got = table.color[0, GLOSSY] + table.fresnel_color(np.zeros(len(cos), np.int64), GLOSSY, cos)
    rows = len(cos)
    want = thin_film.physical_conductor_reflectance(TABLE, cos, 300.0, 1.4, np.tile(n, (rows, 1)),
                                                    np.tile(k, (rows, 1)))
    np.testing.assert_allclose(got, want, atol=5e-4)
    f82 = thin_film.conductor_reflectance(TABLE, cos, 300.0, 1.4, f0, b)
    assert np.abs(f82 - want).max() > 0.05

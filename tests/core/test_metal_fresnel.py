"""Metals' Fresnel curve by angle (``Materials.glossy_metal_rise`` / ``glossy_metal_dip``).

Cycles gives a Principled BSDF's metallic part and the Metallic node the F82-tint model:
F(c) = F0 + (1 - F0)(1 - c)^5 - b c (1 - c)^6 at microfacet cosine c, saturated, with b set so
that F at cos = 1/7 is the Schlick curve times the edge tint.  The reference below is written
from Cycles' ``fresnel_f82tint`` and ``fresnel_f82tint_B``, not from the core.

Closed forms, a floor of that metal under a constant sky seen by an orthographic camera at an
angle theta from the floor's normal (every pixel sees the floor at theta):

* smooth (a mirror): every pixel is sky F(cos theta), exactly, for camera paths;
* rough (GGX, single scattering): sky times the lobe's directional albedo with the Fresnel of
  each microfacet, E_F = E[G2 / G1 F(wo.m)] over visible normals m (a quadrature of the
  core's chi-square-tested sampler), reached by photons gathered on the floor.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core import RenderSettings, render
from core.bsdf import MaterialTable, lobe_scores, metal_fresnel
from core import sampling as smp
from core.scene import Camera, Materials, SceneError, World
from core.testing.scenes import MeshBuilder, with_one_object

F0 = np.array([0.9, 0.5, 0.1])
TINT = np.array([1.0, 0.6, 0.0])     # white, a tint, and 0 (the curve dips below 0: saturated)


def f82_b(f0, tint):
    """Cycles' ``fresnel_f82tint_B``."""
    f = 6.0 / 7.0
    f5, f6 = f ** 5, f ** 6
    schlick = f0 + (1.0 - f0) * f5
    return schlick * (7.0 / f6) * (1.0 - tint)


def f82(cos_i, f0, b):
    """Cycles' ``fresnel_f82tint``: (n, 3) at cosines (n,)."""
    s = np.clip(1.0 - np.asarray(cos_i, np.float64), 0.0, 1.0)[:, None]
    c = 1.0 - s
    return np.clip(f0 + (1.0 - f0) * s ** 5 - b * c * s ** 6, 0.0, 1.0)


def metal(roughness, f0=F0, tint=TINT, **kw):
    b = f82_b(f0, tint)
    return {"name": "metal", "glossy": f0, "roughness": roughness, "glossy_metal_rise": 1.0 - f0,
            "glossy_metal_dip": b, **kw}


def floor_scene(spec, theta, sky=1.0, h=2.0):
    """A floor of material ``spec`` at z = 0, 2 h wide, under a constant sky; an orthographic
    camera looking at the origin from ``theta`` off the floor's normal."""
    m = MeshBuilder()
    m.add_quad((-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0), 0)
    back = np.array([0.0, -np.sin(theta), np.cos(theta)])        # camera +Z, away from the view
    right = np.array([1.0, 0.0, 0.0])
    cam_m = np.eye(4)
    cam_m[:3, 0], cam_m[:3, 1], cam_m[:3, 2], cam_m[:3, 3] = right, np.cross(back, right), back, 3.0 * back
    cam = Camera(world_from_camera=cam_m, projection="orthographic", frame=(-0.1, 0.1, -0.1, 0.1),
                 resolution=(4, 4))
    return m.build(Materials.build([spec]), camera=cam, world=World(color=np.full(3, sky, np.float32)))


def render_mean(scene, **settings):
    def check(result):
        assert np.isfinite(result.image).all()

    result = render(scene, RenderSettings(workers=1, **settings), on_iteration=check)
    return result.image[..., :3].reshape(-1, 3).mean(axis=0)


THETAS = [0.0, 60.0, 80.0, 87.0]


@pytest.mark.parametrize("theta", THETAS)
def test_a_smooth_metal_reflects_the_sky_by_its_fresnel_curve(theta):
    t = np.radians(theta)
    expected = f82(np.array([np.cos(t)]), F0, f82_b(F0, TINT))[0]
    got = render_mean(floor_scene(metal(0.0), t), method="ppm", passes=1, photons_per_pass=1000)
    np.testing.assert_allclose(got, expected, rtol=1e-3, atol=1e-4)


def rough_albedo(alpha, mu, f0, b, n=400_000, seed=1):
    """E[G2 / G1 F(wo.m)] for the view cosine ``mu``: single-scattering GGX with Fresnel."""
    rng = np.random.default_rng(seed)
    wo = np.tile([np.sqrt(1.0 - mu * mu), 0.0, mu], (n, 1))
    a = np.full(n, alpha)
    m = smp.ggx_sample_visible_normal(wo, a, rng.random(n), rng.random(n))
    wi = smp.reflect(wo, m)
    ok = wi[:, 2] > 0
    g = np.where(ok, smp.ggx_g2(wo[:, 2], np.maximum(wi[:, 2], 1e-9), a) / smp.ggx_g1(wo[:, 2], a), 0.0)
    return (g[:, None] * f82(np.sum(wo * m, axis=1), f0, b)).mean(axis=0)


@pytest.mark.parametrize("method, tolerance", [(dict(method="ppm"), (0.01, 0.006)),
                                               (dict(method="amcmcppm", chains=4096), (0.02, 0.012))],
                         ids=["ppm", "amcmcppm"])
def test_a_rough_metal_gathers_the_sky_by_its_fresnel_curve(method, tolerance):
    """Roughness 0.4 (above the default Glossy Through, so photons meet the floor), 70 degrees
    off the normal.  The same seed renders a grey glossy floor: with PPM the photons are the
    same, so the ratio of the two is free of their number's noise (single renders of the grey
    floor measured 0.92-1.15 of its closed form), though not of their directions' (seeds 0-4:
    within 0.005 of the closed form's ratio); the chains' photons differ too (within 0.013).
    The curve's mean as a constant colour (as before) is 0.075 and 0.083 off in green and blue."""
    rough, theta = 0.4, np.radians(70.0)
    b = f82_b(F0, TINT)
    expected = rough_albedo(rough ** 2, np.cos(theta), F0, b)
    grey = 0.5 * rough_albedo(rough ** 2, np.cos(theta), np.ones(3), 0.0)          # F = 1
    settings = dict(passes=6, photons_per_pass=60_000, max_bounces=2, seed=3, **method)
    got = render_mean(floor_scene(metal(rough, glossy_multiscatter=0.0), theta), **settings)
    got_grey = render_mean(floor_scene({"name": "grey", "glossy": 0.5, "roughness": rough,
                                        "glossy_multiscatter": 0.0}, theta), **settings)
    mean_only = metal_fresnel(F0, TINT) * grey / 0.5
    print(f"rough metal / grey: {got / got_grey[0]}, expected {expected / grey[0]}, "
          f"with the mean colour {mean_only / grey[0]}")
    np.testing.assert_allclose(got_grey, grey, rtol=0.2)
    rtol, atol = tolerance
    np.testing.assert_allclose(got / got_grey[0], expected / grey[0], rtol=rtol, atol=atol)


def test_the_curve_adds_up_with_a_dielectric_rise_and_merges_into_the_mirror():
    """The table's colour at a cosine is the constant plus both curves, within [0, 1] where a
    metal curve is present; a sharp glossy lobe hands them to the mirror lobe."""
    half = 0.5 * F0
    both = metal(0.5, f0=half, glossy_fresnel_ior=1.5, glossy_fresnel_rise=0.2)
    table = MaterialTable.from_materials(Materials.build([metal(0.0), metal(0.5), both,
                                                          {"name": "grey", "glossy": 0.5}]))
    c = np.array([1.0, 0.5, 1.0 / 7.0, 0.2, 0.0])
    expected = f82(c, F0, f82_b(F0, TINT))
    for mat, lobe in ((0, 2), (1, 1)):
        got = table.color[mat, lobe] + table.fresnel_color(np.full(len(c), mat), lobe, c)
        np.testing.assert_allclose(got, expected, atol=1e-6)
    got = table.color[2, 1] + table.fresnel_color(np.full(len(c), 2), 1, c)
    dielectric = 0.2 * smp.fresnel_rise(c, np.full(len(c), 1.5))[:, None]
    np.testing.assert_allclose(got, np.clip(half + (1.0 - half) * (1.0 - c[:, None]) ** 5
                                            - f82_b(half, TINT) * (c * (1.0 - c) ** 6)[:, None] + dielectric,
                                            0.0, 1.0), atol=1e-6)
    assert table.rises[0].tolist() == [False, False, True, False]
    assert table.rises[3].tolist() == [False] * 4
    np.testing.assert_array_equal(table.fresnel_color(np.full(len(c), 3), 1, c), 0.0)


def test_metal_curves_survive_a_file_round_trip_and_are_refused_with_a_program(tmp_path):
    scene = floor_scene(metal(0.3), 0.5)
    path = tmp_path / "metal.npz"
    scene.save(path)
    back = type(scene).load(path)
    np.testing.assert_array_equal(back.materials.glossy_metal_dip, scene.materials.glossy_metal_dip)
    np.testing.assert_array_equal(back.materials.glossy_metal_rise, scene.materials.glossy_metal_rise)
    bad = metal(0.3, glossy_program={"op": "rgb", "value": [0.5, 0.5, 0.5]})
    with pytest.raises(SceneError, match="glossy_program"):
        floor_scene(bad, 0.5)
    with pytest.raises(SceneError, match="glossy_metal_rise is negative"):
        floor_scene(metal(0.3, glossy_metal_rise=-0.1), 0.5)


def test_a_black_metal_with_a_dipping_tint_is_still_chosen_as_a_lobe():
    """F0 = 0 and an edge tint of 0: the curve's unclipped mean is below 0 (1/21 - b/126), yet it
    reflects towards grazing angles, so its lobe keeps a positive score."""
    table = MaterialTable.from_materials(Materials.build([metal(0.5, f0=np.zeros(3), tint=np.zeros(3))]))
    ids = np.zeros(1, np.int64)
    scores = lobe_scores(table, ids, table.color.take(ids, axis=0))
    assert scores[0, 1] > 0.004 and (scores >= 0).all()     # the clipped mean: 0.0044
    assert table.fresnel_color(ids, 1, np.array([0.02]))[0] == pytest.approx(np.full(3, 0.8), abs=0.1)


def textured_metal(roughness, f0_program, tint=TINT, **kw):
    """A metal whose F0 is ``f0_program``'s colour at each hit (``glossy_metal_tint``)."""
    return {"name": "textured metal", "glossy": 1.0, "roughness": roughness, "glossy_program": f0_program,
            "glossy_metal_tint": tint, **kw}


# A float program: 1 on the floor's x > 0 half (object coordinates), 0 on the rest.
HALF = {"op": "math", "operation": "GREATER_THAN",
        "a": {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}, "b": 0.0}


def floor_images(material_lists, theta, method):
    """The (h, w, 3) images of the floor at ``theta`` of each list of material specs (the first one
    the floor's), rendered with the same seed by ``method``."""
    images = []
    for specs in material_lists:
        scene = with_one_object(floor_scene(metal(0.4), theta)).replace(
            materials=Materials.build(specs)).validate()
        res = render(scene, RenderSettings(method=method, passes=3, photons_per_pass=20000, workers=1,
                                           seed=5, chains=1024))
        assert np.isfinite(res.image).all()
        images.append(res.image[..., :3])
    return images


def rgb(colour):
    """A program of the constant ``colour``."""
    c = [float(x) for x in colour]
    return {"op": "mix_color", "fac": 0.0, "a": c, "b": c}


def test_a_textured_metal_takes_the_curve_of_each_hits_colour():
    """The table's curve for metals whose F0 is the hit's colour equals the F82 curve of that F0,
    hit by hit, for a glossy lobe and one merged into the mirror; their lobe keeps a positive
    score where the F0 is black; bad tints are refused."""
    table = MaterialTable.from_materials(Materials.build([textured_metal(0.5, rgb(F0)),
                                                          textured_metal(0.0, rgb(F0)),
                                                          {"name": "grey", "glossy": 0.5},
                                                          textured_metal(0.5, rgb(F0), tint=np.zeros(3))]))
    c = np.array([1.0, 0.5, 1.0 / 7.0, 0.2, 0.0])
    f0s = np.array([F0, [0.0, 0.3, 1.0], F0[::-1], [0.2, 0.2, 0.2], np.zeros(3)])
    expected = np.concatenate([f82(c[i:i + 1], f0s[i], f82_b(f0s[i], TINT)) for i in range(len(c))])
    assert table.hit_metal.tolist() == [True, True, False, True]
    assert table.rises[0].tolist() == [False, True, False, False]
    assert table.rises[1].tolist() == [False, False, True, False]
    for mat, lobe in ((0, 1), (1, 2)):
        ids = np.full(len(c), mat)
        np.testing.assert_allclose(f0s + table.fresnel_color(ids, lobe, c, f0s), expected, atol=1e-7)
        with pytest.raises(ValueError, match="colours"):
            table.fresnel_color(ids, lobe, c)
    mixed = np.array([0, 2, 0, 2, 0])        # rows of a plain lobe in the same call add nothing
    got = table.fresnel_color(mixed, 1, c, f0s)
    np.testing.assert_allclose(got[mixed == 0], expected[mixed == 0] - f0s[mixed == 0], atol=1e-7)
    np.testing.assert_array_equal(got[mixed == 2], 0.0)
    black = np.zeros((1, 4, 3))
    scores = lobe_scores(table, np.full(1, 3), black)       # tint 0: the unclipped mean is below 0
    assert scores[0, 1] == pytest.approx(1.0 / 210.0) and (scores >= 0).all()
    for bad in ({"glossy_metal_tint": [1.2, 0.5, 0.5]}, {"glossy_metal_tint": [0.5, -1.0, 0.5]},
                {"glossy_metal_rise": 0.5}):
        with pytest.raises(SceneError, match="glossy_metal_tint"):
            floor_scene(textured_metal(0.3, rgb(F0), **bad), 0.5)


@pytest.mark.parametrize("theta", [0.0, 80.0])
def test_a_smooth_textured_metal_reflects_the_sky_by_the_curve_of_its_colour(theta):
    t = np.radians(theta)
    expected = f82(np.array([np.cos(t)]), F0, f82_b(F0, TINT))[0]
    got = render_mean(floor_scene(textured_metal(0.0, rgb(F0)), t), method="ppm", passes=1,
                      photons_per_pass=1000)
    np.testing.assert_allclose(got, expected, rtol=1e-3, atol=1e-4)


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_a_textured_metal_floor_equals_each_metal_on_its_half(method):
    """A rough floor whose F0 is one colour on its x > 0 half and another on the rest renders, half
    by half and to rounding, as the floor of either plain metal (same seed: the same photons; the
    curve, its multiscatter F_ss, the gather and the scattering take the hit's colour).  With the
    curve's mean colour per point instead (as before) the halves' channels came out 0.95 to 2.4
    times these at 70 degrees (the blue of F0 0.1 most)."""
    other = np.array([0.2, 0.6, 0.95])
    program = {"op": "mix_color", "fac": HALF, "a": rgb(other), "b": rgb(F0)}
    first, second, mapped, means = floor_images(
        [[metal(0.4, f0=F0, glossy_multiscatter=metal_fresnel(F0, TINT))],
         [metal(0.4, f0=other, glossy_multiscatter=metal_fresnel(other, TINT))],
         [textured_metal(0.4, program, glossy_multiscatter=1.0)],
         [dict(textured_metal(0.4, {"op": "metal", "color": program, "tint": list(TINT)}),
               glossy_metal_tint=-1.0)]],
        np.radians(70.0), method)
    w = mapped.shape[1] // 2
    assert np.abs(first - second).max() > 0.05
    np.testing.assert_allclose(mapped[:, w:], first[:, w:], rtol=1e-5)
    np.testing.assert_allclose(mapped[:, :w], second[:, :w], rtol=1e-5)
    print("mean curve / curve:", means[:, w:].mean(axis=(0, 1)) / first[:, w:].mean(axis=(0, 1)),
          means[:, :w].mean(axis=(0, 1)) / second[:, :w].mean(axis=(0, 1)))


def partial_metal(f0, share, tint, rest, rest_fss, **kw):
    """A glossy lobe that is ``share`` of a metal of F0 ``f0`` beside a dielectric layer of IOR 1.5
    whose normal-incidence colour ``rest`` rises to 1 - share at grazing angles, as plain rows: the
    metal's curve (``glossy_metal_rise``, ``glossy_metal_dip``) beside the layer's rise, with the F_ss of
    both weighted by their mean reflectances (``MaterialTable.multiscatter``)."""
    fm = np.clip(metal_fresnel(f0, tint), 0.0, 1.0)
    fss = (share * fm * fm + (1.0 - share) * rest_fss ** 2) / (share * fm + (1.0 - share) * rest_fss)
    return {"name": "part metal", "glossy": share * f0 + rest, "glossy_metal_rise": share * (1.0 - f0),
            "glossy_metal_dip": share * f82_b(f0, tint), "glossy_fresnel_ior": 1.5,
            "glossy_fresnel_rise": (1.0 - share) - rest, "glossy_multiscatter": fss, **kw}


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_a_partly_metallic_textured_floor_equals_each_plain_lobe_on_its_half(method):
    """A Principled BSDF half metallic (share 0.4) on a textured base colour: its glossy lobe is the
    metal of each hit's F0, from the program (the lobe's colour is 0.4 F0 + rest), beside the dielectric
    layer's rise (``glossy_metal_share``, ``glossy_metal_rest``).  Half by half, and to rounding, it
    renders as the floors of the plain rows of either colour; before, a glossy program could not
    carry the layer at all (the exporter took the metal's mean colour)."""
    tint = np.array([1.0, 0.9, 0.8])        # no dip below 0: the metal's and the rows' clipping agree
    other = np.array([0.2, 0.6, 0.95])
    for f0 in (F0, other):
        assert (f82(np.linspace(0, 1, 201), f0, f82_b(f0, tint)) > 0).all()
    share, f0t = 0.4, 0.04 * np.array([1.0, 0.8, 0.6])
    rest, rest_fss = (1.0 - share) * f0t, np.array([0.09, 0.08, 0.07])
    colour = {"op": "mix_color", "fac": HALF, "a": rgb(other), "b": rgb(F0)}
    first, second, mapped = floor_images(
        [[partial_metal(F0, share, tint, rest, rest_fss, roughness=0.4)],
         [partial_metal(other, share, tint, rest, rest_fss, roughness=0.4)],
         [{"name": "mapped", "glossy": 1.0, "roughness": 0.4, "glossy_program": colour,
           "glossy_metal_tint": tint, "glossy_metal_share": share, "glossy_metal_rest": rest,
           "glossy_fresnel_ior": 1.5, "glossy_fresnel_rise": (1.0 - share) - rest,
           "glossy_multiscatter": rest_fss}]],
        np.radians(70.0), method)
    w = mapped.shape[1] // 2
    assert np.abs(first - second).max() > 0.02
    np.testing.assert_allclose(mapped[:, w:], first[:, w:], rtol=1e-5)
    np.testing.assert_allclose(mapped[:, :w], second[:, :w], rtol=1e-5)


def test_a_partly_metallic_lobe_recovers_its_metal_and_refuses_bad_shares():
    """The table's colour for a share-k metal beside a layer is rest + k F(c) of the F0 in the hit's
    colour, plus the layer's rise; its score counts both parts; shares outside (0, 1] are refused."""
    share, rest = 0.25, np.array([0.03, 0.02, 0.01])
    spec = {"name": "m", "glossy": 1.0, "roughness": 0.5, "glossy_program": rgb(F0),
            "glossy_metal_tint": TINT, "glossy_metal_share": share, "glossy_metal_rest": rest,
            "glossy_fresnel_ior": 1.5, "glossy_fresnel_rise": 0.5}
    table = MaterialTable.from_materials(Materials.build([spec]))
    c = np.array([1.0, 0.5, 1.0 / 7.0, 0.05])
    ids = np.zeros(len(c), np.int64)
    base = np.tile(share * F0 + rest, (len(c), 1))
    rise = smp.fresnel_rise(c, np.full(len(c), 1.5))[:, None]
    expected = rest + share * f82(c, F0, f82_b(F0, TINT)) + 0.5 * rise
    np.testing.assert_allclose(base + table.fresnel_color(ids, 1, c, base), expected, atol=1e-7)
    score = lobe_scores(table, ids[:1], np.stack([np.zeros(3), base[0], np.zeros(3), np.zeros(3)])[None])
    assert score[0, 1] > smp.luminance(share * metal_fresnel(F0, TINT) + rest)
    for bad in ({"glossy_metal_share": 0.0}, {"glossy_metal_share": 1.5}, {"glossy_metal_rest": 1.2},
                {"glossy_metal_share": 1.0}):
        with pytest.raises(SceneError, match="glossy_metal"):
            floor_scene(dict(spec, **bad), 0.5)



@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_a_metallic_map_picks_each_points_material_level(method):
    """A material whose levels (``Materials.level_program``) are a partly metallic textured lobe
    (metallic level 0) and a rough plain metal with a roughness map (level 1), picked by the
    floor's halves: half by half, and to rounding, it renders as the floor of either level (the
    material itself, a grey diffuse, is never shaded).  A level's roughness map picks its own copy
    (``bsdf.roughness_variants``)."""
    tint = np.array([1.0, 0.9, 0.8])
    share, rest, rest_fss = 0.4, 0.024 * np.array([1.0, 0.8, 0.6]), np.array([0.09, 0.08, 0.07])
    first = {"name": "part", "glossy": 1.0, "roughness": 0.3, "glossy_program": rgb(F0),
             "glossy_metal_tint": tint, "glossy_metal_share": share, "glossy_metal_rest": rest,
             "glossy_fresnel_ior": 1.5, "glossy_fresnel_rise": (1.0 - share) - rest,
             "glossy_multiscatter": rest_fss, "diffuse": [0.5, 0.3, 0.2], "diffuse_weight": 0.6,
             "diffuse_layer": rest / 0.6}
    second = dict(metal(0.375, glossy_multiscatter=metal_fresnel(F0, TINT)),
                  roughness_program={"op": "math", "operation": "ADD", "a": 0.0, "b": 0.375},
                  roughness=0.9)
    picks = {"name": "picks", "diffuse": 0.5, "level_program": HALF, "level_first": 1, "level_count": 2}
    a, b, picked = floor_images([[first], [second], [picks, first, second]], np.radians(60.0), method)
    w = picked.shape[1] // 2
    assert np.abs(a - b).max() > 0.05
    np.testing.assert_allclose(picked[:, :w], a[:, :w], rtol=1e-5)      # x < 0: level 0
    np.testing.assert_allclose(picked[:, w:], b[:, w:], rtol=1e-5)


def test_material_levels_are_validated(tmp_path):
    base = {"name": "picks", "diffuse": 0.5, "level_program": HALF, "level_first": 1, "level_count": 2}
    plain = {"name": "plain", "diffuse": 0.3}
    part = {"name": "part", "glossy": 1.0, "glossy_program": rgb(F0), "glossy_metal_tint": TINT,
            "glossy_metal_share": 0.5, "glossy_metal_rest": 0.02, "glossy_fresnel_ior": 1.5,
            "glossy_fresnel_rise": 0.48}
    scene = with_one_object(floor_scene(plain, 0.5)).replace(materials=Materials.build([base, plain, part]))
    scene.validate().save(tmp_path / "levels.npz")
    back = type(scene).load(tmp_path / "levels.npz").materials
    for name in ("level_program", "level_first", "level_count", "glossy_metal_share", "glossy_metal_rest"):
        np.testing.assert_array_equal(getattr(back, name), getattr(scene.materials, name))
    for specs in ([base, plain], [dict(base, level_count=1), plain, plain],
                  [dict(base, level_first=-1), plain, plain], [base, plain, dict(base, level_first=0)]):
        scene = floor_scene(plain, 0.5)
        with pytest.raises(SceneError, match="level_first and level_count"):
            with_one_object(scene).replace(materials=Materials.build(specs)).validate()


def test_a_level_between_two_is_picked_with_the_programs_fraction():
    """``RenderContext.surface`` with pick numbers: a program of 0.3 over three levels (x = 0.6
    between levels 0 and 1) picks level 1 at the hits whose number is below 0.6, level 0 at the
    others, never level 2; without numbers, the nearest (level 1)."""
    from core.context import RenderContext
    plain = [{"name": f"level {k}", "diffuse": 0.1 * (k + 1)} for k in range(3)]
    picks = {"name": "picks", "diffuse": 0.5, "level_first": 1, "level_count": 3,
             "level_program": {"op": "math", "operation": "ADD", "a": 0.0, "b": 0.3}}
    scene = with_one_object(floor_scene(metal(0.4), 0.5)).replace(
        materials=Materials.build([picks] + plain)).validate()
    ctx = RenderContext(scene)
    n = 1000
    prim = np.zeros(n, np.int64)
    b = np.full(n, 0.25)
    numbers = (np.arange(n) + 0.5) / n
    mats = ctx.surface(prim, b, b, numbers).mat_ids
    assert set(np.unique(mats)) == {1, 2} and (mats == 2).mean() == pytest.approx(0.6)
    np.testing.assert_array_equal(mats == 2, numbers < 0.6)
    assert (ctx.surface(prim, b, b).mat_ids == 2).all()


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_a_map_between_two_levels_renders_their_mix(method):
    """A floor whose map is 0.3 everywhere between a red and a blue diffuse of the same green (levels
    0 and 1) under a white sky: each hit takes the blue with probability 0.3, so the floor's albedo
    is 0.7 red + 0.3 blue = (0.59, 0.2, 0.31).  The green, the same for both, gives the photon
    density (whose noise every channel shares), and the red and blue over it match that albedo
    within 5 %: the camera's picks alone (256 pixels x 24 passes) spread the blue by 1.3 % (and the
    photon density under each pick weighs them); the nearest level (red) would give 0.8 and 0.1."""
    red, blue = {"name": "red", "diffuse": [0.8, 0.2, 0.1]}, {"name": "blue", "diffuse": [0.1, 0.2, 0.8]}
    level = {"name": "picks", "diffuse": 0.5, "level_first": 1, "level_count": 2,
             "level_program": {"op": "math", "operation": "ADD", "a": 0.0, "b": 0.3}}
    scene = with_one_object(floor_scene(metal(0.4), np.radians(40.0))).replace(
        materials=Materials.build([level, red, blue]))
    scene = scene.replace(camera=dataclasses.replace(scene.camera, resolution=(16, 16))).validate()
    res = render(scene, RenderSettings(method=method, passes=24, photons_per_pass=20000, workers=1, seed=3,
                                       chains=1024))
    assert np.isfinite(res.image).all()
    mean = res.image[..., :3].reshape(-1, 3).mean(axis=0)
    albedo = 0.2 * mean / mean[1]
    print("albedo:", albedo)
    np.testing.assert_allclose(albedo, [0.59, 0.2, 0.31], rtol=0.05)

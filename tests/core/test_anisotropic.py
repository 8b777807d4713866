"""Anisotropic glossy lobes (``Materials.glossy_stretch``, ``glossy_rotation``, ``glossy_tangent``).

Cycles' anisotropic GGX: alpha_x along the tangent T (projected onto the shading normal's plane),
alpha_y across it, D(m) = 1 / (pi ax ay m_z^4 (1 + (m_x^2 / ax^2 + m_y^2 / ay^2) / m_z^2)^2) and
Smith's Lambda(v) = (sqrt(1 + (ax^2 v_x^2 + ay^2 v_y^2) / v_z^2) - 1) / 2 in the frame (T, N x T, N)
(Heitz 2014).  The references below are written from those formulas, not from the core.  The
tangent is Blender's Tangent node: by default radial about the object's Z axis through the
centre of its texture space, (-(g_y - 1/2), g_x - 1/2, 0) of the Generated coordinates g,
taken to world space as a normal and made perpendicular to the normal.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from core import RenderSettings, bsdf, render
from core import sampling as smp
from core.context import RenderContext
from core.scene import Camera, Lights, Materials, SceneError
from core.testing.scenes import MeshBuilder, _look_down, _sunlit_textured_floor, with_one_object
from stats_utils import sidak
from chi2 import ChiSquareTest
from test_metal_fresnel import floor_scene, render_mean
from test_sampling import WARPED, dir_to_warped, warped_to_dir

ALPHAS = ((0.5, 0.125), (0.04, 0.3))
THETAS_DEG = (0.0, 45.0, 75.0)
ALPHA_EACH = sidak(0.01, len(ALPHAS) * len(THETAS_DEG))


def ref_d(m, ax, ay):
    c2 = np.maximum(m[:, 2] ** 2, 1e-300)
    e = (m[:, 0] ** 2 / ax ** 2 + m[:, 1] ** 2 / ay ** 2) / c2
    return np.where(m[:, 2] > 0, 1.0 / (np.pi * ax * ay * c2 * c2 * (1.0 + e) ** 2), 0.0)


def ref_lambda(v, ax, ay):
    c2 = np.maximum(v[:, 2] ** 2, 1e-300)
    return 0.5 * (np.sqrt(1.0 + (ax ** 2 * v[:, 0] ** 2 + ay ** 2 * v[:, 1] ** 2) / c2) - 1.0)


def ref_f_and_pdf(wo, wi, ax, ay):
    """f = D G2 / (4 cos_o cos_i) and the visible-normal reflection pdf G1(wo) D / (4 cos_o) of
    local directions (x along the tangent)."""
    h = wo + wi
    m = h / np.linalg.norm(h, axis=1, keepdims=True)
    lo, li = ref_lambda(wo, ax, ay), ref_lambda(wi, ax, ay)
    d = ref_d(m, ax, ay)
    ok = (wo[:, 2] > 0) & (wi[:, 2] > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = d / (1.0 + lo + li) / (4.0 * wo[:, 2] * wi[:, 2])
        pdf = d / (1.0 + lo) / (4.0 * wo[:, 2])
    return np.where(ok, f, 0.0), np.where(ok, pdf, 0.0)


def glossy_table(ax, ay, multiscatter=0.0):
    """A white glossy material whose alphas are ax along the tangent and ay across it."""
    rough = (ax * ay) ** 0.25
    mats = Materials.build([{"name": "g", "glossy": 1.0, "roughness": rough,
                             "glossy_multiscatter": multiscatter, "glossy_stretch": math.sqrt(ax / ay)}])
    return bsdf.MaterialTable.from_materials(mats)


# A normal and a tangent that is not perpendicular to it (the lobe projects it).
NORMAL = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
TANGENT = np.array([0.8, 0.5, 0.4])


def local_frame():
    """(3, 3) rows x, y, n of the lobe's frame, by Gram-Schmidt."""
    x = TANGENT - TANGENT @ NORMAL * NORMAL
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(NORMAL, x), NORMAL])


@pytest.mark.parametrize("theta_deg", THETAS_DEG)
@pytest.mark.parametrize("alphas", ALPHAS)
def test_anisotropic_glossy_scatter_samples_the_reference_lobe(alphas, theta_deg):
    """``bsdf.scatter`` of an anisotropic lobe: its directions follow the visible-normal pdf of
    the reference (chi-square about the mirror direction) and each weighs f cos / pdf."""
    ax, ay = alphas
    table = glossy_table(ax, ay)
    assert table.has_anisotropy
    assert np.isclose(table.alpha_x[0], ax) and np.isclose(table.alpha_y[0], ay)
    frame = local_frame()
    phi_o = 0.7
    th = math.radians(theta_deg)
    wo_l = np.array([math.sin(th) * math.cos(phi_o), math.sin(th) * math.sin(phi_o), math.cos(th)])
    wo = wo_l @ frame
    mirror = (np.array([-wo_l[0], -wo_l[1], wo_l[2]])) @ frame
    rng = np.random.default_rng(7000 + 10 * ALPHAS.index(alphas) + THETAS_DEG.index(theta_deg))
    p = 4.0 if min(ax, ay) < 0.1 else 2.0

    def sample(n):
        ones = np.ones(n)
        wi, weight, alive = bsdf.scatter(table, np.zeros(n, np.int32), np.ones((n, table.lobes, 3)),
                                         np.full(n, bsdf.GLOSSY), ones, np.tile(wo, (n, 1)),
                                         np.tile(NORMAL, (n, 1)), np.tile(NORMAL, (n, 1)), rng.random(n),
                                         rng.random(n), "radiance", tangent=np.tile(TANGENT, (n, 1)))
        w = weight[:, 0]
        ok = alive & (w > 0)
        wi_l = wi[ok] @ frame.T
        f, pdf = ref_f_and_pdf(np.tile(wo_l, (ok.sum(), 1)), wi_l, ax, ay)
        assert np.allclose(w[ok], f * wi_l[:, 2] / pdf, rtol=1e-6)
        return dir_to_warped(wi, mirror, p), ok.astype(np.float64)

    def pdf(xy):
        d, jac = warped_to_dir(xy, mirror, p)
        d_l = d @ frame.T
        return ref_f_and_pdf(np.tile(wo_l, (len(d), 1)), d_l, ax, ay)[1] * jac

    test = ChiSquareTest(sample, pdf, WARPED, sample_count=200_000, res=40, ires=6)
    assert test.run(ALPHA_EACH), test.message


def test_anisotropic_glossy_value_is_the_reference_and_isotropic_when_the_alphas_agree():
    rng = np.random.default_rng(7100)
    n = 5000
    wo = rng.normal(size=(n, 3))
    wi = rng.normal(size=(n, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    frame = local_frame()
    ns, t = np.tile(NORMAL, (n, 1)), np.tile(TANGENT, (n, 1))
    for ax, ay in ALPHAS + ((0.2, 0.2),):
        x = smp.tangent_axes(ns, t)
        f, cos_h = bsdf.glossy_anisotropic_value(np.full(n, ax), np.full(n, ay), np.sum(wo * ns, axis=1),
                                                 np.sum(wi * ns, axis=1), np.sum(wo * wi, axis=1),
                                                 np.sum(wo * x, axis=1), np.sum(wi * x, axis=1))
        f_ref, _ = ref_f_and_pdf(wo @ frame.T, wi @ frame.T, ax, ay)
        assert np.allclose(f, f_ref, rtol=1e-9, atol=1e-12)
        h = (wo + wi) / np.linalg.norm(wo + wi, axis=1, keepdims=True)
        assert np.allclose(cos_h, np.sum(wo * h, axis=1))
    f_iso = bsdf.eval_glossy(np.full(n, 0.2), wo, wi, ns)
    assert np.allclose(f, f_iso, rtol=1e-9, atol=1e-12)


def sunlit_floor(tangent, rotation=0.0, ax=0.32, ay=0.08, sun_angle=0.7):
    """The 1 m floor of ``_sunlit_textured_floor`` made a white anisotropic glossy (single
    scattering) with constant UV tangents ``tangent``, lit by a sun ``sun_angle`` from the zenith in
    the x-z plane and seen straight down: every pixel is E cos(sun) f(z, sun)."""
    sun = (math.sin(sun_angle), 0.0, math.cos(sun_angle))
    frame = np.concatenate([np.asarray(tangent, np.float32), [1.0]]).astype(np.float32)
    scene = _sunlit_textured_floor({}, np.ones((2, 2, 3), np.float32), sun, 10.0, 0.5, (8, 8),
                                   tangents=np.broadcast_to(frame, (2, 3, 4)))
    mats = Materials.build([{"name": "brushed", "glossy": 1.0, "roughness": (ax * ay) ** 0.25,
                             "glossy_multiscatter": 0.0, "glossy_stretch": math.sqrt(ax / ay),
                             "glossy_tangent": bsdf.TANGENT_UV, "glossy_rotation": rotation}])
    return scene.replace(materials=mats).validate()


def expected_floor(along_sun, ax=0.32, ay=0.08, sun_angle=0.7):
    """E cos f with the tangent along the sun's azimuth (x) or across it."""
    sun = np.array([[math.sin(sun_angle), 0.0, math.cos(sun_angle)]])
    if not along_sun:
        sun = sun[:, [1, 0, 2]]                    # the sun's azimuth along the lobe's y axis
    f, _ = ref_f_and_pdf(np.array([[0.0, 0.0, 1.0]]), sun, ax, ay)
    return 10.0 * sun[0, 2] * f[0]


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
@pytest.mark.parametrize("tangent, rotation, along", [((1, 0, 0), 0.0, True), ((0, 1, 0), 0.0, False),
                                                      ((1, 0, 0), 0.25, False), ((0, 1, 0), -0.5, False)])
def test_a_sunlit_brushed_floor_gathers_the_reference_lobe(method, tangent, rotation, along):
    """The photons gathered on the floor weigh by the lobe in its tangent's frame: along the sun's
    azimuth the wide alpha_x shows the sun (7.4), across it the narrow alpha_y hardly (0.084);
    a quarter turn swaps them and a half turn changes nothing.  Uniform over the image: the
    pixels' spread within 5 % of it (over seeds 0-9, 1.5 to 2.8 %; their range, which one
    heavy photon through the narrow lobe decides, was 6.5 to 14 %)."""
    res = render(sunlit_floor(tangent, rotation),
                 RenderSettings(method=method, passes=8, photons_per_pass=20000, workers=1, seed=3))
    img = res.image[..., :3]
    assert np.isfinite(img).all()
    expected = expected_floor(along)
    assert abs(img.mean() / expected - 1.0) < 0.04, (img.mean(), expected)
    assert np.std(img.mean(axis=2)) < 0.05 * expected


def test_a_rotation_map_turns_the_tangent_at_each_hit():
    """``rotation_program``: a map that turns the tangent a quarter on the floor's x > 0 half and
    not at all on the other.  Each half of the image equals, to rounding, the render with that
    rotation everywhere (same seed: the same photons reach the same points; only the points'
    lobes differ): 7.4 with the tangent along the sun's azimuth, 0.084 across it."""
    half = {"op": "math", "operation": "GREATER_THAN",
            "a": {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"},
            "b": 0.0}
    quarter = {"op": "math", "operation": "MULTIPLY", "a": half, "b": 0.25}
    settings = RenderSettings(method="ppm", passes=3, photons_per_pass=20000, workers=1, seed=4)
    images = []
    for rotation, program in ((0.0, None), (0.25, None), (0.0, quarter)):
        scene = with_one_object(sunlit_floor((1, 0, 0), rotation), ((0, 0, 0), (0.5, 0.5, 0)))
        if program is not None:
            spec = {"name": "brushed", "glossy": 1.0, "roughness": (0.32 * 0.08) ** 0.25,
                    "glossy_multiscatter": 0.0, "glossy_stretch": 2.0, "glossy_tangent": bsdf.TANGENT_UV,
                    "rotation_program": program}
            scene = scene.replace(materials=Materials.build([spec])).validate()
            assert "rotation maps" in RenderContext(scene).effects
        images.append(render(scene, settings).image[..., :3])
    along, across, mapped = images
    w = mapped.shape[1] // 2
    assert along.mean() > 20 * across.mean()
    np.testing.assert_allclose(mapped[:, :w], along[:, :w], rtol=1e-5)
    np.testing.assert_allclose(mapped[:, w:], across[:, w:], rtol=1e-5)


def test_an_anisotropy_map_stretches_the_lobe_at_each_hit():
    """``stretch_program``: a map that gives the floor's x > 0 half a stretch of 0.49 (narrow along
    the sun's azimuth) and the other half 2.05 (wide).  Each half of the image equals, to
    rounding, the render with that stretch everywhere (both are levels of ``bsdf.stretch_levels``;
    same seed: the same photons reach the same points), and a roughness map on the same material
    keeps its constant stretch."""
    wide, narrow = bsdf.stretch_levels()[[74, 54]]
    half = {"op": "math", "operation": "GREATER_THAN",
            "a": {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"},
            "b": 0.0}
    program = {"op": "math", "operation": "MULTIPLY_ADD", "a": half, "b": float(narrow - wide),
               "c": float(wide)}
    settings = RenderSettings(method="ppm", passes=3, photons_per_pass=20000, workers=1, seed=4)
    spec = {"name": "brushed", "glossy": 1.0, "roughness": (0.32 * 0.08) ** 0.25,
            "glossy_multiscatter": 0.0, "glossy_tangent": bsdf.TANGENT_UV}
    base = with_one_object(sunlit_floor((1, 0, 0)), ((0, 0, 0), (0.5, 0.5, 0)))
    images = []
    for extra in ({"glossy_stretch": float(wide)}, {"glossy_stretch": float(narrow)},
                  {"stretch_program": program},
                  {"glossy_stretch": float(wide), "stretch_program": program,
                   "roughness_program": {"op": "math", "operation": "ADD", "a": 0.0,
                                         "b": spec["roughness"]}}):
        scene = base.replace(materials=Materials.build([dict(spec, **extra)])).validate()
        effects = RenderContext(scene).effects
        assert ("anisotropy maps" in effects) == (extra.keys() == {"stretch_program"}), effects
        images.append(render(scene, settings).image[..., :3])
    along, across, mapped, rough_mapped = images
    w = mapped.shape[1] // 2
    assert along.mean() > 20 * across.mean()
    np.testing.assert_allclose(mapped[:, :w], along[:, :w], rtol=1e-5)
    np.testing.assert_allclose(mapped[:, w:], across[:, w:], rtol=1e-5)
    np.testing.assert_allclose(rough_mapped, along, rtol=0.02)


def test_stretch_levels_are_even_in_log_s_and_include_isotropy():
    """The copies of an anisotropy map: s = 1 and the range's ends are levels; a value maps to
    the nearest level in log s (at most half a step, 3.7 %, off), out-of-range and NaN values
    to the ends and to s = 1."""
    levels = bsdf.stretch_levels()
    assert len(levels) == bsdf.STRETCH_LEVELS
    assert levels[(bsdf.STRETCH_LEVELS - 1) // 2] == 1.0
    np.testing.assert_allclose(levels[[0, -1]], [0.01, 100.0])
    s = np.exp(np.random.default_rng(1).uniform(np.log(0.01), np.log(100.0), 10000))
    picked = levels[bsdf.stretch_level(s)]
    assert np.abs(np.log(picked / s)).max() <= 0.5 * np.log(levels[1] / levels[0]) + 1e-12
    assert np.abs(picked / s - 1.0).max() < 0.037
    assert list(bsdf.stretch_level([1e-6, 1e6, np.nan, -1.0])) == [0, bsdf.STRETCH_LEVELS - 1,
                                                                   (bsdf.STRETCH_LEVELS - 1) // 2, 0]


def test_radial_tangents_turn_about_the_objects_axis():
    """``RenderContext.tangents`` for Blender's default (radial about Z) and the X and Y axes, on
    an object turned 30 degrees about z, moved, and with a texture space of its own: the
    direction about the axis through the texture space's centre, in world space."""
    ax, ay = 0.3, 0.1
    floor = _sunlit_textured_floor({}, np.ones((2, 2, 3), np.float32), (0, 0, 1), 10.0, 0.5, (8, 8))
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    world_from_object = np.array([[c, -s, 0.0, 0.2], [s, c, 0.0, -0.1], [0.0, 0.0, 1.0, 0.0]])
    rot, move = world_from_object[:, :3], world_from_object[:, 3]
    object_from_world = np.concatenate([rot.T, (-rot.T @ move)[:, None]], axis=1)
    # Object-space vertices: the floor's, placed by the transform.
    vertices = (floor.vertices.astype(np.float64) @ rot.T + move).astype(np.float32)
    space = ((0.1, 0.0, 0.3), (0.5, 0.5, 0.5))                 # texture space: location, size
    scene = with_one_object(floor.replace(vertices=vertices), space)
    scene = scene.replace(object_from_world=object_from_world[None])
    for axis in (bsdf.TANGENT_RADIAL_X, bsdf.TANGENT_RADIAL_Y, bsdf.TANGENT_RADIAL_Z):
        mats = Materials.build([{"name": "g", "glossy": 1.0, "roughness": (ax * ay) ** 0.25,
                                 "glossy_stretch": math.sqrt(ax / ay), "glossy_tangent": axis}])
        ctx = RenderContext(scene.replace(materials=mats).validate())
        rng = np.random.default_rng(7200 + axis)
        n = 50
        prim = rng.integers(0, 2, n)
        b1, b2 = rng.random(n) * 0.5, rng.random(n) * 0.5
        surf = ctx.surface(prim, b1, b2)
        p_obj = (surf.position - move) @ rot                       # object space
        g = (p_obj - np.array(space[0])) / (2.0 * np.array(space[1])) + 0.5
        x, y, z = (g - 0.5).T
        raw = [np.stack([0 * x, -z, y], 1), np.stack([-z, 0 * x, x], 1), np.stack([-y, x, 0 * x], 1)][axis]
        t = raw @ rot.T                                             # rotations: normals turn as vectors
        t = t - np.sum(t * surf.ns, axis=1, keepdims=True) * surf.ns
        length = np.linalg.norm(t, axis=1, keepdims=True)
        ok = length[:, 0] > 1e-6
        assert ok.sum() > n // 2
        assert np.allclose(surf.tangent[ok], (t / np.where(length > 0, length, 1.0))[ok], atol=1e-6)


def test_anisotropy_is_validated():
    """A UV tangent needs the scene's tangents; the stretch must lie in [0.01, 100]."""
    floor = _sunlit_textured_floor({}, np.ones((2, 2, 3), np.float32), (0, 0, 1), 10.0, 0.5, (8, 8))
    uv = Materials.build([{"name": "g", "glossy": 1.0, "glossy_stretch": 2.0,
                           "glossy_tangent": bsdf.TANGENT_UV}])
    with pytest.raises(SceneError, match="no tangents"):
        floor.replace(materials=uv).validate()
    mapped = Materials.build([{"name": "g", "glossy": 1.0, "glossy_tangent": bsdf.TANGENT_UV,
                               "stretch_program": {"op": "attribute", "name": "uv"}}])
    with pytest.raises(SceneError, match="no tangents"):
        floor.replace(materials=mapped).validate()
    for bad in (0.0, 1e3):
        mats = Materials.build([{"name": "g", "glossy": 1.0, "glossy_stretch": bad}])
        with pytest.raises(SceneError, match="glossy_stretch"):
            floor.replace(materials=mats).validate()
    isotropic = Materials.build([{"name": "g", "glossy": 1.0, "glossy_tangent": bsdf.TANGENT_UV}])
    assert not bsdf.MaterialTable.from_materials(floor.replace(materials=isotropic).validate().materials) \
        .has_anisotropy


def ref_albedo(wo, ax, ay, n=1_000_000, seed=7300):
    """Directional albedo of the single-scattering lobe from local ``wo``: E = integral of D(m)
    cos_m G2 (wo.m) / (cos_o cos_m) over the projected microfacets, by sampling their slopes
    (s_x / ax, s_y / ay has the density (1 + r^2)^-2 / pi)."""
    rng = np.random.default_rng(seed)
    t, phi = rng.random(n), 2.0 * np.pi * rng.random(n)
    r = np.sqrt(t / (1.0 - t))
    m = np.stack([-ax * r * np.cos(phi), -ay * r * np.sin(phi), np.ones(n)], axis=1)
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    wo = np.tile(wo, (n, 1))
    om = np.sum(wo * m, axis=1)
    wi = 2.0 * om[:, None] * m - wo
    g2 = 1.0 / (1.0 + ref_lambda(wo, ax, ay) + ref_lambda(wi, ax, ay))
    value = np.where((om > 0) & (wi[:, 2] > 0), g2 * om / (wo[:, 2] * m[:, 2]), 0.0)
    return value.mean()


@pytest.mark.parametrize("tangent, along", [((0, 1, 0), True), ((1, 0, 0), False)])
def test_camera_paths_go_on_through_a_smooth_brushed_floor_in_its_tangents_frame(tangent, along):
    """A nearly smooth anisotropic glossy (roughness 0.08 < ``glossy_through_roughness``) is a
    lobe camera paths go on through: under a white sky at 80 degrees from the normal the floor
    shows its directional albedo, lower with the wide alpha along the view's azimuth (0.954)
    than across it (0.999)."""
    ax, ay = 0.05, 0.00125
    theta = math.radians(80.0)
    mats = Materials.build([{"name": "brushed", "glossy": 1.0, "roughness": (ax * ay) ** 0.25,
                             "glossy_multiscatter": 0.0, "glossy_stretch": math.sqrt(ax / ay),
                             "glossy_tangent": bsdf.TANGENT_UV}])
    scene = floor_scene({"name": "floor"}, theta)
    frame = np.concatenate([np.asarray(tangent, np.float32), [1.0]]).astype(np.float32)
    corners = scene.vertices[scene.triangles]
    scene = scene.replace(materials=mats, uvs=corners[..., :2],
                          tangents=np.broadcast_to(frame, (2, 3, 4))).validate()
    assert RenderContext(scene).table.glossy_through.all()
    # The view's direction in the lobe's frame: its azimuth (-y) along or across the tangent.
    wo = np.array([0.0, -math.sin(theta), math.cos(theta)])
    wo_l = wo[[1, 0, 2]] if along else wo
    expected = ref_albedo(wo_l, ax, ay)
    mean = render_mean(scene, method="ppm", passes=16, photons_per_pass=1000, seed=4)
    assert np.allclose(mean, expected, rtol=0.01), (mean, expected)


def test_brushed_and_plain_points_gather_side_by_side():
    """Points of an anisotropic and of an isotropic glossy lobe in one gather (a floor of two
    halves, x < 0 brushed along the sun's azimuth, x > 0 isotropic of the same mean alpha): each
    half shows its own lobe, E cos f, the brushed one 7.4 and the plain one 1.03."""
    ax, ay, sun_angle = 0.32, 0.08, 0.7
    sun = np.array([math.sin(sun_angle), 0.0, math.cos(sun_angle)])
    m = MeshBuilder()
    m.add_quad((-0.5, -0.5, 0), (0.0, -0.5, 0), (0.0, 0.5, 0), (-0.5, 0.5, 0), 0)
    m.add_quad((0.0, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (0.0, 0.5, 0), 1)
    lights = Lights.build([{"kind": "sun", "direction": -sun, "power": 10.0}])
    cam = Camera(world_from_camera=_look_down(0.5), projection="orthographic", frame=(-0.1, 0.1, -0.1, 0.1),
                 resolution=(16, 8))
    mats = Materials.build([{"name": "brushed", "glossy": 1.0, "roughness": (ax * ay) ** 0.25,
                             "glossy_multiscatter": 0.0, "glossy_stretch": math.sqrt(ax / ay),
                             "glossy_tangent": bsdf.TANGENT_UV},
                            {"name": "plain", "glossy": 1.0, "roughness": (ax * ay) ** 0.25,
                             "glossy_multiscatter": 0.0}])
    scene = m.build(Materials.build([{"name": "a"}, {"name": "b"}]), lights, cam)
    frame = np.array([1.0, 0.0, 0.0, 1.0], np.float32)
    scene = scene.replace(materials=mats, uvs=scene.vertices[scene.triangles][..., :2],
                          tangents=np.broadcast_to(frame, (4, 3, 4))).validate()
    img = render(scene, RenderSettings(method="ppm", passes=8, photons_per_pass=40000, workers=1,
                                       seed=5)).image[..., :3].mean(axis=2)
    one = np.array([[0.0, 0.0, 1.0]])
    brushed = 10.0 * sun[2] * ref_f_and_pdf(one, sun[None], ax, ay)[0][0]
    plain = 10.0 * sun[2] * ref_f_and_pdf(one, sun[None], math.sqrt(ax * ay), math.sqrt(ax * ay))[0][0]
    assert brushed / plain > 4.0
    assert img[:, :6].mean() == pytest.approx(brushed, rel=0.04)
    assert img[:, 10:].mean() == pytest.approx(plain, rel=0.04)

"""Closed-form scenes (testing.md 2a): image means against exact values, for SPPM and AMCMCPPM.

Each render keeps its per-pass estimates (the passes are independent), so the
tolerance is a z-test at 4 standard errors plus a small fixed margin for what
the closed form leaves out (tessellation, kernel bias where noted).
"""
import numpy as np
import pytest

from core import RenderSettings, render
from core.bsdf import DIELECTRIC, MaterialTable, scatter
from core.integrator import kz_radius_scales
from core.scene import Materials
from core.testing.scenes import (camera_in_glass, disk_irradiance, furnace_sphere, kernel_radius_px,
                                 point_in_sphere, sky_over_floor, spot_over_plane,
                                 sun_over_bumped_floor, sun_over_normal_mapped_floor,
                                 sun_over_procedural_floor, sun_through_slab)


def render_passes(scene, **settings):
    """Image mean of every pass's own estimate (independent for PPM) and the final image.

    The closed forms are of the plain estimate at the gather radius (with its kernel bias where
    noted), so the image is rendered without the bias correction unless asked for; the corrected
    image has its own closed-form test in ``test_bias_correction.py``."""
    settings.setdefault("bias_correction", False)
    s = RenderSettings(workers=1, **settings)

    def check(result):
        assert np.isfinite(result.image).all()

    result = render(scene, s, on_iteration=check)
    per_pass = np.array([st["pass_mean"] for st in result.stats])
    if s.method == "ppm":
        # The image averages the passes weighted by their photons (AMCMCPPM's cumulative
        # visible fraction makes its image differ from the passes' own estimates).
        n = np.array([st["photons_recorded"] for st in result.stats], float)
        assert result.image[..., :3].mean() == pytest.approx((n * per_pass).sum() / n.sum(), rel=1e-5)
    return per_pass, result


def check_mean(per_pass, expected, rel_margin):
    mean = per_pass.mean()
    se = per_pass.std(ddof=1) / np.sqrt(len(per_pass))
    assert abs(mean - expected) < 4 * se + rel_margin * expected, (mean, expected, se)
    return mean, se


METHODS = [dict(method="ppm"), dict(method="amcmcppm", chains=4096)]
# Closed forms of a BSDF alone, the same for both methods: the chains' case (15-20 s) in the slow
# tier, to keep make test within its budget.
PPM_FAST = [METHODS[0], pytest.param(METHODS[1], marks=pytest.mark.slow)]


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
@pytest.mark.parametrize("albedo,emission", [(0.5, 0.5), (0.8, 1.0)])
def test_furnace_sphere_emitting_inside(method, albedo, emission):
    bounces = 40
    expected = emission * (1 - albedo ** (bounces + 2)) / (1 - albedo)   # eye Le + B + 1 deposits
    per_pass, _ = render_passes(furnace_sphere(albedo, emission), passes=6, photons_per_pass=20_000,
                                max_bounces=bounces, **method)
    # Flat-faceted sphere of 4096 triangles: its area differs from the sphere's by ~0.2 %.
    check_mean(per_pass, expected, 0.01)


@pytest.mark.parametrize("method", PPM_FAST, ids=lambda m: m["method"])
def test_point_light_in_sphere_is_scale_invariant(method):
    albedo, bounces = 0.5, 30
    means = []
    for radius in (1e-3, 1.0, 1e4):
        power = 4 * np.pi * radius ** 2                  # I = R^2, so L is the same at every scale
        intensity = power / (4 * np.pi)
        expected = albedo * intensity / (np.pi * radius ** 2) * (1 - albedo ** (bounces + 1)) / (1 - albedo)
        per_pass, _ = render_passes(point_in_sphere(radius, albedo, power), passes=6,
                                    photons_per_pass=20_000, max_bounces=bounces, **method)
        means.append(check_mean(per_pass, expected, 0.01)[0])
    assert np.ptp(means) < 0.02 * np.mean(means)


def kernel_estimate(kernel_radius, passes=8, photons=150_000, alpha=2 / 3, **kw):
    scene = spot_over_plane(kernel_radius=kernel_radius, **kw)
    per_pass, _ = render_passes(scene, method="ppm", passes=passes, photons_per_pass=photons,
                                max_bounces=1, alpha=alpha, direct_light="photons",
                                initial_radius_px=kernel_radius_px(scene, kernel_radius))
    return per_pass


def test_point_light_over_plane_has_the_disk_kernel_bias():
    albedo, power, h = 0.5, 100.0, 1.0
    intensity = power / (4 * np.pi)
    exact = albedo * intensity / (np.pi * h * h)            # no kernel
    biases = []
    for r in (0.3, 0.15):
        per_pass = kernel_estimate(r)
        radii = r * kz_radius_scales(len(per_pass), 2 / 3)
        expected = albedo / np.pi * disk_irradiance(intensity, h, radii).mean()
        mean, _ = check_mean(per_pass, expected, 0.002)
        assert mean < exact                                    # the disk average is darker
        biases.append(1 - mean / exact)
    # Bias ~ 0.75 r^2 / h^2: halving the radius quarters it.
    assert 4 * 0.8 < biases[0] / biases[1] < 4 * 1.2, biases


def test_mirror_caustic_from_a_spot_pointing_up():
    albedo, power, h, mirror_height, reflectance, r = 0.5, 100.0, 1.0, 2.0, 0.9, 0.2
    intensity = power / (4 * np.pi)
    distance = 2 * mirror_height - h                           # apparent source behind the mirror
    scene = spot_over_plane(height=h, albedo=albedo, power=power, kernel_radius=r,
                            up_mirror=mirror_height, mirror_reflectance=reflectance)
    per_pass, _ = render_passes(scene, method="ppm", passes=8, photons_per_pass=100_000, max_bounces=1,
                                initial_radius_px=kernel_radius_px(scene, r))
    radii = r * kz_radius_scales(len(per_pass), 2 / 3)
    expected = albedo / np.pi * reflectance * disk_irradiance(intensity, distance, radii).mean()
    check_mean(per_pass, expected, 0.003)


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
@pytest.mark.parametrize("fresnel", [1.0, 0.5, 0.0], ids=["glass", "half_refraction", "refraction"])
def test_sun_through_glass_slab_single_pass_transmittance(method, fresnel):
    """(1 - s F0)^2 of the direct light for the share s of the glass that reflects by Fresnel:
    0.9216 for a Glass BSDF, all of it for a Refraction BSDF (s = 0, stop 42; before, the
    Refraction BSDF was a glass: 0.9216) and 0.9604 for a Mix of both."""
    ior, irradiance, albedo = 1.5, 10.0, 0.5
    f0 = ((ior - 1) / (ior + 1)) ** 2
    expected = albedo / np.pi * irradiance * (1 - fresnel * f0) ** 2
    per_pass, _ = render_passes(sun_through_slab(ior, irradiance, albedo, fresnel=fresnel), passes=8,
                                photons_per_pass=100_000, max_bounces=2, **method)
    check_mean(per_pass, expected, 0.005)


def test_a_refraction_only_glass_never_reflects_and_ends_at_total_internal_reflection():
    """``scatter`` on a smooth glass of ``dielectric_fresnel`` 0 (Blender's Refraction BSDF): from
    outside every path refracts with the glass's colour as its weight (photons: over eta^2, Cycles'
    convention); from inside beyond the critical angle every path ends (Cycles: no transmission,
    no reflection), below it every path refracts."""
    mats = Materials.build([{"name": "refraction", "dielectric": (0.9, 0.8, 0.7), "ior": 1.5,
                             "dielectric_fresnel": 0.0, "dielectric_reflection": 0.0}])
    table = MaterialTable.from_materials(mats)
    n = 10_000
    rng = np.random.default_rng(3)
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    ids = np.zeros(n, np.int32)
    colors = table.color.take(ids, axis=0)
    lobe = np.full(n, DIELECTRIC)
    for cos, inside, alive in ((0.3, False, True), (0.9, True, True), (0.5, True, False)):
        wo = np.tile([np.sqrt(1 - cos * cos), 0.0, cos], (n, 1))
        ng = -up if inside else up                     # (wo on the back: inside the glass)
        wi, weight, ok = scatter(table, ids, colors, lobe, np.ones(n), wo, ng, ng, rng.random(n),
                                 rng.random(n), "importance")
        assert ok.all() if alive else not ok.any()
        if alive:
            assert (wi[:, 2] < 0).all()                # through the surface, never reflected
            eta = 1.0 / 1.5 if inside else 1.5
            np.testing.assert_allclose(weight, np.broadcast_to([0.9, 0.8, 0.7], (n, 3)) / eta ** 2, rtol=1e-6)


def bump_shadowing_g(n, cos_i):
    """Cycles' bump shadowing: GGX G1 with alpha^2 = tan^2(n, z) / 8 at the light's cosine
    ``cos_i`` to z, the unbent normal (Conty Estevez et al. 2019)."""
    alpha2 = min(0.125 * (np.dot(n, n) / n[2] ** 2 - 1), 1.0)
    return 2 / (1 + np.sqrt(1 + alpha2 * (1 - cos_i ** 2) / cos_i ** 2))


A40 = np.radians(40.0)
TILT_X = (np.sin(A40), 0.0, np.cos(A40))         # the map's normal, 40 degrees towards the tangent
TILT_Y = (0.0, np.sin(A40), np.cos(A40))         # ... towards the bitangent
TILT_X80 = (np.sin(np.radians(80.0)), 0.0, np.cos(np.radians(80.0)))


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
@pytest.mark.parametrize("case", [
    # (map normal, sun direction, tangent, bitangent sign, strength, expected N . l)
    (TILT_X, TILT_X, (1, 0, 0), 1.0, 1.0, 1.0),                     # bent straight at the sun
    (TILT_X, TILT_X, (-1, 0, 0), 1.0, 1.0, np.cos(2 * A40)),        # the tangent decides the side
    (TILT_Y, TILT_Y, (1, 0, 0), 1.0, 1.0, 1.0),                     # B = w (N x T) = +y
    (TILT_Y, TILT_Y, (1, 0, 0), -1.0, 1.0, np.cos(2 * A40)),        # the sign flips B
    (TILT_X80, (0, 0, 1), (1, 0, 0), 1.0, 0.5, None),               # strength 0.5 (below)
    (TILT_X, (0, 0, 1), (1, 0, 0), 1.0, 2.0, None),                 # strength 2
], ids=["tangent", "tangent_reversed", "bitangent", "bitangent_sign", "half_strength", "double_strength"])
def test_normal_map_bends_the_shading_normal_as_cycles(method, case):
    """A sun over a floor whose constant normal map tilts its shading normal N: albedo E (N . l) G / pi,
    which the photons give through the shading-normal density ratio |N . l| / |Ng . l|, times
    Cycles' bump shadowing G of the sun direction about the floor's own normal."""
    normal, sun, tangent, sign, strength, cos_nl = case
    n = np.array(normal)
    if cos_nl is None:
        # Cycles: tangent-plane components times the strength, the normal one blended from 1
        # by min(strength, 1) (80 degrees at strength 0.5: 40 degrees, against 71 without the blend).
        n = np.array([normal[0] * strength, normal[1] * strength, 1 + (normal[2] - 1) * min(strength, 1.0)])
        cos_nl = n[2] / np.linalg.norm(n)
    g = bump_shadowing_g(n, np.asarray(sun)[2] / np.linalg.norm(sun))
    irradiance, albedo = 10.0, 0.5
    scene = sun_over_normal_mapped_floor(normal, sun, tangent, sign, strength, irradiance, albedo)
    per_pass, _ = render_passes(scene, passes=6, photons_per_pass=50_000, max_bounces=1, **method)
    check_mean(per_pass, albedo / np.pi * irradiance * cos_nl * g, 0.01)


@pytest.mark.parametrize("correction", [True, False], ids=["correction", "no_correction"])
def test_bump_map_correction_off_keeps_the_side_test_alone(correction):
    """A map normal 80 degrees off the floor's, facing a sun 80 degrees from the zenith: N . l = 1,
    so albedo E / pi, times Cycles' bump shadowing G (0.30 here) with Bump Map Correction, and
    without it (stop 42, ``Materials.bump_correction``; before, always G) the light in full."""
    n = np.asarray(TILT_X80)
    g = bump_shadowing_g(n, n[2]) if correction else 1.0
    irradiance, albedo = 10.0, 0.5
    scene = sun_over_normal_mapped_floor(TILT_X80, TILT_X80, (1, 0, 0), 1.0, 1.0, irradiance, albedo,
                                         correction=correction)
    per_pass, _ = render_passes(scene, passes=6, photons_per_pass=50_000, max_bounces=1, method="ppm")
    check_mean(per_pass, albedo / np.pi * irradiance * g, 0.01)


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
@pytest.mark.parametrize("distance, strength, towards", [
    (0.8, 1.0, -1.0),         # the sun where the bumped normal points: N . l = 1
    (0.8, 1.0, 1.0),          # the mirror image: N . l = cos(2 atan 0.8)
    (-0.8, 1.0, 1.0),         # a negative distance (Invert) bends the other way: 1 again
    (0.8, 0.5, -1.0),         # strength 0.5: halfway between z and the bumped normal
], ids=["facing", "away", "inverted", "half_strength"])
@pytest.mark.parametrize("procedural", [False, True, "op"], ids=["image", "program", "normal_program"])
def test_bump_map_bends_the_shading_normal_as_cycles(method, distance, strength, towards, procedural):
    """A sun over a floor whose height rises along u (an image, or a program of the Object
    coordinates, as the material's bump or, since stop 42, as a ``bump`` op in its normal
    program): Cycles' Bump node gives the normal normalize(z - d h_u x), blended with z by the
    strength; radiance albedo E (N . l) G / pi."""
    slope = 1.0
    bent = np.array([-distance * slope, 0.0, 1.0])
    bent /= np.linalg.norm(bent)
    sun = np.array([towards * np.sin(np.arctan(0.8)), 0.0, np.cos(np.arctan(0.8))])
    n = strength * bent + (1 - strength) * np.array([0.0, 0.0, 1.0])
    n /= np.linalg.norm(n)
    irradiance, albedo = 10.0, 0.5
    scene = sun_over_bumped_floor(slope, distance, strength, sun, irradiance, albedo, procedural=procedural)
    expected = albedo / np.pi * irradiance * max(n @ sun, 0.0) * bump_shadowing_g(n, sun[2])
    per_pass, _ = render_passes(scene, passes=6, photons_per_pass=50_000, max_bounces=1, **method)
    check_mean(per_pass, expected, 0.01)


def test_camera_inside_glass_sees_the_radiance_outside_unscaled():
    """As Cycles, camera paths leaving the glass do not scale the radiance by eta^2 (stop 43; before,
    they did: 2.16 Le, physically right, and 2.25 times Cycles for a camera looking out through a
    single-sided pane, test_what_lies_behind_or_inside_glass_matches_cycles)."""
    ior, emission, bounces = 1.5, 1.0, 8
    f0 = ((ior - 1) / (ior + 1)) ** 2
    round_trips = np.sum(f0 ** (2 * np.arange((bounces + 1) // 2)))
    expected = (1 - f0) * emission * round_trips   # 0.96 Le
    per_pass, _ = render_passes(camera_in_glass(ior, emission), method="ppm", passes=8,
                                photons_per_pass=1000, max_bounces=bounces)
    check_mean(per_pass, expected, 0.002)


def sky_halves(scene, method, seeds, passes, per_seed=False, **settings):
    """Mean grey of the far (top rows, grazing) and near (bottom rows, face on) half of the
    image of ``scene`` over ``seeds`` renders of ``passes`` passes of 40,000 photons (with
    ``per_seed``, the (seeds, 2) values instead)."""
    runs = []
    for seed in range(seeds):
        _, result = render_passes(scene, passes=passes, photons_per_pass=40_000, seed=seed, **settings,
                                  **method)
        rgb = result.image[..., :3].mean(axis=2)
        h = rgb.shape[0] // 2
        runs.append([rgb[:h].mean(), rgb[h:].mean()])
    return np.array(runs) if per_seed else np.mean(runs, axis=0)


@pytest.mark.parametrize("method", [METHODS[0], pytest.param(METHODS[1], marks=pytest.mark.slow)],
                         ids=lambda m: m["method"])     # (the chains' case: make test's budget)
def test_floor_under_a_constant_sky_is_albedo_times_sky_near_and_far(method):
    """L = albedo * sky on all of an open floor, in the near (face-on) and far (grazing) half.

    With a small gather radius and few chain steps per pass, Markov chains whose visible set
    is just "deposits in this pass" carried their states from pass to pass where the last
    pass's gather discs covered the floor best, and drifted: after 24 passes the near half was
    1.8 times too bright and the far half 1.25 times (``core/visible_cells.py``).  Both halves
    are checked for each of three seeds' means against a 10 % margin (measured now: within 4 %).
    """
    albedo, sky = 0.5, 1.0
    scene = sky_over_floor(albedo, sky, resolution=(32, 32))
    # (the photons' direct light: the one the chains seek here; light samples make it exact)
    far, near = sky_halves(scene, method, 3, 24, initial_radius_px=1.5,
                           direct_light="photons") / (albedo * sky)
    assert abs(far - 1) < 0.10 and abs(near - 1) < 0.10, (far, near)


@pytest.mark.slow
def test_amcmcppm_floor_under_a_constant_sky_has_no_near_far_bias_to_a_percent():
    """The same floor, 96 seeds of 16 short passes (about ten iterations per chain per pass,
    visible fraction 1.4 %).  Per seed, near half minus far half: 0 exactly.  With a mutation
    size adapted per chain (``core/mcmc.py``, "Adaptation") the chains' states drifted off
    the uniform distribution over V towards the near floor, and the difference was 0.022
    (near 1.019, far 0.996; six standard errors); with one pooled size 0.003 (144 seeds)."""
    albedo = 0.5
    runs = sky_halves(sky_over_floor(albedo, 1.0, resolution=(32, 32)), dict(method="amcmcppm"), 96, 16,
                      per_seed=True, direct_light="photons") / albedo      # (the chains' photons)
    diff = runs[:, 1] - runs[:, 0]
    se = diff.std(ddof=1) / np.sqrt(len(diff))
    assert abs(diff.mean()) < 4 * se, (diff.mean(), se, runs.mean(axis=0))
    assert np.all(np.abs(runs.mean(axis=0) - 1) < 0.015), runs.mean(axis=0)


@pytest.mark.parametrize("method", PPM_FAST, ids=lambda m: m["method"])
def test_white_multiscatter_glossy_floor_under_a_constant_sky_reflects_the_sky_exactly(method):
    """White furnace for the glossy lobe: a white rough GGX floor (roughness 0.8) with Cycles'
    multiscatter energy compensation reflects L = sky at every view angle, near (face on) and
    far (grazing).  Without the compensation it is sky E(mu): the halves measured 0.59 (near)
    and 0.69 (far), so the check below fails by far.  With it, the four seeds' halves spread
    by +-0.05 around means of 1.00-1.02 (both methods), hence the margin of 0.07; on 8 seeds x
    32 passes at roughness 1 all of eight bands were within 1 +- 0.03."""
    sky = 1.0

    def halves(multiscatter, seeds, passes):
        scene = sky_over_floor(1.0, sky, resolution=(32, 32), glossy_roughness=0.8, multiscatter=multiscatter)
        return sky_halves(scene, method, seeds, passes) / sky

    far, near = halves(True, 4, 24)
    assert abs(far - 1) < 0.07 and abs(near - 1) < 0.07, (far, near)
    single = halves(False, 1, 16)
    assert (single < 0.8).all(), single


def principled_white(roughness, layer_f0=None):
    """A white Principled-like dielectric (IOR 1.5): GGX layer of f0 = 0.04 rising to 1 with the
    Fresnel curve, multiscatter, over a white diffuse under the layer (``diffuse_layer``)."""
    f0 = 0.04
    return {"diffuse": 1.0, "glossy": f0, "roughness": roughness, "glossy_fresnel_ior": 1.5,
            "glossy_fresnel_rise": 1.0 - f0, "glossy_multiscatter": 0.1,
            "diffuse_layer": f0 if layer_f0 is None else layer_f0}


@pytest.mark.parametrize("method", PPM_FAST, ids=lambda m: m["method"])
def test_white_principled_floor_under_a_constant_sky_reflects_the_sky_exactly(method):
    """White furnace for Cycles' Principled layering: what the Fresnel layer reflects at a view
    angle (glossy points, whose photons take the colour of their half vector's Fresnel) the
    diffuse under it gives up (its weight 1 - the layer's albedo at the point's view), so the
    floor reflects the sky exactly, face on and grazing.  12 seeds x 16 passes measured
    0.992 / 0.997 (AMCMCPPM, far / near half, standard errors 0.004 / 0.006).  The control
    claims a layer of f0 = 0.5 over the diffuse, which it then loses: below 0.9."""
    sky = 1.0

    def halves(material, seeds, passes):
        return sky_halves(sky_over_floor(1.0, sky, resolution=(32, 32), material=material), method,
                          seeds, passes) / sky

    far, near = halves(principled_white(0.5), 4, 16)
    # Glossy points without the rise in their pairs' colours measured 0.93-0.94 far.
    assert abs(far - 1) < 0.04 and abs(near - 1) < 0.04, (far, near)
    control = halves(principled_white(0.5, layer_f0=0.5), 1, 8)
    assert (control < 0.9).all(), control


def light_over_mirror(spec, camera_up=False, occluder=False, mirror=0.9, profiles=None):
    """A light 3 m over a mirror floor; the camera 1 m over it looks down (or, ``camera_up``,
    from the floor straight at the light).  Nothing diffuse: the image is the light alone.
    ``profiles``: the lights' angular profiles (``Lights.profiles``)."""
    from core.scene import Camera, Lights, Materials
    from core.testing.scenes import MeshBuilder
    mats = Materials.build([{"name": "mirror", "mirror": mirror}, {"name": "black", "diffuse": 0.0}])
    m = MeshBuilder()
    h = 25.0
    m.add_quad((-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0), 0)
    if occluder:
        m.add_quad((-0.4, -0.4, 2), (0.4, -0.4, 2), (0.4, 0.4, 2), (-0.4, 0.4, 2), 1)
    eye, target = ((0, 0, 0.01), (0, 0, 3)) if camera_up else ((0, 0, 1), (0, 0, 0))
    cam = Camera.look_at(eye, target, lens_mm=50.0, resolution=(16, 16))
    spec = {"position": (0, 0, 3), "direction": (0, 0, -1), **spec}
    lights = Lights.build([spec])
    lights.profiles = profiles
    return m.build(mats, lights, cam)


LIGHTS_SEEN = {   # spec, radiance
    "area": ({"kind": "area", "size": (1.0, 1.0), "power": 10.0}, 10.0 / np.pi),
    "ellipse": ({"kind": "disk", "size": (1.0, 0.8), "power": 10.0}, 10.0 / (np.pi * np.pi * 0.5 * 0.4)),
    "sphere": ({"kind": "point", "radius": 0.5, "power": 10.0, "soft_falloff": False},
               10.0 / (4 * np.pi ** 2 * 0.25)),
    "disk-facing point": ({"kind": "point", "radius": 0.5, "power": 10.0}, 10.0 / (4 * np.pi ** 2 * 0.25)),
    "spot": ({"kind": "spot", "radius": 0.5, "power": 10.0, "spot_angle": 1.0, "spot_blend": 0.3},
             10.0 / (4 * np.pi ** 2 * 0.25)),
    "sun": ({"kind": "sun", "sun_angle": np.radians(20.0), "power": 3.0},
            3.0 / (np.pi * np.sin(np.radians(10)) ** 2)),
}


@pytest.mark.parametrize("name", list(LIGHTS_SEEN))
def test_lights_seen_in_a_mirror_show_their_radiance_and_follow_their_visibility(name):
    """The centre pixels see the light's own radiance times the mirror's colour, exactly (camera
    paths only: no photon lands on a mirror).  Lights hide from reflections when their
    visibility says so, behind an occluder, and (area lights) from behind."""
    from core.scene import VISIBLE_CAMERA, VISIBLE_GLOSSY
    spec, radiance = LIGHTS_SEEN[name]
    settings = RenderSettings(method="ppm", passes=2, photons_per_pass=100, workers=1)

    def centre(scene):
        image = render(scene, settings).image
        assert np.isfinite(image).all()
        return image[7:9, 7:9, :3]

    np.testing.assert_allclose(centre(light_over_mirror(spec)), 0.9 * radiance, rtol=1e-5)
    assert centre(light_over_mirror({**spec, "visibility": VISIBLE_CAMERA})).max() == 0.0
    assert centre(light_over_mirror(spec, occluder=True)).max() == 0.0
    if spec["kind"] in ("area", "disk"):
        assert centre(light_over_mirror({**spec, "direction": (0, 0, 1)})).max() == 0.0
    if spec["kind"] != "sun":       # straight at the light from the floor: camera rays only
        assert centre(light_over_mirror(spec, camera_up=True)).max() == 0.0
        both = {**spec, "visibility": VISIBLE_CAMERA | VISIBLE_GLOSSY}
        seen = centre(light_over_mirror(both, camera_up=True))
        np.testing.assert_allclose(seen, radiance, rtol=1e-5)


@pytest.mark.parametrize("soft_falloff", (True, False), ids=("soft", "sphere"))
def test_point_light_of_radius_half_its_height_lights_the_floor_as_cycles(soft_falloff):
    """A point light of radius r = h / 2 over a diffuse floor, the disk kernel of radius R at its
    foot.  As a sphere it lights the floor as a point: E = I cos / d^2.  With Soft Falloff
    Cycles makes it a disk facing the receiver: E = I cos / (d^2 + r^2), whose mean over the
    kernel is (2 I h / (r R^2)) (atan(sqrt(h^2 + R^2) / r) - atan(h / r)); 21 % less here."""
    from core.testing.scenes import point_light_over_floor
    albedo, power, h, r, kernel = 0.5, 100.0, 1.0, 0.5, 0.2
    intensity = power / (4 * np.pi)
    scene = point_light_over_floor(h, r, soft_falloff, albedo, power)
    per_pass, _ = render_passes(scene, method="ppm", passes=8, photons_per_pass=200_000, max_bounces=1,
                                initial_radius_px=kernel_radius_px(scene, kernel), direct_light="photons")
    radii = kernel * kz_radius_scales(len(per_pass), 2 / 3)
    if soft_falloff:
        e = (2 * intensity * h / (r * radii ** 2)
             * (np.arctan(np.sqrt(h * h + radii ** 2) / r) - np.arctan(h / r)))
    else:
        e = disk_irradiance(intensity, h, radii)
    check_mean(per_pass, albedo / np.pi * e.mean(), 0.005)


@pytest.mark.parametrize("gap", (0.0, 0.05), ids=("resting", "floating"))
def test_glass_slab_resting_on_a_floor_traps_light_as_in_closed_form(gap):
    """A wide glass slab (n = 1.45) on a diffuse floor (albedo 0.5) under a uniform sky, seen
    straight down.  Resting on it (the slab's bottom face in the floor's plane) there is no
    glass-air interface below: light enters the top (1 - R), the floor's light escapes only
    through the top, a fraction f = (1 - R) / n^2, and the rest returns to the floor, so
    E = pi (1 - R) / (1 - rho (1 - f)) and the camera sees R0 + rho E / pi (1 - R0) / n^2 =
    0.327 (R the hemispherical mean Fresnel, R0 the normal one).  With the coincident faces
    told apart only by ray offsets, rays left through the bottom under the floor (``Accel.
    with_contacts``).  Floating 5 cm higher the same slab gives about 0.49 (two interfaces each
    way), which the resting value must not be."""
    from core.scene import Camera, Materials, World
    from core.testing.scenes import MeshBuilder, _look_down
    n, rho = 1.45, 0.5
    mats = Materials.build([{"name": "floor", "diffuse": rho},
                            {"name": "glass", "dielectric": 1.0, "ior": n}])
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    m.add_box((-15, -15, gap), (15, 15, gap + 0.2), 1)
    cam = Camera(world_from_camera=_look_down(1.0), projection="orthographic", frame=(-4, 4, -4, 4),
                 resolution=(32, 32))
    scene = m.build(mats, camera=cam, world=World(color=np.ones(3, np.float32)))
    per_pass, _ = render_passes(scene, method="ppm", passes=8, photons_per_pass=200_000, max_bounces=16)
    mu = (np.arange(100_000) + 0.5) / 100_000
    cos_t = np.sqrt(1 - (1 - mu * mu) / n ** 2)
    fresnel = 0.5 * (((mu - n * cos_t) / (mu + n * cos_t)) ** 2 + ((n * mu - cos_t) / (n * mu + cos_t)) ** 2)
    r_mean, r0 = np.mean(2 * mu * fresnel), ((n - 1) / (n + 1)) ** 2
    escape = (1 - r_mean) / n ** 2
    resting = r0 + rho * (1 - r_mean) / (1 - rho * (1 - escape)) * (1 - r0) / n ** 2
    if gap == 0.0:
        check_mean(per_pass, resting, 0.02)             # measured 1.2 % over (the slab's rim)
    else:
        assert per_pass.mean() > 1.4 * resting


def test_floor_under_an_environment_image_gets_its_cosine_weighted_radiance():
    """A diffuse floor under an equirectangular sky image (dark below the horizon, uneven
    above, a bright patch): L = albedo / pi int L(w) cos dw over the upper hemisphere, the
    integral by quadrature of the image lookup; the photons come from the image's own
    importance sampling, so a wrong density or direction convention moves the mean."""
    from core.environment import Environment
    from core.scene import Camera, Materials, World
    from core.testing.scenes import MeshBuilder, _look_down
    rng = np.random.default_rng(7)
    h, w = 32, 64
    tex = np.zeros((h, w, 3), np.float32)
    tex[h // 2:] = 0.5 + rng.random((h // 2, w, 3)).astype(np.float32)     # rows from v = 0.5 up
    tex[h // 2 + 4:h // 2 + 8, 10:16] = 40.0                               # a sun-like patch
    albedo = 0.5
    mats = Materials.build([{"name": "floor", "diffuse": albedo}])
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    cam = Camera(world_from_camera=_look_down(1.0), projection="orthographic", frame=(-2, 2, -2, 2),
                 resolution=(16, 16))
    scene = m.build(mats, camera=cam, world=World(color=np.ones(3, np.float32), texture=tex))
    per_pass, _ = render_passes(scene, method="ppm", passes=8, photons_per_pass=100_000, max_bounces=1)
    # Quadrature of int L cos dw over the upper hemisphere (midpoints in cos theta and phi).
    env = Environment(np.ones(3), tex)
    c = (np.arange(400) + 0.5) / 400
    phi = (np.arange(800) + 0.5) / 800 * 2 * np.pi
    cc, pp = np.meshgrid(c, phi, indexing="ij")
    s = np.sqrt(1 - cc ** 2)
    dirs = np.stack([s * np.cos(pp), s * np.sin(pp), cc], axis=-1).reshape(-1, 3)
    irradiance = (env.radiance(dirs).mean(axis=1) * cc.ravel()).mean() * 2 * np.pi
    check_mean(per_pass, albedo / np.pi * irradiance, 0.01)


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_procedural_checker_floor_reflects_each_cells_colour(method):
    """A sun straight above a floor whose diffuse colour is a checker of object coordinates (four
    cells in view): every pixel away from the cell edges is colour E / pi.  The irradiance the
    photons give is uniform, so the colour must come from the point where the camera sees the
    floor, not from where the photons landed."""
    c1, c2 = np.array([0.8, 0.3, 0.1]), np.array([0.1, 0.2, 0.6])
    program = {"op": "checker", "vector": {"op": "attribute", "name": "object"},
               "color1": c1.tolist(), "color2": c2.tolist(), "scale": 4.0}
    irradiance, n = 10.0, 32
    scene = sun_over_procedural_floor(program, irradiance, resolution=(n, n))
    result = render(scene, RenderSettings(workers=1, passes=6, photons_per_pass=50_000, max_bounces=1,
                                          **method))
    # Cells of 0.25 m: the 0.2 m view shows the corners of four, meeting at the image centre.
    # Top left: x < 0 (cell -1), y > 0 (cell 0), z cell 0 -> colour 1 (Cycles' parity rule).
    img = result.image[..., :3]
    expected = np.where(np.arange(n)[:, None, None] < n // 2,
                        np.where(np.arange(n)[None, :, None] < n // 2, c1, c2),
                        np.where(np.arange(n)[None, :, None] < n // 2, c2, c1)) * irradiance / np.pi
    away = np.ones((n, n), bool)
    away[n // 2 - 2:n // 2 + 2, :] = away[:, n // 2 - 2:n // 2 + 2] = False
    for quadrant in ((slice(0, n // 2), slice(0, n // 2)), (slice(0, n // 2), slice(n // 2, n))):
        sel = away[quadrant]
        ratio = img[quadrant][sel].mean(axis=0) / expected[quadrant][sel].mean(axis=0)
        np.testing.assert_allclose(ratio, 1.0, rtol=0.03)
    # Pixel by pixel the colour is exact: the ratio of channels is the cell's.
    np.testing.assert_allclose((img[..., 0] / img[..., 2])[away], (expected[..., 0] / expected[..., 2])[away],
                               rtol=1e-6)


def test_camera_paths_through_glossy_lobes_see_the_same_white_furnace():
    """``glossy_through_roughness``: camera paths that go on through a glossy lobe (sampled from
    it) instead of ending there see the same white furnace, L = sky, as those that gather photons
    on it: a white multiscatter GGX floor of roughness 0.3 with every such lobe gone through
    (measured 1.001 / 1.000; 4 seeds x 16 passes, as the tests above)."""
    sky = 1.0
    spec = {"glossy": 1.0, "roughness": 0.3, "glossy_multiscatter": 1.0}
    scene = sky_over_floor(1.0, sky, resolution=(32, 32), material=spec)
    far, near = sky_halves(scene, METHODS[0], 4, 16, glossy_through_roughness=1.0) / sky
    assert abs(far - 1) < 0.04 and abs(near - 1) < 0.04, (far, near)

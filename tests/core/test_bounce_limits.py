"""Cycles' bounce limits (``RenderSettings.max_bounces``, ``diffuse_bounces``, ``glossy_bounces``,
``transmission_bounces``, ``volume_bounces``; ``core.settings.BounceLimits``) in closed-form scenes.  A light path
camera - x_1 ... x_n - light has n - 1 bounces: the vertex nearest the light does not count.
Against Cycles itself: ``tests/addon/test_addon_parity.py::test_bounce_limits_match_cycles``."""
import numpy as np
import pytest

from core import RenderSettings, render
from core.testing.scenes import furnace_sphere, sun_through_slab
from test_closed_form import LIGHTS_SEEN, check_mean, light_over_mirror, render_passes


@pytest.mark.parametrize("field,value", [("diffuse_bounces", -1), ("glossy_bounces", 65),
                                         ("transmission_bounces", 1.5 * 64), ("max_bounces", -1)])
def test_bounce_limits_out_of_range_are_refused_by_name(field, value):
    with pytest.raises(ValueError, match=field):
        RenderSettings(**{field: value})


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
@pytest.mark.parametrize("limit", [0, 2])
def test_furnace_keeps_to_the_diffuse_limit(method, limit):
    """Inside a furnace of albedo a and emission Le, a path with k diffuse bounces brings
    a^(k+1) Le: L = Le (1 - a^(L_d + 2)) / (1 - a), the total limit far above (20)."""
    albedo, emission = 0.5, 1.0
    expected = emission * (1 - albedo ** (limit + 2)) / (1 - albedo)
    per_pass, _ = render_passes(furnace_sphere(albedo, emission), method=method, passes=6,
                                photons_per_pass=20_000, max_bounces=20, diffuse_bounces=limit)
    check_mean(per_pass, expected, 0.01)


def test_two_workers_keep_to_the_limits_too():
    """The limits reach the worker processes with each pass's points."""
    albedo, emission = 0.5, 1.0
    settings = RenderSettings(method="ppm", passes=4, photons_per_pass=20_000, workers=2, max_bounces=20,
                              diffuse_bounces=1, bias_correction=False)
    per_pass = np.array([st["pass_mean"] for st in render(furnace_sphere(albedo, emission), settings).stats])
    check_mean(per_pass, emission * (1 + albedo + albedo ** 2), 0.01)


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_light_through_a_slab_needs_one_transmission_bounce(method):
    """Sunlight through a glass slab onto the floor under it: floor - bottom face - top face -
    sun has two bounces (the top face's does not count), a diffuse one and a transmission one.
    With Transmission 1 the floor gets (1 - F0)^2 of the light, with 0 none (with Glossy 0 too:
    light from the floor beside the slab reflects off its underside to the floor under it)."""
    ior, irradiance, albedo = 1.5, 10.0, 0.5
    f0 = ((ior - 1) / (ior + 1)) ** 2
    scene = sun_through_slab(ior, irradiance, albedo)
    per_pass, _ = render_passes(scene, method=method, passes=8, photons_per_pass=100_000, max_bounces=2,
                                transmission_bounces=1)
    check_mean(per_pass, albedo / np.pi * irradiance * (1 - f0) ** 2, 0.005)
    per_pass, result = render_passes(scene, method="ppm", passes=2, photons_per_pass=20_000, max_bounces=2,
                                     transmission_bounces=0, glossy_bounces=0)
    assert result.image[..., :3].max() == 0.0


def test_light_through_a_slab_needs_two_bounces_in_all():
    """The same path with Max Bounces 1 (and Glossy 0, as above) is cut as well."""
    per_pass, result = render_passes(sun_through_slab(), method="ppm", passes=2, photons_per_pass=20_000,
                                     max_bounces=1, glossy_bounces=0)
    assert result.image[..., :3].max() == 0.0


@pytest.mark.parametrize("limits", [dict(max_bounces=1), dict(glossy_bounces=0)])
def test_a_light_seen_in_a_mirror_is_past_the_last_bounce(limits):
    """camera - mirror - light: the mirror is the vertex nearest the light, so its bounce does
    not count: the light shows in the mirror with one bounce in all, and with no glossy one."""
    spec, radiance = LIGHTS_SEEN["area"]
    settings = RenderSettings(method="ppm", passes=2, photons_per_pass=100, workers=1, **limits)
    image = render(light_over_mirror(spec), settings).image
    np.testing.assert_allclose(image[7:9, 7:9, :3], 0.9 * radiance, rtol=1e-5)


@pytest.mark.parametrize("method", ["ppm", pytest.param("amcmcppm", marks=pytest.mark.slow)])
def test_volume_bounces_zero_is_single_scattering(method):
    """Cycles' default Volume bounces, 0: the sun straight down on a fog slab 3 m thick, seen from
    below, gives E sigma_s p(1) D exp(-sigma_t D), the light scattered once (measured 1.002 of it
    with PPM, 1.009 with the chains), while the light scattered more often adds 3-16 % (green,
    optical depth of scattering 0.75: 1.163 without the limit)."""
    from test_scattering_volumes import SIGMA_A, SIGMA_S, E, sunlit_slab
    from core.sampling import hg_phase
    d, g = 3.0, 0.6
    single = E * SIGMA_S * hg_phase(1.0, g) * d * np.exp(-(SIGMA_S + SIGMA_A) * d)
    means = {}
    for limit in (0, 64):
        settings = RenderSettings(method=method, passes=6, photons_per_pass=150_000, max_bounces=8,
                                  volume_bounces=limit, initial_radius_px=2.0, workers=1)
        image = render(sunlit_slab(g, True, thickness=d), settings).image
        assert np.isfinite(image).all()
        means[limit] = image[..., :3].mean(axis=(0, 1))
    np.testing.assert_allclose(means[0], single, rtol=0.02)
    assert means[64][1] > 1.1 * single[1]

"""Cycles' Caustics toggles (``RenderSettings.caustics_reflective``, ``caustics_refractive``) in
closed-form scenes.  Off, Cycles evaluates a light path's vertex right after a diffuse bounce (on
the way from the camera) without the closures whose caustics are off: a mirror's, glossy lobe's or
glass's reflection, or a glass's refraction.  Against Cycles itself:
``tests/addon/test_addon_parity.py::test_caustics_toggles_match_cycles``."""
import numpy as np
import pytest

from core import RenderSettings, render
from core.testing.scenes import kernel_radius_px, sheet_over_glowing_floor, spot_over_plane, sun_through_slab
from test_closed_form import check_mean, principled_white, render_passes


@pytest.mark.parametrize("field", ["caustics_reflective", "caustics_refractive"])
def test_caustics_toggles_must_be_booleans(field):
    with pytest.raises(ValueError, match=field):
        RenderSettings(**{field: 1})


@pytest.mark.parametrize("workers", [1, 2])
def test_a_mirror_caustic_goes_without_reflective_caustics(workers):
    """A spot pointing up at a mirror lights the floor under it by a caustic alone: black with
    Reflective off (in worker processes too); with Refractive off, the image of both on to the bit
    (photons then carry a factor 1 for their diffuse next)."""
    scene = spot_over_plane(up_mirror=2.0, kernel_radius=0.2)
    settings = RenderSettings(method="ppm", passes=2, photons_per_pass=20_000, max_bounces=1, workers=workers,
                              initial_radius_px=kernel_radius_px(scene, 0.2))
    on = render(scene, settings).image
    assert on[..., :3].min() > 0
    assert render(scene, settings.replace(caustics_reflective=False)).image[..., :3].max() == 0.0
    np.testing.assert_array_equal(render(scene, settings.replace(caustics_refractive=False)).image, on)


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_light_through_a_slab_goes_without_refractive_caustics(method):
    """Sunlight through a glass slab onto the floor under it (two bounces at most): the floor's
    last light path vertex before it is the slab's refraction, so Refractive off leaves it black but
    for light from the floor beside the slab reflected off its underside (gone with Glossy 0 or
    Reflective off too), while Reflective off alone keeps (1 - F0)^2 of the light."""
    ior, irradiance, albedo = 1.5, 10.0, 0.5
    f0 = ((ior - 1) / (ior + 1)) ** 2
    scene = sun_through_slab(ior, irradiance, albedo)
    for also in (dict(glossy_bounces=0), dict(caustics_reflective=False)):
        _, result = render_passes(scene, method=method, passes=2, photons_per_pass=20_000, max_bounces=2,
                                  caustics_refractive=False, **also)
        assert result.image[..., :3].max() == 0.0
    per_pass, _ = render_passes(scene, method=method, passes=8, photons_per_pass=100_000, max_bounces=2,
                                caustics_reflective=False)
    check_mean(per_pass, albedo / np.pi * irradiance * (1 - f0) ** 2, 0.005)


@pytest.mark.parametrize("method", ["ppm", pytest.param("amcmcppm", marks=pytest.mark.slow)])
@pytest.mark.parametrize("layer", ["specular", "coat"])
def test_a_principled_sheet_without_reflective_caustics_is_its_diffuse_part(method, layer):
    """A sheet over a glowing diffuse floor, seen on the floor: every light path meets the sheet right
    after the floor's diffuse bounce, where Cycles with Reflective off drops a Principled BSDF's
    specular or coat layer and with it their dimming of the diffuse part under them.  The sheet then
    lights the floor as a Lambertian sheet of its diffuse albedo a does (measured 1.003 and 1.001 of
    it with PPM, 0.998 and 0.996 with the chains; 0.879 with the layers' dimming kept, which fails
    every case), while with Reflective on it adds its reflection (1.021-1.029)."""
    a = 0.8
    sheet = ({**principled_white(0.3), "diffuse": a} if layer == "specular"
             else {"diffuse": a, "coat": 1.0, "coat_roughness": 0.3})
    settings = dict(method=method, passes=4, photons_per_pass=50_000, max_bounces=30)

    def mean(material, **toggles):
        per_pass, _ = render_passes(sheet_over_glowing_floor(material), **settings, **toggles)
        return per_pass.mean(), per_pass.std(ddof=1) / np.sqrt(len(per_pass))

    lambert, se_l = mean({"diffuse": a})
    off, se_o = mean(sheet, caustics_reflective=False)
    assert abs(off - lambert) < 4 * np.hypot(se_l, se_o) + 0.003 * lambert, (off, lambert)
    on, _ = mean(sheet)
    print(f"{layer} {method}: Reflective off {off / lambert:.4f}, on {on / lambert:.4f} of a Lambert sheet")
    assert on > 1.015 * lambert, (on, lambert)

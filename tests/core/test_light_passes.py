"""Cycles' light passes (``core/light_passes.py``): they add up to the image, each light goes to the
pass of the camera path's first scattering event, and the colours are Cycles' estimates."""
import dataclasses

import numpy as np
import pytest

from core import render
from core.light_passes import COLOR_PASSES, LIGHT_PASSES, PHOTON_PASSES, divide_even_color
from core.scene import Camera, Materials, World
from core.settings import RenderSettings
from core.testing import scenes
from core.testing.scenes import MeshBuilder

KINDS = ("diffuse", "glossy", "transmission")


def passes_of(scene, **settings):
    base = dict(passes=3, photons_per_pass=20000, workers=1, seed=3)
    return render(scene, RenderSettings(**{**base, **settings, "data_passes": LIGHT_PASSES}))


def recombined(data):
    """Cycles' compositing of the light passes into the image."""
    rgb = data["emission"] + data["environment"] + data["volume_direct"] + data["volume_indirect"]
    for kind in KINDS:
        rgb = rgb + (data[f"{kind}_direct"] + data[f"{kind}_indirect"]) * data[f"{kind}_color"]
    return rgb


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
@pytest.mark.parametrize("name, present", [
    ("hole_mirror_glass", ("diffuse_indirect", "glossy_color", "transmission_color")),
    ("corner_in_world_fog", ("diffuse_direct", "diffuse_indirect", "volume_direct", "volume_indirect")),
    ("camera_in_glass", ("transmission_direct", "transmission_color", "glossy_color")),
    ("sky_over_floor", ("diffuse_direct", "diffuse_color")),
])
def test_light_passes_add_up_to_the_image(name, present, method):
    """In scenes of mirrors, glass, fog and sky, by uniform photons and the chains: the passes,
    put together as Cycles' compositor does ((direct + indirect) x colour of each kind, plus
    emission, environment and volume), are the image to float rounding in every pixel; the image is
    the same with or without them (to float rounding: the points' sums are split over more slots);
    every pass is finite and not negative, and those the scene makes are not empty."""
    scene = getattr(scenes, name)()
    result = passes_of(scene, method=method)
    # (light passes keep the photons' direct light, core/direct.py: so does the render without them)
    plain = render(scene, RenderSettings(passes=3, photons_per_pass=20000, workers=1, seed=3, method=method,
                                         direct_light="photons"))
    assert np.allclose(result.image, plain.image, rtol=1e-6, atol=1e-7)
    data = result.data
    assert set(LIGHT_PASSES) <= set(data)
    for key in LIGHT_PASSES:
        assert data[key].shape == result.image.shape[:2] + (3,)
        assert np.isfinite(data[key]).all() and (data[key] >= 0).all(), key
    for key in present:
        assert data[key].mean() > 1e-3, key
    rgb = result.image[..., :3]
    assert np.allclose(recombined(data), rgb, rtol=1e-5, atol=1e-6)


def test_a_floor_under_the_sky_is_lit_directly():
    """A lone diffuse floor of albedo 0.5 under a sky of 1: every photon lands on it straight from
    the sky, so Diffuse Indirect is 0, Diffuse Color the albedo in the pixels wholly on the floor
    (the pixel filter mixes the floor and the sky along the horizon), Diffuse Direct there the
    image over that colour (the sky's radiance, 1, within the kernel's noise) and the sky seen above
    the horizon the Environment pass (1).  The image's bias correction is on (its weight is not 0
    here by the fourth pass): the passes take it in proportion, and still make the image."""
    result = passes_of(scenes.sky_over_floor(resolution=(24, 24), pitch_deg=10.0), passes=4)
    assert result.stats[-1]["bias_weight"] > 0
    data = result.data
    colour = data["diffuse_color"][..., 0]
    floor, sky = np.isclose(colour, 0.5, atol=1e-6), colour == 0.0
    assert floor.sum() > 150 and sky.sum() > 100
    assert np.array_equal(data["diffuse_indirect"], np.zeros_like(data["diffuse_indirect"]))
    assert np.allclose(data["diffuse_color"][floor], 0.5, atol=1e-6)
    assert np.allclose(data["environment"][sky], 1.0, atol=1e-6)
    assert data["environment"][floor].max() == 0.0
    assert np.allclose(data["diffuse_direct"][floor], result.image[floor, :3] / 0.5, rtol=1e-6)
    assert abs(data["diffuse_direct"][floor].mean() - 1.0) < 0.1
    for key in ("glossy_direct", "glossy_indirect", "transmission_direct", "transmission_indirect",
                "emission"):
        assert data[key].max() == 0.0, key


def test_a_transparent_film_keeps_the_world_in_the_environment_pass():
    """On a transparent film the sky is cut out of the image (RGB and alpha 0) but the Environment
    pass still shows it, as Cycles evaluates the world for that pass (``integrate_background``)."""
    scene = scenes.sky_over_floor(resolution=(16, 16), pitch_deg=10.0)
    scene = dataclasses.replace(scene, world=dataclasses.replace(scene.world, film_transparent=True))
    result = passes_of(scene, passes=1)
    sky = result.data["diffuse_color"][..., 0] == 0.0
    assert sky.sum() > 40
    assert np.allclose(result.data["environment"][sky], 1.0, atol=1e-6)
    assert result.image[sky].max() == 0.0


def _mirror_scene(mirror_color=0.8, world=(0.2, 0.4, 0.6)):
    """A camera looking down at a mirror tilted 45 degrees, which shows the constant world beside a
    glowing quad (emission 2) also seen directly at the image's top."""
    mats = Materials.build([{"name": "mirror", "mirror": mirror_color},
                            {"name": "glow", "emission": 2.0}])
    m = MeshBuilder()
    m.add_quad((-1, -1, -1), (1, -1, 1), (1, 1, 1), (-1, 1, -1), 0)        # normal (-1, 0, 1)/sqrt2
    m.add_quad((-8, -3, 6), (-8, 3, 6), (-8, 3, 0.5), (-8, -3, 0.5), 1)    # seen in the mirror
    m.add_quad((-1, 1.1, 0), (1, 1.1, 0), (1, 1.6, 0), (-1, 1.6, 0), 1)    # seen directly
    cam = Camera.look_at(np.array([0.0, -0.1, 3.0]), np.array([0.0, 0.0, 0.0]), lens_mm=28.0,
                         resolution=(24, 24))
    return m.build(mats, None, cam, World(color=np.asarray(world, np.float32)))


def test_emission_and_the_world_in_a_mirror_are_glossy_direct():
    """Emission and the world seen through a mirror are Glossy Direct (one bounce), divided by the
    mirror's Glossy Color (its reflectance 0.8): the world's colour and the emitter's strength
    exactly; an emitter seen directly is the Emission pass, the world seen directly Environment;
    nothing is indirect or diffuse."""
    data = passes_of(_mirror_scene(), passes=2).data
    colour = data["glossy_color"][..., 0]
    mirror = np.isclose(colour, 0.8, atol=1e-6)       # (pixels wholly on the mirror)
    assert mirror.sum() > 100
    g = data["glossy_direct"][mirror]
    sky = np.isclose(g, (0.2, 0.4, 0.6), atol=1e-5).all(axis=1)
    glow = np.isclose(g, 2.0, atol=1e-5).all(axis=1)
    assert sky.sum() > 20 and glow.sum() > 5
    assert ((g >= (0.2, 0.4, 0.6)) & (g <= 2.0 + 1e-5)).all()      # (the rest: both, along edges)
    glow = np.isclose(data["emission"], 2.0).all(axis=-1) & (colour == 0.0)
    sky = (data["emission"] == 0.0).all(axis=-1) & (colour == 0.0)
    assert glow.sum() > 5 and sky.sum() > 100
    assert np.allclose(data["environment"][sky], (0.2, 0.4, 0.6), atol=1e-6)
    assert data["environment"][glow | mirror].max() == 0.0
    for key in ("glossy_indirect", "diffuse_direct", "diffuse_indirect", "transmission_direct"):
        assert data[key].max() == 0.0, key


def test_divide_even_color_keeps_passes_grey_as_cycles():
    """Cycles' safe_divide_even_color: a channel whose colour is 0 takes the mean of the other two
    quotients, or the one quotient left; all three 0 give 0."""
    a = np.array([[2.0, 4.0, 6.0]] * 5)
    b = np.array([[1.0, 2.0, 3.0], [0.0, 2.0, 3.0], [1.0, 0.0, 0.0], [0.0, 0.0, 3.0], [0.0, 0.0, 0.0]])
    expected = [[2, 2, 2], [2, 2, 2], [2, 2, 2], [2, 2, 2], [0, 0, 0]]
    assert np.array_equal(divide_even_color(a, b), expected)
    a[1] = (5.0, 4.0, 9.0)
    assert np.array_equal(divide_even_color(a[1], b[1]), [2.5, 2.0, 3.0])


def test_only_the_passes_asked_for_are_made():
    """Asking for one divided pass makes it alone (its colour is made but not returned), and the
    photon passes' blocks are only there for the passes asked for."""
    scene = scenes.sky_over_floor(resolution=(8, 8))
    result = render(scene, RenderSettings(passes=1, photons_per_pass=5000, workers=1,
                                          data_passes=("diffuse_direct",)))
    assert set(result.data) == {"diffuse_direct"}
    assert not set(COLOR_PASSES) & set(result.data) and set(PHOTON_PASSES) & set(result.data)


@pytest.mark.parametrize("distance", [0.5, 2.0, 4.0])
def test_ambient_occlusion_under_a_ceiling_is_the_closed_form(distance):
    """The Ambient Occlusion pass on a floor under a ceiling at height 1: a cosine-distributed ray
    escapes within ``distance`` D when cos(theta) < 1 / D, and cos^2 is uniform under the cosine
    law, so the pass is min(1, 1 / D^2) (1, 0.25, 0.0625) within the noise of 256 pixels x 8
    passes of one ray."""
    mats = Materials.build([{"name": "floor", "diffuse": 0.5}])
    m = MeshBuilder()
    b = 50.0
    m.add_quad((-b, -b, 0), (b, -b, 0), (b, b, 0), (-b, b, 0), 0)
    m.add_quad((-b, -b, 1), (-b, b, 1), (b, b, 1), (b, -b, 1), 0)
    cam = Camera.look_at(np.array([0.0, 0.0, 0.5]), np.array([0.0, 0.01, 0.0]), lens_mm=50.0,
                         resolution=(16, 16))
    scene = m.build(mats, None, cam, World(color=np.full(3, 1.0, np.float32)))
    result = render(scene, RenderSettings(passes=8, photons_per_pass=2000, workers=1, data_passes=("ao",),
                                          ao_distance=distance))
    expected = min(1.0, 1.0 / distance ** 2)
    ao = result.data["ao"]
    assert ao.shape == (16, 16, 3) and set(result.data) == {"ao"}
    assert abs(ao.mean() - expected) < 4.0 * np.sqrt(expected * (1.0 - expected) / 2048) + 1e-9

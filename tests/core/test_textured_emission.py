"""Textured emitters: a material's emission times a procedural program (``Materials.emission_program``).

Photons leave such an emitter with the power of the point they start from, whatever the estimate
of each triangle's power that picks the triangle; the camera sees the program's value; and the
light the photons carry adds up to the closed form of a furnace."""
import numpy as np
import pytest

from core import render
from core.context import RenderContext
from core.scene import Materials
from core.settings import RenderSettings
from core.testing.scenes import furnace_sphere, sun_over_procedural_floor

OBJECT = {"op": "attribute", "name": "object"}


def axis(name):
    return {"op": "separate", "vector": OBJECT, "output": name}


def grey(value):
    return {"op": "splat", "value": value}


# 2 (x + 0.5) on the 1 m floor at z = 0 ([-0.5, 0.5]^2): 0 at one edge, 2 at the other, mean 1.
RAMP = grey({"op": "math", "operation": "MULTIPLY", "a": {"op": "math", "operation": "ADD", "a": axis("X"),
                                                             "b": 0.5}, "b": 2.0})


def emitting_floor(program, emission=3.0, resolution=(16, 16)):
    """The floor of ``sun_over_procedural_floor``, black, emitting ``emission`` times ``program``
    and lit by nothing else; the camera sees x, y in [-0.1, 0.1] from above."""
    scene = sun_over_procedural_floor(grey(0.0), irradiance=0.0, resolution=resolution)
    mats = Materials.build([{"name": "floor", "diffuse": 0.0, "emission": emission,
                             "emission_program": program}])
    return scene.replace(materials=mats).validate()


def photons(scene, n=400_000, seed=1):
    """(origins, directions, flux, normals) of ``n`` photons and the emitters' choice probabilities."""
    lights = RenderContext(scene).lights
    return lights.sample(np.random.default_rng(seed).random((n, 6))), lights.prob


def test_photons_leave_a_textured_emitter_with_the_power_of_their_point():
    (origins, dirs, flux, _), prob = photons(emitting_floor(RAMP))
    # Total power 2 pi A mean(L) = 2 pi 3; the flux-weighted mean of x is int x L / int L = 1/6.
    np.testing.assert_allclose(flux.mean(axis=0), 2 * np.pi * 3.0, rtol=0.01)
    assert (flux[:, 0] * origins[:, 0]).sum() / flux[:, 0].sum() == pytest.approx(1 / 6, abs=0.004)
    # Each photon's flux is 2 pi A L(origin) over its triangle's choice probability (A = 1/2), and
    # the triangles are chosen by their estimated power, not their area.
    per_radiance = flux[:, 1] / (3.0 * 2 * (origins[:, 0] + 0.5))
    triangle = (origins[:, 1] > origins[:, 0]).astype(int)      # the quad's diagonal splits y = x
    np.testing.assert_allclose(per_radiance, np.pi / prob[triangle], rtol=1e-6)
    assert abs(prob[0] - prob[1]) > 0.2
    assert np.isfinite(flux).all() and (np.abs(dirs[:, 2]) > 0).all()


def test_a_fine_texture_the_power_estimate_misses_keeps_the_exact_power():
    """A checker of 31 cells a metre and a red-only stripe pattern: each triangle's power is
    estimated from 16 points, badly; the photons' mean flux is still the exact power."""
    checker = {"op": "checker", "vector": OBJECT, "color1": [4.0, 0.0, 0.0], "color2": [0.0, 1.0, 0.5],
               "scale": 31.0}
    (_, _, flux, _), _ = photons(emitting_floor(checker, emission=1.0))
    g = (np.arange(2000) + 0.5) / 2000 - 0.5
    from core import procedural
    from tests.core.test_procedural import Points
    xx, yy = np.meshgrid(g, g)
    pts = np.stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)], axis=1)
    exact = 2 * np.pi * procedural.evaluate_color(checker, Points(pts), []).mean(axis=0)
    np.testing.assert_allclose(flux.mean(axis=0), exact, rtol=0.02)


def test_photons_leave_an_emitter_of_the_view_with_the_power_of_their_direction():
    """Emission times Layer Weight's Facing (Blend 0.5: 1 - |cos|): a photon leaving along d
    carries 2 pi A L(d) over its triangle's probability (the program seen from d, as Cycles'
    light samples are), so the photons add up to 2 sides x 3 x 2 pi int (1 - mu) mu dmu = 2 pi
    (seen head-on, as before, the floor gave no photons at all)."""
    facing = grey({"op": "layer_weight", "blend": 0.5, "output": "Facing"})
    (origins, dirs, flux, normals), prob = photons(emitting_floor(facing))
    np.testing.assert_allclose(flux.mean(axis=0), 2 * np.pi, rtol=0.01)
    mu = np.abs(dirs[:, 2])
    triangle = (origins[:, 1] > origins[:, 0]).astype(int)
    np.testing.assert_allclose(flux[:, 0] * prob[triangle], 2 * np.pi * 0.5 * 3.0 * (1 - mu),
                               rtol=1e-5, atol=1e-9)
    assert (prob > 0.3).all() and (dirs[:, 2] < 0).mean() == pytest.approx(0.5, abs=0.01)


@pytest.mark.parametrize("seen", [True, False], ids=["camera_only", "light_only"])
def test_an_emission_of_the_light_path_shows_to_the_camera_or_lights(seen):
    """Emission times Light Path's Is Camera Ray: the camera sees it and its photons carry
    nothing (they see it as from a diffuse bounce, ``procedural.photon_path``); times one minus
    it, the photons carry it all (2 pi A L, the floor's power) and the camera sees black.  The
    renders stay finite with an emitter of no power."""
    camera = {"op": "light_path", "output": "Is Camera Ray"}
    program = grey(camera if seen else {"op": "math", "operation": "SUBTRACT", "a": 1.0, "b": camera})
    scene = emitting_floor(program)
    (_, _, flux, _), _ = photons(scene, n=20_000)
    np.testing.assert_allclose(flux.mean(axis=0), 0.0 if seen else 2 * np.pi * 3.0, rtol=1e-6)
    image = render(scene, RenderSettings(workers=1, passes=2, photons_per_pass=2000)).image[..., :3]
    assert np.isfinite(image).all()
    np.testing.assert_allclose(image, 3.0 if seen else 0.0, rtol=1e-5)


def test_the_camera_sees_the_emission_program():
    n = 16
    result = render(emitting_floor(RAMP), RenderSettings(workers=1, passes=4, photons_per_pass=2000))
    x = -0.1 + 0.2 * (np.arange(n) + 0.5) / n          # pixel centres (a symmetric filter keeps a slope)
    expected = 3.0 * 2 * (x + 0.5)
    image = result.image[..., :3]
    assert np.isfinite(image).all()
    np.testing.assert_allclose(image.mean(axis=(0, 2)), expected, rtol=0.01)
    np.testing.assert_allclose(image[..., 0], image[..., 2], rtol=1e-6)


@pytest.mark.parametrize("method", [dict(method="ppm"), dict(method="amcmcppm", chains=4096)],
                         ids=lambda m: m["method"])
def test_furnace_with_a_textured_emission(method):
    """Emission 1 + 0.5 z over a sphere (mean 1 by symmetry): the camera sees Le(x), and the
    light reflected (uniform inside a sphere) is a mean(Le) (1 - a^(b+1)) / (1 - a) whatever the
    pattern, so the render minus the render of a black sphere is that constant everywhere."""
    program = grey({"op": "math", "operation": "MULTIPLY_ADD", "a": axis("Z"), "b": 0.5, "c": 1.0})
    albedo, bounces = 0.5, 30
    settings = dict(workers=1, passes=6, photons_per_pass=20_000, max_bounces=bounces, seed=3, **method)
    seen, lit = (render(furnace_sphere(a, 1.0, emission_program=program), RenderSettings(**settings))
                 .image[..., :3] for a in (0.0, albedo))
    reflected = albedo * (1 - albedo ** (bounces + 1)) / (1 - albedo)
    # The camera sees the gradient (rows top to bottom), and the same rows through the light.
    top, bottom = seen[:8].mean(), seen[8:].mean()
    assert top - bottom > 0.2
    assert seen.mean() == pytest.approx(1.0, rel=0.01)
    diff = lit - seen
    assert diff.mean() == pytest.approx(reflected, rel=0.03)
    assert diff[:8].mean() == pytest.approx(diff[8:].mean(), rel=0.05)

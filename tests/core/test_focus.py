"""Photons from afar aimed at what the camera sees (``core.lights.Focus``,
``RenderSettings.focus_photons``), in whole renders: the image stays exact, the photons land."""
from __future__ import annotations

import numpy as np
import pytest

from core import RenderSettings, render
from core.scene import Camera, Lights, Materials
from core.testing.scenes import MeshBuilder

ALBEDO = 0.6
IRRADIANCE = 4.0
SUN = np.array([-0.4, 0.3, -0.85]) / np.linalg.norm([-0.4, 0.3, -0.85])


def sunlit_corner(resolution=(24, 24)):
    """A long lens (600 mm, 42 m away, 16 degrees down) on a patch of some 3 by 9 m of a 200 m grey
    floor under a sun: the patch is 10^-3 of the scene's disc.  Radiance: albedo E cos(theta) / pi
    everywhere."""
    mats = Materials.build([{"name": "floor", "diffuse": ALBEDO}])
    m = MeshBuilder()
    m.add_quad((-100, -100, 0), (100, -100, 0), (100, 100, 0), (-100, 100, 0), 0)
    lights = Lights.build([{"kind": "sun", "direction": SUN, "power": IRRADIANCE, "sun_angle": 0.01}])
    cam = Camera.look_at((30.0, -30.0, 12.0), (0.0, 0.0, 0.0), lens_mm=600.0, resolution=resolution)
    return m.build(mats, lights, cam)


@pytest.mark.parametrize("workers", (1, 2))
def test_focused_photons_light_a_far_corner_exactly_and_densely(workers):
    """PPM on the sunlit corner: with the focus (also through worker processes, which get it with
    the pass's points) a twentieth or more of the uniform photons land on what the camera sees, against
    about 10^-3 without; after 4 passes the image mean is the closed form's within 1.5 % and the
    pixels' RMS deviation from it below 5 % (some 370 photons a gather and pass: 2.6 % expected), at least
    three times below that of the same photons unaimed."""
    expected = ALBEDO * IRRADIANCE * -SUN[2] / np.pi
    runs = {}
    for focus in (True, False):
        s = RenderSettings(method="ppm", passes=4, photons_per_pass=200_000 // workers, workers=workers,
                           seed=3, focus_photons=focus)
        r = render(sunlit_corner(), s)
        assert np.isfinite(r.image).all()
        visible = sum(st["uniform_visible"] for st in r.stats) / sum(st["uniform_samples"] for st in r.stats)
        runs[focus] = (r.image[..., :3].astype(np.float64) / expected, visible)
    image, visible = runs[True]
    assert visible > 0.05, f"focused: {visible:.3g} of the photons visible"
    assert runs[False][1] < 0.002, f"unfocused: {runs[False][1]:.3g} visible"
    assert abs(image.mean() - 1.0) < 0.015, f"focused image mean {image.mean():.4f} of the closed form"
    rms = float(np.sqrt(np.mean((image - 1.0) ** 2)))
    plain = float(np.sqrt(np.mean((runs[False][0] - 1.0) ** 2)))
    assert rms < 0.05 and plain > 3 * rms, f"pixels' RMS deviation {rms:.4f} focused, {plain:.4f} not"


def test_chains_keep_their_photons_unaimed_and_the_image_exact():
    """The Markov chains' target is a path's visibility, not its flux, so their passes do not aim
    (``RenderSettings.focus_photons`` applies to uniform passes only): with the focus on, AMCMCPPM's
    image is the very image of the focus off, and it matches the closed form."""
    images = {}
    for focus in (True, False):
        s = RenderSettings(method="amcmcppm", passes=3, photons_per_pass=40_000, workers=1, seed=5,
                           focus_photons=focus)
        images[focus] = render(sunlit_corner((16, 16)), s).image
    assert np.array_equal(images[True], images[False])
    expected = ALBEDO * IRRADIANCE * -SUN[2] / np.pi
    assert abs(images[True][..., :3].mean() / expected - 1.0) < 0.05


def shaded_ground(resolution=(16, 16)):
    """A camera under a 16 x 16 m canopy 5 m above a 40 m ground looks at the ground under its
    middle, lit by a 6 x 3 m mirror 11 m away that throws the sun in under the canopy.  The focus
    around what the camera sees aims at the canopy's top: the light comes off the mirror, outside
    the focus sphere, which only the uniform half of the photons reach."""
    mats = Materials.build([{"name": "ground", "diffuse": ALBEDO}, {"name": "mirror", "mirror": 0.95}])
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    m.add_quad((-8, -8, 5), (-8, 8, 5), (8, 8, 5), (8, -8, 5), 0)
    sun = np.array([0.0, 0.3, -1.0]) / np.linalg.norm([0.0, 0.3, -1.0])
    c = np.array([0.0, -11.0, 3.0])
    out = -c / np.linalg.norm(c)
    n = (out - sun) / np.linalg.norm(out - sun)
    t = np.array([1.0, 0.0, 0.0])
    b = np.cross(n, t)
    m.add_quad(c - 3 * t - 1.5 * b, c + 3 * t - 1.5 * b, c + 3 * t + 1.5 * b, c - 3 * t + 1.5 * b, 1)
    lights = Lights.build([{"kind": "sun", "direction": sun, "power": IRRADIANCE, "sun_angle": 0.01}])
    cam = Camera.look_at((0.0, -4.0, 1.5), (0.0, 0.0, 0.0), lens_mm=200.0, resolution=resolution)
    return m.build(mats, lights, cam)


def test_a_focus_that_does_not_pay_goes_after_the_first_pass():
    """The ground under a canopy: the first pass aims (the points are compact in a large scene), its
    photons show that the aimed ones do not reach what the camera sees (mean(w^2 V) > mean(w V),
    the integrator's test), and the later passes do not aim; on the sunlit corner of a plain floor
    every pass aims."""
    s = RenderSettings(method="ppm", passes=4, photons_per_pass=300_000, workers=1, seed=2)
    r = render(shaded_ground(), s)
    assert np.isfinite(r.image).all() and r.image[..., :3].mean() > 0
    radii = [st["focus_radius"] for st in r.stats]
    assert radii[0] > 0 and radii[1:] == [0.0] * 3, radii
    r = render(sunlit_corner((16, 16)), s)
    assert all(st["focus_radius"] > 0 for st in r.stats)

"""Absorbing volumes (``Materials.volume_absorption``): Beer-Lambert along path segments inside a mesh.

Closed forms, each with a coefficient per channel so that one render checks three optical depths:

* a sun through a glass slab of thickness d: the floor under it gets E (1 - F0)^2 exp(-sigma d)
  (photons refract into the slab, which makes them be inside it);
* a camera looking through a volume-only box (no surface: Cycles' invisible mesh) at an emitter
  sees Le exp(-sigma d), from outside, and from inside the box (a path that starts inside is
  inside where it meets the box from the back);
* a floor at the bottom of a volume-only box, seen from above under a constant sky (a pool's
  floor): L = rho sky 2 E3(tau) exp(-tau), tau = sigma h, where 2 E3(tau) = 2 int mu exp(-tau / mu)
  dmu is the sky's irradiance through the layer of depth h over pi sky.  The floor is not the
  volume's mesh: paths are in the volume because they crossed its top.
"""
from __future__ import annotations

import numpy as np
import pytest

from core import RenderSettings, render
from core.context import RenderContext
from core.scene import Camera, Lights, Materials, Scene, SceneError, World
from core.testing.scenes import MeshBuilder, sun_through_slab

METHODS = [dict(method="ppm"), dict(method="amcmcppm", chains=4096)]
SIGMA = np.array([0.0, 2.0, 8.0])


def render_mean(scene, **settings):
    """Mean colour (3,) of the image; every pass's image is checked to be finite."""
    def check(result):
        assert np.isfinite(result.image).all()

    result = render(scene, RenderSettings(workers=1, **settings), on_iteration=check)
    return result.image[..., :3].reshape(-1, 3).mean(axis=0)


def look_down(z):
    """A camera matrix at height ``z`` looking straight down (camera -Z is world -Z)."""
    m = np.eye(4)
    m[:3, 3] = (0.0, 0.0, z)
    return m


def e3(tau):
    """2 int_0^1 mu exp(-tau / mu) dmu (twice the exponential integral E3), by the midpoint rule."""
    mu = (np.arange(200_000) + 0.5) / 200_000
    return np.array([2.0 * np.mean(mu * np.exp(-t / mu)) for t in np.atleast_1d(tau)])


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_sun_through_an_absorbing_glass_slab(method):
    ior, irradiance, albedo, thickness = 1.5, 10.0, 0.5, 0.1
    scene = sun_through_slab(ior, irradiance, albedo)
    mats = Materials.build([{"name": "floor", "diffuse": albedo},
                            {"name": "glass", "dielectric": 1.0, "ior": ior, "volume_absorption": SIGMA}])
    scene = scene.replace(materials=mats).validate()
    f0 = ((ior - 1) / (ior + 1)) ** 2
    expected = albedo / np.pi * irradiance * (1 - f0) ** 2 * np.exp(-SIGMA * thickness)
    got = render_mean(scene, passes=6, photons_per_pass=60_000, max_bounces=2, **method)
    np.testing.assert_allclose(got, expected, rtol=0.01)


def box_before_emitter(camera_z, sigma=SIGMA, emission=1.0):
    """A volume-only box z in [0, 1] (opacity 0) over an emitter at z = -1, an orthographic camera
    at ``camera_z`` looking down: L = emission exp(-sigma) through the whole box."""
    mats = Materials.build([{"name": "volume", "opacity": 0.0, "volume_absorption": sigma},
                            {"name": "emitter", "emission": emission}])
    m = MeshBuilder()
    m.add_box((-1, -1, 0), (1, 1, 1), 0)
    m.add_quad((-2, -2, -1), (2, -2, -1), (2, 2, -1), (-2, 2, -1), 1)
    cam = Camera(world_from_camera=look_down(camera_z), projection="orthographic",
                 frame=(-0.2, 0.2, -0.2, 0.2), resolution=(4, 4))
    return m.build(mats, camera=cam)


@pytest.mark.parametrize("camera_z, depth", [(2.0, 1.0), (0.5, 0.5)], ids=["outside", "inside"])
def test_camera_sees_through_a_volume_only_box(camera_z, depth):
    got = render_mean(box_before_emitter(camera_z), method="ppm", passes=2, photons_per_pass=1000)
    np.testing.assert_allclose(got, np.exp(-SIGMA * depth), rtol=2e-4)      # spawn offsets


def test_a_camera_inside_a_volume_sees_what_lies_inside_through_it():
    """Camera and emitter inside the box, the emitter no part of its mesh: the path is inside
    from its start (RenderContext.enclosing_medium), for a perspective camera (found once, at
    its eye) and an orthographic one (per ray)."""
    for projection in ("orthographic", "perspective"):
        scene = box_before_emitter(0.75)
        mats = Materials.build([{"name": "volume", "opacity": 0.0, "volume_absorption": SIGMA},
                                {"name": "emitter", "emission": 1.0}])
        m = MeshBuilder()
        m.add_box((-1, -1, 0), (1, 1, 1), 0)
        m.add_quad((-0.9, -0.9, 0.25), (0.9, -0.9, 0.25), (0.9, 0.9, 0.25), (-0.9, 0.9, 0.25), 1)
        cam = scene.camera
        if projection == "perspective":
            cam = Camera.look_at((0, 0, 0.75), (0, 0, 0), lens_mm=5000.0, resolution=(4, 4))   # straight
        got = render_mean(m.build(mats, camera=cam), method="ppm", passes=1, photons_per_pass=1000)
        np.testing.assert_allclose(got, np.exp(-SIGMA * 0.5), rtol=3e-3, err_msg=projection)


def pool(sigma=SIGMA, depth=0.5, albedo=0.5, sky=1.0, width=8.0):
    """A diffuse floor (z = 0) at the bottom of a wide volume-only box (z in [-0.01, depth]) under
    a constant sky, an orthographic camera looking straight down from above the box."""
    mats = Materials.build([{"name": "floor", "diffuse": albedo},
                            {"name": "water", "opacity": 0.0, "volume_absorption": sigma}])
    m = MeshBuilder()
    h = width / 2
    m.add_quad((-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0), 0)
    m.add_box((-h, -h, -0.01), (h, h, depth), 1)
    cam = Camera(world_from_camera=look_down(depth + 1.0), projection="orthographic",
                 frame=(-0.5, 0.5, -0.5, 0.5), resolution=(8, 8))
    return m.build(mats, camera=cam, world=World(color=np.full(3, sky, np.float32)))


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_floor_under_an_absorbing_layer_sees_the_sky_through_it(method):
    depth, albedo = 0.5, 0.5
    tau = SIGMA * depth
    expected = albedo * e3(tau) * np.exp(-tau)
    scene = pool(depth=depth, albedo=albedo)
    got = np.mean([render_mean(scene, passes=6, photons_per_pass=60_000, max_bounces=4, seed=seed, **method)
                   for seed in range(3)], axis=0)
    # Most of the photons' noise is common to the channels: single seeds measured within 6.4 % in
    # the clear channel, the absorbing ones against it within 2.1 % and 4.6 % (both methods, 6
    # seeds; their means within 1.3 % of the closed form).
    assert got[0] == pytest.approx(expected[0], rel=0.07)
    ratios = (got[1:] / got[0]) / (expected[1:] / expected[0])
    assert (abs(ratios - 1.0) < [0.03, 0.05]).all(), ratios


def test_no_volume_means_no_factor_and_no_medium():
    """Scenes without volumes trace as before: no factor, no medium (the fast path)."""
    ctx = RenderContext(box_before_emitter(2.0, sigma=0.0))
    assert not ctx.has_volumes
    origins, dirs = np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, 0.0, -1.0]])
    hits, factor, _, medium = ctx.trace(origins, dirs, None, lambda rows, crossing: np.zeros(len(rows)))
    assert hits.is_hit.all() and medium is None
    np.testing.assert_allclose(factor, 1.0)         # the box's crossings, untinted


def test_volumes_survive_a_file_round_trip_and_bad_values_are_refused(tmp_path):
    scene = box_before_emitter(2.0)
    scene.save(tmp_path / "volume.npz")
    loaded = Scene.load(tmp_path / "volume.npz")
    np.testing.assert_array_equal(loaded.materials.volume_absorption, scene.materials.volume_absorption)
    # A file from before volumes loads without any.
    arrays = {k: v for k, v in scene.to_arrays().items() if k != "materials.volume_absorption"}
    np.testing.assert_array_equal(Scene.from_arrays(arrays).materials.volume_absorption, 0.0)
    for bad, message in ((-1.0, "negative"), (np.inf, "NaN or infinite")):
        mats = Materials.build([{"name": "volume", "volume_absorption": bad},
                                {"name": "emitter", "emission": 1}])
        with pytest.raises(SceneError, match=message):
            scene.replace(materials=mats).validate()


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_a_lamp_inside_a_volume_lights_the_floor_through_it(method):
    """A point light 25 cm over the pool's floor, under its surface: the floor under it gets
    I exp(-sigma r) / r^2; the camera sees 2 cm of it around the point under the lamp (r within
    0.2 % of 0.25 m there), so the channels' ratios are exp(-sigma 0.25) within 2 %."""
    scene = pool(depth=0.5, sky=0.0)
    lights = Lights.build([{"kind": "point", "position": (0.0, 0.0, 0.25), "power": 100.0}])
    cam = Camera(world_from_camera=look_down(1.5), projection="orthographic",
                 frame=(-0.02, 0.02, -0.02, 0.02), resolution=(16, 16))
    scene = scene.replace(lights=lights, camera=cam, world=World(color=np.zeros(3, np.float32))).validate()
    got = render_mean(scene, passes=4, photons_per_pass=60_000, max_bounces=3, **method)
    assert got[0] > 0
    np.testing.assert_allclose(got / got[0], np.exp(-SIGMA * (0.25 + 0.5)), rtol=0.02)   # and 0.5 m up

"""The world's volume (``World.volume_absorption``, ``volume_scattering``, ``volume_anisotropy``):
a homogeneous medium filling everything outside the meshes' volumes, unbounded as in Cycles.

Closed forms:

* a point light over a floor in a world that absorbs: the floor's radiance is
  rho / pi * I h / r^3 * exp(-sigma r), seen through exp(-sigma H) more (r the distance to the
  light, h its height, H the camera's); the same formula with sigma = 0 is the control;
* a furnace whose volume is the world's: a closed sphere of black walls emitting 1, with no
  volume of its own, around the camera, the world scattering without absorbing: radiance 1;
* the sun and the world's light reach nothing through a world that attenuates them, and come
  through untouched in the channels it does not attenuate;
* a lamp seen through the fog shows its radiance times the transmittance to its surface (not
  to the next surface behind it, nor zero when nothing lies behind it).

Also: the world's fog renders as the same fog in a volume-only box around the scene, and a
transparent film keeps the alpha of what camera rays crossed on their way out.
"""
from __future__ import annotations

import numpy as np
import pytest

from core.eye_pass import MAX_SEGMENT_POINTS
from core.scene import VISIBLE_CAMERA, Camera, Lights, Materials, SceneError, World
from core.testing.scenes import BUILTIN, MeshBuilder
from render_utils import finite_render

SIGMA = np.array([0.3, 0.1, 0.02])          # absorption per metre, per channel
RHO = 0.5


def looking_down(z, half, resolution):
    pose = np.eye(4)
    pose[2, 3] = z
    return Camera(world_from_camera=pose, projection="orthographic", frame=(-half, half, -half, half),
                  resolution=resolution)


def point_over_floor(world, power=100.0, height=1.0, camera_height=2.0, half=1.0, resolution=(20, 20)):
    """A point light at ``height`` over a diffuse floor 40 m wide; an orthographic camera
    looking straight down from ``camera_height`` at the 2 ``half`` wide square under it."""
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    lights = Lights.build([{"kind": "point", "position": (0, 0, height), "power": power}])
    return m.build(Materials.build([{"name": "floor", "diffuse": RHO}]), lights,
                   looking_down(camera_height, half, resolution), world)


def expected_floor(sigma, power=100.0, height=1.0, camera_height=2.0, half=1.0, resolution=(20, 20)):
    """(3,) the mean over the pixels' centres of the floor's radiance seen by the camera."""
    w, h = resolution
    x = (np.arange(w) + 0.5) / w * 2 * half - half
    y = (np.arange(h) + 0.5) / h * 2 * half - half
    r = np.sqrt(x[None, :] ** 2 + y[:, None] ** 2 + height ** 2)[..., None]
    irradiance = power / (4 * np.pi) * height / r ** 3 * np.exp(-sigma * r)
    return (RHO / np.pi * irradiance * np.exp(-sigma * camera_height)).mean(axis=(0, 1))


@pytest.mark.parametrize("sigma", [np.zeros(3), SIGMA], ids=["clear", "absorbing"])
def test_a_point_light_over_a_floor_in_a_world_that_absorbs(sigma):
    """Three seeds measured 0.996-0.999 of the closed form in every channel."""
    scene = point_over_floor(World(volume_absorption=sigma))
    result = finite_render(scene, method="ppm", passes=6, photons_per_pass=60_000, max_bounces=1,
                           initial_radius_px=1.5)
    assert ("world volume" in result.effects) == bool(sigma.any())
    np.testing.assert_allclose(result.image[..., :3].mean(axis=(0, 1)), expected_floor(sigma), rtol=0.03)


def world_furnace(resolution=(24, 24)):
    """A closed sphere of radius 1 whose black walls emit 1 and hold no volume of their own; the
    world's volume, inside it, scatters (0.5 / 1 / 2, g = 0.5) without absorbing."""
    m = MeshBuilder()
    m.add_sphere((0, 0, 0), 1.0, 0, n_theta=24, n_phi=48, inward=True)
    cam = Camera.look_at((0, 0, 0), (1, 0.2, 0.1), lens_mm=30.0, resolution=resolution)
    world = World(volume_scattering=np.array([0.5, 1.0, 2.0]), volume_anisotropy=0.5)
    return m.build(Materials.build([{"name": "wall", "emission": 1.0, "diffuse": 0.0}]), Lights.empty(),
                   cam, world)


CHAINS = dict(method="amcmcppm", chains=2048)


@pytest.mark.parametrize("method", [dict(method="ppm"), pytest.param(CHAINS, marks=pytest.mark.slow)],
                         ids=lambda m: m["method"])
def test_a_furnace_filled_by_the_world_keeps_its_radiance(method):
    """The camera and the walls' photons start in the world's volume (nothing encloses them);
    every channel must come out 1, as with the walls' own volume (test_scattering_volumes).
    Three seeds of PPM measured 0.977-1.010, blue the lowest (its paths scatter most: those over
    8 scatterings are cut, and the spheres near the wall lose a little)."""
    result = finite_render(world_furnace(), passes=8, photons_per_pass=60_000, initial_radius_px=2.0,
                           **method)
    assert result.stats[-1]["volume_points"] == 24 * 24 * MAX_SEGMENT_POINTS       # every pixel
    np.testing.assert_allclose(result.image[..., :3].mean(axis=(0, 1)), 1.0, rtol=0.035)


def test_the_sun_and_the_sky_reach_through_only_the_channels_the_world_leaves():
    """A sun straight down (10 W/m^2) and a grey sky (0.2) over a floor 2 m wide: without a volume
    the floor shows rho (E / pi + 0.2) (measured 0.994).  A world volume that absorbs blue only
    leaves red and green as they were and blue black (Cycles: the unbounded volume takes the
    light from afar); one that
    attenuates every channel leaves the image black, and no photon is spent on those lights."""
    m = MeshBuilder()
    m.add_quad((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), 0)
    sun = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": 10.0}])
    mats = Materials.build([{"name": "floor", "diffuse": RHO}])
    expected = RHO * (10.0 / np.pi + 0.2)
    settings = dict(method="ppm", passes=4, photons_per_pass=100_000, max_bounces=1)
    for absorption, scattering, channels in (((0.0, 0.0, 0.5), (0.0, 0.0, 0.0), [expected, expected, 0.0]),
                                             ((0.2, 0.0, 0.0), (0.0, 0.1, 0.3), [0.0, 0.0, 0.0])):
        world = World(color=np.full(3, 0.2, np.float32), volume_absorption=np.array(absorption),
                      volume_scattering=np.array(scattering))
        scene = m.build(mats, sun, looking_down(1.0, 0.1, (4, 4)), world)
        result = finite_render(scene, **settings)
        np.testing.assert_allclose(result.image[..., :3].mean(axis=(0, 1)), channels, rtol=0.03, atol=1e-12)


@pytest.mark.parametrize("soft_falloff", [False, True])
def test_a_lamp_seen_through_the_fog_keeps_the_transmittance_to_its_surface(soft_falloff):
    """A point lamp of radius 0.25 m, 3 m under an orthographic camera, nothing behind it but a
    black floor 50 m further down (or nothing at all): its disc shows P / (4 pi^2 r^2) times
    exp(-sigma d), d the depth of its surface at the centre (3 - r; 3 with Soft Falloff, where
    the lamp is a disc through its centre).  Before, the lamp took the transmittance to the
    floor (or none: black, with nothing behind)."""
    lamp = Lights.build([{"kind": "point", "position": (0, 0, 0), "power": 50.0, "radius": 0.25,
                          "visibility": VISIBLE_CAMERA, "soft_falloff": soft_falloff}])
    radiance = 50.0 / (4 * np.pi ** 2 * 0.25 ** 2)
    depth = 3.0 if soft_falloff else 3.0 - 0.25
    world = World(volume_absorption=SIGMA)
    for floor in (True, False):
        m = MeshBuilder()
        if floor:
            m.add_quad((-5, -5, -50), (5, -5, -50), (5, 5, -50), (-5, 5, -50), 0)
        scene = m.build(Materials.build([{"name": "black", "diffuse": 0.0}]), lamp,
                        looking_down(3.0, 0.05, (4, 4)), world)
        result = finite_render(scene, method="ppm", passes=1, photons_per_pass=1000)
        # (the pixels lie within 0.05 of the axis: the sphere's depth there is 3 - r within 0.5 %)
        np.testing.assert_allclose(result.image[..., :3].mean(axis=(0, 1)), radiance * np.exp(-SIGMA * depth),
                                   rtol=0.01)


def test_the_world_volume_renders_as_a_volume_box_around_the_scene():
    """The built-in corner in world fog, and the same with the world clear and the fog in a
    volume-only box 400 m wide around everything (camera and lights inside): the same paths, the
    same image (PPM, same seed; only light beyond the box, 200 m out, may differ)."""
    scene = BUILTIN["corner_in_world_fog"]((16, 16))
    world = scene.world
    fog = {"name": "fog", "opacity": 0.0, "volume_scattering": world.volume_scattering,
           "volume_absorption": world.volume_absorption, "volume_anisotropy": world.volume_anisotropy}
    mats = Materials.build([{"name": "floor", "diffuse": 0.8}, {"name": "wall", "diffuse": 0.5}, fog])
    m = MeshBuilder()
    m.tris, m.mats = [scene.triangle_corners()], [scene.material_ids]
    m.normals = [np.zeros((scene.triangle_count, 3, 3))]
    m.add_box((-200, -200, -200), (200, 200, 200), 2)
    boxed = m.build(mats, scene.lights, scene.camera, World())
    settings = dict(method="ppm", passes=2, photons_per_pass=10_000)
    a, b = (finite_render(s, **settings).image[..., :3] for s in (scene, boxed))
    assert a.mean() > 0.05
    np.testing.assert_allclose(b.mean(axis=(0, 1)), a.mean(axis=(0, 1)), rtol=1e-3)    # (measured 1e-5)
    assert np.abs(b - a).mean() < 1e-3 * a.mean()


def test_a_transparent_film_keeps_the_alpha_of_what_camera_rays_crossed():
    """With a transparent film, a camera ray that leaves the scene makes its pixel's alpha 1 minus
    the mean of what got through (Cycles 5.0, measured: 0.5 behind a Transparent BSDF of colour
    0.2 / 0.5 / 0.8; 0.667 in a world of Volume Absorption attenuating two channels; about
    1 - mean exp(-sigma d) through a volume-only box).  Before, such pixels had alpha 0."""
    cam = looking_down(3.0, 0.5, (4, 4))
    specs = [{"name": "veil", "opacity": 0.0, "transparent_color": (0.2, 0.5, 0.8)},
             {"name": "box", "opacity": 0.0, "volume_absorption": (1.0, 0.5, 0.0)}]
    cases = ((None, World(volume_absorption=np.array([0.05, 0.025, 0.0])), 1.0 - 1.0 / 3.0),
             (0, World(), 0.5),
             (1, World(), 1.0 - np.mean(np.exp(-np.array([1.0, 0.5, 0.0])))))
    for material, world, alpha in cases:
        m = MeshBuilder()
        if material == 0:
            m.add_quad((-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0), 0)
        elif material == 1:
            m.add_box((-5, -5, 0), (5, 5, 1), 1)
        world.film_transparent = True
        scene = m.build(Materials.build(specs), Lights.empty(), cam, world)
        result = finite_render(scene, method="ppm", passes=1, photons_per_pass=1000)
        np.testing.assert_allclose(result.image[..., 3], alpha, rtol=1e-5)


def test_the_world_volume_round_trips_through_a_scene_file_and_is_validated(tmp_path):
    scene = point_over_floor(World(volume_absorption=SIGMA, volume_scattering=np.array([0.1, 0.0, 0.2]),
                                   volume_anisotropy=-0.4))
    path = tmp_path / "fog.npz"
    scene.save(path)
    loaded = type(scene).load(path)
    np.testing.assert_allclose(loaded.world.volume_absorption, SIGMA, rtol=1e-6)
    np.testing.assert_allclose(loaded.world.volume_scattering, (0.1, 0.0, 0.2), rtol=1e-6)
    assert loaded.world.volume_anisotropy == pytest.approx(-0.4)
    clear = point_over_floor(World())
    clear.save(path)
    assert not type(scene).load(path).world.has_volume
    for field, value, message in (("volume_absorption", (1.0, -1.0, 0.0), "volume_absorption must"),
                                  ("volume_scattering", (np.nan, 0.0, 0.0), "volume_scattering must"),
                                  ("volume_anisotropy", 1.0, "volume_anisotropy must")):
        with pytest.raises(SceneError, match=message):
            point_over_floor(World(**{field: value}))

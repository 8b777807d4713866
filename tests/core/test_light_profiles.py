"""Angular light profiles (``Lights.profile``: Blender's IES Texture on a point, spot or area light).

A profile multiplies a light's intensity by a table over the angles of the direction in the
light's frame: v = acos(-z) down the rows (0: straight along the light's -Z), h = atan2(x, y) + pi
along the columns.  The tests use a smooth function of both angles, so the bilinear table is
exact to ~1e-4, and a frame turned away from the world's axes.
"""
import numpy as np
import pytest

from core import RenderSettings, render
from core.lights import LightSampler, profile_factor, profile_means
from core.scene import SUN, Camera, Lights, Materials, SceneError
from core.testing.scenes import MeshBuilder, _look_down

from test_closed_form import check_mean, light_over_mirror, render_passes


def shape(v, h):
    """The test profile: 1 + 0.6 cos v + 0.3 sin v sin h (0.1 to 1.9; one value at each pole)."""
    return 1.0 + 0.6 * np.cos(v) + 0.3 * np.sin(v) * np.sin(h)


def table(rows=181, cols=361):
    v = np.linspace(0.0, np.pi, rows)[:, None]
    h = np.linspace(0.0, 2.0 * np.pi, cols)[None, :]
    return shape(v, h)[None].astype(np.float32)


# The light's frame: X, Y and Z = -direction, turned 30 degrees about the world's Z and tilted 20.
TURN, TILT = np.radians(30.0), np.radians(20.0)
ROT = (np.array([[np.cos(TURN), -np.sin(TURN), 0], [np.sin(TURN), np.cos(TURN), 0], [0, 0, 1]])
       @ np.array([[1, 0, 0], [0, np.cos(TILT), -np.sin(TILT)], [0, np.sin(TILT), np.cos(TILT)]]))


def profiled(spec):
    """``spec`` with the test profile in the turned frame."""
    return {**spec, "direction": -ROT[:, 2], "axis_u": ROT[:, 0], "axis_v": ROT[:, 1], "profile": 0}


def lights_with_profile(specs):
    lights = Lights.build(specs)
    lights.profiles = table()
    return lights


def angles(d):
    """(v, h) of world directions ``d`` (n, 3) in the turned frame."""
    x, y, z = (d @ ROT).T
    return np.arccos(np.clip(-z, -1, 1)), np.arctan2(x, y) + np.pi


def test_profile_factor_follows_the_table_in_the_lights_frame():
    lights = lights_with_profile([profiled({"kind": "point", "power": 1.0}),
                                  {"kind": "point", "power": 1.0}])
    rng = np.random.default_rng(7)
    d = rng.normal(size=(20_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.concatenate([d, [-ROT[:, 2], ROT[:, 2]]])          # along -Z (v = 0) and +Z (v = pi)
    got = profile_factor(lights, np.zeros(len(d), np.int64), d)
    np.testing.assert_allclose(got, shape(*angles(d)), atol=2e-4)
    assert (profile_factor(lights, np.ones(len(d), np.int64), d) == 1.0).all()   # no profile: 1
    # The mean over the sphere: 1 (cos v and sin v sin h average to 0).
    np.testing.assert_allclose(profile_means(lights.profiles), [1.0], atol=1e-4)


def test_photons_of_a_profiled_light_carry_its_intensity_in_every_direction():
    """Photon flux in a direction cone, over the photons, equals the integral of P / (4 pi) f."""
    from core.accel import Accel
    from core.bsdf import MaterialTable
    m = MeshBuilder()
    m.add_quad((-5, -5, -3), (5, -5, -3), (5, 5, -3), (-5, 5, -3), 0)
    mats = Materials.build([{"name": "floor", "diffuse": 0.5}])
    cam = Camera(world_from_camera=_look_down(1.0), projection="orthographic", frame=(-1, 1, -1, 1),
                 resolution=(4, 4))
    power = 12.0
    scene = m.build(mats, lights_with_profile([profiled({"kind": "point", "power": power})]), cam)
    sampler = LightSampler(scene, Accel(scene), MaterialTable.from_materials(scene.materials))
    n = 1_000_000
    u = np.random.default_rng(3).random((n, 6))
    _, d, flux, _ = sampler.sample(u)
    v, h = angles(d)
    for lo, hi in ((0.0, 0.5), (1.0, 1.6), (2.5, np.pi)):
        inside = (v >= lo) & (v < hi) & (h < np.pi)
        # The integral over the band of v and half the circle of h of P / (4 pi) f.
        c, s2 = np.cos(lo) - np.cos(hi), (np.sin(hi) ** 2 - np.sin(lo) ** 2) / 2
        sin_sq = (hi - lo) / 2 - (np.sin(2 * hi) - np.sin(2 * lo)) / 4        # int sin^2 v dv
        expected = power / (4 * np.pi) * (np.pi * c + 0.6 * np.pi * s2 + 0.3 * 2.0 * sin_sq)
        np.testing.assert_allclose(flux[inside, 0].sum() / n, expected, rtol=0.02)


def test_photons_of_a_profiled_area_light_carry_its_radiance_times_the_profile():
    """An area light's photons leave cosine-distributed and carry the profile's value: the flux
    in a band of directions is P / pi int f cos."""
    from core.accel import Accel
    from core.bsdf import MaterialTable
    m = MeshBuilder()
    m.add_quad((-5, -5, -3), (5, -5, -3), (5, 5, -3), (-5, 5, -3), 0)
    spec = profiled({"kind": "area", "power": 6.0})
    spec.update(axis_u=0.3 * ROT[:, 0], axis_v=0.2 * ROT[:, 1])             # half extents
    scene = m.build(Materials.build([{"name": "floor", "diffuse": 0.5}]), lights_with_profile([spec]),
                    Camera())
    sampler = LightSampler(scene, Accel(scene), MaterialTable.from_materials(scene.materials))
    n = 1_000_000
    _, d, flux, _ = sampler.sample(np.random.default_rng(4).random((n, 6)))
    v, h = angles(d)
    for lo, hi in ((0.0, 0.5), (1.0, 1.5)):
        inside = (v >= lo) & (v < hi) & (h < np.pi)
        expected = 6.0 / np.pi * (np.pi * (np.sin(hi) ** 2 - np.sin(lo) ** 2) / 2
                                  + 0.6 * np.pi * (np.cos(lo) ** 3 - np.cos(hi) ** 3) / 3
                                  + 0.6 * (np.sin(hi) ** 3 - np.sin(lo) ** 3) / 3)
        np.testing.assert_allclose(flux[inside, 0].sum() / n, expected, rtol=0.02)


def test_photons_leave_only_where_the_profile_shines():
    """A downlight's profile (0 from 90 degrees up, a narrow beam): photons are drawn from it, so
    none goes up or is wasted, and the flux still sums to the profile's power; an area light's
    too, with its cosine.  A narrow spot's cone keeps its photons as well."""
    from core.accel import Accel
    from core.bsdf import MaterialTable
    tab = table()
    v = np.linspace(0.0, np.pi, tab.shape[1])
    edge = np.cos(np.radians(30.0))
    tab[0] = np.maximum(np.cos(v[:, None]) - edge, 0.0) ** 2            # a beam of 30 degrees
    m = MeshBuilder()
    m.add_quad((-5, -5, -3), (5, -5, -3), (5, 5, -3), (-5, 5, -3), 0)
    lights = Lights.build([profiled({"kind": "point", "power": 10.0})])
    lights.profiles = tab
    scene = m.build(Materials.build([{"name": "floor", "diffuse": 0.5}]), lights, Camera())
    sampler = LightSampler(scene, Accel(scene), MaterialTable.from_materials(scene.materials))
    n = 200_000
    _, d, flux, _ = sampler.sample(np.random.default_rng(5).random((n, 6)))
    v_d, _ = angles(d)
    assert v_d.max() < np.radians(31.0) and (flux[:, 0] > 0).mean() > 0.99
    # int_0^(30 deg) (cos v - cos 30)^2 sin v dv 2 pi, times P / (4 pi): (1 - cos 30)^3 / 3 * P / 2
    expected = (1.0 - edge) ** 3 / 3.0 * 10.0 / 2.0
    np.testing.assert_allclose(flux[:, 0].mean(), expected, rtol=0.01)
    # An area light with the beam: its photons too (P / pi int f cos: 2 P int_c^1 (x - c)^2 x dx).
    area = profiled({"kind": "area", "power": 10.0})
    area.update(axis_u=0.2 * ROT[:, 0], axis_v=0.2 * ROT[:, 1])
    lights = Lights.build([area])
    lights.profiles = tab
    scene = m.build(Materials.build([{"name": "floor", "diffuse": 0.5}]), lights, Camera())
    sampler = LightSampler(scene, Accel(scene), MaterialTable.from_materials(scene.materials))
    _, d, flux, _ = sampler.sample(np.random.default_rng(8).random((n, 6)))
    assert angles(d)[0].max() < np.radians(31.0) and (flux[:, 0] > 0).mean() > 0.99
    expected = 2.0 * 10.0 * (0.25 - 2.0 * edge / 3.0 + edge ** 2 / 2.0 - edge ** 4 / 12.0)
    np.testing.assert_allclose(flux[:, 0].mean(), expected, rtol=0.01)
    # A spot of 20 degrees with the wide test profile: its photons stay in the cone's rows.
    half = np.radians(10.0)
    spot = profiled({"kind": "spot", "power": 10.0, "spot_angle": 2 * half, "spot_blend": 0.0})
    scene = m.build(Materials.build([{"name": "floor", "diffuse": 0.5}]), lights_with_profile([spot]),
                    Camera())
    sampler = LightSampler(scene, Accel(scene), MaterialTable.from_materials(scene.materials))
    _, d, flux, _ = sampler.sample(np.random.default_rng(6).random((n, 6)))
    assert angles(d)[0].max() < half + np.radians(1.0) and (flux[:, 0] > 0).mean() > 0.9
    expected = 10.0 / 2.0 * ((1.0 - np.cos(half)) + 0.6 * np.sin(half) ** 2 / 2)
    np.testing.assert_allclose(flux[:, 0].mean(), expected, rtol=0.01)


@pytest.mark.parametrize("kind", ("point", "area"))
def test_a_profiled_light_seen_in_a_mirror_shows_its_radiance_times_the_profile(kind):
    """Straight down from the light to the mirror and back up to the camera: v = 0, f = 1.6 (the
    four centre pixels, symmetric about the axis: their sin h terms cancel, and 0.6 (1 - cos v)
    over their 2.5 degrees takes off less than 4e-4; within 1e-3, for that and the two passes'
    jitter)."""
    spec = {"kind": kind, "radius": 0.5, "power": 10.0, "position": (0, 0, 3),
            "direction": (0, 0, -1), "axis_u": (1, 0, 0), "axis_v": (0, 1, 0), "profile": 0}
    if kind == "area":
        spec.update(axis_u=(0.5, 0, 0), axis_v=(0, 0.5, 0))                # 1 m square
    scene = light_over_mirror(spec, profiles=table())
    image = render(scene, RenderSettings(method="ppm", passes=2, photons_per_pass=100,
                                                    workers=1)).image
    centre = image[7:9, 7:9, :3]
    expected = 0.9 * 1.6 * 10.0 / (4 * np.pi ** 2 * 0.25 if kind == "point" else np.pi * 1.0)
    np.testing.assert_allclose(centre.mean(axis=(0, 1)), expected, rtol=1e-3)
    assert np.ptp(centre[..., 0]) > 1e-3                   # (the pixels do differ by their h)


@pytest.mark.parametrize("kind", (pytest.param("point", marks=pytest.mark.slow), "spot"))
def test_a_profiled_light_lights_the_floor_by_its_intensity_in_each_direction(kind):
    """A light 1 m over a diffuse floor; a small orthographic patch 0.8 m off its foot.  The
    floor's radiance there is albedo / pi  I f(v, h) cos / d^2 (a small kernel: its curvature
    bias is below 0.1 %).  The spot's cone (around the turned -Z) covers the patch."""
    albedo, power, height, kernel = 0.5, 100.0, 1.0, 0.05
    target = np.array([0.8, 0.3, 0.0])
    light = profiled({"kind": kind, "position": (0, 0, height), "power": power, "radius": 0.0})
    if kind == "spot":
        light.update(spot_angle=np.radians(150.0), spot_blend=0.0)
    mats = Materials.build([{"name": "floor", "diffuse": albedo}])
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    world_from_camera = _look_down(0.5)
    world_from_camera[:3, 3] += target
    cam = Camera(world_from_camera=world_from_camera, projection="orthographic",
                 frame=(-0.005, 0.005, -0.005, 0.005), resolution=(2, 2))
    from core.testing.scenes import kernel_radius_px
    scene = m.build(mats, lights_with_profile([light]), cam)
    per_pass, result = render_passes(scene, method="ppm", passes=8, photons_per_pass=400_000, max_bounces=1,
                                     initial_radius_px=kernel_radius_px(scene, kernel))
    assert "light profiles" in result.effects
    to = target - np.array([0, 0, height])
    d2 = to @ to
    f = shape(*angles(to[None] / np.sqrt(d2)))[0]
    expected = albedo / np.pi * power / (4 * np.pi) * f * (height / np.sqrt(d2)) / d2
    check_mean(per_pass, expected, 0.01)


def test_profiles_round_trip_through_a_file_and_are_validated(tmp_path):
    spot = {"kind": "spot", "power": 5.0, "radius": 0.1, "direction": (0, 0, -1), "axis_u": (1, 0, 0),
            "axis_v": (0, 1, 0), "profile": 0}
    scene = light_over_mirror(spot, profiles=table(19, 37))
    scene.save(tmp_path / "s.npz")
    back = type(scene).load(tmp_path / "s.npz")
    np.testing.assert_array_equal(back.lights.profiles, scene.lights.profiles)
    np.testing.assert_array_equal(back.lights.profile, [0])
    old = light_over_mirror({"kind": "point", "power": 5.0})
    old.lights.profile = None                              # files from before profiles
    assert (old.validate().lights.profile == -1).all()
    for change, message in (({"profiles": None}, "index into lights.profiles"),
                            ({"profiles": -table(19, 37)}, "not negative"),
                            ({"axis_u": np.float32([[1, 0, 1]])}, "orthogonal axis_u"),
                            ({"kind": np.int8([SUN])}, "point, spot and area lights only")):
        bad = light_over_mirror(spot, profiles=table(19, 37))
        for key, value in change.items():
            setattr(bad.lights, key, value)
        with pytest.raises(SceneError, match=message):
            bad.validate()

"""Panoramic cameras (``Camera.projection``: Cycles' equirectangular, fisheye and mirror-ball
projections; their directions are checked pixel by pixel against Cycles in
``tests/addon/test_addon_export.py``).

Closed form: an open diffuse floor under a constant sky (``sky_over_floor``) seen by a panoramic
camera 2 m above it, looking level: every pixel that sees the floor is albedo * sky, every other one the sky.
The measurement points' radii come from each pixel's solid angle, which differs from row to row
of an equirectangular image by the cosine of the latitude.
"""
from __future__ import annotations

import numpy as np
import pytest

from core import RenderSettings, render
from core.camera import generate_camera_rays
from core.scene import Camera, Scene, SceneError
from core.testing.scenes import sky_over_floor

FLOOR = 10.0         # the floor's size: the whole floor is in view, its photons are the ones seen
# 2 m over the floor, looking along +Y (camera -Z) with +Z up (camera +Y).
LEVEL = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 2.0], [0, 0, 0, 1]])
PANORAMAS = {
    "equirectangular": dict(projection="equirectangular"),
    "fisheye_equidistant": dict(projection="fisheye_equidistant", fisheye_fov=2.0),
    "fisheye_equisolid": dict(projection="fisheye_equisolid", fisheye_fov=2.4, sensor_size=(36.0, 24.0)),
    "mirrorball": dict(projection="mirrorball"),
}


def panorama_over_floor(settings, resolution=(24, 16)):
    scene = sky_over_floor(albedo=0.5, sky=1.0, size=FLOOR)
    return scene.replace(camera=Camera(world_from_camera=LEVEL, resolution=resolution, **settings)).validate()


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
@pytest.mark.parametrize("name", sorted(PANORAMAS))
def test_a_panorama_over_a_floor_under_the_sky_sees_albedo_times_sky(name, method):
    scene = panorama_over_floor(PANORAMAS[name])
    cam = scene.camera
    w, h = cam.resolution
    # Pixels whose every point (the corners of the jitter) sees the floor (away from its edges),
    # the sky, or nothing.
    corners = [generate_camera_rays(cam, np.arange(w * h), np.tile([x, y, 0.5, 0.5], (w * h, 1)))[1]
               for x in (0.0, 1.0) for y in (0.0, 1.0)]
    sees = np.all([d.any(axis=1) for d in corners], axis=0)
    blind = ~np.any([d.any(axis=1) for d in corners], axis=0)
    floor, sky = sees.copy(), sees.copy()
    for d in corners:
        t = -2.0 / np.where(d[:, 2] < 0, d[:, 2], -1e-300)
        floor &= (d[:, 2] < -0.05) & (np.abs(d[:, :2] * t[:, None]).max(axis=1) < FLOOR / 2 - 0.5)
        sky &= d[:, 2] > 0.0
    assert floor.sum() >= 32

    def check(result):
        assert np.isfinite(result.image).all()

    settings = RenderSettings(passes=4, photons_per_pass=40_000, seed=1, workers=1, method=method)
    result = render(scene, settings, on_iteration=check)
    img = result.image.reshape(-1, 4)
    # Seeds 0-3 measured 0.961-1.032 of the closed form (SPPM and AMCMCPPM, all four projections).
    assert img[floor, :3].mean() == pytest.approx(0.5, rel=0.05)
    if sky.any():
        np.testing.assert_allclose(img[sky, :3], 1.0, rtol=1e-6)
    # Pixels outside a fisheye's circle or the ball see nothing: black and opaque, as in Cycles.
    np.testing.assert_array_equal(img[blind], np.tile([0.0, 0.0, 0.0, 1.0], (blind.sum(), 1)))


def test_panoramas_survive_a_file_round_trip_and_bad_ranges_are_refused(tmp_path):
    scene = panorama_over_floor(dict(projection="fisheye_equisolid", fisheye_fov=2.4, fisheye_lens=8.0,
                                     sensor_size=(30.0, 20.0)))
    scene.save(tmp_path / "fisheye.npz")
    cam = Scene.load(tmp_path / "fisheye.npz").camera
    assert (cam.projection, cam.fisheye_fov, cam.fisheye_lens, cam.sensor_size) == \
        ("fisheye_equisolid", 2.4, 8.0, (30.0, 20.0))
    # A file from before panoramas: the defaults.
    arrays = {k: v for k, v in scene.to_arrays().items()
              if not k.startswith(("camera.fisheye", "camera.sensor"))}
    assert Scene.from_arrays(arrays).camera.fisheye_lens == 10.5
    for bad in (dict(projection="cylinder"), dict(projection="equirectangular", latitude_range=(-2.0, 0.0)),
                dict(projection="equirectangular", longitude_range=(1.0, 1.0)),
                dict(projection="fisheye_equisolid", fisheye_lens=0.0)):
        with pytest.raises(SceneError, match="camera"):
            panorama_over_floor(bad)

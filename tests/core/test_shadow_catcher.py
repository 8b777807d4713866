"""Shadow catchers (``SHADOW_CATCHER``, ``core/shadow_catcher.py``): Cycles' Combined and Shadow
Catcher pass of objects that show only what the others do to their light.

Closed forms: a catcher floor with nothing on it has nothing to catch (the pass 1, the opaque film's
Combined the world seen through the floor); a black card over a sunlit catcher floor casts a shadow
that the pass and, on a transparent film, Combined's alpha hold exactly (0 and 1 in the umbra, 1
and 0 in the light: the floor's only light is the sun's, and the black card sends none back).
Against Cycles: ``tests/addon/test_addon_engine.py::test_shadow_catcher_matches_cycles``.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core import RenderSettings, render
from core.scene import SHADOW_CATCHER, Camera, Lights, Materials, World
from core.testing.scenes import MeshBuilder

SKY = np.array([0.2, 0.3, 0.5], np.float32)


def look_down(z):
    m = np.eye(4)
    m[:3, 3] = (0.0, 0.0, z)
    return m


def catcher_floor(card=False, sky=SKY, film_transparent=False, resolution=(32, 32), aside=False):
    """A catcher floor of albedo 0.5 (z = 0, 8 x 8) under a sun of 3 W/m^2 from 45 degrees (towards
    +x) and a world of colour ``sky``; with ``card``, a black card of 2 x 2 at z = 1 over the
    origin, whose shadow lies at x in [0, 2], |y| < 1; with ``aside``, a black card at x in [3.5, 4]
    as high as 2, whose shadow falls beside the floor.  An orthographic camera sees x, y in [-3, 3]."""
    mats = Materials.build([{"name": "floor", "diffuse": 0.5}, {"name": "card", "diffuse": 0.0}])
    m = MeshBuilder()
    m.add_quad((-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0), 0)
    if card:
        m.add_quad((-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1), 1)
    if aside:
        m.add_quad((3.5, -0.5, 2), (4, -0.5, 2), (4, 0.5, 2), (3.5, 0.5, 2), 1)
    cam = Camera(world_from_camera=look_down(3.0), projection="orthographic", frame=(-3, 3, -3, 3),
                 resolution=resolution)
    sun = Lights.build([{"kind": "sun", "direction": (1.0, 0.0, -1.0), "power": 3.0}])
    scene = m.build(mats, sun, cam, World(color=sky, film_transparent=film_transparent))
    vis = np.full(scene.triangle_count, 7, np.uint8)
    vis[:2] |= SHADOW_CATCHER
    return scene.replace(triangle_visibility=vis)


def pixel_centres(resolution=(32, 32)):
    """(x, y) (H, W) of the pixels' centres on the floor (top row at y = 3)."""
    w, h = resolution
    x = -3 + 6 * (np.arange(w) + 0.5) / w
    y = 3 - 6 * (np.arange(h) + 0.5) / h
    return np.meshgrid(x, y)


def test_a_catcher_with_nothing_on_it_catches_nothing():
    """Floor alone: the pass is 1 (its light in the scene is its light alone), and Combined on an
    opaque film without the pass is the world seen through the floor (Cycles' approximate shadow
    catcher: the matte, nothing here, over the background times the mean shadow); with the pass
    asked for, Combined is the matte alone, black and transparent on the floor (as Cycles')."""
    settings = dict(passes=6, photons_per_pass=20000, workers=1, method="ppm")
    opaque = render(catcher_floor(), RenderSettings(**settings))
    assert "shadow catcher" in opaque.effects
    np.testing.assert_allclose(opaque.image[..., :3].mean(axis=(0, 1)), SKY, rtol=0.02)
    assert (opaque.image[..., 3] == 1.0).all()
    with_pass = render(catcher_floor(), RenderSettings(**settings, data_passes=("shadow_catcher",)))
    shadow = with_pass.data["shadow_catcher"]
    assert shadow.shape == (32, 32, 3) and set(with_pass.data) == {"shadow_catcher"}
    np.testing.assert_allclose(shadow.mean(axis=(0, 1)), 1.0, atol=0.02)
    # blocks of 8 x 8 pixels
    blocks = shadow.reshape(4, 8, 4, 8, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(blocks, 1.0, atol=0.06)
    assert np.abs(with_pass.image).max() < 1e-6          # (float32 rounding)


@pytest.mark.parametrize("method, workers", [("ppm", 1), ("ppm", 2), ("amcmcppm", 2)])
def test_the_catchers_render_gathers_the_main_renders_photons(method, workers):
    """With nothing between the sun (the only light) and the catcher, the catchers' second render
    (``CatcherRender``) sends the main render's uniform photons (the same numbers, per worker, from
    the same box: the main scene's, here taller than the catchers' scene by a card whose shadow
    falls beside the floor) and gathers them at the same points with the same radii: the shadow is
    exactly 1 in every pixel, not 1 give or take their noise (with the chains, its numerator is the
    same uniform photons traced in the main scene).  (Without the main scene's box, every pixel
    was off, by up to 27-42 %: two samples of a noisy estimate.)"""
    scene = catcher_floor(aside=True, sky=np.zeros(3, np.float32))
    result = render(scene, RenderSettings(passes=3, photons_per_pass=5000, workers=workers, method=method,
                                          data_passes=("shadow_catcher",)))
    np.testing.assert_array_equal(result.data["shadow_catcher"], 1.0)


def test_a_catcher_that_is_partly_a_mirror_catches_nothing_from_the_sky():
    """A catcher floor that is a quarter diffuse and half a mirror, with nothing on it, under the
    sun and the sky: the paths that went on through its mirror are traced again in the catchers'
    scene through the mirror too, with the same weight, and the shadow is 1 (within rounding).
    (When the catchers' render chose the lobe afresh, its diffuse part counted once more: 0.76.)"""
    scene = catcher_floor()
    scene = scene.replace(materials=Materials.build([{"name": "floor", "diffuse": 0.25, "mirror": 0.5},
                                                     {"name": "card", "diffuse": 0.0}]))
    result = render(scene, RenderSettings(passes=4, photons_per_pass=20000, workers=1, method="ppm",
                                          data_passes=("shadow_catcher",)))
    np.testing.assert_allclose(result.data["shadow_catcher"], 1.0, atol=1e-6)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_pass_cut_by_the_time_limit_keeps_the_photons_in_common(workers):
    """Uniform photons under a time limit that cuts the last pass: the catchers' render traces that
    pass again with as many photons as each worker traced (``CatcherRender.finish_pass``), so the
    shadow of the floor with nothing on it stays exactly 1 (before, 0 at pixels of the horizon of a
    floor under a sky whose camera rays met the floor only in the cut pass, 3 % off elsewhere)."""
    scene = catcher_floor(aside=True, sky=np.zeros(3, np.float32), resolution=(64, 64))
    result = render(scene, RenderSettings(time_limit=1.5, photons_per_pass=40000, workers=workers,
                                          method="ppm", data_passes=("shadow_catcher",)))
    print("passes", result.passes, "cut", [s["cut_at_time_limit"] for s in result.stats])
    np.testing.assert_array_equal(result.data["shadow_catcher"], 1.0)


@pytest.mark.parametrize("method, workers", [("ppm", 1), ("amcmcppm", 2)])
def test_a_black_card_casts_its_whole_shadow_on_the_catcher(method, workers):
    """Black card over the catcher floor, transparent film: in the umbra the pass is 0 and, without
    the pass, Combined black with alpha 1 (with it, alpha 0: the matte alone); in the sunlight (away
    from the shadow's edges by more than the gather radius, 0.25 at first) the pass is 1 and
    Combined's alpha about 0; the card itself is Combined's, black and opaque.  With the chains the
    shadow's numerator comes from uniform photons too (``CatcherRender.pair``)."""
    res = (48, 48)
    scene = catcher_floor(card=True, sky=np.zeros(3, np.float32), film_transparent=True, resolution=res)
    settings = RenderSettings(passes=6, photons_per_pass=20000, workers=workers, method=method,
                              initial_radius_px=2.0)
    result = render(scene, dataclasses.replace(settings, data_passes=("shadow_catcher",)))
    image = render(scene, settings).image
    x, y = pixel_centres(res)
    umbra = (np.abs(x - 1.5) < 0.2) & (np.abs(y) < 0.6)
    card = (np.abs(x) < 0.9) & (np.abs(y) < 0.9)
    light = (x < -1.35) | (np.abs(y) > 1.35)
    shadow, matte = result.data["shadow_catcher"], result.image
    assert np.isfinite(image).all() and np.isfinite(shadow).all() and np.isfinite(matte).all()
    assert umbra.sum() > 20 and light.sum() > 1000
    assert np.abs(shadow[umbra]).max() < 1e-6
    np.testing.assert_allclose(image[umbra], [[0.0, 0.0, 0.0, 1.0]] * int(umbra.sum()), atol=1e-6)
    np.testing.assert_allclose(shadow[light].mean(axis=0), 1.0, atol=0.03)
    assert image[light][:, 3].mean() < 0.05
    np.testing.assert_allclose(image[card], [[0.0, 0.0, 0.0, 1.0]] * int(card.sum()), atol=1e-6)
    np.testing.assert_array_equal(matte[card], image[card])
    assert np.abs(matte[umbra | light]).max() < 1e-6


def test_a_catcher_no_camera_ray_meets_changes_nothing():
    """A catcher out of the camera's view: the catchers' second render runs, but the image is the
    one without the catcher, bit for bit, and the pass is 1 (also in a scene without catchers:
    Cycles writes 1 there)."""
    scene = catcher_floor(card=True)
    m = MeshBuilder()
    m.add_quad((3.0, -0.5, 0.5), (3.5, -0.5, 0.5), (3.5, 0.5, 0.5), (3.0, 0.5, 0.5), 0)
    aside = m.build(scene.materials)
    n = scene.triangle_count
    both = scene.replace(vertices=np.concatenate([scene.vertices, aside.vertices]),
                         triangles=np.concatenate([scene.triangles, aside.triangles + len(scene.vertices)]),
                         material_ids=np.concatenate([scene.material_ids, aside.material_ids]))
    vis = np.full(both.triangle_count, 7, np.uint8)
    # (a scene with a catcher keeps the photons' direct light, core/direct.py: so does the one without)
    settings = RenderSettings(passes=2, photons_per_pass=4000, workers=1, method="ppm",
                              direct_light="photons")
    plain = render(both.replace(triangle_visibility=vis), settings)
    vis[n:] |= SHADOW_CATCHER
    caught = render(both.replace(triangle_visibility=vis), settings)
    assert "shadow catcher" in caught.effects and "shadow catcher" not in plain.effects
    np.testing.assert_array_equal(caught.image, plain.image)
    # The pass asked for: 1 everywhere, with the catcher out of view and without any (as Cycles').
    with_pass = dataclasses.replace(settings, data_passes=("shadow_catcher",))
    for scene in (both.replace(triangle_visibility=np.full(both.triangle_count, 7, np.uint8)),
                  both.replace(triangle_visibility=vis)):
        result = render(scene, with_pass)
        np.testing.assert_array_equal(result.data["shadow_catcher"], 1.0)
        np.testing.assert_array_equal(result.image, plain.image)


def test_the_catchers_scene_keeps_every_triangle_field_in_step():
    """``Scene.take_triangles`` (the catchers' scene): every per-triangle field keeps the rows
    taken (a field left out would fail validation, its length no longer the triangles')."""
    scene = catcher_floor(card=True)
    t = scene.triangle_count
    full = scene.replace(
        shading_normals=np.tile(np.float32([0, 0, 1]), (t, 3, 1)), uvs=np.zeros((t, 3, 2), np.float32),
        vertex_colors=np.ones((t, 3, 3), np.float32), attributes={"a": np.zeros((t, 3, 3), np.float32)},
        receiver_sets=np.arange(t, dtype=np.uint8), emitter_exclude=np.zeros(t, np.uint8),
        blocker_sets=np.zeros(t, np.uint8), emitter_group=np.full(t, -1, np.int16),
        cryptomatte_ids=np.arange(3 * t, dtype=np.float32).reshape(t, 3)).validate()
    part = full.take_triangles(np.arange(t) >= 2).validate()
    assert part.triangle_count == t - 2
    np.testing.assert_array_equal(part.receiver_sets, full.receiver_sets[2:])
    np.testing.assert_array_equal(part.cryptomatte_ids, full.cryptomatte_ids[2:])
    assert set(fields_of_length(full, t)) <= set(full.PER_TRIANGLE) | {"attributes"}


def fields_of_length(scene, t):
    """The names of ``scene``'s array fields whose first axis has length ``t`` (not the vertices)."""
    return [name for name in scene.__dataclass_fields__
            if name not in ("vertices", "undisplaced") and isinstance(getattr(scene, name), np.ndarray)
            and len(getattr(scene, name)) == t]


@pytest.mark.parametrize("method, workers", [("ppm", 1), ("ppm", 2), ("amcmcppm", 2)])
def test_under_a_time_limit_the_catchers_render_traces_each_pass_once(method, workers):
    """Under a time limit the catchers' render traces a pass after the main one, with as many
    uniform photons as its workers traced (``CatcherRender.add_pass(defer=True)``): once, where
    before it traced the whole pass beside the main one and, where the limit cut the main pass,
    again with the main pass's count (with one worker its time also came out of the main pass's
    budget); the main pass's budget leaves the catchers' render its share of the time left.  The
    pass statistics' ``catcher_photons`` are the main pass's photons, pass by pass (with the chains,
    whose photons are another sample, the whole pass's, in K and in its pair alike), and the
    shadow of the floor with nothing on it is exactly 1.  (4 s: with 2 s, two pool workers beside
    another test process on 2 cores once finished a single pass.)"""
    scene = catcher_floor(aside=True, sky=np.zeros(3, np.float32), resolution=(48, 48))
    result = render(scene, RenderSettings(time_limit=4.0, photons_per_pass=40000, workers=workers,
                                          method=method, data_passes=("shadow_catcher",)))
    assert result.passes >= 2
    for stats in result.stats:
        main = stats["photons_recorded"] if method == "ppm" else stats["photons_per_pass"] * workers
        assert stats["catcher_photons"] == main, stats
        assert stats["catcher_s"] > 0
    np.testing.assert_array_equal(result.data["shadow_catcher"], 1.0)

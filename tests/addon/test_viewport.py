"""The 3D viewport's Rendered shading (``amcmcppm_addon/viewport.py``) without a window: the view's
matrices make the camera Blender projects with, and the live render shows that view, starts
over when the view or the scene changes and stops after its passes.  (Drawing needs ``gpu``,
which exists only with a window: ``ViewportRender.draw`` is not run here.)"""
import os
import time

import bpy
import numpy as np
import pytest

import blender_scenes as bs

FAST = dict(method="ppm", photons_per_pass=20_000)


def lit_floor(scene):
    bs.plane("Floor", size=4.0, material=bs.diffuse())
    bs.light("POINT", location=(0.3, -0.2, 2.0), energy=300.0)
    return bs.camera(location=(0.5, -4.0, 2.5), target=(0.0, 0.0, 0.0))


def view_of(camera_object, depsgraph, size):
    """(view matrix, projection matrix) Blender uses for ``camera_object`` at ``size`` pixels: what a
    viewport looking through that camera holds in ``RegionView3D``."""
    ob = camera_object.evaluated_get(depsgraph)
    proj = ob.calc_matrix_camera(depsgraph, x=size[0], y=size[1], scale_x=1.0, scale_y=1.0)
    return np.array(ob.matrix_world.inverted()), np.array(proj)


@pytest.mark.parametrize("kind", ["perspective", "shifted", "orthographic"])
def test_the_view_matrices_give_the_camera_the_exporter_makes(scene, kind):
    """``Camera.from_view`` of a camera object's matrices (Blender's projection) equals the exported
    camera: frame (with shift and sensor fit), clip range and pose."""
    from amcmcppm.amcmcppm_addon.export.camera import export_camera
    from amcmcppm.core.scene import Camera

    scene.render.resolution_x, scene.render.resolution_y = 48, 30
    ob = bs.camera(location=(1.0, -3.0, 2.0), lens=35.0, ortho_scale=3.0 if kind == "orthographic" else None)
    if kind == "shifted":
        ob.data.shift_x, ob.data.shift_y = 0.2, -0.1
    ob.data.clip_start, ob.data.clip_end = 0.05, 50.0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    view, proj = view_of(ob, depsgraph, (48, 30))
    got = Camera.from_view(view, proj, kind != "orthographic", (48, 30))
    want = export_camera(depsgraph)
    assert got.projection == want.projection and got.resolution == want.resolution
    np.testing.assert_allclose(got.frame, want.frame, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose((got.clip_start, got.clip_end), (want.clip_start, want.clip_end), rtol=1e-4)
    np.testing.assert_allclose(got.world_from_camera, want.world_from_camera, atol=1e-5)


def lit_floor_view(scene, passes, region):
    """The lit floor seen through its camera by a viewport region of ``region`` pixels at Pixel Size
    2 rendering ``passes`` passes with ``FAST`` settings (the final render at half the region's
    size): (its camera object, depsgraph, view matrix, projection matrix)."""
    for key, value in FAST.items():
        setattr(scene.amcmcppm, key, value)
    scene.amcmcppm.viewport_passes = passes
    scene.amcmcppm.viewport_pixel_size = "2"
    scene.render.resolution_x, scene.render.resolution_y = region[0] // 2, region[1] // 2
    ob = lit_floor(scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    view, proj = view_of(ob, depsgraph, region)
    return ob, depsgraph, view, proj


def refresh_until(vp, depsgraph, view, proj, size, done, timeout=120.0):
    """Refresh ``vp`` until ``done(vp)``; returns the passes of the images it took."""
    passes, t0 = [], time.monotonic()
    while not done(vp):
        if vp.refresh(depsgraph, view, proj, True, size):
            passes.append(vp.stats["pass"])
        assert time.monotonic() - t0 < timeout, f"no end after {timeout} s: {passes}, {vp.status()}"
        time.sleep(0.02)
    return passes


def test_the_viewport_renders_its_view_and_starts_over_on_changes(scene):
    """The viewport's render: the view at the region's size over the pixel size, each pass shown,
    the image of a final render through the same camera (same seed, one worker), done after the
    viewport's passes; a moved view or a changed scene starts it over, an unchanged one does not."""
    from amcmcppm.amcmcppm_addon.export import export_scene, render_settings_from
    from amcmcppm.amcmcppm_addon.viewport import ViewportRender
    from amcmcppm.core import render
    from amcmcppm.core.settings import VIEWPORT_FIRST_PHOTONS

    region = (64, 40)
    ob, depsgraph, view, proj = lit_floor_view(scene, 3, region)
    vp = ViewportRender()
    try:
        passes = refresh_until(vp, depsgraph, view, proj, region, lambda v: v.stats and not v.running
                               and v.stats["pass"] == 3)
        assert passes[-1] == 3 and vp.live.job == 1 and vp.status().endswith("done")
        # (a small first pass, for a first image soon, then the scene's photons per pass)
        assert vp.stats["photons"] == [VIEWPORT_FIRST_PHOTONS, 20_000, 20_000]
        image = vp.image
        assert image.shape == (20, 32, 4) and np.isfinite(image).all()
        # The same view through the scene's camera, rendered whole at the same size.
        settings = render_settings_from(scene.amcmcppm, passes=3, time_limit=0.0, workers=1,
                                        first_pass_photons=VIEWPORT_FIRST_PHOTONS)
        final = render(export_scene(depsgraph).scene, settings).image
        assert image[..., :3].mean() > 0.02
        np.testing.assert_allclose(image[..., :3].mean(), final[..., :3].mean(), rtol=1e-3)
        assert np.corrcoef(image[..., :3].ravel(), final[..., :3].ravel())[0, 1] > 0.999
        # Nothing changed: the render stands; a selection changes the depsgraph, not the scene: it
        # stands too.  The view moves: job 2; the scene changes: job 3; a setting: job 4.
        assert not vp.refresh(depsgraph, view, proj, True, region) and vp.live.job == 1
        exported = vp.exported
        ob.select_set(True)
        vp.scene_changed()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        assert not vp.refresh(depsgraph, view, proj, True, region) and vp.live.job == 1
        assert vp.exported is exported and not vp.stale
        moved = view.copy()
        moved[0, 3] += 0.3
        refresh_until(vp, depsgraph, moved, proj, region, lambda v: v.live.job == 2 and v.stats
                      and v.stats["pass"] >= 1)
        # (a moved view sends no scene: the server renders the one it holds through the new camera)
        assert "scene2.npz" not in os.listdir(vp.live.folder)
        bpy.data.lights[0].energy = 0.0
        vp.scene_changed()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        refresh_until(vp, depsgraph, moved, proj, region, lambda v: v.live.job == 3 and v.stats
                      and v.stats["pass"] >= 1)
        assert vp.image[..., :3].max() == 0.0                 # the light is off now
        assert "scene3.npz" in os.listdir(vp.live.folder)
        scene.amcmcppm.seed = 5
        scene.update_tag()                      # (as the panel's change does; a script's does not)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        refresh_until(vp, depsgraph, moved, proj, region, lambda v: v.live.job == 4 and v.stats
                      and v.stats["pass"] >= 1)
        assert "scene4.npz" not in os.listdir(vp.live.folder)   # (the same scene, other settings)
    finally:
        folder = vp.live.folder
        vp.close()
    assert vp.live is None and not os.path.exists(folder)


def test_a_large_view_shows_a_coarse_preview_first(scene):
    """A view of over ``PREVIEW_PIXELS`` pixels (a region of 640 x 480 at Pixel Size 2: 320 x 240)
    shows the live render's preview first, at half the size, and says so in the corner; then its
    passes at the full size, the last the image of a final render through the same camera."""
    from amcmcppm.amcmcppm_addon.export import export_scene, render_settings_from
    from amcmcppm.amcmcppm_addon.viewport import ViewportRender
    from amcmcppm.core import render
    from amcmcppm.core.settings import VIEWPORT_FIRST_PHOTONS

    region = (640, 480)
    _, depsgraph, view, proj = lit_floor_view(scene, 2, region)
    vp = ViewportRender()
    taken, t0 = [], time.monotonic()        # (pass, image shape, status) of each image taken
    try:
        while not (vp.stats and not vp.running and vp.stats["pass"] == 2):
            if vp.refresh(depsgraph, view, proj, True, region):
                taken.append((vp.stats["pass"], vp.image.shape, vp.status()))
            assert time.monotonic() - t0 < 120, taken
            time.sleep(0.02)
        assert taken[0][:2] == (0, (120, 160, 4)) and taken[0][2].startswith("Preview")
        assert [t[0] for t in taken[1:]] in ([1, 2], [2]) and taken[-1][1] == (240, 320, 4)
        assert vp.status().endswith("done")
        settings = render_settings_from(scene.amcmcppm, passes=2, time_limit=0.0, workers=1,
                                        first_pass_photons=VIEWPORT_FIRST_PHOTONS)
        final = render(export_scene(depsgraph).scene, settings).image
        assert vp.image[..., :3].mean() > 0.02
        np.testing.assert_allclose(vp.image[..., :3].mean(), final[..., :3].mean(), rtol=1e-3)
    finally:
        vp.close()


def test_an_empty_scene_shows_black_with_a_message(scene):
    """Nothing to render, and no camera either (the viewport needs none): a black image and a
    message, no render started."""
    from amcmcppm.amcmcppm_addon.viewport import ViewportRender

    ob = bs.camera()
    view, proj = view_of(ob, bpy.context.evaluated_depsgraph_get(), (20, 10))
    bpy.data.objects.remove(ob)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert depsgraph.scene_eval.camera is None
    vp = ViewportRender()
    assert vp.refresh(depsgraph, view, proj, True, (20, 10))
    assert vp.image.shape == (5, 10, 4) and not vp.image.any() and vp.live is None
    assert "nothing to render" in vp.status()

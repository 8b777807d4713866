"""Objects hidden from some camera-path rays (``Scene.triangle_visibility``, Blender's Object >
Visibility > Ray Visibility: Camera, Glossy, Transmission): such rays go through their triangles,
photons never do.

A camera looks straight down at a mirror floor; an emitter (radiance 1, facing down) hangs above
the camera, so the camera sees it only in the mirror, and a grey veil hangs between the camera and
the mirror.  What each pixel sees follows from which rays see the veil and the emitter.
"""
from __future__ import annotations

import numpy as np
import pytest

from core import RenderSettings, render
from core.context import RenderContext
from core.scene import (VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION, Camera, Materials, SceneError,
                        World)
from core.testing.scenes import MeshBuilder

ALL = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION


def mirror_under_camera(veil, emitter):
    """The scene above, with the veil's and the emitter's visibility bits."""
    mats = Materials.build([{"name": "mirror", "mirror": 1.0}, {"name": "emitter", "emission": 1.0},
                            {"name": "veil", "diffuse": 0.5}])
    m = MeshBuilder()
    m.add_quad((-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0), 0)
    m.add_quad((-4, -4, 5), (-4, 4, 5), (4, 4, 5), (4, -4, 5), 1)              # facing down
    m.add_quad((-2, -2, 1), (2, -2, 1), (2, 2, 1), (-2, 2, 1), 2)
    look = np.eye(4)
    look[:3, 3] = (0.0, 0.0, 3.0)
    cam = Camera(world_from_camera=look, projection="orthographic", frame=(-0.5, 0.5, -0.5, 0.5),
                 resolution=(4, 4))
    scene = m.build(mats, camera=cam, world=World(color=np.zeros(3, np.float32)))
    bits = np.repeat(np.array([ALL, emitter, veil], np.uint8), 2)              # two triangles each
    return scene.replace(triangle_visibility=bits).validate()


@pytest.mark.parametrize("veil, emitter, expected", [
    (ALL, ALL, "veil"),                                   # the camera sees the veil's lit top
    (ALL & ~VISIBLE_CAMERA, ALL, "veil from below"),     # the reflection meets the veil's dark side
    (VISIBLE_TRANSMISSION, ALL, 1.0),                     # neither the camera nor the reflection sees it
    (VISIBLE_TRANSMISSION, ALL & ~VISIBLE_GLOSSY, 0.0),   # the emitter is gone from the mirror
    (VISIBLE_TRANSMISSION, VISIBLE_GLOSSY, 1.0),          # ... but seen in it when only the camera is off
], ids=["all", "veil_hidden_from_camera", "veil_hidden", "emitter_hidden_from_glossy", "emitter_glossy_only"])
def test_what_the_camera_sees_in_a_mirror_follows_ray_visibility(veil, emitter, expected):
    scene = mirror_under_camera(veil, emitter)
    result = render(scene, RenderSettings(passes=2, photons_per_pass=20_000, workers=1, method="ppm"))
    got = result.image[..., :3].mean()
    if expected == "veil":
        # The veil's top, lit by the emitter 4 m above it: 0.5 / pi E, E about 1.6 (a wide emitter).
        assert 0.2 < got < 0.35, got
    elif expected == "veil from below":
        assert got < 0.02, got                            # lit only by light bounced off the mirror's edge
    else:
        np.testing.assert_allclose(got, expected, atol=1e-6)
    assert ("objects hidden from camera rays" in result.effects) == (veil != ALL or emitter != ALL)


def test_photons_meet_hidden_triangles_and_bad_bits_are_refused():
    """A veil hidden from every camera ray still shadows the mirror's photons (no ray_kind), and
    visibility bits must fit in three."""
    scene = mirror_under_camera(0, ALL)
    ctx = RenderContext(scene)
    up, down = np.array([[0.0, 0.0, 0.5]]), np.array([[0.0, 0.0, 1.0]])
    hits, _, _, _ = ctx.trace(up, down)
    assert ctx.material_ids[hits.prim_ids[0]] == 2                          # the veil
    hits, _, _, _ = ctx.trace(up, down, ray_kind=np.array([VISIBLE_GLOSSY], np.uint8))
    assert ctx.material_ids[hits.prim_ids[0]] == 1                          # through it: the emitter
    with pytest.raises(SceneError, match="triangle_visibility must be a bit mask"):
        scene.replace(triangle_visibility=np.full(scene.triangle_count, 64, np.uint8)).validate()

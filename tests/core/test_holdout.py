"""Holdouts (``Materials.holdout``, ``HOLDOUT_OBJECT``): what camera rays that meet them cut out.

As Cycles renders them (checked with bpy 5.0.1 on a card over a glowing floor, 16 samples): a
Holdout shader or a holdout object seen directly, or through a Transparent BSDF, makes the pixel
black with alpha 0, whether the film is transparent or not; a Mix of a Holdout (0.75) and an
emission (0.25) gives a quarter of the emission and alpha 0.25.  Seen in a mirror, a holdout
object shows its material and a Holdout shader is black, with alpha 1.
"""
from __future__ import annotations

import numpy as np
import pytest

from core import RenderSettings, render
from core.scene import HOLDOUT_OBJECT, Camera, Materials, SceneError, World
from core.testing.scenes import MeshBuilder


def look_down(z):
    m = np.eye(4)
    m[:3, 3] = (0.0, 0.0, z)
    return m


def card_scene(card, mirror=False, veil=False, holdout_object=False, film_transparent=False):
    """An emitting floor (radiance (1, 0.5, 0.25)) at z = -1 and a card of material spec ``card``
    at z = 0 (facing down, seen in a mirror at z = -1 instead of the floor, with ``mirror``), an
    orthographic camera looking straight down at z = 3 (through a clear Transparent veil at z = 1
    with ``veil``)."""
    floor = {"name": "mirror", "mirror": 1.0} if mirror else {"name": "floor", "emission": (1.0, 0.5, 0.25)}
    specs = [floor, card, {"name": "veil", "opacity": 0.0}]
    m = MeshBuilder()
    m.add_quad((-5, -5, -1), (5, -5, -1), (5, 5, -1), (-5, 5, -1), 0)
    z = 2.0 if mirror else 0.0
    if mirror:
        m.add_quad((-5, -5, z), (-5, 5, z), (5, 5, z), (5, -5, z), 1)       # faces down, into the mirror
    else:
        m.add_quad((-5, -5, z), (5, -5, z), (5, 5, z), (-5, 5, z), 1)
    if veil:
        m.add_quad((-5, -5, 1), (5, -5, 1), (5, 5, 1), (-5, 5, 1), 2)
    cam = Camera(world_from_camera=look_down(3.0 if not mirror else 1.5), projection="orthographic",
                 frame=(-0.2, 0.2, -0.2, 0.2), resolution=(4, 4))
    scene = m.build(Materials.build(specs), camera=cam,
                    world=World(color=np.full(3, 0.1, np.float32), film_transparent=film_transparent))
    if holdout_object:
        vis = np.full(scene.triangle_count, 7, np.uint8)
        vis[scene.material_ids == 1] |= HOLDOUT_OBJECT
        scene = scene.replace(triangle_visibility=vis).validate()
    return scene


def rgba(scene, **settings):
    def check(result):
        assert np.isfinite(result.image).all()

    result = render(scene, RenderSettings(workers=1, method="ppm", passes=2, photons_per_pass=2000,
                                          **settings), on_iteration=check)
    return result.image.reshape(-1, 4).mean(axis=0), result


@pytest.mark.parametrize("film_transparent", [False, True], ids=["opaque_film", "transparent_film"])
@pytest.mark.parametrize("veil", [False, True], ids=["direct", "through_a_veil"])
def test_a_holdout_cuts_its_pixels_out(film_transparent, veil):
    green = {"name": "card", "emission": (0.0, 1.0, 0.0)}
    for card, holdout_object in (({"name": "card", "holdout": 1.0}, False), (green, True)):
        got, result = rgba(card_scene(card, veil=veil, holdout_object=holdout_object,
                                      film_transparent=film_transparent))
        np.testing.assert_allclose(got, 0.0, atol=1e-6)
        assert "holdout" in result.effects


def test_a_mix_with_a_holdout_keeps_the_rest():
    """A Mix of a Holdout (0.75) and an emission (0.25): the lobes and emission come scaled by
    the exporter (a quarter of the green), the alpha is 1 - 0.75."""
    got, _ = rgba(card_scene({"name": "card", "holdout": 0.75, "emission": (0.0, 0.25, 0.0)}))
    np.testing.assert_allclose(got, [0.0, 0.25, 0.0, 0.25], atol=1e-6)


def test_in_a_mirror_a_holdout_object_shows_its_material_and_a_holdout_shader_is_black():
    got, _ = rgba(card_scene({"name": "card", "emission": (0.0, 1.0, 0.0)}, mirror=True, holdout_object=True))
    np.testing.assert_allclose(got, [0.0, 1.0, 0.0, 1.0], atol=1e-6)
    got, _ = rgba(card_scene({"name": "card", "holdout": 1.0}, mirror=True))
    np.testing.assert_allclose(got, [0.0, 0.0, 0.0, 1.0], atol=1e-6)


def test_holdouts_are_checked_and_survive_a_file_round_trip(tmp_path):
    scene = card_scene({"name": "card", "holdout": 0.5}, holdout_object=True)
    scene.save(tmp_path / "h.npz")
    back = type(scene).load(tmp_path / "h.npz")
    np.testing.assert_array_equal(back.materials.holdout, scene.materials.holdout)
    np.testing.assert_array_equal(back.triangle_visibility, scene.triangle_visibility)
    with pytest.raises(SceneError, match="holdout"):
        card_scene({"name": "card", "holdout": 1.5})
    # (16 is CASTS_NO_SHADOW since stop 41, 32 SHADOW_CATCHER since stop 55)
    with pytest.raises(SceneError, match="0 to 63"):
        scene.replace(triangle_visibility=np.full(scene.triangle_count, 64, np.uint8)).validate()


def test_only_the_pixels_that_see_the_holdout_lose_their_alpha():
    """A holdout card over the left half of the view: the left half black with alpha 0, the right
    half the glowing floor with alpha 1."""
    mats = Materials.build([{"name": "floor", "emission": (1.0, 0.5, 0.25)},
                            {"name": "card", "holdout": 1.0}])
    m = MeshBuilder()
    m.add_quad((-5, -5, -1), (5, -5, -1), (5, 5, -1), (-5, 5, -1), 0)
    m.add_quad((-5, -5, 0), (0, -5, 0), (0, 5, 0), (-5, 5, 0), 1)
    cam = Camera(world_from_camera=look_down(3.0), projection="orthographic", frame=(-0.2, 0.2, -0.2, 0.2),
                 resolution=(4, 4))
    result = render(m.build(mats, camera=cam), RenderSettings(workers=1, method="ppm", passes=2,
                                                             photons_per_pass=2000))
    image = result.image.reshape(4, 4, 4)
    np.testing.assert_allclose(image[:, :2], 0.0, atol=1e-6)
    np.testing.assert_allclose(image[:, 2:], np.broadcast_to([1.0, 0.5, 0.25, 1.0], (4, 2, 4)), atol=1e-6)

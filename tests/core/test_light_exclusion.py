"""Emitters that do not light some rays (``Lights.exclude``, ``World.exclude``,
``Scene.emitter_exclude``; Blender's Ray Visibility boxes Diffuse, Glossy, Transmission and Volume
Scatter on a light, a world or an emissive object, Cycles' SHADER_EXCLUDE_*).

The light that first meets a surface reaches none of its lobes of an excluded kind there, neither
as a deposit nor as a scattering, and what it lights further on is unaffected.  Closed forms:

* a sun straight down through a glass slab onto a diffuse floor (``sun_through_slab``): without
  transmission the floor under the slab is dark; without diffuse or glossy it is as before, its light
  having first met the glass;
* a floor under a constant sky (``sky_over_floor``): without diffuse it is black, without glossy
  exactly as before (the same seed, bit for bit); a floor with a diffuse and a glossy lobe: the
  images without each add up to the whole, pixel by pixel;
* a mirror under an orthographic camera, under a sky of 1: a world that does not light glossy rays
  is black in the mirror;
* a sunlit volume-only slab: without volume scatter its single scattering is gone;
* an emissive panel without diffuse leaves a diffuse floor black, and one that lights nothing
  sends no photons.

An object that casts no shadow (``CASTS_NO_SHADOW``, Ray Visibility > Shadow off) lets the direct
light through: a sunlit diffuse sheet over a diffuse floor, the floor's radiance
rho E / (pi (1 - rho D)) as if the sheet were not in the sun's way.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core import RenderSettings, render
from core.scene import (CASTS_NO_SHADOW, EXCLUDE_ALL, EXCLUDE_DIFFUSE, EXCLUDE_GLOSSY, EXCLUDE_SCATTER,
                        EXCLUDE_TRANSMISSION, VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION, Camera,
                        Lights, Materials, SceneError, World)
from core.testing.scenes import MeshBuilder, sky_over_floor, sun_through_sheet, sun_through_slab

# (emitters that leave out rays keep the photons' direct light, core/direct.py: the renders they are
# compared with take it from photons too)
PPM = dict(method="ppm", workers=1, seed=3, direct_light="photons")
ALL_RAYS = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION
METHODS = [PPM, dict(method="amcmcppm", workers=1, seed=3, chains=1024, direct_light="photons")]


def excluding(scene, bits):
    """``scene`` with every light's ``exclude`` set to ``bits``."""
    scene.lights.exclude = np.full(scene.lights.count, bits, np.uint8)
    return scene.validate()


@pytest.mark.parametrize("settings", METHODS, ids=["ppm", "amcmcppm"])
def test_a_sun_that_does_not_light_transmission_leaves_the_floor_under_a_slab_dark(settings):
    """E (1 - F0)^2 albedo / pi = 1.467 under the slab with every kind lit.  Without transmission
    only the light of the floor around the slab, which the glass throws back under it, is left
    (0.1 % of that, measured; the camera sees 0.2 m of the slab's 0.6, and the floor's own photons
    reach none of its points)."""
    run = RenderSettings(passes=4, photons_per_pass=40_000, max_bounces=2, **settings)
    f0 = (0.5 / 2.5) ** 2
    expected = 10.0 * (1 - f0) ** 2 * 0.5 / np.pi
    images = {bits: render(excluding(sun_through_slab(), bits), run).image[..., :3]
              for bits in (0, EXCLUDE_TRANSMISSION, EXCLUDE_DIFFUSE | EXCLUDE_GLOSSY | EXCLUDE_SCATTER)}
    np.testing.assert_allclose(images[0].mean(), expected, rtol=0.05)
    assert images[EXCLUDE_TRANSMISSION].max() < 5e-3 * expected
    # The floor's light first met the glass (its top face refracts it): nothing else changes.  (The
    # chains' two renders part ways at the first path whose visibility the exclusion changes, and
    # then differ by their noise: 0.4 to 1.5 % over seeds 3 to 5, aimed from the first pass.)
    np.testing.assert_allclose(images[EXCLUDE_DIFFUSE | EXCLUDE_GLOSSY | EXCLUDE_SCATTER].mean(),
                               images[0].mean(), rtol=0.01 if settings["method"] == "ppm" else 0.025)


def test_a_world_that_does_not_light_diffuse_leaves_a_diffuse_floor_black():
    run = RenderSettings(passes=3, photons_per_pass=30_000, **PPM)
    images = {}
    for bits in (0, EXCLUDE_DIFFUSE, EXCLUDE_GLOSSY | EXCLUDE_TRANSMISSION | EXCLUDE_SCATTER):
        scene = sky_over_floor(resolution=(16, 16))
        scene.world.exclude = bits
        images[bits] = render(scene.validate(), run).image[..., :3]
    assert images[0].mean() > 0.3                            # 0.5 in the limit (sky_over_floor)
    assert not images[EXCLUDE_DIFFUSE].any()
    # A diffuse floor has no glossy or transmission lobe: the same photons, the same image.
    np.testing.assert_array_equal(images[EXCLUDE_GLOSSY | EXCLUDE_TRANSMISSION | EXCLUDE_SCATTER], images[0])


@pytest.mark.parametrize("settings", METHODS, ids=["ppm", "amcmcppm"])
def test_a_diffuse_and_a_glossy_lobe_lit_apart_add_up_to_the_whole(settings):
    """A floor of diffuse 0.4 and glossy 0.5 (roughness 0.3) under a sun: the light on each lobe is
    the whole minus the other's.  With the same seed the photons are the same, so the images of a
    sun that lights only the diffuse and only the glossy lobe add up to the whole to rounding
    (with the chains, the visible set is the cells, the same in the three renders)."""
    run = RenderSettings(passes=3, photons_per_pass=30_000, **settings)
    floor = {"diffuse": 0.4, "glossy": 0.5, "roughness": 0.3}
    images = {}
    for bits in (0, EXCLUDE_DIFFUSE, EXCLUDE_GLOSSY):
        scene = sky_over_floor(resolution=(16, 16), material=floor)
        sun = {"kind": "sun", "direction": (0.3, 0.2, -1.0), "power": 5.0, "exclude": bits}
        scene = scene.replace(world=World(color=np.zeros(3, np.float32)), lights=Lights.build([sun]))
        images[bits] = render(scene.validate(), run).image[..., :3].astype(np.float64)
    whole, glossy_only, diffuse_only = images[0], images[EXCLUDE_DIFFUSE], images[EXCLUDE_GLOSSY]
    assert glossy_only.mean() > 0.05 * whole.mean() and diffuse_only.mean() > 0.05 * whole.mean()
    np.testing.assert_allclose(glossy_only + diffuse_only, whole, rtol=1e-4, atol=1e-6)


def mirror_under_sky(bits):
    """An orthographic camera looking straight down at a mirror, under a constant sky of 1 that
    does not light the rays ``bits``."""
    m = MeshBuilder()
    m.add_quad((-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0), 0)
    look = np.eye(4)
    look[:3, 3] = (0.0, 0.0, 3.0)
    cam = Camera(world_from_camera=look, projection="orthographic", frame=(-0.5, 0.5, -0.5, 0.5),
                 resolution=(4, 4))
    world = World(color=np.ones(3, np.float32), exclude=bits)
    return m.build(Materials.build([{"name": "mirror", "mirror": 1.0}]), camera=cam, world=world)


@pytest.mark.parametrize("bits, expected", [(0, 1.0), (EXCLUDE_GLOSSY, 0.0), (EXCLUDE_TRANSMISSION, 1.0),
                                            (EXCLUDE_DIFFUSE | EXCLUDE_SCATTER, 1.0)],
                         ids=["all", "glossy_off", "transmission_off", "diffuse_and_scatter_off"])
def test_a_mirror_shows_the_world_only_where_it_lights_glossy_rays(bits, expected):
    result = render(mirror_under_sky(bits), RenderSettings(passes=1, photons_per_pass=1000, **PPM))
    np.testing.assert_allclose(result.image[..., :3], expected, atol=1e-6)


def sunlit_fog(bits):
    """A volume-only slab z in [1, 1.5] scattering 0.2 and absorbing 0.1 per metre, under a sun
    straight down that does not light the rays ``bits``; an orthographic camera looks down at it."""
    mats = Materials.build([{"name": "slab", "opacity": 0.0, "volume_scattering": 0.2,
                             "volume_absorption": 0.1}])
    m = MeshBuilder()
    m.add_box((-2, -2, 1.0), (2, 2, 1.5), 0)
    pose = np.eye(4)
    pose[2, 3] = 3.0
    cam = Camera(world_from_camera=pose, projection="orthographic", frame=(-1, 1, -1, 1), resolution=(8, 8))
    lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": 10.0, "exclude": bits}])
    return m.build(mats, lights, cam)


def test_a_sun_that_does_not_light_volumes_leaves_fog_dark():
    """Lit, the slab shows its single scattering straight back (``test_scattering_volumes.py`` checks
    its closed form); without volume scatter nothing scatters (the sun reaches no surface)."""
    run = RenderSettings(passes=3, photons_per_pass=60_000, max_bounces=1, initial_radius_px=2.0, **PPM)
    others = EXCLUDE_DIFFUSE | EXCLUDE_GLOSSY | EXCLUDE_TRANSMISSION
    lit, dark, same = (render(sunlit_fog(bits), run).image[..., :3] for bits in (0, EXCLUDE_SCATTER, others))
    assert lit.mean() > 0.05
    assert not dark.any()
    np.testing.assert_array_equal(same, lit)


def test_an_emissive_object_that_does_not_light_diffuse_leaves_the_floor_dark():
    """A diffuse floor under an emissive panel (Scene.emitter_exclude); the panel's photons that
    first land on the floor are its only light there.  Emitters that light nothing send no photons."""
    mats = Materials.build([{"name": "floor", "diffuse": 0.5}, {"name": "panel", "emission": 2.0}])
    m = MeshBuilder()
    m.add_quad((-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0), 0)
    m.add_quad((-1, -1, 1), (-1, 1, 1), (1, 1, 1), (1, -1, 1), 1)              # facing down
    pose = np.eye(4)
    pose[2, 3] = 0.5
    cam = Camera(world_from_camera=pose, projection="orthographic", frame=(-0.5, 0.5, -0.5, 0.5),
                 resolution=(4, 4))
    scene = m.build(mats, camera=cam)
    run = RenderSettings(passes=2, photons_per_pass=20_000, **PPM)
    means = {}
    for bits in (0, EXCLUDE_DIFFUSE, EXCLUDE_ALL):
        result = render(scene.replace(emitter_exclude=np.uint8([0, 0, bits, bits])).validate(), run)
        means[bits] = result.image[..., :3].mean()
        if bits == EXCLUDE_ALL:
            assert result.stats[-1]["photon_vertices"] == 0
    assert means[0] > 0.2 and means[EXCLUDE_DIFFUSE] == 0 and means[EXCLUDE_ALL] == 0


def test_exclusion_bits_round_trip_through_a_scene_file_and_bad_ones_are_refused(tmp_path):
    scene = excluding(sun_through_slab(), EXCLUDE_DIFFUSE | EXCLUDE_SCATTER)
    scene.world.exclude = EXCLUDE_GLOSSY
    scene = scene.replace(emitter_exclude=np.full(scene.triangle_count, EXCLUDE_TRANSMISSION, np.uint8))
    path = tmp_path / "scene.npz"
    scene.save(path)
    back = type(scene).load(path)
    assert back.lights.exclude.tolist() == [EXCLUDE_DIFFUSE | EXCLUDE_SCATTER]
    assert back.world.exclude == EXCLUDE_GLOSSY
    assert (back.emitter_exclude == EXCLUDE_TRANSMISSION).all()
    with pytest.raises(SceneError, match="lights.exclude"):
        excluding(sun_through_slab(), 1)                   # bit 1 (the camera) is not a lit ray
    with pytest.raises(SceneError, match="world.exclude"):
        bad = sun_through_slab()
        bad.world.exclude = 64
        bad.validate()


@pytest.mark.parametrize("settings", METHODS, ids=["ppm", "amcmcppm"])
def test_a_sheet_that_casts_no_shadow_lets_the_sun_onto_the_floor(settings):
    """A diffuse sheet (D = 0.5) over a diffuse floor (rho = 0.5) under a sun straight down
    (``sun_through_sheet``), the sheet marked CASTS_NO_SHADOW (Blender's Ray Visibility > Shadow
    off): the floor gets the sun as if the sheet were not there, and the sheet's underside still
    throws the floor's light back: B = rho E / (1 - rho D), L = B / pi = 2.12.  Casting its shadow,
    the sheet leaves the floor dark.  (The camera sees 10 m of the 40 m floor: with its default
    0.4 m, 6 photons a pass reached what it sees.  Two seeds of each method measured 0.998-1.041.)"""
    run = RenderSettings(passes=4, photons_per_pass=40_000, max_bounces=6, initial_radius_px=2.0, **settings)
    expected = 0.5 * 10.0 / (1 - 0.5 * 0.5) / np.pi
    scene = sun_through_sheet({"diffuse": 0.5}, floor_albedo=0.5, resolution=(32, 32))
    scene = scene.replace(camera=dataclasses.replace(scene.camera, frame=(-5.0, 5.0, -5.0, 5.0))).validate()
    bits = np.uint8([ALL_RAYS | CASTS_NO_SHADOW] * 2 + [ALL_RAYS] * 2)          # the sheet, the floor
    shadowless = scene.replace(triangle_visibility=bits)
    result = render(shadowless.validate(), run)
    np.testing.assert_allclose(result.image[..., :3].mean(), expected, rtol=0.05)
    assert "objects that cast no shadow" in result.effects
    assert render(scene, run).image[..., :3].max() < 1e-3 * expected

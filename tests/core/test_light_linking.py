"""Light linking (``Scene.receiver_sets``, ``Scene.emitter_links``, ``Lights.links``): an emitter
lights directly only the triangles of the receiver sets it links; its light goes on from those
as from any surface; camera rays see every emitter, reflections only those that light the
mirror's set (Cycles' rules).  Shadow linking (``Scene.blocker_sets``, ``Lights.shadow_links``):
only the triangles of the blocker sets an emitter names shadow its direct light."""
import numpy as np
import pytest

from core.scene import ALL_LINKS, Lights, Materials, SceneError
from core.testing.scenes import MeshBuilder, sun_through_sheet

from render_utils import finite_render
from test_closed_form import light_over_mirror
from test_translucent import view_factor_to_square

METHODS = [dict(method="ppm"), dict(method="amcmcppm", chains=4096)]
# The chains' cases of the closed forms below but one run in the slow tier (the photons' rules
# are the same code for both methods).
PPM_FAST = [METHODS[0], pytest.param(METHODS[1], marks=pytest.mark.slow)]


def two_floors(links_a, links_b, resolution=(32, 16)):
    """Two halves of an 8 m floor of albedo 0.5 (x < 0: receiver set 0, x > 0: set 1) under two
    suns straight down, of irradiance 4 (``links_a``) and 1 (``links_b``), seen from above by an
    orthographic camera 4 m wide (pixels of 12.5 cm: gather radii of 50 cm at first)."""
    from core.scene import Camera
    m = MeshBuilder()
    h = 4.0
    m.add_quad((-h, -h, 0), (0, -h, 0), (0, h, 0), (-h, h, 0), 0)
    m.add_quad((0, -h, 0), (h, -h, 0), (h, h, 0), (0, h, 0), 0)
    lights = Lights.build([{"kind": "sun", "power": 4.0, "links": links_a},
                           {"kind": "sun", "power": 1.0, "links": links_b}])
    pose = np.eye(4)
    pose[2, 3] = 1.0
    cam = Camera(world_from_camera=pose, projection="orthographic", frame=(-2, 2, -1, 1),
                 resolution=resolution)
    scene = m.build(Materials.build([{"name": "floor", "diffuse": 0.5}]), lights, cam)
    return scene.replace(receiver_sets=np.repeat(np.uint8([0, 1]), 2)).validate()


@pytest.mark.parametrize("method, links_a, left, right", [
    (METHODS[0], 2, 1.0, 5.0), (METHODS[0], 1, 5.0, 1.0), (METHODS[1], 2, 1.0, 5.0)],
    ids=["ppm-right", "ppm-left", "amcmcppm-right"])
def test_a_sun_linked_to_one_half_of_a_floor_lights_that_half_alone(method, links_a, left, right):
    """Sun A (E = 4) lights set 1 (the right half) only, sun B (E = 1) everything: the left
    half shows 0.5 x 1 / pi, the right 0.5 x 5 / pi (columns away from the seam, where the
    kernel reaches across it).  Linked the other way round, the halves swap."""
    result = finite_render(two_floors(np.uint64(links_a), ALL_LINKS), passes=6, photons_per_pass=100_000,
                           **method)
    assert "light linking" in result.effects
    image = result.image[..., :3]
    np.testing.assert_allclose(image[:, 2:10].mean(axis=(0, 1)), 0.5 * left / np.pi, rtol=0.04)
    np.testing.assert_allclose(image[:, 22:30].mean(axis=(0, 1)), 0.5 * right / np.pi, rtol=0.04)


def test_unlinked_suns_light_both_halves_and_name_no_effect():
    result = finite_render(two_floors(ALL_LINKS, ALL_LINKS), passes=6, photons_per_pass=100_000, method="ppm")
    assert "light linking" not in result.effects
    np.testing.assert_allclose(result.image[..., :3].mean(), 0.5 * 5 / np.pi, rtol=0.04)


@pytest.mark.parametrize("method", PPM_FAST, ids=lambda m: m["method"])
def test_linked_light_reaches_the_unlinked_floor_only_through_the_linked_sheet(method):
    """A sun on a translucent sheet (T = 0.8) 1 m over a floor (test_translucent's closed form,
    rho T E F / pi under the sheet).  Sun linked to the sheet alone: the floor is lit as without
    linking (its light comes through the sheet, where the photons first land).  Sun linked to
    the floor alone: photons end on the unlit sheet and the floor stays black."""
    half, rho, t, e = 3.0, 0.5, 0.8, 10.0
    plain = sun_through_sheet({"translucent": t}, e, floor_albedo=rho, half=half)
    sets = np.uint8([1, 1, 0, 0])                      # the sheet's two triangles, then the floor's
    xs = (np.arange(8) + 0.5) / 8 * 0.4 - 0.2
    f = view_factor_to_square(xs[:, None], xs[None, :], half, 1.0).mean()
    for links, expected in ((2, rho * t * e * f / np.pi), (1, 0.0)):
        lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": e, "links": links}])
        scene = plain.replace(lights=lights, receiver_sets=sets).validate()
        image = finite_render(scene, passes=8, photons_per_pass=60_000, max_bounces=4, **method).image
        if expected:
            np.testing.assert_allclose(image[..., :3].mean(axis=(0, 1)), expected, rtol=0.05)
        else:
            assert image[..., :3].max() == 0.0


@pytest.mark.parametrize("method", PPM_FAST, ids=lambda m: m["method"])
def test_a_sheet_that_does_not_shadow_the_sun_leaves_the_floor_lit(method):
    """Shadow linking: a black sheet (half-size 3 m) 1 m over a floor of albedo 0.5, the camera
    between them looking down.  The sun shadowed by the floor's blocker set alone: the floor
    under the sheet gets its whole direct light, rho E / pi (photons stop on the sheet or pass
    it, each half the time with twice the flux).  Shadowed by the sheet's set: black."""
    rho, e = 0.5, 10.0
    plain = sun_through_sheet({"diffuse": 0.0}, e, floor_albedo=rho, half=3.0)
    sets = np.uint8([1, 1, 0, 0])                      # the sheet's two triangles, then the floor's
    for shadow_links, expected in ((1, rho * e / np.pi), (2, 0.0)):
        lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": e,
                                "shadow_links": shadow_links}])
        scene = plain.replace(lights=lights, blocker_sets=sets).validate()
        result = finite_render(scene, passes=12, photons_per_pass=150_000, **method)
        assert "shadow linking" in result.effects
        image = result.image[..., :3]
        if expected:
            # 4 seeds of PPM at 200,000 photons: 0.988-1.027 of it; AMCMCPPM at 6 passes over seeds
            # 0-21 0.95-1.04 (hence 12).
            np.testing.assert_allclose(image.mean(axis=(0, 1)), expected, rtol=0.05)
        else:
            assert image.max() == 0.0


def test_reflections_show_only_lights_that_light_the_mirror():
    """An area light over a mirror (set 1 here): linked to set 1 the mirror shows it exactly, to
    set 0 it shows nothing; a camera looking straight at a light sees it whatever its links (Cycles
    exempts camera rays).  An emissive quad over the mirror follows its ``emitter_links`` alike."""
    from core.scene import VISIBLE_CAMERA, VISIBLE_GLOSSY
    settings = dict(method="ppm", passes=2, photons_per_pass=100)
    spec = {"kind": "area", "size": (1.0, 1.0), "power": 10.0}
    for links, seen in ((2, 0.9 * 10.0 / np.pi), (1, 0.0)):
        scene = light_over_mirror({**spec, "links": links})
        scene = scene.replace(receiver_sets=np.ones(scene.triangle_count, np.uint8)).validate()
        centre = finite_render(scene, **settings).image[7:9, 7:9, :3]
        np.testing.assert_allclose(centre, seen, rtol=1e-5)
        up = light_over_mirror({**spec, "links": links, "visibility": VISIBLE_CAMERA | VISIBLE_GLOSSY},
                               camera_up=True)
        up = up.replace(receiver_sets=np.ones(up.triangle_count, np.uint8)).validate()
        np.testing.assert_allclose(finite_render(up, **settings).image[7:9, 7:9, :3], 10.0 / np.pi, rtol=1e-5)

    # An emissive quad (radiance 2) 3 m over the mirror, facing down, linked to the mirror's set or not.
    plain = light_over_mirror({**spec, "power": 0.0})
    m = MeshBuilder()
    h = 25.0
    m.add_quad((-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0), 0)
    m.add_quad((-1, -1, 3), (-1, 1, 3), (1, 1, 3), (1, -1, 3), 1)
    mats = Materials.build([{"name": "mirror", "mirror": 0.9}, {"name": "glow", "emission": 2.0}])
    base = m.build(mats, Lights.empty(), plain.camera)
    for links, seen in ((2, 0.9 * 2.0), (1, 0.0)):
        scene = base.replace(receiver_sets=np.uint8([1, 1, 0, 0]),
                             emitter_links=np.uint64([ALL_LINKS, ALL_LINKS, links, links])).validate()
        centre = finite_render(scene, **settings).image[7:9, 7:9, :3]
        np.testing.assert_allclose(centre, seen, rtol=1e-5)


def test_links_round_trip_through_a_scene_file_and_are_validated(tmp_path):
    scene = two_floors(np.uint64(2), ALL_LINKS)
    scene = scene.replace(emitter_links=np.uint64([3, 3, ALL_LINKS, 5]), blocker_sets=np.uint8([2, 2, 0, 0]),
                          emitter_shadow_links=np.uint64([1, 1, 1, ALL_LINKS])).validate()
    path = tmp_path / "linked.npz"
    scene.save(path)
    loaded = type(scene).load(path)
    np.testing.assert_array_equal(loaded.receiver_sets, [0, 0, 1, 1])
    np.testing.assert_array_equal(loaded.emitter_links, scene.emitter_links)
    np.testing.assert_array_equal(loaded.lights.links, [2, ALL_LINKS])
    assert loaded.lights.links.dtype == np.uint64
    np.testing.assert_array_equal(loaded.blocker_sets, [2, 2, 0, 0])
    np.testing.assert_array_equal(loaded.emitter_shadow_links, scene.emitter_shadow_links)
    assert (loaded.lights.shadow_links == ALL_LINKS).all()
    # Files from before light linking: every emitter lights everything.
    unlinked = Lights(**{**scene.lights.__dict__, "links": None, "shadow_links": None})
    old = scene.replace(receiver_sets=None, emitter_links=None, blocker_sets=None, emitter_shadow_links=None,
                        lights=unlinked).validate()
    assert (old.lights.links == ALL_LINKS).all() and (old.lights.shadow_links == ALL_LINKS).all()
    with pytest.raises(SceneError, match="receiver_sets must lie in"):
        scene.replace(receiver_sets=np.uint8([0, 0, 64, 0])).validate()
    with pytest.raises(SceneError, match="receiver_sets has 3 rows"):
        scene.replace(receiver_sets=np.uint8([0, 0, 1])).validate()
    with pytest.raises(SceneError, match="blocker_sets must lie in"):
        scene.replace(blocker_sets=np.uint8([0, 0, 99, 0])).validate()

"""Light groups (Cycles' ``Combined_<group>`` passes, ``Scene.light_groups``): each group's pass is the
image lit by its emitters alone, and the groups' passes add up to the image."""
import dataclasses

import numpy as np
import pytest

from core import render
from core.context import RenderContext
from core.light_passes import LIGHTGROUP_PREFIX, light_groups, photon_groups
from core.scene import Lights, Scene, SceneError, World
from core.settings import RenderSettings
from core.testing import scenes
from core.testing.scenes import with_light_groups

# (a render with light group passes keeps the photons' direct light, core/direct.py: the renders it is
# compared with take it from photons too)
BASE = dict(passes=3, photons_per_pass=20000, workers=1, seed=3, direct_light="photons")


def groups_of(scene, **settings):
    names = tuple(LIGHTGROUP_PREFIX + g for g in scene.light_groups)
    return render(scene, RenderSettings(**{**BASE, **settings, "data_passes": names})), names


def lit_box(lamp_group=0, bulb_group=1, spot_group=1, world_group=2, spot_power=60.0):
    """The Cornell box lit by its ceiling's emissive quad, a point light the camera sees, a spot and
    a sky through its open front, each in the light group given (-1: none) of ("lamp", "bulb",
    "sky")."""
    s = scenes.cornell_box(resolution=(32, 32), light="mesh")
    lamp = s.materials.names.index("lamp")
    lights = Lights.build([{"kind": "point", "position": (0.5, -0.5, 1.5), "power": 40.0, "radius": 0.1,
                            "visibility": 7, "group": bulb_group},
                           {"kind": "spot", "position": (-0.5, -0.5, 1.8), "direction": (0.2, 0.3, -1),
                            "power": spot_power, "radius": 0.05, "group": spot_group}])
    return s.replace(lights=lights, light_groups=("lamp", "bulb", "sky"),
                     emitter_group=np.where(s.material_ids == lamp, lamp_group, -1).astype(np.int16),
                     world=World(color=np.float32([0.3, 0.4, 0.5]), group=world_group))


@pytest.mark.parametrize("name, settings", [
    ("lit_box", dict(method="ppm")),
    ("lit_box", dict(method="amcmcppm")),
    ("lit_box", dict(method="amcmcppm", workers=2, passes=6, bias_correction=True)),
    ("glowing_glass_ball", dict(method="amcmcppm")),
    ("corner_in_world_fog", dict(method="ppm")),
    ("hole_mirror_glass", dict(method="amcmcppm", normalisation="per_pass")),
])
def test_light_groups_add_up_to_the_image(name, settings):
    """Every emitter in a group (a lamp of emissive triangles, lights seen directly and through glass,
    glowing gas in glass, a spot and a point light in fog, the sky): the groups' passes add up to the
    image in every pixel to float rounding (with the chains, two workers and the bias correction,
    whose share each pass takes in proportion), each is finite, not negative and not empty, and the
    image is the same as without them."""
    scene = lit_box() if name == "lit_box" else with_light_groups(getattr(scenes, name)(resolution=(32, 24)))
    result, names = groups_of(scene, **settings)
    plain = render(scene, RenderSettings(**{**BASE, **settings}))
    assert np.array_equal(result.image, plain.image)
    if settings.get("bias_correction"):
        assert result.stats[-1]["bias_weight"] > 0
    parts = [result.data[n] for n in names]
    for n, part in zip(names, parts):
        assert part.shape == result.image.shape[:2] + (3,)
        assert np.isfinite(part).all() and (part >= 0).all(), n
    lit = [n for n, part in zip(names, parts) if part.mean() > 1e-4]
    expected = {"lit_box": 3, "glowing_glass_ball": 1, "corner_in_world_fog": 2, "hole_mirror_glass": 1}
    assert len(lit) == expected[name], lit
    assert np.allclose(sum(parts), result.image[..., :3], rtol=1e-5, atol=1e-6)


def block_means(image, n=4):
    h, w = image.shape[:2]
    return image[:h - h % n, :w - w % n, :3].reshape(n, h // n, n, w // n, 3).mean(axis=(1, 3))


@pytest.mark.parametrize("bias_correction, spot_power", [pytest.param(False, 60.0, marks=pytest.mark.slow),
                                                       (True, 60.0), (True, 2000.0)])
def test_each_group_is_its_emitters_alone(bias_correction, spot_power):
    """A group's pass is the render with only its emitters (the others taken out of the scene): the
    ceiling lamp's and the bulb's in means within 3 % and in the 4 x 4 blocks of at least a fifth of
    the brightest's within 12 % (the photon noise of two renders; dimmer blocks of the spot's light
    were up to 14 % apart; the negative control, the lamp's pass against the bulb's render, is off
    by a factor of 3); the light of the spot, in no group, is the image less the groups' passes.
    With the bias correction each group takes the image's weight times its own difference at half
    the radius (the lamp's pass 0.2 % from the lamp alone; when the groups took the image's
    correction in proportion to their share of each pixel, as the light passes do, 5 % above it).
    The photons of the group with most of them (the bulb's) are not copied (``photon_groups``), or,
    with a strong spot in no group, those of the spot's instead."""
    scene = lit_box(spot_group=-1, spot_power=spot_power).replace(world=World())
    lights = RenderContext(scene).lights
    blocks = light_groups(tuple(LIGHTGROUP_PREFIX + g for g in scene.light_groups), scene.light_groups)[1]
    assert photon_groups(lights.group, lights.prob, blocks)[0] == (1 if spot_power < 100 else -1)
    settings = dict(passes=6, photons_per_pass=40000, bias_correction=bias_correction)
    result, names = groups_of(scene, **settings)
    assert (result.stats[-1]["bias_weight"] > 0) == bias_correction
    lamp = scene.materials.names.index("lamp")
    dark = np.where(scene.material_ids == lamp, 0, scene.material_ids)      # (the lamp's quad white)
    alone = {"lamp": scene.replace(lights=Lights.empty(), world=World()),
             "bulb": scene.replace(lights=Lights.build([{"kind": "point", "position": (0.5, -0.5, 1.5),
                                                         "power": 40.0, "radius": 0.1, "visibility": 7}]),
                                   material_ids=dark, world=World()),
             "spot": scene.replace(lights=Lights.build([{"kind": "spot", "position": (-0.5, -0.5, 1.8),
                                                         "direction": (0.2, 0.3, -1), "power": spot_power,
                                                         "radius": 0.05}]),
                                   material_ids=dark, world=World())}
    images = {g: render(s, RenderSettings(**{**BASE, **settings})).image[..., :3] for g, s in alone.items()}
    passes = {g: result.data[LIGHTGROUP_PREFIX + g] for g in ("lamp", "bulb")}
    passes["spot"] = (result.image[..., :3] - passes["lamp"] - passes["bulb"]
                      - result.data[LIGHTGROUP_PREFIX + "sky"])
    assert result.data[LIGHTGROUP_PREFIX + "sky"].max() == 0.0
    for g, image in images.items():
        ours = passes[g]
        assert abs(ours.mean() / image.mean() - 1.0) < 0.03, (g, ours.mean(), image.mean())
        blocks, expected = block_means(ours), block_means(image)
        bright = expected > 0.2 * expected.max()
        assert np.abs(blocks[bright] / expected[bright] - 1.0).max() < 0.12, g
    assert abs(passes["lamp"].mean() / images["bulb"].mean() - 1.0) > 0.5


def test_world_group_on_a_transparent_film():
    """On a transparent film the sky is cut out of the image, but the world's group shows it (as
    Cycles writes the world to its light group on transparent background rays, like the
    Environment pass); the floor lit by it is in the group as in the image."""
    scene = scenes.sky_over_floor(resolution=(24, 24), pitch_deg=10.0)
    scene = scene.replace(world=dataclasses.replace(scene.world, film_transparent=True, group=0),
                          light_groups=("sky",))
    result, names = groups_of(scene)
    sky = result.image[..., 3] == 0.0
    assert sky.sum() > 100
    assert np.allclose(result.data[names[0]][sky], 1.0, atol=1e-6)
    floor = result.image[..., 3] == 1.0
    assert np.allclose(result.data[names[0]][floor], result.image[floor, :3], rtol=1e-5, atol=1e-7)


def test_light_groups_are_checked_and_saved(tmp_path):
    """A pass for a group the scene does not have is refused with a clear message; group indices out
    of range and repeated or empty names are scene errors; save and load keep the groups."""
    scene = lit_box()
    with pytest.raises(ValueError, match="light group the scene does not have.*lamp, bulb, sky"):
        render(scene, RenderSettings(**BASE, data_passes=(LIGHTGROUP_PREFIX + "key",)))
    with pytest.raises(ValueError, match="light groups"):
        RenderSettings(data_passes=("lightgroups:lamp",))
    n = scene.triangle_count
    for bad, message in ((dict(light_groups=("lamp", "lamp", "sky")), "light_groups"),
                         (dict(light_groups=("lamp", "", "sky")), "light_groups"),
                         (dict(emitter_group=np.full(n, 3, np.int16)), "emitter_group"),
                         (dict(world=World(group=5)), "world.group"),
                         (dict(lights=dataclasses.replace(scene.lights, group=np.int16([0, 7]))),
                          "lights.group")):
        with pytest.raises(SceneError, match=message):
            scene.replace(**bad).validate()
    path = tmp_path / "groups.npz"
    scene.save(path)
    loaded = Scene.load(path)
    assert loaded.light_groups == scene.light_groups
    assert np.array_equal(loaded.emitter_group, scene.emitter_group)
    assert np.array_equal(loaded.lights.group, scene.lights.group) and loaded.world.group == 2
    plain = tmp_path / "plain.npz"
    scenes.cornell_box(resolution=(8, 8)).save(plain)
    assert Scene.load(plain).light_groups == ()


def test_photon_groups_derives_the_one_with_most_photons():
    """The pass left to derive (no copies of its photons' pairs): that of the largest share of the
    photons, unless the emitters in no pass asked for (no group, or a group not asked for) have more
    together; none without passes.  The passes whose groups' emitters send photons are live (the
    others are left out of the photons' passes)."""
    blocks = np.array([0, -1, 1])                      # scene groups 0 and 2 asked for, 1 not

    def derived(groups, prob, b=blocks):
        return photon_groups(np.array(groups), np.array(prob, float), b)[0]

    assert derived([0, 2, 2], [0.2, 0.3, 0.5]) == 1
    assert derived([0, 0], [0.5, 0.5]) == 0
    assert derived([0, -1, 1], [0.4, 0.3, 0.3]) == -1
    assert derived([0, -1, 1], [0.6, 0.3, 0.1]) == 0
    assert derived([0], [1.0], np.array([-1, -1, -1])) == -1
    assert derived(np.zeros(0, np.int64), []) == -1
    assert photon_groups(np.array([0, 1]), np.array([0.5, 0.5]), blocks)[1].tolist() == [0]
    assert photon_groups(np.array([2, 2]), np.array([0.5, 0.5]), blocks)[1].tolist() == [1]


def test_a_scene_lit_by_one_group_copies_no_pair():
    """The Cornell box with its light in a group: the group's pass is the whole image (derived from
    what the points gathered, with no copies of the pairs: the blocks stay empty)."""
    scene = scenes.cornell_box(resolution=(24, 24))
    scene = scene.replace(lights=dataclasses.replace(scene.lights, group=np.int16([0])),
                          light_groups=("key",))
    result, names = groups_of(scene, method="amcmcppm")
    assert np.allclose(result.data[names[0]], result.image[..., :3], rtol=1e-6, atol=1e-7)
    assert result.image[..., :3].mean() > 0.05

"""Transparency (Principled's Alpha, a Transparent BSDF): ``Materials.opacity``, ``opacity_program``.

A sun straight down through a black leaf of opacity o and transparent colour c onto a white
floor: the floor gets E (1 - o) c, and a camera above sees it through the leaf, (1 - o) c times
that again.  An alpha map of 0 and 1 cuts holes: full light under them, none elsewhere."""
import numpy as np
import pytest

from core import render
from core.context import RenderContext
from core.scene import Camera, Lights, Materials, SceneError
from core.settings import RenderSettings
from core.testing.scenes import MeshBuilder, with_one_object

TINT = np.array([1.0, 0.5, 0.25])
METHODS = [dict(method="ppm"), dict(method="amcmcppm", chains=1024)]


def leaf_over_floor(leaf, irradiance=10.0, albedo=0.5, resolution=(16, 16)):
    """A 1 m floor (z = 0), a 1 m leaf of material ``leaf`` (a spec) at z = 0.25 and a sun straight
    down; an orthographic camera at z = 0.5 sees 0.4 m of both."""
    m = MeshBuilder()
    m.add_quad((-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0), 0)
    m.add_quad((-0.5, -0.5, 0.25), (0.5, -0.5, 0.25), (0.5, 0.5, 0.25), (-0.5, 0.5, 0.25), 1)
    lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": irradiance}])
    cam_to_world = np.eye(4)
    cam_to_world[2, 3] = 0.5
    cam = Camera(world_from_camera=cam_to_world, projection="orthographic", frame=(-0.2, 0.2, -0.2, 0.2),
                 resolution=resolution)
    mats = Materials.build([{"name": "floor", "diffuse": albedo}, {"name": "leaf", **leaf}])
    scene = m.build(Materials.build([{"name": "floor"}, {"name": "leaf"}]), lights, cam)
    return with_one_object(scene).replace(materials=mats).validate()


def settings(**kw):
    return RenderSettings(**{"workers": 1, "passes": 6, "photons_per_pass": 60_000, "seed": 1,
                             "initial_radius_px": 1.5, "max_bounces": 3, **kw})


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
@pytest.mark.parametrize("leaf_albedo", [0.0, 0.8])
def test_a_half_transparent_leaf_lets_through_its_share(method, leaf_albedo):
    """One bounce (``max_bounces=1``): the floor gets E (1 - o) c, the leaf's top E; the camera
    sees the leaf as often as it is opaque, a_l E / pi, and otherwise the floor through it."""
    opacity, irradiance, albedo = 0.3, 10.0, 0.5
    scene = leaf_over_floor({"diffuse": leaf_albedo, "opacity": opacity, "transparent_color": TINT.tolist()})
    image = render(scene, settings(max_bounces=1, **method)).image[..., :3]
    assert np.isfinite(image).all()
    expected = irradiance / np.pi * (opacity * leaf_albedo + albedo * ((1 - opacity) * TINT) ** 2)
    np.testing.assert_allclose(image.reshape(-1, 3).mean(axis=0), expected, rtol=0.03)


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_an_alpha_map_cuts_holes(method):
    """Opacity 1 where x > 0, 0 elsewhere: the floor is lit (and seen) only where x < 0."""
    x = {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}
    alpha = {"op": "math", "operation": "GREATER_THAN", "a": x, "b": 0.0}
    scene = leaf_over_floor({"diffuse": 0.8, "opacity_program": alpha})
    image = render(scene, settings(**method)).image[..., :3]
    n = image.shape[1]
    hole, leaf = image[:, 2:n // 2 - 2], image[:, n // 2 + 2:-2]
    np.testing.assert_allclose(hole.mean(), 0.5 * 10.0 / np.pi, rtol=0.03)
    # The leaf's top, white-ish diffuse under the sun: 0.8 E / pi.
    np.testing.assert_allclose(leaf.mean(), 0.8 * 10.0 / np.pi, rtol=0.03)


def test_crossings_are_decided_by_the_opacity_and_limited():
    scene = leaf_over_floor({"diffuse": 0.5, "opacity": 0.25})
    ctx = RenderContext(scene)
    n = 20_000
    spread = np.random.default_rng(0).uniform(-0.3, 0.3, (n, 3)) * [1, 1, 0]
    origins = np.tile([0.0, 0.0, 1.0], (n, 1)) + spread
    dirs = np.tile([0.0, 0.0, -1.0], (n, 1))
    rng = np.random.default_rng(1)
    hits, tint, opacity, _ = ctx.trace(origins, dirs, None, lambda rows, crossing: rng.random(len(rows)))
    on_floor = ctx.material_ids[hits.prim_ids] == 0
    assert on_floor.mean() == pytest.approx(0.75, abs=0.015)
    np.testing.assert_allclose(hits.t[on_floor], 1.0, rtol=1e-5)          # from the original origins
    np.testing.assert_allclose(hits.t[~on_floor], 0.75, rtol=1e-5)
    np.testing.assert_allclose(tint, 1.0)
    np.testing.assert_allclose(opacity[~on_floor], 0.25)                    # stopped on the leaf
    np.testing.assert_allclose(opacity[on_floor], 1.0)
    # Always transparent: every ray reaches the floor; never: none does.
    for opacity, expected in ((0.0, 1.0), (1.0, 0.0)):
        ctx = RenderContext(leaf_over_floor({"diffuse": 0.5, "opacity": opacity}))
        hits, _, _, _ = ctx.trace(origins, dirs, None, lambda rows, crossing: rng.random(len(rows)))
        assert (ctx.material_ids[hits.prim_ids] == 0).mean() == expected


def test_opacity_above_one_is_refused():
    with pytest.raises(SceneError, match=r"opacity is outside \[0.0, 1.0\] for material 'leaf'"):
        leaf_over_floor({"diffuse": 0.5, "opacity": 1.5})


@pytest.mark.parametrize("opacity", [0.25, "program"])
def test_a_transparent_emitter_emits_its_opaque_share(opacity):
    """Cycles' Alpha scales emission: a floor emitting 3 at opacity 0.25 (or an opacity program
    of 0.25) sends photons of a quarter of its power, and the camera sees 3 a quarter of the time."""
    spec = {"diffuse": 0.0, "emission": 3.0}
    if opacity == "program":
        spec["opacity_program"] = {"op": "math", "operation": "ADD", "a": 0.25,
                                   "b": {"op": "math", "operation": "MULTIPLY", "a": 0.0, "b": {
                                       "op": "separate", "vector": {"op": "attribute", "name": "object"},
                                       "output": "X"}}}
    else:
        spec["opacity"] = opacity
    m = MeshBuilder()
    m.add_quad((-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0), 0)
    cam_to_world = np.eye(4)
    cam_to_world[2, 3] = 0.5
    cam = Camera(world_from_camera=cam_to_world, projection="orthographic", frame=(-0.2, 0.2, -0.2, 0.2),
                 resolution=(8, 8))
    scene = with_one_object(m.build(Materials.build([{"name": "floor"}]), camera=cam))
    scene = scene.replace(materials=Materials.build([{"name": "floor", **spec}])).validate()
    lights = RenderContext(scene).lights
    _, _, flux, _ = lights.sample(np.random.default_rng(0).random((20_000, 6)))
    np.testing.assert_allclose(flux.mean(axis=0), 2 * np.pi * 3.0 * 0.25, rtol=1e-9)
    image = render(scene, settings(passes=40, photons_per_pass=100)).image[..., :3]
    assert image.mean() == pytest.approx(0.25 * 3.0, rel=0.05)

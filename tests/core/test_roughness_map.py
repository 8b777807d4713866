"""Roughness maps: a float program for the glossy roughness (``Materials.roughness_program``).

The core copies such a material at ``bsdf.ROUGHNESS_LEVELS`` roughness levels and each hit takes
the copy of the program's value (``RenderContext.surface``), so a map that takes two values renders
exactly as two materials of those roughnesses."""
import numpy as np
import pytest

from core import render
from core.bsdf import GLOSSY, MIRROR, ROUGHNESS_LEVELS
from core.context import RenderContext
from core.scene import Materials, SceneError
from core.settings import RenderSettings
from core.testing.scenes import sun_over_procedural_floor, sun_through_slab, with_one_object

OBJECT = {"op": "attribute", "name": "object"}


def axis(name):
    return {"op": "separate", "vector": OBJECT, "output": name}


def glossy_floor(specs, resolution=(16, 16)):
    """The 1 m floor of ``sun_over_procedural_floor`` (two triangles split along y = x: the first
    where x > y) with materials ``specs``, one per triangle if two, under the sun straight above."""
    scene = sun_over_procedural_floor({"op": "splat", "value": 0.5}, resolution=resolution)
    ids = np.arange(2, dtype=np.int32) if len(specs) == 2 else np.zeros(2, np.int32)
    return scene.replace(materials=Materials.build(specs), material_ids=ids).validate()


def test_each_hit_takes_the_copy_of_its_roughness():
    ramp = {"op": "math", "operation": "ADD", "a": axis("X"), "b": 0.5}        # 0 to 1 across the floor
    scene = glossy_floor([{"name": "floor", "glossy": 0.8, "diffuse": 0.2, "roughness_program": ramp}])
    ctx = RenderContext(scene)
    x = np.linspace(-0.49, 0.49, 50)
    prim = np.where(x > 0.0, 0, 1)                      # y = 0: triangle 0 where x > 0
    tri = scene.vertices[scene.triangles].astype(np.float64)
    pos = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    # Barycentrics of pos in each triangle (b1, b2 of corners 1 and 2).
    a, b, c = (tri[prim, k] for k in range(3))
    m = np.stack([b - a, c - a], axis=2)[:, :2]
    b12 = np.linalg.solve(m, (pos - a)[:, :2, None])[..., 0]
    surf = ctx.surface(prim, b12[:, 0], b12[:, 1])
    roughness = np.sqrt(ctx.table.alpha.take(surf.mat_ids))
    expected = np.rint((x + 0.5) * (ROUGHNESS_LEVELS - 1)) / (ROUGHNESS_LEVELS - 1)
    glossy = expected >= 0.02
    np.testing.assert_allclose(roughness[glossy], expected[glossy], atol=1e-6)
    # Below Blender's 0.02 the copy is a mirror, as a material of that roughness.
    assert (ctx.table.weight[surf.mat_ids[~glossy], MIRROR] > 0).all() and (~glossy).any()
    assert (ctx.table.weight[surf.mat_ids[glossy], GLOSSY] > 0).all()
    # The diffuse part and the names follow the material.
    np.testing.assert_allclose(surf.colors[:, 0], 0.2)
    assert ctx.materials.names[surf.mat_ids[-1]].startswith("floor (roughness")


@pytest.mark.parametrize("method", [dict(method="ppm"), dict(method="amcmcppm", chains=1024)],
                         ids=lambda m: m["method"])
def test_a_two_valued_map_renders_as_two_materials(method):
    """Roughness 0.25 where x > y, 0.625 elsewhere (both are levels), against one material per
    triangle: the same image, pixel for pixel (same seed, same hits; the copies' multiscatter
    tables use the coarser quadrature, 1e-4 of the image here)."""
    base = {"glossy": 0.8, "diffuse": 0.1}
    split = {"op": "math", "operation": "GREATER_THAN", "a": axis("X"), "b": axis("Y")}
    program = {"op": "map_range", "value": split, "from_min": 0.0, "from_max": 1.0, "to_min": 0.625,
               "to_max": 0.25}
    mapped = glossy_floor([{"name": "floor", "roughness_program": program, **base}])
    two = glossy_floor([{"name": "smooth", "roughness": 0.25, **base}, {"name": "rough", "roughness": 0.625,
                                                                        **base}])
    settings = RenderSettings(workers=1, passes=3, photons_per_pass=5000, seed=2, **method)
    a, b = render(mapped, settings).image, render(two, settings).image
    assert np.isfinite(a).all() and a[..., :3].std() > 0.05 * a[..., :3].mean()
    np.testing.assert_allclose(a, b, rtol=1e-3, atol=1e-6)


def test_a_glass_roughness_map_picks_the_glass_copy_of_its_roughness():
    """``dielectric_roughness`` -1: the glass takes the roughness map's level at each hit, beside a
    glossy lobe that takes it too (Principled's one Roughness) or alone (a Glass BSDF); a program
    on a material without such lobes is dropped (no hit picks copies it has not got); -1 without
    a program is refused."""
    ramp = {"op": "math", "operation": "ADD", "a": axis("X"), "b": 0.5}
    for spec in ({"glossy": 0.04, "dielectric": 0.9}, {"dielectric": 1.0}):
        scene = glossy_floor([{"name": "pane", "dielectric_roughness": -1, "ior": 1.5,
                               "roughness_program": ramp, **spec},
                              {"name": "matte", "diffuse": 0.5, "roughness_program": ramp}])
        ctx = RenderContext(scene)
        assert ctx.materials.roughness_program[1] == -1
        prim = np.repeat([0, 1], 20)
        b1 = np.tile(np.linspace(0.05, 0.45, 20), 2)
        surf = ctx.surface(prim, b1, np.full(40, 0.3))
        pos = ctx.accel.hit_positions(prim, b1, np.full(40, 0.3))
        level = np.rint(np.clip(pos[:20, 0] + 0.5, 0, 1) * (ROUGHNESS_LEVELS - 1)) / (ROUGHNESS_LEVELS - 1)
        alpha = np.where(level < 0.02, 0.0, level ** 2)
        np.testing.assert_allclose(ctx.table.dielectric_alpha.take(surf.mat_ids[:20]), alpha, atol=1e-6)
        assert (surf.mat_ids[20:] == 1).all()
        if "glossy" in spec:
            glossy = level >= 0.02
            roughness = np.sqrt(ctx.table.alpha.take(surf.mat_ids[:20]))
            np.testing.assert_allclose(roughness[glossy], level[glossy], atol=1e-6)
    with pytest.raises(SceneError, match="dielectric_roughness"):
        glossy_floor([{"name": "pane", "dielectric": 1.0, "dielectric_roughness": -1}])


@pytest.mark.parametrize("method", [dict(method="ppm"), dict(method="amcmcppm", chains=1024)],
                         ids=lambda m: m["method"])
def test_a_glass_roughness_map_renders_as_the_glass_of_its_roughness(method):
    """The sun through a glass slab onto a floor (``sun_through_slab``): a map of 0.625 everywhere
    (a program that reads the coordinates) renders as the glass of roughness 0.625, pixel for pixel
    (same seed, same hits), and the glass of 0.25 lets through about twice as much onto the
    floor seen (single-scattering GGX and the spread of the rougher one)."""
    x = {"op": "separate", "vector": OBJECT, "output": "X"}
    program = {"op": "map_range", "value": x, "from_min": 0.0, "from_max": 1.0, "to_min": 0.625,
               "to_max": 0.625}
    settings = RenderSettings(workers=1, passes=3, photons_per_pass=20000, seed=2, max_bounces=4, **method)

    def image(glass):
        scene = with_one_object(sun_through_slab()).replace(materials=Materials.build(
            [{"name": "floor", "diffuse": 0.5}, {"name": "glass", "dielectric": 1.0, "ior": 1.5, **glass}]))
        return render(scene.validate(), settings).image
    mapped = image({"dielectric_roughness": -1, "roughness_program": program})
    rough, smoother = image({"dielectric_roughness": 0.625}), image({"dielectric_roughness": 0.25})
    assert np.isfinite(mapped).all()
    np.testing.assert_allclose(mapped, rough, rtol=1e-5, atol=1e-7)
    assert smoother[..., :3].mean() > 1.5 * rough[..., :3].mean()

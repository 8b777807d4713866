"""True displacement (``core.displacement.displace``, Materials.displacement_program): vertices
move along their normals before a render, as Cycles' ``GeometryManager::displace`` moves them."""
from __future__ import annotations

import numpy as np
import pytest

from core.context import RenderContext
from core.displacement import displace
from core.scene import DISPLACE_KEEPS_NORMALS, DISPLACE_VECTOR, DISPLACE_WORLD, Materials, Scene

X = {"op": "separate", "vector": {"op": "attribute", "name": "position"}, "output": "X"}
GENERATED_Z = {"op": "separate", "vector": {"op": "attribute", "name": "generated"}, "output": "Z"}


def grid(spec, n=8, scale=1.0):
    """An n x n grid of quads over [-1, 1]^2 at z = 0 with shared vertices and smooth normals (0, 0, 1),
    of one material ``spec``; its object scaled by ``scale`` along z (object_from_world)."""
    u = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(u, u, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1).astype(np.float32)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i, i + n + 1, i + n + 2, i + 1
    triangles = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]).reshape(-1, 3)
    t = len(triangles)
    return Scene(vertices=vertices, triangles=triangles.astype(np.int32), material_ids=np.zeros(t, np.int32),
                 materials=Materials.build([{"name": "ground", "diffuse": 0.5, **spec}]),
                 shading_normals=np.tile(np.float32([0, 0, 1]), (t, 3, 1)),
                 object_ids=np.zeros(t, np.int32),
                 object_from_world=np.array([np.diag([1.0, 1.0, 1.0 / scale, 0.0])[:3]]),
                 texture_spaces=np.array([[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]])).validate()


def test_a_constant_offset_lifts_every_vertex_along_its_normal():
    """0.1 along (0, 0, 1): in world units, or in the object's space scaled 2 along z, where the
    offset is scaled back (Cycles: the normal into the object's space, normalised, the offset back
    out: 0.2).  Without a displacement program the scene is returned as it is."""
    for flags, scale, lift in ((DISPLACE_WORLD, 2.0, 0.1), (0, 2.0, 0.2), (0, 1.0, 0.1)):
        lift_program = {"op": "math", "operation": "ADD", "a": 0.1, "b": 0.0}
        scene = grid({"displacement_program": lift_program, "displacement_flags": flags}, scale=scale)
        out = displace(scene)
        np.testing.assert_allclose(out.vertices[:, 2], lift, rtol=1e-6)
        np.testing.assert_array_equal(out.vertices[:, :2], scene.vertices[:, :2])
        np.testing.assert_array_equal(out.undisplaced, scene.vertices)
        np.testing.assert_allclose(out.shading_normals, scene.shading_normals, atol=1e-6)
    plain = grid({})
    assert displace(plain) is plain


@pytest.mark.parametrize("keeps", [False, True], ids=["displacement_only", "displacement_and_bump"])
def test_a_ramp_tilts_the_surface_and_its_normals(keeps):
    """An offset of 0.5 x makes the plane z = 0.5 x: its normals (-0.5, 0, 1) / |.| everywhere
    (Displacement Only: each corner's normal plus its vertex normal's change), or (0, 0, 1) kept
    (Displacement and Bump).  Generated coordinates still read the undisplaced surface."""
    flags = DISPLACE_WORLD | (DISPLACE_KEEPS_NORMALS if keeps else 0)
    scene = grid({"displacement_program": {"op": "math", "operation": "MULTIPLY", "a": X, "b": 0.5},
                  "displacement_flags": flags, "diffuse_program": GENERATED_Z})
    out = displace(scene)
    np.testing.assert_allclose(out.vertices[:, 2], 0.5 * scene.vertices[:, 0], atol=1e-6)
    want = np.array([0.0, 0.0, 1.0]) if keeps else np.array([-0.5, 0.0, 1.0]) / np.sqrt(1.25)
    np.testing.assert_allclose(out.shading_normals.reshape(-1, 3),
                               np.broadcast_to(want, (out.triangle_count * 3, 3)), atol=1e-6)
    ctx = RenderContext(scene)
    assert ctx.scene.undisplaced is not None
    prims = np.arange(scene.triangle_count)
    third = np.full(len(prims), 1.0 / 3.0)
    surf = ctx.surface(prims, third, third)
    # Generated z of the undisplaced surface (z = 0 in the texture space [-1, 1]: 1/2), where the
    # displaced one would read (0.5 x + 1) / 2.
    np.testing.assert_allclose(surf.colors[:, 0, 0] / 0.5, 0.5, atol=1e-6)


def test_a_runaway_height_is_clamped_and_the_render_stays_finite():
    """An offset of 3e38 (float32's edge) on the Cornell box's red wall: clamped to OFFSET_LIMIT
    scene sizes, so the rest of the box keeps its scale and light (finite, lit, both methods)."""
    from core import RenderSettings, render
    from core.displacement import OFFSET_LIMIT
    from core.testing.scenes import cornell_box
    plain = cornell_box(resolution=(16, 16))
    mats = plain.materials
    specs = [{"name": n, "diffuse": mats.diffuse_color[i], "emission": mats.emission[i]}
             for i, n in enumerate(mats.names)]
    specs[1].update(displacement_flags=DISPLACE_WORLD,
                    displacement_program={"op": "math", "operation": "ADD", "a": 3e38, "b": 0.0})
    scene = plain.replace(materials=Materials.build(specs)).validate()
    moved = displace(scene)
    lo, hi = scene.bounds()
    assert np.isfinite(moved.vertices).all()
    assert np.abs(moved.vertices).max() <= (OFFSET_LIMIT + 1.0) * np.max(hi - lo)
    for method in ("ppm", "amcmcppm"):
        image = render(scene, RenderSettings(passes=2, photons_per_pass=2000, workers=1, method=method)).image
        assert np.isfinite(image).all() and image[..., :3].mean() > 0.05


def test_the_new_material_fields_survive_a_file_round_trip_and_bad_values_are_refused(tmp_path):
    """Stop 42's fields (displacement, a displacement's bump, Refraction's Fresnel share, a coat's
    own normal, Bump Map Correction) keep their values through ``Scene.save`` / ``load``; flags outside their bits and
    a share outside [0, 1] are refused by name."""
    from core.scene import SceneError
    tilt = {"op": "combine", "x": 0.0, "y": -0.3, "z": 1.0}
    spec = {"displacement_program": {"op": "math", "operation": "MULTIPLY", "a": X, "b": 0.1},
            "displacement_flags": DISPLACE_WORLD | DISPLACE_KEEPS_NORMALS, "displacement_bump": 1,
            "bump_program": X, "dielectric": 0.5, "dielectric_fresnel": 0.25, "coat": 1.0,
            "coat_normal_program": tilt, "coat_bump_program": X, "coat_bump_distance": -0.2,
            "coat_bump_strength": 0.5, "bump_correction": 0}
    scene = grid(spec)
    scene.save(tmp_path / "s.npz")
    back = Scene.load(tmp_path / "s.npz").materials
    m = scene.materials
    for name in ("displacement_program", "displacement_flags", "displacement_bump", "dielectric_fresnel",
                 "coat_normal_program", "coat_bump_program", "coat_bump_distance", "coat_bump_strength",
                 "bump_correction"):
        np.testing.assert_array_equal(getattr(back, name), getattr(m, name), err_msg=name)
    assert back.programs[back.coat_normal_program[0]] == tilt
    for bad, message in (({"displacement_flags": 8}, "displacement_flags"),
                         ({"dielectric_fresnel": 1.5}, "dielectric_fresnel"),
                         ({"bump_correction": 2}, "bump_correction")):
        with pytest.raises(SceneError, match=message):
            grid(bad)


def test_a_vector_offset_moves_every_vertex_by_itself():
    """DISPLACE_VECTOR (a Vector Displacement): the program's world vector (0.1, -0.05, 0.2) is
    each vertex's offset, whatever its normal or its object's scale."""
    shift = {"op": "combine", "x": 0.1, "y": -0.05, "z": 0.2}
    scene = grid({"displacement_program": shift, "displacement_flags": DISPLACE_WORLD | DISPLACE_VECTOR},
                 scale=2.0)
    out = displace(scene)
    moved = out.vertices - scene.vertices
    np.testing.assert_allclose(moved, np.broadcast_to([0.1, -0.05, 0.2], moved.shape), atol=1e-6)


def test_a_bump_on_a_small_object_keeps_its_detail_beside_a_huge_one():
    """A bump of ripples 1 cm apart on a 2 m grid bends its normals alike with a black ground plane
    2 km wide in the scene or not: the differences step by a share of the object's own size (once of
    the scene's, 2 cm there, which took the ripples' slopes for noise)."""
    ripples = {"op": "math", "operation": "MULTIPLY", "a": X, "b": 600.0}
    height = {"op": "math", "operation": "MULTIPLY", "b": 1e-3,
              "a": {"op": "math", "operation": "SINE", "a": ripples}}
    alone = grid({"bump_program": height})
    t = alone.triangle_count
    ground = np.float32([[-1e3, -1e3, -1.0], [1e3, -1e3, -1.0], [1e3, 1e3, -1.0], [-1e3, 1e3, -1.0]])
    beside = alone.replace(
        vertices=np.concatenate([alone.vertices, ground]),
        triangles=np.concatenate([alone.triangles, len(alone.vertices) + np.int32([[0, 1, 2], [0, 2, 3]])]),
        material_ids=np.zeros(t + 2, np.int32),
        shading_normals=np.concatenate([alone.shading_normals, np.tile(np.float32([0, 0, 1]), (2, 3, 1))]),
        object_ids=np.concatenate([alone.object_ids, np.int32([1, 1])]),
        object_from_world=np.repeat(alone.object_from_world, 2, axis=0),
        texture_spaces=np.repeat(alone.texture_spaces, 2, axis=0), object_info=None).validate()
    rng = np.random.default_rng(5)
    prims = rng.integers(0, t, 2000)
    b1 = rng.uniform(0.0, 0.5, 2000)
    b2 = rng.uniform(0.0, 0.5, 2000)
    normals = [RenderContext(scene).surface(prims, b1, b2).ns for scene in (alone, beside)]
    # (the ripples tilt the normals by up to atan(0.6) along x)
    assert np.abs(normals[0][:, 0]).max() > 0.3
    np.testing.assert_allclose(normals[1], normals[0], atol=1e-6)

"""Procedural colour programs (``core/procedural.py``): ops against hand values, validation,
files.  Their agreement with Cycles is ``tests/addon/test_procedural_parity.py``'s."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core import procedural
from core.sampling import fresnel_dielectric
from core.scene import Camera, Materials, Scene, SceneError
from core.testing.scenes import sun_over_procedural_floor


class Points:
    """Attributes at given points (every coordinate name gives the same positions)."""

    def __init__(self, p):
        self.p = np.asarray(p, np.float64)

    @property
    def count(self):
        return len(self.p)

    def get(self, name):
        return self.p


def run(program, points, output=None):
    return procedural.evaluate(program, Points(points), [], output)


OBJECT = {"op": "attribute", "name": "object"}


def test_checker_alternates_by_the_parity_of_the_cells():
    program = {"op": "checker", "vector": OBJECT, "color1": [1, 0, 0], "color2": [0, 0, 1], "scale": 2.0}
    pts = [(0.1, 0.1, 0.1), (0.6, 0.1, 0.1), (0.6, 0.6, 0.1), (-0.1, 0.1, 0.1), (0.1, 0.1, 0.6)]
    fac = run(program, pts, "Fac")
    # Cells (0,0,0) (1,0,0) (1,1,0) (-1 -> |1|,0,0) (0,0,1): colour 1 where (x%2 == y%2) == z%2.
    np.testing.assert_array_equal(fac, [0, 1, 0, 1, 1])
    np.testing.assert_array_equal(run(program, pts)[:, 0], fac)


def test_a_checker_of_cells_beyond_int32_is_one_colour_without_warnings():
    """A Scale of 1e30: every cell beyond int32 is INT_MIN (even), as Cycles' float_to_int makes
    it, so every point has the origin's colour (Fac 0: x and y alike, z even); before stop 76
    NumPy warned "invalid value encountered in cast" (an error here)."""
    program = {"op": "checker", "vector": OBJECT, "color1": [1, 0, 0], "color2": [0, 0, 1], "scale": 1e30}
    fac = run(program, [(0.1, 0.1, 0.1), (-0.6, 0.3, 0.1), (0.0, 0.0, 0.0)], "Fac")
    np.testing.assert_array_equal(fac, [0, 0, 0])


def test_ramp_interpolates_its_table_and_holds_it_when_constant():
    table = [[0, 0, 0, 1], [1, 0.5, 0, 1], [1, 1, 1, 0]]
    fac = {"op": "separate", "vector": OBJECT, "output": "X"}
    ramp = {"op": "ramp", "fac": fac, "table": table}
    pts = [(0.0, 0, 0), (0.25, 0, 0), (0.75, 0, 0), (2.0, 0, 0), (-1.0, 0, 0)]
    np.testing.assert_allclose(run(ramp, pts),
                               [[0, 0, 0], [0.5, 0.25, 0], [1, 0.75, 0.5], [1, 1, 1], [0, 0, 0]])
    np.testing.assert_allclose(run({**ramp, "interpolate": False}, pts)[:, 1], [0, 0, 0.5, 1, 0])
    np.testing.assert_allclose(run(ramp, pts, "Alpha"), [1, 1, 0.5, 0, 1])


@pytest.mark.parametrize("blend, expected", [
    ("MIX", 0.25 * 0.4 + 0.75 * 0.8), ("ADD", 0.4 + 0.75 * 0.8), ("MULTIPLY", 0.4 * (0.25 + 0.75 * 0.8)),
    ("SUBTRACT", 0.4 - 0.75 * 0.8), ("SCREEN", 1 - (0.25 + 0.75 * 0.2) * 0.6),
    ("DIVIDE", 0.25 * 0.4 + 0.75 * 0.5), ("LINEAR_LIGHT", 0.4 + 0.75 * 0.6),
    ("OVERLAY", 0.4 * (0.25 + 1.5 * 0.8)), ("DARKEN", 0.4), ("LIGHTEN", 0.25 * 0.4 + 0.75 * 0.8),
])
def test_blend_modes(blend, expected):
    program = {"op": "mix_color", "blend": blend, "fac": 0.75, "a": [0.4] * 3, "b": [0.8] * 3}
    np.testing.assert_allclose(run(program, [(0, 0, 0)]), [[expected] * 3])


def test_math_is_safe_where_cycles_is():
    a = {"op": "separate", "vector": OBJECT, "output": "X"}
    pts = [(-2.0, 0, 0), (0.0, 0, 0), (3.0, 0, 0)]
    divide = {"op": "math", "operation": "DIVIDE", "a": 1.0, "b": a}
    np.testing.assert_allclose(run(divide, pts), [-0.5, 0, 1 / 3])
    np.testing.assert_allclose(run({"op": "math", "operation": "POWER", "a": a, "b": 0.5}, pts),
                               [0, 0, np.sqrt(3)])          # negative base, fractional exponent: 0
    np.testing.assert_allclose(run({"op": "math", "operation": "POWER", "a": a, "b": 2.0}, pts), [4, 0, 9])
    np.testing.assert_allclose(run({"op": "math", "operation": "SUBTRACT", "a": a, "b": 1.0, "clamp": True},
                                   pts), [0, 0, 1])
    stepped = {"op": "map_range", "interpolation": "STEPPED", "value": a, "from_min": -2.0, "from_max": 3.0,
               "steps": 2.0}
    np.testing.assert_allclose(run(stepped, pts), [0, 0.5, 1])


def test_vector_math_clamp_and_curves_where_cycles_is_safe():
    """Division and normalisation by zero give 0, a refraction past the critical angle 0; a Clamp
    of RANGE swaps its bounds; curves hold or extrapolate past their range."""
    pts = [(0.0, 0, 0), (3.0, 4.0, 0)]
    def vm(operation, **kw):
        return {"op": "vector_math", "operation": operation, "a": OBJECT, **kw}
    np.testing.assert_allclose(run(vm("NORMALIZE"), pts), [[0, 0, 0], [0.6, 0.8, 0]])
    np.testing.assert_allclose(run(vm("DIVIDE", b=[0.0, 2.0, 0.0]), pts), [[0, 0, 0], [0, 2, 0]])
    np.testing.assert_allclose(run({**vm("LENGTH"), "output": "Value"}, pts), [0, 5])
    grazing = {"op": "vector_math", "operation": "REFRACT", "a": [0.8, 0.0, -0.6], "b": [0, 0, 1],
               "scale": 1.5}
    np.testing.assert_allclose(run(grazing, pts), 0.0)                      # total internal reflection
    x = {"op": "separate", "vector": OBJECT, "output": "X"}
    swapped = {"op": "clamp", "clamp_type": "RANGE", "value": x, "min": 2, "max": 1}
    np.testing.assert_allclose(run(swapped, pts), [1, 2])
    np.testing.assert_allclose(run({"op": "clamp", "value": x, "min": 2, "max": 1}, pts), [1, 1])
    ramp = {"op": "float_curve", "value": x, "table": [0.0, 0.5, 1.0], "min_x": 0.0, "max_x": 2.0}
    np.testing.assert_allclose(run({**ramp, "extrapolate": True}, pts), [0, 1.5])
    np.testing.assert_allclose(run({**ramp, "extrapolate": False}, pts), [0, 1.0])
    np.testing.assert_allclose(run({**ramp, "fac": 0.5, "extrapolate": False}, pts), [0, 2.0])


def test_conversions_follow_cycles():
    color = {"op": "attribute", "name": "object"}
    pts = [(1.0, 0.0, 0.0), (0.2, 0.4, 0.6)]
    np.testing.assert_allclose(run({"op": "gray", "color": color}, pts), [0.2126, 0.2126 * 0.2 + 0.7152 * 0.4
                                                                            + 0.0722 * 0.6])
    np.testing.assert_allclose(run({"op": "average", "vector": color}, pts), [1 / 3, 0.4])
    assert run({"op": "splat", "value": 0.3}, pts).shape == (2, 3)


def test_mapping_matrix_and_normalize():
    m = [[0, -2, 0], [2, 0, 0], [0, 0, 2]]
    program = {"op": "affine", "vector": OBJECT, "matrix": m, "pre": [1, 0, 0], "post": [0, 0, 5]}
    np.testing.assert_allclose(run(program, [(2.0, 1.0, 1.0)]), [[-2, 2, 7]])
    np.testing.assert_allclose(run({**program, "normalize": True}, [(2.0, 1.0, 1.0)]),
                               [np.array([-2, 2, 7]) / np.sqrt(57)])


def test_colours_are_finite_and_non_negative():
    program = {"op": "math", "operation": "DIVIDE", "a": {"op": "separate", "vector": OBJECT, "output": "X"},
               "b": 0.0}
    sub = {"op": "mix_color", "blend": "SUBTRACT", "fac": 1.0, "a": [0.1] * 3, "b": [0.5] * 3}
    for p in (program, sub):
        c = procedural.evaluate_color(p, Points([(1.0, 0, 0), (-1.0, 0, 0)]), [])
        assert np.isfinite(c).all() and (c >= 0).all()


@pytest.mark.parametrize("program, message", [
    ({"op": "particle_info"}, "unknown program op"),
    ({"op": "checker", "vector": {"op": "attribute", "name": "reflection"}},
     "name .reflection. is not one of"),
    ({"op": "checker", "output": "Alpha"}, "has no output"),
    ({"op": "image", "texture": 3, "vector": OBJECT}, "not an index below"),
    ({"op": "ramp", "fac": 0.5, "table": [[0, 0, 0]]}, "table must be a finite array of shape"),
    ({"op": "affine", "vector": OBJECT, "matrix": [[1, 0], [0, 1]]}, "matrix must be a finite array"),
    ({"op": "image", "texture": "0", "vector": OBJECT}, "not an index below"),
    ({"op": "affine", "vector": OBJECT}, "lacks its input 'matrix'"),
    ({"op": "mix_color", "blend": "GLOW", "a": [0, 0, 0], "b": [1, 1, 1]}, "blend 'GLOW' is not one of"),
    ({"op": "math", "operation": "ADD", "a": "two"}, "input a must be a finite number"),
    ({"op": "checker", "vector": OBJECT, "scale": float("nan")}, "input scale must be a finite number"),
    ({"op": "noise", "vector": OBJECT, "noise_type": "PERLIN"}, "noise_type 'PERLIN'"),
    ({"op": "vector_math", "operation": "SLERP", "a": OBJECT}, "operation 'SLERP' is not one of"),
    ({"op": "curves", "color": OBJECT, "table": [[0, 0], [1, 1]]}, "table must be a finite array of shape"),
    ({"op": "float_curve", "value": 0.5}, "lacks its input 'table'"),
    ({"op": "bump", "distance": 0.1}, "lacks its input 'height'"),
])
def test_scene_validation_names_a_bad_program(program, message):
    checker = {"op": "checker", "vector": OBJECT, "color1": [1, 1, 1], "color2": [0, 0, 0]}
    scene = sun_over_procedural_floor(checker)
    scene.materials.programs = [program]
    with pytest.raises(SceneError, match=message):
        scene.validate()


def test_scene_validation_asks_for_the_coordinates_a_program_reads():
    scene = sun_over_procedural_floor({"op": "gradient", "vector": {"op": "attribute", "name": "generated"}})
    with pytest.raises(SceneError, match="reads 'generated' coordinates"):
        scene.replace(object_ids=None).validate()
    with pytest.raises(SceneError, match="object_ids outside"):
        scene.replace(object_ids=scene.object_ids + 1).validate()
    with pytest.raises(SceneError, match="texture_spaces is missing"):
        scene.replace(texture_spaces=None).validate()


def test_object_and_generated_coordinates_follow_the_object():
    """A hit's Object coordinates undo its object's transform; Generated maps the texture space."""
    from core.context import RenderContext
    program = {"op": "attribute", "name": "object"}
    scene = sun_over_procedural_floor(program)
    # Twice a quarter turn about z, and a shift.
    turn = np.array([[0.0, -2.0, 0.0, 1.0], [2.0, 0.0, 0.0, -1.0], [0.0, 0.0, 2.0, 0.5]])
    scene = scene.replace(object_from_world=turn[None], texture_spaces=np.array([[[0.5, 0, 0], [2, 1, 0]]]))
    attrs = procedural.HitAttributes(scene, np.array([0, 1]), (np.full((2, 1), 0.2), np.full((2, 1), 0.3),
                                                                np.full((2, 1), 0.5)),
                                     np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.0]]))
    obj = attrs.get("object")
    np.testing.assert_allclose(obj, [[1 - 0.4, -1 + 0.2, 0.5], [1 - 0.2, -1 - 0.6, 0.5]])
    np.testing.assert_allclose(attrs.get("generated"), (obj - [0.5, 0, 0]) * [0.25, 0.5, 0] + 0.5)
    assert RenderContext(scene.validate()).has_programs


def test_geometry_attributes_are_the_hits_world_position_and_normals():
    """Geometry's Position is the hit's world position; Normal the interpolated shading normal
    (the facet's without shading normals), True Normal the facet's, both unit, on the front; in a
    world shader Position is the direction and the normals its opposite (Cycles' background).  A
    scene without objects still has them."""
    scene = sun_over_procedural_floor({"op": "attribute", "name": "position"})
    scene = scene.replace(object_ids=None, object_from_world=None, texture_spaces=None).validate()
    bary = tuple(np.full((2, 1), w) for w in (0.2, 0.3, 0.5))
    positions = np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.0]])
    attrs = procedural.HitAttributes(scene, np.array([1, 0]), bary, positions)
    np.testing.assert_array_equal(attrs.get("position"), positions)
    np.testing.assert_allclose(attrs.get("true_normal"), [[0, 0, 1], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(attrs.get("world_normal"), [[0, 0, 1], [0, 0, 1]], atol=1e-12)
    tilted = np.zeros((2, 3, 3), np.float32)
    tilted[:, :, 2] = 1.0
    tilted[:, 0] = [0.6, 0.0, 0.8]                       # corner 0 leans towards +x
    smooth = scene.replace(shading_normals=tilted).validate()
    got = procedural.HitAttributes(smooth, np.array([1, 0]), bary, positions).get("world_normal")
    expected = 0.2 * np.array([0.6, 0.0, 0.8]) + 0.8 * np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(got, np.tile(expected / np.linalg.norm(expected), (2, 1)), rtol=1e-6)
    np.testing.assert_allclose(procedural.HitAttributes(smooth, np.array([1, 0]), bary, positions)
                               .get("true_normal"), [[0, 0, 1], [0, 0, 1]], atol=1e-12)
    d = np.array([[0.0, 0.6, 0.8]])
    world = procedural.DirectionAttributes(d)
    np.testing.assert_array_equal(world.get("position"), d)
    np.testing.assert_array_equal(world.get("world_normal"), -d)


def test_the_ray_turns_the_normals_and_sets_incoming_and_backfacing():
    """With the rays that meet the hits: Incoming is the direction back along each, Backfacing 1
    where it meets the back, and there Normal, True Normal and the object-space Normal turn
    towards it (Cycles); without rays each hit is seen head-on from its front.  In a world shader
    Incoming is the opposite of the direction and Backfacing 0."""
    scene = sun_over_procedural_floor({"op": "attribute", "name": "position"})
    bary = tuple(np.full((2, 1), w) for w in (0.2, 0.3, 0.5))
    positions = np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.0]])
    tilted = np.zeros((2, 3, 3), np.float32)
    tilted[:, :, 2] = 1.0
    tilted[:, 0] = [0.6, 0.0, 0.8]
    smooth = scene.replace(shading_normals=tilted).validate()
    incoming = np.array([[0.0, 0.6, 0.8], [0.0, 0.6, -0.8]])        # from above, from below
    seen = procedural.HitAttributes(smooth, np.array([1, 0]), bary, positions, procedural.Rays(incoming))
    front = procedural.HitAttributes(smooth, np.array([1, 0]), bary, positions)
    np.testing.assert_array_equal(seen.get("incoming"), incoming)
    np.testing.assert_array_equal(seen.get("backfacing"), [[0, 0, 0], [1, 1, 1]])
    side = np.array([[1.0], [-1.0]])
    for name in ("world_normal", "true_normal", "normal"):
        np.testing.assert_allclose(seen.get(name), side * front.get(name), atol=1e-12)
    assert front.get("world_normal")[0, 0] > 0.1
    np.testing.assert_allclose(front.get("incoming"), front.get("world_normal"))
    np.testing.assert_array_equal(front.get("backfacing"), np.zeros((2, 3)))
    d = np.array([[0.0, 0.6, 0.8]])
    world = procedural.DirectionAttributes(d)
    np.testing.assert_array_equal(world.get("incoming"), -d)
    np.testing.assert_array_equal(world.get("backfacing"), np.zeros((1, 3)))


def test_parametric_and_edge_distances_place_the_hit_in_its_triangle():
    """Parametric is (b0, b1, 0); the edge distances are those to the lines through corners 2-0,
    0-1 and 1-2 (Cycles' Wireframe), in world units."""
    scene = sun_over_procedural_floor({"op": "attribute", "name": "position"})
    tri = scene.vertices[scene.triangles[0]].astype(np.float64)
    b = np.array([[0.2, 0.3, 0.5], [0.6, 0.1, 0.3]])
    positions = b @ tri
    attrs = procedural.HitAttributes(scene, np.array([0, 0]), tuple(b[:, k:k + 1] for k in range(3)),
                                     positions)
    np.testing.assert_allclose(attrs.get("parametric"), [[0.2, 0.3, 0.0], [0.6, 0.1, 0.0]])
    for i in range(3):
        a, c = tri[i - 1], tri[i]
        height = 2.0 * b[:, i - 2] * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0])) / 2.0
        np.testing.assert_allclose(attrs.get("edge_distance")[:, i], height / np.linalg.norm(c - a),
                                   rtol=1e-6)


def floor_with_quad(quad, own_object, resolution=(32, 32)):
    """The 1 m floor of ``sun_over_procedural_floor`` (triangles 0, 1 of object 0) and a quad of
    ``quad``'s four corners (counter-clockwise from its front), of the floor's object or (not
    ``own_object``) of object 1, all of the floor's material."""
    floor = sun_over_procedural_floor({"op": "attribute", "name": "position"}, resolution=resolution)
    a, b, c, d = np.asarray(quad, np.float32)
    quad_object = 0 if own_object else 1
    return floor.replace(
        vertices=np.concatenate([floor.vertices, [a, b, c, a, c, d]]),
        triangles=np.concatenate([floor.triangles, [[6, 7, 8], [9, 10, 11]]]).astype(np.int32),
        material_ids=np.zeros(4, np.int32), uvs=np.zeros((4, 3, 2), np.float32),
        object_ids=np.array([0, 0, quad_object, quad_object], np.int32),
        object_from_world=np.repeat(floor.object_from_world, quad_object + 1, 0),
        texture_spaces=np.repeat(floor.texture_spaces, quad_object + 1, 0),
        object_info=np.repeat(floor.object_info, quad_object + 1, 0)).validate()


def floor_hits(scene, xy, sharp=False, with_accel=True):
    """``HitAttributes`` of the floor of :func:`floor_with_quad`'s ``scene`` hit from straight above
    at points ``xy`` (n, 2), seen from above."""
    from core.accel import Accel
    accel = Accel(scene)
    n = len(xy)
    origins = np.concatenate([xy, np.full((n, 1), 0.25)], axis=1)
    hits = accel.intersect(origins, np.tile([0.0, 0.0, -1.0], (n, 1)))
    assert (hits.prim_ids <= 1).all() and hits.is_hit.all()
    bary = (1.0 - hits.b1 - hits.b2)[:, None], hits.b1[:, None], hits.b2[:, None]
    positions = accel.hit_positions(hits.prim_ids, hits.b1, hits.b2)
    rays = procedural.Rays(np.tile([0.0, 0.0, 1.0], (n, 1)), sharp)
    return procedural.HitAttributes(scene, hits.prim_ids, bary, positions, rays,
                                    accel if with_accel else None)


def floor_under_ceiling(height):
    """The floor (object 0) under a 200 m ceiling facing down at ``height`` (object 1), hit at 4000
    points of its middle."""
    ceiling = [[-100, -100, height], [-100, 100, height], [100, 100, height], [100, -100, height]]
    xy = np.random.default_rng(3).uniform(-0.3, 0.3, (4000, 2))
    return floor_hits(floor_with_quad(ceiling, own_object=False), xy)


def test_ambient_occlusion_under_a_ceiling_is_the_closed_form():
    """Under a ceiling at height h a cosine-distributed ray of reach D escapes when cos < h / D:
    Cycles' AO is (h / D)^2 (here 0.25), 1 for D < h, 1 with Only Local (the ceiling is another
    object), 1 inside (the rays go down), the Color that times the colour; a hit gives the same
    value each time (its rays' numbers hash its position), hits apart draw anew; attributes that
    cannot cast rays read 1 (Cycles without a BVH)."""
    attrs = floor_under_ceiling(0.5)
    ao = {"op": "ao", "distance": 1.0, "samples": 16, "color": [0.2, 0.4, 0.8], "output": "AO"}
    value = procedural.evaluate(ao, attrs, [])
    assert value.mean() == pytest.approx(0.25, abs=0.01)
    assert set(np.unique(value * 16)) <= set(range(17)) and value.std() > 0.05
    np.testing.assert_array_equal(procedural.evaluate(ao, attrs, []), value)
    np.testing.assert_allclose(procedural.evaluate({**ao, "output": "Color"}, attrs, []),
                               value[:, None] * [0.2, 0.4, 0.8])
    for changed in ({"distance": 0.4}, {"only_local": True}, {"inside": True}):
        assert (procedural.evaluate({**ao, **changed}, attrs, []) == 1.0).all(), changed
    assert procedural.evaluate({**ao, "distance": 2.0}, attrs, []).mean() == pytest.approx(1 / 16, abs=0.01)
    assert (procedural.evaluate(ao, procedural.SampledAttributes(64), []) == 1.0).all()


@pytest.mark.parametrize("method", [dict(method="ppm"), dict(method="amcmcppm", chains=4096)],
                         ids=lambda m: m["method"])
def test_ambient_occlusion_in_a_lit_sphere_renders_the_closed_form(method):
    """A point light in a closed sphere of radius R whose diffuse colour is AO of reach R: a
    cosine-distributed ray from the wall meets the other side at 2 R cos, so AO = 1 - 1/4
    everywhere, and the sphere renders as one of albedo a AO (``point_in_sphere``'s closed form)
    with the photons' hits casting AO's rays too; both methods, finite."""
    from core import render
    from core.settings import RenderSettings
    from core.testing.scenes import point_in_sphere, with_one_object
    albedo, bounces = 0.6, 20
    ao = {"op": "ao", "distance": 1.0, "samples": 16, "color": [1.0, 1.0, 1.0], "output": "AO"}
    scene = point_in_sphere(albedo=albedo)
    mats = Materials.build([{"name": "shell", "diffuse": albedo, "diffuse_program": ao}])
    scene = with_one_object(scene).replace(materials=mats).validate()
    settings = RenderSettings(workers=1, passes=6, photons_per_pass=20_000, max_bounces=bounces, seed=2,
                              **method)
    image = render(scene, settings).image[..., :3]
    a = albedo * 0.75
    expected = a / np.pi * (1 - a ** (bounces + 1)) / (1 - a)
    assert np.isfinite(image).all()
    assert image.mean() == pytest.approx(expected, rel=0.03)


@pytest.mark.parametrize("method", [dict(method="ppm"), dict(method="amcmcppm", chains=256)],
                         ids=lambda m: m["method"])
def test_a_sky_texture_in_a_material_is_baked_once_per_render(method):
    """A Sky Texture on a surface (the sphere's colour by its normal): the render's
    ``RenderContext`` bakes the sky once (about 1.5 s) and every evaluation (eye pass, each photon
    batch and bounce) reads that bake, where each used to bake its own (a 10 x 10 render of one
    pass took 55 s); the cache holds one entry, keyed by the sky's settings; the image is finite
    and lit."""
    from core import render
    from core.context import RenderContext
    from core.settings import RenderSettings
    from core.testing.scenes import point_in_sphere, with_one_object
    sky = {"op": "sky", "vector": {"op": "attribute", "name": "normal"}, "sky_type": "MULTIPLE_SCATTERING",
           "sun_elevation": 0.3, "sun_rotation": 0.0, "altitude": 100.0, "air_density": 1.0,
           "aerosol_density": 1.0, "ozone_density": 1.0, "turbidity": 2.2, "sun_size": 0.0095,
           "sun_intensity": 1.0, "sun_disc": False, "sun_direction": [0.0, 0.0, 1.0]}
    colour = {"op": "mix_color", "blend": "MULTIPLY", "fac": 1.0, "a": sky, "b": [0.05] * 3}
    mats = Materials.build([{"name": "sky shell", "diffuse": 0.5, "diffuse_program": colour}])
    scene = with_one_object(point_in_sphere(resolution=(8, 8))).replace(materials=mats).validate()
    ctx = RenderContext(scene)
    settings = RenderSettings(workers=1, passes=2, photons_per_pass=4000, seed=3, **method)
    image = render(scene, settings, context=ctx).image[..., :3]
    assert np.isfinite(image).all() and image.mean() > 0
    assert [key[:2] for key in ctx.sky_cache.textures] == [("MULTIPLE_SCATTERING", 0.3)]


WALL = [[-0.5, -0.5, 0.0], [-0.5, 0.5, 0.0], [-0.5, 0.5, 1.0], [-0.5, -0.5, 1.0]]


def test_bevel_turns_the_normal_halfway_at_a_right_angle_edge():
    """A floor and a wall of one object meeting at a right angle: on the edge the Bevel normal is
    the bisector (the two faces alike: a ray along the wall's normal, a quarter of them, finds the
    wall half as often as one along the floor's finds the floor, at twice the weight), a radius
    away from it the floor's normal; rays that are
    not sharp (photons', Cycles' blurry indirect ones) and attributes without an accel keep the
    normal; a given normal is bent as much."""
    # The floor [-0.5, 0.5]^2 and a wall x = -0.5 facing +x, z in [0, 1].
    scene = floor_with_quad(WALL, own_object=True)
    y = np.linspace(-0.2, 0.2, 2000)
    x = np.where(np.arange(2000) % 2 == 0, -0.5 + 1e-6, 0.0)         # on the edge, or 0.5 from it
    up = np.tile([0.0, 0.0, 1.0], (2000, 1))

    def bevel(sharp=True, with_accel=True, **extra):
        attrs = floor_hits(scene, np.stack([x, y], axis=1), sharp, with_accel)
        return procedural.evaluate({"op": "bevel", "radius": 0.2, "samples": 16, **extra}, attrs, [])

    n = bevel()
    np.testing.assert_allclose(n[1::2], up[1::2], atol=1e-12)
    # (Many rays: the sum they normalise is then near its mean, whose direction is the bisector.)
    edge = bevel(samples=256)[0::2].mean(axis=0)
    np.testing.assert_allclose(edge / np.linalg.norm(edge), np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0),
                               atol=0.01)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-9)
    np.testing.assert_array_equal(bevel(sharp=False), up)
    np.testing.assert_array_equal(bevel(with_accel=False), up)
    bent = bevel(normal=[0.0, 1.0, 0.0])
    np.testing.assert_allclose(bent, procedural.normalize(n - up + [0.0, 1.0, 0.0]), atol=1e-12)


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_a_bevelled_normal_renders(method):
    """The floor and wall of ``test_bevel_turns_the_normal_halfway_at_a_right_angle_edge`` moved
    into the camera's view under the sun, the Bevel as the material's normal program
    (``Materials.normal_program``): the render is finite, the same for the same seed, and the
    band along the edge is shaded otherwise than without the bevel (the eye pass bends it)."""
    from core import render
    from core.settings import RenderSettings
    base = floor_with_quad(np.array(WALL) + [0.48, 0.0, 0.0], own_object=True, resolution=(16, 16))
    settings = RenderSettings(workers=1, passes=3, photons_per_pass=20_000, seed=4, method=method)
    images = []
    for normal in (None, {"op": "bevel", "radius": 0.05, "samples": 8}):
        spec = {"name": "floor", "diffuse": 0.8, **({} if normal is None else {"normal_program": normal})}
        scene = base.replace(materials=Materials.build([spec])).validate()
        images.append(render(scene, settings).image[..., :3])
        assert np.isfinite(images[-1]).all()
    again = render(scene, settings).image[..., :3]
    np.testing.assert_array_equal(again, images[-1])
    band = slice(7, 9)                                   # the columns beside the wall (x in [0, 0.025])
    ratio = images[1][:, band].mean() / images[0][:, band].mean()
    print(f"bevel band {ratio:.3f} of the plain render")
    assert abs(ratio - 1.0) > 0.01


class Seen:
    """Attributes of hits on the plane z = 0 seen along ``incoming`` (its normal +z on the ray's
    side, Backfacing where the ray comes from below)."""

    def __init__(self, incoming):
        self.incoming = np.asarray(incoming, np.float64)

    @property
    def count(self):
        return len(self.incoming)

    def get(self, name):
        back = self.incoming[:, 2:3] < 0
        return {"incoming": self.incoming, "backfacing": np.repeat(back * 1.0, 3, axis=1),
                "world_normal": np.where(back, [[0.0, 0.0, -1.0]], [[0.0, 0.0, 1.0]])}[name]


def test_fresnel_and_layer_weight_follow_the_view_as_cycles():
    """Fresnel: the dielectric reflectance of the IOR at the view cosine (of 1 / IOR on a back
    face: total internal reflection past the critical angle); Layer Weight's Fresnel that of
    1 / (1 - Blend), its Facing 1 - cos^(2 Blend) (Blend < 0.5) or cos^(0.5 / (1 - Blend))."""
    mu = np.array([1.0, 0.8, 0.5, 0.2, 0.05])
    sin = np.sqrt(1.0 - mu * mu)
    above = Seen(np.stack([sin, np.zeros(5), mu], axis=1))
    below = Seen(np.stack([sin, np.zeros(5), -mu], axis=1))
    eta = 1.45
    fac = procedural.evaluate({"op": "fresnel", "ior": eta}, above, [])
    assert fac[0] == pytest.approx(((eta - 1) / (eta + 1)) ** 2, rel=1e-12)
    np.testing.assert_allclose(fac, fresnel_dielectric(mu, np.full(5, eta))[0], rtol=1e-12)
    inside = procedural.evaluate({"op": "fresnel", "ior": eta}, below, [])
    np.testing.assert_allclose(inside, fresnel_dielectric(mu, np.full(5, 1 / eta))[0], rtol=1e-12)
    assert inside[0] == pytest.approx(fac[0]) and inside[-1] == 1.0      # (sin > 1 / 1.45: total)
    for blend, power in ((0.3, 0.6), (0.5, 1.0), (0.8, 2.5)):
        lw = {"op": "layer_weight", "blend": blend}
        np.testing.assert_allclose(procedural.evaluate(lw, above, [], "Facing"), 1 - mu ** power, rtol=1e-12)
        np.testing.assert_allclose(procedural.evaluate(lw, above, [], "Fresnel"),
                                   fresnel_dielectric(mu, np.full(5, 1 / (1 - blend)))[0], rtol=1e-12)
    normal = {"op": "fresnel", "ior": eta, "normal": [1.0, 0.0, 0.0]}     # a given normal
    np.testing.assert_allclose(procedural.evaluate(normal, above, []),
                               fresnel_dielectric(sin, np.full(5, eta))[0], rtol=1e-12)
    assert procedural.attributes_used(normal) == {"incoming", "backfacing"}
    assert procedural.varies({"op": "layer_weight", "blend": 0.5})


def test_a_named_attribute_is_interpolated_and_reads_zero_where_the_scene_lacks_it(tmp_path):
    """``named:`` + a name reads ``Scene.attributes[name]`` at the hits' barycentrics, 0 without it
    (Cycles); its shape is checked, and it survives a scene file."""
    program = {"op": "attribute", "name": procedural.NAMED + "wear"}
    scene = sun_over_procedural_floor(program)
    wear = np.arange(18, dtype=np.float32).reshape(2, 3, 3) / 18
    with_wear = scene.replace(attributes={"wear": wear}).validate()
    bary = tuple(np.full((2, 1), w) for w in (0.2, 0.3, 0.5))
    got = procedural.HitAttributes(with_wear, np.array([1, 0]), bary, np.zeros((2, 3))).get(program["name"])
    np.testing.assert_allclose(got, np.einsum("c,tck->tk", [0.2, 0.3, 0.5], wear[[1, 0]]), rtol=1e-6)
    lacking = procedural.HitAttributes(scene.validate(), np.array([0]), tuple(b[:1] for b in bary),
                                       np.zeros((1, 3)))
    assert not lacking.get(program["name"]).any()
    with_wear.save(tmp_path / "s.npz")
    np.testing.assert_array_equal(Scene.load(tmp_path / "s.npz").attributes["wear"], wear)
    with pytest.raises(SceneError, match=r"attributes\['wear'\] must have shape"):
        scene.replace(attributes={"wear": wear[:, :, :2]}).validate()
    with pytest.raises(procedural.ProgramError, match="name"):
        procedural.validate({"op": "attribute", "name": procedural.NAMED}, 0)


def test_an_object_property_reads_each_objects_row(tmp_path):
    """``object:`` + a path reads ``Scene.object_attributes`` of the hit's object, 0 where the scene
    has none; its shape and names are checked, and it survives a scene file."""
    program = {"op": "attribute", "name": "object:[\"tint\"]"}
    scene = sun_over_procedural_floor(program)
    tint = np.array([[0.9, 0.2, 0.1], [0.1, 0.5, 0.8]], np.float32)
    two = np.stack([np.eye(3, 4)] * 2)
    scene = scene.replace(object_ids=np.array([0, 1], np.int32), object_from_world=two,
                          texture_spaces=np.zeros((2, 2, 3)), object_info=None,
                          object_attributes={program["name"]: tint}).validate()
    bary = tuple(np.full((2, 1), w) for w in (0.2, 0.3, 0.5))
    attrs = procedural.HitAttributes(scene, np.array([1, 0]), bary, np.zeros((2, 3)))
    np.testing.assert_allclose(attrs.get(program["name"]), tint[[1, 0]])
    assert not procedural.HitAttributes(scene, np.array([0]), tuple(b[:1] for b in bary), np.zeros((1, 3))) \
        .get("instancer:color").any()
    scene.save(tmp_path / "s.npz")
    np.testing.assert_array_equal(Scene.load(tmp_path / "s.npz").object_attributes[program["name"]], tint)
    with pytest.raises(SceneError, match="object_attributes"):
        scene.replace(object_attributes={program["name"]: tint[:1]}).validate()
    with pytest.raises(SceneError, match="named 'object:'"):
        scene.replace(object_attributes={"tint": tint}).validate()


def test_object_info_reads_each_objects_row(tmp_path):
    """Object Info (``Scene.object_info``): the floor's two triangles as two objects, one turned a
    quarter about z and moved; each hit reads its object's origin in world space, its colour and
    (Alpha, Object Index, Random).  Without rows the values are 0; the rows survive a file and a
    bad shape is named."""
    program = {"op": "attribute", "name": "object_info"}
    scene = sun_over_procedural_floor(program)
    # Object from world: a quarter turn about z and a shift.
    turn = np.array([[0.0, 1.0, 0.0, -0.5], [-1.0, 0.0, 0.0, 0.25], [0.0, 0.0, 1.0, 2.0]])
    info = np.array([[0.5, 3, 0.25, 0.9, 0.1, 0.2], [1.0, 7, 0.75, 0.3, 0.4, 0.5]], np.float32)
    scene = scene.replace(object_ids=np.array([0, 1], np.int32),
                          object_from_world=np.stack([np.eye(3, 4), turn]),
                          texture_spaces=np.zeros((2, 2, 3)), object_info=info).validate()
    bary = tuple(np.full((2, 1), w) for w in (0.2, 0.3, 0.5))
    positions = np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.0]])
    attrs = procedural.HitAttributes(scene, np.array([1, 0]), bary, positions)
    np.testing.assert_allclose(attrs.get("object_info"), info[[1, 0], :3])
    np.testing.assert_allclose(attrs.get("object_color"), info[[1, 0], 3:])
    # Object 1's origin: the world point its map takes to 0, (0.25, 0.5, -2).
    np.testing.assert_allclose(attrs.get("object_location"), [[0.25, 0.5, -2.0], [0.0, 0.0, 0.0]], atol=1e-12)
    scene.save(tmp_path / "s.npz")
    np.testing.assert_array_equal(Scene.load(tmp_path / "s.npz").object_info, info)
    plain = scene.replace(object_info=None).validate()
    assert not procedural.HitAttributes(plain, np.array([0]), tuple(b[:1] for b in bary),
                                        np.zeros((1, 3))).get("object_info").any()
    with pytest.raises(SceneError, match="object_info must have shape"):
        scene.replace(object_info=info[:, :5]).validate()
    with pytest.raises(SceneError, match="reads 'object_info' coordinates"):
        scene.replace(object_ids=None).validate()


def test_programs_and_coordinates_survive_a_file(tmp_path):
    program = {"op": "mix_color", "blend": "MULTIPLY", "fac": 1.0, "a": [0.5, 0.6, 0.7],
               "b": {"op": "gradient", "vector": {"op": "attribute", "name": "generated"}, "output": "Color"}}
    scene = sun_over_procedural_floor(program)
    scene.save(tmp_path / "s.npz")
    loaded = Scene.load(tmp_path / "s.npz")
    assert loaded.materials.programs == [program]
    np.testing.assert_array_equal(loaded.materials.diffuse_program, [0])
    for name in ("object_ids", "object_from_world", "texture_spaces"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(scene, name))


@pytest.mark.parametrize("roughness, lobe", [(0.4, "glossy"), (0.0, "mirror")])
def test_glossy_program_colours_the_glossy_lobe_or_the_mirror_it_merged_into(roughness, lobe):
    """``glossy_program`` scales the glossy lobe's colour at each hit (the mirror lobe's for a sharp
    glossy, which the core merges into it); the diffuse colour keeps its own."""
    from core.bsdf import DIFFUSE, GLOSSY, MIRROR
    from core.context import RenderContext
    checker = {"op": "checker", "vector": OBJECT, "color1": [1.0, 0.5, 0.25], "color2": [0.2, 0.2, 0.2],
               "scale": 4.0}
    floor = sun_over_procedural_floor(checker)
    mats = Materials.build([{"name": "floor", "diffuse": 0.3, "diffuse_weight": 0.5, "glossy": 1.0,
                             "glossy_weight": 0.5, "roughness": roughness, "glossy_program": checker}])
    ctx = RenderContext(floor.replace(materials=mats).validate())
    bary = (np.full((2, 1), 0.25), np.full((2, 1), 0.25), np.full((2, 1), 0.5))
    surf = ctx.surface(np.array([0, 1]), bary[1][:, 0], bary[2][:, 0])
    expected = procedural.evaluate(checker, Points(surf.position), [])
    k = GLOSSY if lobe == "glossy" else MIRROR
    np.testing.assert_allclose(surf.colors[:, k], expected)
    np.testing.assert_allclose(surf.colors[:, DIFFUSE], 0.3)


def test_a_glossy_program_with_a_fresnel_rise_is_refused():
    floor = sun_over_procedural_floor({"op": "attribute", "name": "object"})
    mats = Materials.build([{"name": "layered", "glossy": 1.0, "glossy_fresnel_ior": 1.5,
                             "glossy_program": {"op": "splat", "value": 0.5}}])
    with pytest.raises(SceneError, match="cannot vary a glossy lobe with a Fresnel rise"):
        floor.replace(materials=mats).validate()


def test_blackbody_follows_cycles_fit():
    """Blender 5.0's own light temperature colours (``Light.temperature_color``) and the fit's
    ends: below 800 K and from 12,000 K constant."""
    c = procedural.blackbody(np.array([2700.0, 9000.0, 500.0, 799.0, 12000.0, 20000.0]))
    np.testing.assert_allclose(c[0], [1.9350767, 0.80353075, 0.19172148], rtol=1e-6)
    np.testing.assert_allclose(c[1], [0.9041047, 0.99395841, 1.3429724], rtol=1e-6)
    np.testing.assert_array_equal(c[2], c[3])
    np.testing.assert_array_equal(c[4], c[5])
    np.testing.assert_allclose(c[:2] @ procedural.LUMINANCE, 1.0, atol=2e-4)
    program = {"op": "blackbody", "temperature": {"op": "math", "operation": "MULTIPLY", "a": 3000.0,
                                                  "b": {"op": "separate", "vector": OBJECT, "output": "X"}}}
    np.testing.assert_allclose(run(program, [(0.9, 0, 0), (3.0, 0, 0)]), c[[0, 1]], rtol=1e-6)


def test_unpremultiply_divides_only_partial_alpha():
    """Cycles' ``color_unpremultiply``: colour / alpha where 0 < alpha < 1, unchanged at 0 and 1."""
    x = {"op": "separate", "vector": OBJECT, "output": "X"}
    program = {"op": "unpremultiply", "color": [0.2, 0.4, 0.6], "alpha": x}
    out = run(program, [(0.5, 0, 0), (0.0, 0, 0), (1.0, 0, 0), (2.0, 0, 0)])
    np.testing.assert_allclose(out, [[0.4, 0.8, 1.2], [0.2, 0.4, 0.6], [0.2, 0.4, 0.6], [0.2, 0.4, 0.6]])


def test_tangents_are_radial_about_the_object_axes_or_the_uv_maps():
    """Cycles' Tangent node (``svm_node_tangent``) and Geometry's Tangent (radial about Z): on the
    floor of ``sun_over_procedural_floor`` (Generated = xy + 0.5) the tangent about Z at (x, y) is
    (-y, x, 0) normalised, those about X and Y lie along the normal and vanish; turned with the
    object (a normal's transform); the UV map's tangent made perpendicular to a tilted normal."""
    scene = sun_over_procedural_floor({"op": "attribute", "name": "position"})
    xy = np.array([[0.3, 0.1], [-0.2, 0.25], [0.1, -0.4]])
    attrs = floor_hits(floor_with_quad([[2, 2, 0], [3, 2, 0], [3, 3, 0], [2, 3, 0]], True), xy)
    radial = np.stack([-xy[:, 1], xy[:, 0], np.zeros(3)], axis=1)
    np.testing.assert_allclose(attrs.get("tangent_z"), radial / np.linalg.norm(radial, axis=1, keepdims=True),
                               atol=1e-6)
    for name in ("tangent_x", "tangent_y"):
        np.testing.assert_allclose(attrs.get(name), 0.0, atol=1e-6)
    # The object turned a quarter about world Z (object x = world y): the tangent turns with it.
    turned = np.array([[[0.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]])
    scene_t = scene.replace(object_from_world=turned).validate()
    b = tuple(np.full((1, 1), w) for w in (0.2, 0.3, 0.5))
    p = np.array([[0.3, 0.1, 0.0]])
    t = procedural.HitAttributes(scene_t, np.array([0]), b, p).get("tangent_z")
    g = turned[0, :, :3] @ p[0] + 0.5 - 0.5               # Generated minus 0.5 in the object's space
    expected = turned[0, :, :3].T @ np.array([-g[1], g[0], 0.0])
    np.testing.assert_allclose(t[0], expected / np.linalg.norm(expected), atol=1e-6)
    # UV tangents along x under a normal tilted towards x: the part across the normal, unit length.
    tilted = np.zeros((2, 3, 3), np.float32)
    tilted[..., :] = [0.6, 0.0, 0.8]
    frames = np.zeros((2, 3, 4), np.float32)
    frames[..., 0] = frames[..., 3] = 1.0
    with_uv = scene.replace(shading_normals=tilted, tangents=frames).validate()
    t = procedural.HitAttributes(with_uv, np.array([0]), b, p).get("tangent_uv")
    np.testing.assert_allclose(t[0], [0.8, 0.0, -0.6], atol=1e-6)
    assert not procedural.HitAttributes(scene, np.array([0]), b, p).get("tangent_uv").any()
    assert procedural.reads_objects({"tangent_z"}) and not procedural.reads_objects({"tangent_uv"})


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_camera_rays_see_a_world_program_of_the_window_at_each_pixel(projection):
    """A world whose colour is Texture Coordinate's Window (``World.program``, a backplate's
    coordinates): camera rays that leave the scene see where they land in the frame, (0, 0) at its
    bottom left (one pass: within half a pixel of the pixel's centre, the jitter), also in the file;
    Camera coordinates are the direction in the camera's space; the world's light (``texture``, its
    bake) is unchanged."""
    from core import RenderSettings, render
    from core.scene import Camera, World
    from core.testing.scenes import MeshBuilder
    look = np.eye(4)
    look[:3, 3] = (0.0, 0.0, 5.0)
    w, h = 16, 12
    frame = (-0.4, 0.4, -0.3, 0.3)
    cam = Camera(world_from_camera=look, projection=projection, frame=frame, resolution=(w, h))
    world = World(color=np.full(3, 2.0, np.float32), program={"op": "attribute", "name": "window"})
    m = MeshBuilder()
    m.add_quad((50, 50, -10), (51, 50, -10), (51, 51, -10), (50, 51, -10), 0)      # out of view
    scene = m.build(Materials.build([{"name": "grey", "diffuse": 0.5}]), camera=cam, world=world)
    scene = Scene.from_arrays(scene.to_arrays())
    image = render(scene, RenderSettings(passes=1, photons_per_pass=1000, workers=1, method="ppm")).image
    cx = (np.arange(w) + 0.5) / w
    cy = 1.0 - (np.arange(h) + 0.5) / h                    # (top row first)
    np.testing.assert_allclose(image[..., 0], 2.0 * np.broadcast_to(cx, (h, w)), atol=2.0 * 0.5 / w + 1e-6)
    np.testing.assert_allclose(image[..., 1], 2.0 * np.broadcast_to(cy[:, None], (h, w)),
                               atol=2.0 * 0.5 / h + 1e-6)
    assert not image[..., 2].any()
    dirs = np.array([[0.0, 0.0, -1.0], [0.6, 0.0, -0.8]])
    attrs = procedural.DirectionAttributes(dirs, cam)
    np.testing.assert_allclose(attrs.get("camera"), [[0, 0, 1], [0.6, 0, 0.8]], atol=1e-12)
    if projection == "perspective":
        np.testing.assert_allclose(attrs.get("window")[0], [0.5, 0.5, 0.0])
    assert not procedural.DirectionAttributes(dirs).get("window").any()


@pytest.mark.parametrize("frame", ["own", "kept"])
def test_the_local_scene_answers_each_ray_over_its_own_object_as_a_scene_of_that_object_alone(frame):
    """``Accel.local_scene`` (every object shifted apart in one embree scene) against a query over
    each object's triangles alone (``Accel.subset``), ray by ray: the same triangles, distances and
    barycentrics, also where a box rests on the floor (its bottom face in the floor's plane) and
    for rays that start outside their object's box or would reach other objects first; also in
    embree's frame of an earlier version of the scene (``FRAME_SHIFT``: the scene moved by 0.35 of
    its extent, its triangles up to 0.85 of it from the frame's centre)."""
    from core.accel import Accel
    scene = floor_with_quad([[-0.2, -0.2, 0.0], [0.2, -0.2, 0.0], [0.2, 0.2, 0.0], [-0.2, 0.2, 0.0]],
                            own_object=False)          # a second object lying in the floor's plane
    offset = np.zeros(3)
    if frame == "kept":
        before = Accel(scene)
        offset[0] = 0.35 * before.extent
        scene = scene.replace(vertices=scene.vertices + offset.astype(np.float32), lights=dataclasses.replace(
            scene.lights, position=scene.lights.position + offset.astype(np.float32)))
        accel = Accel(scene, reuse=before)
        assert np.array_equal(accel.center, before.center)
        corners = np.concatenate([accel.v0, accel.v0 + accel.e1, accel.v0 + accel.e2])
        assert np.abs(corners - accel.center).max() > 0.8 * accel.extent
    else:
        accel = Accel(scene)
    rng = np.random.default_rng(5)
    n = 4000
    origins = rng.uniform(-0.8, 0.8, (n, 3)) + offset
    targets = np.concatenate([rng.uniform(-0.5, 0.5, (n, 2)), np.zeros((n, 1))], axis=1) + offset
    dirs = targets - origins                               # (towards the floor's square and the quad)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    objects = rng.integers(0, 2, n)
    tmax = rng.uniform(0.1, 3.0, n)
    got = accel.local_scene().intersect(origins, dirs, tmax, objects)
    for obj in (0, 1):
        rows = np.flatnonzero(objects == obj)
        alone = accel.subset(np.flatnonzero(scene.object_ids == obj)).intersect(origins[rows], dirs[rows],
                                                                                tmax[rows])
        np.testing.assert_array_equal(got.is_hit[rows], alone.is_hit)
        np.testing.assert_array_equal(got.prim_ids[rows], alone.prim_ids)
        hit = alone.is_hit
        np.testing.assert_allclose(got.t[rows][hit], alone.t[hit], rtol=1e-4)        # (float32; grazing rays)
        np.testing.assert_allclose(got.b1[rows][hit], alone.b1[hit], atol=1e-4)
    assert 0.3 < got.is_hit.mean() < 0.9 and got.is_hit[objects == 1].any()


def test_programs_over_more_hits_than_a_chunk_give_each_hit_its_own_value(monkeypatch):
    """``evaluate`` takes ``EVAL_CHUNK`` hits at a time (a world's bake 1.2 to 2.4 times faster,
    ``benchmarks/eval_chunk.py``): every hit's value is what one evaluation of all of them gives,
    bit for bit, for programs of the hit (noise, Voronoi, the incoming ray's Fresnel, Ambient
    Occlusion's rays, object info) and of the direction with the camera's view."""
    scene = floor_with_quad([[-1, -1, 0.3], [-1, 1, 0.3], [1, 1, 0.3], [1, -1, 0.3]], own_object=True)
    xy = np.random.default_rng(5).uniform(-0.45, 0.45, (3000, 2))
    hits = floor_hits(scene, xy)
    up = np.random.default_rng(7).normal(size=(3000, 3))
    up[:, 2] = np.abs(up[:, 2]) + 0.1
    rays = procedural.Rays(up / np.linalg.norm(up, axis=1, keepdims=True))
    seen = procedural.HitAttributes(scene, hits.prim_ids, hits.bary, hits.positions, rays, hits.accel)
    object_coords = {"op": "attribute", "name": "object"}
    hit_program = {"op": "mix_color", "blend": "ADD", "fac": 0.5,
                   "a": {"op": "noise", "vector": object_coords, "scale": 4.0, "detail": 3.0,
                         "roughness": 0.5, "lacunarity": 2.0, "output": "Color"},
                   "b": {"op": "voronoi", "vector": object_coords, "scale": 6.0, "output": "Color"}}
    cases = [(hits, hit_program), (seen, {"op": "fresnel", "ior": 1.45}),
             (hits, {"op": "ao", "color": [0.8] * 3, "distance": 0.5, "samples": 4, "output": "Color"}),
             (hits, {"op": "attribute", "name": "object_info"})]
    d = np.random.default_rng(6).normal(size=(3000, 3))
    cam = Camera(world_from_camera=np.eye(4), resolution=(8, 6))
    cases.append((procedural.DirectionAttributes(d / np.linalg.norm(d, axis=1, keepdims=True), cam),
                  {"op": "attribute", "name": "window"}))
    for attrs, program in cases:
        whole = procedural.evaluate(program, attrs, [])
        monkeypatch.setattr(procedural, "EVAL_CHUNK", 700)
        chunked = procedural.evaluate(program, attrs, [])
        monkeypatch.setattr(procedural, "EVAL_CHUNK", 1 << 40)
        assert chunked.shape == whole.shape and len(whole) == 3000, program["op"]
        np.testing.assert_array_equal(chunked, whole, err_msg=program["op"])

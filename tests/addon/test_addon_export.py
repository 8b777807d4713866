"""Depsgraph export (shared/docs/testing.md 2f): geometry, instances, materials, lights, camera, world.

These export with the viewport depsgraph (``evaluated_depsgraph_get``); the render
depsgraph path is covered by the end-to-end renders in test_addon_engine.py.
"""
from __future__ import annotations

import math

import bmesh
import bpy
import numpy as np
import pytest
from mathutils import Matrix, Vector

import blender_scenes as bs
from core.scene import (DISPLACE_KEEPS_NORMALS, DISPLACE_VECTOR, DISPLACE_WORLD, SUBSURFACE_RANDOM_WALK,
                        SUBSURFACE_SKIN)


def mesh_of(triangles_scene):
    return triangles_scene.vertices[triangles_scene.triangles].astype(np.float64)


def geometric_normals(core_scene):
    p = mesh_of(core_scene)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True), p.mean(axis=1)


# ---------------------------------------------------------------------- geometry
def test_empty_scene_exports_nothing(scene):
    bs.camera()
    ex = bs.export()
    assert ex.is_empty and ex.scene.triangle_count == 0 and ex.scene.lights.count == 0
    assert ex.scene.materials.count == 1        # a default material keeps the scene valid


def test_faceless_mesh_is_skipped_with_info(scene):
    bm = bmesh.new()
    a, b, c = (bm.verts.new(p) for p in ((0, 0, 0), (1, 0, 0), (0, 1, 0)))
    bm.edges.new((a, b))
    bm.edges.new((b, c))
    bs.mesh_object("Wire", bm)
    bs.plane("Floor", material=bs.diffuse())
    bs.camera()
    ex = bs.export()
    assert ex.scene.triangle_count == 2
    assert any("'Wire'" in m and "no faces" in m for m in ex.infos)
    assert ex.warnings == []


def test_ngons_are_triangulated_without_changing_area_or_power(scene):
    n, r, strength = 32, 1.0, 3.0
    bs.disk_ngon("Disk", radius=r, segments=n, material=bs.emission("Glow", strength=strength))
    bs.camera()
    me = bpy.data.objects["Disk"].data
    assert len(me.polygons) == 1 and len(me.polygons[0].vertices) == n
    s = bs.export().scene
    area = 0.5 * n * r * r * math.sin(2 * math.pi / n)
    assert s.triangle_count == n - 2
    assert bs.triangle_areas(s).sum() == pytest.approx(area, rel=1e-5)
    # Two-sided Lambertian emitter: power = 2 pi A L.
    assert bs.emitted_power(s) == pytest.approx(np.full(3, 2 * math.pi * area * strength), rel=1e-5)


def _polygon_mesh(name, sizes, rng):
    """A mesh of separate polygons with ``sizes`` corners: random, often concave or non-planar."""
    sizes = np.asarray(sizes)
    n_corner = int(sizes.sum())
    corner_in_polygon = np.arange(n_corner) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    angle = 2 * np.pi * corner_in_polygon / np.repeat(sizes, sizes)
    co = np.stack([np.cos(angle), np.sin(angle), np.zeros(n_corner)], axis=1)
    co += rng.normal(0.0, rng.choice([0.0, 0.3, 1.0], n_corner)[:, None], (n_corner, 3))
    co += 3.0 * np.repeat(np.arange(len(sizes)), sizes)[:, None]
    me = bpy.data.meshes.new(name)
    me.vertices.add(n_corner)
    me.vertices.foreach_set("co", co.astype(np.float32).ravel())
    me.loops.add(n_corner)
    me.loops.foreach_set("vertex_index", np.arange(n_corner, dtype=np.int32))
    me.polygons.add(len(sizes))
    me.polygons.foreach_set("loop_start", (np.cumsum(sizes) - sizes).astype(np.int32))
    me.update()
    return me


@pytest.mark.parametrize("mix", ["triangles", "quads", "triangles and quads", "with n-gons"])
def test_triangulation_is_blenders(scene, mix):
    """Our NumPy split of triangles and quads gives Blender's loop triangles, corner for corner,
    on random convex, concave and non-planar quads."""
    import importlib
    mesh_module = importlib.import_module("amcmcppm.amcmcppm_addon.export.mesh")
    rng = np.random.default_rng(3)
    choices = {"triangles": [3], "quads": [4], "triangles and quads": [3, 4],
               "with n-gons": [3, 4, 5, 7]}[mix]
    me = _polygon_mesh("Polygons", rng.choice(choices, 4000), rng)
    me.calc_loop_triangles()
    expected = np.array([t.loops[:] for t in me.loop_triangles])
    expected_poly = np.array([t.polygon_index for t in me.loop_triangles])
    positions = np.array([v.co[:] for v in me.vertices], np.float32)
    corner_vert = np.array([lp.vertex_index for lp in me.loops], np.int32)
    tri_loops, tri_poly = mesh_module._triangulate(me, positions, corner_vert)
    np.testing.assert_array_equal(tri_loops, expected)
    np.testing.assert_array_equal(tri_poly, expected_poly)
    local = mesh_module.read_mesh(me, "Polygons", None)
    np.testing.assert_array_equal(local.triangles, corner_vert[expected])


def test_array_modifier_is_evaluated(scene):
    ob = bs.cube("Cube", material=bs.diffuse())
    mod = ob.modifiers.new("Array", "ARRAY")
    mod.count = 18
    bs.camera()
    assert bs.export().scene.triangle_count == 216


def _instance_collection():
    coll = bpy.data.collections.new("Source")
    quad = bs.plane("Quad", size=0.5, material=bs.emission("Glow", strength=2.0), collection=coll)
    return coll, quad


def test_collection_instances_multiply_triangles_and_power(scene):
    coll, _ = _instance_collection()
    for i in range(100):
        empty = bpy.data.objects.new(f"Instance {i}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (i % 10, i // 10, 0.0)
        scene.collection.objects.link(empty)
    bs.camera()
    ex = bs.export()
    single = 2 * math.pi * 0.25 * 2.0
    assert ex.scene.triangle_count == 200
    assert ex.instances == 100 and ex.meshes == 1
    assert bs.emitted_power(ex.scene) == pytest.approx(np.full(3, 100 * single), rel=1e-5)
    # Each instance sits where its empty is.
    centres = mesh_of(ex.scene).mean(axis=1)
    assert sorted(set(np.round(centres[:, 0]).astype(int))) == list(range(10))


def test_geometry_node_instances_share_one_mesh(scene):
    _, quad = _instance_collection()
    ng = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    grid = ng.nodes.new("GeometryNodeMeshGrid")
    grid.inputs["Vertices X"].default_value = 10
    grid.inputs["Vertices Y"].default_value = 10
    grid.inputs["Size X"].default_value = 20.0
    grid.inputs["Size Y"].default_value = 20.0
    info = ng.nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = quad
    iop = ng.nodes.new("GeometryNodeInstanceOnPoints")
    out = ng.nodes.new("NodeGroupOutput")
    ng.links.new(grid.outputs["Mesh"], iop.inputs["Points"])
    ng.links.new(info.outputs["Geometry"], iop.inputs["Instance"])
    ng.links.new(iop.outputs["Instances"], out.inputs["Geometry"])
    host = bs.mesh_object("Host", bmesh.new())
    host.modifiers.new("GN", "NODES").node_group = ng
    bs.camera()
    ex = bs.export()
    assert ex.scene.triangle_count == 200 and ex.instances == 100 and ex.meshes == 1
    assert bs.emitted_power(ex.scene) == pytest.approx(np.full(3, 100 * 2 * math.pi * 0.25 * 2.0), rel=1e-5)
    assert ex.scene.materials.names == ["Glow"]      # the mesh's own material (no object slots)


@pytest.mark.parametrize("scale", [(-1, 1, 1), (1, -2, 1), (-1, -1, -1), (0.5, 0.5, -3)])
def test_negative_scale_keeps_outward_winding_and_power(scene, scale):
    glow = bs.emission("Glow", strength=1.5)
    ref = bs.cube("Reference", material=glow, location=(-5, 0, 0), scale=tuple(abs(s) for s in scale))
    bs.cube("Mirrored", material=glow, location=(5, 0, 0), scale=scale,
            rotation=(0.3, 0.2, 0.1))
    ref.rotation_euler = (0.3, 0.2, 0.1)
    bs.camera()
    s = bs.export().scene
    n, c = geometric_normals(s)
    left = c[:, 0] < 0
    for part, centre in ((left, (-5, 0, 0)), (~left, (5, 0, 0))):
        outward = np.einsum("ij,ij->i", n[part], c[part] - np.asarray(centre))
        assert (outward > 0).all(), "triangle winding must face outward"
    areas = bs.triangle_areas(s)
    assert areas[left].sum() == pytest.approx(areas[~left].sum(), rel=1e-5)
    power_ref = 2 * math.pi * areas[left].sum() * 1.5
    assert bs.emitted_power(s) == pytest.approx(np.full(3, 2 * power_ref), rel=1e-5)


def test_negative_scale_keeps_smooth_normals_outward(scene):
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=1.0)
    ob = bs.mesh_object("Ball", bm, bs.diffuse(), scale=(-1, 1, 1))
    ob.data.shade_smooth()
    bs.camera()
    s = bs.export().scene
    assert s.shading_normals is not None
    corners = mesh_of(s)
    radial = corners / np.linalg.norm(corners, axis=2, keepdims=True)
    assert np.einsum("tci,tci->tc", s.shading_normals, radial).min() > 0.95
    n, _ = geometric_normals(s)
    assert np.einsum("ti,ti->t", n, radial.mean(axis=1)).min() > 0


def test_normals_domains(scene):
    """Flat -> no shading normals; smooth (POINT) -> vertex normals; mixed (CORNER) -> corner normals."""
    flat = bs.cube("Flat", material=bs.diffuse())
    bs.camera()
    assert flat.data.normals_domain == "FACE"
    assert bs.export().scene.shading_normals is None

    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=24, v_segments=12, radius=1.0)
    ball = bs.mesh_object("Ball", bm, bs.diffuse(), location=(4, 0, 0))
    ball.data.shade_smooth()
    assert ball.data.normals_domain == "POINT"
    s = bs.export().scene
    n, c = geometric_normals(s)
    on_ball = c[:, 0] > 2
    # Flat triangles get their geometric normal at every corner, smooth ones the vertex normals.
    assert np.allclose(s.shading_normals[~on_ball], n[~on_ball][:, None, :], atol=1e-5)
    corners = mesh_of(s)[on_ball] - np.array([4.0, 0, 0])
    radial = corners / np.linalg.norm(corners, axis=2, keepdims=True)
    assert np.einsum("tci,tci->tc", s.shading_normals[on_ball], radial).min() > 0.99

    # Sharp edges on a smooth cube: corner normals, equal to the face normals at sharp corners.
    cube = bs.cube("Sharp", material=bs.diffuse(), location=(-4, 0, 0))
    cube.data.shade_smooth()
    sharp = cube.data.attributes.new("sharp_edge", "BOOLEAN", "EDGE")
    sharp.data.foreach_set("value", [True] * len(cube.data.edges))
    assert cube.data.normals_domain in ("CORNER", "FACE")
    s = bs.export().scene
    n, c = geometric_normals(s)
    on_cube = c[:, 0] < -2
    assert np.allclose(s.shading_normals[on_cube], n[on_cube][:, None, :], atol=1e-5)


def test_curves_and_text_become_triangles(scene):
    text = bpy.data.curves.new("Text", "FONT")
    text.body = "Hi"
    scene.collection.objects.link(bpy.data.objects.new("Text", text))
    curve = bpy.data.curves.new("Curve", "CURVE")
    curve.dimensions = "3D"
    curve.bevel_depth = 0.1
    spline = curve.splines.new("POLY")
    spline.points.add(1)
    spline.points[1].co = (2, 0, 0, 1)
    scene.collection.objects.link(bpy.data.objects.new("Curve", curve))
    bs.camera()
    ex = bs.export()
    assert ex.scene.triangle_count > 20
    assert ex.meshes == 2


def test_material_slots_and_object_links(scene):
    red, green, blue = (bs.diffuse(n, c) for n, c in (("Red", (1, 0, 0)), ("Green", (0, 1, 0)),
                                                      ("Blue", (0, 0, 1))))
    ob = bs.cube("Cube", material=red)
    ob.data.materials.append(green)
    mat_index = np.zeros(6, np.int32)
    mat_index[3:] = 1
    ob.data.attributes.new("material_index", "INT", "FACE").data.foreach_set("value", mat_index)
    bs.camera()
    s = bs.export().scene
    names = [s.materials.names[i] for i in s.material_ids]
    assert names.count("Red") == 6 and names.count("Green") == 6
    # Link slot 1 to the object instead of the mesh: the object's material wins.
    ob.material_slots[1].link = "OBJECT"
    ob.material_slots[1].material = blue
    s = bs.export().scene
    names = [s.materials.names[i] for i in s.material_ids]
    assert names.count("Red") == 6 and names.count("Blue") == 6 and "Green" not in names


def test_objects_without_materials_get_the_default(scene):
    bs.cube("Bare")
    bs.camera()
    s = bs.export().scene
    assert s.materials.names == ["default surface"]
    assert s.materials.diffuse_color[0] == pytest.approx([0.8, 0.8, 0.8])


def test_view_layer_material_override(scene):
    bs.cube("A", material=bs.diffuse("Red", (1, 0, 0)))
    bs.cube("B", material=bs.diffuse("Green", (0, 1, 0)), location=(3, 0, 0))
    bpy.context.view_layer.material_override = bs.diffuse("Clay", (0.5, 0.5, 0.5))
    bs.camera()
    s = bs.export().scene
    assert {s.materials.names[i] for i in s.material_ids} == {"Clay"}


# ---------------------------------------------------------------------- materials
def material_row(core_scene, name):
    m = core_scene.materials
    i = m.names.index(name)
    return {f: getattr(m, f)[i] for f in m.ARRAY_FIELDS}


def export_material(mat):
    bs.plane("Plane", material=mat)
    bs.camera()
    ex = bs.export()
    return material_row(ex.scene, mat.name), ex


def principled(name, **inputs):
    mat = bpy.data.materials.new(name)
    node = mat.node_tree.nodes["Principled BSDF"]
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat


def test_unsupported_node_warns_once_and_falls_back_to_grey(scene):
    mat = bs._material("Cartoon", "ShaderNodeBsdfToon")
    row, ex = export_material(mat)
    warnings = [w for w in ex.warnings if "Cartoon" in w]
    assert len(warnings) == 1 and "Toon BSDF" in warnings[0] and "ShaderNodeBsdfToon" in warnings[0]
    assert row["diffuse_weight"] == pytest.approx(1.0)
    assert row["diffuse_color"] == pytest.approx([0.8, 0.8, 0.8])


def test_several_unsupported_nodes_give_one_warning_naming_each(scene):
    mat = bpy.data.materials.new("Odd")
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    mix = nt.nodes.new("ShaderNodeMixShader")
    toon = nt.nodes.new("ShaderNodeBsdfToon")
    portal = nt.nodes.new("ShaderNodeBsdfRayPortal")
    nt.links.new(toon.outputs[0], mix.inputs[1])
    nt.links.new(portal.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, ex = export_material(mat)
    warnings = [w for w in ex.warnings if "'Odd'" in w]
    assert len(warnings) == 1
    assert "Toon BSDF" in warnings[0] and "Ray Portal BSDF" in warnings[0]
    assert row["diffuse_color"] == pytest.approx([0.8, 0.8, 0.8])


def test_missing_image_warns_and_uses_a_constant_colour(scene, tmp_path):
    img = bpy.data.images.new("Gone", 4, 4)
    img.source = "FILE"
    img.filepath = str(tmp_path / "does_not_exist.png")
    img.reload()
    mat = bs.diffuse("Textured")
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nt.links.new(tex.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    assert any("Gone" in w and "does_not_exist.png" in w for w in ex.warnings)
    assert row["diffuse_texture"] == -1
    assert row["diffuse_color"] == pytest.approx([1.0, 0.0, 1.0])
    assert ex.scene.textures == []


@pytest.mark.parametrize("setting", [("projection", "BOX"), ("extension", "CLIP"),
                                     ("interpolation", "Closest")])
def test_an_image_with_other_settings_is_a_program(scene, setting):
    """An Image Texture on the UV map with a box projection, another extension or Closest is a
    program with that setting, not the core's plain (flat, repeat, linear) image texture."""
    img = bpy.data.images.new("Tiles", 4, 4)
    mat = bs.diffuse("Set")
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    setattr(tex, *setting)
    nt.links.new(tex.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    assert row["diffuse_texture"] == -1
    program = ex.scene.materials.programs[row["diffuse_program"]]
    assert program["op"] == "image" and program[setting[0]] == setting[1]


def test_image_texture_is_linearised_and_uses_uvs(scene):
    img = bpy.data.images.new("Checker", 8, 4)
    px = np.zeros((4, 8, 4), np.float32)
    px[:, :4, :3] = 0.5            # left half mid grey in sRGB encoding, right half black
    px[..., 3] = 1.0
    img.pixels.foreach_set(px.ravel())
    img.colorspace_settings.name = "sRGB"
    mat = bs.diffuse("Textured")
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    reroute = nt.nodes.new("NodeReroute")
    nt.links.new(tex.outputs["Color"], reroute.inputs[0])
    nt.links.new(reroute.outputs[0], nt.nodes["Diffuse BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    s = ex.scene
    assert row["diffuse_texture"] == 0 and len(s.textures) == 1
    assert s.textures[0].shape == (4, 8, 3)
    stored = np.empty(4 * 8 * 4, np.float32)
    img.pixels.foreach_get(stored)
    stored = stored.reshape(4, 8, 4)[:, :, :3]
    expected = np.where(stored <= 0.04045, stored / 12.92, ((stored + 0.055) / 1.055) ** 2.4)
    assert s.textures[0] == pytest.approx(expected, abs=1e-5)
    assert s.uvs is not None and s.uvs.shape == (2, 3, 2)
    assert s.uvs.min() >= 0 and s.uvs.max() <= 1


def test_procedural_colour_becomes_a_program_with_the_coordinates_it_reads(scene):
    """A Principled base colour from a checker on Generated coordinates mixed with a gradient on
    Object coordinates: a program, and per-corner coordinates for every triangle (the plain
    object's too, which reads none); the texture's mean stands in where a lobe cannot vary."""
    mat = principled("Procedural")
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Object"], gradient.inputs["Vector"])
    mix = nt.nodes.new("ShaderNodeMixRGB")
    nt.links.new(checker.outputs["Color"], mix.inputs["Color1"])
    nt.links.new(gradient.outputs["Fac"], mix.inputs["Color2"])
    nt.links.new(mix.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    bs.plane("Plane", size=3.0, material=mat, location=(1, 2, 0), rotation=(0, 0, 0.5))
    bs.plane("Plain", material=bs.diffuse("Plain"), location=(5, 0, 0))
    bs.camera()
    ex = bs.export()
    s = ex.scene
    row = material_row(s, "Procedural")
    assert row["diffuse_program"] == 0 and row["diffuse_texture"] == -1
    assert row["diffuse_color"] == pytest.approx([1, 1, 1])
    program = s.materials.programs[0]
    assert program["op"] == "mix_color" and program["a"]["op"] == "checker"
    assert program["a"]["vector"] == {"op": "attribute", "name": "generated"}      # unlinked: Generated
    gradient = {"op": "gradient", "output": "Fac", "gradient_type": "LINEAR",
                "vector": {"op": "attribute", "name": "object"}}
    assert program["b"] == {"op": "splat", "value": gradient}
    assert material_row(s, "Plain")["diffuse_program"] == -1
    assert s.object_ids.shape == (4,) and s.object_from_world.shape == (2, 3, 4) and s.uvs is None
    textured = np.flatnonzero(s.material_ids == s.materials.names.index("Procedural"))
    # Object coordinates undo the object's transform; Generated maps its texture space to [0, 1].
    corners = s.vertices[s.triangles[textured]].reshape(-1, 3).astype(np.float64)
    from amcmcppm.core.procedural import HitAttributes
    tri = np.repeat(textured, 3)
    bary = tuple((np.tile(np.eye(3), (len(textured), 1))[:, k:k + 1]) for k in range(3))
    attrs = HitAttributes(s, tri, bary, corners)
    obj = attrs.get("object")
    assert np.abs(obj[:, :2]).max() == pytest.approx(1.5) and np.abs(obj[:, 2]).max() < 1e-6
    np.testing.assert_allclose(attrs.get("generated"), obj * [1 / 3, 1 / 3, 0] + 0.5, atol=1e-6)
    assert not any("Procedural" in w for w in ex.warnings), ex.warnings


def test_textures_on_inputs_that_cannot_vary_use_their_mean_with_a_warning(scene):
    mat = principled("Refractive", Metallic=1.0)
    nt = mat.node_tree
    ramp = nt.nodes.new("ShaderNodeValToRGB")         # black to white over a gradient: mean 0.5
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(gradient.outputs["Fac"], ramp.inputs["Fac"])
    ramp.color_ramp.elements[1].color = (3.0, 3.0, 3.0, 1.0)      # to 3: mean 1.5
    nt.links.new(ramp.outputs["Color"], nt.nodes["Principled BSDF"].inputs["IOR"])
    row, ex = export_material(mat)
    assert row["ior"] == pytest.approx(1.5, abs=0.05)
    assert has_no_programs(ex.scene)
    assert any("Refractive" in w and "IOR varies over the surface" in w for w in ex.warnings), ex.warnings


def test_a_roughness_map_becomes_a_program_clamped_to_one(scene):
    """A Principled BSDF's Roughness from a gradient times 2 (0 to 2): a float program clamped to
    [0, 1] (mean 0.75), the same one for both halves of a metallic map and for the glass of a
    transmissive one (``dielectric_roughness`` -1: the core's roughness copies roughen the glass
    too; before stop 39 it took the mean, noted), in the row and in every level."""
    mat = principled("Mapped", **{"Transmission Weight": 0.5})
    nt = mat.node_tree
    times = nt.nodes.new("ShaderNodeMath")
    times.operation = "MULTIPLY"
    times.inputs[1].default_value = 2.0
    nt.links.new(nt.nodes.new("ShaderNodeTexGradient").outputs["Fac"], times.inputs[0])
    nt.links.new(times.outputs[0], nt.nodes["Principled BSDF"].inputs["Roughness"])
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Metallic"])
    row, ex = export_material(mat)
    s = ex.scene
    program = s.materials.programs[row["roughness_program"]]
    from amcmcppm.core import procedural
    assert procedural.to_json(program).count('"op":"gradient"') == 1
    values = procedural.evaluate(program, procedural.SampledAttributes(), [])
    assert values.min() >= 0.0 and values.max() == 1.0 and values.mean() == pytest.approx(0.75, abs=0.02)
    assert row["glossy_roughness"] == pytest.approx(0.75, abs=0.02)
    assert row["dielectric_roughness"] == -1
    for k in (0, 8):
        level = material_row(s, f"Mapped (level {k}/16)")
        assert level["dielectric_roughness"] == -1 and level["roughness_program"] == row["roughness_program"]
        assert level["dielectric_weight"] == pytest.approx(0.5 * (1 - k / 16))
    assert not any("Mapped" in w and "glass" in w for w in ex.warnings), ex.warnings


def assert_two_shaders_are_the_levels(name, kind, roughness, field):
    """A Mix Shader by a checker of two ``kind`` nodes of Roughness ``roughness`` (two values) is
    not a constant mix in the core: the two shaders themselves are its levels, with their own
    ``field`` (the material row's roughness of that lobe)."""
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    first, second = (nt.nodes.new(kind) for _ in range(2))
    first.inputs["Roughness"].default_value, second.inputs["Roughness"].default_value = roughness
    bs.mix_shaders(nt, nt.nodes.new("ShaderNodeTexChecker").outputs["Fac"], first, second)
    if "Plane" in bpy.data.objects:
        bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    assert row["level_count"] == 2
    levels = [material_row(ex.scene, f"{name} (level {k}/1)") for k in (0, 1)]
    assert [level[field] for level in levels] == pytest.approx(roughness)


def test_a_glass_roughness_map_roughens_the_glass_point_by_point(scene):
    """A Glass BSDF whose Roughness is a gradient: the row's glass follows the clamped program
    (``dielectric_roughness`` -1, ``roughness_program``), no note.  Mixed at 0.5 with a Glossy BSDF of
    constant roughness the core has one roughness program for both, so the glass takes the map's
    mean, noted.  A mask between two glasses of different roughness gives the two as levels."""
    from amcmcppm.core import procedural
    mat = bpy.data.materials.new("Frosted")
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(gradient.outputs["Fac"], glass.inputs["Roughness"])
    nt.links.new(glass.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, ex = export_material(mat)
    assert row["dielectric_roughness"] == -1 and row["dielectric_weight"] == pytest.approx(1.0)
    pts = procedural.SampledAttributes(64)
    values = procedural.evaluate(ex.scene.materials.programs[row["roughness_program"]], pts, [])
    np.testing.assert_allclose(values, np.clip(pts.get("generated")[:, 0], 0, 1), atol=1e-6)
    assert not [w for w in ex.warnings if "'Frosted'" in w], ex.warnings
    bs.mix_in(mat, "Glass BSDF", "ShaderNodeBsdfGlossy", 0.5)
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    assert row["dielectric_roughness"] == pytest.approx(0.5, abs=0.02)
    assert row["glossy_roughness"] == pytest.approx(0.5) and row["roughness_program"] == -1
    assert any("'Frosted'" in w and "varying glass roughness" in w for w in ex.warnings), ex.warnings
    assert_two_shaders_are_the_levels("Two panes", "ShaderNodeBsdfGlass", (0.0, 0.6), "dielectric_roughness")


def test_textured_emission_becomes_one_program_scaled_to_its_mean(scene):
    """A Principled BSDF with a checker Emission Color of strength 20 and a metallic map: the
    emission is the checker's mean's largest channel times a program of about 1 (the texture's
    own range, not 20 times it: the core clamps nothing below 1e30 there, and keeps the numbers
    readable), and the metallic map's two halves share that one program instead of mixing it
    with itself."""
    mat = principled("Glowing", **{"Emission Strength": 20.0})
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    checker = nt.nodes.new("ShaderNodeTexChecker")       # 0.8 and 0.2 grey: mean 0.5
    nt.links.new(checker.outputs["Color"], bsdf.inputs["Emission Color"])
    nt.links.new(nt.nodes.new("ShaderNodeTexGradient").outputs["Fac"], bsdf.inputs["Metallic"])
    row, ex = export_material(mat)
    s = ex.scene
    assert row["emission"] == pytest.approx([10.0] * 3, rel=0.02)
    program = s.materials.programs[row["emission_program"]]
    from amcmcppm.core import procedural
    values = procedural.evaluate_color(program, procedural.SampledAttributes(), s.textures, limit=1e30)
    assert set(np.unique(values.round(4))) <= {round(0.2 * 20 / row["emission"][0], 4),
                                               round(0.8 * 20 / row["emission"][0], 4)}
    assert "checker" in procedural.to_json(program) and procedural.to_json(program).count("checker") == 1
    assert row["diffuse_program"] >= 0                   # the metallic map mixes the base colours


def test_multiscatter_glass_reaches_the_core_with_its_transmission_tint(scene):
    """Multiscatter GGX (Blender's default) on a Glass BSDF gives ``dielectric_multiscatter`` its
    colour, on a Principled glass the square root of its base colour (Cycles' F_ss, the
    transmission tint; stop 45); GGX and the Refraction BSDF give 0 (single scattering)."""
    row, _ = export_material(bs._material("Frosted", "ShaderNodeBsdfGlass", Roughness=0.5,
                                          Color=(0.9, 0.6, 0.3, 1.0)))
    assert row["dielectric_multiscatter"] == pytest.approx([0.9, 0.6, 0.3])
    mat = bs._material("Single", "ShaderNodeBsdfGlass", Roughness=0.5)
    mat.node_tree.nodes["Glass BSDF"].distribution = "GGX"
    row, _ = export_material(mat)
    assert not row["dielectric_multiscatter"].any()
    row, _ = export_material(bs._material("Refractive", "ShaderNodeBsdfRefraction", Roughness=0.5))
    assert not row["dielectric_multiscatter"].any()
    row, _ = export_material(principled("Principled glass", **{"Transmission Weight": 1.0, "Roughness": 0.4,
                                                               "Base Color": (0.81, 0.49, 0.25, 1.0)}))
    assert row["dielectric_multiscatter"] == pytest.approx([0.9, 0.7, 0.5], rel=1e-5)


def test_beckmann_microfacets_reach_the_core(scene):
    """Beckmann (the Refraction BSDF's default, a choice of the Glossy, Glass and Metallic BSDFs)
    reaches ``Materials.glossy_distribution`` / ``dielectric_distribution`` (stop 46; before, it
    rendered as GGX), without multiscatter; GGX and Multiscatter GGX give 0.  A Mix of glossy
    shaders of both takes the distribution of most of its weight and is noted."""
    from amcmcppm.core.bsdf import DISTRIBUTION_BECKMANN, DISTRIBUTION_GGX
    row, _ = export_material(bs._material("Refractive", "ShaderNodeBsdfRefraction", Roughness=0.5))
    assert row["dielectric_distribution"] == DISTRIBUTION_BECKMANN
    for node_type, name in (("ShaderNodeBsdfGlass", "Glass BSDF"), ("ShaderNodeBsdfGlossy", "Glossy BSDF"),
                            ("ShaderNodeBsdfMetallic", "Metallic BSDF")):
        for distribution in ("BECKMANN", "GGX", "MULTI_GGX"):
            mat = bs._material(f"{node_type} {distribution}", node_type, Roughness=0.5)
            mat.node_tree.nodes[name].distribution = distribution
            row, _ = export_material(mat)
            key = "dielectric" if node_type == "ShaderNodeBsdfGlass" else "glossy"
            expected = DISTRIBUTION_BECKMANN if distribution == "BECKMANN" else DISTRIBUTION_GGX
            assert row[f"{key}_distribution"] == expected, (node_type, distribution)
            if distribution == "BECKMANN":
                assert not row[f"{key}_multiscatter"].any()
    mat = bs._material("Mixed", "ShaderNodeBsdfGlossy", Roughness=0.4)
    mat.node_tree.nodes["Glossy BSDF"].distribution = "BECKMANN"
    other = bs.mix_in(mat, "Glossy BSDF", "ShaderNodeBsdfGlossy", 0.3)
    other.distribution = "GGX"
    row, ex = export_material(mat)
    assert row["glossy_distribution"] == DISTRIBUTION_BECKMANN
    assert any("'Mix Shader'" in w and "Beckmann" in w for w in ex.warnings), ex.warnings


def test_stained_glass_becomes_a_program_of_the_transmitted_colour(scene):
    """A Glass BSDF coloured by a checker: the transmitted colour is the checker (colour 1 times
    the program), the reflection its mean; a Principled glass: the square root of its base colour
    per interface (a gamma of 0.5), reflecting its specular tint."""
    from amcmcppm.core import procedural
    glass = bs.glass("Stained")
    nt = glass.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")             # 0.8 and 0.2 grey: mean 0.5
    nt.links.new(checker.outputs["Color"], nt.nodes["Glass BSDF"].inputs["Color"])
    principled_glass = principled("Tinted", **{"Transmission Weight": 1.0})
    pt = principled_glass.node_tree
    pt.links.new(pt.nodes.new("ShaderNodeTexChecker").outputs["Color"],
                 pt.nodes["Principled BSDF"].inputs["Base Color"])
    bs.plane("Plane", material=glass)
    bs.plane("Other", material=principled_glass, location=(3, 0, 0))
    bs.camera()
    ex = bs.export()
    s = ex.scene
    row = material_row(s, "Stained")
    program = s.materials.programs[row["dielectric_program"]]
    assert program["op"] == "checker"
    assert row["dielectric_color"] == pytest.approx([1, 1, 1])
    assert row["dielectric_reflection_color"] == pytest.approx([0.5] * 3, abs=0.02)
    tinted = material_row(s, "Tinted")
    program = s.materials.programs[tinted["dielectric_program"]]
    assert program["op"] == "gamma" and program["gamma"] == 0.5 and program["color"]["op"] == "checker"
    assert tinted["dielectric_reflection_color"] == pytest.approx([1, 1, 1])
    values = procedural.evaluate_color(program, procedural.SampledAttributes(), s.textures)
    assert set(np.unique(values.round(4))) == {round(0.2 ** 0.5, 4), round(0.8 ** 0.5, 4)}
    assert not any("Stained" in w or "Tinted" in w for w in ex.warnings), ex.warnings


def test_alpha_and_transparent_bsdf_become_an_opacity(scene):
    """Principled Alpha 0.25: opacity 0.25, the lobes and emission those of the opaque node; a Mix
    Shader of a tinted Transparent BSDF and a textured Diffuse by a gradient mask: the opacity is
    the mask (a program), the transparent colour the tint, and the diffuse colour the texture
    itself (the mask divided out), with no note."""
    from amcmcppm.core import procedural
    half = principled("Half", Alpha=0.25, **{"Base Color": (0.5, 0.2, 0.1, 1.0), "Emission Strength": 2.0,
                                             "Emission Color": (1.0, 1.0, 1.0, 1.0)})
    solid = principled("Solid", **{"Base Color": (0.5, 0.2, 0.1, 1.0), "Emission Strength": 2.0,
                                   "Emission Color": (1.0, 1.0, 1.0, 1.0)})
    mask = bpy.data.materials.new("Mask")
    nt = mask.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    clear = nt.nodes.new("ShaderNodeBsdfTransparent")
    clear.inputs["Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Color"], diffuse.inputs["Color"])
    bs.mix_shaders(nt, nt.nodes.new("ShaderNodeTexGradient").outputs["Fac"], clear, diffuse)
    for i, mat in enumerate((half, solid, mask)):
        bs.plane(mat.name, material=mat, location=(3 * i, 0, 0))
    bs.camera()
    ex = bs.export()
    s = ex.scene
    h, o, m = (material_row(s, name) for name in ("Half", "Solid", "Mask"))
    assert h["opacity"] == pytest.approx(0.25) and o["opacity"] == 1.0 and h["opacity_program"] == -1
    for key in ("diffuse_weight", "glossy_weight", "diffuse_color", "glossy_color", "emission"):
        np.testing.assert_allclose(h[key], o[key], rtol=1e-5, err_msg=key)
    assert m["opacity_program"] >= 0 and m["opacity"] == pytest.approx(0.5, abs=0.02)
    np.testing.assert_allclose(m["transparent_color"], [1.0, 0.5, 0.25])
    assert m["diffuse_weight"] == pytest.approx(1.0)
    pts = procedural.SampledAttributes()
    colour = procedural.evaluate_color(s.materials.programs[m["diffuse_program"]], pts, s.textures)
    opacity = procedural.evaluate(s.materials.programs[m["opacity_program"]], pts, s.textures)
    shown = opacity > 0.01                              # where the surface is ever shaded
    assert set(np.unique(colour[shown].round(4))) == {0.2, 0.8}
    assert not any("Mask" in w or "Half" in w for w in ex.warnings), ex.warnings


def has_no_programs(core_scene):
    """No procedural colour and no coordinates for one."""
    return core_scene.materials.programs == [] and core_scene.object_ids is None


def test_constant_node_graphs_fold_into_constants(scene):
    """Math of numbers and a Mix of colours vary nowhere: plain values, no program, no warning."""
    mat = bs.diffuse("Folded")
    nt = mat.node_tree
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.blend_type = "MULTIPLY"
    mix.inputs["Fac"].default_value = 1.0
    mix.inputs["Color1"].default_value = (0.5, 0.8, 1.0, 1.0)
    mix.inputs["Color2"].default_value = (0.5, 0.5, 0.5, 1.0)
    nt.links.new(mix.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    assert row["diffuse_color"] == pytest.approx([0.25, 0.4, 0.5]) and row["diffuse_program"] == -1
    assert has_no_programs(ex.scene) and not ex.warnings


def test_a_varying_mix_factor_between_diffuse_and_glossy_is_exact(scene):
    """Mix Shader(Diffuse, Glossy) by a gradient (mean 0.5 over the texture space): the diffuse
    colour becomes (1 - F) colour / mean(1 - F) and the glossy colour F white / mean(F), over the
    weights' means: exact, so no note."""
    mat = bpy.data.materials.new("Masked")
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    glossy = nt.nodes.new("ShaderNodeBsdfGlossy")
    mix = nt.nodes.new("ShaderNodeMixShader")
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(gradient.outputs["Fac"], mix.inputs["Fac"])
    nt.links.new(diffuse.outputs[0], mix.inputs[1])
    nt.links.new(glossy.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, ex = export_material(mat)
    assert row["diffuse_weight"] == pytest.approx(0.5, abs=0.02)
    assert row["glossy_weight"] == pytest.approx(0.5, abs=0.02)
    assert row["diffuse_program"] == 0 and row["diffuse_color"] == pytest.approx([1, 1, 1])
    from amcmcppm.core import procedural
    program = ex.scene.materials.programs[0]
    pts = procedural.SampledAttributes(64)
    colour = procedural.evaluate(program, pts, [])
    x = np.clip(pts.get("generated")[:, 0], 0, 1)
    np.testing.assert_allclose(colour, (1 - x)[:, None] * [0.2, 0.4, 0.6] / row["diffuse_weight"], rtol=1e-6)
    glossy = procedural.evaluate(ex.scene.materials.programs[row["glossy_program"]], pts, [])
    np.testing.assert_allclose(glossy, x[:, None] * [0.8, 0.8, 0.8] / row["glossy_weight"], rtol=1e-6)
    assert row["glossy_color"] == pytest.approx([1, 1, 1])
    assert not [w for w in ex.warnings if "'Masked'" in w], ex.warnings


def test_a_bump_of_constant_height_is_the_normal_wherever_it_goes(scene, tmp_path):
    """A Bump whose Height is unlinked (a constant: no slope) gives its Normal input unchanged, as
    Cycles' does, wherever a program reads it: as a colour it renders the very image of the
    Geometry node's Normal, and into a Vector Displacement it renders (before: "TypeError: 'float'
    object is not subscriptable", no image; found by a fuzz sweep)."""
    images = []
    for source in ("bump", "geometry", "displaced"):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bs.lit_floor_scene((16, 16))
        mat = bs.diffuse("Bumped")
        nt = mat.node_tree
        if source == "geometry":
            normal = nt.nodes.new("ShaderNodeNewGeometry").outputs["Normal"]
        else:
            normal = nt.nodes.new("ShaderNodeBump").outputs["Normal"]
        absolute = nt.nodes.new("ShaderNodeVectorMath")
        absolute.operation = "ABSOLUTE"
        nt.links.new(normal, absolute.inputs[0])
        nt.links.new(absolute.outputs[0], nt.nodes["Diffuse BSDF"].inputs["Color"])
        if source == "displaced":
            shift = nt.nodes.new("ShaderNodeVectorDisplacement")
            shift.inputs["Scale"].default_value = 0.01
            nt.links.new(normal, shift.inputs["Vector"])
            nt.links.new(shift.outputs[0], nt.nodes["Material Output"].inputs["Displacement"])
            mat.displacement_method = "BOTH"
        bs.cube("Box", size=0.6, material=mat, location=(0, 0, 0.3), rotation=(0.3, 0.2, 0.5))
        images.append(bs.render_exr(tmp_path / f"{source}.exr"))
    assert all(np.isfinite(img).all() for img in images)
    np.testing.assert_allclose(images[0], images[1], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("fac, textured_first", [(1.0, True), (0.0, False)], ids=["fac_1", "fac_0"])
def test_a_mix_that_shows_one_side_alone_drops_the_textured_other(scene, fac, textured_first):
    """Mix Shader(textured Diffuse, plain Diffuse) by a factor of exactly 1 (or 0, the sides
    swapped), an artist's switch: the material is the plain side's, a constant colour (before:
    "TypeError: '>=' not supported between instances of 'list' and 'int'", no image; found by a
    fuzz sweep)."""
    mat = bpy.data.materials.new("Switch")
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    textured, plain = nt.nodes.new("ShaderNodeBsdfDiffuse"), nt.nodes.new("ShaderNodeBsdfDiffuse")
    plain.inputs["Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    nt.links.new(nt.nodes.new("ShaderNodeTexChecker").outputs["Color"], textured.inputs["Color"])
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = fac
    first, second = (textured, plain) if textured_first else (plain, textured)
    nt.links.new(first.outputs[0], mix.inputs[1])
    nt.links.new(second.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, _ = export_material(mat)
    assert row["diffuse_program"] == -1 and row["diffuse_texture"] == -1
    assert row["diffuse_weight"] == pytest.approx(1.0)
    assert row["diffuse_color"] == pytest.approx([0.2, 0.4, 0.6])


def test_a_mask_between_a_metal_and_a_paint_picks_levels_of_the_mask(scene):
    """Mix Shader(Principled paint, Principled metal) by a gradient: they differ beyond their diffuse
    colours, so the mix gets levels of the factor (``Closure.levels``), each a constant mix: level 0
    the paint, level 16 the metal (its curve), level 8 half of each; no note.  Of different
    roughness, the two themselves.  A Principled with a metallic map on one side keeps its own
    levels and the mask mixes by its mean, noted."""
    from amcmcppm.core import procedural
    mat = bpy.data.materials.new("Rust")
    nt = mat.node_tree
    paint = nt.nodes["Principled BSDF"]
    paint.inputs["Base Color"].default_value = (0.1, 0.2, 0.6, 1.0)
    metal = nt.nodes.new("ShaderNodeBsdfPrincipled")
    metal.inputs["Metallic"].default_value = 1.0
    metal.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1.0)
    bs.mix_shaders(nt, nt.nodes.new("ShaderNodeTexGradient").outputs["Fac"], paint, metal)
    row, ex = export_material(mat)
    assert row["level_count"] == 17 and row["level_program"] >= 0
    first, middle, last = (material_row(ex.scene, f"Rust (level {k}/16)") for k in (0, 8, 16))
    assert first["diffuse_color"] == pytest.approx([0.1, 0.2, 0.6]) and first["diffuse_weight"] == 1.0
    assert not first["glossy_metal_rise"].any() and first["glossy_fresnel_ior"] == pytest.approx(1.5)
    assert last["diffuse_weight"] == 0 and last["glossy_color"] == pytest.approx([0.9, 0.6, 0.3])
    np.testing.assert_allclose(last["glossy_metal_rise"], [0.1, 0.4, 0.7], rtol=1e-5)
    assert middle["diffuse_weight"] == pytest.approx(0.5)
    np.testing.assert_allclose(middle["glossy_metal_rise"], [0.05, 0.2, 0.35], rtol=1e-5)
    assert not [w for w in ex.warnings if "'Rust'" in w], ex.warnings
    # Of different roughness, a constant mix is one lobe of their mean roughness: the two
    # themselves are the levels (the core picks either by the mask).
    metal.inputs["Roughness"].default_value = 0.2
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    first, last = (material_row(ex.scene, f"Rust (level {k}/1)") for k in (0, 1))
    assert row["level_count"] == 2 and first["glossy_roughness"] == pytest.approx(0.5)
    assert last["glossy_roughness"] == pytest.approx(0.2) and last["diffuse_weight"] == 0
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], metal.inputs["Metallic"])
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    mats = ex.scene.materials
    assert (mats.level_program >= 0).sum() == 1
    assert "noise" in procedural.to_json(mats.programs[mats.level_program[mats.names.index("Rust")]])
    assert any("'Rust'" in w and "varying Fac" in w for w in ex.warnings), ex.warnings


def test_a_coat_map_picks_levels_of_the_coat(scene):
    """Coat Weight from a checker (a varnish worn off in squares): levels of it as for a metallic
    map, level k the node with a coat of weight k / 16 (its roughness and IOR), no note of a mix
    of different coats (the coat covers the whole node at every level).  Within a metallic map's
    levels, each mixes its coat by the map's mean, noted."""
    mat = principled("Varnish", **{"Base Color": (0.5, 0.3, 0.1, 1.0), "Coat Roughness": 0.1,
                                   "Coat IOR": 1.6})
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Coat Weight"])
    row, ex = export_material(mat)
    assert row["level_count"] == 17 and 0.3 < row["coat_weight"] < 0.7
    levels = [material_row(ex.scene, f"Varnish (level {k}/16)") for k in (0, 4, 16)]
    assert [r["coat_weight"] for r in levels] == pytest.approx([0.0, 0.25, 1.0])
    assert levels[1]["coat_roughness"] == pytest.approx(0.1) and levels[2]["coat_ior"] == pytest.approx(1.6)
    assert all(r["diffuse_color"] == pytest.approx([0.5, 0.3, 0.1]) for r in levels)
    assert not [w for w in ex.warnings if "'Varnish'" in w], ex.warnings
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(gradient.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Metallic"])
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    assert row["level_count"] == 17 and (ex.scene.materials.level_program >= 0).sum() == 1
    assert 0.3 < material_row(ex.scene, "Varnish (level 0/16)")["coat_weight"] < 0.7
    assert any("'Varnish'" in w and "varying Coat Weight" in w for w in ex.warnings), ex.warnings
    assert not any("different coats" in w for w in ex.warnings), ex.warnings


def test_a_mask_between_coated_and_bare_or_rough_and_smooth_diffuse_picks_levels(scene):
    """Mix Shader by a checker of a coated and a bare Principled BSDF (wet patches), otherwise
    alike: the core has one coat per material, so a point-by-point mix would coat both by the
    mask's mean; the mix gets levels of the mask instead, level k coated at k / 16.  So does a mask
    between Diffuse BSDFs of different roughness (one diffuse roughness per material: the two
    themselves as levels)."""
    mat = principled("Wet", **{"Base Color": (0.3, 0.2, 0.1, 1.0)})
    nt = mat.node_tree
    wet = nt.nodes.new("ShaderNodeBsdfPrincipled")
    wet.inputs["Base Color"].default_value = (0.15, 0.1, 0.05, 1.0)
    wet.inputs["Coat Weight"].default_value = 1.0
    checker = nt.nodes.new("ShaderNodeTexChecker")
    bs.mix_shaders(nt, checker.outputs["Fac"], nt.nodes["Principled BSDF"], wet)
    row, ex = export_material(mat)
    assert row["level_count"] == 17
    levels = [material_row(ex.scene, f"Wet (level {k}/16)") for k in (0, 8, 16)]
    assert [r["coat_weight"] for r in levels] == pytest.approx([0.0, 0.5, 1.0])
    assert levels[2]["diffuse_color"] == pytest.approx([0.15, 0.1, 0.05])          # (level 16)
    assert_two_shaders_are_the_levels("Mossy", "ShaderNodeBsdfDiffuse", (0.8, 0.0), "diffuse_roughness")


def test_a_masks_levels_between_textured_and_plain_paints_share_the_point_by_point_diffuse(scene):
    """Mix Shader by a noise mask of a Principled of a noise base colour and a coated one of a plain
    colour (wet patches on a textured ground): the diffuse lobes differ in colour alone, so every
    level takes the mask's point-by-point mix of the two colours, one program (the levels' own
    constant mixes were a program each), and keeps its own coat."""
    from amcmcppm.core import procedural
    mat = bpy.data.materials.new("Wet ground")
    nt = mat.node_tree
    dry = nt.nodes["Principled BSDF"]
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Color"], dry.inputs["Base Color"])
    wet = nt.nodes.new("ShaderNodeBsdfPrincipled")
    wet.inputs["Base Color"].default_value = (0.1, 0.08, 0.05, 1.0)
    wet.inputs["Coat Weight"].default_value = 1.0
    mask = nt.nodes.new("ShaderNodeTexGradient")
    bs.mix_shaders(nt, mask.outputs["Fac"], dry, wet)
    row, ex = export_material(mat)
    mats = ex.scene.materials
    first, count = row["level_first"], row["level_count"]
    assert count == 17
    assert len(set(mats.diffuse_program[first:first + count].tolist())) == 1
    pts = procedural.SampledAttributes(64)
    x = np.clip(pts.get("generated")[:, 0], 0.0, 1.0)
    noise = {"op": "noise", "vector": {"op": "attribute", "name": "generated"}, "dimensions": "3D",
             "noise_type": "FBM", "normalize": True, "scale": 5.0, "detail": 2.0, "roughness": 0.5,
             "lacunarity": 2.0, "distortion": 0.0, "output": "Color"}
    expected = (1 - x)[:, None] * procedural.evaluate(noise, pts, []) + x[:, None] * [0.1, 0.08, 0.05]
    for k in (0, 8, 16):
        level = material_row(ex.scene, f"Wet ground (level {k}/16)")
        program = mats.programs[level["diffuse_program"]]
        colour = level["diffuse_color"] * procedural.evaluate(program, pts, [])
        np.testing.assert_allclose(colour * level["diffuse_weight"], expected, rtol=1e-5, atol=1e-7)
        assert level["coat_weight"] == pytest.approx(k / 16)
    # (the core's one coat per material covers both shaders at each level, noted)
    assert [w for w in ex.warnings if "'Wet ground'" in w and "different coats" not in w] == []


def test_a_specular_map_picks_levels_of_the_specular_ior_level(scene):
    """Specular IOR Level from a checker times 2 (0 or 2): the node at 17 levels from 0 to the map's
    largest value, 2, each the row a constant Specular IOR Level exports (the layer's Fresnel
    IOR and colour), the pick the map over 2; the row itself is the node at the map's mean; no
    note.  Under 1 the levels still reach 1 (an image's range)."""
    from amcmcppm.core import procedural
    mat = principled("Glaze", **{"Base Color": (0.2, 0.5, 0.3, 1.0)})
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    double = nt.nodes.new("ShaderNodeMath")
    double.operation = "MULTIPLY"
    double.inputs[1].default_value = 2.0
    nt.links.new(checker.outputs["Fac"], double.inputs[0])
    nt.links.new(double.outputs[0], nt.nodes["Principled BSDF"].inputs["Specular IOR Level"])
    row, ex = export_material(mat)
    assert row["level_count"] == 17
    assert not [w for w in ex.warnings if "'Glaze'" in w], ex.warnings
    pts = procedural.SampledAttributes(256)
    checker_fac = {"op": "checker", "vector": {"op": "attribute", "name": "generated"}, "scale": 5.0,
                   "color1": [1, 1, 1], "color2": [0, 0, 0], "output": "Fac"}
    fac = procedural.evaluate(checker_fac, pts, [])
    picks = procedural.evaluate(ex.scene.materials.programs[row["level_program"]], pts, [])
    np.testing.assert_allclose(picks, fac, atol=1e-6)
    levels = {k: material_row(ex.scene, f"Glaze (level {k}/16)") for k in (0, 4, 8, 16)}
    keys = ("glossy_weight", "glossy_color", "glossy_fresnel_ior", "glossy_fresnel_rise", "diffuse_layer",
            "diffuse_weight", "diffuse_color")
    for k, level in levels.items():
        bpy.data.objects.remove(bpy.data.objects["Plane"])
        plain, _ = export_material(principled(f"Plain {k}", **{"Base Color": (0.2, 0.5, 0.3, 1.0),
                                                                "Specular IOR Level": k / 8}))
        for key in keys:
            np.testing.assert_allclose(level[key], plain[key], rtol=1e-6, atol=1e-9, err_msg=f"{k} {key}")
    assert levels[0]["glossy_weight"] == 0
    assert levels[16]["glossy_fresnel_ior"] > levels[8]["glossy_fresnel_ior"]
    nt.links.new(checker.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Specular IOR Level"])
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    assert row["level_count"] == 17
    picks = procedural.evaluate(ex.scene.materials.programs[row["level_program"]], pts, [])
    np.testing.assert_allclose(picks, fac, atol=1e-6)
    assert material_row(ex.scene, "Glaze (level 8/16)")["glossy_fresnel_ior"] == pytest.approx(1.5)


def test_a_masks_levels_share_the_paints_texture(scene):
    """Mix Shader(Principled paint of a noise base colour, metal) by a noise mask: every level with a
    diffuse part has the paint's noise as its colour program, one program for all (the core evaluates
    a program once per batch; a program per level halved the photon pass,
    ``benchmarks/roughness_map_cost.py --kind mask``), and its weight times colour is (1 - k) times
    the paint's."""
    from amcmcppm.core import procedural
    mat = bpy.data.materials.new("Rusty paint")
    nt = mat.node_tree
    paint = nt.nodes["Principled BSDF"]
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Color"], paint.inputs["Base Color"])
    metal = nt.nodes.new("ShaderNodeBsdfPrincipled")
    metal.inputs["Metallic"].default_value = 1.0
    mask = nt.nodes.new("ShaderNodeTexNoise")
    mask.inputs["Scale"].default_value = 2.0
    bs.mix_shaders(nt, mask.outputs["Fac"], paint, metal)
    row, ex = export_material(mat)
    mats = ex.scene.materials
    first, count = row["level_first"], row["level_count"]
    assert count == 17
    programs = mats.diffuse_program[first:first + count]
    assert len(set(programs[:-1].tolist())) == 1 and programs[-1] == -1     # (level 16: the metal)
    pts = procedural.SampledAttributes(64)
    noise = procedural.evaluate(mats.programs[programs[0]], pts, [])
    for k in (1, 5, 15):
        level = material_row(ex.scene, f"Rusty paint (level {k}/16)")
        colour = level["diffuse_weight"] * level["diffuse_color"] * noise
        np.testing.assert_allclose(colour, (1 - k / 16) * noise, rtol=1e-9)


def test_color_attribute_of_a_mesh_without_one_is_black_and_a_named_layer_is_noted(scene):
    """The render colour attribute of a mesh without one reads black; a Color Attribute node that
    names a layer reads that layer (``Scene.attributes``, stop 39; before, the render one, noted),
    black on a mesh without it, and its Alpha 1 there (stop 42; before, the Alpha was noted)."""
    mat = bs.diffuse("Painted")
    nt = mat.node_tree
    attr = nt.nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Dirt"
    nt.links.new(attr.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    assert row["diffuse_program"] == 0
    assert ex.scene.vertex_colors is None and ex.scene.attributes is not None
    assert (ex.scene.attributes["Dirt"] == 0).all() and ex.scene.attributes["Dirt"].shape == (2, 3, 3)
    assert ex.scene.object_ids is None and ex.scene.uvs is None
    assert not any("'Painted'" in w for w in ex.warnings), ex.warnings
    scale = nt.nodes.new("ShaderNodeVectorMath")
    scale.operation = "SCALE"
    nt.links.new(attr.outputs["Color"], scale.inputs[0])
    nt.links.new(attr.outputs["Alpha"], scale.inputs["Scale"])
    nt.links.new(scale.outputs["Vector"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    assert (ex.scene.attributes[".alpha:Dirt"] == 1.0).all()
    assert not any("'Painted'" in w for w in ex.warnings), ex.warnings


def test_named_attributes_follow_each_mesh_and_instance(scene, tmp_path):
    """An Attribute node naming a point attribute that one mesh has and another lacks, the first
    also instanced mirrored: ``Scene.attributes`` holds each triangle's corner values (its mesh's
    values at its corners, the mirrored instance's corners swapped as its triangles are, zero on
    the mesh without it), and survives a scene file."""
    mat = bs.diffuse("Heat map")
    nt = mat.node_tree
    node = nt.nodes.new("ShaderNodeAttribute")
    node.attribute_name = "warmth"
    nt.links.new(node.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    hot = bs.plane("Hot", material=mat, location=(-3, 0, 0))
    values = np.array([0.1, 0.9, 0.4, 0.7], np.float32)
    hot.data.attributes.new("warmth", "FLOAT", "POINT").data.foreach_set("value", values)
    bs.plane("Cold", material=mat, location=(3, 0, 0))
    mirrored = bpy.data.objects.new("Mirror", hot.data)
    bpy.context.scene.collection.objects.link(mirrored)
    mirrored.location, mirrored.scale = (0, 4, 0), (-1, 1, 1)
    bs.camera()
    ex = bs.export()
    s = ex.scene
    attrs = s.attributes["warmth"]
    assert attrs.shape == (6, 3, 3)                                         # three planes
    np.testing.assert_array_equal(attrs[..., 0], attrs[..., 2])             # a float: x = y = z
    corners = s.vertices[s.triangles]                                        # (T, 3, 3) world
    local = hot.data.vertices
    for t in range(len(s.triangles)):
        centre = corners[t].mean(axis=0)
        origin = (-3, 0, 0) if centre[0] < -1 else (3, 0, 0) if centre[0] > 1 else (0, 4, 0)
        if origin == (3, 0, 0):
            assert not attrs[t].any()
            continue
        for c in range(3):
            p = corners[t, c] - origin
            if origin == (0, 4, 0):
                p[0] = -p[0]
            v = min(range(len(local)), key=lambda i: np.linalg.norm(np.array(local[i].co) - p))
            assert attrs[t, c, 0] == pytest.approx(values[v])
    s.save(tmp_path / "s.npz")
    back = type(s).load(tmp_path / "s.npz")
    np.testing.assert_array_equal(back.attributes["warmth"], attrs)
    assert not [w for w in ex.warnings if "Heat map" in w], ex.warnings


def test_a_metallic_map_mixes_the_principled_at_zero_and_one_and_picks_its_levels(scene):
    """Metallic from a checker's Fac: the material's own row (what the core keeps for what is decided
    before shading) mixes the diffuse colour point by point (the base colour where the checker is
    0, nothing where it is 1, divided by the mean diffuse weight) and the rest by the mean metal
    share; its levels, the node at 17 values of Metallic, follow it in the table and the checker
    picks one at each point (``Materials.level_program``), so no part is noted as averaged."""
    mat = principled("Rusty", **{"Base Color": (0.8, 0.4, 0.2, 1.0)})
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Metallic"])
    row, ex = export_material(mat)
    from amcmcppm.core import procedural
    pts = procedural.SampledAttributes(256)
    checker_fac = {"op": "checker", "vector": {"op": "attribute", "name": "generated"}, "scale": 5.0,
                   "color1": [1, 1, 1], "color2": [0, 0, 0], "output": "Fac"}
    m = procedural.evaluate(checker_fac, pts, [])
    mean = procedural.evaluate(checker_fac, procedural.SampledAttributes(), []).mean()   # the exporter's
    assert 0.3 < mean < 0.7
    assert row["diffuse_weight"] == pytest.approx(1 - mean)
    colour = procedural.evaluate(ex.scene.materials.programs[0], pts, [])
    np.testing.assert_allclose(colour * row["diffuse_weight"], (1 - m)[:, None] * [0.8, 0.4, 0.2], rtol=1e-5)
    assert not any("'Rusty'" in w and "Metallic" in w for w in ex.warnings), ex.warnings
    mats = ex.scene.materials
    i = mats.names.index("Rusty")
    assert row["level_first"] == i + 1 and row["level_count"] == 17
    picks = procedural.evaluate(mats.programs[row["level_program"]], pts, [])
    np.testing.assert_allclose(picks, m, atol=1e-6)
    levels = [material_row(ex.scene, f"Rusty (level {k}/16)") for k in (0, 8, 16)]
    assert [r["diffuse_weight"] for r in levels] == pytest.approx([1.0, 0.5, 0.0])
    assert [r["glossy_weight"] for r in levels] == pytest.approx([1.0, 1.0, 1.0])
    assert levels[0]["diffuse_color"] == pytest.approx([0.8, 0.4, 0.2])
    assert not levels[0]["glossy_metal_rise"].any() and levels[0]["glossy_fresnel_ior"] == pytest.approx(1.5)
    assert levels[2]["glossy_color"] == pytest.approx([0.8, 0.4, 0.2])
    assert levels[2]["glossy_fresnel_ior"] == 0
    np.testing.assert_allclose(levels[2]["glossy_metal_rise"], [0.2, 0.6, 0.8], rtol=1e-5)
    np.testing.assert_allclose(levels[1]["glossy_metal_rise"], [0.1, 0.3, 0.4], rtol=1e-5)   # half the lobe
    assert all(r["level_program"] == -1 for r in levels)
    # Mixed with a Diffuse BSDF at 0.5: the levels are mixed too; with a second metallic map: none.
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    diffuse = bs.mix_in(mat, "Principled BSDF", "ShaderNodeBsdfDiffuse", 0.5)
    row, ex = export_material(mat)
    level = material_row(ex.scene, "Rusty (level 16/16)")
    assert row["level_count"] == 17 and level["diffuse_weight"] == pytest.approx(0.5)
    assert level["glossy_weight"] == pytest.approx(0.5)
    nt.nodes.remove(diffuse)
    other = nt.nodes.new("ShaderNodeBsdfPrincipled")
    nt.links.new(other.outputs[0], nt.nodes["Mix Shader"].inputs[2])
    nt.links.new(checker.outputs["Color"], other.inputs["Metallic"])
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    assert row["level_program"] == -1 and row["level_count"] == 0
    assert any("'Mix Shader'" in w and "two shaders that both vary by a map" in w
               for w in ex.warnings), ex.warnings


def test_a_transmission_map_picks_levels_and_beside_a_metallic_map_takes_its_mean(scene):
    """Transmission Weight from a checker: levels of it as for a metallic map (glass at 1, the
    dielectric at 0).  With a metallic map too, the levels are Metallic's and each mixes its
    transmission by the map's mean, noted; no level has levels of its own."""
    mat = principled("Pane", **{"Base Color": (0.8, 0.8, 0.8, 1.0)})
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Transmission Weight"])
    row, ex = export_material(mat)
    assert row["level_count"] == 17 and row["dielectric_weight"] == pytest.approx(0.5, abs=0.2)
    first, last = (material_row(ex.scene, f"Pane (level {k}/16)") for k in (0, 16))
    assert first["dielectric_weight"] == 0 and first["diffuse_weight"] == pytest.approx(1.0)
    assert last["dielectric_weight"] == pytest.approx(1.0) and last["diffuse_weight"] == 0
    assert not any("'Pane'" in w and "Transmission" in w for w in ex.warnings), ex.warnings
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(gradient.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Metallic"])
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    row, ex = export_material(mat)
    mats = ex.scene.materials
    assert row["level_count"] == 17 and (mats.level_program >= 0).sum() == 1
    first = material_row(ex.scene, "Pane (level 0/16)")
    assert 0.2 < first["dielectric_weight"] < 0.8 and first["glossy_metal_rise"].sum() == 0
    assert any("'Pane'" in w and "varying Transmission Weight" in w for w in ex.warnings), ex.warnings


def test_unsupported_texture_nodes_are_named_and_replaced_by_the_sockets_value(scene):
    """(The Gabor Texture was the example until stop 42, which models it and Particle Info; now
    Curves Info's Tangent Normal, which stop 56 leaves out where it models the node's other
    outputs.)"""
    mat = bs.diffuse("Odd", (0.3, 0.4, 0.5))
    nt = mat.node_tree
    info = nt.nodes.new("ShaderNodeHairInfo")
    nt.links.new(info.outputs["Tangent Normal"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    assert row["diffuse_color"] == pytest.approx([0.3, 0.4, 0.5]) and row["diffuse_program"] == -1
    assert any("'Odd'" in w and "HairInfo" in w for w in ex.warnings), ex.warnings


def test_instances_get_their_own_object_coordinates(scene):
    """Two instances of one mesh, one mirrored: each triangle's object maps its world corners back
    to the same object-space corners, whatever the instance's placement."""
    mat = bs.diffuse("Cells")
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Object"], checker.inputs["Vector"])
    nt.links.new(checker.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    a = bs.plane("A", material=mat, location=(0, 0, 0))
    b = bpy.data.objects.new("B", a.data)
    b.location, b.scale = (4, 0, 1), (-2, 1, 1)
    bpy.context.scene.collection.objects.link(b)
    bs.camera()
    s = bs.export().scene
    assert len(s.triangles) == 4 and len(s.object_from_world) == 2
    world = s.vertices[s.triangles].astype(np.float64)                       # (4, 3, 3)
    local = np.einsum("tij,tcj->tci", s.object_from_world[s.object_ids][:, :, :3], world) \
        + s.object_from_world[s.object_ids][:, None, :, 3]
    shifted = np.abs(world[..., 0] - local[..., 0]).max(axis=1) > 1
    assert shifted.sum() == 2                       # B's triangles are elsewhere in the world ...
    key = lambda c: sorted(map(tuple, np.round(c.reshape(-1, 3), 5)))        # noqa: E731
    assert key(local[shifted]) == key(local[~shifted])                      # ... with A's object coords
    assert np.abs(local).max() == pytest.approx(1.0, abs=1e-6)


def normal_mapped(name, rgb=(0.7, 0.5, 0.9)):
    """A Principled material whose Normal input takes a tangent-space Normal Map (strength 0.7)
    of a constant image of colour ``rgb``."""
    mat = principled(name)
    bs.add_normal_map(mat, np.broadcast_to(2.0 * np.asarray(rgb) - 1.0, (4, 4, 3)), "Principled BSDF", 0.7)
    return mat


def uv_plane(name, material, **kw):
    """A 2 m plane in z = 0 whose UVs run along +x (u) and +y (v)."""
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")                 # calc_uvs fills an existing layer
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=1.0, calc_uvs=True)
    return bs.mesh_object(name, bm, material, **kw)


def test_island_and_pointiness_of_normal_mapped_ngons_come_from_the_mesh_itself(scene):
    """Random Per Island and Pointiness of a mesh with n-gons and a normal map (read from a
    triangulated copy, which has more edges): the same at every vertex as without the normal map
    (the mesh's own edges, as Cycles)."""
    def values(mapped):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        mat = normal_mapped("Bumpy") if mapped else principled("Bumpy")
        nt = mat.node_tree
        geometry = nt.nodes.new("ShaderNodeNewGeometry")
        nt.links.new(geometry.outputs["Random Per Island"], nt.nodes["Principled BSDF"].inputs["Roughness"])
        nt.links.new(geometry.outputs["Pointiness"], nt.nodes["Principled BSDF"].inputs["Metallic"])
        bm = bmesh.new()
        bm.loops.layers.uv.new("UVMap")
        for x in (-1.5, 1.5):
            bmesh.ops.create_circle(bm, cap_ends=True, segments=12, radius=1.0, calc_uvs=True,
                                    matrix=Matrix.Translation((x, 0.0, 0.1 * x)))
        for k, v in enumerate(bm.verts):                  # a wavy rim: the diagonals change the angles
            v.co.z += 0.3 * math.sin(2.0 * k)
        bs.mesh_object("Disks", bm, mat)
        bs.camera()
        s = bs.export().scene
        corners = s.vertices[s.triangles].reshape(-1, 3)
        out = {}
        for name in (".random_per_island", ".pointiness"):
            v = s.attributes[name][..., 0].reshape(-1)
            out[name] = {tuple(np.round(p, 4)): float(x) for p, x in zip(corners, v)}
        return out

    plain, mapped = values(False), values(True)
    for name in plain:
        assert plain[name].keys() == mapped[name].keys()
        for p, x in plain[name].items():
            assert mapped[name][p] == pytest.approx(x, abs=1e-6), (name, p)
    assert len(set(plain[".random_per_island"].values())) == 2                 # two islands


@pytest.mark.parametrize("transform, tangent, sign", [
    ({}, (1, 0, 0), 1.0),
    ({"rotation": (0, 0, math.pi / 2)}, (0, 1, 0), 1.0),          # turned: the tangent turns along
    ({"scale": (-1, 1, 1)}, (-1, 0, 0), -1.0),                    # mirrored: B = w (N x T) stays +y
    ({"scale": (3, 3, 3), "location": (1, 2, 0)}, (1, 0, 0), 1.0),
])
def test_normal_map_exports_the_image_strength_and_mikktspace_tangents(scene, transform, tangent, sign):
    mat = normal_mapped("Bumpy")
    uv_plane("Plane", mat, **transform)
    bs.camera()
    ex = bs.export()
    s = ex.scene
    row = material_row(s, "Bumpy")
    assert row["normal_texture"] == 0 and row["normal_strength"] == pytest.approx(0.7)
    assert row["diffuse_texture"] == -1
    # Stored as bytes (1/255 steps) and not linearised (sRGB would make 0.7 into 0.45).
    assert s.textures[0] == pytest.approx(np.broadcast_to([0.7, 0.5, 0.9], (4, 4, 3)), abs=2.5e-3)
    assert s.uvs is not None and s.tangents is not None and s.tangents.shape == (2, 3, 4)
    assert s.tangents[..., :3].reshape(-1, 3) == pytest.approx(np.tile(tangent, (6, 1)), abs=1e-5)
    assert s.tangents[..., 3] == pytest.approx(np.full((2, 3), sign))
    # The object's bitangent (its +v direction) in world space is w (N x T).
    n, _ = geometric_normals(s)
    b = sign * np.cross(n, np.asarray(tangent, float))
    v_world = np.array(Matrix(bpy.data.objects["Plane"].matrix_world).to_3x3() @ Vector((0, 1, 0)))
    assert b == pytest.approx(np.tile(v_world / np.linalg.norm(v_world), (2, 1)), abs=1e-5)
    assert not [w for w in ex.warnings if "Bumpy" in w]


def test_normal_mapped_ngons_are_read_from_a_triangulated_copy(scene):
    """Blender computes no tangents for meshes with n-gons: the exporter triangulates a copy."""
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_circle(bm, cap_ends=True, cap_tris=False, segments=12, radius=1.0, calc_uvs=True)
    ob = bs.mesh_object("Disk", bm, normal_mapped("Bumpy"))
    meshes = len(bpy.data.meshes)
    bs.camera()
    ex = bs.export()
    s = ex.scene
    assert s.triangle_count == 10 and not ex.warnings
    assert bs.triangle_areas(s).sum() == pytest.approx(6 * math.sin(math.pi / 6), rel=1e-5)   # 12-gon area
    t = s.tangents[..., :3].reshape(-1, 3)
    assert np.linalg.norm(t, axis=1) == pytest.approx(np.ones(30), abs=1e-5)
    assert np.abs(t[:, 2]).max() < 1e-5 and (np.abs(s.tangents[..., 3]) == 1).all()
    assert len(bpy.data.meshes) == meshes and len(ob.data.polygons) == 1      # copy removed, mesh kept


def test_normal_map_on_a_mesh_without_uvs_keeps_the_normal_and_an_unmapped_mesh_gets_zero_tangents(scene):
    bs.plane("NoUV", material=normal_mapped("Bumpy"))                 # create_grid without UVs
    uv_plane("Plain", bs.diffuse("Plain"), location=(3, 0, 0))
    bs.camera()
    s = bs.export().scene
    assert s.tangents is not None and (s.tangents == 0).all()     # no frame anywhere: unbent, as Cycles


@pytest.mark.parametrize("space", ["OBJECT", "WORLD", "BLENDER_WORLD"])
def test_object_and_world_space_normal_maps_reach_the_core(scene, space):
    """A Normal Map in object or world space: its image with ``Materials.normal_space`` (stop 41;
    before, noted and left out); it needs no tangents, the object's space the objects' transforms."""
    from amcmcppm.core.scene import NORMAL_BLENDER_WORLD, NORMAL_OBJECT, NORMAL_WORLD
    mat = normal_mapped("Spatial")
    mat.node_tree.nodes["Normal Map"].space = space
    uv_plane("Plane", mat)
    bs.camera()
    ex = bs.export()
    row = material_row(ex.scene, "Spatial")
    assert row["normal_texture"] >= 0 and not [w for w in ex.warnings if "Spatial" in w], ex.warnings
    assert row["normal_space"] == {"OBJECT": NORMAL_OBJECT, "WORLD": NORMAL_WORLD,
                                   "BLENDER_WORLD": NORMAL_BLENDER_WORLD}[space]
    assert ex.scene.tangents is None and (ex.scene.object_ids is not None) == (space == "OBJECT")


def test_a_normal_map_of_another_colour_is_a_program(scene):
    """A Normal Map whose colour is a constant or a procedural texture (stop 42; before, noted and
    the surface's own normal kept) is a program of the normal (``normal_program``, a ``normal_map``
    op), which needs the render UV map's tangents; the neutral colour bends nothing."""
    mat = normal_mapped("Odd")
    nt = mat.node_tree
    normal_map = nt.nodes["Normal Map"]
    nt.links.remove(normal_map.inputs["Color"].links[0])
    normal_map.inputs["Color"].default_value = (0.7, 0.5, 0.9, 1.0)
    uv_plane("Plane", mat)
    bs.camera()
    ex = bs.export()
    row = material_row(ex.scene, "Odd")
    program = ex.scene.materials.programs[row["normal_program"]]
    assert row["normal_texture"] == -1 and program["op"] == "normal_map" and program["space"] == "TANGENT"
    assert ex.scene.tangents is not None and not ex.warnings
    nt.links.new(nt.nodes.new("ShaderNodeTexChecker").outputs["Color"], normal_map.inputs["Color"])
    ex = bs.export()
    program = ex.scene.materials.programs[material_row(ex.scene, "Odd")["normal_program"]]
    assert program["color"]["op"] == "checker" and not ex.warnings
    nt.links.remove(normal_map.inputs["Color"].links[0])
    normal_map.inputs["Color"].default_value = (0.5, 0.5, 1.0, 1.0)
    row = material_row(bs.export().scene, "Odd")
    assert row["normal_program"] == -1 and row["normal_texture"] == -1


def test_a_normal_from_a_program_is_the_normal_program(scene):
    """A BSDF's Normal fed by nodes the programs know is ``Materials.normal_program`` (stop 40;
    before, unsupported and noted): a Bevel its op; a Vector Math of a direction that direction
    (Cycles takes a constant normal as given); one of zero nothing (Cycles falls back to the
    surface's own normal), all without a note; a Bump on a Bevel both, the bevel first."""
    from amcmcppm.core import procedural

    def material(name, build):
        mat = principled(name)
        nt = mat.node_tree
        nt.links.new(build(nt), nt.nodes["Principled BSDF"].inputs["Normal"])
        return mat

    def bevel(nt):
        node = nt.nodes.new("ShaderNodeBevel")
        node.inputs["Radius"].default_value, node.samples = 0.07, 6
        return node.outputs["Normal"]

    def direction(value):
        def build(nt):
            node = nt.nodes.new("ShaderNodeVectorMath")
            node.inputs[0].default_value = value
            return node.outputs[0]
        return build

    def bumped(nt):
        bump = nt.nodes.new("ShaderNodeBump")
        nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], bump.inputs["Height"])
        nt.links.new(bevel(nt), bump.inputs["Normal"])
        return bump.outputs["Normal"]

    mats = [material("Bevelled", bevel), material("Tilted", direction((0.0, 0.6, 0.8))),
            material("Zero", direction((0.0, 0.0, 0.0))), material("Bumped", bumped)]
    for k, mat in enumerate(mats):
        bs.plane(mat.name, material=mat, location=(3 * k, 0, 0))
    bs.camera()
    ex = bs.export()
    m = ex.scene.materials
    assert not [w for w in ex.warnings if any(x.name in w for x in mats)], ex.warnings
    rows = {x.name: material_row(ex.scene, x.name) for x in mats}
    bevelled = m.programs[rows["Bevelled"]["normal_program"]]
    assert bevelled["op"] == "bevel" and bevelled["samples"] == 6
    assert bevelled["radius"] == pytest.approx(0.07)
    points = procedural.SampledAttributes(4)
    tilted = procedural.evaluate(m.programs[rows["Tilted"]["normal_program"]], points, [])
    np.testing.assert_allclose(tilted, np.tile([0.0, 0.6, 0.8], (4, 1)), atol=1e-6)
    assert rows["Zero"]["normal_program"] == -1 and rows["Zero"]["bump_program"] == -1
    assert m.programs[rows["Bumped"]["normal_program"]]["op"] == "bevel"
    assert rows["Bumped"]["bump_program"] >= 0


def test_bump_of_a_noise_becomes_a_height_program(scene):
    """A Bump whose Height is a Noise's Fac: a bump program (no image, no UVs or tangents needed)
    with the node's strength and (inverted) distance."""
    mat = principled("Noisy")
    nt = mat.node_tree
    bump = nt.nodes.new("ShaderNodeBump")
    bump.invert = True
    bump.inputs["Strength"].default_value = 0.7
    bump.inputs["Distance"].default_value = 0.05
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Normal"])
    row, ex = export_material(mat)
    program = ex.scene.materials.programs[row["bump_program"]]
    assert program["op"] == "noise" and program["output"] == "Fac"
    assert row["bump_texture"] == -1 and row["bump_strength"] == pytest.approx(0.7)
    assert row["bump_distance"] == pytest.approx(-0.05)
    assert ex.scene.uvs is None and ex.scene.tangents is None and not ex.warnings


def test_a_bump_on_a_bump_is_the_outer_bump(scene):
    """A Bump whose Normal is another Bump (stop 41; before, noted and the outer one dropped): the
    inner one is the material's bump, the outer one ``outer_bump_program`` with its strength and
    distance; with a third in a row (stop 42; before, noted and left out) the chain is one program
    of the normal (``normal_program``, nested ``bump`` ops)."""
    mat = principled("Layered")
    nt = mat.node_tree

    def bump(height_node, distance, below=None):
        node = nt.nodes.new("ShaderNodeBump")
        node.inputs["Distance"].default_value = distance
        node.inputs["Strength"].default_value = 0.8
        nt.links.new(nt.nodes.new(height_node).outputs["Fac"], node.inputs["Height"])
        if below is not None:
            nt.links.new(below.outputs["Normal"], node.inputs["Normal"])
        return node

    inner = bump("ShaderNodeTexNoise", 0.05)
    outer = bump("ShaderNodeTexWave", 0.02, inner)
    nt.links.new(outer.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Normal"])
    row, ex = export_material(mat)
    programs = ex.scene.materials.programs
    assert programs[row["bump_program"]]["op"] == "noise" and row["bump_distance"] == pytest.approx(0.05)
    assert programs[row["outer_bump_program"]]["op"] == "wave"
    assert row["outer_bump_distance"] == pytest.approx(0.02)
    assert row["outer_bump_strength"] == pytest.approx(0.8)
    assert not ex.warnings
    third = bump("ShaderNodeTexChecker", 0.01, outer)
    nt.links.new(third.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Normal"])
    row, ex = export_material(mat)
    chain = ex.scene.materials.programs[row["normal_program"]]
    assert chain["op"] == "bump" and chain["height"]["op"] == "checker"
    assert chain["normal"]["op"] == "bump" and chain["normal"]["height"]["op"] == "wave"
    assert chain["normal"]["normal"]["height"]["op"] == "noise" and "normal" not in chain["normal"]["normal"]
    assert row["bump_program"] < 0 and row["outer_bump_program"] < 0 and not ex.warnings


@pytest.mark.parametrize("invert", [False, True])
def test_bump_node_exports_its_height_image_strength_and_distance_over_a_normal_map(scene, invert):
    mat = normal_mapped("Bumpy")
    nt = mat.node_tree
    img = bpy.data.images.new("Heights", 8, 2)
    bump = nt.nodes.new("ShaderNodeBump")
    bump.invert = invert
    bump.inputs["Strength"].default_value = 0.6
    bump.inputs["Distance"].default_value = 0.02
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nt.links.new(tex.outputs["Color"], bump.inputs["Height"])
    nt.links.new(nt.nodes["Normal Map"].outputs["Normal"], bump.inputs["Normal"])
    nt.links.new(bump.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Normal"])
    uv_plane("Plane", mat)
    bs.camera()
    ex = bs.export()
    row = material_row(ex.scene, "Bumpy")
    assert row["normal_texture"] == 0 and row["bump_texture"] == 1 and ex.scene.textures[1].shape == (2, 8, 3)
    assert row["bump_strength"] == pytest.approx(0.6)
    assert row["bump_distance"] == pytest.approx(-0.02 if invert else 0.02)
    assert ex.scene.tangents is not None and not [w for w in ex.warnings if "Bumpy" in w]


def test_bump_map_correction_off_reaches_the_core(scene):
    """Material > Settings > Bump Map Correction off (stop 42; before, noted and rendered on):
    ``Materials.bump_correction`` 0, no note; on (Blender's default), 1."""
    mat = normal_mapped("Sharp")
    mat.cycles.use_bump_map_correction = False
    uv_plane("Plane", mat)
    bs.camera()
    ex = bs.export()
    row = material_row(ex.scene, "Sharp")
    assert row["normal_texture"] == 0 and row["bump_correction"] == 0 and not ex.warnings
    uv_plane("Other", normal_mapped("Plain"))
    assert material_row(bs.export().scene, "Plain")["bump_correction"] == 1


def test_principled_mapping(scene):
    base = (0.8, 0.2, 0.1, 1.0)
    plain, _ = export_material(principled("Plastic", **{"Base Color": base, "Roughness": 0.3}))
    assert plain["diffuse_color"] == pytest.approx(base[:3])
    # Cycles' layering: a Fresnel layer (F0 0.04 of IOR 1.5, rising to 1) over the whole diffuse,
    # whose weight the core scales by 1 - the layer's albedo at the view.
    assert plain["diffuse_weight"] == pytest.approx(1.0) and plain["glossy_weight"] == pytest.approx(1.0)
    assert plain["glossy_color"] == pytest.approx(np.full(3, 0.04), rel=1e-5)
    assert plain["glossy_fresnel_ior"] == pytest.approx(1.5, rel=1e-5)
    assert plain["glossy_fresnel_rise"] == pytest.approx(np.full(3, 0.96), rel=1e-5)
    assert plain["diffuse_layer"] == pytest.approx(np.full(3, 0.04), rel=1e-5)
    assert plain["diffuse_layer_weight"] == pytest.approx(1.0)
    assert plain["glossy_roughness"] == pytest.approx(0.3)
    # Specular IOR Level 0.25 halves F0 (0.02), an IOR of 1.33; Specular Tint tints only F0.
    tint = (1.0, 0.5, 0.0, 1.0)
    half, _ = export_material(principled("Half", **{"Specular IOR Level": 0.25, "Specular Tint": tint}))
    assert half["glossy_fresnel_ior"] == pytest.approx((1 + 0.02 ** 0.5) / (1 - 0.02 ** 0.5), rel=1e-5)
    assert half["glossy_color"] == pytest.approx([0.02, 0.01, 0.0], rel=1e-4, abs=1e-7)
    assert half["glossy_fresnel_rise"] == pytest.approx([0.98, 0.99, 1.0], rel=1e-5)
    assert half["diffuse_layer"] == pytest.approx([0.02, 0.01, 0.0], rel=1e-4, abs=1e-7)
    # Mixed half and half with a plain Diffuse: half the diffuse lies under the layer.
    mixed = principled("Mixed")
    bs.mix_in(mixed, "Principled BSDF", "ShaderNodeBsdfDiffuse", 0.5)
    row, _ = export_material(mixed)
    assert row["diffuse_weight"] == pytest.approx(1.0) and row["glossy_weight"] == pytest.approx(0.5)
    assert row["diffuse_layer_weight"] == pytest.approx(0.5)
    assert row["diffuse_layer"] == pytest.approx(np.full(3, 0.04), rel=1e-5)
    metal, _ = export_material(principled("Metal", **{"Base Color": base, "Metallic": 1.0,
                                                      "Roughness": 0.0}))
    assert metal["glossy_weight"] == pytest.approx(1.0) and metal["diffuse_weight"] == 0
    assert metal["glossy_fresnel_ior"] == 0
    f0 = np.array(base[:3])
    # Cycles' F82 curve by angle: F0 + (1 - F0)(1 - c)^5, the white Specular Tint giving no dip.
    assert metal["glossy_color"] == pytest.approx(f0, rel=1e-6)
    assert metal["glossy_metal_rise"] == pytest.approx(1 - f0, rel=1e-6)
    assert metal["glossy_metal_dip"] == pytest.approx([0, 0, 0])
    assert metal["glossy_roughness"] == 0
    glass, _ = export_material(principled("Clear", **{"Transmission Weight": 1.0, "IOR": 1.33}))
    assert glass["dielectric_weight"] == pytest.approx(1.0) and glass["ior"] == pytest.approx(1.33)
    tinted, _ = export_material(principled("Bottle", **{"Transmission Weight": 1.0, "Base Color": base,
                                                        "Roughness": 0.2}))
    # Cycles: transmission tinted by sqrt(base colour) per interface, reflections by the specular tint.
    assert tinted["dielectric_color"] == pytest.approx(np.sqrt(base[:3]), rel=1e-6)
    assert tinted["dielectric_reflection_color"] == pytest.approx([1, 1, 1])
    assert tinted["dielectric_roughness"] == pytest.approx(0.2)
    no_spec, _ = export_material(principled("Matte", **{"Specular IOR Level": 0.0}))
    assert no_spec["diffuse_weight"] == pytest.approx(1.0) and no_spec["glossy_weight"] == 0
    lamp, _ = export_material(principled("Lamp", **{"Emission Color": (1, 0.5, 0.25, 1),
                                                    "Emission Strength": 4.0}))
    assert lamp["emission"] == pytest.approx([4, 2, 1])


def test_a_displacement_node_becomes_a_bump(scene):
    """Material Output > Displacement from a Displacement node: Cycles' default method (Bump Only)
    bends the normal as a Bump of Distance = Scale (a Vector Displacement by its offset along the
    normal).  The other
    methods (stop 42; before, noted and rendered as the bump) move the vertices by
    ``displacement_program``, Displacement and Bump with the bump too.  A shader's own Bump (stop
    42; before, the displacement was noted and dropped) bends the displaced normal: the
    displacement is the bump, the shader's the outer bump (an image's height as a program of its
    luminance); beside a Bump on a Bump it is noted."""
    mat = bs.diffuse("Bumpy")
    nt = mat.node_tree
    disp = nt.nodes.new("ShaderNodeDisplacement")
    disp.inputs["Scale"].default_value = 0.3
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], disp.inputs["Height"])
    nt.links.new(disp.outputs["Displacement"], nt.nodes["Material Output"].inputs["Displacement"])
    row, ex = export_material(mat)
    assert row["bump_program"] >= 0 and row["bump_strength"] == pytest.approx(1.0)
    assert row["bump_distance"] == pytest.approx(0.3)
    assert not [w for w in ex.warnings if "'Bumpy'" in w], ex.warnings
    assert row["displacement_program"] < 0
    # True displacement (stop 42; before, noted and rendered as the bump): (Height - Midlevel) Scale.
    disp.space = "WORLD"
    for method, bumped, flags in (("BOTH", True, DISPLACE_WORLD | DISPLACE_KEEPS_NORMALS),
                                  ("DISPLACEMENT", False, DISPLACE_WORLD)):
        mat.displacement_method = method
        row, ex = export_material(mat)
        assert (row["bump_program"] >= 0) == bumped and row["displacement_flags"] == flags
        offset = ex.scene.materials.programs[row["displacement_program"]]
        assert offset["operation"] == "MULTIPLY" and offset["b"] == pytest.approx(0.3)
        assert offset["a"]["a"]["op"] == "noise" and offset["a"]["b"] == pytest.approx(0.5)
        assert not [w for w in ex.warnings if "'Bumpy'" in w], ex.warnings
    disp.space = "OBJECT"
    mat.displacement_method = "BUMP"
    bump = nt.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.05
    image = nt.nodes.new("ShaderNodeTexImage")
    image.image = bpy.data.images.new("Height", 4, 4)
    nt.links.new(image.outputs["Color"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], nt.nodes["Diffuse BSDF"].inputs["Normal"])
    row, ex = export_material(mat)
    programs = ex.scene.materials.programs
    assert programs[row["bump_program"]]["op"] == "noise" and row["bump_distance"] == pytest.approx(0.3)
    outer = programs[row["outer_bump_program"]]
    assert outer["op"] == "gray" and outer["color"]["op"] == "image"
    assert outer["color"]["texture"] >= 0 and row["outer_bump_distance"] == pytest.approx(0.05)
    assert not ex.warnings
    on_top = nt.nodes.new("ShaderNodeBump")
    nt.links.new(bump.outputs["Normal"], on_top.inputs["Normal"])
    nt.links.new(nt.nodes.new("ShaderNodeTexWave").outputs["Fac"], on_top.inputs["Height"])
    nt.links.new(on_top.outputs["Normal"], nt.nodes["Diffuse BSDF"].inputs["Normal"])
    row, ex = export_material(mat)
    assert row["bump_texture"] >= 0 and ex.scene.materials.programs[row["outer_bump_program"]]["op"] == "wave"
    assert any("Displacement output is ignored" in w for w in ex.warnings), ex.warnings
    # A Vector Displacement (stop 42; before, noted and ignored): its offset along the normal as a
    # bump of distance 1, or the world offset itself (DISPLACE_VECTOR) for the other methods.
    flat = bs.diffuse("Flat")
    nt = flat.node_tree
    vector = nt.nodes.new("ShaderNodeVectorDisplacement")
    vector.space = "WORLD"
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Color"], vector.inputs["Vector"])
    nt.links.new(vector.outputs[0], nt.nodes["Material Output"].inputs["Displacement"])
    row, ex = export_material(flat)
    height = ex.scene.materials.programs[row["bump_program"]]
    assert height["operation"] == "DOT_PRODUCT" and height["b"] == {"op": "attribute", "name": "world_normal"}
    assert row["bump_distance"] == 1.0 and row["displacement_program"] < 0
    assert not [w for w in ex.warnings if "'Flat'" in w], ex.warnings
    flat.displacement_method = "DISPLACEMENT"
    row, ex = export_material(flat)
    offset = ex.scene.materials.programs[row["displacement_program"]]
    assert row["displacement_flags"] == DISPLACE_WORLD | DISPLACE_VECTOR and row["bump_program"] < 0
    assert offset["operation"] == "SCALE" and offset["a"]["a"]["op"] == "noise"
    assert not [w for w in ex.warnings if "'Flat'" in w], ex.warnings


def test_muted_nodes_pass_their_internal_links_through(scene):
    """Cycles' muting: a muted Mix Shader passes its first shader, a muted Invert what feeds its
    colour, a muted BSDF nothing (black); before stop 37 each was an unsupported node rendered
    grey. A run of muted nodes and reroutes that ends in an unlinked input passes nothing, and the
    socket it feeds keeps its own value (Cycles drops the link: a ball under a muted Checker, a
    muted Invert or a dangling reroute renders in its Base Color, stop 76; before, the Checker's
    Color1 and the Invert's colour came through, as Blender's UI shows them)."""
    mixed = bs.diffuse("Mixed", (0.2, 0.4, 0.6))
    bs.mix_in(mixed, "Diffuse BSDF", "ShaderNodeBsdfGlossy", 0.7)
    mixed.node_tree.nodes["Mix Shader"].mute = True
    row, ex = export_material(mixed)
    assert row["diffuse_color"] == pytest.approx([0.2, 0.4, 0.6]) and row["diffuse_weight"] == 1
    assert row["glossy_weight"] == 0 and not [w for w in ex.warnings if "'Mixed'" in w], ex.warnings
    inverted = bs.diffuse("Inverted", (0.3, 0.6, 0.2))
    nt = inverted.node_tree
    diffuse = nt.nodes["Diffuse BSDF"]
    invert = nt.nodes.new("ShaderNodeInvert")
    invert.inputs["Color"].default_value = (0.9, 0.5, 0.1, 1)
    invert.mute = True
    nt.links.new(invert.outputs["Color"], diffuse.inputs["Color"])
    row, _ = export_material(inverted)
    assert row["diffuse_color"] == pytest.approx([0.3, 0.6, 0.2])
    invert.mute = False
    row, _ = export_material(inverted)
    assert row["diffuse_color"] == pytest.approx([0.1, 0.5, 0.9])
    rgb = nt.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.7, 0.1, 0.4, 1)
    nt.links.new(rgb.outputs[0], invert.inputs["Color"])
    invert.mute = True
    row, _ = export_material(inverted)
    assert row["diffuse_color"] == pytest.approx([0.7, 0.1, 0.4])
    checker = nt.nodes.new("ShaderNodeTexChecker")       # muted Invert <- muted Checker, unlinked
    nt.links.new(checker.outputs["Color"], invert.inputs["Color"])
    checker.mute = True
    row, _ = export_material(inverted)
    assert row["diffuse_color"] == pytest.approx([0.3, 0.6, 0.2])
    reroute = nt.nodes.new("NodeReroute")                # a dangling reroute
    nt.links.new(reroute.outputs[0], diffuse.inputs["Color"])
    row, _ = export_material(inverted)
    assert row["diffuse_color"] == pytest.approx([0.3, 0.6, 0.2])
    textured = bs.diffuse("Textured")                    # a Vector by a muted Mapping, unlinked
    nt = textured.node_tree
    checker, mapping = nt.nodes.new("ShaderNodeTexChecker"), nt.nodes.new("ShaderNodeMapping")
    nt.links.new(checker.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    nt.links.new(mapping.outputs[0], checker.inputs["Vector"])
    mapping.mute = True
    row, ex = export_material(textured)
    program = ex.scene.materials.programs[row["diffuse_program"]]
    assert program["vector"] == {"op": "attribute", "name": "generated"}
    black = bs.diffuse("Muted")
    black.node_tree.nodes["Diffuse BSDF"].mute = True
    row, ex = export_material(black)
    assert row["diffuse_weight"] == 0 and row["glossy_weight"] == 0 and not row["emission"].any()


def test_a_subsurface_scattering_bsdf_scatters_beneath_its_surface(scene):
    """The Subsurface Scattering BSDF (stop 44; before, a diffuse of its colour, noted): a diffuse
    lobe of its colour that scatters beneath the surface whole, the radius times Scale, Cycles'
    clamps on the IOR and anisotropy, its Roughness the entry's alpha itself; Skin by the falloff;
    Christensen-Burley noted (rendered as Random Walk).  The scene then carries its objects (the
    walks stay inside theirs)."""
    mat = bs._material("Skin", "ShaderNodeSubsurfaceScattering", **{"Color": (0.8, 0.5, 0.4, 1.0),
                                                                     "Scale": 0.2, "IOR": 5.0,
                                                                     "Anisotropy": 0.95, "Roughness": 0.3})
    row, ex = export_material(mat)
    assert row["diffuse_color"] == pytest.approx([0.8, 0.5, 0.4]) and row["diffuse_weight"] == 1
    assert row["subsurface_weight"] == 1 and row["subsurface_method"] == SUBSURFACE_RANDOM_WALK
    assert row["subsurface_radius"] == pytest.approx([0.2, 0.04, 0.02])
    assert row["subsurface_ior"] == pytest.approx(3.8) and row["subsurface_anisotropy"] == pytest.approx(0.9)
    assert row["subsurface_alpha"] == pytest.approx(0.3)
    assert not [w for w in ex.warnings if "'Skin'" in w], ex.warnings
    assert ex.scene.object_ids is not None
    mat = bs._material("Skin 2", "ShaderNodeSubsurfaceScattering")
    mat.node_tree.nodes["Subsurface Scattering"].falloff = "RANDOM_WALK_SKIN"
    row, _ = export_material(mat)
    assert row["subsurface_method"] == SUBSURFACE_SKIN
    mat = bs._material("Skin 3", "ShaderNodeSubsurfaceScattering")
    mat.node_tree.nodes["Subsurface Scattering"].falloff = "BURLEY"
    row, ex = export_material(mat)
    assert row["subsurface_weight"] == 1
    assert any("'Subsurface Scattering'" in w and "Christensen-Burley" in w for w in ex.warnings), ex.warnings


def test_principled_subsurface_reaches_the_core(scene):
    """Principled's Subsurface (stop 44; before, noted and rendered as diffuse): its Weight is the
    share of the diffuse lobe that scatters beneath, Radius times Scale the radii; Random Walk takes
    the Principled's IOR and its roughness squared for the entry, Skin the Subsurface IOR; a metallic
    part keeps its own lobe (the share is of the diffuse lobe alone)."""
    row, ex = export_material(principled("Wax", **{"Subsurface Weight": 0.5, "Subsurface Scale": 0.1,
                                                   "Subsurface Radius": (1.0, 0.5, 0.25), "Roughness": 0.4,
                                                   "IOR": 1.45, "Metallic": 0.5}))
    assert row["subsurface_weight"] == pytest.approx(0.5) and row["diffuse_weight"] == pytest.approx(0.5)
    assert row["subsurface_radius"] == pytest.approx([0.1, 0.05, 0.025])
    assert row["subsurface_ior"] == pytest.approx(1.45) and row["subsurface_alpha"] == pytest.approx(0.16)
    assert not [w for w in ex.warnings if "'Wax'" in w], ex.warnings
    mat = principled("Skin", **{"Subsurface Weight": 1.0})
    mat.node_tree.nodes["Principled BSDF"].subsurface_method = "RANDOM_WALK_SKIN"
    mat.node_tree.nodes["Principled BSDF"].inputs["Subsurface IOR"].default_value = 1.33    # (shown for Skin)
    row, _ = export_material(mat)
    assert row["subsurface_method"] == SUBSURFACE_SKIN and row["subsurface_ior"] == pytest.approx(1.33)
    row, _ = export_material(principled("Plastic"))
    assert row["subsurface_weight"] == 0


def test_principled_sheen_subsurface_and_anisotropy_export_without_a_warning(scene):
    """Every Principled input has a model (the Sheen was noted as not supported before)."""
    _, ex = export_material(principled("Paint", **{"Sheen Weight": 0.2, "Subsurface Weight": 0.1,
                                                   "Anisotropic": 0.5}))
    assert not [w for w in ex.warnings if "'Paint'" in w], ex.warnings
    _, ex = export_material(principled("Plain"))
    assert not [w for w in ex.warnings if "'Plain'" in w]


def test_a_principled_thin_film_reaches_the_core_on_its_specular_layer(scene):
    """Thin Film Thickness over Cycles' cut-off of 0.1 nm gives the layer its film (thickness,
    IOR, the specular tint) without a note (stop 43; before, noted and left out); on a layer of
    IOR 1, which Cycles drops without a film, the film keeps it.  A transmissive one's glass takes
    the same film and reflects white (the tint scales the film's colour instead).  A film on the
    metallic part takes it too (``film_metal``, its share of the glossy lobe), as a Metallic BSDF's
    (F82, or a Physical Conductor's by its complex index since stop 45: before, noted and left
    out) and a Glass BSDF's (untinted)."""
    row, ex = export_material(principled("Oil", **{"Thin Film Thickness": 480.0, "Thin Film IOR": 1.4,
                                                   "Specular Tint": (1.0, 0.5, 0.25, 1.0)}))
    assert row["film_thickness"] == pytest.approx(480.0) and row["film_ior"] == pytest.approx(1.4)
    assert row["film_tint"] == pytest.approx([1.0, 0.5, 0.25])
    assert row["glossy_fresnel_ior"] == pytest.approx(1.5)
    assert not [w for w in ex.warnings if "'Oil'" in w]
    row, _ = export_material(principled("Soap", **{"IOR": 1.0, "Thin Film Thickness": 300.0}))
    assert row["glossy_fresnel_ior"] == pytest.approx(1.0) and row["glossy_weight"] > 0
    assert row["film_thickness"] == pytest.approx(300.0)
    row, _ = export_material(principled("Bare", **{"IOR": 1.0, "Thin Film Thickness": 0.1}))
    assert row["glossy_weight"] == 0 and row["film_thickness"] == 0
    row, ex = export_material(principled("Bubble", **{"Transmission Weight": 1.0,
                                                      "Thin Film Thickness": 500.0,
                                                      "Specular Tint": (1.0, 0.5, 0.25, 1.0)}))
    assert row["dielectric_weight"] == 1 and row["film_thickness"] == pytest.approx(500.0)
    assert row["dielectric_reflection_color"] == pytest.approx([1.0, 1.0, 1.0])
    assert row["film_tint"] == pytest.approx([1.0, 0.5, 0.25])
    assert not [w for w in ex.warnings if "'Bubble'" in w]
    row, ex = export_material(principled("Foil", **{"Metallic": 0.5, "Thin Film Thickness": 300.0}))
    assert row["film_metal"] == pytest.approx(0.5 / (0.5 + 0.5))
    assert row["film_thickness"] == pytest.approx(300.0)
    assert not [w for w in ex.warnings if "'Foil'" in w]
    row, _ = export_material(bs._material("Foil BSDF", "ShaderNodeBsdfMetallic",
                                          **{"Thin Film Thickness": 300.0}))
    assert row["film_metal"] == 1.0 and row["film_thickness"] == pytest.approx(300.0)
    mat = bs._material("Conductor", "ShaderNodeBsdfMetallic", **{"Thin Film Thickness": 300.0})
    node = mat.node_tree.nodes["Metallic BSDF"]
    node.fresnel_type = "PHYSICAL_CONDUCTOR"
    row, ex = export_material(mat)
    assert row["film_metal"] == 1.0 and row["film_thickness"] == pytest.approx(300.0)
    assert row["film_metal_ior"] == pytest.approx(node.inputs["IOR"].default_value[:3])
    assert row["film_metal_extinction"] == pytest.approx(node.inputs["Extinction"].default_value[:3])
    assert not [w for w in ex.warnings if "'Conductor'" in w], ex.warnings
    row, _ = export_material(bs._material("Bare conductor", "ShaderNodeBsdfMetallic"))
    assert row["film_metal"] == 0 and not row["film_metal_ior"].any()
    row, ex = export_material(bs._material("Pane", "ShaderNodeBsdfGlass", **{"Thin Film Thickness": 300.0,
                                                                             "Thin Film IOR": 1.4}))
    assert row["film_thickness"] == pytest.approx(300.0) and row["film_ior"] == pytest.approx(1.4)
    assert row["film_tint"] == pytest.approx([1.0, 1.0, 1.0])
    assert not [w for w in ex.warnings if "Pane" in w]


def test_principled_coat_is_exported_with_cycles_clamps(scene):
    """Coat Weight, Roughness, IOR and Tint reach the core (weight and tint saturated, the IOR at
    least 1, as Cycles); no coat without weight.  A Bump on the Coat Normal (stop 42; before,
    noted and left out) bends the coat alone (``coat_bump_program``); a Bump over a Normal Map's
    image or on a Bump, as one program of the normal.  A Displacement output bends an unlinked
    Coat Normal too (Cycles' Bump Only)."""
    row, ex = export_material(principled("Varnish", **{"Coat Weight": 0.7, "Coat Roughness": 0.2,
                                                       "Coat IOR": 1.8, "Coat Tint": (1.2, 0.5, 0.25, 1)}))
    assert row["coat_weight"] == pytest.approx(0.7) and row["coat_roughness"] == pytest.approx(0.2)
    assert row["coat_ior"] == pytest.approx(1.8) and row["coat_tint"] == pytest.approx([1.0, 0.5, 0.25])
    assert not [w for w in ex.warnings if "'Varnish'" in w]
    row, _ = export_material(principled("Low", **{"Coat Weight": 0.5, "Coat IOR": 0.5}))
    assert row["coat_ior"] == pytest.approx(1.0)
    # The coat's tint tints the coat only: the specular layer and a metal keep the Specular Tint
    # (the Coat Tint took its place before).
    for metallic in (0.0, 1.0):
        row, _ = export_material(principled("Tinted", **{"Coat Weight": 0.5, "Coat Tint": (0.2, 0.4, 1.0, 1),
                                                         "Specular Tint": (1.0, 0.5, 0.25, 1),
                                                         "Metallic": metallic}))
        assert row["coat_tint"] == pytest.approx([0.2, 0.4, 1.0])
        if metallic:
            b = (0.8 + 0.2 * (6 / 7) ** 5) * 7 / (6 / 7) ** 6 * np.array([0.0, 0.5, 0.75])
            assert row["glossy_metal_dip"] == pytest.approx(b, rel=1e-5)
        else:
            assert row["diffuse_layer"] == pytest.approx([0.04, 0.02, 0.01], rel=1e-4)
    row, _ = export_material(principled("Bare"))
    assert row["coat_weight"] == 0
    mat = principled("Bumped", **{"Coat Weight": 1.0})
    nt = mat.node_tree
    bump = nt.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.04
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Coat Normal"])
    row, ex = export_material(mat)
    programs = ex.scene.materials.programs
    assert programs[row["coat_bump_program"]]["op"] == "noise"
    assert row["coat_bump_distance"] == pytest.approx(0.04) and row["coat_normal_program"] < 0
    assert row["bump_program"] < 0 and row["bump_texture"] < 0 and not ex.warnings
    normal_map = nt.nodes.new("ShaderNodeNormalMap")
    image = nt.nodes.new("ShaderNodeTexImage")
    image.image = bpy.data.images.new("Normals", 4, 4)
    nt.links.new(image.outputs["Color"], normal_map.inputs["Color"])
    nt.links.new(normal_map.outputs["Normal"], bump.inputs["Normal"])
    row, ex = export_material(mat)
    chain = ex.scene.materials.programs[row["coat_normal_program"]]
    assert chain["op"] == "bump" and chain["normal"]["op"] == "normal_map"
    assert chain["normal"]["color"]["op"] == "image" and row["normal_texture"] < 0
    assert row["coat_bump_program"] < 0 and not ex.warnings
    outer = nt.nodes.new("ShaderNodeBump")
    nt.links.new(nt.nodes.new("ShaderNodeTexWave").outputs["Fac"], outer.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], outer.inputs["Normal"])
    nt.links.new(outer.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Coat Normal"])
    nt.links.remove(normal_map.outputs["Normal"].links[0])
    row, ex = export_material(mat)
    chain = ex.scene.materials.programs[row["coat_normal_program"]]
    assert chain["op"] == "bump" and chain["height"]["op"] == "wave" and chain["normal"]["op"] == "bump"
    assert row["coat_bump_program"] < 0 and not ex.warnings
    displaced = principled("Displaced", **{"Coat Weight": 1.0})
    nt = displaced.node_tree
    disp = nt.nodes.new("ShaderNodeDisplacement")
    disp.inputs["Scale"].default_value = 0.3
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], disp.inputs["Height"])
    nt.links.new(disp.outputs["Displacement"], nt.nodes["Material Output"].inputs["Displacement"])
    row, ex = export_material(displaced)
    assert row["coat_bump_program"] == row["bump_program"] >= 0
    assert row["coat_bump_distance"] == row["bump_distance"] == pytest.approx(0.3)


def test_principled_sheen_is_a_layer_of_weight_times_tint(scene):
    """Principled's Sheen: the core's sheen of colour Sheen Weight times Sheen Tint and the Sheen
    Roughness, which dims the rest of the node by 1 - k E(mu), k the largest channel of that
    colour (Cycles' closure_layering_weight); no warning.  Cycles' clamps: the weight and tint at
    least 0, the roughness saturated, no sheen of weight at most 1e-5.  The Alpha's Transparent
    part leaves the sheen of the opaque part as it is."""
    row, ex = export_material(principled("Velvet", **{"Sheen Weight": 0.8, "Sheen Tint": (1.0, 0.5, 0.25, 1),
                                                      "Sheen Roughness": 0.3}))
    assert row["sheen_color"] == pytest.approx([0.8, 0.4, 0.2])
    assert row["sheen_roughness"] == pytest.approx(0.3) and row["sheen_cover"] == pytest.approx(0.8)
    assert row["diffuse_weight"] == pytest.approx(1.0)             # (the rest stays, the core dims it)
    assert not [w for w in ex.warnings if "'Velvet'" in w], ex.warnings
    row, ex = export_material(principled("Bare", **{"Sheen Weight": 0.0, "Sheen Tint": (1.0, 0.5, 0.25, 1)}))
    assert not row["sheen_color"].any() and row["sheen_cover"] == 0
    assert row["sheen_roughness"] == pytest.approx(0.5)
    assert not [w for w in ex.warnings if "'Bare'" in w], ex.warnings
    row, _ = export_material(principled("Faint", **{"Sheen Weight": 1e-6}))
    assert not row["sheen_color"].any() and row["sheen_cover"] == 0
    row, _ = export_material(principled("Clamped", **{"Sheen Weight": 2.0, "Sheen Tint": (0.5, -1.0, 0.25, 1),
                                                      "Sheen Roughness": 1.5}))
    assert row["sheen_color"] == pytest.approx([1.0, 0.0, 0.5]) and row["sheen_cover"] == pytest.approx(1.0)
    assert row["sheen_roughness"] == pytest.approx(1.0)
    row, _ = export_material(principled("Sheer", **{"Sheen Weight": 0.8, "Alpha": 0.5}))
    assert row["opacity"] == pytest.approx(0.5)
    assert row["sheen_color"] == pytest.approx([0.8, 0.8, 0.8]) and row["sheen_cover"] == pytest.approx(0.8)


def test_a_sheen_bsdf_is_a_sheen_without_a_layer(scene):
    """The Sheen BSDF: a sheen of its Color and Roughness alone (no other lobe), which dims nothing
    (k = 0: not a layer).  Its Ashikhmin distribution (Cycles' older velvet) renders as Microfiber,
    named in the material's warning."""
    row, ex = export_material(bs._material("Fuzz", "ShaderNodeBsdfSheen", Color=(0.2, 0.4, 0.6, 1),
                                           Roughness=0.7))
    assert row["sheen_color"] == pytest.approx([0.2, 0.4, 0.6])
    assert row["sheen_roughness"] == pytest.approx(0.7) and row["sheen_cover"] == 0
    assert row["diffuse_weight"] == 0 and row["glossy_weight"] == 0 and row["opacity"] == pytest.approx(1.0)
    assert not [w for w in ex.warnings if "'Fuzz'" in w], ex.warnings
    mat = bs._material("Old velvet", "ShaderNodeBsdfSheen", Color=(0.2, 0.4, 0.6, 1), Roughness=0.7)
    mat.node_tree.nodes["Sheen BSDF"].distribution = "ASHIKHMIN"
    row, ex = export_material(mat)
    assert row["sheen_color"] == pytest.approx([0.2, 0.4, 0.6])
    assert row["sheen_roughness"] == pytest.approx(0.7)
    warnings = [w for w in ex.warnings if "'Old velvet'" in w]
    assert len(warnings) == 1 and "'Sheen BSDF'" in warnings[0] and "Ashikhmin" in warnings[0]
    assert "Microfiber" in warnings[0]


def _two_shaders(name, kind, first, second, fac=0.5):
    """A material whose surface is a Mix (``fac``) or Add Shader (``kind``) of nodes ``first`` and
    ``second`` ((bl_idname, {input: value}) each); the material and the two nodes."""
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    join = nt.nodes.new(kind)
    if kind == "ShaderNodeMixShader":
        join.inputs["Fac"].default_value = fac
    nodes = []
    for slot, (node_type, inputs) in zip(("Shader", "Shader_001"), (first, second)):
        node = nt.nodes.new(node_type)
        for key, value in inputs.items():
            node.inputs[key].default_value = value
        nt.links.new(node.outputs[0], next(s for s in join.inputs if s.identifier == slot))
        nodes.append(node)
    nt.links.new(join.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat, nodes


def test_mixed_sheens_take_their_shares(scene):
    """A Mix or Add scales a sheen's colour and its layer's k by the shader's share (the core dims the
    whole material by that k: exact for alike shaders); sheens of different roughness take their
    mean weighted by their colours' means; a Sheen BSDF adds no layer."""
    sheen = {"Sheen Weight": 0.8, "Sheen Tint": (1.0, 0.5, 0.25, 1), "Sheen Roughness": 0.3}
    mat, _ = _two_shaders("Half velvet", "ShaderNodeMixShader", ("ShaderNodeBsdfPrincipled", sheen),
                          ("ShaderNodeBsdfDiffuse", {}), fac=0.25)
    row, _ = export_material(mat)
    assert row["sheen_color"] == pytest.approx(0.75 * np.array([0.8, 0.4, 0.2]))
    assert row["sheen_cover"] == pytest.approx(0.75 * 0.8) and row["sheen_roughness"] == pytest.approx(0.3)
    mat, _ = _two_shaders("Velvet and fuzz", "ShaderNodeAddShader", ("ShaderNodeBsdfPrincipled", sheen),
                          ("ShaderNodeBsdfSheen", {"Color": (0.2, 0.2, 0.2, 1), "Roughness": 0.9}))
    row, _ = export_material(mat)
    assert row["sheen_color"] == pytest.approx([1.0, 0.6, 0.4]) and row["sheen_cover"] == pytest.approx(0.8)
    w = np.mean([0.8, 0.4, 0.2]), 0.2
    assert row["sheen_roughness"] == pytest.approx((w[0] * 0.3 + w[1] * 0.9) / sum(w))
    mat, _ = _two_shaders("Two velvets", "ShaderNodeAddShader", ("ShaderNodeBsdfPrincipled", sheen),
                          ("ShaderNodeBsdfPrincipled", {**sheen, "Sheen Weight": 0.4}))
    row, _ = export_material(mat)
    assert row["sheen_color"] == pytest.approx(1.5 * np.array([0.8, 0.4, 0.2]))
    assert row["sheen_cover"] == pytest.approx(0.8 + 0.4)


def test_a_mask_between_a_sheen_and_none_picks_the_two_shaders(scene):
    """Mix Shader by a checker of a bare and a velvet Principled BSDF: the core dims the whole
    material by its one sheen layer, so mixes at the mask's levels would dim the bare one too; the
    two shaders themselves are the levels (each exact), the mask picking one at each point."""
    mat = principled("Worn velvet")
    nt = mat.node_tree
    velvet = nt.nodes.new("ShaderNodeBsdfPrincipled")
    velvet.inputs["Sheen Weight"].default_value = 0.8
    bs.mix_shaders(nt, nt.nodes.new("ShaderNodeTexChecker").outputs["Fac"], nt.nodes["Principled BSDF"],
                   velvet)
    row, ex = export_material(mat)
    assert row["level_count"] == 2
    levels = [material_row(ex.scene, f"Worn velvet (level {k}/1)") for k in (0, 1)]
    assert [r["sheen_cover"] for r in levels] == pytest.approx([0.0, 0.8])
    assert levels[1]["sheen_color"] == pytest.approx([0.8, 0.8, 0.8]) and not levels[0]["sheen_color"].any()


def test_a_textured_sheen_takes_its_means(scene):
    """Textures on the Sheen Weight, Tint and Roughness (and the Sheen BSDF's Color and Roughness)
    give the sheen their means, each named in the material's warning."""
    mat = principled("Patchy", **{"Sheen Weight": 1.0, "Sheen Roughness": 0.3})
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")         # (0.8 and 0.2: a mean near 0.5)
    nt.links.new(checker.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Sheen Tint"])
    nt.links.new(checker.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Sheen Roughness"])
    nt.links.new(checker.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Sheen Weight"])
    row, ex = export_material(mat)
    assert row["sheen_color"] == pytest.approx([0.25, 0.25, 0.25], abs=0.05)     # (mean weight x mean tint)
    assert row["sheen_cover"] == pytest.approx(row["sheen_color"].max())
    assert row["sheen_roughness"] == pytest.approx(0.5, abs=0.05)
    warnings = [w for w in ex.warnings if "'Patchy'" in w]
    assert len(warnings) == 1 and "Sheen Tint varies over the surface" in warnings[0]
    assert "Sheen Weight varies over the surface" in warnings[0]
    assert "Sheen Roughness varies over the surface" in warnings[0] and "using its mean" in warnings[0]
    mat = bs._material("Patchy fuzz", "ShaderNodeBsdfSheen")
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Color"], nt.nodes["Sheen BSDF"].inputs["Color"])
    nt.links.new(checker.outputs["Fac"], nt.nodes["Sheen BSDF"].inputs["Roughness"])
    row, ex = export_material(mat)
    assert row["sheen_color"] == pytest.approx([0.5, 0.5, 0.5], abs=0.05)
    assert row["sheen_roughness"] == pytest.approx(0.5, abs=0.05) and row["sheen_cover"] == 0
    warnings = [w for w in ex.warnings if "'Patchy fuzz'" in w]
    assert len(warnings) == 1 and "'Sheen BSDF': Color varies over the surface" in warnings[0]
    assert "Roughness varies over the surface" in warnings[0]


def test_volumes_are_exported_as_cycles_coefficients(scene):
    """Volume Absorption absorbs (1 - Color) Density per metre, Principled Volume
    (1 - Color)(1 - sqrt(Absorption Color)) Density and scatters Color Density, Volume Scatter
    scatters Color Density (Cycles' svm_node_principled_volume and svm_node_closure_volume; the
    absorption measured with Cycles 5.0: a 1 m volume-only cube against the white sky gave
    exp(-(1 - C) D) within 0.1 %); the scatterers' Anisotropy is the phase function's g, and Blender
    5.0's phase functions and Volume Coefficients reach the core (stop 51).  A volume without a
    surface makes the surface let everything through.  Emission: Principled Volume's Emission
    Strength times Color plus its blackbody, an Emission shader's Color times Strength, Mixes at
    their shares."""
    from amcmcppm.core.procedural import blackbody
    mat, _ = bs.volume_material("Tinted glass", "ShaderNodeVolumeAbsorption", "ShaderNodeBsdfGlass",
                             Color=(0.2, 0.5, 1.2, 1), Density=2.0)
    row, ex = export_material(mat)
    assert row["volume_absorption"] == pytest.approx([1.6, 1.0, 0.0])
    assert row["dielectric_weight"] == 1 and row["opacity"] == 1
    assert not [w for w in ex.warnings if "'Tinted glass'" in w], ex.warnings

    mat, _ = bs.volume_material("Smoke", "ShaderNodeVolumePrincipled", None, Color=(0.0, 0.0, 0.0, 1),
                             Density=3.0, **{"Absorption Color": (0.25, 0.5, 0.0, 1)})
    row, ex = export_material(mat)
    assert row["volume_absorption"] == pytest.approx(3.0 * (1.0 - np.sqrt([0.25, 0.5, 0.0])))
    assert row["opacity"] == 0 and row["transparent_color"] == pytest.approx([1, 1, 1])
    assert not [w for w in ex.warnings if "'Smoke'" in w], ex.warnings

    mat, node = bs.volume_material("Fog", "ShaderNodeVolumePrincipled", "ShaderNodeBsdfDiffuse",
                                   Anisotropy=0.3)
    node.inputs["Emission Strength"].default_value = 2.0
    node.inputs["Emission Color"].default_value = (1.0, 0.5, 0.25, 1)
    row, ex = export_material(mat)
    assert row["volume_absorption"] == pytest.approx(np.full(3, 0.5))      # grey 0.5, density 1
    assert row["volume_scattering"] == pytest.approx(np.full(3, 0.5))
    assert row["volume_anisotropy"] == pytest.approx(0.3)
    assert row["volume_emission"] == pytest.approx([2.0, 1.0, 0.5])       # (not scaled by the density)
    assert not [w for w in ex.warnings if "'Fog'" in w], ex.warnings
    node.inputs["Emission Strength"].default_value = 0.0
    node.inputs["Blackbody Intensity"].default_value = 0.5
    node.inputs["Blackbody Tint"].default_value = (1.0, 1.0, 0.5, 1)
    node.inputs["Temperature"].default_value = 1500.0
    row, _ = export_material(mat)
    intensity = 5.670373e-14 / np.pi * (0.5 + 0.5 * 1500.0 ** 4)
    colour = np.maximum(blackbody([1500.0])[0], 0.0)          # (its blue is a little below 0)
    assert row["volume_emission"] == pytest.approx(intensity * np.array([1, 1, 0.5]) * colour, rel=1e-5)

    mat, node = bs.volume_material("Haze", "ShaderNodeVolumeScatter", None, Color=(0.9, 0.8, 0.7, 1),
                                Density=0.5, Anisotropy=-0.4)
    row, ex = export_material(mat)
    assert row["volume_scattering"] == pytest.approx([0.45, 0.4, 0.35])
    assert row["volume_absorption"] == pytest.approx([0, 0, 0])
    assert row["volume_anisotropy"] == pytest.approx(-0.4)
    assert not [w for w in ex.warnings if "'Haze'" in w], ex.warnings
    assert row["volume_phase"] == 0
    # Blender 5.0's other phase functions (stop 51; before, noted and taken as Henyey-Greenstein).
    from amcmcppm.core.phase import PHASE_NAMES
    for name, inputs, params in (("RAYLEIGH", {}, (0, 0, 0)), ("DRAINE", {"Alpha": 0.7}, (0.7, 0, 0)),
                                 ("FOURNIER_FORAND", {"Backscatter": 0.05, "IOR": 1.2}, (0.05, 1.2, 0)),
                                 ("MIE", {"Diameter": 12.0}, (12.0, 0, 0))):
        node.phase = name
        for key, value in inputs.items():
            node.inputs[key].default_value = value
        row, ex = export_material(mat)
        assert row["volume_phase"] == PHASE_NAMES.index(name)
        assert row["volume_phase_params"] == pytest.approx(params)
        assert not [w for w in ex.warnings if "'Haze'" in w], ex.warnings
    # Volume Coefficients (Blender 5.0): its coefficients per metre, its phase.
    mat, node = bs.volume_material("Coefficients", "ShaderNodeVolumeCoefficients", None,
                                   **{"Absorption Coefficients": (0.1, 0.2, 0.3),
                                      "Scatter Coefficients": (0.4, 0.5, 0.6),
                                      "Emission Coefficients": (0.0, 0.0, 0.7)})
    node.phase = "RAYLEIGH"
    row, ex = export_material(mat)
    assert row["volume_absorption"] == pytest.approx([0.1, 0.2, 0.3])
    assert row["volume_scattering"] == pytest.approx([0.4, 0.5, 0.6])
    assert row["volume_emission"] == pytest.approx([0.0, 0.0, 0.7])
    assert row["volume_phase"] == PHASE_NAMES.index("RAYLEIGH")
    assert not [w for w in ex.warnings if "'Coefficients'" in w], ex.warnings

    # A Mix of an absorption with a scatter: each at its share.
    mat, mix = bs.volume_material("Mixed", "ShaderNodeMixShader", None)
    mix.inputs[0].default_value = 0.25
    nt = mat.node_tree
    absorb = nt.nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.0, 0.5, 1.0, 1)
    absorb.inputs["Density"].default_value = 4.0
    nt.links.new(absorb.outputs[0], mix.inputs[1])
    nt.links.new(nt.nodes.new("ShaderNodeVolumeScatter").outputs[0], mix.inputs[2])
    row, ex = export_material(mat)
    assert row["volume_absorption"] == pytest.approx([3.0, 1.5, 0.0])
    assert row["volume_scattering"] == pytest.approx(np.full(3, 0.8 * 0.25))  # the default grey 0.8
    assert not row["volume_emission"].any()
    assert not [w for w in ex.warnings if "'Mixed'" in w], ex.warnings
    glow = nt.nodes.new("ShaderNodeEmission")
    glow.inputs["Color"].default_value = (0.2, 0.4, 0.8, 1)
    glow.inputs["Strength"].default_value = 5.0
    nt.links.new(glow.outputs[0], mix.inputs[2])
    row, _ = export_material(mat)
    assert row["volume_emission"] == pytest.approx(0.25 * 5.0 * np.array([0.2, 0.4, 0.8]))
    assert not row["volume_scattering"].any()

    row, _ = export_material(principled("Plain"))
    assert row["volume_absorption"] == pytest.approx([0, 0, 0]) and row["opacity"] == 1


def test_the_world_volume_is_exported_as_the_world_medium(scene):
    """World > Volume becomes ``World.volume_*`` with a material volume's coefficients.  A sun or
    a world that emits gets a warning, since (as in Cycles) their light does not get through;
    point lights alone do not."""
    bs.camera()
    bs.world_volume("ShaderNodeVolumePrincipled", Color=(0.5, 0.5, 0.5, 1.0), Density=0.2, Anisotropy=0.3,
                 **{"Absorption Color": (0.0, 0.0, 0.0, 1.0)})
    bs.light("POINT", location=(0, 0, 2), energy=100.0)
    ex = bs.export()
    world = ex.scene.world
    assert world.volume_scattering == pytest.approx(np.full(3, 0.1))
    assert world.volume_absorption == pytest.approx(np.full(3, 0.1))
    assert world.volume_anisotropy == pytest.approx(0.3)
    assert not any("world's volume" in w for w in ex.warnings), ex.warnings

    bs.world_volume("ShaderNodeVolumeAbsorption", (0.1, 0.1, 0.1), Color=(1.0, 1.0, 0.0, 1.0), Density=2.0)
    ex = bs.export()
    assert ex.scene.world.volume_absorption == pytest.approx([0.0, 0.0, 2.0])
    assert not ex.scene.world.volume_scattering.any()
    assert any("world's volume fills all space" in w for w in ex.warnings), ex.warnings

    bs.world((0.1, 0.1, 0.1))
    assert not bs.export().scene.world.has_volume


def test_object_ray_visibility_reaches_the_triangles(scene):
    """Object > Visibility > Ray Visibility (Camera, Glossy, Transmission) becomes each triangle's
    ``Scene.triangle_visibility`` bits; a scene where every object is seen by every ray has none."""
    from amcmcppm.core.scene import VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION
    bs.camera()
    shown = bs.plane("Shown", material=bs.diffuse("Grey"))
    assert bs.export().scene.triangle_visibility is None
    hidden = bs.plane("Hidden", material=bs.diffuse("Grey"), location=(0, 0, 1))
    hidden.visible_camera = hidden.visible_transmission = False
    ex = bs.export()
    vis = ex.scene.triangle_visibility
    z = ex.scene.vertices[ex.scene.triangles].mean(axis=1)[:, 2]
    assert set(vis[z > 0.5]) == {VISIBLE_GLOSSY}
    assert set(vis[z < 0.5]) == {VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION}
    assert shown.visible_camera


def test_an_object_with_shadow_off_casts_no_shadow(scene):
    """Ray Visibility > Shadow off: its triangles' CASTS_NO_SHADOW bit (before: ignored, it shadowed)."""
    from amcmcppm.core.scene import CASTS_NO_SHADOW, VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION
    bs.camera()
    bs.plane("Floor", material=bs.diffuse("Grey"))
    board = bs.plane("Board", material=bs.diffuse("Grey"), location=(0, 0, 1))
    board.visible_shadow = False
    ex = bs.export()
    z = ex.scene.vertices[ex.scene.triangles].mean(axis=1)[:, 2]
    every = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION
    assert set(ex.scene.triangle_visibility[z > 0.5]) == {every | CASTS_NO_SHADOW}
    assert set(ex.scene.triangle_visibility[z < 0.5]) == {every}


def fresnel_mix(name, factor_node, output, **inputs):
    """A Mix of a red Diffuse and a white Glossy by ``factor_node``'s ``output``."""
    mat = bs.diffuse(name, (0.8, 0.1, 0.1))
    nt = mat.node_tree
    glossy, mix = nt.nodes.new("ShaderNodeBsdfGlossy"), nt.nodes.new("ShaderNodeMixShader")
    glossy.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    factor = nt.nodes.new(factor_node)
    for key, value in inputs.items():
        factor.inputs[key].default_value = value
    nt.links.new(factor.outputs[output], mix.inputs["Fac"])
    nt.links.new(nt.nodes["Diffuse BSDF"].outputs[0], mix.inputs[1])
    nt.links.new(glossy.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat


def test_a_mix_by_a_fresnel_curve_is_a_layer_and_other_view_factors_pick_levels(scene):
    """Mix(Diffuse, Glossy) by a Fresnel node: the glossy rises along the Fresnel curve of its IOR
    from C F0, over a diffuse whose layer reflects F0 (both at weight 1); by Layer Weight's Facing
    f = 1 - |I . N|^e (e = 2 Blend) at the ray's Incoming I: the glossy's colour f C_g and the
    diffuse's (1 - f) C_d at each hit, as programs over the lobes' weights, the factor's mean over
    view directions (f: 1 - 2 / (e + 2)); no note."""
    from amcmcppm.core import procedural
    row, ex = export_material(fresnel_mix("Fresnel", "ShaderNodeFresnel", "Fac", IOR=1.45))
    f0 = (0.45 / 2.45) ** 2
    assert row["glossy_fresnel_ior"] == pytest.approx(1.45) and not ex.warnings
    assert row["glossy_weight"] == pytest.approx(1.0) and row["diffuse_weight"] == pytest.approx(1.0)
    assert row["glossy_color"] == pytest.approx(np.full(3, f0), rel=1e-5)
    assert row["glossy_fresnel_rise"] == pytest.approx(np.full(3, 1 - f0), rel=1e-5)
    assert row["diffuse_layer"] == pytest.approx(np.full(3, f0), rel=1e-5)
    assert row["glossy_multiscatter"] == pytest.approx(np.ones(3), rel=1e-5)        # the Glossy's own
    row, ex = export_material(fresnel_mix("Facing", "ShaderNodeLayerWeight", "Facing", Blend=0.3))
    assert row["glossy_weight"] == pytest.approx(1 - 2 / 2.6, rel=1e-3) and row["glossy_fresnel_ior"] == 0
    assert not ex.warnings, ex.warnings
    pts = procedural.SampledAttributes(256)
    mu = np.abs(np.einsum("ki,ki->k", pts.get("incoming"), pts.get("world_normal")))
    assert mu.min() < 0.1 and mu.max() > 0.9
    facing = (1.0 - mu ** 0.6)[:, None]
    programs = ex.scene.materials.programs
    glossy = row["glossy_weight"] * procedural.evaluate(programs[row["glossy_program"]], pts, [])
    diffuse = row["diffuse_weight"] * procedural.evaluate(programs[row["diffuse_program"]], pts, [])
    np.testing.assert_allclose(glossy, facing * np.ones(3), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(diffuse, (1.0 - facing) * [0.8, 0.1, 0.1], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("ray, bit", [("Is Camera Ray", 1), ("Is Glossy Ray", 2), ("Is Transmission Ray", 4)])
def test_a_light_path_mix_with_a_clear_transparent_is_ray_visibility(scene, ray, bit):
    """Mix(Emission, clear Transparent) by a Light Path ray output: the emission, its triangles
    hidden from that kind of camera-path ray; with a tinted Transparent the opacity is one minus
    the Light Path output at each hit (stop 40: a program; before, the node was unsupported,
    noted, and the Mix took its own factor)."""
    from amcmcppm.core import procedural
    def panel(tint):
        mat = bs.emission(f"Panel {ray} {tint}", (1.0, 0.9, 0.8), 8.0)
        nt = mat.node_tree
        clear, mix, path = (nt.nodes.new(t) for t in ("ShaderNodeBsdfTransparent", "ShaderNodeMixShader",
                                                      "ShaderNodeLightPath"))
        clear.inputs["Color"].default_value = (1.0, tint, 1.0, 1.0)
        nt.links.new(path.outputs[ray], mix.inputs["Fac"])
        nt.links.new(nt.nodes["Emission"].outputs[0], mix.inputs[1])
        nt.links.new(clear.outputs[0], mix.inputs[2])
        nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        return mat
    bs.camera()
    bs.plane("Floor", material=bs.diffuse("Grey"))
    bs.plane("Panel", material=panel(1.0), location=(0, 0, 1))
    ex = bs.export()
    z = ex.scene.vertices[ex.scene.triangles].mean(axis=1)[:, 2]
    assert set(ex.scene.triangle_visibility[z > 0.5]) == {7 & ~bit}
    assert set(ex.scene.triangle_visibility[z < 0.5]) == {7}
    row = material_row(ex.scene, f"Panel {ray} 1.0")
    assert row["emission"] == pytest.approx([8.0, 7.2, 6.4]) and row["opacity"] == 1.0
    assert not any("Light Path" in w for w in ex.warnings)
    row, ex = export_material(panel(0.5))
    assert not any("Light Path" in w for w in ex.warnings), ex.warnings
    points = procedural.SampledAttributes(64)                  # (half camera rays, half photons)
    opacity = procedural.evaluate(ex.scene.materials.programs[row["opacity_program"]], points, [])
    output = points.get("light_path")[:, procedural.LIGHT_PATH.index(ray)]
    np.testing.assert_allclose(opacity, 1.0 - output)
    assert output.min() < output.max()


def test_translucent_bsdf_is_the_translucent_lobe_mixed_by_weight(scene):
    """A Translucent BSDF is the core's translucent lobe of its colour; a Mix with a Diffuse by
    0.4 weighs it 0.4 and the diffuse 0.6; a texture on its colour becomes its program, which
    the core evaluates at each hit."""
    from amcmcppm.core.context import RenderContext
    row, ex = export_material(bs._material("Paper", "ShaderNodeBsdfTranslucent", Color=(0.9, 0.6, 0.3, 1.0)))
    assert row["translucent_weight"] == 1.0 and row["diffuse_weight"] == 0.0 and not ex.warnings
    assert row["translucent_color"] == pytest.approx([0.9, 0.6, 0.3])
    row, ex = export_material(bs.leaf("Leaf", (0.1, 0.5, 0.1), (0.3, 0.8, 0.2), 0.4))
    assert row["translucent_weight"] == pytest.approx(0.4) and row["diffuse_weight"] == pytest.approx(0.6)
    assert row["translucent_color"] == pytest.approx([0.3, 0.8, 0.2])
    assert row["diffuse_color"] == pytest.approx([0.1, 0.5, 0.1]) and not ex.warnings
    assert "translucency" in RenderContext(ex.scene).effects
    mat = bs.leaf("Veined", fac=1.0)
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Color1"].default_value = (1.0, 1.0, 1.0, 1.0)
    checker.inputs["Color2"].default_value = (0.0, 0.0, 0.0, 1.0)
    nt.links.new(checker.outputs["Color"], nt.nodes["Translucent BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    assert not ex.warnings and row["translucent_program"] >= 0 and row["translucent_weight"] == 1.0
    assert row["translucent_color"] == pytest.approx([1, 1, 1])
    program = ex.scene.materials.programs[row["translucent_program"]]
    assert "checker" in repr(program)
    assert "procedural textures" in RenderContext(ex.scene).effects


def test_diffuse_roughness_is_exported_from_the_diffuse_and_principled_bsdfs(scene):
    """The Diffuse BSDF's Roughness and Principled's Diffuse Roughness become
    ``diffuse_roughness`` (no longer noted as unsupported); a Mix weighs them by the diffuse
    weights; 0 stays Lambert."""
    row, ex = export_material(bs._material("Clay", "ShaderNodeBsdfDiffuse", Roughness=0.8))
    assert row["diffuse_roughness"] == pytest.approx(0.8) and not ex.warnings
    row, ex = export_material(principled("Matte", **{"Diffuse Roughness": 0.6}))
    assert row["diffuse_roughness"] == pytest.approx(0.6) and not ex.warnings
    row, _ = export_material(bs.leaf("Half", fac=0.5))
    assert row["diffuse_roughness"] == 0.0
    mat = bs._material("Mixed", "ShaderNodeBsdfDiffuse", Roughness=0.8)
    bs.mix_in(mat, "Diffuse BSDF", "ShaderNodeBsdfDiffuse", 0.25)          # a smooth one
    row, _ = export_material(mat)
    assert row["diffuse_roughness"] == pytest.approx(0.75 * 0.8)


def test_holdout_shaders_and_objects_are_exported(scene):
    """A Holdout shader is a holdout share of 1 and no lobes; in a Mix with a Diffuse by 0.25 the
    share is 0.75 and the diffuse weight 0.25; a holdout object's triangles get HOLDOUT_OBJECT
    besides their ray visibility."""
    from amcmcppm.core.scene import HOLDOUT_OBJECT, VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION
    row, ex = export_material(bs._material("Hold", "ShaderNodeHoldout"))
    assert row["holdout"] == 1.0 and row["diffuse_weight"] == row["glossy_weight"] == 0 and not ex.warnings
    row, _ = export_material(bs.mix_with_holdout(bs.diffuse("Half"), "Diffuse BSDF", 0.25))
    assert row["holdout"] == pytest.approx(0.75) and row["diffuse_weight"] == pytest.approx(0.25)
    bs.camera()
    bs.plane("Shown", material=bs.diffuse("Grey"))
    card = bs.plane("Card", material=bs.diffuse("Grey"), location=(0, 0, 1))
    card.is_holdout = True
    ex = bs.export()
    vis = ex.scene.triangle_visibility
    z = ex.scene.vertices[ex.scene.triangles].mean(axis=1)[:, 2]
    every = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION
    assert set(vis[z > 0.5]) == {every | HOLDOUT_OBJECT} and set(vis[z < 0.5]) == {every}


def test_multiscatter_ggx_gets_cycles_mean_fresnel_colour_and_single_scatter_gets_none(scene):
    """glossy_multiscatter is the F_ss of Cycles' energy compensation: 0 unless the node's
    distribution is Multiscatter GGX (Blender's default)."""
    from amcmcppm.amcmcppm_addon.export.materials import mean_fresnel
    colour = (0.9, 0.5, 0.2, 1.0)
    glossy = bs._material("Brushed", "ShaderNodeBsdfGlossy", Color=colour, Roughness=0.5)
    row, _ = export_material(glossy)
    assert glossy.node_tree.nodes["Glossy BSDF"].distribution == "MULTI_GGX"
    assert row["glossy_multiscatter"] == pytest.approx(colour[:3])
    glossy.node_tree.nodes["Glossy BSDF"].distribution = "GGX"
    row, _ = export_material(glossy)
    assert row["glossy_multiscatter"] == pytest.approx([0, 0, 0])

    metal, _ = export_material(principled("Copper", **{"Base Color": colour, "Metallic": 1.0}))
    f0 = np.array(colour[:3])
    assert metal["glossy_multiscatter"] == pytest.approx(f0 + (1 - f0) / 21, rel=1e-6)   # F82 mean
    plastic = principled("Plastic", **{"Base Color": colour})
    plain, _ = export_material(plastic)
    # The layer's F_ss as Cycles: f0 + (1 - f0) times its mean Fresnel rescaled from [F0, 1].
    f_avg = (mean_fresnel(1.5) - 0.04) / 0.96
    assert plain["glossy_multiscatter"] == pytest.approx(np.full(3, 0.04 + 0.96 * f_avg), rel=1e-4)
    plastic.node_tree.nodes["Principled BSDF"].distribution = "GGX"
    plain, _ = export_material(plastic)
    assert plain["glossy_multiscatter"] == pytest.approx([0, 0, 0])

    # Mix of a metal and a white Glossy: F_ss averaged with weights weight * colour per channel,
    # the metal's colour its F0 and its F_ss the F82 curve's mean.
    f_metal = f0 + (1 - f0) / 21
    mat = bpy.data.materials.new("Blend")
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    a, b = nt.nodes.new("ShaderNodeBsdfMetallic"), nt.nodes.new("ShaderNodeBsdfGlossy")
    a.inputs["Base Color"].default_value = colour
    a.inputs["Edge Tint"].default_value = (1.0, 1.0, 1.0, 1.0)       # b = 0 (the default tint is not white)
    b.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    nt.links.new(a.outputs[0], mix.inputs[1])
    nt.links.new(b.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, _ = export_material(mat)
    expected = (f0 * f_metal + 1.0) / (f0 + 1.0)
    assert row["glossy_multiscatter"] == pytest.approx(expected, rel=1e-6)
    assert row["glossy_color"] == pytest.approx(0.5 * f0 + 0.5, rel=1e-6)
    assert row["glossy_metal_rise"] == pytest.approx(0.5 * (1 - f0), rel=1e-6)


def test_metallic_node_gives_the_fresnel_curve_of_its_model(scene):
    """F82 tint: colour F0, rise 1 - F0, dip b from the edge tint (Cycles' fresnel_f82tint_B),
    F_ss the curve's mean F0 + (1 - F0) / 21 - b / 126; physical conductor: the F82 curve through
    the complex-IOR Fresnel face on and at cos 1/7, F_ss the mean of that Fresnel, which for
    k = 0 is the dielectric's."""
    from amcmcppm.amcmcppm_addon.export.materials import conductor_reflectance, mean_fresnel
    f0, tint = np.array([0.9, 0.6, 0.3]), np.array([0.5, 0.8, 1.0])
    mat = bs._material("Brass", "ShaderNodeBsdfMetallic", **{"Base Color": (*f0, 1.0),
                                                             "Edge Tint": (*tint, 1.0), "Roughness": 0.4})
    row, _ = export_material(mat)
    f = 6 / 7
    b = (f0 + (1 - f0) * f ** 5) * 7 / f ** 6 * (1 - tint)
    assert row["glossy_color"] == pytest.approx(f0, rel=1e-6)
    assert row["glossy_metal_rise"] == pytest.approx(1 - f0, rel=1e-6)
    assert row["glossy_metal_dip"] == pytest.approx(b, rel=1e-5, abs=1e-7)
    assert row["glossy_metal_dip"][2] == 0                                              # white tint
    # The same mean by quadrature of F82 itself.
    mu = (np.arange(100000) + 0.5) / 100000
    f82 = f0[:, None] + (1 - f0[:, None]) * (1 - mu) ** 5 - b[:, None] * mu * (1 - mu) ** 6
    assert row["glossy_multiscatter"] == pytest.approx(np.mean(2 * mu * f82, axis=1), rel=1e-5)
    node = mat.node_tree.nodes["Metallic BSDF"]
    node.fresnel_type = "PHYSICAL_CONDUCTOR"
    node.inputs["IOR"].default_value = (1.5, 1.5, 1.5)
    node.inputs["Extinction"].default_value = (0.0, 0.0, 0.0)
    row, _ = export_material(mat)
    assert row["glossy_color"] == pytest.approx(np.full(3, 0.04), rel=1e-4)
    assert row["glossy_multiscatter"] == pytest.approx(np.full(3, mean_fresnel(1.5)), rel=1e-4)
    # Gold (Blender's default conductor): the fitted curve against the exact one at every angle.
    ior, k = (0.18, 0.42, 1.37), (3.42, 2.35, 1.77)
    node.inputs["IOR"].default_value, node.inputs["Extinction"].default_value = ior, k
    row, _ = export_material(mat)
    mu = np.linspace(0.0, 1.0, 201)
    fitted = (row["glossy_color"][:, None] + row["glossy_metal_rise"][:, None] * (1 - mu) ** 5
              - row["glossy_metal_dip"][:, None] * mu * (1 - mu) ** 6)
    error = np.abs(fitted - conductor_reflectance(ior, k, mu))
    print(f"gold: F82 fit within {error.max(axis=1)} of the conductor's Fresnel")
    assert error.max() < 0.03      # measured 0.006 / 0.004 / 0.023 (the mean, as before: 0.06 / 0.21 / 0.59)
    assert 0.3 < row["glossy_color"][2] < row["glossy_color"][1] < row["glossy_color"][0] < 1.0


def test_a_textured_metal_keeps_the_fresnel_curve_of_each_points_colour(scene):
    """A texture on a metal's base colour (Principled metallic 1, or the Metallic node's F82
    tint) makes its F0 a program, clamped to [0, 1], with the edge tint beside it
    (``glossy_metal_tint``): the core takes the curve of each hit's F0, also where it shares the
    lobe with a plain glossy colour (a Glossy BSDF, a Principled's specular layer, a paint mixed
    in: ``glossy_metal_share``).  Where it shares the lobe with another metal's curve or mixes by
    a varying factor, or its Edge Tint is textured, the lobe keeps the curve's mean."""
    def checkered(mat, socket, node_name):
        nt = mat.node_tree
        checker = nt.nodes.new("ShaderNodeTexChecker")
        checker.inputs["Color1"].default_value = (0.95, 0.6, 0.2, 1)
        checker.inputs["Color2"].default_value = (0.9, 0.9, 0.92, 1)
        nt.links.new(checker.outputs["Color"], nt.nodes[node_name].inputs[socket])
        return mat

    def program(row, ex):
        return ex.scene.materials.programs[row["glossy_program"]]

    tint = (1.0, 0.6, 0.3)
    mat = checkered(principled("Rusty", **{"Metallic": 1.0, "Specular Tint": (*tint, 1)}), "Base Color",
                    "Principled BSDF")
    row, ex = export_material(mat)
    assert row["glossy_metal_tint"] == pytest.approx(tint)
    assert row["glossy_color"] == pytest.approx([1, 1, 1]) and row["glossy_weight"] == pytest.approx(1.0)
    assert not row["glossy_metal_rise"].any() and not row["glossy_metal_dip"].any()
    p = program(row, ex)
    assert p["op"] == "mix_color" and p["clamp_result"] and p["a"]["op"] == "checker"
    metallic = checkered(bs._material("Brass", "ShaderNodeBsdfMetallic", **{"Edge Tint": (*tint, 1)}),
                         "Base Color", "Metallic BSDF")
    row, ex = export_material(metallic)
    assert row["glossy_metal_tint"] == pytest.approx(tint) and program(row, ex)["a"]["op"] == "checker"
    edge = checkered(bs._material("Edged", "ShaderNodeBsdfMetallic"), "Edge Tint", "Metallic BSDF")
    row, ex = export_material(edge)
    assert row["glossy_metal_tint"] == pytest.approx([-1, -1, -1]) and program(row, ex)["op"] == "metal"
    # Mixed at a constant factor with a Diffuse BSDF: still the whole glossy lobe.
    half = checkered(principled("Half", **{"Metallic": 1.0}), "Base Color", "Principled BSDF")
    bs.mix_in(half, "Principled BSDF", "ShaderNodeBsdfDiffuse", 0.5)
    row, ex = export_material(half)
    assert row["glossy_metal_tint"] == pytest.approx([1, 1, 1]) and row["glossy_weight"] == pytest.approx(0.5)
    # Beside a plain Glossy BSDF (0.8 grey) at 0.5: the metal is half of the lobe, the grey the rest.
    beside = checkered(principled("Beside", **{"Metallic": 1.0}), "Base Color", "Principled BSDF")
    bs.mix_in(beside, "Principled BSDF", "ShaderNodeBsdfGlossy", 0.5)
    row, ex = export_material(beside)
    assert row["glossy_metal_tint"] == pytest.approx([1, 1, 1])
    assert row["glossy_metal_share"] == pytest.approx(0.5)
    np.testing.assert_allclose(row["glossy_metal_rest"], [0.4] * 3, rtol=1e-5)
    assert row["glossy_fresnel_ior"] == 0
    # Beside a plain metal with its own curve: one lobe of the constant colours and that curve.
    shared = checkered(principled("Shared", **{"Metallic": 1.0}), "Base Color", "Principled BSDF")
    bs.mix_in(shared, "Principled BSDF", "ShaderNodeBsdfMetallic", 0.5)
    row, ex = export_material(shared)
    assert row["glossy_metal_tint"] == pytest.approx([-1, -1, -1]) and row["glossy_program"] == -1
    assert row["glossy_metal_rise"].any()
    # Partly metallic: the metal's share k of the lobe beside the dielectric layer, the program
    # F0 (the lobe's colour is k F0 + rest), the rest's F_ss (f0 + (1 - f0) times the rescaled
    # mean Fresnel), no row curve.
    part = checkered(principled("Part", **{"Metallic": 0.3, "Specular Tint": (*tint, 1)}), "Base Color",
                     "Principled BSDF")
    row, ex = export_material(part)
    f0t = 0.04 * np.array(tint)
    assert row["glossy_metal_tint"] == pytest.approx(tint) and row["glossy_weight"] == pytest.approx(1.0)
    assert row["glossy_metal_share"] == pytest.approx(0.3) and row["glossy_fresnel_ior"] == pytest.approx(1.5)
    np.testing.assert_allclose(row["glossy_metal_rest"], 0.7 * f0t, rtol=1e-5)
    np.testing.assert_allclose(row["glossy_fresnel_rise"], 0.7 * (1.0 - f0t), rtol=1e-5)
    assert row["glossy_color"] == pytest.approx([1, 1, 1])
    assert not row["glossy_metal_rise"].any() and not row["glossy_metal_dip"].any()
    assert ((row["glossy_multiscatter"] > f0t) & (row["glossy_multiscatter"] < 0.15)).all()
    p = program(row, ex)
    assert p["op"] == "mix_color" and p["clamp_result"] and p["a"]["op"] == "checker"
    # A textured metal and a paint mixed at 0.3 (or a mask's level between them) as the same lobe.
    mixed = checkered(principled("Mixed", **{"Metallic": 1.0, "Specular Tint": (*tint, 1)}), "Base Color",
                      "Principled BSDF")
    bs.mix_in(mixed, "Principled BSDF", "ShaderNodeBsdfPrincipled", 0.7)
    row, ex = export_material(mixed)
    assert row["glossy_metal_share"] == pytest.approx(0.3) and row["glossy_fresnel_ior"] == pytest.approx(1.5)
    np.testing.assert_allclose(row["glossy_metal_rest"], [0.7 * 0.04] * 3, rtol=1e-5)
    np.testing.assert_allclose(row["glossy_fresnel_rise"], [0.7 * 0.96] * 3, rtol=1e-5)
    assert row["glossy_metal_tint"] == pytest.approx(tint) and program(row, ex)["clamp_result"]
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    # The same under a varying factor (an alpha map): the curve of the mean F0, no program.
    nt = part.node_tree
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], nt.nodes["Principled BSDF"].inputs["Alpha"])
    row, ex = export_material(part)
    assert row["glossy_metal_tint"] == pytest.approx([-1, -1, -1]) and row["glossy_program"] < 0
    assert row["glossy_metal_rise"].any() and row["glossy_metal_share"] == pytest.approx(1.0)


def test_mix_add_groups_and_basic_bsdfs(scene):
    mat = bpy.data.materials.new("Layered")
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    # A node group wrapping a Diffuse BSDF whose colour comes from the group input.
    group = bpy.data.node_groups.new("Paint", "ShaderNodeTree")
    group.interface.new_socket("Tint", in_out="INPUT", socket_type="NodeSocketColor")
    group.interface.new_socket("BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    gin, gout = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    inner = group.nodes.new("ShaderNodeBsdfDiffuse")
    group.links.new(gin.outputs["Tint"], inner.inputs["Color"])
    group.links.new(inner.outputs[0], gout.inputs["BSDF"])
    paint = nt.nodes.new("ShaderNodeGroup")
    paint.node_tree = group
    paint.inputs["Tint"].default_value = (0.2, 0.4, 0.6, 1.0)
    glossy = nt.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.25
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.25
    nt.links.new(paint.outputs["BSDF"], mix.inputs[1])
    nt.links.new(glossy.outputs[0], mix.inputs[2])
    emit = nt.nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = 2.0
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(mix.outputs[0], add.inputs[0])
    nt.links.new(emit.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, ex = export_material(mat)
    assert not [w for w in ex.warnings if "Layered" in w]
    assert row["diffuse_weight"] == pytest.approx(0.75)
    assert row["diffuse_color"] == pytest.approx([0.2, 0.4, 0.6])
    assert row["glossy_weight"] == pytest.approx(0.25) and row["glossy_roughness"] == pytest.approx(0.25)
    assert row["emission"] == pytest.approx([2, 2, 2])

    glass = bs.glass("Water", ior=1.33)
    row, _ = export_material(glass)
    assert row["dielectric_weight"] == 1 and row["ior"] == pytest.approx(1.33)
    assert row["dielectric_roughness"] == 0
    glass.node_tree.nodes["Glass BSDF"].inputs["Roughness"].default_value = 0.3
    row, ex = export_material(glass)
    assert row["dielectric_roughness"] == pytest.approx(0.3) and not [w for w in ex.warnings if "Water" in w]
    assert row["dielectric_reflection_color"] == pytest.approx(row["dielectric_color"])
    mirror = bs._material("Chrome", "ShaderNodeBsdfGlossy", Roughness=0.0)
    row, _ = export_material(mirror)
    assert row["glossy_weight"] == 1 and row["glossy_roughness"] == 0   # the core treats it as a mirror


# ---------------------------------------------------------------------- lights
def light_row(core_scene, i=0):
    L = core_scene.lights
    return {f: getattr(L, f)[i] for f in L.ARRAY_FIELDS}


def export_light(kind, **props):
    ob = bs.light(kind, location=(1, 2, 3), target=(1, 2, 0), **props)
    bs.camera()
    return ob, light_row(bs.export().scene)


def test_point_light_units(scene):
    _, row = export_light("POINT", energy=100.0, shadow_soft_size=0.25, color=(1, 0.5, 0.25), exposure=1.0)
    assert row["power"] == pytest.approx([200, 100, 50])
    assert row["radius"] == pytest.approx(0.25) and tuple(row["position"]) == pytest.approx((1, 2, 3))


def test_light_nodes_scale_the_power(scene):
    """A light with nodes: its Emission's Color (a Blackbody of 3000 K) times Strength (2)
    multiply its power; with nothing on its output it emits nothing."""
    from amcmcppm.core.procedural import blackbody
    light = bpy.data.lights.new("Warm", "POINT")
    light.energy = 100.0
    light.use_nodes = True
    nt = light.node_tree
    emission = nt.nodes["Emission"]
    emission.inputs["Strength"].default_value = 2.0
    bb = nt.nodes.new("ShaderNodeBlackbody")
    bb.inputs["Temperature"].default_value = 3000.0
    nt.links.new(bb.outputs["Color"], emission.inputs["Color"])
    ob = bpy.data.objects.new("Warm", light)
    bpy.context.scene.collection.objects.link(ob)
    bs.camera()
    ex = bs.export()
    np.testing.assert_allclose(ex.scene.lights.power[0], 200.0 * blackbody([3000.0])[0], rtol=1e-5)
    assert not any("Warm" in w for w in ex.warnings), ex.warnings
    nt.links.remove(nt.nodes["Light Output"].inputs["Surface"].links[0])
    assert bs.export().scene.lights.count == 0


def test_an_ies_texture_gives_a_point_light_its_profile_in_the_lights_frame(scene):
    """An IES Texture (Strength 2) on a turned point light's Emission Strength: the power is the
    light's times 2, the profile the file's candela values times 4 pi / 177.83 (Cycles' factor)
    at its own angles (where Cycles' Catmull-Rom lookup returns the data), 0 from 90 degrees up
    (the file stops there), and the frame the light's X and Y axes."""
    from amcmcppm.amcmcppm_addon.export import ies
    ob = bs.light("POINT", location=(0, 0, 2), energy=10.0)
    ob.rotation_euler = (0.3, -0.2, 0.9)
    bs.add_ies(ob, bs.ies_text(), strength=2.0)
    bs.camera()
    ex = bs.export()
    assert not ex.warnings
    lights = ex.scene.lights
    np.testing.assert_allclose(lights.power[0], 20.0, rtol=1e-6)
    assert lights.profile[0] == 0 and lights.profiles.shape == (1, *ies.GRID)
    m = np.array(ob.matrix_world)
    np.testing.assert_allclose(lights.axis_u[0], m[:3, 0], atol=1e-6)
    np.testing.assert_allclose(lights.axis_v[0], m[:3, 1], atol=1e-6)
    table = lights.profiles[0]
    for v in (0, 15, 45, 75):
        for h in (0, 45, 135, 270):
            candela = 800.0 * np.sqrt(np.cos(np.radians(v))) * (1.0 + 0.6 * np.cos(np.radians(h - 60)))
            assert table[v, h] == pytest.approx(candela * ies.CANDELA_TO_WATT, rel=1e-5), (v, h)
    assert (table[90:] == 0).all() and (table[:89] > 0).all()
    np.testing.assert_allclose(table[:, -1], table[:, 0], rtol=1e-5)       # 360 degrees is 0 again


def test_ies_files_are_read_as_cycles_reads_them(scene):
    """One quadrant of a type C file is mirrored to the whole circle; the candela multiplier and
    the ballast factors scale the values; TILT=INCLUDE data is skipped; type A files, files cut
    short and missing files are not read (the light shines evenly, with a warning).  An area
    light takes the profile as point and spot lights do; the sun, whose light has one direction,
    its value along the sun's -Z."""
    from amcmcppm.amcmcppm_addon.export import ies
    quadrant = bs.ies_text(horizontal=(0, 30, 60, 90))
    table = ies.tabulate(quadrant)
    for h in (30, 60):
        for mirror in (180 - h, 180 + h, 360 - h):
            np.testing.assert_allclose(table[:90, mirror], table[:90, h], rtol=1e-6)
    scaled = quadrant.replace("1 -1 1.0 ", "1 -1 2.0 ").replace("\n1.0 1.0 50", "\n0.5 0.8 50")
    np.testing.assert_allclose(ies.tabulate(scaled), 0.8 * table, rtol=1e-6)
    tilted = quadrant.replace("TILT=NONE", "TILT=INCLUDE\n1\n2\n0 90\n1.0 0.5")
    np.testing.assert_allclose(ies.tabulate(tilted), table, rtol=1e-6)
    # A file with Windows line ends, one horizontal angle and the whole vertical range: Cycles'
    # Catmull-Rom at 45 degrees between 100 and 50 (with 50 again past the pole) is 81.25.
    crlf = "\r\n".join(["IESNA:LM-63-2002", "[TEST] X", "TILT=NONE", "1 1000 1 3 1 1 2 0.1 1.2 0.05",
                         "1 1 12", "0 90 180", "0", "100 50 0", ""])
    round_ = ies.tabulate(crlf) / ies.CANDELA_TO_WATT
    np.testing.assert_allclose(round_[[0, 45, 90], 0], [100.0, 81.25, 50.0], rtol=1e-6)
    np.testing.assert_allclose(round_, np.broadcast_to(round_[:, :1], round_.shape), rtol=1e-5, atol=1e-6)
    for bad in (quadrant.replace("1 -1 1.0 7 4 1 ", "1 -1 1.0 7 4 3 "), quadrant[:200], "no tilt line",
                quadrant.replace("\n0 30 60 90\n", "\n0 30 30 90\n")):          # an angle twice
        with pytest.raises(ies.IESError):
            ies.tabulate(bad)
    ob = bs.light("SPOT", location=(0, 0, 2), energy=10.0)
    node = bs.add_ies(ob, quadrant)
    node.mode = "EXTERNAL"
    node.filepath = "/nonexistent/profile.ies"
    bs.camera()
    ex = bs.export()
    assert ex.scene.lights.count == 1 and ex.scene.lights.profile[0] == -1
    assert any("cannot read its profile" in w for w in ex.warnings), ex.warnings
    sun = bs.light("SUN", energy=2.0)
    bs.add_ies(sun, quadrant, strength=0.5)
    area = bs.light("AREA", energy=3.0, size=0.5)
    bs.add_ies(area, quadrant)
    ex = bs.export()
    lights = ex.scene.lights
    assert lights.count == 3 and list(lights.profile) == [-1, -1, 0], lights.profile
    np.testing.assert_allclose(lights.power[1], 2.0 * 0.5 * table[0, 180], rtol=1e-5)
    np.testing.assert_allclose(lights.profiles[0], table, rtol=1e-6)


def _lit(core, light_links, name):
    """Whether an emitter with ``light_links`` lights the object whose material is ``name``."""
    sets = core.receiver_sets[core.material_ids == core.materials.names.index(name)]
    assert len(sets) and (sets == sets[0]).all()
    return bool((int(light_links) >> int(sets[0])) & 1)


def test_light_and_shadow_linking_follow_blenders_include_and_exclude_rules(scene):
    """Object > Shading > Light Linking > Receivers: a collection that includes objects lights only
    those (a child collection's state holds for everything in it, the collection's own entry for
    an object wins over it); one that only excludes lights all but those; a light without one
    lights everything; an emissive mesh's collection sets its triangles' links.  Shadow linking
    (Blockers) follows the same rules."""
    from amcmcppm.core.scene import ALL_LINKS
    objects = {n: bs.cube(n, material=bs.diffuse(n), location=(3 * i, 0, 0)) for i, n in enumerate("ABCD")}
    glow = bs.plane("Glow", material=bs.emission("Glow", strength=2.0), location=(0, 0, 4))
    bs.camera()
    l1 = bs.light("POINT", location=(0, 0, 2), energy=10.0, name="L1")
    l2 = bs.light("POINT", location=(2, 0, 2), energy=10.0, name="L2")
    bs.light("POINT", location=(4, 0, 2), energy=10.0, name="L3")
    core = bs.export().scene
    assert core.receiver_sets is None and (core.lights.links == ALL_LINKS).all()

    # L1: includes B and a child collection holding C and D, whose own entry for D excludes it.
    r1 = bpy.data.collections.new("R1")
    child = bpy.data.collections.new("Child")
    r1.children.link(child)
    child.objects.link(objects["C"])
    child.objects.link(objects["D"])
    r1.objects.link(objects["B"])
    r1.objects.link(objects["D"])
    r1.collection_objects[1].light_linking.link_state = "EXCLUDE"
    l1.light_linking.receiver_collection = r1
    # L2 and the emissive plane: exclude A only.
    r2 = bpy.data.collections.new("R2")
    r2.objects.link(objects["A"])
    r2.collection_objects[0].light_linking.link_state = "EXCLUDE"
    l2.light_linking.receiver_collection = r2
    glow.light_linking.receiver_collection = r2
    exported = bs.export()
    core = exported.scene
    assert not any("linking" in w for w in exported.warnings), exported.warnings
    links = dict(zip(["L1", "L2", "L3"], core.lights.links))
    names = "ABCD"
    assert [_lit(core, links["L1"], n) for n in names] == [False, True, True, False]
    assert [_lit(core, links["L2"], n) for n in names] == [False, True, True, True]
    assert [_lit(core, links["L3"], n) for n in names] == [True] * 4
    glow_links = core.emitter_links[core.material_ids == core.materials.names.index("Glow")]
    assert (glow_links == glow_links[0]).all()
    assert [_lit(core, glow_links[0], n) for n in names] == [False, True, True, True]
    # The other meshes' links are those of emitters without a collection.
    assert (core.emitter_links[core.material_ids != core.materials.names.index("Glow")] == ALL_LINKS).all()

    # Shadow linking: L2's blockers are all but A; the emissive plane's only B (and C, D excluded).
    l2.light_linking.blocker_collection = r2
    r3 = bpy.data.collections.new("R3")
    for n, state in zip("BCD", ("INCLUDE", "EXCLUDE", "EXCLUDE")):
        r3.objects.link(objects[n])
        r3.collection_objects[-1].light_linking.link_state = state
    glow.light_linking.blocker_collection = r3
    core = bs.export().scene
    shadow = dict(zip(["L1", "L2", "L3"], core.lights.shadow_links))

    def blocks(links, name):
        sets = core.blocker_sets[core.material_ids == core.materials.names.index(name)]
        return bool((int(links) >> int(sets[0])) & 1)
    assert [blocks(shadow["L2"], n) for n in names] == [False, True, True, True]
    assert [blocks(shadow["L1"], n) for n in names] == [True] * 4
    glow_shadow = core.emitter_shadow_links[core.material_ids == core.materials.names.index("Glow")]
    assert [blocks(glow_shadow[0], n) for n in names] == [False, True, False, False]
    # Light linking is unchanged by it.
    assert [_lit(core, core.lights.links[0], n) for n in names] == [False, True, True, False]


def test_light_groups_follow_the_view_layers_list(scene):
    """View Layer > Light Groups: ``Scene.light_groups`` are the view layer's names in its order; a
    light's group (``Lights.group``), an object's (``Scene.emitter_group``, for all its triangles)
    and the world's (``World.group``, and its sky's sun disc's) index them, -1 for no group or a
    name the view layer does not list.  An instance without a group takes its instancer's (a
    collection instance's empty), as Cycles' sync does; one with its own keeps it.  Without light
    groups: no groups and no emitter_group.  A name the view layer does not list is named in an info
    message."""
    from amcmcppm.core.scene import SUN
    bs.camera()
    key = bs.light("AREA", location=(0, 0, 3), energy=50.0, name="Key")
    fill = bs.light("POINT", location=(2, 0, 3), energy=20.0, name="Fill")
    stray = bs.light("POINT", location=(-2, 0, 3), energy=20.0, name="Stray")
    glow = bs.cube("Glow", material=bs.emission("Glow", strength=2.0), location=(0, 2, 0.5))
    bs.plane("Floor", size=10.0, material=bs.diffuse("Floor"))
    world = bs.world((0.1, 0.1, 0.1))
    nt = world.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    nt.links.new(sky.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    # A collection instance: its quad has no group (it takes the empty's), its cube its own.
    source = bpy.data.collections.new("Source")
    bs.plane("Quad", size=0.5, material=bs.emission("Quad", strength=1.0), collection=source)
    own = bs.cube("Own", size=0.2, material=bs.emission("Own", strength=1.0), collection=source)
    empty = bpy.data.objects.new("Instancer", None)
    empty.instance_type, empty.instance_collection = "COLLECTION", source
    empty.location = (3.0, 3.0, 0.0)
    scene.collection.objects.link(empty)
    for ob, name in ((key, "key"), (fill, "fill"), (stray, "nowhere"), (glow, "key"), (empty, "fill"),
                     (own, "key")):
        ob.lightgroup = name
    world.lightgroup = "sky"
    core = bs.export().scene
    assert core.light_groups == () and core.emitter_group is None
    assert (core.lights.group == -1).all() and core.world.group == -1

    layer = scene.view_layers[0]
    for name in ("fill", "key", "sky"):
        layer.lightgroups.add(name=name)
    exported = bs.export()
    core = exported.scene
    assert core.light_groups == ("fill", "key", "sky")
    # (a name the view layer does not list is named in an info message)
    assert [m for m in exported.infos if "light group" in m] == [
        "light group 'nowhere' of Stray is not in the view layer's Light Groups: its light is in no "
        "Combined_ pass"]
    lights = core.lights
    by_x = {round(float(p[0])): int(g) for p, g, k in zip(lights.position, lights.group, lights.kind)
            if k != SUN}
    assert by_x == {0: 1, 2: 0, -2: -1}                      # Key, Fill, Stray ("nowhere": none)
    assert lights.group[lights.kind == SUN].tolist() == [2] and core.world.group == 2
    group = core.emitter_group
    assert group is not None and group.dtype == np.int16 and group.shape == (core.triangle_count,)
    for name, expected in (("Glow", 1), ("Floor", -1), ("Quad", 0), ("Own", 1)):
        mine = group[core.material_ids == core.materials.names.index(name)]
        assert len(mine) and (mine == expected).all(), name
    # Groups no object uses: the world in none, no triangle in one.
    for ob in (glow, empty, own):
        ob.lightgroup = ""
    world.lightgroup = "nowhere"
    core = bs.export().scene
    assert core.emitter_group is None and core.world.group == -1
    assert core.lights.group[core.lights.kind == SUN].tolist() == [-1]


def test_unnormalized_point_light_matches_cycles_radiance(scene):
    # Cycles: normalize off skips the 1/(4 pi r^2) area division -> radiance P/pi.
    _, row = export_light("POINT", energy=10.0, shadow_soft_size=0.5, normalize=False)
    r = 0.5
    radiance = row["power"][0] / (4 * math.pi ** 2 * r * r)
    assert radiance == pytest.approx(10.0 / math.pi, rel=1e-5)


def test_temperature_multiplies_the_colour(scene):
    ob, row = export_light("POINT", energy=10.0, use_temperature=True, temperature=3000.0)
    expected = 10.0 * np.array(ob.data.temperature_color[:3])
    assert row["power"] == pytest.approx(expected, rel=1e-5)
    assert row["power"][0] > row["power"][2]


def test_spot_light(scene):
    _, row = export_light("SPOT", energy=50.0, spot_size=math.radians(40), spot_blend=0.3)
    from amcmcppm.core.scene import SPOT
    assert row["kind"] == SPOT and row["power"] == pytest.approx([50, 50, 50])
    assert row["spot_angle"] == pytest.approx(math.radians(40)) and row["spot_blend"] == pytest.approx(0.3)
    assert row["direction"] == pytest.approx([0, 0, -1], abs=1e-6)


@pytest.mark.parametrize("shape,size,size_y,area", [
    ("SQUARE", 2.0, 9.0, 4.0 * 1.5 * 0.5),
    ("RECTANGLE", 2.0, 3.0, 6.0 * 1.5 * 0.5),
    ("DISK", 2.0, 9.0, math.pi * 1.5 * 0.5),
    ("ELLIPSE", 2.0, 3.0, math.pi * 1.5 * 0.5 * 1.5),
])
def test_area_light_shapes_include_object_scale(scene, shape, size, size_y, area):
    from amcmcppm.core.scene import AREA_DISK, AREA_RECT
    ob = bs.light("AREA", location=(0, 0, 3), target=(0, 0, 0), energy=100.0, shape=shape, size=size,
                  size_y=size_y)
    ob.scale = (1.5, 0.5, 2.0)
    bs.camera()
    row = light_row(bs.export().scene)
    assert row["kind"] == (AREA_DISK if shape in ("DISK", "ELLIPSE") else AREA_RECT)
    half_u, half_v = np.linalg.norm(row["axis_u"]), np.linalg.norm(row["axis_v"])
    got = 4 * half_u * half_v * (math.pi / 4 if row["kind"] == AREA_DISK else 1.0)
    assert got == pytest.approx(area, rel=1e-5)
    assert row["direction"] == pytest.approx([0, 0, -1], abs=1e-6)
    assert row["power"] == pytest.approx([100, 100, 100])
    ob.data.normalize = False         # Cycles: radiance P / pi without the area division
    row = light_row(bs.export().scene)
    assert row["power"][0] / (math.pi * area) == pytest.approx(100 / math.pi, rel=1e-5)


def test_a_shadow_catchers_triangles_carry_the_bit(scene):
    """Object > Visibility > Mask > Shadow Catcher: its triangles get SHADOW_CATCHER besides their
    ray visibility (a holdout catcher both bits: the core lets the holdout win), the others do not;
    no warning (before: named in one, rendered as an ordinary surface).  Setting the box tags the
    depsgraph: the export after it sees it, and sees it cleared."""
    from amcmcppm.core.scene import (HOLDOUT_OBJECT, SHADOW_CATCHER, VISIBLE_CAMERA, VISIBLE_GLOSSY,
                                     VISIBLE_TRANSMISSION)
    bs.camera()
    floor = bs.plane("Catcher", material=bs.diffuse("Grey", (0.5, 0.5, 0.5)))
    bs.cube("Box", size=0.5, material=bs.diffuse("Grey"), location=(0, 0, 1))
    held = bs.plane("Held", size=0.5, material=bs.diffuse("Grey"), location=(0, 0, 2))
    assert bs.export().scene.triangle_visibility is None
    floor.is_shadow_catcher = held.is_shadow_catcher = held.is_holdout = True
    ex = bs.export()
    vis = ex.scene.triangle_visibility
    z = ex.scene.vertices[ex.scene.triangles].mean(axis=1)[:, 2]
    every = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION
    assert ex.scene.triangle_count == 16 and not ex.warnings, ex.warnings
    assert set(vis[z < 0.5]) == {every | SHADOW_CATCHER}
    assert set(vis[(z > 0.5) & (z < 1.5)]) == {every}
    assert set(vis[z > 1.5]) == {every | SHADOW_CATCHER | HOLDOUT_OBJECT}
    floor.is_shadow_catcher = False
    vis = bs.export().scene.triangle_visibility
    assert set(vis[z < 0.5]) == {every}


def test_instances_of_shadow_catchers_and_of_catcher_instancers_are_catchers(scene):
    """As Cycles' sync: an instance is a shadow catcher when its object is one or its instancer is
    (here a collection instance's empty, and a mesh instancing on its vertices).  Two empties
    instance a collection of a plain quad and a catcher cube: the catcher empty's quad and cube
    and the plain empty's cube carry SHADOW_CATCHER, the plain empty's quad does not; so do the
    quads a catcher mesh instances on its 4 vertices (and that mesh, which the viewport shows), not
    the instanced quad itself (shown too, at its own place), nor the floor."""
    from amcmcppm.core.scene import SHADOW_CATCHER
    bs.camera()
    bs.plane("Floor", size=20.0, material=bs.diffuse("Floor"))
    source = bpy.data.collections.new("Source")
    bs.plane("Quad", size=0.5, material=bs.diffuse("Quad"), collection=source)
    cube = bs.cube("Own", size=0.2, material=bs.diffuse("Own"), collection=source)
    cube.is_shadow_catcher = True
    for name, x, catcher in (("Catching", 3.0, True), ("Plain", -3.0, False)):
        empty = bpy.data.objects.new(name, None)
        empty.instance_type, empty.instance_collection = "COLLECTION", source
        empty.location = (x, 0.0, 1.0)
        empty.is_shadow_catcher = catcher
        scene.collection.objects.link(empty)
    dots = bs.plane("Dots", size=1.0, material=bs.diffuse("Dots"), location=(0.0, 5.0, 2.0))
    bs.plane("Dot", size=0.2, material=bs.diffuse("Dot")).parent = dots
    dots.instance_type = "VERTS"
    dots.is_shadow_catcher = True
    ex = bs.export()
    sc = ex.scene
    assert not ex.warnings, ex.warnings
    centres = sc.vertices[sc.triangles].mean(axis=1)
    caught = (sc.triangle_visibility & SHADOW_CATCHER) != 0
    names = np.array(sc.materials.names)[sc.material_ids]
    for name, where, expected in (("Floor", centres[:, 2] < 0.5, False),
                                  ("Quad", centres[:, 0] > 2.0, True), ("Own", centres[:, 0] > 2.0, True),
                                  ("Quad", centres[:, 0] < -2.0, False), ("Own", centres[:, 0] < -2.0, True),
                                  ("Dot", np.abs(centres[:, 0]) > 0.25, True),
                                  ("Dot", np.abs(centres[:, 0]) < 0.25, False),
                                  ("Dots", centres[:, 1] > 4.0, True)):
        mine = caught[(names == name) & where]
        assert len(mine) and (mine == expected).all(), (name, expected)
    assert (names == "Quad").sum() == 4 and (names == "Dot").sum() == 10


def test_volume_objects_are_named_in_warnings_and_hair_renders(scene):
    """Volume objects (OpenVDB grids), which Cycles renders without a mesh, are named, not silently
    left out.  Hair renders (since stop 56: before, hair curves and a mesh's hair particles were
    named and left out): a hair object's curves, a plane's 1000 hair particles (the viewport's 5
    keys a strand: its display steps), not those of a particle system switched off.  An empty point
    cloud adds nothing, unnamed."""
    for name, data in (("Fur", bpy.data.hair_curves.new("Fur")),
                       ("Dots", bpy.data.pointclouds.new("Dots")), ("Smoke", bpy.data.volumes.new("Smoke"))):
        bpy.context.scene.collection.objects.link(bpy.data.objects.new(name, data))
    bpy.data.objects["Fur"].data.add_curves([4, 4])
    hairy = bs.plane("Hairy")
    hairy.modifiers.new("Hair", "PARTICLE_SYSTEM")
    hairy.particle_systems[0].settings.type = "HAIR"
    bald = bs.plane("Bald", location=(3, 0, 0))
    off = bald.modifiers.new("Hair", "PARTICLE_SYSTEM")
    off.show_render = off.show_viewport = False
    bald.particle_systems[0].settings.type = "HAIR"
    bs.camera()
    ex = bs.export()
    assert ex.scene.triangle_count == 4 + 2 * (3 * 4) * 8 * 2 + 1000 * (4 * 4) * 8 * 2
    assert any("'Smoke' is a volume object" in w for w in ex.warnings), ex.warnings
    assert not any("'Bald'" in w or "'Dots'" in w or "'Fur'" in w or "'Hairy'" in w for w in ex.warnings), \
        ex.warnings


def test_hair_curves_become_tubes(scene):
    """A Curves object (hair): each curve of two or more points a tube of 8 sides around the
    Catmull-Rom spline through its points (4 pieces a segment), its triangles facing out, its
    corner normals the circle's (perpendicular to the curve), the polygon widened so that its mean
    width is the circle's; the first material slot; Cycles' radius 0.005 without a radius attribute;
    a curve of one point adds nothing.  Poly curves are straight between their points (one piece a
    segment).  The view layer's Filter > Hair box off leaves them out, as Cycles does."""
    red, blue = bs.diffuse("Red", (0.8, 0.1, 0.1)), bs.diffuse("Blue", (0.1, 0.1, 0.8))
    ob = bs.hair_curves("Fur", [[(0, 0, 0), (0, 0, 1), (0, 0, 2)], [(1, 0, 0)], [(2, 0, 0), (2, 0, 1)]],
                        radius=0.1, material=red, location=(0, 0, 1))
    ob.data.materials.append(blue)
    bs.hair_curves("Thin", [[(5, 0, 0), (5, 0, 1)]], location=(0, 0, 1))
    bs.hair_curves("Bent", [[(8, 0, 0), (8, 0, 1), (9, 0, 1)]], radius=0.1, kind="POLY")
    bs.camera(location=(4, -12, 2), target=(4, 0, 1))
    ex = bs.export()
    s = ex.scene
    assert not ex.warnings, ex.warnings
    v = s.vertices[s.triangles].astype(np.float64)                    # (T, 3, 3)
    fur, thin, bent = (v[:, :, 0].mean(axis=1) < lim for lim in (3, 6, 10))
    thin, bent = thin & ~fur, bent & ~thin & ~fur
    assert fur.sum() == (2 + 1) * 4 * 8 * 2 and thin.sum() == 4 * 8 * 2 and bent.sum() == 2 * 8 * 2
    names = [s.materials.names[i] for i in np.unique(s.material_ids[fur])]
    assert names == ["Red"], names
    ng = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    ns = s.shading_normals.astype(np.float64)
    assert (np.einsum("tj,tcj->tc", ng, ns) > 0).all()                 # facing out, as their normals
    # Straight curves along z: normals horizontal, corners at the widened radius from the axis.
    widen = np.pi / (8 * np.sin(np.pi / 8))
    for mask, axis_x, r in ((fur, (0.0, 2.0), 0.1), (thin, (5.0,), 0.005)):
        assert np.abs(ns[mask][..., 2]).max() < 1e-6
        corners = v[mask].reshape(-1, 3)
        dx = corners[:, 0, None] - np.array(axis_x)[None]
        dist = np.sqrt(np.min(np.abs(dx), axis=1) ** 2 + corners[:, 1] ** 2)
        np.testing.assert_allclose(dist, r * widen, rtol=1e-5, atol=1e-6)
        assert corners[:, 2].min() == pytest.approx(1.0, abs=1e-6)
    # The poly curve: its two straight tubes meet in a mitre at the bend (corners on its plane).
    corners = v[bent].reshape(-1, 3)
    assert corners[:, 2].max() == pytest.approx(1.0 + 0.1 * widen, rel=1e-5)
    assert corners[:, 0].max() == pytest.approx(9.0, abs=1e-6)
    bpy.context.view_layer.use_strand = False
    assert bs.export().scene.triangle_count == 0


def test_many_hair_curves_get_fewer_sides(scene, monkeypatch):
    """A hair object whose tubes of 8 sides and 4 pieces a segment would pass the triangle budget
    gets fewer, the first of ``CURVE_LEVELS`` that fits (here, under a budget lowered to 2,000
    triangles: 40 curves of one segment, 6 sides and 4 pieces, 1,920), still facing out."""
    from amcmcppm.amcmcppm_addon.export import mesh
    monkeypatch.setattr(mesh, "SPHERE_BUDGET", 2000)
    bs.hair_curves("Fur", [[(0.1 * i, 0, 0), (0.1 * i, 0, 1)] for i in range(40)], radius=0.01)
    bs.camera()
    ex = bs.export()
    assert ex.scene.triangle_count == 40 * 6 * 4 * 2
    assert any("40 curves as tubes of 6 sides" in m for m in ex.infos), ex.infos


def test_hair_curves_read_curves_info(scene):
    """Curves Info's outputs on the tubes' corners (the values Cycles gives its curves): Is Strand
    1, Intercept the length along the points over the curve's at each ring (0 at the root, 1 at
    the tip), Length the curve's, Thickness twice the radius, Random Cycles'
    hash_uint2_to_float(curve, 0); on a mesh all 0.  (The exact match with Cycles:
    ``test_curves_info_matches_cycles``.)"""
    from core.texture_hash import hash_uint2_to_float
    mat = bs.diffuse("Hair")
    nt = mat.node_tree
    info, comb, comb2 = (nt.nodes.new(k) for k in ("ShaderNodeHairInfo", "ShaderNodeCombineXYZ",
                                                    "ShaderNodeCombineXYZ"))
    for out, sock in (("Is Strand", comb.inputs["X"]), ("Intercept", comb.inputs["Y"]),
                      ("Length", comb.inputs["Z"]), ("Thickness", comb2.inputs["X"]),
                      ("Random", comb2.inputs["Y"])):
        nt.links.new(info.outputs[out], sock)
    add = nt.nodes.new("ShaderNodeVectorMath")
    nt.links.new(comb.outputs[0], add.inputs[0])
    nt.links.new(comb2.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], nt.nodes["Diffuse BSDF"].inputs["Color"])
    bs.hair_curves("Fur", [[(0, 0, 0), (0, 0, 1), (0, 0, 3)], [(2, 0, 0), (2, 0, 2)]], radius=0.1,
                   material=mat, kind="POLY")
    bs.plane("Floor", size=0.5, material=mat, location=(5, 0, 0))
    bs.camera(location=(2, -10, 1), target=(2, 0, 1))
    ex = bs.export()
    s = ex.scene
    assert not ex.warnings, ex.warnings
    from amcmcppm.amcmcppm_addon.export.mesh import HAIR_INFO
    values = {k: s.attributes[k][..., 0].astype(np.float64) for k in HAIR_INFO}
    x = s.vertices[s.triangles][..., 0].astype(np.float64)
    z = s.vertices[s.triangles][..., 2].astype(np.float64)
    first, second, floor = x < 1, (x > 1) & (x < 3), x > 4
    assert values[".hair_is_strand"][first | second].min() == 1
    np.testing.assert_allclose(values[".hair_intercept"][first], z[first] / 3, atol=1e-6)
    np.testing.assert_allclose(values[".hair_intercept"][second], z[second] / 2, atol=1e-6)
    assert values[".hair_length"][first].min() == values[".hair_length"][first].max() == pytest.approx(3.0)
    assert values[".hair_length"][second].max() == pytest.approx(2.0)
    np.testing.assert_allclose(values[".hair_thickness"][first | second], 0.2, rtol=1e-6)
    expected = hash_uint2_to_float(np.arange(2, dtype=np.uint32), np.uint32(0))
    np.testing.assert_allclose(values[".hair_random"][first], expected[0], rtol=1e-6)
    np.testing.assert_allclose(values[".hair_random"][second], expected[1], rtol=1e-6)
    for k in HAIR_INFO:
        assert values[k][floor].max() == 0


def test_a_point_cloud_becomes_spheres(scene):
    """Geometry Nodes' Mesh to Points: each point a sphere of its radius (Cycles' point primitive),
    an icosphere of 1280 triangles (fewer for big clouds) whose corner normals are the sphere's;
    the first material slot.  Before: named in a warning and left out."""
    cloud = bs.point_cloud("Dots", [(0, 0, 0.5), (1, 0, 0.5), (0, 1, 0.8)], radius=0.2,
                           material=bs.diffuse("Red", (0.8, 0.1, 0.1)))
    bs.camera()
    ex = bs.export()
    sc = ex.scene
    assert sc.triangle_count == 3 * 1280 and not [w for w in ex.warnings if "'Dots'" in w], ex.warnings
    centres = np.array([(0, 0, 0.5), (1, 0, 0.5), (0, 1, 0.8)])
    corners = sc.vertices[sc.triangles].reshape(3, -1, 3).astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(corners - centres[:, None], axis=2), 0.2, rtol=1e-5)
    normals = sc.shading_normals.reshape(3, -1, 3)
    np.testing.assert_allclose(normals, (corners - centres[:, None]) / 0.2, atol=1e-5)
    assert sc.materials.names[sc.material_ids[0]] == "Red" and len(set(sc.material_ids)) == 1
    assert cloud.type == "MESH"                          # (the points come from its modifier)


def test_a_point_clouds_attributes_reach_its_spheres(scene):
    """An Attribute node naming a point cloud's attribute (here its ``radius``) reads each point's
    value on the whole of its sphere; Point Info's Position is the point's centre in world space
    (the object moved), 0 on a mesh.  A colour attribute's Alpha is its alpha (the floor lacks it:
    1)."""
    mat = bs.diffuse("ByRadius")
    nt = mat.node_tree
    attr, info, add = (nt.nodes.new(k) for k in ("ShaderNodeAttribute", "ShaderNodePointInfo",
                                                "ShaderNodeVectorMath"))
    attr.attribute_name = "radius"
    tint = nt.nodes.new("ShaderNodeAttribute")
    tint.attribute_name = "tint"
    nt.links.new(attr.outputs["Vector"], add.inputs[0])
    nt.links.new(info.outputs["Position"], add.inputs[1])
    scale = nt.nodes.new("ShaderNodeVectorMath")
    scale.operation = "SCALE"
    nt.links.new(add.outputs["Vector"], scale.inputs[0])
    nt.links.new(tint.outputs["Alpha"], scale.inputs["Scale"])
    nt.links.new(scale.outputs["Vector"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    cloud = bs.point_cloud("Dots", [(0, 0, 0), (1, 0, 0)], material=mat, random_radius=(0.1, 0.3))
    cloud.location = (0.0, 2.0, 0.0)
    tree = cloud.modifiers["Points"].node_group
    store = tree.nodes.new("GeometryNodeStoreNamedAttribute")
    store.data_type, store.domain = "FLOAT_COLOR", "POINT"
    store.inputs["Name"].default_value = "tint"
    store.inputs["Value"].default_value = (0.2, 0.4, 0.6, 0.25)
    output = tree.nodes["Group Output"]
    tree.links.new(output.inputs[0].links[0].from_socket, store.inputs["Geometry"])
    tree.links.new(store.outputs["Geometry"], output.inputs[0])
    bs.plane("Floor", material=mat)
    bs.camera()
    sc = bs.export().scene
    radius = sc.attributes["radius"][..., 0]
    position = sc.attributes[".point_position"]
    spheres = np.flatnonzero(np.abs(position).sum(axis=(1, 2)) > 0)
    assert len(spheres) == 2 * 1280 and len(radius) == len(sc.triangles)
    corners = sc.vertices[sc.triangles[spheres]].astype(np.float64)
    centre = position[spheres, 0]
    np.testing.assert_allclose(np.linalg.norm(corners - centre[:, None], axis=2), radius[spheres], rtol=1e-4)
    assert {tuple(np.round(c, 4)) for c in centre} == {(0.0, 2.0, 0.0), (1.0, 2.0, 0.0)}
    assert 0.1 <= radius[spheres].min() and radius[spheres].max() <= 0.3
    assert not radius[np.setdiff1d(np.arange(len(radius)), spheres)].any()     # (the floor: 0)
    alpha = sc.attributes[".alpha:tint"]
    np.testing.assert_allclose(alpha[spheres], 0.25)
    assert (np.delete(alpha, spheres, axis=0) == 1.0).all()


@pytest.mark.parametrize("fit", ["AUTO", "HORIZONTAL", "VERTICAL"])
def test_a_stereo_eye_is_the_camera_moved_and_shifted(scene, fit):
    """A view of Stereoscopy (``CameraView``: the eye's matrix and Shift X, as Blender gives them)
    renders from the eye with the window moved by the eye's extra shift in units of the side the
    sensor fits (stop 76; before, every view was the camera's own, the right eye black); an
    active object that is not a camera has no eyes."""
    from amcmcppm.amcmcppm_addon.export.camera import CameraView
    scene.render.resolution_x, scene.render.resolution_y = (40, 60) if fit == "AUTO" else (60, 40)
    ob = bs.camera(location=(0, -5, 1), target=(0, 0, 1), lens=40.0)
    ob.data.sensor_fit = fit
    ob.data.shift_x = 0.05
    plain = bs.export().scene.camera
    depsgraph = bpy.context.evaluated_depsgraph_get()
    eye = np.array(depsgraph.scene_eval.camera.matrix_world, np.float64)
    eye[:3, 3] += 0.3 * eye[:3, 0]                      # 30 cm along the camera's x
    view = CameraView("right", eye * np.array([2.0, 2.0, 2.0, 1.0]), 0.05 - 0.02)     # (scaled: removed)
    export = bs.package().amcmcppm_addon.export.export_scene
    cam = export(depsgraph, view=view).scene.camera
    np.testing.assert_allclose(cam.world_from_camera, eye, atol=1e-12)
    x0, x1, y0, y1 = plain.frame
    side = {"HORIZONTAL": x1 - x0, "VERTICAL": y1 - y0}.get(fit, y1 - y0)      # (AUTO: the longer)
    np.testing.assert_allclose(cam.frame, (x0 - 0.02 * side, x1 - 0.02 * side, y0, y1), atol=1e-12)
    empty = bpy.data.objects.new("Empty", None)
    scene.collection.objects.link(empty)
    scene.camera = empty
    alone = bs.export().scene.camera.world_from_camera
    depsgraph = bpy.context.evaluated_depsgraph_get()
    np.testing.assert_array_equal(export(depsgraph, view=view).scene.camera.world_from_camera, alone)


def test_a_deformed_mesh_exports_its_undeformed_vertices_for_generated_coordinates(scene, tmp_path):
    """``Scene.generated_vertices``: a shape-keyed box's undeformed vertices in world space where a
    material reads Generated coordinates (stop 76), through the scene's file too; none for a box
    that nothing deforms, nor where a Subdivision Surface made new vertices (Blender's orco is the
    stack run on the undeformed mesh there: not followed), nor where no material reads them."""
    from amcmcppm.core.scene import Scene
    mat = bs.diffuse("Checked")
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    box = bs.cube("Box", 1.0, mat, location=(2.0, 0.0, 0.0))
    bs.camera()
    assert bs.export().scene.generated_vertices is None
    box.shape_key_add(name="Basis")
    key = box.shape_key_add(name="Up")
    for v in key.data:
        v.co.z += 1.0
    key.value = 1.0
    s = bs.export().scene
    np.testing.assert_allclose(s.generated_vertices, s.vertices - np.float32([0, 0, 1]), atol=1e-6)
    s.save(tmp_path / "s.npz")
    np.testing.assert_array_equal(Scene.load(tmp_path / "s.npz").generated_vertices, s.generated_vertices)
    box.modifiers.new("Subdivision", "SUBSURF")
    assert bs.export().scene.generated_vertices is None
    box.modifiers.clear()
    box.data.materials[0] = bs.diffuse("Plain")
    assert bs.export().scene.generated_vertices is None


def test_a_metaball_exports_with_generated_coordinates(scene):
    """An evaluated mesh whose original object is not a mesh (a metaball here; a curve or text
    that nodes make a mesh) has no undeformed mesh to read: it exports as before (stop 76's
    first version of ``undeformed_positions`` stopped the render: "'MetaBall' object has no
    attribute 'shape_keys'", fuzz case 3433)."""
    mat = bs.diffuse("Checked")
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(checker.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    meta = bpy.data.metaballs.new("Meta")
    meta.elements.new().radius = 1.0
    meta.materials.append(mat)
    scene.collection.objects.link(bpy.data.objects.new("Meta", meta))
    bs.camera()
    s = bs.export().scene
    assert s.triangle_count > 0 and s.generated_vertices is None


def test_a_mix_of_factor_one_whose_unused_side_alone_has_a_roughness_map(scene):
    """A Mix Shader at Factor 1 between a Glossy whose Roughness a Noise drives and a Principled:
    the map has no weight, so the material's roughness is the Principled's constant (before stop
    76 the mix kept a bare number as the roughness program and the export stopped: "a program
    must be a node dict, not float", fuzz case 3766)."""
    mat = bs.diffuse("Mixed")
    nt = mat.node_tree
    nt.nodes.clear()
    out, mix = nt.nodes.new("ShaderNodeOutputMaterial"), nt.nodes.new("ShaderNodeMixShader")
    glossy, noise = nt.nodes.new("ShaderNodeBsdfAnisotropic"), nt.nodes.new("ShaderNodeTexNoise")
    principled = nt.nodes.new("ShaderNodeBsdfPrincipled")
    principled.inputs["Roughness"].default_value = 0.3
    nt.links.new(noise.outputs["Fac"], glossy.inputs["Roughness"])
    nt.links.new(glossy.outputs[0], mix.inputs[1])
    nt.links.new(principled.outputs[0], mix.inputs[2])
    mix.inputs["Fac"].default_value = 1.0
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    row, ex = export_material(mat)
    assert row["roughness_program"] < 0 and row["glossy_roughness"] == pytest.approx(0.3)


def test_a_material_without_an_output_node_is_black(scene):
    """A node tree without a Material Output renders black, as Cycles renders it (before stop 76:
    the viewport colour, grey; fuzz 76: a cube 0.394 against Cycles' 0.349 of a scene whose
    plain diffuse cube both give 0.39), with a note; a material without nodes keeps its viewport
    colour."""
    mat = bs.diffuse("Empty", (0.8, 0.8, 0.8))
    mat.node_tree.nodes.clear()
    row, ex = export_material(mat)
    assert row["diffuse_weight"] == 0 and row["glossy_weight"] == 0 and not row["emission"].any()
    assert any("no material output node; rendered black" in w for w in ex.warnings), ex.warnings


def test_motion_blur_is_named_in_a_warning(scene):
    bs.camera()
    assert not [w for w in bs.export().warnings if "motion blur" in w]
    scene.render.use_motion_blur = True
    ex = bs.export()
    assert any("motion blur is not supported" in w for w in ex.warnings), ex.warnings


@pytest.mark.parametrize("linking", [False, True], ids=["alone", "with_shadow_linking"])
def test_a_light_without_cast_shadow_is_shadowed_by_no_blocker_set(scene, linking):
    """Light > Cast Shadow off: ``Lights.shadow_links`` 0 (no blocker set shadows it), also where
    shadow linking gives the other lights theirs; the others keep every set.  Before: a warning,
    and the light was shadowed."""
    from amcmcppm.core.scene import ALL_LINKS
    shadowless = bs.light("POINT", energy=10.0, name="Shadowless")
    shadowless.data.use_shadow = False
    other = bs.light("POINT", location=(1, 0, 3), energy=10.0, name="Other")
    ball = bs.cube("Ball", size=0.5, location=(0, 0, 0.5))
    bs.plane("Floor", size=4.0)
    if linking:
        only_ball = bpy.data.collections.new("OnlyBall")
        only_ball.objects.link(ball)
        other.light_linking.blocker_collection = only_ball
        shadowless.light_linking.blocker_collection = only_ball
    bs.camera()
    ex = bs.export()
    # (told apart by their x: 0 and 1)
    links = dict(zip(np.where(ex.scene.lights.position[:, 0] > 0.5, "Other", "Shadowless"),
                     ex.scene.lights.shadow_links.tolist()))
    assert links["Shadowless"] == 0 and links["Other"] != 0
    assert (links["Other"] == int(ALL_LINKS)) == (not linking)
    assert not [w for w in ex.warnings if "Cast Shadow" in w], ex.warnings


def test_a_portal_area_light_becomes_a_portal_of_the_world(scene):
    """Cycles' light portals (an area light in a window, ``cycles.is_portal``) guide its sampling
    of the world and emit nothing: exported as a light they would shine as a bright panel in the
    window.  Each becomes a portal of the world (``World.portals``: its centre and half extents,
    light crossing along its -Z; a disk or ellipse marked round), through which the photons from
    afar are aimed; an ordinary area light beside them stays a light."""
    portal = bs.light("AREA", location=(0, 0, 3), energy=100.0, name="Window", size=2.0)
    portal.data.cycles.is_portal = True
    side = bs.light("AREA", location=(2, 0, 1), target=(0, 0, 1), energy=100.0, name="Side", shape="ELLIPSE",
                    size=1.0, size_y=0.5)
    side.data.cycles.is_portal = True
    side.scale = (-1.0, 1.0, 1.0)           # mirrored: still facing its -Z
    bs.light("AREA", location=(0, 1, 3), energy=50.0, name="Lamp")
    bs.camera()
    ex = bs.export()
    assert ex.scene.lights.count == 1
    assert light_row(ex.scene)["power"] == pytest.approx([50, 50, 50])
    world = ex.scene.world
    assert world.portals.shape == (2, 3, 3) and sorted(world.portal_disks.tolist()) == [False, True]
    expected = {False: ((0, 0, 3), (0, 0, -1), (1.0, 1.0)),      # (centre, crossing, half extents)
                True: ((2, 0, 1), (-1, 0, 0), (0.25, 0.5))}
    for (centre, u, v), disk in zip(world.portals, world.portal_disks):
        where, crossing, extents = expected[bool(disk)]
        assert centre == pytest.approx(where, abs=1e-6)
        across = np.cross(u, v)
        assert across / np.linalg.norm(across) == pytest.approx(crossing, abs=1e-6)
        assert sorted([np.linalg.norm(u), np.linalg.norm(v)]) == pytest.approx(sorted(extents))


def test_sun_light(scene):
    from amcmcppm.core.scene import SUN
    _, row = export_light("SUN", energy=3.0, angle=math.radians(2.0))
    assert row["kind"] == SUN and row["power"] == pytest.approx([3, 3, 3])
    assert row["sun_angle"] == pytest.approx(math.radians(2.0))
    assert row["direction"] == pytest.approx([0, 0, -1], abs=1e-6)


def test_dark_and_negative_lights_are_skipped(scene):
    bs.light("POINT", energy=0.0)
    bs.light("POINT", energy=-5.0, name="Negative")
    bs.camera()
    ex = bs.export()
    assert ex.scene.lights.count == 0
    assert any("Negative" in w for w in ex.warnings)


# ---------------------------------------------------------------------- camera and world
def test_perspective_camera_matches_view_frame(scene):
    cam = bs.camera(location=(0, -5, 1), target=(0, 0, 1), lens=35.0)
    cam.data.shift_x, cam.data.shift_y = 0.1, -0.05
    cam.data.sensor_fit = "VERTICAL"
    cam.data.sensor_height = 20.0
    scene.render.resolution_x, scene.render.resolution_y = 60, 40
    c = bs.export().scene.camera
    corners = np.array([tuple(v) for v in cam.data.view_frame(scene=scene)])
    xy = corners[:, :2] / -corners[:, 2:3]
    assert c.frame == pytest.approx((xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()))
    # Vertical fit: the frame height is sensor_height / lens on the z = -1 plane.
    assert c.frame[3] - c.frame[2] == pytest.approx(20.0 / 35.0, rel=1e-5)
    assert c.resolution == (60, 40) and c.projection == "perspective"
    assert np.asarray(c.world_from_camera)[:3, 3] == pytest.approx([0, -5, 1])


def test_the_camera_takes_cycles_pixel_filter(scene):
    """Film > Pixel Filter is Cycles' setting (``scene.cycles``), which our Film panel draws: the
    exported camera's filter and width (Blender's default Blackman-Harris of 1.5; a box is one pixel
    whatever the width, as Cycles renders it), for perspective and panoramic cameras."""
    cam = bs.camera(location=(0, -5, 1), target=(0, 0, 1))
    c = bs.export().scene.camera
    assert (c.pixel_filter, c.filter_width) == ("blackman_harris", 1.5)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "GAUSSIAN", 2.5
    scene.update_tag()
    c = bs.export().scene.camera
    assert (c.pixel_filter, c.filter_width) == ("gaussian", 2.5)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 3.0
    scene.update_tag()
    c = bs.export().scene.camera
    assert (c.pixel_filter, c.filter_width) == ("box", 1.0)
    scene.cycles.pixel_filter_type = "GAUSSIAN"
    cam.data.type, cam.data.panorama_type = "PANO", "EQUIRECTANGULAR"
    scene.update_tag()
    c = bs.export().scene.camera
    assert c.projection == "equirectangular" and (c.pixel_filter, c.filter_width) == ("gaussian", 3.0)


def test_cryptomatte_ids_and_manifests_are_exported_for_the_kinds_asked_for(scene):
    """Scene.cryptomatte_ids (object, material, asset) only when a Cryptomatte box is ticked, and the
    manifests of the ticked kinds alone (what the render's metadata names)."""
    from amcmcppm.core.cryptomatte import name_id
    bs.camera(location=(0, -5, 1), target=(0, 0, 1))
    bs.plane("Floor", size=4.0, material=bs.diffuse("FloorMat", (0.5, 0.5, 0.5)))
    assert bs.export().scene.cryptomatte_ids is None
    scene.view_layers[0].use_pass_cryptomatte_object = True
    exported = bs.export()
    np.testing.assert_array_equal(exported.scene.cryptomatte_ids,
                                  np.float32([[name_id(n)[0] for n in ("Floor", "FloorMat", "Floor")]] * 2))
    assert exported.cryptomatte_manifests == {"crypto_object": {"Floor": name_id("Floor")[1]}}


def test_camera_scale_is_removed_and_percentage_applied(scene):
    cam = bs.camera(location=(0, -5, 1), target=(0, 0, 1))
    cam.scale = (2, 2, 2)
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 101, 50, 50
    c = bs.export().scene.camera
    m = np.asarray(c.world_from_camera)
    assert np.linalg.norm(m[:3, :3], axis=0) == pytest.approx([1, 1, 1])
    assert c.resolution == (50, 25)


def test_orthographic_camera(scene):
    bs.camera(location=(0, 0, 5), target=(0, 0, 0), ortho_scale=4.0)
    scene.render.resolution_x, scene.render.resolution_y = 40, 20
    c = bs.export().scene.camera
    assert c.projection == "orthographic"
    assert c.frame == pytest.approx((-2.0, 2.0, -1.0, 1.0))


def test_depth_of_field(scene):
    cam = bs.camera(location=(0, -5, 0), target=(0, 0, 0), lens=50.0)
    cam.data.dof.use_dof = True
    cam.data.dof.aperture_fstop = 2.0
    cam.data.dof.focus_distance = 3.0
    c = bs.export().scene.camera
    assert c.aperture_radius == pytest.approx(0.05 / 4)
    assert c.focus_distance == pytest.approx(3.0)
    assert (c.aperture_blades, c.aperture_rotation, c.aperture_ratio) == (0, 0.0, 1.0)
    cam.data.dof.aperture_blades, cam.data.dof.aperture_rotation, cam.data.dof.aperture_ratio = 6, 0.5, 1.25
    c = bs.export().scene.camera
    assert (c.aperture_blades, c.aperture_rotation, c.aperture_ratio) == (6, pytest.approx(0.5),
                                                                          pytest.approx(1.25))
    target = bpy.data.objects.new("Focus", None)
    target.location = (1.0, -1.0, 0.5)     # 4 m in front of the camera along its view axis
    scene.collection.objects.link(target)
    cam.data.dof.focus_object = target
    assert bs.export().scene.camera.focus_distance == pytest.approx(4.0, rel=1e-5)
    cam.data.clip_start, cam.data.clip_end = 0.5, 20.0
    c = bs.export().scene.camera
    assert (c.clip_start, c.clip_end) == pytest.approx((0.5, 20.0))


PANORAMAS = [("EQUIRECTANGULAR", (8, 4), {}),
             ("EQUIRECTANGULAR", (6, 4), dict(latitude_min=-0.5, latitude_max=1.0, longitude_min=-1.0,
                                              longitude_max=0.5)),
             ("FISHEYE_EQUIDISTANT", (6, 4), {}), ("FISHEYE_EQUIDISTANT", (4, 6), dict(fisheye_fov=4.0)),
             ("FISHEYE_EQUISOLID", (6, 4), {}),
             ("FISHEYE_EQUISOLID", (5, 7), dict(fisheye_lens=8.0, fisheye_fov=3.5, sensor_width=30.0)),
             ("FISHEYE_EQUISOLID", (7, 5), dict(fisheye_lens=8.0, fisheye_fov=3.5, sensor_height=20.0,
                                                sensor_fit="VERTICAL")),
             ("MIRRORBALL", (6, 4), {})]


@pytest.mark.parametrize("kind, resolution, settings", PANORAMAS,
                         ids=[f"{k.lower()}_{r[0]}x{r[1]}" for k, r, _ in PANORAMAS])
def test_panoramic_cameras_see_the_directions_cycles_sees(scene, tmp_path, kind, resolution, settings):
    """Cycles renders a world whose colour is the ray's direction (Texture Coordinate Generated,
    times 0.5 plus 0.5) at each pixel's centre through a turned panoramic camera; the core's camera
    rays through the same centres point the same way (1e-4), and see nothing at the same pixels
    (outside a fisheye's circle or the ball: black in Cycles).  Before, a panoramic camera
    rendered a perspective view with a warning."""
    scene.render.resolution_x, scene.render.resolution_y = resolution
    world = bs.world()
    nt = world.node_tree
    coords = nt.nodes.new("ShaderNodeTexCoord")
    scale = nt.nodes.new("ShaderNodeVectorMath")
    scale.operation = "MULTIPLY_ADD"
    scale.inputs[1].default_value = scale.inputs[2].default_value = (0.5, 0.5, 0.5)
    nt.links.new(coords.outputs["Generated"], scale.inputs[0])
    nt.links.new(scale.outputs[0], nt.nodes["Background"].inputs["Color"])
    cam = bs.camera(location=(0.3, -0.2, 0.5), target=(1.0, 2.0, 1.2))
    cam.data.type, cam.data.panorama_type = "PANO", "EQUIRECTANGULAR"
    cam.data.panorama_type = kind
    for key, value in settings.items():
        setattr(cam.data, key, value)
    ex = bs.export()
    assert not [w for w in ex.warnings if "camera" in w], ex.warnings
    seen = bs.cycles_pixel_centres(tmp_path / "directions.exr").reshape(-1, 3)
    from amcmcppm.core.camera import generate_camera_rays
    c = ex.scene.camera
    w, h = resolution
    origins, dirs, _, _ = generate_camera_rays(c, np.arange(w * h), np.full((w * h, 4), 0.5))
    sees = dirs.any(axis=1)
    np.testing.assert_array_equal(sees, seen.any(axis=1))
    assert sees.sum() >= w * h // 2
    np.testing.assert_allclose(dirs[sees], 2.0 * seen[sees] - 1.0, atol=1e-4)
    # From the eye, clipped at clip_start along the rays.
    eye = origins[sees] - c.clip_start * dirs[sees]
    np.testing.assert_allclose(eye, np.tile([0.3, -0.2, 0.5], (sees.sum(), 1)), atol=1e-6)


def test_other_panoramas_and_their_depth_of_field_are_noted(scene):
    cam = bs.camera()
    cam.data.type, cam.data.panorama_type = "PANO", "EQUIRECTANGULAR"
    cam.data.panorama_type = "CENTRAL_CYLINDRICAL"
    cam.data.dof.use_dof = True
    ex = bs.export()
    assert ex.scene.camera.projection == "equirectangular"
    assert any("central cylindrical panorama is not supported" in w and "depth of field" in w
               for w in ex.warnings), ex.warnings


def test_border_is_passed_to_the_camera(scene):
    bs.camera()
    r = scene.render
    r.use_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.2, 0.6
    assert bs.export().scene.camera.border == pytest.approx((0.25, 0.75, 0.2, 0.6))


def test_world_background_and_override(scene):
    bs.world((0.2, 0.4, 0.8), strength=2.5)
    bs.camera()
    assert bs.export().scene.world.color == pytest.approx([0.5, 1.0, 2.0])
    other = bpy.data.worlds.new("Other")
    other.node_tree.nodes["Background"].inputs["Color"].default_value = (1, 1, 1, 1)
    other.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.5
    bpy.context.view_layer.world_override = other
    assert bs.export().scene.world.color == pytest.approx([0.5, 0.5, 0.5])


def test_world_ray_visibility_camera_off_shows_black_past_the_scene(scene):
    """World > Ray Visibility > Camera off: camera rays see black past the scene while the world
    still lights it (``World.camera``); the other ray types off keep its light from them
    (``World.exclude``), without a warning."""
    from amcmcppm.core.scene import EXCLUDE_ALL, EXCLUDE_GLOSSY, EXCLUDE_SCATTER
    w = bs.world((0.2, 0.4, 0.8), strength=2.5)
    bs.camera()
    ex = bs.export()
    assert ex.scene.world.camera is None and ex.scene.world.exclude == 0
    w.cycles_visibility.camera = False
    ex = bs.export()
    assert ex.scene.world.color == pytest.approx([0.5, 1.0, 2.0])
    assert ex.scene.world.camera is not None and not ex.scene.world.camera.color.any()
    assert ex.scene.world.exclude == 0
    w.cycles_visibility.glossy = False
    w.cycles_visibility.scatter = False
    ex = bs.export()
    assert ex.scene.world.exclude == EXCLUDE_GLOSSY | EXCLUDE_SCATTER
    w.cycles_visibility.diffuse = False
    w.cycles_visibility.transmission = False
    ex = bs.export()
    assert ex.scene.world.exclude == EXCLUDE_ALL
    assert not [m for m in ex.warnings if "Ray Visibility" in m], ex.warnings


def test_a_world_of_the_view_keeps_its_program_for_camera_rays(scene):
    """A world colour that reads Texture Coordinate's Window (a backplate) is baked with the
    camera's view (before: Window read 0 in a world) and kept as ``World.program`` for camera rays;
    one of the direction alone is only baked."""
    w = bs.world((1.0, 1.0, 1.0))
    nt = w.node_tree
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["Generated"], nt.nodes["Background"].inputs["Color"])
    bs.camera()
    ex = bs.export()
    assert ex.scene.world.program is None and ex.scene.world.texture is not None
    nt.links.new(coords.outputs["Window"], nt.nodes["Background"].inputs["Color"])
    ex = bs.export()
    world = ex.scene.world
    assert world.program is not None and world.texture is not None
    assert np.ptp(world.texture[..., 0]) > 0.5          # (Window varies with the direction)
    assert not [m for m in ex.warnings if "Window" in m], ex.warnings


def test_light_and_emitter_ray_visibility_becomes_what_they_do_not_light(scene):
    """A light's (and an emissive mesh's) Ray Visibility boxes Diffuse, Glossy, Transmission and
    Volume Scatter off: ``Lights.exclude`` (``Scene.emitter_exclude`` for the mesh's triangles)."""
    from amcmcppm.core.scene import EXCLUDE_DIFFUSE, EXCLUDE_GLOSSY, EXCLUDE_SCATTER, VISIBLE_GLOSSY
    bs.camera()
    lamp = bs.light("POINT", (0, 0, 3), energy=100.0)
    panel = bs.plane("Panel", size=1.0, location=(0, 0, 2), material=bs.emission(strength=2.0))
    bs.plane("Floor", size=4.0, material=bs.diffuse(color=(0.5, 0.5, 0.5)))
    ex = bs.export()
    assert ex.scene.lights.exclude.tolist() == [0] and ex.scene.emitter_exclude is None
    lamp.visible_glossy = False
    lamp.visible_volume_scatter = False
    panel.visible_diffuse = False
    ex = bs.export()
    assert ex.scene.lights.exclude.tolist() == [EXCLUDE_GLOSSY | EXCLUDE_SCATTER]
    # (its Glossy box also hides the light from mirrors, as before)
    assert not ex.scene.lights.visibility[0] & VISIBLE_GLOSSY
    bits = ex.scene.emitter_exclude
    emissive = ex.scene.materials.emission[ex.scene.material_ids].any(axis=1)
    assert emissive.any() and (bits[emissive] == EXCLUDE_DIFFUSE).all() and not bits[~emissive].any()


def test_world_texture_warns_and_keeps_the_colour(scene):
    w = bs.world((0.1, 0.1, 0.1))
    nt = w.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "HOSEK_WILKIE"
    nt.links.new(sky.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    bs.camera()
    ex = bs.export()
    assert any("Hosek-Wilkie sky is not supported" in m for m in ex.warnings), ex.warnings
    assert np.isfinite(ex.scene.world.color).all() and ex.scene.world.texture is None


@pytest.mark.parametrize("through_mix", [False, True])
def test_sky_texture_becomes_an_image_and_a_sun(scene, through_mix):
    """Blender 5.0's default sky: baked without its disc, which becomes a sun light (times the
    Background's strength) pointing from the disc; a sky mixed with another colour keeps no disc."""
    w = bs.world((0.0, 0.0, 0.0), strength=2.0)
    nt = w.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sun_elevation, sky.sun_rotation = math.radians(30.0), math.radians(90.0)
    out = sky.outputs["Color"]
    if through_mix:
        mix = nt.nodes.new("ShaderNodeMixRGB")
        mix.inputs["Fac"].default_value = 0.5
        nt.links.new(out, mix.inputs["Color1"])
        out = mix.outputs["Color"]
    nt.links.new(out, nt.nodes["Background"].inputs["Color"])
    bs.camera()
    ex = bs.export()
    world, lights = ex.scene.world, ex.scene.lights
    assert world.texture.shape == (512, 1024, 3) and world.color == pytest.approx([2, 2, 2])
    zenith = world.texture[-1].mean(axis=0)
    assert zenith[2] > zenith[0] > 0                                 # a blue sky
    if through_mix:
        assert lights.count == 0
        assert any("sun disc" in m for m in ex.warnings), ex.warnings
        return
    from amcmcppm.core.sky import sun_disc
    disc = sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(30.0),
                    sun_rotation=math.radians(90.0))
    assert lights.count == 1 and lights.kind[0] == 4                  # SUN
    np.testing.assert_allclose(lights.power[0], 2.0 * disc["irradiance"], rtol=1e-5)
    np.testing.assert_allclose(-lights.direction[0], disc["direction"], atol=1e-6)
    assert disc["direction"][2] == pytest.approx(math.sin(math.radians(30.0)), abs=1e-6)
    assert lights.sun_angle[0] == pytest.approx(sky.sun_size)
    assert not [m for m in ex.warnings if "world" in m]


def test_world_environment_texture_becomes_the_world_image(scene):
    w = bs.world((0.0, 0.0, 0.0))
    nt = w.node_tree
    image = bpy.data.images.new("Studio", 8, 4, float_buffer=True)
    rgba = np.zeros((4, 8, 4), np.float32)
    rgba[..., 0] = np.arange(8)[None, :]
    rgba[..., 1] = np.arange(4)[:, None]
    rgba[..., 3] = 1.0
    image.pixels.foreach_set(rgba.ravel())
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    nt.nodes["Background"].inputs["Strength"].default_value = 2.0
    bs.camera()
    ex = bs.export()
    world = ex.scene.world
    assert world.color == pytest.approx([2, 2, 2]) and not [m for m in ex.warnings if "world" in m]
    np.testing.assert_array_equal(world.texture, rgba[..., :3])         # row 0 = the image's bottom
    assert world.texture_rotation is None
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.pi / 2)
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    ex = bs.export()                     # an unlinked Mapping vector is (0, 0, 0) in Cycles: one colour
    assert ex.scene.world.texture is None and np.isfinite(ex.scene.world.color).all()
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    ex = bs.export()
    assert not [m for m in ex.warnings if "world" in m]
    np.testing.assert_allclose(ex.scene.world.texture_rotation, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-6)
    # Moved (a Point mapping's location changes the direction looked up): baked, exactly.
    mapping.inputs["Location"].default_value = (0.0, 0.0, 0.5)
    ex = bs.export()
    world = ex.scene.world
    assert world.texture_rotation is None and world.texture.shape == (512, 1024, 3)
    assert not [m for m in ex.warnings if "world" in m]


def test_transform_helpers_match_mathutils():
    """The instance transform used by the exporter agrees with mathutils for a mirrored matrix."""
    from amcmcppm.amcmcppm_addon.export import mesh
    rotation = Matrix.Rotation(0.4, 3, "Z").to_quaternion()
    m = Matrix.LocRotScale(Vector((1, 2, 3)), rotation, Vector((-2, 1, 3)))
    vertex_normals = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 0.8, 0.6]], np.float32)
    local = mesh.LocalMesh("t", np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64),
                           np.array([[0, 1, 2]], np.int32), np.zeros(1, np.int32), normals=vertex_normals,
                           normal_index=np.array([[0, 1, 2]], np.int32), uvs=None, mesh_materials=())
    part = mesh.transform_instances(local, np.array(m)[None], np.array([0], np.int32), 0)
    expected = [tuple(m @ Vector(p)) for p in local.positions]
    assert part["vertices"] == pytest.approx(np.array(expected))
    assert part["triangles"].tolist() == [[0, 2, 1]]        # mirrored: winding reversed
    # Shading normals: inverse transpose, renormalised, corners swapped with the winding.
    normal_matrix = m.to_3x3().inverted().transposed()
    expected_n = [tuple((normal_matrix @ Vector(n)).normalized()) for n in vertex_normals[[0, 2, 1]]]
    assert part["normals"][0] == pytest.approx(np.array(expected_n), abs=1e-6)


def test_export_operator_writes_a_core_scene(scene, tmp_path):
    """The .npz the operator writes loads in the core alone (python -m core render scene.npz)."""
    from amcmcppm.core.scene import Scene
    bs.lit_floor_scene()
    assert bpy.ops.amcmcppm.export_scene(filepath=str(tmp_path / "scene.npz")) == {"FINISHED"}
    loaded = Scene.load(tmp_path / "scene.npz")
    assert loaded.triangle_count == 2 and loaded.lights.count == 1
    assert loaded.camera.resolution == (32, 32)


def test_light_ray_visibility_and_soft_falloff(scene):
    from amcmcppm.core.scene import VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION
    ob, row = export_light("POINT", energy=10.0, shadow_soft_size=0.2)
    assert not ob.visible_camera and ob.visible_glossy and ob.visible_transmission   # Blender's defaults
    assert row["visibility"] == VISIBLE_GLOSSY | VISIBLE_TRANSMISSION and row["soft_falloff"]
    ob.visible_camera, ob.visible_glossy = True, False
    ob.data.use_soft_falloff = False
    row = light_row(bs.export().scene)
    assert row["visibility"] == VISIBLE_CAMERA | VISIBLE_TRANSMISSION and not row["soft_falloff"]


def _glossy_with_tangent(name, tangent_node=None, **inputs):
    """A Glossy BSDF material with ``inputs``; ``tangent_node`` (bl_idname, attributes) feeds its
    Tangent input."""
    mat = bs._material(name, "ShaderNodeBsdfAnisotropic", **inputs)
    if tangent_node is not None:
        kind, attrs = tangent_node
        nt = mat.node_tree
        node = nt.nodes.new(kind)
        for key, value in attrs.items():
            setattr(node, key, value)
        bsdf_node = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfAnisotropic")
        nt.links.new(node.outputs[0], bsdf_node.inputs["Tangent"])
    return mat


def test_anisotropy_reaches_the_core_with_cycles_alphas_and_tangents(scene):
    """Glossy and Metallic Anisotropy a: stretch 1 - a (a >= 0) or 1 / (1 + a) (Cycles: alpha_x =
    alpha (1 - a), alpha_y = alpha / (1 - a)); Principled's Anisotropic a: 1 / sqrt(1 - 0.9 a)
    (alpha / aspect, alpha aspect); their rotations in turns.  Unlinked, the tangent is radial
    about Z and the scene carries the objects' Generated coordinates; a Tangent node gives its
    axis or the UV map (the scene then has the UV map's tangents); anything else is noted."""
    from core.bsdf import TANGENT_RADIAL_X, TANGENT_RADIAL_Z, TANGENT_UV
    row, ex = export_material(bs._material("Brushed", "ShaderNodeBsdfAnisotropic", Anisotropy=0.5,
                                           Rotation=0.125))
    assert row["glossy_stretch"] == pytest.approx(0.5) and row["glossy_rotation"] == pytest.approx(0.125)
    assert row["glossy_tangent"] == TANGENT_RADIAL_Z and ex.scene.object_ids is not None
    row, _ = export_material(bs._material("Across", "ShaderNodeBsdfAnisotropic", Anisotropy=-0.5))
    assert row["glossy_stretch"] == pytest.approx(2.0)
    row, _ = export_material(bs._material("Steel", "ShaderNodeBsdfMetallic", Anisotropy=0.3))
    assert row["glossy_stretch"] == pytest.approx(0.7)
    row, _ = export_material(principled("Pan", **{"Metallic": 1.0, "Anisotropic": 0.6,
                                                  "Anisotropic Rotation": 0.3}))
    assert row["glossy_stretch"] == pytest.approx(1.0 / math.sqrt(1.0 - 0.54), rel=1e-6)
    assert row["glossy_rotation"] == pytest.approx(0.3)
    row, _ = export_material(principled("Isotropic", Metallic=1.0))
    assert row["glossy_stretch"] == 1.0
    row, _ = export_material(_glossy_with_tangent("AxisX", ("ShaderNodeTangent", {"axis": "X"}),
                                                  Anisotropy=0.4))
    assert row["glossy_tangent"] == TANGENT_RADIAL_X
    row, ex = export_material(_glossy_with_tangent("Noted", ("ShaderNodeCombineXYZ", {}), Anisotropy=0.4))
    assert row["glossy_tangent"] == TANGENT_RADIAL_Z
    assert any("'Noted'" in w and "Tangent input is not supported" in w for w in ex.warnings), ex.warnings
    mat = _glossy_with_tangent("ByUV", ("ShaderNodeTangent", {"direction_type": "UV_MAP"}), Anisotropy=0.4)
    ob = bs.plane("Plane", material=mat)
    ob.data.uv_layers.new(name="UVMap")
    bs.camera()
    ex = bs.export()
    row = material_row(ex.scene, "ByUV")
    assert row["glossy_tangent"] == TANGENT_UV and ex.scene.tangents is not None
    assert np.abs(ex.scene.tangents[..., :3]).sum() > 0


def test_geometry_tangent_on_a_tangent_input_is_the_default_radial_tangent(scene):
    """Geometry's Tangent (radial about Z, Cycles' ``primitive_tangent``) on a BSDF's Tangent input
    is the default tangent, without a note (before: an unsupported source, noted)."""
    from core.bsdf import TANGENT_RADIAL_Z
    mat = _glossy_with_tangent("ByGeometry", None, Anisotropy=0.4)
    nt = mat.node_tree
    bsdf_node = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfAnisotropic")
    nt.links.new(nt.nodes.new("ShaderNodeNewGeometry").outputs["Tangent"], bsdf_node.inputs["Tangent"])
    row, ex = export_material(mat)
    assert row["glossy_tangent"] == TANGENT_RADIAL_Z
    assert not [w for w in ex.warnings if "Tangent" in w], ex.warnings


def test_an_anisotropy_map_becomes_a_program_of_the_stretch(scene):
    """A texture on Anisotropy (a gradient times a factor) stays a float program of the stretch s
    the core evaluates at each hit, Cycles' alphas: 1 - a for the Glossy BSDF's a >= 0, 1 / (1 + a)
    below, Principled's 1 / sqrt(1 - 0.9 a); the rotation is then read as for any anisotropy.  A
    Mix with an isotropic glossy takes the geometric mean; beside a roughness map it is noted and
    takes its mean."""
    from amcmcppm.core import procedural

    def mapped(name, node_kind, socket, factor, rough_map=False, **inputs):
        mat = bs._material(name, node_kind, **inputs) if node_kind else principled(name, **inputs)
        nt = mat.node_tree
        times = nt.nodes.new("ShaderNodeMath")
        times.operation = "MULTIPLY"
        times.inputs[1].default_value = factor
        gradient = nt.nodes.new("ShaderNodeTexGradient")
        nt.links.new(gradient.outputs["Fac"], times.inputs[0])
        bsdf_node = next(n for n in nt.nodes if n.bl_idname in ("ShaderNodeBsdfAnisotropic",
                                                                 "ShaderNodeBsdfPrincipled"))
        nt.links.new(times.outputs[0], bsdf_node.inputs[socket])
        if rough_map:
            nt.links.new(gradient.outputs["Fac"], bsdf_node.inputs["Roughness"])
        return mat

    attrs = procedural.SampledAttributes()

    def stretches(row, ex):
        assert row["stretch_program"] >= 0, ex.warnings
        return procedural.evaluate(ex.scene.materials.programs[row["stretch_program"]], attrs, [])

    for name, factor, low, high in (("Brushed", 0.9, 0.1, 1.0), ("Across", -0.9, 1.0, 10.0)):
        row, ex = export_material(mapped(name, "ShaderNodeBsdfAnisotropic", "Anisotropy", factor))
        s = stretches(row, ex)
        assert s.min() == pytest.approx(low, rel=0.02) and s.max() == pytest.approx(high, rel=0.02)
        assert row["glossy_stretch"] == pytest.approx(s.mean(), rel=0.01)
        assert not any(name in w for w in ex.warnings), ex.warnings
    from amcmcppm.core.context import RenderContext
    assert "anisotropy maps" in RenderContext(ex.scene).effects
    row, ex = export_material(mapped("Pan", None, "Anisotropic", 1.0, Metallic=1.0))
    s = stretches(row, ex)
    assert s.min() == pytest.approx(1.0, rel=0.02) and s.max() == pytest.approx(10 ** 0.5, rel=0.02)
    # Mixed half and half with an isotropic glossy: exp(log(s) / 2).
    mat = mapped("Mixed", "ShaderNodeBsdfAnisotropic", "Anisotropy", 0.9)
    nt = mat.node_tree
    glossy = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfAnisotropic")
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    plain = nt.nodes.new("ShaderNodeBsdfAnisotropic")
    plain.inputs["Anisotropy"].default_value = 0.0
    nt.links.new(plain.outputs[0], mix.inputs[1])
    nt.links.new(glossy.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, ex = export_material(mat)
    s_mixed = stretches(row, ex)
    row_b, ex_b = export_material(mapped("Brushed2", "ShaderNodeBsdfAnisotropic", "Anisotropy", 0.9))
    np.testing.assert_allclose(s_mixed ** 2, stretches(row_b, ex_b), rtol=1e-9)
    row, ex = export_material(mapped("Both", "ShaderNodeBsdfAnisotropic", "Anisotropy", 0.9, rough_map=True))
    assert row["stretch_program"] == -1 and row["roughness_program"] >= 0
    assert row["glossy_stretch"] == pytest.approx(0.55, rel=0.05)
    assert any("Both" in w and "Anisotropy" in w for w in ex.warnings), ex.warnings


def test_a_rotation_map_becomes_a_program_of_the_tangents_turn(scene):
    """A texture on an anisotropic lobe's Rotation (a spun-metal pattern: a gradient times 0.5)
    stays a float program the core evaluates at each hit, with the mean as the constant and no
    note; on an isotropic lobe it is dropped; a Mix keeps the anisotropic side's map."""
    def mapped(name, node_kind, socket, **inputs):
        mat = bs._material(name, node_kind, **inputs) if node_kind else principled(name, **inputs)
        nt = mat.node_tree
        times = nt.nodes.new("ShaderNodeMath")
        times.operation = "MULTIPLY"
        times.inputs[1].default_value = 0.5
        nt.links.new(nt.nodes.new("ShaderNodeTexGradient").outputs["Fac"], times.inputs[0])
        bsdf_node = next(n for n in nt.nodes if n.bl_idname in ("ShaderNodeBsdfAnisotropic",
                                                                 "ShaderNodeBsdfPrincipled"))
        nt.links.new(times.outputs[0], bsdf_node.inputs[socket])
        return mat

    from amcmcppm.core import procedural
    row, ex = export_material(mapped("Spun", "ShaderNodeBsdfAnisotropic", "Rotation", Anisotropy=0.6))
    program = ex.scene.materials.programs[row["rotation_program"]]
    values = procedural.evaluate(program, procedural.SampledAttributes(), [])
    assert values.min() >= 0.0 and values.max() == pytest.approx(0.5, abs=0.01)
    assert row["glossy_rotation"] == pytest.approx(values.mean(), abs=0.01)
    assert not any("Spun" in w for w in ex.warnings), ex.warnings
    from amcmcppm.core.context import RenderContext
    assert "rotation maps" in RenderContext(ex.scene).effects
    row, ex = export_material(mapped("Pan", None, "Anisotropic Rotation", Metallic=1.0, Anisotropic=0.5))
    assert row["rotation_program"] >= 0 and row["glossy_stretch"] > 1.0
    row, ex = export_material(mapped("Round", "ShaderNodeBsdfAnisotropic", "Rotation", Anisotropy=0.0))
    assert row["rotation_program"] == -1 and row["glossy_stretch"] == 1.0
    mat = mapped("Mixed", "ShaderNodeBsdfAnisotropic", "Rotation", Anisotropy=0.6)
    nt = mat.node_tree
    glossy = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfAnisotropic")
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    nt.links.new(nt.nodes.new("ShaderNodeBsdfDiffuse").outputs[0], mix.inputs[1])
    nt.links.new(glossy.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    row, ex = export_material(mat)
    assert row["rotation_program"] >= 0 and row["diffuse_weight"] == pytest.approx(0.5)


def test_particle_info_of_an_object_without_particles_is_cycles_dummy_particle(scene):
    """Particle Info on an object no particle system made: Cycles' dummy particle 0 (Index, Age,
    Location ... 0; Random its hash, ``hash_uint2_to_float(0, 0)``), read as object properties."""
    from core.texture_hash import hash_uint2_to_float
    mat = bs.diffuse("Dust")
    nt = mat.node_tree
    info = nt.nodes.new("ShaderNodeParticleInfo")
    mix = nt.nodes.new("ShaderNodeCombineXYZ")
    nt.links.new(info.outputs["Random"], mix.inputs["X"])
    nt.links.new(info.outputs["Age"], mix.inputs["Y"])
    nt.links.new(mix.outputs[0], nt.nodes["Diffuse BSDF"].inputs["Color"])
    row, ex = export_material(mat)
    values = ex.scene.object_attributes
    assert float(values["object:.particle:random"][0, 0]) == pytest.approx(float(hash_uint2_to_float(0, 0)))
    assert (values["object:.particle:age"] == 0).all() and not ex.warnings


def test_pass_indices_mist_and_what_the_data_passes_read_reach_the_core(scene):
    """View Layer > Passes: each material's pass index is ``Materials.pass_index`` (the rows of a
    mask's levels too: a Mix of shaders is one Blender material), World > Mist Pass the world's
    ``mist_start``, ``mist_depth`` and ``mist_falloff`` (Quadratic 2, Linear 1, Inverse Quadratic
    0.5; without a world Cycles' film's: from 0 over 100 m, linear, not a new world's 5, 25,
    quadratic).  The objects (their pass index the Object Info's) are exported for the Object Index
    pass and the UVs for the UV pass when the view layer asks for them, and only then when no
    material reads them."""
    bs.camera()
    paint = bs.diffuse("Paint")
    paint.pass_index = 4
    rust = bpy.data.materials.new("Rust")
    nt = rust.node_tree
    metal = nt.nodes.new("ShaderNodeBsdfPrincipled")
    metal.inputs["Metallic"].default_value = 1.0
    mask = nt.nodes.new("ShaderNodeTexGradient")     # (of the world position: no object data read)
    nt.links.new(nt.nodes.new("ShaderNodeNewGeometry").outputs["Position"], mask.inputs["Vector"])
    bs.mix_shaders(nt, mask.outputs["Fac"], nt.nodes["Principled BSDF"], metal)
    rust.pass_index = 9
    plane = bs.plane("Plane", material=paint)
    plane.data.uv_layers.new(name="UVMap")          # (the quad spans 0..1)
    plane.pass_index = 3
    bs.cube("Box", material=rust, location=(0, 0, 2)).pass_index = 6
    ex = bs.export()
    s = ex.scene
    mats = s.materials
    on_box = s.vertices[s.triangles].mean(axis=1)[:, 2] > 1.0
    assert (mats.pass_index.take(s.material_ids) == np.where(on_box, 9, 4)).all()
    levels = [i for i, name in enumerate(mats.names) if name.startswith("Rust (level")]
    assert len(levels) > 2 and (mats.pass_index[levels] == 9).all()
    assert s.object_ids is None and s.uvs is None and s.object_info is None
    # No world: Cycles' film's mist; a world's mist settings.
    assert (s.world.mist_start, s.world.mist_depth, s.world.mist_falloff) == (0.0, 100.0, 1.0)
    mist = bs.world((0.1, 0.1, 0.1)).mist_settings
    mist.start, mist.depth = 1.5, 12.0
    for falloff, power in (("QUADRATIC", 2.0), ("LINEAR", 1.0), ("INVERSE_QUADRATIC", 0.5)):
        mist.falloff = falloff
        world = bs.export().scene.world
        assert (world.mist_start, world.mist_depth, world.mist_falloff) == (1.5, 12.0, power), falloff
    layer = bpy.context.view_layer
    layer.use_pass_object_index = True
    s = bs.export().scene
    assert s.uvs is None and s.object_ids is not None
    assert (s.object_info[:, 1].take(s.object_ids) == np.where(on_box, 6, 3)).all()
    layer.use_pass_uv = True
    layer.use_pass_object_index = False
    s = bs.export().scene
    assert s.object_ids is None and s.uvs is not None and s.uvs.shape == (len(s.triangles), 3, 2)
    assert not s.uvs[on_box].any()
    assert s.uvs[~on_box].min() == 0.0 and s.uvs[~on_box].max() == 1.0


def fibre_shares(row):
    """(what the hair's lobes scatter (3,), what goes on through the fibre (3,)) of a hair
    material's row: the front face stops a ray with its opacity o and scatters weight x colour
    there, the back face lets all through; each face tints by the transparent colour."""
    o = row["opacity"]
    scatter = o * row["glossy_weight"] * row["glossy_color"]
    return scatter, (1.0 - o) * row["transparent_color"] ** 2


@pytest.mark.parametrize("settings", [{"parametrization": "ABSORPTION", "Absorption Coefficient": (0, 0, 0)},
                                      {"parametrization": "MELANIN", "Melanin": 0.0, "Tint": (1, 1, 1, 1)},
                                      {"model": "HUANG", "parametrization": "COLOR", "Color": (1, 1, 1, 1)}])
def test_a_clear_hair_fibre_scatters_or_lets_through_all_the_light(scene, settings):
    """Principled Hair BSDF (stop 56; before, unsupported: grey diffuse): a fibre that absorbs
    nothing reflects at its surface (R) or inside it (TRT and later) or lets the light through (TT),
    and these add up to 1 in each channel (the lobes' shares of a smooth dielectric cylinder, by
    Chiang et al.'s A_p, averaged across the fibre).  R and TRT are a glossy lobe on the front face
    of the curve's tube, TT a transparency of both faces (the back one wholly, by Backfacing)."""
    row, ex = export_material(bs.hair_bsdf("Clear", **settings))
    assert row["diffuse_weight"] == 0 and row["translucent_weight"] == 0 and row["opacity_program"] >= 0
    scatter, through = fibre_shares(row)
    np.testing.assert_allclose(scatter + through, 1.0, atol=1e-4)
    assert 0.05 < scatter.min() and 0.75 < through.min()
    assert any("'Clear'" in w and "approximated" in w for w in ex.warnings), ex.warnings


def test_hair_fibres_take_their_colour_from_absorption(scene):
    """Principled Hair BSDF's parametrizations give Cycles' absorption: the default dark brown
    Color (0.018, 0.006, 0.002: what many fibres together look) lets a single fibre pass under
    half the red and a ninth of the blue; a blonde Color lets through more red than blue; Melanin 0.8
    (pheomelanin) absorbs blue most; a huge Absorption Coefficient leaves only the surface's
    reflection, the fibre's mean Fresnel reflectance at IOR 1.55 (0.0465 face on, 1 at its
    edges), grey; Huang's TT factor 0 lets nothing through, and its R factor 2 doubles R."""
    def shares(**settings):
        return fibre_shares(export_material(bs.hair_bsdf("Hair", **settings))[0])
    scatter, through = shares()                                        # (Chiang, Color, default)
    assert 0.5 > through[0] > through[1] > through[2] and through[2] < 0.15 and scatter.max() < 0.2
    blonde = shares(parametrization="COLOR", Color=(0.6, 0.45, 0.25, 1.0))[1]
    assert blonde[0] > blonde[1] > blonde[2] > 0.5
    melanin = shares(parametrization="MELANIN", Melanin=0.8, **{"Melanin Redness": 1.0})[1]
    assert melanin[0] > melanin[1] > melanin[2]
    scatter, through = shares(parametrization="ABSORPTION", **{"Absorption Coefficient": (1e3, 1e3, 1e3)})
    h = (np.arange(100_000) + 0.5) / 100_000                            # (where light strikes across it)
    cos_i = np.sqrt(1.0 - h * h)
    cos_t = np.sqrt(1.0 - (h / 1.55) ** 2)
    fresnel = 0.5 * (((cos_i - 1.55 * cos_t) / (cos_i + 1.55 * cos_t)) ** 2
                     + ((1.55 * cos_i - cos_t) / (1.55 * cos_i + cos_t)) ** 2)
    assert through.max() < 1e-6
    np.testing.assert_allclose(scatter, fresnel.mean(), rtol=1e-3)
    huang = dict(model="HUANG", parametrization="COLOR", Color=(0.6, 0.45, 0.25, 1.0))
    assert shares(**huang, **{"TT lobe": 0.0})[1].max() == 0
    opaque_r = shares(parametrization="ABSORPTION", model="HUANG",
                      **{"Absorption Coefficient": (1e3, 1e3, 1e3), "R lobe": 2.0})[0]
    np.testing.assert_allclose(opaque_r, 2 * fresnel.mean(), rtol=1e-3)


def test_hair_bsdf_reflects_or_lets_through(scene):
    """Hair BSDF (Cycles' older one): Reflection a glossy lobe of its Color and of RoughnessU,
    Transmission the light going on through the fibre tinted by its Color (both faces of the tube,
    as the Principled Hair BSDF's TT)."""
    row, ex = export_material(bs.hair_bsdf("Shine", "ShaderNodeBsdfHair", component="Reflection",
                                            Color=(0.8, 0.6, 0.4, 1.0), RoughnessU=0.25))
    assert row["opacity"] == 1 and row["glossy_weight"] == pytest.approx(1.0)
    np.testing.assert_allclose(row["glossy_color"], [0.8, 0.6, 0.4], rtol=1e-6)
    assert row["glossy_roughness"] == pytest.approx(0.5)
    row, ex = export_material(bs.hair_bsdf("Veil", "ShaderNodeBsdfHair", component="Transmission",
                                            Color=(0.8, 0.6, 0.4, 1.0)))
    scatter, through = fibre_shares(row)
    np.testing.assert_allclose(through, [0.8, 0.6, 0.4], rtol=1e-5)
    assert row["glossy_weight"] == 0 and row["diffuse_weight"] == 0


@pytest.mark.parametrize("case", ["blonde", "huang_doubled"])
def test_dense_hair_stays_finite(scene, case):
    """Hard hair: 60 strands of a blonde Principled Hair BSDF crossing one another (each tube closed,
    so photons that pass one strand land inside others), and Huang's model with every lobe factor
    2 (its glossy lobe's albedo above 1, the transparency at its cap of 0.999): after every pass
    of PPM and of the chains the image is finite, not negative, its alpha within [0, 1]."""
    from core.integrator import render
    from core.settings import RenderSettings
    settings = {"parametrization": "COLOR", "Color": (0.6, 0.45, 0.25, 1.0)}
    if case == "huang_doubled":
        settings.update({"model": "HUANG", "R lobe": 2.0, "TT lobe": 2.0, "TRT lobe": 2.0})
    rng = np.random.default_rng(3)
    roots = rng.uniform(-0.3, 0.3, (60, 2))
    bends = rng.normal(0.0, 0.3, (60, 2))
    curves = [[(x + b * t * t, y - b2 * t * t, 0.8 * t) for t in np.linspace(0, 1, 6)]
              for (x, y), (b, b2) in zip(roots, bends)]
    bs.hair_curves("Tangle", curves, radius=0.03, material=bs.hair_bsdf("Hair", **settings))
    bs.plane("Floor", size=4.0, material=bs.diffuse("Floor", (0.5, 0.5, 0.5)))
    bs.light("AREA", location=(0.5, -1.0, 2.0), target=(0, 0, 0.3), energy=200.0, size=0.5)
    bs.world((0.2, 0.2, 0.2), strength=1.0)
    bs.camera(location=(0, -2.5, 1.2), target=(0, 0, 0.4))
    bpy.context.scene.render.resolution_x = bpy.context.scene.render.resolution_y = 24
    s = bs.export().scene

    def check(result):
        image = result.image
        assert np.isfinite(image).all() and (image >= 0).all(), result.passes
        assert (image[..., 3] <= 1.0).all(), result.passes

    for method in ("ppm", "amcmcppm"):
        run = RenderSettings(passes=3, photons_per_pass=20_000, workers=1, seed=1, method=method)
        assert render(s, run, on_iteration=check).passes == 3


def test_hair_curves_read_their_colours_and_attributes(scene):
    """A hair object's colour attribute named in a Color Attribute node (on its points: between two
    points as Cycles interpolates along a segment) and an attribute named in an Attribute node (on
    its curves: each curve's value) reach the tubes' corners; an unnamed Color Attribute node reads
    0 (curves have no render colour attribute)."""
    mat = bs.diffuse("Painted")
    nt = mat.node_tree
    color, attribute, add = (nt.nodes.new(k) for k in ("ShaderNodeVertexColor", "ShaderNodeAttribute",
                                                        "ShaderNodeMix"))
    color.layer_name = "Paint"
    attribute.attribute_name = "shade"
    add.data_type, add.blend_type = "RGBA", "ADD"
    add.inputs["Factor"].default_value = 1.0
    nt.links.new(color.outputs["Color"], add.inputs["A"])
    nt.links.new(attribute.outputs["Fac"], add.inputs["B"])
    nt.links.new(add.outputs["Result"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    ob = bs.hair_curves("Fur", [[(0, 0, 0), (0, 0, 1), (0, 0, 2)], [(2, 0, 0), (2, 0, 2)]], radius=0.1,
                        material=mat, kind="POLY")
    cv = ob.data
    paint = cv.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
    paint.data.foreach_set("color", np.array([(1, 0, 0, 1), (0, 1, 0, 1), (0, 0, 1, 1),
                                              (0.2, 0.2, 0.2, 1), (0.6, 0.6, 0.6, 1)], np.float32).ravel())
    cv.attributes.new("shade", "FLOAT", "CURVE").data.foreach_set("value", np.array([0.25, 0.75], np.float32))
    bs.camera(location=(1, -10, 1), target=(1, 0, 1))
    ex = bs.export()
    s = ex.scene
    assert not ex.warnings, ex.warnings
    corners = s.vertices[s.triangles].astype(np.float64)                    # (T, 3, 3)
    x, z = corners[..., 0], corners[..., 2]
    first = x.mean(axis=1) < 1
    colours = s.attributes["Paint"].astype(np.float64)
    keys = np.rint(z[first]).astype(int)                         # (the corners lie at the points)
    np.testing.assert_allclose(colours[first], np.eye(3)[keys], atol=1e-6)      # red, green, blue
    np.testing.assert_allclose(colours[~first][..., 0], 0.2 + 0.2 * z[~first], atol=1e-5)
    shade = s.attributes["shade"][..., 0]
    assert (shade[first] == 0.25).all() and (shade[~first] == 0.75).all()


def test_hair_particles_become_tubes_as_cycles_exports_them(scene):
    """A mesh's hair particle systems (Cycles' ``ObtainCacheParticleData``): each strand a tube
    through its path-cache keys (the viewport's 2^display steps + 1), of radius half the Radius
    Scale times Diameter Root at the root, in the material slot its settings name; the emitter
    hidden (Show Emitter off), the hair still renders; Curves Info's Random numbers the strands on
    across the object's systems (Cycles' ``hash_uint2_to_float(curve, 0)``), Intercept 0 at the
    root; the view layer's Hair box off leaves the particles out too."""
    from core.texture_hash import hash_uint2_to_float
    mat = bs.diffuse("Hair")
    nt = mat.node_tree
    info = nt.nodes.new("ShaderNodeHairInfo")
    comb = nt.nodes.new("ShaderNodeCombineXYZ")
    nt.links.new(info.outputs["Random"], comb.inputs["X"])
    nt.links.new(info.outputs["Intercept"], comb.inputs["Y"])
    nt.links.new(comb.outputs[0], nt.nodes["Diffuse BSDF"].inputs["Color"])
    skin = bs.plane("Skin", size=2.0, material=bs.diffuse("Skin"))
    skin.data.materials.append(mat)
    skin.show_instancer_for_viewport = skin.show_instancer_for_render = False
    for name, count in (("Long", 10), ("Short", 5)):
        settings = skin.modifiers.new(name, "PARTICLE_SYSTEM").particle_system.settings
        settings.type, settings.count, settings.material = "HAIR", count, 2
        settings.hair_length, settings.radius_scale, settings.root_radius = 1.0, 0.1, 1.0
        settings.display_step = 2                                     # (5 keys a strand)
    bs.camera(location=(0, -6, 2), target=(0, 0, 0.5))
    ex = bs.export()
    s = ex.scene
    assert not ex.warnings, ex.warnings
    assert s.triangle_count == 15 * (4 * 4) * 8 * 2                  # (no emitter)
    assert [s.materials.names[i] for i in np.unique(s.material_ids)] == ["Hair"]
    random = np.unique(s.attributes[".hair_random"][..., 0])
    np.testing.assert_allclose(np.sort(random), np.sort(hash_uint2_to_float(np.arange(15, dtype=np.uint32),
                                                                          np.uint32(0))), rtol=1e-6)
    corners = s.vertices[s.triangles].astype(np.float64)
    root = s.attributes[".hair_intercept"][..., 0] == 0
    rings = np.unique(corners[root].reshape(-1, 3).round(6), axis=0)
    assert len(rings) == 15 * 8 and np.abs(rings[:, 2]).max() < 1e-6   # (upright strands rooted on the skin)
    # (the root ring: an octagon of radius 0.05 widened, its sides 2 R sin(pi / 8) long)
    gaps = np.linalg.norm(rings[:, None] - rings[None], axis=2) + np.eye(len(rings))
    widen = np.pi / (8 * np.sin(np.pi / 8))
    np.testing.assert_allclose(gaps.min(axis=1), 2 * 0.05 * widen * np.sin(np.pi / 8), rtol=1e-3)
    bpy.context.view_layer.use_strand = False
    assert bs.export().scene.triangle_count == 0

"""Bad input through the real exporter and engine: a clear warning and a finite image, no crash.

Values that are not numbers (a driver's or script's NaN or infinity) in a mesh, a material or a
light, a clip range that holds nothing, and every shader node Blender 5.0.1 has, in each of its
modes, wired into a material (``make test-slow`` for that sweep).
"""
from __future__ import annotations

import re

import bpy
import numpy as np
import pytest

import blender_scenes as bs

NAN = float("nan")


def _mesh(name, vertices, faces, material=None):
    me = bpy.data.meshes.new(name)
    me.from_pydata(vertices, [], faces)
    if material is not None:
        me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def test_values_that_are_not_numbers_render_with_warnings(scene, tmp_path, capfd):
    """A mesh with a vertex at NaN and one at infinity keeps its other triangle (Cycles' BVH skips
    primitives whose bounds are not finite), a material whose colour is NaN takes the default's,
    a light of NaN or infinite strength is left out; each is named in a warning, and the image is
    finite and lit (before: the render stopped with "vertices contains NaN or infinite values",
    which named no object)."""
    bs.lit_floor_scene()
    before = bs.export().scene.triangle_count
    _mesh("Broken", [(0, 0, 0.5), (NAN, 0, 0.5), (0, 0.3, 0.5), (0.3, 0, 0.5), (0.3, 0.3, 0.5),
                     (0.6, float("inf"), 0.5)], [(0, 3, 2), (0, 1, 2), (3, 4, 5)],
          bs.emission("Glow", strength=2.0))
    bs.cube("Box", size=0.3, material=bs.diffuse("Undefined", (NAN, 0.5, 0.5)), location=(-0.5, 0, 0.15))
    bs.light("SPOT", location=(0.5, 0, 1), energy=NAN, name="Driven")
    bs.light("POINT", location=(-0.5, 0, 1), energy=float("inf"), name="Runaway")
    exported = bs.export()
    assert exported.scene.triangle_count == before + 1 + 12
    assert exported.scene.lights.count == 1
    colours = exported.scene.materials.diffuse_color
    assert np.isfinite(colours).all()
    img = bs.render_exr(tmp_path / "nan.exr")
    assert np.isfinite(img).all() and img[..., :3].mean() > 0
    out = capfd.readouterr().out
    assert ("object 'Broken': 2 of its 3 triangles have a corner at NaN or infinity (a vertex, or a "
            "point's position or radius); they are left out") in out
    assert "material 'Undefined': diffuse_color is not a finite number" in out
    for light in ("Driven", "Runaway"):
        assert f"light '{light}': its strength or placement is not a finite number" in out


def test_points_and_curves_at_undefined_positions_are_left_out(scene, tmp_path):
    """A point of a point cloud at NaN loses its sphere, a hair curve with a point at NaN its tube
    (the other curve keeps its own), a curve whose radius is NaN at a point all of it; each object
    named in a warning with the triangles it lost, the image finite and lit (before: "vertices
    contains NaN or infinite values")."""
    bs.lit_floor_scene()
    before = bs.export().scene.triangle_count
    bs.point_cloud("Dots", [(0, 0, 0.5), (NAN, 0, 0.5), (0.3, 0.2, 0.4)], material=bs.diffuse("Dot"))
    bs.hair_curves("Strands", [[(0, 0, 0.1), (0, NAN, 0.3), (0, 0, 0.5)],
                               [(0.2, 0, 0.1), (0.2, 0, 0.3), (0.2, 0, 0.5)]],
                   radius=0.02, material=bs.diffuse("H"))
    bs.hair_curves("Thread", [[(0, 0.4, 0.1), (0, 0.4, 0.3), (0, 0.4, 0.5)]], radius=[0.02, NAN, 0.02],
                   material=bs.diffuse("H"), kind="POLY")
    exported = bs.export()
    count, out = exported.scene.triangle_count, "\n".join(exported.warnings)
    lost = {}
    for name in ("Dots", "Strands", "Thread"):
        match = re.search(rf"object '{name}': (\d+) of its (\d+) triangles have a corner at NaN or infinity",
                          out)
        assert match, name
        lost[name] = (int(match[1]), int(match[2]))
    assert 3 * lost["Dots"][0] == lost["Dots"][1] and 2 * lost["Strands"][0] == lost["Strands"][1]
    assert lost["Thread"][0] == lost["Thread"][1]
    assert count == before + sum(total - gone for gone, total in lost.values())
    img = bs.render_exr(tmp_path / "points.exr")
    assert np.isfinite(img).all() and img[..., :3].mean() > 0


def test_a_mesh_whose_vertices_are_all_undefined_is_left_out(scene, tmp_path, capfd):
    """(Its object gives no triangles, not an empty mesh.)"""
    bs.lit_floor_scene()
    before = bs.export().scene.triangle_count
    _mesh("Lost", [(NAN, 0, 0), (0, NAN, 0), (0, 0, NAN)], [(0, 1, 2)], bs.diffuse())
    assert bs.export().scene.triangle_count == before
    assert np.isfinite(bs.render_exr(tmp_path / "lost.exr")).all()
    assert "object 'Lost': 1 of its 1 triangles have a corner at NaN or infinity" in capfd.readouterr().out


@pytest.mark.parametrize("clip", [(10.0, 1.0), (1e-6, 1e-6)], ids=["inverted", "equal"])
def test_a_clip_range_that_holds_nothing_shows_the_world(scene, tmp_path, capfd, clip):
    """Clip End not beyond Clip Start (Blender allows both at 1e-6, or the end nearer): camera rays
    meet nothing, and Cycles shows the world alone (checked: 0.300 / 0.198 / 0.100 at the centre of a
    4-sample render of this scene); so do we, with a warning (before: "camera clip range must
    satisfy 0 <= clip_start < clip_end" and no image)."""
    bs.lit_floor_scene()
    bs.world((0.3, 0.2, 0.1))
    cam = bpy.context.scene.camera.data
    cam.clip_start, cam.clip_end = clip
    img = bs.render_exr(tmp_path / "clipped.exr")
    np.testing.assert_allclose(img[..., :3], np.broadcast_to([0.3, 0.2, 0.1], img[..., :3].shape), rtol=1e-5)
    assert "is not beyond Clip Start" in capfd.readouterr().out


@pytest.mark.parametrize("scale, kind", [((0, 1, 1), "PERSP"), ((1, 1, 0), "ORTHO"), ((0, 0, 1), "PANO"),
                                         ((0, 0, 0), "PERSP")], ids=["x", "z-ortho", "xy-pano", "all"])
def test_a_camera_of_zero_scale_shows_the_world(scene, tmp_path, capfd, scale, kind):
    """A camera scaled to zero along any axis (an animated scale passing 0): Cycles shows the world
    alone (checked for each axis, two and all three: 0.300 / 0.200 / 0.100 everywhere); so do we, with
    a warning naming the axes (before: "camera 'Camera' has zero scale" and no image)."""
    bs.lit_floor_scene()
    bs.world((0.3, 0.2, 0.1))
    cam = bpy.context.scene.camera
    cam.scale, cam.data.type = scale, kind
    cam.data.panorama_type = "EQUIRECTANGULAR"     # (a fisheye is black outside its circle)
    img = bs.render_exr(tmp_path / "flat.exr")
    np.testing.assert_allclose(img[..., :3], np.broadcast_to([0.3, 0.2, 0.1], img[..., :3].shape), rtol=1e-5)
    axes = {(0, 1, 1): "X axis", (1, 1, 0): "Z axis", (0, 0, 1): "X and Y axes", (0, 0, 0): "X, Y and Z axes"}
    assert f"camera 'Camera' has zero scale along its local {axes[scale]}, so" in capfd.readouterr().out


def _noise_material(name):
    """A diffuse material coloured by a Noise Texture on its default coordinates (Generated)."""
    mat = bs.diffuse(name)
    noise = mat.node_tree.nodes.new("ShaderNodeTexNoise")
    mat.node_tree.links.new(noise.outputs["Color"], mat.node_tree.nodes["Diffuse BSDF"].inputs["Color"])
    return mat


def test_a_mesh_with_an_undefined_vertex_keeps_its_texture_space(scene, tmp_path):
    """Blender's texture space of a mesh with a vertex at NaN is NaN itself: Generated coordinates
    now take the box of the finite vertices (as Blender's automatic texture space does), so the
    triangle left keeps the texture space of the mesh without that vertex (before: the whole render
    stopped with "texture_spaces contains NaN or infinite values", naming no object)."""
    bs.lit_floor_scene()
    mat = _noise_material("Noisy")
    good = [(0, 0, 0.5), (1, 0, 0.5), (0, 1, 0.5)]
    _mesh("Clean", good, [(0, 1, 2)], mat)
    _mesh("Broken", good + [(NAN, 0, 0.5)], [(0, 1, 2), (1, 2, 3)], mat)
    spaces = bs.export().scene.texture_spaces
    assert np.isfinite(spaces).all()
    assert len(np.unique(spaces[-2:], axis=0)) == 1        # (the floor's, then one a mesh)
    assert np.isnan(bpy.data.meshes["Broken"].texspace_location[0])        # (Blender's own)
    img = bs.render_exr(tmp_path / "texspace.exr")
    assert np.isfinite(img).all() and img[..., :3].mean() > 0


def test_a_flattened_object_reads_object_coordinates(scene, tmp_path):
    """An object scaled to 0 along an axis (an animated scale passing 0) has no inverse transform:
    its Object coordinates take the pseudo-inverse, so the face seen keeps its x and y (Cycles
    inverts such a matrix with 1e-8 added to its diagonal: the same coordinates on the flat face).
    The image equals that of the same box scaled to 1e-6 there, and a box flattened along x whose
    noise reads Object coordinates through a Vector Transform out of object space renders too
    (before: "LinAlgError: Singular matrix" and no image)."""
    images = []
    for flat in (1e-6, 0.0):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bs.empty_scene((24, 24))
        bs.camera(location=(0, 0, 5), target=(0, 0, 0), lens=50.0)
        mat = bpy.data.materials.new("Coordinates")
        nt = mat.node_tree
        nt.nodes.remove(nt.nodes["Principled BSDF"])
        coords, split = nt.nodes.new("ShaderNodeTexCoord"), nt.nodes.new("ShaderNodeSeparateXYZ")
        join, glow = nt.nodes.new("ShaderNodeCombineXYZ"), nt.nodes.new("ShaderNodeEmission")
        nt.links.new(coords.outputs["Object"], split.inputs[0])
        for axis in "XY":
            nt.links.new(split.outputs[axis], join.inputs[axis])
        nt.links.new(join.outputs[0], glow.inputs["Color"])
        nt.links.new(glow.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        bs.cube("Flat", size=2.0, material=mat, location=(0.3, 0.2, 0.5), scale=(0.5, 0.5, flat))
        other = _noise_material("Generated")
        swap = other.node_tree.nodes.new("ShaderNodeVectorTransform")
        swap.convert_from, swap.convert_to = "OBJECT", "WORLD"
        noise = other.node_tree.nodes["Noise Texture"]
        other.node_tree.links.new(other.node_tree.nodes.new("ShaderNodeTexCoord").outputs["Object"],
                                  swap.inputs[0])
        other.node_tree.links.new(swap.outputs[0], noise.inputs["Vector"])
        bs.cube("Generated", size=0.5, material=other, location=(-1.0, -1.0, 0.5), scale=(0.0, 1.0, 1.0))
        images.append(bs.render_exr(tmp_path / f"flat{flat}.exr"))
    assert all(np.isfinite(img).all() for img in images)
    assert images[1][..., :2].max() > 0.5                   # (x and y reach 1 at the face's corners)
    np.testing.assert_allclose(images[1], images[0], atol=2e-3)


def test_a_material_in_a_slot_no_face_uses_may_read_uvs_the_mesh_lacks(scene, tmp_path):
    """A leftover slot whose material reads a UV map (a UV Map node, an Image Texture) on a mesh
    whose faces all use another slot: the exporter leaves the UVs out, and the scene's check now
    asks for them only for the materials some triangle has (before: "materials.programs[0] reads
    'uv' coordinates but the scene has none", and "materials use image textures but the scene has
    no uvs", and no image)."""
    bs.lit_floor_scene()
    reads = bs.diffuse("ReadsUV")
    uv = reads.node_tree.nodes.new("ShaderNodeUVMap")
    reads.node_tree.links.new(uv.outputs[0], reads.node_tree.nodes["Diffuse BSDF"].inputs["Color"])
    image = bpy.data.images.new("Checker", 8, 8)
    image.generated_type = "COLOR_GRID"
    textured = bs.diffuse("Textured")
    texture = textured.node_tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    textured.node_tree.links.new(texture.outputs["Color"],
                                 textured.node_tree.nodes["Diffuse BSDF"].inputs["Color"])
    ob = bs.plane("Leftovers", size=1.0, location=(0, 0, 0.5))
    ob.data.uv_layers.new(name="UVMap")
    for mat in (reads, textured, bs.diffuse("Plain", (0.2, 0.6, 0.2))):
        ob.data.materials.append(mat)
    ob.data.polygons[0].material_index = 2
    # (the floor has no UV map either: lit_floor_scene's plane is made without one)
    exported = bs.export()
    assert exported.scene.uvs is None
    img = bs.render_exr(tmp_path / "slots.exr")
    assert np.isfinite(img).all() and img[..., :3].mean() > 0


def test_an_object_its_transform_takes_past_float32_is_left_out(scene, tmp_path, capfd):
    """A quad with corners at +-3e38 (finite in its object) turned 45 degrees reaches 4.2e38 in the
    world, past float32: its triangles are left out with a warning, as Cycles leaves them (embree
    skips coordinates past 1.844e18), and the floor renders as it does without it (before: "vertices
    contains NaN or infinite values", no image); so is an object moved 1e20 away."""
    bs.lit_floor_scene((16, 12))
    alone = bs.render_exr(tmp_path / "alone.exr")
    s = 3e38
    huge = _mesh("Huge", [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [(0, 1, 2, 3)])
    huge.rotation_euler = (0.0, 0.0, np.radians(45.0))
    huge.location = (0.0, 0.0, -100.0)
    bs.cube("Away", size=1.0, location=(1e20, 0.0, 0.0))
    capfd.readouterr()
    img = bs.render_exr(tmp_path / "huge.exr")
    np.testing.assert_array_equal(img, alone)
    assert ("14 of the scene's 16 triangles have a corner beyond 1.84e+18 or at infinity in world space"
            in capfd.readouterr().out)


def test_a_sky_texture_in_a_material_is_baked_once(scene):
    """A Principled BSDF whose Emission Strength reads a Sky Texture and whose Metallic is textured
    (the exporter evaluates the emission at each of the metallic map's levels): the sky is baked
    once into the export's cache (before: once an evaluation, 18 bakes of 1.5 s each here, and the
    fuzz's renders timed out)."""
    from amcmcppm.amcmcppm_addon.export.materials import MaterialExporter
    from amcmcppm.amcmcppm_addon.export.scene import ExportLog
    mat = bs._material("SkyGlow", "ShaderNodeBsdfPrincipled")
    nt = mat.node_tree
    principled = nt.nodes["Principled BSDF"]
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "MULTIPLE_SCATTERING"
    grey = nt.nodes.new("ShaderNodeRGBToBW")
    nt.links.new(sky.outputs["Color"], grey.inputs[0])
    nt.links.new(grey.outputs[0], principled.inputs["Emission Strength"])
    principled.inputs["Emission Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], principled.inputs["Metallic"])
    exporter = MaterialExporter(ExportLog())
    exporter.material_id(mat)
    assert len(exporter.textures.sky_cache.textures) == 1


def test_eevees_specular_bsdf_renders_black_as_in_cycles(scene, tmp_path, capfd):
    """EEVEE's Specular BSDF (a shader Cycles has no closure for) on the lit floor: black in Cycles,
    black here, with the warning that names it (before: a grey diffuse floor)."""
    scene = bs.lit_floor_scene((8, 8))
    floor = bpy.data.objects["Floor"]
    floor.data.materials[0] = bs._material("Specular", "ShaderNodeEeveeSpecular")
    images = {}
    for engine in ("CYCLES", "AMCMCPPM"):
        scene.render.engine = engine
        scene.cycles.samples = 4
        images[engine] = bs.render_exr(tmp_path / f"{engine}.exr")[..., :3]
    # (Cycles' floor has a pixel or two at 4e-5: its mean 5e-7)
    assert images["CYCLES"].mean() < 1e-5 and images["AMCMCPPM"].max() == 0.0
    assert ("'Specular BSDF' (ShaderNodeEeveeSpecular) rendered black, as Cycles renders it"
            in capfd.readouterr().out)


@pytest.mark.parametrize("kind, lens", [("EMPTY", 50.0), ("MESH", 50.0),
                                        ("SPOT", 16.0 / np.tan(np.radians(30.0))),
                                        ("AREA", 16.0 / np.tan(np.radians(22.5)))],
                         ids=["empty", "mesh", "spot", "area_light"])
def test_an_active_camera_that_is_not_a_camera_renders_its_view_as_cycles(scene, tmp_path, capfd, kind, lens):
    """Blender lets any object be the scene's camera.  Cycles then renders its view through a 50 mm
    lens on a 36 mm sensor (a light: 16 mm / tan(spot size / 2), 45 degrees where the light is not
    a spot; checked against Cycles in bpy 5.0.1: within 4e-6 of a camera of that lens on an
    emitting floor of Generated colours); so do we, with a warning (before: "the active camera is not
    a camera object" and no image)."""
    images = []
    for as_camera in (False, True):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bs.empty_scene((24, 16))
        bs.plane("Floor", size=4.0, material=bs.emission("Glow"))
        glow = bpy.data.materials["Glow"].node_tree
        glow.links.new(glow.nodes.new("ShaderNodeTexCoord").outputs["Generated"],
                       glow.nodes["Emission"].inputs["Color"])
        if as_camera:
            data = bpy.data.cameras.new("Lens")
            data.lens = lens
        elif kind in ("SPOT", "AREA"):
            data = bpy.data.lights.new("Look", kind)
            data.energy = 0.0
            if kind == "SPOT":
                data.spot_size = np.radians(60.0)
        else:
            data = bpy.data.meshes.new("Look") if kind == "MESH" else None
        ob = bpy.data.objects.new("Look", data)
        bpy.context.scene.collection.objects.link(ob)
        ob.location = (0.3, 0.2, 3.0)
        bpy.context.scene.camera = ob
        images.append(bs.render_exr(tmp_path / f"{kind}{as_camera}.exr"))
    assert np.isfinite(images[0]).all()
    np.testing.assert_allclose(images[0], images[1], atol=1e-5)
    assert "the active camera 'Look' is not a camera object: rendering its view as Cycles does" in \
        capfd.readouterr().out


def test_every_setting_at_the_ends_of_its_range_is_a_valid_core_setting(scene):
    """Each number in the panel set to its lowest and its highest value (its hard limits) gives
    settings the core accepts, one at a time: a FloatProperty keeps float32, whose 1e-4 is
    9.99999975e-05, below Initial Mutation Size's bound of 1e-4 (before: "RenderSettings.
    initial_mutation_size must lie in [1e-4, 1e3]" and no image, found by a fuzz sweep)."""
    from amcmcppm.amcmcppm_addon.export import render_settings_from
    from amcmcppm.amcmcppm_addon.properties import CORE_SETTING_NAMES

    props = bpy.context.scene.amcmcppm
    props.time_limit = 60.0             # (Passes 0 with no time limit would never stop: an error)
    checked = 0
    for name in CORE_SETTING_NAMES:
        rna = props.bl_rna.properties[name]
        if rna.type not in ("FLOAT", "INT") or rna.is_readonly:
            continue
        default = getattr(props, name)
        for end in (rna.hard_min, rna.hard_max):
            setattr(props, name, end)
            try:
                render_settings_from(props)
            except ValueError as e:
                raise AssertionError(f"{name} = {getattr(props, name)!r}: {e}") from None
            checked += 1
        setattr(props, name, default)
    assert checked >= 20


# ---------------------------------------------------------------------- every shader node
# Nodes that are not material nodes, or need data this sweep cannot make up (a script, a group).
NOT_SWEPT = {"ShaderNodeTree", "ShaderNode", "ShaderNodeGroup", "ShaderNodeCustomGroup", "ShaderNodeScript",
             "ShaderNodeOutputAOV", "ShaderNodeOutputLight", "ShaderNodeOutputLineStyle",
             "ShaderNodeOutputMaterial", "ShaderNodeOutputWorld"}
SHADER_NODES = sorted(n for n in dir(bpy.types) if n.startswith("ShaderNode") and n not in NOT_SWEPT)
NORMAL_NODES = {"ShaderNodeBump", "ShaderNodeNormalMap", "ShaderNodeBevel"}
DISPLACEMENT_NODES = {"ShaderNodeDisplacement", "ShaderNodeVectorDisplacement"}


# Every node's enumerations of the editor alone (its icon, which warnings it shows).
UI_ENUMS = {"bl_icon", "warning_propagation"}


def _modes(node_type):
    """Settings of ``node_type`` to sweep: {} (its defaults), then each value of each of its
    enumerations (one at a time, the others at their defaults) but ``UI_ENUMS``."""
    nt = bpy.data.materials.new("modes").node_tree
    node = nt.nodes.new(node_type)
    modes = [{}]
    for p in node.bl_rna.properties:
        if (p.type == "ENUM" and not p.is_readonly and not p.is_enum_flag
                and p.identifier not in UI_ENUMS):
            values = [item.identifier for item in p.enum_items]
            if len(values) > 1:
                modes += [{p.identifier: v} for v in values]
    return modes


def _wire(node_type, settings, output):
    """A material with a new ``node_type`` node of ``settings`` whose ``output``-th output (modulo
    its count) drives it: a shader as the Surface (a volume's as the Volume), a displacement as the
    Displacement, a normal as the Principled BSDF's Normal, anything else as its Base Color (and a
    number its Roughness too); a Vector input left open reads the UV map. None where the node
    refuses the settings or has no output."""
    mat = bpy.data.materials.new(f"{node_type} {settings} {output}")
    nt = mat.node_tree
    out, principled = nt.nodes["Material Output"], nt.nodes["Principled BSDF"]
    node = nt.nodes.new(node_type)
    try:
        for key, value in settings.items():
            setattr(node, key, value)
    except (TypeError, ValueError, AttributeError):
        return None
    sockets = [s for s in node.outputs if s.enabled]
    if not sockets:
        return None
    socket = sockets[output % len(sockets)]
    if socket.type == "SHADER":
        nt.links.new(socket, out.inputs["Volume" if "Volume" in node_type else "Surface"])
    elif node_type in DISPLACEMENT_NODES:
        nt.links.new(socket, out.inputs["Displacement"])
    elif node_type in NORMAL_NODES:
        nt.links.new(socket, principled.inputs["Normal"])
    else:
        nt.links.new(socket, principled.inputs["Base Color"])
        if socket.type == "VALUE":
            nt.links.new(socket, principled.inputs["Roughness"])
    coordinates = nt.nodes.new("ShaderNodeTexCoord")
    for socket in node.inputs:
        if socket.enabled and socket.type == "VECTOR" and socket.name == "Vector" and not socket.is_linked:
            nt.links.new(coordinates.outputs["UV"], socket)
    return mat


@pytest.mark.slow
@pytest.mark.parametrize("node_type", SHADER_NODES)
def test_every_shader_node_exports_and_renders_finite(scene, node_type):
    """Each shader node type, in its default settings (each of its first three outputs) and in each
    value of each of its enumerations (Math's operations, Mix's blend modes, Voronoi's features, ...),
    drives the floor's material of a lit scene (a point light, a sun, a grey world): the export
    and a render of one pass (core level, 10 x 10) raise nothing and give a finite image. (The
    sweep found a Sky Texture in a material baked again at every evaluation: 55 s for this render,
    now 4 s: ``test_a_sky_texture_in_a_material_is_baked_once_per_render``.)"""
    from amcmcppm.core.integrator import render
    from amcmcppm.core.settings import RenderSettings
    bs.lit_floor_scene(resolution=(10, 10))
    bs.light("SUN", energy=2.0)
    bs.world((0.1, 0.1, 0.1))
    floor = bpy.data.objects["Floor"]
    cases = [(settings, output) for settings in _modes(node_type)
             for output in (range(3) if not settings else (0,))]
    failures = []
    for k, (settings, output) in enumerate(cases):
        mat = _wire(node_type, settings, output)
        if mat is None:
            continue
        floor.data.materials.clear()
        floor.data.materials.append(mat)
        exported = bs.export()
        image = render(exported.scene, RenderSettings(passes=1, photons_per_pass=2000, workers=1, chains=64,
                                                      seed=k)).image
        if not np.isfinite(image).all():
            failures.append((settings, output))
    assert not failures

"""Small scenes built with the real bpy module for the add-on tests (no operators, no UI context)."""
from __future__ import annotations

import math
import sys

import bpy  # noqa: I001 (first: bmesh and mathutils exist only after it)
import bmesh
import numpy as np
from mathutils import Vector

ENGINE = "AMCMCPPM"
# Fast settings for tests: tiny images and few photons in this process.
# (the engine's own bounce limits: tests set them through ours, Cycles' through scene.cycles)
FAST = {"passes": 2, "time_limit": 0.0, "photons_per_pass": 4000, "workers": 1, "chains": 256,
        "light_paths_from_cycles": False}


def package():
    return sys.modules["amcmcppm"]


def empty_scene(resolution=(32, 32), **settings):
    """Factory-empty scene with our engine, a black world and the FAST settings."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = ENGINE
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    for key, value in {**FAST, **settings}.items():
        setattr(scene.amcmcppm, key, value)
    return scene


# ---------------------------------------------------------------------- materials
def _material(name, node_type, **inputs):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for node in list(nt.nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(node)
    node = nt.nodes.new(node_type)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat


def diffuse(name="Diffuse", color=(0.8, 0.8, 0.8)):
    return _material(name, "ShaderNodeBsdfDiffuse", Color=(*color, 1.0))


def emission(name="Emission", color=(1.0, 1.0, 1.0), strength=1.0):
    return _material(name, "ShaderNodeEmission", Color=(*color, 1.0), Strength=strength)


def mix_with_holdout(mat, shader, fac):
    """Make ``mat``'s surface a Mix Shader of a Holdout (factor 0) and its node ``shader`` (factor
    1) by ``fac``."""
    nt = mat.node_tree
    hold, mix = nt.nodes.new("ShaderNodeHoldout"), nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = fac
    nt.links.new(hold.outputs[0], mix.inputs[1])
    nt.links.new(nt.nodes[shader].outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat


def mix_in(mat, shader, node_type, fac):
    """Make ``mat``'s surface a Mix Shader of its node ``shader`` (factor 0) and a new node of
    ``node_type`` (factor 1) by ``fac``; returns the new node."""
    nt = mat.node_tree
    other, mix = nt.nodes.new(node_type), nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = fac
    nt.links.new(nt.nodes[shader].outputs[0], mix.inputs[1])
    nt.links.new(other.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return other


def mix_shaders(nt, fac, first, second):
    """Make tree ``nt``'s surface a Mix Shader of nodes ``first`` (factor 0) and ``second`` (factor
    1) by the output socket ``fac`` (a mask); returns the Mix node."""
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(fac, mix.inputs["Fac"])
    nt.links.new(first.outputs[0], mix.inputs[1])
    nt.links.new(second.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mix


def volume_material(name, kind, surface=None, **inputs):
    """A material whose Volume output is a new ``kind`` node with ``inputs``, its Surface a new
    ``surface`` node (None: unlinked): (material, volume node)."""
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    out = nt.nodes["Material Output"]
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    if surface is not None:
        nt.links.new(nt.nodes.new(surface).outputs[0], out.inputs["Surface"])
    node = nt.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    nt.links.new(node.outputs[0], out.inputs["Volume"])
    return mat, node


def leaf(name="Leaf", diffuse=(0.8, 0.8, 0.8), translucent=(0.8, 0.8, 0.8), fac=0.5):
    """A Mix Shader of a Diffuse (factor 0) and a Translucent BSDF (factor 1) by ``fac``."""
    mat = _material(name, "ShaderNodeBsdfDiffuse", Color=(*diffuse, 1.0))
    back = mix_in(mat, "Diffuse BSDF", "ShaderNodeBsdfTranslucent", fac)
    back.inputs["Color"].default_value = (*translucent, 1.0)
    return mat


def glass(name="Glass", ior=1.5):
    return _material(name, "ShaderNodeBsdfGlass", IOR=ior)


def add_normal_map(mat, normals, bsdf="Diffuse BSDF", strength=1.0):
    """Feed ``bsdf``'s Normal input of ``mat`` from a tangent-space Normal Map of an image.

    normals : (H, W, 3) unit tangent-space normals (stored as (n + 1) / 2, non-colour data).
    Returns the Normal Map node.
    """
    h, w = normals.shape[:2]
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = (np.asarray(normals) + 1.0) / 2.0
    img = bpy.data.images.new(f"{mat.name} normals", w, h)
    img.colorspace_settings.name = "Non-Color"      # first: changing it regenerates the pixels
    img.pixels.foreach_set(rgba.ravel())
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = strength
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], nt.nodes[bsdf].inputs["Normal"])
    return nmap


def tilted(degrees, towards=0):
    """Unit tangent-space normal tilted ``degrees`` towards the tangent (0) or bitangent (1)."""
    n = np.array([0.0, 0.0, math.cos(math.radians(degrees))])
    n[towards] = math.sin(math.radians(degrees))
    return n


# ---------------------------------------------------------------------- objects
def mesh_object(name, bm, material=None, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1),
                collection=None):
    me = bpy.data.meshes.new(name)
    bm.to_mesh(me)
    bm.free()
    if material is not None:
        me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    (collection or bpy.context.scene.collection).objects.link(ob)
    return ob


def plane(name="Plane", size=2.0, material=None, **kw):
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=size / 2)
    return mesh_object(name, bm, material, **kw)


def cube(name="Cube", size=1.0, material=None, **kw):
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=size)
    return mesh_object(name, bm, material, **kw)


def disk_ngon(name="Disk", radius=1.0, segments=32, material=None, **kw):
    """A disk made of one n-gon (segments corners)."""
    bm = bmesh.new()
    bmesh.ops.create_circle(bm, cap_ends=True, cap_tris=False, segments=segments, radius=radius)
    return mesh_object(name, bm, material, **kw)


def point_cloud(name, points, radius=0.05, material=None, random_radius=None):
    """A mesh object of vertices ``points`` whose Geometry Nodes modifier makes them a point cloud
    of ``radius`` (Mesh to Points; with ``random_radius`` (low, high) a Random Value per point
    instead), with ``material`` (Set Material): the depsgraph then holds a POINTCLOUD instance."""
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(p) for p in points], [], [])
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    given, out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    to_points = tree.nodes.new("GeometryNodeMeshToPoints")
    to_points.inputs["Radius"].default_value = radius
    if random_radius is not None:
        value = tree.nodes.new("FunctionNodeRandomValue")
        value.data_type = "FLOAT"
        value.inputs["Min"].default_value, value.inputs["Max"].default_value = random_radius
        tree.links.new(value.outputs["Value"], to_points.inputs["Radius"])
    tree.links.new(given.outputs[0], to_points.inputs["Mesh"])
    last = to_points.outputs[0]
    if material is not None:
        setter = tree.nodes.new("GeometryNodeSetMaterial")
        setter.inputs["Material"].default_value = material
        tree.links.new(last, setter.inputs["Geometry"])
        last = setter.outputs[0]
    tree.links.new(last, out.inputs[0])
    ob.modifiers.new("Points", "NODES").node_group = tree
    return ob


def hair_curves(name, curves, radius=None, material=None, kind=None, location=(0, 0, 0)):
    """A Curves (hair) object of ``curves`` (a list of point lists), with ``radius`` (one value or a
    value per point; None: no radius attribute, Cycles' 0.005), of curve type ``kind`` (None:
    Catmull-Rom, Blender's default; "POLY", ...) and ``material`` in its first slot."""
    cv = bpy.data.hair_curves.new(name)
    cv.add_curves([len(c) for c in curves])
    points = np.array([p for c in curves for p in c], np.float32)
    cv.attributes["position"].data.foreach_set("vector", points.ravel())
    if radius is not None:
        values = np.broadcast_to(np.asarray(radius, np.float32), (len(points),))
        cv.attributes.new("radius", "FLOAT", "POINT").data.foreach_set("value", np.ascontiguousarray(values))
    if kind is not None:
        cv.set_types(type=kind)
    if material is not None:
        cv.materials.append(material)
    ob = bpy.data.objects.new(name, cv)
    ob.location = location
    bpy.context.scene.collection.objects.link(ob)
    return ob


def hair_bsdf(name, node="ShaderNodeBsdfHairPrincipled", **settings):
    """A material of one hair BSDF ``node`` (Principled Hair or Hair), its properties (model,
    parametrization, component) and inputs set from ``settings``."""
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    hair = nt.nodes.new(node)
    for key, value in settings.items():
        if key in ("model", "parametrization", "component"):
            setattr(hair, key, value)
        else:
            hair.inputs[key].default_value = value
    nt.links.new(hair.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat


def intercept_colours(name, root=(0.8, 0.15, 0.1), tip=(0.1, 0.3, 0.8)):
    """A Diffuse BSDF material whose colour goes from ``root`` to ``tip`` by Curves Info's
    Intercept (0 at a hair's root, 1 at its tip)."""
    mat = diffuse(name, (0.8, 0.8, 0.8))
    nt = mat.node_tree
    info, mix = nt.nodes.new("ShaderNodeHairInfo"), nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["A"].default_value = (*root, 1.0)
    mix.inputs["B"].default_value = (*tip, 1.0)
    nt.links.new(info.outputs["Intercept"], mix.inputs["Factor"])
    nt.links.new(mix.outputs["Result"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    return mat


def camera(location=(0, -4, 3), target=(0, 0, 0), lens=50.0, sensor=36.0, ortho_scale=None):
    cam = bpy.data.cameras.new("Camera")
    cam.lens, cam.sensor_width = lens, sensor
    if ortho_scale is not None:
        cam.type = "ORTHO"
        cam.ortho_scale = ortho_scale
    ob = bpy.data.objects.new("Camera", cam)
    ob.location = location
    ob.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.scene.camera = ob
    return ob


def light(kind, location=(0, 0, 3), target=(0, 0, 0), energy=100.0, name=None, **props):
    data = bpy.data.lights.new(name or kind.title(), kind)
    data.energy = energy
    for key, value in props.items():
        setattr(data, key, value)
    ob = bpy.data.objects.new(data.name, data)
    ob.location = location
    ob.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(ob)
    return ob


def ies_text(vertical=range(0, 91, 15), horizontal=range(0, 361, 45), candela=800.0):
    """A type C IES file whose candela values fall off with the vertical angle v and vary with the
    horizontal angle h as 1 + 0.6 cos(h - 60 degrees) (no mirror symmetry: a profile turned or
    mirrored in the light's frame shows)."""
    v, h = np.radians(list(vertical)), np.radians(list(horizontal))
    values = candela * np.sqrt(np.cos(v))[None, :] * (1.0 + 0.6 * np.cos(h - np.radians(60)))[:, None]
    lines = ["IESNA:LM-63-2002", "[TEST] a test profile", "TILT=NONE",
             f"1 -1 1.0 {len(v)} {len(h)} 1 2 0.1 0.1 0.0", "1.0 1.0 50",
             " ".join(f"{a:g}" for a in vertical), " ".join(f"{a:g}" for a in horizontal)]
    lines += [" ".join(f"{x:.3f}" for x in row) for row in values]
    return "\n".join(lines) + "\n"


def add_ies(ob, text, strength=1.0):
    """Feed the light object ``ob``'s Emission Strength from an IES Texture of ``text`` (internal)."""
    ob.data.use_nodes = True
    nt = ob.data.node_tree
    node = nt.nodes.new("ShaderNodeTexIES")
    node.mode = "INTERNAL"
    node.ies = bpy.data.texts.new("profile.ies")
    node.ies.write(text)
    node.inputs["Strength"].default_value = strength
    nt.links.new(node.outputs["Fac"], nt.nodes["Emission"].inputs["Strength"])
    return node


def world(color=(0.0, 0.0, 0.0), strength=1.0):
    w = bpy.data.worlds.new("World")
    w.color = color
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    bpy.context.scene.world = w
    return w


def world_volume(kind, color=(0.0, 0.0, 0.0), **inputs):
    """The scene's new world of background ``color`` with a new ``kind`` node of ``inputs`` on its
    Volume output."""
    w = world(color)
    nt = w.node_tree
    node = nt.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    nt.links.new(node.outputs[0], nt.nodes["World Output"].inputs["Volume"])
    return w


# ---------------------------------------------------------------------- export and render
def export(scene=None):
    """Export the current scene with the viewport depsgraph (``ExportedScene``)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return package().amcmcppm_addon.export.export_scene(depsgraph)


def emitted_power(core_scene):
    """(3,) power emitted by the scene's emissive triangles: sum of 2 pi A L (two-sided, as Cycles).

    Computed from the public ``core.Scene`` arrays (the units ``core/scene.py`` documents).
    """
    emission = core_scene.materials.emission[core_scene.material_ids].astype(np.float64)
    return (2 * np.pi * triangle_areas(core_scene)) @ emission


def triangle_areas(core_scene):
    p = core_scene.vertices[core_scene.triangles].astype(np.float64)
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def read_exr(path):
    """(H, W, 4) float32 RGBA, top row first."""
    import OpenEXR
    with OpenEXR.File(str(path)) as f:
        return np.asarray(f.channels()["RGBA"].pixels, np.float32)


def render_exr(path, scene=None):
    """Render the scene with write_still into an EXR at ``path`` and return its pixels."""
    scene = scene or bpy.context.scene
    s = scene.render.image_settings
    s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_mode = "RGBA"
    s.color_depth = "32"
    scene.render.filepath = str(path)
    scene.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    return read_exr(path)


def lit_floor_scene(resolution=(32, 32), **settings):
    """A diffuse floor under a point light, seen from above: a quick renderable scene."""
    scene = empty_scene(resolution, **settings)
    plane("Floor", size=4.0, material=diffuse("Floor", (0.8, 0.8, 0.8)))
    light("POINT", location=(0, 0, 2), energy=200.0, shadow_soft_size=0.0)
    camera(location=(0, 0, 5), target=(0, 0, 0), lens=50.0)
    return scene


def deg(x):
    return math.radians(x)


# ---------------------------------------------------------------------- procedural textures
def texture_plane(connect, resolution=(48, 48), size=2.0, location=(0, 0, 0), rotation=(0, 0, 0),
                  scale=(1, 1, 1)):
    """A size x size plane (UVs 0..1) seen straight from above by an orthographic camera that
    frames exactly the plane at the origin: image right is +x, image up is +y.

    ``connect(nt)`` adds nodes to the plane material's tree and returns the colour (or float)
    output socket under test; it drives the Color of a Diffuse BSDF (what our exporter reads).
    Returns the material and the world positions (H, W, 3) of the pixel centres on the plane
    (top row first) when the plane is neither moved nor turned.
    """
    scene = empty_scene(resolution)
    mat = diffuse("Textured")
    nt = mat.node_tree
    nt.links.new(connect(nt), nt.nodes["Diffuse BSDF"].inputs["Color"])
    ob = plane("Plane", size=size, material=mat, location=location, rotation=rotation, scale=scale)
    ob.data.uv_layers.new(name="UVMap")         # Blender's default: the quad spans 0..1
    camera(location=(0, 0, 5), target=(0, 0, 0), ortho_scale=size)
    scene.render.resolution_x, scene.render.resolution_y = resolution
    w, h = resolution
    x = -size / 2 + (np.arange(w) + 0.5) * size / w
    y = size / 2 - (np.arange(h) + 0.5) * size / h
    xy = np.stack(np.meshgrid(x, y), axis=-1)
    return mat, np.concatenate([xy, np.zeros((h, w, 1))], axis=-1)


def cycles_texture_values(mat, path, samples=1):
    """What Cycles evaluates the texture of :func:`texture_plane`'s material to at each pixel
    centre: (H, W, 3).  The socket feeding the Diffuse BSDF is moved to an Emission shader of
    strength 1 (seen directly, 'Standard' view: the pixel is the colour), one sample per pixel
    and a pixel filter of 0.01 pixel, so each pixel is the texture at its centre (with ``samples``:
    the mean of that many evaluations there, for a texture that draws random numbers)."""
    nt = mat.node_tree
    socket = nt.nodes["Diffuse BSDF"].inputs["Color"].links[0].from_socket
    emit = nt.nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = 1.0
    nt.links.new(socket, emit.inputs["Color"])
    nt.links.new(emit.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    scene = bpy.context.scene
    try:
        return cycles_pixel_centres(path, samples)
    finally:
        # Back to the Diffuse BSDF and our engine: the scene can then be exported as built.
        nt.links.new(nt.nodes["Diffuse BSDF"].outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        nt.nodes.remove(emit)
        scene.render.engine = ENGINE


def cycles_pixel_centres(path, samples=1):
    """The current scene rendered by Cycles at one sample with a 0.01-pixel filter (each pixel is
    what the camera sees through its centre): (H, W, 3) float64.  Leaves Cycles selected."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.use_adaptive_sampling, c.use_denoising = "CPU", samples, False, False
    c.filter_width = 0.01
    c.seed = 1
    return render_exr(path)[..., :3].astype(np.float64)


def our_texture_values(positions, emitted=False):
    """The diffuse colour (or with ``emitted`` the radiance emitted) our exporter and core give
    the current scene's surfaces at world ``positions`` (H, W, 3), hit by rays straight down from
    above: (H, W, 3) float64, NaN where a ray misses."""
    from amcmcppm.core.bsdf import DIFFUSE
    from amcmcppm.core.context import RenderContext
    ctx = RenderContext(export().scene)
    p = positions.reshape(-1, 3)
    origins = p + np.array([0.0, 0.0, 1.0])
    hits = ctx.accel.intersect(origins, np.tile([0.0, 0.0, -1.0], (len(p), 1)))
    hit = np.flatnonzero(hits.prim_ids >= 0)
    colors = np.full((len(p), 3), np.nan)
    prim, b1, b2 = hits.prim_ids[hit], hits.b1[hit], hits.b2[hit]
    colors[hit] = ctx.emitted(prim, b1, b2) if emitted else ctx.surface(prim, b1, b2).colors[:, DIFFUSE]
    return colors.reshape(positions.shape)

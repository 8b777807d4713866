"""Build the sample scenes and save them as .blend files next to this script.

    python sample_blends/build_samples.py [name ...]        # with the bpy module
    blender -b --factory-startup -P sample_blends/build_samples.py -- [name ...]

Every scene opens with the AMCMCPPM engine selected and settings that give a
recognisable image in about a minute on two cores (a 60 s time limit).  Units are
metres and watts; materials use Blender's own shader nodes (Diffuse, Glass,
Glossy with roughness 0 as a mirror), so Cycles renders the same files.

* ``cornell_box``: the diffuse Cornell box under a square area light (brightness
  parity with Cycles).
* ``glass_ceiling``: a closed room lit only by an area light outside, through a
  glass pane in the ceiling (Watanabe et al., scene 1).
* ``hole_mirror_glass``: a spot light outside shines through a small hole in a
  wall onto a mirror, which throws the beam through a glass Suzanne onto the
  floor; the camera sees the caustic directly and in the mirror (scene 2).
* ``small_view``: a 400 mm lens sees a 1.5 m wide detail of a sunlit 80 m square
  courtyard (scene 3).
* ``caustic_sds``: a glass sphere's caustic on the floor, seen only through a
  glass block and in a mirror (specular-diffuse-specular paths).
* ``checker_caustic``: a glass sphere and a glass Suzanne throw caustics onto a
  procedural checker floor (Checker on Object coordinates) in front of a wall
  coloured by a Noise Texture through a Color Ramp, under a small spot light.
* ``stained_window``: a room lit by the sun through leaves cut out by an alpha map
  (Principled Alpha) and a stained-glass window (a Glass BSDF coloured by Voronoi
  cells), onto a floor whose roughness a noise varies, with a lamp panel on the
  back wall whose emission a Wave Texture bands; a light portal in the window.
* ``pool_caustics``: the sun through a water surface (Glass of IOR 1.33 bumped by a
  Noise Texture, over a Volume Absorption that tints the deep water) throws caustics
  onto a pool's tiles (a Brick Texture), which the camera sees through the water
  (specular-diffuse-specular paths).
* ``foggy_glass_ceiling``: the glass-ceiling room, its plaster darker, in a world full of
  haze (World > Volume: a Principled Volume): the light through the pane shows as a beam.
* ``glass_lantern``: a room lit only by a glowing gas (a Principled Volume's Emission inside a
  volume-only sphere) held in a solid glass ball on the floor: all its light leaves through
  the glass, so the whole room is lit by caustics.
"""
from __future__ import annotations

import importlib.util
import math
import os
import sys

import bpy  # noqa: I001 (first: with the bpy module, bmesh and mathutils exist only after it)
import bmesh
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
OUTPUT_DIR = os.environ.get("AMCMCPPM_SAMPLES_DIR", HERE)    # tests build into a temporary folder


def load_addon():
    """Register the extension from this checkout (the engine must exist to be selected)."""
    try:
        bpy.context.scene.render.engine = "AMCMCPPM"
        return
    except TypeError:
        pass
    spec = importlib.util.spec_from_file_location("amcmcppm", os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    module = importlib.util.module_from_spec(spec)
    sys.modules["amcmcppm"] = module
    spec.loader.exec_module(module)
    module.register()


class SceneBuilder:
    """Helpers that build objects without operators (no UI context needed)."""

    def __init__(self):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        self.scene = bpy.context.scene
        self.collection = self.scene.collection
        self.materials = {}

    # ------------------------------------------------------------------ materials
    def _material(self, name, node_type, viewport_color, **inputs):
        mat = bpy.data.materials.new(name)
        mat.diffuse_color = (*viewport_color, 1.0)
        nt = mat.node_tree
        for node in list(nt.nodes):
            if node.bl_idname != "ShaderNodeOutputMaterial":
                nt.nodes.remove(node)
        out = nt.nodes["Material Output"]
        bsdf = nt.nodes.new(node_type)
        bsdf.location = (-250, 300)
        for key, value in inputs.items():
            bsdf.inputs[key].default_value = value
        nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
        return mat

    def diffuse(self, name, color):
        return self._material(name, "ShaderNodeBsdfDiffuse", color, Color=(*color, 1.0))

    def glass(self, name, ior=1.5, color=(1.0, 1.0, 1.0)):
        return self._material(name, "ShaderNodeBsdfGlass", (0.8, 0.9, 1.0), Color=(*color, 1.0), IOR=ior)

    def mirror(self, name, color=(0.95, 0.95, 0.95)):
        return self._material(name, "ShaderNodeBsdfGlossy", color, Color=(*color, 1.0), Roughness=0.0)

    def principled(self, name, color):
        return self._material(name, "ShaderNodeBsdfPrincipled", color, **{"Base Color": (*color, 1.0)})

    def emission(self, name, color, strength):
        return self._material(name, "ShaderNodeEmission", color, Color=(*color, 1.0), Strength=strength)

    # ------------------------------------------------------------------ objects
    def mesh_object(self, name, bm, material=None, location=(0, 0, 0), rotation=(0, 0, 0),
                    scale=(1, 1, 1), smooth=False):
        me = bpy.data.meshes.new(name)
        bm.to_mesh(me)
        bm.free()
        if smooth:
            me.shade_smooth()
        if material is not None:
            me.materials.append(material)
        ob = bpy.data.objects.new(name, me)
        ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
        self.collection.objects.link(ob)
        return ob

    def polygons(self, name, polys, material):
        """An object from a list of polygons, each a list of world-space corners."""
        bm = bmesh.new()
        for poly in polys:
            bm.faces.new([bm.verts.new(p) for p in poly])
        bmesh.ops.remove_doubles(bm, verts=bm.verts, dist=1e-6)
        return self.mesh_object(name, bm, material)

    def box(self, name, lo, hi, material):
        bm = bmesh.new()
        bmesh.ops.create_cube(bm, size=1.0)
        size = [h - l for l, h in zip(lo, hi)]
        center = [(l + h) / 2 for l, h in zip(lo, hi)]
        return self.mesh_object(name, bm, material, location=center, scale=size)

    def sphere(self, name, center, radius, material, segments=64, rings=32):
        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
        return self.mesh_object(name, bm, material, location=center, smooth=True)

    def monkey(self, name, location, rotation, scale, material, subdivision=2):
        bm = bmesh.new()
        bmesh.ops.create_monkey(bm)
        ob = self.mesh_object(name, bm, material, location, rotation, scale, smooth=True)
        mod = ob.modifiers.new("Subdivision", "SUBSURF")
        mod.levels = 1
        mod.render_levels = subdivision
        return ob

    def camera(self, location, target, lens=35.0, sensor=36.0):
        cam = bpy.data.cameras.new("Camera")
        cam.lens, cam.sensor_width = lens, sensor
        ob = bpy.data.objects.new("Camera", cam)
        ob.location = location
        direction = Vector(target) - Vector(location)
        ob.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
        self.collection.objects.link(ob)
        self.scene.camera = ob
        return ob

    def light(self, name, kind, location, target=None, energy=100.0, color=(1, 1, 1), **props):
        data = bpy.data.lights.new(name, kind)
        data.energy, data.color = energy, color
        for key, value in props.items():
            setattr(data, key, value)
        ob = bpy.data.objects.new(name, data)
        ob.location = location
        if target is not None:
            direction = Vector(target) - Vector(location)
            ob.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
        self.collection.objects.link(ob)
        return ob

    def world(self, color=(0.0, 0.0, 0.0), strength=1.0):
        world = bpy.data.worlds.new("World")
        world.color = color
        bg = world.node_tree.nodes.get("Background")
        if bg is not None:
            bg.inputs["Color"].default_value = (*color, 1.0)
            bg.inputs["Strength"].default_value = strength
        self.scene.world = world
        return world

    # ------------------------------------------------------------------ saving
    def finish(self, name, resolution, view_transform="AgX", exposure=0.0, **settings):
        scene = self.scene
        scene.name = name
        r = scene.render
        r.engine = "AMCMCPPM"
        r.resolution_x, r.resolution_y = resolution
        r.resolution_percentage = 100
        r.image_settings.file_format = "PNG"
        r.filepath = f"//render/{name}"
        scene.view_settings.view_transform = view_transform
        scene.view_settings.exposure = exposure
        # About a minute on two cores: stop at 60 s; the pass count is open.
        defaults = {"passes": 0, "time_limit": 60.0, "workers": 0}
        for key, value in {**defaults, **settings}.items():
            setattr(scene.amcmcppm, key, value)
        path = os.path.join(OUTPUT_DIR, f"{name}.blend")
        bpy.context.preferences.filepaths.save_version = 0       # no .blend1 backups
        bpy.ops.wm.save_as_mainfile(filepath=path, compress=True)
        return path


def texture(nt, kind, on_object=True, **inputs):
    """A texture node ``kind`` added to ``nt`` with ``inputs`` set, on Object coordinates (else
    on its default, Generated)."""
    node = nt.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    if on_object:
        nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Object"], node.inputs["Vector"])
    return node


def ramp(nt, fac, low, high):
    """The Color output of a Color Ramp from ``low`` to ``high`` (RGB) over the socket ``fac``."""
    node = nt.nodes.new("ShaderNodeValToRGB")
    node.color_ramp.elements[0].color = (*low, 1.0)
    node.color_ramp.elements[1].color = (*high, 1.0)
    nt.links.new(fac, node.inputs["Fac"])
    return node.outputs["Color"]


def rect_with_hole(corner, u, v, hole):
    """Four quads covering the rectangle corner + [0,1]u + [0,1]v minus the hole (u0, u1, v0, v1)."""
    c, u, v = Vector(corner), Vector(u), Vector(v)
    u0, u1, v0, v1 = hole

    def quad(a0, a1, b0, b1):
        return [c + a0 * u + b0 * v, c + a1 * u + b0 * v, c + a1 * u + b1 * v, c + a0 * u + b1 * v]

    return [quad(0, 1, 0, v0), quad(0, 1, v1, 1), quad(0, u0, v0, v1), quad(u1, 1, v0, v1)]


def room(b, name, lo, hi, material, holes=None):
    """A closed box of six walls (diffuse both sides); ``holes`` maps a wall name to a hole."""
    holes = holes or {}
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    walls = {
        "floor": ((x0, y0, z0), (x1 - x0, 0, 0), (0, y1 - y0, 0)),
        "ceiling": ((x0, y0, z1), (x1 - x0, 0, 0), (0, y1 - y0, 0)),
        "back": ((x0, y1, z0), (x1 - x0, 0, 0), (0, 0, z1 - z0)),
        "front": ((x0, y0, z0), (x1 - x0, 0, 0), (0, 0, z1 - z0)),
        "left": ((x0, y0, z0), (0, y1 - y0, 0), (0, 0, z1 - z0)),
        "right": ((x1, y0, z0), (0, y1 - y0, 0), (0, 0, z1 - z0)),
    }
    polys = []
    for wall, (corner, u, v) in walls.items():
        c, uu, vv = Vector(corner), Vector(u), Vector(v)
        if wall in holes:
            polys += rect_with_hole(c, uu, vv, holes[wall])
        else:
            polys.append([c, c + uu, c + uu + vv, c + vv])
    return b.polygons(name, polys, material)


# ---------------------------------------------------------------------- scenes
def cornell_box():
    b = SceneBuilder()
    white = b.diffuse("White", (0.73, 0.73, 0.73))
    red = b.diffuse("Red", (0.63, 0.065, 0.05))
    green = b.diffuse("Green", (0.14, 0.45, 0.091))
    b.polygons("Floor and ceiling", [
        [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
        [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)],
        [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)]], white)
    b.polygons("Left wall", [[(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)]], red)
    b.polygons("Right wall", [[(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)]], green)
    tall = b.box("Tall block", (-0.3, -0.3, 0), (0.3, 0.3, 1.2), white)
    tall.location = (-0.33, 0.3, 0.6)
    tall.rotation_euler = (0, 0, math.radians(17))
    short = b.box("Short block", (-0.3, -0.3, 0), (0.3, 0.3, 0.6), white)
    short.location = (0.35, -0.3, 0.3)
    short.rotation_euler = (0, 0, math.radians(-17))
    b.light("Ceiling light", "AREA", (0, 0, 1.98), target=(0, 0, 0), energy=40.0, size=0.5,
            color=(1.0, 0.85, 0.65))
    b.camera((0, -3.9, 1.0), (0, 0, 1.0), lens=50.0)
    b.world((0.0, 0.0, 0.0))
    return b.finish("cornell_box", (256, 256), view_transform="Standard", photons_per_pass=100_000)


def glass_ceiling_room():
    """The glass-ceiling room's builder, not yet saved (glass_ceiling, foggy_glass_ceiling)."""
    b = SceneBuilder()
    wall = b.diffuse("Plaster", (0.75, 0.72, 0.68))
    floor = b.diffuse("Floor", (0.45, 0.32, 0.22))
    blue = b.diffuse("Blue", (0.1, 0.2, 0.6))
    glass = b.glass("Pane glass", ior=1.5)
    room(b, "Room", (-2, -2, 0), (2, 2, 2.5), wall, holes={"ceiling": (0.35, 0.65, 0.45, 0.75)})
    b.polygons("Floor", [[(-1.99, -1.99, 0.001), (1.99, -1.99, 0.001), (1.99, 1.99, 0.001),
                          (-1.99, 1.99, 0.001)]], floor)
    # The pane fills the hole (x in [-0.6, 0.6], y in [-0.2, 1.0]) and is 2 cm thick.
    b.box("Glass pane", (-0.6, -0.2, 2.49), (0.6, 1.0, 2.51), glass)
    b.box("Cube", (0.6, -0.4, 0), (1.3, 0.3, 0.7), blue)
    b.sphere("Ball", (-0.8, 0.4, 0.45), 0.45, wall)
    b.light("Sky light", "AREA", (0.0, 0.4, 5.0), target=(0.0, 0.4, 0.0), energy=5000.0, size=1.2,
            color=(1.0, 0.95, 0.88))
    b.camera((1.7, -1.8, 1.5), (-0.3, 0.5, 0.6), lens=22.0)
    b.world((0.0, 0.0, 0.0))
    return b


def glass_ceiling():
    return glass_ceiling_room().finish("glass_ceiling", (320, 240), photons_per_pass=100_000)


def foggy_glass_ceiling():
    """The glass-ceiling room in a world full of haze (World > Volume: a Principled Volume of
    Density 0.06, Anisotropy 0.3), its plaster darker: the light through the pane shows as a beam."""
    b = glass_ceiling_room()
    # Darker plaster, so that the beam stands out against the light the walls send around.
    plaster = bpy.data.materials["Plaster"]
    plaster.node_tree.nodes["Diffuse BSDF"].inputs["Color"].default_value = (0.2, 0.19, 0.18, 1.0)
    plaster.diffuse_color = (0.2, 0.19, 0.18, 1.0)
    nt = b.scene.world.node_tree
    fog = nt.nodes.new("ShaderNodeVolumePrincipled")
    fog.location = (0, -200)
    fog.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
    fog.inputs["Density"].default_value = 0.06
    fog.inputs["Anisotropy"].default_value = 0.3
    nt.links.new(fog.outputs[0], nt.nodes["World Output"].inputs["Volume"])
    return b.finish("foggy_glass_ceiling", (320, 240), photons_per_pass=100_000)


def hole_mirror_glass():
    b = SceneBuilder()
    wall = b.diffuse("Plaster", (0.7, 0.7, 0.7))
    floor = b.diffuse("Floor", (0.6, 0.55, 0.5))
    mirror = b.mirror("Mirror")
    glass = b.glass("Suzanne glass", ior=1.5)
    stand = b.diffuse("Stand", (0.3, 0.3, 0.3))
    hole_center = Vector((-3.0, 0.0, 2.4))
    # The wall at x = -3 has a 30 cm square hole around hole_center.
    room(b, "Room", (-3, -2, 0), (3, 2, 3), wall,
         holes={"left": ((2.0 - 0.15) / 4, (2.0 + 0.15) / 4, (2.4 - 0.15) / 3, (2.4 + 0.15) / 3)})
    b.polygons("Floor", [[(-2.99, -1.99, 0.001), (2.99, -1.99, 0.001), (2.99, 1.99, 0.001),
                          (-2.99, 1.99, 0.001)]], floor)
    # The beam through the hole hits the mirror centre; the mirror reflects it through Suzanne.
    mirror_center = Vector((1.5, 0.0, 1.4))
    suzanne_center = Vector((0.0, 0.0, 0.7))
    d_in = (mirror_center - hole_center).normalized()
    d_out = (suzanne_center - mirror_center).normalized()
    normal = (d_out - d_in).normalized()
    mirror_ob = b.polygons("Mirror", [[(0, -1.2, -0.6), (0, 1.2, -0.6), (0, 1.2, 0.6), (0, -1.2, 0.6)]],
                           mirror)
    mirror_ob.location = mirror_center
    mirror_ob.rotation_euler = Vector((1.0, 0.0, 0.0)).rotation_difference(normal).to_euler()
    b.monkey("Suzanne", suzanne_center, (0.0, 0.0, math.radians(-90)), (0.45, 0.45, 0.45), glass)
    b.box("Stand", (-0.08, -0.08, 0.0), (0.08, 0.08, 0.35), stand)
    # A narrow spot 6 m outside: its cone is a little wider than the hole.
    spot_at = hole_center - 6.0 * d_in
    b.light("Sun spot", "SPOT", tuple(spot_at), target=tuple(hole_center), energy=12000.0,
            spot_size=math.radians(8.0), spot_blend=0.1, shadow_soft_size=0.02, color=(1.0, 0.93, 0.8))
    b.camera((-2.5, -1.8, 1.6), (0.6, 0.2, 0.7), lens=24.0)
    b.world((0.0, 0.0, 0.0))
    return b.finish("hole_mirror_glass", (320, 240), exposure=1.0, photons_per_pass=100_000)


def small_view():
    b = SceneBuilder()
    ground = b.diffuse("Ground", (0.5, 0.5, 0.48))
    stone = b.diffuse("Stone", (0.65, 0.6, 0.52))
    red = b.diffuse("Red", (0.7, 0.12, 0.08))
    glass = b.glass("Glass", ior=1.5)
    b.polygons("Ground", [[(-40, -40, 0), (40, -40, 0), (40, 40, 0), (-40, 40, 0)]], ground)
    # A courtyard of pillars, instanced from one mesh (collection instances share the mesh).
    pillar = b.box("Pillar", (-0.5, -0.5, 0), (0.5, 0.5, 6.0), stone)
    pillars = bpy.data.collections.new("Pillars")
    pillars.objects.link(pillar)
    b.collection.objects.unlink(pillar)
    for i in range(-3, 4):
        for j in range(-3, 4):
            if (i, j) == (0, 0):
                continue
            inst = bpy.data.objects.new(f"Pillar {i} {j}", None)
            inst.instance_type = "COLLECTION"
            inst.instance_collection = pillars
            inst.location = (i * 10.0, j * 10.0, 0.0)
            b.collection.objects.link(inst)
    # The detail the camera sees: a glass ball and a red cube, 1.5 m across.
    b.sphere("Glass ball", (0.0, 0.0, 0.25), 0.25, glass)
    b.box("Red cube", (0.35, 0.1, 0.0), (0.65, 0.4, 0.3), red)
    b.light("Sun", "SUN", (0, 0, 20), target=(-0.6, -0.35, 0.0), energy=5.0, angle=math.radians(1.0),
            color=(1.0, 0.95, 0.85))
    b.camera((16.0, -24.0, 9.0), (0.15, 0.1, 0.15), lens=400.0)
    b.world((0.05, 0.07, 0.1))
    return b.finish("small_view", (320, 240), photons_per_pass=100_000)


def caustic_sds():
    b = SceneBuilder()
    floor = b.diffuse("Floor", (0.7, 0.7, 0.7))
    wall = b.diffuse("Wall", (0.5, 0.55, 0.6))
    glass = b.glass("Sphere glass", ior=1.5)
    block_glass = b.glass("Block glass", ior=1.5)
    mirror = b.mirror("Mirror")
    b.polygons("Floor", [[(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)]], floor)
    b.polygons("Back wall", [[(-4, 3, 0), (4, 3, 0), (4, 3, 3), (-4, 3, 3)]], wall)
    b.sphere("Glass sphere", (0.0, 0.5, 0.9), 0.5, glass)
    # The camera sees the floor under the sphere only through this block and in the mirror.
    b.box("Glass block", (-1.0, -1.1, 0.0), (1.0, -0.7, 1.2), block_glass)
    b.polygons("Mirror", [[(-1.5, 2.9, 0.2), (1.5, 2.9, 0.2), (1.5, 2.9, 1.6), (-1.5, 2.9, 1.6)]], mirror)
    b.light("Spot", "SPOT", (0.3, 0.4, 3.0), target=(0.0, 0.5, 0.9), energy=800.0,
            spot_size=math.radians(26.0), spot_blend=0.05, shadow_soft_size=0.02)
    b.camera((0.0, -3.2, 0.9), (0.0, 0.5, 0.35), lens=32.0)
    b.world((0.03, 0.03, 0.035))
    return b.finish("caustic_sds", (320, 240), photons_per_pass=100_000)


def checker_caustic():
    b = SceneBuilder()
    floor = b.diffuse("Checker floor", (0.8, 0.8, 0.8))
    nt = floor.node_tree
    checker = texture(nt, "ShaderNodeTexChecker", Scale=2.0, Color1=(0.75, 0.72, 0.65, 1.0),
                      Color2=(0.12, 0.14, 0.2, 1.0))
    nt.links.new(checker.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    wall = b.diffuse("Noise wall", (0.5, 0.5, 0.5))
    nt = wall.node_tree
    noise = texture(nt, "ShaderNodeTexNoise", on_object=False, Scale=3.0, Detail=4.0)
    nt.links.new(ramp(nt, noise.outputs["Fac"], (0.15, 0.25, 0.4), (0.7, 0.6, 0.45)),
                 nt.nodes["Diffuse BSDF"].inputs["Color"])
    glass = b.glass("Glass", ior=1.5)
    tinted = b.glass("Green glass", ior=1.45, color=(0.7, 0.95, 0.75))
    b.polygons("Floor", [[(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)]], floor)
    b.polygons("Wall", [[(-4, 2.5, 0), (4, 2.5, 0), (4, 2.5, 3), (-4, 2.5, 3)]], wall)
    b.sphere("Glass sphere", (-0.7, 0.4, 0.55), 0.55, glass)
    b.monkey("Glass Suzanne", (0.8, 0.6, 0.5), (math.radians(-20), 0.0, math.radians(25)), (0.5, 0.5, 0.5),
             tinted)
    b.light("Spot", "SPOT", (-1.5, -1.0, 3.2), target=(0.0, 0.5, 0.4), energy=1500.0,
            spot_size=math.radians(40.0), spot_blend=0.1, shadow_soft_size=0.03)
    b.camera((0.0, -3.5, 1.6), (0.0, 0.5, 0.3), lens=35.0)
    b.world((0.02, 0.02, 0.025))
    return b.finish("checker_caustic", (320, 240), photons_per_pass=100_000)


def stained_window():
    b = SceneBuilder()
    wall = b.diffuse("Plaster", (0.72, 0.7, 0.66))
    # Stained glass: a Glass BSDF coloured by Voronoi cells (random colours, lightened).
    stained = b.glass("Stained glass", ior=1.5)
    nt = stained.node_tree
    cells = texture(nt, "ShaderNodeTexVoronoi", Scale=5.0)
    lighten = nt.nodes.new("ShaderNodeMixRGB")
    lighten.inputs["Fac"].default_value = 0.3
    lighten.inputs["Color2"].default_value = (1.0, 1.0, 1.0, 1.0)
    nt.links.new(cells.outputs["Color"], lighten.inputs["Color1"])
    nt.links.new(lighten.outputs["Color"], nt.nodes["Glass BSDF"].inputs["Color"])
    # The floor: a Principled BSDF whose roughness a noise varies from 0.15 to 0.55.
    floor = b.principled("Floor", (0.35, 0.22, 0.12))
    nt = floor.node_tree
    noise = texture(nt, "ShaderNodeTexNoise", on_object=False, Scale=4.0)
    nt.links.new(ramp(nt, noise.outputs["Fac"], (0.15,) * 3, (0.55,) * 3),
                 nt.nodes["Principled BSDF"].inputs["Roughness"])
    # Leaves outside the window: green discs cut out of planes by an alpha map.
    leaves = b.principled("Leaves", (0.15, 0.35, 0.08))
    nt = leaves.node_tree
    discs = texture(nt, "ShaderNodeTexVoronoi", Scale=2.5)
    inside = nt.nodes.new("ShaderNodeMath")
    inside.operation = "LESS_THAN"
    inside.inputs[1].default_value = 0.45
    nt.links.new(discs.outputs["Distance"], inside.inputs[0])
    nt.links.new(inside.outputs[0], nt.nodes["Principled BSDF"].inputs["Alpha"])
    # A lamp panel on the back wall whose emission a Wave Texture bands.
    lamp = b.emission("Lamp panel", (1.0, 0.8, 0.55), 6.0)
    nt = lamp.node_tree
    wave = texture(nt, "ShaderNodeTexWave", Scale=3.0)
    nt.links.new(wave.outputs["Fac"], nt.nodes["Emission"].inputs["Strength"])
    # A room 5 x 4 x 2.6 m with a 1.6 x 1.4 m window in the wall at x = -2.5.
    room(b, "Room", (-2.5, -2, 0), (2.5, 2, 2.6), wall,
         holes={"left": (0.3, 0.7, 0.8 / 2.6, 2.2 / 2.6)})
    b.polygons("Floor", [[(-2.49, -1.99, 0.001), (2.49, -1.99, 0.001), (2.49, 1.99, 0.001),
                          (-2.49, 1.99, 0.001)]], floor)
    b.box("Window", (-2.51, -0.8, 0.8), (-2.49, 0.8, 2.2), stained)
    for i, (y, z, tilt) in enumerate(((-0.5, 1.9, 20.0), (0.4, 1.4, -15.0))):
        b.polygons(f"Leaves {i}", [[(0, -0.6, -0.45), (0, 0.6, -0.45), (0, 0.6, 0.45), (0, -0.6, 0.45)]],
                   leaves).location = (-3.0 - 0.15 * i, y, z)
        bpy.data.objects[f"Leaves {i}"].rotation_euler = (math.radians(tilt), 0.0, math.radians(10.0))
    b.polygons("Lamp", [[(-0.4, 1.99, 1.5), (0.4, 1.99, 1.5), (0.4, 1.99, 2.0), (-0.4, 1.99, 2.0)]], lamp)
    b.light("Sun", "SUN", (-6.0, 0.0, 5.0), target=(0.0, 0.3, 0.0), energy=6.0, angle=math.radians(1.0),
            color=(1.0, 0.95, 0.85))
    # A light portal just outside the window (Cycles' Portal box): the sun's and the sky's photons
    # are aimed through it (it emits nothing).
    b.light("Window portal", "AREA", (-2.52, 0.0, 1.5), target=(0.0, 0.0, 1.5), shape="RECTANGLE", size=1.6,
            size_y=1.4).data.cycles.is_portal = True
    b.camera((2.3, -1.8, 1.5), (-1.0, 0.2, 0.5), lens=20.0)
    b.world((0.04, 0.05, 0.07))
    return b.finish("stained_window", (320, 240), exposure=1.0, photons_per_pass=100_000)


def pool_caustics():
    b = SceneBuilder()
    # Tiles: a Brick Texture on Object coordinates (white tiles, grey grout).
    tiles = b.diffuse("Tiles", (0.7, 0.75, 0.78))
    nt = tiles.node_tree
    brick = texture(nt, "ShaderNodeTexBrick", Scale=4.0, Color1=(0.55, 0.75, 0.85, 1.0),
                    Color2=(0.45, 0.68, 0.8, 1.0), Mortar=(0.25, 0.27, 0.3, 1.0))
    brick.offset = 0.0
    nt.links.new(brick.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    # The water's surface: a Glass BSDF (IOR 1.33) whose normal a Noise Texture bumps, over a
    # Volume Absorption that takes red out of the light the deeper it goes (0.4 / 0.1 / 0.05 a
    # metre: light down to the floor and back up keeps 0.41 / 0.80 / 0.89).
    water = b.glass("Water", ior=1.33, color=(1.0, 1.0, 1.0))
    nt = water.node_tree
    absorb = nt.nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.6, 0.9, 0.95, 1.0)
    absorb.inputs["Density"].default_value = 1.0
    nt.links.new(absorb.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    noise = texture(nt, "ShaderNodeTexNoise", Scale=2.5, Detail=3.0)
    bump = nt.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.08
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], nt.nodes["Glass BSDF"].inputs["Normal"])
    deck = b.diffuse("Deck", (0.6, 0.55, 0.48))
    # A basin 4 x 3 m and 1.2 m deep, its rim at z = 0, filled to z = -0.1.
    b.polygons("Basin", [[(-2, -1.5, -1.2), (2, -1.5, -1.2), (2, 1.5, -1.2), (-2, 1.5, -1.2)],
                         [(-2, 1.5, -1.2), (2, 1.5, -1.2), (2, 1.5, 0), (-2, 1.5, 0)],
                         [(-2, -1.5, 0), (2, -1.5, 0), (2, -1.5, -1.2), (-2, -1.5, -1.2)],
                         [(-2, -1.5, -1.2), (-2, 1.5, -1.2), (-2, 1.5, 0), (-2, -1.5, 0)],
                         [(2, -1.5, 0), (2, 1.5, 0), (2, 1.5, -1.2), (2, -1.5, -1.2)]], tiles)
    b.polygons("Deck", [[(-4, -4, 0), (4, -4, 0), (4, -1.5, 0), (-4, -1.5, 0)],
                        [(-4, 1.5, 0), (4, 1.5, 0), (4, 4, 0), (-4, 4, 0)],
                        [(-4, -1.5, 0), (-2, -1.5, 0), (-2, 1.5, 0), (-4, 1.5, 0)],
                        [(2, -1.5, 0), (4, -1.5, 0), (4, 1.5, 0), (2, 1.5, 0)]], deck)
    b.polygons("Water surface", [[(-2, -1.5, -0.1), (2, -1.5, -0.1), (2, 1.5, -0.1), (-2, 1.5, -0.1)]], water)
    b.light("Sun", "SUN", (0, 0, 10), target=(0.6, 0.4, -3.0), energy=4.0, angle=math.radians(0.5),
            color=(1.0, 0.96, 0.9))
    b.camera((0.0, -4.2, 2.6), (0.0, 0.2, -0.9), lens=28.0)
    b.world((0.25, 0.35, 0.5), strength=0.6)
    return b.finish("pool_caustics", (320, 240), photons_per_pass=100_000)


def glass_lantern():
    """A glowing gas in a solid glass ball (radius 0.35 m, IOR 1.5) on the floor of a closed
    room, its only light: a volume-only sphere of radius 0.2 m whose Principled Volume emits an
    orange Emission Strength 20 and scatters a little (Density 1.5, Anisotropy 0.2)."""
    b = SceneBuilder()
    wall = b.diffuse("Plaster", (0.7, 0.7, 0.7))
    floor = b.diffuse("Floor", (0.5, 0.45, 0.4))
    blue = b.diffuse("Blue", (0.1, 0.2, 0.6))
    glass = b.glass("Ball glass", ior=1.5)
    gas = bpy.data.materials.new("Glowing gas")
    gas.diffuse_color = (1.0, 0.45, 0.15, 1.0)
    nt = gas.node_tree
    for node in list(nt.nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(node)
    glow = nt.nodes.new("ShaderNodeVolumePrincipled")
    glow.inputs["Color"].default_value = (0.75, 0.75, 0.75, 1.0)
    glow.inputs["Density"].default_value = 1.5
    glow.inputs["Anisotropy"].default_value = 0.2
    glow.inputs["Emission Strength"].default_value = 20.0
    glow.inputs["Emission Color"].default_value = (1.0, 0.45, 0.15, 1.0)
    nt.links.new(glow.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    room(b, "Room", (-2, -2, 0), (2, 2, 2.5), wall)
    b.polygons("Floor", [[(-1.99, -1.99, 0.001), (1.99, -1.99, 0.001), (1.99, 1.99, 0.001),
                          (-1.99, 1.99, 0.001)]], floor)
    b.sphere("Glass ball", (0.0, 0.2, 0.351), 0.35, glass)
    b.sphere("Gas", (0.0, 0.2, 0.351), 0.2, gas, segments=32, rings=16)
    cube = b.box("Cube", (-0.25, -0.25, -0.3), (0.25, 0.25, 0.3), blue)
    cube.location = (0.9, 0.6, 0.3)
    cube.rotation_euler = (0, 0, 0.5)
    b.sphere("Ball", (-0.9, 0.9, 0.3), 0.3, wall)
    b.camera((1.6, -1.8, 1.3), (0.0, 0.3, 0.3), lens=24.0)
    b.world((0.0, 0.0, 0.0))
    return b.finish("glass_lantern", (320, 240), photons_per_pass=100_000)


def fur_under_glass():
    """The glass-ceiling room with a furry ball in the light through its pane: a sphere of radius
    0.25 m grows 1200 hair particles 8 cm long (10 interpolated children each in a render, Radius
    Scale 0.01 tapering to the tip) of a Principled Hair BSDF (Chiang's model, Melanin 0.55,
    Redness 0.6), rendered as tubes of triangles (README, "Hair")."""
    b = glass_ceiling_room()
    skin = b.diffuse("Skin", (0.25, 0.15, 0.1))
    hair = b._material("Fur", "ShaderNodeBsdfHairPrincipled", (0.35, 0.2, 0.1))
    fibre = hair.node_tree.nodes["Principled Hair BSDF"]
    fibre.parametrization = "MELANIN"                   # (before its inputs: Blender hides the others)
    fibre.inputs["Melanin"].default_value = 0.55
    fibre.inputs["Melanin Redness"].default_value = 0.6
    ball = b.sphere("Fur ball", (-0.1, -0.05, 0.25), 0.25, skin, segments=32, rings=16)
    ball.data.materials.append(hair)
    settings = ball.modifiers.new("Fur", "PARTICLE_SYSTEM").particle_system.settings
    settings.type, settings.count, settings.hair_length, settings.material = "HAIR", 1200, 0.08, 2
    settings.child_type, settings.rendered_child_count, settings.child_percent = "INTERPOLATED", 10, 2
    return b.finish("fur_under_glass", (320, 240), photons_per_pass=100_000)


SCENES = {f.__name__: f for f in (cornell_box, glass_ceiling, hole_mirror_glass, small_view, caustic_sds,
                                  checker_caustic, stained_window, pool_caustics, foggy_glass_ceiling,
                                  glass_lantern, fur_under_glass)}


def main(argv):
    names = argv or list(SCENES)
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        print(f"build_samples.py: error: unknown scene(s) {unknown}; choose from {list(SCENES)}",
              file=sys.stderr)
        return 2
    load_addon()
    for name in names:
        print("wrote", SCENES[name]())
    return 0


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else \
        ([] if bpy.app.binary_path else sys.argv[1:])
    sys.exit(main(args))

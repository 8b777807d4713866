"""The random scene generator of ``fuzz_scenes.py`` (imported inside each case's subprocess).

A case is a list of (feature name, sub-seed) pairs: each feature in :data:`FEATURES` builds one
part of the scene (an object, a light, the world, the camera, view-layer passes, flags...) with its
own ``random.Random(sub-seed)``, so a feature can be dropped without changing what the others
build (``fuzz_scenes.py reduce``).  Values are mostly ordinary, with a share of extreme ones (0,
negative, 1e30, NaN, missing images, degenerate meshes, zero scales) to find what breaks the
add-on.  :func:`apply_settings` then draws the engine settings and the image size from the case's
settings seed.  The features share a :class:`Case`: the objects made so far, whether passes were
asked for, and a free-text log of what was built, recorded with the case's result.

Needs ``bpy`` and the add-on registered (``fuzz_scenes.py`` loads it from the repository first);
builds on ``tests/addon/blender_scenes.py``.
"""
from __future__ import annotations

import math
import os
import random
import sys
import traceback
from dataclasses import dataclass, field

import bpy  # noqa: I001 (first: bmesh and mathutils exist only after it)
import bmesh
from mathutils import Vector

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests", "addon"))
import blender_scenes as bs  # noqa: E402


@dataclass
class Case:
    """What the features of one case share."""
    objects: list = field(default_factory=list)     # objects made so far (targets for booleans, focus)
    passes: bool = False                             # a view layer asked for passes: write multilayer EXR
    log_lines: list = field(default_factory=list)   # what the features did (free text)
    materials: int = 0                               # materials made so far (their names: Mat1, Mat2...)

    def log(self, msg):
        self.log_lines.append(msg)


def build_case(features, settings_seed, light_settings=False, resolution=None):
    """Build a case in a new empty scene: each (name, sub-seed) of ``features`` in turn, then the
    settings.  A feature that raises is recorded and skipped.  Returns (scene, case, settings
    description, feature failures)."""
    scene = bs.empty_scene((32, 24))
    case = Case()
    failures = []
    for name, sub_seed in features:
        case.log(f"-- {name} {sub_seed}")
        try:
            FEATURES[name](random.Random(sub_seed), case)
        except Exception as e:
            failures.append(f"{name}: {type(e).__name__}: {e}")
            case.log(traceback.format_exc())
    settings = apply_settings(random.Random(settings_seed), case, scene, light_settings, resolution)
    return scene, case, settings, failures


# ---------------------------------------------------------------------------- values
def rfloat(r, lo=0.0, hi=1.0, extreme=0.25):
    if r.random() < extreme:
        return r.choice([0.0, 1.0, -1.0, 1e6, -1e6, 1e-6, 1e30, -1e30, 1e-30, 100.0, 2.0, 0.5])
    return r.uniform(lo, hi)


def rcolor(r, extreme=0.2):
    if r.random() < extreme:
        c = r.choice([(0, 0, 0), (1, 1, 1), (1e6, 1e6, 1e6), (1e30, 0, 0), (-1, 0.5, 0.5), (1e-6, 0, 0)])
        return (*map(float, c), 1.0)
    return (r.random(), r.random(), r.random(), 1.0)


def rvec(r, n=3, scale=1.0, extreme=0.2):
    if r.random() < extreme:
        return tuple(r.choice([0.0, 1e6, -1e6, 1e-6, 1.0, -1.0]) for _ in range(n))
    return tuple(r.uniform(-scale, scale) for _ in range(n))


def set_socket(r, case, sock, extreme=0.25):
    if sock.is_linked or not hasattr(sock, "default_value"):
        return
    t = sock.type
    try:
        if t == "VALUE":
            sock.default_value = rfloat(r, 0.0, 1.0 if r.random() < 0.7 else 10.0, extreme)
        elif t == "INT":
            sock.default_value = r.choice([0, 1, 2, 5, -1, 100])
        elif t == "BOOLEAN":
            sock.default_value = r.random() < 0.5
        elif t == "RGBA":
            sock.default_value = rcolor(r, extreme)
        elif t == "VECTOR":
            sock.default_value = rvec(r, len(sock.default_value), 2.0, extreme)
        elif t == "STRING":
            sock.default_value = r.choice(["", "density", "Col", "UVMap", "nonexistent"])
    except Exception as e:  # (a value out of the socket's range, a read-only socket)
        case.log(f"set_socket {sock.name}: {e}")


def randomise_enums(r, case, node, skip=()):
    """Set each of ``node``'s own enum properties (not those every shader node has) with chance 0.6."""
    common = {p.identifier for p in bpy.types.ShaderNode.bl_rna.properties}
    for p in node.bl_rna.properties:
        if p.type != "ENUM" or p.is_readonly or p.identifier in common or p.identifier in skip:
            continue
        if getattr(p, "is_enum_flag", False):
            continue
        items = [e.identifier for e in p.enum_items]
        if items and r.random() < 0.6:
            try:
                setattr(node, p.identifier, r.choice(items))
            except Exception as e:
                case.log(f"enum {node.bl_idname}.{p.identifier}: {e}")


# ---------------------------------------------------------------------------- images
def gen_image(r, case, name="Img"):
    k = r.random()
    if k < 0.08:
        img = bpy.data.images.new(name, 4, 4)
        img.source = "FILE"
        img.filepath = "/nonexistent/missing_texture.png"
        case.log("image: missing file")
        return img
    w, h = r.choice([1, 2, 7, 16, 64]), r.choice([1, 3, 16, 32])
    img = bpy.data.images.new(name, w, h, alpha=r.random() < 0.5, float_buffer=r.random() < 0.4)
    img.generated_type = r.choice(["BLANK", "UV_GRID", "COLOR_GRID"])
    img.generated_color = rcolor(r, 0.3)
    if r.random() < 0.3:
        try:
            img.colorspace_settings.name = r.choice(["Non-Color", "sRGB", "Linear Rec.709"])
        except Exception as e:
            case.log(f"colorspace: {e}")
    case.log(f"image {w}x{h} {img.generated_type} float={img.use_generated_float}")
    return img


# ---------------------------------------------------------------------------- materials
SURFACE_SHADERS = ["ShaderNodeBsdfPrincipled"] * 4 + [
    "ShaderNodeBsdfDiffuse", "ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfGlass", "ShaderNodeBsdfRefraction",
    "ShaderNodeEmission", "ShaderNodeBsdfTransparent", "ShaderNodeBsdfTranslucent",
    "ShaderNodeSubsurfaceScattering", "ShaderNodeBsdfSheen", "ShaderNodeBsdfHair",
    "ShaderNodeBsdfHairPrincipled", "ShaderNodeBsdfToon", "ShaderNodeBsdfMetallic", "ShaderNodeHoldout",
    "ShaderNodeBsdfRayPortal", "ShaderNodeEeveeSpecular", "ShaderNodeBackground", "ShaderNodeBsdfDiffuse",
    "ShaderNodeEmission"]
VOLUME_SHADERS = ["ShaderNodeVolumeScatter", "ShaderNodeVolumeAbsorption", "ShaderNodeVolumePrincipled",
                  "ShaderNodeVolumeCoefficients"]
TEXTURES = ["ShaderNodeTexNoise", "ShaderNodeTexVoronoi", "ShaderNodeTexWave", "ShaderNodeTexChecker",
            "ShaderNodeTexGradient", "ShaderNodeTexMagic", "ShaderNodeTexBrick", "ShaderNodeTexImage",
            "ShaderNodeTexImage", "ShaderNodeTexWhiteNoise", "ShaderNodeTexGabor", "ShaderNodeTexSky",
            "ShaderNodeTexEnvironment"]
UTILITIES = ["ShaderNodeValToRGB", "ShaderNodeMath", "ShaderNodeMix", "ShaderNodeMapRange",
             "ShaderNodeInvert", "ShaderNodeHueSaturation", "ShaderNodeTexCoord", "ShaderNodeMapping",
             "ShaderNodeAttribute", "ShaderNodeObjectInfo", "ShaderNodeNewGeometry", "ShaderNodeLayerWeight",
             "ShaderNodeFresnel", "ShaderNodeVertexColor", "ShaderNodeBlackbody", "ShaderNodeWavelength",
             "ShaderNodeRGBCurve", "ShaderNodeSeparateColor", "ShaderNodeCombineColor",
             "ShaderNodeCombineXYZ", "ShaderNodeSeparateXYZ", "ShaderNodeAmbientOcclusion", "ShaderNodeBevel",
             "ShaderNodeLightPath", "ShaderNodeCameraData", "ShaderNodeValue", "ShaderNodeRGB",
             "ShaderNodeBump", "ShaderNodeNormalMap", "ShaderNodeWireframe", "ShaderNodeHairInfo",
             "ShaderNodePointInfo", "ShaderNodeVectorMath", "ShaderNodeVectorRotate",
             "ShaderNodeVectorTransform", "ShaderNodeClamp", "ShaderNodeFloatCurve", "ShaderNodeGamma",
             "ShaderNodeBrightContrast", "ShaderNodeRGBToBW", "ShaderNodeShaderToRGB",
             "ShaderNodeRadialTiling", "ShaderNodeTangent", "ShaderNodeUVMap", "ShaderNodeParticleInfo",
             "ShaderNodeVolumeInfo", "ShaderNodeLightFalloff", "ShaderNodeMixRGB", "ShaderNodeSqueeze",
             "ShaderNodeNormal", "ShaderNodeVectorCurve"]


def new_node(r, case, nt, kind):
    node = nt.nodes.new(kind)
    randomise_enums(r, case, node, skip=("target",) if r.random() < 0.9 else ())
    if kind in ("ShaderNodeTexImage", "ShaderNodeTexEnvironment"):
        if r.random() < 0.9:
            node.image = gen_image(r, case)
        else:
            case.log("image texture without image")
    if kind == "ShaderNodeAttribute":
        node.attribute_name = r.choice(["", "Col", "UVMap", "position", "nonexistent", "radius"])
    if kind == "ShaderNodeOutputAOV":
        node.aov_name = "aov"
    for s in node.inputs:
        if r.random() < 0.5:
            set_socket(r, case, s)
    return node


def texture_chain(r, case, nt, depth=0):
    """A random non-shader source node (texture or utility), its inputs partly fed by others."""
    kind = r.choice(TEXTURES if r.random() < 0.6 else UTILITIES)
    node = new_node(r, case, nt, kind)
    case.log(f"  tex {kind}")
    if depth < 2:
        ins = [s for s in node.inputs if s.type != "SHADER" and s.enabled]
        for s in r.sample(ins, min(len(ins), r.choice([0, 0, 1, 2]))):
            src = texture_chain(r, case, nt, depth + 1)
            outs = [o for o in src.outputs if o.enabled] or list(src.outputs)
            if outs:
                nt.links.new(r.choice(outs), s)
    return node


def shader_tree(r, case, nt, depth=0, volume=False):
    if depth < 2 and r.random() < 0.25:
        kind = r.choice(["ShaderNodeMixShader", "ShaderNodeAddShader"])
        node = nt.nodes.new(kind)
        case.log(f"  {kind}")
        if kind == "ShaderNodeMixShader":
            if r.random() < 0.4:
                nt.links.new(r.choice(texture_chain(r, case, nt).outputs), node.inputs[0])
            else:
                node.inputs[0].default_value = rfloat(r, 0, 1, 0.3)
            first = 1
        else:
            first = 0
        for i in (first, first + 1):
            if r.random() < 0.9:
                nt.links.new(shader_tree(r, case, nt, depth + 1, volume).outputs[0], node.inputs[i])
        return node
    kind = r.choice(VOLUME_SHADERS if volume else SURFACE_SHADERS)
    node = new_node(r, case, nt, kind)
    case.log(f"  shader {kind}")
    ins = [s for s in node.inputs if s.type not in ("SHADER", "STRING") and s.enabled]
    for s in r.sample(ins, min(len(ins), r.choice([0, 0, 1, 1, 2, 3]))):
        src = texture_chain(r, case, nt)
        outs = [o for o in src.outputs if o.enabled] or list(src.outputs)
        if outs:
            nt.links.new(r.choice(outs), s)
    if r.random() < 0.05:     # a shader linked into a non-shader input (a red link in the editor)
        try:
            other = new_node(r, case, nt, r.choice(SURFACE_SHADERS))
            if ins:
                nt.links.new(other.outputs[0], r.choice(ins))
                case.log("  shader into value socket")
        except Exception as e:
            case.log(f"bad link: {e}")
    return node


def random_material(r, case):
    case.materials += 1
    mat = bpy.data.materials.new(f"Mat{case.materials}")
    nt = mat.node_tree
    k = r.random()
    if k < 0.07:
        nt.nodes.clear()
        case.log(f"{mat.name}: no nodes at all")
        return mat
    if k < 0.15:
        case.log(f"{mat.name}: default principled")
        return mat
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if r.random() < 0.05:
        out.target = r.choice(["EEVEE", "CYCLES", "ALL"])
    case.log(f"{mat.name}: random tree")
    if r.random() < 0.92:
        nt.links.new(shader_tree(r, case, nt).outputs[0], out.inputs["Surface"])
    if r.random() < 0.15:
        nt.links.new(shader_tree(r, case, nt, volume=True).outputs[0], out.inputs["Volume"])
        case.log("  + volume")
    if r.random() < 0.12:
        d = nt.nodes.new(r.choice(["ShaderNodeDisplacement", "ShaderNodeVectorDisplacement"]))
        randomise_enums(r, case, d)
        for s in d.inputs:
            set_socket(r, case, s)
        t = texture_chain(r, case, nt)
        tgt = d.inputs[0]
        nt.links.new(r.choice(t.outputs), tgt)
        nt.links.new(d.outputs[0], out.inputs["Displacement"])
        mat.displacement_method = r.choice(["BUMP", "DISPLACEMENT", "BOTH"])
        case.log(f"  + displacement {mat.displacement_method}")
    if r.random() < 0.05:
        out2 = nt.nodes.new("ShaderNodeOutputMaterial")     # a second output node (which is active?)
        nt.links.new(shader_tree(r, case, nt).outputs[0], out2.inputs["Surface"])
        case.log("  + second output node")
    if r.random() < 0.05:
        aov = nt.nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = "aov"
        nt.links.new(texture_chain(r, case, nt).outputs[0], aov.inputs[0])
        case.log("  + AOV output")
    if r.random() < 0.1:
        mat.use_backface_culling = True
    return mat


def assign_material(r, case, ob):
    if not hasattr(ob.data, "materials"):
        return
    k = r.random()
    if k < 0.12:
        case.log(f"{ob.name}: no material")
        return
    if k < 0.18:
        ob.data.materials.append(None)
        case.log(f"{ob.name}: empty slot")
        return
    n = 1 if r.random() < 0.8 else r.randint(2, 4)
    for i in range(n):
        ob.data.materials.append(random_material(r, case) if r.random() > 0.1 or i == 0 else None)
    if n > 1 and ob.type == "MESH":
        for p in ob.data.polygons:
            p.material_index = r.randint(0, n + 1)      # (sometimes an index past the slots)
        case.log(f"{ob.name}: {n} slots, random indices")
    if r.random() < 0.05 and ob.type == "MESH":
        ob.material_slots[0].link = "OBJECT"
        ob.material_slots[0].material = random_material(r, case)
        case.log(f"{ob.name}: object-linked material")


# ---------------------------------------------------------------------------- geometry
def bm_primitive(r):
    bm = bmesh.new()
    kind = r.choice(["cube", "uvsphere", "icosphere", "cone", "circle", "grid", "monkey", "cylinder"])
    if kind == "cube":
        bmesh.ops.create_cube(bm, size=1.0)
    elif kind == "uvsphere":
        bmesh.ops.create_uvsphere(bm, u_segments=r.randint(3, 16), v_segments=r.randint(3, 8), radius=0.6)
    elif kind == "icosphere":
        bmesh.ops.create_icosphere(bm, subdivisions=r.randint(1, 3), radius=0.6)
    elif kind == "cone":
        bmesh.ops.create_cone(bm, cap_ends=r.random() < 0.7, cap_tris=r.random() < 0.5,
                              segments=r.randint(3, 24), radius1=r.choice([0.0, 0.5]),
                              radius2=r.choice([0.0, 0.3, 0.5]), depth=1.0)
    elif kind == "cylinder":
        bmesh.ops.create_cone(bm, cap_ends=True, cap_tris=False, segments=r.randint(3, 64), radius1=0.5,
                              radius2=0.5, depth=1.0)
    elif kind == "circle":
        bmesh.ops.create_circle(bm, cap_ends=r.random() < 0.8, cap_tris=r.random() < 0.3,
                                segments=r.randint(3, 64), radius=0.6)
    elif kind == "grid":
        bmesh.ops.create_grid(bm, x_segments=r.randint(1, 10), y_segments=r.randint(1, 10), size=0.7)
    else:
        bmesh.ops.create_monkey(bm)
    return bm, kind


def degenerate_mesh(r, case, name):
    """A mesh of odd geometry through from_pydata."""
    kind = r.choice(["zero_area", "dup_verts", "single_vertex", "loose_edges", "empty", "ngon_concave",
                     "ngon_nonplanar", "ngon_collinear", "huge_coords", "nan_vertex", "sliver",
                     "two_sided_pair", "many_ngons"])
    me = bpy.data.meshes.new(name)
    if kind == "zero_area":
        me.from_pydata([(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (0, 1, 0), (1, 1, 0)], [],
                       [(0, 1, 2), (3, 4, 5), (0, 1, 5, 3)])
    elif kind == "dup_verts":
        me.from_pydata([(0, 0, 0), (0, 0, 0), (0, 0, 0), (1, 0, 0), (1, 1, 0)], [],
                       [(0, 1, 2), (0, 3, 4), (1, 3, 4)])
    elif kind == "single_vertex":
        me.from_pydata([(0, 0, 0.5)], [], [])
    elif kind == "loose_edges":
        me.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 1)], [(0, 1), (1, 2)], [])
    elif kind == "empty":
        pass
    elif kind == "ngon_concave":
        pts = [(math.cos(a) * (1 if i % 2 else 0.3), math.sin(a) * (1 if i % 2 else 0.3), 0)
               for i, a in enumerate([j * 2 * math.pi / 10 for j in range(10)])]
        me.from_pydata(pts, [], [tuple(range(10))])
    elif kind == "ngon_nonplanar":
        pts = [(math.cos(a), math.sin(a), r.uniform(-1, 1)) for a in [j * 2 * math.pi / 7 for j in range(7)]]
        me.from_pydata(pts, [], [tuple(range(7))])
    elif kind == "ngon_collinear":
        me.from_pydata([(i, 0, 0) for i in range(6)], [], [tuple(range(6))])
    elif kind == "huge_coords":
        s = r.choice([1e6, 1e12, 1e20, 3e38])
        me.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    elif kind == "nan_vertex":
        nan = float(r.choice(["nan", "inf", "-inf"]))
        me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0), (nan, 0, 0)], [], [(0, 1, 2), (1, 2, 3)])
    elif kind == "sliver":
        me.from_pydata([(0, 0, 0), (1, 0, 0), (0.5, 1e-9, 0)], [], [(0, 1, 2)])
    elif kind == "two_sided_pair":
        me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2), (0, 2, 1)])
    else:
        bm = bmesh.new()
        bmesh.ops.create_circle(bm, cap_ends=True, segments=200, radius=1.0)
        bm.to_mesh(me)
        bm.free()
    case.log(f"degenerate mesh {kind}")
    return me


def random_transform(r, case, ob):
    ob.location = rvec(r, 3, 1.0, 0.0)
    ob.rotation_euler = rvec(r, 3, math.pi, 0.0)
    if r.random() < 0.35:
        k = r.choice(["neg", "zero_axis", "zero", "huge", "tiny", "far", "far_huge", "nonuniform"])
        if k in ("zero", "zero_axis") and r.random() < 0.75:
            k = "neg"         # (zero scale: a known defect, LinAlgError; kept rarer)
        if k == "neg":
            ob.scale = (r.choice([-1, 1]), r.choice([-1, 1]), -1)
        elif k == "zero_axis":
            ob.scale = (1, 1, 0)
        elif k == "zero":
            ob.scale = (0, 0, 0)
        elif k == "huge":
            ob.scale = (1e6, 1e6, 1e6)
        elif k == "tiny":
            ob.scale = (1e-6, 1e-6, 1e-6)
        elif k == "far":
            ob.location = (r.choice([1e6, -1e7, 1e4]), 0, 0)
        elif k == "far_huge":
            ob.location = (0, 0, -1e5)
            ob.scale = (1e5, 1e5, 1e5)
        else:
            ob.scale = (100, 0.01, 1)
        case.log(f"{ob.name}: transform {k}")


def add_modifiers(r, case, ob):
    n = r.choice([0, 0, 1, 1, 2, 3])
    for _ in range(n):
        kind = r.choice(["SUBSURF", "SOLIDIFY", "ARRAY", "MIRROR", "DISPLACE", "BEVEL", "BOOLEAN",
                         "TRIANGULATE", "WIREFRAME", "DECIMATE", "WELD", "SMOOTH", "REMESH", "SCREW"])
        try:
            m = ob.modifiers.new(kind, kind)
            if kind == "SUBSURF":
                m.levels = m.render_levels = r.randint(0, 3)
                m.subdivision_type = r.choice(["CATMULL_CLARK", "SIMPLE"])
            elif kind == "SOLIDIFY":
                m.thickness = rfloat(r, -0.5, 0.5, 0.3)
            elif kind == "ARRAY":
                m.count = r.randint(1, 20)
                m.relative_offset_displace = rvec(r, 3, 2.0, 0.1)
            elif kind == "DISPLACE":
                m.strength = rfloat(r, -1, 1, 0.3)
                if r.random() < 0.5:
                    tex = bpy.data.textures.new("T", r.choice(["CLOUDS", "NOISE", "VORONOI", "MARBLE"]))
                    m.texture = tex
            elif kind == "BEVEL":
                m.width = rfloat(r, 0, 0.3, 0.2)
                m.segments = r.randint(1, 4)
            elif kind == "BOOLEAN":
                others = [o for o in case.objects if o.type == "MESH" and o is not ob]
                if others:
                    m.object = r.choice(others)
                m.operation = r.choice(["DIFFERENCE", "UNION", "INTERSECT"])
                m.solver = r.choice(["FLOAT", "EXACT", "MANIFOLD"])
            elif kind == "WIREFRAME":
                m.thickness = rfloat(r, 0, 0.1, 0.2)
            elif kind == "DECIMATE":
                m.ratio = r.choice([0.0, 0.1, 0.5])
            elif kind == "REMESH":
                m.mode = r.choice(["BLOCKS", "SMOOTH", "SHARP"])
                m.octree_depth = r.randint(1, 5)
            elif kind == "SCREW":
                m.steps = m.render_steps = r.randint(2, 16)
            case.log(f"{ob.name}: modifier {kind}")
        except Exception as e:
            case.log(f"modifier {kind}: {e}")


def link(case, ob):
    bpy.context.scene.collection.objects.link(ob)
    case.objects.append(ob)
    return ob


def mesh_common(r, case, ob):
    assign_material(r, case, ob)
    random_transform(r, case, ob)
    if ob.type == "MESH":
        me = ob.data
        if len(me.polygons) and r.random() < 0.5:
            me.shade_smooth()
        if r.random() < 0.3 and len(me.vertices):
            me.uv_layers.new(name="UVMap")
        if r.random() < 0.2 and len(me.vertices):
            a = me.color_attributes.new("Col", r.choice(["FLOAT_COLOR", "BYTE_COLOR"]),
                                        r.choice(["POINT", "CORNER"]))
            for d in a.data:
                d.color = rcolor(r, 0.2)
    add_modifiers(r, case, ob)


# ---------------------------------------------------------------------------- features
# Each feature builds one part of the scene: f(r, case) with its own random.Random r.
def f_floor(r, case):
    bs.plane("Floor", size=r.choice([4.0, 10.0, 100.0]), material=bs.diffuse("FloorMat", (0.8, 0.8, 0.8)),
             location=(0, 0, -0.5))
    case.objects.append(bpy.data.objects["Floor"])


def f_camera(r, case):
    bs.camera(location=(0, -4, 2.5), target=(0, 0, 0), lens=35.0)


def f_light(r, case):
    bs.light("POINT", location=(1, -1, 3), energy=500.0)


def f_mesh(r, case):
    bm, kind = bm_primitive(r)
    me = bpy.data.meshes.new(kind)
    bm.to_mesh(me)
    bm.free()
    ob = link(case, bpy.data.objects.new(kind, me))
    case.log(f"mesh {kind}")
    mesh_common(r, case, ob)


def f_degenerate(r, case):
    me = degenerate_mesh(r, case, "Degenerate")
    ob = link(case, bpy.data.objects.new("Degenerate", me))
    mesh_common(r, case, ob)


def f_ops_primitive(r, case):
    kind = r.choice(["torus", "cylinder", "cone", "uv_sphere", "ico_sphere", "monkey", "plane", "cube",
                     "circle"])
    kw = {}
    if kind == "circle":
        kw["fill_type"] = r.choice(["NOTHING", "NGON", "TRIFAN"])
    getattr(bpy.ops.mesh, f"primitive_{kind}_add")(location=rvec(r, 3, 1.0, 0.0), **kw)
    ob = bpy.context.active_object
    case.objects.append(ob)
    case.log(f"ops primitive {kind} -> {ob.name}")
    mesh_common(r, case, ob)


def f_text(r, case):
    cu = bpy.data.curves.new("Text", "FONT")
    cu.body = r.choice(["Hi", "", " ", "A\nB", "x" * 40, "Ünïcødé ☃", "\t."])
    cu.extrude = rfloat(r, 0, 0.2, 0.2)
    cu.bevel_depth = rfloat(r, 0, 0.05, 0.1)
    cu.size = r.choice([1.0, 0.01, 10.0])
    ob = link(case, bpy.data.objects.new("Text", cu))
    case.log(f"text {cu.body!r}")
    assign_material(r, case, ob)
    random_transform(r, case, ob)


def f_curve(r, case):
    cu = bpy.data.curves.new("Curve", "CURVE")
    cu.dimensions = "3D"
    kind = r.choice(["POLY", "BEZIER", "NURBS"])
    sp = cu.splines.new(kind)
    n = r.choice([1, 2, 5])
    pts = sp.bezier_points if kind == "BEZIER" else sp.points
    pts.add(n - 1)
    for i, p in enumerate(pts):
        co = (i * 0.5 - 1, r.uniform(-0.5, 0.5), r.uniform(0, 1))
        if kind == "BEZIER":
            p.co = co
            p.handle_left_type = p.handle_right_type = "AUTO"
        else:
            p.co = (*co, 1.0)
    sp.use_cyclic_u = r.random() < 0.3
    cu.bevel_depth = rfloat(r, 0, 0.2, 0.3)
    cu.bevel_resolution = r.randint(0, 6)
    cu.extrude = rfloat(r, 0, 0.2, 0.2)
    cu.fill_mode = r.choice(["FULL", "BACK", "FRONT", "HALF"])
    ob = link(case, bpy.data.objects.new("Curve", cu))
    case.log(f"curve {kind} n={n} bevel={cu.bevel_depth}")
    assign_material(r, case, ob)
    random_transform(r, case, ob)


def f_metaball(r, case):
    mb = bpy.data.metaballs.new("Meta")
    mb.resolution = mb.render_resolution = r.choice([0.1, 0.2, 0.4])
    for _ in range(r.randint(0, 3)):
        el = mb.elements.new()
        el.type = r.choice(["BALL", "CAPSULE", "PLANE", "ELLIPSOID", "CUBE"])
        el.co = rvec(r, 3, 0.5, 0.0)
        el.radius = r.choice([0.5, 1.0, 0.0])
    ob = link(case, bpy.data.objects.new("Meta", mb))
    case.log(f"metaball {len(mb.elements)} elements")
    assign_material(r, case, ob)
    random_transform(r, case, ob)


def f_collection_instance(r, case):
    coll = bpy.data.collections.new("Inst")
    bm, kind = bm_primitive(r)
    me = bpy.data.meshes.new(kind)
    bm.to_mesh(me)
    bm.free()
    src = bpy.data.objects.new("InstSrc", me)
    coll.objects.link(src)
    assign_material(r, case, src)
    if r.random() < 0.3:
        ld = bpy.data.lights.new("InstLight", r.choice(["POINT", "SPOT", "AREA", "SUN"]))
        ld.energy = 100.0
        lo = bpy.data.objects.new("InstLight", ld)
        lo.location = (0, 0, 1.5)
        coll.objects.link(lo)
        case.log("instanced light")
    if r.random() < 0.3:
        bpy.context.scene.collection.children.link(coll)       # also in the scene itself
        case.log("instanced collection also in scene")
    for i in range(r.randint(1, 4)):
        e = bpy.data.objects.new(f"Empty{i}", None)
        e.instance_type = "COLLECTION"
        e.instance_collection = coll
        random_transform(r, case, e)
        bpy.context.scene.collection.objects.link(e)
    if r.random() < 0.3:       # nested instancing
        outer = bpy.data.collections.new("Outer")
        e = bpy.data.objects.new("Inner", None)
        e.instance_type = "COLLECTION"
        e.instance_collection = coll
        outer.objects.link(e)
        e2 = bpy.data.objects.new("OuterEmpty", None)
        e2.instance_type = "COLLECTION"
        e2.instance_collection = outer
        e2.location = (1, 1, 0)
        bpy.context.scene.collection.objects.link(e2)
        case.log("nested instance")
    case.log(f"collection instance of {kind}")


def f_gn_instances(r, case):
    me = bpy.data.meshes.new("GN")
    ob = link(case, bpy.data.objects.new("GN", me))
    tree = bpy.data.node_groups.new("GNTree", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = tree.nodes.new("NodeGroupOutput")
    tree.nodes.new("NodeGroupInput")
    kind = r.choice(["instances", "instances", "realized", "empty", "points", "nan_offset", "curve_to_mesh"])
    if kind == "empty":
        case.log("GN: empty output")
    elif kind == "curve_to_mesh":
        circ = tree.nodes.new("GeometryNodeCurvePrimitiveCircle")
        prof = tree.nodes.new("GeometryNodeCurvePrimitiveCircle")
        prof.inputs["Radius"].default_value = rfloat(r, 0.01, 0.2, 0.3)
        c2m = tree.nodes.new("GeometryNodeCurveToMesh")
        tree.links.new(circ.outputs[0], c2m.inputs["Curve"])
        tree.links.new(prof.outputs[0], c2m.inputs["Profile Curve"])
        tree.links.new(c2m.outputs[0], out.inputs[0])
    else:
        grid = tree.nodes.new("GeometryNodeMeshGrid")
        grid.inputs["Vertices X"].default_value = r.randint(1, 6)
        grid.inputs["Vertices Y"].default_value = r.randint(1, 6)
        last = grid.outputs[0]
        if kind in ("instances", "realized"):
            inst = tree.nodes.new("GeometryNodeInstanceOnPoints")
            shape = tree.nodes.new(r.choice(["GeometryNodeMeshCube", "GeometryNodeMeshIcoSphere",
                                             "GeometryNodeMeshCone"]))
            tree.links.new(last, inst.inputs["Points"])
            tree.links.new(shape.outputs[0], inst.inputs["Instance"])
            inst.inputs["Scale"].default_value = (0.2, 0.2, 0.2) if r.random() < 0.8 else rvec(r, 3, 1.0, 0.5)
            last = inst.outputs[0]
            if kind == "realized":
                real = tree.nodes.new("GeometryNodeRealizeInstances")
                tree.links.new(last, real.inputs[0])
                last = real.outputs[0]
        elif kind == "points":
            pts = tree.nodes.new("GeometryNodeMeshToPoints")
            pts.inputs["Radius"].default_value = rfloat(r, 0.01, 0.2, 0.3)
            tree.links.new(last, pts.inputs[0])
            last = pts.outputs[0]
        elif kind == "nan_offset":
            sp = tree.nodes.new("GeometryNodeSetPosition")
            math_node = tree.nodes.new("ShaderNodeMath")
            math_node.operation = "DIVIDE"
            math_node.inputs[0].default_value = 0.0
            math_node.inputs[1].default_value = 0.0
            comb = tree.nodes.new("ShaderNodeCombineXYZ")
            tree.links.new(math_node.outputs[0], comb.inputs[r.randint(0, 2)])
            tree.links.new(last, sp.inputs["Geometry"])
            tree.links.new(comb.outputs[0], sp.inputs["Offset"])
            last = sp.outputs[0]
        if r.random() < 0.7:
            sm = tree.nodes.new("GeometryNodeSetMaterial")
            sm.inputs["Material"].default_value = random_material(r, case)
            tree.links.new(last, sm.inputs["Geometry"])
            last = sm.outputs[0]
        tree.links.new(last, out.inputs[0])
    ob.modifiers.new("GN", "NODES").node_group = tree
    case.log(f"GN {kind}")
    random_transform(r, case, ob)


def f_point_cloud(r, case):
    n = r.choice([1, 5, 50])
    pts = [rvec(r, 3, 1.0, 0.0) for _ in range(n)]
    rad = r.choice([0.05, 0.0, 1e-6, 1.0, 5.0])
    mat = random_material(r, case) if r.random() < 0.7 else None
    ob = bs.point_cloud("Points", pts, radius=rad, material=mat,
                        random_radius=(0.0, 0.1) if r.random() < 0.2 else None)
    case.objects.append(ob)
    case.log(f"point cloud n={n} radius={rad}")


def f_hair_curves(r, case):
    curves = []
    for _ in range(r.choice([1, 3, 20])):
        n = r.choice([1, 2, 4, 8])
        x, y = r.uniform(-1, 1), r.uniform(-1, 1)
        curves.append([(x + r.uniform(-0.1, 0.1) * i, y, 0.3 * i) for i in range(n)])
    radius = r.choice([None, 0.005, 0.0, 0.1, 1.0, 1e-7])
    kind = r.choice([None, "POLY", "BEZIER", "NURBS", "CATMULL_ROM"])
    mat = random_material(r, case) if r.random() < 0.5 else bs.hair_bsdf("Hair")
    ob = bs.hair_curves("Hair", curves, radius=radius, material=mat, kind=kind)
    case.objects.append(ob)
    case.log(f"hair curves n={len(curves)} radius={radius} kind={kind}")


def f_particles(r, case):
    bm, kind = bm_primitive(r)
    me = bpy.data.meshes.new("Emitter")
    bm.to_mesh(me)
    bm.free()
    ob = link(case, bpy.data.objects.new("Emitter", me))
    assign_material(r, case, ob)
    ob.modifiers.new("Particles", "PARTICLE_SYSTEM")
    ps = ob.particle_systems[0].settings
    ps.type = r.choice(["HAIR", "EMITTER"])
    ps.count = r.choice([1, 10, 100])
    if ps.type == "HAIR":
        ps.hair_length = r.choice([0.2, 0.0, 2.0])
        ps.display_step = ps.render_step = r.randint(1, 4)
    else:
        ps.frame_start, ps.frame_end, ps.lifetime = -50, 1, 200
    ps.render_type = r.choice(["PATH", "OBJECT", "NONE", "HALO"]) if ps.type == "HAIR" else r.choice(
        ["OBJECT", "HALO", "NONE"])
    if ps.render_type == "OBJECT":
        inst = bpy.data.objects.new("PInst", bpy.data.meshes.new("PInstMesh"))
        bmi = bmesh.new()
        bmesh.ops.create_cube(bmi, size=1.0)
        bmi.to_mesh(inst.data)
        bmi.free()
        bpy.context.scene.collection.objects.link(inst)
        inst.location = (0, 0, -50)
        ps.instance_object = inst
        ps.particle_size = r.choice([0.05, 0.0, 1.0])
    if r.random() < 0.3:
        ob.show_instancer_for_render = False
    bpy.context.scene.frame_set(1)
    case.log(f"particles {ps.type} {ps.render_type} count={ps.count}")


def f_volume_object(r, case):
    vol = bpy.data.volumes.new("Volume")
    link(case, bpy.data.objects.new("Volume", vol))
    mat, _ = bs.volume_material("VolMat", r.choice(VOLUME_SHADERS[:3]))
    vol.materials.append(mat)
    case.log("empty volume object")


def f_volume_cube(r, case):
    """A cube of volume material (with or without a surface)."""
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=r.choice([1.0, 2.0, 20.0]))
    kind = r.choice(VOLUME_SHADERS)
    mat, node = bs.volume_material("Fog", kind, surface=r.choice([None, None, "ShaderNodeBsdfGlass",
                                                                  "ShaderNodeBsdfTransparent"]))
    for s in node.inputs:
        if r.random() < 0.5:
            set_socket(r, case, s, 0.3)
    ob = bs.mesh_object("Fog", bm, mat)
    case.objects.append(ob)
    case.log(f"volume cube {kind}")
    if r.random() < 0.3:
        random_transform(r, case, ob)


def f_flags(r, case):
    """Holdout, shadow catcher, visibility toggles, hide_render on random objects."""
    obs = [o for o in bpy.context.scene.objects if o.type != "CAMERA"]
    for ob in r.sample(obs, min(len(obs), r.randint(1, 3))):
        k = r.choice(["holdout", "catcher", "vis", "hide", "lightgroup", "pass_index", "color"])
        if k == "holdout":
            ob.is_holdout = True
        elif k == "catcher":
            ob.is_shadow_catcher = True
        elif k == "vis":
            for p in ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission",
                      "visible_volume_scatter", "visible_shadow"):
                if r.random() < 0.4:
                    setattr(ob, p, False)
        elif k == "hide":
            ob.hide_render = True
        elif k == "lightgroup":
            ob.lightgroup = r.choice(["LG", "LG2", "", "Missing"])
        elif k == "pass_index":
            ob.pass_index = r.choice([0, 1, 1000])
        else:
            ob.color = rcolor(r, 0.3)
        case.log(f"{ob.name}: flag {k}")


def f_random_light(r, case):
    kind = r.choice(["POINT", "SPOT", "SUN", "AREA", "AREA"])
    ld = bpy.data.lights.new(f"L{kind}", kind)
    if r.random() < 0.4:
        ld.energy = r.choice([0.0, 1e-6, 10.0, 100.0, 1000.0, 1e6, 1e12])
    else:
        ld.energy = r.uniform(10, 1000)
    if kind == "SUN":
        ld.energy = r.choice([0.0, 1.0, 5.0, 1e6]) if r.random() < 0.4 else r.uniform(0.5, 10)
        ld.angle = r.choice([0.0, 1e-4, math.radians(10), math.pi])
    ld.color = rcolor(r, 0.2)[:3]
    if r.random() < 0.4:
        ld.shadow_soft_size = r.choice([0.0, 1e-6, 0.1, 1.0, 100.0, 1e5])
    if kind == "SPOT":
        ld.spot_size = r.choice([math.radians(1), 1e-3, math.radians(45), math.pi])
        ld.spot_blend = r.choice([0.0, 0.5, 1.0])
        ld.show_cone = True
    if kind == "AREA":
        ld.shape = r.choice(["SQUARE", "RECTANGLE", "DISK", "ELLIPSE"])
        ld.size = r.choice([0.0, 1e-6, 0.5, 2.0, 1e4])
        ld.size_y = r.choice([0.0, 0.3, 5.0])
        ld.spread = r.choice([0.0, 1e-3, math.radians(30), math.pi])
        if r.random() < 0.1:
            ld.cycles.is_portal = True
            case.log("portal")
    if r.random() < 0.1:
        ld.use_shadow = False
    if r.random() < 0.05:
        ld.use_soft_falloff = False
    ob = bpy.data.objects.new(ld.name, ld)
    ob.location = (r.uniform(-3, 3), r.uniform(-3, 3), r.uniform(0.5, 5))
    if r.random() < 0.15:
        ob.location = (0, 0, 0)       # inside whatever is at the origin
        case.log("light at origin")
    ob.rotation_euler = (Vector((0, 0, 0)) - ob.location).to_track_quat("-Z", "Y").to_euler() \
        if ob.location.length > 0 else (0, 0, 0)
    if r.random() < 0.1:
        ob.scale = r.choice([(0, 0, 0), (-1, 1, 1), (5, 0.1, 1)])
        case.log(f"light scale {tuple(ob.scale)}")
    if r.random() < 0.1:
        for p in ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission"):
            setattr(ob, p, r.random() < 0.5)
    bpy.context.scene.collection.objects.link(ob)
    if r.random() < 0.05 and kind in ("POINT", "SPOT", "AREA"):
        bs.add_ies(ob, bs.ies_text())
        case.log("IES")
    elif r.random() < 0.1:
        try:
            ld.use_nodes = True
            nt = ld.node_tree
            em = nt.nodes.get("Emission")
            if em is not None:
                t = texture_chain(r, case, nt)
                nt.links.new(r.choice(t.outputs), em.inputs[r.choice(["Color", "Strength"])])
                case.log("light nodes")
        except Exception as e:
            case.log(f"light nodes: {e}")
    case.log(f"light {kind} energy={ld.energy} color={tuple(ld.color)}")


def f_world(r, case):
    k = r.choice(["none", "color", "zero", "sky", "env", "gradient", "volume", "huge", "noise", "no_nodes",
                  "random"])
    if k == "none":
        bpy.context.scene.world = None
    elif k == "no_nodes":
        w = bpy.data.worlds.new("W")
        w.node_tree.nodes.clear()
        bpy.context.scene.world = w
    else:
        w = bs.world((0.05, 0.05, 0.08), 1.0)
        nt = w.node_tree
        bg = nt.nodes["Background"]
        if k == "color":
            bg.inputs["Color"].default_value = rcolor(r, 0.3)
            bg.inputs["Strength"].default_value = rfloat(r, 0, 3, 0.2)
        elif k == "zero":
            bg.inputs["Strength"].default_value = 0.0
        elif k == "huge":
            bg.inputs["Strength"].default_value = 1e6
        elif k in ("sky", "env", "gradient", "noise", "random"):
            kind = {"sky": "ShaderNodeTexSky", "env": "ShaderNodeTexEnvironment",
                    "gradient": "ShaderNodeTexGradient", "noise": "ShaderNodeTexNoise"}.get(k)
            node = new_node(r, case, nt, kind) if kind else texture_chain(r, case, nt)
            outs = [o for o in node.outputs if o.type == "RGBA"] or list(node.outputs)
            nt.links.new(outs[0], bg.inputs["Color"])
            if k == "sky":
                for p in ("sun_elevation", "sun_rotation", "altitude", "air_density", "aerosol_density",
                          "ozone_density", "sun_size", "sun_intensity", "turbidity", "ground_albedo"):
                    if hasattr(node, p) and r.random() < 0.4:
                        try:
                            setattr(node, p, rfloat(r, 0, 1, 0.4))
                        except Exception as e:
                            case.log(f"sky {p}: {e}")
        elif k == "volume":
            vk = r.choice(VOLUME_SHADERS)
            vn = nt.nodes.new(vk)
            for s in vn.inputs:
                if r.random() < 0.5:
                    set_socket(r, case, s, 0.2)
            if "Density" in vn.inputs:
                vn.inputs["Density"].default_value = r.choice([0.0, 0.01, 0.1, 1.0])
            nt.links.new(vn.outputs[0], nt.nodes["World Output"].inputs["Volume"])
            k = f"volume {vk}"
        if r.random() < 0.1:
            w.light_settings.distance = r.choice([0.0, 1e-6, 1e6])
        if r.random() < 0.2:
            w.mist_settings.start, w.mist_settings.depth = r.choice([(0.0, 0.0), (5, 1e-6), (0, 1e6)])
    case.log(f"world {k}")


def f_camera_random(r, case):
    scene = bpy.context.scene
    k = r.choice(["persp", "persp", "ortho", "pano", "pano", "dof", "shift", "clip", "inside",
                  "mesh_as_camera", "scale", "sensor"])
    cam_ob = scene.camera
    if cam_ob is None or cam_ob.type != "CAMERA":
        bs.camera(location=(0, -4, 2.5), target=(0, 0, 0))
        cam_ob = scene.camera
    cam = cam_ob.data
    if k == "persp":
        cam.lens = r.choice([1.0, 5.0, 50.0, 500.0, 5000.0])
    elif k == "ortho":
        cam.type = "ORTHO"
        cam.ortho_scale = r.choice([1e-4, 1.0, 10.0, 1e4])
    elif k == "pano":
        cam.type = "PANO"
        types = cam.bl_rna.properties["panorama_type"].enum_items
        cam.panorama_type = r.choice([e.identifier for e in types])
        for p, v in (("fisheye_fov", r.choice([0.1, math.pi, 2 * math.pi])),
                     ("fisheye_lens", r.choice([0.1, 10.5])), ("latitude_min", -math.pi / 2),
                     ("longitude_max", r.choice([0.0, math.pi]))):
            if hasattr(cam, p) and r.random() < 0.5:
                setattr(cam, p, v)
        k = f"pano {cam.panorama_type}"
    elif k == "dof":
        cam.dof.use_dof = True
        cam.dof.aperture_fstop = r.choice([0.1, 1.0, 128.0, 1e-3])
        cam.dof.focus_distance = r.choice([0.0, 0.1, 4.5, 1e4])
        cam.dof.aperture_blades = r.choice([0, 3, 16])
        cam.dof.aperture_ratio = r.choice([1.0, 0.01, 100.0])
        if r.random() < 0.3 and case.objects:
            cam.dof.focus_object = r.choice(case.objects)
    elif k == "shift":
        cam.shift_x, cam.shift_y = r.choice([(0.5, 0), (-10, 10), (0, 0.3)])
    elif k == "clip":
        cam.clip_start, cam.clip_end = r.choice([(1e-6, 1e-5), (10, 1), (0.1, 1e12), (100, 200), (5, 5)])
    elif k == "inside":
        cam_ob.location = (0, 0, 0)
    elif k == "mesh_as_camera":
        objs = [o for o in scene.objects if o.type != "CAMERA"]
        if objs:
            scene.camera = r.choice(objs)
            k = f"camera is {scene.camera.type} {scene.camera.name}"
    elif k == "scale":
        cam_ob.scale = r.choice([(0, 0, 0), (-1, 1, 1), (1, 1, -1), (10, 10, 10)])
    elif k == "sensor":
        cam.sensor_fit = r.choice(["AUTO", "HORIZONTAL", "VERTICAL"])
        cam.sensor_width = r.choice([1.0, 36.0, 100.0])
        cam.sensor_height = r.choice([1.0, 24.0, 100.0])
    case.log(f"camera {k}")


def f_view_layer(r, case):
    scene = bpy.context.scene
    vl = bpy.context.view_layer
    props = ["use_pass_z", "use_pass_mist", "use_pass_position", "use_pass_normal", "use_pass_uv",
             "use_pass_object_index", "use_pass_material_index", "use_pass_diffuse_direct",
             "use_pass_diffuse_indirect", "use_pass_diffuse_color", "use_pass_glossy_direct",
             "use_pass_glossy_indirect", "use_pass_glossy_color", "use_pass_transmission_direct",
             "use_pass_transmission_indirect", "use_pass_transmission_color", "use_pass_emit",
             "use_pass_environment", "use_pass_ambient_occlusion", "use_pass_cryptomatte_object",
             "use_pass_cryptomatte_material", "use_pass_cryptomatte_asset", "use_pass_shadow",
             "use_pass_vector", "use_pass_subsurface_direct"]
    chosen = r.sample(props, r.randint(1, 8))
    for p in chosen:
        setattr(vl, p, True)
    cy = ["denoising_store_passes", "use_pass_volume_direct", "use_pass_volume_indirect",
          "use_pass_shadow_catcher"]
    for p in cy:
        if r.random() < 0.2:
            setattr(vl.cycles, p, True)
            chosen.append(p)
    if r.random() < 0.3:
        vl.pass_cryptomatte_depth = r.choice([1, 2, 6, 16])
    if r.random() < 0.3:
        vl.pass_alpha_threshold = r.choice([0.0, 1.0])
    if r.random() < 0.4:
        for name in r.sample(["LG", "LG2", "Empty Group", "weird name.1"], r.randint(1, 3)):
            vl.lightgroups.add(name=name)
        for ob in scene.objects:
            if ob.type in ("LIGHT", "MESH") and r.random() < 0.5:
                ob.lightgroup = r.choice(["LG", "LG2", "Missing"])
        if scene.world is not None and r.random() < 0.5:
            scene.world.lightgroup = "LG2"
        chosen.append("lightgroups")
    if r.random() < 0.2:
        aov = vl.aovs.add()
        aov.name = r.choice(["aov", "", "Depth"])
        aov.type = r.choice(["COLOR", "VALUE"])
        chosen.append(f"aov:{aov.name}")
    if r.random() < 0.1:
        vl.material_override = random_material(r, case)
        chosen.append("material_override")
    if r.random() < 0.1:
        vl.use_strand = False
    if r.random() < 0.1:
        vl2 = scene.view_layers.new("Second")
        vl2.use_pass_normal = True
        chosen.append("second view layer")
    case.log(f"view layer passes {chosen}")
    case.passes = True


def f_shading_test_object(r, case):
    """A sphere of one random material in front of the camera (material-focused)."""
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=0.8)
    me = bpy.data.meshes.new("Ball")
    bm.to_mesh(me)
    bm.free()
    me.shade_smooth()
    me.uv_layers.new(name="UVMap")
    ob = link(case, bpy.data.objects.new("Ball", me))
    me.materials.append(random_material(r, case))
    if r.random() < 0.3:
        add_modifiers(r, case, ob)


def f_emissive_mesh(r, case):
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=r.choice([0.5, 1e-4, 10.0]))
    mat = bs.emission("Emit", rcolor(r, 0.2)[:3], r.choice([0.0, 1.0, 10.0, 1e6, -5.0]))
    ob = bs.mesh_object("Emitter", bm, mat, location=(0, 0, 2), rotation=(math.pi, 0, 0))
    case.objects.append(ob)
    case.log("emissive quad")


def f_render_opts(r, case):
    scene = bpy.context.scene
    k = r.choice(["film_transparent", "motion_blur", "pixel_aspect", "frame", "simplify", "filter"])
    if k == "film_transparent":
        scene.render.film_transparent = True
    elif k == "motion_blur":
        scene.render.use_motion_blur = True
    elif k == "pixel_aspect":
        scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = r.choice([(1, 200), (200, 1), (3, 1)])
    elif k == "frame":
        scene.frame_set(r.choice([0, -100, 100000]))
    elif k == "simplify":
        scene.render.use_simplify = True
        scene.render.simplify_subdivision_render = 0
    elif k == "filter":
        scene.cycles.filter_width = r.choice([0.01, 1.5, 10.0])
    case.log(f"render option {k}")


# ---------------------------------------------------------------------------- features (stop 75)
# Appended: drawn only for combo cases from NEW_FEATURES_FROM on (fuzz_scenes.make_spec), and in
# the single phase from id 21 on, so that the earlier cases stay as they were.
def new_mesh_object(r, case, name, kind=None, material=True, collection=None):
    """A primitive mesh object (random kind unless ``kind``) linked to the scene (or ``collection``)."""
    bm = bmesh.new()
    if kind == "sphere":
        bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=0.5)
    elif kind == "cube":
        bmesh.ops.create_cube(bm, size=1.0)
    else:
        bm.free()
        bm, kind = bm_primitive(r)
    me = bpy.data.meshes.new(name)
    bm.to_mesh(me)
    bm.free()
    ob = bpy.data.objects.new(name, me)
    if collection is None:
        link(case, ob)
    else:
        collection.objects.link(ob)
    if material:
        me.materials.append(random_material(r, case))
    return ob


def f_animated(r, case):
    """Shape keys and keyframed object, material, light and world values; then another frame."""
    scene = bpy.context.scene
    ob = new_mesh_object(r, case, "Anim", r.choice(["sphere", "cube", None]))
    me = ob.data
    kinds = []
    if r.random() < 0.7 and len(me.vertices):
        ob.shape_key_add(name="Basis")
        for i in range(r.randint(1, 3)):
            key = ob.shape_key_add(name=f"Key{i}")
            off = rvec(r, 3, 0.5, 0.15)
            for v in key.data:
                v.co = v.co + Vector(off) * r.random()
            key.value = rfloat(r, 0, 1, 0.3) if r.random() < 0.8 else r.choice([-10.0, 10.0])
            if r.random() < 0.3:
                key.slider_min, key.slider_max = -10.0, 10.0
            if r.random() < 0.5:
                key.value = 0.0
                key.keyframe_insert("value", frame=1)
                key.value = 1.0
                key.keyframe_insert("value", frame=r.choice([2, 10, 50]))
            if r.random() < 0.1:
                key.mute = True
        if r.random() < 0.2:
            me.shape_keys.use_relative = False
            me.shape_keys.eval_time = r.choice([0.0, 10.0, 1e6])
        kinds.append(f"shape keys {len(me.shape_keys.key_blocks)}")
    if r.random() < 0.7:
        for frame in sorted(r.sample([1, 2, 5, 10, 50, 100], r.randint(1, 3))):
            ob.location = rvec(r, 3, 1.5, 0.1)
            ob.rotation_euler = rvec(r, 3, math.pi, 0.0)
            ob.keyframe_insert("location", frame=frame)
            ob.keyframe_insert("rotation_euler", frame=frame)
            if r.random() < 0.3:
                ob.scale = r.choice([(1, 1, 1), (0, 0, 0), (-1, 1, 1), (2, 2, 2)])
                ob.keyframe_insert("scale", frame=frame)
        if r.random() < 0.3 and ob.animation_data and ob.animation_data.action:
            for fc in getattr(ob.animation_data.action, "fcurves", []):
                fc.extrapolation = "LINEAR"
                for kp in fc.keyframe_points:
                    kp.interpolation = r.choice(["CONSTANT", "LINEAR", "BEZIER", "ELASTIC", "BOUNCE"])
        kinds.append("object keys")
    mat = me.materials[0] if len(me.materials) else None
    if mat is not None and mat.node_tree is not None and r.random() < 0.5:
        socks = [s for n in mat.node_tree.nodes for s in n.inputs
                 if not s.is_linked and s.type in ("VALUE", "RGBA") and hasattr(s, "default_value")]
        if socks:
            s = r.choice(socks)
            for frame in (1, r.choice([3, 20])):
                set_socket(r, case, s, 0.3)
                s.keyframe_insert("default_value", frame=frame)
            kinds.append(f"material socket {s.node.name}.{s.name}")
    if r.random() < 0.5:
        ld = bpy.data.lights.new("AnimLight", r.choice(["POINT", "SPOT", "AREA", "SUN"]))
        lo = bpy.data.objects.new("AnimLight", ld)
        lo.location = (0, -1, 3)
        scene.collection.objects.link(lo)
        for frame, e in ((1, 0.0), (r.choice([5, 20]), r.choice([100.0, 1000.0, 1e6]))):
            ld.energy = e if ld.type != "SUN" else min(e, 10.0)
            ld.keyframe_insert("energy", frame=frame)
            ld.color = rcolor(r, 0.2)[:3]
            ld.keyframe_insert("color", frame=frame)
        kinds.append("light keys")
    if r.random() < 0.3 and scene.world is not None and scene.world.node_tree is not None:
        bg = scene.world.node_tree.nodes.get("Background")
        if bg is not None:
            for frame, v in ((1, 0.0), (10, r.choice([1.0, 5.0]))):
                bg.inputs["Strength"].default_value = v
                bg.inputs["Strength"].keyframe_insert("default_value", frame=frame)
            kinds.append("world keys")
    random_transform(r, case, ob) if r.random() < 0.2 else None
    frame = r.choice([0, 1, 3, 7, 25, 200, -5])
    sub = r.choice([0.0, 0.0, 0.5, 0.999])
    scene.frame_set(frame, subframe=sub)
    case.log(f"animated {kinds} frame {frame}+{sub}")


def f_drivers(r, case):
    """Drivers on object, shape key, material and light properties (some invalid)."""
    ob = new_mesh_object(r, case, "Driven", r.choice(["sphere", "cube", None]))
    other = r.choice([o for o in case.objects if o is not ob] or [ob])
    made = []
    for _ in range(r.randint(1, 4)):
        target = r.choice(["loc", "scale", "rot", "material", "light", "hide"])
        try:
            if target == "loc":
                fc = ob.driver_add("location", r.randint(0, 2))
            elif target == "scale":
                fc = ob.driver_add("scale", r.randint(0, 2))
            elif target == "rot":
                fc = ob.driver_add("rotation_euler", r.randint(0, 2))
            elif target == "hide":
                fc = ob.driver_add("hide_render")
            elif target == "material":
                mat = ob.data.materials[0]
                if mat is None or mat.node_tree is None:
                    continue
                socks = [(n, i) for n in mat.node_tree.nodes for i, s in enumerate(n.inputs)
                         if not s.is_linked and s.type == "VALUE" and hasattr(s, "default_value")]
                if not socks:
                    continue
                n, i = r.choice(socks)
                fc = mat.node_tree.driver_add(f'nodes["{n.name}"].inputs[{i}].default_value')
            else:
                ld = bpy.data.lights.new("DrivenLight", "POINT")
                lo = bpy.data.objects.new("DrivenLight", ld)
                lo.location = (1, -2, 2)
                bpy.context.scene.collection.objects.link(lo)
                fc = ld.driver_add("energy")
            d = fc.driver
            k = r.choice(["expr", "expr", "var", "avg", "bad", "python"])
            if k == "expr":
                d.type = "SCRIPTED"
                d.expression = r.choice(["frame / 10", "1 / 0", "sin(frame) * 2", "1e30", "-1",
                                         "0", "nan", "max(0, frame)"])
            elif k in ("var", "avg"):
                v = d.variables.new()
                v.name = "var"
                v.type = "TRANSFORMS"
                v.targets[0].id = other
                v.targets[0].transform_type = r.choice(["LOC_X", "LOC_Z", "SCALE_X", "ROT_Y"])
                if k == "var":
                    d.type = "SCRIPTED"
                    d.expression = r.choice(["var * 2", "var + 1", "1 / var"])
                else:
                    d.type = r.choice(["AVERAGE", "SUM", "MIN", "MAX"])
            elif k == "bad":
                d.type = "SCRIPTED"
                d.expression = r.choice(["undefined_name", "(", "var", ""])
            else:
                d.type = "SCRIPTED"
                d.expression = "bpy.context.scene.frame_current * 0.1"     # needs Python (auto-run off)
            made.append(f"{target}:{k}:{d.expression if d.type == 'SCRIPTED' else d.type}")
        except Exception as e:
            case.log(f"driver {target}: {e}")
    bpy.context.scene.frame_set(bpy.context.scene.frame_current)
    case.log(f"drivers {made}")


def f_stereo(r, case):
    """Multiview: stereo 3D or custom views, with the camera's stereo settings."""
    scene = bpy.context.scene
    rd = scene.render
    rd.use_multiview = True
    rd.views_format = r.choice(["STEREO_3D", "STEREO_3D", "MULTIVIEW"])
    if rd.views_format == "MULTIVIEW":
        v = rd.views.new("extra")
        v.camera_suffix = "_X"
        if r.random() < 0.5:
            rd.views["left"].use = False
    elif r.random() < 0.2:
        rd.views["right"].use = False
    cam = scene.camera
    if cam is not None and cam.type == "CAMERA":
        st = cam.data.stereo
        st.convergence_mode = r.choice(["OFFAXIS", "PARALLEL", "TOE"])
        st.interocular_distance = r.choice([0.065, 0.0, 1.0, 100.0])
        st.convergence_distance = r.choice([1.95, 1e-5, 1e4])
        if r.random() < 0.3:
            st.use_spherical_stereo = True
    scene.render.image_settings.views_format = r.choice(["INDIVIDUAL", "STEREO_3D"])
    case.log(f"multiview {rd.views_format} views={[v.name for v in rd.views if v.use]}")


def f_camera_enclosed(r, case):
    """The camera inside a closed object: glass, an opaque box, a volume, nested glass."""
    scene = bpy.context.scene
    if scene.camera is None or scene.camera.type != "CAMERA":
        bs.camera(location=(0, -4, 2.5), target=(0, 0, 0))
    cam = scene.camera
    k = r.choice(["glass", "opaque", "volume", "nested", "inside_out", "emissive"])
    size = r.choice([0.5, 2.0, 20.0])
    if k in ("glass", "nested"):
        mats = [bs.glass("EncGlass", r.choice([1.0, 1.33, 1.5, 2.4]))]
        if k == "nested":
            mats.append(bs.glass("EncGlass2", r.choice([1.1, 1.5])))
    elif k == "opaque":
        mats = [bs.diffuse("EncBox", (0.7, 0.7, 0.7))]
    elif k == "volume":
        mats = [bs.volume_material("EncFog", r.choice(VOLUME_SHADERS[:3]),
                                   surface=r.choice([None, "ShaderNodeBsdfTransparent"]))[0]]
    elif k == "emissive":
        mats = [bs.emission("EncGlow", (1, 1, 1), r.choice([1.0, 1e6]))]
    else:
        mats = [random_material(r, case)]
    for i, mat in enumerate(mats):
        bm = bmesh.new()
        if r.random() < 0.5:
            bmesh.ops.create_uvsphere(bm, u_segments=24, v_segments=12, radius=size / (i + 1))
        else:
            bmesh.ops.create_cube(bm, size=size / (i + 1))
        if k == "inside_out":
            bmesh.ops.reverse_faces(bm, faces=bm.faces)
        ob = bs.mesh_object(f"Enclosure{i}", bm, mat, location=tuple(cam.location))
        case.objects.append(ob)
    case.log(f"camera enclosed {k} size {size}")


def f_nested_glass(r, case):
    """Glass in glass, volumes in glass, overlapping glass, optionally a world volume."""
    made = []
    n = r.randint(2, 4)
    for i in range(n):
        k = r.choice(["glass", "glass", "refraction", "principled_glass", "volume", "glass_volume"])
        if k == "glass":
            mat = bs.glass(f"NG{i}", r.choice([1.0, 1.33, 1.5, 2.4, 0.5]))
        elif k == "refraction":
            mat = bs._material(f"NG{i}", "ShaderNodeBsdfRefraction")
            mat.node_tree.nodes["Refraction BSDF"].inputs["IOR"].default_value = r.choice([1.2, 1.5])
        elif k == "principled_glass":
            mat = bs._material(f"NG{i}", "ShaderNodeBsdfPrincipled")
            p = mat.node_tree.nodes["Principled BSDF"]
            p.inputs["Transmission Weight"].default_value = 1.0
            p.inputs["Roughness"].default_value = r.choice([0.0, 0.2])
            p.inputs["IOR"].default_value = r.choice([1.0, 1.45, 3.0])
        elif k == "volume":
            mat = bs.volume_material(f"NG{i}", r.choice(VOLUME_SHADERS))[0]
        else:
            mat = bs.volume_material(f"NG{i}", r.choice(VOLUME_SHADERS[:3]), surface="ShaderNodeBsdfGlass")[0]
        bm = bmesh.new()
        radius = 1.0 * (0.7 ** i) if r.random() < 0.8 else r.uniform(0.3, 1.0)
        if r.random() < 0.6:
            bmesh.ops.create_icosphere(bm, subdivisions=2, radius=radius)
        else:
            bmesh.ops.create_cube(bm, size=2 * radius)
        off = (0, 0, 0) if r.random() < 0.7 else rvec(r, 3, 0.4, 0.0)
        ob = bs.mesh_object(f"Nest{i}", bm, mat, location=off)
        case.objects.append(ob)
        made.append(k)
    if r.random() < 0.3:
        w = bs.world_volume(r.choice(VOLUME_SHADERS[:3]), (0.05, 0.05, 0.05))
        vn = [nd for nd in w.node_tree.nodes if nd.bl_idname in VOLUME_SHADERS][0]
        if "Density" in vn.inputs:
            vn.inputs["Density"].default_value = r.choice([0.01, 0.1, 1.0])
        made.append("world volume")
    case.log(f"nested glass {made}")


def f_linked_duplicates(r, case):
    """Objects sharing one mesh, each with its own modifiers, object-linked materials, parents of
    negative or zero scale."""
    src = new_mesh_object(r, case, "Shared", r.choice(["sphere", "cube", None]))
    me = src.data
    dups = [src]
    for i in range(r.randint(1, 4)):
        d = bpy.data.objects.new(f"Dup{i}", me)
        link(case, d)
        d.location = rvec(r, 3, 1.5, 0.0)
        dups.append(d)
    notes = []
    for d in dups:
        if r.random() < 0.5:
            add_modifiers(r, case, d)
        if r.random() < 0.3 and len(d.material_slots):
            d.material_slots[0].link = "OBJECT"
            d.material_slots[0].material = random_material(r, case) if r.random() < 0.8 else None
            notes.append(f"{d.name} object material")
    if r.random() < 0.6:
        parent = bpy.data.objects.new("Parent", None)
        bpy.context.scene.collection.objects.link(parent)
        parent.scale = r.choice([(-1, 1, 1), (-1, -1, -1), (1, 1, -1), (-2, 0.5, 1), (0, 1, 1)])
        parent.rotation_euler = rvec(r, 3, math.pi, 0.0)
        for d in r.sample(dups, r.randint(1, len(dups))):
            d.parent = parent
        if r.random() < 0.4:          # a chain: parent of a parent
            grand = bpy.data.objects.new("Grand", None)
            bpy.context.scene.collection.objects.link(grand)
            grand.scale = (-1, 1, 1)
            parent.parent = grand
            notes.append("grandparent")
        notes.append(f"parent scale {tuple(parent.scale)}")
    if r.random() < 0.2:
        me.materials.clear()
        notes.append("mesh materials cleared")
    case.log(f"linked duplicates x{len(dups)} {notes}")


def f_dupli_verts_faces(r, case):
    """Instancing by vertices or faces of a parent mesh (meshes, lights, collection instances)."""
    bm, kind = bm_primitive(r)
    me = bpy.data.meshes.new("Dupli")
    bm.to_mesh(me)
    bm.free()
    parent = link(case, bpy.data.objects.new("DupliParent", me))
    parent.instance_type = r.choice(["VERTS", "FACES"])
    if parent.instance_type == "FACES":
        parent.use_instance_faces_scale = r.random() < 0.5
        parent.instance_faces_scale = r.choice([1.0, 0.0, 0.3, 10.0])
    else:
        parent.use_instance_vertices_rotation = r.random() < 0.5
    parent.show_instancer_for_render = r.random() < 0.5
    if r.random() < 0.3:
        parent.scale = r.choice([(-1, 1, 1), (0.5, 0.5, 0.5), (1, 1, 0)])
    children = []
    for i in range(r.randint(1, 2)):
        k = r.choice(["mesh", "mesh", "light", "empty_inst"])
        if k == "mesh":
            c = new_mesh_object(r, case, f"DupliChild{i}", r.choice(["sphere", "cube"]))
            c.scale = (0.15, 0.15, 0.15)
        elif k == "light":
            ld = bpy.data.lights.new("DupliLight", r.choice(["POINT", "SPOT", "AREA"]))
            ld.energy = 20.0
            c = bpy.data.objects.new("DupliLight", ld)
            bpy.context.scene.collection.objects.link(c)
        else:
            coll = bpy.data.collections.new("DupliColl")
            new_mesh_object(r, case, "DupliCollMesh", "cube", collection=coll).scale = (0.1, 0.1, 0.1)
            c = bpy.data.objects.new("DupliEmpty", None)
            c.instance_type = "COLLECTION"
            c.instance_collection = coll
            bpy.context.scene.collection.objects.link(c)
        c.parent = parent
        children.append(k)
    case.log(f"instancing by {parent.instance_type} of {kind}: {children}")


def f_scene_scale(r, case):
    """Everything made so far scaled by 1e-4 or 1e4 (camera clip, light sizes and powers with it),
    by moving and scaling the objects, or by parenting them to a scaled empty."""
    scene = bpy.context.scene
    s = r.choice([1e-4, 1e-4, 1e4, 1e4, 1e-3, 1e3])
    how = r.choice(["objects", "objects", "parent"])
    roots = [o for o in scene.objects if o.parent is None]
    if how == "parent":
        top = bpy.data.objects.new("ScaleRoot", None)
        scene.collection.objects.link(top)
        top.scale = (s, s, s)
        for o in roots:
            o.parent = top
    else:
        for o in roots:
            o.location = o.location * s
            if o.type != "CAMERA":
                o.scale = o.scale * s
    for o in scene.objects:
        if o.type == "CAMERA":
            c = o.data
            c.clip_start, c.clip_end = c.clip_start * s, c.clip_end * s
            c.ortho_scale *= s
            c.dof.focus_distance *= s
        elif o.type == "LIGHT" and how == "objects":
            ld = o.data
            ld.shadow_soft_size *= s
            if ld.type == "AREA":
                ld.size *= s
                ld.size_y *= s
            if ld.type != "SUN" and r.random() < 0.7:
                ld.energy *= s * s
    case.log(f"scene scaled by {s} ({how}), {len(roots)} roots")


def f_light_linking(r, case):
    """Light and shadow linking between random emitters and objects (include, exclude, empty)."""
    scene = bpy.context.scene
    obs = [o for o in scene.objects if o.type in ("MESH", "CURVE", "POINTCLOUD", "CURVES", "VOLUME", "EMPTY")]
    emitters = [o for o in scene.objects if o.type == "LIGHT"] + [o for o in obs if o.type == "MESH"]
    if not emitters:
        ld = bpy.data.lights.new("LinkLight", "POINT")
        ld.energy = 300.0
        lo = bpy.data.objects.new("LinkLight", ld)
        lo.location = (-1, -1, 3)
        scene.collection.objects.link(lo)
        emitters = [lo]
    made = []
    for em in r.sample(emitters, min(len(emitters), r.randint(1, 3))):
        for kind in ("receiver", "blocker"):
            if r.random() < 0.4:
                continue
            coll = bpy.data.collections.new(f"{kind}_{em.name}")
            members = r.sample(obs, min(len(obs), r.randint(0, 3)))
            if r.random() < 0.15:
                members.append(em)                       # the emitter in its own collection
            for o in members:
                if o.name not in coll.objects:
                    coll.objects.link(o)
            if r.random() < 0.2:
                child = bpy.data.collections.new("child")
                coll.children.link(child)
                for o in r.sample(obs, min(len(obs), 1)):
                    child.objects.link(o)
                if len(coll.collection_children):
                    coll.collection_children[0].light_linking.link_state = r.choice(["INCLUDE", "EXCLUDE"])
            for link_ in coll.collection_objects:
                link_.light_linking.link_state = r.choice(["INCLUDE", "EXCLUDE"])
            setattr(em.light_linking, f"{kind}_collection", coll)
            made.append(f"{em.name}.{kind}: {[o.name for o in coll.objects]}")
    case.log(f"light linking {made}")


def f_curve_bevel(r, case):
    """Curves beveled by an object or a profile, with caps, a taper, start/end factors."""
    cu = bpy.data.curves.new("BevCurve", "CURVE")
    cu.dimensions = r.choice(["3D", "2D"])
    sp = cu.splines.new(r.choice(["BEZIER", "POLY"]))
    pts = sp.bezier_points if sp.type == "BEZIER" else sp.points
    pts.add(r.randint(1, 4))
    for i, p in enumerate(pts):
        co = (i * 0.6 - 1, r.uniform(-0.5, 0.5), r.uniform(0, 0.8) if cu.dimensions == "3D" else 0)
        if sp.type == "BEZIER":
            p.co = co
            p.handle_left_type = p.handle_right_type = "AUTO"
            p.radius = r.choice([1.0, 0.0, 3.0])
        else:
            p.co = (*co, 1.0)
    sp.use_cyclic_u = r.random() < 0.3
    mode = r.choice(["ROUND", "OBJECT", "PROFILE"])
    cu.bevel_mode = mode
    if mode == "OBJECT":
        pc = bpy.data.curves.new("Profile", "CURVE")
        ps = pc.splines.new("BEZIER")
        ps.bezier_points.add(3)
        for i, p in enumerate(ps.bezier_points):
            a = i * math.pi / 2
            p.co = (0.1 * math.cos(a), 0.1 * math.sin(a), 0)
            p.handle_left_type = p.handle_right_type = "AUTO"
        ps.use_cyclic_u = r.random() < 0.7
        prof = bpy.data.objects.new("Profile", pc)
        bpy.context.scene.collection.objects.link(prof)
        prof.location = (0, 0, -40)
        cu.bevel_object = prof
    else:
        cu.bevel_depth = rfloat(r, 0.01, 0.2, 0.2)
        cu.bevel_resolution = r.randint(0, 6)
    cu.use_fill_caps = r.random() < 0.7
    if r.random() < 0.3:
        tc = bpy.data.curves.new("Taper", "CURVE")
        ts = tc.splines.new("POLY")
        ts.points.add(2)
        for i, p in enumerate(ts.points):
            p.co = (i * 0.5, r.choice([0.0, 0.5, 1.0]), 0, 1)
        tob = bpy.data.objects.new("Taper", tc)
        bpy.context.scene.collection.objects.link(tob)
        cu.taper_object = tob
    cu.bevel_factor_start = r.choice([0.0, 0.0, 0.3])
    cu.bevel_factor_end = r.choice([1.0, 1.0, 0.3, 0.7])
    cu.offset = r.choice([0.0, 0.0, -0.1, 0.5])
    cu.extrude = r.choice([0.0, 0.0, 0.2])
    if cu.dimensions == "2D":
        cu.fill_mode = r.choice(["NONE", "BACK", "FRONT", "BOTH"])
    ob = link(case, bpy.data.objects.new("BevCurve", cu))
    assign_material(r, case, ob)
    case.log(f"curve bevel {mode} caps={cu.use_fill_caps} taper={cu.taper_object is not None} "
             f"factors=({cu.bevel_factor_start},{cu.bevel_factor_end})")


def f_grease_pencil(r, case):
    """A Grease Pencil object with a stroke or none (to be left out cleanly)."""
    gp = bpy.data.grease_pencils.new("GP")
    ob = bpy.data.objects.new("GP", gp)
    bpy.context.scene.collection.objects.link(ob)
    n = 0
    if r.random() < 0.8:
        layer = gp.layers.new("Lines")
        frame = layer.frames.new(bpy.context.scene.frame_current)
        d = frame.drawing
        n = r.choice([1, 3])
        d.add_strokes([r.choice([2, 5, 20])] * n)
        for s in d.strokes:
            for i, p in enumerate(s.points):
                p.position = (i * 0.1 - 0.5, r.uniform(-0.5, 0.5), r.uniform(0, 1))
                p.radius = r.choice([0.01, 0.1, 0.0])
        if r.random() < 0.7:
            mat = bpy.data.materials.new("GPMat")
            bpy.data.materials.create_gpencil_data(mat)
            mat.grease_pencil.show_fill = r.random() < 0.5
            gp.materials.append(mat)
    if r.random() < 0.3:
        ob.modifiers.new("Thick", r.choice(["GREASE_PENCIL_THICKNESS", "GREASE_PENCIL_ARRAY"]))
    case.log(f"grease pencil strokes={n}")


def f_material_odd(r, case):
    """Odd material structures: no output node, a disconnected or inactive output, muted nodes and
    links, a group node without a tree, only empty slots."""
    ob = new_mesh_object(r, case, "OddMat", r.choice(["sphere", "cube", None]), material=False)
    me = ob.data
    k = r.choice(["no_output", "disconnected", "inactive_output", "muted_node", "muted_link",
                  "empty_group", "empty_slots", "reroute_dangling", "invalid_link", "frame_parent"])
    mat = bpy.data.materials.new("Odd")
    nt = mat.node_tree
    nt.nodes.clear()
    shader = new_node(r, case, nt, r.choice(SURFACE_SHADERS[:8]))
    out = None
    if k != "no_output":
        out = nt.nodes.new("ShaderNodeOutputMaterial")
    if k in ("muted_node", "muted_link", "empty_group", "reroute_dangling", "invalid_link", "frame_parent",
             "inactive_output"):
        nt.links.new(shader.outputs[0], out.inputs["Surface"])
    if k == "inactive_output":
        out2 = nt.nodes.new("ShaderNodeOutputMaterial")
        nt.links.new(new_node(r, case, nt, "ShaderNodeEmission").outputs[0], out2.inputs["Surface"])
        out2.is_active_output = r.random() < 0.5
        out.is_active_output = not out2.is_active_output
        if r.random() < 0.3:
            out.target = "EEVEE"
    elif k == "muted_node":
        t = texture_chain(r, case, nt)
        ins = [s for s in shader.inputs if s.type in ("RGBA", "VALUE") and s.enabled]
        if ins:
            nt.links.new(t.outputs[0], ins[0])
        r.choice([t, shader]).mute = True
    elif k == "muted_link":
        t = texture_chain(r, case, nt)
        ins = [s for s in shader.inputs if s.type in ("RGBA", "VALUE") and s.enabled]
        if ins:
            nt.links.new(t.outputs[0], ins[0]).is_muted = True
        nt.links[0].is_muted = r.random() < 0.5
    elif k == "empty_group":
        g = nt.nodes.new("ShaderNodeGroup")
        ins = [s for s in shader.inputs if s.type in ("RGBA", "VALUE") and s.enabled]
        if ins and len(g.outputs):
            nt.links.new(g.outputs[0], ins[0])
    elif k == "reroute_dangling":
        rr = nt.nodes.new("NodeReroute")
        rr2 = nt.nodes.new("NodeReroute")
        nt.links.new(rr.outputs[0], rr2.inputs[0])
        ins = [s for s in shader.inputs if s.type in ("RGBA", "VALUE") and s.enabled]
        if ins:
            nt.links.new(rr2.outputs[0], ins[0])
    elif k == "invalid_link":
        t = texture_chain(r, case, nt)
        outs = [o for o in t.outputs] or []
        if outs:
            nt.links.new(outs[0], out.inputs["Surface"])       # a colour into the Surface input
    elif k == "frame_parent":
        fr = nt.nodes.new("NodeFrame")
        fr2 = nt.nodes.new("NodeFrame")
        fr2.parent = fr
        shader.parent = fr2
        out.parent = fr
    me.materials.append(None if k == "empty_slots" else mat)
    if k == "empty_slots" or r.random() < 0.3:
        for _ in range(r.randint(1, 3)):
            me.materials.append(None)
        for p in me.polygons:
            p.material_index = r.randint(0, len(me.materials) - 1)
    case.log(f"odd material {k}")


def _group_tree(r, case, depth, name):
    """A shader node group of custom inputs and outputs (some unlinked), reroutes and frames; it
    holds a group ``depth`` - 1 deep."""
    g = bpy.data.node_groups.new(name, "ShaderNodeTree")
    items = [("Color", "NodeSocketColor"), ("Fac", "NodeSocketFloat"), ("Vec", "NodeSocketVector"),
             ("Unused", "NodeSocketFloat")]
    for nm, st in items:
        s = g.interface.new_socket(nm, in_out="INPUT", socket_type=st)
        if hasattr(s, "default_value") and r.random() < 0.5:
            try:
                s.default_value = (r.random(), r.random(), r.random(), 1.0) if st == "NodeSocketColor" else \
                    ((0.5, 0.5, 0.5) if st == "NodeSocketVector" else rfloat(r, 0, 1, 0.3))
            except Exception as e:
                case.log(f"group default: {e}")
    g.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    g.interface.new_socket("Col", in_out="OUTPUT", socket_type="NodeSocketColor")
    g.interface.new_socket("Dangling", in_out="OUTPUT", socket_type="NodeSocketFloat")
    gi = g.nodes.new("NodeGroupInput")
    go = g.nodes.new("NodeGroupOutput")
    frame = g.nodes.new("NodeFrame")
    if depth > 1 and r.random() < 0.8:
        inner = g.nodes.new("ShaderNodeGroup")
        inner.node_tree = _group_tree(r, case, depth - 1, f"{name}_in")
        src = inner
        if r.random() < 0.7:
            g.links.new(gi.outputs["Color"], inner.inputs["Color"])
        if r.random() < 0.5:
            g.links.new(gi.outputs["Fac"], inner.inputs["Fac"])
        inner.parent = frame
    else:
        src = None
    glossy = "ShaderNodeBsdfGlossy" if "ShaderNodeBsdfGlossy" in dir(bpy.types) else "ShaderNodeBsdfDiffuse"
    shader = new_node(r, case, g, r.choice(["ShaderNodeBsdfPrincipled", "ShaderNodeBsdfDiffuse",
                                            "ShaderNodeEmission", glossy]))
    shader.parent = frame
    rr = g.nodes.new("NodeReroute")
    rr2 = g.nodes.new("NodeReroute")
    g.links.new(gi.outputs["Color"] if src is None or r.random() < 0.3 else src.outputs["Col"], rr.inputs[0])
    g.links.new(rr.outputs[0], rr2.inputs[0])
    if "Color" in shader.inputs or "Base Color" in shader.inputs:
        g.links.new(rr2.outputs[0], shader.inputs["Base Color" if "Base Color" in shader.inputs else "Color"])
    if src is not None and r.random() < 0.5:
        mix = g.nodes.new("ShaderNodeMixShader")
        g.links.new(gi.outputs["Fac"], mix.inputs[0])
        g.links.new(shader.outputs[0], mix.inputs[1])
        g.links.new(src.outputs["Shader"], mix.inputs[2])
        shader = mix
    if r.random() < 0.9:
        g.links.new(shader.outputs[0], go.inputs["Shader"])
    if r.random() < 0.6:
        g.links.new(rr2.outputs[0], go.inputs["Col"])
    return g


def f_node_groups(r, case):
    """A material of shader node groups nested several deep, with reroutes, frames and custom
    inputs and outputs, some unlinked; the same group used twice."""
    ob = new_mesh_object(r, case, "Grouped", r.choice(["sphere", "cube", None]), material=False)
    depth = r.randint(1, 5)
    g = _group_tree(r, case, depth, "G")
    mat = bpy.data.materials.new("GroupMat")
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    node = nt.nodes.new("ShaderNodeGroup")
    node.node_tree = g
    for s in node.inputs:
        if r.random() < 0.5:
            set_socket(r, case, s)
    if r.random() < 0.4:
        t = texture_chain(r, case, nt)
        nt.links.new(t.outputs[0], node.inputs[r.choice(["Color", "Fac", "Vec"])])
    k = r.choice(["shader", "color", "dangling", "twice"])
    if k == "shader":
        nt.links.new(node.outputs["Shader"], out.inputs["Surface"])
    elif k == "color":          # a group's colour as the Surface (emission in Cycles)
        nt.links.new(node.outputs["Col"], out.inputs["Surface"])
    elif k == "dangling":
        em = nt.nodes.new("ShaderNodeEmission")
        nt.links.new(node.outputs["Dangling"], em.inputs["Strength"])
        nt.links.new(em.outputs[0], out.inputs["Surface"])
    else:
        node2 = nt.nodes.new("ShaderNodeGroup")
        node2.node_tree = g
        node2.inputs["Fac"].default_value = 1.0 - node.inputs["Fac"].default_value
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(node.outputs["Shader"], add.inputs[0])
        nt.links.new(node2.outputs["Shader"], add.inputs[1])
        nt.links.new(add.outputs[0], out.inputs["Surface"])
    ob.data.materials.append(mat)
    if r.random() < 0.2 and bpy.context.scene.world is not None:      # the group in the world too
        wnt = bpy.context.scene.world.node_tree
        wn = wnt.nodes.new("ShaderNodeGroup")
        wn.node_tree = g
        bg = wnt.nodes.get("Background")
        if bg is not None:
            wnt.links.new(wn.outputs["Col"], bg.inputs["Color"])
            k += "+world"
    random_transform(r, case, ob) if r.random() < 0.2 else None
    case.log(f"node groups depth {depth} used as {k}")


def f_principled_all(r, case):
    """A Principled BSDF with every input fed by a texture, and Color Ramps of many stops."""
    ob = new_mesh_object(r, case, "AllIn", r.choice(["sphere", "cube", None]), material=False)
    if r.random() < 0.7:
        ob.data.uv_layers.new(name="UVMap")
    mat = bpy.data.materials.new("AllInputs")
    nt = mat.node_tree
    p = nt.nodes["Principled BSDF"]
    randomise_enums(r, case, p)
    n = 0
    for s in p.inputs:
        if s.type in ("SHADER", "STRING") or not s.enabled or r.random() < 0.1:
            continue
        if r.random() < 0.3:
            ramp = nt.nodes.new("ShaderNodeValToRGB")
            cr = ramp.color_ramp
            cr.interpolation = r.choice(["LINEAR", "CONSTANT", "EASE", "B_SPLINE", "CARDINAL"])
            cr.color_mode = r.choice(["RGB", "HSV", "HSL"])
            for _ in range(r.choice([2, 10, 30])):
                e = cr.elements.new(r.choice([r.random(), 0.5, 0.0, 1.0]))
                e.color = rcolor(r, 0.2)
            nt.links.new(texture_chain(r, case, nt).outputs[0], ramp.inputs[0])
            nt.links.new(ramp.outputs[r.choice([0, 1])], s)
        else:
            t = texture_chain(r, case, nt)
            outs = [o for o in t.outputs if o.enabled] or list(t.outputs)
            nt.links.new(r.choice(outs), s)
        n += 1
    ob.data.materials.append(mat)
    case.log(f"principled with {n} inputs textured")


def f_light_path(r, case):
    """Light Path tricks: camera-only emission, shadow-ray transparency, ray-depth cut-offs, a
    world seen differently by the camera."""
    ob = new_mesh_object(r, case, "LPath", r.choice(["sphere", "cube", None]), material=False)
    mat = bpy.data.materials.new("LightPath")
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    lp = nt.nodes.new("ShaderNodeLightPath")
    mix = nt.nodes.new("ShaderNodeMixShader")
    a = new_node(r, case, nt, r.choice(["ShaderNodeEmission", "ShaderNodeBsdfDiffuse",
                                        "ShaderNodeBsdfGlass"]))
    b = new_node(r, case, nt, r.choice(["ShaderNodeBsdfTransparent", "ShaderNodeBsdfDiffuse",
                                        "ShaderNodeHoldout", "ShaderNodeEmission"]))
    outname = r.choice([o.name for o in lp.outputs])
    src = lp.outputs[outname]
    if outname in ("Ray Length", "Ray Depth", "Diffuse Depth", "Glossy Depth", "Transparent Depth",
                   "Transmission Depth", "Portal Depth") and r.random() < 0.7:
        m = nt.nodes.new("ShaderNodeMath")
        m.operation = r.choice(["GREATER_THAN", "LESS_THAN", "DIVIDE", "MODULO"])
        m.inputs[1].default_value = r.choice([0.0, 0.5, 1.0, 2.0])
        nt.links.new(src, m.inputs[0])
        src = m.outputs[0]
    nt.links.new(src, mix.inputs[0])
    nt.links.new(a.outputs[0], mix.inputs[1])
    nt.links.new(b.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    if r.random() < 0.3:        # a light path value as a colour
        ins = [s for s in a.inputs if s.type in ("RGBA", "VALUE") and s.enabled]
        if ins:
            nt.links.new(lp.outputs[r.choice([o.name for o in lp.outputs])], r.choice(ins))
    ob.data.materials.append(mat)
    k = f"material {outname}"
    if r.random() < 0.4:
        w = bs.world((0.02, 0.02, 0.02), 1.0)
        wnt = w.node_tree
        wlp = wnt.nodes.new("ShaderNodeLightPath")
        wmix = wnt.nodes.new("ShaderNodeMixShader")
        bg1 = wnt.nodes["Background"]
        bg2 = wnt.nodes.new("ShaderNodeBackground")
        bg2.inputs["Color"].default_value = rcolor(r, 0.3)
        bg2.inputs["Strength"].default_value = r.choice([1.0, 5.0, 0.0])
        wnt.links.new(wlp.outputs[r.choice(["Is Camera Ray", "Is Glossy Ray", "Is Diffuse Ray",
                                            "Ray Depth"])], wmix.inputs[0])
        wnt.links.new(bg1.outputs[0], wmix.inputs[1])
        wnt.links.new(bg2.outputs[0], wmix.inputs[2])
        wnt.links.new(wmix.outputs[0], wnt.nodes["World Output"].inputs["Surface"])
        k += " + world"
    case.log(f"light path {k}")


def f_aov_outputs(r, case):
    """AOV Output nodes in materials (and in a group), names matching the view layer's AOVs or not."""
    vl = bpy.context.view_layer
    names = []
    for _ in range(r.randint(0, 3)):
        aov = vl.aovs.add()
        aov.name = r.choice(["col", "val", "aov", "dup", "dup", ""])
        aov.type = r.choice(["COLOR", "VALUE"])
        names.append(f"{aov.name}:{aov.type}")
    made = []
    for i in range(r.randint(1, 2)):
        ob = new_mesh_object(r, case, f"AOVObj{i}", r.choice(["sphere", "cube", None]))
        mat = ob.data.materials[0]
        nt = mat.node_tree
        for _ in range(r.randint(1, 3)):
            node = nt.nodes.new("ShaderNodeOutputAOV")
            node.aov_name = r.choice(["col", "val", "aov", "dup", "missing", ""])
            if r.random() < 0.7:
                t = texture_chain(r, case, nt)
                outs = [o for o in t.outputs if o.enabled] or list(t.outputs)
                nt.links.new(r.choice(outs), node.inputs[r.choice(["Color", "Value"])])
            else:
                node.inputs["Color"].default_value = rcolor(r, 0.3)
                node.inputs["Value"].default_value = rfloat(r, 0, 1, 0.3)
            made.append(node.aov_name)
        if r.random() < 0.3:
            g = bpy.data.node_groups.new("AOVGroup", "ShaderNodeTree")
            g.interface.new_socket("In", in_out="INPUT", socket_type="NodeSocketColor")
            gi = g.nodes.new("NodeGroupInput")
            a = g.nodes.new("ShaderNodeOutputAOV")
            a.aov_name = "col"
            g.links.new(gi.outputs[0], a.inputs["Color"])
            gn = nt.nodes.new("ShaderNodeGroup")
            gn.node_tree = g
            gn.inputs[0].default_value = rcolor(r, 0.2)
            made.append("group:col")
    case.passes = True
    case.log(f"AOVs {names} outputs {made}")


# Feature name -> builder(r, case).  The first three make the base scene (fuzz_scenes.BASE_FEATURES);
# fuzz_scenes.WEIGHTS says how often each of the others is drawn.
FEATURES = {
    "floor": f_floor, "camera": f_camera, "light": f_light,
    "mesh": f_mesh, "degenerate": f_degenerate, "ops_primitive": f_ops_primitive, "text": f_text,
    "curve": f_curve, "metaball": f_metaball, "collection_instance": f_collection_instance,
    "gn": f_gn_instances, "point_cloud": f_point_cloud, "hair_curves": f_hair_curves,
    "particles": f_particles,
    "volume_object": f_volume_object, "volume_cube": f_volume_cube, "flags": f_flags,
    "random_light": f_random_light, "world": f_world, "camera_random": f_camera_random,
    "view_layer": f_view_layer, "material_ball": f_shading_test_object, "emissive_mesh": f_emissive_mesh,
    "render_opts": f_render_opts,
    # (stop 75)
    "animated": f_animated, "drivers": f_drivers, "stereo": f_stereo, "camera_enclosed": f_camera_enclosed,
    "nested_glass": f_nested_glass, "linked_duplicates": f_linked_duplicates,
    "dupli_verts_faces": f_dupli_verts_faces, "scene_scale": f_scene_scale, "light_linking": f_light_linking,
    "curve_bevel": f_curve_bevel, "grease_pencil": f_grease_pencil, "material_odd": f_material_odd,
    "node_groups": f_node_groups, "principled_all": f_principled_all, "light_path": f_light_path,
    "aov_outputs": f_aov_outputs,
}


# ---------------------------------------------------------------------------- settings
def apply_settings(r, case, scene, light=False, resolution=None):
    """Random engine settings and image size (light: only the size and a few of them); returns a
    description of them.  ``resolution`` (W, H), if given, replaces the drawn size (the draws stay
    the same)."""
    p = scene.amcmcppm
    res = r.choice([(8, 8), (16, 12), (24, 24), (32, 24), (48, 36), (1, 1), (13, 7), (2, 40)])
    if resolution:
        res = tuple(resolution)
    scene.render.resolution_x, scene.render.resolution_y = res
    scene.render.resolution_percentage = 100 if r.random() < 0.85 else r.choice([1, 50, 50, 200, 200, 200])
    p.passes = r.randint(1, 3)
    p.time_limit = 0.0
    p.workers = 1
    p.photons_per_pass = r.randint(2000, 20000)
    p.first_pass_photons = r.choice([0, r.randint(2000, 20000)])
    p.seed = r.randint(0, 1000)
    desc = {"res": res, "pct": scene.render.resolution_percentage}
    if r.random() < 0.15:
        scene.render.use_border = True
        x0, y0 = r.random(), r.random()
        x1 = r.choice([min(1.0, x0 + r.random())] * 8 + [x0, min(1.0, x0 + 1.01 / res[0])])
        y1 = r.choice([min(1.0, y0 + r.random())] * 8 + [y0, min(1.0, y0 + 1.01 / res[1])])
        scene.render.border_min_x, scene.render.border_max_x = x0, x1
        scene.render.border_min_y, scene.render.border_max_y = y0, y1
        scene.render.use_crop_to_border = r.random() < 0.5
        desc["border"] = (round(x0, 3), round(x1, 3), round(y0, 3), round(y1, 3),
                          scene.render.use_crop_to_border)
    if light:
        return desc
    p.method = r.choice(["amcmcppm", "ppm", "auto"])
    p.direct_light = r.choice(["sampled", "photons"])
    p.pixel_jitter = r.choice(["stratified", "random"])
    p.bias_correction = r.random() < 0.4
    p.edge_coverage = r.random() < 0.5
    p.focus_photons = r.random() < 0.5
    p.chains = r.choice([1, 7, 64, 256, 1024])
    if r.random() < 0.3:
        p.alpha = r.choice([0.01, 0.5, 0.99])
    if r.random() < 0.3:
        p.initial_radius_px = r.choice([0.01, 1.0, 32.0, 1000.0])
    if r.random() < 0.3:
        p.target_acceptance = r.choice([0.01, 0.234, 0.99])
        p.mutation = r.choice(["off", "paper", "exact"])
        p.normalisation = r.choice(["cumulative", "per_pass"])
        p.initial_mutation_size = r.choice([2e-4, 0.1, 1e3])
    if r.random() < 0.2:
        p.glossy_through_roughness = r.choice([0.0, 1.0])
    if r.random() < 0.3:
        p.direct_samples = r.choice([1, 4, 64])
    if r.random() < 0.15:
        p.passes = 0
        p.time_limit = r.choice([0.5, 2.0])
        desc["time_limit"] = p.time_limit
    p.light_paths_from_cycles = r.random() < 0.4
    tgt = scene.cycles if p.light_paths_from_cycles else p
    if r.random() < 0.5:
        for name in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                     "volume_bounces", "transparent_max_bounces"):
            if r.random() < 0.5:
                v = r.choice([0, 1, 2, 8, 1024]) if tgt is scene.cycles else r.choice([0, 1, 2, 8])
                try:
                    setattr(tgt, name, v)
                except Exception as e:
                    case.log(f"bounce {name}={v}: {e}")
        tgt.caustics_reflective = r.random() < 0.7
        tgt.caustics_refractive = r.random() < 0.7
    desc.update({k: getattr(p, k) for k in ("method", "direct_light", "pixel_jitter", "bias_correction",
                                              "edge_coverage", "focus_photons", "chains", "passes",
                                              "photons_per_pass", "first_pass_photons",
                                              "light_paths_from_cycles", "max_bounces")})
    return desc

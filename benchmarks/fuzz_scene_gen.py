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

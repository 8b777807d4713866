"""Blender texture and colour nodes -> the core's procedural programs (``core/procedural.py``).

:class:`ExpressionBuilder` follows the links into a socket and returns either a constant (a float,
or three floats for colour and vector sockets) or a program node dict, inserting the type
conversions Cycles makes where a link joins sockets of different types (colour to float by
luminance, vector to float by the average, float to colour as grey). Supported nodes: Texture
Coordinate (Generated, Object, UV, Normal, Camera, Window), UV Map (the active render one or a
named one), Color Attribute (the render one or a named one), Attribute (a mesh attribute by name;
an object's or instancer's property), Object Info (per object: Location, Color, Alpha, Object Index
and Random as Cycles sets them; Material Index the material's pass index), Geometry (Position,
Normal and True Normal in world space, Incoming, Backfacing, Parametric; Random Per Island;
Pointiness), Camera Data, Wireframe (in world units), Ambient Occlusion, Bevel (its normal), Light
Path, Mapping (all four types), Image Texture (flat and box projections, every extension, linear,
closest, cubic or smart), Environment Texture (equirectangular), Checker, Gradient, Noise, Voronoi,
Wave, Brick, Magic and White Noise Textures, Color Ramp (sampled by Blender itself, as Cycles bakes
it), Mix (float, vector, colour; 19 blend modes) and the legacy MixRGB, Math (every operation),
Vector Math, Vector Transform, Normal, Vector Rotate (a constant rotation), Clamp, Map Range (float
and vector), RGB Curves, Vector Curves and Float Curve (sampled by Blender as Cycles bakes them),
Invert, Gamma, Hue/Saturation/Value, Bright/Contrast, RGB to BW, Wavelength, Separate/Combine XYZ
and Color (RGB, HSV, HSL), RGB and Value, Fresnel and Layer Weight (at the direction of the ray
that meets the hit: the eye's, or where a photon came from). Anything else is named in the
material's warning and replaced by the input socket's own value. Settings that Cycles lets vary
over the surface but the core takes as constants (a texture's Scale, Detail, ...; Mapping's
Location, Rotation, Scale) use the mean of what drives them, with a note.
"""
from __future__ import annotations

import numpy as np

from ...core import procedural
from ...core.sampling import affine_inverse
from .mesh import (ALPHA, HAIR_INTERCEPT, HAIR_IS_STRAND, HAIR_LENGTH, HAIR_RANDOM, HAIR_THICKNESS, PARTICLE,
                   POINT_POSITION, POINT_RADIUS, POINT_RANDOM, POINTINESS, RANDOM_PER_ISLAND, rna_property)

RAMP_TABLE_SIZE = 256            # Cycles' RAMP_TABLE_SIZE: the colour band baked into a table
FLOAT, VEC = "float", "vec"
SOCKET_KIND = {"VALUE": FLOAT, "INT": FLOAT, "BOOLEAN": FLOAT, "RGBA": VEC, "VECTOR": VEC}


class ExpressionBuilder:
    """Builds program expressions for one material; ``walker`` is its ``NodeWalker`` (links,
    notes, images)."""

    def __init__(self, walker):
        self.walker = walker
        self._memo = {}

    # ----------------------------------------------------------------- entry points
    def expression(self, sock, stack, want):
        """Constant or node dict of what feeds input ``sock``, as ``want`` (FLOAT or VEC)."""
        src, default, stack = self.walker.source(sock, stack)
        if src is None:
            return _constant(default if default is not None else sock, want)
        node = src.node
        handler = None if node.mute else NODES.get(node.bl_idname)
        if handler is None:
            self.walker.unsupported(node, f"drives '{sock.name}'; using the socket's value"
                                    if not node.mute else "(muted)")
            return _constant(sock, want)
        key = (node.as_pointer(), tuple(g.as_pointer() for g in stack))
        if key not in self._memo:
            self._memo[key] = handler(self, node, stack)
        built = self._memo[key]
        if built is None:                               # the handler noted why
            return _constant(sock, want)
        value = built.get(src.identifier, built.get(src.name))
        if value is None:
            self.walker.unsupported(node, f"output '{src.name}' drives '{sock.name}'; using the socket's "
                                    "value")
            return _constant(sock, want)
        return _convert(value, SOCKET_KIND.get(src.type, VEC), src.type, want)

    def constant_of(self, sock, stack, want=FLOAT):
        """A setting the core takes as a constant: the socket's value, or the mean of what
        drives it (noted)."""
        e = self.expression(sock, stack, want)
        if not isinstance(e, dict):
            return e
        mean = self.walker.textures.mean_value(e)
        mean = mean if want == FLOAT else mean.tolist()
        if not procedural.varies(e):
            return mean                                 # constant nodes only (Math of numbers...)
        self.walker.note(f"'{sock.node.name}': {sock.name} varies over the surface, which is not "
                         f"supported here; using its mean {np.round(mean, 3).tolist()}")
        return mean

    def input(self, node, name, stack, want):
        sock = (node.inputs[name] if name in node.inputs
                else next(s for s in node.inputs if s.identifier == name))
        return self.expression(sock, stack, want)

    def vector_or(self, node, stack, default_attribute):
        """The node's Vector input, or the coordinates Cycles uses when it is not linked."""
        sock = node.inputs.get("Vector")
        src, default, _ = self.walker.source(sock, stack) if sock is not None else (None, None, ())
        if src is None and (default is None or default.as_pointer() == sock.as_pointer()):
            # Unlinked, or fed by a dangling reroute or a muted node with an unlinked input (a
            # group node's unlinked Vector passes its value, as in Cycles).
            return {"op": "attribute", "name": default_attribute}
        return self.expression(sock, stack, VEC)


# ---------------------------------------------------------------------- conversions
def _constant(sock, want):
    """A socket's own value as ``want``."""
    value = getattr(sock, "default_value", 0.0)
    try:
        v = ([float(x) for x in value] + [0.0] * 3)[:3]
    except TypeError:
        return _convert(float(value), FLOAT, "VALUE", want)
    return _convert(v, VEC, sock.type, want)


def _convert(value, kind, socket_type, want):
    """``value`` of an output of ``kind`` as ``want`` (Cycles' implicit conversions)."""
    if kind == want:
        return value
    if not isinstance(value, dict):             # a constant output (RGB, Value, missing image)
        if want == VEC:
            return [float(value)] * 3
        return float(np.dot(value, procedural.LUMINANCE)) if socket_type == "RGBA" else float(np.mean(value))
    if want == VEC:
        return {"op": "splat", "value": value}
    if socket_type == "RGBA":
        return {"op": "gray", "color": value}
    return {"op": "average", "vector": value}


def _out(op, **outputs):
    """Outputs (by socket identifier) of one program node ``op``."""
    return {name: {**op, "output": out} for name, out in outputs.items()}


# ---------------------------------------------------------------------- nodes
def _tex_coord(b, node, stack):
    """Texture Coordinate: the attributes of ``procedural``; Reflection the view reflected about the
    shading normal in world space, 2 (N . I) N - I (Cycles; in a world, I); Object in the space of the
    node's object when it names one (its inverse world matrix on the hit's world position)."""
    normal, incoming = {"op": "attribute", "name": "world_normal"}, {"op": "attribute", "name": "incoming"}
    cosine = {"op": "vector_math", "operation": "DOT_PRODUCT", "a": normal, "b": incoming, "output": "Value"}
    twice = {"op": "math", "operation": "MULTIPLY", "a": 2.0, "b": cosine}
    out = {"Generated": {"op": "attribute", "name": "generated"},
           "UV": {"op": "attribute", "name": "uv"}, "Normal": {"op": "attribute", "name": "normal"},
           "Camera": {"op": "attribute", "name": "camera"}, "Window": {"op": "attribute", "name": "window"},
           "Reflection": {"op": "vector_math", "operation": "SUBTRACT", "b": incoming,
                          "a": {"op": "vector_math", "operation": "SCALE", "a": normal, "scale": twice}}}
    if node.object is None:
        out["Object"] = {"op": "attribute", "name": "object"}
    else:
        m = affine_inverse(np.array(node.object.matrix_world, np.float64))
        out["Object"] = {"op": "affine", "vector": {"op": "attribute", "name": "position"},
                         "matrix": m[:3, :3].tolist(), "post": m[:3, 3].tolist()}
    return out


def _geometry(b, node, stack):
    """Geometry: Position, Normal and True Normal in world space (turned towards the ray on a back
    face, as Cycles), Incoming and Backfacing (``procedural.RAY``), Parametric
    (``procedural.TRIANGLE``), Tangent (radial about the object's Z axis, Cycles'
    ``primitive_tangent``: ``procedural.TANGENTS``), Random Per Island and Pointiness
    (``mesh.random_per_island``, ``mesh.pointiness``)."""
    return {"Position": {"op": "attribute", "name": "position"},
            "Normal": {"op": "attribute", "name": "world_normal"},
            "True Normal": {"op": "attribute", "name": "true_normal"},
            "Incoming": {"op": "attribute", "name": "incoming"},
            "Parametric": {"op": "attribute", "name": "parametric"},
            "Tangent": {"op": "attribute", "name": "tangent_z"},
            "Backfacing": {"op": "separate", "vector": {"op": "attribute", "name": "backfacing"},
                           "output": "X"},
            "Random Per Island": {"op": "separate", "vector": _named(RANDOM_PER_ISLAND), "output": "X"},
            "Pointiness": {"op": "separate", "vector": _named(POINTINESS), "output": "X"}}


def _tangent(b, node, stack):
    """Tangent: radial about the object's X, Y or Z axis, or the UV map's tangents (the active render
    map's; another map named is noted), perpendicular to the normal (``procedural.TANGENTS``)."""
    if node.direction_type == "UV_MAP":
        if node.uv_map:
            b.walker.note(f"'{node.name}': the active render UV map's tangents are used (UV map "
                          f"'{node.uv_map}' is not looked up apart)")
        return {"Tangent": {"op": "attribute", "name": "tangent_uv"}}
    return {"Tangent": {"op": "attribute", "name": "tangent_" + {"X": "x", "Y": "y"}.get(node.axis, "z")}}


def _point_info(b, node, stack):
    """Point Info: a point cloud's point (its centre, radius and Cycles' random number; 0 on meshes,
    as in Cycles), read as named attributes of its spheres (``mesh.POINT_INFO``)."""
    return {"Position": _named(POINT_POSITION),
            "Radius": {"op": "separate", "vector": _named(POINT_RADIUS), "output": "X"},
            "Random": {"op": "separate", "vector": _named(POINT_RANDOM), "output": "X"}}


def _hair_info(b, node, stack):
    """Curves Info (Hair Info): a hair curve's Is Strand, Intercept, Length, Thickness and Random,
    read as named attributes of its tube (``mesh.HAIR_INFO``; 0 on meshes, as in Cycles).  Its
    Tangent Normal is not modelled (named, the socket's value)."""
    return {out: {"op": "separate", "vector": _named(key), "output": "X"}
            for out, key in (("Is Strand", HAIR_IS_STRAND), ("Intercept", HAIR_INTERCEPT),
                             ("Length", HAIR_LENGTH), ("Thickness", HAIR_THICKNESS), ("Random", HAIR_RANDOM))}


def _camera_data(b, node, stack):
    """Camera Data: the hit in camera space (Texture Coordinate's Camera) normalised, its depth and
    its length, as Cycles' ``svm_node_camera``."""
    cam = {"op": "attribute", "name": "camera"}
    return {"View Vector": {"op": "vector_math", "operation": "NORMALIZE", "a": cam},
            "View Z Depth": {"op": "separate", "vector": cam, "output": "Z"},
            "View Distance": {"op": "vector_math", "operation": "LENGTH", "a": cam, "output": "Value"}}


def _wireframe(b, node, stack):
    """Wireframe: 1 where the hit lies within half the Size of a line through one of its
    triangle's edges (Cycles' ``wireframe``: a quad's diagonal shows too), else 0; the Size in
    world units, or with Pixel Size in the camera's pixels there (``procedural.TRIANGLE``'s
    "pixel_width")."""
    edges = {"op": "attribute", "name": "edge_distance"}
    nearest = {"op": "math", "operation": "MINIMUM", "a": {"op": "separate", "vector": edges, "output": "X"},
               "b": {"op": "math", "operation": "MINIMUM",
                     "a": {"op": "separate", "vector": edges, "output": "Y"},
                     "b": {"op": "separate", "vector": edges, "output": "Z"}}}
    half = {"op": "math", "operation": "ABSOLUTE",
            "a": {"op": "math", "operation": "MULTIPLY", "a": b.input(node, "Size", stack, FLOAT), "b": 0.5}}
    if node.use_pixel_size:
        pixel = {"op": "separate", "vector": {"op": "attribute", "name": "pixel_width"}, "output": "X"}
        half = {"op": "math", "operation": "MULTIPLY", "a": half, "b": pixel}
    return {"Fac": {"op": "math", "operation": "LESS_THAN", "a": nearest, "b": half}}


def _ambient_occlusion(b, node, stack):
    """Ambient Occlusion: Cycles' rays about the normal at each hit (``procedural`` op ``ao``)."""
    op = {"op": "ao", "color": b.input(node, "Color", stack, VEC),
          "distance": b.input(node, "Distance", stack, FLOAT), "samples": int(node.samples),
          "inside": bool(node.inside), "only_local": bool(node.only_local),
          **_normal_input(b, node, stack)}
    return _out(op, Color="Color", AO="AO")


def _bevel(b, node, stack):
    """Bevel: Cycles' bevelled normal at each hit seen by the camera (``procedural`` op ``bevel``)."""
    return {"Normal": {"op": "bevel", "radius": b.input(node, "Radius", stack, FLOAT),
                       "samples": int(node.samples), **_normal_input(b, node, stack)}}


def _light_path(b, node, stack):
    """Light Path: the outputs of the rays that meet each hit (``procedural.LIGHT_PATH``,
    ``procedural.Rays``): exact for camera paths, as from a first diffuse bounce at photons' hits."""
    return _out({"op": "light_path"}, **{name: name for name in procedural.LIGHT_PATH})


def _object_info(b, node, stack):
    info = {"op": "attribute", "name": "object_info"}          # (Alpha, Object Index, Random)
    return {"Location": {"op": "attribute", "name": "object_location"},
            "Color": {"op": "attribute", "name": "object_color"},
            "Alpha": {"op": "separate", "vector": info, "output": "X"},
            "Object Index": {"op": "separate", "vector": info, "output": "Y"},
            "Random": {"op": "separate", "vector": info, "output": "Z"},
            "Material Index": float(b.walker.pass_index)}


def _named(name):
    """The program of mesh attribute ``name`` (``procedural.NAMED``)."""
    return {"op": "attribute", "name": procedural.NAMED + name}


def _uv_map(b, node, stack):
    if node.from_instancer:
        b.walker.note(f"'{node.name}': UV maps from the instancer are not supported (the object's are used)")
    return {"UV": _named(node.uv_map) if node.uv_map else {"op": "attribute", "name": "uv"}}


def _color_attribute(b, node, stack):
    """Color Attribute: the render colour attribute, or the one it names, and its Alpha."""
    if node.layer_name:
        return {"Color": _named(node.layer_name), "Alpha": _alpha(_named(ALPHA + node.layer_name))}
    return {"Color": {"op": "attribute", "name": "color"}, "Alpha": _alpha(_named(ALPHA))}


def _alpha(value):
    """The float of a program ``value`` whose x, y and z are one number (an attribute's Alpha)."""
    return {"op": "separate", "vector": value, "output": "X"}


# Cycles' standard attribute names (``Attribute::standard_name``), which an Attribute node reads
# instead of a mesh attribute of that name: the volume grids' read 0 on a surface, Generated and the
# UV map are the texture coordinates, the others are not modelled here.
VOLUME_ATTRIBUTES = ("density", "color", "flame", "heat", "temperature", "velocity", "velocity_x",
                     "velocity_y", "velocity_z")
STANDARD_COORDINATES = {"generated": "generated", "uv": "uv"}
STANDARD_NAMED = {"random_per_island": RANDOM_PER_ISLAND, "pointiness": POINTINESS}
OTHER_STANDARD_ATTRIBUTES = ("N", "Ng", "tangent", "tangent_sign", "vertex_color", "undeformed",
                             "undisplaced", "motion_P", "motion_N", "particle", "curve_intercept",
                             "curve_length", "curve_random", "point_random", "ptex_face_id", "ptex_uv",
                             "generated_transform", "shadow_transparency")


def _attribute(b, node, stack):
    """Attribute of the Geometry type: the mesh attribute of that name (a float, vector, colour or
    2D one; 0 on meshes without it) as Color and Vector, its average as Fac (Cycles); Cycles'
    standard names first (``VOLUME_ATTRIBUTES``: 0; Generated and UV).  Of the Object and Instancer
    types: the object's property at that RNA path (``mesh.object_property``); of the View Layer
    type, one value for the render: the view layer's, the scene's or the world's
    (``view_layer_owners``).  Alpha (of the Geometry type): a colour attribute's alpha, 1 for the
    others and where there is none (``mesh.ALPHA``).  The other standard names are noted."""
    if node.attribute_type in ("OBJECT", "INSTANCER") and node.attribute_name:
        value = {"op": "attribute", "name": f"{node.attribute_type.lower()}:{node.attribute_name}"}
        return {"Color": value, "Vector": value, "Fac": {"op": "average", "vector": value}}
    if node.attribute_type == "VIEW_LAYER" and node.attribute_name and b.walker.layer_owners:
        value = rna_property(b.walker.layer_owners, node.attribute_name).astype(np.float64)
        return {"Color": value.tolist(), "Vector": value.tolist(), "Fac": float(value.mean())}
    name = node.attribute_name
    if node.attribute_type != "GEOMETRY" or not name or name in OTHER_STANDARD_ATTRIBUTES:
        kind = node.attribute_type.lower().replace("_", " ")
        what = (f"attributes of the {kind} type" if name and node.attribute_type != "GEOMETRY"
                else f"the attribute '{name}'" if name else "no attribute name")
        b.walker.note(f"'{node.name}': {what} not supported")
        return None
    if name in VOLUME_ATTRIBUTES:
        return {"Color": [0.0, 0.0, 0.0], "Vector": [0.0, 0.0, 0.0], "Fac": 0.0, "Alpha": 1.0}
    if name in STANDARD_COORDINATES or name in STANDARD_NAMED:
        value = ({"op": "attribute", "name": STANDARD_COORDINATES[name]} if name in STANDARD_COORDINATES
                 else _named(STANDARD_NAMED[name]))
        alpha = 1.0
    else:
        value, alpha = _named(name), _alpha(_named(ALPHA + name))
    return {"Color": value, "Vector": value, "Fac": {"op": "average", "vector": value}, "Alpha": alpha}


def view_layer_owners(depsgraph):
    """Where an Attribute node of the View Layer type looks its name up, in Cycles' order: the
    view layer, the scene, the world (``mesh.rna_property``)."""
    scene = depsgraph.scene_eval
    world = depsgraph.view_layer_eval.world_override or scene.world
    return tuple(x for x in (depsgraph.view_layer_eval, scene, world) if x is not None)


def _blackbody(b, node, stack):
    return {"Color": {"op": "blackbody", "temperature": b.input(node, "Temperature", stack, FLOAT)}}


def _rgb(b, node, stack):
    return {"Color": [float(x) for x in node.outputs[0].default_value[:3]]}


def _value(b, node, stack):
    return {"Value": float(node.outputs[0].default_value)}


def _mapping(b, node, stack):
    from mathutils import Euler
    # Vector and Normal mappings have no Location input.
    const = [b.constant_of(node.inputs[k], stack, VEC) if k in node.inputs else default
             for k, default in (("Location", [0.0] * 3), ("Rotation", [0.0] * 3), ("Scale", [1.0] * 3))]
    loc, rot, scale = (np.asarray(v, np.float64) for v in const)
    r = np.array(Euler(rot, "XYZ").to_matrix(), np.float64)
    inv_scale = np.where(scale != 0.0, 1.0 / np.where(scale != 0.0, scale, 1.0), 0.0)
    kind = node.vector_type
    op = {"op": "affine", "vector": b.expression(node.inputs["Vector"], stack, VEC)}
    if kind == "POINT":
        op.update(matrix=r * scale, post=loc)
    elif kind == "TEXTURE":
        op.update(matrix=inv_scale[:, None] * r.T, pre=loc)
    elif kind == "VECTOR":
        op.update(matrix=r * scale)
    else:                                               # NORMAL
        op.update(matrix=r * inv_scale, normalize=True)
    op["matrix"] = op["matrix"].tolist()
    for k in ("pre", "post"):
        if k in op:
            op[k] = op[k].tolist()
    return {"Vector": op}


def _image(b, node, stack):
    w = b.walker
    if node.image is None:
        w.note(f"image texture '{node.name}' has no image; using magenta")
        return {"Color": [1.0, 0.0, 1.0], "Alpha": 1.0}
    index, _ = w.textures.lookup(node.image, f"material '{w.name}'")
    if index < 0:
        return {"Color": [1.0, 0.0, 1.0], "Alpha": 1.0}
    # Cycles' CPU takes Smart as Cubic.
    interpolation = "Cubic" if node.interpolation == "Smart" else node.interpolation
    settings = {} if (node.extension, interpolation) == ("REPEAT", "Linear") else {
        "extension": node.extension, "interpolation": interpolation}
    if node.projection == "BOX":
        settings.update(projection="BOX", blend=float(node.projection_blend))
    elif node.projection in ("SPHERE", "TUBE"):
        settings.update(projection=node.projection)
    vector = b.vector_or(node, stack, "uv")
    # Cycles filters an image with alpha premultiplied.  Its Color is that, or when the Alpha output
    # is used, that divided by the filtered alpha: for float images (stored premultiplied) after
    # filtering, for byte ones (stored straight) in their 8-bit space, which gives back the colour
    # as painted.
    alpha = w.textures.alpha(index) if node.outputs["Alpha"].is_linked else None
    if alpha is None:
        return {"Color": {"op": "image", "texture": w.textures.premultiplied(index), "vector": vector,
                          **settings}, "Alpha": 1.0}
    alpha_op = {"op": "separate", "output": "X",
                "vector": {"op": "image", "texture": alpha, "vector": vector, **settings}}
    color = {"op": "image", "texture": index, "vector": vector, **settings}
    if not w.textures.is_byte(index):
        color = {"op": "unpremultiply", "color": color, "alpha": alpha_op}
    return {"Color": color, "Alpha": alpha_op}


def _environment(b, node, stack):
    w = b.walker
    if node.image is None:
        w.note(f"environment texture '{node.name}' has no image; using magenta")
        return {"Color": [1.0, 0.0, 1.0], "Alpha": 1.0}
    index, _ = w.textures.lookup(node.image, f"'{w.name}'")
    if index < 0:
        return {"Color": [1.0, 0.0, 1.0], "Alpha": 1.0}
    # (Equirectangular or Mirror Ball, the two projections Blender's node has)
    projection = {} if node.projection == "EQUIRECTANGULAR" else {"projection": node.projection}
    return {"Color": {"op": "environment", "texture": index, "vector": b.vector_or(node, stack, "generated"),
                      **projection}, "Alpha": 1.0}


def _sky(b, node, stack):
    if node.sky_type not in ("MULTIPLE_SCATTERING", "SINGLE_SCATTERING", "PREETHAM"):
        b.walker.note(f"'{node.name}': the {node.sky_type.replace('_', '-').title()} sky is not supported; "
                      "the input it feeds takes its own value")
        return None
    op = {"op": "sky", "vector": b.vector_or(node, stack, "generated"), "sky_type": node.sky_type,
          **{k: float(getattr(node, k)) for k in ("sun_elevation", "sun_rotation", "altitude", "air_density",
                                                  "aerosol_density", "ozone_density", "turbidity",
                                                  "sun_size", "sun_intensity")},
          "sun_disc": bool(node.sun_disc), "sun_direction": [float(x) for x in node.sun_direction]}
    return {"Color": op}


def _checker(b, node, stack):
    op = {"op": "checker", "vector": b.vector_or(node, stack, "generated"),
          "color1": b.input(node, "Color1", stack, VEC), "color2": b.input(node, "Color2", stack, VEC),
          "scale": b.input(node, "Scale", stack, FLOAT)}
    return _out(op, Color="Color", Fac="Fac")


def _gradient(b, node, stack):
    op = {"op": "gradient", "vector": b.vector_or(node, stack, "generated"),
          "gradient_type": node.gradient_type}
    return _out(op, Color="Color", Fac="Fac")


def _settings(b, node, stack, names):
    """The node's numeric settings that its current type shows (Blender removes the others)."""
    return {key: b.constant_of(node.inputs[name], stack) for key, name in names.items()
            if name in node.inputs and node.inputs[name].enabled}


def _noise(b, node, stack):
    op = {"op": "noise", "vector": b.vector_or(node, stack, "generated"),
          "dimensions": node.noise_dimensions, "noise_type": node.noise_type,
          "normalize": bool(node.normalize),
          **_settings(b, node, stack, {"scale": "Scale", "detail": "Detail", "roughness": "Roughness",
                                       "lacunarity": "Lacunarity", "distortion": "Distortion",
                                       "offset": "Offset", "gain": "Gain", "w": "W"})}
    return _out(op, Fac="Fac", Color="Color")


def _voronoi(b, node, stack):
    op = {"op": "voronoi", "vector": b.vector_or(node, stack, "generated"),
          "dimensions": node.voronoi_dimensions, "feature": node.feature, "metric": node.distance,
          "normalize": bool(node.normalize),
          **_settings(b, node, stack, {"scale": "Scale", "detail": "Detail", "roughness": "Roughness",
                                       "lacunarity": "Lacunarity", "smoothness": "Smoothness",
                                       "exponent": "Exponent", "randomness": "Randomness", "w": "W"})}
    return _out(op, Distance="Distance", Color="Color", Position="Position", W="W", Radius="Radius")


def _wave(b, node, stack):
    op = {"op": "wave", "vector": b.vector_or(node, stack, "generated"), "wave_type": node.wave_type,
          "bands_direction": node.bands_direction, "rings_direction": node.rings_direction,
          "wave_profile": node.wave_profile,
          **_settings(b, node, stack, {"scale": "Scale", "distortion": "Distortion", "detail": "Detail",
                                       "detail_scale": "Detail Scale", "detail_roughness": "Detail Roughness",
                                       "phase_offset": "Phase Offset"})}
    return _out(op, Color="Color", Fac="Fac")


def _brick(b, node, stack):
    op = {"op": "brick", "vector": b.vector_or(node, stack, "generated"),
          **{k: b.input(node, name, stack, VEC) for k, name in
             (("color1", "Color1"), ("color2", "Color2"), ("mortar", "Mortar"))},
          "offset": float(node.offset), "offset_frequency": int(node.offset_frequency),
          "squash": float(node.squash), "squash_frequency": int(node.squash_frequency),
          **_settings(b, node, stack, {"scale": "Scale", "mortar_size": "Mortar Size",
                                       "mortar_smooth": "Mortar Smooth", "bias": "Bias",
                                       "brick_width": "Brick Width", "row_height": "Row Height"})}
    return _out(op, Color="Color", Fac="Fac")


def _magic(b, node, stack):
    op = {"op": "magic", "vector": b.vector_or(node, stack, "generated"), "depth": int(node.turbulence_depth),
          **_settings(b, node, stack, {"scale": "Scale", "distortion": "Distortion"})}
    return _out(op, Color="Color", Fac="Fac")


def _white_noise(b, node, stack):
    op = {"op": "white_noise", "vector": b.vector_or(node, stack, "generated"),
          "dimensions": node.noise_dimensions, "w": b.input(node, "W", stack, FLOAT)}
    return _out(op, Value="Value", Color="Color")


def _gabor(b, node, stack):
    op = {"op": "gabor", "vector": b.vector_or(node, stack, "generated"),
          "gabor_type": node.gabor_type, "scale": b.input(node, "Scale", stack, FLOAT),
          "frequency": b.input(node, "Frequency", stack, FLOAT),
          "anisotropy": b.input(node, "Anisotropy", stack, FLOAT),
          "orientation_2d": b.input(node, "Orientation 2D", stack, FLOAT),
          "orientation_3d": b.input(node, "Orientation 3D", stack, VEC)}
    return _out(op, Value="Value", Phase="Phase", Intensity="Intensity")


def _ramp(b, node, stack):
    ramp = node.color_ramp
    table = [list(ramp.evaluate(i / (RAMP_TABLE_SIZE - 1))) for i in range(RAMP_TABLE_SIZE)]
    op = {"op": "ramp", "fac": b.input(node, "Fac", stack, FLOAT), "table": table,
          "interpolate": ramp.interpolation != "CONSTANT"}
    return _out(op, Color="Color", Alpha="Alpha")


def _mix(b, node, stack):
    kind = node.data_type
    if kind == "RGBA":
        blend = _blend_mode(b, node)
        op = {"op": "mix_color", "blend": blend, "fac": b.input(node, "Factor_Float", stack, FLOAT),
              "a": b.input(node, "A_Color", stack, VEC), "b": b.input(node, "B_Color", stack, VEC),
              "clamp_factor": bool(node.clamp_factor), "clamp_result": bool(node.clamp_result)}
        return {"Result_Color": op}
    if kind == "FLOAT":
        op = {"op": "mix_float", "fac": b.input(node, "Factor_Float", stack, FLOAT),
              "a": b.input(node, "A_Float", stack, FLOAT), "b": b.input(node, "B_Float", stack, FLOAT),
              "clamp_factor": bool(node.clamp_factor)}
        return {"Result_Float": op}
    if kind == "VECTOR" and node.factor_mode == "UNIFORM":
        op = {"op": "mix_vector", "fac": b.input(node, "Factor_Float", stack, FLOAT),
              "a": b.input(node, "A_Vector", stack, VEC), "b": b.input(node, "B_Vector", stack, VEC),
              "clamp_factor": bool(node.clamp_factor)}
        return {"Result_Vector": op}
    b.walker.unsupported(node, f"(mix of type {kind.lower()} / {node.factor_mode.lower()})")
    return None


def _mix_rgb(b, node, stack):
    op = {"op": "mix_color", "blend": _blend_mode(b, node), "fac": b.input(node, "Fac", stack, FLOAT),
          "a": b.input(node, "Color1", stack, VEC), "b": b.input(node, "Color2", stack, VEC),
          "clamp_factor": True, "clamp_result": bool(node.use_clamp)}
    return {"Color": op}


def _blend_mode(b, node):
    if node.blend_type in procedural.BLEND_MODES:
        return node.blend_type
    b.walker.note(f"'{node.name}': blend mode {node.blend_type.lower()} is not supported (mix is used)")
    return "MIX"


def _math(b, node, stack):
    if node.operation not in procedural.MATH:
        b.walker.unsupported(node, f"(operation {node.operation.lower()})")
        return None
    ins = [s for s in node.inputs]
    op = {"op": "math", "operation": node.operation, "clamp": bool(node.use_clamp),
          **{k: b.expression(s, stack, FLOAT) for k, s in zip("abc", ins)}}
    return {"Value": op}


def _vector_math(b, node, stack):
    if node.operation not in procedural.CHOICES[("vector_math", "operation")]:
        b.walker.unsupported(node, f"(operation {node.operation.lower()})")
        return None
    vectors = [s for s in node.inputs if s.type == "VECTOR"]
    op = {"op": "vector_math", "operation": node.operation,
          **{k: b.expression(s, stack, VEC) for k, s in zip("abc", vectors)},
          "scale": b.input(node, "Scale", stack, FLOAT)}
    return _out(op, Vector="Vector", Value="Value")


def _clamp(b, node, stack):
    op = {"op": "clamp", "clamp_type": node.clamp_type, "value": b.input(node, "Value", stack, FLOAT),
          "min": b.input(node, "Min", stack, FLOAT), "max": b.input(node, "Max", stack, FLOAT)}
    return {"Result": op}


def _curve_tables(mapping, curves, combined=None):
    """(table (RAMP_TABLE_SIZE, len(curves)), min_x, max_x, extrapolate) of a curve mapping, as
    Cycles bakes it (``curvemapping_color_to_array``): every curve sampled over the x range of all
    the mapping's curves it uses, through ``combined`` first if given (RGB Curves' C curve)."""
    mapping.initialize()
    mapping.update()
    used = list(curves) + ([combined] if combined is not None else [])
    lo = min(c.points[0].location[0] for c in used)
    hi = max(c.points[-1].location[0] for c in used)
    table = []
    for i in range(RAMP_TABLE_SIZE):
        t = lo + i / (RAMP_TABLE_SIZE - 1) * (hi - lo)
        x = mapping.evaluate(combined, t) if combined is not None else t
        table.append([mapping.evaluate(c, x) for c in curves])
    return table, lo, hi, mapping.extend == "EXTRAPOLATED"


def _component_curves(b, node, stack, socket, combined):
    """RGB Curves (``socket`` Color, its C curve ``combined`` first) or Vector Curves (Vector)."""
    mapping = node.mapping
    table, lo, hi, extrapolate = _curve_tables(mapping, mapping.curves[:3],
                                               mapping.curves[3] if combined else None)
    return {socket: {"op": "curves", "color": b.input(node, socket, stack, VEC),
                     "fac": b.input(node, "Fac", stack, FLOAT), "table": table, "min_x": lo, "max_x": hi,
                     "extrapolate": extrapolate}}


def _rgb_curves(b, node, stack):
    return _component_curves(b, node, stack, "Color", combined=True)


def _vector_curves(b, node, stack):
    return _component_curves(b, node, stack, "Vector", combined=False)


def _float_curve(b, node, stack):
    mapping = node.mapping
    table, lo, hi, extrapolate = _curve_tables(mapping, mapping.curves[:1])
    return {"Value": {"op": "float_curve", "value": b.input(node, "Value", stack, FLOAT),
                      "fac": b.input(node, "Factor", stack, FLOAT), "table": [row[0] for row in table],
                      "min_x": lo, "max_x": hi, "extrapolate": extrapolate}}


def _map_range(b, node, stack):
    """Map Range: the float one, or the vector one as the float one per component (Cycles'
    ``svm_map_range_vector``)."""
    names = {"value": "Value", "from_min": "From Min", "from_max": "From Max", "to_min": "To Min",
             "to_max": "To Max", "steps": "Steps"}
    settings = {"op": "map_range", "interpolation": node.interpolation_type, "clamp": bool(node.clamp)}
    if node.data_type == "FLOAT":
        return {"Result": {**settings, **{k: b.input(node, name, stack, FLOAT) for k, name in names.items()}}}
    vectors = {k: b.input(node, "Vector" if k == "value" else name.replace(" ", "_") + "_FLOAT3", stack, VEC)
               for k, name in names.items()}
    axes = [{**settings, **{k: _component(v, axis) for k, v in vectors.items()}} for axis in range(3)]
    return {"Vector": {"op": "combine", "x": axes[0], "y": axes[1], "z": axes[2]}}


def _component(v, axis):
    """Component ``axis`` of a vector: three numbers or a program."""
    if isinstance(v, dict):
        return {"op": "separate", "vector": v, "output": "XYZ"[axis]}
    return float(v[axis])


def _vector_rotate(b, node, stack):
    """Vector Rotate (Cycles' ``svm_node_vector_rotate``) as the affine op: about an axis (its own,
    or X, Y, Z) by an angle, or by Euler XYZ angles, around the Center, inverted or not.  The
    rotation is taken as a constant (its mean where a texture drives it, noted)."""
    from mathutils import Euler, Matrix
    inp = node.inputs
    vector = b.expression(inp["Vector"], stack, VEC)
    if node.rotation_type == "EULER_XYZ":
        m = np.array(Euler(b.constant_of(inp["Rotation"], stack, VEC), "XYZ").to_matrix(), np.float64)
        m = m.T if node.invert else m
    else:
        fixed = {"X_AXIS": (1.0, 0.0, 0.0), "Y_AXIS": (0.0, 1.0, 0.0), "Z_AXIS": (0.0, 0.0, 1.0)}
        axis = np.asarray(fixed.get(node.rotation_type) or b.constant_of(inp["Axis"], stack, VEC), np.float64)
        length = float(np.linalg.norm(axis))
        if length == 0.0:
            return {"Vector": vector}                   # (Cycles: no axis, no turn)
        angle = float(b.constant_of(inp["Angle"], stack, FLOAT))
        m = np.array(Matrix.Rotation(-angle if node.invert else angle, 3, axis / length), np.float64)
    center = b.expression(inp["Center"], stack, VEC)
    op = {"op": "affine", "vector": vector, "matrix": m.tolist()}
    if not isinstance(center, dict):
        return {"Vector": {**op, "pre": list(center), "post": list(center)}}
    op["vector"] = {"op": "vector_math", "operation": "SUBTRACT", "a": vector, "b": center}
    return {"Vector": {"op": "vector_math", "operation": "ADD", "a": op, "b": center}}


def _invert(b, node, stack):
    return {"Color": {"op": "invert", "fac": b.input(node, "Fac", stack, FLOAT),
                      "color": b.input(node, "Color", stack, VEC)}}


def _normal(b, node, stack):
    """Normal: its direction (the Normal output's own value, normalised as Cycles does) and Dot, that
    direction's dot product with the normalised input (Cycles' ``svm_node_normal``)."""
    direction = np.asarray(node.outputs["Normal"].default_value, np.float64)
    length = float(np.linalg.norm(direction))
    direction = (direction / length if length > 0.0 else direction).tolist()
    unit = {"op": "vector_math", "operation": "NORMALIZE", "a": b.input(node, "Normal", stack, VEC)}
    return {"Normal": direction,
            "Dot": {"op": "vector_math", "operation": "DOT_PRODUCT", "a": direction, "b": unit,
                    "output": "Value"}}


def _vector_transform(b, node, stack):
    """Vector Transform between world, object and camera space (core ``vector_transform``)."""
    return {"Vector": {"op": "vector_transform", "type": node.vector_type, "convert_from": node.convert_from,
                       "convert_to": node.convert_to, "vector": b.input(node, "Vector", stack, VEC)}}


def _wavelength(b, node, stack):
    return {"Color": {"op": "wavelength", "wavelength": b.input(node, "Wavelength", stack, FLOAT)}}


def _rgb_to_bw(b, node, stack):
    """RGB to BW: the colour's luminance (Cycles' ``linear_rgb_to_gray``, Rec. 709)."""
    return {"Val": {"op": "gray", "color": b.input(node, "Color", stack, VEC)}}


def _gamma(b, node, stack):
    return {"Color": {"op": "gamma", "color": b.input(node, "Color", stack, VEC),
                      "gamma": b.input(node, "Gamma", stack, FLOAT)}}


def _hsv(b, node, stack):
    return {"Color": {"op": "hsv", "color": b.input(node, "Color", stack, VEC),
                      "hue": b.input(node, "Hue", stack, FLOAT),
                      "saturation": b.input(node, "Saturation", stack, FLOAT),
                      "value": b.input(node, "Value", stack, FLOAT),
                      "fac": b.input(node, "Fac", stack, FLOAT)}}


def _bright_contrast(b, node, stack):
    return {"Color": {"op": "bright_contrast", "color": b.input(node, "Color", stack, VEC),
                      "bright": b.input(node, "Bright", stack, FLOAT),
                      "contrast": b.input(node, "Contrast", stack, FLOAT)}}


def _separate_xyz(b, node, stack):
    return _out({"op": "separate", "vector": b.input(node, "Vector", stack, VEC)}, X="X", Y="Y", Z="Z")


def _separate_color(b, node, stack):
    """Separate Color: RGB, or HSV or HSL (Cycles' ``rgb_to_hsv``, ``rgb_to_hsl``) in its three outputs."""
    color = b.input(node, "Color", stack, VEC)
    if node.mode != "RGB":
        color = {"op": "color_space", "conversion": f"RGB_TO_{node.mode}", "color": color}
    return _out({"op": "separate", "vector": color}, Red="Red", Green="Green", Blue="Blue")


def _combine_xyz(b, node, stack):
    return {"Vector": {"op": "combine", **{k: b.input(node, k.upper(), stack, FLOAT) for k in "xyz"}}}


def _combine_color(b, node, stack):
    """Combine Color: RGB, or from HSV or HSL (Cycles' ``hsv_to_rgb``, ``hsl_to_rgb``)."""
    color = {"op": "combine", **{k: b.input(node, name, stack, FLOAT)
                                 for k, name in zip("xyz", ("Red", "Green", "Blue"))}}
    if node.mode != "RGB":
        color = {"op": "color_space", "conversion": f"{node.mode}_TO_RGB", "color": color}
    return {"Color": color}


def _normal_input(b, node, stack):
    """The Normal input of a Fresnel, Layer Weight, Ambient Occlusion, Bevel or Bump node as
    ``normal`` ({} when unlinked: the shading normal), a Bump's or Normal Map's a program."""
    sock = node.inputs["Normal"]
    src, _, _ = b.walker.source(sock, stack)
    if src is None:
        return {}
    return {"normal": b.expression(sock, stack, VEC)}


def _normal_map(b, node, stack):
    """Normal Map: the bent normal as a program (``procedural._normal_map``) of any colour; in
    tangent space the tangents of the active render UV map (another map named here is noted)."""
    op = {"op": "normal_map", "color": b.input(node, "Color", stack, VEC),
          "strength": b.input(node, "Strength", stack, FLOAT), "space": node.space}
    if node.space == "TANGENT":
        op["tangent"] = {"op": "attribute", "name": "tangent_uv"}     # (the exporter sends tangents)
        if node.uv_map:
            b.walker.note(f"'{node.name}': takes the active render UV map's tangents, not "
                          f"'{node.uv_map}''s, as a program")
    return {"Normal": op}


def _particle_info(b, node, stack):
    """Particle Info: each object's particle (``mesh.particle_info``), read as an object property."""
    def value(output, vector=False):
        attr = {"op": "attribute", "name": f"object:{PARTICLE}{output}"}
        return attr if vector else {"op": "separate", "vector": attr, "output": "X"}
    return {"Index": value("index"), "Random": value("random"), "Age": value("age"),
            "Lifetime": value("lifetime"), "Location": value("location", True), "Size": value("size"),
            "Velocity": value("velocity", True), "Angular Velocity": value("angular_velocity", True)}


def _bump(b, node, stack):
    """Bump: the bent normal as a program (``procedural._bump``); Invert negates the Distance, and
    the Filter Width (Cycles' footprint of its differences) has no equivalent here."""
    normal = _normal_input(b, node, stack)
    height, _, _ = b.walker.source(node.inputs["Height"], stack)
    if height is None:
        # (no slope: Cycles folds the node into its Normal input, the shading normal unlinked)
        return {"Normal": normal.get("normal", {"op": "attribute", "name": "world_normal"})}
    distance = b.input(node, "Distance", stack, FLOAT)
    if node.invert:
        distance = {"op": "math", "operation": "MULTIPLY", "a": distance, "b": -1.0}
    return {"Normal": {"op": "bump", "height": b.input(node, "Height", stack, FLOAT),
                       "strength": b.input(node, "Strength", stack, FLOAT), "distance": distance, **normal}}


def _fresnel(b, node, stack):
    """Fresnel: Cycles' dielectric Fresnel of the IOR at the view cosine (``procedural.RAY``)."""
    return {"Fac": {"op": "fresnel", "ior": b.input(node, "IOR", stack, FLOAT),
                    **_normal_input(b, node, stack)}}


def layer_weight_ior(blend):
    """The IOR of Layer Weight's Fresnel output for its ``blend``: 1 / (1 - Blend), as Cycles."""
    return 1.0 / max(1.0 - blend, 1e-5)


def _layer_weight(b, node, stack):
    """Layer Weight: Fresnel (of IOR 1 / (1 - Blend)) and Facing, as Cycles'
    ``svm_node_layer_weight`` at the view direction (``procedural.RAY``)."""
    op = {"op": "layer_weight", "blend": b.input(node, "Blend", stack, FLOAT),
          **_normal_input(b, node, stack)}
    return _out(op, Fresnel="Fresnel", Facing="Facing")


NODES = {
    "ShaderNodeTexCoord": _tex_coord, "ShaderNodeUVMap": _uv_map, "ShaderNodeVertexColor": _color_attribute,
    "ShaderNodeObjectInfo": _object_info, "ShaderNodeNewGeometry": _geometry, "ShaderNodeTangent": _tangent,
    "ShaderNodePointInfo": _point_info, "ShaderNodeHairInfo": _hair_info,
    "ShaderNodeAttribute": _attribute,
    "ShaderNodeRGB": _rgb, "ShaderNodeBlackbody": _blackbody,
    "ShaderNodeValue": _value, "ShaderNodeMapping": _mapping, "ShaderNodeTexImage": _image,
    "ShaderNodeTexEnvironment": _environment, "ShaderNodeTexSky": _sky,
    "ShaderNodeTexChecker": _checker, "ShaderNodeTexGradient": _gradient, "ShaderNodeTexNoise": _noise,
    "ShaderNodeTexVoronoi": _voronoi, "ShaderNodeTexWave": _wave, "ShaderNodeTexBrick": _brick,
    "ShaderNodeTexMagic": _magic, "ShaderNodeTexWhiteNoise": _white_noise, "ShaderNodeTexGabor": _gabor,
    "ShaderNodeValToRGB": _ramp,
    "ShaderNodeMix": _mix,
    "ShaderNodeMixRGB": _mix_rgb, "ShaderNodeMath": _math, "ShaderNodeMapRange": _map_range,
    "ShaderNodeInvert": _invert, "ShaderNodeGamma": _gamma, "ShaderNodeHueSaturation": _hsv,
    "ShaderNodeRGBToBW": _rgb_to_bw, "ShaderNodeVectorRotate": _vector_rotate,
    "ShaderNodeNormal": _normal, "ShaderNodeVectorTransform": _vector_transform,
    "ShaderNodeWavelength": _wavelength,
    "ShaderNodeBrightContrast": _bright_contrast,
    "ShaderNodeSeparateXYZ": _separate_xyz, "ShaderNodeSeparateColor": _separate_color,
    "ShaderNodeCombineXYZ": _combine_xyz, "ShaderNodeCombineColor": _combine_color,
    "ShaderNodeVectorMath": _vector_math, "ShaderNodeClamp": _clamp, "ShaderNodeRGBCurve": _rgb_curves,
    "ShaderNodeVectorCurve": _vector_curves, "ShaderNodeFloatCurve": _float_curve,
    "ShaderNodeFresnel": _fresnel, "ShaderNodeLayerWeight": _layer_weight,
    "ShaderNodeCameraData": _camera_data, "ShaderNodeWireframe": _wireframe,
    "ShaderNodeAmbientOcclusion": _ambient_occlusion, "ShaderNodeBevel": _bevel,
    "ShaderNodeLightPath": _light_path, "ShaderNodeBump": _bump, "ShaderNodeNormalMap": _normal_map,
    "ShaderNodeParticleInfo": _particle_info,
}

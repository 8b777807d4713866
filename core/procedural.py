"""Procedural colour programs: Blender's texture and colour nodes, evaluated at surface hits.

A material's diffuse colour, the colour of its glossy lobe without a Fresnel rise, or the factor
of its emission may be a *program*: a tree of nodes as plain JSON-able dicts, which the exporter
builds from the material's node graph and this module evaluates, vectorised over all hits of the
material at once; a world's colour may be one of the direction, which the exporter bakes into an
image.
A node is ``{"op": name, ...}``; its inputs are numbers (float sockets), lists of three numbers
(colour and vector sockets) or nodes, and a node input picks one of the node's outputs with
``"output"`` (default: the op's first).  Inputs are typed as in Blender: the exporter inserts
the conversions (``gray``, ``average``, ``splat``) where a link joins sockets of different types,
as Cycles does.

Ops, their inputs and outputs (what Cycles' SVM nodes compute, ``intern/cycles/kernel/svm``):

* ``attribute`` name = generated | object | uv | color | normal | position | world_normal |
  true_normal | incoming | backfacing | light_path | parametric | edge_distance | tangent_x |
  tangent_y | tangent_z | tangent_uv (and Object Info's, ``OBJECT_INFO``): -> Vector (light_path:
  the Light Path's outputs, ``LIGHT_PATH``). Blender's Generated and Object coordinates (the hit in
  its object's space, ``Scene.object_from_world``, and that object's texture space mapped to
  [0, 1]^3, ``Scene.texture_spaces``), and the per-corner ``Scene.uvs`` as (u, v, 0) and
  ``Scene.vertex_colors``, interpolated; the Geometry node's Position, Normal and True Normal in
  world space (``GEOMETRY``), Incoming and Backfacing (``RAY``), Parametric and the edges' distances
  (``TRIANGLE``), tangents (``TANGENTS``); the Texture Coordinate's Camera and Window (``VIEW``);
  ``named:`` + a name, ``Scene.attributes[name]`` interpolated (``NAMED``); ``object:`` or
  ``instancer:`` + an RNA path, ``Scene.object_attributes`` (``OBJECT_PROPERTY``).
* ``affine`` vector, matrix (3 x 3), pre, post (3), normalize: -> Vector = M (v - pre) + post
  (the Mapping node, its four types folded into M by the exporter).
* ``checker`` vector, color1, color2, scale: -> Color, Fac (``checker.h``).
* ``gradient`` vector, gradient_type: -> Color, Fac (``gradient.h``).
* ``noise`` vector and the Noise Texture's settings: -> Fac, Color (``core/noise.py``).
* ``voronoi`` vector and the Voronoi Texture's settings: -> Distance, Color, Position, W, Radius
  (``core/voronoi.py``).
* ``wave``, ``brick``, ``magic`` vector and the node's settings: -> Color, Fac; ``white_noise``
  vector, dimensions, w: -> Value, Color (``core/pattern_textures.py``).
* ``image`` texture (index into the scene's images), vector, extension (REPEAT, EXTEND, CLIP,
  MIRROR), interpolation (Linear, Closest), projection (FLAT; SPHERE, TUBE: Cycles' maps of the
  vector (2 vector - 1) about the origin; BOX: three flat lookups weighted
  by the object-space normal, :func:`box_weights`), blend: -> Color, Alpha = 1
  (:func:`image_lookup`).
* ``environment`` texture, vector (a direction): -> Color (equirectangular), Alpha = 1.
* ``sky`` vector (a direction) and the Sky Texture's settings: -> Color, the sky without its sun
  disc (``core/sky.py``; the world export adds the disc as a sun light).
* ``ramp`` fac, table (N x 4 RGBA, Blender's colour band sampled at i / (N - 1)), interpolate:
  -> Color, Alpha (``ramp_util.h``'s table lookup; the exporter samples the band with Blender).
* ``mix_color`` blend, fac, a, b, clamp_factor, clamp_result: -> Result (``color_util.h``).
* ``mix_float`` / ``mix_vector`` fac, a, b, clamp_factor: -> Result.
* ``math`` operation, a, b, c, clamp: -> Value (``math_util.h``, every operation).
* ``vector_math`` operation, a, b, c, scale: -> Vector, Value (``svm_vector_math``).
* ``clamp`` clamp_type (MINMAX, RANGE), value, min, max: -> Result.
* ``curves`` color, fac, table (N x 3: each component's curve sampled over [min_x, max_x]),
  min_x, max_x, extrapolate: -> Color (RGB Curves, its combined curve folded into the table,
  and Vector Curves; ``svm_node_curves``); ``float_curve`` value, fac, table (N), min_x, max_x,
  extrapolate: -> Value (Float Curve).  The exporter samples the curves with Blender.
* ``map_range`` interpolation, value, from_min, from_max, to_min, to_max, steps, clamp: -> Result.
* ``metal`` color, tint: -> Color, a metal's mean F82-tint Fresnel reflectance (its glossy colour).
* ``invert`` fac, color; ``gamma`` color, gamma; ``bright_contrast`` color, bright, contrast;
  ``hsv`` color, hue, saturation, value, fac (``hsv.h``): -> Color.
* ``wavelength`` wavelength (nm): -> Color (Cycles' Wavelength node).
* ``ao`` color, distance, normal, samples, inside, only_local: -> Color, AO (Cycles' Ambient
  Occlusion, ``HitAttributes.occlusion``).
* ``bevel`` radius, samples, normal: -> Normal (Cycles' Bevel, ``HitAttributes.bevel``).
* ``light_path``: -> the Light Path node's outputs (``LIGHT_PATH``) of the rays that meet the hits.
* ``fresnel`` ior, normal: -> Fac; ``layer_weight`` blend, normal: -> Fresnel, Facing (Cycles'
  Fresnel and Layer Weight nodes at the ray's Incoming, ``RAY``; normal: the shading normal on the
  ray's side unless given).
* ``vector_transform`` vector, type, convert_from, convert_to (Vector Transform): -> Vector.
* ``color_space`` color, conversion (RGB_TO_HSV, HSV_TO_RGB, RGB_TO_HSL, HSL_TO_RGB; Separate and
  Combine Color in HSV and HSL mode): -> Color.
* ``separate`` vector: -> X, Y, Z (also Red, Green, Blue); ``combine`` x, y, z: -> Vector.
* ``blackbody`` temperature: -> Color (Cycles' fit of the Planckian locus, luminance 1);
  ``unpremultiply`` color, alpha: -> Color (colour / alpha where 0 < alpha < 1: an image's straight
  colour after filtering it premultiplied, as Cycles).
* ``gray`` color: -> Value (Rec. 709 luminance, Cycles' colour-to-float); ``average`` vector:
  -> Value (vector-to-float); ``splat`` value: -> Vector (float-to-colour/vector).

Everything runs in float64 where Cycles uses float32.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from . import noise as _noise_module
from . import pattern_textures as _patterns
from . import sky as _sky_module
from . import voronoi as _voronoi_module
from .accel import interpolate_corners
from .bsdf import bilinear, metal_fresnel
from .environment import equirectangular_uv
from .sampling import (affine_inverse, cosine_hemisphere, dot, fresnel_dielectric, inverse, length, normalize,
                       orthonormal_frames, to_world)
from .texture_hash import float_to_int, hash_uint3, hash_uint3_to_float

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])      # Rec. 709: Cycles' colour-to-float conversion
# A bump's finite-difference step, times the object's size (``RenderContext._apply_bump_maps``, ``_bump``;
# ``Accel.object_sizes``).
BUMP_STEP = 1e-5
# Hits a program is evaluated on at once (``evaluate``): a world's bake of a Noise Texture's Color
# of detail 15 (524,288 directions) took 8.26 s in chunks of 65,536 against 15.41 s all at once, of
# detail 2 0.53 against 0.90 s (benchmarks/eval_chunk.py; chunks of 16,384 about the same).
EVAL_CHUNK = 1 << 16
ATTRIBUTES = ("generated", "object", "uv", "color", "normal", "object_location", "object_color",
              "object_info", "position", "world_normal", "true_normal", "camera", "window", "incoming",
              "backfacing", "light_path", "parametric", "edge_distance", "pixel_width", "tangent_x",
              "tangent_y", "tangent_z", "tangent_uv")
# Blender's Geometry node: "position" the hit's world position, "world_normal" the world-space
# shading normal (interpolated where the mesh is smooth), "true_normal" the facet's; both normals
# turned towards the ray on a back face, as Cycles turns them (``RAY``).
GEOMETRY = ("position", "world_normal", "true_normal")
# The ray that meets the hit (``Rays.incoming``): "incoming" the unit direction back along it
# (Cycles' I: towards the eye, or towards the light a photon left), "backfacing" (b, b, b) with
# b = 1 where it meets the triangle's back, "light_path" its Light Path node's outputs
# (``LIGHT_PATH``).  Where the caller gives no rays, each hit is seen head-on from its front
# (Incoming the front's normal) by a camera ray.
RAY = ("incoming", "backfacing", "light_path")
# The Light Path node's outputs, in the order of ``Rays.path``'s columns.
LIGHT_PATH = ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray", "Is Singular Ray",
              "Is Reflection Ray", "Is Transmission Ray", "Is Volume Scatter Ray", "Ray Length", "Ray Depth",
              "Diffuse Depth", "Glossy Depth", "Transparent Depth", "Transmission Depth", "Portal Depth")
CAMERA_PATH = np.array([1.0] + [0.0] * (len(LIGHT_PATH) - 1))      # a camera ray (of length 0)
# The hit within its triangle: "parametric" (b0, b1, 0), the weights of its first two corners
# (Geometry's Parametric: Cycles' (1 - u - v, u, 0)), "edge_distance" the distances in world
# units to the lines through its three edges (of corners 2 and 0, 0 and 1, 1 and 2: Cycles'
# Wireframe compares them with half its Size), "pixel_width" (w, w, w) with w the width of the
# camera's pixel there (Wireframe's Pixel Size, ``HitAttributes._pixel_width``).
TRIANGLE = ("parametric", "edge_distance", "pixel_width")
# Tangents at the hits, perpendicular to the shading normal (Blender's Tangent node, Cycles'
# ``svm_node_tangent``): "tangent_x", "tangent_y", "tangent_z" the radial direction about the
# object's X, Y or Z axis through the centre of its texture space (from the Generated coordinates;
# "tangent_z" is also Geometry's Tangent, Cycles' ``primitive_tangent``), "tangent_uv" the active
# render UV map's (``Scene.tangents``; 0 without them, as Cycles without the map).
TANGENTS = ("tangent_x", "tangent_y", "tangent_z", "tangent_uv")
# Most hits on its own object a Bevel ray counts (Cycles' LOCAL_MAX_HITS).
LOCAL_HITS = 4
# Texture Coordinate's Camera (the hit in the camera's space, Cycles' axes: x right, y up, z the
# depth in front) and Window (where the hit lands in the frame, (0, 0) at its bottom left, z = 0;
# perspective and orthographic cameras, 0 for panoramic ones).
VIEW = ("camera", "window")
# An attribute named NAMED + a mesh attribute's name reads ``Scene.attributes[name]`` per corner
# (Blender's Attribute node, a Color Attribute or UV Map node naming a layer); 0 where the scene
# has no such attribute (Cycles: a missing attribute reads 0).
NAMED = "named:"
# An attribute named OBJECT_PROPERTY[k] + an RNA path reads ``Scene.object_attributes`` of the hit's
# object (Blender's Attribute node of the Object type: the object's property or custom property,
# else its data's; Instancer: the instancer's first), 0 where the scene has none.
OBJECT_PROPERTY = ("object:", "instancer:")


def reads_objects(names) -> bool:
    """Whether attributes ``names`` (``attributes_used``) need the scene's objects."""
    radial = TANGENTS[:3]                           # (from the Generated coordinates)
    return any(n in ("object", "generated", "normal", *OBJECT_INFO, *radial) or n.startswith(OBJECT_PROPERTY)
               for n in names)
# Blender's Object Info per object (``Scene.object_info``): "object_location" the object's origin
# in world space, "object_color" its colour, "object_info" (Alpha, Object Index, Random).
OBJECT_INFO = ("object_location", "object_color", "object_info")
# Largest albedo a program may give: above 1 a surface adds light (Cycles allows it, and a Mix
# Shader mask divided by its mean weight may exceed 1), but a program gone wild (a power, a
# division by ~0) must not overflow the photons' flux over many bounces.
COLOR_MAX = 100.0
# Largest factor an emission program may give (emission is not multiplied along a path, and a
# sky or a lamp in an HDR image may be thousands of times its mean; inf stays finite).
EMISSION_MAX = 1e30


class ProgramError(ValueError):
    """A malformed program (unknown op, missing input, bad texture index)."""


def radial_tangents(centred, axis, object_from_world=None):
    """(k, 3) Cycles' radial tangent directions (``svm_node_tangent``) about the object's X, Y or Z
    axis (``axis`` (k,) 0, 1 or 2) of points ``centred`` (k, 3) (Generated coordinates minus 0.5),
    taken to world space as a normal is (A^T t, A the (k, 3, >= 3) ``object_from_world`` matrices;
    None: left as they are)."""
    x, y, z = centred[:, 0], centred[:, 1], centred[:, 2]
    zero = np.zeros(len(centred))
    a = np.asarray(axis)[:, None]
    t = np.where(a == 0, np.stack([zero, -z, y], axis=1),
                 np.where(a == 1, np.stack([-z, zero, x], axis=1), np.stack([-y, x, zero], axis=1)))
    if object_from_world is not None:
        t = np.einsum("kji,kj->ki", np.asarray(object_from_world)[:, :, :3], t)
    return t


def perpendicular_tangents(raw, normals):
    """(k, 3) unit tangents ``raw`` (k, 3) made perpendicular to the unit ``normals`` (k, 3), as
    Cycles' cross(N, normalize(cross(T, N))); 0 where ``raw`` is 0 or along the normal."""
    across = np.cross(raw, normals)
    length = np.sqrt(dot(across, across))
    return np.cross(normals, across / np.where(length > 0, length, 1.0)[:, None])


def camera_path(camera, reflected, lengths, depth, glossy_depth, transmission_depth):
    """(k, len(LIGHT_PATH)) the light path of camera paths' rays (``Rays.path``), as Cycles flags
    them: where ``camera`` (k,) a camera ray, else one after mirror or glass bounces, a singular
    glossy ray, a reflection where ``reflected`` (k,), else a transmission; ``lengths`` (k,) this
    segment's, ``depth`` the bounces so far, ``glossy_depth`` and ``transmission_depth`` (k,) the
    mirror and glass ones among them."""
    path = np.zeros((len(lengths), len(LIGHT_PATH)))
    column = LIGHT_PATH.index
    camera = np.asarray(camera, bool)
    path[:, column("Is Camera Ray")] = camera
    path[:, column("Is Glossy Ray")] = path[:, column("Is Singular Ray")] = ~camera
    path[:, column("Is Reflection Ray")] = ~camera & reflected
    path[:, column("Is Transmission Ray")] = ~camera & ~np.asarray(reflected, bool)
    path[:, column("Ray Length")] = lengths
    path[:, column("Ray Depth")] = depth
    path[:, column("Glossy Depth")] = glossy_depth
    path[:, column("Transmission Depth")] = transmission_depth
    return path


def photon_path(lengths):
    """(k, len(LIGHT_PATH)) the light path of photons' hits (``Rays.path``) of segments ``lengths``
    (k,): Cycles sees such a hit from the camera path's side, which a photon does not know; here as
    from a first diffuse bounce off a measurement point (Is Diffuse Ray and Is Reflection Ray, Ray
    Depth and Diffuse Depth 1), its Ray Length the photon's own segment."""
    path = np.zeros((len(lengths), len(LIGHT_PATH)))
    for name in ("Is Diffuse Ray", "Is Reflection Ray", "Ray Depth", "Diffuse Depth"):
        path[:, LIGHT_PATH.index(name)] = 1.0
    path[:, LIGHT_PATH.index("Ray Length")] = lengths
    return path


@dataclass(frozen=True)
class Rays:
    """The rays that meet k hits, as programs see them: ``incoming`` (k, 3) unit directions back
    along them; ``sharp`` whether they are the camera's or followed a mirror or glass from it (a
    Bevel bends only those, ``HitAttributes.bevel``); ``path`` (k, len(LIGHT_PATH)) their Light
    Path outputs, or None for camera rays (``CAMERA_PATH``)."""
    incoming: np.ndarray
    sharp: bool = False
    path: np.ndarray = None

    def take(self, rows) -> "Rays":
        return Rays(self.incoming.take(rows, axis=0), self.sharp,
                    None if self.path is None else self.path.take(rows, axis=0))


class HitAttributes:
    """Texture coordinates of k hits, computed when a program first asks for them.

    scene : the ``Scene`` (its uvs, vertex colours and objects); prim_ids : (k,) triangle ids;
    bary : (b0, b1, b2), (k, 1) each; positions : (k, 3) float64 world positions of the hits;
    rays : the ``Rays`` that meet them (``RAY``), or None; accel : the scene's ``Accel``, for
    Ambient Occlusion's and Bevel's rays (:meth:`occlusion`, :meth:`bevel`), or None."""

    def __init__(self, scene, prim_ids, bary, positions, rays=None, accel=None):
        self.scene, self.prim_ids, self.bary, self.positions = scene, prim_ids, bary, positions
        self.rays, self.accel = rays, accel
        self._cache = {}

    def rows(self, start, stop) -> "HitAttributes":
        """The hits ``start:stop`` (a fresh one: attributes are computed again as asked for)."""
        rays = None if self.rays is None else self.rays.take(np.arange(start, stop))
        return HitAttributes(self.scene, self.prim_ids[start:stop], tuple(b[start:stop] for b in self.bary),
                             self.positions[start:stop], rays, self.accel)

    @property
    def incoming(self):
        """(k, 3) the rays' directions back (``Rays.incoming``), or None without rays."""
        return None if self.rays is None else self.rays.incoming

    @property
    def sharp(self) -> bool:
        """Whether the rays are sharp (``Rays.sharp``): a Bevel bends only those."""
        return self.rays is not None and self.rays.sharp

    @property
    def count(self) -> int:
        return len(self.prim_ids)

    def get(self, name):
        if name not in self._cache:
            if name == "normal":
                value = self._normal()
            elif name in GEOMETRY:
                value = self._geometry(name)
            elif name in RAY:
                value = self._ray(name)
            elif name in TRIANGLE:
                value = self._triangle(name)
            elif name in TANGENTS:
                value = self._tangent(name)
            elif name in VIEW:
                value = self._view(name)
            elif name in ("object", "generated"):
                value = self._object(name)
            elif name in OBJECT_INFO:
                value = self._object_info(name)
            elif name.startswith(NAMED):
                value = self._named(name[len(NAMED):])
            elif name.startswith(OBJECT_PROPERTY):
                value = self._object_property(name)
            else:
                value = self._corners(name)
            self._cache[name] = value
        return self._cache[name]

    def _normal(self):
        """The object-space normal (Cycles' Texture Coordinate Normal, and a box projection's): the
        interpolated shading normal (the facet's without one) through the inverse transpose of
        the object's transform; on the ray's side, as the Geometry node's (``GEOMETRY``)."""
        s = self.scene
        if s.object_ids is None:
            raise ProgramError("the program needs 'normal' coordinates, which the scene lacks")
        n = self.get("world_normal")
        objects, which = np.unique(s.object_ids.take(self.prim_ids), return_inverse=True)
        world_from_object = inverse(s.object_from_world.take(objects, axis=0)[:, :, :3])
        n = np.einsum("kji,kj->ki", world_from_object.take(which, axis=0), n)      # W^T n
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.divide(n, length, out=np.zeros_like(n), where=length > 0)

    def _geometry(self, name):
        """(k, 3) world position, shading normal or facet normal of the hits (``GEOMETRY``), the
        normals on the ray's side."""
        if name == "position":
            return np.asarray(self.positions, np.float64)
        n = self._front(name)
        if self.incoming is None:
            return n
        return n * self._side()[:, None]

    def _side(self):
        """(k,) -1 where the ray meets the back of the triangle, else 1 (1 without rays)."""
        if "side" not in self._cache:
            side = np.ones(self.count)
            if self.incoming is not None:
                side[dot(np.asarray(self.incoming, np.float64), self._front("true_normal")) < 0.0] = -1.0
            self._cache["side"] = side
        return self._cache["side"]

    def _ray(self, name):
        """(k, 3) Incoming or Backfacing, or (k, len(LIGHT_PATH)) the light path of the hits (``RAY``)."""
        if name == "light_path":
            if self.rays is None or self.rays.path is None:
                return np.tile(CAMERA_PATH, (self.count, 1))
            return np.asarray(self.rays.path, np.float64)
        if name == "incoming":
            if self.incoming is None:
                return self._front("world_normal")
            return np.asarray(self.incoming, np.float64)
        return np.repeat((self._side() < 0.0).astype(np.float64)[:, None], 3, axis=1)

    def occlusion(self, normals, distance, samples, only_local=False):
        """(k,) Cycles' Ambient Occlusion (``svm_ao``) at the hits: the share of ``samples`` rays
        about the unit ``normals`` (k, 3), cosine-distributed, that meet nothing (with
        ``only_local``: nothing of the hit's own object) within ``distance`` ((k,)); 1 where the
        distance is not positive, and everywhere without an ``accel`` (Cycles without a BVH).
        The rays' numbers hash the hit's position and the ray's index, so that the same hit gives
        the same value (a photon path stays a function of its primary sample) and hits apart
        draw anew; the first of each pair is stratified over the rays."""
        k = self.count
        distance = np.broadcast_to(np.asarray(distance, np.float64), (k,))
        rows = np.flatnonzero(distance > 0.0)
        out = np.ones(k)
        if self.accel is None or samples < 1 or len(rows) == 0:
            return out
        p = np.asarray(self.positions, np.float64).take(rows, axis=0)
        key = _position_keys(p)
        n = np.asarray(normals, np.float64).take(rows, axis=0)
        ng = self._front("true_normal").take(rows, axis=0)
        objects = None
        prims = self.prim_ids.take(rows)
        if only_local and self.scene.object_ids is not None:
            objects = self.scene.object_ids.take(prims)
        free = np.zeros(len(rows))
        for j in range(samples):
            u1, u2 = (hash_uint3_to_float(key, np.uint32(j), np.uint32(axis)) for axis in (0, 1))
            u1 = np.minimum((j + u1) / samples, 1.0)  # (stratified, as Cycles' numbers are)
            d = to_world(cosine_hemisphere(u1, u2), n)
            spawn = self.accel.spawn if objects is None else self.accel.spawn_local
            free += ~self._blocked(spawn(p, ng, d, prims), d, distance.take(rows), objects)
        out[rows] = free / samples
        return out

    def bevel(self, radius, samples):
        """(k, 3) Cycles' Bevel normal (``svm_bevel``): ``samples`` rays, each along one of the
        facet's three axes (the normal's with probability 1/2) through a point of the disk about
        the hit drawn by the cubic falloff of ``radius`` ((k,)), meet the hit's own object at up to
        LOCAL_HITS points, whose smooth normals add up weighted by the three axes' power heuristic
        and the falloff at their true distance over the drawn one; on the ray's side.  The shading
        normal where the radius is not positive, nothing was met, the rays are not ``sharp`` (Cycles
        bevels no blurry indirect ray) or there is no ``accel`` or no objects.  The numbers hash the
        hit's position, as :meth:`occlusion`'s."""
        s = self.scene
        out = self.get("world_normal").copy()
        radius = np.broadcast_to(np.asarray(radius, np.float64), (self.count,))
        rows = np.flatnonzero(radius > 0.0)
        if self.accel is None or not self.sharp or samples < 1 or len(rows) == 0 or s.object_ids is None:
            return out
        p = np.asarray(self.positions, np.float64).take(rows, axis=0)
        r_max = radius.take(rows)[:, None]
        key = _position_keys(p)
        ng = self._front("true_normal").take(rows, axis=0)
        tangent, bitangent = orthonormal_frames(ng)
        objects = s.object_ids.take(self.prim_ids.take(rows))
        total = np.zeros((len(rows), 3))
        axes, chances = (ng, tangent, bitangent), (0.5, 0.25, 0.25)
        for j in range(samples):
            u, v = (hash_uint3_to_float(key, np.uint32(j), np.uint32(axis)) for axis in (2, 3))
            u = np.minimum((j + u) / samples, 1.0)  # (stratified, as Cycles' numbers are)
            # The axis: the normal (chance 1/2, u < 1/2), else the tangent or the bitangent (1/4 each).
            which = np.where(u < 0.5, 0, np.where(u < 0.75, 1, 2))[:, None]
            disk_n = np.where(which == 0, ng, np.where(which == 1, tangent, bitangent))
            disk_t = np.where(which == 1, ng, tangent)
            disk_b = np.where(which == 2, ng, bitangent)
            u = np.where(u < 0.5, 2.0 * u, np.where(u < 0.75, (u - 0.5) * 4.0, (u - 0.75) * 4.0))[:, None]
            disk_r = r_max * _cubic_falloff_root(v)[:, None]
            height = np.sqrt(np.maximum(r_max * r_max - disk_r * disk_r, 0.0))
            phi = 2.0 * np.pi * u
            start = p + disk_n * height + disk_r * (np.cos(phi) * disk_t + np.sin(phi) * disk_b)
            for row, prim, at, b1, b2 in self._local_hits(start, -disk_n, 2.0 * height[:, 0], objects):
                hit_ng = self.accel.geometric_normals.take(prim, axis=0)
                pdf = [pk * np.abs(dot(a.take(row, axis=0), hit_ng))[:, None] for pk, a in zip(chances, axes)]
                chosen = np.choose(which.take(row, axis=0), pdf)
                w = chosen / (pdf[0] ** 2 + pdf[1] ** 2 + pdf[2] ** 2)
                r = length(at - p.take(row, axis=0))[:, None]
                falloff = np.maximum(r_max.take(row, axis=0) - r, 0.0) / np.maximum(
                    r_max.take(row, axis=0) - disk_r.take(row, axis=0), 1e-300)
                # The smooth normal there (the facet's where it is 0, as Cycles').
                smooth = HitAttributes(s, prim, ((1.0 - b1 - b2)[:, None], b1[:, None], b2[:, None]),
                                       at)._front("world_normal")
                normal = np.where((length(smooth) > 0.0)[:, None], smooth, hit_ng)
                np.add.at(total, row, w * falloff ** 3 * normal)
        n = normalize(total)
        found = length(n) > 0.0
        out[rows[found]] = n[found] * self._side().take(rows[found])[:, None]
        return out

    def _local_hits(self, origins, dirs, tmax, objects):
        """For the hits along rays ``origins + t dirs`` (0 < t < ``tmax``) on each ray's object
        (``objects`` (n,); ``Accel.local_scene``), up to LOCAL_HITS per ray, nearest first: (ray
        rows, triangle ids, world points, b1, b2), one such per round."""
        accel, local = self.accel, self.accel.local_scene()
        rows = np.arange(len(origins))
        o, d, left = origins, dirs, np.broadcast_to(np.asarray(tmax, np.float64), (len(origins),))
        for _ in range(LOCAL_HITS):
            hits = local.intersect(o, d, np.maximum(left, 0.0), objects.take(rows))
            h = np.flatnonzero(hits.is_hit)
            if len(h) == 0:
                break
            prim = hits.prim_ids.take(h)
            b1, b2 = hits.b1.take(h), hits.b2.take(h)
            at = accel.hit_positions(prim, b1, b2)
            yield rows.take(h), prim, at, b1, b2
            d = d.take(h, axis=0)
            o = accel.spawn_local(at, accel.geometric_normals.take(prim, axis=0), d, prim)
            rows, left = rows.take(h), left.take(h) - hits.t.take(h).astype(np.float64)

    def _blocked(self, origins, dirs, tmax, objects):
        """(n,) whether rays ``origins + t dirs`` meet a triangle within ``tmax`` (of each ray's
        object alone with ``objects`` (n,): ``Accel.local_scene``)."""
        if objects is None:
            return self.accel.intersect(origins, dirs, tmax).is_hit
        return self.accel.local_scene().intersect(origins, dirs, tmax, objects).is_hit

    def _tangent(self, name):
        """(k, 3) a tangent of the hits (``TANGENTS``), made perpendicular to the shading normal."""
        s = self.scene
        if name == "tangent_uv":
            if s.tangents is None:
                return np.zeros((self.count, 3))
            corners = s.tangents.take(self.prim_ids, axis=0).astype(np.float64)
            raw = interpolate_corners(corners, self.bary)[:, :3]
        else:
            axis = np.full(self.count, TANGENTS.index(name))
            if s.object_ids is None:
                # (Cycles without Generated coordinates: the position)
                raw = radial_tangents(np.asarray(self.positions, np.float64) - 0.5, axis)
            else:
                raw = radial_tangents(self.get("generated") - 0.5, axis,
                                      s.object_from_world.take(s.object_ids.take(self.prim_ids), axis=0))
        return perpendicular_tangents(raw, self._front("world_normal"))

    def _triangle(self, name):
        """(k, 3) Parametric or the edge distances of the hits (``TRIANGLE``)."""
        if name == "parametric":
            b0, b1 = (np.asarray(w, np.float64).reshape(-1) for w in self.bary[:2])
            return np.stack([b0, b1, np.zeros_like(b0)], axis=1)
        if name == "pixel_width":
            return np.repeat(self._pixel_width()[:, None], 3, axis=1)
        s = self.scene
        c = s.vertices.take(s.triangles.take(self.prim_ids, axis=0), axis=0).astype(np.float64)
        p = np.asarray(self.positions, np.float64)
        out = np.zeros((self.count, 3))
        for i in range(3):
            edge = c[:, i] - c[:, i - 1]
            across = np.cross(edge, p - c[:, i])
            span = np.maximum(dot(edge, edge), 1e-300)
            out[:, i] = np.sqrt(dot(across, across) / span)
        return out

    def _pixel_width(self):
        """(k,) the width of the camera's pixel at the hits, as Cycles' Wireframe with Pixel Size
        measures it for a camera ray: the ray differential's compact size d (a perspective camera:
        the distance t times the spread of the normalised direction over a pixel, pw n_z
        (sqrt(1 - n_x^2) + sqrt(1 - n_y^2)) / 2 for the unit direction n in the camera's space and
        the frame's pixel width pw; orthographic: pw) laid along Cycles' two tangents of the facet
        (``make_orthonormals``) and projected across the view, d (|a_perp| + |b_perp|) / 2.  Every
        hit takes the camera's view of it: exact for camera rays, what the camera's pixel covers
        for photons and for paths past a mirror or glass.  Panoramic cameras: the spread 2 pi / the
        width in pixels."""
        cam = self.scene.camera
        w = cam.resolution[0]
        pw = (cam.frame[1] - cam.frame[0]) / w
        c = self.get("camera")
        t = np.linalg.norm(c, axis=1)
        n = c / np.maximum(t, 1e-300)[:, None]
        m = np.asarray(cam.world_from_camera, np.float64)
        if cam.projection == "orthographic":
            d = np.full(self.count, pw * np.linalg.norm(m[:3, 0]))
            view = np.broadcast_to(m[:3, 2] / np.linalg.norm(m[:3, 2]), (self.count, 3))
        else:
            spread = (pw * n[:, 2] * (np.sqrt(np.maximum(1.0 - n[:, 0] ** 2, 0.0))
                                      + np.sqrt(np.maximum(1.0 - n[:, 1] ** 2, 0.0))) / 2
                      if cam.projection == "perspective" else np.full(self.count, 2.0 * np.pi / w))
            d = t * spread
            view = normalize(m[:3, 3] - np.asarray(self.positions, np.float64))
        a, b = _cycles_orthonormals(self._front("true_normal"))
        across = [np.sqrt(np.maximum(1.0 - dot(x, view) ** 2, 0.0)) for x in (a, b)]
        return d * (across[0] + across[1]) / 2

    def _front(self, name):
        """(k, 3) the shading ("world_normal") or facet ("true_normal") unit normal on the
        triangle's front."""
        key = "front:" + name
        if key in self._cache:
            return self._cache[key]
        s = self.scene
        if name == "world_normal" and s.shading_normals is not None:
            corners = s.shading_normals.take(self.prim_ids, axis=0).astype(np.float64)
            n = interpolate_corners(corners, self.bary)
        else:
            c = s.vertices.take(s.triangles.take(self.prim_ids, axis=0), axis=0).astype(np.float64)
            n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        self._cache[key] = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
        return self._cache[key]

    def object_transforms(self, back=False):
        """(k, 3, 4) the affine maps of world positions into the hits' objects' spaces (``back``:
        out of them into the world; a pseudo-inverse for a flattened object)."""
        s = self.scene
        if s.object_ids is None:
            raise ProgramError("the program needs the objects' transforms, which the scene lacks")
        m = np.asarray(s.object_from_world, np.float64)
        if back:
            m = affine_inverse(m)
        return m.take(s.object_ids.take(self.prim_ids), axis=0)

    def camera_from_world(self):
        """(4, 4) world to Cycles' camera space (x right, y up, z the depth in front)."""
        return camera_from_world(self.scene.camera)

    def _view(self, name):
        """(k, 3) Camera or Window coordinates of the hits (``VIEW``)."""
        m = self.camera_from_world()
        c = np.asarray(self.positions, np.float64) @ m[:3, :3].T + m[:3, 3]
        return c if name == "camera" else window_coordinates(self.scene.camera, c)

    def _object_property(self, name):
        """(k, 3) the hits' objects' values of ``name`` (``Scene.object_attributes``); 0 without."""
        s = self.scene
        values = (s.object_attributes or {}).get(name)
        if values is None or s.object_ids is None:
            return np.zeros((self.count, 3))
        return np.asarray(values, np.float64).take(s.object_ids.take(self.prim_ids), axis=0)

    def _named(self, name):
        """(k, 3) mesh attribute ``name`` (``Scene.attributes``) interpolated at the hits; 0 without it."""
        values = (self.scene.attributes or {}).get(name)
        if values is None:
            return np.zeros((self.count, 3))
        return interpolate_corners(values.take(self.prim_ids, axis=0).astype(np.float64), self.bary)

    def _corners(self, name):
        c = {"uv": self.scene.uvs, "color": self.scene.vertex_colors}[name]
        if c is None:
            raise ProgramError(f"the program needs '{name}' data, which the scene lacks")
        v = interpolate_corners(c.take(self.prim_ids, axis=0), self.bary)
        if v.shape[1] == 2:
            v = np.concatenate([v, np.zeros((len(v), 1))], axis=1)
        return v

    def _object_info(self, name):
        """(k, 3) Object Info of the hits' objects (``OBJECT_INFO``)."""
        s = self.scene
        if s.object_ids is None:
            raise ProgramError(f"the program needs '{name}' of objects, which the scene lacks")
        objects, which = np.unique(s.object_ids.take(self.prim_ids), return_inverse=True)
        if name == "object_location":
            # The origin: where the object-from-world map takes 0 (pseudo-inverse: a flattened
            # object has no inverse).
            values = affine_inverse(s.object_from_world.take(objects, axis=0))[:, :, 3]
        else:
            info = s.object_info.take(objects, axis=0).astype(np.float64)
            values = info[:, 3:6] if name == "object_color" else info[:, :3]
        return values.take(which.ravel(), axis=0)

    def _object(self, name):
        s = self.scene
        if s.object_ids is None:
            raise ProgramError(f"the program needs '{name}' coordinates, which the scene lacks")
        obj = s.object_ids.take(self.prim_ids)
        m = s.object_from_world.take(obj, axis=0)                               # (k, 3, 4)
        positions = self.positions
        base = s.generated_vertices if s.generated_vertices is not None else s.undisplaced
        if name == "generated" and base is not None:
            # Cycles' Generated coordinates are the undeformed (orco) and undisplaced surface's.
            corners = base.take(s.triangles.take(self.prim_ids, axis=0), axis=0).astype(np.float64)
            positions = interpolate_corners(corners, self.bary)
        p = np.einsum("kij,kj->ki", m[:, :, :3], positions) + m[:, :, 3]
        if name == "object":
            return p
        space = s.texture_spaces.take(obj, axis=0)                               # (k, 2, 3)
        size = space[:, 1]
        half = np.where(size != 0.0, 0.5 / np.where(size != 0.0, size, 1.0), 0.0)
        return (p - space[:, 0]) * half + 0.5


def _cycles_orthonormals(n):
    """Cycles' ``make_orthonormals`` of unit normals ``n`` (k, 3): a = (1, 1, 1) x n normalised (or
    (-1, 1, 1) x n where n's components are all equal), b = n x a."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    equal = (x == y) & (x == z)
    a = np.stack([z - y, np.where(equal, x + z, x - z), np.where(equal, -y - x, y - x)], axis=1)
    a = normalize(a)
    return a, np.cross(n, a)


def camera_from_world(camera):
    """(4, 4) world to Cycles' camera space (x right, y up, z the depth in front) of ``camera``."""
    flip = np.diag([1.0, 1.0, -1.0, 1.0])
    return flip @ np.linalg.inv(np.asarray(camera.world_from_camera, np.float64))


def window_coordinates(camera, c):
    """(k, 3) Texture Coordinate's Window of points ``c`` (k, 3) in Cycles' camera space: where they
    land in the frame, (0, 0) at its bottom left, z = 0 (0 for panoramic cameras)."""
    out = np.zeros((len(c), 3))
    if camera.projection in ("perspective", "orthographic"):
        x0, x1, y0, y1 = camera.frame
        xy = c[:, :2]
        if camera.projection == "perspective":
            depth = c[:, 2:3]
            xy = np.divide(xy, depth, out=np.zeros_like(xy), where=depth != 0.0)
        out[:, 0] = (xy[:, 0] - x0) / (x1 - x0)
        out[:, 1] = (xy[:, 1] - y0) / (y1 - y0)
    return out


class DirectionAttributes:
    """The coordinates of a world shader: Generated, Object and the Geometry's Position are the
    direction (Cycles), its normals and Incoming the opposite, the uvs, colours, Backfacing and the
    light path zero.  directions : (k, 3) unit float64.

    With the scene's ``camera`` the view's coordinates are Cycles' for the background: Camera the
    direction in the camera's space, Window where the point at the camera plus the direction lands
    in its frame (a backplate); for an orthographic camera, where the ray's ``origins`` (k, 3) land
    when given (camera rays, Cycles' ray_P), else the direction taken as a point (Cycles' other
    rays).  Without a camera both are 0."""

    def __init__(self, directions, camera=None, origins=None):
        self.directions = np.asarray(directions, np.float64)
        self.camera, self.origins = camera, origins

    @property
    def count(self) -> int:
        return len(self.directions)

    def rows(self, start, stop) -> "DirectionAttributes":
        """The directions ``start:stop``."""
        return DirectionAttributes(self.directions[start:stop], self.camera,
                                   None if self.origins is None else self.origins[start:stop])

    def get(self, name):
        if name in ("generated", "object", "normal", "position"):
            return self.directions
        if name in ("world_normal", "true_normal", "incoming"):
            return -self.directions                 # (Cycles' background: N = Ng = I = -D)
        if name == "light_path":
            return np.zeros((self.count, len(LIGHT_PATH)))   # (the light it sheds: no camera ray)
        if name in VIEW and self.camera is not None:
            m = camera_from_world(self.camera)
            d = self.directions @ m[:3, :3].T               # (the camera's position plus d, in its space)
            if name == "camera":
                return d
            if self.camera.projection == "orthographic":
                points = (np.asarray(self.origins, np.float64) @ m[:3, :3].T + m[:3, 3]
                          if self.origins is not None else d + m[:3, 3])
                return window_coordinates(self.camera, points)
            return window_coordinates(self.camera, d)
        return np.zeros_like(self.directions)


class SampledAttributes:
    """Stand-in coordinates for an average of a program over a surface: generated (and vertex
    colours) uniform in the unit cube, object in [-1, 1]^3, uv in the unit square; for Object
    Info, locations in [-1, 1]^3, colours in the unit cube, alpha 1, index 0 and Random uniform
    in [0, 1]; Incoming cosine-distributed about the normal, never the back; the hits met by camera
    rays, rays off a mirror, through a glass and photons' in turn, of lengths in [0, 2] (seeded,
    reproducible)."""

    def __init__(self, n=4096, seed=0):
        rng = np.random.default_rng(seed)
        g = rng.random((n, 3))
        d = rng.normal(size=(n, 3))
        self._values = {"generated": g, "object": 2.0 * g - 1.0,
                        "uv": np.concatenate([g[:, :2], np.zeros((n, 1))], axis=1), "color": g,
                        "normal": d / np.linalg.norm(d, axis=1, keepdims=True),
                        "object_location": 2.0 * g - 1.0, "object_color": g,
                        "object_info": np.concatenate([np.ones((n, 1)), np.zeros((n, 1)), g[:, :1]], axis=1),
                        "position": 2.0 * g - 1.0, "camera": 2.0 * g - 1.0,
                        "window": np.concatenate([g[:, :2], np.zeros((n, 1))], axis=1),
                        "parametric": np.concatenate([g[:, :2], np.zeros((n, 1))], axis=1),
                        "edge_distance": g, "pixel_width": 0.01 * g}
        self._values["world_normal"] = self._values["true_normal"] = normals = self._values["normal"]
        # Unit tangents in random directions about the normals.
        across = np.cross(normals, rng.normal(size=(n, 3)))
        for name in TANGENTS:
            self._values[name] = across / np.linalg.norm(across, axis=1, keepdims=True)
        # Cosine-distributed, stratified in the squared sine: accurate means of the view's factors.
        s2, phi = (rng.permutation(n) + rng.random(n)) / n, 2.0 * np.pi * rng.random(n)
        local = np.stack([np.sqrt(s2) * np.cos(phi), np.sqrt(s2) * np.sin(phi), np.sqrt(1.0 - s2)], axis=1)
        self._values["incoming"] = to_world(local, normals)
        self._values["backfacing"] = np.zeros((n, 3))
        # Camera rays, rays off a mirror, through a glass and photons' in turn (each output then
        # varies as it may: a mask's mean is no 0 or 1).
        kind, lengths = np.arange(n) % 4, 2.0 * g[:, 0]
        bounced = (kind == 1) | (kind == 2)
        path = camera_path(kind == 0, kind == 1, lengths, bounced, kind == 1, kind == 2)
        path[kind == 3] = photon_path(lengths[kind == 3])
        self._values["light_path"] = path

    @property
    def count(self) -> int:
        return len(self._values["generated"])

    def get(self, name):
        if name.startswith((NAMED, *OBJECT_PROPERTY)):
            return self._values["color"]            # (an attribute: uniform in the unit cube)
        return self._values[name]


def _position_keys(points):
    """(k,) uint32 hash keys of float64 ``points`` (k, 3): all their bits, folded."""
    bits = np.ascontiguousarray(points, np.float64).view(np.uint64)
    folded = ((bits ^ (bits >> np.uint64(32))) & np.uint64(0xFFFFFFFF)).astype(np.uint32)
    return hash_uint3(folded[:, 0], folded[:, 1], folded[:, 2])


def _cubic_falloff_root(xi):
    """(k,) x in [0, 1] with 10 x^2 - 20 x^3 + 15 x^4 - 4 x^5 = ``xi``: the radius, over the
    falloff's reach, of Cycles' cubic falloff (Bevel's ``svm_bevel_cubic_quintic_root_find``, by
    Newton's method from 1/4)."""
    x = np.full(len(xi), 0.25)
    for _ in range(10):
        nx = 1.0 - x
        f = 10.0 * x ** 2 - 20.0 * x ** 3 + 15.0 * x ** 4 - 4.0 * x ** 5 - xi
        slope = 20.0 * (x * nx) * (nx * nx)
        step = np.where((np.abs(f) < 1e-6) | (slope == 0.0), 0.0, f / np.where(slope == 0.0, 1.0, slope))
        x = np.clip(x - step, 0.0, 1.0)
    return x


def evaluate(program, attrs, images, output=None, sky_cache=None):
    """Value of ``program`` (a node dict) at the hits of ``attrs``: (k,) or (k, 3) float64.

    images : the scene's images (H, W, 3), for ``image`` nodes.
    sky_cache : a ``sky.SkyTextureCache`` kept by the caller across evaluations (a render's
        ``RenderContext``), so that a Sky Texture is baked once (about 1.5 s) rather than at every
        evaluation; None: one for this evaluation alone.
    More than ``EVAL_CHUNK`` hits are evaluated ``EVAL_CHUNK`` at a time, so that a program's
    temporaries stay in the processor's cache: each hit's value is its own, so the values are the
    same, but where a setting that must be constant (``_Evaluator.scalar``: a texture's Scale,
    Detail, ...) is fed by a varying program, whose mean over the chunk it then takes instead of
    the mean over all hits (an approximation either way: Cycles varies it hit by hit)."""
    program = program if output is None else {**program, "output": output}
    k = attrs.count
    if k <= EVAL_CHUNK or not hasattr(attrs, "rows"):
        return _Evaluator(attrs, images, sky_cache).output(program)
    sky_cache = _sky_module.SkyTextureCache() if sky_cache is None else sky_cache
    return np.concatenate([_Evaluator(attrs.rows(start, min(start + EVAL_CHUNK, k)), images, sky_cache)
                           .output(program) for start in range(0, k, EVAL_CHUNK)])


def evaluate_color(program, attrs, images, limit=COLOR_MAX, sky_cache=None):
    """(k, 3) float64 colour of ``program`` (a float result is grey) in [0, ``limit``]; NaN -> 0."""
    v = evaluate(program, attrs, images, sky_cache=sky_cache)
    if v.ndim == 1:
        v = np.repeat(v[:, None], 3, axis=1)
    return np.clip(np.nan_to_num(v, nan=0.0), 0.0, limit)


def mean_color(program, images, n=4096, sky_cache=None):
    """(3,) mean colour of ``program`` over :class:`SampledAttributes`: what a lobe that cannot
    vary over the surface uses."""
    return evaluate_color(program, SampledAttributes(n), images, sky_cache=sky_cache).mean(axis=0)


def varies(program) -> bool:
    """Whether ``program`` (a node dict, or a constant) depends on the hit: reads some attribute."""
    return isinstance(program, dict) and bool(attributes_used(program))


def mean_value(program, images, sky_cache=None):
    """Mean of ``program`` over :class:`SampledAttributes`: a float, or (3,) for a colour or vector."""
    v = evaluate(program, SampledAttributes(), images, sky_cache=sky_cache)
    return float(v.mean()) if v.ndim == 1 else v.mean(axis=0)


def attributes_used(program) -> set:
    """Names of the per-corner data (``ATTRIBUTES``) ``program`` reads."""
    used = set()
    for node in nodes(program):
        if node["op"] == "attribute":
            used.add(node["name"])
        elif node["op"] == "image" and node.get("projection", "FLAT") == "BOX":
            used.add("normal")
        elif node["op"] in ("fresnel", "layer_weight"):
            used |= {"incoming", "backfacing"} | (set() if "normal" in node else {"world_normal"})
        elif node["op"] == "ao":
            used |= {"position"} | (set() if "normal" in node else {"world_normal"})
            if node.get("only_local", False):
                used.add("object")                  # (which object a triangle is of)
        elif node["op"] == "bevel":
            used |= {"position", "world_normal", "object"}
        elif node["op"] == "bump":
            used |= {"position"} | (set() if "normal" in node else {"world_normal"})
        elif node["op"] == "light_path":
            used.add("light_path")
        elif node["op"] == "vector_transform":
            spaces = {node.get("convert_from", "WORLD"), node.get("convert_to", "OBJECT")}
            used |= {"object"} & {s.lower() for s in spaces} | ({"camera"} if "CAMERA" in spaces else set())
    return used


def to_json(program) -> str:
    return json.dumps(program, separators=(",", ":"), default=_jsonable)


def from_json(text):
    return json.loads(text)


def validate(program, n_images):
    """Raise :class:`ProgramError` naming the first problem of ``program``."""
    if not isinstance(program, dict):
        raise ProgramError(f"a program must be a node dict, not {type(program).__name__}")
    for node in nodes(program):
        op = node.get("op")
        if op not in OPS:
            raise ProgramError(f"unknown program op {op!r}")
        outputs = OUTPUTS[op]
        if node.get("output", outputs[0]) not in outputs:
            raise ProgramError(f"op '{op}' has no output {node.get('output')!r} (it has {outputs})")
        for name in REQUIRED.get(op, ()):
            if name not in node:
                raise ProgramError(f"op '{op}' lacks its input '{name}'")
        if op in ("image", "environment") and not (isinstance(node["texture"], int)
                                                   and 0 <= node["texture"] < n_images):
            raise ProgramError(f"image node texture {node['texture']!r} is not an index below {n_images}")
        for key, value in node.items():
            _check_value(op, key, value)
        for key, shape in ARRAYS.get(op, {}).items():
            if key in node:
                _check_array(op, key, node[key], shape)


def _check_value(op, key, value):
    """A node's setting must be one of its op's choices, an input a number, three numbers or a node."""
    if key in ("op", "output") or isinstance(value, dict):
        return
    choices = CHOICES.get((op, key))
    if (op, key) == ("attribute", "name") and isinstance(value, str) and any(
            value.startswith(p) and len(value) > len(p) for p in (NAMED, *OBJECT_PROPERTY)):
        return                                      # a mesh attribute's or an object's property's name
    if choices is not None:
        if value not in choices:
            raise ProgramError(f"op '{op}': {key} {value!r} is not one of {tuple(choices)}")
        return
    if key in ARRAYS.get(op, {}):
        return                                      # arrays, checked in validate
    ok = isinstance(value, (bool, int, float)) or (
        isinstance(value, list) and len(value) == 3 and all(isinstance(x, (int, float)) for x in value))
    if not ok or not np.isfinite(value).all():
        raise ProgramError(f"op '{op}': input {key} must be a finite number, three numbers or a node, "
                           f"not {value!r}")


def _check_array(op, key, value, shape):
    """An op's array setting: finite, of ``shape`` (None: any length >= 2 along that axis)."""
    try:
        a = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        a = None
    ok = (a is not None and a.ndim == len(shape) and np.isfinite(a).all()
          and all(n == k if k is not None else n >= 2 for n, k in zip(a.shape, shape)))
    if not ok:
        raise ProgramError(f"op '{op}': {key} must be a finite array of shape "
                           f"{tuple('N' if k is None else k for k in shape)}")


def nodes(program):
    """Every node of the tree (depth first)."""
    stack = [program]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            yield node
            stack.extend(v for v in node.values() if isinstance(v, dict))


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"cannot store {type(x).__name__} in a program")


class _Evaluator:
    """One evaluation: inputs resolved recursively, each node evaluated once (by identity)."""

    def __init__(self, attrs, images, sky_cache=None):
        self.attrs, self.images, self.k = attrs, images, attrs.count
        self._done = {}
        # a Sky Texture's bakes (``evaluate``'s sky_cache)
        self.sky_cache = _sky_module.SkyTextureCache() if sky_cache is None else sky_cache

    def output(self, node):
        key = id(node)
        if key not in self._done:
            self._done[key] = (node, OPS[node["op"]](self, node))
        outputs = self._done[key][1]
        return outputs[node.get("output", OUTPUTS[node["op"]][0])]

    def float(self, node, name, default=0.0):
        v = node.get(name, default)
        if isinstance(v, dict):
            v = self.output(v)
            return v if v.ndim == 1 else v @ LUMINANCE
        return np.full(self.k, float(np.mean(v)))

    def vec(self, node, name, default=(0.0, 0.0, 0.0)):
        v = node.get(name, default)
        if isinstance(v, dict):
            v = self.output(v)
            return v if v.ndim == 2 else np.repeat(v[:, None], 3, axis=1)
        return np.broadcast_to(np.asarray(v, np.float64).reshape(-1)[:3] if np.ndim(v) else np.full(3, v),
                               (self.k, 3)).copy()

    def scalar(self, node, name, default=0.0) -> float:
        """A setting that must not vary over the surface (the exporter stores constants)."""
        v = node.get(name, default)
        if isinstance(v, dict):
            return float(np.mean(self.float(node, name)))
        return float(v)


# ---------------------------------------------------------------------- ops
def _attribute(ev, node):
    return {"Vector": ev.attrs.get(node["name"])}


def _affine(ev, node):
    v = ev.vec(node, "vector") - np.asarray(node.get("pre", (0, 0, 0)), np.float64)
    out = v @ np.asarray(node["matrix"], np.float64).T + np.asarray(node.get("post", (0, 0, 0)), np.float64)
    if node.get("normalize"):
        length = np.sqrt((out * out).sum(axis=1))
        out = np.where(length[:, None] > 0, out / np.where(length > 0, length, 1.0)[:, None], 0.0)
    return {"Vector": out}


def _checker(ev, node):
    p = ev.vec(node, "vector") * ev.float(node, "scale", 5.0)[:, None]
    # Cycles nudges the coordinates off exact integers ("precision issues on unit coordinates").
    cell = np.abs(float_to_int(np.floor((p + 1e-6) * 0.999999))) % 2
    fac = ((cell[:, 0] == cell[:, 1]) == (cell[:, 2] == 1)).astype(np.float64)
    color = np.where(fac[:, None] == 1.0, ev.vec(node, "color1"), ev.vec(node, "color2"))
    return {"Color": color, "Fac": fac}


def _gradient(ev, node):
    p = ev.vec(node, "vector")
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    kind = node.get("gradient_type", "LINEAR")
    if kind == "QUADRATIC":
        f = np.maximum(x, 0.0) ** 2
    elif kind == "EASING":
        r = np.clip(x, 0.0, 1.0)
        f = 3.0 * r * r - 2.0 * r * r * r
    elif kind == "DIAGONAL":
        f = (x + y) * 0.5
    elif kind == "RADIAL":
        f = np.arctan2(y, x) / (2.0 * np.pi) + 0.5
    elif kind in ("QUADRATIC_SPHERE", "SPHERICAL"):
        r = np.maximum(0.999999 - np.sqrt(x * x + y * y + z * z), 0.0)
        f = r * r if kind == "QUADRATIC_SPHERE" else r
    else:
        f = x
    f = np.clip(f, 0.0, 1.0)
    return {"Color": np.repeat(f[:, None], 3, axis=1), "Fac": f}


def _noise(ev, node):
    fac, color = _noise_module.noise_texture(
        ev.vec(node, "vector"), ev.scalar(node, "scale", 5.0), ev.scalar(node, "detail", 2.0),
        ev.scalar(node, "roughness", 0.5), ev.scalar(node, "lacunarity", 2.0),
        ev.scalar(node, "distortion", 0.0), noise_type=node.get("noise_type", "FBM"),
        normalize=bool(node.get("normalize", True)), offset=ev.scalar(node, "offset", 0.0),
        gain=ev.scalar(node, "gain", 1.0), dimensions=node.get("dimensions", "3D"),
        w=ev.scalar(node, "w", 0.0), color=node.get("output", "Fac") == "Color")
    return {"Fac": fac, "Color": color}


def _voronoi(ev, node):
    out = _voronoi_module.voronoi_texture(
        ev.vec(node, "vector"), ev.scalar(node, "scale", 5.0), detail=ev.scalar(node, "detail", 0.0),
        roughness=ev.scalar(node, "roughness", 0.5), lacunarity=ev.scalar(node, "lacunarity", 2.0),
        randomness=ev.scalar(node, "randomness", 1.0), feature=node.get("feature", "F1"),
        metric=node.get("metric", "EUCLIDEAN"), exponent=ev.scalar(node, "exponent", 0.5),
        smoothness=ev.scalar(node, "smoothness", 1.0), normalize=bool(node.get("normalize", False)),
        dimensions=node.get("dimensions", "3D"), w=ev.scalar(node, "w", 0.0))
    return {name: out[name] for name in OUTPUTS["voronoi"]}


def _wave(ev, node):
    return _patterns.wave_texture(
        ev.vec(node, "vector"), wave_type=node.get("wave_type", "BANDS"),
        bands_direction=node.get("bands_direction", "X"), rings_direction=node.get("rings_direction", "X"),
        wave_profile=node.get("wave_profile", "SIN"), scale=ev.scalar(node, "scale", 5.0),
        distortion=ev.scalar(node, "distortion", 0.0), detail=ev.scalar(node, "detail", 2.0),
        detail_scale=ev.scalar(node, "detail_scale", 1.0),
        detail_roughness=ev.scalar(node, "detail_roughness", 0.5),
        phase_offset=ev.scalar(node, "phase_offset", 0.0))


def _brick(ev, node):
    return _patterns.brick_texture(
        ev.vec(node, "vector"), color1=ev.vec(node, "color1", (0.8,) * 3),
        color2=ev.vec(node, "color2", (0.2,) * 3),
        mortar=ev.vec(node, "mortar", (0.0,) * 3), scale=ev.scalar(node, "scale", 5.0),
        mortar_size=ev.scalar(node, "mortar_size", 0.02), mortar_smooth=ev.scalar(node, "mortar_smooth", 0.1),
        bias=ev.scalar(node, "bias", 0.0), brick_width=ev.scalar(node, "brick_width", 0.5),
        row_height=ev.scalar(node, "row_height", 0.25), offset=ev.scalar(node, "offset", 0.5),
        offset_frequency=max(int(node.get("offset_frequency", 2)), 1), squash=ev.scalar(node, "squash", 1.0),
        squash_frequency=max(int(node.get("squash_frequency", 2)), 1))      # Blender's range starts at 1


def _magic(ev, node):
    return _patterns.magic_texture(ev.vec(node, "vector"), depth=int(np.clip(node.get("depth", 2), 0, 10)),
                                   scale=ev.scalar(node, "scale", 5.0),
                                   distortion=ev.scalar(node, "distortion", 1.0))


def _white_noise(ev, node):
    return _patterns.white_noise_texture(ev.vec(node, "vector"), dimensions=node.get("dimensions", "3D"),
                                         w=ev.float(node, "w", 0.0))


def _gabor(ev, node):
    return _patterns.gabor_texture(
        ev.vec(node, "vector"), gabor_type=node.get("gabor_type", "2D"), scale=ev.float(node, "scale", 5.0),
        frequency=ev.float(node, "frequency", 2.0), anisotropy=ev.float(node, "anisotropy", 1.0),
        orientation_2d=ev.float(node, "orientation_2d", np.pi / 4),
        orientation_3d=ev.vec(node, "orientation_3d", (np.sqrt(2.0), np.sqrt(2.0), 0.0)))


def _environment(ev, node):
    """An equirectangular image looked up by direction (Cycles' ``direction_to_equirectangular``:
    u = 1/2 - atan2(y, x) / 2 pi, v = 1 - acos(z) / pi; bilinear, wrapping in u, clamped in v), or
    with ``projection`` "MIRROR_BALL" a photo of a mirror ball (:func:`mirror_ball_uv`)."""
    d = ev.vec(node, "vector")
    if node.get("projection", "EQUIRECTANGULAR") == "MIRROR_BALL":
        u, v = mirror_ball_uv(d)
    else:
        u, v = equirectangular_uv(d)
    return {"Color": bilinear(ev.images[int(node["texture"])], u, v, clamp_v=True), "Alpha": np.ones(ev.k)}


def mirror_ball_uv(dirs):
    """Image coordinates (u, v), (n,) each, of directions ``dirs`` (n, 3) (any length) in a photo of a
    mirror ball taken along +y (Cycles' ``direction_to_mirrorball``: the unit direction d less
    (0, 1, 0), over 2 sqrt(-(d_y - 1) / 2), gives u = (x + 1) / 2, v = (z + 1) / 2)."""
    d = normalize(np.asarray(dirs, np.float64))
    d[:, 1] -= 1.0
    div = 2.0 * np.sqrt(np.maximum(-0.5 * d[:, 1], 0.0))
    d = d / np.where(div > 0.0, div, 1.0)[:, None]
    return 0.5 * (d[:, 0] + 1.0), 0.5 * (d[:, 2] + 1.0)


def _sky(ev, node):
    """Blender's Sky Texture without its sun disc (``core/sky.py``); the vector is a direction."""
    d = ev.vec(node, "vector")
    length = np.sqrt((d * d).sum(axis=1))
    d = np.where(length[:, None] > 0, d / np.where(length > 0, length, 1.0)[:, None], [0.0, 0.0, 1.0])
    sun_direction = node.get("sun_direction")
    color = _sky_module.sky_radiance(
        d, sky_type=node.get("sky_type", "MULTIPLE_SCATTERING"),
        sun_elevation=ev.scalar(node, "sun_elevation"), sun_rotation=ev.scalar(node, "sun_rotation"),
        altitude=ev.scalar(node, "altitude", 100.0), air_density=ev.scalar(node, "air_density", 1.0),
        aerosol_density=ev.scalar(node, "aerosol_density", 1.0),
        ozone_density=ev.scalar(node, "ozone_density", 1.0), turbidity=ev.scalar(node, "turbidity", 2.2),
        sun_direction=None if sun_direction is None else np.asarray(sun_direction, np.float64),
        cache=ev.sky_cache)
    return {"Color": color}


def _image(ev, node):
    p = ev.vec(node, "vector")
    image = ev.images[int(node["texture"])]
    extension = node.get("extension", "REPEAT")
    interpolation = node.get("interpolation", "Linear")

    def lookup(u, v):
        if extension == "REPEAT" and interpolation == "Linear":
            return bilinear(image, u, v)
        return image_lookup(image, u, v, extension, interpolation)

    projection = node.get("projection", "FLAT")
    if projection == "FLAT":
        return {"Color": lookup(p[:, 0], p[:, 1]), "Alpha": np.ones(ev.k)}
    if projection in ("SPHERE", "TUBE"):
        u, v = (map_to_sphere if projection == "SPHERE" else map_to_tube)(2.0 * p - 1.0)
        return {"Color": lookup(u, v), "Alpha": np.ones(ev.k)}
    # Box: three flat projections along the object-space axes, weighted by the normal.
    n = ev.attrs.get("normal")
    weights = box_weights(n, float(node.get("blend", 0.0)))
    color = np.zeros((ev.k, 3))
    faces = ((n[:, 0] < 0.0, p[:, 1], p[:, 2]), (n[:, 1] > 0.0, p[:, 0], p[:, 2]),
             (n[:, 2] > 0.0, p[:, 1], p[:, 0]))
    for axis, (flip, u, v) in enumerate(faces):
        rows = np.flatnonzero(weights[:, axis] > 0.0)
        if len(rows):
            uu = np.where(flip, 1.0 - u, u).take(rows)
            color[rows] += weights[rows, axis, None] * lookup(uu, v.take(rows))
    return {"Color": color, "Alpha": np.ones(ev.k)}


def map_to_sphere(co):
    """(u, v) of points ``co`` (k, 3) around the origin on Cycles' sphere projection (``map_to_sphere``:
    the longitude from +y, turning towards -x, and the latitude; 0 at the origin)."""
    x, y, z = co[:, 0], co[:, 1], co[:, 2]
    r = np.sqrt(x * x + y * y + z * z)
    u = np.where((x == 0.0) & (y == 0.0), 0.0, 0.5 - np.arctan2(x, y) / (2.0 * np.pi))
    v = 1.0 - np.arccos(np.clip(np.divide(z, r, out=np.zeros_like(z), where=r > 0.0), -1.0, 1.0)) / np.pi
    return np.where(r > 0.0, u, 0.0), np.where(r > 0.0, v, 0.0)


def map_to_tube(co):
    """(u, v) of points ``co`` (k, 3) around the z axis on Cycles' tube projection (``map_to_tube``:
    the angle about z as the sphere's, the height from -1 to 1; 0 on the axis)."""
    x, y, z = co[:, 0], co[:, 1], co[:, 2]
    on_axis = (x == 0.0) & (y == 0.0)
    u = 0.5 - np.arctan2(x, y) / (2.0 * np.pi)
    return np.where(on_axis, 0.0, u), np.where(on_axis, 0.0, 0.5 * (z + 1.0))


def box_weights(normals, blend):
    """(k, 3) weights of the x, y and z projections of Cycles' box-projected Image Texture
    (``svm_node_tex_image_box``) for object-space ``normals`` (k, 3) and ``blend``: one axis
    where it dominates, else blends of two or three."""
    a = np.abs(np.asarray(normals, np.float64))
    total = a.sum(axis=1, keepdims=True)
    a = np.divide(a, total, out=np.full_like(a, 1.0 / 3.0), where=total > 0)
    x, y, z = a[:, 0], a[:, 1], a[:, 2]
    limit = 0.5 * (1.0 + blend)
    w = np.zeros_like(a)
    only_x = (x > limit * (x + y)) & (x > limit * (x + z))
    only_y = ~only_x & (y > limit * (x + y)) & (y > limit * (y + z))
    only_z = ~only_x & ~only_y & (z > limit * (x + z)) & (z > limit * (y + z))
    rest = ~(only_x | only_y | only_z)
    w[only_x, 0] = w[only_y, 1] = w[only_z, 2] = 1.0
    if blend <= 0.0:
        w[rest, 0] = 1.0                                          # Cycles' fallback: one side
        return w
    with np.errstate(all="ignore"):
        xy = rest & (z < (1.0 - limit) * (y + x))
        yz = rest & ~xy & (x < (1.0 - limit) * (y + z))
        xz = rest & ~xy & ~yz & (y < (1.0 - limit) * (x + z))
        three = rest & ~xy & ~yz & ~xz
        ramp = lambda t: np.clip((t - 0.5 * (1.0 - blend)) / blend, 0.0, 1.0)  # noqa: E731
        wx = ramp(x / (x + y))
        w[xy, 0], w[xy, 1] = wx[xy], 1.0 - wx[xy]
        wy = ramp(y / (y + z))
        w[yz, 1], w[yz, 2] = wy[yz], 1.0 - wy[yz]
        wxz = ramp(x / (x + z))
        w[xz, 0], w[xz, 2] = wxz[xz], 1.0 - wxz[xz]
        for k, c in enumerate((x, y, z)):
            w[three, k] = (((2.0 - limit) * c + (limit - 1.0)) / (2.0 * limit - 1.0))[three]
    return w


def image_lookup(image, u, v, extension="REPEAT", interpolation="Linear"):
    """(n, 3) lookups of ``image`` (H, W, 3; row 0 is v = 0) at (u, v) as Cycles' Image Texture
    (``kernel/device/cpu/image.h``): ``interpolation`` Linear (bilinear between texel centres),
    Closest (the texel under the point) or Cubic (the cubic B-spline of the 4 x 4 texels around,
    Cycles' ``interp_cubic``, which its CPU also takes for Smart), and texels outside the image by
    ``extension``: REPEAT (wrap), EXTEND (the edge texel), CLIP (black) or MIRROR (reflected)."""
    h, w = image.shape[:2]
    u = np.nan_to_num(np.asarray(u, np.float64))
    v = np.nan_to_num(np.asarray(v, np.float64))
    flat = image.reshape(-1, 3)

    def fetch(ix, iy):
        inside = np.ones(len(ix), bool)
        if extension == "CLIP":
            inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
        ix, iy = _wrap(ix, w, extension), _wrap(iy, h, extension)
        return np.where(inside[:, None], flat.take(iy * w + ix, axis=0), 0.0)

    if interpolation == "Closest":
        return fetch(np.floor(u * w).astype(np.int64), np.floor(v * h).astype(np.int64))
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    ix, iy = x0.astype(np.int64), y0.astype(np.int64)
    if interpolation == "Cubic":
        wx, wy = _cubic_bspline(fx), _cubic_bspline(fy)
        out = np.zeros((len(ix), 3))
        for j in range(4):
            row = np.zeros((len(ix), 3))
            for i in range(4):
                row += wx[i] * fetch(ix + i - 1, iy + j - 1)
            out += wy[j] * row
        return out
    return ((1 - fx) * (1 - fy) * fetch(ix, iy) + fx * (1 - fy) * fetch(ix + 1, iy)
            + (1 - fx) * fy * fetch(ix, iy + 1) + fx * fy * fetch(ix + 1, iy + 1))


def _cubic_bspline(t):
    """The four cubic B-spline weights (Cycles' ``SET_CUBIC_SPLINE_WEIGHTS``) at fractions ``t``."""
    return ((((-1.0 / 6.0) * t + 0.5) * t - 0.5) * t + 1.0 / 6.0, ((0.5 * t - 1.0) * t) * t + 2.0 / 3.0,
            ((-0.5 * t + 0.5) * t + 0.5) * t + 1.0 / 6.0, (1.0 / 6.0) * t * t * t)


def _wrap(i, size, extension):
    """Texel indices ``i`` brought into [0, size) by ``extension`` (CLIP's outside ones are masked
    by the caller)."""
    if extension == "REPEAT":
        return np.mod(i, size)
    if extension == "MIRROR":                        # Cycles' wrap_mirror
        m = np.mod(np.abs(i + (i < 0)), 2 * size)
        return np.where(m >= size, 2 * size - m - 1, m)
    return np.clip(i, 0, size - 1)                  # EXTEND, and CLIP inside


def _table_lookup(table, f, interpolate=True):
    """Cycles' ``rgb_ramp_lookup`` of (N, c) ``table`` at positions ``f`` in [0, 1] (clamped; NaN
    as 0), (k, c) a column each or (k, 1) one for all: linearly between entries with
    ``interpolate``, else the entry below."""
    size = len(table)
    x = np.clip(np.nan_to_num(f, nan=0.0), 0.0, 1.0) * (size - 1)
    i = np.clip(x.astype(np.int64), 0, size - 1)
    cols = np.arange(table.shape[1])
    out = table[i, cols]
    if interpolate:
        t = x - i
        out = np.where(t > 0.0, (1.0 - t) * out + t * table[np.minimum(i + 1, size - 1), cols], out)
    return out


def _ramp(ev, node):
    out = _table_lookup(np.asarray(node["table"], np.float64), ev.float(node, "fac")[:, None],
                        node.get("interpolate", True))
    return {"Color": out[:, :3], "Alpha": out[:, 3]}


def _mix_color(ev, node):
    t = ev.float(node, "fac", 0.5)
    if node.get("clamp_factor", True):
        t = np.clip(t, 0.0, 1.0)
    a, b = ev.vec(node, "a"), ev.vec(node, "b")
    out = _blend(node.get("blend", "MIX"), t[:, None], a, b)
    if node.get("clamp_result", False):
        out = np.clip(out, 0.0, 1.0)
    return {"Result": out}


def _blend(kind, t, a, b):
    """Blender's colour blend modes (``color_util.h``), t (k, 1), a and b (k, 3)."""
    lerp = lambda x: (1.0 - t) * a + t * x      # noqa: E731
    simple = {"MIX": lambda: b, "ADD": lambda: a + b, "MULTIPLY": lambda: a * b,
              "SUBTRACT": lambda: a - b, "DIFFERENCE": lambda: np.abs(a - b),
              "DARKEN": lambda: np.minimum(a, b), "LIGHTEN": lambda: np.maximum(a, b),
              "EXCLUSION": lambda: a + b - 2.0 * a * b}
    if kind in simple:
        return lerp(simple[kind]())
    if kind == "SCREEN":
        return 1.0 - ((1.0 - t) + t * (1.0 - b)) * (1.0 - a)
    if kind == "OVERLAY":
        low = a * ((1.0 - t) + 2.0 * t * b)
        high = 1.0 - ((1.0 - t) + 2.0 * t * (1.0 - b)) * (1.0 - a)
        return np.where(a < 0.5, low, high)
    if kind == "DIVIDE":
        return np.where(b != 0.0, (1.0 - t) * a + t * a / np.where(b != 0.0, b, 1.0), a)
    if kind == "LINEAR_LIGHT":
        return a + t * (2.0 * b - 1.0)
    if kind == "SOFT_LIGHT":
        screen = 1.0 - (1.0 - b) * (1.0 - a)
        return (1.0 - t) * a + t * ((1.0 - a) * b * a + a * screen)
    if kind == "DODGE":
        d = 1.0 - t * b
        with np.errstate(all="ignore"):
            q = np.where(d > 0.0, a / np.where(d > 0.0, d, 1.0), 1.0)
        return np.where(a != 0.0, np.minimum(q, 1.0), a)
    if kind == "BURN":
        d = (1.0 - t) + t * b
        with np.errstate(all="ignore"):
            q = 1.0 - (1.0 - a) / np.where(d > 0.0, d, 1.0)
        return np.where(d > 0.0, np.clip(q, 0.0, 1.0), 0.0)
    if kind in ("HUE", "SATURATION", "VALUE", "COLOR"):
        return _blend_hsv(kind, t, a, b)
    raise ProgramError(f"unsupported blend mode {kind!r}")


def _blend_hsv(kind, t, a, b):
    """Hue, Saturation, Value and Color blends: the HSV components of a taken from b."""
    ha, hb = rgb_to_hsv(a), rgb_to_hsv(b)
    if kind == "VALUE":
        ha[:, 2] = (1.0 - t[:, 0]) * ha[:, 2] + t[:, 0] * hb[:, 2]
        return hsv_to_rgb(ha)
    if kind == "SATURATION":
        out = ha.copy()
        out[:, 1] = (1.0 - t[:, 0]) * ha[:, 1] + t[:, 0] * hb[:, 1]
        return np.where(ha[:, 1:2] != 0.0, hsv_to_rgb(out), a)
    out = ha.copy()
    out[:, 0] = hb[:, 0]
    if kind == "COLOR":
        out[:, 1] = hb[:, 1]
    return np.where(hb[:, 1:2] != 0.0, (1.0 - t) * a + t * hsv_to_rgb(out), a)


def rgb_to_hsv(c):
    """(k, 3) hue, saturation, value of (k, 3) RGB colours (Cycles' ``rgb_to_hsv``)."""
    r, g, b = c[:, 0], c[:, 1], c[:, 2]
    cmax, cmin = np.maximum(r, np.maximum(g, b)), np.minimum(r, np.minimum(g, b))
    delta = cmax - cmin
    s = np.where(cmax != 0.0, delta / np.where(cmax != 0.0, cmax, 1.0), 0.0)
    d = np.where(delta != 0.0, delta, 1.0)
    cr, cg, cb = (cmax - r) / d, (cmax - g) / d, (cmax - b) / d
    h = np.where(r == cmax, cb - cg, np.where(g == cmax, 2.0 + cr - cb, 4.0 + cg - cr)) / 6.0
    h = np.where(h < 0.0, h + 1.0, h)
    return np.stack([np.where(s != 0.0, h, 0.0), s, cmax], axis=1)


def hsv_to_rgb(hsv):
    """(k, 3) RGB of (k, 3) hue, saturation, value (Cycles' ``hsv_to_rgb``)."""
    h, s, v = hsv[:, 0], hsv[:, 1], hsv[:, 2]
    h = np.where(h == 1.0, 0.0, h) * 6.0
    i = np.floor(h)
    f = h - i
    p, q, t = v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f))
    sector = np.where((i >= 0.0) & (i <= 4.0), i, 5.0).astype(np.int64)[:, None]   # (Cycles' else: 5)
    rows = np.stack([np.stack(x, axis=1) for x in ((v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v),
                                                   (v, p, q))])
    rgb = rows[sector[:, 0], np.arange(len(h))]
    return np.where((s != 0.0)[:, None], rgb, np.stack([v, v, v], axis=1))


def rgb_to_hsl(c):
    """(k, 3) hue, saturation, lightness of (k, 3) RGB colours (Cycles' ``rgb_to_hsl``)."""
    r, g, b = c[:, 0], c[:, 1], c[:, 2]
    cmax, cmin = np.maximum(r, np.maximum(g, b)), np.minimum(r, np.minimum(g, b))
    lightness = np.minimum(1.0, (cmax + cmin) / 2.0)
    d = cmax - cmin
    dd = np.where(d != 0.0, d, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(lightness > 0.5, d / (2.0 - cmax - cmin), d / (cmax + cmin))
    h = np.where(cmax == r, (g - b) / dd + np.where(g < b, 6.0, 0.0),
                 np.where(cmax == g, (b - r) / dd + 2.0, (r - g) / dd + 4.0))
    flat = cmax == cmin
    return np.stack([np.where(flat, 0.0, h) / 6.0, np.where(flat, 0.0, s), lightness], axis=1)


def hsl_to_rgb(hsl):
    """(k, 3) RGB of (k, 3) hue, saturation, lightness (Cycles' ``hsl_to_rgb``)."""
    h, s, lightness = hsl[:, 0:1], hsl[:, 1:2], hsl[:, 2:3]
    n = np.concatenate([np.abs(h * 6.0 - 3.0) - 1.0, 2.0 - np.abs(h * 6.0 - 2.0),
                        2.0 - np.abs(h * 6.0 - 4.0)], axis=1)
    chroma = (1.0 - np.abs(2.0 * lightness - 1.0)) * s
    return (np.clip(n, 0.0, 1.0) - 0.5) * chroma + lightness


COLOR_SPACES = {"RGB_TO_HSV": rgb_to_hsv, "HSV_TO_RGB": hsv_to_rgb, "RGB_TO_HSL": rgb_to_hsl,
                "HSL_TO_RGB": hsl_to_rgb}


def _color_space(ev, node):
    return {"Color": COLOR_SPACES[node["conversion"]](ev.vec(node, "color"))}


def _vector_transform(ev, node):
    """Cycles' ``svm_node_vector_transform``: a point, vector or normal (by the inverse transpose,
    normalised) from world, object or camera space to another; object spaces need the hits'
    objects (none in a world shader or over stand-in coordinates: unchanged), camera spaces the
    camera (none there either)."""
    v = ev.vec(node, "vector")
    point, normal = (node.get("type", "VECTOR") == kind for kind in ("POINT", "NORMAL"))
    src, dst = node.get("convert_from", "WORLD"), node.get("convert_to", "OBJECT")
    has_objects = hasattr(ev.attrs, "object_transforms")
    camera = ev.attrs.camera_from_world() if hasattr(ev.attrs, "camera_from_world") else None

    def affine(m, x):                                   # m (3, 4) or (k, 3, 4)
        linear = m[..., :3]
        if normal:                                      # (normals: the inverse transpose)
            linear = np.swapaxes(np.linalg.pinv(linear), -1, -2)
        if m.ndim == 2:
            return x @ linear.T + (m[:, 3] if point else 0.0)
        return np.einsum("kij,kj->ki", linear, x) + (m[:, :, 3] if point else 0.0)

    if src == "WORLD" or src == "CAMERA":
        if src == "CAMERA" and dst != "CAMERA" and camera is not None:
            v = affine(affine_inverse(camera[:3]), v)
        if dst == "CAMERA" and src == "WORLD" and camera is not None:
            v = affine(camera[:3], v)
        elif dst == "OBJECT" and has_objects:
            v = affine(ev.attrs.object_transforms(), v)
    elif src == "OBJECT":
        if dst != "OBJECT" and has_objects:
            v = affine(ev.attrs.object_transforms(back=True), v)
        if dst == "CAMERA" and camera is not None:
            v = affine(camera[:3], v)
    if normal:
        n = np.sqrt((v * v).sum(axis=1, keepdims=True))
        v = np.divide(v, n, out=np.zeros_like(v), where=n > 0.0)
    return {"Vector": v}


def _hsv(ev, node):
    c = ev.vec(node, "color")
    hsv = rgb_to_hsv(c)
    hsv[:, 0] = np.mod(hsv[:, 0] + ev.float(node, "hue", 0.5) + 0.5, 1.0)
    hsv[:, 1] = np.clip(hsv[:, 1] * ev.float(node, "saturation", 1.0), 0.0, 1.0)
    hsv[:, 2] *= ev.float(node, "value", 1.0)
    fac = ev.float(node, "fac", 1.0)[:, None]
    return {"Color": np.maximum(fac * hsv_to_rgb(hsv) + (1.0 - fac) * c, 0.0)}


BLEND_MODES = ("MIX", "ADD", "MULTIPLY", "SUBTRACT", "DIFFERENCE", "DARKEN", "LIGHTEN", "EXCLUSION",
               "SCREEN", "OVERLAY", "DIVIDE", "LINEAR_LIGHT", "SOFT_LIGHT", "DODGE", "BURN", "HUE",
               "SATURATION", "VALUE", "COLOR")


def _mix_float(ev, node):
    t = ev.float(node, "fac", 0.5)
    if node.get("clamp_factor", True):
        t = np.clip(t, 0.0, 1.0)
    return {"Result": (1.0 - t) * ev.float(node, "a") + t * ev.float(node, "b")}


def _mix_vector(ev, node):
    t = ev.float(node, "fac", 0.5)
    if node.get("clamp_factor", True):
        t = np.clip(t, 0.0, 1.0)
    return {"Result": (1.0 - t[:, None]) * ev.vec(node, "a") + t[:, None] * ev.vec(node, "b")}


def _safe_divide(a, b):
    return np.where(b != 0.0, a / np.where(b != 0.0, b, 1.0), 0.0)


def _safe_power(a, b):
    bad = (a < 0.0) & (b != np.floor(b))
    with np.errstate(all="ignore"):
        return np.where(bad, 0.0, np.power(np.where(bad, 1.0, a), b))


MATH = {
    "ADD": lambda a, b, c: a + b, "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b, "DIVIDE": lambda a, b, c: _safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c, "POWER": lambda a, b, c: _safe_power(a, b),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0.0)), "ABSOLUTE": lambda a, b, c: np.abs(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b), "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "LESS_THAN": lambda a, b, c: (a < b).astype(np.float64),
    "GREATER_THAN": lambda a, b, c: (a > b).astype(np.float64),
    "SIGN": lambda a, b, c: np.sign(a), "ROUND": lambda a, b, c: np.floor(a + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a), "CEIL": lambda a, b, c: np.ceil(a),
    "TRUNC": lambda a, b, c: np.trunc(a), "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: np.where(b != 0.0, np.fmod(a, np.where(b != 0.0, b, 1.0)), 0.0),
    "FLOORED_MODULO": lambda a, b, c: np.where(b != 0.0, a - np.floor(_safe_divide(a, b)) * b, 0.0),
    "SINE": lambda a, b, c: np.sin(a), "COSINE": lambda a, b, c: np.cos(a),
    "SNAP": lambda a, b, c: np.floor(_safe_divide(a, b)) * b,
    "LOGARITHM": lambda a, b, c: _safe_log(a, b),
    "INVERSE_SQRT": lambda a, b, c: np.where(a > 0.0, 1.0 / np.sqrt(np.where(a > 0.0, a, 1.0)), 0.0),
    "EXPONENT": lambda a, b, c: np.exp(a),
    "RADIANS": lambda a, b, c: a * (np.pi / 180.0), "DEGREES": lambda a, b, c: a * (180.0 / np.pi),
    "TANGENT": lambda a, b, c: np.tan(a), "ARCSINE": lambda a, b, c: np.arcsin(np.clip(a, -1.0, 1.0)),
    "ARCCOSINE": lambda a, b, c: np.arccos(np.clip(a, -1.0, 1.0)), "ARCTANGENT": lambda a, b, c: np.arctan(a),
    "ARCTAN2": lambda a, b, c: np.arctan2(a, b), "SINH": lambda a, b, c: np.sinh(a),
    "COSH": lambda a, b, c: np.cosh(a), "TANH": lambda a, b, c: np.tanh(a),
    "COMPARE": lambda a, b, c: ((a == b) | (np.abs(a - b) <= np.maximum(c, FLT_EPSILON))).astype(np.float64),
    "WRAP": lambda a, b, c: _wrapf(a, b, c), "PINGPONG": lambda a, b, c: _pingpong(a, b),
    "SMOOTH_MIN": lambda a, b, c: _smooth_min(a, b, c), "SMOOTH_MAX": lambda a, b, c: -_smooth_min(-a, -b, c),
}


FLT_EPSILON = float(np.finfo(np.float32).eps)


def _safe_log(a, b):
    """log_b(a), 0 where a or b is not positive (Cycles' ``safe_logf``)."""
    ok = (a > 0.0) & (b > 0.0)
    return np.where(ok, _safe_divide(np.log(np.where(ok, a, 1.0)), np.log(np.where(ok, b, 2.0))), 0.0)


def _wrapf(value, high, low):
    """Cycles' ``wrapf``: ``value`` wrapped into [low, high)."""
    span = high - low
    return np.where(span != 0.0, value - span * np.floor(_safe_divide(value - low, span)), low)


def _pingpong(a, b):
    """Cycles' ``pingpongf``: ``a`` bounced between 0 and ``b``."""
    x = _safe_divide(a - b, b * 2.0)
    return np.where(b != 0.0, np.abs((x - np.floor(x)) * b * 2.0 - b), 0.0)


def _smooth_min(a, b, k):
    """Cycles' ``smoothminf``: the minimum, rounded over a distance ``k``."""
    h = _safe_divide(np.maximum(k - np.abs(a - b), 0.0), k)
    return np.where(k != 0.0, np.minimum(a, b) - h * h * h * k / 6.0, np.minimum(a, b))


def _math(ev, node):
    op = node.get("operation", "ADD")
    if op not in MATH:
        raise ProgramError(f"unsupported math operation {op!r}")
    with np.errstate(all="ignore"):
        v = MATH[op](ev.float(node, "a"), ev.float(node, "b"), ev.float(node, "c"))
    if node.get("clamp"):
        v = np.clip(v, 0.0, 1.0)
    return {"Value": v}


def _per_component(fn):
    """A vector operation applying the float one ``fn`` (a, b, c) to each component."""
    return lambda a, b, c, s: fn(a, b, c)


def _project(a, b):
    bb = dot(b, b)[:, None]
    return np.where(bb != 0.0, b * dot(a, b)[:, None] / np.where(bb != 0.0, bb, 1.0), 0.0)


def _reflect(a, b):
    n = normalize(b)
    return a - 2.0 * dot(n, a)[:, None] * n


def _refract(a, b, eta):
    n = normalize(b)
    d = dot(n, a)
    k = 1.0 - eta * eta * (1.0 - d * d)
    out = eta[:, None] * a - (eta * d + np.sqrt(np.maximum(k, 0.0)))[:, None] * n
    return np.where((k < 0.0)[:, None], 0.0, out)


# Blender's Vector Math node (Cycles' ``svm_vector_math``): (a, b, c, scale) -> vector, per
# operation; VECTOR_VALUES give a Value instead.
VECTOR_MATH = {
    "ADD": lambda a, b, c, s: a + b, "SUBTRACT": lambda a, b, c, s: a - b,
    "MULTIPLY": lambda a, b, c, s: a * b, "DIVIDE": lambda a, b, c, s: _safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c, s: a * b + c, "CROSS_PRODUCT": lambda a, b, c, s: np.cross(a, b),
    "PROJECT": lambda a, b, c, s: _project(a, b), "REFLECT": lambda a, b, c, s: _reflect(a, b),
    "REFRACT": lambda a, b, c, s: _refract(a, b, s),
    "FACEFORWARD": lambda a, b, c, s: np.where((dot(c, b) < 0.0)[:, None], a, -a),
    "SCALE": lambda a, b, c, s: a * s[:, None], "NORMALIZE": lambda a, b, c, s: normalize(a),
    "SNAP": _per_component(MATH["SNAP"]), "FLOOR": _per_component(MATH["FLOOR"]),
    "CEIL": _per_component(MATH["CEIL"]), "MODULO": _per_component(MATH["MODULO"]),
    "WRAP": _per_component(MATH["WRAP"]), "FRACTION": _per_component(MATH["FRACT"]),
    "ABSOLUTE": _per_component(MATH["ABSOLUTE"]), "POWER": _per_component(MATH["POWER"]),
    "SIGN": _per_component(MATH["SIGN"]), "MINIMUM": _per_component(MATH["MINIMUM"]),
    "MAXIMUM": _per_component(MATH["MAXIMUM"]), "SINE": _per_component(MATH["SINE"]),
    "COSINE": _per_component(MATH["COSINE"]), "TANGENT": _per_component(MATH["TANGENT"]),
}
VECTOR_VALUES = {
    "DOT_PRODUCT": lambda a, b: dot(a, b), "DISTANCE": lambda a, b: length(a - b),
    "LENGTH": lambda a, b: length(a),
}


def _vector_math(ev, node):
    op = node.get("operation", "ADD")
    a, b, c = ev.vec(node, "a"), ev.vec(node, "b"), ev.vec(node, "c")
    zeros_v, zeros_f = np.zeros((ev.k, 3)), np.zeros(ev.k)
    with np.errstate(all="ignore"):
        if op in VECTOR_VALUES:
            return {"Vector": zeros_v, "Value": VECTOR_VALUES[op](a, b)}
        return {"Vector": VECTOR_MATH[op](a, b, c, ev.float(node, "scale", 1.0)), "Value": zeros_f}


def _clamp(ev, node):
    v, lo, hi = ev.float(node, "value"), ev.float(node, "min", 0.0), ev.float(node, "max", 1.0)
    if node.get("clamp_type", "MINMAX") == "RANGE":
        lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    return {"Result": np.minimum(np.maximum(v, lo), hi)}


def _curve_lookup(table, f, extrapolate):
    """Cycles' ``rgb_ramp_lookup`` of (N, c) ``table`` at (k, c) positions ``f`` in [0, 1],
    interpolated, and past the ends along the end segments' slopes with ``extrapolate``."""
    size = len(table)
    out = _table_lookup(table, f)
    if extrapolate:
        low, high = f < 0.0, f > 1.0
        out = np.where(low, table[0] + (table[0] - table[1]) * (-f) * (size - 1), out)
        out = np.where(high, table[-1] + (table[-1] - table[-2]) * (f - 1.0) * (size - 1), out)
    return out


def _curves(ev, node):
    """RGB Curves / Vector Curves (``svm_node_curves``): each component through its column of
    ``table``, sampled over [min_x, max_x], mixed with the input by ``fac``."""
    c = ev.vec(node, "color")
    lo, hi = node.get("min_x", 0.0), node.get("max_x", 1.0)
    f = _safe_divide(c - lo, np.full_like(c, hi - lo))
    curved = _curve_lookup(np.asarray(node["table"], np.float64), f, node.get("extrapolate", True))
    t = ev.float(node, "fac", 1.0)[:, None]
    return {"Color": (1.0 - t) * c + t * curved}


def _float_curve(ev, node):
    """Float Curve (``svm_node_curve``): the value through ``table`` over [min_x, max_x]."""
    v = ev.float(node, "value")
    lo, hi = node.get("min_x", 0.0), node.get("max_x", 1.0)
    f = _safe_divide(v - lo, np.full_like(v, hi - lo))[:, None]
    table = np.asarray(node["table"], np.float64)[:, None]
    curved = _curve_lookup(table, f, node.get("extrapolate", True))[:, 0]
    t = ev.float(node, "fac", 1.0)
    return {"Value": (1.0 - t) * v + t * curved}


def _map_range(ev, node):
    v = ev.float(node, "value")
    f0, f1 = ev.float(node, "from_min", 0.0), ev.float(node, "from_max", 1.0)
    t0, t1 = ev.float(node, "to_min", 0.0), ev.float(node, "to_max", 1.0)
    f = _safe_divide(v - f0, f1 - f0)
    kind = node.get("interpolation", "LINEAR")
    if kind == "STEPPED":
        steps = ev.float(node, "steps", 4.0)
        f = np.where(steps > 0.0, np.floor(f * (steps + 1.0)) / np.where(steps > 0.0, steps, 1.0), 0.0)
    elif kind == "SMOOTHSTEP":
        f = np.clip(f, 0.0, 1.0)
        f = (3.0 - 2.0 * f) * f * f
    elif kind == "SMOOTHERSTEP":
        f = np.clip(f, 0.0, 1.0)
        f = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
    out = t0 + f * (t1 - t0)
    if node.get("clamp", True) and kind in ("LINEAR", "STEPPED"):
        out = np.where(t0 > t1, np.clip(out, t1, t0), np.clip(out, t0, t1))
    return {"Result": out}


def _metal(ev, node):
    """The mean F82-tint Fresnel reflectance of a metal of base colour ``color`` and edge ``tint``
    (the colour the core gives a textured metal's glossy lobe where it cannot take the curve of
    each hit's F0: a textured edge tint, or a metal mixed with other glossy lobes;
    ``bsdf.metal_fresnel``)."""
    return {"Color": metal_fresnel(ev.vec(node, "color"), ev.vec(node, "tint", (1.0, 1.0, 1.0)))}


def _node_normal(ev, node):
    """(k, 3) a Fresnel, Layer Weight or Ambient Occlusion node's normal: its own, else the shading
    normal on the ray's side (Cycles' N)."""
    return ev.vec(node, "normal") if "normal" in node else ev.attrs.get("world_normal")


def bump_edges(scene, prims):
    """(e1, e2) (k, 3) float64 the edges from corner 0 of triangles ``prims``, along which a bump is
    taken: on the undisplaced surface of a truly displaced scene (``Scene.undisplaced``)."""
    surface = scene.vertices if scene.undisplaced is None else scene.undisplaced
    corners = surface.take(scene.triangles.take(prims, axis=0), axis=0).astype(np.float64)
    return corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]


def bend_normals(n0, dpdu, dpdv, hu, hv, strength, distance):
    """(k, 3) Cycles' Bump formula: unit normals ``n0`` bent by a height's derivatives ``hu``, ``hv``
    along a parametrisation (u, v) of the surface (dP/du ``dpdu``, dP/dv ``dpdv``): with
    R_u = dP/dv x N, R_v = N x dP/du and det = dP/du . R_u, N' = normalize(|det| N - d sign(det)
    (h_u R_u + h_v R_v)) for the ``distance`` d, then normalize(s N' + (1 - s) N) for the
    ``strength`` s (the result does not depend on the parametrisation); zero or NaN rows keep N."""
    ru, rv = np.cross(dpdv, n0), np.cross(n0, dpdu)
    det = dot(dpdu, ru)
    along = hu[:, None] * ru + hv[:, None] * rv
    n = normalize(np.abs(det)[:, None] * n0 - (distance * np.sign(det))[:, None] * along)
    s = np.maximum(strength, 0.0)[:, None]
    n = normalize(s * n + (1.0 - s) * n0)
    return _keep_where_bad(n, n0)


def bumped_normals(attrs, height, images, n0, strength, distance, step=None, sky_cache=None):
    """(k, 3) unit normals ``n0`` at the hits ``attrs`` bent by the height program ``height``
    (:func:`bend_normals`): its derivatives from forward differences of ``step`` world units (None:
    a thousandth of each edge) along the triangles' edges (:func:`bump_edges`), evaluated at the
    undisplaced surface of a truly displaced scene, as Cycles evaluates a bump there."""
    scene, prims = attrs.scene, attrs.prim_ids
    e1, e2 = bump_edges(scene, prims)
    if step is None:
        s1 = s2 = np.full(len(prims), 1e-3)
    else:
        s1 = step / np.maximum(np.linalg.norm(e1, axis=1), 1e-300)
        s2 = step / np.maximum(np.linalg.norm(e2, axis=1), 1e-300)
    b = [np.asarray(w, np.float64).reshape(-1) for w in attrs.bary]
    x = np.asarray(attrs.positions, np.float64)
    if scene.undisplaced is not None:
        x = interpolate_corners(scene.undisplaced.take(scene.triangles.take(prims, axis=0), axis=0)
                                .astype(np.float64), attrs.bary)
    heights = []
    for d1, d2 in ((0.0, 0.0), (s1, 0.0), (0.0, s2)):
        d1, d2 = np.broadcast_to(d1, (len(prims),)), np.broadcast_to(d2, (len(prims),))
        shifted = ((b[0] - d1 - d2)[:, None], (b[1] + d1)[:, None], (b[2] + d2)[:, None])
        moved = x + d1[:, None] * e1 + d2[:, None] * e2
        h = evaluate(height, HitAttributes(scene, prims, shifted, moved, attrs.rays, attrs.accel), images,
                     sky_cache=sky_cache)
        heights.append(h @ LUMINANCE if h.ndim == 2 else h)
    hu = np.nan_to_num((heights[1] - heights[0]) / s1)
    hv = np.nan_to_num((heights[2] - heights[0]) / s2)
    return bend_normals(n0, e1, e2, hu, hv, strength, distance)


def tangent_space_normals(c, strength, n0, frame):
    """(k, 3) Cycles' Normal Map in tangent space (``svm_node_normal_map``): colours ``c`` = 2 rgb
    - 1, (c_x, c_y) times the ``strength`` s and c_z blended from 1 by min(s, 1), give
    normalize(c_x T + c_y B + c_z N0) with T the tangent of ``frame`` (k, 4), B = w (N0 x T) with
    its sign w, and N0 the unit shading normals ``n0``; no frame (zero tangent) or a degenerate
    result keeps N0."""
    t = frame[:, :3]
    b = frame[:, 3:4] * np.cross(n0, t)
    cz = 1.0 + (c[:, 2] - 1.0) * np.minimum(strength, 1.0)
    n = normalize((c[:, 0] * strength)[:, None] * t + (c[:, 1] * strength)[:, None] * b + cz[:, None] * n0)
    no_frame = ~(np.abs(t).sum(axis=1) > 0)
    n[no_frame] = n0[no_frame]
    return _keep_where_bad(n, n0)


def spatial_normals(c, strength, n0):
    """(k, 3) Cycles' Normal Map in object or world space: N = normalize(c) for the map's normal
    ``c`` already in world space, then normalize(N0 + (N - N0) s) where the ``strength`` s is not
    1; a degenerate result keeps N0."""
    n = normalize(c)
    blend = strength != 1.0
    if blend.any():
        s = np.maximum(strength, 0.0)[:, None]
        n = np.where(blend[:, None], normalize(n0 + (n - n0) * s), n)
    return _keep_where_bad(n, n0)


def _keep_where_bad(n, fallback):
    """``n`` with its zero or non-finite rows replaced by ``fallback``'s."""
    bad = ~np.isfinite(n).all(axis=1) | (np.abs(n).sum(axis=1) == 0.0)
    n[bad] = fallback[bad]
    return n


def _bump(ev, node):
    """Blender's Bump node as a program (its Normal, :func:`bumped_normals`) about the node's
    normal or the shading normal, with differences of ``BUMP_STEP`` times the object's size (a
    thousandth of an edge without the scene's acceleration structure); a negative distance is an
    inverted bump.  Where there is no triangle to step along (a world's directions) the normal is
    returned as it is, as it is for a constant height (an unlinked Height: no slope)."""
    attrs = ev.attrs
    n0 = normalize(_node_normal(ev, node))
    if not isinstance(attrs, HitAttributes) or not isinstance(node.get("height"), dict):
        return {"Normal": n0}
    step = None if attrs.accel is None else BUMP_STEP * attrs.accel.object_sizes(attrs.prim_ids)
    return {"Normal": bumped_normals(attrs, node["height"], ev.images, n0, ev.float(node, "strength", 1.0),
                                     ev.float(node, "distance", 1.0), step, ev.sky_cache)}


NORMAL_MAP_SPACES = ("TANGENT", "OBJECT", "WORLD", "BLENDER_OBJECT", "BLENDER_WORLD")


def _normal_map(ev, node):
    """Blender's Normal Map node as a program (its Normal): :func:`tangent_space_normals` in the UV
    map's tangent frame (``Scene.tangents``; without one, the surface's normal), or
    :func:`spatial_normals` in the object's or world space (Blender's variants flip y and z),
    about the shading normal of the triangle's front, turned to the ray's side on a back face as
    Cycles turns it; a world's directions keep their normal."""
    attrs = ev.attrs
    c = 2.0 * ev.vec(node, "color", (0.5, 0.5, 1.0)) - 1.0
    strength = np.maximum(ev.float(node, "strength", 1.0), 0.0)
    if not isinstance(attrs, HitAttributes):
        return {"Normal": normalize(attrs.get("world_normal"))}
    s = attrs.scene
    n0 = attrs._front("world_normal")
    space = node.get("space", "TANGENT")
    if space == "TANGENT":
        n = n0.copy()
        if s.tangents is not None:
            corners = s.tangents.take(attrs.prim_ids, axis=0).astype(np.float64)
            n = tangent_space_normals(c, strength, n0, interpolate_corners(corners, attrs.bary))
    else:
        if space.startswith("BLENDER_"):
            c[:, 1:] *= -1.0                                  # ("strange blender convention")
        if space.endswith("OBJECT") and s.object_ids is not None:
            objects = s.object_from_world.take(s.object_ids.take(attrs.prim_ids), axis=0)
            c = np.einsum("kji,kj->ki", objects[:, :, :3], c)
        n = spatial_normals(c, strength, n0)
    back = attrs.get("backfacing")[:, :1] > 0.5
    return {"Normal": np.where(back, -n, n)}


def _view_cosine(ev, node):
    """(k,) the cosine of Incoming with the node's normal (:func:`_node_normal`), at most 1, and
    (k,) whether the ray meets the back (``RAY``)."""
    back = ev.attrs.get("backfacing")[:, 0] > 0.5
    return np.minimum(np.abs(dot(ev.attrs.get("incoming"), _node_normal(ev, node))), 1.0), back


def _fresnel(ev, node):
    """Cycles' Fresnel node: the IOR's reflectance at the view cosine (its inverse on a back face;
    Cycles' ``fresnel_dielectric_cos`` is ``sampling.fresnel_dielectric``)."""
    cos, back = _view_cosine(ev, node)
    eta = np.maximum(ev.float(node, "ior", 1.5), 1e-5)
    return {"Fac": fresnel_dielectric(cos, np.where(back, 1.0 / eta, eta))[0]}


def _layer_weight(ev, node):
    """Cycles' ``svm_node_layer_weight``: Fresnel of the IOR 1 / (1 - Blend) (its inverse on a back
    face) and Facing 1 - |cos|^e, e = 2 Blend below 0.5, else 0.5 / (1 - Blend)."""
    cos, back = _view_cosine(ev, node)
    blend = ev.float(node, "blend", 0.5)
    eta = np.maximum(1.0 - blend, 1e-5)
    edge = np.clip(blend, 0.0, 1.0 - 1e-5)
    power = np.where(blend == 0.5, 1.0, np.where(edge < 0.5, 2.0 * edge, 0.5 / (1.0 - edge)))
    return {"Fresnel": fresnel_dielectric(cos, np.where(back, eta, 1.0 / eta))[0],
            "Facing": 1.0 - cos ** power}


def _ao(ev, node):
    """Cycles' Ambient Occlusion node (``svm_node_ao``): AO the unoccluded share of ``samples`` rays
    within ``distance`` about the normal (the shading normal on the ray's side unless given; its
    opposite ``inside``), Color the colour times it (``HitAttributes.occlusion``; 1 for attributes
    that cannot cast rays: a world, stand-in points)."""
    n = _node_normal(ev, node)
    n = normalize(-n if node.get("inside", False) else n)
    occlusion = getattr(ev.attrs, "occlusion", None)
    ao = np.ones(ev.k)
    if occlusion is not None:
        ao = occlusion(n, ev.float(node, "distance", 1.0), int(node.get("samples", 16)),
                       bool(node.get("only_local", False)))
    return {"Color": ev.vec(node, "color", (1.0, 1.0, 1.0)) * ao[:, None], "AO": ao}


def _bevel(ev, node):
    """Cycles' Bevel node (``svm_node_bevel``): the bevelled normal (``HitAttributes.bevel``; the
    shading normal for attributes that cannot cast rays), with a given normal that normal bent
    as much: normalize(normal + bevel - N)."""
    n = ev.attrs.get("world_normal")
    bevel = getattr(ev.attrs, "bevel", None)
    out = n if bevel is None else bevel(ev.float(node, "radius", 0.05), int(node.get("samples", 4)))
    if "normal" in node:
        out = normalize(ev.vec(node, "normal") + (out - n))
    return {"Normal": out}


def _light_path(ev, node):
    """The Light Path node's outputs (``LIGHT_PATH``) of the rays that meet the hits (``Rays.path``)."""
    path = ev.attrs.get("light_path")
    return {name: path[:, i] for i, name in enumerate(LIGHT_PATH)}


def _invert(ev, node):
    t = ev.float(node, "fac", 1.0)[:, None]
    c = ev.vec(node, "color")
    return {"Color": (1.0 - t) * c + t * (1.0 - c)}


def _gamma(ev, node):
    c = ev.vec(node, "color")
    g = ev.float(node, "gamma", 1.0)[:, None]
    with np.errstate(all="ignore"):
        return {"Color": np.where(c > 0.0, np.power(np.maximum(c, 0.0), g), c)}


def _bright_contrast(ev, node):
    a = 1.0 + ev.float(node, "contrast")[:, None]
    b = ev.float(node, "bright")[:, None] - (a - 1.0) * 0.5
    return {"Color": np.maximum(a * ev.vec(node, "color") + b, 0.0)}


def _separate(ev, node):
    v = ev.vec(node, "vector")
    return {"X": v[:, 0], "Y": v[:, 1], "Z": v[:, 2], "Red": v[:, 0], "Green": v[:, 1], "Blue": v[:, 2]}


def _combine(ev, node):
    return {"Vector": np.stack([ev.float(node, "x"), ev.float(node, "y"), ev.float(node, "z")], axis=1)}


def _gray(ev, node):
    return {"Value": ev.vec(node, "color") @ LUMINANCE}


def _average(ev, node):
    return {"Value": ev.vec(node, "vector").mean(axis=1)}


# The CIE 1931 colour matching functions x, y, z at 380, 385, ..., 780 nm (the table Cycles'
# Wavelength node interpolates, as in John Walker's public-domain specrend).
CIE_XYZ = np.array([
    0.0014, 0.0000, 0.0065, 0.0022, 0.0001, 0.0105, 0.0042, 0.0001, 0.0201, 0.0076, 0.0002, 0.0362,
    0.0143, 0.0004, 0.0679, 0.0232, 0.0006, 0.1102, 0.0435, 0.0012, 0.2074, 0.0776, 0.0022, 0.3713,
    0.1344, 0.0040, 0.6456, 0.2148, 0.0073, 1.0391, 0.2839, 0.0116, 1.3856, 0.3285, 0.0168, 1.6230,
    0.3483, 0.0230, 1.7471, 0.3481, 0.0298, 1.7826, 0.3362, 0.0380, 1.7721, 0.3187, 0.0480, 1.7441,
    0.2908, 0.0600, 1.6692, 0.2511, 0.0739, 1.5281, 0.1954, 0.0910, 1.2876, 0.1421, 0.1126, 1.0419,
    0.0956, 0.1390, 0.8130, 0.0580, 0.1693, 0.6162, 0.0320, 0.2080, 0.4652, 0.0147, 0.2586, 0.3533,
    0.0049, 0.3230, 0.2720, 0.0024, 0.4073, 0.2123, 0.0093, 0.5030, 0.1582, 0.0291, 0.6082, 0.1117,
    0.0633, 0.7100, 0.0782, 0.1096, 0.7932, 0.0573, 0.1655, 0.8620, 0.0422, 0.2257, 0.9149, 0.0298,
    0.2904, 0.9540, 0.0203, 0.3597, 0.9803, 0.0134, 0.4334, 0.9950, 0.0087, 0.5121, 1.0000, 0.0057,
    0.5945, 0.9950, 0.0039, 0.6784, 0.9786, 0.0027, 0.7621, 0.9520, 0.0021, 0.8425, 0.9154, 0.0018,
    0.9163, 0.8700, 0.0017, 0.9786, 0.8163, 0.0014, 1.0263, 0.7570, 0.0011, 1.0567, 0.6949, 0.0010,
    1.0622, 0.6310, 0.0008, 1.0456, 0.5668, 0.0006, 1.0026, 0.5030, 0.0003, 0.9384, 0.4412, 0.0002,
    0.8544, 0.3810, 0.0002, 0.7514, 0.3210, 0.0001, 0.6424, 0.2650, 0.0000, 0.5419, 0.2170, 0.0000,
    0.4479, 0.1750, 0.0000, 0.3608, 0.1382, 0.0000, 0.2835, 0.1070, 0.0000, 0.2187, 0.0816, 0.0000,
    0.1649, 0.0610, 0.0000, 0.1212, 0.0446, 0.0000, 0.0874, 0.0320, 0.0000, 0.0636, 0.0232, 0.0000,
    0.0468, 0.0170, 0.0000, 0.0329, 0.0119, 0.0000, 0.0227, 0.0082, 0.0000, 0.0158, 0.0057, 0.0000,
    0.0114, 0.0041, 0.0000, 0.0081, 0.0029, 0.0000, 0.0058, 0.0021, 0.0000, 0.0041, 0.0015, 0.0000,
    0.0029, 0.0010, 0.0000, 0.0020, 0.0007, 0.0000, 0.0014, 0.0005, 0.0000, 0.0010, 0.0004, 0.0000,
    0.0007, 0.0002, 0.0000, 0.0005, 0.0002, 0.0000, 0.0003, 0.0001, 0.0000, 0.0002, 0.0001, 0.0000,
    0.0002, 0.0001, 0.0000, 0.0001, 0.0000, 0.0000, 0.0001, 0.0000, 0.0000, 0.0001, 0.0000, 0.0000,
    0.0000, 0.0000, 0.0000]).reshape(81, 3)


def _xyz_to_rec709():
    """(3, 3) CIE XYZ to linear Rec. 709 (its primaries and D65 white; Cycles' Wavelength node
    matches it to 2e-6, where an adaptation from Blender's XYZ role, illuminant E, was 0.08 off)."""
    def xyz(x, y):
        return np.array([x / y, 1.0, (1.0 - x - y) / y])
    primaries = np.stack([xyz(0.64, 0.33), xyz(0.30, 0.60), xyz(0.15, 0.06)], axis=1)
    rgb_to_xyz = primaries * np.linalg.solve(primaries, xyz(0.3127, 0.3290))
    return np.linalg.inv(rgb_to_xyz)


XYZ_TO_RGB = _xyz_to_rec709()


def _wavelength(ev, node):
    """Cycles' ``svm_node_wavelength``: the colour matching functions at the wavelength (nm; 0 off
    380 to 780), in linear Rec. 709, over 2.52, clamped at 0."""
    ii = (ev.float(node, "wavelength", 500.0) - 380.0) / 5.0
    i = np.trunc(ii)
    inside = (i >= 0.0) & (i < 80.0)
    k = np.where(inside, i, 0.0).astype(np.int64)
    t = (ii - i)[:, None]
    xyz = np.where(inside[:, None], (1.0 - t) * CIE_XYZ[k] + t * CIE_XYZ[k + 1], 0.0)
    return {"Color": np.maximum(xyz @ XYZ_TO_RGB.T / 2.52, 0.0)}


# Cycles' fit of the Planckian locus in Rec. 709 (``svm_math_blackbody_color_rec709``, Blender
# 4.x/5.x, normalised to luminance 1): R, G = a / t + b t + c, B = ((a t + b) t + c) t + d, per
# range of temperatures from these knots.
BLACKBODY_KNOTS = np.array([965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0])
BLACKBODY_R = np.array([[1.61919106e+03, -2.05010916e-03, 5.02995757e+00],
                        [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
                        [3.34143193e+03, -4.86551192e-04, 1.76486769e+00],
                        [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
                        [4.67028036e+03, 2.91258199e-05, 1.26703442e-01],
                        [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
                        [3.78717450e+03, 9.35907826e-06, 3.99075871e-01]], np.float32)
BLACKBODY_G = np.array([[-4.88999748e+02, 6.04330754e-04, -7.55807526e-02],
                        [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
                        [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01],
                        [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
                        [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00],
                        [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
                        [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00]], np.float32)
BLACKBODY_B = np.array([[5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03],
                        [2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02],
                        [-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02],
                        [-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01],
                        [-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02],
                        [-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01],
                        [6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01]], np.float32)
BLACKBODY_HOT = np.array([0.8262954810464208, 0.9945080501520986, 1.566307710274283])     # >= 12000 K
BLACKBODY_COLD = np.array([5.413294490189271, -0.20319390035873933, -0.0822535242887164])  # < 800 K


def blackbody(t):
    """(k, 3) Rec. 709 colour of temperatures ``t`` (k,) in kelvin (Cycles' Blackbody node)."""
    t = np.asarray(t, np.float64)
    i = np.searchsorted(BLACKBODY_KNOTS, t, side="right")
    r, g, b = (table.astype(np.float64).take(i, axis=0) for table in (BLACKBODY_R, BLACKBODY_G, BLACKBODY_B))
    with np.errstate(all="ignore"):
        inv = 1.0 / t
        out = np.stack([r[:, 0] * inv + r[:, 1] * t + r[:, 2], g[:, 0] * inv + g[:, 1] * t + g[:, 2],
                        ((b[:, 0] * t + b[:, 1]) * t + b[:, 2]) * t + b[:, 3]], axis=1)
    out = np.where((t >= 12000.0)[:, None], BLACKBODY_HOT, out)
    return np.where((t < 800.0)[:, None] | np.isnan(t)[:, None], BLACKBODY_COLD, out)


def _blackbody(ev, node):
    return {"Color": blackbody(ev.float(node, "temperature", 1500.0))}


def _unpremultiply(ev, node):
    """Cycles' ``color_unpremultiply``: colour / alpha where 0 < alpha < 1."""
    c = ev.vec(node, "color")
    a = ev.float(node, "alpha", 1.0)[:, None]
    partial = (a > 0.0) & (a < 1.0)
    return {"Color": np.where(partial, c / np.where(partial, a, 1.0), c)}


def _splat(ev, node):
    return {"Vector": np.repeat(ev.float(node, "value")[:, None], 3, axis=1)}


OPS = {"attribute": _attribute, "affine": _affine, "checker": _checker, "gradient": _gradient,
       "noise": _noise, "voronoi": _voronoi, "wave": _wave, "brick": _brick, "magic": _magic,
       "white_noise": _white_noise, "gabor": _gabor, "image": _image, "environment": _environment,
       "sky": _sky, "ramp": _ramp,
       "mix_color": _mix_color, "mix_float": _mix_float, "mix_vector": _mix_vector, "math": _math,
       "map_range": _map_range, "metal": _metal, "invert": _invert, "gamma": _gamma, "hsv": _hsv,
       "bright_contrast": _bright_contrast, "separate": _separate, "combine": _combine, "gray": _gray,
       "color_space": _color_space, "vector_transform": _vector_transform, "wavelength": _wavelength,
       "average": _average, "splat": _splat, "blackbody": _blackbody, "unpremultiply": _unpremultiply,
       "vector_math": _vector_math, "clamp": _clamp, "curves": _curves, "float_curve": _float_curve,
       "fresnel": _fresnel, "layer_weight": _layer_weight, "ao": _ao, "bevel": _bevel,
       "light_path": _light_path, "bump": _bump, "normal_map": _normal_map}
OUTPUTS = {"attribute": ("Vector",), "affine": ("Vector",), "checker": ("Color", "Fac"),
           "gradient": ("Color", "Fac"), "noise": ("Fac", "Color"),
           "voronoi": ("Distance", "Color", "Position", "W", "Radius"), "wave": ("Color", "Fac"),
           "brick": ("Color", "Fac"), "magic": ("Color", "Fac"), "white_noise": ("Value", "Color"),
           "gabor": ("Value", "Phase", "Intensity"),
           "image": ("Color", "Alpha"), "environment": ("Color", "Alpha"), "sky": ("Color",),
           "ramp": ("Color", "Alpha"), "mix_color": ("Result",), "mix_float": ("Result",),
           "mix_vector": ("Result",), "math": ("Value",), "map_range": ("Result",), "metal": ("Color",),
           "invert": ("Color",),
           "gamma": ("Color",), "hsv": ("Color",), "bright_contrast": ("Color",), "color_space": ("Color",),
           "vector_transform": ("Vector",), "wavelength": ("Color",),
           "separate": ("X", "Y", "Z", "Red", "Green", "Blue"), "combine": ("Vector",),
           "gray": ("Value",), "average": ("Value",), "splat": ("Vector",), "blackbody": ("Color",),
           "unpremultiply": ("Color",), "vector_math": ("Vector", "Value"), "clamp": ("Result",),
           "curves": ("Color",), "float_curve": ("Value",), "fresnel": ("Fac",),
           "layer_weight": ("Fresnel", "Facing"), "ao": ("Color", "AO"), "bevel": ("Normal",),
           "light_path": LIGHT_PATH, "bump": ("Normal",), "normal_map": ("Normal",)}
REQUIRED = {"attribute": ("name",), "affine": ("matrix",), "image": ("texture",),
            "color_space": ("conversion",),
            "environment": ("texture",), "bump": ("height",), "ramp": ("table",), "curves": ("table",),
            "float_curve": ("table",)}
GRADIENT_TYPES = ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "QUADRATIC_SPHERE", "SPHERICAL")
# Settings chosen from a list (the others are numbers, colours or nodes).
CHOICES = {
    ("attribute", "name"): ATTRIBUTES, ("mix_color", "blend"): BLEND_MODES, ("math", "operation"): MATH,
    ("gradient", "gradient_type"): GRADIENT_TYPES, ("noise", "noise_type"): _noise_module.NOISE_TYPES,
    ("noise", "dimensions"): _noise_module.DIMENSIONS, ("voronoi", "feature"): _voronoi_module.FEATURES,
    ("voronoi", "metric"): _voronoi_module.METRICS, ("voronoi", "dimensions"): _voronoi_module.DIMENSIONS,
    ("map_range", "interpolation"): ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"),
    ("wave", "wave_type"): _patterns.WAVE_TYPES, ("wave", "bands_direction"): _patterns.BANDS_DIRECTIONS,
    ("wave", "rings_direction"): _patterns.RINGS_DIRECTIONS,
    ("wave", "wave_profile"): _patterns.WAVE_PROFILES,
    ("white_noise", "dimensions"): _patterns.DIMENSIONS, ("gabor", "gabor_type"): _patterns.GABOR_TYPES,
    ("normal_map", "space"): NORMAL_MAP_SPACES,
    ("sky", "sky_type"): ("MULTIPLE_SCATTERING", "SINGLE_SCATTERING", "PREETHAM"),
    ("image", "extension"): ("REPEAT", "EXTEND", "CLIP", "MIRROR"),
    ("image", "interpolation"): ("Linear", "Closest", "Cubic"),
    ("image", "projection"): ("FLAT", "BOX", "SPHERE", "TUBE"),
    ("environment", "projection"): ("EQUIRECTANGULAR", "MIRROR_BALL"),
    ("vector_math", "operation"): tuple(VECTOR_MATH) + tuple(VECTOR_VALUES),
    ("clamp", "clamp_type"): ("MINMAX", "RANGE"), ("color_space", "conversion"): tuple(COLOR_SPACES),
    ("vector_transform", "type"): ("POINT", "VECTOR", "NORMAL"),
    ("vector_transform", "convert_from"): ("WORLD", "OBJECT", "CAMERA"),
    ("vector_transform", "convert_to"): ("WORLD", "OBJECT", "CAMERA")}
# Array settings and their shapes (None: N >= 2).
ARRAYS = {"ramp": {"table": (None, 4)}, "affine": {"matrix": (3, 3), "pre": (3,), "post": (3,)},
          "sky": {"sun_direction": (3,)}, "curves": {"table": (None, 3)}, "float_curve": {"table": (None,)}}

"""True displacement (Blender's Displacement Method Displacement Only, or Displacement and Bump):
the vertices of materials with a ``Materials.displacement_program`` move along their normal before
a render, as Cycles' ``GeometryManager::displace`` moves them.

Each vertex is evaluated once, at the corner of the first triangle (in triangle order) of such a
material that uses it, with that corner's shading normal (a flat face's normal) as Cycles sets up
its displacement shader there; the program gives the offset along it, in the object's space
(``Scene.object_from_world``: the object-space normal scaled back into the world) or in world units
(``DISPLACE_WORLD``); with ``DISPLACE_VECTOR`` it gives the world offset itself (a Vector
Displacement).  Displacement Only then turns the shading normals with the surface: each
corner's normal plus the change of its vertex's normal (the normalised sum of the unit normals of
the triangles around it) from before to after, normalised (Cycles' corner-normal delta, which for a
smooth mesh is the new vertex normal).  Displacement and Bump keeps them (``DISPLACE_KEEPS_NORMALS``:
its bump bends them).  ``Scene.undisplaced`` keeps the old vertices for Generated coordinates.
Offsets that are not finite are 0 and larger ones than ``OFFSET_LIMIT`` scene sizes are clamped.
"""
from __future__ import annotations

import numpy as np

from .bsdf import Textures
from .procedural import LUMINANCE, HitAttributes, evaluate
from .sampling import inverse, normalize
from .scene import DISPLACE_KEEPS_NORMALS, DISPLACE_VECTOR, DISPLACE_WORLD

# The largest offset, in sizes of the undisplaced scene (its bounds' largest side).
OFFSET_LIMIT = 10.0


def displace(scene, sky_cache=None):
    """``scene`` with its truly displaced materials' vertices moved (and shading normals turned),
    or ``scene`` itself when no material displaces (``sky_cache``: ``procedural.evaluate``'s)."""
    mats = scene.materials
    programs = mats.displacement_program
    if programs is None or not (programs >= 0).any() or scene.triangle_count == 0:
        return scene
    tri_program = programs.take(scene.material_ids)
    displaced = np.flatnonzero(tri_program >= 0)
    if len(displaced) == 0:
        return scene
    corners = scene.triangles.take(displaced, axis=0).ravel()
    vertices, first = np.unique(corners, return_index=True)      # each vertex's first corner
    prims, corner = displaced.take(first // 3), first % 3
    bary = tuple(np.asarray(corner == k, np.float64)[:, None] for k in range(3))
    old = np.asarray(scene.vertices, np.float64)
    facets = _facet_normals(old, scene.triangles)
    normal = (facets.take(prims, axis=0) if scene.shading_normals is None
              else normalize(scene.shading_normals[prims, corner].astype(np.float64)))
    attrs = HitAttributes(scene, prims, bary, old.take(vertices, axis=0))
    offset, vector = np.zeros(len(vertices)), np.zeros((len(vertices), 3))
    images = Textures(scene.textures).images
    vertex_program = tri_program.take(prims)
    for p in np.unique(vertex_program):
        sel = np.flatnonzero(vertex_program == p)
        value = evaluate(mats.programs[p], _subset(attrs, sel), images, sky_cache=sky_cache)
        offset[sel] = value @ LUMINANCE if value.ndim == 2 else value
        vector[sel] = value if value.ndim == 2 else value[:, None] * normal.take(sel, axis=0)
    # Not finite: 0 (Cycles' ensure_finite); beyond OFFSET_LIMIT scene sizes: clamped, so that a
    # runaway height leaves the rest of the scene its scale (ray offsets, gather radii).
    lo, hi = scene.bounds()
    limit = OFFSET_LIMIT * float(max(np.max(hi - lo), 1e-6))
    offset = np.clip(np.nan_to_num(offset, nan=0.0, posinf=0.0, neginf=0.0), -limit, limit)
    vector = np.nan_to_num(vector, nan=0.0, posinf=0.0, neginf=0.0)
    length = np.linalg.norm(vector, axis=1, keepdims=True)
    vector *= np.minimum(1.0, limit / np.maximum(length, 1e-300))
    flags = mats.displacement_flags.take(scene.material_ids.take(prims))
    step = normal * offset[:, None]
    in_object = (flags & (DISPLACE_WORLD | DISPLACE_VECTOR)) == 0
    if in_object.any() and scene.object_ids is not None:
        rows = np.flatnonzero(in_object)
        objects = scene.object_ids.take(prims.take(rows))
        to_world = inverse(np.asarray(scene.object_from_world, np.float64)[objects, :, :3])
        # The object-space normal (the world normal through the inverse transpose), scaled back.
        n_object = normalize(np.einsum("kji,kj->ki", to_world, normal.take(rows, axis=0)))
        step[rows] = np.einsum("kij,kj->ki", to_world, n_object * offset.take(rows)[:, None])
    as_vector = np.flatnonzero(flags & DISPLACE_VECTOR)
    step[as_vector] = vector[as_vector]
    new = old.copy()
    new[vertices] += step
    out = scene.replace(vertices=new.astype(np.float32), undisplaced=np.asarray(scene.vertices, np.float32))
    turn = (flags & DISPLACE_KEEPS_NORMALS) == 0
    if scene.shading_normals is None or not turn.any():
        return out
    # Displacement Only: the corners' normals turn with their vertices' normals.
    moved = np.zeros(len(old), bool)
    moved[vertices.take(np.flatnonzero(turn))] = True
    before = _vertex_normals(facets, scene.triangles, len(old))
    after = _vertex_normals(_facet_normals(new, scene.triangles), scene.triangles, len(old))
    touched = np.flatnonzero(moved.take(scene.triangles).any(axis=1))
    v = scene.triangles.take(touched, axis=0)
    normals = scene.shading_normals.astype(np.float64).copy()
    normals[touched] = normalize((normals[touched] + after.take(v, axis=0) - before.take(v, axis=0))
                                 .reshape(-1, 3)).reshape(-1, 3, 3)
    return out.replace(shading_normals=normals.astype(np.float32))


def _subset(attrs, rows):
    """The hits ``rows`` of ``attrs`` (a fresh :class:`HitAttributes`)."""
    bary = tuple(b.take(rows, axis=0) for b in attrs.bary)
    return HitAttributes(attrs.scene, attrs.prim_ids.take(rows), bary, attrs.positions.take(rows, axis=0))


def _facet_normals(vertices, triangles):
    """(T, 3) float64 unit normals of the triangles (0 for degenerate ones)."""
    c = vertices.take(triangles, axis=0)
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def _vertex_normals(facets, triangles, count):
    """(V, 3) float64 the normalised sums of the unit normals ``facets`` of the triangles around
    each vertex (Cycles' ``compute_vertex_normals``)."""
    corners = triangles.ravel()
    sums = np.stack([np.bincount(corners, weights=np.repeat(facets[:, a], 3), minlength=count)
                     for a in range(3)], axis=1)
    length = np.linalg.norm(sums, axis=1, keepdims=True)
    return np.divide(sums, length, out=np.zeros_like(sums), where=length > 0)

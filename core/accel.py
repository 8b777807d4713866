"""Ray queries: the only module that talks to embreex.

:class:`Accel` wraps one static embree scene holding every triangle of a
:class:`~core.scene.Scene` and answers batched closest-hit queries.  Embree
works in float32, so it sees the scene shifted to the centre of its bounds (a
scene far from the origin keeps its precision).  Surface positions are rebuilt
from the barycentrics in float64 on the hit triangle's plane, and new rays are
spawned with an offset along the geometric normal that scales with the
coordinate magnitude in that centred frame (algorithm.md 6.4).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sampling import dot

# Spawned rays start this many float32 ulps (relative to the coordinate magnitude) off the surface.
_OFFSET_ULPS = 64.0 * np.finfo(np.float32).eps
# Embree's meshes are built from vertices and indices when there are fewer vertices than this many
# per triangle, else from the triangles' corners (Accel, _embree_scene; benchmarks/context_cost.py).
SHARED_VERTICES = 1.5


@dataclass
class Hits:
    """Closest hits of a batch of n rays."""

    is_hit: np.ndarray      # (n,) bool
    prim_ids: np.ndarray    # (n,) int32 triangle index, -1 on a miss
    t: np.ndarray           # (n,) float32 hit distance along the (unit) direction, inf on a miss
    b1: np.ndarray          # (n,) float64 barycentric of corner 1
    b2: np.ndarray          # (n,) float64 barycentric of corner 2
    scatter_t: np.ndarray = None  # (n,) float64 distance where a ray stopped in a volume, inf; or None
    forced: tuple = None            # RenderContext.trace's forced volume points, or None


class Accel:
    """Embree BVH over a scene's triangles plus per-triangle data for shading."""

    def __init__(self, scene, bounds=None, reuse=None):
        """``bounds``: None, or (lo, hi) to take for the scene's box instead of its own (the extent,
        and the disc the sun's and the world's photons start from: ``LightSampler``).  ``reuse``:
        None, or an ``Accel`` of an earlier version of the scene whose triangles' data this one takes
        if it holds the same triangles, and its embree scenes if they also see them in the same frame
        (the 3D viewport's edits of materials and lights: ``core/live.py``)."""
        # (what the triangles are made of, compared with a later version's; None: a subset())
        self._mesh_key = (scene.vertices, scene.triangles)
        same_triangles = reuse is not None and _same_mesh(self._mesh_key, reuse._mesh_key)
        corners = None
        if same_triangles:
            self.triangle_count = reuse.triangle_count
            for name in ("v0", "e1", "e2", "area", "geometric_normals"):
                setattr(self, name, getattr(reuse, name))
        else:
            corners = scene.triangle_corners().astype(np.float64)      # (T, 3, 3)
            self.triangle_count = len(corners)
            # Contiguous: take() on a strided view would first copy the whole array, every call.
            self.v0 = np.ascontiguousarray(corners[:, 0])               # (T, 3) float64
            self.e1 = corners[:, 1] - corners[:, 0]                     # (T, 3) float64
            self.e2 = corners[:, 2] - corners[:, 0]                     # (T, 3) float64
            cross = np.cross(self.e1, self.e2)
            length = np.linalg.norm(cross, axis=1)
            self.area = 0.5 * length                                    # (T,) float64
            safe = np.where(length > 0, length, 1.0)
            ng = cross / safe[:, None]
            ng[length == 0] = (0.0, 0.0, 1.0)
            self.geometric_normals = ng                                 # (T, 3) float64, unit
        lo, hi = scene.bounds() if bounds is None else bounds
        self.bounds = (lo, hi)
        self.extent = float(max(np.max(hi - lo), 1e-6))
        self.center = 0.5 * (lo + hi)                                    # (3,) float64, embree's origin
        self.offset_floor = 1e-7 * self.extent
        self._embree = None
        self._contact = None            # embree scene of the non-glass triangles (see with_contacts())
        self._ids = None                # the scene's triangles this one holds (subset()), None: all
        self.object_ids = scene.object_ids  # (T,) each triangle's object, or None
        self._locals = None             # LocalScene of every object apart (local_scene())
        if self.triangle_count:
            # Embree's meshes from the vertices and their indices where the triangles share them
            # (as Blender's do), else from the corners: the same float32 corners either way
            # (_embree_scene).
            shared = len(scene.vertices) < SHARED_VERTICES * self.triangle_count
            relative = np.asarray(scene.vertices, np.float64) - self.center if shared else None

            def mesh(ids=None):
                nonlocal corners
                if shared:
                    return _embree_scene(relative, scene.triangles if ids is None else scene.triangles[ids])
                if corners is None:
                    corners = scene.triangle_corners().astype(np.float64)
                return _embree_scene((corners if ids is None else corners[ids]) - self.center)
            # (embree's scenes hold the triangles as seen from the centre)
            same_frame = same_triangles and np.array_equal(self.center, reuse.center)
            self._embree = reuse._embree if same_frame else mesh()
            mats = scene.materials
            glass = (mats.dielectric_weight > 0).take(scene.material_ids)
            self.glass = glass                                          # (T,) bool
            if glass.any() and not glass.all():
                self.contact_ids = np.flatnonzero(~glass)
                kept = (same_frame and reuse._contact is not None
                        and np.array_equal(reuse.contact_ids, self.contact_ids))
                self._contact = reuse._contact if kept else mesh(self.contact_ids)

    def intersect(self, origins, directions, tmax=None) -> Hits:
        """Closest hits of rays ``origins + t directions`` for 0 < t < tmax.

        origins : (n, 3) float64, world.  directions : (n, 3), unit.
        tmax : None, a scalar or (n,) maximum distances.
        """
        n = len(origins)
        if n == 0 or self._embree is None:
            return Hits(np.zeros(n, bool), np.full(n, -1, np.int32), np.full(n, np.inf, np.float32),
                        np.zeros(n), np.zeros(n))
        o = np.ascontiguousarray(origins - self.center, np.float32)
        d = np.ascontiguousarray(directions, np.float32)
        if tmax is None:
            dists = None
        else:
            dists = np.ascontiguousarray(np.broadcast_to(np.minimum(tmax, 1e37), (n,)), np.float32)
        r = self._embree.run(o, d, dists=dists, output=1)
        prim = r["primID"]
        is_hit = prim >= 0
        if self._ids is not None:
            prim = np.where(is_hit, self._ids.take(np.maximum(prim, 0)), -1)
        t = np.where(is_hit, r["tfar"], np.float32(np.inf))
        return Hits(is_hit, np.where(is_hit, prim, -1).astype(np.int32), t,
                    r["u"].astype(np.float64), r["v"].astype(np.float64))

    def subset(self, tri_ids) -> "Accel":
        """A query over triangles ``tri_ids`` alone (a glowing volume's mesh), in this one's frame:
        its :meth:`intersect` gives the hits' indices in the whole scene."""
        out = Accel.__new__(Accel)
        out.__dict__.update(self.__dict__)
        out._contact = None
        out._locals = None
        out._mesh_key = None
        out._ids = np.asarray(tri_ids, np.int64)
        v0, e1, e2 = (a.take(out._ids, axis=0) for a in (self.v0, self.e1, self.e2))
        out._embree = _embree_scene(np.stack([v0, v0 + e1, v0 + e2], axis=1) - self.center)
        return out

    def local_scene(self) -> "LocalScene":
        """Queries of each ray over its own object's triangles alone (:class:`LocalScene`, built on
        first use): Cycles' local intersection, which a Bevel and Ambient Occlusion's Only Local use."""
        if self._locals is None:
            self._locals = LocalScene(self)
        return self._locals

    def hit_positions(self, prim_ids, b1, b2):
        """(n, 3) float64 surface points from triangle ids and barycentrics."""
        # take(axis=0) gathers rows ~4x faster than fancy indexing (throughout the core).
        return (self.v0.take(prim_ids, axis=0) + b1[:, None] * self.e1.take(prim_ids, axis=0)
                + b2[:, None] * self.e2.take(prim_ids, axis=0))

    def with_contacts(self, hits, origins, directions) -> Hits:
        """``hits`` with glass faces that rest on another surface replaced by that surface.

        A glass resting on a table has its bottom face in the table's plane.  A ray inside the
        glass that reaches that face meets no glass-air interface there but the table itself,
        and light the table scatters goes straight into the glass.  Offsets along the normal
        cannot tell the two coincident faces apart (a ray refracted out through the bottom
        would be spawned under the table and leak), so hits on a glass face from inside (the
        ray leaving the glass) probe the non-glass triangles within a few offsets of the hit:
        a front face found there, one the ray goes into, becomes the hit.  Rays leaving the
        table upwards already pass the coincident glass face, as they should.
        """
        if self._contact is None or not hits.is_hit.any():
            return hits
        h = np.flatnonzero(hits.is_hit)
        prim = hits.prim_ids.take(h)
        d = directions.take(h, axis=0)
        leaving = self.glass.take(prim) & (dot(d, self.geometric_normals.take(prim, axis=0)) > 0)
        rows = h[leaving]
        if len(rows) == 0:
            return hits
        d = directions.take(rows, axis=0)
        p = self.hit_positions(hits.prim_ids.take(rows), hits.b1.take(rows), hits.b2.take(rows))
        eps = self._offsets(p)
        o = np.ascontiguousarray(p - 2.0 * eps[:, None] * d - self.center, np.float32)
        r = self._contact.run(o, np.ascontiguousarray(d, np.float32),
                              dists=np.ascontiguousarray(4.0 * eps, np.float32), output=1)
        local = r["primID"]
        found = np.flatnonzero(local >= 0)
        if len(found) == 0:
            return hits
        table = self.contact_ids.take(local.take(found))
        into = dot(d.take(found, axis=0), self.geometric_normals.take(table, axis=0)) < 0
        found, table = found[into], table[into]
        if len(found) == 0:
            return hits
        at = rows.take(found)
        prim_ids, b1, b2 = hits.prim_ids.copy(), hits.b1.copy(), hits.b2.copy()
        prim_ids[at] = table
        b1[at], b2[at] = r["u"].take(found).astype(np.float64), r["v"].take(found).astype(np.float64)
        return Hits(hits.is_hit, prim_ids, hits.t, b1, b2)

    def spawn(self, positions, normals, directions):
        """Origins for rays leaving ``positions`` along ``directions``.

        Offset along the geometric ``normals`` to the side the direction points
        to, by an amount that grows with the coordinate magnitude.
        """
        side = np.where(dot(normals, directions) >= 0, 1.0, -1.0)
        return positions + (side * self._offsets(positions))[:, None] * normals

    def _offsets(self, positions):
        """(n,) spawn offsets at ``positions``: ulps of the coordinate magnitude, and a floor."""
        rel = np.abs(positions - self.center)
        # Column by column: NumPy reduces a short inner axis (max over axis 1) ~10x slower.
        return _OFFSET_ULPS * np.maximum(np.maximum(rel[:, 0], rel[:, 1]), rel[:, 2]) + self.offset_floor


class LocalScene:
    """Every object's triangles in one embree scene, each object moved apart by its own shift (a
    grid of steps of twice the scene's extent), so that one batched query answers each ray over its
    own object alone (Cycles' local intersection): a ray is moved with its object and clipped to the
    object's bounding box, which no other object's shifted box overlaps.  Triangles keep their
    indices; before, one embree scene per object, queried in a Python loop over the objects a batch
    touched (``benchmarks/local_queries_cost.py``).  Embree's float32 sees coordinates up to the grid's
    size: for 4,096 objects 16 extents from its centre, 16 times the whole scene's rounding."""

    def __init__(self, accel):
        self.accel = accel
        ids = np.asarray(accel.object_ids, np.int64)
        self.objects, rank = np.unique(ids, return_inverse=True)
        n = len(self.objects)
        side = max(int(np.ceil(n ** (1.0 / 3.0) - 1e-9)), 1)
        while side ** 3 < n:
            side += 1
        grid = np.stack(np.unravel_index(np.arange(n), (side, side, side)), axis=1).astype(np.float64)
        self.shift = (grid - 0.5 * (side - 1)) * (2.0 * accel.extent)             # (n, 3)
        corners = np.stack([accel.v0, accel.v0 + accel.e1, accel.v0 + accel.e2], axis=1)    # (T, 3, 3)
        lo, hi = np.full((n, 3), np.inf), np.full((n, 3), -np.inf)
        np.minimum.at(lo, rank, corners.min(axis=1))
        np.maximum.at(hi, rank, corners.max(axis=1))
        pad = 1e-5 * accel.extent
        self.lo, self.hi = lo - pad, hi + pad                                     # (n, 3) world boxes
        self._embree = _embree_scene(corners - accel.center + self.shift.take(rank, axis=0)[:, None, :])

    def intersect(self, origins, directions, tmax, objects) -> Hits:
        """Closest hits of rays ``origins + t directions`` (0 < t < ``tmax``, a scalar or (n,)) on the
        triangles of each ray's object ``objects`` (n,) alone, as :meth:`Accel.intersect` gives them."""
        n = len(origins)
        d = np.asarray(directions, np.float64)
        rank = np.searchsorted(self.objects, np.asarray(objects, np.int64))
        lo, hi = self.lo.take(rank, axis=0), self.hi.take(rank, axis=0)
        # The part of each ray inside its object's box (slabs; a zero component: a tiny one).
        tiny = np.where(d < 0.0, -1e-300, 1e-300)
        inv = 1.0 / np.where(np.abs(d) < 1e-300, tiny, d)
        a, b = (lo - origins) * inv, (hi - origins) * inv
        near, far = np.minimum(a, b), np.maximum(a, b)
        start = np.maximum(np.maximum(np.maximum(near[:, 0], near[:, 1]), near[:, 2]), 0.0)
        end = np.minimum(np.minimum(np.minimum(far[:, 0], far[:, 1]), far[:, 2]),
                         np.broadcast_to(np.asarray(tmax, np.float64), (n,)))
        rows = np.flatnonzero(end > start)
        is_hit = np.zeros(n, bool)
        prim, t = np.full(n, -1, np.int32), np.full(n, np.inf, np.float32)
        b1, b2 = np.zeros(n), np.zeros(n)
        if len(rows):
            s = start.take(rows)
            o = (origins.take(rows, axis=0) + s[:, None] * d.take(rows, axis=0) - self.accel.center
                 + self.shift.take(rank.take(rows), axis=0))
            r = self._embree.run(np.ascontiguousarray(o, np.float32),
                                 np.ascontiguousarray(d.take(rows, axis=0), np.float32),
                                 dists=np.ascontiguousarray(np.minimum(end.take(rows) - s, 1e37), np.float32),
                                 output=1)
            found = r["primID"] >= 0
            h = rows[found]
            is_hit[h] = True
            prim[h] = r["primID"][found]
            t[h] = (r["tfar"][found] + s[found]).astype(np.float32)
            b1[h], b2[h] = r["u"][found], r["v"][found]
        return Hits(is_hit, prim, t, b1, b2)


def _same_mesh(a, b):
    """Whether two (vertices, triangles) hold the same triangles."""
    return a is not None and b is not None and all(np.shape(u) == np.shape(v) and np.array_equal(u, v)
                                                   for u, v in zip(a, b))


def _embree_scene(points, triangles=None):
    """A robust embree scene of triangles: ``points`` (T, 3, 3) their corners, or (V, 3) vertices
    that ``triangles`` (T, 3) index, in the frame embree sees (float32).

    embreex copies them into embree's buffers one element at a time through Python indexing, 3 s
    for 2 million triangles' corners, 5 times embree's own build; an index costs it about 3.5 times
    a coordinate.  So ``Accel`` hands over vertices shared by their triangles, as Blender's are,
    with their indices (1.95-1.97 times faster on a grid of 2 million triangles and 1 million
    vertices; the whole context 1.8 times), and unshared ones as corners (the indices 0.72-0.80
    times as fast there; ``benchmarks/context_cost.py``)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    scene = rtcore_scene.EmbreeScene(robust=True)
    if triangles is None:
        TriangleMesh(scene, np.ascontiguousarray(points, np.float32))
    else:
        TriangleMesh(scene, np.ascontiguousarray(points, np.float32),
                     np.ascontiguousarray(triangles, np.int32))
    return scene


def interpolate_corners(corners, bary):
    """(k, c) float64 values inside triangles from their (k, 3, c) corner values and the
    barycentric weights ``bary`` ((k, 1) each, of corners 0, 1, 2)."""
    c = corners.astype(np.float64)
    return bary[0] * c[:, 0] + bary[1] * c[:, 1] + bary[2] * c[:, 2]

"""Ray queries: the only module that talks to embreex.

:class:`Accel` wraps one static embree scene holding every triangle of a
:class:`~core.scene.Scene` (or, after an edit in the viewport moved a few of them, an earlier
version's with the moved ones and those about their old places apart: :class:`SplitScene`) and
answers batched closest-hit queries.  Embree works in float32, so it sees the scene shifted to a
centre inside its bounds, the point of them nearest the world's origin: a scene far from the
origin keeps its precision, and one about the origin keeps Cycles' (an object far away does not
take it from the others).  Surface positions are rebuilt from the barycentrics in float64 on the
hit triangle's plane, and new rays are spawned with an offset along the geometric normal that
scales with the coordinate magnitude in that frame and, a little, with the largest of the
triangle's corners (algorithm.md 6.4): embree sees each plane to an ulp or two of that, so a small
object beside a huge ground plane keeps offsets of its own size.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sampling import dot

# Embree leaves out triangles with a coordinate beyond this (its FLT_LARGE) or not finite: the exporter
# leaves them out first, with a warning (``export.scene.within_reach``), as Cycles' BVH leaves them.
EMBREE_REACH = 1.844e18
# Spawned rays start this many float32 ulps (relative to the coordinate magnitude) off the surface,
# and this share of the largest coordinate of their triangle's corners further (about two ulps:
# embree's plane of a triangle is as far off ours where its corners are far from embree's origin).
_OFFSET_ULPS = 64.0 * np.finfo(np.float32).eps
_CORNER_SHARE = 2e-7
# Embree's meshes are built from vertices and indices when there are fewer vertices than this many
# per triangle, else from the triangles' corners (Accel, _embree_scene; benchmarks/context_cost.py).
SHARED_VERTICES = 1.5
# An edit of the viewport (``Accel(reuse=...)``) that moves at most this share of a scene's triangles
# (an object moved, a vertex dragged), of a scene of at least SPLIT_MIN_TRIANGLES, keeps the earlier
# version's embree scenes and builds those of the moved ones and of the triangles about their old
# places (SplitScene), while those add up to at most this share; below that count a whole build
# takes a few tens of milliseconds.
SPLIT_SHARE = 0.25
SPLIT_MIN_TRIANGLES = 1 << 14
# The box of the moved triangles' old copies (SplitScene) is this share of the scene's extent wider
# on every side than they are: many float32 ulps of embree's coordinates.
SPLIT_MARGIN = 1e-4
# At most this many groups of moved triangles in boxes apart (objects dragged one after another)
# before a whole build.
SPLIT_GROUPS = 8
# A group of moved triangles keeps its embree scene where an affine map takes them from where it has
# them to where they are now (Mover.follow): fitted on this many of their corners, of a condition
# number at most this, and every corner within a quarter of the spawn offset there.
MOVER_SAMPLE = 4096
MOVER_CONDITION = 1e4
MOVER_TOLERANCE = 0.25
# An edited scene whose box, this share of its extent wider on every side, still holds the earlier
# version's centre (a light dragged above a floor, an object past the others) keeps that centre for
# embree's frame, and so its embree scenes: the coordinates embree sees grow by at most as much.
FRAME_SHIFT = 0.4
# LocalScene's classes of objects within this factor of size, its grids' steps this many times a
# class's largest size, and the float32 ulps of the largest coordinate of an object's box there
# that its spawn offsets for its queries are at least.
LOCAL_CLASS = 8.0
LOCAL_STEP = 1.25
_LOCAL_ULPS = 4.0 * np.finfo(np.float32).eps


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

    def __init__(self, scene, bounds=None, reuse=None, take=False):
        """``bounds``: None, or (lo, hi) to take for the scene's box instead of its own (the extent,
        and the disc the sun's and the world's photons start from: ``LightSampler``).  ``reuse``:
        None, or an ``Accel`` of an earlier version of the scene whose triangles' data this one takes
        if it holds the same triangles, and its embree scenes if they also see them in the same frame
        (``FRAME_SHIFT``; the 3D viewport's edits of materials and lights: ``core/live.py``).  Where
        the edit moved a few triangles of the same mesh (``SPLIT_SHARE``), the data is taken and
        changed in their rows, and the earlier version's embree scenes are kept beside scenes of
        the moved triangles and of those about their old places (:class:`SplitScene`; an object
        dragged keeps its own triangles' scene from step to step, :class:`Mover`).  ``take``:
        ``reuse`` is not used again (the live server drops it), so its tables are changed in those
        rows instead of copied (hundreds of MB for millions of triangles), and it is left unable to
        be reused."""
        # (what the triangles are made of, compared with a later version's; None: a subset())
        self._mesh_key = (scene.vertices, scene.triangles)
        same_triangles = reuse is not None and _same_mesh(self._mesh_key, reuse._mesh_key)
        moved = None if same_triangles or reuse is None else _moved_triangles(self._mesh_key, reuse._mesh_key)
        if moved is not None and len(moved) == 0:
            same_triangles, moved = True, None          # (only vertices no triangle uses)
        if moved is not None and len(moved) > SPLIT_SHARE * len(scene.triangles):
            moved = None
        corners = None
        old = None                      # (the moved triangles' v0, e1, e2 in the earlier version)
        if same_triangles:
            self.triangle_count = reuse.triangle_count
            for name in ("v0", "e1", "e2", "area", "geometric_normals"):
                setattr(self, name, getattr(reuse, name))
        elif moved is not None:
            self.triangle_count = reuse.triangle_count
            rows = _triangle_data(scene.vertices[scene.triangles[moved]].astype(np.float64))
            old = tuple(getattr(reuse, name).take(moved, axis=0) for name in ("v0", "e1", "e2"))
            for name, new in zip(("v0", "e1", "e2", "area", "geometric_normals"), rows):
                table = getattr(reuse, name) if take else getattr(reuse, name).copy()
                table[moved] = new
                setattr(self, name, table)
            if take:
                reuse._mesh_key = None          # (its tables are this version's now)
        else:
            corners = scene.triangle_corners().astype(np.float64)      # (T, 3, 3)
            self.triangle_count = len(corners)
            # (v0, e1, e2: (T, 3) float64, v0 contiguous; area (T,) float64; unit normals (T, 3))
            self.v0, self.e1, self.e2, self.area, self.geometric_normals = _triangle_data(corners)
        lo, hi = scene.bounds() if bounds is None else bounds
        self.bounds = (lo, hi)
        self.extent = float(max(np.max(hi - lo), 1e-6))
        # Embree's origin: the point of the box nearest the world's origin; the earlier version's
        # where still inside the box widened by FRAME_SHIFT (a light or an object moved: its scenes
        # kept).
        self.center = np.clip(np.zeros(3), lo, hi)
        if reuse is not None and (np.abs(reuse.center - np.clip(reuse.center, lo, hi))
                                  <= FRAME_SHIFT * self.extent).all():
            self.center = reuse.center
        if same_triangles and np.array_equal(self.center, reuse.center):
            self.corner_offset = reuse.corner_offset
        elif moved is not None and np.array_equal(self.center, reuse.center):
            self.corner_offset = reuse.corner_offset if take else reuse.corner_offset.copy()
            rows = (a.take(moved, axis=0) for a in (self.v0, self.e1, self.e2))
            self.corner_offset[moved] = _corner_offsets(*rows, self.center)
        else:
            self.corner_offset = _corner_offsets(self.v0, self.e1, self.e2, self.center)   # (T,) float64
        self._embree = None
        self._contact = None            # embree scene of the non-glass triangles (see with_contacts())
        self._ids = None                # the scene's triangles this one holds (subset()), None: all
        self._moved = None              # the triangles embree's scenes hold apart (SplitScene), or None
        self._groups = None             # their groups (ids, box, patch: _split), or None
        self._margin = None             # the boxes' margin (_split)
        self.object_ids = scene.object_ids  # (T,) each triangle's object, or None
        self._locals = None             # LocalScene of every object apart (local_scene())
        self._boxes = None              # the objects' boxes (object_boxes())
        if self.triangle_count:
            # Embree's meshes from the vertices and their indices where the triangles share them
            # (as Blender's do), else from the corners: the same float32 corners either way
            # (_embree_scene).
            shared = len(scene.vertices) < SHARED_VERTICES * self.triangle_count

            def mesh(ids=None):
                """Embree's scene of the triangles ``ids`` (None: all), None where there are none."""
                if ids is not None and len(ids) == 0:
                    return None
                if shared and (ids is None or len(ids) > len(scene.vertices) // 8):
                    relative = np.asarray(scene.vertices, np.float64) - self.center
                    return _embree_scene(relative, scene.triangles if ids is None else scene.triangles[ids])
                if corners is not None:
                    return _embree_scene((corners if ids is None else corners[ids]) - self.center)
                # (a few of the triangles, an edit's: their corners alone)
                picked = scene.triangles if ids is None else scene.triangles[ids]
                return _embree_scene(scene.vertices[picked].astype(np.float64) - self.center)
            # (embree's scenes hold the triangles as seen from the centre)
            same_frame = reuse is not None and np.array_equal(self.center, reuse.center)
            split = False
            if moved is not None and same_frame and self.triangle_count >= SPLIT_MIN_TRIANGLES:
                split = self._split(reuse, moved, old)
            if same_triangles and same_frame:
                self._embree = reuse._embree
                self._moved, self._groups, self._margin = reuse._moved, reuse._groups, reuse._margin
            elif split:
                self._embree = SplitScene.build(mesh, _base(reuse._embree), None, self._groups, self._margin,
                                                self.triangle_count, self._corners_now,
                                                _split_scene(reuse._embree), moved)
            else:
                self._embree = mesh()
            mats = scene.materials
            glass = (mats.dielectric_weight > 0).take(scene.material_ids)
            self.glass = glass                                          # (T,) bool
            if glass.any() and not glass.all():
                self.contact_ids = np.flatnonzero(~glass)
                kept = (same_frame and reuse._contact is not None
                        and np.array_equal(reuse.contact_ids, self.contact_ids))
                if kept and same_triangles:
                    self._contact = reuse._contact
                elif kept and split and (isinstance(reuse._contact, SplitScene)
                                         == isinstance(reuse._embree, SplitScene)):
                    # (its earlier version that of the whole scene's base)
                    self._contact = SplitScene.build(mesh, _base(reuse._contact), self.contact_ids,
                                                     self._groups, self._margin, self.triangle_count,
                                                     self._corners_now, _split_scene(reuse._contact), moved)
                else:
                    self._contact = mesh(self.contact_ids)

    def _split(self, reuse, moved, old):
        """Whether embree's scenes of ``reuse`` (an earlier version of the same mesh in the same
        frame) can serve with the triangles ``moved`` since (sorted ids; ``old``: their v0, e1, e2
        there) apart (:class:`SplitScene`); if so sets ``_moved`` (those and the ones ``reuse`` kept
        apart: every triangle whose copy in the kept scenes is out of date) and ``_groups``: (ids,
        lo, hi, patch ids) of each set of them whose copies lie in a box (``lo``, ``hi`` in embree's
        frame, ``_margin`` wider than they are) apart from the others' boxes, and of the other
        triangles that reach into it.  False where the groups would be over ``SPLIT_GROUPS`` or
        hold over ``SPLIT_SHARE`` of the triangles (copies and patches)."""
        count = self.triangle_count
        if reuse._moved is None:
            known, groups, margin = moved[:0], [], SPLIT_MARGIN * self.extent
        else:
            known, groups, margin = reuse._moved, list(reuse._groups), reuse._margin
        new = np.setdiff1d(moved, known, assume_unique=True)
        stale = np.union1d(known, new)
        if len(stale) > SPLIT_SHARE * count:
            return False
        if len(new):
            # (their copies in the kept scenes are where the earlier version had them)
            at = np.searchsorted(moved, new)
            lo, hi = _corner_box(*(rows.take(at, axis=0) for rows in old))
            ids, lo, hi = new, lo - self.center - margin, hi - self.center + margin
            merged = True                   # (a box that meets the new one: one group, boxes grow)
            while merged:
                merged = False
                for group in groups:
                    if (group[1] <= hi).all() and (group[2] >= lo).all():
                        ids = np.union1d(ids, group[0])
                        lo, hi = np.minimum(lo, group[1]), np.maximum(hi, group[2])
                        groups.remove(group)
                        merged = True
                        break
            if len(groups) >= SPLIT_GROUPS:
                return False
            near = _overlapping(self.v0, self.e1, self.e2, lo + self.center, hi + self.center)
            near[stale] = False
            groups.append((ids, lo, hi, np.flatnonzero(near)))
        if len(stale) + sum(len(group[3]) for group in groups) > SPLIT_SHARE * count:
            return False
        self._moved, self._groups, self._margin = stale, groups, margin
        return True

    def _corners_now(self, ids):
        """The corners (k, 3, 3) float64 of triangles ``ids`` in embree's frame, and how far (k, 3)
        a scene of them may have each (a quarter of the spawn offset there: ``Mover``)."""
        corners = np.empty((len(ids), 3, 3))
        corners[:, 0] = self.v0.take(ids, axis=0) - self.center
        corners[:, 1] = corners[:, 0] + self.e1.take(ids, axis=0)
        corners[:, 2] = corners[:, 0] + self.e2.take(ids, axis=0)
        return corners, MOVER_TOLERANCE * self._offsets_at(np.abs(corners))

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
        out._moved = None
        out._ids = np.asarray(tri_ids, np.int64)
        v0, e1, e2 = (a.take(out._ids, axis=0) for a in (self.v0, self.e1, self.e2))
        out._embree = _embree_scene(np.stack([v0, v0 + e1, v0 + e2], axis=1) - self.center)
        return out

    def object_sizes(self, prims):
        """(n,) the size of the objects of triangles ``prims`` (their boxes' longest side; the scene's
        extent in a scene without objects): a bump's differences are a share of it
        (``procedural.BUMP_STEP``), so a small object keeps its detail beside a huge one."""
        if self.object_ids is None:
            return np.full(len(prims), self.extent)
        _, rank, lo, hi = self.object_boxes()
        return (hi - lo).max(axis=1).take(rank.take(prims))

    def object_boxes(self):
        """(objects (n,) the object ids the triangles have, sorted; rank (T,) each triangle's row
        among them; lo, hi (n, 3) float64 their boxes in the world), made on first use (the bump's
        steps, :class:`LocalScene`); None without object ids."""
        if self._boxes is None and self.object_ids is not None:
            objects, rank = np.unique(np.asarray(self.object_ids, np.int64), return_inverse=True)
            lo, hi = np.full((len(objects), 3), np.inf), np.full((len(objects), 3), -np.inf)
            for corner in (self.v0, self.v0 + self.e1, self.v0 + self.e2):
                np.minimum.at(lo, rank, corner)
                np.maximum.at(hi, rank, corner)
            self._boxes = (objects, rank, lo, hi)
        return self._boxes

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
        eps = self._offsets(p, hits.prim_ids.take(rows))
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

    def spawn(self, positions, normals, directions, prims):
        """Origins for rays leaving ``positions`` on triangles ``prims`` (n,) along ``directions``:
        offset along the geometric ``normals`` to the side the direction points to, by an amount
        that grows with the coordinate magnitude and the triangle's ``corner_offset``."""
        return _pushed(positions, normals, directions, self._offsets(positions, prims))

    def spawn_local(self, positions, normals, directions, prims):
        """:meth:`spawn` for rays of :meth:`local_scene`'s queries: offsets at least its floor for the
        triangles' objects (what its own frame tells apart); :meth:`spawn` in a scene of one object."""
        if self.object_ids is None:
            return self.spawn(positions, normals, directions, prims)
        offsets = np.maximum(self._offsets(positions, prims), self.local_scene().floor_at(prims))
        return _pushed(positions, normals, directions, offsets)

    def offsets_near(self, points):
        """(n,) the spawn offset at ``points`` (n, 3) on a triangle with a corner there and none
        further from embree's origin."""
        rel = self._offsets_at(np.abs(points - self.center))
        return rel * (1.0 + _CORNER_SHARE / _OFFSET_ULPS)

    def _offsets(self, positions, prims):
        """(n,) spawn offsets at ``positions`` on triangles ``prims``."""
        return self._offsets_at(np.abs(positions - self.center)) + self.corner_offset.take(prims)

    def _offsets_at(self, rel):
        """(...) the coordinate magnitude's part of the spawn offsets at points whose coordinates in
        embree's frame have magnitudes ``rel`` (..., 3)."""
        # Column by column: NumPy reduces a short inner axis (max over axis 1) ~10x slower.
        largest = np.maximum(np.maximum(rel[..., 0], rel[..., 1]), rel[..., 2])
        return _OFFSET_ULPS * largest


class LocalScene:
    """Every object's triangles in a few embree scenes, one a class of objects of about one size
    (within a factor LOCAL_CLASS), each object's box centre moved to a point of its own (a grid of
    steps of LOCAL_STEP times its class's largest size), so that one batched query a class answers
    each ray over its own object alone (Cycles' local intersection): a ray is moved with its object
    and clipped to the object's bounding box, which no other object's moved box overlaps.
    Triangles keep their indices; before, one embree scene per object, queried in a Python loop
    over the objects a batch touched (``benchmarks/local_queries_cost.py``).  Embree's float32 sees
    an object's coordinates up to its class's grid's size: for 4,096 objects of a class 20 of their
    largest sizes from its centre, wherever the objects are in the scene and whatever else is in
    it (a huge ground plane has a class of its own)."""

    def __init__(self, accel):
        self.accel = accel
        self.objects, rank, lo, hi = accel.object_boxes()
        n = len(self.objects)
        corners = np.stack([accel.v0, accel.v0 + accel.e1, accel.v0 + accel.e2], axis=1)    # (T, 3, 3)
        size = (hi - lo).max(axis=1)
        reach = np.maximum(np.abs(lo - accel.center), np.abs(hi - accel.center))
        spawned = 1e-5 * size + 4.0 * accel.offsets_near(accel.center + reach)
        room = size + 2.0 * spawned
        room = np.maximum(room, 1e-12 * room.max() + 1e-30)
        self._class = np.floor(np.log(room.max() / room) / np.log(LOCAL_CLASS)).astype(np.int64)     # (n,)
        # Each box's centre goes to its class's grid point (the pads below are far under the
        # step's room).
        at = np.zeros((n, 3))
        for c in np.unique(self._class):
            members = np.flatnonzero(self._class == c)
            side = max(int(np.ceil(len(members) ** (1.0 / 3.0) - 1e-9)), 1)
            while side ** 3 < len(members):
                side += 1
            grid = np.stack(np.unravel_index(np.arange(len(members)), (side, side, side)), axis=1)
            at[members] = (grid - 0.5 * (side - 1)) * (LOCAL_STEP * float(room.take(members).max()))
        # The offsets a frame tells apart: a few float32 ulps of the largest coordinate an object's
        # box has in it (rays spawned off an object for its queries start that far at least:
        # Accel.spawn_local).
        self.floor = _LOCAL_ULPS * (np.abs(at).max(axis=1) + 0.5 * size + spawned) + 1e-30      # (n,)
        self._rank = rank                                           # (T,) each triangle's object
        # (boxes wider than the spawn offsets there: rays spawned off an object start in its box)
        pad = spawned + 4.0 * self.floor
        self.lo, self.hi = lo - pad[:, None], hi + pad[:, None]                   # (n, 3) world boxes
        self.shift = at - 0.5 * (lo + hi)                                         # (n, 3)
        # (each class's embree scene and its triangles' indices in the scene)
        tri_class = self._class.take(rank)
        self._scenes = {}
        for c in np.unique(self._class):
            tri = np.flatnonzero(tri_class == c)
            self._scenes[int(c)] = (_embree_scene(corners.take(tri, axis=0)
                                                  + self.shift.take(rank.take(tri), axis=0)[:, None, :]), tri)

    def floor_at(self, prims):
        """(n,) the least spawn offset of rays off triangles ``prims`` for this scene's queries."""
        return self.floor.take(self._rank.take(prims))

    def intersect(self, origins, directions, tmax, objects) -> Hits:
        """Closest hits of rays ``origins + t directions`` (0 < t < ``tmax``, a scalar or (n,)) on the
        triangles of each ray's object ``objects`` (n,) alone, as :meth:`Accel.intersect` gives them."""
        n = len(origins)
        d = np.asarray(directions, np.float64)
        rank = np.searchsorted(self.objects, np.asarray(objects, np.int64))
        lo, hi = self.lo.take(rank, axis=0), self.hi.take(rank, axis=0)
        # The part of each ray inside its object's box (slabs).
        inv = _slab_inverse(d)
        a, b = (lo - origins) * inv, (hi - origins) * inv
        near, far = np.minimum(a, b), np.maximum(a, b)
        start = np.maximum(np.maximum(np.maximum(near[:, 0], near[:, 1]), near[:, 2]), 0.0)
        end = np.minimum(np.minimum(np.minimum(far[:, 0], far[:, 1]), far[:, 2]),
                         np.broadcast_to(np.asarray(tmax, np.float64), (n,)))
        inside = np.flatnonzero(end > start)
        is_hit = np.zeros(n, bool)
        prim, t = np.full(n, -1, np.int32), np.full(n, np.inf, np.float32)
        b1, b2 = np.zeros(n), np.zeros(n)
        classes = self._class.take(rank.take(inside))
        for c in np.unique(classes):
            rows = inside if len(self._scenes) == 1 else inside[classes == c]
            scene, tri = self._scenes[int(c)]
            s = start.take(rows)
            dr = d.take(rows, axis=0)
            o = origins.take(rows, axis=0) + s[:, None] * dr + self.shift.take(rank.take(rows), axis=0)
            dists = np.ascontiguousarray(np.minimum(end.take(rows) - s, 1e37), np.float32)
            r = scene.run(np.ascontiguousarray(o, np.float32), np.ascontiguousarray(dr, np.float32),
                          dists=dists, output=1)
            found = r["primID"] >= 0
            h = rows[found]
            is_hit[h] = True
            prim[h] = tri.take(r["primID"][found])
            t[h] = (r["tfar"][found] + s[found]).astype(np.float32)
            b1[h], b2[h] = r["u"][found], r["v"][found]
        return Hits(is_hit, prim, t, b1, b2)


class SplitScene:
    """An embree scene of an earlier version of a scene's triangles (``base``: all of them, or a set
    of them, the contact scene's), queried (``run``, as an embree scene's) as if the triangles edits
    moved since were where they are now.  Their new places are a scene a group (``movers``, kept
    while the group moves by one affine map: :class:`Mover`); their old copies lie in boxes apart
    (a group each, ``group_of``), and a ray whose nearest hit in the base is such a copy is answered
    inside that box by a scene of the other triangles that reach into it (the group's ``patches``)
    and past the box by the base again.  So an object dragged in the viewport builds the scenes of
    its own triangles and of what lies around where it was, not of the rest, and only at its first
    step.  ``run`` gives the hit's index within the set, as an embree scene of the whole set
    would."""

    def __init__(self, base, group_of, lo, hi, margin, patches, patch_ids, movers):
        self.base, self.group_of = base, group_of       # (k,) int32 over the set: a group, or -1
        self.lo, self.hi, self.margin = lo, hi, margin  # (g, 3) boxes in embree's frame, their margin
        self.patches, self.patch_ids = patches, patch_ids
        self.movers = movers                            # (g,) Mover: each group's triangles now

    @classmethod
    def build(cls, mesh, base, members, groups, margin, count, now, keep=None, moved=None):
        """``base``: embree's scene of the triangles ``members`` (sorted ids, or None: all ``count``
        of them) where an earlier version had them; ``groups``: ``Accel._groups`` (those whose
        copies there are out of date, their boxes with their ``margin``, the triangles that reach
        into them).  ``mesh(ids)``: an embree scene of the scene's triangles ``ids`` (None where
        there are none); ``now(ids)``: their corners (k, 3, 3) float64 in embree's frame and how far
        (k, 3) each may be from where a scene of them has it (``Mover.follow``); ``keep``: None, or a
        SplitScene of the same base and members whose patches of the same triangles are kept, and
        its scenes of a group's triangles where none of them is among ``moved`` (sorted ids: those
        the edit since moved) or they moved by one affine map (an object dragged)."""
        local = (lambda ids: ids) if members is None else (lambda ids: np.flatnonzero(np.isin(members, ids)))
        at = (lambda ids: ids) if members is None else members.take
        group_of = np.full(count if members is None else len(members), -1, np.int32)
        patches, patch_ids, movers = [], [], []
        for g, (ids, _, _, patch) in enumerate(groups):
            still = moved is not None and not _meet(ids, moved)
            ids = local(ids)
            group_of[ids] = g
            known = [] if keep is None else [m for m in keep.movers if np.array_equal(m.ids, ids)]
            if known and still:
                movers.append(known[0])
            else:
                corners, tolerance = now(at(ids))
                mover = known[0].follow(corners, tolerance) if known else None
                movers.append(mover or Mover(mesh(at(ids)), ids, corners))
            ids = local(patch)
            kept = [] if keep is None else [scene for scene, known in zip(keep.patches, keep.patch_ids)
                                            if np.array_equal(known, ids)]
            patches.append(kept[0] if kept else mesh(at(ids)))
            patch_ids.append(ids)
        lo = np.array([group[1] for group in groups])
        hi = np.array([group[2] for group in groups])
        return cls(base, group_of, lo, hi, margin, patches, patch_ids, movers)

    def run(self, origins, directions, dists=None, output=1):
        """The closest hits (embree's ``run`` with ``output=1``: primID, tfar, u, v)."""
        n = len(origins)
        tmax = np.broadcast_to(np.float32(1e37) if dists is None else dists, (n,)).astype(np.float32)
        # (embree writes its distances into the array it is given: a copy)
        r = self.base.run(origins, directions, dists=tmax.copy(), output=1)
        out = prim, tfar, u, v = r["primID"].astype(np.int64), r["tfar"], r["u"], r["v"]
        rows = np.flatnonzero(prim >= 0)
        group = self.group_of.take(prim.take(rows))
        rows, group = rows[group >= 0], group[group >= 0]
        o = origins.take(rows, axis=0).astype(np.float64)
        d = directions.take(rows, axis=0).astype(np.float64)
        limit = tmax.take(rows).astype(np.float64)
        start = np.zeros(len(rows))
        prim[rows], tfar[rows] = -1, tmax.take(rows)
        pending = np.arange(len(rows))
        # A ray met an out-of-date copy in a group's box: the nearest of the other triangles there
        # (its patch), else the base from the box's far side, which may meet another group's copy
        # (a box left is not met again: at most a round a group).
        for _ in range(len(self.patches)):
            if len(pending) == 0:
                break
            g = group.take(pending)
            dp = d.take(pending, axis=0)
            inv = _slab_inverse(dp)
            op = o.take(pending, axis=0)
            far = np.maximum((self.lo.take(g, axis=0) - op) * inv, (self.hi.take(g, axis=0) - op) * inv)
            leave = np.minimum(np.minimum(far[:, 0], far[:, 1]), far[:, 2])
            s = start.take(pending)
            for k in np.unique(g):
                at = np.flatnonzero(g == k)
                _nearest(self.patches[k], self.patch_ids[k], op[at] + s[at, None] * dp[at], dp[at],
                         np.minimum(leave[at], limit.take(pending[at])) - s[at], rows.take(pending[at]),
                         s[at], out)
            # (past the box no copy of its group: the base from half its margin inside)
            on = np.flatnonzero((prim.take(rows.take(pending)) < 0) & (leave < limit.take(pending)))
            s = np.maximum(leave - 0.5 * self.margin, s)
            pending, s = pending.take(on), s.take(on)
            _nearest(self.base, None, o.take(pending, axis=0) + s[:, None] * d.take(pending, axis=0),
                     d.take(pending, axis=0), limit.take(pending) - s, rows.take(pending), s, out)
            found = prim.take(rows.take(pending))
            again = self.group_of.take(np.maximum(found, 0))
            more = (found >= 0) & (again >= 0)
            pending = pending[more]
            start[pending], group[pending] = s[more], again[more]
            at = rows.take(pending)
            prim[at], tfar[at] = -1, tmax.take(at)
        # (a ray still on a copy after a round a group: none, a safeguard; left as missing it)
        # (the moved triangles' hits only nearer than the others')
        for mover in self.movers:
            if mover.back is None:
                _nearest(mover.scene, mover.ids, origins, directions, tfar, None, 0.0, out)
            else:
                # (the rays where the scene has the triangles: the same distances, the same corners)
                rt, shift = mover.back
                mapped = origins @ rt       # (float32: a few ulps, within the spawn offsets' 64)
                mapped += shift
                _nearest(mover.scene, mover.ids, mapped, directions @ rt, tfar, None, 0.0, out)
        return {"primID": prim, "tfar": tfar, "u": u, "v": v}


class Mover:
    """An embree scene (``scene``, or None) of a group of a :class:`SplitScene`'s triangles (``ids``
    within its set), built where they were (``corners`` (k, 3, 3) float32 in embree's frame: what
    embree was given, half the memory of float64's), and the
    affine map ``back`` from where they are now to there (None: they are where it has them): a ray
    mapped so meets them at the same distance (an affine map keeps a ray's parameter along its
    direction) and barycentrics.  An object dragged (moved, turned or scaled: an affine map of
    its triangles) keeps its scene from step to step instead of building it again."""

    def __init__(self, scene, ids, corners, back=None):
        self.scene, self.ids, self.back = scene, ids, back
        self.corners = np.asarray(corners, np.float32)

    def follow(self, corners, tolerance):
        """This mover for its triangles now at ``corners`` (k, 3, 3; embree's frame), or None where
        no affine map (invertible, well conditioned) takes its scene's corners to within
        ``tolerance`` (k, 3) of them: the triangles moved otherwise (a vertex dragged)."""
        if self.scene is None:
            return None
        if np.array_equal(corners.astype(np.float32), self.corners):
            return Mover(self.scene, self.ids, self.corners)
        # (float32 corners off float64's by half an ulp, within the tolerance's 16 spawn-offset ulps)
        built, now = self.corners.reshape(-1, 3), corners.reshape(-1, 3)
        # Least squares on a sample of the corners (now - built = (built - m) D + c, the mean m
        # apart: a translation gives D = 0 but for rounding, also for a flat object, whose corners
        # leave D's part along its normal free, the least-norm answer 0), then every corner.
        sample = np.linspace(0, len(built) - 1, min(len(built), MOVER_SAMPLE)).astype(np.int64)
        xs = built.take(sample, axis=0).astype(np.float64)
        zs = now.take(sample, axis=0) - xs
        m, c = xs.mean(axis=0), zs.mean(axis=0)
        d = np.linalg.lstsq(xs - m, zs - c, rcond=None)[0]                  # (3, 3), on row vectors
        a, b = np.eye(3) + d, c - m @ d                                     # now = built @ a + b
        if not np.isfinite(a).all() or np.linalg.cond(a) > MOVER_CONDITION:
            return None
        off = built @ a             # (in place: arrays of millions of corners)
        off += b
        off -= now
        np.abs(off, out=off)
        if not (np.maximum(np.maximum(off[:, 0], off[:, 1]), off[:, 2]) <= tolerance.reshape(-1)).all():
            return None
        rt = np.linalg.inv(a)           # (built = now @ rt - b @ rt)
        back = rt.astype(np.float32), (-b @ rt).astype(np.float32)
        return Mover(self.scene, self.ids, self.corners, back)


def _nearest(scene, ids, origins, directions, limit, rows, start, out):
    """Writes into ``out`` (primID, tfar, u, v arrays), at ``rows`` (None: all), the hits of embree's
    ``scene`` (None: none) nearer than ``limit`` along rays that begin ``start`` (0, or one a ray)
    along theirs; ``ids`` maps its triangles to the set's (None: the same)."""
    if scene is None:
        return
    r = scene.run(np.ascontiguousarray(origins, np.float32), np.ascontiguousarray(directions, np.float32),
                  dists=np.ascontiguousarray(np.minimum(limit, 1e37), np.float32), output=1)
    hit = np.flatnonzero(r["primID"] >= 0)
    at = hit if rows is None else rows.take(hit)
    prim, tfar, u, v = out
    found = r["primID"].take(hit)
    prim[at] = found if ids is None else ids.take(found)
    tfar[at] = r["tfar"].take(hit) + (start if np.ndim(start) == 0 else start.take(hit))
    u[at], v[at] = r["u"].take(hit), r["v"].take(hit)


def _meet(a, b):
    """Whether sorted id arrays ``a`` and ``b`` share an id."""
    at = np.searchsorted(b, a)
    return bool(np.any(b.take(np.minimum(at, len(b) - 1)) == a)) if len(b) else False


def _slab_inverse(d):
    """1 / ``d`` (n, 3) for slab tests, a zero component taken as a tiny one of its sign."""
    tiny = np.where(d < 0.0, -1e-300, 1e-300)
    return 1.0 / np.where(np.abs(d) < 1e-300, tiny, d)


def _base(scene):
    """The embree scene of the version an earlier ``Accel``'s scene (plain or split) was built of."""
    return scene.base if isinstance(scene, SplitScene) else scene


def _split_scene(scene):
    """``scene`` if it is a :class:`SplitScene`, else None."""
    return scene if isinstance(scene, SplitScene) else None


def _corner_box(v0, e1, e2):
    """(lo, hi) (3,) of triangles' corners from their (k, 3) v0, e1, e2 (k > 0)."""
    corners = np.concatenate([v0, v0 + e1, v0 + e2])
    return corners.min(axis=0), corners.max(axis=0)


def _overlapping(v0, e1, e2, lo, hi):
    """(T,) bool: the triangles (v0, e1, e2 (T, 3)) whose boxes meet the box ``lo``, ``hi`` (3,)."""
    near = np.ones(len(v0), bool)
    for k in range(3):              # (column by column: no (T, 3) temporaries)
        a = v0[:, k]
        b, c = a + e1[:, k], a + e2[:, k]
        near &= np.minimum(np.minimum(a, b), c) <= hi[k]
        near &= np.maximum(np.maximum(a, b), c) >= lo[k]
    return near


def _pushed(positions, normals, directions, offsets):
    """``positions`` moved by ``offsets`` (n,) along the ``normals``, to the side ``directions`` go."""
    side = np.where(dot(normals, directions) >= 0, 1.0, -1.0)
    return positions + (side * offsets)[:, None] * normals


def _corner_offsets(v0, e1, e2, center):
    """(T,) each triangle's part of its spawn offsets (corners ``v0``, ``v0 + e1``, ``v0 + e2``):
    _CORNER_SHARE of the largest coordinate of its corners in embree's frame (about ``center``), and
    a floor (a triangle at the very origin)."""
    a = v0 - center
    m = np.abs(a)
    b = a + e1
    np.maximum(m, np.abs(b, out=b), out=m)
    np.add(a, e2, out=b)
    np.maximum(m, np.abs(b, out=b), out=m)
    # (column by column: NumPy reduces a short inner axis ~10x slower)
    return _CORNER_SHARE * np.maximum(np.maximum(m[:, 0], m[:, 1]), m[:, 2]) + 1e-30


def _triangle_data(corners):
    """(v0, e1, e2, area, unit geometric normals) of triangles of ``corners`` (T, 3, 3) float64."""
    # Contiguous: take() on a strided view would first copy the whole array, every call.
    v0 = np.ascontiguousarray(corners[:, 0])
    e1 = corners[:, 1] - corners[:, 0]
    e2 = corners[:, 2] - corners[:, 0]
    cross = np.cross(e1, e2)
    length = np.linalg.norm(cross, axis=1)
    safe = np.where(length > 0, length, 1.0)
    ng = cross / safe[:, None]
    ng[length == 0] = (0.0, 0.0, 1.0)
    return v0, e1, e2, 0.5 * length, ng


def _moved_triangles(a, b):
    """Sorted ids (int64) of the triangles whose corners differ between two (vertices, triangles)
    of the same mesh (the same triangles of as many vertices), or None where the meshes differ."""
    if a is None or b is None:
        return None
    (va, ta), (vb, tb) = a, b
    if np.shape(va) != np.shape(vb) or np.shape(ta) != np.shape(tb) or not np.array_equal(ta, tb):
        return None
    moved = va[:, 0] != vb[:, 0]            # (column by column: faster than any(axis=1))
    moved |= va[:, 1] != vb[:, 1]
    moved |= va[:, 2] != vb[:, 2]
    corner = moved.take(ta)
    return np.flatnonzero(corner[:, 0] | corner[:, 1] | corner[:, 2])


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

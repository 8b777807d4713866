"""Uniform grid over the measurement points, rebuilt every pass, queried by photons.

Every point is inserted into each cell its search sphere (centre x_j, radius
r_j) overlaps, so a photon looks up exactly one cell.  Cells are identified by
an exact integer key (no hash collisions).  The build packs (cell key, point
id) into one int64 per entry and sorts that (NumPy's vectorised sort of 64-bit
integers is several times faster than an argsort), then finds the cell
boundaries: SmallVCM's counting sort, in NumPy.

Each entry keeps a copy of its point's position and radius next to it (contiguous
per cell, so a photon's candidates are read sequentially): the point position
relative to the entry's *cell origin* and r_j^2, in float32; the oriented normals,
which only the distance test's survivors need, stay one per point (float32).  The
photon's position is taken relative to the same cell origin, so the distance
test runs on small numbers where float32 is accurate to ~1e-7 of the cell size
whatever the scene's coordinates (algorithm.md 6.4 asks for float64 because of
absolute coordinates; relative ones need no more).

The deposit test (used for both the deposit and the visibility V(u) of a photon
path, ``algorithm.md`` 2 and 6.6; the Markov chains' V also counts the vertices in
``core/visible_cells.py``'s cells) is::

    |x_photon - x_j| < r_j   and   n_photon . n_j >= NORMAL_COS
                             and   |(x_photon - x_j) . n_j| < SLAB r_j

with both normals flipped to the side the light and the camera arrive from; the
normal test rejects photons on the back of thin walls and across corners, the slab
test photons on another surface that faces the same way within the radius: the
inside of a small box's far wall seen through its near wall (the light of a lamp in
a closed 20 cm box leaked onto its outside, 1.28 times Cycles' image where the radii
were wider than the box), a shadowed floor under a low table top.  On a curved
surface the photons within r lie within r^2 / (2 R) of the tangent plane, inside the
slab while r <= R; the edge coverage's probes search the same slab
(``core/coverage.py``).  A grid built without normals (points in volumes, which
gather in spheres) keeps none and tests the distance alone.
"""
from __future__ import annotations

import numpy as np

NORMAL_COS = 0.707          # SLR's threshold on the normals' cosine
SLAB = 0.5                  # half the gather's thickness about the point's tangent plane, in radii
MAX_AXIS_CELLS = 1 << 20    # keeps the cell key below 2^60 whatever the radius
CELL_PER_RADIUS = 2.0       # preferred cell size in median radii (benchmarks/throughput.py)
ENTRY_BUDGET = 8            # grid entries per point at most (the cell grows to fit) ...
MAX_ENTRIES = 1 << 24       # ... and in all (bounds memory for big images)
CHUNK_CANDIDATES = 1 << 18  # candidate pairs per chunk (temporaries stay in cache)
GROUP_SPAN = 3              # boxes up to this many cells per axis are listed by offset groups


class HashGrid:
    """Grid of measurement points for radius queries."""

    def __init__(self, positions, radii, normals):
        """positions (m, 3) float64; radii (m,) float64 > 0; normals (m, 3) unit, oriented, or None
        (no normal test)."""
        m = len(positions)
        self.point_count = m
        if m == 0:
            self.cell_size, self.origin, self.dims = 1.0, np.zeros(3), np.ones(3, np.int64)
            self.cell_keys = np.zeros(0, np.int64)
            self.cell_start = np.zeros(1, np.int64)
            self.entry_point = np.zeros(0, np.int32)
            self.entry_pos = np.zeros((3, 0), np.float32)
            self.entry_r2 = np.zeros(0, np.float32)
            self.point_normal = np.zeros((3, 0), np.float32)
            return
        # Column by column: NumPy reduces over axis 0 of an (m, 3) array ~10x slower (and reads
        # and gathers from contiguous columns faster).
        columns = np.ascontiguousarray(np.asarray(positions, np.float64).T)
        lo = np.array([(columns[k] - radii).min() for k in range(3)])
        hi = np.array([(columns[k] + radii).max() for k in range(3)])
        budget = min(ENTRY_BUDGET, max(4, MAX_ENTRIES // m))
        self.cell_size = c = _choose_cell_size(radii, hi - lo, budget)
        self.origin = lo
        self.dims = dims = np.floor((hi - lo) / c).astype(np.int64) + 1
        # Cells spanned by every point's bounding box.
        cmin, span = [], []
        for k in range(3):                     # per column: np.clip on (m, 3) is ~4x slower
            lo_k = np.floor((columns[k] - radii - lo[k]) / c).astype(np.int64)
            hi_k = np.floor((columns[k] + radii - lo[k]) / c).astype(np.int64)
            for a in (lo_k, hi_k):
                np.clip(a, 0, dims[k] - 1, out=a)
            cmin.append(lo_k)
            hi_k -= lo_k
            hi_k += 1
            span.append(hi_k)                  # cells spanned along axis k
        base_key = cmin[0] + dims[0] * (cmin[1] + dims[1] * cmin[2])
        del cmin
        packed_ok = int(dims.prod()) < (1 << 31)
        # Points in the order of their first cell (ties by index), then their entries one
        # offset (ox, oy, oz) of the box at a time: each group's keys come out sorted, so
        # the final sort only merges a few sorted runs (a stable sort finds them: ~3x faster
        # than sorting the entries from scratch).  Boxes wider than GROUP_SPAN cells on some
        # axis (rare: radii far above the median) are listed entry by entry instead.
        if packed_ok:
            packed = (base_key << 32) | np.arange(m, dtype=np.int64)
            packed.sort()
            order = packed & 0xFFFFFFFF
            del packed
        else:
            order = np.argsort(base_key, kind="stable")
        base_sorted = base_key.take(order)
        span_sorted = [a.take(order) for a in span]
        small = span_sorted[0] <= GROUP_SPAN
        small &= (span_sorted[1] <= GROUP_SPAN) & (span_sorted[2] <= GROUP_SPAN)
        keys, points = [], []
        for oz in range(GROUP_SPAN):
            in_z = small & (span_sorted[2] > oz)
            for oy in range(GROUP_SPAN):
                in_zy = in_z & (span_sorted[1] > oy)
                for ox in range(GROUP_SPAN):
                    sel = np.flatnonzero(in_zy & (span_sorted[0] > ox))
                    if len(sel):
                        keys.append(base_sorted.take(sel) + (ox + dims[0] * (oy + dims[1] * oz)))
                        points.append(order.take(sel))
        wide = order.take(np.flatnonzero(~small))
        if len(wide):
            sx, sy, sz = (a.take(wide) for a in span)
            count = sx * sy * sz
            entry_wide = np.repeat(wide, count)
            # Offset of each entry within its point's box: x fastest, then y, then z.
            local = np.arange(len(entry_wide)) - np.repeat(np.cumsum(count) - count, count)
            oz, rest = np.divmod(local, np.repeat(sx * sy, count))
            oy, ox = np.divmod(rest, np.repeat(sx, count))
            keys.append(base_key.take(entry_wide) + ox + dims[0] * (oy + dims[1] * oz))
            points.append(entry_wide)
        keys, point_of_entry = np.concatenate(keys), np.concatenate(points)
        del base_sorted, span_sorted, small, points
        if packed_ok:
            packed = (keys << 32) | point_of_entry
            packed.sort(kind="stable")
            keys = packed >> 32
            point_of_entry = packed & 0xFFFFFFFF
            del packed
        else:
            by_key = np.argsort(keys, kind="stable")
            keys = keys.take(by_key)
            point_of_entry = point_of_entry.take(by_key)
        first = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
        self.cell_keys = keys[first]
        self.cell_start = np.r_[first, len(keys)].astype(np.int64)
        self.entry_point = point_of_entry.astype(np.int32)
        del keys
        # Entry data, positions relative to the entry's cell origin (decoded once per cell).
        cell_keys = self.cell_keys
        per_cell = np.diff(self.cell_start)
        cell_xyz = (cell_keys % dims[0], cell_keys // dims[0] % dims[1], cell_keys // (dims[0] * dims[1]))
        self.entry_pos = np.empty((3, len(point_of_entry)), np.float32)
        for k in range(3):
            self.entry_pos[k] = columns[k].take(point_of_entry) - np.repeat(lo[k] + cell_xyz[k] * c, per_cell)
        # (radii past 1.8e19, in scenes scaled to 1e30, square to float32's largest, not infinity)
        squared = np.minimum(np.asarray(radii, np.float64) ** 2, np.finfo(np.float32).max)
        self.entry_r2 = squared.astype(np.float32).take(point_of_entry)
        # (3, m) float32, or (3, 0): a grid without normals
        self.point_normal = (np.ascontiguousarray(np.asarray(normals).T, np.float32) if normals is not None
                             else np.zeros((3, 0), np.float32))

    FIELDS = ("cell_size", "origin", "dims", "cell_keys", "cell_start", "entry_point", "entry_pos",
              "entry_r2", "point_normal", "point_count")

    def to_arrays(self) -> dict:
        """Plain arrays (for a worker process); :meth:`from_arrays` restores the grid."""
        return {f: np.asarray(getattr(self, f)) for f in self.FIELDS}

    @classmethod
    def from_arrays(cls, d) -> "HashGrid":
        grid = cls.__new__(cls)
        for f in cls.FIELDS:
            setattr(grid, f, d[f])
        grid.cell_size = float(grid.cell_size)
        grid.point_count = int(grid.point_count)
        return grid

    @property
    def entry_count(self) -> int:
        return int(len(self.entry_point))

    @property
    def has_normals(self) -> bool:
        """Whether the grid holds its points' normals (and the query tests them)."""
        return self.point_count > 0 and self.point_normal.shape[1] == self.point_count

    def _cells(self, x):
        """Cell keys (n,) of positions x (n, 3), -1 outside the grid, and integer cell coordinates."""
        cell = np.floor((x - self.origin) / self.cell_size).astype(np.int64)
        inside = (cell[:, 0] >= 0) & (cell[:, 0] < self.dims[0])     # columns: faster than all(axis=1)
        for k in (1, 2):
            inside &= (cell[:, k] >= 0) & (cell[:, k] < self.dims[k])
        keys = cell[:, 0] + self.dims[0] * (cell[:, 1] + self.dims[1] * cell[:, 2])
        return np.where(inside, keys, -1), cell

    def query(self, x, normals, directions=None, inner=False):
        """Pairs (photon index, point id) that pass the deposit test.

        x : (n, 3) float64 photon positions; normals : (n, 3) unit geometric normals
        flipped towards the side the photon arrived from, or None for a grid built without
        normals; directions : optional (n, 3) unit vectors, whose cosine with each pair's
        point normal is returned (a grid with normals only).
        Returns ``(photon_idx (k,) int64, point_ids (k,) int64, cosines (k,) or None)``,
        grouped by photon (photons in the order of their cells, not of ``x``); with ``inner``
        also a (k,) bool: the pair lies within half the point's radius.
        """
        n = len(x)
        if n == 0 or len(self.cell_keys) == 0:
            empty = (np.zeros(0, np.int64), np.zeros(0, np.int64),
                     None if directions is None else np.zeros(0))
            return empty + (np.zeros(0, bool),) if inner else empty
        if (normals is None) == self.has_normals or (directions is not None and not self.has_normals):
            raise ValueError("HashGrid.query: normals (and directions) go with a grid built with normals")
        keys, cell = self._cells(x)
        pos = np.minimum(np.searchsorted(self.cell_keys, keys), len(self.cell_keys) - 1)
        found = (self.cell_keys[pos] == keys) & (keys >= 0)
        start = self.cell_start[pos]
        count = np.where(found, self.cell_start[pos + 1] - start, 0)
        # Photons cell by cell: the candidates of neighbouring photons are then the same
        # entries, read while still in cache (1.3x faster than in photon order).
        photons = np.flatnonzero(count)
        photons = photons[np.argsort(keys[photons], kind="stable")]
        count = count[photons]
        start = start[photons]
        # Photon positions relative to their cell origin (as the entries), normals, directions.
        rel = (x.take(photons, axis=0) - (self.origin + cell.take(photons, axis=0) * self.cell_size)
               ).T.astype(np.float32)
        nrm = None if normals is None else normals.take(photons, axis=0).T.astype(np.float32)
        dirs = None if directions is None else directions.take(photons, axis=0).T.astype(np.float32)
        out_p, out_j, out_c, out_i = [], [], [], []
        pn = self.point_normal                 # (3, m): read by the pairs that pass the distance test
        bounds = np.cumsum(count)
        lo = 0
        while lo < len(photons):
            # Photons [lo, hi) whose candidates fit in one chunk (at least one photon).
            base = bounds[lo - 1] if lo else 0
            hi = max(lo + 1, int(np.searchsorted(bounds, base + CHUNK_CANDIDATES, side="right")))
            cnt = count[lo:hi]
            ends = np.cumsum(cnt)
            eidx = np.arange(ends[-1]) + np.repeat(start[lo:hi] - (ends - cnt), cnt)
            # Distance test on every candidate (the offsets kept for the slab test).
            d2 = np.zeros(len(eidx), np.float32)
            sq = np.empty(len(eidx), np.float32)
            offsets = []
            for axis in range(3):
                d = self.entry_pos[axis].take(eidx)
                d -= np.repeat(rel[axis, lo:hi], cnt)
                offsets.append(d)
                d2 += np.multiply(d, d, out=sq)
            r2 = self.entry_r2.take(eidx)
            near = np.flatnonzero(d2 < r2)
            j = self.entry_point.take(eidx.take(near))
            ph = np.repeat(np.arange(lo, hi), cnt)[near]
            r2 = r2.take(near)
            if inner:
                half = 4.0 * d2.take(near) < r2
            if nrm is not None:
                # Normal and slab tests on the survivors.
                p0, p1, p2 = pn[0].take(j), pn[1].take(j), pn[2].take(j)
                cos_n = p0 * nrm[0].take(ph)
                cos_n += p1 * nrm[1].take(ph)
                cos_n += p2 * nrm[2].take(ph)
                h = offsets[0].take(near) * p0
                h += offsets[1].take(near) * p1
                h += offsets[2].take(near) * p2
                h *= h
                ok = np.flatnonzero((cos_n >= NORMAL_COS) & (h < SLAB * SLAB * r2))
                j, ph = j.take(ok), ph.take(ok)
                if inner:
                    half = half.take(ok)
            if inner:
                out_i.append(half)
            out_p.append(photons[ph])
            out_j.append(j.astype(np.int64))
            if dirs is not None:
                cos_d = pn[0].take(j) * dirs[0].take(ph)
                cos_d += pn[1].take(j) * dirs[1].take(ph)
                cos_d += pn[2].take(j) * dirs[2].take(ph)
                out_c.append(cos_d)
            lo = hi
        cat = (lambda a: np.concatenate(a)) if out_p else (lambda a: np.zeros(0, np.int64))
        cos = None if dirs is None else (np.concatenate(out_c) if out_c else np.zeros(0))
        if inner:
            return cat(out_p), cat(out_j), cos, (np.concatenate(out_i) if out_i else np.zeros(0, bool))
        return cat(out_p), cat(out_j), cos


def _choose_cell_size(radii, extent, budget):
    """Cell edge: about CELL_PER_RADIUS median radii, grown until the entries fit the budget."""
    r_med = float(np.median(radii))
    c = max(CELL_PER_RADIUS * r_med, float(np.max(extent)) / (MAX_AXIS_CELLS - 2), 1e-30)
    sample = radii if len(radii) <= 65536 else radii[:: len(radii) // 65536 + 1]
    for _ in range(200):
        # Expected cells per point for a box of side 2r at a random offset: (2r/c + 1)^3.
        if np.mean((2.0 * sample / c + 1.0) ** 3) <= budget:
            break
        c *= 1.25
    return c


def brute_force_query(x, normals, positions, radii, point_normals, inner=False):
    """Reference for tests: all (photon, point) pairs passing the deposit test, in float64
    (the distance test alone when ``normals`` is None); with ``inner`` also whether each pair
    lies within half the point's radius."""
    d2 = ((x[:, None, :] - positions[None, :, :]) ** 2).sum(axis=2)
    ok = d2 < radii[None, :] ** 2
    if normals is not None:
        ok &= normals @ point_normals.T >= NORMAL_COS
        h = (x[:, None, :] - positions[None, :, :]) * point_normals[None, :, :]
        ok &= np.abs(h.sum(axis=2)) < SLAB * radii[None, :]
    p, j = np.nonzero(ok)
    if inner:
        return p.astype(np.int64), j.astype(np.int64), 4.0 * d2[p, j] < radii[j] ** 2
    return p.astype(np.int64), j.astype(np.int64)

"""The surface the camera has seen so far, as grid cells: a visibility that holds still between passes.

Why.  AMCMCPPM's chains sample photon paths uniformly over the visible set V of primary
sample space, and the estimate is unbiased for *any* V that holds still, if the paths
outside V that contribute are counted some other way (here: by the uniform samples; paths in
V that contribute nothing are recorded with zero).  Hachisuka and Jensen take V =
"contributes to a point of this pass".  With SPPM's fresh, jittered measurement points every
pass that set changes from pass to pass, and the chains carry their states over: a state
survives into the next pass only if it is visible there too, so the surviving states are
denser where the last pass's points covered the surface better.  Where the gather discs leave
gaps (radii below the point spacing: late passes, or surfaces seen at a grazing angle) the
coverage varies across the image, and with a few chain iterations per pass the image drifts:
measured on a floor under a constant world at 64x64 with a 1.5-pixel initial radius, the
near floor 28 % too bright and the far floor 14 % too dark after 32 passes (PPM on the same
scene: within 1 %).

What.  V is now "has a non-delta vertex, with a normal of the same major axis and sign, in a
cell that the gather box (x +- r_1) of a measurement point of an earlier or this pass
overlapped".  Paths that contribute to a point outside every cell are left to the uniform
samples, which count them directly (``core/mcmc.py``, "Two parts"): V only grows, and no
chain state ever drops out of it.  Cells are between one and two of the point's initial
radius r_1 wide (levels of powers of two from a base fixed by the first pass), so on a
surface the camera sees every cell is overlapped already in the first pass whatever the
gather radii have shrunk to, and the union over passes only grows at the edges.  The set is
therefore almost the same in every pass and the surviving states stay uniform over it.  On
the floor above, after 24 passes: within 1 % near and far with the default radius, within
5 % with 1.5 pixels (``tests/core/test_closed_form.py``).  The normal's axis keeps the backs of
thin walls out; a surface behind another within a cell (a slab thinner than a cell) is in V
and only costs chain steps.  The integrator adds the points of the first passes and then of
every eighth (``CELL_PASSES``, ``CELL_EVERY``).

Lone points add no cells: a point counts only when the cell four times as wide around it
holds at least four of the pass's points (``DENSITY_LEVELS``, ``MIN_POINTS``).  Points
seen through a glass ball or in a curved mirror lie metres apart, at other places every
pass; their cells, added pass after pass, made V many times larger than the surface the
camera sees (``small_view`` at 128x96, a ball on sunlit ground: 8 times PPM's visible
fraction after 40 passes, now 1.2 to 1.5 times), and the chains spent their steps there.
The paths that reach them only count through the uniform samples.

Cells are exact integer keys (20 bits per axis around the first pass's points, then a
3-bit normal axis), one sorted array per level; points far outside that range clamp to
the border cells, which can only make V larger.  The estimate is unbiased whatever the
cells hold, as long as they hold still: the cells then affect efficiency, never correctness.
Their growth does not hold still: after it the carried states were spread over the old part
while the normaliser counted all of it, until the chains mixed (glass505 of the glass parity
family: the chains 1.0094 +- 0.0024 of PPM's image).  Cells from the first pass alone removed
that but cost ``small_view`` 1.6 times the relMSE (README, "A visible set that holds still",
stops 76 and 77).  So each cell keeps the generation it came in (``extended``'s ``generation``,
:meth:`entry`), and a chain's run keeps the generation it began in: for it the set holds still
(``core/mcmc.py``, "Generations").
"""
from __future__ import annotations

import numpy as np

AXIS_BITS = 20
AXIS_OFFSET = 1 << (AXIS_BITS - 1)        # cell 0 of the first pass sits mid-range
LEVEL_RANGE = 24                           # levels -24..24: cell sizes of 2^-24..2^24 base
MIN_POINTS = 4                             # a pass's points in the cell 2^DENSITY_LEVELS times
DENSITY_LEVELS = 2                         # as wide around a point, for the point to count
NEVER = np.iinfo(np.int64).max           # the generation of a vertex in no cell (VisibleCells.entry)
VOLUME_AXIS = 6                            # the "normal axis" of points in scattering volumes


def normal_axis(normals):
    """(n,) int64 in 0..5: the major axis k of each normal and its sign, 2 k + (n_k < 0)."""
    x, y, z = (normals[:, k] for k in range(3))
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    use_x = (ax >= ay) & (ax >= az)
    use_y = ~use_x & (ay >= az)
    value = np.where(use_x, x, np.where(use_y, y, z))
    return np.where(use_x, 0, np.where(use_y, 2, 4)) + (value < 0)


class VisibleCells:
    """Sorted cell keys per level; :meth:`extended` adds a pass's points, :meth:`contains` tests photons."""

    def __init__(self, base=0.0, origin=None, levels=None, gens=None):
        self.base = float(base)                             # cell size of level 0 (0: no points yet)
        self.origin = np.zeros(3) if origin is None else np.asarray(origin, np.float64)
        self.levels = dict(levels or {})                    # level -> sorted unique int64 keys
        # level -> (keys,) int64: the generation each cell was added in (``extended``'s
        # ``generation``; all 0 where not given)
        self.gens = dict(gens) if gens is not None else {
            lv: np.zeros(len(k), np.int64) for lv, k in self.levels.items()}
        self._box = None                                    # world bounds of all cells, on demand

    @property
    def generation(self) -> int:
        """The newest generation of the cells (0 for an empty set)."""
        return max((int(g.max()) for g in self.gens.values() if len(g)), default=0)

    @property
    def key_count(self) -> int:
        return int(sum(len(k) for k in self.levels.values()))

    def _keys(self, x, level, axis):
        size = self.base * 2.0 ** level
        key = axis.copy()
        for k in range(3):
            c = np.floor((x[:, k] - self.origin[k]) / size).astype(np.int64) + AXIS_OFFSET
            np.clip(c, 1, (1 << AXIS_BITS) - 2, out=c)
            key |= c << (3 + AXIS_BITS * (2 - k))
        return key

    def _ball_keys(self, x, r, level, axis):
        """Sorted unique keys of every cell of ``level`` (at least ``r`` wide) that the boxes x +- r
        overlap: the point's own cell and the neighbours its box reaches (up to 8 of 27)."""
        size = self.base * 2.0 ** level
        rho = r / size
        cells, code = [], axis.copy()
        for k in range(3):                     # column by column (NumPy is slow across rows)
            t = (x[:, k] - self.origin[k]) / size
            c = np.floor(t)
            f = t - c
            c = c.astype(np.int64) + AXIS_OFFSET
            np.clip(c, 1, (1 << AXIS_BITS) - 2, out=c)
            cells.append(c)
            # Which neighbours the box reaches: bit 0 the lower one, bit 1 the upper one.
            code += ((f < rho) + 2 * (f > 1.0 - rho).astype(np.int64)) << (3 + 2 * k)
        # Many points share a cell and a reach: one row each before expanding (cells relative
        # to this batch's lowest, 18 bits per axis, and the 9-bit code in one int64 when they fit).
        lo = [int(c.min()) for c in cells]
        rel = [c - lo_k for c, lo_k in zip(cells, lo)]
        m18 = (1 << 18) - 1
        if max(int(q.max()) for q in rel) <= m18:
            u = np.unique(((rel[0] << 18 | rel[1]) << 18 | rel[2]) << 9 | code)
            cells = [(u >> 45) + lo[0], ((u >> 27) & m18) + lo[1], ((u >> 9) & m18) + lo[2]]
            code = u & 511
        else:
            packed = (cells[0] << AXIS_BITS | cells[1]) << AXIS_BITS | cells[2]
            order = np.lexsort((code, packed))
            packed, code = packed.take(order), code.take(order)
            first = np.ones(len(packed), bool)
            first[1:] = (np.diff(packed) != 0) | (np.diff(code) != 0)
            packed, code = packed[first], code[first]
            mask = (1 << AXIS_BITS) - 1
            cells = [packed >> (2 * AXIS_BITS), (packed >> AXIS_BITS) & mask, packed & mask]
        axis = code & 7
        reach = [(code >> (3 + 2 * k)) & 3 for k in range(3)]
        keys = []
        for d in np.array(np.meshgrid((-1, 0, 1), (-1, 0, 1), (-1, 0, 1), indexing="ij")).reshape(3, -1).T:
            ok = np.ones(len(axis), bool)
            for k in range(3):
                if d[k]:
                    ok &= (reach[k] & (1 if d[k] < 0 else 2)) > 0
            sel = np.flatnonzero(ok)
            if len(sel):
                n = [cells[k].take(sel) + d[k] for k in range(3)]
                keys.append((((n[0] << AXIS_BITS | n[1]) << AXIS_BITS | n[2]) << 3) | axis.take(sel))
        return np.unique(np.concatenate(keys))

    def extended(self, positions, normals, radii, min_points=MIN_POINTS, volume=False,
                 generation=0) -> "VisibleCells":
        """A new set: these cells plus those of points (positions, oriented normals) each in a cell
        at least ``radii`` wide, counting only points with ``min_points`` of them in the cell
        2^DENSITY_LEVELS times as wide around them (1: every point).  ``volume``: the points lie
        in scattering volumes (no normals; cells of their own, :meth:`contains_volume`).  The new
        cells are of ``generation`` (the integrator's pass; :meth:`entry`)."""
        positions = np.asarray(positions, np.float64)
        radii = np.asarray(radii, np.float64)
        ok = np.isfinite(radii) & (radii > 0) & np.isfinite(positions).all(axis=1)
        if volume:
            normals = np.zeros((len(positions), 3))
        if not ok.all():
            positions, normals, radii = positions[ok], np.asarray(normals)[ok], radii[ok]
        if len(radii) == 0:
            return self
        base, origin = self.base, self.origin
        if base <= 0:
            base, origin = float(np.median(radii)), positions.min(axis=0)
        out = VisibleCells(base, origin, self.levels, self.gens)
        # The smallest level whose cells are at least as large as the point's radius.
        level = np.clip(np.ceil(np.log2(radii / base) - 1e-9), -LEVEL_RANGE, LEVEL_RANGE).astype(np.int64)
        axis = (np.full(len(radii), VOLUME_AXIS, np.int64) if volume
                else normal_axis(np.asarray(normals, np.float64)))
        for lv in range(int(level.min()), int(level.max()) + 1):
            sel = np.flatnonzero(level == lv)
            if min_points > 1 and len(sel):
                own = out._keys(positions.take(sel, axis=0), lv + DENSITY_LEVELS, axis.take(sel))
                _, inverse, counts = np.unique(own, return_inverse=True, return_counts=True)
                sel = sel[counts[inverse] >= min_points]
            if len(sel) == 0:
                continue
            keys = out._ball_keys(positions.take(sel, axis=0), radii.take(sel), lv, axis.take(sel))
            old = out.levels.get(lv)
            gens = np.full(len(keys), generation, np.int64)
            if old is not None:
                keys = keys[~_in_sorted(keys, old)]          # after the first passes, mostly none
                if len(keys) == 0:
                    continue
                keys = np.concatenate([old, keys])
                order = np.argsort(keys, kind="stable")
                keys = keys.take(order)
                gens = np.concatenate([out.gens[lv], np.full(len(order) - len(old), generation,
                                                             np.int64)]).take(order)
            out.levels[lv] = keys
            out.gens[lv] = gens
        return out

    def bounds(self):
        """(lo, hi): world-space corners of a box around every cell (empty set: lo > hi)."""
        if self._box is None:
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            mask = (1 << AXIS_BITS) - 1
            for lv, keys in self.levels.items():
                if len(keys) == 0:
                    continue
                size = self.base * 2.0 ** lv
                for k in range(3):
                    c = (keys >> (3 + AXIS_BITS * (2 - k))) & mask
                    c0, c1 = int(c.min()), int(c.max())
                    # A border cell holds everything clamped into it, out to infinity.
                    lo[k] = min(lo[k], -np.inf if c0 <= 1 else self.origin[k] + (c0 - AXIS_OFFSET) * size)
                    hi[k] = max(hi[k], np.inf if c1 >= mask - 1 else
                                self.origin[k] + (c1 + 1 - AXIS_OFFSET) * size)
            self._box = (lo, hi)
        return self._box

    def contains_volume(self, x):
        """(n,) bool: the photon vertices ``x`` in scattering volumes lie in a visible volume cell."""
        return self.contains(x, None, volume=True)

    def contains(self, x, normals, volume=False):
        """(n,) bool: the photon vertices ``x`` with oriented normals ``normals`` lie in a visible cell."""
        return self.entry(x, normals, volume) < NEVER

    def entry(self, x, normals, volume=False):
        """(n,) int64: the oldest generation of the visible cells that hold the photon vertices ``x``
        with oriented normals ``normals`` (``NEVER`` for none)."""
        inside = np.full(len(x), NEVER, np.int64)
        if not self.levels or len(x) == 0:
            return inside
        # Most photon vertices of a big scene are far from what the camera sees: a box test first.
        lo, hi = self.bounds()
        near = np.ones(len(x), bool)
        for k in range(3):
            near &= (x[:, k] >= lo[k]) & (x[:, k] <= hi[k])
        sel = np.flatnonzero(near)
        if len(sel) == 0:
            return inside
        if len(sel) < len(x):
            x = x.take(sel, axis=0)
            normals = None if volume else normals.take(sel, axis=0)
        axis = np.full(len(x), VOLUME_AXIS, np.int64) if volume else normal_axis(normals)
        found = np.full(len(sel), NEVER, np.int64)
        for lv, keys in self.levels.items():
            if len(keys) == 0:
                continue
            q = self._keys(x, lv, axis)
            i = np.searchsorted(keys, q)
            np.minimum(i, len(keys) - 1, out=i)
            gen = np.where(keys.take(i) == q, self.gens[lv].take(i), NEVER)
            np.minimum(found, gen, out=found)
        inside[sel] = found
        return inside

    def to_arrays(self) -> dict:
        """Plain arrays (for a worker process); :meth:`from_arrays` restores the set."""
        lv = np.array(sorted(self.levels), np.int64)
        keys = [self.levels[int(v)] for v in lv]
        return {"base": np.float64(self.base), "origin": self.origin, "levels": lv,
                "counts": np.array([len(k) for k in keys], np.int64),
                "keys": np.concatenate(keys) if keys else np.zeros(0, np.int64),
                "gens": (np.concatenate([self.gens[int(v)] for v in lv]) if keys
                         else np.zeros(0, np.int64))}

    @staticmethod
    def from_arrays(d) -> "VisibleCells":
        bounds = np.concatenate([[0], np.cumsum(d["counts"])])
        levels = {int(v): d["keys"][bounds[i]:bounds[i + 1]] for i, v in enumerate(d["levels"])}
        gens = {int(v): d["gens"][bounds[i]:bounds[i + 1]] for i, v in enumerate(d["levels"])}
        return VisibleCells(float(d["base"]), d["origin"], levels, gens)


def _in_sorted(q, keys):
    """(n,) bool: which of ``q`` occur in the sorted array ``keys``."""
    if len(keys) == 0:
        return np.zeros(len(q), bool)
    i = np.searchsorted(keys, q)
    np.minimum(i, len(keys) - 1, out=i)
    return keys.take(i) == q

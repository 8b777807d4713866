"""How much of a measurement point's gather disc lies on a surface that photons can land on.

A point gathers the photons within its radius r whose surface faces as its own does
(``core/hash_grid.py``) and divides their flux by the disc's area, pi r^2.  Near an edge of
its surface (a table's rim, a floor that ends at a wall, a leaf cut by an alpha map) part of
that disc holds no surface and receives no photons, so the estimate is too dark, by up to
half at the edge itself (README, "Edges").  The disc's *covered* share c corrects it: the
kernel becomes 1 / (c pi r^2).

c is estimated with probes on the point's tangent plane: ``DIRECTIONS`` directions, turned by a
random angle per point, at the radii of ``RINGS`` (each ring the middle of an equal share of the
disc's area).  A probe at offset o is covered when a ray from p + h n + o along -n (h =
``LIFT`` r) meets, within 2 h, a surface that faces as the point's does (``NORMAL_COS``), whose
material has a lobe photons deposit on and which is not cut away there by its opacity.  That is
the grid's own notion of the disc: it gathers photons within the radius and within its slab, h
above and below the tangent plane, whatever lies between (a thin wall standing on a floor that
runs on under it does not stop the photons on its other side), so the probes do not look for
walls either; a floor that ends at a wall, or a surface that ends at an edge, has nothing below
the probes beyond it.

The share is the covered probes' (each ring weighs the same), kept at least ``MIN_COVERAGE``.
Inside a surface every probe is covered and c is exactly 1, so the estimate there is unchanged.
On a sphere the area within a ball of radius r about a point of it is pi r^2 whatever the
sphere's radius (Archimedes); the probes reach h above and below the plane, which holds the
sphere for radii up to about its own.
"""
from __future__ import annotations

import numpy as np

from .hash_grid import NORMAL_COS, SLAB
from .procedural import Rays
from .sampling import dot

DIRECTIONS = 8
# Radii of the probe rings as fractions of r: the midpoints (in area) of four equal shares of the
# disc, sqrt((k + 1/2) / 4).  Against the exact share of a disc cut by a straight edge at any
# distance, rings so placed are off by at most 5.4 % with two rings, 3.7 % with three and 2.8 %
# with four (probes in the directions being exact there).
RINGS = tuple(float(np.sqrt((k + 0.5) / 4)) for k in range(4))
LIFT = SLAB               # height of the probes' rays above the tangent plane, in radii: the grid's slab
MIN_COVERAGE = 0.25       # (a point on a sliver of a surface keeps at most 4 times the kernel)
PASSES = 3                # surfaces a probe's ray goes through (glass) before it gives up


def disc_coverage(ctx, position, normal, radius, rng):
    """(m,) float64 covered share of the discs of radii ``radius`` (m,) about ``position`` (m, 3) on
    the planes of unit ``normal`` (m, 3): see the module docstring.  ``ctx``: the scene's
    :class:`~core.context.RenderContext`; ``rng``: the turn of each point's probes.  The outer
    ring is probed first, the others only where it is not wholly covered (an edge that cuts the
    disc by more than 7 % of its radius crosses it): most discs near an edge are still whole."""
    m = len(position)
    if m == 0:
        return np.ones(0)
    n = np.asarray(normal, np.float64)
    u, v = _tangent_basis(n)
    turn = rng.random(m)[:, None] + np.arange(DIRECTIONS)[None, :] / DIRECTIONS      # (m, D) turns
    angle = 2.0 * np.pi * turn
    dirs = np.cos(angle)[..., None] * u[:, None] + np.sin(angle)[..., None] * v[:, None]   # (m, D, 3)
    outer = _probe(ctx, position, n, dirs, radius, RINGS[-1])
    share = np.ones(m)
    cut = np.flatnonzero(~outer.all(axis=1))
    if len(cut):
        p, nc, dc, rc = position.take(cut, axis=0), n.take(cut, axis=0), dirs.take(cut, axis=0), radius.take(cut)
        rings = [_probe(ctx, p, nc, dc, rc, ring) for ring in RINGS[:-1]] + [outer.take(cut, axis=0)]
        share[cut] = np.concatenate(rings, axis=1).mean(axis=1)
    return np.maximum(share, MIN_COVERAGE)


def _probe(ctx, position, n, dirs, radius, ring):
    """(m, D) bool: which probes at ``ring`` r along ``dirs`` (m, D, 3) are covered.  A ray that
    first meets a surface it does not land on (glass or a mirror, with no lobe to land on; one
    that faces otherwise, or is cut away there by its opacity) goes on through it, up to
    ``PASSES`` times, as the grid gathers through whatever lies between; a glass face resting on
    another surface counts as that surface (``Accel.with_contacts``: the floor under a glass
    block)."""
    m, k = dirs.shape[:2]
    lift = LIFT * radius
    starts = (position + n * lift[:, None])[:, None, :] + dirs * (ring * radius)[:, None, None]
    starts = starts.reshape(-1, 3)
    down = -np.repeat(n, k, axis=0)
    left = 2.0 * np.repeat(lift, k)                      # length left to each ray
    covered = np.zeros(m * k, bool)
    rows = np.arange(m * k)
    origins = starts
    for _ in range(PASSES):
        d = down.take(rows, axis=0)
        below = ctx.accel.with_contacts(ctx.accel.intersect(origins, d, left.take(rows)), origins, d)
        h = np.flatnonzero(below.is_hit)
        if len(h) == 0:
            break
        prim = below.prim_ids.take(h)
        mats = ctx.material_ids.take(prim)
        facing = np.abs(dot(ctx.accel.geometric_normals.take(prim, axis=0), d.take(h, axis=0)))
        land = ctx.table.has_nondelta.take(mats) & (facing >= NORMAL_COS)
        if ctx.has_transparency:
            t = np.flatnonzero(land & ctx.see_through.take(mats))
            if len(t):
                ht = h.take(t)
                at = ctx.accel.hit_positions(prim.take(t), below.b1.take(ht), below.b2.take(ht))
                land[t] = ctx._opacity(prim.take(t), below.b1.take(ht), below.b2.take(ht), at,
                                       Rays(-d.take(ht, axis=0))) > 0.0
        covered[rows.take(h[land])] = True
        # On through the surfaces it did not land on, with what is left of the ray.
        on = h[~land]
        if len(on) == 0:
            break
        t_hit = below.t.take(on).astype(np.float64)
        hit_at = origins.take(on, axis=0) + d.take(on, axis=0) * t_hit[:, None]
        rows_on = rows.take(on)
        left[rows_on] -= t_hit
        keep = np.flatnonzero(left.take(rows_on) > 0)
        rows = rows_on.take(keep)
        crossed = below.prim_ids.take(on.take(keep))
        through = ctx.accel.geometric_normals.take(crossed, axis=0)
        origins = ctx.accel.spawn(hit_at.take(keep, axis=0), through, down.take(rows, axis=0), crossed)
    return covered.reshape(m, k)


def _tangent_basis(n):
    """Two unit vectors (m, 3) each, perpendicular to the unit rows of ``n`` and to each other."""
    a = np.where((np.abs(n[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    u = np.cross(n, a)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(n, u)


# Neighbouring pixels' points lie on one plane when their normals agree this well and the step
# between them leans out of the plane by at most this sine.
PLANE_COS = 0.999
PLANE_SIN = 0.05


def edge_candidates(points, width, height, reach):
    """(m,) bool: the measurement points ``points`` (one per pixel of a ``width`` x ``height``
    window) within ``reach`` pixels of a pixel whose neighbour lies off its plane (or has no
    point).  Elsewhere the points around a pixel, and so its gather disc of at most ``reach``
    pixel footprints, lie on one plane: its coverage is 1 and needs no probes.  (A disc partly
    hidden behind something in front shows that something's pixels: a candidate too.)"""
    n_pix = width * height
    index = np.full(n_pix, -1, np.int64)
    index[points.pixel_ids] = np.arange(points.count)
    index = index.reshape(height, width)
    pos, ng = points.position, points.ng.astype(np.float64)
    broken = np.zeros((height, width), bool)
    for a, b in (((slice(None), slice(0, -1)), (slice(None), slice(1, None))),
                 ((slice(0, -1), slice(None)), (slice(1, None), slice(None)))):
        ia, ib = index[a], index[b]
        both = (ia >= 0) & (ib >= 0)
        step = np.zeros(ia.shape, bool)
        ja, jb = ia[both], ib[both]
        d = pos.take(jb, axis=0) - pos.take(ja, axis=0)
        na, nb = ng.take(ja, axis=0), ng.take(jb, axis=0)
        off = np.abs(dot(d, na)) > PLANE_SIN * np.sqrt(dot(d, d))
        step[both] = (dot(na, nb) < PLANE_COS) | off
        step |= both != ((ia >= 0) | (ib >= 0))          # one of the two has no point
        broken[a] |= step
        broken[b] |= step
    near = _dilate(broken, int(np.ceil(reach)))
    return near.ravel().take(points.pixel_ids)


def _dilate(mask, k):
    """``mask`` (H, W) grown by ``k`` pixels in x and y (a square of side 2k + 1)."""
    out = mask.copy()
    for axis in (1, 0):
        grown = out.copy()
        for s in range(1, k + 1):
            if axis == 1:
                grown[:, s:] |= out[:, :-s]
                grown[:, :-s] |= out[:, s:]
            else:
                grown[s:] |= out[:-s]
                grown[:-s] |= out[s:]
        out = grown
    return out


def point_coverage(ctx, points, radius, width, height, reach, rng, inner=False):
    """(coverage (m,), inner coverage (m,) or None) of the points' discs of ``radius`` (m,) and,
    with ``inner``, of half of it: 1 away from edges (:func:`edge_candidates`), probed near them
    (:func:`disc_coverage`; the inner disc only where the outer one is not wholly covered, as it
    lies inside it).  Returns (None, None) when every disc is whole."""
    near = np.flatnonzero(edge_candidates(points, width, height, reach))
    if len(near) == 0:
        return None, None
    c = np.ones(points.count)
    ng = points.ng.take(near, axis=0).astype(np.float64)
    pos = points.position.take(near, axis=0)
    c[near] = disc_coverage(ctx, pos, ng, radius.take(near), rng)
    if (c == 1.0).all():
        return None, None
    c_inner = None
    if inner:
        c_inner = np.ones(points.count)
        part = np.flatnonzero(c.take(near) < 1.0)
        rows = near.take(part)
        c_inner[rows] = disc_coverage(ctx, pos.take(part, axis=0), ng.take(part, axis=0),
                                      0.5 * radius.take(rows), rng)
    return c, c_inner

"""Cryptomatte: per pixel, the ids of the objects, materials and assets it shows and their coverage.

As Cycles writes its CryptoObject, CryptoMaterial and CryptoAsset passes (``film/data_passes.h``,
``film/cryptomatte_passes.h``): each camera ray adds, at every surface its transparent bounces
reach, the weight of what reaches that surface times the surface's opacity, 1 - mean(transparency),
to the slot of that surface's id; a pixel's slots are summed over its samples (passes here), sorted
by weight and divided by the samples.  Cycles' sample crosses a surface by picking its Transparent
BSDF and carries the weight it leaves; ours follows every crossing at once with that weight (the
same mean).  Rays that meet nothing add nothing (a pixel's weights sum to its coverage).

An id is MurmurHash3 (x86, 32 bits, seed 0) of a name turned into a float32 as Cycles does
(``util_hash_to_float``: the bits as a float, exponent kept within 1..254 so that it is finite and
not 0); the add-on computes them (``Scene.cryptomatte_ids``) and writes the manifest.
"""
from __future__ import annotations

import struct

import numpy as np

from .scene import VISIBLE_CAMERA

# The kinds of Cryptomatte pass, their column of Scene.cryptomatte_ids and core data pass names.
KINDS = ("crypto_object", "crypto_material", "crypto_asset")
# Surfaces a camera ray's coverage follows through transparent ones, and the weight below which
# it stops.
MAX_SURFACES = 16
MIN_WEIGHT = 1e-6


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32 of ``data`` (Cryptomatte's hash of a name)."""
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed & mask
    n = len(data) // 4
    for (k,) in struct.iter_unpack("<I", data[:4 * n]):
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        h ^= (k * c2) & mask
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    tail = data[4 * n:]
    if tail:
        k = int.from_bytes(tail, "little")
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        h ^= (k * c2) & mask
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    h ^= h >> 16
    return h


def hash_to_float(h: int) -> float:
    """Cycles' ``util_hash_to_float``: the hash's bits as a float32, its exponent within 1..254."""
    exponent = min(max((h >> 23) & 0xFF, 1), 254)
    bits = (h & 0x807FFFFF) | (exponent << 23)
    return struct.unpack("<f", struct.pack("<I", bits))[0]


def name_id(name: str) -> tuple[float, str]:
    """(float id, manifest hex) of ``name``: the pass value and the manifest's "%08x" of the hash."""
    h = murmur3_32(name.encode("utf-8"))
    return hash_to_float(h), f"{h:08x}"


def coverage(ctx, pix, origins, dirs, tmax):
    """(pixels, triangles, weights) (k,) each: the surfaces the camera rays ``origins + t dirs`` of
    pixels ``pix`` (t < ``tmax``) reach through transparent ones, with the weight that reaches each
    times its opacity, 1 - (1 - opacity) mean(transparent colour) (Cycles' matte weight).  Rays go
    through the triangles hidden from the camera; volumes are not in it (as in Cycles)."""
    out_pix, out_prim, out_w = [], [], []
    accel = ctx.accel
    rows = np.arange(len(pix))
    weight = np.ones(len(pix))
    o, d, left = origins, dirs, np.asarray(tmax, np.float64)
    for _ in range(MAX_SURFACES):
        if len(rows) == 0:
            break
        hits, _, opacity, _ = ctx.trace(o, d, left, lambda r, crossing: np.zeros(len(r)),
                                        ray_kind=np.full(len(rows), VISIBLE_CAMERA, np.uint8),
                                        alpha_threshold=0.0)
        h = np.flatnonzero(hits.is_hit & (hits.t < left))
        if len(h) == 0:
            break
        prim = hits.prim_ids.take(h)
        a = np.ones(len(h)) if opacity is None else opacity.take(h)
        through = (1.0 - a) * ctx.transparent_color.take(ctx.material_ids.take(prim), axis=0).mean(axis=1)
        w = weight.take(h)
        out_pix.append(pix.take(rows.take(h)))
        out_prim.append(prim)
        out_w.append(w * (1.0 - through))
        go = np.flatnonzero(w * through > MIN_WEIGHT)
        if len(go) == 0:
            break
        hg = h.take(go)
        pg = prim.take(go)
        p = accel.hit_positions(pg, hits.b1.take(hg), hits.b2.take(hg))
        dg = d.take(hg, axis=0)
        start = accel.spawn(p, accel.geometric_normals.take(pg, axis=0), dg, pg)
        left = np.maximum(left.take(hg) - hits.t.take(hg) - np.einsum("ij,ij->i", start - p, dg), 0.0)
        rows, weight, o, d = rows.take(hg), (w * through).take(go), start, dg
    if not out_pix:
        empty = np.zeros(0)
        return empty.astype(np.int64), empty.astype(np.int32), empty
    return np.concatenate(out_pix), np.concatenate(out_prim), np.concatenate(out_w)


class CryptoSums:
    """Summed weights per (pixel, id) over the passes of one kind of Cryptomatte pass."""

    def __init__(self):
        self.keys = np.zeros(0, np.int64)       # pixel << 32 | the id's float32 bits, sorted
        self.sums = np.zeros(0)

    def add(self, pixels, ids, weights):
        """Add the weights (k,) of ``ids`` (k,) float32 at ``pixels`` (k,)."""
        bits = np.asarray(ids, np.float32).view(np.uint32).astype(np.int64)
        keys = np.concatenate([self.keys, (np.asarray(pixels, np.int64) << 32) | bits])
        values = np.concatenate([self.sums, np.asarray(weights, np.float64)])
        self.keys, inverse = np.unique(keys, return_inverse=True)
        self.sums = np.bincount(inverse.ravel(), values, minlength=len(self.keys))

    def image(self, n_pixels, levels, passes):
        """(n_pixels, 2 ``levels``) float32: per pixel its ``levels`` ids of most weight and their
        weights over ``passes``, as (id, weight) pairs by decreasing weight (0, 0 past the last)."""
        out = np.zeros((n_pixels, 2 * levels), np.float32)
        if len(self.keys) == 0 or passes == 0:
            return out
        pix = self.keys >> 32
        order = np.lexsort((-self.sums, pix))
        pix, keys, w = pix.take(order), self.keys.take(order), self.sums.take(order) / passes
        rank = np.arange(len(pix)) - np.searchsorted(pix, pix, side="left")
        keep = np.flatnonzero(rank < levels)
        p, r = pix.take(keep), rank.take(keep)
        out[p, 2 * r] = (keys.take(keep) & 0xFFFFFFFF).astype(np.uint32).view(np.float32)
        out[p, 2 * r + 1] = w.take(keep)
        return out

"""Blender's Voronoi Texture node as Cycles evaluates it (Blender 4.3 to 5.0), vectorised in NumPy.

A port of Cycles' SVM kernel ``intern/cycles/kernel/svm/voronoi.h`` (``svm_node_tex_voronoi``; the
1D to 4D ``voronoi_f1`` / ``voronoi_smooth_f1`` / ``voronoi_f2`` / ``voronoi_distance_to_edge`` /
``voronoi_n_sphere_radius``; the fractal ``fractal_voronoi_x_fx`` / ``fractal_voronoi_distance_to_edge``
of Blender >= 4.1), with the hashes of ``intern/cycles/util/hash.h`` (ported in :mod:`.texture_hash`)
and ``mix`` / ``smoothstep`` of ``intern/cycles/util/math_base.h``.  Everything of the node is
supported: features F1, F2, Smooth F1, Distance to Edge and N-Sphere Radius; metrics Euclidean,
Manhattan, Chebychev and Minkowski; the octaves (Detail, Roughness, Lacunarity, Normalize); 1D (W
only), 2D (x, y), 3D and 4D (x, y, z, W).  The node's inputs are scalars here (a Scale, Detail, ...
linked per point is not supported; W may vary per point).

Hashes: since Blender 4.3 the 2D / 3D / 4D kernels hash the *integer* cell with PCG
(``hash_int{2,3,4}_to_float{2,3,4}``, colours ``hash_int{2,3,4}_to_float3``); 1D still hashes the
float32 bits of the cell (``hash_float_to_float``, colour ``hash_float_to_float3``).  Older Blender
(<= 4.2, Jenkins hash of the float cell in every dimension) gives a different pattern.

What is followed exactly: the input clamps (detail to [0, 15], roughness and randomness to [0, 1],
smoothness / 2 to [0, 0.5]); the cell ``floor(coord)`` and the neighbour cells searched (-1..1 per
axis, -2..2 for Smooth F1) in Cycles' loop order (first axis fastest) with its strict ``<``, so that
ties go to the same cell; F1's search on ``voronoi_distance_bound`` (squared Euclidean, Minkowski
without the root) and N-Sphere Radius' on squared distances; a feature point at
``offset + hash(cell + offset) * randomness``; the colour as the hash of the winning cell; the
Position as ``cell + feature point`` in the scaled space, mixed over the octaves and divided by
Scale; the ``max_distance`` Normalize divides by.

Differences from Cycles: Cycles computes in float32, this module in float64 (the scalar inputs are
rounded to float32 as Blender stores them; cells must stay within int32).  Measured against Cycles
(tests/addon/test_voronoi_texture.py) the outputs agree to ~1e-6 (Minkowski with a small exponent
to ~2e-4, float32 ``powf``).  They can differ where two feature points are equally near within
float32 rounding, i.e. on the edges of the pattern, where the two may pick different cells (Color
and Position jump there, Distance does not).

Shapes: every function works on n points; arrays are float64 unless stated.
"""
from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np

from .texture_hash import (float_to_int, hash_float_to_float, hash_float_to_float3, hash_int2_to_float2,
                           hash_int2_to_float3, hash_int3_to_float3, hash_int4_to_float3,
                           hash_int4_to_float4)

FEATURES = ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE", "N_SPHERE_RADIUS")
METRICS = ("EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI")
DIMENSIONS = ("1D", "2D", "3D", "4D")
CHUNK = 1 << 15             # points evaluated together (bounds the temporaries to a few MB each)


@dataclass(frozen=True)
class VoronoiParams:
    """The node's settings after Cycles' clamps (``VoronoiParams`` of voronoi.h)."""
    dim: int                # 1 to 4
    feature: str
    metric: str
    scale: float
    detail: float           # [0, 15]
    roughness: float        # [0, 1]
    lacunarity: float
    smoothness: float       # the node's Smoothness / 2 clamped to [0, 0.5]
    exponent: float
    randomness: float       # [0, 1]
    normalize: bool
    max_distance: float     # what Normalize divides by (0 for N-Sphere Radius)


@dataclass
class _Octave:
    """One octave's outputs at n points, component-major: distance (n,), color (3, n), position (dim, n)."""
    distance: np.ndarray
    color: np.ndarray
    position: np.ndarray


# ---------------------------------------------------------------------- public API
def voronoi_texture(vector, scale, *, detail=0.0, roughness=0.5, lacunarity=2.0, randomness=1.0,
                    feature="F1", metric="EUCLIDEAN", exponent=0.5, smoothness=1.0, normalize=False,
                    dimensions="3D", w=0.0):
    """The Voronoi Texture node's outputs at the points ``vector`` (Cycles' SVM result).

    vector : (n, 3) float64 texture coordinates (the node's Vector input), finite; their cells
        (coordinates times Scale, Lacunarity^octave) must fit in int32.
    w : scalar or (n,) float64, the W input (used by 1D and 4D).
    The other arguments are the node's scalar inputs and its enum settings (the names of Blender's
    ``feature``, ``distance`` and ``voronoi_dimensions`` properties).
    Returns a dict of float64 arrays: "Distance" (n,), "Color" (n, 3), "Position" (n, 3), "W" (n,)
    and "Radius" (n,); like Cycles, the outputs a feature does not produce are zero (Distance to
    Edge gives only Distance, N-Sphere Radius only Radius).
    """
    vector = np.asarray(vector, dtype=np.float64).reshape(-1, 3)
    n = len(vector)
    w = np.broadcast_to(np.asarray(w, dtype=np.float64), (n,))
    params = make_params(scale, detail=detail, roughness=roughness, lacunarity=lacunarity,
                         randomness=randomness, feature=feature, metric=metric, exponent=exponent,
                         smoothness=smoothness, normalize=normalize, dimensions=dimensions)
    out = {"Distance": np.zeros(n), "Color": np.zeros((n, 3)), "Position": np.zeros((n, 3)),
           "W": np.zeros(n), "Radius": np.zeros(n)}
    for start in range(0, n, CHUNK):
        part = slice(start, start + CHUNK)
        coord = _node_coord(vector[part], w[part], params)
        for key, value in _evaluate(coord, params).items():
            out[key][part] = value
    return out


def make_params(scale=5.0, *, detail=0.0, roughness=0.5, lacunarity=2.0, randomness=1.0, feature="F1",
                metric="EUCLIDEAN", exponent=0.5, smoothness=1.0, normalize=False, dimensions="3D"):
    """:class:`VoronoiParams` from the node's inputs: float32 rounding, clamps and max_distance."""
    if feature not in FEATURES or metric not in METRICS or dimensions not in DIMENSIONS:
        raise ValueError(f"unknown Voronoi setting {feature!r}, {metric!r} or {dimensions!r}")
    f32 = lambda x: float(np.float32(x))  # noqa: E731  (the node's float inputs)
    clamp = lambda x, hi: min(max(f32(x), 0.0), hi)  # noqa: E731
    partial = VoronoiParams(DIMENSIONS.index(dimensions) + 1, feature, metric, f32(scale),
                            clamp(detail, 15.0), clamp(roughness, 1.0), f32(lacunarity),
                            min(max(f32(smoothness) / 2.0, 0.0), 0.5), f32(exponent),
                            clamp(randomness, 1.0), bool(normalize), 0.0)
    return dataclasses.replace(partial, max_distance=_max_distance(partial))


def _max_distance(p):
    """Cycles' ``params.max_distance``: the metric distance from a cell corner to the farthest feature
    point, doubled for F2; 0.5 + 0.5 randomness for Distance to Edge; 0 for N-Sphere Radius."""
    edge = 0.5 + 0.5 * p.randomness
    if p.feature == "N_SPHERE_RADIUS":
        return 0.0
    if p.feature == "DISTANCE_TO_EDGE" or p.dim == 1:
        return edge * (2.0 if p.feature == "F2" else 1.0)
    d = _metric_distance(np.full((p.dim, 1), edge), p)[0]
    return float(d) * (2.0 if p.feature == "F2" else 1.0)


def _node_coord(vector, w, p):
    """(dim, n) coordinates the kernel works on: (W), (x, y), (x, y, z) or (x, y, z, W), times Scale."""
    rows = {1: [w], 2: [vector[:, 0], vector[:, 1]], 3: list(vector.T), 4: [*vector.T, w]}[p.dim]
    return np.stack(rows) * p.scale


def _evaluate(coord, p):
    """The node's outputs (dict of (n,) or (n, 3) arrays) for (dim, n) scaled coordinates."""
    if p.feature == "DISTANCE_TO_EDGE":
        return {"Distance": _fractal_distance_to_edge(coord, p)}
    if p.feature == "N_SPHERE_RADIUS":
        return {"Radius": _n_sphere_radius(coord, p)}
    octave = _fractal(coord, p)
    position = np.zeros((4, coord.shape[1]))        # Cycles' float4 voronoi_position
    position[{1: [3], 2: [0, 1], 3: [0, 1, 2], 4: [0, 1, 2, 3]}[p.dim]] = octave.position
    return {"Distance": octave.distance, "Color": octave.color.T, "Position": position[:3].T,
            "W": position[3]}


# ---------------------------------------------------------------------- Cycles' helpers
def _mix(a, b, t):
    """Cycles' ``mix``: a + t (b - a)."""
    return a + t * (b - a)


def _smoothstep01(x):
    """Cycles' ``smoothstep(0, 1, x)``: 0 below 0, 1 from 1 on, (3 - 2x) x^2 between; (n,)."""
    t = np.clip(x, 0.0, 1.0)
    return (3.0 - 2.0 * t) * (t * t)


def _metric_distance(d, p):
    """Cycles' ``voronoi_distance`` of (dim, n) differences in the node's metric: (n,).
    1D always uses |d| (its kernel has no metric)."""
    if p.dim == 1:
        return np.abs(d[0])
    if p.metric == "EUCLIDEAN":
        return _length(d)
    if p.metric == "MANHATTAN":
        return np.abs(d).sum(axis=0)
    if p.metric == "CHEBYCHEV":
        return np.abs(d).max(axis=0)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        return (np.abs(d) ** p.exponent).sum(axis=0) ** (1.0 / p.exponent)


def _metric_bound(d, p):
    """Cycles' ``voronoi_distance_bound``: a cheaper monotone function of the metric distance, used
    to find F1 (squared Euclidean, Minkowski without the root); (n,)."""
    if p.dim == 1:
        return np.abs(d[0])
    if p.metric == "EUCLIDEAN":
        return _length2(d)
    if p.metric == "MINKOWSKI":
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            return (np.abs(d) ** p.exponent).sum(axis=0)
    return _metric_distance(d, p)


def _length2(d):
    """Squared Euclidean length of (dim, n) vectors: (n,)."""
    return np.einsum("ij,ij->j", d, d)


def _length(d):
    """Euclidean length of (dim, n) vectors: (n,)."""
    return np.sqrt(_length2(d))


def _offsets(dim, reach):
    """(K, dim) neighbour cell offsets -reach..reach in Cycles' loop order (first axis fastest)."""
    r = range(-reach, reach + 1)
    return np.array([t[::-1] for t in itertools.product(r, repeat=dim)], dtype=np.float64)


# ---------------------------------------------------------------------- cell hashes
def _keys(cells):
    """Hash keys of (dim, m) integer-valued float64 cells, one array per component: the float32 value
    in 1D (``+ 0.0`` turns a -0.0 into the +0.0 of Cycles' ``cellPosition + cellOffset``), else the
    int32 cell."""
    if len(cells) == 1:
        return [(cells[0] + 0.0).astype(np.float32)]
    return list(float_to_int(cells).astype(np.int32))


def _point_hash(keys):
    """Cycles' hash placing the feature point of each cell, (dim, m) in [0, 1], for :func:`_keys`."""
    if len(keys) == 1:
        return hash_float_to_float(keys[0])[None, :]
    return {2: hash_int2_to_float2, 3: hash_int3_to_float3, 4: hash_int4_to_float4}[len(keys)](*keys).T


def _color_hash(keys):
    """Cycles' colour hash of each cell, (3, m) in [0, 1], for :func:`_keys`."""
    if len(keys) == 1:
        return hash_float_to_float3(keys[0]).T
    return {2: hash_int2_to_float3, 3: hash_int3_to_float3, 4: hash_int4_to_float3}[len(keys)](*keys).T


def unique_columns(cells):
    """Distinct columns of (dim, n) integer-valued float cells, in ``np.unique(axis=1)``'s order
    (lexicographic), and the (n,) index of each column among them.  Columns are packed into one
    int64 key when their bounding box allows: a 1D sort, where ``np.unique(axis=1)`` sorts the
    columns as records (half of a 3D Gabor Texture's time went to that)."""
    packable = cells.shape[1] > 0 and np.isfinite(cells).all()
    if packable:
        lo = cells.min(axis=1, keepdims=True)
        span = cells.max(axis=1) - lo[:, 0] + 1
        packable = np.prod(span) < 2.0 ** 62
    if not packable:
        unique, inverse = np.unique(cells, axis=1, return_inverse=True)
        return unique, inverse.reshape(-1)
    shifted = (cells - lo).astype(np.int64)
    key = shifted[0]
    for axis in range(1, len(cells)):
        key = key * np.int64(span[axis]) + shifted[axis]
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return cells[:, first], inverse.reshape(-1)


def _unique_cells(cells):
    """:func:`unique_columns` of (dim, n) cells, or (cells, None) when most are distinct."""
    n = cells.shape[1]
    if n == 0:
        return cells, None
    unique, inverse = unique_columns(cells)
    if 2 * unique.shape[1] > n:
        return cells, None
    return unique, inverse


class _Cells:
    """Hashes of the cells around n base cells: each neighbour's hash is computed once per distinct
    base cell and gathered to the points."""

    def __init__(self, base):
        """base : (dim, n) integer-valued float64 cells."""
        self.unique, self.inverse = _unique_cells(base)

    def _gather(self, values):
        return values if self.inverse is None else np.take(values, self.inverse, axis=1)

    def points(self, offset, randomness):
        """(dim, n) feature points offset + hash(cell + offset) * randomness, relative to the base
        cell; offset (dim, 1)."""
        return offset + self._gather(_point_hash(_keys(self.unique + offset))) * randomness

    def colors_and_points(self, offset, randomness):
        """(3 + dim, n): the colours of the cells base + offset, then :meth:`points` (in 3D and 4D
        the colour is the point's hash, or its first three components)."""
        keys = _keys(self.unique + offset)
        point = self._gather(_point_hash(keys))
        color = point[:3] if len(keys) >= 3 else self._gather(_color_hash(keys))
        return np.concatenate([color, offset + point * randomness])


def _take(dst, src, mask):
    """dst[..., mask] = src[..., mask] in place, for (n,) or (k, n) arrays and an (n,) mask."""
    np.copyto(dst, src, where=mask)


def _split(coord):
    """Cell (floor) and position inside it of (dim, n) coordinates."""
    cell = np.floor(coord)
    return cell, coord - cell


# ---------------------------------------------------------------------- one octave
def _octave(coord, p):
    """The F1 / F2 / Smooth F1 octave at (dim, n) coordinates (``voronoi_*`` of voronoi.h)."""
    if p.feature == "F2":
        return _f2(coord, p)
    if p.feature == "SMOOTH_F1" and p.smoothness != 0.0:
        return _smooth_f1(coord, p)
    return _f1(coord, p)


def _f1(coord, p):
    """``voronoi_f1``: the nearest feature point in the 3^dim cells around each point."""
    cell, local = _split(coord)
    cells = _Cells(cell)
    n, offsets = coord.shape[1], _offsets(p.dim, 1)
    best_d, best_k, best_pos = np.full(n, np.inf), np.zeros(n, np.intp), np.zeros_like(coord)
    for k, offset in enumerate(offsets):
        pos = cells.points(offset[:, None], p.randomness)
        d = _metric_bound(pos - local, p)
        closer = d < best_d
        _take(best_d, d, closer)
        _take(best_pos, pos, closer)
        best_k[closer] = k
    color = _color_hash(_keys(cell + offsets[best_k].T))
    return _Octave(_metric_distance(best_pos - local, p), color, best_pos + cell)


def _f2(coord, p):
    """``voronoi_f2``: the second nearest feature point in the 3^dim cells around each point."""
    cell, local = _split(coord)
    cells = _Cells(cell)
    n, offsets = coord.shape[1], _offsets(p.dim, 1)
    d1, d2 = np.full(n, np.inf), np.full(n, np.inf)
    k1, k2 = np.zeros(n, np.intp), np.zeros(n, np.intp)
    pos1, pos2 = np.zeros_like(coord), np.zeros_like(coord)
    for k, offset in enumerate(offsets):
        pos = cells.points(offset[:, None], p.randomness)
        d = _metric_distance(pos - local, p)
        first = d < d1
        second = ~first & (d < d2)
        for dst, src in ((d2, d1), (k2, k1), (pos2, pos1)):      # the old F1 becomes F2
            _take(dst, src, first)
        for dst, src in ((d1, d), (pos1, pos)):
            _take(dst, src, first)
        k1[first] = k
        for dst, src in ((d2, d), (pos2, pos)):
            _take(dst, src, second)
        k2[second] = k
    color = _color_hash(_keys(cell + offsets[k2].T))
    return _Octave(d2, color, pos2 + cell)


def _smooth_f1(coord, p):
    """``voronoi_smooth_f1``: the smooth minimum over the 5^dim cells around each point."""
    cell, local = _split(coord)
    cells = _Cells(cell)
    s, n = p.smoothness, coord.shape[1]
    dist = np.zeros(n)
    mixed = np.zeros((3 + p.dim, n))          # colour and position, mixed alike
    h = np.ones(n)                            # Cycles' h == -1 case: the first cell counts fully
    for k, offset in enumerate(_offsets(p.dim, 2)):
        target = cells.colors_and_points(offset[:, None], p.randomness)
        d = _metric_distance(target[3:] - local, p)
        if k:
            h = _smoothstep01(0.5 + 0.5 * (dist - d) / s)
        correction = s * h * (1.0 - h)
        dist = _mix(dist, d, h) - correction
        correction /= 1.0 + 3.0 * s
        target -= mixed                       # mixed = mix(mixed, target, h) - correction, in place
        target *= h
        mixed += target
        mixed -= correction
    return _Octave(dist, mixed[:3], cell + mixed[3:])


def _distance_to_edge(coord, p):
    """``voronoi_distance_to_edge``: distance to the nearest cell edge (Euclidean, any metric); (n,)."""
    if p.dim == 1:
        return _distance_to_edge_1d(coord[0], p.randomness)
    cell, local = _split(coord)
    cells = _Cells(cell)
    offsets = _offsets(p.dim, 1)[:, :, None]
    best, to_closest = np.full(coord.shape[1], np.inf), np.zeros_like(coord)
    for offset in offsets:
        v = cells.points(offset, p.randomness) - local
        d = _length2(v)
        closer = d < best
        _take(best, d, closer)
        _take(to_closest, v, closer)
    best[:] = np.inf
    for offset in offsets:
        v = cells.points(offset, p.randomness) - local
        perp = v - to_closest
        perp2 = _length2(perp)
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.einsum("ij,ij->j", (to_closest + v) / 2.0, perp) / np.sqrt(perp2)
        np.minimum(best, d, out=best, where=perp2 > 0.0001)
    return best


def _distance_to_edge_1d(x, randomness):
    """1D ``voronoi_distance_to_edge``: distance to the nearer midpoint between feature points; (n,)."""
    cell = np.floor(x)
    local = x - cell
    h = lambda c: hash_float_to_float(_keys(c[None, :])[0])  # noqa: E731
    mid = h(cell) * randomness
    left = -1.0 + h(cell - 1.0) * randomness
    right = 1.0 + h(cell + 1.0) * randomness
    return np.minimum(np.abs((mid + left) / 2.0 - local), np.abs((mid + right) / 2.0 - local))


def _n_sphere_radius(coord, p):
    """``voronoi_n_sphere_radius``: half the distance from the nearest feature point to its own nearest
    feature point (Euclidean, any metric, no octaves); (n,)."""
    cell, local = _split(coord)
    cells = _Cells(cell)
    offsets = _offsets(p.dim, 1)[:, :, None]
    best = np.full(coord.shape[1], np.inf)
    closest, closest_offset = np.zeros_like(coord), np.zeros_like(coord)
    for offset in offsets:
        pos = cells.points(offset, p.randomness)
        d = _length2(pos - local)
        closer = d < best
        _take(best, d, closer)
        _take(closest, pos, closer)
        _take(closest_offset, offset, closer)
    # Second search around the closest point's cell (its cells relative to the point's own cell).
    around = _Cells(cell + closest_offset)
    best[:] = np.inf
    neighbour = np.zeros_like(coord)
    for offset in offsets[np.any(offsets != 0, axis=(1, 2))]:
        pos = around.points(offset, p.randomness) + closest_offset
        d = _length2(closest - pos)
        closer = d < best
        _take(best, d, closer)
        _take(neighbour, pos, closer)
    return _length(neighbour - closest) / 2.0


# ---------------------------------------------------------------------- octaves
def _fractal(coord, p):
    """``fractal_voronoi_x_fx``: F1 / F2 / Smooth F1 summed over the Detail octaves, Normalize
    applied and the Position divided by Scale (``safe_divide``)."""
    if p.detail == 0.0 or p.roughness == 0.0:
        out, max_amplitude = _octave(coord, p), 1.0
    else:
        out, max_amplitude = _octaves(coord, p)
    if p.normalize:
        out.distance = out.distance / (max_amplitude * p.max_distance)
        out.color = out.color / max_amplitude
    out.position = out.position / p.scale if p.scale != 0.0 else np.zeros_like(out.position)
    return out


def _octaves(coord, p):
    """The octave loop of ``fractal_voronoi_x_fx`` (detail > 0): (_Octave, max_amplitude)."""
    out = _Octave(np.zeros(coord.shape[1]), np.zeros((3, coord.shape[1])), np.zeros_like(coord))
    amplitude, max_amplitude, scale = 1.0, 0.0, 1.0
    remainder = p.detail - np.floor(p.detail)
    for i in range(int(np.ceil(p.detail)) + 1):
        if i > p.detail and remainder == 0.0:
            break
        octave = _octave(coord * scale, p)
        position = _mix(out.position, octave.position / scale, amplitude)
        t = 1.0 if i <= p.detail else remainder     # the last, partial octave is mixed in
        max_amplitude = _mix(max_amplitude, max_amplitude + amplitude, t)
        out.distance = _mix(out.distance, out.distance + octave.distance * amplitude, t)
        out.color = _mix(out.color, out.color + octave.color * amplitude, t)
        out.position = _mix(out.position, position, t)
        scale *= p.lacunarity
        amplitude *= p.roughness
    return out, max_amplitude


def _fractal_distance_to_edge(coord, p):
    """``fractal_voronoi_distance_to_edge``: the minimum over the octaves, mixed by amplitude; (n,)."""
    if p.detail == 0.0 or p.roughness == 0.0:
        distance, max_amplitude = _distance_to_edge(coord, p), p.max_distance
    else:
        distance = np.full(coord.shape[1], 8.0)
        amplitude, max_amplitude, scale = 1.0, p.max_distance, 1.0
        remainder = p.detail - np.floor(p.detail)
        for i in range(int(np.ceil(p.detail)) + 1):
            if i > p.detail and remainder == 0.0:
                break
            octave = _distance_to_edge(coord * scale, p)
            t = 1.0 if i <= p.detail else remainder
            lerp_amplitude = _mix(max_amplitude, p.max_distance / scale, amplitude)
            lerp_distance = _mix(distance, np.minimum(distance, octave / scale), amplitude)
            max_amplitude = _mix(max_amplitude, lerp_amplitude, t)
            distance = _mix(distance, np.minimum(distance, lerp_distance), t)
            scale *= p.lacunarity
            amplitude *= p.roughness
    return distance / max_amplitude if p.normalize else distance

"""Blender's Noise Texture node as Cycles evaluates it (Blender 4.1 .. 5.0), vectorised in NumPy.

Ported from Cycles' SVM kernel (``intern/cycles/kernel/svm/``), itself adapted from Open Shading Language:

* ``noise.h``: Perlin gradient noise in 1D..4D (``perlin_1d`` .. ``perlin_4d``: lattice hash
  ``hash_uint{1..4}`` of the integer cell corners, ``grad1`` .. ``grad4``, quintic ``fade``,
  multilinear mix), the per-dimension scale factors (``noise_scale1`` .. ``noise_scale4``) and the
  "safe" signed noise ``snoise_Nd`` that repeats every 100000 units (``fmod``) and shifts coordinates
  with ``|p| >= 1e6`` by half a cell (the precision correction);
* ``fractal_noise.h``: the five fractal types with fractional detail (fBM with Normalize,
  multifractal, hybrid multifractal, ridged multifractal, heterogeneous terrain);
* ``noisetex.h``: the node itself: Scale, detail clamped to [0, 15], roughness clamped to >= 0, the
  Distortion (each coordinate displaced by signed noise at a random offset) and the Color output
  (R = Fac, G and B the same fractal at two more random offsets in [100, 200]);
* ``util/hash.h`` via :mod:`.texture_hash`.

Precision: Cycles works in float32; this port works in float64 except that the node's scalar
settings and the random offsets are first rounded to float32 as Cycles holds them.  Results agree to
a few 1e-6 typically; larger (still small) differences arise where float32 rounding of a large
coordinate (e.g. ``p + offset`` near 200, times lacunarity**octave) moves a point by a float32 ulp,
and near lattice-cell boundaries where the two precisions pick neighbouring cells (the noise is
continuous there, so the difference stays of the order of that rounding).

Shapes: points are rows, ``p`` is (n, d) float64 with d in 1..4 the noise dimension; every noise
function returns (n,) float64.  Nothing here is stateful or random: the "random" offsets are hashes.
"""
from __future__ import annotations

import itertools

import numpy as np

from .texture_hash import (hash_float2_to_float, hash_float_to_float, hash_uint, hash_uint2, hash_uint3,
                           hash_uint4)

NOISE_TYPES = ("FBM", "MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN")
DIMENSIONS = ("1D", "2D", "3D", "4D")

_HASH = {1: hash_uint, 2: hash_uint2, 3: hash_uint3, 4: hash_uint4}
# Cycles' noise_scale1..4: bring Perlin noise of each dimension roughly into [-1, 1].
_NOISE_SCALE = {1: 0.25, 2: 0.6616, 3: 0.9820, 4: 0.8344}


def _f32(x):
    """Scalar ``x`` rounded to float32 (how Cycles holds the node's settings), as a Python float."""
    return float(np.float32(x))


# ------------------------------------------------------------------------------- Perlin noise
def fade(t):
    """Perlin's quintic fade 6t^5 - 15t^4 + 10t^3 of an array ``t`` (float64, same shape)."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _negate_if(value, condition):
    """``-value`` where ``condition`` is nonzero, ``value`` elsewhere (arrays of one shape)."""
    return np.where(condition != 0, -value, value)


def _grad1(h, f):
    """Cycles' ``grad1``: h uint32 (n,), f [x] -> (n,) float64."""
    h = h.astype(np.int64) & 15
    return _negate_if(1.0 + (h & 7), h & 8) * f[0]


def _grad2(h, f):
    """Cycles' ``grad2``: h uint32 (n,), f [x, y] -> (n,) float64."""
    x, y = f
    h = h.astype(np.int64) & 7
    u = np.where(h < 4, x, y)
    v = 2.0 * np.where(h < 4, y, x)
    return _negate_if(u, h & 1) + _negate_if(v, h & 2)


def _grad3(h, f):
    """Cycles' ``grad3``: h uint32 (n,), f [x, y, z] -> (n,) float64."""
    x, y, z = f
    h = h.astype(np.int64) & 15
    u = np.where(h < 8, x, y)
    vt = np.where((h == 12) | (h == 14), x, z)
    v = np.where(h < 4, y, vt)
    return _negate_if(u, h & 1) + _negate_if(v, h & 2)


def _grad4(h, f):
    """Cycles' ``grad4``: h uint32 (n,), f [x, y, z, w] -> (n,) float64."""
    x, y, z, w = f
    h = h.astype(np.int64) & 31
    u = np.where(h < 24, x, y)
    v = np.where(h < 16, y, z)
    s = np.where(h < 8, z, w)
    return _negate_if(u, h & 1) + _negate_if(v, h & 2) + _negate_if(s, h & 4)


_GRAD = {1: _grad1, 2: _grad2, 3: _grad3, 4: _grad4}


def _gradient_table(d):
    """(16 or 32, d) float64: the gradient each hash value picks, as :func:`_grad2` .. :func:`_grad4`
    compute it (their result is the dot product of that row with the offsets: components are 0 or
    +-1, +-2 for 2D's v, so the sums come out bit for bit as the selects give them)."""
    size = {2: 8, 3: 16, 4: 32}[d]
    h = np.arange(size, dtype=np.uint32)
    return np.stack([_GRAD[d](h, list(np.eye(d)[k][:, None] * np.ones(size))) for k in range(d)], axis=1)


_GRAD_TABLE = {d: _gradient_table(d) for d in (2, 3, 4)}


def perlin(p):
    """Cycles' ``perlin_Nd`` (unscaled Perlin gradient noise) at points ``p`` (n, d) -> (n,) float64."""
    p = np.asarray(p, dtype=np.float64)
    n, d = p.shape
    cell = np.floor(p)
    frac = p - cell
    cell = cell.astype(np.int64)
    corners = np.empty((2,) * d + (n,))
    table = _GRAD_TABLE.get(d)
    for corner in itertools.product((0, 1), repeat=d):
        h = _HASH[d](*(cell[:, k] + corner[k] for k in range(d)))
        offsets = [frac[:, k] - corner[k] for k in range(d)]
        if table is None:
            corners[corner] = _grad1(h, offsets)
            continue
        rows = (h & np.uint32(len(table) - 1)).astype(np.intp)
        g = table[:, 0].take(rows) * offsets[0]
        for k in range(1, d):
            g += table[:, k].take(rows) * offsets[k]
        corners[corner] = g
    u = fade(frac)
    for k in range(d):                         # mix along x, then y, ...
        corners = corners[0] + u[:, k] * (corners[1] - corners[0])
    return corners


def snoise(p):
    """Cycles' signed ``snoise_Nd`` at points ``p`` (n, d): about [-1, 1], (n,) float64.

    Coordinates repeat every 100000 (C ``fmod``); those with ``|x| >= 1e6`` also move by half a cell."""
    p = np.asarray(p, dtype=np.float64)
    correction = 0.5 * (np.abs(p) >= 1.0e6)
    return _NOISE_SCALE[p.shape[1]] * perlin(np.fmod(p, 100000.0) + correction)


def noise(p):
    """Cycles' unsigned ``noise_Nd`` = 0.5 snoise + 0.5 at points ``p`` (n, d): (n,) float64."""
    return 0.5 * snoise(p) + 0.5


# ------------------------------------------------------------------------------- fractals
def noise_fbm(p, detail, roughness, lacunarity, normalize):
    """Fractal Brownian motion of ``snoise`` at (n, d) points -> (n,) float64.

    Normalized: sum / total amplitude mapped to about [0, 1]; else the raw signed sum."""
    fscale, amp, maxamp = 1.0, 1.0, 0.0
    total = np.zeros(len(p))
    for _ in range(int(detail) + 1):
        total = total + snoise(fscale * p) * amp
        maxamp += amp
        amp *= roughness
        fscale *= lacunarity
    value = 0.5 * total / maxamp + 0.5 if normalize else total
    rmd = detail - np.floor(detail)
    if rmd == 0.0:
        return value
    total2 = total + snoise(fscale * p) * amp
    value2 = 0.5 * total2 / (maxamp + amp) + 0.5 if normalize else total2
    return value + rmd * (value2 - value)


def noise_multi_fractal(p, detail, roughness, lacunarity):
    """Multifractal: product of (1 + amplitude * snoise) over octaves; (n, d) points -> (n,) float64."""
    value, pwr = np.ones(len(p)), 1.0
    for _ in range(int(detail) + 1):
        value = value * (pwr * snoise(p) + 1.0)
        pwr *= roughness
        p = p * lacunarity
    rmd = detail - np.floor(detail)
    if rmd != 0.0:
        value = value * (rmd * pwr * snoise(p) + 1.0)
    return value


def noise_hetero_terrain(p, detail, roughness, lacunarity, offset):
    """Heterogeneous terrain: octaves scaled by the value so far; (n, d) points -> (n,) float64."""
    pwr = roughness
    value = offset + snoise(p)
    p = p * lacunarity
    for _ in range(1, int(detail) + 1):
        value = value + (snoise(p) + offset) * pwr * value
        pwr *= roughness
        p = p * lacunarity
    rmd = detail - np.floor(detail)
    if rmd != 0.0:
        value = value + rmd * (snoise(p) + offset) * pwr * value
    return value


def noise_hybrid_multi_fractal(p, detail, roughness, lacunarity, offset, gain):
    """Hybrid additive / multiplicative multifractal; (n, d) points -> (n,) float64.

    A point stops adding octaves once its weight falls to 0.001 or below (Cycles' loop condition)."""
    pwr = 1.0
    value, weight = np.zeros(len(p)), np.ones(len(p))
    for _ in range(int(detail) + 1):
        alive = weight > 0.001
        if not alive.any():
            break
        w = np.minimum(weight, 1.0)
        signal = (snoise(p) + offset) * pwr
        pwr *= roughness
        value = np.where(alive, value + w * signal, value)
        weight = np.where(alive, w * gain * signal, weight)
        p = p * lacunarity
    rmd = detail - np.floor(detail)
    alive = weight > 0.001
    if rmd != 0.0 and alive.any():
        signal = (snoise(p) + offset) * pwr
        value = np.where(alive, value + rmd * np.minimum(weight, 1.0) * signal, value)
    return value


def noise_ridged_multi_fractal(p, detail, roughness, lacunarity, offset, gain):
    """Ridged multifractal; (n, d) points -> (n,) float64.  Cycles ignores the fractional detail here."""
    pwr = roughness
    signal = (offset - np.abs(snoise(p))) ** 2
    value = signal
    for _ in range(1, int(detail) + 1):
        p = p * lacunarity
        weight = np.clip(signal * gain, 0.0, 1.0)
        signal = (offset - np.abs(snoise(p))) ** 2 * weight
        value = value + signal * pwr
        pwr *= roughness
    return value


def noise_select(p, detail, roughness, lacunarity, offset, gain, noise_type, normalize):
    """The fractal of ``noise_type`` (one of NOISE_TYPES) at (n, d) points -> (n,) float64."""
    if noise_type == "FBM":
        return noise_fbm(p, detail, roughness, lacunarity, normalize)
    if noise_type == "MULTIFRACTAL":
        return noise_multi_fractal(p, detail, roughness, lacunarity)
    if noise_type == "HYBRID_MULTIFRACTAL":
        return noise_hybrid_multi_fractal(p, detail, roughness, lacunarity, offset, gain)
    if noise_type == "RIDGED_MULTIFRACTAL":
        return noise_ridged_multi_fractal(p, detail, roughness, lacunarity, offset, gain)
    if noise_type == "HETERO_TERRAIN":
        return noise_hetero_terrain(p, detail, roughness, lacunarity, offset)
    raise ValueError(f"unknown noise type {noise_type!r}; expected one of {NOISE_TYPES}")


# ------------------------------------------------------------------------------- the node
def random_offset(d, seed):
    """Cycles' ``random_float{,2,3,4}_offset(seed)``: (d,) float64 in [100, 200], float32-rounded."""
    if d == 1:
        h = np.array([hash_float_to_float(seed)])
    else:
        h = hash_float2_to_float(seed, np.arange(d, dtype=np.float64))
    return (np.float32(100.0) + h.astype(np.float32) * np.float32(100.0)).astype(np.float64)


def distort(p, distortion):
    """Noise-texture distortion: each coordinate of (n, d) ``p`` moved by ``distortion`` times signed
    noise at the random offset of seed = its axis; returns a new (n, d) float64 array."""
    if distortion == 0.0:
        return p
    d = p.shape[1]
    shift = np.stack([snoise(p + random_offset(d, float(k))) for k in range(d)], axis=1)
    return p + shift * distortion


def _node_coordinates(vector, w, scale, dimensions):
    """The scaled (n, d) coordinates the node's dimension mode reads from ``vector`` (n, 3) and ``w``."""
    vector = np.asarray(vector, dtype=np.float64)
    w = np.broadcast_to(np.asarray(w, dtype=np.float64), vector.shape[:1])
    columns = {"1D": [w], "2D": [vector[:, 0], vector[:, 1]], "3D": list(vector.T),
               "4D": [*vector.T, w]}
    if dimensions not in columns:
        raise ValueError(f"unknown dimensions {dimensions!r}; expected one of {DIMENSIONS}")
    return np.stack(columns[dimensions], axis=1) * scale


def noise_texture(vector, scale, detail, roughness, lacunarity, distortion, *, noise_type="FBM",
                  normalize=True, offset=0.0, gain=1.0, dimensions="3D", w=0.0, color=True):
    """The Noise Texture node's (Fac, Color) as Cycles computes them.

    vector : (n, 3) float64 texture coordinates (the node's Vector input; 1D mode ignores it).
    scale, detail, roughness, lacunarity, distortion, offset, gain : the node's scalar inputs.
    noise_type : one of NOISE_TYPES (the node's "Type"); normalize : its "Normalize" (fBM only).
    dimensions : "1D", "2D" (x, y), "3D" or "4D" (x, y, z, W); w : the W input, scalar or (n,).
    Returns fac (n,) float64 and color (n, 3) float64 (R = fac), or None without ``color`` (as
    Cycles, which skips the G and B fractals when the Color output is not linked: 3x cheaper).
    """
    scale, roughness, lacunarity, distortion, offset, gain = (
        _f32(x) for x in (scale, roughness, lacunarity, distortion, offset, gain))
    detail = min(max(_f32(detail), 0.0), 15.0)
    roughness = max(roughness, 0.0)
    p = distort(_node_coordinates(vector, w, scale, dimensions), distortion)
    d = p.shape[1]
    args = (detail, roughness, lacunarity, offset, gain, noise_type, bool(normalize))
    fac = noise_select(p, *args)
    if not color:
        return fac, None
    green = noise_select(p + random_offset(d, float(d)), *args)
    blue = noise_select(p + random_offset(d, float(d + 1)), *args)
    return fac, np.stack([fac, green, blue], axis=1)

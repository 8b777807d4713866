"""Blender's Wave, Brick, Magic, White Noise and Gabor Texture nodes as Cycles evaluates them,
vectorised in NumPy (checked value by value against Blender 5.0.1's Cycles:
tests/addon/test_pattern_textures_cycles.py).

Ported from Cycles' SVM kernel (``intern/cycles/kernel/svm/``):

* ``wave.h``: bands (X, Y, Z, diagonal) or rings (about X, Y, Z, or spherical) of a sine, saw or
  triangle profile, after the "precision" nudge ``p = (p + 1e-6) * 0.999999`` of the scaled
  coordinates, with a phase offset and a distortion by the normalised fBM noise of
  ``fractal_noise.h`` (lacunarity 2; :func:`.noise.noise_fbm`) at ``p * detail_scale``;
* ``brick.h``: rows of height ``row_height`` and bricks of width ``brick_width`` (every
  ``squash_frequency``-th row squashed, every ``offset_frequency``-th row shifted), the per-brick
  tint from Cycles' own integer hash ``brick_noise`` of ``(row << 16) + (brick & 0xFFFF)`` plus the
  bias, and the mortar (hard, or a clamped ``smoothstepf`` ramp with Mortar Smooth); the colours are
  blended as ``svm_node_tex_brick`` does (``util/math_base.h`` for ``smoothstepf``);
* ``magic.h``: the nested sine / cosine turbulence of depth 0..10, on coordinates first reduced with
  ``fmodf(p, 2 pi)``, the Scale applied after that reduction (inside the sines);
* ``white_noise.h``: ``hash_float{,2,3,4}_to_float`` / ``..._to_float3`` of the float32 bits of
  the coordinates (``util/hash.h``, via :mod:`.texture_hash`);
* ``gabor.h``: sparse Gabor noise (:func:`gabor_texture`).

Node settings come from ``intern/cycles/scene/shader_nodes.cpp`` as Blender passes them: the
Brick's Offset / Squash amounts and frequencies are node properties (ints, 1..99 in Blender), the
Magic's depth an int (0..10 in Blender).

Precision: Cycles computes in float32, this port in float64 except that the scalar settings and the
kernel's constants (1e-6f, 0.999999f, M_PI_2_F, M_2PI_F) are first rounded to float32 as Cycles holds
them.  Continuous outputs then agree to a few 1e-6 (the wave, the magic texture at low distortion),
more where a steep slope scales float32's rounding of the coordinates: a narrow Mortar Smooth ramp
(~5e-5 at 0.1) or the magic texture's sines of arguments multiplied by a large distortion (~1e-4 at
depth 4, distortion 2.5).  Where a float32 rounding decides a discontinuity the two
may differ by a whole step: the saw / triangle wrap of the wave, the brick and row a point falls in
and the mortar's hard edge (``floor_to_int`` of ``p / width``, ``min_dist >= mortar_size``), and
``fmodf`` in the magic texture at multiples of 2 pi.  White noise hashes bits, so any coordinate that
is not exactly the float32 Cycles holds hashes to an unrelated value: it is exact when the inputs are
(float64 inputs are rounded to float32 first, as the hash keys are in :mod:`.texture_hash`).

Shapes: ``vector`` is (n, 3) float64; every node returns a dict of (n,) float64 and (n, 3) float64
arrays named as the node's output sockets.  Nothing here is stateful or random.
"""
from __future__ import annotations

import numpy as np

from .noise import noise_fbm
from .texture_hash import (float_to_int, hash_float2_to_float, hash_float2_to_float3, hash_float3_to_float,
                           hash_float3_to_float3, hash_float4_to_float, hash_float4_to_float3,
                           hash_float_to_float, hash_float_to_float3)
from .voronoi import unique_columns

WAVE_TYPES = ("BANDS", "RINGS")
BANDS_DIRECTIONS = ("X", "Y", "Z", "DIAGONAL")
RINGS_DIRECTIONS = ("X", "Y", "Z", "SPHERICAL")
WAVE_PROFILES = ("SIN", "SAW", "TRI")
DIMENSIONS = ("1D", "2D", "3D", "4D")
MAGIC_MAX_DEPTH = 10
# The Wave texture's distortion noise takes at most this many octaves (one Python step each):
# Cycles takes any Detail a driver gives it, but 1e6 octaves would stall the export (found by a
# fuzz sweep), and past about 24 octaves float32 coordinates (doubled each octave) have no bits
# left below the noise's lattice, where it is 0.  (Blender's socket stops at 15.)
MAX_WAVE_DETAIL = 64.0

_PI_2 = float(np.float32(np.pi / 2.0))        # M_PI_2_F
_TWO_PI = float(np.float32(2.0 * np.pi))      # M_2PI_F


def _f32(x):
    """Scalar ``x`` rounded to float32 (how Cycles holds the node's settings), as a Python float."""
    return float(np.float32(x))


def _points(vector):
    """``vector`` as an (n, 3) float64 array (a copy is not made when it already is one)."""
    vector = np.asarray(vector, dtype=np.float64)
    if vector.ndim != 2 or vector.shape[1] != 3:
        raise ValueError(f"vector must be (n, 3), got {vector.shape}")
    return vector


def _check(name, value, allowed):
    if value not in allowed:
        raise ValueError(f"unknown {name} {value!r}; expected one of {allowed}")


def _gray(value):
    """(n,) -> (n, 3): a float output seen as a colour (Cycles' make_float3(f, f, f))."""
    return np.repeat(value[:, None], 3, axis=1)


# ------------------------------------------------------------------------------------------ wave
def wave_texture(vector, *, wave_type="BANDS", bands_direction="X", rings_direction="X", wave_profile="SIN",
                 scale=5.0, distortion=0.0, detail=2.0, detail_scale=1.0, detail_roughness=0.5,
                 phase_offset=0.0):
    """The Wave Texture node (Cycles' ``svm_wave``).

    vector : (n, 3) float64 texture coordinates.
    wave_type : "BANDS" or "RINGS"; bands_direction : "X", "Y", "Z" or "DIAGONAL" (bands only);
    rings_direction : "X", "Y", "Z" or "SPHERICAL" (rings only, the axis the rings go around);
    wave_profile : "SIN", "SAW" or "TRI".
    scale, distortion, detail, detail_scale, detail_roughness, phase_offset : the node's inputs
    (scalars).  ``detail`` is used as given, as Cycles does (Blender's socket limits it to 0..15),
    up to ``MAX_WAVE_DETAIL`` octaves.
    Returns {"Color": (n, 3) float64 grey, "Fac": (n,) float64 in [0, 1]}.
    """
    _check("wave type", wave_type, WAVE_TYPES)
    _check("bands direction", bands_direction, BANDS_DIRECTIONS)
    _check("rings direction", rings_direction, RINGS_DIRECTIONS)
    _check("wave profile", wave_profile, WAVE_PROFILES)
    scale, distortion, detail, detail_scale, detail_roughness, phase_offset = (
        _f32(x) for x in (scale, distortion, detail, detail_scale, detail_roughness, phase_offset))
    detail = min(max(detail, 0.0), MAX_WAVE_DETAIL)
    p = (_points(vector) * scale + _f32(1e-6)) * _f32(0.999999)
    if wave_type == "BANDS":
        if bands_direction == "DIAGONAL":
            n = (p[:, 0] + p[:, 1] + p[:, 2]) * 10.0
        else:
            n = p[:, "XYZ".index(bands_direction)] * 20.0
    else:
        keep = {"X": [1, 2], "Y": [0, 2], "Z": [0, 1], "SPHERICAL": [0, 1, 2]}[rings_direction]
        n = np.sqrt(np.sum(p[:, keep] ** 2, axis=1)) * 20.0
    n = n + phase_offset
    if distortion != 0.0:
        n = n + distortion * (noise_fbm(p * detail_scale, detail, detail_roughness, 2.0, True) * 2.0 - 1.0)
    if wave_profile == "SIN":
        fac = 0.5 + 0.5 * np.sin(n - _PI_2)
    elif wave_profile == "SAW":
        n = n / _TWO_PI
        fac = n - np.floor(n)
    else:
        n = n / _TWO_PI
        fac = np.abs(n - np.floor(n + 0.5)) * 2.0
    return {"Color": _gray(fac), "Fac": fac}


# ------------------------------------------------------------------------------------------ brick
def brick_noise(n):
    """Cycles' ``brick_noise`` (a fast integer hash): integer array -> float64 in [0, 1], same shape.

    The float32 steps are kept: the 31-bit hash is rounded to float32 before the division."""
    n = np.asarray(n).astype(np.int64) & 0xFFFFFFFF
    n = ((n + 1013) & 0x7FFFFFFF).astype(np.uint32)
    n = (n >> np.uint32(13)) ^ n
    nn = n * (n * n * np.uint32(60493) + np.uint32(19990303)) + np.uint32(1376312589)
    nn &= np.uint32(0x7FFFFFFF)
    return 0.5 * (nn.astype(np.float32) / np.float32(1073741824.0)).astype(np.float64)


def _smoothstepf(f):
    """Cycles' ``smoothstepf``: 0 below 0, 1 above 1, 3f^2 - 2f^3 between (float64, same shape)."""
    f = np.clip(f, 0.0, 1.0)
    ff = f * f
    return 3.0 * ff - 2.0 * ff * f


def _color(c, n):
    """A colour input, (3,) or (n, 3) (or RGBA), as an (n, 3) float64 array."""
    c = np.asarray(c, dtype=np.float64)[..., :3]
    return np.broadcast_to(c, (n, 3))


def brick_texture(vector, *, color1, color2, mortar, scale=5.0, mortar_size=0.02, mortar_smooth=0.0, bias=0.0,
                  brick_width=0.5, row_height=0.25, offset=0.5, offset_frequency=2, squash=1.0,
                  squash_frequency=2):
    """The Brick Texture node (Cycles' ``svm_brick`` and ``svm_node_tex_brick``).

    vector : (n, 3) float64 texture coordinates (z is ignored).
    color1, color2, mortar : (3,) or (n, 3) colours (an RGBA's alpha is dropped).
    scale, mortar_size, mortar_smooth, bias, brick_width, row_height : the node's inputs (scalars);
    offset, squash : float properties; offset_frequency, squash_frequency : int properties (both
    nonzero for the offset and squash to apply, as in Cycles).  The defaults are Blender's node
    defaults except ``mortar_smooth``: 0 here (Cycles' socket default), 0.1 on a new Blender node.
    Returns {"Color": (n, 3) float64, "Fac": (n,) float64 mortar weight in [0, 1] (1 = mortar)}.
    """
    scale, mortar_size, mortar_smooth, bias, brick_width, row_height, offset, squash = (
        _f32(x) for x in (scale, mortar_size, mortar_smooth, bias, brick_width, row_height, offset, squash))
    offset_frequency, squash_frequency = int(offset_frequency), int(squash_frequency)
    p = _points(vector) * scale
    count = len(p)
    px, py = p[:, 0], p[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):     # (a Row Height of 0: INT_MIN, as Cycles)
        row = float_to_int(np.floor(py / row_height))
    width = np.full(count, brick_width)
    shift = np.zeros(count)
    if offset_frequency and squash_frequency:
        # C's % and Python's differ in sign for negative rows, but not in which are 0.
        width = np.where(row % squash_frequency != 0, brick_width, brick_width * squash)
        shift = np.where(row % offset_frequency != 0, 0.0, width * offset)
    with np.errstate(divide="ignore", invalid="ignore"):
        brick = float_to_int(np.floor((px + shift) / width))
    x = (px + shift) - width * brick
    y = py - row_height * row
    tint = np.clip(brick_noise((row << 16) + (brick & 0xFFFF)) + bias, 0.0, 1.0)
    min_dist = np.minimum(np.minimum(x, y), np.minimum(width - x, row_height - y))
    if mortar_smooth == 0.0:
        fac = np.where(min_dist >= mortar_size, 0.0, 1.0)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            ramp = _smoothstepf((1.0 - min_dist / mortar_size) / mortar_smooth)
        fac = np.where(min_dist >= mortar_size, 0.0, ramp)
    c1, c2, cm = (_color(c, count) for c in (color1, color2, mortar))
    brick_color = np.where((fac != 1.0)[:, None], (1.0 - tint)[:, None] * c1 + tint[:, None] * c2, c1)
    color = brick_color * (1.0 - fac)[:, None] + cm * fac[:, None]
    return {"Color": color, "Fac": fac}


# ------------------------------------------------------------------------------------------ magic
# Cycles' nested turbulence steps, one per depth level 1..10: (output axis, sign, function, signs of
# x, y, z in the argument); after each step the output is multiplied by the distortion.
_MAGIC_STEPS = (
    (1, -1.0, np.cos, (1, -1, 1)),
    (0, 1.0, np.cos, (1, -1, -1)),
    (2, 1.0, np.sin, (-1, -1, -1)),
    (0, -1.0, np.cos, (-1, 1, -1)),
    (1, -1.0, np.sin, (-1, 1, 1)),
    (1, -1.0, np.cos, (-1, 1, 1)),
    (0, 1.0, np.cos, (1, 1, 1)),
    (2, 1.0, np.sin, (1, 1, -1)),
    (0, -1.0, np.cos, (-1, -1, 1)),
    (1, -1.0, np.sin, (1, -1, 1)),
)


def magic_texture(vector, *, depth=2, scale=5.0, distortion=1.0):
    """The Magic Texture node (Cycles' ``svm_magic``).

    vector : (n, 3) float64 texture coordinates; depth : int 0..10 (more acts as 10, as in Cycles);
    scale, distortion : the node's inputs (scalars).
    Returns {"Color": (n, 3) float64, "Fac": (n,) float64 the mean of the colour's channels}.
    """
    depth = int(depth)
    if depth < 0:
        raise ValueError(f"depth must be >= 0, got {depth}")
    scale, distortion = _f32(scale), _f32(distortion)
    q = np.fmod(_points(vector), _TWO_PI)
    px, py, pz = q[:, 0], q[:, 1], q[:, 2]
    s = 5.0 * scale
    xyz = [np.sin((px + py + pz) * s), np.cos((-px + py - pz) * s), -np.cos((-px - py + pz) * s)]
    if depth > 0:
        xyz = [v * distortion for v in xyz]
    for axis, sign, func, signs in _MAGIC_STEPS[:min(depth, MAGIC_MAX_DEPTH)]:
        arg = signs[0] * xyz[0] + signs[1] * xyz[1] + signs[2] * xyz[2]
        xyz[axis] = sign * func(arg) * distortion
    if distortion != 0.0:
        xyz = [v / (2.0 * distortion) for v in xyz]
    color = 0.5 - np.stack(xyz, axis=1)
    return {"Color": color, "Fac": color.mean(axis=1)}


# ------------------------------------------------------------------------------------------ white noise
# (value hash, colour hash) for 1..4 key components.
_WHITE_NOISE_HASHES = ((hash_float_to_float, hash_float_to_float3),
                       (hash_float2_to_float, hash_float2_to_float3),
                       (hash_float3_to_float, hash_float3_to_float3),
                       (hash_float4_to_float, hash_float4_to_float3))


def white_noise_texture(vector, *, dimensions="3D", w=0.0):
    """The White Noise Texture node (Cycles' ``svm_node_tex_white_noise``).

    vector : (n, 3) float64 coordinates (2D reads x, y; 1D ignores it); w : the W input, scalar or
    (n,) (1D and 4D).  The keys are the float32 roundings of the inputs, as Cycles holds them.
    Returns {"Value": (n,) float64 in [0, 1], "Color": (n, 3) float64 in [0, 1]} (Value = Color's R).
    """
    _check("dimensions", dimensions, DIMENSIONS)
    vector = _points(vector)
    w = np.broadcast_to(np.asarray(w, dtype=np.float64), vector.shape[:1])
    x, y, z = vector.T
    keys = {"1D": (w,), "2D": (x, y), "3D": (x, y, z), "4D": (x, y, z, w)}[dimensions]
    scalar_hash, color_hash = _WHITE_NOISE_HASHES[len(keys) - 1]
    return {"Value": scalar_hash(*keys), "Color": color_hash(*keys)}


GABOR_TYPES = ("2D", "3D")
GABOR_IMPULSES = 8                            # Cycles' IMPULSES_COUNT: kernels per cell


def gabor_texture(vector, *, gabor_type="2D", scale=5.0, frequency=2.0, anisotropy=1.0,
                  orientation_2d=np.pi / 4, orientation_3d=(np.sqrt(2.0), np.sqrt(2.0), 0.0)):
    """The Gabor Texture node (Cycles' ``svm_node_tex_gabor``, ``kernel/svm/gabor.h``): sparse
    Gabor convolution (Lagae et al. 2009) with Tavernier et al.'s (2019) eight impulses per cell
    of weight +-1, and Tricard et al.'s (2019) phasor for the phase and intensity.

    In the 3 x 3 (2D, on x and y) or 3 x 3 x 3 cells around the scaled point, impulse i of cell c
    lies at ``hash_float{3,4}_to_float{2,3}(c, 3 i + 1)`` within it, weighs -1 or +1 by
    ``hash(c, 3 i + 2) < 1/2``, and turns from the Orientation by a random angle times the
    isotropy 1 - clamp(Anisotropy) (2D: (hash(c, 3 i) - 1/2) pi; 3D: both spherical angles by
    ``hash_float4_to_float2(c, 3 i)`` pi).  Its kernel at offset p (|p| < 1) is the Gaussian
    exp(-pi |p|^2) under a Hann window 1/2 + cos(pi |p|^2) / 2, times exp(2 pi i p . f) for the
    frequency vector f (max(Frequency, 0.001) along the orientation).  The sum's imaginary part
    over 6 standard deviations (sqrt(8 / 2 / 4) in 2D, sqrt(8 / 2 / (4 sqrt 2)) in 3D), mapped to
    [0, 1], is the Value; its angle over 2 pi from -pi the Phase; its length over the same the
    Intensity.

    vector : (n, 3) float64; the settings scalars or (n,) arrays, ``orientation_3d`` (3,) or
    (n, 3) (normalised here).  Returns {"Value", "Phase", "Intensity"}, each (n,) float64.
    """
    _check("gabor_type", gabor_type, GABOR_TYPES)
    vector = _points(vector)
    n = len(vector)
    flat = gabor_type == "2D"
    dims = 2 if flat else 3
    coords = vector[:, :dims] * np.broadcast_to(np.asarray(scale, np.float64), (n,))[:, None]
    frequency = np.maximum(np.broadcast_to(np.asarray(frequency, np.float64), (n,)), 0.001)
    isotropy = 1.0 - np.clip(np.broadcast_to(np.asarray(anisotropy, np.float64), (n,)), 0.0, 1.0)
    if flat:
        base = np.broadcast_to(np.asarray(orientation_2d, np.float64), (n,))
    else:
        base = np.broadcast_to(np.asarray(orientation_3d, np.float64), (n, 3))
        length = np.linalg.norm(base, axis=1, keepdims=True)
        base = np.divide(base, length, out=np.zeros((n, 3)), where=length > 0)
        inclination = np.arccos(np.clip(base[:, 2], -1.0, 1.0))
        across = np.hypot(base[:, 0], base[:, 1])
        cos_azimuth = np.divide(base[:, 0], across, out=np.ones(n), where=across > 0)
        azimuth = np.where(base[:, 1] < 0.0, -1.0, 1.0) * np.arccos(np.clip(cos_azimuth, -1.0, 1.0))
    cell = np.floor(coords)
    local = coords - cell
    phasor = np.zeros((n, 2))
    offsets = np.stack(np.meshgrid(*[np.arange(-1.0, 2.0)] * dims, indexing="ij"), axis=-1).reshape(-1, dims)
    for offset in offsets:
        # Each neighbouring cell's impulses depend on the cell alone: hash the distinct cells.
        cells, which = unique_columns((cell + offset).T)
        keys = tuple(cells)
        for i in range(GABOR_IMPULSES):
            seeds = [np.full(cells.shape[1], 3.0 * i + j) for j in range(3)]
            if flat:
                center = np.stack([hash_float3_to_float(*keys, seeds[1]),
                                   hash_float3_to_float(seeds[1], *keys)], axis=1)
                weight = hash_float3_to_float(*keys, seeds[2])
            else:
                center = hash_float4_to_float3(*keys, seeds[1])
                weight = hash_float4_to_float(*keys, seeds[2])
            p = local - offset - center[which]
            d2 = (p * p).sum(axis=1)
            near = np.flatnonzero(d2 < 1.0)
            if len(near) == 0:
                continue
            pn, d2n = p[near], d2[near]
            if flat:
                turn = (hash_float3_to_float(*keys, seeds[0]) - 0.5) * np.pi
                angle_o = base[near] + turn[which[near]] * isotropy[near]
                f = frequency[near, None] * np.stack([np.cos(angle_o), np.sin(angle_o)], axis=1)
            else:
                turns = np.stack([hash_float4_to_float(*keys, seeds[0]),
                                  hash_float4_to_float(keys[2], keys[0], seeds[0], keys[1])], axis=1) * np.pi
                t = turns[which[near]] * isotropy[near, None]
                inc, azi = inclination[near] + t[:, 0], azimuth[near] + t[:, 1]
                turned = np.stack([np.sin(inc) * np.cos(azi), np.sin(inc) * np.sin(azi), np.cos(inc)], axis=1)
                direction = np.where((isotropy[near] == 0.0)[:, None], base[near], turned)
                f = frequency[near, None] * direction
            envelope = np.exp(-np.pi * d2n) * (0.5 + 0.5 * np.cos(np.pi * d2n))
            angle = 2.0 * np.pi * (pn * f).sum(axis=1)
            sign = np.where(weight[which[near]] < 0.5, -1.0, 1.0) * envelope
            phasor[near, 0] += sign * np.cos(angle)
            phasor[near, 1] += sign * np.sin(angle)
    deviation = np.sqrt(GABOR_IMPULSES * 0.5 * (0.25 if flat else 1.0 / (4.0 * np.sqrt(2.0))))
    norm = 6.0 * deviation
    return {"Value": phasor[:, 1] / norm * 0.5 + 0.5,
            "Phase": (np.arctan2(phasor[:, 1], phasor[:, 0]) + np.pi) / (2.0 * np.pi),
            "Intensity": np.hypot(phasor[:, 0], phasor[:, 1]) / norm}

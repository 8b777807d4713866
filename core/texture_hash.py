"""Cycles' hash functions for procedural textures, vectorised over NumPy arrays.

A port of ``intern/cycles/util/hash.h`` (Blender 4.x / 5.0): Bob Jenkins' lookup3 ``final`` / ``mix``
(http://burtleburtle.net/bob/c/lookup3.c) hashing one to four uint32 keys, the mapping of the hash to a
float in [0, 1] (``uint_to_float_incl``) and the float-keyed variants used by the Noise and Voronoi
textures.  Names are Cycles' own, in snake_case.

Conventions
-----------
* Every function takes arrays (or scalars) of any mutually broadcastable shapes and returns the
  broadcast shape; vector-valued functions append a last axis (2, 3 or 4).
* The ``hash_floatN_*`` functions take the key either as N component arrays,
  ``hash_float3_to_float(x, y, z)``, or as one array whose last axis has length N,
  ``hash_float3_to_float(p)`` with ``p`` of shape (..., 3).
* uint functions take and return ``np.uint32``; arithmetic wraps modulo 2**32 as in C.
* Float keys are reinterpreted as the bit pattern of their float32 value, as Cycles'
  ``__float_as_uint`` does: float64 inputs are first rounded to float32, so a float64 key hashes like
  the float32 that Cycles would hold.
* Float outputs are ``np.float64`` holding exactly Cycles' float32 value (``float(n) / 2**32`` with
  ``n`` rounded to float32, which is what ``(float)n * (1.0f / (float)0xFFFFFFFFu)`` computes).
"""
from __future__ import annotations

import numpy as np

_U32 = np.uint32
_TWO_POW_M32 = np.float32(2.0 ** -32)


def _u32(x):
    """``x`` as an np.uint32 array (integers are taken modulo 2**32)."""
    x = np.asarray(x)
    if x.dtype == np.uint32:
        return x
    return (x.astype(np.int64) & 0xFFFFFFFF).astype(np.uint32)


def float_to_int(x):
    """Cycles' ``float_to_int`` of float ``x`` (already an integer, e.g. a ``floorf``'s) as an int64
    array of int32 values: x86's conversion, which gives INT_MIN for NaN and for values beyond
    int32 (a texture Scale of 1e30, a Row Height of 0), without NumPy's cast warning."""
    x = np.asarray(x, np.float64)
    with np.errstate(invalid="ignore"):
        inside = np.abs(x) < 2.0 ** 31
    return np.where(inside, x, -2.0 ** 31).astype(np.int64)


def _rot(x, k):
    """Rotate uint32 ``x`` left by ``k`` bits."""
    return (x << _U32(k)) | (x >> _U32(32 - k))


def _final(a, b, c):
    """lookup3's ``final(a, b, c)``; returns the new (a, b, c)."""
    c = (c ^ b) - _rot(b, 14)
    a = (a ^ c) - _rot(c, 11)
    b = (b ^ a) - _rot(a, 25)
    c = (c ^ b) - _rot(b, 16)
    a = (a ^ c) - _rot(c, 4)
    b = (b ^ a) - _rot(a, 14)
    c = (c ^ b) - _rot(b, 24)
    return a, b, c


def _mix(a, b, c):
    """lookup3's ``mix(a, b, c)``; returns the new (a, b, c)."""
    a = (a - c) ^ _rot(c, 4)
    c = c + b
    b = (b - a) ^ _rot(a, 6)
    a = a + c
    c = (c - b) ^ _rot(b, 8)
    b = b + a
    a = (a - c) ^ _rot(c, 16)
    c = c + b
    b = (b - a) ^ _rot(a, 19)
    a = a + c
    c = (c - b) ^ _rot(b, 4)
    b = b + a
    return a, b, c


def _init(nkeys, *keys):
    """lookup3's initial a = b = c, broadcast to the keys' shape."""
    shape = np.broadcast_shapes(*(np.shape(k) for k in keys))
    return np.full(shape, 0xDEADBEEF + (nkeys << 2) + 13, dtype=np.uint32)


def hash_uint(kx):
    """lookup3 hash of one uint32 key; uint32 array of ``kx``'s shape."""
    kx = _u32(kx)
    with np.errstate(over="ignore"):
        a = _init(1, kx)
        b, c = a.copy(), a.copy()
        a = a + kx
        return _final(a, b, c)[2]


def hash_uint2(kx, ky):
    """lookup3 hash of two uint32 keys; uint32 array of the broadcast shape."""
    kx, ky = _u32(kx), _u32(ky)
    with np.errstate(over="ignore"):
        a = _init(2, kx, ky)
        b, c = a + ky, a.copy()
        a = a + kx
        return _final(a, b, c)[2]


def hash_uint3(kx, ky, kz):
    """lookup3 hash of three uint32 keys; uint32 array of the broadcast shape."""
    kx, ky, kz = _u32(kx), _u32(ky), _u32(kz)
    with np.errstate(over="ignore"):
        a = _init(3, kx, ky, kz)
        a, b, c = a + kx, a + ky, a + kz
        return _final(a, b, c)[2]


def hash_uint4(kx, ky, kz, kw):
    """lookup3 hash of four uint32 keys; uint32 array of the broadcast shape."""
    kx, ky, kz, kw = _u32(kx), _u32(ky), _u32(kz), _u32(kw)
    with np.errstate(over="ignore"):
        a = _init(4, kx, ky, kz, kw)
        a, b, c = _mix(a + kx, a + ky, a + kz)
        return _final(a + kw, b, c)[2]


# ------------------------------------------------------------------ uint -> float in [0, 1]
def uint_to_float_incl(n):
    """uint32 -> float64 in [0, 1]: Cycles' float32 ``(float)n * (1 / (float)0xFFFFFFFF)``."""
    return (_u32(n).astype(np.float32) * _TWO_POW_M32).astype(np.float64)


def uint_to_float_excl(n):
    """uint32 -> float64 in [0, 1): Cycles' float32 ``(float)n * (1 / 4294967808)``."""
    return (_u32(n).astype(np.float32) * np.float32(1.0 / 4294967808.0)).astype(np.float64)


def hash_uint_to_float(kx):
    """Hash of one uint32 key as float64 in [0, 1]."""
    return uint_to_float_incl(hash_uint(kx))


def hash_uint2_to_float(kx, ky):
    """Hash of two uint32 keys as float64 in [0, 1]."""
    return uint_to_float_incl(hash_uint2(kx, ky))


def hash_uint3_to_float(kx, ky, kz):
    """Hash of three uint32 keys as float64 in [0, 1]."""
    return uint_to_float_incl(hash_uint3(kx, ky, kz))


def hash_uint4_to_float(kx, ky, kz, kw):
    """Hash of four uint32 keys as float64 in [0, 1]."""
    return uint_to_float_incl(hash_uint4(kx, ky, kz, kw))


# ------------------------------------------------------------------ float keys
def float_as_uint(x):
    """Cycles' ``__float_as_uint``: the bits of ``x`` rounded to float32, as uint32 (same shape)."""
    return np.asarray(x, dtype=np.float32).view(np.uint32)


def _components(keys, n):
    """The N key components from either N arrays or one (..., N) array."""
    if len(keys) == n:
        return keys
    if len(keys) == 1 and np.shape(keys[0])[-1:] == (n,):
        k = np.asarray(keys[0])
        return tuple(k[..., i] for i in range(n))
    raise ValueError(f"expected {n} key components or one (..., {n}) array")


def hash_float_to_float(k):
    """Hash of float key ``k`` (any shape) as float64 in [0, 1], same shape."""
    return hash_uint_to_float(float_as_uint(k))


def hash_float2_to_float(*k):
    """Hash of the float2 (kx, ky) as float64 in [0, 1], broadcast shape."""
    kx, ky = _components(k, 2)
    return hash_uint2_to_float(float_as_uint(kx), float_as_uint(ky))


def hash_float3_to_float(*k):
    """Hash of the float3 (kx, ky, kz) as float64 in [0, 1], broadcast shape."""
    kx, ky, kz = _components(k, 3)
    return hash_uint3_to_float(float_as_uint(kx), float_as_uint(ky), float_as_uint(kz))


def hash_float4_to_float(*k):
    """Hash of the float4 (kx, ky, kz, kw) as float64 in [0, 1], broadcast shape."""
    kx, ky, kz, kw = _components(k, 4)
    return hash_uint4_to_float(float_as_uint(kx), float_as_uint(ky), float_as_uint(kz), float_as_uint(kw))


# ------------------------------------------------------------------ float keys -> vectors
def hash_float2_to_float2(*k):
    """float2 key -> (..., 2) float64 in [0, 1]."""
    kx, ky = _components(k, 2)
    return np.stack([hash_float2_to_float(kx, ky), hash_float3_to_float(kx, ky, 1.0)], axis=-1)


def hash_float3_to_float3(*k):
    """float3 key -> (..., 3) float64 in [0, 1]."""
    kx, ky, kz = _components(k, 3)
    return np.stack([hash_float3_to_float(kx, ky, kz),
                     hash_float4_to_float(kx, ky, kz, 1.0),
                     hash_float4_to_float(kx, ky, kz, 2.0)], axis=-1)


def hash_float4_to_float4(*k):
    """float4 key -> (..., 4) float64 in [0, 1]."""
    kx, ky, kz, kw = _components(k, 4)
    return np.stack([hash_float4_to_float(kx, ky, kz, kw),
                     hash_float4_to_float(kw, kx, ky, kz),
                     hash_float4_to_float(kz, kw, kx, ky),
                     hash_float4_to_float(ky, kz, kw, kx)], axis=-1)


def hash_float_to_float3(k):
    """float key -> (..., 3) float64 in [0, 1]."""
    return np.stack([hash_float_to_float(k),
                     hash_float2_to_float(k, 1.0),
                     hash_float2_to_float(k, 2.0)], axis=-1)


def hash_float2_to_float3(*k):
    """float2 key -> (..., 3) float64 in [0, 1]."""
    kx, ky = _components(k, 2)
    return np.stack([hash_float2_to_float(kx, ky),
                     hash_float3_to_float(kx, ky, 1.0),
                     hash_float3_to_float(kx, ky, 2.0)], axis=-1)


def hash_float4_to_float3(*k):
    """float4 key -> (..., 3) float64 in [0, 1]."""
    kx, ky, kz, kw = _components(k, 4)
    return np.stack([hash_float4_to_float(kx, ky, kz, kw),
                     hash_float4_to_float(kz, kx, kw, ky),
                     hash_float4_to_float(kw, kz, ky, kx)], axis=-1)


# The ``*_to_color`` names of Cycles' OSL / older SVM code are the same functions.
hash_float_to_color = hash_float_to_float3
hash_float2_to_color = hash_float2_to_float3
hash_float3_to_color = hash_float3_to_float3
hash_float4_to_color = hash_float4_to_float3


# ------------------------------------------------------------------ integer keys (PCG)
# Blender >= 4.3 hashes the integer cells of the 2D / 3D / 4D Voronoi texture with these
# (``hash_pcg{2,3,4}d_i`` and ``hash_int{2,3,4}_to_float*`` of ``util/hash.h``): Jarzynski and Olano's
# PCG hashes ("Hash Functions for GPU Rendering", JCGT 2020) on signed int32, wrapping on overflow, with
# an arithmetic shift; the result masked to 31 bits.
_PCG_MUL = np.int32(1664525)
_PCG_ADD = np.int32(1013904223)


def _i32(x):
    """``x`` as an np.int32 array (integers are taken modulo 2**32, as a C int)."""
    x = np.asarray(x)
    if x.dtype == np.int32:
        return x
    return x.astype(np.int64).astype(np.int32)


def _pcg_start(keys):
    """v * 1664525 + 1013904223 of each key component, broadcast to a common shape."""
    keys = np.broadcast_arrays(*(_i32(k) for k in keys))
    return [k * _PCG_MUL + _PCG_ADD for k in keys]


def _xorshift16(v):
    return [x ^ (x >> np.int32(16)) for x in v]


def hash_pcg2d_i(*k):
    """Cycles' ``hash_pcg2d_i``: int2 key -> (..., 2) int32 in [0, 2**31)."""
    with np.errstate(over="ignore"):
        x, y = _pcg_start(_components(k, 2))
        x = x + y * _PCG_MUL
        y = y + x * _PCG_MUL
        x, y = _xorshift16((x, y))
        x = x + y * _PCG_MUL
        y = y + x * _PCG_MUL
    return np.stack([x, y], axis=-1) & np.int32(0x7FFFFFFF)


def hash_pcg3d_i(*k):
    """Cycles' ``hash_pcg3d_i``: int3 key -> (..., 3) int32 in [0, 2**31)."""
    with np.errstate(over="ignore"):
        x, y, z = _pcg_start(_components(k, 3))
        for step in range(2):
            if step:
                x, y, z = _xorshift16((x, y, z))
            x = x + y * z
            y = y + z * x
            z = z + x * y
    return np.stack([x, y, z], axis=-1) & np.int32(0x7FFFFFFF)


def hash_pcg4d_i(*k):
    """Cycles' ``hash_pcg4d_i``: int4 key -> (..., 4) int32 in [0, 2**31)."""
    with np.errstate(over="ignore"):
        x, y, z, w = _pcg_start(_components(k, 4))
        for step in range(2):
            if step:
                x, y, z, w = _xorshift16((x, y, z, w))
            x = x + y * w
            y = y + z * x
            z = z + x * y
            w = w + y * z
    return np.stack([x, y, z, w], axis=-1) & np.int32(0x7FFFFFFF)


def _int_hash_to_float(h):
    """Cycles' ``(float)h * (1.0f / (float)0x7FFFFFFFu)``: h rounded to float32 times 2**-31, float64."""
    return h.astype(np.float32).astype(np.float64) * 2.0 ** -31


def hash_int2_to_float2(*k):
    """int2 key -> (..., 2) float64 in [0, 1] (PCG 2D)."""
    return _int_hash_to_float(hash_pcg2d_i(*k))


def hash_int3_to_float3(*k):
    """int3 key -> (..., 3) float64 in [0, 1] (PCG 3D)."""
    return _int_hash_to_float(hash_pcg3d_i(*k))


def hash_int4_to_float4(*k):
    """int4 key -> (..., 4) float64 in [0, 1] (PCG 4D)."""
    return _int_hash_to_float(hash_pcg4d_i(*k))


def hash_int2_to_float3(*k):
    """int2 key -> (..., 3) float64 in [0, 1]: ``hash_int3_to_float3`` of (x, y, 0)."""
    kx, ky = _components(k, 2)
    return hash_int3_to_float3(kx, ky, 0)


def hash_int4_to_float3(*k):
    """int4 key -> (..., 3) float64 in [0, 1]: the first three components of ``hash_int4_to_float4``."""
    return hash_int4_to_float4(*k)[..., :3]

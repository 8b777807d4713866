"""Warps from the unit square to directions and shapes, with their densities.

Pure vectorised functions: inputs are arrays of uniform numbers in [0, 1), outputs
arrays of samples.  Local directions use a frame whose +Z is the normal.
Densities are per unit solid angle (directions) or per unit area (shapes).
"""
from __future__ import annotations

import numpy as np

INV_PI = 1.0 / np.pi


def luminance(rgb):
    """Rec.709 luminance of (..., 3) linear RGB."""
    rgb = np.asarray(rgb)
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def dot(a, b):
    """Row-wise dot product of (n, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def length(v):
    """Row lengths of (n, 3) ``v`` (``np.linalg.norm`` over axis 1 reduces a short axis: slow)."""
    return np.sqrt(dot(v, v))


def normalize(v):
    """Rows of (n, 3) scaled to unit length; zero rows stay zero."""
    n = length(v)
    return v / np.where(n > 0, n, 1.0)[:, None]


def inverse(m):
    """Inverses of square matrices ``m`` (..., k, k), the pseudo-inverse of singular ones (an object
    flattened to scale 0 on an axis: its points keep their coordinates along the others, 0 along
    that one), never ``LinAlgError``."""
    m = np.asarray(m, np.float64)
    flat = m.reshape(-1, m.shape[-2], m.shape[-1])
    scale = np.abs(flat).max(axis=(1, 2)) if len(flat) else np.zeros(0)
    with np.errstate(over="ignore", invalid="ignore"):
        det = np.linalg.det(flat)
    singular = ~(np.abs(det) > 1e-12 * np.maximum(scale, 1e-300) ** m.shape[-1])
    out = np.empty_like(flat)
    if (~singular).any():
        out[~singular] = np.linalg.inv(flat[~singular])
    if singular.any():
        out[singular] = np.linalg.pinv(np.where(np.isfinite(flat[singular]), flat[singular], 0.0))
    return out.reshape(m.shape)


def affine_inverse(m):
    """The inverses (..., 3, 4) of affine maps ``m`` (..., 3 or 4, 4: rows of a linear part and a
    translation), by :func:`inverse` of their linear parts (pseudo-inverses where flattened)."""
    m = np.asarray(m, np.float64)
    linear = inverse(m[..., :3, :3])
    return np.concatenate([linear, -(linear @ m[..., :3, 3:])], axis=-1)


def orthonormal_frames(n):
    """Tangent and bitangent (n, 3) completing unit normals ``n`` (Duff et al. 2017)."""
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] * n[:, 0] * a, sign * b, -sign * n[:, 0]], axis=1)
    bt = np.stack([b, sign + n[:, 1] * n[:, 1] * a, -n[:, 1]], axis=1)
    return t, bt


def to_world(local, n):
    """Rotate local directions (z = normal) into the frames around unit normals ``n``.

    The same frames as :func:`orthonormal_frames`, written per column (fewer temporaries).
    """
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    x, y, z = local[:, 0], local[:, 1], local[:, 2]
    sign = np.where(nz >= 0, 1.0, -1.0)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    out = np.empty((len(n), 3))
    out[:, 0] = x * (1.0 + sign * nx * nx * a) + y * b + z * nx
    out[:, 1] = x * (sign * b) + y * (sign + ny * ny * a) + z * ny
    out[:, 2] = -x * (sign * nx) - y * ny + z * nz
    return out


def to_local(v, n):
    """Express world vectors ``v`` in the frames around ``n`` (inverse of :func:`to_world`)."""
    t, b = orthonormal_frames(n)
    return np.stack([dot(v, t), dot(v, b), dot(v, n)], axis=1)


def concentric_disk(u1, u2):
    """Uniform points on the unit disk (Shirley-Chiu), area density 1/pi."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    use_a = np.abs(a) > np.abs(b)
    r = np.where(use_a, a, b)
    safe_a = np.where(a == 0, 1.0, a)
    safe_b = np.where(b == 0, 1.0, b)
    phi = np.where(use_a, (np.pi / 4) * (b / safe_a), np.pi / 2 - (np.pi / 4) * (a / safe_b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return r * np.cos(phi), r * np.sin(phi)


def splitmix64(z):
    """SplitMix64's finaliser of the uint64 array ``z`` (its arithmetic wraps): well-mixed bits
    from counters and seeds, a function of ``z`` alone."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def hash_bits(keys, salt, dims):
    """(n, dims) uint64 hash of the integers ``keys`` (n,) and ``salt`` (an integer below 2^64):
    :func:`splitmix64` of key x dims + dimension times the golden ratio plus the salt.  Random bits
    for many items (a render's pixels) without a stream to keep or a table to store."""
    k = np.asarray(keys).astype(np.uint64)[:, None] * np.uint64(dims) + np.arange(dims, dtype=np.uint64)
    return splitmix64(k * np.uint64(0x9E3779B97F4A7C15) + np.uint64(salt))


def sobol_02(index):
    """(a, b): point ``index`` of the (0, 2)-sequence in base 2 (Sobol's first two dimensions, the
    van der Corput sequence and the one of the polynomial x + 1) as two 32-bit integers, the
    coordinates times 2^32.  Its first 2^k points put one in each of the 2^k boxes of area 2^-k
    of every shape whose sides are powers of two (a (0, k, 2)-net), and so do the next 2^k and each
    block of 2^k after them (2^(k-4) in each quarter-by-quarter cell); an XOR of every point with
    the same bits keeps that."""
    a = b = 0
    v = 1 << 31                         # the second dimension's direction number of bit k
    for k in range(32):
        if (index >> k) & 1:
            a ^= 1 << (31 - k)
            b ^= v
        v ^= v >> 1
    return a, b


# Sobol's dimensions 3 to 11 (Joe and Kuo's direction numbers, new-joe-kuo-6.21201): the degree s,
# the coefficients a and the initial m of the primitive polynomials x^2 + x + 1, x^3 + x + 1,
# x^3 + x^2 + 1, x^4 + x + 1, x^4 + x^3 + 1 and four of degree 5 (8 to 11: the camera does not
# take them; benchmarks/light_numbers.py compares them with the light samples' own sequence).
SOBOL_POLYNOMIALS = {3: (2, 1, (1, 3)), 4: (3, 1, (1, 3, 1)), 5: (3, 2, (1, 1, 1)), 6: (4, 1, (1, 1, 3, 3)),
                     7: (4, 4, (1, 3, 5, 13)), 8: (5, 2, (1, 1, 5, 5, 17)), 9: (5, 4, (1, 1, 5, 5, 5)),
                     10: (5, 7, (1, 1, 7, 11, 19)), 11: (5, 11, (1, 1, 5, 1, 1))}


def sobol_directions(dim):
    """The 32 direction numbers of Sobol's dimension ``dim`` (1 to 11) as 32-bit integers: point
    ``index`` is the XOR of those of its set bits (Bratley and Fox's recurrence; 1 and 2 are
    :func:`sobol_02`'s)."""
    if dim <= 2:
        return [sobol_02(1 << k)[dim - 1] for k in range(32)]
    s, a, m = SOBOL_POLYNOMIALS[dim]
    v = [m[i] << (31 - i) for i in range(s)]
    for i in range(s, 32):
        x = v[i - s] ^ (v[i - s] >> s)
        for k in range(1, s):
            if (a >> (s - 1 - k)) & 1:
                x ^= v[i - k]
        v.append(x)
    return v


def sobol(index, dims):
    """Point ``index`` of Sobol's dimensions ``dims`` (each 3 to 11; 1 and 2 are :func:`sobol_02`'s)
    as 32-bit integers, the coordinates times 2^32 (:func:`sobol_directions`).  With
    :func:`sobol_02`'s two they make the Sobol sequence: its first 2^k points put 2^(k - i - j) in
    each box of 2^-i by 2^-j in any pair of dimensions up to 4 (up to 7: with a t of at most 2 or
    3), and an XOR of every point with the same bits keeps that."""
    out = []
    for dim in dims:
        c = 0
        for k, v in enumerate(sobol_directions(dim)):
            if (index >> k) & 1:
                c ^= v
        out.append(c)
    return tuple(out)


def sobol_points(index, dims):
    """(n, len(dims)) uint64: points ``index`` ((n,) integers below 2^32, each its own) of Sobol's
    dimensions ``dims`` (1 to 11) as 32-bit integers, the vectorised :func:`sobol`: per byte of
    the index a table of its 256 XORs of direction numbers."""
    index = np.asarray(index).astype(np.uint64)
    v = np.array([sobol_directions(d) for d in dims], np.uint64).T          # (32, len(dims))
    out = np.zeros((len(index), len(dims)), np.uint64)
    for byte in range(4):
        table = np.zeros((1, len(dims)), np.uint64)
        for k in range(8):
            table = np.concatenate([table, table ^ v[8 * byte + k]])
        out ^= table.take(((index >> np.uint64(8 * byte)) & np.uint64(255)).astype(np.intp), axis=0)
    return out


def reverse_bits32(x):
    """The uint32 array ``x`` with each value's 32 bits in reverse order."""
    x = np.asarray(x).astype(np.uint32)
    for shift, mask in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF)):
        s, m = np.uint32(shift), np.uint32(mask)
        x = ((x >> s) & m) | ((x & m) << s)
    return (x >> np.uint32(16)) | (x << np.uint32(16))


def owen_scramble(x, seed):
    """Burley's (2020) nested uniform (Owen) scramble of the 32-bit integers ``x`` with each its own
    32-bit ``seed`` (same shape): bit k of the result is bit k of ``x`` XORed with a hash of the
    seed and the bits of ``x`` above k, so that the map takes every aligned block of 2^k integers
    onto another (a random permutation of the blocks at every level).  On an index it keeps the
    points of a (t, s)-sequence in each block of 2^k scrambled indices a net (those of an aligned
    block) while their order, and so their pairing with another sequence's, is random; on a
    coordinate (times 2^32) it permutes the strata of every size at random, keeping a net a net
    (Owen's scramble, uniform in every point).  The hash is Laine and Karras's on the reversed bits
    (each step changes a bit by those below it), with Burley's constants."""
    x = reverse_bits32(x)
    seed = np.asarray(seed).astype(np.uint32)
    x ^= x * np.uint32(0x3D20ADEA)
    x += seed
    x *= (seed >> np.uint32(16)) | np.uint32(1)
    x ^= x * np.uint32(0x05526C56)
    x ^= x * np.uint32(0x53A22864)
    return reverse_bits32(x)


def scrambled_sobol(index, dims, seeds):
    """(n, len(dims)) numbers in [0, 1): points ``index`` (n,) of Sobol's dimensions ``dims``, the
    index and each coordinate Owen-scrambled (:func:`owen_scramble`) with the 32-bit ``seeds`` (n,
    len(dims) + 1; the last the index's): Cycles' Sobol-Burley pattern, each point uniform and the
    points of one seed, index after index, a net."""
    index = owen_scramble(index, seeds[:, len(dims)])
    return owen_scramble(sobol_points(index, dims), seeds[:, :len(dims)]).astype(np.float64) * 2.0 ** -32


def cosine_hemisphere(u1, u2):
    """Cosine-weighted local directions; density cos(theta)/pi."""
    x, y = concentric_disk(u1, u2)
    z = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
    return np.stack([x, y, z], axis=1)


def cosine_hemisphere_pdf(cos_theta):
    return np.maximum(cos_theta, 0.0) * INV_PI


def uniform_sphere(u1, u2):
    """Uniform directions on the unit sphere; density 1/(4 pi)."""
    z = 1.0 - 2.0 * u1
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def uniform_cone(u1, u2, cos_max):
    """Uniform local directions within ``acos(cos_max)`` of +Z; density 1/(2 pi (1 - cos_max))."""
    z = 1.0 - u1 * (1.0 - cos_max)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def uniform_triangle(u1, u2):
    """Barycentrics (b1, b2) uniform over a triangle (area density 1/area)."""
    s = np.sqrt(u1)
    return s * (1.0 - u2), s * u2


def smoothstep(x):
    """Hermite smoothstep of ``x`` clamped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def reflect(wo, n):
    """Mirror ``wo`` (pointing away from the surface) about ``n``."""
    return 2.0 * dot(wo, n)[:, None] * n - wo


def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance and the refracted cosine.

    ``cos_i`` >= 0 is the cosine of the incident direction on the incident side,
    ``eta`` = n_transmitted / n_incident.  Returns ``(F, cos_t)`` with F = 1 and
    cos_t = 0 under total internal reflection (no NaN).
    """
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    r_s = (cos_i - eta * cos_t) / np.maximum(cos_i + eta * cos_t, 1e-30)
    r_p = (eta * cos_i - cos_t) / np.maximum(eta * cos_i + cos_t, 1e-30)
    f = np.where(tir, 1.0, 0.5 * (r_s * r_s + r_p * r_p))
    return np.minimum(f, 1.0), np.where(tir, 0.0, cos_t)


def refract(wo, n, eta, cos_t):
    """Refract ``wo`` (pointing away from the surface on ``n``'s side) through the surface.

    ``eta`` = n_transmitted / n_incident and ``cos_t`` from :func:`fresnel_dielectric`.
    """
    cos_i = dot(wo, n)
    return (-wo / eta[:, None]) + ((cos_i / eta) - cos_t)[:, None] * n


# ---------------------------------------------------------------- GGX microfacets
def ggx_d(cos_m, alpha):
    """GGX normal distribution D(m) for the cosine of the half vector to the normal."""
    a2 = alpha * alpha
    c2 = cos_m * cos_m
    denom = c2 * (a2 - 1.0) + 1.0
    return np.where(cos_m > 0, a2 / (np.pi * denom * denom), 0.0)


def ggx_lambda(cos_v, alpha):
    """Smith Lambda for GGX."""
    c2 = np.maximum(cos_v * cos_v, 1e-300)
    t2 = np.maximum(0.0, 1.0 - c2) / c2
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * t2) - 1.0)


def ggx_g1(cos_v, alpha):
    return 1.0 / (1.0 + ggx_lambda(cos_v, alpha))


def ggx_g2(cos_o, cos_i, alpha):
    """Height-correlated Smith masking-shadowing."""
    return 1.0 / (1.0 + ggx_lambda(cos_o, alpha) + ggx_lambda(cos_i, alpha))


def ggx_sample_visible_normal(wo_local, alpha, u1, u2, alpha_y=None):
    """Sample a microfacet normal from the GGX distribution of visible normals (Heitz 2018).

    ``wo_local`` (n, 3) with z > 0.  The half vector's density is
    G1(wo) max(0, wo.m) D(m) / wo.z.  With ``alpha_y`` the distribution is anisotropic:
    ``alpha`` along the local x axis, ``alpha_y`` along y (Heitz 2014).
    """
    ay = alpha if alpha_y is None else alpha_y
    vh = normalize(np.stack([alpha * wo_local[:, 0], ay * wo_local[:, 1], wo_local[:, 2]], axis=1))
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    inv = 1.0 / np.sqrt(np.where(lensq > 0, lensq, 1.0))
    t1 = np.where((lensq > 0)[:, None], np.stack([-vh[:, 1] * inv, vh[:, 0] * inv,
                                                  np.zeros_like(inv)], axis=1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(vh, t1)
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vh[:, 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
    p3 = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = p1[:, None] * t1 + p2[:, None] * t2 + p3[:, None] * vh
    return normalize(np.stack([alpha * nh[:, 0], ay * nh[:, 1], np.maximum(1e-9, nh[:, 2])], axis=1))


def ggx_lambda_aniso(v_local, alpha_x, alpha_y):
    """Smith Lambda of anisotropic GGX for local directions ``v_local`` (n, 3): the isotropic
    one with the alpha of v's azimuth, sqrt(alpha_x^2 cos^2 phi + alpha_y^2 sin^2 phi)."""
    z2 = np.maximum(v_local[:, 2] * v_local[:, 2], 1e-300)
    s = ((alpha_x * v_local[:, 0]) ** 2 + (alpha_y * v_local[:, 1]) ** 2) / z2
    return 0.5 * (np.sqrt(1.0 + s) - 1.0)


def tangent_frames(n, t):
    """(x, y) (n, 3) completing unit normals ``n`` with x along tangents ``t`` projected onto
    their planes and y = n x x (Cycles' ``make_orthonormals_tangent``); where a tangent is
    (nearly) along its normal, the frame of :func:`orthonormal_frames`."""
    x = tangent_axes(n, t)
    return x, np.cross(n, x)


def tangent_axes(n, t):
    """The x axes of :func:`tangent_frames`, in the dtype of the inputs (float32 points keep
    their temporaries small)."""
    x = t - dot(t, n)[:, None] * n
    length = np.sqrt(dot(x, x))
    bad = length < (1e-9 if x.dtype == np.float64 else 1e-5)
    x /= np.where(bad, 1.0, length)[:, None]
    if bad.any():
        x[bad] = orthonormal_frames(n[bad].astype(np.float64))[0]
    return x


# ---------------------------------------------------------------- Beckmann microfacets
# Blender's glossy, glass and metallic nodes offer Beckmann beside GGX, and it is the Refraction
# BSDF's default.  Cycles weighs its samples with Walter et al.'s rational fit of the Smith
# Lambda (``beckmann_lambda``); the visible normals are sampled exactly (Heitz and d'Eon 2014,
# with Jakob's inversion of the slope distribution), whose density has the exact Lambda.

def erfc(x):
    """Vectorised complementary error function: the Chebyshev fit of Numerical Recipes (relative
    error below 1.2e-7 everywhere, tails included)."""
    x = np.asarray(x, np.float64)
    z = np.minimum(np.abs(x), 30.0)                     # (erfc(30) < 1e-392: 0 in float64)
    t = 1.0 / (1.0 + 0.5 * z)
    poly = -1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (
        -0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (
            -0.82215223 + t * 0.17087277))))))))
    r = t * np.exp(-z * z + poly)
    return np.where(x >= 0, r, 2.0 - r)


def erf(x):
    """Vectorised error function, 1 - :func:`erfc` (absolute error below 1.2e-7)."""
    return 1.0 - erfc(x)


def erfinv(y):
    """Vectorised inverse error function on (-1, 1): Giles' single-precision fit (2010) and one
    Newton step on :func:`erf`; +-inf at +-1."""
    y = np.asarray(y, np.float64)
    inner = np.clip(y, -1.0 + 1e-16, 1.0 - 1e-16)
    w = -np.log((1.0 - inner) * (1.0 + inner))
    low = w - 2.5
    p_low = 2.81022636e-08
    for c in (3.43273939e-07, -3.5233877e-06, -4.39150654e-06, 0.00021858087, -0.00125372503,
              -0.00417768164, 0.246640727, 1.50140941):
        p_low = c + p_low * low
    high = np.sqrt(w) - 3.0
    p_high = -0.000200214257
    for c in (0.000100950558, 0.00134934322, -0.00367342844, 0.00573950773, -0.0076224613,
              0.00943887047, 1.00167406, 2.83297682):
        p_high = c + p_high * high
    x = np.where(w < 5.0, p_low, p_high) * inner
    x = x - (erf(x) - inner) / (2.0 / np.sqrt(np.pi) * np.exp(-x * x))
    return np.where(np.abs(y) >= 1.0, np.copysign(np.inf, y), x)


def beckmann_d(cos_m, alpha):
    """Beckmann normal distribution D(m) for the cosine of the half vector to the normal."""
    a2 = alpha * alpha
    c2 = np.minimum(cos_m * cos_m, 1.0)
    return np.where(cos_m > 0, beckmann_exp(c2, (1.0 - c2) / a2) / (np.pi * a2), 0.0)


def beckmann_exp(c2, s):
    """exp(-s / c2) / c2^2 (the Beckmann D times pi ax ay, ``s`` the stretched squared sine of the
    half vector: (1 - c2) / alpha^2 isotropic, hx^2 / ax^2 + hy^2 / ay^2 anisotropic) without
    overflow or 0 / 0 at the horizon (c2 -> 0: 0)."""
    c2 = np.clip(c2, 1e-150, 1.0)
    return np.exp(np.minimum(-np.maximum(s, 0.0) / c2 - 2.0 * np.log(c2), 700.0))


def beckmann_lambda(cos_v, alpha):
    """Smith Lambda of Beckmann, Walter et al.'s rational fit (Cycles' ``bsdf_lambda``): 0 for
    a = 1 / (alpha tan theta) >= 1.6."""
    c2 = np.maximum(cos_v * cos_v, 1e-300)
    return beckmann_lambda_of(alpha * alpha * np.maximum(0.0, 1.0 - c2) / c2)


def beckmann_lambda_aniso(v_local, alpha_x, alpha_y):
    """:func:`beckmann_lambda` of anisotropic Beckmann for local directions ``v_local`` (n, 3)."""
    z2 = np.maximum(v_local[:, 2] * v_local[:, 2], 1e-300)
    return beckmann_lambda_of(((alpha_x * v_local[:, 0]) ** 2 + (alpha_y * v_local[:, 1]) ** 2) / z2)


def beckmann_lambda_of(sqr_alpha_tan):
    """:func:`beckmann_lambda` of alpha^2 tan^2 theta (stretched by the azimuth's alpha where
    anisotropic)."""
    a = 1.0 / np.sqrt(np.maximum(sqr_alpha_tan, 1e-300))
    lam = ((0.396 * a - 1.259) * a + 1.0) / ((2.181 * a + 3.535) * a)
    return np.where(sqr_alpha_tan < 0.39, 0.0, lam)


def beckmann_lambda_exact(cos_v, alpha):
    """The exact Smith Lambda of Beckmann, (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)) with
    a = 1 / (alpha tan theta): the normaliser of :func:`beckmann_sample_visible_normal`."""
    c2 = np.maximum(cos_v * cos_v, 1e-300)
    tan = np.sqrt(np.maximum(0.0, 1.0 - c2) / c2)
    a = np.minimum(1.0 / np.maximum(alpha * tan, 1e-300), 30.0)
    return np.where(a >= 30.0, 0.0, -0.5 * erfc(a) + np.exp(-a * a) / (2.0 * a * np.sqrt(np.pi)))


def beckmann_sample_visible_normal(wo_local, alpha, u1, u2, alpha_y=None, iterations=6):
    """Sample a microfacet normal from the Beckmann distribution of visible normals of
    ``wo_local`` (n, 3) with z > 0: density G1(wo) max(0, wo.m) D(m) / wo.z (exact G1).  The
    view is stretched to roughness 1, the slope along its azimuth drawn by inverting the
    cumulative 1 + erf(x) + K exp(-x^2) (K = tan theta / sqrt(pi), x below cot theta) with
    Newton steps on b = erf(x) kept in their bracket (Jakob's reformulation, its first guess),
    the other slope a Gaussian, both turned back and unstretched.  ``alpha_y`` as in
    :func:`ggx_sample_visible_normal`."""
    ax = np.broadcast_to(np.asarray(alpha, np.float64), u1.shape)
    ay = ax if alpha_y is None else np.broadcast_to(np.asarray(alpha_y, np.float64), u1.shape)
    v = normalize(np.stack([ax * wo_local[:, 0], ay * wo_local[:, 1], wo_local[:, 2]], axis=1))
    cos_t = np.clip(v[:, 2], 1e-9, 1.0)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    u1 = np.clip(u1, 1e-12, 1.0 - 1e-12)
    tilted = sin_t > 1e-5
    tan_t = sin_t / cos_t
    a = cos_t / np.maximum(sin_t, 1e-5)
    k = tan_t / np.sqrt(np.pi)
    erf_a = erf(a)
    exp_a2 = np.exp(-a * a)
    y = u1 * (1.0 + erf_a + k * exp_a2)
    y_approx = u1 * (1.0 + erf_a + k * (1.0 - erf_a * erf_a))
    b = np.where(k > 0, (0.5 - np.sqrt(np.maximum(k * (k - y_approx + 1.0) + 0.25, 0.0)))
                 / np.maximum(k, 1e-300), y_approx - 1.0)
    lo, hi = np.full_like(b, -1.0), erf_a.copy()
    b = np.clip(b, lo, hi)
    for _ in range(iterations):
        x = erfinv(b)
        g = 1.0 + b + k * np.exp(-x * x) - y
        lo = np.where(g < 0, b, lo)
        hi = np.where(g < 0, hi, b)
        step = b - g / np.maximum(1.0 - x * tan_t, 1e-12)
        b = np.where((step >= lo) & (step <= hi), step, 0.5 * (lo + hi))
    slope_x = erfinv(np.clip(b, -1.0 + 1e-16, 1.0 - 1e-16))
    slope_y = erfinv(np.clip(2.0 * u2 - 1.0, -1.0 + 1e-16, 1.0 - 1e-16))
    # Seen from the normal: slopes of the plain distribution, a Gaussian disc.
    r = np.sqrt(-np.log(u1))
    slope_x = np.where(tilted, slope_x, r * np.cos(2.0 * np.pi * u2))
    slope_y = np.where(tilted, slope_y, r * np.sin(2.0 * np.pi * u2))
    inv = 1.0 / np.where(tilted, sin_t, 1.0)
    cos_p, sin_p = np.where(tilted, v[:, 0] * inv, 1.0), np.where(tilted, v[:, 1] * inv, 0.0)
    sx = (cos_p * slope_x - sin_p * slope_y) * ax
    sy = (sin_p * slope_x + cos_p * slope_y) * ay
    return normalize(np.stack([-sx, -sy, np.ones_like(sx)], axis=1))


def microfacet_d(cos_m, alpha, beckmann=None):
    """D(m) of GGX, or of Beckmann where the (n,) bool ``beckmann`` is set."""
    d = ggx_d(cos_m, alpha)
    if beckmann is None or not beckmann.any():
        return d
    return np.where(beckmann, beckmann_d(cos_m, alpha), d)


def microfacet_lambda(cos_v, alpha, beckmann=None):
    """Smith Lambda of GGX, or of Beckmann (Cycles' fit) where ``beckmann`` is set."""
    lam = ggx_lambda(cos_v, alpha)
    if beckmann is None or not beckmann.any():
        return lam
    return np.where(beckmann, beckmann_lambda(cos_v, alpha), lam)


def microfacet_lambda_aniso(v_local, alpha_x, alpha_y, beckmann=None):
    lam = ggx_lambda_aniso(v_local, alpha_x, alpha_y)
    if beckmann is None or not beckmann.any():
        return lam
    return np.where(beckmann, beckmann_lambda_aniso(v_local, alpha_x, alpha_y), lam)


def microfacet_ratio(cos_o, cos_i, alpha, beckmann=None):
    """G2 / G1 = (1 + Lambda(wo)) / (1 + Lambda(wo) + Lambda(wi)): the weight of a sampled
    visible normal (Cycles' eval / pdf), of GGX or of Beckmann where ``beckmann`` is set."""
    if beckmann is None or not beckmann.any():
        return ggx_g2(cos_o, cos_i, alpha) / ggx_g1(cos_o, alpha)
    lam_o = microfacet_lambda(cos_o, alpha, beckmann)
    return (1.0 + lam_o) / (1.0 + lam_o + microfacet_lambda(cos_i, alpha, beckmann))


def sample_visible_normal(wo_local, alpha, u1, u2, alpha_y=None, beckmann=None):
    """:func:`ggx_sample_visible_normal`, or :func:`beckmann_sample_visible_normal` for the rows
    where the (n,) bool ``beckmann`` is set."""
    m = ggx_sample_visible_normal(wo_local, alpha, u1, u2, alpha_y)
    if beckmann is None or not beckmann.any():
        return m
    b = np.flatnonzero(beckmann)

    def rows(x):
        return None if x is None else np.broadcast_to(np.asarray(x, np.float64), u1.shape).take(b)
    m[b] = beckmann_sample_visible_normal(wo_local.take(b, axis=0), rows(alpha), u1.take(b), u2.take(b),
                                          rows(alpha_y))
    return m


def beckmann_reflection_pdf(wo_local, wi_local, alpha):
    """Density of :func:`beckmann_sample_visible_normal` + reflection, per solid angle of wi."""
    m = normalize(wo_local + wi_local)
    cos_o = wo_local[:, 2]
    g1 = 1.0 / (1.0 + beckmann_lambda_exact(cos_o, alpha))
    d_vis = g1 * np.maximum(0.0, dot(wo_local, m)) * beckmann_d(m[:, 2], alpha) / np.maximum(cos_o, 1e-12)
    return np.where((cos_o > 0) & (wi_local[:, 2] > 0),
                    d_vis / np.maximum(4.0 * np.abs(dot(wo_local, m)), 1e-12), 0.0)


def ggx_reflection_pdf(wo_local, wi_local, alpha):
    """Density of :func:`ggx_sample_visible_normal` + reflection, per solid angle of wi."""
    m = normalize(wo_local + wi_local)
    cos_o = wo_local[:, 2]
    d_vis = ggx_g1(cos_o, alpha) * np.maximum(0.0, dot(wo_local, m)) * ggx_d(m[:, 2], alpha) \
        / np.maximum(cos_o, 1e-12)
    return np.where((cos_o > 0) & (wi_local[:, 2] > 0),
                    d_vis / np.maximum(4.0 * np.abs(dot(wo_local, m)), 1e-12), 0.0)


def ggx_reflection_f(wo_local, wi_local, alpha):
    """Scalar GGX reflection BSDF value (no Fresnel, no colour)."""
    m = normalize(wo_local + wi_local)
    cos_o, cos_i = wo_local[:, 2], wi_local[:, 2]
    valid = (cos_o > 0) & (cos_i > 0)
    f = ggx_d(m[:, 2], alpha) * ggx_g2(cos_o, cos_i, alpha) / np.maximum(4.0 * cos_o * cos_i, 1e-12)
    return np.where(valid, f, 0.0)


def ggx_albedo(alpha, mu, strata=64):
    """Directional albedo E(mu) = integral of f |cos_i| over wi of GGX reflection without Fresnel.

    ``alpha`` a scalar, ``mu`` (k,) cosines of the view direction; returns (k,) float64 in
    (0, 1].  Deterministic: the midpoint rule on a ``strata`` x ``strata`` grid of visible-normal
    samples (``ggx_sample_visible_normal``), each weighing G2 / G1.  The radial coordinate is
    u1 = 1 - (1 - t)^3, midpoints in t: the reflection drops below the horizon in a sliver of
    u1 near 1 (1 - u1 < alpha^2 / (1 + alpha^2) at normal view), which uniform u1 resolves
    badly at low roughness (0.007 off at roughness 0.3; now within 2e-4 of a 2048 x 2048 grid
    at roughness 0.15 to 1).
    The energy a single scattering loses is 1 - E; multiple-scattering GGX puts it back.
    """
    w, _ = _ggx_reflection_nodes(alpha, mu, strata)
    return w.mean(axis=1)


def ggx_fresnel_rise_average(alpha, mu, eta, strata=64):
    """(E(mu), S(mu)): the albedo of :func:`ggx_albedo` and the mean of :func:`fresnel_rise`
    over the reflected light, S = integral f s(wo.m) |cos_i| / E, with the same quadrature.

    S is what Cycles tabulates as ``ggx_gen_schlick_ior_s``: a specular layer of normal
    reflectance f0 reflects E (f0 + (1 - f0) S) of the light arriving along the view.
    """
    w, cos_om = _ggx_reflection_nodes(alpha, mu, strata)
    e = w.mean(axis=1)
    s = (w * fresnel_rise(cos_om, eta)).mean(axis=1) / np.maximum(e, 1e-12)
    return e, s


def dielectric_f0(eta):
    """Reflectance face on, ((eta - 1) / (eta + 1))^2, of a dielectric of relative index ``eta``."""
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def fresnel_rise(cos_i, eta):
    """Cycles' Principled specular Fresnel as a blend factor: saturate((F(cos_i) - F0) / (1 - F0))
    with the real dielectric F of relative index ``eta`` (> 1) and F0 = F(1).  The layer then
    reflects f0 + (1 - f0) s, which is F itself for f0 = F0 (an untinted layer)."""
    eta = np.maximum(np.asarray(eta, np.float64), 1.0 + 1e-6)
    f0 = dielectric_f0(eta)
    f, _ = fresnel_dielectric(np.clip(cos_i, 0.0, 1.0), eta)
    return np.clip((f - f0) / (1.0 - f0), 0.0, 1.0)


def mean_fresnel(ior) -> float:
    """Cosine-weighted hemispherical mean of the unpolarised dielectric Fresnel reflectance
    (Cycles' ``fresnel_dielectric_Fss``), 2 int F(mu) mu dmu, by the midpoint rule."""
    eta = max(float(ior), 1.0 + 1e-4)
    mu = (np.arange(256) + 0.5) / 256
    f, _ = fresnel_dielectric(mu, eta)
    return float(np.mean(2.0 * mu * f))


def ggx_glass_albedo(alpha, mu, eta, strata=64):
    """Directional albedo E(mu) of single-scattering GGX glass of relative index ``eta`` (n on the
    far side over n on the view's; below 1 seen from inside): Fresnel reflection above the
    surface plus refraction below it, each weighing G2 / G1 about visible-normal samples as
    :func:`ggx_albedo` (the midpoint rule on its grid), refraction without a 1 / eta^2 (camera
    paths' convention, Cycles').  ``alpha``, ``eta`` scalars, ``mu`` (k,); (k,) in (0, 1]."""
    mu = np.clip(np.asarray(mu, np.float64), 1e-4, 1.0)
    wo, m, jac = _visible_normal_grid(alpha, mu, strata)
    cos_o = wo[:, 2]
    cos_h = np.clip(dot(wo, m), 0.0, 1.0)
    f, cos_t = fresnel_dielectric(cos_h, eta)
    up = reflect(wo, m)[:, 2]
    down = refract(wo, m, np.full(len(wo), float(eta)), cos_t)[:, 2]
    g1 = ggx_g1(cos_o, alpha)
    reflected = np.where(up > 0, f * ggx_g2(cos_o, np.maximum(up, 1e-12), alpha), 0.0)
    below = np.maximum(-down, 1e-12)
    refracted = np.where((down < 0) & (f < 1.0), (1.0 - f) * ggx_g2(cos_o, below, alpha), 0.0)
    w = (reflected + refracted) / g1
    return (w * jac).reshape(len(mu), -1).mean(axis=1)


def _visible_normal_grid(alpha, mu, strata):
    """The albedo quadratures' nodes: views ``wo`` (k strata^2, 3) at cosines ``mu`` (k,), their
    visible normals ``m`` on a ``strata`` x ``strata`` grid (radial u1 = 1 - (1 - t)^3 at midpoints
    in t, see :func:`ggx_albedo`) and the grid's Jacobian (k strata^2,)."""
    t = (np.arange(strata) + 0.5) / strata
    u1 = np.tile(np.repeat(1.0 - (1.0 - t) ** 3, strata), len(mu))
    jac = np.tile(np.repeat(3.0 * (1.0 - t) ** 2, strata), len(mu))
    u2 = np.tile(np.tile(t, strata), len(mu))
    cos_o = np.repeat(mu, strata * strata)
    wo = np.stack([np.sqrt(1.0 - cos_o * cos_o), np.zeros_like(cos_o), cos_o], axis=1)
    return wo, ggx_sample_visible_normal(wo, alpha, u1, u2), jac


def _ggx_reflection_nodes(alpha, mu, strata):
    """Quadrature of ``ggx_albedo``: weights (k, strata^2) whose row means are E(mu), and the
    cosines wo.m of their microfacet normals."""
    mu = np.clip(np.asarray(mu, np.float64), 1e-4, 1.0)
    wo, m, jac = _visible_normal_grid(alpha, mu, strata)
    cos_o = wo[:, 2]
    wi = reflect(wo, m)
    w = np.where(wi[:, 2] > 0, ggx_g2(cos_o, np.maximum(wi[:, 2], 1e-12), alpha) / ggx_g1(cos_o, alpha), 0.0)
    return (w * jac).reshape(len(mu), -1), dot(wo, m).reshape(len(mu), -1)


def hg_phase(cos_theta, g):
    """Henyey-Greenstein phase function (per steradian) at the cosine between the direction
    light travels in and the one it leaves in; ``g`` > 0 scatters forwards, 0 evenly (1/(4 pi))."""
    g = np.asarray(g, np.float64)
    denom = 1.0 + g * g - 2.0 * g * cos_theta
    return (1.0 - g * g) / (4.0 * np.pi * denom * np.sqrt(np.maximum(denom, 1e-300)))


def sample_hg(d, g, u1, u2):
    """Directions (n, 3) scattered from travel directions ``d`` (n, 3) with the Henyey-Greenstein
    phase function of ``g`` (n,): its density exactly, so the weight is 1."""
    return direction_at(d, hg_cosine(g, u1), u2)


def hg_cosine(g, u):
    """(n,) cosines distributed by the Henyey-Greenstein phase function of ``g`` (n,), from uniform
    numbers ``u`` (n,)."""
    g = np.asarray(g, np.float64)
    small = np.abs(g) < 1e-3
    gs = np.where(small, 0.5, g)
    s = (1.0 - gs * gs) / (1.0 + gs - 2.0 * gs * u)
    return np.where(small, 1.0 - 2.0 * u, (1.0 + gs * gs - s * s) / (2.0 * gs))


def direction_at(d, cos, u):
    """(n, 3) unit directions at cosines ``cos`` (n,) (clipped to [-1, 1]) from the axes ``d`` (n, 3),
    at azimuths 2 pi ``u`` (n,) about them."""
    cos = np.clip(cos, -1.0, 1.0)
    r = np.sqrt(np.maximum(0.0, 1.0 - cos * cos))
    phi = 2.0 * np.pi * np.asarray(u, np.float64)
    local = np.stack([r * np.cos(phi), r * np.sin(phi), cos], axis=1)
    return normalize(to_world(local, d))


def optical_depth(sigma, length):
    """(n, 3) ``sigma`` ``length`` of coefficients (n, 3) >= 0 over lengths (n,), which may be
    infinite (inf where a channel attenuates, 0 where it does not)."""
    return sigma * np.where(sigma > 0, np.asarray(length, np.float64)[:, None], 0.0)


def transmittance(sigma, length):
    """(n, 3) exp(-``sigma`` ``length``) (:func:`optical_depth`)."""
    return np.exp(-optical_depth(sigma, length))


def volume_glow(sigma_t, emission, length):
    """(n, 3) the radiance a volume of extinction ``sigma_t`` (n, 3) that emits ``emission``
    (n, 3) per length sends along a segment of ``length`` (n,) (finite) to its start: the integral
    of ``emission`` T(s) ds, ``emission`` (1 - T(L)) / ``sigma_t`` (``emission`` L where
    ``sigma_t`` is 0, or so small that the difference would lose its digits)."""
    tau = optical_depth(sigma_t, length)
    length = np.asarray(length, np.float64)[:, None]
    small = tau < 1e-6
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(small, length * (1.0 - 0.5 * tau), -np.expm1(-tau) / np.where(small, 1.0, sigma_t))
    return emission * share


def _pick_channel(sigma_t, sigma_s, u, throughput):
    """(probabilities (n, 3), chosen channel (n,), the number rescaled within its choice (n,)):
    channels by ``throughput`` times the albedo (evenly where that is 0)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        albedo = np.where(sigma_t > 0, sigma_s / np.where(sigma_t > 0, sigma_t, 1.0), 0.0)
    w = albedo if throughput is None else np.abs(throughput) * albedo
    total = w.sum(axis=1)
    prob = np.where(total[:, None] > 0, w / np.where(total > 0, total, 1.0)[:, None], 1.0 / 3.0)
    cum = np.cumsum(prob, axis=1)
    c = np.minimum((u[:, None] >= cum[:, :2]).sum(axis=1), 2)
    lo = np.where(c > 0, np.take_along_axis(cum, np.maximum(c - 1, 0)[:, None], axis=1)[:, 0], 0.0)
    pc = np.take_along_axis(prob, c[:, None], axis=1)[:, 0]
    return prob, c, np.clip((u - lo) / np.where(pc > 0, pc, 1.0), 0.0, 1.0 - 2.0 ** -53)


def free_flight(sigma_t, sigma_s, u, length, throughput=None):
    """Distances sampled in homogeneous media of extinction ``sigma_t`` and scattering ``sigma_s``
    (n, 3) along segments of ``length`` (n,) (inf: unbounded): a channel chosen by ``u`` (n,) with
    probabilities proportional to the path's ``throughput`` (n, 3) times the albedo (evenly
    without), then the distance from that channel's exponential; the density is the mixture
    over the channels (Cycles' ``volume_sample_channel``), which keeps the weights bounded along
    a path.

    Returns ``(t, scattered, weight)``: the distance (n,), whether it falls inside the segment
    (n,) bool, and (n, 3) the transmittance over the density: T(t) / p(t) for the scattered
    (without the scattering coefficient) and T(L) / P(t > L) for the rest.
    """
    prob, c, v = _pick_channel(sigma_t, sigma_s, u, throughput)
    sc = np.take_along_axis(sigma_t, c[:, None], axis=1)[:, 0]
    with np.errstate(divide="ignore"):
        t = np.where(sc > 0, -np.log1p(-v) / np.where(sc > 0, sc, 1.0), np.inf)
    scattered = t < length
    at = np.where(scattered, t, length)
    finite = np.isfinite(at)
    tr = np.exp(-sigma_t * np.where(finite, at, 0.0)[:, None])          # (n, 3) T per channel
    tr[~finite] = 0.0
    pdf = (prob * np.where(scattered[:, None], sigma_t * tr, tr)).sum(axis=1)
    weight = np.where(pdf[:, None] > 0, tr / np.where(pdf > 0, pdf, 1.0)[:, None], 0.0)
    return t, scattered, weight


def forced_flight(sigma_t, sigma_s, u, length, throughput=None):
    """A distance inside each segment of ``length`` (n,) of homogeneous media (as
    :func:`free_flight`: the channel by ``throughput`` times the albedo, ``u`` (n,)), drawn from
    that channel's exponential cut at the segment's end, so that every segment gets a point.

    Returns ``(t, weight, transmittance)``: the distance (n,), T(t) / p(t) (n, 3) with p the
    mixture of the cut densities (estimates int_0^L T(t) f(t) dt as weight f(t)), and T(L)
    (n, 3), what goes on to the segment's end.
    """
    prob, c, v = _pick_channel(sigma_t, sigma_s, u, throughput)
    tau = optical_depth(sigma_t, length)
    reach = -np.expm1(-tau)                                            # (n, 3) 1 - T(L)
    sc = np.take_along_axis(sigma_t, c[:, None], axis=1)[:, 0]
    rc = np.take_along_axis(reach, c[:, None], axis=1)[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(sc > 0, -np.log1p(-v * rc) / np.where(sc > 0, sc, 1.0), v * length)
    tr = np.exp(-sigma_t * t[:, None])
    # Each channel's cut density (uniform over the segment where its extinction is 0; the camera's
    # segments into the world's unbounded volume come cut to RenderContext's FAR_EXTENTS).
    with np.errstate(divide="ignore", invalid="ignore"):
        dens = np.where(reach > 0, sigma_t * tr / np.where(reach > 0, reach, 1.0), 1.0 / length[:, None])
    pdf = (prob * dens).sum(axis=1)
    weight = np.where(pdf[:, None] > 0, tr / np.where(pdf > 0, pdf, 1.0)[:, None], 0.0)
    return t, weight, np.exp(-tau)

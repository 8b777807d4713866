"""Subsurface scattering: Cycles' random walks beneath a surface, for camera paths and photons.

Cycles' BSSRDF (the Random Walk methods of Blender's Principled BSDF and Subsurface Scattering
BSDF) sends a path that picks it into the surface, walks it through a homogeneous medium inside
the object until it meets the object's surface again, and lights the exit as a white diffuse
surface.  Here the eye pass does the same (:func:`random_walk`): a measurement point on such a
surface becomes, with the subsurface part's share, a point at the exit of a walk, which gathers
photons by a Lambertian lobe (``eye_pass._beneath``).  Cycles 5.0 walks on paths from any surface
(only Christensen-Burley falls back to diffuse after a diffuse bounce), so photons walk too
(``photon_pass._beneath``): light that enters one point leaves at another and goes on, its numbers
hashed from the photon's primary sample.

The medium (Chiang, Kutz and Burley 2016, "Practical and Controllable Subsurface Scattering for
Production Path Tracing"; anisotropy from Wrenninge, Villemin and Hery 2017, "Path Traced
Subsurface Scattering using Anisotropic Phase Functions and Non-Exponential Free Flights"): per
channel, the single-scattering albedo whose multiple scattering gives the surface's colour,
an extinction of 1 / (d (1 - g)) for a mean free path d, and Henyey-Greenstein scattering of
anisotropy g.  Distances are sampled by a channel picked in proportion to albedo times
throughput, with the balance heuristic over the channels, so each channel's estimate is that of
its own medium.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .accel import Hits
from .sampling import (cosine_hemisphere, dot, ggx_d, ggx_g1, ggx_sample_visible_normal, hg_phase, normalize,
                       orthonormal_frames, sample_hg, splitmix64, to_local, to_world)
from .scene import SUBSURFACE_SKIN

MAX_STEPS = 256                   # Cycles' BSSRDF_MAX_BOUNCES: a walk that has not left is lost
SIMILARITY_STEP = 9               # after this many steps, isotropic with the similar coefficients
MIN_ALPHA = 0.2                   # single-scattering albedos are kept above, the throughput scaled
THROUGHPUT_EPSILON = 1e-6         # a walk whose throughput falls below stops (Cycles' volumes')
MIN_RADIUS = 1e-8                 # channels of a smaller radius stay diffuse (Cycles)
SKIN_DIFFUSE_ENTRY = 0.5          # Random Walk (Skin): the share of entries that are diffuse
WALK_NUMBERS = 6                  # uniform numbers a step takes


def single_scattering_albedo(albedo, g):
    """(..., 3) the single-scattering albedo whose medium's multiple scattering reflects
    ``albedo`` (the fit of Wrenninge et al. to anisotropy ``g`` (...,), which Cycles uses), in
    [0, 0.999999]."""
    g = np.asarray(g, np.float64)[..., None]
    powers = [g ** k for k in range(8)]

    def poly(c):
        return sum(ck * pk for ck, pk in zip(c, powers))
    a = poly((1.8260523782, -1.28451056436, -1.79904629312, 9.19393289202, -22.8215585862, 32.0234874259,
              -23.6264803333, 7.21067002658))
    b = 4.98511194385 + 0.127355959438 * np.exp(poly((0.0, 31.1491581433, -201.847017512, 841.576016723,
                                                      -2018.09288505, 2731.71560286, -1935.41424244,
                                                      559.009054474)))
    c = poly((1.09686102424, -0.394704063468, 1.05258115941, -8.83963712726, 28.8643230661, -46.8802913581,
              38.5402837518, -12.7181042538))
    d = poly((0.496310210422, 0.360146581622, -2.15139309747, 17.8896899217, -55.2984010333, 82.065982243,
              -58.5106008578, 15.8478295021))
    e = 4.23190299701 + 0.00310603949088 * np.exp(poly((0.0, 76.7316253952, -594.356773233, 2448.8834203,
                                                        -5576.68528998, 7116.60171912, -4763.54467887,
                                                        1303.5318055)))
    f = poly((2.40602999408, -2.51814844609, 9.18494908356, -79.2191708682, 259.082868209, -403.613804597,
              302.85712436, -87.4370473567))
    albedo = np.asarray(albedo, np.float64)
    blend = albedo ** 0.25
    alpha = (1.0 - blend) * a * np.arctan(b * albedo) ** c + blend * d * np.arctan(e * albedo) ** f
    return np.clip(alpha, 0.0, 0.999999)


def skin_radius(radius, albedo, ior):
    """(k, 3) Random Walk (Skin)'s mean free paths: ``radius`` times sqrt(3 (1 - a')), a' the
    reduced albedo whose dipole (Jensen et al. 2001, with the boundary of ``ior`` (k,)) reflects
    ``albedo`` (bisection, as Cycles)."""
    inv = 1.0 / np.asarray(ior, np.float64)
    f_dr = inv * (-1.440 * inv + 0.710) + 0.668 + 0.0636 * np.asarray(ior, np.float64)
    four_thirds_a = ((4.0 / 3.0) * (1.0 + f_dr) / (1.0 - f_dr))[:, None]

    def reflectance(a):
        s = np.sqrt(3.0 * (1.0 - a))
        return 0.5 * a * (1.0 + np.exp(-four_thirds_a * s)) * np.exp(-s)
    albedo = np.asarray(albedo, np.float64)
    lo, hi = np.zeros_like(albedo), np.ones_like(albedo)
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        below = reflectance(mid) < albedo
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    a = np.where(albedo < 1e-4, 0.0, np.where(albedo >= 0.995, 0.999999, 0.5 * (lo + hi)))
    return np.asarray(radius, np.float64) * np.sqrt(3.0 * (1.0 - a))


def medium(albedo, radius, g, method, ior):
    """(sigma_t, alpha, scale) (k, 3) of walks of surfaces of colour ``albedo`` (clamped to [0, 1])
    and radii ``radius`` (k, 3), anisotropy ``g``, ``method`` (SUBSURFACE_*) and ``ior`` (k,): the
    extinction, the single-scattering albedo (at least MIN_ALPHA) and the throughput's factor for
    that floor."""
    albedo = np.clip(np.asarray(albedo, np.float64), 0.0, 1.0)
    radius = np.asarray(radius, np.float64)
    skin = np.asarray(method) == SUBSURFACE_SKIN
    d = np.where(skin[:, None], skin_radius(radius, albedo, ior), radius * (0.25 / np.pi))
    g = np.asarray(g, np.float64)
    sigma_t = 1.0 / (np.maximum(d, 1e-16) * (1.0 - g)[:, None])
    alpha = single_scattering_albedo(albedo, g)
    scale = np.where(alpha < MIN_ALPHA, alpha / MIN_ALPHA, 1.0)
    return sigma_t, np.maximum(alpha, MIN_ALPHA), scale


def entry(mats, rows):
    """(alpha, ior, diffuse_share), each (k,), of the entry of materials ``rows`` (``scene.Materials``)
    into their surface, as Cycles': Random Walk refracts at a GGX microfacet of ``subsurface_alpha``
    and ``subsurface_ior``; Skin enters diffusely with SKIN_DIFFUSE_ENTRY, else at alpha 1 (the
    arguments of :func:`entry_directions` and :func:`exit_directions`)."""
    skin = np.asarray(mats.subsurface_method).take(rows) == SUBSURFACE_SKIN
    return (np.where(skin, 1.0, np.asarray(mats.subsurface_alpha, np.float64).take(rows)),
            np.asarray(mats.subsurface_ior, np.float64).take(rows), np.where(skin, SKIN_DIFFUSE_ENTRY, 0.0))


def entry_directions(n, ng, wo, alpha, ior, diffuse_share, u):
    """(k, 3) directions into the surface at points of (shading) normal ``n`` and geometric normal
    ``ng`` (both on the side of ``wo``, the direction back along the camera ray) and (k,) whether
    each is valid (it goes below ``ng``): with probability ``diffuse_share`` cosine-distributed
    about -n, else the view refracted at a GGX microfacet of ``alpha`` (a visible normal, without
    a weight: Cycles keeps only the direction) and the relative index ``ior``.  ``u`` (k, 3)."""
    out = np.empty((len(n), 3))
    diffuse = u[:, 0] < diffuse_share
    rows = np.flatnonzero(diffuse)
    if len(rows):
        # (one number picks and samples: rescaled)
        local = cosine_hemisphere(u[rows, 0] / diffuse_share.take(rows), u[rows, 1])
        out[rows] = to_world(local, -n.take(rows, axis=0))
    rows = np.flatnonzero(~diffuse)
    valid = np.ones(len(n), bool)
    if len(rows):
        share = diffuse_share.take(rows)
        u0 = np.clip((u[rows, 0] - share) / np.maximum(1.0 - share, 1e-12), 0.0, 1.0 - 1e-12)
        nf, w = n.take(rows, axis=0), wo.take(rows, axis=0)
        w_local = to_local(w, nf)
        valid[rows] = w_local[:, 2] > 0.0
        w_local[:, 2] = np.maximum(w_local[:, 2], 1e-7)
        h = ggx_sample_visible_normal(w_local, np.maximum(alpha.take(rows), 1e-7), u0, u[rows, 1])
        h = to_world(h, nf)
        cos_hi = dot(h, w)
        neta = 1.0 / ior.take(rows)
        root = np.sqrt(np.maximum(1.0 - neta ** 2 * (1.0 - cos_hi ** 2), 0.0))
        out[rows] = normalize(-neta[:, None] * w + (neta * cos_hi - np.maximum(root, 1e-7))[:, None] * h)
    return out, valid & (dot(out, ng) < 0.0)


def exit_directions(n, ng, d, alpha, ior, diffuse_share, u):
    """(k, 3) directions in which photons whose walks reached the surface along ``d`` (k, 3, going
    out) leave it, and (k,) their weights, 0 where they do not leave: the adjoint of
    :func:`entry_directions` (``n``, ``ng`` outward; ``alpha``, ``ior``, ``diffuse_share`` as
    there; ``u`` (k, 3)).

    A camera path seen from w enters along d_in with the density p(d_in | w) and weight 1, so a
    photon that reaches the surface along d = -d_in leaves towards w with the weight
    p(-d | w) cos(w) / (|cos(d)| q(w)) for w drawn with the density q: by cosine with
    ``diffuse_share`` (the diffuse entries'), else refracted out at a GGX microfacet visible from
    inside (lost where that reflects totally), both weighted by the balance heuristic.  Without
    diffuse entries the weight is eta^2 G1(w) / G1(d) (Cycles' entry does not scale the light by
    1 / eta^2, as its camera paths through glass do not).  Light that reaches the surface evenly
    (deep in a large object) leaves with its flux on average, as it would by cosine; light that
    comes through a thin slab mostly straight leaves more of it, towards the directions the
    entry's refraction reaches from (``tests/core/test_subsurface.py``)."""
    k = len(n)
    share = np.asarray(diffuse_share, np.float64)
    eta = np.asarray(ior, np.float64)
    alpha = np.maximum(np.asarray(alpha, np.float64), 1e-7)
    inner = -n
    v = -np.asarray(d, np.float64)                              # d_in: into the surface
    out = np.empty((k, 3))
    diffuse = u[:, 0] < share
    rows = np.flatnonzero(diffuse)
    if len(rows):
        out[rows] = to_world(cosine_hemisphere(u[rows, 1], u[rows, 2]), n.take(rows, axis=0))
    rows = np.flatnonzero(~diffuse)
    if len(rows):
        inner_r, v_r, eta_r = inner.take(rows, axis=0), v.take(rows, axis=0), eta.take(rows)
        v_local = to_local(v_r, inner_r)
        v_local[:, 2] = np.maximum(v_local[:, 2], 1e-7)
        h = to_world(ggx_sample_visible_normal(v_local, alpha.take(rows), u[rows, 1], u[rows, 2]), inner_r)
        cos_vh = dot(v_r, h)
        root = 1.0 - eta_r ** 2 * (1.0 - cos_vh ** 2)
        # (total internal reflection at the microfacet: a direction into the surface, lost below)
        refracted = -eta_r[:, None] * v_r + (eta_r * cos_vh - np.sqrt(np.maximum(root, 0.0)))[:, None] * h
        out[rows] = np.where((root > 0.0)[:, None], refracted, inner_r)
    out = normalize(out)
    cos_w, cos_v = dot(out, n), -dot(v, n)
    # The refraction's half vector (on the outer side), by which both densities go.
    h = -(out + eta[:, None] * v)
    h = normalize(h * np.where(dot(h, n) < 0.0, -1.0, 1.0)[:, None])
    w_h, v_h = dot(out, h), dot(v, h)
    ok = (cos_w > 0.0) & (cos_v > 0.0) & (w_h > 0.0) & (v_h < 0.0)
    cw, cv = np.maximum(cos_w, 1e-12), np.maximum(cos_v, 1e-12)
    # Both densities (visible normals, then Walter et al. 2007's refraction Jacobian) share
    # D(h) |w.h d.h| / (w.h + eta d.h)^2.
    shared = np.where(ok, ggx_d(dot(h, n), alpha) * np.abs(w_h * v_h)
                      / np.maximum((w_h + eta * v_h) ** 2, 1e-300), 0.0)
    p = share * cv / np.pi + (1.0 - share) * eta ** 2 * ggx_g1(cw, alpha) / cw * shared
    q = share * cw / np.pi + (1.0 - share) * ggx_g1(cv, alpha) / cv * shared
    weight = np.where((cos_w > 0.0) & (q > 0.0), p * cw / (cv * np.maximum(q, 1e-300)), 0.0)
    return out, weight


def diffusion_length(alpha):
    """(k,) the Dwivedi guiding's diffusion length at single-scattering albedos ``alpha`` (k,) (their
    channels' largest, as Cycles: d'Eon and Krivanek 2020, eq. 67), above 1."""
    a = np.asarray(alpha, np.float64)
    return 1.0 / np.sqrt(np.maximum(1.0 - a ** (2.44294 - 0.0215813 * a + 0.578637 / a), 1e-300))


def hashed_uniforms(seeds, step):
    """(k, WALK_NUMBERS) uniform numbers in [0, 1) of walks of uint64 ``seeds`` (k,) at ``step``:
    SplitMix64's finaliser of the seed and the number's counter (a function of the seed alone, so a
    photon's walk stays a function of its primary sample; one array pass for all six numbers)."""
    counter = np.uint64(step * WALK_NUMBERS) + np.arange(WALK_NUMBERS, dtype=np.uint64)
    z = splitmix64(seeds[:, None] * np.uint64(0x9E3779B97F4A7C15) + counter * np.uint64(0xD1B54A32D192ED03))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0 ** -53


def random_walk(intersect, origins, dirs, normals, sigma_t, alpha, g, throughput, uniforms, guide=True):
    """Walk k paths from ``origins`` (k, 3) on the surface, of (outward) normals ``normals``, along
    ``dirs`` (k, 3) through media of extinction ``sigma_t`` (k, 3), single-scattering albedo
    ``alpha`` (k, 3) and anisotropy ``g`` (k,), each until it meets the surface again;
    ``intersect(rows, origins, dirs, tmax)`` gives the :class:`~core.accel.Hits` of walks ``rows``
    (their own object's surface alone); ``uniforms(rows, step)`` the (len(rows), WALK_NUMBERS)
    numbers of walks ``rows`` at that step.

    Each step after the first samples its direction by the phase function or, with Cycles' share,
    by Dwivedi's guiding towards the surface (Meng, Hanika and Dachsbacher 2016), or towards the
    opposite one that the first step's ray found, and its distance with the guide's stretched
    extinction; the balance heuristic over the strategies and channels keeps each channel's
    estimate that of its medium.  Those still inside after MAX_STEPS are lost, as in Cycles
    (guided, more walks leave within them, 94 % against 90 % in a deep box at albedo 0.999, with
    the same light: the long walks weigh little).  ``guide`` False: the phase function alone.

    The loop's cost is its steps, nearly all of them over the few long walks (up to MAX_STEPS
    ray casts one after another), so a step is few array operations: the walks' state and
    constants are the columns of one array (one gather keeps those still inside), and the
    isotropic steps (after SIMILARITY_STEP) sample both strategies in the normal's frame, made
    once per walk.

    Returns (rows, hits, dirs, throughput): the walks that left (indices into the k), where
    (their Hits), along which directions, and with what throughput (``throughput`` (k, 3) times
    each channel's estimate)."""
    k = len(origins)
    sigma_t = np.asarray(sigma_t, np.float64)
    alpha = np.asarray(alpha, np.float64)
    sigma_s = sigma_t * alpha
    g = np.broadcast_to(np.asarray(g, np.float64), (k,))
    n = np.asarray(normals, np.float64)
    tangent, bitangent = orthonormal_frames(n)
    # Similarity after SIMILARITY_STEP steps: isotropic, with the scattering reduced by 1 - g.
    sigma_s_star = sigma_s * (1.0 - g)[:, None]
    v = diffusion_length(alpha.max(axis=1))
    share = 1.0 - np.maximum(0.5, np.abs(g) ** 0.125)          # Cycles' share of guided steps
    s = np.empty((k, _COLUMNS))
    for name, value in (("pos", origins), ("d", dirs), ("beta", throughput), ("st", sigma_t), ("ss", sigma_s),
                        ("st_star", sigma_t - sigma_s + sigma_s_star), ("ss_star", sigma_s_star),
                        ("alpha", alpha), ("tangent", tangent), ("bitangent", bitangent), ("n", n),
                        ("start_n", dot(np.asarray(origins, np.float64), n)), ("v", v),
                        ("log", np.log((v + 1.0) / (v - 1.0))), ("share", share if guide else 0.0), ("g", g),
                        ("has_opp", 0.0), ("opp", 0.0)):
        s[:, _COL[name]] = value
    rows = np.arange(k)
    # Distance densities by the phase function's extinction and the guide's two stretched ones.
    strategies = np.array([0.0, -1.0, 1.0])
    out_rows, out_hits, out_dirs, out_beta = [], [], [], []
    for step in range(MAX_STEPS):
        if len(rows) == 0:
            break
        similar = step > SIMILARITY_STEP
        pos, d, beta = s[:, _COL["pos"]], s[:, _COL["d"]], s[:, _COL["beta"]]
        st = s[:, _COL["st_star"] if similar else _COL["st"]]
        ss = s[:, _COL["ss_star"] if similar else _COL["ss"]]
        m = len(rows)
        u = uniforms(rows, step)
        # The channel by albedo times throughput (the last where those are all 0: such a walk
        # carries nothing and stops after this step).
        w = s[:, _COL["alpha"]] * np.abs(beta)
        c = np.cumsum(w, axis=1)
        total = c[:, 2:]
        channel = (u[:, :1] * total >= c[:, :2]).sum(axis=1)
        sample_st = st[np.arange(m), channel]
        if step:
            vr, logr, nr = s[:, _COL["v"]], s[:, _COL["log"]], s[:, _COL["n"]]
            gf = (0.75 if guide else 0.0) if similar else s[:, _COL["share"]]
            opp = s[:, _COL["opp"]]
            depth = np.clip(s[:, _COL["start_n"]] - dot(pos, nr), 0.0, opp)
            # (Cycles' chance of guiding towards the opposite side, by the depth reached)
            back_share = s[:, _COL["has_opp"]] / (1.0 + np.exp(np.minimum((opp - 2.0 * depth) / vr, 700.0)))
            guided = u[:, 2] < gf
            backward = guided & (u[:, 3] < back_share)
            cos = vr - (vr + 1.0) * np.exp(-u[:, 4] * logr)
            cos = np.clip(np.where(backward, -cos, cos), -1.0, 1.0)
            if similar:
                # Isotropic: the phase function's directions too in the normal's frame.
                cos = np.where(guided, cos, 1.0 - 2.0 * u[:, 4])
                hg = 1.0 / (4.0 * np.pi)
            sin = np.sqrt(np.maximum(1.0 - cos * cos, 0.0))
            phi = 2.0 * np.pi * u[:, 5]
            local = np.stack([sin * np.cos(phi), sin * np.sin(phi), cos], axis=1)
            new_d = np.einsum("ij,ijk->ik", local, s[:, _COL["frame"]].reshape(m, 3, 3))
            if not similar:
                gg = s[:, _COL["g"]]
                new_d = np.where(guided[:, None], new_d, sample_hg(d, gg, u[:, 4], u[:, 5]))
                hg = hg_phase(dot(d, new_d), gg)
                cos = dot(new_d, nr)
            # (stretches: 1, forwards and backwards)
            stretches = 1.0 + np.multiply.outer(cos / vr, strategies)
            stretch = np.where(backward, stretches[:, 2], np.where(guided, stretches[:, 1], 1.0))
            sample_st = sample_st * stretch
            d = new_d
        t = -np.log1p(-u[:, 1]) / sample_st
        reach = t if step else np.maximum(t, 10.0 / st.min(axis=1))    # (looks for the opposite side)
        hits = intersect(rows, pos, d, reach)
        found = hits.is_hit
        hit_t = hits.t.astype(np.float64)
        if not step:
            f = np.flatnonzero(found)
            s[f, _COL["opp"]] = s[f, _COL["start_n"]] - dot(pos[f] + hit_t[f, None] * d[f], s[f, _COL["n"]])
            s[f, _COL["has_opp"]] = 1.0
            found = found & (hit_t < t)
        t = np.where(found, hit_t, t)
        if step:
            sigma = stretches[:, :, None] * st[:, None, :]
            tr = np.exp(-sigma * t[:, None, None])
            pdf = np.where(found[:, None, None], tr, sigma * tr)
            scale = 1.0 / (2.0 * np.pi * logr * hg)
            guided_p = (pdf[:, 1] * ((1.0 - back_share) * scale / (vr - cos))[:, None]
                        + pdf[:, 2] * (back_share * scale / (vr + cos))[:, None])
            p = pdf[:, 0] + (guided_p - pdf[:, 0]) * (gf[:, None] if np.ndim(gf) else gf)
            tr = tr[:, 0]
        else:
            tr = np.exp(-st * t[:, None])
            p = np.where(found[:, None], tr, st * tr)
        # (the balance heuristic's sum over the channels, with their probabilities w / total)
        beta = beta * tr * np.where(found[:, None], 1.0, ss) * (
            total / np.maximum((w * p).sum(axis=1, keepdims=True), 1e-300))
        left = np.flatnonzero(found)
        if len(left):
            out_rows.append(rows.take(left))
            out_hits.append(_take_hits(hits, left))
            out_dirs.append(d.take(left, axis=0))
            out_beta.append(beta.take(left, axis=0))
        stay = np.flatnonzero(~found & (beta.max(axis=1) >= THROUGHPUT_EPSILON))
        s[:, _COL["pos"]] = pos + t[:, None] * d
        s[:, _COL["d"]], s[:, _COL["beta"]] = d, beta
        s, rows = s.take(stay, axis=0), rows.take(stay)
    if not out_rows:
        z = np.zeros(0)
        none = Hits(np.zeros(0, bool), np.zeros(0, np.int32), np.zeros(0, np.float32), z, z)
        return np.zeros(0, np.int64), none, np.zeros((0, 3)), np.zeros((0, 3))
    return (np.concatenate(out_rows), _concat_hits(out_hits), np.concatenate(out_dirs),
            np.concatenate(out_beta))


def _column_slices(widths):
    """{name: slice} of consecutive columns of the given widths (1: a single column)."""
    cols, at = {}, 0
    for name, width in widths:
        cols[name] = at if width == 1 else slice(at, at + width)
        at += width
    return cols, at


# A walk's state and constants, the columns of one (k, _COLUMNS) array.
_COL, _COLUMNS = _column_slices([("pos", 3), ("d", 3), ("beta", 3), ("st", 3), ("ss", 3), ("st_star", 3),
                                 ("ss_star", 3), ("alpha", 3), ("frame", 9), ("start_n", 1), ("v", 1),
                                 ("log", 1), ("share", 1), ("g", 1), ("has_opp", 1), ("opp", 1)])
_COL.update({name: slice(_COL["frame"].start + 3 * i, _COL["frame"].start + 3 * i + 3)
             for i, name in enumerate(("tangent", "bitangent", "n"))})


def _take_hits(hits, rows):
    return Hits(hits.is_hit.take(rows), hits.prim_ids.take(rows), hits.t.take(rows), hits.b1.take(rows),
                hits.b2.take(rows))


def _concat_hits(parts):
    return Hits(*(np.concatenate([getattr(p, f) for p in parts])
                  for f in ("is_hit", "prim_ids", "t", "b1", "b2")))


def exit_variant(mats):
    """(materials, row): ``mats`` (``scene.Materials``) followed by the surface at the exits of
    walks (a white Lambertian lobe alone, Cycles' diffuse BSDF there) and its row, when some of
    them scatter beneath their surface; else (``mats``, -1)."""
    if not (np.asarray(mats.subsurface_weight) > 0).any():
        return mats, -1
    rows = np.concatenate([np.arange(mats.count), [0]])
    changes = {name: np.ascontiguousarray(getattr(mats, name)[rows]) for name in mats.ARRAY_FIELDS}
    for name in mats.ARRAY_FIELDS:
        if name in mats.INDEX_FIELDS or name in ("glossy_metal_tint", "level_first"):
            changes[name][-1] = -1
        elif name not in ("ior", "glossy_roughness", "glossy_tangent", "normal_space", "film_ior",
                          "subsurface_ior"):
            changes[name][-1] = 0
    for name in ("diffuse_weight", "diffuse_color", "opacity", "normal_strength", "bump_strength",
                 "bump_distance", "outer_bump_strength", "outer_bump_distance", "coat_bump_strength",
                 "coat_bump_distance", "diffuse_layer_weight", "glossy_stretch", "glossy_metal_share",
                 "bump_correction", "dielectric_fresnel", "transparent_color", "film_tint",
                 "subsurface_radius", "subsurface_alpha"):
        changes[name][-1] = 1
    return dataclasses.replace(mats, names=list(mats.names) + ["subsurface exit"], **changes), mats.count

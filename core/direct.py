"""Direct light by light samples at the measurement points (``RenderSettings.direct_light``).

A photon deposits at every non-delta vertex, the first included, so by default the light that
reaches a surface straight from an emitter comes from photons too: the plain method of the paper,
and the blotchy look of a photon map where most of the light is direct (the Cornell box:
``benchmarks/versus_cycles.py``).  With ``direct_light="sampled"`` each pass's measurement points
get that light from ``direct_samples`` light samples each instead: an emitter chosen by power among
those :meth:`~core.lights.LightSampler.direct_entries` names (where the scene has several lamps,
these by their power over the squared distance in part: :func:`lamp_choice`), a point on it or a
direction (:meth:`~core.lights.LightSampler.sample_direct`; the world's mostly through its light
portals where the scene has them), a shadow ray, and the point's BSDF through the pair weights a
photon arriving along the same direction would get
(:meth:`~core.photon_pass.DepositTarget.pair_weights`, with the landing facet the point's own). The
photon pass then leaves out the deposits at the first vertex of the photons of those emitters
(``DepositTarget.direct``), and nothing else: light through glass or off a mirror (a caustic, a
room lit through a glass roof) still comes from photons, as does the light of emitters left out. So
the two estimate disjoint parts of the light and their sum is the same image, without the photons'
kernel bias in the direct part; the light samples are averaged over passes with the emission the
camera sees (``EyePassResult.emission``), and with ``pixel_jitter="stratified"`` a pixel's samples,
pass after pass, fill the light's strata evenly (:func:`stratified_light`).  The Markov chains then
seek paths that matter beyond their first vertex, as a path visible only there is no longer
visible.  Points whose glossy lobe is sharper than ``MIN_GLOSSY_ALPHA`` take no samples and keep
their photons' direct light (``DepositTarget.direct_points``: the photon pass then leaves out the
first-vertex pairs of the others alone, and a first vertex in the chains' visible cells still
counts).

Scenes with what the light samples do not model keep the photons' direct light
(:func:`sampled_emitters`; ``RenderResult.direct_light`` says why): volumes, shadow catchers,
subsurface scattering, light and shadow linking, emitters that leave out some rays, and a
Transparent bounces limit the camera paths count against.  Cycles' light passes and light group
passes take the samples' parts as they would take the photons' first vertices
(:func:`sample_direct`).

Measured (``benchmarks/versus_cycles.py --methods ours ours-sampled``, 160 x 120, 60 s, 2 seeds,
stop 58): a long lens on a corner of a sunlit town (``small_view``) 2.6 times lower error against
either reference (4 to 7 times without the 0.1 % worst pixels), where few of the sun's photons
land on what the camera sees; the Cornell box, the glass-roofed room and a caustic seen through
glass and in a mirror within 6 % of the photons' (the light there is indirect or through glass,
or its photons are plenty).  Off by default (README, "Direct light from light samples": sharp
glossy lobes, hair tubes).
"""
from __future__ import annotations

import numpy as np

from . import sampling as smp
from .light_passes import VIA_GLOSSY, VIA_NONE, VIA_TRANSMISSION
from .lights import _spot_mask
from .sampling import dot
from .scene import AREA_DISK, AREA_RECT, POINT, SPOT


def sampled_emitters(ctx, limits=None):
    """(mask, reason): the emitters (``LightSampler`` entries, (count,) bool) whose direct light
    the measurement points sample, or (None, why not) where the scene calls for something the
    light samples do not model (module docstring).  ``limits``: the render's
    :class:`~core.settings.BounceLimits`."""
    lights = ctx.lights
    reasons = (("volumes", ctx.has_volumes), ("shadow catchers", ctx.catcher is not None),
               ("subsurface scattering", ctx.subsurface_exit >= 0),
               ("light or shadow linking", lights.has_links or lights.has_shadow_links
                or ctx.receiver_sets is not None or ctx.blocker_sets is not None),
               ("emitters that leave out some rays", lights.has_exclusion),
               ("a Transparent bounces limit", limits is not None and limits.counts_crossings
                and ctx.has_transparency))
    for why, on in reasons:
        if on:
            return None, why
    mask = lights.direct_entries() if lights.count else np.zeros(0, bool)
    if not mask.any():
        return None, "no emitter whose light it samples"
    return mask, ""


# Light samples taken at once (bounds the memory at large images and many samples per point).
CHUNK = 1 << 18
# Points whose glossy lobe is sharper than this (GGX alpha, roughness squared: roughness 0.5) keep
# their photons' direct light: light samples drawn by the light alone seldom meet such a lobe, and
# their estimate is heavy-tailed.  A grey GGX floor under a constant sky seen 70 degrees off its
# normal (16 pixels, 6 passes, 6 seeds; the photons 60,000 a pass): the spread of the image mean
# over seeds 1.6 / 0.52 / 0.18 / 0.079 / 0.021 with light samples against 0.55 / 0.30 / 0.13 /
# 0.066 / 0.029 with photons at roughness 0.2 / 0.3 / 0.4 / 0.5 / 0.7.
MIN_GLOSSY_ALPHA = 0.25


# The emitter's choice at a point (lamp_choice): with several lamps (point, spot and area lights)
# the lamps' share of the samples goes to each by its power over its squared distance (times its
# spot cone, the side an area light faces) in this share, by its power alone in the rest (which
# keeps every lamp's chance above zero where the estimate misjudges: a lamp behind a wall).  Up to
# MAX_LAMPS lamps (sample_direct takes the samples of at most LAMP_TABLE / lamps points at once, for
# the table of their chances); more keep the choice by power.
NEAR_SHARE = 0.75
MAX_LAMPS = 64
LAMP_TABLE = 1 << 21


def lamp_choice(lights, prob, cdf):
    """(choose, the most points it takes at once or None): ``choose`` a function of (u (k,) in [0,
    1), points x (m, 3), the point of each sample rows (k,)) -> (the emitters (k,) of ``lights``'
    entries, their chances (k,) at those points): by ``prob`` (cumulated ``cdf``), or, where two to
    ``MAX_LAMPS`` lamps have a chance, the lamps' share of ``u`` split among them by how much of
    their light could reach each point (``NEAR_SHARE``; the others keep ``prob``).  Either way
    the chances of a point sum to 1 and every emitter of ``prob`` keeps one above zero, so the
    light samples' mean stays the direct light; with lamps near some points and far from others
    (a street of lamps, a room of bulbs) each point samples the ones that light it."""
    lamps = np.flatnonzero(np.isin(lights.kinds, (POINT, SPOT, AREA_RECT, AREA_DISK)) & (prob > 0))

    def by_power(u, x, rows):
        entry = np.minimum(np.searchsorted(cdf, u, side="right"), len(prob) - 1)
        return entry, prob.take(entry)
    if not 2 <= len(lamps) <= MAX_LAMPS:
        return by_power, None
    share = prob.take(lamps)
    others = np.setdiff1d(np.flatnonzero(prob > 0), lamps)
    rest_total = float(prob.take(others).sum())
    lamp_total = 1.0 - rest_total
    rest_cdf = np.cumsum(prob.take(others)) / rest_total if len(others) else None
    if rest_cdf is not None:
        rest_cdf[-1] = 1.0
    L = lights.lights
    ids = lights.ids.take(lamps)
    kinds = L.kind.take(ids)
    centre = L.position.take(ids, axis=0).astype(np.float64)
    axis = lights.axes.take(ids, axis=0)
    area = np.isin(kinds, (AREA_RECT, AREA_DISK))
    # (no closer than the lamp's size: a point on a lamp's sphere or by its panel)
    span = np.linalg.norm(np.cross(L.axis_u.take(ids, axis=0), L.axis_v.take(ids, axis=0)), axis=1)
    near2 = np.maximum(np.where(area, 4.0 * span / np.pi, L.radius.take(ids).astype(np.float64) ** 2), 1e-12)
    spot = kinds == SPOT
    cos_half = np.cos(0.5 * L.spot_angle.take(ids).astype(np.float64))
    blend = L.spot_blend.take(ids).astype(np.float64)
    by_share = share / lamp_total

    def near(x):
        """(k, lamps) chances within the lamps at points x (k, 3), each row summing to 1."""
        to = [x[:, c:c + 1] - centre[:, c] for c in range(3)]              # (k, lamps) each: lamp to point
        d2 = to[0] * to[0] + to[1] * to[1] + to[2] * to[2]
        w = share / np.maximum(d2, near2)
        if area.any() or spot.any():
            along = to[0] * axis[:, 0] + to[1] * axis[:, 1] + to[2] * axis[:, 2]
            cos = along / np.sqrt(np.maximum(d2, 1e-300))
            w = np.where(area & (cos <= 0), 0.0, w)
            if spot.any():
                w = np.where(spot, w * _spot_mask(cos, cos_half, blend), w)
        total = w.sum(axis=1, keepdims=True)
        w = np.where(total > 0, w / np.where(total > 0, total, 1.0), by_share)
        return (1.0 - NEAR_SHARE) * by_share + NEAR_SHARE * w

    def choose(u, x, rows):
        entry = np.zeros(len(u), np.int64)
        p = np.zeros(len(u))
        # (the first lamp_total of the unit interval chooses a lamp, the rest another emitter)
        on_lamp = (u < lamp_total) | (rest_cdf is None)
        other = np.flatnonzero(~on_lamp)
        if len(other):
            v = (u.take(other) - lamp_total) / rest_total
            k = np.minimum(np.searchsorted(rest_cdf, v, side="right"), len(others) - 1)
            entry[other] = others.take(k)
            p[other] = prob.take(entry[other])
        r = np.flatnonzero(on_lamp)
        if len(r):
            chance = near(x)                                     # (the points' own, each sample's by rows)
            at = rows.take(r)
            v = np.minimum(u.take(r) / lamp_total, 1.0)
            below = np.cumsum(chance, axis=1).take(at, axis=0) <= v[:, None]
            j = np.minimum(below.sum(axis=1), len(lamps) - 1)
            entry[r] = lamps.take(j)
            p[r] = lamp_total * chance[at, j]
        return entry, p
    return choose, max(LAMP_TABLE // len(lamps), 1)


def sampled_points(table, points):
    """(m,) bool: the surface ``points`` (:class:`~core.eye_pass.MeasurementPoints`) that take
    light samples (no glossy lobe, or one at least ``MIN_GLOSSY_ALPHA`` rough), or None: all."""
    mats = points.mat_ids
    alpha = table.alpha.take(mats)
    if table.has_anisotropy:            # (the sharper axis; alpha_x = alpha_y = alpha where isotropic)
        alpha = np.minimum(table.alpha_x.take(mats), table.alpha_y.take(mats))
    sharp = table.has_glossy.take(mats) & (alpha < MIN_GLOSSY_ALPHA)
    return ~sharp if sharp.any() else None


def stratified_light(salt, pass_index, samples, keys):
    """The light samples' numbers in pass ``pass_index`` of the points whose pixels are ``keys`` (n,)
    (:func:`point_keys`; ``RenderSettings.pixel_jitter``): a function of (rows (m,), sample (m,))
    giving (m, 4) numbers in [0, 1) for sample ``sample`` of ``samples`` a pass of points ``rows``:
    the emitter's choice, the point on it (or the direction) and the one more some emitters take.  A
    pixel's samples, pass after pass, are the points of the 4-dimensional Sobol sequence (the
    point on the light the (0, 2)-sequence's first two dimensions, the choice the third) at the
    indices ``pass_index * samples + sample``, index and coordinates Owen-scrambled with seeds of
    the pixel's own (:func:`~core.sampling.scrambled_sobol`; Cycles' Sobol-Burley pattern).  So each
    pass's samples are uniform, and a pixel's first 2^k samples fill the light's strata evenly (its
    samples of a pass each a different stratum): soft shadows, the light of many emitters, what
    part of an area light a point sees settle faster.  The scrambles pair them with the pixel's own
    jitter (:func:`~core.camera.stratified_jitter`) at random.  A digital shift of the coordinates
    instead of their scramble, or Sobol's dimensions 8 to 11 at the same index, after the camera's 1
    to 7, did worse in places than independent numbers (``benchmarks/light_numbers.py``; README,
    "Pixel jitter stratified over passes")."""
    # (five 32-bit seeds a point: the index's and each coordinate's, from one hash of 3 x 64 bits)
    seeds = smp.hash_bits(keys, salt, 3).view(np.uint32)
    first = np.uint64(pass_index * samples)

    def numbers(rows, sample):
        index = np.asarray(sample, np.uint64) + first
        return smp.scrambled_sobol(index, (3, 1, 2, 4), seeds.take(rows, axis=0))
    return numbers


def point_keys(pixel_ids):
    """(m,) int64: a key of each point's own for :func:`stratified_light`, the same pass after pass:
    its pixel and its rank among the pixel's points (0 where it is the only one)."""
    pixel_ids = np.asarray(pixel_ids, np.int64)
    if len(pixel_ids) < 2 or (np.diff(pixel_ids) > 0).all():
        return pixel_ids * 64
    order = np.argsort(pixel_ids, kind="stable")
    sorted_ids = pixel_ids.take(order)
    start = np.flatnonzero(np.r_[True, sorted_ids[1:] != sorted_ids[:-1]])
    rank = np.arange(len(order)) - np.repeat(start, np.diff(np.r_[start, len(order)]))
    keys = np.empty_like(pixel_ids)
    keys[order] = sorted_ids * 64 + np.minimum(rank, 63)
    return keys


def sample_direct(ctx, target, mask, rng, samples=1, passes=None, groups=None, numbers=None):
    """(n_pixels, 3) float64: the mean of ``samples`` light samples' estimates of the direct light
    at each of ``target``'s surface points (a :class:`~core.photon_pass.DepositTarget`), through
    its throughput, from the emitters ``mask`` (:func:`sampled_emitters`) chosen by power
    (:func:`lamp_choice`).

    ``passes``: None, or name -> (n_pixels, 3) arrays of Cycles' light passes
    (``core/light_passes.py``) to add the samples' parts to, as the photons' first vertices would
    go: at points with no delta event before them (``MeasurementPoints.via``) the glossy lobe's part
    to ``glossy_direct`` and the rest to ``diffuse_direct``, at the others all to the
    ``<kind>_indirect`` pass of their first delta event.  ``groups``: None, or (the light group
    passes' arrays, the index among them of each of the scene's light groups or -1): each sample
    also goes to its emitter's group's pass.  ``numbers``: None (independent numbers of ``rng``),
    or the stratified ones' function of the points' keys (:func:`stratified_light`)."""
    pts = target.points
    out = np.zeros((target.n_pixels, 3))
    q = ctx.lights.prob * mask
    base = (np.arange(pts.count) if target.direct_points is None
            else np.flatnonzero(target.direct_points))           # (the points that take samples)
    if len(base) == 0 or not q.sum() > 0:
        return out
    prob = q / q.sum()
    cdf = np.cumsum(prob)
    cdf[-1] = 1.0
    choose, most = lamp_choice(ctx.lights, prob, cdf)
    split = bool(passes)
    draw = None if numbers is None else numbers(point_keys(pts.pixel_ids).take(base))
    # Sample k is number k // len(base) of point base[k mod len(base)]; a chunk's samples are of
    # consecutive points (mod len(base)), at most ``most`` of them with the lamps' choice.
    total = len(base) * samples
    chunk = CHUNK if most is None else min(CHUNK, most * samples)
    for start in range(0, total, chunk):
        sample_ids = np.arange(start, min(start + chunk, total))
        slot = sample_ids % len(base)
        u = rng.random((len(slot), 4)) if draw is None else draw(slot, sample_ids // len(base))
        x = rows = None
        if most is not None:
            lo = int(slot[0])
            chunk_points = base.take((lo + np.arange(min(len(slot), len(base)))) % len(base))
            x, rows = pts.position.take(chunk_points, axis=0).astype(np.float64), (slot - lo) % len(base)
        entry, chance = choose(u[:, 0], x, rows)
        j, estimate, glossy, entry = _light_samples(ctx, target, base.take(slot), entry, chance, u, rng,
                                                    split)
        pix = pts.pixel_ids.take(j)
        value = target.point_values(j, estimate / samples)
        np.add.at(out, pix, value)
        if split:
            via = np.zeros(len(j), np.uint8) if pts.via is None else pts.via.take(j)
            shine = np.zeros_like(value) if glossy is None else target.point_values(j, glossy / samples)
            first = via == VIA_NONE
            for name, sel, part in (("diffuse_direct", first, value - shine), ("glossy_direct", first, shine),
                                    ("glossy_indirect", via == VIA_GLOSSY, value),
                                    ("transmission_indirect", via == VIA_TRANSMISSION, value)):
                if name in passes and sel.any():
                    np.add.at(passes[name], pix[sel], part[sel])
        if groups is not None:
            arrays, index = groups
            group = ctx.lights.group.take(entry)
            for g in np.unique(group[group >= 0]):
                k = index[g]
                if k >= 0:
                    sel = group == g
                    np.add.at(arrays[k], pix[sel], value[sel])
    return out


def _light_samples(ctx, target, point, entry, chance, u, rng, split=False):
    """One light sample at each of ``target``'s surface points ``point`` (k,) of the emitters
    ``entry`` (k,) chosen with the chances ``chance`` (k,) (:func:`lamp_choice`) and the numbers
    ``u`` (k, 4): (the points j whose samples reached the light, (len(j), 3) their estimates before
    :meth:`~core.photon_pass.DepositTarget.point_values`, with ``split`` the glossy lobe's part of
    them (None where no point has one), and their emitters)."""
    lights, pts = ctx.lights, target.points
    m = len(point)
    x = pts.position.take(point, axis=0).astype(np.float64)
    ng = pts.ng.take(point, axis=0).astype(np.float64)
    translucent = np.zeros(m, bool) if target.translucent is None else target.translucent.take(point)
    wi, t_max, value = lights.sample_direct(entry, x, ng, translucent, u[:, 1:])
    cos = dot(wi, ng)
    back = cos < 0
    live = value.any(axis=1) & (cos != 0) & (~back | translucent)
    if target.room is not None:
        # (a point behind as many bounces as the limits allow in all gets no direct light)
        live &= target.bounce_filter(point, 0, np.zeros((m, 4), np.int16))[0]
    r = np.flatnonzero(live)
    nothing = (np.zeros(0, np.int64), np.zeros((0, 3)), None, np.zeros(0, np.int64))
    if len(r) == 0:
        return nothing
    d = wi.take(r, axis=0)
    origins = ctx.accel.spawn(x.take(r, axis=0), ng.take(r, axis=0), d, pts.prim.take(point.take(r)))
    hits, tint, _, _ = ctx.trace(origins, d, t_max.take(r), lambda rows, k: rng.random(len(rows)))
    open_ = np.flatnonzero(~hits.is_hit)
    r = r.take(open_)
    if len(r) == 0:
        return nothing
    j = point.take(r)
    behind = back.take(r)
    cos_g = np.abs(cos.take(r))
    d = wi.take(r, axis=0) * np.where(behind, -1.0, 1.0)[:, None]    # (back pairs: on the point's side)
    w = target.pair_weights(j, d, cos_g, cos_g if target.has_shading_normals else None,
                            behind if behind.any() else None, split=split)
    w, glossy = w if split else (w, None)
    arriving = value.take(r, axis=0) * (cos_g / chance.take(r))[:, None]
    if tint is not None:
        arriving *= tint.take(open_, axis=0)

    def times(weights):
        with np.errstate(over="ignore", invalid="ignore"):
            e = arriving * (weights[:, None] if weights.ndim == 1 else weights.T)
        # (a point on top of a point light or an emitter's edge: no sample beyond float range)
        return np.where(np.isfinite(e), e, 0.0)
    return j, times(w), None if glossy is None else times(glossy), entry.take(r)

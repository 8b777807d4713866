"""Direct light by light samples at the measurement points (``RenderSettings.direct_light``).

A photon deposits at every non-delta vertex, the first included, so by default the light that
reaches a surface straight from an emitter comes from photons too: the plain method of the paper,
and the blotchy look of a photon map where most of the light is direct (the Cornell box:
``benchmarks/versus_cycles.py``).  With ``direct_light="sampled"`` each pass's measurement points
get that light from one light sample each instead: an emitter chosen by power among those
:meth:`~core.lights.LightSampler.direct_entries` names, a point on it or a direction
(:meth:`~core.lights.LightSampler.sample_direct`), a shadow ray, and the point's BSDF through the
pair weights a photon arriving along the same direction would get
(:meth:`~core.photon_pass.DepositTarget.pair_weights`, with the landing facet the point's own).
The photon pass then leaves out the deposits at the first vertex of the photons of those emitters
(``DepositTarget.direct``), and nothing else: light through glass or off a mirror (a caustic, a
room lit through a glass roof) still comes from photons, as does the light of emitters left out.
So the two estimate disjoint parts of the light and their sum is the same image, without the
photons' kernel bias in the direct part; the light samples are averaged over passes with the
emission the camera sees (``EyePassResult.emission``).  The Markov chains then seek paths that
matter beyond their first vertex, as a path visible only there is no longer visible.

Scenes with what the light samples do not model keep the photons' direct light, with a warning
(:func:`sampled_emitters`): volumes, shadow catchers, subsurface scattering, light and shadow
linking, emitters that leave out some rays, light and light group passes, and a Transparent
bounces limit the camera paths count against.
"""
from __future__ import annotations

import numpy as np

from .sampling import dot


def sampled_emitters(ctx, light_passes=False, limits=None):
    """(mask, reason): the emitters (``LightSampler`` entries, (count,) bool) whose direct light
    the measurement points sample, or (None, why not) where the scene calls for something the
    light samples do not model (module docstring).  ``light_passes``: whether the render makes
    light or light group passes; ``limits``: its :class:`~core.settings.BounceLimits`."""
    lights = ctx.lights
    reasons = (("volumes", ctx.has_volumes), ("shadow catchers", ctx.catcher is not None),
               ("subsurface scattering", ctx.subsurface_exit >= 0),
               ("light or shadow linking", lights.has_links or lights.has_shadow_links
                or ctx.receiver_sets is not None or ctx.blocker_sets is not None),
               ("emitters that leave out some rays", lights.has_exclusion),
               ("light or light group passes", bool(light_passes)),
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


def sample_direct(ctx, target, mask, rng, samples=1):
    """(n_pixels, 3) float64: the mean of ``samples`` light samples' estimates of the direct light
    at each of ``target``'s surface points (a :class:`~core.photon_pass.DepositTarget`), through
    its throughput, from the emitters ``mask`` (:func:`sampled_emitters`) chosen by power."""
    pts = target.points
    out = np.zeros((target.n_pixels, 3))
    q = ctx.lights.prob * mask
    if pts.count == 0 or not q.sum() > 0:
        return out
    cdf = np.cumsum(q / q.sum())
    cdf[-1] = 1.0
    # Sample k is of point k mod m.
    total = pts.count * samples
    for start in range(0, total, CHUNK):
        point = np.arange(start, min(start + CHUNK, total)) % pts.count
        j, estimate = _light_samples(ctx, target, point, q / q.sum(), cdf, rng)
        np.add.at(out, pts.pixel_ids.take(j), target.point_values(j, estimate / samples))
    return out


def _light_samples(ctx, target, point, prob, cdf, rng):
    """One light sample at each of ``target``'s surface points ``point`` (k,), emitters chosen
    with probabilities ``prob`` (cumulated ``cdf``): (the points j whose samples reached the light,
    (len(j), 3) their estimates before :meth:`~core.photon_pass.DepositTarget.point_values`)."""
    lights, pts = ctx.lights, target.points
    m = len(point)
    u = rng.random((m, 4))
    entry = np.minimum(np.searchsorted(cdf, u[:, 0], side="right"), lights.count - 1)
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
    if len(r) == 0:
        return r, np.zeros((0, 3))
    d = wi.take(r, axis=0)
    origins = ctx.accel.spawn(x.take(r, axis=0), ng.take(r, axis=0), d)
    hits, tint, _, _ = ctx.trace(origins, d, t_max.take(r), lambda rows, k: rng.random(len(rows)))
    open_ = np.flatnonzero(~hits.is_hit)
    r = r.take(open_)
    if len(r) == 0:
        return r, np.zeros((0, 3))
    j = point.take(r)
    behind = back.take(r)
    cos_g = np.abs(cos.take(r))
    d = wi.take(r, axis=0) * np.where(behind, -1.0, 1.0)[:, None]    # (back pairs: on the point's side)
    w = target.pair_weights(j, d, cos_g, cos_g if target.has_shading_normals else None,
                            behind if behind.any() else None)
    arriving = value.take(r, axis=0) * (cos_g / prob.take(entry.take(r)))[:, None]
    if tint is not None:
        arriving *= tint.take(open_, axis=0)
    return j, arriving * (w[:, None] if w.ndim == 1 else w.T)

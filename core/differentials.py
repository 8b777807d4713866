"""Ray differentials (Igehy 1999): how wide a pixel's beam is where a camera path ends.

A measurement point's initial radius is a few pixel footprints at the point.  Seen
directly, a pixel's beam at distance t is t footprints wide; after a flat mirror or a flat
pane of glass it is about (path length) footprints wide.  A curved mirror or a glass ball
spreads it: a ball a few pixels wide shows the whole scene around it, so the points seen in it lie
metres apart, far more than their path length makes their radii.  Such points are lone: few
photons reach their small discs, and too few of them share a cell for
``core/visible_cells.py`` to count them, so the Markov chains never visit the paths that
reach them (those count through the uniform samples only, at plain photon tracing's rate).

Each camera ray carries the derivatives of its origin and direction per pixel step in x
and in y.  At a hit the origin derivatives move onto the tangent plane; a delta
reflection or refraction turns the direction derivatives with the derivative of the
shading normal, interpolated from the vertex normals (flat triangles have none, so a
faceted mirror acts as many flat ones).  The beam's cross-section at the point, across
the ray, is ``dp + t dd`` with its component along the ray removed; the point's width is
the root mean square of the two axes' lengths (a focal line keeps its long axis).

The derivatives are first order: at a focus of the camera's beam they vanish while the
true footprint does not, so the width is kept above ``MIN_WIDTH_RATIO`` times the
straight-line width (footprint times path length).  The radius only sets the kernel's
bias against its noise (every radius gives a consistent estimate), so an inexact width
costs efficiency, never correctness.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sampling import dot

MIN_WIDTH_RATIO = 0.25      # floor of the beam width, against footprint x path length
MIN_COS = 1e-3              # |cos| below which a ray grazes a plane: the transfer is capped there


@dataclass
class Differentials:
    """Per ray: derivatives of the origin (``dpx``, ``dpy``) and of the unit direction
    (``ddx``, ``ddy``) per pixel step in x and y, each (n, 3) float64 in world space."""

    dpx: np.ndarray
    dpy: np.ndarray
    ddx: np.ndarray
    ddy: np.ndarray

    def take(self, rows) -> "Differentials":
        return Differentials(*(a.take(rows, axis=0) for a in (self.dpx, self.dpy, self.ddx, self.ddy)))


def from_camera(camera, directions, footprint) -> Differentials:
    """Differentials of camera rays: ``footprint`` (n,) wide per pixel across each ray,
    along the camera's right and up axes (the lens of a thin-lens camera is left out)."""
    d = np.asarray(directions, np.float64)
    right = np.asarray(camera.world_from_camera, np.float64)[:3, 0]
    right = right / max(np.linalg.norm(right), 1e-300)
    e1 = right[None, :] - dot(d, right[None, :])[:, None] * d
    e1 /= np.maximum(np.linalg.norm(e1, axis=1), 1e-300)[:, None]
    e2 = np.cross(d, e1)
    fp = np.asarray(footprint, np.float64)[:, None]
    zero = np.zeros_like(d)
    if camera.projection == "perspective":
        return Differentials(zero, zero.copy(), fp * e1, fp * e2)
    return Differentials(fp * e1, fp * e2, zero, zero.copy())


def _across(a, d):
    """``a`` (n, 3) without its component along the unit ``d`` (n, 3)."""
    return a - dot(a, d)[:, None] * d


def beam_width(diff, directions, t):
    """(n,) width of the beam at distance ``t`` (n,) along the rays, across them."""
    t = np.asarray(t, np.float64)[:, None]
    ax = _across(diff.dpx + t * diff.ddx, directions)
    ay = _across(diff.dpy + t * diff.ddy, directions)
    return np.sqrt(0.5 * (dot(ax, ax) + dot(ay, ay)))


def transfer(diff, directions, t, ng):
    """Origin derivatives moved to the hits at ``t`` along the rays, on the planes with normals ``ng``."""
    t = np.asarray(t, np.float64)[:, None]
    cos = dot(directions, ng)
    cos = np.where(np.abs(cos) < MIN_COS, np.where(cos < 0, -MIN_COS, MIN_COS), cos)
    out = []
    for dp, dd in ((diff.dpx, diff.ddx), (diff.dpy, diff.ddy)):
        a = dp + t * dd
        out.append(a - (dot(a, ng) / cos)[:, None] * directions)
    return out


def shading_normal_derivatives(ctx, prim_ids, b1, b2, dpx, dpy):
    """Derivatives (n, 3) x 2 of the unit interpolated shading normal along the surface offsets
    ``dpx``, ``dpy`` (on the triangles' planes); zero without shading normals."""
    if not ctx.has_shading_normals:
        return np.zeros_like(dpx), np.zeros_like(dpy)
    a = ctx.accel
    e1, e2 = a.e1.take(prim_ids, axis=0), a.e2.take(prim_ids, axis=0)
    sn = ctx.shading_normals.take(prim_ids, axis=0).astype(np.float64)
    b0 = 1.0 - b1 - b2
    n = b0[:, None] * sn[:, 0] + b1[:, None] * sn[:, 1] + b2[:, None] * sn[:, 2]
    length = np.sqrt(dot(n, n))
    ok = length > 1e-12
    nhat = n / np.where(ok, length, 1.0)[:, None]
    dn1, dn2 = sn[:, 1] - sn[:, 0], sn[:, 2] - sn[:, 0]
    # Barycentric derivatives: dp = db1 e1 + db2 e2 solved through the Gram matrix.
    g11, g12, g22 = dot(e1, e1), dot(e1, e2), dot(e2, e2)
    det = g11 * g22 - g12 * g12
    inv = np.where(det > 0, 1.0 / np.where(det > 0, det, 1.0), 0.0)
    out = []
    for dp in (dpx, dpy):
        r1, r2 = dot(e1, dp), dot(e2, dp)
        db1, db2 = (g22 * r1 - g12 * r2) * inv, (g11 * r2 - g12 * r1) * inv
        dn = db1[:, None] * dn1 + db2[:, None] * dn2
        dn = (dn - dot(dn, nhat)[:, None] * nhat) / np.where(ok, length, 1.0)[:, None]
        out.append(np.where(ok[:, None], dn, 0.0))
    return out


def scattered(dp, dd, wo, wi, normal, dnormal, reflected, eta):
    """Direction derivatives of the delta-scattered rays ``wi`` (n, 3).

    dp : the origin derivatives on the surface ([dpx, dpy]), carried on unchanged.
    dd : the incoming direction derivatives ([ddx, ddy]); ``wo`` (n, 3) = -incoming direction.
    normal : (n, 3) unit normal the rays scattered about, on the side of ``wo``;
    dnormal : its derivatives [x, y].  reflected : (n,) bool.
    eta : (n,) relative index of refraction n_t / n_i across the surface (refracted rays only).
    Mirror reflection wi = -wo + 2 (wo.n) n; refraction wi = -wo / eta + mu n with
    mu = cos_i / eta - cos_t (pbrt's SpecularTransmit, Igehy 1999).
    """
    cos_i = dot(wo, normal)
    eta = np.asarray(eta, np.float64)
    e = 1.0 / np.where(eta > 0, eta, 1.0)
    cos_t = np.abs(dot(wi, normal))
    mu = e * cos_i - cos_t
    dmu_dcos = np.where(cos_t > 1e-6, e - e * e * cos_i / np.maximum(cos_t, 1e-6), 0.0)
    out = []
    for d_in, dn in zip(dd, dnormal):
        dwo = -d_in
        dcos = dot(dwo, normal) + dot(wo, dn)
        refl = -dwo + 2.0 * (cos_i[:, None] * dn + dcos[:, None] * normal)
        refr = -e[:, None] * dwo + mu[:, None] * dn + (dmu_dcos * dcos)[:, None] * normal
        out.append(np.where(reflected[:, None], refl, refr))
    return Differentials(dp[0], dp[1], out[0], out[1])

"""Eye pass: one camera path per pixel, through delta bounces, to a measurement point.

Each pass jitters every pixel anew (and the lens sample), follows the camera
path through mirror and glass, adds the emission it sees on the way (emitters,
glowing volumes, the world, and the analytic lights that the ray's kind may see: ``Lights.visibility``,
directly or through delta chains) and stores a *measurement
point* at the first hit where it picks a non-delta lobe (``algorithm.md`` 1:
the variant in which photons carry direct light too).  Every segment through a
scattering volume also gets a :class:`VolumePoints` point (the path goes on).

Glossary: ``beta`` camera-path throughput, ``wo`` direction back towards the camera.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .accel import interpolate_corners
from .bsdf import (DIELECTRIC, DIFFUSE, GLOSSY, MIRROR, SHEEN, TRANSLUCENT, choose_lobe, dielectric_albedos,
                   face_forward, lobe_remainder, lobe_scores, pick_coat, reflector_albedo, scatter,
                   valid_reflection_normal)
from .camera import generate_camera_rays
from . import cryptomatte, subsurface
from .light_passes import (VIA_GLOSSY, VIA_NONE, VIA_TRANSMISSION, EyeLight, light_groups,
                           wanted as light_wanted)
from .procedural import Rays, camera_path
from .sampling import cosine_hemisphere, dot, orthonormal_frames, to_world
from .scene import PANORAMAS, VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION, linked
from .shadow_catcher import (CATCHER_BACKGROUND, CATCHER_HIT, CATCHER_WEIGHT, START_BACK, START_MIN,
                             CatcherRays)
from .settings import AOV_PREFIX, BounceLimits


@dataclass
class MeasurementPoints:
    """Camera-path end points of one pass (at most one per pixel)."""

    pixel_ids: np.ndarray   # (m,) int64 index of the pixel in the window, row-major from the top
    position: np.ndarray    # (m, 3) float64, world
    ng: np.ndarray          # (m, 3) float32 unit geometric normal, on the side of wo
    ns: np.ndarray          # (m, 3) float32 unit shading normal, on the side of ng
    wo: np.ndarray          # (m, 3) float32 unit direction back along the camera path
    weight: np.ndarray      # (m, 3) float32 camera-path throughput / non-delta choice probability
    mat_ids: np.ndarray     # (m,) int32 material
    colors: np.ndarray      # (m, 2, 3) float32 diffuse and glossy colour at the point, and (m, 3, 3) the
    #                         translucent colour third in scenes with translucency
    base_radius: np.ndarray  # (m,) float64 r_1: initial_radius_px pixel footprints at the point
    nn: np.ndarray = None   # (m, 3) float32 shading normal before normal maps, side of ng; None without
    ns_glossy: np.ndarray = None  # (m, 3) float32 glossy lobes' normal (valid_reflection_normal); None: ns
    tangent: np.ndarray = None    # (m, 3) float32 anisotropic glossy lobes' tangent (Surface.tangent); None
    bounces: np.ndarray = None    # (m, 5) uint8 the camera path's bounces before the point, in all and of
    #                               each kind (BounceLimits.array's order); None: none
    crossings: np.ndarray = None  # (m,) int16 the transparent surfaces the camera path crossed before the
    #                               point (RenderContext.trace); None: not counted
    via: np.ndarray = None        # (m,) uint8 the kind of the camera path's first delta event
    #                               (light_passes.VIA_*); None: no light passes
    caught: np.ndarray = None     # (m,) bool the camera path's first hit was a shadow catcher
    #                               (core/shadow_catcher.py); None: the scene has none
    prim: np.ndarray = None       # (m,) int32 the triangle the point lies on (rays leave it by its
    #                               Accel.spawn offset)

    @property
    def count(self) -> int:
        return int(len(self.pixel_ids))

    @property
    def glossy_normals(self) -> np.ndarray:
        """(m, 3) float32 normals of the glossy lobes: ``ns_glossy``, or ``ns`` without one."""
        return self.ns if self.ns_glossy is None else self.ns_glossy

    def take(self, sel) -> "MeasurementPoints":
        return MeasurementPoints(*(None if getattr(self, f) is None else getattr(self, f)[sel]
                                   for f in self.__dataclass_fields__))

    @staticmethod
    def concatenate(parts) -> "MeasurementPoints":
        return MeasurementPoints(*(None if getattr(parts[0], f) is None
                                   else np.concatenate([getattr(p, f) for p in parts])
                                   for f in MeasurementPoints.__dataclass_fields__))


@dataclass
class VolumePoints:
    """Points of one pass's camera paths in scattering volumes, one in every segment that crosses
    one (so a pixel may have several, besides its :class:`MeasurementPoints` point): they gather
    the photons that scattered within a sphere around them."""

    pixel_ids: np.ndarray   # (k,) int64 pixel in the window
    position: np.ndarray    # (k, 3) float64, world
    wo: np.ndarray          # (k, 3) float32 unit direction back along the camera path
    weight: np.ndarray      # (k, 3) float32 camera-path throughput to it, times T(t) / p(t) in its segment
    mat_ids: np.ndarray     # (k,) int32 the material whose volume it lies in
    base_radius: np.ndarray  # (k,) float64 r_1, as MeasurementPoints.base_radius
    planes: np.ndarray      # (k, 2 + SIDE_PROBES) float64 distances to the planes of the faces its
    #                         camera ray entered and would have left the volume by, and of those of
    #                         its volume beside the ray (side_planes) (inf: none)
    bounces: np.ndarray = None  # (k, 5) uint8 as MeasurementPoints.bounces
    crossings: np.ndarray = None  # (k,) int16 as MeasurementPoints.crossings (those before its segment)
    via: np.ndarray = None        # (k,) uint8 as MeasurementPoints.via
    caught: np.ndarray = None     # (k,) bool as MeasurementPoints.caught

    @property
    def count(self) -> int:
        return int(len(self.pixel_ids))

    @staticmethod
    def concatenate(parts) -> "VolumePoints":
        if not parts:
            z3 = np.zeros((0, 3), np.float32)
            return VolumePoints(np.zeros(0, np.int64), np.zeros((0, 3)), z3, z3, np.zeros(0, np.int32),
                                np.zeros(0), np.zeros((0, 2)))
        return VolumePoints(*(None if getattr(parts[0], f) is None
                              else np.concatenate([getattr(p, f) for p in parts])
                              for f in VolumePoints.__dataclass_fields__))


@dataclass
class EyePassResult:
    points: MeasurementPoints
    emission: np.ndarray     # (n_pixels, 3) float64 emission seen directly or through delta chains
    alpha: np.ndarray        # (n_pixels,) float64 coverage (1 unless the film is transparent)
    rays: int                # rays traced
    volume: VolumePoints = None  # the camera paths' points in scattering volumes
    data: dict = None        # RenderSettings.data_passes: "depth", "denoising_depth" (n_pixels,), "normal",
    #                          "albedo", "denoising_normal" (n_pixels, 3); with shadow catchers also
    #                          shadow_catcher.CATCHER_HIT, CATCHER_WEIGHT and CATCHER_BACKGROUND
    catcher: CatcherRays = None  # the camera rays whose first hit was a shadow catcher and whose paths
    #                              went on through its mirror or glass lobes, or None without catchers


# Camera paths traced at once (bounds the memory of big images).
EYE_CHUNK = 1 << 18
# Points in each segment of a camera path through a scattering volume (RenderContext.trace's
# ``forced``): as many as keep a pass's volume points within VOLUME_POINT_BUDGET for one segment
# per pixel, at most MAX_SEGMENT_POINTS.  16 points per segment against one, same passes and
# photons (benchmarks/volume_points.py): the image's noise 0.12 times as high for 2.2-2.6 times
# the time in the built-in corner in world fog (64 x 64), 0.29-0.42 times for 1.25-1.33 times in
# the foggy glass-ceiling room (64 x 48), PPM and the chains; 8 points did less in both.
VOLUME_POINT_BUDGET = 1 << 21
MAX_SEGMENT_POINTS = 16


def trace_eye_pass(ctx, rng, initial_radius_px, max_bounces, data_passes=(), limits=None,
                   alpha_threshold=1.0, ao_distance=10.0, rays=None, jitter=None,
                   choices=None, should_stop=None) -> EyePassResult:
    """Trace one camera path per window pixel with fresh jitter from ``rng`` (or, for the pixel
    jitter, from ``jitter``: None, or a function of the pixel ids (n,) that returns their (n, 2)
    numbers, :func:`~core.camera.stratified_jitter`, or (n, 4) with the lens samples,
    :func:`~core.camera.stratified_lens`; and for the lobe choice at each surface, from
    ``choices``: None, or a function of the pixel ids and the depth returning (n, 3),
    :func:`~core.camera.stratified_choices`); with
    ``data_passes`` (``RenderSettings.data_passes``) also the data of the surfaces the camera
    rays stop on (:func:`first_hit_data`; the normal and UV past transparent surfaces by
    ``alpha_threshold``, :func:`threshold_data`).  ``limits`` (:class:`~core.settings.BounceLimits`, by
    default ``max_bounces`` in all and none per kind): a point may follow as many mirror and
    glass bounces as leave room for its photons' (at least none), emission may be seen after
    one more (that last bounce does not count, as in Cycles).  ``ao_distance``: the Ambient
    Occlusion pass's (:func:`ambient_occlusion`).  In scenes with shadow catchers the paths that
    meet one first are marked and summed apart (``core/shadow_catcher.py``).  ``rays``: None, or
    :class:`~core.shadow_catcher.CatcherRays` to trace instead of the camera's (each from just
    before its catcher hit, with its radius: :class:`~core.shadow_catcher.CatcherRender`).
    ``should_stop``: None, or polled between chunks of ``EYE_CHUNK`` paths: the pass returns None
    as soon as it returns True (the 3D viewport's next job waits for it)."""
    if limits is None:
        limits = BounceLimits(max_bounces)
    x0, x1, y0, y1 = ctx.scene.camera.window
    n_pix = (x1 - x0) * (y1 - y0)
    emission = np.zeros((n_pix, 3))
    alpha = np.ones(n_pix)
    data = {}
    if "depth" in data_passes:
        data["depth"] = np.full(n_pix, NO_DEPTH)
    for name in ("normal", "position", "uv"):
        if name in data_passes:
            data[name] = np.zeros((n_pix, 3))
    for name in ("object_index", "material_index"):
        if name in data_passes:
            data[name] = np.zeros(n_pix)
    if "mist" in data_passes:
        data["mist"] = np.ones(n_pix)                 # (rays that meet nothing: all mist)
    if "ao" in data_passes:
        data["ao"] = np.zeros((n_pix, 3))
    for name in data_passes:
        if name.startswith(AOV_PREFIX):
            data[name] = np.zeros((n_pix, 4))         # (value or colour, and 1 where written)
    for name in ("denoising_normal", "denoising_depth"):
        if name in data_passes:
            data[name] = np.zeros((n_pix, 3) if name == "denoising_normal" else n_pix)
    if {"albedo", "denoising_normal", "denoising_depth"} & set(data_passes):
        data["albedo"] = np.zeros((n_pix, 3))         # (the other denoising features follow it)
    # Cycles' light passes: the eye pass's part (emission, the world, colours; the Accumulator adds
    # the photons'), and every pass's points record their paths' first delta events.
    # Light groups likewise: what the camera paths see of each group's emitters.
    photon_light, eye_light, colours = light_wanted(data_passes)
    groups = light_groups(data_passes, ctx.scene.light_groups)
    light = None
    if photon_light or eye_light or colours or groups[0]:
        light = EyeLight({name: np.zeros((n_pix, 3), np.float32) for name in eye_light + colours + groups[0]},
                         groups)
        data.update(light.sums)
    caught = None
    if ctx.catcher is not None and rays is None:
        caught = []                                   # (CatcherRays of each chunk)
        data.update({CATCHER_HIT: np.zeros((n_pix, 3)), CATCHER_WEIGHT: np.zeros(n_pix),
                     CATCHER_BACKGROUND: np.zeros((n_pix, 3))})
    kinds = [k for k in cryptomatte.KINDS if k in data_passes and ctx.scene.cryptomatte_ids is not None]
    chunks = [] if kinds else None                    # Cryptomatte's (pixels, triangles, weights) per chunk
    parts, volume = [], []
    n_rays = 0
    per_segment = int(np.clip(VOLUME_POINT_BUDGET // max(n_pix, 1), 1, MAX_SEGMENT_POINTS))
    n_paths = n_pix if rays is None else rays.count
    for start in range(0, n_paths, EYE_CHUNK):
        if start and should_stop is not None and should_stop():
            return None
        chunk = np.arange(start, min(start + EYE_CHUNK, n_paths))
        given = None if rays is None else _catcher_starts(ctx, rays, chunk)
        pixel_ids = chunk if rays is None else given[0]
        points, r = _trace_camera_paths(ctx, rng, pixel_ids, emission, alpha, initial_radius_px,
                                        limits, volume, per_segment, data, alpha_threshold, chunks, light,
                                        ao_distance, given, caught, jitter, choices)
        parts.extend(points)
        n_rays += r
    points = MeasurementPoints.concatenate(parts) if parts else _empty_points()
    if "albedo" not in data_passes:
        data.pop("albedo", None)
    if kinds:
        # Each kind: (pixels, ids, weights) of the surfaces the rays reached (Accumulator sums them).
        pix, prim, weight = (np.concatenate(c) for c in zip(*chunks))
        ids = ctx.scene.cryptomatte_ids.take(prim, axis=0)
        for k in kinds:
            data[k] = (pix, ids[:, cryptomatte.KINDS.index(k)], weight)
    return EyePassResult(points, emission, alpha, n_rays, VolumePoints.concatenate(volume), data or None,
                         None if caught is None else CatcherRays.concatenate(caught))


def _catch(data, rows, pix, beta, world_along):
    """Record the camera rays ``rows`` whose first hit is a shadow catcher: their throughput's mean
    there to ``data``'s CATCHER_WEIGHT and the world along them to its CATCHER_BACKGROUND."""
    if len(rows) == 0:
        return
    p = pix.take(rows)
    b = beta.take(rows, axis=0)
    data[CATCHER_WEIGHT][p] += b.mean(axis=1)
    sky = world_along(rows)
    if sky is not None:
        data[CATCHER_BACKGROUND][p] += b * sky


def _catcher_starts(ctx, rays, rows):
    """(pix, origins, dirs, tmax, footprint, path_len) of catcher rays ``rows`` of ``rays``
    (:class:`~core.shadow_catcher.CatcherRays`), each from START_BACK of its distance before its
    catcher (at least START_MIN of the scene's extent), as far along the path."""
    t = rays.t.take(rows)
    back = np.maximum(START_BACK * t, START_MIN * ctx.accel.extent)
    start = np.maximum(t - back, 0.0)
    dirs = rays.dirs.take(rows, axis=0)
    origins = rays.origins.take(rows, axis=0) + start[:, None] * dirs
    return (rays.pixel_ids.take(rows), origins, dirs, np.full(len(rows), np.inf), rays.footprint.take(rows),
            start)


# Cycles' line between specular-like and diffuse-like closures for its denoising features: a
# microfacet lobe whose alpha_x alpha_y exceeds 0.075^2 is diffuse-like (film/denoising_passes.h).
FEATURE_ALPHA = 0.075


class DenoisingPaths:
    """Cycles' denoising features (Denoising Albedo, Normal and Depth) along one chunk of camera
    paths (``film/denoising_passes.h``).

    A path is *open* from the camera on.  At each surface it meets while open, the albedos of the
    material's lobes are split into diffuse-like (diffuse, translucent, sheen, and glossy or glass
    lobes rougher than ``FEATURE_ALPHA``) and specular-like ones (:func:`surface_albedo`); if the
    diffuse-like part is more than a quarter of the total (or there is none at all), the path
    writes its feature throughput ``feat`` times the diffuse-like part and closes, else ``feat``
    takes the specular-like part and the path goes on.  Emission, lights and the world that an
    open path sees add ``feat`` times what they add to the image, a scattering volume on the way
    its part (:meth:`volume`).  Where an open path stops at a measurement point of such a
    specular surface (its glossy lobe is not followed, as Cycles follows any closure), it writes
    ``feat`` times both parts: what the lobe reflects is taken as white.  Where it writes the
    albedo of a surface it also writes that surface's shading normal facing the camera side
    (``normal``; Cycles' mean of its closures' normals: none without any), and every surface an
    open path meets adds the mean of ``feat`` times the segment's length (``depth``, Cycles'
    Denoising Depth).  ``albedo`` (n_pixels, 3), ``normal`` (n_pixels, 3) and ``depth`` (n_pixels,)
    (either None: not asked for) are this eye pass's sums."""

    def __init__(self, n, rng, albedo, normal=None, depth=None):
        self.open = np.ones(n, bool)
        self.feat = np.ones((n, 3))
        self.alive = np.ones(n)          # the chance the features are still open (volumes)
        self.out = albedo
        self.normal = normal
        self.depth = depth
        self.rng = rng
        self.pending = None              # (rows, feat x both parts, specular part, normals) at a vertex

    def light(self, pix, rows, value):
        """Paths ``rows`` (of the chunk's current ``pix``) see ``value`` (k, 3), as the image does."""
        o = np.flatnonzero(self.open.take(rows))
        if len(o):
            r = rows.take(o)
            self.out[pix.take(r)] += self.feat.take(r, axis=0) * value.take(o, axis=0)

    def surface(self, table, surf, wo, pix, segment):
        """The open paths meet ``surf`` (all current paths' hits), seen from ``wo``, at the end of
        segments of length ``segment`` (all paths')."""
        o = np.flatnonzero(self.open)
        if len(o) == 0:
            return
        feat = self.feat.take(o, axis=0)
        if self.depth is not None:
            self.depth[pix.take(o)] += (feat[:, 0] + feat[:, 1] + feat[:, 2]) / 3.0 * segment.take(o)
        diffuse_like, specular, d, t = surface_albedo(table, surf, wo, o, self.rng)
        normals = None
        if self.normal is not None:
            # (none where no lobe reflects anything: an emitter's, as Cycles' mean over no closures)
            w = wo.take(o, axis=0)
            normals = face_forward(surf.ns.take(o, axis=0), face_forward(surf.ng.take(o, axis=0), w))
            normals *= (t > 0)[:, None]
        done = (t <= 0) | (4.0 * d > t)
        c = np.flatnonzero(done)
        self._write(pix, o.take(c), feat.take(c, axis=0) * diffuse_like.take(c, axis=0),
                    None if normals is None else normals.take(c, axis=0))
        go = np.flatnonzero(~done)
        if len(go):
            self.pending = (o.take(go), feat.take(go, axis=0) * (diffuse_like.take(go, axis=0)
                                                                 + specular.take(go, axis=0)),
                            specular.take(go, axis=0), None if normals is None else normals.take(go, axis=0))

    def _write(self, pix, rows, albedo, normals):
        """Paths ``rows`` write ``albedo`` (and ``normals``) and close."""
        self.out[pix.take(rows)] += albedo
        if normals is not None:
            self.normal[pix.take(rows)] += normals * self.alive.take(rows)[:, None]
        self.open[rows] = False

    def volume(self, pix, rows, scattered, extinct, back):
        """Paths ``rows`` (repeated for several points) cross scattering volumes: ``scattered`` and
        ``extinct`` (k, 3) are their points' weights times the scattering and extinction coefficients
        (sums over a path's points estimate the integrals of sigma_s T and sigma_t T over its
        segments: the volume's albedo times 1 - T, and 1 - T).  As Cycles (``film_write_denoising_
        features_volume``): the albedo gets the first; with the chance that the path scatters
        there, the mean of the second, the normal gets the camera's backward axis ``back`` (3,) (Cycles'
        (0, 0, -1) in the camera's frame) and the features close, and the rest goes on to what lies
        behind."""
        n = len(self.open)
        a = np.stack([np.bincount(rows, scattered[:, c], minlength=n) for c in range(3)], axis=1)
        p = np.clip(np.bincount(rows, extinct[:, 0] + extinct[:, 1] + extinct[:, 2], minlength=n) / 3.0,
                    0.0, 1.0)
        r = np.flatnonzero(self.open & (p > 0))
        if len(r) == 0:
            return
        self.out[pix.take(r)] += self.feat.take(r, axis=0) * a.take(r, axis=0)
        if self.normal is not None:
            self.normal[pix.take(r)] += back * (self.alive.take(r) * p.take(r))[:, None]
        keep = 1.0 - p.take(r)
        self.feat[r] *= keep[:, None]
        self.alive[r] *= keep

    def settle(self, pix, onward):
        """After a vertex: paths ``onward`` go on (the others ended there or became points)."""
        if self.pending is None:
            return
        rows, both, specular, normals = self.pending
        self.pending = None
        on = np.zeros(len(self.open), bool)
        on[onward] = True
        goes = on.take(rows)
        self.feat[rows[goes]] *= specular[goes]
        self._write(pix, rows[~goes], both[~goes], None if normals is None else normals[~goes])

    def take(self, rows):
        self.open, self.alive = self.open.take(rows), self.alive.take(rows)
        self.feat = self.feat.take(rows, axis=0)


def surface_albedo(table, surf, wo, rows, rng):
    """(diffuse-like, specular-like) (k, 3) each: the albedos of the lobes of the materials at
    hits ``rows`` of ``surf`` seen from ``wo`` (all hits), as Cycles' ``bsdf_albedo`` estimates
    them for its denoising features (what a closure reflects and transmits under a white sky), split
    by :data:`FEATURE_ALPHA` (:class:`DenoisingPaths`); then the diffuse-like lobes' and all lobes'
    sample weights (k,) (their :func:`~core.bsdf.lobe_scores`, Cycles' ``sample_weight``: these
    decide, not the samples, one of which may come out 0).  The albedos are :func:`lobe_albedos`'."""
    k = len(rows)
    diffuse_like, specular = np.zeros((k, 3)), np.zeros((k, 3))
    d_weight, weight = np.zeros(k), np.zeros(k)
    for lobe, m_s, dest, w, score, _ in lobe_albedos(table, surf, wo, rows, rng):
        if lobe == GLOSSY:
            rough = table.alpha.take(m_s) > FEATURE_ALPHA
        elif lobe == DIELECTRIC:
            rough = table.dielectric_alpha.take(m_s) > FEATURE_ALPHA
        else:
            rough = np.full(len(m_s), lobe != MIRROR)
        diffuse_like[dest[rough]] += w[rough]
        specular[dest[~rough]] += w[~rough]
        d_weight[dest[rough]] += score[rough]
        weight[dest] += score
    return diffuse_like, specular, d_weight, weight


def colour_albedos(table, surf, wo, rows, rng):
    """Cycles' Diffuse, Glossy and Transmission Color at hits ``rows`` of ``surf`` seen from ``wo``:
    (k, 3) each, the :func:`lobe_albedos` of the diffuse-type lobes (diffuse, translucent, sheen),
    of the glossy ones (glossy, mirror, a glass's reflection) and of the transmitting ones (a
    glass's refraction), as ``surface_shader_diffuse``, ``_glossy`` and ``_transmission`` sum them
    (Cycles' estimates, not samples: :func:`lobe_albedos` with ``estimated``)."""
    k = len(rows)
    out = {name: np.zeros((k, 3)) for name in ("diffuse_color", "glossy_color", "transmission_color")}
    for lobe, _, dest, w, _, sides in lobe_albedos(table, surf, wo, rows, rng, estimated=True):
        # (a lobe's hits are distinct: no repeats in ``dest``)
        if lobe in (DIFFUSE, TRANSLUCENT, SHEEN):
            out["diffuse_color"][dest] += w
        elif lobe == DIELECTRIC:
            out["glossy_color"][dest] += sides[0]
            out["transmission_color"][dest] += sides[1]
        else:
            out["glossy_color"][dest] += w
    return out


def lobe_albedos(table, surf, wo, rows, rng, estimated=False):
    """For the hits ``rows`` of ``surf`` seen from ``wo`` (all hits), per lobe that some of them
    have: (lobe, materials (s,), hit numbers in ``rows`` (s,), albedos (s, 3), sample weights (s,),
    sides), as Cycles' ``bsdf_albedo`` estimates a closure's albedo (what it reflects and transmits
    under a white sky).  Diffuse and translucent lobes give their weight times colour (under a
    specular layer, its factor at the view), a sheen its E at the view.  Glossy, mirror and glass
    lobes give one sample each: the lobe's :func:`~core.bsdf.scatter` weight towards the camera,
    whose mean is its directional albedo at the view with what the lobe's weight takes there
    (Fresnel, a metal's curve, multiscatter); with ``estimated`` Cycles' estimates instead, without
    a sample (:func:`~core.bsdf.reflector_albedo`; a glass's by :func:`~core.bsdf.dielectric_albedos`,
    whose (reflected, transmitted) parts are then ``sides``; else None).  A coat is its own lobes
    and attenuates those under it; a sheen dims the others."""
    k = len(rows)
    every = k == len(surf.mat_ids)                   # (all hits: no copies)
    pick = (lambda a: a) if every else (lambda a: a.take(rows, axis=0))      # noqa: E731
    mats = pick(surf.mat_ids)
    layers = [(np.arange(k), mats, pick(surf.colors), pick(surf.ns), None)]
    if table.has_coat:
        coated = np.flatnonzero(table.coat_row.take(mats) >= 0)
        if len(coated):
            under = np.ones((k, 3))
            under[coated] = coat_attenuation(table, surf, wo, rows.take(coated))
            layers[0] = layers[0][:4] + (under,)
            coat = table.coat_row.take(mats.take(coated))
            layers.append((coated, coat, table.color.take(coat, axis=0),
                           coat_normal(surf).take(rows.take(coated), axis=0), None))
    for at, m, colors, ns, factor in layers:
        whole = every and len(at) == k
        wo_r = wo if whole else wo.take(rows.take(at), axis=0)
        ng = surf.ng if whole else surf.ng.take(rows.take(at), axis=0)
        tangent = surf.tangent if whole or surf.tangent is None else surf.tangent.take(rows.take(at), axis=0)
        mu_all = None
        scores = lobe_scores(table, m, colors)
        if factor is not None:
            scores *= ((factor[:, 0] + factor[:, 1] + factor[:, 2]) / 3.0)[:, None]
        for lobe in range(table.lobes):
            sel = np.flatnonzero(table.weight[:, lobe].take(m) > 0)
            if len(sel) == 0:
                continue
            m_s = m.take(sel)
            sides = None
            if lobe in (DIFFUSE, TRANSLUCENT, SHEEN):
                # (known without a sample: Cycles' estimate is the weight, a sheen's E at the view)
                if mu_all is None:
                    mu_all = np.abs(dot(wo_r, ns))
                mu = mu_all.take(sel)
                w = table.weight[:, lobe].take(m_s)[:, None] * colors[:, lobe].take(sel, axis=0)
                if lobe == DIFFUSE and table.has_layer:
                    w = w * table.layer_factor(m_s, mu)[:, None]
                if lobe == SHEEN:
                    w = w * table.sheen_lobe(m_s, mu)[0][:, None]
                elif table.has_sheen:
                    w = w * table.sheen_dim(m_s, mu)[:, None]
            elif estimated:
                c_s, wo_s, ns_s = colors.take(sel, axis=0), wo_r.take(sel, axis=0), ns.take(sel, axis=0)
                if lobe == DIELECTRIC:
                    sides = dielectric_albedos(table, m_s, c_s, wo_s, ng.take(sel, axis=0), ns_s)
                    w = sides[0] + sides[1]
                else:
                    w = reflector_albedo(table, lobe, m_s, c_s, wo_s, ns_s)
            else:
                u = rng.random((len(sel), 3))
                _, w, _ = scatter(table, m_s, colors.take(sel, axis=0), np.full(len(sel), lobe),
                                  np.ones(len(sel)), wo_r.take(sel, axis=0), ng.take(sel, axis=0),
                                  ns.take(sel, axis=0), u[:, 0], u[:, 1], "radiance", u[:, 2],
                                  tangent=None if tangent is None else tangent.take(sel, axis=0))
            if factor is not None:
                w = w * factor.take(sel, axis=0)
                sides = None if sides is None else tuple(a * factor.take(sel, axis=0) for a in sides)
            yield lobe, m_s, at.take(sel), w, scores[:, lobe].take(sel), sides


def ambient_occlusion(ctx, surf, prim, wo, medium, distance, rng):
    """(k, 3) Cycles' Ambient Occlusion pass at the hits ``surf`` (on triangles ``prim``) seen from ``wo``
    (``integrate_surface_ao``): one ray each in a cosine direction about the shading normal facing
    the viewer (Cycles' mean of its diffuse closures' normals, or the shading normal), from the
    volume ``medium`` (k,) the paths are in (None: none), that carries back what reaches
    ``distance`` (1 in the open; the tint of the transparent surfaces and volumes it crosses) and
    0 where a surface stops it first."""
    n = len(surf.mat_ids)
    ng = face_forward(surf.ng, wo)
    ns = face_forward(surf.ns, ng)
    u = rng.random((n, 2))
    d = to_world(cosine_hemisphere(u[:, 0], u[:, 1]), ns)
    below = dot(d, ng)
    d = d - 2.0 * np.minimum(below, 0.0)[:, None] * ng                # (a bent normal's: kept above)
    origins = ctx.accel.spawn(surf.position, ng, d, prim)
    never = lambda rows, k: np.full(len(rows), 1.0 - 2.0 ** -53)    # noqa: E731  (cross every one)
    hits, factor, _, _ = ctx.trace(origins, d, np.full(n, float(distance)), never, medium, cut=True)
    out = np.ones((n, 3)) if factor is None else np.array(factor, np.float64)
    out[hits.is_hit] = 0.0
    return out


# The depth pass where a camera ray meets nothing (Cycles' Z pass there).
NO_DEPTH = 1e10


def first_hit_data(ctx, data, pix, surf, wo, prim, b1, b2):
    """Write the data passes ``data`` (``trace_eye_pass``) of pixels ``pix`` whose camera rays
    stop at ``surf`` (triangles ``prim``, barycentrics ``b1``, ``b2``), seen from ``wo`` (k, 3):
    as Cycles' (``film/data_passes.h``) the depth along the camera's view axis (its distance
    from the camera for panoramas: ``camera_z_depth``), the shading normal on the camera's side,
    the position, the UV map's (u, v, 1) (0 without UVs), the object's and the material's pass
    indices and the mist of the distance from the camera (``World.mist_*``)."""
    scene = ctx.scene
    camera = scene.camera
    m = np.asarray(camera.world_from_camera, np.float64)
    origin = m[:3, 3]
    offset = surf.position - origin
    if "depth" in data:
        if camera.projection in PANORAMAS:
            data["depth"][pix] = np.sqrt(dot(offset, offset))
        else:
            forward = -m[:3, 2] / np.linalg.norm(m[:3, 2])
            data["depth"][pix] = offset @ forward
    if "normal" in data:
        data["normal"][pix] = face_forward(surf.ns, face_forward(surf.ng, wo))
    if "position" in data:
        data["position"][pix] = surf.position
    if "uv" in data and scene.uvs is not None:
        # (a triangle whose corners are all (0, 0) is of a mesh without a UV map, which the
        # exporter fills with zeros: Cycles' (0, 0, 0) there)
        corners = scene.uvs.take(prim, axis=0)
        bary = ((1.0 - b1 - b2)[:, None], b1[:, None], b2[:, None])
        uv = interpolate_corners(corners, bary)
        mapped = corners.reshape(len(prim), 6).any(axis=1)
        data["uv"][pix] = np.column_stack([uv, np.ones(len(pix))]) * mapped[:, None]
    if "object_index" in data and scene.object_ids is not None and scene.object_info is not None:
        data["object_index"][pix] = scene.object_info[:, 1].take(scene.object_ids.take(prim))
    if "material_index" in data and scene.materials.pass_index is not None:
        data["material_index"][pix] = scene.materials.pass_index.take(scene.material_ids.take(prim))
    aovs = [name for name in data if name.startswith(AOV_PREFIX)]
    if aovs:
        rays = Rays(wo, True)
        names = scene.materials.aov_names
        for name in aovs:
            if name[len(AOV_PREFIX):] in names:
                writes, values = ctx.aov_values(names.index(name[len(AOV_PREFIX):]), prim, b1, b2,
                                                surf.position, rays)
                data[name][pix] = np.column_stack([values, np.ones(len(pix))]) * writes[:, None]
    if "mist" in data:
        w = scene.world
        fraction = np.clip((np.sqrt(dot(offset, offset)) - w.mist_start) / max(w.mist_depth, 1e-30), 0.0, 1.0)
        data["mist"][pix] = fraction ** w.mist_falloff


def centre_data(ctx, rng, names, alpha_threshold=1.0):
    """The data passes ``names`` of ``settings.FIRST_PASS_DATA`` ("depth", "position",
    "object_index", "material_index") as Cycles takes them from its first sample, whose ray goes
    through the pixel's centre (and the lens's): {name: (n_pixels,) or (n_pixels, 3)}, of the
    surface each such ray stops on past what is transparent to it: a surface at least
    ``alpha_threshold`` opaque stops it, a more transparent one with the chance that Cycles' sample
    picks a closure other than its Transparent BSDF there (:func:`cycles_stop_chance`, by ``rng``;
    Cycles' path then scatters there); 1e10 (depth) or 0 where rays meet nothing."""
    cam = ctx.scene.camera
    x0, x1, y0, y1 = cam.window
    n_pix = (x1 - x0) * (y1 - y0)
    data = {name: (np.full(n_pix, NO_DEPTH) if name == "depth" else
                   np.zeros((n_pix, 3)) if name == "position" else np.zeros(n_pix)) for name in names}
    pix = np.arange(n_pix)
    pix, origins, dirs, tmax, _ = _camera_rays(cam, pix, np.full((n_pix, 4), 0.5))
    threshold_data(ctx, rng, data, pix, origins, dirs, tmax, alpha_threshold, past_threshold=False)
    return data


# The data passes Cycles writes at the first surface at least as opaque as the Alpha Threshold that
# a sample's transparent bounces reach (film/data_passes.h: at a more transparent one where the
# sample stops, none), and the Shader AOVs ("aov:" + name, ``settings.AOV_PREFIX``), which it
# writes there too (svm/aov.h; also at the more transparent ones crossed before it: not here).
THRESHOLD_DATA = {"normal", "uv"}


def threshold_data(ctx, rng, data, pix, origins, dirs, tmax, alpha_threshold, past_threshold=True):
    """Write the data passes ``data`` (:func:`first_hit_data`) of pixels ``pix`` as Cycles' sample
    along the camera rays ``origins + t dirs`` (t < ``tmax``) does: its transparent bounces cross a
    surface less opaque than ``alpha_threshold`` by picking its Transparent BSDF
    (:func:`cycles_stop_chance`) and go on; the first surface at least that opaque (any, at
    threshold 0) gives the passes their values.  With ``past_threshold`` (the normal and UV,
    ``THRESHOLD_DATA``) a ray that stops on a more transparent one, or meets nothing, gives 0
    (averaged over passes: through a sheet of opacity 0.3 and colour 0.8, at threshold 0.5, 0.745 of
    the wall's normal; at 0.2 the sheet's); without (the centre rays' passes, :func:`centre_data`),
    the surface it stops on gives them."""
    hits, _, opacity, _ = ctx.trace(origins, dirs, tmax, lambda rows, crossing: rng.random(len(rows)),
                                    ray_kind=np.full(len(pix), VISIBLE_CAMERA, np.uint8),
                                    alpha_threshold=alpha_threshold, stop_chance=cycles_stop_chance(ctx))
    keep = hits.is_hit & (hits.t < tmax)
    if past_threshold and opacity is not None and alpha_threshold > 0.0:
        keep &= opacity >= min(alpha_threshold, 1.0)
    h = np.flatnonzero(keep)
    if len(h):
        prim, b1, b2 = hits.prim_ids.take(h), hits.b1.take(h), hits.b2.take(h)
        wo = -dirs.take(h, axis=0)
        pick = rng.random(len(h)) if ctx.has_level_programs else None
        surf = ctx.surface(prim, b1, b2, pick, Rays(wo, True))
        first_hit_data(ctx, data, pix.take(h), surf, wo, prim, b1, b2)


def cycles_stop_chance(ctx):
    """``RenderContext.trace``'s ``stop_chance`` for the data passes' rays: Cycles' sample picks one
    closure by their sample weights (the mean of each closure's weight), so it crosses a surface of
    opacity a with the chance t / (t + a S): t = (1 - a) times the mean of the transparent colour,
    S the sum of the other lobes' sample weights at the hit (:func:`~core.bsdf.lobe_scores`), not
    with the chance 1 - a (a sheet of opacity 0.3 and colour 0.8 lets 0.745 of Cycles' samples
    through).  The image does not depend on it (Cycles weighs the pick; ours too)."""
    def chance(prim, b1, b2, rays, opacity):
        surf = ctx.surface(prim, b1, b2, None, rays)
        through = (1.0 - opacity) * ctx.transparent_color.take(surf.mat_ids, axis=0).mean(axis=1)
        kept = opacity * lobe_scores(ctx.table, surf.mat_ids, surf.colors).sum(axis=1)
        # (nothing to cross by: a black transparent colour stops it, as a closure of weight 0)
        return np.where(through > 0.0, kept / np.maximum(kept + through, 1e-30), 1.0)
    return chance


def _camera_rays(cam, pix, u):
    """(pix, origins, dirs, tmax, footprint) of :func:`~core.camera.generate_camera_rays` for pixels
    ``pix`` and numbers ``u`` (n, 4), without the pixels outside a fisheye's circle, which see
    nothing (black and opaque, as in Cycles)."""
    origins, dirs, tmax, footprint = generate_camera_rays(cam, pix, u)
    if cam.projection in PANORAMAS:
        sees = np.flatnonzero(dirs.any(axis=1))
        pix, origins, dirs = pix.take(sees), origins.take(sees, axis=0), dirs.take(sees, axis=0)
        tmax, footprint = tmax.take(sees), footprint.take(sees)
    return pix, origins, dirs, tmax, footprint


# Probes perpendicular to a camera ray from the middle of its segment in a volume (side_planes).
SIDE_PROBES = 4


def side_planes(ctx, origins, dirs, rows, t_v, ends, radius, media, position, planes):
    """(k, 2 + SIDE_PROBES) ``planes`` (the distances of the volume points ``position`` (k, 3) to the
    planes of the faces their camera rays entered and would leave their volumes by) and the
    distances to the planes of the faces of their volumes beside the rays: a gather sphere that
    reaches out of its volume through a face the ray did not cross (the top of a fog box seen
    from the side) finds no photons beyond it either, and ``photon_pass._inside_share`` takes
    every plane's cap out of the sphere.  Per segment of a ray in a volume (points of ray ``rows``
    with the same ``ends``), ``SIDE_PROBES`` probes perpendicular to the ray from the middle of
    its points look up to its points' ``radius`` for a face of its volume (``media``: a triangle
    of that material; the world's volume has none); inf where none is found, or where the face is
    one of ``planes`` already (the same distance) or another probe's (the same plane)."""
    k = len(rows)
    extra = np.full((k, SIDE_PROBES), np.inf)
    inside = media != ctx.outside
    if k == 0 or not inside.any():
        return np.concatenate([planes, extra], axis=1)
    order = np.lexsort((ends, rows))                     # (a segment's points by ray and end)
    r_sorted, e_sorted = rows.take(order), ends.take(order)
    first = np.ones(k, bool)
    first[1:] = (r_sorted[1:] != r_sorted[:-1]) | (e_sorted[1:] != e_sorted[:-1])
    seg = np.empty(k, np.int64)
    seg[order] = np.cumsum(first) - 1
    lead = order[first]                                   # (S,) a point of each segment
    count = np.bincount(seg)
    mid = np.bincount(seg, weights=t_v) / count
    d = dirs.take(rows.take(lead), axis=0)
    centre = origins.take(rows.take(lead), axis=0) + mid[:, None] * d
    u, v = orthonormal_frames(d)
    probes = np.stack([u, -u, v, -v], axis=1).reshape(-1, 3)
    starts = np.repeat(centre, SIDE_PROBES, axis=0)
    hits = ctx.accel.intersect(starts, probes, np.repeat(radius.take(lead), SIDE_PROBES))
    prim = np.maximum(hits.prim_ids, 0)
    own = hits.is_hit & (ctx.scene.material_ids.take(prim) == np.repeat(media.take(lead), SIDE_PROBES))
    own &= np.repeat(inside.take(lead), SIDE_PROBES)
    found = own.reshape(-1, SIDE_PROBES).any(axis=1).take(seg)
    pts = np.flatnonzero(found)                          # (points of segments with a face beside them)
    if len(pts) == 0:
        return np.concatenate([planes, extra], axis=1)
    at = starts + np.where(own, hits.t, 0.0)[:, None] * probes
    normal = ctx.accel.geometric_normals.take(prim, axis=0)
    p, s, crossed = position.take(pts, axis=0), seg.take(pts), planes.take(pts, axis=0)
    tol = 1e-3 * radius.take(pts)
    side = np.full((len(pts), SIDE_PROBES), np.inf)
    for j in range(SIDE_PROBES):
        r = s * SIDE_PROBES + j
        dist = np.abs(dot(p - at.take(r, axis=0), normal.take(r, axis=0)))
        keep = own.take(r)
        for c in range(crossed.shape[1]):                # (a face the ray crossed is there already)
            keep &= np.abs(dist - crossed[:, c]) > tol
        for i in range(j):                               # (and one another probe found)
            q = s * SIDE_PROBES + i
            parallel = dot(normal.take(r, axis=0), normal.take(q, axis=0)) > 0.999
            keep &= ~(parallel & (np.abs(dist - side[:, i]) <= tol))
        side[:, j] = np.where(keep, dist, np.inf)
    extra[pts] = side
    return np.concatenate([planes, extra], axis=1)


def _box_exit(origins, dirs, lo, hi):
    """(n,) the distance at which rays ``origins + t dirs`` leave the box [``lo``, ``hi``] (0 for
    those that do not cross it ahead)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        t0, t1 = (lo - origins) * inv, (hi - origins) * inv
    far = np.nan_to_num(np.maximum(t0, t1), nan=np.inf).min(axis=1)
    return np.where(np.isfinite(far), np.maximum(far, 0.0), 0.0)


def _trace_camera_paths(ctx, rng, pix, emission, alpha, initial_radius_px, limits, volume,
                        per_segment=1, data=None, alpha_threshold=1.0, coverage=None, light=None,
                        ao_distance=10.0, start=None, catcher_rays=None, jitter=None, choices=None):
    """Camera paths of pixels ``pix``: adds to ``emission``/``alpha``, returns measurement points
    (and appends the paths' :class:`VolumePoints` in scattering volumes to ``volume``,
    ``per_segment`` in each segment through one, and to the list ``coverage``, if given, the camera
    rays' Cryptomatte coverage, :func:`~core.cryptomatte.coverage`).  ``light``: None, or the
    :class:`~core.light_passes.EyeLight` that takes the emission by the paths' first scattering
    events and the colours of their first surfaces; ``ao_distance``: the Ambient Occlusion pass's
    (``data["ao"]``, :func:`ambient_occlusion`).  ``start``: None, or the rays to trace instead of
    the camera's (:func:`_catcher_starts`); ``catcher_rays``: None, or (in scenes with shadow
    catchers) the list that takes the :class:`~core.shadow_catcher.CatcherRays` of the paths
    whose first hit is a catcher and that go on through its mirror or glass lobes; the sums of the
    paths whose first hit is a catcher go to ``data``'s ``shadow_catcher.CATCHER_*``.  ``jitter``,
    ``choices``: :func:`trace_eye_pass`'s."""
    scene, accel, table = ctx.scene, ctx.accel, ctx.table
    cam = scene.camera
    if start is None:
        u = rng.random((len(pix), 4))
        if jitter is not None:
            given = jitter(pix)
            u[:, :given.shape[1]] = given
        pix, origins, dirs, tmax, footprint = _camera_rays(cam, pix, u)
        path_len = np.zeros(len(pix))
    else:
        pix, origins, dirs, tmax, footprint, path_len = start
    world = np.asarray(scene.world.color, np.float64)
    extent = accel.extent
    # The lobe colours a measurement point keeps (MeasurementPoints.colors).
    point_lobes = table.point_lobes
    grows = cam.projection != "orthographic"         # footprints grow with the distance
    beta = np.ones((len(pix), 3))
    # Which rays see analytic lights (Blender's ray visibility): direct camera rays, and after
    # a delta event rays reflected (glossy) or refracted (transmission).
    ray_kind = np.full(len(pix), VISIBLE_CAMERA, np.uint8)
    # The volume each path is in (RenderContext.trace), in scenes with volumes.
    medium = ctx.camera_medium(origins) if ctx.has_volumes else None
    # With light linking, the receiver set of the triangle each path last scattered at (None while
    # the paths are camera rays, which see every emitter).
    sets = None
    origin_normals = None       # geometric normals where the paths left their last surface
    # The bounces each path took (BounceLimits.array's order: all, diffuse, mirror and glossy
    # reflections, glass transmissions, volume), for the limits and the Light Path node; paths
    # past a limit (``last``) see emission at their next hit and end there.
    bounces = np.zeros((len(pix), 5), np.uint8)
    last = np.zeros(len(pix), bool)
    # The transparent surfaces each path crossed, where that limit binds and there are some (else None):
    # Cycles ends a path at the surface after the crossing that reached the limit (after the first
    # at 0), where it sees emission alone.
    crossed = np.zeros(len(pix), np.int16) if limits.counts_crossings and ctx.has_transparency else None
    room = limits.array
    # The kind of each path's first delta event (light passes; VIA_NONE before it).
    via = np.zeros(len(pix), np.uint8)
    grouped = light is not None and light.has_groups
    n_groups = len(scene.light_groups)
    # Shadow catchers: the paths whose first hit was one (set at that hit), and what they see after it.
    caught = None if catcher_rays is None else np.zeros(len(pix), bool)

    def to_catcher(rows, value):
        """Add ``value`` (r, 3) seen by paths ``rows`` to the catcher-hit sum where they met a catcher."""
        if caught is not None:
            c = np.flatnonzero(caught.take(rows))
            if len(c):
                data[CATCHER_HIT][pix.take(rows.take(c))] += value.take(c, axis=0)

    def world_along(rows):
        """(r, 3) the world's radiance along the paths ``rows``' rays, or None where it is black."""
        if depth == 0 and ctx.camera_background is not None:
            return ctx.camera_background(dirs[rows], origins[rows])     # (Light Path's)
        if ctx.lights.environment is not None:
            return ctx.lights.environment.radiance(dirs[rows])
        return np.broadcast_to(world, (len(rows), 3)) if world.any() else None
    parts = []
    rays = 0
    # Cycles' denoising features, made along the paths (their own random numbers: the image stays
    # the same; the albedo decides where the normal is taken and how far the depth goes).
    feature = None
    if data and "albedo" in data:
        feature = DenoisingPaths(len(pix), rng.spawn(1)[0], data["albedo"], data.get("denoising_normal"),
                                 data.get("denoising_depth"))
    # The normal and UV past transparent surfaces by the Alpha Threshold (their own rays and
    # numbers; where no surface is transparent, those of the paths' first hits).
    apart = ({k for k in data if k in THRESHOLD_DATA or k.startswith(AOV_PREFIX)}
             if data and ctx.has_transparency else set())
    if apart:
        threshold_data(ctx, rng.spawn(1)[0], {k: data[k] for k in apart}, pix, origins, dirs, tmax,
                       alpha_threshold)
    if coverage is not None:
        coverage.append(cryptomatte.coverage(ctx, pix, origins, dirs, tmax))
    for depth in range(limits.total + 2):
        if len(pix) == 0:
            break
        # A camera path stops on a transparent surface as often as it is opaque, with its weight.
        numbers = lambda rows, crossing: rng.random(len(rows))          # noqa: E731
        medium_in = medium
        glow = np.zeros((len(pix), 3)) if ctx.has_volume_emission else None
        # (light groups: what each group's emitters send, before the paths' weights)
        split = (lambda: np.zeros((n_groups, len(pix), 3))) if grouped else (lambda: None)
        glow_split = split() if glow is not None else None
        crossed_before = None if crossed is None else crossed.copy()
        hits, through, _, medium = ctx.trace(origins, dirs, tmax if depth == 0 else None, numbers, medium,
                                             ray_kind, distances=numbers, throughput=beta,
                                             origin_normals=origin_normals, forced=per_segment, glow=glow,
                                             crossings=crossed, max_crossings=max(limits.transparent, 1),
                                             glow_split=glow_split)
        if hits.forced is not None:
            # A point in every segment through a scattering volume (the path goes on through it).
            rows, t_v, w_v, ends, planes, media = hits.forced
            if last.any():
                keep = np.flatnonzero(~last.take(rows))
                rows, t_v, w_v, ends, planes, media = (a.take(keep, axis=0)
                                                       for a in (rows, t_v, w_v, ends, planes, media))
            # The gather sphere is as wide as a surface point's where the segment ends (the
            # volume's far side): a point near the camera, with a footprint-sized sphere, would
            # almost never find a photon, and then one at a huge weight.
            # A segment into the world's unbounded volume ends where it leaves the scene's box.
            far = ~np.isfinite(ends)
            if far.any():
                ends = ends.copy()
                out = rows[far]
                exit_t = _box_exit(origins.take(out, axis=0), dirs.take(out, axis=0), *accel.bounds)
                ends[far] = np.maximum(exit_t, t_v[far])
            reach = path_len.take(rows) + ends
            r1 = initial_radius_px * footprint.take(rows) * (reach if grows else 1.0)
            position = origins.take(rows, axis=0) + t_v[:, None] * dirs.take(rows, axis=0)
            r1 = np.minimum(np.maximum(r1, accel.offsets_near(position)), 0.5 * extent)
            planes = side_planes(ctx, origins, dirs, rows, t_v, ends, r1, media, position, planes)
            volume.append(VolumePoints(
                pixel_ids=pix.take(rows),
                position=position,
                wo=(-dirs.take(rows, axis=0)).astype(np.float32),
                weight=(beta.take(rows, axis=0) * w_v).astype(np.float32), mat_ids=media.astype(np.int32),
                base_radius=r1, planes=planes,
                bounces=bounces.take(rows, axis=0),
                crossings=None if crossed_before is None else crossed_before.take(rows),
                via=None if light is None else via.take(rows),
                caught=None if caught is None else caught.take(rows)))
            if feature is not None:
                back = np.asarray(cam.world_from_camera, np.float64)[:3, 2]
                feature.volume(pix, rows, w_v * ctx.scattering.take(media, axis=0),
                               w_v * ctx.extinction.take(media, axis=0), back / np.linalg.norm(back))
        beta_in = beta
        if glow is not None:
            lit = np.flatnonzero(glow.any(axis=1))             # glowing volumes on the way
            emission[pix[lit]] += beta.take(lit, axis=0) * glow.take(lit, axis=0)
            to_catcher(lit, beta.take(lit, axis=0) * glow.take(lit, axis=0))
            if feature is not None:
                feature.light(pix, lit, beta.take(lit, axis=0) * glow.take(lit, axis=0))
            if light is not None:
                light.add(pix.take(lit), beta.take(lit, axis=0) * glow.take(lit, axis=0), depth,
                          via.take(lit))
                if glow_split is not None:
                    light.add_split(pix, beta, glow_split)
        if through is not None:
            beta = beta * through                            # transparent surfaces and volumes crossed
        rays += len(pix)
        if ctx.lights.visible_to(VISIBLE_CAMERA if depth == 0 else VISIBLE_GLOSSY | VISIBLE_TRANSMISSION):
            t_max = hits.t.astype(np.float64)
            if depth == 0:
                t_max = np.minimum(t_max, tmax)
            # Lights crossed get what reaches them (not what reaches the segment's end).
            attenuation = None if through is None else (
                lambda r, t, o=origins, d=dirs, m=medium_in, k=ray_kind, c=crossed_before: ctx.factor_to(
                    o.take(r, axis=0), d.take(r, axis=0), t, None if m is None else m.take(r), k.take(r),
                    None if c is None else c.take(r), max(limits.transparent, 1)))
            seen_split = split()
            seen = ctx.lights.seen_radiance(origins, dirs, t_max, ~hits.is_hit, ray_kind, sets, attenuation,
                                            seen_split)
            lit = np.flatnonzero(seen.any(axis=1))
            emission[pix[lit]] += beta_in[lit] * seen[lit]
            to_catcher(lit, beta_in[lit] * seen[lit])
            if feature is not None:
                feature.light(pix, lit, beta_in[lit] * seen[lit])
            if light is not None:
                # (a light seen: emission; the world through its lights' sky, if any, is the world)
                light.add(pix.take(lit), beta_in[lit] * seen[lit], depth, via.take(lit))
                if seen_split is not None:
                    light.add_split(pix, beta_in, seen_split)
        # Rays that leave the scene see the world (primary ones are cut out on a transparent film,
        # as far as what they crossed lets them through: Cycles' alpha is 1 - the mean of the
        # throughput, e.g. 0.5 behind a Transparent BSDF of mean colour 0.5, 1 in world fog).
        miss = ~hits.is_hit
        if scene.world.exclude and depth:
            # A world that does not light glossy or transmission rays is black to those leaving a
            # mirror or a glass (EXCLUDE_GLOSSY and EXCLUDE_TRANSMISSION are the VISIBLE_* bits).
            miss &= (ray_kind & scene.world.exclude) == 0
        if miss.any():
            cut_out = depth == 0 and scene.world.film_transparent
            if cut_out:
                alpha[pix[miss]] = np.clip(1.0 - beta[miss].mean(axis=1), 0.0, 1.0)
            # (Cycles' Environment pass and the world's light group show the world on a transparent
            # film too)
            if not cut_out or (light is not None and ("environment" in light.sums or light.has_groups)):
                m_ = np.flatnonzero(miss)
                sky = world_along(m_)
                sky = None if sky is None else beta[m_] * sky
                if sky is not None and not cut_out:
                    emission[pix[m_]] += sky                # one path per pixel: no repeats
                    to_catcher(m_, sky)
                    if depth == 0 and caught is not None:
                        data[CATCHER_BACKGROUND][pix[m_]] += sky
                    if feature is not None:
                        feature.light(pix, m_, sky)
                if sky is not None and light is not None:
                    light.add(pix.take(m_), sky, depth, via.take(m_), background=True)
                    light.add_group(pix.take(m_), sky, scene.world.group)
        h = np.flatnonzero(hits.is_hit)
        if depth == 0 and ctx.has_holdout and len(h):
            # Holdouts cut camera rays that meet them directly out of the pixel (Cycles, with or
            # without a transparent film); a whole holdout ends the path there.
            share = ctx.holdout_at(hits.prim_ids.take(h))
            cut = h.take(np.flatnonzero(share > 0))
            alpha[pix.take(cut)] -= share[share > 0] * beta.take(cut, axis=0).mean(axis=1)
            np.maximum(alpha, 0.0, out=alpha)
            h = h.take(np.flatnonzero(share < 1.0))
        if caught is not None:
            if depth == 0:
                caught = ctx.catcher.take(hits.prim_ids.take(h))
                _catch(data, h.take(np.flatnonzero(caught)), pix, beta, world_along)
            else:
                caught = caught.take(h)
        pix, beta, dirs = pix.take(h), beta.take(h, axis=0), dirs.take(h, axis=0)
        if feature is not None:
            feature.take(h)
        via = via.take(h)
        ray_kind = ray_kind.take(h)
        bounces, last = bounces.take(h, axis=0), last.take(h)
        crossed = None if crossed is None else crossed.take(h)
        medium = None if medium is None else medium.take(h)
        sets = None if sets is None else sets.take(h)
        path_len = path_len.take(h) + hits.t.take(h)
        footprint = footprint.take(h)
        prim, b1, b2 = hits.prim_ids.take(h), hits.b1.take(h), hits.b2.take(h)
        wo = -dirs
        if ctx.reads_light_path:
            path = camera_path(ray_kind == VISIBLE_CAMERA, ray_kind == VISIBLE_GLOSSY, hits.t.take(h), depth,
                               bounces[:, 2].astype(np.int32), bounces[:, 3].astype(np.int32))
            rays_in = Rays(wo, True, path)
        else:
            rays_in = Rays(wo, True)
        surf = ctx.surface(prim, b1, b2, rng.random(len(prim)) if ctx.has_level_programs else None, rays_in)
        if depth == 0 and data:
            first = {k: v for k, v in data.items() if k not in apart}
            first_hit_data(ctx, first, pix, surf, wo, prim, b1, b2)
        # Emission seen along the path (emitters are two-sided).
        emissive = table.is_emissive.take(surf.mat_ids)
        if emissive.any():
            e = np.flatnonzero(emissive)
            seen = ctx.emitted(prim.take(e), b1.take(e), b2.take(e), surf.mat_ids.take(e),
                               surf.position.take(e, axis=0), rays_in.take(e))
            if table.has_coat:
                seen = seen * coat_attenuation(table, surf, wo, e)
            if table.has_sheen:
                seen = seen * sheen_dim(table, surf, wo, e)[:, None]
            if sets is not None:
                seen = seen * linked(ctx.emitter_links.take(prim.take(e)), sets.take(e))[:, None]
            emission[pix[e]] += beta[e] * seen
            to_catcher(e, beta[e] * seen)
            if feature is not None:
                feature.light(pix, e, beta[e] * seen)
            if light is not None:
                light.add(pix.take(e), beta[e] * seen, depth, via.take(e))
                if grouped and scene.emitter_group is not None:
                    light.add_group(pix.take(e), beta[e] * seen, scene.emitter_group.take(prim.take(e)))
        if depth == 0 and light is not None and light.colours:
            # Cycles' colour passes at the first surface (reached through transparent ones).
            albedos = colour_albedos(table, surf, wo, np.arange(len(pix)), rng.spawn(1)[0])
            light.add_colours(pix, {k: beta * v for k, v in albedos.items()})
        if depth == 0 and data and "ao" in data:
            ao = ambient_occlusion(ctx, surf, prim, wo, medium, ao_distance, rng.spawn(1)[0])
            data["ao"][pix] += beta * ao
        if feature is not None:
            feature.surface(table, surf, wo, pix, hits.t.take(h))
        # Choose a lobe: non-delta ends the path at a measurement point, delta continues it.
        scores = lobe_scores(table, surf.mat_ids, surf.colors)
        if table.has_coat:
            # The coat or what lies under it (with its factor at the view direction wo).
            mats, colors, scores, layer_scale, under, _ = pick_coat(table, surf.mat_ids, surf.colors, scores,
                                                                    rng.random(len(pix)))
            beta = beta * layer_scale[:, None]
            if len(under):
                beta[under] *= coat_attenuation(table, surf, wo, under)
            surf = dataclasses.replace(surf, ns=coat_normals(surf, mats), mat_ids=mats, colors=colors)
        u = rng.random((len(pix), 3))
        if choices is not None:
            u = choices(pix, depth)     # (the stream's numbers drawn all the same: the rest keep theirs)
        non_delta = scores[:, DIFFUSE] + scores[:, GLOSSY]
        if table.has_translucent:
            non_delta = non_delta + scores[:, TRANSLUCENT]
        if table.has_sheen:
            non_delta = non_delta + scores[:, SHEEN]
        total = non_delta + scores[:, MIRROR] + scores[:, DIELECTRIC]     # columns: sum(axis=1) is slow
        through = None
        if table.has_glossy_through:
            # Camera paths go on through smooth glossy lobes without a diffuse lobe beside them (a
            # direction sampled from the lobe), as through a mirror: photons could hardly find
            # such narrow lobes (Cycles' default coat roughness is 0.03), and the path then sees
            # lights and the world in them (benchmarks/glossy_through.py).
            through = table.glossy_through.take(surf.mat_ids)
            non_delta = np.where(through, 0.0, non_delta)
        p_nd = np.where(total > 0, non_delta / np.where(total > 0, total, 1), 0)
        if depth == 0 and start is not None:
            # Rays traced again for the catchers' render went on through the catcher's mirror or
            # glass lobes in the main render: so do they here, with the same weight (a lobe chosen
            # afresh would add the catcher's non-delta part to K once more).
            u[:, 0] = np.where(p_nd < 1.0, p_nd + u[:, 0] * (1.0 - p_nd), u[:, 0])
        stop = (u[:, 0] < p_nd) & ~last
        if stop.any():
            s = np.flatnonzero(stop)
            rows = lambda a: a.take(s, axis=0)                      # noqa: E731
            ng = face_forward(rows(surf.ng), rows(wo))
            r1 = initial_radius_px * rows(footprint) * (rows(path_len) if grows else 1.0)
            f32 = np.float32
            ns = face_forward(rows(surf.ns), ng)
            ns_glossy = None
            if surf.nn is not None:
                # Cycles keeps a bent normal's reflection of the view valid for glossy lobes.
                point_mats = rows(surf.mat_ids)
                bent = table.normal_mapped.take(point_mats) & table.bump_correction.take(point_mats)
                ns_glossy = ns.copy()
                ns_glossy[bent] = valid_reflection_normal(ng[bent], rows(wo)[bent], ns[bent])
                ns_glossy = ns_glossy.astype(f32)
            points = MeasurementPoints(
                pixel_ids=rows(pix), position=rows(surf.position), ng=ng.astype(f32),
                ns=ns.astype(f32), wo=rows(wo).astype(f32),
                weight=(rows(beta) / rows(p_nd)[:, None]).astype(f32), mat_ids=rows(surf.mat_ids),
                colors=rows(surf.colors)[:, point_lobes].astype(f32),
                base_radius=np.minimum(np.maximum(r1, accel.offsets_near(rows(surf.position))), 0.5 * extent),
                nn=None if surf.nn is None else face_forward(rows(surf.nn), ng).astype(f32),
                ns_glossy=ns_glossy,
                tangent=None if surf.tangent is None else rows(surf.tangent).astype(f32),
                bounces=rows(bounces), crossings=None if crossed is None else rows(crossed),
                via=None if light is None else rows(via), caught=None if caught is None else rows(caught),
                prim=rows(prim))
            if ctx.subsurface_exit >= 0:
                # Some points go beneath their surface, to the exit of a random walk.
                points, exits, r = _beneath(ctx, rng, points, rows(prim), rows(scores[:, DIFFUSE]),
                                            rows(non_delta))
                rays += r
                if exits is not None:
                    parts.append(exits)
            parts.append(points)
        go = np.flatnonzero(~stop & (total > 0) & ~last)
        if depth == 0 and caught is not None:
            # The camera rays of the paths that go on through a catcher's mirror or glass lobe: the
            # catchers' render traces them again (those that stopped there give it their points).
            g = go.take(np.flatnonzero(caught.take(go)))
            if len(g):
                first = h.take(g)
                catcher_rays.append(CatcherRays(pix.take(g), origins.take(first, axis=0),
                                                dirs.take(g, axis=0), hits.t.take(first).astype(np.float64),
                                                footprint.take(g)))
        if len(go) == 0:
            if feature is not None:
                feature.settle(pix, go)
            break
        # Continue through the delta lobes only (rescale the lobe number into the delta range).
        delta_scores = scores[go].copy()
        delta_scores[:, [DIFFUSE, GLOSSY]] = 0.0
        if table.has_translucent:
            delta_scores[:, TRANSLUCENT] = 0.0
        if table.has_sheen:
            delta_scores[:, SHEEN] = 0.0
        if through is not None:
            delta_scores[:, GLOSSY] = np.where(through[go], scores[go, GLOSSY], 0.0)
        u_delta = (u[go, 0] - p_nd[go]) / np.maximum(1.0 - p_nd[go], 1e-300)
        u_delta = np.clip(u_delta, 0.0, np.nextafter(1.0, 0.0))
        lobe, prob = choose_lobe(delta_scores, u_delta)
        u3 = lobe_remainder(delta_scores, u_delta, lobe) if table.has_rough_dielectric else None
        prob = prob * (1.0 - p_nd[go])
        wi, weight, alive = scatter(table, surf.mat_ids[go], surf.colors[go], lobe, prob, wo[go],
                                    surf.ng[go], surf.ns[go], u[go, 1], u[go, 2], "radiance", u3,
                                    tangent=None if surf.tangent is None else surf.tangent[go])
        keep = np.flatnonzero(alive)
        g = go[keep]
        reflected = dot(wi[keep], surf.ng[g]) * dot(wo[g], surf.ng[g]) > 0
        ray_kind = np.where(reflected, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION).astype(np.uint8)
        bounces = bounces[g]
        crossed = None if crossed is None else crossed[g]
        via = via[g]
        caught = None if caught is None else caught[g]
        via[via == VIA_NONE] = np.where(reflected, VIA_GLOSSY, VIA_TRANSMISSION)[via == VIA_NONE]
        bounces[:, 0] += 1
        bounces[:, 2] += reflected
        bounces[:, 3] += ~reflected
        last = (bounces > room).any(axis=1)
        if medium is not None:
            medium = ctx.next_medium(medium[g], prim[g], wi[keep], wo[g])
        if ctx.receiver_sets is not None:
            sets = ctx.receiver_sets.take(prim[g])
        if feature is not None:
            feature.settle(pix, g)
            feature.take(g)
        pix, beta, dirs = pix[g], beta[g] * weight[keep], wi[keep]
        path_len, footprint = path_len[g], footprint[g]
        origins = accel.spawn(surf.position[g], surf.ng[g], dirs, prim[g])
        origin_normals = surf.ng[g]
    return parts, rays


def _beneath(ctx, rng, points, prim, diffuse_score, non_delta):
    """(points, exits, rays): ``points`` (k, at hits of triangles ``prim``) of which those of
    materials that scatter beneath their surface (``Materials.subsurface_weight``) go there with
    the probability of that part's share of their non-delta choice (their lobes' scores
    ``diffuse_score`` and ``non_delta``, both (k,)): they are replaced by a point at the exit of a
    random walk (``core/subsurface.py``) that gathers as a white Lambertian surface (the material
    ``RenderContext.subsurface_exit``), of weight the subsurface part's at the entry, which Cycles
    gives as its share of the diffuse lobe, under the Fresnel layer at the view; the others keep
    their diffuse lobe without that part.  Walks that do not leave within ``subsurface.MAX_STEPS``
    (or that start away from the surface) are lost, as in Cycles."""
    mats, table, accel = ctx.materials, ctx.table, ctx.accel
    m = points.mat_ids
    share = np.asarray(mats.subsurface_weight, np.float64).take(m)
    rows = np.flatnonzero(share > 0)
    if len(rows) == 0:
        return points, None, 0
    mr = m.take(rows)
    radius = np.asarray(mats.subsurface_radius, np.float64).take(mr, axis=0)
    part = share.take(rows)[:, None] * (radius >= subsurface.MIN_RADIUS)          # (r, 3)
    q = np.clip(part.mean(axis=1) * diffuse_score.take(rows) / np.maximum(non_delta.take(rows), 1e-300),
                0.0, 1.0)
    u = rng.random((len(rows), 4))
    into = u[:, 0] < q
    stay = np.flatnonzero(~into)
    colors, weight = points.colors.copy(), points.weight.copy()
    colors[rows[stay], 0] *= (1.0 - part[stay]).astype(np.float32)
    weight[rows[stay]] /= (1.0 - q[stay, None]).astype(np.float32)
    go = np.flatnonzero(into)
    w_rows, mg = rows.take(go), mr.take(go)
    keep = np.ones(points.count, bool)
    keep[w_rows] = False
    kept = dataclasses.replace(points, colors=colors, weight=weight).take(np.flatnonzero(keep))
    if len(go) == 0:
        return kept, None, 0
    # The part's weight: the diffuse lobe's share (under a Fresnel layer, its factor at the view)
    # without the colour, which the walk makes.
    w_d = table.weight[mg, DIFFUSE]
    if table.has_layer:
        mu = dot(points.wo[w_rows], points.glossy_normals[w_rows]).astype(np.float64)
        w_d = w_d * table.layer_factor(mg, mu)
    method = np.asarray(mats.subsurface_method).take(mg)
    sigma_t, alpha, scale = subsurface.medium(
        points.colors[w_rows, 0], radius.take(go, axis=0), np.asarray(mats.subsurface_anisotropy).take(mg),
        method, np.asarray(mats.subsurface_ior, np.float64).take(mg))
    beta = (points.weight[w_rows] / q.take(go)[:, None] * part.take(go, axis=0) * w_d[:, None] * scale)
    n, ng = points.ns[w_rows].astype(np.float64), points.ng[w_rows].astype(np.float64)
    dirs, valid = subsurface.entry_directions(n, ng, points.wo[w_rows].astype(np.float64),
                                              *subsurface.entry(mats, mg), u[go, 1:])
    ok = np.flatnonzero(valid)
    objects = None if accel.object_ids is None else accel.object_ids.take(prim.take(w_rows.take(ok)))
    rays = 0

    def intersect(r, origins, d, tmax):
        nonlocal rays
        rays += len(r)
        if objects is None:
            return accel.intersect(origins, d, tmax)
        return accel.local_scene().intersect(origins, d, tmax, objects.take(r))
    starts = accel.spawn_local(points.position[w_rows[ok]], ng.take(ok, axis=0), dirs.take(ok, axis=0),
                               prim.take(w_rows.take(ok)))
    left, hits, d_out, beta_out = subsurface.random_walk(
        intersect, starts, dirs.take(ok, axis=0), n.take(ok, axis=0), sigma_t.take(ok, axis=0),
        alpha.take(ok, axis=0),
        np.asarray(mats.subsurface_anisotropy, np.float64).take(mg.take(ok)), beta.take(ok, axis=0),
        lambda r, step: rng.random((len(r), subsurface.WALK_NUMBERS)))
    if len(left) == 0:
        return kept, None, rays
    src = w_rows.take(ok.take(left))
    pick = rng.random(len(left)) if ctx.has_level_programs else None
    surf = ctx.surface(hits.prim_ids, hits.b1, hits.b2, pick, Rays(d_out))
    # Seen from outside, as Cycles turns the walk's last ray round.
    ng_out = face_forward(surf.ng, d_out)
    ns_out = face_forward(surf.ns, ng_out).astype(np.float32)
    f32 = np.float32
    colors = np.zeros((len(left),) + points.colors.shape[1:], f32)
    colors[:, 0] = 1.0
    exits = MeasurementPoints(
        pixel_ids=points.pixel_ids.take(src), position=surf.position, ng=ng_out.astype(f32), ns=ns_out,
        wo=ng_out.astype(f32), weight=beta_out.astype(f32),
        mat_ids=np.full(len(left), ctx.subsurface_exit, points.mat_ids.dtype), colors=colors,
        base_radius=points.base_radius.take(src),
        nn=None if points.nn is None else ns_out, ns_glossy=None if points.ns_glossy is None else ns_out,
        tangent=None if points.tangent is None else np.zeros((len(left), 3), f32),
        bounces=None if points.bounces is None else points.bounces.take(src, axis=0),
        crossings=None if points.crossings is None else points.crossings.take(src),
        via=None if points.via is None else points.via.take(src),
        caught=None if points.caught is None else points.caught.take(src), prim=hits.prim_ids)
    return kept, exits, rays


def coat_normals(surf, mats):
    """Shading normals at hits whose materials ``mats`` (after :func:`~core.bsdf.pick_coat`) may be
    coats: the coat's own there (:func:`coat_normal`)."""
    if surf.nn is None:
        return surf.ns
    return np.where((mats != surf.mat_ids)[:, None], coat_normal(surf), surf.ns)


def coat_normal(surf):
    """(n, 3) the coats' normals at ``surf``: the normal before normal and bump maps, which do not
    bend a coat, unless the coat has its own (``Surface.nc``)."""
    if surf.nc is not None:
        return surf.nc
    return surf.ns if surf.nn is None else surf.nn


def sheen_dim(table, surf, wo, rows):
    """(k,) the sheens' factor (:meth:`~core.bsdf.MaterialTable.sheen_dim`) at hits ``rows`` of
    ``surf`` seen from ``wo`` (n, 3), with the shading normal."""
    return table.sheen_dim(surf.mat_ids.take(rows), dot(wo.take(rows, axis=0), surf.ns.take(rows, axis=0)))


def coat_attenuation(table, surf, wo, rows, albedo_only=False):
    """(k, 3) factors under the coats at hits ``rows`` of ``surf`` seen from ``wo`` (rows whose
    materials have no coat get 1): :meth:`~core.bsdf.MaterialTable.coat_attenuation` at the view
    cosine with the coat's normal (:func:`coat_normal`); with ``albedo_only`` (k,) the coat's
    albedo's part of them (:meth:`~core.bsdf.MaterialTable.coat_layer_factor`)."""
    mats = surf.mat_ids.take(rows)
    out = np.ones(len(rows)) if albedo_only else np.ones((len(rows), 3))
    coated = np.flatnonzero(table.coat_row.take(mats) >= 0)
    if len(coated):
        r = rows.take(coated)
        n_c = coat_normal(surf).take(r, axis=0)
        mu = np.abs(dot(wo.take(r, axis=0), n_c))
        factor = table.coat_layer_factor if albedo_only else table.coat_attenuation
        out[coated] = factor(mats.take(coated), mu)
    return out


def _empty_points():
    z3 = np.zeros((0, 3), np.float32)
    return MeasurementPoints(np.zeros(0, np.int64), np.zeros((0, 3)), z3, z3, z3, z3,
                             np.zeros(0, np.int32), np.zeros((0, 2, 3), np.float32), np.zeros(0),
                             prim=np.zeros(0, np.int32))


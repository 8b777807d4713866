"""Photon tracing as a deterministic function of a primary sample, with deposits.

A photon path is a function of u in [0, 1)^d with a fixed stride
(``algorithm.md`` 4): six light dimensions, then four per bounce
``[lobe, direction 0, direction 1, Russian roulette]``, so d = 6 + 4 B for at
most B scattering events.  The path deposits at every vertex whose material has
a non-delta lobe, including the first hit, and is *visible* (V(u) = 1) when any
deposit finds a measurement point (the same test as the deposit itself) or, for the
Markov chains, when a non-delta vertex lies in the target's visible cells: a set that
holds still between passes (``core/visible_cells.py``).  With cells, V is the cells
alone; paths that deposit outside them (at points seen through a glass ball, whose cells
are left out) count through the uniform samples instead (``core/mcmc.py``, "Two parts").

The contribution of photon p to measurement point j (pixel of j) is::

    w_j f_j(wo_j, wi_p) |cos_s| / |cos_g| Phi_p / (pi r_j^2)

with wi_p pointing back along the photon; dividing by the number of recorded
photons gives one pass's radiance estimate (Knaus & Zwicker 2011).

Low-dimension mutation (Watanabe et al.): when ``refresh_rng`` is given, a path
that becomes visible at a vertex gets every dimension from that vertex's
scattering block onwards redrawn uniformly, in place in ``u``, before it is used.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import cached_property

import numpy as np

from .bsdf import (DIELECTRIC, DIFFUSE, GLOSSY, SHEEN, TRANSLUCENT, bump_shadowing, choose_lobe, eval_glossy,
                   face_forward, glossy_anisotropic_value, lobe_remainder, lobe_scores, pick_coat,
                   refraction_scale, rough_diffuse_factor, rough_diffuse_terms, scatter, sheen_frame,
                   sheen_value)
from . import subsurface
from .context import MAX_TRANSPARENT_CROSSINGS, Surface
from .eye_pass import MeasurementPoints, VolumePoints, coat_attenuation, coat_normals
from .hash_grid import HashGrid
from .light_passes import VIA_GLOSSY, VIA_NONE, VIA_TRANSMISSION
from .lights import LIGHT_DIMS, Focus
from .phase import isotropic as isotropic_phase, sample as sample_phase, value as phase_value
from .procedural import Rays, photon_path
from .scene import EXCLUDE_DIFFUSE, EXCLUDE_GLOSSY, EXCLUDE_SCATTER, EXCLUDE_TRANSMISSION
from .settings import BounceLimits
from .shadow_catcher import CATCHER_HIT
from .sampling import cosine_hemisphere, dot, luminance, tangent_axes, to_world
from .texture_hash import float_as_uint, hash_uint3, hash_uint3_to_float
from .visible_cells import NEVER, VisibleCells

ISOTROPIC_PHASE = 1.0 / (4.0 * np.pi)      # hg_phase at g = 0, to the bit

BOUNCE_DIMS = 4


# Keys of the hashed numbers for the distances in scattering volumes (after the crossings'), and
# for the pick of a material's level at a surface vertex (Materials.level_program).
DISTANCE_KEYS = 1 << 24
LEVEL_KEYS = 1 << 25
# ... and for the random walks beneath surfaces (_walk_uniforms).
WALK_KEYS = 1 << 26


def _crossing_uniforms(u, idx, bounce, base=0):
    """``RenderContext.trace``'s numbers for the photons of paths ``idx`` at vertex ``bounce``: a
    hash of their light position dimensions, the vertex and the crossing, so that a path stays a
    function of its primary sample (the chains' mutations need that), yet no dimension is used
    twice.  With ``base`` = DISTANCE_KEYS, the numbers for the distances in scattering volumes
    (per segment: a crossing starts a new one).  A mutation of the light's position dimensions
    draws them anew; the other dimensions leave them as they are."""
    def uniforms(rows, crossing):
        paths = idx.take(rows)
        stride = MAX_TRANSPARENT_CROSSINGS + (1 if base else 0)       # segments: one more than crossings
        key = np.full(len(rows), base + bounce * stride + crossing, np.uint32)
        r = hash_uint3_to_float(float_as_uint(u[paths, 1]), float_as_uint(u[paths, 2]), key)
        return np.minimum(r, 1.0 - 2.0 ** -33)
    return uniforms


def path_dims(max_bounces: int) -> int:
    """Dimensions of a photon path's primary sample."""
    return LIGHT_DIMS + BOUNCE_DIMS * max_bounces


def bounce_offset(bounce: int) -> int:
    """First dimension of the scattering block at vertex ``bounce`` (0 = first surface hit)."""
    return LIGHT_DIMS + BOUNCE_DIMS * bounce


class DepositTarget:
    """The measurement points of one pass, gridded, with their per-point kernel weights.

    Volume points (:class:`~core.eye_pass.VolumePoints`) follow the m surface points in the
    numbering of the sums: point m + k is volume point k.  With ``light_passes`` the pairs of the
    points whose camera paths met no delta event (``split``) are spread over three more blocks of
    slots after those n_points: the pairs of photons at their first vertex go to the direct block
    (n_points slots) instead, and the glossy lobe's part of a pair to the glossy block (m slots), or
    at the first vertex to the direct glossy block (m slots), the rest staying where it would go
    (:meth:`route_pairs`); what a point gathered is the sum of its slots (:meth:`to_pixels`), and
    :meth:`pass_pixels` makes Cycles' light passes of them (``core/light_passes.py``).  With
    ``inner`` the pairs within half surface point j's radius are deposited a second time, whole, on
    slot ``inner_slots + j`` of the sums (m slots after all those), for the second estimate at
    half the radius (:meth:`inner_pixels`, ``RenderSettings.bias_correction``).  With
    ``light_groups`` a pair whose photon comes from an emitter of a light group asked for is also
    copied, whole, to that group's block of n_points slots after those (``group_slots``,
    :meth:`group_pairs`), and with ``inner`` those within half the radius once more to the group's
    inner block of m slots after all the groups' (``group_inner_slots``), for each group's own
    estimate at half the radius (:meth:`group_inner_pixels`); but the pairs of the ``derived``
    group (that of most photons, if any) are not copied: its block takes those of the photons of
    emitters in no group asked for instead, and its pass is what the points gathered less all the
    blocks.  ``n_slots`` slots in all.  The pairs on the slots before ``inner_slots`` are the ones
    that count towards a splat (:class:`PointSums`)."""

    def __init__(self, points, radius, table, n_pixels, has_shading_normals, grid=None, cells=None,
                 volume=None, volume_radius=None, volume_grid=None, media=None, inner=False,
                 coverage=None, inner_coverage=None, limits=None, light_passes=(), light_groups=None,
                 direct=None, direct_points=None, focus=None):
        """points : MeasurementPoints; radius : (m,) float64 current gather radii r_j;
        table : the scene's material table; cells : None, or the :class:`VisibleCells` that
        then alone make a path visible (Markov chains; see ``core/visible_cells.py``);
        volume : VolumePoints with at least one point, or None; volume_radius : (k,) their
        radii; media : (M, phase.ROW) float64 the materials' phase functions (``core/phase.py``, for
        the volume points);
        inner : also sum the pairs within half the radius (see the class docstring);
        coverage, inner_coverage : None, or (m,) the share of each point's disc (of the radius,
        of half of it) that lies on a surface (``core/coverage.py``): the kernel's area is
        that share of pi r^2; limits : None (no limits), or the render's
        :class:`~core.settings.BounceLimits`, which pairs must keep to (:meth:`bounce_filter`);
        light_passes : the photon passes (``light_passes.PHOTON_PASSES``) to make, or ();
        light_groups : None, or (the light group passes to make, the index of each of the scene's
        light groups among them or -1, the pass derived from the others or -1[, the passes whose
        groups' emitters send photons]), the first two as :func:`~core.light_passes.light_groups`
        returns them, the others :func:`~core.light_passes.photon_groups`'; direct : None, or (count,)
        bool per emitter (``LightSampler`` entries): those whose light the points sample
        (``core/direct.py``), whose photons then deposit nothing at their first vertex on the points
        ``direct_points`` ((m,) bool; None: all surface points); focus : None, or the
        :class:`~core.lights.Focus` the photons from afar are aimed at (the same for every pass of a
        render)."""
        self.points = points
        self.focus = focus
        self.direct = None if direct is None else np.asarray(direct, bool)
        self.direct_points = None if direct_points is None else np.asarray(direct_points, bool)
        # The render's light samples at these points and their time (statistics; core/direct.py).
        self.light_samples, self.light_sample_s = 0, 0.0
        self.coverage, self.inner_coverage = coverage, inner_coverage
        self.inner = bool(inner)
        self.volume = volume if volume is not None and volume.count else None
        self.volume_radius = volume_radius
        self.media = media
        if self.volume is not None and volume_grid is None:
            volume_grid = HashGrid(self.volume.position, volume_radius, None)
        self.volume_grid = volume_grid if self.volume is not None else None
        self.n_points = points.count + (0 if self.volume is None else self.volume.count)
        self.light_passes = tuple(light_passes)
        self.split = None
        self.inner_slots = self.n_points
        if self.light_passes:
            # Blocks: photons at their first vertex, glossy parts, glossy parts at the first vertex.
            self.direct_slots = self.n_points
            self.glossy_slots = self.direct_slots + self.n_points
            self.direct_glossy_slots = self.glossy_slots + points.count
            self.inner_slots = self.direct_glossy_slots + points.count
            self.split = np.concatenate([np.ones(p.count, bool) if p.via is None else p.via == VIA_NONE
                                         for p in (points, self.volume) if p is not None])
        self.n_slots = self.inner_slots + (points.count if self.inner else 0)   # (no inner volume slots)
        # Light groups: a block of n_points slots for each group pass that can have pairs (``live``:
        # those of groups whose emitters send photons, and the derived one; the others are left
        # out of pass_pixels), ``block_of`` pass -> block (-1: none); per group of the scene and
        # for emitters in none (first), the block its photons' pairs are copied to (-1: none).
        self.group_passes, self.group_blocks, self.derived, self.copy_to = (), None, -1, None
        self.block_of, self.n_blocks = np.zeros(0, np.int64), 0
        if light_groups is not None and len(light_groups[0]):
            self.group_passes = tuple(light_groups[0])
            self.group_blocks = np.asarray(light_groups[1], np.int64)
            self.derived = int(light_groups[2])
            live = np.ones(len(self.group_passes), bool)
            if len(light_groups) > 3:
                live[:] = False
                live[np.asarray(light_groups[3], np.int64)] = True
            if self.derived >= 0:
                live[self.derived] = True
            self.n_blocks = int(live.sum())
            self.block_of = np.where(live, np.cumsum(live) - 1, -1)
            passes = self.group_blocks
            rest = self.derived
            copy_to = np.concatenate([[rest], np.where(passes < 0, rest,
                                                       np.where(passes == self.derived, -1, passes))])
            self.copy_to = np.where(copy_to >= 0, self.block_of.take(np.maximum(copy_to, 0)), -1)
        self.group_slots = self.n_slots
        self.n_slots += self.n_blocks * self.n_points
        # Shadow catchers: per point (surface, then volume) whether its camera path met one first
        # (MeasurementPoints.caught), or None; their photons make CATCHER_HIT (pass_pixels).
        self.caught = None
        if points.caught is not None:
            self.caught = np.concatenate([p.caught for p in (points, self.volume) if p is not None])
        self.group_inner_slots = self.n_slots
        if self.inner:
            self.n_slots += self.n_blocks * points.count
        self.cells = cells
        self.radius = radius
        self.grid = grid if grid is not None else HashGrid(points.position, radius, points.ng)
        self.n_pixels = n_pixels
        self.pixel_ids = points.pixel_ids
        self.has_shading_normals = has_shading_normals
        self.table = table
        self.limits = limits
        # Per point (surface, then volume): the bounces its photons may take in all and of each
        # kind (limits less the camera path's); None where no pair can go past a limit (no
        # limit of a kind binds and no camera path bounced).
        self.room = None
        self.counts_kinds = limits is not None and limits.by_kind
        # A Caustics toggle off: photons keep what a diffuse event next is worth (trace_photons).
        self.blocks_caustics = limits is not None and limits.blocks_caustics
        if limits is not None:
            taken = np.concatenate([np.zeros((p.count, 5), np.uint8) if p.bounces is None else p.bounces
                                    for p in (points, self.volume) if p is not None])
            if self.counts_kinds or taken[:, 0].any():
                self.room = limits.array - taken.astype(np.int16)
        # Per point (surface, then volume): the transparent surfaces its photons may cross (Cycles'
        # Transparent bounces less the camera path's crossings), where that limit binds and the
        # camera paths counted them (in scenes with transparent surfaces); else None.
        self.crossing_room = None
        parts = [p for p in (points, self.volume) if p is not None]
        if limits is not None and limits.counts_crossings and any(p.crossings is not None for p in parts):
            crossed = np.concatenate([np.zeros(p.count, np.int16) if p.crossings is None else p.crossings
                                      for p in parts])
            self.crossing_room = (limits.transparent - crossed.astype(np.int32)).astype(np.int32)
            # (Cycles at 0 still shades a vertex no crossing came before: its limit before the
            # vertex nearest the light is max(N - 1, 0))
            self._shading_room = self.crossing_room - (1 if limits.transparent > 0 else 0)
        # Points with a normal map (Cycles' bump-map terms in pair_weights), or None.
        bumped = table.normal_mapped.take(points.mat_ids) if table.has_normal_maps else None
        self.bumped = bumped if bumped is not None and bumped.any() else None
        glossy = table.has_glossy.take(points.mat_ids)
        # Points with a glossy lobe; with a sheen, or None; and those whose pairs carry their
        # whole weight (is_glossy: either).
        self.glossy_lobe = glossy
        sheened = table.weight[:, SHEEN].take(points.mat_ids) > 0 if table.has_sheen else None
        self.sheened = sheened if sheened is not None and sheened.any() else None
        self.is_glossy = glossy if self.sheened is None else glossy | self.sheened
        self.any_glossy = bool(self.is_glossy.any())
        self.alpha = table.alpha.take(points.mat_ids)
        # Points whose glossy lobe has Beckmann microfacets (None: all GGX).
        self.beckmann = _some(None if table.glossy_beckmann is None
                              else table.glossy_beckmann.take(points.mat_ids))
        # Points of anisotropic glossy lobes (None: none), evaluated in their tangents' frames.
        self.anisotropic = _some(glossy & table.anisotropic.take(points.mat_ids) if table.has_anisotropy
                                 else None)
        if self.anisotropic is not None:
            # Per point: the alphas, the tangent in the glossy normal's plane (x) and wo . x
            # (float32 as the points: 24 bytes a point in scenes with anisotropy).
            a = np.flatnonzero(self.anisotropic)
            mats = points.mat_ids.take(a)
            self._alpha_x = np.zeros(points.count, np.float32)
            self._alpha_y = np.zeros(points.count, np.float32)
            self._alpha_x[a], self._alpha_y[a] = table.alpha_x.take(mats), table.alpha_y.take(mats)
            self._x = np.zeros((points.count, 3), np.float32)
            self._x[a] = tangent_axes(points.glossy_normals.take(a, axis=0),
                                      points.tangent.take(a, axis=0))
            self._wo_x = np.zeros(points.count, np.float32)
            self._wo_x[a] = dot(points.wo.take(a, axis=0), self._x.take(a, axis=0))
        # Glossy points whose colour rises with the Fresnel factor of the pair's half vector: their
        # pairs carry the whole colour, and to_pixels does not multiply by one.
        rising = glossy & table.rises[:, GLOSSY].take(points.mat_ids) if table.has_fresnel else None
        self.rising = rising if rising is not None and rising.any() else None
        if self.rising is not None:
            # Per material: the glossy colour is const + table.fresnel_color(wo.h); 1 + 0 where
            # the colour is constant (to_pixels multiplies by it instead).
            self._const = np.where(table.rises[:, GLOSSY, None], table.color[:, GLOSSY], 1.0)
        # The glossy colours of the points, where some metal's curve follows its colour at each
        # hit (their F0: ``MaterialTable.hit_metal``); None otherwise.
        self._hit_base = None
        if self.rising is not None and table.has_hit_metal and (table.hit_metal.take(points.mat_ids)
                                                                & self.rising).any():
            self._hit_base = points.colors[:, 1]
        # Points of translucent materials, or None: photons that land on the other side of their
        # surface reach them through the translucent lobe (``back`` pairs).  Points of rough diffuse
        # materials, or None: their diffuse pairs weigh by the directions (rough_diffuse_factor).
        # The diffuse pairs of either carry their colour (``coloured``; to_pixels multiplies by 1).
        self.translucent = _some(table.translucent.take(points.mat_ids) if table.has_translucent else None)
        self.rough = _some(table.is_rough_diffuse.take(points.mat_ids) if table.has_rough_diffuse else None)
        either = table.has_translucent or table.has_rough_diffuse
        self.coloured = _some((table.translucent | table.is_rough_diffuse).take(points.mat_ids) if either
                              else None)

    def _glossy_mixed(self, jg, g, wi, nsg):
        """(f, wo.h) of the glossy pairs ``g`` (points ``jg``, glossy normals ``nsg``) where some
        points' lobes are anisotropic (:func:`~core.bsdf.glossy_anisotropic_value`, per-point
        parts precomputed)."""
        f, cos_h = np.zeros(len(g)), np.zeros(len(g))
        aniso = self.anisotropic.take(jg)
        wo = self.points.wo
        for sel, is_aniso in ((np.flatnonzero(~aniso), False), (np.flatnonzero(aniso), True)):
            if len(sel) == 0:
                continue
            js, wi_s, n_s = jg.take(sel), wi.take(g.take(sel), axis=0), nsg.take(sel, axis=0)
            wo_s = wo.take(js, axis=0)
            if is_aniso:
                f[sel], cos_h[sel] = glossy_anisotropic_value(
                    self._alpha_x.take(js), self._alpha_y.take(js), dot(wo_s, n_s), dot(wi_s, n_s),
                    dot(wo_s, wi_s), self._wo_x.take(js), dot(wi_s, self._x.take(js, axis=0)),
                    self._beckmann(js))
            else:
                f[sel], cos_h[sel] = eval_glossy(self.alpha.take(js), wo_s, wi_s, n_s, with_cos_h=True,
                                                 beckmann=self._beckmann(js))
        return f, cos_h

    def _beckmann(self, j):
        """(k,) bool: points ``j`` have Beckmann glossy lobes; None where no point has."""
        return None if self.beckmann is None else self.beckmann.take(j)

    def to_arrays(self) -> dict:
        """Plain arrays for a worker process (see :meth:`from_arrays`)."""
        d = {f"points.{f}": getattr(self.points, f) for f in MeasurementPoints.__dataclass_fields__
             if getattr(self.points, f) is not None}
        d.update({f"grid.{k}": v for k, v in self.grid.to_arrays().items()})
        d.update(radius=self.radius, n_pixels=np.int64(self.n_pixels),
                 has_shading_normals=np.bool_(self.has_shading_normals), inner=np.bool_(self.inner),
                 light_passes=np.array(self.light_passes, dtype=str))
        if self.group_passes:
            d.update(group_passes=np.array(self.group_passes, dtype=str), group_blocks=self.group_blocks,
                     derived_group=np.int64(self.derived),
                     live_groups=np.flatnonzero(self.block_of >= 0))
        for name in ("coverage", "inner_coverage"):
            if getattr(self, name) is not None:
                d[name] = getattr(self, name)
        if self.cells is not None:
            d.update({f"cells.{k}": v for k, v in self.cells.to_arrays().items()})
        if self.limits is not None:
            d.update({f"limits.{k}": np.asarray(v) for k, v in asdict(self.limits).items()})
        if self.direct is not None:
            d["direct"] = self.direct
        if self.direct_points is not None:
            d["direct_points"] = self.direct_points
        if self.focus is not None:
            d["focus"] = self.focus.to_array()
        if self.volume is not None:
            d.update({f"volume.{f}": getattr(self.volume, f) for f in VolumePoints.__dataclass_fields__
                      if getattr(self.volume, f) is not None})
            d.update({f"vgrid.{k}": v for k, v in self.volume_grid.to_arrays().items()})
            d.update(volume_radius=self.volume_radius, media=self.media)
        return d

    @staticmethod
    def from_arrays(d, table) -> "DepositTarget":
        points = MeasurementPoints(**{f: d[f"points.{f}"] for f in MeasurementPoints.__dataclass_fields__
                                      if f"points.{f}" in d})
        grid = HashGrid.from_arrays({k[5:]: v for k, v in d.items() if k.startswith("grid.")})
        cells = {k[6:]: v for k, v in d.items() if k.startswith("cells.")}
        limits = {k[7:]: v.item() for k, v in d.items() if k.startswith("limits.")}
        volume = vgrid = None
        if "volume.pixel_ids" in d:
            volume = VolumePoints(**{f: d[f"volume.{f}"] for f in VolumePoints.__dataclass_fields__
                                     if f"volume.{f}" in d})
            vgrid = HashGrid.from_arrays({k[6:]: v for k, v in d.items() if k.startswith("vgrid.")})
        return DepositTarget(points, d["radius"], table, int(d["n_pixels"]), bool(d["has_shading_normals"]),
                             grid=grid, cells=VisibleCells.from_arrays(cells) if cells else None,
                             volume=volume, volume_radius=d.get("volume_radius"), volume_grid=vgrid,
                             media=d.get("media"), inner=bool(d.get("inner", False)),
                             coverage=d.get("coverage"), inner_coverage=d.get("inner_coverage"),
                             limits=BounceLimits(**limits) if limits else None,
                             light_passes=tuple(str(n) for n in d.get("light_passes", ())),
                             light_groups=((tuple(str(n) for n in d["group_passes"]), d["group_blocks"],
                                            int(d["derived_group"]), d["live_groups"])
                                           if "group_passes" in d else None),
                             direct=d.get("direct"), direct_points=d.get("direct_points"),
                             focus=Focus.from_array(d["focus"]) if "focus" in d else None)

    def bounce_filter(self, j, bounce, kinds, volume=False):
        """Which pairs of points ``j`` (surface, then volume numbering) with photons at vertex
        ``bounce`` that took ``kinds`` (k, 4) int16 bounces of each kind (diffuse, glossy,
        transmission, volume) after their first vertex (None: not counted) keep to the limits,
        as Cycles counts a light path's bounces: (keep (k,) bool, exclude (k,) uint8 or None).
        The photons' first vertex is the path's vertex nearest the light and does not count; for
        photons past it the point's own scattering does, so a pair must leave room for it: a
        volume point (``volume``) room for a volume bounce, else ``exclude`` has EXCLUDE_DIFFUSE
        (the pair's diffuse and translucent part) or EXCLUDE_GLOSSY where that kind has none left
        (for :meth:`pair_weights`)."""
        room = self.room.take(j, axis=0)
        keep = bounce <= room[:, 0]
        if kinds is None:
            return keep, None
        keep &= (kinds <= room[:, 1:]).all(axis=1)
        if bounce == 0:
            return keep, None
        if volume:
            return keep & (kinds[:, 3] < room[:, 4]), None
        exclude = (np.where(kinds[:, 0] >= room[:, 1], EXCLUDE_DIFFUSE, 0)
                   | np.where(kinds[:, 1] >= room[:, 2], EXCLUDE_GLOSSY, 0)).astype(np.uint8)
        return keep, exclude

    def crossing_filter(self, j, crossings, first):
        """Which pairs of points ``j`` (surface, then volume numbering) with photons that crossed
        ``crossings`` (k,) transparent surfaces in all, ``first`` (k,) of them before their first
        vertex, keep to Cycles' Transparent bounces: at most the limit N in all with the camera
        path's, and at most max(N - 1, 0) before the photon's first vertex (the light path's vertex
        nearest the light, which Cycles shades only before a crossing has reached the limit)."""
        return (crossings <= self.crossing_room.take(j)) & (crossings - first <= self._shading_room.take(j))

    def volume_pairs(self, x, d):
        """Pairs of photons that scattered at ``x`` (n, 3) travelling along ``d`` (n, 3) with the
        volume points: (photon rows, point numbers (m + k), phase function values), the last
        one number 1/(4 pi) when every volume point's medium scatters evenly."""
        pi, pj, _ = self.volume_grid.query(x, None)
        if len(pi) == 0:
            return pi, pj, np.zeros(0)
        if self._isotropic:
            return pi, pj + self.points.count, ISOTROPIC_PHASE
        vol = self.volume
        cos = dot(d.take(pi, axis=0), vol.wo.take(pj, axis=0))
        return pi, pj + self.points.count, phase_value(self.media.take(vol.mat_ids.take(pj), axis=0), cos)

    @cached_property
    def _isotropic(self) -> bool:
        """Whether every volume point's medium scatters evenly (Cycles' default)."""
        return bool(isotropic_phase(self.media.take(np.unique(self.volume.mat_ids), axis=0)).all())

    @cached_property
    def back_grid(self):
        """(grid, ids) for the back pairs: a grid of the translucent points alone and their point
        indices (the grid's own are 0..k-1), or the whole grid and None when every point is
        translucent.  Built where first needed (in the worker), once per pass: a photon on a
        surface far from any translucent point then costs a cell lookup instead of a second
        search among the candidates of its cell (``layer_cost.py``)."""
        ids = np.flatnonzero(self.translucent)
        if len(ids) == len(self.translucent):
            return self.grid, None
        pts = self.points
        return HashGrid(pts.position.take(ids, axis=0), self.radius.take(ids), pts.ng.take(ids, axis=0)), ids

    @cached_property
    def _sides(self):
        """(front (m, 3), back (m, 3)) diffuse pair colours of the ``coloured`` points: the
        diffuse weight times the albedo (under a Fresnel layer, times its factor at the view
        direction; 1 elsewhere) and, for translucent ones, the translucent weight times its colour
        at the point (0 elsewhere)."""
        pts, table, c = self.points, self.table, self.coloured
        mats = pts.mat_ids
        front = np.ones((len(mats), 3))
        back = np.zeros((len(mats), 3))
        front[c] = pts.colors[c, 0] * table.weight[mats[c], DIFFUSE, None]
        if table.has_layer:
            mu = dot(pts.wo[c], pts.glossy_normals[c]).astype(np.float64)
            front[c] *= table.layer_factor(mats[c], mu)[:, None]
        if self.translucent is not None:
            t = self.translucent
            back[t] = pts.colors[t, 2] * table.weight[mats[t], TRANSLUCENT, None]
        return front, back

    @cached_property
    def _rough_terms(self):
        """(a, b (m,), ms (m, 3), cos_v (m,)) at the points' view directions
        (:func:`~core.bsdf.rough_diffuse_terms`; only the rough points' are used)."""
        pts = self.points
        cos_v = dot(pts.wo, pts.ns).astype(np.float64)
        return (*rough_diffuse_terms(self.table, pts.mat_ids, pts.colors[:, 0], cos_v), cos_v)

    def pair_weights(self, j, wi, cos_g, cos_photon=None, back=None, exclude=None, diffuse_scale=None,
                     split=False):
        """What pairs with points ``j`` are worth per unit of photon flux (the points' throughput
        and kernel aside, :meth:`to_pixels`).

        wi : (k, 3) unit directions back along the photons, or None for flat diffuse-only
        targets; cos_g : (k,) their cosines with the points' oriented geometric normals, as
        returned by the grid query; cos_photon : (k,) their cosines with the geometric normal
        where they landed (needed with shading normals).  With shading normals a pair weighs
        |N_s . wi| / |N_g(photon) . wi|: the photon's density is flux per area of *its* facet,
        and a point's own facet can be nearly edge-on to photons that landed on a neighbour
        (README "Brightness parity with Cycles"); a photon from behind the point's facet
        (cos_g <= 0) counts for nothing, as with flat shading.  Normal-mapped points add
        Cycles' bump terms (:func:`~core.bsdf.bump_shadowing`).
        ``back`` (k,) bool marks pairs of photons that landed on the other side of a translucent
        point's surface (their ``wi`` and ``cos_g`` mirrored through it, so on the point's side):
        they weigh only in the diffuse part, by the translucent lobe.  Pairs with points of a rough
        diffuse lobe weigh by :func:`~core.bsdf.rough_diffuse_factor` of their directions besides.
        ``exclude`` (k,) uint8, or None: the rays the pairs' emitters do not light (bits EXCLUDE_*,
        for photons at their first vertex): EXCLUDE_DIFFUSE drops the diffuse part (the translucent
        lobe's too), EXCLUDE_GLOSSY the glossy part.  ``diffuse_scale`` (k,) float, or None: factors
        of the diffuse part (the photons' ``diffuse_next``, :func:`trace_photons`).

        A pair's diffuse weight wd is that geometry (times its colour at the ``coloured``
        points, :attr:`_sides`), its glossy weight wg the lobe's f (times its colour at the
        ``rising`` points).  Pairs with glossy points carry the whole ``d_j wd + g_j wg`` of
        the points' factors (:attr:`_factors`); the others carry wd, and :meth:`to_pixels`
        multiplies their sums by d_j.  So a point has one sum, not one per lobe (README, "Brushed
        metal": a rough gold Cornell box's photon pass peaked at 379 MiB instead of 585 at 1080p).
        Returns (k,) or, when the pairs carry colours, (3, k) in channel rows; with ``split``,
        that and the glossy lobe's part of it, (3, k) (None where no pair has one), for the light
        passes (a sheen's part is diffuse, as Cycles counts it).
        """
        w, glossy = self._pair_weights(j, wi, cos_g, cos_photon, back, exclude, diffuse_scale, split)
        return (w, glossy) if split else w

    def _pair_weights(self, j, wi, cos_g, cos_photon, back, exclude, diffuse_scale, split):
        """:meth:`pair_weights`: (weights, glossy part or None)."""
        pts = self.points
        ratio = None
        if self.has_shading_normals:
            cos_s = dot(wi, pts.ns.take(j, axis=0))
            ratio = np.abs(cos_s) / np.maximum(cos_photon, 1e-4)
            wd = np.where((cos_s > 0) & (cos_g > 0), ratio, 0.0)
            if self.bumped is not None:
                on = self.bumped.take(j)
                if on.any():
                    b = np.flatnonzero(on)
                    jb = j.take(b)
                    diffuse, valid = bump_shadowing(pts.nn.take(jb, axis=0), pts.ns.take(jb, axis=0),
                                                    wi.take(b, axis=0))
                    if back is not None:
                        # Light through a translucent lobe: the validity alone (the photons'
                        # scatter through it takes no shadowing term either; Cycles applies it
                        # to its light samples, not to its BSDF samples).
                        diffuse = np.where(back.take(b), valid, diffuse)
                    # Bump Map Correction off: the side test alone.
                    diffuse = np.where(self.table.bump_correction.take(pts.mat_ids.take(jb)), diffuse, valid)
                    wd[b] *= diffuse
                    ratio[b[~valid]] = 0.0          # glossy pairs too (below)
        else:
            wd = (cos_g > 0).astype(np.float64)
        geometry = wd
        if self.coloured is not None:
            front, behind = self._sides
            color = front.take(j, axis=0)
            if self.rough is not None:
                r = self.rough.take(j) if back is None else self.rough.take(j) & ~back
                r = np.flatnonzero(r)
                if len(r):
                    jr = j.take(r)
                    ta, tb, tm, cos_v = self._rough_terms
                    wi_r, ns_r = wi.take(r, axis=0), pts.ns.take(jr, axis=0)
                    terms = (ta.take(jr), tb.take(jr), tm.take(jr, axis=0))
                    color[r] *= rough_diffuse_factor(self.table, None, None, dot(wi_r, ns_r), cos_v.take(jr),
                                                     dot(wi_r, pts.wo.take(jr, axis=0)), terms=terms)
            if back is not None:
                b = np.flatnonzero(back)
                color[b] = behind.take(j.take(b), axis=0)
            wd = color.T * wd
        keep_g = None
        if exclude is not None:
            wd = wd * ((exclude & EXCLUDE_DIFFUSE) == 0)
            keep_g = (exclude & EXCLUDE_GLOSSY) == 0
        if diffuse_scale is not None:
            wd = wd * diffuse_scale
        if not self.any_glossy:
            return wd, None
        s = np.flatnonzero(self.is_glossy.take(j))
        if len(s) == 0:
            return wd, None
        # The pairs with glossy points (s), of which those that are not back pairs (g) have a
        # glossy part; built apart and put in place once (none of that when all pairs are so).
        d_fac, g_fac = self._factors
        whole = len(s) == len(j)
        js = j if whole else j.take(s)
        w_s = d_fac.take(js, axis=1) * (wd if whole else wd.take(s, axis=-1))        # (3, |s|)
        if back is None:
            g, jg, in_s = s, js, None
        else:
            in_s = np.flatnonzero(~back.take(s))
            g, jg = s.take(in_s), js.take(in_s)
        if self.sheened is not None:
            # The sheen's part (not dimmed, a diffuse event: ``exclude``'s diffuse bit and the
            # diffuse scale apply), then the glossy part of the points that have a glossy lobe.
            front_s = np.arange(len(s)) if in_s is None else in_s
            h = front_s.take(np.flatnonzero(self.sheened.take(js.take(front_s))))
            if len(h):
                w_s[:, h] += self._sheen_part(js.take(h), s.take(h), wi, geometry, exclude, diffuse_scale)
            in_s = front_s.take(np.flatnonzero(self.glossy_lobe.take(js.take(front_s))))
            g, jg = s.take(in_s), js.take(in_s)
        glossy = None
        if len(g):
            nsg = pts.glossy_normals.take(jg, axis=0)
            if self.anisotropic is None:
                f, cos_h = eval_glossy(self.alpha.take(jg), pts.wo.take(jg, axis=0), wi.take(g, axis=0),
                                       nsg, with_cos_h=True, beckmann=self._beckmann(jg))
            else:
                f, cos_h = self._glossy_mixed(jg, g, wi, nsg)
            if ratio is not None:
                if pts.ns_glossy is not None:
                    # |wi . N| / |N_g(photon) . wi| with the glossy lobes' own normal (0 where
                    # the bump terms made the pair invalid).
                    f *= np.where(ratio.take(g) > 0, np.abs(dot(wi.take(g, axis=0), nsg))
                                  / np.maximum(cos_photon.take(g), 1e-4), 0.0)
                else:
                    f *= ratio.take(g)
            if keep_g is not None:
                f = f * keep_g.take(g)
            wg = g_fac.take(jg, axis=1) * f
            if self.rising is not None:
                mats = pts.mat_ids.take(jg)
                if self._hit_base is None:
                    wg *= (self._const.take(mats, axis=0) + self.table.fresnel_color(mats, GLOSSY, cos_h)).T
                else:
                    base = self._hit_base.take(jg, axis=0)
                    hit = self.table.hit_metal.take(mats)
                    const = (base if hit.all()
                             else np.where(hit[:, None], base, self._const.take(mats, axis=0)))
                    wg *= (const + self.table.fresnel_color(mats, GLOSSY, cos_h, base)).T
            if in_s is None:
                w_s += wg
            else:
                w_s[:, in_s] += wg
            if split:
                glossy = np.zeros((3, len(j)))
                glossy[:, g] = wg
        if whole:
            return w_s, glossy
        w = np.empty((3, len(j)))
        w[:] = wd
        w[:, s] = w_s
        return w, glossy

    def route_pairs(self, j, bounce, w, glossy):
        """Where pairs with surface points ``j`` of photons at vertex ``bounce``, of weights ``w``
        and glossy parts ``glossy`` (:meth:`pair_weights` with ``split``) go with ``light_passes``:
        (slots (k,), their weights (as ``w``), and the glossy parts' pairs (rows (r,), slots (r,),
        weights (3, r)) or None).  At the points that ``split``, a pair at the photon's first vertex
        goes to the direct block, and its glossy part apart to the glossy block (the direct glossy
        block at the first vertex); elsewhere it stays on the point's slot."""
        rows = np.flatnonzero(self.split.take(j))
        slots = j
        if bounce == 0 and len(rows):
            slots = j.copy()
            slots[rows] += self.direct_slots
        if glossy is None:
            return slots, w, None
        g = rows.take(np.flatnonzero(self.glossy_lobe.take(j.take(rows))))
        if len(g) == 0:
            return slots, w, None
        part = glossy.take(g, axis=1)
        w = w.copy()
        w[:, g] -= part
        offset = self.direct_glossy_slots if bounce == 0 else self.glossy_slots
        return slots, w, (g, j.take(g) + offset, part)

    @property
    def makes_passes(self) -> bool:
        """Whether the target makes light, light group or catcher passes (:meth:`pass_pixels`)."""
        return bool(self.light_passes or self.group_passes) or self.caught is not None

    def group_pairs(self, groups, j, near=None):
        """The copies of pairs with points ``j`` (k,) (surface, then volume numbering) of photons
        from emitters of light groups ``groups`` (k,; -1 none) on the blocks they are copied to
        (their groups', or the derived group's for those of no group asked for), and of those
        ``near`` (k,) bool (within half the radius; None: none) on the groups' inner blocks: (rows
        (r,) of the pairs copied, their slots (r,)), or None where there are none."""
        block = self.copy_to.take(groups + 1)
        rows = np.flatnonzero(block >= 0)
        if len(rows) == 0:
            return None
        block, points = block.take(rows), j.take(rows)
        slots = self.group_slots + block * self.n_points + points
        if near is not None and self.inner:
            again = np.flatnonzero(near.take(rows))
            m = self.points.count
            rows = np.concatenate([rows, rows.take(again)])
            inner = self.group_inner_slots + block.take(again) * m + points.take(again)
            slots = np.concatenate([slots, inner])
        return rows, slots

    def _sheen_part(self, jh, h, wi, geometry, exclude, diffuse_scale):
        """(3, k) the sheen's part of pairs ``h`` with sheened points ``jh`` (:meth:`pair_weights`'s
        ``geometry`` the pairs' geometric factor): the point's sheen colour times E at its view,
        times the lobe's f towards the photon (:func:`~core.bsdf.sheen_value`)."""
        pts = self.points
        color, a, b = self._sheen
        n = pts.ns.take(jh, axis=0).astype(np.float64)
        x, y = sheen_frame(pts.wo.take(jh, axis=0).astype(np.float64), n)
        w = wi.take(h, axis=0)
        f = sheen_value(a.take(jh), b.take(jh), dot(w, x), dot(w, y), dot(w, n)) * geometry.take(h)
        if exclude is not None:
            f = f * ((exclude.take(h) & EXCLUDE_DIFFUSE) == 0)
        if diffuse_scale is not None:
            f = f * diffuse_scale.take(h)
        return color.take(jh, axis=1) * f

    @cached_property
    def _sheen(self):
        """(color (3, m) float32, a, b (m,)): per sheened point its sheen's colour times E at the
        view, and the LTC's coefficients there (:meth:`~core.bsdf.MaterialTable.sheen_lobe`)."""
        pts, m = self.points, self.points.count
        color = np.zeros((3, m), np.float32)
        a, b = np.zeros(m), np.zeros(m)
        j = np.flatnonzero(self.sheened)
        mu = dot(pts.wo.take(j, axis=0), pts.ns.take(j, axis=0)).astype(np.float64)
        e, a[j], b[j] = self.table.sheen_lobe(pts.mat_ids.take(j), mu)
        color[:, j] = (pts.colors[j, 3] * e[:, None]).T
        return color, a, b

    @cached_property
    def _dim(self):
        """(m,) float32 the factor of each point's lobes under a sheen at its view
        (:meth:`~core.bsdf.MaterialTable.sheen_dim`), or None in scenes without sheens."""
        if not self.table.has_sheen:
            return None
        pts = self.points
        return self.table.sheen_dim(pts.mat_ids, dot(pts.wo, pts.ns).astype(np.float64)).astype(np.float32)

    @cached_property
    def _factors(self):
        """(d, g) (3, m) float32 (channel rows): per point, what a pair's diffuse and glossy weights
        (:meth:`pair_weights`) are worth besides the point's throughput and kernel.  d: the
        diffuse lobe's weight times its albedo over pi (1 over pi at the ``coloured`` points,
        whose pairs carry both), under a Fresnel layer times its factor at the view direction;
        g: the glossy lobe's weight times its colour (1 at the ``rising`` points, whose pairs
        carry it), with multiscatter GGX times the compensation at the view direction (a
        factor of the point's view direction, BSDF docs in bsdf.py); None without glossy
        points.  Computed where first needed, in the worker that deposits: the main process
        builds a target for its grid only, and at 1920x1080 these products made its preparation
        of a pass longer (whole renders with 100,000 photons per pass and worker 1.08x faster
        without them, ``ab_photon_pass.py``)."""
        pts, table = self.points, self.table
        mats, f32 = pts.mat_ids, np.float32
        # (in float32 from the start, and a lobe's weights alone: at 1920x1080 the temporaries
        # of the whole (m, lobes) weights in float64 took 218 MiB)
        w_d = (table.weight[:, DIFFUSE] / np.pi).astype(f32).take(mats)
        if self.coloured is None:
            d = pts.colors[:, 0] * w_d[:, None]
        else:
            d = np.where(self.coloured[:, None], f32(1.0 / np.pi), pts.colors[:, 0] * w_d[:, None])
        mu = None
        if table.has_layer:
            mu = dot(pts.wo, pts.glossy_normals).astype(np.float64)
            layer = table.layer_factor(mats, mu).astype(f32)
            if self.coloured is not None:
                layer[self.coloured] = 1.0
            d *= layer[:, None]
        if self._dim is not None:
            d *= self._dim[:, None]
        if not self.any_glossy:
            return np.ascontiguousarray(d.T), None
        base = pts.colors[:, 1]
        color = base
        if self.rising is not None:
            color = np.where(self.rising[:, None], f32(1.0), color)
        g = color * table.weight[:, GLOSSY].astype(f32).take(mats)[:, None]
        if table.ms_fresnel.any():
            if mu is None:
                mu = dot(pts.wo, pts.glossy_normals).astype(np.float64)
            g *= table.multiscatter(mats, mu, base)
        if self._dim is not None:
            g *= self._dim[:, None]
        return np.ascontiguousarray(d.T), np.ascontiguousarray(g.T)

    @property
    def needs_directions(self) -> bool:
        return self.has_shading_normals or self.any_glossy or self.rough is not None

    def to_pixels(self, sums):
        """(n_pixels, 3) radiance sums from the per-slot sums of flux times :meth:`pair_weights`
        (``n_slots``, 3)."""
        return self._pixels(sums, inner=False)

    def inner_pixels(self, sums):
        """As :meth:`to_pixels` for the estimate at half the radius: the surface points' inner
        slots over a quarter of the area; the volume points' part is the same as in
        :meth:`to_pixels` (their gathers have no inner estimate)."""
        if not self.inner:
            raise ValueError("DepositTarget.inner_pixels: the target was built without inner sums")
        return self._pixels(sums, inner=True)

    def _pixels(self, sums, inner):
        """to_pixels of what the points gathered (:meth:`gathered`), or of the surface points' inner
        slots (at half the radius) with ``inner``."""
        m = self.points.count
        whole = self.gathered(sums)
        block = sums[self.inner_slots:self.inner_slots + m] if inner else whole[:m]
        out = np.zeros((self.n_pixels, 3))
        out[self.pixel_ids] = self._surface_values(block, half=inner)
        if self.volume is not None:
            np.add.at(out, self.volume.pixel_ids, self._volume_values(whole[m:]))
        return out

    def gathered(self, sums):
        """(n_points, 3) each point's sum over its slots (with ``light_passes``, its blocks')."""
        n, m = self.n_points, self.points.count
        if not self.light_passes:
            return sums[:n]
        whole = sums[:n] + sums[self.direct_slots:self.direct_slots + n]
        whole[:m] += sums[self.glossy_slots:self.glossy_slots + m]
        whole[:m] += sums[self.direct_glossy_slots:self.direct_glossy_slots + m]
        return whole

    def _surface_values(self, block, half=False):
        """(m, 3) radiance of the surface points from their slots' sums ``block`` (m, 3): w_j
        (throughput) times the kernel (of half the radius with ``half``), and d_j where the pairs
        do not carry it; one measurement point per pixel and pass."""
        radius = 0.5 * self.radius if half else self.radius
        kernel = 1.0 / (np.pi * radius * radius)                                   # (m,)
        coverage = self.inner_coverage if half else self.coverage
        if coverage is not None:
            kernel /= coverage
        return self.point_values(None, block * kernel[:, None])

    def point_values(self, j, values):
        """(k, 3) ``values`` (k, 3) of surface points ``j`` (k,; None: all, in order) times what their
        pairs do not carry: w_j (throughput), and d_j where the pairs do not carry it."""
        d = self._factors[0].T
        weight = self.points.weight
        if j is not None:
            d, weight = d.take(j, axis=0), weight.take(j, axis=0)
        if self.any_glossy:
            glossy = self.is_glossy if j is None else self.is_glossy.take(j)
            d = np.where(glossy[:, None], np.float32(1.0), d)
        return weight * d * values

    def _volume_values(self, block):
        """(k, 3) radiance of the volume points from their slots' sums ``block``: w_j sum(flux phase)
        / (4/3 pi r_j^3) (the flux holds the scattering coefficient, the weight the camera path's
        transmittance over its density)."""
        r = self.volume_radius
        kernel = 3.0 / (4.0 * np.pi * r * r * r) / _inside_share(self.volume.planes, r)
        return self.volume.weight * block * kernel[:, None]

    def pass_pixels(self, sums):
        """name -> (n_pixels, 3) the photons' part of the light passes ``light_passes`` and of the
        light group passes ``group_passes`` (those with some) from the per-slot sums (``n_slots``,
        3), as :meth:`to_pixels` makes the image's: a point with no delta event before it
        (``split``) gives its direct block to the direct pass (diffuse; a volume point's volume),
        its glossy blocks to the glossy passes and its own slot to the indirect one; a point behind
        a delta event gives its slot to the indirect pass of that event's kind (its blocks are
        empty); a group's pass takes the group's block (:meth:`_group_block`); with shadow catchers,
        ``CATCHER_HIT`` takes what the points behind one (``caught``) gathered."""
        m = self.points.count
        surface, volume = self._light_blocks(sums) if self.light_passes else ({}, {})
        names = self.light_passes + self.group_passes
        if self.caught is not None:
            names += (CATCHER_HIT,)
            whole = self.gathered(sums)
            surface[CATCHER_HIT] = np.where(self.caught[:m, None], whole[:m], 0.0)
            if self.volume is not None:
                volume[CATCHER_HIT] = np.where(self.caught[m:, None], whole[m:], 0.0)
        for k, name in enumerate(self.group_passes):
            if self.block_of[k] < 0:
                continue
            block = self._group_block(sums, k)
            surface[name] = block[:m]
            if self.volume is not None:
                volume[name] = block[m:]
        out = {}
        for name in names:
            total = np.zeros((self.n_pixels, 3))
            if name in surface:
                total[self.pixel_ids] = self._surface_values(surface[name])
            if name in volume:
                np.add.at(total, self.volume.pixel_ids, self._volume_values(volume[name]))
            if total.any():     # (passes this target has nothing for are left out: the workers send less)
                out[name] = total
        return out

    def group_inner_pixels(self, sums):
        """name -> (n_pixels, 3) each light group pass's estimate at half the radius (those with
        some; :meth:`inner_pixels` of the group's pairs: its surface points' inner block, its volume
        points' part as in :meth:`pass_pixels`)."""
        if not self.inner:
            raise ValueError("DepositTarget.group_inner_pixels: the target was built without inner sums")
        m = self.points.count
        out = {}
        for k, name in enumerate(self.group_passes):
            if self.block_of[k] < 0:
                continue
            total = np.zeros((self.n_pixels, 3))
            total[self.pixel_ids] = self._surface_values(self._group_block(sums, k, inner=True), half=True)
            if self.volume is not None:
                np.add.at(total, self.volume.pixel_ids, self._volume_values(self._group_block(sums, k)[m:]))
            if total.any():
                out[name] = total
        return out

    def _group_block(self, sums, k, inner=False):
        """(n_points, 3) the sums of light group pass ``k``'s pairs per point (with ``inner``, (m, 3)
        those within half the radius): its block, or for the ``derived`` group what the points
        gathered less every group block (not below 0: the sums differ in their rounding)."""
        m = self.points.count
        size, first = (m, self.group_inner_slots) if inner else (self.n_points, self.group_slots)
        if k != self.derived:
            b = self.block_of[k]
            return sums[first + b * size:first + (b + 1) * size]
        whole = sums[self.inner_slots:self.inner_slots + m] if inner else self.gathered(sums)
        g = self.n_blocks
        blocks = sums[first:first + g * size].reshape(g, size, 3).sum(axis=0)
        return np.maximum(whole - blocks, 0.0)

    def _light_blocks(self, sums):
        """The light passes' sums of the surface points and of the volume points (name -> (m, 3),
        name -> (k, 3)) from the per-slot sums (:meth:`pass_pixels`)."""
        m, n = self.points.count, self.n_points
        main, direct = sums[:n], sums[self.direct_slots:self.direct_slots + n]
        zero = np.zeros(3)

        def by_event(points, main, split):
            via = np.zeros(points.count, np.uint8) if points.via is None else points.via
            return {"glossy_indirect": np.where((via == VIA_GLOSSY)[:, None], main, zero),
                    "transmission_indirect": np.where((via == VIA_TRANSMISSION)[:, None], main, zero),
                    "split": np.where(split[:, None], main, zero)}

        s = by_event(self.points, main[:m], self.split[:m])
        surface = {"diffuse_direct": direct[:m], "diffuse_indirect": s["split"],
                   "glossy_direct": sums[self.direct_glossy_slots:self.direct_glossy_slots + m],
                   "glossy_indirect": (sums[self.glossy_slots:self.glossy_slots + m]
                                       + s["glossy_indirect"]),
                   "transmission_indirect": s["transmission_indirect"]}
        volume = {}
        if self.volume is not None:
            v = by_event(self.volume, main[m:], self.split[m:])
            volume = {"volume_direct": direct[m:], "volume_indirect": v["split"],
                      "glossy_indirect": v["glossy_indirect"],
                      "transmission_indirect": v["transmission_indirect"]}
        return surface, volume


def _inside_share(planes, r):
    """(k,) the share of spheres of radii ``r`` on the volume's side of the faces at distances
    ``planes`` (k, P) (the entry and exit faces of their camera rays and the faces beside them,
    ``eye_pass.side_planes``, taken as planes): photons only lie inside the volume, and a sphere
    that reaches out of it would otherwise find too few (at a face, half).  Kept at least 1/4."""
    share = np.ones(len(r))
    for k in range(planes.shape[1]):
        h = np.clip(r - planes[:, k], 0.0, 2.0 * r)            # height of the cap beyond the plane
        share -= h * h * (3.0 * r - h) / (4.0 * r ** 3)
    return np.maximum(share, 0.25)


def _some(mask):
    """``mask`` if any of it is set, else None."""
    return mask if mask is not None and mask.any() else None


class PointSums:
    """Per-slot sums of pair values (:meth:`DepositTarget.pair_weights` times the flux), float64.

    ``add`` buffers pairs; they are splatted with one bincount per channel once at least
    ``n_points`` pairs are waiting (and by ``flush``): a bincount costs O(points) besides
    O(pairs), so splatting every small group of pairs on its own would cost a pass over all
    points each time (at 1080p, 2 million points, more than the pairs themselves).
    """

    def __init__(self, n_points, min_pairs=1 << 16):
        self.n_points = n_points
        self.total = np.zeros((n_points, 3))
        self.min_pairs = max(n_points, min_pairs)
        self._points, self._values, self._waiting = [], [], 0

    def add(self, point_ids, values, counted=None):
        """Pairs with points ``point_ids`` (k,) and ``values`` (3, k) (three channel rows, each
        contiguous).  ``counted``: how many of them count towards a splat (default all): the pairs
        on the inner slots (``DepositTarget`` with ``inner``) do not, so that the main slots are
        splatted in the same groups, and so summed to the same bits, with or without them."""
        self._points.append(point_ids)
        self._values.append(values)
        self._waiting += len(point_ids) if counted is None else counted
        if self._waiting >= self.min_pairs:
            self.flush()

    def flush(self):
        if not self._points:
            return
        points = np.concatenate(self._points) if len(self._points) > 1 else self._points[0]
        for c in range(3):
            w = np.concatenate([v[c] for v in self._values]) if len(self._values) > 1 else self._values[0][c]
            self.total[:, c] += np.bincount(points, weights=w, minlength=self.n_points)
        self._points, self._values, self._waiting = [], [], 0


@dataclass
class PhotonBatch:
    """What a batch of n photon paths did."""

    visible: np.ndarray          # (n,) bool V(u)
    first_dim: np.ndarray        # (n,) int32 dimensions consumed before the first visible vertex, -1
    pair_path: np.ndarray        # (k,) int64 path index of each deposit pair (if collected)
    pair_point: np.ndarray       # (k,) int64 measurement point of each pair
    pair_value: np.ndarray       # (k, 3) float64 flux * DepositTarget.pair_weights of each pair
    pair_bounce: np.ndarray      # (k,) int16 vertex of each pair (0 = first surface hit)
    first: dict                  # arrays (n, ...): each visible path at its first visible vertex
    sums: np.ndarray             # (n_slots, 3) per-slot sums of the pair values (if summed here)
    rays: int                    # closest-hit rays traced (= photon path vertices attempted)
    vertices: int                # surface hits (photon path vertices)
    aims: np.ndarray | None = None  # (n,) with a Focus: each path's w from afar, 0 for the others and resumed
    entry: np.ndarray | None = None  # (n,) int64 with visible cells: the oldest generation of the cells
    #                                  that held a tested vertex (VisibleCells.NEVER: none; trace_photons)


# Per-path state at a vertex before it scatters, enough to resume a trace there.
VERTEX_FIELDS = ("bounce", "position", "ng", "ns", "nn", "mat_ids", "colors", "wo", "flux", "prim", "medium",
                 "volume", "tangent", "nc", "kinds", "diffuse_next", "crossings", "first_crossings")


def _vertex_arrays(n, lobes, tangents=False, coat_normals=False, kinds=False, caustics=False,
                   crossings=False):
    """Per-path vertex records (``VERTEX_FIELDS``; ``tangent`` only with ``tangents``, ``nc`` only
    with ``coat_normals``, ``kinds`` (the bounces of each kind after the first vertex,
    ``trace_photons``) only with ``kinds``, ``diffuse_next`` (``trace_photons``) only with
    ``caustics``; ``crossings`` and ``first_crossings`` (``trace_photons``) only with ``crossings``)."""
    out = {"bounce": np.full(n, -1, np.int32), "position": np.zeros((n, 3)), "ng": np.zeros((n, 3)),
            "ns": np.zeros((n, 3)), "nn": np.zeros((n, 3)), "mat_ids": np.zeros(n, np.int32),
            "colors": np.zeros((n, lobes, 3)), "wo": np.zeros((n, 3)), "flux": np.zeros((n, 3)),
            "prim": np.zeros(n, np.int32), "medium": np.full(n, -1, np.int32), "volume": np.zeros(n, bool)}
    if tangents:
        out["tangent"] = np.zeros((n, 3))
    if coat_normals:
        out["nc"] = np.zeros((n, 3))
    if kinds:
        out["kinds"] = np.zeros((n, 4), np.int16)
    if caustics:
        out["diffuse_next"] = np.ones(n)
    if crossings:
        out["crossings"] = np.zeros(n, np.int16)
        out["first_crossings"] = np.zeros(n, np.int16)
    return out


def trace_photons(ctx, target, u, max_bounces, *, refresh_rng=None, collect_pairs=False, resume=None,
                  sums=None, unweighted=False, cell_limit=None, cell_floor=None):
    """Trace photon paths for primary samples ``u`` (n, d) and deposit them on ``target``.

    With ``collect_pairs`` the deposits are returned per pair (for Markov chains) together
    with each visible path's state at its first visible vertex (``PhotonBatch.first``);
    otherwise they are summed per measurement point: into ``sums`` (a :class:`PointSums`
    that outlives the call, e.g. one per pass) if given, else into ``PhotonBatch.sum_*``.

    ``resume`` (arrays as ``PhotonBatch.first``, k rows) restarts the last k paths of ``u``
    at their recorded vertices, scattering with their (redrawn) dimensions there: the
    deposits at and before those vertices are not repeated.  This is the Gibbs refresh of
    the exact low-dimension mutation, which changes only the dimensions after the first
    visible vertex.  The first n - k paths are traced from the lights as usual, so one
    batch can hold both (a batch has a fixed cost of a few milliseconds per bounce).

    ``unweighted`` (the Markov chains, whose target takes the weights instead): the paths from
    afar under ``target.focus`` carry their flux without the focus's weight w
    (``LightSampler.sample_aimed``); ``PhotonBatch.aims`` has the weights either way.

    ``cell_limit`` (n,) int64 (with ``target.cells``; None: no limit): a path is visible from its
    first vertex in a cell of that generation or older (the Markov chains' generations,
    ``core/mcmc.py``).  ``cell_floor`` (n,) int64 (None: none): a visible path's later vertices are
    still tested while the oldest generation found so far is newer than it.  ``PhotonBatch.entry``
    holds that oldest generation per path (resumed paths: -1).
    """
    focus = target.focus
    n = len(u)
    accel, table = ctx.accel, ctx.table
    visible = np.zeros(n, bool)
    first_dim = np.full(n, -1, np.int32)
    n_resumed = 0 if resume is None else len(resume["bounce"])
    fresh = n - n_resumed
    # (aims: the focus's weights w of the paths from afar, 0 for the others; the integrator drops a
    # focus that does not pay)
    origins, dirs, flux, _, aims = ctx.lights.sample_aimed(u[:fresh, :LIGHT_DIMS], focus)
    if unweighted and focus is not None:
        flux = flux / np.where(aims > 0, aims, 1.0)[:, None]
    idx = np.flatnonzero(luminance(flux) > 0)
    origins, dirs, flux = origins.take(idx, axis=0), dirs.take(idx, axis=0), flux.take(idx, axis=0)
    last_join = -1
    if n_resumed:
        visible[fresh:] = True
        first_dim[fresh:] = bounce_offset(resume["bounce"])
        last_join = int(resume["bounce"].max())
    cell_test = None
    if target.cells is not None:
        entry = np.full(n, NEVER, np.int64)
        entry[fresh:] = -1
        limit = np.full(n, NEVER - 1, np.int64) if cell_limit is None else np.asarray(cell_limit, np.int64)
        floor = None if cell_floor is None else np.asarray(cell_floor, np.int64)
        cell_test = (limit, floor, entry)
    m = target.points.count
    pairs = {"path": [], "point": [], "value": [], "bounce": []}
    # Bounce limits: the bounces of each kind every path took after its first vertex, where some
    # kind's limit binds (DepositTarget.bounce_filter; None where not counted).
    kinds = np.zeros((n, 4), np.int16) if target.counts_kinds else None
    if kinds is not None and n_resumed:
        kinds[fresh:] = resume["kinds"]
    # A Caustics toggle off (Cycles drops a closure whose caustics are off at a path's vertex after a
    # diffuse bounce): what a diffuse event next (a deposit's diffuse part, a diffuse scatter) is worth
    # to each path after its last scattering (_diffuse_next); None with both toggles on.
    diffuse_next = np.ones(n) if target.blocks_caustics else None
    if diffuse_next is not None and n_resumed:
        diffuse_next[fresh:] = resume["diffuse_next"]
    # Cycles' Transparent bounces: the transparent surfaces each path crossed in all and before its
    # first vertex (DepositTarget.crossing_filter); None where that limit does not bind.
    crossings = first_crossings = None
    if target.crossing_room is not None:
        crossings, first_crossings = np.zeros(n, np.int16), np.zeros(n, np.int16)
        if n_resumed:
            crossings[fresh:], first_crossings[fresh:] = resume["crossings"], resume["first_crossings"]
    first = (_vertex_arrays(n, table.lobes, table.has_anisotropy, ctx.has_coat_normals, kinds is not None,
                            diffuse_next is not None, crossings is not None) if collect_pairs else None)
    own_sums = not collect_pairs and sums is None
    if own_sums:
        sums = PointSums(target.n_slots)
    rays = vertices = 0
    soft = ctx.lights.has_soft_falloff
    volumes = ctx.has_volumes
    # Emitters that do not light some rays (Lights.exclude): what each photon's first vertex gets.
    excluding = ctx.lights.has_exclusion
    # The volume each path is in (RenderContext.trace).
    medium = ctx.light_medium(u[idx, 0]) if volumes else np.full(len(idx), -1, np.int32)
    prim = np.zeros(0, np.int32)
    for bounce in range(max_bounces + 1):
        if len(idx) == 0 and bounce > last_join:
            break
        if len(idx):
            crossing = _crossing_uniforms(u, idx, bounce)
            shadow = None
            if bounce == 0 and ctx.blocker_sets is not None:
                # Shadow linking: what shadows each photon's emitter on its way from it.
                shadow = ctx.lights.shadow_links.take(ctx.lights.entries(u[idx, 0]))
            distances = _crossing_uniforms(u, idx, bounce, DISTANCE_KEYS) if ctx.has_scattering else None
            crossed = None if crossings is None else crossings.take(idx)
            hits, through, opacity, medium = ctx.trace(
                origins, dirs, None, crossing, medium, shadow=shadow, distances=distances, throughput=flux,
                crossings=crossed, max_crossings=None if crossed is None else target.limits.transparent)
            if crossed is not None:
                crossings[idx] = crossed
                if bounce == 0:
                    first_crossings[idx] = crossed
            if through is not None:
                flux = flux * through                        # transparent surfaces and volumes crossed
            rays += len(idx)
            vert = None
            if hits.scatter_t is not None:
                # Photons that stopped in a scattering volume: a vertex there.
                v = np.flatnonzero(np.isfinite(hits.scatter_t))
                if bounce == 0 and excluding and len(v):
                    # (its emitter may not light volumes: nothing there to deposit or scatter)
                    v = v[(ctx.lights.excluded(u[idx.take(v), 0]) & EXCLUDE_SCATTER) == 0]
                if len(v):
                    x_v = origins.take(v, axis=0) + hits.scatter_t.take(v)[:, None] * dirs.take(v, axis=0)
                    f_v = flux.take(v, axis=0)
                    if bounce == 0 and soft:
                        f_v = f_v * ctx.lights.soft_falloff(u[idx.take(v), :1], x_v)[:, None]
                    vert = {"idx": idx.take(v), "position": x_v, "d": dirs.take(v, axis=0), "flux": f_v,
                            "medium": medium.take(v)}
                    vertices += len(v)
            h = np.flatnonzero(hits.is_hit)
            if bounce == 0 and ctx.receiver_sets is not None and len(h):
                # Light linking: a photon ends where it first lands on a triangle its emitter
                # does not light (which then neither shows that light nor passes it on).
                sets = ctx.receiver_sets.take(hits.prim_ids.take(h))
                h = h.take(np.flatnonzero(ctx.lights.lights_sets(u[idx.take(h), 0], sets)))
            idx, dirs, flux = idx.take(h), dirs.take(h, axis=0), flux.take(h, axis=0)
            prim = hits.prim_ids.take(h)
            medium = medium.take(h) if volumes else np.full(len(h), -1, np.int32)
            vertices += len(idx)
            pick = None
            if ctx.has_level_programs:
                pick = _crossing_uniforms(u, idx, bounce, LEVEL_KEYS)(np.arange(len(idx)), 0)
            path = photon_path(hits.t.take(h).astype(np.float64)) if ctx.reads_light_path else None
            surf = ctx.surface(prim, hits.b1.take(h), hits.b2.take(h), pick, Rays(-dirs, path=path))
            if bounce == 0 and soft:
                flux = flux * ctx.lights.soft_falloff(u[idx, :1], surf.position)[:, None]
            # A photon stops on a transparent surface with the probability of its opacity there,
            # and deposits the flux of all that arrive: its own over that probability.
            deposited = flux if opacity is None else flux / np.maximum(opacity.take(h), 1e-12)[:, None]
            excluded = ctx.lights.excluded(u[idx, 0]) if bounce == 0 and excluding else None
        else:
            excluded = None
            surf = ctx.surface(np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
            prim, medium = np.zeros(0, np.int32), np.zeros(0, np.int32)
            deposited = flux
            vert = None
        wo = -dirs
        # Deposit at non-delta vertices; a pair found makes the path visible, or, if the target
        # has visible cells, a vertex in one of them (and nothing else).
        dep = np.flatnonzero(table.has_nondelta[surf.mat_ids])
        first_sampled = None
        if bounce == 0 and target.direct is not None and len(dep):
            # The light of emitters that the points sample (core/direct.py) from the second vertex on;
            # where only some points sample it, the pairs of the others alone (below).
            first_sampled = target.direct.take(ctx.lights.entries(u[idx.take(dep), 0]))
            if target.direct_points is None:
                dep, first_sampled = dep[~first_sampled], None
        if len(dep) and m:
            wo_dep = wo.take(dep, axis=0)
            x_dep = surf.position.take(dep, axis=0)
            nrm = face_forward(surf.ng.take(dep, axis=0), wo_dep)
            found = target.grid.query(x_dep, nrm, wo_dep, inner=target.inner)
            pi, pj, cos_g = found[:3]
            near = found[3] if target.inner else None
            sides = back = None
            if target.translucent is not None:
                # Photons on a translucent surface also reach the points on its other side.
                sides = np.flatnonzero(table.translucent.take(surf.mat_ids.take(dep)))
                if len(sides):
                    grid, ids = target.back_grid
                    found = grid.query(x_dep.take(sides, axis=0), -nrm.take(sides, axis=0),
                                       -wo_dep.take(sides, axis=0), inner=target.inner)
                    bi, bj, bcos = found[:3]
                    if ids is not None:
                        bj = ids.take(bj)
                    back = np.concatenate([np.zeros(len(pi), bool), np.ones(len(bi), bool)])
                    pi, pj = np.concatenate([pi, sides.take(bi)]), np.concatenate([pj, bj])
                    cos_g = np.concatenate([cos_g, bcos])
                    if near is not None:
                        near = np.concatenate([near, found[3]])
            seen = np.zeros(len(idx), bool)
            keep = limited = scale = None
            if len(pi) and target.room is not None:
                keep, limited = target.bounce_filter(
                    pj, bounce, None if kinds is None else kinds.take(idx.take(dep.take(pi)), axis=0))
            if len(pi) and diffuse_next is not None:
                # (pairs worth nothing, with no glossy part, make no path visible)
                scale = diffuse_next.take(idx.take(dep.take(pi)))
                glossy = target.glossy_lobe.take(pj)
                worth = (scale > 0) | (glossy if back is None else glossy & ~back)
                keep = worth if keep is None else keep & worth
            if len(pi) and first_sampled is not None:
                ok = ~(first_sampled.take(pi) & target.direct_points.take(pj))
                keep = ok if keep is None else keep & ok
            if len(pi) and crossings is not None:
                lanes = idx.take(dep.take(pi))
                ok = target.crossing_filter(pj, crossings.take(lanes), first_crossings.take(lanes))
                keep = ok if keep is None else keep & ok
            if keep is not None and not keep.all():
                k = np.flatnonzero(keep)
                pi, pj, cos_g = pi.take(k), pj.take(k), cos_g.take(k)
                back, near, limited, scale = (None if a is None else a.take(k)
                                              for a in (back, near, limited, scale))
            if len(pi):
                lane = dep.take(pi)
                cos_photon = dot(nrm, wo_dep).take(pi) if target.has_shading_normals else None
                wi_pairs = None
                if target.needs_directions:
                    wi_pairs = wo.take(lane, axis=0)
                    if back is not None:
                        wi_pairs[back] *= -1.0           # mirrored through the surface, as cos_g
                exclude = None if excluded is None else excluded.take(lane)
                if limited is not None:
                    exclude = limited if exclude is None else exclude | limited
                if target.light_passes:
                    w, glossy = target.pair_weights(pj, wi_pairs, cos_g, cos_photon, back, exclude, scale,
                                                    split=True)
                    main_slots, main_w, extra = target.route_pairs(pj, bounce, w, glossy)
                else:
                    w = target.pair_weights(pj, wi_pairs, cos_g, cos_photon, back, exclude, scale)
                    main_slots, main_w, extra = pj, w, None
                # The pairs within half the radius once more (whole), on the inner slots; the glossy
                # parts routed apart last.
                again = None if near is None else np.flatnonzero(near)
                slots = [main_slots]
                if again is not None:
                    slots.append(pj.take(again) + target.inner_slots)
                if extra is not None:
                    slots.append(extra[1])
                # Light groups: copies of the pairs of photons from a group's emitters, whole.
                copies = (None if target.group_blocks is None
                          else target.group_pairs(ctx.lights.groups_of(u[idx.take(lane), 0]), pj, near))
                if copies is not None:
                    slots.append(copies[1])
                slots = np.concatenate(slots) if len(slots) > 1 else main_slots
                if collect_pairs:
                    f = deposited.take(lane, axis=0)
                    path = idx[lane]
                    v = f * (main_w[:, None] if main_w.ndim == 1 else main_w.T)
                    if again is not None:
                        whole = v if extra is None else f * (w[:, None] if w.ndim == 1 else w.T)
                        path = np.concatenate([path, path.take(again)])
                        v = np.concatenate([v, whole.take(again, axis=0)])
                    if extra is not None:
                        path = np.concatenate([path, idx[lane].take(extra[0])])
                        v = np.concatenate([v, f.take(extra[0], axis=0) * extra[2].T])
                    if copies is not None:
                        rows = copies[0]
                        path = np.concatenate([path, idx[lane].take(rows)])
                        v = np.concatenate([v, f.take(rows, axis=0) * (w.take(rows)[:, None] if w.ndim == 1
                                                                       else w.take(rows, axis=1).T)])
                    pairs["path"].append(path)
                    pairs["point"].append(slots)
                    pairs["value"].append(v)
                    pairs["bounce"].append(np.full(len(slots), bounce, np.int16))
                else:
                    f = [deposited[:, c].take(lane) for c in range(3)]
                    v = [fc * (main_w if main_w.ndim == 1 else main_w[c]) for c, fc in enumerate(f)]
                    if again is not None:
                        whole = v if extra is None else [fc * (w if w.ndim == 1 else w[c])
                                                         for c, fc in enumerate(f)]
                        v = [np.concatenate([vc, wc.take(again)]) for vc, wc in zip(v, whole)]
                    if extra is not None:
                        v = [np.concatenate([vc, fc.take(extra[0]) * extra[2][c]]) for c, (vc, fc)
                             in enumerate(zip(v, f))]
                    if copies is not None:
                        rows = copies[0]
                        v = [np.concatenate([vc, fc.take(rows) * (w if w.ndim == 1 else w[c]).take(rows)])
                             for c, (vc, fc) in enumerate(zip(v, f))]
                    sums.add(slots, v, len(pj) + (0 if extra is None else len(extra[0])))
                if target.cells is None:
                    seen[lane] = True
            if target.cells is not None:
                lane = idx.take(dep)
                open_ = _cell_open(visible, cell_test, lane)
                if len(open_):
                    gen = target.cells.entry(x_dep.take(open_, axis=0), nrm.take(open_, axis=0))
                    if sides is not None and len(sides):
                        # (or seen on the other side of a translucent surface)
                        t = np.flatnonzero(table.translucent.take(surf.mat_ids.take(dep.take(open_))))
                        gen[t] = np.minimum(gen[t], target.cells.entry(x_dep.take(open_[t], axis=0),
                                                                        -nrm.take(open_[t], axis=0)))
                    seen[dep.take(open_[_cell_inside(cell_test, lane.take(open_), gen)])] = True
            if seen.any():
                rows = np.flatnonzero(seen)
                rows = rows[~visible[idx[rows]]]
                new = idx[rows]
                visible[new] = True
                first_dim[new] = bounce_offset(bounce)
                if collect_pairs:
                    for key, val in (("bounce", bounce), ("position", surf.position[rows]),
                                     ("ng", surf.ng[rows]), ("ns", surf.ns[rows]),
                                     ("nn", (surf.ns if surf.nn is None else surf.nn)[rows]),
                                     ("mat_ids", surf.mat_ids[rows]), ("colors", surf.colors[rows]),
                                     ("wo", wo[rows]), ("flux", flux[rows]), ("prim", prim[rows]),
                                     ("medium", medium[rows])):
                        first[key][new] = val
                    if surf.tangent is not None:
                        first["tangent"][new] = surf.tangent[rows]
                    if surf.nc is not None:
                        first["nc"][new] = surf.nc[rows]
                    if kinds is not None:
                        first["kinds"][new] = kinds[new]
                    if diffuse_next is not None:
                        first["diffuse_next"][new] = diffuse_next[new]
                    if crossings is not None:
                        first["crossings"][new] = crossings[new]
                        first["first_crossings"][new] = first_crossings[new]
                if refresh_rng is not None and len(new) and bounce < max_bounces:
                    start = bounce_offset(bounce)
                    u[new, start:] = refresh_rng.random((len(new), u.shape[1] - start))
        if vert is not None:
            _deposit_in_volumes(ctx, target, vert, bounce, u, visible, first_dim, first, pairs, sums,
                                cell_test, collect_pairs, refresh_rng, max_bounces, kinds, diffuse_next,
                                None if crossings is None else (crossings, first_crossings))
        if resume is not None and bounce <= last_join:
            # Resumed paths join at their recorded vertex, after its (unchanged) deposits.
            join = np.flatnonzero(resume["bounce"] == bounce)
            in_volume = resume["volume"].take(join)
            if in_volume.any():
                jv = join[in_volume]
                joined = {"idx": fresh + jv, "position": resume["position"][jv], "d": -resume["wo"][jv],
                          "flux": resume["flux"][jv], "medium": resume["medium"][jv]}
                vert = joined if vert is None else {k: np.concatenate([vert[k], joined[k]]) for k in vert}
                join = join[~in_volume]
            if len(join):
                idx = np.concatenate([idx, fresh + join])
                flux = np.concatenate([flux, resume["flux"][join]])
                wo = np.concatenate([wo, resume["wo"][join]])
                prim = np.concatenate([prim, resume["prim"][join]])
                medium = np.concatenate([medium, resume["medium"][join]])
                surf = _join_surfaces(surf, resume, join, ctx.has_shading_normals, ctx.has_normal_maps,
                                      table.has_anisotropy, ctx.has_coat_normals)
        if bounce == max_bounces or (len(idx) == 0 and vert is None):
            continue
        if len(idx):
            # Scatter with this vertex's block of dimensions.
            block = u[idx, bounce_offset(bounce):bounce_offset(bounce) + BOUNCE_DIMS]
            mats, colors, ns, u0 = surf.mat_ids, surf.colors, surf.ns, block[:, 0]
            scores = lobe_scores(table, mats, colors)
            if table.has_coat:
                # The coat or what lies under it, by the lobe-choice number (rescaled for the lobes).
                mats, colors, scores, layer_scale, under, u0 = pick_coat(table, mats, colors, scores, u0)
                ns = coat_normals(surf, mats)
            lobe, prob = choose_lobe(scores, u0)
            u3 = (lobe_remainder(scores, u0, lobe) if table.has_rough_dielectric or ctx.subsurface_exit >= 0
                  else None)
            wi, weight, alive = scatter(table, mats, colors, lobe, prob, wo, surf.ng, ns,
                                        block[:, 1], block[:, 2], "importance", u3, surf.nn, surf.tangent)
            leave = None
            if ctx.subsurface_exit >= 0:
                # Some go beneath the surface and leave it elsewhere (their new origins: leave).
                leave = _beneath(ctx, u, idx, bounce, surf, prim, mats, colors, lobe, prob, u3, wo, wi,
                                 weight, alive)
            kind = None
            if (bounce == 0 and excluding) or (kinds is not None and bounce) or diffuse_next is not None:
                kind = scatter_kind(lobe, wi, wo, surf.ng)
            if bounce == 0 and excluding:
                alive &= (ctx.lights.excluded(u[idx, 0]) & kind) == 0
            if diffuse_next is not None:
                into = np.flatnonzero(kind == EXCLUDE_DIFFUSE)
                weight[into] *= diffuse_next.take(idx.take(into))[:, None]
                diffuse_next[idx] = _diffuse_next(table, target.limits, surf, mats, ns, lobe, kind, wi,
                                                  under if table.has_coat else None, leave)
            if kinds is not None and bounce:
                # (the first vertex's kind does not count: it is the one nearest the light)
                kinds[idx, np.where(kind == EXCLUDE_DIFFUSE, 0, np.where(kind == EXCLUDE_GLOSSY, 1, 2))] += 1
                alive &= (kinds.take(idx, axis=0) <= target.limits.array[1:]).all(axis=1)
            if table.has_coat:
                # Under a coat: its factor at the view (camera-side) direction, for photons the new one.
                weight *= layer_scale[:, None]
                if len(under):
                    weight[under] *= coat_attenuation(table, surf, wi, under)
            new_flux = flux * weight
            # Russian roulette on the luminance ratio (the path stays a function of u), without the
            # scale of refracted flux (bsdf.refraction_scale).
            ratio = luminance(new_flux) / np.maximum(luminance(flux), 1e-300)
            if table.has_dielectric:
                ratio /= refraction_scale(table, mats, lobe, wo, wi, surf.ng)
            q = np.minimum(1.0, ratio)
            alive &= (block[:, 3] < q) & (q > 0)
            keep = np.flatnonzero(alive)
            idx = idx.take(keep)
            flux = new_flux.take(keep, axis=0) / q.take(keep)[:, None]
            dirs = wi.take(keep, axis=0)
            position, ng, at = surf.position, surf.ng, prim
            if leave is not None:
                rows, position, ng, _, at = leave
            if volumes:
                medium = medium.take(keep)
                crossed = ctx.next_medium(medium, prim.take(keep), dirs, wo.take(keep, axis=0))
                # (photons that left an object where a walk took them stay in the volume they were in)
                medium = crossed if leave is None else np.where(np.isin(keep, rows), medium, crossed)
            origins = accel.spawn(position.take(keep, axis=0), ng.take(keep, axis=0), dirs, at.take(keep))
        else:
            flux, dirs, origins = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))
            medium = np.zeros(0, np.int32)
        if vert is not None:
            # Photons in volumes scatter by the phase function (its density: weight 1), with
            # Russian roulette on the albedo (the scattering's share of the extinction, for the
            # photon's colour).  The arriving flux holds T / p(t), about 1 / extinction: against
            # it, the scattered flux's share would be the scattering coefficient itself, which
            # (per unit of length) in thin fog killed most photons and multiplied the survivors'
            # flux by 1 / extinction at every scattering (x 6 each in a 0.17 / m fog).
            vidx = vert["idx"]
            block = u[vidx, bounce_offset(bounce):bounce_offset(bounce) + BOUNCE_DIMS]
            vmed = vert["medium"]
            d_v = sample_phase(ctx.phase.take(vmed, axis=0), vert["d"], block[:, 1], block[:, 2])
            f_v = vert["flux"] * ctx.scattering.take(vmed, axis=0)
            f_t = vert["flux"] * ctx.extinction.take(vmed, axis=0)
            q = np.minimum(1.0, luminance(f_v) / np.maximum(luminance(f_t), 1e-300))
            go = (block[:, 3] < q) & (q > 0)
            if kinds is not None and bounce:
                kinds[vidx, 3] += 1                     # (as at surfaces: not at the first vertex)
                go &= kinds[vidx, 3] <= target.limits.volume
            if diffuse_next is not None:
                diffuse_next[vidx] = 1.0                # (Cycles drops no closure after a volume's)
            keep = np.flatnonzero(go)
            idx = np.concatenate([idx, vidx.take(keep)])
            flux = np.concatenate([flux, f_v.take(keep, axis=0) / q.take(keep)[:, None]])
            dirs = np.concatenate([dirs, d_v.take(keep, axis=0)])
            medium = np.concatenate([medium, vmed.take(keep)])
            origins = np.concatenate([origins, vert["position"].take(keep, axis=0)])
    if collect_pairs and pairs["path"]:
        pp, pj = np.concatenate(pairs["path"]), np.concatenate(pairs["point"])
        pv, pb = np.concatenate(pairs["value"]), np.concatenate(pairs["bounce"])
    elif collect_pairs:
        pp, pj, pv, pb = np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int16)
    else:
        pp = pj = pv = pb = None
    total = None
    if own_sums:
        sums.flush()
        total = sums.total
    if focus is not None and n_resumed:
        aims = np.concatenate([aims, np.zeros(n_resumed)])
    return PhotonBatch(visible, first_dim, pp, pj, pv, pb, first, total, rays, vertices,
                       aims if focus is not None else None, None if cell_test is None else cell_test[2])


def _cell_open(visible, cell_test, lane):
    """Rows of the vertices of paths ``lane`` that the visible cells test: those of paths not yet
    visible, and of those whose oldest generation so far is newer than their floor."""
    test = ~visible.take(lane)
    _, floor, entry = cell_test
    if floor is not None:
        test |= entry.take(lane) > floor.take(lane)
    return np.flatnonzero(test)


def _cell_inside(cell_test, paths, gen):
    """(k,) bool: which vertices (of paths ``paths``, in cells of generations ``gen``) make their
    paths visible; keeps the paths' oldest generations (``PhotonBatch.entry``)."""
    limit, _, entry = cell_test
    entry[paths] = np.minimum(entry.take(paths), gen)
    return gen <= limit.take(paths)


def aim_moments(batch, rows):
    """(sum of w, sum of w^2, count) over the visible paths from afar among ``rows`` of ``batch``
    (its Focus's weights w, ``PhotonBatch.aims``; zeros without a focus): what the integrator's test
    of whether the focus pays sums."""
    if batch.aims is None:
        return 0.0, 0.0, 0
    a = batch.aims[rows]
    w = a[(a > 0) & batch.visible[rows]]
    return float(w.sum()), float((w * w).sum()), len(w)


def _walk_uniforms(u, idx, bounce):
    """The numbers of the random walks beneath surfaces of photons of paths ``idx`` at vertex
    ``bounce`` (``subsurface.random_walk``'s ``uniforms``; step MAX_STEPS: the direction they leave
    in): from a seed per walk hashed as :func:`_crossing_uniforms`' numbers from the light position
    dimensions and the vertex (``subsurface.hashed_uniforms``)."""
    key = np.full(len(idx), WALK_KEYS + bounce, np.uint32)
    high = hash_uint3(float_as_uint(u[idx, 1]), float_as_uint(u[idx, 2]), key)
    low = hash_uint3(float_as_uint(u[idx, 3]), high, key)
    seeds = (high.astype(np.uint64) << np.uint64(32)) | low.astype(np.uint64)

    def uniforms(rows, step):
        return subsurface.hashed_uniforms(seeds.take(rows), step)
    return uniforms


def _beneath(ctx, u, idx, bounce, surf, prim, mats, colors, lobe, prob, pick, wo, wi, weight, alive):
    """Photons of paths ``idx`` (at ``surf``, triangles ``prim``) that picked the diffuse lobe (``lobe``,
    with probability ``prob``)
    of a material that scatters beneath its surface (``Materials.subsurface_weight``) go beneath
    with that part's share (by ``pick``, the lobe number's remainder), as the light that Cycles'
    walks from a camera path reach: in a cosine-distributed direction (the exit's diffuse BSDF,
    weight 1), through a random walk (``core/subsurface.py``, its medium by the colour where
    they entered), and out of the surface where it ends as the camera's walks enter there
    (``subsurface.exit_directions``, the adjoint of their entry), with the part's weight at that
    direction (under a Fresnel layer, its factor there).  The others keep their diffuse lobe
    without the part.  Updates ``wi``, ``weight`` and ``alive`` (walks that do not leave, and
    photons that do not get out of the surface, are lost) in place; returns None or (rows,
    positions, normals, exit shading normals, triangles): the photons that left and where they leave
    from (the others' own positions, normals and triangles; the shading normals of the rows
    alone)."""
    materials, table, accel = ctx.materials, ctx.table, ctx.accel
    share = np.asarray(materials.subsurface_weight, np.float64).take(mats)
    rows = np.flatnonzero((lobe == DIFFUSE) & (share > 0) & alive)
    if len(rows) == 0:
        return None
    m = mats.take(rows)
    radius = np.asarray(materials.subsurface_radius, np.float64).take(m, axis=0)
    part = share.take(rows)[:, None] * (radius >= subsurface.MIN_RADIUS)
    q = part.mean(axis=1)
    into = pick.take(rows) < q
    stay = rows[~into]
    weight[stay] *= (1.0 - part[~into]) / (1.0 - q[~into, None])
    go, m, part, q = rows[into], m[into], part[into], q[into]
    if len(go) == 0:
        return None
    block = u[idx.take(go), bounce_offset(bounce):bounce_offset(bounce) + BOUNCE_DIMS]
    ng_in = face_forward(surf.ng.take(go, axis=0), wo.take(go, axis=0))
    n_in = face_forward(surf.ns.take(go, axis=0), ng_in)
    d = to_world(cosine_hemisphere(block[:, 1], block[:, 2]), -n_in)
    alive[go] = False
    # (a direction about the shading normal that stays above the surface does not enter: lost)
    enter = np.flatnonzero(dot(d, ng_in) < 0.0)
    go, m, part, q, d, ng_in, n_in = (a.take(enter, axis=0) for a in (go, m, part, q, d, ng_in, n_in))
    radius = radius[into].take(enter, axis=0)
    method = np.asarray(materials.subsurface_method).take(m)
    g = np.asarray(materials.subsurface_anisotropy, np.float64).take(m)
    sigma_t, albedo, scale = subsurface.medium(colors[go, DIFFUSE], radius, g, method,
                                               np.asarray(materials.subsurface_ior, np.float64).take(m))
    objects = None if accel.object_ids is None else accel.object_ids.take(prim.take(go))

    def intersect(r, origins, dirs, tmax):
        if objects is None:
            return accel.intersect(origins, dirs, tmax)
        return accel.local_scene().intersect(origins, dirs, tmax, objects.take(r))
    numbers = _walk_uniforms(u, idx.take(go), bounce)
    starts = accel.spawn_local(surf.position.take(go, axis=0), ng_in, d, prim.take(go))
    left, hits, d_out, beta = subsurface.random_walk(
        intersect, starts, d, n_in, sigma_t, albedo, g, scale / (prob.take(go) * q)[:, None], numbers)
    if len(left) == 0:
        return None
    out = go.take(left)
    v = numbers(left, subsurface.MAX_STEPS)
    pick = v[:, 0] if ctx.has_level_programs else None
    exit_ = ctx.surface(hits.prim_ids, hits.b1, hits.b2, pick, Rays(d_out))
    ng_out = face_forward(exit_.ng, d_out)
    n_out = face_forward(exit_.ns, ng_out)
    # Out as the camera's walks come in.
    ml = m.take(left)
    leave, through = subsurface.exit_directions(n_out, ng_out, d_out, *subsurface.entry(materials, ml),
                                                v[:, 3:6])
    w = part.take(left, axis=0) * (table.weight[ml, DIFFUSE] * through)[:, None]
    if table.has_layer:
        w *= table.layer_factor(ml, np.abs(dot(leave, n_out)))[:, None]
    wi[out] = leave
    weight[out] = beta * w
    alive[out] = (dot(leave, ng_out) > 0) & (through > 0)
    position, ng, at = surf.position.copy(), surf.ng.copy(), prim.copy()
    position[out], ng[out], at[out] = exit_.position, ng_out, hits.prim_ids
    return out, position, ng, n_out, at


def scatter_kind(lobe, wi, wo, ng):
    """(n,) uint8: the EXCLUDE_* bit of the rays that scatterings by ``lobe`` (n,) from ``wo`` to ``wi``
    stand for: diffuse for the diffuse, translucent and sheen lobes, transmission for a glass's refraction
    (``wi`` and ``wo`` on opposite sides of the geometric normal ``ng``), glossy for the others
    (Cycles' closure classes for its excluded lights)."""
    refracted = (lobe == DIELECTRIC) & (dot(wi, ng) * dot(wo, ng) < 0)
    return np.where((lobe == DIFFUSE) | (lobe == TRANSLUCENT) | (lobe == SHEEN), EXCLUDE_DIFFUSE,
                    np.where(refracted, EXCLUDE_TRANSMISSION, EXCLUDE_GLOSSY)).astype(np.uint8)


def _diffuse_next(table, limits, surf, mats, ns, lobe, kind, wi, under, leave):
    """(n,) what a diffuse event next is worth to photons that scattered at ``surf`` by ``lobe`` of
    materials ``mats`` (after :func:`~core.bsdf.pick_coat`; ``under``: the rows that chose what lies
    under a coat, or None) with ``kind`` (:func:`scatter_kind`) into ``wi``, with the Caustics toggles
    of ``limits``.  Cycles evaluates a path's vertex after a diffuse bounce without the closures whose
    caustics are off: 0 after a reflection (Reflective off) or a refraction (Refractive off).  Without
    the Principled BSDF's specular and coat layers (Reflective off) what lies under them is not
    attenuated by their albedo either: 1 / those factors (at ``wi``, the photon's view direction;
    at the exit of a walk beneath the surface for the rows of ``leave``) after its diffuse part, and
    1 / the coat's after its transmission."""
    out = np.ones(len(lobe))
    if not limits.caustics_refractive:
        out[kind == EXCLUDE_TRANSMISSION] = 0.0
    if limits.caustics_reflective:
        return out
    out[kind == EXCLUDE_GLOSSY] = 0.0
    d = np.flatnonzero(lobe == DIFFUSE)
    if table.has_layer and len(d):
        n = ns.take(d, axis=0)
        if leave is not None:
            n[np.searchsorted(d, leave[0])] = leave[3]          # (walks leave from diffuse rows only)
        out[d] /= np.maximum(table.layer_factor(mats.take(d), np.abs(dot(wi.take(d, axis=0), n))), 1e-12)
    if under is not None and len(under):
        out[under] /= np.maximum(coat_attenuation(table, surf, wi, under, albedo_only=True), 1e-12)
    return out


def _deposit_in_volumes(ctx, target, vert, bounce, u, visible, first_dim, first, pairs, sums, cell_test,
                        collect_pairs, refresh_rng, max_bounces, kinds=None, diffuse_next=None,
                        crossings=None):
    """Deposits of the photons that stopped in scattering volumes at vertex ``bounce`` (``vert``:
    their paths, positions, travel directions, arrival flux and volumes) on the target's volume
    points: flux times the scattering coefficient times the phase function towards each point's
    camera path.  As on surfaces, a pair found (or, with visible cells, a vertex in one of the
    volume cells) makes the path visible, and the paths that become so are recorded in
    ``first`` (``volume`` set) and have their later dimensions redrawn with ``refresh_rng``.
    ``kinds`` and ``diffuse_next`` as in :func:`trace_photons` (pairs keep to the limits:
    DepositTarget.bounce_filter; a volume point's scattering is not a diffuse bounce), and
    ``crossings`` its (crossings, first_crossings) (DepositTarget.crossing_filter) or None.
    ``cell_test``: None, or the trace's (limit, floor, entry) for the visible cells (``_cell_open``)."""
    idx, x, d, vmed = vert["idx"], vert["position"], vert["d"], vert["medium"]
    seen = np.zeros(len(idx), bool)
    if target.volume is not None:
        pi, pj, phase = target.volume_pairs(x, d)
        if len(pi) and target.room is not None:
            keep = np.flatnonzero(target.bounce_filter(
                pj, bounce, None if kinds is None else kinds.take(idx.take(pi), axis=0), volume=True)[0])
            pi, pj = pi.take(keep), pj.take(keep)
            if np.ndim(phase):
                phase = phase.take(keep)
        if len(pi) and crossings is not None:
            lanes = idx.take(pi)
            total, before = crossings[0].take(lanes), crossings[1].take(lanes)
            keep = np.flatnonzero(target.crossing_filter(pj, total, before))
            pi, pj = pi.take(keep), pj.take(keep)
            if np.ndim(phase):
                phase = phase.take(keep)
        if len(pi):
            f = vert["flux"] * ctx.scattering.take(vmed, axis=0)
            # One phase value for all pairs (even scattering) multiplies the photons, not the pairs.
            f = (f * phase).take(pi, axis=0) if np.ndim(phase) == 0 else f.take(pi, axis=0) * phase[:, None]
            path, slots = idx.take(pi), pj
            if target.light_passes and bounce == 0:
                # (light passes: photons at their first vertex go to the direct block)
                slots = np.where(target.split.take(pj), pj + target.direct_slots, pj)
            counted = len(slots)
            copies = (None if target.group_blocks is None
                      else target.group_pairs(ctx.lights.groups_of(u[path, 0]), pj))
            if copies is not None:
                # (light groups: copies of the pairs on the groups' blocks)
                path = np.concatenate([path, path.take(copies[0])])
                slots = np.concatenate([slots, copies[1]])
                f = np.concatenate([f, f.take(copies[0], axis=0)])
            if collect_pairs:
                pairs["path"].append(path)
                pairs["point"].append(slots)
                pairs["value"].append(f)
                pairs["bounce"].append(np.full(len(slots), bounce, np.int16))
            else:
                sums.add(slots, [f[:, c] for c in range(3)], counted)
            if target.cells is None:
                seen[pi] = True
    if target.cells is not None:
        open_ = _cell_open(visible, cell_test, idx)
        if len(open_):
            gen = target.cells.entry(x.take(open_, axis=0), None, volume=True)
            seen[open_[_cell_inside(cell_test, idx.take(open_), gen)]] = True
    rows = np.flatnonzero(seen & ~visible[idx])
    if len(rows) == 0:
        return
    new = idx[rows]
    visible[new] = True
    first_dim[new] = bounce_offset(bounce)
    if first is not None:
        for key, val in (("bounce", bounce), ("position", x[rows]), ("mat_ids", vmed[rows]), ("wo", -d[rows]),
                         ("flux", vert["flux"][rows]), ("prim", -1), ("medium", vmed[rows]),
                         ("volume", True)):
            first[key][new] = val
        if kinds is not None:
            first["kinds"][new] = kinds[new]
        if diffuse_next is not None:
            first["diffuse_next"][new] = diffuse_next[new]
        if crossings is not None:
            first["crossings"][new] = crossings[0][new]
            first["first_crossings"][new] = crossings[1][new]
    if refresh_rng is not None and bounce < max_bounces:
        start = bounce_offset(bounce)
        u[new, start:] = refresh_rng.random((len(new), u.shape[1] - start))


def _join_surfaces(surf, resume, join, has_shading_normals, has_normal_maps, has_anisotropy,
                   has_coat_normals):
    """``surf`` followed by the recorded vertices ``join`` of ``resume``."""
    def cat(a, key):
        return np.concatenate([a, resume[key][join]])
    ng = cat(surf.ng, "ng")
    ns = cat(surf.ns, "ns") if has_shading_normals else ng
    nn = cat(surf.nn, "nn") if has_normal_maps else None
    tangent = cat(surf.tangent, "tangent") if has_anisotropy else None
    nc = cat(surf.nc, "nc") if has_coat_normals else None
    return Surface(cat(surf.position, "position"), ng, ns, cat(surf.mat_ids, "mat_ids"),
                   cat(surf.colors, "colors"), nn, tangent, nc)

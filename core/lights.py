"""Photon emission: choose an emitter by power and sample a photon ray from it.

Emitters are the analytic lights of the scene, every emissive triangle, every
glowing volume and the world background.  Each photon uses the six light dimensions of its primary
sample (``algorithm.md`` section 4):

    [0] emitter choice  [1] position 0  [2] position 1  [3] side  [4] direction 0  [5] direction 1

and carries the flux ``Phi`` = emitted power / (probability density of its
choice), so that the sum of ``Phi`` over N photons divided by N estimates the
total emitted power.  Units follow Cycles (``scene.py``).  The sun and the world, which have no
side, take [3] for :class:`Focus`'s choice of disc.
"""
from __future__ import annotations

import numpy as np

from . import sampling as smp
from .environment import Environment
from .procedural import Rays, photon_path
from .scene import ALL_LINKS, AREA_DISK, AREA_RECT, EXCLUDE_ALL, POINT, SPOT, SUN, linked

LIGHT_DIMS = 6
# Focus (photons from afar aimed at what the camera sees, Focus): the share of them that still start
# anywhere on the scene's disc (the defensive part of the mixture), the shares of the measurement
# points the focus sphere may cover, and the largest modelled variance (Focus.around) at which the
# render aims photons.
FOCUS_UNIFORM_SHARE = 0.5
FOCUS_QUANTILES = (0.5, 0.75, 0.9, 0.95, 0.99, 1.0)
FOCUS_MAX_VARIANCE = 0.5
# Under light portals, the share of the world's light samples (LightSampler._world_samples) that keep
# the cosine's or the image's directions where a portal faces the point (the rest aim through
# the portals): the defensive part, bounding the variance where the portals do not pay at 1 / it
# times the cosine's.  A sky through an opening with a portal (test_direct_light): pixels' RMS
# 26 % at 1/2, 14 % at 1/4, 8.5 % at 1/10 (16 samples a pixel); benchmarks/portal_cost.py.
PORTAL_SAMPLE_SHARE = 0.25
# The visible photons from afar a render's focused passes must have had before it judges the focus
# by them (core/integrator.py).
FOCUS_MIN_VISIBLE = 64
# Emitter kinds in the combined table (analytic kinds keep their Lights.kind value).
TRIANGLE, WORLD, VOLUME = 10, 11, 12
# A glowing volume's photons start on lines through its mesh, each traced through at most this many
# of the mesh's faces (GlowingVolume).
MAX_GLOW_CROSSINGS = 64
# Textured emitters: the power of each emissive triangle is estimated from its radiance at up to
# TEXTURED_POWER_SIDE^2 stratified points (fewer when the mesh has more than TEXTURED_POWER_BUDGET
# / that many triangles), kept at least TEXTURED_POWER_FLOOR times its material's mean.
TEXTURED_POWER_SIDE = 4
TEXTURED_POWER_BUDGET = 1 << 18
TEXTURED_POWER_FLOOR = 0.05


class Focus:
    """Where the photons from afar (the sun's, the world's) are aimed: a sphere around what the camera
    sees.  Such a photon starts on the disc of the scene's bounding sphere perpendicular to its
    direction, uniformly (what it did without a focus) with the chance ``uniform_share``, else
    uniformly on the disc of this sphere in the same plane; its flux is divided by the density of
    that mixture relative to the scene's disc, so every photon of either part keeps the estimate
    exact (a one-sample mixture, the defensive part bounding what a useless focus costs:
    1 / ``uniform_share`` times the variance).  A long lens on a corner of a town (``small_view``)
    sees a few square metres, and the town in a glass ball's reflections: 99 % of its points lie
    within a sphere whose disc is 4 % of the town's, and the aimed photons land there.  Where the
    scene has light portals (Cycles' portals in its windows, ``World.portals``) the aimed part goes
    through them instead (:meth:`through`)."""

    def __init__(self, center, radius, uniform_share=FOCUS_UNIFORM_SHARE, portals=None, portal_disks=None):
        self.center = np.asarray(center, np.float64).reshape(3)
        self.radius = float(radius)
        self.uniform_share = float(uniform_share)
        # Portals (World.portals) instead of the sphere: (K, 3, 3) centre, half extents u and v
        # (photons cross along u x v), (K,) bool ellipses; their unit normals, areas and the dual
        # basis of (u, v) in their planes.
        self.portals = self.portal_disks = None
        if portals is not None and len(portals):
            self.portals = np.asarray(portals, np.float64).reshape(-1, 3, 3)
            self.portal_disks = np.asarray(portal_disks, bool).reshape(len(self.portals))
            u, v = self.portals[:, 1], self.portals[:, 2]
            cross = np.cross(u, v)
            size = np.sqrt(smp.dot(cross, cross))[:, None]
            self._normal = cross / size
            self._area = size[:, 0] * np.where(self.portal_disks, np.pi, 4.0)
            self._dual_u = np.cross(v, self._normal) / size
            self._dual_v = np.cross(self._normal, u) / size

    @property
    def portal_count(self) -> int:
        """The portals aimed at (0: the sphere)."""
        return 0 if self.portals is None else len(self.portals)

    def to_array(self) -> np.ndarray:
        if self.portals is None:
            return np.array([*self.center, self.radius, self.uniform_share], np.float64)
        return np.concatenate([self.center, [self.radius, self.uniform_share],
                               np.column_stack([self.portals.reshape(-1, 9), self.portal_disks]).ravel()])

    def holds(self, origins, dirs) -> np.ndarray:
        """(n,) bool: the rays from ``origins`` along ``dirs`` (n, 3) start on this sphere's disc
        across them (pass within its radius of the centre)."""
        return _off_axis2(origins - self.center, dirs) <= (self.radius * (1.0 + 1e-9)) ** 2

    @staticmethod
    def from_array(a) -> "Focus":
        a = np.asarray(a, np.float64)
        if len(a) == 5:
            return Focus(a[:3], a[3], a[4])
        rows = a[5:].reshape(-1, 10)
        return Focus(a[:3], a[3], a[4], rows[:, :9], rows[:, 9] > 0.5)

    @staticmethod
    def through(world, lights, uniform_share=FOCUS_UNIFORM_SHARE) -> "Focus | None":
        """The focus on the world's portals (Cycles' light portals in windows, ``World.portals``), or
        None without portals or an emitter from afar.  With the chance ``1 - uniform_share`` a photon
        from afar whose direction d crosses some portal into the scene (d . n > 0) starts on the
        scene's disc across d where it passes through one of them, chosen by its area projected
        across d, A |d . n|, uniformly over it: density N(o, d) / P(d) on that plane, P the sum of
        the projected areas and N the portals the line crosses (so weights stay exact where
        portals overlap across d).  The sun's photons go through them too (Cycles' portals guide
        only the world's samples: here they are a density, not a light)."""
        portals = getattr(world, "portals", None)
        if portals is None or not len(portals) or not np.isin(lights.kinds, (SUN, WORLD)).any():
            return None
        return Focus(np.zeros(3), 0.0, uniform_share, portals, world.portal_disks)

    def projected(self, d) -> np.ndarray:
        """(n, K) the portals' areas projected across directions ``d`` (n, 3), 0 where d does not
        cross one into the scene."""
        return self._area * np.maximum(d @ self._normal.T, 0.0)

    def _lines(self, origins, d):
        """The lines from ``origins`` along ``d`` (n, 3) against every portal's plane: (d . n (n, K),
        the distances t (n, K) along d to the planes (0 where parallel), (n, K) bool whether the
        line meets the plane within the portal)."""
        facing = d @ self._normal.T
        height = smp.dot(self.portals[:, 0], self._normal)[None, :] - origins @ self._normal.T
        t = height / np.where(facing != 0, facing, 1.0) * (facing != 0)
        p = origins[:, None, :] + t[:, :, None] * d[:, None, :] - self.portals[None, :, 0]
        x = np.einsum("nkj,kj->nk", p, self._dual_u)
        y = np.einsum("nkj,kj->nk", p, self._dual_v)
        inside = np.where(self.portal_disks, x * x + y * y, np.maximum(x * x, y * y)) <= 1.0 + 1e-6
        return facing, t, inside & (facing != 0)

    def crossings(self, origins, d) -> np.ndarray:
        """(n,) how many portals the lines from ``origins`` along ``d`` (n, 3) cross into the scene."""
        facing, _, inside = self._lines(origins, d)
        return ((facing > 0) & inside).sum(axis=1).astype(np.float64)

    def seen_from(self, x) -> np.ndarray:
        """(n, K) how much each portal is worth aiming at from points ``x`` (n, 3) inside, A h /
        (D^2 + A)^(3/2) (its solid angle A h / D^3 as seen from afar, bounded near it; D the
        distance to its centre, h the height over its plane on the scene's side, 0 on the
        other side)."""
        to = x[:, None, :] - self.portals[None, :, 0]
        h = np.maximum(np.einsum("nkj,kj->nk", to, self._normal), 0.0)
        return self._area * h / (np.einsum("nkj,nkj->nk", to, to) + self._area) ** 1.5

    def points_on(self, weights, u1, u2, u3):
        """(n, 3) points uniform on a portal picked with chances ``weights`` (n, K) (rows with a
        positive sum) by ``u3``, placed on it by ``u1``, ``u2`` (concentric on an ellipse)."""
        cumulative = np.cumsum(weights, axis=1)
        pick = u3 * cumulative[:, -1]
        k = np.minimum((cumulative <= pick[:, None]).sum(axis=1), len(self.portals) - 1)
        disk = self.portal_disks[k]
        cx, cy = smp.concentric_disk(u1, u2)
        a = np.where(disk, cx, 2.0 * u1 - 1.0)[:, None]
        b = np.where(disk, cy, 2.0 * u2 - 1.0)[:, None]
        return self.portals[k, 0] + a * self.portals[k, 1] + b * self.portals[k, 2]

    def sample_towards(self, x, weights, u1, u2, u3):
        """(n, 3) unit directions from points ``x`` (n, 3) towards :meth:`points_on`."""
        return smp.normalize(self.points_on(weights, u1, u2, u3) - x)

    def towards_pdf(self, x, weights, d) -> np.ndarray:
        """(n,) the density per solid angle of :meth:`sample_towards` with ``weights`` at the unit
        directions ``d`` (n, 3): over the portals the ray from x along d leaves the scene through,
        their chance times t^2 / (A |d . n|) (exact where portals overlap along d)."""
        facing, t, inside = self._lines(x, d)
        # (a portal of positive weight has x on its scene side: a ray leaving through it meets it ahead)
        through = inside & (facing < 0)
        total = weights.sum(axis=1, keepdims=True)
        chance = weights / np.where(total > 0, total, 1.0)
        per = np.where(through, chance * t * t / (self._area * np.where(through, -facing, 1.0)), 0.0)
        return per.sum(axis=1)

    @staticmethod
    def around(positions, reach, lights, uniform_share=FOCUS_UNIFORM_SHARE) -> "Focus | None":
        """The focus on points ``positions`` (n, 3) (the first pass's measurement points) with gather
        radii ``reach`` (n,), or None where it would not pay.  Its sphere is centred on the points'
        median and holds the discs of one of FOCUS_QUANTILES of them, grown by a tenth (later
        passes' points move within their pixels): the one with the least modelled variance of the
        points' photon counts, sum over points of 1 / (their photon density over the uniform
        disc's) / n, i.e. share q inside with density s + (1 - s) (R / r)^2, the rest s.  It pays
        where that is at most FOCUS_MAX_VARIANCE (1 without a focus).  The points seen in a glass
        ball's reflections are few but far apart (``small_view``: 99 % within 24 m of the median,
        all within 60 m, of a town 142 m in radius), hence the quantiles.  None also without an
        emitter from afar or any point."""
        if len(positions) == 0 or not np.isin(lights.kinds, (SUN, WORLD)).any():
            return None
        positions = np.asarray(positions, np.float64)
        if not np.isfinite(positions).all():
            return None
        centre = np.median(positions, axis=0)
        far = np.quantile(np.sqrt(((positions - centre) ** 2).sum(axis=1)) + reach, FOCUS_QUANTILES)
        radius = np.maximum(1.1 * far, 1e-9)
        s = uniform_share
        inside = s + (1.0 - s) * (lights.radius / radius) ** 2
        variance = np.asarray(FOCUS_QUANTILES) / inside + (1.0 - np.asarray(FOCUS_QUANTILES)) / s
        best = int(np.argmin(variance))
        if variance[best] > FOCUS_MAX_VARIANCE:
            return None
        return Focus(centre, radius[best], s)


class LightSampler:
    """Power-proportional choice over all emitters and their photon sampling."""

    def __init__(self, scene, accel, table, emitted=None, opacity=None, varies=None,
                 distant_transmittance=None, volume_emission=None, light_path=False):
        """``distant_transmittance`` (3,): the share of the light from afar (the sun, the world)
        that reaches the scene (the world's volume, RenderContext.outside), or None: all.
        ``volume_emission`` (>= M, 3): each material's ``Materials.volume_emission``, or None.
        ``light_path``: whether some program reads the Light Path (``RenderContext.reads_light_path``)."""
        lights = scene.lights
        # Radiance leaving points of emissive triangles, emission times opacity
        # (RenderContext.emitted_out), for emitters where it varies (``varies`` per material);
        # ``opacity`` (per material, constant) scales the others.
        self.emitted = emitted
        self.light_path = light_path
        m = table.emission.shape[0]
        self.opacity = np.ones(m) if opacity is None else np.asarray(opacity, np.float64)
        self.varies = np.zeros(m, bool) if varies is None else np.asarray(varies, bool)
        emissive_varies = self.varies & table.is_emissive
        self.textured_emitters = emitted is not None and bool(emissive_varies.any())
        # Emitters under a coat (Materials.coat_weight) emit through it: its factor at the direction.
        self.coated_emitters = bool(table.has_coat and scene.triangle_count
                                    and (table.coat_row[scene.material_ids] >= 0).any())
        # Emitters under a sheen (Materials.sheen_cover), dimmed by it likewise.
        self.sheened_emitters = bool(table.has_sheen and scene.triangle_count
                                     and (table.sheen_cover[scene.material_ids] > 0).any())
        self.table, self.material_ids = table, scene.material_ids
        self.lights = lights
        # Emission axes renormalised in float64 (the scene stores them in float32).
        self.axes = smp.normalize(lights.direction.astype(np.float64)) if lights.count else np.zeros((0, 3))
        self.accel = accel
        lo, hi = accel.bounds
        self.center = 0.5 * (lo + hi)
        self.radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)  # bounding sphere radius
        self.profile_mean = np.maximum(profile_means(lights.profiles), 1e-12)
        self.has_profiles = bool(lights.count and (lights.profile >= 0).any())
        # Directions of lights with a profile are drawn from it (cells of its table by their mean
        # value times solid angle, uniform within a cell; a spot's cone, around the profile's v = 0,
        # keeps the rows that start inside it; an area light's, times the cosine at the row's
        # start, the rows of its front): one table per light, -1 none.  Area lights with a
        # narrow spread keep their cone's directions, weighted.
        self.profile_cdf, self.cdf_row = None, None
        full = ~np.isin(lights.kind, (AREA_RECT, AREA_DISK)) | (0.5 * lights.spread >= FULL_SPREAD)
        sampled = np.flatnonzero((lights.profile >= 0) & (lights.kind != SUN) & full) \
            if self.has_profiles else np.zeros(0, np.int64)
        if len(sampled):
            kinds = lights.kind.take(sampled)
            cones = np.where(kinds == SPOT, 0.5 * lights.spot_angle.take(sampled),
                             np.where(kinds == POINT, np.pi, 0.5 * np.pi))
            self.profile_cdf = profile_cdfs(lights.profiles.take(lights.profile.take(sampled), axis=0), cones,
                                            lambert=np.isin(kinds, (AREA_RECT, AREA_DISK)))
            self.cdf_row = np.full(lights.count, -1, np.int64)
            self.cdf_row[sampled] = np.arange(len(sampled))
        # Analytic lights (a loop over the few lights, not over photons).
        self.light_scale = np.array([self._light_scale(i) for i in range(lights.count)], np.float64)
        light_power = (lights.power.astype(np.float64) * self.light_scale[:, None]).reshape(-1, 3) \
            if lights.count else np.zeros((0, 3))
        # Emissive triangles: two-sided Lambertian, power 2 pi A L.
        tri_mat = scene.material_ids
        emissive_tris = np.flatnonzero(table.is_emissive[tri_mat] & (accel.area > 0)) \
            if scene.triangle_count else np.zeros(0, np.int64)
        emissive_mats = tri_mat.take(emissive_tris)
        tri_power = ((2.0 * np.pi * accel.area[emissive_tris] * self.opacity.take(emissive_mats))[:, None]
                     * table.emission.take(emissive_mats, axis=0))
        if self.textured_emitters:
            textured = np.flatnonzero(self.varies.take(emissive_mats))
            tri_power[textured] = self._textured_power(emissive_tris.take(textured), tri_mat)
        # World: a constant colour or an image (core/environment.py) seen through the bounding sphere.
        world = np.asarray(scene.world.color, np.float64)
        texture = scene.world.texture
        self.environment = (Environment(world, texture, scene.world.texture_rotation)
                            if texture is not None else None)
        if self.environment is not None:
            world = self.environment.integral / (4.0 * np.pi)     # the mean radiance, for the power
        # Light portals (World.portals) guide the world's light samples (sample_direct) as Cycles'
        # guide its world samples; the photons' focus on them is the integrator's (Focus.through).
        portals = getattr(scene.world, "portals", None)
        self.portals = (Focus(np.zeros(3), 0.0, PORTAL_SAMPLE_SHARE, portals, scene.world.portal_disks)
                        if portals is not None and len(portals) else None)
        n_world = 1 if world.any() else 0
        # Glowing volumes: 4 pi E V each, V the volume their material's triangles enclose.
        self.volumes = {}
        glow = np.zeros((0, 3)) if volume_emission is None else np.asarray(volume_emission, np.float64)
        if scene.triangle_count:
            for m in np.flatnonzero((glow[:scene.materials.count] > 0).any(axis=1)):   # the few glowing ones
                tris = np.flatnonzero(tri_mat == m)
                if len(tris):
                    v = GlowingVolume(accel, tris)
                    if v.volume > 0:
                        self.volumes[int(m)] = v
        glow_mats = np.array(sorted(self.volumes), np.int64)
        volume = np.array([self.volumes[m].volume for m in glow_mats], np.float64)
        glow_power = 4.0 * np.pi * volume[:, None] * glow.take(glow_mats, axis=0)
        n_volumes = len(glow_mats)
        all_kinds = np.concatenate([lights.kind.astype(np.int32) if lights.count else np.zeros(0, np.int32),
                                    np.full(len(emissive_tris), TRIANGLE, np.int32),
                                    np.full(n_world, WORLD, np.int32), np.full(n_volumes, VOLUME, np.int32)])
        all_ids = np.concatenate([np.arange(lights.count), emissive_tris, np.zeros(n_world, np.int64),
                                  glow_mats])
        world_power = (world * 4.0 * np.pi * np.pi * self.radius ** 2).reshape(1, 3)[:n_world]
        self.world_radiance = world              # (3,) the constant world's radiance (unused with an image)
        # (3,) the share of the sun's and the world's light that reaches the scene
        self.far = (np.ones(3) if distant_transmittance is None
                    else np.asarray(distant_transmittance, np.float64))
        if distant_transmittance is not None:
            far = np.asarray(distant_transmittance, np.float64)
            light_power = np.where((lights.kind == SUN)[:, None], light_power * far, light_power) \
                if lights.count else light_power
            world_power = world_power * far
        all_power = np.concatenate([light_power, tri_power.reshape(-1, 3), world_power, glow_power])
        score = smp.luminance(all_power)
        # The rays each emitter does not light (Lights.exclude, Scene.emitter_exclude, World.exclude;
        # glowing volumes light everything): an emitter that lights none sends no photons.
        tri_exclude = (scene.emitter_exclude.take(emissive_tris) if scene.emitter_exclude is not None
                       else np.zeros(len(emissive_tris), np.uint8))
        exclude = np.concatenate([lights.exclude if lights.count else np.zeros(0, np.uint8), tri_exclude,
                                  np.full(n_world, scene.world.exclude, np.uint8),
                                  np.zeros(n_volumes, np.uint8)]).astype(np.uint8)
        keep = (score > 0) & (exclude != EXCLUDE_ALL)
        self.exclude = exclude[keep]
        self.has_exclusion = bool(self.exclude.any())
        self.kinds, self.ids, self.power = all_kinds[keep], all_ids[keep], all_power[keep]
        # Light and shadow linking: the receiver sets each emitter lights (Scene.receiver_sets) and
        # the blocker sets that shadow it (Scene.blocker_sets), the world's all of them, and
        # whether any emitter leaves one out.
        def per_emitter(light_links, tri_links):
            tri = (tri_links.take(emissive_tris) if tri_links is not None
                   else np.full(len(emissive_tris), ALL_LINKS, np.uint64))
            light = light_links if lights.count else np.zeros(0, np.uint64)
            return np.concatenate([light, tri, np.full(n_world + n_volumes, ALL_LINKS, np.uint64)])[keep]
        self.links = per_emitter(lights.links, scene.emitter_links)
        self.has_links = bool((self.links != ALL_LINKS).any())
        self.shadow_links = per_emitter(lights.shadow_links, scene.emitter_shadow_links)
        self.has_shadow_links = bool((self.shadow_links != ALL_LINKS).any())
        # Light groups (Lights.group, Scene.emitter_group, World.group; a glowing volume's is that of
        # most of its material's triangles, material_groups): each emitter's, -1 none.
        tri_group = (scene.emitter_group.take(emissive_tris) if scene.emitter_group is not None
                     else np.full(len(emissive_tris), -1, np.int16))
        volume_group = material_groups(scene, glow_mats).astype(np.int16)
        self.group = np.concatenate([lights.group if lights.count else np.zeros(0, np.int16), tri_group,
                                     np.full(n_world, scene.world.group, np.int16),
                                     volume_group])[keep].astype(np.int64)
        score = score[keep]
        self.count = len(score)
        if self.count:
            self.cdf = np.cumsum(score) / score.sum()
            self.cdf[-1] = 1.0
            self.prob = score / score.sum()
        else:
            self.cdf = np.zeros(0)
            self.prob = np.zeros(0)

    def _light_scale(self, i):
        """The factor of light ``i``'s ``Lights.power`` that gives the watts it emits (for the
        choice probabilities)."""
        L = self.lights
        kind = L.kind[i]
        # An angular profile: its mean over the sphere (the cone's mean is left out: only the
        # choice of lights uses this).
        scale = float(self.profile_mean[L.profile[i]]) if L.profile[i] >= 0 else 1.0
        if kind == SPOT:
            # Intensity P/(4 pi) over the cone of solid angle 2 pi (1 - cos_half), times the mean
            # of the smoothstep edge over that cone, which is exactly 1 - blend/2.
            cos_half = np.cos(L.spot_angle[i] / 2)
            return scale / 2 * (1.0 - cos_half) * _spot_mean_mask(L.spot_blend[i])
        if kind == SUN:
            return scale * np.pi * self.radius ** 2
        return scale

    def _sample_profile(self, ids, u1, u2):
        """(directions (n, 3), pdf per steradian (n,)) drawn from the profiles of lights ``ids``."""
        L = self.lights
        table = L.profiles
        rows, cols = table.shape[1] - 1, table.shape[2] - 1
        k = self.cdf_row.take(ids)
        cdf = self.profile_cdf
        cell = np.empty(len(ids), np.int64)
        for j in np.unique(k):                   # a loop over the few profiled lights
            sel = np.flatnonzero(k == j)
            cell[sel] = np.minimum(np.searchsorted(cdf[j], u1[sel], side="right"), rows * cols - 1)
        lo = np.where(cell > 0, cdf[k, np.maximum(cell - 1, 0)], 0.0)
        p_cell = np.maximum(cdf[k, cell] - lo, 1e-300)
        t = np.clip((u1 - lo) / p_cell, 0.0, 1.0)                  # the remainder of u1, in the cell
        r, c = np.divmod(cell, cols)
        cos_a, cos_b = np.cos(r * (np.pi / rows)), np.cos((r + 1) * (np.pi / rows))
        cos_v = cos_a + t * (cos_b - cos_a)
        h = (c + u2) * (2.0 * np.pi / cols)
        sin_v = np.sqrt(np.maximum(1.0 - cos_v * cos_v, 0.0))
        # Local (x, y, z) = (-sin v sin h, -sin v cos h, -cos v), z along -direction (an area
        # light's axes are its half extents: their directions).
        axis_u = smp.normalize(L.axis_u.take(ids, axis=0).astype(np.float64))
        axis_v = smp.normalize(L.axis_v.take(ids, axis=0).astype(np.float64))
        d = (-(sin_v * np.sin(h))[:, None] * axis_u - (sin_v * np.cos(h))[:, None] * axis_v
             + cos_v[:, None] * L.direction.take(ids, axis=0))
        solid = (cos_a - cos_b) * (2.0 * np.pi / cols)
        return smp.normalize(d), p_cell / solid

    # ------------------------------------------------------------------ soft falloff
    @property
    def has_soft_falloff(self) -> bool:
        """Whether any point or spot light of non-zero radius has Soft Falloff."""
        L = self.lights
        return bool(L.count and (np.isin(L.kind, (POINT, SPOT)) & L.soft_falloff & (L.radius > 0)).any())

    def soft_falloff(self, u, positions):
        """(n,) flux factors d^2 / (d^2 + r^2) at the first hits ``positions`` (n, 3) of photons
        with light dimensions ``u`` (n, >=1); 1 for photons of other emitters.

        Cycles shows a point or spot light with Soft Falloff as a disk of radius r facing the
        shading point, whose irradiance at distance d is P / (4 pi (d^2 + r^2)) where the
        sphere (what the photons leave) gives P / (4 pi d^2).  The factor, applied where the
        photon first lands, turns the one into the other (exactly for receivers facing the
        light; the disk's tilt towards other receivers is left out)."""
        out = np.ones(len(u))
        if not self.has_soft_falloff or len(u) == 0:
            return out
        L = self.lights
        entry = self.entries(u[:, 0])
        sel = np.flatnonzero(np.isin(self.kinds.take(entry), (POINT, SPOT)))
        ids = self.ids.take(entry.take(sel))
        soft = L.soft_falloff.take(ids) & (L.radius.take(ids) > 0)
        sel, ids = sel[soft], ids[soft]
        offset = positions.take(sel, axis=0) - L.position.take(ids, axis=0)
        d2 = np.einsum("ij,ij->i", offset, offset)
        r2 = L.radius.take(ids).astype(np.float64) ** 2
        out[sel] = d2 / (d2 + r2)
        return out

    # ------------------------------------------------------------------ seen by camera rays
    def visible_to(self, flags) -> bool:
        """Whether any analytic light can be seen by rays of the ``VISIBLE_*`` kinds in ``flags``."""
        L = self.lights
        return bool(L.count and (L.visibility & flags).any())

    def seen_radiance(self, origins, dirs, t_max, escaped, flags, sets=None, attenuation=None, split=None):
        """(n, 3) radiance of the analytic lights that rays ``origins + t dirs`` cross.

        Rays are camera-path segments of the kinds in ``flags`` (n,) (bits ``VISIBLE_*``); a
        light counts when its visibility shares a bit with the ray's, it lies at 0 < t <
        ``t_max`` (the scene hit, or the clip distance), and, for the sun, when the ray
        ``escaped`` the scene.  Lights are transparent (Cycles adds their emission and goes
        on), so every crossed light adds.  Radiances are those the photons are emitted with:
        area P / (pi A) from the front only (times its spread attenuation); sphere
        P / (4 pi^2 r^2) (spot: times its smoothstep mask towards the viewer; with
        ``soft_falloff`` the disk of radius r through the centre facing the ray's origin);
        sun P / (pi sin^2(angle / 2)) (Cycles).  ``sets`` (n,), for rays that left a reflection or
        refraction: the receiver set of its triangle (Scene.receiver_sets); a linked light counts
        only for those it lights (camera rays see every light, as in Cycles).  ``attenuation``,
        a function of (rays (k,), distances (k,)) -> (k, 3), is what reaches each light crossed
        from the rays' origins (transparent surfaces and volumes on the way; inf for the sun), or
        None: nothing in between.  ``split`` (G, n, 3), or None: gets each light's radiance at the
        rows of its light group (``Lights.group``; lights in none are left out).
        A loop over the lights, each vectorised over the rays.
        """
        n = len(dirs)
        out = np.zeros((n, 3))
        L = self.lights
        for i in np.flatnonzero(L.visibility):
            seen = flags & L.visibility[i]
            if sets is not None and L.links[i] != ALL_LINKS:
                seen = np.where(linked(L.links[i], sets), seen, 0)
            rays = np.flatnonzero(seen)
            if len(rays) == 0:
                continue
            o, d, tm = origins.take(rays, axis=0), dirs.take(rays, axis=0), t_max.take(rays)
            p = L.power[i].astype(np.float64)
            kind, axis = L.kind[i], self.axes[i]
            if kind in (AREA_RECT, AREA_DISK):
                au, av = L.axis_u[i].astype(np.float64), L.axis_v[i].astype(np.float64)
                cross = float(np.linalg.norm(np.cross(au, av)))
                area = (4.0 if kind == AREA_RECT else np.pi) * cross
                if area <= 0:
                    continue
                cos = d @ axis
                front = cos < 0                              # travelling into the emitting face
                t = ((L.position[i] - o) @ axis) / np.where(front, cos, -1.0)
                q = o + t[:, None] * d - L.position[i]
                x, y = (q @ au) / (au @ au), (q @ av) / (av @ av)
                if kind == AREA_RECT:
                    inside = np.maximum(np.abs(x), np.abs(y)) <= 1.0
                else:
                    inside = x * x + y * y <= 1.0
                hit = front & (t > 0) & (t < tm) & inside
                radiance = np.broadcast_to(p / (np.pi * area), (len(rays), 3))
                if L.spread[i] < 2.0 * FULL_SPREAD:
                    radiance = radiance * spread_attenuation(-cos, 0.5 * float(L.spread[i]))[:, None]
                if L.profile[i] >= 0:
                    radiance = radiance * profile_factor(L, np.full(len(rays), i), -d)[:, None]
            elif kind in (POINT, SPOT):
                r = float(L.radius[i])
                if r <= 0:
                    continue
                oc = o - L.position[i]
                b = np.einsum("ij,ij->i", oc, d)
                oc2 = np.einsum("ij,ij->i", oc, oc)
                if L.soft_falloff[i]:
                    # A disk of radius r through the centre, facing the ray's origin (Cycles).
                    t = -oc2 / np.where(b < 0, b, -1.0)
                    miss2 = oc2 + 2.0 * t * b + t * t          # |oc + t d|^2
                    hit = (b < 0) & (oc2 > r * r) & (miss2 <= r * r) & (t > 0) & (t < tm)
                else:
                    disc = b * b - (oc2 - r * r)
                    t = -b - np.sqrt(np.maximum(disc, 0.0))
                    hit = (disc > 0) & (t > 0) & (t < tm)
                radiance = np.broadcast_to(p / (4.0 * np.pi ** 2 * r * r), (len(rays), 3))
                if kind == SPOT:
                    mask = _spot_mask(-(d @ axis), np.cos(L.spot_angle[i] / 2.0), L.spot_blend[i])
                    radiance = radiance * mask[:, None]
                if L.profile[i] >= 0:
                    radiance = radiance * profile_factor(L, np.full(len(rays), i), -d)[:, None]
            else:
                half = float(L.sun_angle[i]) / 2.0
                if half <= 0:
                    continue
                hit = escaped.take(rays) & (-(d @ axis) >= np.cos(half))
                radiance = np.broadcast_to(p / (np.pi * np.sin(half) ** 2), (len(rays), 3))
                t = np.full(len(rays), np.inf)
            sel = np.flatnonzero(hit)
            radiance = radiance.take(sel, axis=0)
            if attenuation is not None and len(sel):
                radiance = radiance * attenuation(rays.take(sel), t.take(sel))
            out[rays.take(sel)] += radiance
            if split is not None and L.group[i] >= 0:
                split[L.group[i], rays.take(sel)] += radiance
        return out

    # ------------------------------------------------------------------ sampling
    def sample(self, u, focus=None):
        """Photon rays for primary samples ``u`` (n, >=6) in [0, 1); ``focus``: None, or the
        :class:`Focus` the photons from afar are aimed at.

        Returns ``origins`` (n, 3) float64, ``directions`` (n, 3) float64 unit,
        ``flux`` (n, 3) float64 and ``normals`` (n, 3): the emitter's geometric normal
        where the photon leaves a mesh (for the ray offset), else 0.
        """
        return self.sample_aimed(u, focus)[:4]

    def sample_aimed(self, u, focus=None):
        """:meth:`sample`'s four arrays and ``aims`` (n,): the weight :meth:`_disk_origin` gave each
        photon from afar (the sun, the world; part of its flux), 0 for the others."""
        n = len(u)
        aims = np.zeros(n)
        origins = np.zeros((n, 3))
        dirs = np.zeros((n, 3))
        dirs[:, 2] = 1.0
        flux = np.zeros((n, 3))
        normals = np.zeros((n, 3))
        if self.count == 0 or n == 0:
            return origins, dirs, flux, normals, aims
        entry = self.entries(u[:, 0])
        kind = self.kinds[entry]
        base = self.power[entry] / self.prob[entry][:, None]       # power / choice probability
        for k in np.unique(kind):
            sel = np.flatnonzero(kind == k)
            us = u[sel]
            ids = self.ids[entry[sel]]
            if k in (POINT, SPOT):
                o, d, w = self._sample_sphere_light(ids, us)
            elif k in (AREA_RECT, AREA_DISK):
                o, d, w = self._sample_area_light(ids, us, k)
            elif k == SUN:
                d, w = self._sun_directions(ids, us)
            elif k == TRIANGLE:
                o, d, emitted, nrm = self._sample_triangle(ids, us, self.power[entry[sel]])
                normals[sel] = nrm
            elif k == VOLUME:
                o, d, w = self._sample_volume(ids, us)
            else:
                d, w = self._world_directions(us)
            if k in (SUN, WORLD):
                o, aims[sel] = self._disk_origin(d, us, focus)
                w = w * (aims[sel] if w.ndim == 1 else aims[sel][:, None])
            origins[sel], dirs[sel] = o, d
            if k == TRIANGLE:
                # The power the chosen points emit over the choice probability: exact whatever
                # estimate of the triangle's power set that probability.
                flux[sel] = emitted / self.prob[entry[sel]][:, None]
            else:
                flux[sel] = base[sel] * (w if w.ndim == 2 else w[:, None])
        return origins, dirs, flux, normals, aims

    # ------------------------------------------------------------------ light samples (direct light)
    def direct_entries(self) -> np.ndarray:
        """(count,) bool: the emitters whose light :meth:`sample_direct` samples exactly as their
        photons carry it at their first vertex: point, spot and area lights without an angular
        profile, suns, emissive triangles whose radiance is one constant (no texture, program, coat
        or sheen) and the world.  Glowing volumes and the others are left to their photons."""
        kinds, ids = self.kinds, self.ids
        out = np.isin(kinds, (POINT, SPOT, AREA_RECT, AREA_DISK, SUN, WORLD))
        if self.has_profiles:
            lamp = np.flatnonzero(np.isin(kinds, (POINT, SPOT, AREA_RECT, AREA_DISK)))
            out[lamp] &= self.lights.profile.take(ids.take(lamp)) < 0
        tri = np.flatnonzero(kinds == TRIANGLE)
        if len(tri):
            mats = self.material_ids.take(ids.take(tri))
            plain = ~self.varies.take(mats)
            if self.coated_emitters:
                plain &= self.table.coat_row.take(mats) < 0
            if self.sheened_emitters:
                plain &= self.table.sheen_cover.take(mats) <= 0
            out[tri] = plain
        return out

    def sample_direct(self, entry, x, n, both, u):
        """Light samples for points ``x`` (k, 3) from emitters ``entry`` (k,) (of
        :meth:`direct_entries`): (directions wi (k, 3) from the points towards the light, the
        distances ``t_max`` (k,) to it (inf for the sun and the world), and (k, 3) the radiance
        arriving along wi over the density of wi per solid angle), with ``u`` (k, 3) numbers in
        [0, 1).  The radiance is the photons' (:meth:`sample`): a point or spot light's sphere
        radiates P mask(d) / (4 pi^2 r^2) along each ray d leaving it (drawn uniformly in the cone
        it fills as seen from x; a point inside it gets nothing, as from its photons), times the
        soft falloff's d^2 / (d^2 + r^2); an area light's P att / (pi A) (a point drawn uniformly
        on it); a sun's irradiance over its cone; an emissive triangle's (two-sided) P / (2 pi A);
        the world's in a cosine direction about the points' normals ``n`` (k, 3) (either side where
        ``both`` (k,) bool, each half the time), or drawn from its image, and under light portals
        mostly towards them (:meth:`_world_samples`).  The choice of the emitter is left to the
        caller."""
        k = len(entry)
        wi, t_max, value = np.zeros((k, 3)), np.full(k, np.inf), np.zeros((k, 3))
        wi[:, 2] = 1.0
        if k == 0:
            return wi, t_max, value
        L = self.lights
        kinds = self.kinds.take(entry)
        for kind in np.unique(kinds):
            sel = np.flatnonzero(kinds == kind)
            ids, xs, us = self.ids.take(entry.take(sel)), x.take(sel, axis=0), u.take(sel, axis=0)
            if kind in (POINT, SPOT):
                to = L.position.take(ids, axis=0) - xs
                d2 = np.einsum("ij,ij->i", to, to)
                dist = np.sqrt(d2)
                r = L.radius.take(ids).astype(np.float64)
                # The cone of the sphere: 1 - cos_max = (r/D)^2 / (1 + cos_max), without cancellation.
                s2 = np.minimum(r * r / np.maximum(d2, 1e-300), 1.0)
                cos_max = np.sqrt(1.0 - s2)
                z = 1.0 - us[:, 0] * (s2 / (1.0 + cos_max))
                rho = np.sqrt(np.maximum(0.0, 1.0 - z * z))
                phi = 2.0 * np.pi * us[:, 1]
                d = smp.to_world(np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1),
                                 to / np.maximum(dist, 1e-300)[:, None])
                t = dist * z - np.sqrt(np.maximum(r * r - d2 * (1.0 - z * z), 0.0))
                # radiance / pdf = P mask / (4 pi^2 r^2) 2 pi (1 - cos_max)
                #                = P mask / (2 pi D^2 (1 + cos_max))
                w = 1.0 / (2.0 * np.pi * np.maximum(d2, 1e-300) * (1.0 + cos_max))
                w = np.where(dist > r, w, 0.0)
                spot = np.flatnonzero(L.kind.take(ids) == SPOT)
                if len(spot):
                    cos_half = np.cos(L.spot_angle.take(ids.take(spot)).astype(np.float64) / 2)
                    cos_axis = -smp.dot(d.take(spot, axis=0), self.axes.take(ids.take(spot), axis=0))
                    w[spot] *= _spot_mask(cos_axis, cos_half, L.spot_blend.take(ids.take(spot)))
                soft = np.flatnonzero(L.soft_falloff.take(ids) & (r > 0))
                if len(soft):
                    w[soft] *= d2.take(soft) / (d2.take(soft) + r.take(soft) ** 2)
                wi[sel], t_max[sel] = d, t
                value[sel] = L.power.take(ids, axis=0) * w[:, None]
            elif kind in (AREA_RECT, AREA_DISK):
                span = np.linalg.norm(np.cross(L.axis_u.take(ids, axis=0).astype(np.float64),
                                                L.axis_v.take(ids, axis=0).astype(np.float64)), axis=1)
                if kind == AREA_RECT:
                    a, b, area = 2.0 * us[:, 0] - 1.0, 2.0 * us[:, 1] - 1.0, 4.0 * span
                else:
                    (a, b), area = smp.concentric_disk(us[:, 0], us[:, 1]), np.pi * span
                y = (L.position.take(ids, axis=0) + a[:, None] * L.axis_u.take(ids, axis=0)
                     + b[:, None] * L.axis_v.take(ids, axis=0))
                to = y - xs
                d2 = np.einsum("ij,ij->i", to, to)
                dist = np.sqrt(d2)
                d = to / np.maximum(dist, 1e-300)[:, None]
                cos_y = -smp.dot(d, self.axes.take(ids, axis=0))
                half = 0.5 * L.spread.take(ids).astype(np.float64)
                att = spread_attenuation(cos_y, half)
                # (narrow spreads: photons only within the clamped cone)
                att = np.where(cos_y >= np.cos(np.clip(half, MIN_HALF_SPREAD, np.pi / 2)), att, 0.0)
                w = np.where(cos_y > 0, att * cos_y / (np.pi * np.maximum(d2, 1e-300)), 0.0)
                wi[sel], t_max[sel] = d, dist
                value[sel] = L.power.take(ids, axis=0) * w[:, None]
            elif kind == SUN:
                cos_half = np.cos(L.sun_angle.take(ids).astype(np.float64) / 2)
                d = smp.to_world(smp.uniform_cone(us[:, 0], us[:, 1], cos_half), self.axes.take(ids, axis=0))
                wi[sel] = -d
                value[sel] = L.power.take(ids, axis=0) * self.far
            elif kind == TRIANGLE:
                b1, b2 = smp.uniform_triangle(us[:, 0], us[:, 1])
                y = self.accel.hit_positions(ids, b1, b2)
                to = y - xs
                d2 = np.einsum("ij,ij->i", to, to)
                dist = np.sqrt(d2)
                d = to / np.maximum(dist, 1e-300)[:, None]
                cos_y = np.abs(smp.dot(d, self.accel.geometric_normals.take(ids, axis=0)))
                # radiance P / (2 pi A) times A cos_y / D^2 (a point uniform on the triangle)
                w = cos_y / (2.0 * np.pi * np.maximum(d2, 1e-300))
                wi[sel], t_max[sel] = d, dist * (1.0 - 1e-4)
                value[sel] = self.power.take(entry.take(sel), axis=0) * w[:, None]
            elif kind == WORLD:
                wi[sel], value[sel] = self._world_samples(xs, n.take(sel, axis=0), both.take(sel), us)
        return wi, t_max, value

    def _world_samples(self, x, n, both, u):
        """:meth:`sample_direct` for the world at points ``x`` (k, 3) with normals ``n``: (directions
        (k, 3), radiance over density (k, 3)).  Directions come from the world's image, or else
        by the cosine about n (either side where ``both``, each half the time, by ``u[:, 2]``);
        under light portals, with the chance 1 - PORTAL_SAMPLE_SHARE (by ``u[:, 0]``) where some
        portal faces the point, towards a point on a portal instead (:meth:`Focus.seen_from`,
        ``u[:, 2]`` picking it), the density that of the mixture (a sky seen through a window:
        most of the cosine's directions meet a wall)."""
        env, portals = self.environment, self.portals
        aim = portals.seen_from(x) if portals is not None else None
        share = (np.where(aim.sum(axis=1) > 0, portals.uniform_share, 1.0) if aim is not None
                 else np.ones(len(x)))
        aimed = u[:, 0] >= share
        # (the first number rescaled within its part)
        u0 = np.where(aimed, (u[:, 0] - share) / np.where(share < 1.0, 1.0 - share, 1.0), u[:, 0] / share)
        if env is not None:
            d, pdf = env.sample(u0, u[:, 1])
        else:
            flip = both & (u[:, 2] < 0.5)
            d = smp.to_world(smp.cosine_hemisphere(u0, u[:, 1]), n * np.where(flip, -1.0, 1.0)[:, None])
        if aimed.any():
            a = np.flatnonzero(aimed)
            d[a] = portals.sample_towards(x[a], aim[a], u0[a], u[a, 1], u[a, 2])
        if env is None:
            cos = smp.dot(d, n)
            pdf = np.where(both, 0.5 * np.abs(cos), np.maximum(cos, 0.0)) / np.pi
        elif aim is not None:
            pdf = env.pdf(d)
        if aim is not None:
            pdf = share * pdf + (1.0 - share) * portals.towards_pdf(x, aim, d)
        radiance = env.radiance(d) if env is not None else self.world_radiance[None, :]
        value = radiance * self.far / np.maximum(pdf, 1e-300)[:, None] * (pdf > 0)[:, None]
        return d, value

    def lights_sets(self, u0, sets):
        """(n,) bool: whether the emitters of photons with first light dimensions ``u0`` (n,)
        light receiver sets ``sets`` (n,) (Scene.receiver_sets)."""
        return linked(self.links.take(self.entries(u0)), sets)

    def excluded(self, u0):
        """(n,) uint8: the rays (bits EXCLUDE_*) that the emitters of photons with first light
        dimensions ``u0`` (n,) do not light."""
        return self.exclude.take(self.entries(u0))

    def groups_of(self, u0):
        """(n,) the light group (``Scene.light_groups``; -1 none) of the emitters of photons with
        first light dimensions ``u0`` (n,)."""
        return self.group.take(self.entries(u0))

    def entries(self, u0):
        """(n,) emitter of each photon from its first light dimension (power-proportional)."""
        return np.minimum(np.searchsorted(self.cdf, u0, side="right"), self.count - 1)

    def _sample_sphere_light(self, ids, u):
        """Point and spot lights: direction first, then a point on the sphere's visible disk."""
        L = self.lights
        is_spot = L.kind[ids] == SPOT
        cos_half = np.where(is_spot, np.cos(L.spot_angle[ids].astype(np.float64) / 2), -1.0)
        axis = self.axes[ids]
        local = smp.uniform_cone(u[:, 4], u[:, 5], cos_half)
        d = smp.to_world(local, axis)
        # Flux = power share * mask / (mean mask over the cone), so that photons average to the
        # emitted power of the cone (uniform directions in the cone).
        mask = np.where(is_spot, _spot_mask(local[:, 2], cos_half, L.spot_blend[ids]), 1.0)
        w = mask / np.where(is_spot, _spot_mean_mask(L.spot_blend[ids]), 1.0)
        if self.has_profiles:
            # Lights with an angular profile draw their directions from it; the flux is then
            # P f(d) mask(d) / (4 pi pdf(d)), over the scale of P that their choice used.
            p = np.flatnonzero(L.profile.take(ids) >= 0)
            if len(p):
                ip = ids.take(p)
                dp, pdf = self._sample_profile(ip, u[p, 4], u[p, 5])
                d[p] = dp
                cos_axis = np.einsum("ij,ij->i", dp, axis[p])
                mask_p = np.where(is_spot[p], _spot_mask(cos_axis, cos_half[p], L.spot_blend[ip]), 1.0)
                w[p] = mask_p * profile_factor(L, ip, dp) / (4.0 * np.pi * pdf * self.light_scale.take(ip))
        r = L.radius[ids].astype(np.float64)
        x, y = smp.concentric_disk(u[:, 1], u[:, 2])
        t, b = smp.orthonormal_frames(d)
        z = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
        o = L.position[ids] + r[:, None] * (x[:, None] * t + y[:, None] * b + z[:, None] * d)
        return o, d, w

    def _sample_area_light(self, ids, u, kind):
        """Cosine-distributed directions; with a spread below 180 degrees, uniform in its cone
        weighted by the emission's density cos a att(a) / pi over the cone's 1 / (2 pi (1 - cos h))."""
        L = self.lights
        if kind == AREA_RECT:
            x, y = 2.0 * u[:, 1] - 1.0, 2.0 * u[:, 2] - 1.0
        else:
            x, y = smp.concentric_disk(u[:, 1], u[:, 2])
        o = L.position[ids] + x[:, None] * L.axis_u[ids] + y[:, None] * L.axis_v[ids]
        n = self.axes[ids]
        local = smp.cosine_hemisphere(u[:, 4], u[:, 5])
        w = np.ones(len(ids))
        half = 0.5 * L.spread.take(ids).astype(np.float64)
        narrow = np.flatnonzero(half < FULL_SPREAD)
        if len(narrow):
            h = np.maximum(half.take(narrow), MIN_HALF_SPREAD)
            cos_h = np.cos(h)
            cone = smp.uniform_cone(u[narrow, 4], u[narrow, 5], cos_h)
            local[narrow] = cone
            w[narrow] = 2.0 * (1.0 - cos_h) * cone[:, 2] * spread_attenuation(cone[:, 2], h)
        d = smp.to_world(local, n)
        if self.has_profiles:
            # An angular profile weighs the directions (over its mean, which the choice used);
            # where the profile is sampled, its directions replace the cosine's: the flux is then
            # P f(d) cos / (pi pdf(d)).
            k = L.profile.take(ids)
            drawn = np.flatnonzero(self.cdf_row.take(ids) >= 0) if self.cdf_row is not None else []
            if len(drawn):
                dp, pdf = self._sample_profile(ids.take(drawn), u[drawn, 4], u[drawn, 5])
                d[drawn] = dp
                w[drawn] = np.maximum(np.einsum("ij,ij->i", dp, n[drawn]), 0.0) / (np.pi * pdf)
            w = w * profile_factor(L, ids, d) / np.where(k >= 0, self.light_scale.take(ids), 1.0)
        return o, d, w

    def _sun_directions(self, ids, u):
        """Directions (n, 3) uniform in the suns' cones and weights (n,) 1 (origins: _disk_origin)."""
        L = self.lights
        cos_half = np.cos(L.sun_angle[ids].astype(np.float64) / 2)
        return smp.to_world(smp.uniform_cone(u[:, 4], u[:, 5], cos_half), self.axes[ids]), np.ones(len(ids))

    def _world_directions(self, u):
        """Directions and weights (origins: _disk_origin): uniform directions, weight 1, for a
        constant world; for an image, directions drawn from it with RGB weights L(d) / (pdf(d) int L)
        (mean 1: the power above is pi R^2 int L)."""
        env = self.environment
        if env is None:
            return smp.uniform_sphere(u[:, 4], u[:, 5]), np.ones(len(u))
        towards_sky, pdf = env.sample(u[:, 4], u[:, 5])
        w = env.radiance(towards_sky) / (pdf[:, None] * np.where(env.integral > 0, env.integral, 1.0))
        return -towards_sky, w

    def _sample_volume(self, ids, u):
        """Glowing volumes ``ids`` (materials): points from :meth:`GlowingVolume.sample`, directions
        uniform over the sphere."""
        o, w = np.zeros((len(ids), 3)), np.zeros(len(ids))
        for m in np.unique(ids):
            sel = np.flatnonzero(ids == m)
            o[sel], w[sel] = self.volumes[int(m)].sample(u[sel, 1], u[sel, 2], u[sel, 3])
        return o, smp.uniform_sphere(u[:, 4], u[:, 5]), w

    def _disk_origin(self, d, u, focus=None):
        """(origins, weights): origins on the disk of the bounding sphere perpendicular to ``d``,
        outside the scene; with a :class:`Focus`, with the chance ``1 - uniform_share`` (by
        ``u[:, 3]``) on the focus sphere's disc in the same plane instead, and the weights (n,)
        the scene disc's uniform density over the mixture's (1 without a focus)."""
        x, y = smp.concentric_disk(u[:, 1], u[:, 2])
        t, b = smp.orthonormal_frames(d)
        r = self.radius
        if focus is None or focus.portals is not None:
            plain = self.center + r * (x[:, None] * t + y[:, None] * b) - 2.0 * r * d
            if focus is None:
                return plain, np.ones(len(d))
            return self._portal_origin(d, u, focus, plain)
        share = focus.uniform_share
        aimed = u[:, 3] >= share
        centre = np.where(aimed[:, None], focus.center, self.center)
        across = np.where(aimed, focus.radius, r)[:, None] * (x[:, None] * t + y[:, None] * b)
        # (the aimed origins moved along d into the plane of the others, 2 r before the centre)
        o = centre + across - (smp.dot(centre - self.center, d) + 2.0 * r)[:, None] * d
        in_scene = _off_axis2(o - self.center, d) <= (r * (1.0 + 1e-9)) ** 2
        in_focus = focus.holds(o, d)
        return o, 1.0 / (share * in_scene + (1.0 - share) * (r / focus.radius) ** 2 * in_focus)

    def _portal_origin(self, d, u, focus, origins):
        """:meth:`_disk_origin` under a focus on portals (:meth:`Focus.through`): ``origins`` (n, 3)
        on the scene's disc replaced, with the chance ``1 - uniform_share`` (by ``u[:, 3]``, which
        then also picks the portal, :meth:`Focus.points_on`) where d crosses a portal, by a point of
        a portal moved back along d into the disc's plane; the weights are the scene disc's density
        over the mixture's, 0 off the scene's disc."""
        share, r = focus.uniform_share, self.radius
        projected = focus.projected(d)
        total = projected.sum(axis=1)
        aimed = np.flatnonzero((u[:, 3] >= share) & (total > 0))
        if len(aimed):
            pick = (u[aimed, 3] - share) / (1.0 - share)
            p = focus.points_on(projected[aimed], u[aimed, 1], u[aimed, 2], pick)
            da = d[aimed]
            origins[aimed] = p - (smp.dot(p - self.center, da) + 2.0 * r)[:, None] * da
        in_scene = _off_axis2(origins - self.center, d) <= (r * (1.0 + 1e-9)) ** 2
        uniform = np.where(total > 0, share, 1.0)
        density = uniform * in_scene + (1.0 - uniform) * (np.pi * r * r) * focus.crossings(origins, d) \
            / np.where(total > 0, total, 1.0)
        return origins, np.where(in_scene & (density > 0), 1.0 / np.where(density > 0, density, 1.0), 0.0)

    def _sample_triangle(self, ids, u, power):
        """Origins, directions, the power 2 pi A L(x) (n, 3) the chosen points emit (the
        triangles' ``power`` (n, 3) unless some emitter's radiance varies) and the normals."""
        a = self.accel
        b1, b2 = smp.uniform_triangle(u[:, 1], u[:, 2])
        p = a.hit_positions(ids, b1, b2)
        ng = a.geometric_normals[ids]
        side = np.where(u[:, 3] < 0.5, 1.0, -1.0)
        n = ng * side[:, None]
        d = smp.to_world(smp.cosine_hemisphere(u[:, 4], u[:, 5]), n)
        emitted = power
        if self.textured_emitters:
            radiance = self.emitted(ids, b1, b2, positions=p, rays=self._emitter_rays(d))
            emitted = (2.0 * np.pi * a.area.take(ids))[:, None] * radiance
        if self.coated_emitters:
            mats = self.material_ids.take(ids)
            coated = np.flatnonzero(self.table.coat_row.take(mats) >= 0)
            if len(coated):
                # The photon's cosine with the emitter (flat: the coat's normal is the facet's).
                emitted = np.array(emitted, np.float64)
                mu = np.abs(smp.dot(d, n).take(coated))
                emitted[coated] *= self.table.coat_attenuation(mats.take(coated), mu)
        if self.sheened_emitters:
            emitted = np.array(emitted, np.float64)
            emitted *= self.table.sheen_dim(self.material_ids.take(ids), smp.dot(d, n))[:, None]
        return a.spawn(p, n, d, ids), d, emitted, n

    def _emitter_rays(self, directions):
        """The ``procedural.Rays`` an emitting triangle's photons see it by: along ``directions``
        (n, 3), with the light path of a photon's hit of length 0 (``procedural.photon_path``) where
        some program reads it."""
        return Rays(directions, path=photon_path(np.zeros(len(directions))) if self.light_path else None)

    def _textured_power(self, tris, tri_mat):
        """(k, 3) estimated power 2 pi A mean(L) of emissive triangles ``tris`` whose radiance
        varies (an emission or opacity program): L at TEXTURED_POWER_SIDE^2 stratified points
        each (fewer on big meshes), each towards a cosine-distributed direction on either side (for
        programs of the view), kept above TEXTURED_POWER_FLOOR times their material's mean so
        that no triangle that emits somewhere goes unchosen (photon fluxes stay exact: ``sample``)."""
        area = self.accel.area.take(tris)
        side = int(np.clip(np.sqrt(TEXTURED_POWER_BUDGET / max(len(tris), 1)), 1, TEXTURED_POWER_SIDE))
        g = (np.arange(side) + 0.5) / side
        u1, u2 = (x.ravel() for x in np.meshgrid(g, g, indexing="ij"))
        b1, b2 = smp.uniform_triangle(u1, u2)
        k = len(b1)
        # The directions (seeded: the same estimate every run), every other on the back.
        facing = np.where(np.arange(k) % 2 == 0, 1.0, -1.0)
        local = smp.cosine_hemisphere(*np.random.default_rng(0).random((2, k)))
        mean = np.zeros((len(tris), 3))
        chunk = max(1, TEXTURED_POWER_BUDGET // k)
        for start in range(0, len(tris), chunk):
            part = tris[start:start + chunk]
            ids = np.repeat(part, k)
            n = np.repeat(self.accel.geometric_normals.take(part, axis=0), k, axis=0)
            d = smp.to_world(np.tile(local, (len(part), 1)), n * np.tile(facing, len(part))[:, None])
            radiance = self.emitted(ids, np.tile(b1, len(part)), np.tile(b2, len(part)),
                                    rays=self._emitter_rays(d))
            mean[start:start + chunk] = radiance.reshape(len(part), k, 3).mean(axis=1)
        mats = tri_mat.take(tris)
        for m in np.unique(mats):
            rows = np.flatnonzero(mats == m)
            material_mean = (area[rows, None] * mean[rows]).sum(axis=0) / max(area[rows].sum(), 1e-300)
            mean[rows] = np.maximum(mean[rows], TEXTURED_POWER_FLOOR * material_mean)
        return (2.0 * np.pi * area)[:, None] * mean


def _off_axis2(v, d):
    """Squared length of the parts of vectors ``v`` (n, 3) perpendicular to unit ``d`` (n, 3)."""
    along = smp.dot(v, d)
    return np.maximum(smp.dot(v, v) - along * along, 0.0)


def material_groups(scene, materials):
    """(k,) int64 the light group of each of ``materials`` (k,): that of most of its triangles
    (``Scene.emitter_group``; -1 none).  Blender gives a glowing volume its object's group; here a
    volume is its material's triangles."""
    out = np.full(len(materials), -1, np.int64)
    if scene.emitter_group is None:
        return out
    for i, m in enumerate(materials):            # (a loop over the few glowing materials)
        groups = scene.emitter_group[scene.material_ids == m]
        if len(groups):
            out[i] = np.bincount(groups.astype(np.int64) + 1).argmax() - 1
    return out


class GlowingVolume:
    """Points inside the closed mesh of a glowing volume (``Materials.volume_emission``) from
    three numbers each, for photons: a line parallel to the longest side of the mesh's bounding
    box through a point of the box's cross-section (the first two), traced through the mesh's
    faces (the inside is where more faces were gone into through their front than left, as
    ``RenderContext.next_medium`` tracks a path), and a point uniform on the line's inside (the
    third).  Weighting each point by A L / V (A the cross-section's area, L the inside length of
    its line, V the mesh's volume) makes the points' mean that of points uniform in the volume;
    lines that miss it carry 0."""

    def __init__(self, accel, tris):
        self.accel = accel.subset(tris)
        v0, e1, e2 = (a.take(tris, axis=0) for a in (accel.v0, accel.e1, accel.e2))
        corners = np.concatenate([v0, v0 + e1, v0 + e2])
        self.lo, self.hi = corners.min(axis=0), corners.max(axis=0)
        # The divergence theorem over the faces (about the box's centre, for precision): > 0 for
        # a closed mesh whose faces point out; a mesh whose faces point in has no inside (the
        # paths' tracking agrees), and gets no photons.
        c = 0.5 * (self.lo + self.hi)
        self.volume = float(np.einsum("ij,ij->", v0 - c, np.cross(e1, e2))) / 6.0
        size = self.hi - self.lo
        self.axis = int(np.argmax(size))
        self.across = [k for k in range(3) if k != self.axis]
        self.area = float(size[self.across[0]] * size[self.across[1]])

    def sample(self, u1, u2, u3):
        """(points (n, 3), weights A L / V (n,))."""
        n, k = len(u1), self.axis
        i, j = self.across
        offset = self.accel.offsets_near(np.stack([self.lo, self.hi])).max()
        start = self.lo[k] - 0.01 * (self.hi[k] - self.lo[k]) - offset
        o = np.empty((n, 3))
        o[:, i] = self.lo[i] + u1 * (self.hi[i] - self.lo[i])
        o[:, j] = self.lo[j] + u2 * (self.hi[j] - self.lo[j])
        o[:, k] = start
        d = np.zeros((n, 3))
        d[:, k] = 1.0
        # The crossings along each line, a column each: where (t from the start; 0: none) and how
        # deep inside the line is after it.
        ts, depths = [np.zeros(n)], [np.zeros(n, np.int32)]
        depth = np.zeros(n, np.int32)
        rows, origins = np.arange(n), o
        for _ in range(MAX_GLOW_CROSSINGS):        # a loop over crossings, as over bounces
            hits = self.accel.intersect(origins, d.take(rows, axis=0))
            h = np.flatnonzero(hits.is_hit)
            rows = rows.take(h)
            if len(rows) == 0:
                break
            prim = hits.prim_ids.take(h)
            p = self.accel.hit_positions(prim, hits.b1.take(h), hits.b2.take(h))
            ng = self.accel.geometric_normals.take(prim, axis=0)
            depth[rows] += np.where(ng[:, k] < 0, 1, -1).astype(np.int32)
            t, after = np.zeros(n), np.zeros(n, np.int32)
            t[rows], after[rows] = p[:, k] - start, depth.take(rows)
            ts.append(t)
            depths.append(after)
            origins = self.accel.spawn(p, ng, d.take(rows, axis=0), prim)
        ts, depths = np.stack(ts, axis=1), np.stack(depths, axis=1)
        # The inside lengths between crossings (a crossing's column 0: it had none).
        inside = np.where((depths[:, :-1] > 0) & (ts[:, 1:] > 0), np.maximum(np.diff(ts, axis=1), 0.0), 0.0)
        if inside.shape[1] == 0:
            return o, np.zeros(n)
        cum = np.cumsum(inside, axis=1)
        total = cum[:, -1]
        target = u3 * total
        piece = np.minimum((cum <= target[:, None]).sum(axis=1), inside.shape[1] - 1)
        before = np.where(piece > 0, np.take_along_axis(cum, np.maximum(piece - 1, 0)[:, None], axis=1)[:, 0],
                          0.0)
        t = np.take_along_axis(ts, piece[:, None], axis=1)[:, 0] + (target - before)
        points = o.copy()
        points[:, k] = start + np.where(total > 0, t, 0.0)
        return points, self.area * total / self.volume


FULL_SPREAD = 0.5 * np.pi - 1e-6       # half spreads from here on are Lambertian
MIN_HALF_SPREAD = 1e-3                  # narrower spreads are clamped (Cycles' beam is a delta)


def profile_factor(lights, ids, dirs):
    """(n,) factors of the angular profiles (``Lights.profile``) of lights ``ids`` (n,) towards
    unit directions ``dirs`` (n, 3) leaving them; 1 for lights without one.  Bilinear in the
    table, which the exporter samples from Cycles' IES lookup."""
    out = np.ones(len(ids))
    k = lights.profile.take(ids)
    sel = np.flatnonzero(k >= 0)
    if len(sel) == 0:
        return out
    ids, k, d = ids.take(sel), k.take(sel), dirs.take(sel, axis=0)
    # (Area lights' axes are half extents: only their directions count.)
    x = np.einsum("ij,ij->i", d, smp.normalize(lights.axis_u.take(ids, axis=0).astype(np.float64)))
    y = np.einsum("ij,ij->i", d, smp.normalize(lights.axis_v.take(ids, axis=0).astype(np.float64)))
    z = -np.einsum("ij,ij->i", d, lights.direction.take(ids, axis=0))
    table = lights.profiles
    rows, cols = table.shape[1] - 1, table.shape[2] - 1
    v = np.arccos(np.clip(-z, -1.0, 1.0)) * (rows / np.pi)
    h = (np.arctan2(x, y) + np.pi) * (cols / (2.0 * np.pi))
    v0 = np.clip(v.astype(np.int64), 0, rows - 1)
    h0 = np.clip(h.astype(np.int64), 0, cols - 1)
    fv, fh = np.clip(v - v0, 0.0, 1.0), np.clip(h - h0, 0.0, 1.0)
    flat = table.reshape(len(table), -1)
    at = lambda r, c: flat[k, r * (cols + 1) + c]                  # noqa: E731
    out[sel] = ((1.0 - fv) * ((1.0 - fh) * at(v0, h0) + fh * at(v0, h0 + 1))
                + fv * ((1.0 - fh) * at(v0 + 1, h0) + fh * at(v0 + 1, h0 + 1)))
    return out


def profile_cdfs(profiles, cones, lambert=None):
    """(P, cells) cumulative probabilities of the cells of each profile's table (row-major), by
    the mean of their corners times their solid angle, the rows that start beyond each cone's half
    angle ``cones`` (P,) left out, and times the cosine at the row's start where ``lambert`` (P,)
    bool (area lights); uniform for a profile that is all 0 there."""
    table = np.asarray(profiles, np.float64)
    rows, cols = table.shape[1] - 1, table.shape[2] - 1
    v = np.linspace(0.0, np.pi, rows + 1)
    solid = (np.cos(v[:-1]) - np.cos(v[1:]))[None, :, None] * (2.0 * np.pi / cols)
    mean = 0.25 * (table[:, :-1, :-1] + table[:, 1:, :-1] + table[:, :-1, 1:] + table[:, 1:, 1:])
    inside = (v[None, :-1] < np.asarray(cones, np.float64)[:, None]).astype(np.float64)   # (P, rows)
    if lambert is not None:
        cosine = np.maximum(np.cos(v[None, :-1]), 0.0)
        inside = np.where(np.asarray(lambert)[:, None], inside * cosine, inside)
    weight = (mean * solid * inside[:, :, None]).reshape(len(table), -1)
    empty = weight.sum(axis=1) <= 0
    weight[empty] = 1.0
    cdf = np.cumsum(weight, axis=1)
    cdf /= cdf[:, -1:]
    cdf[:, -1] = 1.0
    return cdf


def profile_means(profiles):
    """(P,) mean of each profile over the sphere of directions (sin-weighted over its rows)."""
    if profiles is None:
        return np.zeros(0)
    table = np.asarray(profiles, np.float64)
    v = np.linspace(0.0, np.pi, table.shape[1])
    # Trapezoids along both angles, the last column (360 degrees) being the first again.
    w_v = np.sin(v) * np.gradient(v)
    w_h = np.full(table.shape[2], 1.0)
    w_h[[0, -1]] = 0.5
    total = np.einsum("pvh,v,h->p", table, w_v, w_h)
    return total / (w_v.sum() * w_h.sum())


def spread_attenuation(cos_a, half):
    """Cycles' area-light spread (``area_light_spread_attenuation``): a soft box whose slats
    let through max(0, (tan h - tan a) / (tan h - h)) at angle a from the normal, h the half
    spread; 1 for a full spread.  The emitted power stays P: cos a att(a) / pi is a density."""
    cos_a, half = np.broadcast_arrays(np.asarray(cos_a, np.float64), np.asarray(half, np.float64))
    h = np.clip(half, MIN_HALF_SPREAD, FULL_SPREAD)
    tan_h = np.tan(h)
    norm = np.where(h > 0.05, 1.0 / np.maximum(tan_h - h, 1e-300), 3.0 / h ** 3)
    tan_a = np.sqrt(np.maximum(0.0, 1.0 - cos_a * cos_a)) / np.maximum(cos_a, 1e-12)
    att = np.maximum((tan_h - tan_a) * norm, 0.0)
    return np.where(cos_a > 0, np.where(half >= FULL_SPREAD, 1.0, att), 0.0)


def _spot_mean_mask(blend):
    """Mean of :func:`_spot_mask` over directions uniform in the cone: 1 - blend/2 (blend <= 1)."""
    return 1.0 - 0.5 * np.clip(np.asarray(blend, np.float64), 0.0, 1.0)


def _spot_mask(cos_theta, cos_half, blend):
    """Cycles' spot attenuation: smoothstep((cos - cos_half) / ((1 - cos_half) blend))."""
    cos_theta, cos_half, blend = np.broadcast_arrays(np.asarray(cos_theta, np.float64),
                                                     np.asarray(cos_half, np.float64),
                                                     np.asarray(blend, np.float64))
    width = (1.0 - cos_half) * blend
    inside = cos_theta > cos_half
    soft = smp.smoothstep((cos_theta - cos_half) / np.where(width > 0, width, 1.0))
    return np.where(inside, np.where(width > 0, soft, 1.0), 0.0)

"""Everything derived once from a scene for tracing: BVH, material table, emitters."""
from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass

import numpy as np

from . import phase
from .accel import Accel, Hits, interpolate_corners
from .bsdf import (DIELECTRIC, MIRROR, ROUGHNESS_LEVELS, TANGENT_UV, TRANSLUCENT, MaterialTable, Textures,
                   coat_variants, lobe_colors, roughness_variants, stretch_level, stretch_variants)
from .displacement import displace
from .environment import Environment
from .lights import VOLUME, LightSampler, material_groups
from .procedural import (BUMP_STEP, COLOR_MAX, EMISSION_MAX, DirectionAttributes, HitAttributes, Rays,
                         attributes_used, bend_normals, bump_edges, bumped_normals, camera_path, evaluate,
                         evaluate_color, perpendicular_tangents, photon_path, radial_tangents,
                         spatial_normals, tangent_space_normals)
from .sampling import dot, forced_flight, free_flight, normalize, transmittance, volume_glow
from .scene import (ALL_LINKS, AREA_DISK, AREA_RECT, CASTS_NO_SHADOW, HOLDOUT_OBJECT, NORMAL_BLENDER_OBJECT,
                    NORMAL_BLENDER_WORLD, NORMAL_OBJECT, NORMAL_TANGENT, PANORAMAS, POINT, SHADOW_CATCHER,
                    SPOT, VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION, linked)
from .settings import GLOSSY_THROUGH_ROUGHNESS
from .sky import SkyTextureCache
from .subsurface import exit_variant

# Rec. 709 luminance: Cycles' colour-to-float conversion of a height image.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
# Transparent surfaces a ray may cross (RenderContext.trace); the next one it meets is opaque.
MAX_TRANSPARENT_CROSSINGS = 64
# Probe rays that find the volume a point lies in (RenderContext.enclosing_medium): a direction
# off the axes (scenes are often axis-aligned: no probe along an edge) and the surfaces they cross.
PROBE_DIRECTION = np.array([0.0123, 0.0371, 1.0]) / np.linalg.norm([0.0123, 0.0371, 1.0])
MAX_PROBE_CROSSINGS = 64
# Rays that leave the scene into the world's volume stop (photons) or get camera points within
# this many times the scene's size (Accel.extent); light that would scatter further out is lost
# (a photon 1000 scene sizes away comes back into the scene's solid angle once in a million).
FAR_EXTENTS = 1e3


@dataclass
class Surface:
    """Shading data at n surface points."""

    position: np.ndarray    # (n, 3) float64, world
    ng: np.ndarray          # (n, 3) float64 unit geometric normal (front side of the triangle)
    ns: np.ndarray          # (n, 3) float64 unit shading normal (is ng for flat shading without normal maps)
    mat_ids: np.ndarray     # (n,) int32 material index
    colors: np.ndarray      # (n, L, 3) float64 lobe colours (textured diffuse albedo filled in)
    nn: np.ndarray = None   # (n, 3) float64 shading normal before normal maps; None without normal maps
    tangent: np.ndarray = None  # (n, 3) float64 unit tangent of anisotropic glossy lobes (0 at other
    #                             points; :meth:`RenderContext.tangents`); None in scenes without them
    nc: np.ndarray = None   # (n, 3) float64 the coats' normal (Materials.coat_normal_program and
    #                         coat_bump_*; nn elsewhere); None in scenes without them: nn is the coats'


class RenderContext:
    """Scene plus acceleration structure and shading tables, built once per render/worker."""

    def __init__(self, scene, glossy_through_roughness=GLOSSY_THROUGH_ROUGHNESS, bounds=None, reuse=None,
                 take=False):
        """``glossy_through_roughness``: ``RenderSettings.glossy_through_roughness``; ``bounds``: None,
        or the box to take for the scene's (``Accel``); ``reuse``: None, or the context of an earlier
        version of the scene, whose BVH this one takes if its triangles are the same (``Accel``);
        ``take``: ``reuse`` is not used again, and its triangle tables may be changed for this one
        instead of copied (``Accel``; the live server)."""
        self.source = scene                         # the scene as given (``with_camera``, ``render``)
        self.glossy_through_roughness = glossy_through_roughness
        # Sky Textures in programs, baked once per context (``procedural.evaluate``'s sky_cache;
        # shared by ``with_camera``; not taken over by ``reuse``, whose sky may have been edited: a
        # kept cache would grow by 3 MB with each sun a dragged slider passes through).
        self.sky_cache = SkyTextureCache()
        scene = displace(scene, self.sky_cache)     # (true displacement; the scene itself without)
        self.scene = scene
        self.accel = Accel(scene, bounds, reuse=None if reuse is None else reuse.accel, take=take)
        # The materials, a copy per roughness level of those with a roughness map, per stretch
        # level of those with an anisotropy map, and the coats.
        self.materials, self.roughness_first = roughness_variants(scene.materials)
        self.materials, self.stretch_first = stretch_variants(self.materials)
        copies = np.arange(self.materials.count) >= scene.materials.count
        self.materials, coat_row = coat_variants(self.materials)
        # The surface at the exits of subsurface walks (subsurface.exit_variant; -1: none).
        self.materials, self.subsurface_exit = exit_variant(self.materials)
        coat_row = np.concatenate([coat_row, np.full(self.materials.count - len(coat_row), -1, np.int32)])
        copies = np.concatenate([copies, np.zeros(self.materials.count - len(copies), bool)])
        self.table = MaterialTable.from_materials(self.materials, coarse=copies, coat_row=coat_row,
                                                  through_roughness=glossy_through_roughness)
        self.textures = Textures(scene.textures)
        # Procedural colours: the programs and the coordinates they read.
        self.programs = scene.materials.programs
        self.has_roughness_programs = bool((self.roughness_first >= 0).any())
        levels = scene.materials.level_program
        self.has_level_programs = levels is not None and bool((levels >= 0).any())
        self.has_stretch_programs = bool((self.stretch_first >= 0).any())
        self.has_programs = bool((self.table.program >= 0).any())
        self.has_glossy_programs = bool((self.table.glossy_program >= 0).any())
        self.has_emission_programs = bool((self.table.emission_program >= 0).any())
        self.has_dielectric_programs = bool((self.table.dielectric_program >= 0).any())
        table = self.table
        self.has_translucent_programs = bool((table.translucent_program[table.translucent] >= 0).any())
        self.has_rotation_programs = bool((table.rotation_program >= 0).any())
        self.material_ids = np.ascontiguousarray(scene.material_ids)
        mats = self.materials
        # Transparency: materials a ray may pass through (Materials.opacity, opacity_program).
        self.opacity = np.asarray(mats.opacity, np.float64)
        self.opacity_program = np.asarray(mats.opacity_program, np.int32)
        self.transparent_color = np.asarray(mats.transparent_color, np.float64)
        self.see_through = (self.opacity < 1.0) | (self.opacity_program >= 0)
        self.has_transparency = bool(self.see_through.any())
        # Triangles hidden from some camera-path rays (Scene.triangle_visibility).
        self.triangle_visibility = scene.triangle_visibility
        every_ray = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION
        self.has_hidden = (self.triangle_visibility is not None
                           and bool(((self.triangle_visibility & every_ray) != every_ray).any()))
        # Holdouts (Materials.holdout, HOLDOUT_OBJECT): what camera rays that meet them cut out.
        self.holdout = np.asarray(mats.holdout, np.float64)
        self.has_holdout = bool((self.holdout > 0).any()) or (
            self.triangle_visibility is not None and bool((self.triangle_visibility & HOLDOUT_OBJECT).any()))
        # Shadow catchers (SHADOW_CATCHER, core/shadow_catcher.py): (T,) bool, or None without any (a
        # holdout object is none, as in Cycles).
        self.catcher = None
        if self.triangle_visibility is not None:
            vis = self.triangle_visibility
            catcher = ((vis & SHADOW_CATCHER) != 0) & ((vis & HOLDOUT_OBJECT) == 0)
            self.catcher = catcher if catcher.any() else None
        # Volumes (Materials.volume_absorption, volume_scattering): per-material coefficients, which
        # have a volume, and which scatter.
        self.absorption = np.asarray(mats.volume_absorption, np.float64)
        self.scattering = np.asarray(mats.volume_scattering, np.float64)
        self.anisotropy = np.asarray(mats.volume_anisotropy, np.float64)
        kinds = np.asarray(mats.volume_phase, np.int64)
        params = np.asarray(mats.volume_phase_params, np.float64)
        self.volume_emission = np.asarray(mats.volume_emission, np.float64)
        # The world's volume (World.volume_*): one more row after the materials', the medium
        # ``outside`` every mesh volume (-1: none, empty space).
        world = scene.world
        self.outside = -1
        if world.has_volume:
            self.outside = len(self.absorption)
            self.absorption = np.vstack([self.absorption, np.asarray(world.volume_absorption, np.float64)])
            self.scattering = np.vstack([self.scattering, np.asarray(world.volume_scattering, np.float64)])
            self.anisotropy = np.append(self.anisotropy, float(world.volume_anisotropy))
            kinds = np.append(kinds, int(world.volume_phase))
            params = np.vstack([params, np.asarray(world.volume_phase_params, np.float64)])
            self.volume_emission = np.vstack([self.volume_emission, np.zeros(3)])
        self.extinction = self.absorption + self.scattering
        # The media's phase functions, resolved (core/phase.py): (M [+ 1], phase.ROW).
        self.phase = phase.resolve(kinds, self.anisotropy, params)
        self.scatters = (self.scattering > 0).any(axis=1)
        self.glows = (self.volume_emission > 0).any(axis=1)
        self.volumetric = (self.absorption > 0).any(axis=1) | self.scatters | self.glows
        self.has_volume_emission = bool(self.glows.any())
        self.has_volumes = bool(self.volumetric.any())
        self.has_scattering = bool(self.scatters.any())
        self._eye_medium = self._light_media = None     # found when first needed
        # Light from afar (the sun, the world) comes through the world's unbounded volume only in
        # the channels it does not attenuate.
        through = (self.extinction[self.outside] == 0).astype(np.float64) if self.outside >= 0 else None
        # Whether some program reads the Light Path (then the passes give their rays' paths).
        self.reads_light_path = any("light_path" in attributes_used(p) for p in self.programs)
        self.lights = LightSampler(scene, self.accel, self.table, self.emitted_out, self.opacity,
                                   (self.table.emission_program >= 0) | (self.opacity_program >= 0),
                                   distant_transmittance=through, volume_emission=self.volume_emission,
                                   light_path=self.reads_light_path)
        # The light group of each glowing volume (-1: none; the world's volume does not glow).
        self.glow_groups = np.full(len(self.glows), -1, np.int64)
        glowing = np.flatnonzero(self.glows[:scene.materials.count])
        self.glow_groups[glowing] = material_groups(scene, glowing)
        # Light linking (Scene.receiver_sets): each triangle's receiver set and each emissive one's
        # links, when some emitter leaves a set out (else None: every emitter lights everything).
        self.receiver_sets = self.emitter_links = None
        if self.lights.has_links:
            t = scene.triangle_count
            self.receiver_sets = (scene.receiver_sets if scene.receiver_sets is not None
                                  else np.zeros(t, np.uint8))
            self.emitter_links = (scene.emitter_links if scene.emitter_links is not None
                                  else np.full(t, ALL_LINKS, np.uint64))
        # Shadow linking (Scene.blocker_sets): each triangle's blocker set, or None; and the
        # triangles that shadow no emitter (CASTS_NO_SHADOW), or None.  Either makes photons
        # leaving their emitter pass such triangles (trace's ``shadow``).
        self.shadowless = None
        if self.triangle_visibility is not None:
            shadowless = (self.triangle_visibility & CASTS_NO_SHADOW) != 0
            self.shadowless = shadowless if shadowless.any() else None
        self.blocker_sets = None
        if self.lights.has_shadow_links or self.shadowless is not None:
            self.blocker_sets = (scene.blocker_sets if scene.blocker_sets is not None
                                 else np.zeros(scene.triangle_count, np.uint8))
        # What camera rays that leave the scene see, when it differs from the world's bake
        # (World.camera, or a World.program of the view): a function of the directions (n, 3) and
        # the rays' origins -> radiance (n, 3), or None.
        self.camera_background = self._camera_background()
        # Normal and bump maps: per-material image index (-1: none) and parameters.
        self.normal_texture = np.ascontiguousarray(mats.normal_texture, np.int32)
        self.normal_strength = np.asarray(mats.normal_strength, np.float64)
        self.bump_texture = np.ascontiguousarray(mats.bump_texture, np.int32)
        self.bump_strength = np.asarray(mats.bump_strength, np.float64)
        self.bump_distance = np.asarray(mats.bump_distance, np.float64)
        # Either bends the shading normal (the name stays: Cycles treats both alike).
        self.has_normal_maps = self.table.has_normal_maps
        self.has_shading_normals = scene.shading_normals is not None or self.has_normal_maps
        # Per-triangle arrays gathered with take(), which copies a non-contiguous array first.
        self.shading_normals = (np.ascontiguousarray(scene.shading_normals)
                                if scene.shading_normals is not None else None)
        self.has_textures = bool((self.table.texture >= 0).any())
        # Materials that look an image up with the UVs (colour, normal or bump map).
        self.uses_uvs = (self.table.texture >= 0) | (self.normal_texture >= 0) | (self.bump_texture >= 0)
        self.bump_program = np.asarray(mats.bump_program, np.int32)
        self.outer_bump_program = np.asarray(mats.outer_bump_program, np.int32)
        self.outer_bump_strength = np.asarray(mats.outer_bump_strength, np.float64)
        self.outer_bump_distance = np.asarray(mats.outer_bump_distance, np.float64)
        self.normal_program = np.asarray(mats.normal_program, np.int32)
        self.displacement_bump = np.asarray(mats.displacement_bump, bool)
        self.has_displacement_bumps = bool(self.displacement_bump.any())
        # A coat's own normal (Principled's Coat Normal), or None: the one before the maps.
        self.coat_normal_program = np.asarray(mats.coat_normal_program, np.int32)
        self.coat_bump_program = np.asarray(mats.coat_bump_program, np.int32)
        self.coat_bump_strength = np.asarray(mats.coat_bump_strength, np.float64)
        self.coat_bump_distance = np.asarray(mats.coat_bump_distance, np.float64)
        self.has_coat_normals = bool(((self.coat_normal_program >= 0) | (self.coat_bump_program >= 0)).any())

    def _camera_background(self):
        """What camera rays that leave the scene see (``camera_background``) through its camera."""
        world = self.scene.world
        seen = world.camera
        if seen is None and world.program is not None:
            seen = world
        return _background(seen, self.scene.camera, self.textures.images, self.sky_cache)

    def with_camera(self, camera) -> "RenderContext":
        """This context for the same scene seen through ``camera`` (a ``Camera``): the acceleration
        structure, tables and lights shared, what depends on the camera made again (what camera rays
        see of the world, the medium they start in).  The 3D viewport's moved views: building the
        context of a scene of 2 million triangles takes seconds, most of it embree's BVH."""
        ctx = copy.copy(self)
        ctx.source = dataclasses.replace(self.source, camera=camera)
        ctx.scene = dataclasses.replace(self.scene, camera=camera)
        ctx._eye_medium = None
        ctx.camera_background = ctx._camera_background()
        return ctx

    @property
    def effects(self) -> tuple:
        """Names of the optional effects this scene calls for, each simulated only when named
        here (its code runs behind the flag that makes it appear): specular transport (mirrors,
        glass, rough glass, camera paths through smooth glossy lobes), translucency (light through
        thin diffuse surfaces), sheen, rough diffuse (Oren-Nayar), glossy lobes (anisotropic ones need
        tangents at every hit) and their layers (Fresnel
        layers, thin films on them, metals' Fresnel curves, coats), subsurface scattering, textures
        (images, procedural, roughness maps,
        normal and bump maps, textured emitters), true displacement, glass that refracts without
        reflecting (Refraction BSDF), lights' angular (IES) profiles, light and shadow
        linking, transparency, objects hidden from some camera rays, holdouts, shadow catchers, volumes
        (the world's too; glowing ones), an environment image, and the camera's depth of field or panorama."""
        table, w = self.table, self.table.weight
        cam = self.scene.camera
        flags = (("mirrors", (w[:, MIRROR] > 0).any()),
                 ("glass", table.has_dielectric),
                 ("rough glass", table.has_rough_dielectric),
                 ("glossy", table.has_glossy.any()),
                 ("anisotropic glossy", table.has_anisotropy),
                 ("translucency", table.has_translucent),
                 ("sheen", table.has_sheen),
                 ("rough diffuse", table.has_rough_diffuse),
                 ("camera paths through glossy", table.has_glossy_through),
                 ("Fresnel layers", table.has_layer),
                 ("thin films", table.has_film),
                 ("metal Fresnel curves", table.has_metal_curve),
                 ("coats", table.has_coat),
                 ("subsurface scattering", self.subsurface_exit >= 0),
                 ("image textures", self.has_textures),
                 ("procedural textures", self.has_programs or self.has_glossy_programs
                  or self.has_emission_programs or self.has_dielectric_programs
                  or self.has_translucent_programs),
                 ("roughness maps", self.has_roughness_programs),
                 ("rotation maps", self.has_rotation_programs),
                 ("anisotropy maps", self.has_stretch_programs),
                 ("normal and bump maps", self.has_normal_maps),
                 ("true displacement", self.scene.undisplaced is not None),
                 ("refraction without reflection", self.table.dielectric_fresnel is not None),
                 ("textured emitters", self.lights.textured_emitters),
                 ("light profiles", self.lights.has_profiles),
                 ("light linking", self.lights.has_links),
                 ("shadow linking", self.lights.has_shadow_links),
                 ("objects that cast no shadow", self.shadowless is not None),
                 ("transparency", self.has_transparency),
                 ("objects hidden from camera rays", self.has_hidden),
                 ("holdout", self.has_holdout),
                 ("shadow catcher", self.catcher is not None),
                 ("volumes", self.has_volumes),
                 ("scattering volumes", self.has_scattering),
                 ("world volume", self.outside >= 0),
                 ("volume emission", self.has_volume_emission),
                 ("environment image", self.lights.environment is not None),
                 ("depth of field", cam.aperture_radius > 0 and cam.projection not in PANORAMAS),
                 ("panorama", cam.projection in PANORAMAS))
        return tuple(name for name, on in flags if on)

    def trace(self, origins, dirs, tmax=None, uniforms=None, medium=None, ray_kind=None, shadow=None,
              distances=None, throughput=None, origin_normals=None, forced=0, cut=False, glow=None,
              crossings=None, max_crossings=None, alpha_threshold=1.0, stop_chance=None, glow_split=None):
        """Closest hits of rays ``origins + t dirs`` (0 < t < ``tmax``) on surfaces that stop them.

        A transparent surface (``Materials.opacity``) stops a ray with probability its opacity at
        the hit, decided by ``uniforms(rows, crossing)`` ((k,) numbers in [0, 1) for the rays
        ``rows`` at their ``crossing``-th transparent hit); otherwise the ray goes on from there,
        tinted by the material's transparent colour, up to ``MAX_TRANSPARENT_CROSSINGS`` times.
        ``medium`` (n,) int32 is the material whose volume each ray starts in (-1: none;
        ``outside``: the world's; None: all ``outside``), as :meth:`next_medium` tracks it; each
        segment that ends on a hit is absorbed by its volume (``Materials.volume_absorption``;
        rays that leave the scene are not, but in the world's volume, which is unbounded, they
        are extinguished in the channels it attenuates, past ``tmax`` too, as in Cycles; with
        ``cut``, rays that reach ``tmax`` in any volume are attenuated to there).  In a
        volume that scatters (``Materials.volume_scattering``) the segment ends at a distance drawn
        by ``distances(rows, segment)`` (numbers like ``uniforms``, for the rays' ``segment``-th
        segment; :func:`~core.sampling.free_flight`, its channel by the rays' ``throughput`` (n, 3)
        times the volume's albedo) where that falls before the hit: the ray
        stops in the volume there (``hits.scatter_t``, ``is_hit`` False), the factor holding
        T(t) / p(t) (without the scattering coefficient); those that reach the hit carry
        T / P(reach).  Without ``distances`` volumes only absorb.  With ``forced`` > 0 (camera
        paths) no ray stops: every segment in a scattering volume gets that many points at
        distances drawn inside it, stratified (:func:`~core.sampling.forced_flight`, each with
        1 / ``forced`` of the weight) and the ray goes on with T(L); ``hits.forced``
        = (rays, t, weight (k, 3) of the point with the factor before the segment, the segment's
        end, planes (k, 2), volumes) of those points, or None.  ``planes`` are the points'
        distances to the planes of the faces their segment entered and left the volume by (the
        first segment's entry face is ``origin_normals`` (n, 3) at the origins, if given; inf:
        none), for the gather spheres that reach out of the volume.
        ``alpha_threshold``: transparent surfaces at least this opaque stop the rays whatever
        ``uniforms`` (Cycles' data passes' Alpha Threshold; 1: none but the opaque).  ``stop_chance``,
        if given, is the chance that a transparent surface stops a ray instead of its opacity:
        ``stop_chance(prim, b1, b2, rays, opacity)`` (k,) (the data passes' rays: Cycles' closure
        pick, ``eye_pass.cycles_stop_chance``); the opacity returned stays the surface's.
        ``crossings`` (n,) int16, if given, counts the transparent surfaces each ray crosses (in
        place; not the triangles hidden from it, nor those shadow linking lets through), and a ray
        that would cross one more than ``max_crossings`` in all ends there instead, black (``is_hit``
        False, factor 0): Cycles' Transparent bounces.
        ``glow`` (n, 3), for camera paths, gets the radiance that glowing volumes
        (``Materials.volume_emission``) send along the rays to their origins, through what
        lies between (the factor at each segment's start).
        ``ray_kind`` (n,) uint8 (camera paths: VISIBLE_CAMERA, VISIBLE_GLOSSY or
        VISIBLE_TRANSMISSION) makes the rays go through triangles hidden from their kind
        (``Scene.triangle_visibility``); without it (photons) every triangle stops them.
        ``shadow`` (n,) uint64, for photons leaving their emitter: the blocker sets that shadow it
        (shadow linking, ``Lights.shadow_links``); a triangle of another set stops such a ray with
        probability 1/2 (by the same numbers), and both the rays it stops and those that go on
        through it carry twice the flux in the factor: each surface on the way gets the direct
        light it would get without that triangle.
        Returns ``(hits, factor, opacity, medium)``: the hits (``t`` from the original origins;
        glass resting on a surface resolved, ``Accel.with_contacts``; ``hits.scatter_t`` (n,) the
        distance of the rays that stopped in a volume, inf for the others, or None when no ray
        can), the (n, 3) tint of the
        crossings and volumes, the (n,) opacity where each ray stopped (1 on opaque surfaces; the
        rays that stop there are that share of those that arrive: photons deposit flux /
        opacity) and the (n,) volume each ray arrives in at its hit; the factor and the opacity
        are None when no transparent surface (nor, for the factor, volume; nor, for camera
        paths, hidden triangle) can act, and the medium is returned as given (None stays None)
        without absorbing materials."""
        accel = self.accel
        n = len(dirs)
        raw = accel.intersect(origins, dirs, tmax)
        factor = None
        stops = None            # scatter_t (n,) of the rays that stop in volumes, or a list of the
        if distances is not None and self.has_scattering:     # forced points
            stops = [] if forced else np.full(n, np.inf)
        else:
            distances = None
        limit = None if tmax is None else np.broadcast_to(np.asarray(tmax, np.float64), (n,))
        if self.has_volumes:
            medium = np.full(n, self.outside, np.int32) if medium is None else np.array(medium, np.int32)
            factor = np.ones((n, 3))
            self._absorb(factor, medium, np.arange(n), raw, dirs, distances, 0, stops, throughput,
                         origin_normals, limit if cut else None, forced, glow, glow_split)
        hits = accel.with_contacts(raw, origins, dirs)
        if stops is not None and not forced:
            hits = _stop_in_volumes(hits, stops)
        hiding = self.has_hidden and ray_kind is not None
        shadow = shadow if shadow is not None and self.blocker_sets is not None else None
        if not (self.has_transparency or hiding or shadow is not None) or not hits.is_hit.any():
            if forced and stops:
                hits.forced = _forced_points(stops)
            return hits, factor, None, medium
        is_hit, prim, b1, b2 = hits.is_hit.copy(), hits.prim_ids.copy(), hits.b1.copy(), hits.b2.copy()
        t = hits.t.astype(np.float64)
        factor = np.ones((n, 3)) if factor is None else factor
        stopped = np.ones(n)
        rows = np.flatnonzero(is_hit)
        for crossing in range(MAX_TRANSPARENT_CROSSINGS):
            pr = prim.take(rows)
            # Triangles hidden from these rays (object ray visibility) let them through untouched.
            unseen = ((self.triangle_visibility.take(pr) & ray_kind.take(rows)) == 0 if hiding
                      else np.zeros(len(rows), bool))
            clear = self.see_through.take(self.material_ids.take(pr)) & ~unseen
            passing = np.zeros(len(rows), bool)
            if shadow is not None:
                # Triangles that do not shadow the photon's emitter (shadow linking).
                sets = self.blocker_sets.take(pr)
                passing = ~linked(shadow.take(rows), sets)
                if self.shadowless is not None:
                    passing |= self.shadowless.take(pr)
            sel = unseen | clear | passing
            rows, unseen, clear, passing = rows[sel], unseen[sel], clear[sel], passing[sel]
            if len(rows) == 0:
                break
            p = accel.hit_positions(prim.take(rows), b1.take(rows), b2.take(rows))
            through = unseen.copy()
            u = np.zeros(len(rows))
            need = np.flatnonzero(clear | passing)
            if len(need):
                u[need] = uniforms(rows.take(need), crossing)
            if passing.any():
                # Stop here or go on, each with probability 1/2 (the number rescaled for the
                # opacity of those that stop), and twice the flux either way; no tint going on.
                q = np.flatnonzero(passing)
                factor[rows.take(q)] *= 2.0
                go = u.take(q) >= 0.5
                through[q[go]] = True
                u[q] = np.where(go, 2.0 * u.take(q) - 1.0, 2.0 * u.take(q))
                clear = clear & ~through
            if clear.any():
                c = np.flatnonzero(clear)
                rc = rows.take(c)
                crossing_rays = self._crossing_rays(dirs, rc, t, ray_kind)
                pc, b1c, b2c = prim.take(rc), b1.take(rc), b2.take(rc)
                opacity = self._opacity(pc, b1c, b2c, p.take(c, axis=0), crossing_rays)
                chance = opacity if stop_chance is None else stop_chance(pc, b1c, b2c, crossing_rays, opacity)
                crossed = (u.take(c) >= chance) & (opacity < min(alpha_threshold, 1.0))
                stopped[rc[~crossed]] = opacity[~crossed]
                if crossings is not None:
                    # (past the limit the ray ends here, black)
                    over = crossed & (crossings.take(rc) >= max_crossings)
                    if over.any():
                        is_hit[rc[over]] = False
                        factor[rc[over]] = 0.0
                        crossed &= ~over
                    crossings[rc[crossed]] += 1
                through[c] = crossed
            rows, p, clear = rows[through], p[through], clear[through]
            if len(rows) == 0:
                break
            pr = prim.take(rows)
            tinted = rows[clear]
            factor[tinted] *= self.transparent_color.take(self.material_ids.take(pr[clear]), axis=0)
            d = dirs.take(rows, axis=0)
            if self.has_volumes:
                medium[rows] = self.next_medium(medium.take(rows), pr, d, -d)
            start = accel.spawn(p, accel.geometric_normals.take(pr, axis=0), d, pr)
            travelled = t.take(rows) + dot(start - p, d)
            left = None if limit is None else np.maximum(limit.take(rows) - travelled, 0.0)
            raw = accel.intersect(start, d, left)
            seg = None
            if stops is not None:
                seg = [] if forced else np.full(len(rows), np.inf)
            if self.has_volumes:
                self._absorb(factor, medium, rows, raw, d, distances, crossing + 1, seg, throughput,
                             accel.geometric_normals.take(pr, axis=0) if forced else None,
                             left if cut else None, forced, glow, glow_split)
            nxt = accel.with_contacts(raw, start, d)
            if forced:
                for rr, tt, ww, ee, pp, mm in seg or ():   # (rr are the rays' own numbers)
                    off = travelled.take(np.searchsorted(rows, rr))
                    stops.append((rr, tt + off, ww, ee + off, pp, mm))
            elif seg is not None:
                nxt = _stop_in_volumes(nxt, seg)
                stops[rows] = travelled + seg
            is_hit[rows], prim[rows], b1[rows], b2[rows] = nxt.is_hit, nxt.prim_ids, nxt.b1, nxt.b2
            t[rows] = travelled + nxt.t
            rows = rows[nxt.is_hit]
        out = Hits(is_hit, prim, t.astype(np.float32), b1, b2, None if forced else stops)
        if forced and stops:
            out.forced = _forced_points(stops)
        return out, factor, stopped, medium

    def _crossing_rays(self, dirs, rows, t, ray_kind):
        """The ``Rays`` of :meth:`trace`'s rays ``rows`` at a transparent surface they cross, of the
        length ``t`` travelled: camera paths' by their ``ray_kind`` (past a mirror or glass, as
        after one bounce: ``procedural.camera_path``), photons' as their hits
        (``procedural.photon_path``)."""
        incoming = -dirs.take(rows, axis=0)
        if not self.reads_light_path:
            return Rays(incoming)
        lengths = t.take(rows)
        if ray_kind is None:
            return Rays(incoming, path=photon_path(lengths))
        kind = ray_kind.take(rows)
        glossy, transmission = kind == VISIBLE_GLOSSY, kind == VISIBLE_TRANSMISSION
        return Rays(incoming, path=camera_path(kind == VISIBLE_CAMERA, glossy, lengths, glossy | transmission,
                                               glossy, transmission))

    def _absorb(self, factor, medium, rows, raw, dirs, distances=None, segment=0, stops_out=None,
                throughput=None, entry_normals=None, limit=None, forced=1, glow=None, glow_split=None):
        """Absorb the segments of rays ``rows`` that end on the hits ``raw`` (before contacts;
        ``dirs`` their directions) in ``factor``, and set ``medium`` to the volume each one was
        in: the tracked one, or that of a surface hit from the back (the ray was inside it).
        Rays that miss in a volume go on to ``limit`` (len(rows),) (None or inf: to infinity, where
        only the world's volume, ``outside``, reaches; other volumes leave them as they are).
        With ``distances`` (see :meth:`trace`), segments in a scattering volume draw where they
        stop instead: ``stops_out`` (len(rows),) gets the distances of those that stop; or, a
        list, gets ``forced`` points in each such segment (rays, t, weight, segment length,
        distances to the planes of the faces the segment started from (``entry_normals``, if
        given) and went to, volumes).  ``glow`` (n, 3), if given, gets the radiance glowing
        volumes send along the segments (:func:`~core.sampling.volume_glow`, times ``factor``), and
        ``glow_split`` (G, n, 3), if given, the same at each glowing volume's light group
        (``glow_groups``; volumes in none are left out)."""
        hit = raw.is_hit
        if self.outside >= 0 or limit is not None:
            # Misses in a volume: in the world's, or cut short by the limit.
            now = medium.take(rows)
            cut = np.isfinite(limit) if limit is not None else False
            hit = hit | ((now >= 0) & ((now == self.outside) | cut))
        h = np.flatnonzero(hit)
        if len(h) == 0:
            return
        on = raw.is_hit.take(h)
        r = rows.take(h)
        inside = medium.take(r)
        if on.any():
            prim = np.where(on, raw.prim_ids.take(h), 0)
            mat = self.material_ids.take(prim)
            back = on & (dot(dirs.take(h, axis=0), self.accel.geometric_normals.take(prim, axis=0)) > 0)
            inside = np.where(back & self.volumetric.take(mat), mat, inside)
        medium[r] = inside
        a = np.flatnonzero(inside >= 0)
        if len(a) == 0:
            return
        vol = inside.take(a)
        end = np.full(len(h), np.inf) if limit is None else limit.take(h)
        length = np.where(on, raw.t.take(h).astype(np.float64), end).take(a)
        # Points and stops on an unbounded segment are drawn within FAR_EXTENTS scene sizes.
        far = FAR_EXTENTS * self.accel.extent
        if glow is not None and self.has_volume_emission:
            e = np.flatnonzero(self.glows.take(vol))
            if len(e):
                re, ve = r.take(a.take(e)), vol.take(e)
                value = factor.take(re, axis=0) * volume_glow(
                    self.extinction.take(ve, axis=0), self.volume_emission.take(ve, axis=0),
                    np.minimum(length.take(e), far))
                glow[re] += value
                if glow_split is not None:
                    group = self.glow_groups.take(ve)
                    for g in np.unique(group[group >= 0]):      # (the few groups of glowing volumes)
                        sel = np.flatnonzero(group == g)
                        glow_split[g, re.take(sel)] += value.take(sel, axis=0)
        if distances is not None and isinstance(stops_out, list):
            # Forced points: ``forced`` inside every segment in a scattering volume, their numbers
            # stratified (a whole image's points then vary less than with one per segment, for
            # the same photons; README "Camera points in fog"); all rays go on.
            s = np.flatnonzero(self.scatters.take(vol))
            if len(s):
                rs, ms = r.take(a.take(s)), vol.take(s)
                thr = factor.take(rs, axis=0) * (1.0 if throughput is None else throughput.take(rs, axis=0))
                seg_len = np.minimum(length.take(s), far)
                unbounded = np.flatnonzero(~np.isfinite(length.take(s)))
                sig_t, sig_s = self.extinction.take(ms, axis=0), self.scattering.take(ms, axis=0)
                u = distances(rs, segment)
                at = h.take(a.take(s))
                d_at = dirs.take(at, axis=0)
                exits = np.flatnonzero(on.take(a.take(s)))            # (a miss leaves by no face)
                n_exit = self.accel.geometric_normals.take(raw.prim_ids.take(at.take(exits)), axis=0)
                cos_exit = np.abs(dot(d_at.take(exits, axis=0), n_exit))
                cos_entry = (np.abs(dot(d_at, entry_normals.take(at, axis=0))) if entry_normals is not None
                             else None)
                for k in range(forced):
                    t, weight, transmitted = forced_flight(sig_t, sig_s, (k + u) / forced, seg_len, thr)
                    planes = np.full((len(s), 2), np.inf)
                    planes[exits, 1] = (seg_len.take(exits) - t.take(exits)) * cos_exit
                    if cos_entry is not None:
                        planes[:, 0] = t * cos_entry
                    point_weight = factor.take(rs, axis=0) * (weight / forced)
                    stops_out.append((rs, t, point_weight, length.take(s), planes, ms))
                transmitted[unbounded] = transmittance(sig_t.take(unbounded, axis=0),
                                                       length.take(s).take(unbounded))       # T(inf)
                factor[rs] *= transmitted
                keep = np.ones(len(a), bool)
                keep[s] = False
                a, vol, length = a[keep], vol[keep], length[keep]
        elif distances is not None:
            s = np.flatnonzero(self.scatters.take(vol))
            if len(s):
                rs, ms = r.take(a.take(s)), vol.take(s)
                thr = factor.take(rs, axis=0) * (1.0 if throughput is None else throughput.take(rs, axis=0))
                t, stops, weight = free_flight(self.extinction.take(ms, axis=0),
                                               self.scattering.take(ms, axis=0), distances(rs, segment),
                                               np.minimum(length.take(s), far), thr)
                factor[rs] *= weight
                stops_out[h.take(a.take(s[stops]))] = t[stops]
                keep = np.ones(len(a), bool)
                keep[s] = False
                a, vol, length = a[keep], vol[keep], length[keep]
        if len(a):
            factor[r.take(a)] *= transmittance(self.absorption.take(vol, axis=0), length)

    def factor_to(self, origins, dirs, t, medium, ray_kind, crossings=None, max_crossings=None):
        """(n, 3) what reaches distances ``t`` (n,) (inf: infinity) along camera-path rays that
        get there (they crossed every transparent surface before): the tints of those surfaces
        and the transmittance of the volumes on the way, from ``medium`` (n,) at the origins; 0
        past ``max_crossings`` transparent surfaces with the ``crossings`` (n,) made before
        (Cycles' Transparent bounces; None: not counted)."""
        crossing = lambda rows, k: np.full(len(rows), 1.0 - 2.0 ** -53)     # noqa: E731
        counts = None if crossings is None else np.array(crossings, np.int16)
        _, factor, _, _ = self.trace(origins, dirs, t, crossing, medium, ray_kind, distances=crossing,
                                     forced=1, cut=True, crossings=counts, max_crossings=max_crossings)
        return np.ones((len(dirs), 3)) if factor is None else factor

    def enclosing_medium(self, points):
        """(n,) int32 the volume each of ``points`` lies in (``outside``: none of the meshes'), as
        Cycles finds a camera's: a probe ray from each point walks through every surface; the
        first one of an absorbing material that it leaves (meets from the back) without having
        gone into it along the probe encloses the point.  A single slot tracks the volume the probe went
        into, so a point is found in the innermost of nested volumes only when the probe
        crosses no other volume before leaving it."""
        n = len(points)
        found = np.full(n, self.outside, np.int32)
        if not self.has_volumes or n == 0:
            return found
        entered = np.full(n, -1, np.int32)
        rows = np.arange(n)
        origins = np.asarray(points, np.float64)
        d = np.broadcast_to(PROBE_DIRECTION, (n, 3))
        for _ in range(MAX_PROBE_CROSSINGS):
            hits = self.accel.intersect(origins, d)
            h = np.flatnonzero(hits.is_hit)
            rows, origins, d = rows.take(h), origins.take(h, axis=0), d.take(h, axis=0)
            if len(rows) == 0:
                break
            prim = hits.prim_ids.take(h)
            mat = self.material_ids.take(prim)
            ng = self.accel.geometric_normals.take(prim, axis=0)
            back = dot(d, ng) > 0
            volume = self.volumetric.take(mat)
            inside = entered.take(rows)
            into = volume & ~back & (inside < 0)
            entered[rows[into]] = mat[into]
            out = volume & back & (inside == mat)
            entered[rows[out]] = -1
            done = volume & back & (inside < 0)
            found[rows[done]] = mat[done]
            go = np.flatnonzero(~done)
            hit = h.take(go)
            p = self.accel.hit_positions(prim.take(go), hits.b1.take(hit), hits.b2.take(hit))
            rows, d = rows.take(go), d.take(go, axis=0)
            origins = self.accel.spawn(p, ng.take(go, axis=0), d, prim.take(go))
        return found

    def holdout_at(self, prim):
        """(n,) the holdout share of hits on triangles ``prim``: their material's ``holdout``, 1
        on a holdout object's triangles."""
        h = self.holdout.take(self.material_ids.take(prim))
        if self.triangle_visibility is not None:
            h = np.where((self.triangle_visibility.take(prim) & HOLDOUT_OBJECT) != 0, 1.0, h)
        return h

    def camera_medium(self, origins):
        """(n,) the volume camera rays from ``origins`` start in (:meth:`enclosing_medium`; a
        perspective or panoramic camera's is its eye's, found once)."""
        cam = self.scene.camera
        if cam.projection == "orthographic":
            return self.enclosing_medium(origins)
        if self._eye_medium is None:
            eye = np.asarray(cam.world_from_camera, np.float64)[:3, 3]
            self._eye_medium = int(self.enclosing_medium(eye[None])[0])
        return np.full(len(origins), self._eye_medium, np.int32)

    def light_medium(self, u0):
        """(n,) the volume photons of light-choice numbers ``u0`` start in: that of the point,
        spot or area light's centre (:meth:`enclosing_medium`, found once); a glowing volume's
        own; ``outside`` for the sun, the world and emitting triangles (a path that starts inside
        still is inside where it leaves)."""
        if self._light_media is None:
            kinds = self.lights.kinds
            self._light_media = np.full(len(kinds), self.outside, np.int32)
            glowing = kinds == VOLUME
            self._light_media[glowing] = self.lights.ids[glowing]
            placed = np.flatnonzero(np.isin(kinds, (POINT, SPOT, AREA_RECT, AREA_DISK)))
            if len(placed):
                centres = np.asarray(self.scene.lights.position, np.float64)[self.lights.ids[placed]]
                self._light_media[placed] = self.enclosing_medium(centres)
        return self._light_media.take(self.lights.entries(u0))

    def next_medium(self, medium, prim_ids, wi, wo):
        """(n,) the volumes of paths that arrived in ``medium`` at triangles ``prim_ids`` from
        ``wo`` and leave along ``wi``: a path that goes through the surface into its back enters
        the material's volume (if it has one; otherwise it stays where it was), one that goes
        out through its front leaves it (to ``outside``); a reflected path stays."""
        mat = self.material_ids.take(prim_ids)
        ng = self.accel.geometric_normals.take(prim_ids, axis=0)
        into, came = dot(wi, ng), dot(wo, ng)
        enter = (into < 0) & (came > 0) & self.volumetric.take(mat)
        leave = (into > 0) & (came < 0) & (medium == mat)
        return np.where(enter, mat, np.where(leave, self.outside, medium)).astype(np.int32)

    def _opacity(self, prim_ids, b1, b2, positions, rays=None):
        """(k,) opacity at points of triangles ``prim_ids``: the material's, or its program's (met by
        ``rays``, ``procedural.Rays``)."""
        mat = self.material_ids.take(prim_ids)
        out = self.opacity.take(mat)
        bary = ((1.0 - b1 - b2)[:, None], b1[:, None], b2[:, None])
        for sel, value in self._program_values(self.opacity_program, prim_ids, bary, positions, mat, rays):
            out[sel] = np.clip(np.nan_to_num(value, nan=1.0), 0.0, 1.0)
        return out

    def surface(self, prim_ids, b1, b2, pick=None, rays=None) -> Surface:
        """Surface data at hits given by triangle ids and barycentrics; ``pick`` (n,) uniform
        numbers choose the materials' levels (``Materials.level_program``; None: the nearest);
        ``rays`` (``procedural.Rays``, or None) the rays that meet them, which programs may read:
        their directions, whether they are sharp (a Bevel), their light path."""
        a = self.accel
        pos = a.hit_positions(prim_ids, b1, b2)
        ng = a.geometric_normals.take(prim_ids, axis=0)
        b0 = 1.0 - b1 - b2
        mat = self.material_ids.take(prim_ids)
        bary = (b0[:, None], b1[:, None], b2[:, None])
        if self.has_level_programs:
            self._pick_level(mat, prim_ids, bary, pos, pick, rays)
        if self.has_roughness_programs:
            self._pick_roughness(mat, prim_ids, bary, pos, rays)
        if self.has_stretch_programs:
            self._pick_stretch(mat, prim_ids, bary, pos, rays)
        if self.shading_normals is not None:
            ns = normalize(interpolate_corners(self.shading_normals.take(prim_ids, axis=0), bary))
            _replace_bad(ns, ng)
        else:
            ns = ng.copy() if self.has_normal_maps else ng
        # Texture coordinates, once for every image lookup at these hits.
        uv = None
        if self.uses_uvs.take(mat).any():
            uv = interpolate_corners(self.scene.uvs.take(prim_ids, axis=0), bary)
        nn = nc = None
        if self.has_normal_maps:
            nn = ns.copy()
            if self.has_coat_normals:
                nc = ns.copy()
                self._apply_normal_programs(nc, prim_ids, bary, pos, mat, rays, self.coat_normal_program)
                self._bump_by_programs(nc, prim_ids, bary, pos, mat, rays, self.coat_bump_program,
                                       self.coat_bump_strength, self.coat_bump_distance)
            self._apply_normal_programs(ns, prim_ids, bary, pos, mat, rays)
            self._apply_normal_maps(ns, prim_ids, bary, uv, mat)
            self._apply_bump_maps(ns, prim_ids, bary, pos, uv, mat, rays, nn)
        albedo = self.table.color[:, 0].take(mat, axis=0)
        if self.has_textures:
            tex = self.table.texture[mat]
            if (tex >= 0).any():
                albedo = np.where((tex >= 0)[:, None],
                                  albedo * self.textures.lookup(tex, uv), albedo)
        if self.has_programs:
            for sel, color in self._program_colors(self.table.program, prim_ids, bary, pos, mat,
                                                   rays=rays):
                albedo[sel] *= color           # a fresh array (take or where above)
        colors = lobe_colors(self.table, mat, albedo)
        if self.has_glossy_programs:
            lobe = self.table.glossy_program_lobe
            for sel, color in self._program_colors(self.table.glossy_program, prim_ids, bary, pos, mat,
                                                   rays=rays):
                colors[sel, lobe.take(mat.take(sel))] *= color
        if self.table.has_partial_metal:
            # A metal that is part k of its lobe: the colour so far is its F0, the lobe's k F0 + rest.
            t = self.table
            part = np.flatnonzero(t.hit_metal.take(mat) & (t.hit_metal_share.take(mat) < 1.0))
            if len(part):
                m = mat.take(part)
                lobe = t.hit_metal_lobe.take(m)
                colors[part, lobe] = (t.hit_metal_share.take(m)[:, None] * colors[part, lobe]
                                      + t.hit_metal_rest.take(m, axis=0))
        if self.has_dielectric_programs:
            for sel, color in self._program_colors(self.table.dielectric_program, prim_ids, bary, pos, mat,
                                                   rays=rays):
                colors[sel, DIELECTRIC] *= color
        if self.has_translucent_programs:
            for sel, color in self._program_colors(self.table.translucent_program, prim_ids, bary, pos, mat,
                                                   rays=rays):
                colors[sel, TRANSLUCENT] *= color
        tangent = None
        if self.table.has_anisotropy:
            tangent = self.tangents(prim_ids, bary, pos, mat, ns if nn is None else nn, ns, rays)
        return Surface(pos, ng, ns, mat, colors, nn, tangent, nc)

    def tangents(self, prim_ids, bary, pos, mat, smooth, ns, rays=None):
        """(n, 3) the tangents of anisotropic glossy lobes at hits (0 where the material ``mat`` has
        none), as Cycles' Tangent node and closure: the radial direction about an object axis
        through the centre of the texture space (from the Generated coordinates; without
        objects the world position) or the UV map's tangent, taken to world space as a normal
        is, made perpendicular to the ``smooth`` normal (before normal maps), then turned about
        the shading normal ``ns`` by the material's rotation or its rotation map's value at the
        hit (about the front side's normal: Cycles turns about the normal facing the ray, which on
        a back face turns the other way; a quarter or half turn gives the same lobe either way)."""
        out = np.zeros((len(mat), 3))
        sel = np.flatnonzero(self.table.anisotropic.take(mat))
        if len(sel) == 0:
            return out
        m = mat.take(sel)
        axis = self.table.tangent_axis.take(m)
        w = tuple(b.take(sel, axis=0) for b in bary)
        raw = np.zeros((len(sel), 3))
        uv = np.flatnonzero(axis == TANGENT_UV)
        if len(uv):
            raw[uv] = interpolate_corners(self.scene.tangents.take(prim_ids.take(sel.take(uv)), axis=0),
                                          tuple(b.take(uv, axis=0) for b in w))[:, :3]
        radial = np.flatnonzero(axis != TANGENT_UV)
        if len(radial):
            r = sel.take(radial)
            scene = self.scene
            if scene.object_ids is None:
                raw[radial] = radial_tangents(pos.take(r, axis=0) - 0.5, axis.take(radial))  # (no Generated)
            else:
                attrs = HitAttributes(scene, prim_ids.take(r), tuple(b.take(radial, axis=0) for b in w),
                                      pos.take(r, axis=0))
                objects = scene.object_from_world.take(scene.object_ids.take(prim_ids.take(r)), axis=0)
                raw[radial] = radial_tangents(attrs.get("generated") - 0.5, axis.take(radial), objects)
        t = perpendicular_tangents(raw, smooth.take(sel, axis=0))
        turn = self.table.rotation.take(m).astype(np.float64)
        if self.has_rotation_programs:
            for s, value in self._program_values(self.table.rotation_program, prim_ids.take(sel), w,
                                                 pos.take(sel, axis=0), m,
                                                 None if rays is None else rays.take(sel)):
                turn[s] = np.nan_to_num(value, nan=0.0, posinf=0.0, neginf=0.0)
        if (turn != 0).any():
            # Rodrigues' rotation about the shading normal (Cycles' rotate_around_axis).
            k = ns.take(sel, axis=0)
            angle = 2.0 * np.pi * turn
            cos, sin = np.cos(angle)[:, None], np.sin(angle)[:, None]
            t = t * cos + np.cross(k, t) * sin + k * (dot(k, t)[:, None] * (1.0 - cos))
        out[sel] = t
        return out

    def _pick_level(self, mat, prim_ids, bary, pos, pick=None, rays=None):
        """Replace, in place, the materials ``mat`` (n,) that pick one of their levels at each hit
        (``Materials.level_program``) by a level: with ``pick`` ((n,) uniform numbers) one of the
        two around the program's value there, the upper with the probability of the value's
        fraction between them (``Materials``); without, the nearest."""
        mats = self.materials
        for sel, value in self._program_values(mats.level_program, prim_ids, bary, pos, mat, rays):
            m = mat.take(sel)
            top = mats.level_count.take(m) - 1
            x = np.clip(np.nan_to_num(value, nan=0.0), 0.0, 1.0) * top
            if pick is None:
                level = np.rint(x)
            else:
                level = np.floor(x)
                level += pick.take(sel) < x - level
                np.minimum(level, top, out=level)
            mat[sel] = mats.level_first.take(m) + level.astype(np.int32)

    def _pick_roughness(self, mat, prim_ids, bary, pos, rays=None):
        """Replace, in place, the materials ``mat`` (n,) that have a roughness map by their copy of
        the nearest roughness level (``bsdf.roughness_variants``) at these hits."""
        for sel, value in self._program_values(self.materials.roughness_program, prim_ids, bary, pos, mat,
                                               rays):
            level = np.rint(np.clip(np.nan_to_num(value, nan=0.0), 0.0, 1.0) * (ROUGHNESS_LEVELS - 1))
            mat[sel] = self.roughness_first.take(mat.take(sel)) + level.astype(np.int32)

    def _pick_stretch(self, mat, prim_ids, bary, pos, rays=None):
        """Replace, in place, the materials ``mat`` (n,) that have an anisotropy map by their copy of
        the nearest stretch level (``bsdf.stretch_variants``) at these hits."""
        for sel, value in self._program_values(self.materials.stretch_program, prim_ids, bary, pos, mat,
                                               rays):
            mat[sel] = self.stretch_first.take(mat.take(sel)) + stretch_level(value)

    def emitted(self, prim_ids, b1, b2, mat=None, positions=None, rays=None):
        """(n, 3) float64 radiance emitted at the points of triangles ``prim_ids`` with barycentrics
        ``b1``, ``b2``: the material's emission times its emission program there (``mat`` (n,) and
        ``positions`` (n, 3) when the caller has them; ``rays`` the rays it is seen by, which
        programs may read, ``procedural.Rays``)."""
        if mat is None:
            mat = self.material_ids.take(prim_ids)
        out = self.table.emission.take(mat, axis=0)
        if self.has_emission_programs:
            if positions is None:
                positions = self.accel.hit_positions(prim_ids, b1, b2)
            bary = ((1.0 - b1 - b2)[:, None], b1[:, None], b2[:, None])
            programs = self.table.emission_program
            for sel, factor in self._program_colors(programs, prim_ids, bary, positions, mat, EMISSION_MAX,
                                                    rays):
                out[sel] *= factor
        return out

    def emitted_out(self, prim_ids, b1, b2, mat=None, positions=None, rays=None):
        """(n, 3) radiance that leaves the points of emissive triangles: :meth:`emitted` times the
        opacity there (a half-transparent emitter emits half: Cycles' Alpha scales emission)."""
        out = self.emitted(prim_ids, b1, b2, mat, positions, rays)
        if self.has_transparency:
            if positions is None:
                positions = self.accel.hit_positions(prim_ids, b1, b2)
            out *= self._opacity(prim_ids, b1, b2, positions, rays)[:, None]
        return out

    def _program_values(self, programs, prim_ids, bary, pos, mat, rays=None):
        """(hit indices, (k,) numbers) for each float program in ``programs`` (per material, -1:
        none) that some of the hits' materials have; a colour counts by its luminance (Cycles)."""
        program = programs.take(mat)
        for p in np.unique(program[program >= 0]):
            sel = np.flatnonzero(program == p)
            value = evaluate(self.programs[p], self._hit_attributes(sel, prim_ids, bary, pos, rays),
                             self.textures.images, sky_cache=self.sky_cache)
            yield sel, (value @ LUMINANCE if value.ndim == 2 else value)

    def aov_values(self, column, prim_ids, b1, b2, pos, rays=None):
        """(writes (k,) bool, values (k, 3) float64) of the Shader AOV ``column``
        (``Materials.aov_names``) at hits of triangles ``prim_ids`` (barycentrics ``b1``, ``b2``,
        positions ``pos``, met by ``rays``): whether each triangle's material writes it, and its
        value there (a number repeated), unclamped as Cycles writes it; NaN -> 0."""
        mats = self.scene.materials
        mat = self.material_ids.take(prim_ids)
        writes = mats.aov_writes[:, column].take(mat)
        values = mats.aov_value[:, column].take(mat, axis=0).astype(np.float64)
        program = mats.aov_program[:, column].take(mat)
        bary = ((1.0 - b1 - b2)[:, None], b1[:, None], b2[:, None])
        for p in np.unique(program[program >= 0]):
            sel = np.flatnonzero(program == p)
            attrs = self._hit_attributes(sel, prim_ids, bary, pos, rays)
            v = evaluate(self.programs[p], attrs, self.textures.images, sky_cache=self.sky_cache)
            values[sel] = v if v.ndim == 2 else v[:, None]
        return writes, np.nan_to_num(values, nan=0.0, posinf=0.0, neginf=0.0)

    def _hit_attributes(self, sel, prim_ids, bary, pos, rays):
        """``HitAttributes`` of the hits ``sel`` of these (which may cast Ambient Occlusion's and, for
        sharp ``rays``, Bevel's rays)."""
        return HitAttributes(self.scene, prim_ids.take(sel), tuple(w.take(sel, axis=0) for w in bary),
                             pos.take(sel, axis=0), None if rays is None else rays.take(sel), self.accel)

    def _program_colors(self, programs, prim_ids, bary, pos, mat, limit=COLOR_MAX, rays=None):
        """(hit indices, (k, 3) colours in [0, ``limit``]) for each program in ``programs`` (per
        material, -1: none) that some of the hits' materials have (met by ``rays``)."""
        program = programs.take(mat)
        for p in np.unique(program[program >= 0]):
            sel = np.flatnonzero(program == p)
            attrs = self._hit_attributes(sel, prim_ids, bary, pos, rays)
            yield sel, evaluate_color(self.programs[p], attrs, self.textures.images, limit, self.sky_cache)

    def _apply_normal_programs(self, ns, prim_ids, bary, pos, mat, rays, programs=None):
        """Replace ``ns`` (n, 3) in place by the normalised value of the material's normal program
        (``programs`` per material, None: ``Materials.normal_program``) where it has one, keeping
        ``ns`` where that is zero or not finite (Cycles' ``safe_normalize_fallback``)."""
        program = (self.normal_program if programs is None else programs).take(mat)
        for p in np.unique(program[program >= 0]):
            sel = np.flatnonzero(program == p)
            attrs = self._hit_attributes(sel, prim_ids, bary, pos, rays)
            value = evaluate(self.programs[p], attrs, self.textures.images, sky_cache=self.sky_cache)
            if value.ndim == 1:
                continue                            # (a float is no direction: the exporter sends none)
            n0 = ns.take(sel, axis=0)
            n = normalize(np.nan_to_num(value, nan=0.0, posinf=0.0, neginf=0.0))
            _replace_bad(n, n0)
            ns[sel] = n

    def _apply_normal_maps(self, ns, prim_ids, bary, uv, mat):
        """Bend ``ns`` (n, 3) in place where the material has a normal map.

        As Cycles' Normal Map node: c = 2 rgb - 1; in tangent space (c_x, c_y) times the strength
        s and c_z blended from 1 by min(s, 1), N = normalize(c_x T + c_y B + c_z N0) with T the
        interpolated tangent, B = w (N0 x T) and N0 the interpolated shading normal (here unit
        length); in object or world space (``Materials.normal_space``) N = normalize(c) (y and z
        flipped for Blender's variants, through the object's normal matrix for the object's),
        then normalize(N0 + (N - N0) s) where s is not 1.  No tangent frame (zero tangent) or a
        degenerate result keeps N0.
        """
        tex = self.normal_texture.take(mat)
        sel = np.flatnonzero(tex >= 0)
        if len(sel) == 0:
            return
        c = 2.0 * self.textures.lookup(tex.take(sel), uv.take(sel, axis=0)) - 1.0
        s = self.normal_strength.take(mat.take(sel))
        n0 = ns.take(sel, axis=0)
        space = self.materials.normal_space.take(mat.take(sel))
        other = np.flatnonzero(space != NORMAL_TANGENT)
        if len(other):
            rows = sel.take(other)
            ns[rows] = self._spatial_normals(c.take(other, axis=0), space.take(other), prim_ids.take(rows),
                                             n0.take(other, axis=0), s.take(other))
            tangent_space = np.flatnonzero(space == NORMAL_TANGENT)
            if len(tangent_space) == 0:
                return
            sel, c, s = sel.take(tangent_space), c.take(tangent_space, axis=0), s.take(tangent_space)
            n0 = n0.take(tangent_space, axis=0)
        tg = interpolate_corners(self.scene.tangents.take(prim_ids.take(sel), axis=0),
                                 tuple(w.take(sel, axis=0) for w in bary))    # (k, 4): xyz and sign
        ns[sel] = tangent_space_normals(c, s, n0, tg)

    def _spatial_normals(self, c, space, prim_ids, n0, strength):
        """(k, 3) the normals of object- or world-space normal maps of colours ``c`` (2 rgb - 1) at
        hits on triangles ``prim_ids`` with shading normals ``n0`` (Cycles' ``svm_node_normal_map``)."""
        c = np.array(c, np.float64)
        flip = np.isin(space, (NORMAL_BLENDER_OBJECT, NORMAL_BLENDER_WORLD))
        c[flip, 1:] *= -1.0                                  # ("strange blender convention")
        in_object = np.flatnonzero(np.isin(space, (NORMAL_OBJECT, NORMAL_BLENDER_OBJECT)))
        if len(in_object):
            # A normal's transform out of the object: A^T c with A the object-from-world matrix.
            objects = self.scene.object_from_world.take(self.scene.object_ids.take(prim_ids.take(in_object)),
                                                        axis=0)
            c[in_object] = np.einsum("kji,kj->ki", objects[:, :, :3], c.take(in_object, axis=0))
        return spatial_normals(c, strength, n0)

    def _apply_bump_maps(self, ns, prim_ids, bary, pos, uv, mat, rays=None, nn=None):
        """Bend ``ns`` (n, 3) in place where the material has a bump map (after a normal map).

        As Cycles' Bump node, with the height's gradient along a parametrisation (u, v) of the
        triangle instead of finite differences over the pixel footprint: with dP/du, dP/dv,
        R_u = dP/dv x N, R_v = N x dP/du and det = dP/du . R_u,
        N' = normalize(|det| N - d sign(det) (h_u R_u + h_v R_v)), d the distance, and then
        normalize(s N' + (1 - s) N) for strength s (the result does not depend on the
        parametrisation).  An image's height (its luminance) takes the UVs and the bilinear
        image's exact gradient (triangles without a UV parametrisation keep N); a program's
        (``Materials.bump_program``) the barycentrics b1, b2 (dP/db = the edges) and forward
        differences of ``BUMP_STEP`` times the object's size along each edge.  A second bump
        (``Materials.outer_bump_program``, a Bump on a Bump) then bends the normal the first made.
        Where the first is the Displacement output's (``Materials.displacement_bump``) it replaces
        the surface's own normal ``nn`` too (Cycles' Set Normal), which the bump-map terms compare
        the shading normal with.
        """
        tex = self.bump_texture.take(mat)
        sel = np.flatnonzero(tex >= 0)
        if len(sel):
            p = prim_ids.take(sel)
            uvs = self.scene.uvs.take(p, axis=0).astype(np.float64)                    # (k, 3, 2)
            e1, e2 = bump_edges(self.scene, p)
            d1, d2 = uvs[:, 1] - uvs[:, 0], uvs[:, 2] - uvs[:, 0]
            det_uv = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
            ok = np.abs(det_uv) > 1e-20
            inv = np.where(ok, 1.0 / np.where(ok, det_uv, 1.0), 0.0)[:, None]
            dpdu = (d2[:, 1:2] * e1 - d1[:, 1:2] * e2) * inv
            dpdv = (d1[:, 0:1] * e2 - d2[:, 0:1] * e1) * inv
            gu, gv = self.textures.gradient(tex.take(sel), uv.take(sel, axis=0))
            m = mat.take(sel)
            n0 = ns.take(sel, axis=0)
            n = bend_normals(n0, dpdu, dpdv, gu @ LUMINANCE, gv @ LUMINANCE, self.bump_strength.take(m),
                             self.bump_distance.take(m))
            ns[sel] = np.where(ok[:, None], n, n0)
        self._bump_by_programs(ns, prim_ids, bary, pos, mat, rays, self.bump_program, self.bump_strength,
                               self.bump_distance)
        if nn is not None and self.has_displacement_bumps:
            replaced = np.flatnonzero(self.displacement_bump.take(mat))
            nn[replaced] = ns[replaced]
        self._bump_by_programs(ns, prim_ids, bary, pos, mat, rays, self.outer_bump_program,
                               self.outer_bump_strength, self.outer_bump_distance)

    def _bump_by_programs(self, ns, prim_ids, bary, pos, mat, rays, programs, strength, distance):
        """Bend ``ns`` in place where the materials ``mat`` have a bump's height program among
        ``programs`` (per material), of ``strength`` and ``distance`` (``procedural.bumped_normals``,
        with differences of ``BUMP_STEP`` times the object's size)."""
        program = programs.take(mat)
        for k in np.unique(program[program >= 0]):
            sel = np.flatnonzero(program == k)
            m = mat.take(sel)
            step = BUMP_STEP * self.accel.object_sizes(prim_ids.take(sel))
            ns[sel] = bumped_normals(self._hit_attributes(sel, prim_ids, bary, pos, rays), self.programs[k],
                                     self.textures.images, ns.take(sel, axis=0), strength.take(m),
                                     distance.take(m), step, self.sky_cache)


def _forced_points(parts):
    """The forced volume points of a trace as (rays, t, weight, ends, planes, volumes), each
    concatenated over the segments."""
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(6))


def _stop_in_volumes(hits, scatter_t):
    """``hits`` with the rays that stopped in a volume (finite ``scatter_t``) no longer hitting:
    their ``t`` the distance where they stopped, ``scatter_t`` attached."""
    stop = np.isfinite(scatter_t)
    if not stop.any():
        return Hits(hits.is_hit, hits.prim_ids, hits.t, hits.b1, hits.b2, scatter_t)
    return Hits(hits.is_hit & ~stop, np.where(stop, -1, hits.prim_ids).astype(np.int32),
                np.where(stop, scatter_t, hits.t).astype(np.float32), hits.b1, hits.b2, scatter_t)


def _background(world, camera, images, sky_cache=None):
    """Radiance of ``world`` (a ``World``: colour, times its program of the view seen by ``camera``
    with the scene's ``images`` and Sky Textures' bakes ``sky_cache``, or times its image) as a
    function of camera rays' directions and origins (n, 3), or None."""
    if world is None:
        return None
    color = np.asarray(world.color, np.float64)
    if world.program is not None:
        program = world.program

        def seen(dirs, origins=None):
            attrs = DirectionAttributes(dirs, camera, origins)
            return color * evaluate_color(program, attrs, images, EMISSION_MAX, sky_cache)
        return seen
    if world.texture is None:
        return lambda dirs, origins=None: np.broadcast_to(color, (len(dirs), 3))
    radiance = Environment(color, world.texture, world.texture_rotation).radiance
    return lambda dirs, origins=None: radiance(dirs)


def _replace_bad(n, fallback):
    """Rows of ``n`` that are zero or NaN (e.g. after interpolation or normalising) take ``fallback``'s."""
    # Columns: sum(axis=1) is slow for (n, 3).
    bad = np.flatnonzero(~(np.abs(n[:, 0]) + np.abs(n[:, 1]) + np.abs(n[:, 2]) > 0))
    n[bad] = fallback[bad]

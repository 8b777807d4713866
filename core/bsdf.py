"""Materials as weighted lobes: lobe choice, sampling and evaluation on batches.

Lobes (index order used everywhere): 0 diffuse, 1 glossy (GGX), 2 mirror,
3 dielectric, 4 translucent (Lambertian transmission) in tables of scenes that have
it, and 5 sheen (Cycles' microfiber sheen, :func:`sheen_albedo`) in tables of scenes that have
that (``MaterialTable.lobes``: 4, 5 or 6 columns).  Diffuse, glossy, translucent and sheen are
*non-delta* (photons are deposited on them and camera paths store measurement points
there); mirror and dielectric are *delta* (camera paths continue through them).  A sheen lies
over the rest of its material: every other lobe takes :meth:`MaterialTable.sheen_dim` at the
view direction.
Emission is not a lobe: it is added where a camera path hits an emitter.

Conventions: ``wo`` points away from the surface towards the previous vertex,
``wi`` away from the surface towards the next one.  ``ng``/``ns`` are the raw
geometric/shading normals; :func:`face_forward` flips them to the side of a
direction.  Throughput weights returned by :func:`scatter` are f |cos| / pdf
divided by the lobe-choice probability.

The glossy lobe may carry Cycles' multiscatter GGX energy compensation
(:meth:`MaterialTable.multiscatter`): a factor of the *view* direction, which makes the
BSDF non-reciprocal, as in Cycles.  The view is ``wo`` for camera paths and measurement
points, and the sampled ``wi`` for photons (the direction towards the camera side).

``mode="importance"`` (photons) applies the adjoint shading-normal correction
(Veach 1997, 5.3).  Refraction follows Cycles' convention, which does not scale radiance by
1/eta^2 where it crosses into a medium (physically, radiance inside a medium of index n is n^2
that outside): camera paths (``mode="radiance"``) carry it unscaled, so what lies behind a
single-sided pane or inside water is seen as it is there, and photons, the adjoint, take the
scaling instead: 1/eta^2 of their flux going into the denser medium, eta^2 coming out (eta =
n_transmitted / n_incident).  Through closed glass the two cancel; where light and eye meet on
different sides of an interface (a pool's floor under the sun, seen from above) the product is
Cycles', which is there also the physical value.  With shading normals, photons leave the
Lambertian lobes (diffuse, translucent) cosine-distributed about the *geometric* normal with
weight |wo.N_s| / |wo.N_g|: Cycles' lobe, max(N_s.wo, 0) / pi for any view on the surface's
side, has that exact adjoint (sampling about N_s left the views between the two hemispheres
dark; ``test_a_screen_lit_from_behind_through_its_translucent_bsdf_matches_cycles[bumped]``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from . import sampling as smp
from . import thin_film
from .sampling import dot

DIFFUSE, GLOSSY, MIRROR, DIELECTRIC, TRANSLUCENT, SHEEN = 0, 1, 2, 3, 4, 5
REFLECTING = (DIFFUSE, GLOSSY)          # the non-delta lobes that reflect
DELTA = (MIRROR, DIELECTRIC)
# Glossy lobes with a smaller Blender roughness act as a perfect mirror.
MIRROR_ROUGHNESS = 0.02
MIN_ALPHA = 1e-4
# Where an anisotropic glossy lobe's tangent comes from (``Materials.glossy_tangent``, Blender's
# Tangent node): around the object's X, Y or Z axis through the centre of its texture space
# (radial, from the Generated coordinates; Z is Cycles' default), or the UV map's tangents.
TANGENT_RADIAL_X, TANGENT_RADIAL_Y, TANGENT_RADIAL_Z, TANGENT_UV = 0, 1, 2, 3
# Microfacet distributions of a glossy or glass lobe (Materials.glossy_distribution,
# dielectric_distribution): Blender's GGX and Multiscatter GGX, or Beckmann.
DISTRIBUTION_GGX, DISTRIBUTION_BECKMANN = 0, 1
# Single-scattering GGX albedo E(mu) is tabulated per material at mu = (k / MS_NODES)^2: finer
# towards grazing, where E changes fastest.
MS_NODES = 32
# A roughness map (Materials.roughness_program) picks, at each hit, one of this many copies of its
# material with roughness k / (ROUGHNESS_LEVELS - 1): steps of 1/64, at most 0.008 off.  Each copy
# costs its tables (about 10 ms each for the albedo and the layer, ``COARSE_STRATA``).
ROUGHNESS_LEVELS = 65
# An anisotropy map (Materials.stretch_program) picks, at each hit, one of this many copies of its
# material with stretch s = 100^((2k - (STRETCH_LEVELS - 1)) / (STRETCH_LEVELS - 1)): even in log s
# over [0.01, 100], s = 1 a level, steps of a factor 1.075 (at most 3.7 % off).  The copies share
# their tables (they depend on sqrt(ax ay), the same unless the stretch saturates an alpha).
STRETCH_LEVELS = 129
STRETCH_RANGE = 100.0
# Strata of the GGX albedo quadrature (sampling.ggx_albedo) per table: exact, and for those copies.
EXACT_STRATA, COARSE_STRATA = 64, 32
# Diffuse roughness below this is Lambert, as in Cycles (``diffuse_roughness_is_almost_zero``).
ROUGH_DIFFUSE_MIN = 1e-5
# A thin film's curve (MaterialTable.film_curve) is tabulated at microfacet cosines c = (k / FILM_NODES)^2.
FILM_NODES = 256


def roughness_variants(mats):
    """(materials, first) for materials ``mats`` (``scene.Materials``) whose glossy roughness, or
    glass roughness (``dielectric_roughness`` -1), may come from a program: the materials
    followed by ``ROUGHNESS_LEVELS`` copies of each such one, copy k with roughness
    k / (ROUGHNESS_LEVELS - 1) (the glass's too where it follows the program) and no program, and
    ``first`` (M,) int32 the index of a material's first copy (-1: none).  The copies get every
    per-material table of the core (multiscatter, layer, a mirror below 0.02) as any material; a
    hit picks its copy (``RenderContext.surface``).  Without roughness programs (or glossy or
    such glass lobes): ``mats`` itself."""
    program = mats.roughness_program
    first = np.full(mats.count, -1, np.int32)
    follows = (mats.dielectric_roughness < 0) & (mats.dielectric_weight > 0)
    mapped = (np.flatnonzero((program >= 0) & ((mats.glossy_weight > 0) | follows) & ~_picks_level(mats))
              if program is not None else np.zeros(0, np.int64))
    if len(mapped) == 0:
        return mats, first
    first[mapped] = mats.count + ROUGHNESS_LEVELS * np.arange(len(mapped))
    rows = np.concatenate([np.arange(mats.count), np.repeat(mapped, ROUGHNESS_LEVELS)])
    changes = {name: np.ascontiguousarray(getattr(mats, name)[rows]) for name in mats.ARRAY_FIELDS}
    levels = np.linspace(0.0, 1.0, ROUGHNESS_LEVELS, dtype=np.float32)
    changes["glossy_roughness"][mats.count:] = np.tile(levels, len(mapped))
    glass = changes["dielectric_roughness"]
    glass[mats.count:] = np.where(glass[mats.count:] < 0, np.tile(levels, len(mapped)), glass[mats.count:])
    changes["roughness_program"][mats.count:] = -1
    # (a program on a material without such lobes changes nothing: dropped, so that no hit picks
    # copies it has not got)
    changes["roughness_program"][np.flatnonzero((program >= 0) & (first < 0) & ~_picks_level(mats))] = -1
    changes["stretch_program"][mats.count:] = -1          # such a material keeps its stretch
    names = list(mats.names) + [f"{mats.names[m]} (roughness {r:.3f})" for m in mapped for r in levels]
    return dataclasses.replace(mats, names=names, **changes), first


def _picks_level(mats):
    """(M,) bool: the material picks one of its levels at each hit (``Materials.level_program``), so
    it is never shaded itself and needs no copies."""
    return np.zeros(mats.count, bool) if mats.level_program is None else mats.level_program >= 0


def stretch_levels():
    """(STRETCH_LEVELS,) float64 the stretches of an anisotropy map's copies (``stretch_variants``)."""
    return STRETCH_RANGE ** np.linspace(-1.0, 1.0, STRETCH_LEVELS)


def stretch_level(stretch):
    """Index of the copy (``stretch_variants``) nearest in log s to each of ``stretch`` (NaN: s = 1)."""
    s = np.clip(np.nan_to_num(np.asarray(stretch, np.float64), nan=1.0, posinf=STRETCH_RANGE, neginf=1.0),
                1.0 / STRETCH_RANGE, STRETCH_RANGE)
    half = (STRETCH_LEVELS - 1) / 2
    return np.rint((np.log(s) / np.log(STRETCH_RANGE) + 1.0) * half).astype(np.int32)


def stretch_variants(mats):
    """(materials, first) for materials ``mats`` (``scene.Materials``) whose glossy stretch may
    come from a program (an anisotropy map): the materials followed by ``STRETCH_LEVELS`` copies
    of each such one, copy k with stretch ``stretch_levels()[k]`` and no program, and ``first``
    (M,) int32 the index of a material's first copy (-1: none); a hit picks its copy
    (``RenderContext.surface``).  A material that also has a roughness map keeps its constant
    stretch (its copies would multiply).  Without anisotropy maps: ``mats`` itself."""
    program = mats.stretch_program
    first = np.full(mats.count, -1, np.int32)
    if program is None:
        return mats, first
    rough = mats.roughness_program if mats.roughness_program is not None else np.full(mats.count, -1)
    mapped = np.flatnonzero((program >= 0) & (mats.glossy_weight > 0) & (rough < 0) & ~_picks_level(mats))
    if len(mapped) == 0:
        return mats, first
    first[mapped] = mats.count + STRETCH_LEVELS * np.arange(len(mapped))
    rows = np.concatenate([np.arange(mats.count), np.repeat(mapped, STRETCH_LEVELS)])
    changes = {name: np.ascontiguousarray(getattr(mats, name)[rows]) for name in mats.ARRAY_FIELDS}
    levels = stretch_levels()
    changes["glossy_stretch"][mats.count:] = np.tile(levels, len(mapped))
    changes["stretch_program"][mats.count:] = -1
    names = list(mats.names) + [f"{mats.names[m]} (stretch {s:.3g})" for m in mapped for s in levels]
    return dataclasses.replace(mats, names=names, **changes), first


def coat_variants(mats):
    """(materials, coat_row) for materials ``mats`` (``scene.Materials``) some of which have a
    coat: the materials followed by one coat material per distinct (weight, roughness, IOR), and
    ``coat_row`` int32 the coat material of each of them (-1: none, and for the coat materials).
    A coat material is the coat alone: a glossy lobe of weight ``coat_weight`` that reflects
    F0 + (1 - F0) s(c) = F(c) (``glossy_fresnel_ior`` the coat's IOR) with multiscatter F_ss the
    mean Fresnel (Cycles' ``bsdf_microfacet_setup_fresnel_dielectric``), without normal or bump
    maps.  A sheen lies over the coat (Cycles' Principled): a coated material's sheen moves to its
    coat material, which the sheen's factor (``sheen_cover``) dims as the material keeps dimming
    what lies under the coat.  Without coats: ``mats`` itself."""
    weight = np.asarray(mats.coat_weight, np.float64)
    coat_row = np.full(mats.count, -1, np.int32)
    coated = np.flatnonzero(weight > 0)
    if len(coated) == 0:
        return mats, coat_row
    keys = np.column_stack([weight[coated], mats.coat_roughness[coated], mats.coat_ior[coated],
                            mats.sheen_color[coated], mats.sheen_roughness[coated], mats.sheen_cover[coated]])
    unique, which = np.unique(keys, axis=0, return_inverse=True)
    coat_row[coated] = mats.count + which.ravel()
    k = len(unique)
    rows = np.concatenate([np.arange(mats.count), np.zeros(k, np.int64)])
    changes = {name: np.ascontiguousarray(getattr(mats, name)[rows]) for name in mats.ARRAY_FIELDS}
    new = slice(mats.count, None)
    for name in mats.ARRAY_FIELDS:
        if name in mats.INDEX_FIELDS or name == "glossy_metal_tint":
            changes[name][new] = -1
        elif name not in ("ior", "glossy_roughness"):
            changes[name][new] = 0.0
    ior = np.maximum(unique[:, 2], 1.0)
    f0 = smp.dielectric_f0(ior)
    changes["glossy_weight"][new] = unique[:, 0]
    changes["glossy_roughness"][new] = unique[:, 1]
    changes["glossy_color"][new] = f0[:, None]
    changes["glossy_fresnel_ior"][new] = ior
    changes["glossy_fresnel_rise"][new] = 1.0 - f0[:, None]
    changes["glossy_multiscatter"][new] = np.array([smp.mean_fresnel(x) for x in ior])[:, None]
    # (the sheen moves to the coat; the material keeps its cover, which dims what lies under the coat)
    changes["sheen_color"][new] = unique[:, 3:6]
    changes["sheen_color"][coated] = 0.0
    changes["sheen_roughness"][new] = unique[:, 6]
    changes["sheen_cover"][new] = unique[:, 7]
    for name in ("opacity", "normal_strength", "bump_strength", "bump_distance", "outer_bump_strength",
                 "outer_bump_distance", "coat_bump_strength", "coat_bump_distance", "diffuse_layer_weight",
                 "glossy_stretch", "glossy_metal_share", "bump_correction", "dielectric_fresnel"):
        changes[name][new] = 1.0
    names = list(mats.names) + [f"coat {w:.3f}, roughness {r:.3f}, IOR {x:.3f}" for w, r, x in unique[:, :3]]
    return (dataclasses.replace(mats, names=names, **changes),
            np.concatenate([coat_row, np.full(k, -1, np.int32)]))


@dataclass
class MaterialTable:
    """Per-material arrays ready for shading (mirror-like glossy merged into mirror)."""

    weight: np.ndarray          # (M, L) float64 lobe weights, lobe order as above (L = lobes)
    color: np.ndarray           # (M, L, 3) float64 lobe colours (diffuse colour is 1 if textured)
    alpha: np.ndarray           # (M,) float64 GGX alpha of the glossy lobe
    dielectric_alpha: np.ndarray  # (M,) float64 GGX alpha of the dielectric lobe, 0 = smooth
    reflection: np.ndarray        # (M, 3) float64 dielectric reflection colour (the lobe's colour: same)
    ior: np.ndarray             # (M,) float64
    emission: np.ndarray        # (M, 3) float64 radiance
    texture: np.ndarray         # (M,) int32 diffuse texture or -1
    has_nondelta: np.ndarray    # (M,) bool: photons deposit / camera paths may stop here
    has_glossy: np.ndarray      # (M,) bool: the non-delta part has a glossy lobe
    is_emissive: np.ndarray     # (M,) bool
    ms_albedo: np.ndarray       # (M, MS_NODES + 1) float64 single-scattering GGX albedo E (1: none)
    ms_fresnel: np.ndarray      # (M, 3) float64 multiple-scattering Fresnel F_ms (0: single scattering)
    ms_e_avg: np.ndarray        # (M,) float64 E_avg of the compensated lobes (0: single scattering)
    fresnel_ior: np.ndarray     # (M,) float64 IOR of the glossy (or merged mirror) lobe's Fresnel rise
    rise: np.ndarray            # (M, L, 3) float64 colour added times s(c) (glossy or mirror entry)
    edge: np.ndarray            # (M, L, 3) float64 metal colour added times (1 - c)^5 (glossy or mirror)
    dip: np.ndarray             # (M, L, 3) float64 metal colour taken away times c (1 - c)^6
    layer: np.ndarray           # (M, MS_NODES + 1) float64 diffuse weight factor at the view cosine
    score_extra: np.ndarray     # (M, L) float64 lobe-score terms of the rise and the layer (mean)
    normal_mapped: np.ndarray = None  # (M,) bool: a normal or bump map (image or program) bends the normal
    #                                   (or the coat's: Materials.coat_normal_program, coat_bump_program)
    program: np.ndarray = None        # (M,) int32 procedural diffuse colour (Materials.programs) or -1
    glossy_program: np.ndarray = None  # (M,) int32 procedural glossy colour or -1 ...
    glossy_program_lobe: np.ndarray = None  # (M,) int64 ... of this lobe (MIRROR where a sharp glossy merged)
    emission_program: np.ndarray = None     # (M,) int32 procedural factor of ``emission`` or -1
    dielectric_program: np.ndarray = None   # (M,) int32 procedural transmitted colour of the glass or -1
    translucent_program: np.ndarray = None  # (M,) int32 procedural translucent colour or -1
    rotation_program: np.ndarray = None     # (M,) int32 float program of an anisotropic lobe's turn or -1
    coat_row: np.ndarray = None             # (M,) int32 the coat's material (coat_variants) or -1
    bump_correction: np.ndarray = None      # (M,) bool: Bump Map Correction on (Materials.bump_correction)
    dielectric_fresnel: np.ndarray = None   # (M,) float64 share of the glass that reflects by Fresnel (the
    #                                         rest refracts whatever it: Refraction BSDF); None: 1
    coat_factor: np.ndarray = None          # (M, MS_NODES + 1, 3) float64 factor under the coat at mu
    coat_layer: np.ndarray = None           # (M, MS_NODES + 1) float64 the coat's albedo's part of it
    coat_score: np.ndarray = None           # (M, 2) float64 mean lobe-score totals: coat, factor under it
    glossy_through: np.ndarray = None       # (M,) bool: camera paths go on through the glossy lobe
    rough_diffuse: np.ndarray = None        # (M, 4) float64 a, b, Eavg / (1 - Eavg), 1 - Eavg of a rough
    #                                         diffuse lobe (rough_diffuse_factor); Lambert: 1 / pi, 0, 0, 0
    anisotropic: np.ndarray = None          # (M,) bool: the glossy lobe's alphas differ along a tangent
    alpha_x: np.ndarray = None              # (M,) float64 its alpha along the tangent (``alpha`` where
    alpha_y: np.ndarray = None              # isotropic) and across it; ``alpha`` is then sqrt(ax ay)
    glass_ms_albedo: np.ndarray = None      # (M, 2, MS_NODES + 1) float64 rough glass albedo E seen from
    #                                         outside and inside (1: none; Materials.dielectric_multiscatter)
    glass_ms_fresnel: np.ndarray = None     # (M, 2, 3) float64 its F_ms from either side (0: single
    #                                         scattering)
    rotation: np.ndarray = None             # (M,) float64 the tangent's turn about the normal (turns)
    tangent_axis: np.ndarray = None         # (M,) int32 Materials.glossy_tangent
    hit_metal: np.ndarray = None            # (M,) bool: the metal's curve follows the lobe's colour at each
    #                                         hit (Materials.glossy_metal_tint), in lobe ``hit_metal_lobe``
    hit_metal_lobe: np.ndarray = None       # (M,) int64 GLOSSY, or MIRROR where a sharp glossy merged
    hit_metal_dip: np.ndarray = None        # (M, 3) float64 the dip per unit Schlick value at 1/7 (below)
    hit_metal_share: np.ndarray = None      # (M,) float64 the metal's share k of such a lobe (1: all of it)
    hit_metal_rest: np.ndarray = None       # (M, 3) float64 the rest's colour (the lobe's: k F0 + rest)
    film_index: np.ndarray = None           # (M,) int64 the row of a filmed layer's curve (film_curve) or -1
    film_curve: np.ndarray = None           # (F, FILM_NODES + 1, 3) float64 its rise (Materials.film_*)
    glass_film: np.ndarray = None           # (M,) bool: the glass has a film (glass_film_reflectance)
    film_thickness: np.ndarray = None       # (M,) float64 Materials.film_thickness, film_ior, film_tint
    film_ior: np.ndarray = None
    film_tint: np.ndarray = None
    film_sensitivity: np.ndarray = None     # (thin_film.TABLE_SIZE, 3) complex where some glass has a film
    metal_film_index: np.ndarray = None     # (M,) int64 the row of a filmed metal's curve or -1
    metal_film_lobe: np.ndarray = None      # (M,) int64 its lobe (GLOSSY, or MIRROR where merged)
    metal_film_curve: np.ndarray = None     # (F, FILM_NODES + 1, 3) k (G_m(c) - F0): what the metal adds
    glossy_beckmann: np.ndarray = None      # (M,) bool: the glossy lobe's microfacets are Beckmann's (no
    #                                         multiscatter); None: all GGX
    dielectric_beckmann: np.ndarray = None  # (M,) bool: so are the rough glass's; None: all GGX
    sheen_roughness: np.ndarray = None      # (M,) float64 the sheen's roughness (None: no sheen in the scene)
    sheen_cover: np.ndarray = None          # (M,) float64 k of the rest's factor 1 - k E(mu) (sheen_dim)

    @staticmethod
    def from_materials(mats, coarse=None, coat_row=None, through_roughness=0.0) -> "MaterialTable":
        """The table of materials ``mats``; ``coarse`` (M,) bool marks rows whose GGX albedo
        tables may use the coarser quadrature ``COARSE_STRATA`` (the copies of a roughness map:
        1e-3 of the exact albedo, 7 times faster); ``coat_row`` is :func:`coat_variants`'s.
        Camera paths go on through glossy lobes (coats' included) of a roughness below
        ``through_roughness`` that have no diffuse lobe beside them (``glossy_through``) instead
        of ending there; so no measurement point holds such a material."""
        m = mats.count
        coarse = np.zeros(m, bool) if coarse is None else np.asarray(coarse, bool)
        translucent = _or_zeros(mats.translucent_weight, m)
        translucent_color = _or_zeros(mats.translucent_color, (m, 3))
        translucent_on = (translucent > 0) & (smp.luminance(translucent_color) > 0)
        sheen_color = np.maximum(_or_zeros(mats.sheen_color, (m, 3)), 0.0)
        sheen_cover = np.maximum(_or_zeros(mats.sheen_cover, m), 0.0)
        sheen_on = smp.luminance(sheen_color) > 0
        lobes = 6 if (sheen_on | (sheen_cover > 0)).any() else 5 if translucent_on.any() else 4
        weight = np.zeros((m, lobes))
        color = np.zeros((m, lobes, 3))
        if lobes >= 5:
            weight[:, TRANSLUCENT] = np.where(translucent_on, translucent, 0.0)
            color[:, TRANSLUCENT] = translucent_color
        if lobes == 6:
            weight[:, SHEEN] = sheen_on
            color[:, SHEEN] = sheen_color
        weight[:, DIFFUSE] = mats.diffuse_weight
        color[:, DIFFUSE] = mats.diffuse_color
        program = (np.asarray(mats.diffuse_program, np.int32) if mats.diffuse_program is not None
                   else np.full(m, -1, np.int32))
        textured = (mats.diffuse_texture >= 0) | (program >= 0)
        glossy_program = (np.asarray(mats.glossy_program, np.int32) if mats.glossy_program is not None
                          else np.full(m, -1, np.int32))
        emission_program = (np.asarray(mats.emission_program, np.int32) if mats.emission_program is not None
                            else np.full(m, -1, np.int32))
        weight[:, GLOSSY] = mats.glossy_weight
        color[:, GLOSSY] = mats.glossy_color
        weight[:, MIRROR] = mats.mirror_weight
        color[:, MIRROR] = mats.mirror_color
        weight[:, DIELECTRIC] = mats.dielectric_weight
        color[:, DIELECTRIC] = mats.dielectric_color
        fresnel_ior = mats.glossy_fresnel_ior.astype(np.float64)
        rise = np.zeros((m, lobes, 3))
        rise[:, GLOSSY] = np.where((fresnel_ior > 0)[:, None], mats.glossy_fresnel_rise, 0.0)
        edge = np.zeros((m, lobes, 3))
        dip = np.zeros((m, lobes, 3))
        edge[:, GLOSSY] = mats.glossy_metal_rise
        dip[:, GLOSSY] = mats.glossy_metal_dip
        # Merge near-specular glossy lobes into the mirror lobe (weighted colour).
        sharp = (mats.glossy_roughness < MIRROR_ROUGHNESS) & (weight[:, GLOSSY] > 0)
        if sharp.any():
            wm, wg = weight[sharp, MIRROR], weight[sharp, GLOSSY]
            color[sharp, MIRROR] = (wm[:, None] * color[sharp, MIRROR]
                                    + wg[:, None] * color[sharp, GLOSSY]) / (wm + wg)[:, None]
            for curve in (rise, edge, dip):
                curve[sharp, MIRROR] = wg[:, None] * curve[sharp, GLOSSY] / (wm + wg)[:, None]
                curve[sharp, GLOSSY] = 0.0
            weight[sharp, MIRROR] = wm + wg
            weight[sharp, GLOSSY] = 0.0
        alpha = np.maximum(mats.glossy_roughness.astype(np.float64) ** 2, MIN_ALPHA)
        lum = smp.luminance(color)
        diffuse_on = (weight[:, DIFFUSE] > 0) & (textured | (lum[:, DIFFUSE] > 0))
        glossy_on = (weight[:, GLOSSY] > 0) & ((lum[:, GLOSSY] > 0) | (smp.luminance(rise[:, GLOSSY]) > 0)
                                               | (smp.luminance(edge[:, GLOSSY]) > 0))
        # Anisotropy: alpha times and over the stretch along and across the tangent, each in
        # [MIN_ALPHA, 1] (Cycles saturates them); the albedo tables take sqrt(ax ay) (Cycles).
        stretch = np.ones(m) if mats.glossy_stretch is None else np.asarray(mats.glossy_stretch, np.float64)
        anisotropic = glossy_on & (np.abs(stretch - 1.0) > 1e-6)
        alpha_x = np.where(anisotropic, np.clip(alpha * stretch, MIN_ALPHA, 1.0), alpha)
        alpha_y = np.where(anisotropic, np.clip(alpha / stretch, MIN_ALPHA, 1.0), alpha)
        alpha = np.where(anisotropic, np.sqrt(alpha_x * alpha_y), alpha)
        emission = mats.emission.astype(np.float64)
        # One quadrature per (alpha, IOR) of a Fresnel rise gives its mean S and the albedo E, which
        # the multiscatter tables then reuse.
        albedo = {}
        rise_means = _rise_means(alpha, fresnel_ior, rise, coarse, albedo)
        # Beckmann lobes (Materials.glossy_distribution) scatter once: Cycles has no compensation.
        glossy_beckmann = _beckmann(mats.glossy_distribution, m) & (weight[:, GLOSSY] > 0)
        dielectric_beckmann = _beckmann(mats.dielectric_distribution, m) & (weight[:, DIELECTRIC] > 0)
        ms_albedo, ms_fresnel, ms_e_avg = _multiscatter_tables(alpha, glossy_on & ~glossy_beckmann,
                                                               mats.glossy_multiscatter, coarse, albedo)
        dielectric_program = (np.asarray(mats.dielectric_program, np.int32)
                              if mats.dielectric_program is not None else np.full(m, -1, np.int32))
        # A glass reflects its reflection colour where it transmits at all, or with a program (which
        # varies the transmitted colour only) always.
        glass = color[:, DIELECTRIC]
        reflection = np.where(((glass > 0) | (dielectric_program >= 0)[:, None]),
                              mats.dielectric_reflection_color.astype(np.float64), 0.0)
        rough = mats.dielectric_roughness.astype(np.float64)
        dielectric_alpha = np.where(rough < MIRROR_ROUGHNESS, 0.0, rough * rough)
        layered = (fresnel_ior > 0) & diffuse_on
        film = _film_tables(mats, fresnel_ior, rise)
        layer, score_extra = _layer_tables(alpha, fresnel_ior, rise, layered, mats.diffuse_layer,
                                           np.clip(mats.diffuse_layer_weight, 0.0, 1.0),
                                           ms_albedo, ms_fresnel, weight, rise_means, film)
        for lobe in (GLOSSY, MIRROR):
            mean = _metal_mean_rise(color[:, lobe], edge[:, lobe], dip[:, lobe])
            score_extra[:, lobe] += weight[:, lobe] * smp.luminance(mean)
        coat_row = np.full(m, -1, np.int32) if coat_row is None else np.asarray(coat_row, np.int32)
        has_nondelta = diffuse_on | glossy_on | translucent_on | sheen_on
        tint = _or_none(mats.glossy_metal_tint, (m, 3)).astype(np.float64)
        hit_metal = (tint >= 0).all(axis=1) & ((weight[:, GLOSSY] > 0) | (weight[:, MIRROR] > 0))
        coat_factor, coat_layer, coat_score = _coat_tables(mats, coat_row, alpha, fresnel_ior, rise_means,
                                                           ms_albedo, ms_fresnel)
        coated = np.flatnonzero(coat_row >= 0)
        has_nondelta[coated] |= has_nondelta[coat_row[coated]]
        return MaterialTable(weight=weight, color=color, alpha=alpha, dielectric_alpha=dielectric_alpha,
                             reflection=reflection,
                             ior=mats.ior.astype(np.float64), emission=emission,
                             texture=mats.diffuse_texture.astype(np.int32),
                             has_nondelta=has_nondelta, has_glossy=glossy_on,
                             is_emissive=(emission > 0).any(axis=1),
                             ms_albedo=ms_albedo, ms_fresnel=ms_fresnel, ms_e_avg=ms_e_avg,
                             fresnel_ior=fresnel_ior,
                             rise=rise, edge=edge, dip=dip, layer=layer, score_extra=score_extra,
                             normal_mapped=(np.asarray(mats.normal_texture) >= 0)
                             | (np.asarray(mats.bump_texture) >= 0)
                             | (np.asarray(_or_none(mats.bump_program, m)) >= 0)
                             | (np.asarray(_or_none(mats.outer_bump_program, m)) >= 0)
                             | (np.asarray(_or_none(mats.coat_normal_program, m)) >= 0)
                             | (np.asarray(_or_none(mats.coat_bump_program, m)) >= 0)
                             | (np.asarray(_or_none(mats.normal_program, m)) >= 0), program=program,
                             glossy_program=glossy_program,
                             glossy_program_lobe=np.where(weight[:, GLOSSY] > 0, GLOSSY, MIRROR),
                             emission_program=emission_program, dielectric_program=dielectric_program,
                             translucent_program=np.asarray(_or_none(mats.translucent_program, m), np.int32),
                             rotation_program=np.where(anisotropic, _or_none(mats.rotation_program, m),
                                                       -1).astype(np.int32),
                             coat_row=coat_row, coat_factor=coat_factor, coat_layer=coat_layer,
                             coat_score=coat_score,
                             bump_correction=(np.ones(m, bool) if mats.bump_correction is None
                                              else np.asarray(mats.bump_correction) != 0),
                             dielectric_fresnel=(None if mats.dielectric_fresnel is None
                                                 or (mats.dielectric_fresnel >= 1).all()
                                                 else np.asarray(mats.dielectric_fresnel, np.float64)),
                             glossy_through=glossy_on & ~diffuse_on & ~sheen_on
                             & (mats.glossy_roughness < through_roughness),
                             rough_diffuse=_rough_diffuse_table(_or_zeros(mats.diffuse_roughness, m)),
                             anisotropic=anisotropic, alpha_x=alpha_x, alpha_y=alpha_y,
                             rotation=_or_zeros(mats.glossy_rotation, m),
                             tangent_axis=(np.full(m, TANGENT_RADIAL_Z, np.int32)
                                           if mats.glossy_tangent is None
                                           else np.asarray(mats.glossy_tangent, np.int32)),
                             hit_metal=hit_metal,
                             hit_metal_lobe=np.where(weight[:, GLOSSY] > 0, GLOSSY, MIRROR),
                             hit_metal_dip=np.where(hit_metal[:, None],
                                                    F82_DIP * (1.0 - np.clip(tint, 0.0, 1.0)), 0.0),
                             hit_metal_share=np.where(hit_metal, np.clip(_or_ones(mats.glossy_metal_share, m),
                                                                         1e-6, 1.0), 1.0),
                             hit_metal_rest=np.where(hit_metal[:, None],
                                                     _or_zeros(mats.glossy_metal_rest, (m, 3)), 0.0),
                             film_index=film.index, film_curve=film.curve,
                             **_glass_film(mats, weight, film),
                             **_metal_film(mats, weight, edge, dip, sharp, film),
                             glossy_beckmann=glossy_beckmann if glossy_beckmann.any() else None,
                             dielectric_beckmann=(dielectric_beckmann if (dielectric_beckmann
                                                                          & (dielectric_alpha > 0)).any()
                                                  else None),
                             **_glass_multiscatter_tables(
                                 mats, weight, np.where(dielectric_beckmann, 0.0, dielectric_alpha), coarse),
                             **_sheen_tables(mats, lobes, sheen_on, sheen_cover, score_extra))

    @property
    def has_glass_multiscatter(self) -> bool:
        return self.glass_ms_albedo is not None

    def glass_multiscatter(self, mat_ids, mu, inside):
        """(n, 3) factors 1 + F_ms (1 - E(mu)) / E(mu) of rough glasses seen at camera-side cosines
        ``mu`` (n,) from ``inside`` (n,) bool or outside: Cycles' energy compensation of its
        Multiscatter GGX glass (``microfacet_ggx_preserve_energy``: the albedo E of the glass's
        single scattering from that side, its relative IOR inverted inside, and F_ms of F_ss its
        transmission tint), 1 for materials without it."""
        rows = np.asarray(mat_ids, np.int64) * 2 + np.asarray(inside, np.int64)
        e = _interpolate(self.glass_ms_albedo.reshape(-1, MS_NODES + 1), rows, mu)
        fms = self.glass_ms_fresnel.reshape(-1, 3).take(rows, axis=0)
        return 1.0 + fms * ((1.0 - e) / np.maximum(e, 1e-6))[:, None]

    @property
    def lobes(self) -> int:
        """Columns of the lobe arrays: 6 with a sheen in the scene, else 5 with a translucent lobe
        in the scene, else 4."""
        return self.weight.shape[1]

    @property
    def has_sheen(self) -> bool:
        return self.lobes > SHEEN

    @property
    def point_lobes(self) -> list:
        """The lobes whose colours a measurement point keeps (``MeasurementPoints.colors``)."""
        return [DIFFUSE, GLOSSY, TRANSLUCENT, SHEEN][:self.lobes - 2]

    def sheen_lobe(self, mat_ids, mu):
        """(E, a, b), each (n,): the sheens of materials ``mat_ids`` seen at view cosines ``mu``:
        their directional albedo and the LTC's coefficients (:func:`sheen_albedo`)."""
        return sheen_albedo(mu, self.sheen_roughness.take(mat_ids))

    def sheen_dim(self, mat_ids, mu):
        """(n,) the factor of everything under the sheens of materials ``mat_ids`` (all lobes but the
        sheen, the coat, the emission) at view cosines ``mu`` (their absolute values: Cycles' normal
        faces the view): 1 - k E(mu), clamped to [0, 1] (Cycles' ``closure_layering_weight`` of the
        Principled's sheen, k the largest channel of its weight times tint); 1 without a sheen."""
        k = self.sheen_cover.take(mat_ids)
        e, _, _ = sheen_albedo(np.abs(mu), self.sheen_roughness.take(mat_ids))
        return np.clip(1.0 - k * e, 0.0, 1.0)

    @cached_property
    def has_translucent(self) -> bool:
        """Whether some material has a translucent lobe (its column exists in scenes with a sheen)."""
        return self.lobes > TRANSLUCENT and bool((self.weight[:, TRANSLUCENT] > 0).any())

    @cached_property
    def is_rough_diffuse(self) -> np.ndarray:
        """(M,) bool: the diffuse lobe is rough (Oren-Nayar, :func:`rough_diffuse_factor`)."""
        if self.rough_diffuse is None:
            return np.zeros(len(self.weight), bool)
        return (self.rough_diffuse[:, 1] > 0) & (self.weight[:, DIFFUSE] > 0)

    @cached_property
    def has_rough_diffuse(self) -> bool:
        return bool(self.is_rough_diffuse.any())

    @cached_property
    def translucent(self) -> np.ndarray:
        """(M,) bool: the material transmits diffusely (a translucent lobe)."""
        if not self.has_translucent:
            return np.zeros(len(self.weight), bool)
        return self.weight[:, TRANSLUCENT] > 0

    @cached_property
    def has_anisotropy(self) -> bool:
        """Whether some glossy lobe is anisotropic (its points need a tangent)."""
        return self.anisotropic is not None and bool(self.anisotropic.any())

    @property
    def has_normal_maps(self) -> bool:
        return self.normal_mapped is not None and bool(self.normal_mapped.any())

    @property
    def has_rough_dielectric(self) -> bool:
        return bool(((self.dielectric_alpha > 0) & (self.weight[:, DIELECTRIC] > 0)).any())

    def multiscatter(self, mat_ids, mu, base=None):
        """(n, 3) factors 1 + F_ms (1 - E(mu)) / E(mu) of the glossy lobes at view cosines ``mu``.

        This is Cycles' energy compensation of multiscatter GGX (``microfacet_ggx_preserve_energy``,
        after Kulla and Conty 2017): the single-scattering lobe scaled by a factor of the *view*
        direction, so that a white lobe reflects all the light it receives from any direction.
        The view is the camera side: a measurement point's ``wo``, or the direction a photon
        leaves in.  Rows of materials without compensation get 1.  ``base`` (n, 3), the glossy
        colours at the hits, gives the metals whose curve follows it (``hit_metal``) F_ss, the mean
        of that curve (:func:`metal_fresnel`), hit by hit; needed where the table has them.
        """
        e = _interpolate(self.ms_albedo, mat_ids, mu)
        fms = self.ms_fresnel.take(mat_ids, axis=0)
        if self.has_hit_metal:
            h = np.flatnonzero(self.hit_metal.take(mat_ids) & (self.ms_e_avg.take(mat_ids) > 0))
            if len(h):
                if base is None:
                    raise ValueError("multiscatter: metals with a per-hit curve need the hits' colours")
                m = mat_ids.take(h)
                f0, dip = self.hit_metal_f0_dip(m, np.asarray(base).take(h, axis=0))
                fss = np.clip(f82_mean(f0, dip), 0.0, 1.0)
                if self.has_partial_metal:
                    # Beside the rest (share 1 - k, its own F_ss in ms_fss): the two F_ss weighted by
                    # the parts' mean reflectances, k F_ss and (1 - k) F_ss_rest.
                    k = self.hit_metal_share.take(m)[:, None]
                    f_rest = self.ms_fss.take(m, axis=0)
                    rest = (1.0 - k) * f_rest
                    total = k * fss + rest
                    fss = np.divide(k * fss * fss + rest * f_rest, total, out=np.zeros_like(total),
                                    where=total > 0)
                e_avg = self.ms_e_avg.take(m)[:, None]
                fms[h] = _multiple_scattering_fresnel(fss, e_avg)
        return 1.0 + fms * ((1.0 - e) / e)[:, None]

    @cached_property
    def reflection_differs(self) -> bool:
        """Whether some glass reflects another colour than it transmits (or may, by a program)."""
        return bool((self.dielectric_program >= 0).any()
                    or (self.reflection != self.color[:, DIELECTRIC]).any())

    @cached_property
    def rises(self) -> np.ndarray:
        """(M, 4) bool: the lobe's colour changes with the microfacet cosine (:meth:`fresnel_color`)."""
        out = (self.rise != 0).any(axis=2) | (self.edge != 0).any(axis=2) | (self.dip != 0).any(axis=2)
        if self.has_hit_metal:
            rows = np.flatnonzero(self.hit_metal)
            out[rows, self.hit_metal_lobe.take(rows)] = True
        return out

    @cached_property
    def has_hit_metal(self) -> bool:
        """Whether some metal's curve follows its colour at each hit (a textured metal)."""
        return self.hit_metal is not None and bool(self.hit_metal.any())

    @cached_property
    def has_partial_metal(self) -> bool:
        """Whether some such metal is only part of its lobe (``hit_metal_share`` < 1)."""
        return self.has_hit_metal and bool((self.hit_metal_share < 1.0).any())

    @cached_property
    def ms_fss(self) -> np.ndarray:
        """(M, 3) F_ss of each row from its F_ms and E_avg (0 where there is no compensation): for a
        partly metallic lobe, the rest's (``Materials.glossy_metal_share``)."""
        e = self.ms_e_avg[:, None]
        return np.divide(self.ms_fresnel, e + self.ms_fresnel * (1.0 - e), out=np.zeros_like(self.ms_fresnel),
                         where=e > 0)

    @cached_property
    def has_fresnel(self) -> bool:
        return bool(self.rises.any())

    @cached_property
    def has_metal_curve(self) -> bool:
        return self.has_row_metal_curve or self.has_hit_metal

    @cached_property
    def has_row_metal_curve(self) -> bool:
        """Whether some material has a metal curve of its own (``edge``, ``dip``)."""
        return bool((self.edge != 0).any() or (self.dip != 0).any())

    @cached_property
    def has_layer(self) -> bool:
        return bool((self.layer != 1).any())

    @cached_property
    def has_glossy_through(self) -> bool:
        return self.glossy_through is not None and bool(self.glossy_through.any())

    @cached_property
    def has_coat(self) -> bool:
        return self.coat_row is not None and bool((self.coat_row >= 0).any())

    def coat_attenuation(self, mat_ids, mu):
        """(n, 3) factors of everything under the coats of materials ``mat_ids`` (all coated) at
        view cosines ``mu`` (:class:`~core.scene.Materials`: the coat's albedo and its tint)."""
        return _interpolate(self.coat_factor, mat_ids, mu)

    def coat_layer_factor(self, mat_ids, mu):
        """(n,) the part of :meth:`coat_attenuation` that the coat's albedo takes (without its tint)."""
        return _interpolate(self.coat_layer, mat_ids, mu)

    def fresnel_color(self, mat_ids, lobe, cos_m, base=None):
        """(n, 3) the colour lobe ``lobe`` (GLOSSY or MIRROR) adds at microfacet cosines ``cos_m``
        (the view direction with the microfacet normal) to its constant colour: ``rise`` s(cos_m)
        (:func:`fresnel_rise`) plus a metal's ``edge`` (1 - c)^5 - ``dip`` c (1 - c)^6 (Cycles'
        F82 tint, ``Materials``), the metal's reflectance kept within [0, 1] as Cycles saturates it.
        ``base`` (n, 3), the lobe's colour at each hit, gives the curve of the metals whose F0 it is
        (``hit_metal``: edge 1 - F0, dip b(F0, tint)); needed where the table has them."""
        hit = None
        if self.has_hit_metal:
            hit = self.hit_metal.take(mat_ids) & (self.hit_metal_lobe.take(mat_ids) == lobe)
            if not hit.any():
                hit = None
            elif base is None:
                raise ValueError("fresnel_color: metals with a per-hit curve need the hits' colours")
        if hit is None:
            return self._row_fresnel_color(mat_ids, lobe, cos_m)
        if hit.all() and not self.has_partial_metal:
            return self._hit_metal_curve(mat_ids, cos_m, base)
        out = np.empty((len(mat_ids), 3))
        h, r = np.flatnonzero(hit), np.flatnonzero(~hit)
        mh, ch = mat_ids.take(h), cos_m.take(h)
        out[h] = self._hit_metal_curve(mh, ch, np.asarray(base).take(h, axis=0))
        if self.has_partial_metal:
            # The rest of a partly metallic lobe: its dielectric rise (Materials.glossy_metal_share).
            out[h] += self._row_fresnel_color(mh, lobe, ch)
        if len(r):
            out[r] = self._row_fresnel_color(mat_ids.take(r), lobe, cos_m.take(r))
        return out

    def hit_metal_f0_dip(self, mat_ids, base):
        """(F0, dip) (n, 3) of the metals ``mat_ids`` (``hit_metal``) whose F0 comes from the hits'
        colour ``base`` (n, 3), (base - rest) / k (k the metal's share of the lobe, rest the colour
        of the other part; F0 = base for a whole metal), clamped to [0, 1]: dip = b(F0, tint) of
        Cycles' F82 tint."""
        return self._f0_dip(mat_ids, self._hit_metal_raw_f0(mat_ids, base))

    def _f0_dip(self, mat_ids, raw):
        f0 = np.clip(raw, 0.0, 1.0)
        return f0, (f0 + (1.0 - f0) * F82_SCHLICK) * self.hit_metal_dip.take(mat_ids, axis=0)

    def _hit_metal_raw_f0(self, mat_ids, base):
        b = np.asarray(base, np.float64)
        if not self.has_partial_metal:
            return b
        return (b - self.hit_metal_rest.take(mat_ids, axis=0)) / self.hit_metal_share.take(mat_ids)[:, None]

    def _hit_metal_curve(self, mat_ids, cos_m, base):
        """(n, 3) what the metal part of lobes whose F0 follows the hits' colour ``base`` (n, 3)
        adds at microfacet cosines ``cos_m``: k times its curve less F0, the metal kept within [0, 1]."""
        b = self._hit_metal_raw_f0(mat_ids, base)
        f0, dip = self._f0_dip(mat_ids, b)
        c = np.clip(cos_m, 0.0, 1.0)
        p = 1.0 - c
        p5 = p * p
        p5 *= p5 * p
        curve = (1.0 - f0) * p5[:, None]
        curve -= dip * (c * p5 * p)[:, None]
        np.clip(curve, -b, np.maximum(1.0 - b, 0.0), out=curve)
        if self.has_partial_metal:
            curve *= self.hit_metal_share.take(mat_ids)[:, None]
        return curve

    def _row_fresnel_color(self, mat_ids, lobe, cos_m):
        """:meth:`fresnel_color` of the materials' own (per-row) curves; a metal under a film takes
        the film's curve (``metal_film_curve``) in place of its own."""
        out = self._row_curves(mat_ids, lobe, cos_m)
        if self.has_metal_film:
            row = self.metal_film_index.take(mat_ids)
            f = np.flatnonzero((row >= 0) & (self.metal_film_lobe.take(mat_ids) == lobe))
            if len(f):
                m, c = mat_ids.take(f), cos_m.take(f)
                rise = self._dielectric_part(m, lobe, c)
                out[f] = _interpolate(self.metal_film_curve, row.take(f), c, FILM_NODES) + (
                    0.0 if rise is None else rise)
        return out

    def _dielectric_part(self, mat_ids, lobe, cos_m):
        """(n, 3) what the lobe's dielectric rise adds (a film's where it has one), or None."""
        out = None
        if self.has_dielectric_rise:
            s = smp.fresnel_rise(cos_m, self.fresnel_ior.take(mat_ids))
            out = self.rise[:, lobe].take(mat_ids, axis=0) * s[:, None]
            if self.has_film:
                # A filmed layer: its curve's rise per channel (Materials.film_thickness).
                row = self.film_index.take(mat_ids)
                f = np.flatnonzero(row >= 0)
                if len(f):
                    out[f] = self.rise[:, lobe].take(mat_ids.take(f), axis=0) * _interpolate(
                        self.film_curve, row.take(f), cos_m.take(f), FILM_NODES)
        return out

    def _row_curves(self, mat_ids, lobe, cos_m):
        """The dielectric rise and the metal curve of :meth:`_row_fresnel_color`."""
        out = self._dielectric_part(mat_ids, lobe, cos_m)
        if not self.has_row_metal_curve:
            return out if out is not None else np.zeros((len(mat_ids), 3))
        edge, dip, low, high, metal = self._metal_rows[lobe]
        c = np.clip(cos_m, 0.0, 1.0)
        p = 1.0 - c
        p5 = p * p
        p5 *= p5 * p
        curve = edge.take(mat_ids, axis=0) * p5[:, None]
        curve -= dip.take(mat_ids, axis=0) * (c * p5 * p)[:, None]
        if out is None:                                 # metals alone (rows without a curve: 0)
            return np.clip(curve, low.take(mat_ids, axis=0), high.take(mat_ids, axis=0), out=curve)
        total = out + curve
        clipped = np.clip(total, low.take(mat_ids, axis=0), high.take(mat_ids, axis=0))
        return np.where(metal.take(mat_ids)[:, None], clipped, total)

    @cached_property
    def has_dielectric_rise(self) -> bool:
        return bool((self.rise != 0).any())

    @cached_property
    def has_film(self) -> bool:
        return ((self.film_index is not None and bool((self.film_index >= 0).any())) or self.has_glass_film
                or self.has_metal_film)

    @cached_property
    def has_metal_film(self) -> bool:
        return self.metal_film_index is not None and bool((self.metal_film_index >= 0).any())

    @cached_property
    def has_dielectric(self) -> bool:
        """Whether some material has a glass lobe."""
        return bool((self.weight[:, DIELECTRIC] > 0).any())

    @cached_property
    def has_glass_film(self) -> bool:
        return self.glass_film is not None and bool(self.glass_film.any())

    def glass_film_reflectance(self, mat_ids, cos_i, entering):
        """(n, 3) reflectance of the filmed glasses ``mat_ids`` at cosines ``cos_i`` (with the
        normal or microfacet normal), from outside where ``entering``: Cycles' Principled glass with
        a film, whose film and glass indices are relative to the side the light comes from (the
        film's over the glass's from inside), the film's colour scaled towards F0 t as the
        layer's (:func:`thin_film.principled_reflectance`, t = ``film_tint``)."""
        ior = self.ior.take(mat_ids)
        film_ior = self.film_ior.take(mat_ids)
        eta = np.where(entering, ior, 1.0 / ior)
        f0t = smp.dielectric_f0(ior)[:, None] * self.film_tint.take(mat_ids, axis=0)
        return thin_film.principled_reflectance(self.film_sensitivity, cos_i,
                                                self.film_thickness.take(mat_ids),
                                                np.where(entering, film_ior, film_ior / ior), eta, f0t)

    @cached_property
    def _metal_rows(self):
        """Per lobe (GLOSSY, MIRROR): contiguous (M, 3) edge and dip, the bounds -colour and
        max(1 - colour, 0) of what a metal's curve may add, and (M,) which rows have a curve."""
        rows = {}
        for lobe in (GLOSSY, MIRROR):
            base = self.color[:, lobe]
            edge, dip = np.ascontiguousarray(self.edge[:, lobe]), np.ascontiguousarray(self.dip[:, lobe])
            metal = ((edge != 0) | (dip != 0)).any(axis=1)
            rows[lobe] = (edge, dip, -base, np.maximum(1.0 - base, 0.0), metal)
        return rows

    def layer_factor(self, mat_ids, mu):
        """(n,) factors of the diffuse lobe under a Fresnel layer at view cosines ``mu`` (1: none)."""
        return _interpolate(self.layer, mat_ids, mu)


def sheen_albedo(mu, roughness):
    """(E, a, b), each (n,), of Cycles' microfiber sheen (Zeltner, Burley and Chiang 2022, "Practical
    multiple-scattering sheen using linearly transformed cosines") at view cosines ``mu`` and
    roughness (both (n,)): its directional albedo E and the coefficients of its lobe, the cosine
    transformed by the inverse matrix [[a, 0, b], [0, a, 0], [0, 0, 1]] in the frame whose x axis is
    the view's direction along the surface (:func:`sheen_value`).  Cycles reads the three from a
    32 x 32 table of the paper's fit; these are the paper's analytic fits of that table (a Gaussian
    in mu for E, rational functions for a and b), within about 1 % of Cycles' furnace albedo at
    roughness 0.3 to 1 (2 to 5 % by band of mu, more where E is below 0.01).  As in Cycles the
    roughness is clamped to [1e-3, 1] and a sheen whose a or E falls below 1e-5 is left out (E 0)."""
    x = np.clip(mu, 0.0, 1.0)
    y = np.clip(roughness, 1e-3, 1.0)
    s = y * (0.0206607 + 1.58491 * y) / (0.0379424 + y * (1.32227 + y))
    m = y * (-0.193854 + y * (-1.14885 + y * (1.7932 - 0.95943 * y * y))) / (0.046391 + y)
    o = y * (0.000654023 + (-0.0207818 + 0.119681 * y) * y) / (1.26264 + y * (-1.92021 + y))
    e = np.exp(-0.5 * ((x - m) / s) ** 2) / (s * np.sqrt(2.0 * np.pi)) + o
    a = (2.58126 * x + 0.813703 * y) * y / (1.0 + 0.310327 * x * x + 2.60994 * x * y)
    b = (np.sqrt(1.0 - x) * (y - 1.0) * y * y * y
         / (0.0000254053 + 1.71228 * x - 1.71506 * x * y + 1.34174 * y * y))
    e = np.where((np.abs(a) < 1e-5) | (e < 1e-5), 0.0, np.clip(e, 0.0, 1.0))
    return e, a, b


def sheen_frame(view, n):
    """(x, y) (n, 3) of the sheen's frame with normal ``n``: x the view's direction along the surface
    (any tangent where the view is the normal), y = n x x (Cycles' ``make_orthonormals_safe_tangent``)."""
    x = view - dot(view, n)[:, None] * n
    length = np.sqrt(dot(x, x))
    flat = length < 1e-7
    x = x / np.where(flat, 1.0, length)[:, None]
    if flat.any():
        x[flat] = smp.orthonormal_frames(n[flat])[0]
    return x, np.cross(n, x)


def sheen_value(a, b, lx, ly, lz):
    """(n,) the sheen's f (per unit of its colour times E; without the cosine) towards a light of
    local coordinates ``lx``, ``ly``, ``lz`` (:func:`sheen_frame` and the normal): the transformed
    cosine a^2 max(lz, 0) / (pi |M^-1 l|^4) over lz (Cycles' ``bsdf_sheen_eval`` divided by the
    cosine); 0 below the surface."""
    len_sq = (a * lx + b * lz) ** 2 + (a * ly) ** 2 + lz * lz
    return np.where(lz > 0, a * a / (np.pi * np.maximum(len_sq, 1e-300) ** 2), 0.0)


def _sheen_tables(mats, lobes, sheen_on, cover, score_extra):
    """The table's sheen fields (``sheen_roughness``, ``sheen_cover``; None without a sheen column),
    and each sheen's lobe-choice score term: its cosine-weighted mean albedo over views, into
    ``score_extra`` (which :func:`lobe_scores` multiplies by)."""
    if lobes <= SHEEN:
        return dict(sheen_roughness=None, sheen_cover=None)
    m = len(cover)
    rough = np.clip(np.full(m, 0.5) if mats.sheen_roughness is None
                    else np.asarray(mats.sheen_roughness, np.float64), 0.0, 1.0)
    mu = (np.arange(64) + 0.5) / 64
    e, _, _ = sheen_albedo(np.tile(mu, m), np.repeat(rough, 64))
    score_extra[:, SHEEN] = np.where(sheen_on, 2.0 * (e.reshape(m, 64) * mu).mean(axis=1), 0.0)
    return dict(sheen_roughness=rough, sheen_cover=cover)


def _or_ones(values, m):
    """Per-material values, 1 for all when absent."""
    return np.ones(m) if values is None else np.asarray(values, np.float64)


def _or_none(indices, m):
    """Per-material program indices, -1 for all when absent."""
    return np.full(m, -1, np.int32) if indices is None else indices


def _rough_diffuse_table(roughness):
    """(M, 4) a, b, Eavg / (1 - Eavg) and 1 - Eavg per material of Cycles' rough diffuse
    (``bsdf_oren_nayar_param``): a = 1 / (pi + s (pi / 2 - 2 / 3)), b = s a for s = the roughness,
    Eavg = a pi + (2 pi - 5.6) / 3 b; Lambert (1 / pi, 0, 0, 0) below ``ROUGH_DIFFUSE_MIN``."""
    s = np.clip(np.asarray(roughness, np.float64), 0.0, 1.0)
    rough = s >= ROUGH_DIFFUSE_MIN
    a = np.where(rough, 1.0 / (np.pi + s * (0.5 * np.pi - 2.0 / 3.0)), 1.0 / np.pi)
    b = np.where(rough, s * a, 0.0)
    keep = np.where(rough, 1.0 - (a * np.pi + (2.0 * np.pi - 5.6) / 3.0 * b), 0.0)
    ratio = np.where(rough, (1.0 - keep) / np.where(rough, keep, 1.0), 0.0)
    return np.stack([a, b, ratio, keep], axis=1)


def oren_nayar_g(mu):
    """G(mu) of Cycles' rough diffuse (``bsdf_oren_nayar_G``), exactly."""
    mu = np.clip(mu, 0.0, 1.0)
    sin = np.sqrt(np.maximum(1.0 - mu * mu, 0.0))
    theta = np.arccos(mu)
    g = sin * (theta - 2.0 / 3.0 - sin * mu) \
        + 2.0 / 3.0 * (sin / np.maximum(mu, 1e-6)) * (1.0 - sin * sin * sin)
    return np.where(mu < 1e-6, (0.5 * np.pi - 2.0 / 3.0) - mu, g)


# G at 1024 equal steps of mu, interpolated linearly (within 5e-6 of G; 5 times faster).
G_NODES = 1024
G_TABLE = oren_nayar_g(np.linspace(0.0, 1.0, G_NODES + 1))


def oren_nayar_albedo(a, b, mu):
    """E(mu) = a pi + b G(mu): the single-scattering albedo of Cycles' rough diffuse (Fujii's
    improved Oren-Nayar) at cosine ``mu``, G from ``G_TABLE``."""
    t = np.clip(mu, 0.0, 1.0) * G_NODES
    k = np.minimum(t.astype(np.int64), G_NODES - 1)
    lo = G_TABLE.take(k)
    return a * np.pi + b * (lo + (t - k) * (G_TABLE.take(k + 1) - lo))


def rough_diffuse_terms(table, mat_ids, albedo, cos_v):
    """(a, b (k,), m (k, 3)): the parts of :func:`rough_diffuse_factor` that do not depend on
    the light direction, m = pi E_ms (1 - E(v)) at view cosines ``cos_v``."""
    a, b, ratio, keep = (table.rough_diffuse[:, c].take(mat_ids) for c in range(4))
    rho = np.clip(albedo, 0.0, 1.0)
    ms = rho * rho * (ratio[:, None] / (1.0 - rho * keep[:, None]))
    ms *= (1.0 - oren_nayar_albedo(a, b, np.maximum(cos_v, 0.0)))[:, None]
    return a, b, ms


def rough_diffuse_factor(table, mat_ids, albedo, cos_l, cos_v, cos_lv, terms=None):
    """(k, 3) pi f / albedo of Cycles' rough diffuse (1 for Lambert) for light and view cosines
    ``cos_l``, ``cos_v`` with the shading normal and ``cos_lv`` between them (k,) each:
    pi (a + b t + E_ms (1 - E(l)) (1 - E(v))), t = l.v - (n.l)(n.v), divided by max(n.l, n.v)
    where positive, E_ms = rho^2 / pi Eavg / (1 - Eavg) / (1 - rho (1 - Eavg)) of the saturated
    ``albedo`` rho (k, 3) (the OpenPBR energy compensation Cycles uses): a white lobe keeps all
    the light, from any direction.  Symmetric in light and view.  ``terms``: those of
    :func:`rough_diffuse_terms` if known (then ``mat_ids`` and ``albedo`` are not read)."""
    a, b, ms = terms if terms is not None else rough_diffuse_terms(table, mat_ids, albedo, cos_v)
    nl, nv = np.maximum(cos_l, 0.0), np.maximum(cos_v, 0.0)
    t = cos_lv - nl * nv
    t = np.where(t > 0, t / (np.maximum(nl, nv) + 1e-30), t)
    out = ms * (1.0 - oren_nayar_albedo(a, b, nl))[:, None]
    out += (np.pi * (a + b * t))[:, None]
    return out


def _beckmann(distribution, m):
    """(M,) bool: a Materials distribution field (None: all GGX) says Beckmann."""
    if distribution is None:
        return np.zeros(m, bool)
    return np.asarray(distribution) == DISTRIBUTION_BECKMANN


def _or_zeros(values, shape):
    """Per-material values as float64, zeros when absent."""
    return np.zeros(shape) if values is None else np.asarray(values, np.float64)


def _interpolate(table, rows, x, nodes=MS_NODES):
    """Rows ``rows`` of a (R, nodes + 1) or (R, nodes + 1, 3) table at x = (k / nodes)^2, linearly in
    sqrt(x): (n,) or (n, 3)."""
    t = np.sqrt(np.clip(x, 0.0, 1.0)) * nodes
    k = np.minimum(t.astype(np.int64), nodes - 1)
    f = t - k
    flat = rows.astype(np.int64) * (nodes + 1) + k
    if table.ndim == 2:
        e = table.ravel()
        return (1.0 - f) * e.take(flat) + f * e.take(flat + 1)
    e = table.reshape(-1, table.shape[-1])
    f = f[:, None]
    return (1.0 - f) * e.take(flat, axis=0) + f * e.take(flat + 1, axis=0)


def _metal_mean_rise(base, edge, dip, nodes=64):
    """(M, 3) the cosine-weighted mean of what a metal's curve adds to its constant colour
    ``base``, base + edge (1 - mu)^5 - dip mu (1 - mu)^6 kept within [0, 1] as in
    :meth:`MaterialTable.fresnel_color`, less ``base`` (0 for rows without a curve): for lobe
    scores."""
    on = ((edge != 0) | (dip != 0)).any(axis=1)
    out = np.zeros_like(base)
    if not on.any():
        return out
    mu = (np.arange(nodes) + 0.5) / nodes
    p = 1.0 - mu
    b, e, d = base[on, :, None], edge[on, :, None], dip[on, :, None]
    curve = np.clip(b + e * p ** 5 - d * mu * p ** 6, 0.0, np.maximum(1.0, b))
    out[on] = np.mean(2.0 * mu * curve, axis=2) - base[on]
    return out


def _rise_means(alpha, fresnel_ior, rise, coarse, albedo):
    """{(alpha, IOR): S(mu)} at the ``MS_NODES`` + 1 nodes for the rows with a Fresnel rise
    (:func:`ggx_fresnel_rise_average`); the albedo E(mu) each quadrature gives along goes into
    ``albedo`` under (alpha, strata)."""
    on = (fresnel_ior > 0) & (rise != 0).any(axis=(1, 2))
    mu = (np.arange(MS_NODES + 1) / MS_NODES) ** 2
    means = {}
    for a, eta in set(zip(alpha[on], fresnel_ior[on])):
        strata = _strata(coarse[on & (alpha == a) & (fresnel_ior == eta)])
        e, means[(a, eta)] = smp.ggx_fresnel_rise_average(a, mu, max(eta, 1.0 + 1e-6), strata)
        albedo.setdefault((a, strata), e)
    return means


def _layer_tables(alpha, fresnel_ior, rise, layered, layer_f0, layer_share, ms_albedo, ms_fresnel, weight,
                  rise_means, film=None):
    """The diffuse factor L(mu) under a Fresnel layer, per material at the ``MS_NODES`` + 1 nodes,
    and mean lobe-score terms for the Fresnel rise and the layer.

    As Cycles' Principled BSDF (``closure_layering_weight`` with ``bsdf_microfacet_estimate_albedo``):
    L = saturate(1 - share max over channels of K (f0 + (1 - f0) S(mu))), with f0 the layer's
    normal-incidence colour, S the lobe mean of the Fresnel rise (:func:`ggx_fresnel_rise_average`)
    and K = E + F_ms (1 - E) the layer's energy with multiscatter GGX, 1 without (Cycles does not
    count the single-scattering loss there), and share the part of the diffuse lobe under the
    layer (1 for a Principled BSDF alone).  Scores use the cosine-weighted means over mu.
    ``rise_means`` is :func:`_rise_means`'s.  A filmed layer (``film``, :func:`_film_tables`) takes
    its film's reflectance at mu for f0 + (1 - f0) S(mu), as Cycles (no lobe mean for a film),
    and its curve's mean for the rise's score.
    """
    m = len(alpha)
    layer = np.ones((m, MS_NODES + 1))
    extra = np.zeros(weight.shape)
    on = (fresnel_ior > 0) & (rise != 0).any(axis=(1, 2))
    if not on.any():
        extra[:, DIFFUSE] = 1.0                           # a factor, see lobe_scores
        return layer, extra
    mu = (np.arange(MS_NODES + 1) / MS_NODES) ** 2
    f0 = np.clip(np.asarray(layer_f0, np.float64), 0.0, 1.0)
    for a, eta in set(zip(alpha[on], fresnel_ior[on])):
        rows = np.flatnonzero(on & (alpha == a) & (fresnel_ior == eta))
        s = rise_means[(a, eta)]
        s_mean = 2.0 * np.trapz(s * mu, mu)
        filmed = film.index[rows] if film is not None else np.full(len(rows), -1)
        for lobe in (GLOSSY, MIRROR):
            extra[rows, lobe] = weight[rows, lobe] * smp.luminance(rise[rows, lobe]) * s_mean
            f = filmed >= 0
            extra[rows[f], lobe] = weight[rows[f], lobe] * smp.luminance(rise[rows[f], lobe]
                                                                         * film.mean_rise[filmed[f]])
        lay = rows[layered[rows]]
        if len(lay):
            e = ms_albedo[lay][:, :, None]                     # (k, nodes, 1); 1 without multiscatter
            k = e + ms_fresnel[lay, None, :] * (1.0 - e)
            reflected = f0[lay, None, :] + (1.0 - f0[lay, None, :]) * s[None, :, None]
            if film is not None:
                row = film.index[lay]
                reflected[row >= 0] = film.albedo[row[row >= 0]]
            a_layer = k * reflected
            layer[lay] = np.clip(1.0 - layer_share[lay, None] * a_layer.max(axis=2), 0.0, 1.0)
    l_mean = 2.0 * np.trapz(layer * mu, mu, axis=1)
    extra[:, DIFFUSE] = np.where(layered, l_mean, 1.0)     # a factor, see lobe_scores
    return layer, extra


@dataclass
class _Film:
    """The films' shared inputs and the filmed layers' tables (:func:`_film_tables`)."""

    thickness: np.ndarray   # (M,) Materials.film_thickness (0 without)
    filmed: np.ndarray      # (M,) bool: above Cycles' cut-off
    sensitivity: np.ndarray  # thin_film.sensitivity_table() where some row has a film, else None
    index: np.ndarray       # (M,) int64 row of a filmed layer in the tables below or -1
    curve: np.ndarray       # (F, FILM_NODES + 1, 3) (G(c) - f0 t) / (1 - f0 t) at c = (k / FILM_NODES)^2
    albedo: np.ndarray      # (F, MS_NODES + 1, 3) G at mu = (k / MS_NODES)^2: the layer's albedo
    mean_rise: np.ndarray   # (F, 3) the cosine-weighted mean of the rise over mu


def _film_tables(mats, fresnel_ior, rise):
    """The rise of each layer coated by a thin film (``Materials.film_thickness``) at the film's
    nodes: (G(c) - f0 t) / (1 - f0 t) per channel, G = :func:`thin_film.principled_reflectance` of the
    layer (IOR ``fresnel_ior``, f0 its F0, t = ``film_tint``), so that ``rise`` times it is what the
    layer adds to its normal-incidence colour; and G at the layer tables' nodes."""
    m = len(fresnel_ior)
    thickness = _or_zeros(mats.film_thickness, m)
    filmed = thickness > np.float32(thin_film.THICKNESS_CUTOFF)
    sensitivity = thin_film.sensitivity_table() if filmed.any() else None
    on = np.flatnonzero(filmed & (fresnel_ior > 0) & (rise != 0).any(axis=(1, 2)))
    index = np.full(m, -1, np.int64)
    index[on] = np.arange(len(on))
    if len(on) == 0:
        return _Film(thickness, filmed, sensitivity, index, np.zeros((0, FILM_NODES + 1, 3)),
                     np.zeros((0, MS_NODES + 1, 3)), np.zeros((0, 3)))
    eta = np.maximum(fresnel_ior[on], 1.0)
    f0t = np.clip(smp.dielectric_f0(eta)[:, None] * _or_ones(mats.film_tint, (m, 3))[on], 0.0, 1.0)
    args = (thickness[on], np.asarray(mats.film_ior, np.float64)[on], eta, f0t)
    _, g = _at_film_nodes(FILM_NODES, thin_film.principled_reflectance, sensitivity, *args)
    curve = (g - f0t[:, None, :]) / np.maximum(1.0 - f0t, 1e-6)[:, None, :]
    mu, albedo = _at_film_nodes(MS_NODES, thin_film.principled_reflectance, sensitivity, *args)
    lifted = (albedo - f0t[:, None, :]) / np.maximum(1.0 - f0t, 1e-6)[:, None, :]
    mean_rise = 2.0 * np.trapz(lifted * mu[None, :, None], mu, axis=1)
    return _Film(thickness, filmed, sensitivity, index, curve, albedo, mean_rise)


def _at_film_nodes(nodes, reflectance, sensitivity, *per_row):
    """(x (nodes + 1,), (rows, nodes + 1, 3)): ``reflectance(sensitivity, x, ...)`` at x = (k /
    nodes)^2 for each row of the per-row arguments ``per_row`` (first axis: the rows)."""
    x = (np.arange(nodes + 1) / nodes) ** 2
    rows = len(per_row[0])
    g = reflectance(sensitivity, np.tile(x, rows), *(np.repeat(a, len(x), axis=0) for a in per_row))
    return x, g.reshape(rows, len(x), 3)


def _glass_film(mats, weight, film):
    """MaterialTable fields of the glasses with a film (``Materials.film_thickness``)."""
    on = film.filmed & (weight[:, DIELECTRIC] > 0)
    if not on.any():
        return {}
    return {"glass_film": on, "film_thickness": film.thickness,
            "film_ior": np.asarray(mats.film_ior, np.float64),
            "film_tint": _or_ones(mats.film_tint, (len(weight), 3)), "film_sensitivity": film.sensitivity}


def _metal_film(mats, weight, edge, dip, sharp, film):
    """MaterialTable fields of the metals under a film (``Materials.film_metal``): per filmed metal,
    what it adds to its lobe's colour at the film's nodes, k (G_m(c) - F0) (k its share of the lobe,
    after a sharp glossy lobe's merge into the mirror's; F0 and b from its rise and dip, G_m of a
    physical conductor by its complex index, ``Materials.film_metal_ior``)."""
    m = len(weight)
    share = _or_zeros(mats.film_metal, m)
    lobe = np.where(weight[:, GLOSSY] > 0, GLOSSY, MIRROR)
    rows = np.arange(m)
    e, d = edge[rows, lobe], dip[rows, lobe]
    on = np.flatnonzero(film.filmed & (share > 0) & ((e != 0) | (d != 0)).any(axis=1))
    if len(on) == 0:
        return {}
    merged = np.ones(m)
    merged[sharp] = np.divide(np.asarray(mats.glossy_weight, np.float64)[sharp], weight[sharp, MIRROR],
                              out=np.zeros(int(sharp.sum())), where=weight[sharp, MIRROR] > 0)
    k = (share * merged)[on][:, None]
    f0 = np.clip(1.0 - e[on] / k, 0.0, 1.0)
    film_ior = np.asarray(mats.film_ior, np.float64)[on]
    _, g = _at_film_nodes(FILM_NODES, thin_film.conductor_reflectance, film.sensitivity, film.thickness[on],
                          film_ior, f0, d[on] / k)
    # (physical conductors: their own complex index under the film)
    n, k_ext = (_or_zeros(x, (m, 3))[on] for x in (mats.film_metal_ior, mats.film_metal_extinction))
    physical = np.flatnonzero((n > 0).any(axis=1))
    if len(physical):
        _, g[physical] = _at_film_nodes(FILM_NODES, thin_film.physical_conductor_reflectance,
                                        film.sensitivity, film.thickness[on][physical], film_ior[physical],
                                        n[physical], k_ext[physical])
    index = np.full(m, -1, np.int64)
    index[on] = np.arange(len(on))
    return {"metal_film_index": index, "metal_film_lobe": lobe,
            "metal_film_curve": k[:, None, :] * (g - f0[:, None])}


def _coat_tables(mats, coat_row, alpha, fresnel_ior, rise_means, ms_albedo, ms_fresnel):
    """(factor (M, MS_NODES + 1, 3), layer (M, MS_NODES + 1), score (M, 2)): the factor under each
    material's coat at the nodes mu = (k / MS_NODES)^2, the coat's albedo's part of it, and, for
    the choice between the coat and what lies under it (:func:`pick_coat`), the coat's
    cosine-weighted mean albedo and the mean luminance of the factor.  As Cycles' Principled BSDF:
    1 - w K(mu) (F0 + (1 - F0) S(mu)) (the coat's albedo as ``bsdf_microfacet_estimate_albedo`` of
    a dielectric GGX lobe, K its multiscatter energy) times 1 - w + w tint^(1 / cos_t), the tint
    of the path through the coat refracted to cos_t."""
    m = len(coat_row)
    factor = np.ones((m, MS_NODES + 1, 3))
    layer = np.ones((m, MS_NODES + 1))
    score = np.zeros((m, 2))
    coated = np.flatnonzero(coat_row >= 0)
    if len(coated) == 0:
        return factor, layer, score
    mu = (np.arange(MS_NODES + 1) / MS_NODES) ** 2
    for i in coated:
        c = coat_row[i]
        w = float(mats.coat_weight[i])
        eta = float(fresnel_ior[c])
        f0 = smp.dielectric_f0(eta)
        s = rise_means.get((alpha[c], fresnel_ior[c]), np.zeros(MS_NODES + 1))
        e = ms_albedo[c]
        k = e + ms_fresnel[c, 0] * (1.0 - e)
        albedo = k * (f0 + (1.0 - f0) * s)
        cos_t = np.sqrt(np.maximum(1.0 - (1.0 - mu * mu) / (eta * eta), 1e-12))
        tint = np.clip(np.asarray(mats.coat_tint[i], np.float64), 0.0, 1.0)
        through = 1.0 - w + w * tint[None, :] ** (1.0 / cos_t[:, None])
        layer[i] = np.clip(1.0 - w * albedo, 0.0, 1.0)
        factor[i] = layer[i][:, None] * through
        score[i, 0] = w * 2.0 * np.trapz(albedo * mu, mu)
        score[i, 1] = 2.0 * np.trapz(smp.luminance(factor[i]) * mu, mu)
    return factor, layer, score


def _strata(coarse):
    """Quadrature strata for a group of rows: coarse only if all of them may be."""
    return COARSE_STRATA if coarse.all() else EXACT_STRATA


def _multiple_scattering_fresnel(fss, e_avg):
    """F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)): the colour of the light that leaves after more
    than one microfacet bounce (Kulla and Conty's appendix, one F_ss cancelled as in Cycles)."""
    return fss * e_avg / (1.0 - fss * (1.0 - e_avg))


def _glass_multiscatter_tables(mats, weight, dielectric_alpha, coarse):
    """MaterialTable fields of the rough glasses with Multiscatter GGX
    (``Materials.dielectric_multiscatter``, their F_ss): E(mu) at the ``MS_NODES`` + 1 nodes
    from outside (relative IOR ``ior``) and inside (1 / ``ior``), and F_ms = F_ss E_avg / (1 - F_ss
    (1 - E_avg)) with each side's E_avg.  One quadrature per distinct (alpha, IOR)."""
    fss = _or_zeros(mats.dielectric_multiscatter, (len(weight), 3))
    on = (weight[:, DIELECTRIC] > 0) & (dielectric_alpha > 0) & (fss > 0).any(axis=1)
    if not on.any():
        return {}
    m = len(weight)
    table = np.ones((m, 2, MS_NODES + 1))
    fms = np.zeros((m, 2, 3))
    mu = (np.arange(MS_NODES + 1) / MS_NODES) ** 2
    ior = np.asarray(mats.ior, np.float64)
    f = np.clip(fss, 0.0, 1.0)
    for a, eta in set(zip(dielectric_alpha[on], ior[on])):
        rows = np.flatnonzero(on & (dielectric_alpha == a) & (ior == eta))
        strata = _strata(coarse[rows])
        for side, relative in enumerate((eta, 1.0 / eta)):
            e = smp.ggx_glass_albedo(a, mu, relative, strata)
            e_avg = 2.0 * np.trapz(e * mu, mu)
            table[rows, side] = e
            fms[rows, side] = _multiple_scattering_fresnel(f[rows], e_avg)
    return {"glass_ms_albedo": table, "glass_ms_fresnel": fms}


def _multiscatter_tables(alpha, glossy_on, fresnel_ss, coarse, albedo):
    """Per-material E(mu) at the ``MS_NODES`` + 1 nodes, F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg))
    and E_avg (0 where a material has no compensation).

    F_ms is the colour of the light that leaves after more than one microfacet bounce (the
    appendix of Kulla and Conty, with one F_ss cancelled as in Cycles); E_avg = 2 int E mu dmu.
    One table per distinct alpha: a few milliseconds each, none where ``albedo`` (a dict by
    (alpha, strata)) has it already.
    """
    m = len(alpha)
    table = np.ones((m, MS_NODES + 1))
    fms = np.zeros((m, 3))
    e_avgs = np.zeros(m)
    on = glossy_on & (np.asarray(fresnel_ss) > 0).any(axis=1)
    if not on.any():
        return table, fms, e_avgs
    mu = (np.arange(MS_NODES + 1) / MS_NODES) ** 2
    fss = np.clip(np.asarray(fresnel_ss, np.float64), 0.0, 1.0)
    for a in np.unique(alpha[on]):
        rows = np.flatnonzero(on & (alpha == a))
        strata = _strata(coarse[rows])
        e = albedo.get((a, strata))
        if e is None:
            e = smp.ggx_albedo(a, mu, strata)
        e_avg = 2.0 * np.trapz(e * mu, mu)
        table[rows] = e
        f = fss[rows]
        fms[rows] = _multiple_scattering_fresnel(f, e_avg)
        e_avgs[rows] = e_avg
    return table, fms, e_avgs


class Textures:
    """Image textures looked up bilinearly with repeat wrapping; row 0 is v = 0."""

    def __init__(self, images):
        self.images = [np.asarray(im, np.float32) for im in images]

    def lookup(self, texture_ids, uv):
        """(n, 3) float64 colours; rows with ``texture_ids`` < 0 get 1."""
        out = np.ones((len(texture_ids), 3))
        for k in np.unique(texture_ids[texture_ids >= 0]):
            sel = np.flatnonzero(texture_ids == k)
            out[sel] = bilinear(self.images[k], uv[sel, 0], uv[sel, 1])
        return out

    def gradient(self, texture_ids, uv):
        """(d/du, d/dv), each (n, 3) float64, of the bilinear lookups (every id >= 0)."""
        du, dv = np.zeros((len(texture_ids), 3)), np.zeros((len(texture_ids), 3))
        for k in np.unique(texture_ids):
            sel = np.flatnonzero(texture_ids == k)
            du[sel], dv[sel] = bilinear_gradient(self.images[k], uv[sel, 0], uv[sel, 1])
        return du, dv


def bilinear(image, u, v, clamp_v=False):
    """(n, 3) bilinear lookups of ``image`` (H, W, 3) at (u, v) (n,) each; row 0 is v = 0, and u
    wraps around.  v wraps too, or with ``clamp_v`` stops at the first and last rows' centres
    (an environment image's poles)."""
    fx, fy, a, b, c, d = _bilinear_cell(image, u, v, clamp_v)
    return (1 - fx) * (1 - fy) * a + fx * (1 - fy) * b + (1 - fx) * fy * c + fx * fy * d


def bilinear_gradient(image, u, v):
    """(d/du, d/dv), each (n, 3), of :func:`bilinear` (u and v wrap): the exact derivatives of
    the interpolated image, constant across each cell of four texel centres."""
    h, w = image.shape[:2]
    fx, fy, a, b, c, d = _bilinear_cell(image, u, v, False)
    return w * ((1 - fy) * (b - a) + fy * (d - c)), h * ((1 - fx) * (c - a) + fx * (d - b))


def _bilinear_cell(image, u, v, clamp_v):
    """Fractions (n, 1) fx, fy and the four texels (n, 3) around (u, v): lower left, lower
    right, upper left, upper right."""
    h, w = image.shape[:2]
    x = u * w - 0.5
    y = v * h - 0.5
    if clamp_v:
        y = np.clip(y, 0.0, h - 1.0)
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    ix0 = np.mod(x0, w).astype(np.int64)
    ix1 = (ix0 + 1) % w
    if clamp_v:
        iy0 = y0.astype(np.int64)
        iy1 = np.minimum(iy0 + 1, h - 1)
    else:
        iy0 = np.mod(y0, h).astype(np.int64)
        iy1 = (iy0 + 1) % h
    return fx, fy, image[iy0, ix0], image[iy0, ix1], image[iy1, ix0], image[iy1, ix1]


# Cycles' F82 tint (``fresnel_f82tint_B``): the Schlick curve's (1 - c)^5 at c = 1/7, and the factor
# 7 / (f^5 f), f = 6/7, that makes b of F0 and the tint (F0 + (1 - F0) F82_SCHLICK) F82_DIP (1 - tint).
F82_SCHLICK = (6.0 / 7.0) ** 5
F82_DIP = 7.0 / (6.0 / 7.0) ** 6


def metal_curve(color, edge_tint=(1.0, 1.0, 1.0)):
    """(F0, rise, dip), each (..., 3), of Cycles' F82-tint metal Fresnel (F0 = ``color``, clamped
    to [0, 1] as ``edge_tint``): F(c) = F0 + rise (1 - c)^5 - dip c (1 - c)^6 with rise = 1 - F0
    and dip = b of ``fresnel_f82tint_B``, which makes F at cos = 1/7 the Schlick curve there
    times the tint (``Materials.glossy_metal_rise`` and ``glossy_metal_dip``)."""
    f0 = np.clip(np.asarray(color, np.float64), 0.0, 1.0)
    tint = np.clip(np.asarray(edge_tint, np.float64), 0.0, 1.0)
    dip = (f0 + (1.0 - f0) * F82_SCHLICK) * F82_DIP * (1.0 - tint)
    return f0, 1.0 - f0, dip


def metal_fresnel(color, edge_tint=(1.0, 1.0, 1.0)):
    """Cosine-weighted hemispherical mean of Cycles' F82-tint metal Fresnel (F0 = ``color``, any
    shape (..., 3), as ``edge_tint``):
    F(mu) = F0 + (1 - F0)(1 - mu)^5 - b mu (1 - mu)^6 averages to F0 + (1 - F0) / 21 - b / 126,
    b the edge-tint term of ``fresnel_f82tint_B`` (0 for a white tint)."""
    f0, _, dip = metal_curve(color, edge_tint)
    return np.clip(f82_mean(f0, dip), 0.0, 1.0)


def f82_mean(f0, dip):
    """The cosine-weighted mean F0 + (1 - F0) / 21 - b / 126 of the F82-tint curve of ``f0`` and
    ``dip`` = b, unclipped (:func:`metal_fresnel` clips it)."""
    return f0 + (1.0 - f0) / 21.0 - dip / 126.0


def face_forward(n, v):
    """Flip the unit normals ``n`` (n, 3) to the side of the vectors ``v``."""
    return n * np.where(dot(n, v) < 0, -1.0, 1.0)[:, None]


def lobe_colors(table, mat_ids, diffuse_albedo):
    """(n, L, 3) lobe colours at hits, with the (textured) diffuse albedo filled in."""
    colors = table.color.take(mat_ids, axis=0)
    colors[:, DIFFUSE] = diffuse_albedo
    return colors


def lobe_scores(table, mat_ids, colors):
    """(n, L) unnormalised lobe-choice probabilities: weight times colour luminance; for lobes
    with a Fresnel rise or under a layer, with their mean over view directions."""
    scores = table.weight.take(mat_ids, axis=0) * np.maximum(smp.luminance(colors), 0.0)
    if table.has_fresnel:
        extra = table.score_extra.take(mat_ids, axis=0)
        scores[:, DIFFUSE] *= extra[:, DIFFUSE]
        # (a metal's curve may dip below its F0 on average: never below 0)
        scores[:, GLOSSY] = np.maximum(scores[:, GLOSSY] + extra[:, GLOSSY], 0.0)
        scores[:, MIRROR] = np.maximum(scores[:, MIRROR] + extra[:, MIRROR], 0.0)
    if table.has_hit_metal:
        # Metals whose curve follows the hit's colour: the curve's mean, F0 + (1 - F0) / 21 - b / 126
        # (:func:`metal_fresnel` unclipped), of the hit's F0, kept above (1 - F0) / 210 where a dipping
        # tint takes it below 0 (a black metal still reflects at grazing angles).
        h = np.flatnonzero(table.hit_metal.take(mat_ids))
        if len(h):
            m = mat_ids.take(h)
            lobe = table.hit_metal_lobe.take(m)
            f0, dip = table.hit_metal_f0_dip(m, colors[h, lobe])
            mean = np.maximum(f82_mean(f0, dip), (1.0 - f0) / 210.0)
            if table.has_partial_metal:
                # k times that, and the rest: its colour (its rise's mean is in score_extra, 0 for a
                # whole metal).
                mean = table.hit_metal_share.take(m)[:, None] * mean + table.hit_metal_rest.take(m, axis=0)
            scores[h, lobe] = table.weight[m, lobe] * smp.luminance(mean) + table.score_extra[m, lobe]
    if table.has_sheen:
        # (a factor: the sheen's mean albedo over views)
        scores[:, SHEEN] *= table.score_extra[:, SHEEN].take(mat_ids)
    return scores


# Least chance of either layer of a coated surface (pick_coat) where both reflect light.
MIN_LAYER_CHANCE = 0.05


def pick_coat(table, mat_ids, colors, scores, u):
    """Choose, at hits of coated materials, the coat or what lies under it.

    ``scores`` are :func:`lobe_scores` of ``mat_ids``, ``u`` (n,) a uniform number.  The coat
    is chosen with probability p = C / (C + B) (clamped to [MIN_LAYER_CHANCE, 1 -
    MIN_LAYER_CHANCE] when both are positive), C the coat's mean albedo and B the scores' total
    times the mean factor under the coat.  Returns ``(mat_ids, colors, scores, scale, under, u)``:
    the coat's material, colours and scores where it was chosen, the others unchanged; ``scale``
    (n,) 1 / the chosen layer's probability (1 without a coat); ``under`` the rows that chose
    what lies under a coat (whose weights then take :meth:`MaterialTable.coat_attenuation` at
    the view direction); and ``u`` rescaled within the choice (still uniform).
    """
    n = len(mat_ids)
    scale = np.ones(n)
    rows = np.flatnonzero(table.coat_row.take(mat_ids) >= 0)
    if len(rows) == 0:
        return mat_ids, colors, scores, scale, rows, u
    m = mat_ids.take(rows)
    coat = table.coat_score[:, 0].take(m)
    base = scores[rows].sum(axis=1) * table.coat_score[:, 1].take(m)
    total = coat + base
    p = np.where(total > 0, coat / np.where(total > 0, total, 1.0), 1.0)
    p = np.where((coat > 0) & (base > 0), np.clip(p, MIN_LAYER_CHANCE, 1.0 - MIN_LAYER_CHANCE), p)
    u_rows = u.take(rows)
    on_coat = u_rows < p
    mat_ids, colors, scores, u = mat_ids.copy(), colors.copy(), scores.copy(), u.copy()
    c = rows[on_coat]
    mat_ids[c] = table.coat_row.take(m[on_coat])
    colors[c] = table.color.take(mat_ids.take(c), axis=0)
    scores[c] = lobe_scores(table, mat_ids.take(c), colors[c])
    chosen = np.where(on_coat, p, 1.0 - p)
    scale[rows] = 1.0 / np.maximum(chosen, 1e-300)
    u[rows] = np.clip(np.where(on_coat, u_rows / np.maximum(p, 1e-300),
                               (u_rows - p) / np.maximum(1.0 - p, 1e-300)), 0.0, np.nextafter(1.0, 0.0))
    return mat_ids, colors, scores, scale, rows[~on_coat], u


def choose_lobe(scores, u):
    """Lobe index (n,) by ``scores`` (n, L); -1 where all scores are 0.  Also the choice probability."""
    # Column by column: NumPy reduces a short inner axis (sum/cumsum over axis 1) ~8x slower.
    lobes = scores.shape[1]
    s = [scores[:, k] for k in range(lobes)]
    cdf = [s[0]]
    for k in range(1, lobes):
        cdf.append(cdf[-1] + s[k])
    total = cdf[-1]
    target = u * total
    lobe = (cdf[0] <= target).astype(np.int64)
    for k in range(1, lobes - 1):
        lobe += cdf[k] <= target
    # Never pick a lobe of score 0 (u exactly at a cdf step of an empty lobe).
    flat = np.arange(len(lobe)) * lobes
    chosen_score = scores.ravel().take(flat + lobe)
    bad = chosen_score <= 0
    if bad.any():
        lobe[bad] = np.argmax(scores[bad] > 0, axis=1)
        chosen_score = scores.ravel().take(flat + lobe)
    prob = np.where(total > 0, chosen_score / np.where(total > 0, total, 1.0), 0.0)
    return np.where(total > 0, lobe, -1), prob


def lobe_remainder(scores, u, lobe):
    """(n,) the lobe-choice number ``u`` rescaled within the chosen lobe's share of ``scores``:
    uniform on [0, 1) given the choice, so it can serve as one more random number."""
    lobes = scores.shape[1]
    s = [scores[:, k] for k in range(lobes)]
    before = np.zeros(len(u))
    total = s[0].copy()
    for k in range(1, lobes):
        before += np.where(lobe >= k, s[k - 1], 0.0)
        total += s[k]
    chosen = scores.ravel().take(np.arange(len(u)) * lobes + np.maximum(lobe, 0))
    r = (u * total - before) / np.where(chosen > 0, chosen, 1.0)
    return np.clip(r, 0.0, np.nextafter(1.0, 0.0))


def reflector_albedo(table, lobe, mat_ids, colors, wo, ns):
    """(n, 3) what the glossy or mirror lobe ``lobe`` of ``mat_ids`` with lobe colours ``colors``
    (n, lobes, 3) reflects seen from ``wo``, as Cycles' ``bsdf_albedo`` estimates a microfacet
    closure's: the lobe's weight times its colour, a Fresnel curve's colour taken at the shading
    normal (the smooth surface's), the microfacets' own albedo taken as 1 (Cycles' closures carry
    their energy compensation apart)."""
    colour = colors[:, lobe]
    w = table.weight[:, lobe].take(mat_ids)[:, None]
    if not table.has_fresnel:
        return w * colour
    mu = np.clip(np.abs(dot(wo, ns)), 0.0, 1.0)
    return w * (colour + table.fresnel_color(mat_ids, lobe, mu, colour))


def dielectric_albedos(table, mat_ids, colors, wo, ng, ns):
    """(reflected, transmitted) (n, 3): what the glass lobes (``DIELECTRIC``) of ``mat_ids`` with
    lobe colours ``colors`` (n, lobes, 3) reflect and transmit seen from ``wo``, as Cycles'
    ``bsdf_microfacet_estimate_albedo`` takes a dielectric's (smooth or rough): the Fresnel
    factor F at the shading normal, F times the reflection colour and (1 - F) times the colour,
    times the lobe's weight (a Refraction BSDF's share of F, a film's F by channel; nothing
    transmitted past total internal reflection), the means of :func:`scatter`'s two branches."""
    m = mat_ids
    entering = dot(wo, ng) > 0
    ior = table.ior.take(m)
    eta = np.where(entering, ior, 1.0 / ior)
    fr, cos_t = smp.fresnel_dielectric(np.clip(np.abs(dot(wo, ns)), 0.0, 1.0), eta)
    refracts = np.ones(len(m), bool)
    if table.dielectric_fresnel is not None:
        refracts = cos_t > 0.0
        fr = table.dielectric_fresnel.take(m) * fr
    f = np.repeat(fr[:, None], 3, axis=1)
    if table.has_glass_film:
        film = np.flatnonzero(table.glass_film.take(m))
        if len(film):
            share = (1.0 if table.dielectric_fresnel is None
                     else table.dielectric_fresnel.take(m.take(film))[:, None])
            cos_i = np.clip(np.abs(dot(wo.take(film, axis=0), ns.take(film, axis=0))), 0.0, 1.0)
            f[film] = share * table.glass_film_reflectance(m.take(film), cos_i, entering.take(film))
    weight = table.weight[:, DIELECTRIC].take(m)[:, None]
    reflection = table.reflection.take(m, axis=0) if table.reflection_differs else colors[:, DIELECTRIC]
    return (f * weight * reflection,
            (1.0 - f) * weight * colors[:, DIELECTRIC] * refracts[:, None])


def scatter(table, mat_ids, colors, lobe, prob, wo, ng, ns, u1, u2, mode, u3=None, nn=None, tangent=None):
    """Sample a new direction from the chosen ``lobe`` at n surface points.

    ``u1``, ``u2`` are the direction's random numbers; rough dielectrics need a third, ``u3``
    (e.g. :func:`lobe_remainder`), for the choice between reflection and refraction.

    ``ns is ng`` (flat shading, as :meth:`RenderContext.surface` returns it) skips the
    shading-normal correction, which is then exactly 1.  ``nn``, the normals before a normal map
    (None without normal maps), adds Cycles' bump-map terms (:func:`bump_shadowing`) for photons:
    their light-side direction is ``wo``.  ``tangent`` (n, 3) (``Surface.tangent``) orients the
    anisotropic glossy lobes (``MaterialTable.anisotropic``); None in scenes without them.

    Returns ``(wi (n, 3), weight (n, 3), alive (n,))``: ``weight`` multiplies the
    path throughput; dead paths (absorbed, sampled below the surface, no lobe)
    have ``alive`` False and zero weight.
    """
    n = len(lobe)
    wi = np.zeros((n, 3))
    weight = np.zeros((n, 3))
    alive = np.zeros(n, bool)
    # Normals on the side of wo; the shading normal is flipped to agree with the geometric one.
    ngf = face_forward(ng, wo)
    nsf = ngf if ns is ng else face_forward(ns, ngf)
    nnf = face_forward(nn, ngf) if nn is not None and mode == "importance" else None
    for k in range(table.lobes):
        sel = np.flatnonzero(lobe == k)
        if len(sel) == 0:
            continue
        w_o, n_s, n_g = wo.take(sel, axis=0), nsf.take(sel, axis=0), ngf.take(sel, axis=0)
        m_sel = mat_ids.take(sel)
        lw = (table.weight[:, k].take(m_sel)[:, None] * colors[:, k].take(sel, axis=0)
              / prob.take(sel)[:, None])
        if k in (DIFFUSE, TRANSLUCENT):
            # Lambertian reflection, or transmission (cosine-distributed on the other side).
            out = 1.0 if k == DIFFUSE else -1.0
            if mode == "importance" and ns is not ng:
                # Photons: the exact adjoint of Cycles' lobe, whose value depends on the light's
                # side alone (max(N . wo, 0) / pi, any view on the surface's side): they leave
                # cosine-distributed about the geometric normal, weighing |wo . N_s| / |wo . N_g|,
                # and none where wo lies below the shading normal.
                cos_s = dot(w_o, n_s)
                d = smp.to_world(smp.cosine_hemisphere(u1[sel], u2[sel]), out * n_g)
                ok = cos_s > 0
                w = lw * (np.maximum(cos_s, 0.0) / np.maximum(dot(w_o, n_g), 1e-12))[:, None]
            else:
                d = smp.to_world(smp.cosine_hemisphere(u1[sel], u2[sel]), out * n_s)
                ok = out * dot(d, n_g) > 0
                w = lw
        if k == DIFFUSE:
            if table.has_rough_diffuse:
                r = np.flatnonzero(table.is_rough_diffuse.take(m_sel))
                if len(r):
                    wo_r, d_r, ns_r = w_o.take(r, axis=0), d.take(r, axis=0), n_s.take(r, axis=0)
                    w = w.copy()
                    w[r] *= rough_diffuse_factor(table, m_sel.take(r), colors[sel.take(r), DIFFUSE],
                                                 dot(wo_r, ns_r), dot(d_r, ns_r), dot(wo_r, d_r))
            if table.has_layer:
                # Under a Fresnel layer: a factor of the view (camera-side) direction, as multiscatter.
                view = d if mode == "importance" else w_o
                w = w * table.layer_factor(m_sel, dot(view, n_s))[:, None]
        elif k == GLOSSY:
            ok_o = dot(w_o, n_s) > 1e-9
            wo_l, m, wi_l, d, ratio = _sample_glossy(table, m_sel, w_o, n_s, u1[sel], u2[sel],
                                                     None if tangent is None else tangent.take(sel, axis=0))
            ok = ok_o & (wi_l[:, 2] > 0) & (dot(d, n_g) > 0)
            # Energy compensation is a factor of the view (camera-side) direction: wi for photons.
            view_mu = wi_l[:, 2] if mode == "importance" else wo_l[:, 2]
            if table.has_fresnel:
                lw = lw + (table.weight[:, k].take(m_sel) / prob.take(sel))[:, None] \
                    * table.fresnel_color(m_sel, k, dot(wo_l, m), colors[:, k].take(sel, axis=0))
            w = lw * ratio[:, None] * table.multiscatter(m_sel, view_mu, colors[:, k].take(sel, axis=0))
        elif k == MIRROR:
            d = smp.reflect(w_o, n_s)
            below = dot(d, n_g) <= 0
            if below.any():
                d[below] = smp.reflect(w_o[below], n_g[below])
            ok = dot(d, n_g) > 0
            w = lw
            if table.has_fresnel:
                w = w + (table.weight[:, k].take(m_sel) / prob.take(sel))[:, None] \
                    * table.fresnel_color(m_sel, k, np.abs(dot(w_o, n_s)), colors[:, k].take(sel, axis=0))
        elif k == DIELECTRIC:
            entering = dot(w_o, ng.take(sel, axis=0)) > 0     # wo on the front (outside) of the surface
            ior = table.ior.take(m_sel)
            eta = np.where(entering, ior, 1.0 / ior)
            alpha = table.dielectric_alpha.take(m_sel)
            rough = alpha > 0
            # Rough glass: a GGX microfacet normal from the visible normals of wo (u1, u2), then
            # Fresnel reflection or refraction about it (u3; Walter et al. 2007).  Both branches
            # weigh G2 / G1 (f |cos| / pdf with the branch chosen by F).  Smooth glass chooses
            # the branch with u1.
            h = n_s
            branch = u1[sel]
            if rough.any():
                if u3 is None:
                    raise ValueError("scatter: rough dielectrics need u3")
                r = np.flatnonzero(rough)
                wo_l = smp.to_local(w_o[r], n_s[r])
                wo_l[:, 2] = np.maximum(wo_l[:, 2], 1e-9)
                beckmann = (None if table.dielectric_beckmann is None
                            else table.dielectric_beckmann.take(m_sel.take(r)))
                m_l = smp.sample_visible_normal(wo_l, alpha[r], u1[sel][r], u2[sel][r], beckmann=beckmann)
                h = n_s.copy()
                h[r] = smp.to_world(m_l, n_s[r])
                branch = np.where(rough, u3[sel], branch)
            cos_i = np.clip(dot(w_o, h), 0.0, 1.0)
            fr, cos_t = smp.fresnel_dielectric(cos_i, eta)
            refracts = True
            if table.dielectric_fresnel is not None:
                # Only a share s reflects by Fresnel (s F); the rest refracts but for total internal
                # reflection, where it ends (Cycles' Refraction BSDF).
                refracts = cos_t > 0.0
                fr = table.dielectric_fresnel.take(m_sel) * fr
            film = None
            if table.has_glass_film:
                # A filmed glass reflects F (n, 3) by channel: reflect with its mean p (times s), the
                # weights F / p and (1 - s F) / (1 - s p) (Cycles' pdf_reflect is alike).
                f = np.flatnonzero(table.glass_film.take(m_sel))
                if len(f):
                    film = table.glass_film_reflectance(m_sel.take(f), cos_i.take(f), entering.take(f))
                    share = (1.0 if table.dielectric_fresnel is None
                             else table.dielectric_fresnel.take(m_sel.take(f))[:, None])
                    film = share * film                 # (s F: what reflects by Fresnel)
                    fr[f] = film.mean(axis=1)
            is_refl = branch < fr
            d = np.where(is_refl[:, None], smp.reflect(w_o, h), smp.refract(w_o, h, eta, cos_t))
            side = dot(d, n_g)
            ok = np.where(is_refl, side > 0, (side < 0) & refracts)
            w = lw
            if table.reflection_differs:
                # Reflections take the material's reflection colour, refractions the hit's colour.
                reflected = (table.weight[:, k].take(m_sel)[:, None] * table.reflection.take(m_sel, axis=0)
                             / prob.take(sel)[:, None])
                w = np.where(is_refl[:, None], reflected, w)
            if film is not None:
                p = fr[f][:, None]
                w[f] = w[f] * np.where(is_refl[f][:, None],
                                       np.divide(film, p, out=np.ones_like(film), where=p > 0),
                                       np.divide(1.0 - film, 1.0 - p, out=np.ones_like(film), where=p < 1))
            if rough.any():
                cos_o_s = np.abs(dot(w_o, n_s))
                cos_i_s = dot(d, n_s)
                # The reflected or refracted direction must leave on its side of the macro surface.
                ok &= ~rough | np.where(is_refl, cos_i_s > 0, cos_i_s < 0)
                beckmann = (None if table.dielectric_beckmann is None
                            else table.dielectric_beckmann.take(m_sel))
                ratio = np.where(rough, smp.microfacet_ratio(cos_o_s, np.abs(cos_i_s),
                                                             np.maximum(alpha, MIN_ALPHA), beckmann), 1.0)
                w = w * ratio[:, None]
                if table.has_glass_multiscatter:
                    # Energy compensation, a factor of the camera-side direction (wi for photons)
                    # from its side of the surface (inside: behind the front of ``ng``).
                    view = d if mode == "importance" else w_o
                    inside = dot(view, ng.take(sel, axis=0)) < 0
                    w = w * table.glass_multiscatter(m_sel, np.abs(dot(view, n_s)), inside)
            if mode == "importance":
                # Cycles' convention (see the module docstring): photons going into a denser medium
                # lose 1 / eta^2 of their flux, and gain it back coming out (refraction_scale).
                w = w * np.where(is_refl, 1.0, 1.0 / (eta * eta))[:, None]
        elif k == SHEEN:
            d, w, ok = _scatter_sheen(table, m_sel, lw, w_o, n_s, n_g, u1[sel], u2[sel], mode)
        if table.has_sheen and k != SHEEN:
            # Under a sheen: its factor at the view (camera-side) direction, for photons the new one.
            view = d if mode == "importance" else w_o
            w = w * table.sheen_dim(m_sel, dot(view, n_s))[:, None]
        if mode == "importance" and ns is not ng and k not in (DIFFUSE, TRANSLUCENT):
            w = w * _adjoint_factor(w_o, d, n_g, n_s)[:, None]
        if nnf is not None and (k in REFLECTING or k == SHEEN):
            # (a sheen is one of Cycles' diffuse closures, which take the softening too)
            diffuse, valid = bump_shadowing(nnf.take(sel, axis=0), n_s, w_o)
            if k != GLOSSY:
                # (Bump Map Correction off: the side test alone)
                diffuse = np.where(table.bump_correction.take(m_sel), diffuse, valid)
            w = w * (valid if k == GLOSSY else diffuse)[:, None]
        wi[sel] = d
        weight[sel] = np.where(ok[:, None], w, 0.0)
        alive[sel] = ok
    return smp.normalize(wi), weight, alive


def _scatter_sheen(table, mats, lw, wo, ns, ng, u1, u2, mode):
    """(wi, weight, ok) of the sheen lobe (:func:`sheen_albedo`) of materials ``mats`` at hits of
    normals ``ns``, ``ng`` (on the side of ``wo``), lobe weights ``lw`` (n, 3) (weight times colour
    over the choice's probability).  Camera paths (``wo`` the view) sample the transformed cosine
    itself: weight E(wo).  Photons (``wo`` towards the light) leave cosine-distributed about the
    normal, the new direction being the view: f(wi, wo) |cos| / pdf = E(wi) a^2 / |M^-1 wo|^4 in
    the frame of wi."""
    if mode == "importance":
        wi = smp.to_world(smp.cosine_hemisphere(u1, u2), ns)
        e, a, b = table.sheen_lobe(mats, dot(wi, ns))
        x, y = sheen_frame(wi, ns)
        lz = dot(wo, ns)
        value = sheen_value(a, b, dot(wo, x), dot(wo, y), lz) * np.pi
        ok = (lz > 0) & (dot(wi, ng) > 0) & (e > 0)
        return wi, lw * (e * value)[:, None], ok
    e, a, b = table.sheen_lobe(mats, dot(wo, ns))
    x, y = sheen_frame(wo, ns)
    # A cosine-distributed direction, transformed by M (Cycles' ``bsdf_sheen_sample``).
    c = smp.cosine_hemisphere(u1, u2)
    local = smp.normalize(np.stack([c[:, 0] - c[:, 2] * b, c[:, 1], c[:, 2] * a], axis=1))
    wi = local[:, :1] * x + local[:, 1:2] * y + local[:, 2:] * ns
    ok = (dot(wi, ng) > 0) & (e > 0)
    return wi, lw * e[:, None], ok


def refraction_scale(table, mat_ids, lobe, wo, wi, ng):
    """(n,) the factor by which :func:`scatter` in ``mode="importance"`` scaled each photon for
    Cycles' convention at a refraction, 1 / eta^2 (eta = n_transmitted / n_incident), 1 for
    anything else: a scale of the flux, not a loss, which Russian roulette leaves out (surviving
    photons inside glass would otherwise come out 2.25 times as bright and as rare)."""
    out = np.ones(len(lobe))
    glass = np.flatnonzero(lobe == DIELECTRIC)
    if len(glass):
        n = ng.take(glass, axis=0)
        cos_o = dot(wo.take(glass, axis=0), n)
        through = cos_o * dot(wi.take(glass, axis=0), n) < 0
        ior = table.ior.take(mat_ids.take(glass))
        out[glass] = np.where(through, np.where(cos_o > 0, 1.0 / (ior * ior), ior * ior), 1.0)
    return out


def _sample_glossy(table, mat_ids, wo, ns, u1, u2, tangent):
    """GGX reflection of ``wo`` (k, 3) about ``ns`` (k, 3) for materials ``mat_ids``: ``(wo, m,
    wi)`` local (k, 3) each, ``wi`` in world (k, 3) and the weight G2 / G1.  Anisotropic lobes
    are sampled in the frames of ``tangent`` (k, 3), the others in :func:`~core.sampling.to_local`'s
    (rows of the local arrays in different frames: callers read only z and wo.m)."""
    aniso = table.anisotropic.take(mat_ids) if table.has_anisotropy else None
    beckmann = None if table.glossy_beckmann is None else table.glossy_beckmann.take(mat_ids)
    if aniso is None or not aniso.any():
        return _scatter_isotropic(table.alpha.take(mat_ids), wo, ns, u1, u2, beckmann)
    if tangent is None:
        raise ValueError("scatter: anisotropic glossy lobes need tangents")
    k = len(mat_ids)
    out = (np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty(k))
    a, i = np.flatnonzero(aniso), np.flatnonzero(~aniso)
    rows = lambda x, r: x.take(r, axis=0)                                   # noqa: E731
    ma = mat_ids.take(a)
    part = (lambda r: None) if beckmann is None else beckmann.take          # noqa: E731
    parts = [(a, _scatter_anisotropic(table.alpha_x.take(ma), table.alpha_y.take(ma), rows(wo, a),
                                      rows(ns, a), rows(tangent, a), u1.take(a), u2.take(a), part(a)))]
    if len(i):
        parts.append((i, _scatter_isotropic(table.alpha.take(mat_ids.take(i)), rows(wo, i), rows(ns, i),
                                            u1.take(i), u2.take(i), part(i))))
    for r, part in parts:
        for o, p in zip(out, part):
            o[r] = p
    return out


def _scatter_isotropic(alpha, wo, ns, u1, u2, beckmann=None):
    """:func:`_sample_glossy` of isotropic lobes, in the frames of :func:`~core.sampling.to_local`;
    Beckmann microfacets where the (k,) bool ``beckmann`` is set."""
    wo_l = smp.to_local(wo, ns)
    wo_l[:, 2] = np.maximum(wo_l[:, 2], 1e-9)
    m = smp.sample_visible_normal(wo_l, alpha, u1, u2, beckmann=beckmann)
    wi_l = smp.reflect(wo_l, m)
    ratio = smp.microfacet_ratio(wo_l[:, 2], wi_l[:, 2], alpha, beckmann)
    return wo_l, m, wi_l, smp.to_world(wi_l, ns), ratio


def _scatter_anisotropic(alpha_x, alpha_y, wo, ns, tangent, u1, u2, beckmann=None):
    """Anisotropic GGX (or Beckmann, where ``beckmann`` is set) reflection about ``ns`` (k, 3) in
    the frames of ``tangent`` (k, 3): ``(wo, m, wi)`` local (k, 3) each, ``wi`` in world (k, 3)
    and the weight G2 / G1."""
    x, y = smp.tangent_frames(ns, tangent)
    wo_l = np.stack([dot(wo, x), dot(wo, y), np.maximum(dot(wo, ns), 1e-9)], axis=1)
    m = smp.sample_visible_normal(wo_l, alpha_x, u1, u2, alpha_y, beckmann)
    wi_l = smp.reflect(wo_l, m)
    d = wi_l[:, :1] * x + wi_l[:, 1:2] * y + wi_l[:, 2:] * ns
    lambda_o = smp.microfacet_lambda_aniso(wo_l, alpha_x, alpha_y, beckmann)
    lambda_i = smp.microfacet_lambda_aniso(wi_l, alpha_x, alpha_y, beckmann)
    ratio = (1.0 + lambda_o) / (1.0 + lambda_o + lambda_i)
    return wo_l, m, wi_l, d, ratio


def bump_shadowing(nn, ns, wi):
    """Cycles' bump-map terms for a light-side direction ``wi`` at normal-mapped points.

    nn : (k, 3) the unbent (smooth) normal, ns : (k, 3) the bent one, both on one side; wi : (k, 3).
    Returns ``(diffuse (k,), valid (k,) bool)``: ``valid`` is False where wi and ns lie on opposite
    sides of the smooth surface (no light through the back of opaque geometry; every lobe), and
    ``diffuse`` is the diffuse lobes' factor: 0 there, else the GGX shadowing G1 of wi about nn with
    alpha^2 = min(tan^2(nn, ns) / 8, 1) (Conty Estevez et al. 2019, "A Microfacet-Based Shadowing
    Function to Solve the Bump Terminator Problem"), which darkens the bent normal's light
    towards the smooth surface's terminator.  1 where ns equals nn.
    """
    cos_ni = dot(nn, wi)
    cos_nd = dot(nn, ns)
    valid = ~(cos_ni * cos_nd * dot(ns, wi) < 0.0)
    cos_i = np.abs(cos_ni)
    cos_d = np.minimum(np.abs(cos_nd), 1.0)
    alpha2 = np.minimum(0.125 * (1.0 / np.maximum(cos_d * cos_d, 1e-12) - 1.0), 1.0)
    c2 = np.maximum(cos_i * cos_i, 1e-12)
    g = 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * (1.0 - c2) / c2))
    g = np.where((cos_d >= 1.0) | (cos_i >= 1.0), 1.0, np.where(cos_i < 1e-6, 0.0, g))
    return np.where(valid, g, 0.0), valid


def valid_reflection_normal(ng, i, n):
    """Cycles' ``ensure_valid_specular_reflection``: ``n`` (k, 3), tilted towards the geometric
    normal ``ng`` just enough that the mirror direction of the view ``i`` (k, 3; all on ng's
    side) stays above the surface by min(0.9 i.ng, 0.01).  Cycles gives it to the glossy layers
    of a bump- or normal-mapped surface, seen from ``i``."""
    i_z = dot(i, ng)
    threshold = np.minimum(0.9 * i_z, 0.01)
    r = 2.0 * dot(n, i)[:, None] * n - i
    bad = dot(ng, r) < threshold
    if not bad.any():
        return n
    out = n.copy()
    g, v, nb, t, iz = ng[bad], i[bad], n[bad], threshold[bad], i_z[bad]
    x = smp.normalize(nb - dot(nb, g)[:, None] * g)
    i_x = dot(v, x)
    a = i_x * i_x + iz * iz
    b = 2.0 * (a + iz * t)
    c = (t + iz) ** 2
    root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
    nz2 = np.where(i_x < 0, 0.25 * (b + root), 0.25 * (b - root)) / np.maximum(a, 1e-30)
    out[bad] = np.sqrt(np.maximum(1.0 - nz2, 0.0))[:, None] * x + np.sqrt(np.maximum(nz2, 0.0))[:, None] * g
    return out


def _adjoint_factor(wo, wi, ng, ns):
    """|wo.ns| |wi.ng| / (|wo.ng| |wi.ns|): shading-normal correction for importance transport,
    applied to the throughput after f |wi.ns| / pdf."""
    num = np.abs(dot(wo, ns)) * np.abs(dot(wi, ng))
    den = np.abs(dot(wo, ng)) * np.abs(dot(wi, ns))
    return np.where(den > 1e-12, num / np.maximum(den, 1e-12), 0.0)


def eval_glossy(alpha, wo, wi, ns, with_cos_h=False, beckmann=None):
    """Scalar GGX reflection value f(wo, wi) around the shading normals ``ns`` (side of wo),
    Beckmann's where the (k,) bool ``beckmann`` is set.

    Frame-free: the half vector h = (wo + wi) / |wo + wi| enters through cosines only, with
    |wo + wi| = sqrt(2 + 2 wo.wi), h.n = (wo.n + wi.n) / |wo + wi| and wo.h = |wo + wi| / 2.
    With ``with_cos_h`` also returns wo.h (the microfacet cosine of the Fresnel factor)."""
    cos_o, cos_i = dot(wo, ns), dot(wi, ns)
    len_h = np.sqrt(np.maximum(2.0 + 2.0 * dot(wo, wi), 1e-24))
    if beckmann is None or not beckmann.any():
        g2 = smp.ggx_g2(cos_o, cos_i, alpha)
    else:
        g2 = 1.0 / (1.0 + smp.microfacet_lambda(cos_o, alpha, beckmann)
                    + smp.microfacet_lambda(cos_i, alpha, beckmann))
    f = smp.microfacet_d((cos_o + cos_i) / len_h, alpha, beckmann) * g2 \
        / np.maximum(4.0 * cos_o * cos_i, 1e-12)
    f = np.where((cos_o > 0) & (cos_i > 0), f, 0.0)
    return (f, 0.5 * len_h) if with_cos_h else f


def glossy_anisotropic_value(alpha_x, alpha_y, cos_o, cos_i, cos_oi, wo_x, wi_x, beckmann=None):
    """(f, wo.h): :func:`eval_glossy` of anisotropic GGX (Cycles' ``bsdf_aniso_D`` and
    ``bsdf_aniso_lambda``; Beckmann's where ``beckmann`` is set) from cosines of unit
    directions: wo and wi with the normal
    (``cos_o``, ``cos_i``), with each other and with the unit tangent x in the normal's plane
    (:func:`~core.sampling.tangent_axes`; alpha_x lies along it).
    Frame-free as :func:`eval_glossy`: a direction's component along y = n x x squared is
    1 - (its z)^2 - (its x)^2, and the half vector's components are the sums over |wo + wi|."""
    len_h = np.sqrt(np.maximum(2.0 + 2.0 * cos_oi, 1e-24))
    h_n, h_x = (cos_o + cos_i) / len_h, (wo_x + wi_x) / len_h
    h_y2 = np.maximum(1.0 - h_n * h_n - h_x * h_x, 0.0)
    t = h_x * h_x / (alpha_x * alpha_x) + h_y2 / (alpha_y * alpha_y) + h_n * h_n
    d = np.where(h_n > 0, 1.0 / (np.pi * alpha_x * alpha_y * t * t), 0.0)
    some = beckmann is not None and beckmann.any()
    if some:
        # Beckmann: exp(-(hx^2 / ax^2 + hy^2 / ay^2) / hn^2) / (pi ax ay hn^4)
        d_b = smp.beckmann_exp(h_n * h_n, t - h_n * h_n) / (np.pi * alpha_x * alpha_y)
        d = np.where(beckmann, np.where(h_n > 0, d_b, 0.0), d)

    def lam(c, v_x):
        c2 = np.maximum(c * c, 1e-300)
        v_y2 = np.maximum(1.0 - c * c - v_x * v_x, 0.0)
        s = (alpha_x * alpha_x * v_x * v_x + alpha_y * alpha_y * v_y2) / c2
        ggx = 0.5 * (np.sqrt(1.0 + s) - 1.0)
        return np.where(beckmann, smp.beckmann_lambda_of(s), ggx) if some else ggx
    f = d / (1.0 + lam(cos_o, wo_x) + lam(cos_i, wi_x)) / np.maximum(4.0 * cos_o * cos_i, 1e-12)
    return np.where((cos_o > 0) & (cos_i > 0), f, 0.0), 0.5 * len_h

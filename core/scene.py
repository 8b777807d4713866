"""Scene description: a structure of NumPy arrays that the renderer consumes.

Everything the core needs arrives through :class:`Scene`; the Blender exporter
(``amcmcppm_addon/export``) and the built-in test scenes (``core/testing``) both
build one.  All positions and directions are in one right-handed world space
(Blender's, Z up, metres); all colours are linear Rec.709 RGB.

Units follow Cycles (see ``shared/docs/blender.md`` section 3):

* lights carry their emitted power in watts (RGB, colour already applied),
  the sun its irradiance in W/m^2;
* emissive materials and the world carry radiance in W/(m^2 sr).

Glossary: ``T`` triangles, ``V`` vertices, ``M`` materials, ``L`` lights,
``K`` image textures.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from . import procedural
from .bsdf import DISTRIBUTION_BECKMANN, DISTRIBUTION_GGX, TANGENT_RADIAL_Z, TANGENT_UV


class SceneError(ValueError):
    """A scene that cannot be rendered; the message says which field is wrong."""


# Light kinds (values of ``Lights.kind``).
POINT, SPOT, AREA_RECT, AREA_DISK, SUN = 0, 1, 2, 3, 4
# Camera.projection: the panoramic ones are Cycles' panorama types of the same names.
PANORAMAS = ("equirectangular", "fisheye_equidistant", "fisheye_equisolid", "mirrorball")
PROJECTIONS = ("perspective", "orthographic") + PANORAMAS
# Cycles' Film > Pixel Filter types (Camera.pixel_filter).
PIXEL_FILTERS = ("box", "gaussian", "blackman_harris")
LIGHT_KIND_NAMES = {POINT: "point", SPOT: "spot", AREA_RECT: "area (rectangle)",
                    AREA_DISK: "area (disk/ellipse)", SUN: "sun"}
# Bits of ``Lights.visibility``: which camera rays see a light (Blender's ray visibility).
VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION = 1, 2, 4
# Scene.triangle_visibility: the triangle's object is a holdout (Blender's Object > Visibility >
# Mask > Holdout): camera rays that meet it directly cut its pixel out (Materials.holdout).
HOLDOUT_OBJECT = 8
# Scene.triangle_visibility: the triangle's object casts no shadow (Blender's Ray Visibility >
# Shadow off): photons on their way from their emitter pass it or stop there, each with probability
# 1/2 and twice the flux (as a triangle that shadow linking says does not shadow their emitter).
CASTS_NO_SHADOW = 16
# Scene.triangle_visibility: the triangle's object is a shadow catcher (Blender's Object >
# Visibility > Mask > Shadow Catcher, ``core/shadow_catcher.py``): camera rays that meet it first
# show the image without it and the shadows and light the other objects cast on it.
SHADOW_CATCHER = 32
DEFAULT_LIGHT_VISIBILITY = VISIBLE_GLOSSY | VISIBLE_TRANSMISSION     # Blender's default for lights
# Materials.normal_space: the Normal Map node's Space (its colour 2 c - 1 is a direction along the
# UV map's tangent frame, or in object or world space; the Blender variants flip its y and z).
NORMAL_TANGENT, NORMAL_OBJECT, NORMAL_WORLD, NORMAL_BLENDER_OBJECT, NORMAL_BLENDER_WORLD = range(5)
# Materials.displacement_flags: the offset is in world units (the Displacement node's World space,
# else the object's), the shading normals stay (Displacement and Bump) rather than follow it, and
# the program gives the offset as a world vector (a Vector Displacement) rather than along the normal.
DISPLACE_WORLD, DISPLACE_KEEPS_NORMALS, DISPLACE_VECTOR = 1, 2, 4
# Materials.subsurface_method: Cycles' Random Walk (mean free paths of the radius over 4 pi, a
# refractive entry of the material's roughness) or Random Walk (Skin) (mean free paths scaled by
# the albedo through the dipole, half the entries diffuse, the other half refracted at alpha 1).
SUBSURFACE_RANDOM_WALK, SUBSURFACE_SKIN = 0, 1
# The rays an emitter does not light (``Lights.exclude``, ``World.exclude``, ``Scene.emitter_exclude``;
# Blender's Ray Visibility boxes Glossy, Transmission, Diffuse and Volume Scatter off, Cycles'
# SHADER_EXCLUDE_*): the light that first meets a surface or volume reaches no lobe of that kind
# there.  Diffuse: the diffuse and translucent lobes; glossy: glossy, mirror, a coat and a glass's
# reflection; transmission: a glass's refraction; scatter: a volume's scattering.  The glossy and
# transmission bits are those of the rays (VISIBLE_*) that then see nothing of a world past the scene.
EXCLUDE_GLOSSY, EXCLUDE_TRANSMISSION = VISIBLE_GLOSSY, VISIBLE_TRANSMISSION
EXCLUDE_DIFFUSE, EXCLUDE_SCATTER = 8, 16
EXCLUDE_ALL = EXCLUDE_GLOSSY | EXCLUDE_TRANSMISSION | EXCLUDE_DIFFUSE | EXCLUDE_SCATTER
# Light and shadow linking (Scene.receiver_sets, Scene.blocker_sets and the emitters' links): an
# emitter whose mask has every bit set lights every receiver set, or is shadowed by every blocker set.
ALL_LINKS = np.uint64(0xFFFFFFFFFFFFFFFF)
MAX_RECEIVER_SETS = 64


def linked(links, sets):
    """(n,) bool: whether emitters of ``links`` (n,) uint64 (or one) light (or are shadowed by)
    the sets ``sets`` (n,): bit s of the links."""
    return ((np.asarray(links, np.uint64) >> np.asarray(sets).astype(np.uint64)) & np.uint64(1)).astype(bool)


def _f32(a, shape_tail=()):
    return np.ascontiguousarray(np.asarray(a, dtype=np.float32).reshape((-1,) + shape_tail))


@dataclass
class Materials:
    """Per-material lobe weights and parameters, shape ``(M, ...)``.

    A material is a weighted sum of lobes.  Each ``*_weight`` is the mixing weight
    of a lobe (Blender's Mix/Add node factors multiplied out); weights normally sum
    to at most 1.  Lobes:

    * diffuse: Lambertian, albedo ``diffuse_color`` or, when ``diffuse_texture``
      is >= 0, that image texture looked up with the triangle UVs, or, when
      ``diffuse_program`` is >= 0, that entry of ``programs`` (a tree of Blender's texture
      and colour nodes, ``core/procedural.py``) evaluated at the hit, times ``diffuse_color``;
      ``diffuse_roughness`` > 0 makes it Cycles' rough diffuse (Blender's Diffuse BSDF Roughness,
      Principled's Diffuse Roughness): Fujii's improved Oren-Nayar with the OpenPBR energy
      compensation (``bsdf.rough_diffuse_factor``);
    * glossy: GGX microfacet reflection (Beckmann's where ``glossy_distribution`` is
      ``bsdf.DISTRIBUTION_BECKMANN``, single scattering), ``glossy_roughness`` is Blender's
      roughness (alpha = roughness^2); roughness below 0.02 acts as a mirror.  A
      ``roughness_program`` (when >= 0; a float program) gives the roughness at each hit instead
      (a roughness map), rounded to one of ``bsdf.ROUGHNESS_LEVELS`` levels in [0, 1].  Its colour
      ``glossy_color`` is multiplied by the program ``glossy_program`` (when >= 0) at each hit;
      such a lobe has no Fresnel rise.
      ``glossy_multiscatter`` is the lobe's mean Fresnel colour F_ss for the energy that
      scatters between microfacets more than once (Cycles' Multiscatter GGX, the default of
      Blender's glossy nodes): a white lobe with F_ss = 1 then reflects all the light it
      receives; 0 gives plain single-scattering GGX, which darkens with roughness.
      ``glossy_fresnel_ior`` > 0 makes part of the lobe a dielectric interface (Principled's
      specular layer): at microfacet cosine c it reflects ``glossy_color`` +
      ``glossy_fresnel_rise`` s(c), s = saturate((F(c) - F0) / (1 - F0)) with the real
      dielectric Fresnel F of that IOR, so the layer's reflectance rises from its normal-incidence
      colour to 1 at grazing angles (Cycles' Principled BSDF).  The diffuse lobe then lies
      *under* that layer: its weight is scaled by 1 - the largest channel of the layer's albedo
      at the view direction, the layer reflecting ``diffuse_layer`` (its normal-incidence colour
      f0 * specular tint) + (1 - ``diffuse_layer``) s averaged over the lobe (Cycles'
      ``closure_layering_weight``); ``diffuse_layer_weight`` is the share of the diffuse lobe
      under the layer (a Principled mixed with a plain Diffuse: the rest keeps its weight).
      ``film_thickness`` > 0.1 (nm; Cycles' cut-off) coats that layer with a thin film of index
      ``film_ior`` (Principled's Thin Film; no layer without ``glossy_fresnel_ior``): the layer, of
      share k = ``glossy_fresnel_rise`` / (1 - f0 t) of the lobe (f0 = F0 of ``glossy_fresnel_ior``,
      t = ``film_tint``, the specular tint), then reflects k G(c) in place of k (f0 t + (1 - f0 t)
      s(c)), G the film's interference colour scaled towards f0 t
      (:func:`core.thin_film.principled_reflectance`), and the diffuse lobe under it takes G at the
      view cosine for the layer's albedo (Cycles has no lobe mean for a film).  The glass lobe
      of such a material takes the film too (Principled glass): it reflects its reflection colour
      times G by channel in place of times F (the film's and the glass's indices relative to the
      side the light comes from, as Cycles, with F0 of ``ior``), and refracts 1 - G.
      ``film_metal`` k > 0 puts the film over the lobe's metal as well (its metal curve, of share
      k: F0 = 1 - ``glossy_metal_rise`` / k, b = ``glossy_metal_dip`` / k), which then reflects k
      G_m(c) in place of its curve (:func:`core.thin_film.conductor_reflectance`), or, where
      ``film_metal_ior`` n > 0, the film over a physical conductor of complex index n + i
      ``film_metal_extinction`` (Cycles' Metallic BSDF: its own polarised Fresnel under the film,
      :func:`core.thin_film.physical_conductor_reflectance`; the curve stays its F82 fit).
      ``glossy_metal_rise`` and ``glossy_metal_dip`` give a metal's Fresnel curve (Cycles'
      F82-tint model): at microfacet cosine c the lobe reflects ``glossy_color`` +
      ``glossy_metal_rise`` (1 - c)^5 - ``glossy_metal_dip`` c (1 - c)^6, kept within [0, 1]
      (F0 = the colour, rise = 1 - F0, dip = b of ``fresnel_f82tint_B``); either may sit beside
      a dielectric rise (a Principled BSDF partly metallic), the parts adding up.
      ``glossy_metal_tint`` >= 0 (an edge tint in [0, 1]; -1: none) makes the lobe a metal whose
      F0 is its colour at each hit (``glossy_color`` times ``glossy_program``: a textured metal):
      it reflects that curve with rise 1 - F0 and dip b(F0, tint) of the hit's own F0, so a
      textured metal brightens towards grazing angles point by point (the rise and dip above
      are then 0).  ``glossy_metal_share`` k < 1 makes such a metal only part of the lobe, beside
      a dielectric layer (a Principled BSDF partly metallic with a textured base colour): the
      colour and program then give F0, and the lobe's colour at a hit is k F0 +
      ``glossy_metal_rest`` (the layer's normal-incidence colour); it reflects k times the
      metal's curve of that F0 plus the rest and its Fresnel rise (``glossy_fresnel_ior``,
      ``glossy_fresnel_rise``), and ``glossy_multiscatter`` is then the rest's F_ss (the two
      F_ss are weighted by the parts' mean reflectances).
      ``glossy_stretch`` s != 1 makes the lobe anisotropic (Blender's Anisotropy): alpha s along
      a tangent and alpha / s across it (each at most 1), the tangent from ``glossy_tangent``
      (``bsdf.TANGENT_*``: around the object's X, Y or Z axis (Z, 2, is Blender's default) from
      the Generated coordinates, or 3, the UV map's ``Scene.tangents``) turned about the normal
      by ``glossy_rotation`` turns, or by the float program ``rotation_program`` (when >= 0) at
      each hit (a rotation map, e.g. spun metal).  A ``stretch_program`` (when >= 0; a float
      program) gives s at each hit instead (an anisotropy map), clamped to [0.01, 100] and
      rounded to one of ``bsdf.STRETCH_LEVELS`` levels even in log s (at most 3.7 % off); a
      material that also has a ``roughness_program`` keeps ``glossy_stretch``.  Cycles' Glossy
      BSDF of Anisotropy a has s = 1 - a for a >= 0 and 1 / (1 + a) below; Principled's
      s = 1 / sqrt(1 - 0.9 a);
    * translucent: Lambertian transmission (Blender's Translucent BSDF), colour
      ``translucent_color`` times the program ``translucent_program`` (when >= 0) at each hit:
      light that arrives on one side leaves the other side with a cosine distribution,
      f = colour / pi;
    * mirror: perfect specular reflection tinted by ``mirror_color``;
    * dielectric: glass with index of refraction ``ior``, Fresnel
      reflection/refraction and total internal reflection, tinted by
      ``dielectric_color`` (as Cycles' Glass colour; reflections by
      ``dielectric_reflection_color`` where that differs, as Principled's white specular
      over its tinted transmission); the transmitted colour is multiplied by the program
      ``dielectric_program`` (when >= 0) at each hit (stained glass), the reflected one is not;
      smooth, or rough with GGX microfacets (Beckmann's where ``dielectric_distribution`` is
      ``bsdf.DISTRIBUTION_BECKMANN``, single scattering; the Refraction BSDF's default) of Blender
      roughness ``dielectric_roughness`` (single scattering, or with ``dielectric_multiscatter``
      F_ss > 0 Cycles' Multiscatter GGX glass: the energy compensation 1 + F_ms (1 - E) / E of
      the glass's albedo E at the camera-side cosine, from that side); -1 there takes the roughness
      map's value at each hit (``roughness_program``, which then varies both lobes' roughness:
      Principled's one Roughness, a Glass BSDF's roughness map); ``dielectric_fresnel`` s is the
      share of the lobe that reflects by Fresnel: the rest refracts whatever the Fresnel
      reflectance (Blender's Refraction BSDF, nothing under total internal reflection), so it
      reflects s F and refracts 1 - s F;
    * emission: radiance ``emission`` in W/(m^2 sr), emitted from both sides, times the
      program ``emission_program`` (when >= 0) at each point (a textured emitter).

    Transparency (Principled's Alpha, a Transparent BSDF mixed in): the surface is the material
    above with probability ``opacity`` (or the float program ``opacity_program`` at the hit,
    when >= 0: an alpha map), and otherwise lets the ray through unchanged, tinted by
    ``transparent_color`` (``RenderContext.trace``; Cycles' stochastic transparency).  The lobe
    weights and emission describe the opaque part alone.

    A coat (Principled's Coat) lies over all of that: a GGX dielectric interface of weight
    ``coat_weight`` (0: none), Blender roughness ``coat_roughness`` and index ``coat_ior``, which
    reflects ``coat_weight`` F(c) at microfacet cosine c (the real dielectric Fresnel, with
    multiscatter energy compensation; untinted).  Everything under it (every lobe and the
    emission) is scaled at the view direction's cosine mu with the surface normal before normal
    and bump maps (which do not bend the coat) by
    (1 - ``coat_weight`` K(mu) (F0 + (1 - F0) S(mu))) (1 - ``coat_weight`` + ``coat_weight``
    ``coat_tint`` ^ (1 / cos_t(mu))), as Cycles: the coat's albedo at mu (K and S as for the
    Fresnel layer above) and the tint of a path through the coat refracted to cos_t.

    A sheen (Principled's Sheen, Blender's Sheen BSDF; Cycles' microfiber sheen of Zeltner et
    al. 2022, ``bsdf.sheen_albedo``) of colour ``sheen_color`` (0: none) and roughness
    ``sheen_roughness`` reflects ``sheen_color`` E(mu) of the light, E its directional albedo at
    the view cosine mu, in a lobe towards grazing views; ``sheen_cover`` k lays it over the rest
    of the material: every other lobe, the coat and the emission are scaled by (1 - k E(mu)),
    clamped to [0, 1] (Cycles' layering of the Principled's sheen: k the largest channel of its
    weight times tint; 0 for the Sheen BSDF, which is no layer).

    A volume (Blender's Volume Absorption, Principled Volume's absorption) fills the mesh:
    ``volume_absorption`` (per channel, per scene unit of length; 0: none) scales light along a
    path segment inside it by exp(-``volume_absorption`` length), Beer-Lambert without
    scattering.  A path is inside the material whose surface it last went into (refracted or
    crossed as transparent towards the back of the triangles), and inside it when it meets that
    material's surface from the back (a path that starts inside: a camera or lamp in the water).
    A material with no surface (opacity 0) and a volume is Cycles' volume-only mesh.
    ``volume_scattering`` (per channel, per length; 0: none) makes the volume scatter light as
    well (Volume Scatter, Principled Volume): light is lost to extinction ``volume_absorption``
    + ``volume_scattering`` along a segment, and scattered with the Henyey-Greenstein phase
    function of ``volume_anisotropy`` g in (-1, 1) (0: isotropic; > 0: forwards).
    ``volume_emission`` (per channel, radiance per length; 0: none) makes it glow (Principled
    Volume's emission, an Emission shader on the Volume output): every length ds of a path inside
    adds ``volume_emission`` ds of radiance, itself attenuated by what lies between, and the
    volume emits 4 pi ``volume_emission`` V watts (V its mesh's volume) as photons, evenly in
    all directions.  It is a volume on its own (a glowing gas that neither absorbs nor scatters).

    A material may stand for a family of others picked point by point (a Principled BSDF's
    Metallic map, a Mix Shader's mask): where ``level_program`` >= 0, that float program's value p
    at a hit, clamped to [0, 1], picks one of ``level_count`` consecutive materials from
    ``level_first`` on (its levels, themselves without a ``level_program``), which then shades the
    hit in its place (its lobes, maps and coat; the material itself keeps what is decided before
    shading: its emission, opacity, volume and holdout, which its levels should share).  With
    p (``level_count`` - 1) = i + t, level i + 1 with probability t and level i otherwise (a
    random number per hit: the camera path's, or a hash of the photon path's primary sample), so
    the expected material is linear in p: with two levels, exactly their mix by p, whatever they
    hold (Cycles' Mix Shader).

    ``holdout`` (Blender's Holdout shader, in [0, 1]) is the share of a pixel that the surface
    cuts out of the image where camera rays meet it directly or through transparent surfaces
    (Cycles: whether the film is transparent or not): the pixel's alpha loses holdout times the
    ray's weight, and at 1 the path ends there (no colour, no emission).  Its lobes (what the rest
    of a Mix with a Holdout leaves) shade the pixel as usual, and every other ray and photon sees
    only them.

    A tangent-space normal map (Blender's Normal Map node) bends the shading normal of every
    lobe: ``normal_texture`` >= 0 is the image (non-colour data, RGB in [0, 1] meaning
    2 c - 1 along tangent, bitangent and normal), looked up with the triangle UVs in the frame of
    ``Scene.tangents``, with ``normal_strength`` as in Cycles (tangent-plane components times
    the strength, the normal component blended from 1).  With ``normal_space`` another than
    NORMAL_TANGENT, 2 c - 1 is the normal itself in the object's space (through its normal matrix)
    or in world space (Blender's variants: y and z flipped), blended from the surface's normal by
    the strength where it is not 1 (Cycles' ``svm_node_normal_map``).  A bump map (Blender's Bump node) then
    bends it further: ``bump_texture`` >= 0 is the image whose luminance is the height,
    ``bump_distance`` its scale (negative: inverted) and ``bump_strength`` the blend towards
    the bumped normal, as Cycles' Bump node with the height's exact surface gradient; or
    ``bump_program`` >= 0, a float program of the height (a procedural bump), whose gradient is
    taken by finite differences along the triangle's edges.  Before both, ``normal_program`` >= 0
    is a vector program whose value, normalised, is the shading normal (a BSDF's Normal input fed
    by a Bevel node or any vector: Cycles' ``safe_normalize_fallback`` to the surface's own).

    True displacement (Blender's Displacement Method Displacement Only, or Displacement and Bump):
    ``displacement_program`` >= 0 is a float program of the offset of the material's vertices
    along their normal ((Height - Midlevel) Scale), in the object's space or, with bit
    DISPLACE_WORLD of ``displacement_flags``, in world units (with DISPLACE_VECTOR a vector
    program of the world offset itself); bit DISPLACE_KEEPS_NORMALS keeps the
    shading normals (Displacement and Bump, whose bump bends them), else they follow the displaced
    surface (``displacement.displace``, before each render).

    A coat (``coat_weight``) takes the surface's normal before all of those, unless it has its own
    (Principled's Coat Normal): ``coat_normal_program`` >= 0 gives it as ``normal_program`` does,
    and ``coat_bump_program`` >= 0, with ``coat_bump_strength`` and ``coat_bump_distance``, then
    bends it as ``bump_program`` does.
    """

    names: list = field(default_factory=list)          # M material names (for messages)
    diffuse_weight: np.ndarray = None                   # (M,) float32
    diffuse_color: np.ndarray = None                    # (M, 3) float32, linear albedo
    diffuse_texture: np.ndarray = None                  # (M,) int32, index into Scene.textures or -1
    glossy_weight: np.ndarray = None                    # (M,) float32
    glossy_color: np.ndarray = None                     # (M, 3) float32
    glossy_roughness: np.ndarray = None                 # (M,) float32 in [0, 1]
    glossy_multiscatter: np.ndarray = None              # (M, 3) float32 in [0, 1]; None: glossy_color
    glossy_fresnel_ior: np.ndarray = None               # (M,) float32, 0 = no Fresnel; None: 0
    glossy_fresnel_rise: np.ndarray = None              # (M, 3) float32; None: 0
    glossy_metal_rise: np.ndarray = None                # (M, 3) float32 >= 0; None: 0
    glossy_metal_dip: np.ndarray = None                 # (M, 3) float32, any sign; None: 0
    glossy_metal_tint: np.ndarray = None                # (M, 3) float32 in [0, 1] or -1 (none); None: -1
    glossy_metal_share: np.ndarray = None               # (M,) float32 in (0, 1]; None: 1
    glossy_metal_rest: np.ndarray = None                # (M, 3) float32 in [0, 1]; None: 0
    glossy_stretch: np.ndarray = None                   # (M,) float32 in [0.01, 100]; None: 1 (isotropic)
    glossy_rotation: np.ndarray = None                  # (M,) float32 turns, any sign; None: 0
    glossy_tangent: np.ndarray = None                   # (M,) int32 bsdf.TANGENT_*; None: 2 (radial Z)
    diffuse_layer: np.ndarray = None                    # (M, 3) float32 in [0, 1]; None: 0
    diffuse_layer_weight: np.ndarray = None             # (M,) float32 in [0, 1]; None: 1
    diffuse_roughness: np.ndarray = None                # (M,) float32 in [0, 1]; None: 0 (Lambert)
    mirror_weight: np.ndarray = None                    # (M,) float32
    mirror_color: np.ndarray = None                     # (M, 3) float32
    dielectric_weight: np.ndarray = None                # (M,) float32
    dielectric_color: np.ndarray = None                 # (M, 3) float32
    dielectric_roughness: np.ndarray = None             # (M,) float32 in [0, 1] or -1 (the roughness
    #                                                     program's); None: 0 (smooth)
    dielectric_reflection_color: np.ndarray = None      # (M, 3) float32; None: dielectric_color
    dielectric_fresnel: np.ndarray = None               # (M,) float32 in [0, 1]; None: 1
    dielectric_multiscatter: np.ndarray = None          # (M, 3) float32 in [0, 1]; None: 0 (single)
    glossy_distribution: np.ndarray = None              # (M,) int32 bsdf.DISTRIBUTION_*; None: 0 (GGX)
    dielectric_distribution: np.ndarray = None          # (M,) int32 bsdf.DISTRIBUTION_*; None: 0 (GGX)
    displacement_program: np.ndarray = None             # (M,) int32, index into programs or -1; None: -1
    displacement_flags: np.ndarray = None               # (M,) int32 DISPLACE_* bits; None: 0
    # 1 where the bump is the Displacement output's (Bump Only, Displacement and Bump): it replaces
    # the surface's own normal (Cycles' Set Normal), so the bump-map terms leave it alone.
    displacement_bump: np.ndarray = None                # (M,) int32 0 or 1; None: 0
    # 0 where Blender's Bump Map Correction is off: the bump-map terms keep only their side test
    # (no softening of the diffuse terminator, no valid reflection for glossy lobes).
    bump_correction: np.ndarray = None                  # (M,) int32 0 or 1; None: 1
    film_thickness: np.ndarray = None                   # (M,) float32 in [0, 1e6] nm; None: 0 (none)
    film_ior: np.ndarray = None                         # (M,) float32 in [1e-5, 100]; None: 1.33
    film_tint: np.ndarray = None                        # (M, 3) float32 in [0, 1]; None: 1
    film_metal: np.ndarray = None                       # (M,) float32 in [0, 1]; None: 0
    film_metal_ior: np.ndarray = None                   # (M, 3) float32 in [0, 100]; None: 0 (F82)
    film_metal_extinction: np.ndarray = None            # (M, 3) float32 in [0, 100]; None: 0
    # Subsurface scattering (Cycles' random walk, ``core/subsurface.py``): the share of the diffuse
    # lobe that enters the surface (Principled's Subsurface Weight; 1 for the Subsurface Scattering
    # BSDF), walks inside the object with the lobe's colour as its albedo and mean free paths of
    # ``subsurface_radius`` (scene units, Radius times Scale) and leaves it as diffuse light.
    subsurface_weight: np.ndarray = None                # (M,) float32 in [0, 1]; None: 0
    subsurface_radius: np.ndarray = None                # (M, 3) float32 >= 0; None: 1
    subsurface_anisotropy: np.ndarray = None            # (M,) float32 in [0, 0.9]; None: 0
    subsurface_ior: np.ndarray = None                   # (M,) float32 in [1.01, 3.8]; None: 1.4
    subsurface_alpha: np.ndarray = None                 # (M,) float32 GGX alpha of the entry; None: 1
    subsurface_method: np.ndarray = None                # (M,) int32 SUBSURFACE_*; None: random walk
    ior: np.ndarray = None                              # (M,) float32, > 0
    emission: np.ndarray = None                         # (M, 3) float32 radiance
    normal_texture: np.ndarray = None                   # (M,) int32, index into Scene.textures or -1
    normal_strength: np.ndarray = None                  # (M,) float32 >= 0; None: 1
    normal_space: np.ndarray = None                     # (M,) int32 NORMAL_*; None: NORMAL_TANGENT
    bump_texture: np.ndarray = None                     # (M,) int32, index into Scene.textures or -1
    bump_strength: np.ndarray = None                    # (M,) float32 >= 0; None: 1
    bump_distance: np.ndarray = None                    # (M,) float32, any sign; None: 1
    diffuse_program: np.ndarray = None                  # (M,) int32, index into programs or -1; None: -1
    glossy_program: np.ndarray = None                   # (M,) int32, index into programs or -1; None: -1
    emission_program: np.ndarray = None                 # (M,) int32, index into programs or -1; None: -1
    roughness_program: np.ndarray = None                # (M,) int32, index into programs or -1; None: -1
    dielectric_program: np.ndarray = None               # (M,) int32, index into programs or -1; None: -1
    bump_program: np.ndarray = None                     # (M,) int32, index into programs or -1; None: -1
    # A second Bump over the first (Blender's Bump whose Normal is another Bump): its height program,
    # strength and distance, applied to the normal the first one made.
    outer_bump_program: np.ndarray = None               # (M,) int32, index into programs or -1; None: -1
    outer_bump_strength: np.ndarray = None              # (M,) float32 >= 0; None: 1
    outer_bump_distance: np.ndarray = None              # (M,) float32, any sign; None: 1
    normal_program: np.ndarray = None                   # (M,) int32, index into programs or -1; None: -1
    opacity: np.ndarray = None                          # (M,) float32 in [0, 1]; None: 1
    opacity_program: np.ndarray = None                  # (M,) int32, index into programs or -1; None: -1
    transparent_color: np.ndarray = None                # (M, 3) float32; None: 1
    coat_weight: np.ndarray = None                      # (M,) float32 in [0, 1]; None: 0
    coat_roughness: np.ndarray = None                   # (M,) float32 in [0, 1]; None: 0.03
    coat_ior: np.ndarray = None                         # (M,) float32 >= 1; None: 1.5
    coat_tint: np.ndarray = None                        # (M, 3) float32 in [0, 1]; None: 1
    coat_normal_program: np.ndarray = None              # (M,) int32, index into programs or -1; None: -1
    coat_bump_program: np.ndarray = None                # (M,) int32, index into programs or -1; None: -1
    coat_bump_strength: np.ndarray = None               # (M,) float32 >= 0; None: 1
    coat_bump_distance: np.ndarray = None               # (M,) float32, any sign; None: 1
    volume_absorption: np.ndarray = None                # (M, 3) float32 >= 0, 1 / length; None: 0
    volume_scattering: np.ndarray = None                # (M, 3) float32 >= 0, 1 / length; None: 0
    volume_anisotropy: np.ndarray = None                # (M,) float32 in (-1, 1); None: 0
    volume_phase: np.ndarray = None                     # (M,) int32 phase.PHASE_NAMES index; None: 0 (HG)
    volume_phase_params: np.ndarray = None              # (M, 3) float32 >= 0 (phase.resolve); None: 0
    volume_emission: np.ndarray = None                  # (M, 3) float32 >= 0, radiance / length; None: 0
    holdout: np.ndarray = None                          # (M,) float32 in [0, 1]; None: 0
    sheen_color: np.ndarray = None                      # (M, 3) float32 >= 0; None: 0 (no sheen)
    sheen_roughness: np.ndarray = None                  # (M,) float32 in [0, 1]; None: 0.5
    sheen_cover: np.ndarray = None                      # (M,) float32 >= 0; None: 0
    pass_index: np.ndarray = None                       # (M,) float32 >= 0 (Material Index pass); None: 0
    translucent_weight: np.ndarray = None               # (M,) float32; None: 0
    translucent_color: np.ndarray = None                # (M, 3) float32; None: 0
    translucent_program: np.ndarray = None              # (M,) int32, index into programs or -1; None: -1
    rotation_program: np.ndarray = None                 # (M,) int32, index into programs or -1; None: -1
    stretch_program: np.ndarray = None                  # (M,) int32, index into programs or -1; None: -1
    level_program: np.ndarray = None                    # (M,) int32, index into programs or -1; None: -1
    level_first: np.ndarray = None                      # (M,) int32, a material index or -1; None: -1
    level_count: np.ndarray = None                      # (M,) int32 >= 0; None: 0
    programs: list = field(default_factory=list)        # procedural colour programs (node dicts)
    # Shader AOVs (AOV Output nodes; Cycles writes them at the surfaces camera rays reach, as the
    # Normal pass): A names; per material and AOV whether it writes it, its constant value (a
    # colour, or a number repeated) and a program of it (index into programs, or -1: the constant).
    aov_names: list = field(default_factory=list)
    aov_writes: np.ndarray = None                       # (M, A) bool; None: none
    aov_value: np.ndarray = None                        # (M, A, 3) float32
    aov_program: np.ndarray = None                      # (M, A) int32

    ARRAY_FIELDS = ("diffuse_weight", "diffuse_color", "diffuse_texture", "glossy_weight",
                    "glossy_color", "glossy_roughness", "glossy_multiscatter", "glossy_fresnel_ior",
                    "glossy_fresnel_rise", "glossy_metal_rise", "glossy_metal_dip", "diffuse_layer",
                    "diffuse_layer_weight", "mirror_weight",
                    "mirror_color", "dielectric_weight", "dielectric_color", "dielectric_roughness",
                    "dielectric_reflection_color", "ior", "emission", "normal_texture", "normal_strength",
                    "bump_texture", "bump_strength", "bump_distance", "diffuse_program", "glossy_program",
                    "emission_program", "roughness_program", "dielectric_program", "bump_program", "opacity",
                    "opacity_program", "transparent_color", "coat_weight", "coat_roughness", "coat_ior",
                    "coat_tint", "volume_absorption", "holdout", "translucent_weight", "translucent_color",
                    "translucent_program", "diffuse_roughness", "volume_scattering", "volume_anisotropy",
                    "volume_emission", "glossy_stretch", "glossy_rotation", "glossy_tangent",
                    "rotation_program", "stretch_program", "glossy_metal_tint", "glossy_metal_share",
                    "glossy_metal_rest", "level_program", "level_first", "level_count", "normal_program",
                    "normal_space", "outer_bump_program", "outer_bump_strength", "outer_bump_distance",
                    "coat_normal_program", "coat_bump_program", "coat_bump_strength", "coat_bump_distance",
                    "dielectric_fresnel", "dielectric_multiscatter", "displacement_program",
                    "displacement_flags", "displacement_bump",
                    "bump_correction", "film_thickness", "film_ior", "film_tint", "film_metal",
                    "film_metal_ior", "film_metal_extinction",
                    "subsurface_weight", "subsurface_radius", "subsurface_anisotropy", "subsurface_ior",
                    "subsurface_alpha", "subsurface_method", "glossy_distribution",
                    "dielectric_distribution", "sheen_color", "sheen_roughness", "sheen_cover",
                    "pass_index", "volume_phase", "volume_phase_params")
    INT_FIELDS = ("diffuse_texture", "normal_texture", "bump_texture")     # image indices
    PROGRAM_FIELDS = ("diffuse_program", "glossy_program", "emission_program", "roughness_program",
                      "dielectric_program", "bump_program", "opacity_program", "translucent_program",
                      "rotation_program", "stretch_program", "level_program", "normal_program",
                      "outer_bump_program", "coat_normal_program", "coat_bump_program",
                      "displacement_program")
    INDEX_FIELDS = INT_FIELDS + PROGRAM_FIELDS
    INTEGER_FIELDS = INDEX_FIELDS + ("glossy_tangent", "level_first", "level_count",   # stored as int32
                                     "normal_space", "displacement_flags", "displacement_bump",
                                     "bump_correction", "subsurface_method", "glossy_distribution",
                                     "dielectric_distribution", "volume_phase")
    SIGNED_FIELDS = INDEX_FIELDS + ("bump_distance", "outer_bump_distance", "coat_bump_distance",
                                    "glossy_metal_dip",
                                    "volume_anisotropy", "glossy_rotation", "glossy_metal_tint",
                                    "level_first", "dielectric_roughness")

    @property
    def count(self) -> int:
        return len(self.names)

    @staticmethod
    def build(specs) -> "Materials":
        """Build from a list of dicts, each with a ``name`` and any of the lobe keys.

        Missing keys default to a black, non-scattering, non-emitting material;
        colours may be scalars.  Example: ``{"name": "wall", "diffuse": (0.8, 0.8, 0.8)}``
        or ``{"name": "glass", "dielectric": 1.0, "ior": 1.5}``.
        Short keys: ``diffuse``/``glossy``/``mirror``/``dielectric``/``translucent`` give the colour
        and set the weight to 1 unless ``<lobe>_weight`` is given.  ``glossy_multiscatter``
        defaults to the glossy colour (Multiscatter GGX); give 0 for single-scattering GGX.
        ``glossy_fresnel_ior``, ``glossy_fresnel_rise``, ``glossy_metal_rise``, ``glossy_metal_dip``
        and ``diffuse_layer`` default to 0,
        ``diffuse_layer_weight`` to 1, ``diffuse_roughness`` to 0.  ``normal_texture`` (default -1: none) and
        ``normal_strength`` (default 1) give a normal map, tangent-space unless ``normal_space``
        (``NORMAL_*``) says otherwise, ``bump_texture``
        (default -1), ``bump_strength`` and ``bump_distance`` (default 1) a bump map.
        ``diffuse_program`` is a program (node dict, ``core/procedural.py``) for the diffuse
        colour, which then defaults to 1, ``glossy_program`` one for the glossy colour and
        ``emission_program`` one that multiplies ``emission``, ``roughness_program`` one for the
        glossy roughness, ``dielectric_program`` one for the glass's transmitted colour, which
        then defaults to 1, ``translucent_program`` one for the translucent colour (likewise),
        ``bump_program`` one for a bump's height (with ``bump_strength`` and
        ``bump_distance``; ``outer_bump_program``, with ``outer_bump_strength`` and
        ``outer_bump_distance``, a second bump over the first), ``normal_program`` one for the
        shading normal and ``opacity_program``
        one for the opacity (equal programs are stored once).  ``opacity`` (default 1) and
        ``transparent_color`` (default 1) make it transparent.
        ``coat`` (the coat's weight, default 0), ``coat_roughness`` (0.03), ``coat_ior`` (1.5) and
        ``coat_tint`` (1) give it a coat, ``sheen`` (colour, 0), ``sheen_roughness`` (0.5) and
        ``sheen_cover`` (0) a sheen, ``volume_absorption`` (0) a volume, which
        ``volume_scattering`` (0) and ``volume_anisotropy`` (0) make scatter (by Henyey-Greenstein's
        phase function, or by ``volume_phase`` (0) with ``volume_phase_params`` (0): ``core/phase.py``) and
        ``volume_emission`` (0) glow (or that alone), ``holdout`` (0) a holdout share.
        ``glossy_stretch`` (1), ``glossy_rotation`` (0) and ``glossy_tangent`` (2) make the
        glossy lobe anisotropic; ``rotation_program``, a float program, turns its tangent by the
        program's value at each hit instead of ``glossy_rotation``, and ``stretch_program``, a float
        program, gives the stretch at each hit instead of ``glossy_stretch``.  ``glossy_metal_tint``
        (default -1: none) makes a textured glossy lobe a metal of that edge tint whose F0 is its
        colour at each hit; ``glossy_metal_share`` (1) and ``glossy_metal_rest`` (0) make it part
        of the lobe beside a dielectric layer.  ``film_thickness`` (0: none), ``film_ior`` (1.33)
        and ``film_tint`` (1) coat the Fresnel layer with a thin film, ``film_metal`` (0) the metal.
        ``subsurface_weight`` (0), ``subsurface_radius`` (1), ``subsurface_anisotropy`` (0),
        ``subsurface_ior`` (1.4), ``subsurface_alpha`` (1) and ``subsurface_method`` (0) make part
        of the diffuse lobe scatter beneath the surface.
        ``level_program`` (a float program), ``level_first`` and ``level_count`` make it pick one of
        that many materials, its levels, at each hit.  ``pass_index`` (0) is Blender's pass index
        of the material (the Material Index pass).
        """
        m = len(specs)
        out = Materials(names=[s.get("name", f"material_{i}") for i, s in enumerate(specs)])
        out.diffuse_weight = np.zeros(m, np.float32)
        out.diffuse_color = np.zeros((m, 3), np.float32)
        out.diffuse_texture = np.full(m, -1, np.int32)
        out.glossy_weight = np.zeros(m, np.float32)
        out.glossy_color = np.zeros((m, 3), np.float32)
        out.glossy_roughness = np.full(m, 0.5, np.float32)
        out.glossy_multiscatter = np.zeros((m, 3), np.float32)
        out.glossy_fresnel_ior = np.zeros(m, np.float32)
        out.glossy_fresnel_rise = np.zeros((m, 3), np.float32)
        out.glossy_metal_rise = np.zeros((m, 3), np.float32)
        out.glossy_metal_dip = np.zeros((m, 3), np.float32)
        out.glossy_metal_tint = np.full((m, 3), -1.0, np.float32)
        out.glossy_metal_share = np.ones(m, np.float32)
        out.glossy_metal_rest = np.zeros((m, 3), np.float32)
        out.glossy_stretch = np.ones(m, np.float32)
        out.glossy_rotation = np.zeros(m, np.float32)
        out.glossy_tangent = np.full(m, TANGENT_RADIAL_Z, np.int32)
        out.diffuse_layer = np.zeros((m, 3), np.float32)
        out.diffuse_layer_weight = np.ones(m, np.float32)
        out.diffuse_roughness = np.zeros(m, np.float32)
        out.mirror_weight = np.zeros(m, np.float32)
        out.mirror_color = np.zeros((m, 3), np.float32)
        out.dielectric_weight = np.zeros(m, np.float32)
        out.dielectric_color = np.ones((m, 3), np.float32)
        out.dielectric_roughness = np.zeros(m, np.float32)
        out.dielectric_reflection_color = np.ones((m, 3), np.float32)
        out.ior = np.full(m, 1.5, np.float32)
        out.emission = np.zeros((m, 3), np.float32)
        out.normal_texture = np.full(m, -1, np.int32)
        out.normal_strength = np.ones(m, np.float32)
        out.normal_space = np.zeros(m, np.int32)
        out.bump_texture = np.full(m, -1, np.int32)
        out.bump_strength = np.ones(m, np.float32)
        out.bump_distance = np.ones(m, np.float32)
        out.outer_bump_strength = np.ones(m, np.float32)
        out.outer_bump_distance = np.ones(m, np.float32)
        out.diffuse_program = np.full(m, -1, np.int32)
        out.glossy_program = np.full(m, -1, np.int32)
        out.emission_program = np.full(m, -1, np.int32)
        out.roughness_program = np.full(m, -1, np.int32)
        out.dielectric_program = np.full(m, -1, np.int32)
        out.bump_program = np.full(m, -1, np.int32)
        out.outer_bump_program = np.full(m, -1, np.int32)
        out.coat_normal_program = np.full(m, -1, np.int32)
        out.dielectric_fresnel = np.ones(m, np.float32)
        out.dielectric_multiscatter = np.zeros((m, 3), np.float32)
        out.glossy_distribution = np.zeros(m, np.int32)
        out.dielectric_distribution = np.zeros(m, np.int32)
        out.displacement_program = np.full(m, -1, np.int32)
        out.displacement_flags = np.zeros(m, np.int32)
        out.displacement_bump = np.zeros(m, np.int32)
        out.bump_correction = np.ones(m, np.int32)
        out.film_thickness = np.zeros(m, np.float32)
        out.film_ior = np.full(m, 1.33, np.float32)
        out.film_tint = np.ones((m, 3), np.float32)
        out.film_metal = np.zeros(m, np.float32)
        out.film_metal_ior = np.zeros((m, 3), np.float32)
        out.film_metal_extinction = np.zeros((m, 3), np.float32)
        out.subsurface_weight = np.zeros(m, np.float32)
        out.subsurface_radius = np.ones((m, 3), np.float32)
        out.subsurface_anisotropy = np.zeros(m, np.float32)
        out.subsurface_ior = np.full(m, 1.4, np.float32)
        out.subsurface_alpha = np.ones(m, np.float32)
        out.subsurface_method = np.zeros(m, np.int32)
        out.coat_bump_program = np.full(m, -1, np.int32)
        out.coat_bump_strength = np.ones(m, np.float32)
        out.coat_bump_distance = np.ones(m, np.float32)
        out.normal_program = np.full(m, -1, np.int32)
        out.opacity = np.ones(m, np.float32)
        out.opacity_program = np.full(m, -1, np.int32)
        out.transparent_color = np.ones((m, 3), np.float32)
        out.coat_weight = np.zeros(m, np.float32)
        out.coat_roughness = np.full(m, 0.03, np.float32)
        out.coat_ior = np.full(m, 1.5, np.float32)
        out.coat_tint = np.ones((m, 3), np.float32)
        out.volume_absorption = np.zeros((m, 3), np.float32)
        out.volume_scattering = np.zeros((m, 3), np.float32)
        out.volume_anisotropy = np.zeros(m, np.float32)
        out.volume_phase = np.zeros(m, np.int32)
        out.volume_phase_params = np.zeros((m, 3), np.float32)
        out.volume_emission = np.zeros((m, 3), np.float32)
        out.holdout = np.zeros(m, np.float32)
        out.translucent_weight = np.zeros(m, np.float32)
        out.translucent_color = np.zeros((m, 3), np.float32)
        out.sheen_color = np.zeros((m, 3), np.float32)
        out.sheen_roughness = np.full(m, 0.5, np.float32)
        out.sheen_cover = np.zeros(m, np.float32)
        out.pass_index = np.zeros(m, np.float32)
        out.translucent_program = np.full(m, -1, np.int32)
        out.rotation_program = np.full(m, -1, np.int32)
        out.stretch_program = np.full(m, -1, np.int32)
        out.level_program = np.full(m, -1, np.int32)
        out.level_first = np.full(m, -1, np.int32)
        out.level_count = np.zeros(m, np.int32)
        stored = {}
        # Shader AOVs: spec "aovs" {name: a colour, a number or a program}.
        out.aov_names = sorted({name for s in specs for name in s.get("aovs", {})})
        out.aov_writes = np.zeros((m, len(out.aov_names)), bool)
        out.aov_value = np.zeros((m, len(out.aov_names), 3), np.float32)
        out.aov_program = np.full((m, len(out.aov_names)), -1, np.int32)
        for i, s in enumerate(specs):
            for name, value in s.get("aovs", {}).items():
                a = out.aov_names.index(name)
                out.aov_writes[i, a] = True
                if isinstance(value, dict):
                    out.aov_program[i, a] = _stored_program(out, stored, value)
                else:
                    out.aov_value[i, a] = np.broadcast_to(np.asarray(value, np.float32), (3,))
        for i, s in enumerate(specs):
            for lobe in ("diffuse", "glossy", "mirror", "dielectric", "translucent"):
                if lobe in s:
                    getattr(out, f"{lobe}_color")[i] = np.broadcast_to(
                        np.asarray(s[lobe], np.float32), (3,))
                    getattr(out, f"{lobe}_weight")[i] = s.get(f"{lobe}_weight", 1.0)
                elif f"{lobe}_weight" in s:
                    getattr(out, f"{lobe}_weight")[i] = s[f"{lobe}_weight"]
            for field_name in Materials.PROGRAM_FIELDS:
                if field_name in s:
                    getattr(out, field_name)[i] = _stored_program(out, stored, s[field_name])
            if "diffuse_texture" in s or "diffuse_program" in s:
                out.diffuse_texture[i] = s.get("diffuse_texture", -1)
                if "diffuse" not in s:
                    out.diffuse_color[i] = 1.0
                    out.diffuse_weight[i] = s.get("diffuse_weight", 1.0)
            if "translucent_program" in s and "translucent" not in s:
                out.translucent_color[i] = 1.0
                out.translucent_weight[i] = s.get("translucent_weight", 1.0)
            if "dielectric_program" in s and "dielectric" not in s:
                out.dielectric_color[i] = 1.0
                out.dielectric_weight[i] = s.get("dielectric_weight", 1.0)
            out.glossy_multiscatter[i] = np.broadcast_to(
                np.asarray(s.get("glossy_multiscatter", out.glossy_color[i]), np.float32), (3,))
            if "roughness" in s:
                out.glossy_roughness[i] = s["roughness"]
            out.glossy_fresnel_ior[i] = s.get("glossy_fresnel_ior", 0.0)
            out.diffuse_layer_weight[i] = s.get("diffuse_layer_weight", 1.0)
            out.diffuse_roughness[i] = s.get("diffuse_roughness", 0.0)
            out.glossy_stretch[i] = s.get("glossy_stretch", 1.0)
            out.glossy_rotation[i] = s.get("glossy_rotation", 0.0)
            out.glossy_tangent[i] = s.get("glossy_tangent", TANGENT_RADIAL_Z)
            for key in ("glossy_fresnel_rise", "glossy_metal_rise", "glossy_metal_dip", "diffuse_layer"):
                getattr(out, key)[i] = np.broadcast_to(np.asarray(s.get(key, 0.0), np.float32), (3,))
            out.glossy_metal_tint[i] = np.broadcast_to(np.asarray(s.get("glossy_metal_tint", -1.0),
                                                              np.float32), (3,))
            out.glossy_metal_share[i] = s.get("glossy_metal_share", 1.0)
            out.level_first[i] = s.get("level_first", -1)
            out.level_count[i] = s.get("level_count", 0)
            out.glossy_metal_rest[i] = np.broadcast_to(np.asarray(s.get("glossy_metal_rest", 0.0),
                                                              np.float32), (3,))
            if "ior" in s:
                out.ior[i] = s["ior"]
            if "dielectric_roughness" in s:
                out.dielectric_roughness[i] = s["dielectric_roughness"]
            out.dielectric_reflection_color[i] = np.broadcast_to(np.asarray(
                s.get("dielectric_reflection", out.dielectric_color[i]), np.float32), (3,))
            if "emission" in s:
                out.emission[i] = np.broadcast_to(np.asarray(s["emission"], np.float32), (3,))
            out.opacity[i] = s.get("opacity", 1.0)
            out.transparent_color[i] = np.broadcast_to(
                np.asarray(s.get("transparent_color", 1.0), np.float32), (3,))
            out.coat_weight[i] = s.get("coat", 0.0)
            out.coat_roughness[i] = s.get("coat_roughness", 0.03)
            out.coat_ior[i] = s.get("coat_ior", 1.5)
            out.coat_tint[i] = np.broadcast_to(np.asarray(s.get("coat_tint", 1.0), np.float32), (3,))
            out.sheen_color[i] = np.broadcast_to(np.asarray(s.get("sheen", 0.0), np.float32), (3,))
            out.sheen_roughness[i] = s.get("sheen_roughness", 0.5)
            out.sheen_cover[i] = s.get("sheen_cover", 0.0)
            out.pass_index[i] = s.get("pass_index", 0)
            out.volume_absorption[i] = np.broadcast_to(
                np.asarray(s.get("volume_absorption", 0.0), np.float32), (3,))
            out.volume_scattering[i] = np.broadcast_to(
                np.asarray(s.get("volume_scattering", 0.0), np.float32), (3,))
            out.volume_anisotropy[i] = s.get("volume_anisotropy", 0.0)
            out.volume_phase[i] = s.get("volume_phase", 0)
            out.volume_phase_params[i] = s.get("volume_phase_params", (0.0, 0.0, 0.0))
            out.volume_emission[i] = np.broadcast_to(
                np.asarray(s.get("volume_emission", 0.0), np.float32), (3,))
            out.holdout[i] = s.get("holdout", 0.0)
            out.normal_texture[i] = s.get("normal_texture", -1)
            out.normal_strength[i] = s.get("normal_strength", 1.0)
            out.normal_space[i] = s.get("normal_space", NORMAL_TANGENT)
            out.bump_texture[i] = s.get("bump_texture", -1)
            out.bump_strength[i] = s.get("bump_strength", 1.0)
            out.bump_distance[i] = s.get("bump_distance", 1.0)
            out.outer_bump_strength[i] = s.get("outer_bump_strength", 1.0)
            out.outer_bump_distance[i] = s.get("outer_bump_distance", 1.0)
            out.coat_bump_strength[i] = s.get("coat_bump_strength", 1.0)
            out.coat_bump_distance[i] = s.get("coat_bump_distance", 1.0)
            out.dielectric_fresnel[i] = s.get("dielectric_fresnel", 1.0)
            out.dielectric_multiscatter[i] = np.broadcast_to(
                np.asarray(s.get("dielectric_multiscatter", 0.0), np.float32), (3,))
            out.glossy_distribution[i] = s.get("glossy_distribution", DISTRIBUTION_GGX)
            out.dielectric_distribution[i] = s.get("dielectric_distribution", DISTRIBUTION_GGX)
            out.displacement_flags[i] = s.get("displacement_flags", 0)
            out.displacement_bump[i] = s.get("displacement_bump", 0)
            out.bump_correction[i] = s.get("bump_correction", 1)
            out.film_thickness[i] = s.get("film_thickness", 0.0)
            out.film_ior[i] = s.get("film_ior", 1.33)
            out.film_tint[i] = np.broadcast_to(np.asarray(s.get("film_tint", 1.0), np.float32), (3,))
            out.film_metal[i] = s.get("film_metal", 0.0)
            for name in ("film_metal_ior", "film_metal_extinction"):
                getattr(out, name)[i] = np.broadcast_to(np.asarray(s.get(name, 0.0), np.float32), (3,))
            out.subsurface_weight[i] = s.get("subsurface_weight", 0.0)
            radius = np.asarray(s.get("subsurface_radius", 1.0), np.float32)
            out.subsurface_radius[i] = np.broadcast_to(radius, (3,))
            out.subsurface_anisotropy[i] = s.get("subsurface_anisotropy", 0.0)
            out.subsurface_ior[i] = s.get("subsurface_ior", 1.4)
            out.subsurface_alpha[i] = s.get("subsurface_alpha", 1.0)
            out.subsurface_method[i] = s.get("subsurface_method", SUBSURFACE_RANDOM_WALK)
        return out


@dataclass
class Lights:
    """Analytic lights, shape ``(L, ...)``; emissive meshes are materials instead.

    ``kind`` selects the model (Cycles' conventions):

    * POINT: a sphere of ``radius`` (0 = a point) radiating ``power`` watts
      uniformly; radiance P/(4 pi^2 r^2), intensity P/(4 pi).
    * SPOT: a point light masked by a cone of full angle ``spot_angle`` around
      ``direction`` with smoothstep edge ``spot_blend``; the cone does not
      concentrate the power (intensity stays P/(4 pi)).
    * AREA_RECT / AREA_DISK: a one-sided Lambertian emitter facing ``direction``,
      spanned by the half-extent vectors ``axis_u`` and ``axis_v`` (a rectangle, or
      an ellipse with those semi-axes); radiance P/(pi A), times Cycles' soft-box
      attenuation when ``spread`` (full angle, radians) is below pi:
      max(0, (tan(s/2) - tan a) / (tan(s/2) - s/2)) at angle a from ``direction``, which
      keeps the emitted power.
    * SUN: a distant light arriving along ``direction`` with irradiance ``power``
      (W/m^2) over a cone of angular diameter ``sun_angle``; radiance
      P / (pi sin^2(sun_angle / 2)).

    ``visibility`` says which camera rays see a light with that radiance (a bit mask of
    VISIBLE_CAMERA, VISIBLE_GLOSSY: rays reflected by a mirror or glass, VISIBLE_TRANSMISSION:
    rays refracted by glass); lights are transparent to the rays, as in Cycles, and a point or
    sun of size 0 is never seen.  Default: seen in reflections and through glass, not directly.
    ``profile`` (L,) indexes ``profiles``, a point, spot or area light's angular profile (Blender's
    IES Texture on its Emission Strength; -1: none, the default): its intensity in a direction d
    is multiplied by ``profiles[k]`` at the angles of d in the light's frame (``axis_u``,
    ``axis_v`` the directions of its X and Y axes, unit for point and spot lights, ``-direction``
    its Z): v = acos(-z) in [0, pi] down the rows, h = atan2(x, y) + pi in [0, 2 pi] along the
    columns, both sampled at equal steps with their ends included (Cycles' IES lookup,
    tabulated; bilinear in between).
    ``exclude`` (L,) the rays each light does not light (bits EXCLUDE_*; 0, the default: all).
    ``links`` (L,) says which receiver sets each light lights (light linking, bit s for
    ``Scene.receiver_sets`` value s; ``ALL_LINKS``, the default, lights everything), and
    ``shadow_links`` (L,) which blocker sets shadow it (shadow linking, ``Scene.blocker_sets``).
    ``group`` (L,) the light group of each light (an index into ``Scene.light_groups``; -1, the
    default: none), whose pass (Cycles' ``Combined_<group>``) holds the light it sends.
    With ``soft_falloff`` (Blender's Soft Falloff, on by default) a point or spot light acts as
    Cycles then makes it: a disk of ``radius`` facing the receiver or viewer instead of a
    sphere.  It is seen as that disk, and its irradiance at distance d is P / (4 pi (d^2 + r^2))
    instead of the sphere's P / (4 pi d^2): photons still leave the sphere, and their flux is
    scaled by d^2 / (d^2 + r^2) where they first land.
    """

    kind: np.ndarray = None             # (L,) int8, one of POINT, SPOT, AREA_RECT, AREA_DISK, SUN
    position: np.ndarray = None         # (L, 3) float64, world; centre of the light (unused for SUN)
    direction: np.ndarray = None        # (L, 3) float32, unit; emission axis (-Z of the light object)
    axis_u: np.ndarray = None           # (L, 3) float32, world; area half-extent along local X
    axis_v: np.ndarray = None           # (L, 3) float32, world; area half-extent along local Y
    power: np.ndarray = None            # (L, 3) float32; watts, or W/m^2 for SUN
    radius: np.ndarray = None           # (L,) float32; sphere radius of POINT/SPOT
    spot_angle: np.ndarray = None       # (L,) float32; full cone angle in radians
    spot_blend: np.ndarray = None       # (L,) float32 in [0, 1]
    sun_angle: np.ndarray = None        # (L,) float32; angular diameter in radians
    visibility: np.ndarray = None       # (L,) uint8 bit mask of VISIBLE_*; None: the default
    soft_falloff: np.ndarray = None     # (L,) bool, point/spot seen as a disk; None: True
    spread: np.ndarray = None           # (L,) float32 in [0, pi], area lights; None: pi
    profile: np.ndarray = None          # (L,) int16 index into ``profiles`` or -1; None: all -1
    profiles: np.ndarray = None         # (P, V, H) float32 >= 0 angular profiles, or None
    links: np.ndarray = None            # (L,) uint64 receiver sets lit (Scene.receiver_sets); None: all
    shadow_links: np.ndarray = None     # (L,) uint64 blocker sets that shadow (Scene.blocker_sets); None: all
    exclude: np.ndarray = None          # (L,) uint8 bit mask of EXCLUDE_*, rays not lit; None: 0
    group: np.ndarray = None            # (L,) int16 light group (Scene.light_groups) or -1; None: all -1

    ARRAY_FIELDS = ("kind", "position", "direction", "axis_u", "axis_v", "power", "radius",
                    "spot_angle", "spot_blend", "sun_angle", "visibility", "soft_falloff", "spread",
                    "profile", "links", "shadow_links", "exclude", "group")

    @property
    def count(self) -> int:
        return 0 if self.kind is None else int(len(self.kind))

    @staticmethod
    def empty() -> "Lights":
        return Lights.build([])

    @staticmethod
    def build(specs) -> "Lights":
        """Build from dicts with ``kind`` ("point", "spot", "area", "disk", "sun") and fields.

        Example: ``{"kind": "point", "position": (0, 0, 2), "power": 100}``,
        ``{"kind": "area", "position": p, "direction": (0, 0, -1), "size": (1, 2)}``
        (``size`` gives full extents along axes perpendicular to ``direction``;
        pass ``axis_u``/``axis_v`` for explicit half-extent vectors).
        """
        kinds = {"point": POINT, "spot": SPOT, "area": AREA_RECT, "rect": AREA_RECT,
                 "disk": AREA_DISK, "ellipse": AREA_DISK, "sun": SUN}
        n = len(specs)
        out = Lights(kind=np.zeros(n, np.int8), position=np.zeros((n, 3)),
                     direction=np.tile(np.float32([0, 0, -1]), (n, 1)),
                     axis_u=np.zeros((n, 3), np.float32), axis_v=np.zeros((n, 3), np.float32),
                     power=np.zeros((n, 3), np.float32), radius=np.zeros(n, np.float32),
                     spot_angle=np.full(n, np.pi / 4, np.float32), spot_blend=np.zeros(n, np.float32),
                     sun_angle=np.zeros(n, np.float32),
                     visibility=np.full(n, DEFAULT_LIGHT_VISIBILITY, np.uint8),
                     soft_falloff=np.ones(n, bool), spread=np.full(n, np.pi, np.float32),
                     profile=np.full(n, -1, np.int16), links=np.full(n, ALL_LINKS, np.uint64),
                     shadow_links=np.full(n, ALL_LINKS, np.uint64), exclude=np.zeros(n, np.uint8),
                     group=np.full(n, -1, np.int16))
        for i, s in enumerate(specs):
            out.kind[i] = kinds[s["kind"]]
            out.position[i] = s.get("position", (0, 0, 0))
            d = np.asarray(s.get("direction", (0, 0, -1)), np.float64)
            d = d / np.linalg.norm(d)
            out.direction[i] = d
            out.power[i] = np.broadcast_to(np.asarray(s.get("power", 0.0), np.float32), (3,))
            out.radius[i] = s.get("radius", 0.0)
            out.spot_angle[i] = s.get("spot_angle", np.pi / 4)
            out.spot_blend[i] = s.get("spot_blend", 0.0)
            out.sun_angle[i] = s.get("sun_angle", 0.0)
            out.visibility[i] = s.get("visibility", DEFAULT_LIGHT_VISIBILITY)
            out.soft_falloff[i] = s.get("soft_falloff", True)
            out.spread[i] = s.get("spread", np.pi)
            out.profile[i] = s.get("profile", -1)
            out.links[i] = np.uint64(s.get("links", ALL_LINKS))
            out.shadow_links[i] = np.uint64(s.get("shadow_links", ALL_LINKS))
            out.exclude[i] = s.get("exclude", 0)
            out.group[i] = s.get("group", -1)
            if "axis_u" in s:
                out.axis_u[i] = s["axis_u"]
                out.axis_v[i] = s["axis_v"]
            elif out.kind[i] in (AREA_RECT, AREA_DISK):
                sx, sy = np.broadcast_to(np.asarray(s.get("size", 1.0), np.float64), (2,))
                u, v = orthonormal_basis(d)
                out.axis_u[i] = u * sx / 2
                out.axis_v[i] = v * sy / 2
            elif out.profile[i] >= 0:
                out.axis_u[i], out.axis_v[i] = orthonormal_basis(-d)     # the light's X and Y
        return out


def orthonormal_basis(n):
    """Two unit vectors that complete the unit vector ``n`` (3,) to a right-handed basis."""
    n = np.asarray(n, np.float64)
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(a, n)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


@dataclass
class Camera:
    """A pinhole, thin-lens or orthographic camera.

    The camera looks along its local -Z with +Y up (Blender's convention);
    ``world_from_camera`` maps camera space to world space.  ``frame`` is the
    visible window of the image plane, as Blender's ``Camera.view_frame``:
    on the plane z = -1 for a perspective camera, in camera units for an
    orthographic one, so sensor fit, aspect ratio and shift are already in it.
    ``border`` is the rendered sub-window in fractions of the frame with y measured
    from the bottom (Blender's ``border_min_y``); the image produced covers
    ``floor(border * resolution)`` pixels.

    Panoramic cameras (Cycles' panorama types) see from their eye in every direction that
    their projection maps the image to (``core.camera.panorama_directions``; ``frame``, the
    aperture and the focus do not apply, clip distances are along the rays):
    ``equirectangular`` over ``latitude_range`` and ``longitude_range`` (radians, longitude
    0 straight ahead and growing to the right, latitude 0 at the camera's horizon);
    ``fisheye_equidistant`` (angle from the view axis proportional to the distance from the
    image centre, ``fisheye_fov`` across the image, an ellipse on a non-square image);
    ``fisheye_equisolid`` (a real fisheye lens of focal length ``fisheye_lens`` mm on the
    ``sensor_size`` (width, height) in mm the image covers, its circle ``fisheye_fov`` wide);
    ``mirrorball`` (the reflection in a mirror ball that fills the image).  Pixels outside a
    fisheye's circle or the ball see nothing (black, opaque), as in Cycles.

    The thin lens's aperture is Cycles': a disc of ``aperture_radius``, or with ``aperture_blades``
    of 3 or more a regular polygon of that circumradius turned by ``aperture_rotation``, its width
    divided by ``aperture_ratio`` (anamorphic bokeh); ``core.camera.aperture_points``.

    ``pixel_filter`` and ``filter_width`` are Cycles' Film > Pixel Filter: each camera ray leaves
    its pixel's centre at an offset drawn from the filter (:func:`core.camera.filter_offsets`), so
    a pixel is the filter's weighted mean of what lies around it.  Blender's default is
    Blackman-Harris of width 1.5 (its window spans twice that: 3 pixels); the core's default, a box
    of width 1, is one pixel's area.
    """

    world_from_camera: np.ndarray = field(default_factory=lambda: np.eye(4))  # (4, 4) float64
    projection: str = "perspective"     # "perspective", "orthographic" or one of PANORAMAS
    frame: tuple = (-0.36, 0.36, -0.2025, 0.2025)   # (x_min, x_max, y_min, y_max)
    resolution: tuple = (64, 36)        # (width, height) of the full frame in pixels
    border: tuple = (0.0, 1.0, 0.0, 1.0)  # (x_min, x_max, y_min, y_max), fractions, y from bottom
    aperture_radius: float = 0.0        # thin-lens aperture radius in world units (0 = pinhole)
    focus_distance: float = 10.0        # distance of the plane in focus along -Z
    aperture_blades: int = 0            # polygonal aperture's corners (below 3: a disc)
    aperture_rotation: float = 0.0      # the polygon's rotation, radians
    aperture_ratio: float = 1.0         # anamorphic: the aperture's height over its width
    clip_start: float = 0.0             # near clip along -Z
    clip_end: float = 1e30              # far clip along -Z
    latitude_range: tuple = (-np.pi / 2, np.pi / 2)    # equirectangular (min, max), radians
    longitude_range: tuple = (-np.pi, np.pi)          # equirectangular (min, max), radians
    fisheye_fov: float = np.pi          # fisheyes' field of view, radians
    fisheye_lens: float = 10.5          # equisolid fisheye's focal length, mm
    sensor_size: tuple = (36.0, 24.0)   # equisolid fisheye: (width, height) of the image in mm
    pixel_filter: str = "box"           # one of PIXEL_FILTERS
    filter_width: float = 1.0           # pixels (Cycles' Filter Width)

    PANORAMA_FIELDS = ("latitude_range", "longitude_range", "fisheye_fov", "fisheye_lens", "sensor_size")

    @staticmethod
    def look_at(eye, target, up=(0, 0, 1), *, lens_mm=50.0, sensor_width=36.0, sensor_height=24.0,
                sensor_fit="AUTO", resolution=(64, 64), shift=(0.0, 0.0), **kwargs) -> "Camera":
        """A perspective camera at ``eye`` looking at ``target``, framed as Blender does."""
        eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
        back = eye - target
        back /= np.linalg.norm(back)
        right = np.cross(up, back)
        if np.linalg.norm(right) < 1e-9:
            right = orthonormal_basis(back)[0]
        right /= np.linalg.norm(right)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(back, right), back, eye
        frame = perspective_frame(lens_mm, sensor_width, sensor_height, sensor_fit, resolution, shift)
        return Camera(world_from_camera=m, frame=frame, resolution=tuple(int(r) for r in resolution),
                      **kwargs)

    @staticmethod
    def from_view(view_matrix, projection_matrix, perspective, resolution, **kwargs) -> "Camera":
        """The camera of a view given as OpenGL matrices, as Blender's 3D viewport keeps them
        (``RegionView3D.view_matrix``, world to view, and ``window_matrix``, view to clip space;
        or a camera object's inverse world matrix and ``calc_matrix_camera``): a perspective
        camera when ``perspective``, else orthographic, whose frame, near and far clip are the
        projection's, rendered at ``resolution``.  An orthographic view whose near plane lies
        behind the view's origin (the viewport's, for things behind its centre) starts its rays
        there instead."""
        view = np.asarray(view_matrix, np.float64)
        p = np.asarray(projection_matrix, np.float64)
        if not (np.isfinite(view).all() and np.isfinite(p).all()) or p[0, 0] == 0 or p[1, 1] == 0:
            raise SceneError("Camera.from_view: the view or projection matrix is degenerate")
        world_from_camera = np.linalg.inv(view)
        if perspective:
            # clip = P (x, y, z, 1) with w = -z: on the plane z = -1, x = (ndc_x + P02) / P00.
            frame = ((-1 + p[0, 2]) / p[0, 0], (1 + p[0, 2]) / p[0, 0],
                     (-1 + p[1, 2]) / p[1, 1], (1 + p[1, 2]) / p[1, 1])
            near, far = p[2, 3] / (p[2, 2] - 1.0), p[2, 3] / (p[2, 2] + 1.0)
        else:
            # clip = P (x, y, z, 1) with w = 1: x = (ndc_x - P03) / P00.
            frame = ((-1 - p[0, 3]) / p[0, 0], (1 - p[0, 3]) / p[0, 0],
                     (-1 - p[1, 3]) / p[1, 1], (1 - p[1, 3]) / p[1, 1])
            near, far = (p[2, 3] + 1.0) / p[2, 2], (p[2, 3] - 1.0) / p[2, 2]
            if near < 0:
                world_from_camera[:3, 3] -= near * world_from_camera[:3, 2]     # back along +Z to it
                near, far = 0.0, far - near
        return Camera(world_from_camera=world_from_camera,
                      projection="perspective" if perspective else "orthographic",
                      frame=tuple(float(v) for v in frame), resolution=tuple(int(r) for r in resolution),
                      clip_start=float(max(near, 0.0)), clip_end=float(far), **kwargs)

    @property
    def filter_reach(self) -> float:
        """How far (pixels) the pixel filter sends a camera ray from its pixel's centre at most
        (:func:`core.camera.filter_offsets`): a box half its width, a Gaussian 1.5 times it,
        Blackman-Harris its width."""
        return self.filter_width * {"box": 0.5, "gaussian": 1.5, "blackman_harris": 1.0}[self.pixel_filter]

    @property
    def window(self):
        """Pixel window ``(x0, x1, y0, y1)`` rendered, rows counted from the top."""
        w, h = self.resolution
        bx0, bx1, by0, by1 = self.border
        x0, x1 = int(np.floor(bx0 * w + 1e-9)), int(np.floor(bx1 * w + 1e-9))
        # Blender's border y is measured from the bottom; our rows from the top.
        y0, y1 = h - int(np.floor(by1 * h + 1e-9)), h - int(np.floor(by0 * h + 1e-9))
        return x0, max(x1, x0), y0, max(y1, y0)


def perspective_frame(lens_mm, sensor_width, sensor_height, sensor_fit, resolution, shift=(0.0, 0.0)):
    """Image-plane window at z = -1 as Blender computes it (``view_frame``).

    AUTO fits the larger image dimension to ``sensor_width``; HORIZONTAL fits the
    width to ``sensor_width``; VERTICAL fits the height to ``sensor_height``.  Shift
    is in units of the fitted dimension.
    """
    w, h = resolution
    fit = sensor_fit.upper()
    if fit == "AUTO":
        fit = "HORIZONTAL" if w >= h else "VERTICAL"
        sensor = sensor_width
    else:
        sensor = sensor_width if fit == "HORIZONTAL" else sensor_height
    size = sensor / lens_mm     # extent of the fitted dimension on the z = -1 plane
    if fit == "HORIZONTAL":
        half_w, half_h = size / 2, size / 2 * h / w
        sx, sy = shift[0] * size, shift[1] * size
    else:
        half_h, half_w = size / 2, size / 2 * w / h
        sx, sy = shift[0] * size, shift[1] * size
    return (-half_w + sx, half_w + sx, -half_h + sy, half_h + sy)


@dataclass
class World:
    """Background radiance seen by rays that leave the scene: ``color``, times the
    equirectangular image ``texture`` when given (Blender's Environment Texture with its
    default mapping; ``core/environment.py`` has the direction convention)."""

    color: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # (3,) radiance
    film_transparent: bool = False      # escaped camera rays give alpha 0 instead of the background
    texture: np.ndarray = None          # (H, W, 3) float32 linear, row 0 = bottom (nadir), or None
    texture_rotation: np.ndarray = None  # (3, 3) float64: the image is looked up at R d; None: identity
    # A program of the view (``procedural``: it reads Texture Coordinate's Window or Camera, e.g. a
    # backplate image), or None: camera rays that leave the scene see ``color`` times its value
    # there (``procedural.DirectionAttributes`` with the camera), the others ``texture``, its bake.
    program: dict = None
    # What rays leaving the camera straight into the sky see instead (Blender's Light Path "Is
    # Camera Ray" between two Backgrounds): a World of its own (color, texture, texture_rotation),
    # or None: the same as every other ray.
    camera: "World" = None
    # The world's volume (Blender's World > Volume): a homogeneous medium filling everything
    # outside the meshes' volumes, with the coefficients of Materials.volume_absorption,
    # volume_scattering and volume_anisotropy.  It is unbounded, as in Cycles: rays that leave
    # the scene through it are extinguished in every channel it attenuates, so the background,
    # the sun and the world's light do not get through it (only light from emitters in it).
    volume_absorption: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # (3,) >= 0
    volume_scattering: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # (3,) >= 0
    volume_anisotropy: float = 0.0      # Henyey-Greenstein g in [-0.99, 0.99]
    volume_phase: int = 0               # the phase function (Materials.volume_phase), and its
    volume_phase_params: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # parameters
    # The rays the world does not light (bits EXCLUDE_*, Blender's World > Ray Visibility): its
    # photons and its sun lights' as ``Lights.exclude``, and camera paths that leave a mirror
    # (EXCLUDE_GLOSSY) or a glass (EXCLUDE_TRANSMISSION) see black past the scene.
    exclude: int = 0
    # The light group of the world and its sun lights (an index into Scene.light_groups; -1: none).
    group: int = -1
    # Blender's World > Mist Pass (the Mist pass, ``RenderSettings.data_passes``): the mist is 0 up to
    # ``mist_start`` metres from the camera and rises to 1 over ``mist_depth``, as the fraction of
    # that depth to the power ``mist_falloff`` (2 quadratic, 1 linear, 0.5 inverse quadratic).
    mist_start: float = 5.0
    mist_depth: float = 25.0
    mist_falloff: float = 2.0
    # Light portals (Cycles' area lights marked Portal, in windows): (K, 3, 3) float64 rows of the
    # centre and the half extents u and v (world; light from the world and the sun crosses them
    # into the scene along u x v), and (K,) bool ellipses (else parallelograms); None: no portals.
    # They emit nothing: the photons from afar are aimed through them (core.lights.Focus.through).
    portals: np.ndarray = None
    portal_disks: np.ndarray = None

    VOLUME_FIELDS = ("volume_absorption", "volume_scattering", "volume_anisotropy", "volume_phase",
                     "volume_phase_params")
    MIST_FIELDS = ("mist_start", "mist_depth", "mist_falloff")

    @property
    def has_volume(self) -> bool:
        """Whether the world's volume attenuates some channel."""
        return bool(np.any(self.volume_absorption) or np.any(self.volume_scattering))


def _validate_background(w, name, fail, n_textures):
    """Check and normalise the colour, image, rotation and program of World ``w`` (``name`` in
    messages; ``n_textures`` images for the program)."""
    if w.program is not None:
        if isinstance(w.program, str):
            w.program = procedural.from_json(w.program)
        try:
            procedural.validate(w.program, n_textures)
        except procedural.ProgramError as e:
            fail(f"{name}.program: {e}")
    col = np.asarray(w.color, np.float32).reshape(-1)
    if col.shape != (3,) or not np.isfinite(col).all() or (col < 0).any():
        fail(f"{name}.color must be three finite non-negative numbers")
    w.color = col
    if w.texture is not None:
        tex = np.asarray(w.texture, np.float32)
        if tex.ndim != 3 or tex.shape[2] != 3 or tex.shape[0] < 1 or tex.shape[1] < 1:
            fail(f"{name}.texture must have shape (H, W, 3), not {tex.shape}")
        if not np.isfinite(tex).all() or (tex < 0).any():
            fail(f"{name}.texture must hold finite non-negative radiance")
        w.texture = np.ascontiguousarray(tex)
    if w.texture_rotation is not None:
        rot = np.asarray(w.texture_rotation, np.float64)
        if rot.shape != (3, 3) or not np.isfinite(rot).all() or abs(abs(np.linalg.det(rot)) - 1) > 1e-3:
            fail(f"{name}.texture_rotation must be a 3 x 3 rotation matrix")
        w.texture_rotation = rot


def _validate_portals(w, fail):
    """Check and normalise World ``w``'s portals (None when there are none)."""
    if w.portals is None or not len(w.portals):
        w.portals = w.portal_disks = None
        return
    portals = np.asarray(w.portals, np.float64)
    if portals.ndim != 3 or portals.shape[1:] != (3, 3) or not np.isfinite(portals).all():
        fail(f"world.portals must be finite (K, 3, 3) rows of a centre and two half extents, "
             f"not of shape {portals.shape}")
    if (np.linalg.norm(np.cross(portals[:, 1], portals[:, 2]), axis=1) <= 0).any():
        fail("world.portals: a portal has zero area (its half extents are parallel or zero)")
    disks = np.zeros(len(portals), bool) if w.portal_disks is None else np.asarray(w.portal_disks)
    if disks.shape != (len(portals),):
        fail(f"world.portal_disks must be ({len(portals)},) bools, not of shape {disks.shape}")
    w.portals, w.portal_disks = portals, disks.astype(bool)


def _validate_world_volume(w, fail):
    """Check and normalise the coefficients of World ``w``'s volume."""
    for name in ("volume_absorption", "volume_scattering"):
        value = np.asarray(getattr(w, name), np.float32).reshape(-1)
        if value.shape != (3,) or not np.isfinite(value).all() or (value < 0).any():
            fail(f"world.{name} must be three finite non-negative numbers")
        setattr(w, name, value)
    g = np.asarray(w.volume_anisotropy, np.float64).reshape(-1)
    if g.shape != (1,) or not -0.99 <= g[0] <= 0.99:
        fail("world.volume_anisotropy must be a number in [-0.99, 0.99]")
    w.volume_anisotropy = float(g[0])
    kind = np.asarray(w.volume_phase).reshape(-1)
    if kind.shape != (1,) or not float(kind[0]).is_integer() or not 0 <= kind[0] <= 4:
        fail("world.volume_phase must be an index of core.phase.PHASE_NAMES (0-4)")
    w.volume_phase = int(kind[0])
    params = np.asarray(w.volume_phase_params, np.float32).reshape(-1)
    if params.shape != (3,) or not np.isfinite(params).all() or (params < 0).any():
        fail("world.volume_phase_params must be three finite non-negative numbers")
    w.volume_phase_params = params


@dataclass
class Scene:
    """A renderable scene.  See the module docstring for units and spaces."""

    vertices: np.ndarray                # (V, 3) float32, world
    triangles: np.ndarray               # (T, 3) int32, counter-clockwise = front (normal side)
    material_ids: np.ndarray            # (T,) int32, index into ``materials``
    materials: Materials
    lights: Lights = field(default_factory=Lights.empty)
    camera: Camera = field(default_factory=Camera)
    world: World = field(default_factory=World)
    shading_normals: np.ndarray = None  # (T, 3, 3) float32 per-corner normals, or None (flat)
    uvs: np.ndarray = None              # (T, 3, 2) float32 per-corner texture coordinates, or None
    # (T, 3, 4) float32 per-corner tangent (xyz, world, unit; zero: no tangent frame) and bitangent
    # sign w: bitangent = w cross(normal, tangent).  Needed by normal maps (Materials), else None.
    tangents: np.ndarray = None
    textures: list = field(default_factory=list)  # K images (H, W, 3) float32, linear, row 0 = bottom
    # The objects (instances) of procedural textures' Object and Generated coordinates, or None
    # when no program reads them: object_ids (T,) int32 each triangle's object; object_from_world
    # (O, 3, 4) float64 the affine map of a world position into its object's space; texture_spaces
    # (O, 2, 3) float64 the location and size of each object's texture space (Generated maps it to
    # [0, 1]^3: (p_object - location) / (2 size) + 1/2, 1/2 along an axis of size 0).
    object_ids: np.ndarray = None
    object_from_world: np.ndarray = None
    texture_spaces: np.ndarray = None
    # (O, 6) float32 Blender's Object Info of each object: Alpha, Object Index (the pass index),
    # Random (Cycles' random number in [0, 1]) and Color (rgb); None: zeros (``validate``).
    object_info: np.ndarray = None
    # Properties of the objects that programs read (``procedural.OBJECT_PROPERTY``): {name: (O, 3)
    # float32}, a number repeated; None: none (they read 0).
    object_attributes: dict = None
    vertex_colors: np.ndarray = None    # (T, 3, 3) float32 linear RGB per corner (Color Attribute), or None
    # Named mesh attributes that programs read (``procedural.NAMED``): {name: (T, 3, 3) float32 per
    # corner}, a float attribute repeated in x, y and z, a 2D one (x, y, 0), a colour linear RGB;
    # 0 on meshes without it.  None: none.
    attributes: dict = None
    # (T,) uint8 the camera-path rays that see each triangle (Blender's object ray visibility, bits
    # as Lights.visibility: VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION), or None: all of
    # them.  The others go through it (RenderContext.trace); photons always meet it.  The bit
    # HOLDOUT_OBJECT makes it a holdout for camera rays (as Materials.holdout = 1), the bit
    # CASTS_NO_SHADOW lets the direct light through it.
    triangle_visibility: np.ndarray = None
    # Light linking (Blender's Object > Shading > Light Linking, receivers; Cycles' light sets), or
    # None: every emitter lights every triangle.  receiver_sets (T,) uint8 the set (0 to 63) each
    # triangle receives light as; emitter_links (T,) uint64 for emissive triangles the sets their
    # light reaches, bit s for set s (Lights.links for lights).  An emitter lights a triangle
    # directly only if its bit for the triangle's set is on: a photon that first lands on a
    # triangle its emitter does not light ends there, and a camera path sees an emitter after a
    # reflection or refraction only if it lights the set of that vertex's triangle (Cycles).
    receiver_sets: np.ndarray = None
    emitter_links: np.ndarray = None
    # Shadow linking, or None: every triangle shadows every emitter.  blocker_sets (T,) uint8 each
    # triangle's blocker set; emitter_shadow_links (T,) uint64 for emissive triangles the sets that
    # shadow them (Lights.shadow_links for lights).  A triangle that does not shadow an emitter
    # still receives its direct light, and so does what lies behind it: photons on their way from
    # the emitter stop on such a triangle or pass it, each with probability 1/2 and twice the flux
    # (Cycles' shadow rays skip it for every surface behind).
    blocker_sets: np.ndarray = None
    emitter_shadow_links: np.ndarray = None
    # (T,) uint8 for emissive triangles the rays their light does not reach (bits EXCLUDE_*, as
    # Lights.exclude: the object's Ray Visibility boxes), or None: 0.  The triangles themselves still
    # meet every photon (triangle_visibility says which camera-path rays see them).
    emitter_exclude: np.ndarray = None
    # Light groups (Blender's View Layer > Light Groups; Cycles' Combined_<name> passes): their
    # names, and emitter_group (T,) int16 for emissive triangles and glowing volumes' triangles the
    # group each belongs to (an index into light_groups, -1 none), or None: none (Lights.group and
    # World.group for the others).  A group's pass is the image lit only by its emitters.
    light_groups: tuple = ()
    emitter_group: np.ndarray = None
    # (T, 3) float32 Cryptomatte's ids of each triangle's object, material and asset (the object's
    # topmost parent): MurmurHash3 of their names as floats (``core.cryptomatte``), or None: no
    # Cryptomatte passes.
    cryptomatte_ids: np.ndarray = None
    # (V, 3) float32 world the vertices Generated coordinates read where they are not ``vertices``:
    # a mesh's before its shape keys and deform modifiers (Blender's orco, which Cycles reads), or
    # None: ``vertices`` (or ``undisplaced``).
    generated_vertices: np.ndarray = None
    # (V, 3) float32 the vertices before true displacement (Materials.displacement_program), which
    # Generated coordinates read as Cycles' undisplaced ones; set by ``displacement.displace`` for a
    # render (never stored), else None.
    undisplaced: np.ndarray = None

    # ------------------------------------------------------------------ queries
    @property
    def triangle_count(self) -> int:
        return int(len(self.triangles))

    def triangle_corners(self) -> np.ndarray:
        """(T, 3, 3) float32 world positions of every triangle's corners."""
        return self.vertices[self.triangles]

    def bounds(self):
        """(lo, hi) float64 (3,) of the geometry and light positions; a unit box if empty."""
        used = np.zeros(len(self.vertices), bool)
        used[self.triangles] = True                  # O(T), where np.unique sorts
        # (all of them, as a rule: a boolean gather and a float64 copy of millions of vertices
        # took a second)
        pts = [self.vertices if used.all() else self.vertices[used]]
        if self.lights.count:
            finite = self.lights.kind != SUN
            pts.append(self.lights.position[finite])
        pts = [np.asarray(a).reshape(-1, 3) for a in pts if len(a)]
        if not pts:
            return np.full(3, -1.0), np.full(3, 1.0)
        # Column by column: NumPy reduces over axis 0 of an (n, 3) array ~10x slower.
        lo = np.array([min(float(a[:, k].min()) for a in pts) for k in range(3)])
        hi = np.array([max(float(a[:, k].max()) for a in pts) for k in range(3)])
        return lo, hi

    def live_materials(self):
        """(materials,) bool: the materials some triangle has (a material in a slot no face uses is
        never evaluated)."""
        live = np.zeros(self.materials.count, bool)
        live[np.asarray(self.material_ids, np.int64)] = True
        return live

    # --------------------------------------------------------------- validation
    def validate(self) -> "Scene":
        """Check shapes, dtypes, ranges and finiteness; raise :class:`SceneError` naming the field.

        Returns ``self`` with arrays converted to the documented dtypes, so
        ``scene = scene.validate()`` is the usual call.
        """
        def fail(msg):
            raise SceneError(msg)

        def arr(name, a, dtype, tail, n=None, finite=True):
            if a is None:
                fail(f"{name} is missing")
            a = np.asarray(a)
            if a.ndim != 1 + len(tail) or tuple(a.shape[1:]) != tuple(tail):
                fail(f"{name} must have shape (n, {', '.join(map(str, tail))}) but has {a.shape}"
                     if tail else f"{name} must be one-dimensional but has shape {a.shape}")
            if n is not None and len(a) != n:
                fail(f"{name} has {len(a)} rows, expected {n}")
            if finite and np.issubdtype(a.dtype, np.floating) and not np.isfinite(a).all():
                fail(f"{name} contains NaN or infinite values")
            return np.ascontiguousarray(a.astype(dtype, copy=False))

        self.vertices = arr("vertices", self.vertices, np.float32, (3,))
        if self.generated_vertices is not None:
            self.generated_vertices = arr("generated_vertices", self.generated_vertices, np.float32, (3,),
                                          len(self.vertices))
        self.triangles = arr("triangles", self.triangles, np.int32, (3,))
        t = len(self.triangles)
        if t and (self.triangles.min() < 0 or self.triangles.max() >= len(self.vertices)):
            fail(f"triangles index vertices outside [0, {len(self.vertices)})")
        self.material_ids = arr("material_ids", self.material_ids, np.int32, (), t)
        mats = self.materials
        nm = mats.count
        if t and nm == 0:
            fail("the scene has triangles but no materials")
        if t and (self.material_ids.min() < 0 or self.material_ids.max() >= nm):
            fail(f"material_ids outside [0, {nm})")
        if mats.dielectric_reflection_color is None and mats.dielectric_color is not None:
            mats.dielectric_reflection_color = np.array(mats.dielectric_color, np.float32)
        if mats.dielectric_roughness is None and mats.ior is not None:
            mats.dielectric_roughness = np.zeros(len(mats.ior), np.float32)
        if mats.glossy_multiscatter is None and mats.glossy_color is not None:
            mats.glossy_multiscatter = np.array(mats.glossy_color, np.float32)   # Blender's default
        if mats.ior is not None:
            n = len(mats.ior)
            for name, shape, value in (("glossy_fresnel_ior", (n,), 0.0),
                                       ("glossy_fresnel_rise", (n, 3), 0.0),
                                       ("glossy_metal_rise", (n, 3), 0.0),
                                       ("glossy_metal_dip", (n, 3), 0.0),
                                       ("glossy_metal_tint", (n, 3), -1.0),
                                       ("glossy_metal_share", (n,), 1.0), ("glossy_metal_rest", (n, 3), 0.0),
                                       ("diffuse_layer", (n, 3), 0.0), ("diffuse_layer_weight", (n,), 1.0),
                                       ("normal_texture", (n,), -1), ("normal_strength", (n,), 1.0),
                                       ("bump_texture", (n,), -1), ("bump_strength", (n,), 1.0),
                                       ("bump_distance", (n,), 1.0), ("diffuse_program", (n,), -1),
                                       ("glossy_program", (n,), -1), ("emission_program", (n,), -1),
                                       ("roughness_program", (n,), -1), ("dielectric_program", (n,), -1),
                                       ("bump_program", (n,), -1), ("opacity", (n,), 1.0),
                                       ("outer_bump_program", (n,), -1), ("outer_bump_strength", (n,), 1.0),
                                       ("outer_bump_distance", (n,), 1.0),
                                       ("coat_normal_program", (n,), -1), ("coat_bump_program", (n,), -1),
                                       ("coat_bump_strength", (n,), 1.0), ("coat_bump_distance", (n,), 1.0),
                                       ("dielectric_fresnel", (n,), 1.0),
                                       ("dielectric_multiscatter", (n, 3), 0.0),
                                       ("glossy_distribution", (n,), DISTRIBUTION_GGX),
                                       ("dielectric_distribution", (n,), DISTRIBUTION_GGX),
                                       ("displacement_program", (n,), -1),
                                       ("displacement_flags", (n,), 0), ("displacement_bump", (n,), 0),
                                       ("bump_correction", (n,), 1), ("film_thickness", (n,), 0.0),
                                       ("film_ior", (n,), 1.33), ("film_tint", (n, 3), 1.0),
                                       ("film_metal", (n,), 0.0), ("film_metal_ior", (n, 3), 0.0),
                                       ("film_metal_extinction", (n, 3), 0.0),
                                       ("subsurface_weight", (n,), 0.0),
                                       ("subsurface_radius", (n, 3), 1.0),
                                       ("subsurface_anisotropy", (n,), 0.0),
                                       ("subsurface_ior", (n,), 1.4), ("subsurface_alpha", (n,), 1.0),
                                       ("subsurface_method", (n,), SUBSURFACE_RANDOM_WALK),
                                       ("opacity_program", (n,), -1),
                                       ("transparent_color", (n, 3), 1.0), ("coat_weight", (n,), 0.0),
                                       ("coat_roughness", (n,), 0.03), ("coat_ior", (n,), 1.5),
                                       ("coat_tint", (n, 3), 1.0), ("volume_absorption", (n, 3), 0.0),
                                       ("volume_scattering", (n, 3), 0.0), ("volume_anisotropy", (n,), 0.0),
                                       ("volume_phase", (n,), 0), ("volume_phase_params", (n, 3), 0.0),
                                       ("volume_emission", (n, 3), 0.0),
                                       ("holdout", (n,), 0.0), ("translucent_weight", (n,), 0.0),
                                       ("translucent_color", (n, 3), 0.0), ("translucent_program", (n,), -1),
                                       ("sheen_color", (n, 3), 0.0), ("sheen_roughness", (n,), 0.5),
                                       ("sheen_cover", (n,), 0.0), ("pass_index", (n,), 0.0),
                                       ("diffuse_roughness", (n,), 0.0), ("glossy_stretch", (n,), 1.0),
                                       ("glossy_rotation", (n,), 0.0), ("rotation_program", (n,), -1),
                                       ("stretch_program", (n,), -1), ("level_program", (n,), -1),
                                       ("level_first", (n,), -1), ("level_count", (n,), 0),
                                       ("normal_program", (n,), -1), ("normal_space", (n,), NORMAL_TANGENT),
                                       ("glossy_tangent", (n,), TANGENT_RADIAL_Z)):
                if getattr(mats, name) is None:
                    setattr(mats, name, np.full(shape, value, np.int32 if name in Materials.INTEGER_FIELDS
                                                else np.float32))
        for name in Materials.ARRAY_FIELDS:
            colour = name.endswith(("color", "emission", "multiscatter", "rise", "dip", "layer", "tint",
                                    "absorption", "scattering", "rest", "radius", "film_metal_ior",
                                    "film_metal_extinction", "phase_params"))
            tail = (3,) if colour else ()
            dtype = np.int32 if name in Materials.INTEGER_FIELDS else np.float32
            v = arr(f"materials.{name}", getattr(mats, name), dtype, tail, nm)
            if name not in Materials.SIGNED_FIELDS and (v < 0).any():
                bad = int(np.flatnonzero((v < 0).reshape(nm, -1).any(axis=1))[0])
                fail(f"materials.{name} is negative for material '{mats.names[bad]}'")
            setattr(mats, name, v)
        if (mats.ior <= 0).any():
            fail("materials.ior must be positive")
        tint = mats.glossy_metal_tint
        per_hit = (tint >= 0).any(axis=1)
        odd = per_hit & (((tint < 0) | (tint > 1)).any(axis=1)
                         | ((mats.glossy_fresnel_ior > 0) & (mats.glossy_metal_share >= 1.0))
                         | (mats.glossy_metal_rise != 0).any(axis=1)
                         | (mats.glossy_metal_dip != 0).any(axis=1))
        if odd.any():
            fail(f"materials.glossy_metal_tint of material '{mats.names[int(np.argmax(odd))]}' must be -1 or "
                 "in [0, 1] in every channel, on a lobe without a metal rise or dip, and without a "
                 "Fresnel rise unless glossy_metal_share < 1")
        share, rest = mats.glossy_metal_share, mats.glossy_metal_rest
        odd = ((share <= 0) | (share > 1)) | (rest > 1).any(axis=1)
        if odd.any():
            fail(f"material '{mats.names[int(np.argmax(odd))]}': glossy_metal_share must be in (0, 1] and "
                 "glossy_metal_rest in [0, 1]")
        for name, low, high in (("opacity", 0.0, 1.0), ("coat_weight", 0.0, 1.0), ("holdout", 0.0, 1.0),
                                ("dielectric_fresnel", 0.0, 1.0), ("dielectric_multiscatter", 0.0, 1.0),
                                ("displacement_flags", 0, DISPLACE_WORLD | DISPLACE_KEEPS_NORMALS
                                 | DISPLACE_VECTOR),
                                ("displacement_bump", 0, 1), ("bump_correction", 0, 1),
                                ("film_thickness", 0.0, 1e6), ("film_ior", 1e-5, 100.0),
                                ("film_tint", 0.0, 1.0), ("film_metal", 0.0, 1.0),
                                ("film_metal_ior", 0.0, 100.0), ("film_metal_extinction", 0.0, 100.0),
                                ("subsurface_weight", 0.0, 1.0), ("subsurface_radius", 0.0, np.inf),
                                ("subsurface_anisotropy", 0.0, 0.9), ("subsurface_ior", 1.01, 3.8),
                                ("subsurface_alpha", 0.0, 1.0),
                                ("subsurface_method", SUBSURFACE_RANDOM_WALK, SUBSURFACE_SKIN),
                                ("diffuse_roughness", 0.0, 1.0), ("volume_anisotropy", -0.99, 0.99),
                                ("volume_phase", 0, 4), ("volume_phase_params", 0.0, 1e6),
                                ("sheen_roughness", 0.0, 1.0),
                                ("coat_roughness", 0.0, 1.0), ("coat_ior", 1.0, np.inf),
                                ("glossy_stretch", 0.01, 100.0), ("glossy_tangent", 0, TANGENT_UV),
                                ("normal_space", NORMAL_TANGENT, NORMAL_BLENDER_WORLD),
                                ("glossy_distribution", DISTRIBUTION_GGX, DISTRIBUTION_BECKMANN),
                                ("dielectric_distribution", DISTRIBUTION_GGX, DISTRIBUTION_BECKMANN)):
            outside = (getattr(mats, name) < low) | (getattr(mats, name) > high)
            if outside.ndim > 1:
                outside = outside.any(axis=1)
            if outside.any():
                fail(f"materials.{name} is outside [{low}, {high}] for material "
                     f"'{mats.names[int(np.argmax(outside))]}'")
        rough = mats.dielectric_roughness
        odd = ~(((rough >= 0) & (rough <= 1)) | ((rough == -1) & (mats.roughness_program >= 0)))
        if odd.any():
            fail(f"material '{mats.names[int(np.argmax(odd))]}': dielectric_roughness must be in [0, 1], "
                 "or -1 (the roughness program's) where roughness_program is set")
        # (what the scene lacks matters only to the materials its triangles have: a slot no face uses
        # may read UVs the exporter left out)
        live = self.live_materials()
        self._validate_programs(fail, live)
        self._validate_levels(fail)
        for name in Materials.INT_FIELDS:
            v = getattr(mats, name)
            if ((v < -1) | (v >= len(self.textures))).any():
                fail(f"materials.{name} must be -1 or an index below {len(self.textures)}")
        imaged = any((live & (getattr(mats, name) >= 0)).any() for name in Materials.INT_FIELDS)
        if imaged and self.uvs is None:
            fail("materials use image textures but the scene has no uvs")
        mapped = live & (mats.normal_texture >= 0)
        if (mapped & (mats.normal_space == NORMAL_TANGENT)).any() and self.tangents is None:
            fail("materials use normal maps but the scene has no tangents")
        in_objects = np.isin(mats.normal_space, (NORMAL_OBJECT, NORMAL_BLENDER_OBJECT))
        if (mapped & in_objects).any() and self.object_ids is None:
            fail("materials use object-space normal maps but the scene has no objects")
        uv_tangents = live & (mats.glossy_tangent == TANGENT_UV) & ((mats.glossy_stretch != 1.0)
                                                                    | (mats.stretch_program >= 0))
        if uv_tangents.any() and self.tangents is None:
            fail("materials take an anisotropic glossy lobe's tangent from the UV map but the scene has "
                 "no tangents")
        self.textures = [self._texture(i, x) for i, x in enumerate(self.textures)]
        def per_corner(name, a, k):
            a = np.asarray(a)
            if a.shape != (t, 3, k):
                fail(f"{name} must have shape (T, 3, {k}) = ({t}, 3, {k}) but has {a.shape}")
            return arr(name, a.reshape(t, 3 * k), np.float32, (3 * k,), t).reshape(t, 3, k)

        if self.shading_normals is not None:
            self.shading_normals = per_corner("shading_normals", self.shading_normals, 3)
        if self.uvs is not None:
            self.uvs = per_corner("uvs", self.uvs, 2)
        if self.tangents is not None:
            self.tangents = per_corner("tangents", self.tangents, 4)
        if self.vertex_colors is not None:
            self.vertex_colors = per_corner("vertex_colors", self.vertex_colors, 3)
        if self.attributes is not None:
            if not all(isinstance(k, str) and k for k in self.attributes):
                fail("attributes must be named by non-empty strings")
            self.attributes = {k: per_corner(f"attributes['{k}']", v, 3) for k, v in self.attributes.items()}
        if self.object_ids is not None:
            self._validate_objects(fail, arr, t)
        if self.cryptomatte_ids is not None:
            self.cryptomatte_ids = arr("cryptomatte_ids", self.cryptomatte_ids, np.float32, (3,), t)
        if self.triangle_visibility is not None:
            self.triangle_visibility = arr("triangle_visibility", self.triangle_visibility, np.uint8, (), t)
            if t and self.triangle_visibility.max() > 63:
                fail("triangle_visibility must be a bit mask of VISIBLE_CAMERA, VISIBLE_GLOSSY, "
                     "VISIBLE_TRANSMISSION, HOLDOUT_OBJECT, CASTS_NO_SHADOW and SHADOW_CATCHER (0 to 63)")
        groups = self.light_groups
        if isinstance(groups, str) or not all(isinstance(g, str) and g for g in groups) \
                or len(set(groups)) != len(groups):
            fail(f"light_groups must be distinct non-empty names, not {groups!r}")
        self.light_groups = tuple(groups)
        if self.emitter_group is not None:
            self.emitter_group = arr("emitter_group", self.emitter_group, np.int16, (), t)
            if t and ((self.emitter_group < -1) | (self.emitter_group >= len(groups))).any():
                fail(f"emitter_group must be -1 or index light_groups ({len(groups)} of them)")
        if self.emitter_exclude is not None:
            self.emitter_exclude = arr("emitter_exclude", self.emitter_exclude, np.uint8, (), t)
            if t and (self.emitter_exclude & ~np.uint8(EXCLUDE_ALL)).any():
                fail(f"emitter_exclude must be a bit mask of EXCLUDE_* (a subset of {EXCLUDE_ALL})")
        for sets, links in (("receiver_sets", "emitter_links"), ("blocker_sets", "emitter_shadow_links")):
            if getattr(self, sets) is not None:
                v = arr(sets, getattr(self, sets), np.uint8, (), t)
                if t and v.max() >= MAX_RECEIVER_SETS:
                    fail(f"{sets} must lie in [0, {MAX_RECEIVER_SETS})")
                setattr(self, sets, v)
            if getattr(self, links) is not None:
                setattr(self, links, arr(links, getattr(self, links), np.uint64, (), t))
        lights = self.lights
        nl = lights.count
        if lights.visibility is None and lights.kind is not None:
            lights.visibility = np.full(len(lights.kind), DEFAULT_LIGHT_VISIBILITY, np.uint8)
        if lights.soft_falloff is None and lights.kind is not None:
            lights.soft_falloff = np.ones(len(lights.kind), bool)
        if lights.spread is None and lights.kind is not None:
            lights.spread = np.full(len(lights.kind), np.pi, np.float32)
        if lights.profile is None and lights.kind is not None:
            lights.profile = np.full(len(lights.kind), -1, np.int16)
        for name in ("links", "shadow_links"):
            if getattr(lights, name) is None and lights.kind is not None:
                setattr(lights, name, np.full(len(lights.kind), ALL_LINKS, np.uint64))
        if lights.exclude is None and lights.kind is not None:
            lights.exclude = np.zeros(len(lights.kind), np.uint8)
        if lights.group is None and lights.kind is not None:
            lights.group = np.full(len(lights.kind), -1, np.int16)
        for name in Lights.ARRAY_FIELDS:
            tail = (3,) if name in ("position", "direction", "axis_u", "axis_v", "power") else ()
            dtype = {"kind": np.int8, "position": np.float64, "visibility": np.uint8,
                     "soft_falloff": bool, "profile": np.int16, "links": np.uint64,
                     "shadow_links": np.uint64, "exclude": np.uint8, "group": np.int16}.get(name, np.float32)
            v = arr(f"lights.{name}", getattr(lights, name), dtype, tail, nl)
            setattr(lights, name, v)
        if nl:
            if ((lights.kind < POINT) | (lights.kind > SUN)).any():
                fail("lights.kind must be one of POINT, SPOT, AREA_RECT, AREA_DISK, SUN")
            if (lights.power < 0).any():
                fail("lights.power must not be negative")
            if (np.abs(np.linalg.norm(lights.direction, axis=1) - 1) > 1e-3).any():
                fail("lights.direction must be unit vectors")
            for name in ("radius", "spot_angle", "spot_blend", "sun_angle", "spread"):
                if (getattr(lights, name) < 0).any():
                    fail(f"lights.{name} must not be negative")
            if (lights.visibility > 7).any():
                fail("lights.visibility must be a bit mask of VISIBLE_CAMERA, VISIBLE_GLOSSY and "
                     "VISIBLE_TRANSMISSION (0 to 7)")
            if (lights.exclude & ~np.uint8(EXCLUDE_ALL)).any():
                fail(f"lights.exclude must be a bit mask of EXCLUDE_* (a subset of {EXCLUDE_ALL})")
            if ((lights.group < -1) | (lights.group >= len(self.light_groups))).any():
                fail(f"lights.group must be -1 or index light_groups ({len(self.light_groups)} of them)")
            if (lights.spot_blend > 1).any():
                fail("lights.spot_blend must lie in [0, 1]")
            if any((getattr(lights, k) > np.pi).any() for k in ("spot_angle", "sun_angle", "spread")):
                fail("lights.spot_angle, lights.sun_angle and lights.spread must not exceed pi")
        self._validate_profiles(fail, lights)
        cam = self.camera
        m = np.asarray(cam.world_from_camera, np.float64)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            fail("camera.world_from_camera must be a finite 4x4 matrix")
        if abs(np.linalg.det(m[:3, :3])) < 1e-12:
            fail("camera.world_from_camera is singular")
        cam.world_from_camera = m
        if cam.projection not in PROJECTIONS:
            fail(f"camera.projection must be one of {PROJECTIONS}, not {cam.projection!r}")
        for name in ("latitude_range", "longitude_range", "sensor_size"):
            v = np.asarray(getattr(cam, name), np.float64)
            if v.shape != (2,) or not np.isfinite(v).all():
                fail(f"camera.{name} must be two finite numbers, got {getattr(cam, name)}")
            setattr(cam, name, (float(v[0]), float(v[1])))
        lat = cam.latitude_range
        if max(abs(lat[0]), abs(lat[1])) > np.pi / 2 + 1e-6 or lat[0] == lat[1]:
            fail(f"camera.latitude_range {lat} must span an angle within [-pi/2, pi/2]")
        cam.latitude_range = tuple(float(np.clip(v, -np.pi / 2, np.pi / 2)) for v in lat)
        if cam.longitude_range[0] == cam.longitude_range[1]:
            fail(f"camera.longitude_range {cam.longitude_range} must span an angle")
        for name in ("fisheye_fov", "fisheye_lens"):
            v = float(getattr(cam, name))
            if not (np.isfinite(v) and v > 0):
                fail(f"camera.{name} must be positive, got {v}")
            setattr(cam, name, v)
        if min(cam.sensor_size) <= 0:
            fail(f"camera.sensor_size {cam.sensor_size} must be positive")
        fx0, fx1, fy0, fy1 = (float(v) for v in cam.frame)
        if not (np.isfinite([fx0, fx1, fy0, fy1]).all() and fx1 > fx0 and fy1 > fy0):
            fail(f"camera.frame must be (x_min < x_max, y_min < y_max), got {cam.frame}")
        w, h = (int(v) for v in cam.resolution)
        if w < 1 or h < 1 or w * h > 2 ** 28:
            fail(f"camera.resolution {cam.resolution} must be positive and at most 2^28 pixels")
        cam.resolution = (w, h)
        b = tuple(float(v) for v in cam.border)
        if not (0 <= b[0] <= b[1] <= 1 and 0 <= b[2] <= b[3] <= 1):
            fail(f"camera.border {cam.border} must satisfy 0 <= min <= max <= 1")
        x0, x1, y0, y1 = cam.window
        if x1 <= x0 or y1 <= y0:
            fail(f"camera.border {cam.border} selects no pixels at resolution {cam.resolution}")
        if cam.aperture_radius < 0 or not np.isfinite(cam.aperture_radius):
            fail("camera.aperture_radius must be finite and not negative")
        if cam.aperture_radius > 0 and not cam.focus_distance > 0:
            fail("camera.focus_distance must be positive when depth of field is on")
        blades = float(cam.aperture_blades)
        if not (float(cam.aperture_ratio) > 0 and np.isfinite(cam.aperture_ratio)
                and np.isfinite(cam.aperture_rotation) and 0 <= blades <= 1000 and blades == int(blades)):
            fail("camera.aperture_ratio must be finite and positive, aperture_rotation finite and "
                 "aperture_blades between 0 and 1000")
        if not (0 <= cam.clip_start < cam.clip_end):
            fail("camera clip range must satisfy 0 <= clip_start < clip_end")
        if cam.pixel_filter not in PIXEL_FILTERS:
            fail(f"camera.pixel_filter must be one of {PIXEL_FILTERS}, not {cam.pixel_filter!r}")
        if not 0.01 <= float(cam.filter_width) <= 10.0:
            fail(f"camera.filter_width {cam.filter_width} must lie in [0.01, 10] pixels (Cycles' range)")
        cam.filter_width = float(cam.filter_width)
        _validate_background(self.world, "world", fail, len(self.textures))
        _validate_world_volume(self.world, fail)
        exclude = self.world.exclude
        if not isinstance(exclude, (int, np.integer)) or int(exclude) & ~EXCLUDE_ALL or int(exclude) < 0:
            fail(f"world.exclude must be a bit mask of EXCLUDE_* (a subset of {EXCLUDE_ALL}), "
                 f"not {exclude!r}")
        self.world.exclude = int(exclude)
        group = self.world.group
        if not isinstance(group, (int, np.integer)) or not -1 <= int(group) < len(self.light_groups):
            fail(f"world.group must be -1 or index light_groups ({len(self.light_groups)} of them), "
                 f"not {group!r}")
        self.world.group = int(group)
        for name in World.MIST_FIELDS:
            value = getattr(self.world, name)
            if not (isinstance(value, (int, float, np.integer, np.floating)) and np.isfinite(value)
                    and (value >= 0 if name != "mist_falloff" else value > 0)):
                fail(f"world.{name} must be a finite number >= 0 (> 0 for the falloff), not {value!r}")
            setattr(self.world, name, float(value))
        if self.world.camera is not None:
            _validate_background(self.world.camera, "world.camera", fail, len(self.textures))
        _validate_portals(self.world, fail)
        return self

    def _validate_objects(self, fail, arr, t):
        self.object_ids = arr("object_ids", self.object_ids, np.int32, (), t)
        for name in ("object_from_world", "texture_spaces"):
            if getattr(self, name) is None:
                fail(f"{name} is missing (the scene has object_ids)")
        n = len(self.object_from_world)
        self.object_from_world = arr("object_from_world", np.asarray(self.object_from_world).reshape(n, 12),
                                     np.float64, (12,)).reshape(n, 3, 4)
        spaces = np.asarray(self.texture_spaces).reshape(-1, 6)
        self.texture_spaces = arr("texture_spaces", spaces, np.float64, (6,), n).reshape(n, 2, 3)
        info = np.zeros((n, 6), np.float32) if self.object_info is None else self.object_info
        self.object_info = arr("object_info", info, np.float32, (6,), n)
        if t and (self.object_ids.min() < 0 or self.object_ids.max() >= n):
            fail(f"object_ids outside [0, {n})")
        if self.object_attributes is not None:
            names = self.object_attributes
            if not all(isinstance(k, str) and k.startswith(procedural.OBJECT_PROPERTY) for k in names):
                fail("object_attributes must be named 'object:' or 'instancer:' and a property")
            self.object_attributes = {k: arr(f"object_attributes['{k}']", v, np.float32, (3,), n)
                                      for k, v in self.object_attributes.items()}

    def _validate_levels(self, fail):
        mats = self.materials
        on = mats.level_program >= 0
        if not on.any():
            return
        first, count = mats.level_first[on], mats.level_count[on]
        bad = (count < 2) | (first < 0) | (first + count > mats.count)
        if not bad.any():
            rows = np.concatenate([np.arange(f, f + c) for f, c in zip(first, count)])
            bad = np.zeros_like(bad) if not (mats.level_program[rows] >= 0).any() else np.ones_like(bad)
        if bad.any():
            name = mats.names[int(np.flatnonzero(on)[int(np.argmax(bad))])]
            fail(f"material '{name}': level_first and level_count must name at least 2 materials of the "
                 "scene, none of them with a level_program")

    def _validate_programs(self, fail, live):
        mats = self.materials
        mats.programs = [procedural.from_json(p) if isinstance(p, str) else p for p in mats.programs]
        for name in Materials.PROGRAM_FIELDS:
            v = getattr(mats, name)
            if ((v < -1) | (v >= len(mats.programs))).any():
                fail(f"materials.{name} must be -1 or an index below {len(mats.programs)}")
        n_aov = len(mats.aov_names)
        m = len(mats.names)
        if mats.aov_writes is None:
            mats.aov_writes, mats.aov_program = np.zeros((m, 0), bool), np.zeros((m, 0), np.int32)
            mats.aov_value = np.zeros((m, 0, 3), np.float32)
        mats.aov_names = [str(n) for n in mats.aov_names]
        for name, shape in (("aov_writes", (m, n_aov)), ("aov_program", (m, n_aov)),
                            ("aov_value", (m, n_aov, 3))):
            if np.shape(getattr(mats, name)) != shape:
                fail(f"materials.{name} must have shape {shape} (materials, aov_names)")
        mats.aov_writes = np.asarray(mats.aov_writes, bool)
        mats.aov_program = np.asarray(mats.aov_program, np.int32)
        mats.aov_value = np.asarray(mats.aov_value, np.float32)
        if not np.isfinite(mats.aov_value).all():
            fail("materials.aov_value contains NaN or infinite values")
        if ((mats.aov_program < -1) | (mats.aov_program >= len(mats.programs))).any():
            fail(f"materials.aov_program must be -1 or an index below {len(mats.programs)}")
        used = np.concatenate([getattr(mats, name)[live] for name in Materials.PROGRAM_FIELDS]
                              + [mats.aov_program[live].ravel()])
        partial = (mats.glossy_metal_tint >= 0).all(axis=1) & (mats.glossy_metal_share < 1.0)
        rising = np.flatnonzero((mats.glossy_program >= 0) & (((mats.glossy_fresnel_ior > 0) & ~partial)
                                                                | (mats.glossy_metal_rise != 0).any(axis=1)
                                                                | (mats.glossy_metal_dip != 0).any(axis=1)))
        if len(rising):
            fail(f"material '{mats.names[rising[0]]}': a glossy_program cannot vary a glossy lobe with a "
                 "Fresnel rise (glossy_fresnel_ior, glossy_metal_rise, glossy_metal_dip) unless it is a "
                 "metal beside a dielectric layer (glossy_metal_tint, glossy_metal_share < 1)")
        coords = {"generated": self.object_ids, "object": self.object_ids, "normal": self.object_ids,
                  "object_location": self.object_ids, "object_color": self.object_ids,
                  "object_info": self.object_ids,
                  "uv": self.uvs,
                  "color": self.vertex_colors}
        for i, program in enumerate(mats.programs):
            try:
                procedural.validate(program, len(self.textures))
            except procedural.ProgramError as e:
                fail(f"materials.programs[{i}]: {e}")
            for name in procedural.attributes_used(program):
                if name in (procedural.GEOMETRY + procedural.VIEW + procedural.RAY + procedural.TRIANGLE
                            + procedural.TANGENTS):
                    continue                        # (the hit's position, normals, ray, camera, tangents)
                if name.startswith((procedural.NAMED, *procedural.OBJECT_PROPERTY)):
                    continue                        # (0 where the scene lacks it, as in Cycles)
                if coords[name] is None and (used == i).any():
                    fail(f"materials.programs[{i}] reads '{name}' coordinates but the scene has none")

    @staticmethod
    def _texture(i, x):
        x = np.asarray(x, np.float32)
        if x.ndim == 2:
            x = x[:, :, None]
        if x.ndim != 3 or x.shape[0] < 1 or x.shape[1] < 1 or x.shape[2] not in (1, 3, 4):
            raise SceneError(f"textures[{i}] must be an (H, W, 1|3|4) image, got shape {x.shape}")
        x = x[:, :, :3] if x.shape[2] >= 3 else np.repeat(x, 3, axis=2)
        if not np.isfinite(x).all():
            raise SceneError(f"textures[{i}] contains NaN or infinite values")
        return np.ascontiguousarray(x)

    @staticmethod
    def _validate_profiles(fail, lights):
        """``lights.profiles`` and the ``profile`` indices into it (see :class:`Lights`)."""
        table = lights.profiles
        if table is not None:
            table = np.asarray(table, np.float32)
            if table.ndim != 3 or min(table.shape[1:]) < 2:
                fail("lights.profiles must be a (P, V, H) array with V, H >= 2")
            if not np.isfinite(table).all() or (table < 0).any():
                fail("lights.profiles must be finite and not negative")
            lights.profiles = np.ascontiguousarray(table)
        used = np.flatnonzero(lights.profile >= 0) if lights.count else np.zeros(0, np.int64)
        if len(used) == 0:
            return
        if table is None or (lights.profile.take(used) >= len(table)).any() or (lights.profile < -1).any():
            fail("lights.profile must be -1 or an index into lights.profiles")
        if (lights.kind.take(used) == SUN).any():
            fail("lights.profile applies to point, spot and area lights only")
        frame = np.stack([lights.axis_u.take(used, axis=0), lights.axis_v.take(used, axis=0),
                          -lights.direction.take(used, axis=0)], axis=1).astype(np.float64)
        frame /= np.maximum(np.linalg.norm(frame, axis=2, keepdims=True), 1e-30)
        if (np.abs(frame @ frame.transpose(0, 2, 1) - np.eye(3)) > 1e-3).any():
            fail("a light with a profile needs orthogonal axis_u, axis_v and direction")

    # ------------------------------------------------------------------ file io
    def to_arrays(self) -> dict:
        """A flat dict of NumPy arrays (no objects): for ``.npz`` files and worker processes."""
        d = {"format_version": np.int32(1), "vertices": self.vertices, "triangles": self.triangles,
             "material_ids": self.material_ids,
             "materials.names": np.array(self.materials.names, dtype=str)}
        for name in Materials.ARRAY_FIELDS:
            d[f"materials.{name}"] = getattr(self.materials, name)
        if self.materials.programs:
            d["materials.programs"] = np.array([procedural.to_json(p) for p in self.materials.programs], str)
        if self.materials.aov_names:
            d["materials.aov_names"] = np.array(self.materials.aov_names, str)
            for name in ("aov_writes", "aov_value", "aov_program"):
                d[f"materials.{name}"] = getattr(self.materials, name)
        for name in Lights.ARRAY_FIELDS:
            d[f"lights.{name}"] = getattr(self.lights, name)
        if self.lights.profiles is not None:
            d["lights.profiles"] = self.lights.profiles
        cam = self.camera
        d["camera.world_from_camera"] = np.asarray(cam.world_from_camera, np.float64)
        d["camera.projection"] = np.array(cam.projection)
        for name in ("frame", "resolution", "border"):
            d[f"camera.{name}"] = np.asarray(getattr(cam, name))
        for name in ("aperture_radius", "focus_distance", "clip_start", "clip_end"):
            d[f"camera.{name}"] = np.float64(getattr(cam, name))
        for name in Camera.PANORAMA_FIELDS:
            d[f"camera.{name}"] = np.asarray(getattr(cam, name), np.float64)
        d["camera.pixel_filter"] = np.array(cam.pixel_filter)
        d["camera.filter_width"] = np.float64(cam.filter_width)
        if cam.aperture_blades or cam.aperture_ratio != 1.0:
            d["camera.aperture_shape"] = np.array(
                [cam.aperture_blades, cam.aperture_rotation, cam.aperture_ratio], np.float64)
        d["world.color"] = np.asarray(self.world.color, np.float32)
        d["world.film_transparent"] = np.bool_(self.world.film_transparent)
        if self.world.exclude:
            d["world.exclude"] = np.uint8(self.world.exclude)
        if self.light_groups:
            d["light_groups"] = np.array(self.light_groups, str)
            d["world.group"] = np.int16(self.world.group)
        for name in World.MIST_FIELDS:
            d[f"world.{name}"] = np.float64(getattr(self.world, name))
        if self.world.texture is not None:
            d["world.texture"] = self.world.texture
        if self.world.texture_rotation is not None:
            d["world.texture_rotation"] = self.world.texture_rotation
        if self.world.portals is not None:
            d["world.portals"] = np.asarray(self.world.portals, np.float64)
            d["world.portal_disks"] = np.asarray(self.world.portal_disks, bool)
        if self.world.program is not None:
            d["world.program"] = np.array(procedural.to_json(self.world.program))
        if self.world.has_volume:
            for name in World.VOLUME_FIELDS:
                d[f"world.{name}"] = np.asarray(getattr(self.world, name), np.float32)
        camera_world = self.world.camera
        if camera_world is not None:
            d["world.camera.color"] = np.asarray(camera_world.color, np.float32)
            for key in ("texture", "texture_rotation"):
                if getattr(camera_world, key) is not None:
                    d[f"world.camera.{key}"] = getattr(camera_world, key)
            if camera_world.program is not None:
                d["world.camera.program"] = np.array(procedural.to_json(camera_world.program))
        if self.shading_normals is not None:
            d["shading_normals"] = self.shading_normals
        if self.uvs is not None:
            d["uvs"] = self.uvs
        if self.tangents is not None:
            d["tangents"] = self.tangents
        for name in ("vertex_colors", "object_ids", "object_from_world", "texture_spaces", "object_info",
                     "generated_vertices", "triangle_visibility", "receiver_sets", "emitter_links",
                     "blocker_sets",
                     "emitter_shadow_links", "emitter_exclude", "emitter_group", "cryptomatte_ids"):
            if getattr(self, name) is not None:
                d[name] = getattr(self, name)
        for name, values in (self.attributes or {}).items():
            d[f"attributes.{name}"] = values
        for name, values in (self.object_attributes or {}).items():
            d[f"object_attributes.{name}"] = values
        for i, tex in enumerate(self.textures):
            d[f"textures.{i}"] = tex
        return d

    @staticmethod
    def from_arrays(z) -> "Scene":
        """Inverse of :meth:`to_arrays` (also accepts an open ``.npz``); validates the result."""
        keys = set(z.keys()) if hasattr(z, "keys") else set(z.files)

        def get(k, default=None):
            return z[k] if k in keys else default

        mats = Materials(names=[str(s) for s in get("materials.names", np.array([], str))])
        for name in Materials.ARRAY_FIELDS:
            setattr(mats, name, get(f"materials.{name}"))
        mats.programs = [str(p) for p in get("materials.programs", np.array([], str))]
        if "materials.aov_names" in keys:
            mats.aov_names = [str(n) for n in get("materials.aov_names")]
            for name in ("aov_writes", "aov_value", "aov_program"):
                setattr(mats, name, get(f"materials.{name}"))
        lights = Lights(**{name: get(f"lights.{name}") for name in Lights.ARRAY_FIELDS},
                        profiles=get("lights.profiles"))
        cam = Camera(world_from_camera=get("camera.world_from_camera"),
                     projection=str(get("camera.projection")),
                     frame=tuple(float(v) for v in get("camera.frame")),
                     resolution=tuple(int(v) for v in get("camera.resolution")),
                     border=tuple(float(v) for v in get("camera.border")),
                     **{name: float(get(f"camera.{name}")) for name in
                        ("aperture_radius", "focus_distance", "clip_start", "clip_end")},
                     **_panorama_fields(get), **_filter_fields(get), **_aperture_fields(get))
        def program(key):
            return str(z[key]) if key in keys else None

        camera_world = (World(color=get("world.camera.color"), texture=get("world.camera.texture"),
                              texture_rotation=get("world.camera.texture_rotation"),
                              program=program("world.camera.program"))
                        if "world.camera.color" in keys else None)
        world = World(color=get("world.color"), texture=get("world.texture"),
                      texture_rotation=get("world.texture_rotation"),
                      film_transparent=bool(get("world.film_transparent", False)), camera=camera_world,
                      exclude=int(get("world.exclude", 0)), program=program("world.program"),
                      group=int(get("world.group", -1)), portals=get("world.portals"),
                      portal_disks=get("world.portal_disks"),
                      **{name: get(f"world.{name}") for name in World.VOLUME_FIELDS
                         if f"world.{name}" in keys},
                      **{name: float(get(f"world.{name}")) for name in World.MIST_FIELDS
                         if f"world.{name}" in keys})
        ntex = sum(1 for k in keys if k.startswith("textures."))
        scene = Scene(vertices=get("vertices"), triangles=get("triangles"),
                      material_ids=get("material_ids"), materials=mats, lights=lights,
                      camera=cam, world=world, shading_normals=get("shading_normals"),
                      uvs=get("uvs"), tangents=get("tangents"), vertex_colors=get("vertex_colors"),
                      object_ids=get("object_ids"), object_from_world=get("object_from_world"),
                      texture_spaces=get("texture_spaces"), object_info=get("object_info"),
                      generated_vertices=get("generated_vertices"),
                      triangle_visibility=get("triangle_visibility"),
                      receiver_sets=get("receiver_sets"), emitter_links=get("emitter_links"),
                      blocker_sets=get("blocker_sets"), emitter_shadow_links=get("emitter_shadow_links"),
                      emitter_exclude=get("emitter_exclude"), cryptomatte_ids=get("cryptomatte_ids"),
                      light_groups=tuple(str(g) for g in get("light_groups", ())),
                      emitter_group=get("emitter_group"),
                      textures=[get(f"textures.{i}") for i in range(ntex)],
                      attributes={k[len("attributes."):]: z[k] for k in sorted(keys)
                                  if k.startswith("attributes.")} or None,
                      object_attributes={k[len("object_attributes."):]: z[k] for k in sorted(keys)
                                         if k.startswith("object_attributes.")} or None)
        return scene.validate()

    def save(self, path) -> None:
        """Write the scene to a ``.npz`` file (no pickles; loadable with :meth:`load`)."""
        np.savez_compressed(path, **self.to_arrays())

    @staticmethod
    def load(path) -> "Scene":
        """Read a scene written by :meth:`save` and validate it."""
        try:
            z = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as e:
            raise SceneError(f"cannot read scene file {path}: {e}") from e
        with z:
            return Scene.from_arrays(z)

    def replace(self, **changes) -> "Scene":
        """A shallow copy with some fields replaced (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    # The fields that hold one entry per triangle (first axis T; ``attributes`` a dict of them).
    PER_TRIANGLE = ("triangles", "material_ids", "shading_normals", "uvs", "tangents", "object_ids",
                    "vertex_colors", "triangle_visibility", "receiver_sets", "emitter_links", "blocker_sets",
                    "emitter_shadow_links", "emitter_exclude", "emitter_group", "cryptomatte_ids")

    def take_triangles(self, rows) -> "Scene":
        """A shallow copy with only the triangles ``rows`` (indices or a (T,) bool mask), and their
        entries of every per-triangle field (``PER_TRIANGLE``); the vertices, materials, lights,
        camera, world and objects stay."""
        rows = np.flatnonzero(rows) if np.asarray(rows).dtype == bool else np.asarray(rows, np.int64)
        changes = {name: getattr(self, name).take(rows, axis=0) for name in self.PER_TRIANGLE
                   if getattr(self, name) is not None}
        if self.attributes is not None:
            changes["attributes"] = {k: v.take(rows, axis=0) for k, v in self.attributes.items()}
        return self.replace(**changes)


def _stored_program(mats, stored, program):
    """The index of ``program`` in ``mats.programs``, appended once (``stored``: its JSON -> index)."""
    key = procedural.to_json(program)
    if key not in stored:
        stored[key] = len(mats.programs)
        mats.programs.append(procedural.from_json(key))
    return stored[key]


def _aperture_fields(get):
    """The aperture's shape stored in a file (a disc where none is: files from before it, discs)."""
    shape = get("camera.aperture_shape")
    if shape is None:
        return {}
    return {"aperture_blades": int(shape[0]), "aperture_rotation": float(shape[1]),
            "aperture_ratio": float(shape[2])}


def _filter_fields(get):
    """The camera's pixel filter stored in a file (files from before it have none: a box of 1)."""
    kind, width = get("camera.pixel_filter"), get("camera.filter_width")
    return {} if kind is None else {"pixel_filter": str(kind), "filter_width": float(width)}


def _panorama_fields(get):
    """The panoramic camera's fields stored in a file (files from before panoramas have none)."""
    out = {}
    for name in Camera.PANORAMA_FIELDS:
        v = get(f"camera.{name}")
        if v is not None:
            out[name] = float(v) if np.ndim(v) == 0 else tuple(float(x) for x in v)
    return out

"""Blender materials -> ``core.Materials`` (weighted lobes) and image textures.

A node walker follows the material's Cycles output (``Surface``) through
reroutes, node groups, Mix and Add Shader nodes and reduces the shader to a
:class:`Closure`: weights and colours of the core's lobes (diffuse, glossy,
mirror, dielectric, translucent), a sheen and emitted radiance.  Mix/Add combine closures linearly,
which is exact for emission and for lobes of one kind with different colours,
and an average for glossy roughness and IOR.

Supported nodes: Principled BSDF (with its Alpha), Diffuse, Glossy, Metallic, Glass, Refraction,
Translucent, Sheen, Emission, Transparent, Holdout, Mix Shader, Add Shader, reroutes and groups, and
approximated (noted) the Principled Hair and Hair BSDFs (``_hair_principled``); on colour
and number inputs the texture and colour nodes of ``procedural.py`` (a varying diffuse colour becomes a
program the core evaluates at each hit, an Image Texture on the active UV map stays a plain image
texture; other inputs take the mean); and on a BSDF's Normal input a tangent-space Normal Map node
fed by an Image Texture, a Bump node whose Height comes from an Image Texture, or a Bump on
a Normal Map (one of each per material: the first that a Mix or Add meets).
A Mix Shader of a Diffuse and a Glossy BSDF by a Fresnel curve (Fresnel node, Layer Weight's
Fresnel) is a Fresnel layer (``_fresnel_layer``); a Mix of any shader and a clear Transparent
BSDF by Light Path's Is Camera, Glossy or Transmission Ray is that shader hidden from those rays
(``Closure.hidden_rays``, the object's ray visibility of its triangles).
Anything else becomes a grey diffuse closure (for shaders; EEVEE's Specular BSDF no closure, black,
as in Cycles) or the socket's own value (for colours and numbers), and the material gets *one*
warning naming every such node.

Principled BSDF mapping (``metallic`` m, ``Transmission Weight`` t, specular
level s, base colour B):
  * metal, weight m: glossy lobe with the F82 Fresnel curve of B and the Specular Tint
    (``metal_curve``) and the node's roughness;
  * glass, weight (1 - m) t: dielectric lobe with colour sqrt(B) (Cycles' tint per interface),
    reflections tinted by the Specular Tint instead, the node's IOR and roughness;
  * dielectric base, weight (1 - m)(1 - t): as Cycles, a glossy layer of IOR n' (the IOR
    whose F0 is the node's F0 times 2 s, ``specular_ior``) reflecting f0 + (1 - f0) s(c),
    f0 = F0 times the Specular Tint and s the real Fresnel curve rescaled to [0, 1]
    (the core's ``glossy_fresnel_*``), over a diffuse lobe of colour B whose weight the core
    scales by 1 - the layer's albedo at the view direction (``diffuse_layer``; Cycles'
    ``closure_layering_weight``).  A Mix with other shaders keeps the share of the diffuse
    under the layer (``diffuse_layer_weight``).
  * sheen (Sheen Weight w, Sheen Tint T): the core's sheen (Cycles' microfiber sheen) of colour
    w T and the Sheen Roughness, a layer over all of the node's other parts (and its coat and
    emission), which the core dims by 1 - k E(mu), k = max(w T) and E the sheen's albedo
    (Cycles' ``closure_layering_weight``).  The Sheen BSDF is the same sheen of its Color, a
    shader of its own (k = 0).
  A texture on m (a metallic map) or else on t gives the node at ``MAP_LEVELS`` values of it as
  levels, of which the core picks one of the two around the map's value at each point, by the
  fraction between them (``Closure.levels``, ``Materials.level_program``): their mix, exactly.
Metals (Metallic node, Principled metallic) are a glossy lobe whose colour follows the metal's
Fresnel curve by the microfacet angle (``Materials.glossy_metal_rise`` and ``glossy_metal_dip``):
the F82-tint model (base colour, edge tint; Principled uses its Specular Tint), or that model
through the physical conductor's reflectance face on and at cos = 1/7 (``conductor_f82``).  A
texture on a metal's base colour makes its F0 a program beside its edge tint
(``Materials.glossy_metal_tint``), and the core takes the curve of each hit's F0, also beside a
plain glossy colour in the same lobe (the specular layer of a Principled partly metallic, a
Glossy BSDF or a paint mixed in at a constant factor: ``glossy_metal_share``); a textured edge
tint, or such a metal sharing the glossy lobe with another metal's curve or by a varying factor,
makes its colour the curve's mean (at each point where it can: ``metal`` in
``core/procedural.py``), without the curve.
Anisotropy (Glossy and Metallic Anisotropy, Principled's Anisotropic) becomes the core's
``glossy_stretch`` (alpha s along the tangent, alpha / s across it, Cycles' alphas; a texture on
it stays a program of s, ``stretch_program``: an anisotropy map, its mean where the material also
has a roughness map, noted), with the
Rotation (a texture on it stays a program, ``rotation_program``: a rotation map) and the Tangent
input: unlinked, Cycles' default radial tangent about the object's Z axis (the scene then carries
the objects' Generated coordinates), or a Tangent node (radial about its axis, or its UV map's
tangents); anything else there is noted.
The Diffuse BSDF's Roughness and Principled's Diffuse Roughness become the core's rough diffuse
(``diffuse_roughness``, Cycles' Oren-Nayar); a Mix weighs them by the diffuse weights.
Glossy, Metallic and Principled nodes set to Multiscatter GGX (Blender's default) get the
core's energy compensation with the mean Fresnel colour F_ss Cycles uses: the colour for
Glossy and metals, the layer's reflectance for the dielectric specular layer; Mix and Add
average it weighted by each glossy part's colour.  Other distributions are single-scattering GGX.
Glass and Refraction keep their roughness (GGX microfacet glass, single scattering: Cycles'
multiscatter glass keeps a little more light at high roughness).
Roughness below 0.02 is turned into a mirror (smooth glass) by the core.  Textures are
kept only where the core supports them (the diffuse colour, a glossy colour without a Fresnel
rise, the glossy roughness, anisotropy and rotation, the emission's colour and strength, the colour
a glass transmits, the translucent colour);
elsewhere their mean is used (e.g. the sheen's weight, tint, colour and roughness, noted).
A missing image file gives a warning and Cycles' magenta.

The Volume output: Volume Absorption, Volume Scatter and Principled Volume (their Add and Mix)
become the core's ``volume_absorption``, ``volume_scattering`` and ``volume_anisotropy``,
Cycles' coefficients, and Principled Volume's emission (Emission Strength and Color, Blackbody) and
an Emission shader on the Volume output its ``volume_emission`` (the world's is noted and left
out).  A material with a volume and no Surface is Cycles' volume-only mesh:
a surface that lets every ray through (opacity 0).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ...core import procedural, thin_film
from ...core.phase import FOURNIER_FORAND, HENYEY_GREENSTEIN, PHASE_NAMES
from ...core.bsdf import (DISTRIBUTION_BECKMANN, TANGENT_RADIAL_X, TANGENT_RADIAL_Y, TANGENT_RADIAL_Z,
                          TANGENT_UV, metal_curve, metal_fresnel)
from ...core.imageio import linear_to_srgb
from ...core.sampling import dielectric_f0, fresnel_dielectric, mean_fresnel
from ...core.scene import (DISPLACE_KEEPS_NORMALS, DISPLACE_VECTOR, DISPLACE_WORLD, NORMAL_BLENDER_OBJECT,
                           NORMAL_BLENDER_WORLD, NORMAL_OBJECT, NORMAL_TANGENT, NORMAL_WORLD,
                           SUBSURFACE_RANDOM_WALK, SUBSURFACE_SKIN, VISIBLE_CAMERA, VISIBLE_GLOSSY,
                           VISIBLE_TRANSMISSION, Materials)
from ...core.sky import SkyTextureCache
from .procedural import FLOAT, VEC, ExpressionBuilder, layer_weight_ior
from .procedural import NODES as PROGRAM_NODES

LOBES = ("diffuse", "glossy", "mirror", "dielectric", "translucent")
DIFFUSE, GLOSSY, MIRROR, DIELECTRIC, TRANSLUCENT = range(5)
GREY = np.full(3, 0.8)                         # Cycles' default surface colour
TANGENT_DEFAULT = (TANGENT_RADIAL_Z, None)     # an unlinked Tangent input (Cycles' default Tangent node)
# The Normal Map node's spaces (core.scene.NORMAL_*).
NORMAL_SPACES = {"TANGENT": NORMAL_TANGENT, "OBJECT": NORMAL_OBJECT, "WORLD": NORMAL_WORLD,
                 "BLENDER_OBJECT": NORMAL_BLENDER_OBJECT, "BLENDER_WORLD": NORMAL_BLENDER_WORLD}
MISSING_TEXTURE = np.array([1.0, 0.0, 1.0])    # what Cycles shows for a missing image
MAX_ANISOTROPY = 0.99                           # |g| of volumes' phase functions (volume_anisotropy)
# Principled Volume's blackbody emission per T^4 (Cycles: the Stefan-Boltzmann constant 5.670373e-8
# W m^-2 K^-4, times 1e-6, over pi).
STEFAN_BOLTZMANN_CYCLES = 5.670373e-14 / np.pi


@dataclass
class Closure:
    """A shader reduced to the core's lobes: what one node output evaluates to."""

    weight: np.ndarray = field(default_factory=lambda: np.zeros(len(LOBES)))        # (5,) lobe weights
    color: np.ndarray = field(default_factory=lambda: np.zeros((len(LOBES), 3)))    # (5, 3) weight * colour
    roughness: float = 0.5          # glossy roughness (Blender's; its mean where it varies)
    diffuse_roughness: float = 0.0  # diffuse roughness (Oren-Nayar; its mean where it varies)
    roughness_texture: dict = None  # float program of the glossy roughness where it varies (a map)
    stretch: float = 1.0            # glossy anisotropy: alpha x s along the tangent, alpha / s across
    stretch_texture: dict = None    # float program of s where the anisotropy varies (an anisotropy map)
    rotation: float = 0.0           # the tangent's turn about the normal (turns; its mean where it varies)
    rotation_texture: dict = None   # float program of that turn where it varies (a rotation map)
    tangent: tuple = TANGENT_DEFAULT  # (core.bsdf.TANGENT_*, UV map name or None) of the tangent
    ior: float = 1.5                # dielectric index of refraction
    dielectric_roughness: float = 0.0   # dielectric (glass) roughness (Blender's; its mean where it varies)
    dielectric_roughness_texture: dict = None  # float program of it where it varies (a glass roughness map)
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))      # (3,) (mean) radiance
    emission_texture: dict = None   # program of the radiance where it varies (emission: its mean)
    texture: object = -1            # diffuse colour source: -1, an image index or a program (dict)
    glossy_texture: dict = None     # program of the glossy colour where it varies (color[GLOSSY]: its mean)
    metal_texture: dict = None      # program of a metal's F0 where it varies (glossy_texture: curve's mean)
    metal_tint: np.ndarray = None   # (3,) that metal's edge tint
    metal_layer: tuple = None       # (share, rest colour (3,), rest F_ss (3,)) of such a metal beside a
    #                                 dielectric layer in one glossy lobe (Materials.glossy_metal_share)
    levels: tuple = None            # (float program in [0, 1], [Closure]) the closures a map picks from
    #                                 at each point by its value (a metallic or transmission map, a Mix
    #                                 Shader's mask; Materials.level_program); this closure is their
    #                                 mix by the map's mean
    dielectric_texture: dict = None  # program of the glass's transmitted colour (color[DIELECTRIC]: its mean)
    translucent_texture: dict = None  # program of the translucent colour (color[TRANSLUCENT]: its mean)
    multiscatter: np.ndarray = field(default_factory=lambda: np.zeros(3))  # (3,) glossy weight*colour*F_ss
    # (3,) dielectric weight * F_ss (its transmission tint) of a Multiscatter GGX glass
    glass_multiscatter: np.ndarray = field(default_factory=lambda: np.zeros(3))
    beckmann: float = 0.0           # the glossy weight with Beckmann microfacets (the rest GGX)
    glass_beckmann: float = 0.0     # the dielectric weight with Beckmann microfacets
    reflection: np.ndarray = None   # (3,) dielectric weight * reflection colour; None: its colour
    refraction_only: float = 0.0    # the part of the dielectric weight that only refracts (Refraction
    #                                 BSDF: no Fresnel reflection, nothing under total internal reflection)
    fresnel_ior: float = 0.0        # IOR of the glossy lobe's Fresnel rise (Principled), 0: none
    film: tuple = None              # (thickness nm, IOR, specular tint (3,)) of a thin film on that layer,
    #                                 the glass and the metal
    film_metal: float = 0.0         # glossy weight of the metal (curve) under that film
    film_conductor: tuple = None    # (IOR (3,), extinction (3,)) of that metal if a physical conductor
    rise: np.ndarray = field(default_factory=lambda: np.zeros(3))          # (3,) glossy weight * rise
    metal_rise: np.ndarray = field(default_factory=lambda: np.zeros(3))    # (3,) weight * a metal's rise
    metal_dip: np.ndarray = field(default_factory=lambda: np.zeros(3))     # (3,) weight * its dip (F82 tint)
    layer: np.ndarray = field(default_factory=lambda: np.zeros(3))         # (3,) layered weight * f0
    layered: float = 0.0            # diffuse weight under the Fresnel layer
    transparent: np.ndarray = field(default_factory=lambda: np.zeros(3))   # (3,) weight * colour let through
    transparent_weight: float = 0.0  # weight of the Transparent part (1 - the mean opacity)
    opacity_texture: dict = None    # float program of the opacity where it varies (an alpha map)
    normal_map: tuple = None        # (texture index, strength, uv map name, NORMAL_* space) of a normal map
    # (texture index or height program, strength, distance[, (height program, strength, distance) of a
    # second Bump over it]) of a bump map
    bump: tuple = None
    displacement_bump: bool = False  # the bump (its first) is the Displacement output's
    coat: float = 0.0               # weight of a coat over everything (Principled's Coat), 0: none
    coat_roughness: float = 0.03    # the coat's roughness, IOR and tint
    coat_ior: float = 1.5
    coat_tint: np.ndarray = field(default_factory=lambda: np.ones(3))
    # The coat's own normal (Principled's Coat Normal): (normal program or None, (height program,
    # strength, distance) of a bump over it or None); None: the surface's before its maps.
    coat_normal: tuple = None
    sheen: np.ndarray = field(default_factory=lambda: np.zeros(3))        # (3,) weight * colour of a sheen
    sheen_roughness: float = 0.5    # the sheen's roughness (its mean by the sheens' colours where it varies)
    # k of a sheen layer (Principled's Sheen, times its share): the core dims the rest of the material
    # (its other lobes, coat and emission) by 1 - k E(mu), E the sheen's albedo; 0: no layer.
    sheen_cover: float = 0.0
    holdout: float = 0.0            # weight of a Holdout shader (what camera rays cut out)
    subsurface: float = 0.0         # the part of the diffuse weight that scatters beneath the surface
    # (radius (3,) scene units, anisotropy, IOR, entry alpha, core.scene.SUBSURFACE_*) of that part
    subsurface_params: tuple = None
    hidden_rays: int = 0            # VISIBLE_* bits of the camera-path rays that pass through it

    @staticmethod
    def lobe(index, weight, color, **kw) -> "Closure":
        c = Closure(**kw)
        c.weight[index] = weight
        c.color[index] = weight * np.asarray(color, np.float64)
        return c

    def combine(self, other, fa, fb, fac=None) -> "Closure":
        """fa * self + fb * other (Mix: fa = 1 - fac, fb = fac; Add: 1, 1).

        ``fac`` : a program for a Mix factor that varies over the surface (fa, fb are then its
        mean's): the diffuse colours are mixed by it exactly, point by point (weight times
        colour, divided by the mean diffuse weight), the other lobes by its mean."""
        wa, wb = fa * self.weight, fb * other.weight
        out = Closure(weight=wa + wb, color=fa * self.color + fb * other.color,
                      emission=fa * self.emission + fb * other.emission,
                      multiscatter=fa * self.multiscatter + fb * other.multiscatter,
                      glass_multiscatter=fa * self.glass_multiscatter + fb * other.glass_multiscatter,
                      beckmann=fa * self.beckmann + fb * other.beckmann,
                      glass_beckmann=fa * self.glass_beckmann + fb * other.glass_beckmann,
                      reflection=fa * self.glass_reflection() + fb * other.glass_reflection(),
                      rise=fa * self.rise + fb * other.rise, layer=fa * self.layer + fb * other.layer,
                      metal_rise=fa * self.metal_rise + fb * other.metal_rise,
                      metal_dip=fa * self.metal_dip + fb * other.metal_dip,
                      film_metal=fa * self.film_metal + fb * other.film_metal,
                      layered=fa * self.layered + fb * other.layered,
                      transparent=fa * self.transparent + fb * other.transparent,
                      transparent_weight=fa * self.transparent_weight + fb * other.transparent_weight,
                      holdout=fa * self.holdout + fb * other.holdout,
                      subsurface=fa * self.subsurface + fb * other.subsurface,
                      refraction_only=fa * self.refraction_only + fb * other.refraction_only,
                      sheen=fa * self.sheen + fb * other.sheen,
                      sheen_cover=fa * self.sheen_cover + fb * other.sheen_cover,
                      hidden_rays=self.hidden_rays & other.hidden_rays)
        out.roughness = _weighted(self.roughness, other.roughness, wa[GLOSSY], wb[GLOSSY])
        # Anisotropy: the stretch's geometric mean by the glossy weights, the tangent and its
        # rotation of the first anisotropic side (as the roughness, one lobe per material).
        out.stretch = float(np.exp(_weighted(np.log(self.stretch), np.log(other.stretch), wa[GLOSSY],
                                             wb[GLOSSY])))
        turned = [c for c, w in ((self, wa), (other, wb)) if w[GLOSSY] > 0 and c.anisotropic]
        if turned:
            out.rotation, out.tangent = turned[0].rotation, turned[0].tangent
            out.rotation_texture = turned[0].rotation_texture
        if any(c.stretch_texture is not None for c in turned):
            # The map's geometric mean by the glossy weights, as the constants'.
            terms = [(c.log_stretch_term(), w[GLOSSY]) for c, w in ((self, wa), (other, wb)) if w[GLOSSY] > 0]
            out.stretch_texture = {"op": "math", "operation": "EXPONENT", "a": _float_average(terms)}
        out.diffuse_roughness = _weighted(self.diffuse_roughness, other.diffuse_roughness, wa[DIFFUSE],
                                          wb[DIFFUSE])
        # One medium per material: the first side's that scatters beneath (mixes_exactly).
        beneath = [c.subsurface_params for c, f in ((self, fa), (other, fb)) if f * c.subsurface > 0]
        out.subsurface_params = beneath[0] if beneath else None
        sides = ((self, wa), (other, wb))
        out.roughness_texture = _mixed_map(sides, GLOSSY, "roughness_texture", Closure.roughness_term)
        rising = (wa[GLOSSY] * (self.fresnel_ior > 0), wb[GLOSSY] * (other.fresnel_ior > 0))
        # (no rising glossy part left, e.g. one side at factor 0: none)
        out.fresnel_ior = _weighted(self.fresnel_ior, other.fresnel_ior, *rising) if sum(rising) > 0 else 0.0
        # One film per material (its layer and glass): the first side's that has one where the
        # film counts (mixes_exactly tells where the two differ).
        filmed = [c.film for c, w in ((self, wa), (other, wb)) if c.film is not None
                  and ((w[GLOSSY] > 0 and (c.fresnel_ior > 0 or c.film_metal > 0)) or w[DIELECTRIC] > 0)]
        out.film = filmed[0] if filmed else None
        # (and the first filmed metal's complex index, if a physical conductor)
        metals = [c.film_conductor for c, w in ((self, wa), (other, wb))
                  if c.film_metal > 0 and w[GLOSSY] > 0]
        out.film_conductor = metals[0] if metals else None
        out.ior = _weighted(self.ior, other.ior, wa[DIELECTRIC], wb[DIELECTRIC])
        out.dielectric_roughness = _weighted(self.dielectric_roughness, other.dielectric_roughness,
                                             wa[DIELECTRIC], wb[DIELECTRIC])
        out.dielectric_roughness_texture = _mixed_map(sides, DIELECTRIC, "dielectric_roughness_texture",
                                                      Closure.dielectric_roughness_term)
        # A coat lies over the whole material (one coat per material, NodeWalker._note_mixed):
        # its weight mixes as the lobes', its parameters by the coats' weights.
        ca, cb = fa * self.coat, fb * other.coat
        out.coat = ca + cb
        out.coat_roughness = _weighted(self.coat_roughness, other.coat_roughness, ca, cb)
        out.coat_ior = _weighted(self.coat_ior, other.coat_ior, ca, cb)
        out.coat_tint = ((ca * self.coat_tint + cb * other.coat_tint) / out.coat if out.coat > 0
                         else np.ones(3))
        coated = [c for c, w in ((self, ca), (other, cb)) if w > 0]
        out.coat_normal = coated[0].coat_normal if coated else None
        # One sheen per material: its roughness the mean by the sheens' (mean) colours.  A Principled's
        # sheen layer dims only that node's other parts in Cycles; the core dims the whole material
        # by the layers' k mixed as the weights (exact where the mixed shaders are alike: the same k
        # on both sides; beside another shader that one is dimmed too, and the node a little less).
        out.sheen_roughness = _weighted(self.sheen_roughness, other.sheen_roughness, fa * self.sheen.mean(),
                                        fb * other.sheen.mean())
        # One bent normal per material: the first side's that has weight.
        bent = [c for c, f in ((self, fa), (other, fb)) if f > 0 and (c.normal_map or c.bump)]
        out.normal_map, out.bump = (bent[0].normal_map, bent[0].bump) if bent else (None, None)
        total = out.weight[DIFFUSE]
        if total > 0 and (textured(self.texture) or textured(other.texture) or fac is not None):
            # The core multiplies the diffuse colour by a program: sum both sides' weight times
            # colour (each times its factor) and divide by the summed weight.
            shares = (fa, fb) if fac is None else (_one_minus(fac), fac)
            terms = [_times(c.diffuse_term(), f) for c, f, w in zip((self, other), shares, (wa, wb))
                     if w[DIFFUSE] > 0]
            mixed = terms[0] if len(terms) == 1 else _plus(*terms)
            if isinstance(mixed, dict):
                out.texture = _times(mixed, 1.0 / total)
                out.color[DIFFUSE] = total
            # (else the textured side has no weight, a Mix's factor exactly 0 or 1: the other
            # side's constant colour, fa * self.color + fb * other.color, stands)
        out.glossy_texture = self._mixed_glossy(other, wa, wb, fa, fb, fac)
        # A textured metal keeps its curve per point where it is the whole glossy lobe at one
        # weight; mixed with other glossy lobes or by a varying factor, its curve's mean per point.
        glossy = [(c, f) for c, f, w in ((self, fa, wa), (other, fb, wb)) if w[GLOSSY] > 0]
        if fac is None and len(glossy) == 1 and glossy[0][0].metal_texture is not None:
            out.metal_texture, out.metal_tint = glossy[0][0].metal_texture, glossy[0][0].metal_tint
            out.metal_layer = glossy[0][0].metal_layer
        elif fac is None and len(glossy) == 2:
            out._metal_beside(*glossy)
        out.emission_texture = self._mixed_emission(other, fa, fb, fac)
        out.dielectric_texture = self._mixed_lobe_program(other, wa, wb, DIELECTRIC, "dielectric_texture")
        out.translucent_texture = self._mixed_lobe_program(other, wa, wb, TRANSLUCENT, "translucent_texture")
        out.opacity_texture = self._mixed_opacity(other, fa, fb, fac)
        # One side's levels, each mixed as the whole (both sides': neither, the mean stands).
        if self.levels is not None and other.levels is None:
            out.levels = (self.levels[0], [c.combine(other, fa, fb, fac) for c in self.levels[1]])
        elif other.levels is not None and self.levels is None:
            out.levels = (other.levels[0], [self.combine(c, fa, fb, fac) for c in other.levels[1]])
        return out

    def _metal_beside(self, a, b):
        """Where one of the two glossy parts ``a`` and ``b`` ((closure, factor) each) mixed into this
        closure is a whole textured metal and the other a plain glossy colour, constant, with or
        without a dielectric rise (a paint; a Mix of metal and paint, or a mask's level between
        them): keep the metal's curve per hit beside it (``metal_layer``: the metal's share of
        the lobe, the paint's colour and F_ss per unit weight)."""
        for (metal, fm), (paint, fp) in ((a, b), (b, a)):
            if metal.beside_plain(paint):
                total = self.weight[GLOSSY]
                share, colour = fm * metal.weight[GLOSSY] / total, paint.color[GLOSSY]
                rest = fp * colour / total
                if share > 1.0 - 1e-6 or (rest > 1.0).any():     # (the core's bounds: the mean then)
                    return
                fss = np.divide(paint.multiscatter, colour, out=np.zeros(3), where=colour > 0)
                self.metal_texture, self.metal_tint = metal.metal_texture, metal.metal_tint
                self.metal_layer = (share, rest, fss)
                return

    @property
    def anisotropic(self) -> bool:
        return abs(self.stretch - 1.0) > 1e-6 or self.stretch_texture is not None

    def log_stretch_term(self):
        """log of the stretch: a number or a float program."""
        if self.stretch_texture is None:
            return float(np.log(self.stretch))
        return {"op": "math", "operation": "LOGARITHM", "a": self.stretch_texture, "b": float(np.e)}

    def opacity_term(self):
        """The opacity: a number or a float program."""
        return 1.0 - self.transparent_weight if self.opacity_texture is None else self.opacity_texture

    def _mixed_opacity(self, other, fa, fb, fac):
        """The opacity program of fa * self + fb * other, or None where it is constant."""
        if self.opacity_texture is None and other.opacity_texture is None and (
                fac is None or np.isclose(self.transparent_weight, other.transparent_weight)):
            return None
        if fac is None:
            terms = [(c.opacity_term(), f) for c, f in ((self, fa), (other, fb)) if f > 0]
            return _float_average(terms) if terms else None
        a, b = self.opacity_term(), other.opacity_term()
        return {"op": "mix_float", "fac": fac, "a": a, "b": b}

    @property
    def only_transparent(self) -> bool:
        """Whether this is a Transparent BSDF alone (nothing that scatters or emits)."""
        return (self.transparent_weight > 0 and not self.weight.any() and not self.emission.any()
                and not self.sheen.any())

    def _mixed_lobe_program(self, other, wa, wb, lobe, name):
        """The program ``name`` of the mix's colour of lobe ``lobe`` (the glass's transmitted
        colour, the translucent colour), or None: kept where one side alone has the lobe, or both
        the same program and colour; two different ones take their mean colours."""
        sides = [c for c, w in ((self, wa), (other, wb)) if w[lobe] > 0]
        if len(sides) == 1:
            return getattr(sides[0], name)
        a, b = self.color[lobe], other.color[lobe]          # weight times colour
        same = getattr(self, name) == getattr(other, name) and np.allclose(a * wb[lobe], b * wa[lobe])
        return getattr(self, name) if same else None

    def _mixed_emission(self, other, fa, fb, fac):
        """The radiance program of fa * self + fb * other, or None where it is constant."""
        if self.emission_texture is None and other.emission_texture is None and (
                fac is None or np.allclose(self.emission, other.emission)):
            return None
        if self.emission_texture == other.emission_texture and np.allclose(self.emission, other.emission):
            return _times(self.emission_texture, 1.0 if fac is not None else fa + fb)   # e.g. both halves
        shares = (fa, fb) if fac is None else (_one_minus(fac), fac)               # of a Principled
        terms = [_times(c.emission_term(), f) for c, f in zip((self, other), shares)
                 if c.emission_texture is not None or c.emission.any()]
        return terms[0] if len(terms) == 1 else _plus(*terms)

    def roughness_term(self):
        """The glossy roughness: a number or a float program."""
        return self.roughness if self.roughness_texture is None else self.roughness_texture

    def dielectric_roughness_term(self):
        """The glass's roughness: a number or a float program."""
        return (self.dielectric_roughness if self.dielectric_roughness_texture is None
                else self.dielectric_roughness_texture)

    def glass_roughness_map(self):
        """The float program the glass's roughness follows in the core (``roughness_program`` with
        ``dielectric_roughness`` -1), or None: a glass roughness map is kept where the material has
        no glossy lobe or one of the same map (Principled's one Roughness), the core having one
        roughness program per material; elsewhere its mean stands (noted by the walker)."""
        if self.dielectric_roughness_texture is None or self.weight[DIELECTRIC] <= 0:
            return None
        if self.weight[GLOSSY] > 0 and self.roughness_texture != self.dielectric_roughness_texture:
            return None
        return self.dielectric_roughness_texture

    def emission_term(self):
        """The emitted radiance: three numbers or a program."""
        return self.emission.tolist() if self.emission_texture is None else self.emission_texture

    @property
    def clear(self) -> bool:
        """Whether this is a white Transparent BSDF alone (lets every ray through untinted)."""
        return self.only_transparent and bool(np.allclose(self.transparent, self.transparent_weight))

    @property
    def diffuse_only(self) -> bool:
        """Whether this is a diffuse lobe alone (a Diffuse BSDF, textured or not)."""
        return self._only(DIFFUSE)

    @property
    def glossy_only(self) -> bool:
        """Whether this is a glossy lobe alone without a Fresnel curve or a texture (a Glossy BSDF)."""
        return self._only(GLOSSY) and not self.rises and self.glossy_texture is None

    def _only(self, lobe) -> bool:
        others = np.delete(self.weight, lobe)
        return bool(self.weight[lobe] > 0 and not others.any() and not self.emission.any()
                    and self.transparent_weight == 0 and self.coat == 0 and self.holdout == 0
                    and not self.layered and not self.sheen.any())

    @property
    def rises(self) -> bool:
        """Whether the glossy colour changes with the angle (a dielectric rise or a metal curve)."""
        return self.fresnel_ior > 0 or bool(self.metal_rise.any() or self.metal_dip.any())

    def _mixed_glossy(self, other, wa, wb, fa, fb, fac):
        """The glossy colour program of fa * self + fb * other, or None: mixed as the diffuse
        colours (weight times colour) where some side varies or the factor does, unless a side's
        glossy lobe has a Fresnel rise or a metal curve (the core keeps such lobes constant): the
        mean then."""
        total = wa[GLOSSY] + wb[GLOSSY]
        sides = [(c, f, w) for c, f, w in zip((self, other), (fa, fb) if fac is None else
                                              (_one_minus(fac), fac), (wa, wb)) if w[GLOSSY] > 0]
        if total <= 0 or any(c.rises for c, _, _ in sides):
            return None
        if fac is None and not any(c.glossy_texture is not None for c, _, _ in sides):
            return None
        terms = [_times(c.glossy_term(), f) for c, f, _ in sides]
        return _times(terms[0] if len(terms) == 1 else _plus(*terms), 1.0 / total)

    def glossy_term(self):
        """Weight times colour of the glossy lobe: three numbers or a program."""
        if self.glossy_texture is None:
            return self.color[GLOSSY].tolist()
        return _times(self.glossy_texture, self.weight[GLOSSY])

    def diffuse_term(self):
        """Weight times colour of the diffuse lobe: three numbers or a program."""
        w = self.color[DIFFUSE]
        if not textured(self.texture):
            return w.tolist()
        source = self.texture if isinstance(self.texture, dict) else {
            "op": "image", "texture": int(self.texture), "vector": {"op": "attribute", "name": "uv"}}
        return _times(source, w)

    def same_coat(self, other) -> bool:
        """Whether both closures have the same coat (or none)."""
        return bool(np.isclose(self.coat, other.coat)
                    and np.isclose(self.coat_roughness, other.coat_roughness)
                    and np.isclose(self.coat_ior, other.coat_ior)
                    and np.allclose(self.coat_tint, other.coat_tint)
                and procedural.to_json(self.coat_normal) == procedural.to_json(other.coat_normal))

    def same_sheen(self, other) -> bool:
        """Whether both closures have the same sheen (colour, roughness and layer) or none."""
        return bool(np.allclose(self.sheen, other.sheen) and np.isclose(self.sheen_cover, other.sheen_cover)
                    and (not self.sheen.any() or np.isclose(self.sheen_roughness, other.sheen_roughness)))

    def beside_plain(self, other) -> bool:
        """Whether this closure's glossy lobe is a whole textured metal and ``other``'s a plain
        colour (no texture, no metal curve): the two share a lobe exactly (``_metal_beside``)."""
        curve = other.metal_rise.any() or other.metal_dip.any()
        return (self.metal_texture is not None and self.metal_layer is None and other.metal_texture is None
                and other.glossy_texture is None and not curve)

    def mixes_exactly(self, other) -> bool:
        """Whether this closure and ``other`` mixed at any constant factor (``combine``) are their
        mix exactly in the core, which has one lobe of each kind per material: lobes that both
        have agree in what the core keeps one of (the glossy roughness, anisotropy and its maps,
        the layer's IOR, the glass's IOR and roughness, the diffuse roughness, the coat, the
        sheen's roughness; and the sheen layer's k, which dims the whole material), and at
        most one side's glossy colour varies over the surface (a textured metal only beside a
        plain colour: ``_metal_beside``)."""
        def both(lobe):
            return self.weight[lobe] > 0 and other.weight[lobe] > 0

        if both(GLOSSY) and self.glossy_beckmann != other.glossy_beckmann:
            return False                    # (one microfacet distribution per lobe)
        if both(DIELECTRIC) and self.dielectric_beckmann != other.dielectric_beckmann:
            return False
        if both(GLOSSY):
            same = (np.isclose(self.roughness, other.roughness) and np.isclose(self.stretch, other.stretch)
                    and np.isclose(self.rotation, other.rotation) and self.tangent == other.tangent
                    and all(getattr(self, k) is None and getattr(other, k) is None
                            for k in ("roughness_texture", "stretch_texture", "rotation_texture")))
            if not same or (self.fresnel_ior > 0 and other.fresnel_ior > 0
                            and not np.isclose(self.fresnel_ior, other.fresnel_ior)):
                return False
            if (self.rises or other.rises) and not _same_film(self.film, other.film):
                return False                # (one film per material)
            if self.film_metal > 0 and other.film_metal > 0 and not _same_conductor(self.film_conductor,
                                                                                      other.film_conductor):
                return False                # (and one metal under it)
            varies = [c for c in (self, other) if c.glossy_texture is not None or c.metal_texture is not None]
            if len(varies) == 2:
                return False
            if varies:
                plain = other if varies[0] is self else self
                if varies[0].metal_texture is not None:
                    if not varies[0].beside_plain(plain):
                        return False
                elif self.rises or other.rises:
                    return False            # (a glossy program cannot sit beside a Fresnel rise)
        if both(DIELECTRIC) and not _same_film(self.film, other.film):
            return False
        if both(DIELECTRIC) and not (np.isclose(self.ior, other.ior)
                                     and np.isclose(self.dielectric_roughness, other.dielectric_roughness)
                                     and self.dielectric_roughness_texture is None
                                     and other.dielectric_roughness_texture is None):
            return False
        if both(DIFFUSE) and not np.isclose(self.diffuse_roughness, other.diffuse_roughness):
            return False
        if self.sheen.any() and other.sheen.any() and not np.isclose(self.sheen_roughness,
                                                                     other.sheen_roughness):
            return False                    # (one sheen roughness per material)
        if not np.isclose(self.sheen_cover, other.sheen_cover):
            return False                    # (the core dims the whole material by the mixed layer)
        if self.subsurface > 0 and other.subsurface > 0 and not _same_medium(self.subsurface_params,
                                                                             other.subsurface_params):
            return False
        return self.same_coat(other) or self.coat == 0 or other.coat == 0

    def same_diffuse_base(self, other) -> bool:
        """Whether both closures have a diffuse lobe of the same weight, roughness and layering
        (the share under a Fresnel layer and its colour): their mix at any factor then differs in
        the diffuse colour alone, so a mask's levels can all take its point-by-point mix."""
        wa, wb = self.weight[DIFFUSE], other.weight[DIFFUSE]
        if wa <= 0 or wb <= 0 or not np.isclose(wa, wb) or not np.isclose(self.layered, other.layered):
            return False
        layer_a = self.layer / self.layered if self.layered > 0 else np.zeros(3)
        layer_b = other.layer / other.layered if other.layered > 0 else np.zeros(3)
        return bool(np.allclose(layer_a, layer_b)
                    and np.isclose(self.diffuse_roughness, other.diffuse_roughness))

    def same_except_diffuse(self, other) -> bool:
        """Whether the two closures differ in their diffuse colours and weights only, or also in a
        glossy colour and weight without a Fresnel rise or a textured metal's curve (a varying Mix
        factor is then exact); their coats, sheens and diffuse roughness agree (the core has one
        of each per material)."""
        rise = self.rises or other.rises
        other_lobes = [k for k in range(len(LOBES)) if k != DIFFUSE and (rise or k != GLOSSY)]
        rough = self.weight[DIFFUSE] > 0 and other.weight[DIFFUSE] > 0 and not np.isclose(
            self.diffuse_roughness, other.diffuse_roughness)
        glass = self.weight[DIELECTRIC] > 0 and other.weight[DIELECTRIC] > 0 and not (
            np.isclose(self.dielectric_roughness, other.dielectric_roughness)
            and self.dielectric_roughness_texture == other.dielectric_roughness_texture)
        return (np.allclose(self.color[other_lobes], other.color[other_lobes])
                and np.allclose(self.weight[other_lobes], other.weight[other_lobes])
                and np.isclose(self.roughness, other.roughness) and np.isclose(self.stretch, other.stretch)
                and np.isclose(self.ior, other.ior) and self.same_coat(other) and self.same_sheen(other)
                and not rough and not glass
                and self.metal_texture is None and other.metal_texture is None)

    def _transparency(self) -> dict:
        """The ``Materials.build`` keys of the Transparent part: opacity (or its program) and tint."""
        s = {"opacity": float(np.clip(1.0 - self.transparent_weight, 0.0, 1.0)),
             "transparent_color": self.transparent / self.transparent_weight}
        if self.opacity_texture is not None:
            s["opacity_program"] = _clamp01(self.opacity_texture)
        return s

    def _opaque_part(self) -> "Closure":
        """The closure without its Transparent part, divided by its opacity (the core shades a
        surface only where a ray stops on it, with probability the opacity): the weights by the
        mean opacity, the programs that carry a varying opacity (a Mix by an alpha mask puts it
        into the mixed colours) by the opacity at each point over that mean."""
        o = 1.0 - self.transparent_weight
        if o <= 0.0:
            return Closure(roughness=self.roughness, ior=self.ior)
        scaled = {name: getattr(self, name) / o for name in ("weight", "color", "emission", "multiscatter",
                                                             "glass_multiscatter", "beckmann",
                                                             "glass_beckmann",
                                                             "rise", "metal_rise", "metal_dip", "layer",
                                                             "layered", "coat", "holdout", "refraction_only",
                                                             "film_metal", "subsurface", "sheen",
                                                             "sheen_cover")}
        out = dataclasses.replace(self, **scaled, transparent=np.zeros(3), transparent_weight=0.0,
                                  opacity_texture=None,
                                  reflection=None if self.reflection is None else self.reflection / o)
        if self.opacity_texture is not None:
            # o_mean / o(x) (Cycles' Divide gives 0 where o(x) is 0: never shaded there).
            per_point = {"op": "math", "operation": "DIVIDE", "a": o, "b": self.opacity_texture}
            out.texture = _times(self.texture, per_point) if isinstance(self.texture, dict) else self.texture
            out.glossy_texture = (None if self.glossy_texture is None
                                  else _times(self.glossy_texture, per_point))
            out.metal_texture = out.metal_tint = out.metal_layer = None   # the curve's mean times the opacity
            out.emission_texture = (None if self.emission_texture is None
                                    else _times(self.emission_texture, per_point))
        return out

    @property
    def glossy_beckmann(self) -> bool:
        """The glossy lobe takes Beckmann microfacets: most of its weight has them."""
        return self.beckmann > 0.5 * self.weight[GLOSSY]

    @property
    def dielectric_beckmann(self) -> bool:
        return self.glass_beckmann > 0.5 * self.weight[DIELECTRIC]

    def glass_reflection(self) -> np.ndarray:
        return self.color[DIELECTRIC] if self.reflection is None else self.reflection

    def spec(self, name) -> dict:
        """A ``Materials.build`` entry."""
        if self.transparent_weight > 0:
            return self._opaque_part().spec(name) | self._transparency()
        s = {"name": name, "roughness": self.roughness, "ior": self.ior, "emission": self.emission,
             "dielectric_roughness": self.dielectric_roughness}
        for i, lobe in enumerate(LOBES):
            w = self.weight[i]
            s[lobe] = self.color[i] / w if w > 0 else np.zeros(3)
            s[f"{lobe}_weight"] = w
        w = self.weight[DIELECTRIC]
        fresnel = w - self.refraction_only              # the share that reflects by Fresnel
        s["dielectric_reflection"] = self.glass_reflection() / fresnel if fresnel > 1e-12 else np.zeros(3)
        if w > 0 and self.refraction_only > 0:
            s["dielectric_fresnel"] = float(np.clip(fresnel / w, 0.0, 1.0))
        if w > 0 and self.glass_multiscatter.any():
            s["dielectric_multiscatter"] = np.clip(self.glass_multiscatter / w, 0.0, 1.0)
        if w > 0 and self.dielectric_beckmann:
            s["dielectric_distribution"] = DISTRIBUTION_BECKMANN
        if self.weight[GLOSSY] > 0 and self.glossy_beckmann:
            s["glossy_distribution"] = DISTRIBUTION_BECKMANN
        g = self.color[GLOSSY]
        s["glossy_multiscatter"] = np.divide(self.multiscatter, g, out=np.zeros(3), where=g > 0)
        if self.fresnel_ior > 0 and self.weight[GLOSSY] > 0:
            s["glossy_fresnel_ior"] = self.fresnel_ior
            s["glossy_fresnel_rise"] = self.rise / self.weight[GLOSSY]
            if self.layered > 0 and self.weight[DIFFUSE] > 0:
                s["diffuse_layer"] = self.layer / self.layered
                s["diffuse_layer_weight"] = min(1.0, self.layered / self.weight[DIFFUSE])
        curve = self.metal_rise.any() or self.metal_dip.any()
        if curve and self.weight[GLOSSY] > 0 and self.metal_texture is None:
            s["glossy_metal_rise"] = self.metal_rise / self.weight[GLOSSY]
            s["glossy_metal_dip"] = self.metal_dip / self.weight[GLOSSY]
        metal_film = self.film_metal > 0 and curve and self.weight[GLOSSY] > 0 and self.metal_texture is None
        if self.film is not None and ((self.fresnel_ior > 0 and self.weight[GLOSSY] > 0) or metal_film
                                      or self.weight[DIELECTRIC] > 0):
            s["film_thickness"], s["film_ior"], s["film_tint"] = self.film
            if metal_film:
                s["film_metal"] = float(np.clip(self.film_metal / self.weight[GLOSSY], 0.0, 1.0))
                if self.film_conductor is not None:
                    s["film_metal_ior"], s["film_metal_extinction"] = self.film_conductor
        if self.dielectric_texture is not None and self.weight[DIELECTRIC] > 0:
            s["dielectric_program"] = self.dielectric_texture
            s["dielectric"] = np.ones(3)
        if self.translucent_texture is not None and self.weight[TRANSLUCENT] > 0:
            s["translucent_program"] = self.translucent_texture
            s["translucent"] = np.ones(3)
        if self.glossy_texture is not None and self.weight[GLOSSY] > 0:
            s["glossy_program"] = self.glossy_texture
            s["glossy"] = np.ones(3)
        if self.metal_texture is not None and self.weight[GLOSSY] > 0:
            # The core takes the F82 curve of each hit's F0 (Materials.glossy_metal_tint).
            s["glossy_program"] = self.metal_texture
            s["glossy_metal_tint"] = np.clip(np.asarray(self.metal_tint, np.float64), 0.0, 1.0)
            if self.metal_layer is not None:
                # Beside a dielectric layer: the share k and the rest's colour and own F_ss.
                s["glossy_metal_share"], s["glossy_metal_rest"], fss = self.metal_layer
                s["glossy"] = np.ones(3)
                s["glossy_multiscatter"] = fss
        if self.roughness_texture is not None and self.weight[GLOSSY] > 0:
            s["roughness_program"] = self.roughness_texture
        glass_map = self.glass_roughness_map()
        if glass_map is not None:
            # The core's roughness copies take the map's level for the glass as well.
            s["roughness_program"], s["dielectric_roughness"] = glass_map, -1.0
        if self.anisotropic and self.weight[GLOSSY] > 0:
            s.update(glossy_stretch=float(np.clip(self.stretch, 0.01, 100.0)), glossy_rotation=self.rotation,
                     glossy_tangent=self.tangent[0])
            if self.tangent[0] == TANGENT_UV:
                s["tangent_uv_map"] = self.tangent[1]
            if self.rotation_texture is not None:
                s["rotation_program"] = self.rotation_texture
            if self.stretch_texture is not None:
                s["stretch_program"] = self.stretch_texture
        if self.emission_texture is not None and self.emission.any():
            # The core multiplies the emission by the program: scaled to a mean near 1.
            scale = float(self.emission.max())
            s["emission"] = np.full(3, scale)
            s["emission_program"] = _times(self.emission_texture, 1.0 / scale)
        if isinstance(self.texture, dict):
            s["diffuse_program"] = self.texture
            s["diffuse"] = np.ones(3)
        elif self.texture >= 0:
            s["diffuse_texture"] = self.texture
            s["diffuse"] = np.ones(3)
        if self.holdout > 0:
            s["holdout"] = min(self.holdout, 1.0)
        if self.diffuse_roughness > 0 and self.weight[DIFFUSE] > 0:
            s["diffuse_roughness"] = float(np.clip(self.diffuse_roughness, 0.0, 1.0))
        if self.subsurface > 0 and self.weight[DIFFUSE] > 0 and self.subsurface_params is not None:
            radius, anisotropy, ior, alpha, method = self.subsurface_params
            s.update(subsurface_weight=float(np.clip(self.subsurface / self.weight[DIFFUSE], 0.0, 1.0)),
                     subsurface_radius=radius, subsurface_anisotropy=anisotropy, subsurface_ior=ior,
                     subsurface_alpha=alpha, subsurface_method=method)
        if self.coat > 0:
            s.update(coat=min(self.coat, 1.0), coat_roughness=self.coat_roughness, coat_ior=self.coat_ior,
                     coat_tint=self.coat_tint)
            normal, bump = self.coat_normal or (None, None)
            if normal is not None:
                s["coat_normal_program"] = normal
            if bump is not None:
                s["coat_bump_program"], s["coat_bump_strength"], s["coat_bump_distance"] = bump
        if self.sheen.any():
            s.update(sheen=np.maximum(self.sheen, 0.0),
                     sheen_roughness=float(np.clip(self.sheen_roughness, 0.0, 1.0)),
                     sheen_cover=max(float(self.sheen_cover), 0.0))
        if isinstance(self.normal_map, dict):
            s["normal_program"] = self.normal_map
        elif self.normal_map is not None:
            s["normal_texture"], s["normal_strength"], s["normal_uv_map"], s["normal_space"] = self.normal_map
        if self.bump is not None:
            source, s["bump_strength"], s["bump_distance"], *outer = self.bump
            if outer:
                s["outer_bump_program"], s["outer_bump_strength"], s["outer_bump_distance"] = outer[0]
            s["bump_program" if isinstance(source, dict) else "bump_texture"] = source
            if self.displacement_bump:
                s["displacement_bump"] = 1
        if self.levels is not None:
            # MaterialSet adds the levels' rows after this one (level_first, level_count).
            program, closures = self.levels
            count = len(closures)
            s["level_program"] = program
            s["levels"] = [c.spec(f"{name} (level {k}/{count - 1})") for k, c in enumerate(closures)]
        return s


def _fresnel_layer(a, b, eta) -> Closure:
    """A Mix of a diffuse-only closure ``a`` and a glossy-only one ``b`` by the Fresnel curve of
    IOR ``eta`` at the view direction (Cycles: (1 - F(wo.N)) a + F(wo.N) b), as the layering of
    Principled's dielectric base: ``b``'s colour C rises along the Fresnel curve of the microfacet
    normal (C F0 + C (1 - F0) s(c)), with its own F_ss (C) for multiscatter, over ``a``'s diffuse
    lobe, which loses the layer's albedo at the view direction.  Exact for a smooth glossy under
    a white light; for a rough one the curve follows the microfacet normal, not the surface's."""
    f0 = dielectric_f0(eta)
    glossy = dataclasses.replace(b, color=b.color * f0, multiscatter=b.multiscatter * f0,
                                 fresnel_ior=eta, rise=b.color[GLOSSY] * (1.0 - f0))
    w = a.weight[DIFFUSE]
    base = dataclasses.replace(a, layer=np.full(3, w * f0), layered=w)
    return base.combine(glossy, 1.0, 1.0)


# Geometry's Backfacing (1 where a ray meets a face from behind), a float program.
_BACKFACING = {"op": "separate", "vector": {"op": "attribute", "name": "backfacing"}, "output": "X"}


def _through_fibre(c, through):
    """Closure ``c`` (a hair fibre's lobes that scatter, each weighing what it takes of the light)
    with ``through`` (3,) of the light going on through the fibre, on a curve's tube: its front
    face Transparent with the weight w of ``through``'s largest channel and its back face wholly
    (the fibre is one surface: its lobes act once), each tinting by sqrt(through / w); the front
    face's lobes are then divided by 1 - w, their albedo at most 1 in that channel where the
    fibre's lobes and ``through`` add up to at most 1.  (Strands that pass through one another
    count each other's photons twice there: keep them apart.)"""
    w = float(np.clip(np.max(through), 0.0, 0.999))
    if w <= 0.0:
        return c
    # (Closure._opaque_part divides the lobes by the mean opacity, 1 - w: the front face's)
    tint = np.sqrt(np.clip(np.asarray(through, np.float64) / w, 0.0, 1.0))
    front = _math("MULTIPLY", 1.0 - w, _math("SUBTRACT", 1.0, _BACKFACING))
    return dataclasses.replace(c, transparent=w * tint, transparent_weight=w, opacity_texture=front)


def hair_sigma(color, radial_roughness):
    """(3,) Chiang et al.'s absorption of a hair fibre (per fibre radius) whose many fibres look
    ``color``, for its azimuthal roughness (Cycles' ``bsdf_principled_hair_sigma_from_reflectance``)."""
    x = radial_roughness
    fac = ((((0.245 * x + 5.574) * x - 10.73) * x + 2.532) * x - 0.215) * x + 5.969
    return (np.log(np.clip(np.asarray(color, np.float64), 1e-6, 1.0)) / fac) ** 2


def hair_lobes(sigma, eta, n=4096):
    """(R, TT, TRT and later) the shares of the light that a smooth dielectric fibre of index
    ``eta`` and absorption ``sigma`` (3,) per radius reflects at its surface (a float), sends through
    (3,) and back after inner reflections (3,), for light square to the fibre, averaged over where
    it strikes across the fibre's width (Chiang et al.'s A_p at h, theta = 0: the path
    2 cos(gamma_t) radii inside, T = exp(-2 sigma cos(gamma_t)))."""
    h = (np.arange(n) + 0.5) / n
    f = fresnel_dielectric(np.sqrt(1.0 - h * h), eta)[0][:, None]
    cos_t = np.sqrt(1.0 - (h / eta) ** 2)[:, None]
    t = np.exp(-2.0 * np.asarray(sigma, np.float64)[None] * cos_t)
    tt = (1.0 - f) ** 2 * t
    trt = tt * f * t / (1.0 - f * t)
    return float(f.mean()), tt.mean(axis=0), trt.mean(axis=0)


def _program_of(source, constant):
    """The program of a colour source (:meth:`NodeWalker.color`): itself, an image's lookup with
    the active UV map, or (-1) the ``constant`` colour as three numbers."""
    if isinstance(source, dict):
        return source
    if source >= 0:
        return {"op": "image", "texture": int(source), "vector": {"op": "attribute", "name": "uv"}}
    return [float(x) for x in constant]


def _times(a, f):
    """Program (or constant) ``a`` (a colour) times ``f``: a number, three numbers or a float program."""
    if isinstance(f, dict):
        return {"op": "mix_color", "blend": "MULTIPLY", "fac": 1.0, "a": a, "b": {"op": "splat", "value": f}}
    f = np.broadcast_to(np.asarray(f, np.float64), (3,))
    if not isinstance(a, dict):
        return (np.asarray(a, np.float64) * f).tolist()
    if _scaled(a):
        # One factor, not a chain of them: a product that rounds to 1 is then the program itself,
        # which the levels of a mask share (the core evaluates a program once per batch).
        a, f = a["a"], f * np.asarray(a["b"], np.float64)
    if np.allclose(f, 1.0, rtol=0.0, atol=1e-12):
        return a
    return {"op": "mix_color", "blend": "MULTIPLY", "fac": 1.0, "a": a, "b": f.tolist()}


def _scaled(e) -> bool:
    """Whether program ``e`` is a program times three constants (what ``_times`` makes)."""
    return (e.get("op") == "mix_color" and e.get("blend") == "MULTIPLY" and e.get("fac") == 1.0
            and isinstance(e.get("b"), list) and len(e) == 5)


def _mixed_map(sides, lobe, texture, term):
    """The float program of a parameter of lobe ``lobe`` of a mix ((closure, weights) ``sides``)
    where some side's ``texture`` varies: averaged as the constants, by the lobe's weights (a map
    with a constant, or two maps; ``term`` gives a side's number or program); else None (also
    where the sides with a map have none of the lobe: a Mix of factor 1 whose unused side alone
    is mapped, the constants then averaged by the caller)."""
    if all(getattr(c, texture) is None for c, w in sides if w[lobe] > 0):
        return None
    terms = [(term(c), w[lobe]) for c, w in sides if w[lobe] > 0]
    return _float_average(terms)


def _float_average(terms):
    """sum w x / sum w of (x, w) pairs, x a number or a float program; a program if any x is."""
    total = sum(w for _, w in terms)
    if all(x == terms[0][0] for x, _ in terms):
        return terms[0][0]                      # e.g. the two halves of a Principled's metallic map
    out = None
    for x, w in terms:
        term = {"op": "math", "operation": "MULTIPLY", "a": x, "b": w / total}
        out = term if out is None else {"op": "math", "operation": "ADD", "a": out, "b": term}
    return out


def _plus(a, b):
    if not isinstance(a, dict) and not isinstance(b, dict):
        return (np.asarray(a) + np.asarray(b)).tolist()
    return {"op": "mix_color", "blend": "ADD", "fac": 1.0, "a": a, "b": b}


def _clamp01(f):
    """Float program ``f`` clamped to [0, 1] (a mix factor, as Cycles clamps it)."""
    low = {"op": "math", "operation": "MAXIMUM", "a": f, "b": 0.0}
    return {"op": "math", "operation": "MINIMUM", "a": low, "b": 1.0}


def _clamped_color(c):
    """Colour program ``c`` kept within [0, 1] in every channel (a metal's F0, as Cycles saturates it)."""
    return {"op": "mix_color", "fac": 0.0, "a": c, "b": [0.0, 0.0, 0.0], "clamp_result": True}


def _math(operation, a, b=0.0):
    """Blender's Math node ``operation`` of numbers or float programs: a number if both are."""
    if isinstance(a, dict) or isinstance(b, dict):
        return {"op": "math", "operation": operation, "a": a, "b": b}
    return float(procedural.MATH[operation](np.float64(a), np.float64(b), 0.0))


def _glossy_stretch(a):
    """The Glossy BSDF's stretch (1 - max(a, 0)) / (1 + min(a, 0)) of anisotropy ``a``, a number or
    a float program."""
    return _math("DIVIDE", _math("SUBTRACT", 1.0, _math("MAXIMUM", a, 0.0)),
                 _math("ADD", 1.0, _math("MINIMUM", a, 0.0)))


def _principled_stretch(a):
    """Principled's stretch 1 / sqrt(1 - 0.9 a) of anisotropy ``a``, a number or a float program."""
    return _math("INVERSE_SQRT", _math("SUBTRACT", 1.0, _math("MULTIPLY", 0.9, a)))


def _one_minus(f):
    return {"op": "math", "operation": "SUBTRACT", "a": 1.0, "b": f}


def _plain_environment(e):
    """(texture index, rotation (3, 3) or None) when program ``e`` is an Environment Texture of the
    direction, at most turned (a Mapping whose matrix is a positive multiple of a rotation and
    which moves nothing: the lookup normalises the direction); else None."""
    if (e.get("op") != "environment" or e.get("output", "Color") != "Color"
            or e.get("projection", "EQUIRECTANGULAR") != "EQUIRECTANGULAR"):
        return None
    direction = {"op": "attribute", "name": "generated"}
    v = e["vector"]
    if v == direction:
        return e["texture"], None
    if not (isinstance(v, dict) and v.get("op") == "affine" and v["vector"] == direction
            and not v.get("normalize") and not np.any(v.get("pre", 0.0)) and not np.any(v.get("post", 0.0))):
        return None
    m = np.asarray(v["matrix"], np.float64)
    scale = float(np.cbrt(np.linalg.det(m)))
    if scale <= 0 or not np.allclose(m @ m.T, scale * scale * np.eye(3), atol=1e-6 * scale * scale):
        return None
    return e["texture"], m / scale


def _plain_image(e) -> bool:
    """Whether program ``e`` is an Image Texture's Color on the UV map with the default settings
    (repeat, linear, flat): what the core's plain image textures do."""
    return (isinstance(e, dict) and e.get("op") == "image" and e.get("output", "Color") == "Color"
            and e.get("vector") == {"op": "attribute", "name": "uv"}
            and not set(e) - {"op", "texture", "vector", "output"})


def _image_height(texture: int) -> dict:
    """The height program of a bump by an image's index (its colour's luminance, on the UV map)."""
    image = {"op": "image", "texture": texture, "vector": {"op": "attribute", "name": "uv"}}
    return {"op": "gray", "color": image}


def textured(source) -> bool:
    """Whether a colour source (:meth:`NodeWalker.color`) varies over the surface."""
    return isinstance(source, dict) or source >= 0


def _same_medium(a, b) -> bool:
    """Whether two ``Closure.subsurface_params`` are the same medium."""
    return a is None or b is None or (a[4] == b[4] and all(np.allclose(x, y) for x, y in zip(a[:4], b[:4])))


def _same_film(a, b) -> bool:
    """Whether two layers' films (``Closure.film``) are the same (or both absent)."""
    if a is None or b is None:
        return a is None and b is None
    return bool(np.isclose(a[0], b[0]) and np.isclose(a[1], b[1]) and np.allclose(a[2], b[2]))


def _same_conductor(a, b) -> bool:
    """Whether two filmed metals' complex indices (``Closure.film_conductor``) are the same (or both
    F82 metals)."""
    if a is None or b is None:
        return a is None and b is None
    return bool(np.allclose(a[0], b[0]) and np.allclose(a[1], b[1]))


def _weighted(a, b, wa, wb):
    return (a * wa + b * wb) / (wa + wb) if wa + wb > 0 else (a if wa >= wb else b)


def specular_ior(ior, level):
    """Principled's specular layer: (IOR, F0) after ``Specular IOR Level`` scales F0 by 2 level
    (Cycles: F0 = ((n - 1) / (n + 1))^2, then the IOR of the scaled F0).  An IOR below 1 acts
    as its inverse (the same F0)."""
    n = float(ior)
    n = 1.0 / n if 0.0 < n < 1.0 else n
    f0 = float(np.clip(dielectric_f0(n) * 2.0 * level, 0.0, 0.999))
    r = np.sqrt(f0)
    return (1.0 + r) / (1.0 - r), f0


def conductor_reflectance(ior, extinction, mu) -> np.ndarray:
    """(3, len(mu)) unpolarised Fresnel reflectance of the complex index ``ior`` + i
    ``extinction`` (per channel, (3,)) at the cosines ``mu``: the Metallic node's Physical Conductor."""
    k = np.maximum(np.asarray(extinction, np.float64), 0.0)
    n = (np.asarray(ior, np.float64) + 1j * k)[:, None]
    mu = np.asarray(mu, np.float64)[None, :]
    cos_t = np.sqrt(1.0 - (1.0 - mu * mu) / (n * n))
    rs = (mu - n * cos_t) / (mu + n * cos_t)
    rp = (n * mu - cos_t) / (n * mu + cos_t)
    return np.clip(0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2), 0.0, 1.0)


def conductor_fresnel(ior, extinction) -> np.ndarray:
    """Cosine-weighted hemispherical mean of :func:`conductor_reflectance`, (3,)."""
    mu = (np.arange(256) + 0.5) / 256                     # midpoint rule for int 2 mu F dmu
    return np.clip(np.mean(2.0 * mu * conductor_reflectance(ior, extinction, mu), axis=1), 0.0, 1.0)


def conductor_f82(ior, extinction):
    """(F0, edge tint), each (3,): the F82-tint curve (``core.bsdf.metal_curve``) through the
    conductor's reflectance face on and at cos = 1/7, where the curve's tint term acts most
    (the tint clamped to [0, 1] there)."""
    f = conductor_reflectance(ior, extinction, [1.0, 1.0 / 7.0])
    f0, f82 = f[:, 0], f[:, 1]
    schlick = f0 + (1.0 - f0) * (6.0 / 7.0) ** 5
    return f0, np.clip(f82 / np.maximum(schlick, 1e-12), 0.0, 1.0)


def srgb_to_linear(x):
    x = np.asarray(x, np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((np.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4
                    ).astype(np.float32)


class Textures:
    """Image datablocks -> linear float32 (H, W, 3) arrays (row 0 = bottom), one per image."""

    def __init__(self, log):
        self.log = log
        self.images = []            # list of (H, W, 3) float32
        self._index = {}            # image pointer -> index, or -1 if unusable
        self._mean = {}             # index -> mean colour (3,)
        # index of an image with alpha -> (alpha (H, W) float32, byte: None for a float image, else
        # whether it was 8-bit sRGB, made linear here; whether it is non-colour data)
        self._alpha = {}
        self._derived = {}          # (kind, index) -> texture index of an image made from image index
        # Sky Textures' bakes for the means of programs (``procedural.evaluate``'s sky_cache)
        self.sky_cache = SkyTextureCache()

    def mean_value(self, program):
        """``procedural.mean_value`` of ``program`` over these images (a Sky Texture baked once)."""
        return procedural.mean_value(program, self.images, sky_cache=self.sky_cache)

    def mean_color(self, program):
        """``procedural.mean_color`` of ``program`` over these images (a Sky Texture baked once)."""
        return procedural.mean_color(program, self.images, sky_cache=self.sky_cache)

    def lookup(self, image, where):
        """(texture index or -1, mean colour) of ``image``; ``where`` names the user in messages."""
        key = image.as_pointer()
        if key not in self._index:
            self._index[key] = self._load(image, where)
        i = self._index[key]
        return i, (self._mean[i] if i >= 0 else MISSING_TEXTURE)

    def mean(self, index):
        """(3,) mean colour of loaded image ``index``."""
        return self._mean[index]

    def premultiplied(self, index):
        """Texture index of loaded image ``index``'s colour times its alpha, as Cycles filters an
        image with alpha (and gives its Color when the Alpha output is not used): byte images are
        stored straight (8-bit sRGB ones are multiplied before they are made linear), float ones
        premultiplied already.  ``index`` itself for opaque images and non-colour data."""
        if not self.is_byte(index) or self._alpha[index][2]:
            return index
        plane, srgb, _ = self._alpha[index]
        a = plane[:, :, None]
        rgb = self.images[index]
        return self._derive("premultiplied", index,
                            lambda: srgb_to_linear(linear_to_srgb(rgb) * a) if srgb else rgb * a)

    def is_byte(self, index):
        """Whether loaded image ``index`` has alpha and 8-bit pixels (stored straight)."""
        return index in self._alpha and self._alpha[index][1] is not None

    def alpha(self, index):
        """Texture index of loaded image ``index``'s alpha as a grey image, or None when it is
        opaque everywhere (no alpha channel, or alpha mode None)."""
        if index not in self._alpha:
            return None
        plane = self._alpha[index][0]
        return self._derive("alpha", index, lambda: np.repeat(plane[:, :, None], 3, axis=2))

    def _derive(self, kind, index, make):
        """Texture index of the image ``make()`` builds from image ``index``, built once."""
        key = (kind, index)
        if key not in self._derived:
            rgb = np.ascontiguousarray(make(), np.float32)
            self.images.append(rgb)
            self._derived[key] = len(self.images) - 1
            self._mean[self._derived[key]] = rgb.reshape(-1, 3).mean(axis=0).astype(np.float64)
        return self._derived[key]

    def _load(self, image, where):
        try:
            w, h = image.size
            n = int(w) * int(h)
            if n == 0 or len(image.pixels) != 4 * n:
                raise RuntimeError("no pixel data")
            px = np.empty(4 * n, np.float32)
            image.pixels.foreach_get(px)
        except Exception as e:     # a missing or unreadable file: Blender raises or returns nothing
            path = getattr(image, "filepath", "") or image.name
            self.log.warning(f"{where}: image '{image.name}' ({path}) could not be loaded ({e}); "
                             "using a constant magenta colour")
            return -1
        rgba = px.reshape(int(h), int(w), 4)
        rgb = rgba[:, :, :3]
        alpha = np.nan_to_num(np.clip(rgba[:, :, 3], 0.0, 1.0), nan=1.0)
        keep_alpha = getattr(image, "alpha_mode", "STRAIGHT") != "NONE" and (alpha < 1.0).any()
        space = image.colorspace_settings.name
        byte_srgb = not image.is_float and "srgb" in space.lower()
        if byte_srgb:
            rgb = srgb_to_linear(rgb)
        rgb = np.ascontiguousarray(np.nan_to_num(rgb, nan=0.0, posinf=0.0, neginf=0.0), np.float32)
        self.images.append(rgb)
        i = len(self.images) - 1
        self._mean[i] = rgb.reshape(-1, 3).mean(axis=0).astype(np.float64)
        if keep_alpha:
            self._alpha[i] = (np.ascontiguousarray(alpha, np.float32), None if image.is_float else byte_srgb,
                              bool(getattr(image.colorspace_settings, "is_data", False)))
        return i


class MaterialExporter:
    """Assigns core material ids to Blender materials and builds ``core.Materials``."""

    def __init__(self, log, layer_owners=(), aovs=None):
        self.log = log
        self.layer_owners = layer_owners    # (``procedural.view_layer_owners``)
        self.aovs = dict(aovs or {})        # the view layer's Shader AOVs: name -> 'COLOR' or 'VALUE'
        self.textures = Textures(log)
        self._specs = []            # Materials.build entries
        self._ids = {}              # material pointer (or None for the default) -> id
        self._hidden = {}           # id -> VISIBLE_* bits of the rays that pass through it (Light Path)

    @property
    def count(self) -> int:
        return len(self._specs)

    def default_id(self) -> int:
        """The material used where an object has no material (Cycles' grey diffuse)."""
        if None not in self._ids:
            self._ids[None] = self._add(Closure.lobe(DIFFUSE, 1.0, GREY).spec("default surface"))
        return self._ids[None]

    def material_id(self, material) -> int:
        if material is None:
            return self.default_id()
        key = material.as_pointer()
        if key not in self._ids:
            walker = NodeWalker(material.name, self.textures, material.pass_index, self.layer_owners)
            closure = walker.material_closure(material)
            if walker.notes:
                self.log.warning(f"material '{material.name}': " + "; ".join(walker.notes))
            spec = closure.spec(material.name)
            if not getattr(getattr(material, "cycles", None), "use_bump_map_correction", True):
                spec["bump_correction"] = 0         # (Materials.bump_correction)
            if walker.medium is not None and any(np.any(walker.medium[i]) for i in (0, 1, 3)):
                spec.update(volume_absorption=walker.medium[0], volume_scattering=walker.medium[1],
                            volume_anisotropy=walker.medium[2], volume_emission=walker.medium[3],
                            volume_phase=walker.medium[4][0], volume_phase_params=walker.medium[4][1])
            if walker.true_displacement is not None:
                spec.update(walker.true_displacement)
            # The Material Index pass: the material's pass index, on the rows of its levels too.
            for row in (spec, *spec.get("levels", ())):
                row["pass_index"] = float(material.pass_index)
            if self.aovs:
                written = walker.aov_outputs(material, self.aovs)
                if written:
                    spec["aovs"] = written
            self._ids[key] = self._add(spec)
            if closure.hidden_rays:
                self._hidden[self._ids[key]] = closure.hidden_rays
        return self._ids[key]

    def hidden_rays(self) -> np.ndarray:
        """(M,) uint8 the VISIBLE_* bits of the camera-path rays each material lets through (a
        Mix with a clear Transparent BSDF by Light Path's Is Camera, Glossy or Transmission Ray)."""
        out = np.zeros(self.count, np.uint8)
        for i, bits in self._hidden.items():
            out[i] = bits
        return out

    def uses_textures(self, ids) -> bool:
        """Whether any of the material ``ids`` looks up an image with the UVs (colour or normal map)."""
        rows = self._with_levels(ids)
        return any(self._specs[i].get("diffuse_texture", -1) >= 0 or "normal_texture" in self._specs[i]
                   or "bump_texture" in self._specs[i] for i in rows) or "uv" in self.coordinates_used(ids)

    def coordinates_used(self, ids) -> set:
        """Names of the data (``procedural.ATTRIBUTES``) the procedural colours of ``ids`` read
        (and "generated" for an anisotropic glossy lobe's radial tangent, "object" for an
        object-space normal map: the objects' transforms, and for subsurface scattering, whose
        walks stay inside their object)."""
        used = set()
        for i in self._with_levels(ids):
            for key in Materials.PROGRAM_FIELDS:
                if key in self._specs[i]:
                    used |= procedural.attributes_used(self._specs[i][key])
            for value in self._specs[i].get("aovs", {}).values():      # (Shader AOVs' programs)
                if isinstance(value, dict):
                    used |= procedural.attributes_used(value)
            if self._specs[i].get("glossy_tangent", TANGENT_UV) != TANGENT_UV:
                used.add("generated")
            if self._specs[i].get("normal_space") in (NORMAL_OBJECT, NORMAL_BLENDER_OBJECT):
                used.add("object")
            if ("displacement_program" in self._specs[i]
                    and not self._specs[i].get("displacement_flags", 0) & DISPLACE_WORLD):
                used.add("object")                  # (an offset in the object's space)
            if self._specs[i].get("subsurface_weight", 0.0) > 0:
                used.add("object")                  # (random walks stay inside their object)
        return used

    def tangent_uv(self, ids):
        """The UV map name ('' = the active render map) of the first of ``ids`` that needs the UV
        map's tangents (a normal map, an anisotropic glossy lobe oriented by them, a program's
        Tangent node), or None."""
        for s in (self._specs[i] for i in self._with_levels(ids)):
            if "normal_texture" in s and s["normal_space"] == NORMAL_TANGENT:
                return s["normal_uv_map"]
            if "tangent_uv_map" in s:
                return s["tangent_uv_map"]
        return "" if "tangent_uv" in self.coordinates_used(ids) else None

    def build(self) -> Materials:
        """``core.Materials`` of the materials met so far; a value that is not a finite number (a
        driver's or script's NaN or infinity, which ``Scene.validate`` refuses) takes the value of
        a material that sets nothing, named in a warning."""
        mats = Materials.build(self._specs)
        default = None
        for name in Materials.ARRAY_FIELDS:
            v = getattr(mats, name)
            if not np.issubdtype(v.dtype, np.floating):
                continue
            bad = ~np.isfinite(v.reshape(len(v), -1)).all(axis=1)
            if bad.any():
                if default is None:
                    default = Materials.build([{"name": ""}])
                v = v.copy()
                v[bad] = getattr(default, name)[0]
                setattr(mats, name, v)
                for owner in dict.fromkeys(mats.names[i] for i in np.flatnonzero(bad)):
                    self.log.warning(f"material '{owner}': {name} is not a finite number (NaN or "
                                     "infinite); the default value is taken")
        return mats

    def cryptomatte_names(self) -> list:
        """The name of each core material row for Cryptomatte: its Blender material's (a level's
        row its own spec's), Cycles' "default_surface" for the default."""
        names = [spec.get("name", "") for spec in self._specs]
        if None in self._ids:
            names[self._ids[None]] = "default_surface"
        return names

    def _add(self, spec) -> int:
        """Add ``spec`` and, after it, its levels' rows (``Closure.levels``); its index."""
        levels = spec.pop("levels", [])
        self._specs.append(spec)
        index = len(self._specs) - 1
        if levels:
            spec.update(level_first=index + 1, level_count=len(levels))
            self._specs.extend(levels)
        return index

    def _with_levels(self, ids):
        """Material ``ids`` and the rows of their levels."""
        out = []
        for i in ids:
            s = self._specs[i]
            out.append(i)
            if "level_first" in s:
                out.extend(range(s["level_first"], s["level_first"] + s["level_count"]))
        return out


class NodeWalker:
    """Evaluates one material's node tree into a :class:`Closure`; collects notes for a warning."""

    def __init__(self, material_name, textures, pass_index=0, layer_owners=()):
        self.name = material_name
        self.textures = textures
        self.pass_index = pass_index    # the material's pass index (Object Info's Material Index)
        self.layer_owners = layer_owners  # view layer, scene, world (``procedural.view_layer_owners``)
        self.notes = []
        self.programs = ExpressionBuilder(self)
        self.world_texture = None       # texture index of the world's environment image, if any
        self.world_rotation = None      # (3, 3) rotation of its Mapping node, if any
        self.world_program = None       # program of the direction for any other varying world colour
        self.camera_walker = None       # what camera rays see (Light Path's Is Camera Ray), its own
        self.camera_color = None        # world_* and colour, or None: the same as the other rays
        self.medium = None              # the material's volume (volume(): absorption, scattering, g, glow)
        self.true_displacement = None   # {"displacement_program": offset program, "displacement_flags": ..}

    def note(self, msg):
        if msg not in self.notes:
            self.notes.append(msg)

    def unsupported(self, node, what):
        self.note(f"unsupported node '{node.name}' ({node.bl_idname}) {what}")

    # ----------------------------------------------------------------- entry points
    def material_closure(self, material) -> Closure:
        nt = material.node_tree
        if nt is None:
            return Closure.lobe(DIFFUSE, 1.0, material.diffuse_color[:3])
        out = nt.get_output_node('CYCLES')
        if out is None:
            # (Cycles: no shader, black; the viewport colour is for a material without nodes)
            self.note("no material output node; rendered black, as in Cycles")
            return Closure()
        closure = self.shader(out.inputs["Surface"], ())
        self.medium = self.volume(out.inputs["Volume"], ())
        if closure is None and self.medium is not None:
            # No surface, a volume: Cycles' volume-only mesh, whose surface lets every ray through.
            return Closure(transparent=np.ones(3), transparent_weight=1.0)
        levels = closure.levels[1] if closure is not None and closure.levels is not None else []
        for c in [closure] + levels:
            if (c is not None and c.dielectric_roughness_texture is not None and c.weight[DIELECTRIC] > 0
                    and c.glass_roughness_map() is None):
                self.note(f"a varying glass roughness beside a glossy lobe of another roughness takes its "
                          f"mean {c.dielectric_roughness:.3f} (one roughness map per material)")
        bump = self.displacement(out.inputs["Displacement"], material)
        if bump is not None and closure is not None:
            self._displace(closure, bump)
        return closure or Closure()

    def aov_outputs(self, material, aovs):
        """{name: a colour, a number or a program} of the material's AOV Output nodes whose name is
        one of the view layer's Shader ``aovs`` (name -> 'COLOR' or 'VALUE'): its Color input for a
        colour AOV, its Value for a value AOV, as Cycles compiles them (svm/aov.h), those inside
        node groups too (at any depth, each use of a group in its own context); muted nodes and
        groups are not read."""
        out = {}

        def outputs(tree, stack):
            for node in tree.nodes if tree is not None else ():
                if node.mute:
                    continue
                if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
                    if node.node_tree not in [g.node_tree for g in stack]:      # (no recursion)
                        yield from outputs(node.node_tree, stack + (node,))
                elif node.bl_idname == "ShaderNodeOutputAOV" and node.aov_name in aovs:
                    yield node, stack

        for node, stack in outputs(material.node_tree, ()):
            color = aovs[node.aov_name] == 'COLOR'
            sock, want = (node.inputs["Color"], VEC) if color else (node.inputs["Value"], FLOAT)
            e = self.programs.expression(sock, stack, want)
            if isinstance(e, dict) and procedural.varies(e):
                out[node.aov_name] = e
            else:
                value = self.programs.constant_of(sock, stack, want)
                out[node.aov_name] = [float(v) for v in np.broadcast_to(np.asarray(value, np.float64), (3,))]
        return out

    def _displace(self, closure, bump):
        """Lay the Displacement output's ``bump`` under ``closure`` and its levels.  Cycles' Bump
        Only method bends the normal every unlinked Normal input starts from, so a shader's own
        Bump (whose Normal is unlinked) bends the displaced normal: the displacement becomes the
        inner bump and the shader's the outer one (``Materials.outer_bump_*``).  Beside a normal
        map, or under a Bump on a Bump (a third bump), the displacement is noted and dropped.  A
        coat whose Coat Normal is unlinked takes the displaced normal too (a bump of the coat);
        under the coat's own Bump it is noted and dropped there."""
        source = bump[0] if isinstance(bump[0], dict) else _image_height(bump[0])
        for c in [closure] + (closure.levels[1] if closure.levels is not None else []):
            if c.coat > 0 and c.coat_normal is None:
                c.coat_normal = (None, (source, *bump[1:3]))
            elif c.coat > 0 and c.coat_normal[1] is not None:
                self.note("the Displacement output does not bend a coat under its own Bump (one bump "
                          "per coat)")
            if c.normal_map is not None or (c.bump is not None and len(c.bump) > 3):
                self.note("the Displacement output is ignored beside the shader's own normal map or "
                          "Bump on a Bump")
            elif c.bump is None:
                c.bump, c.displacement_bump = bump, True
            else:
                source, strength, distance = c.bump
                height = source if isinstance(source, dict) else _image_height(source)
                c.bump, c.displacement_bump = (*bump, (height, strength, distance)), True

    def displacement(self, sock, material):
        """The bump (as :meth:`bent_normal`'s) of a Displacement node on the material output's
        Displacement: Cycles' default Displacement Method, Bump Only, bends the normal as a Bump
        node of Distance ``Scale`` and Strength 1 on the same Height (the Midlevel, a constant,
        bends nothing).  Displacement Only moves the vertices instead (``true_displacement``: the
        offset (Height - Midlevel) Scale along the normal, in the node's Space; no bump), and
        Displacement and Bump does both, keeping the shading normals for the bump to bend
        (``Materials.displacement_program``, ``core.displacement``).  Anything but a Displacement
        node (a Vector Displacement) is ignored, noted."""
        src, _, stack = self.source(sock, ())
        if src is None:
            return None
        node = src.node
        method = getattr(material, "displacement_method", "BUMP")
        if node.bl_idname == "ShaderNodeVectorDisplacement" and not node.mute:
            return self._vector_displacement(node, stack, method)
        if node.bl_idname != "ShaderNodeDisplacement":
            self.unsupported(node, "drives the Displacement output; ignored")
            return None
        if self.linked(node.inputs["Normal"], stack):
            self.note(f"displacement '{node.name}': a linked Normal is ignored (the surface's own is used)")
        if method != "BUMP":
            offset = {"op": "math", "operation": "MULTIPLY",
                      "a": {"op": "math", "operation": "SUBTRACT",
                            "a": self.programs.expression(node.inputs["Height"], stack, FLOAT),
                            "b": self.programs.expression(node.inputs["Midlevel"], stack, FLOAT)},
                      "b": self.programs.expression(node.inputs["Scale"], stack, FLOAT)}
            flags = ((DISPLACE_WORLD if node.space == "WORLD" else 0)
                     | (DISPLACE_KEEPS_NORMALS if method == "BOTH" else 0))
            self.true_displacement = {"displacement_program": offset, "displacement_flags": flags}
            if method == "DISPLACEMENT":
                return None
        tex = self._bump_height(node.inputs["Height"], stack)
        return None if tex is None else (tex, 1.0, self.value(node.inputs["Scale"], stack))

    def _vector_displacement(self, node, stack, method):
        """A Vector Displacement node on the Displacement output: the offset (Vector - Midlevel)
        Scale in its Space (tangent: along the UV map's tangent, the normal and their bitangent,
        x, y, z, the bitangent's sign taken as +1; or the object's, or world units) as a program of
        a world vector (``DISPLACE_VECTOR``) for Displacement Only and Displacement and Bump, and
        for Bump Only (and that method's bump) a bump of distance 1 of the offset's component along
        the normal, as Cycles' bump from a displacement dots the two."""
        vector = self.programs.expression(node.inputs["Vector"], stack, VEC)
        level = {"op": "splat", "value": self.programs.expression(node.inputs["Midlevel"], stack, FLOAT)}
        local = {"op": "vector_math", "operation": "SCALE",
                 "a": {"op": "vector_math", "operation": "SUBTRACT", "a": vector, "b": level},
                 "scale": self.programs.expression(node.inputs["Scale"], stack, FLOAT)}
        normal = {"op": "attribute", "name": "world_normal"}
        if node.space == "WORLD":
            offset = local
        elif node.space == "OBJECT":
            offset = {"op": "vector_transform", "type": "VECTOR", "convert_from": "OBJECT",
                      "convert_to": "WORLD", "vector": local}
        else:
            tangent = {"op": "attribute", "name": "tangent_uv"}
            bitangent = {"op": "vector_math", "operation": "CROSS_PRODUCT", "a": normal, "b": tangent}
            axes = [{"op": "vector_math", "operation": "SCALE", "a": axis,
                     "scale": {"op": "separate", "vector": local, "output": xyz}}
                    for axis, xyz in ((tangent, "X"), (normal, "Y"), (bitangent, "Z"))]
            offset = {"op": "vector_math", "operation": "ADD", "a": axes[0],
                      "b": {"op": "vector_math", "operation": "ADD", "a": axes[1], "b": axes[2]}}
        if method != "BUMP":
            flags = DISPLACE_WORLD | DISPLACE_VECTOR | (DISPLACE_KEEPS_NORMALS if method == "BOTH" else 0)
            self.true_displacement = {"displacement_program": offset, "displacement_flags": flags}
            if method == "DISPLACEMENT":
                return None
        height = {"op": "vector_math", "operation": "DOT_PRODUCT", "a": offset, "b": normal,
                  "output": "Value"}
        return height, 1.0, 1.0

    def world_color(self, world):
        """Background radiance (3,) of a world: Background/Emission colour times strength (its
        Volume goes to ``medium``, as a material's).

        A colour that varies with the direction is left in ``world_program`` (a program of the
        direction, which the world export bakes into an image) unless it is an equirectangular
        Environment Texture, at most turned by a Mapping node, which becomes ``world_texture``
        (and ``world_rotation``) as it is; the returned colour then multiplies either."""
        nt = world.node_tree
        if nt is None:
            return np.array(world.color[:3], np.float64)
        out = nt.get_output_node('CYCLES')
        if out is None:
            return np.array(world.color[:3], np.float64)
        self.medium = self.volume(out.inputs["Volume"], ())
        if self.medium is not None and self.medium[3].any():
            self.note("volume emission in the world is not supported (left out)")
        src, default, stack = self.source(out.inputs["Surface"], ())
        if src is None:
            return np.zeros(3)
        node = src.node
        camera_mix = node.bl_idname == "ShaderNodeMixShader" and not node.mute
        if camera_mix and self._is_camera_ray(node.inputs[0], stack):
            # Light Path's Is Camera Ray: the second shader for camera rays, the first for the rest.
            self.camera_walker = NodeWalker(self.name, self.textures, layer_owners=self.layer_owners)
            self.camera_color = self.camera_walker._background(
                *self.source(_by_identifier(node.inputs, "Shader_001"), stack)[::2], world)
            self.notes += [n for n in self.camera_walker.notes if n not in self.notes]
            return self._background(*self.source(_by_identifier(node.inputs, "Shader"), stack)[::2], world)
        return self._background(src, stack, world)

    def _is_camera_ray(self, sock, stack) -> bool:
        """Whether ``sock`` is fed by a Light Path node's Is Camera Ray output."""
        return self._light_path_output(sock, stack) == "Is Camera Ray"

    def _light_path_output(self, sock, stack):
        """The name of the Light Path node's output that feeds ``sock``, or None."""
        src, _, _ = self.source(sock, stack)
        if src is None or src.node.bl_idname != "ShaderNodeLightPath" or src.node.mute:
            return None
        return src.name

    def _background(self, src, stack, world):
        """The radiance (3,) of the world shader output ``src`` (None: black), as
        :meth:`world_color`."""
        if src is None:
            return np.zeros(3)
        node = src.node
        if node.bl_idname in ("ShaderNodeBackground", "ShaderNodeEmission"):
            strength = self.value(node.inputs["Strength"], stack)
            e = self.programs.expression(node.inputs["Color"], stack, VEC)
            if not procedural.varies(e):
                color, _ = self.color(node.inputs["Color"], stack)
                return color * strength
            plain = _plain_environment(e)
            if plain is not None:
                self.world_texture, self.world_rotation = plain
            else:
                self.world_program = e
            return np.full(3, strength)
        self.unsupported(node, "in the world; using the world colour")
        return np.array(world.color[:3], np.float64)

    # ----------------------------------------------------------------- links
    def source(self, sock, stack):
        """Follow the links into input ``sock``.

        Returns ``(output_socket, None, stack)`` for the node output that feeds it,
        or ``(None, input_socket, stack)`` when nothing does, the input socket then
        being the one whose ``default_value`` applies (possibly a group node's input), or
        ``(None, None, stack)`` when a muted node passes nothing to the output.
        Reroutes, group boundaries and muted nodes are followed through. As in Cycles, a run of
        reroutes and muted nodes that ends in an input with no link passes nothing: the socket
        it started from keeps its own value (Blender's UI would show the muted node's input's).
        ``stack`` is the tuple of group nodes entered so far.
        """
        start = None                    # the socket where the current run of reroutes/mutes began
        for _ in range(10_000):         # guard against cycles in malformed trees
            links = [ln for ln in sock.links if ln.is_valid and not ln.is_muted]
            if not links:
                return None, start if start is not None else sock, stack
            out = links[0].from_socket
            node = out.node
            if node.bl_idname == "NodeReroute":
                start = sock if start is None else start
                sock = node.inputs[0]
            elif node.bl_idname == "NodeGroupInput":
                if not stack:
                    return None, start if start is not None else sock, stack
                group = stack[-1]
                sock = _by_identifier(group.inputs, out.identifier)
                stack = stack[:-1]
                start = None
                if sock is None:
                    return None, None, stack
            elif node.mute:
                # The node passes what feeds the input of its internal link to this output (a Mix
                # Shader its first shader, an Invert its colour's link); without one (a BSDF)
                # nothing comes out.
                through = [ln for ln in node.internal_links if ln.to_socket.identifier == out.identifier]
                if not through:
                    return None, None, stack
                start = sock if start is None else start
                sock = through[0].from_socket
            elif node.bl_idname == "ShaderNodeGroup":
                tree = node.node_tree
                gout = _group_output(tree) if tree is not None else None
                inner = _by_identifier(gout.inputs, out.identifier) if gout is not None else None
                if inner is None:
                    self.note(f"node group '{node.name}' has no matching output")
                    return None, None, stack
                sock = inner
                stack = stack + (node,)
                start = None
            else:
                return out, None, stack
        return None, None, stack

    def linked(self, sock, stack) -> bool:
        """Whether a node feeds ``sock`` once reroutes, muted nodes and group boundaries are
        followed (a dangling reroute or a muted node with an unlinked input feeds nothing)."""
        return self.source(sock, stack)[0] is not None

    # ----------------------------------------------------------------- values
    def value(self, sock, stack) -> float:
        """A number input: its value, or the mean of the texture driving it (noted)."""
        return float(self.programs.constant_of(sock, stack, FLOAT))

    def color(self, sock, stack):
        """(mean rgb (3,) float64, source) of a colour input; source is -1 (a constant), an image
        index (an Image Texture on the active UV map, the core's plain textures) or a program
        (``core/procedural.py``) of the texture and colour nodes feeding it."""
        e = self.programs.expression(sock, stack, VEC)
        if not isinstance(e, dict):
            return np.array(e, np.float64), -1
        if _plain_image(e):
            return self.textures.mean(e["texture"]), e["texture"]
        mean = self.textures.mean_color(e)
        if not procedural.varies(e):
            return mean, -1                     # constant nodes only: the same everywhere
        return mean, e

    def mean_color(self, sock, stack) -> np.ndarray:
        """A colour input the core takes as a constant: its value, or the mean of the texture
        driving it (noted), (3,) float64."""
        return np.array(self.programs.constant_of(sock, stack, VEC), np.float64)

    # ----------------------------------------------------------------- shaders
    def shader(self, sock, stack):
        """The closure feeding shader input ``sock``, or None for no closure (black)."""
        src, _, stack = self.source(sock, stack)
        if src is None:
            return None
        node = src.node
        kind = node.bl_idname
        handler = None if node.mute else SHADERS.get(kind)
        if handler is None and kind in EEVEE_ONLY_SHADERS:
            self.unsupported(node, "rendered black, as Cycles renders it (a shader of EEVEE's alone)")
            return None
        if handler is None:
            self.unsupported(node, "rendered as grey diffuse")
            return Closure.lobe(DIFFUSE, 1.0, GREY)
        closure = handler(self, node, stack)
        if "Normal" in node.inputs and closure.normal_map is None and closure.bump is None:
            closure.normal_map, closure.bump = self.bent_normal(node.inputs["Normal"], stack)
        return closure

    def volume(self, sock, stack):
        """(absorption (3,), scattering (3,), anisotropy g, emission (3,), phase) of the volume
        shader feeding ``sock`` (coefficients and emission per unit of length, as Cycles), or None
        when nothing does; ``phase`` is (``core.phase`` kind, its three parameters: Draine's Alpha,
        Fournier-Forand's Backscatter and IOR, Mie's Diameter).  Volume Absorption absorbs
        (1 - Color) Density; Volume Scatter scatters Color Density by its phase function (Blender
        5.0's Henyey-Greenstein of its Anisotropy, Rayleigh, Draine, Fournier-Forand or Mie), Volume
        Coefficients by its coefficients and phase; Principled Volume scatters Color Density and
        absorbs (1 - Color)(1 - sqrt(Absorption Color)) Density.  Add and Mix add the
        coefficients; scatterers of different anisotropy get their mean weighted by the
        scattering, of different phase functions the one that scatters most (noted).  Principled
        Volume emits Emission Strength Emission Color plus, with
        Blackbody Intensity b > 0, Blackbody Tint (1 - b + b T^4) 5.670373e-14 / pi times the
        Blackbody colour of its Temperature T (Cycles' Stefan-Boltzmann law), neither scaled by
        the Density; an Emission shader emits Color Strength.  Textures on the inputs take their
        means (noted)."""
        src, _, stack = self.source(sock, stack)
        if src is None:
            return None
        node = src.node
        kind = "muted" if node.mute else node.bl_idname
        zero = np.zeros(3)
        even = (HENYEY_GREENSTEIN, (0.0, 0.0, 0.0))

        def color(name):
            value = self.programs.constant_of(node.inputs[name], stack, VEC)
            return np.maximum(np.array(value, np.float64), 0.0)

        def phase():
            """(kind, parameters) of a Volume Scatter's or Volume Coefficients' phase function."""
            name = getattr(node, "phase", "HENYEY_GREENSTEIN")
            if name not in PHASE_NAMES:
                self.note(f"'{node.name}': the {name.replace('_', ' ').title()} phase function is not "
                          "supported (Henyey-Greenstein used)")
                return even
            k = PHASE_NAMES.index(name)
            first = {"DRAINE": "Alpha", "FOURNIER_FORAND": "Backscatter", "MIE": "Diameter"}.get(name)
            params = [max(self.value(node.inputs[first], stack), 0.0) if first else 0.0, 0.0, 0.0]
            if k == FOURNIER_FORAND:
                params[1] = max(self.value(node.inputs["IOR"], stack), 0.0)
            return k, tuple(params)

        def density():
            return max(self.value(node.inputs["Density"], stack), 0.0)

        def anisotropy():
            sock = node.inputs.get("Anisotropy")        # absent for some phase functions
            if sock is None or not getattr(sock, "enabled", True):
                return 0.0
            return float(np.clip(self.value(sock, stack), -MAX_ANISOTROPY, MAX_ANISOTROPY))

        if kind == "ShaderNodeVolumeAbsorption":
            return np.maximum(1.0 - color("Color"), 0.0) * density(), zero, 0.0, zero, even
        if kind == "ShaderNodeVolumeScatter":
            return zero, color("Color") * density(), anisotropy(), zero, phase()
        if kind == "ShaderNodeVolumeCoefficients":
            # (Blender 5.0: the coefficients themselves, per metre)
            return (color("Absorption Coefficients"), color("Scatter Coefficients"), anisotropy(),
                    color("Emission Coefficients"), phase())
        if kind == "ShaderNodeVolumePrincipled":
            scatter, d = color("Color"), density()
            emission = max(self.value(node.inputs["Emission Strength"], stack), 0.0) * color("Emission Color")
            b = self.value(node.inputs["Blackbody Intensity"], stack)
            t = max(self.value(node.inputs["Temperature"], stack), 0.0)
            if b > 0:
                intensity = STEFAN_BOLTZMANN_CYCLES * (1.0 - b + b * t ** 4)
                glow = color("Blackbody Tint") * intensity * np.maximum(procedural.blackbody([t])[0], 0.0)
                emission = emission + np.maximum(glow, 0.0)
            kept = np.maximum(1.0 - np.sqrt(color("Absorption Color")), 0.0)
            return np.maximum(1.0 - scatter, 0.0) * kept * d, scatter * d, anisotropy(), emission, even
        if kind in ("ShaderNodeAddShader", "ShaderNodeMixShader"):
            a = self.volume(_by_identifier(node.inputs, "Shader"), stack)
            b = self.volume(_by_identifier(node.inputs, "Shader_001"), stack)
            if a is None and b is None:
                return None
            fa, fb = 1.0, 1.0
            if kind == "ShaderNodeMixShader":
                fb = float(np.clip(self.programs.constant_of(node.inputs[0], stack), 0.0, 1.0))
                fa = 1.0 - fb
            a, b = a or (zero, zero, 0.0, zero, even), b or (zero, zero, 0.0, zero, even)
            wa, wb = fa * a[1].mean(), fb * b[1].mean()
            if wa > 0 and wb > 0 and a[2] != b[2]:
                self.note(f"'{node.name}': volumes of different anisotropy scatter with their mean")
            if wa > 0 and wb > 0 and a[4] != b[4]:
                self.note(f"'{node.name}': volumes of different phase functions scatter by the one "
                          "that scatters most")
            g = (wa * a[2] + wb * b[2]) / (wa + wb) if wa + wb > 0 else 0.0
            return (fa * a[0] + fb * b[0], fa * a[1] + fb * b[1], g, fa * a[3] + fb * b[3],
                    a[4] if wa >= wb else b[4])
        if kind == "ShaderNodeEmission":
            glow = color("Color") * max(self.value(node.inputs["Strength"], stack), 0.0)
            return zero, zero, 0.0, glow, even
        if kind != "muted":
            self.unsupported(node, "as a volume; left out")
        return zero, zero, 0.0, zero, even

    def bent_normal(self, sock, stack):
        """(normal map or None, bump or None) feeding a ``Normal`` input: a Normal Map node
        (:meth:`normal_map`), a Bump node whose Height is an image's colour, whose own Normal
        may take a Normal Map or another Bump (the bump's fourth item: Materials.outer_bump_*); any
        other node the programs know (a Bevel, a Geometry normal
        turned by Vector Math, ...) gives a program of the normal in the normal map's place
        (``Materials.normal_program``); anything else is noted and leaves the normal alone."""
        src, _, stack = self.source(sock, stack)
        if src is None:
            return None, None
        node = src.node
        if node.bl_idname == "ShaderNodeNormalMap" and not node.mute:
            image = self.normal_map(node, stack)
            if image is not None:
                return image, None                  # an image's map exactly (Materials.normal_texture)
            color, tex = self.color(node.inputs["Color"], stack)
            if not textured(tex) and np.abs(color - (0.5, 0.5, 1.0)).max() <= 1e-6:
                return None, None                   # (the flat colour bends nothing)
            return self.programs.expression(sock, stack, VEC), None     # any other colour: a program
        if node.bl_idname != "ShaderNodeBump" and not node.mute and node.bl_idname in PROGRAM_NODES:
            program = self.programs.expression(sock, stack, VEC)
            if not procedural.varies(program):
                # A constant direction (Cycles' falls back to the surface's own normal where it is 0).
                c = (self.textures.mean_value(program) if isinstance(program, dict)
                     else program)
                c = np.asarray(c, np.float64).reshape(-1)
                if not np.any(c != 0.0) or not np.isfinite(c).all():
                    return None, None
                program = {"op": "combine", "x": float(c[0]), "y": float(c[1]), "z": float(c[2])}
            return program, None
        if node.bl_idname != "ShaderNodeBump" or node.mute:
            self.unsupported(node, f"drives '{sock.name}'; using the surface's own normal")
            return None, None
        inner, inner_bump = self.bent_normal(node.inputs["Normal"], stack)
        tex = self._bump_height(node.inputs["Height"], stack)
        if tex is None:
            return inner, inner_bump
        strength = max(self.value(node.inputs["Strength"], stack), 0.0)
        distance = self.value(node.inputs["Distance"], stack) * (-1.0 if node.invert else 1.0)
        if inner_bump is None:
            return inner, (tex, strength, distance)
        if len(inner_bump) > 3:
            if inner is not None:
                self.note(f"bump '{node.name}': a third Bump in a row over a normal map is not supported; "
                          "using the inner two")
                return inner, inner_bump
            # A third Bump in a row: the whole chain as one program of the normal (procedural's bump).
            return self.programs.expression(sock, stack, VEC), None
        # A Bump on a Bump: this one bends the normal the inner one made (its height as a program).
        height = self.programs.expression(node.inputs["Height"], stack, FLOAT)
        return inner, (*inner_bump, (height, strength, distance))

    def coat_normal(self, node, stack):
        """The coat's own normal (``Closure.coat_normal``) from Principled ``node``'s Coat Normal: a
        program of the normal and at most one Bump over it (its height a program), or the chain
        (a Normal Map's image, Bumps on Bumps) as one program.  None where the input is unlinked
        or bends nothing."""
        sock = node.inputs["Coat Normal"]
        if not self.linked(sock, stack):
            return None
        normal, bump = self.bent_normal(sock, stack)
        if (normal is not None and not isinstance(normal, dict)) or (bump is not None and len(bump) > 3):
            # A Normal Map's image, or a Bump on a Bump: the chain as one program of the normal.
            normal, bump = self.programs.expression(sock, stack, VEC), None
        if bump is not None:
            height, strength, distance = bump[:3]
            bump = (height if isinstance(height, dict) else _image_height(height), strength, distance)
        return None if normal is None and bump is None else (normal, bump)

    def _bump_height(self, sock, stack):
        """A bump's height source from input ``sock``: an image's index (the core takes its colour's
        luminance) or any other texture as a float program; None for a constant height, which bends
        nothing."""
        height = self.programs.expression(sock, stack, FLOAT)
        if not procedural.varies(height):
            return None
        image = height.get("color") if height.get("op") == "gray" else None
        return image["texture"] if _plain_image(image) else height

    def normal_map(self, node, stack):
        """(texture index, strength, uv map name, core ``NORMAL_*`` space) of a Normal Map ``node``
        fed by an image (tangent, object or world space, or Blender's object or world space), or
        None where its colour is another (:meth:`bent_normal` then takes the node as a program)."""
        space = NORMAL_SPACES.get(node.space)
        strength = max(self.value(node.inputs["Strength"], stack), 0.0)
        color, tex = self.color(node.inputs["Color"], stack)
        if space is None or isinstance(tex, dict) or tex < 0:
            return None
        return tex, strength, node.uv_map, space

    def _mix(self, node, stack):
        a = self.shader(_by_identifier(node.inputs, "Shader"), stack) or Closure()
        b = self.shader(_by_identifier(node.inputs, "Shader_001"), stack) or Closure()
        eta = self._fresnel_factor(node.inputs[0], stack)
        if eta is not None and a.diffuse_only and b.glossy_only:
            return _fresnel_layer(a, b, eta)
        ray = LIGHT_PATH_RAYS.get(self._light_path_output(node.inputs[0], stack))
        if ray is not None and b.clear:
            # Light Path's Is Camera (Glossy, Transmission) Ray into a clear Transparent BSDF: those
            # rays go through, every other ray sees the first shader (the object's ray visibility).
            return dataclasses.replace(a, hidden_rays=a.hidden_rays | ray)
        f = self.programs.expression(node.inputs[0], stack, FLOAT)
        if procedural.varies(f):
            exact = a.same_except_diffuse(b) or a.only_transparent or b.only_transparent
            if exact or a.levels is not None or b.levels is not None:
                return self._masked_mix(node, "Fac", f, a, b)
            # A mask between shaders that differ beyond their diffuse colours: levels the core picks
            # by the mask (the mix by the mask's mean for what comes before shading), constant mixes
            # where those are exact, else the two shaders themselves (exact, but noisier where
            # the mask is between 0 and 1: a pick of either at each point).
            c = self._masked_mix(node, "Fac", f, a, b, noted=False)
            steps = np.linspace(0.0, 1.0, MAP_LEVELS) if a.mixes_exactly(b) else (0.0, 1.0)
            levels = [a.combine(b, 1.0 - k, k) for k in steps]
            if len(steps) > 2 and (textured(a.texture) or textured(b.texture)) and a.same_diffuse_base(b):
                # Every level's diffuse lobe is the same but for its colour: each takes the mask's
                # point-by-point mix, one program for all (a program of its own per level made
                # the core evaluate the textures once per level, benchmarks/roughness_map_cost.py
                # --kind mask), and exact without the pick's noise.
                for level in levels:
                    level.texture, level.color[DIFFUSE] = c.texture, c.color[DIFFUSE]
            c.levels = (_clamp01(f), levels)
            return c
        fac = float(np.clip(self.programs.constant_of(node.inputs[0], stack), 0.0, 1.0))
        if 0.0 < fac < 1.0:
            self._note_mixed(node, a, b)
        return a.combine(b, 1.0 - fac, fac)

    def _fresnel_factor(self, sock, stack):
        """The IOR of a Fresnel curve that drives a Mix Shader's factor (a Fresnel node, or Layer
        Weight's Fresnel output of IOR 1 / (1 - Blend), on the surface's own normal), or None."""
        src, _, stack = self.source(sock, stack)
        if src is None or src.node.mute or src.node.bl_idname not in FRESNEL_FACTORS:
            return None
        node, constant = src.node, self.programs.constant_of
        if self.linked(node.inputs["Normal"], stack):
            return None
        if node.bl_idname == "ShaderNodeFresnel" and src.identifier == "Fac":
            eta = float(constant(node.inputs["IOR"], stack))
        elif node.bl_idname == "ShaderNodeLayerWeight" and src.identifier == "Fresnel":
            eta = layer_weight_ior(float(constant(node.inputs["Blend"], stack)))
        else:
            return None
        return eta if eta > 1.0 + 1e-6 else None

    def _add(self, node, stack):
        a = self.shader(_by_identifier(node.inputs, "Shader"), stack) or Closure()
        b = self.shader(_by_identifier(node.inputs, "Shader_001"), stack) or Closure()
        self._note_mixed(node, a, b)
        return a.combine(b, 1.0, 1.0)

    def _note_mixed(self, node, a, b):
        """Note a mix of shaders with different coats: the core has one coat per material, which
        then lies over both (weighted), where Cycles coats only its own Principled BSDF; one of
        two shaders that both have levels (``Closure.levels``: metallic or transmission maps, masks),
        which do not mix; and one of glossy or glass lobes of different microfacet distributions
        (one per lobe)."""
        if not (a.same_coat(b) or a.only_transparent or b.only_transparent):
            self.note(f"'{node.name}': mixes shaders with different coats; one coat (weighted) "
                      "covers both")
        if a.levels is not None and b.levels is not None:
            self.note(f"'{node.name}': mixes two shaders that both vary by a map (metallic, transmission or "
                      "a mask); their parts other than the diffuse take the maps' means")
        for lobe, what, attr in ((GLOSSY, "glossy", "glossy_beckmann"),
                                 (DIELECTRIC, "glass", "dielectric_beckmann")):
            if a.weight[lobe] > 0 and b.weight[lobe] > 0 and getattr(a, attr) != getattr(b, attr):
                self.note(f"'{node.name}': mixes {what} shaders of GGX and Beckmann microfacets; the "
                          "mix takes the distribution of most of its weight")

    def _diffuse(self, node, stack):
        """Diffuse BSDF: Lambert, or with a Roughness Cycles' rough diffuse (Oren-Nayar)."""
        color, tex = self.color(node.inputs["Color"], stack)
        c = Closure.lobe(DIFFUSE, 1.0, np.ones(3) if textured(tex) else color)
        c.texture = tex
        c.diffuse_roughness = float(np.clip(self.value(node.inputs["Roughness"], stack), 0.0, 1.0))
        return c

    def _subsurface(self, node, stack):
        """Subsurface Scattering BSDF: a diffuse lobe of its colour that scatters beneath the
        surface (Cycles' Random Walk; Christensen-Burley renders so too, noted)."""
        inp = node.inputs
        color, tex = self.color(inp["Color"], stack)
        c = Closure.lobe(DIFFUSE, 1.0, np.ones(3) if textured(tex) else color)
        c.texture = tex
        # Cycles: the Roughness input is the entry's alpha itself (saturated).  (Blender 5.0 finds
        # the inputs a method hides by their identifier alone; Cycles reads them all the same.)
        hidden = {name: _by_identifier(inp, name) for name in ("IOR", "Roughness", "Anisotropy")}
        alpha = float(np.clip(self.value(hidden["Roughness"], stack), 0.0, 1.0))
        c.subsurface = 1.0
        c.subsurface_params = self.subsurface_medium(node, node.falloff, inp["Radius"], inp["Scale"],
                                                     hidden["IOR"], hidden["Anisotropy"], alpha, stack)
        return c

    def subsurface_medium(self, node, method, radius, scale, ior, anisotropy, alpha, stack):
        """``Closure.subsurface_params`` of a subsurface part: Blender's ``method`` (its Random Walk
        methods; Christensen-Burley as Random Walk, noted) and its inputs ``radius``, ``scale``,
        ``ior``, ``anisotropy`` (sockets) and the entry's GGX ``alpha``, clamped as Cycles does."""
        if method == "BURLEY":
            self.note(f"'{node.name}': Christensen-Burley subsurface scattering renders as Random Walk")
        r = np.maximum(np.asarray(self.programs.constant_of(radius, stack, VEC), np.float64), 0.0)
        r = r * max(self.value(scale, stack), 0.0)
        return (r, float(np.clip(self.value(anisotropy, stack), 0.0, 0.9)),
                float(np.clip(self.value(ior, stack), 1.01, 3.8)), alpha,
                SUBSURFACE_SKIN if method == "RANDOM_WALK_SKIN" else SUBSURFACE_RANDOM_WALK)

    def _glossy(self, node, stack, color=None, program=None):
        """A glossy lobe of (mean) ``color``, varying as ``program`` if given."""
        if color is None:
            color, tex = self.color(node.inputs["Color"], stack)
            program = _program_of(tex, color) if textured(tex) else None
        rough, rough_map = self.roughness(node.inputs["Roughness"], stack)
        c = Closure.lobe(GLOSSY, 1.0, color, roughness=rough)
        c.glossy_texture = program
        c.roughness_texture = rough_map
        # Cycles' Glossy and Metallic anisotropy a in [-0.99, 0.99]: alpha (1 - a) along the
        # tangent and alpha / (1 - a) across it, or alpha / (1 + a) and alpha (1 + a) below 0:
        # s = (1 - max(a, 0)) / (1 + min(a, 0)).
        c.stretch, c.stretch_texture = self.anisotropy(node.inputs["Anisotropy"], stack, rough_map,
                                                       -0.99, 0.99, _glossy_stretch)
        if c.anisotropic:
            c.rotation, c.rotation_texture = self.rotation(node.inputs["Rotation"], stack)
            c.tangent = self.tangent(node.inputs["Tangent"], stack)
        if node.distribution == "MULTI_GGX":
            c.multiscatter = c.color[GLOSSY] * color
        elif node.distribution == "BECKMANN":
            c.beckmann = c.weight[GLOSSY]
        elif node.distribution == "ASHIKHMIN_SHIRLEY":
            self.note(f"'{node.name}': the Ashikhmin-Shirley distribution is rendered as GGX")
        return c

    def _metallic(self, node, stack):
        """A glossy lobe with the metal's Fresnel curve by angle: Cycles' F82 tint of the base
        colour and edge tint, or that curve through the physical conductor's reflectance face on
        and at cos = 1/7 (``conductor_f82``), F_ss the mean of the conductor's own curve.  A
        texture on the base colour makes the F0 a program (``Closure.metal_texture``), one on the
        edge tint the lobe's colour a program of the curve's mean instead.  A thin film goes over
        either (a physical conductor's by its complex index, ``Closure.film_conductor``)."""
        film = self.thin_film(node, stack)
        conductor = None
        if node.fresnel_type == "PHYSICAL_CONDUCTOR":
            ior, _ = self.color(node.inputs["IOR"], stack)
            extinction, _ = self.color(node.inputs["Extinction"], stack)
            base, tint = conductor_f82(ior, extinction)
            mean = conductor_fresnel(ior, extinction)
            conductor = (np.clip(ior, 0.0, 100.0), np.clip(extinction, 0.0, 100.0))
        else:
            base, base_tex = self.color(node.inputs["Base Color"], stack)
            tint, tint_tex = self.color(node.inputs["Edge Tint"], stack)
            mean = metal_fresnel(base, tint)
            if textured(base_tex) or textured(tint_tex):
                program = {"op": "metal", "color": _program_of(base_tex, base),
                           "tint": _program_of(tint_tex, tint)}
                c = self._glossy(node, stack, mean, program)
                if not textured(tint_tex):
                    c.metal_texture, c.metal_tint = _clamped_color(_program_of(base_tex, base)), tint
                if film is not None:
                    self.note(f"'{node.name}': Thin Film on a textured metal is not supported (ignored)")
                return c
        f0, rise, dip = metal_curve(base, tint)
        c = self._glossy(node, stack, f0)
        c.metal_rise, c.metal_dip = rise.copy(), dip.copy()          # weight 1
        if node.distribution == "MULTI_GGX":
            c.multiscatter = f0 * mean
        if film is not None:
            c.film, c.film_metal, c.film_conductor = (*film, np.ones(3)), 1.0, conductor
        return c

    def tangent(self, sock, stack):
        """(core.bsdf.TANGENT_*, UV map name or None) of a BSDF's Tangent input: Blender's Tangent
        node (radial about an axis, or a UV map's tangents) or, unlinked or Geometry's Tangent,
        Cycles' default (radial about Z); anything else is noted and takes the default."""
        src, _, stack = self.source(sock, stack)
        if src is None:
            return TANGENT_DEFAULT
        node = src.node
        if node.bl_idname == "ShaderNodeNewGeometry" and src.name == "Tangent" and not node.mute:
            return TANGENT_DEFAULT                      # (Geometry's Tangent: radial about Z)
        if node.bl_idname != "ShaderNodeTangent" or node.mute:
            self.note(f"'{node.name}' on a Tangent input is not supported (the radial tangent about "
                      "the object's Z axis is used, Cycles' default)")
            return TANGENT_DEFAULT
        if node.direction_type == "UV_MAP":
            return TANGENT_UV, node.uv_map
        return {"X": TANGENT_RADIAL_X, "Y": TANGENT_RADIAL_Y}.get(node.axis, TANGENT_RADIAL_Z), None

    def anisotropy(self, sock, stack, rough_map, low, high, stretch):
        """(stretch, float program of it or None) of an Anisotropy input clamped to [``low``,
        ``high``], ``stretch`` the node's float program of s from its anisotropy program.  A
        texture on it (an anisotropy map) stays a program, which the core evaluates at each hit,
        except beside a roughness map ``rough_map`` (the core keeps one of them: its mean, noted);
        s = 1 (isotropic) where |a| <= 1e-4."""
        f = self.programs.expression(sock, stack, FLOAT)
        if not procedural.varies(f):
            a = float(np.clip(self.value(sock, stack), low, high))
            return (1.0, None) if abs(a) <= 1e-4 else (float(stretch(a)), None)
        program = stretch(_math("MINIMUM", _math("MAXIMUM", f, low), high))
        mean = float(self.textures.mean_value(program))
        if rough_map is not None:
            self.note(f"'{sock.node.name}': a texture on Anisotropy beside a roughness map takes its mean")
            return mean, None
        return mean, program

    def rotation(self, sock, stack):
        """(mean turn, float program or None) of an anisotropic lobe's Rotation input: a texture on
        it (a rotation map: spun metal, brushed patterns) stays a program, which turns the
        tangent at each hit in the core, as in Cycles."""
        f = self.programs.expression(sock, stack, FLOAT)
        if not procedural.varies(f):
            return self.value(sock, stack), None
        return float(self.textures.mean_value(f)), f

    def roughness(self, sock, stack):
        """(mean roughness in [0, 1], float program or None) of a glossy Roughness input: a texture
        on it (a roughness map) stays a program, which the core evaluates at each hit."""
        f = self.programs.expression(sock, stack, FLOAT)
        if not procedural.varies(f):
            return float(np.clip(self.value(sock, stack), 0.0, 1.0)), None
        clamped = _clamp01(f)
        return float(self.textures.mean_value(clamped)), clamped

    def _glass(self, node, stack):
        """Glass and Refraction: a textured colour (stained glass) tints the light the glass lets
        through point by point, its reflections by the texture's mean (a few per cent of the light).
        Refraction has no Fresnel reflection: it refracts everything but under total internal
        reflection, where it gives nothing (Cycles; ``Materials.dielectric_fresnel``).  A Glass
        BSDF's Thin Film makes its reflection the film's colour (times its own), as Cycles; its
        Multiscatter GGX (the default) keeps Cycles' energy compensation of rough glass
        (``Materials.dielectric_multiscatter``: F_ss its colour)."""
        color, tex = self.color(node.inputs["Color"], stack)
        ior = self.value(node.inputs["IOR"], stack)
        rough, rough_map = self.roughness(node.inputs["Roughness"], stack) if "Roughness" in node.inputs \
            else (0.0, None)
        c = Closure.lobe(DIELECTRIC, 1.0, color, ior=max(ior, 1e-3), dielectric_roughness=rough,
                         dielectric_roughness_texture=rough_map)
        if textured(tex):
            c.dielectric_texture = _program_of(tex, color)
        if node.distribution == "BECKMANN":
            c.glass_beckmann = 1.0                  # (the Refraction BSDF's default)
        if node.bl_idname == "ShaderNodeBsdfRefraction":
            c.refraction_only, c.reflection = 1.0, np.zeros(3)
        elif node.distribution == "MULTI_GGX":
            # (Cycles' energy compensation, F_ss its transmission tint: the colour)
            c.glass_multiscatter = np.clip(np.asarray(color, np.float64), 0.0, 1.0)
        if node.bl_idname != "ShaderNodeBsdfRefraction" and "Thin Film Thickness" in node.inputs:
            film = self.thin_film(node, stack)
            c.film = None if film is None else (*film, np.ones(3))
        return c

    def _translucent(self, node, stack):
        """Translucent BSDF: the core's translucent lobe (Lambertian transmission); a texture on
        its colour (a leaf's veins) makes that colour a program the core evaluates at each hit."""
        color, tex = self.color(node.inputs["Color"], stack)
        c = Closure.lobe(TRANSLUCENT, 1.0, np.clip(color, 0.0, None))
        if textured(tex):
            c.translucent_texture = _program_of(tex, color)
        return c

    def _sheen(self, node, stack):
        """Sheen BSDF: the core's sheen (Cycles' microfiber sheen) of its Color (at least 0) and
        Roughness (saturated), not a layer: it dims nothing beside it.  Ashikhmin (Cycles' older
        velvet) renders as Microfiber, noted.  Textures on either input take their means (noted)."""
        if node.distribution != "MICROFIBER":
            self.note(f"'{node.name}': the Ashikhmin sheen is rendered as Microfiber")
        color = np.maximum(self.mean_color(node.inputs["Color"], stack), 0.0)
        rough = float(np.clip(self.value(node.inputs["Roughness"], stack), 0.0, 1.0))
        return Closure(sheen=color, sheen_roughness=rough)

    def _hair_principled(self, node, stack):
        """Principled Hair BSDF (Chiang's or Huang's model of a dielectric fibre with an absorbing
        core, on a curve's tube): its lobes approximated by the core's, from the same fibre
        (:func:`hair_lobes`: the absorption sigma of its Color, Melanin and Tint or Absorption
        Coefficient as Cycles derives it, and its IOR): R, the surface's reflection, and TRT with
        the later passes that come back out one glossy lobe of their shares and of the roughness of
        their spread along the fibre; TT, the light through the fibre, a tinted transparency
        (:func:`_through_fibre`); Huang's R, TT and TRT factors scale them.  The lobes' azimuthal
        shapes, the cuticle tilt (Offset), Coat, the elliptical fibre and the Random Color and
        Roughness are not modelled (those set are named).  In a white furnace the hair keeps the
        energy Cycles' keeps to 0.3 % (``test_hair_fibres_keep_the_energy_cycles_keeps``)."""
        inp = node.inputs
        huang = node.model == "HUANG"
        rough = float(np.clip(self.value(inp["Roughness"], stack), 0.0, 1.0))
        radial = rough if huang else float(np.clip(self.value(inp["Radial Roughness"], stack), 0.0, 1.0))
        kind = node.parametrization
        if kind == "ABSORPTION":
            sigma = np.maximum(self.mean_color(inp["Absorption Coefficient"], stack), 0.0)
        elif kind == "MELANIN":
            melanin = -np.log(max(1.0 - self.value(inp["Melanin"], stack), 1e-4))
            red = self.value(inp["Melanin Redness"], stack)
            sigma = (melanin * (1.0 - red) * np.array([0.506, 0.841, 1.653])
                     + melanin * red * np.array([0.343, 0.733, 1.924])
                     + hair_sigma(self.mean_color(inp["Tint"], stack), radial))
        else:
            sigma = hair_sigma(self.mean_color(inp["Color"], stack), radial)
        eta = max(self.value(inp["IOR"], stack), 1.0 + 1e-3)
        r, tt, trt = hair_lobes(sigma, eta)
        if huang:
            factors = [max(self.value(inp[name], stack), 0.0) for name in ("R lobe", "TT lobe", "TRT lobe")]
        else:
            factors = [1.0, 1.0, 1.0]
        # Chiang's longitudinal variance v of the roughness; Huang's roughness is the microfacets'
        # alpha.  The reflection's spread along the fibre is twice its normals': alpha = sqrt(v / 2).
        v = (0.726 * rough + 0.812 * rough ** 2 + 3.7 * rough ** 20) ** 2
        alpha = rough if huang else float(np.sqrt(v / 2.0))
        named = [name for name in ("Random Color", "Random Roughness", "Coat")
                 if name in inp and inp[name].enabled and self.value(inp[name], stack) != 0.0]
        if named:
            self.note(f"'{node.name}': its {', '.join(named)} not modelled (hair lobes approximated)")
        self.note(f"'{node.name}': the Principled Hair BSDF is approximated by a glossy lobe and a tinted "
                  "transparency")
        # R and TRT both leave along the fibre's specular cone (Chiang: TRT with twice R's spread and
        # shifted by the cuticle's tilt): one glossy lobe of their sum, its alpha their mean by share
        # (no Fresnel rise: at a tube's silhouette the rise to 1 would outweigh the opacity left there).
        glossy = factors[0] * r + factors[2] * trt
        share = factors[0] * r / max(float(glossy.mean()), 1e-30)
        alpha = alpha * (share + 2.0 * (1.0 - share))
        c = Closure.lobe(GLOSSY, 1.0, glossy, roughness=float(np.sqrt(min(alpha, 1.0))))
        # TT goes on through the fibre (Chiang's TT lobe lies within 20 degrees of straight on for a
        # smooth fibre of IOR 1.55).
        return _through_fibre(c, factors[1] * tt)

    def _hair(self, node, stack):
        """Hair BSDF (Cycles' older lobes about the fibre): Reflection a glossy lobe of its Color and
        of RoughnessU (the spread along the fibre), Transmission the light going on through the
        fibre tinted by its Color (:func:`_through_fibre`); Offset and RoughnessV (the spread about
        the fibre) are not modelled (noted)."""
        color = np.maximum(self.mean_color(node.inputs["Color"], stack), 0.0)
        self.note(f"'{node.name}': the Hair BSDF's {node.component.lower()} is approximated by "
                  f"{'a glossy lobe' if node.component == 'Reflection' else 'a tinted transparency'}")
        if node.component == "Transmission":
            return _through_fibre(Closure(), color)
        rough = float(np.clip(self.value(node.inputs["RoughnessU"], stack), 0.0, 1.0))
        return Closure.lobe(GLOSSY, 1.0, color, roughness=float(np.sqrt(rough)))

    def _holdout(self, node, stack):
        """Holdout: black for every ray, and what camera rays that meet it cut out of the image."""
        return Closure(holdout=1.0)

    def _transparent(self, node, stack):
        color, _ = self.color(node.inputs["Color"], stack)
        return Closure(transparent=np.clip(color, 0.0, None), transparent_weight=1.0)

    def _emission(self, node, stack):
        return self.emitted(node.inputs["Color"], node.inputs["Strength"], stack)

    def emitted(self, color_sock, strength_sock, stack) -> Closure:
        """An emission of colour times strength (Cycles: both sides, negative gives nothing here);
        a texture on either makes the radiance a program (``emission_texture``)."""
        color, tex = self.color(color_sock, stack)
        f = self.programs.expression(strength_sock, stack, FLOAT)
        if not procedural.varies(f):
            strength = self.value(strength_sock, stack)
            c = Closure(emission=np.maximum(color * strength, 0.0))
            if textured(tex) and strength > 0:
                c.emission_texture = _times(_program_of(tex, color), strength)
            return c
        program = _times(_program_of(tex, color), f)
        values = procedural.evaluate(program, procedural.SampledAttributes(), self.textures.images,
                                     sky_cache=self.textures.sky_cache)
        mean = np.maximum(values, 0.0).mean(axis=0)
        return Closure(emission=mean, emission_texture=program)

    def _masked_mix(self, node, what, f, a, b, noted=True, one_node=False) -> Closure:
        """Closures ``a`` and ``b`` mixed by ``f``, a float program that varies over the surface (a
        mask; clamped to [0, 1] as Cycles does): exact for the diffuse colours and the glossy ones
        without a Fresnel rise (``Closure.combine``), the rest by f's mean, noted (unless not
        ``noted``).  ``one_node``: ``a`` and ``b`` are one Principled BSDF at two values of an
        input, whose coat covers all of it (no note of different coats)."""
        f = _clamp01(f)
        if not one_node:
            self._note_mixed(node, a, b)
        mean = self.textures.mean_value(f)
        if noted and not (a.same_except_diffuse(b) or a.only_transparent or b.only_transparent):
            self.note(f"'{node.name}': a varying {what} mixes the diffuse colours point by point and the "
                      f"other parts by its mean {mean:.3f}")
        return a.combine(b, 1.0 - mean, mean, fac=f)

    def _specular_levels(self, node, stack, f) -> Closure:
        """The Principled BSDF ``node`` whose Specular IOR Level is the float program ``f`` (a
        specular map): the node at the map's mean, with the node at ``MAP_LEVELS`` values of the
        level from 0 to the map's largest value over stand-in coordinates (at least 1: an image's
        range) as its levels, which the core picks from by f over that at each point.  The level
        scales the layer's F0, not a mix of two shaders: between two neighbouring levels the pick
        takes their mix, and above the largest value the largest level."""
        f = _math("MAXIMUM", f, 0.0)
        values = np.nan_to_num(procedural.evaluate(f, procedural.SampledAttributes(), self.textures.images,
                                                   sky_cache=self.textures.sky_cache), nan=0.0, posinf=0.0)
        top = max(1.0, float(values.max()))
        c = self._principled_opaque(node, stack, {SPECULAR_LEVEL: float(values.mean())})
        levels = [self._principled_opaque(node, stack, {SPECULAR_LEVEL: float(v)})
                  for v in np.linspace(0.0, top, MAP_LEVELS)]
        c.levels = (_clamp01(_math("MULTIPLY", f, 1.0 / top)), levels)
        return c

    def thin_film(self, node, stack):
        """(thickness nm, IOR) of a node's Thin Film, or None where it is at most Cycles' cut-off of
        0.1 nm (the IOR at least 1e-5, as Cycles); a texture on either takes its mean (noted)."""
        thickness = self.value(node.inputs["Thin Film Thickness"], stack)
        if not np.float32(thickness) > np.float32(thin_film.THICKNESS_CUTOFF):    # (Cycles' floats)
            return None
        return float(min(thickness, 1e6)), float(np.clip(self.value(node.inputs["Thin Film IOR"], stack),
                                                         1e-5, 100.0))

    def _principled(self, node, stack):
        """Principled BSDF (:meth:`_principled_opaque`) with its Alpha: a Mix with a white
        Transparent BSDF by it (point by point for an alpha map, as a Mix Shader's mask)."""
        c = self._principled_opaque(node, stack)
        sock = node.inputs["Alpha"]
        alpha = self.programs.expression(sock, stack, FLOAT)
        clear = Closure(transparent=np.ones(3), transparent_weight=1.0)
        if procedural.varies(alpha):
            return self._masked_mix(node, "Alpha", alpha, clear, c)
        a = float(np.clip(self.value(sock, stack), 0.0, 1.0))
        return c if a >= 1.0 else clear.combine(c, 1.0 - a, a)

    def _principled_opaque(self, node, stack, fixed=None):
        """Principled BSDF without its Alpha.  Its Metallic, Transmission Weight and Coat Weight mix
        its metal, glass, dielectric and coated parts linearly (Cycles), so a texture on one makes
        it a Mix of the node at 0 and at 1 by that texture (``Closure.combine``: exact for the
        diffuse colour), and also gives the node at ``MAP_LEVELS`` values of it as levels the core
        picks from by the texture at each point (``Closure.levels``: a metallic map, else a
        transmission map, else a coat map; within the first one's levels, the others mix by
        their maps' means, noted).  A specular map (Specular IOR Level) where none of those varies
        gives levels too (:meth:`_specular_levels`); ``fixed`` holds the values so set."""
        inp = node.inputs
        fixed = fixed or {}
        for name in LINEAR_LEVEL_INPUTS + (SPECULAR_LEVEL,):
            f = self.programs.expression(inp[name], stack, FLOAT)
            if name in fixed or not procedural.varies(f):
                continue
            if name == SPECULAR_LEVEL:
                if not fixed:               # (within another map's levels: its mean, noted below)
                    return self._specular_levels(node, stack, f)
            else:
                at = [self._principled_opaque(node, stack, {**fixed, name: v}) for v in (0.0, 1.0)]
                if fixed:                   # within another map's levels: the mix, noted
                    return self._masked_mix(node, name, f, *at, one_node=True)
                c = self._masked_mix(node, name, f, *at, noted=False, one_node=True)
                between = [self._principled_opaque(node, stack, {**fixed, name: float(v)})
                           for v in np.linspace(0.0, 1.0, MAP_LEVELS)[1:-1]]
                c.levels = (_clamp01(f), [at[0], *between, at[1]])
                return c
        base, tex = self.color(inp["Base Color"], stack)
        m = fixed.get("Metallic")
        m = float(np.clip(self.value(inp["Metallic"], stack), 0.0, 1.0)) if m is None else m
        rough, rough_map = self.roughness(inp["Roughness"], stack)
        ior = max(self.value(inp["IOR"], stack), 1e-3)
        t = fixed.get("Transmission Weight")
        t = float(np.clip(self.value(inp["Transmission Weight"], stack), 0.0, 1.0)) if t is None else t
        level = fixed.get(SPECULAR_LEVEL)
        level = max(self.value(inp[SPECULAR_LEVEL], stack), 0.0) if level is None else level
        tint, _ = self.color(inp["Specular Tint"], stack)
        emitted = self.emitted(inp["Emission Color"], inp["Emission Strength"], stack)
        coat = fixed.get("Coat Weight")
        coat = float(np.clip(self.value(inp["Coat Weight"], stack), 0.0, 1.0)) if coat is None else coat
        # Cycles: alpha / aspect along the tangent and alpha aspect across it, aspect =
        # sqrt(1 - 0.9 a), for the metal and the specular layer (its glass stays isotropic).
        stretch, stretch_map = self.anisotropy(inp["Anisotropic"], stack, rough_map, 0.0, 1.0,
                                               _principled_stretch)
        beneath = float(np.clip(self.value(inp["Subsurface Weight"], stack), 0.0, 1.0))
        film = self.thin_film(node, stack)

        base_color = np.ones(3) if textured(tex) else base
        flat_base = base                  # the texture's mean where a lobe cannot use a texture
        dielectric = (1.0 - m) * (1.0 - t)
        c = Closure(roughness=rough, ior=ior, emission=emitted.emission,
                    emission_texture=emitted.emission_texture, dielectric_roughness=rough,
                    roughness_texture=rough_map,
                    diffuse_roughness=float(np.clip(self.value(inp["Diffuse Roughness"], stack), 0.0, 1.0)))
        c.stretch, c.stretch_texture = stretch, stretch_map
        if c.anisotropic:
            c.rotation, c.rotation_texture = self.rotation(inp["Anisotropic Rotation"], stack)
            c.tangent = self.tangent(inp["Tangent"], stack)
        if coat > 0:
            # Cycles: roughness and tint saturated, the IOR at least 1.
            c.coat = coat
            c.coat_roughness = float(np.clip(self.value(inp["Coat Roughness"], stack), 0.0, 1.0))
            c.coat_ior = max(self.value(inp["Coat IOR"], stack), 1.0)
            coat_tint, _ = self.color(inp["Coat Tint"], stack)
            c.coat_tint = np.clip(coat_tint, 0.0, 1.0)
            c.coat_normal = self.coat_normal(node, stack)
        sheen_weight = max(self.value(inp["Sheen Weight"], stack), 0.0)
        if sheen_weight > SHEEN_CUTOFF:
            # Cycles: the tint at least 0 and the roughness saturated; the sheen's albedo dims
            # everything beneath it (closure_layering_weight) by 1 - max(weight * tint) E(mu).
            c.sheen = sheen_weight * np.maximum(self.mean_color(inp["Sheen Tint"], stack), 0.0)
            c.sheen_roughness = float(np.clip(self.value(inp["Sheen Roughness"], stack), 0.0, 1.0))
            c.sheen_cover = float(c.sheen.max())
        c.weight[DIFFUSE] = dielectric
        c.color[DIFFUSE] = dielectric * base_color
        if beneath > 0 and dielectric > 0:
            # Cycles: the IOR is the Principled's (Random Walk: the entry's alpha its roughness
            # squared) or, for Skin, the Subsurface IOR (alpha 1).
            skin = node.subsurface_method == "RANDOM_WALK_SKIN"
            c.subsurface = dielectric * beneath
            c.subsurface_params = self.subsurface_medium(
                node, node.subsurface_method, inp["Subsurface Radius"], inp["Subsurface Scale"],
                _by_identifier(inp, "Subsurface IOR") if skin else inp["IOR"],
                _by_identifier(inp, "Subsurface Anisotropy"), 1.0 if skin else rough ** 2, stack)
        eta, f0 = specular_ior(ior, level)
        # Cycles drops a layer of IOR 1, unless a film coats it (a soap film's reflection).
        spec = dielectric if eta > 1.0 + 1e-6 or film is not None else 0.0
        f0_tint = np.clip(f0 * np.asarray(tint, np.float64), 0.0, 1.0)
        # Cycles' metallic layer: F82 with the specular tint, its curve by angle; a textured base
        # colour makes its F0 a program (below).
        metal_mean = metal_fresnel(flat_base, tint)
        metal_program = m > 0 and textured(tex)
        metal, metal_rise, metal_dip = metal_curve(flat_base, tint)
        if metal_program and spec == 0:
            metal = metal_mean
        else:
            c.metal_rise, c.metal_dip = m * metal_rise, m * metal_dip
        c.weight[GLOSSY] = m + spec
        c.color[GLOSSY] = m * metal + spec * f0_tint
        if spec > 0:
            c.fresnel_ior = eta
            c.rise = spec * (1.0 - f0_tint)
            c.layer = spec * f0_tint
            c.layered = spec
        layer_fss = np.zeros(3)
        if node.distribution == "MULTI_GGX":
            # F_ss of the layer as Cycles: f0 + (1 - f0) times the mean Fresnel rescaled to [0, 1].
            f_avg = (mean_fresnel(eta) - f0) / (1.0 - f0) if spec > 0 else 0.0
            layer_fss = f0_tint + (1.0 - f0_tint) * float(np.clip(f_avg, 0.0, 1.0))
            c.multiscatter = m * metal * metal_mean + spec * f0_tint * layer_fss
        c.weight[DIELECTRIC] = (1.0 - m) * t
        if rough_map is not None and c.weight[DIELECTRIC] > 0:
            c.dielectric_roughness_texture = rough_map      # (the glass follows the map too)
        # Cycles tints Principled glass by the square root of the base colour at each interface,
        # so that light crossing it (in and out) takes the base colour once.
        c.color[DIELECTRIC] = c.weight[DIELECTRIC] * np.sqrt(np.clip(flat_base, 0.0, None))
        if node.distribution == "MULTI_GGX":
            # (Cycles' energy compensation of the glass, F_ss its transmission tint)
            c.glass_multiscatter = c.weight[DIELECTRIC] * np.sqrt(np.clip(flat_base, 0.0, 1.0))
        c.reflection = c.weight[DIELECTRIC] * np.asarray(tint, np.float64)     # Cycles: the specular tint
        if film is not None and (spec > 0 or c.weight[DIELECTRIC] > 0 or m > 0):
            # The layer, the glass and the metal share the film; the tint then scales the film's
            # colour (core.thin_film.principled_reflectance), the glass reflecting white by it, and
            # is the metal's F82 tint as without a film.
            c.film = (*film, np.clip(np.asarray(tint, np.float64), 0.0, 1.0))
            c.reflection = c.weight[DIELECTRIC] * np.ones(3)
            if m > 0 and metal_program:
                self.note(f"'{node.name}': Thin Film on a textured metal is not supported (the metal "
                          "renders without it)")
            elif m > 0:
                c.film_metal = m
        if textured(tex) and c.weight[DIELECTRIC] > 0:
            c.dielectric_texture = {"op": "gamma", "color": _program_of(tex, base), "gamma": 0.5}
        c.texture = tex if c.weight[DIFFUSE] > 0 else -1
        if metal_program:
            # The metal's F0 follows the base colour's texture.  Alone in the glossy lobe, its
            # curve's mean too where it is mixed (Closure.combine); beside the dielectric layer
            # (0 < m < 1), the lobe's colour is k F0 + rest per unit weight (k = m / (m + spec);
            # the same F0 program at every metallic level of a map), and mixed the lobe keeps the
            # curve of the mean F0 (the core has no program beside a rise).
            c.metal_texture = _clamped_color(_program_of(tex, base))
            c.metal_tint = np.asarray(tint, np.float64)
            if spec == 0:
                c.glossy_texture = {"op": "metal", "color": _program_of(tex, base),
                                    "tint": [float(x) for x in tint]}
            else:
                c.metal_layer = (m / (m + spec), spec * f0_tint / (m + spec), layer_fss)
        return c


# Light Path outputs a Mix with a clear Transparent BSDF turns into ray visibility (Closure.hidden_rays).
LIGHT_PATH_RAYS = {"Is Camera Ray": VISIBLE_CAMERA, "Is Glossy Ray": VISIBLE_GLOSSY,
                   "Is Transmission Ray": VISIBLE_TRANSMISSION}

# A map between two closures that mix exactly at a constant factor (a Principled BSDF's metallic or
# transmission map, most masks) gives this many levels at factors k / 16; the core picks one of the
# two around the map's value at each point, by the fraction between them (exact, and the pick's
# noise is that of neighbours 1/16 apart).  Each costs the core a material row and its tables.
MAP_LEVELS = 17

# Principled inputs by which Cycles mixes the node's parts linearly (metal, glass, coat): a map on one
# gives the node at MAP_LEVELS values of it in [0, 1], in this order of precedence; then a specular
# map (NodeWalker._principled_opaque).
LINEAR_LEVEL_INPUTS = ("Metallic", "Transmission Weight", "Coat Weight")
SPECULAR_LEVEL = "Specular IOR Level"

# Nodes whose output may be a Fresnel curve of the view direction (NodeWalker._fresnel_factor).
FRESNEL_FACTORS = ("ShaderNodeFresnel", "ShaderNodeLayerWeight")

# Cycles leaves out a Principled's sheen of weight at most this (CLOSURE_WEIGHT_CUTOFF).
SHEEN_CUTOFF = 1e-5

# Shader nodes of EEVEE's alone: Cycles makes no closure of them (black).
EEVEE_ONLY_SHADERS = frozenset({"ShaderNodeEeveeSpecular"})
SHADERS = {
    "ShaderNodeBsdfPrincipled": NodeWalker._principled,
    "ShaderNodeBsdfDiffuse": NodeWalker._diffuse,
    "ShaderNodeSubsurfaceScattering": NodeWalker._subsurface,
    "ShaderNodeBsdfGlossy": NodeWalker._glossy,
    "ShaderNodeBsdfAnisotropic": NodeWalker._glossy,
    "ShaderNodeBsdfMetallic": NodeWalker._metallic,
    "ShaderNodeBsdfGlass": NodeWalker._glass,
    "ShaderNodeBsdfRefraction": NodeWalker._glass,
    "ShaderNodeEmission": NodeWalker._emission,
    "ShaderNodeBsdfTransparent": NodeWalker._transparent,
    "ShaderNodeBsdfTranslucent": NodeWalker._translucent,
    "ShaderNodeBsdfSheen": NodeWalker._sheen,
    "ShaderNodeBsdfHairPrincipled": NodeWalker._hair_principled,
    "ShaderNodeBsdfHair": NodeWalker._hair,
    "ShaderNodeHoldout": NodeWalker._holdout,
    "ShaderNodeMixShader": NodeWalker._mix,
    "ShaderNodeAddShader": NodeWalker._add,
}


def _by_identifier(sockets, identifier):
    for s in sockets:
        if s.identifier == identifier:
            return s
    return None


def _group_output(tree):
    outputs = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
    active = [n for n in outputs if n.is_active_output]
    return (active or outputs or [None])[0]

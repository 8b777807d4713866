"""Render settings stored in the .blend: ``scene.amcmcppm`` (one PropertyGroup on Scene).

Every property that configures the renderer has the same name as the
:class:`core.RenderSettings` field it feeds, and takes its default from that
dataclass, so the panel, ``render.py`` and the core never disagree on a default.
``export/settings.py`` turns the group into a ``RenderSettings``.  The last three
properties configure optional file outputs of the engine (statistics, snapshots).
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from ..core.settings import (AUTO_AIMED_VISIBLE, AUTO_PHOTONS_MIN, AUTO_PHOTONS_PER_PIXEL, AUTO_RAMP,
                             AUTO_UNIFORM_VISIBLE, DIRECT_LIGHT, MAX_BOUNCES, MAX_TRANSPARENT_BOUNCES,
                             METHODS, MUTATIONS, NORMALISATIONS, PIXEL_JITTER, VIEWPORT_FIRST_PHOTONS,
                             RenderSettings)

# Enum items: identifier (the core's value) -> (name, description, index).  The index is what
# the .blend stores, so each identifier keeps its own index whatever order the core lists them in.
METHOD_ITEMS = {
    "amcmcppm": ("AMCMCPPM", "Adaptive Markov chain Monte Carlo progressive photon mapping: photon "
                             "paths are mutated towards paths the camera sees", 0),
    "ppm": ("PPM", "Stochastic progressive photon mapping with independent uniform photons "
                   "(the baseline)", 1),
    "auto": ("Automatic", "AMCMCPPM, or uniform photons from the second pass on when many of the "
                          f"first pass's uniform photon paths are visible (at least "
                          f"{AUTO_UNIFORM_VISIBLE:.0%}; {AUTO_AIMED_VISIBLE:.0%} of those aimed where "
                          "distant photons are aimed at the view or through light portals), where the "
                          "chains gain little for what they cost", 2),
}
MUTATION_ITEMS = {
    "off": ("Off", "Mutate every dimension of the photon path", 0),
    "paper": ("Paper", "Redraw the dimensions after the vertex at which the mutated path became "
                       "visible (Watanabe et al.); biased by a few percent when that vertex varies", 1),
    "exact": ("Exact", "The paper's proposals, plus a redraw of the current state's suffix after a "
                       "rejection, which keeps detailed balance", 2),
}
NORMALISATION_ITEMS = {
    "cumulative": ("Cumulative", "Estimate the visible fraction from all passes so far, each "
                   "weighted by its recorded photons", 0),
    "per_pass": ("Per Pass", "Scale each pass by its own visible-fraction estimate", 1),
}

DIRECT_LIGHT_ITEMS = {
    "photons": ("Photons", "The light that reaches a surface straight from an emitter comes from the "
                           "photons' first hits, as the rest (the paper's method)", 0),
    "sampled": ("Light Samples", "Light samples and shadow rays (Light Samples per pixel and pass) for the "
                                 "light that reaches a surface straight from a lamp, an emissive mesh or the "
                                 "world (aimed through its light portals, if any); photons for the rest "
                                 "(light through glass or off mirrors, on sharp glossy surfaces, and in "
                                 "scenes with volumes)", 1),
}
PIXEL_JITTER_ITEMS = {
    "stratified": ("Stratified", "Each pixel's passes spread their camera rays evenly over the pixel, "
                                 "the lens (depth of field) and the lobes of the surfaces they meet "
                                 "(glass's reflection and refraction), and its light samples over the "
                                 "lights, by randomised Sobol sequences: edges, textures, small bright "
                                 "spots, out-of-focus blur, what glass shows and soft shadows settle "
                                 "sooner", 0),
    "random": ("Random", "Each pass's camera rays take independent random numbers for the pixel, the "
                         "lens and the surfaces' lobes, and so do the light samples", 1),
}


def enum_items(values, known):
    """EnumProperty items for the core's ``values``; a value new to the add-on still gets an item."""
    return tuple((v, *known.get(v, (v.replace("_", " ").title(), f"Core setting value {v!r}",
                                     100 + i))) for i, v in enumerate(values))


enum_methods = enum_items(METHODS, METHOD_ITEMS)
enum_mutations = enum_items(MUTATIONS, MUTATION_ITEMS)
enum_normalisations = enum_items(NORMALISATIONS, NORMALISATION_ITEMS)
enum_direct_light = enum_items(DIRECT_LIGHT, DIRECT_LIGHT_ITEMS)
enum_pixel_jitter = enum_items(PIXEL_JITTER, PIXEL_JITTER_ITEMS)

_DEFAULTS = RenderSettings()
INT_MAX = 2 ** 31 - 1


def bounce_limit(kind, what):
    """The property of one of Cycles' bounce limits of a kind (its name ``kind``)."""
    return IntProperty(
        name=kind, default=getattr(_DEFAULTS, f"{kind.lower()}_bounces"), min=0, max=MAX_BOUNCES,
        description=f"Most {what} of a light path, as Cycles' {kind} bounces (at Max Bounces or more, "
                    "no limit of its own)")


class AMCMCPPMRenderSettings(bpy.types.PropertyGroup):
    """Scene-level settings of the AMCMCPPM engine (``scene.amcmcppm``)."""

    method: EnumProperty(
        name="Method", items=enum_methods, default=_DEFAULTS.method,
        description="How photon paths are generated")
    passes: IntProperty(
        name="Passes", default=_DEFAULTS.passes, min=0, max=INT_MAX, soft_max=4096,
        description="Passes to render, each an eye pass and a photon pass (0 = until the time limit)")
    time_limit: FloatProperty(
        name="Time Limit", default=_DEFAULTS.time_limit, min=0.0, soft_max=3600.0, unit='TIME_ABSOLUTE',
        description="Stop after this many seconds of rendering (0 = no limit). The first pass runs whole; "
                    "a later pass still running at the limit is cut short there")
    viewport_passes: IntProperty(
        name="Viewport Passes", default=64, min=1, max=INT_MAX, soft_max=4096,
        description="Passes the 3D viewport renders in Rendered shading before it stops (it starts over "
                    "whenever the view or the scene changes)")
    viewport_pixel_size: EnumProperty(
        name="Viewport Pixel Size", default="2",
        items=[(str(k), f"{k} px", f"Render the 3D viewport at 1/{k} of its size") for k in (1, 2, 4, 8)],
        description="Pixel size of the 3D viewport's render in Rendered shading (larger: a coarser image "
                    "sooner)")
    photons_per_pass: IntProperty(
        name="Photons per Pass", default=_DEFAULTS.photons_per_pass, min=0, max=INT_MAX,
        soft_max=10_000_000,
        description="Photon paths traced per pass by every worker (with W workers a pass has W times as "
                    f"many); 0 = automatic: {AUTO_PHOTONS_MIN:,}, or {AUTO_PHOTONS_PER_PIXEL:g} per pixel "
                    f"of the image when that is more, reached after a few smaller first passes "
                    f"(from {AUTO_PHOTONS_MIN:,}) that show the first image soon")
    first_pass_photons: IntProperty(
        name="First Pass Photons", default=_DEFAULTS.first_pass_photons, min=0, max=INT_MAX,
        soft_max=10_000_000,
        description="Photon paths per worker in the first pass, from which the count grows "
                    f"{AUTO_RAMP} times a pass up to Photons per Pass: a first, noisy image sooner; "
                    f"0 = automatic (from {AUTO_PHOTONS_MIN:,} with automatic Photons per Pass, else "
                    f"no ramp; the viewport from {VIEWPORT_FIRST_PHOTONS:,})")
    seed: IntProperty(
        name="Seed", default=_DEFAULTS.seed, min=0, max=INT_MAX,
        description="Random seed; the same seed, settings and worker count give the same image")
    pixel_jitter: EnumProperty(
        name="Pixel Jitter", items=enum_pixel_jitter, default=_DEFAULTS.pixel_jitter,
        description="Where in its pixel and on the lens each pass's camera ray starts, which "
                    "lobe it takes at each surface and where its light samples fall (as "
                    "Cycles' sampling pattern)")
    alpha: FloatProperty(
        name="Alpha", default=_DEFAULTS.alpha, min=0.01, max=0.99, precision=3,
        description="Radius reduction per pass: r(i+1)^2 = r(i)^2 (i + alpha) / (i + 1); "
                    "smaller shrinks faster")
    initial_radius_px: FloatProperty(
        name="Initial Radius", default=_DEFAULTS.initial_radius_px, min=0.01, max=1000.0, soft_max=32.0,
        description="Initial photon gather radius, in pixel footprints at each visible point")
    direct_light: EnumProperty(
        name="Direct Light", items=enum_direct_light, default=_DEFAULTS.direct_light,
        description="Where the light that reaches a surface straight from an emitter comes from")
    direct_samples: IntProperty(
        name="Light Samples", default=_DEFAULTS.direct_samples, min=1, max=1024, soft_max=64,
        description="Light samples per pixel and pass (Direct Light: Light Samples)")
    bias_correction: BoolProperty(
        name="Bias Correction", default=_DEFAULTS.bias_correction,
        description="Also gather the photons within half the radius and correct the image towards "
                    "the extrapolation that removes the blur of the gather radius, as far as the "
                    "noise allows (one weight for the whole image)")
    edge_coverage: BoolProperty(
        name="Edge Coverage", default=_DEFAULTS.edge_coverage,
        description="Divide each gather near an edge of its surface (a table's rim, a floor that ends "
                    "at a wall, a leaf cut by an alpha map) by the share of its disc on the surface, so "
                    "that edges do not darken while the radius is large")
    focus_photons: BoolProperty(
        name="Aim Distant Photons", default=_DEFAULTS.focus_photons,
        description="Aim half of the sun's and the world's uniform photons (and the Markov chains' "
                    "uniform samples) at a sphere around what the camera sees, where that pays (a small "
                    "view of a large scene), or through the light portals of the scene's windows (area "
                    "lights marked Portal), as long as the passes' photons show it pays; the image's "
                    "expectation stays the same")
    light_paths_from_cycles: BoolProperty(
        name="Use Cycles' Light Paths", default=True,
        description="Take the bounce limits and caustics toggles from Cycles' Light Paths settings of "
                    "the scene (Total, Diffuse, Glossy, Transmission, Volume, Transparent; Reflective and "
                    "Refractive Caustics; the panel edits them), so that a scene keeps them between the two "
                    "engines; off: the engine's own settings below")
    max_bounces: IntProperty(
        name="Max Bounces", default=_DEFAULTS.max_bounces, min=0, max=MAX_BOUNCES,
        description="Most bounces of a light path from the camera to a light, counted as Cycles' Total: "
                    "the camera path's mirror and glass bounces plus the photon's (0: direct light)")
    diffuse_bounces: bounce_limit("Diffuse", "diffuse bounces")
    glossy_bounces: bounce_limit("Glossy", "glossy bounces (reflections off mirrors, glossy lobes and glass)")
    transmission_bounces: bounce_limit("Transmission", "transmission bounces (refractions through glass)")
    volume_bounces: bounce_limit("Volume", "scatterings in volumes (0: single scattering)")
    transparent_max_bounces: IntProperty(
        name="Transparent", default=_DEFAULTS.transparent_max_bounces, min=0, max=MAX_TRANSPARENT_BOUNCES,
        description="Most transparent surfaces (Transparent BSDFs, alpha) a light path crosses, as Cycles' "
                    "Transparent bounces; they count apart from the other bounces (at "
                    f"{MAX_TRANSPARENT_BOUNCES}: not counted)")
    caustics_reflective: BoolProperty(
        name="Reflective Caustics", default=_DEFAULTS.caustics_reflective,
        description="Light reflected off mirrors, glossy surfaces and glass lights diffuse surfaces, "
                    "as Cycles' Reflective Caustics (off: it does not, and a Principled BSDF's diffuse "
                    "part lit by diffuse surfaces is not dimmed by its specular and coat layers, as in "
                    "Cycles)")
    caustics_refractive: BoolProperty(
        name="Refractive Caustics", default=_DEFAULTS.caustics_refractive,
        description="Light refracted through glass lights diffuse surfaces, as Cycles' Refractive Caustics "
                    "(off: it does not, as in Cycles, so that a room lit only through glass is dark)")
    workers: IntProperty(
        name="Workers", default=_DEFAULTS.workers, min=0, max=1024, soft_max=64,
        description="Processes tracing photons in parallel (0 = one per CPU core, 1 = in Blender's "
                    "own process)")
    chains: IntProperty(
        name="Chains", default=_DEFAULTS.chains, min=1, max=1 << 24, soft_max=1 << 18,
        description="Markov chains advanced in lockstep by every worker (AMCMCPPM only)")
    target_acceptance: FloatProperty(
        name="Target Acceptance", default=_DEFAULTS.target_acceptance, min=0.01, max=0.99, precision=3,
        description="Acceptance rate the mutation size adapts towards (0.234 = the original method, "
                    "0.60 = Watanabe et al.)")
    mutation: EnumProperty(
        name="Low-Dimension Mutation", items=enum_mutations, default=_DEFAULTS.mutation,
        description="Which dimensions of a photon path a mutation changes")
    normalisation: EnumProperty(
        name="Normalisation", items=enum_normalisations, default=_DEFAULTS.normalisation,
        description="How the fraction of photon paths seen by the camera is estimated")
    glossy_through_roughness: FloatProperty(
        name="Glossy Through", default=_DEFAULTS.glossy_through_roughness, min=0.0, max=1.0, precision=3,
        description="Camera paths go on through glossy surfaces without a diffuse part (metals, "
                    "coats) smoother than this roughness, as through a mirror, instead of gathering "
                    "photons there: photons rarely find narrow lobes, and paths through wide ones meet "
                    "small lights by chance")
    initial_mutation_size: FloatProperty(
        name="Initial Mutation Size", default=_DEFAULTS.initial_mutation_size, min=1e-4, max=1e3,
        soft_max=10.0, precision=4,
        description="Mutation size every chain starts with, before adaptation")

    def light_path_limits(self):
        """({name: value} of the five bounce limits, two caustics toggles and the transparent limit
        (``LIGHT_PATHS``) a render takes, notes): Cycles' settings of the scene (``scene.cycles``, the
        same names) with ``light_paths_from_cycles`` and Cycles there, a limit above the engine's most
        (``MAX_BOUNCES``; ``MAX_TRANSPARENT_BOUNCES``, Cycles' own most, for the transparent limit)
        taken as that (noted); else the engine's own."""
        cycles = getattr(self.id_data, "cycles", None) if self.light_paths_from_cycles else None
        if cycles is None:
            notes = ["Cycles' Light Paths are not available (the Cycles add-on is off); the engine's own "
                     "bounce limits apply"] if self.light_paths_from_cycles else []
            return {name: getattr(self, name) for name in LIGHT_PATHS}, notes
        limits, notes = {}, []
        for name in LIGHT_PATHS:
            if name.startswith("caustics_"):
                limits[name] = bool(getattr(cycles, name))
                continue
            value = int(getattr(cycles, name))
            most = MAX_TRANSPARENT_BOUNCES if name == "transparent_max_bounces" else MAX_BOUNCES
            if value > most:
                notes.append(f"Cycles' {cycles.bl_rna.properties[name].name} of {value} is more than this "
                             f"engine traces; rendering with {most}")
                value = most
            limits[name] = value
        return limits, notes

    def own_light_paths(self):
        """Switch to the engine's own Light Paths, set to those a render takes now (Cycles')."""
        limits, _ = self.light_path_limits()
        for name, value in limits.items():
            setattr(self, name, value)
        self.light_paths_from_cycles = False

    stats_path: StringProperty(
        name="Statistics File", default="", subtype='FILE_PATH', options={'PATH_SUPPORTS_BLEND_RELATIVE'},
        description="Append per-pass statistics to this file as JSON lines (empty = off)")
    snapshot_times: StringProperty(
        name="Snapshot Times", default="",
        description="Comma-separated elapsed times in seconds at which to save the image so far, "
                    "for example 1,2,4,8 (empty = off)")
    snapshot_dir: StringProperty(
        name="Snapshot Folder", default="", subtype='DIR_PATH', options={'PATH_SUPPORTS_BLEND_RELATIVE'},
        description="Folder for the snapshot EXR files and their index snapshots.jsonl")


# Core settings that Blender's own data gives, not a property of ours: the data passes, their
# Alpha Threshold and Cryptomatte's levels are the view layer's (View Layer > Passes,
# engine.data_passes_of, engine.crypto_pass_count), the Ambient Occlusion pass's distance the
# world's (World > Ambient Occlusion > Distance).
FROM_BLENDER = ("data_passes", "pass_alpha_threshold", "cryptomatte_levels", "ao_distance")

# Cycles' Light Paths that the engine follows: the bounce limits, caustics toggles and transparent limit, as
# named by Cycles' settings and ours (AMCMCPPMRenderSettings.light_path_limits).
LIGHT_PATHS = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces",
               "caustics_reflective", "caustics_refractive", "transparent_max_bounces")

# Names of the properties that map one-to-one onto core.RenderSettings fields.
CORE_SETTING_NAMES = tuple(name for name in AMCMCPPMRenderSettings.__annotations__
                           if name in RenderSettings.__dataclass_fields__)

classes = (AMCMCPPMRenderSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.amcmcppm = PointerProperty(
        type=AMCMCPPMRenderSettings, name="AMCMCPPM Settings", description="AMCMCPPM render settings")


def unregister():
    del bpy.types.Scene.amcmcppm
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)

"""Render settings: one frozen dataclass; every default of the renderer lives here.

Symbols follow ``shared/docs/algorithm.md``: alpha (Knaus-Zwicker radius
reduction), A* (target acceptance), theta (mutation size).
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass

import numpy as np

from .light_passes import LIGHT_PASSES, LIGHTGROUP_PREFIX

METHODS = ("amcmcppm", "ppm", "auto")
# "auto": uniform photons from the second pass on when at least this share of the first pass's
# uniform samples were visible (benchmarks/error_vs_time.py; RenderSettings.method).
AUTO_UNIFORM_VISIBLE = 0.3
# ... or, where the photons from afar are aimed (a focus sphere or light portals that the first pass
# kept), when at least this share of its aimed uniform samples were visible: the photons PPM would
# go on with (benchmarks/portal_cost.py, focus_cost.py: aimed PPM ahead from 0.16 up).
AUTO_AIMED_VISIBLE = 0.1
AUTO_PHOTONS_MIN = 100_000          # photons per pass and worker at least (automatic count)
AUTO_PHOTONS_PER_PIXEL = 0.5        # ... and per pixel of the image (benchmarks/photons_per_pass.py)
GLOSSY_THROUGH_ROUGHNESS = 0.2     # benchmarks/glossy_through.py: through wins below, loses above
AUTO_RAMP = 4                       # the automatic count starts at the minimum and grows this much a pass
# The 3D viewport's first pass, photons per worker (with RenderSettings.first_pass_photons 0): a moved
# view's first image after 0.26 of the time on the Cornell box at 320x180, 0.54 on glass_ceiling_room
# (benchmarks/viewport_first_image.py).
VIEWPORT_FIRST_PHOTONS = 10_000
# Under light portals (core.lights.Focus.through) the automatic count aims at this many visible
# photons per pixel and pass over all workers, by the last pass's visible share, and at least
# AUTO_PORTAL_MIN per worker (benchmarks/portal_cost.py; RenderSettings.portal_photons).
AUTO_PORTAL_VISIBLE_PER_PIXEL = 1.0
AUTO_PORTAL_MIN = 10_000
MUTATIONS = ("off", "paper", "exact")
DIRECT_LIGHT = ("photons", "sampled")
PIXEL_JITTER = ("stratified", "random")
NORMALISATIONS = ("cumulative", "per_pass")
# Data passes of the first surface each camera ray meets (RenderSettings.data_passes), and those
# taken from the first pass alone (as Cycles takes them from its first sample; the others are means).
DATA_PASSES = ("depth", "normal", "albedo", "denoising_normal", "denoising_depth", "position", "uv",
               "object_index", "material_index", "mist", "crypto_object", "crypto_material", "crypto_asset",
               *LIGHT_PASSES, "ao", "shadow_catcher")
FIRST_PASS_DATA = ("depth", "position", "object_index", "material_index")
# A Shader AOV's data pass: this and its name (Materials.aov_names).
AOV_PREFIX = "aov:"
MAX_BOUNCES = 64                    # the most any bounce limit may be
# The most transparent bounces (Cycles' Transparent, at most 1024 there too): at it, crossings are
# not counted (each segment of a path crosses at most context.MAX_TRANSPARENT_CROSSINGS surfaces).
MAX_TRANSPARENT_BOUNCES = 1024


@dataclass(frozen=True)
class BounceLimits:
    """Cycles' bounce limits of a light path (``RenderSettings.max_bounces`` and the four after
    it): ``total`` bounces in all, and of each kind.  A light path camera - x_1 ... x_n - light
    has n - 1 bounces (x_n, the vertex nearest the light, does not count: 0 is direct light),
    each of the kind of its scattering: diffuse (diffuse, translucent, subsurface), glossy
    (reflections off mirrors, glossy lobes and glass), transmission (refraction) or volume
    (scattering in a volume).  With Cycles' Caustics toggles, ``caustics_reflective`` and
    ``caustics_refractive``: off, a light path that reaches a mirror, glossy lobe or a glass's
    reflection (a glass's refraction) right after a diffuse bounce, on the way from the camera,
    carries nothing (:class:`RenderSettings`).  ``transparent``: Cycles' Transparent bounces
    (``RenderSettings.transparent_max_bounces``)."""

    total: int = 8
    diffuse: int = MAX_BOUNCES
    glossy: int = MAX_BOUNCES
    transmission: int = MAX_BOUNCES
    volume: int = MAX_BOUNCES
    caustics_reflective: bool = True
    caustics_refractive: bool = True
    transparent: int = MAX_TRANSPARENT_BOUNCES

    @property
    def counts_crossings(self) -> bool:
        """Whether the transparent limit binds (below ``MAX_TRANSPARENT_BOUNCES``): paths then count
        the transparent surfaces they cross (``RenderSettings.transparent_max_bounces``)."""
        return self.transparent < MAX_TRANSPARENT_BOUNCES

    @property
    def array(self):
        """(5,) int16 [total, diffuse, glossy, transmission, volume] (the order of ``bounces``
        rows)."""
        return np.array([self.total, self.diffuse, self.glossy, self.transmission, self.volume], np.int16)

    @property
    def by_kind(self) -> bool:
        """Whether some kind's limit binds (is below ``total``): photons then count their kinds."""
        return min(self.diffuse, self.glossy, self.transmission, self.volume) < self.total

    @property
    def blocks_caustics(self) -> bool:
        """Whether a Caustics toggle is off: photons then keep what a diffuse bounce next is worth."""
        return not (self.caustics_reflective and self.caustics_refractive)


def usable_cpus() -> int:
    """CPUs this process may run on (at least 1): its affinity where the system reports one."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):          # (macOS and Windows have no sched_getaffinity)
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class RenderSettings:
    """How to render.  Invalid values raise ``ValueError`` naming the field."""

    method: str = "amcmcppm"
    """"amcmcppm": photons from Markov chains that seek paths seen by the camera
    (Hachisuka & Jensen 2011); "ppm": independent uniform photons (stochastic
    progressive photon mapping, the baseline); "auto": the chains' first pass, then uniform
    photons when at least ``AUTO_UNIFORM_VISIBLE`` of that pass's uniform samples were visible
    (unaimed: with a focus, estimated from its aimed ones by their weights), or where the photons
    from afar are aimed (``focus_photons``, kept after that pass) at least ``AUTO_AIMED_VISIBLE``
    of the aimed ones, else the chains on.  The chains sample the visible paths uniformly, so
    where a share f of uniform paths is visible they record at most 1/f times as many useful
    photons per path as uniform photons do, while an iteration traces up to two paths and keeps
    its books (two to three uniform paths' time); at f >= 0.3 that bound, 3.3, is about what they
    cost.  Aimed, the uniform photons PPM goes on with are the aimed ones, and it measured ahead
    from f = 0.16 up (a far sunlit corner, rooms lit through light portals).  The image then
    starts again from the second pass."""

    passes: int = 16
    """Passes to render (eye pass + photon pass each); 0 = until ``time_limit``."""

    time_limit: float = 0.0
    """Stop after this many seconds of rendering (0 = no limit).  The first pass always runs
    whole; a later pass still running at the limit is cut short there, and its photons count
    by their number (see :class:`core.integrator.Accumulator`)."""

    photons_per_pass: int = 0
    """Photon paths per pass and worker; 0 = automatic: ``AUTO_PHOTONS_MIN`` (the paper's
    100,000 per thread), or ``AUTO_PHOTONS_PER_PIXEL`` per pixel of the image when that is
    more (1,036,800 at 1920x1080; see :meth:`photons_for`); the first passes of an automatic
    count are smaller, so that the first image comes soon (:meth:`pass_photons`).  PPM traces
    this many uniform paths; AMCMCPPM runs this many chain iterations (each traces a uniform
    path, plus a mutated one unless the uniform path is visible, and records one path once
    the chain has a visible state).  With W workers a pass has W times as many photons."""

    first_pass_photons: int = 0
    """Photon paths per worker in the first pass, from which the count grows ``AUTO_RAMP`` times a
    pass up to ``photons_per_pass`` (explicit or automatic); 0 = the automatic count's own ramp
    (from ``AUTO_PHOTONS_MIN``), and none for an explicit count.  A small first pass shows a first,
    noisy image sooner; passes are averaged by their photons, so it weighs little later.  The 3D
    viewport starts from ``VIEWPORT_FIRST_PHOTONS`` when this is 0 (see :meth:`pass_photons`)."""

    seed: int = 0
    """Random seed; the same seed, settings and worker count give the same image."""

    alpha: float = 2.0 / 3.0
    """Knaus-Zwicker radius reduction: r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1)."""

    initial_radius_px: float = 4.0
    """Initial gather radius in pixel footprints at each measurement point."""

    bias_correction: bool = True
    """Correct the image for the photon gathers' kernel bias: every gather also sums the
    photons within half its radius, and the image is A + w (B - A) of the estimates A at the
    radius and B at half of it, clamped at 0 (w = 4/3 removes a bias that grows as r^2, the
    Richardson extrapolation; w = 0 is the plain estimate).  One w for the whole image, from
    the spread of the passes (for the Markov chains also of two halves of the chains): the one that
    minimises the estimated relMSE (noise of the extrapolation against the bias it removes;
    :meth:`core.integrator.Accumulator._corrected`).  Volume gathers are not corrected."""

    edge_coverage: bool = True
    """Divide each surface gather by the share of its disc that lies on a surface photons can
    land on (``core/coverage.py``): near an edge (a table's rim, a floor that ends at a wall, a leaf
    cut by an alpha map) the disc reaches off the surface and the plain estimate is too dark, by up
    to half at the edge.  Probed only near discontinuities of the image's points; elsewhere the
    share is exactly 1."""

    direct_light: str = "photons"
    """Where the light that reaches a surface seen by the camera straight from an emitter comes
    from: "photons", the photons' first vertices (the paper's method), or "sampled",
    ``direct_samples`` light samples per measurement point and pass (an emitter chosen by power,
    several lamps by their power over the squared distance in part; a shadow ray), the photons then
    depositing from their second vertex on for those emitters at those points (``core/direct.py``:
    which emitters, points and scenes; the others keep their photons' direct light, and
    ``RenderResult.direct_light`` says why where the scene rules the samples out).  Light through
    glass or off mirrors comes from photons either way."""

    direct_samples: int = 4
    """Light samples per measurement point and pass with ``direct_light="sampled"``."""

    pixel_jitter: str = "stratified"
    """Where in its pixel (by the pixel filter) each pass's camera ray of a pixel starts, with depth
    of field where on the lens, which lobe it takes at each surface, and where its light samples
    fall (``direct_light="sampled"``): "stratified", each pixel's passes spread evenly over its
    area (Sobol's dimensions 1 and 2 with a random digital shift per pixel,
    :func:`core.camera.stratified_jitter`), over the lens (dimensions 3 and 4,
    :func:`core.camera.stratified_lens`) and over the lobes (at the first surface dimensions 5 to
    7, behind it a scrambled Sobol sequence of each depth's own: a glass's reflection and
    refraction in their Fresnel shares, :func:`core.camera.stratified_choices`), and its light
    samples over the emitters and the points on them (a 4-dimensional Sobol sequence of its own,
    index and coordinates scrambled per pixel: :func:`core.direct.stratified_light`), or "random",
    independent numbers every pass.  Each pass's numbers are uniform either way (the image's
    expectation is the same); stratified, the noise of where the passes look (edges, textures,
    small bright spots, sharp shadows, the blur out of focus, what glass and mirrors show) and of
    soft shadows falls faster."""

    focus_photons: bool = True
    """Aim the uniform photons from afar (the sun's, the world's) at what the camera sees: half of
    them start on the disc of a sphere around most of the first pass's measurement points instead of
    anywhere on the scene's (:class:`core.lights.Focus`; their fluxes keep the estimate exact),
    where that pays by a model of the points' photon density, until the passes' own photons show
    that it does not (light from outside the sphere, such as off a mirror or through a window
    beyond it).  A long lens on a corner of a large sunlit scene gets hundreds of times the photons
    there.  The Markov chains draw their uniform samples so too, their target and normaliser taking
    the weights and each run of states from a visible uniform sample recorded with its weight
    (core/mcmc.py, "Photons from afar"): they find and swap in visible paths that much more often.
    For them the focus also goes where their uniform samples outside the visible set (which light
    what the camera sees only through glass or in a curved mirror) show that it does not pay
    there.  Where the scene has light portals (``World.portals``, Cycles' portals in its windows)
    the aimed half goes through them instead of the sphere (:meth:`core.lights.Focus.through`).
    Off: every such photon starts anywhere."""

    max_bounces: int = 8
    """Most bounces of a light path from the camera to a light, as Cycles' Max Bounces (Total):
    the camera path's mirror and glass bounces plus the photon's, counted as Cycles counts them
    (every scattering event but the one nearest the light; 0 is direct light alone).  A
    photon path has at most this many scattering events; a camera path sees emitters through
    up to one more mirror or glass bounce."""

    diffuse_bounces: int = MAX_BOUNCES
    """Most diffuse bounces of a light path (Cycles' Diffuse bounces, counted as ``max_bounces``;
    diffuse, translucent and subsurface scattering); at ``max_bounces`` or more, no limit of its
    own."""

    glossy_bounces: int = MAX_BOUNCES
    """Most glossy bounces of a light path (Cycles' Glossy bounces, counted as ``max_bounces``:
    reflections off mirrors, glossy lobes and glass); at ``max_bounces`` or more, no limit of its
    own."""

    transmission_bounces: int = MAX_BOUNCES
    """Most transmission bounces of a light path (Cycles' Transmission bounces, counted as
    ``max_bounces``: refractions through glass); at ``max_bounces`` or more, no limit of its own."""

    volume_bounces: int = MAX_BOUNCES
    """Most scatterings in volumes of a light path (Cycles' Volume bounces, counted as
    ``max_bounces``; Cycles' default 0 is single scattering); at ``max_bounces`` or more, no limit
    of its own."""

    caustics_reflective: bool = True
    """Cycles' Reflective Caustics: off, light that reflects off a mirror, a glossy lobe (a
    Principled BSDF's specular, metal or coat) or a glass and then meets a diffuse surface
    (diffuse, translucent or subsurface scattering) carries nothing on from there, as Cycles drops
    those closures at a path's vertex after a diffuse bounce; so does a Principled's diffuse part
    lose its specular and coat layers' attenuation there, as in Cycles."""

    caustics_refractive: bool = True
    """Cycles' Refractive Caustics: off, light that refracts through glass (a Glass, Refraction or
    Principled BSDF's transmission) and then meets a diffuse surface carries nothing on from there
    (``caustics_reflective``)."""

    transparent_max_bounces: int = MAX_TRANSPARENT_BOUNCES
    """Most transparent surfaces a light path crosses in all (Cycles' Transparent bounces: alpha,
    Transparent BSDF and volume-only meshes, not counted as bounces): a light path camera - x_1 ...
    x_n - light carries light only if it crosses at most this many, and at most one fewer before
    x_n, the vertex nearest the light (Cycles ends a camera path at the surface after its last
    allowed crossing, where it sees emission alone, and its light samples may cross the rest).  At
    ``MAX_TRANSPARENT_BOUNCES`` (1024, the default) crossings are not counted; a path's segment
    crosses at most ``context.MAX_TRANSPARENT_CROSSINGS`` surfaces either way."""

    workers: int = 0
    """Processes tracing photons in parallel; 0 = one per CPU core this process may use
    (:func:`usable_cpus`), 1 = in this process."""

    chains: int = 4096
    """Markov chains advanced in lockstep by every worker (AMCMCPPM only); many chains make
    big NumPy batches, fewer chains run more iterations each per pass."""

    target_acceptance: float = 0.60
    """Target acceptance rate A* of the mutation-size adaptation (0.234 = the original)."""

    mutation: str = "exact"
    """Low-dimension mutation: "off" mutates every dimension; "paper" redraws the dimensions
    after the vertex at which the mutated path became visible (Watanabe et al.), which is
    biased when that vertex varies between paths (a few percent in a furnace); "exact" makes
    the same proposals and also redraws the current state's suffix after a rejection, which
    keeps detailed balance (algorithm.md 3)."""

    normalisation: str = "cumulative"
    """Visible-fraction estimate: "cumulative" uses one fraction for all passes so far (the
    passes' own fractions averaged with weights = their recorded photons, which pools all
    uniform samples when the passes are alike); "per_pass" scales each pass by that pass's
    own fraction."""

    initial_mutation_size: float = 1.0
    """theta_1, the mutation size every chain starts with."""

    glossy_through_roughness: float = GLOSSY_THROUGH_ROUGHNESS
    """Camera paths go on through glossy lobes (metals, Glossy BSDFs, coats) of a smaller roughness
    (Blender's), as through a mirror, instead of ending on them to gather photons: photons find
    narrow lobes rarely, while a path through a wide lobe meets small lights by chance.  Not
    through a glossy lobe with a diffuse one beside it (Principled's specular layer), where the
    point weighs both (measured with ``benchmarks/glossy_through.py``)."""

    data_passes: tuple = ()
    """Data passes to make besides the image (``RenderResult.data``), of the surface each camera
    ray stops on (past what is transparent to it): "depth", its distance along the camera's view
    axis (from the camera for panoramas; 1e10 where the ray meets nothing), from rays through the
    pixels' centres as Cycles' Z pass (its first sample); "normal", its shading normal in world
    space facing the camera (0 where the ray meets nothing; past transparent surfaces by
    ``pass_alpha_threshold``), averaged over the passes as Cycles' Normal pass; "albedo", Cycles'
    Denoising Albedo for a denoiser (:class:`core.eye_pass.DenoisingPaths`): the albedo of the
    diffuse-like lobes (diffuse, translucent, sheen, glossy and glass rougher than Cycles' 0.075
    alpha) of the first surface where they make more than a quarter of the total, times the
    albedos of the specular-like lobes before it, plus the emission and the world seen on the
    way, averaged over the passes; "denoising_normal", Cycles' Denoising Normal:
    the shading normal (world space, facing the camera side) of that surface (0 where the path
    leaves the scene first); "denoising_depth", Cycles' Denoising Depth: the lengths of the
    path's segments up to that surface, each times the mean of the specular albedos before it;
    and of the surface each camera ray stops on, as Cycles' passes of those names: "position"
    (world space, from the centre rays; 0 where rays meet nothing), "uv" ((u, v, 1) of
    ``Scene.uvs``, 0 without; as the normal), "object_index" and "material_index" (the pass
    indices, ``Scene.object_info`` and ``Materials.pass_index``, from the centre rays; 0 where rays meet
    nothing), "mist" (``World.mist_*`` of its distance from the camera; 1 where rays meet
    nothing); "crypto_object", "crypto_material", "crypto_asset": Cycles' Cryptomatte passes
    (:mod:`core.cryptomatte`, ``Scene.cryptomatte_ids``), (H, W, 2 ``cryptomatte_levels``) of (id,
    coverage) pairs by decreasing coverage; "aov:" + a name (``Materials.aov_names``): that Shader
    AOV (H, W, 4), its value (a colour, or a number repeated) where the camera rays' surface writes
    it and 1 in the fourth channel, averaged over the passes (0 where none writes it).  Cycles'
    light passes (:mod:`core.light_passes`, (H, W, 3) each): "diffuse_direct", "diffuse_indirect",
    "glossy_direct", "glossy_indirect", "transmission_direct", "transmission_indirect" (divided by
    their colour, as Cycles writes them), "volume_direct", "volume_indirect", "emission",
    "environment", and the colours "diffuse_color", "glossy_color", "transmission_color"; they add
    up to the image (they take its ``bias_correction`` in proportion).  "ao": Cycles' Ambient
    Occlusion pass (H, W, 3): at the surfaces camera rays stop on, what a ray sent in a cosine
    direction about the shading normal carries back unoccluded within ``ao_distance`` (1 in the
    open, through transparent surfaces their tint; times the camera path's weight there), averaged
    over the passes.  "lightgroup:" + a name (``Scene.light_groups``): Cycles' light group pass
    ``Combined_<name>`` (H, W, 3), the image as lit by that group's emitters alone (``Lights.group``,
    ``Scene.emitter_group``, ``World.group``): their light seen directly and all that their photons
    bring (with the image's bias correction in proportion); the groups' passes and the light of
    emitters in none add up to the image.  "shadow_catcher": Cycles' Shadow Catcher pass (H, W, 3)
    in scenes with shadow catchers (``SHADOW_CATCHER``, :mod:`core.shadow_catcher`): what the
    other objects do to the catchers' light, the light of the camera paths that met a catcher first
    over the catchers' own (1 where they met none).  With catchers the image is Cycles' Combined of
    them: the matte alone (its alpha without the shadow) when this pass is asked for, else Cycles'
    approximate shadow catcher (the matte with the shadow as alpha, or over the world on an opaque
    film)."""

    ao_distance: float = 10.0
    """How far the Ambient Occlusion pass's rays look for what occludes them (Blender's World >
    Ambient Occlusion > Distance, in scene units)."""

    cryptomatte_levels: int = 6
    """The (id, coverage) pairs per pixel of the Cryptomatte passes (Blender's View Layer >
    Cryptomatte > Levels: 6, at most 16; Cycles writes them in passes of two)."""

    pass_alpha_threshold: float = 0.5
    """The Alpha Threshold of the data passes, as Blender's View Layer > Passes: a transparent
    surface at least this opaque stops the rays through the pixels' centres (depth, position,
    object and material index: ``FIRST_PASS_DATA``), a more transparent one with the chance that
    Cycles' sample picks a closure other than its Transparent BSDF there
    (``eye_pass.cycles_stop_chance``; 0: every surface stops them); the normal and UV are those of
    the first surface at least this opaque, where a ray crosses the more transparent ones before
    it (by the same chance; else 0, as Cycles' samples: ``eye_pass.threshold_data``)."""

    def __post_init__(self):
        def bad(name, why):
            raise ValueError(f"RenderSettings.{name} {why} (got {getattr(self, name)!r})")

        if self.method not in METHODS:
            bad("method", f"must be one of {METHODS}")
        if self.mutation not in MUTATIONS:
            bad("mutation", f"must be one of {MUTATIONS}")
        if self.direct_light not in DIRECT_LIGHT:
            bad("direct_light", f"must be one of {DIRECT_LIGHT}")
        if not 1 <= self.direct_samples <= 1024:
            bad("direct_samples", "must lie in [1, 1024]")
        if self.pixel_jitter not in PIXEL_JITTER:
            bad("pixel_jitter", f"must be one of {PIXEL_JITTER}")
        if self.normalisation not in NORMALISATIONS:
            bad("normalisation", f"must be one of {NORMALISATIONS}")
        if not all(name in DATA_PASSES or (isinstance(name, str) and name.startswith((AOV_PREFIX,
                                                                                     LIGHTGROUP_PREFIX)))
                   for name in self.data_passes):
            bad("data_passes", f"must name some of {DATA_PASSES}, Shader AOVs ('{AOV_PREFIX}' + name) or "
                               f"light groups ('{LIGHTGROUP_PREFIX}' + name)")
        if self.passes < 0:
            bad("passes", "must be >= 0")
        if not self.time_limit >= 0:
            bad("time_limit", "must be >= 0")
        if self.passes == 0 and self.time_limit == 0:
            bad("passes", "and time_limit are both 0, so the render would never stop")
        if self.photons_per_pass < 0:
            bad("photons_per_pass", "must be >= 0 (0 = automatic)")
        if self.first_pass_photons < 0:
            bad("first_pass_photons", "must be >= 0 (0 = automatic)")
        if not 0 < self.alpha < 1:
            bad("alpha", "must lie in (0, 1)")
        if not 0 < self.initial_radius_px <= 1000:
            bad("initial_radius_px", "must lie in (0, 1000]")
        if not 0 <= self.max_bounces <= MAX_BOUNCES:
            bad("max_bounces", f"must lie in [0, {MAX_BOUNCES}]")
        for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
            if not 0 <= getattr(self, name) <= MAX_BOUNCES:
                bad(name, f"must lie in [0, {MAX_BOUNCES}]")
        if not 0 <= self.transparent_max_bounces <= MAX_TRANSPARENT_BOUNCES:
            bad("transparent_max_bounces", f"must lie in [0, {MAX_TRANSPARENT_BOUNCES}]")
        if not 0.0 <= self.pass_alpha_threshold <= 1.0:
            bad("pass_alpha_threshold", "must lie in [0, 1]")
        if not (math.isfinite(self.ao_distance) and self.ao_distance > 0.0):
            bad("ao_distance", "must be a positive number of scene units")
        levels = self.cryptomatte_levels
        if not (isinstance(levels, (int, np.integer)) and 1 <= levels <= 16):
            bad("cryptomatte_levels", "must be an integer in [1, 16]")
        if self.workers < 0:
            bad("workers", "must be >= 0")
        if self.chains < 1:
            bad("chains", "must be >= 1")
        if not 0 < self.target_acceptance < 1:
            bad("target_acceptance", "must lie in (0, 1)")
        for name in ("bias_correction", "edge_coverage", "focus_photons", "caustics_reflective",
                     "caustics_refractive"):
            if not isinstance(getattr(self, name), bool):
                bad(name, "must be True or False")
        if not 1e-4 <= self.initial_mutation_size <= 1e3:
            bad("initial_mutation_size", "must lie in [1e-4, 1e3]")
        if not 0 <= self.glossy_through_roughness <= 1:
            bad("glossy_through_roughness", "must lie in [0, 1]")

    @property
    def bounce_limits(self) -> "BounceLimits":
        """The five bounce limits, the Caustics toggles and the transparent limit (:class:`BounceLimits`)."""
        return BounceLimits(self.max_bounces, self.diffuse_bounces, self.glossy_bounces,
                            self.transmission_bounces, self.volume_bounces, self.caustics_reflective,
                            self.caustics_refractive, self.transparent_max_bounces)

    @property
    def worker_count(self) -> int:
        """Workers actually used: ``workers``, or when it is 0 the CPUs this process may run on
        (its affinity where the system tells it, e.g. under ``taskset`` or a container's CPU set,
        else the machine's count)."""
        return self.workers or usable_cpus()

    def photons_for(self, n_pixels: int) -> int:
        """Photon paths per pass and worker for an image of ``n_pixels`` (rendered) pixels.

        The automatic count grows with the image.  The main process prepares the next eye
        pass and its grid while the workers trace photons, and at 1920x1080 100,000 photons
        per worker are traced long before that preparation ends; more photons per pass then
        cost few passes.  Measured with ``benchmarks/photons_per_pass.py`` (2 workers, 90 s):
        at 1920x1080, 1 million per worker against 100,000 gave 0.23 of the relMSE on the
        Cornell box (PPM) and 0.06 on glass_ceiling_room (AMCMCPPM), and 2 million no more
        than 1 million; at 640x480, 200,000 gave 0.79 and 400,000 no more.  The count does
        not depend on the worker count: every worker's share of a pass takes the same time.
        """
        if self.photons_per_pass:
            return self.photons_per_pass
        return max(AUTO_PHOTONS_MIN, int(math.ceil(AUTO_PHOTONS_PER_PIXEL * n_pixels)))

    def pass_photons(self, n_pixels: int, pass_index: int) -> int:
        """Photon paths per worker in pass ``pass_index`` (0 = the first pass).

        An explicit ``photons_per_pass`` holds in every pass, unless ``first_pass_photons`` starts
        a ramp to it.  The automatic count starts at ``first_pass_photons`` or else
        ``AUTO_PHOTONS_MIN`` and grows ``AUTO_RAMP`` times a pass up to :meth:`photons_for`:
        at 1920x1080, 100,000, 400,000, then 1,036,800 per worker; the first image came after
        4.2 s instead of 14.9 s on the Cornell box (``benchmarks/first_image.py``).  Passes are
        weighted by their recorded photons, so the small first passes add little noise; at
        equal time (90 s) the ramp cost 1.03 (PPM, Cornell) and 1.11 (AMCMCPPM, glass) of the
        relMSE of a fixed full count, and 0.99 on glass at 240 s (``benchmarks/photons_per_pass.py``).
        """
        full = self.photons_for(n_pixels)
        start = self.first_pass_photons or (0 if self.photons_per_pass else AUTO_PHOTONS_MIN)
        if not start:
            return full
        return int(min(full, start * AUTO_RAMP ** min(pass_index, 64)))

    def portal_photons(self, photons: int, n_pixels: int, workers: int, visible: float) -> int:
        """Photon paths per worker in a pass under light portals: the automatic count ``photons``
        (:meth:`pass_photons`) lowered so that, with the share ``visible`` of the last pass's
        uniform photons (or the chains' uniform samples) that reached what the camera sees, the
        ``workers`` trace about AUTO_PORTAL_VISIBLE_PER_PIXEL visible ones per pixel, and at least
        AUTO_PORTAL_MIN.  Portals send the photons from afar into the room the camera sees, where
        they bounce on: a pass of the automatic count then cost 2 to 5 times as long, and the
        passes, not the photons, bounded the error (the sky through the window, whose edges
        converge by camera rays, and the radius, which shrinks by passes).  An explicit
        ``photons_per_pass`` holds."""
        if self.photons_per_pass or not visible > 0:
            return photons
        wanted = math.ceil(AUTO_PORTAL_VISIBLE_PER_PIXEL * n_pixels / (max(workers, 1) * visible))
        return int(min(photons, max(AUTO_PORTAL_MIN, wanted)))

    def replace(self, **changes) -> "RenderSettings":
        return dataclasses.replace(self, **changes)

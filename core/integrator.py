"""The render loop: eye pass, measurement-point grid, photon pass, statistics.

One pass (``algorithm.md`` 1, Knaus & Zwicker 2011):

1. eye pass with new jitter: measurement points and the emission seen directly;
2. radii r_i(x) = r_1(x) s_i with the global shrink s_i^2 = prod_{k<i} (k + alpha)/(k + 1);
3. photon pass (uniform photons, or the Markov chains of :mod:`core.mcmc`) in the
   worker pool, deposits summed per pixel;
4. the pass estimates L_i = Vc S_i / N_i (Vc = 1 for uniform photons) are averaged
   over passes, weighted by their recorded photons N_i (equal weights for passes of
   equal size), and the eye-pass emission is averaged over passes; AMCMCPPM adds the
   deposits of its uniform samples outside the chains' visible set, O_i / n_U,i, averaged
   with weights n_U,i (``core/mcmc.py``, "Two parts");
5. with ``bias_correction`` the same estimate at half the radius, B, is kept too, and the
   image is A + w (B - A) with one weight w for the image (``Accumulator._corrected``).

The eye pass of pass i+1 is traced while the workers trace the photons of pass i.
``method="auto"`` runs the chains' first pass and, when many of its uniform samples were
visible, goes on with uniform photons in a new accumulator (``RenderSettings.method``).
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from .camera import stratified_choices, stratified_jitter, stratified_lens
from .context import RenderContext
from .coverage import point_coverage
from .cryptomatte import KINDS as CRYPTO_KINDS, CryptoSums
from .direct import sample_direct, sampled_emitters, sampled_points, stratified_light
from .eye_pass import EyePassResult, MeasurementPoints, centre_data, trace_eye_pass
from .light_passes import (COLOR_PASSES, LIGHT_PASSES, LIGHTGROUP_PREFIX, PHOTON_PASSES, colour_of,
                           divide_even_color, light_groups, photon_groups)
from .lights import FOCUS_MIN_VISIBLE, Focus
from .parallel import make_pool
from .photon_pass import DepositTarget
from .scene import PANORAMAS
from .settings import AUTO_AIMED_VISIBLE, AUTO_UNIFORM_VISIBLE, FIRST_PASS_DATA, RenderSettings
from .shadow_catcher import (CATCHER_BACKGROUND, CATCHER_HIT, CATCHER_WEIGHT, SHADOW_CATCHER_PASS,
                             catcher_scene, compose)
from .visible_cells import VisibleCells
from .worker import (STREAM_CATCHER, STREAM_CENTRE, STREAM_COVERAGE, STREAM_DIRECT, STREAM_EYE, STREAM_JITTER,
                     PhotonWorker)

# A pass is not started when the time left would trace less than this share of its photons.
MIN_CUT_PASS = 0.05
# Passes whose measurement points add to the chains' visible cells: the first CELL_PASSES, then
# every CELL_EVERY-th (at 1920x1080 the cells of one pass take about a second to add).
CELL_PASSES, CELL_EVERY = 4, 8

PASS_STAT_KEYS = ("pass", "elapsed_s", "paths_traced", "photons_recorded", "proposals", "accepted",
                  "acceptance_rate", "mutation_size", "exchanges", "uniform_samples", "uniform_visible",
                  "visible_fraction", "radius")


@dataclass
class RenderResult:
    """A finished (or interrupted) render."""

    image: np.ndarray                           # (H, W, 4) float32 linear RGBA, top row first (with
    #                                             shadow catchers, Cycles' Combined: core/shadow_catcher.py)
    stats: list = field(default_factory=list)   # one dict per pass
    warnings: list = field(default_factory=list)
    passes: int = 0                             # passes in the image
    elapsed_s: float = 0.0                      # wall time of the render loop
    interrupted: bool = False                   # stopped by ``should_stop``
    effects: tuple = ()                         # the optional effects simulated (RenderContext.effects)
    direct_light: str = ""                      # where the direct light came from: "sampled" (light
    #                                             samples, core/direct.py), "photons", or "photons (why)"
    #                                             where light samples were asked for but the scene rules
    #                                             them out
    method: str = ""                            # "amcmcppm" or "ppm": what made the image's photons
    data: dict = field(default_factory=dict)    # RenderSettings.data_passes: (H, W) or (H, W, 3) float32
    #                                             each, top row first


class Accumulator:
    """Float64 sums over passes, turned into an image on demand.

    The eye-pass emission is averaged over passes.  The photons of all passes are pooled: the
    pass estimates L_p = Vc_p S_p / N_p (S_p the pass's summed contributions, N_p its recorded
    photons) are averaged with weights N_p, and the cumulative visible fraction is the
    N_p-weighted mean of the passes' Vc_p.  Passes of the same size get the same weight, as in
    Knaus and Zwicker's (1/P) sum_p L_p.  A pass with fewer photons counts less: the first
    passes of an automatic count, a pass cut short by the time limit or a stop request, and
    AMCMCPPM passes in which few chains have found a visible path yet (in the first pass of
    a scene seen through glass, a few hundred recorded photons out of 200,000 chain steps).
    """

    def __init__(self, n_pixels, normalisation, bias_correction=False, crypto_levels=6, light_passes=()):
        self.normalisation = normalisation
        self.emission = np.zeros((n_pixels, 3))     # sum of eye-pass emission
        self.alpha = np.zeros(n_pixels)             # sum of coverage
        self.photons = np.zeros((n_pixels, 3))      # sum over passes of S_p
        self.photons_scaled = None                  # sum over passes of Vc_p S_p (the chains' per-pass
        #                                             normalisation; made by their first pass)
        self.recorded = 0                           # sum over passes of N_p
        self.visible_weighted = 0.0                 # sum over passes of N_p Vc_p
        self.passes = 0
        self.n_uniform = 0                          # n_U, all passes
        self.n_visible = 0                          # n_UV, all passes
        self.outside = None                         # sum over passes of O_p (uniform samples outside V;
        #                                             made by the first; None: none yet)
        self.last_pass_mean = 0.0                   # image mean of the last pass's own estimate
        self.data_sums = {}                         # sums over passes of the data passes
        self.crypto = {}                            # Cryptomatte's CryptoSums per kind
        self.crypto_levels = crypto_levels          # their (id, coverage) pairs per pixel
        # Cycles' light passes asked for (core/light_passes.py): the eye passes' parts are data
        # sums (with the colours, also where only a divided pass asks for one); the photons' parts
        # per pass: name -> [sum of S_p, sum of Vc_p S_p, sum of O_p], as the image's (0 where not
        # needed: Vc_p S_p for the chains' per-pass normalisation only, O_p for the chains only).
        # The light group passes (LIGHTGROUP_PREFIX + a name) come in the same way.
        self.light_passes = tuple(light_passes)
        self.light = {}
        # With the bias correction, each light group pass's own differences at half the radius:
        # name -> [sum of T_p, sum of Vc_p T_p, sum of the outside part's T_p] (as the image's), and
        # where the last image's correction made it negative before its clamp at 0 ((n, 3) bool).
        self.group_passes = tuple(n for n in self.light_passes if n.startswith(LIGHTGROUP_PREFIX))
        self.group_diff = {}
        self.clamped = None
        self.photon_factor = None                   # (n, 3) the last image's correction of its photons
        # The estimate at half the radius (RenderSettings.bias_correction): the differences
        # T_p = S_p(r/2) - S_p(r) of the recorded photons and of the outside part, with their
        # spread, the sum of Vc_p T_p (per-pass normalisation) and, for the chains, the sum of
        # X_p, T_p of the even chains minus T_p of the odd ones.
        self.bias_correction = bias_correction
        self.bias_weight = 0.0                      # w of the last image (image = A + w D)
        if bias_correction:
            self.diff = None                        # _Spread of T_p over N_p (made by the first pass)
            self.outside_diff = None                # _Spread of the outside part's T_p over n_U,p
            self.diff_scaled = np.zeros((n_pixels, 3)) if normalisation == "per_pass" else None
            self.halves = None                      # sum of X_p (made by the first chain pass)

    @property
    def visible_fraction(self) -> float:
        """Uniform samples that were visible, over all passes (reported in the statistics)."""
        return self.n_visible / self.n_uniform if self.n_uniform else 0.0

    def add(self, eye, pixel_sum, recorded, n_uniform, n_visible, is_chain, outside_sum=None,
            inner_sum=None, outside_inner=None, half_diff=None, light_sum=None, light_outside=None,
            light_inner=None, light_outside_inner=None):
        """Add one pass; returns the number of pixels whose non-finite photon sums were dropped.

        ``outside_sum``: AMCMCPPM's sums over its uniform samples outside the visible set (O_p).
        ``inner_sum``, ``outside_inner``: the same sums at half the radius (with
        ``bias_correction``; both or neither when there are outside sums).  ``half_diff``: with
        ``bias_correction``, the chains' X_p (one worker's even chains' T_p minus its odd
        chains', ``PhotonWorker.run_pass``, or the workers' difference, ``_halves_difference``).
        Also sets ``last_pass_mean``: the mean over pixels and RGB of this pass's own estimate,
        its emission plus Vc_p S_p / N_p with the pass's own visible fraction Vc_p, plus O_p / n_U.
        ``light_sum``, ``light_outside``: the light passes' S_p and O_p (name -> (n_pixels, 3)), or
        None (their non-finite values are left out as zeros; they take the image's bias correction
        in proportion, :meth:`data`).  ``light_inner``, ``light_outside_inner``: with
        ``bias_correction``, the light group passes' sums at half the radius (as ``inner_sum``,
        ``outside_inner``), or None: the groups' own corrections.
        """
        if self.bias_correction and inner_sum is None:
            raise ValueError("Accumulator.add: a bias-corrected image needs the inner sums")
        if self.bias_correction and is_chain and recorded and half_diff is None:
            raise ValueError("Accumulator.add: a bias-corrected chain image needs the halves' difference")
        self.passes += 1
        self.emission += eye.emission
        self.alpha += eye.alpha
        data = getattr(eye, "data", None)            # (RenderSettings.data_passes)
        if data:
            for name, value in data.items():
                if name in CRYPTO_KINDS:                # (pixels, ids, weights)
                    self.crypto.setdefault(name, CryptoSums()).add(*value)
                    continue
                total = self.data_sums.get(name)
                # (float64 sums, also of the eye's float32 light passes)
                self.data_sums[name] = value.astype(np.float64) if total is None else total + value
        self.n_uniform += n_uniform
        self.n_visible += n_visible
        vc_pass = (n_visible / n_uniform if n_uniform else 0.0) if is_chain else 1.0
        for part, sums, on in ((0, light_sum, recorded), (2, light_outside, n_uniform)):
            for name, value in (sums or {}).items() if on else ():
                value = np.where(np.isfinite(value), value, 0.0)
                total = self.light.setdefault(name, [0.0, 0.0, 0.0])
                total[part] = total[part] + value
                if part == 0 and is_chain and self.normalisation == "per_pass":
                    total[1] = total[1] + vc_pass * value
        for part, inner, sums, on in ((0, light_inner, light_sum, recorded),
                                      (2, light_outside_inner, light_outside, n_uniform)):
            if inner is None or not on:
                continue
            for name in self.group_passes:      # (T_p of each group: its inner sums less its sums)
                if name not in inner and name not in (sums or {}):
                    continue
                t = inner.get(name, 0.0) - (sums or {}).get(name, 0.0)
                t = np.where(np.isfinite(t), t, 0.0)
                total = self.group_diff.setdefault(name, [0.0, 0.0, 0.0])
                total[part] = total[part] + t
                if part == 0 and is_chain and self.normalisation == "per_pass":
                    total[1] = total[1] + vc_pass * t
        self.last_pass_mean = float(eye.emission.mean())
        dropped = 0
        if outside_sum is not None and n_uniform:
            # Non-finite contributions are dropped before they reach the sums (and counted).
            dropped, (outside_sum, outside_inner) = _finite(outside_sum, outside_inner)
            if self.outside is None:
                self.outside = np.array(outside_sum, np.float64)
            else:
                self.outside += outside_sum
            self.last_pass_mean += float(outside_sum.mean()) / n_uniform
        if self.bias_correction and is_chain and n_uniform:
            # (a pass whose uniform samples outside V deposited nothing adds a zero difference)
            if self.outside_diff is None:
                self.outside_diff = _Spread(len(self.alpha))
            self.outside_diff.add(None if outside_sum is None else outside_inner - outside_sum, n_uniform)
        if not recorded:
            return dropped
        bad_pixels, (pixel_sum, inner_sum, half_diff) = _finite(pixel_sum, inner_sum, half_diff)
        dropped += bad_pixels
        self.recorded += recorded
        self.visible_weighted += recorded * vc_pass
        self.photons += pixel_sum
        if is_chain and self.normalisation == "per_pass":
            scaled = vc_pass * pixel_sum
            if self.photons_scaled is None:
                self.photons_scaled = scaled
            else:
                self.photons_scaled += scaled
        self.last_pass_mean += vc_pass * float(pixel_sum.mean()) / recorded
        if self.bias_correction:
            t = inner_sum - pixel_sum
            if self.diff is None:
                self.diff = _Spread(len(t))
            self.diff.add(t, recorded)
            if self.diff_scaled is not None:
                self.diff_scaled += vc_pass * t
            if is_chain:
                if self.halves is None:
                    self.halves = np.zeros_like(t)
                self.halves += half_diff
        return dropped

    def image(self, is_chain):
        if self.passes == 0:
            return np.zeros((len(self.alpha), 4), np.float32)
        rgb = self.emission / self.passes
        scale = 1.0         # of S / N in the image (the cumulative visible fraction for the chains)
        if self.recorded:
            photons = self.photons
            if is_chain:
                scale = self.visible_weighted / self.recorded
                photons = scale * photons if self.normalisation == "cumulative" else self.photons_scaled
            rgb = rgb + photons / self.recorded
        if is_chain and self.n_uniform and self.outside is not None:
            rgb = rgb + self.outside / self.n_uniform
        self.photon_factor = None
        if self.bias_correction:
            plain = rgb
            rgb = self._corrected(rgb, is_chain, scale)
            if self.light and self.bias_weight:
                # The light passes' photons take the correction in proportion (data()).
                base = self.emission / self.passes
                with np.errstate(divide="ignore", invalid="ignore"):
                    factor = (rgb - base) / (plain - base)
                self.photon_factor = np.where(plain - base > 0, np.maximum(factor, 0.0), 1.0)
        out = np.empty((len(rgb), 4), np.float32)
        # Sums beyond float32 (a scene whose albedos above 1 feed on themselves) stay finite.
        out[:, :3] = np.minimum(rgb, FLOAT32_MAX)
        out[:, 3] = self.alpha / self.passes
        return out

    def data(self, height, width, is_chain=False):
        """The data passes (``RenderResult.data``) as (H, W[, 3]) float32 images; the light passes
        are the eye passes' mean plus the photons' estimate as in :meth:`image`, whose bias
        correction (of the last :meth:`image`) they take in proportion to their photons' part of
        each pixel's, so that they still add up to the image; those of a colour are divided by it
        (:func:`~core.light_passes.divide_even_color`)."""
        if not self.passes:
            return {}

        def image(value):
            return np.asarray(value, np.float32).reshape((height, width) + np.shape(value)[1:])

        out = {name: image(value / self.passes) for name, value in self.data_sums.items()
               if name not in LIGHT_PASSES and name not in self.light_passes}
        colours = {name: self.data_sums[name] / self.passes for name in COLOR_PASSES
                   if name in self.data_sums}
        own = self._own_corrections(is_chain)
        for name in self.light_passes:          # (one at a time: 13 of them at 1080p take 0.6 GB)
            if name == CATCHER_HIT:             # (the shadow catchers', _with_catchers)
                continue
            value = (colours[name] if name in colours
                     else self._light_mean(name, is_chain, own if name in self.group_passes else None))
            if colour_of(name):
                value = divide_even_color(value, colours[colour_of(name)])
            out[name] = image(np.minimum(value, FLOAT32_MAX))
        for name, sums in self.crypto.items():
            out[name] = sums.image(height * width, self.crypto_levels, self.passes).reshape(height, width, -1)
        return out

    def _own_corrections(self, is_chain):
        """(n, 3) bool: where the light group passes take their own bias corrections (the image's
        weight times their own differences, so that a group's pass is what its emitters alone would
        give): where the image's was not clamped at 0 and none of theirs is below 0; elsewhere they
        take the image's in proportion, as the light passes do (either way they add up to it).
        None: nowhere (no group passes, no correction, or no group differences)."""
        if not self.group_passes or self.photon_factor is None or not self.group_diff:
            return None
        ok = ~self.clamped
        for name in self.group_passes:
            part = self._photon_part(name, is_chain)
            ok &= part + self.bias_weight * self._group_difference(name, is_chain) >= 0
        return ok

    def _group_difference(self, name, is_chain):
        """(n, 3) light group pass ``name``'s own D (:meth:`difference`'s, of its photons alone)."""
        t, t_scaled, t_outside = self.group_diff.get(name, (0.0, 0.0, 0.0))
        d = np.zeros((len(self.alpha), 3))
        if self.recorded:
            if is_chain and self.normalisation == "per_pass":
                d = d + t_scaled / self.recorded
            else:
                scale = self.visible_weighted / self.recorded if is_chain else 1.0
                d = d + scale * t / self.recorded
        if is_chain and self.outside_diff is not None and self.n_uniform:
            d = d + t_outside / self.n_uniform
        return d

    def _light_mean(self, name, is_chain, own=None, corrected=True):
        """(n, 3) float64 light pass ``name`` before any division by a colour: the eye passes' mean
        plus the photons' estimate as in :meth:`image`, times ``photon_factor``, or, where ``own``
        ((n, 3) bool, :meth:`_own_corrections`), plus the image's weight times its own D (neither
        without ``corrected``)."""
        value = (self.data_sums[name] / self.passes if name in self.data_sums
                 else np.zeros((len(self.alpha), 3)))
        if name not in self.light:
            return value
        photon_part = self._photon_part(name, is_chain)
        if self.photon_factor is not None and corrected:
            shared = photon_part * self.photon_factor
            if own is not None:
                own_part = photon_part + self.bias_weight * self._group_difference(name, is_chain)
                shared = np.where(own, own_part, shared)
            photon_part = shared
        return value + photon_part

    def _photon_part(self, name, is_chain):
        """(n, 3) the photons' estimate of light pass ``name`` as in :meth:`image`, uncorrected."""
        if name not in self.light:
            return np.zeros((len(self.alpha), 3))
        photons, scaled, outside = self.light[name]
        photon_part = 0.0
        if self.recorded:
            if is_chain:
                scale = self.visible_weighted / self.recorded
                photons = scale * photons if self.normalisation == "cumulative" else scaled
            photon_part = photons / self.recorded
        if is_chain and self.n_uniform:
            photon_part = photon_part + outside / self.n_uniform
        return photon_part + np.zeros((len(self.alpha), 3))

    def _corrected(self, rgb, is_chain, scale):
        """The image A + w D, clamped at 0: D = (estimate at r/2) - (estimate at r), w in
        [0, 4/3] minimising the estimated relMSE over the image (RenderSettings.bias_correction).

        Kernel bias grows as r^2, so E[D] = -3b/4 for A's bias b, and b^2 is estimated per pixel
        by (16/9)(D^2 - Var D).  The image's relMSE, summed over pixels weighted by
        1 / (A^2 + 0.01), is sum (1 - 3w/4)^2 b^2 + Var A + w^2 Var D, smallest at
        w = sum(1.5 b^2) / sum(9/8 b^2 + 2 Var D) = (4/3) (1 - V / S), V = sum Var D and
        S = sum D^2 (weighted): Richardson's 4/3 less the share of noise in D^2, 0 when V >= S.
        Cov(A, D) is left out: photons of even density make it 0, as the gather at r/2 is a
        quarter of the one at r (Cov(A, B) = Var A).
        Var D comes from the spread of the passes' differences (:class:`_Spread`) for uniform
        photons and the chains' outside part.  The chains keep their states from pass to pass,
        so for their recorded photons that spread is too small where few fresh states come in
        (on glass_ceiling_room w came out 1.2 where 0.8 was best, V a third of the spread of D
        over seeds); their Var T is also X^2, X = sum_p X_p of two independent halves of the
        chains (two workers' chains, or one worker's even and odd chains), as
        E[X^2] = Var T_even + Var T_odd = Var T when the halves are alike.  That is one degree
        of freedom per pixel, but w depends on Var D only through V.  The halves share the eye
        passes, so X misses the noise of the measurement points' jitter, which the spread of
        the passes holds (on the Cornell box at 64x48 X gave two thirds of V, the passes all of
        it): V is the larger of the two (``benchmarks/bias_variance_check.py``)."""
        self.bias_weight = 0.0
        self.clamped = None
        diff = self.difference(is_chain, scale)
        if diff is None:
            return rgb
        d, variances = diff
        with np.errstate(over="ignore", invalid="ignore"):
            weight = 1.0 / (rgb * rgb + 0.01)
            sums = [float(np.sum(weight * v)) for v in variances] + [float(np.sum(weight * d * d))]
        if not np.isfinite(sums).all():
            return rgb
        noise, square = max(sums[:-1]), sums[-1]
        if noise >= square:
            return rgb
        self.bias_weight = 4.0 / 3.0 * (1.0 - noise / square)
        corrected = rgb + self.bias_weight * d
        self.clamped = corrected < 0
        return np.maximum(corrected, 0.0)

    def difference(self, is_chain, scale=1.0):
        """(D, estimates of Var D) per pixel for :meth:`_corrected`, or None before
        BIAS_MIN_PASSES passes with photons: D (n_pixels, 3) and a tuple of (n_pixels, 3)
        estimates, each too small in its own way (the image uses the largest weighted sum): the
        spread of the passes, and for the chains also their halves.  ``scale``: the chains'
        cumulative visible fraction."""
        n = self.recorded
        if not self.bias_correction or self.diff is None or not n or self.diff.passes < BIAS_MIN_PASSES:
            return None
        variances = [self.diff.variance(n)]
        if is_chain and self.halves is not None:
            with np.errstate(over="ignore"):
                variances.append(self.halves * self.halves / (n * n))
        variances = [scale * scale * v for v in variances]
        if self.diff_scaled is not None and is_chain:
            d = self.diff_scaled / n
        else:
            d = scale * self.diff.total / n
        if is_chain and self.outside_diff is not None and self.n_uniform:
            var_o = self.outside_diff.variance(self.n_uniform)
            if var_o is None:
                return None
            d = d + self.outside_diff.total / self.n_uniform
            variances = [v + var_o for v in variances]
        return d, tuple(variances)


@dataclass
class _CatcherPass:
    """A pass :meth:`CatcherRender.add_pass` prepared (and traced unless deferred) for
    :meth:`CatcherRender.finish_pass`: ``runs`` (accumulator, workers, their outputs: None where no
    camera ray met a catcher, ``DEFERRED`` to trace), K's eye pass and target (None: no tracing
    again), and the seconds and K photons its traces took so far."""

    index: int
    eye: object
    target: object
    runs: list
    n_photons: int
    should_stop: object
    seconds: float = 0.0
    photons: int = 0


DEFERRED = "deferred"


class CatcherRender:
    """K of Cycles' shadow catcher (``core/shadow_catcher.py``): the catcher objects' own light,
    rendered in a scene of them and the emitters alone, at the main render's points on catchers
    met first (with its radii and edge coverage), by uniform photons in this process.  Its photons
    are the main render's uniform ones, each worker's numbers (``workers`` of them) and count: the
    same emitters in the same box (the main scene's, where the sun's and the world's photons start)
    send them the same way, so that where nothing came between, both renders gather the same
    photons and their ratio is 1 without noise.  The Markov chains' photons are another sample:
    with them (``pair``) the same uniform photons are traced in the main scene too, to the same
    points, for the shadow's numerator (:meth:`hit`)."""

    def __init__(self, scene, ctx, settings, n_pixels, workers, pair=False):
        keep = ctx.catcher | ctx.table.is_emissive.take(scene.material_ids)
        self.scene = catcher_scene(scene, keep).validate()
        self.ctx = RenderContext(self.scene, settings.glossy_through_roughness, bounds=ctx.accel.bounds)
        self.settings = dataclasses.replace(settings, method="ppm", data_passes=(), bias_correction=False)
        self.workers = [PhotonWorker(self.scene, self.settings, index=i, ctx=self.ctx)
                        for i in range(workers)]
        self.pair = ([PhotonWorker(scene, self.settings, index=i, ctx=ctx) for i in range(workers)]
                     if pair else [])
        self.n_pixels = n_pixels
        self._pending = None            # (the _CatcherPass of add_pass, for finish_pass)
        self.reset()

    def add_pass(self, pass_index, eye, target, scale, n_photons, should_stop=None, defer=False):
        """Trace pass ``pass_index`` of the main render's eye pass ``eye`` and target ``target`` (its radii's
        shrink ``scale``), or with ``defer`` (a render under a time limit) only prepare it:
        :meth:`finish_pass` traces it after the main pass, with as many photons as the main render's workers
        traced (the main pass is then cut only once, and K traced once). Its points on a catcher met first,
        with no mirror or glass before them, are K's as they are (the same positions and radii: where nothing
        came between, both renders gather the very same photons; a point traced again from just before the
        catcher lay a rounding apart, and a photon at the edge of its disc made a pixel of a floor with
        nothing on it 2.35 instead of 1), with the light their paths saw there; the other camera rays that met
        a catcher first (:class:`~core.shadow_catcher.CatcherRays`: paths that went on through a mirror or
        glass catcher) are traced in the catchers' scene from just before it, their points without edge
        coverage. (Both scenes have the same materials, so their points have the same optional fields.) The
        pass is added by :meth:`finish_pass`."""
        s = self.settings
        main = target.points
        direct = main.caught if main.bounces is None else main.caught & (main.bounces[:, 0] == 0)
        rows = np.flatnonzero(direct)
        points = dataclasses.replace(main.take(rows), caught=None, via=None)
        coverage = None if target.coverage is None else target.coverage.take(rows)
        emission = np.zeros((self.n_pixels, 3))
        emission[points.pixel_ids] = eye.data[CATCHER_HIT][points.pixel_ids]
        vol = None
        rest = eye.catcher
        if rest.count:
            rng = np.random.default_rng([s.seed, STREAM_CATCHER, pass_index])
            traced = trace_eye_pass(self.ctx, rng, s.initial_radius_px, s.max_bounces, (), s.bounce_limits,
                                    s.pass_alpha_threshold, rays=rest)
            if traced.points.count:
                if coverage is not None:
                    coverage = np.concatenate([coverage, np.ones(traced.points.count)])
                points = MeasurementPoints.concatenate([points, traced.points])
            emission += traced.emission
            vol = traced.volume
        k_eye = EyePassResult(points, emission, np.ones(self.n_pixels), 0, vol)
        runs = [(acc, w) for acc, w in ((self.acc, self.workers), (self.hit_acc, self.pair)) if w]
        if not points.count and (vol is None or not vol.count):
            # (no camera ray met a catcher: a pass whose photons found nothing)
            self._pending = _CatcherPass(pass_index, k_eye, None, [(acc, w, None) for acc, w in runs],
                                         n_photons, should_stop)
            return
        vol_radius = vol.base_radius * scale ** (2.0 / 3.0) if vol is not None and vol.count else None
        target = DepositTarget(points, points.base_radius * scale, self.ctx.table, self.n_pixels,
                               self.ctx.has_shading_normals, volume=vol, volume_radius=vol_radius,
                               media=self.ctx.phase, limits=s.bounce_limits, coverage=coverage)
        if defer:
            self._pending = _CatcherPass(pass_index, k_eye, target, [(acc, w, DEFERRED) for acc, w in runs],
                                         n_photons, should_stop)
            return
        t0 = time.perf_counter()
        traced = [(acc, w, [x.run_pass(pass_index, target, n_photons, should_stop, uniform=True) for x in w])
                  for acc, w in runs]
        # (the target kept only where finish_pass may trace the pass again: not with the pair)
        self._pending = _CatcherPass(pass_index, k_eye, None if self.pair else target, traced, n_photons,
                                     should_stop, time.perf_counter() - t0, _recorded(traced[0][2]))

    def finish_pass(self, outputs=None):
        """Add the pass :meth:`add_pass` traced, or trace it first (deferred).  ``outputs``: the main
        render's workers' results of that pass when its photons were uniform (PPM): where a worker
        traced fewer than the pass's (cut by the time limit), K is traced (again) with as many, the
        same ones (else, at a pixel whose camera rays met a catcher only in that pass, the two sums
        of a sample in common would differ by the rest: a shadow of 0 where nothing shadowed); with
        the chains K and its pair trace the whole pass, each as many.  Returns the pass's statistics:
        ``catcher_photons`` (K's photons traced, again ones included) and ``catcher_s`` (the seconds
        K's and the pair's traces took), 0 without a pass."""
        p, self._pending = self._pending, None
        if p is None:
            return {"catcher_photons": 0, "catcher_s": 0.0}
        counts = None
        if outputs is not None and not self.pair and len(outputs) == len(self.workers):
            counts = [int(o["counters"]["recorded"]) for o in outputs]
        cut = counts is not None and p.target is not None and any(c != p.n_photons for c in counts)
        t0 = time.perf_counter()
        for k, (acc, workers, outs) in enumerate(p.runs):
            deferred = outs is DEFERRED
            if deferred or cut:
                # (a deferred pass after a stop request is cut too: the stop comes first)
                each = counts if counts is not None else [p.n_photons] * len(workers)
                outs = [w.run_pass(p.index, p.target, c, p.should_stop if deferred else None, uniform=True)
                        for w, c in zip(workers, each)]
                if k == 0:
                    p.photons += _recorded(outs)
            if outs is None:
                n = p.n_photons * len(workers) if counts is None else sum(counts)
                acc.add(p.eye, np.zeros((self.n_pixels, 3)), n, n, 0, False)
                continue
            out = _merge(outs)
            c = out["counters"]
            acc.add(p.eye, out["pixel_sum"], c["recorded"], c["uniform_samples"], c["uniform_visible"], False)
        return {"catcher_photons": p.photons, "catcher_s": p.seconds + time.perf_counter() - t0}

    def radiance(self):
        """(n_pixels, 3) float32 K so far."""
        return self.acc.image(False)[:, :3]

    def hit(self):
        """(n_pixels, 3) float32 C - M of the ``pair``'s photons so far, or None without them (the
        eye passes' emission is the catchers' scene's: what the main scene shows in a catcher that
        is a mirror is left out)."""
        return self.hit_acc.image(False)[:, :3] if self.pair else None

    def reset(self, pair=True):
        """Start over (after ``method="auto"``'s switch, with the main render's, without the pair:
        ``pair`` False)."""
        if not pair:
            self.pair = []
        self.acc = Accumulator(self.n_pixels, self.settings.normalisation)
        self.hit_acc = Accumulator(self.n_pixels, self.settings.normalisation) if self.pair else None


def _aiming_loses(sums):
    """Whether photons under a focus, with sums (sum of w, sum of w^2, count) over those that count,
    show a larger second moment aimed, mean(w^2), than unaimed, mean(w), once FOCUS_MIN_VISIBLE
    of them have been seen."""
    return sums[2] >= FOCUS_MIN_VISIBLE and sums[1] > sums[0]


def _recorded(outputs):
    """The photons the workers' ``outputs`` of a pass traced in all."""
    return sum(int(o["counters"]["recorded"]) for o in outputs)


def _with_catchers(acc, image, data, is_chain, catcher, wanted, film_transparent):
    """(image, data) with shadow catchers (``catcher`` a :class:`CatcherRender`, or None: as they
    are): Cycles' Combined and, if ``wanted``, its Shadow Catcher pass
    (:func:`~core.shadow_catcher.compose`); the catchers' sums out of the data.  Without catchers
    the pass is 1 (as Cycles writes it then)."""
    if not acc.passes:
        return image, data
    if catcher is None:
        if wanted:
            data[SHADOW_CATCHER_PASS] = np.ones(image.shape[:2] + (3,), np.float32)
        return image, data
    h, w = image.shape[:2]
    n = h * w
    weight, background = (data.pop(name, None) for name in (CATCHER_WEIGHT, CATCHER_BACKGROUND))
    hit = catcher.hit() if is_chain else None
    image, shadow = compose(image.reshape(n, 4), acc._light_mean(CATCHER_HIT, is_chain),
                            acc._light_mean(CATCHER_HIT, is_chain, corrected=False) if hit is None else hit,
                            catcher.radiance(),
                            np.zeros(n) if weight is None else weight.reshape(n),
                            np.zeros((n, 3)) if background is None else background.reshape(n, 3),
                            wanted, film_transparent)
    if wanted:
        data[SHADOW_CATCHER_PASS] = shadow.reshape(h, w, 3)
    return image.reshape(h, w, 4), data


class _Spread:
    """Sum over passes of per-pixel differences T_p (n_pixels, 3), each from N_p samples, and
    their spread about the mean, for the variance of the sum.

    A pass of N_p samples has Var T_p = sigma^2 N_p, estimated over the p passes by
    (sum T_p^2 / N_p - (sum T_p)^2 / sum N_p) / (p - 1).  The passes are taken as independent.
    The Markov chains carry their states from pass to pass, so for them this underestimates the
    variance where few fresh states come in; for their recorded photons the image also
    estimates it from two halves of the chains and takes the larger (``Accumulator._corrected``)."""

    def __init__(self, n_pixels):
        self.total = np.zeros((n_pixels, 3))        # sum of T_p
        self.n = 0                                  # sum of N_p
        self.passes = 0
        self._moment = np.zeros((n_pixels, 3))      # sum of T_p^2 / N_p

    def add(self, t, n):
        """A pass's differences ``t`` (None: all zero) from ``n`` samples."""
        if t is not None:
            self.total += t
            self._moment += t * t / n
        self.n += n
        self.passes += 1

    def variance(self, n):
        """(n_pixels, 3) estimated variance of ``total / n``, or None before BIAS_MIN_PASSES."""
        if self.passes < BIAS_MIN_PASSES:
            return None
        with np.errstate(over="ignore", invalid="ignore"):
            sigma2 = (self._moment - self.total * self.total / self.n) / (self.passes - 1)
        return np.maximum(sigma2, 0.0) * (self.n / (n * n))


FLOAT32_MAX = float(np.finfo(np.float32).max)
# Passes with photons before the bias correction starts (it needs their spread).
BIAS_MIN_PASSES = 4


def _finite(*sums):
    """(the number of pixels with a non-finite entry in any of ``sums``, the sums with those
    entries set to 0 in every one): sums of one pass of shape (n_pixels, 3), or None."""
    bad = None
    for s in sums:
        if s is not None:
            bad = ~np.isfinite(s) if bad is None else bad | ~np.isfinite(s)
    dropped = int(bad.any(axis=1).sum())
    if dropped:
        sums = tuple(None if s is None else np.where(bad, 0.0, s) for s in sums)
    return dropped, sums


def kz_radius_scales(n, alpha):
    """s_i for passes i = 1..n: s_1 = 1, s_{i+1}^2 = s_i^2 (i + alpha) / (i + 1)."""
    i = np.arange(1, n)
    return np.sqrt(np.concatenate([[1.0], np.cumprod((i + alpha) / (i + 1.0))]))


def render(scene, settings=None, on_iteration=None, should_stop=None, context=None,
           stop_first_pass=False) -> RenderResult:
    """Render ``scene`` progressively.

    on_iteration : called after every pass with the :class:`RenderResult` so far.
    should_stop : polled between passes and photon batches (and between the steps of preparing
        a pass); when it returns True the render ends promptly with the passes finished so far,
        at least the first (with the photons it traced by then).
    context : a :class:`RenderContext` of ``scene`` to use rather than build one (e.g. an earlier
        render's ``with_camera``: the 3D viewport's moved views, ``core/live.py``).
    stop_first_pass : ``should_stop`` may also end the render before its first pass's photons,
        which then returns a black image and no pass (the 3D viewport's server, which has shown a
        preview of the job: ``core/live.py``).
    """
    settings = settings or RenderSettings()
    scene = scene.validate()
    t0 = time.perf_counter()
    stop = should_stop or (lambda: False)
    if context is None:
        ctx = RenderContext(scene, settings.glossy_through_roughness)
    elif context.source is not scene or context.glossy_through_roughness != settings.glossy_through_roughness:
        raise ValueError("render: the context was built for another scene or glossy_through_roughness")
    else:
        ctx = context
    x0, x1, y0, y1 = scene.camera.window
    width, height = x1 - x0, y1 - y0
    n_pixels = width * height
    is_chain = settings.method != "ppm"
    light_passes = tuple(name for name in settings.data_passes if name in LIGHT_PASSES)
    # Light groups (Scene.light_groups): their passes, made as the photon light passes are.
    groups = light_groups(settings.data_passes, scene.light_groups)
    light_passes += groups[0]
    photons_of_groups = photon_groups(ctx.lights.group, ctx.lights.prob, groups[1])
    # Shadow catchers (core/shadow_catcher.py): the light of the paths that met one first is a light
    # pass of the Accumulator's; the catchers' own light a second render's.
    catcher = None
    if ctx.catcher is not None:
        light_passes += (CATCHER_HIT,)
        catcher = CatcherRender(scene, ctx, settings, n_pixels, settings.worker_count, pair=is_chain)
    catcher_wanted = SHADOW_CATCHER_PASS in settings.data_passes

    def images():
        """(image, data) of the passes so far (the data passes of the pixels' centres too)."""
        return _with_catchers(acc, acc.image(is_chain).reshape(height, width, 4),
                              {**centre_images(), **acc.data(height, width, is_chain)}, is_chain, catcher,
                              catcher_wanted, scene.world.film_transparent)
    acc = Accumulator(n_pixels, settings.normalisation, settings.bias_correction, settings.cryptomatte_levels,
                      light_passes)
    result = RenderResult(image=np.zeros((height, width, 4), np.float32), effects=ctx.effects,
                          method="amcmcppm" if is_chain else "ppm")
    warnings = result.warnings
    if ctx.lights.count == 0:
        warnings.append("the scene emits no light (no light with power, emissive material or world); "
                        "the image shows only what the camera sees of emitters")
    if scene.triangle_count == 0:
        warnings.append("the scene has no geometry")
    # Direct light from light samples (core/direct.py): the emitters sampled, or None.
    direct = None
    result.direct_light = "photons"
    if settings.direct_light == "sampled":
        direct, why = sampled_emitters(ctx, settings.bounce_limits)
        result.direct_light = "sampled" if direct is not None else f"photons ({why})"
    max_passes = settings.passes or np.iinfo(np.int64).max
    deadline = t0 + settings.time_limit if settings.time_limit else None
    scales = kz_radius_scales(1, settings.alpha)

    # The data passes Cycles takes from its first sample (through the pixels' centres), once;
    # the eye passes make the others.
    first = [name for name in settings.data_passes if name in FIRST_PASS_DATA]
    centre = (centre_data(ctx, np.random.default_rng([settings.seed, STREAM_CENTRE]), first,
                          settings.pass_alpha_threshold) if first else {})
    averaged = tuple(name for name in settings.data_passes
                     if name not in FIRST_PASS_DATA and name != SHADOW_CATCHER_PASS)

    def centre_images():
        return {name: value.astype(np.float32).reshape((height, width) + value.shape[1:])
                for name, value in centre.items()}

    salt = int(np.random.SeedSequence([settings.seed, STREAM_JITTER]).generate_state(1, np.uint64)[0])
    # With depth of field the lens samples are stratified over the passes too (camera.stratified_lens).
    lens_salt = None
    if scene.camera.aperture_radius > 0 and scene.camera.projection not in PANORAMAS:
        lens_seed = np.random.SeedSequence([settings.seed, STREAM_JITTER, 1])
        lens_salt = int(lens_seed.generate_state(1, np.uint64)[0])

    choice_seed = np.random.SeedSequence([settings.seed, STREAM_JITTER, 2])
    choice_salt = int(choice_seed.generate_state(1, np.uint64)[0])
    light_seed = np.random.SeedSequence([settings.seed, STREAM_JITTER, 3])
    light_salt = int(light_seed.generate_state(1, np.uint64)[0])

    def camera_numbers(i, pix):
        """Pass i's stratified pixel jitter (n, 2), with the lens samples (n, 4) under depth of field."""
        u = stratified_jitter(salt, i, pix)
        return u if lens_salt is None else np.concatenate([u, stratified_lens(lens_salt, i, pix)], axis=1)

    def eye_pass(i, stop=None):
        """Pass ``i``'s eye pass, or None where ``stop`` (polled between its chunks) asks first."""
        rng = np.random.default_rng([settings.seed, STREAM_EYE, i])
        stratified = settings.pixel_jitter == "stratified"
        return trace_eye_pass(ctx, rng, settings.initial_radius_px, settings.max_bounces,
                              averaged, settings.bounce_limits, settings.pass_alpha_threshold,
                              settings.ao_distance, jitter=partial(camera_numbers, i) if stratified else None,
                              choices=partial(stratified_choices, choice_salt, i) if stratified else None,
                              should_stop=stop)

    # The Markov chains' visible set also holds the cells around the measurement points of the
    # first passes and of every CELL_EVERY-th pass after them (``core/visible_cells.py``): it
    # barely changes between passes.
    cells = VisibleCells() if is_chain else None
    # Where the photons from afar are aimed (core.lights.Focus), from the first pass's points: the
    # uniform photons', and the chains' uniform samples, whose target and runs then take the weights
    # (core/mcmc.py, "Photons from afar").  The passes' own photons tell whether it pays (aim_sums
    # and, for the chains, outside_sums, below).
    focus = None
    aim_sums = np.zeros(3)
    outside_sums = np.zeros(3)

    def make_target(i, eye, stop=None):
        """Pass ``i``'s deposit target of ``eye``'s points, or None where ``stop`` (polled before
        and after the edge coverage and before the light samples) asks to stop first."""
        nonlocal scales, cells, focus
        if len(scales) < i + 1:
            scales = kz_radius_scales(2 * (i + 1), settings.alpha)
        pts, vol = eye.points, eye.volume
        radius = pts.base_radius * scales[i]
        # Points in volumes gather in spheres: radii that shrink as the cube root of the same
        # sequence (r^3 by (i + alpha) / (i + 1), Knaus and Zwicker's rule in three dimensions).
        vol_radius = vol.base_radius * scales[i] ** (2.0 / 3.0) if vol is not None and vol.count else None
        if cells is not None and (i < CELL_PASSES or i % CELL_EVERY == 0):
            cells = cells.extended(pts.position, pts.ng, pts.base_radius, generation=i)
            if vol_radius is not None:
                cells = cells.extended(vol.position, None, vol.base_radius, volume=True, generation=i)
        if i == 0 and settings.focus_photons:
            around, reach = [pts.position], [radius]
            if vol_radius is not None:
                around.append(vol.position)
                reach.append(vol_radius)
            # (portals in the windows, where the scene has them, else a sphere around the points)
            focus = (Focus.through(scene.world, ctx.lights)
                     or Focus.around(np.concatenate(around), np.concatenate(reach), ctx.lights))
        if stop is not None and stop():
            return None
        coverage = inner_coverage = None
        if settings.edge_coverage and pts.count:
            rng = np.random.default_rng([settings.seed, STREAM_COVERAGE, i])
            # (reach: the disc's radius in pixel footprints this pass, and how far the pixel filter
            # sends a point from its pixel's centre, plus half a pixel: 1 with a box of one pixel)
            reach = settings.initial_radius_px * scales[i] + scene.camera.filter_reach + 0.5
            coverage, inner_coverage = point_coverage(ctx, pts, radius, width, height, reach, rng,
                                                      inner=settings.bias_correction)
            if stop is not None and stop():
                return None
        target = DepositTarget(pts, radius, ctx.table, n_pixels, ctx.has_shading_normals, cells=cells,
                               volume=vol, volume_radius=vol_radius, media=ctx.phase,
                               inner=settings.bias_correction, coverage=coverage,
                               inner_coverage=inner_coverage, limits=settings.bounce_limits,
                               light_passes=tuple(n for n in light_passes if n in PHOTON_PASSES),
                               light_groups=groups + photons_of_groups if groups[0] else None, direct=direct,
                               direct_points=None if direct is None else sampled_points(ctx.table, pts),
                               focus=focus)
        if direct is not None:
            if stop is not None and stop():
                return None
            # The points' light samples join the emission the camera sees (averaged over passes).
            rng = np.random.default_rng([settings.seed, STREAM_DIRECT, i])
            t_direct = time.perf_counter()
            passes = group_sums = None
            if light_passes:
                # (their parts of the light passes and light groups join the eye pass's)
                data = eye.data
                passes = {}
                for name in ("diffuse_direct", "glossy_direct", "glossy_indirect", "transmission_indirect"):
                    if name in light_passes:
                        passes[name] = data.setdefault(name, np.zeros((n_pixels, 3)))
                if groups[0]:
                    group_sums = ([data[name] for name in groups[0]], groups[1])
            numbers = (partial(stratified_light, light_salt, i, settings.direct_samples)
                       if settings.pixel_jitter == "stratified" else None)
            eye.emission += sample_direct(ctx, target, direct, rng, settings.direct_samples, passes,
                                          group_sums, numbers)
            sampling = pts.count if target.direct_points is None else int(target.direct_points.sum())
            target.light_samples = sampling * settings.direct_samples
            target.light_sample_s = time.perf_counter() - t_direct
        return target

    def prepare(i, stop=stop):
        """Pass ``i``'s eye pass and deposit target, or None where ``stop`` (None: never) asks to stop
        first (polled between their steps and the eye pass's chunks: the 3D viewport's next job
        waits for this one to stop)."""
        eye = eye_pass(i, stop)
        target = None if eye is None or (stop is not None and stop()) else make_target(i, eye, stop)
        return None if target is None else (eye, target)

    # The worker processes start (scene, acceleration structure) while this one traces the
    # first eye pass.
    pool = make_pool(scene, settings, ctx)
    warned_invisible = False
    try:
        pass_index = 0
        prepared = prepare(0, stop if stop_first_pass else None)
        if prepared is None:
            result.interrupted = True
            return result
        eye, target = prepared
        last_rate = None                # photons per second per worker of the last whole pass
        portal_visible = None           # under light portals: the last pass's visible share
        catcher_share = 0.0             # the catchers' render's time over the main photons' (last pass)
        while pass_index < max_passes:
            if stop() and (pass_index > 0 or stop_first_pass):
                result.interrupted = True
                break
            photons = settings.pass_photons(n_pixels, pass_index)
            if portal_visible:
                photons = settings.portal_photons(photons, n_pixels, settings.worker_count, portal_visible)
            # The first pass runs whole; later ones get the time left before the limit.
            budget = needed = None
            if deadline is not None and pass_index > 0:
                # (the catchers' render traces after the main photons, as many: their share of the
                # time left is the last pass's)
                budget = (deadline - time.perf_counter()) / (1.0 + catcher_share)
                needed = photons / last_rate if last_rate else None
                # No pass that the limit would cut to a sliver (its eye pass is spent already).
                if budget <= 0 or (needed is not None and budget < MIN_CUT_PASS * needed):
                    break
            pool.submit(pass_index, target, photons, budget, uniform=not is_chain)
            if catcher is not None and eye.catcher is not None:
                # (before the next pass is prepared: the two passes' points are not held at once;
                # under a time limit traced by finish_pass, after the main pass)
                catcher.add_pass(pass_index, eye, target, scales[pass_index], photons, stop,
                                 defer=deadline is not None)
            # Prepare the next pass while the workers trace photons, unless it is the last, or
            # the time limit will cut this one, or this is the first pass (whose image is
            # shown as soon as it is done; the next pass is prepared after it).
            last = pass_index + 1 >= max_passes
            cut_expected = needed is not None and needed > budget
            next_target = None
            prep_s = 0.0
            stopped = False             # (a stop request while the next pass was prepared)
            if not last and pass_index > 0 and not cut_expected:
                t_next = time.perf_counter()
                prepared = prepare(pass_index + 1)
                stopped = prepared is None
                if prepared is not None:
                    next_eye, next_target = prepared
                prep_s = time.perf_counter() - t_next
            outputs = pool.collect(stop)
            if outputs is None:         # stopped before any worker returned photons
                result.interrupted = True
                break
            merged = _merge(outputs, halves=is_chain and settings.bias_correction)
            catcher_stats = {}
            if catcher is not None:
                catcher_stats = catcher.finish_pass(None if is_chain or stop() else outputs)
                if merged["photon_s"] > 0:
                    catcher_share = catcher_stats["catcher_s"] / merged["photon_s"]
            c = merged["counters"]
            if focus is not None and target.focus is not None:
                # Does the focus pay?  Its photons' visibility V with the weights w estimates the
                # second moment of the paths from afar with it, mean(w^2 V), and without it,
                # mean(w V) (importance sampling's identity, the same photons): the focus goes
                # (from the next pass not yet made) where the first is larger, as when the light
                # comes through a window outside the sphere (then only the uniform half brings it).
                # For the chains the same two moments are the variances of their normaliser's
                # estimate, mean(w V), with and without it.
                aim_sums += (c["aimed_w"], c["aimed_w2"], c["aimed_visible"])
                # The chains' uniform samples outside their visible set deposit as plain photons
                # (core/mcmc.py, "Two parts"), and the same identity over those that deposit tells
                # whether aiming pays for that part of the image: it goes where it does not (light
                # that reaches what the camera sees only through a glass ball from off the disc).
                outside_sums += (c["outside_w"], c["outside_w2"], c["uniform_outside"])
                if _aiming_loses(aim_sums) or (is_chain and _aiming_loses(outside_sums)):
                    focus = None
            # (the automatic photon count under portals goes by it: RenderSettings.portal_photons)
            portal_visible = (c["uniform_visible"] / c["uniform_samples"] if focus is not None
                              and focus.portal_count and c["uniform_samples"] else None)
            # A stop request or the time limit mid-pass returns the photons traced so far.
            cut = any(o["interrupted"] for o in outputs)
            interrupted = stopped or stop()
            if not cut and merged["photon_s"] > 0:
                last_rate = photons / merged["photon_s"]
            # (the chains' normaliser: sum(w V) / n_U, their recordings weighted by their runs' W,
            # core/mcmc.py "Photons from afar")
            visible, recorded = ((c["uniform_visible_w"], c["recorded_w"]) if is_chain
                                 else (c["uniform_visible"], c["recorded"]))
            dropped = acc.add(eye, merged["pixel_sum"], recorded, c["uniform_samples"], visible,
                              is_chain, merged["outside_sum"], merged["inner_sum"], merged["outside_inner"],
                              merged["half_diff"], merged["light_sum"], merged["light_outside"],
                              merged["light_inner"], merged["light_outside_inner"])
            if dropped:
                warnings.append(f"pass {pass_index + 1}: dropped non-finite photon contributions "
                                f"in {dropped} pixels")
            if (c["uniform_samples"] and c["uniform_visible"] == 0 and c["uniform_outside"] == 0
                    and (not is_chain or c["recorded"] == 0) and not warned_invisible and ctx.lights.count):
                warned_invisible = True
                sampled = "" if direct is None else " past their first vertex"
                warnings.append(
                    f"pass {pass_index + 1}: none of {c['uniform_samples']} uniform photon paths reached "
                    f"a surface seen by the camera{sampled}; the image shows only emission "
                    f"{'and the light samples ' if direct is not None else ''}so far and the "
                    "search goes on in the next passes")
            elapsed = time.perf_counter() - t0
            result.image, result.data = images()
            stats = _pass_stats(pass_index, elapsed, merged, acc, eye, target, prep_s, pool.size, settings,
                                photons, cut and not interrupted, is_chain) | catcher_stats
            result.stats.append(stats)
            result.passes = acc.passes
            result.elapsed_s = elapsed
            result.method = "amcmcppm" if is_chain else "ppm"
            if on_iteration is not None:
                on_iteration(result)
            pass_index += 1
            if interrupted:
                result.interrupted = True
                break
            if deadline is not None and time.perf_counter() >= deadline:
                break
            if last:
                break
            # (the unaimed share: aimed, the chains' visible uniform samples estimate it by sum(w V);
            # where the aim holds, PPM goes on aimed and its share is the aimed samples')
            if (settings.method == "auto" and pass_index == 1 and c["uniform_samples"]
                    and (visible >= AUTO_UNIFORM_VISIBLE * c["uniform_samples"]
                         or (focus is not None and target.focus is not None
                             and c["uniform_visible"] >= AUTO_AIMED_VISIBLE * c["uniform_samples"]))):
                # Many uniform paths are visible: uniform photons from here on, and an image of
                # their passes alone (RenderSettings.method).  The next pass is not prepared yet
                # (none is while the first runs), so it is made without the chains' cells.
                is_chain, cells, last_rate = False, None, None
                acc = Accumulator(n_pixels, settings.normalisation, settings.bias_correction,
                                  settings.cryptomatte_levels, light_passes)
                if catcher is not None:
                    catcher.reset(pair=False)
            if next_target is None:
                prepared = prepare(pass_index)
                if prepared is None:
                    result.interrupted = True
                    break
                next_eye, next_target = prepared
            eye, target = next_eye, next_target
    finally:
        pool.close()
    result.elapsed_s = time.perf_counter() - t0
    if acc.passes:      # (after the switch of "auto", the first image stands until a pass lands)
        result.image, result.data = images()
    return result


def _pass_stats(pass_index, elapsed, merged, acc, eye, target, prep_s, workers, settings, photons, cut,
                is_chain):
    """The statistics of one pass (``PASS_STAT_KEYS`` first, then diagnostics)."""
    c = merged["counters"]
    return {
        "pass": pass_index + 1,
        "elapsed_s": elapsed,
        "paths_traced": c["paths_traced"],
        "photons_recorded": c["recorded"],
        "proposals": c["proposals"],
        "accepted": c["accepted"],
        "acceptance_rate": c["accepted"] / c["proposals"] if c["proposals"] else 0.0,
        "mutation_size": merged["theta_mean"] if is_chain else 0.0,
        "exchanges": c["exchanges"],
        "uniform_samples": c["uniform_samples"],
        "uniform_visible": c["uniform_visible"],
        "uniform_outside": c["uniform_outside"],
        "visible_fraction": acc.visible_fraction,
        "radius": float(np.median(target.radius)) if len(target.radius) else 0.0,
        "method": "amcmcppm" if is_chain else "ppm",
        "visible_fraction_pass": c["uniform_visible"] / c["uniform_samples"] if c["uniform_samples"] else 0.0,
        "cumulative_acceptance_rate": (merged["total_accepted"] / merged["total_proposed"]
                                       if merged["total_proposed"] else 0.0),
        "chains_with_state": merged["valid_chains"],
        "older_share": c["recorded_older"] / c["recorded"] if c["recorded"] else 0.0,
        "uniform_newer": c["uniform_newer"],
        "initialised": c["initialised"],
        "rays": c["rays"] + eye.rays,
        "photon_vertices": c["vertices"],
        "measurement_points": eye.points.count,
        "light_samples": target.light_samples,
        "light_sample_s": target.light_sample_s,
        "volume_points": 0 if eye.volume is None else eye.volume.count,
        "grid_entries": target.grid.entry_count,
        "focus_radius": target.focus.radius if target.focus is not None else 0.0,
        "focus_portals": target.focus.portal_count if target.focus is not None else 0,
        "aiming_workers": c["aiming_workers"],
        "photon_s": merged["photon_s"],
        "bookkeeping_share": 1.0 - c["trace_s"] / merged["photon_cpu_s"] if merged["photon_cpu_s"] > 0 else 0.0,
        "prepare_next_s": prep_s,
        "workers": workers,
        "photons_per_pass": photons,
        "cut_at_time_limit": cut,
        "pass_mean": acc.last_pass_mean,
        "bias_weight": acc.bias_weight,
    }


def _merge(outputs, halves=False):
    """Sum the workers' results of one pass; with ``halves`` (chains, bias correction) and two
    or more workers, ``half_diff`` is :func:`_halves_difference`."""
    merged = {"counters": dict(outputs[0]["counters"])}
    for key in ("pixel_sum", "outside_sum", "inner_sum", "outside_inner", "half_diff"):
        sums = [o[key] for o in outputs if o.get(key) is not None]
        merged[key] = np.sum(sums, axis=0) if sums else None
    for key in ("light_sum", "light_outside", "light_inner", "light_outside_inner"):   # (name -> pixel sums)
        parts = [o[key] for o in outputs if o.get(key) is not None]
        names = sorted({name for p in parts for name in p})
        merged[key] = ({name: np.sum([p[name] for p in parts if name in p], axis=0) for name in names}
                       if parts else None)
    if halves and len(outputs) > 1 and merged["inner_sum"] is not None:
        merged["half_diff"] = _halves_difference(outputs)
    for o in outputs[1:]:
        for k, v in o["counters"].items():
            merged["counters"][k] += v
    valid = [o["valid_chains"] for o in outputs]
    merged["valid_chains"] = sum(valid)
    merged["theta_mean"] = float(np.mean([o["theta_mean"] for o in outputs]))
    merged["total_proposed"] = sum(o["total_proposed"] for o in outputs)
    merged["total_accepted"] = sum(o["total_accepted"] for o in outputs)
    merged["photon_s"] = max(o["photon_s"] for o in outputs)
    merged["photon_cpu_s"] = sum(o["photon_s"] for o in outputs)
    return merged


def _halves_difference(outputs):
    """The chains' X_p (``Accumulator``) of a pass traced by two or more workers, whose chains
    are independent: the sum over pairs of workers (0 and 1, 2 and 3, ...) of
    sqrt(N_b / N_a) T_a - sqrt(N_a / N_b) T_b, T = inner - outer pixel sums and N the recorded
    photons (weighted by their runs' W under a Focus, ``recorded_w``).  With Var T_k = N_k sigma^2
    a pair has mean 0 and variance (N_a + N_b) sigma^2, also when a pass cut short leaves the
    workers unequal; X is scaled by sqrt(N / N_paired) for the workers left out (an odd count, or a
    pair with a worker that recorded nothing), so that E[X^2] = Var T.  No extra sums are traced
    for it."""
    x = np.zeros_like(outputs[0]["pixel_sum"])
    recorded = [o["counters"]["recorded_w"] for o in outputs]
    paired = 0
    # (non-finite sums give non-finite entries, dropped by Accumulator.add with the others)
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(0, len(outputs) - 1, 2):
            (a, b), (n_a, n_b) = outputs[i:i + 2], recorded[i:i + 2]
            if n_a and n_b:
                x += np.sqrt(n_b / n_a) * (a["inner_sum"] - a["pixel_sum"])
                x -= np.sqrt(n_a / n_b) * (b["inner_sum"] - b["pixel_sum"])
                paired += n_a + n_b
        if paired:
            x *= np.sqrt(sum(recorded) / paired)
    return x

"""Photon work of one process: uniform photons (PPM) or Markov chains (AMCMCPPM).

A :class:`PhotonWorker` owns its scene context, random streams and (for
AMCMCPPM) its chains, which persist across passes.  The integrator runs one in
its own process (``workers=1``) or several in worker processes
(:mod:`core.parallel`), each tracing an independent share of every pass against
the same measurement points; their per-pixel sums are merged per pass.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from .context import RenderContext
from .mcmc import ChainCounters, ChainSet, DepositLog, begin_pass, end_pass, iterate
from .photon_pass import PointSums, aim_moments, path_dims, trace_photons

# Uniform photon paths traced per batch (bounds the memory of the deposit pairs).
PPM_BATCH = 1 << 14

# Stream identifiers for numpy SeedSequence entropy: (seed, stream, ...).
(STREAM_EYE, STREAM_PHOTONS, STREAM_CHAINS, STREAM_COVERAGE, STREAM_CENTRE, STREAM_CATCHER,
 STREAM_DIRECT, STREAM_JITTER) = 0, 1, 2, 3, 4, 5, 6, 7


class PhotonWorker:
    """Traces the photons of one worker's share of every pass.

    ``lane_halves``: a worker that is the only one splits its chains into halves for the
    bias correction's variance (``half_diff`` of :meth:`run_pass`); with two or more workers
    the workers are the halves (``core.integrator._halves_difference``)."""

    def __init__(self, scene, settings, index=0, ctx=None, lane_halves=False):
        self.ctx = ctx if ctx is not None else RenderContext(scene, settings.glossy_through_roughness)
        self.settings = settings
        self.index = index
        self.lane_halves = lane_halves
        self.dims = path_dims(settings.max_bounces)
        self.chains = None
        self.chain_focus = None         # the Focus of the chains' last pass (its key)
        if settings.method != "ppm":
            n_chains = settings.chains
            self.chain_rng = np.random.default_rng([settings.seed, STREAM_CHAINS, index])
            self.chains = ChainSet.create(n_chains, self.dims, settings.initial_mutation_size,
                                          self.chain_rng)

    def run_pass(self, pass_index, target, n_photons, should_stop=None, uniform=False) -> dict:
        """Trace this worker's photons of pass ``pass_index``; return sums and counters.

        target : the pass's DepositTarget (measurement points and their grid); uniform : trace
        uniform photons even if this worker has chains (``method="auto"`` after its switch).
        The result holds ``pixel_sum`` (n_pixels, 3): the summed contributions of the
        recorded photons (not yet divided by their number or scaled by the visible
        fraction), ``outside_sum`` (AMCMCPPM: the summed contributions of the uniform samples
        outside the chains' visible set, to be divided by n_U; else None), ``inner_sum`` and
        ``outside_inner`` (the same at half the radius if the target has inner sums, else
        None), ``half_diff`` (with ``lane_halves``, AMCMCPPM and inner sums: the even chains'
        (inner - outer) pixel sums minus the odd chains'; else None), ``light_sum`` and
        ``light_outside`` (the target's light and light group passes: name -> pixel sums as
        ``pixel_sum`` and ``outside_sum``, :meth:`~core.photon_pass.DepositTarget.pass_pixels`; else
        None), ``light_inner`` and ``light_outside_inner`` (with inner sums, the light group passes'
        as ``inner_sum`` and ``outside_inner``,
        :meth:`~core.photon_pass.DepositTarget.group_inner_pixels`; else None), ``counters`` (a
        :class:`ChainCounters` as a dict) and chain figures.
        """
        stop = should_stop or (lambda: False)
        t0 = time.perf_counter()
        counters = ChainCounters()
        outside_sum = outside_inner = half_diff = light_outside = light_outside_inner = None
        group_inner = target.inner and bool(target.group_passes)
        chains = None if uniform else self.chains
        if chains is None:
            sums, interrupted = self._uniform_pass(pass_index, target, n_photons, counters, stop)
            theta_mean, valid = 0.0, 0
        else:
            sums, outside, halves, interrupted = self._chain_pass(target, n_photons, counters, stop)
            if outside is not None:
                outside_sum, outside_inner = _pixels(target, outside)
                if target.makes_passes:
                    light_outside = target.pass_pixels(outside)
                if group_inner:
                    light_outside_inner = target.group_inner_pixels(outside)
            if halves is not None:
                outer, inner = _pixels(target, halves)
                with np.errstate(over="ignore", invalid="ignore"):     # (dropped by the Accumulator)
                    half_diff = inner - outer
            adapted = chains.proposed > 0
            theta_mean = float(chains.theta[adapted].mean()) if adapted.any() else float(chains.theta.mean())
            valid = int(chains.valid.sum())
        pixel_sum, inner_sum = _pixels(target, sums)
        return {"pixel_sum": pixel_sum, "outside_sum": outside_sum, "inner_sum": inner_sum,
                "outside_inner": outside_inner, "half_diff": half_diff,
                "light_sum": target.pass_pixels(sums) if target.makes_passes else None,
                "light_outside": light_outside,
                "light_inner": target.group_inner_pixels(sums) if group_inner else None,
                "light_outside_inner": light_outside_inner,
                "counters": dataclasses.asdict(counters),
                "theta_mean": theta_mean, "valid_chains": valid,
                "total_proposed": int(chains.proposed.sum()) if chains else 0,
                "total_accepted": int(chains.accepted.sum()) if chains else 0,
                "interrupted": interrupted, "photon_s": time.perf_counter() - t0}

    def _uniform_pass(self, pass_index, target, n_photons, counters, stop):
        s = self.settings
        rng = np.random.default_rng([s.seed, STREAM_PHOTONS, pass_index, self.index])
        sums = PointSums(target.n_slots)
        done = 0
        interrupted = False
        while done < n_photons:
            if stop():
                interrupted = True
                break
            b = min(PPM_BATCH, n_photons - done)
            t0 = time.perf_counter()
            batch = trace_photons(self.ctx, target, rng.random((b, self.dims)), s.max_bounces, sums=sums)
            counters.trace_s += time.perf_counter() - t0
            visible = int(batch.visible.sum())
            sw, sw2, k = aim_moments(batch, slice(None))
            counters.add(ChainCounters(iterations=b, paths_traced=b, recorded=b, uniform_samples=b,
                                       uniform_visible=visible, rays=batch.rays, vertices=batch.vertices,
                                       aimed_w=sw, aimed_w2=sw2, aimed_visible=k))
            done += b
        sums.flush()
        return sums.total, interrupted

    def _chain_pass(self, target, n_photons, counters, stop):
        s = self.settings
        chains = self.chains
        halves = target.inner and self.lane_halves
        recorder = DepositLog(target.n_slots, chains.count, halves=halves, main_slots=target.inner_slots)
        focus = tuple(target.focus.to_array()) if target.focus is not None else None
        if focus != self.chain_focus:
            # The focus maps samples to other paths: the states would no longer follow the target.
            chains.forget()
            self.chain_focus = focus

        def trace(u, refresh_rng, resume=None, limit=None, floor=None):
            t0 = time.perf_counter()
            batch = trace_photons(self.ctx, target, u, s.max_bounces, refresh_rng=refresh_rng,
                                  collect_pairs=True, resume=resume, unweighted=True, cell_limit=limit,
                                  cell_floor=floor)
            counters.trace_s += time.perf_counter() - t0
            return batch

        # The chains' runs keep the generation of the cells they began in (core/mcmc.py, "Generations").
        generation = target.cells.generation if target.cells is not None else 0
        recorder.lane_gen, recorder.shares = chains.gen, chains.generation_shares
        chains.raise_floor()              # the last pass's recordings are splatted
        begin_pass(chains, trace, recorder, counters)
        iterations = -(-n_photons // chains.count)
        interrupted = False
        prefetched = None
        for i in range(iterations):
            if stop():
                interrupted = True
                break
            prefetched = iterate(chains, trace, recorder, self.chain_rng, s, counters,
                                 prefetched=prefetched, prefetch=i + 1 < iterations, generation=generation)
        end_pass(chains, recorder, prefetched, trace, counters)
        recorder.flush()
        if focus is not None:
            counters.aiming_workers += 1
        outside = recorder.outside_sums if recorder.outside_pairs else None
        if recorder.newer_pairs and counters.recorded_w > 0:
            # Shares of this iteration's recordings, per recording of the pass and iteration: the
            # integrator divides by n_U = C T (mcmc.py, "Generations").
            newer = recorder.newer_sums * (counters.iterations / chains.count / counters.recorded_w)
            outside = newer if outside is None else outside + newer
        halves = recorder.half_sums if halves else None
        return recorder.sums, outside, halves, interrupted


def _pixels(target, sums):
    """(pixel sums, pixel sums at half the radius or None) of per-slot sums."""
    inner = target.inner_pixels(sums) if target.inner else None
    return target.to_pixels(sums), inner

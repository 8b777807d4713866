"""Markov chain machinery against synthetic visibility oracles of known measure (testing.md 2d).

No ray tracing: an oracle V(u) on [0, 1)^d stands in for "the photon path of u
reaches a measurement point".  Each oracle also reports the dimension offset of
the first visible "vertex" (for low-dimension mutation) and a label per sample,
which a recorder turns into occupancy counts.
"""
from types import SimpleNamespace

import numpy as np
import pytest

from core.mcmc import (THETA_MAX, THETA_MIN, ChainCounters, ChainSet, DepositLog, Recorder, adapt_theta,
                       begin_pass, end_pass, iterate, mutate, wrap_unit)
from core.settings import RenderSettings

DIMS = 8


class BoxOracle:
    """V(u) = 1 inside axis-aligned boxes over the first two dimensions; label = box index.

    ``second`` optionally adds boxes over dimensions 2-3, reached "at the second vertex"
    (first visible dimension 4 instead of 2), so the first-visible index varies.
    """

    def __init__(self, boxes, second=(), gens=None):
        self.boxes = [(np.asarray(lo), np.asarray(hi)) for lo, hi in boxes]
        self.second = [(np.asarray(lo), np.asarray(hi)) for lo, hi in second]
        self.calls = 0
        # The generation of each of ``boxes`` (not ``second``), as visible cells' (None: no
        # generations, ``entry`` None as for a target without cells).
        self.gens = None if gens is None else np.asarray(gens, np.int64)

    def measure(self):
        return sum(np.prod(hi - lo) for lo, hi in self.boxes)

    def __call__(self, u, refresh_rng, resume=None, limit=None, floor=None):
        # The prefix of a resumed state (the last k rows, as in ``trace_photons``) is
        # unchanged, so the oracle's answer from ``u`` is the same; such a path is visible
        # from the start, so the low-dimension refresh leaves it alone.  With generations a box
        # counts for a path whose ``limit`` is at least the box's generation; ``entry`` is the
        # oldest generation of the boxes that hold the path.
        self.calls += 1
        n = len(u)
        resumed = np.zeros(n, bool)
        if resume is not None:
            resumed[n - len(resume["label"]):] = True
        label = np.full(n, -1)
        first = np.full(n, -1, np.int32)
        entry = np.full(n, np.iinfo(np.int64).max)
        for k, (lo, hi) in enumerate(self.boxes):
            inside = ((u[:, :2] >= lo) & (u[:, :2] < hi)).all(axis=1)
            if self.gens is not None:
                entry[inside] = np.minimum(entry[inside], self.gens[k])
                if limit is not None:
                    inside &= self.gens[k] <= limit
            inside &= label < 0
            label[inside] = k
            first[inside] = 2
        if refresh_rng is not None:
            new = (label >= 0) & ~resumed
            u[new, 2:] = refresh_rng.random((int(new.sum()), u.shape[1] - 2))
        for k, (lo, hi) in enumerate(self.second):
            inside = ((u[:, 2:4] >= lo) & (u[:, 2:4] < hi)).all(axis=1) & (label < 0)
            label[inside] = len(self.boxes) + k
            first[inside] = 4
            new = inside & ~resumed
            if refresh_rng is not None and new.any():
                u[new, 4:] = refresh_rng.random((int(new.sum()), u.shape[1] - 4))
        assert (label[resumed] >= 0).all(), "a resumed state was not visible"
        entry[resumed] = -1
        return SimpleNamespace(visible=label >= 0, first_dim=first, rays=n, vertices=n, label=label,
                               u5=u[:, 5].copy(), first={"label": label.copy()}, aims=self.aims(u, resumed),
                               entry=None if self.gens is None else entry)

    def aims(self, u, resumed):
        """The paths' weights w under a Focus (``PhotonBatch.aims``): None, no focus."""
        return None


class AimedOracle(BoxOracle):
    """As if the samples' first dimension aimed photons from afar: w = 1/4 below 1/2, 2 above (a
    focus on the left half), 0 for resumed rows (``trace_photons``)."""

    def aims(self, u, resumed):
        return np.where(resumed, 0.0, np.where(u[:, 0] < 0.5, 0.25, 2.0))


class OccupancyRecorder(Recorder):
    """Counts recordings per label (a prefix property), per chain, and sums of u[5] (a suffix
    property) over recorded states."""

    def __init__(self, n_chains, n_labels):
        self.label = np.full(n_chains, -1)
        self.u5 = np.zeros(n_chains)
        self.counts = np.zeros(n_labels)
        self.per_chain = np.zeros((n_chains, n_labels))
        self.u5_sum = 0.0

    def replace(self, lanes, batch, rows):
        self.label[lanes] = batch.label[rows]
        self.u5[lanes] = batch.u5[rows]

    def replace_suffix(self, lanes, batch, rows):
        assert (self.label[lanes] == batch.label[rows]).all(), "a suffix refresh changed the prefix"
        self.u5[lanes] = batch.u5[rows]

    def commit(self, lanes, prefix_counts, suffix_counts):
        ok = self.label[lanes] >= 0
        lanes, prefix_counts, suffix_counts = lanes[ok], prefix_counts[ok], suffix_counts[ok]
        np.add.at(self.counts, self.label[lanes], prefix_counts)
        np.add.at(self.per_chain, (lanes, self.label[lanes]), prefix_counts)
        self.u5_sum += float((self.u5[lanes] * suffix_counts).sum())


def run_chains(oracle, n_chains, iterations, n_labels, seed=0, exchange=True, prefetch=True, **settings):
    """Iterations as the worker runs them: with ``prefetch`` the uniform samples of the next
    iteration are traced in one batch with the proposals."""
    s = RenderSettings(**settings)
    rng = np.random.default_rng(seed)
    chains = ChainSet.create(n_chains, DIMS, s.initial_mutation_size, rng)
    rec = OccupancyRecorder(n_chains, n_labels)
    counters = ChainCounters()
    begin_pass(chains, oracle, rec, counters)
    prefetched = None
    for i in range(iterations):
        prefetched = iterate(chains, oracle, rec, rng, s, counters, exchange=exchange,
                             prefetched=prefetched, prefetch=prefetch and i + 1 < iterations)
    assert prefetched is None
    end_pass(chains, rec)
    # The recorder's view of every current state is the chain's (no refresh left untraced).
    np.testing.assert_array_equal(rec.u5[chains.valid], chains.u[chains.valid, 5])
    return chains, rec, counters


def test_a_pass_cut_short_traces_its_pending_gibbs_refreshes():
    # With prefetch, the suffixes redrawn in an iteration are traced with the next one's batch;
    # a pass that stops after such an iteration must trace them before recording them.
    oracle = varying_first_vertex()
    s = RenderSettings(mutation="exact", target_acceptance=0.6)
    rng = np.random.default_rng(5)
    chains = ChainSet.create(64, DIMS, s.initial_mutation_size, rng)
    rec = OccupancyRecorder(64, 2)
    counters = ChainCounters()
    begin_pass(chains, oracle, rec, counters)
    prefetched = None
    for _ in range(20):
        prefetched = iterate(chains, oracle, rec, rng, s, counters, prefetched=prefetched, prefetch=True)
    assert prefetched.refreshed is not None and len(prefetched.refreshed[0])
    lanes = prefetched.refreshed[0]
    assert (rec.u5[lanes] != chains.u[lanes, 5]).all()       # not yet traced
    paths = counters.paths_traced
    end_pass(chains, rec, prefetched, oracle, counters)
    assert counters.paths_traced == paths + len(lanes)
    np.testing.assert_array_equal(rec.u5[chains.valid], chains.u[chains.valid, 5])
    assert rec.counts.sum() == counters.recorded


def test_normaliser_within_four_binomial_sigma():
    oracle = BoxOracle([((0.0, 0.0), (0.7, 0.5))])        # measure 0.35
    chains, rec, c = run_chains(oracle, 64, 2000, 1)
    p = oracle.measure()
    v_hat = c.uniform_visible / c.uniform_samples
    sigma = np.sqrt(p * (1 - p) / c.uniform_samples)
    assert c.uniform_samples == 64 * 2000
    assert abs(v_hat - p) < 4 * sigma


class DepositingOracle(BoxOracle):
    """Every path "deposits" (one pair each), inside V or not; the batch keeps its samples."""

    def __call__(self, u, refresh_rng, resume=None, limit=None, floor=None):
        batch = super().__call__(u, refresh_rng, resume, limit, floor)
        batch.pair_path = np.arange(len(u))
        batch.u = u.copy()
        return batch


class OutsideRecorder(OccupancyRecorder):
    def __init__(self, n_chains, n_labels):
        super().__init__(n_chains, n_labels)
        self.outside = []

    def uniform(self, batch, rows):
        self.outside.append(batch.u[rows])
        return rows


@pytest.mark.parametrize("prefetch", [False, True])
def test_uniform_samples_outside_the_visible_set_reach_the_recorder_once_each(prefetch):
    """The chains count the paths in V; the uniform samples outside V count directly (module
    docstring, "Two parts"): every one of them, once, and none inside V."""
    box = ((0.0, 0.0), (0.7, 0.5))
    oracle = DepositingOracle([box])
    s = RenderSettings()
    rng = np.random.default_rng(3)
    chains = ChainSet.create(32, DIMS, s.initial_mutation_size, rng)
    rec, counters = OutsideRecorder(32, 1), ChainCounters()
    prefetched = None
    for i in range(50):
        prefetched = iterate(chains, oracle, rec, rng, s, counters, prefetched=prefetched,
                             prefetch=prefetch and i + 1 < 50)
    end_pass(chains, rec)
    outside = np.concatenate(rec.outside)
    assert len(outside) == counters.uniform_outside == counters.uniform_samples - counters.uniform_visible
    inside = ((outside[:, :2] >= box[0]) & (outside[:, :2] < box[1])).all(axis=1)
    assert not inside.any()
    assert len(np.unique(outside, axis=0)) == len(outside)
    p = 1 - oracle.measure()
    assert abs(len(outside) / counters.uniform_samples - p) < 4 * np.sqrt(p * (1 - p) / counters.uniform_samples)


def test_every_iteration_records_one_path_per_chain_with_a_state():
    oracle = BoxOracle([((0.0, 0.0), (0.3, 0.3))])
    chains, rec, c = run_chains(oracle, 16, 300, 1)
    # Once initialised, each chain records exactly once per iteration (including rejections).
    assert rec.counts.sum() == c.recorded
    assert c.recorded > 0.9 * 16 * 300
    # A chain with a state after an iteration was initialised, exchanged or proposed in it.
    assert c.recorded == c.initialised + c.exchanges + c.proposals


@pytest.mark.parametrize("start", [pytest.param(1e-3, marks=pytest.mark.slow), 0.5])
# The paper's 23.4 % (the baseline the seed paper improves on) in the slow tier: make test's budget.
@pytest.mark.parametrize("target", [pytest.param(0.234, marks=pytest.mark.slow), 0.60])
def test_acceptance_settles_on_target_from_small_and_large_steps(target, start):
    """One mutation size for 32 chains, adapted on their pooled acceptance, settles where that
    acceptance is the target: over the last 3,000 of 30,000 iterations the pooled acceptance is
    within 0.02 of it (measured 0.595-0.608 and 0.232-0.245 over two seeds), each chain's within
    0.06 (3,000 proposals each: 0.009 of spread).  (Two chains over 100,000 iterations took 18 s.)"""
    # Visible set of measure 0.01: far below both targets at large steps.
    oracle = BoxOracle([((0.2, 0.3), (0.3, 0.4))])
    s = RenderSettings(target_acceptance=target, mutation="off")
    rng = np.random.default_rng(1)
    n_chains, iterations = 32, 30_000
    chains = ChainSet.create(n_chains, DIMS, start, rng)
    # Start in the visible set, exchanges off: every iteration is a mutation proposal.
    chains.u[:, :2] = (0.25, 0.35)
    chains.valid[:] = True
    chains.first_dim[:] = 2
    rec = OccupancyRecorder(n_chains, 1)
    rec.label[:] = 0
    counters = ChainCounters()
    for i in range(iterations):
        if i == iterations - 3_000:
            accepted_before = chains.accepted.copy()
        iterate(chains, oracle, rec, rng, s, counters, exchange=False)
    assert (chains.proposed == iterations).all()
    recent = (chains.accepted - accepted_before) / 3_000
    assert abs(recent.mean() - target) < 0.02, recent.mean()
    assert np.all(np.abs(recent - target) < 0.06), recent
    assert np.isfinite(chains.theta).all()
    assert ((THETA_MIN <= chains.theta) & (chains.theta <= THETA_MAX)).all()


def test_one_mutation_size_for_all_chains_driven_by_their_pooled_acceptance():
    """Chains started in a wide box (most proposals accepted) and in a thin sliver (most
    rejected) share one size, and it settles where the pooled acceptance is the target.
    Sizes adapted per chain would differ from chain to chain (a chain's size would follow
    where it has been, which moved the chains' states off the uniform distribution in
    renders: see the module docstring of ``core/mcmc.py``)."""
    oracle = BoxOracle([((0.0, 0.0), (0.5, 0.5)), ((0.6, 0.6), (0.9, 0.603))])
    s = RenderSettings(target_acceptance=0.6, mutation="off")
    rng = np.random.default_rng(4)
    chains = ChainSet.create(64, DIMS, 1.0, rng)
    chains.u[:32, :2] = (0.25, 0.25)               # half in the box, half in the sliver
    chains.u[32:, :2] = (0.75, 0.6015)
    chains.valid[:] = True
    chains.first_dim[:] = 2
    rec = OccupancyRecorder(64, 2)
    rec.label[:32], rec.label[32:] = 0, 1
    counters = ChainCounters()
    for i in range(3000):
        if i == 2000:
            before = counters.accepted, counters.proposals
        iterate(chains, oracle, rec, rng, s, counters, exchange=False)
    assert np.ptp(chains.theta) == 0.0, chains.theta
    pooled = (counters.accepted - before[0]) / (counters.proposals - before[1])
    assert abs(pooled - 0.6) < 0.03, pooled


def test_first_adaptation_has_no_zero_division():
    theta = adapt_theta(np.array([1.0]), np.array([0]), np.array([0]), 0.6)
    assert np.isfinite(theta).all()
    # All-visible oracle: every iteration is an exchange, no proposal, theta untouched.
    oracle = BoxOracle([((0.0, 0.0), (1.0, 1.0))])
    chains, rec, c = run_chains(oracle, 8, 20, 1)
    assert c.proposals == 0
    assert (chains.theta == 1.0).all() and (chains.proposed == 0).all()


def test_nothing_visible_terminates_with_no_recording():
    oracle = BoxOracle([((0.0, 0.0), (0.0, 0.0))])         # empty set
    chains, rec, c = run_chains(oracle, 32, 200, 1)
    assert c.recorded == 0 and c.uniform_visible == 0 and c.proposals == 0
    assert c.uniform_samples == 32 * 200
    assert not chains.valid.any()


def two_islands():
    # Measures 0.2 and 0.02: stationary occupancy 10/11 and 1/11.
    return BoxOracle([((0.0, 0.0), (0.5, 0.4)), ((0.7, 0.6), (0.8, 0.8))])


def test_replica_exchange_gives_the_right_occupancy_of_two_islands():
    oracle = two_islands()
    s = dict(target_acceptance=0.6, mutation="off")
    n_batches, per_batch = 20, 150
    occupancy = []
    rng_seed = 2
    chains = None
    for b in range(n_batches):
        # Continue the same chains batch after batch (batch means).
        if chains is None:
            settings = RenderSettings(**s)
            rng = np.random.default_rng(rng_seed)
            chains = ChainSet.create(64, DIMS, 1.0, rng)
            counters = ChainCounters()
        rec = OccupancyRecorder(64, 2)
        begin_pass(chains, oracle, rec, counters)
        for _ in range(per_batch):
            iterate(chains, oracle, rec, rng, settings, counters)
        end_pass(chains, rec)
        occupancy.append(rec.counts[1] / rec.counts.sum())
    occupancy = np.array(occupancy[2:])          # drop the first batches (burn-in)
    se = occupancy.std(ddof=1) / np.sqrt(len(occupancy))
    assert abs(occupancy.mean() - 1 / 11) < 3 * se + 1e-3, (occupancy.mean(), se)


@pytest.mark.parametrize("mode", ["off", "exact"])
def test_aimed_samples_leave_the_chains_on_visibility_times_weight(mode):
    """Under a Focus the samples u come from q = p / w and the chains target V w in u (core/mcmc.py,
    "Photons from afar"): of a box of measure 0.9 across the weights' edge, the half at w 2 holds
    8/9 of that (1/2 unweighted), and sum(w V) / n_U estimates its integral 1.0125, the normaliser.
    A chain takes every visible sample and starts a run of weight W = w there, which its mutations
    keep: the recordings weighted by W hold 8/9 on that half, and their mean W is the mean w of the
    visible samples, 1.125 (a W that followed the state would give 1.81; mutations that ignored w
    leave 0.85 on that half).  Batch means over passes of the same chains, after burn-in."""
    oracle = AimedOracle([((0.0, 0.0), (0.5, 0.9)), ((0.5, 0.0), (1.0, 0.9))])
    settings = RenderSettings(target_acceptance=0.6, mutation=mode)
    rng = np.random.default_rng(4)
    chains = ChainSet.create(64, DIMS, 1.0, rng)
    counters = ChainCounters()
    occupancy = []
    for b in range(24):
        rec = OccupancyRecorder(64, 2)
        begin_pass(chains, oracle, rec, counters)
        prefetched = None
        for i in range(150):
            prefetched = iterate(chains, oracle, rec, rng, settings, counters, prefetched=prefetched,
                                 prefetch=i + 1 < 150)
        end_pass(chains, rec)
        occupancy.append(rec.counts[1] / rec.counts.sum())
    occupancy = np.array(occupancy[2:])
    se = occupancy.std(ddof=1) / np.sqrt(len(occupancy))
    assert abs(occupancy.mean() - 8 / 9) < 3 * se + 2e-3, (occupancy.mean(), se)
    n = counters.uniform_samples
    vc = counters.uniform_visible_w / n
    sigma = np.sqrt((0.45 * 0.25 ** 2 + 0.45 * 2.0 ** 2 - 1.0125 ** 2) / n)
    assert abs(vc - 1.0125) < 4 * sigma, (vc, sigma)
    assert counters.aimed_visible == counters.uniform_visible
    assert counters.aimed_w == pytest.approx(counters.uniform_visible_w)
    assert counters.recorded_w / counters.recorded == pytest.approx(1.125, rel=0.03)


def mixing_flagged(per_chain_counts, expected):
    """Flag chains that do not mix: per-chain occupancy far from the pooled expectation."""
    occ = per_chain_counts[:, 1] / per_chain_counts.sum(axis=1)
    return bool(np.max(np.abs(occ - expected)) > 0.25)


def test_stuck_chains_are_flagged_without_exchange():
    oracle = two_islands()
    # Exchange on: every chain visits both islands in proportion.
    _, rec_on, _ = run_chains(oracle, 32, 3000, 2, seed=3, target_acceptance=0.6, mutation="off")
    assert not mixing_flagged(rec_on.per_chain, 1 / 11)
    # Negative control: no exchange and tiny steps, so every chain stays on its first island.
    _, rec_off, c_off = run_chains(oracle, 32, 3000, 2, seed=3, exchange=False, target_acceptance=0.99,
                                   initial_mutation_size=1e-4, mutation="off")
    assert c_off.exchanges == 0
    assert mixing_flagged(rec_off.per_chain, 1 / 11)


def varying_first_vertex():
    # Visible either "at vertex 1" (dims 0-1, measure 0.1) or, failing that, "at vertex 2"
    # (dims 2-3, measure 0.3): the first visible dimension differs between the two sets.
    return BoxOracle([((0.0, 0.0), (0.2, 0.5))], second=[((0.0, 0.0), (0.6, 0.5))])


def first_set_occupancy(mode, seeds=4, prefetch=True):
    """Occupancy of the set visible at the first vertex, mean and standard error over seeds."""
    occ = []
    for seed in range(seeds):
        _, rec, _ = run_chains(varying_first_vertex(), 256, 1500, 2, seed=10 + seed, mutation=mode,
                               target_acceptance=0.6, prefetch=prefetch)
        occ.append(rec.counts[0] / rec.counts.sum())
        assert abs(rec.u5_sum / rec.counts.sum() - 0.5) < 0.02     # u5 is uniform given V
    return np.mean(occ), np.std(occ, ddof=1) / np.sqrt(seeds)


# P(first set | visible) = 0.1 / (0.1 + 0.9 * 0.3).
FIRST_SET = 0.1 / (0.1 + 0.9 * 0.3)


@pytest.mark.parametrize("mode", ["off", "exact"])
@pytest.mark.parametrize("prefetch", [True, False])
def test_full_and_exact_low_dimension_mutation_keep_the_stationary_distribution(mode, prefetch):
    mean, se = first_set_occupancy(mode, prefetch=prefetch)
    assert abs(mean - FIRST_SET) < 4 * se + 2e-4, (mean, se)


def test_paper_low_dimension_mutation_is_measurably_biased_when_the_first_visible_vertex_varies():
    # algorithm.md 3: the paper's proposal breaks detailed balance when the first visible index of
    # the current state and of the proposal differ; on this oracle it over-weights the first set
    # by about 1 %.  This documents the caveat; renders compare the modes in benchmarks/.
    # Eight seeds: the bias (about 0.003) is then about six standard errors.
    mean, se = first_set_occupancy("paper", seeds=8)
    assert mean - FIRST_SET > 4 * se, (mean, se)
    assert abs(mean - FIRST_SET) / FIRST_SET < 0.05


def test_exact_mode_gibbs_refresh_keeps_visibility_and_first_vertex():
    oracle = varying_first_vertex()
    chains, rec, c = run_chains(oracle, 64, 200, 2, seed=5, mutation="exact")
    assert chains.valid.all()
    check = oracle(chains.u.copy(), None)
    assert check.visible.all()
    np.testing.assert_array_equal(check.first_dim, chains.first_dim)


def test_wrap_unit_never_returns_one():
    for dtype in (np.float32, np.float64):
        x = np.array([-1e-9, -1e-20, 1 - 1e-12, 1.0, -1.0, 2.5, -0.0], dtype)
        y = wrap_unit(x)
        assert ((y >= 0) & (y < 1)).all(), (dtype, y)


def test_mutation_stays_in_unit_cube_and_is_identity_in_the_limit():
    rng = np.random.default_rng(6)
    u = rng.random((1000, DIMS))
    for theta in (THETA_MIN, 1.0, THETA_MAX):
        v = mutate(u, np.full(1000, theta), rng)
        assert ((v >= 0) & (v < 1)).all()
    tiny = mutate(u, np.full(1000, THETA_MIN), rng)
    d = np.abs((tiny - u + 0.5) % 1.0 - 0.5)
    assert np.median(d) < 1e-6


def test_deposit_log_sums_every_recording_once_whatever_the_flush_size():
    from core.mcmc import DepositLog
    n_points, n_chains = 50, 8
    results = []
    for flush_pairs in (1 << 30, 7, 1):
        rng = np.random.default_rng(11)
        log = DepositLog(n_points, n_chains, flush_pairs=flush_pairs, halves=True)
        expected = np.zeros((n_points, 3))
        halves = np.zeros((n_points, 3))         # even lanes' sums minus odd lanes'
        prefix, suffix = {}, {}            # lane -> (points, values) of its current parts

        def add(part, lane, c):
            if lane in part:
                p, v = part[lane]
                np.add.at(expected, p, v * c)
                sign = 1 if lane % 2 == 0 else -1
                np.add.at(halves, p, sign * v * c)

        def pairs(n_paths, bounces):
            # ``off`` unrelated paths come first (as when proposals and prefetched uniform
            # samples share a batch); the lanes' paths are rows off, off + 1, ...
            n_paths = n_paths + off
            k = rng.integers(0, 6, n_paths)
            paths = np.repeat(np.arange(n_paths), k)
            return SimpleNamespace(visible=np.ones(n_paths, bool), pair_path=paths,
                                   pair_point=rng.integers(0, n_points, len(paths)),
                                   pair_value=rng.random((len(paths), 3)),
                                   pair_bounce=rng.choice(bounces, len(paths)).astype(np.int16),
                                   first_dim=np.full(n_paths, 6 + 4 * 1, np.int32))

        for step in range(300):
            lanes = np.unique(rng.integers(0, n_chains, rng.integers(1, 4)))
            pc, sc = rng.integers(0, 5, len(lanes)), rng.integers(0, 5, len(lanes))
            log.commit(lanes, pc, sc)
            for lane, a, b in zip(lanes.tolist(), pc.tolist(), sc.tolist()):
                add(prefix, lane, a)
                add(suffix, lane, b)
            full = rng.random() < 0.5
            off = int(rng.integers(0, 3))
            batch = pairs(len(lanes), [1, 2, 3] if full else [2, 3])
            rows = off + np.arange(len(lanes))
            if full:
                log.replace(lanes, batch, rows)
            else:
                log.replace_suffix(lanes, batch, rows)
            for i, lane in enumerate(lanes.tolist()):
                sel = batch.pair_path == off + i
                is_pre = batch.pair_bounce <= 1
                if full:
                    s_pre = sel & is_pre
                    prefix[lane] = (batch.pair_point[s_pre], batch.pair_value[s_pre])
                    sel = sel & ~is_pre
                suffix[lane] = (batch.pair_point[sel], batch.pair_value[sel])
        final = np.arange(n_chains)
        pc, sc = rng.integers(1, 4, n_chains), rng.integers(1, 4, n_chains)
        log.commit(final, pc, sc)
        for lane, a, b in zip(final.tolist(), pc.tolist(), sc.tolist()):
            add(prefix, lane, a)
            add(suffix, lane, b)
        log.flush()
        np.testing.assert_allclose(log.sums, expected, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(log.half_sums, halves, rtol=1e-12, atol=1e-12)
        assert np.abs(halves).sum() > 0.1 * np.abs(expected).sum()
        results.append(log.sums)
    np.testing.assert_allclose(results[0], results[2], rtol=1e-12)


def test_uniform_samples_outside_the_visible_set_deposit_their_weighted_flux():
    """Under a Focus the chains' traces carry unweighted fluxes (``trace_photons``'s ``unweighted``):
    the uniform samples outside V count with their weights w (1 for paths not from afar, aims 0)."""
    from core.mcmc import DepositLog
    rng = np.random.default_rng(2)
    n_points = 20
    paths = np.array([0, 0, 1, 2, 2, 3])
    batch = SimpleNamespace(visible=np.zeros(4, bool), pair_path=paths,
                            pair_point=rng.integers(0, n_points, 6), pair_value=rng.random((6, 3)),
                            aims=np.array([0.5, 0.0, 3.0, 0.25]))
    expected = np.zeros((n_points, 3))
    w = np.array([0.5, 1.0, 3.0, 0.25])
    np.add.at(expected, batch.pair_point, batch.pair_value * w[paths][:, None])
    log = DepositLog(n_points, 4)
    np.testing.assert_array_equal(log.uniform(batch, np.arange(4)), np.arange(4))
    log.flush()
    np.testing.assert_allclose(log.outside_sums, expected, rtol=1e-12)
    batch.aims = None
    log = DepositLog(n_points, 4)
    log.uniform(batch, np.arange(4))
    log.flush()
    unweighted = np.zeros((n_points, 3))
    np.add.at(unweighted, batch.pair_point, batch.pair_value)
    np.testing.assert_allclose(log.outside_sums, unweighted, rtol=1e-12)


def test_chains_under_a_focus_start_weighted_runs():
    """A chain without a state takes every visible aimed sample, half of them on each half of the
    box, and records it with the weight W = w of that sample: the weighted first states follow V w
    (8/9 on the w = 2 half), as H&J's first states follow V, and the counters' recorded_w is the sum
    of those weights (core/mcmc.py, "Photons from afar")."""
    oracle = AimedOracle([((0.0, 0.0), (0.5, 0.9)), ((0.5, 0.0), (1.0, 0.9))])
    settings = RenderSettings(target_acceptance=0.6, mutation="off")
    rng = np.random.default_rng(9)
    chains = ChainSet.create(20000, DIMS, 1.0, rng)
    counters = ChainCounters()
    rec = OccupancyRecorder(20000, 2)
    iterate(chains, oracle, rec, rng, settings, counters)
    end_pass(chains, rec)
    started = chains.u[chains.valid, 0] >= 0.5
    n = len(started)
    assert n == counters.initialised == counters.recorded
    assert abs(n / 20000 - 0.9) < 4 * np.sqrt(0.09 / 20000)
    assert abs(started.mean() - 0.5) < 4 * np.sqrt(0.25 / n), started.mean()
    np.testing.assert_array_equal(chains.run_weight[chains.valid], np.where(started, 2.0, 0.25))
    assert counters.recorded_w == pytest.approx(chains.run_weight[chains.valid].sum())
    assert rec.counts.sum() == pytest.approx(counters.recorded_w)
    share = rec.counts[1] / rec.counts.sum()
    # (its spread: d share / d started.mean() = 0.4 at 1/2)
    assert abs(share - 8 / 9) < 4 * 0.4 * np.sqrt(0.25 / n), share


class CellOracle(BoxOracle):
    """Paths in box k deposit ``values[k]`` on point 0 (one pair each, whatever their V): the
    photon pass's deposits, as :class:`DepositLog` records them."""

    def __init__(self, boxes, values, gens):
        super().__init__(boxes, gens=gens)
        self.values = np.asarray(values, np.float64)

    def __call__(self, u, refresh_rng, resume=None, limit=None, floor=None):
        batch = super().__call__(u, refresh_rng, resume, limit, floor)
        value = np.zeros(len(u))
        for k, (lo, hi) in enumerate(self.boxes):
            value[((u[:, :2] >= lo) & (u[:, :2] < hi)).all(axis=1)] = self.values[k]
        path = np.flatnonzero(value > 0)
        batch.pair_path, batch.pair_point = path, np.zeros(len(path), np.int64)
        batch.pair_value = np.repeat(value[path, None], 3, axis=1)
        batch.pair_bounce = np.zeros(len(path), np.int16)
        return batch


def chain_pass(chains, oracle, rng, settings, iterations, generation):
    """One pass of the worker's chains (``PhotonWorker._chain_pass``) on one point: its estimate
    Vc S / N + (outside + newer shares) / n_U, as the worker and the integrator make it."""
    rec, counters = DepositLog(1, chains.count), ChainCounters()
    rec.lane_gen, rec.shares = chains.gen, chains.generation_shares
    begin_pass(chains, oracle, rec, counters)
    prefetched = None
    for i in range(iterations):
        prefetched = iterate(chains, oracle, rec, rng, settings, counters, prefetched=prefetched,
                             prefetch=i + 1 < iterations, generation=generation)
    end_pass(chains, rec, prefetched, oracle, counters)
    rec.flush()
    n_u = counters.uniform_samples
    estimate = rec.outside_sums[0, 0] / n_u
    if counters.recorded:
        estimate += counters.uniform_visible / n_u * rec.sums[0, 0] / counters.recorded_w
        estimate += rec.newer_sums[0, 0] * (counters.iterations / chains.count / counters.recorded_w) / n_u
    return estimate


@pytest.mark.parametrize("generations", [True, False])
def test_chains_keep_the_cells_of_their_runs_so_growth_leaves_no_bias(generations):
    """The visible cells grow: box B's cells come in generation 1, after the chains found their
    states in box A (generation 0).  Chains that take B at once (as before the generations:
    every chain of the newest generation) stay in A until an exchange, while the normaliser
    counts A and B: the pass after the growth came out 0.73 +- 0.02 of the integral.  With the
    generations each chain keeps A until a uniform sample starts a new run, the recordings of
    A's chains count |A| / |A u B| of theirs, and B's uniform samples count for them."""
    a, b = ((0.1, 0.1), (0.4, 0.2)), ((0.6, 0.6), (0.65, 0.8))
    oracle = CellOracle([a, b], [1.0, 3.0], gens=[0, 1])
    exact = 0.03 * 1.0 + 0.01 * 3.0
    s = RenderSettings()
    estimates = []
    for seed in range(40):
        rng = np.random.default_rng(seed)
        chains = ChainSet.create(64, DIMS, s.initial_mutation_size, rng)
        chain_pass(chains, oracle, rng, s, 150, 0)
        assert chains.valid.mean() > 0.9
        if not generations:
            chains.gen[:] = 1                    # (the chains as before: in the newest V at once)
        estimates.append(chain_pass(chains, oracle, rng, s, 10, 1))
    mean, se = np.mean(estimates), np.std(estimates) / np.sqrt(len(estimates))
    if generations:
        assert abs(mean - exact) < 4 * se + 0.01 * exact, (mean, se, exact)
    else:
        assert mean < 0.85 * exact, (mean, se, exact)


def test_the_shares_of_a_generation_count_its_samples_after_its_last_chain_left():
    """rho_g counts the uniform samples whose oldest cells are of generation g for as long as the
    window lasts, though the last chain of g has started a new run since: its recordings of
    the pass wait for rho until the splat.  (A floor that followed the chains' oldest generation
    up counted them under generation 1: rho_0 1/7, and the half-transparent leaf of
    ``tests/core/test_transparency.py`` came out 0.993 +- 0.002 of PPM's image over 40 seeds.)
    Between passes :meth:`ChainSet.raise_floor` may merge them."""
    never = np.iinfo(np.int64).max
    chains = ChainSet.create(4, DIMS, 0.1, np.random.default_rng(0))
    chains.valid[:] = True
    chains.gen[:] = [0, 1, 1, 1]
    assert chains.entry_window(1) == 0
    chains.count_entries(1, np.array([0, 1, 1, never]), np.ones(4))
    chains.gen[0] = 1                           # the last chain of generation 0 begins a new run
    chains.count_entries(1, np.array([0, 1, 1, 1]), np.ones(4))
    np.testing.assert_allclose(chains.generation_shares(), [2 / 7, 1])
    chains.raise_floor()                        # (the pass's recordings splatted)
    assert chains.entry_floor == 1
    np.testing.assert_allclose(chains.generation_shares(), [0, 1])
    chains.count_entries(2, np.array([0, 2]), np.ones(2))      # newer cells: a new window
    assert chains.entry_floor == 1
    np.testing.assert_allclose(chains.generation_shares(), [0, 0.5, 1])

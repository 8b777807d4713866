"""Visibility-driven Markov chains in primary sample space (Hachisuka & Jensen 2011).

C chains advance in lockstep.  Each chain pairs a *uniform* chain (target 1:
every step a fresh uniform vector) with a *visibility* chain (target V(u)/Vc).
One iteration, for every chain (``algorithm.md`` 2):

1. draw a uniform sample u_U and trace it (one batch for all chains; within a pass it
   was traced in the previous iteration's proposal batch, see :class:`Prefetched`);
2. replica exchange: if V(u_U) = 1 the uniform sample becomes the current state
   and no mutation happens (a chain without a visible state yet takes it as its
   initial state: this is the initialisation search, counted as uniform samples);
3. otherwise mutate the current state (one batch for all such chains) and accept
   exactly when the proposal is visible; adapt the mutation size (one for all chains,
   see below);
4. ``mutation="exact"`` only: after a rejection, redraw the dimensions after the
   current state's first visible vertex (a Gibbs step on the suffix, ``algorithm.md`` 3),
   tracing only from that vertex on (its state is kept per chain), within a pass in the
   next iteration's batch;
5. every chain with a visible state records its current state once.

Recording is lazy: a state's deposits are kept with a count of its recordings and
summed, multiplied by that count, in bulk (SLR's cached ``prevResults``, without its
stale-cache bug: the deposits are dropped at the end of every pass and the states are
traced again against the next pass's measurement points).  A state has two parts, the
deposits up to its first visible vertex (the *prefix*) and after it (the *suffix*);
the Gibbs refresh replaces only the suffix, so the two parts keep separate counts.

Two parts.  The chains' visible set V is the target's visible cells (``core/visible_cells.py``),
which only grow, so a state never leaves it between passes.  A path can also deposit on
points outside the cells (points seen through a glass ball or in a curved mirror lie apart
and add no cells): the integral splits exactly into the paths in V, Vc E_V[f] from the
chains, and the rest, (1/n_U) sum f(u_U) [u_U not in V] from the uniform samples, as plain
photon tracing would count them (:meth:`Recorder.uniform`).  Before, V also held the paths
that deposited in the current pass; that part moved with every pass's points, the states
in it were dropped at the next pass, and with exchanges as rare as Vc per iteration the
chains could not refill it: on ``small_view`` (a 600 mm lens on a glass ball) the pixels
seen through the ball came out 0.78 of SPPM's at equal radii and the rest 1.024
(``benchmarks/outside_cells.py``; now 1.02 and 1.006).

Generations.  The cells grow (the integrator adds the points of later passes), and a chain whose
states were spread over the old cells is not spread over the new ones: counting it with the new
normaliser made the passes after a growth too dark where the new cells are and too bright elsewhere
until exchanges mixed the chains (on glass505 of the glass parity family the image 1.0094 +- 0.0024 of
PPM's; README, "A visible set that holds still").  So every cell has the generation (pass) it came in,
and a chain's run keeps the generation g of the cells it began in (``ChainSet.gen``): its proposals
are visible in the cells of generation g or older alone (``trace_photons``'s ``cell_limit``), so its
states stay uniform over V_g, and a visible uniform sample (visible in the newest cells) begins a new
run in the newest generation.  The integral splits for each g as in "Two parts": I = |V_g| E_g[f] +
(paths outside V_g), and the pass's estimate mixes these by the chains' recordings: a recording of a
chain of generation g counts rho_g = |V_g| / |V_newest| of its deposits (the integrator multiplies by
the newest Vc; rho from the uniform samples since the newest generation came, whose oldest cells the
trace reports, ``ChainSet.generation_shares``, applied when :class:`DepositLog` splats), and a visible
uniform sample whose oldest cell is of generation e counts, as a sample outside V, for the chains of
older generations: times the sum of their recordings' W in that iteration (``Recorder.newer``), which
the worker scales by iterations / recordings of the pass.  With one generation (no growth since the
chains' runs began) nothing changes.  The trace tells the samples' oldest cells apart down to the
chains' oldest generation when the window began, and that floor rises between passes alone
(``ChainSet.entry_window``): one that followed the chains' oldest up counted a generation's samples
under a newer one once its last chain had left, while that chain's recordings of the pass still
waited for rho (the fast tier's half-transparent leaf 0.9925 +- 0.0016 of PPM's, now 1.0008 +-
0.0015; ``benchmarks/cell_generations.py --scene leaf``).  ``tests/core/test_mcmc.py`` grows a box
of the sample space under chains that found their states in another: 1.005 +- 0.032 of the integral
in the pass after, 0.73 +- 0.02 with every chain in the newest cells at once (as before).

Adaptation.  theta_{i+1} = theta_i + (A_i - A*) / i (``algorithm.md`` 2), i counting the
iterations with proposals, A_i the acceptance of *all* chains so far: one mutation size for
the chains of a worker.  Each chain adapting on its own acceptance, as a single chain does in
the papers, made a chain's step size depend on where it had been, and with the few iterations
a chain gets per pass (photons per pass / chains, about 10 at 4096 chains) that moved the
chains' states off the uniform distribution over V: on an open floor under a constant sky
(visible fraction 1.4 %) the grazing band of the image held 0.992 +- 0.002 of its share of
the recorded states and the near half came out 1.017 +- 0.003 of the exact value (144
seeds, 16 passes); with the pooled size the far and near halves are 1.002 +- 0.001 and
1.004 +- 0.003.  A size frozen at the value the pool settles on (0.08) kept the band's
share too (0.998 +- 0.002); README "Bias of a mutation size per chain".

Photons from afar.  Under a :class:`~core.lights.Focus` a sample u maps to a path whose origin
(sun, world) came from the mixture q(x) = p(x) / w(x) of the scene's disc and the focus's, not from
the scene's disc p; the weight w(u) is what the photon's flux would carry (``trace_photons``'s
``unweighted``: here it does not).  The chains then target V(u) w(u) in u, which is V in the
paths' own measure, so the recorded states carry their fluxes as they are, Vc = E_q[V w] comes
from the uniform samples as sum(w V) / n_U (``uniform_visible_w``), the uniform samples outside V
deposit w times their flux, and a mutation is accepted with V(u') min(1, w' / w).  A visible
uniform sample comes from q V, not from the target: a chain takes every one, as without a focus,
and the run of states that starts there, up to the chain's next visible uniform sample, is
recorded with the weight W = w of that sample (``ChainSet.run_weight``; the recorder's counts are
times W, and the integrator divides by their sum, ``recorded_w``, instead of the recordings' count).
The mutations leave V w invariant, so E[W f(X_t)] = E_qV[w] E_Vw[f] at every step t of a run, and a
run ends when a uniform sample, drawn independently of the state, is visible: sum W f / sum W
estimates E_Vw[f] (without a focus W = 1: H&J's estimator).  Taking every visible sample without W
starts the chains on q V, off the target wherever w varies over the visible paths.  In stop 61 a
chain with a state took a visible sample with the chance min(1, w' / w) and one without with the
chance w / M (M the largest w seen: rejection from q V), exact, but where visible paths also start
off the focus's disc (w = 2 against about 0.16 on it on an open sky-lit floor) M = 2 times slower
than unaimed to find first states, so such chains did not aim; with the runs' weights they do, and
the sky-lit floor's relMSE is 1.3 times lower (README, "Photons from afar aimed at what the camera
sees").  The uniform samples outside V are plain photons, and where they light what the camera
sees from off the disc (``small_view``'s ball shows the town beyond the sphere), aiming halves
them: the integrator then drops the focus, by the test it applies to the normaliser, on the
samples that deposit there (``outside_w``, ``outside_w2``).  A focus that comes or goes maps the
samples to other paths, so the worker then drops every state (``ChainSet.forget``).

Glossary: theta = mutation size, A* = target acceptance, n_U / n_UV = uniform
samples / visible uniform samples (the normaliser Vc ~ n_UV / n_U).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .lights import LIGHT_DIMS
from .photon_pass import BOUNCE_DIMS, PointSums, aim_moments

THETA_MIN, THETA_MAX = 1e-4, 1e3


def wrap_unit(x):
    """Map to [0, 1): ``x mod 1`` with the floating-point result 1.0 sent to 0.  (``x - floor(x)``
    gives np.mod's numbers to the bit, 3.7 times faster on (4096, 40) states.)"""
    y = x - np.floor(x)
    y[y >= 1.0] = 0.0
    return y


def mutate(u, theta, rng):
    """Kelemen-style mutation of every dimension: u + sgn(2 xi0 - 1) xi1^(1/theta + 1), wrapped.

    u : (n, d) states in [0, 1); theta : (n,) mutation sizes.  The step density is
    symmetric, so the Metropolis-Hastings acceptance is V(u') (``algorithm.md`` 2).
    """
    xi = rng.random((2,) + u.shape)
    step = np.where(xi[0] < 0.5, -1.0, 1.0) * xi[1] ** (1.0 / theta + 1.0)[:, None]
    return wrap_unit(u + step)


def adapt_theta(theta, accepted, proposed, target, step=None):
    """theta + (A - A*) / i with A = accepted / proposed so far and i = ``step`` (default: the
    proposals), clamped (no 0/0: counts below 1 count as 1)."""
    a = accepted / np.maximum(proposed, 1)
    i = np.maximum(proposed if step is None else step, 1)
    return np.clip(theta + (a - target) / i, THETA_MIN, THETA_MAX)


@dataclass
class ChainCounters:
    """Counts of one pass (summed over chains); merged across workers."""

    iterations: int = 0          # chain iterations (one uniform sample each)
    paths_traced: int = 0        # photon paths traced (uniform, proposals, re-traces)
    recorded: int = 0            # photon paths recorded (N_iter of the normaliser)
    recorded_w: float = 0.0      # the chains' recordings, each weighted by its run's W (Focus)
    proposals: int = 0           # mutation proposals
    accepted: int = 0            # accepted proposals
    exchanges: int = 0           # replica exchanges (visible uniform sample replaced a state)
    aiming_workers: int = 0      # workers whose chains drew their uniform samples aimed (Focus)
    initialised: int = 0         # chains that found their first visible state
    uniform_samples: int = 0     # n_U of this pass
    uniform_visible: int = 0     # n_UV of this pass
    uniform_visible_w: float = 0.0  # sum of w over them (the normaliser's; = n_UV without a Focus)
    uniform_outside: int = 0     # uniform samples outside V that deposited (counted directly)
    recorded_older: int = 0      # recordings of chains whose runs began before the newest cells
    uniform_newer: int = 0       # visible uniform samples outside some older chains' V ("Generations")
    rays: int = 0                # closest-hit rays of the photon paths
    vertices: int = 0            # photon path vertices (surface hits)
    trace_s: float = 0.0         # seconds spent tracing photon paths (the rest is chain bookkeeping)
    # Visible uniform paths from afar under a Focus (photon_pass.aim_moments): sums of w, w^2, count.
    aimed_w: float = 0.0
    aimed_w2: float = 0.0
    aimed_visible: int = 0
    # The chains' uniform samples outside V that deposited, under a Focus: sums of w, w^2 (their count
    # is uniform_outside).
    outside_w: float = 0.0
    outside_w2: float = 0.0

    def add(self, other: "ChainCounters") -> None:
        for f in self.__dataclass_fields__:
            setattr(self, f, getattr(self, f) + getattr(other, f))


@dataclass
class ChainSet:
    """State of C chains: current samples, validity, adaptation counters."""

    u: np.ndarray                   # (C, d) float64 current states in [0, 1)
    valid: np.ndarray               # (C,) bool: the current state is visible
    first_dim: np.ndarray           # (C,) int32 first visible vertex's dimension offset of the state
    theta: np.ndarray               # (C,) float64 mutation size, one value for all (see "Adaptation")
    proposed: np.ndarray            # (C,) int64 mutation proposals so far (all passes)
    accepted: np.ndarray            # (C,) int64 accepted proposals so far
    hold: np.ndarray                # (C,) int64 pending recordings of the current suffix
    hold_prefix: np.ndarray         # (C,) int64 pending recordings of the current prefix
    weight: np.ndarray              # (C,) float64 the current state's w under a Focus (1 without)
    run_weight: np.ndarray          # (C,) float64 the weight W of the chain's run: w of its last
    #                                 uniform sample taken (1 without a Focus)
    gen: np.ndarray                 # (C,) int64 the generation of the visible cells of the chain's
    #                                 run: its V (module docstring, "Generations")
    adaptations: int = 0            # iterations with proposals so far: the adaptation's step index
    vertex: dict = field(default_factory=dict)  # arrays (C, ...): state at the first visible vertex
    # The uniform samples since the cells' newest generation came: generation -> sum of their w
    # whose oldest cell is of that generation (those older than ``entry_floor`` counted under it;
    # :meth:`generation_shares`).
    entry_w: dict = field(default_factory=dict)
    entry_since: int = -1           # the newest generation when entry_w began
    entry_floor: int = 0            # the oldest generation entry_w tells apart (:meth:`entry_window`)

    @staticmethod
    def create(n_chains, dims, theta0, rng) -> "ChainSet":
        return ChainSet(u=rng.random((n_chains, dims)), valid=np.zeros(n_chains, bool),
                        first_dim=np.full(n_chains, -1, np.int32),
                        theta=np.full(n_chains, float(theta0)), proposed=np.zeros(n_chains, np.int64),
                        accepted=np.zeros(n_chains, np.int64), hold=np.zeros(n_chains, np.int64),
                        hold_prefix=np.zeros(n_chains, np.int64), weight=np.ones(n_chains),
                        run_weight=np.ones(n_chains), gen=np.zeros(n_chains, np.int64))

    def forget(self) -> None:
        """Drop every state (the chains search again from uniform samples), e.g. when the map from
        samples to paths changes (a Focus that comes or goes); the mutation size stays."""
        self.valid[:] = False
        self.first_dim[:] = -1
        self.weight[:] = 1.0
        self.run_weight[:] = 1.0

    @property
    def count(self) -> int:
        return int(len(self.u))

    def oldest(self, newest) -> int:
        """The oldest generation of the chains with a state (``newest`` when none has one)."""
        return int(self.gen[self.valid].min()) if self.valid.any() else int(newest)

    def entry_window(self, newest) -> int:
        """The floor of :attr:`entry_w`'s generations; it starts again, with the floor at the chains'
        oldest generation, whenever the cells' ``newest`` generation changes.  The floor must not
        follow the chains' oldest up while recordings of older chains wait for their rho (a
        window whose floor rose with the last old chain's exchange counted the samples of the
        older generations under a newer one after it: those chains' recordings came out too
        small, 0.993 of PPM's image on the half-transparent leaf); :meth:`raise_floor` raises it
        between passes."""
        if newest != self.entry_since:
            self.entry_w, self.entry_since = {}, int(newest)
            self.entry_floor = self.oldest(newest)
        return self.entry_floor

    def raise_floor(self) -> None:
        """Raise :attr:`entry_floor` to the chains' oldest generation (once every recording so far
        has been splatted, e.g. at a pass's start): counts below it merge into it."""
        if self.entry_since < 0:
            return
        floor = self.oldest(self.entry_since)
        if floor <= self.entry_floor:
            return
        merged = {}
        for k, v in self.entry_w.items():
            merged[max(k, floor)] = merged.get(max(k, floor), 0.0) + v
        self.entry_w, self.entry_floor = merged, floor

    def count_entries(self, newest, entry, w) -> None:
        """Add uniform samples whose oldest cells are of generations ``entry`` (weights ``w``) to
        :attr:`entry_w` (:meth:`entry_window`)."""
        e = np.maximum(entry, self.entry_window(newest))
        keys, inverse = np.unique(e, return_inverse=True)
        sums = np.bincount(inverse, weights=w, minlength=len(keys))
        for k, v in zip(keys.tolist(), sums.tolist()):
            self.entry_w[k] = self.entry_w.get(k, 0.0) + v

    def generation_shares(self):
        """(newest + 1,) float64: rho_g = |V_g| / |V_newest| for every generation g, estimated from
        :attr:`entry_w`: what a recording of a chain of generation g counts in units of the newest
        V (all 1 where no visible sample has been counted yet; None before any count)."""
        if self.entry_since < 0:
            return None
        dense = np.zeros(self.entry_since + 1)
        for k, v in self.entry_w.items():
            if k <= self.entry_since:
                dense[k] += v
        run = np.cumsum(dense)
        return run / run[-1] if run[-1] > 0 else np.ones(len(run))

    @property
    def acceptance_rate(self) -> float:
        p = int(self.proposed.sum())
        return float(self.accepted.sum()) / p if p else 0.0


class Recorder:
    """Receives the chains' recordings.  Subclasses cache per-chain payloads."""

    def replace(self, lanes, batch, rows):
        """The current states of chains ``lanes`` are now the traced paths ``rows`` of ``batch``."""

    def replace_suffix(self, lanes, batch, rows):
        """Only the suffixes of ``lanes`` changed, to the resumed traces ``rows`` of ``batch``."""

    def commit(self, lanes, prefix_counts, suffix_counts):
        """Record the prefixes and the suffixes of the current states of ``lanes`` so many times."""

    def uniform(self, batch, rows):
        """Uniform samples ``rows`` of ``batch`` are outside V: their deposits count as they are
        (divided by n_U, not recorded by a chain; module docstring, "Two parts").  Returns the rows
        of those that deposited.  Under a Focus their flux is unweighted (the chains' traces) and
        takes its w here (``batch.aims``)."""
        return rows[:0]

    def newer(self, batch, rows, share):
        """Visible uniform samples ``rows`` of ``batch`` lie outside the V of older chains, whose
        recordings this iteration sum to ``share`` (k,): their deposits count times that share
        (module docstring, "Generations")."""


def begin_pass(chains, trace, recorder, counters):
    """Trace every visible state again against the new target; states no longer visible are dropped."""
    lanes = np.flatnonzero(chains.valid)
    if len(lanes) == 0:
        return
    gen = chains.gen[lanes]
    batch = trace(chains.u[lanes], None, limit=gen, floor=gen)
    counters.paths_traced += len(lanes)
    counters.rays += batch.rays
    counters.vertices += batch.vertices
    still = batch.visible
    chains.valid[lanes[~still]] = False
    chains.first_dim[lanes] = np.where(still, batch.first_dim, -1)
    keep = np.flatnonzero(still)
    _store_vertex(chains, lanes[keep], batch, keep)
    chains.weight[lanes[keep]] = path_weights(batch, keep)
    recorder.replace(lanes[keep], batch, keep)


def path_weights(batch, rows):
    """(k,) the Focus's weights w of paths ``rows`` of ``batch`` (1 for paths not from afar, and
    without a focus)."""
    if batch.aims is None:
        return np.ones(len(rows))
    a = batch.aims[rows]
    return np.where(a > 0, a, 1.0)


def end_pass(chains, recorder, prefetched=None, trace=None, counters=None):
    """Record every pending state (the cached deposits are valid only within the pass).

    ``prefetched`` is what the last iteration returned when the pass was cut short: its
    untraced Gibbs refreshes are traced (with ``trace``) before they are recorded.
    """
    if prefetched is not None and prefetched.refreshed is not None:
        lanes, u, resume = prefetched.refreshed
        batch = trace(u, None, resume=resume, limit=chains.gen[lanes], floor=chains.gen[lanes])
        _count_traced(counters, len(lanes), batch)
        recorder.replace_suffix(lanes, batch, np.arange(len(lanes)))
        prefetched.refreshed = None
    _commit(chains, recorder, np.flatnonzero(chains.valid))
    chains.hold[:] = 0
    chains.hold_prefix[:] = 0


def _store_vertex(chains, lanes, batch, rows):
    """Keep the first-visible-vertex state of traced paths ``rows`` for chains ``lanes``."""
    for key, value in (batch.first or {}).items():
        if key not in chains.vertex:
            chains.vertex[key] = np.zeros((chains.count,) + value.shape[1:], value.dtype)
        chains.vertex[key][lanes] = value[rows]


class Prefetched:
    """What an iteration leaves for the next one of the same pass.

    ``u`` (C, d) are the next iteration's uniform samples as traced, ``batch`` the batch
    that holds them at rows ``offset + arange(C)``.  Tracing them with the proposals saves
    a batch per iteration (a batch has a fixed cost of a few milliseconds per bounce).  The
    low-dimension refresh then also redraws their suffixes after their first visible
    vertex; that leaves them uniform, because the vertex depends only on the dimensions
    before it.

    ``refreshed`` (``mutation="exact"``) is None or ``(lanes, u, resume)``: chains whose
    suffixes were redrawn (Gibbs refresh) but not yet traced, their new states and their
    first visible vertices.  They are traced at the end of the next iteration's batch; the
    recorder hears of the new suffixes before that iteration's first commit, and the
    redrawn states are already the chains' current states for the next mutation, so the
    chains evolve exactly as if they had been traced at once.
    """

    def __init__(self, u, batch, offset, refreshed=None):
        self.u, self.batch, self.offset = u, batch, offset
        self.refreshed = refreshed


def iterate(chains, trace, recorder, rng, settings, counters, exchange=True, prefetched=None,
            prefetch=False, generation=0):
    """Advance every chain by one iteration (see the module docstring).

    ``exchange=False`` switches replica exchange off for chains that already have a
    state (a negative control for tests: such chains never jump between islands).
    ``prefetched`` (a :class:`Prefetched` from the previous iteration of the same pass)
    supplies this iteration's uniform samples; with ``prefetch`` the next iteration's
    are traced together with this one's proposals and returned (otherwise None), and
    the Gibbs refresh of this iteration's rejected states is left for the next batch.
    ``generation``: the newest generation of the target's visible cells (module docstring,
    "Generations"; 0 without cells).

    ``trace(u, refresh_rng, resume=None, limit=None, floor=None)`` traces paths for states ``u``
    (n, d) and returns an object with ``visible`` (n,), ``first_dim`` (n,), ``first`` (a dict of
    per-path arrays describing the first visible vertex), ``rays``, ``vertices`` and ``entry``
    (None, or (n,) the oldest generation of the cells a path met, tested while it is newer than
    its ``floor``; ``limit``: the newest generation whose cells make a path visible);
    with ``refresh_rng`` it redraws, in place in ``u``, the dimensions after the first
    visible vertex (low-dimension mutation) of paths not resumed; with ``resume`` (k rows
    of such a dict) it traces the last k paths only from those vertices on.
    """
    c, d = chains.u.shape
    mode = settings.mutation
    refresh = rng if mode in ("paper", "exact") else None
    was_valid = chains.valid.copy()
    counters.iterations += c
    oldest = chains.oldest(generation)
    # The uniform samples' oldest cells are told apart down to the window's floor (ChainSet.entry_window).
    floor = chains.entry_window(generation)
    newest_c, floor_c = np.full(c, generation, np.int64), np.full(c, floor, np.int64)
    # 1. Uniform samples for every chain.
    refreshed = None
    if prefetched is None:
        u_uniform = rng.random((c, d))
        batch_u = trace(u_uniform, None, limit=newest_c, floor=floor_c)
        _count_traced(counters, c, batch_u)
        rows_u = np.arange(c)
    else:
        u_uniform, batch_u = prefetched.u, prefetched.batch
        rows_u = prefetched.offset + np.arange(c)
        refreshed = prefetched.refreshed
    vis = batch_u.visible[rows_u]
    w_u = path_weights(batch_u, rows_u)
    counters.uniform_samples += c
    counters.uniform_visible += int(vis.sum())
    counters.uniform_visible_w += float(w_u[vis].sum())
    newer = None
    if batch_u.entry is not None:
        entry = batch_u.entry[rows_u]
        chains.count_entries(generation, entry, w_u)
        # Visible samples outside the V of older chains: counted for those as outside samples.
        newer = np.flatnonzero(vis & (entry > oldest))
        newer = (rows_u[newer], entry[newer]) if len(newer) else None
    aimed = batch_u.aims is not None
    if aimed:
        sw, sw2, k = aim_moments(batch_u, rows_u)
        counters.aimed_w += sw
        counters.aimed_w2 += sw2
        counters.aimed_visible += k
    outside = rows_u[~vis]
    if len(outside):
        deposited = recorder.uniform(batch_u, outside)
        counters.uniform_outside += len(deposited)
        if aimed:
            w = path_weights(batch_u, deposited)
            counters.outside_w += float(w.sum())
            counters.outside_w2 += float(w @ w)
    if not exchange:
        vis = vis & ~was_valid
    take = np.flatnonzero(vis)
    # 3. Mutation of the other chains that have a state (with the next uniform samples and
    # the previous iteration's Gibbs refreshes, in one batch).
    lanes = np.flatnonzero(was_valid & ~vis)
    proposal = mutate(chains.u[lanes], chains.theta[lanes], rng) if len(lanes) else np.zeros((0, d))
    u_next = rng.random((c, d)) if prefetch else None
    upcoming = None
    parts = [proposal] + ([u_next] if prefetch else []) + ([refreshed[1]] if refreshed else [])
    if len(lanes) or prefetch or refreshed:
        u_all = np.concatenate(parts) if len(parts) > 1 else proposal
        gen_parts = [chains.gen[lanes]] + ([newest_c] if prefetch else []) + (
            [chains.gen[refreshed[0]]] if refreshed else [])
        floor_parts = [chains.gen[lanes]] + ([floor_c] if prefetch else []) + (
            [chains.gen[refreshed[0]]] if refreshed else [])
        batch_p = trace(u_all, refresh, resume=refreshed[2] if refreshed else None,
                        limit=np.concatenate(gen_parts), floor=np.concatenate(floor_parts))
        _count_traced(counters, len(u_all), batch_p)
        if prefetch:
            upcoming = Prefetched(u_all[len(lanes):len(lanes) + c], batch_p, len(lanes))
        if refreshed:
            # The suffixes redrawn in the previous iteration (already the chains' states).
            k = len(refreshed[0])
            recorder.replace_suffix(refreshed[0], batch_p, np.arange(len(u_all) - k, len(u_all)))
    # 2. Replica exchange (or initialisation of chains without a state), after the batch: the
    # recorder hears of the previous refreshes before any commit.  Exchanged chains are not
    # mutated, so the batch is the same either way.
    if len(take):
        _switch(chains, recorder, take, u_uniform[take], batch_u.first_dim[rows_u[take]], batch_u,
                rows_u[take], w_u[take], new_run=True, generation=generation)
        counters.exchanges += int(was_valid[take].sum())
        counters.initialised += int((~was_valid[take]).sum())
    if len(lanes):
        proposal = u_all[:len(lanes)]
        acc = batch_p.visible[:len(lanes)]
        rows_p = np.arange(len(lanes))
        w_p = path_weights(batch_p, rows_p)
        if aimed:
            acc = acc & (rng.random(len(lanes)) * chains.weight[lanes] < w_p)
        counters.proposals += len(lanes)
        counters.accepted += int(acc.sum())
        chains.proposed[lanes] += 1
        chains.accepted[lanes] += acc
        # One size for all chains, on their pooled acceptance (module docstring, "Adaptation").
        chains.adaptations += 1
        chains.theta[:] = adapt_theta(chains.theta[0], chains.accepted.sum(), chains.proposed.sum(),
                                      settings.target_acceptance, chains.adaptations)
        a = np.flatnonzero(acc)
        if len(a):
            _switch(chains, recorder, lanes[a], proposal[a], batch_p.first_dim[a], batch_p, a, w_p[a])
        # 4. Exact low-dimension mutation: Gibbs refresh of the rejected states' suffixes.
        rejected = lanes[~acc]
        if mode == "exact" and len(rejected):
            new_u = chains.u[rejected].copy()
            starts = chains.first_dim[rejected]
            cols = np.arange(d)[None, :]
            redraw = cols >= starts[:, None]
            new_u[redraw] = rng.random(int(redraw.sum()))
            # The prefix (and so V and the first visible vertex) is unchanged: trace from there.
            resume = {k: v[rejected] for k, v in chains.vertex.items()}
            recorder.commit(rejected, np.zeros(len(rejected)),
                            chains.hold[rejected] * chains.run_weight[rejected])
            chains.hold[rejected] = 0
            chains.u[rejected] = new_u
            if upcoming is not None:
                upcoming.refreshed = (rejected, new_u, resume)
            else:
                batch_g = trace(new_u, None, resume=resume, limit=chains.gen[rejected],
                                floor=chains.gen[rejected])
                _count_traced(counters, len(rejected), batch_g)
                recorder.replace_suffix(rejected, batch_g, np.arange(len(rejected)))
    # 5. Every chain with a state records it once.
    chains.hold[chains.valid] += 1
    chains.hold_prefix[chains.valid] += 1
    counters.recorded += int(chains.valid.sum())
    counters.recorded_w += float(chains.run_weight[chains.valid].sum())
    counters.recorded_older += int((chains.gen[chains.valid] < generation).sum())
    if newer is not None:
        counters.uniform_newer += len(newer[0])
        # Each such sample counts for the chains (this iteration's recordings, by their W) whose V
        # it is outside: share_t(e) = sum of W over the recorded chains of generations before e.
        lanes_v = np.flatnonzero(chains.valid)
        order = np.argsort(chains.gen[lanes_v], kind="stable")
        gens = chains.gen[lanes_v].take(order)
        run = np.concatenate([[0.0], np.cumsum(chains.run_weight[lanes_v].take(order))])
        recorder.newer(batch_u, newer[0], run[np.searchsorted(gens, newer[1], side="left")])
    return upcoming


def _count_traced(counters, n, batch):
    counters.paths_traced += n
    counters.rays += batch.rays
    counters.vertices += batch.vertices


def _switch(chains, recorder, lanes, new_u, new_first_dim, batch, rows, weights, new_run=False,
            generation=0):
    """Make traced paths ``rows`` of ``batch`` (weights w ``weights``) the current states of chains
    ``lanes``; with ``new_run`` (uniform samples) they begin new runs of weight W = w in the cells'
    ``generation``."""
    old = lanes[chains.valid[lanes]]
    _commit(chains, recorder, old)
    chains.hold[lanes] = 0
    chains.hold_prefix[lanes] = 0
    chains.u[lanes] = new_u
    chains.first_dim[lanes] = new_first_dim
    chains.valid[lanes] = True
    chains.weight[lanes] = weights
    if new_run:
        chains.run_weight[lanes] = weights
        chains.gen[lanes] = generation
    _store_vertex(chains, lanes, batch, rows)
    recorder.replace(lanes, batch, rows)


def _commit(chains, recorder, lanes):
    """Record the pending recordings of chains ``lanes``, each with its run's weight W."""
    w = chains.run_weight[lanes]
    recorder.commit(lanes, chains.hold_prefix[lanes] * w, chains.hold[lanes] * w)


class DepositLog(Recorder):
    """Deposits of the chains' states, kept until their recordings are known, then summed per point.

    Every state part (prefix or suffix) that becomes current gets an id and its deposit
    pairs are appended to a log (no per-iteration search through other chains' deposits).
    ``commit`` adds to the recording counts of the lanes' current parts.  ``flush`` splats
    the log, each pair times its part's count so far, into per-point sums and keeps only
    the pairs of the parts that are still current; it runs when the log grows past
    ``flush_pairs`` and at the end of the pass (deposits are valid for that pass only).
    Chain c's prefix lives in slot c, its suffix in slot C + c.

    With ``halves`` it also sums the even chains' deposits minus the odd chains'
    (``half_sums``): two independent halves of the chains, whose difference
    estimates the spread of the sums (``core.integrator.Accumulator``; the chains keep their
    states from pass to pass, so the spread of the passes underestimates it).

    ``main_slots``: the pairs on slots from it on (``DepositTarget``'s inner slots) do not count
    towards a flush or a splat (:meth:`PointSums.add`'s ``counted``), so that the other slots
    are summed in the same groups, to the same bits, with or without them (None: all count).

    Generations: ``lane_gen`` (the chains' :attr:`ChainSet.gen`, read when a part becomes current)
    and ``shares`` (a callable giving :meth:`ChainSet.generation_shares`, called at every flush)
    scale each part's recordings by rho of its chain's generation; ``newer_sums`` holds the
    visible uniform samples outside older chains' V times their shares (:meth:`newer`).
    """

    def __init__(self, n_points, n_chains, flush_pairs=1 << 21, halves=False, main_slots=None):
        self.n_points = n_points
        self.main_slots = main_slots
        self.flush_pairs = flush_pairs
        self._sums = PointSums(n_points)
        self.sums = self._sums.total                    # (m, 3), complete after flush()
        self._outside = PointSums(n_points)             # deposits of uniform samples outside V
        self.outside_sums = self._outside.total         # (m, 3), complete after flush()
        self.outside_pairs = 0
        self.n_chains = n_chains
        self.state_of_lane = np.full(2 * n_chains, -1, np.int64)   # current part id per slot
        self.count = np.zeros(1024)             # recordings per state id (times their runs' W)
        self.next_state = 0
        self.chunks = []                                        # (state ids, points, values)
        self.logged = 0
        self._halves = PointSums(n_points) if halves else None
        self.half_sums = self._halves.total if halves else None      # (m, 3), after flush()
        self.sign = np.zeros(len(self.count)) if halves else None   # +1 (even chain) or -1 per state id
        self.lane_gen = None                    # (C,) the chains' generations (ChainSet.gen), or None
        self.shares = None                      # callable -> rho per generation (or None), or None
        self.gen_of = np.zeros(len(self.count), np.int64)           # the generation of each state id
        self._newer = PointSums(n_points)
        self.newer_sums = self._newer.total     # (m, 3), complete after flush()
        self.newer_pairs = 0

    def replace(self, lanes, batch, rows):
        if len(lanes) == 0:
            return
        # Pairs at the first visible vertex form the prefix, later ones the suffix.
        first_bounce = (batch.first_dim - LIGHT_DIMS) // BOUNCE_DIMS
        row_first = np.full(len(batch.visible), -1, np.int64)
        row_first[rows] = first_bounce[rows]
        is_suffix = batch.pair_bounce > row_first[batch.pair_path]
        self._append(np.concatenate([lanes, lanes + self.n_chains]), batch, rows, is_suffix)

    def replace_suffix(self, lanes, batch, rows):
        if len(lanes) == 0:
            return
        self._append(lanes + self.n_chains, batch, rows, None)

    def commit(self, lanes, prefix_counts, suffix_counts):
        slots = np.concatenate([lanes, lanes + self.n_chains])
        ids = self.state_of_lane[slots]
        counts = np.concatenate([prefix_counts, suffix_counts])
        ok = (ids >= 0) & (counts > 0)
        np.add.at(self.count, ids[ok], counts[ok])

    def uniform(self, batch, rows):
        """Sum the deposits of paths ``rows`` of ``batch`` as they are; return those that deposited."""
        mask = np.zeros(len(batch.visible), bool)
        mask[rows] = True
        sel = np.flatnonzero(mask.take(batch.pair_path))
        if len(sel) == 0:
            return rows[:0]
        value = batch.pair_value.take(sel, axis=0)
        if batch.aims is not None:
            value = value * path_weights(batch, batch.pair_path.take(sel))[:, None]
        point = batch.pair_point.take(sel)
        self._outside.add(point, [value[:, c] for c in range(3)], self._counted(point))
        self.outside_pairs += len(sel)
        return np.unique(batch.pair_path.take(sel))

    def newer(self, batch, rows, share):
        scale = np.zeros(len(batch.visible))
        scale[rows] = share if batch.aims is None else share * path_weights(batch, rows)
        sel = np.flatnonzero(scale.take(batch.pair_path) > 0)
        if len(sel) == 0:
            return
        value = batch.pair_value.take(sel, axis=0) * scale.take(batch.pair_path.take(sel))[:, None]
        point = batch.pair_point.take(sel)
        self._newer.add(point, [value[:, c] for c in range(3)], self._counted(point))
        self.newer_pairs += len(sel)

    def _append(self, slots, batch, rows, is_suffix):
        """New part ids for ``slots``; log their pairs.  With ``is_suffix`` (per pair) the first
        half of ``slots`` takes a row's prefix pairs and the second half its suffix pairs."""
        ids = np.arange(self.next_state, self.next_state + len(slots))
        self.next_state += len(slots)
        if self.next_state > len(self.count):
            grown = np.zeros(2 * self.next_state)
            grown[:len(self.count)] = self.count
            self.count = grown
            if self.sign is not None:
                sign = np.zeros(len(grown))
                sign[:len(self.sign)] = self.sign
                self.sign = sign
            gen_of = np.zeros(len(grown), np.int64)
            gen_of[:len(self.gen_of)] = self.gen_of
            self.gen_of = gen_of
        self.state_of_lane[slots] = ids
        if self.lane_gen is not None:
            self.gen_of[ids] = self.lane_gen.take(slots % self.n_chains)
        if self.sign is not None:
            self.sign[ids] = 1.0 - 2.0 * (slots % self.n_chains % 2)
        k = len(rows)
        row_state = np.full(len(batch.visible), -1, np.int64)
        row_state[rows] = ids[:k]
        state = row_state[batch.pair_path]
        if is_suffix is not None:
            row_suffix = np.full(len(batch.visible), -1, np.int64)
            row_suffix[rows] = ids[k:]
            state = np.where(is_suffix, row_suffix[batch.pair_path], state)
        sel = np.flatnonzero(state >= 0)
        if len(sel) == 0:
            return
        if len(sel) == len(state):      # every pair (e.g. a batch's visible paths all switched in)
            self.chunks.append((state, batch.pair_point, batch.pair_value))
        else:
            self.chunks.append((state.take(sel), batch.pair_point.take(sel), batch.pair_value.take(sel, axis=0)))
        self.logged += self._counted(self.chunks[-1][1])
        if self.logged > self.flush_pairs:
            self.flush()

    def _counted(self, point):
        """How many of the pairs with points ``point`` count (``main_slots``)."""
        return len(point) if self.main_slots is None else int(np.count_nonzero(point < self.main_slots))

    def flush(self):
        """Splat the recordings so far; keep the pairs of the current states only.

        Each pair's values times its part's count, summed per point (through
        :class:`PointSums`, in groups of at least as many pairs as points); pairs of parts
        recorded zero times add zeros.
        """
        self._outside.flush()
        self._newer.flush()
        if not self.chunks:
            return
        rho = self.shares() if self.shares is not None else None
        current = self.state_of_lane[self.state_of_lane >= 0]
        alive = np.zeros(len(self.count), bool)
        alive[current] = True
        kept = []
        for chunk in self.chunks:
            state, point = chunk[0], chunk[1]
            w = self.count.take(state)
            if rho is not None and len(rho) > 1:
                w = w * rho.take(np.minimum(self.gen_of.take(state), len(rho) - 1))
            value = chunk[2]
            counted = self._counted(point)
            self._sums.add(point, [value[:, c] * w for c in range(3)], counted)
            if self._halves is not None:
                w = w * self.sign.take(state)
                self._halves.add(point, [value[:, c] * w for c in range(3)], counted)
            keep = np.flatnonzero(alive.take(state))
            if len(keep) == len(state):
                kept.append(chunk)
            elif len(keep):
                kept.append(tuple(a.take(keep, axis=0) for a in chunk))
        self._sums.flush()
        if self._halves is not None:
            self._halves.flush()
        self.count[current] = 0
        # The kept pairs, as one chunk (later flushes then see few chunks).
        self.chunks = [tuple(np.concatenate(part) for part in zip(*kept))] if kept else []
        self.logged = self._counted(self.chunks[0][1]) if kept else 0

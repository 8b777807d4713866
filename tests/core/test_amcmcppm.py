"""AMCMCPPM against plain SPPM on a scene where SPPM converges (issue 3)."""
import numpy as np
import pytest

from core import RenderSettings, render
from core.context import RenderContext
from core.eye_pass import trace_eye_pass
from core.photon_pass import DepositTarget
from core.testing.scenes import cornell_box
from core.visible_cells import VisibleCells
from core.worker import PhotonWorker

SEEDS = 4
SCENE = dict(resolution=(16, 16))
RUN = dict(passes=3, photons_per_pass=40_000, chains=2048, workers=1)


def block_means(image, blocks=2):
    h, w = image.shape[:2]
    rgb = image[..., :3].mean(axis=2)
    return rgb.reshape(blocks, h // blocks, blocks, w // blocks).mean(axis=(1, 3)).ravel()


@pytest.fixture(scope="module")
def sppm_blocks():
    scene = cornell_box(**SCENE)
    return np.array([block_means(render(scene, RenderSettings(method="ppm", seed=s, **RUN)).image)
                     for s in range(SEEDS)])


@pytest.mark.parametrize("mutation", [pytest.param("off", marks=pytest.mark.slow), "paper", "exact"])
def test_amcmcppm_agrees_with_sppm_in_mean(sppm_blocks, mutation):
    scene = cornell_box(**SCENE)
    blocks = np.array([block_means(render(scene, RenderSettings(method="amcmcppm", mutation=mutation,
                                                                seed=s, **RUN)).image)
                       for s in range(SEEDS)])
    # The same seed gives both methods the same eye passes: compare paired differences per block.
    d = blocks - sppm_blocks
    se = d.std(axis=0, ddof=1) / np.sqrt(SEEDS)
    # Student t with 3 degrees of freedom, Sidak over 4 blocks at alpha = 0.01: |t| < 9.2.
    t = d.mean(axis=0) / np.maximum(se, 1e-12)
    assert np.all(np.abs(t) < 9.2), (d.mean(axis=0), se)
    # And a fixed tolerance on the whole image: within 2 % of SPPM.
    assert abs(blocks.mean() / sppm_blocks.mean() - 1) < 0.02


def test_different_seeds_agree_within_their_error_bars():
    scene = cornell_box(**SCENE)
    means, errors = [], []
    for seed in range(SEEDS):
        result = render(scene, RenderSettings(method="amcmcppm", seed=seed, **{**RUN, "passes": 5}))
        est = np.array([s["pass_mean"] for s in result.stats])
        means.append(est.mean())
        errors.append(est.std(ddof=1) / np.sqrt(len(est)))
    means, errors = np.array(means), np.array(errors)
    pooled = means.mean()
    assert np.all(np.abs(means - pooled) < 4 * np.sqrt(errors ** 2 + (errors ** 2).mean() / SEEDS)), \
        (means, errors)


def test_pass_statistics_are_consistent():
    scene = cornell_box(**SCENE)
    result = render(scene, RenderSettings(method="amcmcppm", seed=1, **RUN))
    stats = result.stats
    n_u = sum(s["uniform_samples"] for s in stats)
    n_uv = sum(s["uniform_visible"] for s in stats)
    assert stats[-1]["visible_fraction"] == pytest.approx(n_uv / n_u)
    for s in stats:
        assert s["uniform_samples"] >= RUN["photons_per_pass"]
        assert s["acceptance_rate"] == pytest.approx(s["accepted"] / s["proposals"])
        assert 1e-4 <= s["mutation_size"] <= 1e3
        # Each traced path is a uniform sample, a proposal, a Gibbs refresh or a pass-start re-trace.
        assert s["paths_traced"] >= s["uniform_samples"] + s["proposals"]
        assert s["photons_recorded"] <= s["uniform_samples"]
    assert stats[-1]["chains_with_state"] == RUN["chains"]
    # The radius shrinks as Knaus-Zwicker prescribes: r_2 / r_1 = sqrt((1 + alpha) / 2).
    assert stats[1]["radius"] / stats[0]["radius"] == pytest.approx(np.sqrt((1 + 2 / 3) / 2), rel=0.05)


def test_cumulative_and_per_pass_normalisation_agree():
    scene = cornell_box(**SCENE)
    a = render(scene, RenderSettings(method="amcmcppm", seed=2, normalisation="cumulative", **RUN)).image
    b = render(scene, RenderSettings(method="amcmcppm", seed=2, normalisation="per_pass", **RUN)).image
    # Same chains, only the visible-fraction weighting of the passes differs.
    assert abs(a[..., :3].mean() / b[..., :3].mean() - 1) < 0.01


def test_paths_outside_the_chains_visible_set_count_as_plain_photon_tracing():
    """With no visible cells no path is in the chains' V: every deposit comes from the chains'
    uniform samples (``core/mcmc.py``, "Two parts"), and their sum over n_U is plain photon
    tracing.  The same target's per-pass estimates from a PPM worker agree per image block."""
    scene = cornell_box(**SCENE)
    ctx = RenderContext(scene)
    eye = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8)
    pts = eye.points
    n_pixels = SCENE["resolution"][0] * SCENE["resolution"][1]
    plain = DepositTarget(pts, pts.base_radius, ctx.table, n_pixels, ctx.has_shading_normals)
    empty = DepositTarget(pts, pts.base_radius, ctx.table, n_pixels, ctx.has_shading_normals,
                          cells=VisibleCells())
    chain_worker = PhotonWorker(scene, RenderSettings(method="amcmcppm", chains=1024, seed=1), ctx=ctx)
    ppm_worker = PhotonWorker(scene, RenderSettings(method="ppm", seed=1), ctx=ctx)
    chain_est, ppm_est = [], []
    for i in range(6):
        out = chain_worker.run_pass(i, empty, 20_000)
        c = out["counters"]
        assert c["recorded"] == 0 and c["uniform_visible"] == 0 and not out["pixel_sum"].any()
        assert c["uniform_outside"] > 0
        chain_est.append(block_means(out["outside_sum"].reshape(16, 16, 3)) / c["uniform_samples"])
        out = ppm_worker.run_pass(i, plain, 20_000)
        ppm_est.append(block_means(out["pixel_sum"].reshape(16, 16, 3)) / out["counters"]["recorded"])
    a, b = np.array(chain_est), np.array(ppm_est)
    se = np.sqrt(a.var(axis=0, ddof=1) / len(a) + b.var(axis=0, ddof=1) / len(b))
    # Welch t with about 10 degrees of freedom, Sidak over 4 blocks at alpha = 0.01: |t| < 4.1.
    assert np.all(np.abs(a.mean(axis=0) - b.mean(axis=0)) < 4.1 * se), (a.mean(axis=0), b.mean(axis=0), se)
    assert abs(a.mean() / b.mean() - 1) < 0.03

"""The kernel-bias correction (RenderSettings.bias_correction): a second gather at half the
radius, and one weight for the whole image towards the extrapolation that removes an r^2 bias."""
import numpy as np
import pytest

from core import RenderSettings, render
from core.integrator import BIAS_MIN_PASSES, Accumulator, _halves_difference
from core.testing.scenes import BUILTIN, disk_irradiance, kernel_radius_px, spot_over_plane


class Eye:
    def __init__(self, n):
        self.emission = np.zeros((n, 3))
        self.alpha = np.ones(n)


def synthetic_passes(acc, rng, truth, bias, noise, passes=40, photons=1000):
    """Passes whose sums at r estimate truth + bias and at r/2 truth + bias / 4, with Poisson-like
    noise (the inner sum's own noise twice the outer's, as for a quarter of the area)."""
    n = len(truth)
    for _ in range(passes):
        outer_noise = noise * np.sqrt(photons) * rng.normal(size=(n, 3))
        s = photons * (truth + bias) + outer_noise
        own_noise = np.sqrt(3) * noise * np.sqrt(photons) * rng.normal(size=(n, 3))
        inner = photons * (truth + bias / 4) + outer_noise + own_noise
        acc.add(Eye(n), s, photons, photons, photons, False, inner_sum=inner)


def test_a_bias_that_grows_as_r_squared_is_extrapolated_away():
    rng = np.random.default_rng(1)
    truth = rng.uniform(0.2, 1.0, (3000, 3))
    acc = Accumulator(3000, "cumulative", bias_correction=True)
    synthetic_passes(acc, rng, truth, bias=0.2 * truth, noise=0.05)
    img = acc.image(False)[:, :3]
    assert acc.bias_weight == pytest.approx(4 / 3, abs=0.05)
    plain = Accumulator(3000, "cumulative")
    synthetic_passes(plain, np.random.default_rng(1), truth, bias=0.2 * truth, noise=0.05)
    err, err_plain = np.abs(img / truth - 1).mean(), np.abs(plain.image(False)[:, :3] / truth - 1).mean()
    assert err < 0.02 < 0.19 < err_plain


def test_noise_without_bias_keeps_the_plain_estimate():
    rng = np.random.default_rng(2)
    truth = rng.uniform(0.2, 1.0, (3000, 3))
    acc = Accumulator(3000, "cumulative", bias_correction=True)
    synthetic_passes(acc, rng, truth, bias=0.0, noise=1.0)
    assert acc.image(False) is not None and 0.0 <= acc.bias_weight < 0.1


def test_no_correction_before_enough_passes_and_never_a_negative_pixel():
    rng = np.random.default_rng(3)
    truth = np.full((500, 3), 0.01)
    acc = Accumulator(500, "cumulative", bias_correction=True)
    synthetic_passes(acc, rng, truth, bias=0.5, noise=0.01, passes=BIAS_MIN_PASSES - 1)
    acc.image(False)
    assert acc.bias_weight == 0.0
    synthetic_passes(acc, rng, truth, bias=0.5, noise=0.01, passes=1)
    img = acc.image(False)
    assert acc.bias_weight > 1 and (img >= 0).all() and np.isfinite(img).all()
    with pytest.raises(ValueError, match="inner sums"):
        acc.add(Eye(500), np.zeros((500, 3)), 10, 10, 10, False)


def chain_passes(acc, rng, truth, bias, noise, passes=40, photons=1000, shared=0.0):
    """Chain passes whose error in T lasts over the passes, each half of the chains keeping its
    own (chains whose states do not move): the passes do not spread, the halves do.  ``shared``:
    a fresh error each pass common to both halves (as the measurement points' jitter): the
    passes spread, the halves do not."""
    n = len(truth)
    lasting = noise * rng.normal(size=(2, n, 3))
    for _ in range(passes):
        s = photons * (truth + bias)
        t = 0.5 * photons * (-0.75 * bias + lasting + shared * rng.normal(size=(n, 3)))   # T of each half
        acc.add(Eye(n), s, photons, photons, photons, True, inner_sum=s + t.sum(axis=0),
                half_diff=t[0] - t[1])


def test_the_chains_variance_comes_from_their_halves_or_their_passes():
    """Without bias, an error that lasts over the passes keeps w near 0 (the spread of the passes
    would see no noise and give 4/3), and so does a fresh error each pass that both halves share
    (the halves would see none); a bias larger than the halves' difference still gives 4/3."""
    rng = np.random.default_rng(4)
    truth = rng.uniform(0.2, 1.0, (3000, 3))
    noisy = Accumulator(3000, "cumulative", bias_correction=True)
    chain_passes(noisy, rng, truth, bias=0.0, noise=0.1)
    noisy.image(True)
    assert noisy.bias_weight < 0.15
    biased = Accumulator(3000, "cumulative", bias_correction=True)
    chain_passes(biased, rng, truth, bias=0.2 * truth, noise=0.005)
    img = biased.image(True)[:, :3]
    assert biased.bias_weight > 1.25 and np.abs(img / truth - 1).mean() < 0.02
    # Noise the halves share (the eye passes') is seen by the spread of the passes.
    shared = Accumulator(3000, "cumulative", bias_correction=True)
    chain_passes(shared, rng, truth, bias=0.0, noise=0.0, shared=0.1 * np.sqrt(40))
    shared.image(True)
    assert shared.bias_weight < 0.15
    with pytest.raises(ValueError, match="halves"):
        biased.add(Eye(3000), np.ones((3000, 3)), 10, 10, 10, True, inner_sum=np.ones((3000, 3)))


@pytest.mark.parametrize("workers", [2, 3, 4])
def test_the_workers_difference_has_the_variance_of_their_sum(workers):
    """Workers of unequal photon counts (a pass cut short): X has mean 0 and E[X^2] = Var T.  (The
    chains' counts, ``recorded_w``: their recordings weighted by their runs' W, 1 without a focus.)"""
    rng = np.random.default_rng(5)
    n, mu, sigma = 20000, 0.3, 0.5
    recorded = rng.integers(500, 2000, workers)
    outputs = []
    for n_k in recorded:
        t = n_k * mu + sigma * np.sqrt(n_k) * rng.normal(size=(n, 3))      # Var T_k = N_k sigma^2
        outer = rng.uniform(0, 5, (n, 3))
        outputs.append({"pixel_sum": outer, "inner_sum": outer + t, "counters": {"recorded_w": float(n_k)}})
    x = _halves_difference(outputs)
    var_t = sigma ** 2 * recorded.sum()
    assert abs(x.mean()) < 5 * np.sqrt(var_t / x.size)
    assert 0.95 * var_t < (x * x).mean() < 1.05 * var_t


@pytest.mark.parametrize("method", ["ppm", "amcmcppm"])
def test_point_light_over_a_plane_loses_its_kernel_bias(method):
    """At the foot of a point light, a disk kernel of radius 0.3 h reads 6.3 % dark; the
    extrapolation from r and r/2 leaves 0.1 % (closed forms in ``spot_over_plane``)."""
    albedo, power, h, r = 0.5, 100.0, 1.0, 0.3
    intensity = power / (4 * np.pi)
    exact = albedo * intensity / (np.pi * h * h)
    scene = spot_over_plane(kernel_radius=r, resolution=(4, 4))
    images = {}
    for correct in (False, True):
        # (the photons' kernel bias: their direct light; light samples have none)
        result = render(scene, RenderSettings(method=method, passes=10, photons_per_pass=100_000,
                                              max_bounces=1, workers=1, bias_correction=correct,
                                              direct_light="photons",
                                              initial_radius_px=kernel_radius_px(scene, r)))
        images[correct] = result.image[..., :3].mean()
    weight = result.stats[-1]["bias_weight"]
    plain_bias = 1 - disk_irradiance(intensity, h, r) * albedo / np.pi / exact
    assert plain_bias > 0.05
    # The plain image is dark (less than at r: the radius shrinks over the passes).
    assert images[False] < (1 - 0.5 * plain_bias) * exact
    assert abs(images[True] / exact - 1) < 0.25 * plain_bias, (images, exact, weight)
    assert weight > 0.9


@pytest.mark.parametrize("method", ["ppm", "amcmcppm", "auto"])
def test_the_plain_estimate_is_unchanged_and_every_image_finite(method):
    """The correction adds a gather and changes no photon: the passes' own (plain) estimates
    are those of a render without it, to the bit; with two workers the inner sums merge."""
    scene = BUILTIN["glowing_glass_ball"](resolution=(24, 18))
    runs = {}
    for correct, workers in ((False, 1), (True, 1), (True, 2)):
        images = []
        # (edge coverage off: its per-point kernel factors expose, in the last bit, that the
        # inner slots group the splats' pairs differently; the photons are the same)
        result = render(scene, RenderSettings(method=method, passes=6, photons_per_pass=8000, workers=workers,
                                              bias_correction=correct, edge_coverage=False),
                        on_iteration=lambda r: images.append(np.isfinite(r.image).all()))
        assert all(images) and len(images) == 6
        runs[correct, workers] = result
    assert ([s["pass_mean"] for s in runs[False, 1].stats] == [s["pass_mean"] for s in runs[True, 1].stats])
    assert all(s["bias_weight"] == 0.0 for s in runs[False, 1].stats)
    assert runs[True, 1].stats[-1]["bias_weight"] > 0.0
    assert runs[True, 2].stats[-1]["bias_weight"] > 0.0

"""AMCMCPPM against SPPM at equal radii on ``small_view``: the pixels seen through the glass ball.

Points seen through the ball lie apart and add no visible cells (``core/visible_cells.py``),
so the photon paths that reach them are outside the chains' visible set V.  Until 9d3c1be
V also held "deposits in this pass", which moved with every pass's points; chain states
there were dropped at the next pass and only rare replica exchanges (the visible fraction
is 5e-4) brought chains back.  Now those paths count through the uniform samples
(``core/mcmc.py``, "Two parts").

Renders, two at a time, each with one worker and 100,000 photons per pass: SPPM of this
checkout (``--ppm-passes``), AMCMCPPM of this checkout and of ``core`` at ``--base``
(``--passes``; extracted as in ``ab_photon_pass.py``).  The same initial radius for all, so
all three estimate the same blurred image.  Printed per run: the image mean with a standard
error from batch means of the per-pass estimates, the mean over the pixels whose camera ray
hits the ball and over the rest, and both over SPPM's.

    python benchmarks/outside_cells.py [--base 9d3c1be] [--passes 600] [--ppm-passes 3000]
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ab_photon_pass import extract  # noqa: E402

RESOLUTION = (64, 48)
GLASS = 2           # the ball's material in core.testing.scenes.small_view


def through_ball_mask():
    """(H*W,) bool: pixels whose camera ray through the pixel centre hits the ball first."""
    from core.camera import generate_camera_rays
    from core.context import RenderContext
    from core.testing.scenes import small_view
    scene = small_view(RESOLUTION)
    pix = np.arange(RESOLUTION[0] * RESOLUTION[1])
    origins, dirs = generate_camera_rays(scene.camera, pix, np.full((len(pix), 4), 0.5))[:2]
    hits = RenderContext(scene).accel.intersect(origins, dirs)
    return hits.is_hit & (scene.material_ids[np.maximum(hits.prim_ids, 0)] == GLASS)


def run(job):
    package, method, passes, seed, path = job
    if path:
        sys.path.insert(0, path)
    core = importlib.import_module(package)
    scenes = importlib.import_module(f"{package}.testing.scenes")
    means = []
    settings = core.RenderSettings(method=method, passes=passes, seed=seed, workers=1,
                                   photons_per_pass=100_000)
    result = core.render(scenes.small_view(RESOLUTION), settings,
                         on_iteration=lambda r: means.append(r.stats[-1]["pass_mean"]))
    return result.image[..., :3].mean(axis=2).ravel(), np.array(means)


def batch_se(values, batches=20):
    k = len(values) // batches
    b = values[:batches * k].reshape(batches, k).mean(axis=1)
    return float(b.std(ddof=1) / np.sqrt(batches))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="9d3c1be", help="git revision of the comparison core")
    ap.add_argument("--passes", type=int, default=600, help="AMCMCPPM passes")
    ap.add_argument("--ppm-passes", type=int, default=3000, help="SPPM passes")
    ap.add_argument("--seed", type=int, default=11)
    a = ap.parse_args()
    mask = through_ball_mask()
    with tempfile.TemporaryDirectory() as tmp:
        extract(a.base, tmp)
        jobs = {"sppm": ("core", "ppm", a.ppm_passes, a.seed, None),
                "amcmcppm": ("core", "amcmcppm", a.passes, a.seed + 1, None),
                f"amcmcppm at {a.base}": ("core_base", "amcmcppm", a.passes, a.seed + 1, tmp)}
        with ProcessPoolExecutor(max_workers=2) as ex:
            results = dict(zip(jobs, ex.map(run, jobs.values())))
    ref = results["sppm"][0]
    print(f"small_view {RESOLUTION[0]}x{RESOLUTION[1]}, {int(mask.sum())} pixels through the ball, "
          f"100,000 photons per pass")
    print(f"{'run':24} {'passes':>6} {'mean':>7} {'+- SE':>7} {'ball':>7} {'rest':>7} {'ball/SPPM':>10} "
          f"{'rest/SPPM':>10}")
    for name, (img, means) in results.items():
        print(f"{name:24} {len(means):6d} {img.mean():7.4f} {batch_se(means):7.4f} {img[mask].mean():7.4f} "
              f"{img[~mask].mean():7.4f} {img[mask].mean() / ref[mask].mean():10.3f} "
              f"{img[~mask].mean() / ref[~mask].mean():10.3f}")


if __name__ == "__main__":
    main()

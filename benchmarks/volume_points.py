"""Camera points in fog: how many points per segment of a camera path through a scattering
volume (``eye_pass.MAX_SEGMENT_POINTS``) pay for themselves.

For each count, the scene is rendered with two seeds (same passes and photons); the image's
noise is the RMS of their difference over sqrt(2), relative to the mean, and the time is the
mean wall time of the two.  Counts alternate within each round so the machine's load falls on
all alike; the table gives each count's noise and time as ratios to one point per segment, with
the variance-time product (lower is better: the time one point per segment needs for the same
noise, over the time this count needs).

    python benchmarks/volume_points.py [--scene corner_in_world_fog] [--counts 1 4 8 16]
                                       [--method ppm] [--passes 8] [--photons 50000]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import RenderSettings, eye_pass, render  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402


def measure(scene, count, settings, seeds=(0, 1)):
    """(relative noise, mean seconds) of ``scene`` with ``count`` points per segment."""
    eye_pass.MAX_SEGMENT_POINTS = count
    images, seconds = [], []
    for seed in seeds:
        t0 = time.perf_counter()
        result = render(scene, RenderSettings(seed=seed, **settings))
        seconds.append(time.perf_counter() - t0)
        images.append(result.image[..., :3].astype(np.float64))
    a, b = images
    noise = np.sqrt(((a - b) ** 2).mean() / 2.0) / (0.5 * (a.mean() + b.mean()))
    return noise, float(np.mean(seconds))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="corner_in_world_fog", choices=sorted(BUILTIN))
    ap.add_argument("--counts", type=int, nargs="+", default=[1, 4, 8, 16])
    ap.add_argument("--method", default="ppm", choices=["ppm", "amcmcppm"])
    ap.add_argument("--passes", type=int, default=8)
    ap.add_argument("--photons", type=int, default=50_000)
    ap.add_argument("--rounds", type=int, default=1)
    args = ap.parse_args(argv)
    scene = BUILTIN[args.scene]()
    settings = dict(method=args.method, passes=args.passes, photons_per_pass=args.photons, workers=1)
    budget = eye_pass.VOLUME_POINT_BUDGET
    w, h = scene.camera.resolution
    print(f"{args.scene} {w}x{h}, {args.method}, {args.passes} passes of {args.photons} photons "
          f"(the budget allows {budget // (w * h)} points per segment at this size)")
    rows = {c: [] for c in args.counts}
    for _ in range(args.rounds):
        for c in args.counts:
            rows[c].append(measure(scene, c, settings))
    base_noise = np.median([r[0] for r in rows[args.counts[0]]])
    base_time = np.median([r[1] for r in rows[args.counts[0]]])
    print("points/segment  noise   time s  noise ratio  time ratio  efficiency (var x time)")
    for c in args.counts:
        noise, secs = np.median([r[0] for r in rows[c]]), np.median([r[1] for r in rows[c]])
        eff = (base_noise ** 2 * base_time) / (noise ** 2 * secs)
        print(f"{c:14d}  {noise:.4f}  {secs:6.1f}  {noise / base_noise:11.3f}  {secs / base_time:10.3f}  "
              f"{eff:10.2f}")


if __name__ == "__main__":
    main()

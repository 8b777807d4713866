"""The kernel-bias correction's weight w against an oracle: the best w for each render's own A and D.

Renders a scene (as ``error_vs_time.py`` does: 64x48, a time limit, a seed) and keeps the last
image's plain estimate A and difference D (``Accumulator.difference``); then sweeps w over
[0, 4/3] against the stored reference of ``error_vs_time.py`` and prints the best w, its relMSE,
the plain relMSE (w = 0) and the relMSE of the w the renderer chose.  The relMSE is the one of
``error_vs_time.py`` (weights 1 / (ref^2 + 0.01), the reference's own noise removed).

    python benchmarks/bias_weight_oracle.py [--scenes glass_ceiling_room ...] [--method amcmcppm]
                                            [--seeds 2] [--workers 1 2] [--time 60]

One render at a time (``--workers 2`` uses both cores).  The oracle is only as good as the
reference: where the reference's split-half noise is close to the runs' error (``small_view``)
its best w moves from seed to seed.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from core import RenderSettings, render  # noqa: E402
from core import integrator  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402
from error_vs_time import errors, reference_path  # noqa: E402

STEPS = 25          # w = 0, 1/18, ..., 4/3
RESOLUTION = (64, 48)


def render_parts(scene, settings):
    """Render; return (A, D, estimates of Var D, w of the renderer, passes) of the last image:
    A and D (n_pixels, 3) and ``Accumulator.difference``'s tuple of (n_pixels, 3) estimates."""
    last = {}
    original = integrator.Accumulator._corrected

    def keep(acc, rgb, is_chain, scale):
        out = original(acc, rgb, is_chain, scale)
        last.update(a=rgb.copy(), diff=acc.difference(is_chain, scale), w=acc.bias_weight)
        return out

    integrator.Accumulator._corrected = keep
    try:
        result = render(scene, settings)
    finally:
        integrator.Accumulator._corrected = original
    if last.get("diff") is None:
        raise RuntimeError("no corrected image: fewer passes than BIAS_MIN_PASSES, or the correction off")
    d, variances = last["diff"]
    return last["a"], d, variances, last["w"], result.passes


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["glass_ceiling_room", "glowing_glass_ball"])
    ap.add_argument("--method", default="amcmcppm", choices=("amcmcppm", "ppm"))
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--time", type=float, default=60.0, help="seconds per render")
    args = ap.parse_args()
    grid = np.linspace(0.0, 4.0 / 3.0, STEPS)
    print("| scene | workers | seed | passes | best w | its relMSE | plain relMSE | renderer's w "
          "| its relMSE | renderer / best |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.scenes:
        z = np.load(reference_path(name, RESOLUTION))
        ref = z["image"][..., :3].astype(np.float64)
        ref_var = (z["half_a"][..., :3].astype(np.float64) - z["half_b"][..., :3]) ** 2 / 4
        scene = BUILTIN[name](resolution=RESOLUTION)
        for workers in args.workers:
            for seed in range(args.seeds):
                settings = RenderSettings(method=args.method, seed=seed, passes=0, time_limit=args.time,
                                          workers=workers)
                a, d, _, w, passes = render_parts(scene, settings)
                images = np.maximum(a + np.append(grid, w)[:, None, None] * d, 0.0).reshape(-1, *ref.shape)
                rel = errors(images, ref, ref_var)[3]       # corrected relMSE per image
                best = int(np.argmin(rel[:-1]))
                print(f"| {name} | {workers} | {seed} | {passes} | {grid[best]:.2f} | {rel[best]:.4g} "
                      f"| {rel[0]:.4g} | {w:.2f} | {rel[-1]:.4g} | {rel[-1] / rel[best]:.3f} |", flush=True)


if __name__ == "__main__":
    main()

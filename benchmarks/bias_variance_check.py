"""Is Var D right?  The bias correction's noise estimate against the spread of D over seeds.

The weight of the kernel-bias correction is w = (4/3)(1 - V/S), V the weighted sum over pixels
of Var D (``Accumulator.difference``).  This renders a scene with several seeds, the same
settings and a fixed number of passes, and compares the V each render estimates with the V of
the spread of D between the renders (no reference needed).  For the Markov chains it shows both
estimates and the larger, which the renderer uses: the halves of the chains (they share the eye
passes, so they miss the noise of the measurement points' jitter) and the spread of the passes
(which takes the passes as independent, and the chains' are not).  Weights 1 / (A^2 + 0.01) with
A the seeds' mean image.

    python benchmarks/bias_variance_check.py [--scenes glass_ceiling_room small_view ...]
        [--method amcmcppm] [--seeds 8] [--passes 40] [--workers 1] [--jobs 2]

Runs ``--jobs`` renders at a time, each in its own process.  The ratio estimate / spread should
be near 1; its own uncertainty is about sqrt(2 / (seeds - 1)) where few pixels dominate V.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def run_one(scene_name, method, seed, passes, workers, out_path):
    """One render in this process; saves A, D and both variance estimates of the last image."""
    from bias_weight_oracle import render_parts
    from core import RenderSettings
    from core.testing.scenes import BUILTIN

    scene = BUILTIN[scene_name](resolution=(64, 48))
    a, d, variances, w, _ = render_parts(scene, RenderSettings(method=method, seed=seed, passes=passes,
                                                                workers=workers))
    # (the spread of the passes[, the chains' halves])
    np.savez(out_path, a=a, d=d, var_passes=variances[0], var_halves=variances[-1], w=w)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run-one", nargs=6, help=argparse.SUPPRESS)
    ap.add_argument("--scenes", nargs="+", default=["glass_ceiling_room", "small_view", "glowing_glass_ball"])
    ap.add_argument("--method", default="amcmcppm", choices=("amcmcppm", "ppm"))
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--passes", type=int, default=40)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    if args.run_one:
        name, method, seed, passes, workers, out = args.run_one
        run_one(name, method, int(seed), int(passes), int(workers), out)
        return
    print(f"{args.method}, {args.seeds} seeds, {args.passes} passes, {args.workers} worker(s) per render, "
          "64x48")
    print("| scene | S (mean D^2) | V from the seeds' spread | V, halves / spread | V, passes / spread "
          "| V, the larger (renderer) / spread | w: mean over seeds |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            paths = [os.path.join(tmp, f"{name}_{s}.npz") for s in range(args.seeds)]

            def job(seed):
                cmd = [sys.executable, os.path.abspath(__file__), "--run-one", name, args.method,
                       str(seed), str(args.passes), str(args.workers), paths[seed]]
                subprocess.run(cmd, check=True)

            with ThreadPoolExecutor(max_workers=args.jobs) as ex:
                list(ex.map(job, range(args.seeds)))
            runs = [np.load(p) for p in paths]
            a = np.mean([r["a"] for r in runs], axis=0)
            weight = 1.0 / (a * a + 0.01)
            d = np.array([r["d"] for r in runs])
            spread = float(np.sum(weight * d.var(axis=0, ddof=1)))
            square = float(np.mean([np.sum(weight * r["d"] ** 2) for r in runs]))
            halves = np.array([np.sum(weight * r["var_halves"]) for r in runs])
            passes = np.array([np.sum(weight * r["var_passes"]) for r in runs])
            larger = np.maximum(halves, passes)
            w = float(np.mean([r["w"] for r in runs]))
            print(f"| {name} | {square:.4g} | {spread:.4g} | {halves.mean() / spread:.2f} "
                  f"| {passes.mean() / spread:.2f} | {larger.mean() / spread:.2f} | {w:.2f} |", flush=True)


if __name__ == "__main__":
    main()

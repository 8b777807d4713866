"""A/B of procedural textures: this checkout's ``core`` against ``core`` at another git revision.

Both versions are imported into one process (the other as ``core_base``, extracted with ``git
archive``, as ``ab_photon_pass.py`` does) and evaluate the same texture over the same points in
turns (the order reversing every round), so each round's ratio is taken under the same machine
load; the outputs must be equal bit for bit.  Medians and ranges over rounds:

    python benchmarks/texture_ab.py [--base HEAD~1] [--points 65536] [--rounds 5]
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from ab_photon_pass import extract  # noqa: E402

CASES = {
    "gabor_2d": ("pattern_textures", "gabor_texture", {"gabor_type": "2D"}),
    "gabor_3d": ("pattern_textures", "gabor_texture", {"gabor_type": "3D"}),
    "voronoi_3d_f1": ("voronoi", "voronoi_texture", {"scale": 5.0}),
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="HEAD~1")
    ap.add_argument("--points", type=int, default=65536)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    args = ap.parse_args()
    d = np.random.default_rng(0).normal(size=(args.points, 3))
    points = d / np.linalg.norm(d, axis=1, keepdims=True) * 2.0      # (a world's directions, scaled)
    with tempfile.TemporaryDirectory() as tmp:
        extract(args.base, tmp)
        sys.path.insert(0, tmp)
        print(f"{args.points} points, {args.rounds} rounds; this checkout against {args.base}")
        for name in args.cases:
            module, function, kwargs = CASES[name]
            funcs = {pkg: getattr(importlib.import_module(f"{pkg}.{module}"), function)
                     for pkg in ("core", "core_base")}
            outputs = {pkg: f(points, **kwargs) for pkg, f in funcs.items()}       # (warm-up)
            if any(not np.array_equal(outputs["core"][k], outputs["core_base"][k]) for k in outputs["core"]):
                raise SystemExit(f"{name}: the two revisions differ")
            seconds = {pkg: [] for pkg in funcs}
            for r in range(args.rounds):
                for pkg in (list(funcs) if r % 2 == 0 else list(funcs)[::-1]):
                    t0 = time.perf_counter()
                    funcs[pkg](points, **kwargs)
                    seconds[pkg].append(time.perf_counter() - t0)
            ratio = np.array(seconds["core_base"]) / np.array(seconds["core"])
            print(f"{name}: {np.median(seconds['core_base']):.3f} s -> {np.median(seconds['core']):.3f} s, "
                  f"{np.median(ratio):.2f}x faster (range {ratio.min():.2f}-{ratio.max():.2f})", flush=True)


if __name__ == "__main__":
    main()

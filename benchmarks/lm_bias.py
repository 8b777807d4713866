"""Bias of the low-dimension mutation modes against converged SPPM (issue 3, algorithm.md 3).

The paper's low-dimension mutation accepts every visible proposal although its proposal
density is not symmetric when the first visible vertex of the current and the proposed
path differ, so its stationary law is not exactly V/Vc.  This measures the image-mean
bias of every mode (off, paper, exact) against SPPM on scenes where SPPM converges:

* a furnace (camera inside an emitting diffuse sphere of albedo 0.8): L = 5 exactly, and
  the first visible vertex varies from path to path (a photon may land near the visible
  spot at its first, second, ... bounce);
* the Cornell box (diffuse).

Each (scene, method) runs ``--seeds`` times; the same seed gives every method the same
eye passes, so the bias is estimated from paired differences with a standard error.

    python benchmarks/lm_bias.py [--seeds 6] [--passes 6] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import RenderSettings, render  # noqa: E402
from core.testing.scenes import cornell_box, furnace_sphere  # noqa: E402

SCENES = {
    "furnace (albedo 0.8, L = 5)": (lambda: furnace_sphere(0.8, 1.0, resolution=(16, 16)), dict(max_bounces=40)),
    "cornell box": (lambda: cornell_box((24, 24)), dict()),
}
MODES = {"ppm": dict(method="ppm"), "off": dict(method="amcmcppm", mutation="off"),
         "paper": dict(method="amcmcppm", mutation="paper"), "exact": dict(method="amcmcppm", mutation="exact")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--passes", type=int, default=6)
    ap.add_argument("--photons-per-pass", type=int, default=40_000)
    ap.add_argument("--json")
    a = ap.parse_args()
    out = {}
    for name, (build, extra) in SCENES.items():
        scene = build()
        means = {m: [] for m in MODES}
        for seed in range(a.seeds):
            for m, kw in MODES.items():
                s = RenderSettings(seed=seed, passes=a.passes, photons_per_pass=a.photons_per_pass, chains=2048,
                                   workers=1, **kw, **extra)
                means[m].append(float(render(scene, s).image[..., :3].mean()))
        ppm = np.array(means["ppm"])
        out[name] = {"ppm_mean": float(ppm.mean()), "ppm_se": float(ppm.std(ddof=1) / np.sqrt(a.seeds))}
        print(f"{name}: SPPM mean {ppm.mean():.5f} +- {out[name]['ppm_se']:.5f}")
        for m in ("off", "paper", "exact"):
            d = (np.array(means[m]) - ppm) / ppm.mean()
            bias, se = float(d.mean()), float(d.std(ddof=1) / np.sqrt(a.seeds))
            out[name][m] = {"relative_bias": bias, "se": se, "z": bias / se if se > 0 else float("nan")}
            print(f"  {m:6s} relative bias {bias:+.3%} +- {se:.3%}  (z = {bias / se:+.1f})")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()

"""Bias of AMCMCPPM on an open floor under a constant sky: L = albedo * sky everywhere.

The floor of ``core.testing.scenes.sky_over_floor`` (32x32, seen at a slant up to grazing
angles) is rendered ``--seeds`` times by SPPM and by AMCMCPPM of this checkout, and by
AMCMCPPM of ``core`` at git revision ``--base`` (extracted as ``core_base``, as in
``ab_photon_pass.py``), with the default target acceptance and with 23.4 %.  Printed: the far (top, grazing) and near (bottom, face-on) halves
of the image over the exact value, mean and standard error over seeds.  Few photons per
pass and many chains leave each chain about ten iterations per pass, as in real renders;
the visible fraction is 1.4 %, so the chains move mostly by mutation.

Written for the switch from per-chain to pooled mutation-size adaptation
(``core/mcmc.py``, "Adaptation"): ``--base 7e5aa08`` is the last revision with a size per
chain.

    python benchmarks/sky_floor_bias.py [--base 7e5aa08] [--seeds 96] [--passes 16]
                                        [--photons 40000] [--albedo 0.5]
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
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ab_photon_pass import extract  # noqa: E402


def halves(package, method, a, seed, **extra):
    """(far, near) mean grey of the image of one render, over albedo * sky."""
    core = importlib.import_module(package)
    scenes = importlib.import_module(f"{package}.testing.scenes")
    scene = scenes.sky_over_floor(a.albedo, 1.0, resolution=(32, 32))
    settings = core.RenderSettings(method=method, workers=1, passes=a.passes, photons_per_pass=a.photons,
                                   seed=seed, **extra)
    grey = core.render(scene, settings).image[..., :3].mean(axis=2)
    h = grey.shape[0] // 2
    return np.array([grey[:h].mean(), grey[h:].mean()]) / a.albedo


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="7e5aa08", help="git revision of the comparison core")
    ap.add_argument("--seeds", type=int, default=96)
    ap.add_argument("--passes", type=int, default=16)
    ap.add_argument("--photons", type=int, default=40_000, help="photons per pass")
    ap.add_argument("--albedo", type=float, default=0.5)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        extract(a.base, tmp)
        sys.path.insert(0, tmp)
        runs = {"sppm": ("core", "ppm", {}), "amcmcppm": ("core", "amcmcppm", {}),
                f"amcmcppm at {a.base}": ("core_base", "amcmcppm", {}),
                f"amcmcppm at {a.base}, A* 0.234": ("core_base", "amcmcppm", {"target_acceptance": 0.234})}
        out = {k: [] for k in runs}
        t0 = time.perf_counter()
        for seed in range(a.seeds):
            for name, (package, method, extra) in runs.items():
                out[name].append(halves(package, method, a, seed, **extra))
    print(f"sky_over_floor albedo {a.albedo}, 32x32, {a.passes} passes of {a.photons} photons, "
          f"{a.seeds} seeds ({time.perf_counter() - t0:.0f} s); image halves over the exact value:")
    for name, rows in out.items():
        r = np.array(rows)
        m, se = r.mean(axis=0), r.std(axis=0, ddof=1) / np.sqrt(len(r))
        print(f"  {name:32s} far {m[0]:.4f} +- {se[0]:.4f}   near {m[1]:.4f} +- {se[1]:.4f}")


if __name__ == "__main__":
    main()

"""What stratified numbers buy (a thin lens's samples, the first surface's lobe choice, light samples).

This checkout's ``core`` against another revision's.  Both versions are imported into one process
(the other one as ``core_base``, extracted with ``git archive``, as ``ab_photon_pass.py`` does)
and render the same built-in scenes with a thin lens (``--pinhole``: as they are), PPM, the same
passes and photons, one worker, over the same seeds, one render of each version after the other;
``--direct-light sampled``: with light samples (``RenderSettings.direct_light``).
Each pass's numbers are uniform in either version, so the two images have the same
expectation and the difference of their mean squared errors is that of their variances: the
script reports each pixel's variance over the seeds (averaged over the image, and over the pixels
whose mean differs most from their neighbours': edges in and out of focus), relative to the image
mean squared, and the time per pass.

    python benchmarks/lens_cost.py --base 9428c42 [--scenes cornell_box hole_mirror_glass]
                                   [--resolution 160 120] [--passes 32] [--seeds 6] [--pinhole]
                                   [--direct-light sampled]
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from ab_photon_pass import extract  # noqa: E402

# A thin lens for each scene: (aperture radius, focus distance) in scene units.  The Cornell box
# focused on its back wall 4.9 m away (the boxes' front edges blur over about 5 pixels at 160 x
# 120), the sun through a hole focused on the mirror (the caustic and the glass blur).
LENSES = {"cornell_box": (0.15, 4.9), "hole_mirror_glass": (0.08, 2.0), "glass_ceiling_room": (0.1, 3.0)}


def renders(package, scene_name, resolution, passes, photons, seeds, lens=True, direct_light="photons"):
    """(seeds, h, w, 3) images and the seconds per pass of ``package``'s renders."""
    core = importlib.import_module(package)
    scene = importlib.import_module(f"{package}.testing.scenes").BUILTIN[scene_name](resolution=resolution)
    if lens:
        aperture, focus = LENSES[scene_name]
        scene = scene.replace(camera=dataclasses.replace(scene.camera, aperture_radius=aperture,
                                                         focus_distance=focus))
    images, t0 = [], time.perf_counter()
    for seed in seeds:
        settings = core.RenderSettings(method="ppm", passes=passes, photons_per_pass=photons, workers=1,
                                       seed=seed, direct_light=direct_light)
        images.append(core.render(scene, settings).image[..., :3].astype(np.float64))
    return np.array(images), (time.perf_counter() - t0) / (passes * len(seeds))


def edges(mean, share=0.1):
    """(h, w) bool: the ``share`` of pixels whose mean differs most from their 4 neighbours'."""
    lum = mean.mean(axis=2)
    p = np.pad(lum, 1, mode="edge")
    contrast = np.abs(4 * lum - p[:-2, 1:-1] - p[2:, 1:-1] - p[1:-1, :-2] - p[1:-1, 2:])
    return contrast >= np.quantile(contrast, 1.0 - share)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare with (before the change)")
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "hole_mirror_glass"],
                    help=f"built-in scenes (with a lens: {', '.join(sorted(LENSES))})")
    ap.add_argument("--resolution", type=int, nargs=2, default=(160, 120))
    ap.add_argument("--passes", type=int, default=32)
    ap.add_argument("--photons-per-pass", type=int, default=50_000)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--pinhole", action="store_true", help="the scenes' own cameras, without a lens")
    ap.add_argument("--direct-light", choices=("photons", "sampled"), default="photons")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="lens_cost_")
    extract(a.base, tmp)
    sys.path.insert(0, tmp)
    seeds = list(range(1, a.seeds + 1))
    print(f"{a.resolution[0]}x{a.resolution[1]}, {'pinhole' if a.pinhole else 'thin lens'}, PPM, "
          f"direct light from {a.direct_light}, "
          f"{a.passes} passes of {a.photons_per_pass:,} photons, "
          f"one worker, seeds {seeds[0]}-{seeds[-1]}; variance over the seeds / mean(image)^2")
    print("| scene | this checkout: all pixels | edges (10 %) | base: all pixels | edges | base / this, "
          "all | edges | s per pass, this / base |")
    print("|---|---|---|---|---|---|---|---|")
    for name in a.scenes:
        res = tuple(a.resolution)
        ours, t_ours = renders("core", name, res, a.passes, a.photons_per_pass, seeds, not a.pinhole,
                               a.direct_light)
        base, t_base = renders("core_base", name, res, a.passes, a.photons_per_pass, seeds, not a.pinhole,
                               a.direct_light)
        mean = np.concatenate([ours, base]).mean(axis=0)
        norm = float(mean.mean()) ** 2
        sel = edges(mean)
        v_ours, v_base = ours.var(axis=0, ddof=1).mean(axis=2), base.var(axis=0, ddof=1).mean(axis=2)
        row = [v_ours.mean() / norm, v_ours[sel].mean() / norm, v_base.mean() / norm, v_base[sel].mean() / norm]
        print(f"| {name} | " + " | ".join(f"{x:.3g}" for x in row) +
              f" | {row[2] / row[0]:.2f} | {row[3] / row[1]:.2f} | {t_ours:.3f} / {t_base:.3f} |", flush=True)


if __name__ == "__main__":
    main()

"""Bias of the chains where the visible cells grow: a random-parity case's image mean over seeds.

Stop 76 found the chains' image of glass505 (the glass family of ``random_parity_scenes.py``: an open
room under a world colour with a smooth glass cube) 0.9 % over PPM's, from the visible cells' growth;
stop 78's generations (tried and reverted: README, "A visible set that holds still") brought it to
0.9917 +- 0.0032 of before.  This exports the case through the
add-on (bpy), renders it with random_parity's settings for ours (16 passes of 100,000 photons, 4096
chains, initial radius 1.5 pixels, one worker, Cycles' light paths) at each seed, and prints the mean
and its standard error per method::

    python benchmarks/cell_generations.py --case 505 --seeds 40 --methods amcmcppm ppm

``--scene leaf`` renders the fast tier's half-transparent leaf instead
(``tests/core/test_transparency.py``: a sun through a leaf of opacity 0.3 and albedo 0.8 onto a floor,
one bounce, 6 passes of 60,000 photons, 1024 chains), whose closed form the means are divided by; it
showed stop 78's generations 1.1 % under PPM (stop 79: a generation's rho counted too few samples).
With two methods the last line is the first's image mean over the second's at the same seeds (mean
+- standard error of the per-seed ratios).

To compare revisions, run it in a worktree of each (``git worktree add``), side by side.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "addon"))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))


def export_case(seed, resolution, path):
    """The glass case ``seed`` as a core Scene saved to ``path`` (.npz), and its RenderSettings."""
    from fuzz_scenes import load_addon
    from random_parity import set_light_paths, set_ours
    from random_parity_scenes import FAMILIES, build
    load_addon()
    import bpy
    from amcmcppm.amcmcppm_addon.export.scene import export_scene
    from amcmcppm.amcmcppm_addon.export.settings import render_settings_from
    spec = FAMILIES["glass"](seed)
    scene = build(spec, resolution)
    set_light_paths(scene, spec)
    # (random_parity's defaults for ours; the seed is set per render)
    set_ours(scene, {"spec": spec, "seed": 1, "passes": 16, "photons": 100_000, "chains": 4096,
                     "initial_radius": 1.5})
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    exported.scene.save(path)
    return render_settings_from(scene.amcmcppm)


def leaf_case():
    """The fast tier's half-transparent leaf, its RenderSettings and its closed-form image mean."""
    from tests.core.test_transparency import TINT, leaf_over_floor, settings
    opacity, albedo, leaf = 0.3, 0.5, 0.8
    scene = leaf_over_floor({"diffuse": leaf, "opacity": opacity, "transparent_color": TINT.tolist()})
    exact = 10.0 / np.pi * (opacity * leaf + albedo * ((1 - opacity) * TINT) ** 2)
    return scene, settings(max_bounces=1, chains=1024), float(exact.mean())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=("glass", "leaf"), default="glass")
    ap.add_argument("--case", type=int, default=505, help="the glass family's case (its seed)")
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--methods", nargs="+", default=["amcmcppm", "ppm"])
    ap.add_argument("--resolution", type=int, nargs=2, default=(64, 48))
    args = ap.parse_args()
    from core import render
    from core.scene import Scene
    if args.scene == "leaf":
        scene, settings, scale = leaf_case()
        name = "leaf (over the closed form)"
    else:
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "case.npz")
            settings = export_case(args.case, tuple(args.resolution), path)
            scene = Scene.load(path)
        scale, name = 1.0, f"glass{args.case:03d}"
    per_method = []
    for method in args.methods:
        means, seconds = [], []
        for seed in range(1, args.seeds + 1):
            t0 = time.perf_counter()
            result = render(scene, dataclasses.replace(settings, method=method, seed=seed))
            means.append(float(result.image[..., :3].astype(np.float64).mean()) / scale)
            seconds.append(time.perf_counter() - t0)
        m = np.array(means)
        per_method.append(m)
        print(f"{name} {method}: mean {m.mean():.5f} +- {m.std(ddof=1) / np.sqrt(len(m)):.5f} "
              f"({len(m)} seeds, {np.mean(seconds):.1f} s a render)", flush=True)
    if len(per_method) == 2 and len(per_method[0]) > 1:
        ratio = per_method[0] / per_method[1]
        print(f"{name} {args.methods[0]} / {args.methods[1]} at the same seeds: {ratio.mean():.4f} +- "
              f"{ratio.std(ddof=1) / np.sqrt(len(ratio)):.4f}", flush=True)


if __name__ == "__main__":
    main()

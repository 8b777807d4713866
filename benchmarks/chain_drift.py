"""Do AMCMCPPM's chains drift from pass to pass?  An open floor under a constant sky, this checkout
against a base revision.

On ``sky_over_floor`` every pixel sees radiance albedo * sky exactly.  The camera looks down at a
slant, so the floor is seen face on at the bottom of the image and at a grazing angle at the top.
This renders it with PPM and AMCMCPPM for several seeds and prints the mean of four horizontal
bands (top = far, bottom = near) over the exact value, with standard errors over the seeds.  With
``--base`` the same scene (saved from this checkout) is rendered by ``core`` at that revision too
(extracted with ``git archive``), each version in its own process.

    python benchmarks/chain_drift.py [--base 2a44cab] [--passes 24] [--photons 40000]
                                     [--radius 1.5] [--seeds 6] [--resolution 32 32]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from ab_photon_pass import extract  # noqa: E402
from core.testing.scenes import sky_over_floor  # noqa: E402

ALBEDO, SKY = 0.5, 1.0

_RUN = r"""
import json, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
from core import RenderSettings, render
from core.scene import Scene
scene = Scene.load(sys.argv[2])
args = json.loads(sys.argv[3])
out = {}
for method in args["methods"]:
    bands, work = [], np.zeros(3)
    for seed in range(args["seeds"]):
        t0 = time.perf_counter()
        r = render(scene, RenderSettings(method=method, passes=args["passes"], photons_per_pass=args["photons"],
                                         initial_radius_px=args["radius"], workers=1, seed=seed))
        work += (time.perf_counter() - t0, sum(s["paths_traced"] for s in r.stats),
                 sum(s["photons_recorded"] for s in r.stats))
        rgb = r.image[..., :3].mean(axis=2)
        bands.append(rgb.reshape(4, rgb.shape[0] // 4, -1).mean(axis=(1, 2)).tolist())
    out[method] = dict(bands=bands, work=(work / args["seeds"]).tolist())
print(json.dumps(out))
"""


def run(root, scene_path, args):
    cmd = [sys.executable, "-c", _RUN, root, scene_path,
           json.dumps(dict(methods=args.methods, seeds=args.seeds, passes=args.passes, photons=args.photons,
                           radius=args.radius))]
    return json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", help="git revision to compare with (default: this checkout only)")
    ap.add_argument("--passes", type=int, default=24)
    ap.add_argument("--photons", type=int, default=40_000, help="photons per pass")
    ap.add_argument("--radius", type=float, default=1.5, help="initial_radius_px")
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--resolution", type=int, nargs=2, default=(32, 32))
    ap.add_argument("--methods", nargs="+", default=["ppm", "amcmcppm"])
    args = ap.parse_args()
    if args.resolution[1] % 4:
        ap.error("the image height must be a multiple of 4 (four bands)")
    with tempfile.TemporaryDirectory() as tmp:
        scene_path = os.path.join(tmp, "sky_over_floor.npz")
        sky_over_floor(ALBEDO, SKY, resolution=tuple(args.resolution)).save(scene_path)
        versions = [("this checkout", ROOT)]
        if args.base:
            extract(args.base, tmp, package="core")
            versions.append((args.base, tmp))
        print(f"sky_over_floor {args.resolution[0]}x{args.resolution[1]}, {args.passes} passes of "
              f"{args.photons} photons, initial radius {args.radius} px, {args.seeds} seeds, one worker")
        print("band means over albedo * sky, far (top) to near (bottom), +- standard error over seeds;\n"
              "then per render: seconds, photon paths traced, photons recorded")
        for name, root in versions:
            for method, res in run(root, scene_path, args).items():
                b = np.array(res["bands"]) / (ALBEDO * SKY)
                se = b.std(axis=0, ddof=1) / np.sqrt(len(b)) if len(b) > 1 else np.zeros(4)
                cells = "  ".join(f"{m:.3f} +- {e:.3f}" for m, e in zip(b.mean(axis=0), se))
                seconds, paths, recorded = res["work"]
                print(f"{name:>14} {method:9} {cells}   {seconds:6.2f} s {paths:11,.0f} {recorded:11,.0f}")


if __name__ == "__main__":
    main()
